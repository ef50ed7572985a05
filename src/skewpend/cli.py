"""The ``skewpend`` command line: thin wrappers over the library.

Heavy modules (SymPy, NumPy) are imported inside the commands so that
``skewpend --help`` is instant.  A user's mistake is reported as one line on
stderr with exit status 2.
"""

from __future__ import annotations

import os
import re
import sys
from enum import Enum
from typing import Annotated, Dict, List, Optional

import typer

from .errors import SkewpendError

app = typer.Typer(
    name="skewpend",
    help="The double pendulum with skewed hinge axes: a self-contained HTML report (skewpend report), the equations of motion, simulation, animation, flip-time maps, normal modes, validation against MuJoCo.",
    add_completion=False,
    no_args_is_help=True,
    pretty_exceptions_enable=False,
    rich_markup_mode=None,
)


def _version(value: bool) -> None:
    if value:
        from . import __version__

        sys.stdout.write(f"skewpend {__version__}\n")
        raise typer.Exit()


@app.callback()
def _root(
    version: Annotated[
        bool, typer.Option("--version", callback=_version, is_eager=True, help="show the version and exit")
    ] = False,
) -> None:
    """The double pendulum with skewed hinge axes (see the README for the model)."""


from .parsing import UsageError, parse_inertia, parse_scalar, parse_vector  # noqa: E402


# -- shared options -----------------------------------------------------------------------------------
_P = "Model parameters (a number, or 'sym' for symbolic; default symbolic)"
_G = "General bodies and axes (default: the specification's thin rods)"
A = Annotated[Optional[str], typer.Option("--a", help="length of rod 1 [m]", rich_help_panel=_P)]
B = Annotated[Optional[str], typer.Option("--b", help="length of rod 2 [m]", rich_help_panel=_P)]
M1 = Annotated[Optional[str], typer.Option("--m1", help="mass of rod 1 [kg]", rich_help_panel=_P)]
M2 = Annotated[Optional[str], typer.Option("--m2", help="mass of rod 2 [kg]", rich_help_panel=_P)]
ALPHA = Annotated[Optional[str], typer.Option("--alpha", help="skew angle of the hinges [rad, or e.g. 30deg]", rich_help_panel=_P)]
GRAV = Annotated[Optional[str], typer.Option("--g", help="gravitational acceleration [m/s^2]", rich_help_panel=_P)]
COM1 = Annotated[Optional[str], typer.Option("--com1", help="centre of mass of body 1, 'x,y,z' in its frame [m]", rich_help_panel=_G)]
COM2 = Annotated[Optional[str], typer.Option("--com2", help="centre of mass of body 2, 'x,y,z' in its frame [m]", rich_help_panel=_G)]
IN1 = Annotated[Optional[str], typer.Option("--inertia1", help="inertia of body 1 about its centre of mass: 'Ixx,Iyy,Izz[,Ixy,Ixz,Iyz]' [kg m^2]", rich_help_panel=_G)]
IN2 = Annotated[Optional[str], typer.Option("--inertia2", help="inertia of body 2 about its centre of mass: 'Ixx,Iyy,Izz[,Ixy,Ixz,Iyz]' [kg m^2]", rich_help_panel=_G)]
AX1 = Annotated[Optional[str], typer.Option("--axis1", help="axis of hinge 1, 'x,y,z' (default k)", rich_help_panel=_G)]
AX2 = Annotated[Optional[str], typer.Option("--axis2", help="axis of hinge 2 with the rods vertical, 'x,y,z' (default cos(alpha) k + sin(alpha) i; replaces --alpha)", rich_help_panel=_G)]


def build_parameters(a, b, m1, m2, alpha, g, c1, c2, tau1, tau2, com1, com2, inertia1, inertia2, axis1, axis2):
    """Parameters from command-line strings (validated; errors are SkewpendError)."""
    from .symbolic.model import Parameters

    return Parameters(
        a=parse_scalar(a, "--a"),
        b=parse_scalar(b, "--b"),
        m1=parse_scalar(m1, "--m1"),
        m2=parse_scalar(m2, "--m2"),
        alpha=parse_scalar(alpha, "--alpha", angle=True),
        g=parse_scalar(g, "--g"),
        c1=parse_scalar(c1, "--c1"),
        c2=parse_scalar(c2, "--c2"),
        tau1=parse_scalar(tau1, "--tau1"),
        tau2=parse_scalar(tau2, "--tau2"),
        com1=parse_vector(com1, "--com1"),
        com2=parse_vector(com2, "--com2"),
        inertia1=parse_inertia(inertia1, "--inertia1"),
        inertia2=parse_inertia(inertia2, "--inertia2"),
        axis1=parse_vector(axis1, "--axis1"),
        axis2=parse_vector(axis2, "--axis2"),
    )


_R = "Initial state and run"


C1R = Annotated[Optional[str], typer.Option("--c1", help="viscous damping in hinge 1 [N m s] (default 0)", rich_help_panel=_P)]
C2R = Annotated[Optional[str], typer.Option("--c2", help="viscous damping in hinge 2 [N m s] (default 0)", rich_help_panel=_P)]
TAU1R = Annotated[Optional[str], typer.Option("--tau1", help="constant torque in hinge 1 [N m] (default 0)", rich_help_panel=_P)]
TAU2R = Annotated[Optional[str], typer.Option("--tau2", help="constant torque in hinge 2 [N m] (default 0)", rich_help_panel=_P)]
PHI0 = Annotated[Optional[str], typer.Option("--phi0", help="initial phi [rad, or e.g. 60deg] (default 1.2)", rich_help_panel=_R)]
PSI0 = Annotated[Optional[str], typer.Option("--psi0", help="initial psi [rad, or deg] (default -0.8)", rich_help_panel=_R)]
DPHI0 = Annotated[Optional[str], typer.Option("--dphi0", help="initial dphi/dt [rad/s] (default 0)", rich_help_panel=_R)]
DPSI0 = Annotated[Optional[str], typer.Option("--dpsi0", help="initial dpsi/dt [rad/s] (default 0)", rich_help_panel=_R)]
CONFIG = Annotated[Optional[str], typer.Option("--config", help="TOML file with [parameters], [initial], [simulation]; options override it", rich_help_panel=_R)]


#: Model options shared by every command (name -> annotated type); default None.
MODEL_OPTIONS = {
    "a": A, "b": B, "m1": M1, "m2": M2, "alpha": ALPHA, "g": GRAV,
    "c1": C1R, "c2": C2R, "tau1": TAU1R, "tau2": TAU2R,
    "com1": COM1, "com2": COM2, "inertia1": IN1, "inertia2": IN2, "axis1": AX1, "axis2": AX2,
}
#: Initial-state options of simulate and validate.
INITIAL_OPTIONS = {"phi0": PHI0, "psi0": PSI0, "dphi0": DPHI0, "dpsi0": DPSI0}


def _options(*groups: dict):
    """Give a command the shared options of ``groups`` (declared once, above); the command
    receives them collected in its ``model`` (and ``initial``) argument, by name."""
    import functools
    import inspect

    def decorate(func):
        sig = inspect.signature(func, eval_str=True)
        own = [p for name, p in sig.parameters.items() if name not in ("model", "initial")]
        extra = [
            inspect.Parameter(name, inspect.Parameter.POSITIONAL_OR_KEYWORD, default=None, annotation=ann)
            for group in groups
            for name, ann in group.items()
        ]
        targets = [("model", set(groups[0]))] + ([("initial", set(groups[1]))] if len(groups) > 1 else [])

        @functools.wraps(func)
        def command(**kwargs):
            collected = {target: {k: kwargs.pop(k) for k in names if k in kwargs} for target, names in targets}
            return func(**collected, **kwargs)

        command.__signature__ = sig.replace(parameters=extra + own)
        return command

    return decorate


class DeriveFormat(str, Enum):
    text = "text"
    latex = "latex"
    json = "json"
    python = "python"
    c = "c"
    javascript = "javascript"


