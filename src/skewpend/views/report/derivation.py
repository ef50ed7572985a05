"""Sections 2 and 3 of the report (pure SymPy, computed in a second process when there are two cores): the
derivation step by step and its check.  A model that answers the specification's names (the double pendulum's
facade) is derived by the specification's steps, every parameter symbolic, and checked at alpha = 0 against the
specification's formulas; any other is derived link by link with its values (up to :data:`SYMBOLIC_MAX_LINKS`
links) and checked against the recursive algorithms its kernels compile."""

from __future__ import annotations

import math
from typing import Dict, List, Tuple

import numpy as np

from ...symbolic.layout import equations_fit, equations_tex, layout, linear_tex, numeric, rounded_linear
from ... import schema
from ...errors import SkewpendError
from ...symbolic.model import Parameters

from .common import (SYMBOLIC_MAX_LINKS, Context, answers_names, array_tex, detail, display_math, esc, fmt_num,
                     inline_math, prose, tex_of, vector_tex)

#: Digits of the floating-point numbers in the expressions derived link by link, and the longest one displayed
#: (LaTeX characters; a longer one is named by its size).
DISPLAY_DIGITS = 4
DISPLAY_MAX_CHARS = 2400
#: Random states at which the two derivations are compared, and the agreement required (relative).
CHECK_STATES = 20
CHECK_TOL = 1e-11


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


_P1, _P = r"\underline{\underline{P}}_1", r"\underline{\underline{P}}"


def _step_items(p: Parameters, steps: Dict) -> List[Tuple[str, str]]:
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


def _derivation_body(model: Parameters, symbolic: bool) -> str:
    """Section 2 up to the values of section 1: the derivation's steps, the equations of motion and their
    linearisation, of ``model`` -- every scalar symbolic (``symbolic``) or with its values."""
    from ...symbolic.derivation import derive
    from ...symbolic.display import display_steps

    eom = derive(model)
    if symbolic:
        steps = display_steps(eom.steps)
        out = [prose(
            "<p>The derivation follows the specification: rotation tensors by Rodrigues' formula for the kinematics, "
            "Lagrange's equations for the dynamics. It is written with every parameter symbolic, "
            "$" + ", ".join(schema.tex(n) for n in schema.CORE_NAMES) + "$"
            + (f", and the {' and '.join(_ROLE_TEXT[r][0] for r in _roles_on(model))} of section 1" if _roles_on(model) else "")
            + ", so that each step can be read against the specification; the values of section 1 are put in at the end. "
            "Each intermediate result is shown in the simplest form found, proved equal to the derivation's own "
            "(which the simulation uses).</p>")]
    else:  # numbers to 4 significant digits
        steps = {k: numeric(v, 4) for k, v in eom.steps.items()}
        out = [prose(
            "<p>The derivation follows the specification (rotation tensors by Rodrigues' formula, Lagrange's equations) "
            "for the bodies and axes of section 1, with their values; numbers are rounded to 4 significant "
            "digits.</p>")]
    items = _step_items(model, steps)
    out.append('<ol class="steps">' + "".join(
        f'<li><p class="step-title">{esc(title)}</p>{body}</li>' for title, body in items) + "</ol>")
    out.append("<h3>The equations of motion</h3>")
    if equations_fit(steps["M"]):
        out.append("<p>Written out, the nonlinear equations of motion are</p>")
    else:
        out.append(prose(r"<p>The nonlinear equations of motion, with the entries $M_{mn}$ and $f_m$ of step 9, are</p>"))
    out.append(display_math(equations_tex(steps["M"], steps["f"], tex_of)))  # in display form or rounded already
    try:
        lin = eom.linearize()
    except SkewpendError as exc:
        out.append(f'<p class="callout warn">No linearisation about φ = ψ = 0: {esc(exc)}</p>')
    else:
        out.append(prose(
            r"<p>Linearised about the hanging position ($\varphi, \psi$ and their speeds small, first-order terms "
            r"kept), $M_0\,\ddot q + C_0\,\dot q + K_0\,q = 0$:</p>"))
        out.append(display_math(linear_tex(lin if symbolic else rounded_linear(lin, 4), tex_of)))
    return "\n".join(out)


