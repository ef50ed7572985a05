"""A chain's model read as polynomials in its angles' sines and cosines and its speeds: the form of the
recursive algorithms' equations in which the Taylor integrator's series are cheap.

The recursive algorithms (:func:`skewpend.numeric.recursive.chain_functions`) build ``M(q)``, ``f(q, q')``,
the joint forces ``Q`` and the energy ``T + Pi`` through rotations composed link by link: taken as a graph of
series, each rotation's entries are products of series (two links: 138 Cauchy products an order, against the
derivation's few dozen).  The same quantities are short polynomials: the mass matrix's entries in the sines
and cosines of the angles after the first (the first cancels through ``sin^2 + cos^2 = 1``), ``f``'s in those
and the speeds' products.  :func:`polynomial_model` walks the graph once, operation by operation, in
polynomial arithmetic whose coefficients are functions of the parameter vector ``p`` (CasADi expressions,
printed into the Taylor kernel's ``taylor_prepare``), and gives the polynomials to the Taylor generator
(:mod:`skewpend.numeric.taylor_source`), which tries its expanded, collected and nested forms on them as on
the derivation's.

*Which coefficients vanish.*  A coefficient that cancels (the first angle's ``sin^2 + cos^2``, a unit axis's
components) is zero for every ``p`` of the structure.  Each coefficient is evaluated alongside at
:data:`SAMPLES` random parameter vectors of the structure (unit axes in their patterns) and dropped when every
value is below :data:`ZERO_TOL` of the magnitude of what was added up -- an identity test at random points
(a polynomial in ``p`` that is not identically zero vanishes at a random point with probability 0); one equal
to a number at every sample is that number (a unit axis's ``ex^2 + ez^2``).  The result is checked against
the graph it came from at random states and parameters before it is used (:func:`check`).
"""

from __future__ import annotations

import math
import random
from dataclasses import dataclass
from typing import Dict, List, Sequence, Tuple

import sympy as sp

from ..errors import require

__all__ = ["PolynomialModel", "polynomial_model", "check", "SAMPLES", "ZERO_TOL"]

#: Random parameter vectors each coefficient is evaluated at.
SAMPLES = 3
#: A coefficient whose values are all below this fraction of the magnitude of its terms is zero.
ZERO_TOL = 1e-9

_Vals = Tuple[float, ...]


@dataclass
class _Coef:
    """A coefficient: its node in the coefficients' graph (an expression of ``p``, :meth:`_Lifter.node`), its
    values at the samples, and the magnitude of what was added up to it (the scale its rounding is relative to)."""

    sx: int
    vals: _Vals
    scale: _Vals


@dataclass
class PolynomialModel:
    """A chain's ``M`` (packed lower triangle, row by row), ``f``, ``Q`` and ``T + Pi`` as SymPy expressions
    in ``sin(q_i)``, ``cos(q_i)``, ``q_i'`` (symbols ``q``, ``dq``) and the named constants ``K0, K1, ...``,
    whose values are ``constants(p)`` (a CasADi function of the parameter vector)."""

    n: int
    q: Tuple[sp.Symbol, ...]
    dq: Tuple[sp.Symbol, ...]
    M: List[sp.Expr]
    f: List[sp.Expr]
    Q: List[sp.Expr]
    energy: sp.Expr
    names: Tuple[str, ...]  # the constants' names, in constants' output order
    constants: object  # casadi.Function p -> the constants


