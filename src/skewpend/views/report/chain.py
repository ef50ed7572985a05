"""The report of a chain of links (:func:`skewpend.views.report.build_report` given a
:class:`~skewpend.symbolic.chain.Chain`; ``skewpend report --config`` with ``[[links]]``).

The same worked solution as the double pendulum's, for a chain of any length, from the same library
calls: the system (pictures, the links' table), the equations of motion by rotation tensors and
Lagrange's equations (displayed up to :data:`SYMBOLIC_MAX_LINKS` links; longer chains' are the recursive
algorithms' code, shown as what it is), their check against the recursive algorithms the kernels compile
(two derivations of one model, compared at random states), the normal modes and their dependence on each
hinge's tilt, a simulation with its figures and the live 3D view, the flip-time map over ``(q1, q2)``,
the Lyapunov spectrum (2 n exponents), every equilibrium with its stability and the nonlinear normal
modes, and the comparison with MuJoCo.  What is two-dimensional by definition (Poincare sections, the
chaos diagram) is the double pendulum's and is not drawn for a chain.
"""

from __future__ import annotations

import math
import time
from typing import Dict, List

import numpy as np

from ...errors import SkewpendError
from .common import (CHAOS_LYAPUNOV_T_END, FIGURE_DT, FIGURE_MAX_ROWS, FLIPMAP_T_END, VALIDATION_DT, VALIDATION_T_END,
                     VALIDATION_TOL, Context, display_math, esc, facts_html, fig_png, figure_html, fmt_deg, fmt_num,
                     inline_math, prose, table_html, detail, telling)

#: (id, title) of a chain report's sections, in order.
CHAIN_SECTIONS = (
    ("system", "The system"),
    ("derivation", "Equations of motion, step by step"),
    ("check", "Check: two derivations of one model"),
    ("modes", "Small oscillations: normal modes"),
    ("simulation", "Simulation"),
    ("flipmap", "Which starts flip: the flip-time map"),
    ("chaos", "How chaotic: the Lyapunov spectrum"),
    ("orbits", "Beyond small oscillations: equilibria and nonlinear normal modes"),
    ("validation", "Validation against MuJoCo"),
    ("provenance", "How this report was made"),
)
#: The longest chain whose equations the report derives and displays by SymPy (four links take
#: 45 s and expressions of thousands of terms; the recursive algorithms serve any length).
SYMBOLIC_MAX_LINKS = 3
#: Digits of the floating-point numbers in the displayed expressions, and the longest one displayed (LaTeX
#: characters; a longer one is named by its size).
DISPLAY_DIGITS = 4
DISPLAY_MAX_CHARS = 2400
#: Random states at which the two derivations are compared, and the agreement required (relative).
CHECK_STATES = 20
CHECK_TOL = 1e-11
#: The flip map of a chain: cells per side (each start a run of FLIPMAP_T_END seconds); past
#: :data:`SHORT_CHAIN` links, :data:`LONG_FLIPMAP_N` (the work grows with the links: 16 s for 96 x 96 at six).
CHAIN_FLIPMAP_N = 96
LONG_FLIPMAP_N = 64
SHORT_CHAIN = 3
#: Values of each tilt in 0..180 deg for the frequency curves (fewer past SHORT_CHAIN links: a sweep a hinge).
CHAIN_SWEEP_POINTS = 61
LONG_SWEEP_POINTS = 31
#: The Lyapunov run past SHORT_CHAIN links [s] (2 n tangent vectors).
LONG_LYAPUNOV_T_END = 200.0
#: Orbits per family of nonlinear normal modes.
CHAIN_NNM_RESOLUTION = 40
#: The chains whose nonlinear normal modes the report follows (each family is a continuation of
#: shooting problems of 2 n + 1 unknowns).
CHAIN_NNM_MAX_LINKS = 4
#: What each part of a chain report is, as said when it begins.
CHAIN_PARTS = {
    "simulation": "section 5, the simulation",
    "system": "section 1, pictures of the chain",
    "derivation": "section 2, the equations of motion (SymPy)",
    "check": "section 3, the derivation against the recursive algorithms",
    "modes": "section 4, the normal modes against each hinge's tilt",
    "flipmap": "section 6, the flip-time map",
    "chaos": "section 7, the Lyapunov spectrum",
    "orbits": "section 8, equilibria and nonlinear normal modes",
    "validation": "section 9, the comparison with MuJoCo",
}


def _q(k: int) -> str:
    return f"q_{{{k}}}"


def _vec(v, digits: int = 4) -> str:
    return "(" + ", ".join(fmt_num(x, digits) for x in v) + ")"


