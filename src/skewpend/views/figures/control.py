"""A controlled run: angles, the motors' torques and the energy against time."""

from __future__ import annotations

import math

import numpy as np

from ..style import COLORS, parameter_text, style
from .base import coordinate_label, heading, new_figure

__all__ = ["control_figure", "roa_figure", "leaderboard_figure", "ROA_COLORS"]


def control_figure(run):
    """A swing-up (:func:`skewpend.swingup`) drawn against time: the hinge angles (unwrapped,
    degrees) with the target's, the input torques with their limits, and the energy ``E = T + Pi``
    with the target's energy; the capture by the LQR marked.  ``run``: a
    :class:`~skewpend.analysis.control.SwingUp` (it holds the trajectory, the controller and the
    capture time; the figure computes nothing)."""
    from ...numeric.control import actuated_joints
    from .motion import coordinate_styles

    tr = run.trajectory
    ctl = run.controller
    mpc = getattr(run, "mpc", None)
    u = tr.inputs()
    target = run.lqr.linearization.target
    styles = coordinate_styles(tr.params.coordinates)  # the model's coordinates: phi, psi; q1 ... qn
    with style():
        fig = new_figure((8.5, 8.0))
        ax1, ax2, ax3 = fig.subplots(3, 1, sharex=True)
        for k, (color, symbol, _) in enumerate(styles):
            ax1.plot(tr.t, np.degrees(np.unwrap(tr.y[:, k])), color=color, label=f"{symbol} (hinge {k + 1})")
        ax1.set_ylabel("angle [deg]")
        ax1.set_title("Hinge angles (unwrapped); the target modulo 360°: " + ", ".join(
            f"{symbol}* = {math.degrees(x):.4g}°" for (_, symbol, _), x in zip(styles, target)), loc="left")
        ax1.legend(loc="best", fontsize=8)
        for j in actuated_joints(ctl.actuated, ctl.nq):
            ax2.plot(tr.t, u[:, j - 1], color=styles[j - 1][0], lw=1.0, label=f"u{j} (joint {j})")
        for lim in ctl.umax:
            if math.isfinite(lim):
                ax2.axhline(lim, color="0.5", ls="--", lw=0.8)
                ax2.axhline(-lim, color="0.5", ls="--", lw=0.8)
        ax2.set_ylabel("input torque [N m]")
        ax2.set_title(f"Motor torques ({_actuated_text(ctl.actuated, ctl.nq)}; dashed: the limits)", loc="left")
        ax2.legend(loc="best", fontsize=8)
        ax3.plot(tr.t, tr.energy, color=COLORS["path"], label="E = T + Π")
        ax3.axhline(ctl.target_energy, color=COLORS["psi"], ls="--", lw=1.0, label="the target's energy E*")
        ax3.set_ylabel("energy [J]")
        ax3.set_xlabel("t [s]")
        ax3.set_title("Energy: pumped towards E*, then held by the LQR" if mpc is None else
                      "Energy: driven towards E* by the MPC's cost, then held at the goal", loc="left")
        if run.captured:
            for ax in (ax1, ax2, ax3):
                ax.axvline(run.capture_time, color="0.3", lw=0.8, ls=":")
            ax3.annotate(f"captured at {run.capture_time:.3g} s", (run.capture_time, 0.05), xycoords=ax3.get_xaxis_transform(),
                         textcoords="offset points", xytext=(4, 0), fontsize=8, color="0.3")
        ax3.legend(loc="best", fontsize=8)
        limits = sorted({u for u in ctl.umax if math.isfinite(u)})
        limit = "no torque limit" if not limits else "|u| ≤ " + ", ".join(f"{u:g}" for u in limits) + " N m"
        heading(fig, ("Swing-up and capture by the LQR\n" if mpc is None else
                      "Swing-up by model-predictive control, captured in the LQR's region\n") + parameter_text(tr.params)
                + f"\n{limit}; " + run.message)
    return fig


#: Colours of the region-of-attraction map: capture times, not captured, failed, the LQR's estimate.
ROA_COLORS = {"cmap": "viridis", "not_captured": "#f2f2f2", "failed": "#e4572e", "estimate": "#111111",
              "target": "#e4572e"}


