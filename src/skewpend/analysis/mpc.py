"""Model-predictive control on the generated dynamics: a real-time iteration, compiled, for any model.

:class:`MPC` is a controller: at each call it takes the state, solves one quadratic programme and returns
the torques of the actuated joints.  The optimal control problem over the next ``horizon`` seconds:

* the model (the double pendulum as the chain of two, any chain, any skew) from the recursive algorithms
  (:func:`skewpend.numeric.recursive.chain_functions`, CasADi's graph, as the optimal swing-ups use it),
  ``nodes`` intervals of one classical RK4 step each, the torques held over an interval and bounded by the
  motors' limits;
* the cost of a node's state ``x``: ``energy ((E(x) - E*) / (E* - E0))^2`` (the mechanical energy's distance
  to the goal's ``E*``, in units of the goal's height in energy above the lowest rest ``E0``, the hanging one: what swings the rods up
  from anywhere; the speeds of cyclic joints -- whose angle the potential does not depend on, as the rotary
  pendulum's arm about its vertical hinge -- left out of ``E``, so that turning them buys no energy) plus ``angle |q - q*|^2 + speed |q' - q*'|^2`` (the goal's angles taken nearest the present
  ones: a turn more or less is the same goal) and ``torque |u|^2``; at the horizon's end the goal's discrete LQR
  cost-to-go (the Riccati solution of the same RK4 step about the goal, weights ``terminal``), so that near
  the goal the controller is that LQR;
* solved by a **real-time iteration** (Diehl et al. 2005; acados' SQP-RTI, the 2025 competition winner's
  method): one Gauss-Newton step a call from the previous call's torques (shifted by the time passed),
  single shooting condensed onto the torques (the states' exact derivatives by CasADi's automatic
  differentiation of the RK4 step), the box-constrained quadratic programme solved by DAQP (Arnström et al.
  2022, the active-set solver CasADi ships and generates code for);
* all of it one C function, CasADi's code generator's output compiled through skewpend's cache (a second
  to build, then loaded): one call a control step, no Python in the solve;
* a late measurement (``MPCSettings.delay``, or ``max_delay`` to estimate it at each call from the positions):
  the state carried over the delay by the torques applied in it, before the programme (a predictor as Smith's).

A step whose programme fails (non-finite data -- a rollout that diverges --, a solver status) is solved once more
from zero torques with the warm start's iterations (:attr:`MPC.restarts` counts those); failing again, the motors
brake their joints (``-umax q'/max(|q'|, BRAKE_SPEED)``: energy out, never a silent zero) and the next call starts
from zero -- counted and said (:attr:`MPC.fallbacks`, :attr:`MPC.message`).  Each solve's
wall time and CPU time are kept (:attr:`MPC.solve_times`, :attr:`MPC.solve_cpu_times`; bounded: the last
:data:`TIMES_KEPT`).

The DFKI lab's controller interface (``get_control_output(x, t)``, ``init()``, ``reset()``, ``save(dir)``)
makes it a controller of their ``Simulator`` and benchmark code unchanged; :meth:`MPC.controller` makes it a
:class:`skewpend.Controller` for :func:`skewpend.simulate` (a Python law: the slow path, sampled every
``period``).  A call at an earlier time than the last one starts a new run (the plan forgotten, as
:meth:`MPC.reset`); :class:`~skewpend.analysis.trajopt.SpeedObserver` gives it speeds from positions.
"""

from __future__ import annotations

import ctypes
import math
import time
from dataclasses import asdict, dataclass, replace
from pathlib import Path
from typing import Optional, Tuple

import numpy as np

from ..errors import ParameterError, require
from .control import EVERY_LINK_UP

__all__ = ["MPC", "MPCSettings", "mpc_swingup", "cyclic_joints", "TIMES_KEPT", "PERIOD", "BRAKE_SPEED", "HORIZON",
           "MAX_DELAY_STEPS", "DELAY_FORGETTING", "BOARD_SETTINGS",
           "HORIZON_TIME_CONSTANTS"]

