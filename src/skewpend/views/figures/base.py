"""What every figure shares: the Matplotlib figure class (imported on first use), a new figure
with constrained layout, the heading, the angle wrap and :func:`save_figure`."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np

from ... import __version__
from ...errors import SkewpendError
from ..style import DPI, style

__all__ = ["FIGURE_SUFFIXES", "FORMATS", "ENERGY_FLOOR", "TWO_PI", "figure_class", "new_figure", "heading",
           "wrap_angle", "save_figure"]

#: File formats :func:`save_figure` writes, by suffix.
FIGURE_SUFFIXES = FORMATS = (".png", ".svg", ".pdf")

#: The relative energy error is drawn no lower than this on its log axis (exact zeros, e.g. at t = 0).
ENERGY_FLOOR = 1e-17

TWO_PI = 2.0 * math.pi


def figure_class():
    try:
        import mpl_toolkits.mplot3d  # noqa: F401  (registers the "3d" projection)
        from matplotlib.figure import Figure
    except ImportError:  # pragma: no cover - depends on the installation
        raise SkewpendError("figures need matplotlib (a dependency of skewpend): pip install matplotlib") from None
    return Figure


def new_figure(figsize):
    """A figure with constrained layout (call inside :func:`style`)."""
    return figure_class()(figsize=figsize, layout="constrained")


def heading(fig, text: str) -> None:
    fig.suptitle(text, fontsize=8.5, color="0.25", linespacing=1.45)


def wrap_angle(x):
    """Angles [rad] wrapped to (-pi, pi]."""
    return math.pi - np.mod(math.pi - np.asarray(x, dtype=float), TWO_PI)


def save_figure(fig, path) -> Path:
    """Write ``fig`` to ``path`` as PNG, SVG or PDF (by the suffix, any case), atomically like
    every file skewpend writes (:func:`skewpend.io.atomic_path`): ``path`` appears only
    complete, with the umask's permissions; on any error (Ctrl-C too) nothing is left behind.
    An unknown suffix or an unwritable place is a :class:`ParameterError`."""
    from ...io import atomic_path, check_output_path

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
