"""The animation's (and the report picture's) labels follow what the model is, asked of the model, never its type
(issue 54): the specification's double pendulum -- its parameters, or a chain of two with its geometry -- is
drawn with its names (rod 1 (a), n₁; rod 2 (b), e = P₁·e₀); any other chain, of two links too (the rotary
pendulum: hinge 1 vertical, hinge 2 along the arm), with a chain's: link i, hinge i's axis eᵢ."""

from __future__ import annotations

from pathlib import Path

import pytest

import skewpend
from skewpend.config import Run
from skewpend.symbolic.chain import Chain
from skewpend.views.animation import FrameRenderer
from skewpend.views.animation.renderer import is_double_pendulum

ROOT = Path(__file__).resolve().parent.parent


def _drawn_texts(model, y0):
    """The title, the legend's entries and the hinge axes' labels as drawn on a frame of ``model``'s motion."""
    tr = skewpend.simulate(model, y0, 0.2, dt_out=0.1, method="dop853")
    r = FrameRenderer(tr, size=(640, 480))
    r.draw(1)
    title = r.fig.texts[0].get_text()
    legend = [t.get_text() for t in r.legend.get_texts()]
    axes = [r.artists[f"{name}_label"].get_text() for name in r.axis_names]
    return title, legend, axes


DOUBLE_LEGEND = ["rod 1 (a)", "rod 2 (b)", "hinge 1 axis n₁ (fixed)", "hinge 2 axis e = P₁·e₀ (turns with rod 1)"]


@pytest.mark.parametrize("model", [skewpend.reference_parameters(),
                                   Chain.from_parameters(skewpend.reference_parameters())],
                         ids=["parameters", "chain of two with its geometry"])
def test_the_specification_s_double_pendulum_keeps_its_names(model):
    assert is_double_pendulum(model)
    title, legend, axes = _drawn_texts(model, [1.0, 0.5, 0.0, 0.0])
    assert title.startswith("Double pendulum with skewed hinge axes")
    assert legend[:4] == DOUBLE_LEGEND and axes == ["n₁", "e"]


def test_the_rotary_pendulum_is_drawn_as_a_chain_of_two_links():
    chain = Run("animate", str(ROOT / "examples" / "qube_servo2.toml")).chain()
    assert chain.n == 2 and not is_double_pendulum(chain)
    title, legend, axes = _drawn_texts(chain, [0.3, 0.9, 4.0, 0.0])
    assert title == "Chain of 2 links:  ∠(e₁, e₂) = 90°"
    assert legend[:4] == ["link 1", "link 2", "hinge 1's axis e₁ (fixed)", "hinge 2's axis e₂ (turns with link 1)"]
    assert axes == ["e₁", "e₂"]
    assert not any("(a)" in t or "P₁" in t or "n₁" in t for t in [title, *legend, *axes])


def test_a_chain_of_two_off_the_specification_s_axes_and_a_triple_are_chains():
    """A chain of two whose hinge 1 is not along k (else the double pendulum's geometry) and a chain of three."""
    two = Chain.from_lists(2, length=[1.0, 0.8], mass=[1.0, 0.7], axis=[(1, 0, 0), (0, 0, 1)])
    assert not is_double_pendulum(two)
    _, legend, axes = _drawn_texts(two, [0.5, 0.2, 0.0, 0.0])
    assert legend[:2] == ["link 1", "link 2"] and axes == ["e₁", "e₂"]
    triple = Chain.from_lists(3, length=[0.5, 0.4, 0.3], mass=[1.0, 0.8, 0.5], axis=[(0, 0, 1), (0.5, 0, 1), (1, 0, 0)])
    title, legend, axes = _drawn_texts(triple, [1.0, 0.5, 0.2, 0.0, 0.0, 0.0])
    assert title.startswith("Chain of 3 links")
    assert legend[:6] == ["link 1", "link 2", "link 3", "hinge 1's axis e₁ (fixed)",
                          "hinge 2's axis e₂ (turns with link 1)", "hinge 3's axis e₃ (turns with link 2)"]
    assert axes == ["e₁", "e₂", "e₃"]
