"""Sections 6, 7, 9 and 10 of the report: the flip-time map, chaos, the validation against
MuJoCo, how the report was made -- for any model."""

from __future__ import annotations

import math
import platform
from typing import Callable, Dict, List, Tuple

import numpy as np

from ... import __version__
from ... import schema
from ...errors import ParameterError, SkewpendError

from .common import (CHAOS_DIAGRAM, CHAOS_DIAGRAM_LEVELS, CHAOS_LYAPUNOV_T_END, CHAOS_MAP_N, CHAOS_MAP_T_END,
                     CHAOS_SECTION_CROSSINGS, CHAOS_SECTION_LEVELS, CHAOS_SECTION_ORBITS, FIGURE_DT, FIGURE_MAX_ROWS,
                     FLIPMAP_N, FLIPMAP_N_BY_LINKS, FLIPMAP_T_END, LONG_FLIPMAP_N, LONG_LYAPUNOV_T_END, VALIDATION_DT,
                     VALIDATION_T_END, VALIDATION_TOL, Context, answers_names, by_links, detail, esc, facts_html, fig_png,
                     figure_html, fmt_deg, fmt_num, inline_math, katex_assets, prose, sections, table_html, telling)
from .system import TEXT, label, rate_tex, start_tex, tex


def nonconservative_text(p) -> str:
    """The terms that make ``p`` non-conservative, as HTML: ``Coulomb friction in hinge 1 cf1 = 0.1 N m``
    (:attr:`skewpend.Parameters.nonconservative_terms`; meanings and units from the schema)."""
    parts = []
    for n in p.nonconservative_terms:
        value = getattr(p, n)
        shown = "symbolic" if value is None else f"= {fmt_num(value)} {schema.unit(n)}"
        parts.append(f"{esc(schema.meaning(n))} <code>{n}</code> {shown}")
    return ", ".join(parts)


# -- section 7: chaos ------------------------------------------------------------------------------------------
def chaos_jobs(ctx: Context) -> Dict[str, Callable]:
    """Section 7's ensembles, as ``{name: compute(progress)}`` -- started when the report starts
    (:class:`Prefetch`), so that they run while the earlier sections draw: the Poincare sections,
    the largest-exponent map and the chaos diagram (a conservative model only: they need an energy
    surface; the diagram only when the model has a skew angle)."""
    from ...analysis.chaos import chaos_diagram, potential_range
    from ...analysis.lyapunov import lyapunov_map
    from ...analysis.poincare import poincare

    p = ctx.params
    if not answers_names(p) or not p.conservative:  # the planar pictures; no energy surface with losses or torques
        return {}
    span = potential_range(p)
    jobs: Dict[str, Callable] = {}
    for level in CHAOS_SECTION_LEVELS:
        jobs[f"section {level}"] = (lambda e: lambda check: poincare(
            p, e, n_orbits=CHAOS_SECTION_ORBITS, n_crossings=CHAOS_SECTION_CROSSINGS, progress=check))(level * span)
    jobs["map"] = lambda check: lyapunov_map(p, CHAOS_MAP_N, t_end=CHAOS_MAP_T_END, progress=check)
    if p.uses_alpha:
        jobs["diagram"] = lambda check: chaos_diagram(p, energy=[level * span for level in CHAOS_DIAGRAM_LEVELS],
                                                      progress=check, **CHAOS_DIAGRAM)
    return jobs


