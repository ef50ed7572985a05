"""flip_map with a Zarr store (issue 9): chunk by chunk, resumable after Ctrl-C or kill -9, bitwise
the same as in memory whatever the chunking, refusing other settings and existing paths."""

from __future__ import annotations

import json
import math
import signal
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

zarr = pytest.importorskip("zarr")

from skewpend import ParameterError, SkewpendError  # noqa: E402
from skewpend.analysis.flipmap import (  # noqa: E402
    FlipMap, chunk_rows, fingerprint, flip_map, flip_settings, open_flip_map, row_groups,
)
from skewpend.numeric.grid import UNITS_PER_WORKER, work_units  # noqa: E402
from skewpend.numeric.store import LOCK_NAME, RowStore  # noqa: E402

from skewpend.config import reference_parameters  # noqa: E402
BENCH = reference_parameters()  # the reference case: a = 1, b = 0.8, m1 = 1, m2 = 0.7, alpha = 0.6, g = 9.81
KIND = "skewpend flip map"


def same(a: FlipMap, b: FlipMap) -> bool:
    return a.flip_time.tobytes() == b.flip_time.tobytes() and a.which.tobytes() == b.which.tobytes()


@pytest.fixture(scope="module")
def ref36():
    return flip_map(BENCH, 36, t_end=6.0)


def _mark_not_done(path: Path, chunks, *, garbage: bool = True) -> None:
    """What a crash between a chunk's data and its flag leaves: the flag unset (and, to be sure
    nothing of it is trusted, its rows overwritten with garbage)."""
    g = zarr.open_group(str(path), mode="r+")
    rows = int(g.attrs["chunk_rows"])
    for k in chunks:
        if garbage:
            g["flip_time"][k * rows:(k + 1) * rows, :] = 123.0
            g["which"][k * rows:(k + 1) * rows, :] = 7
        g["done"][k] = False


# -- the store ------------------------------------------------------------------------------------------
def test_store_is_the_in_memory_map_and_reads_back(tmp_path, ref36):
    path = tmp_path / "map.zarr"
    fm = flip_map(BENCH, 36, t_end=6.0, store=path)
    assert same(fm, ref36)
    for key in ("integrated", "skipped_energy", "mirrored", "steps", "rejected", "failed", "flipped"):
        assert fm.stats[key] == ref36.stats[key], key
    assert fm.settings == ref36.settings
    assert fm.stats["store"] == str(path) and fm.stats["chunks_computed"] == fm.stats["chunks"]
    assert fm.stats["chunks_resumed"] == 0 and not (path / LOCK_NAME).exists()  # lock released
    # the template: arrays, coordinates, settings and their fingerprint
    g = zarr.open_group(str(path), mode="r")
    settings = flip_settings(BENCH, 36, t_end=6.0, plane=("phi", "psi"), ranges=((-math.pi, math.pi), (-math.pi, math.pi)),
                             held=(0.0, 0.0), rtol=1e-10, atol=1e-10, max_steps=fm.settings["max_steps"], shortcuts=True)
    assert g.attrs["fingerprint"] == fingerprint(settings) == fm.stats["fingerprint"]
    assert json.loads(g.attrs["settings"]) == settings and g.attrs["complete"] is True
    assert settings["params"]["alpha"] == 0.6 and settings["skewpend_version"]
    rows = g.attrs["chunk_rows"]
    assert g["flip_time"].chunks == (rows, 36) and g["which"].chunks == (rows, 36)
    assert np.array_equal(g["phi0"][:], fm.phi0[:, 0]) and bool(np.all(g["done"][:]))
    back = open_flip_map(path)
    assert same(back, fm) and back.settings == fm.settings and back.stats == fm.stats and back.params == BENCH
    xr = pytest.importorskip("xarray")
    if int(zarr.__version__.split(".")[0]) < 3:
        return  # pragma: no cover - today's xarray reads Zarr 2's stores only through Zarr 3
    ds = xr.open_zarr(path, consolidated=False)
    assert ds["flip_time"].dims == ("phi0", "psi0") and ds["flip_time"].attrs["units"] == "s"
    np.testing.assert_array_equal(ds["flip_time"].values, fm.flip_time)


