"""Issue 29 for the equilibria, the modes about them, the periodic orbits and the nonlinear normal
modes: absurd angles refused (never reduced into another point), a trivial orbit is a status,
infeasible work refused before it starts, numpy scalars accepted, bad tolerances refused."""

from __future__ import annotations

import math

import numpy as np
import pytest
from helpers import assert_refused, run_cli

import skewpend
from skewpend.analysis.equilibria import equilibria, equilibrium_at, find_equilibrium
from skewpend.analysis.modes import normal_modes
from skewpend.errors import ParameterError

REF = skewpend.reference_parameters()


# -- angles: reduced modulo 2 pi, refused where the reduction loses its meaning -----------------------


@pytest.mark.parametrize("about", [(1e17, 0.0), (0.0, -1e300), (math.inf, 0.0), (math.nan, 0.0), (1e6 + 1, 0.0)])
def test_modes_about_absurd_angles_refused(about):
    with pytest.raises(ParameterError, match=r"about\[[01]\] must be a finite angle"):
        normal_modes(REF, about=about)


def test_modes_about_reduce_whole_turns():
    """An equilibrium given k whole turns away is the same point: the same modes to 1e-9."""
    top = normal_modes(REF, about="up-up")
    q = top.equilibrium
    for k in (1, -7, 1000):
        m = normal_modes(REF, about=(q[0] + 2 * math.pi * k, q[1] - 2 * math.pi * k))
        assert all(abs(math.remainder(a - b, 2 * math.pi)) < 1e-9 for a, b in zip(m.equilibrium, q))
        np.testing.assert_allclose(m.growth_rates, top.growth_rates, rtol=1e-9, atol=1e-12)
        np.testing.assert_allclose(m.frequencies, top.frequencies, rtol=1e-9, atol=1e-12)


@pytest.mark.parametrize("which", [None, b"up-up", {"phi": 0}, (0.0,), (0.0, 0.0, 0.0), ("a", "b"), 3.0,
                                   np.zeros((2, 2)), (True, 0.0)])
def test_find_equilibrium_bad_input_is_one_parameter_error(which):
    with pytest.raises(ParameterError):
        find_equilibrium(REF, which, "about")


def test_equilibrium_at_numpy_inputs():
    e = equilibrium_at(REF, np.array([np.float32(0.0), np.float32(0.0)]))
    assert e.label == "down-down" and max(abs(e.q[0]), abs(e.q[1])) < 1e-12


@pytest.mark.parametrize("params", [None, "x", 3, {"a": 1}])
def test_equilibria_of_a_non_parameter_is_one_parameter_error(params):
    with pytest.raises(ParameterError, match="params must be a skewpend.Parameters"):
        equilibria(params)
    with pytest.raises(ParameterError, match="params must be a skewpend.Parameters"):
        equilibrium_at(params, (0.0, 0.0))


def test_equilibrium_newton_converges_only_with_a_small_residual():
    """Every root equilibria() reports has |grad V| below 1e-9 of the gradient's scale, and a
    point far from every equilibrium is refused, not "converged" onto."""
    from skewpend.analysis.equilibria import _geometry_only, _scalars, linearisation_functions

    f = linearisation_functions(_geometry_only(REF))
    for e in equilibria(REF):
        _, g, _, _, _ = f(*_scalars(REF), *e.q)
        assert max(abs(float(x)) for x in g) < 1e-9 * REF.g * (REF.m1 + REF.m2) * (REF.a + REF.b)
    with pytest.raises(skewpend.errors.EquilibriumError, match="not an equilibrium"):
        equilibrium_at(REF, (1.0, -0.5))


def test_cli_modes_about_absurd_angle_refused():
    ran = run_cli(["modes", "--about", "1e17,0"])
    assert_refused(ran, ["about", "1e+06 rad"])


# -- a trivial orbit is a status, never a success -----------------------------------------------------


@pytest.mark.parametrize("label", ["down-down", "up-down"])
def test_an_equilibrium_is_not_a_periodic_orbit(label):
    from skewpend.analysis.orbits import periodic_orbit

    q = equilibria(REF).find(label).q
    o = periodic_orbit(REF, (q[0], q[1], 0.0, 0.0), 2.0)
    assert o.status is skewpend.Status.TRIVIAL and not o.ok and not o.stable
    assert "equilibrium" in o.message and label in o.message
    assert np.all(np.isnan(o.state)) and math.isnan(o.period)  # no orbit's numbers on a non-orbit
    with pytest.raises(skewpend.errors.IntegrationError, match="equilibrium"):
        periodic_orbit(REF, (q[0], q[1], 0.0, 0.0), 2.0, throw=True)