def section_chaos(ctx: Context) -> str:
    import warnings

    from ...analysis.chaos import potential_range
    from ...analysis.lyapunov import lyapunov
    from ...status import Status
    from .. import figures as F

    p, y0, n = ctx.params, ctx.y0, ctx.params.n
    horizon = CHAOS_LYAPUNOV_T_END if n <= 3 else LONG_LYAPUNOV_T_END
    out = [prose(
        "<p>Chaos, measured. The <b>Lyapunov exponents</b> are the rates at which nearby motions separate: the state is "
        f"integrated together with {schema.count_text(2 * n, 'tangent vectors')} — the variational equations "
        r"$\dot v = J(y)\,v$ with the Jacobian $J$ generated from the model of section 2, in the same adaptive "
        "DOP853 steps as the state — and every second the vectors are re-orthonormalised (QR), their logarithmic "
        "growths summed (Benettin's method). A positive largest exponent means chaos; without damping and torques "
        r"the spectrum comes in pairs $\pm\lambda$ with two zeros.</p>")]
    notes = []
    with warnings.catch_warnings(record=True):
        warnings.simplefilter("always")
        try:
            spec = lyapunov(p, y0, t_end=horizon, throw=False,
                            progress=telling(schema.count_text(2 * n, "Lyapunov exponents"), "s"))
        except SkewpendError as exc:
            spec = None
            out.append(f'<p class="callout warn">The Lyapunov spectrum could not be computed: {esc(exc)}</p>')
    if spec is not None:
        detail("the figure of the running estimates")
        fig = F.lyapunov_figure(spec)
        out.append(figure_html(fig_png(fig), prose(
            f"Running estimates of the {schema.count_text(spec.k, 'Lyapunov exponents')} of the simulation's initial "
            f"state (section 5), over {fmt_num(horizon)} s, QR every {fmt_num(spec.settings['renorm_every'])} s; they "
            "settle as the time grows (± is the 95 % interval from the spread over 10 time windows, given once they "
            "have settled)."), "Lyapunov exponents against time"))
        settled = spec.status != Status.NOT_SETTLED
        facts = [(f"λ{i + 1}", f"{spec.exponents[i]:+.4f}" + (f" ± {spec.interval[i]:.2g}" if settled else "") + " 1/s")
                 for i in range(spec.k)]
        facts.append(("sum", f"{spec.sum:+.2e} 1/s"))
        facts.append(("work", f"{fmt_count(spec.stats['steps'])} steps in {spec.stats['wall_time']:.2f} s"))
        if spec.status != 0:
            facts.append(("stopped" if settled else "not settled", esc(spec.message)))
        out.append(facts_html(facts))
        notes.append(f"Lyapunov spectrum of {spec.k} exponents, {spec.stats['wall_time']:.2f} s")

    if not answers_names(p):  # the planar pictures read the double pendulum's names (phi = 0, (psi, p_psi), alpha)
        out.append('<p class="note">Poincaré sections and the chaos diagram are planar pictures of the double '
                   + (f"pendulum (a section of its three-dimensional energy surface); a chain of {n} links has a "
                      f"{2 * n - 1}-dimensional one, and the report draws neither.</p>" if n > 2 else
                      "pendulum read from its parameters (a, b, m1, m2, alpha, ...): given so, as a run file's "
                      "[parameters], this model's report draws them.</p>"))
        ctx.notes["chaos"] = ", ".join(notes)
        return "\n".join(out)
    if not p.conservative:
        terms = p.nonconservative_terms
        out.append("<p class=\"note\">Poincaré sections and the chaos diagram need an energy surface, that is a "
                   "conservative model; this one is not (" + nonconservative_text(p) + ": section 1), so they are left "
                   "out (the Lyapunov exponents above are those of this model: with damping or friction their sum is "
                   "the rate of phase-space contraction).</p>")
        ctx.notes["chaos"] = ", ".join(notes) + f"; sections and diagram skipped (not conservative: {', '.join(terms)})"
        return "\n".join(out)

    span = potential_range(p)
    jobs = chaos_jobs(ctx)
    out.append(prose(
        "<p>A <b>Poincaré section</b> cuts the motion at fixed energy each time the first rod passes the vertical "
        r"($\varphi = 0$, moving forwards) and plots the second joint's angle and canonical momentum "
        r"$(\psi, p_\psi)$ — coordinates in which the section map preserves area. Regular orbits draw closed curves; "
        "chaotic ones scatter over an area. Each crossing is located on the dense output of the step that made it. "
        f"Left: a low energy, right: a higher one ({CHAOS_SECTION_ORBITS} orbits, up to {CHAOS_SECTION_CROSSINGS} "
        "crossings each).</p>"))
    imgs = []
    for level in CHAOS_SECTION_LEVELS:
        e = level * span
        try:
            sec = ctx.prefetch.result(f"section {level}", jobs[f"section {level}"])
        except SkewpendError as exc:
            imgs.append(f'<p class="callout warn">The section at {fmt_num(e, 4)} J could not be made: {esc(exc)}</p>')
            continue
        imgs.append(figure_html(fig_png(F.poincare_figure(sec)), prose(
            f"Section $\\varphi = 0$ at E = {fmt_num(e, 4)} J ({fmt_num(100 * level, 3)} % of the potential's span "
            f"{fmt_num(span, 4)} J): {fmt_count(sec.n_points)} points, energy error at most "
            f"{sec.stats['max_energy_error']:.1e} J."), f"Poincaré section at {e:.3g} J"))
        notes.append(f"section {e:.3g} J {sec.stats['wall_time']:.2f} s")
    out.append('<div class="figure-row">' + "".join(imgs) + "</div>")

    try:
        m = ctx.prefetch.result("map", jobs["map"])
        out.append(figure_html(fig_png(F.lyapunov_map_figure(m)), prose(
            f"The largest Lyapunov exponent over {fmt_num(CHAOS_MAP_T_END)} s for starts at rest on a "
            f"{CHAOS_MAP_N}&nbsp;×&nbsp;{CHAOS_MAP_N} grid of $(\\varphi_0, \\psi_0)$ — compare the flip-time map of "
            "section 6: the starts low in the well move regularly (exponent near 0), the wild ones are chaotic."),
            "largest Lyapunov exponent of starts at rest"))
        notes.append(f"map {m.stats['wall_time']:.2f} s")
    except SkewpendError as exc:
        out.append(f'<p class="callout warn">The largest-exponent map could not be made: {esc(exc)}</p>')

    if p.uses_alpha:
        try:
            d = ctx.prefetch.result("diagram", jobs["diagram"])
        except SkewpendError as exc:
            d = None
            out.append(f'<p class="callout warn">The chaos diagram could not be made: {esc(exc)}</p>')
        if d is not None:
            out.append(prose(
                "<p><b>Does skewing the hinges tame or feed chaos?</b> For each skew angle $\\alpha$ and energy above "
                f"the rest state, {CHAOS_DIAGRAM['samples']} starts spread over the energy surface (on the section "
                "$\\varphi = 0$) are followed for " + fmt_num(CHAOS_DIAGRAM['t_end']) + " s; the fraction whose largest "
                f"exponent exceeds {fmt_num(d.threshold, 3)} 1/s (clearly above the finite-time level of regular motion) "
                "is the chaotic fraction of that energy surface. The other parameters are those of section 1.</p>"))
            out.append(figure_html(fig_png(F.chaos_diagram_figure(d)), prose(
                "Chaotic fraction of the energy surface against $\\alpha$ and the energy above rest. "
                "A larger diagram: <code>skewpend chaos-diagram --out diagram.zarr --plot diagram.png</code>."),
                "chaos diagram over alpha and energy"))
            out.append('<pre class="table">' + esc(d.table()) + "</pre>")
            notes.append(f"diagram {d.stats['wall_time']:.2f} s")
    ctx.notes["chaos"] = ", ".join(notes)
    return "\n".join(out)


