"""``control lqr|swingup|roa``: balance the pendulum at an equilibrium with LQR, swing it up to it,
and map the LQR's region of attraction."""

from __future__ import annotations

import math
import sys
from enum import Enum
from typing import Annotated, Optional

import typer

from ..parsing import UsageError
from . import types as T
from .analyses import ATOL_E8, RTOL_E8, RESUME, draw_figure, ensemble_outputs
from ..progress import stage
from .options import CONFIG, ENSEMBLE, MODEL, QUIET, RUN, command, option, plot_option, progress, resolve
from .simulate import check_plot

COMMANDS = ("control",)


class Action(str, Enum):
    lqr = "lqr"
    swingup = "swingup"
    roa = "roa"
    leaderboard = "leaderboard"


class Robot(str, Enum):
    acrobot = "acrobot"
    pendubot = "pendubot"


class Board(str, Enum):
    v2 = "v2"
    v3 = "v3"


class Law(str, Enum):
    energy = "energy"
    tvlqr = "tvlqr"
    mpc = "mpc"


#: Which controllers each action runs (the first its default; leaderboard's default is the board's: see run_leaderboard).
LAWS = {"swingup": ("energy", "mpc"), "leaderboard": ("tvlqr", "mpc")}


#: The options that belong to some actions only (the others refuse them with one line).
ONLY = {
    "--robot": ("leaderboard",), "--robustness": ("leaderboard",), "--version": ("leaderboard",),
    "--controller": ("swingup", "leaderboard"), "--target": ("lqr", "swingup", "roa"), "--actuated": ("lqr", "swingup", "roa"),
    "--q": ("lqr", "swingup", "roa"), "--r": ("lqr", "swingup", "roa"),
    "--t-end": ("swingup", "roa"), "--energy-gain": ("swingup",), "--elbow-gains": ("swingup",), "--out": ("swingup", "roa", "leaderboard"),
    "--plot": ("swingup", "roa", "leaderboard"), "--animate": ("swingup",), "--n": ("roa",), "--plane": ("roa",), "--window": ("roa",),
    "--rtol": ("roa",), "--atol": ("roa",), "--resume": ("roa",), "--workers": ("roa",), "--scheduler": ("roa",),
}


