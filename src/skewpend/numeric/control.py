"""Joint torques that vary: the inputs the compiled integrators apply (``sp_control`` in
``integrators.c``), with no Python call per step.

A :class:`Controller` drives the ``nq`` joints of a model (the double pendulum's 2, a chain's n) and says
which have a motor (:func:`actuated_joints`: ``"both"`` or ``"all"``, the joints' numbers ``(2,)``, ``(1, 3)``,
or a two-link robot's name, ``"acrobot"`` -- the elbow only -- or ``"pendubot"`` -- the shoulder only), the
saturation of each joint's torque and the law:

* ``Controller.feedback(K, target, u_target)``: linear state feedback ``u = u* - K (x - x*)``,
  the angles of ``x - x*`` wrapped to (-pi, pi] (a PD law is the feedback ``K = [Kp, Kd]``);
* ``Controller.swingup(energy_gain, target_energy, K, target, P, rho, elbow_gains=(kp, kd))``:
  energy shaping ``u_j = k_e (E* - E) q'_j`` on the actuated joints (``E = T + Pi`` from the
  derivation), which pumps energy towards ``E*``, the elbow also held towards its target angle by
  ``-kp (psi - psi*) - kd psi'`` (so the two rods swing up as one), switched to the feedback
  inside the region ``(x - x*)^T P (x - x*) < rho``;
* ``Controller.table(times, torques)``: ``u(t)`` interpolated linearly in a table (held at its
  ends);
* ``Controller.tracking(dt, states, inputs, gains, K, target)``: time-varying feedback along a
  reference sampled every ``dt``: ``u = u_k - K_k (x - x_k)`` at ``t = k dt``, blended linearly
  between samples, then the feedback ``-K (x - x*)`` of the goal after the last sample (a TVLQR's
  law, :func:`skewpend.analysis.trajopt.tvlqr`);
* ``Controller.function(f)``: any law ``u = f(t, x)`` written in Python -- the slow path: the
  compiled integrator calls back into Python at every stage (about a microsecond or two each,
  tens of times the cost of the built-in laws); an exception in ``f`` stops the run and is
  raised by :func:`skewpend.simulate`.

The inputs add to the model's constant torques ``tau``; the work ``W`` of ``Q = tau + u - c q'``
then includes theirs, so ``E - W`` stays conserved (the energy balance of every run).

Every law has the same shape for ``n`` joints (``Controller.nq``): a gain of shape ``(n, 2 n)``, a table of
``n`` columns, a Python law of the state (the model's coordinates, then their rates) returning ``n`` torques
(``nq=n``); the compiled ``sp_control`` is laid out for the model's ``SP_NQ`` (``kernels.control_struct_type``).
"""

from __future__ import annotations

import contextlib
import ctypes
import inspect
import math
import numbers
import signal
from dataclasses import dataclass, field
from typing import Any, Dict, Optional, Sequence, Tuple

import numpy as np

from ..errors import ParameterError

__all__ = ["Controller", "ROBOTS", "KINDS", "CALLBACK", "MAX_JOINTS", "actuated_joints", "actuation_mask", "torque_limits",
           "capture_many", "capture_lanes_available", "raise_law_error"]

#: The leaderboard's robots, chains of :data:`ROBOT_LINKS` links named by the joint with the motor (1: the
#: shoulder, 2: the elbow); a name of the user's input, valid for a model of that many links.
ROBOTS: Dict[str, Tuple[int, ...]] = {"pendubot": (1,), "acrobot": (2,)}
ROBOT_LINKS = 2
#: The laws (the ``SP_CTL_*`` codes of ``integrators.c``).
KINDS = {"feedback": 1, "swingup": 2, "table": 3, "function": 4, "tracking": 5}
#: The C signature of a Python law: u[n] at time t and state y[2 n] (``sp_control.callback``).
CALLBACK = ctypes.CFUNCTYPE(None, ctypes.c_double, ctypes.POINTER(ctypes.c_double), ctypes.POINTER(ctypes.c_double))
#: The most joints a controller drives (the actuated set is one 32-bit mask in ``sp_control``).
MAX_JOINTS = 31


