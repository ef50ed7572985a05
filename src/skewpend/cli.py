"""The ``skewpend`` command line: thin wrappers over the library.

Heavy modules (SymPy, NumPy) are imported inside the commands so that
``skewpend --help`` is instant.  A user's mistake is reported as one line on
stderr with exit status 2.
"""

from __future__ import annotations

import math
import sys
from enum import Enum
from typing import List, Optional

import typer
from typing_extensions import Annotated

from .errors import SkewpendError

app = typer.Typer(
    name="skewpend",
    help="The double pendulum with skewed hinge axes: derive its equations of motion.",
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


class UsageError(SkewpendError):
    """A malformed command-line value."""


# -- parsing of values --------------------------------------------------------------------------
_SYMBOLIC = ("sym", "symbolic")


def parse_scalar(text: Optional[str], option: str, *, angle: bool = False) -> Optional[float]:
    """A number; for angles radians or a ``deg`` suffix; ``sym`` leaves it symbolic (None)."""
    if text is None:
        return None
    t = text.strip().lower()
    if t in _SYMBOLIC:
        return None
    scale = 1.0
    if angle:
        for suffix in ("deg", "°"):
            if t.endswith(suffix):
                t, scale = t[: -len(suffix)].strip(), math.pi / 180
                break
    try:
        value = float(t)
    except ValueError:
        allowed = "a number in radians or with a deg suffix (e.g. 30deg)" if angle else "a number"
        raise UsageError(f"{option}: expected {allowed}, or 'sym' for symbolic; got {text!r}") from None
    if not math.isfinite(value):
        raise UsageError(f"{option}: expected a finite number, got {text!r}")
    return value * scale


def parse_vector(text: Optional[str], option: str, sizes=(3,)) -> Optional[List[float]]:
    """Comma-separated numbers, e.g. ``0,0.4,0``."""
    if text is None:
        return None
    try:
        values = [float(x) for x in text.replace(" ", "").split(",") if x != ""]
    except ValueError:
        raise UsageError(f"{option}: expected {' or '.join(map(str, sizes))} comma-separated numbers, got {text!r}") from None
    if len(values) not in sizes:
        raise UsageError(f"{option}: expected {' or '.join(map(str, sizes))} comma-separated numbers, got {len(values)}")
    if not all(math.isfinite(v) for v in values):
        raise UsageError(f"{option}: expected finite numbers, got {text!r}")
    return values


def parse_inertia(text: Optional[str], option: str):
    """``Ixx,Iyy,Izz`` (principal, body axes) or ``Ixx,Iyy,Izz,Ixy,Ixz,Iyz`` or 9 entries."""
    v = parse_vector(text, option, sizes=(3, 6, 9))
    if v is None:
        return None
    if len(v) == 3:
        return [[v[0], 0, 0], [0, v[1], 0], [0, 0, v[2]]]
    if len(v) == 6:
        xx, yy, zz, xy, xz, yz = v
        return [[xx, xy, xz], [xy, yy, yz], [xz, yz, zz]]
    return [v[0:3], v[3:6], v[6:9]]


# -- shared options -----------------------------------------------------------------------------------
_P = "Model parameters (a number, or 'sym' for symbolic; default symbolic)"
_G = "General bodies and axes (default: the specification's thin rods)"
A = Annotated[Optional[str], typer.Option("--a", help="length of rod 1 [m]", rich_help_panel=_P)]
B = Annotated[Optional[str], typer.Option("--b", help="length of rod 2 [m]", rich_help_panel=_P)]
M1 = Annotated[Optional[str], typer.Option("--m1", help="mass of rod 1 [kg]", rich_help_panel=_P)]
M2 = Annotated[Optional[str], typer.Option("--m2", help="mass of rod 2 [kg]", rich_help_panel=_P)]
ALPHA = Annotated[Optional[str], typer.Option("--alpha", help="skew angle of the hinges [rad, or e.g. 30deg]", rich_help_panel=_P)]
GRAV = Annotated[Optional[str], typer.Option("--g", help="gravitational acceleration [m/s^2]", rich_help_panel=_P)]
C1 = Annotated[str, typer.Option("--c1", help="viscous damping in hinge 1 [N m s] (default 0)", rich_help_panel=_P)]
C2 = Annotated[str, typer.Option("--c2", help="viscous damping in hinge 2 [N m s] (default 0)", rich_help_panel=_P)]
TAU1 = Annotated[str, typer.Option("--tau1", help="constant torque in hinge 1 [N m] (default 0)", rich_help_panel=_P)]
TAU2 = Annotated[str, typer.Option("--tau2", help="constant torque in hinge 2 [N m] (default 0)", rich_help_panel=_P)]
COM1 = Annotated[Optional[str], typer.Option("--com1", help="centre of mass of body 1, 'x,y,z' in its frame [m]", rich_help_panel=_G)]
COM2 = Annotated[Optional[str], typer.Option("--com2", help="centre of mass of body 2, 'x,y,z' in its frame [m]", rich_help_panel=_G)]
IN1 = Annotated[Optional[str], typer.Option("--inertia1", help="inertia of body 1 about its centre of mass: 'Ixx,Iyy,Izz[,Ixy,Ixz,Iyz]' [kg m^2]", rich_help_panel=_G)]
IN2 = Annotated[Optional[str], typer.Option("--inertia2", help="inertia of body 2 about its centre of mass: 'Ixx,Iyy,Izz[,Ixy,Ixz,Iyz]' [kg m^2]", rich_help_panel=_G)]
AX1 = Annotated[Optional[str], typer.Option("--axis1", help="axis of hinge 1, 'x,y,z' (default k)", rich_help_panel=_G)]
AX2 = Annotated[Optional[str], typer.Option("--axis2", help="axis of hinge 2 with the rods vertical, 'x,y,z' (default cos(alpha) k + sin(alpha) i; replaces --alpha)", rich_help_panel=_G)]


def build_parameters(a, b, m1, m2, alpha, g, c1, c2, tau1, tau2, com1, com2, inertia1, inertia2, axis1, axis2):
    """Parameters from command-line strings (validated; errors are SkewpendError)."""
    from .model import Parameters

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


class DeriveFormat(str, Enum):
    text = "text"
    latex = "latex"
    json = "json"
    python = "python"
    c = "c"
    javascript = "javascript"


@app.command()
def derive(
    a: A = None,
    b: B = None,
    m1: M1 = None,
    m2: M2 = None,
    alpha: ALPHA = None,
    g: GRAV = None,
    c1: C1 = "0",
    c2: C2 = "0",
    tau1: TAU1 = "0",
    tau2: TAU2 = "0",
    com1: COM1 = None,
    com2: COM2 = None,
    inertia1: IN1 = None,
    inertia2: IN2 = None,
    axis1: AX1 = None,
    axis2: AX2 = None,
    linear: Annotated[bool, typer.Option("--linear", help="add the equations linearised about phi = psi = 0")] = False,
    steps: Annotated[bool, typer.Option("--steps", help="print the derivation step by step (P1, e, P, omega2, v_c, Theta2, T, Pi)")] = False,
    fmt: Annotated[DeriveFormat, typer.Option("--format", "-f", help="output format: equations (text, latex, json) or generated code (python, c, javascript)")] = DeriveFormat.text,
) -> None:
    """Derive the equations of motion M(q) q'' = f(q, q') by the specification's method."""
    params = build_parameters(a, b, m1, m2, alpha, g, c1, c2, tau1, tau2, com1, com2, inertia1, inertia2, axis1, axis2)
    if fmt in (DeriveFormat.python, DeriveFormat.c, DeriveFormat.javascript):
        from .codegen import generate

        if linear or steps:
            raise UsageError("--linear and --steps go with --format text|latex|json, not with generated code")
        sys.stdout.write(generate(params, fmt.value))
        return
    from .derivation import derive as derive_eom
    from . import render

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
    "simulation": {"t_end": 20.0, "method": "dop853", "rtol": 1e-10, "atol": 1e-10},
}