@app.command()
@_options(MODEL_OPTIONS)
def derive(
    model: dict,
    linear: Annotated[bool, typer.Option("--linear", help="add the equations linearised about phi = psi = 0")] = False,
    steps: Annotated[bool, typer.Option("--steps", help="print the derivation step by step (P1, e, P, omega2, v_c, Theta2, T, Pi)")] = False,
    fmt: Annotated[DeriveFormat, typer.Option("--format", "-f", help="output format: equations (text, latex, json) or generated code (python, c, javascript)")] = DeriveFormat.text,
) -> None:
    """Derive the equations of motion M(q) q'' = f(q, q') by the specification's method."""
    zero = {k: "0" for k in ("c1", "c2", "tau1", "tau2") if model.get(k) is None}
    params = build_parameters(**{**model, **zero})
    if fmt in (DeriveFormat.python, DeriveFormat.c, DeriveFormat.javascript):
        from .numeric.codegen import generate

        if linear or steps:
            raise UsageError("--linear and --steps go with --format text|latex|json, not with generated code")
        # numeric values become the code's default parameter vector P, all of them or none
        # (generate refuses a partial set); a typed --c1/--c2/--tau1/--tau2 needs that vector
        typed = [f"--{k}" for k in ("c1", "c2", "tau1", "tau2") if model.get(k) is not None and getattr(params, k) is not None]
        core = [f"--{k}" for k in ("a", "b", "m1", "m2", "alpha", "g") if k != "alpha" or params.uses_alpha]
        if typed and all(getattr(params, k[2:]) is None for k in core):
            raise UsageError(
                f"{', '.join(typed)} with --format {fmt.value} needs {' '.join(core)} as numbers too (all become the "
                f"code's default parameter vector P); give them, or leave out {', '.join(typed)} (p is supplied at run time)"
            )
        sys.stdout.write(generate(params, fmt.value))
        return
    from .symbolic.derivation import derive as derive_eom
    from .symbolic import render

    eom = derive_eom(params)
    lin = eom.linearize() if linear else None
    if fmt is DeriveFormat.json:
        import json

        text = json.dumps(render.to_json(eom, linear=lin, steps=steps), indent=2) + "\n"
    elif fmt is DeriveFormat.latex:
        text = render.to_latex(eom, linear=lin, steps=steps)
    else:
        text = render.to_text(eom, linear=lin, steps=steps)
    sys.stdout.write(text)


# -- simulate -------------------------------------------------------------------------------------------
#: The run ``skewpend simulate`` does with no options (the benchmark case of the README).
DEFAULT_RUN = {
    "parameters": {"a": 1.0, "b": 0.8, "m1": 1.0, "m2": 0.7, "alpha": 0.6, "g": 9.81},
    "initial": {"phi0": 1.2, "psi0": -0.8, "dphi0": 0.0, "dpsi0": 0.0},
    "simulation": {"t_end": 20.0, "method": "dop853"},
}


def _as_text(value, where: str = "value") -> Optional[str]:
    """A config value in the command line's spelling (numbers, '30deg', vectors, matrices)."""
    if value is None:
        return None
    if isinstance(value, bool):
        raise UsageError(f"{where}: expected a number, got {str(value).lower()}")
    if isinstance(value, (list, tuple)):
        flat = []
        for v in value:
            flat.extend(v if isinstance(v, (list, tuple)) else [v])
        if any(isinstance(x, (bool, list, tuple, dict)) for x in flat):
            raise UsageError(f"{where}: expected numbers or symbol names, got {value!r}")
        return ",".join(repr(float(x)) if isinstance(x, (int, float)) else str(x) for x in flat)
    if isinstance(value, dict):
        raise UsageError(f"{where}: expected a number, got a table")
    return value if isinstance(value, str) else repr(value)


class Method(str, Enum):
    dop853 = "dop853"
    rk4 = "rk4"
    gauss = "gauss"




class _Run:
    """Resolved settings: built-in defaults, then the config file, then command-line options.

    Every value remembers where it came from, so a message names the option (``--a``) or
    the file and key (``run.toml: [parameters] a``) that the user typed.
    """

    def __init__(self, config: Optional[str], sections: Dict[str, dict], defaults: bool = True):
        from .io import read_config

        self.values: Dict[str, Dict[str, object]] = {k: {} for k in DEFAULT_RUN}
        self.where: Dict[str, Dict[str, str]] = {k: {} for k in DEFAULT_RUN}
        self.given: Dict[str, set] = {k: set() for k in DEFAULT_RUN}
        if defaults:
            for section, values in DEFAULT_RUN.items():
                for k, v in values.items():
                    self._set(section, k, v, f"default {k}", given=False)
        if config is not None:
            for section, values in read_config(config).items():
                for k, v in values.items():
                    self._set(section, k, v, f"{config}: [{section}] {k}")
        for section, values in sections.items():
            for k, v in values.items():
                if v is not None:
                    self._set(section, k, v, "--" + k.replace("_", "-"))
        P = self.values["parameters"]
        if "axis2" in P and "alpha" in P and "alpha" not in self.given["parameters"]:
            del P["alpha"]  # the built-in alpha gives way to a user's axis2

    def _set(self, section, key, value, where, given=True):
        self.values[section][key] = value
        self.where[section][key] = where
        if given:
            self.given[section].add(key)

    def text(self, section: str, key: str) -> Optional[str]:
        return _as_text(self.values[section].get(key), self.where[section].get(key, key))

    def scalar(self, section: str, key: str, *, angle: bool = False) -> Optional[float]:
        return parse_scalar(self.text(section, key), self.where[section].get(key, key), angle=angle)

    def is_given(self, section: str, key: str) -> bool:
        return key in self.given[section]

    def option(self, section: str, key: str) -> str:
        return self.where[section].get(key, "--" + key.replace("_", "-"))

    def parameters(self):
        P = self.values["parameters"]
        w = self.where["parameters"]
        t = {k: self.text("parameters", k) for k in P}
        return _build(t, w)

    def initial_state(self):
        from .parsing import MAX_ANGLE

        y0 = []
        for k in ("phi0", "psi0", "dphi0", "dpsi0"):
            value = self.scalar("initial", k, angle=k in ("phi0", "psi0"))
            if value is None:
                raise UsageError(f"{self.option('initial', k)}: the initial state must be numeric, not 'sym'")
            if k in ("phi0", "psi0") and abs(value) > MAX_ANGLE:
                raise UsageError(f"{self.option('initial', k)}: expected an angle of at most {MAX_ANGLE:g} rad in magnitude, got {value:g}")
            y0.append(value)
        return y0


def _build(t: dict, where: dict):
    """Parameters from spelled values, each parsed with the name the user knows it by."""
    from .symbolic.model import Parameters

    def w(k):
        return where.get(k, "--" + k)

    scalars = {k: parse_scalar(t.get(k), w(k), angle=(k == "alpha")) for k in ("a", "b", "m1", "m2", "alpha", "g")}
    for k in ("c1", "c2", "tau1", "tau2"):
        scalars[k] = parse_scalar(t.get(k, "0") or "0", w(k))
    geometry = {k: parse_vector(t.get(k), w(k)) for k in ("com1", "com2", "axis1", "axis2")}
    geometry.update({k: parse_inertia(t.get(k), w(k)) for k in ("inertia1", "inertia2")})
    return Parameters(**scalars, **geometry)


def _resolve(config: Optional[str], parameters: dict, initial: dict, simulation: dict):
    """Numeric parameters, initial state and the resolved run (see :class:`_Run`)."""
    run = _Run(config, {"parameters": parameters, "initial": initial, "simulation": simulation})
    return run.parameters(), run.initial_state(), run


def _positive(text: str, where: str) -> float:
    """A positive finite number typed by the user ('sym' is not a run setting)."""
    value = parse_scalar(text, where)
    if value is None or not value > 0:
        raise UsageError(f"{where}: expected a positive number, got {text!r}")
    return value


def _setting(run: "_Run", key: str) -> Optional[float]:
    """A run setting (t_end, dt, dt_out, rtol, atol): None when not set, else a positive number."""
    if run.values["simulation"].get(key) is None:
        return None
    return _positive(run.text("simulation", key), run.option("simulation", key))


def _positive_setting(run: "_Run", key: str) -> float:
    value = _setting(run, key)
    if value is None:  # pragma: no cover - callers check is_given
        raise UsageError(f"{run.option('simulation', key)}: expected a positive number")
    return value


#: Largest step cap (the compiled integrators count steps in 64-bit integers).
_MAX_STEP_CAP = 10**15


def _integration(run: "_Run"):
    """The method and step cap of a run; a tolerance or step that does not apply is refused."""
    from .numeric.simulation import MAX_STEPS, METHODS

    method_name = run.values["simulation"].get("method", "dop853")
    if not isinstance(method_name, str) or method_name not in METHODS:
        raise UsageError(f"{run.option('simulation', 'method')}: expected one of {', '.join(METHODS)}, got {method_name!r}")
    for key in ("rtol", "atol"):
        if method_name != "dop853" and run.is_given("simulation", key):
            raise UsageError(f"{run.option('simulation', key)} is a tolerance of dop853; {method_name} takes fixed steps (set --dt)")
    if method_name == "dop853" and run.is_given("simulation", "dt"):
        raise UsageError(f"{run.option('simulation', 'dt')} is the step of rk4 and gauss; dop853 chooses its own steps (set --rtol/--atol)")
    steps = _step_cap(run) if run.is_given("simulation", "max_steps") else MAX_STEPS
    return method_name, steps


def _step_cap(run: "_Run") -> int:
    where = run.option("simulation", "max_steps")
    text = run.text("simulation", "max_steps")
    try:
        value = float(text)
    except (TypeError, ValueError):
        value = float("nan")
    if not (1 <= value <= _MAX_STEP_CAP and value == int(value)):
        raise UsageError(f"{where}: expected a positive whole number of at most {_MAX_STEP_CAP:.0e}, got {text!r}")
    return int(value)


