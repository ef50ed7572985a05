"""Sturdy in a user's hands: Ctrl-C, long runs, memory, progress, files, the kernel cache.

Real processes where the behaviour is about processes (signals, exit status, peak memory).
Every run that could take long is bounded by a timeout; no test depends on absolute times
beyond generous upper bounds on reaction to Ctrl-C.
"""

from __future__ import annotations

import os
import signal
import stat
import subprocess
import sys
import time

import numpy as np
import pytest

import skewpend
from skewpend import Parameters

P = Parameters(a=1.0, b=0.8, m1=1.0, m2=0.7, alpha=0.6, g=9.81, c1=0.0, c2=0.0, tau1=0.0, tau2=0.0)
Y0 = (1.2, -0.8, 0.0, 0.0)


def cli(*args):
    return [sys.executable, "-m", "skewpend", *map(str, args)]


def run(args, cwd=None, env=None, timeout=300):
    """``args`` as a process; its stage lines (issue 36: one per stage on stderr off a terminal) are
    in ``.stages``, apart from the rest of stderr."""
    from helpers import without_stages

    proc = subprocess.run(args, capture_output=True, text=True, cwd=cwd, env={**os.environ, **(env or {})}, timeout=timeout)
    proc.stderr, proc.stages = without_stages(proc.stderr)
    return proc


def _interrupt(args, cwd, after: float, env=None):
    """Start ``args``, wait until it is integrating (``after`` s), send SIGINT; (proc, out, err, seconds to exit)."""
    proc = subprocess.Popen(args, cwd=cwd, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
                            env={**os.environ, **(env or {})})
    time.sleep(after)
    assert proc.poll() is None, proc.communicate()
    sent = time.monotonic()
    proc.send_signal(signal.SIGINT)
    out, err = proc.communicate(timeout=60)
    from helpers import without_stages

    return proc, out, without_stages(err)[0], time.monotonic() - sent


# -- Ctrl-C ---------------------------------------------------------------------------------------------
#: The bound on the seconds from a signal to the exit: a hang guard, not a speed test (issue 36: no test
#: asserts an absolute time) -- the runs below would take half an hour or more (1e9 steps of 1e-4 s), the
#: compiled loop works in ~0.05 s chunks, and a loaded 2-core machine may delay the exit by seconds.
STOP_LIMIT = 20.0
#: A simulation far longer than STOP_LIMIT: 1e9 steps (max_steps raised to allow it); to a file a row a second.
LONG_RUN = ["simulate", "--method", "gauss", "--dt", "1e-4", "--t-end", "1e5", "--max-steps", "1e12"]


@pytest.mark.parametrize("out", ["long.csv", "long.nc", None])
def test_ctrl_c_stops_the_cli_with_status_130_and_no_file(tmp_path, out):
    skewpend.simulate(P, Y0, 0.01)  # the kernel is compiled and cached before the clock starts
    args = LONG_RUN + (["--dt-out", "1", "--out", out] if out else [])
    proc, stdout, stderr, took = _interrupt(cli(*args), tmp_path, after=2.5)
    assert proc.returncode == 130, stderr
    assert stderr.strip().splitlines() == ["skewpend: interrupted"], stderr
    assert took < STOP_LIMIT
    assert list(tmp_path.iterdir()) == []  # neither the output nor a temporary file


# -- SIGTERM gets what Ctrl-C gets (issue 20, class 6) ------------------------------------------------------
def _terminated(args, tmp_path, after: float):
    from helpers import signal_process

    ran, took = signal_process(args, tmp_path, after=after, signum=signal.SIGTERM)
    assert ran.code == 143, ran.report()
    assert ran.err.strip().splitlines() == ["skewpend: terminated"], ran.report()
    assert "Traceback" not in ran.err
    return ran, took


@pytest.mark.parametrize("out", ["long.csv", "long.nc", None])
def test_sigterm_stops_simulate_with_status_143_and_no_file(tmp_path, out):
    skewpend.simulate(P, Y0, 0.01, method="gauss")  # the kernel is compiled and cached before the clock starts
    args = LONG_RUN + (["--dt-out", "1", "--out", out] if out else [])
    _, took = _terminated(args, tmp_path, after=2.5)
    assert took < STOP_LIMIT
    assert list(tmp_path.iterdir()) == []  # neither the output nor a .NAME.skewpend-PID.tmp


