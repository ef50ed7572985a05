"""The flip-time map, and the axes every map over starts at rest shares (the Lyapunov map's too)."""

from __future__ import annotations

import math
from typing import List, Optional, Sequence

import numpy as np

from ...errors import ParameterError, SkewpendError
from ..style import flipmap_caption, flipmap_window, fmt, style
from .base import heading, new_figure, wrap_angle

__all__ = ["FLIPMAP_COLORS", "flipmap_figure", "flipmap_forbidden", "flipmap_energy_margin", "degree_extent",
           "start_map_axes"]

#: Colours of the flip-time map: the colour map of the flip times (log scale), the cells that do not
#: flip by t_end, the cells that energy forbids to flip and the line around them.
FLIPMAP_COLORS = {"cmap": "viridis_r", "no_flip": "#ffffff", "forbidden": "#d4d4d4", "boundary": "0.35",
                  "mark": "#e4572e"}


def flipmap_energy_margin(fm) -> Optional[np.ndarray]:
    """``fm.energy_margin()`` (:meth:`skewpend.FlipMap.energy_margin`: negative where energy
    forbids a flip), or None if the compiled potential cannot be had here (no compiler)."""
    try:
        return fm.energy_margin()
    except (SkewpendError, OSError):
        return None


def flipmap_forbidden(fm) -> Optional[np.ndarray]:
    """The cells of ``fm`` that energy alone forbids to flip, as a boolean array laid out like
    ``fm.flip_time``: released at rest, ``V = Pi - tau·q`` (which never increases: damping only
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


def degree_extent(result) -> list:
    """``[phi_lo, phi_hi, psi_lo, psi_hi]`` in degrees: the window of a map over starts at rest."""
    (phi_lo, phi_hi), (psi_lo, psi_hi) = flipmap_window(result)
    return [math.degrees(phi_lo), math.degrees(phi_hi), math.degrees(psi_lo), math.degrees(psi_hi)]


#: The double pendulum's angles at release as axis labels (another angle's: its symbol, :func:`start_label`).
_START_SYMBOLS = {"phi": r"$\varphi_0$", "psi": r"$\psi_0$"}


def start_label(name: str, coordinates) -> str:
    """The axis label of the angle ``name`` at release: ``$\varphi_0$, hinge 1 at release [deg]``, ``q₃, hinge 3 ...``."""
    from .base import coordinate_label

    symbol = _START_SYMBOLS.get(name) or coordinate_label(name).split(" − ")[0]
    return f"{symbol}, hinge {tuple(coordinates).index(name) + 1} at release [deg]"


def start_map_axes(ax, extent, title: str, labels=(start_label("phi", ("phi", "psi")), start_label("psi", ("phi", "psi")))) -> None:
    """The axes of a map over starts at rest (flip map, Lyapunov map): limits, degree ticks
    outwards, a closed frame, the hinge labels (``labels``: x, y; the double pendulum's by default) and the title."""
    ax.set_xlim(extent[0], extent[1])
    ax.set_ylim(extent[2], extent[3])
    _degree_ticks(ax.xaxis, extent[0], extent[1])
    _degree_ticks(ax.yaxis, extent[2], extent[3])
    ax.tick_params(which="both", direction="out")
    for side in ("top", "right"):
        ax.spines[side].set_visible(True)
    ax.set_xlabel(labels[0])
    ax.set_ylabel(labels[1])
    ax.set_title(title, loc="left")


def map_image(fig, values: np.ndarray, extent, cmap, norm):
    """A map over starts at rest drawn on a new axes of ``fig``: ``values`` **transposed** with ``origin="lower"``
    (NaN in the colour map's "bad" colour), equal aspect, and a colour bar exactly as tall as the (square) map;
    returns the axes, the image and the colour bar."""
    ax = fig.subplots()
    ax.grid(False)
    interpolation = "nearest" if max(values.shape) <= 1024 else "antialiased"
    im = ax.imshow(np.ma.masked_invalid(values.T), origin="lower", extent=extent, cmap=cmap, norm=norm,
                   interpolation=interpolation, aspect="equal")
    bar = fig.colorbar(im, cax=ax.inset_axes([1.035, 0.0, 0.04, 1.0]))
    bar.ax.tick_params(which="both", direction="out")
    bar.ax.grid(False)
    return ax, im, bar


def flipmap_figure(fm, *, mark: Optional[Sequence[float]] = None, mark_label: str = "start",
                   forbidden="auto"):
    """The flip-time map of a :class:`skewpend.FlipMap` (of any model), the classic picture.

    The image is ``fm.flip_time`` **transposed**, drawn with ``origin="lower"``: the plane's first
    angle (``phi0``; a chain's e.g. ``q1``) on the x axis, its second on the y axis, both in degrees over
    the map's window (the image's extent is the cells' outer edges).  Flip times on a logarithmic colour
    scale (:class:`LogNorm`) from the shortest flip time to ``t_end``, with a colour bar "flip time [s]";
    the cells that do not flip by ``t_end`` (NaN) in flat white; the cells that energy alone forbids to
    flip (:func:`flipmap_forbidden`; a model whose kernel prints no flip potential has none) in light
    grey with a line around them (``forbidden``: "auto" computes them, None leaves them white; or an
    array like ``fm.flip_time``: boolean, or :func:`flipmap_energy_margin`, negative where forbidden,
    whose zero line is the edge).  ``mark``: a point of the plane [rad, wrapped to (-180, 180]] drawn
    with the legend entry ``mark_label``.  The heading states the model, the grid (and the angles held)
    and the integrator settings (:func:`skewpend.views.style.flipmap_caption`).
    """
    from matplotlib.colors import ListedColormap, LogNorm
    from matplotlib.lines import Line2D
    from matplotlib.patches import Patch
    from matplotlib.ticker import FixedLocator, FuncFormatter, NullFormatter

    import matplotlib

    ft = np.asarray(fm.flip_time, dtype=float)
    if ft.ndim != 2 or ft.size == 0:
        raise ParameterError(f"a flip map needs a 2-D array of flip times, got shape {ft.shape}")
    extent = [math.degrees(v) for v in (*fm.window()[0], *fm.window()[1])]
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
    with style():
        fig = new_figure((6.6, 6.9))
        cmap = matplotlib.colormaps[colors["cmap"]].with_extremes(bad=colors["no_flip"])
        ax, im, bar = map_image(fig, ft, extent, cmap, LogNorm(vmin=vmin, vmax=t_end))
        handles = [Patch(facecolor=colors["no_flip"], edgecolor="0.45", lw=0.6,
                         label=f"no flip by t_end = {fmt(t_end)} s")]
        if forbidden is not None and forbidden.any():
            if margin is not None and min(ft.shape) >= 2:
                # the region where the margin is negative, with a smooth edge (its zero line), over the
                # whole window: the margin is extended linearly from the cell centres to the window's edges
                k = max(1, -(-max(ft.shape) // 1024))  # at most about 1024 points a side: plenty for a smooth line
                x = _to_edges(np.degrees(np.asarray(fm.x0, dtype=float)[::k]), extent[0], extent[1])
                y = _to_edges(np.degrees(np.asarray(fm.y0, dtype=float)[::k]), extent[2], extent[3])
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
        start_map_axes(ax, extent, "Flip time: when any hinge angle first leaves (−180°, 180°)",
                       tuple(start_label(c, fm.params.coordinates) for c in fm.plane))
        bar.set_label("flip time [s]")
        bar.ax.yaxis.set_major_locator(FixedLocator(_log_ticks(vmin, t_end)))
        bar.ax.yaxis.set_major_formatter(FuncFormatter(lambda v, _: fmt(v, 3)))
        bar.ax.yaxis.set_minor_formatter(NullFormatter())
        ax.legend(handles=handles, loc="upper center", bbox_to_anchor=(0.5, -0.1), ncols=len(handles),
                  frameon=False, handlelength=1.4, columnspacing=1.4, borderaxespad=0.0)
        heading(fig, flipmap_caption(fm))
    return fig
