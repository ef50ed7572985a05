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
           "Disturbance",
           "read_csv", "write_csv", "CSV_COLUMNS", "dfki_model", "lab_values", "ROBOTS", "PUBLISHED"]


@dataclass(frozen=True)
class Protocol:
    """The leaderboard's simulation settings: the step ``dt`` [s], the run's length ``t_final`` [s],
    the motors' torque limit ``umax`` [N m], the height fraction of the success test."""

    dt: float = 0.002
    t_final: float = 10.0
    umax: float = 6.0
    height: float = 0.9

    @property
    def steps(self) -> int:
        """The rows of a run (5000): the leaderboard's simulator steps until ``t >= t_final``."""
        return int(round(self.t_final / self.dt))


#: The simulation leaderboard v2's settings.
PROTOCOL = Protocol()
#: The form of the equations the leaderboard optimises (:mod:`~skewpend.analysis.trajopt`: CasADi's graph of the
#: recursive algorithms, :func:`skewpend.numeric.recursive.chain_functions`) and runs by the protocol (the same
#: algorithms printed straight, ``kernels.model_kernel(model, FORM)``): one model, optimised and scored -- its
#: RK4 step 2.18e3 instructions on the leaderboard's plant, the exact form's 3.19e3 (callgrind).
FORM = "straight"
#: The v2 score's criteria and their normalisation constants (``calculate_leaderboard_score.py``).
NORMALISATION: Dict[str, float] = {"swingup_time": 20.0, "energy": 60.0, "tau_cost": 20.0, "tau_smoothness": 0.1,
                                   "velocity_cost": 400.0}
#: The best published entries (leaderboards v2, real_ai_gym_leaderboard at 81ea5bc): robot -> board -> (name, score).
PUBLISHED: Dict[str, Dict[str, Tuple[str, float]]] = {
    "acrobot": {"simulation": ("History SAC", 0.655), "robustness": ("History SAC", 0.751)},
    "pendubot": {"simulation": ("History SAC", 0.682), "robustness": ("AR-EAPO", 0.913)},
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


def score(c, version: str = "v2") -> float:
    """The leaderboard's v2 score of :class:`Criteria` (or a mapping of the five criteria and
    ``success``): ``success * (1 - 1/5 sum_i tanh(pi c_i / n_i))``, :data:`NORMALISATION`'s ``n_i``."""
    if version != "v2":
        raise ParameterError(f"version must be 'v2' (the current leaderboards' score), got {version!r}")
    get = (lambda k: c[k]) if isinstance(c, dict) else (lambda k: getattr(c, k))
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
    last step (NaN when the run stopped early); ``criteria`` and ``score``."""

    t: np.ndarray
    x: np.ndarray
    u: np.ndarray
    heights: np.ndarray
    reach: float
    protocol: Protocol = PROTOCOL
    message: str = ""
    final: Optional[np.ndarray] = field(default=None, repr=False)  #: the state after the last step (2 n,)

    @property
    def ok(self) -> bool:
        return not self.message

    @property
    def criteria(self) -> Criteria:
        """The leaderboard's criteria of the rows; a run that failed (``ok`` False) has none: IntegrationError
        with its ``message`` (its score is 0)."""
        if not self.ok:
            from ..errors import IntegrationError

            raise IntegrationError(f"a failed run has no leaderboard criteria (its score is 0): {self.message}")
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
    no noise from the speeds, a lag of order dt^2)."""
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
