"""The equations' linearity in the inertial parameters, the base parameters, the first estimate
(skewpend.symbolic.regressor)."""

from __future__ import annotations

import math

import numpy as np
import pytest
import sympy as sp

from skewpend import Parameters, derive
from skewpend.symbolic import regressor as R
from skewpend.symbolic.symbols import SYMBOLS as S

PLANAR = Parameters(alpha=0.0)
SKEWED = Parameters()  # alpha generic


def _body(rng, m, length):
    """A seeded random rigid body: centre of mass off the rod axis, a full inertia tensor."""
    s = rng.uniform(0.05, 1.0, 3) * np.array([0.03, length, 0.03]) ** 2 * m / 4
    lam = np.array([s[1] + s[2], s[0] + s[2], s[0] + s[1]])  # principal moments of a mass distribution
    Q, _ = np.linalg.qr(rng.normal(size=(3, 3)))
    inertia = Q @ np.diag(lam) @ Q.T
    com = np.array([rng.normal(0, 0.02), rng.uniform(0.3, 0.7) * length, rng.normal(0, 0.02)])
    return tuple(map(float, com)), tuple(tuple(map(float, r)) for r in inertia)


def _general_model(seed=7, alpha=math.radians(20)):
    rng = np.random.default_rng(seed)
    com1, in1 = _body(rng, 0.6, 0.2)
    com2, in2 = _body(rng, 0.4, 0.25)
    return Parameters(a=0.2, b=0.25, m1=0.6, m2=0.4, alpha=alpha, g=9.81, c1=0.004, c2=0.002,
                      com1=com1, com2=com2, inertia1=in1, inertia2=in2)


@pytest.fixture(scope="module")
def reg():
    return R.regressor()


@pytest.fixture(scope="module")
def planar():
    return R.base_parameters(PLANAR)


@pytest.fixture(scope="module")
def skewed():
    return R.base_parameters(SKEWED)


@pytest.fixture(scope="module")
def general():
    """A general-body model at alpha = 20 deg with damping, and its compiled kernel."""
    from skewpend.numeric.kernels import kernel_module

    p = _general_model()
    return p, kernel_module(p)


def _accelerations(kernel, p, ys):
    """q'' from the model's own generated right-hand side, row by row."""
    from skewpend.numeric.kernels import parameter_vector

    pv = parameter_vector(p)
    out = np.empty(5)
    acc = np.empty((len(ys), 2))
    for k, y in enumerate(ys):
        kernel.rhs(np.append(y[:4], 0.0), pv, out)
        acc[k] = out[2:4]
    return acc


# -- 1. the regressor -------------------------------------------------------------------------------
def test_regressor_is_exactly_linear(reg):
    """Y is free of pi and Y pi is the derivation's M q'' - f, symbolically (checked when built too)."""
    assert reg.Y.shape == (2, len(R.PI_NAMES))
    assert not reg.Y.free_symbols & set(reg.pi)
    assert reg.Y.free_symbols <= {S[n] for n in ("phi", "psi", "dphi", "dpsi", "ddphi", "ddpsi", "a", "alpha", "g")}
    rest = (reg.lhs - reg.Y * sp.Matrix(reg.pi)).applyfunc(R._canonical)
    assert rest == sp.zeros(2, 1)
    # the damping columns are the speeds, m1 enters nowhere
    assert reg.column("c1") == sp.Matrix([S["dphi"], 0]) and reg.column("c2") == sp.Matrix([0, S["dpsi"]])
    assert reg.column("m1") == sp.zeros(2, 1)


def test_thin_rods_planar_symbolically(reg):
    """alpha = 0, thin rods: Y pi equals the derivation's equations of the specification's model."""
    a, b, m1, m2 = (S[n] for n in ("a", "b", "m1", "m2"))
    eom = derive(Parameters(alpha=0.0, c1=None, c2=None))
    ddq = sp.Matrix([S["ddphi"], S["ddpsi"]])
    values = {n: 0 for n in R.PI_NAMES}
    values.update(m1=m1, m2=m2, h1y=m1 * a / 2, h2y=m2 * b / 2, c1=S["c1"], c2=S["c2"],
                  J1xx=m1 * a**2 / 3, J1zz=m1 * a**2 / 3, J2xx=m2 * b**2 / 3, J2zz=m2 * b**2 / 3)
    pi = sp.Matrix([values[n] for n in R.PI_NAMES])
    diff = (reg.Y.subs(S["alpha"], 0) * pi - (eom.mass_matrix * ddq - eom.forcing)).applyfunc(R._canonical)
    assert diff == sp.zeros(2, 1)


