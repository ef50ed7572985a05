"""Lyapunov exponents (Benettin/QR on the variational equations): checked against properties
that hold for this system and against quantities computed independently of the chaos kernel --
the symbolic derivation (``derive``: mass matrix, accelerations, their Jacobian's trace) and the
ordinary integrator (``simulate``), or SciPy's DOP853 on the symbolic equations.

Parameters: thin rods, ``a = b = 1 m``, ``m1 = m2 = 1 kg``, ``alpha = 0.6``.  Starts used:

* ``CHAOTIC = (2, 2.5, 0, 0)`` (about 26 J, far above the ~8-16 J where chaos sets in);
* ``REGULAR = (0.3, 0.2, 0.5, -1)`` (about 1.4 J: the whole section at this energy is
  covered by smooth invariant curves, see test_poincare.py).
"""

from __future__ import annotations

import json
import math
import threading

import numpy as np
import pytest
import sympy as sp

from skewpend import SYMBOLS, IntegrationError, ParameterError, Parameters, derive, simulate
from skewpend.analysis.lyapunov import LyapunovSpectrum, largest_exponents, lyapunov, lyapunov_map
from skewpend.numeric.ensemble import Cancelled
from skewpend.numeric.kernels import kernel_module, parameter_vector

P = Parameters(a=1.0, b=1.0, m1=1.0, m2=1.0, g=9.81, alpha=0.6)
CHAOTIC = (2.0, 2.5, 0.0, 0.0)
CHAOTIC2 = (1.5, -2.0, 0.0, 0.0)
CHAOTIC3 = (3.0, 0.0, 0.0, 0.0)
REGULAR = (0.3, 0.2, 0.5, -1.0)
#: An a-priori bound on how fast nearby motions separate for these parameters [1/s]: the
#: largest exponents measured at any energy are ~1.3 1/s.  Used only to bound how much the
#: integration error (1e-12) can be amplified over a short time in the chaotic tolerances.
LAMBDA_MAX = 1.5

Q = [SYMBOLS["phi"], SYMBOLS["psi"]]
DQ = [SYMBOLS["dphi"], SYMBOLS["dpsi"]]


@pytest.fixture(scope="module")
def sym():
    """Numeric functions from the symbolic derivation (independent of the generated C)."""
    eom = derive(P)
    detM = sp.lambdify(Q, eom.mass_matrix.det(), "numpy")
    return {"eom": eom, "detM": detM}


def states_at(y0, times, params=P):
    """The states at ``times`` (multiples of 0.5 s) by ``simulate`` at rtol = atol = 1e-12 (dense output)."""
    T = float(np.max(times))
    tr = simulate(params, y0, T, dt_out=0.5, rtol=1e-12, atol=1e-12)
    assert tr.success
    idx = np.rint(np.asarray(times) / 0.5).astype(int)
    assert np.allclose(tr.t[idx], times, rtol=0, atol=1e-9)
    return tr.y[idx]