QUIET = Annotated[bool, typer.Option("--quiet", "-q", help="no progress bar (it is shown on a terminal for work over ~1 s)", rich_help_panel=_R)]
# integration settings shared by simulate, animate and report (declared once)
METHOD = Annotated[Optional[Method], typer.Option("--method", help="integrator (default dop853)", rich_help_panel=_R)]
RTOL = Annotated[Optional[str], typer.Option("--rtol", help="relative tolerance, dop853 only (default 1e-10)", rich_help_panel=_R)]
ATOL = Annotated[Optional[str], typer.Option("--atol", help="absolute tolerance, dop853 only (default 1e-10)", rich_help_panel=_R)]
DT = Annotated[Optional[str], typer.Option("--dt", help="step [s], rk4 and gauss only (default 1e-3)", rich_help_panel=_R)]
MAX_STEPS_OPT = Annotated[Optional[str], typer.Option("--max-steps", help="refuse or stop a run that needs more steps (default 1e8)", rich_help_panel=_R)]
# ensemble settings shared by flipmap and chaos-diagram (declared once)
WORKERS = Annotated[Optional[str], typer.Option("--workers", help="threads on this machine (default: every core)", rich_help_panel=_R)]
SCHEDULER = Annotated[Optional[str], typer.Option("--scheduler", help="run on a dask.distributed cluster: tcp://HOST:PORT (needs skewpend[cluster])", rich_help_panel=_R)]


@app.command()
@_options(MODEL_OPTIONS, INITIAL_OPTIONS)
def simulate(
    model: dict,
    initial: dict,
    t_end: Annotated[Optional[str], typer.Option("--t-end", help="duration [s] (default 20)", rich_help_panel=_R)] = None,
    dt_out: Annotated[Optional[str], typer.Option("--dt-out", help="with --out: output interval [s] (default: the integrator's own steps)", rich_help_panel=_R)] = None,
    method: METHOD = None,
    rtol: RTOL = None,
    atol: ATOL = None,
    dt: DT = None,
    max_steps: MAX_STEPS_OPT = None,
    out: Annotated[Optional[str], typer.Option("--out", "-o", help="stream the trajectory to FILE (.csv or .nc)", rich_help_panel=_R)] = None,
    plot: Annotated[Optional[str], typer.Option("--plot", help="draw the run to FILE (.png, .svg or .pdf): angles, speeds, energy error, phase portraits, torus, 3D rod ends", rich_help_panel=_R)] = None,
    quiet: QUIET = False,
    config: CONFIG = None,
) -> None:
    """Simulate the nonlinear equations of motion; print a summary, or stream the trajectory to a file.

    Exit status: 0 done, 1 the run stopped early (what it computed is written), 2 bad input,
    130 interrupted (nothing written).
    """
    params, y0, run = _resolve(
        config, model, initial,
        dict(t_end=t_end, dt_out=dt_out, method=method.value if method else None, rtol=rtol, atol=atol, dt=dt,
             max_steps=max_steps, out=out, plot=plot),
    )
    S = run.values["simulation"]
    method_name, steps = _integration(run)
    out_path = S.get("out")
    if out_path is not None and not isinstance(out_path, str):
        raise UsageError(f"{run.option('simulation', 'out')}: expected a file name, got {out_path!r}")
    plot_path = S.get("plot")
    if plot_path is not None and not isinstance(plot_path, str):
        raise UsageError(f"{run.option('simulation', 'plot')}: expected a file name, got {plot_path!r}")
    if out_path is None and plot_path is None and run.is_given("simulation", "dt_out"):
        raise UsageError(f"{run.option('simulation', 'dt_out')} sets the rows written to --out or drawn by --plot; give --out FILE.csv|.nc or --plot FILE.png too")
    if out_path is not None:
        from .io import TRAJECTORY_SUFFIXES, check_output_path

        check_output_path(out_path, TRAJECTORY_SUFFIXES, option=run.option("simulation", "out"))
    _check_plot(plot_path, run.option("simulation", "plot"))
    from .numeric.simulation import simulate as run_simulation
    from .progress import ProgressBar

    with ProgressBar("simulating", unit="s", enabled=None if not quiet else False) as bar:
        traj = run_simulation(
            params, y0, _setting(run, "t_end"),
            dt_out=_setting(run, "dt_out"), method=method_name,
            rtol=_setting(run, "rtol"), atol=_setting(run, "atol"), dt=_setting(run, "dt"),
            max_steps=steps, out=out_path, keep=plot_path is not None, progress=bar,
        )
    _summary(traj, out_path)
    if plot_path is not None:  # also for a run that stopped early: its heading says why
        from .views.figures import save_figure, simulation_figure

        save_figure(simulation_figure(traj), plot_path)
        sys.stdout.write(f"plot          {plot_path}\n")
    if not traj.success:
        written = f"; wrote the {traj.stats['rows']} rows computed to {out_path}" if out_path else ""
        sys.stderr.write(f"skewpend: simulation {traj.message} at t = {traj.t[-1]:.6g} s{written}\n")
        sys.exit(1)


@app.command()
@_options(MODEL_OPTIONS, INITIAL_OPTIONS)
def animate(
    model: dict,
    initial: dict,
    out: Annotated[Optional[str], typer.Option("--out", "-o", help="the video: FILE.mp4 (H.264) or FILE.gif (required)", rich_help_panel=_R)] = None,
    t_end: Annotated[Optional[str], typer.Option("--t-end", help="seconds of motion (default 20); the video lasts t_end/speed", rich_help_panel=_R)] = None,
    fps: Annotated[Optional[str], typer.Option("--fps", help="frames per second of the video (default 30)", rich_help_panel=_R)] = None,
    speed: Annotated[Optional[str], typer.Option("--speed", help="seconds of motion per second of video (default 1; 0.5 = slow motion)", rich_help_panel=_R)] = None,
    trail: Annotated[Optional[str], typer.Option("--trail", help="seconds of motion the fading trail of rod 2's tip covers (default 2; 0 = none)", rich_help_panel=_R)] = None,
    size: Annotated[Optional[str], typer.Option("--size", help="frame size WIDTHxHEIGHT in pixels (default 640x480; even for MP4)", rich_help_panel=_R)] = None,
    method: METHOD = None,
    rtol: RTOL = None,
    atol: ATOL = None,
    dt: DT = None,
    max_steps: MAX_STEPS_OPT = None,
    quiet: QUIET = False,
    config: CONFIG = None,
) -> None:
    """Simulate and write a 3D animation (MP4 or GIF): solid rods, both hinge axes, the tip's trail,
    a readout of time, angles and energy; one frame per row at the exact frame times k*speed/fps.

    Exit status: 0 done, 1 the run stopped early (the frames computed are written), 2 bad input,
    130 interrupted (nothing written).
    """
    params, y0, run = _resolve(
        config, model, initial,
        dict(t_end=t_end, method=method.value if method else None, rtol=rtol, atol=atol, dt=dt, max_steps=max_steps),
    )
    method_name, steps = _integration(run)
    for key in ("dt_out", "out", "plot"):
        if run.is_given("simulation", key):
            raise UsageError(f"{run.option('simulation', key)} does not apply to animate: the frames are the rows (dt_out = speed/fps), written to --out")
    fps_v = 30.0 if fps is None else _positive(fps, "--fps")
    speed_v = 1.0 if speed is None else _positive(speed, "--speed")
    from .views.animation import DEFAULT_SIZE, DEFAULT_TRAIL, check_output

    trail_v = DEFAULT_TRAIL
    if trail is not None:
        trail_v = parse_scalar(trail, "--trail")
        if trail_v is None or not trail_v >= 0:
            raise UsageError(f"--trail: expected a number of seconds >= 0, got {trail!r}")
    size_v = DEFAULT_SIZE
    if size is not None:
        try:
            size_v = tuple(int(v) for v in size.lower().replace("×", "x").split("x"))
            if len(size_v) != 2:
                raise ValueError
        except ValueError:
            raise UsageError(f"--size: expected WIDTHxHEIGHT in pixels (e.g. 640x480), got {size!r}") from None
    if out is None:
        raise UsageError("--out: give the video file, FILE.mp4 or FILE.gif")
    check_output(out)  # suffix, directory: refused before any work
    from .numeric.simulation import simulate as run_simulation
    from .progress import ProgressBar
    from .views.animation import animate as write_animation

    with ProgressBar("simulating", unit="s", enabled=None if not quiet else False) as bar:
        traj = run_simulation(
            params, y0, _setting(run, "t_end"), dt_out=speed_v / fps_v, method=method_name,
            rtol=_setting(run, "rtol"), atol=_setting(run, "atol"), dt=_setting(run, "dt"),
            max_steps=steps, progress=bar,
        )
    with ProgressBar("rendering", unit="frames", enabled=None if not quiet else False) as bar:
        write_animation(traj, out, fps=fps_v, speed=speed_v, trail=trail_v, size=size_v, progress=bar)
    n = traj.t.size
    sys.stdout.write(f"wrote {out}: {n} frames, {n / fps_v:.2f} s at {fps_v:g} fps, {traj.t[-1]:.6g} s of motion ({speed_v:g}x)\n")
    if not traj.success:
        sys.stderr.write(f"skewpend: simulation {traj.message} at t = {traj.t[-1]:.6g} s; animated the frames computed\n")
        sys.exit(1)


