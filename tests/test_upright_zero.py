"""Models whose zero is upright (issue 54): the defaults that assumed q = 0 hangs.

The DeepMind Control Suite's acrobot, read from its MJCF, is upright at q = 0 and hangs at (pi, 0).  Its default
swing-up starts (energy shaping, MPC, the optimal and timed swing-ups) start from that hanging rest; its modes
without ``about`` are the hanging rest's; its last link is drawn where its mass is.  The double pendulum's and
skewpend's chains (q = 0 hangs) keep exactly what they did.
"""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest

from helpers import run_cli

import skewpend
from skewpend.analysis.control import hanging_rest
from skewpend.symbolic.chain import Chain
from skewpend.views.drawing import last_link_sign, link_points

DATA = Path(__file__).resolve().parent / "data"

#: The DeepMind acrobot's geometry (what read_mjcf makes of tests/data/dm_control_acrobot.xml, the thin rods'
#: inertias): two 1 m arms on parallel hinges, each centre of mass 0.5 m ABOVE its hinge at q = 0.
UPRIGHT = Chain.from_lists(2, axis=[(0, 0, 1), (0, 0, 1)], offset=[(0, -2, 0), (0, -1, 0)], length=[1.0, 1.0],
                           mass=[1.0, 1.0], com=[(0, -0.5, 0), (0, -0.5, 0)], damping=[0.05, 0.05])
DOUBLE = skewpend.Parameters(a=1.0, b=0.8, m1=1.0, m2=0.7, alpha=0.4, g=9.81)
HANGING = np.array([math.pi, 0.0, 0.0, 0.0])
NUDGE = np.array([0.05, 0.0, 0.0, 0.0])  # the swing-ups' default nudge at joint 1


def _acrobot():
    path = DATA / "dm_control_acrobot.xml"
    if not path.exists():
        pytest.skip("the acrobot's MJCF is not in tests/data")
    return skewpend.read_mjcf(path).chain


def _rot_k(theta: float) -> np.ndarray:
    c, s = math.cos(theta), math.sin(theta)
    return np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])


# -- the hanging rest ------------------------------------------------------------------------------------------
def test_the_hanging_rest_is_found_from_the_geometry():
    assert np.allclose(hanging_rest(UPRIGHT), HANGING, rtol=0, atol=1e-12)
    assert np.allclose(hanging_rest(_acrobot()), HANGING, rtol=0, atol=1e-12)
    # the double pendulum and a chain of skewpend's own: exactly q = 0 (bit for bit what the defaults were)
    for model in (DOUBLE, DOUBLE.as_chain(), Chain.from_lists(3)):
        rest = hanging_rest(model)
        assert rest.shape == (2 * model.n,) and not np.any(rest)


@pytest.mark.slow
def test_the_hanging_rest_is_at_rest_there():
    # no acceleration at the state returned: a rest of the equations of motion, not of a label
    for model in (UPRIGHT, DOUBLE):
        tr = skewpend.simulate(model, hanging_rest(model), 0.5, dt_out=0.25, rtol=1e-12, atol=1e-12)
        assert np.max(np.abs(tr.y - tr.y[0])) < 1e-9


# -- the default swing-up starts -------------------------------------------------------------------------------
def test_the_energy_shaping_swingup_starts_hanging():
    run = skewpend.swingup(UPRIGHT, actuated=(2,), umax=2.0, t_end=0.02)
    assert np.allclose(run.trajectory.y[0], HANGING + NUDGE, rtol=0, atol=1e-12)
    run = skewpend.swingup(DOUBLE, t_end=0.02)
    assert np.array_equal(run.trajectory.y[0], NUDGE)  # the double pendulum's start unchanged


def test_the_optimal_and_timed_swingups_start_hanging():
    from skewpend.analysis.trajopt import optimal_swingup, timed_swingup

    # the start is a bound of the NLP: the first knot is it whatever the (one) iteration did
    plan = timed_swingup(UPRIGHT, 1.0, umax=2.0, knots=10, attempts=1, max_iter=1)
    assert np.allclose(plan.x[0], HANGING, rtol=0, atol=1e-12)
    plan = optimal_swingup(UPRIGHT, umax=2.0, knots=10, attempts=1, max_iter=1, workers=1)
    assert np.allclose(plan.x[0], HANGING, rtol=0, atol=1e-12)
    plan = timed_swingup(DOUBLE, 1.0, knots=10, attempts=1, max_iter=1)
    assert np.array_equal(plan.x[0], np.zeros(4))


