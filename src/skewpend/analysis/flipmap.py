"""Flip-time maps: how long a start at rest takes until a joint flips over, on a grid of starts.

``flip_map(model, n)`` releases the model at rest from the centres of an ``n x n`` grid of cells over a
plane of two of its angles and records, for each cell, the *flip time* -- the first time any joint angle
leaves ``(-pi, pi)`` -- and which angle it was.  For the planar double pendulum this is the well-known
fractal picture; here it is computed for any skew, any bodies and any chain of links.

One job on the grid driver (:class:`FlipJob`, a :class:`~skewpend.numeric.grid.PlaneJob` as the region of
attraction's): every cell integrated by DOP853 (as ``simulate``'s default method) in compiled code, stopped
at its flip, located on the 7th-order dense output of the step in which an angle reaches pi (not at the
first step past it).  How the cells are integrated is a *strategy*, chosen by what the model's kernel can
print (:func:`flip_kernel`, as :func:`skewpend.analysis.roa.roa_kernel` chooses), never by the model's type:

* **lanes** -- the flip kernel (``sp_flip`` in ``integrators.c``; the specification's derivation, the
  double pendulum's today): ``SP_LANES`` starts side by side in SIMD registers, on a trigonometry-free
  state, and what no general integrator knows used first:

  - **energy bound.**  With constant torques ``tau`` and damping ``c >= 0``, ``T + V`` with
    ``V = Pi - tau·q`` never increases (``d/dt (T + V) = -c q'^2``), and released at rest it
    starts at ``V(q0)``.  To leave the square ``(-pi, pi)^2`` the (unwrapped) angles must reach
    its boundary, where ``V >= V_min``, the minimum of ``V`` over the four sides.  So a cell
    with ``V(q0) < V_min`` can never flip: NaN without integrating.  Without torques ``V`` is
    the potential energy; with torques the bound still holds but with the tilted potential
    (``Pi`` alone would be wrong: the torques feed energy in).  ``V_min`` comes from dense
    sampling of the generated ``V`` along each side and golden-section refinement of every
    sampled local minimum, less a safety margin of 1e-9 of the potential's scale.
  - **symmetry.**  When the equations (without torques) are odd under ``(q, q') -> -(q, q')``
    -- checked symbolically when the kernel is generated: true for thin rods and default axes,
    false e.g. for a centre of mass off the rod's plane -- and there are no torques (nor a held
    angle off 0), the start ``-q0`` is the mirror image of ``q0``: the same flip time and joint.
    In a window symmetric about 0 only half the cells are integrated (the cell centres are
    computed so that mirror cells are exact negatives).

* **one by one** -- any other model (a chain of links): the model's own kernel integrates each start
  (``sp_flip_many``), every cell integrated.

``shortcuts=False`` turns off the energy bound and the symmetry (every cell integrated), for
checking them.

Stored, resumable and distributed runs (``store=``, ``resume=``, ``scheduler=``; the ``cluster`` extra) are
the grid driver's (:func:`skewpend.numeric.grid.run_grid`), bitwise the same whatever the chunking, the workers
or the cluster: the work is cut along whole rows, each with its mirror row (:func:`row_groups`), the store
into chunks of whole rows dividing ``n`` (:func:`chunk_rows`) so that mirror chunks are chunks, its settings
fingerprinted (:func:`flip_settings`, :func:`fingerprint`).  :func:`open_flip_map` reads a complete store or
NetCDF file back -- also the chain flip maps that skewpend wrote before the two were one (kind ``chain flip map``).
"""

from __future__ import annotations

import ctypes
import json
import math
import os
import re
import warnings
from dataclasses import dataclass
from typing import Any, Callable, ClassVar, Dict, List, Optional, Sequence, Tuple

import numpy as np

from ..checks import DEFAULT_TOL, MAX_STEPS  # noqa: F401 - the module's documented defaults
from ..checks import max_steps as check_max_steps, numeric_model, numeric_params, positive, tolerances
from ..errors import ParameterError
from ..numeric.ensemble import Cancelled, FlipChunk, FlipIntegrator
from ..numeric.grid import MAX_N, PROBE_STEPS, ArraySpec, PlaneJob, PlaneMap, cell_centres, check_feasible, check_n  # noqa: F401 - MAX_N, check_n: this module's API
from ..numeric.grid import check_range, check_run_options, read_grid_result, steps_per_second
from ..results import DatasetSpec, canonical_json, fingerprint, netcdf_kind, zarr_store_kind
from ..status import Status
from ..symbolic.model import Parameters

__all__ = ["flip_map", "flip_time", "FlipOfStart", "FlipMap", "FlipJob", "open_flip_map", "flip_kernel", "cell_centres",
           "energy_barrier", "flip_settings", "fingerprint", "MAX_N"]

