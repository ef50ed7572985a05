"""Sections 2 and 3 of the report (pure SymPy, computed in a second process when there
are two cores): the derivation step by step, and the check at alpha = 0."""

from __future__ import annotations

from typing import Dict, List, Tuple

import numpy as np

from ...symbolic.layout import equations_fit, equations_tex, layout, linear_tex, numeric, rounded_linear
from ... import schema
from ...errors import SkewpendError
from ...symbolic.model import Parameters

from .common import (DEFAULT_PARAMETERS, DEFAULT_INITIAL_STATE, DEFAULT_T_END, MAX_T_END, REPORT_SUFFIXES, SECTIONS, CLIP_SECONDS, CLIP_FPS, CLIP_SIZE, PICTURE_SIZE, FIGURE_DPI, SWEEP_POINTS, VALIDATION_DT, VALIDATION_T_END, VALIDATION_TOL, FLIPMAP_N, FLIPMAP_T_END, CHAOS_LYAPUNOV_T_END, CHAOS_SECTION_LEVELS, CHAOS_SECTION_ORBITS, CHAOS_SECTION_CROSSINGS, CHAOS_MAP_N, CHAOS_MAP_T_END, CHAOS_DIAGRAM, CHAOS_DIAGRAM_LEVELS, FIGURE_DT, FIGURE_MAX_ROWS, esc, inline_math, display_math, prose, fmt_num, fmt_num_tex, fmt_deg, fig_png, rgb_png, data_uri, FIGURE_SLOT, figure_html, live_view_html, number_figures, table_html, facts_html, asset, katex_assets, template, tex_of, array_tex, vector_tex, Context)  # noqa: F401

# -- section 2: the derivation ---------------------------------------------------------------------------
def _optional_symbolic(p: Parameters) -> Dict[str, object]:
    """The optional terms (the schema's scalars with a default: damping, torques, Coulomb friction,
    the rotors) as the symbolic derivation takes them: a term that is switched on (its default is 0
    and its value is not) symbolic; a modifier of a term (a non-zero default: the friction's
    smoothing rate, the gear ratio) symbolic when a term of its role is on; every other at its
    default."""
    on = {n for n, d in schema.OPTIONAL_DEFAULTS.items() if d == 0 and getattr(p, n) != 0}
    roles_on = {schema.field(n).role for n in on}
    out: Dict[str, object] = {}
    for n, d in schema.OPTIONAL_DEFAULTS.items():
        symbolic = n in on if d == 0 else schema.field(n).role in roles_on
        out[n] = None if symbolic else d
    return out


def _roles_on(p: Parameters) -> Tuple[str, ...]:
    """The roles of the optional terms the equations of ``p`` carry (non-zero or symbolic), in the schema's order."""
    roles = []
    for n, d in schema.OPTIONAL_DEFAULTS.items():
        role = schema.field(n).role
        if d == 0 and (getattr(p, n) is None or getattr(p, n) != 0) and role not in roles:
            roles.append(role)
    return tuple(roles)


#: How each optional role enters: its words, and its part of the generalised forces Q_i (None: it
#: enters the kinetic energy instead).
_ROLE_TEXT = {
    "damping": ("viscous damping", r"- c_i\,\dot q_i"),
    "torque": ("joint torques", r"\tau_i"),
    "friction": ("Coulomb friction", r"- c_{fi}\arctan(c_{fs}\,\dot q_i)"),
    "rotor": ("the motors' rotors", None),
}


def forces_text(p: Parameters) -> str:
    """The generalised non-potential forces ``Q_i`` of ``p``'s equations, as prose with TeX: one term
    for each role of the optional terms that ``p`` carries (torques, damping, Coulomb friction)."""
    forcing = [r for r in _roles_on(p) if _ROLE_TEXT[r][1] is not None]
    if not forcing:
        return r"$Q_i = 0$ (no dissipation, as in the specification)"
    parts = sorted((_ROLE_TEXT[r][1] for r in forcing), key=lambda t: t.startswith("-"))  # tau_i - c_i q_i ...
    terms = parts[0] + "".join(" " + t if t.startswith("-") else " + " + t for t in parts[1:])
    return f"$Q_i = {terms}$ ({' and '.join(_ROLE_TEXT[r][0] for r in forcing)})"


