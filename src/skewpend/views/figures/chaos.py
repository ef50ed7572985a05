"""Chaos: Lyapunov spectra, Poincaré sections (with their energy boundary), the chaos diagram and
the largest-exponent map."""

from __future__ import annotations

import math
from typing import List, Optional

import numpy as np

from ...errors import ParameterError, SkewpendError
from ..style import COLORS, SYMBOL, fmt, style
from .base import heading, new_figure
from .maps import degree_extent, map_image, start_map_axes

__all__ = ["LYAPUNOV_COLORS", "CHAOS_COLORS", "lyapunov_figure", "poincare_boundary", "poincare_figure",
           "chaos_diagram_figure", "lyapunov_map_figure"]

#: Colours of the Lyapunov exponents lambda_1 .. lambda_4 (the largest in the blue of hinge 1).
LYAPUNOV_COLORS = ("#1f63a8", "#c8312b", "#2a9d4b", "#7b4fa0")

#: Colours of the chaos figures: the chaotic fraction's colour map (0 light, 1 dark red), the lines
#: per skew angle (sampled from ``alpha_cmap``), the Lyapunov map's colour map and the colour of cells
#: without a value (no start reachable, or the integration failed), which neither colour map takes.
CHAOS_COLORS = {"fraction_cmap": "YlOrRd", "alpha_cmap": "viridis", "exponent_cmap": "magma", "no_value": "#9ecae1",
                "edge": "0.35"}


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


def _renormalised(st, transient: str = "") -> List[str]:
    """The renormalisation interval and the transient (``transient``: said after it) of an exponent's run."""
    out = [f"renormalised every {fmt(st['renorm_every'])} s"] if st.get("renorm_every") is not None else []
    return out + ([f"transient {fmt(st['transient'])} s{transient}"] if st.get("transient") else [])


