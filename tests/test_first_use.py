"""The first ``simulate`` of a model (issue 51, item 7): ``method="auto"`` does not wait for the Taylor
library. It runs dop853 at once, says so, and a detached process builds the library; the next run
takes taylor. ``SKEWPEND_TAYLOR_BUILD=foreground`` (what the rest of the suite sets, in conftest.py)
waits for it instead."""

from __future__ import annotations

import os
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest

from helpers import assert_refused, run_process


def _env(cache: Path, mode=None) -> dict:
    env = {k: v for k, v in os.environ.items() if k not in ("SKEWPEND_TAYLOR_BUILD", "SKEWPEND_QUIET")}
    env["SKEWPEND_CACHE_DIR"] = str(cache)
    if mode is not None:
        env["SKEWPEND_TAYLOR_BUILD"] = mode
    return env


def _simulate(tmp_path, env, out):
    argv = [sys.executable, "-m", "skewpend", "simulate", "--t-end", "3", "--out", str(out)]
    return subprocess.run(argv, cwd=tmp_path, env=env, capture_output=True, text=True, timeout=600)


def _taylor_libraries(cache: Path):
    return sorted((cache / "kernels").glob("skewpend_*_taylor*.so")) if (cache / "kernels").is_dir() else []


@pytest.mark.slow
def test_the_first_run_takes_dop853_while_the_taylor_library_builds(tmp_path):
    """A fresh cache: the first run compiles only the model's kernel, runs dop853 and names why; a
    detached process leaves the Taylor library in the cache (polled for up to 10 min on a loaded
    machine: it needs a few seconds' CPU); the second run takes taylor and agrees with the first to
    the tolerances (both at rtol = atol = 1e-10 over 3 s of the built-in regular start: global errors of
    a few tens of rtol, 1e-7 bounds their difference with room)."""
    import xarray as xr

    cache = tmp_path / "cache"
    env = _env(cache)
    first = _simulate(tmp_path, env, tmp_path / "first.nc")
    assert first.returncode == 0, first.stderr
    assert "method        dop853" in first.stdout and "being built in the background" in first.stdout
    assert "building the Taylor kernel of order 15 in the background" in first.stderr
    assert first.stderr.count("compiling") == 1  # the model's kernel only; the Taylor library is not waited for
    deadline = time.monotonic() + 600
    while not _taylor_libraries(cache) or list((cache / "kernels").glob(".skewpend_*.building")):
        assert time.monotonic() < deadline, "the background build left no Taylor library"
        time.sleep(0.2)
    second = _simulate(tmp_path, env, tmp_path / "second.nc")
    assert second.returncode == 0, second.stderr
    assert "method        taylor" in second.stdout and "compiling" not in second.stderr
    with xr.open_dataset(tmp_path / "first.nc") as a, xr.open_dataset(tmp_path / "second.nc") as b:
        ya = np.stack([a[v].values[-1] for v in ("phi", "psi", "dphi", "dpsi")])
        yb = np.stack([b[v].values[-1] for v in ("phi", "psi", "dphi", "dpsi")])
        assert float(a["t"].values[-1]) == float(b["t"].values[-1]) == 3.0
    assert np.max(np.abs(ya - yb)) < 1e-7


def test_foreground_waits_for_the_library_and_takes_taylor(tmp_path):
    """The setting the suite runs under: one choice whatever the cache holds."""
    from skewpend import reference_parameters, reference_state, simulate
    from skewpend.numeric import kernels

    assert kernels.taylor_build_in_foreground()  # conftest.py sets it
    tr = simulate(reference_parameters(), reference_state(), 1.0)
    assert tr.method == "taylor"


def test_the_background_build_is_started_once(tmp_path, monkeypatch):
    """A marker beside the library says a build runs: a second first-use in that window starts none."""
    from skewpend import reference_parameters
    from skewpend.numeric import kernels

    started = []
    monkeypatch.setenv("SKEWPEND_CACHE_DIR", str(tmp_path))
    for loaded in ("_LOADED", "_BYGEOMETRY", "_TAYLOR_OF"):  # libraries this worker's earlier tests loaded
        monkeypatch.setattr(kernels, loaded, {})
    monkeypatch.setattr(subprocess, "Popen", lambda *a, **k: started.append(a))
    p = reference_parameters()
    assert kernels.build_taylor_in_background(p, 12) and kernels.build_taylor_in_background(p, 12)
    assert len(started) == 1
    assert len(list((tmp_path / "kernels").glob(".skewpend_*_taylor12.building"))) == 1
    assert kernels.built_taylor_kernel(p, 12) is None  # nothing built: never built by the look-up


def test_the_background_build_is_said_once_per_library(tmp_path, monkeypatch, capsys):
    """Runs of one process that each find the library missing (identify's held-out pieces: eight) say the
    background build once."""
    from skewpend import reference_parameters, reference_state, simulate
    from skewpend.numeric import kernels

    monkeypatch.setenv("SKEWPEND_TAYLOR_BUILD", "background")
    monkeypatch.delenv("SKEWPEND_QUIET", raising=False)
    monkeypatch.setattr(kernels, "_ANNOUNCED", set())
    monkeypatch.setattr(kernels, "built_taylor_kernel", lambda *a, **k: None)  # never built: every run asks
    monkeypatch.setattr(kernels, "build_taylor_in_background", lambda *a, **k: True)  # a build runs
    p, y0 = reference_parameters().replace(alpha=0.3), reference_state()
    for _ in range(3):
        assert simulate(p, y0, 0.5).method == "dop853"
    err = capsys.readouterr().err
    assert err.count("building the Taylor kernel of order 15 in the background") == 1, err


def test_a_bad_setting_is_one_line(tmp_path):
    ran = run_process(["simulate", "--t-end", "1"], tmp_path, env={"SKEWPEND_CACHE_DIR": str(tmp_path / "cache"),
                                                                "SKEWPEND_TAYLOR_BUILD": "later"})
    assert_refused(ran, ["SKEWPEND_TAYLOR_BUILD", "'background' or 'foreground'", "'later'"])


def test_two_processes_wanting_one_library_build_it_once(tmp_path):
    """pytest-xdist's workers (or two commands started together) on a cold cache: the second waits for
    the first's build (a file lock beside the library) and loads it, instead of compiling it again."""
    code = ("import sys\nfrom skewpend import reference_parameters\nfrom skewpend.numeric import kernels\n"
            "k = kernels.kernel_module(reference_parameters().replace(com2=(0.0, 0.37, 0.0)))\nprint(k.origin)\n")
    env = _env(tmp_path / "cache")
    env["SKEWPEND_QUIET"] = "1"
    procs = [subprocess.Popen([sys.executable, "-c", code], env=env, stdout=subprocess.PIPE, stderr=subprocess.PIPE,
                              text=True) for _ in range(2)]
    outs = [p.communicate(timeout=600) for p in procs]
    assert all(p.returncode == 0 for p in procs), [err for _, err in outs]
    assert sorted(out.strip() for out, _ in outs) == ["cache", "compiled"]
    assert len(list((tmp_path / "cache" / "kernels").glob("skewpend_*.so"))) == 1
