"""Figures from result objects: they draw what a :class:`skewpend.Trajectory`, a
:class:`skewpend.modes.Sweep` or a :class:`skewpend.FlipMap` holds and never integrate or derive
anything (the flip map's energy-forbidden region evaluates the model's compiled potential).

Every function returns a :class:`matplotlib.figure.Figure` built with the object-oriented
API (no pyplot, no GUI backend, global rcParams untouched) in the style of
:mod:`skewpend.views.style`; the figure's heading states the parameters, the initial state
and the integrator settings.  Save one with :func:`save_figure` (PNG, SVG or PDF).

Units: time [s]; angles in **degrees** (phi, psi; unwrapped against time, wrapped to
(-180, 180] in the phase portraits and on the torus); angular speeds [rad/s] (as in the
trajectory); rod ends [m].  The 3D view plots the world point ``(x, y, z)`` at
``(x, z, -y)``: the world's ``j`` (``y``) points down, so ``-y`` is drawn upwards and the
pendulum hangs down from its pivot; ``z`` is the first hinge axis ``k``.

Needs matplotlib (a dependency of skewpend), imported on first use.
"""

from __future__ import annotations

import math
from pathlib import Path
from typing import List, Optional, Sequence

import numpy as np

from .. import __version__
from ..errors import ParameterError, SkewpendError

from .style import COLORS, DPI, SYMBOL, caption, flipmap_caption, flipmap_window, fmt, style, sweep_caption

__all__ = [
    "angles_figure",
    "phase_figure",
    "energy_figure",
    "torus_figure",
    "tips_figure",
    "simulation_figure",
    "plot_sweep",
    "flipmap_figure",
    "flipmap_forbidden",
    "flipmap_energy_margin",
    "FLIPMAP_COLORS",
    "save_figure",
    "FORMATS",
    "FIGURE_SUFFIXES",
    "ENERGY_FLOOR",
    "wrap_angle",
    "wrapped_path",
    "tips_view",
]

#: File formats :func:`save_figure` writes, by suffix.
FIGURE_SUFFIXES = FORMATS = (".png", ".svg", ".pdf")

#: The relative energy error is drawn no lower than this on its log axis (exact zeros, e.g. at t = 0).
ENERGY_FLOOR = 1e-17

_TWO_PI = 2.0 * math.pi


# -- helpers ---------------------------------------------------------------------------------------
def _figure_class():
    try:
        import mpl_toolkits.mplot3d  # noqa: F401  (registers the "3d" projection)
        from matplotlib.figure import Figure
    except ImportError:  # pragma: no cover - depends on the installation
        raise SkewpendError("figures need matplotlib (a dependency of skewpend): pip install matplotlib") from None
    return Figure


def _new_figure(figsize):
    """A figure with constrained layout (call inside :func:`style`)."""
    return _figure_class()(figsize=figsize, layout="constrained")


def _heading(fig, text: str) -> None:
    fig.suptitle(text, fontsize=8.5, color="0.25", linespacing=1.45)


def _check(tr) -> None:
    if not getattr(tr, "kept", True):
        raise ParameterError(
            "this trajectory kept only its first and last rows (simulate(..., keep=False)); figures need "
            "every row: simulate with keep=True (the default) to plot it"
        )
    if len(tr.t) < 2:
        raise ParameterError(f"a figure needs at least two rows of the trajectory, it has {len(tr.t)}")


def wrap_angle(x):
    """Angles [rad] wrapped to (-pi, pi]."""
    return math.pi - np.mod(math.pi - np.asarray(x, dtype=float), _TWO_PI)


def _cell(p: np.ndarray, wrap: np.ndarray) -> np.ndarray:
    """Which copy of the square a point (unwrapped coordinates) lies in: k with p = wrapped + 2 pi k."""
    k = np.zeros_like(p)
    k[..., wrap] = np.round((p[..., wrap] - wrap_angle(p[..., wrap])) / _TWO_PI)
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
        return P - _TWO_PI * K
    nan_row = np.full((1, P.shape[1]), np.nan)
    pieces: List[np.ndarray] = []
    start = 0
    for i in jumps:
        pieces.append(P[start : i + 1] - _TWO_PI * K[start : i + 1])
        a, b = P[i], P[i + 1]
        crossings = []
        for j in np.nonzero(W)[0]:
            if b[j] == a[j]:
                continue
            lo, hi = min(a[j], b[j]), max(a[j], b[j])
            for m in range(math.ceil((lo - math.pi) / _TWO_PI), math.floor((hi - math.pi) / _TWO_PI) + 1):
                crossings.append((math.pi + _TWO_PI * m - a[j]) / (b[j] - a[j]))
        crossings.sort()
        bounds = [0.0, *crossings, 1.0]
        for n, s in enumerate(crossings):
            c = a + s * (b - a)
            before = _cell(a + 0.5 * (bounds[n] + s) * (b - a), W)
            after = _cell(a + 0.5 * (s + bounds[n + 2]) * (b - a), W)
            if np.array_equal(before, after):
                continue
            pieces += [(c - _TWO_PI * before)[None], nan_row, (c - _TWO_PI * after)[None]]
        start = i + 1
    pieces.append(P[start:] - _TWO_PI * K[start:])
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
def _draw_angles(ax, tr) -> None:
    phi, psi = np.degrees(np.unwrap(tr.y[:, 0])), np.degrees(np.unwrap(tr.y[:, 1]))
    ax.plot(tr.t, phi, color=COLORS["phi"], label=f"{SYMBOL['phi']} (hinge 1)")
    ax.plot(tr.t, psi, color=COLORS["psi"], label=f"{SYMBOL['psi']} (hinge 2)")
    _turn_ticks(ax.yaxis, np.concatenate([phi, psi]))
    ax.set_ylabel("angle [deg]")
    ax.set_title("Hinge angles (unwrapped)", loc="left")
    _legend_above(ax)
    ax.set_xlim(tr.t[0], tr.t[-1])


def _draw_speeds(ax, tr) -> None:
    ax.plot(tr.t, tr.y[:, 2], color=COLORS["phi"], label=SYMBOL["dphi"])
    ax.plot(tr.t, tr.y[:, 3], color=COLORS["psi"], label=SYMBOL["dpsi"])
    ax.set_ylabel("angular speed [rad/s]")
    ax.set_title("Angular speeds", loc="left")
    _legend_above(ax)
    ax.set_xlim(tr.t[0], tr.t[-1])


def _energy_error(tr):
    scale = float(np.max(np.abs(tr.energy)))
    err = np.abs(tr.energy - tr.work - tr.energy[0])
    return (err / scale, True) if scale > 0 else (err, False)


def _draw_energy(ax, tr) -> None:
    err, relative = _energy_error(tr)
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


