"""Normal modes, robustness: damped modes labelled by shape (overdamped included), nothing
non-finite, one rule for units in a range, options that take effect or are refused.

The reference values are computed here independently of the code under test: the
one-degree-of-freedom damping ratio c/(2 sqrt(k m)) with k, m of the rods worked out by hand,
4x4 state matrices built and solved here, eigenvalue continuation in the damping, and
high-precision roots of the characteristic quartic (mpmath).
"""

from __future__ import annotations

import itertools
import json
import math
import re

import mpmath as mp
import numpy as np
import pytest
import sympy as sp

from skewpend import ParameterError, Parameters
from skewpend.cli import main
from skewpend.analysis.modes import normal_modes, parse_sweep, sweep
from skewpend.parsing import UsageError, parse_range

from skewpend.config import reference_parameters  # noqa: E402
BENCH = reference_parameters()  # the reference case: a = 1, b = 0.8, m1 = 1, m2 = 0.7, alpha = 0.6, g = 9.81
L, MASS, G = 0.8, 1.3, 9.81
#: Equal uniform thin rods (length L, mass MASS) at alpha = 90 deg: the hinges decouple.
RIGHT = Parameters(a=L, b=L, m1=MASS, m2=MASS, alpha=math.pi / 2, g=G)
# By hand. phi alone (psi = 0): the two rods swing as one rigid rod of length 2L about the
# pivot, inertia m L^2/3 + (m L^2/12 + m (3L/2)^2) = 8/3 m L^2, gravity stiffness
# m g L/2 + m g 3L/2 = 2 m g L.  psi alone (hinge 2 horizontal at alpha = 90 deg): rod 2
# swings about its upper end, m L^2/3 and m g L/2.  (w^2 L/g = 3/4 and 3/2, as in test_modes.)
M_PHI, K_PHI = 8 / 3 * MASS * L**2, 2 * MASS * G * L
M_PSI, K_PSI = MASS * L**2 / 3, MASS * G * L / 2


def zeta_1dof(c, k, m):
    return c / (2 * math.sqrt(k * m))


def state_matrix(M, C, K):
    Minv = np.linalg.inv(M)
    return np.block([[np.zeros((2, 2)), np.eye(2)], [-Minv @ K, -Minv @ C]])


def zeta_of_pair(l1, l2):
    return float(-(l1 + l2).real / (2 * np.sqrt((l1 * l2).real)))


def same_set(a, b, rtol):
    a, b = np.asarray(a), np.asarray(b)
    return min(max(abs(a[i] - b[p[i]]) / abs(b[p[i]]) for i in range(len(a))) for p in itertools.permutations(range(len(b)))) <= rtol


# -- 1. damped modes: matched by shape, overdamped ratios -------------------------------------------
def test_right_angle_matrices_are_the_hand_values():
    m = normal_modes(RIGHT)
    np.testing.assert_allclose(m.M, np.diag([M_PHI, M_PSI]), rtol=1e-12, atol=1e-14)
    np.testing.assert_allclose(m.K, np.diag([K_PHI, K_PSI]), rtol=1e-12, atol=1e-12)


@pytest.mark.parametrize("c1, c2", [(30.0, 0.0), (0.0, 5.0), (10.0, 10.0), (1e3, 1e3), (1e6, 0.3)])
def test_decoupled_damping_ratios_equal_the_one_dof_values(c1, c2):
    """Hinge damping only: at alpha = 90 deg each mode is one hinge, a 1-DOF oscillator, so
    zeta = c/(2 sqrt(k m)) exactly, overdamped (> 1) or not; the lower mode (phi) is the one
    with damping c1 whichever of the two modes is overdamped."""
    m = normal_modes(RIGHT.replace(c1=c1, c2=c2))
    expected = np.array([zeta_1dof(c1, K_PHI, M_PHI), zeta_1dof(c2, K_PSI, M_PSI)])
    np.testing.assert_allclose(m.damping_ratios, expected, rtol=1e-12, atol=1e-14)
    assert list(m.overdamped) == [bool(z > 1) for z in expected]
    for k in range(2):
        if expected[k] > 1:
            assert m.damping_ratios[k] > 1 and m.damped_frequencies[k] == 0
            assert np.all(m.eigenvalue_pairs[k].imag == 0) and np.all(m.eigenvalue_pairs[k].real < 0)
    # independently: the 4x4 state matrix of the hand matrices; an eigenvector moving phi
    # belongs to mode 1, one moving psi to mode 2
    # (its eigenvalues are accurate to ~ eps |A| / |lambda|: 1e-9 here, 1e-5 for c = 1e6)
    A = state_matrix(np.diag([M_PHI, M_PSI]), np.diag([c1, c2]), np.diag([K_PHI, K_PSI]))
    ev, X = np.linalg.eig(A)
    rtol = 1e-9 if max(c1, c2) <= 1e3 else 1e-5
    for k in range(2):
        mine = ev[np.abs(X[k]) > np.abs(X[1 - k])]
        assert mine.size == 2
        assert zeta_of_pair(*mine) == pytest.approx(expected[k], rel=rtol, abs=1e-12)
        assert same_set(m.eigenvalue_pairs[k], mine, rtol)


