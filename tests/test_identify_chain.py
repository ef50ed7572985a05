"""Identifying a chain of links (issue 38): measurements with any number of angles, the chain's shooting
sensitivities against differences, its numerically found base parameters against the double pendulum's
symbolic ones, the recovery of a simulated skewed triple pendulum, and the real triple pendulum of
Kaheman et al. (2023) against the authors' own model."""

from __future__ import annotations

import ctypes
import math
import subprocess
import sys

import numpy as np
import pytest

import skewpend
from skewpend.analysis.identify import chain_terms, model_terms, predict_piece
from skewpend.analysis.measurements import Convention, convert, convert_back, kaheman_published_chain
from skewpend.errors import ParameterError
from skewpend.numeric import recursive
from skewpend.numeric.kernels import chain_kernel
from skewpend.symbolic.chain import Chain

TRIPLE = skewpend.example_data("kaheman2023-triple")


# -- measurements with three angles -----------------------------------------------------------------------
def test_kaheman_triple_reads_as_three_relative_angles():
    fit = skewpend.Measurements.from_kaheman(TRIPLE, which="fit")
    val = skewpend.Measurements.from_kaheman(TRIPLE, which="validation")
    assert (len(fit), len(val), fit.nq, fit.coordinates) == (22, 4, 3, ("q1", "q2", "q3"))
    assert fit.metadata["conversion"] == "q1 = theta1 - pi, q2 = theta2 - theta1, q3 = theta3 - theta2"
    from scipy.io import loadmat

    raw = loadmat(str(TRIPLE / "TriplePendulumDataForParameterEstimation.mat"))["Y_id"][0, 0]
    np.testing.assert_allclose(fit[0].q[:, 2], raw[2] - raw[1], atol=1e-15)
    np.testing.assert_allclose(fit[0].dq[:, 1], raw[4] - raw[3], atol=1e-15)
    # swings of about +-0.45, +-0.55 and +-1.2 rad about the hanging rest (the data README)
    assert all(abs(float(np.median(p.q[:, 0]))) < 0.3 for p in fit)


@pytest.mark.parametrize("convention", [Convention(second="absolute", zero="upright"),
                                        Convention(second="absolute", unit="deg", sign=(1, -1, 1, -1)),
                                        Convention(sign=(-1, 1, 1, 1))])
def test_conversion_of_four_angles_is_invertible(convention):
    rng = np.random.default_rng(4)
    q, dq, u = rng.normal(size=(5, 4)), rng.normal(size=(5, 4)), rng.normal(size=(5, 4))
    back = convert_back(*convert(q, dq, u, convention=convention), convention=convention)
    for a, b in zip((q, dq, u), back):
        np.testing.assert_allclose(b, a, rtol=0, atol=1e-12)
    # absolute from the upright: each joint angle the difference of consecutive rods' angles
    q, _, _ = convert([[math.pi + 0.1, math.pi + 0.3, math.pi - 0.2]], convention=Convention(second="absolute", zero="upright"))
    np.testing.assert_allclose(q, [[0.1, 0.2, -0.5]], atol=1e-15)


def test_mismatched_angle_columns_are_refused():
    t = np.linspace(0, 1, 50)
    q = np.column_stack([np.sin(t), np.cos(t), np.sin(2 * t)])
    with pytest.raises(ParameterError, match=r"speeds dq must have shape \(50, 3\) like the times and the 3 angles"):
        skewpend.Measurements.from_arrays([{"t": t, "q": q, "dq": q[:, :2]}], skip=("mean",))
    with pytest.raises(ParameterError, match="different numbers of angles"):
        skewpend.Measurements.from_arrays([{"t": t, "q": q, "name": "a"}, {"t": t, "q": q[:, :2], "name": "b"}],
                                          skip=("mean",))
    with pytest.raises(ParameterError, match="gives 2 signs for 3 angles"):
        skewpend.Measurements.from_arrays([{"t": t, "q": q}], convention=Convention(sign=(1, -1)), skip=("mean",))
    with pytest.raises(ParameterError, match=r"must have shape \(50, k\) like the times, k >= 2 angles"):
        skewpend.Measurements.from_arrays([{"t": t, "q": q[:, :1]}])


