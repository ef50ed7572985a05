"""The explorer's one physics contract and one slider definition, for every model (issue 52).

* the sliders come from one definition (``frontend.page_sliders``): the double pendulum's are the ones users
  know (alpha, a, b, m1, m2, g, c1, c2, phi0, psi0 with their ranges and the reference case's values), a
  chain's are the values its physics reads alone (g and each joint's damping) and a start for each joint;
  a chain of two is the double pendulum, and gets its page;
* every model's generated physics (``explorer_source.explorer_js``) exports the same names, and its ``linear`` --
  the M0 and K0 the page's normal modes and linearised equations are computed from -- equals the library's
  ``normal_modes`` (its M and K, in Node) for the double pendulum, a skewed triple and a chain with friction.
"""

from __future__ import annotations

import json
import shutil
import subprocess

import numpy as np
import pytest

import skewpend
from skewpend.numeric.explorer_source import explorer_js, page_vector
from skewpend.symbolic.chain import Chain
from skewpend.views.frontend import page_settings, page_sliders

TRIPLE = Chain.from_lists(3, length=[0.5, 0.4, 0.3], mass=[1.0, 0.8, 0.5], axis=[(0, 0, 1), (0.5, 0, 1), (1, 0, 0)],
                          damping=[0.0, 0.0, 0.01])
TWO = Chain.from_lists(2, length=[1.0, 0.8], mass=[1.0, 0.7])
FRICTION = Chain.from_lists(2, length=[1.0, 0.8], mass=[1.0, 0.7], coulomb=[0.1, 0.0], damping=[0.2, 0.0])


def test_the_double_pendulum_keeps_its_sliders():
    sliders = page_sliders()
    assert [s[0] for s in sliders] == ["alpha", "a", "b", "m1", "m2", "g", "c1", "c2", "phi0", "psi0"]
    assert sliders[0] == ["alpha", "α skew", -180.0, 180.0, 0.5, 34.38, "°", True]
    assert sliders[1] == ["a", "a rod 1", 0.2, 3.0, 0.05, 1.0, "m", False]
    assert [s[1] for s in sliders[3:8]] == ["m1", "m2", "g", "c1 damping", "c2 damping"]
    assert sliders[-2] == ["phi0", "φ0 start", -180.0, 180.0, 0.5, 68.75, "°", True]
    assert sliders[-1][:2] == ["psi0", "ψ0 start"] and sliders[-1][5] == -45.84
    # a run's values are the sliders' start; the skew only where it enters
    assert page_sliders(skewpend.reference_parameters().replace(a=1.5))[1][5] == 1.5
    assert "alpha" not in [s[0] for s in page_sliders(skewpend.Parameters(axis2=(0.3, 0.2, 1.0)))]


def test_a_chain_s_sliders_are_its_live_values_and_its_starts():
    sliders = page_sliders(TRIPLE)
    assert [s[0] for s in sliders] == ["g", "c1", "c2", "c3", "q1_0", "q2_0", "q3_0"]
    assert sliders[3][5] == 0.01 and sliders[4][1] == "q1 start" and sliders[4][5] == 28.65
    settings = page_settings(TRIPLE)
    order = page_vector(TRIPLE)[2]
    assert [order[i] for i in settings["lengths"]] == ["l1", "l2", "l3"]
    assert [order[i] for i in settings["torques"]] == ["tau1", "tau2", "tau3"]
    assert settings["names"] == ["q1", "q2", "q3"] and settings["title"] == "a chain of 3 links"


def test_a_chain_of_two_is_the_double_pendulum_s_page_and_friction_takes_the_recursive_form():
    assert page_vector(TWO)[0] == "exact" and page_vector(FRICTION)[0] == "recursive"
    # the chain of two with the specification's axes is the double pendulum: its page's sliders, alpha its tilt
    assert [s[0] for s in page_sliders(TWO)] == [s[0] for s in page_sliders(skewpend.reference_parameters())]
    assert [s[0] for s in page_sliders(TWO)] == ["alpha", "a", "b", "m1", "m2", "g", "c1", "c2", "phi0", "psi0"]
    assert [s[0] for s in page_sliders(FRICTION)] == ["g", "c1", "c2", "phi0", "psi0"]
    assert "export const TERMS = [\n" in explorer_js(TWO) and "export const TERMS = [];" in explorer_js(FRICTION)


@pytest.mark.skipif(shutil.which("node") is None, reason="Node.js is not installed")
@pytest.mark.parametrize("model", [skewpend.reference_parameters(), TRIPLE, FRICTION], ids=["double", "triple", "friction"])
def test_every_page_s_physics_has_one_contract_and_its_linearisation_is_the_library_s(tmp_path, model):
    (tmp_path / "physics.mjs").write_text(explorer_js(model))
    (tmp_path / "run.mjs").write_text(
        "import * as m from './physics.mjs';\n"
        "const y = new Array(2 * m.N).fill(0.3);\n"
        "console.log(JSON.stringify({n: m.N, P: m.P, order: m.PARAMETER_ORDER, linear: m.linear(y, m.P), "
        "rhs: m.rhs(y), energy: m.energy(y), tips: m.tips(y), axes: m.axes(y), terms: m.TERMS.length, "
        "coefficients: m.coefficients(m.P).length, odd: m.FLIP_ODD}));\n")
    res = json.loads(subprocess.run(["node", str(tmp_path / "run.mjs")], capture_output=True, text=True, check=True,
                                    timeout=60).stdout)
    form, _, order, values = page_vector(model)
    assert res["n"] == model.n and res["P"] == values and res["order"] == list(order)
    assert len(res["rhs"]) == 2 * model.n and len(res["tips"]) == len(res["axes"]) == 3 * model.n
    assert res["terms"] == res["coefficients"] and (res["terms"] > 0) == (form == "exact")
    lib = skewpend.normal_modes(model)
    M0, K0 = (np.array(a) for a in res["linear"])
    np.testing.assert_allclose(M0, lib.M, rtol=1e-12, atol=1e-14 * np.abs(lib.M).max())
    np.testing.assert_allclose(K0, lib.K, rtol=1e-12, atol=1e-14 * np.abs(lib.K).max())
