"""The figures layer (skewpend.views.figures): what the figures DRAW -- the data of their
lines equals the trajectory's arrays in the documented units, every axis has a unit, the
heading states the parameters and settings, the torus path never jumps across the square,
the energy error is on a log axis -- and save_figure writes PNG/SVG/PDF atomically."""

from __future__ import annotations

import io
import math
import re
import subprocess
import sys

import numpy as np
import pytest

pytest.importorskip("matplotlib")

import skewpend  # noqa: E402
from helpers import general_body  # noqa: E402
from skewpend.views import figures as F  # noqa: E402

PARAMS = skewpend.Parameters(a=1.0, b=0.8, m1=1.0, m2=0.7, alpha=0.6, g=9.81)
Y0 = (1.2, -0.8, 0.0, 0.0)
TRAJECTORY_FIGURES = ["angles_figure", "phase_figure", "energy_figure", "torus_figure", "tips_figure", "simulation_figure"]


@pytest.fixture(scope="module")
def tr():
    return skewpend.simulate(PARAMS, Y0, 5.0, dt_out=0.01)


@pytest.fixture(scope="module")
def spin():
    """A seeded, fast motion: hinge 1 goes over the top several times (the torus wraps often)."""
    rng = np.random.default_rng(20240607)
    y0 = (rng.uniform(-1, 1), rng.uniform(-1, 1), 9.0 + rng.uniform(0, 1), -7.0 - rng.uniform(0, 1))
    return skewpend.simulate(PARAMS, y0, 5.0, dt_out=0.01)


def _wrapped_deg(x):
    return np.degrees(np.pi - np.mod(np.pi - np.asarray(x), 2 * np.pi))


def _heading(fig) -> str:
    return "\n".join(t.get_text() for t in fig.texts)


def _interior(x, y):
    """Drop NaN breaks and the crossing points added on the edges (+-180 deg) of a wrapped path."""
    x, y = np.asarray(x, float), np.asarray(y, float)
    keep = np.isfinite(x) & np.isfinite(y) & (np.abs(x) < 180 - 1e-9) & (np.abs(y) < 180 - 1e-9)
    return x[keep], y[keep]


# -- what is drawn ------------------------------------------------------------------------------------
def test_angles_figure_draws_unwrapped_degrees_and_speeds(tr):
    fig = F.angles_figure(tr)
    top, bottom = fig.axes
    np.testing.assert_array_equal(top.lines[0].get_xdata(), tr.t)
    np.testing.assert_allclose(top.lines[0].get_ydata(), np.degrees(np.unwrap(tr.y[:, 0])), rtol=1e-15)
    np.testing.assert_allclose(top.lines[1].get_ydata(), np.degrees(np.unwrap(tr.y[:, 1])), rtol=1e-15)
    np.testing.assert_array_equal(bottom.lines[0].get_ydata(), tr.y[:, 2])
    np.testing.assert_array_equal(bottom.lines[1].get_ydata(), tr.y[:, 3])
    assert "[deg]" in top.get_ylabel() and "[rad/s]" in bottom.get_ylabel() and "[s]" in bottom.get_xlabel()
    # psi goes over the top in this run: the curve is continuous, not wrapped
    assert np.max(np.abs(np.diff(top.lines[1].get_ydata()))) < 30
    assert np.ptp(top.lines[1].get_ydata()) > 180


def test_phase_figure_draws_wrapped_angle_against_speed(tr):
    fig = F.phase_figure(tr)
    for k, ax in enumerate(fig.axes):
        x, y = _interior(ax.lines[0].get_xdata(), ax.lines[0].get_ydata())
        np.testing.assert_allclose(x, _wrapped_deg(tr.y[:, k]), atol=1e-12)
        np.testing.assert_array_equal(y, tr.y[:, k + 2])
        assert "[deg]" in ax.get_xlabel() and "[rad/s]" in ax.get_ylabel()
    # hinge 2 wraps: the line is cut there, on the edges
    xs = np.asarray(fig.axes[1].lines[0].get_xdata(), float)
    assert np.isnan(xs).any()
    finite = np.isfinite(xs)
    assert np.all(np.abs(np.diff(xs)[finite[1:] & finite[:-1]]) < 90)


