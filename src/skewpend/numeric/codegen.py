"""Numeric code generated from the symbolic derivation (the one source of truth).

Every numeric function skewpend runs, and the standalone Python, C and JavaScript a
user can take away, is printed here from :func:`skewpend.derive`'s expressions
with common-subexpression elimination.  No equation of motion is typed by hand;
the only hand-written numerics are the linear solve ``M q'' = f`` (one LDL^T solve, printed
by :func:`ldlt_factor_steps` and its companions into every generated function: the compiled
kernels and their SIMD lanes, the Taylor series, the standalone exports, the explorer's
JavaScript) and the integrators (``integrators.c``); the C the simulations compile is printed
by :mod:`skewpend.numeric.kernel_source` with the helpers below.

Conventions shared by every generated routine:

* state ``y = (phi, psi, dphi, dpsi)`` [rad, rad, rad/s, rad/s];
* parameters ``p = (a, b, m1, m2, alpha, g, c1, c2, tau1, tau2, cf1, cf2, cfs, Ir, gr)`` (SI
  units, radians), the order of :data:`PARAMETER_ORDER` (the optional friction and rotor terms
  are in the code only when the model has them: :func:`~skewpend.numeric.conventions.geometry_of`);
* in the standalone exports and the explorer, general-body geometry (``com``, ``inertia``,
  ``axis``) is baked into the code as numbers; the compiled kernels read the bodies' non-zero
  entries from their ``p`` too (:func:`~skewpend.numeric.conventions.structure_of`).
"""

from __future__ import annotations

import json
import re
from functools import cached_property, lru_cache
from typing import Callable, List, Sequence, Tuple

import sympy as sp

from .. import __version__
from ..symbolic.derivation import SYMBOLS, derive
from ..schema import CORE_NAMES
from ..symbolic.model import Parameters

__all__ = [
    "PARAMETER_ORDER",
    "STATE_ORDER",
    "EQUATION_GENERATORS",
    "EQUATION_ENTRIES",
    "equation_terms",
    "odd_under_reflection",
    "exact_explorer_js",
    "js_rows",
    "classic_js",
    "dop853_js",
    "generate",
    "parameter_vector",
]

from .conventions import PARAMETER_ORDER as KERNEL_ORDER, SCALAR_ORDER, STATE_ORDER, geometry_of, scalar_vector
from .tableau import dop853_js  # noqa: F401 - part of this module's interface

#: The parameter array ``p`` of the generated exports and the explorer: the scalars (their bodies
#: are baked in; the compiled kernels' ``p`` also holds the bodies' entries, :mod:`.conventions`).
PARAMETER_ORDER = SCALAR_ORDER
#: ``p`` of the exports for a numeric model (:data:`PARAMETER_ORDER`).
parameter_vector = scalar_vector


# -- the expressions to print -------------------------------------------------------------------
class _Expressions:
    """What the printers read of one derivation: M, f, T, Pi and Q at once; the derivatives (``dT_dq``,
    ``dPi_dq``, ``df_dy``, ``dM_dq``), the rod ends and the hinge axes when first read (a Taylor kernel
    reads none of them: for a general body their differentiation was 4 of its 11 s)."""

    def __init__(self, eom):
        self._eom = eom
        # immutable: one derivation is shared by every printer of the process (expressions' cache)
        self.M = sp.ImmutableMatrix(eom.mass_matrix)  # 2x2
        self.f = sp.ImmutableMatrix(eom.forcing)  # 2x1
        self.T: sp.Expr = eom.kinetic_energy
        self.Pi: sp.Expr = eom.potential_energy
        self.Q = sp.ImmutableMatrix(eom.generalized_forces)  # 2x1 generalised non-potential forces

    @cached_property
    def dT_dq(self) -> sp.Matrix:  # 2x1, partial derivative of T in q at fixed speeds
        return sp.ImmutableMatrix([self.T.diff(x) for x in _q()])

    @cached_property
    def dPi_dq(self) -> sp.Matrix:
        return sp.ImmutableMatrix([self.Pi.diff(x) for x in _q()])

    @cached_property
    def df_dy(self) -> sp.Matrix:  # 2x4
        return sp.ImmutableMatrix(self.f.jacobian(_q() + _dq()))

    @cached_property
    def dM_dq(self) -> Tuple[sp.Matrix, sp.Matrix]:
        q = _q()
        return (sp.ImmutableMatrix(self.M.diff(q[0])), sp.ImmutableMatrix(self.M.diff(q[1])))

    @cached_property
    def tips(self) -> sp.Matrix:  # 6x1: rod 1's end a j and rod 2's end, world frame
        return sp.ImmutableMatrix(_tips(self._eom))

    @cached_property
    def axes(self) -> sp.Matrix:  # 6x1: hinge 1's axis and hinge 2's current axis e = P1 . e0, world frame
        return sp.ImmutableMatrix(sp.Matrix.vstack(self._eom.steps["omega2"].diff(_dq()[0]), self._eom.steps["e"]))  # omega2 = phi' n1 + psi' e


