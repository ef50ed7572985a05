"""C source of the Taylor integrator's coefficient recurrences, generated from the model's equations.

``simulate(..., method="taylor")`` integrates with an adaptive Taylor series method (the
hand-written driver is ``taylor.c``).  Its model part is printed here, for any form of the model, from
one description (:class:`SeriesSystem`: ``M(q) q'' = f(q, q')``, the non-potential forces ``Q`` and the
energy as SymPy expressions): the derivation's (:func:`exact_system`, the expressions the other kernels
use, :func:`skewpend.numeric.codegen.expressions`) or a chain's recursive algorithms read as polynomials
in its angles' sines and cosines and its speeds (:func:`polynomial_system`,
:mod:`skewpend.numeric.polynomial`).  Either is turned into a sequence of elementary operations on
truncated power series:

* every subexpression free of the state (``m2 b^2/3``, ``sin(alpha)``, ...) is a *constant*,
  computed once per call from the parameter vector (``taylor_prepare``) -- a constant has no
  coefficients beyond order 0, so a product with it is a scalar multiple, a sum with it touches
  order 0 only;
* sums, differences and scalar multiples cost O(1) per order, products and quotients of two
  series O(k) at order k (a square half of that), ``sin``/``cos`` of a series one recurrence pair
  (``s' = c u'``, ``c' = -s u'``), ``atan`` (Coulomb friction) ``a' = u'/(1 + u^2)``;
* ``M q'' = f`` is solved in series arithmetic: ``q''[k] = M[0]^-1 (f[k] - sum_{j>=1} M[j] q''[k-j])``
  (the entries of ``M`` that are constant contribute nothing beyond order 0), ``M[0]`` factored
  once a step (LDL^T, :func:`~skewpend.numeric.codegen.ldlt_factor_steps`, the kernels' one solve)
  and its inverse, formed from the factors, applied at every order
  (:func:`~skewpend.numeric.codegen.spd_mul_steps`: one product and one fused add after ``f[k]``),
  all printed as named constants with their products fused as the series' are;
* the work ``W' = Q . q'`` is a separate block, skipped at run time when the parameters ``Q``
  depends on are all 0 (then ``Q`` is identically 0: checked symbolically here).

Several algebraic forms of the equations are tried -- the derivation's own; the entries expanded as
polynomials in ``sin``/``cos`` of the angles and the speeds, and collected in one of them; and nested
(greedy multivariate Horner) forms with monic factors, so that a factor two entries share is one
series -- and the one with fewest series products is printed.  Nothing here is an equation of motion
typed by hand.
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import lru_cache
from pathlib import Path
from typing import Callable, Dict, List, Optional, Tuple

import sympy as sp

from .. import __version__
from .codegen import (c_printer, cse_block, expressions, ldlt_factor_steps, ldlt_inverse_steps, param_lines, spd_mul_steps,
                      used_names, Lang)
from .conventions import PARAMETER_ORDER
from ..symbolic.derivation import SYMBOLS
from ..symbolic.model import Parameters

__all__ = ["taylor_c_source", "SeriesSystem", "exact_system", "polynomial_system", "SP_TPMAX"]

#: Highest Taylor order (rtol >= 1e-15 needs at most 19).  The order of a tolerance is
#: :func:`skewpend.numeric.kernels.taylor_order` (there: simulate does not import SymPy).
SP_TPMAX = 32


@dataclass
class SeriesSystem:
    """What the Taylor generator prints: a model's ``M`` (packed lower triangle, row by row), ``f``, the joint
    forces ``Q`` and the energy ``T + Pi`` as SymPy expressions of the angles ``q``, the speeds ``dq`` and
    state-free symbols; ``prepare(lang, indent, used)``: C declaring those of the state-free symbols in ``used``
    (names) from the parameter vector ``p``; ``work``: the indices of ``p`` whose being all 0 makes ``Q``
    vanish (None: ``Q`` may not vanish, ``()``: ``Q`` is 0); ``title``: the header's line on the model."""

    q: Tuple[sp.Symbol, ...]
    dq: Tuple[sp.Symbol, ...]
    M: List[sp.Expr]
    f: List[sp.Expr]
    Q: List[sp.Expr]
    energy: sp.Expr
    prepare: Callable[[Lang, str, set], List[str]]
    work: Optional[Tuple[int, ...]]
    title: str
    source: str = "symbolic derivation"
    prelude: Tuple[str, ...] = ()  # C functions before taylor_prepare (its helpers)

    @property
    def n(self) -> int:
        return len(self.q)

    def key(self) -> Tuple:
        return tuple(self.M) + tuple(self.f) + tuple(self.Q)


def exact_system(geometry: Parameters, ex=None) -> SeriesSystem:
    """The derivation's (:func:`~skewpend.numeric.codegen.expressions`) model of ``geometry``."""
    if ex is None:
        ex = expressions(geometry)
    s = SYMBOLS
    # whether W needs integrating: the parameters Q depends on, and whether Q vanishes when they do
    qparams = sorted(used_names([ex.Q[0], ex.Q[1]]) & set(PARAMETER_ORDER), key=PARAMETER_ORDER.index)
    zero = {SYMBOLS[n]: 0 for n in qparams}
    vanishes = all(sp.simplify(sp.sympify(e).xreplace(zero)) == 0 for e in ex.Q)
    work = tuple(PARAMETER_ORDER.index(n) for n in qparams) if vanishes else None
    geo = "thin uniform rods, default axes" if geometry.is_thin_rods else str(geometry.to_dict())
    return SeriesSystem((s["phi"], s["psi"]), (s["dphi"], s["dpsi"]), [ex.M[0, 0], ex.M[0, 1], ex.M[1, 1]],
                        [ex.f[0], ex.f[1]], [ex.Q[0], ex.Q[1]], ex.T + ex.Pi, param_lines, work,
                        f"Geometry: {geo}")


#: Lines of a chain's constants' C function (:func:`polynomial_system`).
CHUNK = 200


@lru_cache(maxsize=8)
def polynomial_system(structure) -> SeriesSystem:
    """The recursive algorithms' model of a chain of ``structure``, read as polynomials
    (:func:`skewpend.numeric.polynomial.polynomial_model`): its constants from ``p`` by the CasADi function
    printed into ``taylor_prepare``."""
    from .polynomial import polynomial_model
    from .recursive import function_lines, parameter_names
    from ..schema import FIELDS, NONCONSERVATIVE_ROLES

    pm = polynomial_model(structure)
    names = parameter_names(structure.n)
    stems = {f.stem for f in FIELDS if f.role in NONCONSERVATIVE_ROLES and f.per_body}  # each joint's damping, ...
    joint = tuple(k for k, name in enumerate(names) if name.rstrip("0123456789") in stems)
    zero_q = all(sp.sympify(e) == 0 for e in pm.Q)

    # the constants: CasADi's operations with the work registers an array, cut into functions of CHUNK lines
    # each (a compiler's time grows faster than a function's length: a general triple's 49,000 operations
    # in one function took gcc 116 s at -O2)
    body = function_lines(pm.constants, ["p"], [[f"Kv[{k}]" for k in range(len(pm.names))]], "    ", False, "c", "w")
    chunks = [body[i:i + CHUNK] for i in range(0, len(body), CHUNK)] if pm.names else []
    prelude: List[str] = []
    for g, lines in enumerate(chunks):
        prelude += [f"static void taylor_constants{g}(const double *p, double *restrict w, double *restrict Kv)", "{",
                    "    (void)p;", *lines, "}", ""]

    def prepare(lang: Lang, indent: str, used: set) -> List[str]:
        if not pm.names:
            return []
        return [f"{indent}double Kv[{len(pm.names)}], w[{max(pm.constants.sz_w(), 1)}];",
                *(f"{indent}taylor_constants{g}(p, w, Kv);" for g in range(len(chunks))),
                *(f"{indent}const double {name} = Kv[{k}];" for k, name in enumerate(pm.names) if name in used)]

    return SeriesSystem(pm.q, pm.dq, pm.M, pm.f, pm.Q, pm.energy, prepare, () if zero_q else joint,
                        f"A chain of {structure.n} links, structure {structure.key()} ({len(pm.names)} constants)",
                        "recursive algorithms' equations, read as polynomials", tuple(prelude))


