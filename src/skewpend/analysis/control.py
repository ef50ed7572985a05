"""Balance it and swing it up: linearisation with inputs, controllability, LQR, swing-up.

* :func:`linearization` -- ``x' = A x + B u`` about any equilibrium (:func:`skewpend.equilibria`),
  ``B`` for the actuated joints: ``"both"``, ``"acrobot"`` (the elbow only) or ``"pendubot"``
  (the shoulder only);
* :func:`controllability` -- the rank of ``[B, AB, A^2 B, A^3 B]`` and how close the pair is to
  uncontrollable: the smallest singular value of ``[A - lambda I, B]`` over the eigenvalues
  ``lambda`` of ``A`` (the Popov-Belevitch-Hautus test, as a distance);
* :func:`lqr` -- the gain ``K``, the Riccati solution ``P`` (SciPy's ``solve_continuous_are``),
  the closed-loop eigenvalues, and an inner estimate of the region of attraction with the torque
  limits: the largest level ``rho`` of ``V = dx^T P dx`` on whose sublevel set ``V' < 0`` for
  the nonlinear closed loop with saturation (checked on samples);
* :func:`swingup` -- energy shaping from hanging towards the target's energy, switched to the LQR
  inside its region, simulated with the torque limit; the run, and when it was captured.

The inputs act inside the compiled integrators (:mod:`skewpend.numeric.control`).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any, Dict, Optional, Sequence, Tuple

import numpy as np

from ..checks import numeric_params
from ..errors import EquilibriumError, ParameterError
from ..symbolic.model import Parameters

__all__ = ["Linearization", "linearization", "controllability", "LQR", "lqr", "SwingUp", "swingup"]


def _columns(actuated: str) -> Tuple[int, ...]:
    from ..numeric.control import ACTUATION

    if actuated not in ACTUATION:
        raise ParameterError(f"actuated must be one of {', '.join(ACTUATION)} (acrobot: the elbow only, pendubot: "
                             f"the shoulder only), got {actuated!r}")
    code = ACTUATION[actuated]
    return tuple(j for j in range(2) if code & (1 << j))


@dataclass(frozen=True)
class Linearization:
    """``d/dt dx = A dx + B du`` about ``equilibrium`` (its state ``x*``); ``actuated`` and the
    joints ``B``'s columns drive (0: the shoulder, 1: the elbow)."""

    A: np.ndarray
    B: np.ndarray
    equilibrium: Any = field(repr=False)
    actuated: str = "both"
    joints: Tuple[int, ...] = (0, 1)

    @property
    def target(self) -> np.ndarray:
        return self.equilibrium.state


def linearization(params: Parameters, equilibrium="up-up", actuated: str = "both") -> Linearization:
    """The state-space linearisation about an equilibrium (a label, an ``Equilibrium`` or
    ``(phi, psi)`` near one) with the input matrix of the actuated joints:
    ``B = [0; M^-1 S]``, ``S`` the columns of the actuated joints."""
    params = numeric_params(params, "a linearisation")
    joints = _columns(actuated)
    from .equilibria import find_equilibrium

    eq = find_equilibrium(params, equilibrium)
    S = np.eye(2)[:, list(joints)]
    B = np.vstack([np.zeros((2, len(joints))), np.linalg.solve(eq.M, S)])
    return Linearization(eq.A.copy(), B, eq, actuated, joints)


def controllability(A: np.ndarray, B: np.ndarray) -> Dict[str, Any]:
    """``rank`` of ``[B, AB, A^2 B, A^3 B]`` (numerical, SVD), its singular values, and
    ``distance`` -- the smallest singular value of ``[A - lambda I, B]`` over the eigenvalues of
    ``A``, relative to ``max(|A|, |B|)``: 0 exactly when the pair is uncontrollable (PBH)."""
    n = A.shape[0]
    blocks = [B]
    for _ in range(n - 1):
        blocks.append(A @ blocks[-1])
    C = np.hstack(blocks)
    sv = np.linalg.svd(C, compute_uv=False)
    tol = max(C.shape) * np.finfo(float).eps * (sv[0] if sv.size else 0.0)
    rank = int(np.sum(sv > tol))
    scale = max(np.abs(A).max(), np.abs(B).max(), 1e-300)
    dist = math.inf
    for lam in np.linalg.eigvals(A):
        M = np.hstack([A - lam * np.eye(n), B.astype(complex)])
        dist = min(dist, float(np.linalg.svd(M, compute_uv=False)[-1]))
    return {"rank": rank, "singular_values": sv, "distance": dist / scale, "controllable": rank == n}