def _symbolic_model(p: Parameters) -> Tuple[Parameters, bool]:
    """The model the derivation is shown for, and whether it is symbolic: the specification's
    thin rods with every scalar symbolic (the optional terms -- damping, torques, Coulomb friction,
    the rotors -- symbolic where the report's are on, else at their defaults); general bodies and
    axes with the report's values."""
    if p.is_thin_rods:
        return Parameters(**_optional_symbolic(p)), True
    return p, False


_P1, _P = r"\underline{\underline{P}}_1", r"\underline{\underline{P}}"


def _step_items(p: Parameters, symbolic: bool, steps: Dict) -> List[Tuple[str, str]]:
    """(title, html) of each step of the derivation, in the specification's order."""
    from ...symbolic.render import LATEX_LABELS as L

    tex = tex_of
    n1 = r"\underline{k}" if p.axis1 is None else r"\underline{n}_1"
    rod = "rod" if p.is_thin_rods else "body"
    Rod = rod.capitalize()
    items = []
    rodrigues = (r"\underline{\underline{P}}(\theta,\underline{n}) = \underline{n}\,\underline{n} + (\underline{\underline{E}}"
                 r" - \underline{n}\,\underline{n})\cos\theta + \underline{n} \times \underline{\underline{E}}\,\sin\theta")
    items.append((
        f"Rotation of {rod} 1",
        prose(r"<p>Rodrigues' formula gives the rotation tensor by the angle $\theta$ about the unit axis $\underline{n}$ "
           r"($\underline{\underline{E}}$ the identity):</p>") + display_math(rodrigues)
        + prose(f"<p>{Rod} 1 turns by $\\varphi$ about ${n1}$; by components in the basis $\\underline{{i}},\\underline{{j}},\\underline{{k}}$:</p>")
        + display_math(layout(L["P1"], 12, steps["P1"], tex, prefix=r"\underline{\underline{P}}(\varphi, " + n1 + ") = ")),
    ))
    if p.axis2 is None:
        e0 = r"\underline{e}_0 = \cos\alpha\,\underline{k} + \sin\alpha\,\underline{i}"
    else:
        e0 = r"\underline{e}_0 = " + vector_tex(p.axis2)
    items.append((
        "Current axis of the second hinge",
        prose(f"<p>With the rods hanging the second hinge's axis is ${e0}$; it turns with {rod} 1:</p>")
        + display_math(layout(L["e"], 10, steps["e"], tex, prefix=_P1 + r" \cdot \underline{e}_0 = ")),
    ))
    items.append((
        f"Rotation of {rod} 2",
        prose(f"<p>{Rod} 2 turns by $\\psi$ about $\\underline{{e}}$ on top of {rod} 1's rotation; as "
           r"$\underline{\underline{P}}(\psi,\underline{e}) = " + _P1 + r"\cdot\underline{\underline{P}}(\psi,\underline{e}_0)\cdot"
           + _P1 + r"^T$:</p>")
        + display_math(layout(L["P"], 30, steps["P"], tex, prefix=r"\underline{\underline{P}}(\psi,\underline{e}) \cdot " + _P1
                      + " = " + _P1 + r" \cdot \underline{\underline{P}}(\psi,\underline{e}_0) = ")),
    ))
    items.append((
        f"Angular velocity of {rod} 2",
        prose(r"<p>By the addition of angular velocities, $\underline{\omega}_2 = \underline{\omega}_1 + " + _P1
           + r"\cdot\tilde{\underline{\omega}}_2$ with $\tilde{\underline{\omega}}_2 = \dot\psi\,\underline{e}_0$:</p>")
        + display_math(layout(L["omega2"], 14, steps["omega2"], tex, prefix=r"\dot\varphi\," + n1 + r" + \dot\psi\,\underline{e} = ")),
    ))
    c2 = r"\tfrac{b}{2}\,\underline{j}" if p.com2 is None else vector_tex(p.com2)
    items.append((
        f"Velocity of {rod} 2's centre of mass",
        prose(r"<p>Rod 1 reaches from the pivot to the second hinge, $\underline{a} = " + _P1 + r"\cdot a\,\underline{j}$; "
           f"the centre of mass of {rod} 2 is at $" + _P + r"\cdot\underline{c}_2$ from that hinge, $\underline{c}_2 = "
           + c2 + f"$ in {rod} 2's frame" + (r" (the specification's $\tfrac{1}{2}\underline{b}$)" if p.com2 is None else "")
           + ":</p>")
        + display_math(layout(L["v_c"], 30, steps["v_c"], tex, prefix=r"\dot\varphi\," + n1 + r" \times \underline{a} + "
                      r"\underline{\omega}_2 \times (" + _P + r"\cdot\underline{c}_2) = ")),
    ))
    if p.inertia2 is None:
        theta0 = r"\underline{\underline{\Theta}}{}^0_2 = \tfrac{m_2 b^2}{12}(\underline{\underline{E}} - \underline{j}\,\underline{j})"
        extra = (r"; this is the specification's $\underline{\underline{\Theta}}_2 = \tfrac{m_2 b^2}{12}(\underline{\underline{E}} - "
                 r"\tilde{\underline{e}}\,\tilde{\underline{e}})$, $\tilde{\underline{e}} = " + _P + r"\cdot\underline{j}$")
    else:
        theta0 = r"\underline{\underline{\Theta}}{}^0_2 = " + array_tex(np.array(p.inertia2, dtype=float), 4)
        extra = ""
    items.append((
        f"Inertia tensor of {rod} 2",
        prose(f"<p>About its centre of mass, turned with the {rod}, from ${theta0}$ in its own frame{extra}:</p>")
        + display_math(layout(L["Theta2"], 16, steps["Theta2"], tex,
                      prefix=_P + r"\cdot\underline{\underline{\Theta}}{}^0_2\cdot" + _P + "^T = ")),
    ))
    if p.is_thin_rods:
        t1 = r"T_1 = \tfrac{1}{2}\Theta_1\dot\varphi^2$ with $\Theta_1 = \tfrac{m_1 a^2}{3}$ (rod 1 about its hinge)"
    else:
        t1 = (r"T_1 = \tfrac{1}{2}\underline{\omega}_1\cdot\underline{\underline{\Theta}}_1\cdot\underline{\omega}_1 + "
              r"\tfrac{1}{2}m_1\underline{\vartheta}_{c1}^2$")
    items.append((
        "Kinetic energy",
        prose("<p>$" + t1 + r", and $T_2 = \tfrac{1}{2}\underline{\omega}_2\cdot\underline{\underline{\Theta}}_2\cdot"
           r"\underline{\omega}_2 + \tfrac{1}{2} m_2\, \underline{\vartheta}_c\cdot\underline{\vartheta}_c$:</p>")
        + display_math(layout("T", 12, steps["T"], tex, prefix="T_1 + T_2 = ")),
    ))
    items.append((
        "Potential energy",
        prose(r"<p>Measured from the hanging position (the specification's $\Pi_2 = m_2 g\,(a + b - \underline{r}_c\cdot"
           r"\underline{j})$ is larger by the constant $m_2 g b/2$, which no equation of motion sees):</p>")
        + display_math(layout(r"\Pi", 12, steps["Pi"], tex, prefix=r"\Pi_1 + \Pi_2 = ")),
    ))
    q = forces_text(p)
    items.append((
        "Lagrange's equations",
        prose(r"<p>With $q = (\varphi, \psi)$ and the generalised non-potential forces " + q + ":</p>")
        + display_math(r"\frac{d}{dt}\frac{\partial T}{\partial \dot{q}_i}-\frac{\partial T}{\partial q_i} = -\frac{\partial \Pi}{\partial q_i}+Q_i")
        + prose(r"<p>$T$ is quadratic in the speeds, so they read $M(q)\,\ddot q = f(q, \dot q)$, the mass matrix $M$ being "
             r"the Hessian of $T$ in the speeds:</p>")
        + display_math(layout("M", 3, steps["M"], tex))
        + display_math(layout("f", 3, steps["f"], tex)),
    ))
    return items


