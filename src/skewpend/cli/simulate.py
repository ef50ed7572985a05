"""``simulate`` (a summary, a trajectory file, a figure), ``animate`` (a video) and ``report``
(one HTML page): one run of the nonlinear equations each."""

from __future__ import annotations

import sys
from typing import Annotated

import typer

from ..parsing import UsageError
from . import types as T
from .options import CONFIG, INITIAL, INTEGRATION, MODEL, QUIET, RUN, command, option, progress, resolve

COMMANDS = ("simulate", "animate", "report")

_SECONDS = T.Positive("number of seconds")


def _run(name: str, config, model, initial, integration, **simulation):
    """The resolved run of ``name``: parameters, initial state, the integrator settings (simulate's
    default method is ``auto``, the library's: the fastest that serves the run)."""
    run = resolve(name, config, parameters=model, initial=initial, simulation={**integration, **simulation})
    methods = None
    if name == "simulate":
        from ..numeric.simulation import AUTO, METHODS

        methods = (AUTO,) + METHODS
    return run, run.parameters(), run.initial_state(), run.integration(methods)


@command(MODEL, INITIAL, INTEGRATION)
def simulate(
    model: dict,
    initial: dict,
    integration: dict,
    t_end: option("--t-end", _SECONDS, "duration [s] (default 20)") = None,
    dt_out: option("--dt-out", _SECONDS, "with --out: output interval [s] (default: the integrator's own steps)") = None,
    out: option("--out", T.OutPath((".csv", ".nc"), check=False), "stream the trajectory to FILE (.csv or .nc)", RUN, "-o") = None,
    plot: option("--plot", T.OutPath("..views.figures:FIGURE_SUFFIXES", check=False), "draw the run to FILE (.png, .svg or .pdf): angles, speeds, energy error, phase portraits, torus, 3D rod ends") = None,
    quiet: QUIET = False,
    config: CONFIG = None,
):
    """Simulate the nonlinear equations of motion; print a summary, or stream the trajectory to a file.

    Exit status: 0 done, 1 the run stopped early (what it computed is written), 2 bad input,
    130 interrupted, 143 terminated (nothing written).
    """
    from ..io import TRAJECTORY_SUFFIXES, check_output_path

    run, params, y0, settings = _run("simulate", config, model, initial, integration, t_end=t_end, dt_out=dt_out,
                                     out=out, plot=plot)
    out_path, plot_path = run.path("out"), run.path("plot")
    if out_path is None and plot_path is None and run.is_given("simulation", "dt_out"):
        raise UsageError(f"{run.option('simulation', 'dt_out')} sets the rows written to --out or drawn by --plot; give --out FILE.csv|.nc or --plot FILE.png too")
    if out_path is not None:
        check_output_path(out_path, TRAJECTORY_SUFFIXES, option=run.option("simulation", "out"))
    check_plot(plot_path, run.option("simulation", "plot"))
    from ..numeric.simulation import simulate as run_simulation

    with progress("simulating", "s", quiet) as bar:
        traj = run_simulation(params, y0, run.number("t_end"), dt_out=run.number("dt_out"), out=out_path,
                              keep=plot_path is not None, progress=bar, **settings)
    sys.stdout.write(summary(traj, out_path))
    if plot_path is not None:  # also for a run that stopped early: its heading says why
        from ..views.figures import save_figure, simulation_figure

        save_figure(simulation_figure(traj), plot_path)
        sys.stdout.write(f"plot          {plot_path}\n")
    written = f"; wrote the {traj.stats['rows']} rows computed to {out_path}" if out_path else ""
    return traj, f" at t = {traj.t[-1]:.6g} s{written}"


def check_plot(plot, option: str = "--plot") -> None:
    """A figure's output path, checked before any work (``option`` names it in the message)."""
    if plot is not None:
        from ..io import check_output_path
        from ..views.figures import FIGURE_SUFFIXES

        check_output_path(plot, FIGURE_SUFFIXES, option=option)


