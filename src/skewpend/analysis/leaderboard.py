"""The RealAIGym leaderboard's protocol and score (the DFKI lab's double-pendulum benchmark), for any model.

The leaderboard (``dfki-ric-underactuated-lab/double_pendulum``, ``leaderboard/*/simulation_v2``;
its ``analysis/leaderboard.py`` defines the criteria) runs a controller on its plant by fixed-step
RK4 (``dt`` 0.002 s for 10 s), the controller asked once a step for the torques at the state, the
torques clipped to the motors' limits and held over the step; it starts hanging at rest and scores
the rows ``(t_k, x_k, u_k)``, ``u_k`` the torques held from ``t_k`` to ``t_k + dt``:

* **swing-up time** -- the first time of the last unbroken run of rows whose end effector (the tip
  of the last rod) is above ``0.9`` times the reach (the sum of the rods' lengths) (the last row
  not looked at); infinite when the run ended early;
* **success** -- that time is before the last row's;
* **energy** ``sum_k sum_j |(q_j,k+1 - q_j,k) u_j,k|`` [J];
* **torque cost** ``sum_k dt u_k . u_k`` [N^2 m^2 s], **velocity cost** ``sum_k dt q'_k . q'_k``
  (both over the rows but the last);
* **torque smoothness** ``sum_j std_k(u_j,k+1 - u_j,k)`` [N m];
* the **score** (``"v2"``): ``success * (1 - 1/5 sum_i tanh(pi c_i / n_i))`` over the swing-up
  time (``n`` 20 s), energy (60 J), torque cost (20), smoothness (0.1) and velocity cost (400).

:func:`criteria` and :func:`score` compute them from any rows (a published trajectory's, a run's);
:func:`run_protocol` runs a law by the protocol on any model (the double pendulum, a chain) in one
compiled loop (``sp_protocol``: the law, the model's RK4 step with the torques held), with the
robustness tests' delay, noise, torque response and perturbations when asked (:class:`Disturbance`);
:data:`PROTOCOL` holds the leaderboard's settings;
:func:`read_csv` and :func:`write_csv` the leaderboard's trajectory files
(``time,pos_meas1,pos_meas2,vel_meas1,vel_meas2,tau_con1,tau_con2``).

**Simulation v3** (the board of the 2025 competition; :data:`PROTOCOL_V3`, ``score(c, "v3")``) scores a global
policy over resets.  As the lab's public code defines it -- ``leaderboard/{acrobot,pendubot}/simulation_v3/``
``sim_parameters.py``, ``calculate_leaderboard_score.py``, ``sim_controller.py`` (the same for both robots but
the motor), ``src/python/double_pendulum/controller/global_policy_testing_controller.py``
(``GlobalPolicyTestingControllerV2``), ``controller/pid/point_pid_controller.py``,
``controller/abstract_controller.py`` (the gravity compensation) and ``analysis/leaderboard.py``
(``leaderboard_scores(score_version="v3")``, ``get_uptime``, ``get_number_of_swingups``) of
``dfki-ric-underactuated-lab/double_pendulum`` at 1e8544e:

* the same plant, RK4 step (``dt`` 0.002 s) and start (hanging at rest), for **60 s** (30,000 rows); the
  simulated plant has both motors (6 N m each: ``mpar_nolim``);
* **15 resets**: reset ``i`` begins at the first step whose time is at or after
  ``60 (i + 1) / 16 + U(-1, 1)`` s (``linspace(3.75, 56.25, 15)`` plus a uniform draw); for the next
  ``0.2`` s (until the sum of the clock's steps exceeds it: 100 or 101 steps, as the sums round) the law
  is not asked: a PID on every joint (``kp`` 10, ``ki`` 0.1, ``kd`` 1, its own ``dt`` 0.001 s, angles not
  wrapped, its sum of
  errors and its last error kept across resets -- it is never re-initialised) pulls the angles to a random
  state (each angle uniform in ``[-pi, pi)``, speeds 0), its torque clipped to the limit, plus the gravity
  compensation (the torques that hold the rods still where they are), the sum clipped by the plant;
  then the law takes over again from wherever the rods are.  The law gets the simulator's clock ``t`` (the
  run's, not restarted at a reset) and the state;
* the **criterion** is the uptime ``sum_k (t_k - t_(k-1))`` over the rows whose end effector is above
  ``0.9`` times the reach (``t_(-1)`` = 0: the reset phases count too); the **score** is ``1.0 *
  uptime / 60`` (weight 1, normalised by the run's length); the number of swing-ups (rows going up, more
  than 1 s after the last counted one) is reported beside it, weight 0.

The lab's draws are NumPy's global generator, unseeded; :class:`Resets` ``seed`` seeds a
``RandomState`` that draws them in the lab's order (the random states, then the jitter), so ``seed = s``
is the lab's run after ``np.random.seed(s)`` just before the wrapper is built.  The published v3 entries
(``real_ai_gym_leaderboard`` at 81ea5bc, ``data/*/simulation_icra2025/*/scores_v3.csv``) hold their uptime
and score; their trajectories (``sim_swingup.csv``, over 4 MiB each) are not in the stored copy of that
repository, so the published scores are reproduced from the published uptimes only (the tests).
"""

