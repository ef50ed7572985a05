"""One grid driver: a computation over many starts is a *job*; :func:`run_grid` runs any job.

The template method of xarray's ``backends/common.py`` ``store()``: the driver owns the
sequence -- check the store, connect the cluster, cut the work, run it on threads or as Dask
tasks, gather rows into chunks, write each chunk to the Zarr store once it is whole, resume,
Ctrl-C, progress -- and a job supplies only its primitives:

* its layout: :meth:`GridJob.shape` ``(rows, cols)``, :meth:`GridJob.arrays` (name ->
  :class:`ArraySpec`), :meth:`GridJob.coords` (the two dimensions' values), optionally a
  trailing dimension (:meth:`GridJob.trailing`) and :attr:`GridJob.stat_names` (statistics
  kept per row and, summed, per store chunk);
* :meth:`GridJob.settings`: the plain-JSON settings that determine every bit of the result
  (their :func:`~skewpend.results.fingerprint` is recorded in a store; resuming with other
  settings is refused, naming what differs);
* :meth:`GridJob.setup` (once per process: compile or load the kernel) and
  :meth:`GridJob.compute` (the rows of one unit of work -> their arrays and statistics);
* :meth:`GridJob.row_groups` (rows that must be computed together, e.g. a row and its mirror
  image) and :meth:`GridJob.chunk_rows` (rows per store chunk);
* :meth:`GridJob.result` (the driver's :class:`GridRun` -> the result object) and
  :meth:`GridJob.result_attrs` (what the store records once the run is complete).

An in-memory run is simply "no store".  Jobs are frozen dataclasses: small and picklable, they
travel with each cluster task.  A unit computes exactly the same cells with exactly the same
arithmetic wherever it runs, so the result is bitwise the same whatever the chunking, the
number of workers or the cluster.  A resumed store is checked first: a chunk marked done whose
data cannot be read or no longer match their digests is computed again.
"""

from __future__ import annotations

import json
import math
import sys
import os
import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Callable, ClassVar, Dict, List, Mapping, Optional, Sequence, Tuple

import numpy as np

from ..errors import ParameterError, SkewpendError
from ..results import DatasetSpec, Result, canonical_json, fingerprint, grid_status
from ..schema import state_coordinates
from .ensemble import (batches, check_scheduler, cluster_threads, connect_scheduler, default_workers,
                       require_distributed, run_chunks, run_on_cluster)
from .store import RowStore, store_target

__all__ = ["GridJob", "GridRun", "ArraySpec", "run_grid", "cluster_task", "read_store", "read_grid_result", "open_store_for", "chunk_rows", "work_units", "check_workers",
           "check_run_options", "check_feasible", "steps_per_second", "probe_time", "UNITS_PER_WORKER", "MAX_N", "check_n",
           "check_range", "cell_centres", "PlaneJob", "PlaneMap", "plane_attrs"]

#: Default store chunk: at most this many cells (whole rows) ...
CHUNK_CELLS = 65536
#: ... and at least this many chunks (so a killed run loses at most about 1/8 of the grid).
MIN_CHUNKS = 8
#: Work units (a few rows each) per worker thread, for balance.
UNITS_PER_WORKER = 8


@dataclass(frozen=True)
class ArraySpec:
    """One result array over the grid: dtype, fill value (what a cell not computed holds),
    attributes (units, long_name), and whether it has the job's trailing dimension."""

    dtype: str
    fill: Any
    attrs: Mapping[str, Any]
    trailing: bool = False


@dataclass
class GridRun:
    """What :func:`run_grid` hands to :meth:`GridJob.result`: the full arrays, the statistics
    of each store chunk (rows of ``job.stat_names``), and ``info`` about the run (``workers``,
    ``chunks``, ``chunk_rows``, ``chunks_resumed``, ``chunks_computed``, ``chunks_repaired``,
    ``store``, ``fingerprint``, ``scheduler``, ``tasks``, ``wall_time``)."""

    data: Dict[str, np.ndarray]
    chunk_stats: np.ndarray
    info: Dict[str, Any] = field(default_factory=dict)
    state: Any = None  #: what ``job.setup()`` returned in this process (None for a cluster run)

    def totals(self, names: Sequence[str]) -> Dict[str, float]:
        """The statistics summed over the chunks, by name."""
        return {name: float(self.chunk_stats[:, i].sum()) for i, name in enumerate(names)}


