"""The compiled integrators of the ``integrators.c`` template: order, accuracy, symplecticity,
status, and resumability (the work split into calls does not change a bit of the result).

A library is built exactly as :mod:`skewpend.numeric.kernels` builds one -- C ``rhs`` / ``ham_rhs``
and the generated return codes followed by the text of ``integrators.c`` -- from test problems
chosen by ``p[0]``:

* 0 -- harmonic oscillator ``q'' = -w^2 q`` (``w = p[1]``), exact solution known;
* 1 -- pendulum ``q'' = -sin q``, Hamiltonian ``H = p^2/2 - cos q``;
* 2 -- ``y' = y^2`` (blows up at ``t = 1/y0``);
* 3 -- ``y' = 1`` for ``y < 1.5``, undefined (NaN) beyond.

:class:`Integrators` calls the resumable C functions in a loop, like :func:`skewpend.simulate`,
with a deliberately small step budget and row buffer per call, and returns whole arrays.
"""

import ctypes
import math
from pathlib import Path

import numpy as np
import pytest
from scipy.integrate import solve_ivp

import skewpend
from skewpend.numeric.kernel_source import status_defines
from skewpend.numeric.kernels import State, _compile

HEADER = r"""
#include <math.h>
#define SP_NPARAM 4
#define SP_TAU_INDEX {2, 3}
static double energy(const double *y, const double *p) { return 0.5 * y[1] * y[1]; }
static void rhs(const double *y, const double *p, double *out)
{
    int kind = (int)p[0];
    if (kind == 0) { out[0] = y[1]; out[1] = -p[1] * p[1] * y[0]; }
    else if (kind == 1) { out[0] = y[1]; out[1] = -sin(y[0]); }
    else if (kind == 2) { out[0] = y[0] * y[0]; out[1] = 0.0; }
    else { out[0] = y[0] < 1.5 ? 1.0 : NAN; out[1] = 0.0; }
}
static void ham_rhs(const double *z, const double *p, double *out)
{
    int kind = (int)p[0];
    if (kind == 0) { out[0] = z[1]; out[1] = -p[1] * p[1] * z[0]; }
    else if (kind == 1) { out[0] = z[1]; out[1] = -sin(z[0]); }
    else { out[0] = z[0] < 1.5 ? 1.0 : NAN; out[1] = 0.0; }
}
"""


class Integrators:
    """Whole-run wrappers over the resumable C integrators (budget steps / cap rows per call)."""

    def __init__(self, path: Path, budget: int = 37, cap: int = 11):
        self.lib = ctypes.CDLL(str(path))
        self.budget, self.cap = budget, cap
        dp, i64, d = ctypes.POINTER(ctypes.c_double), ctypes.c_int64, ctypes.c_double
        ip, sp = ctypes.POINTER(i64), ctypes.POINTER(State)
        self.lib.sp_dop853.argtypes = [sp, ctypes.c_int, dp, d, d, d, i64, i64, d, i64, ip, dp, i64, ip]
        self.lib.sp_rk4.argtypes = [sp, ctypes.c_int, dp, d, d, i64, i64, i64, dp, i64, ip]
        self.lib.sp_gauss.argtypes = [sp, ctypes.c_int, dp, d, d, i64, i64, d, i64, i64, dp, i64, ip]
        self.calls = 0

    def _loop(self, call, n):
        rows = np.empty((self.cap, n + 1))
        m = ctypes.c_int64(0)
        out = []
        ptr = rows.ctypes.data_as(ctypes.POINTER(ctypes.c_double))
        while True:
            status = call(ptr, m)
            self.calls += 1
            assert status != -3, "bad arguments"
            out.append(rows[: m.value].copy())
            if status >= 0:
                break
        table = np.concatenate(out)
        return table[:, 0], table[:, 1:], status

    def dop853(self, y0, t0, t_end, p, rtol, atol, h0, max_steps, dt_out=0.0, n_grid=0):
        s = State.at(t0, y0)
        s.h = h0
        p = np.ascontiguousarray(p, float)
        k_out = ctypes.c_int64(0)
        pp = p.ctypes.data_as(ctypes.POINTER(ctypes.c_double))
        ts, ys, status = self._loop(
            lambda rows, m: self.lib.sp_dop853(ctypes.byref(s), len(y0), pp, t_end, rtol, atol, max_steps, self.budget,
                                               dt_out, n_grid, ctypes.byref(k_out), rows, self.cap, ctypes.byref(m)),
            len(y0),
        )
        return ts, ys, status, s.nfev, s.naccept, s.nreject

    def rk4(self, y0, t0, dt, nsteps, p, stride):
        s = State.at(t0, y0)
        p = np.ascontiguousarray(p, float)
        pp = p.ctypes.data_as(ctypes.POINTER(ctypes.c_double))
        ts, ys, status = self._loop(
            lambda rows, m: self.lib.sp_rk4(ctypes.byref(s), len(y0), pp, t0, dt, nsteps, stride, self.budget, rows,
                                            self.cap, ctypes.byref(m)),
            len(y0),
        )
        return ts, ys, status, s.nfev

    def gauss_legendre(self, z0, t0, dt, nsteps, p, stride, tol, max_iter):
        s = State.at(t0, z0)
        p = np.ascontiguousarray(p, float)
        pp = p.ctypes.data_as(ctypes.POINTER(ctypes.c_double))
        ts, zs, status = self._loop(
            lambda rows, m: self.lib.sp_gauss(ctypes.byref(s), len(z0), pp, t0, dt, nsteps, stride, tol, max_iter,
                                              self.budget, rows, self.cap, ctypes.byref(m)),
            len(z0),
        )
        return ts, zs, status, s.nfev


