"""Regions of attraction (issue 18): each cell's claim checked by an independent full simulation,
the map's symmetry, bitwise identity whatever the workers, chunks or a resume after kill -9, the
store and files, the figure, the CLI and its bad input."""

from __future__ import annotations

import math
import signal
import subprocess
import sys

import numpy as np
import pytest

import skewpend
from skewpend import EquilibriumError, ParameterError
from skewpend.analysis.roa import RegionOfAttraction, open_region_of_attraction, region_of_attraction
from skewpend.config import reference_parameters

BENCH = reference_parameters()  # a = 1, b = 0.8, m1 = 1, m2 = 0.7, alpha = 0.6, g = 9.81
UMAX = 10.0


@pytest.fixture(scope="module")
def design():
    return skewpend.lqr(BENCH, "up-up", "both", umax=UMAX)


@pytest.fixture(scope="module")
def ref(design):
    return region_of_attraction(BENCH, n=24, design=design, t_end=6.0)


def same(a: RegionOfAttraction, b: RegionOfAttraction) -> bool:
    return a.capture_time.tobytes() == b.capture_time.tobytes() and a.outcome.tobytes() == b.outcome.tobytes()


def _wrapped(dx):
    dx = np.array(dx, dtype=float)
    dx[..., :2] = (dx[..., :2] + np.pi) % (2 * np.pi) - np.pi
    return dx


def _interior(mask: np.ndarray) -> np.ndarray:
    """Cells whose 8 neighbours have the same value (away from the region's boundary)."""
    m = mask.astype(int)
    out = np.zeros_like(mask, dtype=bool)
    out[1:-1, 1:-1] = True
    for di in (-1, 0, 1):
        for dj in (-1, 0, 1):
            out[1:-1, 1:-1] &= m[1 + di:m.shape[0] - 1 + di, 1 + dj:m.shape[1] - 1 + dj] == m[1:-1, 1:-1]
    return out


def test_each_claim_holds_in_an_independent_full_simulation(ref, design):
    """A captured cell, simulated by simulate() (dense output, tighter tolerance) for t_end + 10 s,
    enters the estimate when the map says (within the output step and the tolerance) and ends at
    the target; a cell not captured is, at t_end, still outside the estimate (which the
    trajectory could not have left had it entered: V decreases inside)."""
    rng = np.random.default_rng(18)
    ctl = design.controller()
    target = design.linearization.target
    captured = np.argwhere(ref.captured & _interior(ref.captured) & (ref.capture_time > 0))
    missed = np.argwhere((ref.outcome == 0) & _interior(ref.outcome == 0))
    assert len(captured) >= 6 and len(missed) >= 6
    i, j = (ref.plane.index(c) for c in ("phi", "psi"))
    for cells, was_captured in ((captured, True), (missed, False)):
        for a, b in cells[rng.choice(len(cells), 6, replace=False)]:
            y0 = target.copy()
            y0[0], y0[1] = ref.x0[a], ref.y0[b]
            dt = 1e-3
            tr = skewpend.simulate(BENCH, y0, ref.settings["t_end"] + 10.0, controller=ctl, dt_out=dt, rtol=1e-11,
                                   atol=1e-11)
            inside = design.inside(tr.y)
            if was_captured:
                entry = tr.t[np.argmax(inside)]
                assert inside.any() and abs(entry - ref.capture_time[a, b]) <= dt + 1e-6, (a, b, entry)
                assert inside[np.searchsorted(tr.t, entry):].all()  # it stays: the estimate is invariant
                assert np.abs(_wrapped(tr.y[-1] - target)).max() < 1e-6
            else:
                k_end = np.searchsorted(tr.t, ref.settings["t_end"])
                assert not inside[: k_end + 1].any(), (a, b)


