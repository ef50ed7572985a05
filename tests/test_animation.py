"""3-D animation (skewpend.views.animation): written MP4/GIF decoded back, the drawn hinge axes
checked against P1 . e0 computed here by Rodrigues' formula (3-D data and its projection), refusals
that leave no file."""

from __future__ import annotations

import math

import numpy as np
import pytest

import skewpend
from skewpend.views.animation import (
    DEFAULT_VIEW,
    FrameRenderer,
    eye,
    animate,
    choose_view,
    frame_scene,
    plot_to_world,
    world_to_plot,
)

from skewpend.config import reference_parameters  # noqa: E402
BENCH = reference_parameters()  # the reference case: a = 1, b = 0.8, m1 = 1, m2 = 0.7, alpha = 0.6, g = 9.81
Y0 = (1.2, -0.8, 0.0, 0.0)
FPS, SPEED = 12.0, 1.0
SIZE = (240, 180)


@pytest.fixture(scope="module")
def clip():
    """1 s of motion at 12 frames per second: 13 rows exactly at k / 12 s."""
    return skewpend.simulate(BENCH, Y0, 1.0 * SPEED, dt_out=SPEED / FPS)


def _rodrigues(theta: float, n) -> np.ndarray:
    """P(theta, n) = n n + (E - n n) cos theta + n x E sin theta, written out here on purpose."""
    n = np.asarray(n, dtype=float)
    nn = np.outer(n, n)
    cross = np.array([[0.0, -n[2], n[1]], [n[2], 0.0, -n[0]], [-n[1], n[0], 0.0]])
    return nn + (np.eye(3) - nn) * math.cos(theta) + cross * math.sin(theta)


def _files(directory):
    return sorted(p.name for p in directory.iterdir())


def _assert_frames_differ(frames):
    frames = [f.astype(np.int16) for f in frames]
    for k in range(1, len(frames)):
        assert np.abs(frames[k] - frames[k - 1]).sum() > 0, f"frames {k - 1} and {k} are identical"
    assert np.abs(frames[-1] - frames[0]).mean() > 0.5, "the first and last frames hardly differ"


# ---------------------------------------------------------------------------------------------
# written files, decoded


def test_mp4_has_one_frame_per_row_of_the_requested_size(clip, tmp_path):
    imageio_ffmpeg = pytest.importorskip("imageio_ffmpeg")
    calls = []
    out = animate(clip, tmp_path / "motion.mp4", fps=FPS, speed=SPEED, size=SIZE, progress=lambda d, t: calls.append((d, t)))
    assert out == tmp_path / "motion.mp4" and _files(tmp_path) == ["motion.mp4"]  # no temporary file left
    n = clip.t.size
    assert calls == [(k, n) for k in range(1, n + 1)]
    reader = imageio_ffmpeg.read_frames(str(out), pix_fmt="rgb24")
    meta = next(reader)
    assert tuple(meta["size"]) == SIZE
    assert meta["fps"] == pytest.approx(FPS)
    w, h = SIZE
    frames = [np.frombuffer(b, dtype=np.uint8).reshape(h, w, 3) for b in reader]
    assert len(frames) == n
    _assert_frames_differ(frames)


def test_gif_has_one_frame_per_row_its_size_and_timing(clip, tmp_path):
    from PIL import Image

    fps = 10.0  # GIF stores hundredths of a second: 100 ms per frame exactly
    tr = skewpend.simulate(BENCH, Y0, 1.0, dt_out=1.0 / fps)
    out = animate(tr, tmp_path / "motion.gif", fps=fps, size=(200, 150))
    assert _files(tmp_path) == ["motion.gif"]
    with Image.open(out) as im:
        assert im.format == "GIF" and im.size == (200, 150)
        assert im.n_frames == tr.t.size
        assert im.info.get("loop") == 0
        frames = []
        for k in range(im.n_frames):
            im.seek(k)
            assert im.info["duration"] == 100
            frames.append(np.asarray(im.convert("RGB")))
    assert frames[0].shape == (150, 200, 3)
    _assert_frames_differ(frames)


# ---------------------------------------------------------------------------------------------
# the drawn geometry