def section_derivation(ctx: Context) -> str:
    from ...symbolic.derivation import derive
    from ...symbolic.display import display_steps

    p = ctx.params
    model, symbolic = _symbolic_model(p)
    eom = derive(model)
    if symbolic:
        steps = display_steps(eom.steps)
    else:  # numbers to 4 significant digits
        steps = {k: numeric(v, 4) for k, v in eom.steps.items()}
    out = []
    if symbolic:
        out.append(prose(
            "<p>The derivation follows the specification: rotation tensors by Rodrigues' formula for the kinematics, "
            "Lagrange's equations for the dynamics. It is written with every parameter symbolic, "
            "$" + ", ".join(schema.tex(n) for n in schema.CORE_NAMES) + "$"
            + (f", and the {' and '.join(_ROLE_TEXT[r][0] for r in _roles_on(model))} of section 1" if _roles_on(model) else "")
            + ", so that each step can be read against the specification; the values of section 1 are put in at the end. "
            "Each intermediate result is shown in the simplest form found, proved equal to the derivation's own "
            "(which the simulation uses).</p>"
        ))
    else:
        out.append(prose(
            "<p>The derivation follows the specification (rotation tensors by Rodrigues' formula, Lagrange's equations) "
            "for the bodies and axes of section 1, with their values; numbers are rounded to 4 significant digits.</p>"
        ))
    items = _step_items(model, symbolic, steps)
    out.append('<ol class="steps">' + "".join(
        f'<li><p class="step-title">{esc(title)}</p>{body}</li>' for title, body in items) + "</ol>")
    tex = tex_of  # the steps are in display form (symbolic) or rounded (numbers) already
    out.append("<h3>The equations of motion</h3>")
    if equations_fit(steps["M"]):
        out.append("<p>Written out, the nonlinear equations of motion are</p>")
    else:
        out.append(prose(r"<p>The nonlinear equations of motion, with the entries $M_{mn}$ and $f_m$ of step 9, are</p>"))
    out.append(display_math(equations_tex(steps["M"], steps["f"], tex)))
    try:
        lin = eom.linearize()
    except SkewpendError as exc:
        out.append(f'<p class="callout warn">No linearisation about φ = ψ = 0: {esc(exc)}</p>')
    else:
        out.append(prose(
            r"<p>Linearised about the hanging position ($\varphi, \psi$ and their speeds small, first-order terms "
            r"kept), $M_0\,\ddot q + C_0\,\dot q + K_0\,q = 0$:</p>"))
        out.append(display_math(linear_tex(lin if symbolic else rounded_linear(lin, 4), tex)))
    if symbolic:
        eom_n = derive(p)
        out.append("<h3>With the values of section 1</h3>")
        out.append("<p>The same equations with the parameters of section 1 (numbers to 5 significant digits):</p>")
        Mn, fn = numeric(eom_n.mass_matrix), numeric(eom_n.forcing)
        out.append(display_math(equations_tex(Mn, fn, tex_of)))
        if not equations_fit(Mn):
            out.append(display_math(layout("M", 3, Mn, tex_of)))
            out.append(display_math(layout("f", 3, fn, tex_of)))
        try:
            lin_n = eom_n.linearize()
        except SkewpendError:
            pass
        else:
            out.append("<p>Linearised:</p>")
            out.append(display_math(linear_tex(rounded_linear(lin_n, 5), tex_of)))
    ctx.notes["derivation"] = ("the specification's thin rods, every parameter symbolic" if symbolic
                               else "the report's bodies and axes, with their values")
    return "\n".join(out)


