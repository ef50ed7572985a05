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
    fmt: Annotated[DeriveFormat, typer.Option("--format", "-f", help="output format")] = DeriveFormat.text,
) -> None:
    """Derive the equations of motion M(q) q'' = f(q, q') by the specification's method."""
    params = build_parameters(a, b, m1, m2, alpha, g, c1, c2, tau1, tau2, com1, com2, inertia1, inertia2, axis1, axis2)
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
