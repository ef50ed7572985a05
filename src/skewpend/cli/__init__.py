"""The ``skewpend`` command line: parse, call one library function, print (pyhf's ``cli/``).

* :mod:`.types` -- the parameter types (angle, positive, whole, range, output path, ...) that
  parse a typed value once; :mod:`.options` -- the option groups the commands share;
* one short module per command group: :mod:`.equations` (derive, export, validate),
  :mod:`.modes`, :mod:`.simulate` (simulate, animate, report), :mod:`.analyses` (flipmap,
  lyapunov, poincare, chaos-diagram), :mod:`.serve`;
* run files (``--config``) are resolved by the library (:mod:`skewpend.config`).

This module holds the app and :func:`main`, where outcomes become exit statuses, once:

====  =====================================================================================
0     done
1     the result is partly failed (its ``ok`` is False): one line names what failed
2     bad input: one line ``skewpend: error: ...`` (the library's message, with the parameter
      it names shown as the option or run-file key the user typed)
130   interrupted (Ctrl-C): one line, nothing left behind
143   terminated (SIGTERM): the same as Ctrl-C
70    an internal error (a bug): one line; ``SKEWPEND_DEBUG=1`` shows the traceback
====  =====================================================================================

Heavy modules (NumPy, SymPy, Matplotlib) are imported inside the commands, so that
``skewpend --help`` is instant.
"""

from __future__ import annotations

import time

#: When the command line was imported (``time.monotonic()``): a process's start, to within the ~0.1 s
#: the interpreter takes before it (see :func:`main`).
IMPORTED = time.monotonic()

import os  # noqa: E402
import re  # noqa: E402
import sys  # noqa: E402
from typing import Annotated, Any, List, Optional  # noqa: E402

import typer  # noqa: E402

from ..errors import SkewpendError  # noqa: E402

__all__ = ["app", "main", "build_parameters"]

#: The commands in the help's order, each with the module that defines it (its ``COMMANDS``).  A run
#: builds only the command it names: typer's parsing of one command's signature costs what importing
#: NumPy does, and seventeen of them were the larger part of a warm ``skewpend simulate``'s start.
_MODULES = {
    "derive": "equations", "simulate": "simulate", "animate": "simulate", "flipmap": "analyses",
    "lyapunov": "analyses", "poincare": "analyses", "chaos_diagram": "analyses", "serve": "serve",
    "report": "simulate", "export": "equations", "validate": "equations", "modes": "modes",
    "equilibria": "orbits", "orbit": "orbits", "nnm": "orbits", "control": "control", "identify": "identify",
}
COMMAND_NAMES = tuple(name.replace("_", "-") for name in _MODULES)


def _version(value: bool) -> None:
    if value:
        from .. import __version__

        sys.stdout.write(f"skewpend {__version__}\n")
        raise typer.Exit()


def _root(
    ctx: typer.Context,
    version: Annotated[
        bool, typer.Option("--version", callback=_version, is_eager=True, help="show the version and exit")
    ] = False,
) -> None:
    """The double pendulum with skewed hinge axes (see the README for the model)."""
    if ctx.invoked_subcommand is None:  # no command: the help, exit 0
        sys.stdout.write(ctx.get_help() + "\n")
        raise typer.Exit()


def _app(names) -> typer.Typer:
    """The Typer app with the commands ``names`` (the command modules hold plain functions; they
    become commands here, so there is no import cycle)."""
    import importlib

    app = typer.Typer(
        name="skewpend",
        help="The double pendulum with skewed hinge axes: a self-contained HTML report (skewpend report), the equations of motion, simulation, animation, flip-time maps, normal modes, validation against MuJoCo.",
        add_completion=False,
        pretty_exceptions_enable=False,
        rich_markup_mode=None,
    )
    app.callback(invoke_without_command=True)(_root)
    for name in names:
        module = importlib.import_module(f".{_MODULES[name]}", __name__)
        app.command(name.replace("_", "-"))(getattr(module, name))
    return app


