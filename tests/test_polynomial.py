"""A chain's model read as polynomials in its angles' sines and cosines and its speeds (numeric.polynomial), the
form the Taylor generator prints a chain's series from: it equals the recursive algorithms' graph it is read
from, at random states and parameters of the structure, for every kind of term; and it has the mass matrix's
known symmetry (no entry depends on the first angle: turning the whole chain about the first hinge changes no
kinetic energy) -- the cancellation that the coefficients found zero at the random samples must give."""

import pytest
import sympy as sp

from skewpend.symbolic.chain import Chain, Link
from skewpend.numeric import recursive
from skewpend.numeric.polynomial import check, polynomial_model

pytest.importorskip("casadi")


def _chains():
    skewed = Chain.from_lists(3, length=[1.0, 0.8, 0.6], mass=[1.0, 0.7, 0.5], axis=[(0, 0, 1), (0.3, 0, 1), (0.3, 0, 1)])
    lossy = Chain(links=(
        Link(axis=(0, 0, 1), length=0.5, mass=0.8, com=(0.02, 0.2, 0.0), inertia=(0.02, 0.004, 0.021), damping=0.1),
        Link(axis=(0.3, 0.1, 1), length=0.4, mass=0.6, torque=0.2, coulomb=0.05),
        Link(axis=(1, 0.2, 0.5), length=0.3, mass=0.3, com=(0.0, 0.15, 0.01), offset=(0.01, 0.3, 0.0),
             inertia=((0.003, 0.0002, 0), (0.0002, 0.0005, 0), (0, 0, 0.003))),
    ), g=9.81)
    rotors = Chain.from_lists(2, axis=[(0, 0, 1), (0.4, 0, 1)], rotor=[0.01, 0.02], gear=[20.0, 10.0])
    return {"skewed triple": skewed, "lossy triple": lossy, "geared rotors": rotors}


@pytest.mark.parametrize("name", list(_chains()))
def test_the_polynomials_equal_the_graph_they_are_read_from(name):
    """M, f, Q and the energy at random states, with the chain's own parameter vector: equal to the compiled graph's
    to 1e-12 of each quantity's scale (rounding: the coefficients are sums of products of p's entries)."""
    chain = _chains()[name]
    structure = recursive.structure_of_chain(chain)
    pm = polynomial_model(structure)
    assert check(pm, structure, recursive.parameter_vector(chain), states=10) < 1e-12
    # and at other values of the same structure: other masses, lengths and tilts within the axes' patterns
    other = chain.replace_link(1, mass=2.3).replace_link(2, length=0.37)
    assert recursive.structure_of_chain(other) == structure
    assert check(pm, structure, recursive.parameter_vector(other), states=10) < 1e-12


def test_the_mass_matrix_does_not_depend_on_the_first_angle():
    pm = polynomial_model(recursive.structure_of_chain(_chains()["lossy triple"]))
    q1 = pm.q[0]
    assert all(q1 not in sp.sympify(e).free_symbols for e in pm.M)
    # while gravity's forcing does (the first hinge's axis is not vertical)
    assert any(q1 in sp.sympify(e).free_symbols for e in pm.f)
    # the speeds enter f at most quadratically (Coriolis and centrifugal terms), M not at all
    for e in pm.f:
        e = sp.sympify(e)
        poly = sp.Poly(e.xreplace({a: 0 for a in e.atoms(sp.atan)}), *pm.dq)  # Coulomb friction's atan aside
        assert poly.total_degree() <= 2
    assert all(not (sp.sympify(e).free_symbols & set(pm.dq)) for e in pm.M)