def test_the_double_pendulum_refuses_three_angles():
    fit = skewpend.Measurements.from_kaheman(TRIPLE, which="fit")
    for model in (skewpend.Parameters(a=1, b=1, m1=1, m2=1, alpha=0, g=9.81), Chain.from_lists(2)):
        with pytest.raises(ParameterError, match=r"hold 3 angles, the skewed double pendulum has 2 \(one angle a link\): "
                                                 "identify a chain of 3 links"):
            skewpend.identify(fit, model)


# -- the chain's shooting kernel and base parameters -----------------------------------------------------------
def _skewed_triple(friction: bool = False) -> Chain:
    return Chain.from_lists(3, axis=[(0, 0, 1), (0.3, 0.1, 1), (1, 0.2, 0.4)], mass=[0.3, 0.25, 0.1],
                            length=[0.2, 0.25, 0.24], damping=[1e-3, 2e-3, 3e-4], torque=[0.01, -0.02, 0.005],
                            coulomb=[2e-3, 0.0, 1e-3] if friction else 0.0,
                            com=[(0.01, 0.1, 0.0), (0.0, 0.12, 0.01), (0.002, 0.1, 0.0)])


@pytest.mark.parametrize("friction", [False, True])
def test_chain_sensitivities_equal_central_differences(friction):
    """``rhs_sens``'s d q''/d y and d q''/d p against central differences of its own q'' (step 1e-7: the
    truncation error O(h^2) is ~1e-9 of the entries here, the rounding error ~1e-16/1e-7)."""
    chain = _skewed_triple(friction)
    kernel = chain_kernel(chain, shooting=True)
    p = recursive.parameter_vector(chain)
    n, npar = 3, len(p)
    dp = ctypes.POINTER(ctypes.c_double)

    def sens(y, p):
        out = [np.zeros(n), np.zeros(n * 2 * n), np.zeros(n * npar)]
        y, p = np.ascontiguousarray(y, float), np.ascontiguousarray(p, float)
        kernel.lib.sp_rhs_sens(*(a.ctypes.data_as(dp) for a in (y, p, *out)))
        return out[0], out[1].reshape(n, 2 * n), out[2].reshape(n, npar)

    rng = np.random.default_rng(7)
    y = rng.normal(size=2 * n)
    acc, A, B = sens(y, p)
    rhs = np.zeros(2 * n + 1)
    kernel.lib.sp_rhs(np.append(y, 0.0).ctypes.data_as(dp), p.ctypes.data_as(dp), rhs.ctypes.data_as(dp))
    np.testing.assert_allclose(acc, rhs[n:2 * n], rtol=1e-14, atol=1e-14)
    h = 1e-7
    Ad = np.array([(sens(y + h * e, p)[0] - sens(y - h * e, p)[0]) / (2 * h) for e in np.eye(2 * n)]).T
    Bd = np.array([(sens(y, p + h * e)[0] - sens(y, p - h * e)[0]) / (2 * h) for e in np.eye(npar)]).T
    assert np.abs(A - Ad).max() <= 1e-7 * np.abs(A).max()
    assert np.abs(B - Bd).max() <= 1e-7 * np.abs(B).max()


