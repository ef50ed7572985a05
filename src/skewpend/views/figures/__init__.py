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

from .base import ENERGY_FLOOR, FIGURE_SUFFIXES, FORMATS, save_figure, wrap_angle
from .chaos import (CHAOS_COLORS, LYAPUNOV_COLORS, chaos_diagram_figure, lyapunov_figure, lyapunov_map_figure,
                    poincare_boundary, poincare_figure)
from .control import ROA_COLORS, control_figure, roa_figure
from .orbits import FAMILY_COLORS, alpha_family_figure, fep_figure
from .maps import FLIPMAP_COLORS, flipmap_energy_margin, flipmap_figure, flipmap_forbidden
from .motion import (angles_figure, energy_figure, phase_figure, plot_sweep, simulation_figure, tips_figure,
                     tips_view, torus_figure, wrapped_path)
from ..style import fmt

__all__ = [
    "angles_figure", "phase_figure", "energy_figure", "torus_figure", "tips_figure", "simulation_figure", "plot_sweep",
    "flipmap_figure", "flipmap_forbidden", "flipmap_energy_margin", "FLIPMAP_COLORS", "save_figure", "FORMATS",
    "FIGURE_SUFFIXES", "ENERGY_FLOOR", "wrap_angle", "wrapped_path", "tips_view", "lyapunov_figure", "poincare_figure",
    "poincare_boundary", "chaos_diagram_figure", "lyapunov_map_figure", "LYAPUNOV_COLORS", "CHAOS_COLORS", "fmt",
    "fep_figure", "alpha_family_figure", "FAMILY_COLORS", "control_figure", "roa_figure", "ROA_COLORS",
]