def _draw_phase(ax, tr, k: int) -> None:
    name, speed = ("phi", "dphi") if k == 0 else ("psi", "dpsi")
    path = wrapped_path([np.unwrap(tr.y[:, k]), tr.y[:, k + 2]], [True, False])
    ax.plot(np.degrees(path[:, 0]), path[:, 1], color=COLORS[name], **_thin(len(tr.t)))
    ax.plot([math.degrees(wrap_angle(tr.y[0, k]))], [tr.y[0, k + 2]], "o", color=COLORS["start"], ms=5,
            label="start (t = 0)", zorder=3)
    ax.set_xlabel(f"{SYMBOL[name]} (wrapped) [deg]")
    ax.set_ylabel(f"{SYMBOL[speed]} [rad/s]")
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
    ax.set_xlabel(f"{SYMBOL['phi']} (wrapped) [deg]")
    ax.set_ylabel(f"{SYMBOL['psi']} (wrapped) [deg]")
    ax.set_title("Configuration space (torus)", loc="left")
    _legend_above(ax)


def tips_view(tips: np.ndarray) -> np.ndarray:
    """World rod ends ``(x1, y1, z1, x2, y2, z2)`` as drawn by :func:`tips_figure`: each end at
    ``(x, z, -y)`` (``-y`` up, since the world's ``y`` points down)."""
    tips = np.asarray(tips, dtype=float)
    return np.column_stack([tips[:, 0], tips[:, 2], -tips[:, 1], tips[:, 3], tips[:, 5], -tips[:, 4]])


def _draw_tips(ax, tr, zoom: float = 1.0) -> None:
    from matplotlib.ticker import MaxNLocator

    v = tips_view(tr.tips())
    ax.plot(v[:, 0], v[:, 1], v[:, 2], color=COLORS["phi"], label="end of rod 1", **_thin(len(v)))
    ax.plot(v[:, 3], v[:, 4], v[:, 5], color=COLORS["psi"], label="end of rod 2", **_thin(len(v)))
    # the rods at t = 0 and the pivot on the first hinge axis
    ax.plot([0, v[0, 0], v[0, 3]], [0, v[0, 1], v[0, 4]], [0, v[0, 2], v[0, 5]], color=COLORS["rods"], lw=2.2,
            marker="o", ms=3, alpha=0.8, label="rods at t = 0")
    ax.plot([0], [0], [0], marker="s", color="black", ms=5, ls="none", label="pivot")
    pts = np.vstack([np.zeros((1, 3)), v[:, :3], v[:, 3:]])
    pts = pts[np.all(np.isfinite(pts), axis=1)]
    lo, hi = pts.min(axis=0), pts.max(axis=0)
    centre, half = (lo + hi) / 2, max(float(np.max(hi - lo)) / 2 * 1.05, 1e-9)
    ax.set_xlim(centre[0] - half, centre[0] + half)
    ax.set_ylim(centre[1] - half, centre[1] + half)
    ax.set_zlim(centre[2] - half, centre[2] + half)
    ax.set_box_aspect((1, 1, 1), zoom=zoom)
    ax.set_xlabel("x [m]")
    ax.set_ylabel("z [m]")
    ax.set_zlabel("−y [m] (up)")
    for axis in (ax.xaxis, ax.yaxis, ax.zaxis):
        axis.set_major_locator(MaxNLocator(5, steps=[1, 2, 2.5, 5, 10]))
    ax.view_init(elev=18, azim=-58)
    ax.set_title("Rod ends in 3D (z: hinge 1 axis)", loc="left")
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
        fig = _new_figure((8.0, 6.4))
        ax1, ax2 = fig.subplots(2, 1, sharex=True)
        _draw_angles(ax1, tr)
        _draw_speeds(ax2, tr)
        ax2.set_xlabel("t [s]")
        _heading(fig, caption(tr))
    return fig


def phase_figure(tr):
    """Phase portraits (phi, dphi) and (psi, dpsi): angle wrapped to (-180, 180] [deg], speed [rad/s]."""
    _check(tr)
    with style():
        fig = _new_figure((10.0, 4.9))
        ax1, ax2 = fig.subplots(1, 2)
        _draw_phase(ax1, tr, 0)
        _draw_phase(ax2, tr, 1)
        _heading(fig, caption(tr))
    return fig


def energy_figure(tr):
    """The energy error ``|E - W - E0| / max|E|`` on a log scale against t, the reported
    ``energy_drift`` as a dashed line; values below :data:`ENERGY_FLOOR` drawn at it (said so)."""
    _check(tr)
    with style():
        fig = _new_figure((8.0, 4.4))
        ax = fig.subplots()
        _draw_energy(ax, tr)
        _heading(fig, caption(tr))
    return fig


def torus_figure(tr):
    """The path in configuration space: (phi, psi) wrapped to (-180, 180] [deg] on the square
    whose opposite edges are identified (a torus), cut where it wraps."""
    _check(tr)
    with style():
        fig = _new_figure((6.4, 6.9))
        ax = fig.subplots()
        _draw_torus(ax, tr)
        _heading(fig, caption(tr))
    return fig


def tips_figure(tr):
    """The paths of both rod ends in 3D [m], the rods at t = 0 and the pivot; world ``(x, y, z)``
    drawn at ``(x, z, -y)`` (see :func:`tips_view`) so the pendulum hangs down; equal scales."""
    _check(tr)
    with style():
        fig = _new_figure((7.0, 7.3))
        ax = fig.add_subplot(projection="3d")
        _draw_tips(ax, tr)
        _heading(fig, caption(tr))
    return fig


def simulation_figure(tr):
    """Everything in one figure (for ``skewpend simulate --plot``): angles, speeds and the
    energy error against time on the left; the two phase portraits in the middle; the torus
    and the 3D paths of the rod ends on the right."""
    _check(tr)
    with style():
        fig = _new_figure((17.0, 10.0))
        left, middle, right = fig.subfigures(1, 3, width_ratios=[1.55, 1.0, 1.0], wspace=0.01)
        a1, a2, a3 = left.subplots(3, 1, sharex=True)
        _draw_angles(a1, tr)
        _draw_speeds(a2, tr)
        _draw_energy(a3, tr)
        p1, p2 = middle.subplots(2, 1)
        torus = right.add_subplot(2, 1, 1)
        tips = right.add_subplot(2, 1, 2, projection="3d")
        _draw_phase(p1, tr, 0)
        _draw_phase(p2, tr, 1)
        _draw_torus(torus, tr)
        _draw_tips(tips, tr, zoom=0.88)  # room for the tick and axis labels in the small panel
        _heading(fig, caption(tr))
    return fig