def build_parameters(a, b, m1, m2, alpha, g, c1, c2, tau1, tau2, com1, com2, inertia1, inertia2, axis1, axis2,
                     cf1=None, cf2=None, cfs=None, Ir=None, gr=None):
    """Deprecated: :class:`~skewpend.Parameters` from command-line strings; use
    :func:`skewpend.config.build_parameters` (a mapping of values as spelled)."""
    from ..config import build_parameters as build

    return build(dict(a=a, b=b, m1=m1, m2=m2, alpha=alpha, g=g, c1=c1, c2=c2, tau1=tau1, tau2=tau2, com1=com1,
                      com2=com2, inertia1=inertia1, inertia2=inertia2, axis1=axis1, axis2=axis2, cf1=cf1, cf2=cf2,
                      cfs=cfs, Ir=Ir, gr=gr))


#: Names the single-module CLI (``skewpend/cli.py``) had, where they live now (deprecated here).
_MOVED = {"DEFAULT_RUN": ("..config", "DEFAULT_RUN"), "MODEL_OPTIONS": (".options", "MODEL"),
          "INITIAL_OPTIONS": (".options", "INITIAL"), "Method": (".options", "Method")}


_APP: Any = None


def __getattr__(name: str):
    global _APP
    if name == "app":  # every command: for the docs and typer's test runner
        if _APP is None:
            _APP = _app(_MODULES)
        return _APP
    if name in _MOVED:
        import importlib

        module, attribute = _MOVED[name]
        return getattr(importlib.import_module(module, __name__), attribute)
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")


# -- outcomes -> exit statuses (the one place) -------------------------------------------------------
#: The option of each name the library's messages use where it is not ``--name`` (per command
#: where it differs: the chaos diagram's alpha and energy are ranges).
FLAGS = {
    "n_exponents": "--exponents", "n_orbits": "--orbits", "n_crossings": "--crossings", "store": "--out",
    "y0": "the initial state (--phi0, --psi0, --dphi0, --dpsi0)", "n": "--n", "samples": "--samples",
}
COMMAND_FLAGS = {"chaos-diagram": {"alpha": "--alphas", "energy": "--energies"}}
_NAMED = re.compile(r"^([a-z][a-z0-9_]*)(?=(?: must\b|: | \(| is\b))")
_SNAKE = re.compile(r"\b([a-z][a-z0-9]*_[a-z0-9_]+)\b(?! \()")


def locate(message: str, command: Optional[str] = None, options: Any = (), parameter: Optional[str] = None) -> str:
    """A library message, which names parameters, shown with the options the user typed.

    One that begins with a parameter's name is led by its option or run-file key
    (``max_steps must be ...`` -> ``--max-steps: max_steps must be ...``; ``store: ...`` ->
    ``--out: ...``); a parameter named further on gets its option beside it (``use a larger
    dt_out`` -> ``use a larger dt_out (--dt-out)``); an error's own ``parameter`` gets its option
    beside it where the text names it (and only it), else leads.  ``options`` are the command's option names;
    a message that already names an option (``--``) or a run file is left as it is."""
    from .options import LOCATIONS

    if "--" in message or re.search(r"\.toml\b", message):
        return message

    def where(name: str) -> Optional[str]:
        found = COMMAND_FLAGS.get(command or "", {}).get(name) or FLAGS.get(name)
        if found is None and (name in LOCATIONS or name in options):
            found = LOCATIONS.get(name, "")
            if not found or found.startswith("default "):
                found = "--" + name.replace("_", "-")
        return found

    m = _NAMED.match(message)
    if parameter is not None and not (m and m.group(1) == parameter):  # the error's parameter, not the first word
        flag = where(parameter)
        named = rf"\b{re.escape(parameter)}\b(?= = | must\b)"  # the text names it as a parameter: the flag beside it
        if flag and re.search(named, message):
            return re.sub(named, f"{parameter} ({flag})", message, count=1)
        return f"{flag}: {message}" if flag else message
    lead = where(m.group(1)) if m else None
    rest = message[m.end():] if lead else message
    seen = set()

    def beside(match):
        name = match.group(1)
        flag = where(name) if name not in seen else None
        seen.add(name)
        return f"{name} ({flag})" if flag and flag.startswith("--") else name

    rest = _SNAKE.sub(beside, rest)
    if not lead:
        return rest
    if rest.startswith(": "):  # "store: cannot write ..." -> "--out: cannot write ..."
        return lead + rest
    return f"{lead}: {m.group(1)}{rest}"