def test_chain_regressor_is_the_inverse_dynamics():
    """``Y(q, q', a) pi = M a - f`` with ``f`` the recursive model's (torques included on the right):
    the regressor is the exact derivative of a function linear in pi, at any positive masses."""
    chain = _skewed_triple(friction=True)
    structure = recursive.structure_of_chain(chain)
    fn = recursive.regressor_function(structure)
    p, pi = recursive.parameter_vector(chain), recursive.standard_vector(chain)
    model = recursive.chain_functions(structure)["model"]
    rng = np.random.default_rng(3)
    for _ in range(5):
        y, a = rng.normal(size=6), rng.normal(size=3)
        Mp, f, Q = (np.array(x, dtype=float).ravel() for x in model(y, p))
        M = np.zeros((3, 3))
        M[np.tril_indices(3)] = Mp
        M = M + np.tril(M, -1).T
        tau = np.array([link.torque for link in chain.links])
        lhs = np.array(fn(y, a, p, pi), dtype=float) @ pi
        np.testing.assert_allclose(lhs, M @ a - f + tau, rtol=0, atol=1e-13 * np.abs(M @ a - f).max())
        np.testing.assert_allclose(np.array(fn(y, a, p, pi * 1.7), dtype=float), np.array(fn(y, a, p, pi), dtype=float),
                                   rtol=1e-12, atol=1e-15)


@pytest.mark.parametrize("alpha", [0.0, 0.4])
def test_chain_base_parameters_equal_the_double_pendulums_symbolic_ones(alpha):
    """The chain of two's base parameters, found numerically from the recursive model, are the
    symbolic derivation's (``symbolic.regressor.base_parameters``, from SymPy's Lagrange equations): the
    same names, the same combinations ``beta = T pi`` to 1e-9."""
    params = skewpend.Parameters(a=0.8, b=0.6, m1=1.1, m2=0.7, alpha=alpha, g=9.81, c1=0.05, c2=0.02,
                                 com1=(0.02, 0.35, 0.0), com2=(0.0, 0.3, 0.01),
                                 inertia1=((0.05, 0.0, 0.0), (0.0, 0.01, 0.0), (0.0, 0.0, 0.05)),
                                 inertia2=((0.03, 0.0, 0.0), (0.0, 0.004, 0.0), (0.0, 0.0, 0.03)))
    chain = Chain.from_parameters(params)
    numeric, symbolic = chain_terms(chain), model_terms(params)
    assert sorted(numeric.names) == sorted(symbolic.names)
    from skewpend.symbolic.regressor import PI_NAMES

    T = symbolic.B.matrix_at(params.a, alpha, params.g)
    order = [PI_NAMES.index(n) for n in numeric.pi_names]
    rows = [list(symbolic.names).index(n) for n in numeric.names]
    np.testing.assert_allclose(numeric.matrix, T[np.ix_(rows, order)], rtol=0, atol=1e-9)
    assert set(numeric.unidentifiable) == set(symbolic.unidentifiable)


# -- a simulated skewed triple pendulum -----------------------------------------------------------------------
def _simulated(chain, starts, seconds=1.5, dt=0.002):
    pieces = []
    for k, y0 in enumerate(starts):
        tr = skewpend.simulate(chain, y0, seconds, dt_out=dt, rtol=1e-12, atol=1e-12)
        y = np.asarray(tr.y)
        pieces.append({"t": tr.t, "q": y[:, :3], "dq": y[:, 3:6], "name": f"run {k}"})
    return skewpend.Measurements.from_arrays(pieces, skip=("mean",))


@pytest.fixture(scope="module")
def recovered():
    truth = Chain.from_lists(3, axis=[(0, 0, 1), (0.2, 0.0, 1.0), (0.0, 0.3, 1.0)], mass=[0.4, 0.3, 0.2],
                             length=[0.3, 0.3, 0.25], damping=[2e-3, 1e-3, 5e-4],
                             com=[(0.01, 0.14, 0.0), (0.0, 0.16, 0.005), (0.0, 0.12, 0.0)])
    rng = np.random.default_rng(11)
    starts = [np.concatenate([rng.uniform(-1.2, 1.2, 3), rng.normal(0, 1.0, 3)]) for _ in range(7)]
    data = _simulated(truth, starts)
    fit, held = data.split(2 / 7)
    start = truth
    for i, link in enumerate(truth.links, start=1):  # a wrong start: bodies and damping off by 10-50 %
        start = start.replace_link(i, mass=link.mass * 1.1, com=tuple(1.2 * x for x in link.com),
                                   damping=link.damping * 1.5)
    return truth, start, skewpend.identify(fit, start, validation=held, bootstrap=50)


