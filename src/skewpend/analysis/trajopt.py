"""Optimal swing-ups: trajectory optimisation on the generated dynamics, tracked by time-varying LQR.

:func:`optimal_swingup` solves, by direct multiple shooting with IPOPT (through CasADi, on the chain's
equations from the recursive algorithms -- :mod:`skewpend.numeric.recursive` -- with their exact
derivatives), for the torques that take any model (the double pendulum as the chain of two, any
chain, any skew) from a start to an equilibrium with the actuated joints inside their limits:

* the state at ``N`` knots over a free duration ``T`` (bounded by ``horizon``), the torques linear
  between the knots (a first-order hold), each interval one classical RK4 step;
* the cost (:class:`Cost`) weighs the RealAIGym leaderboard's criteria -- swing-up time, energy,
  torque cost, torque smoothness, velocity cost -- each through ``tanh(pi c / n)`` as the score does
  (plus a hundredth of its linear part, which keeps a saturated term's gradient alive); the default
  weights are the v2 score's, so the optimum is the best score the model allows;
* from ``hold`` x ``T`` on the end effector stays above ``height`` x its height at the goal (the
  leaderboard's success line), and the run ends at the goal at rest;
* IPOPT's exact derivatives are built from the transcription's structure: one knot interval's RK4
  step differentiated once (Jacobian and Lagrangian Hessian), mapped over the intervals and scattered
  into the sparse matrices -- a build of about a second, where CasADi's own colouring of the whole
  expanded NLP took 5-17 s for a skewed rig.

:func:`tvlqr` designs the tracking: the optimised motion resampled on a fixed step (the leaderboard's
0.002 s), the discrete-time Riccati recursion along it ending in the goal's discrete LQR, and hands
over to that LQR at the end -- a :class:`Tracking` controller, a law ``u(t, x)`` that
:func:`skewpend.analysis.leaderboard.run_protocol` runs, with the DFKI lab's ``get_control_output(x,
t)`` (their state order and angles: the double pendulum's ``(q1, q2, q1', q2')``, ``q2`` relative,
zero hanging -- skewpend's own) so their ``Simulator`` can run it unchanged.

:func:`timed_swingup` reaches a goal at rest in a given time within the torque limit (the torques' least
effort; cyclic joints' end angles may be left ``free``), :func:`shortest_swingup` bisects that time to the
shortest the optimiser reaches -- the physics' bound on a swing-up within a motor's limit -- and
:func:`swingup_tracking` tracks such a reach (planned within a share of the limit) by :func:`tvlqr` and the
goal's LQR: the rotary pendulum's swing-up within its driver's 3 V (docs: *The rotary pendulum*).

Honest status: a solve that does not converge is reported as such (``ok`` False, IPOPT's status in
``message``) and never returned as an optimum.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field, replace
from typing import Any, Dict, Optional, Tuple

import numpy as np

from ..errors import EquilibriumError, ParameterError, require
from .control import EVERY_LINK_UP
from .leaderboard import NORMALISATION, PROTOCOL

__all__ = ["Cost", "OptimalTrajectory", "optimal_swingup", "Tracking", "tvlqr", "COST_TERMS", "SpeedObserver",
           "casadi_dynamics", "time_argument", "save_directory", "write_yaml", "timed_swingup",
           "shortest_swingup", "swingup_tracking"]

#: The cost's terms, in order: the leaderboard's criteria (their normalisation: ``leaderboard.NORMALISATION``).
COST_TERMS = ("swingup_time", "energy", "tau_cost", "tau_smoothness", "velocity_cost")
#: The linear part's share in each term (see the module).
LINEAR_SHARE = 0.01
#: The seeded starts' spread of the guessed angles [rad] (a swing of random size and sense).
SPREAD = 0.6
#: The most samples of a tracking's reference (:func:`tvlqr`'s ``duration / dt``).
MAX_SAMPLES = 1e6


@dataclass(frozen=True)
class Cost:
    """Weights of the leaderboard's criteria in the optimisation (each ``>= 0``; the default: the v2
    score's, every weight 1): ``time`` (the swing-up time), ``energy``, ``torque`` (the torque cost),
    ``smoothness`` (the torque's smoothness) and ``velocity`` (the velocity cost)."""

    time: float = 1.0
    energy: float = 1.0
    torque: float = 1.0
    smoothness: float = 1.0
    velocity: float = 1.0

    def __post_init__(self) -> None:
        for name in ("time", "energy", "torque", "smoothness", "velocity"):
            v = getattr(self, name)
            if isinstance(v, bool) or not isinstance(v, (int, float, np.floating, np.integer)) or not math.isfinite(v) or v < 0:
                raise ParameterError(f"the cost's weight {name} must be a finite number >= 0, got {v!r}")
            object.__setattr__(self, name, float(v))
        if not any(self.weights):
            raise ParameterError("the cost needs at least one positive weight (time, energy, torque, smoothness, velocity)")

    @property
    def weights(self) -> Tuple[float, ...]:
        return (self.time, self.energy, self.torque, self.smoothness, self.velocity)


@dataclass(frozen=True)
class OptimalTrajectory:
    """An optimised swing-up: knots ``t`` (N + 1,), states ``x`` (N + 1, 2 n), torques ``u`` (N + 1, n)
    (linear between knots), the model (``chain``), ``actuated`` joints, ``goal`` state, ``umax``;
    ``ok`` and IPOPT's ``message``; the criteria the optimiser saw (``predicted``) and ``solve_time`` [s]."""

    t: np.ndarray
    x: np.ndarray
    u: np.ndarray
    chain: Any = field(repr=False)
    actuated: Tuple[int, ...]
    goal: np.ndarray
    umax: float
    ok: bool
    message: str
    predicted: Dict[str, float] = field(default_factory=dict)
    solve_time: float = 0.0
    attempts: int = 1

    @property
    def duration(self) -> float:
        return float(self.t[-1])


def casadi_dynamics(chain, actuated: Tuple[int, ...]):
    """CasADi functions of the chain: ``f(y, u) -> y'`` (u: the actuated joints' torques) and the RK4
    step ``step(y, u0, u1, h)`` with the torque linear from u0 to u1 over the step; ``tip(q)`` the end
    effector's height."""
    ca = require("casadi", "optimal swing-ups (CasADi and IPOPT)")
    from ..numeric.recursive import chain_functions, parameter_names, parameter_vector, structure_of_chain

    n = chain.n
    fns = chain_functions(structure_of_chain(chain))
    names = parameter_names(n)
    pnum = parameter_vector(chain)
    y = ca.SX.sym("y", 2 * n)
    u = ca.SX.sym("u", len(actuated))
    p = ca.SX(ca.DM(pnum))
    for r, j in enumerate(actuated):
        i = names.index(f"tau{j}")
        p[i] = p[i] + u[r]
    Mp, f, _ = fns["model"](y, p)
    M = ca.SX(n, n)
    for k, (i, j) in enumerate(zip(*np.tril_indices(n))):  # the lower triangle, row by row
        M[int(i), int(j)] = M[int(j), int(i)] = Mp[k]
    qdd = ca.solve(M, f)
    rhs = ca.Function("f", [y, u], [ca.vertcat(y[n:], qdd)])
    u1 = ca.SX.sym("u1", len(actuated))
    h = ca.SX.sym("h")
    um = 0.5 * (u + u1)
    k1 = rhs(y, u)
    k2 = rhs(y + h / 2 * k1, um)
    k3 = rhs(y + h / 2 * k2, um)
    k4 = rhs(y + h * k3, u1)
    step = ca.Function("step", [y, u, u1, h], [y + h / 6 * (k1 + 2 * k2 + 2 * k3 + k4)])
    q = ca.SX.sym("q", n)
    ends = fns["ends"](q, ca.SX(ca.DM(pnum)))
    tip = ca.Function("tip", [q], [-ends[3 * n - 2]])
    return ca, rhs, step, tip


def _split(z, n: int, m: int, N: int):
    """The decision vector's parts: states X (2 n, N + 1), torques U (m, N + 1), the criteria's slacks C (5),
    the phases' durations T (2)."""
    import casadi as ca

    nX, nU = 2 * n * (N + 1), m * (N + 1)
    return (ca.reshape(z[:nX], 2 * n, N + 1), ca.reshape(z[nX:nX + nU], m, N + 1), z[nX + nU:nX + nU + 5],
            z[nX + nU + 5:nX + nU + 7])


def _steps(ca, T, N: int, N1: int):
    """The knot intervals' lengths (a row of N): ``T0 / N1`` for the first N1, then ``T1 / (N - N1)``."""
    N2 = N - N1
    return ca.horzcat(ca.repmat(T[0] / N1, 1, N1), ca.repmat(T[1] / N2, 1, N2)) if N2 else ca.repmat(T[0] / N1, 1, N)


def _rest(ca, z, tip, *, n, m, N, N1, joints, up_line, weights, dt_score, steps_score):
    """The transcription's constraints other than the knots' RK4 steps (the duration, the success line, the
    criteria's definitions), the objective and the criteria, as expressions of ``z``."""
    X, U, C, T = _split(z, n, m, N)
    h = _steps(ca, T, N, N1)
    g = [T[0] + T[1]]
    if up_line > 0:
        g.append(ca.vec(tip.map(N + 1 - N1)(X[:n, N1:]) - up_line))
    # the criteria on rows dt_score apart: each knot interval holds h / dt_score rows
    per = h / dt_score
    energy = 0
    for r, j in enumerate(joints):
        w = (X[j - 1, 1:] - X[j - 1, :N]) * 0.5 * (U[r, :N] + U[r, 1:])
        energy = energy + ca.sum2(ca.sqrt(w ** 2 + 1e-8))
    diffs = U[:, 1:] - U[:, :N]
    nd = steps_score - 1
    g.append(C - ca.vertcat(energy, ca.sum2(h * ca.sum1(U[:, :N] ** 2)), ca.sum2(h * ca.sum1(X[n:, :N] ** 2)),
                            ca.sum2(ca.sum1(diffs ** 2) / per) / nd - C[4] ** 2, ca.sum1(ca.sum2(diffs)) / nd))
    values = {"swingup_time": T[0] if up_line > 0 else T[0] + T[1], "energy": C[0], "tau_cost": C[1],
              "velocity_cost": C[2], "tau_smoothness": ca.sqrt(C[3] + 1e-14)}
    objective = 0
    for key in COST_TERMS:
        if weights[key]:
            s = math.pi * values[key] / NORMALISATION[key]
            objective = objective + weights[key] * (ca.tanh(s) + LINEAR_SHARE * s)
    return ca.vertcat(*g), objective, ca.vertcat(*[values[k] for k in COST_TERMS])


def _assembly(ca, shape, rows, cols, sources, coefficients, width):
    """A sparse matrix of ``shape`` whose entry ``(rows[t], cols[t])`` sums ``coefficients[t]`` times entry
    ``sources[t]`` of a vector of ``width``: its sparsity and the constant (nnz x width) matrix that maps
    the vector to its nonzeros (CasADi's column-major order)."""
    nr, nc = shape
    keys = np.asarray(cols, dtype=np.int64) * nr + np.asarray(rows, dtype=np.int64)
    unique, where = np.unique(keys, return_inverse=True)
    colind = np.searchsorted(unique // nr, np.arange(nc + 1))
    sparsity = ca.Sparsity(nr, nc, colind.tolist(), (unique % nr).tolist())
    from scipy.sparse import csc_matrix

    A = csc_matrix((np.asarray(coefficients, dtype=float), (where, np.asarray(sources))), shape=(unique.size, width))
    A.sum_duplicates()
    return sparsity, ca.DM(ca.Sparsity(A.shape[0], A.shape[1], A.indptr.tolist(), A.indices.tolist()), A.data)


def _transcription(ca, step, tip, *, n, m, N, N1, joints, up_line, weights, dt_score, steps_score):
    """The multiple-shooting NLP ``{x, f, g}`` with its constraints' Jacobian and its Lagrangian's Hessian
    built from their structure (``nlpsol`` options ``jac_g`` and ``hess_lag``): the RK4 step's derivatives
    of one knot interval (state, torques at both ends, the phase's duration) derived once, mapped over the
    intervals and scattered into the sparse matrices; the rest (a few expressions per knot) by CasADi's own
    derivatives.  The same matrices as CasADi's automatic ones of the expanded NLP (``tests/test_trajopt.py``),
    built in a fraction of a second where those take 5-17 s (the whole graph's colouring), evaluated about as
    fast (a Hessian of the acrobot at 30 deg: 34 ms against 29 ms).  Also the criteria as expressions of ``x``."""
    N2 = N - N1
    nX, nU = 2 * n * (N + 1), m * (N + 1)
    nz = nX + nU + 7
    nd = 2 * n * N  # the RK4 steps' constraints
    # one interval: w = (y, u0, u1, Tp), h = Tp * c
    y, u0, u1 = ca.SX.sym("y", 2 * n), ca.SX.sym("u0", m), ca.SX.sym("u1", m)
    Tp, c, lam = ca.SX.sym("Tp"), ca.SX.sym("c"), ca.SX.sym("lam", 2 * n)
    w = ca.vertcat(y, u0, u1, Tp)
    nw = w.shape[0]
    nxt = step(y, u0, u1, Tp * c)
    jac_block = ca.Function("jac_block", [y, u0, u1, Tp, c], [ca.densify(ca.jacobian(nxt, w))]).map(N)
    hess_block = ca.Function("hess_block", [y, u0, u1, Tp, c, lam],
                             [ca.densify(ca.hessian(ca.dot(lam, nxt), w)[0])]).map(N)
    # the global column of each interval's local variable
    k = np.arange(N)
    phase = (k >= N1).astype(int)
    col = np.empty((N, nw), dtype=np.int64)
    col[:, :2 * n] = k[:, None] * 2 * n + np.arange(2 * n)
    col[:, 2 * n:2 * n + m] = nX + k[:, None] * m + np.arange(m)
    col[:, 2 * n + m:2 * n + 2 * m] = nX + (k[:, None] + 1) * m + np.arange(m)
    col[:, -1] = nz - 2 + phase
    # the Jacobian of the steps: block (i, a) of interval k at (2n k + i, col[k, a]); -1 at X_k+1
    i, a = np.meshgrid(np.arange(2 * n), np.arange(nw), indexing="ij")
    rows = (k[:, None, None] * 2 * n + i[None]).ravel()
    cols = np.broadcast_to(col[:, None, :], (N, 2 * n, nw)).ravel()
    src = (k[:, None, None] * (2 * n * nw) + a[None] * 2 * n + i[None]).ravel()
    width = N * 2 * n * nw
    rows = np.concatenate([rows, np.arange(nd)])
    cols = np.concatenate([cols, 2 * n + np.arange(nd)])
    src = np.concatenate([src, np.full(nd, width)])
    coef = np.concatenate([np.ones(N * 2 * n * nw), -np.ones(nd)])
    jac_sparsity, jac_map = _assembly(ca, (nd, nz), rows, cols, src, coef, width + 1)
    # the Hessian of the steps' part of the Lagrangian: the upper triangle of each interval's block
    a, b = np.triu_indices(nw)
    hrows = col[:, a].ravel()
    hcols = col[:, b].ravel()
    hsrc = (k[:, None] * nw * nw + b[None] * nw + a[None]).ravel()
    hess_sparsity, hess_map = _assembly(ca, (nz, nz), hrows, hcols, hsrc, np.ones(hsrc.size), N * nw * nw)
    # the rest, in SX: small
    zs = ca.SX.sym("z", nz)
    g_rest, f_rest, values = _rest(ca, zs, tip, n=n, m=m, N=N, N1=N1, joints=joints, up_line=up_line, weights=weights,
                                   dt_score=dt_score, steps_score=steps_score)
    ng_rest = g_rest.shape[0]
    lam_f_s, lam_r_s = ca.SX.sym("lam_f"), ca.SX.sym("lam_r", ng_rest)
    rest = ca.Function("rest", [zs], [g_rest, f_rest, values])
    rest_jac = ca.Function("rest_jac", [zs], [ca.jacobian(g_rest, zs)])
    rest_hess = ca.Function("rest_hess", [zs, lam_f_s, lam_r_s],
                            [ca.triu(ca.hessian(lam_f_s * f_rest + ca.dot(lam_r_s, g_rest), zs)[0])])
    # the NLP in MX
    z = ca.MX.sym("z", nz)
    X, U, C, T = _split(z, n, m, N)
    h = _steps(ca, T, N, N1)
    Tk = ca.horzcat(ca.repmat(T[0], 1, N1), ca.repmat(T[1], 1, N2)) if N2 else ca.repmat(T[0], 1, N)
    ck = ca.DM(np.where(phase == 0, 1.0 / N1, 1.0 / max(N2, 1))).T
    defects = ca.vec(step.map(N)(X[:, :N], U[:, :N], U[:, 1:], h) - X[:, 1:])
    g_r, f, vals = rest(z)
    g = ca.vertcat(defects, g_r)
    p = ca.MX.sym("p", 0, 1)
    J_steps = ca.MX(jac_sparsity, ca.mtimes(jac_map, ca.vertcat(ca.vec(jac_block(X[:, :N], U[:, :N], U[:, 1:], Tk, ck)), 1)))
    jac_g = ca.Function("nlp_jac_g", [z, p], [g, ca.vertcat(J_steps, rest_jac(z))], ["x", "p"], ["g", "jac_g_x"])
    lam_f, lam_g = ca.MX.sym("lam_f"), ca.MX.sym("lam_g", nd + ng_rest)
    Lam = ca.reshape(lam_g[:nd], 2 * n, N)
    H_steps = ca.MX(hess_sparsity, ca.mtimes(hess_map, ca.vec(hess_block(X[:, :N], U[:, :N], U[:, 1:], Tk, ck, Lam))))
    hess_lag = ca.Function("nlp_hess_l", [z, p, lam_f, lam_g], [H_steps + rest_hess(z, lam_f, lam_g[nd:])],
                           ["x", "p", "lam_f", "lam_g"], ["hess_gamma_x_x"])
    return {"x": z, "f": f, "g": g}, {"jac_g": jac_g, "hess_lag": hess_lag}, vals


_SOLVER: list = []  # the solver a forked worker inherits (set only while its pool lives)
#: IPOPT's statuses when a Ctrl-C reached it: CasADi catches the signal inside the solve and returns (the
#: interrupt would be lost; the caller raises it).
INTERRUPTED = ("NonIpopt_Exception_Thrown", "User_Requested_Stop")


def _interrupted(status: str) -> None:
    if status in INTERRUPTED:
        raise KeyboardInterrupt("the optimisation was interrupted")


def _worker_init() -> None:
    """A forked worker leaves Ctrl-C to the parent (which stops the pool) and ends at the pool's SIGTERM."""
    import signal

    signal.signal(signal.SIGINT, signal.SIG_IGN)
    signal.signal(signal.SIGTERM, signal.SIG_DFL)


#: How often [s] the iteration counts of starts solved in forked workers are read and reported.
POLL = 0.2
_TICK: list = []  # the count of the solve running in this process: called by IPOPT's iteration callback
_SHARED: list = []  # (iterations, finished): the workers' counts per start, shared memory set up before the fork


def _iteration_callback(ca, nx: int, ng: int):
    """IPOPT's iteration callback (CasADi's ``iteration_callback``): at each iteration it calls the tick of the
    solve running in this process (``_TICK``), whose answer 1 stops IPOPT (``User_Requested_Stop``)."""

    class Iterations(ca.Callback):
        def __init__(self):
            ca.Callback.__init__(self)
            self.construct("iterations", {})

        def get_n_in(self):
            return ca.nlpsol_n_out()

        def get_n_out(self):
            return 1

        def get_name_in(self, i):
            return ca.nlpsol_out(i)

        def get_name_out(self, i):
            return "stop"

        def get_sparsity_in(self, i):
            size = {"f": 1, "x": nx, "lam_x": nx, "g": ng, "lam_g": ng}.get(ca.nlpsol_out(i))
            return ca.Sparsity(0, 0) if size is None else ca.Sparsity.dense(size)

        def eval(self, arg):
            return [_TICK[0]() if _TICK else 0]

    return Iterations()


def _solve(solver, z0, bounds, tick):
    """IPOPT from ``z0`` with ``tick`` told of each iteration (its answer 1 stops IPOPT): IPOPT's status and the
    solution."""
    _TICK[:] = [tick]
    try:
        sol = solver(x0=z0, **bounds)
    finally:
        _TICK.clear()
    return solver.stats()["return_status"], np.array(sol["x"]).ravel()


def _solve_one(job):
    """One start ``(k, z0, bounds)`` solved by the inherited solver, its iterations counted in the shared
    memory: IPOPT's status and the solution."""
    k, z0, bounds = job
    counts, finished = _SHARED

    def tick() -> int:
        counts[k] += 1
        return 0

    counts[k] = 0
    try:
        return _solve(_SOLVER[0], z0, bounds, tick)
    finally:
        finished[k] = 1


def _solve_starts(solver, starts, bounds, workers, progress, iterations):
    """IPOPT from each start, in order: in this process, or in forked workers that inherit the built solver
    (CasADi's solvers cannot be pickled or shared by threads; building one is most of a design's time).
    ``progress(done, count)`` after each start solved; ``iterations(running, solved, count)`` -- ``running``
    the starts being solved (0-based) and the IPOPT iterations each has reached -- at every iteration in this
    process, every :data:`POLL` s (when a count moved) from the workers."""
    import multiprocessing
    import os

    from ..interrupts import Interrupts

    count = len(starts)
    if workers is None:
        workers = min(os.cpu_count() or 1, count)
    forking = "fork" in multiprocessing.get_all_start_methods()
    if workers == 1 or count == 1 or not forking:
        out = []
        with Interrupts() as intr:
            for k, z0 in enumerate(starts):
                intr.check()
                reached = [-1]
                failed: list = []

                def tick(k=k, reached=reached, failed=failed, solved=len(out)) -> int:
                    reached[0] += 1
                    if iterations is not None and not failed:
                        try:
                            iterations({k: reached[0]}, solved, count)
                        except BaseException as exc:  # noqa: BLE001 - raised again once IPOPT has returned
                            failed.append(exc)
                    return 1 if failed else 0

                result = _solve(solver, z0, bounds, tick)
                if failed:
                    raise failed[0]
                _interrupted(result[0])
                out.append(result)
                if progress is not None:
                    progress(k + 1, count)
        return out
    _SOLVER[:] = [solver]
    _SHARED[:] = [multiprocessing.Array("q", [-1] * count, lock=False), multiprocessing.Array("b", count, lock=False)]
    counts, finished = _SHARED
    try:
        with Interrupts() as intr, multiprocessing.get_context("fork").Pool(min(workers, count), _worker_init) as pool:
            out = []
            results = pool.imap(_solve_one, [(k, z0, bounds) for k, z0 in enumerate(starts)])
            said = None
            while len(out) < count:
                try:
                    result = results.next(timeout=POLL)
                except multiprocessing.TimeoutError:
                    result = None
                intr.check()
                if result is not None:
                    _interrupted(result[0])
                    out.append(result)
                    if progress is not None:
                        progress(len(out), count)
                if iterations is not None:
                    running = {k: int(counts[k]) for k in range(count) if counts[k] >= 0 and not finished[k]}
                    solved = int(sum(finished[:]))
                    if (running, solved) != said:
                        said = (running, solved)
                        iterations(running, solved, count)
            return out
    finally:
        _SOLVER.clear()
        _SHARED.clear()


def _as_chain(model):
    from ..checks import numeric_model

    try:
        return numeric_model(model, "an optimal swing-up").as_chain()
    except ParameterError as exc:
        raise ParameterError(str(exc).replace("params must", "model must", 1)) from None


def _state(name: str, value, n: int) -> np.ndarray:
    """A state of ``n`` joints (2 n finite numbers: angles [rad], then speeds [rad/s]), else one ParameterError."""
    bad = ParameterError(f"{name} must be {2 * n} finite numbers (the angles [rad], then the speeds [rad/s]), got "
                         f"{value!r}")
    if isinstance(value, (str, bytes)):
        raise bad
    try:
        x = np.array(value, dtype=float)
    except (TypeError, ValueError, OverflowError):
        raise bad from None
    if x.shape != (2 * n,) or not np.all(np.isfinite(x)):
        raise bad
    return x


def _optimal_swingup(model, *, actuated=(2,), umax: float = PROTOCOL.umax, goal=EVERY_LINK_UP, start=None,
                    cost: Cost = Cost(), horizon: Tuple[float, float] = (0.5, 4.0), guess: float = 1.5,
                    knots: int = 150, hold: float = 0.8, height: float = PROTOCOL.height, attempts: int = 4,
                    seed: int = 0, dt_score: float = PROTOCOL.dt, steps_score: int = PROTOCOL.steps,
                    max_iter: int = 1500, workers: Optional[int] = None, progress=None,
                    iterations=None) -> OptimalTrajectory:
    """The swing-up of ``model`` from ``start`` (default: at rest in the model's hanging rest,
    :func:`~skewpend.analysis.control.hanging_rest`: ``(pi, 0)`` for the DeepMind acrobot, whose zero is upright) to ``goal`` (an equilibrium's
    label or an ``Equilibrium``) that minimises ``cost`` with the ``actuated`` joints' torques within
    ``umax`` [N m] (see the module).  ``horizon`` bounds the duration [s], ``guess`` starts it;
    ``knots`` intervals; ``hold``: the fraction of the duration after which the end effector stays above
    ``height`` x its goal height (when the goal's end effector is above the roof; otherwise no such
    constraint and the time term is the duration).  ``attempts`` seeded starts (the best converged one is
    returned); the criteria are those of rows ``dt_score`` apart over ``steps_score`` rows (the
    leaderboard's).  ``workers`` processes solve the starts side by side (default: one per core, at most
    ``attempts``; 1: in this process) -- the result is the same.  ``progress(done, attempts)`` is told of each
    start solved; ``iterations(running, solved, attempts)`` of IPOPT's progress inside them -- ``running`` maps
    each start being solved (0-based) to the iterations it has reached -- at each iteration of a start solved in
    this process, every :data:`POLL` s (when a count moved) of those solved by workers.

    Refused with one line: an uncontrollable goal, a horizon too short to reach it under the torque limit
    (no start converges to a feasible motion: ``ok`` False, exit status 1 on the command line), negative
    weights (:class:`Cost`)."""
    import time as _time

    from ..numeric.control import actuated_joints
    from .control import controllability, equilibrium_argument, hanging_rest, linearization
    from .equilibria import find_equilibrium

    chain = _as_chain(model)
    n = chain.n
    joints = actuated_joints(actuated, n)
    if not isinstance(cost, Cost):
        raise ParameterError(f"cost must be a skewpend Cost, got {type(cost).__name__}")
    if workers is not None and (isinstance(workers, bool) or not isinstance(workers, int) or workers < 1):
        raise ParameterError(f"workers must be a whole number >= 1, got {workers!r}")
    for name, value, low in (("attempts", attempts, 1), ("max_iter", max_iter, 1), ("seed", seed, 0)):
        if isinstance(value, bool) or not isinstance(value, (int, np.integer)) or value < low:
            raise ParameterError(f"{name} must be a whole number >= {low}, got {value!r}")
    if progress is not None and not callable(progress):
        raise ParameterError(f"progress must be a callable progress(done, total), got {progress!r}")
    if iterations is not None and not callable(iterations):
        raise ParameterError(f"iterations must be a callable iterations(running, solved, total), got {iterations!r}")
    if isinstance(umax, bool) or not (isinstance(umax, (int, float)) and math.isfinite(umax) and umax > 0):
        raise ParameterError(f"umax must be a positive torque limit [N m], got {umax!r}")
    try:
        lo, hi = (float(v) for v in horizon)
    except (TypeError, ValueError):
        raise ParameterError(f"horizon must be (shortest, longest) durations [s], got {horizon!r}") from None
    if not (0 < lo < hi <= 60):
        raise ParameterError(f"horizon must be 0 < shortest < longest <= 60 s, got {horizon!r}")
    if isinstance(guess, bool) or not isinstance(guess, (int, float)) or not math.isfinite(guess):
        raise ParameterError(f"guess must be a duration [s], got {guess!r}")
    guess = min(max(float(guess), lo), hi)
    if not (isinstance(knots, int) and 10 <= knots <= 5000):
        raise ParameterError(f"knots must be a whole number of intervals, 10 to 5000, got {knots!r}")
    if not (0 < hold <= 1) or not (0 < height <= 1):
        raise ParameterError(f"hold and height must be fractions in (0, 1], got {hold!r} and {height!r}")
    x_start = hanging_rest(chain) if start is None else _state("start", start, n)
    from ..progress import stage

    stage("optimal swing-up: the goal's equilibrium and its controllability")
    # the goal: a label with a word per link, an Equilibrium or angles near one; held by the actuated joints
    eq = find_equilibrium(chain, equilibrium_argument(goal, chain, "goal"), "goal")
    x_goal, label = _state("goal's state", eq.state, n), eq.label
    lin = linearization(chain, label, joints, coulomb="smoothed")
    c = controllability(lin.A, lin.B)
    if not c["controllable"] or c["distance"] < 1e-10:
        raise EquilibriumError(f"the goal {label} cannot be held with the joints {', '.join(map(str, joints))} actuated: "
                               f"the linearisation is not controllable (rank {c['rank']} of {lin.A.shape[0]})")
    stage(f"optimal swing-up: building IPOPT's problem and its derivatives (CasADi, {knots} knots)")
    ca, rhs, step, tip = casadi_dynamics(chain, joints)
    m = len(joints)
    N = knots
    up_line = height * float(tip(x_goal[:n]))
    use_height = up_line > 0
    N1 = max(1, min(N - 1, int(round(hold * N)))) if use_height else N
    N2 = N - N1
    weights = dict(zip(COST_TERMS, cost.weights))
    nlp, options, values = _transcription(ca, step, tip, n=n, m=m, N=N, N1=N1, joints=joints, up_line=up_line,
                                          weights=weights, dt_score=dt_score, steps_score=steps_score)
    objective = nlp["f"]
    lbg = [np.zeros(2 * n * N), [lo]]
    ubg = [np.zeros(2 * n * N), [hi]]
    if use_height:
        lbg.append(np.zeros(N + 1 - N1))
        ubg.append(np.full(N + 1 - N1, np.inf))
    lbg.append(np.zeros(5))
    ubg.append(np.zeros(5))
    z = nlp["x"]
    nz = z.shape[0]
    nX, nU = 2 * n * (N + 1), m * (N + 1)
    lbz, ubz = np.full(nz, -np.inf), np.full(nz, np.inf)
    lbz[:2 * n], ubz[:2 * n] = x_start, x_start
    lbz[2 * n * N:nX], ubz[2 * n * N:nX] = x_goal, x_goal
    lbz[nX:nX + nU], ubz[nX:nX + nU] = -umax, umax
    lbz[nX + nU - m:nX + nU] = ubz[nX + nU - m:nX + nU] = 0.0  # the goal is held by no torque (an equilibrium)
    lbz[nX + nU:nX + nU + 4] = 0.0
    lbz[-2:], ubz[-2:] = 0.02 * lo, hi
    if not N2:
        lbz[-1] = ubz[-1] = 0.0
    counter = _iteration_callback(ca, nz, int(nlp["g"].shape[0]))
    solver = ca.nlpsol("swingup", "ipopt", nlp,
                       dict(options, **{"iteration_callback": counter, "expand": True, "print_time": False, "ipopt.print_level": 0, "ipopt.sb": "yes",
                                        "ipopt.max_iter": int(max_iter), "ipopt.tol": 1e-8,
                                        "ipopt.acceptable_iter": 200, "ipopt.bound_relax_factor": 0.0}))
    evaluate = ca.Function("criteria", [z], [values, objective])
    rng = np.random.default_rng(seed)
    tau_grid = np.linspace(0.0, 1.0, N + 1)
    starts = []
    for attempt in range(int(attempts)):
        X0 = x_start[:, None] + (x_goal - x_start)[:, None] * tau_grid[None, :]
        X0[n:] = ((x_goal - x_start)[:n] / guess)[:, None]
        U0 = np.zeros((m, N + 1))
        duration = guess
        if attempt:  # a seeded start: a swing of random size and sense, torques along it, another duration
            duration = min(max(guess * (1.0 + 0.25 * rng.uniform(-1, 1)), lo), hi)
            X0[:n] += rng.normal(scale=SPREAD, size=(n, 1)) * np.sin(np.pi * tau_grid)[None, :]
            U0[:, :N] = rng.uniform(-0.5, 0.5, size=(m, 1)) * umax * np.sin(2 * np.pi * tau_grid[:N])
        starts.append(np.concatenate([X0.T.ravel(), U0.T.ravel(), np.zeros(5), [duration * N1 / N, duration * N2 / N]]))
    bounds = dict(lbx=lbz, ubx=ubz, lbg=np.concatenate(lbg), ubg=np.concatenate(ubg))
    t0 = _time.perf_counter()
    best = None
    for status, zs in _solve_starts(solver, starts, bounds, workers, progress, iterations):
        ok = status in ("Solve_Succeeded", "Solved_To_Acceptable_Level")
        crit, obj = evaluate(zs)
        obj = float(obj)
        if best is None or (ok and (not best[0] or obj < best[1])):
            best = (ok, obj, zs, status, np.array(crit).ravel())
    ok, obj, zs, status, crit = best
    T1, T2 = float(zs[-2]), float(zs[-1])
    x = zs[:nX].reshape(N + 1, 2 * n)
    u = zs[nX:nX + nU].reshape(N + 1, m)
    full = np.zeros((N + 1, n))
    full[:, [j - 1 for j in joints]] = u
    predicted = {k: float(v) for k, v in zip(COST_TERMS, crit)}
    if ok:
        message = f"optimal ({status}, objective {obj:.4g})"
    else:
        message = (f"no optimal swing-up found: IPOPT ended with {status} in each of {attempts} starts (a horizon "
                   f"{lo:g}..{hi:g} s too short for the torque limit {umax:g} N m, or a goal out of reach)")
    knots_t = np.concatenate([np.linspace(0.0, T1, N1 + 1), T1 + np.linspace(0.0, T2, N2 + 1)[1:]])
    return OptimalTrajectory(knots_t, x, full, chain, joints, x_goal, float(umax), ok, message,
                             predicted, _time.perf_counter() - t0, int(attempts))


def _interruptible(solve):
    """``solve`` with Ctrl-C and SIGTERM taken within 0.3 s of CasADi's build or IPOPT's solve returning
    (``Interrupts(escalate_after=0.3)``: inside a command they are only recorded until a check)."""
    import functools

    @functools.wraps(solve)
    def run(*args, **kwargs):
        from ..interrupts import Interrupts

        with Interrupts(escalate_after=0.3) as intr:
            result = solve(*args, **kwargs)
            intr.check()
        return result

    run.__name__ = run.__qualname__ = solve.__name__.lstrip("_")
    return run


optimal_swingup = _interruptible(_optimal_swingup)


# -- tracking -------------------------------------------------------------------------------------------
@dataclass(frozen=True)
class Tracking:
    """Time-varying LQR along an optimised swing-up, then the goal's LQR (see the module): the law
    ``u(t, x)`` -- sample ``k``'s ``u_k - K_k (x - x_k)`` of the resampled reference at ``t = k dt`` (the
    sample after the last one is the goal's ``-K_goal (x - x_goal)``), the two samples' laws around ``t``
    blended linearly between them (angle errors wrapped to (-pi, pi]) -- clipped to ``umax``; the joints
    not actuated get 0.  :meth:`controller` is the same law compiled for :func:`skewpend.simulate`."""

    dt: float
    x_ref: np.ndarray = field(repr=False)
    u_ref: np.ndarray = field(repr=False)
    K: np.ndarray = field(repr=False)
    K_goal: np.ndarray = field(repr=False)
    goal: np.ndarray
    umax: float
    actuated: Tuple[int, ...]
    trajectory: Any = field(repr=False, default=None)
    Q: Optional[np.ndarray] = field(repr=False, default=None)   #: the design's state weight
    R: Optional[np.ndarray] = field(repr=False, default=None)   #: the design's torque weight
    Qf: Optional[np.ndarray] = field(repr=False, default=None)  #: the goal's LQR's state weight

    @property
    def duration(self) -> float:
        return len(self.K) * self.dt

    def _law(self, k: int, x: np.ndarray) -> np.ndarray:
        """Sample ``k``'s law at ``x`` (``k = len(K)``: the goal's LQR), the actuated joints' torques."""
        n = x.size // 2
        ref, u, K = (self.goal, 0.0, self.K_goal) if k >= len(self.K) else (self.x_ref[k], self.u_ref[k], self.K[k])
        dx = x - ref
        dx[:n] = np.mod(dx[:n] + np.pi, 2 * np.pi) - np.pi
        return u - K @ dx

    def __call__(self, t: float, x) -> np.ndarray:
        x = np.asarray(x, dtype=float)
        n = x.size // 2
        s = t / self.dt
        k = min(max(math.floor(s), 0), len(self.K))
        v = self._law(k, x)
        if k < len(self.K) and s > k:
            v = v + (s - k) * (self._law(k + 1, x) - v)
        out = np.zeros(n)
        idx = [j - 1 for j in self.actuated]
        out[idx] = np.clip(v, -self.umax, self.umax)
        return out

    def controller(self):
        """This law compiled (:class:`skewpend.Controller`, kind ``tracking``) for :func:`skewpend.simulate`:
        the same samples, gains and goal LQR, evaluated inside the integrators with no Python call per step."""
        from ..numeric.control import Controller

        steps, n2 = self.x_ref.shape
        n = n2 // 2
        idx = [j - 1 for j in self.actuated]
        inputs = np.zeros((steps, n))
        inputs[:, idx] = self.u_ref
        gains = np.zeros((steps, n, n2))
        gains[:, idx, :] = self.K
        K_goal = np.zeros((n, n2))
        K_goal[idx, :] = self.K_goal
        return Controller.tracking(self.dt, self.x_ref, inputs, gains, K_goal, self.goal, actuated=self.actuated,
                                   umax=self.umax)

    # the DFKI lab's controller interface (double_pendulum.controller.abstract_controller)
    def get_control_output(self, x, t=None):
        """The torques at the DFKI state ``x = (q1, q2, q1', q2')`` (a chain's ``2 n`` entries) and time ``t``
        [s] (their convention is skewpend's: q2 relative to rod 1, zero hanging).  ``t`` is required: the law
        varies along the motion (the lab's ``Simulator`` passes it)."""
        t, size = time_argument(t), len(self.goal)
        try:
            a = np.array(x, dtype=float).reshape(-1)
        except (TypeError, ValueError):
            a = None
        if a is None or a.shape != (size,) or not np.all(np.isfinite(a)):
            raise ParameterError(f"x must be the state, {size} finite numbers (angles [rad], then speeds [rad/s]), got "
                                 f"{x!r}")
        return self(t, a)

    def init(self) -> None:
        """The DFKI interface's initialisation: nothing to set up (the law keeps no state between calls)."""

    def reset(self) -> None:
        """The DFKI interface's reset: nothing to forget (the law keeps no state between calls)."""

    def save(self, save_dir) -> Tuple[Any, Any]:
        """The DFKI interface's ``save(save_dir)`` (the lab's benchmark scripts call it): the controller's
        parameters as ``controller_tvlqr_parameters.yml`` and its reference with its gains as
        ``controller_tvlqr_reference.csv`` (a row per sample ``k``: ``time = k dt``, the state, the actuated
        joints' torques, the gain's entries ``K<row>_<column>``), written atomically into ``save_dir`` (made if
        missing); the two paths."""
        from ..io import atomic_path

        directory, rows_file = save_directory(save_dir), "controller_tvlqr_reference.csv"
        steps, n2 = self.x_ref.shape
        n = n2 // 2
        m = len(self.actuated)
        entries = {
            "controller": "skewpend.analysis.trajopt.Tracking (time-varying LQR along an optimised swing-up)",
            "dt": self.dt, "samples": steps, "duration": self.duration, "torque_limit": self.umax,
            "actuated_joints": list(self.actuated), "goal": self.goal.tolist(), "K_goal": self.K_goal.tolist(),
            "Q": None if self.Q is None else np.asarray(self.Q).tolist(),
            "R": None if self.R is None else np.asarray(self.R).tolist(),
            "Qf": None if self.Qf is None else np.asarray(self.Qf).tolist(),
            "state": [f"q{j}" for j in range(1, n + 1)] + [f"dq{j}" for j in range(1, n + 1)],
            "convention": "angles [rad], q2 .. qn relative to the link before, zero hanging; speeds [rad/s]; "
                          "torques [N m]",
            "law": "u = u_k - K_k (x - x_k) at t = k dt, blended linearly between samples, the goal's LQR "
                   "-K_goal (x - goal) after the last; angle errors wrapped; clipped to the torque limit",
            "reference": rows_file,
        }
        header = (["time"] + [f"pos{j}" for j in range(1, n + 1)] + [f"vel{j}" for j in range(1, n + 1)]
                  + [f"tau{j}" for j in self.actuated]
                  + [f"K{self.actuated[r]}_{c + 1}" for r in range(m) for c in range(n2)])
        rows = np.column_stack([np.arange(steps) * self.dt, self.x_ref, self.u_ref, self.K.reshape(steps, -1)])
        parameters, table = write_yaml(directory / "controller_tvlqr_parameters.yml", entries), directory / rows_file
        with atomic_path(table) as tmp:
            np.savetxt(tmp, rows, delimiter=",", header=",".join(header), comments="", fmt="%.17g")
        return parameters, table


def time_argument(t) -> float:
    """The time of a call of the DFKI interface, required (a law that varies along the motion)."""
    if t is None:
        raise ParameterError("t must be given: get_control_output(x, t) of this law depends on the time [s] (the "
                             "lab's Simulator passes it)")
    if isinstance(t, (bool, np.bool_, str, bytes)):
        raise ParameterError(f"t must be a time [s], got {t!r}")
    try:
        value = float(t)
    except (TypeError, ValueError):
        raise ParameterError(f"t must be a time [s], got {t!r}") from None
    if not math.isfinite(value):
        raise ParameterError(f"t must be a finite time [s], got {t!r}")
    return value


def save_directory(save_dir):
    from pathlib import Path

    if not isinstance(save_dir, (str, bytes)) and not hasattr(save_dir, "__fspath__"):
        raise ParameterError(f"save_dir must be a directory's path, got {save_dir!r}")
    directory = Path(save_dir)
    if directory.exists() and not directory.is_dir():
        raise ParameterError(f"save_dir {str(directory)!r} is a file, not a directory")
    try:
        directory.mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        raise ParameterError(f"save_dir {str(directory)!r} cannot be made: {exc.strerror}") from None
    return directory


def write_yaml(path, entries: Dict[str, Any]):
    import json

    from ..io import atomic_path

    with atomic_path(path) as tmp:  # JSON's scalars, strings and lists are YAML's flow style
        tmp.write_text("".join(f"{k}: {json.dumps(v)}\n" for k, v in entries.items()))
    return path


class SpeedObserver:
    """A law whose speeds come from the positions it is given (the DFKI interface, for the lab's ``Simulator``):
    at each call the backward difference of second order of this position and the two before, ``(3 q_k -
    4 q_k-1 + q_k-2) / (2 dt)`` (first order at the second call, the given speeds at the first) -- the
    observer of :func:`~skewpend.analysis.leaderboard.run_protocol`'s ``speeds="positions"``, call for call.
    ``reset()``/``init()`` forget the positions."""

    def __init__(self, law, dt: float = PROTOCOL.dt):
        self.law, self.dt = law, float(dt)
        self._seen: list = []

    def get_control_output(self, x, t=None):
        """The law's torques at the state ``x`` with the speeds from the positions seen, at the time ``t`` [s]
        (required: the law it wraps may vary with time)."""
        t = time_argument(t)
        x = np.array(x, dtype=float)
        n = x.size // 2
        self._seen = (self._seen + [x[:n].copy()])[-3:]
        if len(self._seen) == 3:
            q0, q1, q2 = self._seen[2], self._seen[1], self._seen[0]
            x[n:] = (3.0 * q0 - 4.0 * q1 + q2) / (2.0 * self.dt)
        elif len(self._seen) == 2:
            x[n:] = (self._seen[1] - self._seen[0]) / self.dt
        return self.law(t, x)

    def reset(self) -> None:
        self._seen = []

    init = reset

    def save(self, save_dir):
        """The DFKI interface's ``save(save_dir)``: the observer's settings as
        ``controller_observer_parameters.yml``, and the law's own files when it saves (a :class:`Tracking`)."""
        directory = save_directory(save_dir)
        paths = [write_yaml(directory / "controller_observer_parameters.yml", {
            "observer": "skewpend.analysis.trajopt.SpeedObserver: the speeds from the positions, (3 q_k - 4 q_k-1 + "
                        "q_k-2) / (2 dt)", "dt": self.dt,
            "law": getattr(type(self.law), "__qualname__", repr(self.law))})]
        if callable(getattr(self.law, "save", None)):
            paths += list(self.law.save(directory))
        return tuple(paths)


def tvlqr(trajectory: OptimalTrajectory, *, dt: float = PROTOCOL.dt, Q=None, R=None, Qf=None) -> Tracking:
    """The tracking of ``trajectory`` (:class:`Tracking`): the reference resampled every ``dt`` [s] (states
    by cubic Hermite interpolation, torques linearly), the discrete step (RK4, torques held) linearised
    along it, the Riccati recursion ``P_k = Q + A^T P (A - B K_k)`` from the goal's discrete LQR (``Qf``
    its state weight; ``R`` the torques').  Defaults: ``Q = diag(10, ..., 3, ...)`` (angles, speeds),
    ``R = 20`` per motor -- soft gains, which keep the swing-up through delays and model errors (the
    robustness board: at ``R = 0.1`` the acrobot stays up with 5 of 21 delays, at 20 with 13) -- and
    ``Qf = Q``.  ``Q`` and ``Qf`` (2 n x 2 n) must be symmetric positive semi-definite, ``R`` (m x m, a number
    for one motor) symmetric positive definite, ``dt`` positive and at most the duration; else one
    ParameterError naming the argument."""
    from scipy.linalg import solve_discrete_are

    from .control import check_weights

    if not isinstance(trajectory, OptimalTrajectory):
        raise ParameterError(f"trajectory must be an OptimalTrajectory from optimal_swingup, got "
                             f"{type(trajectory).__name__}")
    if not trajectory.ok:
        raise ParameterError(f"cannot track a swing-up that was not optimised: {trajectory.message}")
    if isinstance(dt, (bool, np.bool_)) or not isinstance(dt, (int, float, np.integer, np.floating)) \
            or not (math.isfinite(dt) and dt > 0):
        raise ParameterError(f"dt must be a positive sampling step [s], got {dt!r}")
    dt = float(dt)
    if not dt <= trajectory.duration:
        raise ParameterError(f"dt must be at most the swing-up's duration, {trajectory.duration:.4g} s, got {dt:g}")
    if trajectory.duration / dt > MAX_SAMPLES:
        raise ParameterError(f"dt = {dt:g} s samples the {trajectory.duration:.4g} s swing-up {trajectory.duration / dt:.3g} "
                             f"times; at most {MAX_SAMPLES:g}: use a larger dt")
    chain = trajectory.chain
    n = chain.n
    joints = trajectory.actuated
    m = len(joints)
    Qm, Rm = check_weights(np.diag([10.0] * n + [3.0] * n) if Q is None else Q, 20.0 * np.eye(m) if R is None else R,
                           m, 2 * n)
    Qfm = Qm if Qf is None else check_weights(Qf, None, m, 2 * n, q_name="Qf")[0]
    ca, rhs, step, _ = casadi_dynamics(chain, joints)
    idx = [j - 1 for j in joints]
    t_knots, xk, uk = trajectory.t, trajectory.x, trajectory.u[:, idx]
    K_steps = int(math.ceil(trajectory.duration / dt - 1e-9))
    ts = np.arange(K_steps) * dt
    # reference: Hermite cubic of the knots' states with their derivatives
    fk = np.array([np.array(rhs(xk[i], uk[i])).ravel() for i in range(len(t_knots))])
    i = np.clip(np.searchsorted(t_knots, ts, side="right") - 1, 0, len(t_knots) - 2)
    H = (t_knots[i + 1] - t_knots[i])[:, None]
    s = (ts - t_knots[i]) / H[:, 0]
    h00, h10, h01, h11 = 2 * s**3 - 3 * s**2 + 1, s**3 - 2 * s**2 + s, -2 * s**3 + 3 * s**2, s**3 - s**2
    x_ref = h00[:, None] * xk[i] + h10[:, None] * H * fk[i] + h01[:, None] * xk[i + 1] + h11[:, None] * H * fk[i + 1]
    u_ref = uk[i] + s[:, None] * (uk[i + 1] - uk[i])
    y = ca.SX.sym("y", 2 * n)
    u = ca.SX.sym("u", m)
    nxt = step(y, u, u, dt)
    jac = ca.Function("linear_step", [y, u], [ca.jacobian(nxt, y), ca.jacobian(nxt, u)])
    goal = trajectory.goal
    Ag, Bg = (np.array(v) for v in jac(goal, np.zeros(m)))
    try:
        P = solve_discrete_are(Ag, Bg, Qfm, Rm)
    except (np.linalg.LinAlgError, ValueError) as exc:
        raise EquilibriumError(f"the goal's discrete LQR has no solution: {exc}") from None
    K_goal = np.linalg.solve(Rm + Bg.T @ P @ Bg, Bg.T @ P @ Ag)
    Ks = np.zeros((K_steps, m, 2 * n))
    jm = jac.map(K_steps)
    A_all, B_all = (np.array(v) for v in jm(x_ref.T, u_ref.T))
    A_all = A_all.reshape(2 * n, K_steps, 2 * n).transpose(1, 0, 2)
    B_all = B_all.reshape(2 * n, K_steps, m).transpose(1, 0, 2)
    for k in range(K_steps - 1, -1, -1):
        A, B = A_all[k], B_all[k]
        Kk = np.linalg.solve(Rm + B.T @ P @ B, B.T @ P @ A)
        P = Qm + A.T @ P @ (A - B @ Kk)
        P = 0.5 * (P + P.T)
        Ks[k] = Kk
    if not (np.all(np.isfinite(Ks)) and np.all(np.isfinite(K_goal))):
        raise EquilibriumError("the time-varying LQR's gains are not finite (extreme weights or a stiff motion: try a "
                               "smaller dt)")
    return Tracking(dt, x_ref, u_ref, Ks, K_goal, goal, trajectory.umax, joints, trajectory, Qm, Rm, Qfm)


# -- reaching the goal in a given time; the shortest such time ------------------------------------------
#: The speeds' weight [s] in the end's error (an angle's error of 1 rad weighs as a speed's of 10 rad/s).
END_SPEED_SCALE = 0.1
#: The end's error (angles [rad], speeds times END_SPEED_SCALE) below which a reach counts as arrived.
END_TOLERANCE = 1e-6
#: :func:`shortest_swingup`'s durations tried for a first reach: the longest, then each this share of the one before.
LADDER = 0.8


def _end_error(ca, x, x_goal, free, n):
    """The error of the end state ``x`` from ``x_goal``: each angle not ``free`` through its cosine and sine
    (any number of turns reaches it), every speed scaled by :data:`END_SPEED_SCALE`."""
    parts = []
    for j in range(n):
        if j + 1 not in free:
            parts += [ca.cos(x[j]) - math.cos(x_goal[j]), ca.sin(x[j]) - math.sin(x_goal[j])]
    return ca.vertcat(*parts, END_SPEED_SCALE * x[n:])


class _Reach:
    """The fixed-duration reach's NLP, built once for a model, its limits, start, goal and knots: the states at
    ``knots + 1`` knots over the duration ``T`` (a parameter), the torques linear between them, each interval one
    RK4 step (:func:`casadi_dynamics`); the end's error ``e`` equals a slack ``s`` bounded by ``+-S`` (``S`` a
    parameter); the objective ``rho |s|^2`` plus the torques' mean square over ``umax^2``.  ``S`` large: the end
    as a penalty (a start from anywhere gets near); ``S = 0``: the end exactly, the torques' least effort."""

    RHO = 1e3

    def __init__(self, chain, joints, umax, x_start, x_goal, free, knots, max_iter):
        ca, rhs, step, _ = casadi_dynamics(chain, joints)
        n, m, N = chain.n, len(joints), knots
        self.ca, self.rhs, self.step, self.n, self.m, self.N = ca, rhs, step, n, m, N
        self.umax, self.x_start, self.x_goal, self.free = umax, x_start, x_goal, free
        opti = ca.Opti()
        X, U, T, S = opti.variable(2 * n, N + 1), opti.variable(m, N + 1), opti.parameter(), opti.parameter()
        e = _end_error(ca, X[:, N], x_goal, free, n)
        s = opti.variable(e.shape[0])
        h = T / N
        opti.subject_to(ca.vec(step.map(N)(X[:, :N], U[:, :N], U[:, 1:], h) - X[:, 1:]) == 0)
        opti.subject_to(X[:, 0] == ca.DM(x_start))
        opti.subject_to(opti.bounded(-umax, ca.vec(U), umax))
        opti.subject_to(U[:, N] == 0)  # the goal held by no torque
        opti.subject_to(e == s)
        opti.subject_to(opti.bounded(-S, s, S))
        effort = ca.sumsqr(U[:, :N] + U[:, 1:]) / (4 * N * m * umax ** 2)
        opti.minimize(self.RHO * ca.sumsqr(s) + effort)
        opti.solver("ipopt", {"expand": True, "print_time": False},
                    {"print_level": 0, "sb": "yes", "max_iter": int(max_iter), "tol": 1e-9,
                     "bound_relax_factor": 0.0})  # the torques within the limit exactly, not IPOPT's 1e-8 beyond
        self.opti, self.X, self.U, self.T, self.S, self.e = opti, X, U, T, S, e

    def simulate(self, duration, torques):
        """The knots' states from the start under the knots' ``torques`` (m, N + 1), by the NLP's own RK4 steps."""
        h = duration / self.N
        x = [self.x_start]
        for k in range(self.N):
            x.append(np.array(self.step(x[-1], torques[:, k], torques[:, k + 1], h)).ravel())
        return np.array(x).T

    def solve(self, duration, X0, U0):
        """From the guess ``(X0, U0)``: the penalty's solve, then the exact end's from it.  ``(arrived, X, U,
        end's error, IPOPT's status)``."""
        opti = self.opti
        opti.set_value(self.T, duration)
        values = (X0, U0)
        status = "not solved"
        for bound in (1e6, 0.0):  # CasADi's parameters are finite: 1e6 leaves the end's error (below 4) free
            opti.set_value(self.S, bound)
            opti.set_initial(self.X, values[0])
            opti.set_initial(self.U, values[1])
            try:
                sol = opti.solve()
            except RuntimeError:
                sol = opti.debug
            status = opti.stats()["return_status"]
            _interrupted(status)
            values = (np.array(sol.value(self.X)).reshape(2 * self.n, self.N + 1),
                      np.array(sol.value(self.U)).reshape(self.m, self.N + 1))
            error = float(np.max(np.abs(np.array(sol.value(self.e)))))
            if bound and error > 1e-2:  # the penalty left it far: no exact end from here
                break
        arrived = status in ("Solve_Succeeded", "Solved_To_Acceptable_Level") and error <= END_TOLERANCE
        return arrived, values[0], values[1], error, status

    def guesses(self, duration, attempts, rng):
        """The starts: the start state held, no torque; then seeded smooth torques (a few sines of random
        frequencies and phases, up to the limit) simulated from the start."""
        tau = np.linspace(0.0, 1.0, self.N + 1)
        out = [(np.repeat(self.x_start[:, None], self.N + 1, axis=1), np.zeros((self.m, self.N + 1)))]
        for _ in range(int(attempts) - 1):
            U = np.zeros((self.m, self.N + 1))
            for r in range(self.m):
                for _ in range(3):
                    U[r] += rng.uniform(-1, 1) * np.sin(2 * np.pi * rng.uniform(0.5, 4.0) * tau + rng.uniform(0, 2 * np.pi))
            U = np.clip(U * self.umax, -self.umax, self.umax)
            U[:, -1] = 0.0
            out.append((self.simulate(duration, U), U))
        return out


def _reach_setup(model, actuated, umax, goal, start, free, knots, max_iter, attempts, seed):
    """The checked arguments of :func:`timed_swingup` and :func:`shortest_swingup`: the chain, the actuated
    joints, the goal's state and the reach's NLP."""
    from ..numeric.control import actuated_joints
    from .control import controllability, equilibrium_argument, hanging_rest, linearization
    from .equilibria import find_equilibrium

    chain = _as_chain(model)
    n = chain.n
    joints = actuated_joints(actuated, n)
    if isinstance(umax, bool) or not (isinstance(umax, (int, float)) and math.isfinite(umax) and umax > 0):
        raise ParameterError(f"umax must be a positive torque limit [N m], got {umax!r}")
    if isinstance(free, (str, bytes)) or not hasattr(free, "__iter__") or any(
            isinstance(j, bool) or not isinstance(j, (int, np.integer)) or not 1 <= j <= n for j in free):
        raise ParameterError(f"free must be joints' numbers (1 .. {n}) whose end angle is free, got {free!r}")
    free = tuple(sorted(set(int(j) for j in free)))
    if len(free) == n:
        raise ParameterError(f"free must leave at least one joint's end angle to reach, got {free!r}")
    if not (isinstance(knots, int) and not isinstance(knots, bool) and 10 <= knots <= 2000):
        raise ParameterError(f"knots must be a whole number of intervals, 10 to 2000, got {knots!r}")
    for name, value, low in (("attempts", attempts, 1), ("max_iter", max_iter, 1), ("seed", seed, 0)):
        if isinstance(value, bool) or not isinstance(value, (int, np.integer)) or value < low:
            raise ParameterError(f"{name} must be a whole number >= {low}, got {value!r}")
    x_start = hanging_rest(chain) if start is None else _state("start", start, n)
    eq = find_equilibrium(chain, equilibrium_argument(goal, chain, "goal"), "goal")
    x_goal = _state("goal's state", eq.state, n)
    lin = linearization(chain, eq.label, joints, coulomb="smoothed")
    c = controllability(lin.A, lin.B)
    if not c["controllable"] or c["distance"] < 1e-10:
        raise EquilibriumError(f"the goal {eq.label} cannot be held with the joints {', '.join(map(str, joints))} actuated: "
                               f"the linearisation is not controllable (rank {c['rank']} of {lin.A.shape[0]})")
    from ..progress import stage

    stage(f"swing-up in a given time: building IPOPT's problem (CasADi, {knots} knots)")
    return chain, joints, x_goal, _Reach(chain, joints, float(umax), x_start, x_goal, free, knots, max_iter)


def _duration(name: str, value) -> float:
    if isinstance(value, bool) or not isinstance(value, (int, float, np.integer, np.floating)) \
            or not (math.isfinite(value) and 0 < value <= 60):
        raise ParameterError(f"{name} must be a duration in (0, 60] s, got {value!r}")
    return float(value)


def _reached(reach, chain, joints, duration, X, U, arrived, error, status, solve_time, attempts) -> OptimalTrajectory:
    """The reach's answer as an :class:`OptimalTrajectory` (its goal the end state reached: a free joint's angle
    where it ended; ``ok`` only if it arrived and that end is a rest, no acceleration without torque)."""
    n = chain.n
    x, u = X.T.copy(), np.zeros((reach.N + 1, n))
    u[:, [j - 1 for j in joints]] = U.T
    goal = reach.x_goal.copy()
    goal[:n] = x[-1, :n]  # the angles reached (a turn more or less, a free joint's own)
    goal[n:] = 0.0
    if arrived:
        rest = float(np.max(np.abs(np.array(reach.rhs(goal, np.zeros(len(joints)))).ravel()[n:])))
        if rest > 1e-6:
            arrived = False
            status = f"the end is no rest: accelerations {rest:.3g} rad/s^2 without torque (a free joint not cyclic)"
    if arrived:
        message = f"reached the goal at rest in {duration:g} s (IPOPT {status}, end's error {error:.2g})"
    else:
        message = (f"the goal is not reached in {duration:g} s within the torque limit {reach.umax:g} N m from "
                   f"{attempts} starts (closest end's error {error:.3g}; {status})")
    t = np.linspace(0.0, duration, reach.N + 1)
    predicted = {"effort": float(np.sum((U[:, :-1] + U[:, 1:]) ** 2) / (4 * reach.N * max(U.shape[0], 1) * reach.umax ** 2)),
                 "end_error": error}
    return OptimalTrajectory(t, x, u, chain, joints, goal, reach.umax, bool(arrived), message, predicted, solve_time,
                             int(attempts))


def _reach_from(reach, duration, guesses):
    """The first guess that arrives, else the closest: ``(arrived, X, U, error, status)``."""
    from ..progress import detail

    best = None
    for k, (X0, U0) in enumerate(guesses):
        detail(f"{duration:.4g} s: start {k + 1} of {len(guesses)}")
        result = reach.solve(duration, X0, U0)
        if result[0]:
            return result
        if best is None or result[3] < best[3]:
            best = result
    return best


def _timed_swingup(model, duration: float, *, actuated=(2,), umax: float = PROTOCOL.umax, goal=EVERY_LINK_UP,
                  start=None, free=(), knots: int = 100, attempts: int = 4, seed: int = 0,
                  max_iter: int = 1000) -> OptimalTrajectory:
    """The swing-up of ``model`` from ``start`` (default: at rest in the model's hanging rest,
    :func:`~skewpend.analysis.control.hanging_rest`: ``(pi, 0)`` for the DeepMind acrobot, whose zero is upright) that reaches ``goal`` (an
    equilibrium's label, an ``Equilibrium`` or angles near one) at rest in exactly ``duration`` [s] with the
    ``actuated`` joints' torques within ``umax`` [N m], the torques' mean square least (direct multiple
    shooting with IPOPT on the chain's equations: ``knots`` intervals, each one RK4 step, the torques linear
    between knots).  The end's angles are reached modulo a turn; those of the joints in ``free`` (cyclic
    joints, e.g. a rotary pendulum's arm) may end anywhere -- the returned ``goal`` is the rest reached.

    Each of ``attempts`` starts (the start state held; then seeded smooth torques simulated) is solved with the
    end as a penalty, then exactly from there; the first that arrives is returned.  None arriving: ``ok`` False
    and the closest in ``message`` (never returned as a reach).  Track it with :func:`tvlqr`."""
    import time as _time

    duration = _duration("duration", duration)
    chain, joints, _, reach = _reach_setup(model, actuated, umax, goal, start, free, knots, max_iter, attempts, seed)
    from ..progress import stage

    stage(f"swing-up in {duration:g} s: IPOPT from {attempts} starts")
    t0 = _time.perf_counter()
    result = _reach_from(reach, duration, reach.guesses(duration, attempts, np.random.default_rng(seed)))
    return _reached(reach, chain, joints, duration, *result[1:3], result[0], result[3], result[4],
                    _time.perf_counter() - t0, attempts)


def _shortest_swingup(model, *, actuated=(2,), umax: float = PROTOCOL.umax, goal=EVERY_LINK_UP, start=None, free=(),
                     durations: Tuple[float, float] = (0.1, 4.0), resolution: float = 0.01, knots: int = 100,
                     attempts: int = 4, seed: int = 0, max_iter: int = 1000) -> OptimalTrajectory:
    """The shortest swing-up of ``model`` (as :func:`timed_swingup` reaches: from ``start`` to ``goal`` at rest,
    ``free`` joints' end angles free, torques within ``umax``) with its duration in ``durations`` [s], to
    ``resolution`` [s]: a first reach at the longest duration (from :func:`timed_swingup`'s ``attempts``
    starts), else at each :data:`LADDER` of the one before down to the shortest; then bisection below it --
    each trial warm-started from the shortest reach so far (its knots on the new duration), then from the
    seeded starts.  Returned: the shortest reach found (``ok``), its duration
    :attr:`OptimalTrajectory.duration`; the longest tried below it not reached is in ``message``.  None
    reached: ``ok`` False.  (A local optimiser's answer: a shorter reach from starts it did not try is not
    excluded; the bound below is that no trial shorter reached.)"""
    import time as _time

    lo, hi = (_duration("durations", v) for v in (durations if hasattr(durations, "__len__") and len(durations) == 2
                                                  else (None, None)))
    if not lo < hi:
        raise ParameterError(f"durations must be (shortest, longest) with shortest < longest, got {durations!r}")
    resolution = _duration("resolution", resolution)
    chain, joints, _, reach = _reach_setup(model, actuated, umax, goal, start, free, knots, max_iter, attempts, seed)
    from ..progress import stage

    stage(f"the shortest swing-up: bisecting {lo:g}..{hi:g} s to {resolution:g} s")
    rng = np.random.default_rng(seed)
    t0 = _time.perf_counter()
    # the first reach: the longest duration, else shorter ones (a local optimiser may miss a long swing-up of
    # several swings where a shorter one of fewer is found)
    best_T = hi
    while True:
        best = _reach_from(reach, best_T, reach.guesses(best_T, attempts, rng))
        if best[0] or best_T * LADDER <= lo:
            break
        best_T *= LADDER
    if not best[0]:
        out = _reached(reach, chain, joints, best_T, *best[1:3], False, best[3], best[4], _time.perf_counter() - t0,
                       attempts)
        return replace(out, message=f"{out.message}; nor in any duration tried from {hi:g} s down (each {LADDER:g} of "
                                    f"the one before)")
    failed, tried = lo, False
    while best_T - failed > resolution:
        T = 0.5 * (best_T + failed)
        result = _reach_from(reach, T, [(best[1], best[2])] + reach.guesses(T, attempts, rng)[1:])
        if result[0]:
            best, best_T = result, T
        else:
            failed, tried = T, True
    out = _reached(reach, chain, joints, best_T, *best[1:3], True, best[3], best[4], _time.perf_counter() - t0, attempts)
    return replace(out, message=f"{out.message}; " + (f"not reached in {failed:.4g} s" if tried else
                                                      f"within {resolution:g} s of the durations' shortest, {lo:g} s"))


def _swingup_tracking(model, duration: float, *, actuated=(2,), umax: float = PROTOCOL.umax, goal=EVERY_LINK_UP,
                     start=None, free=(), margin: float = 0.9, knots: int = 200, dt: float = PROTOCOL.dt, Q=None,
                     R=None, attempts: int = 4, seed: int = 0) -> Tracking:
    """A swing-up controller within a torque limit: :func:`timed_swingup` in ``duration`` [s] with the torques
    within ``margin`` x ``umax`` (the rest of the limit left to the feedback), tracked by :func:`tvlqr` -- its
    law clipped to ``umax`` -- which hands over to the goal's LQR at the end (the rest reached: a ``free``
    joint's angle where the swing-up left it).  Weights scaled by the limit (a radian's error against the whole
    torque): default ``Q = diag(1, ..., 0.1, ...)`` (angles, speeds), ``R = 1 / umax^2`` per motor.  A reach
    not found (``duration`` too short for the limit): one :class:`~skewpend.errors.ParameterError` with the
    optimiser's message."""
    if isinstance(margin, bool) or not isinstance(margin, (int, float)) or not 0 < margin <= 1:
        raise ParameterError(f"margin must be the share of the torque limit the swing-up may use, in (0, 1], got "
                             f"{margin!r}")
    if isinstance(umax, bool) or not (isinstance(umax, (int, float)) and math.isfinite(umax) and umax > 0):
        raise ParameterError(f"umax must be a positive torque limit [N m], got {umax!r}")
    plan = _timed_swingup(model, duration, actuated=actuated, umax=margin * umax, goal=goal, start=start, free=free,
                         knots=knots, attempts=attempts, seed=seed)
    if not plan.ok:
        raise ParameterError(f"no swing-up to track: {plan.message}")
    n, m = plan.chain.n, len(plan.actuated)
    Q = np.diag([1.0] * n + [0.1] * n) if Q is None else Q
    R = np.eye(m) / umax ** 2 if R is None else R
    return tvlqr(replace(plan, umax=float(umax)), dt=dt, Q=Q, R=R)


timed_swingup = _interruptible(_timed_swingup)
shortest_swingup = _interruptible(_shortest_swingup)
swingup_tracking = _interruptible(_swingup_tracking)
