"""A result's repr is one line a person can read: its kind, status and message, and each data
field by its shape -- never whole arrays (issue 29: Trajectory, FlipMap, Modes printed thousands
of characters)."""

from __future__ import annotations

import numpy as np
import pytest

import skewpend
from skewpend.results import _brief


@pytest.fixture(scope="module")
def results(reference, reference_state):
    tr = skewpend.simulate(reference, reference_state, 20.0)
    modes = skewpend.normal_modes(reference)
    fm = skewpend.flip_map(reference, 16, t_end=0.5)
    return {"trajectory": tr, "modes": modes, "flip map": fm, "equilibria": skewpend.equilibria(reference)}


@pytest.mark.parametrize("kind", ["trajectory", "modes", "flip map", "equilibria"])
def test_repr_is_one_short_line_with_kind_and_status(results, kind):
    result = results[kind]
    text = repr(result)
    assert "\n" not in text and len(text) <= 420, text
    assert text.startswith(f"<{type(result).__name__} success: {result.message}"), text


def test_repr_names_arrays_by_shape(results):
    tr = results["trajectory"]
    n = len(tr.t)
    assert n > 100  # a 20 s run: a whole array would be thousands of characters
    assert f"t float64[{n}]" in repr(tr) and f"y float64[{n}x4]" in repr(tr)
    assert "flip_time float64[16x16]" in repr(results["flip map"])


def test_brief_shows_few_numbers_whole_and_cuts_the_rest():
    assert _brief(np.array([1.0, 2.5])) == "[1. , 2.5]"
    assert _brief(np.zeros((3, 5))) == "float64[3x5]"
    assert _brief(0.1234567891) == "0.123457"
    assert _brief(list(range(10))) == "list of 10 int"
    assert len(_brief("x" * 200)) == 60