#: How many solve times an :class:`MPC` keeps (its last ones): memory stays bounded over any run.
TIMES_KEPT = 1_000_000
#: The speed [rad/s] below which a failed step's braking torque is proportional to the joint's speed (above it: -umax
#: times the speed's sign).
BRAKE_SPEED = 1.0
#: The longest default horizon [s] (the 2025 competition winner's, on the DFKI rig) and the time constants of the
#: goal's fastest unstable mode it spans at most: the DFKI rig's grows at 9.35/s (0.5 s = 4.7 of them); the rotary
#: pendulum's at 14.6/s takes 0.32 s (held from 0.05 rad off the top; 0.5 s loses it: benchmarks/bench_rotary_mpc.py).
HORIZON = 0.5
HORIZON_TIME_CONSTANTS = 4.7
#: The longest delay an :class:`MPC` predicts over, in sampling periods (``MPCSettings.delay``).
MAX_DELAY_STEPS = 200
#: The weight of a call's misfit in the delay's estimate at the next call (``MPCSettings.max_delay``): the misfits'
#: memory is about 1 / (1 - 0.99) = 100 calls (0.2 s at the leaderboard's 2 ms).
DELAY_FORGETTING = 0.99
#: The default sampling of :meth:`MPC.controller` [s]: the leaderboard's step (a solve each step of its protocol;
#: the 2025 competition's winner solved at 400 Hz).
PERIOD = 0.002


@dataclass(frozen=True)
class MPCSettings:
    """The optimal control problem of an :class:`MPC` (see the module): ``horizon`` [s] over ``nodes`` RK4
    intervals (default None: :data:`HORIZON` s, or :data:`HORIZON_TIME_CONSTANTS` time constants of the goal's
    fastest unstable mode if that is shorter -- a condensed single-shooting step over many of them is
    ill-conditioned); the weights of the energy's distance (dimensionless, per node), the angles' [1/rad^2], the
    speeds' [s^2/rad^2] and the torques' [1/(N m)^2]; ``terminal``: the goal LQR's weights (angle, speed,
    torque) whose cost-to-go ends the horizon; ``iterations``: Gauss-Newton steps a call (1: the real-time
    iteration), ``first``: steps at the first call and at a restart (from zero torques; five take about 1.3 ms,
    within the 400 Hz budget); ``substeps``: RK4 steps
    an interval (a fast motion's rollout stays finite with more); ``delay`` [s]: the age assumed of the state the
    controller is given (a measurement's latency): before the programme is solved, the state is carried over it
    -- rounded to whole sampling periods -- by the torques the controller applied in that time (RK4 steps of the
    period, in the compiled solve), a predictor as Smith's; 0: the state taken as the present one.
    ``max_delay`` [s] > 0: the delay is **estimated** at each call, whole periods from 0 to ``max_delay``
    (``delay`` the first guess): the one under which the torques applied best explain the accelerations the
    positions show (their second differences against the model's ``a0(x) + B(x) u``, the squared misfits
    summed with the weight :data:`DELAY_FORGETTING` per call) -- calls every sampling period assumed."""

    horizon: Optional[float] = None
    nodes: int = 20
    energy: float = 200.0
    angle: float = 10.0
    speed: float = 1.0
    torque: float = 1e-3
    terminal: Tuple[float, float, float] = (10.0, 1.0, 1e-2)
    iterations: int = 1
    first: int = 5
    substeps: int = 2
    delay: float = 0.0
    max_delay: float = 0.0

    def check(self) -> None:
        def positive(name, v, zero=False):
            ok = isinstance(v, (int, float, np.floating)) and not isinstance(v, bool) and math.isfinite(v) and (
                v >= 0 if zero else v > 0)
            if not ok:
                raise ParameterError(f"{name} must be a {'non-negative' if zero else 'positive'} number, got {v!r}")

        if self.horizon is not None:
            positive("horizon", self.horizon)
        for name in ("energy", "angle", "speed", "delay", "max_delay"):
            positive(name, getattr(self, name), zero=True)
        positive("torque", self.torque)
        for name, lo, hi in (("nodes", 2, 200), ("iterations", 1, 50), ("first", 1, 500), ("substeps", 1, 20)):
            v = getattr(self, name)
            if not (isinstance(v, (int, np.integer)) and not isinstance(v, bool) and lo <= v <= hi):
                raise ParameterError(f"{name} must be a whole number from {lo} to {hi}, got {v!r}")
        if len(tuple(self.terminal)) != 3:
            raise ParameterError(f"terminal must be the goal LQR's three weights (angle, speed, torque), got "
                                 f"{self.terminal!r}")
        for name, v in zip(("terminal angle", "terminal speed", "terminal torque"), self.terminal):
            positive(name, v)