# -- 1. Hamiltonian: Liouville in (q, q') coordinates, pairs, zeros -------------------------------------------------
@pytest.mark.parametrize("y0, t_end, renorm_every, transient", [
    (CHAOTIC, 8.0, 1.0, 0.0),
    (REGULAR, 200.0, 0.5, 10.25),
])
def test_hamiltonian_sum_is_the_log_of_the_mass_matrix_determinant_ratio(sym, y0, t_end, renorm_every, transient):
    """Without damping the flow preserves volume in canonical (q, p) coordinates; with p = M(q) q'
    the volume in (q, q') scales by 1/det M(q).  The QR growths of all 4 vectors multiply to the
    determinant of the tangent propagator, so at every renormalisation time t (measured from t0):
    sum(exponents(t)) * (t - t0) == log(det M(q(t0)) / det M(q(t))) -- exactly, up to integration error."""
    r = lyapunov(P, y0, t_end=t_end, renorm_every=renorm_every, transient=transient, rtol=1e-12, atol=1e-12)
    t0 = r.settings["measured_from"]
    # the measurement starts at the last renormalisation at or before the transient
    assert t0 == renorm_every * math.floor(transient / renorm_every)
    assert np.allclose(r.t, t0 + renorm_every * np.arange(1, r.t.size + 1), rtol=0, atol=1e-9) and r.t[-1] == t_end
    lhs = r.history.sum(axis=1) * (r.t - t0)
    q = states_at(y0, np.concatenate([[t0], r.t]))[:, :2]
    rhs = np.log(sym["detM"](q[0, 0], q[0, 1]) / sym["detM"](q[1:, 0], q[1:, 1]))
    assert np.ptp(rhs) > 0.01  # the identity is not the trivial 0 == 0
    if y0 == CHAOTIC:
        # both sides come from integrations at tolerance 1e-12 along different step sequences:
        # their difference is the integration error, amplified by at most exp(LAMBDA_MAX t)
        bound = 1e-11 * (1.0 + np.exp(LAMBDA_MAX * r.t))
    else:
        # regular orbit: errors grow at most linearly; ~1e-12 per step, ~2e4 steps over 200 s
        bound = np.full(r.t.size, 1e-8)
    assert np.all(np.abs(lhs - rhs) <= bound), np.max(np.abs(lhs - rhs) / bound)


@pytest.mark.parametrize("y0", [CHAOTIC, CHAOTIC2, CHAOTIC3])
def test_hamiltonian_spectrum_comes_in_pairs_with_two_zeros(sym, y0):
    T = 1600.0
    r = lyapunov(P, y0, t_end=T)
    l1, l2, l3, l4 = r.exponents
    # descending once converged (QR order), and clearly chaotic (l1 >> ln(T)/T ~ 0.005 of a regular orbit)
    assert l1 > l2 > l3 > l4 and l1 > 0.5
    # the sum is the Liouville identity above: |sum| * T <= log(max det M / min det M) over the torus
    # (~0.72), up to the integration error of the log-volume (~1e-10 per step, ~1e5 steps: 1e-4)
    psi = np.linspace(-math.pi, math.pi, 20001)
    d = sym["detM"](0.0, psi)  # det M depends on psi alone for these bodies
    assert abs(r.sum) * T <= math.log(d.max() / d.min()) + 1e-4
    # pairs (l, -l): finite-time deviations are bounded transients divided by T -- O(1/T); the
    # constant 10 is generous (observed <= 4 for these starts), against l1 ~ 1
    assert abs(l1 + l4) <= 10.0 / T
    assert abs(l2 + l3) <= 10.0 / T
    # the two zero exponents (along the flow and across the energy surface): the tangent vectors
    # there grow at most linearly in t (shear), so |l| <= c ln(T)/T; c = 3 (observed <= 1.5)
    assert max(abs(l2), abs(l3)) <= 3.0 * math.log(T) / T


def test_damped_sum_is_the_time_average_of_the_jacobian_trace():
    """With damping, d/dt log(volume) = tr J(y(t)) (Liouville), so sum(exponents(t)) * t equals
    the integral of tr J along the trajectory.  The integral is computed independently of the
    generated code: the accelerations from derive() (M^-1 f), differentiated by SymPy,
    integrated together with the state by SciPy's DOP853 at rtol = atol = 1e-12."""
    from scipy.integrate import solve_ivp

    params = P.replace(c1=0.3, c2=0.2)
    eom = derive(params)
    acc = eom.mass_matrix.LUsolve(eom.forcing)
    trace = sp.diff(acc[0], DQ[0]) + sp.diff(acc[1], DQ[1])
    f = sp.lambdify(Q + DQ, [acc[0], acc[1], trace], "math")

    def rhs(t, z):
        a0, a1, tr = f(*z[:4])
        return [z[2], z[3], a0, a1, tr]

    T = 20.0
    r = lyapunov(params, CHAOTIC, t_end=T, rtol=1e-12, atol=1e-12)
    sol = solve_ivp(rhs, (0.0, T), list(CHAOTIC) + [0.0], method="DOP853", rtol=1e-12, atol=1e-12, t_eval=r.t)
    assert sol.success
    integral = sol.y[4]
    lhs = r.history.sum(axis=1) * r.t
    assert integral[-1] < -20  # volume contracts strongly: the check is not 0 == 0
    # two integrations at 1e-12 of a damped (contracting on average) flow over 20 s: the
    # accumulated error is ~1e-12 per step x ~1e4 steps, relative to an integral of ~30
    assert np.all(np.abs(lhs - integral) <= 1e-8 * np.maximum(1.0, np.abs(integral)))
    assert r.sum == pytest.approx(integral[-1] / T, rel=1e-9)