def test_drawn_second_hinge_axis_is_P1_e0(clip):
    """At a sampled frame the second hinge axis as drawn -- the artist's 3-D data and its
    projection on screen -- is tip1 +/- h P1 . e0, with P1 = P(phi, k) and e0 = (sin a, 0, cos a)
    computed here; the first axis is k at the origin."""
    from mpl_toolkits.mplot3d import proj3d

    n = clip.t.size
    k = n // 2
    renderer = FrameRenderer(clip, size=(320, 240))
    scene = renderer.draw(k)
    assert scene.k == k and scene.t == clip.t[k]

    phi, alpha, a = clip.y[k, 0], BENCH.alpha, BENCH.a
    P1 = _rodrigues(phi, [0.0, 0.0, 1.0])
    e_ref = P1 @ np.array([math.sin(alpha), 0.0, math.cos(alpha)])
    tip1_ref = P1 @ np.array([0.0, a, 0.0])  # thin rods: rod 1 ends at a j
    assert e_ref[2] == pytest.approx(math.cos(alpha), abs=1e-15)  # e stays on the cone about k

    # the scene: 3-D data in world coordinates
    np.testing.assert_allclose(scene.axis_directions[1], e_ref, rtol=0, atol=1e-12)
    np.testing.assert_allclose(scene.axis_centers[1], tip1_ref, rtol=0, atol=1e-12)
    np.testing.assert_array_equal(scene.axis_directions, clip.axes()[k].reshape(2, 3))
    np.testing.assert_array_equal(scene.rods[1:], clip.tips()[k].reshape(2, 3))
    np.testing.assert_array_equal(scene.axis_centers[0], [0.0, 0.0, 0.0])
    np.testing.assert_allclose(scene.axis_directions[0], [0.0, 0.0, 1.0], rtol=0, atol=1e-15)

    h = scene.axis_half_length
    for i, (centre, direction, name) in enumerate(
        ((np.zeros(3), np.array([0.0, 0.0, 1.0]), "axis1"), (tip1_ref, e_ref, "axis2"))
    ):
        expected_world = np.array([centre - h * direction, centre + h * direction])
        np.testing.assert_allclose(scene.axis_segment(i), expected_world, rtol=0, atol=1e-12)
        line = renderer.artists[name]
        drawn = np.array(line.get_data_3d()).T  # plot coordinates, as handed to Matplotlib
        np.testing.assert_allclose(plot_to_world(drawn), expected_world, rtol=0, atol=1e-12)

        # project: the 2-D data the renderer drew equals the projection of the independent segment
        M = renderer.ax.get_proj()
        xs, ys, _ = proj3d.proj_transform(*world_to_plot(expected_world).T, M)
        x2d, y2d = (np.asarray(v, dtype=float) for v in line.get_data())
        np.testing.assert_allclose(x2d, xs, rtol=0, atol=1e-9)
        np.testing.assert_allclose(y2d, ys, rtol=0, atol=1e-9)
        xd, yd, _ = proj3d.proj_transform(*drawn.T, M)
        np.testing.assert_allclose(np.column_stack([xd, yd]), np.column_stack([xs, ys]), rtol=0, atol=1e-9)

    # and the pixels: the second axis's colour is on screen where its projection says
    line = renderer.artists["axis2"]
    display = line.get_transform().transform(np.column_stack(line.get_data()))
    image = renderer.rgb()
    from matplotlib.colors import to_rgb

    colour = np.array(to_rgb(line.get_color())) * 255
    H = image.shape[0]
    for s in (0.15, 0.3):  # on the minus half, away from arrow head, labels and the arc
        x, y = display[0] + s * (display[1] - display[0])
        row, col = int(round(H - y)), int(round(x))
        patch = image[row - 1 : row + 2, col - 1 : col + 2].reshape(-1, 3).astype(float)
        assert np.min(np.linalg.norm(patch - colour, axis=1)) < 40, f"axis colour not found at ({col}, {row})"

    # the pendulum hangs down the screen: rod 2's end is drawn below the pivot
    pts = world_to_plot(np.array([[0.0, 0.0, 0.0], scene.rods[2]]))
    px, py, _ = proj3d.proj_transform(*pts.T, renderer.ax.get_proj())
    screen = renderer.ax.transData.transform(np.column_stack([px, py]))
    assert scene.rods[2][1] > 0 and screen[1, 1] < screen[0, 1]
    renderer.close()


def test_frame_scene_trail_and_skew_arc(clip):
    k = clip.t.size - 1
    sc = frame_scene(clip, k, trail=0.5)
    tips = clip.tips()
    np.testing.assert_array_equal(sc.rods, [[0.0, 0.0, 0.0], tips[k, 0:3], tips[k, 3:6]])
    first = int(np.searchsorted(clip.t, clip.t[k] - 0.5 - 1e-12))
    np.testing.assert_array_equal(sc.trail, tips[first : k + 1, 3:6])
    assert sc.trail_alpha.shape == (sc.trail.shape[0] - 1,) and np.all(np.diff(sc.trail_alpha) > 0)
    # the arc at the second hinge runs from n1 to e: the skew angle alpha
    radius = np.linalg.norm(sc.skew_arc[0] - sc.axis_centers[1])
    np.testing.assert_allclose((sc.skew_arc[0] - sc.axis_centers[1]) / radius, sc.axis_directions[0], atol=1e-12)
    np.testing.assert_allclose((sc.skew_arc[-1] - sc.axis_centers[1]) / radius, sc.axis_directions[1], atol=1e-12)
    assert math.acos(np.dot(sc.axis_directions[0], sc.axis_directions[1])) == pytest.approx(BENCH.alpha, abs=1e-12)
    assert frame_scene(clip, 0, trail=0).trail.shape == (1, 3)