def _q():
    return [SYMBOLS["phi"], SYMBOLS["psi"]]


def _dq():
    return [SYMBOLS["dphi"], SYMBOLS["dpsi"]]


@lru_cache(maxsize=16)
def expressions(geometry: Parameters) -> _Expressions:
    """The derivation of ``geometry`` for the printers, once per process and bodies (a model's kernel,
    its Taylor orders and its JavaScript read the same one)."""
    return _Expressions(derive(geometry))


def _tips(eom) -> sp.Matrix:
    """World positions of the rod ends: ``P1 . a j`` and ``P1 . a j + P . b j`` [m]."""
    j = sp.Matrix([0, 1, 0])
    a, b = SYMBOLS["a"], SYMBOLS["b"]
    tip1 = eom.steps["P1"] * j * a
    tip2 = tip1 + eom.steps["P"] * j * b
    return sp.Matrix.vstack(tip1, tip2)


# -- printing -----------------------------------------------------------------------------------------
class Lang:
    """How one target language writes assignments, reads inputs and forms a function."""

    def __init__(self, name: str, printer: Callable[[sp.Expr], str], declare: str, end: str):
        self.name, self.printer, self.declare, self.end = name, printer, declare, end

    def assign(self, target: str, expr: sp.Expr, indent: str) -> str:
        return f"{indent}{self.declare}{target} = {self.printer(expr)}{self.end}"


def _py_printer():
    from sympy.printing.pycode import PythonCodePrinter

    printer = PythonCodePrinter({"fully_qualified_modules": True, "standard": "python3"})
    return printer.doprint


def c_printer():
    from sympy.printing.c import C99CodePrinter

    return C99CodePrinter().doprint


def _js_printer():
    from sympy.printing.jscode import JavascriptCodePrinter

    return JavascriptCodePrinter().doprint


def cse_block(
    lang: Lang, exprs: Sequence[sp.Expr], targets: Sequence[str], indent: str, prefix: str = "x"
) -> List[str]:
    """Assignments computing ``targets = exprs`` with common subexpressions shared."""
    symbols = sp.numbered_symbols(prefix)
    replacements, reduced = sp.cse(list(exprs), symbols=symbols, optimizations="basic")
    lines = [lang.assign(str(sym), e, indent) for sym, e in replacements]
    lines += [lang.assign(t, e, indent) for t, e in zip(targets, reduced)]
    return lines


def param_lines(lang: Lang, indent: str, used: set) -> List[str]:
    return [
        f"{indent}{lang.declare}{n} = p[{i}]{lang.end}" for i, n in enumerate(KERNEL_ORDER) if n in used
    ]


def evaluation_lines(lang: Lang, exprs: Sequence[sp.Expr], targets: Sequence[str], indent: str, state: str = "y",
                     names: Sequence[str] = STATE_ORDER) -> List[str]:
    """``targets = exprs`` (:func:`cse_block`) after the state entries (``state[i]``, named ``names``) and the
    parameters they use."""
    used = used_names(exprs)
    lines = [f"{indent}{lang.declare}{n} = {state}[{i}]{lang.end}" for i, n in enumerate(names) if n in used]
    return lines + param_lines(lang, indent, used) + cse_block(lang, exprs, targets, indent)


def used_names(exprs: Sequence[sp.Expr]) -> set:
    names = set()
    for e in exprs:
        names |= {s.name for s in sp.sympify(e).free_symbols}
    return names


