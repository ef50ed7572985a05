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


@pytest.fixture(scope="module", params=[None, "dop853"])
def bench_run(request):
    """The default (method 'auto': taylor here) and dop853 named."""
    kw = {} if request.param is None else {"method": request.param}
    return simulate(BENCH, Y0, 20.0, dt_out=0.01, **kw)


def test_default_method_matches_scipy_and_conserves_energy(bench_run):
    tr = bench_run
    auto = tr.settings.get("method") == "auto"
    assert tr.success and tr.status == 0 and tr.method == ("taylor" if auto else "dop853")
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
    with pytest.raises(IntegrationError, match="taylor: stopped"):  # the default: auto, taylor here
        simulate(BENCH, (0.1, 0.0, 1e150, 0.0), 1.0, max_steps=100_000, throw=True)
    with pytest.raises(IntegrationError, match="dop853: stopped"):
        simulate(BENCH, (0.1, 0.0, 1e150, 0.0), 1.0, max_steps=100_000, throw=True, method="dop853")
    with pytest.raises(ParameterError, match="not finite \\(overflow\\)"):
        simulate(BENCH, (0.1, 0.0, 1e160, 0.0), 1.0)


@pytest.mark.parametrize("method", ["auto", "dop853", "taylor"])
def test_max_steps_status(method):
    """A cap that the first bounded call reaches stops the run there with its status, for every
    adaptive method (taylor rejects no step: its cap and its first call's budget used to coincide)."""
    tr = simulate(BENCH, Y0, 20.0, max_steps=10, method=method)
    assert tr.status == 3 and "maximum number of steps" in tr.message
    assert tr.t[-1] < 20.0 and tr.stats["steps"] + tr.stats["rejected"] == 10


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


# -- the default method, "auto" (issue 36): the fastest method that serves the request -------------------

REGULAR = (0.3, -0.2, 0.0, 0.0)  # small swings: no chaos, errors grow slowly


def _kinds():
    from skewpend.numeric.control import Controller

    table = Controller.table([0.0, 1.0, 2.0], [[0.0, 0.0], [0.2, -0.1], [0.0, 0.1]])
    feedback = Controller.feedback(np.array([[2.0, 0.2, 0.5, 0.1], [0.1, 1.0, 0.05, 0.2]]), [0, 0, 0, 0], umax=1.0)
    return [
        ("own steps", BENCH, {}, "taylor"),
        ("dense grid", BENCH, {"dt_out": 0.05}, "taylor"),
        ("streamed, first and last kept", BENCH, {"keep": False, "out": "run.csv"}, "taylor"),
        ("Coulomb friction and damping", BENCH.replace(cf1=0.05, cf2=0.03, c1=0.02), {"dt_out": 0.05}, "taylor"),
        ("a torque table", BENCH, {"controller": table}, "dop853"),
        ("a feedback law", BENCH, {"controller": feedback, "dt_out": 0.05}, "dop853"),
        ("a Python law", BENCH, {"controller": Controller.function(lambda t, x: (0.1 * np.sin(t), -0.05 * x[1]))},
         "dop853"),
    ]


@pytest.mark.parametrize("kind", range(7), ids=[k[0] for k in _kinds()])
@pytest.mark.parametrize("rtol", [1e-7, 1e-10])
def test_auto_picks_the_method_that_serves_the_request_and_agrees_with_dop853(kind, rtol, tmp_path):
    """Each kind of request: the method AUTO_RULE names, the choice in the settings and the summary,
    and the result agrees with dop853 named at the same tolerances.  Both methods keep each step's
    local error below rtol (of max(1, |y|), the state is O(1)); over 5 s of this regular motion (no
    exponential growth) their global errors stay within a few tens of rtol (measured <= 16 rtol,
    dense output included: dop853's interpolant adds about 10 rtol), so 100 rtol bounds the
    difference -- a method run at a 100x looser tolerance would not pass."""
    from skewpend.numeric.simulation import AUTO_RULE

    name, params, kw, expected = _kinds()[kind]
    kw = {k: (tmp_path / v if k == "out" else v) for k, v in kw.items()}
    tr = simulate(params, REGULAR, 5.0, rtol=rtol, atol=rtol, **kw)
    assert tr.ok and tr.method == expected
    assert tr.settings["method"] == "auto" and tr.settings["method_choice"].startswith(expected + ":")
    assert tr.settings["method_choice"] == AUTO_RULE["controller" if expected == "dop853" else "taylor"]
    assert f"{expected}, t = 0 .. 5 s" in tr.summary() and "chosen by method 'auto'" in tr.summary()
    if "out" in kw:
        kw["out"] = tmp_path / "dop853.csv"
    ref = simulate(params, REGULAR, 5.0, rtol=rtol, atol=rtol, method="dop853", **kw)
    if expected == "dop853":  # the same integrator: the same bits
        np.testing.assert_array_equal(tr.y, ref.y)
    elif "dt_out" in kw:
        np.testing.assert_array_equal(tr.t, ref.t)
        assert np.max(np.abs(tr.y - ref.y)) < 100 * rtol
    else:
        assert tr.t[-1] == ref.t[-1] == 5.0 and np.max(np.abs(tr.y[-1] - ref.y[-1])) < 100 * rtol