def test_camera_does_not_look_along_a_hinge_axis():
    for alpha in np.linspace(0.0, math.pi, 13):
        e0 = np.array([math.sin(alpha), 0.0, math.cos(alpha)])
        elev, azim = choose_view([0.0, 0.0, 1.0], e0)
        assert (elev, azim) == DEFAULT_VIEW
        seen_from = plot_to_world(eye(elev, azim))
        for axis in (np.array([0.0, 0.0, 1.0]), e0):
            assert math.degrees(math.acos(abs(seen_from @ axis))) >= 30.0 - 1e-9
    # a first axis along the default line of sight gets another view
    n1 = plot_to_world(eye(*DEFAULT_VIEW))
    elev, azim = choose_view(n1, [0.0, 0.0, 1.0])
    assert math.degrees(math.acos(abs(plot_to_world(eye(elev, azim)) @ n1))) >= 30.0


# ---------------------------------------------------------------------------------------------
# refusals: nothing written


@pytest.mark.parametrize("name", ["motion.avi", "motion", "motion.mp4.txt"])
def test_bad_suffix_is_refused_and_no_file_is_left(clip, tmp_path, name):
    with pytest.raises(skewpend.ParameterError, match=r"\.mp4 or \.gif"):
        animate(clip, tmp_path / name, fps=FPS, size=SIZE)
    assert _files(tmp_path) == []


def test_trajectory_off_the_frame_grid_is_refused(clip, tmp_path):
    with pytest.raises(skewpend.ParameterError, match="dt_out=speed/fps"):
        animate(clip, tmp_path / "m.gif", fps=FPS, speed=2.0, size=SIZE)  # frames every 1/6 s wanted
    own_steps = skewpend.simulate(BENCH, Y0, 0.5)  # the integrator's own steps
    with pytest.raises(skewpend.ParameterError, match=r"t\[1\]"):
        animate(own_steps, tmp_path / "m.gif", fps=FPS, size=SIZE)
    assert _files(tmp_path) == []


def test_other_bad_arguments_are_refused(clip, tmp_path):
    with pytest.raises(skewpend.ParameterError, match="even width and height"):
        animate(clip, tmp_path / "m.mp4", fps=FPS, size=(241, 180))
    for kwargs in ({"fps": 0}, {"speed": -1}, {"size": (10, 10)}, {"trail": -1}, {"progress": 3}):
        with pytest.raises(skewpend.ParameterError):
            animate(clip, tmp_path / "m.gif", **{"fps": FPS, "size": SIZE, **kwargs})
    assert _files(tmp_path) == []


@pytest.mark.parametrize("suffix", [".gif", ".mp4"])
def test_interrupt_removes_the_temporary_file(clip, tmp_path, suffix):
    if suffix == ".mp4":
        pytest.importorskip("imageio_ffmpeg")

    def progress(done, total):
        if done == 3:
            raise KeyboardInterrupt

    with pytest.raises(KeyboardInterrupt):
        animate(clip, tmp_path / f"m{suffix}", fps=FPS, size=SIZE, progress=progress)
    assert _files(tmp_path) == []


def test_missing_imageio_ffmpeg_gives_an_install_hint(clip, tmp_path, monkeypatch):
    import sys

    monkeypatch.setitem(sys.modules, "imageio_ffmpeg", None)  # import fails
    with pytest.raises(skewpend.SkewpendError, match="pip install imageio-ffmpeg"):
        animate(clip, tmp_path / "m.mp4", fps=FPS, size=SIZE)
    assert _files(tmp_path) == []


# ---------------------------------------------------------------------------------------------
# a chain of links: N rods


def _chain_clip():
    from skewpend.symbolic.chain import Chain

    chain = Chain.from_lists(3, axis=[(0, 0, 1), (1, 0, 2), (1, 0, 0)], length=[0.5, 0.4, 0.3], mass=[1, 0.8, 0.5])
    return chain, skewpend.simulate(chain, [1.0, -0.3, 0.2, 0, 0, 0], 1.0, dt_out=1 / FPS)


