"""Regions of attraction: which starts a saturated LQR brings to its equilibrium, on a grid.

``region_of_attraction(params, target, actuated, n)`` designs (or takes) the LQR about
``target`` with the torque limit ``umax`` and releases the closed loop from the centres of an
``n x n`` grid of cells on a 2-D slice of the state space through the target -- two of
``phi, psi, phi', psi'`` (``plane``; a chain of links': two of ``q1 … qn, dq1 … dqn``) varied over
``window`` about their target values, the others at theirs.  Each start is integrated by DOP853 with the inputs inside the compiled code
(``sp_capture_lanes`` in ``integrators.c``: eight starts side by side in SIMD lanes, on the flip
map's trigonometry-free state, each step stopped at the law's switches -- the saturation kinks and
the wrap's jumps -- rather than rejected around them; ``sp_capture_many``, one by one, for a model
the lanes cannot print; no Python per step) until it enters the LQR's inner
estimate ``dx^T P dx < rho`` (:func:`skewpend.lqr`: inside it ``V = dx^T P dx`` decreases along
the saturated nonlinear loop, so a start that gets there is captured) -- its *capture time* --
or until ``t_end``.  A start entering the estimate is captured (the estimate is an inner bound);
one that does not by ``t_end`` is counted as not captured (it may be captured later, or never).

The map is a :class:`RoaJob` on the grid driver (:func:`skewpend.numeric.grid.run_grid`), as the flip map:
bitwise the same result whatever the chunking, the workers or a resume after kill -9 (each start's arithmetic
is its own).

The feedback wraps the angle errors to (-pi, pi]: the law jumps where an angle is opposite its
target (the hanging position, for an upright target).  A trajectory that lingers there can chatter
on the jump (a sliding mode, with no classical solution); the integration then stops at
``max_steps`` and the cell is *failed* (NaN, ``outcome`` -1, status PARTIAL) -- rare on cell
centres, and reported, never guessed.
"""

from __future__ import annotations

import json
import math
from dataclasses import dataclass
from typing import Any, Callable, ClassVar, Dict, Optional, Sequence, Tuple

import numpy as np

from ..checks import max_steps as check_max_steps, numeric_model, positive, tolerances
from ..errors import EquilibriumError, ParameterError
from ..numeric.control import Controller, capture_many, torque_limits
from ..numeric.grid import PROBE_STEPS, ArraySpec, PlaneJob, PlaneMap, check_feasible, check_n, check_run_options
from ..numeric.grid import read_grid_result, steps_per_second
from ..results import DatasetSpec, canonical_json
from ..schema import state_coordinates
from .control import EVERY_LINK_UP
from .equilibria import wrap

__all__ = ["region_of_attraction", "RegionOfAttraction", "RoaJob", "open_region_of_attraction",
           "STORE_KIND", "MAX_STEPS_ROA"]

STORE_KIND = "skewpend region of attraction"
#: Default cap on the steps of one start (a normal one takes hundreds; see the module on chattering).
MAX_STEPS_ROA = 200_000
#: Largest grid side.
MAX_N = 4096
#: Statistics per row (and per store chunk).
CHUNK_STATS = ("cells", "captured", "failed", "steps", "rejected")


def _plane(plane, nq: int) -> Tuple[str, str]:
    names = state_coordinates(nq)
    try:
        a, b = plane
    except (TypeError, ValueError):
        raise ParameterError(f"plane must be two of {', '.join(names)}, got {plane!r}") from None
    if a not in names or b not in names or a == b:
        raise ParameterError(f"plane must be two different coordinates of {', '.join(names)}, got {plane!r}")
    return str(a), str(b)


def _window(name: str, value, angle: bool) -> Tuple[float, float]:
    try:
        lo, hi = (float(v) for v in value)
    except (TypeError, ValueError):
        raise ParameterError(f"{name} must be a pair (start, stop) of offsets from the target, got {value!r}") from None
    if not (math.isfinite(lo) and math.isfinite(hi) and lo < hi):
        raise ParameterError(f"{name} must be finite with start < stop, got ({lo:g}, {hi:g})")
    if angle and (lo < -math.pi or hi > math.pi):
        raise ParameterError(f"{name}: an angle's offsets from the target must lie within [-pi, pi] (the rest is the "
                             f"same angles again), got ({lo:g}, {hi:g})")
    return lo, hi


