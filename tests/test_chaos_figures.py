"""The chaos figures (skewpend.views.figures): lyapunov_figure, poincare_figure,
chaos_diagram_figure and lyapunov_map_figure draw what the result objects hold -- the data of
their lines, dots, cells and images equals the results' arrays in the stated units, every axis
has a unit, the heading states the parameters and settings, legends and titles do not cover
each other or the data -- from real (small, fast) runs of the analyses.

With $SKEWPEND_ARTIFACTS set (a folder, or 1 for tests/artifacts/) every figure is also kept as
a PNG in its chaos-figures/ folder, to look at."""

from __future__ import annotations

import dataclasses
import io
import math
import os
import re
from pathlib import Path

import numpy as np
import pytest

pytest.importorskip("matplotlib")

import skewpend  # noqa: E402
from skewpend import Parameters  # noqa: E402
from skewpend.views import figures as F  # noqa: E402

P = Parameters(a=1.0, b=1.0, m1=1.0, m2=1.0, g=9.81, alpha=0.6)
Y0 = (1.0, -0.5, 0.0, 0.0)
ALPHA_DEG = f"alpha = {math.degrees(0.6):.4g}°"  # 34.38°
PARAMETER_TEXTS = ("a = 1 m", "b = 1 m", "m1 = 1 kg", "m2 = 1 kg", "g = 9.81 m/s²")


# -- the results, computed once ------------------------------------------------------------------------------
@pytest.fixture(scope="module")
def spec():
    return skewpend.lyapunov(P, Y0, t_end=50)


@pytest.fixture(scope="module")
def section():
    return skewpend.poincare(P, 10.0, n_orbits=6, n_crossings=100)


@pytest.fixture(scope="module")
def diagram():
    return skewpend.chaos_diagram(Parameters(a=1.0, b=1.0, m1=1.0, m2=1.0, g=9.81), n_alpha=3, n_energy=3, samples=4,
                                  t_end=40)


@pytest.fixture(scope="module")
def lmap():
    return skewpend.lyapunov_map(P, 6, t_end=20)


# -- helpers -------------------------------------------------------------------------------------------------
def _heading(fig) -> str:
    return "\n".join(t.get_text() for t in fig.texts)


def _artifacts():
    """Where to keep the PNGs: None unless $SKEWPEND_ARTIFACTS is set (a folder; 1/true/yes: tests/artifacts)."""
    value = os.environ.get("SKEWPEND_ARTIFACTS")
    if not value:
        return None
    default = Path(__file__).resolve().parent / "artifacts"
    root = default if value.strip().lower() in ("1", "true", "yes", "on") else Path(value)
    folder = root / "chaos-figures"
    folder.mkdir(parents=True, exist_ok=True)
    ignore = root / ".gitignore"
    if root.name == "artifacts" and not ignore.exists():
        ignore.write_text("# test artifacts (screenshots, reports): not part of the repository\n*\n")
    return folder


def _keep(fig, name: str) -> None:
    folder = _artifacts()
    if folder is not None:
        F.save_figure(fig, folder / f"{name}.png")


def _boxes(fig):
    """Draw the figure as save_figure does (Agg, in the skewpend style) and return a function giving
    an artist's extent in pixels."""
    from matplotlib.backends.backend_agg import FigureCanvasAgg

    from skewpend.views.style import style

    canvas = FigureCanvasAgg(fig)
    with style():
        canvas.draw()
    renderer = canvas.get_renderer()
    return lambda artist: artist.get_window_extent(renderer)


def _disjoint(a, b, pad: float = 0.0) -> bool:
    return a.x1 + pad <= b.x0 or b.x1 + pad <= a.x0 or a.y1 + pad <= b.y0 or b.y1 + pad <= a.y0


def _heading_clear_of_titles(fig) -> None:
    """No text of the heading, no axes title and no legend overlaps another of them."""
    extent = _boxes(fig)
    boxes = [(f"heading {t.get_text()[:30]!r}", extent(t)) for t in fig.texts]
    for ax in fig.axes:
        for title in (ax.title, ax._left_title, ax._right_title):
            if title.get_text():
                boxes.append((f"title {title.get_text()!r}", extent(title)))
        if ax.get_legend() is not None:
            boxes.append(("legend", extent(ax.get_legend())))
    for i, (name_a, a) in enumerate(boxes):
        for name_b, b in boxes[i + 1:]:
            if name_a.startswith("heading") and name_b.startswith("heading"):
                continue  # the lines of one heading
            assert _disjoint(a, b), (name_a, name_b)


