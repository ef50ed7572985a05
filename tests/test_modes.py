"""Normal modes: published values, closed form, damping, sweeps, linear vs nonlinear."""

from __future__ import annotations

import json

import numpy as np
import pytest
import sympy as sp

from skewpend import EquilibriumError, ParameterError, Parameters, simulate
from skewpend.symbolic.derivation import SYMBOLS as S
from skewpend.analysis.modes import characteristic_equation, check_nonlinear, normal_modes, parse_sweep, sweep

EQUAL = dict(a=1.0, b=1.0, m1=1.0, m2=1.0, g=9.81)
from skewpend.config import reference_parameters  # noqa: E402
from helpers import completed  # noqa: E402
BENCH = reference_parameters()  # the reference case: a = 1, b = 0.8, m1 = 1, m2 = 0.7, alpha = 0.6, g = 9.81


def lam(modes, L=1.0, g=9.81):
    return modes.frequencies**2 * L / g


def test_planar_compound_double_pendulum_known_values():
    """Equal uniform rods at alpha = 0: lambda = w^2 L/g = 3 -/+ 6/sqrt(7) (the compound double
    pendulum; e.g. Goldstein-type textbook result for two identical uniform rods)."""
    m = normal_modes(Parameters(alpha=0.0, **EQUAL))
    np.testing.assert_allclose(lam(m), [3 - 6 / np.sqrt(7), 3 + 6 / np.sqrt(7)], rtol=1e-12)
    # lengths and masses scale out: L = 0.37 m, m = 2.5 kg
    m2 = normal_modes(Parameters(a=0.37, b=0.37, m1=2.5, m2=2.5, alpha=0.0, g=9.81))
    np.testing.assert_allclose(lam(m2, L=0.37), [3 - 6 / np.sqrt(7), 3 + 6 / np.sqrt(7)], rtol=1e-12)


def test_right_angle_skew_decouples():
    m = normal_modes(Parameters(alpha=np.pi / 2, **EQUAL))
    np.testing.assert_allclose(lam(m), [0.75, 1.5], rtol=1e-12)
    # mode 1 moves phi only, mode 2 psi only
    assert m.shapes[1, 0] == 0 and m.shapes[0, 1] == 0
    assert m.ratios[0] == 0 and np.isinf(m.ratios[1])


def test_shapes_are_mass_normalised_and_stiffness_orthogonal():
    m = normal_modes(BENCH)
    V = m.shapes
    np.testing.assert_allclose(V.T @ m.M @ V, np.eye(2), atol=1e-12)
    np.testing.assert_allclose(V.T @ m.K @ V, np.diag(m.frequencies**2), atol=1e-10)
    assert m.frequencies[0] < m.frequencies[1]
    np.testing.assert_allclose(m.periods, 2 * np.pi / m.frequencies)
    assert m.beat_period == pytest.approx(2 * np.pi / (m.frequencies[1] - m.frequencies[0]))


def test_closed_form_roots_reproduce_known_values_symbolically():
    eq, roots = characteristic_equation()
    L = sp.Symbol("L", positive=True)
    for alpha, expected in ((0, (3 - 6 / sp.sqrt(7), 3 + 6 / sp.sqrt(7))), (sp.pi / 2, (sp.Rational(3, 4), sp.Rational(3, 2)))):
        sub = {S["a"]: L, S["b"]: L, S["m2"]: S["m1"], S["alpha"]: alpha}
        for r, e in zip(roots, expected):
            assert sp.simplify(r.subs(sub) * L / S["g"] - e) == 0
    # and agree numerically with the eigen-solver at the benchmark parameters
    vals = {S["a"]: 1.0, S["b"]: 0.8, S["m1"]: 1.0, S["m2"]: 0.7, S["alpha"]: 0.6, S["g"]: 9.81}
    num = np.sqrt([float(r.subs(vals)) for r in roots])
    np.testing.assert_allclose(num, normal_modes(BENCH).frequencies, rtol=1e-12)
    w = sp.Symbol("omega", positive=True)
    assert all(abs(float(eq.lhs.subs(vals).subs(w, x))) < 1e-9 for x in num)


def test_linear_response_matches_the_linearised_simulation_at_small_amplitude():
    m = normal_modes(BENCH)
    q0, dq0 = np.array([1e-4, -2e-4]), np.array([3e-4, 0.0])
    t = np.linspace(0, 10, 101)
    lin = m.linear_response(q0, dq0, t)
    tr = simulate(BENCH, (*q0, *dq0), 10.0, dt_out=0.1, rtol=1e-12, atol=1e-14)
    # nonlinear corrections are O(amplitude^3) ~ 1e-11 relative to 1e-4 amplitudes
    np.testing.assert_allclose(tr.y, lin, atol=1e-9)
    d = m.decompose(q0, dq0)
    assert d["amplitude"].shape == (2,) and np.all(d["amplitude"] > 0)


