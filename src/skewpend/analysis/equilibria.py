"""Every equilibrium of a model on the n-torus, and the linearisation about each.

At rest the equations of motion ``M(q) q'' = f(q, q')`` reduce to ``dPi/dq = tau``: an equilibrium
is a critical point of ``V(q) = Pi(q) - tau . q``, the potential energy with the work of the
constant torques.  The model is any of skewpend's (the double pendulum's
:class:`~skewpend.Parameters`, a :class:`~skewpend.Chain` of ``n`` links): the search asks it for its
coordinates and its chain, never its type.  :func:`equilibria` finds them all:

* Newton's method on ``grad V = 0`` (one vectorised iteration for every start) from the ``2^n``
  configurations with every relative angle 0 or pi and a grid of about ``starts^2`` points over the
  n-torus (``starts^(2/n)`` per side: the double pendulum's ``starts x starts`` grid);
* the roots deduplicated on the torus (angles modulo 2 pi) and polished;
* a check that none is missed: on the n-torus the Morse indices of nondegenerate critical points
  satisfy ``sum (-1)^index = 0`` (Poincare-Hopf: its Euler characteristic); if the sum is not 0 the
  grid is refined, and a result that still fails the check says so (:attr:`~skewpend.Status.PARTIAL`).

``V``'s gradient and Hessian come from the cheapest printer of the model (a strategy, not its type):
the exact derivation (SymPy ``lambdify``, in NumPy over every start) where the model keeps its bodies'
geometry apart from its scalars -- one derivation, cached on disk, serves every value -- else the
recursive algorithms' graph (CasADi, mapped over the starts: a chain's values are numeric data, so an
exact derivation would be made again for each).

Each :class:`Equilibrium` carries its linearisation ``M q'' + C q' + K q = 0`` (``M = M(q*)``,
``K`` the Hessian of ``V``, ``C`` the damping), the eigenvalues of the state matrix, the Morse
index (the number of negative eigenvalues of ``K``: 0 for a minimum of ``V``, a stable
equilibrium), the natural frequencies of its oscillating directions and the growth rates of its
unstable ones, with their directions.  Coulomb friction is left out of ``C`` by default, as
non-smooth at rest (``coulomb="exclude"``, said in the result's message; see
:mod:`skewpend.symbolic.friction`); ``coulomb="smoothed"`` adds its smoothed slope ``cfs cf``.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from functools import cached_property, lru_cache
from typing import Callable, ClassVar, List, Sequence, Tuple

import numpy as np

from ..errors import EquilibriumError, NotNumericError, ParameterError
from ..results import DatasetSpec, Result, agree, netcdf_reader, protocol_fields
from ..schema import GEOMETRY_NAMES, coordinate_names
from ..status import Status
from ..symbolic.friction import DEFAULT_COULOMB, check_coulomb, coulomb_note, friction_terms
from ..symbolic.model import SCALAR_NAMES, Parameters

__all__ = ["Equilibrium", "Equilibria", "equilibria", "linear_point", "equilibrium_at", "find_equilibrium",
           "linearisation_functions", "potential_function", "potential_on_arrays"]

#: Newton starts per side of the double pendulum's grid, ``starts^2`` points on any torus (refined up to
#: :data:`MAX_STARTS` while the index check fails).
DEFAULT_STARTS = 16
MAX_STARTS = 128
#: The most links whose 2^n configurations with every relative angle 0 or pi seed the search.
MAX_SEEDED_LINKS = 12
#: Two roots closer than this on the torus [rad] are one equilibrium.
SAME_ROOT = 1e-6
#: How far [rad] a point given as "near an equilibrium" may lie from it.
NEAR = 0.2
#: An eigenvalue of K below this fraction of the largest is taken as zero (a degenerate point).
DEGENERATE = 1e-9
#: A root's residual ``|grad Pi - tau|`` must be below this fraction of the gradient's scale.
RESIDUAL = 1e-9


# -- the model's potential: two printers, one contract -----------------------------------------------------
def _geometry_only(params: Parameters) -> Parameters:
    """``params`` with every scalar symbolic (the bodies and axes kept): one derivation serves
    every ``a, b, m1, m2, alpha, g, c, tau``."""
    return Parameters(**{k: getattr(params, k) for k in GEOMETRY_NAMES}, **{k: None for k in SCALAR_NAMES})


@lru_cache(maxsize=32)
def linearisation_functions(geometry: Parameters) -> Callable:
    """``f(*scalars, *q) -> (Pi, grad Pi, Hessian of Pi, M, C)`` generated (SymPy ``lambdify``) from the
    derivation of ``geometry`` (scalars in :data:`SCALAR_NAMES` order, then its coordinates;
    ``C = -df/dq'`` at rest, the damping)."""
    from ..numeric.pyfunctions import cached_lambdify

    def build():
        import sympy as sp

        from ..symbolic.derivation import SYMBOLS, coordinate_symbol, derive

        eom = derive(geometry)
        q = [coordinate_symbol(c) for c in geometry.coordinates]
        dq = [coordinate_symbol("d" + c) for c in geometry.coordinates]
        Pi = eom.potential_energy
        grad = [sp.diff(Pi, x) for x in q]
        hess = [[sp.diff(g, x) for x in q] for g in grad]
        rest = {v: 0 for v in dq}
        C = [[-sp.diff(eom.forcing[i], v).subs(rest) for v in dq] for i in range(len(q))]
        return [SYMBOLS[n] for n in SCALAR_NAMES] + q, [Pi, grad, hess, eom.mass_matrix.tolist(), C]

    return cached_lambdify("linearisation", "analysis/equilibria.py", geometry, build)


@lru_cache(maxsize=32)
def _direction_functions(geometry: Parameters) -> Callable:
    """``f(*scalars, *q) -> (j^T P1, j^T P)``: the rows ``j`` of each rod's rotation (``j`` points down), so that
    ``j . (P r)`` is how far below its hinge a point ``r`` of the rod's body is (:func:`link_directions`)."""
    from ..numeric.pyfunctions import cached_lambdify

    def build():
        from ..symbolic.derivation import SYMBOLS, coordinate_symbol, derive

        steps = derive(geometry).steps
        return ([SYMBOLS[n] for n in SCALAR_NAMES] + [coordinate_symbol(c) for c in geometry.coordinates],
                [list(steps["P1"][1, :]), list(steps["P"][1, :])])

    return cached_lambdify("directions", "analysis/equilibria.py", geometry, build)


def _scalars(params: Parameters) -> List[float]:
    return [0.0 if (n == "alpha" and not params.uses_alpha) else float(getattr(params, n)) for n in SCALAR_NAMES]


def _columns(values, m: int) -> np.ndarray:
    """A generated function's outputs (numbers where an entry is constant) as an ``(m, ...)`` array."""
    return np.moveaxis(np.array([[np.broadcast_to(np.asarray(x, dtype=float), (m,)) for x in row] for row in values]),
                       -1, 0)


class _Exact:
    """``V``'s derivatives printed by SymPy from the model's exact derivation, its scalars run-time values:
    NumPy evaluates every start at once."""

    def __init__(self, model, geometry: Parameters, chain):
        self.values = _scalars(model)
        self.functions = linearisation_functions(geometry)
        self.geometry = geometry
        self.chain = chain

    def grad_hess(self, Q: np.ndarray) -> Tuple[np.ndarray, np.ndarray]:
        _, g, H, _, _ = self.functions(*self.values, *Q.T)
        return _columns([g], len(Q))[:, 0], _columns(H, len(Q))

    def potential(self, Q: np.ndarray) -> np.ndarray:
        return np.broadcast_to(np.asarray(self.functions(*self.values, *Q.T)[0], dtype=float), (len(Q),))

    def at(self, q: np.ndarray):
        """``(Pi, Hessian of Pi, M, each link's direction with gravity)`` at one point (:func:`link_directions`)."""
        Pi, _, H, M, _ = self.functions(*self.values, *q)
        rows = np.array(_direction_functions(self.geometry)(*self.values, *q), dtype=float)  # j^T R_i
        coms = np.array([link.com for link in self.chain.links], dtype=float)
        lengths = np.array([link.length for link in self.chain.links], dtype=float)
        down = _unit_directions(self.chain, np.einsum("ij,ij->i", rows, coms), rows[:, 1] * lengths)
        return float(Pi), np.array(H, dtype=float), np.array(M, dtype=float), down


@lru_cache(maxsize=16)
def _newton_function(structure):
    """``(q, p) -> (Pi, grad Pi, Hessian of Pi)`` of the recursive algorithms: their energy at rest (CasADi),
    differentiated by CasADi."""
    import casadi as ca

    from ..numeric.recursive import chain_functions

    energy = chain_functions(structure)["energy"]
    n = structure.n
    q, p = ca.SX.sym("q", n), ca.SX.sym("p", energy.size1_in(1))
    Pi = energy(ca.vertcat(q, ca.SX.zeros(n)), p)
    grad = ca.gradient(Pi, q)
    return ca.Function("newton", [q, p], [Pi, grad, ca.jacobian(grad, q)])


@lru_cache(maxsize=64)
def _mapped(structure, m: int):
    """:func:`_newton_function` mapped over ``m`` points (columns)."""
    return _newton_function(structure).map(m)


class _Recursive:
    """``V``'s derivatives from the recursive algorithms' graph (CasADi, exact by automatic differentiation, no
    compiling), mapped over the starts: any chain."""

    def __init__(self, chain):
        from ..numeric.recursive import parameter_vector, potential_terms, structure_of_chain

        self.chain = chain
        self.structure = structure_of_chain(chain)
        self.terms = potential_terms(chain)
        self.p = parameter_vector(chain)

    def grad_hess(self, Q: np.ndarray) -> Tuple[np.ndarray, np.ndarray]:
        m, n = Q.shape
        _, g, H = _mapped(self.structure, m)(Q.T, self.p)
        return np.array(g, dtype=float).T, np.array(H, dtype=float).reshape(n, m, n).transpose(1, 0, 2)

    def potential(self, Q: np.ndarray) -> np.ndarray:
        return np.array(_mapped(self.structure, len(Q))(Q.T, self.p)[0], dtype=float).ravel()

    def at(self, q: np.ndarray):
        Pi, _, H, M, _ = self.terms(q)
        return Pi, H, M, link_directions(self.chain, q)


@lru_cache(maxsize=16)
def _heights_function(structure):
    """``(q, p) -> (c, r)``: how far below its hinge [m] (``j`` points down) each link's centre of mass is
    (``c``) and its rod's end (``r``: ``l_i R_i j``), from the recursive algorithms' graph -- a link's centre
    of mass from its own potential energy (the chain's ``Pi`` with that link's mass alone, 1 kg, and g = 1:
    ``-(j c_i - j c_i(hanging))``), its hinge from ``hinges``, its rod's end from ``ends``."""
    import casadi as ca

    from ..numeric.recursive import chain_functions, parameter_names

    fns, n = chain_functions(structure), structure.n
    names = parameter_names(n)
    q, p = ca.SX.sym("q", n), ca.SX.sym("p", len(names))
    y, at = ca.vertcat(q, ca.SX.zeros(n)), {name: k for k, name in enumerate(names)}
    hinges, ends = fns["hinges"](q, p), fns["ends"](q, p)
    com, rod = [], []
    for i in range(1, n + 1):
        alone = [1.0 if name in ("g", f"m{i}") else 0.0 if name in {f"m{k}" for k in range(1, n + 1)} else p[k]
                 for k, name in enumerate(names)]
        hanging = sum(p[at[f"hy{k}"]] for k in range(1, i + 1)) + p[at[f"ry{i}"]]  # j c_i with the chain hanging
        below = hanging - fns["energy"](y, ca.vertcat(*alone))
        com.append(below - hinges[3 * i - 2])
        rod.append(ends[3 * i - 2] - hinges[3 * i - 2])
    return ca.Function("heights", [q, p], [ca.vertcat(*com), ca.vertcat(*rod)])


def link_directions(chain, q) -> np.ndarray:
    """Each link's direction with gravity at the angles ``q``: the downward component (along ``j``, gravity's
    direction: a chain's ``g >= 0``) of the unit vector from its hinge to its centre of mass -- positive: the
    link hangs below its hinge, negative: it stands above it -- what an equilibrium's label reads, from the
    geometry, never from ``q`` being 0 or pi (an imported model's zero may be upright: the DeepMind acrobot's).  A link whose centre of mass is on its
    hinge moves no weight of its own: its rod's direction (hinge to the rod's end, ``l_i R_i j``) is read
    instead (the rotary pendulum's arm on its vertical axis: down, as it hangs)."""
    from ..numeric.recursive import parameter_vector, structure_of_chain

    com, rod = _heights_function(structure_of_chain(chain))(np.asarray(q, dtype=float), parameter_vector(chain))
    return _unit_directions(chain, np.array(com, dtype=float).ravel(), np.array(rod, dtype=float).ravel())


def _unit_directions(chain, com, rod) -> np.ndarray:
    """:func:`link_directions` from how far below its hinge each link's centre of mass is (``com`` [m]) and its
    rod's end (``rod``): ``com / |r_i|``, or ``rod / l_i`` where the centre of mass is on the hinge."""
    reach = [float(np.linalg.norm(link.com)) for link in chain.links]
    scale = max([1e-300] + reach + [link.length for link in chain.links] + [np.linalg.norm(link.offset) for link in chain.links])
    return np.array([c / r if r > 1e-12 * scale else (d / link.length if link.length > 0 else 1.0)
                     for c, d, r, link in zip(com, rod, reach, chain.links)])


def _numeric_model(model, what: str):
    """The model's chain (:meth:`as_chain`), or one :class:`ParameterError` line: not a model, or a model with
    symbolic values (``what`` needs numbers)."""
    try:
        as_chain = model.as_chain
    except AttributeError:
        raise ParameterError(f"params must be a skewpend.Parameters or a Chain, got {type(model).__name__}") from None
    try:
        return as_chain()
    except NotNumericError as exc:
        raise ParameterError(f"{what} needs numeric values; {str(exc).partition('; ')[2]}") from None


class _Search:
    """What every search on one model shares: its chain, its potential's printer (the cheapest, see the
    module), its torques and damping."""

    def __init__(self, model, what: str):
        self.chain = _numeric_model(model, what)
        self.n, self.coordinates = model.n, tuple(model.coordinates)
        exact = model.exact_model()  # the parameters the exact derivation prints, or None: the recursive algorithms
        self.land = _Exact(exact, _geometry_only(exact), self.chain) if exact is not None else _Recursive(self.chain)
        self.tau = np.array([link.torque for link in self.chain.links], dtype=float)

    @cached_property
    def gscale(self) -> float:
        """The size of grad Pi over the torus (64 seeded points) and of the torques: the unit in which a root's
        residual ``grad Pi - tau`` is judged (0: no gravity and no torque)."""
        probe = wrap(np.random.default_rng(0).uniform(-np.pi, np.pi, (64, self.n)))
        return float(max(np.abs(self.land.grad_hess(probe)[0]).max(), np.abs(self.tau).max()))

    def damping(self, coulomb: str) -> np.ndarray:
        """``C = -df/dq'`` at rest: each joint's viscous damping, with ``coulomb="smoothed"`` its friction's slope."""
        smoothed = coulomb == "smoothed"
        return np.diag([link.damping + (link.coulomb * self.chain.cfs if smoothed else 0.0) for link in self.chain.links])

    def newton(self, q: np.ndarray, iterations: int = 60) -> Tuple[np.ndarray, np.ndarray, int]:
        """Vectorised Newton on ``grad Pi(q) = tau`` from every row of ``q``: (roots, converged, its).

        The angles are kept in (-pi, pi] after every step, so a step is measured against angles of at
        most pi; a step is at most 0.5 rad long; a row converges when its step is below 1e-13 rad *and* its
        residual is below :data:`RESIDUAL` x the gradient's scale (a step lost to rounding is never taken for
        convergence)."""
        converged = np.zeros(len(q), dtype=bool)
        active = np.ones(len(q), dtype=bool)
        q = wrap(q)
        its = 0
        with np.errstate(all="ignore"):
            for its in range(1, iterations + 1):
                rows = np.flatnonzero(active)
                g, H = self.land.grad_hess(q[rows])
                g = g - self.tau
                det = np.linalg.det(H)
                ok = np.isfinite(det) & (np.abs(det) > 0) & np.all(np.isfinite(g), axis=1)
                # (det's LU is solve's: no zero pivot where det != 0; the other rows solve with E and stop)
                d = -np.linalg.solve(np.where(ok[:, None, None], H, np.eye(self.n)), g[..., None])[..., 0]
                d = np.where(ok[:, None], d, 0.0)
                step = np.sqrt(np.sum(d * d, axis=1))
                shrink = np.where(step > 0.5, 0.5 / np.maximum(step, 1e-300), 1.0)  # at most 0.5 rad a step
                q[rows] = wrap(q[rows] + d * shrink[:, None])
                small = np.max(np.abs(g), axis=1) <= RESIDUAL * self.gscale  # the residual before this (tiny) step
                # a singular Hessian at a root (a cyclic coordinate: the rotary pendulum's arm turns freely about
                # the vertical, every arm angle an equilibrium) has no Newton step, and needs none
                done = (ok & (step < 1e-13 * (1 + np.pi)) | ~ok & np.all(np.isfinite(g), axis=1)) & small
                converged[rows[done]] = True
                active[rows[~ok | done]] = False
                if not active.any():
                    break
        return q, converged, its

    def linearise(self, q: np.ndarray, coulomb: str) -> "Equilibrium":
        """The :class:`Equilibrium` at ``q`` (already a root)."""
        from scipy.linalg import LinAlgError, eigh

        Pi, H, M, down = self.land.at(q)
        K = 0.5 * (H + H.T)
        try:
            np.linalg.inv(M)  # (linear_point's state matrix needs it)
            lam, V = eigh(K, M)
        except (LinAlgError, np.linalg.LinAlgError, ValueError):  # M not positive definite to rounding
            raise ParameterError(
                f"the mass matrix at {', '.join(f'{c} = {x:.6g}' for c, x in zip(self.coordinates, q))} is not positive definite in double precision (condition number "
                f"{np.linalg.cond(M):.3g}): the model's lengths, masses and inertias span too many orders of magnitude"
            ) from None
        return linear_point(q, down, Pi - float(self.tau @ q) + 0.0, M, self.damping(coulomb), K, lam, V, coulomb)


def potential_function(params) -> Callable[..., float]:
    """``V(*q) = Pi - tau . q`` [J] of the numeric model (``V(phi, psi)`` for the double pendulum)."""
    V = potential_on_arrays(params)
    return lambda *q: float(V(*q))


def potential_on_arrays(params) -> Callable[..., np.ndarray]:
    """``V(*q)`` of :func:`potential_function` on arrays of angles at once (broadcast)."""
    search = _Search(params, "the potential")

    def V(*q: np.ndarray) -> np.ndarray:
        q = np.broadcast_arrays(*(np.asarray(x, dtype=float) for x in q))
        Q = np.stack([x.ravel() for x in q], axis=1)
        return (search.land.potential(Q) - Q @ search.tau).reshape(q[0].shape)

    return V


def wrap(q: np.ndarray) -> np.ndarray:
    """Angles into (-pi, pi]."""
    w = np.mod(np.asarray(q, dtype=float) + np.pi, 2 * np.pi) - np.pi
    return np.where(w == -np.pi, np.pi, w)


@dataclass(frozen=True)
class Equilibrium:
    """One equilibrium ``q*`` and the linearised motion about it.

    * ``q`` -- the model's coordinates [rad] in ``(-pi, pi]`` (``(phi, psi)`` for the double pendulum);
      ``label`` -- where each link's centre of mass is, link 1 first: ``down`` below its hinge (along
      gravity), ``up`` above it, ``level`` at its height (:func:`link_directions`: from the geometry, not from
      ``q`` being 0 or pi, so an imported model whose zero is upright -- the DeepMind acrobot -- has its
      ``"up-up"`` at ``q = 0``) -- ``"down-down"`` is the double pendulum hanging, ``"up-up"`` both rods upright
      in line, ``"down-up-down"`` a chain of three with its middle link upright;
    * ``potential`` -- ``V(q*) = Pi(q*) - tau . q*`` [J] (Pi = 0 with every rod hanging);
    * ``M``, ``C``, ``K`` -- the linearisation ``M dq'' + C dq' + K dq = 0`` about ``q*``
      (``K`` the Hessian of ``V``); ``A`` -- the ``2n x 2n`` state matrix of ``(dq, dq')``;
      ``eigenvalues`` -- its eigenvalues (descending real part);
    * ``morse_index`` -- the number of negative eigenvalues of ``K`` (0: a minimum of ``V``,
      stable; n: a maximum of ``V``; between: a saddle); ``stable`` -- index 0;
    * ``frequencies`` [rad/s] and ``shapes`` -- the oscillating directions (``K v = w^2 M v``,
      ``w^2 > 0``), ascending; ``growth_rates`` [1/s] and ``unstable_directions`` -- the
      directions of ``K v = -s^2 M v`` along which a small disturbance grows like ``exp(s t)``
      (without damping; with damping the rates are the positive real parts of ``eigenvalues``).
      Shapes and directions are columns over the coordinates with ``v^T M v = 1``;
    * ``coulomb`` -- how Coulomb friction entered ``C`` (``"exclude"``, the default: not at all;
      ``"smoothed"``: its smoothed slope ``cfs cf``).
    """

    q: Tuple[float, ...]
    label: str
    potential: float
    M: np.ndarray = field(repr=False)
    C: np.ndarray = field(repr=False)
    K: np.ndarray = field(repr=False)
    A: np.ndarray = field(repr=False)
    eigenvalues: np.ndarray = field(repr=False)
    morse_index: int = 0
    frequencies: np.ndarray = field(default_factory=lambda: np.zeros(0), repr=False)
    shapes: np.ndarray = field(default_factory=lambda: np.zeros((2, 0)), repr=False)
    growth_rates: np.ndarray = field(default_factory=lambda: np.zeros(0), repr=False)
    unstable_directions: np.ndarray = field(default_factory=lambda: np.zeros((2, 0)), repr=False)
    coulomb: str = field(default=DEFAULT_COULOMB, repr=False)

    @property
    def stable(self) -> bool:
        """A minimum of ``V`` (Lagrange-Dirichlet): stable; with damping asymptotically so."""
        return self.morse_index == 0

    @property
    def state(self) -> np.ndarray:
        """The equilibrium as a state: its angles followed by zero speeds."""
        return np.r_[np.asarray(self.q, dtype=float), np.zeros(len(self.q))]

    def describe(self) -> str:
        n, k = len(self.q), self.morse_index
        kind = "stable (minimum of V)" if k == 0 else f"{'maximum of V' if k == n else 'saddle'} (index {k})"
        where = ", ".join(f"{c} = {math.degrees(x):8.3f} deg" for c, x in zip(coordinate_names(n), self.q))
        parts = [f"{self.label:>9}  {where}  V = {self.potential:11.6g} J  {kind}"]
        if self.frequencies.size:
            parts.append("frequencies " + ", ".join(f"{w:.6g}" for w in self.frequencies) + " rad/s")
        if self.growth_rates.size:
            parts.append("growth rates " + ", ".join(f"{s:.6g}" for s in self.growth_rates) + " 1/s")
        return ";  ".join(parts)


def linear_point(q, down, potential: float, M, C, K, lam, V, coulomb: str) -> Equilibrium:
    """The :class:`Equilibrium` at ``q`` from its linearisation ``M, C, K`` and ``K v = lam M v``
    (``lam, V`` ascending, any number of coordinates): the state matrix and its eigenvalues, the Morse
    index, the oscillating and the unstable directions, the label from each link's downward component
    ``down`` (:func:`link_directions`: ``down``, ``up`` or ``level``)."""
    from scipy.linalg import eig

    n = len(q)
    Minv = np.linalg.inv(M)
    A = np.block([[np.zeros((n, n)), np.eye(n)], [-Minv @ K, -Minv @ C]])
    ev = eig(A, right=False)
    ev = ev[np.lexsort((-ev.imag, -ev.real))]
    scale = max(np.abs(lam).max(), np.finfo(float).tiny)
    index = int(np.sum(lam < -DEGENERATE * scale))
    V *= np.where(V[np.argmax(np.abs(V), axis=0), np.arange(V.shape[1])] < 0, -1.0, 1.0)  # largest entry positive
    osc = lam > DEGENERATE * scale
    unstable = lam < -DEGENERATE * scale
    if np.any(C != 0):
        growth = np.sort(ev.real[ev.real > 1e-12 * np.abs(ev).max()])[::-1][:index] if index else np.zeros(0)
    else:
        growth = np.sqrt(-lam[unstable])[::-1]
    label = "-".join("level" if abs(float(d)) < 1e-9 else ("down" if float(d) > 0 else "up") for d in down)
    return Equilibrium(
        q=tuple(float(x) for x in q), label=label, potential=potential, M=M, C=C, K=K, A=A, eigenvalues=ev,
        morse_index=index, frequencies=np.sqrt(lam[osc]), shapes=V[:, osc], growth_rates=np.asarray(growth, dtype=float),
        unstable_directions=V[:, unstable][:, ::-1], coulomb=coulomb,
    )


@dataclass(frozen=True)
class Equilibria(Result):
    """Every equilibrium of a model (:func:`equilibria`), ordered by potential energy.

    * ``points`` -- the :class:`Equilibrium` objects (``len``, iteration and indexing reach them);
    * ``index_sum`` -- ``sum (-1)^index`` over them: 0 on the n-torus when none is missed
      (Poincare-Hopf), the check behind ``status``;
    * the result protocol: ``params`` (the model as given), ``settings`` (the grid of starts), ``stats``
      (``starts``, ``converged``, ``newton_iterations``), ``status``, ``message``, ``ok``, ``to_xarray()``,
      ``to_netcdf()``, ``summary()``, ``table()``.
    """

    points: List[Equilibrium]

    result_kind: ClassVar[str] = "equilibria"

    def __len__(self) -> int:
        return len(self.points)

    def __iter__(self):
        return iter(self.points)

    def __getitem__(self, k):
        return self.points[k]

    @property
    def coulomb(self) -> str:
        """How Coulomb friction entered each point's ``C`` (``"exclude"`` or ``"smoothed"``)."""
        return self.settings.get("coulomb", DEFAULT_COULOMB)

    @property
    def coulomb_note(self) -> str:
        """How the Coulomb friction was treated, one line ('' for a model without it)."""
        return coulomb_note(self.params, self.coulomb)

    @property
    def index_sum(self) -> int:
        return int(sum((-1) ** e.morse_index for e in self.points))

    def find(self, label: str) -> Equilibrium:
        """The equilibrium with this ``label`` (``"down-down"``, ``"up-up"``, ``"down-up-down"``, ...)."""
        found = [e for e in self.points if e.label == label]
        if not found:
            have = ", ".join(e.label for e in self.points) or "none"
            raise ParameterError(f"no equilibrium is labelled {label!r}; the model has: {have}")
        return found[0]

    def table(self) -> str:
        width = max([9] + [len(e.label) for e in self.points])
        lines = [f"{'label':>{width}}  " + "  ".join(f"{c + ' [deg]':>10}" for c in self.params.coordinates) +
                 f"  {'V [J]':>12}  index  {'frequencies [rad/s]':<24}  growth rates [1/s]"]
        for e in self.points:
            freq = ", ".join(f"{w:.6g}" for w in e.frequencies) or "--"
            grow = ", ".join(f"{s:.6g}" for s in e.growth_rates) or "--"
            lines.append(f"{e.label:>{width}}  " + "  ".join(f"{math.degrees(x):10.4f}" for x in e.q) +
                         f"  {e.potential:12.6g}  {e.morse_index:>5}  {freq:<24}  {grow}")
        return "\n".join(lines)

    def _dataset(self) -> DatasetSpec:
        n, coordinates = len(self.points), tuple(self.params.coordinates)

        def directions(fn):  # a row an equilibrium, NaN beyond its directions
            out = np.full((n, len(coordinates)), np.nan)
            for i, e in enumerate(self.points):
                out[i, :fn(e).size] = fn(e)
            return out

        return DatasetSpec(
            variables={
                **{c: (("equilibrium",), np.array([e.q[k] for e in self.points]), {"units": "rad"})
                   for k, c in enumerate(coordinates)},
                "potential": (("equilibrium",), np.array([e.potential for e in self.points]),
                              {"units": "J", "long_name": "V = Pi - tau . q"}),
                "morse_index": (("equilibrium",), np.array([e.morse_index for e in self.points], dtype=np.int32), {}),
                "frequency": (("equilibrium", "direction"), directions(lambda e: e.frequencies),
                              {"units": "rad/s", "long_name": "natural angular frequency (NaN: not oscillating)"}),
                "growth_rate": (("equilibrium", "direction"), directions(lambda e: e.growth_rates),
                                {"units": "1/s", "long_name": "growth rate of an unstable direction (NaN: none)"}),
            },
            coords={},
            attrs={"title": f"equilibria on the {len(coordinates)}-torus (skewpend)",
                   "labels": ", ".join(e.label for e in self.points), "index_sum": self.index_sum, **self._base_attrs()},
        )


@netcdf_reader(Equilibria.result_kind)
def read_equilibria(path, variables, attrs) -> Equilibria:
    """:class:`Equilibria` from their ``*.nc`` file (``read_equilibria(path)``, for
    :func:`skewpend.open_result`): the file keeps each point's angles, potential, index, label and
    frequencies; its linearisation is computed again there (:func:`equilibrium_at`), and the
    stored values must agree with it."""
    import dataclasses

    from ..errors import SkewpendError
    from ..symbolic.model import AnyModel

    proto = protocol_fields(path, attrs, AnyModel)
    params = proto["params"]
    labels = [s.strip() for s in str(attrs.get("labels", "")).split(",") if s.strip()]
    angles = np.array([np.asarray(variables[c], dtype=float).reshape(-1) for c in params.coordinates]).T
    if len(labels) != len(angles):
        raise ParameterError(f"{path} is not equilibria made by skewpend: {len(labels)} labels for {len(angles)} points")
    points = []
    for i, q in enumerate(angles):
        q = tuple(float(x) for x in q)
        try:
            e = equilibrium_at(params, q)
        except SkewpendError:
            raise ParameterError(f"{path} was written by another model: ({', '.join(f'{x:.6g}' for x in q)}) is not an "
                                 f"equilibrium of its parameters") from None
        freq = np.asarray(variables["frequency"], dtype=float)[i]
        grow = np.asarray(variables["growth_rate"], dtype=float)[i]
        stored = {"frequencies": freq[np.isfinite(freq)], "growth_rates": grow[np.isfinite(grow)]}
        agree(path, f"equilibrium {i}'s angles", wrap(np.subtract(e.q, q)), np.zeros(len(q)), scale=math.pi)
        agree(path, f"equilibrium {i}'s potential", float(variables["potential"][i]), e.potential,
              scale=max(abs(float(variables["potential"][i])), float(np.abs(e.K).max())))
        for name, value in stored.items():
            agree(path, f"equilibrium {i}'s {name.replace('_', ' ')}", value, getattr(e, name))
        if int(variables["morse_index"][i]) != e.morse_index or labels[i] != e.label:
            raise ParameterError(f"{path} was written by another model: equilibrium {i} is {labels[i]} of index "
                                 f"{int(variables['morse_index'][i])} there, {e.label} of index {e.morse_index} here")
        points.append(dataclasses.replace(e, q=q, potential=float(variables["potential"][i]),
                                          morse_index=int(variables["morse_index"][i]), label=labels[i], **stored))
    return Equilibria(points=points, **proto)


def _starts(n: int, per_side: int) -> np.ndarray:
    """Newton's starts on the n-torus: a grid of ``per_side^(2/n)`` points a side (about ``per_side^2`` in all:
    the double pendulum's ``per_side x per_side``), then the ``2^n`` configurations with every relative angle 0
    or pi."""
    side = max(1, int(math.floor(per_side ** (2.0 / n) + 1e-9)))
    axis = (np.arange(side) + 0.5) / side * 2 * np.pi - np.pi
    grid = np.array(np.meshgrid(*([axis] * n), indexing="ij")).reshape(n, -1).T
    corners = (np.arange(2 ** n)[:, None] >> np.arange(n) & 1) * np.pi
    return np.vstack([grid, corners])


def equilibria(params, *, starts: int = DEFAULT_STARTS, coulomb: str = DEFAULT_COULOMB) -> Equilibria:
    """Every equilibrium of the numeric model ``params`` (the double pendulum's :class:`~skewpend.Parameters` or
    a :class:`~skewpend.Chain`) on the n-torus (see the module).

    ``starts``: Newton starts per side of the first grid of the double pendulum, ``starts^2`` points on any
    torus (doubled, up to 128 a side, while the Poincare-Hopf check fails), besides the ``2^n`` configurations
    with every relative angle 0 or pi (at most :data:`MAX_SEEDED_LINKS` links).  ``coulomb``: Coulomb friction
    left out of each linearisation (``"exclude"``, the default: non-smooth at rest) or linearised by its
    smoothed slope (``"smoothed"``); the message says which.  Refused: a symbolic parameter, and ``g = 0``
    without torques (then every configuration is an equilibrium).  Without gravity but with torques there is
    no equilibrium (an empty result).
    """
    from ..checks import whole

    search = _Search(params, "equilibria")
    starts = whole("starts", starts, lo=2, hi=MAX_STARTS)
    coulomb = check_coulomb(coulomb)
    n = search.n
    if n > MAX_SEEDED_LINKS:
        raise ParameterError(f"equilibria seed Newton's method at the 2^n configurations with every relative angle 0 or "
                             f"pi: at most {MAX_SEEDED_LINKS} links, this model has {n}")
    if not (search.gscale > 0):
        raise EquilibriumError("every configuration is an equilibrium without gravity and torques (g = 0, tau = 0); "
                               "equilibria need g > 0 or a torque")
    total_its = total_starts = 0
    per_side = starts
    while True:
        q0 = _starts(n, per_side)
        roots, conv, its = search.newton(q0)
        total_its += its
        total_starts += len(q0)
        roots = wrap(roots[conv])
        if len(roots):  # the residual where each ended
            g, _ = search.land.grad_hess(roots)
            roots = roots[np.all(np.abs(g - search.tau) <= RESIDUAL * search.gscale, axis=1)]  # gscale has the torques
        found, k = np.empty_like(roots), 0
        for r in roots:
            if not k or np.min(np.max(np.abs(wrap(r - found[:k])), axis=1)) > SAME_ROOT:
                found[k], k = r, k + 1
        points = [search.linearise(r, coulomb) for r in found[:k]]
        points.sort(key=lambda e: (e.potential, e.q))
        index_sum = sum((-1) ** e.morse_index for e in points)
        if index_sum == 0 or per_side >= MAX_STARTS:
            break
        per_side = min(2 * per_side, MAX_STARTS)
    degenerate = [e for e in points
                  if np.min(np.abs(np.linalg.eigvalsh(e.K))) <= DEGENERATE * max(np.abs(np.linalg.eigvalsh(e.K)).max(), 1e-300)]
    if index_sum == 0 and not degenerate:
        status, message = Status.SUCCESS, (
            f"{len(points)} equilibria; their Morse indices sum to 0 as on the {n}-torus (none missed)" if points else
            "no equilibrium: the torques are not balanced by gravity anywhere")
    else:
        status, message = Status.PARTIAL, (
            f"{len(points)} equilibria found, but " + (
                f"{len(degenerate)} of them degenerate (K singular): the index check does not apply" if degenerate else
                f"their indices sum to {index_sum}, not 0: an equilibrium may be missed"))
    settings = {"starts": starts, "final_starts": per_side, "tau": search.tau.tolist()}
    note = coulomb_note(params, coulomb)
    if note:  # only where it matters (a model without friction keeps its fingerprint)
        settings["coulomb"] = coulomb
        message = f"{message}; {note}"
    stats = {"starts": total_starts, "converged": int(len(points)), "newton_iterations": int(total_its)}
    return Equilibria(points=points, params=params, settings=settings, stats=stats, status=status, message=message)


def equilibrium_at(params, q: Sequence[float], name: str = "q", *, coulomb: str = DEFAULT_COULOMB) -> Equilibrium:
    """The equilibrium at ``q`` (the model's coordinates, ``(phi, psi)`` for the double pendulum; angles
    reduced modulo 2 pi, :func:`skewpend.checks.angles`: at most 1e6 rad in magnitude), polished by Newton's
    method from there; refused with one line when ``q`` is not near an equilibrium (the residual names how
    far).  ``name``: the argument's name in a refusal; ``coulomb`` as for :func:`equilibria`."""
    from ..checks import angles

    search = _Search(params, "an equilibrium")
    coulomb = check_coulomb(coulomb)
    q0 = np.array(angles(name, q, search.n), dtype=float).reshape(1, -1)
    g0, _ = search.land.grad_hess(q0.copy())
    root, conv, _ = search.newton(q0.copy(), iterations=30)
    moved = float(np.max(np.abs(wrap(root[0] - q0[0]))))
    if not conv[0] or moved > NEAR:
        residual = float(np.max(np.abs(g0[0] - search.tau)))
        raise EquilibriumError(
            f"({', '.join(search.coordinates)}) = ({', '.join(f'{x:.6g}' for x in q0[0])}) rad is not an equilibrium: "
            f"dV/dq = {residual:.3g} N m there; choose one of skewpend.equilibria(params)")
    return search.linearise(wrap(root[0]), coulomb)


def find_equilibrium(params, which, name: str = "equilibrium", *, coulomb: str = DEFAULT_COULOMB) -> Equilibrium:
    """An equilibrium given as an :class:`Equilibrium`, a label (``"up-up"``: one of :func:`equilibria`'s) or
    angles near one (:func:`equilibrium_at`; reduced modulo 2 pi, refused beyond 1e6 rad); ``name`` is the
    argument's name in the refusal.  Its linearisation treats Coulomb friction as ``coulomb`` says (an
    :class:`Equilibrium` made with the other choice is linearised again)."""
    _numeric_model(params, "an equilibrium")
    coulomb = check_coulomb(coulomb)
    if isinstance(which, Equilibrium):
        if which.coulomb == coulomb or not friction_terms(params):
            return which
        return equilibrium_at(params, which.q, name, coulomb=coulomb)
    if isinstance(which, str):
        return equilibria(params, coulomb=coulomb).find(which)
    if which is None or isinstance(which, (bytes, dict, set)):
        raise ParameterError(f"{name} must be an equilibrium, a label such as '{'-'.join(['up'] * params.n)}', or "
                             f"({', '.join(params.coordinates)}), got {which!r}")
    return equilibrium_at(params, which, name, coulomb=coulomb)