def test_reported_case_mode_two_is_overdamped_with_the_state_space_ratio():
    """``modes --c1 2 --c2 2``: the overdamped mode is mode 2 (higher undamped frequency),
    zeta = (|l1| + |l2|)/(2 sqrt(l1 l2)) ~ 2.41 from the two real eigenvalues of the 4x4
    state matrix (computed here), mode 1 underdamped with -Re/|lambda|."""
    m = normal_modes(BENCH.replace(c1=2.0, c2=2.0))
    ev = np.linalg.eigvals(state_matrix(m.M, np.diag([2.0, 2.0]), m.K))
    real = np.sort(ev[ev.imag == 0].real)
    cplx = ev[ev.imag > 0]
    assert real.size == 2 and cplx.size == 1
    zeta_over = (abs(real[0]) + abs(real[1])) / (2 * math.sqrt(real[0] * real[1]))
    assert zeta_over == pytest.approx(2.408, abs=1e-3)
    assert list(m.overdamped) == [False, True]
    assert m.damping_ratios[1] == pytest.approx(zeta_over, rel=1e-12)
    assert m.damping_ratios[0] == pytest.approx(-cplx[0].real / abs(cplx[0]), rel=1e-12)
    assert m.damped_frequencies[0] == pytest.approx(cplx[0].imag, rel=1e-12)


def _continuation(c_values):
    """Label the four state-space eigenvalues of BENCH with c1 = c2 = c by continuity from
    c -> 0, where mode k has the pair +-i w_k (w_k the undamped frequencies)."""
    M, K = normal_modes(BENCH).M, normal_modes(BENCH).K
    w = normal_modes(BENCH).frequencies
    prev = labels = None
    tracked = []
    for c in c_values:
        ev = np.linalg.eigvals(state_matrix(M, c * np.eye(2), K))
        if prev is None:
            labels = np.array([int(np.argmin(np.abs(abs(z.imag) - w))) for z in ev])
            assert sorted(labels) == [0, 0, 1, 1]
        else:
            def dist(a, b):
                r = a / b
                return abs(np.log(abs(r))) + abs(np.angle(r))

            p = min(itertools.permutations(range(4)), key=lambda p: sum(dist(ev[p[i]], prev[i]) for i in range(4)))
            ev = ev[list(p)]
        tracked.append([ev[labels == k] for k in range(2)])
        prev = ev
    return tracked


def test_labels_follow_the_shapes_continuously_as_damping_grows():
    cs = np.geomspace(1e-3, 1e6, 500)
    tracked = _continuation(cs)
    zetas = []
    for c, ref in zip(cs, tracked):
        m = normal_modes(BENCH.replace(c1=c, c2=c))
        for k in range(2):
            # the 4x4 eigenvalues lose relative accuracy ~ eps |A| / |lambda| for the slow creep
            assert same_set(m.eigenvalue_pairs[k], ref[k], 1e-6 if c <= 1e4 else 1e-3), (c, k)
        zetas.append(m.damping_ratios)
    zetas = np.array(zetas)
    # each mode's ratio grows with the damping, continuously: d log zeta / d log c stays
    # within 5 % of 1 over the nine decades (a label swap would jump by the factor ~12
    # between the two modes' ratios, a slope of ~60 over one step)
    assert np.all(np.diff(zetas, axis=0) > 0)
    slope = np.log(zetas[1:] / zetas[:-1]) / np.log(cs[1] / cs[0])
    assert np.all(np.abs(slope - 1) < 0.05)
    # both ends: the first-order modal estimate at light damping, overdamped at heavy damping
    m0 = normal_modes(BENCH.replace(c1=cs[0], c2=cs[0]))
    est = cs[0] * np.sum(m0.shapes**2, axis=0) / (2 * m0.frequencies)
    np.testing.assert_allclose(zetas[0], est, rtol=1e-3)
    assert np.all(zetas[-1] > 1e4)


