"""Equations of motion by the specification's method: rotation tensors and Lagrange's equations.

The derivation follows the specification step by step:

1. ``P1 = P(phi, k)``; ``e = P1 . e0``; ``P = P1 . P(psi, e0)`` (Rodrigues' formula);
2. ``omega2 = phi' k + psi' e``; the rod vectors ``a = P1 . a j``, ``b = P . b j``;
   the second rod's centre-of-mass velocity ``v_c = omega1 x a + omega2 x (P . c2)``;
   its inertia tensor turned with the rod, ``Theta2 = P . Theta2_body . P^T``;
3. ``T = T1 + T2``, ``Pi = Pi1 + Pi2`` and Lagrange's equations
   ``d/dt dT/dq' - dT/dq = -dPi/dq + Q``.

Compactness comes from structure, not from one large ``simplify()``: ``T`` is built in
the first rod's frame (it does not depend on ``phi``); ``M(q)`` is the Hessian of ``T``
in the speeds; the velocity terms come from derivatives of ``M``
(Christoffel symbols); the gravity terms from ``Pi``; each entry is then reduced with
``cos^2 + sin^2 = 1`` in its shortest form (:meth:`skewpend.symbolic.kinematics.Algebra.shortest`).

The result is ``M(q) q'' = f(q, q')`` with ``f`` containing the generalised
non-potential forces ``Q_i = tau_i - c_i q_i' - cf_i atan(cfs q_i')`` (joint torques, viscous
damping and, optionally, smooth Coulomb friction).  Optionally ``T`` also holds the kinetic
energy of two geared motors' rotors (``Ir``, ``gr``), so their reflected inertia enters ``M``
through Lagrange's equations like every other inertia.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from functools import cached_property
from collections.abc import Mapping
from typing import Callable, Dict, List, Sequence, Tuple

import sympy as sp

from ..errors import EquilibriumError
from .kinematics import Algebra, Relation, floats_for_long_rationals
from ..schema import AXIS_NAMES, LENGTH_NAMES, MASS_NAMES
from .model import GEOMETRY_NAMES, SCALAR_NAMES, Parameters
from .symbols import SYMBOLS

__all__ = ["derive", "EquationsOfMotion", "LinearEquations", "SYMBOLS"]


_SPEEDS = ("dphi", "dpsi")


def coordinate_symbol(name: str) -> sp.Symbol:
    """The symbol of a coordinate, speed or acceleration: the double pendulum's ``phi, dpsi, ...``
    (:data:`SYMBOLS`) or a chain's ``q3, dq3, ddq3`` (real)."""
    return SYMBOLS[name] if name in SYMBOLS else sp.Symbol(name, real=True)


def _number(x: float) -> sp.Rational:
    """Exact rational for a user's float: short decimals as typed (0.8 -> 4/5), others exactly."""
    x = float(x)
    if x.is_integer():
        return sp.Integer(int(x))
    text = repr(x)
    if "e" not in text and len(text.replace("-", "").replace(".", "").lstrip("0")) <= 8:
        return sp.Rational(text)
    return sp.Rational(x)


def _angle_value(x: float) -> sp.Expr:
    """A numeric angle; a whole number of degrees is kept exact (``pi*n/180``) when its cosine
    and sine are algebraic numbers SymPy writes without trigonometric functions."""
    deg = math.degrees(x)
    if abs(deg - round(deg)) < 1e-9:
        exact = sp.pi * sp.Integer(round(deg)) / 180
        if not (sp.cos(exact).has(sp.cos) or sp.sin(exact).has(sp.sin)):
            return exact
    return sp.Float(x)


class LazySteps(Mapping):
    """The derivation's intermediate results (:attr:`EquationsOfMotion.steps`) as a read-only mapping whose
    values are reduced when first read, then kept; in the specification's order.  It pickles as the plain
    dict of every value."""

    def __init__(self, thunks: Dict[str, Callable[[], sp.Basic]]) -> None:
        self._thunks, self._values = dict(thunks), {}

    def __getitem__(self, key: str) -> sp.Basic:
        if key not in self._values:
            self._values[key] = self._thunks[key]()  # KeyError for an unknown key, as a dict's
        return self._values[key]

    def __iter__(self):
        return iter(self._thunks)

    def __len__(self) -> int:
        return len(self._thunks)

    def __reduce__(self):
        return (dict, (dict(self.items()),))

    def __repr__(self) -> str:
        return f"LazySteps({list(self._thunks)})"