# -- standalone source for users -------------------------------------------------------------------------
def generate(params: Parameters, language: str) -> str:
    """Standalone source of the right-hand side and the energy in ``language``.

    ``language`` is ``"python"`` (``rhs(t, y, p)`` returning a list, ready for
    ``scipy.integrate.solve_ivp(rhs, ..., args=(p,))``), ``"c"`` (``skewpend_rhs``,
    ``skewpend_energy``) or ``"javascript"`` (``rhs(y, p)``, ``energy(y, p)``).  Geometry is
    baked in; scalar parameters are read from ``p`` in :data:`SCALAR_ORDER`.

    When ``a, b, m1, m2, g`` (and ``alpha`` if the model uses it) all have numeric values,
    the code also carries them as the default parameter vector, printed exactly (``P`` with
    ``rhs(t, y, p=P)`` in Python, ``SKEWPEND_P`` in C, ``P`` with ``rhs(y, p = P)`` in
    JavaScript); ``c1, c2, tau1, tau2`` then need numbers too (``Parameters`` defaults them
    to 0).  Some but not all of them numeric is refused (:class:`~skewpend.parsing.UsageError`),
    as is a symbolic name in the geometry, which the code could not read from ``p``.
    """
    from ..errors import ParameterError

    langs = {"python": _standalone_python, "c": _standalone_c, "javascript": _standalone_js}
    if language not in langs:
        raise ParameterError(f"unknown language {language!r}; allowed: {', '.join(langs)}")
    geometry = geometry_of(params)
    _check_geometry_numeric(geometry)
    values = _default_vector(params)
    return langs[language](expressions(geometry), geometry, values)


#: Scalars without a default value: given all as numbers (baked into ``P``) or none.
_CORE_SCALARS = CORE_NAMES


def _check_geometry_numeric(geometry: Parameters) -> None:
    """Refuse symbol names in bodies and axes: generated code reads only ``p`` (scalars)."""
    from ..parsing import UsageError

    extra = [n for n in geometry.symbolic_names if n not in SCALAR_ORDER]
    if extra:
        raise UsageError(
            f"generated code needs numeric bodies and axes (they are baked in); symbolic: {', '.join(extra)}; "
            "give com1, com2, inertia1, inertia2, axis1 and axis2 as numbers (or scalar parameter names)"
        )


def _default_vector(params: Parameters):
    """The numeric parameter vector in :data:`SCALAR_ORDER` to bake in as the default ``p``,
    or ``None`` when the scalars are left to run time; partial values are refused."""
    from ..parsing import UsageError

    core = [n for n in _CORE_SCALARS if n != "alpha" or params.uses_alpha]
    given = [n for n in core if getattr(params, n) is not None]
    rest = [n for n in SCALAR_ORDER if n not in _CORE_SCALARS]
    choices = (
        f"give all of {', '.join(core)} as numbers (the code then carries them as its default "
        "parameter vector P) or none of them (p is supplied at run time)"
    )
    if not given:
        ignored = [f"{n} = {getattr(params, n)!r}" for n in rest if getattr(params, n) not in (None, getattr(Parameters(), n))]
        if ignored:
            raise UsageError(f"generated code: {', '.join(ignored)} would be ignored without {', '.join(core)}; {choices}")
        return None
    missing = [n for n in core if n not in given]
    if missing:
        raise UsageError(f"generated code: numeric {', '.join(given)} but not {', '.join(missing)}; {choices}")
    symbolic = [n for n in rest if getattr(params, n) is None]
    if symbolic:
        raise UsageError(
            f"generated code with a default parameter vector P needs numbers for {', '.join(symbolic)} "
            "too (default 0), not symbolic"
        )
    return tuple(0.0 if getattr(params, n) is None else float(getattr(params, n)) for n in SCALAR_ORDER)


def _number(x: float) -> str:
    """``x`` exactly: the shortest decimal that reads back as the same double (Python's repr,
    also valid C and JavaScript, both of which round decimal literals correctly)."""
    return repr(float(x))


def _doc_lines(geometry: Parameters, values=None) -> List[str]:
    lines = [
        f"Generated by skewpend {__version__} from the symbolic derivation of the skewed double pendulum.",
        "State y = (phi, psi, dphi, dpsi): hinge angles [rad] (zero with both rods hanging) and their rates [rad/s].",
        f"Parameters p = ({', '.join(SCALAR_ORDER)}) in SI units; alpha in radians.",
        "Equations: M(q) q'' = f(q, q'), solved numerically (LDL^T of the symmetric positive-definite M).",
        "Geometry: " + ("thin uniform rods, default hinge axes" if geometry.is_thin_rods else str(geometry.to_dict())),
    ]
    if values is not None:
        shown = [
            f"{n} = {_number(v)}" for n, v in zip(SCALAR_ORDER, values) if n != "alpha" or geometry.uses_alpha
        ]
        unused = "" if geometry.uses_alpha else " (alpha unused: the second hinge axis is given)"
        lines.append(f"Values (the default parameter vector P): {', '.join(shown)}{unused}.")
    return lines


