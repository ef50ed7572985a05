"""Sections 1, 4 and 5 of the report: the system, its normal modes, a simulation -- for any model: each asks
the model its coordinates, its links and the names it answers."""

from __future__ import annotations

import math
import time
from typing import Dict, List

import numpy as np

from ... import schema
from ...errors import SkewpendError
from ...symbolic.model import Parameters

from .common import (FIGURE_DT, FIGURE_MAX_ROWS, LONG_SWEEP_POINTS, PICTURE_SIZE, SWEEP_POINTS, SWEEP_POINTS_BY_LINKS,
                     Context, answers_names, array_tex, by_links, detail, display_math, esc, facts_html, fig_png,
                     figure_html, fmt_deg, fmt_num, inline_math, live_view_html, prose, rgb_png, table_html, telling)


# -- section 1: the system ------------------------------------------------------------------------
def _unit(unit: str) -> str:
    return f'<span class="unit">{unit}</span>' if unit and unit != "1" else ""


def _vec_text(v, digits: int = 5) -> str:
    return "(" + ", ".join(fmt_num(x, digits) for x in v) + ")"


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
    """The table's rows of a model that answers the schema's names: each name's symbol, meaning, value and unit."""
    rows = []
    for name in table_scalars(p) + list(schema.GEOMETRY_NAMES):
        value, unit, field = getattr(p, name), schema.unit(name), schema.field(name)
        if name not in schema.GEOMETRY_NAMES:
            shown = fmt_num(value)
            if value is not None and field.bound == "angle":
                shown, unit = f"{fmt_deg(value)} = {fmt_num(value)} rad", ""
        elif value is None:
            shown = f'<span class="note">default: {esc(schema.default_text(name))}</span>'
        elif field.kind == "inertia":
            shown = "<br>".join(_vec_text(r) for r in value)
        else:
            shown = _vec_text(value) + (" (unit vector)" if name in schema.AXIS_NAMES else "")
        rows.append([inline_math(schema.tex(name)), f"<code>{name}</code>", esc(schema.meaning(name)), shown,
                     _unit(unit)])
    return rows


#: The per-joint terms of the links' table, shown when a link has one: (key, header).
_JOINT_TERMS = (("damping", "damping [N m s]"), ("coulomb", "Coulomb [N m]"), ("torque", "torque [N m]"),
                ("rotor", "rotor [kg m²]"))


def _links_table(model) -> str:
    """The table of a model told by its links: each hinge's axis and place, each body's length, mass, centre of
    mass and principal inertias, and the joints' terms that some link has."""
    chain = model.as_chain()
    terms = [(key, head) for key, head in _JOINT_TERMS if any(getattr(link, key) for link in chain.links)]
    head = ["link", "hinge axis<br>(unit)", "hinge at<br>[m]", "l [m]", "m [kg]", "centre of<br>mass [m]",
            "principal<br>inertias [kg m²]"] + [h.replace(" [", "<br>[") for _, h in terms]
    rows = []
    for link in chain.links:
        principal = np.linalg.eigvalsh(np.array(link.inertia, dtype=float))
        row = [str(link.index), _vec_text(link.axis, 4), _vec_text(link.offset, 4), fmt_num(link.length),
               fmt_num(link.mass), _vec_text(link.com, 4), _vec_text(principal, 4)]
        for key, _ in terms:
            row.append(fmt_num(getattr(link, key)) + (f" (gear {fmt_num(link.gear)})" if key == "rotor" and link.rotor
                                                      else ""))
        rows.append(row)
    none = [h.split(" [")[0] for k, h in _JOINT_TERMS if (k, h) not in terms]
    return table_html(head, rows, numeric=(3, 4, *range(7, 7 + len(terms))),
                      caption="The links (SI units): each hinge's axis and position and each body's centre of mass and "
                              "inertia in the frame of the link before it (the roof's for link 1), with the chain hanging"
                              + (f"; no link has {', '.join(none)}" if none else ""))