@dataclass(frozen=True)
class LinearEquations:
    """Linearisation about the hanging equilibrium: ``M0 q'' + C0 q' + K0 q = 0``.

    ``M0`` (mass), ``C0`` (damping) and ``K0`` (stiffness) are 2x2 SymPy matrices in
    the coordinates ``q = (phi, psi)``; SI units.  ``coulomb`` says how the Coulomb friction
    entered ``C0`` (``"exclude"``: not at all, the default; ``"smoothed"``: its slope ``cfs cf``),
    :attr:`note` says it in one line ('' for a model without Coulomb friction).
    """

    M: sp.Matrix
    C: sp.Matrix
    K: sp.Matrix
    params: Parameters
    coulomb: str = "exclude"

    @property
    def note(self) -> str:
        """How the Coulomb friction was treated, one line ('' without Coulomb friction)."""
        from .friction import coulomb_note

        return coulomb_note(self.params, self.coulomb)

    def equations(self) -> Tuple[sp.Expr, ...]:
        """The left-hand sides ``(M0 q'' + C0 q' + K0 q)_i`` (each ``= 0``), one a coordinate."""
        names = getattr(self.params, "coordinates", ("phi", "psi"))
        q = sp.Matrix([coordinate_symbol(c) for c in names])
        dq = sp.Matrix([coordinate_symbol(f"d{c}") for c in names])
        ddq = sp.Matrix([coordinate_symbol(f"dd{c}") for c in names])
        lhs = self.M * ddq + self.C * dq + self.K * q
        return tuple(sp.expand(x) for x in lhs)


@dataclass(frozen=True)
class EquationsOfMotion:
    """The equations of motion ``M(q) q'' = f(q, q')`` of a skewed double pendulum.

    Attributes (SymPy, in the symbols of :data:`SYMBOLS`):

    * ``mass_matrix`` -- 2x2 ``M(q)`` [kg m^2];
    * ``forcing`` -- 2x1 ``f(q, q')`` [N m], velocity, gravity, damping and torque terms;
    * ``kinetic_energy`` ``T`` and ``potential_energy`` ``Pi`` [J] (``Pi = 0`` with both
      rods hanging vertically, ``phi = psi = 0``); ``T`` includes the rotors' when ``Ir != 0``;
    * ``generalized_forces`` -- 2x1 ``Q(q')`` [N m], the non-potential forces
      ``tau_i - c_i q_i' - cf_i atan(cfs q_i')`` (their power ``Q . q'`` is the energy account's
      ``W'``);
    * ``params`` -- the :class:`~skewpend.Parameters` it was derived for.

    :attr:`steps` holds the specification's intermediate results; :meth:`linearize`
    the small-angle equations.
    """

    params: Parameters
    mass_matrix: sp.Matrix
    forcing: sp.Matrix
    kinetic_energy: sp.Expr
    potential_energy: sp.Expr
    generalized_forces: sp.Matrix
    _ctx: "_Context" = field(repr=False, compare=False)

    # -- names ---------------------------------------------------------------------
    @property
    def coordinates(self) -> Tuple[str, ...]:
        """The coordinates' names: ``phi, psi`` for the double pendulum, ``q1`` to ``qn`` for a chain."""
        return self._ctx.coords

    @property
    def speeds(self) -> Tuple[str, ...]:
        return tuple(f"d{c}" for c in self._ctx.coords)

    @property
    def parameter_names(self) -> Tuple[str, ...]:
        """Names of the parameters left symbolic."""
        return getattr(self.params, "symbolic_names", ())

    @property
    def q(self) -> sp.Matrix:
        return sp.Matrix([coordinate_symbol(c) for c in self.coordinates])

    @property
    def dq(self) -> sp.Matrix:
        return sp.Matrix([coordinate_symbol(f"d{c}") for c in self.coordinates])

    @property
    def ddq(self) -> sp.Matrix:
        return sp.Matrix([coordinate_symbol(f"dd{c}") for c in self.coordinates])

    def equations(self) -> Tuple[sp.Eq, ...]:
        """The equations ``(M q'')_i = f_i`` as SymPy ``Eq`` objects, one a coordinate."""
        lhs = self.mass_matrix * self.ddq
        return tuple(sp.Eq(lhs[i], self.forcing[i]) for i in range(len(self.coordinates)))

    @cached_property
    def steps(self) -> Mapping:
        """The specification's intermediate results, in its order (world frame ``i, j, k``).

        Keys: ``P1``, ``e``, ``P``, ``omega2``, ``v_c``, ``Theta2``, ``T``, ``Pi``, and the
        equations ``M``, ``f``.
        """
        return self._ctx.steps(self)

    def linearize(self, coulomb: str = "exclude") -> LinearEquations:
        """Linearise about ``phi = psi = 0`` (both rods hanging): ``M0 q'' + C0 q' + K0 q = 0``.

        Coulomb friction ``cf atan(cfs q')`` is non-smooth at rest (it smooths ``cf sign(q')``),
        so by default it is left out of ``C0`` (``coulomb="exclude"``); ``coulomb="smoothed"``
        adds its smoothed slope ``cf cfs`` as viscous damping.  The result's ``note`` says which.

        Raises :class:`~skewpend.errors.EquilibriumError` if ``q = 0`` is not an
        equilibrium (e.g. constant torques, or centres of mass off the vertical).
        """
        from .friction import check_coulomb

        return self._ctx.linearize(self, check_coulomb(coulomb))

    def _repr_latex_(self) -> str:
        from .render import to_latex

        return "$\\displaystyle " + to_latex(self, display=True) + "$"

    def __str__(self) -> str:
        from .render import to_text

        return to_text(self)


