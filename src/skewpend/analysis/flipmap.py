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
    ``V = Pi - tau . q`` never increases (``d/dt (T + V) = -c q'^2``), and released at rest it
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

import math
import os
import time
import warnings
from dataclasses import dataclass, field
from typing import Any, Callable, Dict, Optional, Sequence, Tuple

import numpy as np

from ..parsing import positive_number
from ..errors import NotNumericError, ParameterError
from ..symbolic.model import Parameters

__all__ = ["flip_map", "FlipMap", "open_flip_map", "cell_centres", "energy_barrier", "flip_settings", "fingerprint", "MAX_N"]

#: Largest grid: n x n cells (16384^2 = 2.7e8 cells, about 4 GB of results).
MAX_N = 16384
#: Default tolerances (relative and absolute) of the DOP853 error control.
DEFAULT_TOL = 1e-10
#: Default cap on the attempted steps of one trajectory.
MAX_STEPS = 100_000_000
#: Points per side of the square sampled for the energy barrier.
_BARRIER_SAMPLES = 4097
#: Safety margin of the energy bound, relative to the potential's scale.
_BARRIER_MARGIN = 1e-9


@dataclass(frozen=True)
class FlipMap:
    """The result of :func:`flip_map`.

    * ``phi0``, ``psi0`` -- the starting angles (cell centres) [rad], shape ``(n, n)``: ``phi0``
      varies along axis 0, ``psi0`` along axis 1 (read-only broadcast views of the two axes);
    * ``flip_time`` -- first time either angle leaves ``(-pi, pi)`` [s], NaN if not by ``t_end``;
    * ``which`` -- the joint that flipped: 0 (phi), 1 (psi), -1 none;
    * ``params``, ``settings`` (n, t_end, window, tolerances, which shortcuts were used),
      ``stats`` (cells integrated / skipped by the energy bound / mirrored, steps, wall time, ...).
    """

    phi0: np.ndarray
    psi0: np.ndarray
    flip_time: np.ndarray
    which: np.ndarray
    params: Parameters
    settings: Dict[str, Any]
    stats: Dict[str, Any] = field(default_factory=dict)

    @property
    def n(self) -> int:
        return int(self.flip_time.shape[0])

    @property
    def flipped(self) -> np.ndarray:
        """Boolean mask of the cells that flipped by ``t_end``."""
        return np.isfinite(self.flip_time)

    def _attrs(self) -> Dict[str, Any]:
        """Global attributes of a file: numbers, strings and lists only (NetCDF and Zarr take
        them as they are); ``flip_map_settings`` / ``flip_map_stats`` (JSON) let
        :func:`open_flip_map` rebuild the map."""
        import json

        attrs: Dict[str, Any] = {"title": "flip-time map of the skewed double pendulum (skewpend)",
                                 "params": json.dumps(self.params.to_dict())}
        for group in (self.settings, self.stats):
            for key, value in group.items():
                if value is None:
                    continue
                if isinstance(value, bool):
                    value = int(value)
                elif isinstance(value, tuple):
                    value = list(value)
                attrs[key] = value
        attrs["flip_map_settings"] = json.dumps(self.settings)
        attrs["flip_map_stats"] = json.dumps(self.stats)
        return attrs

    def to_xarray(self):
        """An :class:`xarray.Dataset`: ``flip_time`` [s] and ``which`` over the coordinates ``phi0``
        and ``psi0`` [rad], with the parameters, settings and statistics as attributes (numbers,
        strings and lists only, so it writes to NetCDF and Zarr as it is)."""
        try:
            import xarray as xr
        except ImportError:
            raise ImportError(
                "FlipMap.to_xarray() needs xarray, which is not installed: pip install xarray"
            ) from None

        dims = ("phi0", "psi0")
        return xr.Dataset(
            {
                "flip_time": (dims, self.flip_time, dict(_VARIABLES["flip_time"])),
                "which": (dims, self.which, dict(_VARIABLES["which"])),
            },
            coords={
                "phi0": ("phi0", self.phi0[:, 0].copy(), dict(_VARIABLES["phi0"])),
                "psi0": ("psi0", self.psi0[0, :].copy(), dict(_VARIABLES["psi0"])),
            },
            attrs=self._attrs(),
        )

    def to_netcdf(self, path) -> "os.PathLike":
        """Write the map to a NetCDF 4 file ``*.nc`` (with ``netCDF4``, the ``netcdf`` extra; no
        xarray needed), the same variables and attributes as :meth:`to_xarray`.  The file
        appears only when complete (:func:`skewpend.io.atomic_path`).  Returns the path."""
        from pathlib import Path

        from ..io import atomic_path, require_netcdf

        path = Path(path)
        if path.suffix.lower() != ".nc":
            raise ParameterError(f"expected a file name ending in .nc, got {str(path)!r}")
        netCDF4 = require_netcdf()
        n = self.n
        with atomic_path(path) as tmp:
            ds = netCDF4.Dataset(tmp, "w", format="NETCDF4")
            try:
                for dim in ("phi0", "psi0"):
                    ds.createDimension(dim, n)
                for name, values in (("phi0", self.phi0[:, 0]), ("psi0", self.psi0[0, :])):
                    v = ds.createVariable(name, "f8", (name,))
                    v.setncatts(_VARIABLES[name])
                    v[:] = values
                chunks = [max(1, min(n, 65536 // n)), n]
                v = ds.createVariable("flip_time", "f8", ("phi0", "psi0"), zlib=True, complevel=4, chunksizes=chunks,
                                      fill_value=False)
                v.setncatts(_VARIABLES["flip_time"])
                v[:] = self.flip_time
                v = ds.createVariable("which", "i1", ("phi0", "psi0"), zlib=True, complevel=4, chunksizes=chunks,
                                      fill_value=False)
                v.setncatts(_VARIABLES["which"])
                v[:] = self.which
                ds.setncatts({k: (np.asarray(v, dtype=float) if isinstance(v, list) else v) for k, v in self._attrs().items()})
            finally:
                ds.close()
        return path


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
    needs ``netCDF4``).  A store whose run has not finished is refused (resume it first)."""
    import json
    from pathlib import Path

    from ..errors import SkewpendError

    path = Path(path)
    suffix = path.suffix.lower()
    if suffix == ".zarr":
        from ..numeric.store import RowStore

        with RowStore.open(path, kind=STORE_KIND) as st:
            attrs = st.attrs
            done = st.done()
            if not attrs.get("complete") or not done.all():
                raise ParameterError(f"{path} is not complete ({int(done.sum())} of {done.size} chunks done); "
                                     "resume it with the same settings first")
            arrays = {name: st.read(name) for name in ("flip_time", "which", "phi0", "psi0")}
    elif suffix == ".nc":
        try:
            import netCDF4
        except ImportError:
            raise SkewpendError('reading .nc needs netCDF4, which is not installed: pip install "skewpend[netcdf]"') from None
        if not path.is_file():
            raise ParameterError(f"{path} does not exist")
        try:
            with netCDF4.Dataset(path) as ds:
                ds.set_auto_mask(False)
                attrs = {k: ds.getncattr(k) for k in ds.ncattrs()}
                arrays = {name: np.asarray(ds.variables[name][:]) for name in ("flip_time", "which", "phi0", "psi0")}
        except (OSError, KeyError) as exc:
            raise ParameterError(f"{path} is not a flip map file ({exc})") from None
    else:
        raise ParameterError(f"expected a store ending in .zarr or a file ending in .nc, got {str(path)!r}")
    try:
        settings = json.loads(attrs["flip_map_settings"])
        stats = json.loads(attrs["flip_map_stats"])
        params = Parameters.from_mapping(json.loads(attrs["params"]))
    except (KeyError, TypeError, ValueError) as exc:
        raise ParameterError(f"{path} is not a flip map made by skewpend (missing or bad attribute: {exc})") from None
    for key in ("phi_range", "psi_range"):
        settings[key] = tuple(settings[key])
    phi, psi = arrays["phi0"].astype(np.float64), arrays["psi0"].astype(np.float64)
    n = phi.size
    return FlipMap(
        phi0=np.broadcast_to(phi[:, None], (n, n)), psi0=np.broadcast_to(psi[None, :], (n, n)),
        flip_time=arrays["flip_time"].astype(np.float64), which=arrays["which"].astype(np.int8),
        params=params, settings=settings, stats=stats,
    )


# -- input checks ---------------------------------------------------------------------------------
def _check_params(params) -> Parameters:
    if not isinstance(params, Parameters):
        raise ParameterError(f"params must be a skewpend.Parameters, got {type(params).__name__}")
    try:
        params.require_numeric("a flip map")
    except NotNumericError as exc:
        raise ParameterError(str(exc)) from None
    return params


def _check_n(n) -> int:
    if isinstance(n, bool) or not isinstance(n, (int, np.integer)):
        raise ParameterError(f"n must be a whole number of cells per side, got {n!r}")
    if not 1 <= n <= MAX_N:
        raise ParameterError(f"n must be from 1 to {MAX_N} (cells per side), got {n}")
    return int(n)


def _check_positive(name: str, value, *, cap: Optional[float] = None) -> float:
    x = positive_number(name, value)
    if cap is not None and x > cap:
        raise ParameterError(f"{name} must be at most {cap:g}, got {x:g}")
    return x


def _check_range(name: str, value) -> Tuple[float, float]:
    try:
        lo, hi = (float(v) for v in value)
    except (TypeError, ValueError):
        raise ParameterError(f"{name} must be a pair (start, stop) of angles in radians, got {value!r}") from None
    if any(isinstance(v, bool) for v in value):
        raise ParameterError(f"{name} must be a pair (start, stop) of angles in radians, got {value!r}")
    if not (math.isfinite(lo) and math.isfinite(hi)):
        raise ParameterError(f"{name} must be finite, got ({lo:g}, {hi:g})")
    if not lo < hi:
        raise ParameterError(f"{name} must have start < stop, got ({lo:g}, {hi:g})" +
                             (" (zero width)" if lo == hi else " (inverted)"))
    if lo < -math.pi or hi > math.pi:
        raise ParameterError(
            f"{name} must lie within [-pi, pi] (a start outside has already flipped), got ({lo:g}, {hi:g})"
        )
    return lo, hi


def _check_workers(workers) -> int:
    from ..numeric.ensemble import default_workers

    if workers is None:
        return default_workers()
    if isinstance(workers, bool) or not isinstance(workers, (int, np.integer)) or workers < 1:
        raise ParameterError(f"workers must be a whole number >= 1, got {workers!r}")
    return int(workers)


# -- the grid and the energy bound ----------------------------------------------------------------------
def cell_centres(lo: float, hi: float, n: int) -> np.ndarray:
    """The ``n`` cell centres ``lo + (k + 1/2) (hi - lo) / n``, computed as
    ``(lo (2n - 2k - 1) + hi (2k + 1)) / 2n`` so that in a window symmetric about 0
    (``lo = -hi``) mirror cells are exact negatives: ``c[n - 1 - k] == -c[k]``."""
    k = np.arange(n, dtype=np.float64)
    return (lo * (2 * n - 2 * k - 1) + hi * (2 * k + 1)) / (2 * n)


def energy_barrier(kernel, p, *, samples: int = _BARRIER_SAMPLES) -> Tuple[float, float]:
    """``(V_min, scale)``: the minimum of ``V = Pi - tau . q`` over the boundary of the square
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
) -> FlipMap:
    """The flip-time map of ``params`` on the ``n x n`` grid of cell centres over
    ``phi_range x psi_range`` [rad] (each within ``[-pi, pi]``), released at rest.

    ``flip_time[i, j]``: the first time [s] either joint angle leaves ``(-pi, pi)`` starting
    from ``(phi0[i], psi0[j], 0, 0)``, NaN if not by ``t_end``; ``which``: 0 (phi), 1 (psi), -1.
    DOP853 with ``rtol``/``atol`` (default 1e-10 each); the crossing is located on the dense
    output.  ``workers`` threads (default: the cores this process may use) integrate chunks
    of ``chunk_size`` cells (default: about 8 chunks per worker); the result does not depend
    on either.  ``progress(done_cells, total_cells)`` is called in the calling thread as chunks
    finish.  Ctrl-C stops within a few milliseconds (:class:`KeyboardInterrupt`).
    ``shortcuts=False`` integrates every cell (no energy bound, no mirror symmetry).
    ``max_steps`` caps the attempted steps of one trajectory (a cell that hits it, or fails
    otherwise, is counted in ``stats["failed"]``, with a warning, and left NaN).

    ``store``: a directory ``*.zarr`` the map is written to chunk by chunk (blocks of whole
    rows; ``chunk_size``, with a store or a scheduler, is the store's chunk in cells, rounded
    down to whole rows dividing ``n``), with the settings and their SHA-256 fingerprint in
    its attributes; an existing path is refused
    unless ``resume=True``, which computes only the chunks not yet done and refuses a store
    made with other settings (a missing store is started afresh).  The store's layout, not
    ``chunk_size``, rules a resumed run.  ``scheduler``: a ``tcp://HOST:PORT`` address or a
    :class:`distributed.Client`: the chunks run as tasks on that Dask cluster (whose workers
    need this skewpend and a C compiler), and ``workers`` must be left out.  Either way the
    result is bitwise the same as without them.  Both need the ``cluster`` extra
    (``pip install "skewpend[cluster]"``); without them neither Zarr nor Dask is imported.
    """
    from ..numeric.ensemble import FlipIntegrator, run_chunks
    from ..numeric.kernels import kernel_module, parameter_vector

    params = _check_params(params)
    n = _check_n(n)
    t_end = _check_positive("t_end", t_end)
    phi_lo, phi_hi = _check_range("phi_range", phi_range)
    psi_lo, psi_hi = _check_range("psi_range", psi_range)
    rtol = DEFAULT_TOL if rtol is None else _check_positive("rtol", rtol, cap=1.0)
    atol = DEFAULT_TOL if atol is None else _check_positive("atol", atol, cap=1.0)
    if rtol < 1e-15 or atol < 1e-300:
        raise ParameterError(f"rtol must be >= 1e-15 (machine precision) and atol >= 1e-300, got rtol={rtol:g}, atol={atol:g}")
    explicit_workers = workers
    workers = _check_workers(workers)
    if progress is not None and not callable(progress):
        raise ParameterError("progress must be a callable progress(done_cells, total_cells)")
    if chunk_size is not None and (isinstance(chunk_size, bool) or not isinstance(chunk_size, (int, np.integer)) or chunk_size < 1):
        raise ParameterError(f"chunk_size must be a whole number >= 1, got {chunk_size!r}")
    if isinstance(max_steps, bool) or not isinstance(max_steps, (int, np.integer)) or not 1 <= max_steps <= 10**15:
        raise ParameterError(f"max_steps must be a whole number from 1 to 1e15, got {max_steps!r}")

    if resume not in (True, False):
        raise ParameterError(f"resume must be True or False, got {resume!r}")
    if store is not None or scheduler is not None or resume:
        if resume and store is None:
            raise ParameterError("resume needs a store: the path of the .zarr store to continue")
        if scheduler is not None and explicit_workers is not None:
            raise ParameterError("give workers or scheduler, not both (a cluster's workers run the chunks)")
        return _chunked_flip_map(
            params, n, t_end=t_end, phi_range=(phi_lo, phi_hi), psi_range=(psi_lo, psi_hi), rtol=rtol, atol=atol,
            workers=workers, progress=progress, shortcuts=bool(shortcuts), chunk_size=chunk_size,
            max_steps=int(max_steps), store=store, resume=bool(resume), scheduler=scheduler,
        )

    _check_memory(n)
    start = time.perf_counter()
    kernel = kernel_module(params, flip=True)
    p = parameter_vector(params)
    phi = cell_centres(phi_lo, phi_hi, n)
    psi = cell_centres(psi_lo, psi_hi, n)
    total = n * n

    def starts(ids):  # the cells (phi0, psi0) of flat indices ids = i n + j
        return np.column_stack([phi[ids // n], psi[ids % n]])

    flip_time = np.full(total, np.nan)
    which = np.full(total, -1, dtype=np.int8)
    no_torque = params.tau1 == 0.0 and params.tau2 == 0.0
    symmetric = bool(shortcuts and kernel.flip_odd and no_torque and phi_lo == -phi_hi and psi_lo == -psi_hi)
    # cell (i, j) and its mirror (n-1-i, n-1-j) = total-1-k: exact negatives in a symmetric window
    todo = np.arange((total + 1) // 2 if symmetric else total, dtype=np.int64)

    barrier = scale = None
    V0 = np.empty(todo.size)
    for a in range(0, todo.size, 1 << 20):
        V0[a:a + (1 << 20)] = kernel.flip_potential_many(starts(todo[a:a + (1 << 20)]), p)
    skipped = 0
    if shortcuts:
        barrier, scale = energy_barrier(kernel, p)
        forbidden = V0 < barrier - _BARRIER_MARGIN * max(scale, 1e-300)
        if symmetric:  # the same decision for a cell and its mirror (V is even, up to rounding)
            mirror_V = np.empty(todo.size)
            for a in range(0, todo.size, 1 << 20):
                mirror_V[a:a + (1 << 20)] = kernel.flip_potential_many(starts(total - 1 - todo[a:a + (1 << 20)]), p)
            forbidden &= mirror_V < barrier - _BARRIER_MARGIN * max(scale, 1e-300)
            del mirror_V
            skipped = 2 * int(np.count_nonzero(forbidden)) - int(np.count_nonzero(forbidden & (todo == total - 1 - todo)))
        else:
            skipped = int(np.count_nonzero(forbidden))
        todo, V0 = todo[~forbidden], V0[~forbidden]
        del forbidden
    # expensive cells first (low energy: likely no flip until t_end), for balanced chunks
    todo = todo[np.argsort(V0, kind="stable")]
    del V0

    done_cells = skipped
    if progress is not None:
        progress(done_cells, total)

    m = todo.size
    integrator = FlipIntegrator(kernel, p, t_end=t_end, rtol=rtol, atol=atol, max_steps=int(max_steps))
    lanes = integrator.lanes
    if chunk_size is None:
        chunk_size = max(8 * lanes, min(4096, -(-m // (8 * workers))))
        chunk_size = -(-chunk_size // lanes) * lanes
    chunk_size = int(chunk_size)
    bounds = [(a, min(a + chunk_size, m)) for a in range(0, m, chunk_size)]

    def work(i, cancel):
        a, b = bounds[i]
        return integrator.run(starts(todo[a:b]), cancel)

    counts = {"n": done_cells}

    def on_done(i, chunk):
        a, b = bounds[i]
        ids = todo[a:b]
        extra = int(np.count_nonzero(total - 1 - ids != ids)) if symmetric else 0
        counts["n"] += (b - a) + extra
        if progress is not None:
            progress(counts["n"], total)

    chunks = run_chunks(len(bounds), work, workers=workers, on_done=on_done)
    steps = rejected = failed = 0
    integrated_time = 0.0
    for (a, b), chunk in zip(bounds, chunks):
        ids = todo[a:b]
        flip_time[ids] = chunk.time
        w = chunk.which.astype(np.int8)
        bad = w == -2
        failed += int(np.count_nonzero(bad))
        w[bad] = -1
        which[ids] = w
        steps += int(chunk.steps.sum())
        rejected += int(chunk.rejected.sum())
        integrated_time += float(np.sum(np.where(np.isfinite(chunk.time), chunk.time, t_end)[~bad]))
    mirrored = 0
    if symmetric:
        mirror = total - 1 - todo
        flip_time[mirror] = flip_time[todo]
        which[mirror] = which[todo]
        mirrored = int(np.count_nonzero(mirror != todo))
    if progress is not None and counts["n"] != total:
        progress(total, total)
    if failed:
        warnings.warn(f"flip_map: the integration of {failed} cell(s) failed (non-finite state, step size underflow "
                      f"or more than max_steps = {max_steps} steps); they are left NaN", RuntimeWarning, stacklevel=2)
    wall = time.perf_counter() - start
    settings = {
        "n": n, "t_end": t_end, "phi_range": (phi_lo, phi_hi), "psi_range": (psi_lo, psi_hi),
        "rtol": rtol, "atol": atol, "max_steps": int(max_steps), "method": "dop853",
        "shortcuts": bool(shortcuts), "energy_bound": bool(shortcuts), "symmetry": symmetric,
    }
    stats = {
        "cells": total,
        "integrated": int(m),
        "skipped_energy": skipped,
        "mirrored": mirrored,
        "flipped": int(np.count_nonzero(np.isfinite(flip_time))),
        "failed": failed,
        "steps": steps,
        "rejected": rejected,
        "integrated_time": integrated_time,
        "energy_barrier": barrier,
        "wall_time": wall,
        "workers": workers,
        "chunks": len(bounds),
        "chunk_size": chunk_size,
        "lanes": lanes,
        "kernel": kernel.origin,
        "kernel_build_time": kernel.build_time,
    }
    return FlipMap(
        phi0=np.broadcast_to(phi[:, None], (n, n)), psi0=np.broadcast_to(psi[None, :], (n, n)),
        flip_time=flip_time.reshape(n, n), which=which.reshape(n, n), params=params, settings=settings, stats=stats,
    )


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


# -- chunked runs: a Zarr store (resumable) and/or a Dask cluster ---------------------------------------
#: The store's kind (its attribute ``kind``): stores of anything else are refused.
STORE_KIND = "skewpend flip map"
#: Columns of the per-chunk statistics kept in a store.
CHUNK_STATS = ("integrated", "skipped_energy", "mirrored", "failed", "steps", "rejected", "integrated_time")
#: Default store chunk: at most this many cells (whole rows) ...
_CHUNK_CELLS = 65536
#: ... and at least this many chunks (so a killed run loses at most about 1/8 of the map).
_MIN_CHUNKS = 8
#: Work units (a few rows each, with their mirrors) per worker thread, for balance.
_UNITS_PER_WORKER = 16


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


def fingerprint(settings: Dict[str, Any]) -> str:
    """SHA-256 (hex) of the canonical JSON of :func:`flip_settings`."""
    import hashlib
    import json

    text = json.dumps(settings, sort_keys=True, separators=(",", ":"), allow_nan=False)
    return hashlib.sha256(text.encode()).hexdigest()


def _divisor_at_most(n: int, target: int) -> int:
    """The largest divisor of ``n`` that is at most ``target`` (at least 1)."""
    target = max(1, min(int(target), n))
    for r in range(target, 0, -1):
        if n % r == 0:
            return r
    return 1  # pragma: no cover


def chunk_rows(n: int, *, chunk_size: Optional[int] = None) -> int:
    """Rows per store chunk, a divisor of ``n`` (every chunk whole rows, one Zarr chunk of each
    array, and the mirror image of a chunk -- rows ``n - 1 - i`` -- a chunk too): ``chunk_size``
    cells rounded down to whole rows, or by default at most :data:`_CHUNK_CELLS` cells and at
    least :data:`_MIN_CHUNKS` chunks."""
    if chunk_size is not None:
        return _divisor_at_most(n, chunk_size // n)
    return _divisor_at_most(n, min(n // _MIN_CHUNKS, _CHUNK_CELLS // n))


def row_groups(n: int, symmetric: bool) -> list:
    """The smallest pieces of work: each row with its mirror row ``n - 1 - i`` when the map is
    mirror-symmetric (the mirror cells are copies, so one piece computes both), else each row
    alone.  Every row is in exactly one group."""
    if not symmetric:
        return [(i,) for i in range(n)]
    groups = [(i, n - 1 - i) for i in range(n // 2)]
    if n % 2:
        groups.append((n // 2,))
    return groups


def work_units(groups: Sequence[Sequence[int]], threads: int) -> list:
    """``groups`` in order, joined into about :data:`_UNITS_PER_WORKER` units per thread (lists of
    rows): small enough for balance, large enough for few calls and tasks."""
    from ..numeric.ensemble import batches

    units = batches(list(groups), max(1, _UNITS_PER_WORKER * max(1, threads)))
    return [sorted(r for g in unit for r in g) for unit in units]


@dataclass(frozen=True)
class _Job:
    """What computing rows of the map needs: small and picklable (sent with each cluster task)."""

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


def _compute_rows(job: _Job, kernel, p, integrator, rows: Sequence[int], cancel=None):
    """``(rows, flip_time, which, stats)`` for a unit of whole ``rows`` (closed under the mirror
    when the map is symmetric): results of shape ``(len(rows), n)`` and per-row statistics
    (columns :data:`CHUNK_STATS`).  Exactly the cells and the arithmetic of :func:`flip_map` in
    memory -- the same representative of each mirror pair is integrated, the same energy test
    decides -- so the same bits."""
    n = job.n
    total = n * n
    phi = cell_centres(*job.phi_range, n)
    psi = cell_centres(*job.psi_range, n)
    rows = np.asarray(sorted(rows), dtype=np.int64)
    ids = (rows[:, None] * n + np.arange(n, dtype=np.int64)[None, :]).ravel()
    reps = ids[ids <= total - 1 - ids] if job.symmetric else ids

    def starts(f):
        return np.column_stack([phi[f // n], psi[f % n]])

    if job.threshold is not None:
        forbidden = kernel.flip_potential_many(starts(reps), p) < job.threshold
        if job.symmetric:
            forbidden &= kernel.flip_potential_many(starts(total - 1 - reps), p) < job.threshold
        todo = reps[~forbidden]
    else:
        todo = reps
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
    copied = mirror != todo if job.symmetric else np.zeros(todo.size, dtype=bool)
    mirror = mirror[copied]
    time_[pos[mirror // n], mirror % n] = out.time[copied]
    which[pos[mirror // n], mirror % n] = w[copied]

    at, m = pos[todo // n], rows.size  # the row (in the unit) of each integrated cell
    lived = np.where(np.isfinite(out.time) & ~bad, out.time, np.where(bad, 0.0, job.t_end))
    stats = np.zeros((m, len(CHUNK_STATS)))
    stats[:, 0] = np.bincount(at, minlength=m)
    stats[:, 2] = np.bincount(pos[mirror // n], minlength=m)
    stats[:, 1] = n - stats[:, 0] - stats[:, 2]
    stats[:, 3] = np.bincount(at, weights=bad, minlength=m)
    stats[:, 4] = np.bincount(at, weights=out.steps, minlength=m)
    stats[:, 5] = np.bincount(at, weights=out.rejected, minlength=m)
    stats[:, 6] = np.bincount(at, weights=lived, minlength=m)
    return rows, time_, which, stats


def _integrator(job: _Job, kernel, p):
    from ..numeric.ensemble import FlipIntegrator

    return FlipIntegrator(kernel, p, t_end=job.t_end, rtol=job.rtol, atol=job.atol, max_steps=job.max_steps)


def _cluster_task(job: _Job, units: Sequence[Sequence[int]]) -> list:
    """A cluster task: the rows of ``units``, computed on a worker (which compiles or loads the
    kernel itself, from its own cache), one thread."""
    from .. import __version__
    from ..errors import SkewpendError
    from ..numeric.kernels import kernel_module, parameter_vector

    if __version__ != job.version:
        raise SkewpendError(f"a worker has skewpend {__version__}, this run {job.version}: install the same skewpend on every worker")
    kernel = kernel_module(job.params, flip=True)
    if kernel.path.name != job.kernel_name:
        raise SkewpendError(f"a worker generates another kernel ({kernel.path.name}, this run {job.kernel_name}): "
                            "install the same skewpend on every worker")
    p = parameter_vector(job.params)
    integrator = _integrator(job, kernel, p)
    return [_compute_rows(job, kernel, p, integrator, rows) for rows in units]


class _Assembler:
    """Rows arriving in any order, gathered into the map in memory and into whole chunks: a
    chunk goes to the store (if any) as soon as all its rows are in.  Chunks already done in
    the store are never written again (their bits are the same anyway)."""

    def __init__(self, n: int, rows_per_chunk: int, done: np.ndarray, store=None):
        self.n, self.R, self.done, self.store = n, rows_per_chunk, done, store
        self.flip_time = np.full((n, n), np.nan)
        self.which = np.full((n, n), -1, dtype=np.int8)
        self.row_stats = np.zeros((n, len(CHUNK_STATS)))
        self.missing = {int(k): rows_per_chunk for k in np.flatnonzero(~done)}  # rows still to come
        self.written = 0

    def add(self, rows, time_, which, stats) -> None:
        R = self.R
        keep = ~self.done[rows // R]
        rows, time_, which, stats = rows[keep], time_[keep], which[keep], stats[keep]
        self.flip_time[rows], self.which[rows], self.row_stats[rows] = time_, which, stats
        for k in np.unique(rows // R).tolist():
            self.missing[k] -= int(np.count_nonzero(rows // R == k))
            if self.missing[k] == 0:
                block = slice(k * R, (k + 1) * R)
                if self.store is not None:
                    self.store.write_chunk(k, {"flip_time": self.flip_time[block], "which": self.which[block]},
                                           self.row_stats[block].sum(axis=0))
                self.done[k] = True
                self.written += 1
                del self.missing[k]


def _store_template(store_path, settings, fp, rows, phi, psi):
    import json

    from ..numeric.store import RowStore

    n = settings["n"]
    attrs = {
        "title": "flip-time map of the skewed double pendulum (skewpend)",
        "fingerprint": fp, "settings": json.dumps(settings, sort_keys=True), "params": json.dumps(settings["params"]),
        "skewpend_version": settings["skewpend_version"],
        **{k: settings[k] for k in ("n", "t_end", "phi_range", "psi_range", "rtol", "atol", "max_steps", "method")},
        "shortcuts": int(settings["shortcuts"]),
    }
    return RowStore.create(
        store_path, kind=STORE_KIND, shape=(n, n), chunk_rows=rows, dims=("phi0", "psi0"),
        arrays={"flip_time": ("float64", np.nan, _VARIABLES["flip_time"]), "which": ("int8", -1, _VARIABLES["which"])},
        coords={"phi0": (phi, _VARIABLES["phi0"]), "psi0": (psi, _VARIABLES["psi0"])},
        stats=CHUNK_STATS, attrs=attrs,
    )


def _open_for_resume(store_path, settings, fp, *, writable):
    """The existing store at ``store_path``, checked against ``settings`` (refused if other)."""
    from ..numeric.store import RowStore

    st = RowStore.open_matching(store_path, kind=STORE_KIND, fingerprint=fp, settings=settings, writable=writable)
    try:
        n = settings["n"]
        if st.shape != (n, n) or n % st.chunk_rows or set(st.arrays) != {"flip_time", "which"}:
            raise ParameterError(f"{store_path} is damaged: its layout does not match its settings")
    except BaseException:
        st.close()
        raise
    return st


def _chunked_flip_map(params, n, *, t_end, phi_range, psi_range, rtol, atol, workers, progress, shortcuts,
                      chunk_size, max_steps, store, resume, scheduler) -> FlipMap:
    """:func:`flip_map` in chunks of whole rows, written to a store and/or run on a cluster."""
    from .. import __version__
    from ..numeric.ensemble import cluster_threads, connect_scheduler, require_distributed, run_chunks
    from ..numeric.kernels import kernel_module, parameter_vector

    settings_record = flip_settings(params, n, t_end=t_end, phi_range=phi_range, psi_range=psi_range, rtol=rtol,
                                    atol=atol, max_steps=max_steps, shortcuts=shortcuts)
    fp = fingerprint(settings_record)
    store_path = None
    if store is not None:
        from ..numeric.store import store_target

        store_path, exists = store_target(store, resume=resume, what="a flip map store")
        if exists:
            _open_for_resume(store_path, settings_record, fp, writable=False).close()  # refuse early, before any work
    if scheduler is not None:
        from ..numeric.ensemble import check_scheduler

        check_scheduler(scheduler)
        require_distributed()
    _check_memory(n)

    start = time.perf_counter()
    client, owned = (connect_scheduler(scheduler) if scheduler is not None else (None, False))
    store_ = None
    try:
        threads = cluster_threads(client) if client is not None else workers
        address = None if client is None else str(client.scheduler.address)
        kernel = kernel_module(params, flip=True)
        p = parameter_vector(params)
        phi = cell_centres(*phi_range, n)
        psi = cell_centres(*psi_range, n)
        no_torque = params.tau1 == 0.0 and params.tau2 == 0.0
        symmetric = bool(shortcuts and kernel.flip_odd and no_torque and phi_range[0] == -phi_range[1]
                         and psi_range[0] == -psi_range[1])
        barrier = scale = threshold = None
        if shortcuts:
            barrier, scale = energy_barrier(kernel, p)
            threshold = barrier - _BARRIER_MARGIN * max(scale, 1e-300)

        if store_path is not None and os.path.lexists(store_path):  # resume
            store_ = _open_for_resume(store_path, settings_record, fp, writable=True)
            rows = store_.chunk_rows
        else:
            rows = chunk_rows(n, chunk_size=chunk_size)
            if store_path is not None:
                store_ = _store_template(store_path, settings_record, fp, rows, phi, psi)
        n_chunks = n // rows
        job = _Job(params=params, n=n, t_end=t_end, phi_range=tuple(phi_range), psi_range=tuple(psi_range), rtol=rtol,
                   atol=atol, max_steps=max_steps, symmetric=symmetric, threshold=threshold, version=__version__,
                   kernel_name=kernel.path.name)
        done = store_.done() if store_ is not None else np.zeros(n_chunks, dtype=bool)
        resumed = int(np.count_nonzero(done))
        needed = ~np.repeat(done, rows)  # rows still to compute
        units = work_units([g for g in row_groups(n, symmetric) if needed[list(g)].any()], threads)
        assembler = _Assembler(n, rows, done.copy(), store_)
        counts = {"cells": resumed * rows * n, "tasks": 0}
        if progress is not None:
            progress(counts["cells"], n * n)

        def collect(result):
            counts["cells"] += n * int(np.count_nonzero(needed[result[0]]))
            assembler.add(*result)
            if progress is not None:
                progress(counts["cells"], n * n)

        if client is None:
            integrator = _integrator(job, kernel, p)
            run_chunks(len(units), lambda i, cancel: _compute_rows(job, kernel, p, integrator, units[i], cancel),
                       workers=workers, on_done=lambda i, result: collect(result), keep=False)
        else:
            from ..numeric.ensemble import batches, run_on_cluster

            tasks = batches(units)
            counts["tasks"] = len(tasks)

            def collect_task(i, results):
                for result in results:
                    collect(result)

            run_on_cluster(client, _cluster_task, [(job, b) for b in tasks], on_done=collect_task,
                           name="skewpend-flipmap")
        if assembler.missing:  # pragma: no cover - every unit delivered: every chunk complete
            raise RuntimeError("internal error: chunks left incomplete")
        counts["computed"] = assembler.written

        flip_time, which = assembler.flip_time, assembler.which
        cs = np.add.reduceat(assembler.row_stats, np.arange(0, n, rows), axis=0)  # per chunk
        if resumed:  # the chunks done before this run: from the store
            old = np.repeat(done, rows)
            flip_time[old] = store_.read("flip_time")[old]
            which[old] = store_.read("which")[old]
            cs[done] = store_.chunk_stats()[done]
        total_stats = {name: cs[:, i].sum() for i, name in enumerate(CHUNK_STATS)}
        settings = {
            "n": n, "t_end": t_end, "phi_range": tuple(phi_range), "psi_range": tuple(psi_range),
            "rtol": rtol, "atol": atol, "max_steps": int(max_steps), "method": "dop853",
            "shortcuts": bool(shortcuts), "energy_bound": bool(shortcuts), "symmetry": symmetric,
        }
        stats = {
            "cells": n * n,
            "integrated": int(total_stats["integrated"]),
            "skipped_energy": int(total_stats["skipped_energy"]),
            "mirrored": int(total_stats["mirrored"]),
            "flipped": int(np.count_nonzero(np.isfinite(flip_time))),
            "failed": int(total_stats["failed"]),
            "steps": int(total_stats["steps"]),
            "rejected": int(total_stats["rejected"]),
            "integrated_time": float(total_stats["integrated_time"]),
            "energy_barrier": barrier,
            "wall_time": time.perf_counter() - start,
            "workers": threads,
            "chunks": n_chunks,
            "chunk_size": rows * n,
            "lanes": kernel.flip_lanes,
            "kernel": kernel.origin,
            "kernel_build_time": kernel.build_time,
            "store": None if store_path is None else str(store_path),
            "fingerprint": fp,
            "chunks_resumed": resumed,
            "chunks_computed": counts["computed"],
            "scheduler": address,
            "tasks": counts["tasks"],
        }
        result = FlipMap(
            phi0=np.broadcast_to(phi[:, None], (n, n)), psi0=np.broadcast_to(psi[None, :], (n, n)),
            flip_time=flip_time, which=which, params=params, settings=settings, stats=stats,
        )
        if store_path is not None:  # the last write: the run's settings and statistics, and "complete"
            import json

            store_.set_attrs(complete=True, flip_map_settings=json.dumps(settings), flip_map_stats=json.dumps(stats))
    finally:
        if store_ is not None:
            store_.close()
        if owned:
            client.close(timeout=5)

    if stats["failed"]:
        warnings.warn(f"flip_map: the integration of {stats['failed']} cell(s) failed (non-finite state, step size "
                      f"underflow or more than max_steps = {max_steps} steps); they are left NaN", RuntimeWarning,
                      stacklevel=3)
    return result
