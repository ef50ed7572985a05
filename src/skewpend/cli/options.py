"""The options the commands share, declared once, and :func:`command`, which gives a command its
option groups and parses every value with its type (:mod:`skewpend.cli.types`) before it runs.

Option groups: :data:`MODEL` (the parameters of the model), :data:`INITIAL` (the initial state),
:data:`INTEGRATION` (method, tolerances, step, step cap) and :data:`ENSEMBLE` (workers and a
cluster).  A command declares the groups it takes with ``@command(MODEL, INITIAL)`` and receives
them collected, by name, in its ``model`` / ``initial`` / ``integration`` / ``ensemble``
argument (only the values given; None for the others).
"""

from __future__ import annotations

import dataclasses
import functools
import re
import inspect
import sys
from enum import Enum
from typing import Annotated, Any, Dict, Optional

import typer

from . import types as T
from .. import schema
from ..checks import ATOL_MIN, RTOL_MIN
from ..numeric.conventions import ADAPTIVE as _ADAPTIVE, METHODS as _METHODS

_P = "Model parameters (a number, or 'sym' for symbolic; default symbolic)"
_G = "General bodies and axes (default: the specification's thin rods)"
RUN = "Initial state and run"


def option(flag: str, kind: T.ParamType, help: str, panel: str = RUN, *aliases: str):
    """An option typed as text whose value ``kind`` parses (None when not given)."""
    return Annotated[Optional[str], typer.Option(flag, *aliases, help=help, metavar=kind.metavar, rich_help_panel=panel), kind]


def _model_option(name: str):
    """The option ``--name`` of the model's parameter ``name``, from the schema: its type by the
    field's kind and bound, its help, its panel (scalars, or the bodies' and axes' geometry)."""
    f = schema.field(name)
    if f.kind == "inertia":
        kind: T.ParamType = T.Inertia()
    elif f.kind == "vector":
        kind = T.Vector()
    else:
        kind = T.Angle() if f.bound == "angle" else T.Scalar()
    return option(f"--{name}", kind, schema.help_text(name), _P if f.kind == "scalar" else _G)


_L = "A chain of links (each value one for every link, or one a link; a run file's [[links]] too)"


def _link_default(key: str) -> str:
    """What a link's ``key`` is when not given (the Link's own default; None: the thin rod's)."""
    from ..symbolic.chain import Link

    value = next(f.default for f in dataclasses.fields(Link) if f.name == key)
    if value is None:  # the hinge at the end of the parent's rod; the centre of mass and inertia a thin rod's
        return "the parent rod's end" if next(stem for k, stem, _ in schema.LINK_FIELDS if k == key) == "h" else "the thin rod's"
    return ",".join(f"{x:g}" for x in value) if isinstance(value, tuple) else f"{value:g}"


def _link_help(key: str, kind: str) -> str:
    form = {"scalar": "", "vector": "x,y,z, ", "inertia": "Ixx,Iyy,Izz[,Ixy,Ixz,Iyz], "}[kind]
    return (f"each link's {key} ({form}{'a comma' if kind == 'scalar' else 'a semicolon'} between links; "
            f"default {_link_default(key)})")


#: A chain of links given on the command line: ``--links N`` and each field of the schema's links as
#: ``--link-FIELD`` (one value for every link, or one a link), the chain's g as ``--g``.
LINK_OPTIONS: Dict[str, Any] = {
    "links": option("--links", T.Whole(1, schema.MAX_LINKS), "a chain of N links (default: the double pendulum, or a run file's "
                                               "[[links]]; the double pendulum's --a, --m1, ... do not apply to it)", _L),
    **{f"link_{key}": option(f"--link-{key}", T.PerLink(kind, most=schema.MAX_LINKS), _link_help(key, kind), _L)
       for key, _, kind in schema.LINK_FIELDS},
}

#: The model's options (every command but serve), in the schema's order: the scalars, then the geometry; then
#: a chain's (:data:`LINK_OPTIONS`: a command that takes no chain refuses them in one line).
MODEL: Dict[str, Any] = {**{name: _model_option(name) for name in schema.SCALAR_NAMES + schema.GEOMETRY_NAMES},
                         **LINK_OPTIONS}