class _Context:
    """The derivation, in the polynomial algebra of :mod:`skewpend.kinematics`.

    Generators: the symbolic scalar parameters; ``c_x, s_x`` (cosine, sine) for the
    angles ``phi, psi`` and, with the default second axis, ``alpha``; ``1/|v|`` for a
    hinge axis ``v`` given by the user; the speeds.  Numeric values of ``alpha`` and of
    ``1/|v|`` are substituted only after reduction (:meth:`finish`).
    """

    def __init__(self, params):
        if params.exact_model() is params:  # the specification's parameters, symbols kept
            self._from_parameters(params)
        else:  # a chain of numeric links
            self._from_chain(params)
        self.n = len(self.coords)

    def _exact_axis(self, components, name: str, gens: List[sp.Symbol], fixed: list):
        """A numeric hinge axis as the exact rationals ``v`` of its (normalised) floats, and, when
        ``|v|`` is 1 only to rounding, the generator ``r = 1/|v|`` (named ``{name}_r``; appended to
        ``gens``, its relation ``r**2 = 1/|v|**2`` to ``fixed``, its value substituted after reduction),
        so the Rodrigues products stay exact.  Returns ``(v, r's name or None)``."""
        v = [_number(x) for x in components]
        norm2 = sum(x * x for x in v)
        if norm2 == 1:
            return v, None
        r = sp.Symbol(f"{name}_r", positive=True)
        gens.append(r)
        fixed.append((r.name, 1 / norm2))
        self.late_expr[r] = sp.Float(1 / math.sqrt(float(norm2)))
        return v, r.name

    def _from_chain(self, chain) -> None:
        """A chain of numeric links: every value exact (short decimals as typed), each coordinate's
        cosine and sine a generator, ``1/|e|`` a generator for an axis whose rational components are
        not of length 1 (the double pendulum's rule)."""
        self.params = chain
        self.coords = chain.coordinates
        gens: List[sp.Symbol] = []
        unit_pairs = []
        self.late_exact, self.late_expr, self.restore = {}, {}, {}
        for name in self.coords:
            c, s = sp.Symbol(f"c_{name}", real=True), sp.Symbol(f"s_{name}", real=True)
            gens += [c, s]
            unit_pairs.append((c.name, s.name))
            sym = coordinate_symbol(name)
            self.restore.update({c: sp.cos(sym), s: sp.sin(sym)})
        fixed = []
        axes = []
        for link in chain.links:
            v, r = self._exact_axis(link.axis, f"e{link.index}", gens, fixed)
            axes.append((v, r))
        gens += [coordinate_symbol(f"d{c}") for c in self.coords]
        self.friction = chain.has_friction
        if self.friction:
            for c in self.coords:
                placeholder = sp.Symbol(f"atan_d{c}", real=True)
                gens.append(placeholder)
                self.restore[placeholder] = sp.atan(_number(chain.cfs) * coordinate_symbol(f"d{c}"))
        self.alg = alg = Algebra(gens)
        self.relations = [Relation(tuple(alg.index[n] for n in pair)) for pair in unit_pairs]
        self.relations += [Relation((alg.index[n],), 1 - v) for n, v in fixed]
        G = alg.gens
        num = lambda x: alg.const(_number(x))  # noqa: E731
        self.val = {"g": num(chain.g)}
        self.cs = {c: (G[f"c_{c}"], G[f"s_{c}"]) for c in self.coords}
        self.J = alg.vec([0, 1, 0])
        self.links = []
        for link, (v, r) in zip(chain.links, axes):
            axis = alg.vec(v)
            if r is not None:
                axis = alg.scale(G[r], axis)
            self.links.append(dict(axis=axis, offset=[num(x) for x in link.offset], com=[num(x) for x in link.com],
                                   inertia=[[num(x) for x in row] for row in link.inertia], m=num(link.mass),
                                   c=num(link.damping), tau=num(link.torque), cf=num(link.coulomb), Ir=num(link.rotor),
                                   gr=num(link.gear)))
        self.P1 = alg.rotation(*self.cs[self.coords[0]], self.links[0]["axis"])

    def _from_parameters(self, params: Parameters) -> None:
        self.params = params
        self.coords = ("phi", "psi")
        S = SYMBOLS
        gens: List[sp.Symbol] = []
        self.relations: List[Relation] = []
        const: Dict[str, sp.Rational] = {}
        for name in SCALAR_NAMES:
            x = getattr(params, name)
            if name == "alpha":
                continue
            if x is None:
                gens.append(S[name])
            else:
                const[name] = _number(x)
        unit_pairs: List[Tuple[str, ...]] = []
        # values substituted after reduction: exact (ring) and non-rational (expression)
        self.late_exact: Dict[str, sp.Rational] = {}
        self.late_expr: Dict[sp.Symbol, sp.Expr] = {}
        self.restore: Dict[sp.Symbol, sp.Expr] = {}
        for ang in ("phi", "psi") + (("alpha",) if params.uses_alpha else ()):
            c, s = sp.Symbol(f"c_{ang}", real=True), sp.Symbol(f"s_{ang}", real=True)
            gens += [c, s]
            unit_pairs.append((c.name, s.name))
            if ang == "alpha" and params.alpha is not None:
                theta = _angle_value(params.alpha)
                for sym, val in ((c, sp.cos(theta)), (s, sp.sin(theta))):
                    if val.is_Rational:
                        self.late_exact[sym.name] = val
                    else:
                        self.late_expr[sym] = val
            else:
                self.restore.update({c: sp.cos(S[ang]), s: sp.sin(S[ang])})
        # A user's axis n = r v: v holds the exact rationals of the given (normalised)
        # floats and r = 1/|v| is a generator reduced by r**2 = 1/|v|**2, so the
        # Rodrigues products stay exact although |v| is 1 only to rounding.
        axis_dirs: Dict[str, List[sp.Rational]] = {}
        fixed_names: List[Tuple[str, sp.Rational]] = []
        # symbol names used in the bodies and axes (a scalar parameter's name means that parameter)
        geometry_symbols: List[str] = []
        for name in GEOMETRY_NAMES:
            value = getattr(params, name)
            if value is None:
                continue
            for x in (e for row in value for e in (row if isinstance(row, tuple) else (row,))):
                if isinstance(x, str) and x not in SCALAR_NAMES and x not in geometry_symbols:
                    geometry_symbols.append(x)
        gens += [sp.Symbol(n, real=True) for n in geometry_symbols]
        symbolic_axes: List[Tuple[str, Tuple[str, ...], sp.Rational]] = []
        for name in AXIS_NAMES:
            vec = getattr(params, name)
            if vec is None:
                continue
            if any(isinstance(x, str) for x in vec):  # a symbolic unit axis: sum of squares = 1
                names = tuple(x for x in vec if isinstance(x, str))
                offset = sum((_number(x) ** 2 for x in vec if not isinstance(x, str)), sp.Integer(0))
                symbolic_axes.append((name, names, offset))
                continue
            axis_dirs[name], _ = self._exact_axis(vec, name, gens, fixed_names)
        gens += [S["dphi"], S["dpsi"]]
        # Coulomb friction: atan(cfs q_i') stands in the ring as a generator of its own, restored
        # to the function by finish() (only when the friction enters: today's ring otherwise).
        self.friction = params.has_friction
        if self.friction:
            rate = S["cfs"] if params.cfs is None else _number(params.cfs)
            for ang in ("phi", "psi"):
                placeholder = sp.Symbol(f"atan_d{ang}", real=True)
                gens.append(placeholder)
                self.restore[placeholder] = sp.atan(rate * S[f"d{ang}"])
        self.alg = alg = Algebra(gens)
        self.relations = [Relation(tuple(alg.index[n] for n in pair)) for pair in unit_pairs]
        for _, names, offset in symbolic_axes:
            choices = () if len(names) <= 2 else (len(names) - 1,)
            self.relations.append(Relation(tuple(alg.index[n] for n in names), offset, choices))
        self.relations += [Relation((alg.index[n],), 1 - v) for n, v in fixed_names]
        G = alg.gens

        def entry(x):
            if isinstance(x, str):
                return self.val[x] if x in self.val else G[x]
            return alg.const(_number(x))

        self.entry = entry

        def axis(name):
            if name not in axis_dirs:  # symbolic components
                return [entry(x) for x in getattr(params, name)]
            v = alg.vec(axis_dirs[name])
            return alg.scale(G[f"{name}_r"], v) if f"{name}_r" in G else v

        self.val = {n: (G[n] if n in G else alg.const(const[n])) for n in SCALAR_NAMES if n != "alpha"}
        self.cs = {ang: (G[f"c_{ang}"], G[f"s_{ang}"]) for ang in ("phi", "psi", "alpha") if f"c_{ang}" in G}

        a, b, m1, m2 = (self.val[n] for n in LENGTH_NAMES + MASS_NAMES)
        I_, J_, K_ = alg.vec([1, 0, 0]), alg.vec([0, 1, 0]), alg.vec([0, 0, 1])
        self.J = J_
        self.n1 = K_ if params.axis1 is None else axis("axis1")
        if params.axis2 is None:
            ca, sa = self.cs["alpha"]
            self.e0 = alg.add(alg.scale(ca, K_), alg.scale(sa, I_))  # cos(alpha) k + sin(alpha) i
        else:
            self.e0 = axis("axis2")
        self.h = alg.scale(a, J_)  # the second hinge, at the end of rod 1
        self.c1 = alg.scale(a / 2, J_) if params.com1 is None else [entry(x) for x in params.com1]
        self.c2 = alg.scale(b / 2, J_) if params.com2 is None else [entry(x) for x in params.com2]

        def inertia(given, m, length):
            if given is None:  # thin rod along j: m l^2/12 (E - j j)
                k = m * length**2 / 12
                return [[k, 0 * k, 0 * k], [0 * k, 0 * k, 0 * k], [0 * k, 0 * k, k]]
            return [[entry(x) for x in row] for row in given]

        self.I1 = inertia(params.inertia1, m1, a)
        self.I2 = inertia(params.inertia2, m2, b)
        self.P1 = alg.rotation(*self.cs["phi"], self.n1)  # P1 = P(phi, n1)
        self.R2 = alg.rotation(*self.cs["psi"], self.e0)  # P(psi, e0)
        # the chain of two: rod 1 on the roof hinge, rod 2 on the hinge at a j
        v = self.val
        zero = alg.scale(0 * a, J_)
        joint = lambda i: {n: v[f"{n}{i}"] for n in ("c", "tau", "cf")}  # noqa: E731
        self.links = [dict(axis=self.n1, offset=zero, com=self.c1, inertia=self.I1, m=m1, Ir=v["Ir"], gr=v["gr"], **joint(1)),
                      dict(axis=self.e0, offset=self.h, com=self.c2, inertia=self.I2, m=m2, Ir=v["Ir"], gr=v["gr"], **joint(2))]

    # -- reduction and output ------------------------------------------------------------------
    def finish(self, p, keys: Sequence[str] = ()) -> sp.Expr:
        """Reduce ``p`` to its shortest form, substitute late values, return a tidy expression."""
        alg = self.alg
        p = alg.shortest(p, self.relations)
        if self.late_exact:
            p = p.subs([(alg.gens[n], v) for n, v in self.late_exact.items()])
            p = alg.shortest(p, self.relations)
        expr = alg.to_expr(p, keys=keys, subs=self.late_expr)
        return floats_for_long_rationals(expr.xreplace(self.restore))

    def finish_matrix(self, m, keys: Sequence[str] = ()) -> sp.Matrix:
        if isinstance(m[0], list):
            return sp.Matrix([[self.finish(x, keys) for x in row] for row in m])
        return sp.Matrix([self.finish(x, keys) for x in m])

    def d_dq(self, p, i: int):
        ang = self.coords[i]
        return self.alg.d_dangle(p, f"c_{ang}", f"s_{ang}")

    @property
    def has_rotor(self) -> bool:
        return bool(self.params.has_rotor)

    # -- the derivation ----------------------------------------------------------------
    def kinematics(self):
        """Each link's hinge ``o_k``, axis ``a_k``, rotation ``R_k`` and centre of mass, in the frame of
        link 1 (the specification's ``P = P1 . P(psi, e0)`` with ``P1`` taken out: ``T`` does not depend on
        the first angle), composed link by link ``R_k = R_{k-1} P(q_k, e_k)``."""
        alg = self.alg
        R, o, a, com = [], [], [], []
        for k, link in enumerate(self.links):
            if k == 0:
                o.append(alg.scale(0 * link["m"], self.J))
                a.append(link["axis"])
                R.append(None)  # E: the frame of link 1
                com.append(link["com"])
                continue
            prev = R[k - 1]
            o.append(alg.add(o[k - 1], link["offset"] if prev is None else alg.matvec(prev, link["offset"])))
            a.append(link["axis"] if prev is None else alg.matvec(prev, link["axis"]))
            P = alg.rotation(*self.cs[self.coords[k]], link["axis"])
            R.append(P if prev is None else alg.matmul(prev, P))
            com.append(alg.add(o[k], alg.matvec(R[k], link["com"])))
        return R, o, a, com

    def derive(self) -> EquationsOfMotion:
        alg, v, n = self.alg, self.val, self.n
        speeds = [alg.gens[f"d{c}"] for c in self.coords]
        R, o, a, com = self.kinematics()

        # Kinetic energy, in the frame of link 1 (T is invariant; there it does not depend on q1):
        #   omega_k = sum_{j <= k} q_j' a_j,  v_ck = sum_{j <= k} q_j' a_j x (c_k - o_j)
        T = alg.R.zero
        omega = None
        for k, link in enumerate(self.links):
            term = alg.scale(speeds[k], a[k])
            omega = term if omega is None else alg.add(omega, term)
            v_c = None
            for j in range(k + 1):
                arm = com[k] if j == 0 else alg.add(com[k], alg.scale(-1, o[j]))
                if j == k and k > 0:  # the link's own centre of mass about its hinge: R_k c_k
                    arm = alg.matvec(R[k], link["com"])
                t = alg.scale(speeds[j], alg.cross(a[j], arm))
                v_c = t if v_c is None else alg.add(v_c, t)
            body = omega if R[k] is None else alg.matvec(alg.transpose(R[k]), omega)
            if k == 0:
                T = T + link["m"] * alg.dot(v_c, v_c) + speeds[0] ** 2 * alg.dot(a[0], alg.matvec(link["inertia"], a[0]))
            else:
                T = T + link["m"] * alg.dot(v_c, v_c) + alg.dot(body, alg.matvec(link["inertia"], body))
        T = T / 2
        # Geared motors (optional, Ir = 0 by default): the rotor of hinge k, carried by link k - 1 (the
        # roof for k = 1), spins about the hinge's axis at (omega_{k-1} . a_k) + gr q_k' (its transverse
        # inertia belongs to its carrier's).
        if self.has_rotor:
            rot = alg.R.zero
            omega_prev = None
            for k, link in enumerate(self.links):
                spin = link["gr"] * speeds[k] + (0 if omega_prev is None else alg.dot(omega_prev, a[k]))
                rot = rot + link["Ir"] * spin**2
                term = alg.scale(speeds[k], a[k])
                omega_prev = term if omega_prev is None else alg.add(omega_prev, term)
            T = T + rot / 2

        # Potential energy: Pi = -g sum m j . r_c, zero with the chain hanging (every q = 0).
        #   j . (P1 x) = (P1^T j) . x
        down = alg.matvec(alg.transpose(self.P1), self.J)
        Pi = alg.R.zero
        for k, link in enumerate(self.links):
            Pi = Pi + link["m"] * alg.dot(down, com[k])
        Pi = -v["g"] * Pi
        Pi = Pi - Pi.subs(self._zero())

        # Mass matrix: Hessian of T in the speeds.
        M = [[T.diff(speeds[i]).diff(speeds[j]) for j in range(n)] for i in range(n)]

        # Lagrange: M q'' = -sum_jk (dM_ij/dq_k - 1/2 dM_jk/dq_i) q'_j q'_k - dPi/dq_i + Q_i,
        # Q_i = tau_i - c_i q'_i - cf_i atan(cfs q'_i).
        dM = [[[self.d_dq(M[i][j], k) for k in range(n)] for j in range(n)] for i in range(n)]
        forcing, forces = [], []
        for i in range(n):
            vel = alg.R.zero
            for j in range(n):
                for k in range(n):
                    vel += (dM[i][j][k] - dM[j][k][i] / 2) * speeds[j] * speeds[k]
            link = self.links[i]
            Q = link["tau"] - link["c"] * speeds[i]
            if self.friction:
                Q = Q - link["cf"] * alg.gens[f"atan_d{self.coords[i]}"]
            forces.append(Q)
            forcing.append(-vel - self.d_dq(Pi, i) + Q)

        self.T, self.Pi, self.M, self.f, self.Q = T, Pi, M, forcing, forces
        keys = [f"d{c}" for c in self.coords]
        return EquationsOfMotion(
            params=self.params,
            mass_matrix=self.finish_matrix(M),
            forcing=self.finish_matrix(forcing, keys=keys),
            kinetic_energy=self.finish(T, keys=keys),
            potential_energy=self.finish(Pi, keys=[m for m in MASS_NAMES if m in alg.gens]),
            generalized_forces=self.finish_matrix(forces, keys=keys),
            _ctx=self,
        )

    def _zero(self):
        G = self.alg.gens
        return [x for c in self.coords for x in ((G[f"c_{c}"], 1), (G[f"s_{c}"], 0))]

    # -- intermediate results, world frame -------------------------------------------------------
    def steps(self, eom: EquationsOfMotion) -> Mapping:
        if not hasattr(self, "R2"):
            return self.chain_steps(eom)
        alg = self.alg
        dphi, dpsi = alg.gens["dphi"], alg.gens["dpsi"]
        P1 = self.P1
        e = alg.matvec(P1, self.e0)
        P = alg.matmul(P1, self.R2)
        omega1 = alg.scale(dphi, self.n1)
        omega2 = alg.add(omega1, alg.scale(dpsi, e))
        fin = self.finish_matrix

        def v_c():
            a_vec = alg.matvec(P1, self.h)
            c2_world = alg.matvec(P, self.c2)
            return fin(alg.add(alg.cross(omega1, a_vec), alg.cross(omega2, c2_world)), keys=_SPEEDS)

        # each step reduced when first read: the generated code reads P1, P, e and omega2 (rod ends,
        # axes); v_c and Theta2 (a general body's P I2 P^T: half a minute of reduction) only the report
        return LazySteps({
            "P1": lambda: fin(P1),
            "e": lambda: fin(e),
            "P": lambda: fin(P),
            "omega2": lambda: fin(omega2, keys=_SPEEDS),
            "v_c": v_c,
            "Theta2": lambda: fin(alg.matmul(alg.matmul(P, self.I2), alg.transpose(P))),
            "T": lambda: eom.kinetic_energy,
            "Pi": lambda: eom.potential_energy,
            "M": lambda: eom.mass_matrix,
            "f": lambda: eom.forcing,
        })

    def chain_steps(self, eom: EquationsOfMotion) -> Dict[str, sp.Basic]:
        """A chain's intermediate results in the world frame: per link ``k`` its rotation tensor ``P{k}``
        (``P_k = P_{k-1} P(q_k, e_k)``), its hinge's current axis ``e{k}`` and angular velocity
        ``omega{k}``; then ``T``, ``Pi``, ``M``, ``f``."""
        alg = self.alg
        R, o, a, com = self.kinematics()
        keys = [f"d{c}" for c in self.coords]
        out: Dict[str, sp.Basic] = {}
        omega = None
        for k in range(self.n):
            P = self.P1 if R[k] is None else alg.matmul(self.P1, R[k])
            axis = alg.matvec(self.P1, a[k])
            term = alg.scale(alg.gens[keys[k]], axis)
            omega = term if omega is None else alg.add(omega, term)
            out[f"P{k + 1}"] = self.finish_matrix(P)
            out[f"e{k + 1}"] = self.finish_matrix(axis)
            out[f"omega{k + 1}"] = self.finish_matrix(omega, keys=keys)
        out.update(T=eom.kinetic_energy, Pi=eom.potential_energy, M=eom.mass_matrix, f=eom.forcing)
        return out

    # -- linearisation -----------------------------------------------------------------------------
    def linearize(self, eom: EquationsOfMotion, coulomb: str = "exclude") -> LinearEquations:
        zero = self._zero()
        n = self.n
        grad = [self.d_dq(self.Pi, i) for i in range(n)]
        static = [self.finish(self.links[i]["tau"] - grad[i].subs(zero)) for i in range(n)]
        if any(sp.simplify(x) != 0 for x in static):
            torques = any(sp.simplify(self.finish(self.links[i]["tau"])) != 0 for i in range(n))
            why = ("constant joint torques hold it elsewhere" if torques else
                   "its centres of mass do not hang straight below their hinges there")
            where = "phi = psi = 0" if self.coords == ("phi", "psi") else "q = 0"
            raise EquilibriumError(
                f"{where} is not an equilibrium of this model ({why}); linearise about its "
                "hanging rest instead: about='down-down' (--about down-down)"
            )
        M0 = sp.Matrix(n, n, lambda i, j: self.finish(self.M[i][j].subs(zero)))
        K0 = sp.Matrix(n, n, lambda i, j: self.finish(self.d_dq(grad[i], j).subs(zero)))
        # damping: -dQ/dq' at rest.  Coulomb friction cf_i sign(q_i') has no slope there; its smoothed
        # form cf_i atan(cfs q_i') has slope cf_i cfs, a viscous damping only with coulomb="smoothed"
        # (symbolic/friction.py says why the default leaves it out).
        smoothed = self.friction and coulomb == "smoothed"
        rate = self.val["cfs"] if "cfs" in self.val else self.alg.const(_number(self.params.cfs))
        friction = (lambda i: self.links[i]["cf"] * rate) if smoothed else (lambda i: 0)
        C0 = sp.Matrix(n, n, lambda i, j: self.finish(self.links[i]["c"] + friction(i)) if i == j else sp.S.Zero)
        return LinearEquations(M=M0, C=C0, K=K0, params=self.params, coulomb=coulomb)


def derive(params=None) -> EquationsOfMotion:
    """Derive the equations of motion ``M(q) q'' = f(q, q')`` for ``params``: the double pendulum's
    :class:`Parameters` or a chain of links (:class:`skewpend.symbolic.chain.Chain`, numeric; exact while
    its size allows -- three links take seconds, each further link about ten times longer: the recursive
    algorithms of :mod:`skewpend.numeric.recursive` compute larger chains, checked against this).

    ``params`` defaults to ``Parameters()``: the specification's thin rods with every
    parameter symbolic (``a, b, m1, m2, alpha, g``) and no damping or torques.

    In the planar case the coupling of the mass matrix is the specification's
    ``m2 b (a cos(psi)/2 + b/3)``:

    >>> import skewpend
    >>> eom = skewpend.derive(skewpend.Parameters(alpha=0))
    >>> eom.mass_matrix[0, 1]
    b*m2*(3*a*cos(psi) + 2*b)/6
    """
    if params is None:
        params = Parameters()
    return _Context(params).derive()