class _Lifter:
    def __init__(self, n: int, p_sx, samples: Sequence[Sequence[float]]):
        ca = require("casadi", "a chain of links (its recursive algorithms)")
        self.ca = ca
        self.n = n
        self.p = p_sx
        self.samples = samples
        self.q = tuple(sp.Symbol(f"q{i + 1}") for i in range(n))
        self.dq = tuple(sp.Symbol(f"dq{i + 1}") for i in range(n))
        # generators: sin q_i, cos q_i, q_i' (then q_i itself and whatever is no polynomial, as met)
        self.gens: List[sp.Expr] = []
        self.gen_index: Dict[sp.Expr, int] = {}
        self.sin_of: Dict[int, int] = {}  # gen index of sin q_i -> that of cos q_i
        for i in range(n):
            s, c = self.gen(sp.sin(self.q[i])), self.gen(sp.cos(self.q[i]))
            self.sin_of[s] = c
        for i in range(n):
            self.gen(self.dq[i])
        self.named: Dict[Tuple, sp.Symbol] = {}  # the named coefficients, by their values at the samples
        self.sx_out: List[int] = []  # their nodes, in the order of their names
        self.nodes: List[Tuple] = []  # the coefficients' graph: ("n", x), ("p", k), (operation, operands...)
        self.index: Dict[Tuple, int] = {}

    def gen(self, e: sp.Expr) -> int:
        if e not in self.gen_index:
            self.gen_index[e] = len(self.gens)
            self.gens.append(e)
        return self.gen_index[e]

    # -- coefficients: expressions of p as nodes of a graph of our own (hash-consed: the same operation on the
    # same operands is one node), made CasADi expressions at the end for the coefficients named (a CasADi
    # operation from Python costs ~35 us: a triple's ~500,000 took 17 s; a tuple here well under 1 us) ----------
    def node(self, *key) -> int:
        if key not in self.index:
            self.index[key] = len(self.nodes)
            self.nodes.append(key)
        return self.index[key]

    def number(self, x: float) -> _Coef:
        return _Coef(self.node("n", float(x)), (x,) * SAMPLES, (abs(x),) * SAMPLES)

    def parameter(self, k: int) -> _Coef:
        vals = tuple(s[k] for s in self.samples)
        return _Coef(self.node("p", k), vals, tuple(abs(v) for v in vals))

    @staticmethod
    def _zero(c: _Coef) -> bool:
        return all(abs(v) <= ZERO_TOL * s for v, s in zip(c.vals, c.scale))

    def cadd(self, a: _Coef, b: _Coef, sign: float = 1.0) -> _Coef:
        key = ("+", min(a.sx, b.sx), max(a.sx, b.sx)) if sign > 0 else ("-", a.sx, b.sx)
        return _Coef(self.node(*key), tuple(x + sign * y for x, y in zip(a.vals, b.vals)),
                     tuple(max(x, y) for x, y in zip(a.scale, b.scale)))

    def cmul(self, a: _Coef, b: _Coef) -> _Coef:
        return _Coef(self.node("*", min(a.sx, b.sx), max(a.sx, b.sx)), tuple(x * y for x, y in zip(a.vals, b.vals)),
                     tuple(x * y for x, y in zip(a.scale, b.scale)))

    def cscale(self, c: _Coef, k: float) -> _Coef:
        if k == 1.0:
            return c
        sx = self.node("neg", c.sx) if k == -1.0 else self.node("*", *sorted((self.number(k).sx, c.sx)))
        return _Coef(sx, tuple(k * v for v in c.vals), tuple(abs(k) * s for s in c.scale))

    def cunary(self, op, a: _Coef) -> _Coef:
        ca = self.ca
        if op == ca.OP_ASSIGN:
            return a
        if op in (ca.OP_NEG, ca.OP_TWICE):
            return self.cscale(a, -1.0 if op == ca.OP_NEG else 2.0)
        if op == ca.OP_SQ:
            return self.cmul(a, a)
        f = {ca.OP_SIN: ("sin", math.sin), ca.OP_COS: ("cos", math.cos), ca.OP_ATAN: ("atan", math.atan),
             ca.OP_SQRT: ("sqrt", math.sqrt), ca.OP_INV: ("inv", lambda x: 1 / x)}
        if op not in f:
            raise ValueError(f"the chain's equations use CasADi operation {op}, which has no series form here")
        name, fv = f[op]
        vals = tuple(fv(v) for v in a.vals)
        return _Coef(self.node(name, a.sx), vals, tuple(abs(v) for v in vals))

    def cdiv(self, a: _Coef, b: _Coef) -> _Coef:
        return _Coef(self.node("/", a.sx, b.sx), tuple(x / y for x, y in zip(a.vals, b.vals)),
                     tuple(x / abs(y) for x, y in zip(a.scale, b.vals)))

    def casadi(self, ids: Sequence[int]) -> List[object]:
        """The CasADi expressions of the nodes ``ids`` (those they need made once, in the graph's order)."""
        ca = self.ca
        need, stack = set(), list(ids)
        while stack:
            i = stack.pop()
            if i in need:
                continue
            need.add(i)
            key = self.nodes[i]
            if key[0] not in ("n", "p"):
                stack += list(key[1:])
        unary = {"neg": lambda x: -x, "sin": ca.sin, "cos": ca.cos, "atan": ca.atan, "sqrt": ca.sqrt, "inv": lambda x: 1 / x}
        binary = {"+": lambda x, y: x + y, "-": lambda x, y: x - y, "*": lambda x, y: x * y, "/": lambda x, y: x / y}
        sx: Dict[int, object] = {}
        for i in sorted(need):
            key = self.nodes[i]
            if key[0] == "n":
                sx[i] = ca.SX(key[1])
            elif key[0] == "p":
                sx[i] = self.p[key[1]]
            elif key[0] in unary:
                sx[i] = unary[key[0]](sx[key[1]])
            else:
                sx[i] = binary[key[0]](sx[key[1]], sx[key[2]])
        return [sx[i] for i in ids]

    # -- polynomials: {monomial: coefficient}, a monomial a sorted tuple of (generator, exponent) ---------------
    def reduce(self, mono: Dict[int, int]) -> List[Tuple[Tuple, float]]:
        """``mono`` with every ``sin^2 q_i`` as ``1 - cos^2 q_i``: its terms (monomial, sign)."""
        out = [(dict(mono), 1.0)]
        for s, c in self.sin_of.items():
            nxt = []
            for m, sign in out:
                e = m.get(s, 0)
                if e < 2:
                    nxt.append((m, sign))
                    continue
                # sin^e = sin^(e mod 2) (1 - cos^2)^(e // 2)
                half, m = e // 2, dict(m)
                m[s] = e % 2
                for k in range(half + 1):
                    t = dict(m)
                    t[c] = t.get(c, 0) + 2 * k
                    nxt.append((t, sign * math.comb(half, k) * (-1) ** k))
            out = nxt
        return [(tuple(sorted((g, e) for g, e in m.items() if e)), sign) for m, sign in out]

    def add(self, P: Dict, R: Dict, sign: float = 1.0) -> Dict:
        out = dict(P)
        for m, c in R.items():
            out[m] = self.cadd(out[m], c, sign) if m in out else (c if sign > 0 else self.cscale(c, -1.0))
        return {m: c for m, c in out.items() if not self._zero(c)}

    def mul(self, P: Dict, R: Dict) -> Dict:
        out: Dict[Tuple, _Coef] = {}
        for m1, c1 in P.items():
            for m2, c2 in R.items():
                mono = dict(m1)
                for g, e in m2:
                    mono[g] = mono.get(g, 0) + e
                c = self.cmul(c1, c2)
                for m, sign in self.reduce(mono):
                    term = c if sign == 1.0 else self.cscale(c, sign)
                    out[m] = self.cadd(out[m], term) if m in out else term
        return {m: c for m, c in out.items() if not self._zero(c)}

    def const_of(self, P: Dict):
        """The coefficient of a polynomial that is a constant, else None."""
        if not P:
            return self.number(0.0)
        if len(P) == 1 and () in P:
            return P[()]
        return None

    def opaque(self, e: sp.Expr) -> Dict:
        return {((self.gen(e), 1),): self.number(1.0)}

    # -- back to SymPy ------------------------------------------------------------------------------------------
    def walk(self, fn) -> Dict[Tuple[int, int], Dict]:
        """Each output entry of ``fn`` (inputs ``y = (q, q')`` and ``p``) as a polynomial."""
        ca = self.ca
        reg: Dict[int, Dict] = {}
        out: Dict[Tuple[int, int], Dict] = {}
        n = self.n
        for i in range(fn.n_instructions()):
            op = fn.instruction_id(i)
            ins, outs = fn.instruction_input(i), fn.instruction_output(i)
            if op == ca.OP_INPUT:
                if ins[0] == 0:
                    k = ins[1]
                    sym = self.q[k] if k < n else self.dq[k - n]
                    reg[outs[0]] = {((self.gen(sym), 1),): self.number(1.0)}
                else:
                    reg[outs[0]] = {(): self.parameter(ins[1])}
                continue
            if op == ca.OP_OUTPUT:
                out[outs[0], outs[1]] = reg[ins[0]]
                continue
            if op == ca.OP_CONST:
                x = float(fn.instruction_constant(i))
                reg[outs[0]] = {(): self.number(x)} if x != 0.0 else {}
                continue
            binary = op in (ca.OP_ADD, ca.OP_SUB, ca.OP_MUL, ca.OP_DIV)
            args = [reg[j] for j in (ins[:2] if binary else ins[:1])]
            consts = [self.const_of(a) for a in args]
            if all(c is not None for c in consts):  # a function of p alone
                if binary:
                    a, b = consts
                    c = {ca.OP_ADD: lambda: self.cadd(a, b), ca.OP_SUB: lambda: self.cadd(a, b, -1.0),
                         ca.OP_MUL: lambda: self.cmul(a, b), ca.OP_DIV: lambda: self.cdiv(a, b)}[op]()
                else:
                    c = self.cunary(op, consts[0])
                reg[outs[0]] = {} if self._zero(c) else {(): c}
                continue
            if op in (ca.OP_ADD, ca.OP_SUB):
                reg[outs[0]] = self.add(args[0], args[1], 1.0 if op == ca.OP_ADD else -1.0)
            elif op in (ca.OP_MUL, ca.OP_SQ):  # a square's one argument twice
                reg[outs[0]] = self.mul(args[0], args[-1])
            elif op in (ca.OP_NEG, ca.OP_TWICE):
                reg[outs[0]] = {m: self.cscale(c, -1.0 if op == ca.OP_NEG else 2.0) for m, c in args[0].items()}
            elif op == ca.OP_ASSIGN:
                reg[outs[0]] = args[0]
            elif op == ca.OP_DIV and consts[1] is not None:
                inv = self.cdiv(self.number(1.0), consts[1])
                reg[outs[0]] = {m: self.cmul(c, inv) for m, c in args[0].items()}
            elif op in (ca.OP_SIN, ca.OP_COS) and len(args[0]) == 1:
                (m, c), = args[0].items()
                if len(m) == 1 and m[0][1] == 1 and self.gens[m[0][0]] in self.q and c.vals == (1.0,) * SAMPLES:
                    trig = (sp.sin if op == ca.OP_SIN else sp.cos)(self.gens[m[0][0]])
                    reg[outs[0]] = {((self.gen(trig), 1),): self.number(1.0)}
                else:
                    reg[outs[0]] = self.opaque((sp.sin if op == ca.OP_SIN else sp.cos)(self.sympy(args[0])))
            elif op == ca.OP_ATAN:
                reg[outs[0]] = self.opaque(sp.atan(self.sympy(args[0])))
            elif op == ca.OP_DIV:
                reg[outs[0]] = self.mul(args[0], self.opaque(1 / self.sympy(args[1])))
            elif op == ca.OP_INV:
                reg[outs[0]] = self.opaque(1 / self.sympy(args[0]))
            else:
                raise ValueError(f"the chain's equations use CasADi operation {op}, which has no series form here")
        return out

    def name(self, c: _Coef) -> sp.Expr:
        """A coefficient as SymPy: a number when its samples say so, else +- a named constant (one name for
        every coefficient with the same values at the samples)."""
        v0 = c.vals[0]
        if all(abs(v - v0) <= ZERO_TOL * max(s, 1e-300) for v, s in zip(c.vals, c.scale)):
            exact = round(v0)
            return sp.Integer(exact) if abs(v0 - exact) <= ZERO_TOL * max(c.scale) else sp.Float(v0)
        key = tuple(float(f"{v:.11e}") for v in c.vals)
        neg = tuple(float(f"{-v:.11e}") for v in c.vals)
        if neg in self.named:
            return -self.named[neg]
        if key not in self.named:
            self.named[key] = sp.Symbol(f"K{len(self.sx_out)}")
            self.sx_out.append(c.sx)
        return self.named[key]

    def sympy(self, P: Dict) -> sp.Expr:
        return sp.Add(*(self.name(c) * sp.Mul(*(self.gens[g] ** e for g, e in m)) for m, c in P.items()))