# -- 3. near the stable equilibrium every exponent tends to 0 -------------------------------------------------------
def test_near_the_stable_equilibrium_every_exponent_tends_to_zero():
    """For the linearised motion the propagator is Phi(t) = V exp(Lambda t) V^-1 with Lambda
    purely imaginary, so its singular values lie in [1/kappa, kappa], kappa = cond(V): the
    j-volume spanned by the first j tangent vectors (started orthonormal) stays within
    kappa^(+-j), i.e. |l_1 + ... + l_j| * T <= j ln(kappa) -- every exponent is O(1/T).  kappa
    from the linear equations of derive(); the amplitude 1e-3 rad makes the nonlinear
    corrections O(1e-6) (allowed for by 5 %)."""
    lin = derive(P).linearize()
    M0, K0 = np.array(lin.M, dtype=float), np.array(lin.K, dtype=float)
    A = np.block([[np.zeros((2, 2)), np.eye(2)], [-np.linalg.solve(M0, K0), np.zeros((2, 2))]])
    w, V = np.linalg.eig(A)
    assert np.max(np.abs(w.real)) < 1e-9  # a centre: the equilibrium is stable
    log_kappa = math.log(np.linalg.cond(V / np.linalg.norm(V, axis=0)))
    largest = []
    for T in (50.0, 200.0, 800.0):
        r = lyapunov(P, (1e-3, -1e-3, 0.0, 0.0), t_end=T)
        partial = np.abs(np.cumsum(r.exponents)) * T
        assert np.all(partial <= np.arange(1, 5) * log_kappa * 1.05), (T, partial / log_kappa)
        largest.append(np.max(np.abs(r.exponents)))
    # hence every exponent <= (2j - 1) ln(kappa) / T  ->  0
    assert largest[-1] <= 7 * log_kappa * 1.05 / 800.0
    assert largest[0] > largest[1] > largest[2]


# -- 4. mirror symmetry ---------------------------------------------------------------------------------------------
@pytest.mark.parametrize("y0, t_end", [(CHAOTIC, 10.0), (REGULAR, 100.0)])
@pytest.mark.parametrize("k", [4, 1])
def test_mirror_start_has_the_same_spectrum(y0, t_end, k):
    """Thin rods, default axes, no torques: the equations are odd under (q, q') -> -(q, q') and the
    Jacobian even, so the mirrored trajectory carries the same tangent dynamics.  The arithmetic
    is sign-symmetric, so the results agree to rounding; over 10 s even a rounding difference
    amplified by exp(LAMBDA_MAX * 10) ~ 3e6 stays far below the tolerance."""
    a = lyapunov(P, y0, t_end=t_end, n_exponents=k)
    b = lyapunov(P, -np.asarray(y0), t_end=t_end, n_exponents=k)
    np.testing.assert_allclose(b.exponents, a.exponents, rtol=1e-6, atol=1e-9)
    np.testing.assert_allclose(b.history, a.history, rtol=1e-6, atol=1e-9)