from __future__ import annotations

import csv
import ctypes
import math
from dataclasses import asdict, dataclass, field
from pathlib import Path
from typing import Any, Dict, Optional, Tuple

import numpy as np

from ..errors import ParameterError
from ..numeric.control import ROBOTS

__all__ = ["PROTOCOL", "Protocol", "NORMALISATION", "Criteria", "criteria", "score", "ProtocolRun", "run_protocol",
           "Disturbance", "PROTOCOL_V3", "Resets", "Uptime", "uptime_criteria", "reset_schedule", "holding_torques",
           "read_csv", "write_csv", "CSV_COLUMNS", "dfki_model", "lab_values", "ROBOTS", "PUBLISHED"]


@dataclass(frozen=True)
class Resets:
    """The simulation v3 board's resets (``GlobalPolicyTestingControllerV2`` as ``calculate_leaderboard_score.py``
    builds it; see the module): ``count`` resets, reset ``i`` due at ``t_final (i + 1) / (count + 1)`` plus a
    uniform draw in ``[-jitter, jitter]`` [s], each a PID (gains ``kp``, ``ki``, ``kd``, its own step ``pid_dt``
    [s]) plus gravity compensation towards a random state for ``length`` [s]; ``seed`` seeds the draws
    (:func:`reset_schedule`)."""

    count: int = 15
    length: float = 0.2
    jitter: float = 1.0
    kp: float = 10.0
    ki: float = 0.1
    kd: float = 1.0
    pid_dt: float = 0.001
    seed: int = 0

    def __post_init__(self):
        if isinstance(self.count, bool) or not isinstance(self.count, (int, np.integer)) or self.count < 0:
            raise ParameterError(f"count must be a whole number of resets >= 0, got {self.count!r}")
        if isinstance(self.seed, bool) or not isinstance(self.seed, (int, np.integer)) or not 0 <= self.seed < 2 ** 32:
            raise ParameterError(f"seed must be a whole number from 0 to 2**32 - 1, got {self.seed!r}")
        for name in ("length", "jitter", "kp", "ki", "kd", "pid_dt"):
            v = getattr(self, name)
            positive = name == "pid_dt"
            if isinstance(v, bool) or not (isinstance(v, (int, float, np.floating)) and math.isfinite(v)
                                           and (v > 0 if positive else v >= 0)):
                raise ParameterError(f"{name} must be a finite number {'> 0' if positive else '>= 0'}, got {v!r}")


@dataclass(frozen=True)
class Protocol:
    """The leaderboard's simulation settings: the step ``dt`` [s], the run's length ``t_final`` [s],
    the motors' torque limit ``umax`` [N m], the height fraction of the success test; ``resets`` the v3
    board's resets (:class:`Resets`; None: v2's one swing-up from hanging)."""

    dt: float = 0.002
    t_final: float = 10.0
    umax: float = 6.0
    height: float = 0.9
    resets: Optional[Resets] = None

    @property
    def steps(self) -> int:
        """The rows of a run (5000): the leaderboard's simulator steps until ``t >= t_final``."""
        return int(round(self.t_final / self.dt))

    @property
    def version(self) -> str:
        """The board's score this protocol's runs get: ``"v3"`` with resets, else ``"v2"``."""
        return "v2" if self.resets is None else "v3"


#: The simulation leaderboard v2's settings.
PROTOCOL = Protocol()
#: The simulation leaderboard v3's settings: 60 s, 15 resets (``sim_parameters.py``,
#: ``calculate_leaderboard_score.py``).
PROTOCOL_V3 = Protocol(t_final=60.0, resets=Resets())
#: The v3 board's swing-up count: a row going up counts when more than this long [s] after the last counted one.
DEADTIME = 1.0
#: The form of the equations the leaderboard optimises (:mod:`~skewpend.analysis.trajopt`: CasADi's graph of the
#: recursive algorithms, :func:`skewpend.numeric.recursive.chain_functions`) and runs by the protocol (the same
#: algorithms printed straight, ``kernels.model_kernel(model, FORM)``): one model, optimised and scored -- its
#: RK4 step 2.18e3 instructions on the leaderboard's plant, the exact form's 3.19e3 (callgrind).
FORM = "straight"
#: The v2 score's criteria and their normalisation constants (``calculate_leaderboard_score.py``).
NORMALISATION: Dict[str, float] = {"swingup_time": 20.0, "energy": 60.0, "tau_cost": 20.0, "tau_smoothness": 0.1,
                                   "velocity_cost": 400.0}
