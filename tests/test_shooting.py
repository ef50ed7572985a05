"""The output-error fit's machinery (skewpend.analysis.shooting, issues 27 and 37): the shooting kernel's
parameter sensitivities against differences of the model kernel, the base parameters' dynamics on it
against the compiled simulation of the model's own bodies, the exactness of the sensitivities (the
gradient of the discrete model against central differences of its own cost), and a fit recovering a
known skewed model from noiseless data."""

from __future__ import annotations

import math

import numpy as np
import pytest

import skewpend
from skewpend.analysis import shooting
from skewpend.symbolic import regressor as R

P = skewpend.Parameters(a=1.0, b=0.8, m1=1.0, m2=0.7, alpha=math.radians(25.0), g=9.81, c1=0.02, c2=0.01)
STARTS = [(1.0, -0.5, 0.3, 0.0), (-0.4, 1.2, 0.0, -1.0), (2.0, 0.2, 1.0, 0.5)]


@pytest.fixture(scope="module")
def generic():
    B = R.base_parameters(P.replace(alpha=None))
    beta = B.values(R.standard_parameters(P), P.a, P.alpha, P.g)
    return B, beta


def _segments(params, seconds=0.6, dt=1e-3, step=0.002, noise=0.0, seed=0):
    rng = np.random.default_rng(seed)
    filtered, names = [], []
    for i, y0 in enumerate(STARTS):
        tr = skewpend.simulate(params, y0, seconds, dt_out=dt, rtol=1e-12, atol=1e-12)
        y = np.asarray(tr.y)
        q = y[:, :2] + rng.normal(0, noise, (len(y), 2)) if noise else y[:, :2]
        filtered.append((np.asarray(tr.t), q, y[:, :2], y[:, 2:4], None))
        names.append(f"s{i}")
    return shooting.segments(filtered, names, segment=seconds, step=step)


def test_the_kernels_parameter_sensitivities_are_the_derivatives():
    """The shooting kernel's ``rhs_sens`` (generated from the derivation: d q''/d y and d q''/d p, one
    LDL^T solve a column) against central differences of the model kernel's own right-hand side in
    every entry of p and of the Jacobian in the state, at random states of a skewed rig with friction
    and a rotor (every body entry read from p): steps 1e-6 relative, truncation ~1e-12, rounding ~1e-10
    of the entries; asserted 1e-6 relative to each column's scale.  Its accelerations are those of the
    rig's own kernel (body 1 a thin rod there, its values in p here)."""
    import ctypes

    from skewpend.numeric.conventions import PARAMETER_ORDER, parameter_vector
    from skewpend.numeric.kernels import kernel_module

    rig = P.replace(cf1=0.05, cf2=0.03, Ir=2e-4, gr=-6.0, com2=(0.02, 0.35, -0.01),
                    inertia2=((0.03, 0.002, 0.001), (0.002, 0.004, 0.001), (0.001, 0.001, 0.03)))
    sens, model = kernel_module(rig, shooting=True), kernel_module(rig)
    p = parameter_vector(rig)
    dp = ctypes.POINTER(ctypes.c_double)
    rng = np.random.default_rng(27)
    for y in rng.uniform(-2, 2, (4, 4)):
        acc, A, B = np.empty(2), np.empty(8), np.empty(2 * len(p))
        sens.lib.sp_rhs_sens(*(a.ctypes.data_as(dp) for a in (y, p, acc, A, B)))
        out = np.empty(5)
        model.rhs(np.append(y, 0.0), p, out)
        np.testing.assert_allclose(acc, out[2:4], rtol=1e-13, atol=1e-13)
        B = B.reshape(2, len(p))
        for j, name in enumerate(PARAMETER_ORDER):
            h = 1e-6 * max(1.0, abs(p[j]))
            f = []
            for sign in (1, -1):
                pj = p.copy()
                pj[j] += sign * h
                sens.rhs(np.append(y, 0.0), pj, out)  # its own right-hand side: every body entry from p
                f.append(out[2:4].copy())
            num = (f[0] - f[1]) / (2 * h)
            assert np.max(np.abs(B[:, j] - num)) <= 1e-6 * max(1.0, np.abs(num).max()), name
        J = np.empty((5, 5))
        sens.jac(np.append(y, 0.0), p, J)
        np.testing.assert_allclose(A.reshape(2, 4), J[2:4, :4], rtol=1e-12, atol=1e-12)
    # the derivative in a body entry is not zero (the bodies are read from p, not baked in)
    assert np.abs(B[:, PARAMETER_ORDER.index("I2zz")]).max() > 0 and np.abs(B[:, PARAMETER_ORDER.index("r1y")]).max() > 0


