"""``identify``: a real pendulum's parameters from its measured motion (issue 27).

Reads the data (:class:`~skewpend.Measurements`: one of the readers, chosen by ``--format`` or
from the path), builds the starting model ``params0`` (the model options and ``--config``; for the
Kaheman rig without them, the authors' published model), calls :func:`skewpend.identify` and
prints its table; ``--out`` writes the fitted model as a run file every command reads
(``--config``), ``--netcdf`` the whole result, ``--plot`` and ``--report`` its figure and page.
A fit whose status is not success exits 1 (:func:`skewpend.cli.main`) and writes no run file.
"""

from __future__ import annotations

import functools
import inspect
import sys
from enum import Enum
from pathlib import Path
from typing import Annotated, Any, Dict, List, Optional

import typer

from ..parsing import UsageError
from . import types as T
from .options import CONFIG, MODEL, QUIET, RUN, command, option, plot_option, progress, resolve

COMMANDS = ("identify",)


class DataFormat(str, Enum):
    kaheman = "kaheman"
    dfki = "dfki"
    csv = "csv"
    mat = "mat"
    trajectory = "trajectory"


class Which(str, Enum):
    fit = "fit"
    validation = "validation"
    all = "all"


class FitMethod(str, Enum):
    output_error = "output-error"
    linear = "linear"


_START = "Starting model params0 (default with --format kaheman: the authors' published model)"
#: What params0 needs as numbers (the rest has the model's defaults; alpha 0).
NEEDED = ("a", "b", "m1", "m2", "g")


def _start_options() -> Dict[str, Any]:
    """The model options as params0's: their help says where params0 comes from instead of the
    reference case's defaults (which the other commands start from)."""
    out = {}
    for key, ann in MODEL.items():
        info = next(m for m in ann.__metadata__ if hasattr(m, "help"))
        kind = next(m for m in ann.__metadata__ if isinstance(m, T.ParamType))
        text = info.help
        if key in NEEDED:
            text += " (required, from the option or --config, unless --format kaheman gives the published model)"
        elif key == "alpha":
            text += " (default 0: parallel hinges, as both rigs in data/ are)"
        out[key] = option("--" + key, kind, text, _START)
    return out


#: The model options of identify (collected into ``model`` like every command's).
MODEL_START = _start_options()


def _start_model(func):
    """Give ``func`` the options of :data:`MODEL_START` and collect them into its ``model`` argument
    (as :func:`~skewpend.cli.options.command` does for the shared groups; typed values are parsed by it)."""
    sig = inspect.signature(func, eval_str=True)
    extra = [inspect.Parameter(k, inspect.Parameter.POSITIONAL_OR_KEYWORD, default=None, annotation=ann)
             for k, ann in MODEL_START.items()]

    @functools.wraps(func)
    def run(**kwargs):
        model = {k: kwargs.pop(k, None) for k in MODEL_START}
        return func(model=model, **kwargs)

    run.__signature__ = sig.replace(parameters=extra + [p for p in sig.parameters.values() if p.name != "model"])
    return run




_SECONDS = T.Positive("number of seconds")
_HORIZON = T.Positive("number of seconds", at_most=1e6)
_HORIZON.metavar = "SECONDS"
_DATA_HELP = ("measured motion: files or folders, combined (kaheman: the folder data/kaheman2023 or its .mat file; "
              "dfki: trajectory_NN.csv files or their folder; csv: CSV files with a header line, see --columns; mat: "
              "MATLAB files, see --variables; trajectory: skewpend's own .nc/.csv runs)")


