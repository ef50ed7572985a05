"""The ensemble engine: many trajectories, in chunks, on every core.

A workload is a list of *chunks* of initial conditions.  Each chunk is integrated by one call
sequence into compiled code generated from the derivation; chunks run on a thread pool --
:mod:`ctypes` releases the GIL for the duration of a foreign call, so the threads run the C
in parallel on all cores.  A chunk's result depends only on its own initial conditions (and
each trajectory's only on its own), so results are bitwise identical whatever the chunk size
and the number of workers.

* :func:`run_chunks` -- the generic part: a thread pool over chunks, results in chunk order,
  ``on_done`` (progress) in the calling thread as chunks complete, and Ctrl-C: the pending
  chunks are cancelled, the running ones stop at their next bounded call into C (a few
  milliseconds), and :class:`KeyboardInterrupt` is re-raised.
* :class:`FlipIntegrator` -- the per-trajectory analysis "flip time": ``sp_flip``
  (``integrators.c``) integrates starts at rest with DOP853, ``SP_LANES`` trajectories per SIMD
  vector, and stops each at the first time a joint angle reaches +-pi, located on the dense
  output.

Computations over grids of starts do not call these directly: they are jobs of the one grid
driver, :func:`skewpend.numeric.grid.run_grid`, which uses :func:`run_chunks` locally and
:func:`run_on_cluster` on a cluster.

Beyond one machine (the ``cluster`` extra, ``dask.distributed``, imported only here and only
when a scheduler is given):

* :func:`connect_scheduler` -- a :class:`distributed.Client` for ``tcp://HOST:PORT`` within
  :data:`CONNECT_TIMEOUT` seconds, or one clear :class:`~skewpend.errors.ParameterError`;
* :func:`batches` -- work units grouped into at most :data:`MAX_TASKS` tasks (thousands of
  tasks, not millions: the scheduler's cost is per task);
* :func:`run_on_cluster` -- the tasks submitted, their results handed to ``on_done`` in the
  calling thread as they arrive (so one process writes the results: the workers need no
  shared file system), Ctrl-C cancelling what is left.
"""

from __future__ import annotations

import concurrent.futures as cf
import ctypes
import os
import re
import threading
import uuid
from dataclasses import dataclass
from typing import Callable, List, Optional, Sequence, TypeVar

import numpy as np

from ..interrupts import Interrupts

__all__ = [
    "run_chunks", "default_workers", "Cancelled", "FlipIntegrator", "FlipChunk",
    "connect_scheduler", "run_on_cluster", "require_distributed", "batches", "CONNECT_TIMEOUT", "MAX_TASKS",
]

R = TypeVar("R")

#: Vector steps (each advances every lane by one trial step) per call into ``sp_flip``:
#: about 5 ms of work, so a cancelled run stops within that.
FLIP_BUDGET = 16_384


class Cancelled(Exception):
    """Raised inside a worker whose run was cancelled (Ctrl-C in the calling thread)."""


def default_workers() -> int:
    """The cores this process may use (``os.sched_getaffinity`` where available)."""
    try:
        return max(1, len(os.sched_getaffinity(0)))
    except (AttributeError, OSError):  # pragma: no cover - non-Linux
        return max(1, os.cpu_count() or 1)