@pytest.mark.parametrize("n, window, shortcuts", [
    (30, None, True),                       # symmetric: chunks paired with their mirrors
    (25, None, True),                       # odd n: the middle row holds the cell that is its own mirror
    (30, ((-3.0, 2.5), (-2.0, 3.1)), True),  # a window: no symmetry
    (24, None, False),                      # every cell integrated
])
def test_store_does_not_depend_on_chunks_or_workers(tmp_path, n, window, shortcuts):
    kw = dict(t_end=5.0, shortcuts=shortcuts)
    if window:
        kw.update(phi_range=window[0], psi_range=window[1])
    ref = flip_map(BENCH, n, **kw)
    layouts = set()
    for i, (chunk_size, workers) in enumerate(((n, 1), (3 * n, 2), (n * n // 2, 2), (n * n, 1), (None, 2))):
        fm = flip_map(BENCH, n, store=tmp_path / f"m{i}.zarr", chunk_size=chunk_size, workers=workers, **kw)
        assert same(fm, ref), (chunk_size, workers)
        assert fm.stats["integrated"] + fm.stats["mirrored"] + fm.stats["skipped_energy"] == n * n
        assert fm.stats["integrated"] == ref.stats["integrated"] and fm.stats["steps"] == ref.stats["steps"]
        layouts.add(fm.stats["chunks"])
    assert len(layouts) >= 3


def test_chunk_layout():
    assert chunk_rows(128) == 16 and chunk_rows(127) == 1  # a divisor of n, at least 8 chunks
    assert chunk_rows(4096) == 16  # at most 65536 cells per chunk
    assert chunk_rows(30, chunk_size=100) == 3 and chunk_rows(30, chunk_size=10) == 1
    assert chunk_rows(30, chunk_size=10**6) == 30
    for n, sym in ((1, True), (2, True), (5, True), (6, True), (5, False)):
        groups = row_groups(n, sym)
        assert sorted(r for g in groups for r in g) == list(range(n))  # every row in exactly one group
        assert all(g == (g[0],) and (not sym or g[0] == n - 1 - g[0]) or g == (g[0], n - 1 - g[0]) for g in groups)
    units = work_units(row_groups(128, True), threads=2)
    assert len(units) == 2 * UNITS_PER_WORKER and sorted(r for u in units for r in u) == list(range(128))
    assert all(n_rows == 128 // len(units) for n_rows in map(len, units))  # whole pairs of mirror rows each


# -- resume -----------------------------------------------------------------------------------------------
_RUN = """
import sys, time, skewpend
from skewpend.analysis.flipmap import flip_map
p = skewpend.Parameters(a=1.0, b=0.8, m1=1.0, m2=0.7, alpha=0.6, g=9.81)
flip_map(p, 8, t_end=1.0)  # the flip kernel, compiled or loaded
def progress(done, total):
    print(done, flush=True)
    time.sleep(0.05)  # a slow run: many chunks written while the test watches
flip_map(p, 36, t_end=6.0, workers=1, chunk_size=36, store=sys.argv[1], progress=progress)
print("finished", flush=True)
"""


def _start_and_stop(path: Path, sig: int, after: int) -> subprocess.CompletedProcess:
    """Run a stored map in a subprocess; send ``sig`` once ``after`` chunks are reported written."""
    proc = subprocess.Popen([sys.executable, "-c", _RUN, str(path)], stdout=subprocess.PIPE, stderr=subprocess.PIPE,
                            text=True)
    try:
        lines = [proc.stdout.readline().strip() for _ in range(after + 1)]
        assert "finished" not in lines and all(lines), lines
        proc.send_signal(sig)
        out, err = proc.communicate(timeout=30)
    finally:
        if proc.poll() is None:
            proc.kill()
            proc.wait()
    return subprocess.CompletedProcess(proc.args, proc.returncode, out, err)


@pytest.mark.parametrize("sig", [signal.SIGKILL, signal.SIGINT], ids=["kill-9", "ctrl-c"])
def test_an_interrupted_run_resumes_to_the_same_bits(tmp_path, ref36, sig):
    path = tmp_path / "map.zarr"
    res = _start_and_stop(path, sig, after=5)
    assert res.returncode != 0 and "finished" not in res.stdout
    if sig == signal.SIGINT:
        assert "KeyboardInterrupt" in res.stderr and not (path / LOCK_NAME).exists()
    else:
        assert (path / LOCK_NAME).exists()  # left by the killed run: taken over below
    with RowStore.open(path, kind=KIND) as st:
        done = st.done()
    assert 0 < done.sum() < done.size == 36  # one row a chunk, some written
    assert not open_flip_map_allowed(path)
    calls = []
    fm = flip_map(BENCH, 36, t_end=6.0, store=path, resume=True, workers=2, chunk_size=5000,
                  progress=lambda d, t: calls.append(d))
    assert same(fm, ref36)
    assert fm.stats["chunks_resumed"] == done.sum() and fm.stats["chunks_computed"] == 36 - done.sum()
    assert fm.stats["chunks"] == 36  # the store's layout, whatever chunk_size says
    assert calls[0] == done.sum() * 36 and calls[-1] == 36 * 36
    assert fm.stats["integrated"] == ref36.stats["integrated"] and fm.stats["steps"] == ref36.stats["steps"]
    assert same(open_flip_map(path), ref36)


def open_flip_map_allowed(path) -> bool:
    try:
        open_flip_map(path)
    except ParameterError as exc:
        assert "not complete" in str(exc)
        return False
    return True


def test_a_partial_store_is_completed(tmp_path, ref36):
    path = tmp_path / "map.zarr"
    flip_map(BENCH, 36, t_end=6.0, store=path, chunk_size=36 * 3)  # 12 chunks of 3 rows
    _mark_not_done(path, [0, 5, 11])  # 0 and 11 are mirrors: one unit; 5 alone in its unit (with 6)
    # a done flag cut short (a kill while it was written): not trusted
    flag = next(p for p in (path / "done").rglob("*") if p.is_file() and p.name == "7")
    flag.write_bytes(b"\x00\x01")
    fm = flip_map(BENCH, 36, t_end=6.0, store=path, resume=True)
    assert same(fm, ref36)
    assert fm.stats["chunks_computed"] == 4 and fm.stats["chunks_resumed"] == 8
    assert fm.stats["integrated"] == ref36.stats["integrated"] and fm.stats["mirrored"] == ref36.stats["mirrored"]
    again = flip_map(BENCH, 36, t_end=6.0, store=path, resume=True)  # complete: nothing computed
    assert same(again, ref36) and again.stats["chunks_computed"] == 0


def test_resume_of_a_missing_store_starts_it(tmp_path, ref36):
    fm = flip_map(BENCH, 36, t_end=6.0, store=tmp_path / "new.zarr", resume=True)
    assert same(fm, ref36) and fm.stats["chunks_resumed"] == 0


# -- refusals: other settings, existing paths, bad input ------------------------------------------------
def _snapshot(path: Path):
    return {p.relative_to(path): p.read_bytes() for p in sorted(path.rglob("*")) if p.is_file()}


@pytest.mark.parametrize("change, named", [
    (dict(t_end=7.0), "t_end 7.0 (store: 6.0)"),
    (dict(params=BENCH.replace(alpha=0.5)), "alpha 0.5 (store: 0.6)"),
    (dict(n=40), "n 40 (store: 36)"),
    (dict(rtol=1e-9), "rtol"),
    (dict(shortcuts=False), "shortcuts"),
    (dict(phi_range=(-3.0, 3.0)), "phi_range"),
])
def test_resume_with_other_settings_is_refused(tmp_path, change, named):
    path = tmp_path / "map.zarr"
    flip_map(BENCH, 36, t_end=6.0, store=path)
    _mark_not_done(path, [3], garbage=False)
    before = _snapshot(path)
    kw = dict(t_end=6.0)
    kw.update({k: v for k, v in change.items() if k not in ("params", "n")})
    with pytest.raises(ParameterError, match="made with other settings") as exc:
        flip_map(change.get("params", BENCH), change.get("n", 36), store=path, resume=True, **kw)
    assert named in str(exc.value) and "\n" not in str(exc.value)
    assert _snapshot(path) == before  # untouched


def test_an_existing_path_is_refused_without_resume(tmp_path):
    path = tmp_path / "map.zarr"
    flip_map(BENCH, 12, t_end=2.0, store=path)
    before = _snapshot(path)
    with pytest.raises(ParameterError, match=r"exists; resume it \(--resume\) or choose another path"):
        flip_map(BENCH, 12, t_end=2.0, store=path)
    with pytest.raises(ParameterError, match="exists"):  # whatever settings
        flip_map(BENCH, 8, t_end=1.0, store=path)
    assert _snapshot(path) == before
    other = tmp_path / "other.zarr"
    other.mkdir()
    (other / "notes.txt").write_text("mine")
    with pytest.raises(ParameterError, match="exists"):
        flip_map(BENCH, 8, t_end=1.0, store=other)
    with pytest.raises(ParameterError, match="not a skewpend flip map store"):
        flip_map(BENCH, 8, t_end=1.0, store=other, resume=True)
    afile = tmp_path / "file.zarr"
    afile.write_text("x")
    with pytest.raises(ParameterError, match="not a directory"):
        flip_map(BENCH, 8, t_end=1.0, store=afile, resume=True)
    assert (other / "notes.txt").read_text() == "mine" and afile.read_text() == "x"


@pytest.mark.parametrize("kwargs, match", [
    (dict(store="map.nc"), r"ending in \.zarr"),
    (dict(store="no/such/dir/map.zarr"), "does not exist"),
    (dict(store=3.5), "store must be a path"),
    (dict(resume=True), "resume needs a store"),
    (dict(store="map.zarr", resume="yes"), "resume must be True or False"),
    (dict(store="map.zarr", t_end=-1.0), "t_end must be a positive"),
    (dict(store="map.zarr", phi_range=(1.0, -1.0)), "inverted"),
])
def test_bad_store_input_is_refused_and_nothing_is_written(tmp_path, monkeypatch, kwargs, match):
    monkeypatch.chdir(tmp_path)
    with pytest.raises(ParameterError, match=match):
        flip_map(BENCH, 8, **{"t_end": 1.0, **kwargs})
    assert list(tmp_path.iterdir()) == []


def test_a_store_in_use_is_refused_until_its_process_is_gone(tmp_path):
    path = tmp_path / "map.zarr"
    flip_map(BENCH, 12, t_end=2.0, store=path)
    _mark_not_done(path, [0])
    holder = subprocess.Popen([sys.executable, "-c", "import time; time.sleep(60)"])
    try:
        import socket

        (path / LOCK_NAME).write_text(json.dumps({"host": socket.gethostname(), "pid": holder.pid}))
        with pytest.raises(ParameterError, match=f"in use by process {holder.pid}"):
            flip_map(BENCH, 12, t_end=2.0, store=path, resume=True)
    finally:
        holder.kill()
        holder.wait()
    fm = flip_map(BENCH, 12, t_end=2.0, store=path, resume=True)  # its holder is gone: taken over
    assert fm.stats["chunks_computed"] == 1 and not (path / LOCK_NAME).exists()


def test_open_flip_map_refuses_what_it_cannot_read(tmp_path):
    with pytest.raises(ParameterError, match="does not exist"):
        open_flip_map(tmp_path / "none.zarr")
    with pytest.raises(ParameterError, match=r"\.zarr or a file ending in \.nc"):
        open_flip_map(tmp_path / "map.csv")


# -- NetCDF -------------------------------------------------------------------------------------------------
def test_netcdf_is_written_atomically_and_reads_back(tmp_path, ref36):
    pytest.importorskip("netCDF4")
    path = tmp_path / "map.nc"
    assert ref36.to_netcdf(path) == path
    assert [p.name for p in tmp_path.iterdir()] == ["map.nc"]  # no temporary file left
    back = open_flip_map(path)
    assert same(back, ref36) and back.settings == ref36.settings and back.params == BENCH
    xr = pytest.importorskip("xarray")
    with xr.open_dataset(path) as ds:
        np.testing.assert_array_equal(ds["flip_time"].values, ref36.flip_time)
        assert ds["which"].dtype == np.int8 and ds.attrs["t_end"] == 6.0
    with pytest.raises(ParameterError, match=r"ending in \.nc"):
        ref36.to_netcdf(tmp_path / "map.txt")


def test_netcdf_failure_leaves_nothing(tmp_path, ref36, monkeypatch):
    netCDF4 = pytest.importorskip("netCDF4")

    def boom(self, *a, **k):
        raise KeyboardInterrupt

    monkeypatch.setattr(netCDF4.Dataset, "setncatts", boom)
    with pytest.raises(KeyboardInterrupt):
        ref36.to_netcdf(tmp_path / "map.nc")
    assert list(tmp_path.iterdir()) == []


# -- without the extra ------------------------------------------------------------------------------------
def test_without_zarr_the_error_names_the_extra(tmp_path, monkeypatch):
    monkeypatch.setitem(sys.modules, "zarr", None)
    with pytest.raises(SkewpendError, match=r'pip install "skewpend\[cluster\]"'):
        flip_map(BENCH, 8, t_end=1.0, store=tmp_path / "map.zarr")
    assert list(tmp_path.iterdir()) == []


def test_in_memory_maps_import_neither_zarr_nor_dask():
    code = ("import sys, skewpend\n"
            "skewpend.flip_map(skewpend.Parameters(a=1.0, b=0.8, m1=1.0, m2=0.7, alpha=0.6, g=9.81), 8, t_end=1.0)\n"
            "print([m for m in ('zarr', 'dask', 'distributed') if m in sys.modules])")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True).stdout
    assert out.strip().splitlines()[-1] == "[]"