def conservation_text(p) -> str:
    """Whether the model conserves its energy, in a sentence: if not, the terms that make it so -- by the
    schema's meanings where the model answers its names (:attr:`Parameters.nonconservative_terms`), else by
    what its links have."""
    if p.conservative:
        return prose(r"No damping, friction or torques: the energy $T + \Pi$ is conserved.")
    if answers_names(p):
        terms = [schema.meaning(n) for n in p.nonconservative_terms]
    else:
        links = p.as_chain().links
        terms = [name for name, key in (("viscous damping", "damping"), ("Coulomb friction", "coulomb"),
                                        ("constant torques", "torque")) if any(getattr(link, key) for link in links)]
    return "Not conservative: " + esc(", ".join(terms)) + " (values below)."


def still_png(tr) -> bytes:
    """Frame 0 of ``tr`` as drawn by the animation (rods, the hinge axes, the angles between them)."""
    from ..animation import FrameRenderer

    r = FrameRenderer(tr, size=PICTURE_SIZE, dpi=100, trail=0.0)
    try:
        r.draw(0)
        return rgb_png(r.rgb())
    finally:
        r.close()


def rate_tex(c: str) -> str:
    r"""A coordinate's rate in TeX: ``\dot\varphi``, ``\dot q_{3}``."""
    t = tex(c)
    return r"\dot" + ("" if t.startswith("\\") else " ") + t


def start_tex(c: str, dot: bool = False) -> str:
    r"""A coordinate's value (``dot``: its rate's) at the start, in TeX: ``\varphi_0``, ``\dot\varphi_0``,
    ``q_{3}(0)``, ``\dot q_{3}(0)``."""
    return (rate_tex(c) if dot else tex(c)) + ("(0)" if "_" in tex(c) else "_0")


