"""Display forms of derived expressions: each entry in its simplest readable form.

The derivation (:mod:`skewpend.symbolic.derivation`) hands out its intermediate results as
polynomials in the cosines and sines of the single angles, the form the numeric code and the
JSON contract use: at ``alpha = 0`` the rotation tensor's first entry is
``-sin(phi) sin(psi) + cos(phi) cos(psi)``, where the specification writes ``cos(phi + psi)``.
:func:`display_form` finds a shorter form of one expression *for display only*:

* candidates: the expression with common factors pulled out; sums of products of sines and
  cosines folded into sines and cosines of sums of angles (``fu``'s rule TR10i); SymPy's
  ``trigsimp`` (for entries small enough for it); double angles written back as squares
  (``cos(2u) = 1 - 2 sin(u)^2 = 2 cos(u)^2 - 1``, ``sin(2u) = 2 sin(u) cos(u)``); and each of
  those collected over its trigonometric factors;
* a candidate replaces the expression only if it is shorter (:func:`cost`: SymPy's
  ``count_ops`` plus a penalty for multiple angles such as ``cos(2 phi)``) **and** proved equal
  (:func:`proven_equal`): the difference, with every trigonometric function expanded down to
  sines and cosines of the single symbols, is reduced modulo ``cos^2 + sin^2 - 1`` for every
  angle and must vanish exactly (a normal form: zero only for an identity); expressions with
  floating-point numbers, where that exact test does not apply, must agree to 1e-12 at random
  points instead;
* among the shorter candidates the shortest wins, except that a sum grouped by products of
  the parameters, as the specification writes its energies, is preferred when it is at most
  :data:`GROUPED_BONUS` operations longer;
* the work per entry is bounded by its size alone (``trigsimp`` only for small entries, the
  product-to-sum route for moderate ones, nothing but the cheap candidates for very large ones:
  :data:`LARGE_OPS`), so the result is the same on every machine and under any load.  A clock
  (``budget`` seconds, checked between candidates; the cheap ones are always tried) is off by
  default: with it, a busy machine could show a longer form of the same entry.

Nothing here changes what the numeric code uses: results are new expressions, and the
derivation's own ones are left as they are.
"""

from __future__ import annotations

import random
import time
from typing import Dict, Iterable, List, Optional

import sympy as sp
from sympy.simplify.fu import TR8, TR10i

__all__ = ["display_form", "display_matrix", "display_steps", "proven_equal", "cost", "DEFAULT_BUDGET"]

#: Seconds of candidates per entry: None, no clock.  Which candidates are tried is decided by the
#: entry's size (below), so that the form shown does not depend on the machine's speed or load (a
#: 2 s clock here once showed a longer potential energy in a report made on a loaded machine).
DEFAULT_BUDGET: Optional[float] = None
#: Entries of more operations than this get only the cheap candidates (common factors, TR10i).
LARGE_OPS = 400
#: Products are turned into sums (TR8) and folded back only for entries of at most this many operations.
FOLD_MAX_OPS = 60
#: ``trigsimp`` is tried only on entries of at most this many operations (it grows badly).
TRIGSIMP_MAX_OPS = 20
#: Relative agreement required at random points when the exact test does not apply.
NUMERIC_TOLERANCE = 1e-12


# -- cost ---------------------------------------------------------------------------------------
def _multiple_angles(expr: sp.Basic) -> int:
    """Trigonometric functions of a multiple angle (``cos(2 phi)``, ``sin(2 (phi + psi))``)."""
    n = 0
    for f in expr.atoms(sp.sin, sp.cos):
        coeff, _ = sp.factor_terms(f.args[0]).as_coeff_Mul()
        if coeff != 1 and coeff != -1:
            n += 1
    return n


def cost(expr: sp.Basic) -> int:
    """How long an expression reads: ``count_ops`` plus 3 per multiple-angle function."""
    return int(sp.count_ops(expr)) + 3 * _multiple_angles(expr)


# -- proof of equality ------------------------------------------------------------------------------
def _expand_all_trig(expr: sp.Expr) -> sp.Expr:
    """Sines and cosines of sums and multiples expanded to those of the single symbols."""
    for _ in range(8):
        new = sp.expand(sp.expand_trig(expr))
        if new == expr:
            break
        expr = new
    return expr