# -- 5. convergence -------------------------------------------------------------------------------------------------
def test_regular_orbit_largest_exponent_decays_like_log_t_over_t():
    """On an invariant torus tangent vectors grow at most linearly (shear between tori), so
    T * l1 <= ln(C T): l1 <= 2 ln(T)/T allows C up to T (observed T l1 / ln T <= 0.9)."""
    values = []
    for T in (100.0, 400.0, 1600.0):
        l1 = lyapunov(P, REGULAR, t_end=T, n_exponents=1).exponents[0]
        assert 0 < l1 <= 2.0 * math.log(T) / T, (T, l1)
        values.append(l1)
    assert values[0] > values[1] > values[2]


def test_chaotic_running_estimate_settles():
    r = lyapunov(P, CHAOTIC, t_end=1000.0, n_exponents=1)
    h = r.history[:, 0]
    assert h.size == 1000 and h[-1] == r.exponents[0]
    half = h.size // 2
    # a running mean: its fluctuations shrink like 1/t, so the last half spreads less than the first
    assert np.ptp(h[half:]) < 0.5 * np.ptp(h[:half])
    assert np.ptp(h[half:]) < 0.1 * h[-1]  # and it has settled to within 10 % of a positive value


# -- 6. the tangent dynamics against two nearby trajectories --------------------------------------------------------
@pytest.mark.parametrize("y0", [CHAOTIC, CHAOTIC2, REGULAR])
def test_benettin_agrees_with_the_two_trajectory_method(y0):
    """The classic method, with simulate alone: a companion trajectory at distance d0 = 1e-8
    along the same initial direction (1, 1, 1, 1)/2, the separation measured and rescaled to d0
    every 1 s.  Per interval its log-growth is off by the nonlinear term ~ d0 e^(lambda) ~ 1e-7
    and by the integration error over the separation ~ tol |y| / d0 ~ 1e-12 * 10 / 1e-8 = 1e-3;
    summed over 20 intervals and divided by T = 20 s: <= 1e-3 1/s.  (The reference trajectory
    itself departs from Benettin's by ~1e-12 e^(lambda T), ~1e-4 at the end: negligible.)"""
    T, d0 = 20.0, 1e-8
    lam = lyapunov(P, y0, t_end=T, n_exponents=1, rtol=1e-12, atol=1e-12).exponents[0]
    y = np.asarray(y0, dtype=float)
    z = y + d0 * np.full(4, 0.5)
    growth = 0.0
    for _ in range(int(T)):
        y = simulate(P, y, 1.0, rtol=1e-12, atol=1e-12).final_state
        sep = simulate(P, z, 1.0, rtol=1e-12, atol=1e-12).final_state - y
        n = np.linalg.norm(sep)
        growth += math.log(n / d0)
        z = y + sep * (d0 / n)
    assert abs(growth / T - lam) <= 1e-3, (growth / T, lam)


# -- 7. the leading exponents do not depend on how many are computed ------------------------------------------------
@pytest.mark.parametrize("y0, t_end, tol", [
    # differences come only from the step sequences (error control includes every vector):
    # ~1e-12 amplified by exp(LAMBDA_MAX * 10) ~ 3e6, divided by T -> ~1e-7 for the chaotic start
    (CHAOTIC, 10.0, 1e-7),
    (REGULAR, 100.0, 1e-9),
])
def test_leading_exponents_do_not_depend_on_how_many_are_computed(y0, t_end, tol):
    """Gram-Schmidt: the j-th vector depends only on vectors 1..j, all started as the same
    columns of the identity; so the first k exponents of a k-vector run are those of the full run."""
    full = lyapunov(P, y0, t_end=t_end, n_exponents=4, rtol=1e-12, atol=1e-12)
    for k in (2, 3):
        part = lyapunov(P, y0, t_end=t_end, n_exponents=k, rtol=1e-12, atol=1e-12)
        assert part.k == k
        np.testing.assert_allclose(part.history, full.history[:, :k], rtol=0, atol=tol)