@command(MODEL, ENSEMBLE)
def control(
    model: dict,
    ensemble: dict,
    action: Annotated[Optional[Action], typer.Argument(help="lqr: the gain at the target, its closed-loop eigenvalues and region estimate; swingup: from hanging to the target and capture by the LQR; roa: the LQR's region of attraction on a grid of starts; leaderboard: an optimal swing-up of the RealAIGym leaderboard's plant, tracked by time-varying LQR, run and scored by the leaderboard's protocol", show_default=False)] = None,
    robot: Annotated[Optional[Robot], typer.Option("--robot", help="leaderboard: acrobot (the motor on the elbow) or pendubot (on the shoulder); required", show_default=False)] = None,
    robustness: Annotated[bool, typer.Option("--robustness", help="leaderboard: also the robustness board's evaluation (v2: 722 runs with model errors, speed noise, torque noise, torque response, delay and perturbations); default off")] = False,
    version: Annotated[Optional[Board], typer.Option("--version", help="leaderboard: the simulation board's protocol and score, v2 (one swing-up from hanging, 10 s; the default) or v3 (a global policy: 60 s, 15 resets to random states, scored by the time up)", show_default=False)] = None,
    controller: Annotated[Optional[Law], typer.Option("--controller", help="swingup: energy (energy shaping, then the LQR; the default) or mpc (model-predictive control, sampled every 2 ms); leaderboard: tvlqr (the optimal swing-up tracked by time-varying LQR; v2's default) or mpc (a global policy; v3's default)", show_default=False)] = None,
    target: option("--target", T.EquilibriumChoice(), "the equilibrium to balance at: a label (default up-up) or PHI,PSI near one") = None,
    actuated: option("--actuated", T.Actuation(), "the joints with a motor: both or all (default: every joint), the joints' numbers, e.g. 2 or 1,3; for two links acrobot (the elbow only) or pendubot (the shoulder only)") = None,
    q: option("--q", T.Numbers(most=64, metavar="Q1,Q2,..."), "LQR state weights: the diagonal of Q, one per coordinate and rate, (phi, psi, phi', psi') for the double pendulum (default all 1)") = None,
    r: option("--r", T.Numbers(most=31, metavar="R1[,R2,...]"), "LQR input weights: the diagonal of R, one per actuated joint (default 1)") = None,
    umax: option("--umax", T.Positive("number of N m"), "torque limit of each motor [N m] (default: none for lqr, 10 for swingup and roa, 6 for leaderboard)") = None,
    t_end: option("--t-end", T.Positive("number of seconds"), "swingup: length of the run [s] (default 20); roa: longest time each start is followed (default 10)") = None,
    energy_gain: option("--energy-gain", T.Positive(), "swingup: gain of the energy shaping [N m s/J] (default 2)") = None,
    elbow_gains: option("--elbow-gains", T.Numbers(2, metavar="KP,KD"), "swingup: the elbow's PD gains holding rod 2 in line while the energy is pumped (default 20,4)") = None,
    n: option("--n", T.Whole(1, 4096), "roa: cells per side, an n x n grid of starts (default 64)") = None,
    plane: option("--plane", T.Plane(), "roa: the two coordinates varied, of phi, psi, dphi, dpsi (a chain's q1 .. qn, dq1 .. dqn; default the first two angles; the others at the target's)") = None,
    window: option("--window", T.Offsets(), "roa: their ranges as offsets from the target, LO:HI,LO:HI (radians or deg; rad/s or deg/s; default -180:180deg for an angle, -5:5 for a speed)") = None,
    rtol: RTOL_E8 = None,
    atol: ATOL_E8 = None,
    out: option("--out", T.OutPath((".csv", ".nc", ".zarr"), check=False), "swingup: write the run to FILE (.csv or .nc); roa: the map to FILE.zarr (chunk by chunk, resumable) or FILE.nc", RUN, "-o") = None,
    plot: plot_option("the swing-up run or the region of attraction") = None,
    animate: option("--animate", T.OutPath((".mp4", ".gif")), "swingup: write the 3D animation to FILE.mp4 or FILE.gif", RUN) = None,
    resume: Annotated[bool, typer.Option("--resume", help="roa: " + RESUME.format("chunks"), rich_help_panel=RUN)] = False,
    quiet: QUIET = False,
    config: CONFIG = None,
):
    """Balance it and swing it up: LQR at any equilibrium (controllability, gain, closed-loop eigenvalues, region estimate), energy-shaping swing-up captured by the LQR, and the region of attraction on a grid of starts -- with skewed axes.

    From a --config run file it takes [parameters]; or a chain of links ([[links]], [chain]): lqr, swingup and roa
    with any set of actuated joints (--actuated 2, --actuated 1,3), --plane of its q1 .. qn, dq1 .. dqn.
    """
    import numpy as np

    from ..analysis.control import controllability, lqr, swingup

    if action is None:
        raise UsageError("control: give what to do, lqr, swingup, roa or leaderboard (e.g. skewpend control lqr "
                         "--actuated acrobot)")
    given = {"--robot": robot, "--robustness": robustness or None, "--version": version, "--controller": controller, "--target": target, "--actuated": actuated, "--q": q, "--r": r, "--t-end": t_end, "--energy-gain": energy_gain, "--elbow-gains": elbow_gains, "--out": out, "--plot": plot,
             "--animate": animate, "--n": n, "--plane": plane, "--window": window, "--rtol": rtol, "--atol": atol,
             "--resume": resume or None, "--workers": ensemble.get("workers"), "--scheduler": ensemble.get("scheduler")}
    used = [flag for flag, value in given.items() if value is not None and action.value not in ONLY[flag]]
    if used:
        goes = " or ".join(f"'control {a}'" for a in ONLY[used[0]])
        raise UsageError(f"{used[0]} goes with {goes}, not 'control {action.value}'")
    if controller is not None and controller.value not in LAWS[action.value]:
        raise UsageError(f"--controller: control {action.value} runs {' or '.join(LAWS[action.value])}, got "
                         f"{controller.value!r}")
    law = None if controller is None else controller.value
    if law == "mpc":
        for flag in ("--energy-gain", "--elbow-gains", "--q", "--r"):
            if given[flag] is not None:
                raise UsageError(f"{flag} is a setting of the energy-shaping swing-up and its LQR; --controller mpc "
                                 "has its own problem (skewpend.analysis.mpc.MPCSettings)")
    store = None
    if action is Action.leaderboard:
        from .leaderboard import check_model_options, run_leaderboard

        alpha = check_model_options(model, config)
        code = run_leaderboard(robot.value if robot is not None else None, alpha, umax, out, plot, quiet,
                               robustness=robustness, version="v2" if version is None else version.value,
                               controller=law)
        if code:
            raise typer.Exit(code)
        return None
    if action is Action.roa:
        if out is not None and not out.lower().endswith((".zarr", ".nc")):
            raise UsageError(f"--out: control roa writes FILE.zarr or FILE.nc, got {out!r}")
        store = ensemble_outputs(ensemble.get("workers"), ensemble.get("scheduler"), out, resume, plot)
    elif out is not None:
        from ..io import check_output_path

        check_output_path(out, (".csv", ".nc"), option="--out")
    check_plot(plot)
    from ..errors import EquilibriumError, ParameterError
    from ..numeric.control import actuated_joints

    run_file = resolve("control", config, parameters=model)
    params = run_file.parameters()  # a [motor]'s back-EMF in its joint's damping (Run.chain)
    nq = params.n
    if run_file.motor is not None:  # its joint actuated, its limit kt Vmax / R, unless the options say otherwise
        actuated, umax, said = run_file.motor.control_actuators(actuated, umax)
        sys.stderr.write(f"skewpend: note: {config}: {run_file.motor.control_note(said)}\n")
    actuated, umax = _file_actuators(config, actuated, umax, law, nq)
    actuated = actuated or "both"
    try:
        joints = len(actuated_joints(actuated, nq))
    except ParameterError as exc:  # a robot's name beside other than two links, or a joint past the last
        raise UsageError(f"--actuated: {exc}" if isinstance(actuated, str) else
                         f"--actuated: {params.title} has joints 1 to {nq}, got {','.join(map(str, actuated))}") from None
    shown = actuated if isinstance(actuated, str) else "joint" + ("s " if len(actuated) > 1 else " ") + ",".join(
        map(str, actuated))
    if q is not None and len(q) != 2 * nq:
        raise UsageError(f"--q: give {2 * nq} state weights, one per coordinate and speed, got {len(q)}")
    if r is not None and len(r) != joints:
        raise UsageError(f"--r: give {joints} weight(s), one per actuated joint ({shown}), got {len(r)}")
    if q is not None and any(x < 0 for x in q):
        raise UsageError("--q: state weights must not be negative")
    if r is not None and any(not x > 0 for x in r):
        raise UsageError("--r: input weights must be positive")
    Q = None if q is None else np.diag(q)
    R = None if r is None else np.diag(r)
    defaults = library_defaults(action)
    goal = _highest_rest(params, defaults["target"]) if target is None else target
    if target is not None:
        from ..analysis.control import equilibrium_argument
        from ..analysis.equilibria import find_equilibrium

        try:  # a word per link, or angles reduced modulo 2 pi (refused beyond 1e6 rad)
            goal = equilibrium_argument(goal, params, "target")
            find_equilibrium(params, goal, "target")
        except (EquilibriumError, ParameterError) as exc:
            raise UsageError(f"--target: {exc}") from None
    if action is Action.roa:
        return _roa(params, goal, actuated, Q, R, umax, t_end, n, plane, window, rtol, atol, out, store, plot, resume,
                    ensemble, quiet, shown)
    if action is Action.lqr:
        design = lqr(params, goal, actuated, Q=Q, R=R, **({} if umax is None else {"umax": umax}))
        lin = design.linearization
        c = controllability(lin.A, lin.B)
        names = params.coordinates
        lines = [
            f"target      {lin.equilibrium.label}: " + ", ".join(f"{x} = {math.degrees(v):.6g} deg"
                                                              for x, v in zip(names, lin.target)),
            f"actuated    {shown}; controllable (rank {c['rank']} of {2 * nq}, PBH distance {c['distance']:.3g})",
            f"gain K      u = -K (x - x*), x = ({', '.join(names)}, {', '.join(x + chr(39) for x in names)})",
        ]
        for row, j in enumerate(lin.joints):
            lines.append(f"  joint {j + 1}   " + "  ".join(f"{v:12.6g}" for v in design.K[row]))
        lines.append("closed loop " + ", ".join(f"{z.real:.6g}{z.imag:+.6g}i" if abs(z.imag) > 1e-12 else f"{z.real:.6g}"
                                                for z in design.eigenvalues) + " [1/s]")
        limit = "no torque limit" if not math.isfinite(design.umax[0]) else f"|u| <= {_limits(design.umax)} N m"
        if design.rho > 0:
            lines.append(f"region      dx' P dx < {design.rho:.6g} ({limit}; V decreases inside wherever a seeded search "
                         "looked: 0.95 of the smallest level where it found V' >= 0)")
        else:
            lines.append("region      none: P is singular (Q leaves modes unweighted), so dx' P dx bounds no region"
                         if np.linalg.eigvalsh(design.P)[0] <= 1e-12 * np.linalg.eigvalsh(design.P)[-1] else
                         f"region      none ({limit}): V' >= 0 arbitrarily close to the target")
        if lin.coulomb_note:  # how the linearisation treated Coulomb friction (left out by default)
            lines.append(lin.coulomb_note)
        sys.stdout.write("\n".join(lines) + "\n")
        return design
    if law == "mpc":
        from ..analysis.mpc import mpc_swingup

        kw = given_only(umax=umax, t_end=t_end)
        stage("building the model-predictive controller (its C function: compiled once, then cached)")
        with progress("simulating the swing-up by model-predictive control", "s", quiet) as bar:
            run = mpc_swingup(params, goal, actuated, progress=bar, **kw)
    else:
        kw = given_only(umax=umax, t_end=t_end, energy_gain=energy_gain, elbow_gains=elbow_gains)  # else the library's
        with progress("simulating the swing-up", "s", quiet) as bar:
            run = swingup(params, goal, actuated, Q=Q, R=R, progress=bar, **kw)
    tr = run.trajectory
    u = tr.inputs()
    lines = [
        f"swing-up    {shown} to {run.lqr.linearization.equilibrium.label}, |u| <= {_limits(run.controller.umax)} N m, "
        f"{tr.t[-1] if len(tr.t) else 0.0:g} s",
        f"result      {run.message}",
    ]
    if run.mpc is not None:
        from .leaderboard import mpc_line

        lines.append(mpc_line(run.mpc))
    if len(u):
        lines.append(f"largest |u| {np.abs(u).max():.4g} N m; energy balance |E - W - E0|/max|E| = {tr.energy_drift:.2g}")
    if out is not None:
        tr.to_netcdf(out) if str(out).lower().endswith(".nc") else _write_csv(tr, u, out, params.coordinates)
        lines.append(f"written     {out}")
    if plot is not None:
        stage(f"drawing {plot}")
        from ..views import figures

        figures.save_figure(figures.control_figure(run), plot)
        lines.append(f"plot        {plot}")
    if animate is not None:
        from ..views.animation import animate as render

        shown, fps = _frames(tr)
        with progress(f"rendering {animate}", "frames", quiet) as bar:
            render(shown, animate, fps=fps, progress=bar)
        lines.append(f"animation   {animate}")
    sys.stdout.write("\n".join(lines) + "\n")
    return run