def section_derivation(ctx: Context) -> str:
    if not answers_names(ctx.params):
        return _links_derivation(ctx)
    from ...symbolic.derivation import derive

    p = ctx.params
    # the specification's thin rods are shown with every scalar symbolic (the optional terms symbolic where the
    # report's are on, else at their defaults); general bodies and axes with the report's values
    symbolic = p.is_thin_rods
    if symbolic:  # depends on which terms are on, not on the values: kept in the cache for every report alike
        from . import cache

        model = Parameters(**_optional_symbolic(p))
        out = [cache.memo("derivation", model.to_dict(), lambda: _derivation_body(model, True))]
    else:
        out = [_derivation_body(p, False)]
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
    if not answers_names(ctx.params):
        return _two_derivations(ctx)
    from . import cache

    thin = ctx.params.is_thin_rods  # the planar case with every parameter symbolic: no value of the report's
    body, note = cache.memo("check", {"thin_rods": thin}, lambda: _check_body(thin))
    ctx.notes["check"] = note
    return body


def _check_body(thin_rods: bool) -> List[str]:
    """Section 3 and its note: the derivation at alpha = 0 against the specification's planar formulas (said to
    be the specification's thin rods where the report's bodies are not, ``thin_rods`` False)."""
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
        + "<p>The differences of the matrices, computed by <code>sympy.simplify</code> with this version of skewpend:</p>"
        + display_math(r"M_0 - M_0^{\text{spec}} = " + tex_of(dM) + r",\qquad K_0 - K_0^{\text{spec}} = " + tex_of(dK))
        + ('<p><span class="verdict ok">✓ identical</span></p>' if lin_ok else '<p><span class="verdict bad">✗ differs</span></p>')
        + "</li>"
    )
    note = "every quantity identical" if all_ok else "A DIFFERENCE WAS FOUND"
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
        + ("" if thin_rods else " (the specification's thin rods, not the bodies of this report)")
        + ".</p>"
    )
    return [intro + verdict + '<ol class="steps">' + "".join(blocks) + "</ol>", note]


# -- a model told by its links: derived link by link, checked against the recursive algorithms -------------
def _link_names(eom) -> Dict:
    from ...symbolic.derivation import coordinate_symbol

    names = {}
    for i, c in enumerate(eom.coordinates, start=1):
        names[coordinate_symbol(c)] = f"q_{{{i}}}"
        names[coordinate_symbol("d" + c)] = rf"\dot q_{{{i}}}"
        names[coordinate_symbol("dd" + c)] = rf"\ddot q_{{{i}}}"
    return names


def _links_derivation(ctx: Context) -> str:
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
    names = _link_names(eom)
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


def _two_derivations(ctx: Context) -> str:
    import sympy as sp

    from ...numeric import kernels
    from ...symbolic.derivation import coordinate_symbol

    chain, n = ctx.params, ctx.params.n
    eom = ctx.eom
    K = kernels.model_kernel(chain) if eom is not None else None  # the code the simulations run, in its form
    if getattr(K, "form", "") == "exact":  # the loader's fastest form for this model: the specification's derivation
        how = ("the specification's derivation of the double pendulum's parameters (SymPy, printed as C) — a second "
               "derivation of the same bodies, its rotation tensors composed by the specification's steps. ")
    else:
        how = ("the <b>recursive algorithms</b> — the mass matrix by composite rigid bodies, the forces by recursive "
               "Newton–Euler — a second derivation with no rotation tensor composed symbolically. ")
    intro = prose("<p>The simulations of this report do not use the expressions of section 2: the compiled code is "
                  "generated from the same model by " + how)
    if eom is None:
        ctx.notes["check"] = "against MuJoCo (section 9)"
        return intro + f"For {n} links the check is section 9's: the same model simulated by MuJoCo.</p>"
    p = kernels.model_vector(chain)
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