# -- section 1 --------------------------------------------------------------------------------------------
#: The per-joint terms of the links' table, shown when a link has one: (key, header).
_JOINT_TERMS = (("damping", "damping [N m s]"), ("coulomb", "Coulomb [N m]"), ("torque", "torque [N m]"),
                ("rotor", "rotor [kg m²]"))


def _links_table(chain) -> str:
    terms = [(key, head) for key, head in _JOINT_TERMS if any(getattr(link, key) for link in chain.links)]
    head = ["link", "hinge axis (unit)", "hinge at [m]", "l [m]", "m [kg]", "centre of mass [m]",
            "principal inertias [kg m²]"] + [h for _, h in terms]
    rows = []
    for link in chain.links:
        principal = np.linalg.eigvalsh(np.array(link.inertia, dtype=float))
        row = [str(link.index), _vec(link.axis), _vec(link.offset), fmt_num(link.length), fmt_num(link.mass),
               _vec(link.com), _vec(principal)]
        for key, _ in terms:
            row.append(fmt_num(getattr(link, key)) + (f" (gear {fmt_num(link.gear)})" if key == "rotor" and link.rotor
                                                      else ""))
        rows.append(row)
    none = [h.split(" [")[0] for k, h in _JOINT_TERMS if (k, h) not in terms]
    return table_html(head, rows, numeric=(3, 4, *range(7, 7 + len(terms))),
                      caption="The links (SI units): each hinge's axis and position and each body's centre of mass and "
                              "inertia in the frame of the link before it (the roof's for link 1), with the chain hanging"
                              + (f"; no link has {', '.join(none)}" if none else ""))


def _conservation_text(chain) -> str:
    terms = [name for name, on in (("viscous damping", any(link.damping for link in chain.links)),
                                   ("Coulomb friction", chain.has_friction),
                                   ("constant torques", any(link.torque for link in chain.links))) if on]
    if not terms:
        return prose(r"No damping, friction or torques: the energy $T + \Pi$ is conserved.")
    return "Not conservative: " + ", ".join(terms) + " (values below)."


def section_system(ctx: Context) -> str:
    from ...numeric.simulation import simulate
    from .system import still_png

    chain, y0, n = ctx.params, ctx.y0, ctx.params.n
    detail("picture 1 of 2: the chain hanging at rest")
    rest = simulate(chain, (0.0,) * (2 * n), 0.01, dt_out=0.01, method="dop853")
    ctx.still = still_png(ctx.clip)
    detail("picture 2 of 2: the chain at the start")
    fig_rest = figure_html(
        still_png(rest),
        prose(f"Reference configuration: all {n} rods hang along $\\underline{{j}}$ (down), every $q_i = 0$. "
              "Each hinge's axis is drawn at its joint (green: the roof's, fixed)."),
        "the chain hanging at rest, with its hinge axes drawn")
    start = ", ".join(f"{inline_math(_q(k + 1) + '(0)')} = {fmt_deg(y0[k])}" for k in range(n))
    fig_start = figure_html(ctx.still, "The initial state of the simulation (section 5): " + start
                            + ". Each hinge's axis turns with the links above it.",
                            "the chain in its initial state, with its hinge axes drawn")
    intro = (f'<p class="lead">{n} rigid bodies hang in a chain, each on a cylindrical hinge carried by the one above; '
             "each hinge's axis is given in the frame of the link that carries it, with the chain hanging — the "
             "specification's two skewed hinges generalised to a chain of any length. Find the equations of motion — "
             "and what they predict.</p>")
    basis = prose(
        r"<p>Basis $\underline{i}, \underline{j}, \underline{k}$: $\underline{j}$ points <b>down</b> (along the rods when "
        r"they hang), $\underline{k}$ is the axis of the roof hinge in the specification's case, $\underline{i}$ completes "
        r"the right-handed triple. The generalised coordinates are the hinge angles $q_1, \dots, q_n$ — $q_i$ the turn of "
        r"link $i$ relative to link $i - 1$ — all zero with the chain hanging; gravity $g$ = " + fmt_num(chain.g)
        + r" m/s² acts along $+\underline{j}$. " + _conservation_text(chain) + "</p>")
    table = _links_table(chain)
    rows = [[inline_math(_q(k + 1) + "(0)"), f"{fmt_deg(y0[k])} = {fmt_num(y0[k])} rad", ""] for k in range(n)]
    rows += [[inline_math(rf"\dot q_{{{k + 1}}}(0)"), fmt_num(y0[n + k]), "rad/s"] for k in range(n)]
    initial = table_html(["", "value", "unit"], rows, caption="Initial state of the simulation (section 5)", compact=True)
    return intro + basis + f'<div class="figure-row">{fig_rest}{fig_start}</div>' + table + initial