class _Graph:
    """Series operations in evaluation order.  A value is ``("c", text)`` (a constant: a C
    expression of the prepared constants) or ``("s", name)`` (a series: ``name[k]``)."""

    def __init__(self, system: SeriesSystem):
        self.ops: List[Tuple] = []  # (kind, target, args...)
        self.memo: Dict[sp.Expr, Tuple[str, str]] = {}
        self.consts: List[sp.Expr] = []
        self.const_index: Dict[sp.Expr, int] = {}
        self.count = 0
        self.cost = 0.0
        n = system.n
        self.state = {v: ("s", f"x[{i}]") for i, v in enumerate(system.q + system.dq)}
        self.series_syms = set(self.state)
        self.const_expr: Dict[sp.Symbol, sp.Expr] = {}  # CSE symbols standing for constants
        self.depth: Dict[str, int] = {f"x[{i}]": _EARLY if i < n else 0 for i in range(2 * n)}  # see _RANK

    def dep(self, v) -> int:
        return self.depth.get(v[1], _EARLY) if v[0] == "s" else _EARLY

    def is_const(self, e: sp.Expr) -> bool:
        return not (e.free_symbols & self.series_syms)

    def define(self, sym: sp.Symbol, e: sp.Expr) -> None:
        """A common subexpression ``sym = e`` (from sp.cse, in order)."""
        if self.is_const(e):
            self.const_expr[sym] = e.xreplace(self.const_expr)
            self.memo[sym] = self.const(self.const_expr[sym])
        else:
            self.memo[sym] = self.node(e)
            self.series_syms.add(sym)

    def const(self, e: sp.Expr) -> Tuple[str, str]:
        e = e.xreplace(self.const_expr)
        if e.is_Number:
            return ("c", repr(float(e)))
        if e not in self.const_index:
            self.const_index[e] = len(self.consts)
            self.consts.append(e)
        return ("c", f"pc[{self.const_index[e]}]")

    def new(self, kind: str, *args, cost: float = 0.0) -> Tuple[str, str]:
        name = f"n{self.count}"
        self.count += 1
        self.ops.append((kind, name) + args)
        self.cost += cost
        _op_depth(self.ops[-1], self.depth)
        return ("s", name)

    def _reuse(self, e: sp.Expr):
        """``x^n R`` (n >= 2) as ``x^(n-1) (x R)`` when ``x R`` is a series already (one product, not
        a square and a product): ``(x R, x^n)``; else None."""
        for a in e.args:
            if a.is_Pow and a.exp.is_Integer and a.exp >= 2:
                key = sp.Mul(a.base, *(b for b in e.args if b is not a))
                if key in self.memo:
                    return key, a
        return None

    def _split(self, e: sp.Expr):
        """The constant arguments of a sum or product, and its series arguments in SymPy's sort order."""
        return ([a for a in e.args if self.is_const(a)],
                sorted((a for a in e.args if not self.is_const(a)), key=sp.default_sort_key))

    def node(self, e: sp.Expr) -> Tuple[str, str]:
        e = sp.sympify(e)
        if e in self.memo:
            return self.memo[e]
        if self.is_const(e):
            out = self.const(e)
        elif e in self.state:
            out = self.state[e]
        elif e.is_Add:
            consts, series = self._split(e)
            if _short_path:  # the terms known first added first (the latest one last)
                def late(a):
                    coeff, rest = a.as_coeff_Mul()
                    return self.dep(self.node(rest if coeff == -1 else a))
                series = sorted(series, key=late)
            acc = self.node(series[0])
            for a in series[1:]:
                coeff, rest = a.as_coeff_Mul()
                if coeff == -1:
                    acc = self.new("sub", acc, self.node(rest))
                else:
                    acc = self.new("add", acc, self.node(a))
            if consts:
                acc = self.new("addc", acc, self.const(sp.Add(*consts)))
            out = acc
        elif e.is_Mul and len([a for a in e.args if not self.is_const(a)]) > 1 and any(self.is_const(a) for a in e.args):
            # c * (the product of the series): the product a node of its own, shared with every other
            # multiple of it
            consts, series = self._split(e)
            c = sp.Mul(*consts)
            ds = [self.dep(self.node(a)) for a in series] if _short_path else [0]
            if min(ds) < max(ds):
                # c onto the factor known first (off the order's critical path), then the product
                i = ds.index(min(ds))
                rest = series[:i] + series[i + 1:]
                out = self.new("mul", self.node(c * series[i]), self.node(sp.Mul(*rest)), cost=1.0)
            else:
                acc = self.node(sp.Mul(*series))
                out = self.new("neg", acc) if c == -1 else self.new("scale", acc, self.const(c))
        elif e.is_Mul and not any(self.is_const(a) for a in e.args) and self._reuse(e) is not None:
            key, a = self._reuse(e)
            out = self.new("mul", self.memo[key], self.node(a.base ** (a.exp - 1)), cost=1.0)
        elif e.is_Mul:
            consts, series = self._split(e)
            if _short_path and len(series) > 2:  # the factors known first multiplied first
                series = sorted(series, key=lambda a: self.dep(self.node(a.base if a.is_Pow and a.exp == -1 else a)))
            acc = self.node(series[0])
            for a in series[1:]:
                if a.is_Pow and a.exp == -1:
                    acc = self.new("div", acc, self.node(a.base), cost=1.0)
                else:
                    acc = self.new("mul", acc, self.node(a), cost=1.0)
            if consts:
                c = sp.Mul(*consts)
                acc = self.new("neg", acc) if c == -1 else self.new("scale", acc, self.const(c))
            out = acc
        elif e.is_Pow and e.exp.is_Integer:
            n = int(e.exp)
            if n < 0:
                out = self.new("rdiv", ("c", "1.0"), self.node(e.base ** (-n)), cost=1.0)
                self.memo[e] = out
                return out
            base = self.node(e.base)
            acc, k = base, 1
            while 2 * k <= n:  # repeated squaring, then products
                acc = self.new("sqr", acc, cost=0.5)
                k *= 2
            while k < n:
                acc = self.new("mul", acc, base, cost=1.0)
                k += 1
            out = acc
        elif isinstance(e, (sp.sin, sp.cos)):
            u = e.args[0]
            key_s, key_c = sp.sin(u), sp.cos(u)
            arg = self.node(u)
            s = self.new("sincos", arg, cost=2.0)
            c = ("s", s[1] + "c")
            self.memo[key_s], self.memo[key_c] = s, c
            return self.memo[e]
        elif isinstance(e, sp.atan):
            arg = self.node(e.args[0])
            out = self.new("atan", arg, cost=2.5)
        else:
            raise ValueError(f"taylor kernel: no series recurrence for {e.func.__name__} (in {e})")
        self.memo[e] = out
        return out