# -- the Lyapunov spectrum -----------------------------------------------------------------------------------
def _exponent_lines(ax):
    return [line for line in ax.lines if line.get_label().startswith(r"$\lambda")]


def test_lyapunov_figure_draws_each_running_estimate_against_log_time(spec):
    fig = F.lyapunov_figure(spec)
    (ax,) = fig.axes
    lines = _exponent_lines(ax)
    assert len(lines) == spec.k == 4 and len(ax.lines) == 5  # four exponents and the zero line
    for j, line in enumerate(lines):
        np.testing.assert_array_equal(line.get_xdata(), spec.t)
        np.testing.assert_array_equal(line.get_ydata(), spec.history[:, j])
    assert len({line.get_color() for line in lines}) == 4
    (zero,) = [line for line in ax.lines if line not in lines]
    assert np.all(np.asarray(zero.get_ydata()) == 0)
    assert ax.get_xscale() == "log" and ax.get_xlim() == pytest.approx((spec.t[0], spec.t[-1]))
    assert "[s]" in ax.get_xlabel() and "[1/s]" in ax.get_ylabel()
    # the time axis is labelled with plain numbers 1, 2, 5, 10, 20, 50
    fig.draw_without_rendering()
    labels = [t.get_text() for t in ax.get_xticklabels() if t.get_text()]
    assert {"1", "10", "50"} <= set(labels), labels
    _keep(fig, "lyapunov")


def test_lyapunov_figure_legend_gives_final_values_and_uncertainties(spec):
    ax = F.lyapunov_figure(spec).axes[0]
    texts = [t.get_text() for t in ax.get_legend().get_texts()]
    assert len(texts) == 5 and texts[-1].startswith("sum = ")
    number = r"([+-]?\d+(?:\.\d+)?(?:e[+-]?\d+)?)"
    for j, text in enumerate(texts[:4]):
        m = re.fullmatch(rf"\$\\lambda_{j + 1}\$ = {number} ± {number} 1/s", text)
        assert m, text
        value, err = float(m.group(1)), float(m.group(2))
        # the value to the precision of its uncertainty (two significant digits)
        assert err == pytest.approx(spec.uncertainty[j], rel=0.05)
        assert abs(value - spec.exponents[j]) <= 0.05 * spec.uncertainty[j]
    m = re.fullmatch(rf"sum = {number} 1/s", texts[-1])
    assert m and float(m.group(1)) == pytest.approx(spec.sum, rel=0.01)
    assert "standard error" in ax.get_legend().get_title().get_text()


def test_lyapunov_figure_legend_is_beside_the_curves_and_the_heading_clear(spec):
    fig = F.lyapunov_figure(spec)
    ax = fig.axes[0]
    extent = _boxes(fig)
    assert _disjoint(extent(ax.get_legend()), ax.get_window_extent())
    _heading_clear_of_titles(fig)


def test_lyapunov_figure_heading_states_parameters_start_and_settings(spec):
    heading = _heading(F.lyapunov_figure(spec))
    for text in (*PARAMETER_TEXTS, ALPHA_DEG, "phi0 = 57.3°", "psi0 = -28.65°", "dphi0 = 0 rad/s", "rtol = 1e-10",
                 "atol = 1e-10", "t_end = 50 s", "renormalised every 1 s", "4 tangent vectors", "10 windows"):
        assert text in heading, (text, heading)


def test_lyapunov_figure_one_exponent_without_uncertainty_after_a_transient():
    spec1 = skewpend.lyapunov(P, Y0, t_end=12, n_exponents=1, windows=1, transient=2.0)
    assert np.isnan(spec1.uncertainty).all()
    fig = F.lyapunov_figure(spec1)
    ax = fig.axes[0]
    (line,) = _exponent_lines(ax)
    np.testing.assert_array_equal(line.get_ydata(), spec1.history[:, 0])
    texts = [t.get_text() for t in ax.get_legend().get_texts()]
    assert len(texts) == 1 and texts[0].endswith("± n/a 1/s")  # no sum for a single exponent
    assert "measured from t = 2 s" in ax.get_title(loc="left")
    heading = _heading(fig)
    assert "1 tangent vector " in heading and "transient 2 s" in heading


