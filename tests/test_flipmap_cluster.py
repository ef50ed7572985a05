"""flip_map on a dask.distributed cluster (issue 9): a LocalCluster on 127.0.0.1 (2 worker
processes) gives bitwise the local result, with and without a store; tasks are batches of
chunks; an unreachable scheduler is refused quickly with one line."""

from __future__ import annotations

import logging
import re
import signal
import socket
import sys
import time

import pytest

distributed = pytest.importorskip("distributed")
pytest.importorskip("zarr")

from skewpend import ParameterError, SkewpendError  # noqa: E402
from skewpend.analysis.flipmap import FlipJob, flip_map, open_flip_map  # noqa: E402
from skewpend.numeric.grid import cluster_task  # noqa: E402
from skewpend.numeric.ensemble import MAX_TASKS, batches  # noqa: E402

from skewpend.config import reference_parameters  # noqa: E402
BENCH = reference_parameters()  # the reference case: a = 1, b = 0.8, m1 = 1, m2 = 0.7, alpha = 0.6, g = 9.81
#: No test here may take longer (no pytest-timeout in the test extra: SIGALRM does it).
TIMEOUT = 90


@pytest.fixture(autouse=True)
def time_limit():
    if not hasattr(signal, "SIGALRM"):  # pragma: no cover - not POSIX
        yield
        return

    def expired(signum, frame):
        raise TimeoutError(f"test took longer than {TIMEOUT} s")

    old = signal.signal(signal.SIGALRM, expired)
    signal.alarm(TIMEOUT)
    try:
        yield
    finally:
        signal.alarm(0)
        signal.signal(signal.SIGALRM, old)


#: The scheduler's HTTP server (health routes; the dashboard too if bokeh is installed) starts even
#: with ``dashboard_address=None`` -- on port 8787; ``":0"``: a free port on 127.0.0.1 instead.
NO_FIXED_PORT = ":0"


@pytest.fixture(scope="module")
def cluster():
    with distributed.LocalCluster(n_workers=2, processes=True, threads_per_worker=1, host="127.0.0.1",
                                  dashboard_address=NO_FIXED_PORT, silence_logs=logging.ERROR) as lc:
        yield lc


@pytest.fixture(scope="module")
def ref40():
    return flip_map(BENCH, 40, t_end=6.0)


def same(a, b) -> bool:
    return a.flip_time.tobytes() == b.flip_time.tobytes() and a.which.tobytes() == b.which.tobytes()


def test_cluster_result_is_bitwise_the_local_one(cluster, ref40):
    fm = flip_map(BENCH, 40, t_end=6.0, scheduler=cluster.scheduler_address)
    assert same(fm, ref40)
    assert fm.stats["scheduler"] == cluster.scheduler_address and fm.stats["workers"] == 2
    assert 2 <= fm.stats["tasks"] <= 20  # one per unit of work here (20 pairs of mirror rows)
    for key in ("integrated", "skipped_energy", "mirrored", "steps", "rejected", "flipped"):
        assert fm.stats[key] == ref40.stats[key], key
    # a window (no symmetry) and no shortcuts, every cell integrated on the cluster
    kw = dict(t_end=4.0, phi_range=(-3.0, 2.5), psi_range=(-2.0, 3.1), shortcuts=False)
    assert same(flip_map(BENCH, 21, scheduler=cluster.scheduler_address, chunk_size=21 * 3, **kw),
                flip_map(BENCH, 21, **kw))


def test_cluster_with_a_store_and_a_client(cluster, ref40, tmp_path):
    path = tmp_path / "map.zarr"
    with distributed.Client(cluster.scheduler_address, set_as_default=False) as client:
        # Ctrl-C part-way (from the progress callback): the store stays resumable
        seen = []

        def interrupt(done, total):
            seen.append(done)
            if len(seen) == 3:
                raise KeyboardInterrupt

        with pytest.raises(KeyboardInterrupt):
            flip_map(BENCH, 40, t_end=6.0, scheduler=client, store=path, chunk_size=40, progress=interrupt)
        fm = flip_map(BENCH, 40, t_end=6.0, scheduler=client, store=path, resume=True)
        assert same(fm, ref40) and 0 < fm.stats["chunks_resumed"] < 40
        assert fm.stats["chunks_resumed"] + fm.stats["chunks_computed"] == 40
        assert client.status == "running"  # a client passed in is left open
    assert same(open_flip_map(path), ref40)
    # a store begun locally is finished on the cluster (and the other way round gives the same)
    local = tmp_path / "local.zarr"
    flip_map(BENCH, 40, t_end=6.0, store=local, chunk_size=80)
    import zarr

    g = zarr.open_group(str(local), mode="r+")
    for k in (0, 3, 19):
        g["done"][k] = False
        g["flip_time"][2 * k:2 * k + 2, :] = -1.0
    fm = flip_map(BENCH, 40, t_end=6.0, store=local, resume=True, scheduler=cluster.scheduler_address)
    assert same(fm, ref40) and fm.stats["chunks_computed"] == 3


def _free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def test_an_unreachable_scheduler_is_refused_quickly(tmp_path, monkeypatch):
    """Refused by the probe's one plain connection, never by dask's retries until its timeout (the
    dask client is never made) -- the path checked, not the seconds (issue 36)."""
    monkeypatch.setattr(distributed, "Client", lambda *a, **k: pytest.fail("a dask Client was made"))
    address = f"tcp://127.0.0.1:{_free_port()}"
    with pytest.raises(ParameterError, match=f"cannot reach the Dask scheduler at {address}") as exc:
        flip_map(BENCH, 8, t_end=1.0, scheduler=address, store=tmp_path / "map.zarr")
    assert "connection refused" in str(exc.value)
    assert "\n" not in str(exc.value)
    assert list(tmp_path.iterdir()) == []  # nothing written


