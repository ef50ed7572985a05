"""flip_map (issue 9): accuracy against simulate, the shortcuts (energy bound, mirror symmetry),
independence of chunking and workers, Ctrl-C, bad input."""

from __future__ import annotations

import math
import subprocess
import sys

import numpy as np
import pytest

from skewpend import ParameterError, Parameters, simulate
from skewpend.analysis.flipmap import MAX_N, FlipMap, cell_centres, energy_barrier, flip_map
from skewpend.numeric.kernels import kernel_module, parameter_vector

from helpers import general_body  # noqa: E402
from skewpend.config import reference_parameters  # noqa: E402
BENCH = reference_parameters()  # the reference case: a = 1, b = 0.8, m1 = 1, m2 = 0.7, alpha = 0.6, g = 9.81
#: A rigid second body, its centre of mass off the rod's line and its hinge tilted out of the (i, k) plane: not
#: mirror-symmetric.  examples/general_body.toml's (tests/helpers.py's general_body: its kernels are the ones the
#: README's and the report's runs of that file compile, so this module compiles none of its own).
SKEW_BODY = general_body()
TORQUES = BENCH.replace(c1=0.3, c2=0.2, tau1=1.0, tau2=0.5)


def simulated_flip(params, phi0, psi0, t_end, dt=1e-3):
    """(flip time, joint) from simulate at rtol = atol = 1e-12 on a fine grid: the first grid
    interval where |phi| or |psi| reaches pi, the crossing located by bisection on the cubic
    Hermite interpolant of the angle (values and rates at both ends)."""
    tr = simulate(params, (phi0, psi0, 0.0, 0.0), t_end, rtol=1e-12, atol=1e-12, dt_out=dt)
    assert tr.success
    q, v = tr.y[:, :2], tr.y[:, 2:]
    out = np.any(np.abs(q) >= math.pi, axis=1)
    if not out.any():
        return math.nan, -1
    k = int(np.argmax(out))
    best = (math.inf, -1)
    t0, h = tr.t[k - 1], tr.t[k] - tr.t[k - 1]
    for c in (0, 1):
        y0, y1, d0, d1 = q[k - 1, c], q[k, c], v[k - 1, c] * h, v[k, c] * h
        if abs(y1) < math.pi:
            continue

        def hermite(s):
            return (2 * s**3 - 3 * s**2 + 1) * y0 + (s**3 - 2 * s**2 + s) * d0 + (-2 * s**3 + 3 * s**2) * y1 + (s**3 - s**2) * d1

        lo, hi = 0.0, 1.0
        for _ in range(60):
            mid = 0.5 * (lo + hi)
            lo, hi = (lo, mid) if abs(hermite(mid)) >= math.pi else (mid, hi)
        if t0 + hi * h < best[0]:
            best = (t0 + hi * h, c)
    return best


@pytest.fixture(scope="module")
def bench_map():
    return flip_map(BENCH, 48, t_end=10.0)


# -- accuracy --------------------------------------------------------------------------------------
def test_sampled_cells_agree_with_simulate(bench_map):
    """Issue 9: flip times within 1e-3 s on >= 99.9% of sampled cells and the outcome right."""
    fm = bench_map
    rng = np.random.default_rng(9)
    cells = rng.choice(fm.n * fm.n, 120, replace=False)
    errors, wrong = [], []
    for k in cells:
        i, j = divmod(int(k), fm.n)
        t_ref, w_ref = simulated_flip(BENCH, fm.phi0[i, j], fm.psi0[i, j], 10.0)
        t, w = fm.flip_time[i, j], fm.which[i, j]
        if math.isfinite(t_ref) != math.isfinite(t) or w != w_ref:
            wrong.append((i, j, t, t_ref))
        elif math.isfinite(t):
            errors.append(abs(t - t_ref))
    assert len(errors) > 50  # most sampled cells flip
    assert not wrong
    assert np.mean(np.array(errors) <= 1e-3) >= 0.999
    assert max(errors) < 1e-3
    # every cell against the map at rtol = atol = 1e-13 (whose sampled cells match simulate to ~1e-8 s)
    ref = flip_map(BENCH, fm.n, t_end=10.0, rtol=1e-13, atol=1e-13)
    same = np.isfinite(ref.flip_time) == fm.flipped
    assert np.mean(same & (ref.which == fm.which)) >= 0.999
    both = fm.flipped & np.isfinite(ref.flip_time)
    assert np.mean(np.abs(fm.flip_time[both] - ref.flip_time[both]) <= 1e-3) >= 0.999


