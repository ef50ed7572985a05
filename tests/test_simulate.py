"""simulate(): accuracy against SciPy, energy accounting, convergence orders, failure status."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.integrate import solve_ivp

from skewpend import IntegrationError, ParameterError
from skewpend.numeric.codegen import generate, parameter_vector
from skewpend.numeric.simulation import simulate

from skewpend.config import reference_parameters  # noqa: E402
BENCH = reference_parameters()  # the reference case: a = 1, b = 0.8, m1 = 1, m2 = 0.7, alpha = 0.6, g = 9.81
Y0 = (1.2, -0.8, 0.0, 0.0)


def _scipy_reference(params, y0, t_eval, rtol=1e-13, atol=1e-13):
    """SciPy's DOP853 on the generated standalone Python right-hand side."""
    ns: dict = {}
    exec(generate(params, "python"), ns)
    p = parameter_vector(params).tolist()
    sol = solve_ivp(ns["rhs"], (0.0, t_eval[-1]), y0, method="DOP853", rtol=rtol, atol=atol, t_eval=t_eval, args=(p,))
    assert sol.success
    return sol.y.T


@pytest.fixture(scope="module")
def bench_run():
    return simulate(BENCH, Y0, 20.0, dt_out=0.01)


def test_default_method_matches_scipy_and_conserves_energy(bench_run):
    tr = bench_run
    assert tr.success and tr.status == 0 and tr.method == "dop853"
    assert tr.y.shape == (2001, 4) and tr.t[-1] == pytest.approx(20.0)
    np.testing.assert_allclose(tr.t, np.arange(2001) * 0.01, atol=1e-12)
    ref = _scipy_reference(BENCH, Y0, np.array([0.0, 5.0]))
    i5 = 500
    # issue 3: error at t = 5 s below 1e-8 at rtol = atol = 1e-10
    assert np.max(np.abs(tr.y[i5] - ref[-1])) < 1e-8
    assert tr.energy_drift < 1e-9
    assert np.all(tr.work == 0.0)
    assert tr.energy[0] == pytest.approx(tr.energy[-1], abs=1e-8)


def test_own_steps_end_exactly_at_t_end():
    tr = simulate(BENCH, Y0, 3.0)
    assert tr.t[0] == 0.0 and tr.t[-1] == 3.0
    assert np.all(np.diff(tr.t) > 0)
    assert tr.stats["steps"] == tr.t.size - 1


def test_dense_output_agrees_with_own_steps():
    own = simulate(BENCH, Y0, 2.0, rtol=1e-12, atol=1e-12)
    grid = simulate(BENCH, Y0, 2.0, dt_out=0.05, rtol=1e-12, atol=1e-12)
    ref = _scipy_reference(BENCH, Y0, grid.t)
    assert np.max(np.abs(grid.y - ref)) < 1e-9
    assert np.max(np.abs(own.y[-1] - grid.y[-1])) < 1e-12


def test_damping_and_torques_energy_accounting():
    p = BENCH.replace(c1=0.05, c2=0.03, tau1=0.2, tau2=-0.1)
    tr = simulate(p, Y0, 10.0, dt_out=0.01)
    assert tr.success
    ref = _scipy_reference(p, Y0, tr.t[[0, -1]])
    assert np.max(np.abs(tr.y[-1] - ref[-1])) < 1e-7
    # E - W is conserved: the work of damping and torques accounts for every joule
    assert np.max(np.abs(tr.energy - tr.work - tr.energy[0])) < 1e-8 * np.max(np.abs(tr.energy))
    assert tr.energy_drift < 1e-8
    assert abs(tr.energy[-1] - tr.energy[0]) > 1e-2  # energy really changed


def _order(method, params, y0, t_end, steps):
    ref = _scipy_reference(params, y0, np.array([0.0, t_end]))[-1]
    errs = []
    for dt in steps:
        tr = simulate(params, y0, t_end, method=method, dt=dt)
        errs.append(np.max(np.abs(tr.y[-1] - ref)))
    return np.polyfit(np.log(steps), np.log(errs), 1)[0], errs


@pytest.mark.parametrize("method", ["rk4", "gauss"])
def test_fixed_step_convergence_order_on_the_pendulum(method):
    steps = np.array([0.04, 0.02, 0.01, 0.005])
    order, errs = _order(method, BENCH, (0.6, -0.4, 0.0, 0.0), 2.0, steps)
    assert 3.7 < order < 4.4, (order, errs)