def _ok(result: Any) -> bool:
    """Whether a command's result is whole (the result protocol's ``ok``)."""
    ok = getattr(result, "ok", None)
    if ok is None:
        ok = getattr(result, "success", True)
    return bool(ok)


def _fail(message: str, status: int = 2) -> None:
    sys.stderr.write(f"skewpend: error: {message}\n")
    sys.exit(status)


def _warning_line(message, category, filename, lineno, file=None, line=None) -> None:
    sys.stderr.write(f"skewpend: warning: {message}\n")


def _usage_message(exc) -> str:
    """A usage error of the command-line parser (typer's click) as one line."""
    ctx = getattr(exc, "ctx", None)
    where = f"skewpend {ctx.info_name}" if ctx is not None and ctx.parent is not None else "skewpend"
    return f"{exc.format_message().strip()} (see '{where} --help')"


def _check_repeats(command, args: List[str]) -> None:
    """An option given twice would silently lose its first value: refused."""
    from ..parsing import UsageError

    by_flag = {flag: p for p in getattr(command, "params", ()) for flag in (*p.opts, *p.secondary_opts)}
    seen, i = {}, 0
    while i < len(args) and args[i] != "--":
        flag = args[i].split("=", 1)[0]
        param = by_flag.get(flag) if args[i].startswith("-") else None
        if param is None:
            i += 1
            continue
        takes_value = not getattr(param, "is_flag", False) and "=" not in args[i]
        if param.name in seen and not getattr(param, "is_flag", False):
            raise UsageError(f"{flag} is given twice ({seen[param.name]!r} and {args[i + 1] if takes_value and i + 1 < len(args) else args[i].split('=', 1)[-1]!r}); give it once")
        seen[param.name] = args[i + 1] if takes_value and i + 1 < len(args) else args[i].split("=", 1)[-1]
        i += 2 if takes_value else 1


_GROUPS: dict = {}


def _group(name: Optional[str] = None):
    """The click group of the app, with every command (``name`` None) or only the command ``name``,
    built once per process (a test suite or a server calling :func:`main` many times would rebuild it
    each time).  The group holds no state of a run: its options' values live in each call's context,
    the run file's in ``LOCATIONS``."""
    if name not in _GROUPS:
        from .options import show_defaults

        app = __getattr__("app") if name is None else _app([name.replace("-", "_")])
        _GROUPS[name] = show_defaults(typer.main.get_command(app))
    return _GROUPS[name]


def _quick_exit(status: int) -> None:
    """Exit after a signal without the interpreter's last full garbage collection (a second or
    more after a report's SymPy and Matplotlib work): the objects are frozen out of it; atexit
    handlers and every ``finally`` still run.  Only as the process's own command line (``main()``
    without ``argv``): a program calling ``main(argv)`` goes on and keeps its collector."""
    import gc

    if _AS_PROGRAM:
        gc.freeze()
    sys.exit(status)


_AS_PROGRAM = False


