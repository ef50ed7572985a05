"""Flip-time maps of a chain of links over a plane of two of its angles, the others held.

``flip_map(chain, n, plane=("q1", "q3"), held=...)`` releases the chain at rest from the centres of an
``n x n`` grid of cells over ``ranges`` of the two angles of ``plane`` (the other angles at ``held``, default
0: hanging) and records, for each, the *flip time*: the first time any joint angle leaves ``(-pi, pi)`` --
NaN when that does not happen by ``t_end`` -- and which joint it was.  The double pendulum's map
(:mod:`skewpend.analysis.flipmap`) is this one's plane ``(phi, psi)`` with its shortcuts (an energy bound and
the mirror symmetry, the starts in SIMD lanes); a chain's cells are each integrated by DOP853 in the chain's
compiled kernel (``sp_flip_many`` in ``integrators.c``, one start at a time, the flip located on the 7th-order
dense output), on the grid driver (:func:`skewpend.numeric.grid.run_grid`): every core, Dask, resumable Zarr
stores, bitwise the same whatever the chunking.
"""

from __future__ import annotations

import json
import math
import warnings
from dataclasses import dataclass
from typing import Any, Callable, ClassVar, Dict, Optional, Sequence, Tuple

import numpy as np

from ..checks import max_steps as check_max_steps, positive, tolerances
from ..errors import ParameterError
from ..numeric.grid import PlaneJob, plane_attrs
from ..results import DatasetSpec, Result, canonical_json

__all__ = ["ChainFlipMap", "ChainFlipJob", "chain_flip_map", "open_chain_flip_map", "STORE_KIND"]

STORE_KIND = "skewpend chain flip map"
#: Statistics per row (and per store chunk).
CHUNK_STATS = ("cells", "flipped", "failed", "steps", "rejected")

_VARIABLES = {
    "flip_time": {"units": "s", "long_name": "first time any joint angle leaves (-pi, pi), released at rest; NaN: not by "
                                             "t_end"},
    "which": {"long_name": "joint that flipped (1 .. n), 0 none, -1 integration failed"},
}


def _index(name: str, nq: int) -> int:
    from ..schema import state_coordinates

    return state_coordinates(nq)[name]


@dataclass(frozen=True)
class ChainFlipMap(Result):
    """The result of :func:`chain_flip_map` (``flip_map(chain, ...)``).

    * ``plane`` -- the two angles varied (``("q1", "q3")``); ``x0``, ``y0`` -- their starting values (cell
      centres, ``x0`` along axis 0) [rad]; ``held`` -- the start's angles at the plane's origin (the others
      as held) [rad];
    * ``flip_time`` (n, n) [s] -- the first time any angle leaves ``(-pi, pi)``, NaN if not by ``t_end`` or
      failed; ``which`` (n, n) -- the joint that flipped, 1 … n (0 none, -1 failed);
    * ``params`` (the chain), ``settings``, ``stats`` (``cells``, ``flipped``, ``failed``, ``steps``,
      ``rejected``, the run's chunks, store and cluster), ``status`` (PARTIAL when cells failed), ``message``;
      ``flipped``, ``flipped_fraction``, ``to_xarray()``, ``to_netcdf()``, ``summary()``.
    """

    plane: Tuple[str, str]
    x0: np.ndarray
    y0: np.ndarray
    held: np.ndarray
    flip_time: np.ndarray
    which: np.ndarray

    result_kind: ClassVar[str] = "chain flip map"

    @property
    def n(self) -> int:
        return int(self.flip_time.shape[0])

    @property
    def flipped(self) -> np.ndarray:
        return np.isfinite(self.flip_time)

    @property
    def flipped_fraction(self) -> float:
        return float(np.count_nonzero(self.flipped)) / self.flip_time.size

    def _dataset(self) -> DatasetSpec:
        a, b = (f"{c}0" for c in self.plane)
        attrs = {"title": ChainFlipJob.title, "plane": ",".join(self.plane), "held": self.held.tolist(),
                 "flipped_fraction": self.flipped_fraction, **self._base_attrs()}
        return DatasetSpec(
            variables={"flip_time": ((a, b), self.flip_time, dict(_VARIABLES["flip_time"])),
                       "which": ((a, b), self.which, dict(_VARIABLES["which"]))},
            coords={a: ((a,), np.asarray(self.x0, dtype=float).copy(), plane_attrs(self.plane[0], len(self.held))),
                    b: ((b,), np.asarray(self.y0, dtype=float).copy(), plane_attrs(self.plane[1], len(self.held)))},
            attrs=attrs,
        )