def test_starts_inside_the_estimate_are_captured_at_zero(ref):
    dx, dy = ref.deviations()
    S = ref.P[:2, :2]
    X, Y = np.meshgrid(dx, dy, indexing="ij")
    inside = S[0, 0] * X * X + 2 * S[0, 1] * X * Y + S[1, 1] * Y * Y < ref.rho
    assert inside.any()
    assert np.all(ref.capture_time[inside] == 0.0) and np.all(ref.capture_time[ref.captured & ~inside] > 0.0)
    assert ref.inner_fraction == pytest.approx(inside.mean())
    assert ref.captured_fraction == pytest.approx(ref.captured.mean())
    assert ref.inner_fraction < ref.captured_fraction < 1.0


def test_the_map_has_the_model_s_point_symmetry(ref):
    """The thin rods' equations are odd about the upright equilibrium (q, q') -> -(q, q') (the flip
    kernel's symbolic check), and so is the saturated LQR: cell (i, j) and (n-1-i, n-1-j) are mirror
    starts.  Same outcome everywhere; capture times equal to the integration's accuracy (rtol 1e-8
    over a few seconds of contracting motion: 1e-4 s is a generous bound, the entry bisected to 1e-14)."""
    from skewpend.numeric.kernels import kernel_module

    assert kernel_module(BENCH, flip=True).flip_odd
    assert np.array_equal(ref.outcome, ref.outcome[::-1, ::-1])
    both = ref.captured & ref.captured[::-1, ::-1]
    assert np.max(np.abs(ref.capture_time - ref.capture_time[::-1, ::-1])[both]) < 1e-4


def test_capture_times_converge_with_the_tolerance(design):
    coarse = region_of_attraction(BENCH, n=12, design=design, t_end=6.0, window=((-1.0, 1.0), (-2.0, 2.0)))
    fine = region_of_attraction(BENCH, n=12, design=design, t_end=6.0, window=((-1.0, 1.0), (-2.0, 2.0)),
                                rtol=1e-11, atol=1e-11)
    assert np.array_equal(coarse.outcome, fine.outcome)
    both = coarse.captured & (coarse.capture_time > 0)
    assert both.sum() > 50
    assert np.max(np.abs(coarse.capture_time - fine.capture_time)[both]) < 1e-4


def test_bitwise_the_same_whatever_the_workers_and_chunks(ref, design):
    for kw in ({"workers": 1}, {"workers": 2, "chunk_size": 24}, {"workers": 2, "chunk_size": 24 * 5}):
        assert same(region_of_attraction(BENCH, n=24, design=design, t_end=6.0, **kw), ref), kw


def test_a_cell_is_the_start_it_names(ref, design):
    """The grid's layout checked cell by cell against a single start integrated alone."""
    from skewpend.numeric.control import capture_many
    from skewpend.numeric.kernels import kernel_module, parameter_vector

    target = design.linearization.target
    for a, b in ((0, 5), (11, 17), (23, 2)):
        y0 = target.copy()
        y0[0], y0[1] = ref.x0[a], ref.y0[b]
        t, _, _, status = capture_many(kernel_module(BENCH, flip=True), parameter_vector(BENCH), design.controller(), y0[None, :],
                                    t_end=6.0, rtol=1e-8, atol=1e-8, max_steps=200_000, P=design.P, rho=design.rho)
        assert status[0] == 0 and t.tobytes() == ref.capture_time[a:a + 1, b].tobytes()


