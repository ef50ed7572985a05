"""The compiled integrators of the ``_kernels.py`` template: order, accuracy, symplecticity, status.

A generated-style module is built exactly as :mod:`skewpend.codegen` builds one -- a header
with ``import``s and njit ``rhs`` / ``ham_rhs``, followed by the text of ``_kernels.py`` --
written to a temporary directory and imported.  To compile the integrators only once, the
test right-hand side serves several problems, chosen by ``p[0]``:

* 0 -- harmonic oscillator ``q'' = -w^2 q`` (``w = p[1]``), exact solution known;
* 1 -- pendulum ``q'' = -sin q``, Hamiltonian ``H = p^2/2 - cos q``;
* 2 -- ``y' = y^2`` (blows up at ``t = 1/y0``);
* 3 -- ``y' = 1`` for ``y < 1.5``, undefined (NaN) beyond.
"""

import ast
import importlib.util
import math
import subprocess
import sys
import uuid
from pathlib import Path

import numpy as np
import pytest
from scipy.integrate import solve_ivp

import skewpend

HEADER = '''"""Test problems (generated-style module)."""
import math
import numpy as np
import numba as nb


@nb.njit(cache=True)
def rhs(y, p, out):
    kind = int(p[0])
    if kind == 0:
        out[0] = y[1]
        out[1] = -p[1] * p[1] * y[0]
    elif kind == 1:
        out[0] = y[1]
        out[1] = -math.sin(y[0])
    elif kind == 2:
        out[0] = y[0] * y[0]
        out[1] = 0.0
    else:
        out[0] = 1.0 if y[0] < 1.5 else math.nan
        out[1] = 0.0


@nb.njit(cache=True)
def ham_rhs(z, p, out):
    kind = int(p[0])
    if kind == 0:
        out[0] = z[1]
        out[1] = -p[1] * p[1] * z[0]
    elif kind == 1:
        out[0] = z[1]
        out[1] = -math.sin(z[0])
    else:
        out[0] = 1.0 if z[0] < 1.5 else math.nan
        out[1] = 0.0

'''

OSC, PEND, BLOWUP, NANWALL = 0.0, 1.0, 2.0, 3.0
W = 1.3  # oscillator frequency


def template_text() -> str:
    return (Path(skewpend.__file__).parent / "_kernels.py").read_text()


@pytest.fixture(scope="module")
def k(tmp_path_factory):
    directory = tmp_path_factory.mktemp("kernels")
    name = f"skewpend_test_model_{uuid.uuid4().hex}"
    path = directory / f"{name}.py"
    path.write_text(HEADER + "\n" + template_text())
    spec = importlib.util.spec_from_file_location(name, path)
    module = importlib.util.module_from_spec(spec)
    sys.modules[name] = module
    spec.loader.exec_module(module)
    yield module
    sys.modules.pop(name, None)


def osc_exact(t, q0=1.0, v0=0.0, w=W):
    return np.stack([q0 * np.cos(w * t) + v0 / w * np.sin(w * t), -q0 * w * np.sin(w * t) + v0 * np.cos(w * t)], -1)


def pend_H(z):
    return 0.5 * z[..., 1] ** 2 - np.cos(z[..., 0])


@pytest.fixture(scope="module")
def pendulum_reference():
    """The pendulum from (q, q') = (2, 0) at t = 10, by scipy to ~1e-13."""
    sol = solve_ivp(lambda t, y: [y[1], -math.sin(y[0])], (0.0, 10.0), [2.0, 0.0], method="DOP853", rtol=1e-13, atol=1e-13)
    assert sol.success
    return sol.y[:, -1]


def fitted_slope(x, y):
    return np.polyfit(np.log(x), np.log(y), 1)[0]


# -- the template itself ----------------------------------------------------------------------------------
def test_template_is_importable_alone_and_generated_definitions_win(k):
    import skewpend._kernels as standalone

    for name in ("rhs", "ham_rhs", "dop853", "rk4", "gauss_legendre"):
        assert hasattr(standalone, name)
    # it is appended after other code: a __future__ import there would be a SyntaxError
    tree = ast.parse(template_text())
    assert not any(isinstance(node, ast.ImportFrom) and node.module == "__future__" for node in ast.walk(tree))
    with pytest.raises(NotImplementedError):  # alone, rhs is a placeholder
        standalone.rhs(np.zeros(2), np.zeros(1), np.zeros(2))
    out = np.empty(2)
    k.rhs(np.array([1.0, 2.0]), np.array([OSC, W]), out)  # the test problem, not the placeholder
    np.testing.assert_array_equal(out, [2.0, -W * W])
    k.ham_rhs(np.array([0.5, 2.0]), np.array([PEND, 0.0]), out)
    np.testing.assert_array_equal(out, [2.0, -math.sin(0.5)])


