"""The figure of an identification (:func:`skewpend.identify`, issue 27): how well the fitted model
predicts the measured motion, how precisely the data determine its parameters, and how they
trade off against each other.

:func:`plot_identification` draws, in one figure sized for 1600 x 1000 px (PNG at the project's
:data:`~skewpend.views.style.DPI`):

(a) measured and predicted angles (degrees) of a few fitting pieces and of every held-out piece:
    the fitted model ``result.params`` and the start ``result.params0`` simulated from each
    piece's first measured state (``q[0]`` and the measured ``dq[0]``, or a Savitzky-Golay
    estimate where the speeds were not measured -- exactly as :func:`~skewpend.identify` predicts
    held-out pieces);
(b) the held-out prediction error against time (mrad), per piece, fitted model and ``params0``;
(c) the 95 % interval half-width of each estimate relative to the estimate (log scale): the
    free-swing ratios when the data determine ratios only, else the base parameters;
(d) the correlation matrix of the free parameters (output-error fits);
(e) the profile of the cost over the freed angle (the skew ``alpha``, or a chain's ``tiltK``), its
    95 % interval shaded.

Pieces with measured torques are not simulated (their inputs vary): their held-out error is the
torque residual that :attr:`~skewpend.analysis.identify.Identification.heldout_rms` reports.
"""

from __future__ import annotations

import math
from typing import List, Optional, Tuple

import numpy as np

from ..style import COLORS, SYMBOL, fmt, style
from .base import heading, new_figure, save_figure

__all__ = ["plot_identification", "identification_predictions", "FIT_PIECES_SHOWN", "HELDOUT_PIECES_SHOWN",
           "FIGURE_SIZE", "PIECE_COLORS", "plus_minus"]

#: Fitting pieces drawn in panel (a) (the first and the last, then evenly between).
FIT_PIECES_SHOWN = 2
#: Held-out pieces drawn in panels (a) and (b) at most (the first this many; the report's table lists every one).
HELDOUT_PIECES_SHOWN = 6
#: The figure's size [in]: 1600 x 1000 px at the style's 150 dpi.
FIGURE_SIZE = (1600 / 150, 1000 / 150)
#: Colours of the held-out pieces in panel (b) (colour-blind safe, without phi's blue and psi's red).
PIECE_COLORS = ("#4c9a2a", "#8e44ad", "#e08a00", "#1b9e9e", "#6b6b6b", "#b5651d", "#c71585", "#2f4f4f")


# -- predictions -----------------------------------------------------------------------------------------
def _smoothing(result) -> float:
    from ...analysis.identify import SMOOTHING

    try:
        s = float(result.settings.get("smoothing", SMOOTHING))
    except (TypeError, ValueError):
        return SMOOTHING
    return s if math.isfinite(s) and s > 0 else SMOOTHING


def _spread(n: int, k: int) -> List[int]:
    """``k`` indices out of ``range(n)``: the first, the last and evenly between."""
    if n <= k:
        return list(range(n))
    if k == 1:
        return [0]
    return sorted({int(round(i * (n - 1) / (k - 1))) for i in range(k)})


def identification_predictions(result, measurements, validation=None, *, fit_pieces: int = FIT_PIECES_SHOWN,
                               heldout_pieces: Optional[int] = HELDOUT_PIECES_SHOWN):
    """The predictions the figure draws: a list of ``(piece, kind, predicted, predicted0)`` with
    ``kind`` ``"fit"`` or ``"held out"`` and the angles (n, 2) [rad] of the fitted model and of
    ``params0`` (None where a simulation failed: the same prediction as the held-out RMS, by
    :func:`~skewpend.analysis.identify.predict_piece`); pieces with measured torques are left out."""
    from ...analysis.identify import predict_piece

    s = _smoothing(result)
    chosen: List[Tuple[object, str]] = []
    fit = [p for p in (measurements or ()) if p.u is None]
    for i in _spread(len(fit), fit_pieces):
        chosen.append((fit[i], "fit"))
    held = [p for p in (validation or ()) if p.u is None]
    if heldout_pieces is not None:
        held = held[:heldout_pieces]
    chosen += [(p, "held out") for p in held]
    return [(piece, kind, predict_piece(result.params, piece, s), predict_piece(result.params0, piece, s))
            for piece, kind in chosen]


# -- the panels ----------------------------------------------------------------------------------------
def _rms_text(x: float) -> str:
    return "failed" if not math.isfinite(x) else f"{1e3 * x:.3g} mrad"