def test_the_lanes_agree_with_the_scalar_integration(ref, design):
    """The map's starts run eight side by side in SIMD lanes (sp_capture_lanes, on the flip map's
    trigonometry-free state); the scalar DOP853 of simulate's kernel (sp_capture_many, one start at
    a time) classifies every cell the same, and the capture times agree to the integration's
    accuracy; a start's bits do not depend on the lane or on the other starts."""
    from skewpend.numeric.control import capture_lanes_available, capture_many
    from skewpend.numeric.kernels import kernel_module, parameter_vector

    ctl, pv = design.controller(), parameter_vector(BENCH)
    lanes, scalar = kernel_module(BENCH, flip=True), kernel_module(BENCH)
    assert capture_lanes_available(lanes, ctl) and not capture_lanes_available(scalar, ctl)
    X, Y = np.meshgrid(ref.x0, ref.y0, indexing="ij")
    starts = np.tile(design.linearization.target, (X.size, 1))
    starts[:, 0], starts[:, 1] = X.ravel(), Y.ravel()
    kw = dict(t_end=6.0, rtol=1e-8, atol=1e-8, max_steps=200_000, P=design.P, rho=design.rho)
    t1, s1, _, st1 = capture_many(lanes, pv, ctl, starts, **kw)
    t0, s0, _, st0 = capture_many(scalar, pv, ctl, starts, **kw)
    assert t1.tobytes() == ref.capture_time.ravel().tobytes()
    assert not st0.any() and not st1.any() and np.array_equal(np.isnan(t0), np.isnan(t1))
    both = np.isfinite(t0) & (t0 > 0)
    assert both.sum() > 100 and np.max(np.abs(t0 - t1)[both]) < 1e-4
    order = np.random.default_rng(3).permutation(len(starts))  # other lanes, other neighbours
    t2, s2, _, _ = capture_many(lanes, pv, ctl, starts[order], **kw)
    assert t2.tobytes() == t1[order].tobytes() and np.array_equal(s2, s1[order])


def test_the_law_s_switches_are_stepped_to_not_rejected_around(ref, design):
    """The lanes stop each DOP853 step at the law's switches (saturation kinks, wrap jumps; cut where
    the switch functions' chord crosses zero), where the scalar integration rejects steps around
    every switch until they are small enough: at the same tolerance (1e-8) fewer steps in all (about
    26 % fewer measured), and capture times closer to a tight reference (the scalar integration at
    1e-12, independent of the lanes): a few 1e-9 s typical, every one within 1e3 x the tolerance."""
    from skewpend.numeric.control import capture_many
    from skewpend.numeric.kernels import kernel_module, parameter_vector

    ctl, pv = design.controller(), parameter_vector(BENCH)
    X, Y = np.meshgrid(ref.x0, ref.y0, indexing="ij")
    starts = np.tile(design.linearization.target, (X.size, 1))
    starts[:, 0], starts[:, 1] = X.ravel(), Y.ravel()
    kw = dict(t_end=6.0, max_steps=2_000_000, P=design.P, rho=design.rho)
    t1, s1, r1, _ = capture_many(kernel_module(BENCH, flip=True), pv, ctl, starts, rtol=1e-8, atol=1e-8, **kw)
    t0, s0, r0, _ = capture_many(kernel_module(BENCH), pv, ctl, starts, rtol=1e-8, atol=1e-8, **kw)
    tr, _, _, st = capture_many(kernel_module(BENCH), pv, ctl, starts, rtol=1e-12, atol=1e-12, **kw)
    assert not st.any() and np.array_equal(np.isnan(t1), np.isnan(tr))
    assert (s1 + r1).sum() < 0.85 * (s0 + r0).sum()  # the steps attempted
    moved = np.isfinite(tr) & (tr > 0)
    e1, e0 = np.abs(t1 - tr)[moved], np.abs(t0 - tr)[moved]
    assert moved.sum() > 100 and np.median(e1) < 0.5 * np.median(e0) and np.median(e1) < 1e-8
    assert e1.max() < 1e3 * 1e-8