def _body(lang: Lang, ex: _Expressions, indent: str) -> Tuple[List[str], List[str]]:
    rhs_lines = evaluation_lines(lang, [ex.M[0, 0], ex.M[0, 1], ex.M[1, 1], ex.f[0], ex.f[1]],
                                 ["M11", "M12", "M22", "f1", "f2"], indent)
    rhs_lines += solve_lines(lang, ["M11", "M12", "M22"], ["f1", "f2"], ["ddphi", "ddpsi"], indent)
    return rhs_lines, evaluation_lines(lang, [ex.T + ex.Pi], ["E"], indent)


# -- the one linear solve ----------------------------------------------------------------------------
# M x = b for the symmetric positive-definite mass matrix, by its LDL^T factorisation, printed as
# straight-line assignments into every generated function (the compiled kernels, their SIMD lanes,
# the Taylor series, the standalone exports, the explorer's JavaScript): one algorithm, one printer.
# (Straight-line code, not calls of a C header's functions: in the long generated functions the
# compiler kept the header's small arrays in memory, 5-7 % of a Taylor step and of the flip map's
# lanes, measured; printed as named constants they cost what the 2 x 2 Cramer solve did.)


def _fma(a: str, b: str, c: str, fused: bool) -> str:
    """``a b + c``: fused (``SP_FMA``, the Taylor kernels' macro) or as a product and a sum."""
    if fused:
        return f"SP_FMA({a}, {b}, {c})"
    if a.startswith("-"):  # c - a' b: the same bits as (-a') b + c
        return f"{c} - {a[1:]} * {b}"
    return f"{a} * {b} + {c}"


def _packed_index(i: int, j: int) -> int:
    return i * (i + 1) // 2 + j


def ldlt_factor_steps(M: Sequence[str], prefix: str = "", fused: bool = False) -> List[Tuple[str, str]]:
    """The factorisation ``M = L D L^T`` as assignments: ``{prefix}iDi = 1/D_i`` and ``{prefix}Lij``
    below the diagonal (``M``: the packed lower triangle's names, row by row), one reciprocal per
    pivot.  (Sharing one reciprocal between the pivots, ``1/(M11 det M)``, overflows for masses or
    lengths far from 1 -- a = 1e100 gave zero accelerations -- where each pivot's own does not.)"""
    n = _order_of(M)

    def m(i, j):
        return M[_packed_index(i, j)]

    P = prefix
    steps: List[Tuple[str, str]] = []
    for i in range(n):
        w = []  # row i of L times D
        for j in range(i):
            u = m(i, j)
            for k in range(j):
                u = _fma(f"-{w[k]}", f"{P}L{j + 1}{k + 1}", u, fused)
            if j:
                steps.append((f"{P}U{i + 1}{j + 1}", u))
                u = f"{P}U{i + 1}{j + 1}"
            w.append(u)
            steps.append((f"{P}L{i + 1}{j + 1}", f"{u} * {P}iD{j + 1}"))
        d = m(i, i)
        for k in range(i):
            d = _fma(f"-{w[k]}", f"{P}L{i + 1}{k + 1}", d, fused)
        steps.append((f"{P}iD{i + 1}", f"1.0 / ({d})" if i else f"1.0 / {d}"))
    return steps


def ldlt_solve_steps(n: int, b: Sequence[str], x: Sequence[str], factors: str = "", prefix: str = "",
                     fused: bool = False) -> List[Tuple[str, str]]:
    """``M x = b`` with the factors of :func:`ldlt_factor_steps` (named with ``factors``):
    ``L z = b``, ``D y = z``, ``L^T x = y`` (temporaries ``{prefix}zi``)."""
    F = factors
    steps: List[Tuple[str, str]] = []
    z = list(b)
    for i in range(1, n):
        v = b[i]
        for k in range(i):
            v = _fma(f"-{F}L{i + 1}{k + 1}", z[k], v, fused)
        steps.append((f"{prefix}z{i + 1}", v))
        z[i] = f"{prefix}z{i + 1}"
    for i in reversed(range(n)):
        v = f"{z[i]} * {F}iD{i + 1}"
        for k in range(i + 1, n):
            v = _fma(f"-{F}L{k + 1}{i + 1}", x[k], v, fused)
        steps.append((x[i], v))
    return steps