def _highest_rest(params, goal):
    """The default target, every link up -- or, where the model has no such rest (a joint turning about the
    vertical, as the rotary pendulum's arm: its angle moves no weight), its highest rest, said in a note."""
    from ..analysis.control import equilibrium_argument
    from ..analysis.equilibria import equilibria

    label = equilibrium_argument(goal, params)
    points = equilibria(params).points
    if not points or any(point.label == label for point in points):
        return goal
    top = max(points, key=lambda point: point.potential)
    sys.stderr.write(f"skewpend: note: the model has no {label} rest (a joint's angle moves no weight: it turns about "
                     f"the vertical); the target is its highest rest, {top.label} (--target chooses another)\n")
    return top.label


def _file_actuators(config, actuated, umax, law, nq: int):
    """``--actuated`` and ``--umax`` as given, else a MuJoCo or URDF model file's actuators and their limits (said in
    one line): the joints it drives, each within its limit (one number when they agree; per joint otherwise -- the
    actuated joints' for the MPC, every joint's for the others, inf where none)."""
    from .options import model_actuators

    found = model_actuators(config)
    if found is None:
        return actuated, umax
    joints, limits = found
    said = []
    if actuated is None:
        actuated = joints
        said.append(f"--actuated {','.join(map(str, joints))}")
    if umax is None and tuple(actuated) == joints and all(u is not None for u in limits):
        if len(set(limits)) == 1:
            umax = limits[0]
        elif law == "mpc":
            umax = limits
        else:
            per = [math.inf] * nq
            for j, u in zip(joints, limits):
                per[j - 1] = u
            umax = tuple(per)
        said.append(f"--umax {','.join(f'{u:g}' for u in limits)}")
    if said:
        sys.stderr.write(f"skewpend: note: the model file's actuators: {' and '.join(said)}\n")
    return actuated, umax