#: Points per side of the square sampled for the energy barrier.
_BARRIER_SAMPLES = 4097
#: Safety margin of the energy bound, relative to the potential's scale.
BARRIER_MARGIN = 1e-9
#: The store's kind (its attribute ``kind``): stores of anything else are refused.
STORE_KIND = "skewpend flip map"
#: What skewpend wrote for a chain's flip map before the two were one: the result kind of its files and
#: the kind of its stores (read back by :func:`open_flip_map`, ``which`` then numbered 1 .. n, 0 none).
FORMER_KIND, FORMER_STORE_KIND = "chain flip map", "skewpend chain flip map"
#: Columns of the per-chunk statistics kept in a store.
CHUNK_STATS = ("integrated", "skipped_energy", "mirrored", "failed", "steps", "rejected", "integrated_time")


@dataclass(frozen=True)
class FlipMap(PlaneMap):
    """The result of :func:`flip_map`.

    * ``plane`` -- the two angles varied (the double pendulum's ``("phi", "psi")``, a chain's e.g.
      ``("q1", "q3")``); ``x0``, ``y0`` -- their starting values, the cell centres [rad] (``x0`` along
      axis 0, ``y0`` along axis 1); ``held`` -- every angle at the plane's origin (the others as held) [rad];
      ``phi0``, ``psi0`` -- the starting angles named so, shape ``(n, n)`` (read-only broadcast views;
      :meth:`start` gives any angle's);
    * ``flip_time`` -- first time any angle leaves ``(-pi, pi)`` [s], NaN if not by ``t_end``;
    * ``which`` -- the angle that flipped, its index in ``params.coordinates`` (0 phi, 1 psi), -1 none;
    * ``params``, ``settings`` (n, t_end, the plane's ranges ``phi_range``/``psi_range`` or ``q1_range``...,
      tolerances, which shortcuts were used; ``plane`` and ``held`` when not the defaults), ``stats``
      (cells integrated / skipped by the energy bound / mirrored, ``failed``, ``steps`` (accepted),
      ``rejected``, ``energy_barrier`` [J], wall time, the run's chunks, store and cluster);
    * the result protocol's ``status`` (PARTIAL when cells failed) and the rest; ``flipped``, ``flipped_fraction``.
    """

    held: np.ndarray
    flip_time: np.ndarray
    which: np.ndarray

    result_kind: ClassVar[str] = "flip map"

    @property
    def flipped(self) -> np.ndarray:
        """Boolean mask of the cells that flipped by ``t_end``."""
        return np.isfinite(self.flip_time)

    @property
    def flipped_fraction(self) -> float:
        return float(np.count_nonzero(self.flipped)) / self.flip_time.size

    def start(self, name: str) -> np.ndarray:
        """The starting value of the angle ``name`` in every cell, shape ``(n, n)`` [rad]: an axis of the
        plane broadcast, or a held angle."""
        shape = np.shape(self.flip_time)
        if name == self.plane[0]:
            return np.broadcast_to(np.asarray(self.x0, dtype=float)[:, None], shape)
        if name == self.plane[1]:
            return np.broadcast_to(np.asarray(self.y0, dtype=float)[None, :], shape)
        coordinates = tuple(self.params.coordinates)
        if name not in coordinates:
            raise ParameterError(f"{name!r} is not an angle of this model ({', '.join(coordinates)})")
        return np.broadcast_to(float(self.held[coordinates.index(name)]), shape)

    @property
    def phi0(self) -> np.ndarray:
        return self.start("phi")

    @property
    def psi0(self) -> np.ndarray:
        return self.start("psi")

    def window(self) -> Tuple[Tuple[float, float], Tuple[float, float]]:
        """The plane's two ranges [rad] (the cells' outer edges), from the settings or else the cell centres."""
        out = []
        for name, centres in zip(self.plane, (self.x0, self.y0)):
            given = self.settings.get(f"{name}_range")
            if given is None:
                c = [float(v) for v in centres]
                half = 0.5 * (c[-1] - c[0]) / (len(c) - 1) if len(c) > 1 else 0.0
                given = (c[0] - half, c[-1] + half)
            out.append((float(given[0]), float(given[1])))
        return out[0], out[1]

    def positions(self) -> np.ndarray:
        """Every cell's start as angles, ``(n * n, nq)`` (row-major: ``x0`` slowest)."""
        return np.column_stack([self.start(c).ravel() for c in self.params.coordinates])

    def energy_margin(self) -> np.ndarray:
        """``V(q0) - V_threshold`` [J] on the cells, laid out like ``flip_time``: the potential
        ``V = Pi - tau·q`` at each start less the energy bound's threshold (its minimum on the
        boundary of the square ``(-pi, pi)^2``, less the safety margin); negative where energy
        alone forbids a flip.  The threshold the map used (``stats["energy_threshold"]``), or,
        for a map made without the shortcuts, the same computed now.  A model whose kernel prints
        no flip potential (a chain of links) has no energy bound: :class:`ParameterError`."""
        from ..numeric.kernels import model_vector

        kernel = flip_kernel(self.params)
        if not kernel.flip:
            raise ParameterError("this model's flip map has no energy bound (its kernel prints no flip potential)")
        p = model_vector(self.params, kernel.form)
        threshold = self.stats.get("energy_threshold")
        if threshold is None:
            barrier, scale = energy_barrier(kernel, p)
            threshold = barrier - BARRIER_MARGIN * max(scale, 1e-300)
        q = np.ascontiguousarray(self.positions())
        return kernel.flip_potential_many(q, p).reshape(np.shape(self.flip_time)) - threshold

    def _dataset(self) -> DatasetSpec:
        """Variables ``flip_time`` [s] and ``which`` over the plane's two angles (``phi0``, ``psi0``;
        ``q10``...) [rad]; attributes: the protocol's (params, settings, stats as JSON, status, message),
        the settings and statistics one by one (numbers, strings and lists only, so NetCDF and Zarr take
        them), the plane and the held angles."""
        attrs: Dict[str, Any] = {"title": FlipJob.title}
        attrs.update({key: int(value) if isinstance(value, bool) else list(value) if isinstance(value, tuple) else value
                      for group in (self.settings, self.stats) for key, value in group.items() if value is not None})
        attrs["plane"], attrs["held"] = ",".join(self.plane), [float(v) for v in self.held]
        attrs.update(self._base_attrs())
        attrs["flip_map_settings"] = canonical_json(self.settings)
        attrs["flip_map_stats"] = canonical_json(self.stats)
        names = tuple(self.params.coordinates)
        return self._plane_dataset(len(names), {"flip_time": (self.flip_time, _flip_time_attrs()),
                                                "which": (self.which, _which_attrs(names))}, attrs)