def test_the_crossing_is_located_on_the_dense_output():
    """At a tight tolerance the flip times match simulate's crossing to ~1e-8 s: the event is
    located inside the step, not at the first step past pi (steps are ~1e-2 s)."""
    phi = np.array([2.0, -1.3, 3.0, 1.9])
    psi = np.array([2.2, 2.8, -2.0, -2.4])
    fm = flip_map(BENCH, 4, t_end=10.0, rtol=1e-12, atol=1e-12, shortcuts=False)
    # the map's own cells, plus four chosen starts through windows of one cell
    for i in range(4):
        one = flip_map(BENCH, 1, t_end=10.0, rtol=1e-12, atol=1e-12, phi_range=(phi[i] - 1e-3, phi[i] + 1e-3),
                       psi_range=(psi[i] - 1e-3, psi[i] + 1e-3))
        t_ref, w_ref = simulated_flip(BENCH, one.phi0[0, 0], one.psi0[0, 0], 10.0)
        assert math.isfinite(t_ref) and one.which[0, 0] == w_ref
        assert abs(one.flip_time[0, 0] - t_ref) < 1e-7
    for i in range(4):
        for j in range(4):
            t_ref, w_ref = simulated_flip(BENCH, fm.phi0[i, j], fm.psi0[i, j], 10.0)
            assert fm.which[i, j] == w_ref
            if math.isfinite(t_ref):
                assert abs(fm.flip_time[i, j] - t_ref) < 1e-7


def test_general_bodies_and_torques_agree_with_simulate():
    for params in (SKEW_BODY, TORQUES):
        fm = flip_map(params, 12, t_end=6.0)
        assert not fm.settings["symmetry"]  # no mirror symmetry: checked, not assumed
        rng = np.random.default_rng(3)
        for k in rng.choice(144, 25, replace=False):
            i, j = divmod(int(k), 12)
            t_ref, w_ref = simulated_flip(params, fm.phi0[i, j], fm.psi0[i, j], 6.0)
            assert fm.which[i, j] == w_ref, (params, i, j)
            if math.isfinite(t_ref):
                assert abs(fm.flip_time[i, j] - t_ref) < 1e-3


# -- the shortcuts ------------------------------------------------------------------------------------
@pytest.mark.parametrize("n", [24, 25])
def test_map_is_mirror_symmetric_with_and_without_the_shortcuts(n):
    full = flip_map(BENCH, n, t_end=6.0, shortcuts=False)
    assert not full.settings["symmetry"] and full.stats["integrated"] == n * n
    mirror_t, mirror_w = full.flip_time[::-1, ::-1], full.which[::-1, ::-1]
    both = np.isfinite(full.flip_time)
    assert np.array_equal(both, np.isfinite(mirror_t)) and np.array_equal(full.which, mirror_w)
    assert np.max(np.abs(full.flip_time[both] - mirror_t[both])) < 1e-6
    assert np.array_equal(full.phi0, -full.phi0[::-1, ::-1]) and np.array_equal(full.psi0, -full.psi0[::-1, ::-1])
    fast = flip_map(BENCH, n, t_end=6.0)
    assert fast.settings["symmetry"] and fast.stats["mirrored"] > 0 and fast.stats["skipped_energy"] > 0
    s = fast.stats
    assert s["integrated"] + s["mirrored"] + s["skipped_energy"] == n * n
    assert np.array_equal(fast.which, full.which)
    assert np.array_equal(np.isfinite(fast.flip_time), both)
    assert np.max(np.abs(fast.flip_time[both] - full.flip_time[both])) < 1e-6


def test_no_symmetry_shortcut_for_an_asymmetric_body_or_torques():
    assert not kernel_module(SKEW_BODY, flip=True).flip_odd
    assert kernel_module(BENCH.replace(c1=0.2), flip=True).flip_odd  # damping keeps the symmetry
    assert not flip_map(TORQUES, 4, t_end=1.0).settings["symmetry"]
    assert not flip_map(BENCH, 4, t_end=1.0, phi_range=(-3.0, 3.1)).settings["symmetry"]  # window not symmetric