@command()
@_start_model
def identify(
    model: dict,
    data: Annotated[List[str], typer.Argument(metavar="DATA", help=_DATA_HELP, show_default=False)] = ...,
    fmt: Annotated[Optional[DataFormat], typer.Option("--format", "-f", help="how DATA is written (default: from DATA -- a folder or file of the Kaheman rig, a folder of trajectory_NN.csv, .mat, .nc, a CSV with --columns)", rich_help_panel=RUN)] = None,
    which: Annotated[Optional[Which], typer.Option("--which", help="--format kaheman: the pieces of DATA to fit (default fit: the 26 fitting pieces, and without --validate the 4 held-out ones of the same file are predicted)", rich_help_panel=RUN)] = None,
    free: Annotated[Optional[str], typer.Option("--free", metavar="NAMES", help="the base parameters to estimate, comma-separated (e.g. J2zz,h2y), and/or alpha to estimate the skew angle too (default: every base parameter, alpha held at params0's)", rich_help_panel=RUN)] = None,
    validate: Annotated[Optional[str], typer.Option("--validate", metavar="DATA[,DATA...]", help="held-out data to predict, read like DATA (--format kaheman: their validation pieces); default: none, or with --format kaheman the validation pieces of DATA", rich_help_panel=RUN)] = None,
    horizon: option("--horizon", _HORIZON, "cut every held-out piece into pieces of about SECONDS each (Measurements.cut), each predicted from its own first measured state, as the driven rig's protocol does with 1 (default: whole pieces)") = None,
    method: Annotated[FitMethod, typer.Option("--method", help="output-error: the linear estimate, then multiple shooting on the angles; linear: the linear estimate (inverse dynamics on filtered signals) alone", show_default=False, rich_help_panel=RUN)] = FitMethod.output_error,
    segment: option("--segment", _SECONDS, "output-error: the shooting segments' length [s], at most 60 (default 0.5)") = None,
    smoothing: option("--smoothing", _SECONDS, "the Savitzky-Golay window of the linear estimate and the segments' starts [s] (default 0.05)") = None,
    columns: Annotated[Optional[str], typer.Option("--columns", metavar="KEY=COLUMN,...", help="--format csv (required with it): the columns of t, phi, psi and optionally dphi,dpsi and tau1,tau2 (pairs; a torque may be a number, e.g. tau2=0)", rich_help_panel=RUN)] = None,
    variables: Annotated[Optional[str], typer.Option("--variables", metavar="DATA_VAR,TIME_VAR|DT", help="--format mat (required with it): the variable holding the samples (a cell array of pieces or one array) and the time variable or a fixed step in seconds", rich_help_panel=RUN)] = None,
    channels: Annotated[Optional[str], typer.Option("--channels", metavar="A1,A2[,V1,V2[,T1,T2]]", help="--format mat: the channels of the two angles, then of their speeds and torques (default 0,1: angles only)", rich_help_panel=RUN)] = None,
    convention: Annotated[Optional[str], typer.Option("--convention", metavar="KEY=VALUE,...", help="csv, mat, dfki: how the file measures its angles: second=relative|absolute, zero=hanging|upright, sign=1:-1, unit=rad|deg, wrapped=yes (default skewpend's: relative, hanging, 1:1, rad)", rich_help_panel=RUN)] = None,
    out: option("--out", T.OutPath((".toml",)), "write the fitted model as a run file FILE.toml (use it with --config in any command); not written when the fit fails", RUN, "-o") = None,
    netcdf: option("--netcdf", T.OutPath((".nc",)), "write the whole result to FILE.nc (default: not written)") = None,
    plot: plot_option("the fit and the held-out prediction") = None,
    report: option("--report", T.OutPath((".html",)), "write a self-contained HTML page of the identification to FILE.html (default: not written)") = None,
    quiet: QUIET = False,
    config: CONFIG = None,
):
    """Identify a real pendulum's parameters from its measured motion: the base parameters with 95 %
    intervals, the skew angle with --free alpha, and the held-out prediction beside params0's.

    With --format kaheman and no --validate, the 26 fitting pieces are fitted and the 4 held-out
    pieces of the same file predicted.  From a --config run file it takes [parameters] (params0).
    Exit status 1 when the fit does not succeed (no run file is written then).
    """
    from ..errors import ParameterError

    paths = [str(p) for p in data]
    for p in paths + _split_paths(validate):
        if not Path(p).exists():
            raise ParameterError(f"DATA: {p} does not exist")
    kind = fmt.value if fmt is not None else _infer(paths, columns, variables)
    _check_combinations(kind, which, columns, variables, channels, convention)
    free_names = _free_names(free)
    reader = _reader(kind, columns, variables, channels, convention)
    params0 = _params0(kind, paths, model, config)
    plot_fn = _view("..views.figures.identification", "plot_identification", "--plot") if plot else None
    report_fn = _view("..views.report.identification", "write_identification_report", "--report") if report else None
    if netcdf is not None:
        from ..io import require_netcdf

        require_netcdf()

    pick = (which.value if which is not None else "fit") if kind == "kaheman" else None
    if horizon is not None and validate is None and pick != "fit":
        raise UsageError("--horizon cuts the held-out pieces: give them with --validate DATA (with --format kaheman "
                         "and --which fit, the default, the file's own held-out pieces)")
    measurements = reader(paths, pick)
    validation = None
    if validate is not None:
        validation = reader(_split_paths(validate), "validation" if kind == "kaheman" else None)
    elif kind == "kaheman" and pick == "fit":
        validation = reader(paths, "validation")
    if horizon is not None:
        validation = _cut(validation, horizon)

    from ..analysis.identify import identify as fit
    from ..interrupts import Interrupts

    kw: Dict[str, Any] = {"free": free_names, "validation": validation, "method": method.value}
    if segment is not None:
        kw["segment"] = segment
    if smoothing is not None:
        kw["smoothing"] = smoothing
    with progress("identify", "%", quiet) as bar, Interrupts(escalate_after=0.3) as intr:
        def say(stage: str, fraction: float) -> None:
            intr.check()  # Ctrl-C between the stages too (the signal is raised within 0.3 s anyway)
            bar(100.0 * fraction, 100.0)

        result = fit(measurements, params0, progress=say, **kw)
        bar(100.0, 100.0)
    note = ""
    written = []
    if netcdf is not None:
        result.to_netcdf(netcdf)
        written.append(("result", netcdf))
    if out is not None:
        if result.ok:
            result.to_run_file(out)
            written.append(("run file", out))
        else:
            note = f"; {out} not written (the fit did not succeed)"
    if plot_fn is not None:
        plot_fn(result, measurements, validation, plot)
        written.append(("plot", plot))
    if report_fn is not None:
        report_fn(result, measurements, validation, report)
        written.append(("report", report))
    lines = result.summary().splitlines()[:2] + ["", result.table()]
    lines += [f"{what:10s}{path}" for what, path in written]
    sys.stdout.write("\n".join(lines) + "\n")
    return result, note