def ldlt_inverse_steps(n: int, inv: Sequence[str], factors: str = "", prefix: str = "",
                       fused: bool = False) -> List[Tuple[str, str]]:
    """``M^-1`` (its packed lower triangle, named ``inv``) from the factors of :func:`ldlt_factor_steps`:
    column j solves ``M x = e_j`` for its rows from j on (``L z = e_j``, ``D y = z``, ``L^T x = y``).
    For one matrix applied to many right-hand sides one after another (the Taylor series: ``M[0]``
    at every order), where each product (:func:`spd_mul_steps`) is a shorter chain of dependent
    operations than the substitutions."""
    F = factors
    steps: List[Tuple[str, str]] = []
    for j in range(n):
        z = {}
        for i in range(j + 1, n):  # L z = e_j (z_j = 1)
            v = f"-{F}L{i + 1}{j + 1}"
            for k in range(j + 1, i):
                v = _fma(f"-{F}L{i + 1}{k + 1}", z[k], v, fused)
            z[i] = f"{prefix}z{i + 1}_{j + 1}"
            steps.append((z[i], v))
        x = {}
        for i in range(j, n):  # D y = z
            x[i] = inv[_packed_index(i, j)] if i == n - 1 else f"{prefix}y{i + 1}_{j + 1}"
            steps.append((x[i], f"{F}iD{i + 1}" if i == j else f"{z[i]} * {F}iD{i + 1}"))
        for i in range(n - 2, j - 1, -1):  # L^T x = y
            v = x[i]
            for k in range(i + 1, n):
                v = _fma(f"-{F}L{k + 1}{i + 1}", x[k], v, fused)
            x[i] = inv[_packed_index(i, j)]
            steps.append((x[i], v))
    return steps


def spd_mul_steps(S: Sequence[str], b: Sequence[str], x: Sequence[str], fused: bool = False) -> List[Tuple[str, str]]:
    """``x = S b`` for a symmetric ``S`` given as its packed lower triangle (such as
    :func:`ldlt_inverse_steps`' ``M^-1``): ``x_i = (((S_i1 b_1 + S_i2 b_2) + ...) + S_in b_n)``, each
    addition fused with its product.  ``b_n`` enters last, through one fused add: where ``b``'s
    entries are computed one after another (the Taylor series' orders, ``b_n`` last) the solution
    waits for ``b_n`` by one operation, not two (measured: summing from ``b_n`` down cost 5-10 %
    of a Taylor step at order 15)."""
    n = len(b)
    out = []
    for i in range(n):
        v = f"{S[_packed_index(i, 0)]} * {b[0]}"
        for j in range(1, n):
            v = _fma(S[_packed_index(max(i, j), min(i, j))], b[j], v, fused)
        out.append((x[i], v))
    return out


def _order_of(M: Sequence[str]) -> int:
    n = int(round(((8 * len(M) + 1) ** 0.5 - 1) / 2))
    if n * (n + 1) // 2 != len(M):
        raise ValueError(f"{len(M)} matrix entries: the packed triangle of n x n has n (n + 1) / 2")
    return n


def ldlt_steps(M: Sequence[str], b: Sequence[str], x: Sequence[str], fused: bool = False) -> List[Tuple[str, str]]:
    """``M x = b`` for a symmetric positive-definite ``M`` (the mass matrix) by its LDL^T factorisation,
    as assignments ``(target, expression)`` in the arithmetic common to Python, C and JavaScript
    (:func:`ldlt_factor_steps`, then :func:`ldlt_solve_steps`).

    ``M``: the names of the packed lower triangle, row by row (``M11, M21, M22, M31, ...``; for
    n = 2 ``M11, M12, M22``); ``b``, ``x``: the names of the right-hand side and of the solution
    (n each).  For n = 2: ``iD1 = 1/M11, L21 = M12 iD1, iD2 = 1/(M22 - M12 L21)``, then
    ``z2 = b2 - L21 b1, x2 = z2 iD2, x1 = b1 iD1 - L21 x2``."""
    n = len(b)
    if len(M) != n * (n + 1) // 2 or len(x) != n:
        raise ValueError(f"ldlt_steps: {len(M)} matrix entries, {len(b)} right-hand sides and {len(x)} unknowns "
                         "(the packed triangle of n x n has n (n + 1) / 2)")
    return ldlt_factor_steps(M, fused=fused) + ldlt_solve_steps(n, b, x, fused=fused)