def _build(system: SeriesSystem, main):
    """The graph of ``main`` (M's packed entries and f, in some algebraic form) and of Q."""
    Q = system.Q
    g = _Graph(system)
    # common subexpressions first (their products shared), then each as one series node
    repl, reduced = sp.cse(main, symbols=sp.numbered_symbols("z"), optimizations="basic")
    for sym, e in repl:
        g.define(sym, e)
    main_nodes = [g.node(e) for e in reduced]
    n_main = len(g.ops)
    work_nodes = [g.node(e) for e in Q]
    return g, main_nodes, n_main, work_nodes


def _forms(system: SeriesSystem):
    """Algebraic forms of M and f to try: the model's own; expanded as polynomials in the
    sines, cosines and speeds; that polynomial collected in each one of them; and its nested
    forms (:func:`_horner_forms`)."""
    angles = set(system.q)
    main = [*system.M, *system.f]
    yield main
    expanded = [sp.expand(sp.expand_trig(e)) if e.free_symbols & angles else sp.expand(e) for e in main]
    yield expanded
    gens = _generators(system, expanded)
    for gen in gens:
        yield [sp.collect(e, gen) for e in expanded]
    yield from _horner_forms(expanded, gens)


def _generators(system: SeriesSystem, expanded) -> list:
    """The sines and cosines of the angles in ``expanded``, and the speeds, in SymPy's sort order."""
    gens = set(system.dq)
    for e in expanded:
        gens |= {a for a in e.atoms(sp.sin, sp.cos) if a.free_symbols & set(system.q)}
    return sorted(gens, key=sp.default_sort_key)


def _large_forms(system: SeriesSystem):
    """The forms tried for large M and f (:data:`SEARCH_OPS`): the model's and the plain nested one."""
    forms = _forms(system)
    yield next(forms)
    expanded = next(forms)
    try:
        yield _horner(expanded, _generators(system, expanded))
    except sp.PolynomialError:
        return


def _horner(exprs, gens, protect=()):
    """``exprs`` (polynomials in ``gens`` with constant coefficients) in a nested form: each one
    split greedily as ``g * Q + R`` by the generator ``g`` in the most of its terms (then ``Q`` and
    ``R`` so), every factor ``Q`` made monic (its constant term, else its first term, 1: a constant
    times it outside), so that the same factor in two expressions is one series (``phi' (1 + r cos
    psi)`` in both f's of thin rods).  ``protect``: monomials (exponent tuples over ``gens``)
    taken as one generator of their own first, e.g. ``sin(phi) cos(psi)`` when two expressions have
    it.  Raises sympy's PolynomialError for an expression that is not such a polynomial."""
    syms = [sp.Dummy(f"g{i}") for i in range(len(gens))]
    psyms = [sp.Dummy(f"p{i}") for i in range(len(protect))]
    allsyms = syms + psyms
    back = dict(zip(syms, gens))
    for d, mono in zip(psyms, protect):
        back[d] = sp.Mul(*(g ** k for g, k in zip(gens, mono)))

    def mono_expr(m):
        return sp.Mul(*(x ** k for x, k in zip(allsyms, m)))

    def unit(c):
        """c, or exactly +-1 for a c within rounding of it (the divisions here leave 0.9999999999999999)"""
        if c.is_Float and abs(abs(float(c)) - 1.0) < 1e-14:
            return sp.Integer(1 if c > 0 else -1)
        return c

    def monic(x):
        if x.is_Add:
            nums = [a for a in x.args if a.is_Number]
            k = nums[0] if nums else sorted(x.args, key=sp.default_sort_key)[0].as_coeff_Mul()[0]
            if k in (0, 1):
                return x, sp.Integer(1)
            terms = []
            for a in x.args:
                c, rest = a.as_coeff_Mul()
                terms.append(unit(c / k) * rest)
            return sp.Add(*terms), k
        k, rest = x.as_coeff_Mul()
        return rest, unit(k)

    def build(terms):
        if not terms:
            return sp.Integer(0)
        n = len(allsyms)
        counts = [sum(1 for m, _ in terms if m[i] > 0) for i in range(n)]
        i = max(range(n), key=lambda j: (counts[j], -j))
        if counts[i] <= 1:
            return sp.Add(*(c * mono_expr(m) for m, c in terms))
        inner = [(m[:i] + (m[i] - 1,) + m[i + 1:], c) for m, c in terms if m[i] > 0]
        rest = [(m, c) for m, c in terms if m[i] == 0]
        q, k = monic(build(inner))
        return sp.Mul(k, allsyms[i], q) + build(rest)

    out = []
    for e in exprs:
        poly = sp.Poly(e.xreplace(dict(zip(gens, syms))), *syms)
        terms = []
        for m, c in poly.terms():
            m, extra = list(m), [0] * len(protect)
            for j, pm in enumerate(protect):
                while all(a >= b for a, b in zip(m, pm)):
                    m = [a - b for a, b in zip(m, pm)]
                    extra[j] += 1
            terms.append((tuple(m) + tuple(extra), c))
        e = build(terms).xreplace(back)
        out.append(e.xreplace({c: unit(c) for c in e.atoms(sp.Float)}))
    return out


#: Up to this many products of two generators shared by two or more entries, each is tried as the one
#: protected product (:func:`_horner_forms`); above it only none and all of them: a chain of three links
#: shares 44 (each form 0.3-0.6 s of search; all together gave 81.5 series products an order, the best single
#: one 90.5), the double pendulum's bodies 8 or fewer (an offset centre of mass).
SINGLE_PROTECTS = 12


def _horner_forms(expanded, gens):
    """:func:`_horner` of the expanded M and f: as they are, and with each product of two generators
    that two or more of them contain (and all those together) taken as one."""
    gens = list(gens)
    try:
        polys = [sp.Poly(e, *gens) for e in expanded]
    except sp.PolynomialError:
        return
    seen = {}
    for i, p in enumerate(polys):
        for m in p.monoms():
            for a in range(len(gens)):
                for b in range(a, len(gens)):
                    pm = tuple((1 if j == a else 0) + (1 if j == b else 0) for j in range(len(gens)))
                    if all(x >= y for x, y in zip(m, pm)):
                        seen.setdefault(pm, set()).add(i)
    shared = sorted((pm for pm, ids in seen.items() if len(ids) > 1), reverse=True)
    singles = [(pm,) for pm in shared] if len(shared) <= SINGLE_PROTECTS else []
    for protect in [()] + singles + ([tuple(shared)] if len(shared) > 1 else []):
        try:
            yield _horner(expanded, gens, protect)
        except sp.PolynomialError:
            return


#: Above this many operations in M and f (:func:`sympy.count_ops`, the derivation's form) only the
#: derivation's form and the plain nested one (:func:`_horner`, nothing protected) are tried: each form
#: costs a common-subexpression pass of seconds at that size, and for bodies whose values are symbols
#: (a general rigid body: 6,434 operations) the collected forms cost 7-26x the series products of the
#: nested one and the protected nested forms 1.0-1.4x (measured on tests/golden's skewed rigid body).
#: Thin rods, tilted axes, friction and an offset centre of mass (130-520 operations) search every form.
SEARCH_OPS = 3000