def _lyapunov_caption(spec) -> str:
    """What a Lyapunov figure shows: the parameters; the start; the method, tolerances, t_end,
    renormalisation interval, transient and windows (and, if the run stopped early, why)."""
    from ..style import wrap_list, initial_text, parameter_text

    st = spec.settings
    run = [f"dop853 on the state and {spec.k} tangent vector{'s' if spec.k != 1 else ''} (Benettin, QR)"]
    run += _settings_list(st, ("rtol", "atol"))
    if st.get("t_end") is not None:
        run.append(f"t_end = {fmt(st['t_end'])} s")
    run += _renormalised(st, f" (measured from t = {fmt(st.get('measured_from', 0.0))} s)")
    if st.get("windows") is not None:
        run.append(f"uncertainty from {st['windows']} windows")
    lines = [wrap_list(parameter_text(spec.params)), "released from " + initial_text(spec.y0),
             wrap_list(", ".join(run), 110)]
    if getattr(spec, "status", 0) != 0:
        import textwrap

        lines.append(textwrap.fill(f"run {spec.message}", 110))
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
        fig = new_figure((9.0, 5.0))
        ax = fig.subplots()
        ax.axhline(0.0, color=COLORS["reference"], lw=0.9, zorder=1)
        colors = LYAPUNOV_COLORS if k <= len(LYAPUNOV_COLORS) else _orbit_colors(k)  # a chain's 2 n exponents
        for j in range(k):
            value, err = float(spec.exponents[j]), float(spec.uncertainty[j])
            ax.plot(t, hist[:, j], color=colors[j],
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
        if k == int(np.size(spec.y0)):  # the full spectrum
            handles.append(Line2D([], [], ls="none"))
            labels.append(f"sum = {_signed(float(np.sum(spec.exponents)), 3)} 1/s")
        ax.legend(handles, labels, loc="upper left", bbox_to_anchor=(1.02, 1.0), borderaxespad=0.0,
                  title="final value ± standard error", title_fontsize=8.5, alignment="left", handlelength=1.6)
        heading(fig, _lyapunov_caption(spec))
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

    if n <= 20:
        return [matplotlib.colormaps["tab10" if n <= 10 else "tab20"](i) for i in range(n)]
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
    from ..style import wrap_list, parameter_text

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
    if max_points is not None and (isinstance(max_points, bool) or not isinstance(max_points, (int, np.integer))
                                   or max_points < 1):
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
        fig = new_figure((7.4, 6.6))
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
        heading(fig, _poincare_caption(section, shown))
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
    from ..style import wrap_list, parameter_text

    st, stats = diagram.settings, diagram.stats
    alpha, energy = np.degrees(np.asarray(diagram.alpha, dtype=float)), np.asarray(diagram.energy, dtype=float)
    samples = int(np.shape(diagram.exponent)[2])
    values = lambda n: f"{n} value{'s' if n != 1 else ''}"  # noqa: E731
    grid = (f"alpha from {fmt(alpha[0])}° to {fmt(alpha[-1])}° ({values(alpha.size)}) x energy from "
            f"{fmt(energy[0])} to {fmt(energy[-1])} J above the minimum ({values(energy.size)}), "
            f"{samples} starts per cell on the section phi = 0 (crossed with phi increasing)")
    run = [f"largest exponent over t_end = {fmt(st['t_end'])} s" if st.get("t_end") is not None else "largest exponent"]
    run += _renormalised(st)
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
        fig = new_figure((12.0, 5.6))
        fig.get_layout_engine().set(wspace=0.08)
        ax, ax2 = fig.subplots(1, 2, width_ratios=[1.0, 1.0])
        ax.grid(False)
        mesh = ax.pcolormesh(_edges(alpha), _edges(energy), np.ma.masked_invalid(frac.T), cmap=cmap, norm=norm,
                             edgecolors="white" if small else "face", linewidth=0.6 if small else 0.0)
        if small:
            for i, j in zip(*np.nonzero(np.isfinite(frac))):  # each cell with a value, labelled
                f = frac[i, j]
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
        heading(fig, _chaos_caption(diagram))
    return fig


def _lyapunov_map_caption(m) -> str:
    from ..style import wrap_list, flipmap_window, parameter_text, window_text

    st = m.settings
    n0, n1 = np.shape(m.exponent)
    phi_range, psi_range = flipmap_window(m)
    grid = f"released at rest from {window_text(phi_range, psi_range)}, n = {n0} x {n1} cells"
    run = []
    if st.get("t_end") is not None:
        run.append(f"t_end = {fmt(st['t_end'])} s")
    run += _renormalised(st)
    run += ["dop853 on the state and one tangent vector (Benettin)"] + _settings_list(st, ("rtol", "atol"))
    failed = int(np.count_nonzero(~np.isfinite(np.asarray(m.exponent, dtype=float))))
    run.append(f"{failed} of {n0 * n1} cells failed" if failed else "every cell integrated")
    return "\n".join([wrap_list(parameter_text(m.params)), grid, wrap_list(", ".join(run), 100)])


def lyapunov_map_figure(m):
    """The largest Lyapunov exponent of starts at rest, a :class:`skewpend.LyapunovMap`, drawn like
    :func:`flipmap_figure` (``phi0`` across, ``psi0`` up, degrees) on a linear colour scale from
    ``min(0, smallest)`` to the largest exponent; cells whose integration failed (NaN) in a flat colour,
    with a legend entry.  The heading states the parameters, the grid and the run's settings."""
    import matplotlib
    from matplotlib.colors import Normalize
    from matplotlib.patches import Patch

    lam = np.asarray(m.exponent, dtype=float)
    if lam.ndim != 2 or lam.size == 0:
        raise ParameterError(f"a Lyapunov map needs a 2-D array of exponents, got shape {lam.shape}")
    extent = degree_extent(m)
    finite = lam[np.isfinite(lam)]
    vmin = min(0.0, float(finite.min())) if finite.size else 0.0
    vmax = float(finite.max()) if finite.size else 1.0
    if not vmax > vmin:
        vmax = vmin + 1.0
    cmap = matplotlib.colormaps[CHAOS_COLORS["exponent_cmap"]].with_extremes(bad=CHAOS_COLORS["no_value"])
    with style():
        fig = new_figure((7.0, 6.9))
        ax, _, bar = map_image(fig, lam, extent, cmap, Normalize(vmin=vmin, vmax=vmax))
        start_map_axes(ax, extent, "Largest Lyapunov exponent of starts at rest")
        bar.set_label("largest Lyapunov exponent [1/s]")
        if finite.size < lam.size:
            ax.legend(handles=[Patch(facecolor=CHAOS_COLORS["no_value"], edgecolor="0.45", lw=0.6,
                                     label="integration failed")],
                      loc="upper center", bbox_to_anchor=(0.5, -0.1), frameon=False, borderaxespad=0.0)
        heading(fig, _lyapunov_map_caption(m))
    return fig