#: The MPC the RealAIGym boards run (``control leaderboard --controller mpc``, the v3 board's default;
#: ``benchmarks/bench_mpc.py``), one for every board: two Gauss-Newton steps a call and the angles weighted 30 (chosen
#: on the v3 board's seeds 1-4, never its reported seed 0), the delay estimated up to the robustness board's longest
#: (0.04 s, its definition's).
BOARD_SETTINGS = MPCSettings(iterations=2, angle=30.0, max_delay=0.04)


def _daqp_archive() -> Tuple[str, str]:
    """CasADi's DAQP: its headers' folder and static library (the generated C calls it)."""
    ca = require("casadi", "model-predictive control (CasADi)")
    root = Path(ca.__file__).resolve().parent
    archive = root / "libdaqpstat.a"
    if not (archive.is_file() and (root / "include" / "daqp" / "api.h").is_file() and ca.has_conic("daqp")):
        raise ParameterError(f"model-predictive control needs CasADi's DAQP solver (CasADi 3.7 or later; this is "
                             f"{ca.__version__}): pip install -U casadi")
    return str(root / "include"), str(archive)


def _step_functions(chain, joints: Tuple[int, ...], h: float, substeps: int = 1, period: Optional[float] = None):
    """CasADi: the interval ``F(x, u)`` over ``h`` (``substeps`` RK4 steps, the torque held) with its Jacobians,
    the energy ``E(x)`` and (with ``period``) the delay's: ``ahead(x, u)``, one RK4 step over the period, the torque
    held, and ``accel(x) -> (a0, B)``, the accelerations ``a0 + B u`` (affine in the torques)."""
    import casadi as ca

    from ..numeric.recursive import chain_functions, parameter_vector, structure_of_chain
    from .trajopt import casadi_dynamics

    _, rhs, step, _ = casadi_dynamics(chain, joints)
    nx, m = 2 * chain.n, len(joints)
    x, u = ca.SX.sym("x", nx), ca.SX.sym("u", m)
    nxt = x
    for _ in range(substeps):
        nxt = step(nxt, u, u, h / substeps)
    J = ca.Function("J", [x, u], [ca.jacobian(nxt, x), ca.jacobian(nxt, u), nxt])
    energy = chain_functions(structure_of_chain(chain))["energy"]
    p = ca.DM(parameter_vector(chain))
    n = chain.n
    cyclic = cyclic_joints(ca.Function("V", [x], [energy(ca.vertcat(x[:n], ca.DM.zeros(n)), p)]), n)
    keep = ca.DM([0.0 if k in cyclic else 1.0 for k in range(n)])
    E = ca.Function("E", [x], [energy(ca.vertcat(x[:n], keep * x[n:]), p)])
    if period is None:
        return J, E, None, None
    acc = rhs(x, u)[n:]
    ahead = ca.Function("ahead", [x, u], [step(x, u, u, period)])
    accel = ca.Function("accel", [x], [ca.substitute(acc, u, ca.DM.zeros(m)), ca.substitute(ca.jacobian(acc, u), u,
                                                                                            ca.DM.zeros(m))])
    return J, E, ahead, accel


def cyclic_joints(V, n: int, samples: int = 8) -> Tuple[int, ...]:
    """The joints (0-based) whose angle the potential ``V(x)`` (a CasADi function of the state, read at its angles)
    does not depend on -- a vertical hinge's, as the rotary pendulum's arm -- found at seeded random angles."""
    import casadi as ca

    x = ca.SX.sym("x", 2 * n)
    grad = ca.Function("g", [x], [ca.gradient(V(x), x)[:n]])
    rng = np.random.default_rng(0)
    G = np.array([np.array(grad(np.r_[rng.uniform(-np.pi, np.pi, n), np.zeros(n)])).ravel() for _ in range(samples)])
    scale = max(float(np.abs(G).max()), np.finfo(float).tiny)
    return tuple(int(k) for k in np.flatnonzero(np.abs(G).max(axis=0) <= 1e-12 * scale))


def _lowest_rest(E, n: int) -> float:
    """The energy of the lowest rest among the joints at 0 or pi each (every combination up to 12 joints, 4,096
    seeded ones beyond): the hanging rest's energy ``E0`` whatever the model's zero (the DeepMind Control Suite's
    acrobot is upright at q = 0)."""
    import itertools

    if n <= 12:
        angles = np.array(list(itertools.product((0.0, np.pi), repeat=n)))
    else:
        angles = np.random.default_rng(0).integers(0, 2, (4096, n)) * np.pi
    states = np.hstack([angles, np.zeros_like(angles)])
    return float(np.min(np.array(E.map(len(states))(states.T)).ravel()))


