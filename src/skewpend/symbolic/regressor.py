"""The equations of motion are linear in the inertial parameters: the regressor and the base parameters.

For each body ``i`` the *standard inertial parameters* are its mass ``m_i``, its first moment
``h_i = m_i c_i`` about its hinge point (body frame: body 1's origin is the roof hinge, body 2's
the second hinge) and its inertia tensor about the hinge point
``J_i = I_ci + m_i (|c_i|^2 E - c_i c_i^T)`` (six entries, tensor components: an off-diagonal
entry is minus a product of inertia).  With the viscous damping ``c1, c2`` they form the
22-vector ``pi`` (:data:`PI_NAMES`).  The joint torques needed for a motion are then

    tau = M(q) q'' - f(q, q') = Y(q, q', q''; a, alpha, g) pi

(``f`` without the torques; the damping ``c_i q_i'`` is in ``Y pi``).  ``Y`` is obtained from the
derivation itself (:func:`skewpend.derive` with symbolic bodies: ``com = h/m``,
``inertia = J - (|h|^2 E - h h^T)/m`` substituted, then the Jacobian in ``pi``; the remainder
``Y pi - (M q'' - f)`` is checked to be exactly zero).  The hinge distance ``a``, the skew
angle ``alpha`` and gravity ``g`` stay arguments of ``Y``: ``g`` multiplies the first moments and
``m2`` in their gravity terms.

The data determine only the *base parameters*: the column space of ``Y``.  :func:`base_parameters`
finds its rank and a set of independent columns (numerically, on seeded random samples), and the
exact linear relation of every other column to them (symbolically, from the coefficients of
``Y`` in the trigonometric monomials of the state).  Each base parameter is a pivot entry of
``pi`` plus the dependent entries that move with it, ``beta = pi_P + K pi_D``, and
``Y pi = Y_P beta``.  :func:`linear_estimate` is the lab's first estimate: weighted least squares
on ``Y_b beta = tau``, or, for free motion (``tau = 0``, homogeneous), the null vector of ``Y_b``
normalised by one base parameter (the overall scale is undetermined).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from functools import lru_cache
from typing import Callable, Dict, List, Optional, Sequence, Tuple

import numpy as np
import sympy as sp

from ..errors import ParameterError
from ..schema import DAMPING_NAMES, LENGTH_NAMES, MASS_NAMES, names
from .model import Parameters
from .symbols import SYMBOLS

__all__ = [
    "PI_NAMES",
    "Regressor",
    "regressor",
    "BaseParameters",
    "base_parameters",
    "LinearEstimate",
    "linear_estimate",
    "standard_parameters",
    "PIVOT_ORDER",
    "independent_columns",
    "lambdify_columns",
    "sample_states",
    "SCALE_DIRECTION",
]

_AXES = "xyz"
_PAIRS = ("xx", "xy", "xz", "yy", "yz", "zz")


def _body_names(i: int) -> Tuple[str, ...]:
    return (f"m{i}",) + tuple(f"h{i}{x}" for x in _AXES) + tuple(f"J{i}{p}" for p in _PAIRS)


#: Names of the standard parameter vector ``pi``, in its order.
PI_NAMES: Tuple[str, ...] = _body_names(1) + _body_names(2) + DAMPING_NAMES

#: The direction free motion cannot determine, in physical terms.
SCALE_DIRECTION = "one overall scale of every inertial parameter and damping"

#: The default preference for pivots (the entry a base parameter is named after): each body's
#: inertia about its hinge axis first (``J1zz``; body 2's ``J2zz``, nearly its axis for small
#: ``alpha``), then first moments along the rod (``y``), the mass last (it is lumped into them).
PIVOT_ORDER: Tuple[str, ...] = tuple(
    name for i, mass in enumerate(MASS_NAMES, start=1)
    for name in tuple(f"J{i}{p}" for p in ("zz", "xz", "yz", "xy", "xx", "yy")) + tuple(f"h{i}{x}" for x in "yxz") + (mass,)
) + DAMPING_NAMES

#: The model's values the regressor is a function of (besides the state): where hinge 2 sits on
#: rod 1 (its length), the skew and gravity.
STRUCTURE: Tuple[str, ...] = (LENGTH_NAMES[0],) + names(kind="scalar", role="axis") + names(role="world")
_ARGS = ("phi", "psi", "dphi", "dpsi", "ddphi", "ddpsi") + STRUCTURE


def _pi_symbol(name: str) -> sp.Symbol:
    if name in SYMBOLS:  # m1, m2, c1, c2: the derivation's own symbols
        return SYMBOLS[name]
    return sp.Symbol(name, real=True)


PI_SYMBOLS: Tuple[sp.Symbol, ...] = tuple(_pi_symbol(n) for n in PI_NAMES)


def standard_parameters(params: Parameters) -> np.ndarray:
    """The standard parameter vector ``pi`` (:data:`PI_NAMES`) of a numeric model.

    Thin rods (the default bodies) and general bodies alike: ``h = m c``,
    ``J = I_c + m (|c|^2 E - c c^T)``.
    """
    p = params
    out = []
    for i, (m, length) in enumerate(((p.m1, p.a), (p.m2, p.b)), start=1):
        if m is None or length is None:
            raise ParameterError(f"standard_parameters needs numeric m{i} and rod lengths")
        com = getattr(p, f"com{i}")
        inertia = getattr(p, f"inertia{i}")
        c = np.array([0.0, length / 2, 0.0]) if com is None else np.array(com, dtype=float)
        ic = m * length**2 / 12 * np.diag([1.0, 0.0, 1.0]) if inertia is None else np.array(inertia, dtype=float)
        J = ic + m * (c @ c * np.eye(3) - np.outer(c, c))
        out += [m, *(m * c)] + [J[0, 0], J[0, 1], J[0, 2], J[1, 1], J[1, 2], J[2, 2]]
    out += [float(p.c1), float(p.c2)]
    return np.array(out, dtype=float)


# -- the regressor ----------------------------------------------------------------------------------
def _axes_key(geometry: Optional[Parameters]) -> Tuple:
    g = geometry if geometry is not None else Parameters()
    return (g.axis1, g.axis2)


@dataclass(frozen=True)
class Regressor:
    """``tau = Y(q, q', q''; a, alpha, g) pi`` for the hinge axes of one geometry.

    ``Y`` is a 2 x 22 SymPy matrix in :data:`~skewpend.symbolic.symbols.SYMBOLS`
    (``phi, psi, dphi, dpsi, ddphi, ddpsi, a, alpha, g``); ``pi`` the symbols of :data:`PI_NAMES`.
    ``lhs`` is the derivation's ``M q'' - f`` (torques zero) in terms of ``pi``;
    ``seconds`` the time the derivation and the check took.
    """

    axes: Tuple
    Y: sp.Matrix
    pi: Tuple[sp.Symbol, ...]
    lhs: sp.Matrix
    seconds: float
    names: Tuple[str, ...] = PI_NAMES

    @property
    def uses_alpha(self) -> bool:
        return self.axes[1] is None

    def column(self, name: str) -> sp.Matrix:
        return self.Y[:, self.names.index(name)]

    def numeric(self) -> Callable:
        """``Y(q, dq, ddq, a, alpha, g) -> (N, 2, 22)`` (NumPy, vectorised over rows)."""
        return lambdify_columns(self.Y)


@lru_cache(maxsize=8)
def _regressor(axes: Tuple) -> Regressor:
    import time

    from .derivation import derive

    t0 = time.perf_counter()
    axis1, axis2 = axes
    sym = Parameters(com1="sym", com2="sym", inertia1="sym", inertia2="sym", axis1=axis1, axis2=axis2,
                     c1=None, c2=None, tau1=0.0, tau2=0.0)
    eom = derive(sym)
    S = SYMBOLS
    ddq = sp.Matrix([S["ddphi"], S["ddpsi"]])
    # M q'' - f with f = f0 - c dq (torques 0): the torques the motion needs.
    lhs0 = eom.mass_matrix * ddq - eom.forcing
    pis = dict(zip(PI_NAMES, PI_SYMBOLS))
    subs = {}
    for i in (1, 2):
        m = pis[f"m{i}"]
        h = [pis[f"h{i}{x}"] for x in _AXES]
        hh = sum(x * x for x in h)
        for k, x in enumerate(_AXES):
            subs[sp.Symbol(f"r{i}{x}", real=True)] = h[k] / m
        for p in _PAIRS:
            k, l = _AXES.index(p[0]), _AXES.index(p[1])
            # I_c = J - (|h|^2 E - h h^T) / m
            subs[sp.Symbol(f"I{i}{p}", real=True)] = pis[f"J{i}{p}"] - ((hh if k == l else 0) - h[k] * h[l]) / m
    # the derivation reduced each entry with cos^2 + sin^2 = 1 in its own shortest way: the 1/m
    # terms of the substitution cancel in the canonical form
    lhs = lhs0.xreplace(subs).applyfunc(_canonical)
    pi = sp.Matrix(PI_SYMBOLS)
    Y = lhs.jacobian(pi).applyfunc(lambda e: _chop(sp.expand(e)))
    bad = Y.free_symbols & set(PI_SYMBOLS)
    if bad:  # the derivation is not linear in pi: a bug, never a user error
        raise AssertionError(f"the equations are not linear in the inertial parameters: Y depends on {sorted(map(str, bad))}")
    rest = (lhs - Y * pi).applyfunc(_canonical)
    if any(x != 0 for x in rest):
        raise AssertionError("Y pi differs from the derived equations")
    stray = Y.free_symbols - {S[n] for n in _ARGS}
    if stray:
        raise AssertionError(f"Y depends on {sorted(map(str, stray))}")
    return Regressor(axes=axes, Y=Y, pi=PI_SYMBOLS, lhs=lhs, seconds=time.perf_counter() - t0)


def regressor(geometry: Optional[Parameters] = None) -> Regressor:
    """The regressor of the model with the hinge axes of ``geometry`` (default: ``axis1 = k`` and
    ``axis2 = e0(alpha)``).  Every inertial parameter, the damping, ``a``, ``alpha`` and ``g``
    are free: only ``axis1`` and ``axis2`` of ``geometry`` are used.  Cached per axes."""
    if geometry is not None and not isinstance(geometry, Parameters):
        raise ParameterError(f"geometry must be a skewpend Parameters, got {geometry!r}")
    return _regressor(_axes_key(geometry))


def lambdify_columns(Y: sp.Matrix) -> Callable:
    """A NumPy function ``(q, dq, ddq, a, alpha, g) -> (N, 2, ncol)`` generated from ``Y`` (cse)."""
    S = SYMBOLS
    args = [S[n] for n in _ARGS]
    rows, cols = Y.shape
    flat = [Y[i, j] for i in range(rows) for j in range(cols)]
    fn = sp.lambdify(args, flat, modules="numpy", cse=True)

    def evaluate(q, dq, ddq, a, alpha, g):
        q, dq, ddq = (np.atleast_2d(np.asarray(x, dtype=float)) for x in (q, dq, ddq))
        n = max(len(q), len(dq), len(ddq))
        vals = fn(q[:, 0], q[:, 1], dq[:, 0], dq[:, 1], ddq[:, 0], ddq[:, 1], float(a), float(alpha), float(g))
        out = np.empty((n, rows * cols))
        for k, v in enumerate(vals):
            out[:, k] = np.broadcast_to(v, (n,))
        return out.reshape(n, rows, cols)

    return evaluate


# -- base parameters ----------------------------------------------------------------------------------
_ANGLES = ("phi", "psi", "alpha")
_C = {n: sp.Symbol(f"C_{n}", real=True) for n in _ANGLES}
_S = {n: sp.Symbol(f"S_{n}", real=True) for n in _ANGLES}
#: ``cos``, ``sin`` of the angles and the polynomial symbols that stand for them.
_TRIG = {**{sp.cos(SYMBOLS[n]): _C[n] for n in _ANGLES}, **{sp.sin(SYMBOLS[n]): _S[n] for n in _ANGLES}}


def _to_poly_symbols(expr: sp.Expr) -> sp.Expr:
    return expr.xreplace(_TRIG)


def _reduce(expr: sp.Expr) -> sp.Expr:
    """Canonical form modulo ``sin^2 + cos^2 = 1`` for ``phi, psi, alpha`` (in the symbols
    ``S_x, C_x``): every even power of a sine replaced, so each sine has degree at most 1."""
    expr = sp.expand(expr)
    if expr == 0:
        return sp.S.Zero
    for n in _ANGLES:
        s, c = _S[n], _C[n]
        if not expr.has(s):
            continue
        poly = sp.Poly(expr, s)
        out = sp.S.Zero
        for (k,), coeff in poly.terms():
            out += coeff * s ** (k % 2) * (1 - c**2) ** (k // 2)
        expr = sp.expand(out)
    return expr


def _chop(expr: sp.Expr, rel: float = 1e-13) -> sp.Expr:
    """Drop the terms of an expanded sum whose float coefficient is rounding next to the largest
    (a user's numeric hinge axis enters the derivation as floats: ``1/|v|`` is irrational)."""
    if not expr.has(sp.Float) or not isinstance(expr, sp.Add):
        return expr
    coeffs = [abs(float(t.as_coeff_Mul()[0])) for t in expr.args]
    big = max(coeffs)
    return sp.Add(*[t for t, c in zip(expr.args, coeffs) if c > rel * big])


def _scale(M: sp.Matrix) -> float:
    return max((abs(float(t.as_coeff_Mul()[0])) for x in M for t in sp.Add.make_args(sp.expand(x)) if x != 0),
               default=1.0)


def _chop_matrix(M: sp.Matrix, scale: Optional[float] = None, rel: float = 1e-12) -> sp.Matrix:
    """Drop float terms below ``rel`` times the largest coefficient of the whole matrix."""
    big = _scale(M) if scale is None else scale

    def chop(x):
        x = sp.expand(x)
        return sp.Add(*[t for t in sp.Add.make_args(x) if abs(float(t.as_coeff_Mul()[0])) > rel * big])

    return M.applyfunc(chop)


def _canonical(expr: sp.Expr) -> sp.Expr:
    """``expr`` (in ``cos``, ``sin``) reduced as :func:`_reduce` does, back in ``cos``, ``sin``."""
    return _chop(_reduce(_to_poly_symbols(expr))).xreplace({v: k for k, v in _TRIG.items()})


_STATE_GENS = [_S["phi"], _C["phi"], _S["psi"], _C["psi"], SYMBOLS["dphi"], SYMBOLS["dpsi"], SYMBOLS["ddphi"],
               SYMBOLS["ddpsi"]]


@lru_cache(maxsize=8)
def _coefficients(axes: Tuple) -> Tuple[sp.Matrix, Tuple]:
    """``Y`` as coefficients of reduced trigonometric monomials of the state: rows (equation, monomial)."""
    reg = _regressor(axes)
    table: Dict[Tuple[int, Tuple[int, ...]], Dict[int, sp.Expr]] = {}
    for i in range(2):
        for j in range(reg.Y.shape[1]):
            e = _reduce(_to_poly_symbols(reg.Y[i, j]))
            if e == 0:
                continue
            for monom, coeff in sp.Poly(e, *_STATE_GENS).terms():
                table.setdefault((i, monom), {})[j] = coeff.as_expr()
    keys = sorted(table)
    C = sp.zeros(len(keys), reg.Y.shape[1])
    for r, k in enumerate(keys):
        for j, v in table[k].items():
            C[r, j] = v
    return C, tuple(keys)


def sample_states(n: int, seed: int, nq: int = 2):
    """``n`` seeded random states ``(q, q', q'')`` of ``nq`` coordinates each."""
    rng = np.random.default_rng(seed)
    q = rng.uniform(-math.pi, math.pi, (n, nq))
    dq = rng.normal(0, 2.0, (n, nq))
    ddq = rng.normal(0, 5.0, (n, nq))
    return q, dq, ddq


def independent_columns(A: np.ndarray, order: Sequence[int], tol: float = 1e-9) -> List[int]:
    """Columns of ``A`` taken greedily in ``order`` when they raise the rank (columns scaled)."""
    norms = np.linalg.norm(A, axis=0)
    B = A / np.where(norms > 0, norms, 1.0)
    zero = 1e-10 * norms.max() if norms.size else 0.0  # a column of rounding errors (cancelled terms) is zero
    chosen: List[int] = []
    for j in order:
        if norms[j] <= zero:
            continue
        trial = B[:, chosen + [j]]
        if trial.shape[1] > trial.shape[0]:
            break
        s = np.linalg.svd(trial, compute_uv=False)
        if s[-1] > tol * s[0]:
            chosen.append(j)
    return chosen


def _exact_angle(x: float) -> sp.Expr:
    """An angle as an exact multiple of pi when it is one with a small denominator, else a Float."""
    r = sp.nsimplify(x / math.pi, rational=True, tolerance=1e-12)
    if isinstance(r, sp.Rational) and r.q <= 12:
        return sp.pi * r
    return sp.Float(x)


def _tidy(expr: sp.Expr) -> sp.Expr:
    """A rational function of ``a, g, cos(alpha), sin(alpha)`` in a short form."""
    expr = sp.factor(sp.cancel(expr))
    S = SYMBOLS
    expr = expr.xreplace({_C["alpha"]: sp.cos(S["alpha"]), _S["alpha"]: sp.sin(S["alpha"])})
    if expr.has(S["alpha"]):
        expr = sp.factor(sp.trigsimp(expr))
    return expr


@dataclass(frozen=True)
class BaseParameters:
    """The combinations of the standard parameters ``pi`` that the data determine.

    * ``names`` -- one per base parameter: the pivot entry of ``pi`` it is named after, with
      ``_b`` appended when other entries move with it (``J1zz_b = J1zz + a**2*m2``);
    * ``expressions`` -- each as a SymPy expression of ``pi`` (and ``a``, ``alpha``);
    * ``matrix`` -- ``beta = matrix * pi`` (SymPy, r x 22; :meth:`matrix_at` numeric);
    * ``pivots``, ``dependent`` -- indices into :data:`PI_NAMES`; ``relations`` the exact
      ``Y_D = Y_P relations``;
    * ``unidentifiable`` -- entries of ``pi`` that do not enter the equations at all;
    * ``regressor`` -- ``Y_b(q, dq, ddq, a, alpha, g) -> (N, 2, r)``, generated from the pivot
      columns of ``Y`` (``tau = Y_b beta``);
    * ``where`` -- the (a, alpha, g) the rank was found at (``None`` = generic, random values).

    The equations are homogeneous in ``beta`` for free motion (no torques): only ratios are
    determined; :meth:`ratios` names them and :data:`SCALE_DIRECTION` the undetermined direction.
    """

    names: Tuple[str, ...]
    expressions: Tuple[sp.Expr, ...]
    matrix: sp.Matrix
    pivots: Tuple[int, ...]
    dependent: Tuple[int, ...]
    relations: sp.Matrix
    regressor: Callable = field(repr=False, compare=False)
    where: Dict[str, Optional[float]] = field(default_factory=dict)
    symbolic_regressor: sp.Matrix = field(default=None, repr=False, compare=False)
    seconds: float = 0.0

    @property
    def rank(self) -> int:
        return len(self.names)

    @property
    def unidentifiable(self) -> Tuple[str, ...]:
        """Entries of ``pi`` that appear in no base parameter (their columns of ``Y`` are zero)."""
        cols = [j for j in range(len(PI_NAMES)) if all(self.matrix[i, j] == 0 for i in range(self.rank))]
        return tuple(PI_NAMES[j] for j in cols)

    def matrix_at(self, a: float, alpha: float = 0.0, g: float = 9.81) -> np.ndarray:
        """``beta = T pi`` as a float array (r x 22) at the given geometry."""
        S = SYMBOLS
        f = sp.lambdify([S["a"], S["alpha"], S["g"]], self.matrix, modules="numpy")
        return np.array(f(a, alpha, g), dtype=float)

    def matrix_functions(self) -> Tuple[Callable, Callable]:
        """``T(a, alpha, g)`` and ``dT/dalpha(a, alpha, g)`` as NumPy functions (each r x 22): a fit
        that frees the skew moves, at fixed ``beta``, the pivots of a representative ``pi`` by
        ``-dT_D/dalpha pi_D``."""
        S = SYMBOLS
        args = [S["a"], S["alpha"], S["g"]]
        return (sp.lambdify(args, self.matrix, modules="numpy"),
                sp.lambdify(args, self.matrix.diff(S["alpha"]), modules="numpy"))

    def values(self, pi, a: float, alpha: float = 0.0, g: float = 9.81) -> np.ndarray:
        """The base parameters of a standard vector ``pi`` (:func:`standard_parameters`)."""
        return self.matrix_at(a, alpha, g) @ np.asarray(pi, dtype=float)

    def ratios(self, reference: Optional[str] = None) -> Tuple[str, ...]:
        """Free motion: the ``r - 1`` ratios ``beta_k / beta_ref`` the data determine (the
        reference defaults to the first base parameter)."""
        ref = self.names[0] if reference is None else reference
        if ref not in self.names:
            raise ParameterError(f"reference must be one of the base parameters {list(self.names)}, got {reference!r}")
        return tuple(f"{n}/{ref}" for n in self.names if n != ref)

    def describe(self, free_motion: bool = False) -> str:
        """Plain text: each base parameter, what cannot be determined, and for free motion the ratios."""
        where = ", ".join(f"{k} = {'generic' if v is None else f'{v:g}'}" for k, v in self.where.items())
        lines = [f"{self.rank} base parameters of {len(PI_NAMES)} standard ones ({where}); tau = Y_b beta:"]
        for n, e in zip(self.names, self.expressions):
            lines.append(f"  {n} = {sp.sstr(e)}")
        if self.unidentifiable:
            lines.append(f"  not in the equations at all: {', '.join(self.unidentifiable)}")
        others = [PI_NAMES[j] for j in self.dependent if PI_NAMES[j] not in self.unidentifiable]
        if others:
            lines.append(f"  determined only inside the combinations above: {', '.join(others)}")
        if free_motion:
            lines.append(f"Free motion (no torques): Y_b beta = 0 is homogeneous, so {SCALE_DIRECTION} is "
                         f"undetermined; the data determine the {self.rank - 1} ratios "
                         f"{', '.join(self.ratios())}.")
        return "\n".join(lines)


def base_parameters(geometry: Optional[Parameters] = None, *, samples: int = 40, seed: int = 0,
                    order: Optional[Sequence[str]] = None,
                    cache: Optional[Callable[[Dict, Callable[[], Dict]], Dict]] = None) -> BaseParameters:
    """The base parameters of the model with ``geometry``'s hinge axes, at its ``a`` and ``alpha``.

    ``a``, ``alpha`` and ``g`` of ``geometry`` that are ``None`` are *generic*: the rank is found
    at seeded random values and the relations hold as expressions in them.  A numeric ``alpha``
    with a lower rank than the generic one (``alpha = 0``: the planar pendulum) gets its own,
    smaller set.  ``order`` is the preference for pivots (default :data:`PI_NAMES`: body 1 before
    body 2, inertias where the column is shared...); ``samples`` random states (``seed``) are stacked.
    ``cache(key, build)``: where the symbolic result may be kept (seconds of SymPy): given ``key``
    (what the result depends on: the hinge axes, the given ``a, alpha, g``, the sampling, the order;
    JSON-able) it returns ``build()``'s dictionary, from a store or made (the numeric layer keeps one
    on disk: :func:`skewpend.numeric.pyfunctions.cached_object`).
    """
    import time

    t0 = time.perf_counter()
    geometry = Parameters() if geometry is None else geometry
    if not isinstance(geometry, Parameters):
        raise ParameterError(f"geometry must be a skewpend Parameters, got {geometry!r}")
    if order is not None and sorted(order) != sorted(PI_NAMES):
        raise ParameterError(f"order must be a permutation of {list(PI_NAMES)}")
    key = {"axes": repr(_axes_key(geometry)), "given": {n: getattr(geometry, n) for n in STRUCTURE},
           "samples": int(samples), "seed": int(seed), "order": None if order is None else list(order)}
    build = lambda: _base_fields(geometry, samples, seed, order)  # noqa: E731
    fields = build() if cache is None else cache(key, build)
    return BaseParameters(**fields, regressor=lambdify_columns(fields["symbolic_regressor"]),
                          seconds=time.perf_counter() - t0)


def _base_fields(geometry: Parameters, samples: int, seed: int, order) -> Dict:
    """:func:`base_parameters`' fields, all but the numeric regressor (SymPy objects and plain values)."""
    reg = regressor(geometry)
    rng = np.random.default_rng(seed + 1)
    generic = dict(zip(STRUCTURE, (float(rng.uniform(0.5, 1.5)), float(rng.uniform(0.3, 1.2)), float(rng.uniform(5, 15)))))
    given = {n: getattr(geometry, n) for n in STRUCTURE}
    if not reg.uses_alpha:
        given["alpha"] = 0.0
    at = {n: (generic[n] if v is None else float(v)) for n, v in given.items()}
    Ynum = reg.numeric()
    q, dq, ddq = sample_states(samples, seed)
    A = Ynum(q, dq, ddq, at["a"], at["alpha"], at["g"]).reshape(-1, len(PI_NAMES))
    A_gen = Ynum(q, dq, ddq, generic["a"], generic["alpha"], generic["g"]).reshape(-1, len(PI_NAMES))
    names_order = list(PIVOT_ORDER if order is None else order)
    pref = [PI_NAMES.index(n) for n in names_order]
    piv = independent_columns(A, pref)  # in the order of preference: the base parameters' order
    generic_rank = len(independent_columns(A_gen, pref))
    dep = [j for j in range(len(PI_NAMES)) if j not in piv]

    # exact relations Y_D = Y_P K from the coefficient matrix (rows: equation x monomial)
    C, _ = _coefficients(reg.axes)
    S = SYMBOLS
    exact: Dict[sp.Symbol, sp.Expr] = {}
    if len(piv) < generic_rank and given["alpha"] is not None:
        ang = _exact_angle(at["alpha"])
        exact = {_C["alpha"]: sp.cos(ang), _S["alpha"]: sp.sin(ang)}
    for n in STRUCTURE[::2]:  # the length and g
        if given[n] is not None and len(piv) < generic_rank:
            exact[S[n]] = sp.nsimplify(given[n], rational=True)
    Cx = C.xreplace(exact) if exact else C
    inexact = Cx.has(sp.Float)  # a user's numeric axis: 1/|v| entered as a float
    if inexact:  # chop the rounding, solve on the exact binary values, check to a tolerance
        Cx = _chop_matrix(Cx).applyfunc(lambda x: x.xreplace({f: sp.Rational(f) for f in x.atoms(sp.Float)}))
    coef_syms = [_C["alpha"], _S["alpha"], S["a"], S["g"]]
    vals = {_C["alpha"]: math.cos(at["alpha"]), _S["alpha"]: math.sin(at["alpha"]), S["a"]: at["a"], S["g"]: at["g"]}
    Cf = np.array(sp.lambdify(coef_syms, Cx, modules="numpy")(*[vals[s] for s in coef_syms]), dtype=float)
    r = len(piv)
    rows = independent_columns(Cf[:, piv].T, range(Cf.shape[0]))
    if len(rows) != r:
        raise AssertionError("the coefficient matrix does not have the regressor's rank")
    CP, CD = Cx[:, piv], Cx[:, dep]
    K = _solve(CP.extract(rows, list(range(r))), CD.extract(rows, list(range(len(dep)))))
    # check every row, exactly, modulo cos^2 + sin^2 = 1
    resid = CP * K - CD
    scale = _scale(Cx) if inexact else 1.0
    for x in resid:
        if x != 0:
            if inexact:  # to rounding, at the generic values (no alpha: the axes are the user's)
                num = sp.Integer(abs(float(x.subs({S["a"]: at["a"], S["g"]: at["g"]}))) > 1e-9 * scale)
            else:
                num = _reduce(sp.numer(sp.together(x)))
            if num != 0:
                raise AssertionError(f"a dependent column's relation does not hold exactly: {x}")
    if inexact:
        K = K.applyfunc(lambda x: sp.expand(x).xreplace(
            {r: sp.Float(r, 15) for r in sp.expand(x).atoms(sp.Rational) if not r.is_Integer}))
        K = _chop_matrix(K, scale=1.0, rel=1e-12)
    K = K.applyfunc(_tidy)
    pi = sp.Matrix(PI_SYMBOLS)
    T = sp.zeros(r, len(PI_NAMES))
    for k, j in enumerate(piv):
        T[k, j] = 1
        for d, jd in enumerate(dep):
            T[k, jd] = K[k, d]
    exprs = tuple(sp.expand((T[k, :] * pi)[0]) for k in range(r))
    names = tuple(PI_NAMES[j] if exprs[k] == PI_SYMBOLS[j] else PI_NAMES[j] + "_b" for k, j in enumerate(piv))
    Yb = reg.Y[:, piv]
    return dict(
        names=names, expressions=exprs, matrix=T, pivots=tuple(piv), dependent=tuple(dep), relations=K,
        symbolic_regressor=Yb,
        where={n: (None if given[n] is None else at[n]) for n in STRUCTURE if n != "alpha" or reg.uses_alpha},
    )


def _solve(A: sp.Matrix, B: sp.Matrix) -> sp.Matrix:
    """``A X = B`` exactly (entries polynomials in a few symbols): fraction-free over their field."""
    from sympy.polys.matrices import DomainMatrix

    dA, dB = DomainMatrix.from_Matrix(A).unify(DomainMatrix.from_Matrix(B))
    return dA.to_field().lu_solve(dB.to_field()).to_Matrix()


# -- the first estimate --------------------------------------------------------------------------------
@dataclass(frozen=True)
class LinearEstimate:
    """A linear least-squares estimate of the base parameters.

    ``values``, ``covariance`` (``sigma2 (Y^T W Y)^-1``), ``stderr``, ``intervals`` (95 %,
    Student's t with ``dof`` degrees of freedom), ``sigma2`` (the residual variance of one
    weighted equation), ``residual_rms``.  For homogeneous data (``reference`` set) the value
    of the reference is 1 exactly and its interval ``(1, 1)``: the ratios are estimated.
    """

    names: Tuple[str, ...]
    values: np.ndarray
    covariance: np.ndarray
    intervals: np.ndarray
    sigma2: float
    dof: int
    residual_rms: float
    reference: Optional[str] = None

    @property
    def stderr(self) -> np.ndarray:
        return np.sqrt(np.clip(np.diag(self.covariance), 0, None))

    def table(self) -> str:
        head = f"{'name':<12} {'value':>14} {'95 % interval':>32}"
        rows = [head]
        for n, v, (lo, hi) in zip(self.names, self.values, self.intervals):
            rows.append(f"{n:<12} {v:>14.6g}   [{lo:>13.6g}, {hi:>13.6g}]")
        return "\n".join(rows)


def linear_estimate(Yb, tau=None, weights=None, *, names: Optional[Sequence[str]] = None,
                    reference: Optional[int] = None, level: float = 0.95) -> LinearEstimate:
    """Weighted linear least squares ``Y_b beta = tau``.

    ``Yb``: (N, 2, r) rows of the base regressor (or (n, r)); ``tau``: (N, 2) (or (n,)) measured
    torques, ``None`` or all zero for free motion; ``weights``: per equation (same shape as
    ``tau``), inverse variances up to one common factor (default 1).

    With torques: ``beta = (Y^T W Y)^-1 Y^T W tau``, covariance ``sigma^2 (Y^T W Y)^-1`` with
    ``sigma^2`` the weighted residual sum of squares over ``n - r``.  Free motion: the equations
    are homogeneous and only ratios are determined: the null vector of ``W^1/2 Y`` (the smallest
    right singular vector, total least squares) normalised so that base parameter ``reference``
    (an index, default 0) is 1; the covariance of the other ratios is that of the least-squares
    problem ``Y_rest x = -Y_ref`` (reference row and column zero).
    """
    from ..results import t_quantile

    Y = np.asarray(Yb, dtype=float)
    r = Y.shape[-1]
    Y = Y.reshape(-1, r)
    n = Y.shape[0]
    homogeneous = tau is None or not np.any(np.asarray(tau, dtype=float))
    t = np.zeros(n) if tau is None else np.asarray(tau, dtype=float).reshape(-1)
    if t.shape[0] != n:
        raise ParameterError(f"tau has {t.shape[0]} equations, Yb {n}")
    w = np.ones(n) if weights is None else np.asarray(weights, dtype=float).reshape(-1)
    if w.shape[0] != n or np.any(~np.isfinite(w)) or np.any(w < 0):
        raise ParameterError("weights must be finite, >= 0, one per equation")
    ok = np.isfinite(t) & np.all(np.isfinite(Y), axis=1) & (w > 0)
    Y, t, w = Y[ok], t[ok], w[ok]
    n = Y.shape[0]
    names = tuple(names) if names is not None else tuple(f"beta{k}" for k in range(r))
    sw = np.sqrt(w)
    Yw = Y * sw[:, None]
    ref_name = None
    if homogeneous:
        k = 0 if reference is None else int(reference)
        if not 0 <= k < r:
            raise ParameterError(f"reference must be an index below {r}, got {reference}")
        dof = n - (r - 1)
        if dof <= 0:
            raise ParameterError(f"{n} equations cannot determine {r - 1} ratios")
        _, s, vt = np.linalg.svd(Yw, full_matrices=False)
        v = vt[-1]
        if abs(v[k]) < 1e-12 * np.abs(v).max():
            raise ParameterError(f"the data do not determine {names[k]} relative to the others: choose another reference")
        beta = v / v[k]
        rest = [j for j in range(r) if j != k]
        A = Yw[:, rest]
        e = Yw @ beta
        sigma2 = float(e @ e / dof)
        cov = np.zeros((r, r))
        cov[np.ix_(rest, rest)] = sigma2 * np.linalg.inv(A.T @ A)
        ref_name = names[k]
    else:
        dof = n - r
        if dof <= 0:
            raise ParameterError(f"{n} equations cannot determine {r} base parameters")
        tw = t * sw
        beta, *_ = np.linalg.lstsq(Yw, tw, rcond=None)
        e = Yw @ beta - tw
        sigma2 = float(e @ e / dof)
        cov = sigma2 * np.linalg.inv(Yw.T @ Yw)
    z = t_quantile(0.5 + level / 2, dof)
    se = np.sqrt(np.clip(np.diag(cov), 0, None))
    intervals = np.column_stack([beta - z * se, beta + z * se])
    rms = float(np.sqrt(np.mean((Y @ beta - t) ** 2)))
    return LinearEstimate(names=names, values=beta, covariance=cov, intervals=intervals, sigma2=sigma2, dof=dof,
                          residual_rms=rms, reference=ref_name)