def _cut(validation, horizon: float):
    """The held-out pieces cut into pieces of about ``horizon`` seconds (:meth:`Measurements.cut`);
    a horizon that leaves no piece is refused naming the option."""
    from ..errors import ParameterError

    try:
        return validation.cut(horizon)
    except ParameterError as exc:
        raise UsageError(f"--horizon {horizon:g}: {exc}") from None


# -- input ----------------------------------------------------------------------------------------------
def _split_paths(text: Optional[str]) -> List[str]:
    """``--validate``'s paths: one path (that exists, commas and all) or several, comma-separated."""
    if text is None:
        return []
    if Path(text).exists():
        return [text]
    parts = [p.strip() for p in text.split(",") if p.strip()]
    if not parts:
        raise UsageError("--validate: expected one or more paths, comma-separated")
    return parts


def _infer(paths: List[str], columns, variables) -> str:
    """The format of DATA from its first path (the others are read alike)."""
    from ..analysis.measurements import KAHEMAN_FILE

    p = Path(paths[0])
    if p.is_dir():
        if (p / KAHEMAN_FILE).is_file():
            return "kaheman"
        if any(p.glob("trajectory_*.csv")):
            return "dfki"
    elif p.name == KAHEMAN_FILE:
        return "kaheman"
    elif p.suffix.lower() == ".nc":
        return "trajectory"
    elif p.suffix.lower() == ".mat" and variables is not None:
        return "mat"
    elif p.suffix.lower() == ".csv" and columns is not None:
        return "csv"
    elif p.suffix.lower() == ".csv" and p.name.startswith("trajectory_"):
        return "dfki"
    raise UsageError(f"DATA: cannot tell how {p} is written; give --format kaheman|dfki|csv|mat|trajectory "
                     "(csv with --columns, mat with --variables)")