def _as_text(value) -> Optional[str]:
    """A config value in the command line's spelling (numbers, '30deg', vectors, matrices)."""
    if value is None:
        return None
    if isinstance(value, bool):
        raise UsageError(f"expected a number, got {value!r}")
    if isinstance(value, (list, tuple)):
        flat = []
        for v in value:
            flat.extend(v if isinstance(v, (list, tuple)) else [v])
        return ",".join(repr(float(x)) if isinstance(x, (int, float)) else str(x) for x in flat)
    return value if isinstance(value, str) else repr(value)


class Method(str, Enum):
    dop853 = "dop853"
    rk4 = "rk4"
    gauss = "gauss"


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


def _resolve(config: Optional[str], parameters: dict, initial: dict, simulation: dict):
    """Numeric parameters, initial state and run settings: built-in defaults, then the
    config file, then command-line options."""
    from .io import read_config

    run = {k: dict(v) for k, v in DEFAULT_RUN.items()}
    if config is not None:
        for section, values in read_config(config).items():
            run[section].update(values)
    for section, values in (("parameters", parameters), ("initial", initial), ("simulation", simulation)):
        run[section].update({k: v for k, v in values.items() if v is not None})
    P, I, S = (run[k] for k in ("parameters", "initial", "simulation"))
    t = {k: _as_text(v) for k, v in P.items()}
    zero = "0"
    params = build_parameters(
        t.get("a"), t.get("b"), t.get("m1"), t.get("m2"), t.get("alpha"), t.get("g"),
        t.get("c1", zero), t.get("c2", zero), t.get("tau1", zero), t.get("tau2", zero),
        t.get("com1"), t.get("com2"), t.get("inertia1"), t.get("inertia2"), t.get("axis1"), t.get("axis2"),
    )
    y0 = [
        parse_scalar(_as_text(I["phi0"]), "--phi0", angle=True),
        parse_scalar(_as_text(I["psi0"]), "--psi0", angle=True),
        parse_scalar(_as_text(I["dphi0"]), "--dphi0"),
        parse_scalar(_as_text(I["dpsi0"]), "--dpsi0"),
    ]
    if any(v is None for v in y0):
        raise UsageError("the initial state must be numeric (not 'sym')")
    return params, y0, S