def _actuated_text(actuated, nq: int) -> str:
    """A map's actuated joints for its heading: the double pendulum's label, a chain's joints."""
    if isinstance(actuated, str):
        return actuated
    joints = list(actuated)
    if len(joints) == nq:
        return "every joint driven"
    return ("joints " if len(joints) > 1 else "joint ") + ", ".join(str(j) for j in joints) + " driven"


def roa_figure(roa):
    """A region of attraction (:func:`skewpend.region_of_attraction`): the capture time of every
    start on the slice (offsets from the target, degrees), the starts not captured by ``t_end``
    light grey, failed ones red, and the LQR's inner estimate ``dx^T P dx < rho`` (its slice)
    drawn on the same axes; the captured fraction in the heading."""
    from matplotlib.colors import ListedColormap

    dx, dy = roa.deviations()
    order_x, order_y = np.argsort(dx), np.argsort(dy)
    x, y = np.degrees(dx[order_x]), np.degrees(dy[order_y])
    t = roa.capture_time[np.ix_(order_x, order_y)]
    outcome = roa.outcome[np.ix_(order_x, order_y)]
    settings = roa.settings
    with style():
        fig = new_figure((7.6, 6.6))
        ax = fig.subplots()
        for value, color in ((0, "not_captured"), (-1, "failed")):  # flat patches: not captured (always drawn), failed
            if value == 0 or np.any(outcome == value):
                ax.pcolormesh(x, y, np.where(outcome == value, 0.0, np.nan).T, cmap=ListedColormap([ROA_COLORS[color]]),
                              shading="nearest")
        mesh = ax.pcolormesh(x, y, t.T, cmap=ROA_COLORS["cmap"], shading="nearest", vmin=0.0,
                             vmax=max(float(np.nanmax(t)) if np.any(np.isfinite(t)) else 1.0, 1e-9))
        cbar = fig.colorbar(mesh, ax=ax, pad=0.02)
        cbar.set_label("time to enter the LQR's estimate [s]")
        e = np.degrees(roa.ellipse())
        ax.plot(e[:, 0], e[:, 1], color=ROA_COLORS["estimate"], lw=1.4, label="LQR estimate  dxᵀP dx < ρ (inner bound)")
        ax.plot([0], [0], marker="+", ms=12, mew=2, color=ROA_COLORS["target"], ls="none", label="the target")
        from matplotlib.patches import Patch

        handles, labels = ax.get_legend_handles_labels()
        handles.append(Patch(color=ROA_COLORS["not_captured"], ec="0.6", label=f"not captured by t = {settings['t_end']:g} s"))
        if np.any(outcome == -1):
            handles.append(Patch(color=ROA_COLORS["failed"], label="failed (chatters on the law's jump)"))
        ax.legend(handles=handles, loc="upper right", fontsize=8, framealpha=0.9)
        ax.set_xlabel(coordinate_label(roa.plane[0]))
        ax.set_ylabel(coordinate_label(roa.plane[1]))
        ax.set_xlim(x[0] - 0.5 * (x[1] - x[0]) if x.size > 1 else x[0] - 1, x[-1] + 0.5 * (x[-1] - x[-2]) if x.size > 1 else x[-1] + 1)
        ax.set_ylim(y[0] - 0.5 * (y[1] - y[0]) if y.size > 1 else y[0] - 1, y[-1] + 0.5 * (y[-1] - y[-2]) if y.size > 1 else y[-1] + 1)
        nq = len(roa.target) // 2
        umax = settings.get("umax") or [None, None]
        limit = "no torque limit" if umax[0] is None else f"|u| ≤ {umax[0]:g} N m"
        tgt = ", ".join(f"{math.degrees(v):.4g}°" for v in roa.target[:nq])
        heading(fig, f"Region of attraction of the LQR at ({tgt}), {_actuated_text(settings['actuated'], nq)}, {limit}\n"
                + parameter_text(roa.params)
                + f"\ncaptured: {100 * roa.captured_fraction:.1f} % of {roa.n} × {roa.n} starts "
                f"(the estimate holds {100 * roa.inner_fraction:.2f} %)")
    return fig