#: The form chosen for each M and f (the search's result does not depend on the order: a second order
#: of the same bodies in this process builds that form alone).
_CHOSEN: Dict[Tuple, list] = {}


def _graph(system: SeriesSystem):
    main0 = system.key()
    if main0 in _CHOSEN:
        return _build(system, _CHOSEN[main0])
    best, chosen = None, None
    forms = _forms(system)
    if sum(sp.count_ops(e) for e in [*system.M, *system.f]) > SEARCH_OPS:
        forms = _large_forms(system)
    for main in forms:
        built = _build(system, main)
        if best is None or built[0].cost < best[0].cost:
            best, chosen = built, main
    _CHOSEN[main0] = chosen
    return best


def _val(v, k: int) -> str:
    return v[1] if v[0] == "c" else f"{v[1]}[{k}]"


#: Up to this order every sum is written out; above it, sums of more than :data:`INLINE_TERMS`
#: terms are loops with fixed bounds: a taylor_jet written out entirely outgrows the instruction
#: cache from order 17 (measured: 1.52 against 0.94 us a step at order 17).
INLINE_ORDER = 16
INLINE_TERMS = 8
#: Partial sums per long sum: its terms j = lo, lo + 2, ... and lo + 1, lo + 3, ... added in two chains,
#: then the two together -- two additions in flight instead of one long dependent chain (measured 3-14 %
#: quicker at orders 6-20; three or four chains were slower than two).  A fixed order written in the C:
#: the same bits on every machine.  The two partial sums are the two lanes of a vector of two doubles (GNU
#: C vector extensions: SSE2 on x86-64; the same additions in the same order as two scalar chains, so the
#: same bits, with half the loads and arithmetic instructions); sums of 2-3 terms stay scalar (with fused
#: multiply-adds a chain of scalar ones is quicker).  The terms with this order's coefficients are added
#: last (:func:`_reduce`).
LANES = 2
#: Whether the series operations are arranged for a short dependency chain an order (the terms of a
#: sum known first added first; a constant factor put on the factor of a product known first; the
#: factors known first multiplied first): the evaluation at low orders is bound by that chain.
SHORT_PATH = True
#: ... up to this order: above it the series products dominate, and the form with fewest is taken (with
#: fused multiply-adds the fewest products win from order 11 on, measured).
SHORT_PATH_MAX_ORDER = 10
_short_path = SHORT_PATH
_inline_terms = INLINE_TERMS


#: The vector of two doubles of the long sums (:data:`LANES`): a load of ``p[0], p[1]`` and one
#: reversed, ``p[1], p[0]`` (the second factor of a Cauchy product runs backwards), and the fused
#: multiply-adds ``SP_FMA`` and ``sp_fma2`` (two lanes).  Every product of the series is fused with the
#: addition that follows it (:func:`_chain`): about 10 % less time a step than a product and a sum
#: (measured at orders 8-15), written as ``fma`` calls, never left to the compiler's
#: contraction (which differs between compilers).  ``fma`` is correctly rounded, so the processor's
#: instruction (-mfma, :func:`skewpend.numeric.kernels.fused_multiply_add`) and the C library's routine
#: give the same bits; a processor without the instruction gets a product and a sum (``SP_FUSED`` 0).
VECTOR_C = [
    "typedef double sp_v2 __attribute__((vector_size(16)));",
    "static inline sp_v2 sp_ld(const double *p) { sp_v2 v; memcpy(&v, p, sizeof v); return v; }",
    "static inline sp_v2 sp_ldr(const double *p) { sp_v2 v = {p[1], p[0]}; return v; }",
    "#if SP_FUSED",
    "#define SP_FMA(a, b, c) fma(a, b, c)",
    "#if defined(__FMA__) && (defined(__x86_64__) || defined(__i386__))",
    "#include <immintrin.h>",
    "static inline sp_v2 sp_fma2(sp_v2 a, sp_v2 b, sp_v2 c) { return (sp_v2)_mm_fmadd_pd((__m128d)a, (__m128d)b, (__m128d)c); }",
    "#else",
    "static inline sp_v2 sp_fma2(sp_v2 a, sp_v2 b, sp_v2 c) { sp_v2 r = {fma(a[0], b[0], c[0]), fma(a[1], b[1], c[1])}; return r; }",
    "#endif",
    "#else /* a processor without fused multiply-add: a product, then a sum (each rounded) */",
    "#define SP_FMA(a, b, c) ((a) * (b) + (c))",
    "static inline sp_v2 sp_fma2(sp_v2 a, sp_v2 b, sp_v2 c) { return a * b + c; }",
    "#endif",
    f"static const double sp_jd[SP_TPMAX + 2] __attribute__((unused)) = {{{', '.join(f'{i}.0' for i in range(SP_TPMAX + 2))}}};",
]


#: How late each series' coefficient of an order is known, in dependent operations after the speeds'
#: coefficients of that order (x[2][k], x[3][k]: 0, the end of the order before -- the path from them
#: to x[2..3][k + 1] is the order's critical path); a series computed from older coefficients alone
#: (sines and cosines of the angles, their combinations): -1000.  For :func:`_dot` (of its two terms
#: with an order-k coefficient, the later one added last); set by :func:`taylor_c_source`.
_RANK: Dict[str, int] = {}


_EARLY = -1000
#: Each angle's series and its speed's (``x[i]`` -> ``x[n + i]``: ``j q[j] = q'[j - 1]``, exact); set by
#: :func:`taylor_c_source` for its model's ``n``.
_DERIV: Dict[str, str] = {"x[0]": "x[2]", "x[1]": "x[3]"}


def _op_depth(op, d: Dict[str, int]) -> None:
    """The :data:`_RANK` of the series ``op`` computes, into ``d`` (its arguments' there)."""
    def of(v):
        return d.get(v[1], _EARLY) if v[0] == "s" else _EARLY

    kind, t = op[0], op[1]
    args = [of(v) for v in op[2:] if isinstance(v, tuple)]
    if kind == "sincos":  # s[k] from u[k] (j u[j], j <= k); of an angle, from its speed at k - 1
        a = op[2]
        d[t] = d[t + "c"] = _EARLY if a[1] in _DERIV else args[0] + 2
        return
    cost = {"add": 1, "sub": 1, "addc": 1, "neg": 1, "scale": 1, "mul": 2, "sqr": 3, "div": 3, "rdiv": 3,
            "atan": 4}.get(kind, 2)
    top = max(args) if args else _EARLY
    d[t] = _EARLY if top <= _EARLY else top + cost
    if kind == "atan":
        d[t + "d"] = d[t]


def _depths(ops) -> Dict[str, int]:
    """:data:`_RANK` of the series of ``ops`` (in evaluation order)."""
    d: Dict[str, int] = {**{x: _EARLY for x in _DERIV}, **{v: 0 for v in _DERIV.values()}}
    for op in ops:
        _op_depth(op, d)
    return d


def _sub(k: int, j) -> str:
    return str(k - j) if isinstance(j, int) else f"{k} - j"


def _chain(pairs, acc: str = "", fma: str = "SP_FMA") -> str:
    """``acc + A1 B1 + A2 B2 + ...`` for the factor pairs ``(A, B)`` as fused multiply-adds, each
    rounded once (``fma``: correctly rounded on every machine, so the same bits everywhere);
    ``acc`` empty: the first pair a product."""
    for a, b in pairs:
        acc = f"{fma}({a}, {b}, {acc})" if acc else f"{a} * {b}"
    return acc