@pytest.mark.parametrize("which", ["tr", "spin"])
def test_torus_figure_never_jumps_across_the_square(which, request):
    traj = request.getfixturevalue(which)
    fig = F.torus_figure(traj)
    ax = fig.axes[0]
    x, y = (np.asarray(v, float) for v in ax.lines[0].get_data())
    assert np.isnan(x).any(), "this run wraps: the path must be broken with NaN"
    assert np.nanmax(np.abs(x)) <= 180 + 1e-9 and np.nanmax(np.abs(y)) <= 180 + 1e-9
    finite = np.isfinite(x) & np.isfinite(y)
    both = finite[1:] & finite[:-1]
    assert np.all(np.abs(np.diff(x))[both] < 180) and np.all(np.abs(np.diff(y))[both] < 180)
    # every row of the trajectory is on the path, in order
    xi, yi = _interior(x, y)
    np.testing.assert_allclose(xi, _wrapped_deg(traj.y[:, 0]), atol=1e-12)
    np.testing.assert_allclose(yi, _wrapped_deg(traj.y[:, 1]), atol=1e-12)
    assert ax.get_xlim() == (-180, 180) and ax.get_ylim() == (-180, 180)
    assert "[deg]" in ax.get_xlabel() and "[deg]" in ax.get_ylabel()


def test_wrapped_path_cuts_at_the_edges_seeded_random_walk():
    rng = np.random.default_rng(7)
    u = np.cumsum(rng.normal(0, 0.8, size=(400, 2)), axis=0)  # big steps: many wraps, some in both at once
    path = F.wrapped_path([u[:, 0], u[:, 1]], [True, True])
    finite = np.all(np.isfinite(path), axis=1)
    assert np.all(np.abs(path[finite]) <= np.pi + 1e-12)
    assert (~finite).sum() >= 10  # it did wrap, many times
    # no drawn segment is longer than the longest step of the walk: nothing jumps across the square
    both = finite[1:] & finite[:-1]
    drawn = np.linalg.norm(np.diff(path, axis=0)[both], axis=1)
    assert np.max(drawn) <= np.max(np.linalg.norm(np.diff(u, axis=0), axis=1)) + 1e-12
    kept = path[finite]
    interior = kept[np.all(np.abs(kept) < np.pi - 1e-12, axis=1)]
    np.testing.assert_allclose(interior, np.pi - np.mod(np.pi - u, 2 * np.pi), atol=1e-12)
    # each added edge point lies on the square's boundary
    edges = kept[~np.all(np.abs(kept) < np.pi - 1e-12, axis=1)]
    assert np.all(np.isclose(np.max(np.abs(edges), axis=1), np.pi))


def test_energy_figure_log_scale_with_floor_and_drift(tr):
    fig = F.energy_figure(tr)
    ax = fig.axes[0]
    assert ax.get_yscale() == "log"
    err = np.abs(tr.energy - tr.work - tr.energy[0]) / np.max(np.abs(tr.energy))
    np.testing.assert_array_equal(ax.lines[0].get_xdata(), tr.t)
    np.testing.assert_allclose(ax.lines[0].get_ydata(), np.maximum(err, F.ENERGY_FLOOR), rtol=1e-15)
    assert np.max(ax.lines[0].get_ydata()) == pytest.approx(tr.energy_drift, rel=1e-9)
    assert ax.lines[1].get_ydata()[0] == pytest.approx(tr.energy_drift)  # the reported drift, dashed
    notes = " ".join(t.get_text() for t in ax.texts)
    assert "below 1e-17" in notes and "drawn at 1e-17" in notes  # the zero at t = 0 is said to be clipped
    assert "[1]" in ax.get_ylabel() and "[s]" in ax.get_xlabel()


def test_tips_figure_draws_the_rod_ends_hanging_down(tr):
    fig = F.tips_figure(tr)
    ax = fig.axes[0]
    assert ax.name == "3d"
    tips = tr.tips()
    for line, (x, y, z) in zip(ax.lines[:2], ((0, 1, 2), (3, 4, 5))):
        X, Y, Z = line.get_data_3d()
        np.testing.assert_array_equal(X, tips[:, x])
        np.testing.assert_array_equal(Y, tips[:, z])  # z (the first hinge axis) on the plot's second axis
        np.testing.assert_array_equal(Z, -tips[:, y])  # world y points down: -y is drawn upwards
    np.testing.assert_array_equal(F.tips_view(tips)[:, :3], np.column_stack([tips[:, 0], tips[:, 2], -tips[:, 1]]))
    # at t = 0 both ends are below the pivot (phi0 = 1.2 rad): the pendulum hangs down in the picture
    assert ax.lines[0].get_data_3d()[2][0] < 0 and ax.lines[1].get_data_3d()[2][0] < 0
    # equal scales on all three axes
    spans = [np.ptp(lim) for lim in (ax.get_xlim(), ax.get_ylim(), ax.get_zlim())]
    assert spans == pytest.approx([spans[0]] * 3)
    for label in (ax.get_xlabel(), ax.get_ylabel(), ax.get_zlabel()):
        assert "[m]" in label