# -- 8. uncertainty, history, windows, to_dict ----------------------------------------------------------------------
def test_uncertainty_history_windows_and_plain_data():
    r = lyapunov(P, CHAOTIC, t_end=100.0, windows=10)
    assert isinstance(r, LyapunovSpectrum) and r.k == 4 and r.status == 0 and r.message == "reached t_end"
    assert r.history.shape == (100, 4) and np.array_equal(r.t, np.arange(1.0, 101.0))
    assert np.array_equal(r.history[-1], r.exponents)
    assert r.window_exponents.shape == (10, 4) and r.settings["windows"] == 10
    # 10 equal windows of 10 intervals: the exponents are the mean of the window exponents (sums of
    # the same logarithms, regrouped: rounding only)
    np.testing.assert_allclose(r.window_exponents.mean(axis=0), r.exponents, rtol=1e-12, atol=1e-14)
    # standard error of the mean over the windows, by definition
    np.testing.assert_allclose(r.uncertainty, r.window_exponents.std(axis=0, ddof=1) / math.sqrt(10), rtol=1e-12)
    assert np.all(np.isfinite(r.uncertainty)) and np.all(r.uncertainty > 0)
    assert r.stats["renormalisations"] == 100 and r.stats["steps"] > 0
    data = json.loads(json.dumps(r.to_dict()))
    assert data["exponents"] == r.exponents.tolist() and data["uncertainty"] == r.uncertainty.tolist()
    assert data["sum"] == r.sum and data["y0"] == list(CHAOTIC) and data["params"]["alpha"] == 0.6
    # the 95 % interval: Student's t with 9 degrees of freedom (2.262, from tables) times the standard error
    np.testing.assert_allclose(r.interval, 2.2621571628 * r.uncertainty, rtol=1e-9)
    assert data["interval"] == r.interval.tolist() and data["confidence"] == 0.95
    # 4 exponents, the sum, the Kaplan-Yorke line (not meaningful: no damping) and what +- means
    lines = r.table().splitlines()
    assert len(lines) == 7 and "not meaningful" in lines[5] and "95 %" in lines[6]
    assert data["kaplan_yorke_dimension"] is None

    one = lyapunov(P, CHAOTIC, t_end=20.0, windows=1, n_exponents=1)
    assert np.all(np.isnan(one.uncertainty)) and one.history.shape == (20, 1)
    assert json.loads(json.dumps(one.to_dict()))["uncertainty"] == [None]
    # one window cannot tell whether the exponent settled: said in the status, never a success
    assert not one.ok and one.status.name == "NOT_SETTLED" and "at least 4" in one.message


def test_history_is_thinned_to_at_most_2000_points():
    r = lyapunov(P, REGULAR, t_end=5000.0, n_exponents=2)
    assert 1000 <= r.t.size <= 2000 and r.history.shape == (r.t.size, 2)
    assert np.all(np.diff(r.t) > 0) and r.t[-1] == 5000.0 and np.array_equal(r.history[-1], r.exponents)


def test_a_run_stopped_early_returns_what_it_measured_or_raises_with_throw():
    with pytest.raises(IntegrationError, match="max_steps"):
        lyapunov(P, CHAOTIC, t_end=50.0, max_steps=500, throw=True)
    r = lyapunov(P, CHAOTIC, t_end=50.0, max_steps=500)  # the one default: throw=False, as simulate
    assert r.status == 3 and not r.ok and "max_steps" in r.message and r.stats["t_reached"] < 50.0
    assert np.all(np.isfinite(r.exponents))
    # the same trajectory stopped at its last renormalisation on purpose: same steps, same growths
    last = float(r.t[-1])
    ref = lyapunov(P, CHAOTIC, t_end=last)
    np.testing.assert_allclose(r.exponents, ref.exponents, rtol=1e-12)


def test_a_run_stopped_early_with_a_thinned_history_measures_over_the_right_time():
    r = lyapunov(P, CHAOTIC, t_end=3000.0, max_steps=2000, throw=False)  # 3000 rows wanted: every 2nd kept
    assert r.status == 3
    last = float(r.stats["renormalisations"]) * 1.0  # the time of the last renormalisation done
    ref = lyapunov(P, CHAOTIC, t_end=last)  # same steps up to there
    np.testing.assert_allclose(r.exponents, ref.exponents, rtol=1e-12)