# -- section 6: the flip-time map --------------------------------------------------------------------------
def fmt_count(k: int) -> str:
    """A whole number with thin spaces between groups of three digits: ``20 736``."""
    return f"{k:,}".replace(",", "\u2009")


def section_flipmap(ctx: Context) -> str:
    import warnings

    from ...analysis.flipmap import flip_map, flip_time
    from .. import figures as F
    from ..figures import wrap_angle

    p, y0 = ctx.params, ctx.y0
    q = len(p.coordinates)
    n, t_end = by_links(q, FLIPMAP_N, FLIPMAP_N_BY_LINKS, LONG_FLIPMAP_N), FLIPMAP_T_END
    sym = [tex(c) for c in p.coordinates[:2]]
    s0 = [start_tex(c) for c in p.coordinates[:2]]
    t0 = [TEXT[c] + "₀" if c in TEXT else label(c) + "(0)" for c in p.coordinates[:2]]
    with warnings.catch_warnings(record=True):
        warnings.simplefilter("always")
        try:
            fm = flip_map(p, n, t_end=t_end, progress=telling(f"{n}×{n} starts", "cells"))
        except SkewpendError as exc:
            ctx.notes["flipmap"] = "could not be made"
            return f'<p class="callout warn">The flip-time map could not be made: {esc(exc)}</p>'
    detail("the figure")
    st = fm.stats
    ctx.notes["flipmap"] = (f"{n} × {n} starts at rest" + (f" over ({', '.join(p.coordinates[:2])})" if q > 2 else "")
                            + f", t_end = {t_end:g} s, DOP853 at rtol = {fm.settings['rtol']:g}, "
                            f"atol = {fm.settings['atol']:g}: {st['flipped']} of {n * n} flip, computed in "
                            f"{st['wall_time']:.2f} s")
    start = [float(wrap_angle(y0[0])), float(wrap_angle(y0[1]))]
    at_rest = not any(y0[q:])
    in_plane = not any(y0[2:q])  # the other angles at the map's 0
    margin = F.flipmap_energy_margin(fm)
    forbidden = None if margin is None else margin < 0
    fig = F.flipmap_figure(fm, mark=start if in_plane else None, forbidden=margin,
                           mark_label="start of section 5" + ("" if at_rest else " (its angles)"))
    cells = n * n
    flipped, skipped = st["flipped"], st["skipped_energy"]
    n_forbidden = int(np.count_nonzero(forbidden)) if forbidden is not None else skipped
    grey = ("grey: energy forbids any flip, so these starts were not integrated at all — released at rest, the energy "
            + prose(r"$T + V$ with $V = \Pi - \tau\cdot q$ never increases (damping only dissipates), and here it starts "
                 r"below the lowest $V$ on the boundary of the square (−180°, 180°)², which the angles must reach to flip; "))
    if forbidden is None or n_forbidden == 0:
        grey = ""
    held = "" if q <= 2 else (", the other " + (schema.count_text(q - 2, "angles") if q > 3 else "angle")
                              + " held at 0 (hanging)")
    if in_plane:
        red = ("red dot: the angles of the simulation's initial state (section 5)"
               + ("." if at_rest else " — which starts with speeds, so its own motion need not follow its cell."))
    else:
        red = "the simulation's initial state (section 5) is not on this plane (its other angles are not 0)."
    caption = (
        prose(f"Flip time of the {'pendulum' if q <= 2 else 'chain'} released at rest from $({s0[0]}, {s0[1]})$ — the "
              f"first time {'either' if q <= 2 else 'any'} hinge angle leaves (−180°, 180°) — on a log colour scale "
              f"(bright: early, dark: late), with ${s0[0]}$ across and ${s0[1]}$ up{held}, for the parameters of section "
              "1 (") + f"{n}&nbsp;×&nbsp;{n} starts, followed for {fmt_num(t_end)} s). "
        + f"White: no flip within {fmt_num(t_end)} s; " + grey + red
    )
    which = (f"either ${sym[0]}$ or ${sym[1]}$" if q <= 2 else "any hinge angle")
    out = [prose(
        "<p>The double pendulum is the textbook chaotic mechanical system" + ("" if q <= 2 else ", and a chain of links "
        "its longer kin") + ". Release it at rest from hinge angles "
        f"$({s0[0]}, {s0[1]})$" + ("" if q <= 2 else " (the others at 0)") + " and wait: does a rod go over the top, "
        f"and when? The <b>flip time</b> is the first time {which} leaves (−180°, 180°). Below, each of "
        + f"{n}&nbsp;×&nbsp;{n} = {fmt_count(cells)}"
        + " starts is one simulation of the equations of section 2 (DOP853 in compiled code generated from the model, "
        "several trajectories side by side, each stopped at its flip, located on the dense output): smooth regions where "
        "nearby starts flip alike, and between them the fractal tangle where the outcome depends sensitively on the start."
        "</p>")]
    out.append(figure_html(fig_png(fig), caption, "flip-time map: flip time against the starting hinge angles"))
    facts = [
        ("starts that flip", f"{fmt_count(flipped)} of {fmt_count(cells)} ({fmt_num(100.0 * flipped / cells, 3)} %) within "
                             f"{fmt_num(t_end)} s"),
        ("no flip", f"{fmt_count(cells - flipped)} ({fmt_num(100.0 * (cells - flipped) / cells, 3)} %)"
                    + (f", of which {fmt_count(n_forbidden)} forbidden by energy" if forbidden is not None else "")),
    ]
    angles = f"{t0[0]} = {fmt_deg(start[0])}, {t0[1]} = {fmt_deg(start[1])}"
    if not in_plane:
        facts.append(("the start of section 5", f"{angles}, off the map's plane"))
    elif at_rest:
        try:
            one = flip_time(p, *start, t_end=FLIPMAP_T_END)
            t_flip, joint, never = one.time, (one.which if one.status.ok else -2), one.forbidden
        except ParameterError:  # not every model's single start is computed on its own: its cell says it
            t_flip, joint, never = math.nan, -3, False
        except SkewpendError:
            t_flip, joint, never = math.nan, -2, False
        if never:
            what = "never flips: energy forbids it"
        elif joint >= 0:
            what = f"flips at t = {fmt_num(t_flip, 5)} s ({label(p.coordinates[joint])}, hinge {joint + 1})"
        elif joint == -1:
            what = f"does not flip within {fmt_num(t_end)} s"
        else:
            what = "could not be computed" if joint == -2 else "see its cell"
        facts.append(("the start of section 5", f"{angles}, at rest: {what}"))
    else:
        facts.append(("the start of section 5", f"{angles}, but not at rest (the map is for starts at rest)"))
    how = (f"{fmt_count(st['integrated'])} starts integrated, {fmt_count(st['mirrored'])} mirrored (the map is symmetric "
           f"under ({t0[0]}, {t0[1]}) → (−{t0[0]}, −{t0[1]}))" if st["mirrored"]
           else f"{fmt_count(st['integrated'])} starts integrated")
    how += (f", {fmt_count(skipped)} skipped by the energy bound; {fmt_count(st['steps'])} steps on {st['workers']} "
            f"thread{'s' if st['workers'] != 1 else ''}")
    facts.append(("work", how))
    facts.append(("time to compute the map", f"{st['wall_time']:.2f} s" + (f" (plus {st['kernel_build_time']:.2f} s to compile its "
                                                         "kernel, now cached)" if st.get("kernel_build_time") else "")))
    if st.get("failed"):  # (flip_map's warning is caught: said here instead)
        facts.append(("failed", f'<span class="verdict bad">{st["failed"]} starts could not be integrated</span> '
                                "(left white)"))
    out.append(facts_html(facts))
    out.append(prose("<p class=\"note\">In Python: <code>skewpend.flip_map(params, 512, t_end=10)</code> gives a larger "
                  "map (a <code>FlipMap</code> with the flip times, the joint that flipped and the settings), "
                  "<code>skewpend.views.figures.flipmap_figure</code> draws it.</p>"))
    return "\n".join(out)


