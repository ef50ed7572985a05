"""``control leaderboard``: optimise a swing-up of the RealAIGym leaderboard's plant, track it, run and score it
by the leaderboard's protocol (the library: :mod:`skewpend.analysis.trajopt`, :mod:`skewpend.analysis.leaderboard`)."""

from __future__ import annotations

import math
import sys
from typing import Optional

from ..parsing import UsageError
from ..progress import stage
from .simulate import check_plot

__all__ = ["run_leaderboard", "mpc_line"]


def check_model_options(model: dict, config: Optional[str]) -> float:
    """The skew angle of the leaderboard's plant (``--alpha``, default 0); every other model option and a run
    file refused in one line: the plant is the leaderboard's."""
    other = sorted(k for k, v in model.items() if v is not None and k != "alpha")
    if other or config is not None:
        what = f"--{other[0].replace('_', '-')}" if other else "--config"
        raise UsageError(f"{what}: control leaderboard runs the leaderboard's plant (the DFKI lab's design C.1, "
                         "model 1.1); only --alpha changes it (the second hinge turned by that angle)")
    alpha = model.get("alpha")
    if alpha is None:
        return 0.0
    if isinstance(alpha, str) or not math.isfinite(alpha):  # 'sym': the leaderboard's plant is simulated, so numeric
        raise UsageError(f"--alpha: control leaderboard simulates the plant, so its skew must be a number (e.g. "
                         f"--alpha 10deg), not {alpha!r}")
    return float(alpha)


#: Seconds between two redraws of IPOPT's iteration counts on a terminal.
REDRAW = 0.25
#: What the published boards are: the lab's planar rig (a skewed run is not compared with them).
PLANAR_NOTE = "the published boards are the planar rig's (alpha = 0)"


def ipopt_reporter(what: str, stages=None, clock=None):
    """``iterations(running, solved, total)`` for :func:`~skewpend.analysis.trajopt.optimal_swingup`: IPOPT's
    progress as the command's stage ``what``.  On a terminal the iterations each running start has reached
    (redrawn at most every :data:`REDRAW` s) and the bar at the starts solved; off one, a line as a start begins
    (a line per stage).  None when no command runs."""
    import time

    from ..progress import active

    stages = active() if stages is None else stages
    if stages is None:
        return None
    clock = time.monotonic if clock is None else clock
    last = {"at": -math.inf, "starts": None, "begun": set()}

    def report(running, solved, total):
        starts = tuple(sorted(running))
        if stages.terminal:
            now = clock()
            if now - last["at"] < REDRAW and starts == last["starts"]:
                return
            last["at"], last["starts"] = now, starts
            each = "; ".join(f"start {k + 1} of {total} at iteration {running[k]}" for k in starts)
            stages.stage(f"{what}: {each or f'{solved} of {total} starts solved'}")
            stages.update(solved, total)
        elif not set(starts) <= last["begun"]:  # a start began: a line (a start that ends adds none)
            last["begun"].update(starts)
            word = "start" if len(starts) == 1 else "starts"
            stages.stage(f"{what}: IPOPT on {word} {', '.join(str(k + 1) for k in starts)} of {total} "
                         f"({solved} solved)")

    return report


def mpc_line(mpc) -> str:
    """The MPC's account, one line: its problem, its solves' wall times, its fallbacks."""
    import numpy as np

    times = mpc.solve_times * 1e3
    line = (f"controller  model-predictive: {mpc.settings.nodes} RK4 nodes over {mpc.settings.horizon:g} s, sampled every "
            f"{mpc.period * 1e3:g} ms; {times.size} solves, median {np.median(times):.3g} ms, max {times.max():.3g} ms"
            if times.size else "controller  model-predictive: no solve")
    if mpc.estimating:
        line += f"; the measurement's delay estimated (0 to {mpc.past * mpc.period:g} s): {mpc.delay * 1e3:g} ms at the end"
    return line + (f"; {mpc.message}" if mpc.message else "; no step failed")


