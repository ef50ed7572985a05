"""Text, LaTeX and JSON forms of derived equations.

The JSON form is a contract (see README): every expression is a string that
``sympy.sympify`` parses back, in the symbols ``phi, psi, dphi, dpsi`` and the
parameter names.
"""

from __future__ import annotations

import math
from typing import TYPE_CHECKING, Any, Dict, List, Optional

import sympy as sp

from .. import __version__, schema
from .symbols import SYMBOLS

if TYPE_CHECKING:  # pragma: no cover - annotations only: the derivation imports this module
    from .derivation import EquationsOfMotion, LinearEquations

__all__ = ["to_text", "to_latex", "to_json", "STEP_TITLES"]

#: What each intermediate result of the derivation is, in the specification's words.
STEP_TITLES = {
    "P1": "rotation tensor of rod 1, P1 = P(phi, k) (Rodrigues' formula)",
    "e": "current axis of the second hinge, e = P1 . e0",
    "P": "rotation tensor of rod 2, P = P1 . P(psi, e0)",
    "omega2": "angular velocity of rod 2, omega2 = phi' k + psi' e",
    "v_c": "velocity of rod 2's centre of mass, v_c = omega1 x a + omega2 x (P . c2)",
    "Theta2": "inertia tensor of rod 2 about its centre of mass, Theta2 = P . Theta2_0 . P^T",
    "T": "kinetic energy, T = T1 + T2",
    "Pi": "potential energy, Pi = Pi1 + Pi2 (zero with both rods hanging)",
    "M": "mass matrix, M = Hessian of T in the speeds",
    "f": "forcing: Lagrange's equations give M q'' = f(q, q')",
}

_S = SYMBOLS
#: The parameters' symbols as the schema writes them (``m₁``, ``τ₂``; TeX ``m_1``, ``\tau_2``).
UNICODE = {
    _S["dphi"]: sp.Symbol("φ̇"),
    _S["dpsi"]: sp.Symbol("ψ̇"),
    _S["ddphi"]: sp.Symbol("φ̈"),
    _S["ddpsi"]: sp.Symbol("ψ̈"),
    **{_S[n]: sp.Symbol(schema.symbol(n)) for n in schema.SCALAR_NAMES if schema.symbol(n) != n},
}
_LATEX_NAMES = {
    _S["phi"]: r"\varphi",
    _S["psi"]: r"\psi",
    _S["dphi"]: r"\dot{\varphi}",
    _S["dpsi"]: r"\dot{\psi}",
    _S["ddphi"]: r"\ddot{\varphi}",
    _S["ddpsi"]: r"\ddot{\psi}",
    **{_S[n]: schema.tex(n) for n in schema.SCALAR_NAMES if schema.tex(n) != n},
}
_TEXT_LABELS = {
    "P1": "P₁",
    "e": "e",
    "P": "P",
    "omega2": "ω₂",
    "v_c": "ϑc",
    "Theta2": "Θ₂",
    "T": "T",
    "Pi": "Π",
    "M": "M",
    "f": "f",
}
LATEX_LABELS = {
    "P1": r"\underline{\underline{P}}_1",
    "e": r"\underline{e}",
    "P": r"\underline{\underline{P}}",
    "omega2": r"\underline{\omega}_2",
    "v_c": r"\underline{\vartheta}_c",
    "Theta2": r"\underline{\underline{\Theta}}_2",
    "T": "T",
    "Pi": r"\Pi",
    "M": "M",
    "f": "f",
}


# -- how the equations are written: the specification's, or a chain's (coordinates q1 .. qn) -------
_SUB = str.maketrans("0123456789", "₀₁₂₃₄₅₆₇₈₉")


def _links_given(eom: "EquationsOfMotion") -> bool:
    """Whether the equations are a chain's (its links' values, numeric; coordinates as the model names them), not
    the specification's: the model is not its own exact form (the double pendulum's parameters, symbols kept)."""
    return eom.params.exact_model() is not eom.params