def _vchain(pairs, acc: str = "") -> str:
    """:func:`_chain` for vectors of two lanes (``sp_fma2``)."""
    return _chain(pairs, acc, "sp_fma2")


def _lanes(terms) -> str:
    """The sum of ``terms`` (each a list of factor pairs): from 2 * :data:`LANES` terms on as
    :data:`LANES` partial sums (terms i, i + LANES, ...: each a chain of fused multiply-adds), then
    those pairwise; else one chain left to right."""
    if LANES > 1 and len(terms) >= 2 * LANES:
        sums = [f"({_chain([p for t in terms[i::LANES] for p in t])})" for i in range(LANES)]
        while len(sums) > 1:
            sums = [f"({a} + {b})" for a, b in zip(sums[0::2], sums[1::2])] + (sums[-1:] if len(sums) % 2 else [])
        return sums[0]
    return f"({_chain([p for t in terms for p in t])})"


def _reduce(term, lo: int, hi: int, init: str = "", op: str = "+", late=(), vterm=None) -> str:
    """C for ``init op (term(lo) + ... + term(hi))`` (``init`` empty: the sum, or its negative).
    ``term(j)``: the factor pairs ``[(A, B), ...]`` of term j (a term is ``A B + ...``), ``vterm(j)``
    those of terms j and j + 1 as vectors of two lanes; every product is fused with the addition
    that follows it (``fma``).  The terms ``late`` (at the ends of the range: those with a
    coefficient of this order, computed just before) are added last, after the others (which need
    only older coefficients, so the processor sums them while this order's coefficients are still
    being computed: the chain of dependent operations of one order shrinks from the length of the
    sums to two or three terms); the others written out, or a loop with fixed bounds for a long sum,
    as :data:`LANES` partial sums from 2 * LANES terms on (written out and in the loop alike: the
    same operations in the same order, the same bits)."""
    if hi < lo:
        return init or "0.0"
    late_in = [j for j in dict.fromkeys(late) if lo <= j <= hi]  # added in this order
    late = sorted(late_in)
    a, b = lo, hi  # the range of the early terms
    while a in late:
        a += 1
    while b in late and b >= a:
        b -= 1
    assert all(j < a or j > b for j in late), (lo, hi, late)
    tail = [p for j in late_in for p in term(j)]
    if b < a:
        early = ""
    elif vterm is not None and LANES == 2 and 4 <= b - a + 1 <= _inline_terms:
        # the two partial sums of _lanes as the two lanes of one vector (the same operations in the same order)
        steps = "".join(f" v_ = {_vchain(vterm(j), 'v_')};" for j in range(a + 2, b, 2))
        lane0 = _chain(term(b), "v_[0]") if (b - a + 1) % 2 else "v_[0]"
        early = f"({{ sp_v2 v_ = {_vchain(vterm(a))};{steps} ({lane0}) + v_[1]; }})"
    elif vterm is not None and LANES == 2 and b - a + 1 > _inline_terms:  # as the loop below
        early = (f"({{ sp_v2 v_ = {{0.0, 0.0}}; int j0_ = {a}; for (; j0_ + 1 <= {b}; j0_ += 2) {{ "
                 f"const int j = j0_; v_ = {_vchain(vterm('j'), 'v_')}; }} double a0_ = v_[0]; "
                 f"if (j0_ <= {b}) {{ const int j = j0_; a0_ = {_chain(term('j'), 'a0_')}; }} a0_ + v_[1]; }})")
    elif b - a + 1 <= _inline_terms:
        early = _lanes([term(j) for j in range(a, b + 1)])
    elif LANES == 2:  # the same two partial sums as written out, in a loop
        early = (f"({{ double a0_ = 0.0, a1_ = 0.0; int j0_ = {a}; for (; j0_ + 1 <= {b}; j0_ += 2) {{ "
                 f"{{ const int j = j0_; a0_ = {_chain(term('j'), 'a0_')}; }} "
                 f"{{ const int j = j0_ + 1; a1_ = {_chain(term('j'), 'a1_')}; }} }} "
                 f"if (j0_ <= {b}) {{ const int j = j0_; a0_ = {_chain(term('j'), 'a0_')}; }} a0_ + a1_; }})")
    else:
        early = (f"({{ double acc_ = {_chain(term(a))}; for (int j = {a + 1}; j <= {b}; j++) "
                 f"acc_ = {_chain(term('j'), 'acc_')}; acc_; }})")
    if op == "+":
        base = f"{init} + {early}" if init and early else (init or early)
        return _chain(tail, base)
    neg = [(f"-{x}", y) for x, y in tail]  # init - early - A B ...: fma(-A, B, .), the negation exact
    if init:
        return _chain(neg, f"{init} - {early}" if early else init)
    return _chain(neg, f"-{early}") if early else f"-({_chain(tail)})"


def _sub1(k: int, j) -> str:
    return str(k - j - 1) if isinstance(j, int) else f"{k} - j - 1"


def _vprod(a: str, b: str, k: int, shift: int = 0):
    """The vector term of ``a[j + shift] * b[k - j]`` for the lanes ``j, j + 1`` (its factor pair)."""
    def v(j):
        aj = j + shift if isinstance(j, int) else (f"j - {-shift}" if shift < 0 else "j")
        return [(f"sp_ld(&{a}[{aj}])", f"sp_ldr(&{b}[{_sub1(k, j)}])")]
    return v


def _dot(a: str, b: str, k: int, lo: int = 0, hi=None) -> str:
    """``a[lo] * b[k - lo] + ... + a[hi] * b[k - hi]`` (hi default k); the terms with ``a[k]`` or
    ``b[k]`` last."""
    hi = k if hi is None else hi
    # of the two terms with an order-k coefficient, the one whose series is computed later goes last
    late = ((k, 0) if _RANK.get(b, -1000) > _RANK.get(a, -1000) else (0, k)) if k > 0 else ()
    return _reduce(lambda j: [(f"{a}[{j}]", f"{b}[{_sub(k, j)}]")], lo, hi, late=late, vterm=_vprod(a, b, k))