def test_damped_modes():
    p = BENCH.replace(c1=0.1, c2=0.05)
    m = normal_modes(p)
    assert np.all(m.eigenvalues.real < 0) and np.all(m.damping_ratios > 0)
    assert np.all(m.damped_frequencies < m.frequencies)
    # light damping: damping ratios ~ first-order modal estimate v^T C v / (2 w)
    est = np.einsum("ik,ij,jk->k", m.shapes, m.C, m.shapes) / (2 * m.frequencies)
    np.testing.assert_allclose(m.damping_ratios, est, rtol=0.05)
    # the free decay of the simulation matches the damped eigenvalue of mode 1
    v = m.shapes[:, 0] * 1e-3
    T = 2 * np.pi / m.damped_frequencies[0]
    tr = simulate(p, (v[0], v[1], 0, 0), 20 * T, dt_out=T / 200, rtol=1e-12, atol=1e-14)
    eta = m.modal_coordinates(tr.y[:, :2])[:, 0]
    peaks = [np.max(np.abs(eta[i * 200 : (i + 1) * 200])) for i in (2, 17)]
    rate = np.log(peaks[0] / peaks[1]) / (15 * T)
    assert rate == pytest.approx(-m.eigenvalues[0].real, rel=0.05)


def test_not_an_equilibrium_or_unstable():
    with pytest.raises(EquilibriumError, match="torques"):
        normal_modes(BENCH.replace(tau1=0.1))
    with pytest.raises(EquilibriumError, match="stable"):
        normal_modes(BENCH.replace(g=0.0))


def test_sweep_over_alpha_and_resonances():
    values = np.radians(np.linspace(0, 180, 181))
    sw = sweep(BENCH, "alpha", values)
    assert sw.frequencies.shape == (181, 2)
    # symmetric in alpha -> pi - alpha (mirror i -> -i)
    np.testing.assert_allclose(sw.frequencies, sw.frequencies[::-1], rtol=1e-10)
    # the 2:1 resonance crossings are real: at the interpolated alpha the ratio is 2
    crossings = [r for r in sw.resonances if r.order == 2 and r.crossed]
    assert len(crossings) == 2
    m = normal_modes(BENCH.replace(alpha=crossings[0].value))
    assert m.frequencies[1] / m.frequencies[0] == pytest.approx(2.0, abs=2e-4)
    cols, rows = sw.columns()
    assert cols[:3] == ["alpha", "omega1", "omega2"] and rows.shape == (181, 11) and cols[-1] == "alpha_deg"


def test_sweep_ratio_and_parse():
    name, v = parse_sweep("alpha=0:180deg:5")
    assert name == "alpha" and v[-1] == pytest.approx(np.pi)
    sw = sweep(BENCH, "b/a", np.linspace(0.5, 2, 4))
    assert sw.frequencies.shape == (4, 2)
    for bad in ("alpha", "beta=0:1:3", "alpha=0:1", "a=0:1:x", "a=0:1:1"):
        with pytest.raises(ParameterError):
            parse_sweep(bad)


def test_nonlinear_frequencies_converge_to_linear():
    """Measured (zero crossings of the modal coordinate) minus linear shrinks like amplitude^2."""
    shifts = [np.abs(check_nonlinear(BENCH, A).relative_shift) for A in (0.2, 0.1, 0.05, 0.01)]
    shifts = np.array(shifts)
    assert np.all(np.diff(shifts, axis=0) < 0)
    # amplitude halves -> shift quarters (within 15 %)
    np.testing.assert_allclose(shifts[0] / shifts[1], 4.0, rtol=0.15)
    assert np.all(shifts[-1] < 5e-5)


def run(*args, check=True):
    return completed(args, check=check)


def test_cli_json_contract():
    data = json.loads(run("modes", "--format", "json", "--a", "1", "--b", "1", "--m1", "1", "--m2", "1", "--alpha", "0").stdout)
    np.testing.assert_allclose(np.array(data["frequencies"]) ** 2 / 9.81, [3 - 6 / np.sqrt(7), 3 + 6 / np.sqrt(7)], rtol=1e-12)
    assert len(data["periods"]) == 2 and np.shape(data["mode_shapes"]) == (2, 2)


def test_cli_sweep_files(tmp_path):
    csv, png = tmp_path / "sweep.csv", tmp_path / "modes.png"
    out = run("modes", "--sweep", "alpha=0:180deg:37", "--out", csv, "--plot", png).stdout
    assert "2:1  w2/w1  crossed at alpha" in out
    rows = np.loadtxt(csv, delimiter=",", skiprows=1)
    assert rows.shape == (37, 11) and np.all(np.isfinite(rows))
    assert png.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"


def test_cli_latex_and_errors():
    out = run("modes", "--format", "latex").stdout
    assert "\\omega_1^2" in out and "\\alpha" in out
    for args, msg in (
        (["modes", "--sweep", "beta=0:1:3"], "cannot sweep 'beta'"),
        (["modes", "--plot", "x.png"], "--plot and --out go with --sweep"),
        (["modes", "--tau1", "1"], "No such option"),
        (["modes", "--g", "0"], "not a stable equilibrium"),
        (["modes", "--sweep", "alpha=0:1:3", "--out", "x.txt"], "--out: expected"),
    ):
        proc = run(*args, check=False)
        assert proc.returncode == 2 and msg in proc.stderr and len(proc.stderr.strip().splitlines()) == 1, proc.stderr