#: The best published entries (leaderboards v2, real_ai_gym_leaderboard at 81ea5bc): robot -> board -> (name, score).
#: ``simulation_v3``: the ICRA 2025 simulation results (``leaderboards/icra2025/ICRA_2025_*_simulation_results.csv``).
PUBLISHED: Dict[str, Dict[str, Tuple[str, float]]] = {
    "acrobot": {"simulation": ("History SAC", 0.655), "robustness": ("History SAC", 0.751),
                "simulation_v3": ("AR-EAPO", 0.658)},
    "pendubot": {"simulation": ("History SAC", 0.682), "robustness": ("AR-EAPO", 0.913),
                 "simulation_v3": ("VIMPPI", 0.799)},
}
#: The columns of the leaderboard's trajectory files.
CSV_COLUMNS = ("time", "pos_meas1", "pos_meas2", "vel_meas1", "vel_meas2", "tau_con1", "tau_con2")


@dataclass(frozen=True)
class Criteria:
    """The leaderboard's criteria of one run (see the module); ``score`` its v2 score."""

    success: bool
    swingup_time: float
    energy: float
    max_tau: float
    integ_tau: float
    tau_cost: float
    tau_smoothness: float
    velocity_cost: float

    @property
    def score(self) -> float:
        return score(self)

    def to_dict(self) -> Dict[str, Any]:
        return {**asdict(self), "success": bool(self.success), "score": self.score}


def _rows(name: str, value, width: Optional[int] = None) -> np.ndarray:
    try:
        a = np.array(value, dtype=float)
    except (TypeError, ValueError):
        raise ParameterError(f"{name} must be numbers (an array), got {type(value).__name__}") from None
    if a.ndim == 1 and width is None:
        return a
    if a.ndim != 2 or (width is not None and a.shape[1] != width):
        raise ParameterError(f"{name} must be an array of rows" + (f" of {width}" if width else "") + f", got shape {a.shape}")
    return a


def criteria(t, x, u, heights, reach: float, *, t_final: float = PROTOCOL.t_final,
             height: float = PROTOCOL.height) -> Criteria:
    """The leaderboard's criteria of the rows ``t`` (k,), states ``x`` (k, 2 n: angles, then speeds),
    torques ``u`` (k, n) held from each row to the next, and the end effector's heights ``heights``
    (k,) [m] above the roof hinge; ``reach`` the sum of the rods' lengths [m] (the success line is
    ``height * reach``).  Non-finite rows are refused."""
    t, x, u, h = (_rows(name, v) for name, v in (("t", t), ("x", x), ("u", u), ("heights", heights)))
    k = t.size
    if t.ndim != 1 or k < 3 or x.ndim != 2 or x.shape[0] != k or x.shape[1] % 2 or u.ndim != 2 or u.shape[0] != k \
            or u.shape[1] != x.shape[1] // 2 or h.shape != (k,):
        raise ParameterError(f"criteria need k >= 3 rows of times (k,), states (k, 2 n), torques (k, n) and heights (k,); "
                             f"got {t.shape}, {x.shape}, {u.shape}, {h.shape}")
    for name, a in (("t", t), ("x", x), ("u", u), ("heights", h)):
        if not np.all(np.isfinite(a)):
            raise ParameterError(f"{name} holds non-finite numbers: a run that failed has no leaderboard criteria")
    if not (math.isfinite(reach) and reach > 0):
        raise ParameterError(f"reach must be a positive length [m], got {reach!r}")
    n = x.shape[1] // 2
    if t[-1] < 0.99 * t_final:
        up_time = math.inf
    else:
        up = h > height * reach
        index = k - 1
        for i in range(k - 2, 0, -1):  # the leaderboard's loop: the last row is not looked at, nor the first
            if up[i]:
                index = i
            else:
                break
        up_time = float(t[index])
    dt = np.diff(t)
    energy = float(sum(np.sum(np.abs(np.diff(x[:, j]) * u[:-1, j])) for j in range(n)))
    tau_cost = float(np.einsum("ij,i,ij->", u[:-1], dt, u[:-1]))
    velocity_cost = float(np.einsum("ij,i,ij->", x[:-1, n:], dt, x[:-1, n:]))
    smooth = float(sum(np.std(np.diff(u[:, j])) for j in range(n)))
    return Criteria(success=bool(up_time < t[-1]), swingup_time=up_time, energy=energy,
                    max_tau=float(np.max(np.abs(u))), integ_tau=float(np.sum(np.abs(u[:-1]) * dt[:, None])),
                    tau_cost=tau_cost, tau_smoothness=smooth, velocity_cost=velocity_cost)


@dataclass(frozen=True)
class Uptime:
    """The simulation v3 board's criteria of one run (see the module): the ``uptime`` [s] above the line, the
    number of ``swingups`` (reported, weight 0), the run's length ``t_final`` [s] (the normalisation);
    ``score`` its v3 score."""

    uptime: float
    swingups: int
    t_final: float = PROTOCOL_V3.t_final

    @property
    def score(self) -> float:
        return score(self, "v3")

    def to_dict(self) -> Dict[str, Any]:
        return {**asdict(self), "score": self.score}