def run_chunks(
    n_chunks: int,
    work: Callable[[int, threading.Event], R],
    *,
    workers: int,
    on_done: Optional[Callable[[int, R], None]] = None,
    keep: bool = True,
) -> List[R]:
    """``[work(i, cancel) for i in range(n_chunks)]`` on ``workers`` threads.

    ``work`` must return promptly (``raise Cancelled``) once ``cancel`` is set.  ``on_done(i,
    result)`` runs in the calling thread after each chunk, in completion order.  An exception
    in a chunk cancels the rest and is re-raised; so is Ctrl-C (:class:`KeyboardInterrupt`),
    which is delivered to the calling thread while it waits.  ``keep=False``: results are
    dropped once ``on_done`` has seen them (streaming to a store; the list returned holds
    ``None``).
    """
    results: List[Optional[R]] = [None] * n_chunks
    if n_chunks == 0:
        return []
    cancel = threading.Event()

    def deliver(i: int, result) -> None:
        if on_done is not None:
            on_done(i, result)
        if keep:
            results[i] = result

    # Ctrl-C sets `cancel` at once (the workers stop at their next bounded call into C) and is
    # raised here as KeyboardInterrupt, whatever the workers raise on the way out
    with Interrupts(on_signal=cancel.set) as intr:
        try:
            if workers <= 1 or n_chunks == 1:  # no thread needed
                for i in range(n_chunks):
                    result = work(i, cancel)
                    intr.check()
                    deliver(i, result)
                    del result
                return results  # type: ignore[return-value]
            pool = cf.ThreadPoolExecutor(max_workers=min(workers, n_chunks), thread_name_prefix="skewpend-ensemble")
            futures = {}
            try:
                futures = {pool.submit(work, i, cancel): i for i in range(n_chunks)}
                pending = set(futures)
                while pending:
                    done, pending = cf.wait(pending, timeout=0.1, return_when=cf.FIRST_COMPLETED)
                    intr.check()
                    for fut in done:
                        deliver(futures.pop(fut), fut.result())  # re-raises a worker's exception
                        del fut
            except BaseException:
                cancel.set()
                for fut in futures:
                    fut.cancel()
                pool.shutdown(wait=True)
                raise
            pool.shutdown(wait=True)
        except Cancelled:
            intr.check()  # cancelled by Ctrl-C: KeyboardInterrupt
            raise
    return results  # type: ignore[return-value]


@dataclass
class FlipChunk:
    """Results for the cells of one chunk: flip time [s] (NaN: none by ``t_end``), ``which``
    (0 phi, 1 psi, -1 none, -2 failed), accepted and rejected steps per cell."""

    time: np.ndarray
    which: np.ndarray
    steps: np.ndarray
    rejected: np.ndarray