def _exact_zero(diff: sp.Expr) -> Optional[bool]:
    """True/False when ``diff`` is/is not identically zero as a trigonometric polynomial; None
    when that cannot be decided exactly here (floats, functions of non-symbol arguments)."""
    if diff.has(sp.Float):
        return None
    diff = _expand_all_trig(diff)
    if diff == 0:
        return True
    trig = diff.atoms(sp.sin, sp.cos)
    if any(not f.args[0].is_Symbol for f in trig) or diff.atoms(sp.tan, sp.cot, sp.sec, sp.csc, sp.exp, sp.log):
        return None
    angles = sorted({f.args[0] for f in trig}, key=sp.default_sort_key)
    c = {x: sp.Dummy(f"c_{x}") for x in angles}
    s = {x: sp.Dummy(f"s_{x}") for x in angles}
    poly = diff.xreplace({**{sp.cos(x): c[x] for x in angles}, **{sp.sin(x): s[x] for x in angles}})
    if poly.atoms(sp.sin, sp.cos):
        return None
    if not angles:
        return sp.expand(poly) == 0
    # cos^2 x -> 1 - sin^2 x for every angle: the remainder is a normal form of the
    # trigonometric polynomial (at most linear in each cos), zero only for an identity
    gens = [c[x] for x in angles] + [s[x] for x in angles]
    others = sorted(poly.free_symbols - set(gens), key=sp.default_sort_key)
    try:
        p = sp.Poly(poly, *gens, *others)
    except sp.PolynomialError:
        return None
    relations = [sp.Poly(c[x] ** 2 + s[x] ** 2 - 1, *gens, *others) for x in angles]
    _, rem = sp.reduced(p, relations, *gens, *others, order="lex")
    return rem.is_zero


def _numeric_equal(a: sp.Expr, b: sp.Expr, points: int = 6, seed: int = 1) -> bool:
    """``a`` and ``b`` agree to :data:`NUMERIC_TOLERANCE` (relative) at random points."""
    symbols = sorted(a.free_symbols | b.free_symbols, key=sp.default_sort_key)
    rng = random.Random(seed)
    for _ in range(points):
        at = {x: sp.Float(rng.uniform(0.3, 1.7) * rng.choice((1, -1)) if not x.is_positive else rng.uniform(0.3, 1.7), 30)
              for x in symbols}
        va = complex(sp.N(a.xreplace(at), 30))
        vb = complex(sp.N(b.xreplace(at), 30))
        if not abs(va - vb) <= NUMERIC_TOLERANCE * max(1.0, abs(va), abs(vb)):
            return False
    return True


def proven_equal(a: sp.Expr, b: sp.Expr) -> bool:
    """``a == b`` identically: exactly (trigonometric normal form) where that applies, else by
    agreement at random points; the numeric test is also made when the exact one succeeds."""
    a, b = sp.sympify(a), sp.sympify(b)
    exact = _exact_zero(sp.expand(a - b))
    if exact is False:
        return False
    return _numeric_equal(a, b)


# -- candidates -----------------------------------------------------------------------------------
def _squares(expr: sp.Expr) -> List[sp.Expr]:
    """Double angles as squares: cos(2u) -> 2 cos(u)^2 - 1 and -> 1 - 2 sin(u)^2; sin(2u) -> 2 sin u cos u."""
    out = []
    doubles = [f for f in expr.atoms(sp.sin, sp.cos) if sp.factor_terms(f.args[0]).as_coeff_Mul()[0] == 2]
    if not doubles:
        return out
    for cos_rule in (lambda u: 2 * sp.cos(u) ** 2 - 1, lambda u: 1 - 2 * sp.sin(u) ** 2):
        rep = {}
        for f in doubles:
            u = f.args[0] / 2
            rep[f] = cos_rule(u) if isinstance(f, sp.cos) else 2 * sp.sin(u) * sp.cos(u)
        out.append(sp.factor_terms(sp.expand(expr.xreplace(rep))))
    return out


def _collected(expr: sp.Expr) -> sp.Expr:
    """Terms gathered over their trigonometric factors, each coefficient factored."""
    trig = sorted(expr.atoms(sp.sin, sp.cos), key=sp.default_sort_key)
    if not trig:
        return sp.factor(expr)
    return sp.collect(sp.expand(expr), trig, func=sp.factor)


def _speed_collected(expr: sp.Expr, speeds: Iterable[sp.Symbol]) -> sp.Expr:
    speeds = [s for s in speeds if expr.has(s)]
    if not speeds:
        return expr
    return sp.collect(sp.expand(expr), speeds, func=lambda c: sp.factor_terms(TR10i(sp.factor_terms(c))))


#: Readability bonus [operations] of a sum grouped by products of the parameters, the way the
#: specification writes its energies (``a^2 m1 phi'^2/6 + ... + b^2 m2 (phi' + psi')^2/6``).
GROUPED_BONUS = 4


def _kinematic(symbol: sp.Symbol) -> bool:
    return symbol.name in ("phi", "psi", "dphi", "dpsi", "ddphi", "ddpsi", "alpha")


def _fold(expr: sp.Expr) -> sp.Expr:
    """A small factor in the angles and speeds, factored; ``cos^2 + sin^2`` removed (``trigsimp``,
    for small factors) and sums of products folded into functions of sums of angles (TR10i)."""
    expr = sp.factor(expr)
    if expr.atoms(sp.sin, sp.cos) and sp.count_ops(expr) <= 2 * TRIGSIMP_MAX_OPS:
        expr = sp.factor(sp.trigsimp(expr))
    return sp.factor_terms(TR10i(expr))


