"""Flip-time maps: how long a start at rest takes until a joint flips over, on a grid of starts.

``flip_map(params, n)`` releases the pendulum at rest from the centres of an ``n x n`` grid of
cells over the window ``phi_range x psi_range`` and records, for each, the *flip time*: the
first time either joint angle leaves ``(-pi, pi)`` -- NaN when that does not happen by
``t_end``.  For the planar double pendulum this is the well-known fractal picture; here it
is computed for any skew ``alpha`` and any bodies.

How (see :mod:`skewpend.numeric.ensemble` and ``sp_flip`` in ``integrators.c``):

* every trajectory is integrated by DOP853 (as ``simulate``'s default method) in compiled code
  generated from the derivation, ``SP_LANES`` trajectories side by side in SIMD registers, and
  stopped at its flip, located on the 7th-order dense output of the step in which an angle
  reaches pi (not at the first step past it);
* the cells are integrated in chunks on a thread pool, one thread per core: bitwise the same
  result whatever the chunk size or worker count;
* what no general integrator knows is used first:

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
    false e.g. for a centre of mass off the rod's plane -- and there are no torques, the start
    ``-q0`` is the mirror image of ``q0``: the same flip time and joint.  In a window symmetric
    about 0 only half the cells are integrated (the cell centres are computed so that mirror
    cells are exact negatives).
  - **early exit**: a trajectory stops at its flip.

``shortcuts=False`` turns off the energy bound and the symmetry (every cell integrated), for
checking them.

Stored, resumable and distributed runs (``store=``, ``resume=``, ``scheduler=``; the
``cluster`` extra, Zarr and dask.distributed, imported only then):

* the work is cut along whole rows: each row with its mirror row (one integration serves
  both), grouped into about 16 units per worker thread -- units run on the local thread
  pool, or in batches as tasks on a Dask cluster (at most
  :data:`~skewpend.numeric.ensemble.MAX_TASKS` tasks; the workers compile or load the kernel
  themselves, and the results come back to this process);
* a unit computes exactly the cells, with exactly the arithmetic, of the in-memory map, so
  the result is bitwise the same whatever the chunking, the workers or the cluster;
* the store (:class:`~skewpend.numeric.store.RowStore`, a ``*.zarr`` directory) is cut into
  chunks of whole rows, at most 65536 cells and at least 8 chunks by default, a divisor of
  ``n`` so that mirror chunks are chunks: its template (arrays, coordinates, the settings
  and their SHA-256 fingerprint, :func:`flip_settings` / :func:`fingerprint`) is written
  first, then each chunk once all its rows are in, its ``done`` flag last.  ``resume=True``
  computes only the rows of chunks not done, and refuses a store made with other settings,
  naming what differs;
* :func:`open_flip_map` reads a complete store (or a NetCDF file written by
  :meth:`FlipMap.to_netcdf`) back into a :class:`FlipMap`.
"""

from __future__ import annotations

import json
import math
import os
import warnings
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any, Callable, ClassVar, Dict, List, Optional, Sequence, Tuple

import numpy as np

from ..checks import DEFAULT_TOL, MAX_STEPS  # noqa: F401 - the module's documented defaults
from ..checks import max_steps as check_max_steps, numeric_params, positive, tolerances
from ..errors import ParameterError
from ..numeric.grid import MAX_N, GridJob, cell_centres, check_n, check_range  # noqa: F401 - the last four: this module's API
from ..results import DatasetSpec, Result, canonical_json, fingerprint
from ..status import Status
from ..symbolic.model import Parameters

if TYPE_CHECKING:
    from .chainflip import ChainFlipMap

__all__ = ["flip_map", "flip_time", "FlipOfStart", "FlipMap", "FlipJob", "open_flip_map", "cell_centres", "energy_barrier", "flip_settings",
           "fingerprint", "MAX_N"]

#: Points per side of the square sampled for the energy barrier.
_BARRIER_SAMPLES = 4097
#: Safety margin of the energy bound, relative to the potential's scale.
BARRIER_MARGIN = 1e-9
_BARRIER_MARGIN = BARRIER_MARGIN


