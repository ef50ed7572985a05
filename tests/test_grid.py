"""The grid driver (numeric/grid.py), the result protocol (results.py) and damaged stores.

* a toy job (pure NumPy, no kernel) shows the protocol a new analysis plugs in with, and that
  the driver's results do not depend on chunks, workers or a store;
* the Lyapunov map gained stores, resume and NetCDF from the driver: same bits either way;
* a store whose chunk files were deleted, emptied or overwritten is repaired on resume (the
  damaged chunks recomputed, bitwise the same map), refused when read, and damage that cannot
  be repaired (array metadata, a deleted array) is one ParameterError;
* a grid with failed cells says so in its status (PARTIAL, ok False), and NetCDF output on a
  full disk is one SkewpendError with no file left.
"""

from __future__ import annotations

import dataclasses
import json
import os
import shutil
import subprocess
import sys
from typing import ClassVar

import numpy as np
import pytest

from skewpend import ParameterError, SkewpendError
from skewpend.numeric.grid import ArraySpec, GridJob, run_grid
from skewpend.status import Status

zarr = pytest.importorskip("zarr")

from skewpend.config import reference_parameters  # noqa: E402
from helpers import completed  # noqa: E402
BENCH = reference_parameters()  # the reference case: a = 1, b = 0.8, m1 = 1, m2 = 0.7, alpha = 0.6, g = 9.81


# -- a toy job: the protocol without any kernel ------------------------------------------------------------
@dataclasses.dataclass(frozen=True)
class Toy(GridJob):
    rows: int
    cols: int
    version: str = "toy"

    kind: ClassVar[str] = "toy grid"
    what: ClassVar[str] = "a toy grid"
    stat_names: ClassVar[tuple] = ("cells", "sum")

    def shape(self):
        return self.rows, self.cols

    def arrays(self):
        return {"value": ArraySpec("float64", np.nan, {"units": "1"}), "parity": ArraySpec("int8", -1, {})}

    def coords(self):
        return {"x": (np.arange(self.rows, dtype=float), {}), "y": (np.arange(self.cols, dtype=float), {})}

    def settings(self):
        return {"rows": self.rows, "cols": self.cols}

    def compute(self, state, rows, cancel=None):
        value = np.sin(rows[:, None] * 1.3 + np.arange(self.cols)[None, :] * 0.7)
        stats = np.column_stack([np.full(rows.size, self.cols), value.sum(axis=1)])
        return {"value": value, "parity": (rows[:, None] + np.arange(self.cols)[None, :]) % 2}, stats

    def result(self, run):
        return run


def _toy_expected(rows, cols):
    i, j = np.meshgrid(np.arange(rows), np.arange(cols), indexing="ij")
    return np.sin(i * 1.3 + j * 0.7), (i + j) % 2


def test_a_toy_job_runs_in_memory_and_in_a_store_with_the_same_result(tmp_path):
    job = Toy(rows=24, cols=5)
    value, parity = _toy_expected(24, 5)
    seen = []
    mem = run_grid(job, workers=2, progress=lambda done, total: seen.append((done, total)))
    assert np.array_equal(mem.data["value"], value) and np.array_equal(mem.data["parity"], parity)
    assert seen[0] == (0, 120) and seen[-1] == (120, 120) and all(a <= b for (a, _), (b, _) in zip(seen, seen[1:]))
    assert mem.totals(Toy.stat_names)["cells"] == 120 and mem.info["store"] is None
    for chunk_size, workers in ((5, 1), (15, 2), (60, 2), (None, 3)):
        run = run_grid(job, workers=workers, store=tmp_path / f"t{chunk_size}.zarr", chunk_size=chunk_size)
        assert run.data["value"].tobytes() == mem.data["value"].tobytes()
        assert run.info["chunks"] * run.info["chunk_rows"] == 24
    again = run_grid(job, workers=1, store=tmp_path / "t5.zarr", resume=True)
    assert again.info["chunks_computed"] == 0 and again.data["value"].tobytes() == mem.data["value"].tobytes()
    with pytest.raises(ParameterError, match="exists; resume it"):
        run_grid(job, workers=1, store=tmp_path / "t5.zarr")
    with pytest.raises(ParameterError, match="other settings: rows 12"):
        run_grid(Toy(rows=12, cols=5), workers=1, store=tmp_path / "t5.zarr", resume=True)