#: The model without the constant torques (modes: the hanging rest is no equilibrium with them).
_TORQUE_KEY = next(key for key, stem, _ in schema.LINK_FIELDS if stem == "tau")
MODEL_NO_TORQUE = {k: v for k, v in MODEL.items() if k not in schema.TORQUE_NAMES and k != f"link_{_TORQUE_KEY}"}

#: The initial state.
INITIAL: Dict[str, Any] = {
    "phi0": option("--phi0", T.Angle("ANGLE"), "initial phi [rad, or e.g. 60deg] (default 1.2)"),
    "psi0": option("--psi0", T.Angle("ANGLE"), "initial psi [rad, or deg] (default -0.8)"),
    "dphi0": option("--dphi0", T.Scalar("NUMBER"), "initial dphi/dt [rad/s] (default 0)"),
    "dpsi0": option("--dpsi0", T.Scalar("NUMBER"), "initial dpsi/dt [rad/s] (default 0)"),
    "q0": option("--q0", T.Angles(most=schema.MAX_LINKS), "a chain's initial angles, one a link [rad, or deg] (default 0.5 each)"),
    "dq0": option("--dq0", T.Numbers(most=schema.MAX_LINKS), "a chain's initial rates, one a link [rad/s] (default 0)"),
}


#: The integrators of ``simulate`` (the library's list: ``skewpend.numeric.simulation.METHODS``).
Method = Enum("Method", {m: m for m in ("auto",) + tuple(_METHODS)}, type=str)  # type: ignore[misc]


#: The integrator (simulate, animate, report).
INTEGRATION: Dict[str, Any] = {
    "method": Annotated[Optional[Method], typer.Option("--method", help="integrator: auto (simulate's default: taylor, or dop853 for a controller's inputs), dop853 (the default of animate and report), rk4, gauss (fixed step --dt), taylor", rich_help_panel=RUN)],
    "rtol": option("--rtol", T.Positive(at_least=RTOL_MIN), f"relative tolerance, {' and '.join(_ADAPTIVE)} only (default 1e-10)"),
    "atol": option("--atol", T.Positive(at_least=ATOL_MIN), f"absolute tolerance, {' and '.join(_ADAPTIVE)} only (default 1e-10)"),
    "dt": option("--dt", T.Positive("number of seconds"), "step [s], rk4 and gauss only (default 1e-3)"),
    "max_steps": option("--max-steps", T.Whole(1, 10**15), "refuse or stop a run that needs more steps (default 1e8)"),
}


def tolerances(default: str) -> Dict[str, Any]:
    """rtol and atol of the DOP853-only analyses (``default`` is the library's, for the help)."""
    return {
        "rtol": option("--rtol", T.Positive(at_least=RTOL_MIN), f"relative tolerance of DOP853 (default {default})"),
        "atol": option("--atol", T.Positive(at_least=ATOL_MIN), f"absolute tolerance of DOP853 (default {default})"),
    }


#: Threads here or a cluster (flipmap, chaos-diagram).
ENSEMBLE: Dict[str, Any] = {
    "workers": option("--workers", T.Whole(1, 1024), "threads on this machine (default: every core)"),
    "scheduler": option("--scheduler", T.Scheduler(), "run on a dask.distributed cluster: tcp://HOST:PORT (needs skewpend[cluster])"),
}

CONFIG = Annotated[Optional[str], typer.Option("--config", metavar="FILE", help="TOML run file with [parameters], [initial], [simulation]; options override it; a key this command does not read is refused", rich_help_panel=RUN)]
QUIET = Annotated[bool, typer.Option("--quiet", "-q", help="say nothing while working (on a terminal a live line with the stage, a bar and the time; otherwise a line per stage on stderr)", rich_help_panel=RUN)]


def plot_option(what: str):
    return option("--plot", T.OutPath("..views.figures:FIGURE_SUFFIXES"), f"draw {what} to FILE (.png, .svg or .pdf)")


_GROUPS = {id(MODEL): "model", id(MODEL_NO_TORQUE): "model", id(INITIAL): "initial", id(INTEGRATION): "integration",
           id(ENSEMBLE): "ensemble"}


def _kind(annotation) -> Optional[T.ParamType]:
    return next((m for m in getattr(annotation, "__metadata__", ()) if isinstance(m, T.ParamType)), None)