def test_a_port_that_is_not_a_scheduler_is_refused_within_the_timeout(monkeypatch):
    """Something listens there but never speaks dask: refused after the connect timeout (its 1 s named
    in the message), never handed to a dask Client (which would wait for ever)."""
    import skewpend.numeric.ensemble as ensemble

    monkeypatch.setattr(ensemble, "CONNECT_TIMEOUT", 1.0)
    monkeypatch.setattr(distributed, "Client", lambda *a, **k: pytest.fail("a dask Client was made"))
    with socket.socket() as server:
        server.bind(("127.0.0.1", 0))
        server.listen(8)
        address = f"tcp://127.0.0.1:{server.getsockname()[1]}"
        start = time.monotonic()
        with pytest.raises(ParameterError, match=f"no Dask scheduler answered at {address} within 1 s") as exc:
            flip_map(BENCH, 8, t_end=1.0, scheduler=address)
        # a hang guard, not a speed test (dask's own connect timeout is 30 s)
        assert time.monotonic() - start < 20 and "\n" not in str(exc.value)


def test_a_scheduler_without_workers_is_refused(monkeypatch, tmp_path):
    import skewpend.numeric.ensemble as ensemble

    monkeypatch.setattr(ensemble, "CONNECT_TIMEOUT", 1.0)
    with distributed.LocalCluster(n_workers=0, processes=True, host="127.0.0.1", dashboard_address=NO_FIXED_PORT,
                                  silence_logs=logging.ERROR) as empty:
        with pytest.raises(ParameterError, match="has no workers"):
            flip_map(BENCH, 8, t_end=1.0, scheduler=empty.scheduler_address, store=tmp_path / "map.zarr")
    assert list(tmp_path.iterdir()) == []


def test_a_worker_address_is_not_a_scheduler(cluster):
    worker = next(iter(cluster.scheduler_info["workers"]))
    with pytest.raises(ParameterError, match=r"is not a Dask scheduler \(it is a Worker\)"):
        flip_map(BENCH, 8, t_end=1.0, scheduler=worker)


@pytest.mark.parametrize("kwargs, match", [
    (dict(scheduler="http://localhost:8786"), "address like tcp://HOST:PORT"),
    (dict(scheduler="tcp://host"), "address like tcp://HOST:PORT"),
    (dict(scheduler="tcp://host:99999"), "address like tcp://HOST:PORT"),
    (dict(scheduler=8786), "address like tcp://HOST:PORT or a dask.distributed Client"),
    (dict(scheduler="tcp://127.0.0.1:8786", workers=2), "workers or scheduler, not both"),
])
def test_bad_scheduler_input(kwargs, match, monkeypatch):
    tried = []  # refused before any connection is tried: counted, not timed (issue 36)
    monkeypatch.setattr(socket, "create_connection", lambda *a, **k: tried.append(a) or pytest.fail("connected"))
    monkeypatch.setattr(distributed, "Client", lambda *a, **k: tried.append(a) or pytest.fail("a dask Client"))
    with pytest.raises(ParameterError, match=match):
        flip_map(BENCH, 8, t_end=1.0, **kwargs)
    assert tried == []


def test_tasks_are_batches_of_chunks():
    units = list(range(10_000))
    got = batches(units)
    assert len(got) == MAX_TASKS and [u for b in got for u in b] == units
    assert max(map(len, got)) - min(map(len, got)) <= 1
    assert batches(list(range(3))) == [[0], [1], [2]] and batches([]) == []


def test_a_worker_with_another_skewpend_is_refused():
    from skewpend.numeric.kernels import kernel_module

    job = dict(params=BENCH, n=4, t_end=1.0, plane=("phi", "psi"), x_range=(-3.0, 3.0), y_range=(-3.0, 3.0),
               held=(0.0, 0.0), rtol=1e-10, atol=1e-10, max_steps=1000, symmetric=True, threshold=None)
    name = kernel_module(BENCH, flip=True).path.name
    with pytest.raises(SkewpendError, match=f"skewpend {re.escape(_version())}, this run 0.0.1"):
        cluster_task(FlipJob(**job, version="0.0.1", kernel_name=name), [[0, 3]])
    with pytest.raises(SkewpendError, match="generates another kernel"):
        cluster_task(FlipJob(**job, version=_version(), kernel_name="skewpend_other.so"), [[0, 3]])
    out = cluster_task(FlipJob(**job, version=_version(), kernel_name=name), [[0, 3], [1, 2]])
    assert [r[0].tolist() for r in out] == [[0, 3], [1, 2]] and out[0][1]["flip_time"].shape == (2, 4)


def _version():
    import skewpend

    return skewpend.__version__


def test_a_bare_host_port_is_tcp():
    from skewpend.numeric.ensemble import check_scheduler

    assert check_scheduler("127.0.0.1:8786") == "tcp://127.0.0.1:8786"
    assert check_scheduler(" tcp://[::1]:8786 ") == "tcp://[::1]:8786"
    with pytest.raises(ParameterError, match="pass a dask.distributed Client"):
        check_scheduler("tls://10.0.0.1:8786")


def test_without_distributed_the_error_names_the_extra(monkeypatch):
    monkeypatch.setitem(sys.modules, "distributed", None)
    with pytest.raises(SkewpendError, match=r'pip install "skewpend\[cluster\]"'):
        flip_map(BENCH, 8, t_end=1.0, scheduler="tcp://127.0.0.1:8786")