def _samples(structure, names: Sequence[str], count: int, seed: int = 20261207) -> List[List[float]]:
    """Random parameter vectors of ``structure``: every entry from N(0, 1) (masses and the like need no sign
    here: the identities hold for any value), each link's hinge axis a random unit vector in its pattern."""
    rng = random.Random(seed)
    out = []
    for _ in range(count):
        p = [rng.gauss(0.0, 1.0) for _ in names]
        for i, pattern in enumerate(structure.patterns, start=1):
            if pattern[0] in "+-":
                continue
            idx = [names.index(f"e{c}{i}") for c in pattern]
            norm = math.sqrt(sum(p[k] ** 2 for k in idx))
            for k in idx:
                p[k] /= norm
        out.append(p)
    return out


def polynomial_model(structure) -> PolynomialModel:
    """The chain of ``structure`` (:class:`~skewpend.numeric.recursive.ChainStructure`) as polynomials."""
    from .recursive import chain_functions, parameter_names

    ca = require("casadi", "a chain of links (its recursive algorithms)")
    fns = chain_functions(structure)
    names = parameter_names(structure.n)
    n = structure.n
    p = ca.SX.sym("p", len(names))
    lifter = _Lifter(n, p, _samples(structure, names, SAMPLES))
    model = lifter.walk(fns["model"])
    energy = lifter.walk(fns["energy"])
    nM = n * (n + 1) // 2
    M = [lifter.sympy(model.get((0, j), {})) for j in range(nM)]
    f = [lifter.sympy(model.get((1, j), {})) for j in range(n)]
    Q = [lifter.sympy(model.get((2, j), {})) for j in range(n)]
    E = lifter.sympy(energy.get((0, 0), {}))
    knames = tuple(f"K{k}" for k in range(len(lifter.sx_out)))
    constants = ca.Function("constants", [p], [ca.vertcat(*lifter.casadi(lifter.sx_out))] if lifter.sx_out else [ca.SX(1, 1)],
                            {"cse": True})
    return PolynomialModel(n, lifter.q, lifter.dq, M, f, Q, E, knames, constants)