@pytest.mark.slow
def test_sigterm_stops_an_ensemble_with_status_143_and_no_file(tmp_path):
    """A flip map on every core (worker threads, chunks in flight) ends as on Ctrl-C: nothing written."""
    skewpend.flip_map(P, 2, t_end=1.0)  # kernels cached before the clock starts
    _, took = _terminated(["flipmap", "--n", "1500", "--t-end", "100", "--out", "map.nc"], tmp_path, after=4.0)
    assert took < STOP_LIMIT  # the whole map (2.25e6 cells) would take hours
    assert list(tmp_path.iterdir()) == []


@pytest.mark.slow
def test_sigterm_while_rendering_an_animation_leaves_no_file_and_no_ffmpeg(tmp_path):
    pytest.importorskip("imageio_ffmpeg")
    from helpers import signal_process

    ran, took = signal_process(["animate", "--t-end", "60", "--out", "m.mp4"], tmp_path, after=1.0,
                               signum=signal.SIGTERM, ready=".m.mp4.*.tmp")
    assert ran.code == 143 and ran.err.strip().splitlines() == ["skewpend: terminated"], ran.report()
    assert took < STOP_LIMIT
    assert list(tmp_path.iterdir()) == []
    ps = subprocess.run(["ps", "-eo", "ppid,args"], capture_output=True, text=True).stdout
    assert "m.mp4" not in ps  # no ffmpeg left writing the video


@pytest.mark.slow
def test_sigterm_stops_lyapunov_with_status_143(tmp_path):
    _, took = _terminated(["lyapunov", "--t-end", "1e5", "--max-steps", "1e12", "--out", "l.json"], tmp_path, after=3.0)
    assert took < STOP_LIMIT
    assert list(tmp_path.iterdir()) == []


def test_ctrl_c_raises_keyboardinterrupt_in_the_python_api(tmp_path):
    code = (
        "import skewpend\n"
        "p = skewpend.Parameters(a=1.0, b=0.8, m1=1.0, m2=0.7, alpha=0.6, g=9.81)\n"
        "skewpend.simulate(p, (1.2, -0.8, 0, 0), 0.01)\n"
        "print('ready', flush=True)\n"
        "try:\n"
        "    skewpend.simulate(p, (1.2, -0.8, 0, 0), 1e5, method='gauss', dt=1e-4, dt_out=1.0, max_steps=10**12,\n"
        "                      out='x.nc')\n"
        "except KeyboardInterrupt:\n"
        "    print('KeyboardInterrupt', flush=True)\n"
    )
    proc, stdout, stderr, took = _interrupt([sys.executable, "-c", code], tmp_path, after=2.5)
    assert proc.returncode == 0, stderr
    assert stdout.split() == ["ready", "KeyboardInterrupt"]
    assert took < STOP_LIMIT
    assert list(tmp_path.iterdir()) == []


# -- memory and long runs ----------------------------------------------------------------------------------
def _peak_rss_mb(args, cwd) -> float:
    proc = subprocess.Popen(args, cwd=cwd, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE)
    _, status, usage = os.wait4(proc.pid, 0)
    assert os.waitstatus_to_exitcode(status) == 0, proc.stderr.read()
    return usage.ru_maxrss / 1024.0  # kB on Linux


@pytest.mark.skipif(sys.platform != "linux", reason="ru_maxrss in kB is Linux's convention")
def test_summary_only_run_keeps_constant_memory(tmp_path):
    """2e5 and 2e6 steps: the same peak memory (keeping 2e6 rows would take >= 100 MB more)."""
    skewpend.simulate(P, Y0, 0.01, method="gauss")
    short = _peak_rss_mb(cli("simulate", "--method", "gauss", "--t-end", "200"), tmp_path)
    long = _peak_rss_mb(cli("simulate", "--method", "gauss", "--t-end", "2000"), tmp_path)
    print(f"peak RSS: 2e5 steps {short:.1f} MB, 2e6 steps {long:.1f} MB")
    assert long - short < 20.0


