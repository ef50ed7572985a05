"""Parameters: validation when built, symbolic bookkeeping."""

from __future__ import annotations

import math

import pytest

from skewpend import NotNumericError, ParameterError, Parameters


def test_defaults_are_the_specifications_symbolic_thin_rods():
    p = Parameters()
    assert p.symbolic_names == ("a", "b", "m1", "m2", "alpha", "g")
    assert p.is_thin_rods and not p.is_numeric
    assert (p.c1, p.c2, p.tau1, p.tau2) == (0.0, 0.0, 0.0, 0.0)


def test_immutable():
    p = Parameters(a=1)
    with pytest.raises(AttributeError):
        p.a = 2  # type: ignore[misc]


@pytest.mark.parametrize(
    "kwargs, message",
    [
        (dict(a=0), "a must be > 0"),
        (dict(m1=-1.0), "m1 must be > 0"),
        (dict(b=math.inf), "b must be finite"),
        (dict(m2=math.nan), "m2 must be finite"),
        (dict(g=-9.81), "g must be >= 0"),
        (dict(c1=-0.1), "c1 must be >= 0"),
        (dict(alpha="30deg"), "alpha must be a real number"),
        (dict(a=True), "a must be a real number"),
        (dict(axis2=(0, 0, 0)), "axis2 must be a non-zero vector"),
        (dict(axis1=(1, 0)), "axis1 must have 3 components"),
        (dict(com2=(0, "1x", 0)), r"com2\[1\] must be a real number or a symbol name"),
        (dict(com2=(0, None, 0)), r"com2\[1\] must be a real number"),
        (dict(inertia2=((1, 0.5, 0), (0, 1, 0), (0, 0, 1))), "inertia2 must be symmetric"),
        (dict(inertia1=((1, 0, 0), (0, -1, 0), (0, 0, 1))), "positive semi-definite"),
        (dict(inertia2=((1, 0, 0), (0, 1, 0), (0, 0, 3))), "triangle inequality"),
    ],
)
def test_bad_values_are_refused_with_a_clear_message(kwargs, message):
    with pytest.raises(ParameterError, match=message):
        Parameters(**kwargs)


def test_axes_are_normalised_and_alpha_unused_with_axis2():
    p = Parameters(axis2=(3.0, 0.0, 4.0))
    assert p.axis2 == pytest.approx((0.6, 0.0, 0.8))
    assert "alpha" not in p.symbolic_names and not p.uses_alpha


def test_thin_rod_inertia_is_accepted_at_the_triangle_limit():
    Parameters(inertia1=((1 / 12, 0, 0), (0, 0, 0), (0, 0, 1 / 12)))


def test_replace_validates_and_refuses_unknown_names():
    p = Parameters(a=1.0)
    assert p.replace(b=2.0).b == 2.0
    with pytest.raises(ParameterError, match="unknown parameter"):
        p.replace(length=2.0)
    with pytest.raises(ParameterError):
        p.replace(b=-2.0)


def test_from_mapping_round_trip():
    p = Parameters(a=1.0, b=0.8, m1=1, m2=0.7, alpha=0.6, g=9.81, com2=(0, 0.4, 0.01))
    assert Parameters.from_mapping(p.to_dict()) == p
    with pytest.raises(ParameterError, match="unknown parameter"):
        Parameters.from_mapping({"mass": 1})


def test_require_numeric_names_the_symbolic_parameters():
    with pytest.raises(NotNumericError, match="symbolic: alpha, g"):
        Parameters(a=1, b=1, m1=1, m2=1).require_numeric("simulation")
    full = Parameters(a=1, b=1, m1=1, m2=1, alpha=0, g=9.81)
    assert full.require_numeric() is full