def test_lyapunov_figure_of_a_run_that_stopped_early():
    spec = skewpend.lyapunov(P, Y0, t_end=50, max_steps=20, throw=False)
    assert spec.status != 0
    fig = F.lyapunov_figure(spec)
    assert "stopped at" in _heading(fig)
    if len(spec.t) == 0:
        assert "nothing to draw" in " ".join(t.get_text() for t in fig.axes[0].texts)


# -- the Poincaré section ------------------------------------------------------------------------------------
def test_poincare_figure_one_colour_per_orbit_at_q_and_p(section):
    fig = F.poincare_figure(section)
    ax = fig.axes[0]
    n = section.crossings.size
    assert n == 6 and len(ax.collections) == n
    colours = set()
    for k, dots in enumerate(ax.collections):
        q, p = section.orbit_points(k)
        np.testing.assert_array_equal(dots.get_offsets(), np.column_stack([q, p]))
        colours.add(tuple(np.round(dots.get_facecolors()[0], 6)))
        assert np.all(dots.get_sizes() <= 6.0)  # small dots
    assert len(colours) == n
    assert ax.get_xlim() == pytest.approx((-math.pi, math.pi))
    fig.draw_without_rendering()
    assert [t.get_text() for t in ax.get_xticklabels()] == ["−π", "−π/2", "0", "π/2", "π"]
    assert "psi" in ax.get_xlabel() and "[rad]" in ax.get_xlabel()
    assert "p_" in ax.get_ylabel() and "psi" in ax.get_ylabel() and "[J s]" in ax.get_ylabel()
    assert "one colour per orbit" in ax.get_title(loc="left")
    _keep(fig, "poincare")


def test_poincare_figure_speeds_when_not_canonical(section):
    fig = F.poincare_figure(section, canonical=False)
    ax = fig.axes[0]
    for k, dots in enumerate(ax.collections):
        sel = section.orbit == k
        np.testing.assert_array_equal(dots.get_offsets(), np.column_stack([section.q[sel], section.dq[sel]]))
    assert "[rad/s]" in ax.get_ylabel() and "psi" in ax.get_ylabel()
    _keep(fig, "poincare-speeds")


@pytest.mark.parametrize("canonical", [True, False])
def test_poincare_figure_edge_of_the_energy_surface_holds_every_point(section, canonical):
    fig = F.poincare_figure(section, canonical=canonical)
    ax = fig.axes[0]
    upper, lower = ax.lines  # drawn upper first
    x = upper.get_xdata()
    assert x[0] == pytest.approx(-math.pi) and x[-1] == pytest.approx(math.pi)
    y = section.p if canonical else section.dq
    scale = np.nanmax(upper.get_ydata())
    assert np.all(y <= np.interp(section.q, x, upper.get_ydata()) + 1e-3 * scale)
    assert np.all(y >= np.interp(section.q, x, lower.get_ydata()) - 1e-3 * scale)
    if canonical:  # symmetric in p; in q' lopsided: phi' > 0 on the section limits one side
        np.testing.assert_allclose(lower.get_ydata(), -upper.get_ydata())
    else:
        assert not np.allclose(lower.get_ydata(), -upper.get_ydata())
    labels = [t.get_text() for t in ax.get_legend().get_texts()]
    assert labels == ["edge of the energy surface"]
    extent = _boxes(fig)
    assert _disjoint(extent(ax.get_legend()), ax.get_window_extent())  # below the axes, not over the dots