# -- 9. bad input ---------------------------------------------------------------------------------------------------
@pytest.mark.parametrize("kwargs, field", [
    (dict(t_end=0.0), "^t_end"),
    (dict(t_end=-5.0), "^t_end"),
    (dict(t_end=math.nan), "^t_end"),
    (dict(t_end=5.0, renorm_every=10.0), "^renorm_every"),
    (dict(t_end=5.0, renorm_every=0.0), "^renorm_every"),
    (dict(t_end=5.0, transient=5.0), "^transient"),
    (dict(t_end=5.0, transient=7.0), "^transient"),
    (dict(t_end=5.0, transient=-1.0), "^transient"),
    (dict(t_end=5.0, n_exponents=0), "^n_exponents"),
    (dict(t_end=5.0, n_exponents=5), "^n_exponents"),
    (dict(t_end=5.0, n_exponents=True), "^n_exponents"),
    (dict(t_end=5.0, windows=0), "^windows"),
    (dict(t_end=5.0, rtol=0.0), "^rtol"),
    (dict(t_end=5.0, max_steps=0), "^max_steps"),
    (dict(t_end=5.0, y0=(math.nan, 0.0, 0.0, 0.0)), "^y0"),
    (dict(t_end=5.0, y0=(0.0, 0.0, math.inf, 0.0)), "^y0"),
    (dict(t_end=5.0, y0=(0.0, 0.0, 0.0)), "^y0"),
    (dict(t_end=5.0, params=Parameters()), "numeric values; symbolic: a, b, m1, m2, alpha, g"),
    (dict(t_end=5.0, params=Parameters(a=1, b=1, m1=1, m2=1, g=9.81)), "symbolic: alpha"),
    (dict(t_end=5.0, params="P"), "params"),
])
def test_bad_input_is_refused_naming_the_field(kwargs, field):
    kwargs = dict(kwargs)
    params = kwargs.pop("params", P)
    y0 = kwargs.pop("y0", (0.1, 0.1, 0.0, 0.0))
    with pytest.raises(ParameterError, match=field):
        lyapunov(params, y0, **kwargs)


@pytest.mark.parametrize("kwargs, field", [
    (dict(n=0), "n must be from 1"),
    (dict(n=2000), "n must be at most 1024"),
    (dict(n=4, phi_range=(1.0, 1.0)), "phi_range"),
    (dict(n=4, workers=0), "workers"),
    (dict(n=4, t_end=5.0, renorm_every=6.0), "renorm_every"),
    (dict(n=4, params=Parameters()), "symbolic"),
])
def test_lyapunov_map_bad_input(kwargs, field):
    kwargs = dict(kwargs)
    params = kwargs.pop("params", P)
    with pytest.raises(ParameterError, match=field):
        lyapunov_map(params, **kwargs)


# -- 10. the map over starts at rest --------------------------------------------------------------------------------
@pytest.fixture(scope="module")
def small_map():
    return lyapunov_map(P, 4, t_end=30.0, workers=1)


def test_lyapunov_map_shape_mirror_symmetry_and_workers(small_map):
    m = small_map
    assert m.n == 4 and m.exponent.shape == m.phi0.shape == m.psi0.shape == (4, 4)
    centres = np.array([-0.75, -0.25, 0.25, 0.75]) * math.pi  # cell centres of [-pi, pi] in 4 cells
    np.testing.assert_allclose(m.phi0[:, 0], centres, rtol=1e-15)
    np.testing.assert_allclose(m.psi0[0], centres, rtol=1e-15)
    assert np.all(np.isfinite(m.exponent)) and m.stats["failed"] == 0
    # the window is symmetric: cell (i, j) starts at minus cell (n-1-i, n-1-j), so it has the same
    # spectrum (see the mirror test above).  The kernel's arithmetic is sign-symmetric, so mirror
    # trajectories coincide; 1e-6 relative allows for the last digits only (an asymmetry of
    # rounding would be amplified by chaos over 30 s into a visibly different estimate)
    np.testing.assert_allclose(m.exponent, m.exponent[::-1, ::-1], rtol=1e-6)
    # the high-energy corners (about 30 J) are chaotic, the low-energy cells near rest are not
    assert m.exponent[0, 0] > 0.5 and m.exponent[1, 2] < 4 * math.log(30.0) / 30.0
    # each trajectory is independent: bitwise the same on any number of threads
    two = lyapunov_map(P, 4, t_end=30.0, workers=2)
    assert two.exponent.tobytes() == m.exponent.tobytes()