@pytest.mark.slow
def test_the_mpc_swingup_starts_hanging():
    pytest.importorskip("casadi")
    from skewpend.analysis.mpc import mpc_swingup

    run = mpc_swingup(UPRIGHT, actuated=(2,), umax=2.0, t_end=0.02)
    assert np.allclose(run.trajectory.y[0], HANGING + NUDGE, rtol=0, atol=1e-12)


# -- the modes without `about` ---------------------------------------------------------------------------------
def test_modes_of_a_model_upright_at_zero_are_its_hanging_rests():
    modes = skewpend.normal_modes(UPRIGHT)
    assert np.allclose(modes.equilibrium, (math.pi, 0.0), rtol=0, atol=1e-12)
    assert np.array_equal(modes.frequencies, skewpend.normal_modes(UPRIGHT, about="down-down").frequencies)
    # independently: the planar acrobot hanging, in absolute angles (theta1, theta2 = theta1 + q2), has
    # M = [[I1 + m1 c1^2 + m2 l1^2, m2 l1 c2], [m2 l1 c2, I2 + m2 c2^2]], K = g diag(m1 c1 + m2 l1, m2 c2)
    (m1, m2), (c1, c2), l1, g = (1.0, 1.0), (0.5, 0.5), 1.0, 9.81
    I1, I2 = (link.inertia[2][2] for link in UPRIGHT.links)  # about the hinges' common axis k
    M = np.array([[I1 + m1 * c1 ** 2 + m2 * l1 ** 2, m2 * l1 * c2], [m2 * l1 * c2, I2 + m2 * c2 ** 2]])
    K = g * np.diag([m1 * c1 + m2 * l1, m2 * c2])
    T = np.array([[1.0, 0.0], [1.0, 1.0]])  # absolute from relative angles
    from scipy.linalg import eigh

    w = np.sqrt(eigh(T.T @ K @ T, T.T @ M @ T, eigvals_only=True))
    assert np.allclose(modes.frequencies, w, rtol=1e-12, atol=0)
    # the double pendulum's modes are still about q = 0
    assert skewpend.normal_modes(DOUBLE).equilibrium == (0.0, 0.0)


def test_the_modes_command_without_about_takes_the_acrobots_hanging_rest(tmp_path):
    import json

    _acrobot()
    path = str(DATA / "dm_control_acrobot.xml")
    ran = run_cli(["modes", "--config", path, "--format", "json"], cwd=tmp_path)
    assert ran.code == 0, ran.report()
    data = json.loads(ran.out)
    assert data["about"] == "down-down"
    assert np.allclose(data["equilibrium"], (math.pi, 0.0), atol=1e-12)
    about = skewpend.normal_modes(_acrobot(), about="down-down")
    assert np.allclose(data["frequencies"], about.frequencies, rtol=1e-12, atol=0)
    ran = run_cli(["modes", "--config", path], cwd=tmp_path)
    assert ran.code == 0 and ran.out.startswith("Normal modes about the hanging rest (down-down) at phi = 180 deg"), \
        ran.report()
    assert f"{about.frequencies[0]:14.8g}" in ran.out and f"{about.frequencies[1]:14.8g}" in ran.out


# -- the drawn last link ---------------------------------------------------------------------------------------
def test_the_last_link_is_drawn_where_its_centre_of_mass_is():
    rng = np.random.default_rng(54)
    q = rng.uniform(-math.pi, math.pi, (6, 2))
    y = np.hstack([q, np.zeros_like(q)])
    tips = np.array([skewpend.simulate(UPRIGHT, row, 0.01, dt_out=0.01).tips()[0] for row in y])
    points = link_points(UPRIGHT, y, tips)
    assert last_link_sign(UPRIGHT) == -1.0
    com = np.array(UPRIGHT.links[1].com)
    for k, (q1, q2) in enumerate(q):
        rod = points[k, 2] - points[k, 1]  # drawn from hinge 2
        towards = _rot_k(q1 + q2) @ com  # hinge 2 to the centre of mass, in the world
        assert np.allclose(rod, towards / 0.5, rtol=0, atol=1e-12)  # along it, the rod's 1 m
    # hanging, the drawn lower arm points down (j is down)
    hang = skewpend.simulate(UPRIGHT, HANGING, 0.01, dt_out=0.01)
    drawn = link_points(UPRIGHT, hang.y[:1], hang.tips()[:1])[0]
    assert drawn[2, 1] - drawn[1, 1] == pytest.approx(1.0, abs=1e-12)
    # a model whose rods run along +j: drawn to the rods' ends, as before
    tr = skewpend.simulate(DOUBLE, [0.3, -0.4, 0.0, 0.0], 0.01, dt_out=0.01)
    assert last_link_sign(DOUBLE) == 1.0
    assert np.array_equal(link_points(DOUBLE, tr.y, tr.tips())[:, 2], tr.tips()[:, 3:])