def _check_combinations(kind, which, columns, variables, channels, convention) -> None:
    """Every option takes effect or is refused, before any work."""
    own = {"--which": ("kaheman",), "--columns": ("csv",), "--variables": ("mat",), "--channels": ("mat",),
           "--convention": ("csv", "mat", "dfki")}
    for flag, value in (("--which", which), ("--columns", columns), ("--variables", variables),
                        ("--channels", channels), ("--convention", convention)):
        if value is not None and kind not in own[flag]:
            raise UsageError(f"{flag} goes with --format {' or '.join(own[flag])}, not {kind}")
    if kind == "csv" and columns is None:
        raise UsageError("--format csv needs --columns t=COLUMN,phi=COLUMN,psi=COLUMN[,dphi=..,dpsi=..][,tau1=..,tau2=..]: "
                         "the columns holding time and the two angles")
    if kind == "mat" and variables is None:
        raise UsageError("--format mat needs --variables DATA_VAR,TIME_VAR (or DATA_VAR,DT): the variable holding "
                         "the samples and the times")


def _free_names(text: Optional[str]) -> Optional[List[str]]:
    if text is None:
        return None
    names = [n.strip() for n in text.split(",") if n.strip()]
    if not names:
        raise UsageError(f"--free: expected base-parameter names and/or alpha, comma-separated, got {text!r}")
    return names


def _number(text: str) -> float:
    """A plain number (ASCII digits: Python's float reads other scripts' digits too)."""
    if not text.isascii():
        raise ValueError(text)
    return float(text)


def _columns(text: str) -> Dict[str, Any]:
    out: Dict[str, Any] = {}
    for item in text.split(","):
        key, eq, value = item.partition("=")
        key, value = key.strip(), value.strip()
        if not eq or not key or not value:
            raise UsageError(f"--columns: expected KEY=COLUMN pairs (t=time,phi=theta1,...), got {item.strip()!r}")
        if key in out:
            raise UsageError(f"--columns: {key} is given twice")
        if key in ("tau1", "tau2"):
            try:
                out[key] = _number(value)
                continue
            except ValueError:
                pass
        out[key] = value
    return out


def _convention(text: Optional[str]):
    from ..analysis.measurements import Convention

    if text is None:
        return Convention()
    kw: Dict[str, Any] = {}
    for item in text.split(","):
        key, eq, value = (s.strip() for s in item.partition("="))
        if key == "wrapped" and not eq:
            value, eq = "yes", "="
        if not eq or key not in ("second", "zero", "sign", "unit", "wrapped"):
            raise UsageError(f"--convention: expected second=, zero=, sign=, unit=, wrapped= (comma-separated), got {item.strip()!r}")
        if key == "sign":
            try:
                kw[key] = tuple(int(s) for s in value.split(":"))
            except ValueError:
                raise UsageError(f"--convention: sign= expects two of +1/-1 as S1:S2, e.g. 1:-1, got {value!r}") from None
        elif key == "wrapped":
            if value.lower() not in ("yes", "no", "true", "false", "1", "0"):
                raise UsageError(f"--convention: wrapped= expects yes or no, got {value!r}")
            kw[key] = value.lower() in ("yes", "true", "1")
        else:
            kw[key] = value
    return Convention(**kw)