def given_only(**options):
    """The options the user gave (not None): the others take the library function's defaults."""
    return {k: v for k, v in options.items() if v is not None}


def library_defaults(action: "Action") -> dict:
    """The defaults of the library function behind ``action`` (lqr, swingup, region_of_attraction),
    read from its signature: the one place they are written."""
    import inspect

    from ..analysis import control, roa

    fn = {"lqr": control.lqr, "swingup": control.swingup, "roa": roa.region_of_attraction}[Action(action).value]
    found = {k: p.default for k, p in inspect.signature(fn).parameters.items() if p.default is not inspect.Parameter.empty}
    found.setdefault("target", found.get("equilibrium"))
    return found


def _write_csv(tr, u, out, coordinates) -> None:
    import numpy as np

    from ..io import atomic_path, trajectory_columns

    header = trajectory_columns(coordinates)[:2 * len(coordinates) + 3] + tuple(f"u{j + 1}" for j in range(u.shape[1]))
    with atomic_path(out) as tmp:
        np.savetxt(tmp, np.column_stack([tr.t, tr.y, tr.energy, tr.work, u]), delimiter=",", header=",".join(header),
                   comments="")


def _limits(umax) -> str:
    """Torque limits for a line: one number when every joint has the same."""
    values = [u for u in umax if math.isfinite(u)]
    return f"{values[0]:g}" if len(set(values)) == 1 else ",".join(f"{u:g}" for u in umax)