def solve_lines(lang: Lang, M: Sequence[str], b: Sequence[str], x: Sequence[str], indent: str) -> List[str]:
    """:func:`ldlt_steps` printed in ``lang``: the standalone exports' and the explorer's solve."""
    return [f"{indent}{lang.declare}{t} = {e}{lang.end}" for t, e in ldlt_steps(M, b, x)]


def spd_c_lines(indent: str, b: Sequence[str], x: Sequence[str], *, M: Sequence[str] = (), factors: str = "sp_m_",
                prefix: str = "sp_", fused: bool = False) -> List[str]:
    """C constants that solve ``M x = b`` (the compiled kernels): ``M`` given (the packed lower
    triangle's names), its factors are computed first, named with ``factors``; otherwise those of an
    earlier call with the same ``factors`` are used (one factorisation, several right-hand sides)."""
    lines = []
    if M:
        lines += [f"{indent}const double {t} = {e};" for t, e in ldlt_factor_steps(M, factors, fused)]
    lines += [f"{indent}const double {t} = {e};" for t, e in ldlt_solve_steps(len(b), b, x, factors, prefix, fused)]
    return lines


#: The state functions the entries of M and f are polynomials in (the equations' "monomials").
EQUATION_GENERATORS = ("sin(phi)", "cos(phi)", "sin(psi)", "cos(psi)", "dphi", "dpsi")
#: The entries of the equations of motion, in the order of :func:`equation_terms`' output.
EQUATION_ENTRIES = ("M11", "M12", "M22", "f1", "f2")


def equation_terms(M, f) -> List[Tuple[str, Tuple[int, ...], sp.Expr, sp.Expr]]:
    """The entries of ``M`` and ``f`` as sums of coefficients times monomials in
    :data:`EQUATION_GENERATORS`: ``(entry, exponents, monomial, coefficient)`` for every term
    (the coefficient free of the state), in display order -- the mass matrix's constant term
    first; the forcing's speed-squared terms, then the gravity terms, the damping terms and the
    constant torque; within each, more trigonometric factors first (the mass matrix: fewer).  Raises ValueError for an entry that is not such a polynomial."""
    s = SYMBOLS
    gens = [sp.sin(s["phi"]), sp.cos(s["phi"]), sp.sin(s["psi"]), sp.cos(s["psi"]), s["dphi"], s["dpsi"]]
    state = {s["phi"], s["psi"], s["dphi"], s["dpsi"]}
    out = []
    for name, expr in zip(EQUATION_ENTRIES, [M[0, 0], M[0, 1], M[1, 1], f[0], f[1]]):
        poly = sp.Poly(sp.expand(expr), *gens)
        rows = []
        for exps, coeff in poly.terms():
            if coeff.free_symbols & state:
                raise ValueError(f"{name} is not a polynomial in {', '.join(EQUATION_GENERATORS)}")
            monomial = sp.Mul(*[g**e for g, e in zip(gens, exps)])
            speeds, trig = exps[4] + exps[5], sum(exps[:4])
            rank = (trig,) if name.startswith("M") else ({2: 0, 0: 1, 1: 2}[speeds] + (3 if speeds + trig == 0 else 0), -trig)
            rows.append((rank, name, tuple(int(e) for e in exps), monomial, coeff))
        out += [row[1:] for row in sorted(rows, key=lambda r: r[0])]
    return out