def _state_names(model):
    """The state's names: ``phi, psi, dphi, dpsi``, or a chain's ``q1 ... qn, dq1 ... dqn``."""
    names = getattr(model, "coordinates", ("phi", "psi"))
    return list(names) + [f"d{c}" for c in names]


def summary(traj, out_path) -> str:
    y, st = traj.final_state, traj.stats
    kernel = "loaded from the cache"
    if st.get("kernel") == "compiled":
        kept = "first use; cached for later runs" if _cache_writable() else "not cached: the kernel cache is not writable"
        by = f" by {st['compiler']}" if st.get("compiler") else ""
        kernel = f"compiled for this model{by} in {st['kernel_build_time']:.2f} s ({kept})"
    lines = [
        f"method        {traj.method}  ({', '.join(f'{k}={v:g}' for k, v in traj.settings.items() if isinstance(v, float) and k != 't_end')})"
        + (f"; the default (no --method) chose it: {traj.settings['method_choice'].split(': ', 1)[-1]}"
           if traj.settings.get("method_choice") else ""),
        f"status        {traj.message}",
        f"final state   t={traj.t[-1]:.6g} s  " + "  ".join(
            f"{name}={value:.12g}" for name, value in zip(_state_names(traj.params), y)),
        f"energy        E0={traj.energy[0]:.12g} J  E={traj.energy[-1]:.12g} J  work of Q={traj.work[-1]:.6g} J",
        f"energy drift  {traj.energy_drift:.3e} (max |E - W - E0| / max |E|)",
        f"steps         {st['steps']} accepted, {st['rejected']} rejected, {st['nfev']} evaluations"
        + (f" (order {st['order']}, step factor e^-{st['step_exponent']:g})" if "order" in st else ""),
        f"wall time     {st['wall_time'] * 1e3:.2f} ms (compiled integration)",
        f"kernel        {kernel}",
    ]
    if out_path is not None:
        from ..io import csv_metadata_path

        beside = f"; how it was made in {csv_metadata_path(out_path).name}" if str(out_path).lower().endswith(".csv") else ""
        lines.append(f"written       {out_path} ({st['rows']} rows{beside})")
    return "\n".join(lines) + "\n"


def _cache_writable() -> bool:
    """Whether compiled kernels are kept for later runs (else a temporary directory held them)."""
    import os

    from ..numeric.kernels import cache_dir

    directory = cache_dir() / "kernels"
    return directory.is_dir() and os.access(directory, os.W_OK)


#: The most frames an animation may have (a 30 fps video of ~30 minutes).
MAX_FRAMES = 54_000


