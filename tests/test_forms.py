"""One model, the form of its generated code an argument (issue 52): ``exact`` (the specification's derivation,
two links), ``straight`` and ``compact`` (the recursive algorithms, any chain).  One equality test per pair of
forms -- the same model functions at random states, the same runs -- replaces the tests that proved, capability
by capability, that the chain of two equals the double pendulum: a chain of two *runs* as the double pendulum
(the same library, the same numbers), so only the forms can differ."""

import itertools

import numpy as np
import pytest

import skewpend
from skewpend.errors import ParameterError
from skewpend.numeric.kernels import FORMS, model_form, model_kernel, model_vector
from skewpend.symbolic.chain import Chain

#: Two-link models the three forms print: the specification's thin rods skewed; general bodies (offset centres
#: of mass, full inertia tensors), a tilted roof hinge, damping, Coulomb friction, constant torques, geared rotors.
MODELS = {
    "skewed rods": skewpend.Parameters(a=1.0, b=0.8, m1=1.0, m2=0.7, alpha=0.4, g=9.81),
    "lossy bodies": skewpend.Parameters(
        a=0.9, b=0.7, m1=1.2, m2=0.6, g=9.81, axis1=(0.1, 0.0, 0.995), axis2=(0.3, 0.1, 0.9),
        com1=(0.01, 0.4, -0.02), com2=(0.0, 0.3, 0.03),
        inertia1=((0.09, 0.001, 0.002), (0.001, 0.01, 0.003), (0.002, 0.003, 0.09)),
        inertia2=((0.03, 0.0, 0.001), (0.0, 0.005, 0.0), (0.001, 0.0, 0.03)),
        c1=0.05, c2=0.02, cf1=0.01, cf2=0.02, tau1=0.1, tau2=-0.05),
    "geared rotors": skewpend.Parameters(a=1.0, b=0.8, m1=1.0, m2=0.7, alpha=0.4, g=9.81, Ir=0.002, gr=3.0, c2=0.01),
}
PAIRS = list(itertools.combinations(FORMS, 2))
#: (model, first form, second form): the compact form prints no rotors (refused in one line, below)
CASES = [(name, one, two) for name in MODELS for one, two in PAIRS
         if not (MODELS[name].Ir and "compact" in (one, two))]


def _functions(model, form, ys):
    kernel = model_kernel(model, form)
    p = model_vector(model, kernel.form)
    assert kernel.form == form
    out = []
    for y in ys:
        y5 = np.append(y, 0.0)
        rhs, mom, tips = np.zeros(5), np.zeros(2), np.zeros(6)
        kernel.rhs(y5, p, rhs)
        kernel.momenta(y5, p, mom)
        kernel.tips(y5, p, tips)
        out.append(np.concatenate([rhs[:4], mom, tips, [kernel.energy(y5, p)]]))
    return np.array(out)


@pytest.mark.parametrize("name, one, two", CASES)
def test_each_pair_of_forms_prints_the_same_model(name, one, two):
    """The accelerations, momenta, rod ends and energy at 50 random states (seeded): equal to 1e-12 of each
    quantity's scale (three printings of one model, differently rounded: measured ~1e-15)."""
    model = MODELS[name]
    rng = np.random.default_rng(52)
    ys = np.column_stack([rng.uniform(-np.pi, np.pi, (50, 2)), rng.uniform(-4, 4, (50, 2))])
    a, b = _functions(model, one, ys), _functions(model, two, ys)
    scale = np.maximum(np.max(np.abs(a), axis=0), 1.0)
    assert np.all(np.abs(a - b) <= 1e-12 * scale), np.max(np.abs(a - b) / scale)