def exact_explorer_js(printed: Parameters, values: Sequence[float]) -> str:
    """The explorer's physics in the exact form (:func:`skewpend.numeric.explorer_source.explorer_js`'s contract)
    for the double pendulum's parameters ``printed``, ``values`` its parameter vector ``P`` in
    :data:`SCALAR_ORDER`: the derivation's expressions, every scalar read from ``p`` (the sliders change ``p``,
    never the code)."""
    head = [f"export const P = [{', '.join(_number(v) for v in values)}];"]
    from ..symbolic.render import tex

    geometry = geometry_of(printed)
    _check_geometry_numeric(geometry)
    ex = expressions(geometry)
    lang = Lang("javascript", _js_printer(), "const ", ";")
    rhs, en = _body(lang, ex, "  ")
    doc = "\n".join(" * " + line for line in _doc_lines(geometry, None))
    out = ["/**", doc, " */", "", f"export const PARAMETER_ORDER = [{', '.join(repr(n) for n in SCALAR_ORDER)}];",
           "/** the model's values (the default parameter vector; the sliders' start) */", *head, "export const N = 2;", "",
           "/** dy/dt = [dphi, dpsi, ddphi, ddpsi] */", "export function rhs(y, p = P) {", *rhs,
           "  return [y[2], y[3], ddphi, ddpsi];", "}", "",
           "/** mechanical energy T + Pi [J] */", "export function energy(y, p = P) {", *en, "  return E;", "}", ""]
    q = [SYMBOLS["phi"], SYMBOLS["psi"]]
    rest = {q[0]: 0, q[1]: 0}
    hess = sp.hessian(ex.Pi, q)
    linear = [ex.M[i, j].subs(rest) for i in range(2) for j in range(2)] + [hess[i, j].subs(rest) for i in range(2) for j in range(2)]
    for name, exprs, doc_line in (("tips", list(ex.tips), "rod ends [x1, y1, z1, x2, y2, z2] [m] (j points down)"),
                                  ("hinges", [sp.Integer(0)] * 3 + list(ex.tips)[:3],
                                   "the hinges' positions [0, 0, 0, x2, y2, z2] [m]: the roof's, and hinge 2 at rod 1's "
                                   "end (the drawings join the rods there)"),
                                  ("axes", list(ex.axes), "hinge axes [n1x, n1y, n1z, ex, ey, ez]: n1 fixed, e = P1 . e0"),
                                  ("linear", linear, "the linearisation at rest (phi = psi = 0): [M0, K0], M0 = M(0), "
                                   "K0 = the Hessian of Pi (y is not read)")):
        body = evaluation_lines(lang, exprs, [f"r{i}" for i in range(len(exprs))], "  ")
        ret = (f"[{js_rows(2, lambda i, j: f'r{2 * i + j}')}, {js_rows(2, lambda i, j: f'r{4 + 2 * i + j}')}]" if name == "linear"
               else "[" + ", ".join(f"r{i}" for i in range(len(exprs))) + "]")
        out += [f"/** {doc_line} */", f"export function {name}(y, p = P) {{", *body, f"  return {ret};", "}", ""]
    terms = equation_terms(ex.M, ex.f)
    listed = ",\n".join(f"  [{json.dumps(name)}, {list(exps)}, {json.dumps(_compact_trig(tex(mono)) if mono != 1 else '')}]"
                        for name, exps, mono, _ in terms)
    coeffs = [c for *_, c in terms]
    body = param_lines(lang, "  ", used_names(coeffs))
    body += cse_block(lang, coeffs, [f"k{i}" for i in range(len(coeffs))], "  ")
    out += [f"/** the terms of the equations of motion: [entry ({', '.join(EQUATION_ENTRIES)}), exponents of "
            f"({', '.join(EQUATION_GENERATORS)}), LaTeX of the monomial] */",
            f"export const TERMS = [\n{listed}\n];", "",
            "/** the coefficient of each of TERMS for the parameters p */", "export function coefficients(p = P) {", *body,
            f"  return [{', '.join(f'k{i}' for i in range(len(coeffs)))}];", "}", "",
            "/** without torques the equations are odd under (q, q') -> -(q, q'): mirror starts flip alike */",
            f"export const FLIP_ODD = {'true' if odd_under_reflection(ex) else 'false'};", ""]
    return "\n".join(out)


def js_rows(n: int, entry) -> str:
    """An n x n JavaScript array of the names ``entry(i, j)``."""
    return "[" + ", ".join("[" + ", ".join(entry(i, j) for j in range(n)) + "]" for i in range(n)) + "]"


def odd_under_reflection(ex) -> bool:
    """Whether, without joint torques, the equations are odd under ``(q, q') -> -(q, q')``:
    ``M(-q) = M(q)`` and ``f(-q, -q') = -f(q, q')`` identically (an exact symbolic check).  Then
    the start at rest ``-q0`` moves as the mirror image of ``q0`` and flips at the same time."""
    s = SYMBOLS
    mirror = {s[n]: -s[n] for n in STATE_ORDER}
    no_torque = {s["tau1"]: 0, s["tau2"]: 0}
    for sign, entries in ((-1, ex.M), (1, ex.f)):  # M even, f odd
        for e in entries:
            e = sp.sympify(e).subs(no_torque)
            if sp.expand(e.xreplace(mirror) + sign * e) != 0:
                return False
    return True


