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
from .control import ROA_COLORS, control_figure, leaderboard_figure, roa_figure
from .orbits import FAMILY_COLORS, alpha_family_figure, fep_figure
from .maps import FLIPMAP_COLORS, flipmap_energy_margin, flipmap_figure, flipmap_forbidden
from .motion import (angles_figure, energy_figure, phase_figure, plot_sweep, simulation_figure, tips_figure,
                     tips_view, torus_figure, wrapped_path)
from ..style import fmt


def _refusing_wrong_types(fn, what: str):
    """``fn`` with one clear :class:`~skewpend.ParameterError` when its first argument is not the
    result it draws (``angles_figure("x")`` was an AttributeError); duck-typed stand-ins still work."""
    import functools
    import inspect

    from ...errors import ParameterError

    name = next(iter(inspect.signature(fn).parameters))

    @functools.wraps(fn)
    def call(obj, *args, **kwargs):
        try:
            return fn(obj, *args, **kwargs)
        except AttributeError as exc:
            bad = getattr(exc, "obj", object())
            if bad is obj:  # the argument itself lacks what the result has
                raise ParameterError(f"{name} must be {what}, got {type(obj).__name__}") from None
            if isinstance(obj, (list, tuple)) and any(bad is item for item in obj):  # one of a sequence's items
                raise ParameterError(f"{name} must be {what}, got a {type(obj).__name__} holding "
                                     f"{type(bad).__name__}") from None
            raise

    return call


_TRAJECTORY = "a skewpend.Trajectory (from skewpend.simulate)"
for _fn, _what in (*((f, _TRAJECTORY) for f in (angles_figure, phase_figure, energy_figure, torus_figure, tips_figure,
                                                 simulation_figure)),
                   (plot_sweep, "a skewpend.modes.Sweep"), (flipmap_figure, "a skewpend.FlipMap"),
                   (lyapunov_figure, "a skewpend.LyapunovSpectrum"), (poincare_figure, "a skewpend.PoincareSection"),
                   (chaos_diagram_figure, "a skewpend.ChaosDiagram"), (lyapunov_map_figure, "a skewpend.LyapunovMap"),
                   (control_figure, "a swing-up run (skewpend.swingup)"),
                   (roa_figure, "a skewpend.RegionOfAttraction"),
                   (leaderboard_figure, "a run by the leaderboard's protocol (leaderboard.run_protocol)"),
                   (fep_figure, "a sequence of nonlinear normal mode families (skewpend.nnm)"),
                   (alpha_family_figure, "a sequence of families in alpha (skewpend.nnm_alpha)")):
    globals()[_fn.__name__] = _refusing_wrong_types(_fn, _what)
del _fn, _what

__all__ = [
    "angles_figure", "phase_figure", "energy_figure", "torus_figure", "tips_figure", "simulation_figure", "plot_sweep",
    "flipmap_figure", "flipmap_forbidden", "flipmap_energy_margin", "FLIPMAP_COLORS", "save_figure", "FORMATS",
    "FIGURE_SUFFIXES", "ENERGY_FLOOR", "wrap_angle", "wrapped_path", "tips_view", "lyapunov_figure", "poincare_figure",
    "poincare_boundary", "chaos_diagram_figure", "lyapunov_map_figure", "LYAPUNOV_COLORS", "CHAOS_COLORS", "fmt",
    "fep_figure", "alpha_family_figure", "FAMILY_COLORS", "control_figure", "roa_figure", "leaderboard_figure", "ROA_COLORS",
]