def test_streamed_file_has_every_row_and_bounded_memory(tmp_path):
    """A grid of 2e5 rows streamed to CSV: every row is there, in order, and finite."""
    path = tmp_path / "grid.csv"
    tr = skewpend.simulate(P, Y0, 200.0, method="rk4", dt=1e-3, dt_out=1e-3, out=path, keep=False)
    assert tr.success and tr.t.size == 2 and tr.stats["rows"] == 200_001
    data = np.loadtxt(path, delimiter=",", skiprows=1)
    assert data.shape == (200_001, 13)
    np.testing.assert_allclose(data[:, 0], np.arange(200_001) * 1e-3, rtol=0, atol=1e-9)
    np.testing.assert_array_equal(data[-1, 1:5], tr.y[-1])  # %.17g round-trips exactly
    kept = skewpend.simulate(P, Y0, 200.0, method="rk4", dt=1e-3, dt_out=1e-3)
    np.testing.assert_array_equal(data[:, 1:5], kept.y)
    assert tr.energy_drift == kept.energy_drift  # measured over every row, kept or not


def test_max_steps_refused_up_front_with_an_estimate(tmp_path):
    t0 = time.monotonic()
    proc = run(cli("simulate", "--t-end", "1e9"), cwd=tmp_path)
    assert proc.returncode == 2 and time.monotonic() - t0 < 30  # a hang guard: refused before a run to t = 1e9 s
    line = proc.stderr.strip()
    assert line.startswith("skewpend: error: t_end = 1e+09 s needs about") and "max_steps (--max-steps) = 100000000" in line
    proc = run(cli("simulate", "--method", "rk4", "--t-end", "100", "--max-steps", "1000"), cwd=tmp_path)
    assert proc.returncode == 2 and "1e+05 steps exceeds the cap max_steps (--max-steps) = 1000" in proc.stderr
    assert list(tmp_path.iterdir()) == []


def test_run_stopped_by_max_steps_writes_what_it_computed(tmp_path):
    """The estimate from the first steps (3.6e3 < 3000 * 1.2 here) can be beaten by a run whose
    steps get shorter later: it then stops at the cap, writes what it computed, exits 1."""
    out = tmp_path / "partial.nc"
    # started near the upright position: the first seconds are slow, the motion then turns wild
    proc = run(cli("simulate", "--phi0", "3.14", "--psi0", "0", "--t-end", "60", "--max-steps", "3000", "--method", "dop853",
                   "--out", out), cwd=tmp_path)  # dop853: its steps get shorter later (taylor's do not)
    assert proc.returncode == 1, proc.stderr
    assert "maximum number of steps exceeded" in proc.stderr and f"to {out}" in proc.stderr
    import netCDF4

    with netCDF4.Dataset(out) as ds:
        assert ds.status == 3 and "maximum number of steps" in ds.message and ds.stat_steps + ds.stat_rejected == 3000
        t = ds["t"][:]
        assert 0 < t[-1] < 60 and ds.t_reached == pytest.approx(t[-1]) and len(t) == ds.stat_steps + 1
        assert np.all(np.isfinite(ds["phi"][:]))
    assert sorted(p.name for p in tmp_path.iterdir()) == ["partial.nc"]


def test_stop_early_status_is_in_the_csv_metadata(tmp_path):
    tr = skewpend.simulate(P, (3.14, 0.0, 0.0, 0.0), 60.0, max_steps=3000, out=tmp_path / "x.csv", keep=False,
                           method="dop853")  # dop853: its steps get shorter later (taylor's do not)
    assert tr.status == 3 and not tr.success
    import json

    meta = json.loads((tmp_path / "x.csv.json").read_text())  # the CSV's metadata, beside it (issue 36)
    assert meta["status"] == 3 and meta["message"] == "stopped: maximum number of steps exceeded"
    data = np.loadtxt(tmp_path / "x.csv", delimiter=",", skiprows=1)
    assert data.shape[0] == tr.stats["rows"] and meta["t_reached"] == data[-1, 0]


# -- progress -------------------------------------------------------------------------------------------
def test_no_progress_bar_when_stderr_is_not_a_terminal(tmp_path):
    """Off a terminal no bar, a line per stage (issue 36: this test asserted an empty stderr, the silent
    wait the issue names)."""
    proc = run(cli("simulate", "--method", "gauss", "--t-end", "300"), cwd=tmp_path)  # ~1.5 s of work
    assert proc.returncode == 0 and proc.stderr == ""  # nothing but the stage lines
    assert any(line.startswith("skewpend simulate: simulating... (") for line in proc.stages), proc.stages
    assert not any("\r" in line or "\x1b" in line or "%" in line for line in proc.stages)