def test_a_chains_frame_draws_every_rod_and_hinge_axis():
    """Three skewed links: the scene's rods end where the rotation tensors composed here put them
    (R_k = R_(k-1) P(q_k, e_k), rod k's end o_k + R_k l_k j), each hinge axis is R_(k-1) e_k at the rod
    before's end, and every rod's colour is on screen."""
    chain, clip = _chain_clip()
    k = clip.t.size // 2
    renderer = FrameRenderer(clip, size=(320, 240))
    sc = renderer.draw(k)
    R, o = np.eye(3), np.zeros(3)
    for i, link in enumerate(chain.links):
        axis = np.asarray(link.axis)
        np.testing.assert_allclose(sc.axis_directions[i], R @ axis, rtol=0, atol=1e-12)
        np.testing.assert_allclose(sc.axis_centers[i], o, rtol=0, atol=1e-12)
        R = R @ _rodrigues(clip.y[k, i], axis)
        o = o + R @ np.array([0.0, link.length, 0.0])
        np.testing.assert_allclose(sc.rods[i + 1], o, rtol=0, atol=1e-12)
    assert sc.rods.shape == (4, 3) and len(sc.skew_arcs) == 2 and sc.q == tuple(clip.y[k, :3])
    for i in range(1, 3):  # each arc spans the angle between consecutive axes
        arc, c = sc.skew_arcs[i - 1], sc.axis_centers[i]
        ends = [(arc[j] - c) / np.linalg.norm(arc[j] - c) for j in (0, -1)]
        np.testing.assert_allclose(ends[0], sc.axis_directions[i - 1], atol=1e-12)
        np.testing.assert_allclose(ends[1], sc.axis_directions[i], atol=1e-12)
    image = renderer.rgb().reshape(-1, 3).astype(float)
    from skewpend.views.animation.scene import rod_color

    # the rods are shaded (ambient + Lambert: the base colour scaled) -- look for its hue, not its value
    dark = image[(image.max(axis=1) > 40) & (image.min(axis=1) < 200)]
    hue = dark / np.linalg.norm(dark, axis=1)[:, None]
    for i in range(3):
        base = np.array(rod_color(i)) / np.linalg.norm(rod_color(i))
        assert np.count_nonzero(hue @ base > 0.999) >= 10, f"rod {i + 1}'s colour is not on screen"
    assert image.std() > 20 and [renderer.artists[f"axis{i}"].get_visible() for i in (1, 2, 3)] == [True] * 3
    renderer.close()


def test_a_chain_animates_to_a_gif_and_draws_a_hinge_off_the_rod_end_where_it_is(tmp_path):
    """A hinge off the end of the rod before is drawn where the model has it: link 2 from its hinge to link 3's
    hinge at ``o_2 + R_2 (0.05, 0.4, 0)`` (the rotation tensors composed here), link 3 from there to its rod's
    end; the hinge axis at that hinge."""
    from PIL import Image

    chain, clip = _chain_clip()
    out = animate(clip, tmp_path / "chain.gif", fps=FPS, speed=SPEED, size=SIZE)
    with Image.open(out) as im:
        assert im.n_frames == clip.t.size and im.size == SIZE
    moved = chain.replace_link(3, offset=(0.05, 0.4, 0.0))
    clip2 = skewpend.simulate(moved, [1.0, -0.3, 0.2, 0, 0, 0], 1.0, dt_out=1 / FPS)
    k = clip2.t.size - 1
    sc = frame_scene(clip2, k)
    R, o = np.eye(3), np.zeros(3)
    for i, link in enumerate(moved.links):
        o = o + R @ np.asarray(link.offset, dtype=float)
        np.testing.assert_allclose(sc.rods[i], o, rtol=0, atol=1e-12)
        np.testing.assert_allclose(sc.axis_centers[i], o, rtol=0, atol=1e-12)
        R = R @ _rodrigues(clip2.y[k, i], np.asarray(link.axis))
    np.testing.assert_allclose(sc.rods[3], o + R @ np.array([0.0, 0.3, 0.0]), rtol=0, atol=1e-12)
    np.testing.assert_allclose(sc.rods[3], clip2.tips()[k, 6:9], rtol=0, atol=1e-12)
    assert np.linalg.norm(sc.rods[2] - clip2.tips()[k, 3:6]) == pytest.approx(0.05, abs=1e-12)  # not rod 2's end
    animate(clip2, tmp_path / "moved.gif", fps=FPS, speed=SPEED, size=SIZE)
    assert _files(tmp_path) == ["chain.gif", "moved.gif"]