def test_simulation_figure_has_every_panel(tr):
    fig = F.simulation_figure(tr)
    assert len(fig.axes) == 7
    assert sum(ax.name == "3d" for ax in fig.axes) == 1
    titles = " | ".join(ax.get_title(loc="left") for ax in fig.axes)
    for word in ("angles", "speeds", "Energy", "Phase portrait, hinge 1", "Phase portrait, hinge 2", "torus", "3D"):
        assert word in titles
    assert any(ax.get_yscale() == "log" for ax in fig.axes)


# -- units, heading, style ------------------------------------------------------------------------
UNIT = re.compile(r"\[(s|deg|rad/s|m|1|J)\]")


@pytest.mark.parametrize("name", TRAJECTORY_FIGURES)
def test_every_axis_has_a_unit_and_the_heading_states_the_run(name, tr):
    fig = getattr(F, name)(tr)
    for ax in fig.axes:
        assert UNIT.search(ax.get_ylabel()), (name, ax.get_ylabel())
        if ax.name == "3d":
            assert UNIT.search(ax.get_zlabel())
        # a shared time axis is labelled once, on the panel below
        xlabels = [a.get_xlabel() for a in ax.get_shared_x_axes().get_siblings(ax)]
        assert any(UNIT.search(label) for label in xlabels), (name, xlabels)
    heading = _heading(fig)
    for text in ("a = 1 m", "b = 0.8 m", "m1 = 1 kg", "m2 = 0.7 kg", f"alpha = {math.degrees(0.6):.4g}°", "g = 9.81 m/s²",
                 "phi0 = 68.75°", "psi0 = -45.84°", "taylor", "rtol = 1e-10", "atol = 1e-10", "t_end = 5 s"):  # simulate's default chose taylor
        assert text in heading, (name, text, heading)
    assert "c1" not in heading and "tau1" not in heading  # zero damping and torques are not listed


def test_heading_lists_damping_torques_and_fixed_step_settings():
    p = skewpend.Parameters(a=1.0, b=0.8, m1=1.0, m2=0.7, alpha=0.6, g=9.81, c1=0.05, tau2=-0.3)
    traj = skewpend.simulate(p, (0.3, 0.1, 0, 0), 1.0, method="gauss", dt=0.01, dt_out=0.05)
    heading = _heading(F.energy_figure(traj))
    for text in ("c1 = 0.05 N m s", "tau2 = -0.3 N m", "gauss", "dt = 0.01 s", "t_end = 1 s"):
        assert text in heading, (text, heading)
    assert "rtol" not in heading and "c2" not in heading


def test_figures_leave_global_rcparams_alone(tr):
    import matplotlib

    before = dict(matplotlib.rcParams)
    F.simulation_figure(tr)
    assert dict(matplotlib.rcParams) == before


def test_import_is_cheap_and_no_pyplot_is_used():
    code = (
        "import sys\nimport skewpend.views.figures as F\n"
        "print('matplotlib' in sys.modules)\n"
        "import skewpend\n"
        "tr = skewpend.simulate(skewpend.Parameters(a=1.0, b=0.8, m1=1.0, m2=0.7, alpha=0.6, g=9.81), (1.2, -0.8, 0, 0), 0.5, dt_out=0.05)\n"
        "fig = F.angles_figure(tr)\n"
        "print('matplotlib.pyplot' in sys.modules, type(fig).__module__)\n"
    )
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True).stdout.split("\n")
    assert out[0] == "False"
    assert out[1] == "False matplotlib.figure"


@pytest.mark.parametrize("name", TRAJECTORY_FIGURES)
def test_refuses_a_trajectory_without_its_rows(name):
    traj = skewpend.simulate(PARAMS, Y0, 0.5, keep=False)
    assert not traj.kept
    with pytest.raises(skewpend.ParameterError, match="keep"):
        getattr(F, name)(traj)


