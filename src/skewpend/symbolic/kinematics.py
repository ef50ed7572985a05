"""Kinematics by rotation tensors (the specification's method), in exact polynomial algebra.

Angles enter through their cosine and sine, held as separate generators of a
polynomial ring over the rationals while the kinematics is built (``c_phi``,
``s_phi``, ...).  Every product of rotation tensors is then a polynomial, and
SymPy's sparse polynomial arithmetic (``sympy.polys.rings``) keeps the whole
derivation exact and fast, with no expression swell.  Relations such as
``cos^2 + sin^2 = 1`` (or ``|n| = 1`` for a hinge axis given by its components)
are applied afterwards by :meth:`Algebra.shortest`, which picks the shortest
reduced form of each entry and only then turns it into a SymPy expression with
``cos``/``sin`` restored.

Vectors are lists of 3 ring elements (components along ``i, j, k``); tensors are
3x3 nested lists in the same basis.
"""

from __future__ import annotations

import itertools
from dataclasses import dataclass
from typing import Dict, Iterable, List, Mapping, Sequence, Tuple

import sympy as sp
from sympy.polys.rings import PolyElement, ring

__all__ = ["Relation", "Algebra", "Vec", "Mat", "floats_for_long_rationals"]

Vec = List[PolyElement]
Mat = List[List[PolyElement]]


@dataclass(frozen=True)
class Relation:
    """A relation ``sum(v_i**2) = 1 - offset`` between generators.

    For an angle the generators are ``(cos, sin)``; for a unit vector its symbolic
    components (``offset`` = the sum of squares of its numeric ones); for ``r = 1/|v|``
    the single generator ``r`` with ``offset = 1 - 1/|v|**2``.  Reduction removes even
    powers of one generator, chosen among ``choices`` (default: any).
    """

    gens: Tuple[int, ...]  # generator indices
    offset: object = 0
    choices: Tuple[int, ...] = ()  # positions in gens that may be eliminated

    @property
    def eliminable(self) -> Tuple[int, ...]:
        return self.choices or tuple(range(len(self.gens)))


_LONG = 10**9


def floats_for_long_rationals(expr: sp.Expr) -> sp.Expr:
    """Show exact fractions with long numerators or denominators (the exact binary values
    of a user's floats, and their products) as floats again."""
    big = {r: sp.Float(r, 15) for r in expr.atoms(sp.Rational) if abs(r.p) > _LONG or r.q > _LONG}
    return expr.xreplace(big) if big else expr