@dataclass(frozen=True)
class LQR:
    """The infinite-horizon LQR of a :class:`Linearization`: ``du = -K dx`` minimises
    ``integral dx^T Q dx + du^T R du``; ``P`` solves the Riccati equation, ``eigenvalues`` are
    those of ``A - B K``; ``rho`` -- the inner estimate of the region of attraction
    ``dx^T P dx < rho`` (with the torque limit ``umax``); ``controller()`` builds the feedback
    for :func:`skewpend.simulate`."""

    K: np.ndarray
    P: np.ndarray
    eigenvalues: np.ndarray
    linearization: Linearization = field(repr=False)
    Q: np.ndarray = field(repr=False, default=None)
    R: np.ndarray = field(repr=False, default=None)
    rho: float = math.inf
    umax: Tuple[float, float] = (math.inf, math.inf)
    params: Any = field(repr=False, default=None)

    @property
    def gain(self) -> np.ndarray:
        """``K`` as a 2 x 4 matrix (a row of zeros for a joint without a motor)."""
        G = np.zeros((2, 4))
        for row, j in enumerate(self.linearization.joints):
            G[j] = self.K[row]
        return G

    def controller(self, umax=None):
        from ..numeric.control import Controller

        lin = self.linearization
        return Controller.feedback(self.gain, lin.target, _u_target(self.params, lin), actuated=lin.actuated,
                                   umax=self.umax if umax is None else umax)

    def inside(self, x) -> np.ndarray:
        """Whether states ``x`` (..., 4) lie inside the estimate ``dx^T P dx < rho`` (angles wrapped)."""
        dx = _deviation(np.asarray(x, dtype=float), self.linearization.target)
        return np.einsum("...i,ij,...j->...", dx, self.P, dx) < self.rho


def _u_target(params: Parameters, lin: Linearization) -> np.ndarray:
    # the equilibrium holds with the constant torques of params; the inputs add nothing there
    return np.zeros(2)


def _deviation(x: np.ndarray, target: np.ndarray) -> np.ndarray:
    from .equilibria import wrap

    dx = x - target
    dx[..., :2] = wrap(dx[..., :2])
    return dx


def _rho_estimate(params: Parameters, lin: Linearization, K2: np.ndarray, P: np.ndarray, umax, samples: int = 20000,
                  seed: int = 0) -> float:
    """The largest rho such that V = dx^T P dx decreases along the saturated nonlinear closed loop
    at every sample with V < rho (samples on ellipsoid shells; the compiled right-hand side)."""
    from ..numeric.control import Controller
    from ..numeric.kernels import kernel_module, parameter_vector

    kernel = kernel_module(params)
    p = parameter_vector(params)
    ctl = Controller.feedback(K2, lin.target, np.zeros(2), actuated=lin.actuated, umax=umax)
    rng = np.random.default_rng(seed)
    # directions uniform on the unit sphere of the P-norm
    L = np.linalg.cholesky(P)
    z = rng.normal(size=(samples, 4))
    z /= np.linalg.norm(z, axis=1, keepdims=True)
    d = np.linalg.solve(L.T, z.T).T  # d^T P d = 1
    radii = rng.uniform(0, 1, samples) ** 0.25  # uniform in the 4-ball
    t = np.zeros(samples)

    def decreasing(rho: float) -> bool:
        dx = d * math.sqrt(rho) * radii[:, None]
        xdot = ctl.closed_loop(kernel, p, t, lin.target + dx)
        return bool(np.all(2.0 * np.einsum("ki,ij,kj->k", dx, P, xdot) < 0))

    # bisection on log(rho) between a level that passes and one that fails
    lo, hi = -8.0, 8.0
    if not decreasing(10 ** lo):
        return 0.0
    if decreasing(10 ** hi):
        return float(10 ** hi)
    for _ in range(24):
        mid = 0.5 * (lo + hi)
        if decreasing(10 ** mid):
            lo = mid
        else:
            hi = mid
    return float(10 ** lo)