def actuated_joints(actuated, n: int) -> Tuple[int, ...]:
    """The joints (numbers 1 .. n) with a motor on a model of ``n`` links: ``"both"`` or ``"all"`` every joint,
    the joints' numbers (``(2,)``, ``(1, 3)``, each once) or a robot's name (:data:`ROBOTS`, a model of two
    links: ``"acrobot"`` the elbow, ``"pendubot"`` the shoulder); else one ParameterError."""
    from ..schema import model_title

    robot = isinstance(actuated, str) and actuated in ROBOTS
    if isinstance(actuated, str) and actuated in ("both", "all"):
        return tuple(range(1, n + 1))
    if robot and n == ROBOT_LINKS:
        return ROBOTS[actuated]
    joints = joint_numbers(actuated, n)
    if joints is not None:
        return joints
    if robot:
        raise ParameterError(f"{actuated} names a joint of the double pendulum; {model_title(n)} takes 'all' or the "
                             f"numbers of the joints with a motor, 1 to {n} (e.g. (2,))")
    names = (f"one of both, {', '.join(ROBOTS)} (acrobot: the elbow only, pendubot: the shoulder only)"
             if n == ROBOT_LINKS else "'all'")
    raise ParameterError(f"actuated must be {names} or the numbers of the joints with a motor, 1 to {n}, each once "
                         f"(e.g. (2,)), got {actuated!r}")


def joint_numbers(actuated, n: int) -> Optional[Tuple[int, ...]]:
    """``actuated`` as the sorted numbers of joints 1 .. n, each once (whole numbers, not bools), or None."""
    if isinstance(actuated, (str, bytes, dict)):
        return None
    try:
        given = [operator_index(j) for j in actuated]
    except TypeError:  # a float, a bool, a string among them, or no collection
        return None
    joints = tuple(sorted(set(given)))
    return joints if joints and len(joints) == len(given) and all(1 <= j <= n for j in joints) else None


def actuation_mask(actuated, nq: int = 2) -> int:
    """The actuated joints (:func:`actuated_joints`) as ``sp_control``'s bit mask (bit j: joint j + 1)."""
    return sum(1 << (j - 1) for j in actuated_joints(actuated, nq))


def actuation_text(actuated, joints: Sequence[int], model) -> str:
    """The actuated model in words: ``"the acrobot"`` by a robot's name, else ``"a chain of 3 links with joint 2
    actuated"`` (``joints`` 1-based)."""
    if isinstance(actuated, str) and actuated in ROBOTS:
        return f"the {actuated}"
    which = "every joint" if len(joints) == model.n else "joint" + ("s " if len(joints) > 1 else " ") + ", ".join(
        map(str, joints))
    return f"{model.title} with {which} actuated"


def operator_index(value) -> int:
    """``value`` as an int (ints and NumPy's integers; not a bool or a float), else TypeError."""
    import operator

    if isinstance(value, (bool, np.bool_)):
        raise TypeError("a bool is no joint number")
    return operator.index(value)


def _actuated_setting(actuated):
    """``actuated`` as stored: a label, or the sorted tuple of joint numbers."""
    return actuated if isinstance(actuated, str) else tuple(sorted(int(j) for j in actuated))


def torque_limits(umax, n: int = 2) -> Tuple[float, ...]:
    """Positive torque limits [N m], one for every joint or one per joint (``n`` joints; None or inf: none)."""
    if umax is None:
        return (math.inf,) * n
    refusal = ParameterError(f"umax must be positive torque limits [N m] (one, or one per joint: {n}; inf: none), got "
                             f"{umax!r}")
    if isinstance(umax, (str, bytes, bool)):
        raise refusal
    try:
        values = np.broadcast_to(np.asarray(umax, dtype=float), (n,))
    except (TypeError, ValueError, OverflowError):
        raise refusal from None
    if not np.all(values > 0) or np.any(values < 2.2250738585072014e-308):  # NaN fails the first, subnormals the second
        raise refusal
    return tuple(float(v) for v in values)


def _array(name: str, value) -> np.ndarray:
    """``value`` as a float array (sequences, arrays and NumPy scalars), else one ParameterError."""
    if isinstance(value, (str, bytes)):
        raise ParameterError(f"{name} must be numbers, got {value!r}")
    try:
        return np.array(value, dtype=float)
    except (TypeError, ValueError, OverflowError):
        raise ParameterError(f"{name} must be numbers (a sequence or an array), got {type(value).__name__}") from None