# -- sections 2 and 3 -------------------------------------------------------------------------------------
def _chain_names(eom) -> Dict:
    from ...symbolic.derivation import coordinate_symbol

    names = {}
    for i, c in enumerate(eom.coordinates, start=1):
        names[coordinate_symbol(c)] = f"q_{{{i}}}"
        names[coordinate_symbol("d" + c)] = rf"\dot q_{{{i}}}"
        names[coordinate_symbol("dd" + c)] = rf"\ddot q_{{{i}}}"
    return names


def section_derivation(ctx: Context) -> str:
    import sympy as sp

    chain, n = ctx.params, ctx.params.n
    method = prose(
        "<p>The specification's method, link by link. Link $i$ turns by $q_i$ about its hinge's axis "
        r"$\underline{e}_{i0}$ (given with the chain hanging) relative to link $i - 1$: its rotation tensor is "
        r"$\underline{\underline{P}}_i = \underline{\underline{P}}_{i-1}\cdot\underline{\underline{P}}(q_i, "
        r"\underline{e}_{i0})$ with Rodrigues' tensor $\underline{\underline{P}}(q, \underline{e}) = "
        r"\underline{\underline{E}}\cos q + (1 - \cos q)\,\underline{e}\,\underline{e} + \underline{e}\times"
        r"\underline{\underline{E}}\sin q$; the hinge's current axis is $\underline{e}_i = \underline{\underline{P}}_{i-1}"
        r"\cdot\underline{e}_{i0}$ and the angular velocity $\underline{\omega}_i = \underline{\omega}_{i-1} + "
        r"\dot q_i\,\underline{e}_i$. Each body's centre of mass moves with the hinges above it; the kinetic energy is "
        r"$T = \sum_i \tfrac12 m_i v_{Ci}^2 + \tfrac12\,\underline{\omega}_i\cdot\underline{\underline{\Theta}}_i\cdot"
        r"\underline{\omega}_i$ (each inertia tensor turned by $\underline{\underline{P}}_i$), the potential "
        r"$\Pi = -\sum_i m_i\,g\,y_{Ci}$, and Lagrange's equations $\frac{d}{dt}\frac{\partial T}{\partial\dot q_i} - "
        r"\frac{\partial T}{\partial q_i} = -\frac{\partial\Pi}{\partial q_i} + Q_i$, with the generalised forces "
        r"$Q_i = \tau_i - c_i\,\dot q_i - c_{f,i}\arctan(c_{fs}\dot q_i)$, give $M(q)\,\ddot q = f(q, \dot q)$.</p>")
    if n > SYMBOLIC_MAX_LINKS:
        ctx.notes["derivation"] = f"not displayed ({n} links; SymPy displays up to {SYMBOLIC_MAX_LINKS})"
        return method + (
            f'<p class="callout">A chain of {n} links is past what this report derives and displays by SymPy (up to '
            f"{SYMBOLIC_MAX_LINKS} links: four already take about 45 s and expressions of thousands of terms). The "
            "numeric code is generated for any length from the same model by the recursive algorithms — the composite-"
            "rigid-body mass matrix and recursive Newton–Euler — as straight-line code (CasADi's graphs printed as C); "
            "<code>skewpend derive --config</code> prints them, section 9 checks them against MuJoCo.</p>")
    from ...symbolic.derivation import derive

    detail(f"deriving the equations of {n} links (SymPy)")
    eom = derive(chain)
    names = _chain_names(eom)
    long = []

    def t(expr, label: str = "") -> str:
        """LaTeX of ``expr`` with its floating-point numbers shown to DISPLAY_DIGITS digits; an expression past
        DISPLAY_MAX_CHARS is named by its size instead."""
        shown = expr.xreplace({x: sp.Float(x, DISPLAY_DIGITS) for x in expr.atoms(sp.Float)})
        text = sp.latex(shown, symbol_names=names)
        if len(text) > DISPLAY_MAX_CHARS:
            long.append(label)
            return rf"\text{{(an expression of {sp.count_ops(expr)} operations: not displayed)}}"
        return text

    out = [method, "<h3>Step by step, with the values of section 1</h3>"]
    labels = {"P": r"\underline{\underline{P}}", "e": r"\underline{e}", "omega": r"\underline{\omega}"}
    rows = []
    for key, value in eom.steps.items():
        if key in ("M", "f", "T", "Pi"):
            continue
        detail(f"typesetting the step {key}")
        stem = key.rstrip("0123456789")
        rows.append(f"{labels[stem]}_{{{key[len(stem):]}}} &= {t(value, key)}")
    out.append(display_math("\\begin{aligned}\n" + " \\\\\n".join(rows) + "\n\\end{aligned}"))
    detail("typesetting T and Pi")
    out.append(display_math(f"T = {t(eom.kinetic_energy, 'T')}"))
    out.append(display_math(rf"\Pi = {t(eom.potential_energy, 'Pi')}"))
    out.append(prose("<p>Lagrange's equations, $M(q)\\,\\ddot q = f(q, \\dot q)$, entry by entry:</p>"))
    M, f = eom.mass_matrix, eom.forcing
    for i in range(n):  # one block per row of M and its f: each scrolls on its own when wide
        detail(f"typesetting row {i + 1} of {n} of M and f")
        eqs = [f"M_{{{i + 1}{j + 1}}} &= {t(M[i, j], f'M{i + 1}{j + 1}')}" for j in range(i, n)]
        eqs.append(f"f_{{{i + 1}}} &= {t(f[i], f'f{i + 1}')}")
        out.append(display_math("\\begin{aligned}\n" + " \\\\\n".join(eqs) + "\n\\end{aligned}"))
    detail("linearising about the hanging rest")
    try:
        lin = eom.linearize()
    except SkewpendError as exc:
        out.append(f'<p class="note">Not linearised about q = 0: {esc(exc)}</p>')
    else:
        out.append(prose("<p>Linearised about the hanging rest $q = 0$: $M_0\\,\\ddot q + C_0\\,\\dot q + K_0\\,q = 0$ "
                         "with</p>"))
        parts = [f"M_0 = {t(lin.M.evalf())}", f"K_0 = {t(lin.K.evalf())}"]
        if lin.C != sp.zeros(n, n):
            parts.append(f"C_0 = {t(lin.C.evalf())}")
        out.append(display_math(r",\qquad ".join(parts)))
    ctx.eom = eom  # section 3 compares it with the recursive algorithms
    out.insert(2, f'<p class="note">Numbers are shown to {DISPLAY_DIGITS} digits; the derivation and section 3 use them in '
               "full" + (f"; {len(long)} expression{'s' if len(long) > 1 else ''} of more than {DISPLAY_MAX_CHARS} characters "
                          f"{'are' if len(long) > 1 else 'is'} named by {'their' if len(long) > 1 else 'its'} size "
                          "(<code>skewpend derive --config</code> prints every one)" if long else "") + ".</p>")
    ctx.notes["derivation"] = f"{n} links, exact (SymPy), with the values of section 1"
    return "\n".join(out)