# -- the Lyapunov map: stores for free ------------------------------------------------------------------------
def test_lyapunov_map_store_resume_and_files_are_bitwise_the_same(tmp_path):
    from skewpend.analysis.lyapunov import lyapunov_map, open_lyapunov_map

    kw = dict(t_end=4.0, phi_range=(-2.0, 2.0), psi_range=(-2.5, 2.5))
    ref = lyapunov_map(BENCH, 8, workers=1, **kw)
    assert ref.ok and ref.status is Status.SUCCESS and ref.stats["cells"] == 64 and np.isfinite(ref.exponent).all()
    path = tmp_path / "lm.zarr"
    stored = lyapunov_map(BENCH, 8, workers=2, store=path, **kw)
    assert stored.exponent.tobytes() == ref.exponent.tobytes() and stored.stats["store"] == str(path)
    back = open_lyapunov_map(path)
    assert back.exponent.tobytes() == ref.exponent.tobytes() and back.settings == stored.settings and back.ok
    pytest.importorskip("netCDF4")
    nc = ref.to_netcdf(tmp_path / "lm.nc")
    again = open_lyapunov_map(nc)
    assert again.exponent.tobytes() == ref.exponent.tobytes() and again.params == ref.params


# -- damaged stores -------------------------------------------------------------------------------------------
@pytest.fixture(scope="module")
def finished(tmp_path_factory):
    """A finished 16 x 16 flip-map store (8 chunks of 2 rows) and the map in memory."""
    from skewpend.analysis.flipmap import flip_map

    d = tmp_path_factory.mktemp("stores")
    kw = dict(t_end=3.0, chunk_size=32)
    ref = flip_map(BENCH, 16, workers=1, **kw)
    flip_map(BENCH, 16, workers=1, store=d / "m.zarr", **kw)
    assert np.isfinite(ref.flip_time).sum() > 20  # there is something to lose
    return d / "m.zarr", ref, kw


def _copy(finished, tmp_path):
    src, ref, kw = finished
    dst = tmp_path / "m.zarr"
    shutil.copytree(src, dst)
    return dst, ref, kw


def _chunk_file(store, array, k):
    return store / array / "c" / str(k) / "0"


def _nonempty_chunks(ref, rows=2):
    """Chunks whose flip times are not all NaN (a chunk of fill values need not exist as a file)."""
    return [k for k in range(8) if np.isfinite(ref.flip_time[k * rows:(k + 1) * rows]).any()]


@pytest.mark.parametrize("damage", ["delete", "empty", "random"])
def test_a_damaged_chunk_is_recomputed_on_resume(finished, tmp_path, damage):
    from skewpend.analysis.flipmap import flip_map, open_flip_map

    path, ref, kw = _copy(finished, tmp_path)
    ks = _nonempty_chunks(ref)[:2]
    rng = np.random.default_rng(7)
    for k in ks:
        f = _chunk_file(path, "flip_time", k)
        if damage == "delete":
            f.unlink()
        elif damage == "empty":
            f.write_bytes(b"")
        else:
            f.write_bytes(rng.integers(0, 256, f.stat().st_size, dtype=np.uint8).tobytes())
    with pytest.raises(ParameterError, match="damaged|cannot be read"):
        open_flip_map(path)
    fm = flip_map(BENCH, 16, workers=1, store=path, resume=True, **kw)
    assert fm.flip_time.tobytes() == ref.flip_time.tobytes() and fm.which.tobytes() == ref.which.tobytes()
    assert fm.stats["chunks_repaired"] == 2 and fm.stats["chunks_computed"] == 2
    assert open_flip_map(path).flip_time.tobytes() == ref.flip_time.tobytes()


@pytest.mark.parametrize("damage", ["array metadata", "deleted array", "group metadata"])
def test_damage_that_cannot_be_repaired_is_one_clear_error(finished, tmp_path, damage):
    from skewpend.analysis.flipmap import flip_map, open_flip_map

    path, ref, kw = _copy(finished, tmp_path)
    if damage == "array metadata":
        (path / "which" / "zarr.json").write_text("{not json")
    elif damage == "deleted array":
        shutil.rmtree(path / "which")
    else:
        (path / "zarr.json").write_text("")
    for call in (lambda: flip_map(BENCH, 16, workers=1, store=path, resume=True, **kw), lambda: open_flip_map(path)):
        with pytest.raises(ParameterError) as info:
            call()
        assert "damaged" in str(info.value) and "\n" not in str(info.value)


