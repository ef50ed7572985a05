"""Equilibria's labels come from the geometry (issue 54): each link's centre of mass below (``down``) or above
(``up``) its hinge along gravity at that equilibrium -- not from ``q`` being 0 or pi.  A model whose zero is
upright (the DeepMind Control Suite's acrobot, read from its MJCF) has its ``up-up`` at ``q = 0`` and its
``down-down`` at ``(pi, 0)``; the goals that name labels (control's default every-link-up target, the MPC's and
the swing-ups' goals, which all go through :func:`~skewpend.analysis.equilibria.find_equilibrium`) mean its
upright; the double pendulum's and the hanging chains' labels are what they were (their q = 0 hangs)."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest

import skewpend
from skewpend.analysis.control import EVERY_LINK_UP, equilibrium_argument, linearization
from skewpend.analysis.equilibria import equilibria, find_equilibrium, link_directions
from skewpend.symbolic.chain import Chain

DATA = Path(__file__).resolve().parent / "data"

#: The DeepMind acrobot's geometry as a chain (what read_mjcf makes of tests/data/dm_control_acrobot.xml, its
#: inertias rounded): two 1 m arms on parallel hinges, each centre of mass 0.5 m ABOVE its hinge at q = 0.
UPRIGHT = Chain.from_lists(2, axis=[(0, 0, 1), (0, 0, 1)], offset=[(0, -2, 0), (0, -1, 0)], length=[1.0, 1.0],
                           mass=[1.0, 1.0], com=[(0, -0.5, 0), (0, -0.5, 0)], damping=[0.05, 0.05])


def _labels(eq):
    return {e.label: tuple(round(math.degrees(x)) % 360 for x in e.q) for e in eq}


def test_a_chain_upright_at_zero_is_labelled_by_where_its_masses_are():
    eq = equilibria(UPRIGHT)
    assert eq.ok and _labels(eq) == {"up-up": (0, 0), "down-down": (180, 0), "up-down": (0, 180), "down-up": (180, 180)}
    # the labels agree with the energy: up-up the highest (Pi = 0 there, every mass 0.5 m or more above), down-down
    # the lowest, a minimum of V
    assert eq.find("up-up").morse_index == 2 and eq.find("down-down").stable
    # (both arms turned over about the shoulder: arm 1's centre of mass 1 m lower, arm 2's 3 m)
    assert eq.find("down-down").potential == pytest.approx(-9.81 * (1.0 * 1.0 + 1.0 * 3.0), rel=1e-12)


def test_goals_named_by_labels_mean_the_upright_of_a_model_whose_zero_is_upright():
    up = find_equilibrium(UPRIGHT, equilibrium_argument(EVERY_LINK_UP, UPRIGHT))  # control's, MPC's, trajopt's path
    assert np.allclose(up.q, 0.0, atol=1e-12) and up.label == "up-up"
    assert np.allclose(linearization(UPRIGHT, "up-up", (2,)).target, 0.0, atol=1e-12)
    assert np.allclose(find_equilibrium(UPRIGHT, "down-down").q, (math.pi, 0.0), atol=1e-12)


def test_the_dm_control_acrobot_read_from_its_mjcf():
    pytest.importorskip("mujoco")
    path = DATA / "dm_control_acrobot.xml"
    if not path.exists():
        pytest.skip("the acrobot's MJCF is not in tests/data")
    chain = skewpend.read_mjcf(path).chain
    eq = equilibria(chain)
    assert eq.ok and _labels(eq) == {"up-up": (0, 0), "down-down": (180, 0), "up-down": (0, 180), "down-up": (180, 180)}
    assert np.allclose(find_equilibrium(chain, equilibrium_argument(EVERY_LINK_UP, chain)).q, 0.0, atol=1e-12)


def test_the_double_pendulum_and_hanging_chains_keep_their_labels():
    """Their q = 0 hangs: down-down at 0, up-up with rod 1 turned by pi (the thin rods' closed forms), the chain of
    three's one word a link; the rotary pendulum's arm (its centre of mass on its vertical hinge: read by its rod)
    down in each of its rests."""
    eq = equilibria(skewpend.Parameters(a=1.0, b=0.8, m1=1.0, m2=0.7, alpha=0.6, g=9.81))
    assert _labels(eq) == {"down-down": (0, 0), "down-up": (0, 180), "up-down": (180, 180), "up-up": (180, 0)}
    triple = Chain.from_lists(3, length=[0.5, 0.4, 0.3], mass=[1.0, 0.8, 0.5], axis=[(0, 0, 1), (0.5, 0, 1), (1, 0, 0)])
    labels = _labels(equilibria(triple))
    assert labels["down-down-down"] == (0, 0, 0) and labels["up-up-up"] == (180, 0, 0) and len(labels) == 8
    from skewpend.config import Run

    rotary = Run("equilibria", str(Path(__file__).resolve().parent.parent / "examples" / "qube_servo2.toml")).chain()
    assert {e.label for e in equilibria(rotary)} == {"down-down", "down-up"}


def test_link_directions_are_the_centres_of_mass_directions_rotated_independently():
    """At random angles, each link's downward component of (centre of mass - hinge) / |...| equals the one of
    SciPy's rotations (right-handed about each hinge's axis, each in its parent's frame) -- general bodies, an
    offset hinge, a centre of mass off the rod."""
    from scipy.spatial.transform import Rotation

    axes = [(0.0, 0.0, 1.0), (0.6, 0.0, 0.8), (0.0, 0.6, 0.8)]
    coms = [(0.1, 0.3, -0.05), (-0.2, 0.15, 0.1), (0.05, -0.2, 0.0)]
    kw = dict(axis=axes, com=coms, length=[0.6, 0.5, 0.4], mass=[1.0, 0.7, 0.4],
              offset=[(0, 0, 0), (0.05, 0.6, 0.0), (0.0, 0.5, 0.02)])
    chain = Chain.from_lists(3, **kw)
    rng = np.random.default_rng(54)
    for q in rng.uniform(-math.pi, math.pi, (5, 3)):
        R, want = np.eye(3), []
        for qi, e, r in zip(q, axes, coms):
            R = R @ Rotation.from_rotvec(qi * np.asarray(e) / np.linalg.norm(e)).as_matrix()
            want.append((R @ r)[1] / np.linalg.norm(r))
        np.testing.assert_allclose(link_directions(chain, q), want, rtol=1e-12, atol=1e-14)


def test_the_double_pendulum_s_printer_reads_the_same_directions_as_the_chain_s():
    """The double pendulum's labels come from its exact derivation's rotations (SymPy, no CasADi), a chain's from
    the recursive graph: the same directions at random angles, for rods and for general bodies off the rods."""
    from skewpend.analysis.equilibria import _Search

    for p in (skewpend.Parameters(a=1.0, b=0.8, m1=1.0, m2=0.7, alpha=0.6, g=9.81),
              skewpend.Parameters(a=1.0, b=0.8, m1=1.0, m2=0.7, alpha=-1.1, g=9.81, com1=(0.2, 0.3, -0.1),
                                  com2=(-0.1, -0.05, 0.3))):
        search = _Search(p, "a test")
        assert type(search.land).__name__ == "_Exact"  # the exact printer is the one under test
        for q in np.random.default_rng(7).uniform(-math.pi, math.pi, (5, 2)):
            np.testing.assert_allclose(search.land.at(q)[3], link_directions(p.as_chain(), q), rtol=1e-12, atol=1e-14)