def _compact_trig(latex: str) -> str:
    """``\\sin^{2}{\\left(\\psi \\right)}`` -> ``\\sin^{2}\\psi``: a function of one angle without brackets."""
    return re.sub(r"\\(sin|cos)(\^\{\d+\})?\{\\left\((\\varphi|\\psi) \\right\)\}", r"\\\1\2\3", latex)


def classic_js(module: str, name: str) -> str:
    """A generated ES module (its exports all ``export const`` / ``export function`` at the start
    of a line) as a classic script defining ``self[name]`` -- for a Web Worker built from text."""
    exported = re.findall(r"^export (?:const|function) ([A-Za-z_]\w*)", module, flags=re.M)
    body = re.sub(r"^export ", "", module, flags=re.M)
    if "export " in re.sub(r"/\*.*?\*/", "", body, flags=re.S):
        raise ValueError("classic_js: an export that is not a top-level const or function")
    return f"self.{name} = (() => {{\n{body}\nreturn {{ {', '.join(exported)} }};\n}})();\n"


def _standalone_python(ex: _Expressions, geometry: Parameters, values=None) -> str:
    lang = Lang("python", _py_printer(), "", "")
    rhs, en = _body(lang, ex, "    ")
    doc = "\n".join(_doc_lines(geometry, values))
    pdef, head = "p", []
    if values is not None:
        pdef = "p=P"
        head = ["", "", f"#: Default parameter vector ({', '.join(SCALAR_ORDER)}): the values given.",
                f"P = ({', '.join(_number(v) for v in values)})"]
    return "\n".join(
        [f'"""{doc}\n"""', "import math", *head, "", "",
         f"def rhs(t, y, {pdef}):", '    """dy/dt = (dphi, dpsi, ddphi, ddpsi); signature of scipy.integrate.solve_ivp."""',
         *rhs, "    return [y[2], y[3], ddphi, ddpsi]", "", "",
         f"def energy(y, {pdef}):", '    """Mechanical energy T + Pi [J]; Pi = 0 with both rods hanging."""',
         *en, "    return E", ""]
    )


def _standalone_c(ex: _Expressions, geometry: Parameters, values=None) -> str:
    lang = Lang("c", c_printer(), "const double ", ";")
    rhs, en = _body(lang, ex, "    ")
    doc = "\n".join(" * " + line for line in _doc_lines(geometry, values))
    head = []
    if values is not None:
        head = [f"/* default parameter vector ({', '.join(SCALAR_ORDER)}): the values given */",
                "#if defined(__GNUC__) || defined(__clang__)",
                "__attribute__((unused))",
                "#endif",
                f"static const double SKEWPEND_P[{len(SCALAR_ORDER)}] = {{{', '.join(_number(v) for v in values)}}};", ""]
    return "\n".join(
        ["/*", doc, " */", "#include <math.h>", "", *head,
         "/* dydt = (dphi, dpsi, ddphi, ddpsi) */",
         f"void skewpend_rhs(const double y[4], const double p[{len(SCALAR_ORDER)}], double dydt[4])", "{",
         *rhs, "    dydt[0] = y[2];", "    dydt[1] = y[3];", "    dydt[2] = ddphi;", "    dydt[3] = ddpsi;", "}", "",
         "/* mechanical energy T + Pi [J] */",
         f"double skewpend_energy(const double y[4], const double p[{len(SCALAR_ORDER)}])", "{", *en, "    return E;", "}", ""]
    )


def _standalone_js(ex: _Expressions, geometry: Parameters, values=None) -> str:
    lang = Lang("javascript", _js_printer(), "const ", ";")
    rhs, en = _body(lang, ex, "  ")
    doc = "\n".join(" * " + line for line in _doc_lines(geometry, values))
    pdef, head = "p", []
    if values is not None:
        pdef = "p = P"
        head = [f"/** default parameter vector [{', '.join(SCALAR_ORDER)}]: the values given */",
                f"export const P = [{', '.join(_number(v) for v in values)}];", ""]
    return "\n".join(
        ["/**", doc, " */", "", *head,
         "/** dy/dt = [dphi, dpsi, ddphi, ddpsi] */",
         f"export function rhs(y, {pdef}) {{", *rhs, "  return [y[2], y[3], ddphi, ddpsi];", "}", "",
         "/** mechanical energy T + Pi [J] */",
         f"export function energy(y, {pdef}) {{", *en, "  return E;", "}", ""]
    )
