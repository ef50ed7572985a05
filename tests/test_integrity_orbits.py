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