# -- saving -------------------------------------------------------------------------------------------
def test_save_figure_png_svg_pdf_atomically(tr, tmp_path):
    from PIL import Image

    fig = F.angles_figure(tr)
    png, svg, pdf = (F.save_figure(fig, tmp_path / f"angles{ext}") for ext in (".png", ".SVG", ".pdf"))
    data = png.read_bytes()
    assert data[:8] == b"\x89PNG\r\n\x1a\n"
    with Image.open(io.BytesIO(data)) as im:
        im.verify()
    with Image.open(io.BytesIO(data)) as im:
        assert im.format == "PNG" and im.size[0] > 800 and im.size[1] > 600
    text = svg.read_text()
    assert text.lstrip().startswith("<?xml") and "<svg" in text
    assert pdf.read_bytes()[:5] == b"%PDF-"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["angles.SVG", "angles.pdf", "angles.png"]  # no temp files


def test_print_figure_same_pixels_as_savefig_with_plain_tick_labels(tr):
    """print_figure (save_figure's and the report's way to write a figure) lays a PNG out once instead of
    savefig's dry draw plus draw: the same pixels; its tick labels are plain text, an offset stays mathtext."""
    from PIL import Image

    from skewpend.views.figures.base import plain_tick_labels, print_figure
    from skewpend.views.style import style

    def pixels(data):
        with Image.open(io.BytesIO(data)) as im:
            return np.asarray(im.convert("RGB"))

    for make in (F.angles_figure, F.tips_figure):  # 2D panels, and a 3D axes with its z axis
        ours, theirs = make(tr), make(tr)
        a, b = io.BytesIO(), io.BytesIO()
        print_figure(ours, a, "png", 110, {})
        plain_tick_labels(theirs)
        with style():
            theirs.savefig(b, format="png", dpi=110, metadata={})
        np.testing.assert_array_equal(pixels(a.getvalue()), pixels(b.getvalue()))
        assert ours.get_layout_engine() is not None  # the layout engine is given back after the save
    labels = [t.get_text() for t in ours.axes[0].get_xticklabels()] + [t.get_text() for t in ours.axes[0].get_yticklabels()]
    assert labels and all(s and "$" not in s for s in labels), labels
    fig = F.energy_figure(tr)
    ax = fig.axes[0]
    with style():  # (its new formatter takes the style's mathtext setting, as the figures' own do)
        ax.set_yscale("linear")
    ax.set_ylim(1e-7, 5e-7)  # a power of ten above the axis: written as mathtext, as before
    print_figure(fig, io.BytesIO(), "png", 60, {})
    assert "$" in ax.yaxis.get_offset_text().get_text()
    assert all("$" not in t.get_text() for t in ax.get_yticklabels() if t.get_text())


def test_save_figure_refuses_unknown_formats_and_cleans_up(tr, tmp_path):
    fig = F.energy_figure(tr)
    for name in ("plot.txt", "plot", "plot.jpg"):
        with pytest.raises(skewpend.ParameterError, match=r"\.png, \.svg or \.pdf"):
            F.save_figure(fig, tmp_path / name)
    with pytest.raises(skewpend.ParameterError, match="does not exist"):
        F.save_figure(fig, tmp_path / "nodir" / "plot.png")
    assert list(tmp_path.iterdir()) == []
    # a failure while writing leaves the old file untouched and no temporary file behind
    target = tmp_path / "plot.png"
    target.write_bytes(b"old")

    def broken_savefig(fh, **kwargs):
        fh.write(b"partial")
        raise RuntimeError("disk on fire")

    fig.savefig = broken_savefig
    with pytest.raises(RuntimeError, match="disk on fire"):
        F.save_figure(fig, target)
    assert target.read_bytes() == b"old"
    assert [p.name for p in tmp_path.iterdir()] == ["plot.png"]


# -- the sweep plot ---------------------------------------------------------------------------------------
def test_plot_sweep():
    sw = skewpend.sweep(PARAMS, "alpha", np.radians(np.linspace(0, 180, 19)))
    fig = F.plot_sweep(sw, title="veering")
    top, bottom = fig.axes
    np.testing.assert_allclose(top.lines[0].get_xdata(), np.linspace(0, 180, 19), atol=1e-12)
    np.testing.assert_array_equal(top.lines[0].get_ydata(), sw.frequencies[:, 0])
    np.testing.assert_array_equal(top.lines[1].get_ydata(), sw.frequencies[:, 1])
    assert "[rad/s]" in top.get_ylabel() and "[deg]" in bottom.get_ylabel() and "[deg]" in bottom.get_xlabel()
    heading = _heading(fig)
    assert "veering" in heading and "alpha from 0° to 180° (19 points)" in heading and "a = 1 m" in heading
    assert "alpha = 34.38" not in heading  # the swept parameter is not listed as fixed
    ratio = skewpend.sweep(PARAMS, "b/a", np.linspace(0.5, 2, 5))
    fig = F.plot_sweep(ratio)
    assert fig.axes[1].get_xlabel() == "b/a [1]"
    assert "b = " not in _heading(fig)