def test_standard_parameters_of_thin_rods():
    p = Parameters(a=2.0, b=1.0, m1=3.0, m2=1.5, alpha=0.1, g=9.81, c1=0.1, c2=0.2)
    pi = dict(zip(R.PI_NAMES, R.standard_parameters(p)))
    assert pi["h1y"] == pytest.approx(3.0) and pi["J1zz"] == pytest.approx(3.0 * 4 / 3)
    assert pi["J1yy"] == pytest.approx(0.0) and pi["h2y"] == pytest.approx(0.75) and pi["c2"] == 0.2


def test_regressor_matches_generated_functions(reg, general):
    """Random general bodies, random alpha (a run-time input of the compiled kernel), random torques:
    Y(q, q', q'') pi = tau with q'' from the generated right-hand side, to 1e-12."""
    p0, kernel = general
    rng = np.random.default_rng(3)
    Y = reg.numeric()
    for _ in range(5):
        p = p0.replace(alpha=float(rng.uniform(-1.5, 1.5)), tau1=float(rng.normal()), tau2=float(rng.normal()))
        ys = np.column_stack([rng.uniform(-3, 3, (20, 2)), rng.normal(0, 3, (20, 2))])
        acc = _accelerations(kernel, p, ys)
        tau = Y(ys[:, :2], ys[:, 2:], acc, p.a, p.alpha, p.g) @ R.standard_parameters(p)
        assert np.abs(tau - [p.tau1, p.tau2]).max() < 1e-12 * max(1.0, abs(p.tau1), abs(p.tau2))


# -- 2, 3. base parameters --------------------------------------------------------------------------
def test_planar_base_parameters(planar):
    """Planar, free rigid bodies: 8 base parameters (6 inertial, 2 damping)."""
    a, m2 = S["a"], S["m2"]
    pi = dict(zip(R.PI_NAMES, R.PI_SYMBOLS))
    assert planar.rank == 8
    got = dict(zip(planar.names, planar.expressions))
    assert got == {
        "J1zz_b": pi["J1zz"] + a**2 * m2, "h1y_b": pi["h1y"] + a * m2, "h1x": pi["h1x"],
        "J2zz": pi["J2zz"], "h2y": pi["h2y"], "h2x": pi["h2x"], "c1": pi["c1"], "c2": pi["c2"],
    }
    assert set(planar.unidentifiable) == {"m1", "h1z", "J1xx", "J1xy", "J1xz", "J1yy", "J1yz",
                                          "h2z", "J2xx", "J2xy", "J2xz", "J2yy", "J2yz"}


def test_skewed_base_parameters(skewed):
    """Skewed (generic alpha), general 3D bodies: 12 base parameters; the relations are exact
    expressions in a and alpha and reduce to the planar ones as alpha -> 0."""
    assert skewed.rank == 12
    pi = dict(zip(R.PI_NAMES, R.PI_SYMBOLS))
    got = dict(zip(skewed.names, skewed.expressions))
    al, a, m2 = S["alpha"], S["a"], S["m2"]
    assert sp.simplify(got["J1zz_b"] - (pi["J1zz"] + a**2 * m2 + pi["J2yy"] * sp.sin(al) ** 2)) == 0
    assert sp.simplify(got["h1x_b"] - (pi["h1x"] + pi["h2z"] * sp.tan(al))) == 0
    assert set(skewed.unidentifiable) == {"m1", "h1z", "J1xx", "J1xy", "J1xz", "J1yy", "J1yz"}
    planar_limit = {n: sp.expand(e.subs(al, 0)) for n, e in got.items()}
    assert planar_limit["J1zz_b"] == pi["J1zz"] + a**2 * m2 and planar_limit["h2x_b"] == pi["h2x"]


@pytest.mark.parametrize("which", ["planar", "skewed"])
def test_base_regressor_full_rank_and_dependent_columns_drop_it(which, planar, skewed, reg):
    base = {"planar": planar, "skewed": skewed}[which]
    alpha = 0.0 if which == "planar" else 0.7
    q, dq, ddq = R.sample_states(30, seed=11)  # other samples than the ones the rank was found on
    Yb = base.regressor(q, dq, ddq, 0.9, alpha, 9.81).reshape(-1, base.rank)
    assert np.linalg.matrix_rank(Yb) == base.rank
    Y = reg.numeric()(q, dq, ddq, 0.9, alpha, 9.81).reshape(-1, len(R.PI_NAMES))
    for j in base.dependent:
        assert np.linalg.matrix_rank(np.column_stack([Yb, Y[:, j]]), tol=1e-9 * np.abs(Yb).max()) == base.rank
    # Y pi = Y_b (T pi): the base parameters carry everything the equations see
    pi = np.random.default_rng(0).normal(size=len(R.PI_NAMES))
    assert np.allclose(Y @ pi, Yb @ (base.matrix_at(0.9, alpha, 9.81) @ pi), rtol=0, atol=1e-12 * np.abs(Y @ pi).max())


