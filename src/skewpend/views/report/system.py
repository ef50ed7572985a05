"""Sections 1, 4 and 5 of the report: the system, its normal modes, a simulation."""

from __future__ import annotations

import math
import time
from typing import Dict, List

import numpy as np

from ... import schema
from ...errors import SkewpendError
from ...symbolic.model import Parameters

from .common import (DEFAULT_PARAMETERS, DEFAULT_INITIAL_STATE, DEFAULT_T_END, MAX_T_END, REPORT_SUFFIXES, SECTIONS, CLIP_SECONDS, CLIP_FPS, CLIP_SIZE, PICTURE_SIZE, FIGURE_DPI, SWEEP_POINTS, VALIDATION_DT, VALIDATION_T_END, VALIDATION_TOL, FLIPMAP_N, FLIPMAP_T_END, CHAOS_LYAPUNOV_T_END, CHAOS_SECTION_LEVELS, CHAOS_SECTION_ORBITS, CHAOS_SECTION_CROSSINGS, CHAOS_MAP_N, CHAOS_MAP_T_END, CHAOS_DIAGRAM, CHAOS_DIAGRAM_LEVELS, FIGURE_DT, FIGURE_MAX_ROWS, esc, inline_math, display_math, prose, fmt_num, fmt_num_tex, fmt_deg, fig_png, rgb_png, data_uri, FIGURE_SLOT, figure_html, live_view_html, number_figures, table_html, facts_html, asset, katex_assets, template, tex_of, array_tex, vector_tex, Context, detail, telling)  # noqa: F401

# -- section 1: the system ------------------------------------------------------------------------
def _unit(unit: str) -> str:
    return f'<span class="unit">{unit}</span>' if unit and unit != "1" else ""


def _vec_text(v) -> str:
    return "(" + ", ".join(fmt_num(x, 5) for x in v) + ")"


def table_scalars(p: Parameters) -> List[str]:
    """The scalars the parameters' table lists: those every model has, its damping and torques
    (even when zero: the model has them), and each further role's (Coulomb friction with its
    smoothing rate, the rotors) when one of its parameters differs from its default; names and
    roles from :mod:`skewpend.schema`."""
    always = schema.CORE_NAMES + schema.DAMPING_NAMES + schema.TORQUE_NAMES
    shown = []
    for name in schema.SCALAR_NAMES:
        if name == "alpha" and not p.uses_alpha:
            continue
        if name not in always:
            group = schema.names(role=schema.field(name).role)
            if all(getattr(p, n) == schema.default(n) for n in group):
                continue
        shown.append(name)
    return shown


def _parameter_rows(p: Parameters) -> List[List[str]]:
    rows = []
    for name in table_scalars(p):
        value = getattr(p, name)
        unit = schema.unit(name)
        if value is not None and schema.field(name).bound == "angle":
            shown, unit = f"{fmt_deg(value)} = {fmt_num(value)} rad", ""
        else:
            shown = fmt_num(value)
        rows.append([inline_math(schema.tex(name)), f"<code>{name}</code>", esc(schema.meaning(name)), shown, _unit(unit)])
    for name in schema.GEOMETRY_NAMES:
        value = getattr(p, name)
        if value is None:
            shown = f'<span class="note">default: {esc(schema.default_text(name))}</span>'
        elif schema.field(name).kind == "inertia":
            shown = "<br>".join(_vec_text(r) for r in value)
        else:
            shown = _vec_text(value) + (" (unit vector)" if name in schema.AXIS_NAMES else "")
        rows.append([inline_math(schema.tex(name)), f"<code>{name}</code>", esc(schema.meaning(name)), shown,
                     _unit(schema.unit(name))])
    return rows


def conservation_text(p: Parameters) -> str:
    """Whether the model conserves its energy, in a sentence (:attr:`Parameters.conservative`): if
    not, the terms that make it so (damping, Coulomb friction, torques), by their meanings."""
    if p.conservative:
        return prose(r"No damping, friction or torques: the energy $T + \Pi$ is conserved.")
    return "Not conservative: " + esc(", ".join(schema.meaning(n) for n in p.nonconservative_terms)) + " (values below)."


def still_png(tr) -> bytes:
    """Frame 0 of ``tr`` as drawn by the animation (rods, both hinge axes, the angle between them)."""
    from ..animation import FrameRenderer

    r = FrameRenderer(tr, size=PICTURE_SIZE, dpi=100, trail=0.0)
    try:
        r.draw(0)
        return rgb_png(r.rgb())
    finally:
        r.close()