def uptime_criteria(t, heights, reach: float, *, t_final: float = PROTOCOL_V3.t_final,
                    height: float = PROTOCOL_V3.height, deadtime: float = DEADTIME) -> Uptime:
    """The v3 board's criteria of the rows at times ``t`` (k,) [s] whose end effector is ``heights`` (k,) [m]
    above the roof hinge, ``reach`` the sum of the rods' lengths: the uptime ``sum (t_k - t_(k-1))`` over the
    rows above ``height * reach`` (``t_(-1)`` = 0), and the swing-ups: rows above the line whose row before is
    not (the first row counts when above), at least ``deadtime`` [s] after the last one counted.  Non-finite
    rows are refused."""
    t, h = _rows("t", t), _rows("heights", heights)
    if t.ndim != 1 or t.size < 1 or h.shape != t.shape:
        raise ParameterError(f"uptime criteria need k >= 1 times (k,) and heights (k,); got {t.shape}, {h.shape}")
    for name, a in (("t", t), ("heights", h)):
        if not np.all(np.isfinite(a)):
            raise ParameterError(f"{name} holds non-finite numbers: a run that failed has no leaderboard criteria")
    if not (math.isfinite(reach) and reach > 0):
        raise ParameterError(f"reach must be a positive length [m], got {reach!r}")
    if not (isinstance(t_final, (int, float)) and math.isfinite(t_final) and t_final > 0):
        raise ParameterError(f"t_final must be a positive length of run [s], got {t_final!r}")
    up = h > height * reach
    steps = np.diff(t, prepend=0.0)
    uptime = float(np.sum(steps[up]))
    count, last_counted = 0, -deadtime
    for k in np.flatnonzero(up & ~np.concatenate(([False], up[:-1]))):  # the rows going up
        if t[k] - last_counted > deadtime:
            count, last_counted = count + 1, float(t[k])
    return Uptime(uptime=uptime, swingups=count, t_final=float(t_final))


def score(c, version: str = "v2") -> float:
    """The leaderboard's score of a run's criteria.  ``"v2"``: of :class:`Criteria` (or a mapping of the five
    criteria and ``success``), ``success * (1 - 1/5 sum_i tanh(pi c_i / n_i))``, :data:`NORMALISATION`'s ``n_i``;
    ``"v3"``: of :class:`Uptime` (or a mapping with ``uptime`` and optionally ``t_final``, default 60 s),
    ``1.0 * uptime / t_final``."""
    if version not in ("v2", "v3"):
        raise ParameterError(f"version must be 'v2' or 'v3' (the simulation boards' scores), got {version!r}")
    get = (lambda k: c[k]) if isinstance(c, dict) else (lambda k: getattr(c, k))
    if version == "v3":
        try:
            uptime = float(get("uptime"))
        except (KeyError, AttributeError, TypeError, ValueError):
            raise ParameterError("the v3 score needs the uptime [s]") from None
        try:
            t_final = float(get("t_final"))
        except (KeyError, AttributeError):
            t_final = PROTOCOL_V3.t_final
        except (TypeError, ValueError):
            raise ParameterError("t_final must be the run's length [s]") from None
        if not (math.isfinite(uptime) and uptime >= 0 and math.isfinite(t_final) and t_final > 0):
            raise ParameterError(f"the v3 score needs an uptime >= 0 and a run's length > 0 [s], got {uptime!r}, "
                                 f"{t_final!r}")
        return 1.0 * uptime / t_final
    try:
        values = {k: float(get(k)) for k in NORMALISATION}
        success = bool(get("success"))
    except (KeyError, AttributeError, TypeError, ValueError):
        raise ParameterError(f"score needs success and the criteria {', '.join(NORMALISATION)}") from None
    if not success:
        return 0.0
    total = sum(math.tanh(math.pi * values[k] / NORMALISATION[k]) for k in NORMALISATION)
    return 1.0 - total / len(NORMALISATION)


@dataclass(frozen=True)
class ProtocolRun:
    """A run by the protocol: rows ``t`` (k,), ``x`` (k, 2 n), ``u`` (k, n) the torques applied over
    each step, ``heights`` (k,) of the end effector, the model's ``reach``, the ``final`` state after the
    last step (NaN when the run stopped early); ``criteria`` and ``score``.  A v3 run's ``resets`` are the
    reset phases ``(start, end)`` [s] (the rows from ``start`` up to, not including, ``end`` driven by the reset
    PID; ``end`` NaN for one the run ended in)."""

    t: np.ndarray
    x: np.ndarray
    u: np.ndarray
    heights: np.ndarray
    reach: float
    protocol: Protocol = PROTOCOL
    message: str = ""
    final: Optional[np.ndarray] = field(default=None, repr=False)  #: the state after the last step (2 n,)
    resets: Tuple[Tuple[float, float], ...] = ()

    @property
    def ok(self) -> bool:
        return not self.message

    @property
    def criteria(self):
        """The leaderboard's criteria of the rows: :class:`Criteria` (v2), :class:`Uptime` (v3, a protocol with
        resets); a run that failed (``ok`` False) has none: IntegrationError with its ``message`` (its score
        is 0)."""
        if not self.ok:
            from ..errors import IntegrationError

            raise IntegrationError(f"a failed run has no leaderboard criteria (its score is 0): {self.message}")
        if self.protocol.resets is not None:
            return uptime_criteria(self.t, self.heights, self.reach, t_final=self.protocol.t_final,
                                   height=self.protocol.height)
        return criteria(self.t, self.x, self.u, self.heights, self.reach, t_final=self.protocol.t_final,
                        height=self.protocol.height)

    @property
    def score(self) -> float:
        return self.criteria.score if self.ok else 0.0


