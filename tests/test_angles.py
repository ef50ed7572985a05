"""Angles beyond 1e6 rad are refused everywhere they enter (issue 29, item 1): their cosine and
sine, or their reduction modulo 2 pi, would be digits of rounding. Within the bound an angle is
reduced exactly (math.remainder) into (-pi, pi]."""

from __future__ import annotations

import math

import numpy as np
import pytest

import skewpend
from skewpend import checks
from skewpend.errors import ParameterError

from helpers import assert_refused, run_cli


@pytest.mark.parametrize("value,expected", [(0.0, 0.0), (math.pi, math.pi), (-math.pi, math.pi), (3 * math.pi, math.pi),
                                            (7.0, 7.0 - 2 * math.pi), (np.float32(1.5), 1.5), (np.int64(-4), -4 + 2 * math.pi)])
def test_angle_is_reduced_into_minus_pi_pi(value, expected):
    got = checks.angle("q", value)
    assert -math.pi < got <= math.pi
    assert got == pytest.approx(expected, abs=4 * math.ulp(max(1.0, abs(float(value)))))


def test_reduction_keeps_its_digits_up_to_the_bound():
    """At the bound the double's spacing is 1.2e-10 rad; the reduction itself is exact to the
    last bit (the libm's sin reduces exactly too, so their sines agree to a few ulps)."""
    assert math.ulp(checks.ANGLE_LIMIT) < 2e-10
    for x in (0.999 * checks.ANGLE_LIMIT, -123456.789, 1e5 + 0.1):
        w = checks.angle("q", x)
        assert math.sin(w) == pytest.approx(math.sin(x), abs=4e-16) and math.cos(w) == pytest.approx(math.cos(x), abs=4e-16)


@pytest.mark.parametrize("bad", [1e17, -1e7, float("nan"), float("inf"), True, "1", None, 1j])
def test_absurd_or_non_real_angles_are_refused(bad):
    with pytest.raises(ParameterError, match="q"):
        checks.angle("q", bad)


def test_angles_takes_arrays_and_counts():
    assert checks.angles("about", np.array([0.5, -0.5]), 2) == (0.5, -0.5)
    with pytest.raises(ParameterError, match="about must be 2 angles"):
        checks.angles("about", [1.0, 2.0, 3.0], 2)
    with pytest.raises(ParameterError, match=r"about\[1\]"):
        checks.angles("about", [1.0, 1e300], 2)


def test_parameters_refuse_an_absurd_skew_angle():
    with pytest.raises(ParameterError, match="alpha must be an angle of at most"):
        skewpend.Parameters(a=1.0, b=1.0, m1=1.0, m2=1.0, alpha=1e17, g=9.81)
    assert skewpend.Parameters(a=1.0, b=1.0, m1=1.0, m2=1.0, alpha=-7.0, g=9.81).alpha == -7.0  # kept as given


@pytest.mark.parametrize("argv,flag", [(["derive", "--alpha", "1e17"], "--alpha"), (["simulate", "--phi0", "1e7"], "--phi0"),
                                       (["simulate", "--psi0", "-2e8deg"], "--psi0")])
def test_cli_refuses_absurd_angles(tmp_path, argv, flag):
    assert_refused(run_cli(argv, cwd=tmp_path), [flag, "at most 1e+06 rad"])


def test_a_huge_whole_number_is_shown_short():
    with pytest.raises(ParameterError, match=r"got 100000000000\.\.\. \(401 digits\)$"):
        checks.whole("n", 10**400, 1, 10)


@pytest.mark.parametrize("name", ["a", "b", "m1", "m2"])
def test_parameters_refuse_subnormal_sizes(name):
    """A subnormal length made a 16 x 16 flip map take 20 s of failing cells: the compiled code may
    flush it to 0, a degenerate model. (A subnormal g, damping, torque or skew is as good as 0 and kept.)"""
    values = {**dict(a=1.0, b=1.0, m1=1.0, m2=1.0, alpha=0.5, g=9.81), name: 1e-320}
    with pytest.raises(ParameterError, match=f"^{name} must be a normal number"):
        skewpend.Parameters(**values)
    assert skewpend.Parameters(a=1.0, b=1.0, m1=1.0, m2=1.0, alpha=1e-320, g=9.81, c1=1e-320).c1 == 1e-320


@pytest.mark.parametrize("argv,fragment", [
    (["equilibria", "--b", "1e17"], "not positive definite in double precision"),  # was exit 70 LinAlgError
    (["modes", "--a", "1e17"], "zero to rounding"),  # said only 'normal modes need g > 0' with g = 9.81
])
def test_scales_too_far_apart_are_one_line(tmp_path, argv, fragment):
    assert_refused(run_cli(argv, cwd=tmp_path), [fragment])


# -- issue 51: an angle typed without a unit beyond one turn is a likely slip of degrees -----------------
@pytest.mark.parametrize("argv,flag,meant", [
    (["derive", "--alpha", "30"], "--alpha", "30deg"),
    (["simulate", "--phi0", "-120"], "--phi0", "-120deg"),
    (["control", "leaderboard", "--robot", "acrobot", "--alpha", "30"], "--alpha", "30deg"),
    (["chaos-diagram", "--alphas", "0:90:7"], "--alphas", "0:90deg:7"),
])
def test_a_bare_angle_beyond_one_turn_is_refused_with_the_likely_spelling(tmp_path, argv, flag, meant):
    """``--alpha 30`` was 30 rad (1719 deg), silently; the leaderboard optimised at that skew."""
    err = assert_refused(run_cli(argv, cwd=tmp_path), [flag, "no unit", meant])
    assert "rad if radians are meant" in err or "rad:7 if radians are meant" in err


def test_a_bare_angle_in_a_run_file_follows_the_same_rule(tmp_path):
    (tmp_path / "run.toml").write_text("[parameters]\nalpha = 35\n", encoding="utf-8")
    assert_refused(run_cli(["derive", "--config", "run.toml"], cwd=tmp_path), ["alpha", "35deg"])


@pytest.mark.parametrize("text,radians", [("6.2", 6.2), ("-6.28", -6.28), ("30rad", 30.0), ("30 rad", 30.0), ("3pi", 3 * math.pi),
                                          ("400deg", 400 * math.pi / 180), ("2pi", 2 * math.pi)])
def test_angles_within_a_turn_or_with_a_unit_are_taken(text, radians):
    from skewpend.parsing import parse_scalar

    assert parse_scalar(text, "--alpha", angle=True) == pytest.approx(radians, rel=1e-15)


def test_a_number_from_python_keeps_its_radians(tmp_path):
    """The rule is about what a person writes (a flag, a run file): Python's numbers are radians by the
    API's contract; a run file says radians beyond a turn as a string with the unit."""
    (tmp_path / "run.toml").write_text('[parameters]\nalpha = "35rad"\n', encoding="utf-8")
    ran = run_cli(["derive", "--config", "run.toml"], cwd=tmp_path)
    assert ran.code == 0 and "alpha=35" in ran.out
    assert skewpend.Parameters(a=1.0, b=1.0, m1=1.0, m2=1.0, alpha=30.0, g=9.81).alpha == 30.0
