"""Every equilibrium of the skewed double pendulum on the torus, and the linearisation about each.

At rest the equations of motion ``M(q) q'' = f(q, q')`` reduce to ``dPi/dq = tau``: an equilibrium
is a critical point of ``V(q) = Pi(q) - tau . q``, the potential energy with the work of the
constant torques.  ``Pi`` is a trigonometric polynomial of degree one in each angle (its
gradient too), so there are finitely many isolated equilibria (at most eight) unless gravity and
the torques both vanish.  :func:`equilibria` finds them all:

* Newton's method on ``grad V = 0`` (gradient and Hessian generated from the derivation, one
  vectorised iteration for every start) from an ``n x n`` grid of starts over the torus;
* the roots deduplicated on the torus (angles modulo 2 pi) and polished;
* a check that none is missed: on the torus the Morse indices of nondegenerate critical points
  satisfy ``sum (-1)^index = 0`` (Poincare-Hopf: the Euler characteristic of the torus); if the
  sum is not 0 the grid is refined, and a result that still fails the check says so
  (:attr:`~skewpend.Status.PARTIAL`).

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
from functools import lru_cache
from typing import Callable, ClassVar, List, Sequence, Tuple

import numpy as np

from ..errors import EquilibriumError, ParameterError
from ..results import DatasetSpec, Result, agree, netcdf_reader, protocol_fields
from ..status import Status
from ..symbolic.friction import DEFAULT_COULOMB, check_coulomb, coulomb_note, friction_terms
from ..schema import GEOMETRY_NAMES, names
from ..symbolic.model import SCALAR_NAMES, Parameters

__all__ = ["Equilibrium", "Equilibria", "equilibria", "chain_equilibria", "linear_point", "equilibrium_at", "find_equilibrium", "linearisation_functions",
           "potential_function"]

#: Grid of Newton starts per side (refined up to :data:`MAX_STARTS` while the index check fails).
DEFAULT_STARTS = 16
MAX_STARTS = 128
#: Two roots closer than this on the torus [rad] are one equilibrium.
SAME_ROOT = 1e-6
#: How far [rad] a point given as "near an equilibrium" may lie from it.
NEAR = 0.2
#: An eigenvalue of K below this fraction of the largest is taken as zero (a degenerate point).
DEGENERATE = 1e-9


def _geometry_only(params: Parameters) -> Parameters:
    """``params`` with every scalar symbolic (the bodies and axes kept): one derivation serves
    every ``a, b, m1, m2, alpha, g, c, tau``."""
    return Parameters(**{k: getattr(params, k) for k in GEOMETRY_NAMES}, **{k: None for k in SCALAR_NAMES})


@lru_cache(maxsize=32)
def linearisation_functions(geometry: Parameters) -> Callable:
    """``f(*scalars, phi, psi) -> (Pi, grad Pi, Hessian of Pi, M, C)`` generated (SymPy
    ``lambdify``) from the derivation of ``geometry`` (scalars in :data:`SCALAR_NAMES` order;
    ``C = -df/dq'`` at rest, the damping)."""
    from ..numeric.pyfunctions import cached_lambdify

    def build():
        import sympy as sp

        from ..symbolic.derivation import SYMBOLS, derive

        eom = derive(geometry)
        phi, psi, dphi, dpsi = (SYMBOLS[n] for n in ("phi", "psi", "dphi", "dpsi"))
        q = [phi, psi]
        Pi = eom.potential_energy
        grad = [sp.diff(Pi, x) for x in q]
        hess = [[sp.diff(g, x) for x in q] for g in grad]
        rest = {dphi: 0, dpsi: 0}
        C = [[-sp.diff(eom.forcing[i], v).subs(rest) for v in (dphi, dpsi)] for i in range(2)]
        return [SYMBOLS[n] for n in SCALAR_NAMES] + q, [Pi, grad, hess, eom.mass_matrix.tolist(), C]

    return cached_lambdify("linearisation", "analysis/equilibria.py", geometry, build)


@lru_cache(maxsize=32)
def _direction_functions(geometry: Parameters) -> Callable:
    """``f(alpha, phi, psi) -> (j . P1 j, j . P j)``: the vertical component of each rod's
    direction (``j`` points down: positive = hanging, negative = pointing up)."""
    from ..numeric.pyfunctions import cached_lambdify

    def build():
        from ..symbolic.derivation import SYMBOLS, derive

        steps = derive(geometry).steps
        return [SYMBOLS[n] for n in SCALAR_NAMES] + [SYMBOLS["phi"], SYMBOLS["psi"]], [steps["P1"][1, 1], steps["P"][1, 1]]

    return cached_lambdify("directions", "analysis/equilibria.py", geometry, build)


def _scalars(params: Parameters) -> List[float]:
    return [0.0 if (n == "alpha" and not params.uses_alpha) else float(getattr(params, n)) for n in SCALAR_NAMES]


def potential_function(params: Parameters) -> Callable[[float, float], float]:
    """``V(phi, psi) = Pi - tau . q`` [J] of the numeric model (generated from the derivation)."""
    params.require_numeric("the potential")
    values = _scalars(params)
    functions = linearisation_functions(_geometry_only(params))
    tau1, tau2 = float(params.tau1), float(params.tau2)

    def V(phi: float, psi: float) -> float:
        return float(functions(*values, phi, psi)[0]) - tau1 * phi - tau2 * psi

    return V


def potential_on_arrays(params: Parameters) -> Callable[[np.ndarray, np.ndarray], np.ndarray]:
    """``V(phi, psi)`` of :func:`potential_function` on arrays of angles at once (the same
    generated function, broadcast)."""
    params.require_numeric("the potential")
    values = _scalars(params)
    functions = linearisation_functions(_geometry_only(params))
    tau1, tau2 = float(params.tau1), float(params.tau2)

    def V(phi: np.ndarray, psi: np.ndarray) -> np.ndarray:
        phi, psi = np.broadcast_arrays(np.asarray(phi, dtype=float), np.asarray(psi, dtype=float))
        Pi = np.broadcast_to(np.asarray(functions(*values, phi, psi)[0], dtype=float), phi.shape)
        return Pi - tau1 * phi - tau2 * psi

    return V


def wrap(q: np.ndarray) -> np.ndarray:
    """Angles into (-pi, pi]."""
    w = np.mod(np.asarray(q, dtype=float) + np.pi, 2 * np.pi) - np.pi
    return np.where(w == -np.pi, np.pi, w)


@dataclass(frozen=True)
class Equilibrium:
    """One equilibrium ``q* = (phi, psi)`` and the linearised motion about it.

    * ``q`` -- ``(phi, psi)`` [rad] in ``(-pi, pi]``; ``label`` -- which way each rod points,
      rod 1 then rod 2: ``down``, ``up`` or ``level`` (horizontal) -- ``"down-down"`` is the
      hanging position, ``"up-up"`` both rods upright in line;
    * ``potential`` -- ``V(q*) = Pi(q*) - tau . q*`` [J] (Pi = 0 with both rods hanging);
    * ``M``, ``C``, ``K`` -- the linearisation ``M dq'' + C dq' + K dq = 0`` about ``q*``
      (``K`` the Hessian of ``V``); ``A`` -- the 4 x 4 state matrix of ``(dq, dq')``;
      ``eigenvalues`` -- its eigenvalues (descending real part);
    * ``morse_index`` -- the number of negative eigenvalues of ``K`` (0: a minimum of ``V``,
      stable; 1: a saddle; 2: a maximum of ``V``); ``stable`` -- index 0;
    * ``frequencies`` [rad/s] and ``shapes`` -- the oscillating directions (``K v = w^2 M v``,
      ``w^2 > 0``), ascending; ``growth_rates`` [1/s] and ``unstable_directions`` -- the
      directions of ``K v = -s^2 M v`` along which a small disturbance grows like ``exp(s t)``
      (without damping; with damping the rates are the positive real parts of ``eigenvalues``).
      Shapes and directions are columns ``[phi, psi]`` with ``v^T M v = 1``;
    * ``coulomb`` -- how Coulomb friction entered ``C`` (``"exclude"``, the default: not at all;
      ``"smoothed"``: its smoothed slope ``cfs cf``).
    """

    q: Tuple[float, float]
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
        """The equilibrium as a state ``(phi, psi, 0, 0)`` (a chain's angles followed by zero speeds)."""
        return np.r_[np.asarray(self.q, dtype=float), np.zeros(len(self.q))]

    def describe(self) -> str:
        n, k = len(self.q), self.morse_index
        kind = "stable (minimum of V)" if k == 0 else f"{'maximum of V' if k == n else 'saddle'} (index {k})"
        names = ("phi", "psi") if n == 2 else tuple(f"q{k + 1}" for k in range(n))
        where = ", ".join(f"{c} = {math.degrees(x):8.3f} deg" for c, x in zip(names, self.q))
        parts = [f"{self.label:>9}  {where}  V = {self.potential:11.6g} J  {kind}"]
        if self.frequencies.size:
            parts.append("frequencies " + ", ".join(f"{w:.6g}" for w in self.frequencies) + " rad/s")
        if self.growth_rates.size:
            parts.append("growth rates " + ", ".join(f"{s:.6g}" for s in self.growth_rates) + " 1/s")
        return ";  ".join(parts)


def _linearise(params: Parameters, q: np.ndarray, values: Sequence[float], functions,
               coulomb: str = DEFAULT_COULOMB) -> Equilibrium:
    """The :class:`Equilibrium` at ``q`` (already a root)."""
    from scipy.linalg import LinAlgError, eigh

    if coulomb != "smoothed":  # Coulomb friction enters C only (its slope cfs cf): excluded, evaluated at cf = 0
        values = [0.0 if n in names(stem="cf") else v for n, v in zip(SCALAR_NAMES, values)]
    Pi, _, H, M, C = functions(*values, float(q[0]), float(q[1]))
    M = np.array(M, dtype=float)
    C = np.array(C, dtype=float) * np.ones((2, 2))
    K = np.array(H, dtype=float)
    K = 0.5 * (K + K.T)
    tau = np.array([params.tau1, params.tau2], dtype=float)
    potential = float(Pi) - float(tau @ q)
    try:
        np.linalg.inv(M)  # (linear_point's state matrix needs it)
        lam, V = eigh(K, M)
    except (LinAlgError, np.linalg.LinAlgError, ValueError):  # M not positive definite to rounding: scales too far apart
        raise ParameterError(
            f"the mass matrix at phi = {float(q[0]):.6g}, psi = {float(q[1]):.6g} is not positive definite in double "
            f"precision (condition number {np.linalg.cond(M):.3g}): the model's lengths, masses and inertias span too "
            f"many orders of magnitude") from None
    dirs = _direction_functions(_geometry_only(params))(*values, float(q[0]), float(q[1]))
    return linear_point(q, dirs, potential, M, C, K, lam, V, coulomb)


def linear_point(q, down, potential: float, M, C, K, lam, V, coulomb: str) -> Equilibrium:
    """The :class:`Equilibrium` at ``q`` from its linearisation ``M, C, K`` and ``K v = lam M v``
    (``lam, V`` ascending, any number of coordinates): the state matrix and its eigenvalues, the Morse
    index, the oscillating and the unstable directions, the label from each rod's downward component
    ``down`` (``down``, ``up`` or ``level``)."""
    from scipy.linalg import eig

    n = len(q)
    Minv = np.linalg.inv(M)
    A = np.block([[np.zeros((n, n)), np.eye(n)], [-Minv @ K, -Minv @ C]])
    ev = eig(A, right=False)
    ev = ev[np.lexsort((-ev.imag, -ev.real))]
    scale = max(np.abs(lam).max(), np.finfo(float).tiny)
    index = int(np.sum(lam < -DEGENERATE * scale))
    for k in range(V.shape[1]):
        col = V[:, k]
        if col[np.argmax(np.abs(col))] < 0:
            V[:, k] = -col
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
    * ``index_sum`` -- ``sum (-1)^index`` over them: 0 on the torus when none is missed
      (Poincare-Hopf), the check behind ``status``;
    * the result protocol: ``params``, ``settings`` (the grid of starts), ``stats`` (``starts``,
      ``converged``, ``newton_iterations``), ``status``, ``message``, ``ok``, ``to_xarray()``,
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
        """The equilibrium with this ``label`` (``"down-down"``, ``"up-up"``, ...)."""
        found = [e for e in self.points if e.label == label]
        if not found:
            have = ", ".join(e.label for e in self.points) or "none"
            raise ParameterError(f"no equilibrium is labelled {label!r}; the model has: {have}")
        return found[0]

    def table(self) -> str:
        if not isinstance(self.params, Parameters):  # a chain: its angles in one column
            width = max([len(e.label) for e in self.points] + [5])
            lines = [f"{'label':>{width}}  {'q [deg]':<{8 * len(self.points[0].q) if self.points else 8}}  {'V [J]':>12}  index  "
                     "frequencies [rad/s]; growth rates [1/s]"]
            for e in self.points:
                freq = ", ".join(f"{w:.6g}" for w in e.frequencies) or "--"
                grow = ", ".join(f"{s:.6g}" for s in e.growth_rates) or "--"
                q = " ".join(f"{math.degrees(x):7.2f}" for x in e.q)
                lines.append(f"{e.label:>{width}}  {q}  {e.potential:12.6g}  {e.morse_index:>5}  {freq}; {grow}")
            return "\n".join(lines)
        lines = [f"{'label':>9}  {'phi [deg]':>10}  {'psi [deg]':>10}  {'V [J]':>12}  index  "
                 f"{'frequencies [rad/s]':<24}  growth rates [1/s]"]
        for e in self.points:
            freq = ", ".join(f"{w:.6g}" for w in e.frequencies) or "--"
            grow = ", ".join(f"{s:.6g}" for s in e.growth_rates) or "--"
            lines.append(f"{e.label:>9}  {math.degrees(e.q[0]):10.4f}  {math.degrees(e.q[1]):10.4f}  "
                         f"{e.potential:12.6g}  {e.morse_index:>5}  {freq:<24}  {grow}")
        return "\n".join(lines)

    def _dataset(self) -> DatasetSpec:
        n = len(self.points)

        def col(fn, k):
            out = np.full(n, np.nan)
            for i, e in enumerate(self.points):
                arr = fn(e)
                if arr.size > k:
                    out[i] = arr[k]
            return out

        return DatasetSpec(
            variables={
                "phi": (("equilibrium",), np.array([e.q[0] for e in self.points]), {"units": "rad"}),
                "psi": (("equilibrium",), np.array([e.q[1] for e in self.points]), {"units": "rad"}),
                "potential": (("equilibrium",), np.array([e.potential for e in self.points]),
                              {"units": "J", "long_name": "V = Pi - tau . q"}),
                "morse_index": (("equilibrium",), np.array([e.morse_index for e in self.points], dtype=np.int32), {}),
                "frequency": (("equilibrium", "direction"),
                              np.stack([col(lambda e: e.frequencies, k) for k in range(2)], axis=1) if n else np.zeros((0, 2)),
                              {"units": "rad/s", "long_name": "natural angular frequency (NaN: not oscillating)"}),
                "growth_rate": (("equilibrium", "direction"),
                                np.stack([col(lambda e: e.growth_rates, k) for k in range(2)], axis=1) if n else np.zeros((0, 2)),
                                {"units": "1/s", "long_name": "growth rate of an unstable direction (NaN: none)"}),
            },
            coords={},
            attrs={"title": "equilibria of the skewed double pendulum (skewpend)",
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

    proto = protocol_fields(path, attrs, Parameters)
    params = proto["params"]
    labels = [s.strip() for s in str(attrs.get("labels", "")).split(",") if s.strip()]
    phi, psi = (np.asarray(variables[k], dtype=float).reshape(-1) for k in ("phi", "psi"))
    if len(labels) != phi.size:
        raise ParameterError(f"{path} is not equilibria made by skewpend: {len(labels)} labels for {phi.size} points")
    points = []
    for i in range(phi.size):
        q = (float(phi[i]), float(psi[i]))
        try:
            e = equilibrium_at(params, q)
        except SkewpendError:
            raise ParameterError(f"{path} was written by another model: ({q[0]:.6g}, {q[1]:.6g}) is not an equilibrium "
                                 f"of its parameters") from None
        freq = np.asarray(variables["frequency"], dtype=float)[i]
        grow = np.asarray(variables["growth_rate"], dtype=float)[i]
        stored = {"frequencies": freq[np.isfinite(freq)], "growth_rates": grow[np.isfinite(grow)]}
        agree(path, f"equilibrium {i}'s angles", wrap(np.subtract(e.q, q)), np.zeros(2), scale=math.pi)
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


def _gradient_scale(grad_hess, tau: np.ndarray) -> float:
    """The size of ``grad Pi`` over the torus (64 seeded points) and of the torques: the unit in
    which a root's residual ``grad Pi - tau`` is judged."""
    probe = wrap(np.random.default_rng(0).uniform(-np.pi, np.pi, (64, 2)))
    return float(max(np.abs(grad_hess(probe)[0]).max(), np.abs(tau).max()))


#: A root's residual ``|grad Pi - tau|`` must be below this fraction of the gradient's scale.
RESIDUAL = 1e-9


def _newton(grad_hess, q: np.ndarray, tau: np.ndarray, iterations: int = 60, *,
            gscale: float = 0.0) -> Tuple[np.ndarray, np.ndarray, int]:
    """Vectorised Newton on ``grad Pi(q) = tau`` from every row of ``q``: (roots, converged, its).

    The angles are kept in (-pi, pi] after every step, so a step is measured against angles of
    at most pi; a row converges when its step is below 1e-13 rad *and* its residual is below
    :data:`RESIDUAL` x ``gscale`` (a step lost to rounding is never taken for convergence)."""
    converged = np.zeros(len(q), dtype=bool)
    active = np.ones(len(q), dtype=bool)
    q = wrap(q)
    its = 0
    with np.errstate(all="ignore"):
        for its in range(1, iterations + 1):
            g, H = grad_hess(q)
            g = g - tau
            det = H[:, 0, 0] * H[:, 1, 1] - H[:, 0, 1] * H[:, 1, 0]
            ok = active & np.isfinite(det) & (np.abs(det) > 0)
            d0 = np.where(ok, -(H[:, 1, 1] * g[:, 0] - H[:, 0, 1] * g[:, 1]) / np.where(ok, det, 1.0), 0.0)
            d1 = np.where(ok, -(-H[:, 1, 0] * g[:, 0] + H[:, 0, 0] * g[:, 1]) / np.where(ok, det, 1.0), 0.0)
            step = np.hypot(d0, d1)
            shrink = np.where(step > 0.5, 0.5 / np.maximum(step, 1e-300), 1.0)  # at most 0.5 rad a step
            q[:, 0] += d0 * shrink
            q[:, 1] += d1 * shrink
            q = wrap(q)
            active &= ok
            small = np.max(np.abs(g), axis=1) <= RESIDUAL * gscale  # the residual before this (tiny) step
            done = active & (step < 1e-13 * (1 + np.pi)) & small
            converged |= done
            active &= ~done
            if not active.any():
                break
    return q, converged, its


def equilibria(params: Parameters, *, starts: int = DEFAULT_STARTS, coulomb: str = DEFAULT_COULOMB) -> Equilibria:
    """Every equilibrium of the numeric model ``params`` on the torus (see the module).

    ``starts``: Newton starts per side of the first grid (doubled, up to 128, while the
    Poincare-Hopf check fails).  ``coulomb``: Coulomb friction left out of each linearisation
    (``"exclude"``, the default: non-smooth at rest) or linearised by its smoothed slope
    (``"smoothed"``); the message says which.  Refused: a symbolic parameter, and ``g = 0`` without torques
    (then every configuration is an equilibrium).  Without gravity but with torques there is no
    equilibrium (an empty result).
    """
    from ..checks import numeric_params, whole
    from ..symbolic.chain import Chain

    if isinstance(params, Chain):
        return chain_equilibria(params, coulomb=coulomb)
    params = numeric_params(params, "equilibria")
    starts = whole("starts", starts, lo=2, hi=MAX_STARTS)
    coulomb = check_coulomb(coulomb)
    tau = np.array([params.tau1, params.tau2], dtype=float)
    values = _scalars(params)
    functions = linearisation_functions(_geometry_only(params))

    def grad_hess(q):
        _, g, H, _, _ = functions(*values, q[:, 0], q[:, 1])
        n = len(q)
        g = np.stack([np.broadcast_to(np.asarray(x, dtype=float), (n,)) for x in g], axis=1)
        H = np.array([[np.broadcast_to(np.asarray(x, dtype=float), (n,)) for x in row] for row in H]).transpose(2, 0, 1)
        return g, H

    # the scale of the gradient (to tell "no equilibrium" and degenerate models apart)
    gscale = _gradient_scale(grad_hess, tau)
    if not (gscale > 0):
        raise EquilibriumError("every configuration is an equilibrium without gravity and torques (g = 0, tau = 0); "
                               "equilibria need g > 0 or a torque")
    total_its = 0
    total_starts = 0
    n = starts
    while True:
        grid = (np.arange(n) + 0.5) / n * 2 * np.pi - np.pi
        q0 = np.array(np.meshgrid(grid, grid, indexing="ij")).reshape(2, -1).T.copy()
        roots, conv, its = _newton(grad_hess, q0, tau, gscale=gscale)
        total_its += its
        total_starts += len(q0)
        found: List[np.ndarray] = []
        for r in wrap(roots[conv]):
            g, _ = grad_hess(r[None, :])
            if not np.all(np.abs(g[0] - tau) <= 1e-9 * max(gscale, np.abs(tau).max())):
                continue
            if all(np.max(np.abs(wrap(r - f))) > SAME_ROOT for f in found):
                found.append(r)
        points = [_linearise(params, wrap(r), values, functions, coulomb) for r in found]
        points.sort(key=lambda e: (e.potential, e.q))
        index_sum = sum((-1) ** e.morse_index for e in points)
        if index_sum == 0 or n >= MAX_STARTS:
            break
        n = min(2 * n, MAX_STARTS)
    degenerate = [e for e in points
                  if np.min(np.abs(np.linalg.eigvalsh(e.K))) <= DEGENERATE * max(np.abs(np.linalg.eigvalsh(e.K)).max(), 1e-300)]
    if index_sum == 0 and not degenerate:
        status, message = Status.SUCCESS, (
            f"{len(points)} equilibria; their Morse indices sum to 0 as on the torus (none missed)" if points else
            "no equilibrium: the torques are not balanced by gravity anywhere")
    else:
        status, message = Status.PARTIAL, (
            f"{len(points)} equilibria found, but " + (
                f"{len(degenerate)} of them degenerate (K singular): the index check does not apply" if degenerate else
                f"their indices sum to {index_sum}, not 0: an equilibrium may be missed"))
    settings = {"starts": starts, "final_starts": n, "tau": tau.tolist()}
    note = coulomb_note(params, coulomb)
    if note:  # only where it matters (a model without friction keeps its fingerprint)
        settings["coulomb"] = coulomb
        message = f"{message}; {note}"
    stats = {"starts": total_starts, "converged": int(len(points)), "newton_iterations": int(total_its)}
    return Equilibria(points=points, params=params, settings=settings, stats=stats, status=status, message=message)


#: The most links whose 2^n up-down configurations seed the equilibria of a chain.
MAX_CHAIN_SEEDS = 12


def chain_equilibria(chain, *, coulomb: str = DEFAULT_COULOMB) -> Equilibria:
    """Every equilibrium of a chain of links on the n-torus: Newton's method on ``grad V = tau`` (``V`` the
    potential energy from the recursive algorithms, its gradient and Hessian exact by automatic
    differentiation) from each of the 2^n configurations with every relative angle 0 or pi, and from 64
    seeded random starts; the roots deduplicated and linearised as the double pendulum's
    (:class:`Equilibrium`, labels ``down``/``up``/``level`` per link).  The check that none is missed is
    the same: on the n-torus the Morse indices sum to 0, ``sum (-1)^index = 0``."""
    from scipy.linalg import eigh

    from ..numeric.recursive import potential_terms

    coulomb = check_coulomb(coulomb)
    n = chain.n
    if n > MAX_CHAIN_SEEDS:
        raise ParameterError(f"equilibria of a chain seed Newton's method at its 2^n up-down configurations: at most "
                             f"{MAX_CHAIN_SEEDS} links, this chain has {n}")
    terms = potential_terms(chain)
    tau = np.array([link.torque for link in chain.links], dtype=float)
    rng = np.random.default_rng(0)
    seeds = [np.array([(k >> i) & 1 for i in range(n)], dtype=float) * np.pi for k in range(2 ** n)]
    seeds += list(rng.uniform(-np.pi, np.pi, (64, n)))
    gscale = max(max(np.abs(terms(q)[1]).max() for q in seeds[:: max(1, len(seeds) // 32)]), np.abs(tau).max())
    if not gscale > 0:
        raise EquilibriumError("every configuration is an equilibrium without gravity and torques (g = 0, tau = 0); "
                               "equilibria need g > 0 or a torque")
    found: List[np.ndarray] = []
    its_total = 0
    for q0 in seeds:
        q = np.array(q0, dtype=float)
        for its in range(60):
            _, g, H, _, _ = terms(q)
            r = g - tau
            try:
                d = -np.linalg.solve(H, r)
            except np.linalg.LinAlgError:
                break
            step = float(np.max(np.abs(d)))
            q = wrap(q + d * min(1.0, 0.5 / max(step, 1e-300)))
            its_total += 1
            if step < 1e-13 * (1 + np.pi) and np.max(np.abs(r)) <= RESIDUAL * gscale:
                if all(np.max(np.abs(wrap(q - f))) > SAME_ROOT for f in found):
                    found.append(q)
                break
    c = np.diag([link.damping + (link.coulomb * chain.cfs if coulomb == "smoothed" else 0.0) for link in chain.links])
    points = []
    for q in found:
        Pi, _, H, M, down = terms(q)
        K = 0.5 * (H + H.T)
        lam, V = eigh(K, M)
        points.append(linear_point(q, down, Pi - float(tau @ q) + 0.0, M, c, K, lam, V, coulomb))
    points.sort(key=lambda e: (e.potential, e.q))
    index_sum = sum((-1) ** e.morse_index for e in points)
    degenerate = [e for e in points
                  if np.min(np.abs(np.linalg.eigvalsh(e.K))) <= DEGENERATE * max(np.abs(np.linalg.eigvalsh(e.K)).max(), 1e-300)]
    if index_sum == 0 and not degenerate:
        status, message = Status.SUCCESS, (f"{len(points)} equilibria; their Morse indices sum to 0 as on the "
                                           f"{n}-torus (none missed)")
    else:
        status, message = Status.PARTIAL, (f"{len(points)} equilibria found, but " + (
            f"{len(degenerate)} of them degenerate (K singular): the index check does not apply" if degenerate else
            f"their indices sum to {index_sum}, not 0: an equilibrium may be missed"))
    settings = {"seeds": len(seeds), "tau": tau.tolist()}
    if chain.has_friction:
        settings["coulomb"] = coulomb
    stats = {"starts": len(seeds), "converged": len(points), "newton_iterations": its_total}
    return Equilibria(points=points, params=chain, settings=settings, stats=stats, status=status, message=message)


def equilibrium_at(params: Parameters, q: Sequence[float], name: str = "q", *, coulomb: str = DEFAULT_COULOMB) -> Equilibrium:
    """The equilibrium at ``q = (phi, psi)`` (angles reduced modulo 2 pi, :func:`skewpend.checks.angles`:
    at most 1e6 rad in magnitude), polished by Newton's method from there; refused with one line
    when ``q`` is not near an equilibrium (the residual names how far).  ``name``: the
    argument's name in a refusal; ``coulomb`` as for :func:`equilibria`."""
    from ..checks import angles, numeric_params

    params = numeric_params(params, "an equilibrium")
    coulomb = check_coulomb(coulomb)
    q0 = np.array(angles(name, q, 2), dtype=float).reshape(1, 2)
    values = _scalars(params)
    functions = linearisation_functions(_geometry_only(params))
    tau = np.array([params.tau1, params.tau2], dtype=float)

    def grad_hess(qq):
        _, g, H, _, _ = functions(*values, qq[:, 0], qq[:, 1])
        n = len(qq)
        g = np.stack([np.broadcast_to(np.asarray(x, dtype=float), (n,)) for x in g], axis=1)
        H = np.array([[np.broadcast_to(np.asarray(x, dtype=float), (n,)) for x in row] for row in H]).transpose(2, 0, 1)
        return g, H

    gscale = _gradient_scale(grad_hess, tau)
    g0, _ = grad_hess(q0.copy())
    root, conv, _ = _newton(grad_hess, q0.copy(), tau, iterations=30, gscale=gscale)
    moved = float(np.max(np.abs(wrap(root[0] - q0[0]))))
    if not conv[0] or moved > NEAR:
        residual = float(np.max(np.abs(g0[0] - tau)))
        raise EquilibriumError(
            f"(phi, psi) = ({q0[0, 0]:.6g}, {q0[0, 1]:.6g}) rad is not an equilibrium: dV/dq = {residual:.3g} N m there; "
            "choose one of skewpend.equilibria(params)")
    return _linearise(params, wrap(root[0]), values, functions, coulomb)


def find_equilibrium(params: Parameters, which, name: str = "equilibrium", *, coulomb: str = DEFAULT_COULOMB) -> Equilibrium:
    """An equilibrium given as an :class:`Equilibrium`, a label (``"up-up"``: one of
    :func:`equilibria`'s) or angles ``(phi, psi)`` near one (:func:`equilibrium_at`; reduced
    modulo 2 pi, refused beyond 1e6 rad); ``name`` is the argument's name in the refusal.  Its
    linearisation treats Coulomb friction as ``coulomb`` says (an :class:`Equilibrium` made with
    the other choice is linearised again)."""
    from ..checks import numeric_params

    params = numeric_params(params, "an equilibrium")
    coulomb = check_coulomb(coulomb)
    if isinstance(which, Equilibrium):
        if which.coulomb == coulomb or not friction_terms(params):
            return which
        return equilibrium_at(params, which.q, name, coulomb=coulomb)
    if isinstance(which, str):
        return equilibria(params, coulomb=coulomb).find(which)
    if which is None or isinstance(which, (bytes, dict, set)):
        raise ParameterError(f"{name} must be an equilibrium, a label such as 'up-up', or (phi, psi), got {which!r}")
    return equilibrium_at(params, which, name, coulomb=coulomb)