class GridJob:
    """The primitives of a computation over a grid (see the module).  Subclasses are frozen
    dataclasses with at least a ``version`` field (the skewpend that made the job: a cluster
    worker with another one is refused)."""

    #: The store's ``kind`` attribute (a store of another kind is refused).
    kind: ClassVar[str] = "grid"
    #: What it is, for messages ("a flip map").
    what: ClassVar[str] = "a grid"
    #: Statistics per row (and, summed, per store chunk).
    stat_names: ClassVar[Tuple[str, ...]] = ()
    #: Title of the store.
    title: ClassVar[str] = "skewpend grid"

    # -- layout -------------------------------------------------------------------------------------
    def shape(self) -> Tuple[int, int]:
        raise NotImplementedError

    def arrays(self) -> Dict[str, ArraySpec]:
        raise NotImplementedError

    def coords(self) -> Dict[str, Tuple[np.ndarray, Mapping[str, Any]]]:
        """The two dimensions, in order: name -> (values, attributes)."""
        raise NotImplementedError

    def trailing(self) -> Optional[Tuple[str, np.ndarray, Mapping[str, Any]]]:
        """A third dimension of the arrays marked ``trailing``: (name, values, attributes)."""
        return None

    def settings(self) -> Dict[str, Any]:
        raise NotImplementedError

    def store_attrs(self) -> Dict[str, Any]:
        """More attributes of a new store's template."""
        return {}

    def row_groups(self) -> List[Tuple[int, ...]]:
        """Rows computed together (every row in exactly one group); default: each row alone."""
        return [(i,) for i in range(self.shape()[0])]

    def chunk_rows(self, chunk_size: Optional[int]) -> int:
        """Rows per store chunk (a divisor of the rows): :func:`chunk_rows`."""
        rows, cols = self.shape()
        return chunk_rows(rows, cols, chunk_size=chunk_size)

    def progress_per_row(self) -> int:
        """Units of progress per row (default: its cells)."""
        return self.shape()[1]

    # -- work ---------------------------------------------------------------------------------------
    def setup(self) -> Any:
        """Per process (here, or a cluster worker): what :meth:`compute` needs (a kernel...)."""
        return None

    def compute(self, state: Any, rows: np.ndarray, cancel=None) -> Tuple[Dict[str, np.ndarray], np.ndarray]:
        """The rows ``rows`` (sorted): their part of every array (leading dimension
        ``len(rows)``) and statistics, shape ``(len(rows), len(stat_names))``."""
        raise NotImplementedError

    # -- result -------------------------------------------------------------------------------------
    def result(self, run: GridRun) -> Any:
        raise NotImplementedError

    def result_attrs(self, result: Any) -> Dict[str, Any]:
        """What a complete store records about the result (JSON strings, numbers)."""
        return {}


def plane_attrs(name: str, nq: int) -> Dict[str, str]:
    """The attributes of a plane's coordinate ``name`` of a state of ``nq`` joints (``phi``, ``dq3``): its
    units and what it is."""
    i = state_coordinates(nq)[name]
    speed = i >= nq
    return {"units": "rad/s" if speed else "rad",
            "long_name": f"initial {'angular speed' if speed else 'angle'} of hinge {i % nq + 1}"}