def test_the_cli_resume_of_a_damaged_store_is_exit_2_or_repaired(finished, tmp_path):
    path, ref, kw = _copy(finished, tmp_path)
    (path / "flip_time" / "zarr.json").write_text("garbage")
    r = completed(["flipmap", "--n", "16", "--t-end", "3", "--out", path, "--resume", "--quiet"], timeout=120)
    assert r.returncode == 2 and len(r.stderr.strip().splitlines()) == 1 and "damaged" in r.stderr, r.stderr


# -- statuses -------------------------------------------------------------------------------------------------
def test_failed_cells_make_a_partial_status():
    from skewpend.analysis.flipmap import flip_map

    with pytest.warns(RuntimeWarning, match="failed"):
        fm = flip_map(BENCH, 6, t_end=5.0, max_steps=20, shortcuts=False)
    assert fm.status is Status.PARTIAL and not fm.ok and fm.stats["failed"] > 0
    assert f"{fm.stats['failed']} of 36 cells failed" in fm.message
    assert "flip map" in fm.summary() and str(fm.stats["failed"]) in fm.summary()
    good = flip_map(BENCH, 6, t_end=1.0)
    assert good.ok and good.status == 0 and good.message == "all 36 cells completed"


def test_a_chaos_diagram_with_failed_trajectories_is_partial():
    from skewpend.analysis.chaos import chaos_diagram

    d = chaos_diagram(BENCH, alpha=[0.0], energy=[12.0], samples=3, t_end=5.0, max_steps=30, workers=1)
    assert d.status is Status.PARTIAL and not d.ok and d.stats["failed"] == 3
    assert "nan" not in d.table()


def test_status_codes_and_messages():
    assert [int(s) for s in Status] == list(range(9)) and Status.of(5) is Status.SHORT
    assert all(s.message for s in Status) and Status.SUCCESS.ok and not Status.PARTIAL.ok
    with pytest.raises(ValueError, match="unknown status code 99"):
        Status.of(99)


# -- files ----------------------------------------------------------------------------------------------------
def test_settings_have_one_strict_encoding():
    from skewpend.results import canonical_json, fingerprint

    a = {"b": (1, 2.5), "a": np.float64(0.1), "n": np.int64(3), "x": float("nan")}
    assert canonical_json(a) == '{"a":0.1,"b":[1,2.5],"n":3,"x":null}'
    assert fingerprint(a) == fingerprint(dict(reversed(list(a.items())))) and len(fingerprint(a)) == 64
    json.loads(canonical_json(a))  # strict JSON


def test_without_netcdf4_no_empty_file_is_left(tmp_path, monkeypatch):
    from skewpend.io import TrajectoryWriter

    monkeypatch.setitem(sys.modules, "netCDF4", None)
    with pytest.raises(SkewpendError, match="netCDF4"):
        with TrajectoryWriter(tmp_path / "s.nc"):
            pass
    assert list(tmp_path.iterdir()) == []


@pytest.fixture
def full_disk(tmp_path):
    """A 256 kB tmpfs (needs root; else skipped with the reason)."""
    if os.geteuid() != 0 or shutil.which("mount") is None:
        pytest.skip("a full disk is simulated with a small tmpfs, which needs root")
    mnt = tmp_path / "full"
    mnt.mkdir()
    r = subprocess.run(["mount", "-t", "tmpfs", "-o", "size=256k", "tmpfs", str(mnt)], capture_output=True)
    if r.returncode != 0:
        pytest.skip(f"cannot mount a tmpfs here: {r.stderr.decode().strip()}")
    try:
        yield mnt
    finally:
        subprocess.run(["umount", "-l", str(mnt)], capture_output=True)  # lazy: HDF5 may hold the failed file open


def test_netcdf_on_a_full_disk_is_one_error_and_no_file(full_disk):
    pytest.importorskip("netCDF4")
    from skewpend.analysis.flipmap import flip_map

    fm = flip_map(BENCH, 300, t_end=0.05, shortcuts=False, workers=2)
    rng = np.random.default_rng(3)  # incompressible values: more than the disk holds
    fm = dataclasses.replace(fm, flip_time=rng.random((300, 300)))
    with pytest.raises(SkewpendError) as info:
        fm.to_netcdf(full_disk / "m.nc")
    assert "cannot write" in str(info.value) and "\n" not in str(info.value)
    assert list(full_disk.iterdir()) == []