def _robustness_lines(robot: str, joints, alpha: float, limit: float, tracking) -> list:
    """The robustness board's evaluation of ``tracking`` (the speeds from the positions), as report lines; the
    published best beside it only for the planar rig (the published board's)."""
    from ..analysis import robustness as rb
    from ..progress import active, stage

    labels = {"model": "model errors", "velocity_noise": "speed noise", "torque_noise": "torque noise",
              "torque_response": "torque response", "delay": "delay", "perturbation": "perturbations"}
    what = (f"the robustness board: {rb.ROBUSTNESS.values} model variations of each of {len(rb.LAB_VARIATIONS)} "
            "parameters, noise, response, delay and perturbations (722 runs)")
    stage(what)
    stages = active()
    current = [None]

    def progress(criterion, done, total):  # a stage per criterion, the bar at the runs done
        if stages is None:
            return
        if criterion != current[0]:
            current[0] = criterion
            stages.stage(f"the robustness board: {labels.get(criterion, criterion)} (runs from {done} of {total})")
        stages.update(done, total)

    r = rb.robustness(tracking, actuated=joints, alpha=alpha, umax=limit, speeds="positions", progress=progress)
    name, published, best = rb.PUBLISHED_ROBUSTNESS[robot]
    # a skewed rig's criteria without the published ones beside them (those are the planar rig's)
    lines = [f"{'robustness (v2)':<22} {'skewpend':>12}" + ("" if alpha else f"   {name}")]
    lines += [f"{labels[key]:<22} {r.criteria[key]:12.3f}" + ("" if alpha else f"   {theirs:.3f}")
              for key, theirs in zip(rb.CRITERIA, published)]
    lines.append(f"{'robustness score':<22} {r.score:12.4f}   " + (
        f"{r.simulations} runs, seed 0; not compared: {PLANAR_NOTE}, best {best:.3f} ({name})" if alpha else
        f"best published: {best:.3f} ({name}); {r.simulations} runs, seed 0"))
    return lines


def _v3_lines(robot: str, run, alpha: float, controller: str = "tvlqr") -> list:
    """The simulation v3 board's criteria of ``run`` as report lines, the published best beside the score only
    for the planar rig."""
    from ..analysis import leaderboard as lb

    c = run.criteria
    r = run.protocol.resets
    name, best = lb.PUBLISHED[robot]["simulation_v3"]
    lines = [f"protocol     simulation v3: {run.protocol.t_final:g} s, {r.count} resets to random states (a PID and "
             f"gravity compensation for {r.length:g} s each; seed {r.seed})" + (
                 "; the law is time-indexed, so after a reset it only holds the goal by its final LQR"
                 if controller == "tvlqr" else "; the MPC swings up from wherever a reset leaves the rods"),
             f"{'criterion':<22} {'skewpend':>12}",
             f"{'uptime [s]':<22} {c.uptime:12.4f}",
             f"{'swing-ups':<22} {c.swingups:12d}"]
    if alpha:
        lines.append(f"{'score (v3)':<22} {c.score:12.4f}   not compared: {PLANAR_NOTE}, best {best:.3f} ({name})")
    else:
        lines.append(f"{'score (v3)':<22} {c.score:12.4f}   best published: {best:.3f} ({name})")
    return lines