@dataclass(frozen=True)
class ChainFlipJob(PlaneJob):
    """A chain's flip map as a job of the grid driver (small and picklable)."""

    params: Any  # a Chain
    n: int
    plane: Tuple[str, str]
    x_range: Tuple[float, float]
    y_range: Tuple[float, float]
    held: Tuple[float, ...]
    t_end: float
    rtol: float
    atol: float
    max_steps: int
    version: str
    kernel_name: str

    kind: ClassVar[str] = STORE_KIND
    what: ClassVar[str] = "a chain's flip map"
    stat_names: ClassVar[Tuple[str, ...]] = CHUNK_STATS
    title: ClassVar[str] = "flip-time map of a chain of links (skewpend)"

    def base_state(self) -> np.ndarray:
        """Every start: the held angles, at rest."""
        return np.r_[np.asarray(self.held, dtype=float), np.zeros(len(self.held))]

    def arrays(self):
        from ..numeric.grid import ArraySpec

        return {"flip_time": ArraySpec("float64", np.nan, _VARIABLES["flip_time"]),
                "which": ArraySpec("int8", -1, _VARIABLES["which"])}

    def settings(self) -> Dict[str, Any]:
        return {"kind": "chain_flip_map", "params": self.params.to_dict(), "n": self.n, "plane": list(self.plane),
                "x_range": list(self.x_range), "y_range": list(self.y_range), "held": list(self.held),
                "t_end": self.t_end, "rtol": self.rtol, "atol": self.atol, "max_steps": self.max_steps,
                "method": "dop853", "skewpend_version": self.version}

    def setup(self):
        from ..numeric.kernels import model_kernel, model_vector

        return self.checked_kernel(model_kernel(self.params)), model_vector(self.params)

    def compute(self, state, rows, cancel=None):
        from ..numeric.ensemble import Cancelled

        kernel, p = state
        rows = np.asarray(rows, dtype=np.int64)
        starts = np.ascontiguousarray(self.starts(rows))
        m = len(starts)
        time_, which = np.full(m, np.nan), np.full(m, -1, dtype=np.int32)
        steps, rejected = np.zeros(m, dtype=np.int64), np.zeros(m, dtype=np.int64)
        status = np.zeros(m, dtype=np.int8)
        dp, i64p = _pointer(np.float64), _pointer(np.int64)
        pp = np.ascontiguousarray(p, dtype=np.float64)
        for a in range(0, m, self.n):  # a row of cells per compiled call, cancel checked between rows
            if cancel is not None and cancel.is_set():
                raise Cancelled()
            b = min(m, a + self.n)
            kernel.lib.sp_flip_many(pp.ctypes.data_as(dp), starts[a:].ctypes.data_as(dp), b - a, float(self.t_end),
                                    float(self.rtol), float(self.atol), int(self.max_steps),
                                    time_[a:].ctypes.data_as(dp), which[a:].ctypes.data_as(_pointer(np.int32)),
                                    steps[a:].ctypes.data_as(i64p), rejected[a:].ctypes.data_as(i64p),
                                    status[a:].ctypes.data_as(_pointer(np.int8)))
        shape = (rows.size, self.n)
        failed = (status != 0).reshape(shape)
        flipped = np.isfinite(time_).reshape(shape)
        joint = np.where(failed, -1, np.where(flipped, which.reshape(shape) + 1, 0)).astype(np.int8)
        stats = np.column_stack([np.full(rows.size, self.n), flipped.sum(1), failed.sum(1),
                                 steps.reshape(shape).sum(1), rejected.reshape(shape).sum(1)]).astype(float)
        return {"flip_time": time_.reshape(shape), "which": joint}, stats

    def result(self, run) -> ChainFlipMap:
        from ..results import grid_status

        n = self.n
        totals = run.totals(CHUNK_STATS)
        settings = {k: v for k, v in self.settings().items() if k not in ("kind", "params", "skewpend_version")}
        stats = {"cells": n * n, "flipped": int(totals["flipped"]), "failed": int(totals["failed"]),
                 "steps": int(totals["steps"]), "rejected": int(totals["rejected"]), **run.info}
        status, message = grid_status(stats["failed"], n * n, "cells")
        xs, ys = (values for values, _ in self.coords().values())
        return ChainFlipMap(plane=tuple(self.plane), x0=xs, y0=ys, held=np.asarray(self.held, dtype=float),
                            flip_time=run.data["flip_time"], which=run.data["which"], params=self.params,
                            settings=settings, stats=stats, status=status, message=message)

    def result_attrs(self, result: ChainFlipMap) -> Dict[str, Any]:
        return {"flip_settings": canonical_json(result.settings), "flip_stats": canonical_json(result.stats)}


def _pointer(dtype):
    import ctypes

    return ctypes.POINTER({np.float64: ctypes.c_double, np.int64: ctypes.c_int64, np.int32: ctypes.c_int32,
                           np.int8: ctypes.c_int8}[dtype])


def _range(name: str, value) -> Tuple[float, float]:
    from ..numeric.grid import check_range

    return check_range(name, value)