def model_reach(model) -> float:
    """The sum of the rods' lengths of a model (the double pendulum's ``a + b``)."""
    return float(sum(link.length for link in model.as_chain().links))


def tip_heights(kernel, p, x: np.ndarray) -> np.ndarray:
    """The heights [m] above the roof hinge of the last rod's end at the states ``x`` (k, 2 n) (``j`` points down)."""
    ends = kernel.tips_many(np.ascontiguousarray(x, dtype=float), p)
    return -ends[:, 3 * kernel.nq - 2]


@dataclass(frozen=True)
class Disturbance:
    """What the leaderboard's robustness tests change in a run (:func:`run_protocol`; all off by default):
    the law sees the state ``delay`` steps old (the start's before) with Gaussian noise of standard
    deviation ``velocity_noise`` [rad/s] on its speeds; the motors apply the previous torque plus
    ``responsiveness`` times the change to the law's, plus Gaussian noise ``torque_noise`` [N m], clipped to
    the limit, plus ``perturbation`` (an array (steps, n) [N m], added after the clip) -- the actuated
    joints only.  ``seed`` seeds NumPy's generator that draws the noise (the lab's is not seeded)."""

    delay: int = 0
    velocity_noise: float = 0.0
    torque_noise: float = 0.0
    responsiveness: float = 1.0
    perturbation: Optional[np.ndarray] = None
    seed: int = 0

    def __post_init__(self):
        if isinstance(self.delay, bool) or not isinstance(self.delay, (int, np.integer)) or self.delay < 0:
            raise ParameterError(f"delay must be a whole number of steps >= 0, got {self.delay!r}")
        for name in ("velocity_noise", "torque_noise"):
            v = getattr(self, name)
            if not (isinstance(v, (int, float, np.floating)) and math.isfinite(v) and v >= 0):
                raise ParameterError(f"{name} must be a standard deviation >= 0, got {v!r}")
        r = self.responsiveness
        if not (isinstance(r, (int, float, np.floating)) and math.isfinite(r) and r > 0):
            raise ParameterError(f"responsiveness must be a positive number (1: the motor follows at once), got {r!r}")


def _compiled_law(law, joints, umax: float, n: int):
    """``law`` as a compiled :class:`~skewpend.Controller` with the protocol's actuated joints and limit: a
    :class:`~skewpend.analysis.trajopt.Tracking` (or anything with ``controller()``) compiled, a
    Controller as given, a Python ``law(t, x)`` on the slow path."""
    from dataclasses import replace

    from ..numeric.control import Controller, actuated_joints, torque_limits

    limits = torque_limits(umax, n)
    if isinstance(law, Controller) or callable(getattr(law, "controller", None)):
        compiled = law if isinstance(law, Controller) else law.controller()
        compiled.check_model(n)
        # a law designed for other motors than the protocol's is refused (an acrobot's law scored as a pendubot's
        # would be scored for torques its design never planned)
        designed = getattr(law, "actuated", compiled.actuated)
        designed = actuated_joints(designed if isinstance(designed, str) else tuple(designed), n)
        if designed != tuple(joints):
            raise ParameterError(f"actuated ({', '.join(map(str, joints))}) must be the joints the law was designed "
                                 f"for ({', '.join(map(str, designed))}): a law for other motors is not this robot's")
        return replace(compiled, actuated=tuple(joints), umax=limits)
    if not callable(law):
        raise ParameterError(f"the law must be a callable law(t, x) -> torques, a Tracking or a Controller, got {law!r}")

    def full(t, x):
        raw = np.asarray(law(t, x), dtype=float).reshape(-1)
        if raw.size == 1 and len(joints) == 1:
            out = np.zeros(n)
            out[joints[0] - 1] = raw[0]
            return out
        if raw.shape != (n,):
            raise ParameterError(f"the law must return {n} torques (or one for the one actuated joint), got shape "
                                 f"{raw.shape}")
        return raw

    return Controller.function(full, actuated=tuple(joints), umax=limits, nq=n)


