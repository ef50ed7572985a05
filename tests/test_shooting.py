"""The output-error fit's machinery (skewpend.analysis.shooting, issue 27): the dynamics generated from
the base regressor against the compiled simulation (two paths from the derivation), the exactness of the
sensitivities (the gradient of the discrete model against central differences of its own cost), and a
fit recovering a known skewed model from noiseless data."""

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


def test_the_compiled_regressor_functions_are_the_expressions(generic):
    """The C functions printed from the base regressor and its derivatives (shooting._generated)
    against SymPy's NumPy printing of the same expressions, at random states: equal to rounding
    (1e-12 relative to the largest entry of each matrix), and the speeds, alpha, a and g all read."""
    import sympy as sp

    from skewpend.symbolic.symbols import SYMBOLS as S

    B, _ = generic
    Y = B.symbolic_regressor
    base, full, r = shooting._generated(Y)
    YM1, YM2 = Y.diff(S["ddphi"]), Y.diff(S["ddpsi"])
    Yh = Y.xreplace({S["ddphi"]: 0, S["ddpsi"]: 0})
    mats = [YM1, YM2, Yh, Yh.diff(S["phi"]), Yh.diff(S["psi"]), YM1.diff(S["phi"]), YM1.diff(S["psi"]),
            YM2.diff(S["phi"]), YM2.diff(S["psi"]), Yh.diff(S["dphi"]), Yh.diff(S["dpsi"]), Yh.diff(S["alpha"]),
            YM1.diff(S["alpha"]), YM2.diff(S["alpha"])]
    args = [S[n] for n in ("phi", "psi", "dphi", "dpsi", "alpha", "a", "g")]
    numpy = sp.lambdify(args, [e for M in mats for e in M], modules="numpy")
    rng = np.random.default_rng(3)
    y = rng.uniform(-3, 3, (7, 4))
    for alpha, a, g in ((0.4, 1.0, 9.81), (-1.1, 0.37, 3.2)):
        got = full(y, alpha, a, g)
        want = np.array([np.broadcast_to(v, (7,)) for v in numpy(*y.T, alpha, a, g)])
        scale = np.abs(want.reshape(14, -1)).max(axis=1).repeat(2 * r)[:, None] + 1e-300
        assert np.all(np.abs(got - want) <= 1e-12 * scale), np.abs(got - want).max()
        assert np.all(np.abs(base(y, alpha, a, g) - want[: 3 * 2 * r]) <= 1e-12 * scale[: 3 * 2 * r])
    assert not np.array_equal(full(y, 0.4, 1.0, 9.81), full(y, 0.4, 1.0, 3.2))  # g is read
    assert not np.array_equal(full(y, 0.4, 1.0, 9.81), full(y, 0.4, 0.9, 9.81))  # a is read


def test_the_regressor_dynamics_are_the_simulations(generic):
    """RK4 at 1 ms on q'' = M(beta)^-1 (tau - Yh beta), generated from the base regressor, against the
    compiled DOP853 at 1e-12 on the kernels generated from the same derivation by another route:
    RK4's global error over 0.6 s is ~1e-11 here; asserted 1e-8 rad on every sample."""
    B, beta = generic
    seg = _segments(P, step=0.001)
    model = shooting._Model(B.symbolic_regressor, P.a, P.g)
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
    model = shooting._Model(B.symbolic_regressor, P.a, P.g)
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
    r = shooting.fit(B.symbolic_regressor, names, start, free, P.alpha + math.radians(2.0), True, seg, P.a, P.g,
                     pieces=len(STARTS), bootstrap=0)
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
    model = shooting._Model(T.symbolic_regressor, P.a, P.g)
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
    model = shooting._Model(T.symbolic_regressor, P.a, P.g)
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