# -- the flip-time map ----------------------------------------------------------------------------------
@pytest.fixture(scope="module")
def fmap():
    return skewpend.flip_map(PARAMS, 48)


def _image_of(fig):
    """The map's Axes and its flip-time image (the first image drawn on it)."""
    ax = fig.axes[0]
    return ax, ax.images[0]


def test_flipmap_figure_draws_the_flip_times_transposed_with_nan_masked(fmap):
    from matplotlib.colors import LogNorm, to_rgba

    fig = F.flipmap_figure(fmap)
    ax, im = _image_of(fig)
    data = im.get_array()
    # phi0 (axis 0 of flip_time) across, psi0 (axis 1) up: the image is flip_time.T with origin "lower"
    assert im.origin == "lower" and data.shape == fmap.flip_time.T.shape
    np.testing.assert_array_equal(np.ma.getmaskarray(data), np.isnan(fmap.flip_time.T))
    np.testing.assert_array_equal(data.filled(np.nan), fmap.flip_time.T)
    assert np.isnan(fmap.flip_time).any() and np.isfinite(fmap.flip_time).any()  # both kinds of cell are there
    # a logarithmic colour scale from the shortest flip time to t_end
    assert isinstance(im.norm, LogNorm)
    assert im.norm.vmax == fmap.settings["t_end"] == 10.0
    assert im.norm.vmin == np.nanmin(fmap.flip_time)
    # the never-flipping cells in one flat colour that the colour map never takes
    bad = im.cmap.get_bad()
    assert tuple(bad) == to_rgba(F.FLIPMAP_COLORS["no_flip"])
    ramp = im.cmap(np.linspace(0, 1, 256))
    assert np.min(np.abs(ramp - bad).sum(axis=1)) > 0.2
    # the window in degrees, equal aspect, ticks at multiples of 90 (minor 45)
    np.testing.assert_allclose(im.get_extent(), [-180, 180, -180, 180], atol=1e-12)
    assert ax.get_xlim() == pytest.approx((-180, 180)) and ax.get_ylim() == pytest.approx((-180, 180))
    assert ax.get_aspect() == 1.0
    for axis in (ax.xaxis, ax.yaxis):
        ticks = [t for t in axis.get_majorticklocs() if -180 <= t <= 180]
        assert ticks == [-180, -90, 0, 90, 180]
        assert all(t % 45 == 0 for t in axis.get_minorticklocs())
    assert "[deg]" in ax.get_xlabel() and "varphi" in ax.get_xlabel()
    assert "[deg]" in ax.get_ylabel() and "psi" in ax.get_ylabel()
    (bar,) = ax.child_axes  # the colour bar, inset beside the map: exactly as tall
    assert bar.get_ylabel() == "flip time [s]"
    assert max(bar.get_yticks()) == pytest.approx(10.0)  # t_end is labelled


def test_flipmap_figure_heading_states_parameters_and_settings(fmap):
    heading = _heading(F.flipmap_figure(fmap))
    for text in ("a = 1 m", "b = 0.8 m", "m1 = 1 kg", "m2 = 0.7 kg", f"alpha = {math.degrees(0.6):.4g}°", "g = 9.81 m/s²",
                 "released at rest", "phi0 in [-180°, 180°], psi0 in [-180°, 180°]", "n = 48 x 48 cells", "t_end = 10 s",
                 "dop853", "rtol = 1e-10", "atol = 1e-10", "% of the cells flip", "% forbidden by energy"):
        assert text in heading, (text, heading)
    flipped = 100 * np.count_nonzero(np.isfinite(fmap.flip_time)) / fmap.flip_time.size
    assert f"{flipped:.3g}% of the cells flip" in heading
    # a long list of parameters is broken between items, not cut off
    # (a general body, damped and driven: examples/general_body.toml's, whose flip kernel other runs compile)
    p = general_body(c1=0.05, tau2=0.2)
    from skewpend.views.style import flipmap_caption

    text = flipmap_caption(skewpend.flip_map(p, 4))
    assert max(len(line) for line in text.split("\n")) <= 100 and "tau2 = 0.2 N m" in text and "custom" in text