# -- work that cannot finish is refused before it starts ------------------------------------------------------
@pytest.mark.parametrize("call", [
    lambda: __import__("skewpend.analysis.flipmap", fromlist=["x"]).flip_map(BENCH, 8, t_end=1e308),
    lambda: __import__("skewpend.analysis.flipmap", fromlist=["x"]).flip_map(BENCH, 8, t_end=1e9),
    lambda: __import__("skewpend.analysis.chaos", fromlist=["x"]).chaos_diagram(BENCH, samples=2, t_end=1e12),
    lambda: __import__("skewpend.analysis.lyapunov", fromlist=["x"]).lyapunov_map(BENCH, 4, t_end=1e12),
    lambda: __import__("skewpend.analysis.flipmap", fromlist=["x"]).flip_map(BENCH, 8, t_end=1e5, max_steps=1000),
    lambda: __import__("skewpend.analysis.poincare", fromlist=["x"]).poincare(BENCH.replace(a=1e100), 5.0),
    lambda: __import__("skewpend.analysis.flipmap", fromlist=["x"]).flip_map(BENCH.replace(c1=1e15), 8),
    lambda: __import__("skewpend.analysis.flipmap", fromlist=["x"]).flip_map(BENCH.replace(b=1e-15), 8),
    lambda: __import__("skewpend.analysis.lyapunov", fromlist=["x"]).lyapunov_map(BENCH.replace(c1=1e15), 4, t_end=5.0),
], ids=["flip-1e308", "flip-1e9", "chaos-1e12", "lyapunov-map-1e12", "flip-small-cap", "poincare-a-1e100",
        "flip-c1-1e15", "flip-b-1e-15", "lyapunov-map-c1-1e15"])
def test_infeasible_grids_are_refused_at_once_with_the_estimate(call, monkeypatch):
    """Refused by the trial run, before the work: the grid driver (and the Poincare section's
    orbits) are never entered -- checked by what is called, not by a clock (a 5 s limit failed
    on a loaded machine for the stiff c1 = 1e15 map, whose trials now stop once their lower bound
    of the rate refuses the work)."""
    import skewpend.numeric.ensemble as ensemble
    import skewpend.numeric.grid as grid

    def started(*args, **kwargs):
        raise AssertionError("the work started before the refusal")

    monkeypatch.setattr(grid, "run_grid", started)
    monkeypatch.setattr(ensemble, "run_chunks", started)  # the Poincare section's orbits
    with pytest.raises(ParameterError) as info:
        call()
    message = str(info.value)
    assert "cannot finish" in message and "steps per trajectory" in message and "max_steps" in message
    assert "\n" not in message and "nan" not in message and "inf" not in message.replace("info", "")


def test_a_generous_t_max_is_not_refused():
    """t_max only bounds a section: orbits that make their crossings early are not refused for it."""
    from skewpend.analysis.poincare import poincare

    sec = poincare(BENCH, 5.0, n_orbits=2, n_crossings=5, t_max=1e12)
    assert sec.ok and np.all(sec.crossings == 5)


@pytest.mark.parametrize("suffix,t_end", [(".csv", 5.0), (".nc", 5.0), (".csv", 0.04), (".nc", 0.1)])
def test_a_trajectory_on_a_full_disk_is_one_error_and_no_file(full_disk, suffix, t_end):
    """Refused up front from the size estimate, or failing while written: either way one line and
    nothing left behind (the disk is filled but for 16 kB first)."""
    if suffix == ".nc":
        pytest.importorskip("netCDF4")
    from skewpend import simulate

    filler = full_disk / "filler"
    with open(filler, "wb") as fh:
        try:
            while True:
                fh.write(b"\0" * 4096)
                fh.flush()
                if shutil.disk_usage(full_disk).free < 16 * 1024:
                    break
        except OSError:
            pass
    with pytest.raises(SkewpendError) as info:
        simulate(BENCH, [1.0, 0.5, 0.0, 0.0], t_end, dt_out=1e-3, out=full_disk / f"s{suffix}")
    assert "\n" not in str(info.value) and str(full_disk) in str(info.value)
    assert sorted(p.name for p in full_disk.iterdir()) == ["filler"]


@pytest.mark.parametrize("kw", [dict(t_end=1e12), dict(t_end=10.0, y0=[1.2, -0.8, 1e10, 0.0]),
                                dict(t_end=1.0, params=BENCH.replace(tau2=1e15)), dict(t_end=1000.0, params=BENCH.replace(c1=1e10))],
                         ids=["t-end-1e12", "dphi0-1e10", "tau2-1e15", "c1-1e10"])