@dataclass(frozen=True)
class RegionOfAttraction(PlaneMap):
    """The result of :func:`region_of_attraction`.

    * ``plane`` -- the two coordinates varied (of ``phi, psi, dphi, dpsi``; a chain's ``q1 … dqn``); ``x0``, ``y0`` -- their
      starting values (cell centres; ``x0`` along axis 0, ``y0`` along axis 1) [rad or rad/s];
    * ``capture_time`` (n, n) [s] -- when the start entered the LQR's estimate (0: it starts
      inside), NaN if not by ``t_end`` or failed; ``outcome`` (n, n) -- 1 captured, 0 not
      captured by ``t_end``, -1 failed;
    * ``target`` (the equilibrium's state), ``K`` (2 x 4; a chain's n x 2 n), ``P``, ``rho`` -- the feedback and its
      estimate ``dx^T P dx < rho``; :meth:`ellipse` is its slice in ``plane``;
    * ``captured_fraction``, ``inner_fraction`` (cells inside the estimate at the start);
    * the result protocol's fields: ``stats`` (``cells``, ``captured``, ``failed``, ``steps``, ``rejected``; the
      run's chunks, store and cluster), ``status`` (PARTIAL when cells failed).
    """

    capture_time: np.ndarray
    outcome: np.ndarray
    target: np.ndarray
    K: np.ndarray
    P: np.ndarray
    rho: float

    result_kind: ClassVar[str] = "region of attraction"

    @property
    def captured(self) -> np.ndarray:
        return self.outcome == 1

    @property
    def _index(self) -> Dict[str, int]:
        return state_coordinates(len(self.target) // 2)

    @property
    def captured_fraction(self) -> float:
        """The fraction of the cells captured by ``t_end``: the region's share of the window."""
        return float(np.count_nonzero(self.captured)) / self.capture_time.size

    def deviations(self) -> Tuple[np.ndarray, np.ndarray]:
        """The axes as offsets from the target (angles wrapped to (-pi, pi])."""
        out, index, nq = [], self._index, len(self.target) // 2
        for name, values in zip(self.plane, (self.x0, self.y0)):
            d = np.asarray(values, dtype=float) - self.target[index[name]]
            out.append(wrap(d) if index[name] < nq else d)
        return out[0], out[1]

    @property
    def inner_fraction(self) -> float:
        """The fraction of the cells inside the LQR's estimate at the start (all captured at t = 0)."""
        dx, dy = self.deviations()
        S = self._slice()
        X, Y = np.meshgrid(dx, dy, indexing="ij")
        v = S[0, 0] * X * X + 2 * S[0, 1] * X * Y + S[1, 1] * Y * Y
        return float(np.count_nonzero(v < self.rho)) / v.size

    def ellipse(self, points: int = 361) -> np.ndarray:
        """The boundary of the estimate's slice ``dx^T P dx = rho`` in ``plane`` (other offsets 0),
        as offsets from the target: an array (points, 2)."""
        L = np.linalg.cholesky(self._slice())
        s = np.linspace(0.0, 2 * np.pi, points)
        unit = np.vstack([np.cos(s), np.sin(s)]) * math.sqrt(self.rho)
        return np.linalg.solve(L.T, unit).T

    def _slice(self) -> np.ndarray:
        """``P`` restricted to the plane's two coordinates."""
        i, j = (self._index[c] for c in self.plane)
        return self.P[np.ix_([i, j], [i, j])]

    def _dataset(self) -> DatasetSpec:
        attrs = {"title": RoaJob.title, "plane": ",".join(self.plane), "target": self.target.tolist(),
                 "K": self.K.ravel().tolist(), "P": self.P.ravel().tolist(), "rho": self.rho,
                 "captured_fraction": self.captured_fraction, **self._base_attrs()}
        return self._plane_dataset(len(self.target) // 2, {name: (getattr(self, name), attrs_)
                                                           for name, attrs_ in _VARIABLES.items()}, attrs)


_VARIABLES = {
    "capture_time": {"units": "s", "long_name": "time the closed loop entered the LQR's region estimate; NaN: not by t_end"},
    "outcome": {"long_name": "1 captured, 0 not captured by t_end, -1 integration failed"},
}


