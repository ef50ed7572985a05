"""Every equilibrium, and the linearisation about each (skewpend.equilibria).

Expected values come from closed forms worked out by hand (the thin rods' four equilibria and their
potentials; a long heavy second rod's extra equilibria), from the compiled simulation (an
equilibrium stays put; a disturbance along an unstable direction grows at the stated rate), from the
compiled Jacobian (the state matrix's eigenvalues) and from an independent root search with SciPy.
"""

from __future__ import annotations

import math

import numpy as np
import pytest

import skewpend
from skewpend.analysis.equilibria import equilibria, equilibrium_at
from skewpend.errors import EquilibriumError, ParameterError
from skewpend.status import Status


def thin(alpha=0.6, a=1.0, b=0.8, m1=1.0, m2=0.7, g=9.81, **kw):
    return skewpend.Parameters(a=a, b=b, m1=m1, m2=m2, alpha=alpha, g=g, **kw)


@pytest.mark.parametrize("alpha", [0.0, 0.6, math.pi / 2, 2.5, -1.1])
def test_thin_rods_have_the_four_equilibria_with_the_closed_form_potentials(alpha):
    p = thin(alpha=alpha)
    eq = equilibria(p)
    assert eq.ok and eq.status == Status.SUCCESS and len(eq) == 4
    a, b, m1, m2, g = 1.0, 0.8, 1.0, 0.7, 9.81
    # heights the centres of mass rise by, worked out by hand (j points down, Pi = 0 hanging)
    expected = {
        "down-down": ((0, 0), 0.0, 0),
        "down-up": ((0, math.pi), m2 * g * b, 1),
        "up-down": ((math.pi, math.pi), m1 * g * a + 2 * m2 * g * a, 1),
        "up-up": ((math.pi, 0), m1 * g * a + m2 * g * (2 * a + b), 2),
    }
    for label, (q, V, index) in expected.items():
        e = eq.find(label)
        assert np.allclose(np.cos(e.q), np.cos(q), atol=1e-12) and np.allclose(np.sin(e.q), np.sin(q), atol=1e-12)
        assert e.potential == pytest.approx(V, rel=1e-12, abs=1e-12)
        assert e.morse_index == index and e.stable == (index == 0)
    assert eq.index_sum == 0


def test_hanging_equilibrium_agrees_with_normal_modes():
    p = skewpend.reference_parameters()
    e = equilibria(p).find("down-down")
    modes = skewpend.normal_modes(p)  # the derivation's own linearisation (another code path)
    assert np.allclose(e.frequencies, modes.frequencies, rtol=1e-12)
    assert np.allclose(e.M, modes.M, rtol=1e-12) and np.allclose(e.K, modes.K, rtol=1e-12)


def test_long_heavy_second_rod_has_extra_equilibria_in_closed_form():
    """With alpha = 90 deg, dPi/dpsi = 0 and dPi/dphi = 0 give, besides sin = 0, the branch
    cos psi = -A / (B sin^2 alpha), with A = (m1/2 + m2) a, B = m2 b / 2, and cos phi = 0
    (by hand from Pi = -g [A cos phi + B (cos phi cos psi - cos alpha sin phi sin psi)])."""
    a, b, m1, m2 = 1.0, 5.0, 0.1, 1.0
    p = thin(alpha=math.pi / 2, a=a, b=b, m1=m1, m2=m2)
    eq = equilibria(p)
    assert eq.ok and len(eq) == 8 and eq.index_sum == 0
    psi = math.acos(-(m1 / 2 + m2) * a / (m2 * b / 2))
    extra = sorted((round(e.q[0], 9), round(e.q[1], 9)) for e in eq if abs(abs(e.q[0]) - math.pi / 2) < 1e-6)
    want = sorted((round(s1 * math.pi / 2, 9), round(s2 * psi, 9)) for s1 in (-1, 1) for s2 in (-1, 1))
    assert np.allclose(extra, want, atol=1e-9)
    # rod 1 horizontal along i turns the second axis e0 = i into j: rod 2 swings level too
    assert {eq_.label for eq_ in eq if abs(abs(eq_.q[0]) - math.pi / 2) < 1e-6} == {"level-level"}


def _simulate_from(p, y0, t_end, rtol=1e-12):
    return skewpend.simulate(p, y0, t_end, rtol=rtol, atol=1e-12, dt_out=t_end / 50)


@pytest.mark.parametrize("torques", [(0.0, 0.0), (3.0, 1.0), (-2.0, 0.5)])
def test_every_equilibrium_stays_put_in_the_compiled_simulation(torques):
    p = thin(alpha=0.9, c1=0.05, tau1=torques[0], tau2=torques[1])
    eq = equilibria(p)
    assert eq.ok and len(eq) >= 2
    for e in eq:
        tr = _simulate_from(p, e.state, 0.5)
        # an unstable one drifts only from round-off amplified by exp(s t): bound it by that
        s = e.growth_rates.max() if e.growth_rates.size else 0.0
        assert np.max(np.abs(tr.y[:, :2] - np.array(e.q))) < 1e-12 * math.exp(s * 0.5) * 100, e.label


