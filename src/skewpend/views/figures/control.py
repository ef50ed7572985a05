"""A controlled run: angles, the motors' torques and the energy against time."""

from __future__ import annotations

import math

import numpy as np

from ..style import COLORS, SYMBOL, parameter_text, style
from .base import heading, new_figure

__all__ = ["control_figure"]


def control_figure(run):
    """A swing-up (:func:`skewpend.swingup`) drawn against time: the hinge angles (unwrapped,
    degrees) with the target's, the input torques with their limits, and the energy ``E = T + Pi``
    with the target's energy; the capture by the LQR marked.  ``run``: a
    :class:`~skewpend.analysis.control.SwingUp` (it holds the trajectory, the controller and the
    capture time; the figure computes nothing)."""
    tr = run.trajectory
    ctl = run.controller
    u = tr.inputs()
    target = run.lqr.linearization.target
    with style():
        fig = new_figure((8.5, 8.0))
        ax1, ax2, ax3 = fig.subplots(3, 1, sharex=True)
        for k, name in enumerate(("phi", "psi")):
            ang = np.degrees(np.unwrap(tr.y[:, k]))
            ax1.plot(tr.t, ang, color=COLORS[name], label=f"{SYMBOL[name]} (hinge {k + 1})")
        ax1.set_ylabel("angle [deg]")
        ax1.set_title("Hinge angles (unwrapped); the target modulo 360°: "
                      f"{SYMBOL['phi']}* = {math.degrees(target[0]):.4g}°, {SYMBOL['psi']}* = {math.degrees(target[1]):.4g}°",
                      loc="left")
        ax1.legend(loc="best", fontsize=8)
        for j, name in enumerate(("phi", "psi")):
            if ctl.actuated == "both" or (ctl.actuated == "pendubot") == (j == 0):
                ax2.plot(tr.t, u[:, j], color=COLORS[name], lw=1.0, label=f"u{j + 1} (joint {j + 1})")
        for lim in ctl.umax:
            if math.isfinite(lim):
                ax2.axhline(lim, color="0.5", ls="--", lw=0.8)
                ax2.axhline(-lim, color="0.5", ls="--", lw=0.8)
        ax2.set_ylabel("input torque [N m]")
        ax2.set_title(f"Motor torques ({ctl.actuated}; dashed: the limits)", loc="left")
        ax2.legend(loc="best", fontsize=8)
        ax3.plot(tr.t, tr.energy, color=COLORS["path"], label="E = T + Π")
        ax3.axhline(ctl.target_energy, color=COLORS["psi"], ls="--", lw=1.0, label="the target's energy E*")
        ax3.set_ylabel("energy [J]")
        ax3.set_xlabel("t [s]")
        ax3.set_title("Energy: pumped towards E*, then held by the LQR", loc="left")
        for ax in (ax1, ax2, ax3):
            if run.captured:
                ax.axvline(run.capture_time, color="0.3", lw=0.8, ls=":")
        if run.captured:
            ax3.annotate(f"captured at {run.capture_time:.3g} s", (run.capture_time, 0.05), xycoords=ax3.get_xaxis_transform(),
                         textcoords="offset points", xytext=(4, 0), fontsize=8, color="0.3")
        ax3.legend(loc="best", fontsize=8)
        heading(fig, "Swing-up and capture by the LQR\n" + parameter_text(tr.params)
                + f"\n|u| ≤ {ctl.umax[0]:g} N m; " + run.message)
    return fig