def _flag(annotation, name: str) -> str:
    info = next((m for m in getattr(annotation, "__metadata__", ()) if hasattr(m, "param_decls")), None)
    decls = [d for d in (getattr(info, "param_decls", None) or ()) if d.startswith("--")]
    return decls[0] if decls else "--" + name.replace("_", "-")


#: What each command does first, said for it if it names no stage of its own within
#: :data:`skewpend.progress.GRACE` seconds (its checks and imports; the stages it names follow).
FIRST_STAGE = {
    "derive": "deriving the equations of motion", "export": "building the model", "validate": "comparing with MuJoCo",
    "simulate": "preparing the run", "animate": "preparing the run", "report": "checking the inputs",
    "modes": "computing the normal modes", "equilibria": "finding the equilibria", "orbit": "preparing the orbit",
    "nnm": "preparing the continuation", "serve": "starting the explorer", "identify": "reading the data",
    "control": "designing the controller", "flipmap": "preparing the flip map", "lyapunov": "preparing the run",
    "poincare": "preparing the section", "chaos-diagram": "preparing the diagram",
}
#: Commands that say their stages as lines on a terminal too (a server's console is a log: a live
#: line would stay under its address line while it serves).
LINES_ONLY = frozenset({"serve"})
#: When the process running the command line as its program started (``time.monotonic()``; set by
#: :func:`skewpend.cli.main`, None when a program calls ``main(argv)``): its first stage is said by
#: :data:`skewpend.progress.FIRST_BY` seconds after it.
PROGRAM_STARTED: Optional[float] = None


def command(*groups: Dict[str, Any], **named: Dict[str, Any]):
    """Give a command the option ``groups`` (and a group of its own as ``name=group``: collected into its
    argument ``name``) and parse every typed value (see the module); a command
    without ``--quiet`` of its own gets it here.  The command runs inside its
    :class:`~skewpend.progress.Stages` (started before any heavy import: within a second of its
    start, the command says what it does; ``--quiet`` silences it)."""

    def decorate(func):
        sig = inspect.signature(func, eval_str=True)
        names = {**{_GROUPS[id(g)]: g for g in groups}, **named}
        own = [p for name, p in sig.parameters.items() if name not in names]
        extra = [
            inspect.Parameter(name, inspect.Parameter.POSITIONAL_OR_KEYWORD, default=None, annotation=ann)
            for group in names.values() for name, ann in group.items()
        ]
        takes_quiet = "quiet" in sig.parameters
        if not takes_quiet:
            own.append(inspect.Parameter("quiet", inspect.Parameter.KEYWORD_ONLY, default=False, annotation=QUIET))
        annotations = {p.name: p.annotation for p in extra + own}
        name = func.__name__.replace("_", "-")

        @functools.wraps(func)
        def run(**kwargs):
            from ..progress import Stages

            quiet = bool(kwargs.get("quiet")) if takes_quiet else bool(kwargs.pop("quiet", False))
            _NOTED.clear()  # a command's notes are said once per command
            for key, value in kwargs.items():
                kind = _kind(annotations.get(key))
                if kind is not None and value is not None:
                    kwargs[key] = kind.convert(value, _flag(annotations[key], key))
            for target, group in names.items():
                kwargs[target] = {k: kwargs.pop(k) for k in group if k in kwargs}
            if "integration" in kwargs and kwargs["integration"].get("method") is not None:
                kwargs["integration"]["method"] = kwargs["integration"]["method"].value
            with Stages(name, enabled=not quiet, first=FIRST_STAGE.get(name, "starting"), started=PROGRAM_STARTED,
                        terminal=False if name in LINES_ONLY else None):
                return func(**kwargs)

        run.__signature__ = sig.replace(parameters=extra + own)
        return run

    return decorate


#: The current command's names for the parameters the library's messages use (see
#: :func:`skewpend.cli.messages.locate`); filled by :func:`resolve`.
LOCATIONS: Dict[str, str] = {}


def resolve(command_name: str, config: Optional[str] = None, *, defaults: bool = True, flags=None, **sections):
    """The :class:`~skewpend.config.Run` of a command (defaults, run file, options); its
    locations are remembered for the messages, its notes (the run file's sections the command leaves
    aside) said once on stderr."""
    from ..config import Run

    run = Run(command_name, config, sections, defaults=defaults, flags=flags, read=_model_file(config))
    LOCATIONS.update(run.locations())
    for note in run.notes:
        if note not in _NOTED:
            _NOTED.add(note)
            sys.stderr.write(f"skewpend: note: {note}\n")
    return run