def _flip_time_attrs() -> Dict[str, str]:
    return {"units": "s", "long_name": "first time any joint angle leaves (-pi, pi), released at rest; NaN: not by t_end"}


def _which_attrs(coordinates: Sequence[str]) -> Dict[str, str]:
    """``joint that flipped: 0 phi, 1 psi, -1 none`` (a chain's ``0 q1, 1 q2, ...``)."""
    return {"long_name": "joint that flipped: " + ", ".join(f"{i} {c}" for i, c in enumerate(coordinates)) + ", -1 none"}


def open_flip_map(path) -> FlipMap:
    """A :class:`FlipMap` read back from a complete store ``*.zarr`` (made with ``flip_map(...,
    store=path)``; needs the ``cluster`` extra) or a file ``*.nc`` (:meth:`FlipMap.to_netcdf`;
    needs ``netCDF4``) -- of any model, also a chain's flip map written before the two were one.  A
    store whose run has not finished, or that is damaged, is refused (resume it first)."""
    from pathlib import Path

    from ..symbolic.model import model_from_mapping

    path = Path(path)
    suffix = path.suffix.lower()
    try:  # a store or file of the former kind (else the reader says what is wrong with it)
        former = ((suffix == ".zarr" and path.is_dir() and zarr_store_kind(path) == FORMER_STORE_KIND)
                  or (suffix == ".nc" and path.is_file() and netcdf_kind(path) == FORMER_KIND))
    except ParameterError:
        former = False

    def build(arrays, attrs, settings, stats):
        params = model_from_mapping(json.loads(attrs["params"]))
        coordinates = tuple(params.coordinates)
        plane = tuple(settings.get("plane") or coordinates[:2])
        which = np.asarray(arrays["which"]).astype(np.int8)
        if former:  # x_range, y_range -> the plane's names; which 1 .. n (0 none) -> the angle's index
            for name, key in zip(plane, ("x_range", "y_range")):
                settings[f"{name}_range"] = settings.pop(key)
            settings = {"shortcuts": True, "energy_bound": False, "symmetry": False, **settings}
            stats = {"integrated": stats.get("cells"), "skipped_energy": 0, "mirrored": 0, **stats}
            which = np.where(which > 0, which - 1, -1).astype(np.int8)
        for key in ("plane", "held", *(f"{c}_range" for c in plane)):
            if key in settings:
                settings[key] = tuple(settings[key])
        return FlipMap.made(plane, [arrays[f"{c}0"] for c in plane], params=params, settings=settings, stats=stats,
                            held=np.asarray(settings.get("held") or np.zeros(len(coordinates)), dtype=np.float64),
                            flip_time=np.asarray(arrays["flip_time"], dtype=np.float64), which=which)

    return read_grid_result(
        path, build, store_kind=FORMER_STORE_KIND if former else STORE_KIND,
        result_kind=FORMER_KIND if former else FlipMap.result_kind, what="a flip map",
        store_keys=("flip_settings", "flip_stats") if former else ("flip_map_settings", "flip_map_stats"))


@dataclass(frozen=True)
class FlipOfStart:
    """:func:`flip_time`'s answer for one start at rest: ``time`` [s] (NaN: no flip by
    ``t_end``), ``which`` joint (0 phi, 1 psi, -1 none), ``forbidden`` (energy alone forbids a
    flip: not integrated) and ``status`` (a failed integration is not SUCCESS)."""

    time: float
    which: int
    forbidden: bool
    status: Status = Status.SUCCESS