@pytest.mark.slow  # about 5 s: the derivation with a float axis and the float-tolerant relations
def test_user_axis_and_no_gravity():
    """A numeric second axis (1/|v| enters the derivation as a float: relations to rounding) and g = 0."""
    tilted = R.base_parameters(Parameters(axis2=(0.3, 0.1, 1.0)))
    assert tilted.rank == 12 and "alpha" not in tilted.where
    assert sp.expand(dict(zip(tilted.names, tilted.expressions))["h1x_b"]) == sp.Symbol("h1x", real=True) + \
        sp.Float(0.3) * sp.Symbol("h2z", real=True)
    q, dq, ddq = R.sample_states(20, seed=5)
    Y = R.regressor(Parameters(axis2=(0.3, 0.1, 1.0))).numeric()(q, dq, ddq, 0.7, 0.0, 9.81).reshape(-1, 22)
    Yb = tilted.regressor(q, dq, ddq, 0.7, 0.0, 9.81).reshape(-1, 12)
    pi = np.random.default_rng(1).normal(size=22)
    assert np.allclose(Y @ pi, Yb @ (tilted.matrix_at(0.7, 0.0, 9.81) @ pi), rtol=0, atol=1e-12 * np.abs(Y @ pi).max())
    weightless = R.base_parameters(Parameters(alpha=0.0, g=0.0))
    assert weightless.rank == 6 and "h1x" in weightless.unidentifiable


def test_planar_base_parameters_are_the_data_readme_combinations(planar):
    """The kaheman2023 README's J1, J2, K, P1, P2 (planar, centres of mass on the rods: a1, a2 from each
    hinge, L1 between the hinges, I1, I2 about the centres of mass) are exactly

        J1 = J1zz_b, J2 = J2zz, K = a h2y, P1 = g h1y_b, P2 = g h2y

    with a = L1, h1y = m1 a1, h2y = m2 a2; its damping k1 (on dtheta1) and k2 (on dtheta2 - dtheta1,
    the relative angle psi) are c1 and c2.  With a and g known, K and P2 are one base parameter
    (K/P2 = a/g): free swing determines 5 independent ratios of the 6 base parameters
    J1zz_b, h1y_b, J2zz, h2y, c1, c2 (the off-axis h1x, h2x are 0 there)."""
    m1, m2, a1, a2, L1, I1, I2, k1, k2, g = sp.symbols("m1 m2 a1 a2 L1 I1 I2 k1 k2 g", positive=True)
    readme = {"J1": I1 + m1 * a1**2 + m2 * L1**2, "J2": I2 + m2 * a2**2, "K": m2 * L1 * a2,
              "P1": g * (m1 * a1 + m2 * L1), "P2": g * m2 * a2}
    pi = {n: 0 for n in R.PI_NAMES}
    pi.update(m1=m1, m2=m2, h1y=m1 * a1, h2y=m2 * a2, J1zz=I1 + m1 * a1**2, J2zz=I2 + m2 * a2**2,
              J1xx=I1 + m1 * a1**2, J2xx=I2 + m2 * a2**2, c1=k1, c2=k2)
    sub = {sym: pi[n] for n, sym in zip(R.PI_NAMES, R.PI_SYMBOLS)}
    sub[S["a"]] = L1
    beta = {n: e.xreplace(sub) for n, e in zip(planar.names, planar.expressions)}
    assert sp.expand(beta["J1zz_b"] - readme["J1"]) == 0
    assert sp.expand(beta["J2zz"] - readme["J2"]) == 0
    assert sp.expand(L1 * beta["h2y"] - readme["K"]) == 0
    assert sp.expand(g * beta["h1y_b"] - readme["P1"]) == 0
    assert sp.expand(g * beta["h2y"] - readme["P2"]) == 0
    assert beta["c1"] == k1 and beta["c2"] == k2 and beta["h1x"] == 0 and beta["h2x"] == 0
    # the README's ratios from the base ones
    ratios = {"J2/J1": beta["J2zz"] / beta["J1zz_b"], "K/J1": L1 * beta["h2y"] / beta["J1zz_b"],
              "P1/J1": g * beta["h1y_b"] / beta["J1zz_b"], "P2/J1": g * beta["h2y"] / beta["J1zz_b"]}
    assert sp.simplify(ratios["K/J1"] - L1 / g * ratios["P2/J1"]) == 0