def _real(name: str, value) -> float:
    """A real number (NumPy's scalars too; not a bool or a string), else one ParameterError."""
    if isinstance(value, (bool, np.bool_)) or not isinstance(value, numbers.Real):
        raise ParameterError(f"{name} must be a real number, got {value!r}")
    return float(value)


def _finite(name: str, value, shape) -> np.ndarray:
    a = _array(name, value)
    if a.shape != shape:
        raise ParameterError(f"{name} must have shape {shape}, got {a.shape}")
    if not np.all(np.isfinite(a)):
        raise ParameterError(f"{name} must be finite")
    return a


def _feedback(K, target, u_target, n: int) -> Dict[str, np.ndarray]:
    """A feedback's gain ``K`` (n, 2 n), target state and input there (default zeros), checked."""
    return dict(K=_finite("K", K, (n, 2 * n)), target=_finite("target", target, (2 * n,)),
                u_target=_finite("u_target", np.zeros(n) if u_target is None else u_target, (n,)))


def _no_feedback(n: int) -> Dict[str, np.ndarray]:
    """The feedback arrays of a law without one (a table, a Python law): zeros of ``n`` joints."""
    return dict(K=np.zeros((n, 2 * n)), target=np.zeros(2 * n), u_target=np.zeros(n), P=np.zeros((2 * n, 2 * n)))


def _joints(nq) -> int:
    """A number of coordinates (the double pendulum's 2, a chain's n), checked."""
    try:
        n = operator_index(nq)
    except TypeError:
        n = 0
    if not 1 <= n <= MAX_JOINTS:
        raise ParameterError(f"nq must be the model's number of coordinates, 1 to {MAX_JOINTS}, got {nq!r}")
    return n


def _gain_joints(K) -> int:
    """The number of joints of a feedback gain ``K`` (n x 2 n)."""
    a = _array("K", K)
    if a.ndim != 2 or a.shape[1] != 2 * a.shape[0] or not 1 <= a.shape[0] <= MAX_JOINTS:
        raise ParameterError(f"K must have shape (n, 2 n): a row per joint, a column per state (2, 4 for the double "
                             f"pendulum), got {a.shape}")
    return a.shape[0]