class PlaneJob(GridJob):
    """A map over starts on a plane of two state coordinates, ``n`` x ``n`` cells (a chain's flip map, a
    region of attraction): the layout, the coordinates, the store's parameters, the starts of whole rows and
    the workers' kernel check.  Subclasses are frozen dataclasses with the fields ``params``, ``n``,
    ``plane``, ``x_range``, ``y_range`` and ``kernel_name``, and say the state every start shares
    (:meth:`base_state`, of ``2 nq`` numbers)."""

    def base_state(self) -> np.ndarray:
        raise NotImplementedError

    @property
    def nq(self) -> int:
        return self.base_state().size // 2

    def shape(self):
        return self.n, self.n

    def coords(self):
        a, b = self.plane
        return {f"{a}0": (cell_centres(*self.x_range, self.n), plane_attrs(a, self.nq)),
                f"{b}0": (cell_centres(*self.y_range, self.n), plane_attrs(b, self.nq))}

    def store_attrs(self):
        return {"params": json.dumps(self.params.to_dict())}

    def checked_kernel(self, kernel):
        """``kernel`` if it is the one this run generated, else an error (a worker with another skewpend)."""
        if kernel.path.name != self.kernel_name:
            raise SkewpendError(f"a worker generates another kernel ({kernel.path.name}, this run {self.kernel_name}): "
                                "install the same skewpend on every worker")
        return kernel

    def states(self, x, y) -> np.ndarray:
        """Starts ``(len(x), 2 nq)``: the base state, the plane's two coordinates set to ``x`` and ``y``."""
        i, j = (state_coordinates(self.nq)[c] for c in self.plane)
        out = np.tile(self.base_state(), (len(x), 1))
        out[:, i], out[:, j] = x, y
        return out

    def starts(self, rows: np.ndarray) -> np.ndarray:
        """The starts of whole rows of cells, (rows * n, 2 nq)."""
        xs, ys = (values for values, _ in self.coords().values())
        rows = np.asarray(rows, dtype=np.int64)
        return self.states(np.repeat(xs[rows], self.n), np.tile(ys, rows.size))


@dataclass(frozen=True)
class PlaneMap(Result):
    """The result of a :class:`PlaneJob`: ``plane``, the two state coordinates varied; ``x0``, ``y0``,
    their starting values, the cell centres (``x0`` along axis 0, ``y0`` along axis 1)."""

    plane: Tuple[str, str]
    x0: np.ndarray
    y0: np.ndarray

    @property
    def n(self) -> int:
        return int(np.size(self.x0))

    @classmethod
    def made(cls, plane, axes, *, params, settings, stats, note: str = "", **data):
        """The map of the cell centres ``axes`` (two arrays) on ``plane`` with its ``data``, its status by the
        cells that failed (``note`` added to the message then)."""
        x0, y0 = (np.asarray(v, dtype=np.float64) for v in axes)
        failed = int(stats.get("failed", 0))
        status, message = grid_status(failed, x0.size * y0.size, "cells")
        if failed > 0:
            message += note
        return cls(plane=(str(plane[0]), str(plane[1])), x0=x0, y0=y0, **data, params=params, settings=settings,
                   stats=stats, status=status, message=message)

    def _plane_dataset(self, nq: int, variables: Mapping[str, Tuple[np.ndarray, Mapping[str, Any]]],
                       attrs: Dict[str, Any]) -> DatasetSpec:
        """``variables`` (name -> values, attributes) over the plane's two coordinates, named ``phi0``, ``dq30``...
        (of a state of ``nq`` joints)."""
        dims = tuple(f"{c}0" for c in self.plane)
        return DatasetSpec(
            variables={name: (dims, values, dict(a)) for name, (values, a) in variables.items()},
            coords={d: ((d,), np.asarray(v, dtype=float).copy(), plane_attrs(c, nq))
                    for d, c, v in zip(dims, self.plane, (self.x0, self.y0))},
            attrs=attrs,
        )


# -- shared checks of the run options -------------------------------------------------------------
def check_workers(workers) -> int:
    """``workers`` as a whole number >= 1 (None: the cores this process may use)."""
    if workers is None:
        return default_workers()
    if isinstance(workers, bool) or not isinstance(workers, (int, np.integer)) or workers < 1:
        raise ParameterError(f"workers must be a whole number >= 1, got {workers!r}")
    if workers > 4096:
        raise ParameterError(f"workers must be at most 4096, got {workers}")
    return int(workers)


def check_run_options(*, workers, scheduler, store, resume, progress, chunk_size=None, unit: str = "cells") -> int:
    """The checks every grid computation makes of its run options; returns the worker count."""
    if resume not in (True, False):
        raise ParameterError(f"resume must be True or False, got {resume!r}")
    if resume and store is None:
        raise ParameterError("resume needs a store: the path of the .zarr store to continue")
    if scheduler is not None and workers is not None:
        raise ParameterError("give workers or scheduler, not both (a cluster's workers run the chunks)")
    if progress is not None and not callable(progress):
        raise ParameterError(f"progress must be a callable progress(done_{unit}, total_{unit})")
    if chunk_size is not None and (isinstance(chunk_size, bool) or not isinstance(chunk_size, (int, np.integer))
                                   or chunk_size < 1):
        raise ParameterError(f"chunk_size must be a whole number >= 1, got {chunk_size!r}")
    return check_workers(workers)