@pytest.mark.parametrize("params", [BENCH, TORQUES, SKEW_BODY], ids=["thin-rods", "damping+torques", "skew-body"])
def test_energetically_forbidden_cells_never_flip(params):
    """The cells the energy bound skips, integrated anyway (simulate at 1e-12, to t_end): none
    leaves (-pi, pi).  Those closest to the barrier are included."""
    n, t_end = 40, 8.0
    fm = flip_map(params, n, t_end=t_end)
    kernel, p = kernel_module(params, flip=True), parameter_vector(params)
    barrier, scale = energy_barrier(kernel, p)
    cells = np.column_stack([fm.phi0.ravel(), fm.psi0.ravel()])
    V0 = kernel.flip_potential_many(cells, p)
    forbidden = np.flatnonzero(V0 < barrier - 1e-9 * scale)
    assert forbidden.size >= 20 and fm.stats["skipped_energy"] >= forbidden.size - 2
    closest = forbidden[np.argsort(barrier - V0[forbidden])[:10]]
    rng = np.random.default_rng(1)
    sample = np.unique(np.concatenate([closest, rng.choice(forbidden, 10, replace=False)]))
    for k in sample:
        # DOP853: the claim is the energy bound's, not an integrator's (auto would build a Taylor library per body)
        tr = simulate(params, (cells[k, 0], cells[k, 1], 0.0, 0.0), t_end, method="dop853", rtol=1e-12, atol=1e-12)
        assert np.max(np.abs(tr.y[:, :2])) < math.pi
        assert math.isnan(fm.flip_time.ravel()[k])
    # and the map without the shortcut agrees on all of them
    full = flip_map(params, n, t_end=t_end, shortcuts=False)
    assert np.all(np.isnan(full.flip_time.ravel()[forbidden]))


def test_with_torques_the_bound_needs_the_torques_work():
    """With constant torques, E0 below the potential barrier does NOT prevent a flip (the torques
    feed energy in); the tilted potential V = Pi - tau . q does -- which is what is used."""
    p_tau = BENCH.replace(tau1=2.0, tau2=-1.0)
    fm = flip_map(p_tau, 40, t_end=8.0, shortcuts=False)
    k0, p0 = kernel_module(BENCH, flip=True), parameter_vector(BENCH)
    cells = np.column_stack([fm.phi0.ravel(), fm.psi0.ravel()])
    below_untilted = k0.flip_potential_many(cells, p0) < energy_barrier(k0, p0)[0]
    assert np.any(np.isfinite(fm.flip_time.ravel()[below_untilted]))  # Pi alone would be wrong
    kt, pt = kernel_module(p_tau, flip=True), parameter_vector(p_tau)
    below_tilted = kt.flip_potential_many(cells, pt) < energy_barrier(kt, pt)[0]
    assert below_tilted.sum() > 50 and not np.any(np.isfinite(fm.flip_time.ravel()[below_tilted]))


def test_energy_barrier_of_thin_rods():
    """Thin rods: the lowest point of the boundary is psi = +-pi with rod 1 hanging (rod 2 up):
    Pi = m2 g b -- whatever alpha, since rod 2 then points straight up along its own hinge plane."""
    kernel, p = kernel_module(BENCH, flip=True), parameter_vector(BENCH)
    barrier, scale = energy_barrier(kernel, p)
    assert barrier == pytest.approx(0.7 * 9.81 * 0.8, rel=1e-12)
    assert scale > barrier


# -- engine ---------------------------------------------------------------------------------------------
def test_results_do_not_depend_on_chunks_or_workers():
    kw = dict(t_end=6.0, phi_range=(-3.0, 2.5), psi_range=(-2.0, 3.1), shortcuts=False)  # every cell integrated
    ref = flip_map(BENCH, 30, chunk_size=8, workers=1, **kw)
    assert ref.stats["chunks"] == 30  # chunks are whole rows: 8 cells (< one row) -> the finest, one row each
    for chunk_size, workers in ((37, 2), (None, 3), (5000, 2), (1, 2)):
        other = flip_map(BENCH, 30, chunk_size=chunk_size, workers=workers, **kw)
        assert other.flip_time.tobytes() == ref.flip_time.tobytes()
        assert other.which.tobytes() == ref.which.tobytes()
    a = flip_map(BENCH, 26, t_end=6.0, workers=1, chunk_size=16)
    b = flip_map(BENCH, 26, t_end=6.0, workers=2)
    assert a.flip_time.tobytes() == b.flip_time.tobytes() and a.settings["symmetry"]