def test_poincare_boundary_is_the_reachable_region(section):
    """The edges against brute force: at each q the states on the section with kinetic energy
    E - Pi form an ellipse in (phi', q'); of its half with phi' > 0 (the direction), the extremes
    of q' and of p_q = M_qc phi' + M_qq q' are the edges."""
    from skewpend.analysis.poincare import mass_matrices, potential
    from skewpend.numeric.conventions import parameter_vector
    from skewpend.numeric.kernels import kernel_module

    kernel, p = kernel_module(section.params, chaos=True), parameter_vector(section.params)
    x, lower, upper = F.poincare_boundary(section, canonical=False, samples=9)
    _, p_lower, p_upper = F.poincare_boundary(section, canonical=True, samples=9)
    theta = np.linspace(0.0, 2 * math.pi, 200_001)
    for k, xi in enumerate(x):
        q = np.array([[0.0, xi]])  # on phi = 0
        M = mass_matrices(kernel, p, q)[0]
        room = section.settings["energy"] - potential(kernel, p, q)[0]
        u = math.sqrt(2 * room) * np.vstack([np.cos(theta), np.sin(theta)])
        v = np.linalg.solve(np.linalg.cholesky(M).T, u)  # v^T M v = 2 room
        ends = math.sqrt(2 * room / M[1, 1]) * np.array([[0.0, 0.0], [1.0, -1.0]])  # the half's ends: phi' = 0
        v = np.hstack([v[:, v[0] >= 0], ends])
        speed, momentum = v[1], M[1, 0] * v[0] + M[1, 1] * v[1]
        assert speed.min() == pytest.approx(lower[k], rel=1e-6) and speed.max() == pytest.approx(upper[k], rel=1e-6)
        assert momentum.min() == pytest.approx(p_lower[k], rel=1e-6)
        assert momentum.max() == pytest.approx(p_upper[k], rel=1e-6)


def test_poincare_figure_heading_states_energy_section_direction_and_parameters(section):
    fig = F.poincare_figure(section)
    heading = _heading(fig)
    for text in (*PARAMETER_TEXTS, ALPHA_DEG, "E = 10 J", "section phi = 0", "crossed with phi increasing",
                 "6 orbits x 100 crossings wanted: 600 points", "dense output", "rtol = 1e-12", "atol = 1e-12",
                 "largest |energy error|"):
        assert text in heading, (text, heading)
    assert "drawn" not in heading  # nothing thinned
    _heading_clear_of_titles(fig)


def test_poincare_figure_max_points_thins_every_orbit_evenly(section):
    fig = F.poincare_figure(section, max_points=150)
    ax = fig.axes[0]
    assert len(ax.collections) == 6  # every orbit still there
    drawn = sum(len(c.get_offsets()) for c in ax.collections)
    assert drawn <= 150
    q0, p0 = section.orbit_points(0)
    np.testing.assert_array_equal(ax.collections[0].get_offsets(), np.column_stack([q0, p0])[::4])
    assert f"600 points, {drawn} drawn (thinned evenly)" in _heading(fig)
    with pytest.raises(skewpend.ParameterError, match="max_points"):
        F.poincare_figure(section, max_points=0)


def test_poincare_figure_other_section_both_directions():
    sec = skewpend.poincare(P, 10.0, section="psi=30deg", direction=0, n_orbits=3, n_crossings=20)
    fig = F.poincare_figure(sec)
    ax = fig.axes[0]
    assert "varphi" in ax.get_xlabel() and "p_" in ax.get_ylabel()
    heading = _heading(fig)
    assert "section psi = 0.5236 rad (30°)" in heading and "crossed with psi either way" in heading
    upper, lower = ax.lines
    np.testing.assert_allclose(lower.get_ydata(), -upper.get_ydata())


# -- the chaos diagram ---------------------------------------------------------------------------------------
def test_chaos_diagram_figure_heat_map_of_the_fraction(diagram):
    fig = F.chaos_diagram_figure(diagram)
    ax_map, ax_lines, bar = fig.axes
    (mesh,) = ax_map.collections
    # alpha [deg] across, energy [J] up: the cells hold fraction.T
    np.testing.assert_array_equal(np.ma.filled(mesh.get_array(), np.nan), diagram.fraction.T)
    corners = mesh.get_coordinates()  # (ne + 1, na + 1, 2): edges midway between the grid values
    centres_x = 0.5 * (corners[0, 1:, 0] + corners[0, :-1, 0])
    centres_y = 0.5 * (corners[1:, 0, 1] + corners[:-1, 0, 1])
    np.testing.assert_allclose(centres_x, np.degrees(diagram.alpha), atol=1e-9)
    np.testing.assert_allclose(centres_y, diagram.energy, rtol=1e-12)
    assert (mesh.norm.vmin, mesh.norm.vmax) == (0.0, 1.0)
    assert bar.get_ylabel() == "chaotic fraction [1]" and bar.get_ylim() == pytest.approx((0.0, 1.0))
    assert "[deg]" in ax_map.get_xlabel() and "alpha" in ax_map.get_xlabel() and "[J]" in ax_map.get_ylabel()
    fig.draw_without_rendering()
    assert [t.get_text() for t in ax_map.get_xticklabels()] == ["0°", "45°", "90°"]
    _keep(fig, "chaos-diagram")