def test_steps_count_accepted_steps_and_rejected_the_rejected(design):
    """The result protocol's statistics (issue 36: the rejected steps were counted as steps, in the
    lanes too): a start's ``steps`` are its accepted steps, as simulate() counts them for the same
    start, law and tolerance (DOP853 there on the state and W, here on the state alone; the lanes
    also stop steps at the law's switches: a few steps either way, measured <= 3 of 22-50), and
    ``rejected`` its rejected ones -- their sum is what ``max_steps`` caps, so a start stopped by
    the cap has attempted exactly ``max_steps``.  A map's stats add the cells' counts."""
    from skewpend.numeric.control import capture_many
    from skewpend.numeric.kernels import kernel_module, parameter_vector

    ctl, pv = design.controller(), parameter_vector(BENCH)
    starts = np.tile(design.linearization.target, (12, 1))
    starts[:, :2] += np.random.default_rng(5).uniform(-2.5, 2.5, (12, 2))
    kw = dict(t_end=3.0, rtol=1e-8, atol=1e-8, P=design.P, rho=0.0)  # rho = 0: never captured, run to t_end
    alone = [skewpend.simulate(BENCH, y0, 3.0, controller=ctl, method="dop853", rtol=1e-8, atol=1e-8).stats
             for y0 in starts]
    accepted = np.array([st["steps"] for st in alone])
    assert sum(st["rejected"] for st in alone) > 0.2 * accepted.sum()  # enough rejections to tell the counts apart
    for kernel in (kernel_module(BENCH, flip=True), kernel_module(BENCH)):
        t, steps, rejected, status = capture_many(kernel, pv, ctl, starts, max_steps=200_000, **kw)
        assert not status.any() and np.isnan(t).all() and (rejected >= 0).all()
        assert np.all(np.abs(steps - accepted) <= np.maximum(3, 0.1 * accepted)), (steps, accepted)
        assert abs(steps.sum() - accepted.sum()) < 0.05 * accepted.sum()
        cap = 40
        t, steps, rejected, status = capture_many(kernel, pv, ctl, starts, max_steps=cap, **kw)
        stopped = status == skewpend.Status.MAX_STEPS
        assert stopped.any() and np.all(steps[stopped] + rejected[stopped] == cap)
        assert np.all(steps[~stopped] + rejected[~stopped] <= cap)
    r = region_of_attraction(BENCH, n=4, design=design, t_end=2.0)
    assert r.stats["steps"] > 0 and r.stats["rejected"] >= 0 and {"steps", "rejected"} <= set(r.stats)


def test_no_cell_fails_at_a_tight_tolerance(design):
    """At rtol = atol = 1e-12 the switch events must not cut steps down to the underflow (a switch
    surface only grazed, or a step starting just before a wrap's jump, did: 6 of these 1024 cells
    failed): every cell completes, classified as at the map's default tolerance."""
    tight = region_of_attraction(BENCH, n=32, design=design, t_end=10.0, rtol=1e-12, atol=1e-12)
    assert tight.stats["failed"] == 0
    assert np.array_equal(tight.outcome, region_of_attraction(BENCH, n=32, design=design, t_end=10.0).outcome)


def test_other_planes_vary_the_speeds(design):
    r = region_of_attraction(BENCH, n=8, design=design, plane=("phi", "dphi"), window=((-0.5, 0.5), (-40.0, 40.0)),
                             t_end=6.0)
    assert r.plane == ("phi", "dphi") and np.allclose(r.y0, np.linspace(-35.0, 35.0, 8))
    # 5 rad/s about the target: captured within ~1.2 s; 35 rad/s: whirls away, not within 6 s
    assert r.captured[:, 3:5].all() and np.all(r.capture_time[:, 3:5] < 2.0) and not r.captured[:, [0, 7]].any()
    assert r.to_xarray()["capture_time"].dims == ("phi0", "dphi0")
    e = r.ellipse()
    S = design.P[np.ix_([0, 2], [0, 2])]
    assert np.allclose(np.einsum("ki,ij,kj->k", e, S, e), design.rho)
    # the layout: cell (2, 6) is the start with phi0 = x0[2], phi0' = y0[6], the rest at the target
    from skewpend.numeric.control import capture_many
    from skewpend.numeric.kernels import kernel_module, parameter_vector

    y0 = design.linearization.target.copy()
    y0[0], y0[2] = r.x0[2], r.y0[6]
    t, _, _, _ = capture_many(kernel_module(BENCH, flip=True), parameter_vector(BENCH), design.controller(), y0[None, :], t_end=6.0,
                           rtol=1e-8, atol=1e-8, max_steps=200_000, P=design.P, rho=design.rho)
    assert t.tobytes() == r.capture_time[2:3, 6].tobytes()