def flip_time(params: Parameters, phi0: float, psi0: float, *, t_end: float = 10.0, rtol: Optional[float] = None,
              atol: Optional[float] = None, max_steps: int = MAX_STEPS) -> FlipOfStart:
    """The flip time of one start ``(phi0, psi0)`` at rest [rad], exactly as a cell of
    :func:`flip_map` with the same settings computes it (the energy bound, the flip kernel,
    DOP853 with the flip located on the dense output)."""
    from ..numeric.kernels import kernel_module, parameter_vector

    params = numeric_params(params, "a flip time")
    t_end = positive("t_end", t_end)
    rtol, atol = tolerances(rtol, atol)
    max_steps = check_max_steps(max_steps)
    q0 = np.array([[float(phi0), float(psi0)]])
    if not np.all(np.isfinite(q0)) or np.any(np.abs(q0) >= math.pi):
        raise ParameterError(f"the start must lie within (-pi, pi) in both angles, got ({phi0!r}, {psi0!r})")
    kernel = kernel_module(params, flip=True)
    p = parameter_vector(params)
    barrier, scale = energy_barrier(kernel, p)
    if kernel.flip_potential_many(q0, p)[0] < barrier - BARRIER_MARGIN * max(scale, 1e-300):
        return FlipOfStart(math.nan, -1, True)
    out = FlipIntegrator(kernel, p, t_end=t_end, rtol=rtol, atol=atol, max_steps=max_steps).run(q0)
    which = int(out.which[0])
    if which == -2:
        return FlipOfStart(math.nan, -1, False, Status.PARTIAL)
    return FlipOfStart(float(out.time[0]), which, False)


# -- the energy bound -----------------------------------------------------------------------------------
def energy_barrier(kernel, p, *, samples: int = _BARRIER_SAMPLES) -> Tuple[float, float]:
    """``(V_min, scale)``: the minimum of ``V = Pi - tau·q`` over the boundary of the square
    ``[-pi, pi]^2`` (the four sides), and the potential's scale (its largest magnitude there).

    Each side is sampled at ``samples`` points; around each of the (up to 8) lowest sampled
    local minima the search zooms in four times (each 257 points between the neighbours of the best one so far), to an
    interval below 1e-12 rad.  ``V`` is the generated ``flip_potential``.
    """
    s = np.linspace(-math.pi, math.pi, samples)
    best, scale = math.inf, 0.0
    for fixed_axis in (0, 1):
        for end in (-math.pi, math.pi):
            def side(u, fixed_axis=fixed_axis, end=end):
                q = np.empty((u.size, 2))
                q[:, fixed_axis] = end
                q[:, 1 - fixed_axis] = u
                return kernel.flip_potential_many(q, p)

            v = side(s)
            scale = max(scale, float(np.max(np.abs(v))))
            best = min(best, float(np.min(v)))
            minima = np.flatnonzero((v[1:-1] <= v[:-2]) & (v[1:-1] <= v[2:])) + 1
            for i in minima[np.argsort(v[minima], kind="stable")[:8]]:  # the 8 lowest (all, but for flat V)
                a, b = s[i - 1], s[i + 1]
                for _ in range(4):
                    u = np.linspace(a, b, 257)
                    w = side(u)
                    k = int(np.argmin(w))
                    best = min(best, float(w[k]))
                    a, b = u[max(k - 1, 0)], u[min(k + 1, u.size - 1)]
    return best, scale


# -- the strategies: how the cells are integrated ------------------------------------------------------
def flip_kernel(model):
    """The kernel a flip map of ``model`` runs on, which chooses its strategy (see the module): the flip
    kernel (``sp_flip``: SIMD lanes, the flip potential of the energy bound, the symmetry check of the
    mirror) where the model's code is printed in the exact form (``kernels.model_form``) and its lanes'
    generator prints it, else the model's own kernel (``sp_flip_many``, one start at a time).  As
    :func:`skewpend.analysis.roa.roa_kernel` chooses."""
    from ..numeric.kernels import model_form, model_kernel

    if model_form(model)[0] == "exact":
        try:
            return model_kernel(model, flip=True)
        except ValueError:  # the lanes' code generator refused the model
            pass
    return model_kernel(model)


def _integrator(kernel, p, **settings):
    """The integrator of the kernel's strategy, ``run(starts, cancel) -> FlipChunk``: the flip kernel's SIMD
    lanes (:class:`~skewpend.numeric.ensemble.FlipIntegrator`), or the model kernel's one start after the other."""
    return (FlipIntegrator if kernel.flip else _OneByOne)(kernel, p, **settings)


class _OneByOne:
    """The model kernel's integrator: one start after the other (``sp_flip_many``), ``row`` starts a call
    with ``cancel`` checked between calls; ``which`` as the lanes' (-2 failed)."""

    def __init__(self, kernel, p, *, t_end: float, rtol: float, atol: float, max_steps: int, row: int = 64):
        self.kernel, self.p = kernel, np.ascontiguousarray(p, dtype=np.float64)
        self.t_end, self.rtol, self.atol, self.max_steps, self.row = float(t_end), float(rtol), float(atol), int(max_steps), row

    def run(self, q: np.ndarray, cancel=None):
        m, nq = q.shape
        starts = np.ascontiguousarray(np.hstack([q, np.zeros((m, nq))]), dtype=np.float64)
        time_, which = np.full(m, np.nan), np.full(m, -1, dtype=np.int32)
        steps, rejected = np.zeros(m, dtype=np.int64), np.zeros(m, dtype=np.int64)
        status = np.zeros(m, dtype=np.int8)
        dp, i64p = ctypes.POINTER(ctypes.c_double), ctypes.POINTER(ctypes.c_int64)
        for a in range(0, m, self.row):
            if cancel is not None and cancel.is_set():
                raise Cancelled()
            self.kernel.lib.sp_flip_many(
                self.p.ctypes.data_as(dp), starts[a:].ctypes.data_as(dp), min(m, a + self.row) - a, self.t_end,
                self.rtol, self.atol, self.max_steps, time_[a:].ctypes.data_as(dp),
                which[a:].ctypes.data_as(ctypes.POINTER(ctypes.c_int32)), steps[a:].ctypes.data_as(i64p),
                rejected[a:].ctypes.data_as(i64p), status[a:].ctypes.data_as(ctypes.POINTER(ctypes.c_int8)))
        which = np.where(status != 0, -2, np.where(np.isfinite(time_), which, -1)).astype(np.int32)
        return FlipChunk(time_, which, steps, rejected)