def _short(name: str, n: int = 16) -> str:
    name = str(name)
    return name if len(name) <= n else name[: n - 1] + "…"


def plus_minus(value: float, half: float) -> str:
    """``6.0004 ± 0.0031``: the value to the half-width's second significant digit."""
    if not (math.isfinite(value) and math.isfinite(half)) or half <= 0:
        return fmt(value, 6)
    places = 1 - math.floor(math.log10(half))
    if 0 < places <= 10:
        v, h = f"{value:.{places}f}", f"{half:.{places}f}"
    else:
        v, h = fmt(value, 4), fmt(half, 2)
    return f"{v} ± {h}".replace("-", "−")


def _mrad(x: float) -> str:
    return "failed" if not math.isfinite(x) else f"{1e3 * x:.3g}"


def _heldout_rms(result, name: str) -> Tuple[float, float]:
    for n, k, r, r0 in zip(result.validation, result.heldout_kind, result.heldout_rms, result.heldout_rms0):
        if n == name and k == "angle":
            return float(r), float(r0)
    return math.nan, math.nan


def _angle_styles(coordinates) -> List[Tuple[str, str]]:
    """Each angle's colour and symbol, by the model's coordinates: the colours of the trajectory figures
    (:func:`skewpend.views.figures.motion.coordinate_styles`), the symbols the style knows (the double pendulum's
    phi and psi), else ``q₁`` .. ``qₙ``."""
    import matplotlib

    from .motion import coordinate_styles

    sub = str.maketrans("0123456789", "₀₁₂₃₄₅₆₇₈₉")
    return [(matplotlib.colors.to_hex(color), SYMBOL.get(c, c.translate(sub)))
            for c, (color, _, _) in zip(coordinates, coordinate_styles(coordinates))]


def _panel_angles(axes, result, predictions) -> None:
    # the angles the fit measured: each rod's from the vertical (sums of the joint angles) where they are absolute
    absolute = getattr(result, "settings", {}).get("angles") == "absolute"

    def shown(x):
        x = np.degrees(np.asarray(x, float))
        return np.cumsum(x, axis=1) if absolute else x

    for ax, (piece, kind, pred, pred0) in zip(axes, predictions):
        t = np.asarray(piece.t, float) - float(piece.t[0])
        q = shown(piece.q)
        for j, (c, _) in enumerate(_angle_styles(result.params0.coordinates)):
            ax.plot(t, q[:, j], color=c, lw=3.2, alpha=0.28, solid_capstyle="butt")
            if pred0 is not None:
                ax.plot(t, shown(pred0)[:, j], color="0.15", lw=0.8, ls=(0, (3, 2)))
            if pred is not None:
                ax.plot(t, shown(pred)[:, j], color=c, lw=0.9)
        title = f"{_short(piece.name)} {'fitting' if kind == 'fit' else 'held out'}"
        if kind == "held out":
            r, _ = _heldout_rms(result, piece.name)
            if math.isfinite(r):
                title += f", RMS {_rms_text(r)}"
        if pred is None:
            title += " (simulation failed)"
        ax.set_title(title, loc="left", fontsize=8)
        ax.set_xlabel("time from the piece's start [s]", fontsize=8)
        ax.set_ylabel("angle [deg]", fontsize=8)
        ax.set_xlim(t[0], t[-1])
        ax.tick_params(labelsize=7.5)


def _angle_legend(subfig, coordinates, absolute: bool = False) -> None:
    from matplotlib.lines import Line2D

    styles = _angle_styles(coordinates)
    if absolute:  # each rod's angle from the vertical, not a joint's
        styles = [(c, f"rod {k}") for k, (c, _) in enumerate(styles, start=1)]
    nq = len(styles)
    handles = [Line2D([], [], color=c, lw=3.2, alpha=0.28) for c, _ in styles]
    handles += [Line2D([], [], color=c, lw=0.9) for c, _ in styles]
    handles.append(Line2D([], [], color="0.15", lw=0.8, ls=(0, (3, 2))))
    labels = [f"{name} measured" for _, name in styles] + [f"{name} fitted model" for _, name in styles]
    labels.append("params0 (the start)")
    subfig.legend(handles, labels, loc="outside lower center", ncols=min(len(labels), 2 * nq + 1 if nq <= 2 else nq + 1),
                  fontsize=8, frameon=False)