def test_chaos_diagram_figure_annotates_each_cell_of_a_small_grid(diagram):
    ax_map = F.chaos_diagram_figure(diagram).axes[0]
    assert len(ax_map.texts) == diagram.fraction.size == 9
    for t in ax_map.texts:
        x, y = t.get_position()
        i = int(np.argmin(np.abs(np.degrees(diagram.alpha) - x)))
        j = int(np.argmin(np.abs(diagram.energy - y)))
        assert x == pytest.approx(math.degrees(diagram.alpha[i])) and y == pytest.approx(diagram.energy[j])
        assert t.get_text() == f"{diagram.fraction[i, j]:.2f}"


def test_chaos_diagram_figure_one_line_per_alpha_against_energy(diagram):
    fig = F.chaos_diagram_figure(diagram)
    ax = fig.axes[1]
    assert len(ax.lines) == diagram.alpha.size == 3
    for i, line in enumerate(ax.lines):
        np.testing.assert_array_equal(line.get_xdata(), diagram.energy)
        np.testing.assert_array_equal(line.get_ydata(), diagram.fraction[i])
    labels = [t.get_text() for t in ax.get_legend().get_texts()]
    assert labels == [r"$\alpha$ = 0°", r"$\alpha$ = 45°", r"$\alpha$ = 90°"]
    # where lines coincide (fractions of 0 or 1 are common) the shrinking rings stay visible
    sizes = [line.get_markersize() for line in ax.lines]
    assert sizes == sorted(sizes, reverse=True) and len(set(sizes)) == 3
    assert ax.get_ylim()[0] < 0 and ax.get_ylim()[1] > 1
    assert "[J]" in ax.get_xlabel() and "[1]" in ax.get_ylabel()
    extent = _boxes(fig)
    assert _disjoint(extent(ax.get_legend()), ax.get_window_extent())
    # the colour bar's label keeps clear (a quarter inch) of the second panel's axis label
    assert _disjoint(extent(fig.axes[2].yaxis.label), extent(ax.yaxis.label), pad=0.25 * fig.dpi)
    _heading_clear_of_titles(fig)


def test_chaos_diagram_figure_heading_states_grid_samples_t_end_and_threshold(diagram):
    heading = _heading(F.chaos_diagram_figure(diagram))
    for text in (*PARAMETER_TEXTS, "alpha from 0° to 90° (3 values)", "13.08 to 39.24 J above the minimum (3 values)",
                 "4 starts per cell",
                 "section phi = 0", "t_end = 40 s", f"threshold = {F.fmt(diagram.threshold)} 1/s", "rtol = 1e-8"):
        assert text in heading, (text, heading)
    assert "alpha = 0°" not in heading  # alpha is the diagram's axis, not a fixed parameter


def test_chaos_diagram_figure_large_grid_and_cells_without_a_start(diagram):
    """13 x 13 cells: no numbers in the cells, a colour bar of alpha instead of a legend; NaN cells
    (no valid start) in their own colour, with a legend entry."""
    rng = np.random.default_rng(7)
    exponent = rng.uniform(0, 1, (13, 13, 4))
    exponent[:, 0, :] = np.nan  # the lowest energy: nothing reachable
    big = dataclasses.replace(diagram, alpha=np.radians(np.linspace(0, 90, 13)), energy=np.linspace(1.0, 20.0, 13),
                              exponent=exponent, threshold=0.5)
    fig = F.chaos_diagram_figure(big)
    ax_map, ax_lines = fig.axes[:2]
    assert not ax_map.texts
    mesh = ax_map.collections[0]
    assert np.ma.getmaskarray(mesh.get_array())[0].all() and not np.ma.getmaskarray(mesh.get_array())[1:].any()
    assert tuple(mesh.cmap.get_bad()) != tuple(mesh.cmap(0.0))
    assert [t.get_text() for t in ax_map.get_legend().get_texts()] == ["no valid start"]
    assert len(ax_lines.lines) == 13 and ax_lines.get_legend() is None
    alpha_bar = fig.axes[-1]
    assert "alpha" in alpha_bar.get_ylabel() and "[deg]" in alpha_bar.get_ylabel()
    _heading_clear_of_titles(fig)
    _keep(fig, "chaos-diagram-13x13")