def run_protocol(model, law, *, actuated=(2,), umax: float = PROTOCOL.umax, protocol: Protocol = PROTOCOL, x0=None,
                 plant=None, plant_values: Optional[Dict[str, float]] = None,
                 disturbance: Optional[Disturbance] = None, speeds: str = "measured") -> ProtocolRun:
    """``law`` run by the protocol on ``model`` (or on ``plant``, another model of the same joints, when given:
    the controller's model and the simulated one differ), from ``x0`` (default hanging at rest) for
    ``protocol.steps`` steps, in one compiled loop (``sp_protocol``).  ``law``: a
    :class:`~skewpend.analysis.trajopt.Tracking` or a :class:`~skewpend.Controller` (compiled: no Python per
    step), or a Python ``law(t, x) -> torques`` (one per joint, or one for a single actuated joint; the slow
    path).  The model runs as :func:`~skewpend.analysis.trajopt.optimal_swingup` optimises it: in the recursive
    algorithms' :data:`FORM` (``kernels.model_kernel(model, FORM)``) -- one model, optimised and scored.
    ``actuated``: the joints' numbers with a motor (the others get 0); every torque clipped to
    ``umax``; ``disturbance`` the robustness tests' changes (:class:`Disturbance`).  ``plant_values``: entries of
    the simulated plant's run-time array set by name (``c1``, ``cf1``, ...) -- values the model itself refuses,
    as the robustness test's negative damping and friction (the plant's code must read them: its friction
    or rotor terms present).  ``speeds``: what the law takes for the speeds, ``"measured"`` (the state's)
    or ``"positions"`` (its own observer's backward differences of the positions it has seen, second order:
    no noise from the speeds, a lag of order dt^2).

    A protocol with ``resets`` (:data:`PROTOCOL_V3`) runs the v3 board's global-policy test instead (see the
    module): the law, asked with the run's clock and the state, between the resets that pull every joint to a
    random state (:func:`reset_schedule`, :func:`holding_torques`); a step at a time from Python (the model's
    compiled RK4 step, ``sp_rk4_hold``; the law's compiled inputs, ``sp_inputs_many``).  No ``disturbance``,
    ``plant_values`` or estimated speeds there (the v3 board has none)."""
    from ..numeric.control import joint_numbers, raise_law_error
    from ..numeric.kernels import model_kernel, model_vector, model_vector_names

    sim = (model if plant is None else plant).as_chain()  # once: the straight form prints the chain
    kernel = model_kernel(sim, FORM)
    p = np.ascontiguousarray(model_vector(sim, FORM), dtype=float)
    if plant_values:
        names = model_vector_names(sim, FORM)
        for name, value in plant_values.items():
            if name not in names or not math.isfinite(float(value)):
                raise ParameterError(f"plant_values: {name!r} is not a finite entry of the plant's run-time array "
                                     f"({', '.join(names)})")
            p[names.index(name)] = float(value)
    n = kernel.nq
    joints = joint_numbers(actuated, n)
    if joints is None:
        raise ParameterError(f"actuated must be the numbers of the joints with a motor, 1 to {n}, each once, got "
                             f"{actuated!r}")
    if speeds not in ("measured", "positions"):
        raise ParameterError(f"speeds must be 'measured' or 'positions' (estimated from the positions), got {speeds!r}")
    controller = _compiled_law(law, joints, umax, n)
    steps = protocol.steps
    state = np.zeros(2 * n) if x0 is None else np.array(x0, dtype=float).reshape(2 * n)
    if not np.all(np.isfinite(state)):
        raise ParameterError(f"x0 must be {2 * n} finite numbers (angles [rad], then speeds [rad/s])")
    if protocol.resets is not None:
        extra = [name for name, v in (("disturbance", disturbance), ("plant_values", plant_values or None),
                                      ("speeds='positions'", speeds == "positions" or None)) if v is not None]
        if extra:
            raise ParameterError(f"{extra[0]}: the v3 board's protocol (resets) has no disturbances, changed plant "
                                 "values or estimated speeds")
        return _run_with_resets(sim, kernel, p, controller, joints, protocol, state, umax)
    d = Disturbance() if disturbance is None else disturbance
    rng = np.random.default_rng(d.seed)
    vnoise = rng.normal(0.0, d.velocity_noise, (steps, n)) if d.velocity_noise > 0 else None
    unoise = rng.normal(0.0, d.torque_noise, (steps, n)) if d.torque_noise > 0 else None
    pert = None
    if d.perturbation is not None:
        pert = np.ascontiguousarray(d.perturbation, dtype=float)
        if pert.shape != (steps, n) or not np.all(np.isfinite(pert)):
            raise ParameterError(f"perturbation must be finite torques of shape ({steps}, {n}) [N m] (a row per step)")
    x = np.zeros((steps, 2 * n))
    u = np.zeros((steps, n))
    dp = ctypes.POINTER(ctypes.c_double)

    def ptr(a):
        return None if a is None else a.ctypes.data_as(dp)

    final = np.full(2 * n, np.nan)
    c = controller.struct()
    done = kernel.lib.sp_protocol(ctypes.byref(c), ptr(p), ptr(state), steps, protocol.dt, int(d.delay),
                                  float(d.responsiveness), ptr(vnoise), ptr(unoise), ptr(pert), int(speeds == "positions"),
                                  ptr(x), ptr(u), ptr(final))
    raise_law_error(c)
    message = ""
    if done < steps:
        t_bad = done * protocol.dt
        message = (f"the law returned non-finite torques at t = {t_bad:.4g} s" if not np.all(np.isfinite(u[done]))
                   else f"the run failed at t = {t_bad:.4g} s (a non-finite state)")
        x, u = x[:done], u[:done]
    t = np.arange(len(x)) * protocol.dt
    heights = tip_heights(kernel, p, x) if len(x) else np.zeros(0)
    return ProtocolRun(t, x, u, heights, model_reach(sim), protocol, message, final)