def test_a_lyapunov_run_that_cannot_finish_is_refused_after_its_first_call(kw):
    """As simulate: the first bounded call's step rate gives the estimate (issue 20 class 1) -- the work
    before the refusal counted, not timed (issue 36): no progress after a call (the refusal comes
    before the first call's), and the estimate made from one bounded call's steps (a budget of
    thousands; finishing would take more than max_steps)."""
    import re

    from skewpend.analysis.lyapunov import lyapunov

    params = kw.pop("params", BENCH)
    y0 = kw.pop("y0", [1.2, -0.8, 0.0, 0.0])
    calls = []
    with pytest.raises(ParameterError, match=r"needs about .* steps at this tolerance .* more than max_steps") as exc:
        lyapunov(params, y0, progress=lambda t, total: calls.append(t), **kw)
    assert calls == []
    assert int(re.search(r"from the first (\d+) steps", str(exc.value)).group(1)) < 100_000


def test_a_lyapunov_start_that_overflows_is_refused_as_simulate_refuses_it():
    from skewpend import simulate
    from skewpend.analysis.lyapunov import lyapunov

    for call in (lambda: simulate(BENCH, [1.2, -0.8, 1e308, 0.0], 1.0),
                 lambda: lyapunov(BENCH, [1.2, -0.8, 1e308, 0.0], t_end=1.0)):
        with pytest.raises(ParameterError, match="is not finite .overflow."):
            call()


def test_a_private_kernel_cache_leaves_nothing_behind(tmp_path):
    """An unwritable cache: the run compiles into a private temporary directory, removed at exit."""
    blocker = tmp_path / "not-a-directory"
    blocker.write_text("")
    tmpdir = tmp_path / "tmp"
    tmpdir.mkdir()
    r = completed(["simulate", "--t-end", "1"], env=dict(SKEWPEND_CACHE_DIR=str(blocker), TMPDIR=str(tmpdir)),
                  timeout=120)
    assert r.returncode == 0, r.stderr
    assert "not cached" in r.stdout and list(tmpdir.iterdir()) == []


def test_a_compiler_that_produces_nothing_is_one_clear_line(tmp_path):
    r = completed(["simulate", "--t-end", "1"], env=dict(CC="/bin/true", SKEWPEND_CACHE_DIR=str(tmp_path / "cache")),
                  timeout=120)
    # the first-use notice (progress: a build takes seconds), then the error in one line
    lines = r.stderr.strip().splitlines()
    assert r.returncode == 2 and len(lines) == 2 and lines[0].startswith("skewpend: compiling the model's kernels")
    assert "'/bin/true' reported success but produced no shared library" in lines[1]


def test_a_diagram_of_subnormal_masses_is_refused_in_one_line():
    from skewpend.analysis.chaos import chaos_diagram

    with pytest.raises(ParameterError, match="m2 must be a normal number"):  # Parameters refuses it first
        chaos_diagram(BENCH.replace(m2=5e-324), samples=2, t_end=5.0)


@pytest.mark.parametrize("t_end", [5e-324, 1e-310])
def test_a_subnormal_duration_is_refused_not_flushed_to_zero(t_end):
    """The compiled code may treat a subnormal time as 0 (a 'bad arguments' internal error
    before this rule); every duration and tolerance is a normal float or refused."""
    from skewpend import flip_map, lyapunov, simulate

    for call in (lambda: flip_map(BENCH, 4, t_end=t_end), lambda: lyapunov(BENCH, [1.0, 1.0, 0.0, 0.0], t_end=t_end),
                 lambda: simulate(BENCH, [1.0, 1.0, 0.0, 0.0], t_end)):
        with pytest.raises(ParameterError, match="smallest normal float"):
            call()


def test_trial_runs_never_last_a_subnormal_time():
    from skewpend.numeric.grid import PROBE_TRIES, probe_durations

    times = list(probe_durations(1e-300, BENCH))
    assert times == pytest.approx([1e-300, 1e-303, 1e-306], rel=1e-12)  # the next, 1e-309, is subnormal
    long = list(probe_durations(1e9, BENCH))
    assert len(long) == PROBE_TRIES and long[0] == pytest.approx(20 * np.sqrt(1.8 / 9.81))
    assert all(b == pytest.approx(a * 1e-3) for a, b in zip(long, long[1:]))