def _reader(kind, columns, variables, channels, convention):
    """``read(paths, which) -> Measurements`` for the format, its options parsed once (so a bad one
    is refused before any file is read)."""
    from ..analysis.measurements import Measurements

    conv = _convention(convention)
    if kind == "kaheman":
        return lambda paths, which: _combine([Measurements.from_kaheman(p, which=which) for p in paths])
    if kind == "dfki":
        return lambda paths, which: Measurements.from_dfki(paths, convention=conv)
    if kind == "csv":
        cols = _columns(columns)
        return lambda paths, which: Measurements.from_csv(paths, cols, convention=conv)
    if kind == "trajectory":
        return lambda paths, which: _combine([Measurements.from_trajectory(p) for p in paths])
    # mat
    parts = [s.strip() for s in variables.split(",")]
    if len(parts) != 2 or not all(parts):
        raise UsageError(f"--variables: expected DATA_VAR,TIME_VAR or DATA_VAR,DT, got {variables!r}")
    try:
        step = _number(parts[1])
        time_kw: Dict[str, Any] = {"dt": step}
    except ValueError:
        time_kw = {"time": parts[1]}
    ch = (0, 1) if channels is None else T.Numbers(metavar="").convert(channels, "--channels")
    if len(ch) not in (2, 4, 6) or any(c != int(c) or c < 0 for c in ch):
        raise UsageError(f"--channels: expected 2, 4 or 6 channel indices (whole numbers from 0), got {channels!r}")
    ch = tuple(int(c) for c in ch)
    idx = {"angles": ch[0:2], "velocities": ch[2:4] or None, "torques": ch[4:6] or None}
    return lambda paths, which: _combine([Measurements.from_mat(p, parts[0], convention=conv, **time_kw, **idx)
                                          for p in paths])


def _combine(parts):
    """One :class:`~skewpend.Measurements` of several files' pieces (a name that repeats is led by
    its file's number, ``2:Y_id[0]``)."""
    import dataclasses

    from ..analysis.measurements import Measurements

    if len(parts) == 1:
        return parts[0]
    names = [p.name for m in parts for p in m.pieces]
    repeated = {n for n in names if names.count(n) > 1}
    pieces = [dataclasses.replace(p, name=f"{k + 1}:{p.name}") if p.name in repeated else p
              for k, m in enumerate(parts) for p in m.pieces]
    first = parts[0].metadata
    meta = {"format": first.get("format", ""), "sources": [s for m in parts for s in m.metadata.get("sources", ())],
            "convention": dict(first.get("convention", {})), "conversion": first.get("conversion", ""),
            "actions": [a for m in parts for a in m.metadata.get("actions", ())]
            + [f"combined {len(parts)} files" + (" (repeated piece names led by the file's number)" if repeated else "")]}
    return Measurements(pieces=tuple(pieces), metadata=meta)


def _params0(kind: str, paths: List[str], model: dict, config: Optional[str]):
    """The starting model: the options and --config; the Kaheman rig's published model without them."""
    given = {k: v for k, v in model.items() if v is not None}
    if kind == "kaheman" and not given and config is None:
        from ..analysis.measurements import kaheman_published_parameters

        return kaheman_published_parameters(paths[0])
    run = resolve("identify", config, defaults=False, parameters=model)
    params = run.parameters()
    missing = [run.option("parameters", k) for k in NEEDED if getattr(params, k) is None]
    if missing:
        hint = "; or leave out every model option and --config to start from the published model" if kind == "kaheman" else ""
        raise UsageError(f"{', '.join(missing)}: params0, the starting model, needs numbers for a, b, m1, m2 and g "
                         f"(options or --config's [parameters]){hint}")
    if params.alpha is None and params.axis2 is None and run.raw("parameters", "alpha") is None:
        params = params.replace(alpha=0.0)
    return params


def _view(module: str, name: str, flag: str):
    """A figure or page function of the views, imported when asked for (before any work)."""
    import importlib

    from ..errors import ParameterError

    try:
        return getattr(importlib.import_module(module, __package__), name)
    except (ImportError, AttributeError):
        raise ParameterError(f"{flag}: this installation has no {name} (skewpend.{module.lstrip('.')}); "
                             f"leave out {flag}") from None