# -- flip-time maps ----------------------------------------------------------------------------------------
#: What the ensemble commands (flipmap, chaos-diagram) write: a resumable store or one NetCDF file.
_ENSEMBLE_OUT = (".zarr", ".nc")


@app.command()
@_options(MODEL_OPTIONS)
def flipmap(
    model: dict,
    n: Annotated[Optional[str], typer.Option("--n", help="cells per side: an n x n map (default 256)", rich_help_panel=_R)] = None,
    t_end: Annotated[Optional[str], typer.Option("--t-end", help="longest time looked at [s] (default 10)", rich_help_panel=_R)] = None,
    window: Annotated[Optional[str], typer.Option("--window", help="PHI0:PHI1,PSI0:PSI1 (radians, or e.g. -90:90deg,-180:180deg; default the whole square)", rich_help_panel=_R)] = None,
    rtol: Annotated[Optional[str], typer.Option("--rtol", help="relative tolerance of DOP853 (default 1e-10)", rich_help_panel=_R)] = None,
    atol: Annotated[Optional[str], typer.Option("--atol", help="absolute tolerance of DOP853 (default 1e-10)", rich_help_panel=_R)] = None,
    out: Annotated[Optional[str], typer.Option("--out", "-o", help="write the map to FILE.zarr (chunk by chunk, resumable) or FILE.nc", rich_help_panel=_R)] = None,
    plot: Annotated[Optional[str], typer.Option("--plot", help="draw the map to FILE (.png, .svg or .pdf)", rich_help_panel=_R)] = None,
    resume: Annotated[bool, typer.Option("--resume", help="with --out FILE.zarr: compute only the chunks an interrupted run left missing", rich_help_panel=_R)] = False,
    workers: WORKERS = None,
    scheduler: SCHEDULER = None,
    quiet: QUIET = False,
    config: CONFIG = None,
) -> None:
    """The flip-time map: for each start (phi0, psi0) at rest on an n x n grid, the first time either
    hinge angle leaves (-180 deg, 180 deg) -- on every core, or on a Dask cluster.

    From a --config run file it takes [parameters].
    """
    import math

    from .parsing import parse_interval

    params, _, _ = _resolve(config, model, {}, {})
    size = 256 if n is None else parse_scalar(n, "--n")
    if size is None or size != int(size) or not 1 <= size <= 16384:
        raise UsageError(f"--n: expected a whole number of cells per side from 1 to 16384, got {n!r}")
    horizon = 10.0 if t_end is None else _positive(t_end, "--t-end")
    tolerances = {k: (None if v is None else _positive(v, f"--{k}")) for k, v in (("rtol", rtol), ("atol", atol))}
    ranges = ((-math.pi, math.pi), (-math.pi, math.pi))
    if window is not None:
        parts = window.split(",")
        if len(parts) != 2:
            raise UsageError(f"--window: expected PHI0:PHI1,PSI0:PSI1 (e.g. -90:90deg,-180:180deg), got {window!r}")
        ranges = tuple(parse_interval(part, f"--window ({name})", angle=True) for part, name in zip(parts, ("phi", "psi")))
        for (lo, hi), name in zip(ranges, ("phi", "psi")):
            if not -math.pi - 1e-12 <= lo < hi <= math.pi + 1e-12:
                raise UsageError(f"--window ({name}): expected START < STOP within -180..180 deg, got {lo:.6g}:{hi:.6g} rad")
    threads = _ensemble_outputs(workers, scheduler, out, resume, plot)
    from .analysis.flipmap import flip_map
    from .progress import ProgressBar

    store = out if out is not None and str(out).lower().endswith(".zarr") else None
    with ProgressBar("flip map", unit="cells", enabled=None if not quiet else False) as bar:
        fm = flip_map(params, int(size), t_end=horizon, phi_range=ranges[0], psi_range=ranges[1], workers=threads,
                      progress=bar, store=store, resume=resume, scheduler=scheduler, **tolerances)
    if out is not None and store is None:
        fm.to_netcdf(out)
    if plot is not None:
        from .views.figures import flipmap_figure, save_figure

        save_figure(flipmap_figure(fm), plot)
    flipped = int(fm.flipped.sum()) if hasattr(fm, "flipped") else int((fm.which >= 0).sum())
    st = fm.stats
    lines = [
        f"flip map      {fm.n} x {fm.n} starts at rest, t_end = {horizon:g} s",
        f"flipped       {flipped} of {fm.n * fm.n} ({100 * flipped / (fm.n * fm.n):.1f} %)",
        f"work          {st.get('integrated', '?')} cells integrated, {st.get('skipped_energy', 0)} ruled out by energy, "
        f"{st.get('mirrored', 0)} by symmetry; {st.get('wall_time', float('nan')):.3g} s on {st.get('workers', '?')} workers",
    ]
    if "chunks_computed" in st:
        lines.append(f"store         {st['chunks_computed']} chunks computed now, {st.get('chunks_resumed', 0)} already done"
                     + (f"; {st['tasks']} tasks on {st['scheduler']}" if st.get("scheduler") else ""))
    if st.get("failed"):
        lines.append(f"failed        {st['failed']} cells (left NaN: the integration stopped early)")
    for what, path in (("written", out), ("plot", plot)):
        if path is not None:
            lines.append(f"{what:14s}{path}")
    sys.stdout.write("\n".join(lines) + "\n")


# -- chaos: Lyapunov spectra, Poincare sections, the chaos diagram ------------------------------------------
def _whole(text: Optional[str], option: str, default: int, lo: int, hi: int) -> int:
    """A whole number typed by the user, from ``lo`` to ``hi`` (``default`` when not given)."""
    if text is None:
        return default
    value = parse_scalar(text, option)
    if value is None or value != int(value) or not lo <= value <= hi:
        raise UsageError(f"{option}: expected a whole number from {lo} to {hi}, got {text!r}")
    return int(value)


def _seconds(text: Optional[str], option: str, default: Optional[float], *, zero: bool = False) -> Optional[float]:
    """A time [s] typed by the user: positive (or >= 0 with ``zero``)."""
    if text is None:
        return default
    value = parse_scalar(text, option)
    if value is None or not (value >= 0 if zero else value > 0):
        raise UsageError(f"{option}: expected a {'non-negative' if zero else 'positive'} number of seconds, got {text!r}")
    return value


def _workers_option(workers: Optional[str]) -> Optional[int]:
    return None if workers is None else _whole(workers, "--workers (threads)", 1, 1, 1024)


def _check_plot(plot: Optional[str], option: str = "--plot") -> None:
    """A figure's output path, checked before any work (``option`` names it in the message)."""
    if plot is not None:
        from .io import check_output_path
        from .views.figures import FIGURE_SUFFIXES

        check_output_path(plot, FIGURE_SUFFIXES, option=option)


def _ensemble_outputs(workers, scheduler, out, resume: bool, plot) -> Optional[int]:
    """The checks of an ensemble command's --workers/--scheduler, --out FILE.zarr|.nc, --resume and
    --plot (before any work); the thread count (None: every core)."""
    from .io import check_output_path

    threads = _workers_option(workers)
    if scheduler is not None and workers is not None:
        raise UsageError("--workers counts threads on this machine; with --scheduler the cluster's workers do the work")
    if out is not None:
        if not str(out).lower().endswith(_ENSEMBLE_OUT):
            raise UsageError(f"--out: expected a file name ending in .zarr or .nc, got {out!r}")
        if str(out).lower().endswith(".nc"):
            check_output_path(out, (".nc",), option="--out")
    if resume and (out is None or not str(out).lower().endswith(".zarr")):
        raise UsageError("--resume continues a store: give --out FILE.zarr (a .nc file is written whole at the end)")
    _check_plot(plot)
    return threads


def _tolerances(rtol: Optional[str], atol: Optional[str]) -> dict:
    return {k: _positive(v, f"--{k}") for k, v in (("rtol", rtol), ("atol", atol)) if v is not None}