def _rti_function(J, E, goal: np.ndarray, settings: MPCSettings, P: np.ndarray, scale: float, e_goal: float,
                  m: int, umax: np.ndarray, ahead=None, accel=None, past: int = 0):
    """One real-time iteration as a CasADi function ``sp_mpc(x0, U, goal) -> U'`` (see the module); with ``past``
    > 0, ``sp_mpc(x0, U, goal, Up, keep) -> (U', a0, B)``: ``x0`` first carried by ``ahead`` (a period's step) under
    those of the ``past`` torques ``Up`` (m, past; the oldest first) whose ``keep`` is 1 (the delay's predictor), and
    ``accel`` at the ``x0`` given (the delay's estimate reads it at the next call)."""
    import casadi as ca

    nx, N, n = goal.size, settings.nodes, goal.size // 2
    x, g = ca.SX.sym("x", nx), ca.SX.sym("g", nx)
    w = np.sqrt(np.r_[[settings.angle] * n, [settings.speed] * n])
    stage = ca.vertcat(math.sqrt(settings.energy) * (E(x) - e_goal) / scale, ca.DM(w) * (x - g))
    end = ca.DM(np.linalg.cholesky(P).T) @ (x - g)
    rs = ca.Function("rs", [x, g], [stage, ca.jacobian(stage, x)])
    rt = ca.Function("rt", [x, g], [end, ca.jacobian(end, x)])
    x0, U, gm, Up = ca.MX.sym("x0", nx), ca.MX.sym("U", m, N), ca.MX.sym("goal", nx), ca.MX.sym("Up", m, past)
    keep = ca.MX.sym("keep", past)
    X, G = x0, ca.MX.zeros(nx, 0)
    for k in range(past):
        X = ca.if_else(keep[k], ahead(X, Up[:, k]), X)
    H, grad = ca.MX.zeros(N * m, N * m), ca.MX.zeros(N * m)
    for k in range(N):  # the states' sensitivities to the torques, node by node (single shooting, condensed)
        A, B, X = J(X, U[:, k])
        G = ca.horzcat(A @ G, B)
        r, Jr = (rs if k < N - 1 else rt)(X, gm)
        JG = ca.horzcat(Jr @ G, ca.MX.zeros(Jr.shape[0], (N - k - 1) * m))
        H += JG.T @ JG
        grad += JG.T @ r
    R = settings.torque * np.eye(N * m)
    Uv = ca.reshape(U, N * m, 1)
    H += ca.DM(R)
    grad += ca.DM(R) @ Uv
    qp = ca.conic("qp", "daqp", {"h": ca.Sparsity.dense(N * m, N * m)}, {"error_on_fail": False})
    lim = ca.DM(np.tile(umax, N))
    sol = qp(h=H, g=grad, lbx=-lim - Uv, ubx=lim - Uv)
    out = U + ca.reshape(sol["x"], m, N)
    if not past:
        return ca.Function("sp_mpc", [x0, U, gm], [out])
    return ca.Function("sp_mpc", [x0, U, gm, Up, keep], [out, *accel(x0)])