def template_text() -> str:
    return (Path(skewpend.__file__).parent / "numeric" / "integrators.c").read_text()


@pytest.fixture(scope="module")
def library(tmp_path_factory):
    path = tmp_path_factory.mktemp("kernels") / "problems.so"
    _compile(HEADER + "\n" + "\n".join(status_defines()) + "\n" + template_text(), path)
    return path


@pytest.fixture(scope="module")
def k(library):
    return Integrators(library)


@pytest.fixture(scope="module")
def k_whole(library):
    """The same library called with budgets and buffers large enough for one call."""
    return Integrators(library, budget=10**9, cap=2_000_000)


OSC, PEND, BLOWUP, NANWALL = 0.0, 1.0, 2.0, 3.0
W = 1.3  # oscillator frequency


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


# -- resumability ------------------------------------------------------------------------------------
def test_splitting_the_work_into_calls_changes_no_bit(k, k_whole):
    """Every method, chunked (37 steps / 11 rows per call) and in one call, gives identical rows."""
    p = np.array([PEND, 0.0])
    y0 = np.array([2.0, 0.0])
    runs = [
        ("dop853 own steps", lambda m: m.dop853(y0, 0.0, 12.3, p, 1e-13, 1e-13, 0.0, 10**6)),
        ("dop853 grid", lambda m: m.dop853(y0, 0.0, 12.3, p, 1e-13, 1e-13, 0.0, 10**6, 0.01, 1231)),
        ("rk4", lambda m: m.rk4(y0, 0.0, 0.01, 1230, p, 7)),
        ("gauss", lambda m: m.gauss_legendre(y0, 0.0, 0.01, 1230, p, 7, 1e-15, 100)),
    ]
    for name, run in runs:
        before = k.calls
        a, b = run(k), run(k_whole)
        assert k.calls - before > 10, name  # really split
        assert a[2] == b[2] == 0, name
        np.testing.assert_array_equal(a[0], b[0], err_msg=name)
        np.testing.assert_array_equal(a[1], b[1], err_msg=name)
        assert a[3:] == b[3:], name  # evaluation and step counts


def test_template_defines_no_model():
    """The template is generic: it uses rhs/ham_rhs from the text before it and defines neither."""
    text = template_text()
    code = "\n".join(line for line in text.splitlines() if not line.lstrip().startswith(("/*", "*")))
    assert "void rhs(" not in code and "void ham_rhs(" not in code and "double energy(" not in code
    for name in ("sp_dop853", "sp_rk4", "sp_gauss", "sp_state_size"):
        assert f"{name}(" in text


def test_dop853_tables_are_scipys():
    """The DOP853 coefficients typed into the template equal SciPy's tables exactly."""
    import re

    from scipy.integrate._ivp import dop853_coefficients as ref

    text = template_text()

    def table(name):
        body = re.search(rf"static const double {name}\[[^=]*= \{{(.*?)\}};", text, re.S).group(1)
        return np.array([float(x) for x in re.findall(r"-?\d[\d.e+-]*", body)])

    np.testing.assert_array_equal(table("DOP_C"), ref.C)
    np.testing.assert_array_equal(table("DOP_A"), np.ravel(ref.A))
    np.testing.assert_array_equal(table("DOP_E3"), ref.E3)
    np.testing.assert_array_equal(table("DOP_E5"), ref.E5)
    np.testing.assert_array_equal(table("DOP_D"), np.ravel(ref.D))


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
        ts, ys, status, nfev, nacc, nrej = k.dop853(np.array([1.0, 0.0]), 0.0, t_end, p, tol, tol, 0.0, 100000)
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
    t_out = np.arange(401) * 0.025
    for tol in (1e-7, 1e-10):
        ts, ys, status, nfev, nacc, nrej = k.dop853(np.array([1.0, 0.0]), 0.0, 10.0, p, tol, tol, 0.0, 100000, 0.025, 401)
        assert status == 0
        np.testing.assert_array_equal(ts, t_out)
        np.testing.assert_array_equal(ys[0], [1.0, 0.0])
        err = np.max(np.abs(ys - osc_exact(t_out)))
        print(f"dense output tol {tol:g}: max error {err:.3g} ({nacc} steps)")
        assert err < 10 * tol
        # 12 evaluations per attempted step, 3 more per step with interior output points, 2 to start
        assert 2 + 12 * (nacc + nrej) < nfev <= 2 + 12 * (nacc + nrej) + 3 * nacc
    # a grid time within rounding beyond t_end (3 * 0.1 > 0.3) gets the final state
    ts, ys, status, *_ = k.dop853(np.array([1.0, 0.0]), 0.0, 0.3, p, 1e-9, 1e-9, 0.0, 1000, 0.1, 4)
    assert status == 0 and len(ts) == 4 and ts[3] > 0.3
    np.testing.assert_allclose(ys[3], osc_exact(0.3), atol=1e-8)