def _panel_residuals(ax, result, predictions) -> None:
    held = [(p, pr, pr0) for p, kind, pr, pr0 in predictions if kind == "held out"]
    from matplotlib.lines import Line2D

    absolute = getattr(result, "settings", {}).get("angles") == "absolute"
    handles, labels = [], []
    for i, (piece, pred, pred0) in enumerate(held):
        c = PIECE_COLORS[i % len(PIECE_COLORS)]
        t = np.asarray(piece.t, float) - float(piece.t[0])
        q = np.asarray(piece.q, float)
        for p, kw in ((pred0, {"lw": 0.7, "ls": (0, (3, 2)), "alpha": 0.8}), (pred, {"lw": 1.0})):  # params0 dashed
            if p is not None:
                e = p - q
                e = np.cumsum(e, axis=1) if absolute else e  # in the angles the fit measured
                ax.plot(t, 1e3 * np.sqrt(np.mean(e ** 2, axis=1)), color=c, **kw)
        r, r0 = _heldout_rms(result, piece.name)
        handles.append(Line2D([], [], color=c, lw=1.4))
        labels.append(f"{_short(piece.name)}: {_mrad(r)} ({_mrad(r0)})")
    if held:
        handles.append(Line2D([], [], color="0.3", lw=0.7, ls=(0, (3, 2))))
        labels.append("dashed: params0")
        ax.legend(handles, labels, fontsize=7, loc="upper left", handlelength=1.5, ncols=2, columnspacing=1.0,
                  title="RMS [mrad]: fitted model (params0)", title_fontsize=7, borderaxespad=0.3)
        top = max([line.get_ydata().max() for line in ax.get_lines() if len(line.get_ydata())] or [1.0])
        ax.set_ylim(0, 1.5 * top)
        ax.margins(x=0)
    else:
        ax.text(0.5, 0.5, "no held-out pieces with angles to predict\n(CLI: --validate DATA; Python: validation=...)", ha="center",
                va="center", transform=ax.transAxes, color="0.4", fontsize=8.5)
    ax.set_title("(b) Held-out prediction error", loc="left")
    ax.set_xlabel("time from the piece's start [s]")
    names = [name for _, name in _angle_styles(result.params0.coordinates)]
    ax.set_ylabel("rods' angle error, RMS [mrad]" if absolute else
                  f"angle error, RMS of ({', '.join(names)}) [mrad]")


def _precision_rows(result):
    """``(label, value, half-width)`` for panel (c): ratios for a free swing, else the base
    parameters the fit freed (the reference and the held ones are left out)."""
    if result.ratios:
        items = [(name, v, result.ratio_intervals.get(name, (math.nan, math.nan))) for name, v in result.ratios.items()]
    else:
        items = [(name, v, iv) for name, v, iv in zip(result.names, np.asarray(result.values, float),
                                                       np.asarray(result.intervals, float))
                 if name != result.reference and name in result.free]
    return [(name, float(v), 0.5 * (float(hi) - float(lo))) for name, v, (lo, hi) in items]


def _panel_precision(ax, result) -> None:
    from matplotlib.ticker import FuncFormatter

    rows = _precision_rows(result)
    ratios = bool(result.ratios)
    title = "(c) Precision: 95 % half-width / |estimate|"
    ax.set_title(title, loc="left")
    ax.set_xlabel("relative half-width [%] (log scale)")
    ax.set_ylabel("ratio of base parameters" if ratios else "base parameter")
    if not rows:
        ax.text(0.5, 0.5, "no estimates", ha="center", va="center", transform=ax.transAxes, color="0.4")
        return
    rel = np.array([abs(h) / abs(v) * 100 if v != 0 and math.isfinite(h) else math.nan for _, v, h in rows])
    y = np.arange(len(rows))[::-1]
    ok = np.isfinite(rel) & (rel > 0)
    lo = float(np.nanmin(rel[ok])) if ok.any() else 1e-2
    hi = float(np.nanmax(rel[ok])) if ok.any() else 1.0
    left = 10 ** math.floor(math.log10(lo) - 0.15)
    right = 10 ** math.ceil(math.log10(hi) + 0.9)  # room for the values written beside the bars
    for yi, r, (name, v, h) in zip(y, rel, rows):
        if math.isfinite(r) and r > 0:
            ax.hlines(yi, left, r, color=COLORS["phi"], lw=5, alpha=0.75)
            ax.text(r * 1.25, yi, plus_minus(v, h), va="center", fontsize=7, color="0.2")
        else:
            why = "not available" if getattr(result, "intervals_note", "").startswith("95 %") else "not determined"
            ax.text(left * 1.3, yi, why, va="center", fontsize=7, color=COLORS["psi"])
    ax.set_xscale("log")
    ax.set_xlim(left, right)
    ax.set_yticks(y, [name for name, _, _ in rows], fontsize=7.5)
    ax.set_ylim(-0.7, len(rows) - 0.3)
    ax.grid(axis="y", visible=False)
    ax.xaxis.set_major_formatter(FuncFormatter(lambda x, _pos: f"{x:g}"))


