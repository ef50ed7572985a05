"""``derive`` (the equations of motion, or generated code), ``export`` (MJCF/URDF) and
``validate`` (against MuJoCo)."""

from __future__ import annotations

import sys
from enum import Enum
from typing import Annotated, Optional

import typer

from ..parsing import UsageError
from . import types as T
from .options import CONFIG, INITIAL, MODEL, command, option, resolve

COMMANDS = ("derive", "export", "validate")


class Coulomb(str, Enum):
    exclude = "exclude"
    smoothed = "smoothed"


class DeriveFormat(str, Enum):
    text = "text"
    latex = "latex"
    json = "json"
    python = "python"
    c = "c"
    javascript = "javascript"


_CODE = ("python", "c", "javascript")


@command(MODEL)
def derive(
    model: dict,
    linear: Annotated[bool, typer.Option("--linear", help="add the equations linearised about phi = psi = 0")] = False,
    steps: Annotated[bool, typer.Option("--steps", help="print the derivation step by step (P1, e, P, omega2, v_c, Theta2, T, Pi)")] = False,
    fmt: Annotated[DeriveFormat, typer.Option("--format", "-f", help="output format: equations (text, latex, json) or generated code (python, c, javascript)")] = DeriveFormat.text,
    coulomb: Annotated[Optional[Coulomb], typer.Option("--coulomb", help="with --linear: Coulomb friction (cf1, cf2) left out of C0 (exclude, the default: non-smooth at rest) or linearised by its smoothed slope cfs*cf (smoothed)")] = None,
    config: CONFIG = None,
) -> None:
    """Derive the equations of motion M(q) q'' = f(q, q') by the specification's method.

    From a --config run file it takes [parameters] (the values it gives; the others stay symbolic),
    or a chain of links ([[links]], [chain]): its equations by the same method, and its code (--format c: the
    kernels' recursive algorithms; python, javascript: standalone modules from the same graphs).
    """
    run = resolve("derive", config, defaults=False, parameters=model)
    params = run.parameters()
    if coulomb is not None and not linear:
        raise UsageError("--coulomb sets how Coulomb friction enters the linearised equations; give it with --linear")
    if fmt.value in _CODE:
        if linear or steps:
            raise UsageError("--linear and --steps go with --format text|latex|json, not with generated code")
        sys.stdout.write(_code(run, params, fmt.value))
        return
    _check_symbolic_size(run, params)
    from ..symbolic import render
    from ..symbolic.derivation import derive as derive_eom

    from ..errors import EquilibriumError

    eom = derive_eom(params)
    try:
        lin = eom.linearize("exclude" if coulomb is None else coulomb.value) if linear else None
    except EquilibriumError as exc:  # the library names about='down-down', which derive does not have
        raise EquilibriumError(f"--linear: {str(exc).split(';')[0]}; derive --linear linearises about phi = psi = 0 only "
                               "(skewpend modes takes a model's modes about its hanging rest)") from None
    if fmt is DeriveFormat.json:
        import json

        text = json.dumps(render.to_json(eom, linear=lin, steps=steps), indent=2) + "\n"
    else:
        text = (render.to_latex if fmt is DeriveFormat.latex else render.to_text)(eom, linear=lin, steps=steps)
    sys.stdout.write(text)


#: From this many links on, derive says up front how long the exact symbolic equations take.
_SYMBOLIC_NOTE_LINKS = 5


def _duration(seconds: float) -> str:
    if seconds > 365 * 86400.0:
        return "more than a year"
    for unit, size in (("days", 86400.0), ("hours", 3600.0), ("min", 60.0)):
        if seconds >= 1.5 * size or unit == "min" and seconds >= 60:
            return f"about {seconds / size:.0f} {unit}"
    return f"about {seconds:.0f} s"


def _check_symbolic_size(run, chain) -> None:
    """The exact symbolic equations of a long chain take minutes to days (about five-fold a link): said up
    front from 5 links, refused beyond :data:`~skewpend.symbolic.chain.SYMBOLIC_LINKS_MAX`, the code named."""
    from ..symbolic.chain import SYMBOLIC_GROWTH, SYMBOLIC_LINKS_MAX, symbolic_seconds

    n = chain.n
    if n < _SYMBOLIC_NOTE_LINKS:
        return
    estimate = _duration(symbolic_seconds(n))
    code = "--format c|python|javascript prints the chain's equations as code from the recursive algorithms at once"
    if n > SYMBOLIC_LINKS_MAX:
        raise UsageError(f"{run.links_source()}: the exact symbolic equations of a chain of {n} links would take "
                         f"{estimate} on a 2-core machine (they grow about {SYMBOLIC_GROWTH:g}-fold a link; derive prints them up to "
                         f"{SYMBOLIC_LINKS_MAX} links); {code}")
    sys.stderr.write(f"skewpend: note: the exact symbolic equations of a chain of {n} links take {estimate} on a 2-core machine "
                     f"(about {SYMBOLIC_GROWTH:g}-fold a link); {code}\n")