def test_state_matrix_equals_the_compiled_jacobian():
    from skewpend.numeric.kernels import kernel_module, parameter_vector

    p = thin(alpha=0.4, c1=0.1, c2=0.03, tau1=1.0)
    kern = kernel_module(p)
    pv = parameter_vector(p)
    for e in equilibria(p):
        J = np.zeros(25)
        kern.jac(np.r_[e.state, 0.0], pv, J)
        J = J.reshape(5, 5)[:4, :4]
        assert np.allclose(e.A, J, rtol=1e-10, atol=1e-10 * np.abs(J).max()), e.label


def test_growth_rate_is_measured_by_the_simulation():
    p = skewpend.reference_parameters()
    for e in equilibria(p):
        for k, s in enumerate(e.growth_rates):
            v = e.unstable_directions[:, k]
            eps = 1e-7
            # along the direction and its velocity for pure growth: dq' = s dq
            y0 = np.r_[np.array(e.q) + eps * v / np.abs(v).max(), s * eps * v / np.abs(v).max()]
            tr = skewpend.simulate(p, y0, 2.0, rtol=1e-13, atol=1e-15, dt_out=0.05)
            dev = np.linalg.norm(tr.y[:, :2] - np.array(e.q), axis=1)
            t = tr.t
            mask = (dev > 10 * eps) & (dev < 1e-3)
            slope = np.polyfit(t[mask], np.log(dev[mask]), 1)[0]
            assert slope == pytest.approx(s, rel=2e-3), (e.label, k)
            break  # the fastest direction of each is enough


def test_general_bodies_with_torques_match_an_independent_root_search():
    from scipy.optimize import fsolve
    import sympy as sp

    rng = np.random.default_rng(7)
    p = skewpend.Parameters(a=1.0, b=0.6, m1=1.2, m2=0.8, g=9.81, axis2=(1.0, 0.2, 1.0), com2=(0.05, 0.3, 0.0),
                            inertia2=((0.03, 0.002, 0.0), (0.002, 0.006, 0.0), (0.0, 0.0, 0.03)), tau1=1.5, tau2=-0.4)
    eq = equilibria(p)
    assert eq.ok and eq.index_sum == 0
    # independent: SymPy's Pi differentiated here, fsolve from 400 random starts
    eom = skewpend.derive(p)
    phi, psi = skewpend.SYMBOLS["phi"], skewpend.SYMBOLS["psi"]
    grad = sp.lambdify([phi, psi], [sp.diff(eom.potential_energy, x) for x in (phi, psi)], "math")
    roots = []
    for q0 in rng.uniform(-math.pi, math.pi, (400, 2)):
        sol, info, ier, _ = fsolve(lambda q: np.array(grad(*q)) - [1.5, -0.4], q0, full_output=True, xtol=1e-13)
        if ier == 1:
            w = np.mod(sol + math.pi, 2 * math.pi) - math.pi
            if all(np.max(np.abs(np.mod(w - r + math.pi, 2 * math.pi) - math.pi)) > 1e-6 for r in roots):
                roots.append(w)
    assert len(roots) == len(eq)
    for r in roots:
        assert min(np.max(np.abs(np.mod(r - np.array(e.q) + math.pi, 2 * math.pi) - math.pi)) for e in eq) < 1e-8


def test_equilibrium_at_polishes_and_refuses():
    p = skewpend.reference_parameters()
    e = equilibrium_at(p, (math.pi - 1e-4, 1e-4))
    assert e.label == "up-up" and abs(e.q[1]) < 1e-12
    with pytest.raises(EquilibriumError, match="not an equilibrium"):
        equilibrium_at(p, (0.7, 0.2))


def test_one_search_for_any_model(tmp_path):
    """A chain of three and the double pendulum go through the same search (issue 52): a chain's point is
    polished and refused as the double pendulum's, its table and file name q1 .. q3, its file reads back as
    the chain; each result keeps the model it was given."""
    pytest.importorskip("netCDF4")
    chain = skewpend.Chain.from_lists(3, length=1.0, mass=1.0, axis=[(0, 0, 1), (0.3, 0, 1), (0, 0, 1)])
    eq = equilibria(chain)
    assert eq.ok and len(eq) == 8 and eq.params is chain
    e = eq.find("down-up-down")
    again = equilibrium_at(chain, np.array(e.q) + 1e-4)
    assert again.label == "down-up-down" and np.allclose(again.q, e.q, rtol=0, atol=1e-12)
    with pytest.raises(EquilibriumError, match=r"^\(q1, q2, q3\) = \(0.7, 0.2, 0.1\) rad is not an equilibrium"):
        equilibrium_at(chain, (0.7, 0.2, 0.1))
    assert eq.table().splitlines()[0].split()[1:7] == ["q1", "[deg]", "q2", "[deg]", "q3", "[deg]"]
    back = skewpend.open_result(eq.to_netcdf(tmp_path / "chain.nc"))
    assert back.params == chain and [x.label for x in back] == [x.label for x in eq]
    p = skewpend.reference_parameters()
    assert equilibria(p).params is p and "phi [deg]" in equilibria(p).table()