def plot_sweep(sw, *, title: Optional[str] = None):
    """Frequencies and mode-shape directions along a :class:`~skewpend.modes.Sweep`.

    Top: ``w1, w2`` [rad/s] against the swept variable (degrees for alpha), internal
    resonances marked.  Bottom: the direction of each mode shape in the (phi, psi) plane
    [deg] (modulo 180, unwrapped), which shows how the modes turn at a veering without the
    infinite ``psi/phi`` ratios of a mode where phi stands still.
    """
    if sw.name == "alpha":
        x, xlabel = np.degrees(sw.values), r"$\alpha$ [deg]"
    else:
        unit = sw.units().get(sw.name, "")
        x, xlabel = np.asarray(sw.values, dtype=float), f"{sw.name} [{unit or '1'}]"
    with style():
        fig = _new_figure((7.5, 7.0))
        ax1, ax2 = fig.subplots(2, 1, sharex=True)
        ax1.plot(x, sw.frequencies[:, 0], label=r"$\omega_1$ (lower mode)", color=COLORS["phi"])
        ax1.plot(x, sw.frequencies[:, 1], label=r"$\omega_2$ (upper mode)", color=COLORS["psi"])
        for r in sw.resonances:
            xv = math.degrees(r.value) if sw.name == "alpha" else r.value
            ax1.axvline(xv, color=COLORS["reference"], lw=0.8, ls="--")
            ax1.annotate(f"{r.order}:1", (xv, 1.0), xycoords=ax1.get_xaxis_transform(), textcoords="offset points",
                         xytext=(3, -12), fontsize=8, color="0.3")
        ax1.set_ylabel("natural frequency [rad/s]")
        ax1.set_title("Natural frequencies (dashed: internal resonances " + r"$\omega_2 = n\,\omega_1$)", loc="left")
        ax1.legend(loc="best")
        # a mode shape is a direction: defined modulo 180 deg; unwrap to continuous curves
        angle = np.degrees(np.arctan2(sw.shapes[:, 1, :], sw.shapes[:, 0, :]))
        angle = np.unwrap((angle + 90.0) % 180.0 - 90.0, period=180.0, axis=0)
        ax2.plot(x, angle[:, 0], color=COLORS["phi"], label="mode 1")
        ax2.plot(x, angle[:, 1], color=COLORS["psi"], label="mode 2")
        ax2.set_ylabel(f"direction in the ({SYMBOL['phi']}, {SYMBOL['psi']}) plane [deg]")
        ax2.set_title(f"Mode shapes: direction of ({SYMBOL['phi']}, {SYMBOL['psi']}), modulo 180°", loc="left")
        ax2.set_xlabel(xlabel)
        if len(x) > 1 and x[0] != x[-1]:
            ax2.set_xlim(x[0], x[-1])
        ax2.legend(loc="best")
        heading = sweep_caption(sw)
        _heading(fig, f"{title}\n{heading}" if title else heading)
    return fig


# -- the flip-time map ----------------------------------------------------------------------------------
#: Colours of the flip-time map: the colour map of the flip times (log scale), the cells that do not
#: flip by t_end, the cells that energy forbids to flip and the line around them.
FLIPMAP_COLORS = {
    "cmap": "viridis_r",
    "no_flip": "#ffffff",
    "forbidden": "#d4d4d4",
    "boundary": "0.35",
    "mark": "#e4572e",
}


def flipmap_energy_margin(fm) -> Optional[np.ndarray]:
    """``fm.energy_margin()`` (:meth:`skewpend.FlipMap.energy_margin`: negative where energy
    forbids a flip), or None if the compiled potential cannot be had here (no compiler)."""
    try:
        return fm.energy_margin()
    except (SkewpendError, OSError):
        return None


def flipmap_forbidden(fm) -> Optional[np.ndarray]:
    """The cells of ``fm`` that energy alone forbids to flip, as a boolean array laid out like
    ``fm.flip_time``: released at rest, ``V = Pi - tau . q`` (which never increases: damping only
    dissipates) starts below its minimum ``V_min`` on the boundary of the square ``(-pi, pi)^2``
    -- the test :func:`skewpend.flip_map` uses to skip them.  Evaluates the compiled potential of
    ``fm.params`` (cached with the map's kernel); None if that is impossible here (no compiler)."""
    margin = flipmap_energy_margin(fm)
    return None if margin is None else margin < 0


def _degree_ticks(axis, lo: float, hi: float) -> None:
    """Major ticks at multiples of 90, 45, 30, 15, ... degrees (about 4 to 8 of them), minor between."""
    from matplotlib.ticker import AutoMinorLocator, MaxNLocator, MultipleLocator

    span = hi - lo
    minor = {90: 45, 45: 15, 30: 10, 15: 5, 10: 5, 5: 1, 2: 1, 1: 0.5}
    for base in (90, 45, 30, 15, 10, 5, 2, 1):
        if span / base >= 3.9:
            axis.set_major_locator(MultipleLocator(base))
            axis.set_minor_locator(MultipleLocator(minor[base]))
            return
    axis.set_major_locator(MaxNLocator(6, steps=[1, 2, 2.5, 5, 10]))
    axis.set_minor_locator(AutoMinorLocator())


def _to_edges(centres: np.ndarray, lo: float, hi: float) -> np.ndarray:
    """Cell centres with the window's edges added at both ends."""
    return np.concatenate([[lo], centres, [hi]])


def _extend(values: np.ndarray, coords: np.ndarray, axis: int) -> np.ndarray:
    """``values`` at the inner ``coords`` (cell centres) extended linearly to the outer two
    (the window's edges) along ``axis``."""
    v = np.moveaxis(np.asarray(values, dtype=float), axis, 0)
    c = coords
    first = v[0] + (v[0] - v[1]) * (c[0] - c[1]) / (c[1] - c[2]) if len(v) > 1 else v[0]
    last = v[-1] + (v[-1] - v[-2]) * (c[-1] - c[-2]) / (c[-2] - c[-3]) if len(v) > 1 else v[-1]
    return np.moveaxis(np.concatenate([first[None], v, last[None]]), 0, axis)


def _log_ticks(lo: float, hi: float) -> List[float]:
    """1, 2, 5 times powers of ten between lo and hi, and hi itself (t_end)."""
    ticks = [m * 10.0 ** k for k in range(math.floor(math.log10(lo)), math.ceil(math.log10(hi)) + 1) for m in (1, 2, 5)]
    ticks = [t for t in ticks if lo * (1 - 1e-9) <= t <= hi * (1 + 1e-9)]
    if len(ticks) > 8:
        ticks = [t for t in ticks if math.isclose(math.log10(t) % 1, 0, abs_tol=1e-9) or
                 math.isclose(math.log10(t) % 1, 1, abs_tol=1e-9)]
    if not any(math.isclose(t, hi, rel_tol=1e-6) for t in ticks):
        ticks = [t for t in ticks if t < hi / 1.3] + [hi]
    return ticks


def _wrap_deg(x: float) -> float:
    return math.degrees(float(wrap_angle(float(x))))


def _degree_extent(result) -> list:
    """``[phi_lo, phi_hi, psi_lo, psi_hi]`` in degrees: the window of a map over starts at rest."""
    (phi_lo, phi_hi), (psi_lo, psi_hi) = flipmap_window(result)
    return [math.degrees(phi_lo), math.degrees(phi_hi), math.degrees(psi_lo), math.degrees(psi_hi)]