def _panel_correlation(fig, ax, result) -> None:
    ax.set_title("(d) Correlation matrix", loc="left")
    C = np.asarray(result.correlation, float)
    names = [str(n) for n in result.settings.get("free", [])] if isinstance(result.settings, dict) else []
    ax.grid(False)
    for s in ax.spines.values():
        s.set_visible(False)
    if C.ndim != 2 or C.size == 0:
        ax.text(0.5, 0.5, "no correlation matrix\n(the output-error fit computes it;\nthe linear estimate has none)",
                ha="center", va="center", transform=ax.transAxes, color="0.4", fontsize=8.5)
        ax.set_xticks([])
        ax.set_yticks([])
        return
    n = C.shape[0]
    if len(names) != n:
        names = [f"θ{i + 1}" for i in range(n)]
    im = ax.imshow(C, cmap="RdBu_r", vmin=-1, vmax=1, interpolation="nearest")
    ax.set_xticks(range(n), names, rotation=55, ha="right", rotation_mode="anchor", fontsize=7.5)
    ax.set_yticks(range(n), names, fontsize=7.5)
    if n <= 10:  # the coefficients written in the cells (more would overlap: the colours alone)
        for i in range(n):
            for j in range(n):
                if i != j and math.isfinite(C[i, j]):
                    ax.text(j, i, f"{C[i, j]:.2f}".replace("0.", ".").replace("-.", "−."), ha="center", va="center",
                            fontsize=6 if n > 8 else 6.8, color="white" if abs(C[i, j]) > 0.6 else "0.15")
    ax.set_xlabel("free parameter")
    ax.set_ylabel("free parameter")
    cb = fig.colorbar(im, ax=ax, shrink=0.85, pad=0.02)
    cb.set_label("correlation coefficient [1]", fontsize=8)
    cb.ax.tick_params(labelsize=7.5)


def _panel_profile(ax, result) -> None:
    a = np.degrees(np.asarray(result.profile_alpha, float))
    c = np.asarray(result.profile_cost, float)
    order = np.argsort(a)
    a, c = a[order], c[order]
    base = float(np.nanmin(c))
    lo, hi = (math.degrees(float(x)) for x in result.alpha_interval)
    if math.isfinite(lo) and math.isfinite(hi):
        ax.axvspan(lo, hi, color=COLORS["start"], alpha=0.15, lw=0,
                   label=f"95 % interval [{lo:.2f}°, {hi:.2f}°]")
    ax.plot(a, 1e3 * (c - base), color=COLORS["path"], marker="o", ms=3.5, lw=1.1, label="profile (others re-fitted)")
    # the freed angle: the double pendulum's skew alpha, or a chain's hinge tilt (tiltK)
    name = getattr(result, "angle", "alpha")
    symbol, words, title = (("α", "skew angle", "Skew-angle") if name == "alpha"
                            else (name, f"hinge {name[4:]}'s tilt", f"Hinge {name[4:]}'s tilt"))
    if math.isfinite(result.alpha):
        ax.axvline(math.degrees(result.alpha), color=COLORS["psi"], lw=1.0, ls="--",
                   label=f"estimate {symbol} = {math.degrees(result.alpha):.2f}°")
    ax.set_title(f"(e) {title} profile", loc="left")
    ax.set_xlabel(f"{words} {symbol} [deg]")
    ax.set_ylabel(r"cost − minimum [$10^{-3}$ rad²]")
    ax.set_ylim(0, 1.45 * float(np.nanmax(1e3 * (c - base))) or 1.0)
    ax.legend(fontsize=7, loc="upper center", framealpha=0.92)


#: The heading's longest line [characters] (the figure is 1600 px wide; the heading's font 8.5 pt).
HEADING_WIDTH = 160