# -- section 9: validation -------------------------------------------------------------------------------
def mujoco_installed() -> bool:
    import importlib.util

    return importlib.util.find_spec("mujoco") is not None


def section_validation(ctx: Context) -> str:
    p, y0 = ctx.params, ctx.y0
    installed = mujoco_installed()
    if ctx.validate is False or not installed:
        ctx.notes["validation"] = "not run: " + ("MuJoCo is not installed" if not installed else "not asked for")
        why = "MuJoCo is not installed" if not installed else "the comparison was switched off"
        return (
            f'<p class="callout warn"><b>Not run: {why}.</b> To compare with MuJoCo, install it with '
            "<code>pip install 'skewpend[validate]'</code> (or <code>pip install mujoco</code>) and make the report again.</p>"
            "<p>The comparison exports the model as MuJoCo MJCF, simulates it with MuJoCo's RK4 and compares the states with "
            "skewpend's on a common time grid; <code>skewpend validate</code> does the same on the command line.</p>"
        )
    from ...interop.validation import compare_with_mujoco

    horizon = min(VALIDATION_T_END, ctx.t_end)
    detail(f"MuJoCo and skewpend over {horizon:g} s")
    try:
        rep = compare_with_mujoco(p, y0, horizon, dt=VALIDATION_DT)
    except SkewpendError as exc:
        ctx.notes["validation"] = "could not be made"
        return f'<p class="callout warn">The comparison with MuJoCo could not be made: {esc(exc)}</p>'
    ok = rep.max_difference <= VALIDATION_TOL
    ctx.notes["validation"] = f"{'AGREE' if ok else 'DISAGREE'}, largest difference {rep.max_difference:.2e}"
    rows = [[inline_math(rate_tex(k[1:]) if k.startswith("d") else tex(k)), fmt_num(v, 3),
             "rad/s" if k.startswith("d") else "rad"] for k, v in rep.max_abs_diff.items()]
    callout, mark, word, how = ("good", "ok", "AGREE", "is within") if ok else ("warn", "bad", "DISAGREE", "exceeds")
    verdict = (f'<p class="callout {callout}"><span class="verdict {mark}">{word}</span> — the largest difference, '
               f"{fmt_num(rep.max_difference, 3)}, {how} the tolerance {fmt_num(VALIDATION_TOL)}.</p>")
    return (
        "<p>An independent engine: the model exported as MuJoCo MJCF (full inertia tensors, hinge axes, damping and "
        "torques; a chain's bodies nested link by link; thin rods get the tiny axial inertia MuJoCo needs, in both "
        "models) is simulated by MuJoCo "
        f"{esc(rep.mujoco_version)} with RK4 at dt = {fmt_num(rep.dt)} s, and by skewpend with DOP853 at rtol = atol = "
        f"10<sup>−12</sup>, from the initial state of section 1 over {fmt_num(rep.t_end)} s; the states are compared at "
        f"{rep.samples} common times.</p>"
        + verdict
        + table_html(["state", "largest |skewpend − MuJoCo|", "unit"], rows, numeric=(1,), caption="Largest differences",
                 compact=True)
    )