def _quartic_roots(M, C, K):
    """Roots of det(l^2 M + l C + K) with 50 digits (the matrices' floats taken exactly)."""
    lam = sp.Symbol("lam")
    Q = sp.Matrix(2, 2, lambda i, j: sp.Rational(M[i, j]) * lam**2 + sp.Rational(C[i, j]) * lam + sp.Rational(K[i, j]))
    coeffs = sp.Poly(sp.expand(Q.det()), lam).all_coeffs()
    mp.mp.dps = 50
    return np.array([complex(z) for z in mp.polyroots([mp.mpf(sp.Rational(c).p) / sp.Rational(c).q for c in coeffs], maxsteps=500, extraprec=2000)])


@pytest.mark.parametrize("c1, c2", [(1e6, 1e6), (1e10, 1e10), (0.04, 1.2e13), (1e12, 1e-3)])
def test_extreme_damping_keeps_full_relative_accuracy(c1, c2):
    """``--c1 1e6 --c2 1e6`` printed zeta = 1 for both modes; now the eigenvalues agree with
    50-digit roots of the characteristic quartic to 1e-12 and the ratios follow from them."""
    m = normal_modes(BENCH.replace(c1=c1, c2=c2))
    roots = _quartic_roots(m.M, m.C, m.K)
    assert same_set(m.eigenvalue_pairs.ravel(), roots, 1e-12)
    for k in range(2):
        assert m.damping_ratios[k] == pytest.approx(zeta_of_pair(*m.eigenvalue_pairs[k]), rel=1e-14)
    if c1 == c2:
        assert np.all(m.damping_ratios > 1) and np.all(m.overdamped)


# -- 2. nothing non-finite ------------------------------------------------------------------------------
def test_overflow_is_refused_not_nan():
    # values that would overflow are refused when the parameters are built (|x| <= 1e100)
    with pytest.raises(ParameterError, match=r"g must be at most 1e\+100"):
        normal_modes(BENCH.replace(g=1e308))
    with pytest.raises(ParameterError, match=r"2 of 3 values failed.*g = 5e\+307: g must be at most 1e\+100"):
        sweep(BENCH, "g", parse_sweep("g=1:1e308:3")[1])
    with pytest.raises(ParameterError, match=r"underflow"):
        normal_modes(BENCH.replace(g=1e-320))
    # a failing point names its value, the others are not reported
    with pytest.raises(ParameterError, match=r"1 of 3 values failed.*g = 0: .*not a stable equilibrium"):
        sweep(BENCH, "g", [0.0, 5.0, 10.0])


def test_every_result_is_finite_for_large_and_small_values():
    for p in (BENCH.replace(g=1e100), BENCH.replace(a=1e-100, b=1e-100), BENCH.replace(c1=1e100, c2=1e-100)):
        m = normal_modes(p)
        for x in (m.frequencies, m.periods, m.shapes, m.eigenvalues, m.eigenvalue_pairs, m.damped_frequencies, m.damping_ratios):
            assert np.all(np.isfinite(x))
    # beyond that, values are refused when the parameters are built
    with pytest.raises(ParameterError, match="at most 1e\\+100"):
        BENCH.replace(c1=1e200)