# -- convergence orders of the fixed-step methods ---------------------------------------------------------
# over t = 10: h = 0.0625 ... 0.0039 (with h >= 0.1 the pendulum from q = 2 is not yet
# asymptotic for rk4 at t = 10: local slopes 3.2, 3.2, 3.7, 3.9, 3.9 from h = 0.2 down)
STEPS = [160, 320, 640, 1280, 2560]


def test_rk4_order(k, pendulum_reference):
    p = np.array([PEND, 0.0])
    errs, hs = [], []
    for n in STEPS:
        ts, ys, status, nfev = k.rk4(np.array([2.0, 0.0]), 0.0, 10.0 / n, n, p, n)
        assert status == 0 and nfev == 4 * n and ts[-1] == pytest.approx(10.0) and ys.shape == (2, 2)
        errs.append(np.max(np.abs(ys[-1] - pendulum_reference)))
        hs.append(10.0 / n)
    slope = fitted_slope(hs, errs)
    print(f"rk4 order {slope:.3f}, errors {errs}")
    assert abs(slope - 4.0) < 0.3


def test_gauss_legendre_order(k, pendulum_reference):
    p = np.array([PEND, 0.0])
    errs, hs = [], []
    for n in STEPS:
        ts, zs, status, nfev = k.gauss_legendre(np.array([2.0, 0.0]), 0.0, 10.0 / n, n, p, n, 1e-14, 100)
        assert status == 0 and ts[-1] == pytest.approx(10.0) and zs.shape == (2, 2)
        errs.append(np.max(np.abs(zs[-1] - pendulum_reference)))
        hs.append(10.0 / n)
    slope = fitted_slope(hs, errs)
    print(f"gauss-legendre order {slope:.3f}, errors {errs}")
    assert abs(slope - 4.0) < 0.3


def test_gauss_legendre_order_exact_solution(k):
    """The oscillator against its exact solution (a check independent of scipy)."""
    p = np.array([OSC, W])
    errs, hs = [], []
    for n in STEPS:
        ts, zs, status, _ = k.gauss_legendre(np.array([1.0, 0.0]), 0.0, 10.0 / n, n, p, n, 1e-14, 100)
        assert status == 0
        errs.append(np.max(np.abs(zs[-1] - osc_exact(10.0))))
        hs.append(10.0 / n)
    assert abs(fitted_slope(hs, errs) - 4.0) < 0.3


# -- dop853 -----------------------------------------------------------------------------------------------
TOLS = [1e-6, 1e-7, 1e-8, 1e-9, 1e-10, 1e-11]


def test_dop853_error_proportional_to_tolerance(k):
    """Error at t_end below 100 tol, ~ tol^1; accepted steps ~ tol^(-1/8).

    The controller keeps the error *estimate* -- O(h^8) (5th-order estimate squared over the
    3rd-order one, as in Hairer's DOP853) -- at ~tol per step, so h ~ tol^(1/8) and the number
    of steps ~ tol^(-1/8).  The 8th-order solution's true local error is O(h^9) ~ tol^(9/8),
    times tol^(-1/8) steps: the global error ~ tol ("tolerance proportionality").
    """
    p = np.array([OSC, W])
    t_end = 30.0
    errs, steps = [], []
    for tol in TOLS:
        ts, ys, status, nfev, nacc, nrej = k.dop853(np.array([1.0, 0.0]), 0.0, t_end, p, tol, tol, 0.0, 100000, np.empty(0))
        assert status == 0 and ts[-1] == t_end
        err = np.max(np.abs(ys[-1] - osc_exact(t_end)))
        assert err < 100 * tol, (tol, err)
        errs.append(err)
        steps.append(nacc)
    err_slope = fitted_slope(TOLS, errs)
    step_slope = fitted_slope(TOLS, steps)
    print(f"dop853: error ~ tol^{err_slope:.3f}, steps ~ tol^{step_slope:.4f}, errors {errs}, steps {steps}")
    assert abs(step_slope + 1.0 / 8.0) < 0.05
    assert 0.8 < err_slope < 1.2