# -- section 10: provenance -------------------------------------------------------------------------------
def _versions() -> List[Tuple[str, str]]:
    from importlib import metadata

    out = [("skewpend", __version__), ("Python", platform.python_version())]
    for name in ("numpy", "sympy", "scipy", "matplotlib", "imageio-ffmpeg", "mujoco"):
        try:
            out.append((name, metadata.version(name)))
        except metadata.PackageNotFoundError:
            out.append((name, "not installed"))
    return out


def section_provenance(ctx: Context) -> str:
    from ..style import settings_text

    named = answers_names(ctx.params)
    sim = {"t_end": ctx.t_end, "rtol": ctx.rtol, "atol": ctx.atol, "dt": ctx.dt}
    settings = [
        ("simulation", esc(settings_text(ctx.method, {k: v for k, v in sim.items() if v is not None}))
         + " (figures: rows every " + fmt_num(max(FIGURE_DT, ctx.t_end / FIGURE_MAX_ROWS)) + " s)"),
        ("animation", esc(ctx.notes.get("clip", ""))),
        ("α sweep" if named else "tilt sweeps", esc(f"0 to 180° in {ctx.notes.get('sweep points', ctx.sweep_points)} values"
                                                    f"{'' if named else ' a hinge'}: {ctx.notes.get('sweep', '')}")),
        ("flip-time map", esc(ctx.notes.get("flipmap", ""))),
        ("chaos", esc(ctx.notes.get("chaos", ""))),
        ("orbits", esc(ctx.notes.get("orbits", ""))),
        ("validation", esc(f"MuJoCo RK4, dt = {VALIDATION_DT:g} s, {min(VALIDATION_T_END, ctx.t_end):g} s, tolerance "
                          f"{VALIDATION_TOL:g}: {ctx.notes.get('validation', '')}")),
        ("derivation shown for", esc(ctx.notes.get("derivation", ""))),
        ("check at α = 0" if named else "check", esc(ctx.notes.get("check", ""))),
        ("model code", esc(ctx.notes.get("kernel", ""))),
        ("platform", esc(f"{platform.system()} {platform.machine()}, {platform.python_implementation()} "
                         f"{platform.python_version()}")),
    ]
    labels = [
        ("system", "1 · the system: pictures"),
        ("derivation", "2 · derivation and display forms" if named else "2 · derivation (SymPy)"),
        ("check", "3 · check at α = 0" if named else "3 · check: two derivations of one model"),
        ("modes", "4 · normal modes and the α sweep" if named else "4 · normal modes and the tilt sweeps"),
        ("simulation", "5 · simulation, all of it"),
        ("simulation: integration", "5 · integration"),
        ("simulation: figures", "5 · figures"),
        ("simulation: live view", "5 · live view: frames, rod ends, axes"),
        ("flipmap", "6 · flip-time map"),
        ("chaos", "7 · chaos: exponents, sections, diagram" if named else "7 · Lyapunov spectrum"),
        ("orbits", "8 · equilibria and nonlinear normal modes"),
        ("validation", "9 · validation against MuJoCo"),
        ("total", "total"),
    ]
    _, _, katex_version = katex_assets()
    rows = [[esc(k), esc(v)] for k, v in _versions() + [("KaTeX (bundled)", katex_version)]]
    if ctx.command:
        settings.insert(0, ("command", f"<code>{esc(ctx.command)}</code>"))
    trows = [[esc(label), f"{ctx.timings[key]:.2f}"] for key, label in labels if key in ctx.timings]
    # kernels compiled in this run (first use): each inside the part that first needed it, not added to the total
    number = {key: n for n, (key, _) in enumerate(sections(ctx.params), 1)}
    compiled = list(ctx.compiled.values())
    at = len(trows) - 1 if "total" in ctx.timings else len(trows)  # before the total
    trows[at:at] = [[esc(f"{number.get(part, '?')} · compiling {what}"), f"{seconds:.2f}"]
                    for what, part, seconds in sorted(compiled, key=lambda c: number.get(c[1], 99))]
    return (
        "<h3>Software</h3>" + table_html(["package", "version"], rows, compact=True)
        + "<h3>Settings</h3>" + facts_html(settings)
        + "<h3>Timings</h3>"
        + table_html(["part", "seconds"], trows, numeric=(1,), compact=True,
                 caption="Wall time of each part in this run" + (
                     " (sections 2 and 3 in a second process, in parallel with the others)" if ctx.notes.get("parallel")
                     else " (sections 2 and 3 read from the cache)" if ctx.notes.get("cached") else "")
                 + ("; no kernel was compiled in this run" if not compiled else
                    "; the rows “compiling …”: kernels compiled in this run (first use), each part of its "
                    "section's work, the others were loaded"))
        + "<p class=\"note\">Everything here was computed when this file was made"
        + (" (sections 2 and 3 by an earlier run with the same parameters and the same skewpend, kept in the cache "
           "directory like the compiled kernels)" if ctx.notes.get("cached") else "")
        + "; opening it computes nothing but the typesetting of the mathematics.</p>"
    )