def test_lyapunov_map_cells_are_single_trajectory_exponents(small_map):
    """A cell is lyapunov(n_exponents=1) from that start at rest, at the map's tolerance 1e-8:
    the same algorithm (same initial vector, renormalisation times, steps), so equal to rounding."""
    m = small_map
    for i, j in [(0, 0), (1, 2), (3, 1)]:
        one = lyapunov(P, (m.phi0[i, j], m.psi0[i, j], 0.0, 0.0), t_end=30.0, n_exponents=1, rtol=1e-8, atol=1e-8)
        assert m.exponent[i, j] == pytest.approx(one.exponents[0], rel=1e-12)
    # with a transient and another renormalisation interval, in a window that is not symmetric
    w = lyapunov_map(P, 2, t_end=20.0, renorm_every=0.5, transient=5.25, phi_range=(-1.0, 2.0), psi_range=(0.0, 3.0))
    for i in range(2):
        one = lyapunov(P, (w.phi0[i, 1], w.psi0[i, 1], 0.0, 0.0), t_end=20.0, renorm_every=0.5, transient=5.25,
                       n_exponents=1, rtol=1e-8, atol=1e-8)
        assert one.settings["measured_from"] == 5.0
        assert w.exponent[i, 1] == pytest.approx(one.exponents[0], rel=1e-12)


def test_largest_exponents_grouping_and_cancel():
    kernel = kernel_module(P, chaos=True)
    p = parameter_vector(P)
    starts = np.array([CHAOTIC, REGULAR, CHAOTIC2, (0.5, -0.4, 0.0, 0.0), CHAOTIC3])
    kw = dict(t_end=15.0, renorm_every=1.0, transient=0.0, rtol=1e-9, atol=1e-9, max_steps=10**7)
    lam1, status1, steps1, rejected1 = largest_exponents(kernel, p, starts, group=1, **kw)
    lam3, status3, steps3, rejected3 = largest_exponents(kernel, p, starts, group=3, **kw)
    assert lam1.tobytes() == lam3.tobytes() and np.array_equal(steps1, steps3) and np.array_equal(rejected1, rejected3)
    assert np.all(status1 == 0) and np.all(steps1 > 0) and np.all(np.isfinite(lam1))
    for y0, lam in zip(starts, lam1):
        assert lam == pytest.approx(lyapunov(P, y0, n_exponents=1, **kw).exponents[0], rel=1e-12)
    # a failing trajectory (step cap) is NaN with its status, the others unaffected
    lam, status, _, _ = largest_exponents(kernel, p, starts[:2], **{**kw, "max_steps": 50})
    assert np.all(np.isnan(lam)) and np.all(status == 3)
    cancel = threading.Event()
    cancel.set()
    with pytest.raises(Cancelled):
        largest_exponents(kernel, p, starts, cancel=cancel, **kw)


def test_largest_exponents_measure_from_the_same_renormalisation_as_lyapunov():
    kernel, p = kernel_module(P, chaos=True), parameter_vector(P)
    kw = dict(t_end=5.0, renorm_every=0.1, transient=0.3, rtol=1e-8, atol=1e-8)
    one = lyapunov(P, CHAOTIC, n_exponents=1, **kw)
    lam, status, _, _ = largest_exponents(kernel, p, np.array([CHAOTIC]), max_steps=10**7, **kw)
    assert status[0] == 0
    assert lam[0] == pytest.approx(one.exponents[0], rel=1e-12)