def test_a_real_orbit_moves_and_closes():
    """The guess (0.3, 0.2, 0, 0), 1.6 s converges to a libration: it moves (amplitude > 0.01 rad)
    and closes after its period to 1e-8 (an independent integration)."""
    from skewpend.analysis.orbits import periodic_orbit

    o = periodic_orbit(REF, (0.3, 0.2, 0.0, 0.0), np.float32(1.6))
    assert o.ok and o.status is skewpend.Status.SUCCESS
    assert np.max(np.abs(o.state[:2])) > 0.01
    end = skewpend.simulate(REF, o.state, o.period, rtol=1e-12, atol=1e-12).y[-1]
    np.testing.assert_allclose(end, o.state, atol=1e-8)
    same = periodic_orbit(REF, (0.3 + 2 * math.pi, np.float64(0.2), np.int64(0), 0.0), 1.6)  # a whole turn away
    assert same.ok and abs(same.period - o.period) < 1e-8 * o.period
    assert periodic_orbit(REF, (0.3, 0.2, 0.0, 0.0), np.int64(2)).status in (skewpend.Status.SUCCESS,
                                                                          skewpend.Status.NO_CONVERGENCE)


def test_cli_orbit_at_rest_exits_1_with_the_reason():
    for top in ("0", "pi"):
        ran = run_cli(["orbit", "--phi0", top, "--psi0", top, "--dphi0", "0", "--dpsi0", "0", "--period", "2"])
        assert ran.code == 1, ran.report()
        assert "equilibrium" in ran.err and "stable" not in ran.out and "Traceback" not in ran.err


# -- validation: numpy scalars accepted, bad numbers refused, infeasible work refused up front ----------------


@pytest.mark.parametrize("kw, fragment", [
    ({"tol": -1}, "tol"), ({"tol": math.nan}, "tol"), ({"tol": 0.5}, "tol must be from"), ({"tol": 1e-20}, "tol must be from"),
    ({"max_iterations": -5}, "max_iterations"), ({"max_iterations": 2.0}, "max_iterations"),
    ({"max_iterations": True}, "max_iterations"),
    ({"rotation": (1e300, 0)}, "rotation"), ({"rotation": (10**400, 0)}, "rotation"), ({"rotation": (1.5, 0)}, "rotation"),
    ({"rotation": (0, 2000)}, "rotation"), ({"rotation": None}, "rotation"),
    ({"energy": math.inf}, "energy"), ({"energy": "1"}, "energy"), ({"throw": "yes"}, "throw"),
    ({"progress": 3}, "progress"),
])
def test_periodic_orbit_bad_settings_refused(kw, fragment):
    from skewpend.analysis.orbits import periodic_orbit

    with pytest.raises(ParameterError, match=fragment):
        periodic_orbit(REF, (0.3, 0.2, 0.0, 0.0), 1.6, **kw)


@pytest.mark.parametrize("y0, period, fragment", [
    ((1e17, 0, 0, 0), 1.6, r"y0\[0\] must be a finite angle"), ((0, -math.inf, 0, 0), 1.6, r"y0\[1\]"),
    ((0, 0, math.nan, 0), 1.6, r"y0\[2\]"), ((0, 0, 0, "1"), 1.6, r"y0\[3\]"), ((0, 0, 0), 1.6, "four numbers"),
    (None, 1.6, "guess"), ("abcd", 1.6, "y0"), ((0.3, 0.2, 0, 0), -1, "period"), ((0.3, 0.2, 0, 0), math.nan, "period"),
    ((0.3, 0.2, 0, 0), True, "period"), ((0.3, 0.2, 0, 0), 1e308, "period"),
])
def test_periodic_orbit_bad_guess_refused(y0, period, fragment):
    from skewpend.analysis.orbits import periodic_orbit

    with pytest.raises(ParameterError, match=fragment):
        periodic_orbit(REF, y0, period)


def test_a_period_too_long_to_shoot_is_refused_before_any_work():
    """1e5 s needs ~3e6 steps per shooting from the gentlest start (~31 per simulated second at
    1e-12): refused by the trial flow's estimate, with the estimate in the message."""
    from skewpend.analysis.orbits import periodic_orbit

    with pytest.raises(ParameterError, match=r"period must be short enough to shoot: 100000 s needs about [0-9.e+]+ steps per shooting"):
        periodic_orbit(REF, (0.3, 0.2, 0.0, 0.0), 1e5)
    with pytest.raises(ParameterError, match="period"):
        periodic_orbit(REF, (0.3, 0.2, 1e6, -1e6), 1.0)  # a start so fast one period is out of reach