def section_system(ctx: Context) -> str:
    from ...numeric.simulation import simulate

    p, y0 = ctx.params, ctx.y0
    # the reference configuration, for its picture (the report's own method: no other kernel compiled)
    rest = simulate(p, (0.0, 0.0, 0.0, 0.0), 0.01, dt_out=0.01, method="dop853")
    rest_png = still_png(rest)
    ctx.still = still_png(ctx.clip)
    thin = p.is_thin_rods
    if p.uses_alpha and p.axis1 is None:
        skew = prose(r"the hinge axes $\underline{k}$ and $\underline{e}_0$ make the angle $\alpha$ = ") + fmt_deg(p.alpha)
    else:
        skew = "the hinge axes are those given in the table below"
    fig_rest = figure_html(
        rest_png,
        prose(r"Reference configuration $\varphi = \psi = 0$: both rods hang along $\underline{j}$ (down) and ") + skew
        + ". Green: hinge 1's axis (fixed); magenta: hinge 2's axis; the arc marks the angle between them.",
        "the pendulum hanging at rest, with both hinge axes drawn",
    )
    fig_start = figure_html(
        ctx.still,
        prose(r"The initial state of the simulation (section 5): $\varphi_0$ = ") + fmt_deg(y0[0]) + prose(r", $\psi_0$ = ")
        + fmt_deg(y0[1]) + prose(r". The second axis $\underline{e} = \underline{\underline{P}}_1\cdot\underline{e}_0$ has turned with rod 1."),
        "the pendulum in its initial state, with both hinge axes drawn",
    )
    if thin:
        intro = prose(
            r'<p class="lead">A rod hangs from the roof on a cylindrical hinge; a second rod hangs from the end of the first '
            r"on another cylindrical hinge whose axis, when both rods are vertical, makes the angle $\alpha$ with the first "
            r"hinge's axis. Find the equations of motion — and what they predict.</p>"
        )
    else:
        intro = (
            '<p class="lead">Two rigid bodies hang in a chain on two cylindrical hinges whose axes are given below — the '
            "specification's rods generalised to arbitrary bodies and axes. Find the equations of motion — and what they "
            "predict.</p>"
        )
    basis = prose(
        r"<p>Basis $\underline{i}, \underline{j}, \underline{k}$: $\underline{j}$ points <b>down</b> (along both rods when "
        r"they hang), $\underline{k}$ is the axis of the roof hinge, $\underline{i}$ completes the right-handed triple. "
        r"The generalised coordinates are the hinge angles $\varphi$ (hinge 1) and $\psi$ (hinge 2), both zero with the "
        r"rods hanging; gravity acts along $+\underline{j}$. "
        + conservation_text(p) + "</p>"
    )
    table = table_html(["symbol", "name", "meaning", "value", "unit"], _parameter_rows(p), caption="Parameters (SI units)")
    initial = table_html(
        ["", "value", "unit"],
        [
            [inline_math(r"\varphi_0"), f"{fmt_deg(y0[0])} = {fmt_num(y0[0])} rad", ""],
            [inline_math(r"\psi_0"), f"{fmt_deg(y0[1])} = {fmt_num(y0[1])} rad", ""],
            [inline_math(r"\dot\varphi_0"), fmt_num(y0[2]), "rad/s"],
            [inline_math(r"\dot\psi_0"), fmt_num(y0[3]), "rad/s"],
        ],
        caption="Initial state of the simulation (section 5)",
        compact=True,
    )
    return intro + basis + f'<div class="figure-row">{fig_rest}{fig_start}</div>' + table + initial