def test_progress_bar_appears_for_long_work_only():
    import io

    from rich.console import Console

    from skewpend.progress import ProgressBar

    buf = io.StringIO()
    console = Console(file=buf, force_terminal=True, width=100)
    with ProgressBar("simulating", unit="s", enabled=True, delay=0.0, console=console) as bar:
        tr = skewpend.simulate(P, Y0, 400.0, method="gauss", keep=False, progress=bar)
        shown = bar.shown
    assert tr.success and shown and "simulating" in buf.getvalue()
    buf2 = io.StringIO()
    with ProgressBar("simulating", enabled=True, delay=60, console=Console(file=buf2, force_terminal=True)) as bar:
        skewpend.simulate(P, Y0, 1.0, progress=bar)
    assert not bar.shown and buf2.getvalue() == ""
    with ProgressBar("simulating", enabled=False, delay=0) as bar:
        skewpend.simulate(P, Y0, 1.0, progress=bar)
    assert not bar.shown


def test_progress_is_called_with_increasing_times():
    seen = []
    skewpend.simulate(P, Y0, 200.0, method="rk4", keep=False, progress=lambda t, T: seen.append((t, T)))
    ts = [t for t, _ in seen]
    assert len(ts) >= 2 and ts == sorted(ts) and ts[-1] == pytest.approx(200.0) and {T for _, T in seen} == {200.0}


# -- files ----------------------------------------------------------------------------------------------
@pytest.mark.parametrize("suffix", [".csv", ".nc"])
@pytest.mark.parametrize("umask", [0o022, 0o077, 0o002])
def test_files_get_the_permissions_of_the_umask(tmp_path, suffix, umask):
    old = os.umask(umask)
    try:
        path = tmp_path / f"x{suffix}"
        skewpend.simulate(P, Y0, 0.1, dt_out=0.05, out=path)
    finally:
        os.umask(old)
    assert stat.S_IMODE(path.stat().st_mode) == 0o666 & ~umask


def test_a_temporary_file_left_by_kill_9_is_removed(tmp_path):
    proc = subprocess.Popen([sys.executable, "-c", "pass"])
    proc.wait()
    stale = tmp_path / f".run.csv.skewpend-{proc.pid}.tmp"  # a pid that no longer exists
    stale.write_text("half a file")
    alive = tmp_path / f".run.csv.skewpend-{os.getppid()}.tmp"  # a live process's: left alone
    alive.write_text("in progress")
    skewpend.simulate(P, Y0, 0.1, out=tmp_path / "run.csv")
    assert sorted(p.name for p in tmp_path.iterdir()) == sorted(["run.csv", "run.csv.json", alive.name])