# -- the map ---------------------------------------------------------------------------------------
def flip_map(
    params,
    n: int,
    *,
    t_end: float = 10.0,
    phi_range: Optional[Sequence[float]] = None,
    psi_range: Optional[Sequence[float]] = None,
    rtol: Optional[float] = None,
    atol: Optional[float] = None,
    workers: Optional[int] = None,
    progress: Optional[Callable[[int, int], None]] = None,
    shortcuts: bool = True,
    chunk_size: Optional[int] = None,
    max_steps: int = MAX_STEPS,
    store=None,
    resume: bool = False,
    scheduler=None,
    plane: Optional[Sequence[str]] = None,
    ranges=None,
    held=None,
) -> FlipMap:
    """The flip-time map of the model ``params`` (the double pendulum's :class:`~skewpend.Parameters` or a
    :class:`~skewpend.Chain` of links) on the ``n x n`` grid of cell centres over a ``plane`` of two of
    its angles (default its first two, ``("phi", "psi")`` or ``("q1", "q2")``), each over its range of
    ``ranges`` (``((lo, hi), (lo, hi))`` [rad], each within ``[-pi, pi]``; default the whole circle) --
    ``phi_range``/``psi_range`` give the range of the angle so named, the double pendulum's -- the other
    angles at ``held`` (every angle [rad], each within ``(-pi, pi)``, the plane's own entries ignored;
    default 0: hanging), released at rest.

    ``flip_time[i, j]`` and ``which[i, j]`` are those of the start ``x0[i]``, ``y0[j]`` (:class:`FlipMap`).
    DOP853 with ``rtol``/``atol`` (default 1e-10 each); the crossing is located on the dense
    output.  ``workers`` threads (default: the cores this process may use) integrate units of
    whole rows (with their mirror rows); the result does not depend on their number.
    ``progress(done_cells, total_cells)`` is called in the calling thread as units finish.
    Ctrl-C stops within a few milliseconds (:class:`KeyboardInterrupt`).
    ``shortcuts=False`` integrates every cell (no energy bound, no mirror symmetry; a model whose
    kernel has no SIMD lanes -- a chain of links -- integrates every cell anyway).
    ``max_steps`` caps the attempted steps of one trajectory (a cell that hits it, or fails
    otherwise, is counted in ``stats["failed"]``, left NaN, and makes the map's ``status``
    PARTIAL, with a warning).

    ``store``: a directory ``*.zarr`` the map is written to chunk by chunk (blocks of whole
    rows; ``chunk_size`` is the store's chunk in cells, rounded down to whole rows dividing
    ``n``), with the settings and their SHA-256 fingerprint in its attributes; an existing
    path is refused unless ``resume=True``, which computes only the chunks not yet done (and
    those found damaged) and refuses a store made with other settings (a missing store is
    started afresh).  The store's layout, not ``chunk_size``, rules a resumed run.
    ``scheduler``: a ``tcp://HOST:PORT`` address or a :class:`distributed.Client`: the chunks
    run as tasks on that Dask cluster (whose workers need this skewpend and a C compiler), and
    ``workers`` must be left out.  Either way the result is bitwise the same as without them.
    Both need the ``cluster`` extra (``pip install "skewpend[cluster]"``); without them neither
    Zarr nor Dask is imported.  The computation is a :class:`FlipJob` on
    :func:`skewpend.numeric.grid.run_grid`.
    """
    from .. import __version__
    from ..numeric.grid import run_grid  # looked up here: a test's stand-in for the driver is called
    from ..numeric.kernels import model_vector, model_vector_names

    params = numeric_model(params, "a flip map")
    n = check_n(n)
    t_end = positive("t_end", t_end)
    (a, b), (ra, rb), q = _plane(tuple(params.coordinates), plane, ranges, held, phi_range=phi_range, psi_range=psi_range)
    rtol, atol = tolerances(rtol, atol)
    workers = check_run_options(workers=workers, scheduler=scheduler, store=store, resume=resume, progress=progress,
                                chunk_size=chunk_size)
    max_steps = check_max_steps(MAX_STEPS if max_steps is None else max_steps)
    _check_memory(n)
    kernel = flip_kernel(params)
    p = model_vector(params, kernel.form)
    barrier = threshold = None
    symmetric = False
    if shortcuts and kernel.flip:
        torques = [i for i, name in enumerate(model_vector_names(params, kernel.form)) if _TORQUE.fullmatch(name)]
        symmetric = bool(kernel.flip_odd and not np.any(p[torques]) and not np.any(q)
                         and ra[0] == -ra[1] and rb[0] == -rb[1])
        barrier, scale = energy_barrier(kernel, p)
        threshold = barrier - BARRIER_MARGIN * max(scale, 1e-300)
    job = FlipJob(params=params, n=n, plane=(a, b), x_range=ra, y_range=rb, held=tuple(float(v) for v in q),
                  t_end=t_end, rtol=rtol, atol=atol, max_steps=int(max_steps), symmetric=symmetric,
                  threshold=threshold, version=__version__, kernel_name=kernel.path.name, shortcuts=bool(shortcuts),
                  barrier=barrier)
    state = job.state(kernel, p)
    _check_feasible(job, state)
    result = run_grid(job, workers=workers, scheduler=scheduler, store=store, resume=bool(resume), progress=progress,
                      chunk_size=chunk_size, state=state)
    if result.stats["failed"]:
        warnings.warn(f"flip_map: {result.message}", RuntimeWarning, stacklevel=2)
    return result