def section_system(ctx: Context) -> str:
    from ...numeric.simulation import simulate

    p, y0, n = ctx.params, ctx.y0, ctx.params.n
    named = answers_names(p)
    sym = [tex(c) for c in p.coordinates]
    rods = schema.count_text(n, "rods") if n > 2 else "both rods"
    what, axes_drawn = "pendulum" if named else "chain", "its" if n > 2 else "both"
    # the reference configuration, for its picture (the report's own method: no other kernel compiled)
    detail("picture 1 of 2: the model hanging at rest")
    rest_png = still_png(simulate(p, (0.0,) * (2 * n), 0.01, dt_out=0.01, method="dop853"))
    detail("picture 2 of 2: the model at the start")
    ctx.still = still_png(ctx.clip)
    if named and p.uses_alpha and p.axis1 is None:
        skew = prose(r"the hinge axes $\underline{k}$ and $\underline{e}_0$ make the angle $\alpha$ = ") + fmt_deg(p.alpha)
    else:
        skew = "the hinge axes are those given in the table below"
    zero = f"${' = '.join(sym)} = 0$" if n <= 3 else "$q_1 = \\dots = q_{" + str(n) + "} = 0$"
    axes = ("Green: hinge 1's axis (fixed); each further hinge's axis in its rod's colour at its joint; the arcs mark the "
            "angles between consecutive axes." if n > 2 else
            "Green: hinge 1's axis (fixed); magenta: hinge 2's axis; the arc marks the angle between them.")
    fig_rest = figure_html(rest_png, prose(f"Reference configuration {zero}: {rods} hang along $\\underline{{j}}$ (down) and ")
                           + skew + ". " + axes, f"the {what} hanging at rest, with {axes_drawn} hinge axes drawn")
    shown = min(n, 3)
    start = ", ".join(prose(f"${start_tex(c)}$ = ") + fmt_deg(y0[k]) for k, c in enumerate(p.coordinates[:shown]))
    start += "" if n == shown else " … (the table below)"
    turned = (prose(r". The second axis $\underline{e} = \underline{\underline{P}}_1\cdot\underline{e}_0$ has turned with rod 1.")
              if named else ". Each hinge's axis turns with the links above it.")
    fig_start = figure_html(ctx.still, "The initial state of the simulation (section 5): " + start + turned,
                            f"the {what} in its initial state, with {axes_drawn} hinge axes drawn")
    if named and p.is_thin_rods:
        intro = prose(
            r'<p class="lead">A rod hangs from the roof on a cylindrical hinge; a second rod hangs from the end of the first '
            r"on another cylindrical hinge whose axis, when both rods are vertical, makes the angle $\alpha$ with the first "
            r"hinge's axis. Find the equations of motion — and what they predict.</p>")
    elif named:
        intro = ('<p class="lead">Two rigid bodies hang in a chain on two cylindrical hinges whose axes are given below — the '
                 "specification's rods generalised to arbitrary bodies and axes. Find the equations of motion — and what "
                 "they predict.</p>")
    else:
        intro = (f'<p class="lead">{n} rigid bodies hang in a chain, each on a cylindrical hinge carried by the one above; '
                 "each hinge's axis is given in the frame of the link that carries it, with the chain hanging — the "
                 "specification's two skewed hinges generalised to a chain of any length. Find the equations of motion — "
                 "and what they predict.</p>")
    if n <= 3:  # (a report draws two links or more)
        names = [f"${s}$ (hinge {k})" for k, s in enumerate(sym, 1)]
        coords = (", ".join(names[:-1]) + " and " + names[-1]
                  + f", {'all' if n > 2 else 'both'} zero with the rods hanging")
    else:
        coords = (r"$q_1, \dots, q_n$ — $q_i$ the turn of link $i$ relative to link $i - 1$ — all zero with the chain "
                  "hanging")
    roof = "" if p.as_chain().links[0].axis == (0.0, 0.0, 1.0) else " in the specification's case"
    basis = prose(
        r"<p>Basis $\underline{i}, \underline{j}, \underline{k}$: $\underline{j}$ points <b>down</b> (along "
        + ("the rods" if n > 2 else "both rods") + r" when they hang), $\underline{k}$ is the axis of the roof hinge"
        + roof + r", $\underline{i}$ completes the right-handed triple. The generalised coordinates are the hinge angles "
        + coords + r"; gravity acts along $+\underline{j}$. " + conservation_text(p) + "</p>")
    table = (table_html(["symbol", "name", "meaning", "value", "unit"], _parameter_rows(p), caption="Parameters (SI units)")
             if named else _links_table(p))
    rows = [[inline_math(start_tex(c)), f"{fmt_deg(y0[k])} = {fmt_num(y0[k])} rad", ""] for k, c in enumerate(p.coordinates)]
    rows += [[inline_math(start_tex(c, dot=True)), fmt_num(y0[n + k]), "rad/s"] for k, c in enumerate(p.coordinates)]
    initial = table_html(["", "value", "unit"], rows, caption="Initial state of the simulation (section 5)", compact=True)
    return intro + basis + f'<div class="figure-row">{fig_rest}{fig_start}</div>' + table + initial


# -- section 4: normal modes -------------------------------------------------------------------------
SUBSCRIPTS = str.maketrans("0123456789", "₀₁₂₃₄₅₆₇₈₉")


def _skews(p) -> List[str]:
    """The skews of the model's hinges a sweep varies: the skew angle alpha where the model answers it and it sets
    hinge 2's axis, else each hinge's tilt below the roof (``tilt2`` … ``tiltn``); none for a model that answers
    the names but whose hinge 2 has an axis given (``axis2``: alpha does not enter it)."""
    if answers_names(p):
        return ["alpha"] if p.uses_alpha else []
    return [f"tilt{i}" for i in range(2, p.n + 1)]


def _here(p, name: str):
    """The model's own value of the swept skew [deg], or None (a tilted axis out of the (k, i) plane)."""
    if name == "alpha":
        return math.degrees(p.alpha) % 360.0
    axis = p.as_chain().links[int(name[4:]) - 1].axis
    return math.degrees(math.atan2(axis[0], axis[2])) if abs(axis[1]) < 1e-12 else None