# -- section 4: normal modes -------------------------------------------------------------------------
def section_modes(ctx: Context) -> str:
    from ...analysis.modes import normal_modes, sweep
    from ..figures import plot_sweep

    p = ctx.params
    try:
        m = normal_modes(p)
    except SkewpendError as exc:
        ctx.notes["modes"] = "none (see section 4)"
        return (f'<p class="callout warn">No normal modes for these parameters: {esc(exc)}</p>'
                "<p>Normal modes describe small oscillations about a stable hanging equilibrium.</p>")
    out = [prose(
        r"<p>Small oscillations about the hanging position obey the linearised equations $M_0\,\ddot q + C_0\,\dot q + "
        r"K_0\,q = 0$ of section 2; with the values of section 1</p>")]
    mats = r"M_0 = " + array_tex(m.M) + r"\ \mathrm{kg\,m^2},\qquad K_0 = " + array_tex(m.K) + r"\ \mathrm{N\,m}"
    if m.damped:
        mats += r",\qquad C_0 = " + array_tex(m.C) + r"\ \mathrm{N\,m\,s}"
    out.append(display_math(mats))
    out.append(prose(
        r"<p>A normal mode $q = v\cos(\omega t - \delta)$ solves $K_0\,v = \omega^2 M_0\,v$: the two values of "
        r"$\omega^2$ are the roots of $\det(K_0 - \omega^2 M_0) = 0$, and the shapes $v$ are normalised with "
        r"$v^T M_0\, v = 1$.</p>"))
    rows = []
    for k in range(2):
        v = m.shapes[:, k]
        ratio = "∞" if not np.isfinite(m.ratios[k]) else fmt_num(m.ratios[k], 5)
        rows.append([str(k + 1), fmt_num(m.frequencies[k]), fmt_num(m.frequencies[k] / (2 * np.pi)), fmt_num(m.periods[k]),
                     f"({fmt_num(v[0], 5)}, {fmt_num(v[1], 5)})", ratio])
    out.append(table_html(["mode", "ω [rad/s]", "f [Hz]", "period [s]", "shape (φ, ψ)", "ψ/φ"], rows, numeric=(1, 2, 3, 5),
                      caption="Normal modes (undamped)"))
    beat = "∞ (equal frequencies)" if not np.isfinite(m.beat_period) else f"{fmt_num(m.beat_period)} s"
    out.append(facts_html([("frequency ratio ω₂/ω₁", fmt_num(m.frequencies[1] / m.frequencies[0])),
                       ("beat period 2π/(ω₂ − ω₁)", beat)]))
    if m.damped:
        drows = []
        for k in range(2):
            l1, l2 = m.eigenvalue_pairs[k]
            lam = (f"{fmt_num(l1.real)} and {fmt_num(l2.real)} (overdamped)" if m.overdamped[k]
                   else f"{fmt_num(l1.real)} ± {fmt_num(abs(l1.imag))} i")
            drows.append([str(k + 1), lam, fmt_num(m.damped_frequencies[k]), fmt_num(m.damping_ratios[k], 4)])
        out.append(table_html(["mode", "eigenvalues λ [1/s]", "damped ω [rad/s]", "damping ratio ζ"], drows,
                          numeric=(2, 3), caption="With the damping of section 1"))
    ctx.notes["modes"] = f"ω = {m.frequencies[0]:.6g}, {m.frequencies[1]:.6g} rad/s"

    out.append("<h3>The frequencies against α</h3>")
    if not p.uses_alpha:
        out.append(
            '<p class="callout warn">Not drawn: hinge 2\'s axis is given explicitly (<code>axis2</code>), so α does not '
            "enter this model and there is nothing to sweep. Without <code>axis2</code> (the skew is then α) the report "
            "shows how the frequencies depend on the skew angle.</p>")
        ctx.notes["sweep"] = "not applicable: axis2 given"
        return "\n".join(out)
    values = np.radians(np.linspace(0.0, 180.0, ctx.sweep_points))
    try:
        sw = sweep(p.replace(alpha=None), "alpha", values)
    except SkewpendError as exc:
        out.append(f'<p class="callout warn">The sweep over α failed: {esc(exc)}</p>')
        ctx.notes["sweep"] = "failed"
        return "\n".join(out)
    fig = plot_sweep(sw)
    ax = fig.axes[0]
    here = math.degrees(p.alpha) % 360.0
    if 0.0 <= here <= 180.0:
        ax.axvline(here, color="#1d7a3e", lw=1.4, ls=":", label=f"this report: α = {here:.4g}°")
        ax.legend(loc="best")
    out.append(figure_html(
        fig_png(fig),
        prose(f"Natural frequencies (top) and the directions of the mode shapes in the $(\\varphi, \\psi)$ plane (bottom) for "
           f"$\\alpha$ from 0 to 180° ({ctx.sweep_points} values), the other parameters as in section 1. Dashed: internal "
           r"resonances $\omega_2 = n\,\omega_1$; dotted green: this report's $\alpha$."),
        "natural frequencies against the skew angle alpha",
    ))
    if sw.resonances:
        items = []
        for r in sw.resonances:
            how = "crossed" if r.crossed else f"approached (ω₂/ω₁ = {fmt_num(r.ratio, 5)})"
            items.append(f"<li><b>{r.order}:1</b> {how} at α = {fmt_deg(r.value)}</li>")
        out.append(f"<p>Internal resonances ω₂/ω₁ = n (n = 1, 2, 3) along the sweep:</p><ul>{''.join(items)}</ul>")
        ctx.notes["sweep"] = ", ".join(f"{r.order}:1 at {math.degrees(r.value):.4g}°" for r in sw.resonances)
    else:
        out.append(f"<p>No internal resonance ω₂/ω₁ ≈ 1, 2 or 3 for α in 0..180° (within {sw.tolerance:g}·n).</p>")
        ctx.notes["sweep"] = "no internal resonance"
    return "\n".join(out)