def grouped_by_parameters(expr: sp.Expr) -> Optional[sp.Expr]:
    """The terms of ``expr`` gathered by their product of parameters (``a^2 m2``, ``a b m2``, ...),
    each group's factor in the angles and speeds simplified (:func:`_fold`); None when all the
    terms share one product."""
    kin = [x for x in expr.free_symbols if _kinematic(x)]
    groups: Dict[sp.Expr, List[sp.Expr]] = {}
    for term in sp.Add.make_args(sp.expand(expr)):
        params, rest = term.as_independent(*kin, as_Add=False) if kin else (term, sp.S.One)
        number, monomial = params.as_coeff_Mul()
        groups.setdefault(monomial, []).append(number * rest)
    if len(groups) < 2:  # one product of parameters: nothing to group
        return None
    return sp.Add(*[monomial * _fold(sp.Add(*rest)) for monomial, rest in groups.items()])


def display_form(expr: sp.Expr, *, budget: Optional[float] = DEFAULT_BUDGET,
                 speeds: Iterable[sp.Symbol] = ()) -> sp.Expr:
    """The shortest proved-equal form of ``expr`` among the candidates its size allows (see the
    module); ``budget``: seconds, checked between candidates (None: no clock)."""
    expr = sp.sympify(expr)
    if expr.is_number or expr.is_Symbol or not expr.free_symbols:
        return expr
    start = time.perf_counter()
    original = cost(expr)
    best, best_score = expr, original
    tried: Dict[sp.Expr, None] = {}  # in the order tried (a set's order would vary between processes)

    def consider(candidate, bonus: int = 0) -> None:
        nonlocal best, best_score
        if candidate is None or candidate in tried:
            return
        tried[candidate] = None
        c = cost(candidate)
        if c < original and c - bonus < best_score and proven_equal(expr, candidate):
            best, best_score = candidate, c - bonus

    def left() -> float:
        return 1.0 if budget is None else budget - (time.perf_counter() - start)

    cheap = [
        lambda e: sp.factor_terms(e),
        lambda e: sp.factor_terms(TR10i(e)),
        lambda e: sp.factor_terms(TR10i(sp.factor_terms(e))),
    ]
    for make in cheap:
        consider(make(expr))
    if original > LARGE_OPS:
        return best
    if left() > 0 and expr.atoms(sp.sin, sp.cos) and sp.count_ops(expr) <= FOLD_MAX_OPS:
        # products to sums, then sums of products back to functions of sums of angles
        folded = sp.factor_terms(TR10i(sp.expand(TR8(expr))))
        consider(folded)
        for sq in _squares(folded):
            consider(sq)
    speeds = tuple(speeds)
    if speeds and left() > 0:
        consider(_speed_collected(expr, speeds))
    if left() > 0 and sp.count_ops(expr) <= TRIGSIMP_MAX_OPS:
        t = sp.trigsimp(expr)
        consider(t)
        for sq in _squares(t):
            consider(sq)
            consider(sp.factor(sq))
    if left() > 0:
        for base in list(tried):
            if left() <= 0:
                break
            if base.atoms(sp.sin, sp.cos):
                consider(_collected(base))
    if left() > 0 and isinstance(sp.expand(best), sp.Add):
        consider(grouped_by_parameters(best), GROUPED_BONUS)
    return best


def display_matrix(m: sp.MatrixBase, *, budget: Optional[float] = DEFAULT_BUDGET, speeds: Iterable[sp.Symbol] = ()) -> sp.Matrix:
    """:func:`display_form` entry by entry (an entry seen before is not simplified again)."""
    done: Dict[sp.Expr, sp.Expr] = {}
    out = []
    for x in m:
        if x not in done:
            done[x] = display_form(x, budget=budget, speeds=speeds)
        out.append(done[x])
    return sp.Matrix(m.rows, m.cols, out)


def display_steps(steps: Dict[str, sp.Basic], *, budget: Optional[float] = DEFAULT_BUDGET,
                  keys: Optional[Iterable[str]] = None) -> Dict[str, sp.Basic]:
    """The derivation's ``steps`` (``EquationsOfMotion.steps``) in display form; ``keys``: which
    (default all).  The dictionary returned is new; the derivation's results are untouched."""
    from .symbols import SYMBOLS

    speeds = (SYMBOLS["dphi"], SYMBOLS["dpsi"])
    wanted = set(steps) if keys is None else set(keys)
    out: Dict[str, sp.Basic] = {}
    for key, value in steps.items():
        if key not in wanted:
            out[key] = value
        elif isinstance(value, sp.MatrixBase):
            out[key] = display_matrix(value, budget=budget, speeds=speeds)
        else:
            out[key] = display_form(value, budget=budget, speeds=speeds)
    return out