def check(pm: PolynomialModel, structure, p_values: Sequence[float], states: int = 5, seed: int = 1) -> float:
    """The largest difference, relative to each output's scale, between ``pm`` and the recursive graph it came
    from at ``states`` random states and the parameter vector ``p_values`` (a real chain's)."""
    import numpy as np

    from .recursive import chain_functions

    fns = chain_functions(structure)
    n = pm.n
    k = np.array(pm.constants(np.asarray(p_values, float))).ravel()
    subs_k = {sp.Symbol(name): float(v) for name, v in zip(pm.names, k)}
    exprs = [*pm.M, *pm.f, *pm.Q, pm.energy]
    fn = sp.lambdify([*pm.q, *pm.dq], [sp.sympify(e).xreplace(subs_k) for e in exprs], "math")
    rng = np.random.default_rng(seed)
    worst = 0.0
    for _ in range(states):
        y = rng.uniform(-math.pi, math.pi, 2 * n) * np.r_[np.ones(n), 0.5 * np.ones(n)]
        M, f, Q = (np.array(x).ravel() for x in fns["model"](y, p_values))
        E = float(fns["energy"](y, p_values))
        ref = np.r_[M, f, Q, E]
        got = np.array(fn(*y), dtype=float)
        for part in (slice(0, len(M)), slice(len(M), len(M) + 2 * n), slice(len(ref) - 1, len(ref))):
            scale = max(np.max(np.abs(ref[part])), 1e-300)
            worst = max(worst, float(np.max(np.abs(got[part] - ref[part])) / scale))
    return worst
