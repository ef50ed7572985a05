"""Figures of one trajectory (angles, speeds, energy balance, phase portraits, the torus, the rod
ends in 3D, the whole simulation) and of a parameter sweep of the normal modes."""

from __future__ import annotations

import math
from typing import List, Optional, Sequence

import numpy as np

from ...errors import ParameterError
from ..style import COLORS, SYMBOL, caption, fmt, style, sweep_caption
from .base import ENERGY_FLOOR, MODE_COLORS, TWO_PI, heading, new_figure, wrap_angle

__all__ = ["angles_figure", "phase_figure", "energy_figure", "torus_figure", "tips_figure", "simulation_figure",
           "plot_sweep", "wrapped_path", "tips_view"]


def _check(tr) -> None:
    if not getattr(tr, "kept", True):
        raise ParameterError("this trajectory kept only its first and last rows (simulate(..., keep=False)); figures "
                             "need every row: simulate with keep=True (the default) to plot it")
    if len(tr.t) < 2:
        raise ParameterError(f"a figure needs at least two rows of the trajectory, it has {len(tr.t)}")


def _cell(p: np.ndarray, wrap: np.ndarray) -> np.ndarray:
    """Which copy of the square a point (unwrapped coordinates) lies in: k with p = wrapped + 2 pi k."""
    k = np.zeros_like(p)
    k[..., wrap] = np.round((p[..., wrap] - wrap_angle(p[..., wrap])) / TWO_PI)
    return k


def wrapped_path(columns: Sequence[np.ndarray], wrap: Sequence[bool]) -> np.ndarray:
    """A path for drawing on the torus (or the cylinder of a phase portrait).

    ``columns`` are continuous coordinates (radians for the wrapped ones); the columns with
    ``wrap`` true are wrapped to (-pi, pi].  Where the path leaves the square it is cut: the
    crossing point on the edge (linearly interpolated between the two rows) ends one piece,
    a row of NaN breaks the line, and the same point on the opposite edge starts the next --
    so no drawn segment jumps across the square.  Returns an array (m, len(columns)), m >= n.
    """
    P = np.column_stack([np.asarray(c, dtype=float) for c in columns])
    W = np.asarray(wrap, dtype=bool)
    K = _cell(P, W)
    jumps = np.nonzero(np.any(np.diff(K, axis=0) != 0, axis=1))[0]
    if len(jumps) == 0:
        return P - TWO_PI * K
    nan_row = np.full((1, P.shape[1]), np.nan)
    pieces: List[np.ndarray] = []
    start = 0
    for i in jumps:
        pieces.append(P[start : i + 1] - TWO_PI * K[start : i + 1])
        a, b = P[i], P[i + 1]
        crossings = []
        for j in np.nonzero(W)[0]:
            if b[j] == a[j]:
                continue
            lo, hi = min(a[j], b[j]), max(a[j], b[j])
            for m in range(math.ceil((lo - math.pi) / TWO_PI), math.floor((hi - math.pi) / TWO_PI) + 1):
                crossings.append((math.pi + TWO_PI * m - a[j]) / (b[j] - a[j]))
        crossings.sort()
        bounds = [0.0, *crossings, 1.0]
        for n, s in enumerate(crossings):
            c = a + s * (b - a)
            before = _cell(a + 0.5 * (bounds[n] + s) * (b - a), W)
            after = _cell(a + 0.5 * (s + bounds[n + 2]) * (b - a), W)
            if np.array_equal(before, after):
                continue
            pieces += [(c - TWO_PI * before)[None], nan_row, (c - TWO_PI * after)[None]]
        start = i + 1
    pieces.append(P[start:] - TWO_PI * K[start:])
    return np.concatenate(pieces)


def _legend_above(ax) -> None:
    """The legend in one row above the axes' top right corner (the title is on the left)."""
    n = len(ax.get_legend_handles_labels()[1])
    ax.legend(loc="lower right", bbox_to_anchor=(1.0, 1.0), ncols=max(n, 1), frameon=False, borderaxespad=0.2,
              handlelength=1.6, columnspacing=1.2)