def test_dop853_own_steps_are_dop853s(k):
    """Own steps: t0 first, the last exactly t_end; the same method as SciPy's DOP853.

    What the algorithm guarantees is asserted, not SciPy's bit patterns: the automatic
    initial step is Hairer's (as SciPy computes it, to rounding), the step count agrees with
    SciPy's within 2 (the error estimate is a sum of O(1) terms cancelling to O(tol), so
    summation order alone perturbs h by ~eps/tol -- enough to shift a late rejection), and
    the solution meets the tolerance against a 1e-13 reference.
    """
    from scipy.integrate._ivp.common import select_initial_step
    from scipy.integrate._ivp.rk import DOP853

    p = np.array([PEND, 0.0])
    y0 = np.array([2.0, 0.0])
    t_end = 12.345
    pend = lambda t, y: np.array([y[1], -math.sin(y[0])])  # noqa: E731
    for h0 in (0.0, 0.05):  # automatic and given initial step
        ts, ys, status, nfev, nacc, nrej = k.dop853(y0, 0.0, t_end, p, 1e-8, 1e-10, h0, 100000)
        assert status == 0
        assert ts[0] == 0.0 and ts[-1] == t_end and np.all(np.diff(ts) > 0)
        assert len(ts) == nacc + 1 and ys.shape == (nacc + 1, 2)
        np.testing.assert_array_equal(ys[0], y0)
        if h0 == 0.0:
            h_ref = select_initial_step(pend, 0.0, y0, t_end, np.inf, pend(0.0, y0), 1, DOP853.error_estimator_order, 1e-8, 1e-10)
            assert ts[1] == pytest.approx(h_ref, rel=1e-12)
        else:
            assert ts[1] == 0.05 or nrej > 0
        sol = solve_ivp(pend, (0.0, t_end), y0, method="DOP853", rtol=1e-8, atol=1e-10, first_step=h0 if h0 > 0 else None)
        assert abs(len(sol.t) - len(ts)) <= 2
        ref = solve_ivp(pend, (0.0, t_end), y0, method="DOP853", rtol=1e-13, atol=1e-13, t_eval=ts)
        assert np.max(np.abs(ys - ref.y.T)) < 100 * 1e-8


def test_dop853_max_steps(k):
    p = np.array([OSC, W])
    ts, ys, status, nfev, nacc, nrej = k.dop853(np.array([1.0, 0.0]), 0.0, 100.0, p, 1e-10, 1e-10, 0.0, 5)
    assert status == 3 and nacc + nrej == 5 and len(ts) == nacc + 1 and ts[-1] < 100.0
    np.testing.assert_allclose(ys, osc_exact(ts), atol=1e-8)
    ts, ys, status, *_ = k.dop853(np.array([1.0, 0.0]), 0.0, 100.0, p, 1e-10, 1e-10, 0.0, 5, 10.0, 11)
    assert status == 3 and len(ts) == 1 and ts[0] == 0.0


def test_dop853_blow_up(k):
    """y' = y^2, y(0) = 1: y = 1/(1 - t) blows up at t = 1 < t_end = 2."""
    p = np.array([BLOWUP, 0.0])
    for t_out in (np.empty(0), np.arange(201) * 0.01):
        grid = (0.01, 201) if len(t_out) else ()
        ts, ys, status, nfev, nacc, nrej = k.dop853(np.array([1.0, 0.0]), 0.0, 2.0, p, 1e-8, 1e-8, 0.0, 100000, *grid)
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
    ts, ys, status, nfev, nacc, nrej = k.dop853(np.array([1.0, 0.0]), 0.0, 2.0, p, 1e-8, 1e-8, 0.0, 100000)
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
    assert k.dop853(y0, 0.0, 1.0, p, 1e-8, 1e-8, 0.0, 100)[2] == 1
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