@dataclass(frozen=True)
class Controller:
    """The inputs of a run (see the module); build one with :meth:`feedback`, :meth:`swingup` or
    :meth:`table`, pass it to :func:`skewpend.simulate` as ``controller=``.  ``nq`` is the number of
    joints it drives (the double pendulum's 2, a chain's n; the gain's or the table's shape says)."""

    kind: str
    actuated: Any = "both"
    umax: Tuple[float, ...] = (math.inf, math.inf)
    K: np.ndarray = field(default_factory=lambda: np.zeros((2, 4)), repr=False)
    target: np.ndarray = field(default_factory=lambda: np.zeros(4))
    u_target: np.ndarray = field(default_factory=lambda: np.zeros(2))
    energy_gain: float = 0.0
    elbow_gains: Tuple[float, float] = (0.0, 0.0)
    target_energy: float = 0.0
    P: np.ndarray = field(default_factory=lambda: np.zeros((4, 4)), repr=False)
    rho: float = 0.0
    times: Optional[np.ndarray] = field(default=None, repr=False)
    torques: Optional[np.ndarray] = field(default=None, repr=False)
    law: Any = field(default=None, repr=False)  #: a Python law (Controller.function)
    nq: int = 2
    #: tracking: the rows (x_k, u_k, K_k) of the reference, sampled every ``dt`` [s]
    reference: Optional[np.ndarray] = field(default=None, repr=False)
    dt: float = 0.0
    #: a sampled law (:meth:`function`'s ``hold``): its period [s], the law held between samples (0: continuous)
    hold: float = 0.0

    # -- constructors ------------------------------------------------------------------------
    @classmethod
    def feedback(cls, K, target, u_target=None, *, actuated="both", umax=None) -> "Controller":
        """``u = u* - K (x - x*)``, ``K`` (n, 2 n) (rows for the joints -- (2, 4) for the double
        pendulum; an unactuated joint's row is ignored), ``target`` the state ``x*`` (2 n,),
        ``u_target`` the input there (default zeros)."""
        n = _gain_joints(K)
        actuation_mask(actuated, n)
        return cls("feedback", _actuated_setting(actuated), torque_limits(umax, n), **_feedback(K, target, u_target, n),
                   P=np.zeros((2 * n, 2 * n)), nq=n)

    @classmethod
    def swingup(cls, energy_gain: float, target_energy: float, K, target, P, rho: float, u_target=None, *,
                elbow_gains=(0.0, 0.0), actuated="both", umax=None) -> "Controller":
        """Energy shaping ``u_j = energy_gain (E* - E) q'_j`` on the actuated joints (joints 2 … n also held
        towards their targets by the PD ``elbow_gains``), switched to the feedback ``u* - K (x - x*)`` inside
        ``(x - x*)^T P (x - x*) < rho``."""
        n = _gain_joints(K)
        actuation_mask(actuated, n)
        energy_gain, target_energy, rho = (_real(k, v) for k, v in (("energy_gain", energy_gain),
                                                                      ("target_energy", target_energy), ("rho", rho)))
        if not (math.isfinite(energy_gain) and energy_gain > 0):
            raise ParameterError(f"energy_gain must be a positive number, got {energy_gain!r}")
        if not math.isfinite(target_energy):
            raise ParameterError(f"target_energy must be finite, got {target_energy!r}")
        if not (math.isfinite(rho) and rho >= 0):
            raise ParameterError(f"rho must be a non-negative number, got {rho!r}")
        gains = _finite("elbow_gains", elbow_gains, (2,))
        if np.any(gains < 0):
            raise ParameterError(f"elbow_gains (kp, kd) must not be negative, got {elbow_gains!r}")
        return cls("swingup", _actuated_setting(actuated), torque_limits(umax, n), **_feedback(K, target, u_target, n),
                   energy_gain=float(energy_gain), elbow_gains=(float(gains[0]), float(gains[1])),
                   target_energy=float(target_energy), P=_finite("P", P, (2 * n, 2 * n)), rho=float(rho), nq=n)

    @classmethod
    def table(cls, times: Sequence[float], torques, *, actuated="both", umax=None, nq: Optional[int] = None
              ) -> "Controller":
        """``u(t)`` linear between the rows ``(times[k], torques[k])`` (``torques`` (rows, n) [N m], a
        column per joint; a 1-D ``torques`` is the one actuated joint's -- the acrobot's or pendubot's,
        or a chain's ``actuated=(j,)`` with ``nq`` its joints), held at the ends."""
        t = _array("times", times)
        u = _array("torques", torques)
        n = _joints(nq) if nq is not None else (u.shape[1] if u.ndim == 2 and u.shape[1] >= 1 else 2)
        code = actuation_mask(actuated, n)
        if u.ndim == 1:
            if bin(code).count("1") != 1:
                raise ParameterError(f"torques must have {n} columns (one per joint) when more than one joint is "
                                     "actuated")
            full = np.zeros((u.size, n))
            full[:, code.bit_length() - 1] = u
            u = full
        if t.ndim != 1 or t.size < 1 or u.shape != (t.size, n):
            raise ParameterError(f"a torque table needs k times and k x {n} torques, got {t.shape} and {u.shape}")
        if not (np.all(np.isfinite(t)) and np.all(np.isfinite(u))):
            raise ParameterError("a torque table must hold finite numbers")
        if t.size > 1 and np.any(np.diff(t) <= 0):
            raise ParameterError("a torque table's times must increase strictly")
        return cls("table", _actuated_setting(actuated), torque_limits(umax, n), times=t, torques=u, nq=n,
                   **_no_feedback(n))

    @classmethod
    def tracking(cls, dt: float, states, inputs, gains, K, target, u_target=None, *, actuated="both", umax=None
                 ) -> "Controller":
        """Time-varying feedback along a reference sampled every ``dt`` [s]: sample ``k``'s law ``inputs[k] -
        gains[k] (x - states[k])`` at ``t = k dt`` (the angles of the deviation wrapped to (-pi, pi]), the
        sample after the last one the feedback ``u* - K (x - x*)`` about ``target``; between two samples
        their laws blended linearly (sample 0's before it, the goal's from ``len(states) dt`` on).
        ``states`` (k, 2 n), ``inputs`` (k, n) and ``gains`` (k, n, 2 n) hold every joint (an unactuated joint's
        rows are ignored)."""
        n = _gain_joints(K)
        actuation_mask(actuated, n)
        dt = _real("dt", dt)
        if not (math.isfinite(dt) and dt > 0):
            raise ParameterError(f"dt must be a positive sampling step [s], got {dt!r}")
        x = _array("states", states)
        if x.ndim != 2 or x.shape[0] < 1 or x.shape[1] != 2 * n:
            raise ParameterError(f"states must have shape (k, {2 * n}): a sample per row, got {x.shape}")
        k = x.shape[0]
        u = _finite("inputs", inputs, (k, n))
        g = _finite("gains", gains, (k, n, 2 * n))
        if not np.all(np.isfinite(x)):
            raise ParameterError("states must be finite")
        reference = np.ascontiguousarray(np.column_stack([x, u, g.reshape(k, -1)]), dtype=float)
        return cls("tracking", _actuated_setting(actuated), torque_limits(umax, n), **_feedback(K, target, u_target, n),
                   P=np.zeros((2 * n, 2 * n)), nq=n, reference=reference, dt=dt)

    @classmethod
    def function(cls, f, *, actuated="both", umax=None, nq: int = 2, hold: Optional[float] = None) -> "Controller":
        """``u = f(t, x)``: a Python callable of the time [s] and the state ``x = (phi, psi, phi',
        psi')`` (a chain's ``(q1 … qn, q1' … qn')``, ``nq`` = n; a NumPy array) returning the joints'
        torques [N m] (the joints not actuated get 0, then the limits apply).  The slow path (see the
        module): for laws the built-in ones cannot express.  ``hold`` [s]: a sampled law (a digital
        controller's, e.g. a model-predictive one): called once every ``hold`` seconds at the state
        reached and held in between -- :func:`skewpend.simulate` runs it with ``method="rk4"`` and ``dt =
        hold`` (its step's start is the sample; "auto" takes them)."""
        n = _joints(nq)
        actuation_mask(actuated, n)
        if not callable(f):
            raise ParameterError(f"the law must be a callable f(t, x) -> (u1, ..., u{n}), got {f!r}")
        try:
            inspect.signature(f).bind(0.0, np.zeros(2 * n))
        except TypeError:
            raise ParameterError(f"the law must take two arguments, f(t, x) -> (u1, ..., u{n}); {f!r} does not") from None
        except ValueError:  # no signature to read (some built-ins): its first call says
            pass
        period = 0.0
        if hold is not None:
            period = _real("hold", hold)
            if not (math.isfinite(period) and period > 0):
                raise ParameterError(f"hold must be a positive sampling period [s], got {hold!r}")
        return cls("function", _actuated_setting(actuated), torque_limits(umax, n), law=f, nq=n, hold=period,
                   **_no_feedback(n))

    def check_model(self, nq: int) -> None:
        """Refuse (one ParameterError) running this controller on a model of ``nq`` coordinates when it
        drives another number of joints."""
        if nq != self.nq:
            from ..schema import model_title

            raise ParameterError(f"this controller drives {self.nq} joints; {model_title(nq)} has {nq} (build it with a gain "
                                 f"of shape ({nq}, {2 * nq}), a table of {nq} columns, or nq={nq})")

    # -- what the integrators get --------------------------------------------------------------
    @property
    def state_size(self) -> int:
        """2 n + 1 (angles, speeds, W; the double pendulum's 5), or 2 n + 2 with the time for a table or
        a Python law."""
        return 2 * self.nq + (2 if self.kind in ("table", "function", "tracking") else 1)

    def struct(self):
        """The ``sp_control`` the compiled code reads (keep it alive during the call)."""
        from .kernels import control_struct_type

        c = control_struct_type(self.nq)()
        c.kind = KINDS[self.kind]
        c.actuated = actuation_mask(self.actuated, self.nq)
        c.umax[:] = list(self.umax)
        c.K[:] = np.ravel(self.K).tolist()
        c.xs[:] = np.asarray(self.target, dtype=float).tolist()
        c.us[:] = np.asarray(self.u_target, dtype=float).tolist()
        c.ke, c.E_target = self.energy_gain, self.target_energy
        c.kp, c.kd = self.elbow_gains
        c.P[:] = np.ravel(self.P).tolist()
        c.rho = self.rho
        c.hold = self.hold
        if self.kind in ("table", "tracking"):  # the rows, kept alive as long as the struct
            table = (self.reference if self.kind == "tracking" else
                     np.ascontiguousarray(np.column_stack([self.times, self.torques]), dtype=float))
            c.n_table, c.dt_table, c._keep = len(table), self.dt, table
            c.table = table.ctypes.data_as(ctypes.POINTER(ctypes.c_double))
        if self.kind == "function":
            c.errors = []
            c._keep = CALLBACK(_python_law(self.law, c.errors, self.nq))
            c.callback = ctypes.cast(c._keep, ctypes.c_void_p)
        return c

    def _many(self, name: str, width: int, kernel, p: np.ndarray, t: np.ndarray, y: np.ndarray) -> np.ndarray:
        """The compiled row function ``name`` (k, ``width``) of the states ``y`` (k, 2 n) and times ``t`` (k,),
        read as rows (k, 2 n + 2), the time last."""
        self.check_model(kernel.nq)
        nx = 2 * self.nq
        rows = np.zeros((len(t), nx + 2))
        rows[:, :nx] = np.asarray(y, dtype=float)[:, :nx]
        rows[:, nx + 1] = t
        out = np.empty((len(t), width))
        dp = ctypes.POINTER(ctypes.c_double)
        c = self.struct()
        getattr(kernel.lib, name)(ctypes.byref(c), rows.ctypes.data_as(dp), len(t), rows.shape[1],
                                  np.ascontiguousarray(p, dtype=float).ctypes.data_as(dp), out.ctypes.data_as(dp))
        raise_law_error(c)
        return out

    def inputs(self, kernel, p: np.ndarray, t: np.ndarray, y: np.ndarray) -> np.ndarray:
        """The inputs ``u`` (k, n) [N m] at the states ``y`` (k, 2 n) and times ``t`` (k,)."""
        return self._many("sp_inputs_many", self.nq, kernel, p, t, y)

    def closed_loop(self, kernel, p: np.ndarray, t: np.ndarray, y: np.ndarray) -> np.ndarray:
        """The closed loop's ``y'`` (k, 2 n) at the states ``y`` (k, 2 n) and times ``t`` (k,): the
        generated right-hand side with these inputs added to the torques (``sp_rhs_ctl_many``)."""
        return self._many("sp_rhs_ctl_many", 2 * self.nq + 2, kernel, p, t, y)[:, :2 * self.nq]

    def closed_loop_function(self, kernel, p: np.ndarray):
        """:meth:`closed_loop` as a function ``f(y) -> y'`` of states ``y`` (k, 2 n) at t = 0, the
        ``sp_control`` built once (for searches that call it thousands of times)."""
        self.check_model(kernel.nq)
        c = self.struct()
        pp = np.ascontiguousarray(p, dtype=np.float64)
        dp = ctypes.POINTER(ctypes.c_double)
        fn, ref, p_ptr = kernel.lib.sp_rhs_ctl_many, ctypes.byref(c), pp.ctypes.data_as(dp)
        nx = 2 * self.nq

        def f(y: np.ndarray) -> np.ndarray:
            rows = np.zeros((len(y), nx + 2))
            rows[:, :nx] = y
            out = np.empty_like(rows)
            fn(ref, rows.ctypes.data_as(dp), len(rows), nx + 2, p_ptr, out.ctypes.data_as(dp))
            raise_law_error(c)
            return out[:, :nx]

        f.keep = (c, pp)  # alive as long as f
        return f

    def settings(self) -> Dict[str, Any]:
        """Plain JSON data describing the inputs (part of a run's settings)."""
        d: Dict[str, Any] = {"kind": self.kind, "nq": self.nq,
                             "actuated": self.actuated if isinstance(self.actuated, str) else list(self.actuated),
                             "umax": [x if math.isfinite(x) else None for x in self.umax]}
        if self.hold:
            d["hold"] = self.hold
        if self.kind in ("feedback", "swingup", "tracking"):
            d.update(K=np.asarray(self.K).tolist(), target=np.asarray(self.target).tolist(),
                     u_target=np.asarray(self.u_target).tolist())
        if self.kind == "swingup":
            d.update(energy_gain=self.energy_gain, elbow_gains=list(self.elbow_gains), target_energy=self.target_energy,
                     P=np.asarray(self.P).tolist(),
                     rho=self.rho)
        if self.kind == "table":
            d.update(times=self.times.tolist(), torques=self.torques.tolist())
        if self.kind == "tracking":
            import hashlib

            d.update(dt=self.dt, samples=len(self.reference),
                     reference_sha256=hashlib.sha256(self.reference.tobytes()).hexdigest())
        if self.kind == "function":
            d.update(function=getattr(self.law, "__qualname__", repr(self.law)))
        return d