def _code(run, model, fmt: str) -> str:
    """The model's code in ``fmt``: its exact derivation's standalone module where it has one (the double pendulum's
    parameters, :func:`~skewpend.numeric.codegen.generate`), else the recursive algorithms' (C: the kernels' own)."""
    exact = model.exact_model()
    if exact is None:
        from ..numeric.recursive import chain_code, chain_source, structure_of_chain

        return chain_source(structure_of_chain(model)) if fmt == "c" else chain_code(model, fmt)
    _check_code_parameters(run, exact, fmt)
    from ..numeric.codegen import generate

    return generate(exact, fmt)


def _check_code_parameters(run, params, fmt: str) -> None:
    """Numeric values become the code's default parameter vector P, all of them or none; a typed
    parameter beyond the core ones (--c1, --tau1, --cf1, --Ir, ...: the schema's scalars with a
    default; or one in the run file) needs that vector."""
    from ..schema import CORE_NAMES, OPTIONAL_DEFAULTS

    typed = [run.option("parameters", k) for k in OPTIONAL_DEFAULTS
             if run.is_given("parameters", k) and getattr(params, k) is not None]
    core = [f"--{k}" for k in CORE_NAMES if k != "alpha" or params.uses_alpha]
    if typed and all(getattr(params, k[2:]) is None for k in core):
        raise UsageError(
            f"{', '.join(typed)} with --format {fmt} needs {' '.join(core)} as numbers too (all become the "
            f"code's default parameter vector P); give them, or leave out {', '.join(typed)} (p is supplied at run time)"
        )


class ExportFormat(str, Enum):
    mjcf = "mjcf"
    urdf = "urdf"


@command(MODEL)
def export(
    model: dict,
    fmt: Annotated[Optional[ExportFormat], typer.Option("--format", "-f", help="model format (default: from the --out suffix, .xml/.mjcf or .urdf; mjcf when printing)")] = None,
    out: Annotated[Optional[str], typer.Option("--out", "-o", help="write to FILE (default: print)")] = None,
    config: CONFIG = None,
) -> None:
    """Export the system as a MuJoCo MJCF model or a URDF (numeric parameters; the defaults of simulate).

    From a --config run file it takes [parameters]; or a chain of links ([[links]], [chain], or --links N); a
    [motor] becomes its joint's voltage-driven actuator (MJCF) or effort limit (URDF).
    """
    from ..interop import export as ex

    run = resolve("export", config, parameters=model)
    params = run.parameters()  # a [motor]'s back-EMF in its joint's damping; its voltage input the motor's actuator
    if out is None:
        sys.stdout.write(ex.to_urdf(params, motor=run.motor) if fmt is ExportFormat.urdf else
                         ex.to_mjcf(params, motor=run.motor))
        return
    path = ex.write_model(params, out, fmt.value if fmt else None, motor=run.motor)
    kind = fmt.value if fmt else ("urdf" if path.suffix.lower() == ".urdf" else "mjcf")
    sys.stderr.write(f"skewpend: wrote {kind.upper()} model to {path}\n")


@command(MODEL, INITIAL)
def validate(
    model: dict,
    initial: dict,
    t_end: option("--t-end", T.Positive("number of seconds"), "duration [s] (default 2)") = None,
    dt: option("--dt", T.Positive("number of seconds"), "MuJoCo RK4 step [s] (default 1e-4)") = None,
    tol: option("--tol", T.Positive(), "largest allowed difference in any state component (default 1e-6)") = None,
    config: CONFIG = None,
) -> None:
    """Compare skewpend with MuJoCo (the exported MJCF, RK4) for your parameters; exit 1 if they disagree.

    From a --config run file it takes [parameters], [initial] and [simulation] t_end; or a chain of links
    ([[links]], [chain], or --links N; its start --q0 --dq0).
    """
    from ..interop.validation import compare_with_mujoco

    run = resolve("validate", config, parameters=model, initial=initial, simulation={"t_end": t_end})
    params, y0 = run.parameters(), run.initial_state()
    report = compare_with_mujoco(params, y0, **run.settings(("t_end",)), **({} if dt is None else {"dt": dt}))
    tolerance = 1e-6 if tol is None else tol
    ok = report.max_difference <= tolerance
    sys.stdout.write("\n".join([
        f"skewpend (dop853, rtol=atol=1e-12) vs MuJoCo {report.mujoco_version} (RK4, dt={report.dt:g} s), {report.t_end:g} s, {report.samples} samples",
        "max |difference|:  " + "  ".join(f"{k}={v:.2e}" for k, v in report.max_abs_diff.items()),
        f"energy drift: skewpend {report.energy_drift:.1e}",
        ("AGREE" if ok else "DISAGREE") + f" within {tolerance:g} (largest difference {report.max_difference:.2e})",
    ]) + "\n")
    return _Verdict(ok, f"skewpend and MuJoCo differ by {report.max_difference:.2e}, more than --tol {tolerance:g}")


class _Verdict:
    """A comparison's outcome in the result protocol's terms (``ok``, ``message``)."""

    def __init__(self, ok: bool, message: str) -> None:
        self.ok, self.message = ok, message