@pytest.mark.parametrize("kw, fragment", [
    ({"energy_max": 1e308}, "energy_max must be at most 29.0376 J"), ({"energy_max": 30.0}, "highest equilibrium"),
    ({"energy_max": 1e-12}, "energy_max must be at least"), ({"energy_max": math.nan}, "energy_max"),
    ({"resolution": 100_000}, "resolution must be below max_orbits"), ({"resolution": 50, "max_orbits": 50}, "resolution"),
    ({"mode": 1.0}, "mode"), ({"mode": 3}, "mode"), ({"max_orbits": -1}, "max_orbits"),
])
def test_nnm_refuses_up_front(kw, fragment):
    from skewpend.analysis.orbits import nnm

    with pytest.raises(ParameterError, match=fragment):
        nnm(REF, **{"mode": 1, **kw})


def test_nnm_numpy_mode_and_backbones_max_order():
    from skewpend.analysis.orbits import backbones, nnm

    fam = nnm(REF, mode=np.int64(1), energy_max=0.05, resolution=5)
    assert fam.ok and fam.mode == 1 and abs(fam.energies[-1] - 0.05) < 1e-9
    for bad in (-1, 0, 2.5, 100):
        with pytest.raises(ParameterError, match="max_order"):
            backbones(REF, max_order=bad)


@pytest.mark.parametrize("kw, fragment", [
    ({"energy": 1e308}, "energy must be at most"), ({"energy": -1}, "energy"),
    ({"alphas": [0.1, 1e300]}, "alphas"), ({"alphas": ["a", "b"]}, "alphas"), ({"alphas": [0.1]}, "alphas"),
    ({"alphas": None}, "alphas"), ({"alphas": [0.2, 0.1, 0.3]}, "alphas"),
])
def test_nnm_alpha_refuses_up_front(kw, fragment):
    from skewpend.analysis.orbits import nnm_alpha

    with pytest.raises(ParameterError, match=fragment):
        nnm_alpha(REF, 1, **{"energy": 1.0, "alphas": [0.1, 0.2], **kw})


@pytest.mark.parametrize("argv, fragments", [
    (["orbit", "--period", "1e5"], ["--period", "steps per shooting"]),
    (["orbit", "--period", "2", "--rotation", "1e300,0"], ["--rotation", "1e+300"]),
    (["orbit", "--mode", "1", "--energy", "1e308"], ["--energy", "highest equilibrium"]),
    (["nnm", "--resolution", "100000"], ["--resolution", "max_orbits"]),
    (["nnm", "--energy-max", "1e308"], ["--energy-max", "highest equilibrium"]),
    (["nnm", "--mode", "1", "--alphas", "0:10deg:3", "--energy", "1e308"], ["--energy", "highest equilibrium"]),
])
def test_cli_infeasible_orbit_work_refused_at_once(argv, fragments):
    assert_refused(run_cli(argv), fragments)


# -- the modes' other entries: one ParameterError for what is not a model or not numbers ------------------


@pytest.mark.parametrize("call", [
    lambda: normal_modes(None), lambda: normal_modes("x"),
    lambda: skewpend.analysis.modes.sweep(None, "alpha", [0, 1]),
    lambda: skewpend.analysis.modes.sweep(REF, "alpha", ["a", "b"]),
    lambda: skewpend.analysis.modes.sweep(REF, "alpha", None),
    lambda: skewpend.analysis.modes.characteristic_equation("x"),
    lambda: skewpend.analysis.modes.check_nonlinear(None, 0.1),
])
def test_modes_entries_refuse_what_is_not_a_model(call):
    with pytest.raises(ParameterError):
        call()


def test_periodic_orbit_reports_progress_per_newton_iteration():
    from skewpend.analysis.orbits import periodic_orbit

    seen = []
    o = periodic_orbit(REF, (0.3, 0.2, 0.0, 0.0), 1.6, progress=lambda done, total: seen.append((done, total)))
    assert o.ok and seen and [d for d, _ in seen] == list(range(1, len(seen) + 1))
    assert {t for _, t in seen} == {25} and len(seen) == o.stats["newton_iterations"]
