"""Balance it and swing it up: linearisation with inputs, controllability, LQR, swing-up.

* :func:`linearization` -- ``x' = A x + B u`` about any equilibrium (:func:`skewpend.equilibria`),
  any model, ``B`` for the actuated joints: ``"both"`` (every joint), the joints' numbers, or for two links
  ``"acrobot"`` (the elbow only) or ``"pendubot"`` (the shoulder only);
* :func:`controllability` -- the rank of ``[B, AB, A^2 B, A^3 B]`` and how close the pair is to
  uncontrollable: the smallest singular value of ``[A - lambda I, B]`` over the eigenvalues
  ``lambda`` of ``A`` (the Popov-Belevitch-Hautus test, as a distance);
* :func:`lqr` -- the gain ``K``, the Riccati solution ``P`` (SciPy's ``solve_continuous_are``),
  the closed-loop eigenvalues, and an inner estimate of the region of attraction with the torque
  limits: a level ``rho`` of ``V = dx^T P dx`` below which ``V' < 0`` for the nonlinear closed
  loop with saturation -- :data:`RHO_MARGIN` (0.95) times the smallest ``V`` at which a seeded
  search (rays bisected to their first crossing, samples in the ball, SLSQP minimising ``V``
  subject to ``V'/V >= 0``) finds ``V' >= 0``, at most where the ellipsoid reaches an angle error
  of pi.  A search, not a proof: a growing region thinner than it resolves could remain;
* :func:`swingup` -- energy shaping from hanging towards the target's energy, switched to the LQR
  inside its region, simulated with the torque limit (any model); the run, and when it was captured.

The inputs act inside the compiled integrators (:mod:`skewpend.numeric.control`).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field, replace
from typing import Any, Callable, Dict, Optional, Sequence, Tuple

import numpy as np

from ..checks import angles, numeric_model
from ..errors import EquilibriumError, ParameterError

__all__ = ["Linearization", "linearization", "controllability", "LQR", "lqr", "SwingUp", "swingup", "capture"]


class EveryLinkUp(str):
    """The default equilibrium, spelled ``"up-up"``: every link up, whatever the number of links (a chain of three:
    ``"up-up-up"``).  Only this default reads so: a ``"up-up"`` given for a chain of three is refused."""

    __slots__ = ()


#: The equilibrium when none is given (see :class:`EveryLinkUp`).
EVERY_LINK_UP = EveryLinkUp("up-up")


@dataclass(frozen=True)
class Linearization:
    """``d/dt dx = A dx + B du`` about ``equilibrium`` (its state ``x*``); ``actuated``: the two-link robot's
    word as given (both, all, acrobot, pendubot), else the joints' numbers; ``joints``: those ``B``'s columns
    drive (0-based: 0 the shoulder); ``coulomb``: how Coulomb friction entered ``A`` (``"smoothed"``, the
    control default: its smoothed slope ``cfs cf`` as viscous damping; ``"exclude"``: not at all),
    ``coulomb_note`` says it."""

    A: np.ndarray
    B: np.ndarray
    equilibrium: Any = field(repr=False)
    actuated: Any = "both"
    joints: Tuple[int, ...] = (0, 1)
    coulomb: str = "smoothed"
    params: Any = field(repr=False, default=None)

    @property
    def target(self) -> np.ndarray:
        return self.equilibrium.state

    @property
    def coulomb_note(self) -> str:
        """How the Coulomb friction was treated, one line ('' for a model without it)."""
        from ..symbolic.friction import coulomb_note

        return "" if self.params is None else coulomb_note(self.params, self.coulomb)


def linearization(params, equilibrium=EVERY_LINK_UP, actuated="both", *, coulomb: str = "smoothed") -> Linearization:
    """The state-space linearisation about an equilibrium (a label, an ``Equilibrium`` or
    angles near one, ``(phi, psi)`` for the double pendulum) with the input matrix of the actuated joints:
    ``B = [0; M^-1 S]``, ``S`` the columns of the actuated joints.

    Coulomb friction: unlike the modes and the equilibria (which leave it out, as non-smooth at
    rest), a controller's linearisation takes the smoothed slope ``cfs cf`` by default
    (``coulomb="smoothed"``): the LQR's region of attraction is certified on the model that is
    simulated, whose friction *is* the smooth ``cf atan(cfs q')``, and a design that leaves its
    slope out gives a ``V = dx^T P dx`` that grows arbitrarily close to the target there (no
    region).  ``coulomb="exclude"`` leaves it out; ``coulomb_note`` says which was done.

    Any model (the double pendulum, a chain of ``n`` links): ``equilibrium`` a label with a word per link
    (``"up-up-up"``; the default, :data:`EVERY_LINK_UP`, every link up), an ``Equilibrium`` or angles near one;
    ``actuated`` ``"both"`` or ``"all"`` (every joint), the numbers of the joints with a motor (``(2,)``,
    ``(1, 3)``) or, for two links, ``"acrobot"`` / ``"pendubot"`` (:func:`skewpend.numeric.control.actuated_joints`)."""
    from ..numeric.control import ROBOT_LINKS, ROBOTS, actuated_joints
    from ..symbolic.friction import check_coulomb
    from .equilibria import find_equilibrium

    model = numeric_model(params, "a linearisation")
    n = model.n
    joints = tuple(j - 1 for j in actuated_joints(actuated, n))
    coulomb = check_coulomb(coulomb)
    eq = find_equilibrium(model, equilibrium_argument(equilibrium, model), "equilibrium", coulomb=coulomb)
    B = np.vstack([np.zeros((n, len(joints))), np.linalg.solve(eq.M, np.eye(n)[:, list(joints)])])
    named = isinstance(actuated, str) and (actuated in ROBOTS or n == ROBOT_LINKS)  # the two-link robot's words
    given = actuated if named else tuple(j + 1 for j in joints)
    return Linearization(eq.A.copy(), B, eq, given, joints, coulomb, model)


def equilibrium_argument(which, model, name: str = "equilibrium"):
    """An equilibrium as given for ``model``: :data:`EVERY_LINK_UP` (the default) every link up; a label with a
    word per link (``"up-up"`` names two links, so a chain of three refuses it rather than reading it as
    ``"up-up-up"``); an ``Equilibrium``; angles near one, reduced modulo 2 pi (:func:`skewpend.checks.angles`:
    refused beyond 1e6 rad, where the reduction loses its digits)."""
    from .equilibria import Equilibrium

    n, up = model.n, "-".join(["up"] * model.n)
    if which is EVERY_LINK_UP:
        return up
    if isinstance(which, str):
        words = len(which.split("-"))
        if words != n:
            raise ParameterError(f"{name} {which!r} names {words} link{'s' if words != 1 else ''}; {model.title} has "
                                 f"{n}: give a word per link, e.g. {up}")
        return which
    if isinstance(which, Equilibrium):
        return which
    if not hasattr(which, "__len__"):
        raise ParameterError(f"{name} must be an equilibrium, a label such as '{up}', or angles "
                             f"({', '.join(model.coordinates)}) near one, got {which!r}")
    return angles(name, which, n)


def hanging_rest(model) -> np.ndarray:
    """The model's hanging rest as a state (its angles, then zero speeds): the equilibrium whose every link's
    centre of mass is below its hinge, ``"down-...-down"`` (labels from the geometry,
    :func:`~skewpend.analysis.equilibria.link_directions`), wherever the model's zero is -- ``q = 0`` for the
    double pendulum and skewpend's chains (returned as exact zeros), ``(pi, 0)`` for the DeepMind Control
    Suite's acrobot, whose zero is upright; a little off 0 for a fitted model whose centres of mass lie off the
    rods' lines.  Newton's method from ``q = 0`` first (one linearisation), the equilibria's search only where
    that lands elsewhere; one :class:`~skewpend.errors.EquilibriumError` line where the model has no such rest."""
    from .equilibria import equilibrium_at, find_equilibrium

    n = model.n
    label = "-".join(["down"] * n)
    try:
        near = equilibrium_at(model, np.zeros(n))
    except EquilibriumError:
        near = None
    if near is not None and near.label == label:
        eq = near
    else:
        try:
            eq = find_equilibrium(model, label, "the hanging rest")
        except (EquilibriumError, ParameterError) as exc:
            raise EquilibriumError(f"the model has no hanging rest ({label}) to start from: {exc}; give the start") from None
    q = np.asarray(eq.q, dtype=float)
    if np.max(np.abs(q)) <= 1e-12:
        q = np.zeros(n)  # the model's zero hangs: exactly it (the runs from q = 0 unchanged to the bit)
    return np.r_[q, np.zeros(n)]


def _matrix(name: str, value, shape: Optional[Tuple[int, ...]] = None, ndim: int = 2) -> np.ndarray:
    """``value`` (a sequence of numbers, an array, NumPy scalars) as a finite float array of
    ``ndim`` dimensions (and ``shape``), else one :class:`ParameterError` naming ``name``."""
    what = ("x".join(str(k) for k in shape) + " " if shape else "") + ("matrix" if ndim == 2 else "vector")
    try:
        a = np.array(value, dtype=float)
    except (TypeError, ValueError, OverflowError):
        a = None
    if a is None or a.ndim != ndim or (shape is not None and a.shape != shape) or a.size == 0:
        got = f"shape {a.shape}" if a is not None else repr(value) if isinstance(value, str) else type(value).__name__
        raise ParameterError(f"{name} must be a {what} of real numbers (a nested sequence or an array), got {got}")
    if not np.all(np.isfinite(a)):
        raise ParameterError(f"{name} must hold finite numbers")
    return a


def controllability(A: np.ndarray, B: np.ndarray) -> Dict[str, Any]:
    """``rank`` of ``[B, AB, A^2 B, A^3 B]`` (numerical, SVD), its singular values, and
    ``distance`` -- the smallest singular value of ``[A - lambda I, B]`` over the eigenvalues of
    ``A``, relative to ``max(|A|, |B|)``: 0 exactly when the pair is uncontrollable (PBH).
    ``A`` (n x n) and ``B`` (n x m): arrays or nested sequences of finite numbers."""
    A = _matrix("A", A)
    n = A.shape[0]
    if A.shape != (n, n):
        raise ParameterError(f"A must be a square matrix, got shape {A.shape}")
    try:
        one_input = np.ndim(B) == 1
    except ValueError:  # ragged
        one_input = False
    B = _matrix("B", B, ndim=1 if one_input else 2)
    if B.ndim == 1:
        B = B[:, None]  # one input
    if B.shape[0] != n:
        raise ParameterError(f"B must have as many rows as A ({n}), got shape {B.shape}")
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
    umax: Tuple[float, ...] = (math.inf, math.inf)
    params: Any = field(repr=False, default=None)

    @property
    def gain(self) -> np.ndarray:
        """``K`` as a 2 x 4 matrix (a chain's: n x 2 n; a row of zeros for a joint without a motor)."""
        n2 = self.linearization.A.shape[0]
        G = np.zeros((n2 // 2, n2))
        G[list(self.linearization.joints)] = self.K
        return G

    def controller(self, umax=None):
        from ..numeric.control import Controller

        lin = self.linearization
        return Controller.feedback(self.gain, lin.target, actuated=lin.actuated, umax=self.umax if umax is None else umax)

    def inside(self, x) -> np.ndarray:
        """Whether states ``x`` (..., 4; a chain's ..., 2 n) lie inside the estimate ``dx^T P dx < rho`` (angles wrapped)."""
        from .equilibria import wrap

        dx = np.asarray(x, dtype=float) - self.linearization.target
        n = dx.shape[-1] // 2
        dx[..., :n] = wrap(dx[..., :n])
        return np.einsum("...i,ij,...j->...", dx, self.P, dx) < self.rho


#: rho is this fraction of the smallest level V at which the search found V' >= 0 (see _rho_estimate).
RHO_MARGIN = 0.95
#: The search: rays through the ellipsoids (each bisected to its first crossing), radii per ray,
#: random samples in the ball, and local minimisations from the best crossings found.
RHO_RAYS, RHO_RADII, RHO_SAMPLES, RHO_STARTS = 2048, 40, 20000, 24


def _rho_estimate(params, lin: Linearization, K2: np.ndarray, P: np.ndarray, umax, samples: int = RHO_SAMPLES,
                  seed: int = 0) -> float:
    """The region estimate ``rho`` (see :func:`lqr`): :data:`RHO_MARGIN` times the smallest level
    ``V = dx^T P dx`` at which a seeded search finds ``V' = 2 dx^T P f(x) >= 0`` for the saturated
    nonlinear closed loop (the compiled right-hand side), and at most the level where the
    ellipsoid reaches an angle error of pi (beyond it the wrapped law jumps).  The search: the
    first crossing along :data:`RHO_RAYS` rays (a grid of radii, then bisection), ``samples``
    points uniform in the ball, then SLSQP (minimise V subject to V' >= 0) from the
    :data:`RHO_STARTS` best crossings, each result moved to its ray's first crossing.  0 when
    ``P`` is not positive definite (V is no Lyapunov function then)."""
    from scipy.optimize import minimize

    w = np.linalg.eigvalsh(P)
    if not (w[0] > 1e-12 * w[-1] > 0):
        return 0.0
    from ..numeric.control import Controller
    from ..numeric.kernels import model_kernel, model_vector

    target = lin.target
    n2 = P.shape[0]
    ctl = Controller.feedback(K2, lin.target, actuated=lin.actuated, umax=umax)
    rhs = ctl.closed_loop_function(model_kernel(params), model_vector(params))
    Pinv = np.linalg.inv(P)
    ceiling = math.pi ** 2 / max(Pinv[i, i] for i in range(n2 // 2))  # the ellipsoid's angle errors reach pi there
    L = np.linalg.cholesky(P)
    rng = np.random.default_rng(seed)

    def vdot(dx: np.ndarray) -> np.ndarray:
        dx = np.atleast_2d(dx)
        with np.errstate(all="ignore"):
            return 2.0 * np.einsum("ki,ij,kj->k", dx, P, rhs(target + dx))

    def unit(z: np.ndarray) -> np.ndarray:  # directions with d^T P d = 1
        z = z / np.linalg.norm(z, axis=-1, keepdims=True)
        return np.linalg.solve(L.T, z.T).T

    def first_crossing(d: np.ndarray, search: bool = False):
        """Per ray d (d^T P d = 1): the smallest radius s with V'(s d) >= 0 (V = s^2), inf if none
        below the ceiling; with ``search`` also the point of each ray nearest to growing (the largest
        V'/V before its crossing) and that ratio."""
        top = math.sqrt(ceiling)
        radii = top * np.geomspace(1e-4, 1.0, RHO_RADII)
        vd = vdot((d[:, None, :] * radii[None, :, None]).reshape(-1, n2)).reshape(len(d), RHO_RADII)
        bad = ~(vd < 0)  # NaN counts as growing
        hit = bad.any(axis=1)
        k = np.argmax(bad, axis=1)
        lo = np.where(k > 0, radii[np.maximum(k - 1, 0)], 0.0)
        hi = radii[k]
        for _ in range(40):
            mid = 0.5 * (lo + hi)
            up = ~(vdot(d * mid[:, None]) < 0)
            hi = np.where(up, mid, hi)
            lo = np.where(up, lo, mid)
        crossing = np.where(hit, hi, math.inf)
        if not search:
            return crossing
        ratio = np.where(radii[None, :] < crossing[:, None], vd / radii[None, :] ** 2, -np.inf)
        j = np.argmax(ratio, axis=1)
        return crossing, d * radii[j][:, None], ratio[np.arange(len(d)), j]

    d = unit(rng.normal(size=(RHO_RAYS, n2)))
    s, near, ratio = first_crossing(d, search=True)
    best = [float(v) ** 2 for v in s[np.isfinite(s)]]
    # points uniform in the ball V < ceiling
    x = unit(rng.normal(size=(samples, n2))) * (math.sqrt(ceiling) * rng.uniform(0, 1, samples) ** (1.0 / n2))[:, None]
    grow = ~(vdot(x) < 0)
    vx = np.einsum("ki,ij,kj->k", x, P, x)
    best += [float(v) for v in vx[grow]]
    # starts of the local search: the earliest crossings, the points nearest to growing, the samples that grow
    third = max(1, RHO_STARTS // 3)
    candidates = [d[i] * s[i] for i in np.argsort(s)[:third] if np.isfinite(s[i])]
    candidates += [near[i] for i in np.argsort(-ratio)[:third] if np.isfinite(ratio[i])]
    candidates += [x[i] for i in np.flatnonzero(grow)[np.argsort(vx[grow])][:third]]

    # local search: minimise V subject to V' >= 0 from the best points found
    def growth(z: np.ndarray) -> np.ndarray:  # V'/V: scale-free, negative near the target (x = 0 is no minimiser)
        z = np.atleast_2d(z)
        return vdot(z) / np.einsum("ki,ij,kj->k", z, P, z)

    def constraint(z):
        return float(growth(z)[0])

    def constraint_gradient(z):  # central differences, one compiled call
        h = 1e-7 * max(1e-3, float(np.abs(z).max()))
        v = growth(np.vstack([z + h * np.eye(n2), z - h * np.eye(n2)]))
        return (v[:n2] - v[n2:]) / (2 * h)

    found = []
    for z0 in candidates:
        with np.errstate(all="ignore"):
            res = minimize(lambda z: float(z @ P @ z), z0, jac=lambda z: 2.0 * P @ z, method="SLSQP",
                           constraints=[{"type": "ineq", "fun": constraint, "jac": constraint_gradient}],
                           options={"maxiter": 60, "ftol": 1e-12})
        z = np.asarray(res.x, dtype=float)
        if np.all(np.isfinite(z)) and np.any(z != 0):
            found.append(z / math.sqrt(float(z @ P @ z)))
    if found:
        s2 = first_crossing(np.array(found))
        best += [float(v) ** 2 for v in s2[np.isfinite(s2)]]
    smallest = min(best, default=math.inf)
    return float(RHO_MARGIN * min(smallest, ceiling))


def check_weights(Q, R, m: int, n2: int = 4, *, q_name: str = "Q") -> Tuple[np.ndarray, np.ndarray]:
    """``Q`` (n2 x n2: 4 x 4, a chain's 2 n x 2 n; default identity) symmetric positive semi-definite and
    ``R`` (m x m, a number for one input; default identity) symmetric positive definite, else one ParameterError
    (``q_name``: the state weight's name in it)."""
    Qm = np.eye(n2) if Q is None else _matrix(q_name, Q, (n2, n2))
    if R is None:
        Rm = np.eye(m)
    else:
        try:
            scalar = np.ndim(R) == 0
        except ValueError:
            scalar = False
        Rm = _matrix("R", [[R]] if scalar else R, (m, m))
    scale = max(float(np.abs(Qm).max()), 1e-300)
    if not np.allclose(Qm, Qm.T, rtol=1e-12, atol=1e-12 * scale) or np.linalg.eigvalsh(Qm).min() < -1e-12 * scale:
        raise ParameterError(f"{q_name} must be a finite, symmetric, positive semi-definite {n2} x {n2} matrix")
    if not np.allclose(Rm, Rm.T, rtol=1e-12, atol=0) or not np.linalg.eigvalsh(Rm).min() > 0:
        raise ParameterError(f"R must be a finite, symmetric, positive definite {m} x {m} matrix")
    return Qm, Rm


def lqr(params, equilibrium=EVERY_LINK_UP, actuated="both", Q=None, R=None, *, umax=None,
        estimate: bool = True, coulomb: str = "smoothed") -> LQR:
    """The LQR of any model about ``equilibrium`` (a label, an ``Equilibrium`` or angles near one, reduced
    modulo 2 pi) with the ``actuated`` joints (see :func:`linearization`).

    ``Q`` (2 n x 2 n: the double pendulum's 4 x 4; default identity) and ``R`` (m x m, default identity; a number for one motor)
    must be symmetric, ``Q`` positive semi-definite and ``R`` positive definite.  A singular
    ``Q`` is accepted where the Riccati equation still has its unique stabilising solution and the
    closed loop is asymptotically stable, i.e. ``(A, Q^1/2)`` is detectable (at the top ``Q = 0``
    is: the LQR then only mirrors the unstable eigenvalues); otherwise one ParameterError.  A
    singular ``P`` gives no region estimate (``rho = 0``: ``V = dx^T P dx`` is no Lyapunov
    function).  Refused with one line too: an uncontrollable pair (the PBH distance in the
    message), a non-finite solution.  ``umax``: torque limits for the region estimate
    (``estimate=False`` skips it); ``rho`` is certified as the module says.  ``coulomb``: how the
    linearisation treats Coulomb friction (:func:`linearization`: by its smoothed slope by default;
    ``result.linearization.coulomb_note``)."""
    from scipy.linalg import solve_continuous_are

    from ..numeric.control import actuated_joints, actuation_text, torque_limits

    if not isinstance(estimate, (bool, np.bool_)):
        raise ParameterError(f"estimate must be True or False, got {estimate!r}")
    params = numeric_model(params, "an LQR")
    n = params.n
    joints = actuated_joints(actuated, n)
    Qm, Rm = check_weights(Q, R, len(joints), 2 * n)
    limits = torque_limits(umax, n)
    lin = linearization(params, equilibrium, actuated, coulomb=coulomb)
    ctrb = controllability(lin.A, lin.B)
    if not ctrb["controllable"] or ctrb["distance"] < 1e-10:
        raise EquilibriumError(
            f"{actuation_text(actuated, joints, params)} is not controllable at {lin.equilibrium.label} for these parameters (rank {ctrb['rank']} of "
            f"{lin.A.shape[0]}, PBH distance {ctrb['distance']:.2e}): no linear feedback can stabilise it")
    w = np.linalg.eigvalsh(Qm)
    singular_q = not (w[0] > 1e-12 * max(w[-1], 1e-300))
    undetectable = ParameterError(
        f"Q must make (A, Q^1/2) detectable at {lin.equilibrium.label}: this Q leaves a mode of the linearisation "
        "that does not decay unweighted, so the Riccati equation has no unique stabilising solution; weight every "
        "state (a positive definite Q)")
    try:
        with np.errstate(all="ignore"):
            P = solve_continuous_are(lin.A, lin.B, Qm, Rm)
    except (np.linalg.LinAlgError, ValueError) as exc:
        if singular_q:
            raise undetectable from None
        raise EquilibriumError(f"the Riccati equation has no stabilising solution here: {exc}") from None
    K = np.linalg.solve(Rm, lin.B.T @ P)
    if not (np.all(np.isfinite(P)) and np.all(np.isfinite(K))):
        raise EquilibriumError("the Riccati solution is not finite (extreme parameters or weights)")
    eig = np.linalg.eigvals(lin.A - lin.B @ K)
    eig = eig[np.argsort(-eig.real)]
    if not eig.real.max() < -1e-6 * max(float(np.abs(eig).max()), 1e-300):
        if singular_q:
            raise undetectable
        raise EquilibriumError("the Riccati solution does not stabilise the linearisation (extreme parameters or weights)")
    P = 0.5 * (P + P.T)
    result = LQR(K, P, eig, lin, Qm, Rm, math.inf, limits, params)
    return replace(result, rho=_rho_estimate(params, lin, result.gain, P, limits)) if estimate else result


@dataclass(frozen=True)
class SwingUp:
    """A swing-up run: ``trajectory`` (with ``inputs()``), whether and when the target's region
    was entered for good (``captured``, ``capture_time`` [s]), the ``lqr`` whose region that is and the
    ``controller``; ``law`` names what swung it up (``"energy shaping"``, :func:`swingup`'s; ``"model-predictive
    control"``, :func:`skewpend.analysis.mpc.mpc_swingup`'s); ``mpc`` the :class:`~skewpend.analysis.mpc.MPC`
    when one ran (its solve times and fallbacks)."""

    trajectory: Any
    captured: bool
    capture_time: float
    lqr: LQR
    controller: Any
    law: str = "energy shaping"
    mpc: Any = None

    @property
    def ok(self) -> bool:
        return bool(self.captured)

    @property
    def message(self) -> str:
        if not getattr(self.trajectory, "ok", True):
            return f"not captured: the run failed ({self.trajectory.message})"
        if self.captured:
            where = "by the LQR" if self.mpc is None else "in the LQR's region"
            return f"captured {where} at t = {self.capture_time:.4g} s and held to the end"
        what = "the energy gain" if self.mpc is None else "the MPC's horizon"
        return f"not captured: the motion never stayed in the LQR's region (raise the torque limit, {what} or t_end)"


#: The longest swing-up run [s]: a swing-up takes seconds; after the capture the run only holds the target.
SWINGUP_T_MAX = 3600.0


def swingup(params, target=EVERY_LINK_UP, actuated="both", *, umax=10.0, energy_gain: float = 2.0,
            elbow_gains=(20.0, 4.0), t_end: float = 20.0, y0: Optional[Sequence[float]] = None, Q=None, R=None,
            dt_out: float = 0.01, progress: Optional[Callable[[float, float], None]] = None) -> SwingUp:
    """Swing any model up from ``y0`` (default: its hanging rest, :func:`hanging_rest` -- ``q = 0`` for the
    double pendulum, ``(pi, 0)`` for the DeepMind acrobot whose zero is upright -- nudged by 0.05 rad at the
    first joint) to ``target`` (a label with a word per link, default every link up, or angles near an equilibrium, reduced modulo 2 pi)
    with the torque limit ``umax`` [N m]: energy shaping towards the target's potential energy (joints 2 ... n
    held in line by ``elbow_gains``), the LQR inside its region of attraction estimate; simulated over ``t_end`` (at most :data:`SWINGUP_T_MAX` s), the states
    every ``dt_out`` s.  ``progress(t, t_end)`` is called as the run advances (first with t = 0,
    before the LQR is designed).  Every argument is checked before any work."""
    from ..checks import positive, progress_callable
    from ..numeric.control import Controller, actuated_joints
    from ..numeric.simulation import simulate

    params = numeric_model(params, "a swing-up")
    n = params.n
    actuated_joints(actuated, n)
    target = equilibrium_argument(target, params, "target")
    t_end = positive("t_end", t_end, cap=SWINGUP_T_MAX)
    dt_out = positive("dt_out", dt_out, cap=t_end)
    if t_end / dt_out > 1e7:
        raise ParameterError(f"dt_out = {dt_out:g} s gives {t_end / dt_out:.3g} rows over t_end = {t_end:g} s; at most "
                             "1e7: use a larger dt_out")
    progress = progress_callable(progress, "progress(t, t_end)")
    # the law's own arguments, checked now rather than after the design
    Controller.swingup(energy_gain, 0.0, np.zeros((n, 2 * n)), np.zeros(2 * n), np.eye(2 * n), 0.0,
                       elbow_gains=elbow_gains, actuated=actuated, umax=umax)
    start = hanging_rest(params) + np.eye(1, 2 * n)[0] * 0.05 if y0 is None else _matrix("y0", y0, (2 * n,), ndim=1)
    angles("y0", start[:n], n)  # refused beyond 1e6 rad (the run keeps the angles as given)
    if progress is not None:
        progress(0.0, t_end)
    design = lqr(params, target, actuated, Q, R, umax=umax)
    if not (design.rho > 0):
        why = ("P is singular (Q leaves modes unweighted), so V = dx^T P dx bounds no region: weight every state in Q"
               if np.linalg.eigvalsh(design.P)[0] <= 1e-12 * np.linalg.eigvalsh(design.P)[-1] else "raise umax")
        raise EquilibriumError(f"the LQR's region of attraction estimate is empty: {why}")
    lin = design.linearization
    ctl = Controller.swingup(energy_gain, lin.equilibrium.potential, design.gain, lin.target, design.P, design.rho,
                             elbow_gains=elbow_gains, actuated=actuated, umax=umax)
    tr = simulate(params, start, t_end, dt_out=dt_out, controller=ctl, progress=progress)
    return SwingUp(tr, *capture(design, tr), design, ctl)


def capture(design: LQR, tr) -> Tuple[bool, float]:
    """Whether the run ``tr`` entered the region of ``design`` for good, and when (the row after the last one
    outside; NaN if not)."""
    inside = design.inside(tr.y)
    if tr.ok and inside.size and inside[-1]:
        outside = np.flatnonzero(~inside)
        return True, float(tr.t[outside[-1] + 1 if outside.size else 0])
    return False, math.nan