def test_killed_writer_leaves_no_output_and_the_next_run_cleans_up(tmp_path):
    proc = subprocess.Popen(cli("simulate", "--method", "gauss", "--dt", "1e-4", "--t-end", "2000", "--dt-out", "0.01",
                                "--out", "big.csv"), cwd=tmp_path, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    deadline = time.monotonic() + 60
    while not list(tmp_path.glob(".big.csv.*.tmp")) and time.monotonic() < deadline:
        time.sleep(0.05)
    time.sleep(0.5)
    proc.kill()
    proc.wait()
    assert not (tmp_path / "big.csv").exists() and not (tmp_path / "big.csv.json").exists()
    assert len(list(tmp_path.glob(".big.csv.skewpend-*.tmp"))) == 1 and len(list(tmp_path.glob(".big.csv.json.*.tmp"))) == 1
    assert run(cli("simulate", "--t-end", "0.1", "--dt-out", "0.05", "--out", "big.csv"), cwd=tmp_path).returncode == 0
    assert sorted(p.name for p in tmp_path.iterdir()) == ["big.csv", "big.csv.json"]


# -- the kernel cache -------------------------------------------------------------------------------------
GEOMETRY = dict(com2=(0.0, 0.37, 0.01))  # a model of its own: its own library in the cache


def test_damaged_kernel_is_rebuilt(tmp_path):
    env = {"SKEWPEND_CACHE_DIR": str(tmp_path / "cache")}
    args = cli("simulate", "--t-end", "1", "--com2", "0,0.37,0.01", "--method", "dop853")  # the model's kernel alone
    first = run(args, env=env)
    assert first.returncode == 0 and "compiled for this model" in first.stdout
    [lib] = (tmp_path / "cache" / "kernels").glob("*.so")
    final = first.stdout.split("final state")[1].splitlines()[0]
    # an empty and a truncated library (any damage meets the same check: the file's digest against the
    # one recorded at its build; a third case, a bare ELF header, repeated it at a compile's cost)
    for damage in (b"", lib.read_bytes()[:-100] + b"\0" * 100):
        lib.write_bytes(damage)
        again = run(args, env=env)
        # rebuilt, and said so in one line (the first-use notice: a build takes seconds)
        assert again.returncode == 0 and again.stderr.splitlines() == [
            "skewpend: compiling the model's kernels for general bodies (first use only; cached for later runs)..."], again.stderr
        assert "compiled for this model" in again.stdout  # rebuilt, not loaded
        assert again.stdout.split("final state")[1].splitlines()[0] == final
    hit = run(args, env=env)
    assert "loaded from the cache" in hit.stdout


def test_unwritable_cache_falls_back_with_one_warning(tmp_path):
    if os.geteuid() == 0:
        # root may write anywhere: a cache path *under a regular file* cannot be created by anyone
        blocker = tmp_path / "file"
        blocker.write_text("")
        cache = blocker / "cache"
    else:
        cache = tmp_path / "ro"
        cache.mkdir()
        cache.chmod(0o500)
    proc = run(cli("simulate", "--t-end", "1", "--com2", "0,0.36,0.01", "--method", "dop853"),  # the model's kernel alone
               env={"SKEWPEND_CACHE_DIR": str(cache)})
    assert proc.returncode == 0, proc.stderr
    lines = proc.stderr.strip().splitlines()
    assert len(lines) == 2 and lines[0].startswith("skewpend: warning: cannot write the kernel cache"), proc.stderr
    assert lines[1] == "skewpend: compiling the model's kernels for general bodies (for this run: the cache is not writable)..."
    assert "reached t_end" in proc.stdout
    assert "not cached" in proc.stdout and "cached for later runs" not in proc.stdout  # the summary says so too


def test_missing_compiler_is_one_clear_line(tmp_path):
    proc = run(cli("simulate", "--t-end", "1", "--com2", "0,0.35,0.01", "--method", "dop853"),
               env={"SKEWPEND_CACHE_DIR": str(tmp_path), "CC": "/nonexistent/cc"})
    assert proc.returncode == 2
    assert proc.stderr.strip().splitlines() == [proc.stderr.strip()]
    assert "C compiler" in proc.stderr and "install gcc or clang" in proc.stderr


def test_cache_hit_loads_without_sympy_or_compiler(tmp_path):
    env = {"SKEWPEND_CACHE_DIR": str(tmp_path)}
    assert run(cli("simulate", "--t-end", "1"), env=env).returncode == 0
    code = (
        "import sys, skewpend\n"
        "p = skewpend.Parameters(a=1.0, b=0.8, m1=1.0, m2=0.7, alpha=0.6, g=9.81)\n"
        "tr = skewpend.simulate(p, (1.2, -0.8, 0, 0), 1.0)\n"
        "print(tr.stats['kernel'], 'sympy' in sys.modules)\n"
    )
    proc = run([sys.executable, "-c", code], env={**env, "CC": "/nonexistent/cc", "PATH": "/nonexistent"})
    assert proc.returncode == 0, proc.stderr
    assert proc.stdout.split() == ["cache", "False"]


def test_a_signal_inside_an_extensions_import_is_the_signal():
    """CPython reports a Ctrl-C or SIGTERM that lands while an extension module initialises as ImportError
    ("initialization failed") raised from the signal's exception: the CLI finds the signal in the chain and
    exits as for the signal (130 / 143), not as an internal error (70)."""
    from skewpend.cli import _signal_in_chain
    from skewpend.interrupts import Terminated

    for signal_exc in (Terminated(), KeyboardInterrupt()):
        try:
            try:
                raise signal_exc
            except KeyboardInterrupt:
                raise ImportError("initialization failed")  # noqa: B904 - the implicit chain, as CPython's
        except ImportError as exc:
            assert _signal_in_chain(exc) is signal_exc
    assert _signal_in_chain(ImportError("no module named x")) is None