def test_dop853_dense_output_matches_exact_solution(k):
    p = np.array([OSC, W])
    # (the error includes the global error, which grows with t: ~4.7 tol at t = 10, ~8.7 tol at t = 30)
    t_out = np.linspace(0.0, 10.0, 401)
    for tol in (1e-7, 1e-10):
        ts, ys, status, nfev, nacc, nrej = k.dop853(np.array([1.0, 0.0]), 0.0, 10.0, p, tol, tol, 0.0, 100000, t_out)
        assert status == 0
        np.testing.assert_array_equal(ts, t_out)
        np.testing.assert_array_equal(ys[0], [1.0, 0.0])
        err = np.max(np.abs(ys - osc_exact(t_out)))
        print(f"dense output tol {tol:g}: max error {err:.3g} ({nacc} steps)")
        assert err < 10 * tol
        # 12 evaluations per attempted step, 3 more per step with interior output points, 2 to start
        assert 2 + 12 * (nacc + nrej) < nfev <= 2 + 12 * (nacc + nrej) + 3 * nacc
    # output times within rounding beyond t_end get the final state
    ts, ys, status, *_ = k.dop853(np.array([1.0, 0.0]), 0.0, 1.0, p, 1e-9, 1e-9, 0.0, 1000, np.array([0.0, 1.0, 1.0 + 1e-13]))
    assert status == 0 and len(ts) == 3
    np.testing.assert_array_equal(ys[2], ys[1])


def test_dop853_rejects_bad_output_times(k):
    p = np.array([OSC, W])
    for t_out in (np.array([0.0, 2.0]), np.array([0.5, 0.2]), np.array([-0.1, 0.5])):
        with pytest.raises(ValueError):
            k.dop853(np.array([1.0, 0.0]), 0.0, 1.0, p, 1e-8, 1e-8, 0.0, 1000, t_out)


def test_dop853_own_steps_match_scipy(k):
    """Own steps: t0 first, the last exactly t_end; the step sequence is scipy's DOP853's.

    Only to ~1e-6: the error estimate is a sum of O(1) terms cancelling to O(tol), so the
    summation order alone changes it by ~eps/tol relative, and h by 1/8 of that.
    """
    p = np.array([PEND, 0.0])
    y0 = np.array([2.0, 0.0])
    t_end = 12.345
    pend = lambda t, y: [y[1], -math.sin(y[0])]  # noqa: E731
    for h0 in (0.0, 0.05):  # automatic and given initial step
        ts, ys, status, nfev, nacc, nrej = k.dop853(y0, 0.0, t_end, p, 1e-8, 1e-10, h0, 100000, np.empty(0))
        assert status == 0
        assert ts[0] == 0.0 and ts[-1] == t_end and np.all(np.diff(ts) > 0)
        assert len(ts) == nacc + 1 and ys.shape == (nacc + 1, 2)
        np.testing.assert_array_equal(ys[0], y0)
        sol = solve_ivp(pend, (0.0, t_end), y0, method="DOP853", rtol=1e-8, atol=1e-10, first_step=h0 if h0 > 0 else None)
        assert len(sol.t) == len(ts) and sol.nfev == nfev
        if h0 == 0.0:
            assert ts[1] == pytest.approx(sol.t[1], rel=1e-12)  # the same automatic initial step
        np.testing.assert_allclose(ts, sol.t, rtol=0, atol=1e-6)
        ref = solve_ivp(pend, (0.0, t_end), y0, method="DOP853", rtol=1e-13, atol=1e-13, t_eval=ts)
        assert np.max(np.abs(ys - ref.y.T)) < 1e-6


def test_dop853_max_steps(k):
    p = np.array([OSC, W])
    ts, ys, status, nfev, nacc, nrej = k.dop853(np.array([1.0, 0.0]), 0.0, 100.0, p, 1e-10, 1e-10, 0.0, 5, np.empty(0))
    assert status == 3 and nacc + nrej == 5 and len(ts) == nacc + 1 and ts[-1] < 100.0
    np.testing.assert_allclose(ys, osc_exact(ts), atol=1e-8)
    ts, ys, status, *_ = k.dop853(np.array([1.0, 0.0]), 0.0, 100.0, p, 1e-10, 1e-10, 0.0, 5, np.linspace(0, 100, 11))
    assert status == 3 and len(ts) == 1 and ts[0] == 0.0