@app.command()
@_options(MODEL_OPTIONS, INITIAL_OPTIONS)
def lyapunov(
    model: dict,
    initial: dict,
    t_end: Annotated[Optional[str], typer.Option("--t-end", help="length of the run [s] (default 1000)", rich_help_panel=_R)] = None,
    renorm_every: Annotated[Optional[str], typer.Option("--renorm-every", help="QR re-orthonormalisation interval [s] (default 1)", rich_help_panel=_R)] = None,
    transient: Annotated[Optional[str], typer.Option("--transient", help="seconds at the start not counted (default 0)", rich_help_panel=_R)] = None,
    exponents: Annotated[Optional[str], typer.Option("--exponents", help="how many exponents: 4 (the spectrum, default) or 1 (the largest, cheaper)", rich_help_panel=_R)] = None,
    rtol: Annotated[Optional[str], typer.Option("--rtol", help="relative tolerance of DOP853 (default 1e-10)", rich_help_panel=_R)] = None,
    atol: Annotated[Optional[str], typer.Option("--atol", help="absolute tolerance of DOP853 (default 1e-10)", rich_help_panel=_R)] = None,
    windows: Annotated[Optional[str], typer.Option("--windows", help="time windows for the uncertainty (default 10)", rich_help_panel=_R)] = None,
    max_steps: MAX_STEPS_OPT = None,
    out: Annotated[Optional[str], typer.Option("--out", "-o", help="write the result to FILE.json (exponents, settings) or FILE.csv (running estimates)", rich_help_panel=_R)] = None,
    plot: Annotated[Optional[str], typer.Option("--plot", help="draw the running estimates to FILE (.png, .svg or .pdf)", rich_help_panel=_R)] = None,
    quiet: QUIET = False,
    config: CONFIG = None,
) -> None:
    """Lyapunov exponents of the motion from the initial state: Benettin's method (QR) on the
    variational equations generated from the derivation.

    From a --config run file it takes [parameters] and [initial].
    """
    from .io import check_output_path
    from .progress import ProgressBar

    params, y0, _ = _resolve(config, model, initial, {})
    horizon = _seconds(t_end, "--t-end", 1000.0)
    every = _seconds(renorm_every, "--renorm-every", 1.0)
    skip = _seconds(transient, "--transient", 0.0, zero=True)
    k = _whole(exponents, "--exponents", 4, 1, 4)
    n_win = _whole(windows, "--windows", 10, 1, 1000)
    cap = _whole(max_steps, "--max-steps", 10**8, 1, 10**15)
    if out is not None:
        check_output_path(out, (".json", ".csv"), option="--out")
    _check_plot(plot)
    from .analysis.lyapunov import lyapunov as run_lyapunov

    with ProgressBar("Lyapunov", unit="s", enabled=None if not quiet else False) as bar:
        spec = run_lyapunov(params, y0, t_end=horizon, renorm_every=every, transient=skip, n_exponents=k,
                            windows=n_win, max_steps=cap, progress=bar, throw=False, **_tolerances(rtol, atol))
    if out is not None:
        _write_lyapunov(spec, out)
    if plot is not None:
        from .views.figures import lyapunov_figure, save_figure

        save_figure(lyapunov_figure(spec), plot)
    st = spec.stats
    lines = [spec.table()]
    if spec.k == 4:
        lines.append(f"Kaplan-Yorke dimension {spec.kaplan_yorke_dimension:.4f}")
    lines.append(f"run      {spec.settings['measured_from']:g} .. {st['t_reached']:g} s, QR every {every:g} s, "
                 f"{st['steps']} steps ({st['rejected']} rejected), {st['wall_time']:.3g} s")
    for what, path in (("written", out), ("plot", plot)):
        if path is not None:
            lines.append(f"{what:9s}{path}")
    sys.stdout.write("\n".join(lines) + "\n")
    if spec.status != 0:
        sys.stderr.write(f"skewpend: lyapunov {spec.message}; the exponents above cover the time up to there\n")
        sys.exit(1)


def _write_lyapunov(spec, out: str) -> None:
    import json

    import numpy as np

    from .io import atomic_path

    with atomic_path(out) as tmp:
        if str(out).lower().endswith(".json"):
            tmp.write_text(json.dumps(spec.to_dict(), indent=2) + "\n")
        else:
            header = "t," + ",".join(f"lambda_{i + 1}" for i in range(spec.k))
            np.savetxt(tmp, np.column_stack([spec.t, spec.history]), delimiter=",", header=header, comments="",
                       fmt="%.17g")


class Direction(str, Enum):
    up = "+1"
    down = "-1"
    both = "both"


class Locate(str, Enum):
    dense = "dense"
    henon = "henon"


@app.command()
@_options(MODEL_OPTIONS)
def poincare(
    model: dict,
    energy: Annotated[Optional[str], typer.Option("--energy", help="the energy of the orbits [J] (required; 0 = at rest, for thin rods)", rich_help_panel=_R)] = None,
    section: Annotated[Optional[str], typer.Option("--section", help="phi=VALUE or psi=VALUE (radians, e.g. 30deg, or a multiple of pi such as pi/2; modulo 360 deg; default phi=0)", rich_help_panel=_R)] = None,
    direction: Annotated[Direction, typer.Option("--direction", help="crossings with the angle increasing (+1), decreasing (-1) or both", rich_help_panel=_R)] = Direction.up,
    orbits: Annotated[Optional[str], typer.Option("--orbits", help="orbits started on the section (default 50)", rich_help_panel=_R)] = None,
    crossings: Annotated[Optional[str], typer.Option("--crossings", help="crossings recorded per orbit (default 500)", rich_help_panel=_R)] = None,
    locate: Annotated[Locate, typer.Option("--locate", help="crossings by the dense output and root finding, or by Henon's trick", rich_help_panel=_R)] = Locate.dense,
    t_max: Annotated[Optional[str], typer.Option("--t-max", help="longest time per orbit [s] (default 200 small-oscillation periods per crossing)", rich_help_panel=_R)] = None,
    rtol: Annotated[Optional[str], typer.Option("--rtol", help="relative tolerance of DOP853 (default 1e-12)", rich_help_panel=_R)] = None,
    atol: Annotated[Optional[str], typer.Option("--atol", help="absolute tolerance of DOP853 (default 1e-12)", rich_help_panel=_R)] = None,
    velocity: Annotated[bool, typer.Option("--velocity", help="plot (q, q') instead of the canonical (q, p_q)", rich_help_panel=_R)] = False,
    out: Annotated[Optional[str], typer.Option("--out", "-o", help="write the points to FILE.csv or FILE.nc", rich_help_panel=_R)] = None,
    plot: Annotated[Optional[str], typer.Option("--plot", help="draw the section to FILE (.png, .svg or .pdf)", rich_help_panel=_R)] = None,
    workers: Annotated[Optional[str], typer.Option("--workers", help="threads (default: every core)", rich_help_panel=_R)] = None,
    quiet: QUIET = False,
    config: CONFIG = None,
) -> None:
    """A Poincare section on an energy surface: orbits started on the section, their crossings
    located on the dense output, in the area-preserving coordinates (q, p_q) of the other joint.

    Needs a conservative model (no damping, no torques). From a --config run file it takes [parameters].
    """
    from .io import check_output_path
    from .progress import ProgressBar

    params, _, _ = _resolve(config, model, {}, {})
    if energy is None:
        raise UsageError("--energy is required: the energy of the orbits in joules (e.g. --energy 10)")
    e = parse_scalar(energy, "--energy")
    if e is None:
        raise UsageError(f"--energy: expected a number of joules, got {energy!r}")
    n_orbits = _whole(orbits, "--orbits", 50, 1, 100_000)
    n_cross = _whole(crossings, "--crossings", 500, 1, 10_000_000)
    horizon = _seconds(t_max, "--t-max", None)
    threads = _workers_option(workers)
    if out is not None:
        check_output_path(out, (".csv", ".nc"), option="--out")
    _check_plot(plot)
    if velocity and plot is None:
        raise UsageError("--velocity chooses the plot's coordinates: give --plot FILE too")
    from .analysis.poincare import poincare as run_poincare

    sign = {"+1": 1, "-1": -1, "both": 0}[direction.value]
    with ProgressBar("Poincare section", unit="crossings", enabled=None if not quiet else False) as bar:
        sec = run_poincare(params, e, section="phi=0" if section is None else section, direction=sign,
                           n_orbits=n_orbits, n_crossings=n_cross, locate=locate.value, t_max=horizon,
                           workers=threads, progress=bar, **_tolerances(rtol, atol))
    if out is not None:
        (sec.to_netcdf if str(out).lower().endswith(".nc") else sec.to_csv)(out)
    if plot is not None:
        from .views.figures import poincare_figure, save_figure

        save_figure(poincare_figure(sec, canonical=not velocity), plot)
    st = sec.stats
    c, o = sec.coord_names
    lines = [
        f"section   {sec.settings['section']} ({'both directions' if sign == 0 else ('increasing' if sign > 0 else 'decreasing')}), "
        f"energy {e:g} J (minimum {st['e_min']:.6g} J)",
        f"points    {st['points']} in ({o}, p_{o}) from {st['orbits']} orbits"
        + (f"; {st['orbits_short']} reached t_max first" if st["orbits_short"] else ""),
        f"accuracy  max |energy error| {st['max_energy_error']:.2e} J",
        f"work      {st['steps']} steps, {st['wall_time']:.3g} s on {st['workers']} workers",
    ]
    if st["failed"]:
        lines.append(f"failed    {st['failed']} orbits stopped early (non-finite state, step underflow or max steps)")
    for what, path in (("written", out), ("plot", plot)):
        if path is not None:
            lines.append(f"{what:10s}{path}")
    sys.stdout.write("\n".join(lines) + "\n")