def reset_schedule(resets: Resets, n: int = 2, t_final: float = PROTOCOL_V3.t_final) -> Tuple[np.ndarray, np.ndarray]:
    """The v3 board's reset times ``(count,)`` [s] and random states ``(10 count + 1, 2 n)`` (angles uniform
    in ``[-pi, pi)``, speeds 0), drawn as ``GlobalPolicyTestingControllerV2`` draws them -- the states, then
    the times' jitter, from NumPy's ``RandomState(resets.seed)`` (the lab's global generator after
    ``np.random.seed(seed)``); reset ``i`` pulls towards state ``i``."""
    if isinstance(n, bool) or not isinstance(n, (int, np.integer)) or n < 1:
        raise ParameterError(f"n must be the number of joints, >= 1, got {n!r}")
    rng = np.random.RandomState(resets.seed)
    states = rng.uniform(0.0, 2.0 * np.pi, (10 * resets.count + 1, 2 * n)) - np.pi
    states[:, n:] = 0.0
    gap = t_final / float(resets.count + 1)
    times = np.linspace(gap, t_final - gap, resets.count) + resets.jitter * 2.0 * (rng.rand(resets.count) - 0.5)
    return times, states


def holding_torques(model):
    """``hold(q) -> tau`` (n,) [N m]: the torques that hold ``model``'s rods still at the angles ``q`` -- the
    bias of its equations at rest (gravity's torques, ``dPi/dq``), the v3 reset's gravity compensation
    (the lab's ``-B G(q)``)."""
    from ..numeric.recursive import chain_functions, parameter_vector, structure_of_chain

    chain = model.as_chain()
    fn = chain_functions(structure_of_chain(chain))["model"]
    p = parameter_vector(chain)
    n = len(chain.links)

    def hold(q) -> np.ndarray:
        y = np.zeros(2 * n)
        y[:n] = np.asarray(q, dtype=float).reshape(n)
        _, f, Q = fn(y, p)
        return np.asarray(Q, dtype=float).reshape(n) - np.asarray(f, dtype=float).reshape(n)

    return hold


def _run_with_resets(sim, kernel, p: np.ndarray, controller, joints, protocol: Protocol, state: np.ndarray,
                     umax: float) -> ProtocolRun:
    """The v3 board's run (see :func:`run_protocol` and the module), a step at a time (plain floats between
    the compiled calls: the loop's own work is a few microseconds a step); ``umax`` every motor's limit (the
    law's and the reset's: the plant's)."""
    from ..numeric.control import raise_law_error

    R = protocol.resets
    n = kernel.nq
    nx = 2 * n
    steps, dt, limit = protocol.steps, protocol.dt, float(umax)
    times, goals = reset_schedule(R, n, protocol.t_final)
    times = np.append(times, math.inf).tolist()
    hold = holding_torques(sim)
    motor = [j + 1 in joints for j in range(n)]
    lib = kernel.lib
    inputs, step = lib.sp_inputs_many, lib.sp_rk4_hold
    dp = ctypes.POINTER(ctypes.c_double)
    c = controller.struct()
    c_ref = ctypes.byref(c)
    row = np.zeros(nx + 2)
    law_u = np.zeros(n)
    applied = np.zeros(n)
    x = np.array(state, dtype=float)
    pp = np.ascontiguousarray(p, dtype=float)
    row_p, law_p, u_p, x_p, p_p = (a.ctypes.data_as(dp) for a in (row, law_u, applied, x, pp))
    xs, us, ts = np.zeros((steps, nx)), np.zeros((steps, n)), np.zeros(steps)
    kp, ki, kd, pid_dt, length = R.kp, R.ki, R.kd, R.pid_dt, R.length
    t = last_t = timer = start = 0.0
    resetting, due = False, 0
    goal = [0.0] * n
    error_sum, last_error, errors = [0.0] * n, [0.0] * n, 0
    phases = []
    done, failure = steps, ""
    for k in range(steps):
        xs[k] = x
        ts[k] = t
        if not resetting and t >= times[due]:
            resetting, goal, timer, start = True, goals[due, :n].tolist(), 0.0, t
            due += 1
        if resetting and timer > length:
            resetting = False
            phases.append((start, t))
        if resetting:  # the PID on every joint (never re-initialised), plus the holding torques
            q = x[:n].tolist()
            error = [g - a for g, a in zip(goal, q)]
            error_sum = [s_ + e for s_, e in zip(error_sum, error)]
            errors += 1
            pid = [kp * e + ki * s_ * pid_dt for e, s_ in zip(error, error_sum)]
            if errors > 2:
                pid = [v + kd * (e - f) / pid_dt for v, e, f in zip(pid, error, last_error)]
            last_error = error
            u = [min(max(min(max(v, -limit), limit) + h, -limit), limit) for v, h in zip(pid, hold(q).tolist())]
            timer += t - last_t
        else:
            row[:nx] = x
            row[nx + 1] = t
            inputs(c_ref, row_p, 1, nx + 2, p_p, law_p)
            raise_law_error(c)
            u = [min(max(v, -limit), limit) if m else 0.0 for v, m in zip(law_u.tolist(), motor)]
        last_t = t
        applied[:] = u
        us[k] = applied
        if not math.isfinite(math.fsum(map(abs, u))):
            done, failure = k, f"the law returned non-finite torques at t = {t:.4g} s"
            break
        step(x_p, p_p, u_p, dt, x_p)
        if not math.isfinite(math.fsum(map(abs, x.tolist()))):
            done, failure = k, f"the run failed at t = {t:.4g} s (a non-finite state)"
            break
        t += dt
    if resetting:
        phases.append((start, math.nan))
    final = np.full(nx, np.nan)
    if done < steps:
        xs, us, ts = xs[:done], us[:done], ts[:done]
    else:
        final = x.copy()
    heights = tip_heights(kernel, pp, xs) if len(xs) else np.zeros(0)
    return ProtocolRun(ts, xs, us, heights, model_reach(sim), protocol, failure, final, tuple(phases))