def test_the_drawn_lower_arm_ends_at_mujocos_tip_site():
    mujoco = pytest.importorskip("mujoco")
    chain = _acrobot()
    model = mujoco.MjModel.from_xml_path(str(DATA / "dm_control_acrobot.xml"))
    data = mujoco.MjData(model)
    tip = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_SITE, "tip")
    rng = np.random.default_rng(7)
    for q in rng.uniform(-math.pi, math.pi, (5, 2)):
        data.qpos[:] = q
        mujoco.mj_forward(model, data)
        x, y, z = data.site_xpos[tip]
        tr = skewpend.simulate(chain, np.r_[q, 0.0, 0.0], 0.01, dt_out=0.01)
        drawn = link_points(chain, tr.y[:1], tr.tips()[:1])[0, 2]
        assert np.allclose(drawn, (x, -z, y), rtol=0, atol=1e-12)  # MuJoCo's z up is skewpend's -y


def test_a_replay_in_the_browser_draws_the_lower_arm_where_the_pictures_do():
    """What the browser's replays draw from (``frontend.replay_data``: the report's live view, the widget's run): the
    hinges and the last rod's end are :func:`link_points`' -- for this model the lower arm's end mirrored at the
    elbow (the rod's ``+j`` end is 2 m away from it), for the double pendulum the rod's end, unchanged."""
    from skewpend.views.frontend import replay_data

    for model, y0, mirrored in ((UPRIGHT, [0.4, -0.7, 1.0, 0.0], True), (DOUBLE, [0.3, -0.4, 0.0, 0.0], False)):
        tr = skewpend.simulate(model, y0, 0.5, dt_out=0.1)
        data = replay_data(tr)
        points = link_points(model, tr.y, tr.tips())
        np.testing.assert_array_equal(np.array(data["hinges"]), points[:, :2].reshape(-1, 6))
        np.testing.assert_array_equal(np.array(data["tips"])[:, 3:], points[:, 2])
        np.testing.assert_array_equal(np.array(data["tips"])[:, :3], tr.tips()[:, :3])
        apart = np.linalg.norm(np.array(data["tips"])[:, 3:] - tr.tips()[:, 3:], axis=1)
        assert (apart.min() > 1.0) if mirrored else (apart.max() == 0.0)


def test_the_animation_frames_the_arms_above_their_shoulder_2_m_over_the_roof():
    """Read from its MJCF, the acrobot's shoulder is 2 m above its world's origin (the roof of skewpend's views):
    nothing of it hangs below the roof (:func:`drawn_depth` 0, not its 4 m reach), the view looks at the 2 m ball
    the arms move in about the shoulder (:func:`drawn_frame`), and every drawn point of a frame -- upright and
    hanging -- is inside the picture (the framing of a chain hanging from the roof put the arms at its top edge)."""
    from mpl_toolkits.mplot3d import proj3d

    from skewpend.interop.importer import read_mjcf
    from skewpend.views.animation import FrameRenderer, world_to_plot
    from skewpend.views.drawing import drawn_depth, drawn_frame

    chain = read_mjcf(DATA / "dm_control_acrobot.xml").chain
    assert drawn_depth(chain) == 0.0 and drawn_frame(chain) == ([0.0, -2.0, 0.0], 2.0)
    assert drawn_frame(DOUBLE) is None  # hinge 1 at the roof: the views' framing as before
    tr = skewpend.simulate(chain, [0.1, 0.2, 0.0, 0.0], 3.0, dt_out=0.25)  # from near upright it falls and swings
    renderer = FrameRenderer(tr, size=(480, 360))
    try:
        assert renderer.floor < 0.0  # below the roof
        renderer.draw(0)
        assert 4.0 * renderer.pixels_per_metre > 0.55 * 360  # the 2 m ball about the shoulder fills the picture's height
        for k in range(tr.t.size):
            sc = renderer.draw(k)
            px, py, _ = proj3d.proj_transform(*world_to_plot(sc.rods).T, renderer.ax.get_proj())
            x, y = renderer.ax.transData.transform(np.column_stack([px, py])).T
            assert np.all((x > 0) & (x < 480) & (y > 0) & (y < 360)), (k, x, y)
    finally:
        renderer.close()