def test_dop853_blow_up(k):
    """y' = y^2, y(0) = 1: y = 1/(1 - t) blows up at t = 1 < t_end = 2."""
    p = np.array([BLOWUP, 0.0])
    for t_out in (np.empty(0), np.linspace(0.0, 2.0, 201)):
        ts, ys, status, nfev, nacc, nrej = k.dop853(np.array([1.0, 0.0]), 0.0, 2.0, p, 1e-8, 1e-8, 0.0, 100000, t_out)
        assert status in (1, 2)
        assert len(ts) >= 1 and np.all(np.isfinite(ys)) and np.all(np.isfinite(ts))
        # the numerical blow-up time is the exact one to about rtol
        assert ts[-1] < 1.0 + 1e-6
        if len(t_out) == 0:
            assert ts[-1] > 1.0 - 1e-6 and ys[-1, 0] > 1e5  # it got close to the singularity
        else:
            # up to 0.99, or 1.0 if the numerical solution blows up just after the exact one
            assert len(ts) in (100, 101)
            np.testing.assert_array_equal(ts, t_out[: len(ts)])
        smooth = ts < 0.999
        np.testing.assert_allclose(ys[smooth, 0], 1.0 / (1.0 - ts[smooth]), rtol=1e-5)


def test_non_finite_derivative_gives_status_1(k):
    """y' = 1 for y < 1.5, NaN beyond: every method stops at the wall with finite rows."""
    p = np.array([NANWALL, 0.0])
    ts, ys, status, nfev, nacc, nrej = k.dop853(np.array([1.0, 0.0]), 0.0, 2.0, p, 1e-8, 1e-8, 0.0, 100000, np.empty(0))
    assert status == 1 and np.all(np.isfinite(ys))
    assert 0.5 - 1e-9 < ts[-1] < 0.5 and ys[-1, 0] < 1.5
    ts, ys, status, nfev = k.rk4(np.array([1.0, 0.0]), 0.0, 0.1, 20, p, 3)
    # the step from y = 1.4 evaluates f(1.5) = NaN: output ends with the last finite state, t = 0.4
    assert status == 1 and np.all(np.isfinite(ys))
    np.testing.assert_allclose(ts, [0.0, 0.3, 0.4])
    np.testing.assert_allclose(ys[:, 0], [1.0, 1.3, 1.4])
    # Gauss-Legendre's stages stay below 1.5 up to z = 1.5 (t = 0.5); the next step fails
    ts, zs, status, nfev = k.gauss_legendre(np.array([1.0, 0.0]), 0.0, 0.1, 20, p, 2, 1e-14, 50)
    assert status == 1 and np.all(np.isfinite(zs))
    np.testing.assert_allclose(ts, [0.0, 0.2, 0.4, 0.5])


def test_dop853_rk4_gauss_non_finite_initial_state(k):
    p = np.array([OSC, W])
    y0 = np.array([np.nan, 0.0])
    assert k.dop853(y0, 0.0, 1.0, p, 1e-8, 1e-8, 0.0, 100, np.empty(0))[2] == 1
    ts, ys, status, _ = k.rk4(y0, 0.0, 0.1, 10, p, 1)
    assert status == 1 and len(ts) == 0 and ys.shape == (0, 2)
    ts, zs, status, _ = k.gauss_legendre(y0, 0.0, 0.1, 10, p, 1, 1e-14, 50)
    assert status == 1 and len(ts) == 0


# -- fixed-step storage and the implicit solve --------------------------------------------------------------
def test_fixed_step_storage(k):
    p = np.array([OSC, W])
    y0 = np.array([1.0, 0.0])
    for method, extra in ((k.rk4, ()), (k.gauss_legendre, (1e-14, 100))):
        full_t, full_y, status, _ = method(y0, 0.5, 0.01, 10, p, 1, *extra)
        assert status == 0 and len(full_t) == 11
        ts, ys, status, _ = method(y0, 0.5, 0.01, 10, p, 3, *extra)
        assert status == 0
        np.testing.assert_allclose(ts, 0.5 + 0.01 * np.array([0, 3, 6, 9, 10]))
        np.testing.assert_array_equal(ys, full_y[[0, 3, 6, 9, 10]])
        ts, ys, status, nfev = method(y0, 0.5, 0.01, 0, p, 3, *extra)
        assert status == 0 and len(ts) == 1 and nfev == 0