def leaderboard_figure(run, reference=None, title: str = ""):
    """A run by the RealAIGym leaderboard's protocol (:func:`skewpend.analysis.leaderboard.run_protocol`):
    the joint angles (unwrapped, degrees), the end effector's height with the success line, and the
    motors' torques, against time over the swing-up and the first seconds held; the optimised
    reference (a :class:`~skewpend.analysis.trajopt.Tracking`'s) when given, a wide light band under the run."""
    c = run.criteria
    n = run.x.shape[1] // 2
    shown = min(run.t[-1], max(3.0, (c.swingup_time if math.isfinite(c.swingup_time) else 0.0) + 2.0))
    keep = run.t <= shown
    t = run.t[keep]
    palette = [COLORS["phi"], COLORS["psi"], COLORS["path"], "#6a4c93", "#1982c4"]
    with style():
        fig = new_figure((8.5, 8.0))
        ax1, ax2, ax3 = fig.subplots(3, 1, sharex=True)
        # the optimised reference as a wide light band under the run (a dashed line of the same colour hid under
        # a run that follows it, issue 51): the run inside its band is the motion tracked
        rt = None if reference is None else np.arange(len(reference.x_ref)) * reference.dt
        for j in range(n):
            if reference is not None:
                ax1.plot(rt, np.degrees(reference.x_ref[:, j]), color=palette[j % len(palette)], lw=6, alpha=0.28,
                         solid_capstyle="butt", label=f"q{j + 1}, optimised")
            ax1.plot(t, np.degrees(np.unwrap(run.x[keep, j])), color=palette[j % len(palette)], lw=1.2,
                     label=f"q{j + 1}, run")
        ax1.set_ylabel("angle [deg]")
        ax1.set_title("Joint angles (unwrapped; q2 relative to rod 1)", loc="left")
        ax1.legend(loc="best", fontsize=8, ncol=2)
        ax2.plot(t, run.heights[keep], color=COLORS["path"], label="end effector")
        line = run.protocol.height * run.reach
        ax2.axhline(line, color="0.4", ls="--", lw=0.9, label=f"success line {run.protocol.height:g} x reach")
        if c.success:
            ax2.axvline(c.swingup_time, color="0.3", ls=":", lw=0.8)
            ax2.annotate(f"swing-up time {c.swingup_time:.3g} s", (c.swingup_time, 0.05), xycoords=ax2.get_xaxis_transform(),
                         textcoords="offset points", xytext=(4, 0), fontsize=8, color="0.3")
        ax2.set_ylabel("height [m]")
        ax2.set_title("End effector's height above the roof hinge", loc="left")
        ax2.legend(loc="lower right", fontsize=8)
        for j in range(n):
            if np.any(run.u[:, j]):
                if reference is not None and j + 1 in reference.actuated:
                    ax3.plot(rt, reference.u_ref[:, list(reference.actuated).index(j + 1)], color=palette[j % len(palette)],
                             lw=6, alpha=0.28, solid_capstyle="butt", label=f"u{j + 1}, optimised")
                ax3.plot(t, run.u[keep, j], color=palette[j % len(palette)], lw=1.0, label=f"u{j + 1} (joint {j + 1})")
        ax3.axhline(run.protocol.umax, color="0.5", ls="--", lw=0.8)
        ax3.axhline(-run.protocol.umax, color="0.5", ls="--", lw=0.8)
        ax3.set_ylabel("torque [N m]")
        ax3.set_xlabel("t [s]")
        ax3.set_title(f"Motor torques, held over each {run.protocol.dt * 1e3:g} ms step (dashed: the limits)", loc="left")
        ax3.legend(loc="best", fontsize=8)
        crit = (f"score {c.score:.3f}: swing-up {c.swingup_time:.3g} s, energy {c.energy:.3g} J, torque cost "
                f"{c.tau_cost:.3g}, smoothness {c.tau_smoothness:.3g}, velocity cost {c.velocity_cost:.4g}"
                if c.success else "no success: the end effector does not stay above the line")
        heading(fig, (title or "A swing-up by the RealAIGym leaderboard's protocol") + "\n" + crit
                + f"\nshown: the first {shown:.3g} s of {run.t[-1] + run.protocol.dt:g} s")
    return fig