def test_grid_progress_stats_and_xarray(bench_map, monkeypatch):
    fm = bench_map
    assert isinstance(fm, FlipMap) and fm.n == 48
    lo, hi, n = -math.pi, math.pi, 48
    np.testing.assert_allclose(fm.phi0[:, 0], lo + (np.arange(n) + 0.5) * (hi - lo) / n, rtol=0, atol=1e-15)
    assert np.all(fm.phi0 == fm.phi0[:, :1]) and np.all(fm.psi0 == fm.psi0[:1, :])
    assert set(np.unique(fm.which)) <= {-1, 0, 1}
    assert np.array_equal(fm.which >= 0, fm.flipped)
    assert np.all(fm.flip_time[fm.flipped] > 0) and np.all(fm.flip_time[fm.flipped] <= 10.0)
    assert fm.stats["flipped"] == fm.flipped.sum() and fm.stats["failed"] == 0
    assert fm.settings["t_end"] == 10.0 and fm.settings["rtol"] == 1e-10 and fm.params == BENCH
    calls = []
    flip_map(BENCH, 20, t_end=3.0, progress=lambda done, total: calls.append((done, total)), chunk_size=16)
    assert len(calls) > 3 and calls[-1] == (400, 400)
    assert all(b[0] >= a[0] for a, b in zip(calls, calls[1:]))
    ds = fm.to_xarray()
    assert ds["flip_time"].dims == ("phi0", "psi0") and ds["flip_time"].attrs["units"] == "s"
    np.testing.assert_array_equal(ds["flip_time"].values, fm.flip_time)
    np.testing.assert_array_equal(ds["phi0"].values, fm.phi0[:, 0])
    assert ds.attrs["t_end"] == 10.0 and "alpha" in ds.attrs["params"]
    monkeypatch.setitem(sys.modules, "xarray", None)
    with pytest.raises(ImportError, match="pip install xarray"):
        fm.to_xarray()


def test_cell_centres_are_exactly_antisymmetric():
    for n in (1, 2, 7, 128, 1001):
        c = cell_centres(-math.pi, math.pi, n)
        assert np.array_equal(c[::-1], -c)
        assert np.all(np.diff(c) > 0) and -math.pi < c[0] and c[-1] < math.pi


_INTERRUPT = """
import os, signal, sys, skewpend
from skewpend.analysis.flipmap import flip_map
p = skewpend.Parameters(a=1.0, b=0.8, m1=1.0, m2=0.7, alpha=0.6, g=9.81)
flip_map(p, 8, t_end=1.0)  # the flip kernel, compiled or loaded
calls = []
def progress(done, total):
    calls.append(done)
    print("progress", len(calls), done, total, flush=True)
    if len(calls) == 3:
        os.kill(os.getpid(), signal.SIGINT)  # Ctrl-C, while the map runs
flip_map(p, 600, t_end=200.0, workers=2, progress=progress)
print("finished", flush=True)
"""