@dataclass(frozen=True)
class RoaJob(PlaneJob):
    """A region-of-attraction map as a job of the grid driver (small and picklable)."""

    params: Any  # Parameters, or a chain of links
    n: int
    plane: Tuple[str, str]
    x_range: Tuple[float, float]  # absolute values of the plane's first coordinate (cell edges)
    y_range: Tuple[float, float]
    target: Tuple[float, ...]
    K: Tuple[float, ...]  # nq x 2 nq (the double pendulum's 2 x 4), row-major
    P: Tuple[float, ...]  # 2 nq x 2 nq, row-major
    rho: float
    actuated: Any  # the double pendulum's label, a chain's joint numbers
    umax: Tuple[float, ...]
    t_end: float
    rtol: float
    atol: float
    max_steps: int
    version: str
    kernel_name: str

    kind: ClassVar[str] = STORE_KIND
    what: ClassVar[str] = "a region-of-attraction map"
    stat_names: ClassVar[Tuple[str, ...]] = CHUNK_STATS
    title: ClassVar[str] = "region of attraction of a saturated LQR (skewpend)"

    def base_state(self) -> np.ndarray:
        """Every start: the target, the plane's two coordinates set."""
        return np.asarray(self.target, dtype=float)

    def arrays(self):
        return {"capture_time": ArraySpec("float64", np.nan, _VARIABLES["capture_time"]),
                "outcome": ArraySpec("int8", -1, _VARIABLES["outcome"])}

    def settings(self) -> Dict[str, Any]:
        return {"kind": "region_of_attraction", "params": self.params.to_dict(), "n": self.n, "plane": list(self.plane),
                "x_range": list(self.x_range), "y_range": list(self.y_range), "target": list(self.target),
                "K": list(self.K), "P": list(self.P), "rho": self.rho,
                "actuated": self.actuated if isinstance(self.actuated, str) else list(self.actuated),
                "umax": [u if math.isfinite(u) else None for u in self.umax], "t_end": self.t_end, "rtol": self.rtol,
                "atol": self.atol, "max_steps": self.max_steps, "method": "dop853", "skewpend_version": self.version}

    def controller(self):
        return Controller.feedback(np.reshape(self.K, (self.nq, 2 * self.nq)), np.asarray(self.target),
                                   actuated=self.actuated, umax=self.umax)

    def setup(self):
        from ..numeric.kernels import model_vector

        return self.checked_kernel(roa_kernel(self.params)), model_vector(self.params), self.controller()

    def compute(self, state, rows, cancel=None):
        kernel, p, ctl = state
        rows = np.asarray(rows, dtype=np.int64)
        time_, steps, rejected, status = capture_many(kernel, p, ctl, self.starts(rows), t_end=self.t_end, rtol=self.rtol,
                                            atol=self.atol, max_steps=self.max_steps, P=self._P,
                                            rho=self.rho, cancel=cancel)
        shape = (rows.size, self.n)
        failed = (status != 0).reshape(shape)
        captured = np.isfinite(time_).reshape(shape)
        outcome = np.where(failed, -1, np.where(captured, 1, 0)).astype(np.int8)
        stats = np.column_stack([np.full(rows.size, self.n), captured.sum(1), failed.sum(1),
                                 steps.reshape(shape).sum(1), rejected.reshape(shape).sum(1)]).astype(float)
        return {"capture_time": time_.reshape(shape), "outcome": outcome}, stats

    def result(self, run) -> RegionOfAttraction:
        totals = run.totals(CHUNK_STATS)
        settings = {k: v for k, v in self.settings().items() if k not in ("kind", "params", "skewpend_version")}
        stats = {"cells": self.n * self.n, **{k: int(totals[k]) for k in CHUNK_STATS[1:]}, **run.info}
        return RegionOfAttraction.made(
            self.plane, [values for values, _ in self.coords().values()], params=self.params, settings=settings,
            stats=stats, note=" (a start that chatters where the wrapped feedback jumps, at the angle opposite the target)",
            capture_time=run.data["capture_time"], outcome=run.data["outcome"], target=np.asarray(self.target, dtype=float),
            K=np.reshape(self.K, (self.nq, 2 * self.nq)), P=self._P, rho=self.rho)

    @property
    def _P(self) -> np.ndarray:
        return np.reshape(self.P, (2 * self.nq, 2 * self.nq))

    def result_attrs(self, result: RegionOfAttraction) -> Dict[str, Any]:
        return {"roa_settings": canonical_json(result.settings), "roa_stats": canonical_json(result.stats)}