def test_a_simulated_skewed_triple_pendulum_is_recovered(recovered):
    """Noise-free data of a skewed triple pendulum: the base parameters' ratios to the scale are the
    truth's to 1e-5 (the Savitzky-Golay start states are estimates; the fit frees them), each inside
    its interval, and the held-out pieces are predicted to 1e-4 rad (the start model's error: 1e-2)."""
    truth, start, result = recovered
    assert result.ok, result.message
    terms = chain_terms(truth)
    beta_true = terms.values(terms.standard(truth))
    k = result.names.index(result.reference)
    got, want = result.values / result.values[k], beta_true / beta_true[k]
    scale = np.abs(want).max()
    assert np.abs(got - want).max() <= 1e-5 * scale, (got - want) / scale
    assert np.max(result.heldout_rms) <= 1e-4 < np.min(result.heldout_rms0)
    assert isinstance(result.params, Chain) and result.params.n == 3


def test_a_chains_identification_reads_back_and_writes_a_run_file(recovered, tmp_path):
    _, start, result = recovered
    nc = result.to_netcdf(tmp_path / "fit.nc")
    back = skewpend.open_result(nc)
    assert back.params == result.params and back.params0 == start and back.names == result.names
    np.testing.assert_allclose(back.values, result.values, rtol=1e-15)
    toml = result.to_run_file(tmp_path / "fit.toml")
    from skewpend.cli.options import resolve

    run = resolve("identify", str(toml), defaults=False)
    assert run.links is not None and run.chain() == result.params  # the run file gives the chain's links


# -- the real triple pendulum -----------------------------------------------------------------------------------
@pytest.fixture(scope="module")
def triple_fit():
    fit = skewpend.Measurements.from_kaheman(TRIPLE, which="fit")
    val = skewpend.Measurements.from_kaheman(TRIPLE, which="validation")
    return fit, val, skewpend.identify(fit, kaheman_published_chain(TRIPLE), validation=val)


def test_the_authors_triple_model_predicts_as_published(triple_fit):
    """The authors' model, in skewpend's chain, predicts their held-out pieces from the first measured
    states with the angle RMS recomputed independently in the data's README: median about 0.0028 rad in
    their absolute angles (here 0.00278) -- a check of the conversion and of the chain's equations."""
    _, val, result = triple_fit
    authors = kaheman_published_chain(TRIPLE)
    absolute = []
    for piece in val:
        e = np.cumsum(predict_piece(authors, piece) - np.asarray(piece.q), axis=1)
        absolute.append(float(np.sqrt(np.mean(e**2))))
    assert abs(np.median(absolute) - 0.0028) <= 0.00005
    # the result's figures: in the absolute angles the data measured (the default), the joint angles beside
    assert result.settings["angles"] == "absolute" and abs(result.heldout_median0 - np.median(absolute)) <= 1e-9
    assert abs(result.stats["heldout_median0_joint"] - 0.00270) <= 0.00002


def test_the_triple_pendulum_fit_in_the_measured_angles_against_the_authors(triple_fit):
    """The default fit: the output error in the absolute angles the rig measured, each 1.54 s piece one
    shooting segment (as the held-out pieces are predicted, from their first measured states).  Held out
    (median angle RMS over the 4 pieces), measured: 0.00290 rad in the absolute angles (the authors' model
    0.00278: issue 53's goal, <= 0.00270, is not met -- see docs/guide/identification.md), 0.00265 in the joint
    angles (authors 0.00270).  Asserted: within 6 % of the authors' in the absolute angles and below theirs in
    the joint angles; physical bodies; intervals from the 22 pieces."""
    _, _, result = triple_fit
    assert result.ok, result.message
    assert result.settings["whole_pieces"] and result.settings["segments"] == 22
    assert result.heldout_median <= 1.06 * result.heldout_median0
    assert result.stats["heldout_median_joint"] < result.stats["heldout_median0_joint"]
    assert np.all(np.isfinite(result.intervals[[n != result.reference for n in result.names]]))
    assert len(result.names) == 12 and result.reference == "J1zz_b"
    assert result.settings["intervals"] == "clusters: 22 pieces"