def _roa(params, goal, actuated, Q, R, umax, t_end, n, plane, window, rtol, atol, out, store, plot, resume, ensemble,
         quiet, shown=None):
    from ..analysis.roa import region_of_attraction

    for name, (lo, hi) in zip(plane or params.coordinates[:2], window or ()):
        if not name.startswith("d") and (lo < -math.pi - 1e-12 or hi > math.pi + 1e-12):
            raise UsageError(f"--window ({name}): an angle's offsets from the target must lie within -180..180 deg, "
                             f"got {lo:.6g}:{hi:.6g} rad")
    kw = given_only(n=n, plane=plane, window=window, t_end=t_end, rtol=rtol, atol=atol, umax=umax)  # else the library's
    with progress(f"mapping the region of attraction ({kw.get('n', 64)} x {kw.get('n', 64)} starts)", "cells", quiet) as bar:
        roa = region_of_attraction(params, goal, actuated, Q=Q, R=R, progress=bar, store=store, resume=resume,
                                   **{k: v for k, v in ensemble.items() if v is not None}, **kw)
    if out is not None and store is None:
        roa.to_netcdf(out)
    draw_figure(plot, "roa_figure", roa)
    st, se = roa.stats, roa.settings
    a, b = roa.plane
    lines = [
        f"target      {', '.join(f'{math.degrees(v):.6g} deg' for v in roa.target[:len(roa.target) // 2])} "
        f"({shown or actuated}, |u| <= {_limits([math.inf if u is None else u for u in se['umax']])} N m)",
        f"grid        {roa.n} x {roa.n} starts over {a} x {b} about the target, followed up to {se['t_end']:g} s",
        f"captured    {st['captured']} of {st['cells']} ({100 * roa.captured_fraction:.1f} %); inside the LQR estimate "
        f"dx' P dx < {roa.rho:.4g} at the start: {100 * roa.inner_fraction:.2f} %",
        f"work        {st['steps']} steps; {st.get('wall_time', float('nan')):.3g} s on {st.get('workers', '?')} workers",
    ]
    if store is not None:
        lines.append(f"store       {st['chunks_computed']} chunks computed now, {st.get('chunks_resumed', 0)} already done")
    if st.get("failed"):
        lines.append(f"failed      {st['failed']} cells (left NaN: chattering where the wrapped feedback jumps)")
    lines += [f"{what:12s}{path}" for what, path in (("written", out), ("plot", plot)) if path is not None]
    sys.stdout.write("\n".join(lines) + "\n")
    return roa


#: Frames per second of ``--animate`` at most: the run's rows come every 0.01 s (100 per second), which
#: a GIF cannot show (browsers draw delays under 2/100 s as 1/10 s: ten times too slow) and which would
#: render four times the frames a viewer sees.
ANIMATION_FPS = 25.0


def _frames(tr):
    """``(trajectory, fps)`` for :func:`skewpend.views.animation.animate`: every k-th row, k the
    smallest whole number that brings the rows' rate to at most :data:`ANIMATION_FPS` per second."""
    import dataclasses

    if len(tr.t) < 2:
        return tr, ANIMATION_FPS
    dt = float(tr.t[1] - tr.t[0])
    k = max(1, math.ceil(1.0 / (dt * ANIMATION_FPS) - 1e-9))
    if k > 1:
        tr = dataclasses.replace(tr, t=tr.t[::k], y=tr.y[::k], energy=tr.energy[::k], work=tr.work[::k])
    return tr, 1.0 / (k * dt)