# -- section 5: simulation ------------------------------------------------------------------------------
#: Where the live view goes in section 5's body (its poster, section 1's picture, is made later).
LIVE_SLOT = "<!--skewpend:live-view-->"


def section_simulation(ctx: Context) -> str:
    from ...numeric.simulation import simulate
    from .. import figures as F
    from ..style import settings_text
    from ..frontend import replay_data

    p, y0 = ctx.params, ctx.y0
    coords = p.coordinates  # the double pendulum's phi, psi; a chain's q1 … qn (its report: views.report.chain)
    sym = [_tex(c) for c in coords]
    dt_out = max(FIGURE_DT, ctx.t_end / FIGURE_MAX_ROWS)
    kw: Dict[str, object] = dict(method=ctx.method, rtol=ctx.rtol, atol=ctx.atol, dt=ctx.dt)
    if ctx.max_steps is not None:
        kw["max_steps"] = int(ctx.max_steps)
    if ctx.method in ("rk4", "gauss"):  # rows on the integrator's fixed step grid
        step = ctx.dt if ctx.dt is not None else 1e-3
        dt_out = max(step, round(dt_out / step) * step)
    t0 = time.perf_counter()
    tr = simulate(p, y0, ctx.t_end, dt_out=min(dt_out, ctx.t_end), progress=telling("integrating", "s"), **kw)
    ctx.timings["simulation: integration"] = time.perf_counter() - t0
    st = tr.stats
    if st.get("kernel") == "compiled":
        built = st.get("kernel_build_time")
        kernel = "generated and compiled in this run" + (f" ({built:.2f} s), now cached" if built else "")
    else:
        kernel = "loaded from the cache"
    ctx.notes["kernel"] = kernel
    fin = tr.final_state
    status = ("finished" if tr.success else
              f'<span class="verdict bad">stopped early at t = {fmt_num(tr.t[-1])} s: {esc(tr.message)}</span>')
    out = [prose(
        f"<p>The nonlinear equations of section 2, integrated from the initial state of section 1 over {fmt_num(ctx.t_end)} s "
        f"with {esc(settings_text(tr.method, tr.settings))}, by compiled C generated from the derivation. "
        r"$E$ is the energy, $W$ the work done by damping, Coulomb friction and torques; $E - W$ is conserved.</p>")]
    out.append(facts_html([
        ("status", status),
        ("energy drift", f"{fmt_num(tr.energy_drift, 3)} &nbsp;<span class=\"note\">(largest |E − W − E₀| / max |E| over every row)</span>"),
        ("initial energy E₀", f"{fmt_num(tr.energy[0], 8)} J"),
        ("final state", _final_state(fin, coords) + f" at t = {fmt_num(tr.t[-1])} s"),
        ("steps", f"{st['steps']} accepted, {st.get('rejected', 0)} rejected, {st['nfev']} evaluations of the equations"),
        ("integration time", f"{st['wall_time'] * 1e3:.2f} ms"),
        ("model code", kernel),
    ]))
    ctx.notes["energy_drift"] = f"{tr.energy_drift:.3e}"
    t0 = time.perf_counter()
    few = len(sym) <= 2  # every angle named in the captions (more: the first, the last, "each joint")
    angles = f"${', '.join(sym)}$" if few else f"${sym[0]}, \\dots, {sym[-1]}$"
    figs = [
        (F.angles_figure, prose(f"The hinge angles {angles} (unwrapped, degrees) and their speeds against time."),
         "hinge angles and speeds against time"),
        (F.energy_figure, prose(r"Energy error $|E - W - E_0| / \max|E|$ on a log scale; dashed: the reported drift ")
         + fmt_num(tr.energy_drift, 3) + ".", "relative energy error against time"),
        (F.phase_figure, prose("Phase portraits " + (" and ".join(f"$({x}, \\dot{{{x}}})$" for x in sym) if few else
                                                     r"$(q_i, \dot q_i)$ of each joint") + ", angles wrapped to ±180°."),
         "phase portraits"),
        (F.torus_figure, prose((f"The path in configuration space: $({sym[0]}, {sym[1]})$" if few else
                                f"The path in the plane of the first two angles $({sym[0]}, {sym[1]})$")
                               + " wrapped to ±180°, opposite edges identified (a torus)."), "path on the configuration torus"),
        (F.tips_figure, prose(("Paths of both rod ends" if few else "The path of the chain's tip")
                              + r" in 3D; the pendulum hangs down, $z$ is the first hinge axis $\underline{k}$."),
         "3D paths of the rod ends"),
    ]
    for k, (make, caption, alt) in enumerate(figs, 1):
        detail(f"figure {k} of {len(figs)}: {alt}")
        out.append(figure_html(fig_png(make(tr)), caption, alt))
    ctx.timings["simulation: figures"] = time.perf_counter() - t0

    # the live view: the first clip_seconds of the same motion, one row per frame (dense output),
    # replayed in the browser from the rod ends and hinge axes the library computes at each frame
    t0 = time.perf_counter()
    frame = 1.0 / ctx.fps
    clip_t = max(frame, math.floor(ctx.clip_seconds / frame + 1e-9) * frame)
    clip_kw = {"max_steps": int(ctx.max_steps)} if ctx.max_steps is not None else {}
    detail("the live view's frames")
    ctx.clip = clip = simulate(p, y0, clip_t, dt_out=frame, method="dop853", **clip_kw)
    ctx.live = replay_data(clip)
    ctx.timings["simulation: live view"] = time.perf_counter() - t0
    ctx.notes["clip"] = (f"{fmt_num(clip.t[-1])} s of motion, {clip.t.size} frames at {ctx.fps:g} per second, "
                         f"replayed live in 3D ({ctx.clip_size[0]}×{ctx.clip_size[1]} px)")
    out.append(LIVE_SLOT)
    return "\n".join(out)