# -- 3. one rule for units in a range --------------------------------------------------------------------
def test_range_unit_rule():
    degrees = [parse_range(s, "--x", angle=True) for s in ("0:180deg:5", "0deg:180:5", "0deg:180deg:5", "0°:180°:5", " 0 DEG : 180 : 5 ")]
    for d in degrees:
        assert np.array_equal(d, degrees[0])
    np.testing.assert_allclose(degrees[0], np.linspace(0, np.pi, 5), rtol=1e-15)
    # the same factor as --alpha 45deg, bit for bit
    assert degrees[0][1] == Parameters(alpha=np.pi / 4).alpha == 45 * (math.pi / 180)
    radians = [parse_range(s, "--x", angle=True) for s in ("0:3:4", "0rad:3:4", "0:3rad:4", "0rad:3rad:4")]
    for r in radians:
        assert np.array_equal(r, np.array([0.0, 1.0, 2.0, 3.0]))
    assert np.array_equal(parse_sweep("alpha=0deg:180:5")[1], degrees[0])
    for bad in ("0deg:1rad:5", "0rad:90deg:3", "0:180deg:1", "0:1:2.5", "0:1", "x:1:3", "-1e308:1e308:3", "0:inf:3"):
        with pytest.raises(UsageError):
            parse_range(bad, "--x", angle=True)
    with pytest.raises(UsageError, match="plain numbers"):
        parse_range("0.5:2deg:3", "--sweep a", angle=False)
    np.testing.assert_array_equal(parse_range("0.5:2:4", "--x", angle=False), [0.5, 1.0, 1.5, 2.0])


def run_cli(args, capsys):
    from helpers import without_stages

    with pytest.raises(SystemExit) as exc:
        main([str(a) for a in args])
    out = capsys.readouterr()
    return exc.value.code, out.out, without_stages(out.err)[0]  # the stage lines (issue 36) apart


def test_sweep_outputs_agree_on_alpha_units(tmp_path, capsys):
    csv, js = tmp_path / "s.csv", tmp_path / "s.json"
    code, text, err = run_cli(["modes", "--sweep", "alpha=0deg:180:5", "--out", csv], capsys)
    assert code == 0, err
    assert "0 rad (0 deg) .. 3.14159 rad (180 deg)" in text
    header = csv.read_text().splitlines()[0].split(",")
    rows = np.loadtxt(csv, delimiter=",", skiprows=1)
    assert header[0] == "alpha" and header[-1] == "alpha_deg"
    np.testing.assert_allclose(rows[:, 0], np.linspace(0, np.pi, 5), rtol=1e-15)
    np.testing.assert_allclose(rows[:, -1], np.linspace(0, 180, 5), rtol=1e-13, atol=1e-13)
    code, text, err = run_cli(["modes", "--sweep", "alpha=0:180deg:5", "--out", js, "--format", "json"], capsys)
    assert code == 0, err
    data = json.loads(js.read_text())
    assert json.loads(text) == data  # --format json prints the table too
    assert data["units"]["alpha"] == "rad" and data["units"]["alpha_deg"] == "deg"
    np.testing.assert_allclose(np.array(data["rows"]), rows, rtol=1e-15)
    for r in data["resonances"]:
        assert r["value_deg"] == pytest.approx(math.degrees(r["value"]))
    # the plot's axis: degrees, labelled so
    from skewpend.views.figures import plot_sweep

    sw = sweep(BENCH, "alpha", parse_sweep("alpha=0:180deg:5")[1])
    fig = plot_sweep(sw)
    ax = fig.axes[0]
    np.testing.assert_allclose(ax.lines[0].get_xdata(), np.linspace(0, 180, 5), atol=1e-12)
    assert "deg" in fig.axes[1].get_xlabel()


# -- 4./5. options take effect or are refused -----------------------------------------------------------
REFUSED = [
    (["--format", "latex", "--sweep", "alpha=0:1:3"], "--format latex"),
    (["--format", "latex", "--plot", "{png}"], "--plot"),
    (["--format", "latex", "--out", "{csv}"], "--out"),
    (["--format", "latex", "--check-nonlinear", "10deg"], "--check-nonlinear"),
    (["--format", "latex", "--tolerance", "0.1"], "--tolerance"),
    (["--format", "latex", "--c1", "0.1"], "undamped characteristic equation"),
    (["--sweep", "alpha=0:1:3", "--check-nonlinear", "10deg", "--out", "{csv}"], "not a sweep"),
    (["--tolerance", "-1"], "without --sweep"),
    (["--tolerance", "0.02"], "without --sweep"),
    (["--sweep", "alpha=0:1:3", "--tolerance", "-1", "--out", "{csv}"], "positive number"),
    (["--sweep", "alpha=0:1:3", "--tolerance", "0", "--plot", "{png}"], "positive number"),
    (["--sweep", "alpha=0deg:1rad:3", "--out", "{csv}"], "write one unit"),
    (["--sweep", "a=0.5m:1:3"], "START must be a number"),
    (["--alpha", "1", "--sweep", "alpha=0:1:3", "--out", "{csv}"], "leave out --alpha"),
    (["--b", "1", "--sweep", "b/a=0.5:2:3"], "leave out --b"),
    (["--axis2", "1,0,0", "--sweep", "alpha=0:1:3"], "alpha has no effect"),
    (["--g", "1e308"], "g must be at most 1e+100"),
    (["--g", "1e308", "--format", "json"], "g must be at most 1e+100"),
    (["--sweep", "g=1:1e308:3", "--out", "{csv}", "--plot", "{png}"], "g = 5e+307: g must be at most 1e+100"),
    (["--c1", "0.1", "--check-nonlinear", "10deg"], "without losses (the energy T + Pi - tau . q decays otherwise; constant torques are allowed), but c1 = 0.1; set c1 to 0"),
    (["--check-nonlinear", "0"], "between 0 and 180 deg"),
    (["--check-nonlinear", "179deg"], "not an oscillation about the hanging position"),
]