def _setting(S: dict, key: str, option: str) -> Optional[float]:
    return None if S.get(key) is None else parse_scalar(_as_text(S[key]), option)


@app.command()
def simulate(
    a: A = None,
    b: B = None,
    m1: M1 = None,
    m2: M2 = None,
    alpha: ALPHA = None,
    g: GRAV = None,
    c1: C1R = None,
    c2: C2R = None,
    tau1: TAU1R = None,
    tau2: TAU2R = None,
    com1: COM1 = None,
    com2: COM2 = None,
    inertia1: IN1 = None,
    inertia2: IN2 = None,
    axis1: AX1 = None,
    axis2: AX2 = None,
    phi0: PHI0 = None,
    psi0: PSI0 = None,
    dphi0: DPHI0 = None,
    dpsi0: DPSI0 = None,
    t_end: Annotated[Optional[str], typer.Option("--t-end", help="duration [s] (default 20)", rich_help_panel=_R)] = None,
    dt_out: Annotated[Optional[str], typer.Option("--dt-out", help="output interval [s] (default: the integrator's own steps)", rich_help_panel=_R)] = None,
    method: Annotated[Optional[Method], typer.Option("--method", help="integrator (default dop853)", rich_help_panel=_R)] = None,
    rtol: Annotated[Optional[str], typer.Option("--rtol", help="relative tolerance, dop853 (default 1e-10)", rich_help_panel=_R)] = None,
    atol: Annotated[Optional[str], typer.Option("--atol", help="absolute tolerance, dop853 (default 1e-10)", rich_help_panel=_R)] = None,
    dt: Annotated[Optional[str], typer.Option("--dt", help="step [s] for rk4 and gauss (default 1e-3)", rich_help_panel=_R)] = None,
    out: Annotated[Optional[str], typer.Option("--out", "-o", help="write the trajectory to FILE (.csv or .nc)", rich_help_panel=_R)] = None,
    config: CONFIG = None,
) -> None:
    """Simulate the nonlinear equations of motion; print a summary or write a trajectory file."""
    params, y0, S = _resolve(
        config,
        dict(a=a, b=b, m1=m1, m2=m2, alpha=alpha, g=g, c1=c1, c2=c2, tau1=tau1, tau2=tau2,
             com1=com1, com2=com2, inertia1=inertia1, inertia2=inertia2, axis1=axis1, axis2=axis2),
        dict(phi0=phi0, psi0=psi0, dphi0=dphi0, dpsi0=dpsi0),
        dict(t_end=t_end, dt_out=dt_out, method=method.value if method else None, rtol=rtol, atol=atol, dt=dt, out=out),
    )
    method_name = str(S.get("method", "dop853"))
    from .integrate import METHODS, simulate as run_simulation

    if method_name not in METHODS:
        raise UsageError(f"--method: expected one of {', '.join(METHODS)}, got {method_name!r}")
    out_path = S.get("out")
    if out_path is not None and not str(out_path).lower().endswith((".csv", ".nc")):
        raise UsageError(f"--out: expected a file name ending in .csv or .nc, got {out_path!r}")
    traj = run_simulation(
        params, y0, _setting(S, "t_end", "--t-end"),
        dt_out=_setting(S, "dt_out", "--dt-out"), method=method_name,
        rtol=_setting(S, "rtol", "--rtol"), atol=_setting(S, "atol", "--atol"),
        dt=_setting(S, "dt", "--dt"),
    )
    if not traj.success:
        sys.stderr.write(f"skewpend: simulation {traj.message} at t = {traj.t[-1]:.6g} s; no file written\n")
        sys.exit(1)
    if out_path is not None:
        from .io import write_trajectory

        write_trajectory(traj, out_path)
    _summary(traj, out_path)