@pytest.mark.parametrize("one, two", PAIRS)
def test_each_pair_of_forms_runs_the_same_motion(one, two):
    """DOP853 at 1e-12 over 3 s of the lossy two-link model from a chaotic start: the states within 1e-8 (the
    runs' global errors ~1e-10 each), the same accepted steps within 2 (the rounding of three printings)."""
    model, y0 = MODELS["lossy bodies"], [1.1, -0.7, 0.0, 0.4]
    a = skewpend.simulate(model, y0, 3.0, method="dop853", rtol=1e-12, atol=1e-12, form=one)
    b = skewpend.simulate(model, y0, 3.0, method="dop853", rtol=1e-12, atol=1e-12, form=two)
    assert a.ok and b.ok and abs(a.stats["steps"] - b.stats["steps"]) <= 2
    assert np.max(np.abs(a.y[-1] - b.y[-1])) < 1e-8 and abs(a.work[-1] - b.work[-1]) < 1e-8


def test_the_taylor_series_of_two_forms_are_one():
    """The Taylor method on two generators (the exact derivation's recurrences, the recursive graph's), skewed,
    damped and driven, at 1e-12: the same order and steps (within 2), the states within 1e-10."""
    params = skewpend.reference_parameters().replace(alpha=0.6, c1=0.05, tau2=0.1)
    y0 = [1.1, -0.7, 0.0, 0.4]
    a = skewpend.simulate(params, y0, 5.0, method="taylor", rtol=1e-12, atol=1e-12, form="exact")
    b = skewpend.simulate(params, y0, 5.0, method="taylor", rtol=1e-12, atol=1e-12, form="straight")
    assert a.ok and b.ok and a.stats["order"] == b.stats["order"] and abs(a.stats["steps"] - b.stats["steps"]) <= 2
    assert np.max(np.abs(a.y[-1] - b.y[-1])) < 1e-10 and abs(a.work[-1] - b.work[-1]) < 1e-10


def test_a_chain_of_two_runs_as_the_double_pendulum():
    """The default form is the fastest that prints the model and reads its axes at run time: a chain of two the
    double pendulum's parameters hold, with the specification's axes (hinge 1 along k, hinge 2 in the plane of k
    and i: its tilt the skew alpha), runs on the double pendulum's very library (exact) with the same run-time
    vector -- thin rods as the facade's rods, general bodies as its bodies; other axes (a tilted roof hinge, hinge 2
    out of that plane), a hinge off rod 1's end and three links on the recursive algorithms, which key only the
    axes' patterns (tilting compiles nothing)."""
    rods = skewpend.Parameters(a=1.0, b=0.8, m1=1.0, m2=0.7, alpha=0.4, g=9.81)
    bodies = MODELS["lossy bodies"].replace(axis1=None, axis2=None, alpha=-0.3)
    for params in (rods, bodies, MODELS["geared rotors"]):
        chain = params.as_chain()
        assert model_kernel(chain) is model_kernel(params) and model_kernel(chain).form == "exact"
        np.testing.assert_array_equal(model_vector(chain), model_vector(params))
    chain = rods.as_chain()
    for other in (chain.replace_link(1, axis=(0.1, 0.0, 1.0)), chain.replace_link(2, axis=(0.3, 0.1, 0.9)),
                  chain.replace_link(2, offset=(0.0, 0.9, 0.05)), MODELS["lossy bodies"].as_chain(), Chain.from_lists(3)):
        assert model_form(other)[0] == "straight"
    assert model_form(Chain.from_lists(12))[0] == "compact"


def test_a_form_the_model_has_not_is_one_line():
    with pytest.raises(ParameterError, match=r"the exact form .* prints two links .* a chain of 3 links: use form "
                                             r"'straight' or 'compact'"):
        skewpend.simulate(Chain.from_lists(3), [0.1] * 6, 1.0, form="exact")
    with pytest.raises(ParameterError, match=r"form must be one of exact, straight, compact, got 'fast'"):
        skewpend.simulate(MODELS["skewed rods"], [0.1] * 4, 1.0, form="fast")
    with pytest.raises(ParameterError, match=r"the compact form prints chains without rotors; .* use form 'exact' or "
                                             r"'straight'"):
        skewpend.simulate(MODELS["geared rotors"], [0.1] * 4, 1.0, form="compact")