def _python_law(f, errors: list, nq: int = 2):
    """The C callback around ``f(t, x)``: the torques, or NaN (which stops the integration) with
    the exception kept in ``errors`` -- an exception must not cross the C frames.  A Ctrl-C (or
    SIGTERM) recorded by the caller's :class:`~skewpend.interrupts.Interrupts` stops it the same
    way at the next call of the law; the caller's check then raises it."""
    nan = float("nan")
    from ..interrupts import Interrupts
    from ..schema import count_text

    what = f"{count_text(nq, 'torques')} ({', '.join(f'u{r}' for r in range(1, nq + 1))})"

    def stop(u):
        for r in range(nq):
            u[r] = nan

    def law(t, y, u):
        # everything inside the try: a signal handler's exception (SIGTERM's Terminated, Ctrl-C's
        # KeyboardInterrupt) raised at any line must not escape into ctypes, which would print it and go on
        try:
            if errors:
                stop(u)
                return
            # the signal an Interrupts of this process recorded and has not raised yet: a slow Python law must not
            # hold Ctrl-C until the compiled call returns (the check between calls would come after all its steps)
            owner = getattr(signal.getsignal(signal.SIGINT), "__self__", None)
            pending = owner.pending if isinstance(owner, Interrupts) else None
            if pending is not None:
                errors.append(pending())
                stop(u)
                return
            got = f(t, np.array(y[:2 * nq]))
            try:
                v = np.asarray(got, dtype=float).reshape(-1)
            except (TypeError, ValueError, OverflowError):
                v = None
            if v is None or v.shape != (nq,):
                raise ParameterError(f"the controller function must return {what} [N m], got "
                                     + (f"shape {v.shape}" if v is not None else repr(got)[:60]))
            for r in range(nq):
                u[r] = float(v[r])
        except BaseException as exc:  # noqa: BLE001 - raised again by the caller (KeyboardInterrupt too)
            errors.append(exc)
            stop(u)

    return law