def _op_lines(op, k: int, I: str) -> List[str]:
    """C for one operation at the order ``k`` (a number: every sum is written out, so the whole
    series evaluation is straight-line code without loops or data-dependent branches)."""
    kind, t = op[0], op[1]
    a: Tuple[str, str] = op[2] if len(op) > 2 else ("c", "0.0")
    b: Tuple[str, str] = op[3] if len(op) > 3 else ("c", "0.0")

    def at(v):
        return _val(v, k)

    if kind in ("add", "sub"):
        sign = "+" if kind == "add" else "-"
        return [f"{I}{t}[{k}] = {at(a)} {sign} {at(b)};"]
    if kind == "addc":
        return [f"{I}{t}[0] = {at(a)} + {b[1]};"] if k == 0 else [f"{I}{t}[{k}] = {at(a)};"]
    if kind == "neg":
        return [f"{I}{t}[{k}] = -{at(a)};"]
    if kind == "scale":
        return [f"{I}{t}[{k}] = {b[1]} * {at(a)};"]
    if kind == "mul":
        return [f"{I}{t}[{k}] = {_dot(a[1], b[1], k)};"]
    if kind == "sqr":
        x = a[1]
        if k == 0:
            return [f"{I}{t}[0] = {x}[0] * {x}[0];"]
        return [_square(I, f"{t}[{k}]", x, k)]
    if kind in ("div", "rdiv"):  # t = a / b: t[k] = (a[k] - sum_{j=1..k} b[j] t[k-j]) / b[0]
        if k == 0:
            return [f"{I}r{t} = 1.0 / {at(b)};", f"{I}{t}[0] = {at(a)} * r{t};"]
        num = at(a) if a[0] == "s" else "0.0"
        red = _reduce(lambda j: [(f"{b[1]}[{j}]", f"{t}[{_sub(k, j)}]")], 1, k, num, "-", late=(k,),
                      vterm=_vprod(b[1], t, k))
        return [f"{I}{t}[{k}] = ({red}) * r{t};"]
    if kind == "sincos":  # s' = c u', c' = -s u': k s[k] = sum_{j=1..k} j u[j] c[k-j]
        c = t + "c"
        if k == 0:
            return [f"{I}{t}[0] = sin({at(a)});", f"{I}{c}[0] = cos({at(a)});"]
        du, vdu = _derivative_of(a), _vderivative_of(a)
        ss = _reduce(lambda j: [(du(j), f"{c}[{_sub(k, j)}]")], 1, k, late=(k,),
                     vterm=lambda j: [(vdu(j), f"sp_ldr(&{c}[{_sub1(k, j)}])")])
        cs = _reduce(lambda j: [(du(j), f"{t}[{_sub(k, j)}]")], 1, k, late=(k,),
                     vterm=lambda j: [(vdu(j), f"sp_ldr(&{t}[{_sub1(k, j)}])")])
        return [f"{I}{t}[{k}] = ({ss}) * inv[{k}];", f"{I}{c}[{k}] = -({cs}) * inv[{k}];"]
    if kind == "atan":  # t' (1 + u^2) = u': d = 1 + u^2, k t[k] d[0] = k u[k] - sum_{j=1..k-1} d[j] (k-j) t[k-j]
        d = t + "d"
        x = a[1]
        if k == 0:
            return [f"{I}{d}[0] = 1.0 + {at(a)} * {at(a)};", f"{I}r{t} = 1.0 / {d}[0];",
                    f"{I}{t}[0] = atan({at(a)});"]
        acc = _reduce(lambda j: [(f"({d}[{j}] * (double)({_sub(k, j)}))", f"{t}[{_sub(k, j)}]")], 1, k - 1,
                      _derivative_of(a)(k), "-")
        return [_square(I, f"{d}[{k}]", x, k), f"{I}{t}[{k}] = ({acc}) * r{t} * inv[{k}];"]
    raise AssertionError(kind)