@dataclass(frozen=True)
class FlipMap(Result):
    """The result of :func:`flip_map`.

    * ``phi0``, ``psi0`` -- the starting angles (cell centres) [rad], shape ``(n, n)``: ``phi0``
      varies along axis 0, ``psi0`` along axis 1 (read-only broadcast views of the two axes);
    * ``flip_time`` -- first time either angle leaves ``(-pi, pi)`` [s], NaN if not by ``t_end``;
    * ``which`` -- the joint that flipped: 0 (phi), 1 (psi), -1 none;
    * ``params``, ``settings`` (n, t_end, window, tolerances, which shortcuts were used),
      ``stats`` (cells integrated / skipped by the energy bound / mirrored, ``failed``, ``steps``
      (accepted), ``rejected``, ``energy_barrier`` [J], wall time, the run's chunks, store and
      cluster);
    * ``status`` (:class:`~skewpend.status.Status`: PARTIAL when cells failed), ``message``,
      ``ok``; ``to_xarray()``, ``to_netcdf(path)``, ``summary()`` (the result protocol).
    """

    phi0: np.ndarray
    psi0: np.ndarray
    flip_time: np.ndarray
    which: np.ndarray

    result_kind: ClassVar[str] = "flip map"

    @property
    def n(self) -> int:
        return int(self.flip_time.shape[0])

    @property
    def flipped(self) -> np.ndarray:
        """Boolean mask of the cells that flipped by ``t_end``."""
        return np.isfinite(self.flip_time)

    def energy_margin(self) -> np.ndarray:
        """``V(q0) - V_threshold`` [J] on the cells, laid out like ``flip_time``: the potential
        ``V = Pi - tau·q`` at each start less the energy bound's threshold (its minimum on the
        boundary of the square ``(-pi, pi)^2``, less the safety margin); negative where energy
        alone forbids a flip.  The threshold the map used (``stats["energy_threshold"]``), or,
        for a map made without the shortcuts, the same computed now."""
        from ..numeric.kernels import kernel_module, parameter_vector

        kernel = kernel_module(self.params, flip=True)
        p = parameter_vector(self.params)
        threshold = self.stats.get("energy_threshold")
        if threshold is None:
            barrier, scale = energy_barrier(kernel, p)
            threshold = barrier - BARRIER_MARGIN * max(scale, 1e-300)
        q = np.column_stack([np.asarray(self.phi0, dtype=float).ravel(), np.asarray(self.psi0, dtype=float).ravel()])
        return kernel.flip_potential_many(np.ascontiguousarray(q), p).reshape(np.shape(self.flip_time)) - threshold

    def _dataset(self) -> DatasetSpec:
        """Variables ``flip_time`` [s] and ``which`` over ``phi0``, ``psi0`` [rad]; attributes: the
        protocol's (params, settings, stats as JSON, status, message) and the settings and
        statistics one by one (numbers, strings and lists only, so NetCDF and Zarr take them)."""
        attrs: Dict[str, Any] = {"title": FlipJob.title}
        for group in (self.settings, self.stats):
            for key, value in group.items():
                if value is None:
                    continue
                attrs[key] = int(value) if isinstance(value, bool) else (list(value) if isinstance(value, tuple)
                                                                         else value)
        attrs.update(self._base_attrs())
        attrs["flip_map_settings"] = canonical_json(self.settings)
        attrs["flip_map_stats"] = canonical_json(self.stats)
        dims = ("phi0", "psi0")
        return DatasetSpec(
            variables={"flip_time": (dims, self.flip_time, dict(_VARIABLES["flip_time"])),
                       "which": (dims, self.which, dict(_VARIABLES["which"]))},
            coords={"phi0": (("phi0",), self.phi0[:, 0].copy(), dict(_VARIABLES["phi0"])),
                    "psi0": (("psi0",), self.psi0[0, :].copy(), dict(_VARIABLES["psi0"]))},
            attrs=attrs,
        )