def test_failed_cells_are_reported_not_guessed(design):
    r = region_of_attraction(BENCH, n=6, design=design, t_end=6.0, max_steps=10)  # 5 is refused up front now (issue 29: the estimate before any work)
    assert r.status == skewpend.Status.PARTIAL and r.stats["failed"] > 0
    failed = r.outcome == -1
    assert np.all(np.isnan(r.capture_time[failed])) and "failed" in r.message
    # chattering: a start at rest exactly opposite the target, where the wrapped feedback jumps
    from skewpend.numeric.control import capture_many
    from skewpend.numeric.kernels import kernel_module, parameter_vector

    y0 = np.array([0.0, -0.648, 0.0, 0.0])  # phi - pi wraps to -pi: the jump
    t, steps, rejected, status = capture_many(kernel_module(BENCH, flip=True), parameter_vector(BENCH), design.controller(), y0[None, :],
                                    t_end=10.0, rtol=1e-8, atol=1e-8, max_steps=20_000, P=design.P, rho=design.rho)
    assert status[0] != 0 and math.isnan(t[0])


def test_netcdf_round_trip(tmp_path, ref):
    path = tmp_path / "roa.nc"
    ref.to_netcdf(path)
    back = open_region_of_attraction(path)
    assert same(back, ref) and back.plane == ref.plane and back.rho == ref.rho
    assert np.array_equal(back.P, ref.P) and back.captured_fraction == ref.captured_fraction


# -- the store: resume after kill -9 ----------------------------------------------------------------------
_RUN = """
import sys, time, skewpend
from skewpend.analysis.roa import region_of_attraction
from skewpend.config import reference_parameters
p = reference_parameters()
d = skewpend.lqr(p, "up-up", "both", umax=10.0)
def progress(done, total):
    print(done, flush=True)
    time.sleep(0.05)
region_of_attraction(p, n=24, design=d, t_end=6.0, workers=1, chunk_size=24, store=sys.argv[1], progress=progress)
print("finished", flush=True)
"""


def test_a_killed_run_resumes_to_the_same_bits(tmp_path, ref, design):
    pytest.importorskip("zarr")
    path = tmp_path / "roa.zarr"
    proc = subprocess.Popen([sys.executable, "-c", _RUN, str(path)], stdout=subprocess.PIPE, stderr=subprocess.PIPE,
                            text=True)
    try:
        lines = [proc.stdout.readline().strip() for _ in range(6)]
        assert "finished" not in lines and all(lines), (lines, proc.stderr.read() if proc.poll() is not None else "")
        proc.send_signal(signal.SIGKILL)
        proc.communicate(timeout=30)
    finally:
        if proc.poll() is None:
            proc.kill()
            proc.wait()
    with pytest.raises(ParameterError, match="not complete"):
        open_region_of_attraction(path)
    r = region_of_attraction(BENCH, n=24, design=design, t_end=6.0, store=path, resume=True, workers=2)
    assert 0 < r.stats["chunks_resumed"] < 24 and r.stats["chunks_computed"] == 24 - r.stats["chunks_resumed"]
    assert same(r, ref) and same(open_region_of_attraction(path), ref)
    with pytest.raises(ParameterError, match="t_end"):  # other settings: refused, naming what differs
        region_of_attraction(BENCH, n=24, design=design, t_end=5.0, store=path, resume=True)