def section_check(ctx: Context) -> str:
    import sympy as sp

    from ...numeric import kernels, recursive
    from ...symbolic.derivation import coordinate_symbol

    chain, n = ctx.params, ctx.params.n
    intro = prose(
        "<p>The simulations of this report do not use the expressions of section 2: the compiled code is generated from "
        "the same model by the <b>recursive algorithms</b> — the mass matrix by composite rigid bodies, the forces by "
        "recursive Newton–Euler — a second derivation with no rotation tensor composed symbolically. ")
    eom = ctx.eom
    if eom is None:
        ctx.notes["check"] = "against MuJoCo (section 9)"
        return intro + f"For {n} links the check is section 9's: the same model simulated by MuJoCo.</p>"
    K, p = kernels.chain_kernel(chain), recursive.parameter_vector(chain)
    symbols = [coordinate_symbol(c) for c in eom.coordinates] + [coordinate_symbol("d" + c) for c in eom.coordinates]
    detail("turning section 2's expressions into functions (SymPy's lambdify)")
    M, f = sp.lambdify(symbols, eom.mass_matrix), sp.lambdify(symbols, eom.forcing)
    E = sp.lambdify(symbols, eom.kinetic_energy + eom.potential_energy)
    rng = np.random.default_rng(2026)
    acc_err = energy_err = 0.0
    out = np.zeros(2 * n + 1)
    for k in range(CHECK_STATES):
        detail(f"random state {k + 1} of {CHECK_STATES}")
        y = np.r_[rng.uniform(-math.pi, math.pi, n), rng.normal(scale=2.0, size=n)]
        acc = np.linalg.solve(np.array(M(*y), float), np.array(f(*y), float).ravel())
        K.rhs(np.r_[y, 0.0], p, out)
        acc_err = max(acc_err, float(np.max(np.abs(out[n:2 * n] - acc)) / max(np.max(np.abs(acc)), 1e-300)))
        e_sym = float(E(*y))
        energy_err = max(energy_err, abs(K.energy(np.r_[y, 0.0], p) - e_sym) / max(abs(e_sym), 1e-300))
    ok = acc_err <= CHECK_TOL and energy_err <= CHECK_TOL
    verdict = (f'<p class="verdict {"ok" if ok else "bad"}">' + ("✓ The two derivations agree" if ok else
               "✗ The two derivations disagree") + f" at {CHECK_STATES} random states: accelerations to "
               f"{fmt_num(acc_err, 2)}, energies to {fmt_num(energy_err, 2)} (relative; required: {fmt_num(CHECK_TOL, 2)})"
               "</p>")
    ctx.notes["check"] = f"accelerations {acc_err:.1e}, energies {energy_err:.1e} at {CHECK_STATES} random states"
    return (intro + prose(f"Here both are evaluated at {CHECK_STATES} random states (angles uniform in ±180°, speeds "
                          "normal with a spread of 2 rad/s): the accelerations $M^{-1} f$ of section 2 against the "
                          "compiled code's, and the energies $T + \\Pi$.</p>") + verdict)