class FlipIntegrator:
    """Flip times of starts at rest, by the compiled ``sp_flip`` (DOP853 over SIMD lanes).

    ``kernel`` is a :class:`~skewpend.numeric.kernels.Kernel`, ``p`` the parameter vector.
    :meth:`run` integrates one chunk of cells ``(phi0, psi0)`` in bounded calls (each at most
    :data:`FLIP_BUDGET` vector steps), checking ``cancel`` between them.  Thread-safe: every
    call works in its own workspace.
    """

    def __init__(self, kernel, p, *, t_end: float, rtol: float, atol: float, max_steps: int,
                 budget: int = FLIP_BUDGET):
        self.kernel = kernel
        self.p = np.ascontiguousarray(p, dtype=np.float64)
        self.t_end, self.rtol, self.atol = float(t_end), float(rtol), float(atol)
        self.max_steps, self.budget = int(max_steps), int(budget)

    def run(self, cells: np.ndarray, cancel: Optional[threading.Event] = None) -> FlipChunk:
        cells = np.ascontiguousarray(cells, dtype=np.float64).reshape(-1, 2)
        m = cells.shape[0]
        out = FlipChunk(np.full(m, np.nan), np.full(m, -1, dtype=np.int32), np.zeros(m, dtype=np.int64),
                        np.zeros(m, dtype=np.int64))
        if m == 0:
            return out
        ws = np.zeros(self.kernel.flip_ws_size // 8 + 8, dtype=np.float64)  # zeroed: a fresh start
        dp = ctypes.POINTER(ctypes.c_double)
        head = (ws.ctypes.data, self.p.ctypes.data_as(dp), cells.ctypes.data_as(dp), m, self.t_end, self.rtol,
                self.atol, self.max_steps)
        tail = (out.time.ctypes.data_as(dp), out.which.ctypes.data_as(ctypes.POINTER(ctypes.c_int32)),
                out.steps.ctypes.data_as(ctypes.POINTER(ctypes.c_int64)),
                out.rejected.ctypes.data_as(ctypes.POINTER(ctypes.c_int64)))
        fn = self.kernel.lib.sp_flip
        from .driver import drive

        def between() -> None:  # the engine's cancel event, between two bounded calls
            if cancel is not None and cancel.is_set():
                raise Cancelled()

        drive(lambda budget: fn(*head, budget, *tail), budget=self.budget, between=between, name="sp_flip")
        return out


# -- beyond one machine: dask.distributed ------------------------------------------------------------
#: Seconds to reach a scheduler (and for it to have a worker) before giving up.
CONNECT_TIMEOUT = 5.0
#: At most this many tasks per run: work units are batched beyond it.
MAX_TASKS = 2000

_ADDRESS = re.compile(r"^(tcp)://(\[[0-9A-Fa-f:.]+\]|[A-Za-z0-9_.-]+):(\d{1,5})/?$")


def require_distributed(what: str = "running on a Dask cluster"):
    """The ``distributed`` module, or a :class:`SkewpendError` naming the extra to install."""
    from ..errors import require

    return require("distributed", what)


def check_scheduler(scheduler):
    """``scheduler`` if it is an address ``tcp://HOST:PORT`` (a bare ``HOST:PORT`` is taken as
    ``tcp://``; TLS and other protocols need security settings: pass a Client made with them) or
    a :class:`distributed.Client`; else a :class:`ParameterError`."""
    from ..errors import ParameterError

    if isinstance(scheduler, str):
        address = scheduler.strip()
        if "://" not in address:  # HOST:PORT, as dask itself accepts it
            address = "tcp://" + address
        m = _ADDRESS.match(address)
        if not m or not 0 < int(m.group(3)) < 65536:
            raise ParameterError(f"scheduler must be an address like tcp://HOST:PORT, got {scheduler!r} (for TLS or "
                                 "another protocol, pass a dask.distributed Client set up for it)")
        return address
    if type(scheduler).__name__ == "Client" and type(scheduler).__module__.startswith("distributed"):
        return scheduler
    raise ParameterError(
        f"scheduler must be an address like tcp://HOST:PORT or a dask.distributed Client, got {type(scheduler).__name__}"
    )


def connect_scheduler(scheduler, *, timeout: Optional[float] = None):
    """``(client, owned)``: a :class:`distributed.Client` for ``scheduler`` (an address or a
    client), ``owned`` if made here (then the caller closes it).  An unreachable scheduler, or
    one without workers, is a :class:`ParameterError` after at most about ``timeout`` seconds
    (default :data:`CONNECT_TIMEOUT`; a refused port or an unknown host at once)."""
    from ..errors import ParameterError

    timeout = CONNECT_TIMEOUT if timeout is None else float(timeout)

    scheduler = check_scheduler(scheduler)
    distributed = require_distributed()
    if not isinstance(scheduler, str):
        return scheduler, False
    _probe(scheduler, timeout)
    import logging

    # a failed connection is reported by the one error below, not by distributed's log
    quiet = [logging.getLogger(name) for name in ("distributed.client", "distributed.comm", "distributed.core")]
    levels = [log.level for log in quiet]
    for log in quiet:
        log.setLevel(logging.CRITICAL)
    try:
        client = distributed.Client(scheduler, timeout=timeout, set_as_default=False)
    except (OSError, TimeoutError) as exc:
        reason = str(exc).strip().splitlines()[0] if str(exc).strip() else type(exc).__name__
        if len(reason) > 160:
            reason = reason[:157] + "..."
        raise ParameterError(f"cannot reach the Dask scheduler at {scheduler} within {timeout:g} s ({reason})") from None
    finally:
        for log, level in zip(quiet, levels):
            log.setLevel(level)
    try:
        client.wait_for_workers(1, timeout=timeout)
    except (OSError, TimeoutError):
        client.close(timeout=timeout)
        raise ParameterError(f"the Dask scheduler at {scheduler} has no workers (none joined within {timeout:g} s)") from None
    return client, True


def _probe(address: str, timeout: float) -> None:
    """Fail fast: a plain TCP connection to the scheduler's port, so that a refused port or an
    unknown host is one clear line at once rather than dask's retries until the timeout."""
    import socket

    from ..errors import ParameterError

    m = _ADDRESS.match(address)
    host, port = m.group(2).strip("[]"), int(m.group(3))
    try:
        with socket.create_connection((host, port), timeout=timeout):
            pass
    except socket.gaierror:
        raise ParameterError(f"cannot reach the Dask scheduler at {address}: unknown host {host}") from None
    except ConnectionRefusedError:
        raise ParameterError(f"cannot reach the Dask scheduler at {address}: connection refused (is the scheduler "
                             "running, on that port?)") from None
    except (socket.timeout, TimeoutError):
        raise ParameterError(f"cannot reach the Dask scheduler at {address} within {timeout:g} s") from None
    except OSError as exc:
        raise ParameterError(f"cannot reach the Dask scheduler at {address}: {exc.strerror or exc}") from None
    _identify(address, timeout)


def _identify(address: str, timeout: float) -> None:
    """Ask whoever listens at ``address`` who it is, over dask's own protocol, with a hard
    deadline: a port that accepts connections but does not answer (a dashboard port, another
    service) would otherwise hang ``distributed.Client`` for ever.  Runs in a thread of its
    own, with its own event loop (the caller may be inside one, e.g. Jupyter)."""
    import asyncio

    from distributed.comm import connect

    from ..errors import ParameterError

    out: dict = {}

    async def ask():
        comm = await asyncio.wait_for(connect(address, timeout=timeout), timeout)
        try:
            await asyncio.wait_for(comm.write({"op": "identity", "reply": True}), timeout)
            out["reply"] = await asyncio.wait_for(comm.read(), timeout)
        finally:
            comm.abort()

    def run():
        try:
            asyncio.run(ask())
        except BaseException as exc:  # noqa: BLE001 - reported below
            out["error"] = exc

    thread = threading.Thread(target=run, name="skewpend-scheduler-probe", daemon=True)
    thread.start()
    thread.join(2 * timeout + 1)
    reply = out.get("reply")
    if not isinstance(reply, dict):
        raise ParameterError(f"no Dask scheduler answered at {address} within {timeout:g} s (is that the scheduler's "
                             "port? dask's default is 8786; 8787 is its dashboard)")
    if reply.get("type") != "Scheduler":
        raise ParameterError(f"{address} is not a Dask scheduler (it is a {reply.get('type', 'something else')}); "
                             "give the scheduler's address")


def cluster_threads(client) -> int:
    """The threads of all the cluster's workers (at least 1)."""
    return max(1, sum(client.nthreads().values()))


def batches(items: Sequence, max_tasks: int = MAX_TASKS) -> List[list]:
    """``items`` in order, grouped into at most ``max_tasks`` consecutive batches of (nearly)
    equal size."""
    m = len(items)
    if m == 0:
        return []
    k = min(m, max(1, int(max_tasks)))
    bounds = [(i * m) // k for i in range(k + 1)]
    return [list(items[bounds[i]:bounds[i + 1]]) for i in range(k)]


def run_on_cluster(client, fn: Callable, args: Sequence[tuple], *, on_done: Callable[[int, object], None],
                   name: str = "skewpend") -> None:
    """``fn(*args[i])`` for every ``i`` as tasks on the cluster; ``on_done(i, result)`` in the
    calling thread as each finishes (results are not kept here).  An error in a task cancels
    the others and is re-raised (a worker that cannot import ``fn``'s module: a
    :class:`SkewpendError` saying to install skewpend there); so is Ctrl-C."""
    from ..errors import SkewpendError

    distributed = require_distributed()
    run = uuid.uuid4().hex[:12]
    futures = [client.submit(fn, *a, key=f"{name}-{run}-{i}", pure=False) for i, a in enumerate(args)]
    index = {f.key: i for i, f in enumerate(futures)}
    try:
        for fut in distributed.as_completed(futures, loop=client.loop):
            try:
                result = fut.result()
            except (ImportError, AttributeError) as exc:  # the task could not be unpickled on the worker
                if "skewpend" in str(exc):
                    raise SkewpendError(
                        f"the cluster's workers cannot run skewpend's tasks ({str(exc).splitlines()[0]}): "
                        "install the same skewpend on every worker"
                    ) from None
                raise
            on_done(index[fut.key], result)
            fut.release()
            del result
    except BaseException:
        try:
            client.cancel([f for f in futures if not f.done()], force=True)
        except Exception:  # noqa: BLE001 - a cluster gone away: nothing left to cancel
            pass
        raise
