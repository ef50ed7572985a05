"""The rotary (Furuta) pendulum drawn as it is (issue 54, item 4: "the explorer and report show it"):
``examples/qube_servo2.toml``'s arm turns about the vertical and runs along its body's ``i`` (its pendulum's
hinge at ``(Lr, 0, 0)``, not at the end of a rod along ``j``).  Every view draws each link from its hinge to the
next link's hinge (the last to its rod's end), from the model's generated kinematics
(:func:`skewpend.views.drawing.link_points`): the drawn arm is horizontal, its end ``Lr`` from the vertical
axis, the pendulum ``Lp`` long from there -- checked against the geometry composed here by hand (Rodrigues'
formula), in the frame's 3-D scene and in its pixels."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from skewpend.config import Run

ROOT = Path(__file__).resolve().parents[1]
RUN_FILE = ROOT / "examples" / "qube_servo2.toml"
Lr, Lp = 0.085, 0.129
FPS = 15


def _rodrigues(theta: float, n) -> np.ndarray:
    n = np.asarray(n, dtype=float) / np.linalg.norm(n)
    K = np.array([[0, -n[2], n[1]], [n[2], 0, -n[0]], [-n[1], n[0], 0]])
    return np.eye(3) + np.sin(theta) * K + (1 - np.cos(theta)) * K @ K


@pytest.fixture(scope="module")
def clip():
    import skewpend

    chain = Run("animate", str(RUN_FILE)).chain()
    # the arm turning (a push on joint 1) while the pendulum swings: every frame a different pose
    return chain, skewpend.simulate(chain, [0.3, 0.9, 4.0, 0.0], 1.0, dt_out=1 / FPS, method="dop853")


def test_every_frame_draws_the_arm_horizontal_and_the_pendulum_from_its_end(clip):
    """In every frame: hinge 1 at the origin; the arm's drawn end (hinge 2) at the height of hinge 1 and ``Lr`` from
    the vertical axis, turned by ``q1`` about it (the hand-composed ``P(q1, -j) (Lr, 0, 0)``); the pendulum from
    there to its rod's end ``Lp`` away, the trajectory's own tip; hinge 2's axis drawn there, along the arm."""
    from skewpend.views.animation import frame_scene

    chain, tr = clip
    assert tr.t.size == 16
    arm_angles = []
    for k in range(tr.t.size):
        sc = frame_scene(tr, k)
        q1, q2 = tr.y[k, :2]
        R1 = _rodrigues(q1, (0, -1, 0))
        np.testing.assert_allclose(sc.rods[0], 0.0, atol=1e-15)
        np.testing.assert_allclose(sc.rods[1], R1 @ np.array([Lr, 0.0, 0.0]), rtol=0, atol=1e-15)
        assert abs(sc.rods[1][1]) < 1e-15  # horizontal: j is the vertical
        assert np.hypot(sc.rods[1][0], sc.rods[1][2]) == pytest.approx(Lr, rel=1e-14)
        tip = sc.rods[1] + R1 @ _rodrigues(q2, (1, 0, 0)) @ np.array([0.0, Lp, 0.0])
        np.testing.assert_allclose(sc.rods[2], tip, rtol=0, atol=1e-14)
        np.testing.assert_allclose(sc.rods[2], tr.tips()[k, 3:6], rtol=0, atol=1e-14)
        np.testing.assert_allclose(sc.axis_centers, sc.rods[:2], rtol=0, atol=0)
        np.testing.assert_allclose(sc.axis_directions[1], sc.rods[1] / Lr, rtol=0, atol=1e-12)
        arm_angles.append(np.arctan2(sc.rods[1][2], sc.rods[1][0]))
    assert np.ptp(np.unwrap(arm_angles)) > 1.0  # the arm swept over a radian: the frames differ


