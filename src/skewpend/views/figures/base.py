"""What every figure shares: the Matplotlib figure class (imported on first use), a new figure
with constrained layout, the heading, the angle wrap, :func:`print_figure` (how every figure is
written: tick labels as plain text, the layout computed once for a PNG) and :func:`save_figure`."""

from __future__ import annotations

import math
from functools import lru_cache
from pathlib import Path
from typing import Optional

import numpy as np

from ... import __version__
from ...errors import SkewpendError
from ..style import COLORS, DPI, SYMBOL, style

__all__ = ["FIGURE_SUFFIXES", "FORMATS", "ENERGY_FLOOR", "TWO_PI", "figure_class", "new_figure", "heading",
           "wrap_angle", "plain_tick_labels", "print_figure", "save_figure"]

#: File formats :func:`save_figure` writes, by suffix.
FIGURE_SUFFIXES = FORMATS = (".png", ".svg", ".pdf")

#: The relative energy error is drawn no lower than this on its log axis (exact zeros, e.g. at t = 0).
ENERGY_FLOOR = 1e-17

TWO_PI = 2.0 * math.pi

#: The colour of mode k (and of its family of nonlinear normal modes): mode 1 and 2 those of phi and psi
#: elsewhere; a chain's further modes from Matplotlib's tab10.
MODE_COLORS = {1: COLORS["phi"], 2: COLORS["psi"], 3: "#2ca02c", 4: "#9467bd", 5: "#8c564b", 6: "#e377c2",
               7: "#7f7f7f", 8: "#bcbd22", 9: "#17becf", 10: "#d62728"}


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


#: Characters of the heading's 8.5 pt text per inch of figure width (a longer line is wrapped, not clipped).
HEADING_CHARS_PER_INCH = 16.0


def _wrap_items(line: str, width: int) -> list:
    """``line`` in lines of at most ``width`` characters, broken only after a ``, `` or ``; `` (an item
    such as ``t_end = 10 s`` is never split); an item longer than ``width`` stands on a line of its own."""
    import re

    items = re.split(r"(?<=[,;]) ", line)
    lines, current = [], ""
    for item in items:
        if current and len(current) + 1 + len(item) > width:
            lines.append(current)
            current = item
        else:
            current = f"{current} {item}" if current else item
    return lines + [current]


def heading(fig, text: str) -> None:
    """The figure's heading, each line longer than the figure is wide wrapped after a comma or semicolon."""
    width = max(40, int(fig.get_figwidth() * HEADING_CHARS_PER_INCH))
    lines = [part for line in text.split("\n") for part in _wrap_items(line, width)]  # a short line stays whole
    fig.suptitle("\n".join(lines), fontsize=8.5, color="0.25", linespacing=1.45)


def wrap_angle(x):
    """Angles [rad] wrapped to (-pi, pi]."""
    return math.pi - np.mod(math.pi - np.asarray(x, dtype=float), TWO_PI)


@lru_cache(maxsize=1)
def _plain_formatter():
    """Matplotlib's ScalarFormatter whose tick labels are plain text rather than mathtext (made once)."""
    from matplotlib.ticker import ScalarFormatter

    class PlainTickFormatter(ScalarFormatter):
        """A ScalarFormatter writing ``0.5`` where it wrote ``$\\mathdefault{0.5}$``: the same digits in the
        same DejaVu Sans (and the same minus sign, U+2212), without a mathtext parse of every label;
        the offset or the power of ten above the axis (``×10⁻⁵``), when there is one, stays mathtext."""

        def __call__(self, x, pos=None):
            s = super().__call__(x, pos)
            head, tail = "$\\mathdefault{", "}$"
            if s.startswith(head) and s.endswith(tail) and not any(c in s[len(head):-len(tail)] for c in "\\{}$^_"):
                return s[len(head):-len(tail)]
            return s

    return PlainTickFormatter


def plain_tick_labels(fig) -> None:
    """Every plain ScalarFormatter of ``fig`` (``axes.formatter.use_mathtext`` on, as :data:`~skewpend.views.style.RC`
    has it) writes its tick labels as plain text: the picture is the same to the eye, and the labels are
    no longer parsed as mathtext in each layout pass and each draw (about a tenth of the time to write a
    report figure)."""
    from matplotlib.ticker import ScalarFormatter

    plain = _plain_formatter()
    for ax in fig.axes:
        for axis in (ax.xaxis, ax.yaxis, getattr(ax, "zaxis", None)):
            if axis is None:
                continue
            formatter = axis.get_major_formatter()
            if type(formatter) is ScalarFormatter and formatter.get_useMathText():
                formatter.__class__ = plain  # the same state (limits, offset, locale), only __call__ differs


def print_figure(fig, fh, fmt_name: str, dpi: float, metadata: dict, pil_kwargs: Optional[dict] = None) -> None:
    """``fig.savefig(fh, format=fmt_name, dpi=dpi, metadata=metadata)`` in the skewpend style, cheaper
    for the same picture: tick labels as plain text (:func:`plain_tick_labels`), and for a PNG of a
    figure with a layout engine the layout computed once, on the renderer that then draws it
    (``savefig`` itself lays the figure out in a first draw that paints nothing, then draws it again;
    here the layout is run directly and ``savefig`` draws once: the same pixels).  ``pil_kwargs``: for a
    PNG, passed to Pillow (``{"compress_level": 3}``: faster, a few per cent larger)."""
    from matplotlib.backend_bases import FigureCanvasBase

    plain_tick_labels(fig)
    png = {"pil_kwargs": pil_kwargs} if pil_kwargs and fmt_name == "png" else {}
    with style():
        engine = fig.get_layout_engine()
        if fmt_name != "png" or engine is None or type(fig.canvas) is not FigureCanvasBase:
            fig.savefig(fh, format=fmt_name, dpi=dpi, metadata=metadata, **png)
            return
        from matplotlib.backends.backend_agg import FigureCanvasAgg

        old_dpi = fig.dpi
        FigureCanvasAgg(fig)  # the canvas savefig would switch to: its renderer (cached per size and dpi) is reused
        try:
            fig.set_dpi(dpi)
            engine.execute(fig)
            fig.set_layout_engine("none")
            fig.savefig(fh, format=fmt_name, dpi=dpi, metadata=metadata, **png)
        finally:
            fig.set_layout_engine(engine)
            fig.set_dpi(old_dpi)


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
    with atomic_path(path) as tmp, open(tmp, "wb") as fh:
        print_figure(fig, fh, fmt_name, DPI, metadata)
    return path


def coordinate_label(name: str) -> str:
    """An axis label of a state coordinate's offset from a target: ``φ − φ* [deg]``, ``q₃′ − q₃′* [deg/s]``."""
    speed = name.startswith("d")
    base = name[1:] if speed else name
    # a chain's q<k> with its index as subscript digits
    sym = SYMBOL.get(base) or "q" + base[1:].translate(str.maketrans("0123456789", "₀₁₂₃₄₅₆₇₈₉"))
    sym += "′" if speed else ""
    return f"{sym} − {sym}* [{'deg/s' if speed else 'deg'}]"