# -- the Lyapunov map ----------------------------------------------------------------------------------------
def test_lyapunov_map_figure_draws_the_exponents_transposed(lmap):
    fig = F.lyapunov_map_figure(lmap)
    ax = fig.axes[0]
    (im,) = ax.images
    assert im.origin == "lower" and im.get_array().shape == lmap.exponent.T.shape
    np.testing.assert_array_equal(im.get_array().filled(np.nan), lmap.exponent.T)
    np.testing.assert_allclose(im.get_extent(), [-180, 180, -180, 180], atol=1e-12)
    assert ax.get_aspect() == 1.0
    # the cell at image row j, column i is (phi0[i], psi0[j])
    x0, x1, y0, y1 = im.get_extent()
    i, j = 1, 4
    assert x0 + (i + 0.5) * (x1 - x0) / 6 == pytest.approx(math.degrees(lmap.phi0[i, 0]))
    assert y0 + (j + 0.5) * (y1 - y0) / 6 == pytest.approx(math.degrees(lmap.psi0[0, j]))
    assert im.norm.vmin == min(0.0, np.nanmin(lmap.exponent)) and im.norm.vmax == np.nanmax(lmap.exponent)
    (bar,) = ax.child_axes
    assert bar.get_ylabel() == "largest Lyapunov exponent [1/s]"
    assert bar.get_ylim() == pytest.approx((im.norm.vmin, im.norm.vmax))
    assert "[deg]" in ax.get_xlabel() and "varphi" in ax.get_xlabel()
    assert "[deg]" in ax.get_ylabel() and "psi" in ax.get_ylabel()
    for axis in (ax.xaxis, ax.yaxis):
        assert [t for t in axis.get_majorticklocs() if -180 <= t <= 180] == [-180, -90, 0, 90, 180]
    assert ax.get_legend() is None  # no failed cell
    _keep(fig, "lyapunov-map")


def test_lyapunov_map_figure_heading_states_parameters_and_settings(lmap):
    fig = F.lyapunov_map_figure(lmap)
    heading = _heading(fig)
    for text in (*PARAMETER_TEXTS, ALPHA_DEG, "released at rest", "phi0 in [-180°, 180°], psi0 in [-180°, 180°]",
                 "n = 6 x 6 cells", "t_end = 20 s", "renormalised every 1 s", "rtol = 1e-8", "atol = 1e-8",
                 "every cell integrated"):
        assert text in heading, (text, heading)
    assert max(len(line) for line in heading.split("\n")) <= 100
    _heading_clear_of_titles(fig)


def test_lyapunov_map_figure_failed_cells_in_their_own_colour(lmap):
    exponent = np.array(lmap.exponent, dtype=float)
    exponent[2, 3] = np.nan
    fig = F.lyapunov_map_figure(dataclasses.replace(lmap, exponent=exponent))
    ax = fig.axes[0]
    im = ax.images[0]
    mask = np.ma.getmaskarray(im.get_array())
    assert mask[3, 2] and mask.sum() == 1
    assert [t.get_text() for t in ax.get_legend().get_texts()] == ["integration failed"]
    assert "1 of 36 cells failed" in _heading(fig)


# -- all of them ---------------------------------------------------------------------------------------------
def test_chaos_figures_save_png_and_leave_rcparams_alone(spec, section, diagram, lmap, tmp_path):
    import matplotlib
    from PIL import Image

    before = dict(matplotlib.rcParams)
    figures = {"lyapunov": F.lyapunov_figure(spec), "poincare": F.poincare_figure(section),
               "chaos": F.chaos_diagram_figure(diagram), "lyapunov-map": F.lyapunov_map_figure(lmap)}
    assert dict(matplotlib.rcParams) == before
    for name, fig in figures.items():
        data = F.save_figure(fig, tmp_path / f"{name}.png").read_bytes()
        with Image.open(io.BytesIO(data)) as im:
            assert im.format == "PNG" and im.size[0] > 800 and im.size[1] > 700
    assert sorted(p.name for p in tmp_path.iterdir()) == sorted(f"{n}.png" for n in figures)
    assert {"lyapunov_figure", "poincare_figure", "chaos_diagram_figure", "lyapunov_map_figure"} <= set(F.__all__)