def test_the_regressor_dynamics_are_the_simulations(generic):
    """RK4 at 1 ms on the shooting kernel (base parameters as a point of p: the representative of beta),
    against the compiled DOP853 at 1e-12 on the model's own kernel (its bodies as given):
    RK4's global error over 0.6 s is ~1e-11 here; asserted 1e-8 rad on every sample."""
    B, beta = generic
    seg = _segments(P, step=0.001)
    model = shooting._Model(B, P)
    q = shooting._simulate(model, seg, seg.y0, beta, P.alpha)
    err = np.abs(q - seg.q) * seg.mask[:, :, None]
    assert err.max() < 1e-8, err.max()
    # and a wrong alpha is seen (the check can fail): 1 degree off moves the angles by > 1e-4 rad
    q1 = shooting._simulate(model, seg, seg.y0, beta, P.alpha + math.radians(1.0))
    assert (np.abs(q1 - seg.q) * seg.mask[:, :, None]).max() > 1e-4


def _central_differences(cost, beta, alpha, fi):
    """d cost / d beta_j (j in fi, steps 1e-6 relative) and d cost / d alpha (step 1e-6), central."""
    num = []
    for j in fi:
        h = 1e-6 * abs(beta[j])
        bp, bm = beta.copy(), beta.copy()
        bp[j] += h
        bm[j] -= h
        num.append((cost(bp, alpha) - cost(bm, alpha)) / (2 * h))
    num.append((cost(beta, alpha + 1e-6) - cost(beta, alpha - 1e-6)) / 2e-6)
    return num


def test_the_sensitivities_are_the_exact_gradient_of_the_discrete_model(generic):
    """g = J^T e from the variational equations (starts, free base parameters, alpha) against central
    differences of the cost 1/2 sum e^2 of the same RK4 map, on data 2 % off the model (so e != 0).
    Differences of step 1e-6 relative: truncation ~1e-12 and rounding ~1e-10 of |g|; asserted 1e-6."""
    B, beta = generic
    truth = P.replace(c1=0.025, m2=P.m2 * 1.02)
    seg = _segments(truth, seconds=0.3)
    model = shooting._Model(B, P)
    names = list(B.names)
    free = [n for n in names if n in ("h1y_b", "J2zz_b", "h2y", "c1", "c2")]
    fi = [names.index(n) for n in free]
    alpha = P.alpha + 0.01
    e, Hll, Hlg, Hgg, gl, gg = shooting._linearise(model, seg, seg.y0, beta, alpha, fi, True)

    def cost(y0, b, al):
        qq = shooting._simulate(model, seg, y0, b, al)
        return 0.5 * float(np.sum(((qq - seg.q) * seg.mask[:, :, None]) ** 2))

    assert cost(seg.y0, beta, alpha) == pytest.approx(0.5 * float(np.sum(e**2)), rel=1e-12)
    num = _central_differences(lambda b, al: cost(seg.y0, b, al), beta, alpha, fi)
    exact = gg.sum(0)
    np.testing.assert_allclose(exact, num, rtol=1e-6, atol=1e-9 * np.abs(exact).max())
    # one start value of one segment
    y0p, y0m = seg.y0.copy(), seg.y0.copy()
    y0p[1, 3] += 1e-6
    y0m[1, 3] -= 1e-6
    assert gl[1, 3] == pytest.approx((cost(y0p, beta, alpha) - cost(y0m, beta, alpha)) / 2e-6, rel=1e-6)


def test_a_fit_recovers_a_skewed_model_from_noiseless_data(generic):
    """From beta 5 % off and alpha 2 degrees off, noiseless data of the 25 degree model: the fit returns
    the truth to the RK4 step's error (2 ms: ~1e-9 rad on the angles), asserted 1e-5 relative on the free
    base parameters and 1e-5 rad on alpha; the cost falls to rounding."""
    B, beta = generic
    seg = _segments(P, seconds=0.6)
    names = list(B.names)
    free = [n for n in names if n in ("h1y_b", "J2zz_b", "h2y", "c1", "c2")]
    start = beta.copy()
    for n in free:
        start[names.index(n)] *= 1.05
    r = shooting.fit(B, P, start, free, P.alpha + math.radians(2.0), True, seg, pieces=len(STARTS), bootstrap=0)
    assert r.converged, r.message
    for n in free:
        assert r.beta[names.index(n)] == pytest.approx(beta[names.index(n)], rel=1e-5), n
    assert abs(r.alpha - P.alpha) < 1e-5
    assert r.cost < 1e-12
    assert r.theta_names == tuple(free) + ("alpha",)