def _square(I: str, target: str, x: str, k: int) -> str:
    """``target`` = coefficient ``k`` (>= 1) of the square of the series ``x``: twice the products below the
    middle, plus the middle square."""
    half = _dot(x, x, k, 0, (k + 1) // 2 - 1)
    value = _chain([(f"{x}[{k // 2}]", f"{x}[{k // 2}]")], "h + h") if k % 2 == 0 else "h + h"
    return f"{I}{{ const double h = {half}; {target} = {value}; }}"


def _vderivative_of(a):
    """:func:`_derivative_of` for the lanes ``j, j + 1`` (a vector)."""
    if a[1] in _DERIV:
        return lambda j: f"sp_ld(&{_derivative_of(a)(j)})"
    return lambda j: f"(sp_ld(&sp_jd[{j}]) * sp_ld(&{a[1]}[{j}]))"


def _derivative_of(a):
    """``j u[j]`` as C for the series ``u``: a state variable's derivative series where there is
    one (``j phi[j] = dphi[j-1]``, exact), else the product."""
    if a[1] in _DERIV:
        return lambda j: f"{_DERIV[a[1]]}[{j - 1 if isinstance(j, int) else 'j - 1'}]"
    return lambda j: f"((double)({j}) * {a[1]}[{j}])"


#: Models with more series operations than this print one loop over the orders (each operation once, its
#: sums as loops over ``j``), not every order written out: the written-out jet of a chain of three links with
#: general axes and bodies (564 operations) was 2.3 MB of C at order 15 and took gcc 116 s (-O1 as long); the
#: double pendulum's have 46-82 (written out: 0.61 against 0.94 us a step at order 15, :data:`INLINE_ORDER`).
LOOP_FROM_OPS = 200


def _loop_val(v, k: str) -> str:
    """Coefficient ``k`` (C text) of a value: a constant's is its value at 0, else 0."""
    return f"({k} == 0 ? {v[1]} : 0.0)" if v[0] == "c" else f"{v[1]}[{k}]"


def _loop_sum(target: str, pairs, lo: str, hi: str, init: str = "0.0", sign: str = "") -> List[str]:
    """``target = init + sign sum_{j=lo..hi} A_j B_j`` as a loop of fused multiply-adds (``pairs``: the factors
    as C text of ``j``).  One chain: two partial sums, as :data:`LANES` writes out, made a triple's 20 s run
    take 8.6 ms against 6.5 (the loops are short, k <= 15, and the second lane's indexing and tail cost more)."""
    body = " ".join(f"acc = SP_FMA({sign}{a}, {b}, acc);" for a, b in pairs)
    return [f"{{ double acc = {init}; for (int j = {lo}; j <= {hi}; j++) {{ {body} }} {target} = acc; }}"]


def _loop_op_lines(op, I: str) -> List[str]:
    """C for one operation at the run-time order ``k`` (:data:`LOOP_FROM_OPS`)."""
    kind, t = op[0], op[1]
    a: Tuple[str, str] = op[2] if len(op) > 2 else ("c", "0.0")
    b: Tuple[str, str] = op[3] if len(op) > 3 else ("c", "0.0")
    if kind in ("add", "sub"):
        return [f"{I}{t}[k] = {_loop_val(a, 'k')} {'+' if kind == 'add' else '-'} {_loop_val(b, 'k')};"]
    if kind == "addc":
        return [f"{I}{t}[k] = {_loop_val(a, 'k')} + (k == 0 ? {b[1]} : 0.0);"]
    if kind == "neg":
        return [f"{I}{t}[k] = -{_loop_val(a, 'k')};"]
    if kind == "scale":
        return [f"{I}{t}[k] = {b[1]} * {_loop_val(a, 'k')};"]
    if kind in ("mul", "sqr"):
        y = a if kind == "sqr" else b
        return [I + ln for ln in _loop_sum(f"{t}[k]", [(f"{a[1]}[j]", f"{y[1]}[k - j]")], "0", "k")]
    if kind in ("div", "rdiv"):  # t = a / b: t[k] = (a[k] - sum_{j=1..k} b[j] t[k-j]) / b[0]
        return [f"{I}if (k == 0) r{t} = 1.0 / {b[1]}[0];",
                *(I + ln for ln in _loop_sum(f"{t}[k]", [(f"{b[1]}[j]", f"{t}[k - j]")], "1", "k", _loop_val(a, "k"), "-")),
                f"{I}{t}[k] *= r{t};"]
    if kind == "sincos":  # k s[k] = sum_{j=1..k} j u[j] c[k-j], k c[k] = -sum j u[j] s[k-j]
        c, du = t + "c", _derivative_of(a)("j")
        return [f"{I}if (k == 0) {{ {t}[0] = sin({a[1]}[0]); {c}[0] = cos({a[1]}[0]); }} else {{",
                f"{I}    double as = 0.0, ac = 0.0;",
                f"{I}    for (int j = 1; j <= k; j++) {{ const double ju = {du}; as = SP_FMA(ju, {c}[k - j], as); "
                f"ac = SP_FMA(ju, {t}[k - j], ac); }}",
                f"{I}    {t}[k] = as * inv[k]; {c}[k] = -ac * inv[k];", f"{I}}}"]
    if kind == "atan":  # d = 1 + u^2, k t[k] d[0] = k u[k] - sum_{j=1..k-1} d[j] (k-j) t[k-j]
        d = t + "d"
        return [*(I + ln for ln in _loop_sum(f"{d}[k]", [(f"{a[1]}[j]", f"{a[1]}[k - j]")], "0", "k", "(k == 0 ? 1.0 : 0.0)")),
                f"{I}if (k == 0) {{ r{t} = 1.0 / {d}[0]; {t}[0] = atan({a[1]}[0]); }} else {{",
                *(I + "    " + ln for ln in _loop_sum(f"{t}[k]", [(f"({d}[j] * (double)(k - j))", f"{t}[k - j]")], "1",
                                                          "k - 1", _derivative_of(a)("k"), "-")),
                f"{I}    {t}[k] *= r{t} * inv[k];", f"{I}}}"]
    raise AssertionError(kind)


def taylor_c_source(system: SeriesSystem, order: int, fused: bool = True) -> str:
    """C of the Taylor kernel of the model ``system`` (:func:`exact_system`: the derivation's; or
    :func:`polynomial_system`: a chain's recursive algorithms) at one ``order`` (a small library of its own,
    :func:`skewpend.numeric.kernels.taylor_kernel`): ``taylor_work(p)`` (whether W needs
    integrating), ``taylor_prepare(p, pc)`` (the constants), ``taylor_jet(x, pc, work, e_out)``
    (the coefficients 1 .. order of the state ``x[SP_TN][SP_TPMAX + 2]`` from its coefficients 0,
    and the energy at them into ``*e_out`` when asked, written out order by order: straight-line
    code up to :data:`INLINE_ORDER`, each long sum as :data:`LANES` partial sums in a fixed order),
    then the driver ``taylor.c``.  ``fused``: each product fused with its addition (``SP_FMA``, ``sp_fma2``: for a
    processor with fused multiply-add, :func:`skewpend.numeric.kernels.fused_multiply_add`), else a product
    and a sum.  Raises ValueError for a function without a recurrence here."""
    from .kernel_source import status_defines

    global _inline_terms, _short_path
    _inline_terms = SP_TPMAX + 1 if order <= INLINE_ORDER else INLINE_TERMS
    _short_path = SHORT_PATH and order <= SHORT_PATH_MAX_ORDER
    if not 2 <= order <= SP_TPMAX:
        raise ValueError(f"taylor kernel: order {order} outside 2 .. {SP_TPMAX}")
    n = system.n
    nM = n * (n + 1) // 2
    _DERIV.clear()
    _DERIV.update({f"x[{i}]": f"x[{n + i}]" for i in range(n)})
    g, main, n_main, work = _graph(system)
    _RANK.clear()
    _RANK.update(_depths(g.ops))
    Mp, fs = main[:nM], main[nM:]
    cost = g.cost
    # the energy T + Pi at order 0 only (the rows' energy account: sin/cos of the angles shared with
    # the series), its operations after those of the main block and of W
    n_work = len(g.ops)
    # (not through W's nodes: those are evaluated only when W is integrated)
    in_work = {op[1] + x for op in g.ops[n_main:n_work] for x in ("", "c", "d")}
    g.memo = {e: v for e, v in g.memo.items() if v[1] not in in_work}
    energy = g.node(system.energy)
    c = Lang("c", c_printer(), "const double ", ";")
    I = "    "
    npc = max(len(g.consts), 1)
    tn = 2 * n + 1
    out = [f"/* Generated by skewpend {__version__} from the {system.source} -- do not edit.",
           f" * The Taylor integrator of order {order}: the model's series recurrences, then taylor.c.",
           f" * {system.title.replace('*/', '* /')}",
           f" * Series products per order: {cost:g} (a square counts 1/2, sin/cos 2). */",
           "#include <math.h>", "#include <stdint.h>", "#include <string.h>", "", *status_defines(), "",
           f"#define SP_TN {tn}", f"#define SP_TPMAX {SP_TPMAX}", f"#define SP_TORDER {order}",
           f"#define SP_TAYLOR_NPC {npc}", f"#define SP_FUSED {int(bool(fused))}", "", *VECTOR_C, ""]
    zero_q = all(v == ("c", "0.0") for v in work)  # Q = 0 already (a model without its terms): W' = 0
    idx = list(system.work or ())
    out += ["/* W' = Q . q' needs integrating unless these parameters are all 0 (then Q = 0 identically) */",
            "static int taylor_work(const double *p)", "{",
            f"{I}(void)p;" if zero_q else "",
            f"{I}return {'0' if zero_q else ' || '.join(f'p[{i}] != 0.0' for i in idx) if idx else '1'};", "}", ""]
    out += list(system.prelude)
    out += ["/* the state-free subexpressions, once per call, into pc[SP_TAYLOR_NPC] */",
            "static void taylor_prepare(const double *p, double *pc)", "{"]
    out += system.prepare(c, I, used_names(g.consts))
    if g.consts:
        block = cse_block(c, g.consts, [f"pc[{i}]" for i in range(len(g.consts))], I, prefix="w")
        out += [ln.replace(f"{I}const double pc[", f"{I}pc[") for ln in block]
    else:
        out.append(f"{I}pc[0] = 0.0;")
    out += ["}", ""]
    names = [op[1] for op in g.ops]
    extra = [op[1] + "c" for op in g.ops if op[0] == "sincos"] + [op[1] + "d" for op in g.ops if op[0] == "atan"]
    acc = [f"a{i + 1}" for i in range(n)]
    L = "SP_TORDER"
    out += ["/* coefficients 1 .. SP_TORDER of x[SP_TN] from x[i][0]: x[i][k + 1] = (x_i')[k] / (k + 1) */",
            "static void taylor_jet(double (*restrict x)[SP_TPMAX + 2], const double *restrict pc, int work, double *e_out)",
            "{",
            f"{I}static const double inv[SP_TPMAX + 2] = {{0.0, {', '.join(f'1.0 / {i}' for i in range(1, SP_TPMAX + 2))}}};",
            f"{I}double {', '.join(f'{n}[{L}]' for n in names + extra + acc)};"]
    recips = [op[1] for op in g.ops if op[0] in ("div", "rdiv", "atan")]
    if recips:
        out.append(f"{I}double {', '.join(f'r{n} = 0.0' for n in recips)};")
    # M[0]^-1 of the series' solve (packed lower triangle, row by row), named once a step
    inv_names = [f"sp_i{i + 1}{j + 1}" for i in range(n) for j in range(i + 1)]
    driver = (Path(__file__).resolve().parent / "taylor.c").read_text()

    def solve(k: int) -> List[str]:
        """M q''[k] = f[k] - sum_{j=1..k} M[j] q''[k-j] (constant entries of M: nothing beyond order 0)."""
        if k == 0:  # M[0] = L D L^T once a step and from its factors M[0]^-1, used at every order (codegen's LDL^T)
            m0 = [f"({_val(m, 0)})" for m in Mp]
            lines = [f"{I}const double {t} = {e};" for t, e in
                     ldlt_factor_steps(m0, "sp_f", fused=True) + ldlt_inverse_steps(n, inv_names, "sp_f", "sp_", fused=True)]
        else:
            lines = []
        for i in range(n):
            series = [(_m_at(Mp, i, j), acc[j]) for j in range(n) if _m_at(Mp, i, j)[0] == "s"]

            def term(j, series=series):
                return [(f"{m[1]}[{j}]", f"{q}[{_sub(k, j)}]") for m, q in series]

            def vterm(j, series=series):
                return [p for m, q in series for p in _vprod(m[1], q, k)(j)]

            # f[k] (the last value of the order) minus the sum of the M[j] q''[k-j] (known before it)
            value = (f"{_val(fs[i], k)} - ({_reduce(term, 1, k, late=(k, 1), vterm=vterm)})" if series and k > 0
                     else _val(fs[i], k))
            lines.append(f"{I}const double r{i + 1}_{k} = {value};")
        # q''[k] = M[0]^-1 r and x[n..2n-1][k + 1] = q''[k] / (k + 1), each a product of M[0]^-1 (scaled by
        # 1 / (k + 1), off the critical path) with r: a product and a fused add after r, where the
        # substitutions would be three dependent operations and the scaling a fourth
        r = [f"r{i + 1}_{k}" for i in range(n)]
        lines += [f"{I}{{"] + [f"{I}    {t} = {e};" for t, e in spd_mul_steps(inv_names, r, [f"{a}[{k}]" for a in acc],
                                                                                fused=True)]
        if k == 0:
            lines += [f"{I}    x[{n + i}][1] = {acc[i]}[0];" for i in range(n)]
        else:
            scaled = [f"sp_s{c[4:]}" for c in inv_names]
            lines += [f"{I}    const double {t} = {c} * inv[{k + 1}];" for t, c in zip(scaled, inv_names)]
            lines += [f"{I}    {t} = {e};" for t, e in spd_mul_steps(scaled, r, [f"x[{n + i}][{k + 1}]" for i in range(n)],
                                                                   fused=True)]
        lines += [f"{I}}}"] + [f"{I}x[{i}][{k + 1}] = x[{n + i}][{k}] * inv[{k + 1}];" for i in range(n)]
        return lines

    def work_lines(k: int) -> List[str]:
        """W' = Q . q' (its series products written out too)."""
        lines = []
        for op in g.ops[n_main:n_work]:
            lines += _op_lines(op, k, I + "    ")
        w = []
        for i, q in enumerate(work):
            v = f"x[{n + i}]"
            if q[0] == "c":
                w.append(f"{q[1]} * {v}[{k}]")
            else:
                w.append(f"({_dot(q[1], v, k)})")
        return ([f"{I}if (work) {{"] + lines + [f"{I}    x[{2 * n}][{k + 1}] = ({' + '.join(w)}) * inv[{k + 1}];",
                                                 f"{I}}} else {{", f"{I}    x[{2 * n}][{k + 1}] = 0.0;", f"{I}}}"])

    if len(g.ops) > LOOP_FROM_OPS:
        return "\n".join(out + _looped_jet(g, n, n_main, n_work, Mp, fs, work, energy, inv_names, acc, I)) + "\n" + driver

    for k in range(order):
        out += ["", f"{I}/* order {k} */"]
        for op in g.ops[:n_main]:
            out += _op_lines(op, k, I)
        if k == 0:  # the energy T + Pi of x[.][0], when asked for
            lines = [ln for op in g.ops[n_work:] for ln in _op_lines(op, 0, I + "    ")]
            out += [f"{I}if (e_out) {{", *lines, f"{I}    *e_out = {_val(energy, 0)};", f"{I}}}"]
        out += solve(k) + work_lines(k)
    out += ["}", ""]
    return "\n".join(out) + "\n" + driver


def _m_at(Mp, i: int, j: int):
    """Entry ``(i, j)`` of the symmetric M from its packed lower triangle ``Mp``."""
    return Mp[max(i, j) * (max(i, j) + 1) // 2 + min(i, j)]


def _looped_jet(g, n: int, n_main: int, n_work: int, Mp, fs, work, energy, inv_names, acc, I: str) -> List[str]:
    """The body of ``taylor_jet`` as one loop over the orders ``k`` (:data:`LOOP_FROM_OPS`); the declarations
    before it are :func:`taylor_c_source`'s."""
    lines = [f"{I}double {', '.join(inv_names)};", f"{I}for (int k = 0; k < SP_TORDER; k++) {{"]
    J = I + "    "
    for op in g.ops[:n_main]:
        lines += _loop_op_lines(op, J)
    energy_lines = [ln for op in g.ops[n_work:] for ln in _op_lines(op, 0, J + "    ")]
    lines += [f"{J}if (k == 0 && e_out) {{", *energy_lines, f"{J}    *e_out = {_val(energy, 0)};", f"{J}}}"]
    # M[0] = L D L^T and its inverse once a step, then q''[k] = M[0]^-1 (f[k] - sum_{j=1..k} M[j] q''[k-j])
    m0 = [f"({_val(m, 0)})" for m in Mp]
    lines += [f"{J}if (k == 0) {{"]
    lines += [f"{J}    const double {t} = {e};" for t, e in ldlt_factor_steps(m0, "sp_f", fused=True)]
    lines += [(f"{J}    {t} = {e};" if t in inv_names else f"{J}    const double {t} = {e};")
              for t, e in ldlt_inverse_steps(n, inv_names, "sp_f", "sp_", fused=True)]
    lines += [f"{J}}}"]
    r = [f"r{i + 1}" for i in range(n)]
    lines.append(f"{J}double {', '.join(r)};")
    for i in range(n):
        pairs = [(f"{_m_at(Mp, i, l)[1]}[j]", f"{acc[l]}[k - j]") for l in range(n) if _m_at(Mp, i, l)[0] == "s"]
        lines += ([J + ln for ln in _loop_sum(r[i], pairs, "1", "k", _loop_val(fs[i], "k"), "-")]
                  if pairs else [f"{J}{r[i]} = {_loop_val(fs[i], 'k')};"])
    lines += [f"{J}{t} = {e};" for t, e in spd_mul_steps(inv_names, r, [f"{a}[k]" for a in acc], fused=True)]
    lines += [f"{J}x[{n + i}][k + 1] = {acc[i]}[k] * inv[k + 1];" for i in range(n)]
    lines += [f"{J}x[{i}][k + 1] = x[{n + i}][k] * inv[k + 1];" for i in range(n)]
    wl = [ln for op in g.ops[n_main:n_work] for ln in _loop_op_lines(op, J + "    ")]
    terms = []
    for i, q in enumerate(work):
        if q[0] == "c":
            terms.append(f"{J}    w = SP_FMA({q[1]}, x[{n + i}][k], w);")
        else:
            terms.append(f"{J}    for (int j = 0; j <= k; j++) w = SP_FMA({q[1]}[j], x[{n + i}][k - j], w);")
    lines += [f"{J}if (work) {{", *wl, f"{J}    double w = 0.0;", *terms, f"{J}    x[{2 * n}][k + 1] = w * inv[k + 1];",
              f"{J}}} else {{", f"{J}    x[{2 * n}][k + 1] = 0.0;", f"{J}}}", f"{I}}}", "}", ""]
    return lines
