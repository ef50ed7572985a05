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
"""

from __future__ import annotations

import math
import os
import time
import warnings
from dataclasses import dataclass, field
from typing import Any, Callable, Dict, Optional, Sequence, Tuple

import numpy as np

from ..errors import NotNumericError, ParameterError
from ..symbolic.model import Parameters

__all__ = ["flip_map", "FlipMap", "cell_centres", "energy_barrier", "MAX_N"]

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
        import json

        dims = ("phi0", "psi0")
        attrs = {"title": "flip-time map of the skewed double pendulum (skewpend)",
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
        return xr.Dataset(
            {
                "flip_time": (dims, self.flip_time, {
                    "units": "s",
                    "long_name": "first time either joint angle leaves (-pi, pi), released at rest; NaN: not by t_end",
                }),
                "which": (dims, self.which, {
                    "long_name": "joint that flipped: 0 phi, 1 psi, -1 none",
                }),
            },
            coords={
                "phi0": ("phi0", self.phi0[:, 0].copy(), {"units": "rad", "long_name": "initial angle of hinge 1"}),
                "psi0": ("psi0", self.psi0[0, :].copy(), {"units": "rad", "long_name": "initial angle of hinge 2"}),
            },
            attrs=attrs,
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
    try:
        x = float(value)
    except (TypeError, ValueError):
        raise ParameterError(f"{name} must be a positive number, got {value!r}") from None
    if isinstance(value, bool) or not math.isfinite(x) or not x > 0:
        raise ParameterError(f"{name} must be a positive finite number, got {value!r}")
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
    rows; ``chunk_size`` cells is rounded down to whole rows dividing ``n``), with the
    settings and their SHA-256 fingerprint in its attributes; an existing path is refused
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
