"""skewpend.identify, the linear first estimate (issue 27): on the real free-swing data of Kaheman et al.
(2023) against the authors' published parameters, on noiseless synthetic data made by skewpend, the
result protocol, and bad input.  The real data are read and fitted once per module (the fixture: a
few seconds, most of it the symbolic base parameters, computed once and cached)."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest

import skewpend
from skewpend import Measurements, Status
from skewpend.analysis.identify import Identification, identify
from skewpend.errors import ParameterError
from skewpend.symbolic import regressor as R

KAHEMAN = Path(__file__).resolve().parent.parent / "data" / "kaheman2023"


def kaheman_values():
    from scipy.io import loadmat

    return [float(x) for x in loadmat(str(KAHEMAN / "EstimatedParameters_DoublePendulum.mat"))
            ["EstimatedParameters"].ravel()]


def kaheman_parameters(**changes) -> skewpend.Parameters:
    """The authors' model in skewpend's terms (as tests/test_measurements.py)."""
    m1, m2, a1, a2, L1, I1, I2, k1, k2, g = kaheman_values()
    p = skewpend.Parameters(a=L1, b=2 * a2, m1=m1, m2=m2, alpha=0, g=g, c1=k1, c2=k2, com1=(0, a1, 0),
                            com2=(0, a2, 0), inertia1=((I1, 0, 0), (0, 0, 0), (0, 0, I1)),
                            inertia2=((I2, 0, 0), (0, 0, 0), (0, 0, I2)))
    return p.replace(**changes) if changes else p


def readme_ratios(ratios, L1, g):
    """The data README's J2/J1, K/J1, P1/J1, P2/J1 from the ratios to J1zz_b (the identities of
    tests/test_regressor.py: J1 = J1zz_b, J2 = J2zz, K = a h2y, P1 = g h1y_b, P2 = g h2y)."""
    return {"J2/J1": ratios["J2zz/J1zz_b"], "K/J1": L1 * ratios["h2y/J1zz_b"],
            "P1/J1": g * ratios["h1y_b/J1zz_b"], "P2/J1": g * ratios["h2y/J1zz_b"]}


def published_ratios():
    m1, m2, a1, a2, L1, I1, I2, k1, k2, g = kaheman_values()
    J1 = I1 + m1 * a1**2 + m2 * L1**2
    return {"J2/J1": (I2 + m2 * a2**2) / J1, "K/J1": m2 * L1 * a2 / J1, "P1/J1": g * (m1 * a1 + m2 * L1) / J1,
            "P2/J1": g * m2 * a2 / J1}


@pytest.fixture(scope="module")
def kaheman_linear():
    fit = Measurements.from_kaheman(KAHEMAN, which="fit")
    val = Measurements.from_kaheman(KAHEMAN, which="validation")
    return identify(fit, kaheman_parameters(), validation=val, method="linear")


@pytest.fixture(scope="module")
def kaheman_fit():
    """The default method: the linear estimate, then the output-error fit (multiple shooting)."""
    fit = Measurements.from_kaheman(KAHEMAN, which="fit")
    val = Measurements.from_kaheman(KAHEMAN, which="validation")
    return identify(fit, kaheman_parameters(), validation=val)


# -- the real free swing -----------------------------------------------------------------------------------
def test_kaheman_linear_ratios_match_the_published_values(kaheman_linear):
    """The linear estimate (default smoothing 0.05 s, order 4) on the 26 fitting pieces against the
    authors' published parameters, measured: J2/J1 +0.22 %, K/J1 +0.14 %, P1/J1 -0.18 %, P2/J1 +0.14 %.
    Asserted: within 1 % each (the issue's goal for the final method is 2 %).  K/P2 = a/g exactly.
    The 95 % intervals (about +-0.07 % on J2/J1) do NOT cover the published values: they carry the
    noise and the piece-to-piece spread, not the filter's bias nor the published model's own error."""
    r = kaheman_linear
    assert r.ok, r.message
    assert r.reference == "J1zz_b" and len(r.ratios) == 7
    m1, m2, a1, a2, L1, I1, I2, k1, k2, g = kaheman_values()
    ours, theirs = readme_ratios(r.ratios, L1, g), published_ratios()
    diff = {k: 100 * (ours[k] / theirs[k] - 1) for k in theirs}
    assert all(abs(d) < 1.0 for d in diff.values()), diff
    assert ours["K/J1"] / ours["P2/J1"] == pytest.approx(L1 / g, rel=1e-12)


def test_kaheman_output_error_ratios_match_the_published_values(kaheman_fit):
    """The default output-error fit (the absolute angles the rig measured, each 2.67 s piece one shooting
    segment, RK4 at 4 ms) from the linear estimate, against the authors' values: J2/J1 +0.50 %, K/J1 +0.27 %,
    P1/J1 +0.01 %, P2/J1 +0.27 % (0.5 s segments in the joint angles: +0.10, +0.01, +0.06, +0.01 %; the goal of
    issue 31: 2 %).  Asserted: 1 % each, and the fit's angle residual per piece below 5e-3 rad (measured median
    3.0e-3 over the whole pieces, 7.6e-4 over 0.5 s segments)."""
    r = kaheman_fit
    assert r.ok, r.message
    assert r.method == "output-error" and r.reference == "J1zz_b" and len(r.ratios) == 7
    m1, m2, a1, a2, L1, I1, I2, k1, k2, g = kaheman_values()
    ours, theirs = readme_ratios(r.ratios, L1, g), published_ratios()
    diff = {k: 100 * (ours[k] / theirs[k] - 1) for k in theirs}
    assert all(abs(d) < 1.0 for d in diff.values()), diff
    assert len(r.fit_rms) == 26 and np.median(r.fit_rms) < 5e-3
    assert r.settings["segments"] == 26 and r.settings["whole_pieces"] and r.settings["converged"]


def test_kaheman_output_error_heldout_beats_the_authors_model(kaheman_fit):
    """The 4 held-out pieces simulated from their first measured state (the authors' protocol).  Measured,
    median over pieces: 0.00398 rad in the absolute angles the rig measured (the authors' model 0.00420),
    0.00293 in the joint angles (authors 0.00328; issue 53's goal: 0.00316 or better); overall (the fourth piece
    dominates it) 0.00751 against 0.00724 in the absolute angles.  Asserted: both medians below the authors',
    the joint one at most 0.00316, the overall within 5 % of theirs."""
    r = kaheman_fit
    assert r.settings["angles"] == "absolute"
    assert r.heldout_median <= r.heldout_median0, (r.heldout_median, r.heldout_median0)
    assert r.stats["heldout_median_joint"] <= min(0.00316, r.stats["heldout_median0_joint"]), r.stats
    assert r.heldout_overall <= 1.05 * r.heldout_overall0


def test_kaheman_linear_heldout_prediction_beside_the_authors_model(kaheman_linear):
    """The 4 held-out pieces simulated from their first measured state over their 2.66 s, angle RMS over
    (phi, psi) and all samples, measured: fitted 0.00517 rad, the authors' model 0.00495 rad under the
    same protocol (piece 4 dominates: 0.0087 and 0.0083).  Asserted: overall below 0.01 rad and at most
    1.25 times the authors' (measured 1.045)."""
    r = kaheman_linear
    assert r.validation == ("Y_vad[0]", "Y_vad[1]", "Y_vad[2]", "Y_vad[3]") or len(r.validation) == 4
    assert set(r.heldout_kind) == {"angle"}
    assert np.all(np.isfinite(r.heldout_rms)) and np.all(np.isfinite(r.heldout_rms0))
    assert r.heldout_overall < 0.01 and r.heldout_overall0 < 0.01
    assert r.heldout_overall <= 1.25 * r.heldout_overall0, (r.heldout_overall, r.heldout_overall0)


@pytest.mark.parametrize("which", ["kaheman_linear", "kaheman_fit"])
def test_kaheman_fitted_parameters_realise_the_estimate(which, request):
    """The fitted Parameters: params0's masses and overall scale (J1zz_b), and base parameters equal to
    the estimate to 1e-9 (recomputed from the Parameters)."""
    r = request.getfixturevalue(which)
    p, p0 = r.params, r.params0
    assert p.m1 == p0.m1 and p.m2 == p0.m2 and p.a == p0.a and p.g == p0.g
    B = R.base_parameters(p0)
    beta = B.values(R.standard_parameters(p), p.a, 0.0, p.g)
    assert np.abs(beta - r.values).max() <= 1e-9 * np.abs(r.values).max()
    beta0 = B.values(R.standard_parameters(p0), p0.a, 0.0, p0.g)
    assert beta[0] == pytest.approx(beta0[0], rel=1e-12)
    free = [n != r.reference for n in r.names]  # the scale is params0's: it has no interval
    assert np.all(r.intervals[free, 0] <= r.values[free]) and np.all(r.values[free] <= r.intervals[free, 1])
    assert np.all(np.isnan(r.intervals[r.names.index(r.reference)]))
    assert len(r.residual_rms) == 26 and np.all(r.residual_rms > 0)


def test_kaheman_result_protocol(kaheman_fit, tmp_path):
    r = kaheman_fit
    assert isinstance(r, Identification) and r.result_kind == "identification" and r.status is Status.SUCCESS
    text = r.table()
    assert "J1zz_b" in text and "one overall scale of every inertial parameter and damping" in text
    assert "m1" in text and "held out angle RMS: median over pieces" in text and "output error per fitting piece" in text
    assert "identification" in r.summary() and "Identification success" in repr(r)
    ds = r.to_xarray()
    assert ds.attrs["base_names"].split("; ") == list(r.names) and ds["value"].shape == (8,)
    assert r.expressions[0] == "J1zz + 0.0298319*m2"  # a**2 m2 at the measured a
    assert ds.attrs["kind"] == "identification"
    path = r.to_netcdf(tmp_path / "fit.nc")
    import xarray as xr

    with xr.open_dataset(path) as back:
        assert np.array_equal(back["value"].values, r.values) and back.attrs["kind"] == "identification"
    # one reader for every result: the same table back, the base parameters re-derived from the stored
    # model and checked; a file whose model was changed is refused
    again = skewpend.open_result(path)
    assert isinstance(again, Identification) and again.table() == r.table() and again.params == r.params
    with xr.open_dataset(path) as back:
        bad = back.load()
    bad["value"].values[1] *= 1.01
    bad.to_netcdf(tmp_path / "bad.nc")
    with pytest.raises(ParameterError, match="base parameters differs from what its parameters give"):
        skewpend.open_result(tmp_path / "bad.nc")


# -- synthetic data made by skewpend -------------------------------------------------------------------
STARTS = [(2.0, -1.0, 0.0, 1.0), (-1.2, 2.5, 1.0, 0.0), (0.5, 1.5, -2.0, 3.0), (1.0, 0.3, 0.0, 0.0),
          (-0.3, -0.6, 1.0, 1.0)]


def _synthetic(p, torques=None, seconds=2.0):
    pieces = []
    for i, y0 in enumerate(STARTS):
        pk = p if torques is None else p.replace(tau1=torques[i][0], tau2=torques[i][1])
        tr = skewpend.simulate(pk, y0, seconds, dt_out=1e-3)
        y = np.asarray(tr.y)
        piece = {"t": np.asarray(tr.t), "q": y[:, :2], "dq": y[:, 2:4], "name": f"s{i}"}
        if torques is not None:
            piece["u"] = np.tile(torques[i], (len(y), 1))
        pieces.append(piece)
    return Measurements.from_arrays(pieces, skip=("mean",))


def test_synthetic_free_swing_recovers_the_ratios():
    """A known planar model with damping (the authors' geometry, larger damping), simulated from five
    starts for 2 s, sampled at 1 kHz, no noise; params0 wrong in c1 and com2.  With smoothing 0.02 s
    (21 samples, order 4) the filter's bias, which scales as window**4 here, leaves measured relative
    errors of 3e-6..6e-5 on the inertial ratios and 6e-4 on the damping ratios (0.05 s: 2e-3 on these
    fast chaotic swings).  Asserted: 1e-3 relative; the off-axis h1x, h2x (truth 0) below 1e-5."""
    truth_p = kaheman_parameters(c1=2e-4, c2=5e-5)
    M = _synthetic(truth_p)
    r = identify(M, truth_p.replace(c1=1e-4, com2=(0, 0.1, 0)), smoothing=0.02)
    assert r.ok, r.message
    B = R.base_parameters(truth_p)
    truth = B.values(R.standard_parameters(truth_p), truth_p.a, 0.0, truth_p.g)
    for n, t in zip(B.names[1:], truth[1:] / truth[0]):
        got = r.ratios[f"{n}/J1zz_b"]
        if n in ("h1x", "h2x"):
            assert abs(got) < 1e-5, (n, got)
        else:
            assert got == pytest.approx(t, rel=1e-3), n
    # J1zz_b held at the truth's value (free= the others): no reference, the same numbers in its scale
    held = identify(M, truth_p, free=[n for n in B.names if n != "J1zz_b"], smoothing=0.02)
    assert held.ok and held.reference is None and not held.ratios and "(held at params0)" in held.table()
    for n, t, got in zip(B.names, truth, held.values):
        if n not in ("h1x", "h2x"):
            assert got == pytest.approx(t, rel=1e-3), n


def test_synthetic_driven_recovers_the_base_parameters():
    """Constant measured torques per piece: the scale is determined (no reference).  Same data and
    smoothing as the free swing; asserted 1e-3 relative on every base parameter but the off-axis h1x,
    h2x (truth 0: below 1e-3 of the largest first moment)."""
    truth_p = kaheman_parameters(c1=2e-4, c2=5e-5)
    torques = [(0.01, -0.005), (-0.02, 0.01), (0.0, 0.015), (0.015, 0.0), (-0.01, -0.01)]
    M = _synthetic(truth_p, torques)
    assert M.has_torques
    r = identify(M, truth_p.replace(m2=truth_p.m2), smoothing=0.02)
    assert r.ok, r.message
    assert r.reference is None and not r.ratios
    B = R.base_parameters(truth_p)
    truth = B.values(R.standard_parameters(truth_p), truth_p.a, 0.0, truth_p.g)
    for n, t, got in zip(B.names, truth, r.values):
        if n in ("h1x", "h2x"):
            assert abs(got) < 1e-3 * abs(truth[B.names.index("h1y_b")]), (n, got)
        else:
            assert got == pytest.approx(t, rel=1e-3), n


def test_rank_deficient_data_get_an_honest_status():
    """Tiny swings (1e-4 rad) of one frequency: sin(phi) = phi to 1e-9, so gravity's columns are
    proportional to the accelerations'; the data do not determine every ratio."""
    t = np.arange(0, 5, 1e-3)
    w = 2 * math.pi * 0.9
    q = 1e-4 * np.column_stack([np.sin(w * t), 0.5 * np.sin(w * t)])
    M = Measurements.from_arrays([{"t": t, "q": q, "name": "tiny"}], skip=("mean", "tracking"))
    r = identify(M, kaheman_parameters())
    assert r.status is Status.NO_CONVERGENCE and not r.ok
    assert r.message.startswith("the data do not determine") and "add excitation" in r.message
    assert r.params == r.params0 and np.all(np.isnan(r.values))


# -- bad input -----------------------------------------------------------------------------------------
def test_bad_input_one_line_errors(kaheman_fit):
    M = Measurements.from_kaheman(KAHEMAN, which="validation")
    p0 = kaheman_parameters()
    cases = [
        (lambda: identify([1, 2], p0), "must be a skewpend Measurements"),
        (lambda: identify(M, {"a": 1}), "params0 must be a skewpend Parameters"),
        (lambda: identify(M, p0.replace(m1=None)), "params0 must be numeric"),
        (lambda: identify(M, p0, free=["J9zz"]), "unknown name 'J9zz'"),
        (lambda: identify(M, p0, free=["alpha"], method="linear"), "alpha enters the equations nonlinearly"),
        (lambda: identify(M, p0, method="newton"), "method must be one of output-error, linear"),
        (lambda: identify(M, p0, segment=0), "segment must be a positive"),
        (lambda: identify(M, p0, segment="x"), "segment must be a positive"),
        (lambda: identify(M, p0, free=["m1"]), "m1 cannot be freed"),
        (lambda: identify(M, p0, free=["J1xx"]), "J1xx is not a base parameter"),
        (lambda: identify(M, p0, free=[]), "free names no parameter"),
        (lambda: identify(M, p0, free=["cf1"]), "cf1 is not in params0.s model"),
        (lambda: identify(M, p0, smoothing=-1), "smoothing"),
        (lambda: identify(M, p0, smoothing=3.0), "too few for the smoothing window"),
        (lambda: identify(M, p0, validation="x"), "validation must be"),
    ]
    for call, says in cases:
        with pytest.raises(ParameterError, match=says) as info:
            call()
        assert "\n" not in str(info.value), says


# -- the skew angle -------------------------------------------------------------------------------------------
def test_kaheman_skew_angle_freed_is_zero_within_its_interval():
    """The real planar pendulum with alpha freed: alpha enters to second order at 0 (mirror symmetry), so
    its square is estimated -- measured -0.00166 +- 0.00126 rad^2, below zero (no skew fits better than
    none) -- and the 95 % bound on |alpha| is the root of its upper end from zero: 2.03 deg.  The issue's
    goal: |alpha| < 1 deg with an interval covering 0.  The base parameters stay the planar fit's."""
    fit = Measurements.from_kaheman(KAHEMAN, which="fit")
    r = identify(fit, kaheman_parameters(), free=["alpha"], bootstrap=50)
    assert r.ok, r.message
    assert abs(math.degrees(r.alpha)) < 1.0
    lo, hi = r.alpha_interval
    assert lo <= 0 <= hi and 0.2 < math.degrees(hi) < 5.0 and lo == -hi
    assert "sign is not determined" in r.alpha_note and "rad^2" in r.alpha_note
    assert len(r.profile_alpha) >= 7 and np.argmin(r.profile_cost) == len(r.profile_cost) // 2
    assert "held at the start's values" in " ".join(r.undetermined)


def test_synthetic_skew_angle_is_recovered_from_a_planar_start():
    """Free swings of the authors' rig made by skewpend at alpha = 20 deg (8 of the real pieces' starts,
    2.67 s at 1 kHz, noise 5e-4 rad), fitted from params0 at alpha = 0: the profile (1, 2, 4 ... 32 deg)
    finds the minimum away from 0, then alpha is fitted with every base parameter the skew brings in.
    Measured: 20.011 deg (seed 1).  Asserted: within 0.1 deg and the interval covers 20 deg;
    the sign is reported as not determined (the mirror rig fits as well)."""
    from skewpend.analysis.measurements import Piece

    real = list(Measurements.from_kaheman(KAHEMAN, which="fit"))[:8]
    truth = kaheman_parameters(alpha=math.radians(20.0))
    rng = np.random.default_rng(1)
    pieces = []
    for k, pc in enumerate(real):
        # rtol 1e-12 (Taylor order 15, the library the Kaheman fits load; 1e-11 took order 16, built for this alone)
        tr = skewpend.simulate(truth, [*pc.q[0], *pc.dq[0]], 2.666, dt_out=1e-3, rtol=1e-12, atol=1e-12)
        pieces.append(Piece(t=np.asarray(tr.t), q=np.asarray(tr.y)[:, :2] + rng.normal(0, 5e-4, (len(tr.t), 2)),
                            name=f"s{k}"))
    r = identify(Measurements(pieces), kaheman_parameters(), free=["alpha"], bootstrap=50)
    assert r.ok, r.message
    assert abs(math.degrees(r.alpha) - 20.0) < 0.1
    lo, hi = r.alpha_interval
    assert lo <= math.radians(20.0) <= hi and hi - lo < math.radians(1.0)
    assert "not determined" in r.alpha_note
    assert r.params.alpha == pytest.approx(r.alpha, abs=1e-15)
    # the model returned (fitted on alpha0's side of the mirror, over physical bodies) misses the angles by
    # the noise: within the chi-square test of identify.consistency (measured 0.99 times the noise; its
    # realisation from the estimate at -20 deg, accepted before as a model error, 1.70 times)
    assert r.stats["output_error"] <= chi2_bound(r.stats["residuals"]) * r.stats["noise"], r.message
    assert "model error" not in r.message


def chi2_bound(n: float) -> float:
    """The largest output error over the noise that identify.consistency's chi-square test passes (n residuals)."""
    from skewpend.analysis.identify import CHI2_SIGMAS, NOISE_SLACK

    return math.sqrt(1.0 + max(CHI2_SIGMAS * math.sqrt(2.0 / n), NOISE_SLACK))


# -- driven, with Coulomb friction and rotor inertia ----------------------------------------------------------
def test_a_geared_rotor_without_coulomb_friction_is_identified():
    """Rotors (Ir, gear -6) and no Coulomb friction: the fit's terms are (Ir,) only, and the base parameters
    of the shooting's vector (the model's own terms after the standard ones) were read at cf1, cf2, Ir's
    places (an IndexError).  Four free swings of 3 s, 0.1 mrad noise, params0 off in m1 and Ir: Ir
    recovered within 10 % (measured 2.9 %)."""
    p = skewpend.Parameters(a=0.3, b=0.25, m1=0.5, m2=0.4, alpha=0.3, g=9.81, c1=0.002, c2=0.001, Ir=2e-4, gr=-6.0)
    rng = np.random.default_rng(0)
    pieces = []
    for k in range(4):
        tr = skewpend.simulate(p, [0.8 - 0.2 * k, -0.5 + 0.3 * k, 0, 0], 3.0, dt_out=0.002)
        pieces.append({"t": tr.t, "q": np.asarray(tr.y)[:, :2] + 1e-4 * rng.normal(size=(len(tr.t), 2)), "name": f"p{k}"})
    r = identify(Measurements.from_arrays(pieces), p.replace(m1=0.55, Ir=1e-4), bootstrap=0)
    assert r.ok, r.message
    assert r.names[-1] == "Ir" and "cf1" not in r.names
    assert abs(r.params.Ir / 2e-4 - 1) < 0.1, r.params.Ir


def test_synthetic_driven_rig_with_friction_and_rotor():
    """The DFKI rig's lab model (h1.0: Coulomb friction cf * atan(100 dq), a geared rotor gr = -6) driven
    by sums of sines for 3 x 3 s, noiseless, sampled at 1 kHz with the torques measured; params0 off in
    c1, cf1, cf2 and Ir.  The friction and rotor columns are the derivative of the derived equations in
    cf1, cf2, Ir.  Measured relative errors: linear (smoothing 0.02 s) <= 2e-2 (damping; inertial 1e-4,
    friction 2e-3), output error <= 1.2e-3 (damping; friction 4e-5, Ir 9e-6).  Asserted: output error 5e-3
    on every base parameter (the off-axis h1x, h2x, truth 0: 5e-3 of the largest first moment)."""
    import sys

    from skewpend.analysis.identify import model_terms, standard_vector
    from skewpend.numeric.control import Controller

    sys.path.insert(0, str(Path(__file__).resolve().parent))
    from test_friction_rotor import dfki_model

    lab = dfki_model()
    pieces = []
    for i, (w1, w2, A1, A2) in enumerate([(1.3, 2.1, 0.6, 0.4), (0.7, 1.7, 0.8, 0.5), (2.3, 0.9, 0.5, 0.6)]):
        t = np.arange(0, 3.0 + 1e-9, 1e-3)
        u = np.column_stack([A1 * np.sin(w1 * 2 * np.pi * t / 3), A2 * np.sin(w2 * 2 * np.pi * t / 3 + 1)])
        tr = skewpend.simulate(lab, (0.1 * i, 0, 0, 0), 3.0, dt_out=1e-3, controller=Controller.table(t, u),
                               rtol=1e-11, atol=1e-11)
        y = np.asarray(tr.y)
        pieces.append({"t": np.asarray(tr.t), "q": y[:, :2], "dq": y[:, 2:],
                       "u": np.column_stack([np.interp(tr.t, t, u[:, k]) for k in range(2)]), "name": f"d{i}"})
    M = Measurements.from_arrays(pieces, skip=("mean",))
    B = model_terms(lab)
    truth = B.values(standard_vector(lab), lab.a, 0.0, lab.g)
    r = identify(M, lab.replace(c1=0.02, cf1=0.05, cf2=0.05, Ir=1e-4), smoothing=0.02)
    assert r.ok, r.message
    assert r.names[-3:] == ("cf1", "cf2", "Ir") and r.reference is None
    for n, v, tv in zip(r.names, r.values, truth):
        if n in ("h1x", "h2x"):
            assert abs(v) < 5e-3 * truth[r.names.index("h1y_b")], n
        else:
            assert v == pytest.approx(tv, rel=5e-3), n
    assert r.params.cf1 == pytest.approx(lab.cf1, rel=5e-3) and r.params.Ir == pytest.approx(lab.Ir, rel=5e-3)


# -- the real driven rig (DFKI design C.0) -----------------------------------------------------------------
DFKI = KAHEMAN.parent / "dfki-design-C.0"


def test_dfki_driven_rig_against_the_labs_models():
    """The driven rig's protocol (docs/guide/identification.md; ``benchmarks/bench_identify.py --only
    driven`` prints the table): fit trajectory_00..05 (60 s, both joints driven, measured torques), the
    9 base parameters of the lab's model (centres of mass on the rods), segments of 0.25 s, from the
    lab's model h1.0; held out trajectory_06, 12, 13 cut into 22 pieces of 1 s, each simulated from its
    first measured state with the measured torques.  Measured against h1.0 (and 3.0): J1zz_b -6.3 %
    (-8.5 %), h1y_b +0.6 % (-4.4 %), J2zz +4.9 % (+4.1 %), h2y +14.1 % (+3.6 %; the lab's two models
    differ by 10.2 % here), cf1 +0.1 %, cf2 -11.8 %; 95 % half-widths 17, 11, 11, 5, 61, 45 %.  Held
    out, median over the pieces: 0.0525 rad against h1.0's 0.0622; overall 1.534 against 1.585 (the
    swing-ups' falls dominate it).  Asserted: those deviations with a margin, h1.0 inside the
    intervals where it was (J1zz_b, h1y_b, J2zz, cf1, cf2; 3.0 for Ir, h2y), the held-out median at least 10 % below h1.0's and the overall no worse."""
    from skewpend.analysis.identify import model_terms, standard_vector
    from skewpend.analysis.measurements import dfki_lab_parameters

    files = lambda ids: [DFKI / f"trajectory_{i:02d}.csv" for i in ids]  # noqa: E731
    fit = Measurements.from_dfki(files(range(6)))
    held = Measurements.from_dfki(files((6, 12, 13))).cut(1.0)
    lab = dfki_lab_parameters(DFKI / "model_h1.0_parameters.yml")
    lab30 = dfki_lab_parameters(DFKI / "model_3.0_parameters.yml")
    free = ["J1zz_b", "h1y_b", "J2zz", "h2y", "c1", "c2", "cf1", "cf2", "Ir"]
    r = identify(fit, lab, validation=held, segment=0.25, free=free)
    assert r.ok, r.message
    assert len(held) == 22 and r.settings["iterations"] <= 20
    B = model_terms(lab)
    ref = dict(zip(B.names, B.values(standard_vector(lab), lab.a, 0.0, lab.g)))
    ref30 = dict(zip(B.names, B.values(standard_vector(lab30), lab30.a, 0.0, lab30.g)))
    got = dict(zip(r.names, r.values))
    iv = dict(zip(r.names, r.intervals))
    for n, tol in {"J1zz_b": 0.08, "h1y_b": 0.02, "J2zz": 0.065, "h2y": 0.16, "cf1": 0.02, "cf2": 0.14}.items():
        assert abs(got[n] / ref[n] - 1) <= tol, (n, got[n], ref[n])
    assert abs(got["h2y"] / ref30["h2y"] - 1) <= 0.05 and abs(got["h1y_b"] / ref30["h1y_b"] - 1) <= 0.05
    for n in ("J1zz_b", "h1y_b", "J2zz", "cf1", "cf2"):
        assert iv[n][0] <= ref[n] <= iv[n][1], n
    assert iv["Ir"][0] <= ref30["Ir"] <= iv["Ir"][1] and iv["h2y"][0] <= ref30["h2y"] <= iv["h2y"][1]
    assert got["h1x"] == 0 and got["h2x"] == 0  # held: the centres of mass on the rods
    assert r.heldout_kind == ("angle",) * 22
    assert r.heldout_median <= 0.9 * r.heldout_median0
    assert r.heldout_overall <= r.heldout_overall0
    # the model realises the estimate exactly (the masses raised: h1.0's cannot carry it)
    check = B.values(standard_vector(r.params), lab.a, 0.0, lab.g)
    assert np.allclose(check, r.values, rtol=1e-9, atol=1e-12)


def test_cut_and_the_labs_models_read_as_parameters():
    """``Measurements.cut`` splits each piece into parts of about the horizon (sharing their boundary
    sample, every sample kept); ``dfki_lab_parameters`` reads the lab's models with their base
    parameters exactly, model 3.0 (as written no body: I2 < m2 r2^2) with raised masses."""
    from skewpend.analysis.measurements import dfki_lab_parameters

    m = Measurements.from_dfki([DFKI / "trajectory_00.csv", DFKI / "trajectory_12.csv"])
    parts = m.cut(1.0)
    assert len(parts) == 10 + 6 and parts.names[0] == "trajectory_00 [0]" and parts.names[-1] == "trajectory_12 [5]"
    whole = m["trajectory_12"]
    twelve = [p for p in parts if p.name.startswith("trajectory_12")]
    assert twelve[0].t[0] == whole.t[0] and twelve[-1].t[-1] == whole.t[-1]
    assert all(a.t[-1] == b.t[0] for a, b in zip(twelve, twelve[1:]))
    assert sum(len(p) for p in twelve) == len(whole) + len(twelve) - 1
    assert all(abs(p.duration - 1.0) < 0.05 for p in twelve) and np.array_equal(twelve[2].u, whole.u[
        np.searchsorted(whole.t, twelve[2].t[0]):np.searchsorted(whole.t, twelve[2].t[-1]) + 1])
    assert len(m.cut(100.0)) == 2 and "cut into pieces" in parts.metadata["actions"][-1]
    with pytest.raises(ParameterError, match="seconds"):
        m.cut(0.0)
    h1 = dfki_lab_parameters(DFKI / "model_h1.0_parameters.yml")
    assert (h1.m1, h1.m2, h1.gr, h1.cfs) == (0.5476215952387185, 0.5978621372377623, -6.0, 100.0)
    m30 = dfki_lab_parameters(DFKI / "model_3.0_parameters.yml")
    assert m30.m2 > 0.563935954099688  # raised: the lab's split is no body
    r1, r2 = m30.com1[1], m30.com2[1]
    got = {"J1zz_b": m30.inertia1[2][2] + m30.m1 * r1**2 + m30.m2 * m30.a**2, "h1y_b": m30.m1 * r1 + m30.m2 * m30.a,
           "J2zz": m30.inertia2[2][2] + m30.m2 * r2**2, "h2y": m30.m2 * r2, "c1": m30.c1, "cf2": m30.cf2, "Ir": m30.Ir}
    assert min(m30.inertia1[2][2], m30.inertia2[2][2]) > 0 and m30.com1[0] == m30.com2[0] == 0
    I1, I2, m1, m2, r1, r2, l1 = 0.02671076499939512, 0.053878129629650884, 0.6416937799349799, 0.563935954099688, \
        0.2, 0.3212669909674605, 0.2
    want = {"J1zz_b": I1 + m2 * l1**2, "h1y_b": m1 * r1 + m2 * l1, "J2zz": I2, "h2y": m2 * r2, "c1": 0.001,
            "cf2": 0.078, "Ir": 9.937281205437459e-05}
    for n, v in want.items():
        assert got[n] == pytest.approx(v, rel=1e-12), n