def read_csv(path) -> Tuple[np.ndarray, np.ndarray, np.ndarray]:
    """A leaderboard trajectory file (:data:`CSV_COLUMNS`) as ``(t, x, u)``."""
    path = Path(path)
    try:
        with path.open(newline="") as fh:
            reader = csv.reader(fh)
            header = [h.strip() for h in next(reader)]
            body = [r for r in reader if r]
    except (OSError, StopIteration, UnicodeDecodeError) as exc:
        raise ParameterError(f"{path}: cannot read a leaderboard trajectory file ({exc.__class__.__name__})") from None
    missing = [c for c in CSV_COLUMNS if c not in header]
    if missing:
        raise ParameterError(f"{path}: a leaderboard trajectory file needs the columns {', '.join(CSV_COLUMNS)}; "
                             f"{missing[0]} is missing")
    index = [header.index(c) for c in CSV_COLUMNS]
    try:
        rows = np.array([[float(r[i]) for i in index] for r in body], dtype=float)
    except (ValueError, IndexError):
        raise ParameterError(f"{path}: every row of a leaderboard trajectory file needs a number in each column") from None
    if rows.ndim != 2 or len(rows) < 3:
        raise ParameterError(f"{path}: a leaderboard trajectory file needs at least 3 rows")
    return rows[:, 0], rows[:, 1:5], rows[:, 5:7]


def write_csv(path, t, x, u) -> None:
    """The rows as a leaderboard trajectory file (:data:`CSV_COLUMNS`; the double pendulum's columns), atomically."""
    from ..io import atomic_path

    x = np.asarray(x, dtype=float)
    if x.shape[1] != 4:
        raise ParameterError(f"a leaderboard trajectory file holds a double pendulum's rows (4 states), got {x.shape[1]}")
    data = np.column_stack([np.asarray(t, dtype=float), x, np.asarray(u, dtype=float)])
    with atomic_path(Path(path)) as tmp:
        np.savetxt(tmp, data, delimiter=",", header=",".join(CSV_COLUMNS), comments="", fmt="%.18e")


def dfki_model(alpha: float = 0.0, values=None):
    """The leaderboard's plant: the DFKI lab's design C.1, model 1.1 (model 1.0 without its motor
    inertia, damping and friction), as :class:`~skewpend.Parameters` -- centres of mass on the rods, the
    inertias about them ``I - m r^2`` across the rod (none along it) -- with the second hinge turned by
    ``alpha`` [rad] (0: the lab's planar rig).  ``values``: other numbers by the lab's names (the
    robustness test's varied models; default the model file's, :func:`lab_values`)."""
    from dataclasses import replace

    from .measurements import dfki_parameters

    params = dfki_parameters(lab_values() if values is None else values)
    return replace(params, alpha=float(alpha))


def lab_values():
    """The numbers of the leaderboard's model (design C.1, model 1.1) by the lab's names (``m1``, ``r1``,
    ``I1`` about the joint, ``b1``, ``cf1``, ``Ir``, ``gr``, ...)."""
    from ..datasets import example_data
    from .measurements import read_dfki_lab_values

    return read_dfki_lab_values(example_data("dfki-design-C.1/model_1.1_parameters.yml"))