def test_describe_names_the_undetermined_scale(planar, skewed):
    text = planar.describe(free_motion=True)
    assert "8 base parameters" in text and "J1zz_b = J1zz + a**2*m2" in text
    assert R.SCALE_DIRECTION in text and "7 ratios" in text
    assert "J2zz/J1zz_b" in planar.ratios()
    assert "12 base parameters" in skewed.describe()


# -- 4. the linear estimate on synthetic data ---------------------------------------------------------
def _pieces(p, kernel, torques, seconds=2.0, dt=0.02):
    """Simulated pieces (one per constant torque pair), q'' from the model's right-hand side."""
    import skewpend

    rows, taus = [], []
    starts = [(2.0, -1.0, 0.0, 1.0), (-1.2, 2.5, 1.0, 0.0), (0.5, 1.5, -2.0, 3.0)]
    for (t1, t2), y0 in zip(torques, starts):
        pk = p.replace(tau1=t1, tau2=t2)
        # any states will do (q'' is the model's at each): DOP853, no Taylor library built for this body alone
        tr = skewpend.simulate(pk, y0, seconds, dt_out=dt, method="dop853")
        ys = np.asarray(tr.y)[:, :4]
        acc = _accelerations(kernel, pk, ys)
        rows.append(np.column_stack([ys, acc]))
        taus.append(np.tile([t1, t2], (len(ys), 1)))
    data = np.vstack(rows)
    return data, np.vstack(taus)


@pytest.fixture(scope="module")
def synthetic(general, skewed):
    p, kernel = general
    data, tau = _pieces(p, kernel, [(0.05, -0.02), (-0.03, 0.04), (0.0, 0.01)])
    Yb = skewed.regressor(data[:, :2], data[:, 2:4], data[:, 4:6], p.a, p.alpha, p.g)
    truth = skewed.values(R.standard_parameters(p), p.a, p.alpha, p.g)
    return p, kernel, data, tau, Yb, truth


def test_linear_estimate_exact_without_noise(synthetic, skewed):
    p, _, data, tau, Yb, truth = synthetic
    assert np.abs(np.einsum("nij,j->ni", Yb, truth) - tau).max() < 1e-12
    est = R.linear_estimate(Yb, tau, names=skewed.names)
    assert np.abs(est.values - truth).max() < 1e-10 * np.abs(truth).max()
    assert np.all(est.intervals[:, 0] <= est.values) and est.names == skewed.names
    assert "J1zz_b" in est.table()


def test_linear_estimate_intervals_cover_over_20_seeds(synthetic, skewed):
    """Torques measured with seeded noise: each 95 % interval covers the truth in >= 17 of 20 seeds."""
    p, _, data, tau, Yb, truth = synthetic
    sigma = 2e-3
    w = np.ones_like(tau)
    cover = np.zeros(skewed.rank, dtype=int)
    for seed in range(20):
        noisy = tau + np.random.default_rng(seed).normal(0, sigma, tau.shape)
        est = R.linear_estimate(Yb, noisy, w, names=skewed.names)
        cover += (est.intervals[:, 0] <= truth) & (truth <= est.intervals[:, 1])
        assert est.sigma2 == pytest.approx(sigma**2, rel=0.3)
    assert cover.min() >= 17, dict(zip(skewed.names, cover))


def test_linear_estimate_free_motion_gives_ratios(general, skewed):
    """No torques: homogeneous; the null vector normalised by J1zz_b gives the ratios exactly."""
    p, kernel = general
    data, tau = _pieces(p, kernel, [(0.0, 0.0), (0.0, 0.0)])
    assert not tau.any()
    Yb = skewed.regressor(data[:, :2], data[:, 2:4], data[:, 4:6], p.a, p.alpha, p.g)
    truth = skewed.values(R.standard_parameters(p), p.a, p.alpha, p.g)
    k = skewed.names.index("J1zz_b")
    est = R.linear_estimate(Yb, None, names=skewed.names, reference=k)
    assert est.reference == "J1zz_b" and est.values[k] == 1.0
    assert np.abs(est.values - truth / truth[k]).max() < 1e-8
    assert est.intervals[k].tolist() == [1.0, 1.0]


def test_linear_estimate_refuses_bad_input(skewed):
    from skewpend.errors import ParameterError

    Yb = np.ones((3, 2, skewed.rank))
    with pytest.raises(ParameterError, match="cannot determine"):
        R.linear_estimate(Yb, np.ones((3, 2)))
    with pytest.raises(ParameterError, match="weights"):
        R.linear_estimate(Yb, np.ones((3, 2)), -np.ones((3, 2)))
    with pytest.raises(ParameterError, match="reference"):
        skewed.ratios("nope")
