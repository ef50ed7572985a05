"""Moved to :mod:`skewpend.views.figures`; this re-export goes away."""
from .views.figures import plot_sweep, save_figure  # noqa: F401