@app.command("chaos-diagram")
@_options(MODEL_OPTIONS)
def chaos_diagram(
    model: dict,
    alphas: Annotated[Optional[str], typer.Option("--alphas", help="skew angles START:STOP:COUNT (e.g. 0:90deg:7, the default)", rich_help_panel=_R)] = None,
    energies: Annotated[Optional[str], typer.Option("--energies", help="energies above the minimum START:STOP:COUNT [J] (default: 8 up to the potential's span)", rich_help_panel=_R)] = None,
    samples: Annotated[Optional[str], typer.Option("--samples", help="starts per cell on the energy surface (default 24)", rich_help_panel=_R)] = None,
    t_end: Annotated[Optional[str], typer.Option("--t-end", help="length of each run [s] (default 150)", rich_help_panel=_R)] = None,
    threshold: Annotated[Optional[str], typer.Option("--threshold", help="largest exponent [1/s] above which a start counts as chaotic (default from the frequencies and t_end)", rich_help_panel=_R)] = None,
    rtol: Annotated[Optional[str], typer.Option("--rtol", help="relative tolerance of DOP853 (default 1e-8)", rich_help_panel=_R)] = None,
    atol: Annotated[Optional[str], typer.Option("--atol", help="absolute tolerance of DOP853 (default 1e-8)", rich_help_panel=_R)] = None,
    out: Annotated[Optional[str], typer.Option("--out", "-o", help="write the diagram to FILE.zarr (row by row, resumable) or FILE.nc", rich_help_panel=_R)] = None,
    plot: Annotated[Optional[str], typer.Option("--plot", help="draw the diagram to FILE (.png, .svg or .pdf)", rich_help_panel=_R)] = None,
    resume: Annotated[bool, typer.Option("--resume", help="with --out FILE.zarr: compute only the rows an interrupted run left missing", rich_help_panel=_R)] = False,
    workers: WORKERS = None,
    scheduler: SCHEDULER = None,
    quiet: QUIET = False,
    config: CONFIG = None,
) -> None:
    """How the skew angle changes chaos: for each alpha and energy, the fraction of starts on
    that energy surface whose largest Lyapunov exponent is clearly positive.

    Needs a conservative model (no damping, no torques); alpha is the diagram's axis (use
    --alphas, not --alpha). From a --config run file it takes [parameters].
    """
    from .parsing import parse_range
    from .progress import ProgressBar

    run = _Run(config, {"parameters": model})
    if run.is_given("parameters", "alpha"):
        raise UsageError(f"{run.option('parameters', 'alpha')}: the chaos diagram varies alpha itself; give the angles with --alphas START:STOP:COUNT")
    run.values["parameters"].pop("alpha", None)
    params = run.parameters()
    alpha_values = None if alphas is None else parse_range(alphas, "--alphas", angle=True)
    energy_values = None if energies is None else parse_range(energies, "--energies", angle=False)
    n_samples = _whole(samples, "--samples", 24, 1, 100_000)
    horizon = _seconds(t_end, "--t-end", 150.0)
    thr = None if threshold is None else _positive(threshold, "--threshold")
    threads = _ensemble_outputs(workers, scheduler, out, resume, plot)
    from .analysis.chaos import chaos_diagram as run_diagram

    store = out if out is not None and str(out).lower().endswith(".zarr") else None
    kw = {"alpha": alpha_values} if alpha_values is not None else {}
    if energy_values is not None:
        kw["energy"] = energy_values
    with ProgressBar("chaos diagram", unit="alphas", enabled=None if not quiet else False) as bar:
        d = run_diagram(params, samples=n_samples, t_end=horizon, threshold=thr, workers=threads, progress=bar,
                        store=store, resume=resume, scheduler=scheduler, **kw, **_tolerances(rtol, atol))
    if out is not None and store is None:
        d.to_netcdf(out)
    if plot is not None:
        from .views.figures import chaos_diagram_figure, save_figure

        save_figure(chaos_diagram_figure(d), plot)
    st = d.stats
    lines = [
        f"chaotic fraction (largest exponent > {d.threshold:.3g} 1/s over {horizon:g} s, {n_samples} starts per cell on phi = 0)",
        d.table(),
        f"work      {st['trajectories']} trajectories, {st['wall_time']:.3g} s on {st['workers']} workers"
        + (f"; {st['rows_resumed']} rows already in the store" if st.get("rows_resumed") else ""),
    ]
    if st["failed"]:
        lines.append(f"failed    {st['failed']} trajectories (left NaN)")
    for what, path in (("written", out), ("plot", plot)):
        if path is not None:
            lines.append(f"{what:10s}{path}")
    sys.stdout.write("\n".join(lines) + "\n")


# -- the live explorer --------------------------------------------------------------------------------------
_LOOPBACK = ("127.0.0.1", "localhost", "::1")


@app.command()
def serve(
    host: Annotated[str, typer.Option("--host", help="address to listen on (default 127.0.0.1: this machine only)")] = "127.0.0.1",
    port: Annotated[Optional[str], typer.Option("--port", help="TCP port (default 8000)")] = None,
    open_browser: Annotated[bool, typer.Option("--open", help="open the page in the web browser")] = False,
) -> None:
    """The live explorer in the browser: the pendulum in 3D with sliders, equations, plots, normal
    modes and a flip map, on physics generated from the derivation (needs skewpend[web]).

    Ctrl-C stops the server.
    """
    import ipaddress
    import socket

    number = 8000
    if port is not None:
        text = port.strip()
        if not (text.isdigit() and 1 <= int(text) <= 65535):
            raise UsageError(f"--port: expected a whole number from 1 to 65535, got {port!r}")
        number = int(text)
    name = host.strip()
    if not name:
        raise UsageError("--host: expected an address such as 127.0.0.1 or 0.0.0.0, got ''")
    try:
        ipaddress.ip_address(name.strip("[]"))
    except ValueError:
        if not re.fullmatch(r"[A-Za-z0-9.-]{1,253}", name):
            raise UsageError(f"--host: expected an IP address or a host name, got {host!r}") from None
    from .views.explorer import require_web

    require_web("skewpend serve")
    family = socket.AF_INET6 if ":" in name else socket.AF_INET
    with socket.socket(family, socket.SOCK_STREAM) as probe:  # refuse a busy port in one line, before starting
        probe.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEADDR, 1)
        try:
            probe.bind((name.strip("[]"), number))
        except OSError as exc:
            raise UsageError(f"--port: cannot listen on {name}:{number}: {exc.strerror or exc}; choose another --port "
                             "or --host") from None
    if name not in _LOOPBACK:
        sys.stderr.write(f"skewpend: warning: serving on {name}:{number}, not only on this machine: anyone who can reach "
                         "it can use the explorer (its work per request is bounded)\n")
    sys.stderr.write(f"skewpend explorer on http://{'127.0.0.1' if name in ('0.0.0.0', '::') else name}:{number}/ "
                     "(Ctrl-C to stop)\n")
    from .views.explorer import serve as run_server

    run_server(name, number, open_browser=open_browser)


# -- report -----------------------------------------------------------------------------------------------
@app.command()
@_options(MODEL_OPTIONS, INITIAL_OPTIONS)
def report(
    model: dict,
    initial: dict,
    t_end: Annotated[Optional[str], typer.Option("--t-end", help="simulated time [s] (default 20, at most 1000)", rich_help_panel=_R)] = None,
    method: METHOD = None,
    rtol: RTOL = None,
    atol: ATOL = None,
    dt: DT = None,
    max_steps: MAX_STEPS_OPT = None,
    out: Annotated[str, typer.Option("--out", "-o", help="the HTML file to write (default report.html)")] = "report.html",
    quiet: QUIET = False,
    config: CONFIG = None,
) -> None:
    """Write one self-contained HTML report (opens offline): the system, the derivation step by step,
    the check against the specification at alpha = 0, normal modes against alpha, a simulation with
    figures and an animation, the comparison with MuJoCo (when installed), how it was made.

    From a --config run file it takes [parameters], [initial] and the integrator settings of
    [simulation]; simulate's outputs there (out, dt_out, plot) do not apply to a report.
    """
    import shlex
    import time

    from .io import check_output_path
    from .views.report import MAX_T_END, REPORT_SUFFIXES, build_report

    started = time.perf_counter()
    run = _Run(config, {"parameters": model, "initial": initial, "simulation": dict(
        t_end=t_end, method=method.value if method else None, rtol=rtol, atol=atol, dt=dt, max_steps=max_steps)})
    params, y0 = run.parameters(), run.initial_state()
    method_name, steps = _integration(run)
    horizon = _setting(run, "t_end")
    if horizon > MAX_T_END:
        raise UsageError(f"{run.option('simulation', 't_end')}: a report draws at most {MAX_T_END:g} s of motion, got {horizon:g}; "
                         "use skewpend simulate --out for long runs")
    check_output_path(out, REPORT_SUFFIXES, option="--out")
    from .progress import ProgressBar

    with ProgressBar("writing the report", unit="parts", enabled=None if not quiet else False) as bar:
        path = build_report(
            params, y0=y0, t_end=horizon, method=method_name,
            rtol=_setting(run, "rtol"), atol=_setting(run, "atol"), dt=_setting(run, "dt"),
            max_steps=steps, out=out, progress=bar,
            command="skewpend " + " ".join(shlex.quote(a) for a in sys.argv[1:]),
        )
    size = path.stat().st_size
    sys.stdout.write(f"wrote {path.resolve()} ({size / 1e6:.1f} MB) in {time.perf_counter() - started:.1f} s\n")