def test_flipmap_figure_window_in_degrees_and_mark_wrapped():
    window = dict(phi_range=(0.2, 1.0), psi_range=(-1.5, -0.5))
    fm = skewpend.flip_map(PARAMS, 24, **window)
    fig = F.flipmap_figure(fm, mark=(1.2 - 2 * math.pi, -0.8), mark_label="the start")
    ax, im = _image_of(fig)
    np.testing.assert_allclose(im.get_extent(), np.degrees([0.2, 1.0, -1.5, -0.5]), rtol=1e-12)
    np.testing.assert_array_equal(im.get_array().filled(np.nan), fm.flip_time.T)
    # the cell at image row j, column i is (phi0[i], psi0[j]): its centre lies in the image there
    x0, x1, y0, y1 = im.get_extent()
    i, j = 5, 17
    assert x0 + (i + 0.5) * (x1 - x0) / 24 == pytest.approx(math.degrees(fm.phi0[i, 0]))
    assert y0 + (j + 0.5) * (y1 - y0) / 24 == pytest.approx(math.degrees(fm.psi0[0, j]))
    (mark,) = [line for line in ax.lines if line.get_marker() == "o"]
    assert mark.get_xdata()[0] == pytest.approx(math.degrees(1.2)) and mark.get_ydata()[0] == pytest.approx(math.degrees(-0.8))
    labels = [t.get_text() for t in ax.get_legend().get_texts()]
    assert "the start" in labels and "no flip by t_end = 10 s" in labels
    assert "phi0 in [11.46°, 57.3°], psi0 in [-85.94°, -28.65°]" in _heading(fig)


def test_flipmap_figure_shows_the_energy_forbidden_region(fmap):
    forbidden = F.flipmap_forbidden(fmap)
    assert forbidden.shape == fmap.flip_time.shape and forbidden.any()
    # exactly the cells flip_map skipped by its energy bound, and none of them flips
    assert np.count_nonzero(forbidden) == fmap.stats["skipped_energy"]
    assert np.all(np.isnan(fmap.flip_time[forbidden]))
    margin = F.flipmap_energy_margin(fmap)
    np.testing.assert_array_equal(margin < 0, forbidden)
    fig = F.flipmap_figure(fmap)
    ax = fig.axes[0]
    labels = [t.get_text() for t in ax.get_legend().get_texts()]
    assert labels == ["no flip by t_end = 10 s", "energy forbids any flip"]
    assert len(ax.collections) >= 2  # the grey region (filled) and its edge (a line)
    # given as cells: drawn as a second image, exactly those cells
    fig = F.flipmap_figure(fmap, forbidden=forbidden)
    ax = fig.axes[0]
    assert len(ax.images) == 2
    np.testing.assert_array_equal(~np.ma.getmaskarray(ax.images[1].get_array()), forbidden.T)
    # or not at all
    ax = F.flipmap_figure(fmap, forbidden=None).axes[0]
    assert len(ax.images) == 1 and not ax.collections
    assert [t.get_text() for t in ax.get_legend().get_texts()] == ["no flip by t_end = 10 s"]
    with pytest.raises(skewpend.ParameterError, match="shape"):
        F.flipmap_figure(fmap, forbidden=forbidden[:-1])


def test_flipmap_figure_without_any_flip():
    fm = skewpend.flip_map(PARAMS.replace(g=0.0), 8)  # no gravity, released at rest: nothing moves
    assert np.isnan(fm.flip_time).all()
    fig = F.flipmap_figure(fm)
    im = fig.axes[0].images[0]
    assert np.ma.getmaskarray(im.get_array()).all()
    assert 0 < im.norm.vmin < im.norm.vmax == 10.0
    assert "0% of the cells flip" in _heading(fig)


def test_flipmap_figure_saves_png_and_leaves_rcparams_alone(fmap, tmp_path):
    import matplotlib
    from PIL import Image

    before = dict(matplotlib.rcParams)
    fig = F.flipmap_figure(fmap, mark=(1.2, -0.8))
    assert dict(matplotlib.rcParams) == before
    path = F.save_figure(fig, tmp_path / "map.png")
    data = path.read_bytes()
    assert data[:8] == b"\x89PNG\r\n\x1a\n"
    with Image.open(io.BytesIO(data)) as im:
        assert im.format == "PNG" and im.size[0] > 800 and im.size[1] > 800
    assert [p.name for p in tmp_path.iterdir()] == ["map.png"]