def test_gauss_legendre_implicit_solve_failure(k):
    p = np.array([OSC, W])
    # one iteration never meets the tolerance
    ts, zs, status, nfev = k.gauss_legendre(np.array([1.0, 0.0]), 0.0, 0.1, 10, p, 1, 1e-14, 1)
    assert status == 4 and len(ts) == 1
    # h w = 6.5: the fixed-point iteration diverges
    ts, zs, status, nfev = k.gauss_legendre(np.array([1.0, 0.0]), 0.0, 5.0, 10, p, 1, 1e-14, 100)
    assert status == 4 and len(ts) == 1 and np.all(np.isfinite(zs))


def test_gauss_legendre_converges_with_tolerance_below_rounding(k):
    """tol = 1e-15 (what skewpend.simulate uses) is met, or the rounding level is detected."""
    p = np.array([PEND, 0.0])
    ts, zs, status, nfev = k.gauss_legendre(np.array([2.0, 0.0]), 0.0, 0.01, 1000, p, 1000, 1e-15, 100)
    assert status == 0
    assert nfev < 1 + 2 * 10 * 1000  # a handful of iterations per step
    ts, zs, status, nfev = k.gauss_legendre(np.array([2.0, 0.0]), 0.0, 0.01, 1000, p, 1000, 0.0, 100)
    assert status == 0


# -- symplecticity ------------------------------------------------------------------------------------------
def test_gauss_legendre_energy_bounded_rk4_drifts(k):
    """Pendulum, h = 0.1, 10^6 steps (t = 10^5): no secular energy drift for Gauss-Legendre."""
    p = np.array([PEND, 0.0])
    z0 = np.array([2.0, 0.0])
    nsteps, stride = 1_000_000, 10
    H0 = pend_H(z0)
    ts, zs, status, nfev = k.gauss_legendre(z0, 0.0, 0.1, nsteps, p, stride, 1e-14, 100)
    assert status == 0 and len(ts) == nsteps // stride + 1
    dH = np.abs(pend_H(zs) - H0)
    tenth = len(dH) // 10
    first, last = dH[:tenth].max(), dH[-tenth:].max()
    print(f"gauss-legendre: max |H - H0| first tenth {first:.3g}, last tenth {last:.3g}, nfev/step {nfev / nsteps:.1f}")
    assert last <= 2 * first
    assert first < 1e-3

    ts, ys, status, _ = k.rk4(z0, 0.0, 0.1, nsteps, p, stride)
    assert status == 0
    dH_rk = np.abs(pend_H(ys) - H0)
    print(f"rk4: |H - H0| at t/10 {dH_rk[tenth]:.3g}, at the end {dH_rk[-1]:.3g}")
    assert dH_rk[-1] > 5 * dH_rk[tenth]
    assert dH_rk[-1] > 10 * last


# -- numba's disk cache -------------------------------------------------------------------------------------
CACHE_CHECK = """
import importlib.util, sys
import numpy as np
name, path = sys.argv[1], sys.argv[2]
spec = importlib.util.spec_from_file_location(name, path)
k = importlib.util.module_from_spec(spec)
sys.modules[name] = k
spec.loader.exec_module(k)
p, y0 = np.array([0.0, 1.3]), np.array([1.0, 0.0])
k.dop853(y0, 0.0, 1.0, p, 1e-8, 1e-8, 0.0, 1000, np.empty(0))
k.rk4(y0, 0.0, 0.1, 10, p, 1)
k.gauss_legendre(y0, 0.0, 0.1, 10, p, 1, 1e-14, 100)
for f in (k.dop853, k.rk4, k.gauss_legendre):
    print(f.__name__, sum(f.stats.cache_hits.values()), sum(f.stats.cache_misses.values()))
"""


def test_integrators_are_loaded_from_numba_cache_in_a_new_process(k):
    p, y0 = np.array([OSC, W]), np.array([1.0, 0.0])
    k.dop853(y0, 0.0, 1.0, p, 1e-8, 1e-8, 0.0, 1000, np.empty(0))  # compiled (and cached) here
    k.rk4(y0, 0.0, 0.1, 10, p, 1)
    k.gauss_legendre(y0, 0.0, 0.1, 10, p, 1, 1e-14, 100)
    run = subprocess.run(
        [sys.executable, "-c", CACHE_CHECK, k.__name__, k.__file__], capture_output=True, text=True, timeout=120
    )
    assert run.returncode == 0, run.stderr
    for line in run.stdout.split("\n")[:3]:
        name, hits, misses = line.split()
        assert (int(hits), int(misses)) == (1, 0), line