class ExportFormat(str, Enum):
    mjcf = "mjcf"
    urdf = "urdf"


@app.command()
@_options(MODEL_OPTIONS)
def export(
    model: dict,
    fmt: Annotated[Optional[ExportFormat], typer.Option("--format", "-f", help="model format (default: from the --out suffix, .xml/.mjcf or .urdf; mjcf when printing)")] = None,
    out: Annotated[Optional[str], typer.Option("--out", "-o", help="write to FILE (default: print)")] = None,
    config: CONFIG = None,
) -> None:
    """Export the system as a MuJoCo MJCF model or a URDF (numeric parameters; the defaults of simulate).

    From a --config run file it takes [parameters].
    """
    from .interop import export as ex

    params, _, _ = _resolve(config, model, {}, {})
    if out is None:
        chosen = fmt or ExportFormat.mjcf
        sys.stdout.write(ex.to_mjcf(params) if chosen is ExportFormat.mjcf else ex.to_urdf(params))
        return
    path = ex.write_model(params, out, fmt.value if fmt else None)
    fmt = fmt or ExportFormat(ex._format_for(path, None))
    sys.stderr.write(f"skewpend: wrote {fmt.value.upper()} model to {path}\n")


@app.command()
@_options(MODEL_OPTIONS, INITIAL_OPTIONS)
def validate(
    model: dict,
    initial: dict,
    t_end: Annotated[Optional[str], typer.Option("--t-end", help="duration [s] (default 2)", rich_help_panel=_R)] = None,
    dt: Annotated[Optional[str], typer.Option("--dt", help="MuJoCo RK4 step [s] (default 1e-4)", rich_help_panel=_R)] = None,
    tol: Annotated[Optional[str], typer.Option("--tol", help="largest allowed difference in any state component (default 1e-6)", rich_help_panel=_R)] = None,
    config: CONFIG = None,
) -> None:
    """Compare skewpend with MuJoCo (the exported MJCF, RK4) for your parameters; exit 1 if they disagree.

    From a --config run file it takes [parameters], [initial] and [simulation] t_end.
    """
    from .interop.validation import compare_with_mujoco

    # a run file's [parameters], [initial] and t_end are used; its other [simulation] settings
    # (method, dt, out, ...) are simulate's and do not apply to a comparison with MuJoCo
    run = _Run(config, {"parameters": model, "initial": initial, "simulation": {"t_end": t_end}})
    params, y0 = run.parameters(), run.initial_state()
    horizon = _positive_setting(run, "t_end") if run.is_given("simulation", "t_end") else 2.0
    step = 1e-4 if dt is None else _positive(dt, "--dt")
    tolerance = 1e-6 if tol is None else _positive(tol, "--tol")
    report = compare_with_mujoco(params, y0, horizon, dt=step)
    lines = [
        f"skewpend (dop853, rtol=atol=1e-12) vs MuJoCo {report.mujoco_version} (RK4, dt={report.dt:g} s), {report.t_end:g} s, {report.samples} samples",
        "max |difference|:  " + "  ".join(f"{k}={v:.2e}" for k, v in report.max_abs_diff.items()),
        f"energy drift: skewpend {report.energy_drift:.1e}",
    ]
    ok = report.max_difference <= tolerance
    lines.append(("AGREE" if ok else "DISAGREE") + f" within {tolerance:g} (largest difference {report.max_difference:.2e})")
    sys.stdout.write("\n".join(lines) + "\n")
    if not ok:
        sys.exit(1)


class ModesFormat(str, Enum):
    text = "text"
    json = "json"
    latex = "latex"


@app.command()
@_options({k: v for k, v in MODEL_OPTIONS.items() if k not in ("tau1", "tau2")})
def modes(
    model: dict,
    fmt: Annotated[ModesFormat, typer.Option("--format", "-f", help="text, json, or latex (the closed-form characteristic equation in the parameters not given; not with --sweep, --plot, --out, --tolerance, --check-nonlinear)")] = ModesFormat.text,
    sweep_spec: Annotated[Optional[str], typer.Option("--sweep", help="NAME=START:STOP:COUNT over alpha, a, b, m1, m2, g, b/a or m2/m1 (e.g. alpha=0:180deg:181; a unit on either end applies to the whole range, plain numbers are radians)")] = None,
    plot: Annotated[Optional[str], typer.Option("--plot", help="with --sweep: write the frequency curves to FILE (.png, .pdf, .svg)")] = None,
    out: Annotated[Optional[str], typer.Option("--out", "-o", help="with --sweep: write the table to FILE (.csv or .json; alpha in rad plus alpha_deg)")] = None,
    tolerance: Annotated[Optional[str], typer.Option("--tolerance", help="with --sweep: flag w2/w1 within tolerance*n of n = 1, 2, 3 (a positive number; default 0.01)")] = None,
    check_nonlinear: Annotated[Optional[str], typer.Option("--check-nonlinear", help="AMPLITUDE [rad or deg]: measure the frequencies of the nonlinear motion started from each mode (undamped, no --sweep)")] = None,
    config: CONFIG = None,
) -> None:
    """Normal modes of the small oscillations about the hanging equilibrium (and how alpha shapes them)."""
    given = model
    # every option takes effect or is refused, before any work is done
    if fmt is ModesFormat.latex:
        extra = [o for o, v in (("--sweep", sweep_spec), ("--plot", plot), ("--out", out), ("--tolerance", tolerance),
                                ("--check-nonlinear", check_nonlinear)) if v is not None]
        if extra:
            raise UsageError(
                f"--format latex prints only the closed-form characteristic equation, so {', '.join(extra)} "
                "cannot be used with it (use --format text or json)"
            )
        _modes_latex(given, config)
        return
    if sweep_spec is None:
        if plot is not None or out is not None:
            raise UsageError("--plot and --out go with --sweep")
        if tolerance is not None:
            raise UsageError("--tolerance sets how close w2/w1 must come to 1, 2, 3 along a --sweep; without --sweep it has no effect")
    elif check_nonlinear is not None:
        raise UsageError("--check-nonlinear measures one parameter set, not a sweep; use it without --sweep")
    from .analysis import modes as md

    params, _, _ = _resolve(config, given, {}, {})
    if sweep_spec is not None:
        tol = 0.01
        if tolerance is not None:
            tol = parse_scalar(tolerance, "--tolerance")
            if tol is None or not tol > 0:
                raise UsageError(f"--tolerance: expected a positive number (e.g. 0.01), got {tolerance!r}")
        _modes_sweep(params, sweep_spec, plot, out, tol, fmt, given)
        return
    amplitude = None
    if check_nonlinear is not None:
        amplitude = parse_scalar(check_nonlinear, "--check-nonlinear", angle=True)
        if amplitude is None or not 0 < amplitude < 3.141592653589793:
            raise UsageError(
                f"--check-nonlinear: expected an amplitude between 0 and 180 deg exclusive (radians, or e.g. 10deg), got {check_nonlinear!r}"
            )
    result = md.normal_modes(params)
    check = md.check_nonlinear(params, amplitude) if amplitude is not None else None
    if fmt is ModesFormat.json:
        import json

        data = result.to_dict()
        if check is not None:
            data["nonlinear_check"] = {
                "amplitude": check.amplitude,
                "measured_frequencies": check.measured.tolist(),
                "relative_shift": check.relative_shift.tolist(),
            }
        sys.stdout.write(json.dumps(data, indent=2) + "\n")
        return
    sys.stdout.write(_modes_text(result, check))


def _modes_text(m, check) -> str:
    import numpy as np

    lines = ["Normal modes about the hanging equilibrium (phi = psi = 0)", ""]
    lines.append(f"{'mode':>4}  {'omega [rad/s]':>14}  {'f [Hz]':>10}  {'period [s]':>11}  {'shape (phi, psi), M0-normalised':>34}  {'psi/phi':>9}")
    for k in range(2):
        v = m.shapes[:, k]
        ratio = "inf" if not np.isfinite(m.ratios[k]) else f"{m.ratios[k]:.5g}"
        lines.append(
            f"{k + 1:>4}  {m.frequencies[k]:14.8g}  {m.frequencies[k] / (2 * np.pi):10.6g}  {m.periods[k]:11.6g}  "
            f"{f'({v[0]:+.6f}, {v[1]:+.6f})':>34}  {ratio:>9}"
        )
    beat = "inf (1:1)" if not np.isfinite(m.beat_period) else f"{m.beat_period:.6g} s"
    lines.append(f"beat period 2 pi/(w2 - w1) = {beat};  w2/w1 = {m.frequencies[1] / m.frequencies[0]:.6g}")
    if m.damped:
        lines.append("with damping (eigenvalues matched to the modes by shape; zeta = -(l1 + l2)/(2 sqrt(l1 l2))):")
        for k in range(2):
            l1, l2 = m.eigenvalue_pairs[k]
            if m.overdamped[k]:
                lines.append(
                    f"  mode {k + 1}: overdamped, lambda = {l1.real:.6g} and {l2.real:.6g} (real), zeta = {m.damping_ratios[k]:.4g}"
                )
            else:
                lines.append(
                    f"  mode {k + 1}: lambda = {l1.real:.6g} +/- {abs(l1.imag):.6g} i, "
                    f"damped omega = {m.damped_frequencies[k]:.6g} rad/s, zeta = {m.damping_ratios[k]:.4g}"
                )
    if check is not None:
        lines.append("")
        lines.append(f"nonlinear check, largest initial angle {check.amplitude:.6g} rad ({np.degrees(check.amplitude):.4g} deg):")
        for k in range(2):
            lines.append(
                f"  mode {k + 1}: linear {check.linear[k]:.8g} rad/s, measured {check.measured[k]:.8g} rad/s "
                f"over {check.cycles[k]} cycles, shift {check.relative_shift[k]:+.3e}"
            )
    return "\n".join(lines) + "\n"