def _start_map_axes(ax, extent, title: str) -> None:
    """The axes of a map over starts at rest (flip map, Lyapunov map): limits, degree ticks
    outwards, a closed frame, the hinge labels and the title."""
    ax.set_xlim(extent[0], extent[1])
    ax.set_ylim(extent[2], extent[3])
    _degree_ticks(ax.xaxis, extent[0], extent[1])
    _degree_ticks(ax.yaxis, extent[2], extent[3])
    ax.tick_params(which="both", direction="out")
    for side in ("top", "right"):
        ax.spines[side].set_visible(True)
    ax.set_xlabel(r"$\varphi_0$, hinge 1 at release [deg]")
    ax.set_ylabel(r"$\psi_0$, hinge 2 at release [deg]")
    ax.set_title(title, loc="left")


def flipmap_figure(fm, *, mark: Optional[Sequence[float]] = None, mark_label: str = "start",
                   forbidden="auto"):
    """The flip-time map of a :class:`skewpend.FlipMap`, the classic picture.

    The image is ``fm.flip_time`` **transposed**, drawn with ``origin="lower"``: ``phi0`` on the
    x axis, ``psi0`` on the y axis, both in degrees over the map's window (the image's extent
    is the cells' outer edges).  Flip times on a logarithmic colour scale (:class:`LogNorm`)
    from the shortest flip time to ``t_end``, with a colour bar "flip time [s]"; the cells that
    do not flip by ``t_end`` (NaN) in flat white; the cells that energy alone forbids to flip
    (:func:`flipmap_forbidden`) in light grey with a line around them (``forbidden``: "auto"
    computes them, None leaves them white; or an array like ``fm.flip_time``: boolean, or
    :func:`flipmap_energy_margin`, negative where forbidden, whose zero line is the edge).  ``mark``:
    a point ``(phi0, psi0)`` [rad, wrapped to (-180, 180]] drawn with the legend entry
    ``mark_label``.  The heading states the parameters, the grid and the integrator settings
    (:func:`skewpend.views.style.flipmap_caption`).
    """
    from matplotlib.colors import ListedColormap, LogNorm
    from matplotlib.lines import Line2D
    from matplotlib.patches import Patch
    from matplotlib.ticker import FixedLocator, FuncFormatter, NullFormatter

    import matplotlib

    ft = np.asarray(fm.flip_time, dtype=float)
    if ft.ndim != 2 or ft.size == 0:
        raise ParameterError(f"a flip map needs a 2-D array of flip times, got shape {ft.shape}")
    extent = _degree_extent(fm)
    finite = ft[np.isfinite(ft)]
    t_end = float(fm.settings.get("t_end") or (np.max(finite) if finite.size else 1.0))
    vmin = float(np.min(finite)) if finite.size else t_end / 100.0
    if not 0 < vmin < t_end:
        vmin = min(max(vmin, 1e-300), t_end) / 10.0 if vmin > 0 else t_end / 100.0
    margin = None
    if isinstance(forbidden, str):
        if forbidden != "auto":
            raise ParameterError(f"forbidden must be 'auto', None or an array like the map's, got {forbidden!r}")
        forbidden = flipmap_energy_margin(fm)
    if forbidden is not None:
        forbidden = np.asarray(forbidden)
        if forbidden.shape != ft.shape:
            raise ParameterError(f"forbidden must have the map's shape {ft.shape}, got {forbidden.shape}")
        if forbidden.dtype != bool:  # the energy margin: negative where forbidden, and a smooth edge
            margin, forbidden = forbidden.astype(float), forbidden < 0
    colors = FLIPMAP_COLORS
    n_phi, n_psi = ft.shape
    with style():
        fig = _new_figure((6.6, 6.9))
        ax = fig.subplots()
        ax.grid(False)
        cmap = matplotlib.colormaps[colors["cmap"]].with_extremes(bad=colors["no_flip"])
        interpolation = "nearest" if max(ft.shape) <= 1024 else "antialiased"
        im = ax.imshow(np.ma.masked_invalid(ft.T), origin="lower", extent=extent, cmap=cmap,
                       norm=LogNorm(vmin=vmin, vmax=t_end), interpolation=interpolation, aspect="equal")
        handles = [Patch(facecolor=colors["no_flip"], edgecolor="0.45", lw=0.6,
                         label=f"no flip by t_end = {fmt(t_end)} s")]
        if forbidden is not None and forbidden.any():
            if margin is not None and min(ft.shape) >= 2:
                # the region where the margin is negative, with a smooth edge (its zero line), over the
                # whole window: the margin is extended linearly from the cell centres to the window's edges
                k = max(1, -(-max(ft.shape) // 1024))  # at most about 1024 points a side: plenty for a smooth line
                x = _to_edges(np.degrees(np.asarray(fm.phi0, dtype=float)[::k, 0]), extent[0], extent[1])
                y = _to_edges(np.degrees(np.asarray(fm.psi0, dtype=float)[0, ::k]), extent[2], extent[3])
                field = _extend(_extend(margin[::k, ::k], x, 0), y, 1).T
                ax.contourf(x, y, field, levels=[float(np.min(field)) - 1.0, 0.0], colors=[colors["forbidden"]])
                ax.contour(x, y, field, levels=[0.0], colors=[colors["boundary"]], linewidths=0.8)
            else:  # the cells themselves
                ax.imshow(np.ma.masked_where(~forbidden.T, np.ones(ft.T.shape)), origin="lower", extent=extent,
                          cmap=ListedColormap([colors["forbidden"]]), vmin=0, vmax=2, interpolation="nearest",
                          aspect="equal")
            handles.append(Patch(facecolor=colors["forbidden"], edgecolor=colors["boundary"], lw=0.7,
                                 label="energy forbids any flip"))
        if mark is not None:
            x, y = _wrap_deg(mark[0]), _wrap_deg(mark[1])
            ax.plot([x], [y], marker="o", ms=7.5, mfc=colors["mark"], mec="white", mew=1.4, ls="none", zorder=4)
            handles.append(Line2D([], [], marker="o", ms=7.5, mfc=colors["mark"], mec="white", mew=1.4, ls="none",
                                  label=mark_label))
        _start_map_axes(ax, extent, "Flip time: when either hinge angle first leaves (−180°, 180°)")
        # the colour bar exactly as tall as the (square) map
        bar = fig.colorbar(im, cax=ax.inset_axes([1.035, 0.0, 0.04, 1.0]))
        bar.set_label("flip time [s]")
        bar.ax.yaxis.set_major_locator(FixedLocator(_log_ticks(vmin, t_end)))
        bar.ax.yaxis.set_major_formatter(FuncFormatter(lambda v, _: fmt(v, 3)))
        bar.ax.yaxis.set_minor_formatter(NullFormatter())
        bar.ax.tick_params(which="both", direction="out")
        bar.ax.grid(False)
        ax.legend(handles=handles, loc="upper center", bbox_to_anchor=(0.5, -0.1), ncols=len(handles),
                  frameon=False, handlelength=1.4, columnspacing=1.4, borderaxespad=0.0)
        _heading(fig, flipmap_caption(fm))
    return fig


def save_figure(fig, path) -> Path:
    """Write ``fig`` to ``path`` as PNG, SVG or PDF (by the suffix, any case), atomically like
    every file skewpend writes (:func:`skewpend.io.atomic_path`): ``path`` appears only
    complete, with the umask's permissions; on any error (Ctrl-C too) nothing is left behind.
    An unknown suffix or an unwritable place is a :class:`ParameterError`."""
    from ..io import atomic_path, check_output_path

    path = check_output_path(path, FIGURE_SUFFIXES, option="figure")
    fmt_name = path.suffix.lower()[1:]
    metadata = {
        "png": {"Software": f"skewpend {__version__}"},
        "svg": {"Date": None, "Creator": f"skewpend {__version__}"},
        "pdf": {"CreationDate": None, "Creator": f"skewpend {__version__}"},
    }[fmt_name]
    with atomic_path(path) as tmp, open(tmp, "wb") as fh, style():
        fig.savefig(fh, format=fmt_name, dpi=DPI, metadata=metadata)
    return path


# -- chaos: Lyapunov spectra, Poincaré sections, the chaos diagram, Lyapunov maps ---------------------------
#: Colours of the Lyapunov exponents lambda_1 .. lambda_4 (the largest in the blue of hinge 1).
LYAPUNOV_COLORS = ("#1f63a8", "#c8312b", "#2a9d4b", "#7b4fa0")

#: Colours of the chaos figures: the chaotic fraction's colour map (0 light, 1 dark red), the lines
#: per skew angle (sampled from ``alpha_cmap``), the Lyapunov map's colour map and the colour of cells
#: without a value (no start reachable, or the integration failed), which neither colour map takes.
CHAOS_COLORS = {
    "fraction_cmap": "YlOrRd",
    "alpha_cmap": "viridis",
    "exponent_cmap": "magma",
    "no_value": "#9ecae1",
    "edge": "0.35",
}


def _signed(x: float, digits: int = 4) -> str:
    """``+0.1515``, ``-0.05``, ``0`` (a number with its sign)."""
    s = fmt(x, digits)
    return s if s.startswith("-") or s == "0" or not math.isfinite(float(x)) else "+" + s


def _value_pm(value: float, err: float) -> str:
    """``+0.151 ± 0.038``: the value to the precision of its uncertainty (two significant digits);
    ``+0.1515 ± n/a`` without one."""
    if not (math.isfinite(err) and err > 0 and math.isfinite(value)):
        return f"{_signed(value)} ± n/a" if not math.isfinite(err) else f"{_signed(value)} ± {fmt(err)}"
    d = max(0, 1 - math.floor(math.log10(err)))
    return f"{value:+.{d}f} ± {err:.{d}f}"


def _log_time_ticks(axis, lo: float, hi: float) -> None:
    """A logarithmic time axis labelled with plain numbers: 1, 2, 5, 10, 20, 50, ... (1, 10, 100, ...
    over more than four decades)."""
    from matplotlib.ticker import FuncFormatter, LogLocator, NullFormatter

    decades = math.log10(hi / lo) if lo > 0 and hi > lo else 0.0
    axis.set_major_locator(LogLocator(base=10, subs=(1.0, 2.0, 5.0) if decades <= 4 else (1.0,)))
    axis.set_major_formatter(FuncFormatter(lambda v, _: fmt(v, 3)))
    axis.set_minor_formatter(NullFormatter())


def _settings_list(settings, keys) -> List[str]:
    return [f"{k} = {fmt(settings[k])}" for k in keys if settings.get(k) is not None]


def _lyapunov_caption(spec) -> str:
    """What a Lyapunov figure shows: the parameters; the start; the method, tolerances, t_end,
    renormalisation interval, transient and windows (and, if the run stopped early, why)."""
    from .style import wrap_list, initial_text, parameter_text

    st = spec.settings
    run = [f"dop853 on the state and {spec.k} tangent vector{'s' if spec.k != 1 else ''} (Benettin, QR)"]
    run += _settings_list(st, ("rtol", "atol"))
    if st.get("t_end") is not None:
        run.append(f"t_end = {fmt(st['t_end'])} s")
    if st.get("renorm_every") is not None:
        run.append(f"renormalised every {fmt(st['renorm_every'])} s")
    if st.get("transient"):
        run.append(f"transient {fmt(st['transient'])} s (measured from t = {fmt(st.get('measured_from', 0.0))} s)")
    if st.get("windows") is not None:
        run.append(f"uncertainty from {st['windows']} windows")
    lines = [wrap_list(parameter_text(spec.params)), "released from " + initial_text(spec.y0),
             wrap_list(", ".join(run), 110)]
    if getattr(spec, "status", 0) != 0:
        lines.append(f"run {spec.message}")
    return "\n".join(lines)


def lyapunov_figure(spec):
    """The Lyapunov spectrum of a :class:`skewpend.LyapunovSpectrum`: the running estimate of each
    exponent (``spec.history[:, j]`` [1/s]) against ``spec.t`` [s] on a logarithmic time axis, one
    line per exponent, a line at 0; the legend (beside the axes, never over the curves) gives each
    final value with its standard error (``spec.uncertainty``, "n/a" with fewer than two windows)
    and, for the full spectrum, their sum.  The heading states the parameters, the start, the
    tolerances, ``t_end`` and the renormalisation interval."""
    from matplotlib.lines import Line2D

    t = np.asarray(spec.t, dtype=float)
    k = int(np.asarray(spec.exponents).size)
    hist = np.asarray(spec.history, dtype=float).reshape(len(t), k)
    symbols = [rf"$\lambda_{j + 1}$" for j in range(k)]
    with style():
        fig = _new_figure((9.0, 5.0))
        ax = fig.subplots()
        ax.axhline(0.0, color=COLORS["reference"], lw=0.9, zorder=1)
        for j in range(k):
            value, err = float(spec.exponents[j]), float(spec.uncertainty[j])
            ax.plot(t, hist[:, j], color=LYAPUNOV_COLORS[j % 4],
                    lw=1.3, label=f"{symbols[j]} = {_value_pm(value, err)} 1/s", zorder=2 + (k - j) / 10)
        if len(t) and t[0] > 0:
            ax.set_xscale("log")
            _log_time_ticks(ax.xaxis, float(t[0]), float(t[-1]))
        if len(t) > 1:
            ax.set_xlim(t[0], t[-1])
        ax.set_xlabel("t [s]" + (" (log scale)" if ax.get_xscale() == "log" else ""))
        ax.set_ylabel("exponent (running estimate) [1/s]")
        since = float(spec.settings.get("measured_from") or 0.0)
        measured = f" (measured from t = {fmt(since)} s)" if since else ""
        ax.set_title("Lyapunov exponents: running estimates" + measured, loc="left")
        if len(t) == 0:
            ax.text(0.5, 0.62, "no renormalisation was reached: nothing to draw", transform=ax.transAxes, ha="center",
                    va="center", color="0.35")
            ax.set_xlim(0.0, float(spec.settings.get("t_end") or 1.0))
        handles, labels = ax.get_legend_handles_labels()
        if k == 4:
            handles.append(Line2D([], [], ls="none"))
            labels.append(f"sum = {_signed(float(np.sum(spec.exponents)), 3)} 1/s")
        ax.legend(handles, labels, loc="upper left", bbox_to_anchor=(1.02, 1.0), borderaxespad=0.0,
                  title="final value ± standard error", title_fontsize=8.5, alignment="left", handlelength=1.6)
        _heading(fig, _lyapunov_caption(spec))
    return fig


def _pi_ticks(axis) -> None:
    """Ticks at multiples of pi/2 labelled -π, -π/2, 0, π/2, π (minor at pi/4)."""
    from matplotlib.ticker import FixedLocator, FixedFormatter, MultipleLocator

    axis.set_major_locator(FixedLocator([-math.pi, -math.pi / 2, 0.0, math.pi / 2, math.pi]))
    axis.set_major_formatter(FixedFormatter(["−π", "−π/2", "0", "π/2", "π"]))
    axis.set_minor_locator(MultipleLocator(math.pi / 4))


def _orbit_colors(n: int):
    """``n`` distinct colours: tab10 up to 10 orbits, tab20 up to 20, else evenly around the hue circle
    (the cyclic hsv map, darkened a little so that yellow stays visible on white)."""
    import matplotlib

    if n <= 10:
        return [matplotlib.colormaps["tab10"](i) for i in range(n)]
    if n <= 20:
        return [matplotlib.colormaps["tab20"](i) for i in range(n)]
    hsv = matplotlib.colormaps["hsv"]
    return [tuple(0.82 * np.asarray(hsv(i / n))[:3]) + (1.0,) for i in range(n)]


def poincare_boundary(section, *, canonical: bool = True, samples: int = 721):
    """The edge of the energy surface on the section of a :class:`skewpend.PoincareSection`:
    ``(q, lower, upper)`` with ``q`` from -pi to pi [rad] and ``lower``, ``upper`` the least and
    the largest value of the drawn coordinate that energy allows there, NaN where ``Pi > E``.

    ``canonical``: the momentum ``p_q`` [J s], ``|p_q| <= sqrt(2 M_qq (E - Pi))`` (the least
    kinetic energy at a given ``p_q`` has the section joint at rest, so the crossing direction
    does not matter).  Otherwise the speed ``q'`` [rad/s]: the least kinetic energy at a given
    ``q'`` is ``q'^2 (M_qq - M_qc^2 / M_cc) / 2`` when the section joint's speed that attains it,
    ``-M_qc q' / M_cc``, has the sign the direction asks for (or the direction is 0), and
    ``M_qq q'^2 / 2`` (section joint at rest) when not -- so the edge is lopsided.
    :meth:`skewpend.PoincareSection.boundary`; None if the compiled model cannot be had here
    (no compiler)."""
    try:
        return section.boundary(canonical=canonical, samples=samples)
    except (SkewpendError, OSError):
        return None


_DIRECTION = {1: "increasing", -1: "decreasing", 0: "either way"}


def _section_text(settings) -> str:
    name, value = settings["coordinate"], float(settings["value"])
    where = f"{name} = {fmt(value)}" + (f" rad ({fmt(math.degrees(value))}°)" if value else "")
    return f"section {where}, crossed with {name} {_DIRECTION.get(int(settings.get('direction', 1)), '?')}"


def _poincare_caption(section, shown: int) -> str:
    from .style import wrap_list, parameter_text

    st, stats = section.settings, section.stats
    n_orbits = int(np.asarray(section.crossings).size)
    total = int(np.asarray(section.q).size)
    surface = f"E = {fmt(st['energy'])} J"
    if stats.get("e_min") is not None:
        surface += f" (least potential energy {fmt(stats['e_min'])} J)"
    orbits = f"{n_orbits} orbit{'s' if n_orbits != 1 else ''}"
    points = f"{orbits} x {st.get('n_crossings', '?')} crossings wanted: {total} points"
    if shown < total:
        points += f", {shown} drawn (thinned evenly)"
    short = int(np.count_nonzero(np.asarray(section.orbit_status) == 5))
    if short:
        points += f", {short} orbit{'s' if short != 1 else ''} stopped at t_max"
    run = ["dop853", f"crossings located by {'dense output' if st.get('locate') == 'dense' else 'Hénon’s method'}"]
    run += _settings_list(st, ("rtol", "atol"))
    if section.energy_error is not None and np.size(section.energy_error):
        run.append(f"largest |energy error| = {fmt(float(np.max(np.abs(section.energy_error))), 2)} J")
    return "\n".join([wrap_list(parameter_text(section.params)), f"{surface}, {_section_text(st)}", points,
                      wrap_list(", ".join(run), 100)])


def poincare_figure(section, *, canonical: bool = True, max_points: Optional[int] = None):
    """The Poincaré section of a :class:`skewpend.PoincareSection`: one dot per crossing at
    ``(q, p_q)`` -- the other joint's angle [rad] (wrapped to [-π, π)) and canonical momentum
    [J s], the coordinates in which the section map preserves area -- or, ``canonical=False``,
    at ``(q, q')`` [rad/s].  Each orbit in its own colour (one scatter per orbit, in the order
    of ``section.seeds``), small dots; the edge of the energy surface (:func:`poincare_boundary`)
    as a thin grey line when it can be evaluated.  ``max_points``: draw at most that many
    points, every k-th of each orbit (said so in the heading).  The heading states the
    parameters, the energy, the section and its direction, and the integrator settings."""
    from matplotlib.lines import Line2D

    q = np.asarray(section.q, dtype=float)
    y = np.asarray(section.p if canonical else section.dq, dtype=float)
    orbit = np.asarray(section.orbit)
    total = q.size
    if max_points is not None:
        if isinstance(max_points, bool) or not isinstance(max_points, (int, np.integer)) or max_points < 1:
            raise ParameterError(f"max_points must be a whole number >= 1 or None, got {max_points!r}")
    stride = 1 if max_points is None or total <= max_points else int(math.ceil(total / int(max_points)))
    keep = np.zeros(total, dtype=bool)
    for k in np.unique(orbit):
        idx = np.nonzero(orbit == k)[0]
        keep[idx[::stride]] = True
    shown = int(np.count_nonzero(keep))
    _, other = section.coord_names
    n_orbits = int(np.asarray(section.crossings).size)
    colors = _orbit_colors(max(n_orbits, 1))
    size = float(np.clip(6.0 * math.sqrt(500.0 / max(shown, 1)), 0.4, 6.0))
    edge = poincare_boundary(section, canonical=canonical)
    with style():
        fig = _new_figure((7.4, 6.6))
        ax = fig.subplots()
        for k in range(n_orbits):
            sel = keep & (orbit == k)
            if not sel.any():
                continue
            ax.scatter(q[sel], y[sel], s=size, color=colors[k], linewidths=0, rasterized=shown > 20000, zorder=2,
                       label=f"orbit {k + 1}")
        handles = []
        if edge is not None:
            x, lower, upper = edge
            ax.plot(x, upper, color=CHAOS_COLORS["edge"], lw=0.8, zorder=1)
            ax.plot(x, lower, color=CHAOS_COLORS["edge"], lw=0.8, zorder=1)
            handles.append(Line2D([], [], color=CHAOS_COLORS["edge"], lw=0.8, label="edge of the energy surface"))
        ax.set_xlim(-math.pi, math.pi)
        _pi_ticks(ax.xaxis)
        ax.set_xlabel(f"{SYMBOL[other]} [rad]")
        ax.set_ylabel(rf"$p_\{other}$ [J s]" if canonical else f"{SYMBOL['d' + other]} [rad/s]")
        ax.set_title(f"Poincaré section, one colour per orbit ({n_orbits})", loc="left")
        if handles:
            ax.legend(handles=handles, loc="upper center", bbox_to_anchor=(0.5, -0.1), frameon=False,
                      borderaxespad=0.0)
        _heading(fig, _poincare_caption(section, shown))
    return fig


def _edges(centres: np.ndarray) -> np.ndarray:
    """Cell edges around increasing centres: midway between them, half a spacing beyond the ends."""
    c = np.asarray(centres, dtype=float)
    if c.size == 1:
        half = 0.5 * abs(c[0]) if c[0] != 0 else 0.5
        return np.array([c[0] - half, c[0] + half])
    mid = 0.5 * (c[1:] + c[:-1])
    return np.concatenate([[c[0] - (mid[0] - c[0])], mid, [c[-1] + (c[-1] - mid[-1])]])


def _chaos_caption(diagram) -> str:
    from .style import wrap_list, parameter_text

    st, stats = diagram.settings, diagram.stats
    alpha, energy = np.degrees(np.asarray(diagram.alpha, dtype=float)), np.asarray(diagram.energy, dtype=float)
    samples = int(np.shape(diagram.exponent)[2])
    values = lambda n: f"{n} value{'s' if n != 1 else ''}"  # noqa: E731
    grid = (f"alpha from {fmt(alpha[0])}° to {fmt(alpha[-1])}° ({values(alpha.size)}) x energy from "
            f"{fmt(energy[0])} to {fmt(energy[-1])} J above the minimum ({values(energy.size)}), "
            f"{samples} starts per cell on the section phi = 0 (crossed with phi increasing)")
    run = [f"largest exponent over t_end = {fmt(st['t_end'])} s" if st.get("t_end") is not None else "largest exponent"]
    if st.get("renorm_every") is not None:
        run.append(f"renormalised every {fmt(st['renorm_every'])} s")
    if st.get("transient"):
        run.append(f"transient {fmt(st['transient'])} s")
    run += _settings_list(st, ("rtol", "atol"))
    run.append(f"chaotic: exponent > threshold = {fmt(diagram.threshold)} 1/s")
    for key, what in (("unreachable", "starts not reachable"), ("failed", "integrations failed")):
        if stats.get(key):
            run.append(f"{stats[key]} {what}")
    return "\n".join([wrap_list(parameter_text(diagram.params, skip=("alpha",))), wrap_list(grid, 120),
                      wrap_list(", ".join(run), 120)])


def chaos_diagram_figure(diagram):
    """The chaos diagram of a :class:`skewpend.ChaosDiagram`: does skewing the hinges tame or feed chaos?

    Left: the chaotic fraction ``diagram.fraction`` (0 to 1, colour bar) as a map over the skew
    angle alpha [deg] (x) and the energy above the minimum of the potential [J] (y), one cell per
    grid point (``pcolormesh``, edges midway between the grid values); on grids of at most
    12 x 12 each cell is labelled with its value; cells without a valid start (NaN) in a flat
    colour the map never takes.  Right: the same fractions against energy, one line per alpha.
    The heading states the parameters, the grid, the samples per cell, ``t_end`` and the threshold."""
    import matplotlib
    from matplotlib.colors import Normalize
    from matplotlib.patches import Patch
    from matplotlib.ticker import FixedLocator, FuncFormatter

    frac = np.asarray(diagram.fraction, dtype=float)
    alpha = np.degrees(np.asarray(diagram.alpha, dtype=float))
    energy = np.asarray(diagram.energy, dtype=float)
    na, ne = frac.shape
    cmap = matplotlib.colormaps[CHAOS_COLORS["fraction_cmap"]].with_extremes(bad=CHAOS_COLORS["no_value"])
    norm = Normalize(vmin=0.0, vmax=1.0)
    small = na <= 12 and ne <= 12
    line_colors = matplotlib.colormaps[CHAOS_COLORS["alpha_cmap"]](np.linspace(0.0, 0.85, na) if na > 1 else [0.0])
    with style():
        fig = _new_figure((12.0, 5.6))
        fig.get_layout_engine().set(wspace=0.08)
        ax, ax2 = fig.subplots(1, 2, width_ratios=[1.0, 1.0])
        ax.grid(False)
        mesh = ax.pcolormesh(_edges(alpha), _edges(energy), np.ma.masked_invalid(frac.T), cmap=cmap, norm=norm,
                             edgecolors="white" if small else "face", linewidth=0.6 if small else 0.0)
        if small:
            for i in range(na):
                for j in range(ne):
                    f = frac[i, j]
                    if not math.isfinite(f):
                        continue
                    r, g, b, _ = cmap(norm(f))
                    dark = 0.299 * r + 0.587 * g + 0.114 * b < 0.5
                    ax.text(alpha[i], energy[j], f"{f:.2f}", ha="center", va="center", fontsize=8.5,
                            color="white" if dark else "0.1")
        for axis, values, unit in ((ax.xaxis, alpha, "°"), (ax.yaxis, energy, "")):
            if values.size <= 12:
                axis.set_major_locator(FixedLocator(values))
                axis.set_major_formatter(FuncFormatter(lambda v, _, u=unit: fmt(v, 3) + u))
        ax.tick_params(which="both", direction="out")
        ax.set_xlabel(r"skew angle $\alpha$ [deg]")
        ax.set_ylabel(r"energy above the minimum, $E - E_{\min}$ [J]")
        ax.set_title("Chaotic fraction of the energy surface", loc="left")
        bar = fig.colorbar(mesh, ax=ax, pad=0.02, fraction=0.06)
        bar.set_label("chaotic fraction [1]")
        bar.set_ticks([0.0, 0.25, 0.5, 0.75, 1.0])
        bar.ax.tick_params(direction="out")
        if np.isnan(frac).any():
            ax.legend(handles=[Patch(facecolor=CHAOS_COLORS["no_value"], edgecolor="0.45", lw=0.6,
                                     label="no valid start")], loc="lower right", bbox_to_anchor=(1.0, 1.0),
                      frameon=False, borderaxespad=0.2)
        # the second panel: fraction against energy, one line per alpha
        # equal fractions (all 0 or all 1) are common: hollow rings shrinking with alpha stay visible
        # one inside the other where lines coincide
        # (on a small grid; many lines get small filled dots and a colour bar instead of a legend)
        sizes = np.linspace(10.0, 4.0, na) if na > 1 else [6.0]
        for i in range(na):
            marks = dict(ms=sizes[i], mfc="none", mew=1.3, lw=1.2) if na <= 12 else dict(ms=3.0, lw=0.9)
            ax2.plot(energy, frac[i], marker="o", color=line_colors[i], label=rf"$\alpha$ = {fmt(alpha[i], 3)}°",
                     **marks)
        ax2.set_ylim(-0.04, 1.04)
        if ne > 1:
            pad = 0.03 * (energy[-1] - energy[0])
            ax2.set_xlim(energy[0] - pad, energy[-1] + pad)
        ax2.set_xlabel(r"energy above the minimum, $E - E_{\min}$ [J]")
        ax2.set_ylabel("chaotic fraction [1]")
        ax2.set_title(r"Chaotic fraction against energy, one line per $\alpha$", loc="left")
        if na <= 12:
            ax2.legend(loc="upper left", bbox_to_anchor=(1.02, 1.0), borderaxespad=0.0, handlelength=1.8,
                       title="skew angle", title_fontsize=8.5, alignment="left")
        else:  # many lines: a colour bar of alpha instead of a legend
            from matplotlib.cm import ScalarMappable
            from matplotlib.colors import BoundaryNorm, ListedColormap

            sm = ScalarMappable(cmap=ListedColormap(line_colors), norm=BoundaryNorm(_edges(alpha), na))
            bar2 = fig.colorbar(sm, ax=ax2, pad=0.02, fraction=0.06, label=r"skew angle $\alpha$ [deg]")
            bar2.set_ticks(alpha[:: max(1, -(-na // 7))])  # ticks on grid values, about 7 of them
            bar2.ax.yaxis.set_major_formatter(FuncFormatter(lambda v, _: fmt(v, 3) + "°"))
            bar2.ax.tick_params(direction="out")
        _heading(fig, _chaos_caption(diagram))
    return fig


def _lyapunov_map_caption(m) -> str:
    from .style import wrap_list, flipmap_window, parameter_text, window_text

    st = m.settings
    n0, n1 = np.shape(m.exponent)
    phi_range, psi_range = flipmap_window(m)
    grid = f"released at rest from {window_text(phi_range, psi_range)}, n = {n0} x {n1} cells"
    run = []
    if st.get("t_end") is not None:
        run.append(f"t_end = {fmt(st['t_end'])} s")
    if st.get("renorm_every") is not None:
        run.append(f"renormalised every {fmt(st['renorm_every'])} s")
    if st.get("transient"):
        run.append(f"transient {fmt(st['transient'])} s")
    run += ["dop853 on the state and one tangent vector (Benettin)"] + _settings_list(st, ("rtol", "atol"))
    failed = int(np.count_nonzero(~np.isfinite(np.asarray(m.exponent, dtype=float))))
    run.append(f"{failed} of {n0 * n1} cells failed" if failed else "every cell integrated")
    return "\n".join([wrap_list(parameter_text(m.params)), grid, wrap_list(", ".join(run), 100)])


def lyapunov_map_figure(m):
    """The largest Lyapunov exponent of starts at rest, a :class:`skewpend.LyapunovMap`, drawn like
    :func:`flipmap_figure`: the image is ``m.exponent`` **transposed** with ``origin="lower"``
    (``phi0`` across, ``psi0`` up, in degrees over the map's window, equal aspect), a linear
    colour scale from ``min(0, smallest)`` to the largest exponent with a colour bar "largest
    Lyapunov exponent [1/s]" exactly as tall as the map; cells whose integration failed (NaN)
    in a flat colour, with a legend entry.  The heading states the parameters, the grid,
    ``t_end``, the renormalisation interval and the tolerances."""
    import matplotlib
    from matplotlib.colors import Normalize
    from matplotlib.patches import Patch

    lam = np.asarray(m.exponent, dtype=float)
    if lam.ndim != 2 or lam.size == 0:
        raise ParameterError(f"a Lyapunov map needs a 2-D array of exponents, got shape {lam.shape}")
    extent = _degree_extent(m)
    finite = lam[np.isfinite(lam)]
    vmin = min(0.0, float(finite.min())) if finite.size else 0.0
    vmax = float(finite.max()) if finite.size else 1.0
    if not vmax > vmin:
        vmax = vmin + 1.0
    cmap = matplotlib.colormaps[CHAOS_COLORS["exponent_cmap"]].with_extremes(bad=CHAOS_COLORS["no_value"])
    with style():
        fig = _new_figure((7.0, 6.9))
        ax = fig.subplots()
        ax.grid(False)
        interpolation = "nearest" if max(lam.shape) <= 1024 else "antialiased"
        im = ax.imshow(np.ma.masked_invalid(lam.T), origin="lower", extent=extent, cmap=cmap,
                       norm=Normalize(vmin=vmin, vmax=vmax), interpolation=interpolation, aspect="equal")
        _start_map_axes(ax, extent, "Largest Lyapunov exponent of starts at rest")
        bar = fig.colorbar(im, cax=ax.inset_axes([1.035, 0.0, 0.04, 1.0]))
        bar.set_label("largest Lyapunov exponent [1/s]")
        bar.ax.tick_params(which="both", direction="out")
        bar.ax.grid(False)
        if finite.size < lam.size:
            ax.legend(handles=[Patch(facecolor=CHAOS_COLORS["no_value"], edgecolor="0.45", lw=0.6,
                                     label="integration failed")],
                      loc="upper center", bbox_to_anchor=(0.5, -0.1), frameon=False, borderaxespad=0.0)
        _heading(fig, _lyapunov_map_caption(m))
    return fig


__all__ += [
    "lyapunov_figure",
    "poincare_figure",
    "poincare_boundary",
    "chaos_diagram_figure",
    "lyapunov_map_figure",
    "LYAPUNOV_COLORS",
    "CHAOS_COLORS",
]