# -- section 4 --------------------------------------------------------------------------------------------
def section_modes(ctx: Context) -> str:
    from ...analysis.modes import normal_modes, sweep
    from ..figures import plot_sweep
    from .common import array_tex

    chain, n = ctx.params, ctx.params.n
    detail("the normal modes")
    try:
        m = normal_modes(chain)
        if not m.ok:
            raise SkewpendError(m.message)
    except SkewpendError as exc:
        ctx.notes["modes"] = "none (see section 4)"
        return (f'<p class="callout warn">No normal modes for this chain: {esc(exc)}</p>'
                "<p>Normal modes describe small oscillations about a stable hanging equilibrium.</p>")
    out = [prose(r"<p>Small oscillations about the hanging position obey $M_0\,\ddot q + C_0\,\dot q + K_0\,q = 0$; "
                 "with the values of section 1</p>"),
           display_math(r"M_0 = " + array_tex(m.M) + r"\ \mathrm{kg\,m^2},\qquad K_0 = " + array_tex(m.K)
                        + r"\ \mathrm{N\,m}"),
           prose(r"<p>A normal mode $q = v\cos(\omega t - \delta)$ solves $K_0\,v = \omega^2 M_0\,v$ "
                 f"({n} roots of $\\det(K_0 - \\omega^2 M_0) = 0$; shapes normalised with $v^T M_0\\,v = 1$).</p>")]
    rows = []
    for k in range(n):
        v = m.shapes[:, k]
        rows.append([str(k + 1), fmt_num(m.frequencies[k]), fmt_num(m.frequencies[k] / (2 * np.pi)), fmt_num(m.periods[k]),
                     _vec(v, 4)])
    out.append(table_html(["mode", "ω [rad/s]", "f [Hz]", "period [s]", "shape (q₁ … q" + str(n).translate(
        str.maketrans("0123456789", "₀₁₂₃₄₅₆₇₈₉")) + ")"], rows, numeric=(1, 2, 3), caption="Normal modes (undamped)"))
    ctx.notes["modes"] = "ω = " + ", ".join(f"{w:.6g}" for w in m.frequencies) + " rad/s"
    out.append("<h3>The frequencies against each hinge's tilt</h3>")
    out.append(prose(
        "<p>The skew of the specification, for each hinge below the roof: hinge $i$'s axis tilted by an angle "
        r"$\beta$ from $\underline{k}$ towards $\underline{i}$, $\underline{e}_{i0} = \cos\beta\,\underline{k} + "
        r"\sin\beta\,\underline{i}$ (the specification's $\alpha$ for $i = 2$), from 0 to 180°, the rest of the chain as "
        "in section 1.</p>"))
    points = CHAIN_SWEEP_POINTS if n <= SHORT_CHAIN else LONG_SWEEP_POINTS
    values = np.radians(np.linspace(0.0, 180.0, points))
    notes = []
    for i in range(2, n + 1):
        detail(f"hinge {i}'s tilt: {points} values (sweep {i - 1} of {n - 1})")
        try:
            sw = sweep(chain, f"tilt{i}", values)
        except SkewpendError as exc:
            out.append(f'<p class="callout warn">The sweep of hinge {i}\'s tilt failed: {esc(exc)}</p>')
            continue
        detail(f"hinge {i}'s tilt: the figure (sweep {i - 1} of {n - 1})")
        fig = plot_sweep(sw)
        axis = chain.links[i - 1].axis
        if abs(axis[1]) < 1e-12:  # this chain's own tilt, if its axis lies in the (k, i) plane
            here = math.degrees(math.atan2(axis[0], axis[2]))
            if 0.0 <= here <= 180.0:
                fig.axes[0].axvline(here, color="#1d7a3e", lw=1.4, ls=":", label=f"this chain: {here:.4g}°")
                fig.axes[0].legend(loc="best")
        res = "; ".join(f"ω{r.pair[1]}/ω{r.pair[0]} = {r.order} {'at' if r.crossed else 'near'} {fmt_deg(r.value)}"
                        for r in sw.resonances) or "no internal resonance ω_(k+1)/ω_k ≈ 1, 2, 3"
        out.append(figure_html(fig_png(fig), f"The {n} natural frequencies against hinge {i}'s tilt ({points} "
                               f"values; dashed: internal resonances, {esc(res)}; dotted green: this chain's tilt when "
                               "its axis lies in that plane).", f"natural frequencies against hinge {i}'s tilt"))
        notes.append(f"tilt{i}: {len(sw.resonances)} resonances")
    ctx.notes["sweep"] = f"{points} values a hinge: " + ", ".join(notes)
    return "\n".join(out)