def chain_flip_map(chain, n: int, *, plane: Optional[Sequence[str]] = None, ranges=None, held=None,
                   t_end: float = 10.0, rtol: Optional[float] = None, atol: Optional[float] = None,
                   workers: Optional[int] = None, progress: Optional[Callable[[int, int], None]] = None,
                   chunk_size: Optional[int] = None, max_steps: Optional[int] = None, store=None, resume: bool = False,
                   scheduler=None) -> ChainFlipMap:
    """The flip-time map of a chain of links (see the module) on ``n x n`` cells over the two angles of
    ``plane`` (default ``("q1", "q2")``), each over its range of ``ranges`` (default ``(-pi, pi)`` each; within
    ``[-pi, pi]``), the other angles at ``held`` (n angles [rad], each within ``(-pi, pi)``; default 0; the
    plane's own entries are ignored), released at rest.  DOP853 at ``rtol``/``atol`` (default 1e-10 each),
    at most ``max_steps`` steps a cell; ``workers``, ``progress``, ``chunk_size``, ``store``, ``resume`` and
    ``scheduler`` as for :func:`skewpend.flip_map`."""
    from .. import __version__
    from ..checks import MAX_STEPS
    from ..numeric.grid import check_run_options, run_grid
    from ..numeric.kernels import model_kernel, model_vector
    from ..numeric.grid import check_n
    from ..schema import state_coordinates

    nq = chain.n
    angles = tuple(state_coordinates(nq))[:nq]
    if plane is None:
        plane = angles[:2]
    try:
        a, b = plane
    except (TypeError, ValueError):
        a = b = None
    if a not in angles or b not in angles or a == b:
        raise ParameterError(f"plane must be two different angles of {', '.join(angles)} (a flip map starts at rest), "
                             f"got {plane!r}")
    n = check_n(n)
    if ranges is None:
        ranges = ((-math.pi, math.pi), (-math.pi, math.pi))
    try:
        ra, rb = ranges
    except (TypeError, ValueError):
        raise ParameterError(f"ranges must be two ranges ((lo, hi), (lo, hi)) of the plane's angles, got {ranges!r}") from None
    ra, rb = _range(f"range of {a}", ra), _range(f"range of {b}", rb)
    if held is None:
        q = np.zeros(nq)
    else:
        try:
            q = np.array(held, dtype=float).reshape(-1)
        except (TypeError, ValueError):
            q = np.zeros(0)
        if q.shape != (nq,) or not np.all(np.isfinite(q)) or np.any(np.abs(q) >= math.pi):
            raise ParameterError(f"held must be the chain's {nq} angles, each within (-pi, pi) [rad], got {held!r}")
    q = q.copy()
    q[[_index(a, nq), _index(b, nq)]] = 0.0
    t_end = positive("t_end", t_end)
    rtol, atol = tolerances(rtol, atol)
    max_steps = check_max_steps(MAX_STEPS if max_steps is None else max_steps)
    workers = check_run_options(workers=workers, scheduler=scheduler, store=store, resume=resume, progress=progress,
                                chunk_size=chunk_size)
    kernel = model_kernel(chain)
    job = ChainFlipJob(params=chain, n=n, plane=(str(a), str(b)), x_range=ra, y_range=rb,
                       held=tuple(float(v) for v in q), t_end=t_end, rtol=rtol, atol=atol, max_steps=int(max_steps),
                       version=__version__, kernel_name=kernel.path.name)
    result = run_grid(job, workers=workers, scheduler=scheduler, store=store, resume=bool(resume), progress=progress,
                      chunk_size=chunk_size, state=(kernel, model_vector(chain)))
    if result.stats["failed"]:
        warnings.warn(f"flip_map: {result.message}", RuntimeWarning, stacklevel=2)
    return result


def open_chain_flip_map(path) -> ChainFlipMap:
    """A :class:`ChainFlipMap` read back from a complete store ``*.zarr`` or a file ``*.nc``."""
    from ..numeric.grid import read_grid_result
    from ..results import grid_status
    from ..symbolic.chain import Chain

    arrays, attrs, settings, stats = read_grid_result(path, store_kind=STORE_KIND, result_kind=ChainFlipMap.result_kind,
                                                      what="a chain's flip map", store_keys=("flip_settings", "flip_stats"))
    try:
        chain = Chain.from_mapping(json.loads(attrs["params"]))
        a, b = settings["plane"]
        x0, y0 = (np.asarray(arrays[f"{c}0"], dtype=float) for c in (a, b))
        flip_time = np.asarray(arrays["flip_time"], dtype=float)
        which = np.asarray(arrays["which"]).astype(np.int8)
        held = np.asarray(settings["held"], dtype=float)
    except (KeyError, TypeError, ValueError) as exc:
        raise ParameterError(f"{path} is not a chain's flip map made by skewpend (missing or bad attribute: {exc})") from None
    status, message = grid_status(int(stats.get("failed", 0)), flip_time.size, "cells")
    return ChainFlipMap(plane=(a, b), x0=x0, y0=y0, held=held, flip_time=flip_time, which=which, params=chain,
                        settings=settings, stats=stats, status=status, message=message)