def _coordinate_symbol(name: str) -> sp.Symbol:
    """The derivation's symbol of a coordinate, speed or acceleration (``derivation.coordinate_symbol``'s rule)."""
    return _S[name] if name in _S else sp.Symbol(name, real=True)


def _chain_symbols(eom: "EquationsOfMotion"):
    """A chain's Unicode and LaTeX names of ``q_i``, ``dq_i``, ``ddq_i``."""
    uni, tex_names = {}, {}
    for i, name in enumerate(eom.coordinates, start=1):
        sub = str(i).translate(_SUB)
        for prefix, mark, latex in (("", "", "q_{%d}"), ("d", "\u0307", "\\dot{q}_{%d}"), ("dd", "\u0308", "\\ddot{q}_{%d}")):
            sym = _coordinate_symbol(prefix + name)
            uni[sym] = sp.Symbol("q" + mark + sub)
            tex_names[sym] = latex % i
    return uni, tex_names


def _chain_step_title(key: str) -> str:
    k = key.lstrip("Peomega")
    return {"P": f"rotation tensor of link {k}, P{k} = P{int(k) - 1} . P(q{k}, e{k}0)" if k != "1" else
            "rotation tensor of link 1, P1 = P(q1, e10)",
            "e": f"current axis of hinge {k}, e{k} = P{int(k) - 1} . e{k}0" if k != "1" else "axis of the roof hinge, e1 = e10",
            "omega": f"angular velocity of link {k}, omega{k} = omega{int(k) - 1} + q{k}' e{k}" if k != "1" else
            "angular velocity of link 1, omega1 = q1' e1"}[key[:len(key) - len(k)]]


class _Writing:
    """How the equations are written: their coordinates' and parameters' names (Unicode, LaTeX), the head and
    values lines, the steps' titles and labels, and what the linearisation adds -- the specification's for
    the double pendulum's parameters (symbols kept), a chain's (q₁ … qₙ, its links' values) otherwise."""

    def __init__(self, eom: "EquationsOfMotion") -> None:
        n = len(eom.coordinates)
        if not _links_given(eom):
            self.uni, self.names, self.head = UNICODE, _LATEX_NAMES, "Skewed double pendulum"
            self.q, self.values, self.rest = "φ, ψ", _params_line(eom), "φ = ψ = 0"
            self.title, self.label, self.latex_label = STEP_TITLES.get, _TEXT_LABELS.get, LATEX_LABELS.get
            self.lhs = _linear_lhs  # the linearised equations written out
            return
        self.uni, self.names = _chain_symbols(eom)
        self.head, self.rest, self.lhs = f"Chain of {n} links", "the hanging rest q = 0", None
        self.q = ", ".join(f"q{str(k).translate(_SUB)}" for k in range(1, n + 1)) if n <= 3 else f"q₁ … q{str(n).translate(_SUB)}"
        self.values = "links -- " + "; ".join(f"{link.index}: axis ({', '.join(f'{x:.6g}' for x in link.axis)}), "
                                              f"l = {link.length:g}, m = {link.mass:g}" for link in eom.params.links) + \
            f"; g = {eom.params.g:g}"
        stem = lambda key: key.rstrip("0123456789")  # noqa: E731
        self.title = lambda key: STEP_TITLES[key] if key in ("T", "Pi") else _chain_step_title(key)
        self.label = lambda key: _TEXT_LABELS[key] if key in ("T", "Pi") else \
            {"P": "P", "e": "e", "omega": "ω"}[stem(key)] + key[len(stem(key)):].translate(_SUB)
        self.latex_label = lambda key: LATEX_LABELS[key] if key in ("T", "Pi") else {
            "P": r"\underline{\underline{P}}", "e": r"\underline{e}", "omega": r"\underline{\omega}"}[stem(key)] + \
            "_{" + key[len(stem(key)):] + "}"