#: The coordinates' symbols the report writes (TeX, text) where the specification names them (the double
#: pendulum's); any other coordinate ``q<k>`` is written ``q_{k}`` and ``q<k>``.
TEX = {"phi": r"\varphi", "psi": r"\psi"}
TEXT = {"phi": "φ", "psi": "ψ"}


def _tex(c: str) -> str:
    stem = c.rstrip("0123456789")
    return TEX.get(c, f"{stem}_{{{c[len(stem):]}}}" if stem != c else c)


def _final_state(fin, coordinates) -> str:
    """The final state in words: each angle (``φ``, ``ψ``; a chain's ``q1 … qn``), and the speeds of up to two
    (a longer chain's left to the figures)."""
    n = len(coordinates)
    names = [TEXT.get(c, c) for c in coordinates]
    angles = [f"{name} = {fmt_deg(fin[k])}" for k, name in enumerate(names)]
    speeds = [f"{name}\u0307 = {fmt_num(fin[n + k], 5)} rad/s" for k, name in enumerate(names)] if n <= 2 else []
    return ", ".join(angles + speeds)


def live_figure(ctx: Context) -> str:
    clip = ctx.clip
    n = ctx.params.n
    if n <= 2:  # each rod and axis named
        what = ("both rods, both hinge axes (green: the roof's, yellow: the second, turning with rod 1) and the trail of "
                "rod 2's tip") if n > 1 else "the rod, its hinge axis (green) and the trail of its tip"
    else:
        what = (f"all {n} rods, their hinge axes (green: the roof's; the others turn with the links above them) "
                "and the trail of the last rod's tip")
    return live_view_html(
        ctx.live,
        f"The first {fmt_num(clip.t[-1])} s of the motion, replayed in real time in 3D from the computed states "
        f"({ctx.fps:g} frames per second; drag to turn the view, scroll to zoom, the slider picks a moment): " + what
        + (" (computed by DOP853, whose dense output gives the states at the frame times)" if ctx.method != "dop853" else "")
        + ". A video of the motion: <code>skewpend animate</code>.",
        ctx.still, ctx.clip_size,
    )