def test_ctrl_c_stops_promptly():
    """Ctrl-C during a long map (600 x 600 cells, two workers) stops it at once: once the interrupt
    is sent (from the 3rd progress call), at most one unit per worker already under way is reported
    -- counted in progress lines, not timed (issue 36) -- and the run ends with KeyboardInterrupt,
    never "finished".  30 s is a hang guard only (the whole map would take minutes)."""
    workers = 2
    proc = subprocess.Popen([sys.executable, "-c", _INTERRUPT], stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    try:
        out, err = proc.communicate(timeout=30)
    finally:
        if proc.poll() is None:
            proc.kill()
            proc.communicate()
    lines = out.splitlines()
    assert proc.returncode != 0 and "KeyboardInterrupt" in err, (out, err[-2000:])
    assert "finished" not in lines
    calls = [line.split() for line in lines if line.startswith("progress ")]
    assert [c[1] for c in calls[:3]] == ["1", "2", "3"], out
    done, total = int(calls[2][2]), int(calls[2][3])
    assert total == 600 * 600 and done < total / 2  # many more units than workers still ahead at the signal
    assert len(calls) - 3 <= workers, out


# -- bad input -------------------------------------------------------------------------------------------
@pytest.mark.parametrize(
    "args, kwargs, match",
    [
        ((BENCH, 0), {}, "n must be from 1"),
        ((BENCH, -3), {}, "n must be from 1"),
        ((BENCH, MAX_N + 1), {}, "n must be from 1"),
        ((BENCH, 2.5), {}, "whole number"),
        ((BENCH, "64"), {}, "whole number"),
        ((BENCH, True), {}, "whole number"),
        ((BENCH, 8), {"t_end": 0.0}, "t_end must be a positive"),
        ((BENCH, 8), {"t_end": -1.0}, "t_end must be a positive"),
        ((BENCH, 8), {"t_end": float("nan")}, "t_end must be a positive"),
        ((BENCH, 8), {"t_end": float("inf")}, "t_end must be a positive"),
        ((BENCH, 8), {"t_end": "ten"}, "t_end must be a positive"),
        ((BENCH, 8), {"phi_range": (1.0, 1.0)}, "zero width"),
        ((BENCH, 8), {"phi_range": (1.0, -1.0)}, "inverted"),
        ((BENCH, 8), {"psi_range": (0.5, 0.2)}, "inverted"),
        ((BENCH, 8), {"phi_range": (-4.0, 0.0)}, r"within \[-pi, pi\]"),
        ((BENCH, 8), {"psi_range": (0.0,)}, "pair"),
        ((BENCH, 8), {"psi_range": "ab"}, "pair"),
        ((BENCH, 8), {"phi_range": (float("nan"), 1.0)}, "finite"),
        ((BENCH, 8), {"rtol": 0.0}, "rtol must be a positive"),
        ((BENCH, 8), {"atol": -1e-9}, "atol must be a positive"),
        ((BENCH, 8), {"rtol": 1e-17}, "machine precision"),
        ((BENCH, 8), {"workers": 0}, "workers"),
        ((BENCH, 8), {"workers": 1.5}, "workers"),
        ((BENCH, 8), {"chunk_size": 0}, "chunk_size"),
        ((BENCH, 8), {"progress": 3}, "progress"),
        ((BENCH, 8), {"max_steps": 0}, "max_steps"),
        ((Parameters(), 8), {}, "numeric values; symbolic"),
        ((Parameters(a=1.0, b=0.8, m1=1.0, m2=0.7, g=9.81), 8), {}, "symbolic: alpha"),
        (({"a": 1.0}, 8), {}, "skewpend.Parameters"),
    ],
)
def test_bad_input_is_refused(args, kwargs, match):
    with pytest.raises(ParameterError, match=match):
        flip_map(*args, **kwargs)


def test_max_steps_failure_is_reported():
    with pytest.warns(RuntimeWarning, match="failed"):
        fm = flip_map(BENCH, 4, t_end=10.0, max_steps=20, shortcuts=False)
    assert fm.stats["failed"] > 0 and np.all(fm.which >= -1)


def test_flip_kernel_is_separate_and_trigonometry_free():
    """The simulation kernel does not carry sp_flip (a simulation's first use does not compile
    it); the flip kernel's right-hand side is generated, free of sin/cos/pow (vectorisable), and
    reads the parameter-only constants (sin(alpha), ...) prepared once per run."""
    from skewpend.numeric.conventions import geometry_of
    from skewpend.numeric.kernel_source import kernel_c_source

    sim = kernel_module(BENCH)
    assert not sim.flip and not hasattr(sim.lib, "sp_flip")
    flip = kernel_module(BENCH, flip=True)
    assert flip.flip and flip.flip_lanes == 8 and flip.flip_odd
    src = kernel_c_source(geometry_of(BENCH), flip=True)
    body = src[src.index("void flip_rhs("):src.index("static void flip_init(")]
    assert "for (int l = 0; l < SP_LANES; l++)" in body
    for call in ("sin(", "cos(", "pow("):
        assert call not in body
    prepare = src[src.index("static void flip_prepare("):src.index("void flip_rhs(")]
    assert "sin(alpha)" in prepare and "cos(alpha)" in prepare
    assert "flip_rhs" not in kernel_c_source(geometry_of(BENCH))
