"""Figures from result objects (they never integrate or derive).  Needs matplotlib
(``pip install 'skewpend[plot]'``); uses the non-interactive Agg backend."""

from __future__ import annotations

from pathlib import Path
from typing import Optional

import numpy as np

from .errors import ParameterError, SkewpendError

__all__ = ["plot_sweep", "save_figure"]

_FORMATS = (".png", ".pdf", ".svg")


def _pyplot():
    try:
        import matplotlib

        matplotlib.use("Agg")
        import matplotlib.pyplot as plt
    except ImportError:  # pragma: no cover - depends on the installation
        raise SkewpendError("plots need matplotlib: pip install 'skewpend[plot]'") from None
    return plt


def plot_sweep(sw, *, title: Optional[str] = None):
    """Frequencies and mode-shape directions along a :class:`~skewpend.modes.Sweep`.

    Top: ``w1, w2`` [rad/s] against the swept variable (degrees for alpha), internal
    resonances marked.  Bottom: the direction of each mode shape in the (phi, psi) plane
    [deg] (modulo 180, unwrapped), which shows how the modes turn at a veering without the
    infinite ``psi/phi`` ratios of a mode where phi stands still.
    """
    plt = _pyplot()
    x = np.degrees(sw.values) if sw.name == "alpha" else sw.values
    xlabel = "α [deg]" if sw.name == "alpha" else sw.name
    fig, (ax1, ax2) = plt.subplots(2, 1, figsize=(7.5, 7), sharex=True, constrained_layout=True)
    ax1.plot(x, sw.frequencies[:, 0], label="ω₁ (lower mode)", color="tab:blue")
    ax1.plot(x, sw.frequencies[:, 1], label="ω₂ (upper mode)", color="tab:red")
    for r in sw.resonances:
        xv = np.degrees(r.value) if sw.name == "alpha" else r.value
        ax1.axvline(xv, color="0.6", lw=0.8, ls="--")
        ax1.annotate(f"{r.order}:1", (xv, ax1.get_ylim()[1]), textcoords="offset points", xytext=(2, -12), fontsize=8)
    ax1.set_ylabel("natural frequency [rad/s]")
    ax1.legend(loc="best")
    ax1.grid(alpha=0.3)
    # a mode shape is a direction: defined modulo 180 deg; unwrap to continuous curves
    angle = np.degrees(np.arctan2(sw.shapes[:, 1, :], sw.shapes[:, 0, :]))
    angle = np.unwrap((angle + 90.0) % 180.0 - 90.0, period=180.0, axis=0)
    ax2.plot(x, angle[:, 0], color="tab:blue", label="mode 1")
    ax2.plot(x, angle[:, 1], color="tab:red", label="mode 2")
    ax2.set_ylabel("mode direction in the (φ, ψ) plane [deg]")
    ax2.set_xlabel(xlabel)
    ax2.legend(loc="best")
    ax2.grid(alpha=0.3)
    if title:
        fig.suptitle(title)
    return fig


def save_figure(fig, path) -> Path:
    """Save atomically (temporary file, then rename) as PNG, PDF or SVG by suffix."""
    from .io import atomic_path

    path = Path(path)
    suffix = path.suffix.lower()
    if suffix not in _FORMATS:
        raise ParameterError(f"unknown figure format {path.suffix!r} for {path}; allowed: {', '.join(_FORMATS)}")
    with atomic_path(path) as tmp:
        fig.savefig(tmp, format=suffix[1:], dpi=130)
    _pyplot().close(fig)
    return path