#: Steps a trial run may take, and how often a failed trial is tried again over a thousandth of
#: its time (a system too stiff for the first trial shows its rate on a shorter one).
PROBE_STEPS = 200_000
PROBE_TRIES = 6


def probe_time(params) -> float:
    """How long a trial run lasts [s]: about 20 swing times ``sqrt(L / g)`` (``L = a + b``, a chain's
    summed link lengths; 1 s without gravity), long enough for a representative step rate, a few ms of work."""
    reach = sum(link.length for link in params.as_chain().links)
    scale = math.sqrt(reach / float(params.g)) if float(params.g) > 0 else 1.0
    return 20.0 * min(max(scale, 1e-6), 1e6)


def probe_durations(t_end: float, params):
    """The durations of successive trial runs: ``min(t_end, probe_time(params))``, then a
    thousandth of the previous one, at most :data:`PROBE_TRIES` of them, and none below the
    smallest normal float (a subnormal time is 0 to the compiled code)."""
    t = min(float(t_end), probe_time(params))
    for _ in range(PROBE_TRIES):
        if not t >= sys.float_info.min:
            return
        yield t
        t *= 1e-3


def steps_per_second(steps, durations) -> float:
    """The largest rate ``steps / duration`` of trial runs (inf when one could not advance)."""
    steps, durations = np.asarray(steps, dtype=float), np.asarray(durations, dtype=float)
    if steps.size == 0:
        return 0.0
    with np.errstate(divide="ignore", invalid="ignore"):
        rates = np.where(durations > 0, steps / durations, np.inf)
    return float(np.max(rates))


#: A grid is refused when its trajectories would need this many times ``max_steps``: the trial
#: rate is that of a few energetic starts, and cells differ in their rate by an order of
#: magnitude or more (and a flip stops a cell early), so only work that could not finish at a
#: hundredth of the trial rate is refused up front; cells that merely reach ``max_steps`` are
#: counted as failed and make the result's status PARTIAL.
FEASIBILITY_FACTOR = 100.0


def check_feasible(trial: Callable[[float], Tuple[float, bool]], *, params, t_end: float, rtol: float, atol: float,
                   max_steps: int, what: str, factor: float = FEASIBILITY_FACTOR, time_name: str = "t_end",
                   advice: Optional[str] = None) -> float:
    """Refuse, before any work, a computation whose trajectories of ``t_end`` seconds would each
    need more than ``factor x max_steps`` steps, with the estimate in the message.  Returns the
    estimated steps per trajectory.  ``trial(t)`` runs the computation's own kernel over ``t``
    seconds (at most :data:`PROBE_STEPS` steps each) and returns ``(rate, ok)``: the steps per
    simulated second (:func:`steps_per_second`) and whether every trajectory finished.  A failed
    trial is tried again over the next of :func:`probe_durations`, unless its rate -- a lower
    bound, as it stopped at its step cap (the message then says "at least") -- already refuses the
    work (a stiff system's trials of PROBE_STEPS steps each took seconds of variational work only
    to raise the bound)."""
    rate, ok = 0.0, False
    for t in probe_durations(t_end, params):
        rate, ok = trial(t)
        if ok or rate * t_end > factor * max_steps:
            break
    lower_bound = not ok
    need = rate * t_end
    if need > factor * max_steps:
        about = ("at least" if lower_bound else "about") + f" {need:.3g}" if math.isfinite(need) else "more than 1e308"
        rate_text = ((("at least " if lower_bound else "~") + f"{rate:.3g} steps per simulated second")
                     if math.isfinite(rate) else "a trial run could not advance")
        raise ParameterError(f"{what} cannot finish: {time_name} = {t_end:g} s needs {about} steps per trajectory "
                             f"({rate_text} at rtol={rtol:g}, atol={atol:g}), more than max_steps = {max_steps:g}; "
                             + (advice or f"use a shorter {time_name} (or a larger max_steps)"))
    return need


def _divisor_at_most(n: int, target: int) -> int:
    """The largest divisor of ``n`` that is at most ``target`` (at least 1)."""
    return max(r for r in range(1, max(1, min(int(target), n)) + 1) if n % r == 0)