class MPC:
    """Model-predictive control of ``model`` (see the module) towards ``goal`` (an equilibrium: the default
    every link up; a label, an ``Equilibrium`` or angles near one), the ``actuated`` joints' torques within
    ``umax`` [N m] (one limit, or one per actuated joint; finite), the problem ``settings``
    (:class:`MPCSettings`).  ``period`` [s]: :meth:`controller`'s sampling (the law held between samples;
    default :data:`PERIOD`, the leaderboard's step: a solve each step of its protocol).  Building it compiles
    its C function (seconds, once: cached).  Call it as ``mpc(t, x)`` -> every joint's torques."""

    def __init__(self, model, *, actuated=(2,), umax=6.0, goal=EVERY_LINK_UP, settings: MPCSettings = MPCSettings(),
                 period: float = PERIOD):
        import scipy.linalg as sl

        from ..numeric.kernels import casadi_library
        from .control import linearization

        if not isinstance(settings, MPCSettings):
            raise ParameterError(f"settings must be an MPCSettings, got {settings!r}")
        settings.check()
        lin = linearization(model, goal, actuated)
        chain = lin.params.as_chain()
        self.model, self.settings, self.n = lin.params, settings, chain.n
        self.joints = tuple(j + 1 for j in lin.joints)
        m = len(self.joints)
        try:
            limits = np.broadcast_to(np.asarray(umax, dtype=float), (m,))
        except (TypeError, ValueError):
            limits = np.full(m, np.nan)
        if isinstance(umax, (bool, str, bytes)) or not np.all(np.isfinite(limits)) or np.any(limits <= 0):
            raise ParameterError(f"umax must be {'a finite positive torque' if m == 1 else f'one finite positive torque or {m}'}"
                                 f" [N m] (the MPC bounds every actuated joint's torque), got {umax!r}")
        self.umax = np.array(limits, dtype=float)
        self.goal = np.asarray(lin.target, dtype=float).copy()
        if settings.horizon is None:
            growth = max(float(np.max(np.linalg.eigvals(lin.A).real)), 0.0)
            horizon = HORIZON if growth * HORIZON <= HORIZON_TIME_CONSTANTS else HORIZON_TIME_CONSTANTS / growth
            settings = replace(settings, horizon=horizon)
            self.settings = settings
        self.dt = settings.horizon / settings.nodes
        try:
            self.period = float(period)
        except (TypeError, ValueError):
            self.period = math.nan
        if isinstance(period, bool) or not (math.isfinite(self.period) and self.period > 0):
            raise ParameterError(f"period must be a positive sampling time [s], got {period!r}")
        # the delay's predictor: the delay assumed (``lag``) and the longest held (``past``), in sampling periods
        self.lag, self.past = (int(round(v / self.period)) for v in (settings.delay, settings.max_delay))
        for name, v, k in (("delay", settings.delay, self.lag), ("max_delay", settings.max_delay, self.past)):
            if v > 0 and not 1 <= k <= MAX_DELAY_STEPS:
                raise ParameterError(f"{name} must be 0 or {0.5 * self.period:g} to {MAX_DELAY_STEPS * self.period:g} s "
                                     f"(half a sampling period to {MAX_DELAY_STEPS} of them; period {self.period:g} s), "
                                     f"got {v!r}")
        self.estimating = self.past > 0
        if not self.estimating:
            self.past = self.lag
        elif self.lag > self.past:
            raise ParameterError(f"delay (the first estimate) must be at most max_delay, got {settings.delay!r} > "
                                 f"{settings.max_delay!r}")
        self.lag0 = self.lag
        include, archive = _daqp_archive()
        J, E, ahead, accel = _step_functions(chain, self.joints, self.dt, settings.substeps, self.period)
        A, B, _ = (np.array(v, dtype=float) for v in J(self.goal, np.zeros(m)))
        ta, ts, tu = settings.terminal
        P = sl.solve_discrete_are(A, B, np.diag([ta] * self.n + [ts] * self.n), tu * np.eye(m))
        self.e_goal, e0 = float(E(self.goal)), _lowest_rest(E, self.n)
        scale = abs(self.e_goal - e0) or 1.0  # a goal at the lowest rest's energy (the hanging rest): the weights stand
        fn = _rti_function(J, E, self.goal, settings, P, scale, self.e_goal, m, self.umax, ahead, accel, self.past)
        self._lib = casadi_library(fn, kind="mpc", flags=("-I", include), archives=(archive,))
        self._bind()
        self.reset()

    # -- the compiled call ---------------------------------------------------------------------------------
    def _bind(self) -> None:
        lib, LL, dp = self._lib, ctypes.c_longlong, ctypes.POINTER(ctypes.c_double)
        sizes = [LL() for _ in range(4)]
        lib.sp_mpc_work(*[ctypes.byref(s) for s in sizes])
        n_arg, n_res, n_iw, n_w = (max(int(s.value), 1) for s in sizes)
        self._iw = (LL * n_iw)()
        self._w = np.zeros(n_w)
        self._x0 = np.zeros(2 * self.n)
        self._U = np.zeros((self.settings.nodes, len(self.joints)))  # row per node: CasADi's column-major (m, N)
        self._g = np.zeros(2 * self.n)
        self._out = np.zeros_like(self._U)
        # the torques applied, the newest last: the predictor's are the last ``past``, the estimate's two more
        self._applied_torques = np.zeros((self.past + 2, len(self.joints)))
        self._keep = np.zeros(self.past)  # which of the predictor's torques carry the state (the last ``lag``)
        self._a0, self._B = np.zeros(self.n), np.zeros((len(self.joints), self.n))  # CasADi's column-major (n, m)
        inputs = (self._x0, self._U, self._g) + ((self._applied_torques[2:], self._keep) if self.past else ())
        outputs = (self._out,) + ((self._a0, self._B) if self.past else ())
        self._arg = (dp * n_arg)(*[a.ctypes.data_as(dp) for a in inputs])
        self._res = (dp * n_res)(*[a.ctypes.data_as(dp) for a in outputs])
        lib.sp_mpc.restype = ctypes.c_int
        self._mem = lib.sp_mpc_checkout()

    def _iterate(self, x: np.ndarray, goal: np.ndarray, steps: int) -> bool:
        """``steps`` Gauss-Newton steps from the plan in ``_U``; False (``_U`` kept) when one fails."""
        self._x0[:] = x
        self._g[:] = goal
        for _ in range(steps):
            status = self._lib.sp_mpc(self._arg, self._res, self._iw, self._w.ctypes.data_as(ctypes.POINTER(ctypes.c_double)),
                                      self._mem)
            out = self._out
            # DAQP's bounds hold to its tolerance (1e-6 relative); beyond: a failed programme
            if status != 0 or not np.all(np.isfinite(out)) or np.any(np.abs(out) > self.umax * (1 + 1e-6)):
                return False
            self._U[:] = np.clip(out, -self.umax, self.umax)
        return True

    # -- the law -----------------------------------------------------------------------------------------------
    def reset(self) -> None:
        """Forget the plan, the time and the statistics (a new run)."""
        self._U = getattr(self, "_U", np.zeros((self.settings.nodes, len(self.joints))))
        self._U[:] = 0.0
        self._forget_delay()
        self._t: Optional[float] = None
        self._times = np.zeros((min(TIMES_KEPT, 1024), 2))  # wall, this thread's CPU
        self._count = 0
        self.fallbacks = 0
        self.restarts = 0
        self._first_fallback: Optional[float] = None
        self.message = ""

    init = reset

    def _kept(self, column: int) -> np.ndarray:
        k, size = self._count, self._times.shape[0]
        if k <= size:
            return self._times[:k, column].copy()
        i = k % size
        return np.concatenate([self._times[i:, column], self._times[:i, column]])

    @property
    def solve_times(self) -> np.ndarray:
        """The wall times [s] of the solves so far (the last :data:`TIMES_KEPT`), in order."""
        return self._kept(0)

    @property
    def solve_cpu_times(self) -> np.ndarray:
        """The CPU times [s] this thread spent in each solve (:attr:`solve_times`' without what other processes
        took of the core: a loaded machine's measure of the work), in order."""
        return self._kept(1)

    def _record(self, start: Tuple[float, float]) -> None:
        k, size = self._count, self._times.shape[0]
        if k >= size and size < TIMES_KEPT:
            self._times = np.concatenate([self._times, np.zeros((min(size, TIMES_KEPT - size), 2))])
        self._times[k % self._times.shape[0]] = (time.perf_counter() - start[0], time.thread_time() - start[1])
        self._count = k + 1

    def _shift(self, dt: float) -> None:
        """The plan moved on by ``dt`` [s] (interpolated between its nodes, the last held)."""
        if dt <= 0:
            return
        N = self.settings.nodes
        s = np.arange(N) + dt / self.dt
        for j in range(self._U.shape[1]):
            self._U[:, j] = np.interp(s, np.arange(N), self._U[:, j])

    def plan(self) -> np.ndarray:
        """The present plan: the actuated joints' torques over the horizon's nodes, a row per node."""
        return self._U.copy()

    def __call__(self, t: float, x) -> np.ndarray:
        x = np.asarray(x, dtype=float).reshape(-1)
        if x.shape != (2 * self.n,) or not np.all(np.isfinite(x)):
            raise ParameterError(f"x must be the state, {2 * self.n} finite numbers (angles [rad], then speeds [rad/s]), "
                                 f"got {x!r}")
        start = (time.perf_counter(), time.thread_time())
        if self._t is not None and t < self._t:  # an earlier time than the last call's: a new run
            self._U[:] = 0.0
            self._forget_delay()
            self._t = None
        first = self._t is None
        passed = math.nan if first else float(t) - self._t
        if not first:
            self._shift(passed)
        self._t = float(t)
        n = self.n
        goal = self.goal.copy()  # the goal's angles taken nearest the present ones
        goal[:n] = x[:n] + (np.mod(goal[:n] - x[:n] + np.pi, 2 * np.pi) - np.pi)
        steps = self.settings.first if first else self.settings.iterations
        if self.estimating:
            self._estimate_delay(x[:n], abs(passed - self.period) <= 1e-9 * self.period)
        if not self._iterate(x, goal, steps):
            # a failed programme (a reset's jump, a plan gone stale): once more from zero torques, the warm start's
            # iterations; failing again, the motors brake their joints and the next call starts from zero
            self._U[:] = 0.0
            if self._iterate(x, goal, self.settings.first):
                self.restarts += 1
            else:
                self._U[:] = 0.0
                self.fallbacks += 1
                self._first_fallback = self._t if self._first_fallback is None else self._first_fallback
                self.message = (f"{self.fallbacks} step(s) whose programme failed twice (from the plan, then from zero "
                                f"torques) braked the motors' joints, -umax q'/max(|q'|, {BRAKE_SPEED:g} rad/s) (first at "
                                f"t = {self._first_fallback:.4g} s)")
                speeds = x[n:][[j - 1 for j in self.joints]]
                brake = -self.umax * speeds / np.maximum(np.abs(speeds), BRAKE_SPEED)
                return self._applied(brake, start)
        return self._applied(self._U[0], start)

    def _forget_delay(self) -> None:
        """A new run: no torque applied before it, the delay back to its first guess, no positions seen."""
        if hasattr(self, "_applied_torques"):
            self._applied_torques[:] = 0.0
            self._a0[:] = np.nan  # no state before the run's first
            self._set_lag(self.lag0)
        self._misfits = np.zeros(self.past + 1)
        self._positions: list = []

    def _set_lag(self, lag: int) -> None:
        self.lag = int(lag)
        self._keep[:] = 0.0
        if lag:
            self._keep[-lag:] = 1.0

    def _estimate_delay(self, q: np.ndarray, consecutive: bool) -> None:
        """The delay under which the torques applied best explain the positions' last second difference (see
        :class:`MPCSettings`), the misfits of every delay to ``past`` periods summed with forgetting.  Positions
        more than a period apart (the first call, a pause: a reset while the law was not asked) start the
        differences afresh."""
        seen = self._positions = (self._positions if consecutive else [])[-2:] + [q.copy()]
        if len(seen) < 3 or not np.all(np.isfinite(self._a0)):
            return
        from .equilibria import wrap  # the differences of angles given wrapped or not

        measured = (wrap(seen[2] - seen[1]) - wrap(seen[1] - seen[0])) / self.period ** 2
        u = self._applied_torques[::-1]  # u[0] the last call's torques, u[1] the one's before, ...
        held = 0.5 * (u[:-1] + u[1:])  # row D: the torques over the two steps the positions span, D periods old
        misfit = measured - self._a0 - held @ self._B
        self._misfits = DELAY_FORGETTING * self._misfits + np.sum(misfit ** 2, axis=1)
        self._set_lag(int(np.argmin(self._misfits)))

    @property
    def delay(self) -> float:
        """The delay [s] the predictor assumes now (``MPCSettings.delay``, or the estimate with ``max_delay``)."""
        return self.lag * self.period

    def _applied(self, torques: np.ndarray, start) -> np.ndarray:
        """Every joint's torques, the actuated ones ``torques``, which the delay's predictor remembers."""
        if self.past:
            self._applied_torques[:-1] = self._applied_torques[1:]
            self._applied_torques[-1] = torques
        self._record(start)
        out = np.zeros(self.n)
        out[[j - 1 for j in self.joints]] = torques
        return out

    # -- skewpend's and the DFKI lab's interfaces ----------------------------------------------------------------
    def controller(self):
        """This MPC as a :class:`skewpend.Controller` for :func:`skewpend.simulate`: a law sampled every
        :attr:`period` (``Controller.function(..., hold=period)``: simulate runs it by RK4 with that step, the
        MPC solved at each step's start from the state reached and its torques held over the step, as a
        digital controller's)."""
        from ..numeric.control import Controller

        held: dict = {}  # sample -> its torques (the trajectory's torques read them back)

        def law(t, x):
            k = math.floor(t / self.period + 0.5)  # the integrator's step k starts at k period
            if k not in held:
                held[k] = self(k * self.period, x)
            return held[k]

        self.reset()
        return Controller.function(law, actuated=self.joints, umax=tuple(self._limits_per_joint()), nq=self.n,
                                   hold=self.period)

    def _limits_per_joint(self):
        limits = [math.inf] * self.n
        for j, u in zip(self.joints, self.umax):
            limits[j - 1] = float(u)
        return limits

    def get_control_output(self, x, t=None):
        """The torques at the DFKI state ``x = (q1, q2, q1', q2')`` (a chain's ``2 n`` entries; q2 relative, zero
        hanging: skewpend's own) at the time ``t`` [s] (required: the plan moves on with it)."""
        from .trajopt import time_argument

        return self(time_argument(t), x)

    def save(self, save_dir):
        """The DFKI interface's ``save(save_dir)``: the controller's settings as ``controller_mpc_parameters.yml``
        (written atomically into ``save_dir``, made if missing); its path."""
        from .trajopt import save_directory, write_yaml

        entries = {"controller": "skewpend.analysis.mpc.MPC (real-time iteration, DAQP, compiled)",
                   "actuated_joints": list(self.joints), "torque_limits": self.umax.tolist(),
                   "goal": self.goal.tolist(), "goal_energy": self.e_goal, "period": self.period,
                   **{k: (list(v) if isinstance(v, tuple) else v) for k, v in asdict(self.settings).items()}}
        return write_yaml(save_directory(save_dir) / "controller_mpc_parameters.yml", entries)

    def __repr__(self) -> str:
        s = self.settings
        limits = sorted(set(self.umax.tolist()))
        return (f"MPC({self.model.title}, joints {','.join(map(str, self.joints))}, |u| <= "
                f"{', '.join(f'{u:g}' for u in limits)} N m, {s.nodes} nodes over {s.horizon:g} s"
                + (f", the delay estimated from 0 to {self.past * self.period:g} s" if self.estimating else
                   f", the state carried over a delay of {self.past * self.period:g} s" if self.past else "") + ")")