# -- section 3: the check at alpha = 0 -----------------------------------------------------------------
def section_check(ctx: Context) -> str:
    import sympy as sp

    from ...symbolic.derivation import derive
    from ...symbolic.display import display_form, display_steps
    from ...symbolic.render import LATEX_LABELS as L
    from ...symbolic.specification import check_planar, planar_latex
    from ...symbolic.symbols import SYMBOLS as S

    spec_tex = planar_latex()
    eom0 = derive(Parameters(alpha=0.0))
    lin0 = eom0.linearize()
    checks = {c.key: c for c in check_planar(eom0)}
    steps = display_steps(eom0.steps, keys=("e", "P", "omega2", "v_c", "T", "Pi"))
    v = steps["v_c"]  # shorter to square
    v2 = display_form(sp.expand((v.T * v)[0, 0]), speeds=(S["dphi"], S["dpsi"]))
    ours = {"e": f"{L['e']} = " + tex_of(steps["e"]), "P": f"{L['P']} = " + tex_of(steps["P"]),
            "omega2": f"{L['omega2']} = " + tex_of(steps["omega2"]),
            "v2": r"\underline{\vartheta}_c\cdot\underline{\vartheta}_c = " + tex_of(v2),
            "T": "T = " + tex_of(steps["T"]), "Pi": r"\Pi = " + tex_of(steps["Pi"])}
    blocks = []
    for key, mine in ours.items():
        c = checks[key]
        if key == "Pi":
            line = (r"\Pi_{\text{skewpend}} - \Pi_{\text{spec}} = " + tex_of(c.expected)
                    + r"\quad\text{(a constant: the specification's zero level)}")
        else:
            zero = r"\underline{0}" if isinstance(c.difference, sp.MatrixBase) else "0"
            line = r"\text{skewpend} - \text{specification} = " + zero
        verdict = '<span class="verdict ok">✓ identical</span>' if c.identical else '<span class="verdict bad">✗ differs</span>'
        blocks.append(
            f'<li><p class="step-title">{esc(c.title)}</p>'
            f'<p class="note">The specification:</p>{display_math(spec_tex[key])}'
            f'<p class="note">This derivation at α = 0:</p>{display_math(mine)}'
            f"<p>{inline_math(line)} &nbsp; {verdict}</p></li>"
        )
    dM, dK = checks["M0"].difference, checks["K0"].difference
    lin_ok = checks["M0"].identical and checks["K0"].identical and checks["C0"].identical
    all_ok = all(c.identical for c in checks.values())
    blocks.append(
        '<li><p class="step-title">The linearised equations of motion</p>'
        '<p class="note">The specification (energies differentiated, first-order terms kept):</p>'
        + display_math(spec_tex["linear"])
        + '<p class="note">This derivation at α = 0:</p>'
        + display_math(linear_tex(lin0, tex_of))
        + "<p>The differences of the matrices, computed by <code>sympy.simplify</code> when this report was made:</p>"
        + display_math(r"M_0 - M_0^{\text{spec}} = " + tex_of(dM) + r",\qquad K_0 - K_0^{\text{spec}} = " + tex_of(dK))
        + ('<p><span class="verdict ok">✓ identical</span></p>' if lin_ok else '<p><span class="verdict bad">✗ differs</span></p>')
        + "</li>"
    )
    ctx.notes["check"] = "every quantity identical" if all_ok else "A DIFFERENCE WAS FOUND"
    verdict = (
        '<p class="callout good"><b>Every quantity agrees.</b> At α = 0 the derivation reproduces the specification\'s '
        "planar formulas and its linear equations exactly: each difference simplifies to zero "
        "(the potential energy's to the constant of its zero level).</p>"
        if all_ok else
        '<p class="callout warn"><b>A difference was found</b> between the derivation at α = 0 and the specification; see below.</p>'
    )
    intro = prose(
        r"<p>The specification checks its method on the particular case $\alpha = 0$: then $\underline{e}_0 = "
        r"\underline{e} = \underline{k}$, both rods turn about $\underline{k}$ and the problem is planar. Each of its "
        "formulas, typed here from its text, stands next to the same quantity from the derivation of section 2 with "
        r"$\alpha = 0$ and the other parameters symbolic"
        + ("" if ctx.params.is_thin_rods else " (the specification's thin rods, not the bodies of this report)")
        + ".</p>"
    )
    return intro + verdict + '<ol class="steps">' + "".join(blocks) + "</ol>"