# -- text ----------------------------------------------------------------------------------
def _pretty(label: str, expr: Any, width: int, names: Optional[dict] = None) -> str:
    names = UNICODE if names is None else names
    expr = expr.xreplace(names) if isinstance(expr, sp.MatrixBase) else sp.sympify(expr).xreplace(names)
    return sp.pretty(sp.Eq(sp.Symbol(label), expr, evaluate=False), use_unicode=True, num_columns=width)


def _params_line(eom: EquationsOfMotion) -> str:
    p = eom.params
    names = eom.parameter_names
    values = {
        k: v
        for k, v in p.to_dict().items()
        if v is not None and k in _S and not (k in schema.OPTIONAL_DEFAULTS and v == schema.OPTIONAL_DEFAULTS[k])
    }
    if not p.uses_alpha:
        values.pop("alpha", None)
    parts = [f"symbolic: {', '.join(names) if names else 'none'}"]
    if values:
        shown = [f"{k}={v:g}" + (f" ({math.degrees(v):.6g}°)" if k == "alpha" else "") for k, v in values.items()]
        parts.append("values: " + ", ".join(shown))
    if not p.is_thin_rods:
        general = [k for k in schema.GEOMETRY_NAMES if getattr(p, k) is not None]
        parts.append("general bodies/axes: " + ", ".join(general))
    return "parameters -- " + "; ".join(parts)


def _linear_lhs(lin: LinearEquations) -> List[sp.Expr]:
    keys = [_S[n] for n in ("ddphi", "ddpsi", "dphi", "dpsi", "phi", "psi")]
    return [sp.collect(e, keys) for e in lin.equations()]


def to_text(
    eom: EquationsOfMotion,
    *,
    linear: Optional[LinearEquations] = None,
    steps: bool = False,
    width: Optional[int] = None,
) -> str:
    """Readable Unicode form of the equations (and optionally the steps and linearisation).

    ``width`` is the line width for SymPy's pretty printer (default: the terminal's, at
    least 100 columns).
    """
    if width is None:
        import shutil

        width = max(100, shutil.get_terminal_size((160, 24)).columns)
    w = _Writing(eom)

    def pretty(label, expr):
        return _pretty(label, expr, width, w.uni)

    n = len(eom.coordinates)
    out = [f"{w.head} -- equations of motion  M(q) q̈ = f(q, q̇),  q = ({w.q})", w.values, ""]
    if steps:
        out.append("Derivation, step by step (world basis i, j, k; j points down):")
        for i, key in enumerate((k for k in eom.steps if k not in ("M", "f")), 1):
            out += [f"{i}. {w.title(key)}", pretty(w.label(key), eom.steps[key]), ""]
        out.append("Lagrange's equations  d/dt ∂T/∂q̇ − ∂T/∂q = −∂Π/∂q + Q,  Q = τ − c q̇:")
    M, f = eom.mass_matrix, eom.forcing
    for i in range(n):
        for j in range(i, n):
            a, b = str(i + 1).translate(_SUB), str(j + 1).translate(_SUB)
            out.append(pretty(f"M{a}{b}" + (f" = M{b}{a}" if i != j else ""), M[i, j]))
    out += [pretty(f"f{str(i + 1).translate(_SUB)}", f[i]) for i in range(n)]
    out += ["", pretty("T", eom.kinetic_energy), pretty("Π", eom.potential_energy)]
    if linear is not None:
        out += ["", f"Linearised about {w.rest}:  M₀ q̈ + C₀ q̇ + K₀ q = 0"] + ([linear.note] if linear.note else [])
        out.append(pretty("M₀", linear.M))
        if linear.C != sp.zeros(n, n):
            out.append(pretty("C₀", linear.C))
        out.append(pretty("K₀", linear.K))
        for lhs in w.lhs(linear) if w.lhs else ():
            out.append(sp.pretty(sp.Eq(lhs.xreplace(UNICODE), 0, evaluate=False), num_columns=width))
    return "\n".join(out) + "\n"


# -- LaTeX -------------------------------------------------------------------------------------
def tex(expr: Any) -> str:
    return sp.latex(expr, symbol_names=_LATEX_NAMES)