# -- section 5 --------------------------------------------------------------------------------------------
def section_simulation(ctx: Context) -> str:
    from .system import section_simulation as simulation

    return simulation(ctx)  # the same library calls and figures serve any chain


# -- section 6 --------------------------------------------------------------------------------------------
def section_flipmap(ctx: Context) -> str:
    from ...analysis.flipmap import flip_map
    from ..figures import flipmap_figure

    chain, n = ctx.params, ctx.params.n
    cells = CHAIN_FLIPMAP_N if n <= SHORT_CHAIN else LONG_FLIPMAP_N
    try:
        fm = flip_map(chain, cells, t_end=FLIPMAP_T_END, progress=telling(f"{cells}×{cells} starts", "cells"))
    except SkewpendError as exc:
        ctx.notes["flipmap"] = "could not be computed"
        return f'<p class="callout warn">The flip-time map could not be computed: {esc(exc)}</p>'
    detail("the figure")
    fig = flipmap_figure(fm)
    flipped = float(fm.flipped_fraction)
    held = ("" if n == 2 else prose(f" The other {n - 2} angle" + ("s are" if n > 3 else " is")
                                    + " held at 0 (hanging) at release."))
    ctx.notes["flipmap"] = (f"{cells}×{cells} starts at rest over (q1, q2), {fmt_num(FLIPMAP_T_END)} s "
                            f"each, {fm.stats['wall_time']:.2f} s")
    return (prose(
        "<p>Released at rest from each cell of a grid of the first two angles $(q_1, q_2)$, how long until any hinge "
        f"angle first leaves $(-180°, 180°)$ — a rod going over the top? Each start is followed for {fmt_num(FLIPMAP_T_END)} s "
        "by the compiled DOP853 (many starts in one call); the time of the flip is located on the dense output.") + held
        + "</p>" + figure_html(fig_png(fig), prose(
            f"Flip time of {cells}&nbsp;×&nbsp;{cells} starts at rest over $(q_1, q_2)$ "
            f"(log colour scale); white: no flip within {fmt_num(FLIPMAP_T_END)} s"
            + f" ({fmt_num(100 * flipped, 3)} % of the starts flip)."),
            "flip-time map over the first two angles"))


# -- section 7 --------------------------------------------------------------------------------------------
def section_chaos(ctx: Context) -> str:
    import warnings

    from ...analysis.lyapunov import lyapunov
    from ...status import Status
    from .. import figures as F

    chain, y0, n = ctx.params, ctx.y0, ctx.params.n
    horizon = CHAOS_LYAPUNOV_T_END if n <= SHORT_CHAIN else LONG_LYAPUNOV_T_END
    out = [prose(
        f"<p>Chaos, measured. The <b>Lyapunov exponents</b> are the rates at which nearby motions separate: the state is "
        f"integrated together with {2 * n} tangent vectors — the variational equations $\\dot v = J(y)\\,v$ with the "
        "Jacobian generated from the same model (CasADi's derivative of the recursive algorithms), in the same adaptive "
        "DOP853 steps as the state — re-orthonormalised (QR) every second, their logarithmic growths summed (Benettin's "
        "method). A positive largest exponent means chaos; without damping and torques the spectrum comes in pairs "
        r"$\pm\lambda$ with two zeros.</p>")]
    with warnings.catch_warnings(record=True):
        warnings.simplefilter("always")
        try:
            spec = lyapunov(chain, y0, t_end=horizon, throw=False, progress=telling(f"{2 * n} Lyapunov exponents", "s"))
        except SkewpendError as exc:
            ctx.notes["chaos"] = "could not be computed"
            return "\n".join(out) + f'<p class="callout warn">The Lyapunov spectrum could not be computed: {esc(exc)}</p>'
    detail("the figure")
    out.append(figure_html(fig_png(F.lyapunov_figure(spec)), prose(
        f"Running estimates of the {spec.k} Lyapunov exponents of the simulation's initial state (section 5), over "
        f"{fmt_num(horizon)} s (± is the 95 % interval from the spread over 10 time windows, once settled)."),
        "Lyapunov exponents against time"))
    settled = spec.status != Status.NOT_SETTLED
    facts = [(f"λ{i + 1}", f"{spec.exponents[i]:+.4f}" + (f" ± {spec.interval[i]:.2g}" if settled else "") + " 1/s")
             for i in range(spec.k)]
    facts.append(("sum", f"{spec.sum:+.2e} 1/s"))
    facts.append(("work", f"{spec.stats['steps']:,} steps in {spec.stats['wall_time']:.2f} s".replace(",", " ")))
    if spec.status != 0:
        facts.append(("stopped" if settled else "not settled", esc(spec.message)))
    out.append(facts_html(facts))
    out.append('<p class="note">Poincaré sections and the chaos diagram are planar pictures of the double pendulum '
               "(a section of its three-dimensional energy surface); a chain of "
               f"{n} links has a {2 * n - 1}-dimensional one, and the report draws neither.</p>"
               if n > 2 else "")
    ctx.notes["chaos"] = f"Lyapunov spectrum of {spec.k} exponents, {spec.stats['wall_time']:.2f} s"
    return "\n".join(out)