class ExportFormat(str, Enum):
    mjcf = "mjcf"
    urdf = "urdf"


@app.command()
def export(
    fmt: Annotated[ExportFormat, typer.Option("--format", "-f", help="model format")] = ExportFormat.mjcf,
    out: Annotated[Optional[str], typer.Option("--out", "-o", help="write to FILE (default: print)")] = None,
    a: A = None,
    b: B = None,
    m1: M1 = None,
    m2: M2 = None,
    alpha: ALPHA = None,
    g: GRAV = None,
    c1: C1R = None,
    c2: C2R = None,
    tau1: TAU1R = None,
    tau2: TAU2R = None,
    com1: COM1 = None,
    com2: COM2 = None,
    inertia1: IN1 = None,
    inertia2: IN2 = None,
    axis1: AX1 = None,
    axis2: AX2 = None,
    config: CONFIG = None,
) -> None:
    """Export the system as a MuJoCo MJCF model or a URDF (numeric parameters; the defaults of simulate)."""
    from . import export as ex

    params, _, _ = _resolve(
        config,
        dict(a=a, b=b, m1=m1, m2=m2, alpha=alpha, g=g, c1=c1, c2=c2, tau1=tau1, tau2=tau2,
             com1=com1, com2=com2, inertia1=inertia1, inertia2=inertia2, axis1=axis1, axis2=axis2),
        {}, {},
    )
    if out is None:
        sys.stdout.write(ex.to_mjcf(params) if fmt is ExportFormat.mjcf else ex.to_urdf(params))
        return
    path = ex.write_model(params, out, fmt.value)
    sys.stderr.write(f"skewpend: wrote {fmt.value.upper()} model to {path}\n")