#: The run-time vector's constant joint torques (``tau1``, ``tau2``, ...: the link field ``torque``).
_TORQUE = re.compile(r"tau\d+")


def _plane(coordinates: Tuple[str, ...], plane, ranges, held, **named):
    """``((a, b), (range_a, range_b), held)``: the plane's two angles, their ranges and every angle at the
    plane's origin (the plane's own entries 0), checked."""
    nq = len(coordinates)
    if plane is None:
        plane = coordinates[:2]
    try:
        a, b = plane
    except (TypeError, ValueError):
        a = b = None
    if a not in coordinates or b not in coordinates or a == b:
        raise ParameterError(f"plane must be two different angles of {', '.join(coordinates)} (a flip map starts at "
                             f"rest), got {plane!r}")
    given = {key: value for key, value in named.items() if value is not None}
    for key in given:
        name = key[:-len("_range")]
        if name not in (a, b):
            raise ParameterError(f"{key} is the double pendulum's (the range of its angle {name}); this model's flip map "
                                 f"takes plane=, ranges= and held= (of {', '.join(coordinates)})")
    if given and ranges is not None:
        raise ParameterError(f"give the ranges either as ranges= or as {' and '.join(given)}, not both")
    full = (-math.pi, math.pi)
    if ranges is None:
        out = [check_range(f"{c}_range", given[f"{c}_range"]) if f"{c}_range" in given else full for c in (a, b)]
    else:
        try:
            ra, rb = ranges
        except (TypeError, ValueError):
            raise ParameterError(f"ranges must be two ranges ((lo, hi), (lo, hi)) of the plane's angles, got {ranges!r}") from None
        out = [check_range(f"range of {a}", ra), check_range(f"range of {b}", rb)]
    if held is None:
        q = np.zeros(nq)
    else:
        try:
            q = np.array(held, dtype=float).reshape(-1)
        except (TypeError, ValueError):
            q = np.zeros(0)
        if q.shape != (nq,) or not np.all(np.isfinite(q)) or np.any(np.abs(q) >= math.pi):
            raise ParameterError(f"held must be the chain's {nq} angles, each within (-pi, pi) [rad], got {held!r}")
    q[[coordinates.index(a), coordinates.index(b)]] = 0.0
    return (str(a), str(b)), (out[0], out[1]), q


def _check_feasible(job: "FlipJob", state) -> None:
    """Refuse a map whose cells could not finish within ``max_steps`` (a trial run of the map's own
    integrator from energetic starts of the window: the ones that flip last the longest)."""
    kernel, p, _ = state
    cx, cy = max(map(abs, job.x_range)), max(map(abs, job.y_range))
    cells = job.positions(np.array([0.9 * cx, 0.9 * cx, 0.5 * cx]), np.array([0.9 * cy, -0.9 * cy, 0.0]))

    def trial(t):
        out = _integrator(kernel, p, t_end=t, rtol=job.rtol, atol=job.atol, max_steps=PROBE_STEPS).run(cells)
        lived = np.where(np.isfinite(out.time), out.time, t)  # a failed trial: a lower bound of the rate
        return steps_per_second(out.steps + out.rejected, lived), not np.any(out.which == -2)

    check_feasible(trial, params=job.params, t_end=job.t_end, rtol=job.rtol, atol=job.atol, max_steps=job.max_steps,
                   what="this flip map")


#: Bytes per cell while a map is computed (results, energies, indices, sort).
_BYTES_PER_CELL = 40


def _check_memory(n: int) -> None:
    """Refuse up front a map whose working memory would exceed half of this machine's."""
    try:
        limit = 0.5 * os.sysconf("SC_PAGE_SIZE") * os.sysconf("SC_PHYS_PAGES")
    except (ValueError, OSError, AttributeError):  # pragma: no cover - non-POSIX
        return
    need = _BYTES_PER_CELL * float(n) * n
    if need > limit:
        raise ParameterError(
            f"an {n} x {n} map needs about {need / 1e9:.3g} GB of memory while it is computed, more than half of "
            f"this machine's ({2 * limit / 1e9:.3g} GB); use a smaller n (or windows of a larger map)"
        )