# -- section 8 --------------------------------------------------------------------------------------------
def section_orbits(ctx: Context) -> str:
    from ...analysis.equilibria import equilibria
    from ...analysis.orbits import backbones
    from .. import figures as F
    from .orbits import REPORT_RESOLUTION, backbone_facts

    chain, n = ctx.params, ctx.params.n
    out = [prose("<p>Between the small oscillations of section 4 and the chaos of section 7 lie the other equilibria and "
                 "the <b>nonlinear normal modes</b>: the families of periodic orbits that continue each linear mode as the "
                 "energy grows.</p>")]
    detail("the equilibria")
    try:
        eq = equilibria(chain)
    except SkewpendError as exc:
        out.append(f'<p class="callout warn">The equilibria could not be found: {esc(exc)}</p>')
    else:
        rows = []
        for e in eq:
            rows.append([esc(e.label), *(fmt_num(math.degrees(x), 5) for x in e.q), fmt_num(e.potential, 5),
                         "0 (stable)" if e.morse_index == 0 else str(e.morse_index), ", ".join(fmt_num(w, 4) for w in e.frequencies) or "—",
                         ", ".join(fmt_num(s, 4) for s in e.growth_rates) or "—"])
        out.append(prose(f"<p>At rest the equations reduce to $\\partial\\Pi/\\partial q = \\tau$: the equilibria are the "
                         f"critical points of $V = \\Pi - \\tau\\cdot q$ on the {n}-torus — {len(rows)} of them, found by "
                         "Newton's method from a grid of starts and checked complete by their Morse indices (their "
                         "alternating sum is 0 on a torus); each with the frequencies of its oscillating directions and "
                         "the growth rates of its unstable ones (the Morse index: how many directions are unstable):</p>"))
        out.append(table_html(["rods", *(f"q{k + 1} [deg]" for k in range(n)), "V [J]", "Morse index",
                               "frequencies [rad/s]", "growth rates [1/s]"], rows, numeric=tuple(range(1, n + 2)),
                              caption=esc(eq.message)))
        ctx.notes["equilibria"] = eq.message
    if any(link.torque for link in chain.links) or chain.has_friction:
        out.append('<p class="callout">With constant torques or Coulomb friction the backbones are not drawn (the modes '
                   "start from a shifted equilibrium, or no motion is periodic): <code>skewpend nnm --config</code> on the "
                   "chain without them.</p>")
        ctx.notes["orbits"] = "backbones not drawn (torques or friction)"
        return "\n".join(out)
    if n > CHAIN_NNM_MAX_LINKS:
        out.append(f'<p class="note">The nonlinear normal modes of {n} links are not followed here (up to '
                   f"{CHAIN_NNM_MAX_LINKS} links: <code>skewpend nnm --config</code> follows any).</p>")
        ctx.notes["orbits"] = "backbones not drawn (long chain)"
        return "\n".join(out)
    damped = any(link.damping for link in chain.links)
    undamped = chain
    for link in chain.links:
        if link.damping:
            undamped = undamped.replace_link(link.index, damping=0.0)
    try:
        bb = backbones(undamped, resolution=min(REPORT_RESOLUTION, CHAIN_NNM_RESOLUTION))
    except SkewpendError as exc:
        ctx.notes["orbits"] = "could not be computed"
        out.append(f'<p class="callout warn">The nonlinear normal modes could not be computed: {esc(exc)}</p>')
        return "\n".join(out)
    E_max = max(f.energy_max for f in bb.families)
    out.append(prose(
        "<p>Each orbit is found by <b>shooting</b>: Newton's method on the start and the period so that the motion closes "
        "after one period at the given energy, the flow's derivative from the variational equations; each family is "
        "followed by pseudo-arclength continuation, and the eigenvalues of the monodromy matrix decide its stability.</p>"))
    caption = ("Frequency 2π/T of each nonlinear normal mode against its energy above the hanging rest, from the linear "
               f"frequencies of section 4 (◀) up to {fmt_num(E_max, 4)} J, the lowest energy at which a joint can flip. "
               "Solid: stable orbits (all Floquet multipliers on the unit circle); dashed: unstable; markers: where a "
               "multiplier leaves the circle (circle: +1, a branch point; square: −1, period doubling; triangle: a Krein "
               "collision); dotted: internal resonances.")
    if damped:
        caption += " Drawn for the undamped chain: with damping no motion is periodic."
    detail("the frequency-energy plot")
    out.append(figure_html(fig_png(F.fep_figure(bb)), caption, "frequency-energy plot of the nonlinear normal modes"))
    out.append(facts_html(backbone_facts(bb)))
    ctx.notes["orbits"] = (" + ".join(str(len(f)) for f in bb.families) + f" orbits up to {fmt_num(E_max, 4)} J"
                           + (" (undamped chain)" if damped else ""))
    return "\n".join(out)