def _model_file(config: Optional[str]):
    """How a MuJoCo (``.xml``, ``.mjcf``) or URDF (``.urdf``) ``--config`` is read: into a chain's run-file sections,
    with the importer's notes and the model's actuators said once (None: a TOML run file)."""
    from pathlib import Path

    from ..interop.importer import MODEL_SUFFIXES

    if config is None or Path(config).suffix.lower() not in MODEL_SUFFIXES:
        return None

    def read(path):
        from ..interop.importer import read_model, run_sections

        model = read_model(path)
        _IMPORTED[str(path)] = model
        notes = list(model.notes)
        if model.actuated:
            limits = ", ".join(f"joint {k}" + (f" |u| <= {u:g} N m" if u is not None else "")
                               for k, u in zip(model.actuated, model.torque_limits))
            notes.append(f"actuators on {limits} (skewpend control drives these joints within these limits unless "
                         "--actuated or --umax is given)")
        return run_sections(model), notes

    return read


#: The notes said by the running command (one resolving its run twice says each once).
_NOTED: set = set()
#: The model files read by the running command (path -> ImportedModel): their actuators, for the commands that drive them.
_IMPORTED: dict = {}


def model_actuators(config: Optional[str]):
    """The actuated joints (1-based) and their torque limits [N m] (None: unlimited) of the MuJoCo or URDF model file
    ``config`` the command has read; None for a TOML run file, no file, or a model without actuators."""
    model = _IMPORTED.get(str(config)) if config is not None else None
    if model is None or not model.actuated:
        return None
    return tuple(model.actuated), tuple(model.torque_limits)


def progress(label: str, unit: str, quiet: bool):
    """The stage ``label`` of a long computation and its bar, a ``progress(done, total)`` callable:
    in a command, a stage of its :class:`~skewpend.progress.Stages` (said when its work begins -- its
    first progress call -- or after :data:`~skewpend.progress.GRACE` seconds; its bar moves on a
    terminal); elsewhere a :class:`~skewpend.progress.ProgressBar` (on a terminal, unless ``quiet``)."""
    from ..progress import ProgressBar, active

    stages = active()
    if stages is not None and not quiet:
        return stages.bar(label, unit)
    return ProgressBar(label, unit=unit, enabled=None if not quiet else False)


#: Commands whose model parameters stay symbolic when not given (the others start from the
#: reference case, :data:`skewpend.config.DEFAULT_RUN`), and those where one format keeps them so.
SYMBOLIC_MODEL = frozenset({"derive"})
SYMBOLIC_FORMAT = {"modes": "--format latex"}
#: Options whose absence needs no default: outputs (nothing written), a cluster (none: this machine).
_NO_DEFAULT = frozenset({"out", "plot", "animate", "export", "scheduler", "config"})


def show_defaults(group) -> Any:
    """Every option's help ends with its default (issue 29: the help showed none for the model's
    parameters, which the reference case fills in): the reference case's value of a model key, or
    'symbolic' for derive (and modes --format latex), or the option's own default; outputs and flags are left
    alone, as are options whose help already says its default or that it is required."""
    from ..config import DEFAULT_RUN

    reference = {**DEFAULT_RUN["parameters"]}
    for name, cmd in getattr(group, "commands", {}).items():
        if hasattr(cmd, "commands"):
            show_defaults(cmd)
            continue
        for p in cmd.params:
            help_text = getattr(p, "help", None)
            if help_text is None or getattr(p, "is_flag", False) or p.name in _NO_DEFAULT:
                continue
            if re.search(r"\bdefault\b|\brequired\b", help_text, re.IGNORECASE):
                continue
            if p.name in MODEL:
                if name in SYMBOLIC_MODEL:
                    value = "symbolic"
                elif p.name in reference:
                    value = f"{reference[p.name]:g}"
                    if name in SYMBOLIC_FORMAT:
                        value += f"; symbolic with {SYMBOLIC_FORMAT[name]}"
                else:
                    value = "the specification's thin rod" if p.name in schema.COM_NAMES + schema.INERTIA_NAMES else None
            else:
                value = getattr(p.default, "value", p.default)
            if value is not None:
                p.help = f"{help_text} (default {value})"
    return group