# -- the job ------------------------------------------------------------------------------------------
def _plain(v):
    if isinstance(v, dict):
        return {k: _plain(x) for k, x in v.items()}
    if isinstance(v, (list, tuple)):
        return [_plain(x) for x in v]
    if v is None or isinstance(v, str):
        return v
    return float(v)


def flip_settings(params, n: int, *, plane: Sequence[str], ranges, held, t_end: float, rtol: float, atol: float,
                  max_steps: int, shortcuts: bool) -> Dict[str, Any]:
    """The resolved settings that determine a map's every bit (and this skewpend's version),
    as plain JSON data: what a store's fingerprint is the SHA-256 of.  The ranges are named by the
    plane's angles (``phi_range``, ``q3_range``); ``plane`` and ``held`` are recorded where they are not
    the defaults (the first two angles; every other angle 0)."""
    from .. import __version__

    return {"kind": "flip_map", "params": _plain(params.to_dict()), "n": int(n), "t_end": float(t_end),
            **{f"{c}_range": [float(x) for x in r] for c, r in zip(plane, ranges)},
            "rtol": float(rtol), "atol": float(atol), "max_steps": int(max_steps), "shortcuts": bool(shortcuts),
            "method": "dop853", "skewpend_version": __version__, **_placement(params.coordinates, plane, held)}


def _placement(coordinates, plane, held) -> Dict[str, list]:
    """``plane`` and ``held`` as settings record them: only where they are not the defaults."""
    if tuple(plane) == tuple(coordinates)[:2] and not any(held):
        return {}
    return {"plane": [str(c) for c in plane], "held": [float(v) for v in held]}


def chunk_rows(n: int, *, chunk_size: Optional[int] = None) -> int:
    """Rows per store chunk of an ``n x n`` map: :func:`skewpend.numeric.grid.chunk_rows`."""
    from ..numeric.grid import chunk_rows as rows_per_chunk

    return rows_per_chunk(n, n, chunk_size=chunk_size)