@pytest.mark.parametrize("args, message", REFUSED, ids=[" ".join(a) for a, _ in REFUSED])
def test_refused_with_one_line(args, message, tmp_path, capsys):
    csv, png = tmp_path / "t.csv", tmp_path / "p.png"
    args = [a.format(csv=csv, png=png) for a in args]
    code, out, err = run_cli(["modes", *args], capsys)
    # a cold cache's one-line build notes come before the refusal (the nonlinear check simulates first)
    lines = [line for line in err.strip().splitlines() if not line.startswith("skewpend: compiling")]
    assert code == 2 and len(lines) == 1 and lines[0].startswith("skewpend: error:"), err
    assert message in lines[0] and "Traceback" not in err and "duration" not in err
    assert out == ""
    assert not csv.exists() and not png.exists()
    assert not list(tmp_path.iterdir())


def test_latex_honours_config(tmp_path, capsys):
    cfg = tmp_path / "run.toml"
    cfg.write_text('[parameters]\na = 1.0\nb = 1.0\nm1 = 1\nm2 = 1\nalpha = "0deg"\ng = 9.81\n')
    code, out, err = run_cli(["modes", "--format", "latex", "--config", cfg], capsys)
    assert code == 0, err
    assert "\\alpha" not in out and "m_1" not in out and "\\omega_1^2" in out
    # all parameters from the config: a numeric quartic A w^4 - B w^2 + D whose roots are the
    # compound double pendulum's w^2 = 9.81 (3 -/+ 6/sqrt 7)
    A, B, D = map(int, re.search(r"(\d+) \\omega\^\{4\} - (\d+) \\omega\^\{2\} \+ (\d+)", out).groups())
    np.testing.assert_allclose(np.sort(np.roots([A, -B, D])), 9.81 * (3 + np.array([-6, 6]) / math.sqrt(7)), rtol=1e-12)
    # an option overrides the config; parameters given in neither stay symbolic
    cfg.write_text('[parameters]\nalpha = "90deg"\n')
    code, out, _ = run_cli(["modes", "--format", "latex", "--config", cfg], capsys)
    assert code == 0 and "\\alpha" not in out and "m_1" in out
    # damping from the config is refused (the equation is undamped), unless set to 0
    cfg.write_text('[parameters]\nalpha = "90deg"\nc1 = 0.5\n')
    code, _, err = run_cli(["modes", "--format", "latex", "--config", cfg], capsys)
    assert code == 2 and "[parameters] c1" in err and len(err.strip().splitlines()) == 1
    code, out, _ = run_cli(["modes", "--format", "latex", "--config", cfg, "--c1", "0"], capsys)
    assert code == 0 and "\\omega_2^2" in out


def test_damped_json_is_finite_and_reports_both_eigenvalues(capsys):
    code, out, err = run_cli(["modes", "--c1", "2", "--c2", "2", "--format", "json"], capsys)
    assert code == 0, err

    def refuse(x):
        raise AssertionError(f"non-finite {x} in the JSON")

    data = json.loads(out, parse_constant=refuse)
    assert data["overdamped"] == [False, True]
    (l1, l2) = [complex(*z) for z in data["eigenvalue_pairs"][1]]
    assert l1.imag == l2.imag == 0
    assert data["damping_ratios"][1] == pytest.approx((abs(l1) + abs(l2)) / (2 * math.sqrt((l1 * l2).real)), rel=1e-12)