def chunk_rows(rows: int, cols: Optional[int] = None, *, chunk_size: Optional[int] = None) -> int:
    """Rows per store chunk, a divisor of ``rows`` (every chunk whole rows, one Zarr chunk of
    each array; for a square grid the mirror image of a chunk -- rows ``n - 1 - i`` -- is a
    chunk too): ``chunk_size`` cells rounded down to whole rows, or by default at most
    :data:`CHUNK_CELLS` cells and at least :data:`MIN_CHUNKS` chunks."""
    cols = rows if cols is None else cols
    if chunk_size is not None:
        return _divisor_at_most(rows, chunk_size // max(cols, 1))
    return _divisor_at_most(rows, min(rows // MIN_CHUNKS, CHUNK_CELLS // max(cols, 1)))


def work_units(groups: Sequence[Sequence[int]], threads: int) -> list:
    """``groups`` in order, joined into about :data:`UNITS_PER_WORKER` units per thread (lists
    of rows): small enough for balance, large enough for few calls and tasks."""
    units = batches(list(groups), max(1, UNITS_PER_WORKER * max(1, threads)))
    return [sorted(r for g in unit for r in g) for unit in units]


# -- the driver -----------------------------------------------------------------------------------
def cluster_task(job: GridJob, units: Sequence[Sequence[int]]) -> list:
    """A cluster task: the rows of ``units``, computed on a worker (which sets the job up
    itself: compiles or loads the kernel from its own cache), one thread."""
    from .. import __version__

    if __version__ != job.version:
        raise SkewpendError(f"a worker has skewpend {__version__}, this run {job.version}: install the same skewpend on "
                            "every worker")
    state = job.setup()
    out = []
    for rows in units:
        rows = np.asarray(sorted(rows), dtype=np.int64)
        out.append((rows, *job.compute(state, rows)))
    return out


class _Assembler:
    """Rows arriving in any order, gathered into the arrays and into whole chunks: a chunk goes
    to the store (if any) as soon as all its rows are in.  Chunks already done are skipped."""

    def __init__(self, job: GridJob, rows_per_chunk: int, done: np.ndarray, store=None):
        rows, cols = job.shape()
        trailing = job.trailing()
        self.data = {}
        for name, spec in job.arrays().items():
            shape = (rows, cols, len(trailing[1])) if spec.trailing else (rows, cols)
            self.data[name] = np.full(shape, spec.fill, dtype=spec.dtype)
        self.row_stats = np.zeros((rows, len(job.stat_names)))
        self.R, self.done, self.store = rows_per_chunk, done, store
        self.missing = {int(k): rows_per_chunk for k in np.flatnonzero(~done)}  # rows still to come
        self.written = 0

    def add(self, rows: np.ndarray, data: Mapping[str, np.ndarray], stats: np.ndarray) -> None:
        R = self.R
        keep = ~self.done[rows // R]
        rows = rows[keep]
        for name, values in data.items():
            self.data[name][rows] = np.asarray(values)[keep]
        self.row_stats[rows] = np.asarray(stats)[keep]
        for k in np.unique(rows // R).tolist():
            self.missing[k] -= int(np.count_nonzero(rows // R == k))
            if self.missing[k] == 0:
                block = slice(k * R, (k + 1) * R)
                if self.store is not None:
                    self.store.write_chunk(k, {name: arr[block] for name, arr in self.data.items()},
                                           self.row_stats[block].sum(axis=0))
                self.done[k] = True
                self.written += 1
                del self.missing[k]


def _template(job: GridJob, path, fp: str, rows_per_chunk: int):
    settings = job.settings()
    dims = tuple(job.coords())
    arrays = {name: (spec.dtype, spec.fill, dict(spec.attrs), spec.trailing) for name, spec in job.arrays().items()}
    attrs = {"title": job.title, "fingerprint": fp, "settings": canonical_json(settings),
             "skewpend_version": settings.get("skewpend_version", job.version), **job.store_attrs()}
    return RowStore.create(path, kind=job.kind, shape=job.shape(), chunk_rows=rows_per_chunk, dims=dims,
                           arrays=arrays, coords=job.coords(), extra=job.trailing(), stats=job.stat_names, attrs=attrs)


def open_store_for(job: GridJob, path, fp: str, *, writable: bool):
    """The existing store at ``path`` for ``job``: the same kind, settings (fingerprint) and layout."""
    st = RowStore.open_matching(path, kind=job.kind, fingerprint=fp, settings=job.settings(), writable=writable)
    try:
        if st.shape != tuple(job.shape()) or set(st.arrays) != set(job.arrays()):
            raise ParameterError(f"{path} is damaged: its layout does not match its settings; delete it and run again")
    except BaseException:
        st.close()
        raise
    return st


def run_grid(job: GridJob, *, workers: int, scheduler=None, store=None, resume: bool = False,
             progress: Optional[Callable[[int, int], None]] = None, chunk_size: Optional[int] = None,
             state: Any = None) -> Any:
    """Run ``job`` and return ``job.result(run)`` (see the module).

    ``workers`` threads (already checked), or ``scheduler`` (a ``tcp://HOST:PORT`` address or a
    :class:`distributed.Client`); ``store`` a ``*.zarr`` path (refused if it exists, unless
    ``resume``); ``progress(done, total)`` in the calling thread, in units of
    :meth:`GridJob.progress_per_row`; ``chunk_size`` cells per store chunk (rounded to whole
    rows); ``state`` what :meth:`GridJob.setup` returned, if the caller has it already.
    Ctrl-C: :class:`KeyboardInterrupt` within a few milliseconds, the store keeping every
    complete chunk.
    """
    fp = fingerprint(job.settings())
    store_path = None
    if store is not None:
        store_path, exists = store_target(store, resume=resume, what=f"{job.what} store")
        if exists:
            open_store_for(job, store_path, fp, writable=False).close()  # refuse early, before any work
    if scheduler is not None:
        check_scheduler(scheduler)
        require_distributed()

    start = time.perf_counter()
    n_rows, _ = job.shape()
    per_row = job.progress_per_row()
    client, owned = (connect_scheduler(scheduler) if scheduler is not None else (None, False))
    st = None
    try:
        threads = cluster_threads(client) if client is not None else workers
        if client is None and state is None:
            state = job.setup()
        repaired = 0
        if store_path is not None and os.path.lexists(store_path):  # resume
            st = open_store_for(job, store_path, fp, writable=True)
            R = st.chunk_rows
            done = st.done()
            bad = st.damaged(done)
            repaired = int(bad.size)
            done[bad] = False
        else:
            R = job.chunk_rows(chunk_size)
            if store_path is not None:
                st = _template(job, store_path, fp, R)
            done = np.zeros(n_rows // R, dtype=bool)
        resumed = int(np.count_nonzero(done))
        needed = ~np.repeat(done, R)  # rows still to compute
        units = work_units([g for g in job.row_groups() if needed[list(g)].any()], threads)
        assembler = _Assembler(job, R, done.copy(), st)
        count = [resumed * R * per_row]
        if progress is not None:
            progress(count[0], n_rows * per_row)

        def collect(result):
            rows, data, stats = result
            count[0] += per_row * int(np.count_nonzero(needed[rows]))
            assembler.add(rows, data, stats)
            if progress is not None:
                progress(count[0], n_rows * per_row)

        tasks = 0
        if client is None:
            def work(i, cancel):
                rows = np.asarray(units[i], dtype=np.int64)
                return (rows, *job.compute(state, rows, cancel))

            run_chunks(len(units), work, workers=workers, on_done=lambda i, result: collect(result), keep=False)
        else:
            batched = batches(units)
            tasks = len(batched)

            def collect_task(i, results):
                for result in results:
                    collect(result)

            run_on_cluster(client, cluster_task, [(job, b) for b in batched], on_done=collect_task,
                           name=f"skewpend-{job.kind.replace(' ', '-')}")
        if assembler.missing:  # pragma: no cover - every unit delivered: every chunk complete
            raise RuntimeError("internal error: chunks left incomplete")

        data = assembler.data
        chunk_stats = np.add.reduceat(assembler.row_stats, np.arange(0, n_rows, R), axis=0)
        if resumed:  # the chunks done before this run: from the store
            old = np.repeat(done, R)
            for name in data:
                data[name][old] = st.read(name)[old]
            chunk_stats[done] = st.chunk_stats()[done]
        info = {
            "workers": threads, "chunks": n_rows // R, "chunk_rows": R, "chunk_size": R * job.shape()[1],
            "chunks_resumed": resumed, "chunks_computed": assembler.written, "chunks_repaired": repaired,
            "store": None if store_path is None else str(store_path), "fingerprint": fp,
            "scheduler": None if client is None else str(client.scheduler.address), "tasks": tasks,
            "wall_time": time.perf_counter() - start,
        }
        result = job.result(GridRun(data=data, chunk_stats=chunk_stats, info=info, state=state))
        if st is not None:  # the last write: what the result records, and "complete"
            st.set_attrs(complete=True, **job.result_attrs(result))
    finally:
        if st is not None:
            st.close()
        if owned:
            client.close(timeout=5)
    return result


def read_store(job_kind: str, path, *, what: str) -> Tuple[Dict[str, np.ndarray], Dict[str, Any]]:
    """``(arrays, attrs)`` of a complete, undamaged store of ``job_kind`` (every array and
    coordinate by name): the reading half of the driver, for the ``open_*`` functions."""
    with RowStore.open(path, kind=job_kind) as st:
        attrs = st.attrs
        done = st.done()
        if not attrs.get("complete") or not done.all():
            raise ParameterError(f"{path} is not complete ({int(done.sum())} of {done.size} chunks done); "
                                 f"resume it with the same settings first")
        bad = st.damaged(done)
        if bad.size:
            raise ParameterError(f"{path} is damaged: {bad.size} chunk(s) cannot be read or changed since they were "
                                 f"written; resume it (with the same settings) to compute them again")
        names = list(st.arrays) + [n for n in st.names() if n not in st.arrays and n not in
                                    ("done", "chunk_stats", "chunk_digest")]
        arrays = {name: st.read(name) for name in names}
    return arrays, attrs


def read_grid_result(path, build: Callable[..., Any], *, store_kind: str, result_kind: str, what: str,
                     store_keys: Tuple[str, str]):
    """``build(arrays, attrs, settings, stats)`` of a grid result written whole: a complete store
    ``*.zarr`` (its settings and statistics in the attributes ``store_keys``) or a file ``*.nc``
    (the result protocol's ``settings`` and ``stats``); anything else, or a missing or bad part
    (``build``'s :class:`KeyError`, :class:`TypeError`, :class:`ValueError`), is refused in one line."""
    path = Path(path)
    suffix = path.suffix.lower()
    if suffix == ".zarr":
        arrays, attrs = read_store(store_kind, path, what=what)
        keys = store_keys
    elif suffix == ".nc":
        from ..io import read_netcdf

        arrays, attrs = read_netcdf(path, kind=result_kind)
        keys = ("settings", "stats")
    else:
        raise ParameterError(f"expected a store ending in .zarr or a file ending in .nc, got {str(path)!r}")
    try:
        settings, stats = (json.loads(attrs[k]) for k in keys)
        return build(arrays, attrs, settings, stats)
    except (KeyError, TypeError, ValueError) as exc:
        raise ParameterError(f"{path} is not {what} made by skewpend (missing or bad attribute: {exc})") from None


# -- the cells of a map over a window of starts (flip maps, regions of attraction, Lyapunov maps) ---------------
#: Largest grid: n x n cells (16384^2 = 2.7e8 cells, about 4 GB of results).
MAX_N = 16384


def check_n(n) -> int:
    """``n`` cells per side: a whole number from 1 to :data:`MAX_N`."""
    if isinstance(n, bool) or not isinstance(n, (int, np.integer)):
        raise ParameterError(f"n must be a whole number of cells per side, got {n!r}")
    if not 1 <= n <= MAX_N:
        raise ParameterError(f"n must be from 1 to {MAX_N} (cells per side), got {n}")
    return int(n)


def check_range(name: str, value) -> Tuple[float, float]:
    """A window ``(start, stop)`` of angles within ``[-pi, pi]``, start < stop."""
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


def cell_centres(lo: float, hi: float, n: int) -> np.ndarray:
    """The ``n`` cell centres ``lo + (k + 1/2) (hi - lo) / n``, computed as
    ``(lo (2n - 2k - 1) + hi (2k + 1)) / 2n`` so that in a window symmetric about 0
    (``lo = -hi``) mirror cells are exact negatives: ``c[n - 1 - k] == -c[k]``."""
    k = np.arange(n, dtype=np.float64)
    return (lo * (2 * n - 2 * k - 1) + hi * (2 * k + 1)) / (2 * n)
