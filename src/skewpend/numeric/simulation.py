"""Simulation: compiled integrators over the generated right-hand side, in bounded chunks.

``simulate`` runs one of three integrators, written in C (``integrators.c``) and compiled
together with the model's generated C (:mod:`skewpend.numeric.kernel_source`):

* ``"dop853"`` (default) -- adaptive Dormand-Prince 8(5,3) with 7th-order dense output;
* ``"rk4"`` -- classical fixed-step Runge-Kutta of order 4;
* ``"gauss"`` -- 2-stage Gauss-Legendre collocation (order 4), applied to Hamilton's
  equations in the canonical variables ``(q, p = M(q) q')``: symplectic, so its energy
  error stays bounded over very long conservative runs;
* ``"taylor"`` -- adaptive Taylor series (``taylor.c``), its coefficient recurrences generated
  from the derivation (:mod:`skewpend.numeric.taylor_source`), one small library per order
  (:func:`skewpend.numeric.kernels.taylor_kernel`), built on its first use.

The integrators are resumable: each call into the compiled code does a bounded amount of
work (aimed at ~0.05 s) and hands back a bounded block of rows, which this module turns
into energies, rod ends, file rows and progress -- so Ctrl-C is honoured within a fraction
of a second and memory stays bounded by what is kept.

The state carries a fifth component ``W``: the work done by the non-potential forces
``Q = tau - c q'``.  ``E(t) - W(t)`` is then conserved for every model, and the
energy drift every run reports is ``max |E - W - E0|`` relative to the energy scale.
"""

from __future__ import annotations

import contextlib
import ctypes
import math
import os
import sys
import time
from dataclasses import dataclass, field
from typing import Any, Callable, ClassVar, Dict, List, Optional, Sequence

import numpy as np

from .. import checks
from ..interrupts import Interrupts
from ..io import TRAJECTORY_KIND, TRAJECTORY_SUFFIXES, TrajectoryWriter, check_output_path, trajectory_metadata
from ..results import ResultProtocol
from ..status import CallCode, Status
from .driver import check_step_estimate, drive
from ..errors import IntegrationError, ParameterError
from ..symbolic.model import Parameters
from ..parsing import MAX_ANGLE, initial_state

__all__ = ["simulate", "Trajectory", "open_trajectory", "METHODS", "AUTO", "AUTO_RULE", "STATUS_MESSAGES", "MAX_STEPS",
           "check_start"]

from .conventions import ADAPTIVE, METHODS, SERIES_MAX_LINKS  # noqa: E402  (the CLI's --help reads them without NumPy)

#: The default ``method`` of :func:`simulate`: the fastest integrator that serves the request (:data:`AUTO_RULE`).
AUTO = "auto"
#: Why ``method="auto"`` chose what it chose (``settings["method_choice"]`` of the trajectory; the
#: summary says it).  The rule, in this order:
#:
#: * inputs that vary (``controller=``, a law or a Python function) -> dop853: taylor's series are
#:   generated for the model with constant torques, and dop853 is the adaptive method that takes them;
#: * equations with a function that has no series recurrence -> dop853 (no model of skewpend has one
#:   today: sin, cos and Coulomb friction's atan all have theirs);
#: * a chain of more than :data:`~skewpend.numeric.conventions.SERIES_MAX_LINKS` links -> dop853 (its model
#:   as polynomials, the form its series are printed from, grows too many terms); up to that, taylor takes
#:   0.6-1.0x its own dop853's time at equal error (``benchmarks/bench_chain_heyoka.py``);
#: * otherwise -> taylor, at every tolerance, own steps or a dense grid (``dt_out``), kept or streamed:
#:   the adaptive Taylor method takes 2-4x less time than dop853 at the same tolerance and reaches a
#:   smaller error (docs/benchmarks.md, work-precision).  Its one cost: the first run at a new order (one
#:   per tolerance band, :func:`skewpend.numeric.kernels.taylor_rule`) builds that order's small library,
#:   cached on disk like the model's kernel;
#: * the first run of a model's structure at a tolerance band, before taylor's library of that order is
#:   built -> dop853, while a detached process builds the library for later runs (``"building"``;
#:   ``SKEWPEND_TAYLOR_BUILD=foreground`` waits for it instead, one choice whatever the cache holds).
#:
#: A fixed step ``dt`` is refused with ``auto`` (it is a setting of rk4 and gauss: name the method).
AUTO_RULE = {
    "sampled": "rk4: a sampled law, each step of its period one sample (the law held over the step)",
    "controller": "dop853: inputs that vary (taylor's series are generated for constant torques)",
    "no series": "dop853: {reason}",
    "recursive": f"dop853: a chain of more than {SERIES_MAX_LINKS} links (its Taylor series, of the model as polynomials, "
                 f"grow too many terms)",
    "taylor": "taylor: the fastest method that serves this request (2-4x dop853's speed at the same tolerance)",
    "series": f"taylor: a chain of up to {SERIES_MAX_LINKS} links, its series printed from its model read as polynomials "
              f"(at equal error 0.6-1.0x dop853's time, measured; 100x smaller error at the same tolerance)",
    "building": "dop853: taylor's library for this model and tolerance is being built in the background (first use; "
                "later runs take taylor, SKEWPEND_TAYLOR_BUILD=foreground waits for it instead)",
}

#: Deprecated: the messages of :class:`skewpend.status.Status` by code (use ``Status(code).message``).
STATUS_MESSAGES = {int(s): s.message for s in Status if s <= Status.NO_CONVERGENCE}