def region_of_attraction(
    params,
    target=EVERY_LINK_UP,
    actuated="both",
    n: int = 64,
    *,
    design=None,
    plane: Optional[Sequence[str]] = None,
    window: Optional[Sequence[Sequence[float]]] = None,
    umax=10.0,
    Q=None,
    R=None,
    t_end: float = 10.0,
    rtol: Optional[float] = 1e-8,
    atol: Optional[float] = 1e-8,
    max_steps: int = MAX_STEPS_ROA,
    workers: Optional[int] = None,
    progress: Optional[Callable[[int, int], None]] = None,
    chunk_size: Optional[int] = None,
    store=None,
    resume: bool = False,
    scheduler=None,
) -> RegionOfAttraction:
    """The region of attraction of the LQR about ``target`` with the ``actuated`` joints and the
    torque limit ``umax`` [N m] (see the module), on ``n x n`` cells of the slice ``plane`` of any model: two
    of its coordinates and their rates (the double pendulum's ``phi, psi, dphi, dpsi``, a chain's ``q1 … qn,
    dq1 … dqn``; default the first two angles); ``target`` a label with a word per link (default every link
    up), an equilibrium or angles near one; ``actuated`` as :func:`skewpend.linearization` takes it.

    ``design``: an :class:`~skewpend.analysis.control.LQR` from :func:`skewpend.lqr` (then
    ``target``, ``actuated``, ``Q``, ``R`` and ``umax`` come from it); otherwise it is designed
    here with ``Q``, ``R``, ``umax``.  ``window``: the ranges of the two coordinates as offsets from
    the target, ``((lo, hi), (lo, hi))`` -- default ``(-pi, pi)`` for an angle (the whole circle)
    and ``(-5, 5)`` rad/s for a speed.  Each start runs for at most ``t_end`` seconds; DOP853 at
    ``rtol``/``atol`` (default 1e-8: whether and when, not the path, is wanted) with at most
    ``max_steps`` steps per start.  ``workers``, ``progress(done_cells, total)``, ``chunk_size``,
    ``store`` (``*.zarr``), ``resume`` and ``scheduler`` as for :func:`skewpend.flip_map`."""
    from .. import __version__
    from ..numeric.grid import run_grid  # looked up here: a test's stand-in for the driver is called
    from .control import LQR, equilibrium_argument, lqr

    params = numeric_model(params, "a region of attraction")
    nq = params.n
    target = equilibrium_argument(target, params, "target")  # a word per link; angles reduced modulo 2 pi
    index = state_coordinates(nq)
    n = check_n(n)
    if n > MAX_N:
        raise ParameterError(f"n must be at most {MAX_N} for a region of attraction, got {n}")
    a, b = _plane(tuple(index)[:2] if plane is None else plane, nq)
    if window is None:
        window = [(-math.pi, math.pi) if index[c] < nq else (-5.0, 5.0) for c in (a, b)]
    try:
        wa, wb = window
    except (TypeError, ValueError):
        raise ParameterError(f"window must be two ranges ((lo, hi), (lo, hi)) of offsets from the target, got {window!r}") from None
    wa = _window(f"window of {a}", wa, index[a] < nq)
    wb = _window(f"window of {b}", wb, index[b] < nq)
    t_end = positive("t_end", t_end)
    rtol, atol = tolerances(rtol, atol)
    max_steps = check_max_steps(max_steps)
    workers = check_run_options(workers=workers, scheduler=scheduler, store=store, resume=resume, progress=progress,
                                chunk_size=chunk_size)
    if design is None:
        design = lqr(params, target, actuated, Q, R, umax=umax)
    elif not isinstance(design, LQR):
        raise ParameterError(f"design must be an LQR from skewpend.lqr, got {type(design).__name__}")
    elif design.params != params:
        raise ParameterError("design was made for other parameters than params")
    if not (design.rho > 0 and math.isfinite(design.rho)):
        raise EquilibriumError(f"the LQR's region estimate is empty or unbounded (rho = {design.rho:g}): raise umax, "
                               "or change Q and R (a Q that leaves states unweighted gives a singular P, which "
                               "bounds no region)")
    lin = design.linearization
    x_star = lin.target
    ia, ib = index[a], index[b]
    kernel = roa_kernel(params)
    job = RoaJob(params=params, n=n, plane=(a, b), x_range=(x_star[ia] + wa[0], x_star[ia] + wa[1]),
                 y_range=(x_star[ib] + wb[0], x_star[ib] + wb[1]), target=tuple(float(v) for v in x_star),
                 K=tuple(float(v) for v in design.gain.ravel()), P=tuple(float(v) for v in np.ravel(design.P)),
                 rho=float(design.rho), actuated=design.controller().actuated,
                 umax=torque_limits(design.umax, nq), t_end=t_end, rtol=rtol,
                 atol=atol, max_steps=int(max_steps), version=__version__, kernel_name=kernel.path.name)
    state = job.setup()
    _check_feasible(job, state)
    return run_grid(job, workers=workers, scheduler=scheduler, store=store, resume=bool(resume), progress=progress,
                    chunk_size=chunk_size, state=state)