def section_modes(ctx: Context) -> str:
    from ...analysis.modes import normal_modes, sweep
    from ..figures import plot_sweep

    p, n = ctx.params, ctx.params.n
    text = [label(c) for c in p.coordinates]
    detail("the normal modes")
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
    damping = r"C_0 = " + array_tex(m.C) + r"\ \mathrm{N\,m\,s}"
    if m.damped and n <= 2:
        mats += r",\qquad " + damping
    out.append(display_math(mats) + (display_math(damping) if m.damped and n > 2 else ""))
    out.append(prose(
        r"<p>A normal mode $q = v\cos(\omega t - \delta)$ solves $K_0\,v = \omega^2 M_0\,v$: the "
        + schema.count_text(n, "values") + r" of $\omega^2$ are the roots of $\det(K_0 - \omega^2 M_0) = 0$, and the "
        r"shapes $v$ are normalised with $v^T M_0\, v = 1$.</p>"))
    rows = []
    for k in range(n):
        ratio = "∞" if not np.isfinite(m.ratios[k]) else fmt_num(m.ratios[k], 5)
        rows.append([str(k + 1), fmt_num(m.frequencies[k]), fmt_num(m.frequencies[k] / (2 * np.pi)), fmt_num(m.periods[k]),
                     _vec_text(m.shapes[:, k]), ratio])
    shape = ", ".join(text) if n <= 3 else f"{text[0]} … {text[-1]}"
    out.append(table_html(["mode", "ω [rad/s]", "f [Hz]", "period [s]", f"shape ({shape})", f"{text[-1]}/{text[0]}"], rows,
                          numeric=(1, 2, 3, 5), caption="Normal modes (undamped)"))
    if n > 1:
        beat = "∞ (equal frequencies)" if not np.isfinite(m.beat_period) else f"{fmt_num(m.beat_period)} s"
        out.append(facts_html([("frequency ratio ω₂/ω₁", fmt_num(m.frequencies[1] / m.frequencies[0])),
                               ("beat period 2π/(ω₂ − ω₁)", beat)]))
    if m.damped:
        drows = []
        for k in range(n):
            l1, l2 = m.eigenvalue_pairs[k]
            lam = (f"{fmt_num(l1.real)} and {fmt_num(l2.real)} (overdamped)" if m.overdamped[k]
                   else f"{fmt_num(l1.real)} ± {fmt_num(abs(l1.imag))} i")
            drows.append([str(k + 1), lam, fmt_num(m.damped_frequencies[k]), fmt_num(m.damping_ratios[k], 4)])
        out.append(table_html(["mode", "eigenvalues λ [1/s]", "damped ω [rad/s]", "damping ratio ζ"], drows,
                              numeric=(2, 3), caption="With the damping of section 1"))
    ctx.notes["modes"] = "ω = " + ", ".join(f"{w:.6g}" for w in m.frequencies) + " rad/s"
    skews = _skews(p)
    alpha = skews == ["alpha"]
    out.append("<h3>The frequencies against α</h3>" if alpha or not skews else
               "<h3>The frequencies against each hinge's tilt</h3>")
    if not skews:
        out.append(
            '<p class="callout warn">Not drawn: hinge 2\'s axis is given explicitly (<code>axis2</code>), so α does not '
            "enter this model and there is nothing to sweep. Without <code>axis2</code> (the skew is then α) the report "
            "shows how the frequencies depend on the skew angle.</p>")
        ctx.notes["sweep"] = "not applicable: axis2 given"
        return "\n".join(out)
    if not alpha:
        out.append(prose(
            "<p>The skew of the specification, for each hinge below the roof: hinge $i$'s axis tilted by an angle "
            r"$\beta$ from $\underline{k}$ towards $\underline{i}$, $\underline{e}_{i0} = \cos\beta\,\underline{k} + "
            r"\sin\beta\,\underline{i}$ (the specification's $\alpha$ for $i = 2$), from 0 to 180°, the rest of the chain "
            "as in section 1.</p>"))
    points = ctx.sweep_points or by_links(n, SWEEP_POINTS, SWEEP_POINTS_BY_LINKS, LONG_SWEEP_POINTS)
    values = np.radians(np.linspace(0.0, 180.0, points))
    pairs = "ω₂/ω₁" if n <= 2 else "ωₖ₊₁/ωₖ"
    notes = []
    for k, name in enumerate(skews, 1):
        what = "α" if alpha else f"hinge {name[4:]}'s tilt"
        detail(f"{what}: {points} values (sweep {k} of {len(skews)})")
        try:
            sw = sweep(p.replace(alpha=None) if alpha else p, name, values)
        except SkewpendError as exc:
            out.append(f'<p class="callout warn">The sweep over {what} failed: {esc(exc)}</p>')
            notes.append(f"{name}: failed")
            continue
        fig = plot_sweep(sw)
        here = _here(p, name)
        if here is not None and 0.0 <= here <= 180.0:
            fig.axes[0].axvline(here, color="#1d7a3e", lw=1.4, ls=":", label=f"this report: {'α = ' if alpha else ''}{here:.4g}°")
            fig.axes[0].legend(loc="best")
        if alpha:
            caption = prose(f"Natural frequencies (top) and the directions of the mode shapes in the $(\\varphi, \\psi)$ "
                            f"plane (bottom) for $\\alpha$ from 0 to 180° ({points} values), the other parameters as in "
                            r"section 1. Dashed: internal resonances $\omega_2 = n\,\omega_1$; dotted green: this report's "
                            r"$\alpha$.")
        else:
            caption = (f"The {n} natural frequencies against hinge {name[4:]}'s tilt ({points} values), the rest of the "
                       "chain as in section 1; dashed: internal resonances of neighbouring modes; dotted green: this "
                       "chain's tilt when its axis lies in that plane.")
        out.append(figure_html(fig_png(fig), caption, f"natural frequencies against {'the skew angle alpha' if alpha else what}"))
        if sw.resonances:
            items = []
            for r in sw.resonances:
                i, j = r.pair
                ratio = f"ω{str(j).translate(SUBSCRIPTS)}/ω{str(i).translate(SUBSCRIPTS)}"
                how = "crossed" if r.crossed else f"approached ({ratio} = {fmt_num(r.ratio, 5)})"
                items.append(f"<li><b>{'' if n <= 2 else ratio + ' = '}{r.order}:1</b> {how} at "
                             f"{'α' if alpha else 'β'} = {fmt_deg(r.value)}</li>")
            out.append(f"<p>Internal resonances {pairs} = n (n = 1, 2, 3) along the sweep:</p><ul>{''.join(items)}</ul>")
            notes.append(", ".join(f"{r.order}:1 at {math.degrees(r.value):.4g}°" for r in sw.resonances))
        else:
            out.append(f"<p>No internal resonance {pairs} ≈ 1, 2 or 3 for {what} in 0..180° (within {sw.tolerance:g}·n).</p>")
            notes.append("no internal resonance")
    ctx.notes["sweep"] = "; ".join(notes) if alpha else "; ".join(f"{s}: {t}" for s, t in zip(skews, notes))
    ctx.notes["sweep points"] = str(points)
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
    sym = [tex(c) for c in coords]
    dt_out = max(FIGURE_DT, ctx.t_end / FIGURE_MAX_ROWS)
    steps_kw = {"max_steps": int(ctx.max_steps)} if ctx.max_steps is not None else {}
    kw: Dict[str, object] = dict(method=ctx.method, rtol=ctx.rtol, atol=ctx.atol, dt=ctx.dt, **steps_kw)
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
        f"with {esc(settings_text(tr.method, tr.settings))}, by compiled C generated from the model. "
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
    detail("the live view's frames")
    ctx.clip = clip = simulate(p, y0, clip_t, dt_out=frame, method="dop853", **steps_kw)
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


def label(c: str) -> str:
    """A coordinate's symbol in text: ``φ``, ``ψ``; ``q₃``."""
    stem = c.rstrip("0123456789")
    return TEXT.get(c, stem + c[len(stem):].translate(SUBSCRIPTS))


def tex(c: str) -> str:
    stem = c.rstrip("0123456789")
    return TEX.get(c, f"{stem}_{{{c[len(stem):]}}}" if stem != c else c)


def _final_state(fin, coordinates) -> str:
    """The final state in words: each angle (``φ``, ``ψ``; a chain's ``q1 … qn``), and the speeds of up to two
    (a longer chain's left to the figures)."""
    n = len(coordinates)
    names = [label(c) for c in coordinates]
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