def _signal_in_chain(exc: BaseException):
    """The KeyboardInterrupt (Terminated included) that caused ``exc``, if any: an extension module whose
    initialisation is interrupted raises ImportError ("initialization failed") from the signal's exception."""
    seen = set()
    while exc is not None and id(exc) not in seen:
        seen.add(id(exc))
        if isinstance(exc, KeyboardInterrupt):
            return exc
        exc = exc.__cause__ or exc.__context__
    return None


def main(argv: Optional[List[str]] = None) -> None:
    """Entry point: run a command and exit with its status (see the module)."""
    import warnings

    from ..interrupts import Terminated, terminate_like_interrupt

    from . import options
    from .options import LOCATIONS

    LOCATIONS.clear()  # this run's (main may run more than once in a process)
    global _AS_PROGRAM
    _AS_PROGRAM = argv is None
    # run as the process's program, the command started with the process (here: when this module was
    # imported, ~0.1 s in): its first stage is said by skewpend.progress.FIRST_BY after that
    options.PROGRAM_STARTED = IMPORTED if _AS_PROGRAM else None
    if _AS_PROGRAM:
        # skewpend never draws with MuJoCo (it validates against its physics): without an OpenGL
        # context its import skips the GLFW bindings, 0.07 s of every report and `validate`
        os.environ.setdefault("MUJOCO_GL", "disable")
    args = sys.argv[1:] if argv is None else list(argv)
    name = next((a for a in args if not a.startswith("-")), None)
    group = _group(name if name in COMMAND_NAMES else None)
    try:
        with terminate_like_interrupt(), warnings.catch_warnings():  # the warning settings are restored on leaving
            warnings.showwarning = _warning_line
            # NumPy's floating-point warnings ("overflow encountered in multiply") are arithmetic
            # detail: a result says what failed in its status, bad input in its one line
            warnings.filterwarnings("ignore", message=r".*encountered in", category=RuntimeWarning)
            if name in group.commands:
                _check_repeats(group.commands[name], args[args.index(name) + 1:])
            with group.make_context("skewpend", args) as ctx:
                result = group.invoke(ctx)
    except typer.Exit as exc:  # --help, --version
        sys.exit(exc.exit_code)
    except Terminated:
        sys.stderr.write("skewpend: terminated\n")
        _quick_exit(143)
    except KeyboardInterrupt:
        sys.stderr.write("skewpend: interrupted\n")
        _quick_exit(130)
    except SkewpendError as exc:
        command = group.commands.get(name) if name else None
        _fail(locate(str(exc), name, {p.name for p in getattr(command, "params", ())}, getattr(exc, "parameter", None)))
    except typer.TyperException as exc:  # the parser's usage errors (typer's click)
        _fail(_usage_message(exc), getattr(exc, "exit_code", 2))
    except Exception as exc:
        signal_exc = _signal_in_chain(exc)
        if signal_exc is not None:  # a Ctrl-C or SIGTERM inside an extension's import surfaces as ImportError
            sys.stderr.write("skewpend: terminated\n" if isinstance(signal_exc, Terminated) else "skewpend: interrupted\n")
            _quick_exit(143 if isinstance(signal_exc, Terminated) else 130)
        if os.environ.get("SKEWPEND_DEBUG"):
            raise
        if isinstance(exc, (OSError, MemoryError)):
            detail = getattr(exc, "strerror", None) or str(exc) or type(exc).__name__
            where = f" ({exc.filename})" if getattr(exc, "filename", None) else ""
            _fail(f"{detail}{where}", 1)
        first = str(exc).splitlines()[0] if str(exc) else ""
        sys.stderr.write(f"skewpend: internal error: {type(exc).__name__}: {first} "
                         "(a bug: please report it with the command; SKEWPEND_DEBUG=1 shows the traceback)\n")
        sys.exit(70)
    result, note = result if isinstance(result, tuple) else (result, "")
    if not _ok(result):
        sys.stderr.write(f"skewpend: {name}: {getattr(result, 'message', 'failed')}{note}\n")
        sys.exit(1)
    sys.exit(0)