def to_latex(
    eom: EquationsOfMotion,
    *,
    linear: Optional[LinearEquations] = None,
    steps: bool = False,
    display: bool = False,
) -> str:
    """LaTeX (an ``aligned`` block; ``display`` gives the body only, for Jupyter)."""
    w = _Writing(eom)

    def t(expr):
        return sp.latex(expr, symbol_names=w.names)

    M, f = eom.mass_matrix, eom.forcing
    rows = [f"{w.latex_label(key)} &= {t(value)}" for key, value in eom.steps.items() if key not in ("M", "f")] if steps else []
    dd = [_coordinate_symbol("dd" + c) for c in eom.coordinates]
    for i in range(len(dd)):
        rows.append(" + ".join(r"\left(" + t(M[i, j]) + r"\right)" + t(dd[j]) for j in range(len(dd))) + f" &= {t(f[i])}")
    rows += [f"T &= {t(eom.kinetic_energy)}", rf"\Pi &= {t(eom.potential_energy)}"]
    if linear is not None:
        rows += ([f"{t(lhs)} &= 0" for lhs in w.lhs(linear)] if w.lhs else
                 [rf"M_0 &= {t(linear.M)}", rf"C_0 &= {t(linear.C)}", rf"K_0 &= {t(linear.K)}"])
    body = "\\begin{aligned}\n" + " \\\\\n".join(rows) + "\n\\end{aligned}"
    if display:
        return body
    note = f"% {linear.note}\n" if linear is not None and linear.note else ""
    return note + "\\[\n" + body + "\n\\]\n"


# -- JSON -----------------------------------------------------------------------------------------
def _s(expr: Any) -> str:
    return str(expr)


def _matrix(m: sp.MatrixBase) -> List[List[str]]:
    return [[_s(m[i, j]) for j in range(m.cols)] for i in range(m.rows)]


def to_json(
    eom: EquationsOfMotion,
    *,
    linear: Optional[LinearEquations] = None,
    steps: bool = False,
) -> Dict[str, Any]:
    """The JSON contract: a dict of strings that ``sympy.sympify`` parses.

    Keys: ``coordinates``, ``speeds``, ``parameters`` (names of the symbolic parameters),
    ``values`` (the numeric ones), ``mass_matrix`` (2x2), ``forcing`` (2) with
    ``mass_matrix . [phi'', psi''] = forcing``, ``kinetic_energy``, ``potential_energy``;
    with ``linear`` a ``linearized`` object with ``M``, ``C``, ``K`` (2x2) (and, for a model with
    Coulomb friction, ``coulomb`` and ``note``: how it entered ``C``); with ``steps``
    a ``steps`` object; ``skewpend_version``.
    """
    params = eom.params.to_dict()
    if _links_given(eom):  # a chain: its links as given (numeric), no symbolic parameters
        values: Dict[str, Any] = params
    else:
        if not eom.params.uses_alpha:
            params.pop("alpha")
        values = {k: v for k, v in params.items() if v is not None}
    data: Dict[str, Any] = {
        "coordinates": list(eom.coordinates),
        "speeds": list(eom.speeds),
        "parameters": list(eom.parameter_names),
        "values": values,
        "mass_matrix": _matrix(eom.mass_matrix),
        "forcing": [_s(x) for x in eom.forcing],
        "kinetic_energy": _s(eom.kinetic_energy),
        "potential_energy": _s(eom.potential_energy),
    }
    if linear is not None:
        data["linearized"] = {"M": _matrix(linear.M), "C": _matrix(linear.C), "K": _matrix(linear.K)}
        if linear.note:  # how the Coulomb friction entered C
            data["linearized"].update(coulomb=linear.coulomb, note=linear.note)
    if steps:
        data["steps"] = {
            k: (_matrix(v) if isinstance(v, sp.MatrixBase) else _s(v)) for k, v in eom.steps.items()
        }
    data["skewpend_version"] = __version__
    return data