@app.command()
def validate(
    a: A = None,
    b: B = None,
    m1: M1 = None,
    m2: M2 = None,
    alpha: ALPHA = None,
    g: GRAV = None,
    c1: C1R = None,
    c2: C2R = None,
    tau1: TAU1R = None,
    tau2: TAU2R = None,
    com1: COM1 = None,
    com2: COM2 = None,
    inertia1: IN1 = None,
    inertia2: IN2 = None,
    axis1: AX1 = None,
    axis2: AX2 = None,
    phi0: PHI0 = None,
    psi0: PSI0 = None,
    dphi0: DPHI0 = None,
    dpsi0: DPSI0 = None,
    t_end: Annotated[str, typer.Option("--t-end", help="duration [s]", rich_help_panel=_R)] = "2",
    dt: Annotated[str, typer.Option("--dt", help="MuJoCo RK4 step [s]", rich_help_panel=_R)] = "1e-4",
    tol: Annotated[str, typer.Option("--tol", help="largest allowed difference in any state component", rich_help_panel=_R)] = "1e-6",
    config: CONFIG = None,
) -> None:
    """Compare skewpend with MuJoCo (the exported MJCF, RK4) for your parameters; exit 1 if they disagree."""
    from .validation import compare_with_mujoco

    params, y0, _ = _resolve(
        config,
        dict(a=a, b=b, m1=m1, m2=m2, alpha=alpha, g=g, c1=c1, c2=c2, tau1=tau1, tau2=tau2,
             com1=com1, com2=com2, inertia1=inertia1, inertia2=inertia2, axis1=axis1, axis2=axis2),
        dict(phi0=phi0, psi0=psi0, dphi0=dphi0, dpsi0=dpsi0),
        {},
    )
    tolerance = parse_scalar(tol, "--tol")
    report = compare_with_mujoco(params, y0, parse_scalar(t_end, "--t-end"), dt=parse_scalar(dt, "--dt"))
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


def _summary(traj, out_path) -> None:
    y = traj.final_state
    st = traj.stats
    lines = [
        f"method        {traj.method}  ({', '.join(f'{k}={v:g}' for k, v in traj.settings.items() if isinstance(v, float))})",
        f"status        {traj.message}",
        f"final state   t={traj.t[-1]:.6g} s  phi={y[0]:.12g}  psi={y[1]:.12g}  dphi={y[2]:.12g}  dpsi={y[3]:.12g}",
        f"energy        E0={traj.energy[0]:.12g} J  E={traj.energy[-1]:.12g} J  work of Q={traj.work[-1]:.6g} J",
        f"energy drift  {traj.energy_drift:.3e} (max |E - W - E0| / max |E|)",
        f"steps         {st['steps']} accepted, {st['rejected']} rejected, {st['nfev']} evaluations",
        f"wall time     {st['wall_time'] * 1e3:.2f} ms (compiled integration"
        + ("; includes loading/compiling the machine code on first use)" if st.get("includes_jit_load") else ")"),
    ]
    if out_path is not None:
        lines.append(f"written       {out_path} ({traj.t.size} rows)")
    sys.stdout.write("\n".join(lines) + "\n")


def _fail(message: str) -> None:
    sys.stderr.write(f"skewpend: error: {message}\n")
    sys.exit(2)


def main(argv: Optional[List[str]] = None) -> None:
    """Entry point: run the app; user mistakes become one line on stderr and exit status 2."""
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
        if kind == "Abort":
            sys.stderr.write("skewpend: aborted\n")
            sys.exit(130)
        if getattr(exc, "exit_code", None) == 2 and hasattr(exc, "format_message"):
            ctx = getattr(exc, "ctx", None)
            where = f"skewpend {ctx.info_name}" if ctx is not None and ctx.parent is not None else "skewpend"
            _fail(f"{exc.format_message().strip()} (see '{where} --help')")
        raise
    sys.exit(result if isinstance(result, int) else 0)


if __name__ == "__main__":  # pragma: no cover
    main()