def test_the_triple_pendulum_fit_in_joint_angles_predicts_them_better_than_the_authors(triple_fit):
    """Fitted in the joint angles over 0.5 s segments: the held-out median joint-angle RMS 0.00247 rad, 8 %
    below the authors' model's 0.00270 (asserted: below 0.0028 and 5 % below theirs)."""
    fit, val, _ = triple_fit
    result = skewpend.identify(fit, kaheman_published_chain(TRIPLE), validation=val, angles="relative", segment=0.5,
                               bootstrap=0)
    assert result.ok, result.message
    assert result.heldout_median <= 0.0028 and result.heldout_median < 0.95 * result.heldout_median0


def test_the_cli_identifies_the_triple_pendulum(tmp_path):
    out = tmp_path / "triple.toml"
    run = subprocess.run([sys.executable, "-m", "skewpend", "identify", "--format", "kaheman", str(TRIPLE), "--out",
                          str(out)], capture_output=True, text=True)
    assert run.returncode == 0, run.stderr
    assert "held out angle RMS: median over pieces" in run.stdout and "[[links]]" in out.read_text()
    for extra, words in ((["--out", str(tmp_path / "x.yml")], "--out FILE.yml: a DFKI lab model file holds a double"),
                         (["--angles", "sideways"], "--angles must be relative or absolute")):
        bad = subprocess.run([sys.executable, "-m", "skewpend", "identify", "--format", "kaheman", str(TRIPLE), *extra],
                             capture_output=True, text=True)
        assert bad.returncode == 2 and words in bad.stderr and "Traceback" not in bad.stderr
        assert [line for line in bad.stderr.splitlines() if "error" in line] == [bad.stderr.strip().splitlines()[-1]]
    assert not (tmp_path / "x.yml").exists()
    page = tmp_path / "triple.html"
    ran = subprocess.run([sys.executable, "-m", "skewpend", "identify", "--format", "kaheman", str(TRIPLE), "--report",
                          str(page)], capture_output=True, text=True)
    assert ran.returncode == 0, ran.stderr
    text = page.read_text()
    assert "Identification of a measured chain of 3 links" in text and "skewpend.Chain</code> of 3 links" in text


def test_a_chains_identification_is_drawn(triple_fit, tmp_path):
    """The identification figure takes a chain's angles: rods 1 .. 3 measured and predicted (the data's absolute
    angles, which the fit measured), the held-out error."""
    from skewpend.views.figures.identification import plot_identification

    fit, val, result = triple_fit
    fig = plot_identification(result, fit, val, tmp_path / "triple.png")
    assert (tmp_path / "triple.png").stat().st_size > 50_000

    def labels(figure):  # every legend's entries, the subfigures' too
        out = [t.get_text() for leg in figure.legends for t in leg.get_texts()]
        return out + [x for sub in figure.subfigs for x in labels(sub)]

    assert {"rod 1 measured", "rod 3 fitted model"} <= set(labels(fig))


def test_a_chains_joint_terms_that_the_data_want_negative_are_named():
    """Base parameters whose joint damping comes out negative: no model, one line naming the term."""
    from skewpend.analysis.identify import _realise_chain  # noqa: PLC2701 - the realisation's message

    chain = Chain.from_lists(3, damping=[0.01, 0.01, 0.01])
    terms = chain_terms(chain)
    beta = terms.values(terms.standard(chain))
    beta[terms.names.index("c2")] = -0.001
    fitted, why = _realise_chain(chain, terms, beta, terms.standard(chain))
    assert fitted is None and why.startswith("c2 = -0.001 < 0: the data want a negative viscous damping in joint 2")