def test_the_stopping_rule_measures_steps_against_the_intervals():
    """``_halves``: the undamped Gauss-Newton step and the sandwich's 95 % half-widths from the
    accumulated blocks (what the stopping rule compares, STEP_HALF); None with fewer than two pieces
    (no interval over pieces) or a singular reduced matrix."""
    from scipy.stats import t as student_t

    rng = np.random.default_rng(3)
    S, p = 6, 2
    J = rng.normal(size=(S, 10, 4 + p))  # per segment: residual Jacobian in (4 start values, p globals)
    r = rng.normal(size=(S, 10))
    Hll = np.einsum("sia,sib->sab", J[:, :, :4], J[:, :, :4])
    Hlg = np.einsum("sia,sib->sab", J[:, :, :4], J[:, :, 4:])
    Hgg = np.einsum("sia,sib->sab", J[:, :, 4:], J[:, :, 4:])
    gl = np.einsum("sia,si->sa", J[:, :, :4], r)
    gg = np.einsum("sia,si->sa", J[:, :, 4:], r)
    owner = np.array([0, 0, 1, 1, 2, 2])
    step, half = shooting._halves(Hll, Hlg, Hgg, gl, gg, owner, 3)
    # the step is the least-squares step of the stacked problem in all unknowns, projected on the globals
    A = np.zeros((S * 10, 4 * S + p))
    for s in range(S):
        A[s * 10:(s + 1) * 10, 4 * s:4 * s + 4] = J[s, :, :4]
        A[s * 10:(s + 1) * 10, 4 * S:] = J[s, :, 4:]
    full = -np.linalg.lstsq(A, r.reshape(-1), rcond=None)[0]
    np.testing.assert_allclose(step, full[4 * S:], rtol=1e-9, atol=1e-12)
    assert half.shape == (p,) and np.all(half > 0)
    Sred, gred, _, _ = shooting._reduce(Hll, Hlg, Hgg, gl, gg, 0.0)
    Sinv = np.linalg.inv(Sred.sum(0))
    gc = np.array([gred[owner == c].sum(0) for c in range(3)])
    cov = Sinv @ (gc.T @ gc * 3 / 2) @ Sinv
    np.testing.assert_allclose(half, student_t.ppf(0.975, 2) * np.sqrt(np.diag(cov)), rtol=1e-12)
    assert shooting._halves(Hll, Hlg, Hgg, gl, gg, np.zeros(S, int), 1) is None
    assert shooting._halves(Hll, np.zeros_like(Hlg), np.zeros_like(Hgg), gl, gg, owner, 3) is None  # singular


#: The driven rig's extra terms (issue 27): Coulomb friction and the second motor's rotor on a geared axis,
#: with the skew angle freed beside them (the rotor's coupling terms are derived with alpha symbolic).
P_EXTRA = P.replace(cf1=0.05, cf2=0.03, Ir=2e-4, gr=-6.0)


@pytest.fixture(scope="module")
def extended():
    from skewpend.analysis import identify as I

    T = I.model_terms(P_EXTRA.replace(alpha=None))
    beta = T.values(I.standard_vector(P_EXTRA), P.a, P.alpha, P.g)
    assert T.extra == ("cf1", "cf2", "Ir")
    return T, beta


def test_friction_and_rotor_columns_keep_their_skew_angle(extended):
    """The extra columns of the regressor are derived with alpha symbolic when alpha is freed: the
    dynamics generated from them are the compiled simulation's at the model's own skew angle.  The
    friction ``cf atan(100 q')`` turns over |q'| ~ 0.01 rad/s, which RK4 resolves only below ~0.5 ms
    (1.6e-6 rad at 1 ms): at 0.5 and 0.25 ms the error is below 1e-7 and falls at least 8-fold (RK4
    order 4: 16) -- the regressor's dynamics converge to the simulation's."""
    T, beta = extended
    model = shooting._Model(T, P_EXTRA)
    errors = []
    for h in (0.0005, 0.00025):
        seg = _segments(P_EXTRA, dt=h, step=h)
        q = shooting._simulate(model, seg, seg.y0, beta, P.alpha)
        errors.append((np.abs(q - seg.q) * seg.mask[:, :, None]).max())
    assert errors[0] < 1e-7 and errors[1] < errors[0] / 8, errors
    # the rotor's coupling terms depend on alpha: a wrong one is seen
    seg = _segments(P_EXTRA, dt=0.00025, step=0.00025)
    q1 = shooting._simulate(model, seg, seg.y0, beta, P.alpha + math.radians(1.0))
    assert (np.abs(q1 - seg.q) * seg.mask[:, :, None]).max() > 1e-4


def test_sensitivities_with_friction_rotor_and_alpha_are_exact(extended):
    """As the test above for the inertial terms, with cf1, cf2, Ir and alpha among the free: the
    gradient from the variational equations against central differences of the same discrete cost."""
    T, beta = extended
    truth = P_EXTRA.replace(m2=P.m2 * 1.02, Ir=2.4e-4)
    seg = _segments(truth, seconds=0.3)
    model = shooting._Model(T, P_EXTRA)
    names = list(T.names)
    fi = [names.index(n) for n in ("h1y_b", "J2zz_b", "cf1", "cf2", "Ir")]
    alpha = P.alpha + 0.01
    e, Hll, Hlg, Hgg, gl, gg = shooting._linearise(model, seg, seg.y0, beta, alpha, fi, True)

    def cost(b, al):
        qq = shooting._simulate(model, seg, seg.y0, b, al)
        return 0.5 * float(np.sum(((qq - seg.q) * seg.mask[:, :, None]) ** 2))

    num = _central_differences(cost, beta, alpha, fi)
    exact = gg.sum(0)
    np.testing.assert_allclose(exact, num, rtol=1e-6, atol=1e-9 * np.abs(exact).max())