def mpc_swingup(model, target=EVERY_LINK_UP, actuated="both", *, umax=10.0, t_end: float = 10.0, y0=None,
                settings: MPCSettings = MPCSettings(), period: float = PERIOD, dt_out: float = 0.01,
                progress=None):
    """Swing any model up from ``y0`` (default: its hanging rest,
    :func:`~skewpend.analysis.control.hanging_rest` -- ``(pi, 0)`` for the DeepMind acrobot, whose zero is
    upright -- nudged by 0.05 rad at the first joint) to ``target`` by
    an :class:`MPC` (``umax`` [N m], ``settings``, sampled every ``period`` s) in :func:`skewpend.simulate` (RK4
    at the period, the torques held over each step), ``t_end`` [s] (at most
    :data:`~skewpend.analysis.control.SWINGUP_T_MAX`), rows every ``dt_out`` s: a
    :class:`~skewpend.analysis.control.SwingUp` (``law`` "model-predictive control", ``mpc`` the controller
    with its solve times) whose capture is the entry, for good, into the region of attraction estimate of the
    target's LQR (the MPC's own horizon ends in that LQR's cost).  ``progress(t, t_end)`` as the run advances.
    Every argument is checked before any work."""
    from dataclasses import replace

    from ..checks import angles, numeric_model, positive, progress_callable
    from ..numeric.simulation import simulate
    from .control import SWINGUP_T_MAX, SwingUp, capture, equilibrium_argument, hanging_rest, lqr

    params = numeric_model(model, "a swing-up")
    n = params.n
    target = equilibrium_argument(target, params, "target")
    t_end = positive("t_end", t_end, cap=SWINGUP_T_MAX)
    dt_out = positive("dt_out", dt_out, cap=t_end)
    progress = progress_callable(progress, "progress(t, t_end)")
    if y0 is None:  # the hanging rest wherever the model's zero is (the DeepMind acrobot's: upright)
        start = hanging_rest(params) + np.eye(1, 2 * n)[0] * 0.05
    else:
        try:
            start = np.array(y0, dtype=float).reshape(-1)
        except (TypeError, ValueError):
            start = np.full(1, np.nan)
        if isinstance(y0, (str, bytes)) or start.shape != (2 * n,) or not np.all(np.isfinite(start)):
            raise ParameterError(f"y0 must be {2 * n} finite numbers (the angles [rad], then the speeds [rad/s]), got "
                                 f"{y0!r}")
        angles("y0", start[:n], n)
    mpc = MPC(params, actuated=actuated, umax=umax, goal=target, settings=settings, period=period)
    if progress is not None:
        progress(0.0, t_end)
    design = lqr(params, target, actuated, umax=tuple(mpc.umax) if len(mpc.umax) > 1 else float(mpc.umax[0]))
    ctl = replace(mpc.controller(), target_energy=mpc.e_goal)  # the figure's energy line: the goal's
    tr = simulate(params, start, t_end, dt_out=max(dt_out, period), controller=ctl, progress=progress)
    return SwingUp(tr, *capture(design, tr), design, ctl, "model-predictive control", mpc)