def _thin(n: int, lw: float = 0.8) -> dict:
    """Line width and opacity for a path of n rows drawn over itself: thinner and lighter for
    long runs, so a dense region still shows its structure instead of a solid blot."""
    if n <= 5000:
        return {"lw": lw}
    return {"lw": max(0.12, lw * math.sqrt(5000 / n)), "alpha": 0.6}


def _turn_ticks(axis, values) -> None:
    """Ticks at multiples of 90, 180, 360, ... degrees when an angle spans more than half a turn."""
    from matplotlib.ticker import MultipleLocator

    finite = np.asarray(values)[np.isfinite(values)]
    span = float(np.ptp(finite)) if finite.size else 0.0
    if span < 180:
        return
    for base in (90, 180, 360, 720, 1440, 3600, 7200, 14400, 36000):
        if span / base <= 8:
            axis.set_major_locator(MultipleLocator(base))
            return


def _angle_ticks(ax, which: str) -> None:
    from matplotlib.ticker import MultipleLocator

    axis = ax.xaxis if which == "x" else ax.yaxis
    axis.set_major_locator(MultipleLocator(90))
    axis.set_minor_locator(MultipleLocator(30))


# -- panels (draw into a given Axes) -------------------------------------------------------------
def coordinate_styles(coordinates: Sequence[str]) -> List[tuple]:
    """Per coordinate (the model's names, ``model.coordinates``): (colour, angle symbol, speed symbol) -- the
    symbol and colour of a name the style knows (the double pendulum's phi and psi), else ``q_k`` in the colour
    ``k`` of a qualitative colour map."""
    from matplotlib import colormaps

    cmap = colormaps["tab10"]
    return [(COLORS.get(c, cmap(k % 10)), SYMBOL.get(c, f"$q_{{{k + 1}}}$"), SYMBOL.get(f"d{c}", f"$\\dot q_{{{k + 1}}}$"))
            for k, c in enumerate(coordinates)]


def _labels(tr) -> List[tuple]:
    """Per coordinate: (colour, angle label, speed label); a name that does not number itself (phi, psi)
    says its hinge in the angle's label."""
    names = tr.params.coordinates  # the model's: phi, psi; q1 ... qn
    return [(color, angle if c[-1].isdigit() else f"{angle} (hinge {k + 1})", speed)
            for k, (c, (color, angle, speed)) in enumerate(zip(names, coordinate_styles(names)))]