def lqr(params: Parameters, equilibrium="up-up", actuated: str = "both", Q=None, R=None, *, umax=None,
        estimate: bool = True) -> LQR:
    """The LQR about ``equilibrium`` with the ``actuated`` joints (see the module).

    ``Q`` (4 x 4, default identity) and ``R`` (m x m, default identity) must be symmetric,
    ``Q`` positive semi-definite and ``R`` positive definite; refused with one line: an
    uncontrollable pair (the PBH distance in the message), a non-finite solution.  ``umax``:
    torque limits for the region estimate (``estimate=False`` skips it)."""
    from scipy.linalg import solve_continuous_are

    from ..numeric.control import torque_limits

    params = numeric_params(params, "an LQR")
    lin = linearization(params, equilibrium, actuated)
    m = lin.B.shape[1]
    Qm = np.eye(4) if Q is None else np.asarray(Q, dtype=float)
    Rm = np.eye(m) if R is None else np.atleast_2d(np.asarray(R, dtype=float))
    if Qm.shape != (4, 4) or not np.all(np.isfinite(Qm)) or not np.allclose(Qm, Qm.T) or np.linalg.eigvalsh(Qm).min() < -1e-12:
        raise ParameterError("Q must be a finite, symmetric, positive semi-definite 4 x 4 matrix")
    if Rm.shape != (m, m) or not np.all(np.isfinite(Rm)) or not np.allclose(Rm, Rm.T) or np.linalg.eigvalsh(Rm).min() <= 0:
        raise ParameterError(f"R must be a finite, symmetric, positive definite {m} x {m} matrix")
    ctrb = controllability(lin.A, lin.B)
    if not ctrb["controllable"] or ctrb["distance"] < 1e-10:
        raise EquilibriumError(
            f"the {actuated} is not controllable at {lin.equilibrium.label} for these parameters (rank {ctrb['rank']} of 4, "
            f"PBH distance {ctrb['distance']:.2e}): no linear feedback can stabilise it")
    try:
        P = solve_continuous_are(lin.A, lin.B, Qm, Rm)
    except (np.linalg.LinAlgError, ValueError) as exc:
        raise EquilibriumError(f"the Riccati equation has no stabilising solution here: {exc}") from None
    K = np.linalg.solve(Rm, lin.B.T @ P)
    if not (np.all(np.isfinite(P)) and np.all(np.isfinite(K))):
        raise EquilibriumError("the Riccati solution is not finite (extreme parameters or weights)")
    eig = np.linalg.eigvals(lin.A - lin.B @ K)
    eig = eig[np.argsort(-eig.real)]
    limits = torque_limits(umax)
    result = LQR(K, P, eig, lin, Qm, Rm, math.inf, limits, params)
    if estimate:
        rho = _rho_estimate(params, lin, result.gain, P, limits)
        result = LQR(K, P, eig, lin, Qm, Rm, rho, limits, params)
    return result


@dataclass(frozen=True)
class SwingUp:
    """A swing-up run: ``trajectory`` (with ``inputs()``), whether and when the target's region
    was entered for good (``captured``, ``capture_time`` [s]), the ``lqr`` used and the
    ``controller``."""

    trajectory: Any
    captured: bool
    capture_time: float
    lqr: LQR
    controller: Any

    @property
    def ok(self) -> bool:
        return bool(self.captured)

    @property
    def message(self) -> str:
        if self.captured:
            return f"captured by the LQR at t = {self.capture_time:.4g} s and held to the end"
        return "not captured: the motion never stayed in the LQR's region (raise the torque limit, the energy gain or t_end)"


def swingup(params: Parameters, target="up-up", actuated: str = "both", *, umax=10.0, energy_gain: float = 2.0,
            elbow_gains=(20.0, 4.0), t_end: float = 20.0, y0: Optional[Sequence[float]] = None, Q=None, R=None,
            dt_out: float = 0.01) -> SwingUp:
    """Swing the pendulum up from ``y0`` (default: hanging, nudged by 0.05 rad) to ``target`` with
    the torque limit ``umax`` [N m]: energy shaping towards the target's potential energy, the LQR
    inside its region of attraction estimate; simulated over ``t_end``."""
    from ..numeric.control import Controller
    from ..numeric.simulation import simulate

    params = numeric_params(params, "a swing-up")
    design = lqr(params, target, actuated, Q, R, umax=umax)
    if not (design.rho > 0):
        raise EquilibriumError("the LQR's region of attraction estimate is empty with this torque limit: raise umax")
    lin = design.linearization
    ctl = Controller.swingup(energy_gain, lin.equilibrium.potential, design.gain, lin.target, design.P, design.rho,
                             elbow_gains=elbow_gains, actuated=actuated, umax=umax)
    start = np.array([0.05, 0.0, 0.0, 0.0]) if y0 is None else np.asarray(y0, dtype=float)
    tr = simulate(params, start, t_end, dt_out=dt_out, controller=ctl)
    inside = design.inside(tr.y)
    if inside[-1]:
        k = len(inside) - 1
        while k > 0 and inside[k - 1]:
            k -= 1
        captured, when = True, float(tr.t[k])
    else:
        captured, when = False, math.nan
    return SwingUp(tr, captured, when, design, ctl)