def _heading_text(result, measurements, validation) -> str:
    n_fit = len(result.pieces) if result.pieces else (len(measurements) if measurements is not None else 0)
    parts = [f"Identification ({result.method}) from {n_fit} fitting piece{'s' if n_fit != 1 else ''}"]
    if len(result.validation):
        parts.append(f"{len(result.validation)} held out")
    line1 = ", ".join(parts) + f": {result.message}"
    line2 = []
    if math.isfinite(result.heldout_median):
        line2.append(f"held-out angle RMS, median over pieces: {_rms_text(result.heldout_median)} "
                     f"(params0 {_rms_text(result.heldout_median0)})")
    if len(result.fit_rms):
        line2.append(f"fitting pieces: median {_rms_text(float(np.median(result.fit_rms)))}")
    seconds = result.stats.get("seconds") if isinstance(result.stats, dict) else None
    if seconds is not None:
        line2.append(f"{float(seconds):.3g} s")
    import textwrap

    # wrapped: a long status message (a projection's note) must not run off the figure's edges
    lines = textwrap.wrap(line1, HEADING_WIDTH) + (textwrap.wrap("; ".join(line2), HEADING_WIDTH) if line2 else [])
    return "\n".join(lines)


# -- the figure ----------------------------------------------------------------------------------------
def plot_identification(result, measurements, validation=None, path=None):
    """The figure of an identification: (a) measured and predicted angles of a few fitting pieces and
    of every held-out piece (the first :data:`HELDOUT_PIECES_SHOWN`), with ``params0``'s prediction
    dashed; (b) the held-out prediction error over time; (c) each estimate's 95 % half-width
    relative to it (log scale; the free-swing ratios when ``result.ratios`` holds them); (d) the
    correlation matrix of the free parameters; (e) when the skew angle was profiled, the cost over
    it with the 95 % interval shaded.

    ``result``: an :class:`~skewpend.analysis.identify.Identification`; ``measurements`` and
    ``validation``: the :class:`~skewpend.Measurements` it was fitted on and validated with.
    Returns the Matplotlib figure (1600 x 1000 px as PNG); with ``path`` (``.png``, ``.svg``,
    ``.pdf``) it is also saved there atomically (:func:`~skewpend.views.figures.save_figure`)."""
    from ...errors import ParameterError

    if not hasattr(result, "heldout_rms") or not hasattr(result, "params0"):
        raise ParameterError(f"result must be a skewpend Identification (from skewpend.identify), got "
                             f"{type(result).__name__}")
    if path is not None:
        from ...io import check_output_path
        from .base import FIGURE_SUFFIXES

        check_output_path(path, FIGURE_SUFFIXES, option="figure")
    predictions = identification_predictions(result, measurements, validation)
    profile = len(result.profile_alpha) > 1
    with style():
        fig = new_figure(FIGURE_SIZE)
        fig.get_layout_engine().set(h_pad=0.04, w_pad=0.04, hspace=0.02, wspace=0.02)
        upper, lower = fig.subfigures(2, 1, height_ratios=(1.12, 1.0), hspace=0.03)
        top, corner = upper.subfigures(1, 2, width_ratios=(0.68, 0.32), wspace=0.02)
        n = max(len(predictions), 1)
        ncols = min(max(2, math.ceil(n / 2)), 4)
        nrows = max(1, math.ceil(n / ncols))
        axes_a = np.atleast_1d(top.subplots(nrows, ncols, squeeze=False, sharex=False).ravel())
        _panel_angles(axes_a, result, predictions)
        for ax in axes_a[len(predictions):]:
            ax.set_visible(False)
        if not predictions:
            axes_a[0].set_visible(True)
            axes_a[0].text(0.5, 0.5, "no piece with angles to predict", ha="center", va="center",
                           transform=axes_a[0].transAxes, color="0.4")
            axes_a[0].set_title("(a) no predictions", loc="left")
            axes_a[0].set_xlabel("time from the piece's start [s]")
            axes_a[0].set_ylabel("angle [deg]")
        top.suptitle("(a) Measured and predicted angles" + (" from the vertical" if getattr(result, "settings", {}).get(
            "angles") == "absolute" else "") + ", each piece simulated from its first measured state",
                     x=0.01, ha="left", fontsize=10.5)
        _angle_legend(top, result.params0.coordinates, getattr(result, "settings", {}).get("angles") == "absolute")
        _panel_correlation(corner, corner.subplots(), result)
        axes = lower.subplots(1, 3 if profile else 2, width_ratios=(1.1, 1.0, 0.9) if profile else (1.2, 1.0))
        _panel_residuals(axes[0], result, predictions)
        _panel_precision(axes[1], result)
        if profile:
            _panel_profile(axes[2], result)
        heading(fig, _heading_text(result, measurements, validation))
    if path is not None:
        save_figure(fig, path)
    return fig