def test_refusals():
    with pytest.raises(EquilibriumError, match="every configuration"):
        equilibria(thin(g=0.0))
    assert len(equilibria(thin(g=0.0, tau1=1.0))) == 0
    with pytest.raises(ParameterError, match="needs numeric values"):  # checks.numeric_params: one ParameterError
        equilibria(skewpend.Parameters())
    with pytest.raises(ParameterError, match="starts"):
        equilibria(thin(), starts=1)


def test_result_protocol():
    eq = equilibria(skewpend.reference_parameters())
    ds = eq.to_xarray()
    assert ds.attrs["labels"].split(", ") == [e.label for e in eq]
    assert np.allclose(ds["phi"].values, [e.q[0] for e in eq])
    assert "none missed" in eq.summary() or "none missed" in eq.message
    text = eq.table()
    assert "down-down" in text and "nan" not in text.lower()


# -- modes about any equilibrium -------------------------------------------------------------------


@pytest.mark.parametrize("damped", [False, True])
def test_modes_about_every_equilibrium_match_the_state_matrix(damped):
    kw = dict(c1=0.2, c2=0.05) if damped else {}
    p = thin(alpha=0.6, **kw)
    for e in equilibria(p):
        m = skewpend.normal_modes(p, about=e.label)
        assert m.equilibrium == pytest.approx(e.q, abs=1e-12)
        ev = np.linalg.eigvals(m.state_matrix)
        scale = np.abs(ev).max()
        for x in m.eigenvalue_pairs.ravel():  # each of the four is an eigenvalue of the state matrix
            assert np.min(np.abs(ev - x)) < 1e-9 * scale, e.label
        assert np.min(np.abs(ev[:, None] - m.eigenvalue_pairs.ravel()[None, :]), axis=1).max() < 1e-9 * scale
        # a growing mode has a growth rate, frequency 0, period inf: never an imaginary frequency
        assert np.all(np.isreal(m.frequencies)) and np.all(m.frequencies >= 0)
        assert int(np.sum(m.unstable)) == e.morse_index
        assert np.allclose(np.sort(m.growth_rates[m.unstable]), np.sort(ev.real[ev.real > 1e-9]), rtol=1e-9)
        assert np.all(np.isinf(m.periods[m.unstable]))


def test_linear_response_about_the_top_matches_the_nonlinear_motion():
    p = skewpend.reference_parameters()
    m = skewpend.normal_modes(p, about="up-up")
    q_star = np.array(m.equilibrium)
    dq0 = np.array([1e-7, -2e-7])
    t = np.linspace(0, 1.0, 21)
    lin = m.linear_response(dq0, [0.0, 0.0], t)
    tr = skewpend.simulate(p, np.r_[q_star + dq0, 0, 0], 1.0, rtol=1e-13, atol=1e-15, dt_out=0.05)
    # the disturbance grows to ~1e-4 rad: the linear theory holds to its square
    assert np.allclose(tr.y[:, :2] - q_star, lin[:, :2], atol=1e-8)
    assert np.max(np.abs(lin[:, :2])) > 1e-5


def test_modes_about_refuses_what_is_not_an_equilibrium():
    p = skewpend.reference_parameters()
    with pytest.raises(EquilibriumError):
        skewpend.normal_modes(p, about=(0.7, 0.2))
    with pytest.raises(ParameterError, match="no equilibrium is labelled"):
        skewpend.normal_modes(p, about="level-level")
    with pytest.raises(EquilibriumError, match="decompose"):
        skewpend.normal_modes(p, about="up-up").decompose([0.1, 0], [0, 0])


def test_cli_equilibria_and_modes_about(tmp_path):
    import json

    from helpers import run_cli

    ran = run_cli(["equilibria", "--format", "json", "--tau1", "1.5"], cwd=tmp_path)
    assert ran.code == 0, ran.report()
    data = json.loads(ran.out)
    assert data["index_sum"] == 0 and len(data["equilibria"]) == 4
    ran = run_cli(["modes", "--about", "up-up"], cwd=tmp_path)
    assert ran.code == 0 and "unstable" in ran.out and "nan" not in ran.out.lower(), ran.report()
    ran = run_cli(["modes", "--about", "up-up", "--format", "json"], cwd=tmp_path)
    d = json.loads(ran.out)
    assert d["periods"] == [None, None] and all(s > 0 for s in d["growth_rates"])
    for argv, text in ((["modes", "--about", "sideways"], "--about"),
                       (["modes", "--about", "up-up", "--sweep", "alpha=0:1:3"], "--about"),
                       (["equilibria", "--g", "0"], "every configuration"),
                       (["modes", "--about", "40deg,10deg"], "not an equilibrium")):
        ran = run_cli(argv, cwd=tmp_path)
        assert ran.code == 2 and text in ran.err and len(ran.err.strip().splitlines()) == 1, ran.report()