class Algebra:
    """A polynomial ring over QQ with the geometry helpers the derivation needs."""

    def __init__(self, symbols: Sequence[sp.Symbol]):
        self.symbols = list(symbols)
        self.R, *gens = ring(self.symbols, sp.QQ)
        self.gens = dict(zip((s.name for s in self.symbols), gens))
        self.index = {s.name: i for i, s in enumerate(self.symbols)}

    # -- construction -------------------------------------------------------------------
    def const(self, x) -> PolyElement:
        return self.R(x)

    def vec(self, items: Iterable) -> Vec:
        return [self.R(x) if not isinstance(x, PolyElement) else x for x in items]

    # -- linear algebra -----------------------------------------------------------------
    @staticmethod
    def add(u: Vec, v: Vec) -> Vec:
        return [x + y for x, y in zip(u, v)]

    @staticmethod
    def scale(k, u: Vec) -> Vec:
        return [k * x for x in u]

    @staticmethod
    def dot(u: Vec, v: Vec) -> PolyElement:
        return u[0] * v[0] + u[1] * v[1] + u[2] * v[2]

    @staticmethod
    def cross(u: Vec, v: Vec) -> Vec:
        return [
            u[1] * v[2] - u[2] * v[1],
            u[2] * v[0] - u[0] * v[2],
            u[0] * v[1] - u[1] * v[0],
        ]

    @staticmethod
    def matvec(m: Mat, v: Vec) -> Vec:
        return [m[r][0] * v[0] + m[r][1] * v[1] + m[r][2] * v[2] for r in range(3)]

    @staticmethod
    def matmul(m: Mat, n: Mat) -> Mat:
        return [[sum((m[r][k] * n[k][c] for k in range(3)), m[0][0] * 0) for c in range(3)] for r in range(3)]

    @staticmethod
    def transpose(m: Mat) -> Mat:
        return [[m[c][r] for c in range(3)] for r in range(3)]

    def rotation(self, c: PolyElement, s: PolyElement, n: Vec) -> Mat:
        """Rodrigues' formula ``P = n n + (E - n n) cos + n x E sin`` (``n`` a unit vector)."""
        skew = [[0, -n[2], n[1]], [n[2], 0, -n[0]], [-n[1], n[0], 0]]
        return [
            [n[r] * n[k] * (1 - c) + (c if r == k else 0) + s * skew[r][k] for k in range(3)]
            for r in range(3)
        ]

    # -- calculus ------------------------------------------------------------------------
    def d_dangle(self, p: PolyElement, cos: str, sin: str) -> PolyElement:
        """Derivative with respect to an angle whose cosine and sine are generators."""
        c, s = self.gens[cos], self.gens[sin]
        return p.diff(c) * (-s) + p.diff(s) * c

    # -- simplification ------------------------------------------------------------------
    def _eliminate(self, p: PolyElement, rel: Relation, which: int) -> PolyElement:
        """Replace ``v_which**2`` by ``1 - sum(other v_i**2)`` throughout ``p``."""
        idx = rel.gens[which]
        rest = self.R.one - self.R.domain.convert(rel.offset)
        for other in rel.gens:
            if other != idx:
                rest -= self.R.gens[other] ** 2
        powers: Dict[int, PolyElement] = {0: self.R.one}
        out: Dict[tuple, object] = {}
        result = self.R.zero
        for monom, coeff in p.terms():
            k = monom[idx]
            if k < 2:
                out[monom] = out.get(monom, 0) + coeff
                continue
            half = k // 2
            if half not in powers:
                powers[half] = rest**half
            base = list(monom)
            base[idx] = k % 2
            result += self.R.from_dict({tuple(base): coeff}) * powers[half]
        return result + self.R.from_dict({m: c for m, c in out.items() if c})

    def shortest(self, p: PolyElement, relations: Sequence[Relation]) -> PolyElement:
        """The reduction of ``p`` by ``relations`` with the fewest terms.

        Every relation whose generators appear is tried with each choice of generator
        to eliminate (ties keep the earlier choice, and the unreduced polynomial wins any tie; for
        angles the cosine is eliminated first, so among equally short results the sine form
        wins -- hence ``sin(alpha)**2 sin(psi)**2`` in ``M11``).
        """
        used = set()
        for monom in p.monoms():
            used.update(i for i, e in enumerate(monom) if e >= 2)
        active = [r for r in relations if used.intersection(r.gens)]
        best = p
        for choice in itertools.product(*(r.eliminable for r in active)):
            q = p
            for rel, which in zip(active, choice):
                q = self._eliminate(q, rel, which)
            if len(q) < len(best):
                best = q
        return best

    def to_expr(
        self,
        p: PolyElement,
        *,
        keys: Sequence[str] = (),
        subs: Mapping[sp.Symbol, sp.Expr] = {},
    ) -> sp.Expr:
        """A tidy SymPy expression: grouped by monomials in the generators ``keys`` (e.g. the
        speeds), common factors pulled out of each group, then ``subs`` applied."""
        key_idx = [self.index[k] for k in keys if k in self.index]
        groups: Dict[tuple, Dict[tuple, object]] = {}
        for monom, coeff in p.terms():
            key = tuple(monom[i] for i in key_idx)
            rest = list(monom)
            for i in key_idx:
                rest[i] = 0
            groups.setdefault(key, {})[tuple(rest)] = coeff
        total = sp.S.Zero
        for key, terms in groups.items():
            mono = sp.Mul(*(self.symbols[i] ** e for i, e in zip(key_idx, key)))
            coeff = floats_for_long_rationals(self.R.from_dict(terms).as_expr())
            if subs:
                coeff = sp.expand(coeff.xreplace(subs))
            total += sp.factor_terms(coeff) * mono
        return total