def test_the_rendered_frame_shows_the_arm_and_the_pendulum_where_the_scene_puts_them(clip):
    """The pixels: along the arm's projection (hinge 1 to hinge 2, away from the pins) the arm's colour, along the
    pendulum's (hinge 2 to its tip) the pendulum's; the pendulum hangs down the screen from the arm's end; the
    drawing fills the frame (the reach is the rig's 0.214 m, not a metre)."""
    from mpl_toolkits.mplot3d import proj3d

    from skewpend.views.animation import FrameRenderer, world_to_plot
    from skewpend.views.animation.scene import rod_color

    chain, tr = clip
    renderer = FrameRenderer(tr, size=(480, 360))
    try:
        k = int(np.argmin(np.abs(tr.y[:, 1])))  # the pendulum nearest hanging
        sc = renderer.draw(k)
        image = renderer.rgb().astype(float)
        H = image.shape[0]
        pts = world_to_plot(sc.rods)
        px, py, _ = proj3d.proj_transform(*pts.T, renderer.ax.get_proj())
        screen = renderer.ax.transData.transform(np.column_stack([px, py]))
        scale, elev = renderer.pixels_per_metre, np.radians(renderer.view[0])
        # an orthographic camera elev above the horizon: a vertical segment shows cos(elev) of its length, a
        # horizontal one at least sin(elev); the pendulum hangs within 0.05 rad, so its drop is nearly all of it
        assert abs(tr.y[k, 1]) < 0.05 and renderer.view == (30.0, -58.0)
        drop = screen[1, 1] - screen[2, 1]
        assert 0.95 * Lp * scale * np.cos(elev) < drop < 1.05 * Lp * scale * np.cos(elev), drop
        assert np.linalg.norm(screen[1] - screen[0]) >= 0.99 * Lr * scale * np.sin(elev)
        assert Lp * scale > 0.2 * H  # the rig fills the frame: its scale is its own 0.214 m reach

        def hue_at(a, b, s):
            x, y = a + s * (b - a)
            row, col = int(round(H - y)), int(round(x))
            patch = image[row - 3:row + 4, col - 3:col + 4].reshape(-1, 3)  # the rod's 7.7 px width about its axis
            return patch / np.linalg.norm(patch, axis=1)[:, None]

        # the pins sit at the hinges; hinge 2's axis line (2.8 px) runs along the arm's middle from its end (0.3 of
        # the reach either side: over 0.25-1 of the arm), the arm's colour beside it
        for i, (a, b, where) in enumerate(((screen[0], screen[1], (0.2, 0.5)), (screen[1], screen[2], (0.55, 0.7)))):
            base = np.array(rod_color(i)) / np.linalg.norm(rod_color(i))
            for s in where:
                assert np.max(hue_at(a, b, s) @ base) > 0.995, f"rod {i + 1}'s colour not at {s} of its projection"
    finally:
        renderer.close()


def test_animate_draws_the_rig_from_its_run_file(tmp_path):
    """``skewpend animate --config examples/qube_servo2.toml`` writes the GIF (exit 0, one frame per row), the
    motor's note said once."""
    from PIL import Image

    from helpers import run_cli

    out = tmp_path / "qube.gif"
    ran = run_cli(["animate", "--config", RUN_FILE, "--out", out, "--t-end", "0.4", "--fps", "10", "--size", "240x180"])
    assert ran.code == 0, ran.report()
    assert sum("[motor] on joint 1" in line for line in ran.err.splitlines()) == 1, ran.report()
    with Image.open(out) as im:
        assert im.n_frames == 5 and im.size == (240, 180)


def test_the_widget_and_the_explorer_page_carry_the_rigs_reach_and_hinges():
    """The browser views get what they draw from: the page's and the widget's reach (the drawn reach, |offset| of
    the pendulum's hinge + its length: a rig under scene.js's 0.9 m is magnified), the JavaScript physics' hinges
    (the same graph as :func:`~skewpend.numeric.recursive.hinge_positions`)."""
    pytest.importorskip("anywidget")
    from skewpend.numeric.explorer_source import explorer_js
    from skewpend.views.frontend import page_settings
    from skewpend.views.widget import PendulumWidget

    chain = Run("serve", str(RUN_FILE)).chain()
    assert page_settings(chain)["reach"] == pytest.approx(Lr + Lp, rel=1e-15)
    assert PendulumWidget(chain).reach == pytest.approx(Lr + Lp, rel=1e-15)
    assert "export function hinges(q, p = P)" in explorer_js(chain)
    assert page_settings()["reach"] == pytest.approx(1.8, rel=1e-15)  # the double pendulum's a + b: drawn at its size


@pytest.mark.slow
def test_the_report_of_the_rig_is_written_with_its_arm_drawn_horizontal(tmp_path):
    """``skewpend report --config examples/qube_servo2.toml`` (refused before): exit 0, the motor's note once; its
    live view's frames (the JSON the page replays) put the pendulum's hinge at the arm's end, at hinge 1's height
    and ``Lr`` from the vertical axis, the tip ``Lp`` from there; its pictures are embedded."""
    import json
    import re

    from helpers import run_cli

    out = tmp_path / "qube.html"
    ran = run_cli(["report", "--config", RUN_FILE, "--out", out])
    assert ran.code == 0, ran.report()
    assert sum("[motor] on joint 1" in line for line in ran.err.splitlines()) == 1, ran.report()
    page = out.read_text(encoding="utf-8")
    data = json.loads(re.search(r'<script type="application/json" class="live-data">(.*?)</script>', page, re.S).group(1))
    hinges, tips = np.array(data["hinges"]), np.array(data["tips"])
    assert hinges.shape == tips.shape and hinges.shape[0] > 100 and data["reach"] == pytest.approx(Lr + Lp)
    np.testing.assert_allclose(hinges[:, :3], 0.0, atol=1e-15)
    arm = hinges[:, 3:6]
    np.testing.assert_allclose(arm[:, 1], 0.0, atol=1e-15)
    np.testing.assert_allclose(np.hypot(arm[:, 0], arm[:, 2]), Lr, rtol=1e-14)
    np.testing.assert_allclose(np.linalg.norm(tips[:, 3:6] - arm, axis=1), Lp, rtol=1e-12)
    assert len(re.findall(r'<img[^>]*src="data:image/png', page)) >= 8