# -- bad input ------------------------------------------------------------------------------------------
@pytest.mark.parametrize("kwargs, exc, match", [
    ({"plane": ("phi", "phi")}, ParameterError, "plane"),
    ({"plane": ("phi", "theta")}, ParameterError, "plane"),
    ({"window": ((-4.0, 1.0), (-1.0, 1.0))}, ParameterError, "within"),
    ({"window": ((1.0, -1.0), (-1.0, 1.0))}, ParameterError, "start < stop"),
    ({"window": (-1.0, 1.0)}, ParameterError, "window"),
    ({"n": 0}, ParameterError, "n must"),
    ({"n": 5000}, ParameterError, "at most"),
    ({"t_end": -1.0}, ParameterError, "t_end"),
    ({"Q": np.zeros((4, 4))}, EquilibriumError, "umax"),  # was umax=1e-4: its estimate is tiny (about 1e-10), not empty
    ({"actuated": "acrobot", "params": skewpend.Parameters(a=1.0, b=0.8, m1=1.0, m2=0.7, alpha=math.pi / 2, g=9.81)},
     EquilibriumError, "not controllable"),
    ({"design": "lqr"}, ParameterError, "design"),
])
def test_bad_input_is_refused_in_one_line(kwargs, exc, match):
    kwargs = dict(kwargs)
    params = kwargs.pop("params", BENCH)
    with pytest.raises(exc, match=match):
        region_of_attraction(params, **{"n": 4, **kwargs})


def test_a_design_for_other_parameters_is_refused(design):
    other = skewpend.Parameters(a=1.0, b=0.8, m1=1.0, m2=0.7, alpha=0.3, g=9.81)
    with pytest.raises(ParameterError, match="other parameters"):
        region_of_attraction(other, n=4, design=design)


# -- figure and CLI ------------------------------------------------------------------------------------------
def test_the_figure_draws_the_map_and_the_estimate(ref, tmp_path):
    from skewpend.views.figures import roa_figure, save_figure

    fig = roa_figure(ref)
    ax = fig.axes[0]
    line = ax.lines[0].get_xydata()
    assert np.allclose(np.radians(line), ref.ellipse(), atol=1e-12)
    assert any("captured" in t.get_text() for t in fig.texts)
    save_figure(fig, tmp_path / "roa.png")
    assert (tmp_path / "roa.png").stat().st_size > 10_000


def test_cli_roa(tmp_path):
    from helpers import run_cli

    ran = run_cli(["control", "roa", "--n", "16", "--t-end", "6", "--out", "r.nc", "--plot", "r.png"], cwd=tmp_path)
    assert ran.code == 0, ran.report()
    assert "captured" in ran.out and (tmp_path / "r.nc").exists() and (tmp_path / "r.png").exists()
    back = open_region_of_attraction(tmp_path / "r.nc")
    assert back.n == 16 and back.settings["t_end"] == 6.0 and back.settings["umax"] == [10.0, 10.0]


@pytest.mark.parametrize("argv, text", [
    (["control", "roa", "--plane", "phi"], "--plane"),
    (["control", "roa", "--window", "-1:1"], "--window"),
    (["control", "roa", "--window", "1:-1,0:1"], "--window"),
    (["control", "roa", "--window", "-200:0deg,-1:1"], "within"),
    (["control", "roa", "--out", "r.csv"], "--out"),
    (["control", "roa", "--resume"], "--resume"),
    (["control", "roa", "--animate", "r.gif"], "--animate"),
    (["control", "roa", "--energy-gain", "3"], "--energy-gain"),
    (["control", "roa", "--n", "0"], "--n"),
    (["control", "roa", "--q", "0,0,0,0"], "umax"),  # was --umax 1e-4: its estimate is tiny (about 4e-9), not empty
    (["control", "swingup", "--n", "8"], "--n"),
    (["control", "lqr", "--workers", "2"], "--workers"),
])
def test_cli_roa_bad_input(argv, text, tmp_path):
    from helpers import run_cli

    ran = run_cli(argv, cwd=tmp_path)
    assert ran.code == 2, ran.report()
    assert text in ran.err and len(ran.err.strip().splitlines()) == 1, ran.report()
    assert not any(tmp_path.iterdir())