def _draw_angles(ax, tr) -> None:
    angles = [np.degrees(np.unwrap(tr.y[:, k])) for k in range(tr.y.shape[1] // 2)]
    for (color, label, _), a in zip(_labels(tr), angles):
        ax.plot(tr.t, a, color=color, label=label)
    _turn_ticks(ax.yaxis, np.concatenate(angles))
    ax.set_ylabel("angle [deg]")
    ax.set_title("Hinge angles (unwrapped)", loc="left")
    _legend_above(ax)
    ax.set_xlim(tr.t[0], tr.t[-1])


def _draw_speeds(ax, tr) -> None:
    n = tr.y.shape[1] // 2
    for k, (color, _, label) in enumerate(_labels(tr)):
        ax.plot(tr.t, tr.y[:, n + k], color=color, label=label)
    ax.set_ylabel("angular speed [rad/s]")
    ax.set_title("Angular speeds", loc="left")
    _legend_above(ax)
    ax.set_xlim(tr.t[0], tr.t[-1])


def _draw_energy(ax, tr) -> None:
    scale = float(np.max(np.abs(tr.energy)))
    relative = scale > 0
    err = np.abs(tr.energy - tr.work - tr.energy[0]) / (scale if relative else 1.0)
    shown = np.maximum(err, ENERGY_FLOOR)
    ax.plot(tr.t, shown, color=COLORS["energy"], lw=0.9, label="error at each row")
    ax.set_yscale("log")
    drift = float(tr.energy_drift)
    if drift > 0 and math.isfinite(drift):
        ax.axhline(drift, color=COLORS["reference"], lw=0.9, ls="--", label=f"reported energy_drift = {fmt(drift, 3)}")
    else:
        ax.plot([], [], ls="none", label=f"reported energy_drift = {fmt(drift, 3)}")
    n_floor = int(np.count_nonzero(err < ENERGY_FLOOR))
    if n_floor:
        what = "row" if n_floor == 1 else "rows"
        ax.text(
            0.99, 0.03, f"{n_floor} {what} below {fmt(ENERGY_FLOOR)} (e.g. 0 at t = 0) drawn at {fmt(ENERGY_FLOOR)}",
            transform=ax.transAxes, ha="right", va="bottom", fontsize=7.5, color="0.35",
        )
    if relative:
        ax.set_ylabel(r"$|E - W - E_0|\,/\,\max|E|$ [1]")
        ax.set_title("Energy error (W: work of damping and torques)", loc="left")
    else:
        ax.set_ylabel(r"$|E - W - E_0|$ [J]")
        ax.set_title("Energy error, absolute (E = 0 throughout)", loc="left")
    ax.set_xlabel("t [s]")
    ax.set_xlim(tr.t[0], tr.t[-1])
    ax.legend(loc="lower left", bbox_to_anchor=(0.015, 0.0))


def _angle_name(tr, k: int) -> str:
    """Joint k's angle as an axis label: its symbol (the double pendulum's phi and psi, a chain's q1 ... qn)."""
    return coordinate_styles(tr.params.coordinates)[k][1]


def _draw_phase(ax, tr, k: int) -> None:
    n = tr.y.shape[1] // 2
    color, _, speed = _labels(tr)[k]
    path = wrapped_path([np.unwrap(tr.y[:, k]), tr.y[:, n + k]], [True, False])
    ax.plot(np.degrees(path[:, 0]), path[:, 1], color=color, **_thin(len(tr.t)))
    ax.plot([math.degrees(wrap_angle(tr.y[0, k]))], [tr.y[0, n + k]], "o", color=COLORS["start"], ms=5,
            label="start (t = 0)", zorder=3)
    ax.set_xlabel(f"{_angle_name(tr, k)} (wrapped) [deg]")
    ax.set_ylabel(f"{speed} [rad/s]")
    ax.set_title(f"Phase portrait, hinge {k + 1}", loc="left")
    if np.any(np.isnan(path[:, 0])):  # it went over the top: show the whole circle
        ax.set_xlim(-180, 180)
        _angle_ticks(ax, "x")
    _legend_above(ax)


def _draw_torus(ax, tr) -> None:
    path = np.degrees(wrapped_path([np.unwrap(tr.y[:, 0]), np.unwrap(tr.y[:, 1])], [True, True]))
    ax.plot(path[:, 0], path[:, 1], color=COLORS["path"], **_thin(len(tr.t), 0.7))
    ax.plot([math.degrees(wrap_angle(tr.y[0, 0]))], [math.degrees(wrap_angle(tr.y[0, 1]))], "o",
            color=COLORS["start"], ms=5, label="start (t = 0)", zorder=3)
    ax.set_xlim(-180, 180)
    ax.set_ylim(-180, 180)
    ax.set_aspect("equal")
    _angle_ticks(ax, "x")
    _angle_ticks(ax, "y")
    ax.set_xlabel(f"{_angle_name(tr, 0)} (wrapped) [deg]")
    ax.set_ylabel(f"{_angle_name(tr, 1)} (wrapped) [deg]")
    every = tr.y.shape[1] // 2 <= 2  # the torus holds every angle: the whole configuration space
    ax.set_title("Configuration space (torus)" if every else "The first two angles (a torus)", loc="left")
    _legend_above(ax)


def tips_view(tips: np.ndarray) -> np.ndarray:
    """World rod ends ``(x1, y1, z1, x2, y2, z2, ...)`` as drawn by :func:`tips_figure`: each end at
    ``(x, z, -y)`` (``-y`` up, since the world's ``y`` points down)."""
    tips = np.asarray(tips, dtype=float)
    return np.column_stack([col for k in range(tips.shape[1] // 3)
                            for col in (tips[:, 3 * k], tips[:, 3 * k + 2], -tips[:, 3 * k + 1])])


def _draw_tips(ax, tr, zoom: float = 1.0) -> None:
    from matplotlib.ticker import MaxNLocator

    from ..drawing import link_points

    n = tr.y.shape[1] // 2
    # the drawn chain (views.drawing): hinge 1, then each link's drawn end (the next hinge, the last rod's end)
    every = tips_view(link_points(tr.params, tr.y, tr.tips()).reshape(len(tr.y), 3 * (n + 1)))
    o, v = every[:, :3], every[:, 3:]
    # up to two rods: each end's path; more: the tip's alone (the inner ones would crowd it)
    drawn = list(enumerate(_labels(tr)))
    drawn = drawn[-1:] if n > 2 else drawn
    for k, (color, _, _) in drawn:
        ax.plot(v[:, 3 * k], v[:, 3 * k + 1], v[:, 3 * k + 2], color=color,
                label=f"end of rod {k + 1}" if len(drawn) > 1 else f"tip (end of rod {n})", **_thin(len(v)))
    # the rods at t = 0 and the pivot (hinge 1) on the first hinge axis
    ax.plot([o[0, 0]] + [v[0, 3 * k] for k in range(n)], [o[0, 1]] + [v[0, 3 * k + 1] for k in range(n)],
            [o[0, 2]] + [v[0, 3 * k + 2] for k in range(n)], color=COLORS["rods"], lw=2.2, marker="o", ms=3, alpha=0.8,
            label="rods at t = 0")
    ax.plot([o[0, 0]], [o[0, 1]], [o[0, 2]], marker="s", color="black", ms=5, ls="none", label="pivot")
    pts = np.vstack([o[:1]] + [v[:, 3 * k:3 * k + 3] for k in range(n)])
    pts = pts[np.all(np.isfinite(pts), axis=1)]
    lo, hi = pts.min(axis=0), pts.max(axis=0)
    centre, half = (lo + hi) / 2, max(float(np.max(hi - lo)) / 2 * 1.05, 1e-9)
    for set_lim, c in zip((ax.set_xlim, ax.set_ylim, ax.set_zlim), centre):
        set_lim(c - half, c + half)
    ax.set_box_aspect((1, 1, 1), zoom=zoom)
    ax.set_xlabel("x [m]")
    ax.set_ylabel("z [m]")
    ax.set_zlabel("−y [m] (up)")
    for axis in (ax.xaxis, ax.yaxis, ax.zaxis):
        axis.set_major_locator(MaxNLocator(5, steps=[1, 2, 2.5, 5, 10]))
    ax.view_init(elev=18, azim=-58)
    first = np.asarray(tr.axes(), dtype=float)[0, :3]  # hinge 1's axis (fixed): named where it is the plot's z
    along_z = abs(abs(float(first[2])) - 1.0) < 1e-9
    ax.set_title("Rod ends in 3D (z: hinge 1 axis)" if along_z else "Rod ends in 3D", loc="left")
    legend = ax.legend(loc="upper left", fontsize=7.5, bbox_to_anchor=(0.0, 0.98))
    for handle in getattr(legend, "legend_handles", None) or legend.legendHandles:  # paths may be drawn thin
        if handle.get_label() != "pivot":
            handle.set_linewidth(max(handle.get_linewidth(), 1.2))
        handle.set_alpha(1.0)


# -- figures ------------------------------------------------------------------------------------
def angles_figure(tr):
    """phi and psi [deg] (unwrapped) against t [s]; below, their speeds [rad/s]."""
    _check(tr)
    with style():
        fig = new_figure((8.0, 6.4))
        ax1, ax2 = fig.subplots(2, 1, sharex=True)
        _draw_angles(ax1, tr)
        _draw_speeds(ax2, tr)
        ax2.set_xlabel("t [s]")
        heading(fig, caption(tr))
    return fig


def phase_figure(tr):
    """Phase portraits (phi, dphi) and (psi, dpsi): angle wrapped to (-180, 180] [deg], speed [rad/s];
    a chain's (q_k, dq_k) for each joint, three to a row."""
    _check(tr)
    n = tr.y.shape[1] // 2
    cols = min(n, 3)
    rows = -(-n // cols)
    with style():
        fig = new_figure((10.0 if cols == 2 else 12.0, 4.9 + 3.9 * (rows - 1)))
        axes = np.atleast_1d(fig.subplots(rows, cols)).ravel()
        for k in range(n):
            _draw_phase(axes[k], tr, k)
        for ax in axes[n:]:
            ax.set_visible(False)
        heading(fig, caption(tr))
    return fig


def _one_panel(tr, figsize, draw, projection=None):
    """A figure of ``tr`` with one panel, drawn by ``draw(ax, tr)``, and the trajectory's heading."""
    _check(tr)
    with style():
        fig = new_figure(figsize)
        draw(fig.add_subplot(projection=projection), tr)
        heading(fig, caption(tr))
    return fig


def energy_figure(tr):
    """The energy error ``|E - W - E0| / max|E|`` on a log scale against t, the reported
    ``energy_drift`` as a dashed line; values below :data:`ENERGY_FLOOR` drawn at it (said so)."""
    return _one_panel(tr, (8.0, 4.4), _draw_energy)


def torus_figure(tr):
    """The path in configuration space: (phi, psi) wrapped to (-180, 180] [deg] on the square
    whose opposite edges are identified (a torus), cut where it wraps."""
    return _one_panel(tr, (6.4, 6.9), _draw_torus)


def tips_figure(tr):
    """The paths of both rod ends in 3D [m], the rods at t = 0 and the pivot; world ``(x, y, z)``
    drawn at ``(x, z, -y)`` (see :func:`tips_view`) so the pendulum hangs down; equal scales.  The rods as every
    view draws them (:func:`skewpend.views.drawing.link_points`): a link's end is the next link's hinge (a rotary
    pendulum's arm ends where its pendulum hangs), the last rod's its tip."""
    return _one_panel(tr, (7.0, 7.3), _draw_tips, "3d")


def simulation_figure(tr):
    """Everything in one figure (for ``skewpend simulate --plot``): angles, speeds and the energy error
    against time on the left; each joint's phase portrait in the middle (up to three joints: more would
    crowd the column); the torus of the first two angles and the 3D paths of the rod ends on the right."""
    _check(tr)
    n = tr.y.shape[1] // 2
    portraits = n if n <= 3 else 0
    with style():
        fig = new_figure((17.0 if portraits else 14.0, 10.0))
        columns = fig.subfigures(1, 3 if portraits else 2, width_ratios=[1.55, 1.0, 1.0][:3 if portraits else 2],
                                 wspace=0.01)
        left, right = columns[0], columns[-1]
        a1, a2, a3 = left.subplots(3, 1, sharex=True)
        _draw_angles(a1, tr)
        _draw_speeds(a2, tr)
        _draw_energy(a3, tr)
        for k, ax in enumerate(np.atleast_1d(columns[1].subplots(portraits, 1)) if portraits else ()):
            _draw_phase(ax, tr, k)
        if n >= 2:
            _draw_torus(right.add_subplot(2, 1, 1), tr)
            _draw_tips(right.add_subplot(2, 1, 2, projection="3d"), tr, zoom=0.88)  # room for the labels in the small panel
        else:
            _draw_tips(right.add_subplot(1, 1, 1, projection="3d"), tr, zoom=0.9)
        heading(fig, caption(tr))
    return fig


def plot_sweep(sw, *, title: Optional[str] = None):
    """Frequencies and mode-shape directions along a :class:`~skewpend.modes.Sweep`.

    Top: ``w1, w2`` [rad/s] against the swept variable (degrees for alpha and a chain's tilts),
    internal resonances marked.  Bottom: the direction of each mode shape in the (phi, psi) plane
    [deg] (modulo 180, unwrapped), which shows how the modes turn at a veering without the
    infinite ``psi/phi`` ratios of a mode where phi stands still.  A chain of more than two links:
    its n frequencies, the resonances between neighbouring modes marked (a shape of n angles has
    no direction in a plane: no bottom panel).
    """
    n = sw.frequencies.shape[1]
    names = sw.params.coordinates
    one_pair = n - 1 == 1  # two modes: one pair of neighbours (written plainly), their shapes directions in a plane
    angle_like = sw.name == "alpha" or sw.name.startswith("tilt")
    if angle_like:
        x, xlabel = np.degrees(sw.values), (r"$\alpha$" if sw.name == "alpha" else sw.name) + " [deg]"
    else:
        unit = sw.units().get(sw.name, "")
        x, xlabel = np.asarray(sw.values, dtype=float), f"{sw.name} [{unit or '1'}]"
    with style():
        fig = new_figure((7.5, 7.0) if one_pair else (7.5, 4.6))
        ax1, ax2 = fig.subplots(2, 1, sharex=True) if one_pair else (fig.subplots(1, 1), None)
        ends = {0: " (lower mode)", n - 1: " (upper mode)"} if one_pair else {}
        for k in range(n):
            ax1.plot(x, sw.frequencies[:, k], label=rf"$\omega_{{{k + 1}}}$" + ends.get(k, ""),
                     color=MODE_COLORS.get(k + 1, "0.3"))
        for i, r in enumerate(sw.resonances):
            xv = math.degrees(r.value) if angle_like else r.value
            ax1.axvline(xv, color=COLORS["reference"], lw=0.8, ls="--")
            mark = f"{r.order}:1" if one_pair else f"ω{r.pair[1]}:ω{r.pair[0]} = {r.order}:1"
            ax1.annotate(mark, (xv, 1.0), xycoords=ax1.get_xaxis_transform(), textcoords="offset points",
                         xytext=(3, -12 - (11 * (i % 3) if n > 2 else 0)), fontsize=8, color="0.3")
        ax1.set_ylabel("natural frequency [rad/s]")
        ax1.set_title("Natural frequencies (dashed: internal resonances " + (
            r"$\omega_2 = n\,\omega_1$)" if one_pair else r"$\omega_{k+1} = n\,\omega_k$)"), loc="left")
        ax1.legend(loc="best", ncol=1 if n <= 4 else 2)
        last = ax1
        if ax2 is not None:
            # a mode shape is a direction: defined modulo 180 deg; unwrap to continuous curves
            angle = np.degrees(np.arctan2(sw.shapes[:, 1, :], sw.shapes[:, 0, :]))
            angle = np.unwrap((angle + 90.0) % 180.0 - 90.0, period=180.0, axis=0)
            (c1, s1, _), (c2, s2, _) = coordinate_styles(names)
            ax2.plot(x, angle[:, 0], color=c1, label="mode 1")
            ax2.plot(x, angle[:, 1], color=c2, label="mode 2")
            ax2.set_ylabel(f"direction in the ({s1}, {s2}) plane [deg]")
            ax2.set_title(f"Mode shapes: direction of ({s1}, {s2}), modulo 180°", loc="left")
            ax2.legend(loc="best")
            last = ax2
        last.set_xlabel(xlabel)
        if len(x) > 1 and x[0] != x[-1]:
            last.set_xlim(x[0], x[-1])
        text = sweep_caption(sw)
        heading(fig, f"{title}\n{text}" if title else text)
    return fig