def raise_law_error(struct) -> None:
    """Raise what a Python law (``Controller.function``) raised during a compiled call, if anything."""
    errors = getattr(struct, "errors", None)
    if errors:
        raise errors[0]


def capture_lanes_available(kernel, controller: Controller) -> bool:
    """Whether :func:`capture_many` runs ``controller`` on ``kernel`` in SIMD lanes
    (``sp_capture_lanes``: a flip kernel, ``kernel_module(params, flip=True)``, of a model the lanes
    can print, and a feedback law)."""
    return controller.kind == "feedback" and hasattr(kernel.lib, "sp_capture_lanes")


#: Steps (of all lanes at once) per call of ``sp_capture_lanes`` between two checks of ``cancel``.
LANE_BUDGET = 20_000


def capture_many(kernel, p: np.ndarray, controller: Controller, starts: np.ndarray, *, t_end: float, rtol: float,
                 atol: float, max_steps: int, P: np.ndarray, rho: float, cancel=None, group: int = 16):
    """The closed loop of ``controller`` from each of ``starts`` (m, 2 n), integrated by DOP853 until
    it enters the region ``dx^T P dx < rho`` about the controller's target: ``(time, steps,
    rejected, status)`` -- the capture time [s] (NaN: not by ``t_end``, or failed), the accepted
    steps, the rejected steps (``max_steps`` bounds their sum) and the integration's status code
    (0: completed).

    On a flip kernel (``kernel_module(params, flip=True)``) with a feedback law, the starts run in
    SIMD lanes (``sp_capture_lanes``, the trigonometry-free state of the flip map, a lane refilled
    as soon as its start is done, each step stopped at the law's switches -- saturation kinks, wrap
    jumps -- instead of rejected around them), the compiled call resumed every
    :data:`LANE_BUDGET` steps;
    otherwise one by one (``sp_capture_many``), ``group`` starts per compiled call.  ``cancel`` (a
    ``threading.Event``) is checked between calls; each start's result does not depend on the
    grouping, the lane or the other starts; a cancel stops a compiled call within a step (see
    :func:`_stopped_on_cancel`)."""
    controller.check_model(kernel.nq)
    nx = 2 * kernel.nq
    starts = np.ascontiguousarray(starts, dtype=np.float64).reshape(-1, nx)
    m = starts.shape[0]
    time = np.full(m, np.nan)
    steps = np.zeros(m, dtype=np.int64)
    rejected = np.zeros(m, dtype=np.int64)
    status = np.zeros(m, dtype=np.int8)
    region = np.ascontiguousarray(P, dtype=np.float64).reshape(nx, nx)
    pp = np.ascontiguousarray(p, dtype=np.float64)
    c = controller.struct()
    with _stopped_on_cancel(c, cancel, kernel.nq):
        from .ensemble import Cancelled

        dp = ctypes.POINTER(ctypes.c_double)
        i64p, i8p = ctypes.POINTER(ctypes.c_int64), ctypes.POINTER(ctypes.c_int8)
        if capture_lanes_available(kernel, controller):
            lib = kernel.lib
            if not getattr(lib, "_sp_capture_lanes_bound", False):
                d, i64 = ctypes.c_double, ctypes.c_int64
                lib.sp_capture_lanes.argtypes = [ctypes.c_void_p, ctypes.c_void_p, dp, dp, i64, d, d, d, i64, dp, d,
                                                 i64, dp, i64p, i64p, i8p]
                lib.sp_capture_lanes.restype = ctypes.c_int
                lib.sp_capture_ws_size.argtypes, lib.sp_capture_ws_size.restype = [], ctypes.c_int64
                lib._sp_capture_lanes_bound = True
            ws = ctypes.create_string_buffer(int(lib.sp_capture_ws_size()))
            while True:
                if cancel is not None and cancel.is_set():
                    raise Cancelled()
                rc = lib.sp_capture_lanes(ws, ctypes.byref(c), pp.ctypes.data_as(dp), starts.ctypes.data_as(dp), m,
                                          float(t_end), float(rtol), float(atol), int(max_steps),
                                          region.ctypes.data_as(dp), float(rho), LANE_BUDGET, time.ctypes.data_as(dp),
                                          steps.ctypes.data_as(i64p), rejected.ctypes.data_as(i64p),
                                          status.ctypes.data_as(i8p))
                if cancel is not None and cancel.is_set():
                    raise Cancelled()
                if rc == 0:
                    return time, steps, rejected, status
                if rc != -1:
                    raise RuntimeError(f"sp_capture_lanes refused its arguments (code {rc})")
        fn = kernel.lib.sp_capture_many
        for a in range(0, m, group):
            if cancel is not None and cancel.is_set():
                raise Cancelled()
            b = min(m, a + group)
            fn(ctypes.byref(c), pp.ctypes.data_as(dp), starts[a:].ctypes.data_as(dp), b - a, float(t_end), float(rtol),
               float(atol), int(max_steps), region.ctypes.data_as(dp), float(rho), time[a:].ctypes.data_as(dp),
               steps[a:].ctypes.data_as(i64p), rejected[a:].ctypes.data_as(i64p), status[a:].ctypes.data_as(i8p))
            if cancel is not None and cancel.is_set():  # the call may have been stopped by the watcher: not a result
                raise Cancelled()
        return time, steps, rejected, status


#: How often [s] a compiled capture's watcher looks at the cancel event (:func:`capture_many`).
CANCEL_POLL = 0.05


@contextlib.contextmanager
def _stopped_on_cancel(struct, cancel, nq: int):
    """While a compiled capture runs, a watcher thread that, once ``cancel`` is set, makes the law's torques NaN
    in the ``sp_control`` the compiled code reads at every stage (its ``us``): the integration of the current
    start stops at its next step as non-finite and every later start at its first, so the compiled call returns
    within a step of the cancel -- a chain's start can take seconds (thousands of steps where the wrapped feedback
    chatters), and a call holds a group of them.  The caller discards what the call returned (Cancelled)."""
    import threading

    if cancel is None:
        yield
        return
    done = threading.Event()

    def watch():
        while not done.is_set():
            if cancel.wait(CANCEL_POLL):
                if not done.is_set():
                    for r in range(nq):
                        struct.us[r] = math.nan
                return

    threading.Thread(target=watch, name="skewpend-capture-cancel", daemon=True).start()
    try:
        yield
    finally:
        done.set()