def _modes_latex(given: dict, config: Optional[str]) -> None:
    """The closed form for the parameters given (options over the config's [parameters]);
    the others stay symbolic.  Damping and torques do not enter det(K0 - w^2 M0): refused."""
    from .errors import EquilibriumError
    from .analysis.modes import characteristic_equation
    from .symbolic.render import _tex

    run = _Run(config, {"parameters": given}, defaults=False)
    for keys, why in (
        (("tau1", "tau2"), "phi = psi = 0 is not an equilibrium with constant joint torques; normal modes need tau1 = tau2 = 0"),
        (("c1", "c2"), None),
    ):
        named = [run.option("parameters", k) for k in keys if run.is_given("parameters", k) and run.scalar("parameters", k) != 0.0]
        if named and why is not None:
            raise EquilibriumError(f"{', '.join(named)}: {why}")
        if named:
            raise UsageError(
                f"--format latex prints det(K0 - w^2 M0) = 0, the undamped characteristic equation, so damping "
                f"({', '.join(named)}) would have no effect; leave it out or set it to 0, or use --format text or json for the damped modes"
            )
    eq, roots = characteristic_equation(run.parameters())
    body = [
        r"\det\left(K_0 - \omega^2 M_0\right) = 0 \;\Longleftrightarrow\; " + _tex(eq.lhs) + " &= 0",
        r"\omega_1^2 &= " + _tex(roots[0]),
        r"\omega_2^2 &= " + _tex(roots[1]),
    ]
    sys.stdout.write("\\[\n\\begin{aligned}\n" + " \\\\\n".join(body) + "\n\\end{aligned}\n\\]\n")


def _modes_sweep(params, spec, plot, out, tolerance, fmt, given) -> None:
    import numpy as np

    from .analysis import modes as md

    name, values = md.parse_sweep(spec)
    swept = md.SWEPT_PARAMETER.get(name, name)
    if given.get(swept) is not None:
        raise UsageError(f"--{swept} and --sweep {name}=... both set {swept}; the sweep gives every value, so leave out --{swept}")
    from .io import check_output_path

    if out is not None:
        check_output_path(out, (".csv", ".json"), option="--out")
    if plot is not None:
        check_output_path(plot, (".png", ".pdf", ".svg"), option="--plot")
    sw = md.sweep(params, name, values, tolerance=tolerance)
    if out is not None:
        from .io import atomic_path

        with atomic_path(out) as tmp:
            if str(out).lower().endswith(".csv"):
                cols, rows = sw.table()
                np.savetxt(tmp, rows, delimiter=",", header=",".join(cols), comments="", fmt="%.17g")
            else:
                import json

                tmp.write_text(json.dumps(sw.to_dict(), indent=2) + "\n")
    if plot is not None:
        from .views.figures import plot_sweep, save_figure

        save_figure(plot_sweep(sw), plot)
    if fmt is ModesFormat.json:
        import json

        sys.stdout.write(json.dumps(sw.to_dict(), indent=2) + "\n")
        return
    # alpha is reported in radians (the SI unit of the files) and in degrees (the plot's axis)
    show = (lambda v: f"{v:.6g} rad ({np.degrees(v):.4g} deg)") if name == "alpha" else (lambda v: f"{v:.6g}")
    lines = [
        f"swept {name} over {show(values[0])} .. {show(values[-1])} ({values.size} values)",
        f"omega1: {sw.frequencies[:, 0].min():.6g} .. {sw.frequencies[:, 0].max():.6g} rad/s;  "
        f"omega2: {sw.frequencies[:, 1].min():.6g} .. {sw.frequencies[:, 1].max():.6g} rad/s;  "
        f"w2/w1: {sw.frequency_ratio.min():.6g} .. {sw.frequency_ratio.max():.6g}",
    ]
    if sw.resonances:
        lines.append(f"internal resonances (w2/w1 within {tolerance:g}*n of n):")
        for r in sw.resonances:
            how = "crossed at" if r.crossed else f"closest ({r.ratio:.5g}) at"
            lines.append(f"  {r.order}:1  {how} {name} = {show(r.value)}")
    else:
        lines.append(f"no internal resonance 1:1, 2:1, 3:1 within {tolerance:g}*n")
    for what, path in (("table", out), ("plot", plot)):
        if path is not None:
            lines.append(f"wrote {what} {path}")
    sys.stdout.write("\n".join(lines) + "\n")


def _summary(traj, out_path) -> None:
    y = traj.final_state
    st = traj.stats
    kernel = (
        f"compiled for this model in {st['kernel_build_time']:.2f} s (first use; cached for later runs)"
        if st.get("kernel") == "compiled" else "loaded from the cache"
    )
    lines = [
        f"method        {traj.method}  ({', '.join(f'{k}={v:g}' for k, v in traj.settings.items() if isinstance(v, float) and k != 't_end')})",
        f"status        {traj.message}",
        f"final state   t={traj.t[-1]:.6g} s  phi={y[0]:.12g}  psi={y[1]:.12g}  dphi={y[2]:.12g}  dpsi={y[3]:.12g}",
        f"energy        E0={traj.energy[0]:.12g} J  E={traj.energy[-1]:.12g} J  work of Q={traj.work[-1]:.6g} J",
        f"energy drift  {traj.energy_drift:.3e} (max |E - W - E0| / max |E|)",
        f"steps         {st['steps']} accepted, {st['rejected']} rejected, {st['nfev']} evaluations",
        f"wall time     {st['wall_time'] * 1e3:.2f} ms (compiled integration)",
        f"kernel        {kernel}",
    ]
    if out_path is not None:
        lines.append(f"written       {out_path} ({st['rows']} rows)")
    sys.stdout.write("\n".join(lines) + "\n")


def _fail(message: str) -> None:
    sys.stderr.write(f"skewpend: error: {message}\n")
    sys.exit(2)


def _warning_line(message, category, filename, lineno, file=None, line=None) -> None:
    sys.stderr.write(f"skewpend: warning: {message}\n")


def main(argv: Optional[List[str]] = None) -> None:
    """Entry point: run the app; user mistakes become one line on stderr and exit status 2,
    Ctrl-C one line and exit status 130."""
    import warnings

    warnings.showwarning = _warning_line
    try:
        result = app(args=argv, prog_name="skewpend", standalone_mode=False)
    except SkewpendError as exc:
        _fail(str(exc))
    except KeyboardInterrupt:
        sys.stderr.write("skewpend: interrupted\n")
        sys.exit(130)
    except Exception as exc:  # Typer's (vendored click's) usage errors, matched by shape
        kind = type(exc).__name__
        if kind == "NoArgsIsHelpError":
            sys.stdout.write(exc.format_message() + "\n")
            sys.exit(0)
        if kind == "Abort" or isinstance(exc.__cause__, KeyboardInterrupt):
            sys.stderr.write("skewpend: interrupted\n")
            sys.exit(130)
        if kind == "Exit":  # typer.Exit: --version and the like
            sys.exit(getattr(exc, "exit_code", 0))
        if getattr(exc, "exit_code", None) == 2 and hasattr(exc, "format_message"):
            ctx = getattr(exc, "ctx", None)
            where = f"skewpend {ctx.info_name}" if ctx is not None and ctx.parent is not None else "skewpend"
            _fail(f"{exc.format_message().strip()} (see '{where} --help')")
        if os.environ.get("SKEWPEND_DEBUG"):
            raise
        if isinstance(exc, (OSError, MemoryError)):
            detail = getattr(exc, "strerror", None) or str(exc) or type(exc).__name__
            where = f" ({exc.filename})" if getattr(exc, "filename", None) else ""
            sys.stderr.write(f"skewpend: error: {detail}{where}\n")
            sys.exit(1)
        sys.stderr.write(
            f"skewpend: internal error: {type(exc).__name__}: {str(exc).splitlines()[0] if str(exc) else ''} "
            "(a bug: please report it with the command; SKEWPEND_DEBUG=1 shows the traceback)\n"
        )
        sys.exit(70)
    if result == 130:  # Typer turns Ctrl-C into an exit code without a word
        sys.stderr.write("skewpend: interrupted\n")
    sys.exit(result if isinstance(result, int) else 0)


if __name__ == "__main__":  # pragma: no cover
    main()