def row_groups(n: int, symmetric: bool) -> list:
    """The smallest pieces of work: each row with its mirror row ``n - 1 - i`` when the map is
    mirror-symmetric (the mirror cells are copies, so one piece computes both), else each row
    alone.  Every row is in exactly one group."""
    if not symmetric:
        return [(i,) for i in range(n)]
    groups: List[Tuple[int, ...]] = [(i, n - 1 - i) for i in range(n // 2)]
    if n % 2:
        groups.append((n // 2,))
    return groups


@dataclass(frozen=True)
class FlipJob(PlaneJob):
    """A flip map as a job of the grid driver: small and picklable (sent with each cluster task)."""

    params: Any  # any model: the double pendulum's Parameters, a chain of links
    n: int
    plane: Tuple[str, str]
    x_range: Tuple[float, float]
    y_range: Tuple[float, float]
    held: Tuple[float, ...]  # every angle at the plane's origin
    t_end: float
    rtol: float
    atol: float
    max_steps: int
    symmetric: bool
    threshold: Optional[float]  # energy bound: cells with V(q0) below it never flip (None: not used)
    version: str
    kernel_name: str  # the compiled kernel's file name: the same generated code (and strategy) everywhere
    shortcuts: bool = True
    barrier: Optional[float] = None

    kind: ClassVar[str] = STORE_KIND
    what: ClassVar[str] = "a flip map"
    stat_names: ClassVar[Tuple[str, ...]] = CHUNK_STATS
    title: ClassVar[str] = "flip-time map of starts at rest (skewpend)"

    def base_state(self) -> np.ndarray:
        """Every start: the held angles, at rest."""
        return np.r_[np.asarray(self.held, dtype=float), np.zeros(len(self.held))]

    def arrays(self):
        return {"flip_time": ArraySpec("float64", np.nan, _flip_time_attrs()),
                "which": ArraySpec("int8", -1, _which_attrs(self.params.coordinates))}

    def settings(self) -> Dict[str, Any]:
        return flip_settings(self.params, self.n, plane=self.plane, ranges=(self.x_range, self.y_range),
                             held=self.held, t_end=self.t_end, rtol=self.rtol, atol=self.atol,
                             max_steps=self.max_steps, shortcuts=self.shortcuts)

    def store_attrs(self) -> Dict[str, Any]:
        s = self.settings()
        return {"params": json.dumps(s["params"]), "shortcuts": int(self.shortcuts),
                **{k: v for k, v in s.items() if k not in ("kind", "params", "shortcuts", "skewpend_version")}}

    def row_groups(self):
        return row_groups(self.n, self.symmetric)

    def state(self, kernel, p):
        """What :meth:`compute` needs: the kernel, ``p`` and the integrator of the kernel's strategy."""
        return kernel, p, _integrator(kernel, p, t_end=self.t_end, rtol=self.rtol, atol=self.atol,
                                      max_steps=self.max_steps)

    def setup(self):
        """The kernel (compiled or loaded here), checked to be the very code of this run."""
        from ..numeric.kernels import model_vector

        kernel = self.checked_kernel(flip_kernel(self.params))
        return self.state(kernel, model_vector(self.params, kernel.form))

    def positions(self, x: np.ndarray, y: np.ndarray) -> np.ndarray:
        """Starts as angles ``(m, nq)``: the held angles, the plane's two ``x`` and ``y``."""
        return np.ascontiguousarray(self.states(x, y)[:, :self.nq])

    def compute(self, state, rows, cancel=None):
        """The cells of whole ``rows`` (closed under the mirror when the map is symmetric): the
        same representative of each mirror pair is integrated, the same energy test decides,
        wherever and in whatever unit the rows are computed -- so the same bits."""
        kernel, p, integrator = state
        n = self.n
        total = n * n
        xs, ys = (values for values, _ in self.coords().values())
        rows = np.asarray(rows, dtype=np.int64)
        ids = (rows[:, None] * n + np.arange(n, dtype=np.int64)[None, :]).ravel()
        reps = ids[ids <= total - 1 - ids] if self.symmetric else ids

        def starts(f):
            return self.positions(xs[f // n], ys[f % n])

        todo = reps
        if kernel.flip:  # the flip potential: the energy test, and the order of the cells
            V = kernel.flip_potential_many(starts(reps), p)
            if self.threshold is not None:
                forbidden = V < self.threshold
                if self.symmetric:
                    forbidden &= kernel.flip_potential_many(starts(total - 1 - reps), p) < self.threshold
                todo, V = reps[~forbidden], V[~forbidden]
            # the long-lived (low-energy) cells first: the lanes' last cells are then the quick ones, so
            # few lanes idle at the end of the unit (each cell's bits do not depend on the order)
            todo = todo[np.argsort(V, kind="stable")]
        out = integrator.run(starts(todo), cancel)

        pos = np.full(n, -1, dtype=np.int64)
        pos[rows] = np.arange(rows.size)
        time_ = np.full((rows.size, n), np.nan)
        which = np.full((rows.size, n), -1, dtype=np.int8)
        w = out.which.astype(np.int8)
        bad = w == -2
        w[bad] = -1
        time_[pos[todo // n], todo % n] = out.time
        which[pos[todo // n], todo % n] = w
        mirror = total - 1 - todo
        copied = mirror != todo if self.symmetric else np.zeros(todo.size, dtype=bool)
        mirror = mirror[copied]
        time_[pos[mirror // n], mirror % n] = out.time[copied]
        which[pos[mirror // n], mirror % n] = w[copied]

        at, m = pos[todo // n], rows.size  # the row (in the unit) of each integrated cell
        lived = np.where(np.isfinite(out.time) & ~bad, out.time, np.where(bad, 0.0, self.t_end))
        stats = np.zeros((m, len(CHUNK_STATS)))
        stats[:, 0] = np.bincount(at, minlength=m)
        stats[:, 2] = np.bincount(pos[mirror // n], minlength=m)
        stats[:, 1] = n - stats[:, 0] - stats[:, 2]
        for col, weights in enumerate((bad, out.steps, out.rejected, lived), start=3):
            stats[:, col] = np.bincount(at, weights=weights, minlength=m)
        return {"flip_time": time_, "which": which}, stats

    def result(self, run) -> FlipMap:
        n = self.n
        totals = run.totals(CHUNK_STATS)
        flip_time, which = run.data["flip_time"], run.data["which"]
        settings = {
            "n": n, "t_end": self.t_end,
            **{f"{c}_range": tuple(r) for c, r in zip(self.plane, (self.x_range, self.y_range))},
            **{k: tuple(v) for k, v in _placement(self.params.coordinates, self.plane, self.held).items()},
            "rtol": self.rtol, "atol": self.atol, "max_steps": int(self.max_steps), "method": "dop853",
            "shortcuts": self.shortcuts, "energy_bound": self.threshold is not None, "symmetry": self.symmetric,
        }
        kernel = run.state[0] if run.state is not None else None
        stats = {
            "cells": n * n, "integrated": int(totals["integrated"]), "skipped_energy": int(totals["skipped_energy"]),
            "mirrored": int(totals["mirrored"]), "flipped": int(np.count_nonzero(np.isfinite(flip_time))),
            "failed": int(totals["failed"]), "steps": int(totals["steps"]), "rejected": int(totals["rejected"]),
            "integrated_time": float(totals["integrated_time"]), "energy_barrier": self.barrier,
            "energy_threshold": self.threshold,
            "lanes": None if kernel is None else (kernel.flip_lanes if kernel.flip else 1),
            "kernel": None if kernel is None else kernel.origin,
            "kernel_build_time": None if kernel is None else kernel.build_time,
            **run.info,
        }
        return FlipMap.made(self.plane, [values for values, _ in self.coords().values()], params=self.params,
                            settings=settings, stats=stats, held=np.asarray(self.held, dtype=float),
                            flip_time=flip_time, which=which)

    def result_attrs(self, result: FlipMap) -> Dict[str, Any]:
        return {"flip_map_settings": canonical_json(result.settings), "flip_map_stats": canonical_json(result.stats)}