@pytest.mark.slow
def test_symplectic_energy_error_bounded_over_a_million_steps():
    """Gauss-Legendre: no secular drift over 10^6 steps; RK4 with the same step drifts."""
    y0 = (0.5, -0.3, 0.0, 0.0)
    gl = simulate(BENCH, y0, 10_000.0, method="gauss", dt=0.01, dt_out=1.0)
    assert gl.success and gl.stats["steps"] == 1_000_000
    err = np.abs(gl.energy - gl.energy[0])
    first, last = err[: err.size // 10].max(), err[-err.size // 10 :].max()
    assert last < 3 * first + 1e-13, (first, last)
    assert err.max() < 1e-6 * abs(gl.energy[0])
    rk = simulate(BENCH, y0, 1_000.0, method="rk4", dt=0.01, dt_out=1.0)
    rk_err = np.abs(rk.energy - rk.energy[0])
    assert rk_err[-1] > 5 * rk_err[rk_err.size // 10]  # secular (linear) growth


def test_blow_up_is_a_status_not_nans():
    tr = simulate(BENCH, (0.1, 0.0, 1e150, 0.0), 1.0, max_steps=100_000)
    assert tr.status in (1, 2, 3) and not tr.success and tr.message.startswith("stopped")
    assert np.all(np.isfinite(tr.y)) and np.all(np.isfinite(tr.energy))
    assert np.isfinite(tr.energy_drift)
    with pytest.raises(IntegrationError, match="dop853: stopped"):
        simulate(BENCH, (0.1, 0.0, 1e150, 0.0), 1.0, max_steps=100_000, throw=True)
    with pytest.raises(ParameterError, match="not finite \\(overflow\\)"):
        simulate(BENCH, (0.1, 0.0, 1e160, 0.0), 1.0)


def test_max_steps_status():
    tr = simulate(BENCH, Y0, 20.0, max_steps=10)
    assert tr.status == 3 and "maximum number of steps" in tr.message
    assert tr.t[-1] < 20.0


def test_tips_are_rod_ends():
    tr = simulate(BENCH, Y0, 1.0, dt_out=0.5)
    tips = tr.tips()
    assert tips.shape == (3, 6)
    np.testing.assert_allclose(np.linalg.norm(tips[:, :3], axis=1), 1.0, rtol=1e-13)  # |tip1| = a
    np.testing.assert_allclose(np.linalg.norm(tips[:, 3:] - tips[:, :3], axis=1), 0.8, rtol=1e-13)  # |tip2 - tip1| = b
    # hanging state: both rods along +j (down)
    rest = simulate(BENCH, (0, 0, 0, 0), 0.5, dt_out=0.5).tips()
    np.testing.assert_allclose(rest[0], [0, 1.0, 0, 0, 1.8, 0], atol=1e-14)


@pytest.mark.parametrize(
    "kwargs, message",
    [
        (dict(t_end=-1.0), "t_end must be a positive"),
        (dict(method="euler"), "unknown method 'euler'"),
        (dict(y0=(0, 0, 0)), "y0 must be 4 numbers"),
        (dict(y0=(0, np.nan, 0, 0)), "y0 must be finite"),
        (dict(rtol=0.0), "rtol must be a positive"),
        (dict(dt_out=30.0), "dt_out .* must not exceed t_end"),
        (dict(method="rk4", dt=0.003), "whole number of steps"),
        (dict(method="rk4", dt=0.01, dt_out=0.015), "whole multiple of dt"),
    ],
)
def test_bad_arguments(kwargs, message):
    args = dict(y0=Y0, t_end=20.0)
    args.update(kwargs)
    with pytest.raises(ParameterError, match=message):
        simulate(BENCH, args.pop("y0"), args.pop("t_end"), **args)


def test_symbolic_parameters_are_refused():
    from skewpend import NotNumericError

    with pytest.raises(NotNumericError, match="symbolic: g"):
        simulate(BENCH.replace(g=None), Y0, 1.0)


@pytest.mark.parametrize("method, t_end", [("dop853", 1e9), ("rk4", 1e9)])
def test_unfinishable_run_is_refused_naming_max_steps_not_a_flag(method, t_end):
    """Refused before the work (rk4: t_end/dt; dop853: the driver's estimate after the first bounded
    call), in the library's names: the command line maps max_steps to its flag."""
    with pytest.raises(ParameterError, match=r"max_steps = 100000000") as info:
        simulate(BENCH, Y0, t_end, method=method)
    assert "--" not in str(info.value)