def roa_kernel(model):
    """The kernel of a map, which chooses its strategy: the flip kernel with ``sp_capture_lanes`` (the starts in
    SIMD lanes) where its generator prints the model (:func:`~skewpend.analysis.flipmap.flip_kernel`) and the
    lanes can take it (not Coulomb friction: not polynomial in the speeds), else the model's own kernel
    (``sp_capture_many``, one start at a time)."""
    from ..numeric.kernels import model_kernel
    from .flipmap import flip_kernel

    kernel = model_kernel(model) if model.has_friction else flip_kernel(model)
    return kernel if hasattr(kernel.lib, "sp_capture_lanes") else model_kernel(model)


def _check_feasible(job: RoaJob, state) -> None:
    """Refuse, before any work, a map whose starts could not finish: a trial run of the closed loop
    (the job's own kernel and law) from the window's corners and edges gives the steps per
    simulated second; a start not captured is followed to ``t_end``, so a ``t_end`` that would need
    more than :data:`~skewpend.numeric.grid.FEASIBILITY_FACTOR` x ``max_steps`` at that rate is
    refused with the estimate (as for every grid: starts that settle step more slowly)."""
    kernel, p, ctl = state
    xs, ys = (values for values, _ in job.coords().values())
    corners = [(xs[i], ys[j]) for i in (0, -1, len(xs) // 2) for j in (0, -1, len(ys) // 2) if (i, j) != (len(xs) // 2,) * 2]
    starts = job.states(*zip(*corners))

    def trial(t):
        time_, steps, rejected, status = capture_many(kernel, p, ctl, starts, t_end=t, rtol=job.rtol, atol=job.atol,
                                                      max_steps=PROBE_STEPS, P=job._P, rho=job.rho)
        moved = ~(time_ == 0)  # a start inside the estimate is captured at once: no steps, no rate
        lived = np.where(np.isfinite(time_), time_, t)[moved]  # a captured start stops early: its rate until then
        return steps_per_second((steps + rejected)[moved], lived), not np.any(status != 0)  # attempted steps

    check_feasible(trial, params=job.params, t_end=job.t_end, rtol=job.rtol, atol=job.atol, max_steps=job.max_steps,
                   what="this region of attraction")


def open_region_of_attraction(path) -> RegionOfAttraction:
    """A :class:`RegionOfAttraction` read back from a complete store ``*.zarr`` or a file ``*.nc``."""
    from ..symbolic.model import model_from_mapping

    def build(arrays, attrs, settings, stats):
        a, b = settings["plane"]
        target = np.asarray(settings["target"], dtype=float)
        nq = len(target) // 2
        return RegionOfAttraction.made(
            (a, b), [arrays[f"{c}0"] for c in (a, b)], params=model_from_mapping(json.loads(attrs["params"])),
            settings=settings, stats=stats, capture_time=np.asarray(arrays["capture_time"], dtype=float),
            outcome=np.asarray(arrays["outcome"]).astype(np.int8), target=target,
            K=np.reshape(np.asarray(settings["K"], dtype=float), (nq, 2 * nq)),
            P=np.reshape(np.asarray(settings["P"], dtype=float), (2 * nq, 2 * nq)), rho=float(settings["rho"]))

    return read_grid_result(path, build, store_kind=STORE_KIND, result_kind=RegionOfAttraction.result_kind,
                            what="a region of attraction", store_keys=("roa_settings", "roa_stats"))