def test_auto_refuses_a_fixed_step_and_names_the_methods_that_take_one():
    with pytest.raises(ParameterError, match="dt is the step of rk4 and gauss; the default method 'auto'"):
        simulate(BENCH, Y0, 1.0, dt=1e-3)
    with pytest.raises(ParameterError, match="unknown method 'euler'; allowed: auto, dop853, rk4, gauss, taylor"):
        simulate(BENCH, Y0, 1.0, method="euler")


def test_auto_falls_back_to_dop853_for_equations_without_series(monkeypatch):
    """A model whose equations have a function without a series recurrence (none today: the
    generator's ValueError is simulated) runs dop853 under auto, saying why; taylor named is refused."""
    from skewpend.numeric import kernels

    def no_series(*args, **kwargs):
        raise ValueError("taylor kernel: no series recurrence for erf (in erf(x))")

    params = BENCH.replace(alpha=0.55)  # a Parameters object of its own: nothing prepared for it yet
    monkeypatch.setattr(kernels, "taylor_kernel", no_series)
    monkeypatch.setattr(kernels, "_TAYLOR_OF", {})
    tr = simulate(params, REGULAR, 1.0)
    assert tr.method == "dop853" and tr.settings["method_choice"] == "dop853: taylor kernel: no series recurrence " \
        "for erf (in erf(x))"
    np.testing.assert_array_equal(tr.y, simulate(params, REGULAR, 1.0, method="dop853").y)
    with pytest.raises(ParameterError, match="method taylor: taylor kernel: no series recurrence for erf"):
        simulate(params, REGULAR, 1.0, method="taylor")


@pytest.mark.parametrize("inner_method", ["auto", "dop853", "rk4", "table"])
def test_a_simulation_inside_a_python_law_is_the_same_as_outside(inner_method):
    """Re-entrancy (issue 36): the compiled code's active inputs belong to one call, so a simulate()
    run inside a Python law -- without inputs, or with its own -- gives what the same call gives
    outside (the same code on the same numbers: the same bits), and the outer run is undisturbed."""
    from skewpend.numeric.control import Controller

    inner_kw = {"auto": {}, "dop853": {"method": "dop853"}, "rk4": {"method": "rk4", "dt": 1e-3},
                "table": {"controller": Controller.table([0.0, 1.0], [[0.3, 0.0], [0.0, -0.2]])}}[inner_method]
    alone = simulate(BENCH, Y0, 1.0, **inner_kw)
    law_alone = Controller.function(lambda t, x: (0.5, -0.1 * x[3]))
    outer_alone = simulate(BENCH, Y0, 0.3, controller=law_alone, method="dop853")
    inner = []

    def law(t, x):
        if not inner:
            inner.append(None)  # (before the call: the inner run must not recurse into this law)
            inner[0] = simulate(BENCH, Y0, 1.0, **inner_kw)
        return (0.5, -0.1 * x[3])

    outer = simulate(BENCH, Y0, 0.3, controller=Controller.function(law), method="dop853")
    np.testing.assert_array_equal(inner[0].y, alone.y)
    np.testing.assert_array_equal(inner[0].t, alone.t)
    np.testing.assert_array_equal(outer.y, outer_alone.y)