# -- section 9 --------------------------------------------------------------------------------------------
def section_validation(ctx: Context) -> str:
    from .analyses import section_validation as validation

    return validation(ctx)  # the same comparison: compare_with_mujoco takes a chain


#: The numeric sections in the order they are built (the simulation first: section 1's pictures use it).
CHAIN_BUILDERS = {
    "simulation": section_simulation,
    "system": section_system,
    "derivation": section_derivation,
    "check": section_check,
    "modes": section_modes,
    "flipmap": section_flipmap,
    "chaos": section_chaos,
    "orbits": section_orbits,
    "validation": section_validation,
}


def chain_settings(ctx: Context) -> List:
    """Section 10's settings rows of a chain report (label, HTML)."""
    from ..style import settings_text

    sim = {"t_end": ctx.t_end, "rtol": ctx.rtol, "atol": ctx.atol, "dt": ctx.dt}
    return [
        ("simulation", esc(settings_text(ctx.method, {k: v for k, v in sim.items() if v is not None}))
         + " (figures: rows every " + fmt_num(max(FIGURE_DT, ctx.t_end / FIGURE_MAX_ROWS)) + " s)"),
        ("animation", esc(ctx.notes.get("clip", ""))),
        ("derivation", esc(ctx.notes.get("derivation", ""))),
        ("check", esc(ctx.notes.get("check", ""))),
        ("tilt sweeps", esc(f"0 to 180°, {ctx.notes.get('sweep', '')}")),
        ("flip-time map", esc(ctx.notes.get("flipmap", ""))),
        ("chaos", esc(ctx.notes.get("chaos", ""))),
        ("orbits", esc(ctx.notes.get("orbits", ""))),
        ("validation", esc(f"MuJoCo RK4, dt = {VALIDATION_DT:g} s, {min(VALIDATION_T_END, ctx.t_end):g} s, tolerance "
                          f"{VALIDATION_TOL:g}: {ctx.notes.get('validation', '')}")),
        ("model code", esc(ctx.notes.get("kernel", ""))),
    ]


CHAIN_TIMING_LABELS = [
    ("system", "1 · the system: pictures"),
    ("derivation", "2 · derivation (SymPy)"),
    ("check", "3 · check against the recursive algorithms"),
    ("modes", "4 · normal modes and the tilt sweeps"),
    ("simulation", "5 · simulation, all of it"),
    ("simulation: integration", "5 · integration"),
    ("simulation: figures", "5 · figures"),
    ("simulation: live view", "5 · live view: frames, rod ends, axes"),
    ("flipmap", "6 · flip-time map"),
    ("chaos", "7 · Lyapunov spectrum"),
    ("orbits", "8 · equilibria and nonlinear normal modes"),
    ("validation", "9 · validation against MuJoCo"),
    ("total", "total"),
]


def build_chain_sections(ctx: Context, intr, progress, total: int) -> Dict[str, str]:
    """Every numeric and symbolic section of a chain report, in :data:`CHAIN_BUILDERS`' order (a signal is
    taken between them: ``intr.check()``); ``progress(done, total)`` after each."""
    from ...progress import stage

    bodies: Dict[str, str] = {}
    for done, (key, build) in enumerate(CHAIN_BUILDERS.items()):
        intr.check()
        stage(CHAIN_PARTS[key], done + 1, total)
        t0 = time.perf_counter()
        bodies[key] = build(ctx)
        ctx.timings[key] = time.perf_counter() - t0
        if progress is not None:
            progress(done + 1, total)
    return bodies