@command(MODEL, INITIAL, INTEGRATION)
def animate(
    model: dict,
    initial: dict,
    integration: dict,
    out: option("--out", T.OutPath("..views.animation:SUFFIXES"), "the video: FILE.mp4 (H.264) or FILE.gif (required)", RUN, "-o") = None,
    t_end: option("--t-end", _SECONDS, "seconds of motion (default 20); the video lasts t_end/speed") = None,
    fps: option("--fps", T.Positive(at_most=240), "frames per second of the video (default 30, at most 240)") = None,
    speed: option("--speed", T.Positive(at_most=1e6), "seconds of motion per second of video (default 1; 0.5 = slow motion)") = None,
    trail: option("--trail", T.NonNegative("number of seconds", at_most=1e6), "seconds of motion the fading trail of rod 2's tip covers (default 2; 0 = none)") = None,
    size: option("--size", T.Size(), "frame size WIDTHxHEIGHT in pixels (default 640x480; even for MP4)") = None,
    quiet: QUIET = False,
    config: CONFIG = None,
):
    """Simulate and write a 3D animation (MP4 or GIF): solid rods, both hinge axes, the tip's trail,
    a readout of time, angles and energy; one frame per row at the exact frame times k*speed/fps.

    Exit status: 0 done, 1 the run stopped early (the frames computed are written), 2 bad input,
    130 interrupted, 143 terminated (nothing written).
    """
    run, params, y0, settings = _run("animate", config, model, initial, integration, t_end=t_end)
    from ..views.animation import check_output

    if out is None:
        raise UsageError("--out: give the video file, FILE.mp4 or FILE.gif")
    fps_v, speed_v, horizon = fps or 30.0, speed or 1.0, run.number("t_end")
    frames = horizon / speed_v * fps_v
    if frames > MAX_FRAMES:
        raise UsageError(f"--t-end {horizon:g} s at --fps {fps_v:g} and --speed {speed_v:g} makes {frames:.3g} frames; "
                         f"an animation has at most {MAX_FRAMES} (raise --speed, or lower --t-end or --fps)")
    check_output(out)  # suffix, directory: refused before any work
    from ..numeric.simulation import simulate as run_simulation
    from ..views.animation import animate as write_animation

    with progress("simulating", "s", quiet) as bar:
        traj = run_simulation(params, y0, horizon, dt_out=speed_v / fps_v, progress=bar, **settings)
    looks = {k: v for k, v in dict(trail=trail, size=size).items() if v is not None}
    with progress("rendering", "frames", quiet) as bar:
        write_animation(traj, out, fps=fps_v, speed=speed_v, progress=bar, **looks)
    n = traj.t.size
    sys.stdout.write(f"wrote {out}: {n} frames, {n / fps_v:.2f} s at {fps_v:g} fps, {traj.t[-1]:.6g} s of motion ({speed_v:g}x)\n")
    return traj, f" at t = {traj.t[-1]:.6g} s; animated the frames computed"


@command(MODEL, INITIAL, INTEGRATION)
def report(
    model: dict,
    initial: dict,
    integration: dict,
    t_end: option("--t-end", _SECONDS, "simulated time [s] (default 20, at most 1000)") = None,
    out: Annotated[str, typer.Option("--out", "-o", help="the HTML file to write (default report.html)")] = "report.html",
    quiet: QUIET = False,
    config: CONFIG = None,
) -> None:
    """Write one self-contained HTML report (opens offline): the system, the derivation step by step,
    the check against the specification at alpha = 0, normal modes against alpha, a simulation with
    figures and an animation, the comparison with MuJoCo (when installed), how it was made.

    From a --config run file it takes [parameters], [initial] and the integrator settings of
    [simulation] (t_end, method, rtol, atol, dt, max_steps); or a chain of links ([[links]], [chain],
    [initial] q0, dq0, or --links N): the same sections, each asking the model (the equations displayed
    up to 3 links and checked against the compiled code; modes against each hinge's tilt; the flip map
    over q1, q2; equilibria, Lyapunov exponents and nonlinear normal modes).
    """
    import shlex
    import time

    from ..io import check_output_path
    from ..views.report import MAX_T_END, REPORT_SUFFIXES, build_report

    started = time.perf_counter()
    run, params, y0, settings = _run("report", config, model, initial, integration, t_end=t_end)
    horizon = run.number("t_end")
    if horizon > MAX_T_END:
        raise UsageError(f"{run.option('simulation', 't_end')}: a report draws at most {MAX_T_END:g} s of motion, got {horizon:g}; "
                         "use skewpend simulate --out for long runs")
    check_output_path(out, REPORT_SUFFIXES, option="--out")
    with progress("writing the report", "parts", quiet) as bar:
        path = build_report(params, y0=y0, t_end=horizon, out=out, progress=bar,
                            command="skewpend " + " ".join(shlex.quote(a) for a in sys.argv[1:]), **settings)
    sys.stdout.write(f"wrote {path.resolve()} ({path.stat().st_size / 1e6:.1f} MB) in {time.perf_counter() - started:.1f} s\n")
