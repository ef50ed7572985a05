"""Issue 53: a declared unit of the angles that makes the motion implausible is named in one line, with the fix
(``unit=rad`` / ``unit=deg``) -- Kaheman et al.'s free swings (their absolute angles from the upright) written
in radians and declared degrees, and written in degrees and declared radians."""

from __future__ import annotations

import math
import sys
import warnings
from pathlib import Path

import pytest

import skewpend
from skewpend.analysis.identify import unit_check
from skewpend.analysis.measurements import Convention, convert_back, kaheman_published_chain
from skewpend.errors import ParameterError

DATA = Path(__file__).resolve().parent.parent / "data"
KAHEMAN_CONVENTION = Convention(second="absolute", zero="upright")


def _rig(name):
    fit = skewpend.Measurements.from_kaheman(DATA / name, which="fit").select(range(6))
    if name == "kaheman2023":
        sys.path.insert(0, str(Path(__file__).resolve().parent))
        from test_identify import kaheman_parameters

        return fit, kaheman_parameters()
    return fit, kaheman_published_chain(DATA / name)


def _written(fit, factor: float, unit: str, skip=("mean", "units")):
    """The pieces as the file's numbers (absolute angles from the upright) times ``factor``, declared ``unit``."""
    pieces = []
    for p in fit:
        raw, raw_dq, _ = convert_back(p.q, p.dq, convention=KAHEMAN_CONVENTION)
        pieces.append({"t": p.t, "q": raw * factor, "dq": raw_dq * factor, "name": p.name})
    return skewpend.Measurements.from_arrays(pieces, convention=Convention(second="absolute", zero="upright", unit=unit),
                                             skip=skip)


@pytest.mark.parametrize("name", ["kaheman2023", "kaheman2023-triple"])
def test_a_wrong_unit_is_named_with_its_fix_and_the_right_one_passes(name):
    """The readers' own checks skipped (``skip=("mean", "units")``), so that the energy check alone speaks: the
    free swings' kinetic and potential energies exchange equally as declared rightly (log10 of their spreads'
    ratio measured within 0.002), 25-270 times apart under the wrong unit (threshold 10)."""
    fit, model = _rig(name)
    assert unit_check(fit, model) is None
    assert unit_check(_written(fit, 1.0, "rad"), model) is None
    for factor, declared, fix in ((1.0, "deg", "unit=rad"), (180 / math.pi, "rad", "unit=deg")):
        line = unit_check(_written(fit, factor, declared), model)
        assert line is not None and line.endswith(f"give {fix}") and "\n" not in line, (declared, line)
        assert f"(unit={declared} declared)" in line


def test_identify_says_the_line_before_the_fit():
    fit, model = _rig("kaheman2023")
    with pytest.warns(UserWarning, match=r"look like radians, not degrees .* give unit=rad$"):
        skewpend.identify(_written(fit, 1.0, "deg"), model, method="linear", bootstrap=0)
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        skewpend.identify(fit, model, method="linear", bootstrap=0)  # the right unit: no word


def test_the_reader_names_the_unit_where_the_other_one_swings_about_the_hanging_rest():
    """Radians declared as degrees with the zero upright read as a swing about the top (its mean near -pi); the
    reader's mean check then names the unit, not the zero (read as radians the swing is about the hanging rest)."""
    fit, _ = _rig("kaheman2023-triple")
    with pytest.raises(ParameterError, match=r"the angles look like radians; state Convention\(unit='rad'\)$"):
        _written(fit, 1.0, "deg", skip=())


def test_a_fit_of_the_implausible_reading_ends_with_its_status_not_an_exception():
    """Radians declared as degrees, the readers' checks skipped, fitted anyway: the warning, then a result (the
    fit's normal equations could not be solved on this reading: a status and a message, never LinAlgError)."""
    fit, model = _rig("kaheman2023")
    with pytest.warns(UserWarning, match="give unit=rad"):
        result = skewpend.identify(_written(fit.select(range(1)), 1.0, "deg"), model, bootstrap=0)
    assert isinstance(result.message, str) and "\n" not in result.message