#: Attributes of the variables in files (NetCDF, Zarr, xarray).
_VARIABLES = {
    "flip_time": {"units": "s",
                  "long_name": "first time either joint angle leaves (-pi, pi), released at rest; NaN: not by t_end"},
    "which": {"long_name": "joint that flipped: 0 phi, 1 psi, -1 none"},
    "phi0": {"units": "rad", "long_name": "initial angle of hinge 1"},
    "psi0": {"units": "rad", "long_name": "initial angle of hinge 2"},
}


def open_flip_map(path) -> FlipMap:
    """A :class:`FlipMap` read back from a complete store ``*.zarr`` (made with ``flip_map(...,
    store=path)``; needs the ``cluster`` extra) or a file ``*.nc`` (:meth:`FlipMap.to_netcdf`;
    needs ``netCDF4``).  A store whose run has not finished, or that is damaged, is refused
    (resume it first)."""
    from pathlib import Path

    path = Path(path)
    suffix = path.suffix.lower()
    if suffix == ".zarr":
        from ..numeric.grid import read_store

        arrays, attrs = read_store(STORE_KIND, path, what="a flip map")
    elif suffix == ".nc":
        from ..io import read_netcdf

        arrays, attrs = read_netcdf(path, kind=FlipMap.result_kind)
    else:
        raise ParameterError(f"expected a store ending in .zarr or a file ending in .nc, got {str(path)!r}")
    try:
        settings = json.loads(attrs["flip_map_settings"])
        stats = json.loads(attrs["flip_map_stats"])
        params = Parameters.from_mapping(json.loads(attrs["params"]))
        arrays = {name: arrays[name] for name in ("flip_time", "which", "phi0", "psi0")}
    except (KeyError, TypeError, ValueError) as exc:
        raise ParameterError(f"{path} is not a flip map made by skewpend (missing or bad attribute: {exc})") from None
    for key in ("phi_range", "psi_range"):
        settings[key] = tuple(settings[key])
    phi, psi = arrays["phi0"].astype(np.float64), arrays["psi0"].astype(np.float64)
    n = phi.size
    from ..results import grid_status

    status, message = grid_status(int(stats.get("failed", 0)), n * n, "cells")
    return FlipMap(
        phi0=np.broadcast_to(phi[:, None], (n, n)), psi0=np.broadcast_to(psi[None, :], (n, n)),
        flip_time=arrays["flip_time"].astype(np.float64), which=arrays["which"].astype(np.int8),
        params=params, settings=settings, stats=stats, status=status, message=message,
    )


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
    from ..numeric.ensemble import FlipIntegrator
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


# -- input checks ---------------------------------------------------------------------------------
# -- the grid and the energy bound ----------------------------------------------------------------------
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