@dataclass(frozen=True)
class Trajectory(ResultProtocol):
    """The result of :func:`simulate` (and of :func:`open_trajectory`); it speaks the result
    protocol (:mod:`skewpend.results`): ``ok``, ``to_xarray()``, ``to_netcdf(path)``, ``summary()``.

    * ``t`` -- times [s], shape (n,);
    * ``y`` -- states ``(phi, psi, dphi, dpsi)`` [rad, rad/s], shape (n, 4);
    * ``energy`` -- mechanical energy ``T + Pi`` [J] (``Pi = 0`` hanging), shape (n,);
    * ``work`` -- work done by damping and joint torques since ``t[0]`` [J], shape (n,);
    * ``params``, ``method``, ``settings`` (rtol, atol, dt, dt_out, ...) -- how it was made;
    * ``stats`` -- ``nfev``, ``steps`` (accepted), ``rejected``, ``wall_time`` [s] of the
      integration, ``rows`` produced, ``kernel`` (``"compiled"`` when this process built the
      model's machine code, taking ``kernel_build_time`` [s], else ``"cache"``), ``compiler``
      (which compiler built it: the system's, or ``zig cc (ziglang)``);
    * ``kept`` -- False when only the first and last rows were kept (``keep=False``);
    * ``status`` (a :class:`~skewpend.Status`; ``SUCCESS`` = 0) and ``message``; ``ok`` (and its
      older name ``success``) is True when the run reached ``t_end``;
    * ``energy_drift`` -- ``max |E - W - E(0)|`` divided by ``max(|E|)`` over the run
      (absolute when that scale is 0).
    """

    t: np.ndarray
    y: np.ndarray
    energy: np.ndarray
    work: np.ndarray
    params: Parameters
    method: str
    settings: Dict[str, Any]
    stats: Dict[str, Any]
    status: int
    message: str
    energy_drift: float
    kept: bool = True
    _kernel: Any = field(default=None, repr=False, compare=False)
    controller: Any = field(default=None, repr=False, compare=False)

    def inputs(self) -> np.ndarray:
        """The joint torques the run's ``controller`` applied at each row, (k, n) [N m] -- the double
        pendulum's (k, 2) -- (the constant torques ``tau`` of the parameters not included; zeros without a
        controller)."""
        if self.controller is None:
            return np.zeros((len(self.t), self.y.shape[1] // 2))
        from .kernels import model_kernel, model_vector

        kernel = self._kernel if self._kernel is not None else model_kernel(self.params)
        return self.controller.inputs(kernel, model_vector(self.params), self.t, self.y)

    result_kind: ClassVar[str] = TRAJECTORY_KIND

    def __post_init__(self):
        object.__setattr__(self, "status", Status.of(self.status))

    @property
    def success(self) -> bool:
        """The same as ``ok`` (the name before the result protocol)."""
        return self.ok

    def _kernel_or_load(self):
        if self._kernel is None:  # a reopened trajectory: the model's kernel from the cache
            from .kernels import model_kernel

            object.__setattr__(self, "_kernel", model_kernel(self.params))
        return self._kernel

    def _dataset(self):
        from ..io import column_unit, trajectory_columns
        from ..results import DatasetSpec

        coords = getattr(self.params, "coordinates", ("phi", "psi"))
        n = len(coords)
        all_columns = trajectory_columns(coords)
        names = {"energy": "mechanical energy T + Pi (Pi = 0 hanging)", "work": "work of damping and joint torques since t[0]"}
        columns = {"energy": self.energy, "work": self.work}
        for k, c in enumerate(coords):
            columns[c], names[c] = self.y[:, k], f"hinge angle {k + 1}"
            columns[f"d{c}"], names[f"d{c}"] = self.y[:, n + k], f"angular speed of hinge {k + 1}"
        tips = self.tips()
        for k, name in enumerate(all_columns[2 * n + 3:]):
            columns[name] = tips[:, k]
            names[name] = f"world {name[0]} of the end of rod {name[1:]}"
        columns = {k: columns[k] for k in all_columns[1:]}  # the file's order
        variables = {k: (("t",), np.asarray(v, dtype=float), {"units": column_unit(k), "long_name": names[k]})
                     for k, v in columns.items()}
        attrs = {**self._base_attrs(), "method": self.method, "energy_drift": float(self.energy_drift),
                 "kept": int(self.kept)}
        return DatasetSpec(variables=variables, coords={"t": (("t",), np.asarray(self.t, dtype=float),
                                                              {"units": "s", "long_name": "time"})}, attrs=attrs)

    def to_netcdf(self, path):
        """Write the trajectory to ``*.nc`` (the same file as ``simulate(..., out=path)`` streams;
        reopen it with :func:`open_trajectory`), atomically.  Returns the path."""
        from pathlib import Path

        from ..io import write_trajectory

        if Path(path).suffix.lower() != ".nc":
            raise ParameterError(f"expected a file name ending in .nc, got {str(path)!r}")
        return write_trajectory(self, path)

    def summary(self) -> str:
        """A few lines: the run, its status, the energy balance and the work it took."""
        st = self.stats
        return "\n".join([
            f"{self.result_kind}: {self.message}",
            f"{self.method}, t = {self.t[0]:g} .. {self.t[-1]:g} s, {len(self.t)} rows{'' if self.kept else ' (first and last kept)'}"
            + (f"; chosen by method 'auto': {self.settings['method_choice'].split(': ', 1)[-1]}"
               if self.settings.get("method_choice") else ""),
            f"energy drift {self.energy_drift:.3g}; {st.get('steps', 0)} steps ({st.get('rejected', 0)} rejected)",
        ])

    @property
    def final_state(self) -> np.ndarray:
        return self.y[-1]

    def tips(self) -> np.ndarray:
        """World positions of the rod ends ``(x1, y1, z1, x2, y2, z2)`` [m], shape (n, 6)."""
        from .kernels import model_vector

        return self._kernel_or_load().tips_many(self.y, model_vector(self.params))

    def axes(self) -> np.ndarray:
        """The hinge axes in the world frame at each row: ``(n1, e)`` with ``e = P1·e0`` the
        second hinge's current axis (it turns with rod 1), shape (n, 6), unit vectors."""
        from .kernels import model_vector

        return self._kernel_or_load().axes_many(self.y, model_vector(self.params))


def open_trajectory(path) -> Trajectory:
    """A :class:`Trajectory` read back from a file skewpend wrote (``simulate(..., out=...)``,
    ``Trajectory.to_netcdf``, ``skewpend simulate --out``): ``*.csv`` or ``*.nc``.  Its rod ends
    and axes come from the model's kernel (loaded, or compiled, on first use)."""
    from ..io import read_trajectory

    rows, meta = read_trajectory(path)
    values = {k[len("param_"):]: v for k, v in meta.items() if k.startswith("param_")}
    try:
        if "chain" in meta:  # a chain of links: its plain data
            import json

            from ..symbolic.chain import Chain

            params = Chain.from_mapping(json.loads(meta["chain"]))
        else:
            params = Parameters(**values)
    except (TypeError, ValueError) as exc:
        raise ParameterError(f"{path}: its parameters cannot be read back ({exc})") from None
    s = 2 * getattr(params, "n", 2) + 1  # the column of the energy
    settings = {k[len("setting_"):]: v for k, v in meta.items() if k.startswith("setting_")}
    stats = {k[len("stat_"):]: v for k, v in meta.items() if k.startswith("stat_")}
    code = meta.get("status", 0)
    return Trajectory(t=rows[:, 0].copy(), y=rows[:, 1:s].copy(), energy=rows[:, s].copy(), work=rows[:, s + 1].copy(),
                      params=params, method=str(meta.get("method", "")), settings=settings, stats=stats,
                      status=int(code), message=str(meta.get("message", Status.of(int(code)).message)),
                      energy_drift=float(meta.get("energy_drift", math.nan)), kept=True)


#: The settings every :func:`simulate` run records (None when unset: then not in its file).
SIMULATE_SETTINGS = ("t_end", "dt_out", "max_steps")


def read_trajectory_result(path) -> Trajectory:
    """:func:`open_trajectory`, checked as :func:`skewpend.open_result` reads every result: the
    parameters must be there, every setting of :data:`SIMULATE_SETTINGS` is present (None where
    the file leaves it out), and the stored energy must be the model's at the stored states (a few
    rows, spread over the run) to :data:`~skewpend.results.AGREEMENT`."""
    from ..results import agree

    traj = open_trajectory(path)
    if not getattr(traj.params, "is_numeric", True):
        raise ParameterError(f"{path} is not a trajectory made by skewpend: its parameters are missing")
    for key in SIMULATE_SETTINGS:  # a file leaves out a setting that is None (dt_out when unset)
        traj.settings.setdefault(key, None)
    rows = np.unique(np.linspace(0, len(traj.t) - 1, min(len(traj.t), 16)).astype(int))
    from .kernels import model_kernel, model_vector

    kernel, p = model_kernel(traj.params), model_vector(traj.params)
    agree(path, "energy", traj.energy[rows], kernel.energies(traj.y[rows], p))
    return traj


def check_start(kernel, p, y, names) -> None:
    """Refuse an initial state ``y`` (2 n) whose energy or acceleration is not finite (overflow:
    huge speeds or parameters) -- before any integration, for every computation from a start; the
    message names ``p``'s non-zero entries by ``names`` (the model's, ``kernels.model_vector_names``)."""
    pa = np.ascontiguousarray(p, dtype=np.float64)
    if not _finite_start(kernel, ctypes.cast(pa.ctypes.data, _DP), [float(v) for v in y]):
        values = ", ".join(f"{n} = {v:g}" for n, v in zip(names, p) if v != 0)
        raise ParameterError(
            f"the energy or acceleration at the initial state {np.asarray(y).tolist()} is not finite (overflow) for "
            f"{values}; use parameters and initial speeds of moderate size"
        )


#: Default cap on the attempted steps of one run (accepted + rejected).
MAX_STEPS = 100_000_000
#: Rows handed back by one call into the compiled integrator (memory per chunk ~ 0.4 MB).
_CHUNK_ROWS = 8192
_DEFAULT_DT = 1e-3
_DEFAULT_TOL = checks.DEFAULT_TOL
_FLOAT_MIN = sys.float_info.min
_DP = ctypes.POINTER(ctypes.c_double)


def _memory_limit() -> float:
    """Bytes a kept trajectory may take: a quarter of the physical memory."""
    try:
        return 0.25 * os.sysconf("SC_PAGE_SIZE") * os.sysconf("SC_PHYS_PAGES")
    except (ValueError, OSError, AttributeError):  # pragma: no cover - non-POSIX
        return 4e9


class _Accumulator:
    """Consumes output rows chunk by chunk: the energy balance, the kept rows, the file."""

    def __init__(self, kernel, p, keep: bool, writer, acc: Optional[np.ndarray] = None, nq: int = 2):
        self.kernel, self.p, self.keep, self.writer = kernel, p, keep, writer
        self.nq = nq  # coordinates: a row is (t, q, q', W)
        # the energy account in C, one call per chunk: acc = (max |E - W - E0|, max |E|, E0, E0 set)
        # (given: the array the Taylor integrator keeps the account of its rows in)
        self.acc = np.zeros(4) if acc is None else acc
        self._addr = (p.ctypes.data, self.acc.ctypes.data)  # (array.ctypes is slow)
        self.blocks: List[np.ndarray] = []  # kept rows (t, y(4), W), copies
        self.eblocks: List[np.ndarray] = []  # ... and their energies
        self.first: Optional[np.ndarray] = None
        self.last: Optional[np.ndarray] = None
        self.rows = 0

    def add(self, rows: np.ndarray, final: bool = False) -> None:
        """``rows``: (k, 6) = (t, phi, psi, dphi, dpsi, W), finite.  ``final``: the last rows of
        the run (then ``rows`` and the energies may be kept as views: nothing overwrites them)."""
        if rows.shape[0] == 0:
            return
        k = rows.shape[0]
        if rows.strides[1] != 8:
            rows = np.ascontiguousarray(rows)
        energy = np.empty(k)  # each block's own (kept as it is)
        p_addr, acc_addr = self._addr
        self.kernel.lib.sp_energy_account(rows.ctypes.data, k, rows.strides[0] // 8, p_addr, energy.ctypes.data, acc_addr)
        self._keep(rows, energy, final)

    def add_accounted(self, rows: np.ndarray, energy: np.ndarray, final: bool = False) -> None:
        """As :meth:`add`, for rows whose energies (``energy``, a buffer: copied) and account in
        ``acc`` the integrator made itself (the Taylor integrator)."""
        if rows.shape[0]:
            self._keep(rows, energy.copy(), final)

    def _keep(self, rows: np.ndarray, energy: np.ndarray, final: bool) -> None:
        k = rows.shape[0]
        if self.keep:
            self.blocks.append(rows if final else rows.copy())
            self.eblocks.append(energy)
        else:
            w = 2 * self.nq + 2
            if self.first is None:
                self.first = np.append(rows[0, :w], energy[0])
            self.last = np.append(rows[k - 1, :w], energy[k - 1])
        if self.writer is not None:
            tips = self.kernel.tips_many(rows, self.p, offset=1)
            s = 2 * self.nq + 1
            self.writer.write(np.column_stack([rows[:, :s], energy, rows[:, s], tips]))
        self.rows += k

    def columns(self):
        """``(t, y, energy, work)`` of the kept rows, each a contiguous array of its own."""
        s = 2 * self.nq + 1  # the column of W
        if self.keep:
            if len(self.blocks) == 1:
                rows, energy = self.blocks[0], self.eblocks[0]
            elif self.blocks:
                rows, energy = np.concatenate(self.blocks), np.concatenate(self.eblocks)
            else:
                rows, energy = np.empty((0, s + 1)), np.empty(0)
            energy = energy if len(self.blocks) == 1 else energy.copy()  # one block's: an array of its own already
            return rows[:, 0].copy(), rows[:, 1:s].copy(), energy, rows[:, s].copy()
        parts = [b for b in (self.first, self.last) if b is not None]
        if len(parts) == 2 and parts[0][0] == parts[1][0]:
            parts = parts[:1]
        table = np.array(parts) if parts else np.empty((0, s + 2))
        return table[:, 0].copy(), table[:, 1:s].copy(), table[:, s + 1].copy(), table[:, s].copy()


class _Prepared:
    """What ``simulate`` needs of one :class:`Parameters` object, computed on its first run and
    kept (a Parameters is immutable): its model kernel, parameter array (read-only) and Taylor
    kernels by order.  Keyed by the object's identity and checked to be that object (it is held,
    so its id cannot be reused while it is here); another object, even an equal one, is prepared
    afresh -- never a stale kernel or parameter array."""

    __slots__ = ("params", "kernel", "p", "p_ptr", "p_addr", "taylor", "taylor_tol", "coordinates", "form")

    def __init__(self, params: Parameters, kernel, p: np.ndarray):
        self.params, self.kernel, self.p = params, kernel, p
        self.coordinates, self.form = params.coordinates, kernel.form
        self.p_ptr = p.ctypes.data_as(ctypes.POINTER(ctypes.c_double))
        self.p_addr = p.ctypes.data
        self.taylor: Dict[int, Any] = {}
        self.taylor_tol: Dict[float, Any] = {}  # the same kernels by rtol (a run skips the order's formula)


#: The prepared Parameters objects, by id (at most :data:`_PREPARED_MAX`, the oldest dropped first;
#: an entry is a few hundred bytes, and preparing one again costs about 0.03 ms a call: a sweep over
#: a few dozen objects, e.g. one per method and tolerance, stays prepared).
_PREPARED: Dict[int, _Prepared] = {}
_PREPARED_MAX = 64


def _prepare(params, form: str = "") -> _Prepared:
    K = _KERNELS or _kernels()
    kernel = K.model_kernel(params, form)
    p = K.model_vector(params, kernel.form)
    p.flags.writeable = False
    entry = _Prepared(params, kernel, p)
    if form:  # a form asked for: not kept (the default's entry is what later calls look up)
        return entry
    while len(_PREPARED) >= _PREPARED_MAX:
        _PREPARED.pop(next(iter(_PREPARED)), None)
    _PREPARED[id(params)] = entry
    return entry


def _initial_state(y0, coordinates) -> List[float]:
    """``initial_state(y0, coordinates)`` as a list, quicker for the common case of 4 Python floats."""
    if len(coordinates) == 2 and type(y0) in (tuple, list) and len(y0) == 4:
        a, b, c, d = y0
        if type(a) is float and type(b) is float and type(c) is float and type(d) is float and abs(a) <= MAX_ANGLE \
                and abs(b) <= MAX_ANGLE and math.isfinite(c) and math.isfinite(d):  # (NaN fails the comparisons)
            return [a, b, c, d]
    checks.real_sequence("y0", y0)
    return initial_state(y0, coordinates).tolist()


def _finite_start(kernel, pp, y: List[float]) -> bool:
    """Whether the energy and the acceleration at ``y`` are finite (ctypes arrays straight into the C
    functions: NumPy's wrappers cost more than the calls)."""
    ns = 2 * kernel.nq + 1
    y5 = (ctypes.c_double * ns)(*y[:ns - 1], 0.0)
    deriv = (ctypes.c_double * ns)()
    kernel.lib.sp_rhs(y5, pp, deriv)
    return math.isfinite(kernel.lib.sp_energy(y5, pp)) and all(math.isfinite(v) for v in deriv)


def _check_start(kernel, entry: _Prepared, y: List[float]) -> None:
    """:func:`check_start` with the prepared parameter pointer (the same test, a few times quicker)."""
    if not _finite_start(kernel, entry.p_ptr, y):
        from .kernels import model_vector_names

        check_start(kernel, entry.p, y, model_vector_names(entry.params))  # raises, with the message


_KERNELS: Any = None


def _kernels():
    """:mod:`skewpend.numeric.kernels`, imported on the first simulation (not with this module)."""
    global _KERNELS
    if _KERNELS is None:
        from . import kernels

        _KERNELS = kernels
    return _KERNELS


def simulate(
    params: Parameters,
    y0: Sequence[float],
    t_end: float,
    *,
    dt_out: Optional[float] = None,
    method: str = AUTO,
    rtol: Optional[float] = None,
    atol: Optional[float] = None,
    dt: Optional[float] = None,
    max_steps: int = MAX_STEPS,
    throw: bool = False,
    out: Optional[os.PathLike] = None,
    keep: bool = True,
    progress: Optional[Callable[[float, float], None]] = None,
    controller: Any = None,
    form: str = "",
) -> Trajectory:
    """Integrate the equations of motion from ``y0 = (phi, psi, dphi, dpsi)`` over ``[0, t_end]``.

    ``method``: ``"auto"`` (the default), ``"dop853"`` or ``"taylor"`` (adaptive; ``rtol``, ``atol``,
    default 1e-10), ``"rk4"`` or ``"gauss"`` (fixed step ``dt`` [s], default 1e-3).  ``"auto"`` picks
    the fastest method that serves the request (:data:`AUTO_RULE`): ``"taylor"``, or ``"dop853"`` for
    inputs that vary (``controller``); ``Trajectory.method`` is the method that ran,
    ``settings["method"]`` is ``"auto"`` and ``settings["method_choice"]`` says why (so does
    ``summary()``).  With ``"auto"`` a fixed step ``dt`` is refused (name ``"rk4"`` or ``"gauss"``).  A setting that does not
    apply to the method (``dt`` with dop853 or taylor, ``rtol``/``atol`` with rk4 or gauss) is
    refused.  ``dt_out=None`` returns the integrator's own steps; otherwise the states on the
    grid ``0, dt_out, 2 dt_out, ... <= t_end`` (dense output for dop853 and taylor; for the
    fixed-step methods ``dt_out`` must be a multiple of ``dt``).

    ``"taylor"`` is an adaptive Taylor series method (Jorba & Zou's order and step rule, as
    heyoka's ``taylor_adaptive``, with skewpend's step factor): order ``p = ceil(-ln(rtol)/L) + 1``,
    step ``h = rho exp(-L) exp(-0.7/(p-1))`` with ``rho = min over m = p-1, p of
    (s / max_i |y_i[m]|)^(1/m)``, ``y_i[m]`` the Taylor coefficients and ``s = max(atol/rtol,
    max_i |y_i|)``: the series' last terms estimate a local error ``exp(-L (p-1)) <= rtol``; ``L`` by
    tolerance band (:func:`skewpend.numeric.kernels.taylor_rule`).  With
    ``rtol = atol = tol`` the scale is heyoka's for its ``tol`` (absolute error control while the
    state's largest component is below 1, relative above); ``atol`` enters only through that floor
    of the scale.  Every step is accepted (``stats["rejected"]`` is 0; ``stats["nfev"]`` counts
    series evaluations, one per step; ``stats["order"]`` is ``p``, ``stats["step_exponent"]`` is
    ``L``); dense output evaluates the step's polynomial.  The coefficient recurrences are generated
    from the derivation (Coulomb friction's ``atan`` included), each order a small library compiled
    on its first use, every product fused with its addition by an explicit ``fma`` (correctly
    rounded: the same bits with the processor's instruction, used where it has one, or without it,
    and with either compiler); it takes no ``controller``.
    At its own steps (``dt_out=None``) the energies of the rows come from the series' order 0 (T + Pi
    generated with them, in one C call with the steps), equal to the model kernel's to rounding.

    The compiled integrator works in bounded chunks: between chunks Ctrl-C raises
    :class:`KeyboardInterrupt` (within about 0.05 s) and ``progress(t, t_end)`` is called.
    ``out``: a ``.csv``/``.nc`` path the rows are streamed to while they are computed (the
    file appears complete, or not at all on an exception or interrupt).  ``keep=False``
    keeps only the first and last rows in the returned trajectory, so memory stays O(1)
    however long the run; the energy drift is still measured over every row.

    ``max_steps`` bounds the attempted steps; a run that cannot finish within it is refused
    up front (exactly for rk4/gauss, by an estimate from the first steps for dop853), and a
    run that stops early (non-finite state, step-size underflow, step cap) returns -- and
    writes -- what it computed, with ``status`` and ``message`` set, never NaN rows; with
    ``throw=True`` it raises :class:`~skewpend.errors.IntegrationError` after that.

    ``controller``: a :class:`skewpend.numeric.control.Controller` -- joint torques that vary
    (feedback laws, swing-up, a table), evaluated inside the compiled integrator at every stage
    (dop853 or rk4), or a Python function (``Controller.function``, the slow path: an exception
    it raises is raised here); ``Trajectory.inputs()`` gives them at the rows, and the work ``W``
    includes theirs.

    ``form``: the form of the generated code the run takes (``kernels.FORMS``: ``"exact"``, the
    specification's derivation, for two links; ``"straight"`` or ``"compact"``, the recursive algorithms,
    for any chain); default the fastest that prints the model (``kernels.model_form``).  A chain of two
    runs as the double pendulum: the same code, the same numbers.
    """
    K = _KERNELS or _kernels()
    # per Parameters object, once (_Prepared); then the quick checks of the common argument types,
    # the library's own checks (same messages) for everything else
    entry = _PREPARED.get(id(params)) if not form else None
    if entry is None or entry.params is not params:
        entry = None
        if not hasattr(params, "as_chain"):
            raise ParameterError(f"simulate takes Parameters or a Chain, got {type(params).__name__}")
        params.require_numeric("simulation")
        coordinates = params.coordinates
    else:
        coordinates = entry.coordinates
    y = _initial_state(y0, coordinates)
    if not (type(t_end) is float and _FLOAT_MIN <= t_end < math.inf):
        t_end = checks.positive("t_end", t_end)
    dt_out = None if dt_out is None else checks.positive("dt_out", dt_out)
    choice = None
    if method == AUTO:  # the rule of AUTO_RULE (a model without series recurrences: below, with the kernel)
        if dt is not None:
            raise ParameterError("dt is the step of rk4 and gauss; the default method 'auto' chooses its own steps (set "
                                 "rtol/atol), or name method='rk4' or 'gauss' with dt")
        K.taylor_build_in_foreground()  # a bad SKEWPEND_TAYLOR_BUILD refused before any build
        if getattr(controller, "hold", 0.0):
            method, choice, dt = "rk4", AUTO_RULE["sampled"], controller.hold
        elif not K.series_form(params, entry.form if entry is not None else form):
            method, choice = "dop853", AUTO_RULE["recursive"]
        elif controller is None:
            exact = (entry.form if entry is not None else K.model_form(params, form)[0]) == "exact"
            method, choice = "taylor", AUTO_RULE["taylor" if exact else "series"]
        else:
            method, choice = "dop853", AUTO_RULE["controller"]
    elif method not in METHODS:
        raise ParameterError(f"unknown method {method!r}; allowed: {AUTO}, {', '.join(METHODS)}")
    if dt_out is not None and dt_out > t_end:
        raise ParameterError(f"dt_out ({dt_out:g}) must not exceed t_end ({t_end:g})")
    if not (type(max_steps) is int and 1 <= max_steps <= checks.MAX_STEPS_LIMIT):
        max_steps = checks.max_steps(max_steps)
    if controller is not None:
        from .control import Controller

        if not isinstance(controller, Controller):
            raise ParameterError(f"controller must be a skewpend Controller (feedback, swing-up, a table or a Python "
                                 f"function: Controller.function), got {controller!r}")
        controller.check_model(len(coordinates))
        why = {"gauss": "gauss integrates Hamilton's equations of",
               "taylor": "taylor's series are generated for"}.get(method)
        if why is not None:
            raise ParameterError(f"inputs that vary need dop853 or rk4 ({why} the model with constant torques)")
        if controller.hold and (method != "rk4" or dt is None or abs(dt - controller.hold) > 1e-12 * controller.hold):
            raise ParameterError(f"a sampled law (held every {controller.hold:g} s) runs with method='rk4' and dt="
                                 f"{controller.hold:g} (each step's start its sample), or method='auto'; got method="
                                 f"{method!r}" + ("" if dt is None else f", dt={dt:g}"))
    if progress is not None:
        checks.progress_callable(progress, "progress(t, t_end)")
    if out is not None:
        out = check_output_path(out, TRAJECTORY_SUFFIXES, option="out")
    settings: Dict[str, Any] = {"t_end": t_end, "dt_out": dt_out, "max_steps": max_steps}
    if choice is not None:
        settings["method"], settings["method_choice"] = AUTO, choice
    if method in ADAPTIVE:
        if dt is not None:
            raise ParameterError(f"dt is the step of rk4 and gauss; {method} chooses its own steps (set rtol/atol instead)")
        if not (type(rtol) is float and type(atol) is float and checks.RTOL_MIN <= rtol <= 1.0
                and checks.ATOL_MIN <= atol <= 1.0):
            rtol, atol = checks.tolerances(rtol, atol, default=_DEFAULT_TOL)
        settings["rtol"], settings["atol"] = rtol, atol
        n_grid = 0 if dt_out is None else int(math.floor(t_end / dt_out * (1 + 1e-12))) + 1
        nsteps = stride = 0
    else:
        for name, value in (("rtol", rtol), ("atol", atol)):
            if value is not None:
                raise ParameterError(f"{name} is a tolerance of dop853 and taylor; {method} takes fixed steps dt (default "
                                     f"{_DEFAULT_DT:g} s)")
        step = _DEFAULT_DT if dt is None else checks.positive("dt", dt)
        if step > t_end:
            raise ParameterError(f"dt ({step:g}) must not exceed t_end ({t_end:g})")
        n_float = t_end / step
        if n_float > max_steps:
            raise ParameterError(
                f"t_end/dt = {n_float:.4g} steps exceeds the cap max_steps = {max_steps}; use a larger dt, a shorter t_end or raise the cap",
                parameter="max_steps")
        nsteps = int(round(n_float))
        if abs(nsteps * step - t_end) > 1e-9 * t_end:
            raise ParameterError(f"t_end ({t_end:g}) must be a whole number of steps dt ({step:g})")
        stride = 1
        if dt_out is not None:
            stride = int(round(dt_out / step))
            if stride < 1 or abs(stride * step - dt_out) > 1e-9 * dt_out:
                raise ParameterError(f"dt_out ({dt_out:g}) must be a whole multiple of dt ({step:g}) for method {method}")
        settings.update(dt=step)
        n_grid = nsteps // stride + 2
    known_rows = n_grid if (method not in ADAPTIVE or dt_out is not None) else None
    if known_rows is not None:
        _check_room(known_rows, keep, out)
    if controller is not None:
        settings["controller"] = controller.settings()

    if entry is None:
        entry = _prepare(params, form)
    kernel, p = entry.kernel, entry.p
    tk: Any = None
    if method == "taylor":
        assert rtol is not None  # an adaptive method's tolerances are set above
        rule = entry.taylor_tol.get(rtol)
        if rule is None:
            order, step_l = K.taylor_rule(rtol)
            tk = entry.taylor.get(order)
            if tk is None and choice is not None and not K.taylor_build_in_foreground():
                tk = K.built_taylor_kernel(params, order, model=kernel, form=entry.form)
                if tk is None:  # auto's first use of this order: dop853 now, the library built for later runs
                    method = "dop853"
                    settings["method_choice"] = AUTO_RULE["building"]
                    if K.build_taylor_in_background(params, order, entry.form):
                        exact = params.exact_model()
                        K.announce_background(f"the Taylor kernel of order {order}" +
                                              (K._bodies_words(exact) if exact is not None else f" of {params.title}"),
                                              "this run uses dop853", key=K.taylor_library_key(params, order, entry.form))
            if tk is None and method == "taylor":
                try:
                    tk = K.taylor_kernel(params, order, model=kernel)
                except ValueError as exc:  # a function in the equations without a series recurrence
                    if choice is None:
                        raise ParameterError(f"method taylor: {exc}; use dop853") from None
                    method, tk = "dop853", None  # auto: the adaptive method that takes any equations
                    settings["method_choice"] = AUTO_RULE["no series"].format(reason=exc)
            if tk is not None:
                entry.taylor[order] = tk
            if tk is not None and len(entry.taylor_tol) < 64:
                entry.taylor_tol[rtol] = (tk, step_l)
        else:
            tk, step_l = rule
    state: Any
    first = None
    if method == "taylor" and dt_out is None and entry.form == "exact":
        # the integrator's own steps: sp_taylor_rows (each row's energy and the account in C, the state
        # reset from y there), buffers from a pool; a run done in its first call returns at once
        buf = _TAYLOR_BUFFERS.pop() if _TAYLOR_BUFFERS else _TaylorBuffers(K)
        rows_fn = tk.__dict__.get("rows_fn") or _rows_fn(tk)
        state, ebuf = buf.state, buf.energy
        buf.y0[0], buf.y0[1], buf.y0[2], buf.y0[3] = y
        cols_addr, e_addr, acc_addr, s_addr, p_addr = buf.cols_addr, buf.e_addr, buf.acc_addr, buf.s_addr, entry.p_addr
        m = buf.m
        budget = _first_budget(max_steps)
        start = time.perf_counter()
        code = rows_fn(s_addr, buf.y0_addr, p_addr, t_end, rtol, atol, step_l, max_steps, budget, cols_addr, _CHUNK_ROWS,
                       e_addr, acc_addr, buf.m_ref)
        k = m.value
        if code == Status.NONFINITE or not (k and math.isfinite(ebuf[0])):
            _check_start(kernel, entry, y)  # an initial state that overflows: refused, as before any run
        if code >= 0 and keep and out is None:
            wall = time.perf_counter() - start
            traj = _taylor_result(params, method, settings, buf, k, code, wall, kernel, tk, step_l)
            _TAYLOR_BUFFERS.append(buf)
            if progress is not None:
                progress(state.t, t_end)
            if code != 0 and throw:
                raise IntegrationError(f"{method}: {traj.message} at t = {state.t:.6g} s")
            return traj
        first = (buf, code, start)  # the run goes on in chunks
    else:
        _check_start(kernel, entry, y)
    return _simulate_chunks(params, method, settings, y, t_end, dt_out, rtol, atol, max_steps, throw, out, keep,
                            progress, controller, kernel, p, entry, tk, K, nsteps, stride, step if method not in ADAPTIVE
                            else None, n_grid, first)


class _TaylorBuffers:
    """One Taylor run's state, row and energy buffers and their addresses, kept in a pool between
    runs (nothing of a returned trajectory refers to them: its columns are copies).  The rows come as
    columns (``sp_taylor_rows``' layout): ``t`` (cap,), ``y`` (cap, 4), ``w`` (cap,), views of ``cols``."""

    __slots__ = ("state", "cols", "t", "y", "w", "energy", "acc", "y0", "m", "m_ref", "s_addr", "cols_addr", "e_addr",
                 "acc_addr", "y0_addr")

    def __init__(self, K):
        cap = _CHUNK_ROWS
        self.state = K.TaylorState()
        self.cols = np.empty(6 * cap)
        self.t, self.y, self.w = self.cols[:cap], self.cols[cap:5 * cap].reshape(cap, 4), self.cols[5 * cap:]
        self.energy = np.empty(cap)
        self.acc = np.zeros(4)
        self.y0 = (ctypes.c_double * 4)()
        self.m = ctypes.c_int64(0)
        self.m_ref = ctypes.byref(self.m)
        self.s_addr, self.y0_addr = ctypes.addressof(self.state), ctypes.addressof(self.y0)
        self.cols_addr, self.e_addr, self.acc_addr = self.cols.ctypes.data, self.energy.ctypes.data, self.acc.ctypes.data

    def rows(self, m: int) -> np.ndarray:
        """The first ``m`` rows as (m, 6): t, the state, W (for the general path's accumulator)."""
        return np.column_stack((self.t[:m], self.y[:m], self.w[:m]))


#: Status by code (Status.of without its checks, for the quick path).
_STATUS_OF: Dict[int, Status] = {int(v): v for v in Status}

#: Taylor buffers not in use (a list: pop and append are atomic, so threads never share one).
_TAYLOR_BUFFERS: List[_TaylorBuffers] = []


def _rows_fn(tk):
    """``sp_taylor_rows`` of a Taylor library (taylor.c), its prototype set once."""
    vp, d, i64 = ctypes.c_void_p, ctypes.c_double, ctypes.c_int64
    fn = tk.lib.sp_taylor_rows
    fn.argtypes = [vp, vp, vp, d, d, d, d, i64, i64, vp, i64, vp, vp, vp]
    fn.restype = ctypes.c_int
    tk.rows_fn = fn
    return fn


def _taylor_result(params, method, settings, buf, k, code, wall, kernel, tk, step_l) -> "Trajectory":
    """The trajectory of a Taylor run done in one call: its ``k`` rows and energies copied out (each
    column in one piece)."""
    status = _STATUS_OF.get(code)
    if status is None:
        status = Status.of(code)
    stats = _stats(buf.state, wall, kernel, k, tk, step_l)
    err, scale = float(buf.acc[0]), float(buf.acc[1])
    # every field set at once (what the dataclass's __init__ does one object.__setattr__ at a time,
    # and __post_init__'s Status: status is one already): test_taylor checks the fields are all here
    traj = object.__new__(Trajectory)
    traj.__dict__.update(t=buf.t[:k].copy(), y=buf.y[:k].copy(), energy=buf.energy[:k].copy(), work=buf.w[:k].copy(),
                         params=params, method=method, settings=settings, stats=stats, status=status,
                         message=status.message, energy_drift=err / scale if scale > 0 else err, kept=True,
                         _kernel=kernel, controller=None)
    return traj


def _simulate_chunks(params, method, settings, y, t_end, dt_out, rtol, atol, max_steps, throw, out, keep, progress,
                     controller, kernel, p, entry, tk, K, nsteps, stride, step, n_grid, first=None) -> "Trajectory":
    """simulate's general path: the run in bounded chunks (``first``: a Taylor run's buffers, the
    code of its first call and its start time, the run begun by simulate)."""
    if method == "taylor" and first is None:
        state = tk.State.at(0.0, y)  # W = 0
    elif method == "taylor":
        state = first[0].state
    elif method == "gauss":
        nq = kernel.nq
        y5 = np.array(y + [0.0])
        mom = np.empty(nq)
        kernel.momenta(y5, p, mom)
        z5 = y5.copy()
        z5[nq:2 * nq] = mom
        state = kernel.State.at(0.0, z5)
        tol, max_iter = 1e-15, 100
        settings.update(implicit_tol=tol, implicit_max_iter=max_iter)
    else:
        state = kernel.State.at(0.0, y + [0.0] * (1 if controller is None else controller.state_size - len(y)))
    n = 2 * kernel.nq + 1 if controller is None else controller.state_size
    cstruct = None if controller is None else controller.struct()
    cref = None if cstruct is None else ctypes.byref(cstruct)

    k_out = ctypes.c_int64(0)
    step_l = K.taylor_rule(rtol)[1] if method == "taylor" else 0.0
    if first is not None:  # the Taylor integrator's steps, with their energies (sp_taylor_rows)
        buf = first[0]
        m, ebuf = buf.m, buf.energy
        rows_fn, s_addr, p_addr, cols_addr, e_addr, acc_addr = (tk.rows_fn, buf.s_addr, entry.p_addr, buf.cols_addr,
                                                                 buf.e_addr, buf.acc_addr)

        def call(budget: int) -> int:
            return rows_fn(s_addr, None, p_addr, t_end, rtol, atol, step_l, max_steps, budget, cols_addr, _CHUNK_ROWS,
                           e_addr, acc_addr, buf.m_ref)
    else:
        rows = np.empty((_CHUNK_ROWS, n + 1))
        m = ctypes.c_int64(0)
    if first is not None:
        pass
    elif method == "taylor":
        taylor_fn, s_addr, p_addr, rows_addr = tk.lib.sp_taylor, ctypes.addressof(state), entry.p_addr, rows.ctypes.data
        m_ref, k_ref, dense_dt = ctypes.byref(m), ctypes.byref(k_out), dt_out or 0.0

        def call(budget: int) -> int:
            return taylor_fn(s_addr, p_addr, t_end, rtol, atol, step_l, max_steps, budget, dense_dt, n_grid, k_ref,
                             rows_addr, _CHUNK_ROWS, m_ref)
    else:
        rows_ptr, p_ptr = rows.ctypes.data_as(_DP), entry.p_ptr
        sref = ctypes.byref(state)
        lib = kernel.lib

        def call(budget: int) -> int:
            if cref is not None:
                if method == "dop853":
                    return lib.sp_dop853_ctl(cref, sref, n, p_ptr, t_end, rtol, atol, max_steps, budget, dt_out or 0.0,
                                             n_grid, ctypes.byref(k_out), rows_ptr, _CHUNK_ROWS, ctypes.byref(m))
                return lib.sp_rk4_ctl(cref, sref, n, p_ptr, 0.0, step, nsteps, stride, budget, rows_ptr, _CHUNK_ROWS,
                                      ctypes.byref(m))
            if method == "dop853":
                return lib.sp_dop853(sref, n, p_ptr, t_end, rtol, atol, max_steps, budget,
                                     dt_out or 0.0, n_grid, ctypes.byref(k_out), rows_ptr, _CHUNK_ROWS, ctypes.byref(m))
            if method == "rk4":
                return lib.sp_rk4(sref, n, p_ptr, 0.0, step, nsteps, stride, budget, rows_ptr, _CHUNK_ROWS, ctypes.byref(m))
            return lib.sp_gauss(sref, n, p_ptr, 0.0, step, nsteps, stride, tol, max_iter, budget, rows_ptr, _CHUNK_ROWS,
                                ctypes.byref(m))

    writer = None
    metadata = {}
    with contextlib.ExitStack() as stack:
        if out is not None:
            from ..io import trajectory_columns

            writer = stack.enter_context(TrajectoryWriter(out, columns=trajectory_columns(
                getattr(params, "coordinates", ("phi", "psi")))))
        acc = _Accumulator(kernel, p, keep, writer, acc=None if first is None else buf.acc, nq=kernel.nq)

        def take(final: bool = False) -> None:
            if first is not None:
                acc.add_accounted(buf.rows(m.value), ebuf[: m.value], final)
            elif m.value:
                chunk = rows[: m.value, :2 * kernel.nq + 2]
                if method == "gauss":
                    chunk = kernel.speeds_many(chunk, p, offset=1)
                acc.add(chunk, final)

        def estimate() -> float:  # after the first bounded call: refuse what cannot finish
            steps = check_step_estimate(state, t_end, max_steps)
            if dt_out is None:
                _check_room(state.naccept * t_end / state.t, keep, out)
            return steps

        def report() -> None:
            if progress is not None:
                progress(state.t, t_end)

        budget = _first_budget(max_steps)
        # The first bounded call (a few ms) runs without Interrupts' signal handlers (installing and
        # restoring them costs more than a short run takes): a Ctrl-C during it raises when the call
        # returns.  A run that goes on continues in drive(), inside Interrupts.
        if first is None:
            start = time.perf_counter()
            code = int(call(budget))
        else:  # made by simulate
            code, start = first[1], first[2]
        if code == CallCode.BAD_ARGUMENTS:  # pragma: no cover - the arguments are checked above
            raise RuntimeError(f"internal error: bad arguments to sp_{method}")
        if code >= 0:
            take(True)
            report()
            status = Status.of(code)
        else:
            take()
            estimated = method not in ADAPTIVE
            if code == CallCode.BUDGET and not estimated:
                estimated = True
                estimate()
            report()
            intr = stack.enter_context(Interrupts())
            status = drive(call, budget=budget, take=take, check=intr.check, progress=report,
                           estimate=None if estimated else estimate, adapt=True, name=f"sp_{method}")
        if cstruct is not None:
            from .control import raise_law_error

            raise_law_error(cstruct)  # a Python law's exception, not a non-finite state
        stats = _stats(state, time.perf_counter() - start, kernel, acc.rows, tk if method == "taylor" else None, step_l)
        err, scale = float(acc.acc[0]), float(acc.acc[1])
        message = status.message
        t_col, y_col, e_col, w_col = acc.columns()
        traj = Trajectory(t=t_col, y=y_col, energy=e_col, work=w_col, params=params, method=method, settings=settings,
                          stats=stats, status=status, message=message, energy_drift=err / scale if scale > 0 else err,
                          kept=keep, _kernel=kernel, controller=controller)
        if writer is not None:
            metadata = trajectory_metadata(traj)
            metadata["t_reached"] = float(state.t)
            writer.finish(metadata)
    if first is not None:
        _TAYLOR_BUFFERS.append(first[0])
    if traj.status != 0 and throw:
        raise IntegrationError(f"{method}: {message} at t = {state.t:.6g} s")
    return traj


def _stats(state, wall: float, kernel, rows: int, tk, step_l: float) -> Dict[str, Any]:
    """A run's ``stats``: its integrator's counts, the kernel's origin, and a Taylor run's (``tk``: its library)
    order and step exponent -- ``"compiled"`` when this process built the library of that order."""
    stats = {"nfev": int(state.nfev), "steps": int(state.naccept), "rejected": int(state.nreject), "wall_time": wall,
             "kernel": kernel.origin, "kernel_build_time": kernel.build_time, "compiler": kernel.compiler, "rows": rows}
    if tk is not None:
        stats["order"], stats["step_exponent"] = int(state.order), step_l
        if tk.origin == "compiled":
            stats["kernel"] = "compiled"
            stats["kernel_build_time"] = kernel.build_time + tk.build_time
    return stats


def _first_budget(max_steps: int) -> int:
    """The step budget of a run's first bounded call: a few ms of work (at most 2000 steps), and past
    ``max_steps`` when the cap is that small -- so a run whose whole cap fits in the first call stops
    at the cap with its status (every method alike), never at the budget (which would refuse it by
    the estimate)."""
    budget = min(2000, max(10, max_steps // 20))
    return max_steps + 1 if budget >= max_steps else budget


def _check_room(rows: float, keep: bool, out) -> None:
    """Refuse up front what cannot fit: kept rows in memory, streamed rows on disk."""
    if keep:
        need = rows * 7 * 8
        limit = _memory_limit()
        if need > limit:
            raise ParameterError(
                f"keeping about {rows:.3g} rows would take {need / 1e9:.3g} GB of memory (limit {limit / 1e9:.3g} GB, a quarter "
                "of this machine's); stream them to a file with out=..., keep=False, or use a larger dt_out"
            )
    if out is not None:
        from ..io import check_disk_space

        check_disk_space(out, rows)