def run_leaderboard(robot: Optional[str], alpha: float, umax: Optional[float], out: Optional[str],
                    plot: Optional[str], quiet: bool, robustness: bool = False, version: str = "v2",
                    controller: Optional[str] = None) -> int:
    """Optimise, track, run by the protocol, score; print the criteria beside the best published entry (and,
    with ``robustness``, the robustness board's six criteria and score beside its best entry's).  ``version``:
    the simulation board, ``"v2"`` (one swing-up from hanging) or ``"v3"`` (the tracking run as a global policy
    through the v3 board's resets, scored by its uptime).  ``controller``: ``"tvlqr"`` (the optimal swing-up
    tracked by time-varying LQR; v2's default) or ``"mpc"`` (:class:`~skewpend.analysis.mpc.MPC`, a global
    policy; v3's default).  Exit status 0 on success (v3: a run that completed), 1 when the optimisation fails
    or the v2 run does not stay up."""
    from ..analysis import leaderboard as lb
    from ..analysis.trajopt import optimal_swingup, tvlqr

    if version not in ("v2", "v3"):
        raise UsageError(f"--version: the simulation board is v2 or v3, got {version!r}")
    if robot is None:
        raise UsageError("control leaderboard: give --robot acrobot or --robot pendubot (the joint with the motor: "
                         "the elbow, the shoulder)")
    if version == "v3" and plot is not None:
        raise UsageError("--plot: control leaderboard draws the v2 swing-up's figure; with --version v3 write the run "
                         "with --out instead")
    if out is not None:
        from ..io import check_output_path

        check_output_path(out, (".csv",), option="--out")
    check_plot(plot)
    limit = lb.PROTOCOL.umax if umax is None else float(umax)
    model = lb.dfki_model(alpha)
    joints = lb.ROBOTS[robot]
    skew = f", alpha = {math.degrees(alpha):.4g} deg" if alpha else ""
    what = f"optimising the {robot}'s swing-up (IPOPT, {limit:g} N m{skew})"
    controller = controller or ("mpc" if version == "v3" else "tvlqr")
    if controller == "mpc":
        from ..analysis.mpc import BOARD_SETTINGS, MPC

        stage("building the model-predictive controller (its C function: compiled once, then cached)")
        tracking, traj = MPC(model, actuated=joints, umax=limit, settings=BOARD_SETTINGS), None
    else:
        stage(what)
        traj = optimal_swingup(model, actuated=joints, umax=limit, iterations=ipopt_reporter(what))
        if not traj.ok:
            sys.stderr.write(f"skewpend: {traj.message}\n")
            return 1
        stage("designing the time-varying LQR along it")
        tracking = tvlqr(traj)
    if version == "v3":
        from dataclasses import replace

        protocol = replace(lb.PROTOCOL_V3, umax=limit)
        stage(f"running the v3 board's protocol ({protocol.steps} RK4 steps of {protocol.dt:g} s, "
              f"{protocol.resets.count} resets)")
    else:
        protocol = lb.Protocol(umax=limit)
        stage(f"running the leaderboard's protocol ({protocol.steps} RK4 steps of {protocol.dt:g} s)")
    run = lb.run_protocol(model, tracking, actuated=joints, umax=limit, protocol=protocol)
    if not run.ok:
        sys.stderr.write(f"skewpend: the tracked swing-up failed by the leaderboard's protocol: {run.message}\n")
        return 1
    c = run.criteria
    name, best = lb.PUBLISHED[robot]["simulation"]
    lines = [
        f"robot        {robot} (motor on joint {joints[0]}), the DFKI lab's design C.1, model 1.1{skew}; |u| <= {limit:g} N m"]
    if traj is None:
        lines.append(mpc_line(tracking).replace("controller  ", "controller   ", 1))
    else:
        lines.append(f"optimised    {traj.message}; the motion takes {traj.duration:.4g} s to the goal; solved in "
                     f"{traj.solve_time:.3g} s ({traj.attempts} seeded starts)")
    if version == "v3":
        lines += _v3_lines(robot, run, alpha, controller)
        if robustness:
            lines += _robustness_lines(robot, joints, alpha, limit, tracking)
        if out is not None:
            lb.write_csv(out, run.t, run.x, run.u)
            lines.append(f"written      {out} (the leaderboard's columns)")
        sys.stdout.write("\n".join(lines) + "\n")
        return 0
    lines.append(f"{'criterion':<22} {'skewpend':>12}")
    for key, label in (("swingup_time", "swing-up time [s]"), ("energy", "energy [J]"), ("tau_cost", "torque cost"),
                       ("tau_smoothness", "torque smoothness"), ("velocity_cost", "velocity cost")):
        lines.append(f"{label:<22} {getattr(c, key):12.5g}")
    lines.append(f"{'success':<22} {'yes' if c.success else 'no':>12}")
    if alpha:  # like with like: the published board is the planar rig's
        lines.append(f"{'score (v2)':<22} {c.score:12.4f}   not compared: {PLANAR_NOTE}, best {best:.3f} ({name})")
    else:
        lines.append(f"{'score (v2)':<22} {c.score:12.4f}   best published: {best:.3f} ({name})")
    if robustness:
        lines += _robustness_lines(robot, joints, alpha, limit, tracking)
    if out is not None:
        lb.write_csv(out, run.t, run.x, run.u)
        lines.append(f"written      {out} (the leaderboard's columns)")
    if plot is not None:
        stage(f"drawing {plot}")
        from ..views import figures

        title = (f"The {robot}'s optimal swing-up, tracked by time-varying LQR{skew}" if traj is not None else
                 f"The {robot}'s swing-up by model-predictive control{skew}")
        figures.save_figure(figures.leaderboard_figure(run, tracking if traj is not None else None, title), plot)
        lines.append(f"plot         {plot}")
    sys.stdout.write("\n".join(lines) + "\n")
    return 0 if c.success else 1