def test_a_driven_chain_is_identified_in_absolute_terms():
    """Measured torques fix the scale a free swing leaves open: pieces of a triple pendulum driven by constant
    joint torques (skewpend's own runs read back by Measurements.from_trajectory) give every base parameter
    itself, the truth's to 1e-3 of the largest (the torques enter the shooting kernel through p's torques; the
    fitted model is RK4's at 4 ms, whose discretisation moves the weakly determined products of inertia of the
    skewed link by ~1e-6 absolute), and a physical chain: the thin rods' bodies are on the edge and the estimate
    lands just outside, so the model is the output-error fit over physical bodies (measured 2 iterations, its
    values 1.7e-5 of the largest from the truth's), never the nearest body to the estimate."""
    truth = Chain.from_lists(3, axis=[(0, 0, 1), (0.3, 0.0, 1.0), (0.0, 0.0, 1.0)], mass=[0.5, 0.4, 0.3],
                             length=[0.3, 0.3, 0.25], damping=[3e-3, 2e-3, 1e-3],
                             com=[(0.0, 0.13, 0.01), (0.01, 0.16, 0.0), (0.0, 0.12, 0.0)])
    rng = np.random.default_rng(4)
    pieces = []
    for k in range(6):
        torques = rng.uniform(-0.3, 0.3, 3)
        driven = truth
        for i, u in enumerate(torques, start=1):
            driven = driven.replace_link(i, torque=float(u))
        y0 = np.concatenate([rng.uniform(-0.8, 0.8, 3), rng.normal(0, 0.5, 3)])
        tr = skewpend.simulate(driven, y0, 1.5, dt_out=0.002, rtol=1e-12, atol=1e-12)
        piece = skewpend.Measurements.from_trajectory(tr, skip=("mean",))[0]
        pieces.append({"t": piece.t, "q": piece.q, "dq": piece.dq, "u": piece.u, "name": f"run {k}"})
    data = skewpend.Measurements.from_arrays(pieces, skip=("mean",))
    assert data.has_torques
    start = truth
    for i, link in enumerate(truth.links, start=1):
        start = start.replace_link(i, mass=link.mass * 1.2, damping=link.damping * 2.0)
    result = skewpend.identify(data, start, bootstrap=0)
    assert result.ok, result.message
    assert result.reference is None and not result.ratios  # nothing held for the scale
    terms = chain_terms(truth)
    want = terms.values(terms.standard(truth))
    assert np.abs(result.values - want).max() <= 1e-3 * np.abs(want).max()
    assert isinstance(result.params, Chain)
    assert "fit over the physical bodies" in result.message and "physical_fit" in result.settings, result.message
    assert np.allclose(terms.values(terms.standard(result.params)), result.values, rtol=0, atol=1e-9 * np.abs(want).max())


def test_absolute_angles_measure_the_held_out_error_of_every_method():
    """``angles="absolute"`` measures the held-out RMS in the rods' absolute angles for the linear estimate too
    (it is not silently ignored): the median equals the one recomputed here from the fitted model's predictions."""
    data = skewpend.example_data("kaheman2023")
    fit = skewpend.Measurements.from_kaheman(data, which="fit").select(range(6))
    val = skewpend.Measurements.from_kaheman(data, which="validation")
    from skewpend.analysis.measurements import kaheman_published_parameters

    result = skewpend.identify(fit, kaheman_published_parameters(data), validation=val, method="linear",
                               angles="absolute", bootstrap=0)
    assert result.ok, result.message
    mine = [float(np.sqrt(np.mean(np.cumsum(predict_piece(result.params, p) - p.q, axis=1) ** 2))) for p in val]
    assert result.heldout_median == pytest.approx(float(np.median(mine)), rel=1e-9)