# -- the map ---------------------------------------------------------------------------------------
def flip_map(
    params: Parameters,
    n: int,
    *,
    t_end: float = 10.0,
    phi_range: Sequence[float] = (-math.pi, math.pi),
    psi_range: Sequence[float] = (-math.pi, math.pi),
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
) -> "FlipMap | ChainFlipMap":
    """The flip-time map of ``params`` on the ``n x n`` grid of cell centres over
    ``phi_range x psi_range`` [rad] (each within ``[-pi, pi]``), released at rest.

    A chain of links is mapped over a ``plane`` of two of its angles (``("q1", "q3")``), over ``ranges``
    (``((lo, hi), (lo, hi))``), the others at ``held``: :func:`skewpend.analysis.chainflip.chain_flip_map`,
    a :class:`~skewpend.analysis.chainflip.ChainFlipMap` (no shortcuts: every cell integrated).

    ``flip_time[i, j]``: the first time [s] either joint angle leaves ``(-pi, pi)`` starting
    from ``(phi0[i], psi0[j], 0, 0)``, NaN if not by ``t_end``; ``which``: 0 (phi), 1 (psi), -1.
    DOP853 with ``rtol``/``atol`` (default 1e-10 each); the crossing is located on the dense
    output.  ``workers`` threads (default: the cores this process may use) integrate units of
    whole rows (with their mirror rows); the result does not depend on their number.
    ``progress(done_cells, total_cells)`` is called in the calling thread as units finish.
    Ctrl-C stops within a few milliseconds (:class:`KeyboardInterrupt`).
    ``shortcuts=False`` integrates every cell (no energy bound, no mirror symmetry).
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
    from ..numeric.grid import check_run_options, run_grid
    from ..numeric.kernels import kernel_module, parameter_vector
    from ..symbolic.chain import Chain

    if isinstance(params, Chain):
        from .chainflip import chain_flip_map

        full = (-math.pi, math.pi)
        given = [k for k, v in (("phi_range", phi_range), ("psi_range", psi_range)) if tuple(v) != full]
        if given or shortcuts is not True:
            raise ParameterError(f"{(given or ['shortcuts'])[0]} is the double pendulum's; a chain's flip map takes "
                                 "plane=, ranges= and held= (and has no shortcuts: every cell is integrated)")
        return chain_flip_map(params, n, plane=plane, ranges=ranges, held=held, t_end=t_end, rtol=rtol, atol=atol,
                              workers=workers, progress=progress, chunk_size=chunk_size, max_steps=max_steps,
                              store=store, resume=resume, scheduler=scheduler)
    if plane is not None or ranges is not None or held is not None:
        raise ParameterError("plane, ranges and held are a chain's; the double pendulum's flip map is over "
                             "phi_range x psi_range")
    params = numeric_params(params, "a flip map")
    n = check_n(n)
    t_end = positive("t_end", t_end)
    phi_lo, phi_hi = check_range("phi_range", phi_range)
    psi_lo, psi_hi = check_range("psi_range", psi_range)
    rtol, atol = tolerances(rtol, atol)
    workers = check_run_options(workers=workers, scheduler=scheduler, store=store, resume=resume, progress=progress,
                                chunk_size=chunk_size)
    max_steps = check_max_steps(max_steps)
    _check_memory(n)
    kernel = kernel_module(params, flip=True)
    p = parameter_vector(params)
    no_torque = params.tau1 == 0.0 and params.tau2 == 0.0
    symmetric = bool(shortcuts and kernel.flip_odd and no_torque and phi_lo == -phi_hi and psi_lo == -psi_hi)
    barrier = threshold = None
    if shortcuts:
        barrier, scale = energy_barrier(kernel, p)
        threshold = barrier - _BARRIER_MARGIN * max(scale, 1e-300)
    job = FlipJob(params=params, n=n, t_end=t_end, phi_range=(phi_lo, phi_hi), psi_range=(psi_lo, psi_hi), rtol=rtol,
                  atol=atol, max_steps=int(max_steps), symmetric=symmetric, threshold=threshold, version=__version__,
                  kernel_name=kernel.path.name, shortcuts=bool(shortcuts), barrier=barrier)
    state = (kernel, p, job.integrator(kernel, p))
    _check_feasible(job, state)
    result = run_grid(job, workers=workers, scheduler=scheduler, store=store, resume=bool(resume), progress=progress,
                      chunk_size=chunk_size, state=state)
    if result.stats["failed"]:
        warnings.warn(f"flip_map: {result.message}", RuntimeWarning, stacklevel=2)
    return result


def _check_feasible(job: "FlipJob", state) -> None:
    """Refuse a map whose cells could not finish within ``max_steps`` (a trial run of the flip
    kernel from energetic starts of the window: the ones that flip last the longest)."""
    from ..numeric.ensemble import FlipIntegrator
    from ..numeric.grid import PROBE_STEPS, check_feasible, probe_durations, refused_already, steps_per_second

    kernel, p, _ = state
    corner = (max(map(abs, job.phi_range)), max(map(abs, job.psi_range)))
    cells = np.array([(0.9 * corner[0], 0.9 * corner[1]), (0.9 * corner[0], -0.9 * corner[1]), (0.5 * corner[0], 0.0)])
    rate, ok = 0.0, False
    for t in probe_durations(job.t_end, job.params):  # a trial that fails (too stiff) is tried over a shorter time
        out = FlipIntegrator(kernel, p, t_end=t, rtol=job.rtol, atol=job.atol, max_steps=PROBE_STEPS).run(cells)
        lived = np.where(np.isfinite(out.time), out.time, t)  # a failed trial: a lower bound of the rate
        rate = steps_per_second(out.steps + out.rejected, lived)
        ok = not np.any(out.which == -2)
        if ok or refused_already(rate, job.t_end, job.max_steps):
            break
    check_feasible(rate, t_end=job.t_end, rtol=job.rtol, atol=job.atol, max_steps=job.max_steps, what="this flip map",
                   lower_bound=not ok)


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
#: The store's kind (its attribute ``kind``): stores of anything else are refused.
STORE_KIND = "skewpend flip map"
#: Columns of the per-chunk statistics kept in a store.
CHUNK_STATS = ("integrated", "skipped_energy", "mirrored", "failed", "steps", "rejected", "integrated_time")


def flip_settings(params: Parameters, n: int, *, t_end: float, phi_range, psi_range, rtol: float, atol: float,
                  max_steps: int, shortcuts: bool) -> Dict[str, Any]:
    """The resolved settings that determine a map's every bit (and this skewpend's version),
    as plain JSON data: what a store's fingerprint is the SHA-256 of."""
    from .. import __version__

    def plain(v):
        if isinstance(v, (list, tuple)):
            return [plain(x) for x in v]
        if v is None or isinstance(v, str):
            return v
        return float(v)

    return {
        "kind": "flip_map", "params": {k: plain(v) for k, v in params.to_dict().items()}, "n": int(n),
        "t_end": float(t_end), "phi_range": [float(x) for x in phi_range], "psi_range": [float(x) for x in psi_range],
        "rtol": float(rtol), "atol": float(atol), "max_steps": int(max_steps), "shortcuts": bool(shortcuts),
        "method": "dop853", "skewpend_version": __version__,
    }


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
class FlipJob(GridJob):
    """A flip map as a job of the grid driver: small and picklable (sent with each cluster task)."""

    params: Parameters
    n: int
    t_end: float
    phi_range: Tuple[float, float]
    psi_range: Tuple[float, float]
    rtol: float
    atol: float
    max_steps: int
    symmetric: bool
    threshold: Optional[float]  # energy bound: cells with V(q0) below it never flip (None: not used)
    version: str
    kernel_name: str  # the compiled kernel's file name: the same generated code everywhere
    shortcuts: bool = True
    barrier: Optional[float] = None

    kind: ClassVar[str] = STORE_KIND
    what: ClassVar[str] = "a flip map"
    stat_names: ClassVar[Tuple[str, ...]] = CHUNK_STATS
    title: ClassVar[str] = "flip-time map of the skewed double pendulum (skewpend)"

    def shape(self) -> Tuple[int, int]:
        return self.n, self.n

    def arrays(self):
        from ..numeric.grid import ArraySpec

        return {"flip_time": ArraySpec("float64", np.nan, _VARIABLES["flip_time"]),
                "which": ArraySpec("int8", -1, _VARIABLES["which"])}

    def coords(self):
        return {"phi0": (cell_centres(*self.phi_range, self.n), _VARIABLES["phi0"]),
                "psi0": (cell_centres(*self.psi_range, self.n), _VARIABLES["psi0"])}

    def settings(self) -> Dict[str, Any]:
        return flip_settings(self.params, self.n, t_end=self.t_end, phi_range=self.phi_range,
                             psi_range=self.psi_range, rtol=self.rtol, atol=self.atol, max_steps=self.max_steps,
                             shortcuts=self.shortcuts)

    def store_attrs(self) -> Dict[str, Any]:
        s = self.settings()
        return {"params": json.dumps(s["params"]), "shortcuts": int(self.shortcuts),
                **{k: s[k] for k in ("n", "t_end", "phi_range", "psi_range", "rtol", "atol", "max_steps", "method")}}

    def row_groups(self):
        return row_groups(self.n, self.symmetric)

    def chunk_rows(self, chunk_size):
        return chunk_rows(self.n, chunk_size=chunk_size)

    def integrator(self, kernel, p):
        from ..numeric.ensemble import FlipIntegrator

        return FlipIntegrator(kernel, p, t_end=self.t_end, rtol=self.rtol, atol=self.atol, max_steps=self.max_steps)

    def setup(self):
        """The kernel (compiled or loaded here), checked to be the very code of this run."""
        from ..errors import SkewpendError
        from ..numeric.kernels import kernel_module, parameter_vector

        kernel = kernel_module(self.params, flip=True)
        if kernel.path.name != self.kernel_name:
            raise SkewpendError(f"a worker generates another kernel ({kernel.path.name}, this run {self.kernel_name}): "
                                "install the same skewpend on every worker")
        p = parameter_vector(self.params)
        return kernel, p, self.integrator(kernel, p)

    def compute(self, state, rows, cancel=None):
        """The cells of whole ``rows`` (closed under the mirror when the map is symmetric): the
        same representative of each mirror pair is integrated, the same energy test decides,
        wherever and in whatever unit the rows are computed -- so the same bits."""
        kernel, p, integrator = state
        n = self.n
        total = n * n
        phi = cell_centres(*self.phi_range, n)
        psi = cell_centres(*self.psi_range, n)
        rows = np.asarray(rows, dtype=np.int64)
        ids = (rows[:, None] * n + np.arange(n, dtype=np.int64)[None, :]).ravel()
        reps = ids[ids <= total - 1 - ids] if self.symmetric else ids

        def starts(f):
            return np.column_stack([phi[f // n], psi[f % n]])

        V = kernel.flip_potential_many(starts(reps), p)
        if self.threshold is not None:
            forbidden = V < self.threshold
            if self.symmetric:
                forbidden &= kernel.flip_potential_many(starts(total - 1 - reps), p) < self.threshold
            todo, V = reps[~forbidden], V[~forbidden]
        else:
            todo = reps
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
        stats[:, 3] = np.bincount(at, weights=bad, minlength=m)
        stats[:, 4] = np.bincount(at, weights=out.steps, minlength=m)
        stats[:, 5] = np.bincount(at, weights=out.rejected, minlength=m)
        stats[:, 6] = np.bincount(at, weights=lived, minlength=m)
        return {"flip_time": time_, "which": which}, stats

    def result(self, run) -> FlipMap:
        from ..results import grid_status

        n = self.n
        totals = run.totals(CHUNK_STATS)
        flip_time, which = run.data["flip_time"], run.data["which"]
        settings = {
            "n": n, "t_end": self.t_end, "phi_range": tuple(self.phi_range), "psi_range": tuple(self.psi_range),
            "rtol": self.rtol, "atol": self.atol, "max_steps": int(self.max_steps), "method": "dop853",
            "shortcuts": self.shortcuts, "energy_bound": self.shortcuts, "symmetry": self.symmetric,
        }
        kernel = run.state[0] if run.state is not None else None
        stats = {
            "cells": n * n, "integrated": int(totals["integrated"]), "skipped_energy": int(totals["skipped_energy"]),
            "mirrored": int(totals["mirrored"]), "flipped": int(np.count_nonzero(np.isfinite(flip_time))),
            "failed": int(totals["failed"]), "steps": int(totals["steps"]), "rejected": int(totals["rejected"]),
            "integrated_time": float(totals["integrated_time"]), "energy_barrier": self.barrier,
            "energy_threshold": self.threshold,
            "lanes": None if kernel is None else kernel.flip_lanes,
            "kernel": None if kernel is None else kernel.origin,
            "kernel_build_time": None if kernel is None else kernel.build_time,
            **run.info,
        }
        status, message = grid_status(stats["failed"], n * n, "cells")
        phi, psi = (values for values, _ in self.coords().values())
        return FlipMap(phi0=np.broadcast_to(phi[:, None], (n, n)), psi0=np.broadcast_to(psi[None, :], (n, n)),
                       flip_time=flip_time, which=which, params=self.params, settings=settings, stats=stats,
                       status=status, message=message)

    def result_attrs(self, result: FlipMap) -> Dict[str, Any]:
        return {"flip_map_settings": canonical_json(result.settings), "flip_map_stats": canonical_json(result.stats)}
