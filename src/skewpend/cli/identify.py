"""``identify``: a real pendulum's parameters from its measured motion (issue 27).

Reads the data (:class:`~skewpend.Measurements`: one of the readers, chosen by ``--format`` or
from the path), builds the starting model ``params0`` (the model options and ``--config``; for the
Kaheman rig without them, the authors' published model), calls :func:`skewpend.identify` and
prints its table; ``--out`` writes the fitted model as a run file every command reads
(``--config``), ``--netcdf`` the whole result, ``--plot`` and ``--report`` its figure and page.
A fit whose status is not success exits 1 (:func:`skewpend.cli.main`) and writes no run file.
"""

from __future__ import annotations

import dataclasses
import functools
import importlib
import re
import sys
from contextlib import contextmanager
from enum import Enum
from pathlib import Path
from typing import Annotated, Any, Dict, List, Optional

import typer

from .. import schema
from ..errors import ParameterError
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
NEEDED = schema.LENGTH_NAMES + schema.MASS_NAMES + ("g",)


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
        out[key] = option("--" + key.replace("_", "-"), kind, text, _START)
    return out


#: The model options of identify (collected into ``model`` like every command's).
MODEL_START = _start_options()


_SECONDS = T.Positive("number of seconds")
_HORIZON = T.Positive("number of seconds", at_most=1e6)
_HORIZON.metavar = "SECONDS"
_FRACTION = T.NonNegative("fraction of rows")
_FRACTION.metavar = "FRACTION"
_DATA_HELP = ("measured motion: files or folders, combined (kaheman: the folder data/kaheman2023 or its .mat file; "
              "dfki: trajectory_NN.csv files or their folder; csv: CSV files with a header line, see --columns; mat: "
              "MATLAB files, see --variables; trajectory: skewpend's own .nc/.csv runs)")


@command(model=MODEL_START)
def identify(
    model: dict,
    data: Annotated[List[str], typer.Argument(metavar="DATA", help=_DATA_HELP, show_default=False)] = ...,
    fmt: Annotated[Optional[DataFormat], typer.Option("--format", "-f", help="how DATA is written (default: from DATA -- a folder or file of the Kaheman rig, a folder of trajectory_NN.csv, .mat, .nc, a CSV with --columns)", rich_help_panel=RUN)] = None,
    which: Annotated[Optional[Which], typer.Option("--which", help="--format kaheman: the pieces of DATA to fit (default fit: the 26 fitting pieces, and without --validate the 4 held-out ones of the same file are predicted)", rich_help_panel=RUN)] = None,
    free: Annotated[Optional[str], typer.Option("--free", metavar="NAMES", help="the base parameters to estimate, comma-separated (e.g. J2zz,h2y), and/or one hinge's tilt to estimate too: alpha, the double pendulum's skew angle, or tiltK, a chain's hinge K turned about the vertical (default: every base parameter, the axes held at params0's)", rich_help_panel=RUN)] = None,
    validate: Annotated[Optional[str], typer.Option("--validate", metavar="DATA[,DATA...]", help="held-out data to predict, read like DATA (--format kaheman: their validation pieces); default: none, or with --format kaheman the validation pieces of DATA", rich_help_panel=RUN)] = None,
    horizon: option("--horizon", _HORIZON, "cut every held-out piece into pieces of about SECONDS each (Measurements.cut), each predicted from its own first measured state, as the driven rig's protocol does with 1 (default: whole pieces)") = None,
    cut: option("--cut", _HORIZON, "cut the fitting data into pieces of about SECONDS each (Measurements.cut), e.g. one long recording into several (default: the pieces as read)") = None,
    params0_file: Annotated[Optional[str], typer.Option("--params0", metavar="FILE.yml", help="start from a DFKI lab model file (model_*_parameters.yml), converted as skewpend.analysis.measurements.dfki_lab_parameters does (inertias to the centres of mass, the gear's sign); model options override its values (default: the model options and --config)", rich_help_panel=RUN)] = None,
    skip: Annotated[Optional[str], typer.Option("--skip", metavar="CHECKS", help="reader checks to leave out, comma-separated: mean, tracking, velocities, units (the heuristic ones; default: none)", rich_help_panel=RUN)] = None,
    nonfinite: option("--nonfinite", _FRACTION, "the largest fraction of a piece's rows holding NaN or inf that the readers drop (each drop said on stderr); above it the data are refused; 0 refuses any (default 0.05)") = None,
    short: Annotated[Optional[str], typer.Option("--short", metavar="refuse|drop", help="pieces with fewer than 10 samples (after cutting at gaps): refuse the data, or drop those pieces (said on stderr) (default refuse)", rich_help_panel=RUN)] = None,
    method: Annotated[FitMethod, typer.Option("--method", help="output-error: the linear estimate, then multiple shooting on the angles; linear: the linear estimate (inverse dynamics on filtered signals) alone", show_default=False, rich_help_panel=RUN)] = FitMethod.output_error,
    segment: option("--segment", _SECONDS, "output-error: the shooting segments' length [s], at most 60 (default: each piece whole where every piece is at most 3 s long, as a held-out piece is predicted; else 0.5)") = None,
    angles: Annotated[Optional[str], typer.Option("--angles", metavar="relative|absolute", help="output-error: the angles the fit and the held-out RMS measure, relative (the joint angles, skewpend's coordinates) or absolute (each rod's from the vertical); default: the angles the data measured (their --convention second=, Kaheman's absolute)", rich_help_panel=RUN)] = None,
    smoothing: option("--smoothing", _SECONDS, "the Savitzky-Golay window of the linear estimate and the segments' starts [s] (default 0.05)") = None,
    columns: Annotated[Optional[str], typer.Option("--columns", metavar="KEY=COLUMN,...", help="--format csv (required with it): the columns of t, phi, psi and optionally dphi,dpsi and tau1,tau2 (pairs; a torque may be a number, e.g. tau2=0)", rich_help_panel=RUN)] = None,
    variables: Annotated[Optional[str], typer.Option("--variables", metavar="DATA_VAR,TIME_VAR|DT", help="--format mat (required with it): the variable holding the samples (a cell array of pieces or one array) and the time variable or a fixed step in seconds", rich_help_panel=RUN)] = None,
    channels: Annotated[Optional[str], typer.Option("--channels", metavar="A1,A2[,V1,V2[,T1,T2]]", help="--format mat: the channels of the two angles, then of their speeds and torques (default 0,1: angles only)", rich_help_panel=RUN)] = None,
    convention: Annotated[Optional[str], typer.Option("--convention", metavar="KEY=VALUE,...", help="csv, mat, dfki: how the file measures its angles and times: second=relative|absolute, zero=hanging|upright, sign=1:-1, unit=rad|deg, wrapped=yes, time=s|ms|us (default skewpend's: relative, hanging, 1:1, rad, s)", rich_help_panel=RUN)] = None,
    out: option("--out", T.OutPath((".toml", ".yml")), "write the fitted model as a run file FILE.toml (use it with --config in any command) or as a DFKI lab model file FILE.yml (planar models with the centres of mass on the rods); not written when the fit fails", RUN, "-o") = None,
    netcdf: option("--netcdf", T.OutPath((".nc",)), "write the whole result to FILE.nc (default: not written)") = None,
    plot: plot_option("the fit and the held-out prediction") = None,
    report: option("--report", T.OutPath((".html",)), "write a self-contained HTML page of the identification to FILE.html (default: not written)") = None,
    quiet: QUIET = False,
    config: CONFIG = None,
):
    """Identify a real pendulum's parameters from its measured motion: the base parameters with 95 %
    intervals, the skew angle with --free alpha (a chain's hinge tilt with --free tiltK), and the held-out
    prediction beside params0's.  The same stages for the double pendulum and a chain of any number of links.

    With --format kaheman and no --validate, the 26 fitting pieces are fitted and the 4 held-out
    pieces of the same file predicted.  From a --config run file it takes [parameters] (params0).
    Exit status 1 when the fit does not succeed (no run file is written then).
    """
    paths = [_data_path(str(p), "DATA") for p in data]
    if validate is not None:
        validate = ",".join(_data_path(p, "--validate") for p in _split_paths(validate))
    kind = fmt.value if fmt is not None else _infer(paths, columns, variables)
    _check_combinations(kind, which, columns, variables, channels, convention)
    free_names = _free_names(free)
    conv = _convention(convention)
    reader = _reader(kind, columns, variables, channels, conv, _checks(skip, nonfinite, short))
    params0 = _params0(kind, paths, model, config, params0_file)
    if angles is not None and angles not in ("relative", "absolute"):
        raise UsageError(f"--angles must be relative or absolute, got {angles!r}")
    lab_out = out is not None and out.lower().endswith(".yml")
    if lab_out:
        _check_lab_out(out, params0, free_names)
    plot_fn = _view("..views.figures.identification", "plot_identification", "--plot") if plot else None
    report_fn = _view("..views.report.identification", "write_identification_report", "--report") if report else None
    if netcdf is not None:
        from ..io import require_netcdf

        require_netcdf()

    pick = (which.value if which is not None else "fit") if kind == "kaheman" else None
    if horizon is not None and validate is None and pick != "fit":
        raise UsageError("--horizon cuts the held-out pieces: give them with --validate DATA (with --format kaheman "
                         "and --which fit, the default, the file's own held-out pieces)")
    with _cli_messages(conv):
        measurements = reader(paths, pick)
        validation = None
        if validate is not None:
            validation = reader(_split_paths(validate), "validation" if kind == "kaheman" else None)
        elif kind == "kaheman" and pick == "fit":
            validation = reader(paths, "validation")
    if cut is not None:
        measurements = _cut(measurements, cut, "--cut")
    if horizon is not None:
        validation = _cut(validation, horizon, "--horizon")
    from ..analysis import hints
    from ..analysis.identify import identify as fit
    from ..interrupts import Interrupts

    with _cli_messages(conv):  # a refusal is its one line: before the actions on the data are said
        hints.check_sampling(measurements, params0, convention=conv, interface="cli")
    _say_actions("data", measurements)
    if validation is not None:
        _say_actions("held-out data", validation)

    kw: Dict[str, Any] = {"free": free_names, "validation": validation, "method": method.value}
    kw.update({k: v for k, v in (("angles", angles), ("segment", segment), ("smoothing", smoothing)) if v is not None})
    with progress("identify", "%", quiet) as bar, Interrupts(escalate_after=0.3) as intr:
        def say(stage: str, fraction: float) -> None:
            intr.check()  # Ctrl-C between the stages too (the signal is raised within 0.3 s anyway)
            bar(100.0 * fraction, 100.0, stage)  # the stage named: said as it begins (issue 36)

        with _cli_messages(conv):
            result = fit(measurements, params0, progress=say, **kw)
        bar(100.0, 100.0)
        why = hints.suspect(result, measurements)
        found: List[str] = []
        if why is not None:  # a fit gone wrong, or it may have: the likely data mistakes (a few linear estimates)
            if kind in ("csv", "mat", "dfki") and not quiet:
                sys.stderr.write("skewpend: identify: checking the data for likely mistakes (a few inverse-dynamics "
                                 "fits)...\n")
            with _cli_messages(conv):
                try:
                    found = hints.diagnose(measurements, params0, convention=conv, free=free_names, interface="cli",
                                           conventions=kind in ("csv", "mat", "dfki"))
                except ParameterError:  # a check that cannot be made (a convention of other angles) gives no answer
                    found = []
    if why is not None:  # a fit that succeeded gets a line only when a mistake is found
        for line in hints.report(found, checked=kind in ("csv", "mat", "dfki") and not result.ok):
            sys.stderr.write(f"skewpend: {line}\n")
    note = f"; {out} not written (the fit did not succeed)" if out is not None and not result.ok else ""
    written, lab_error, views = [], None, (result, measurements, validation)
    # the files, under Ctrl-C's protection to the end: a signal in their last moments is raised at the
    # next check (exit 130, one line), and every file this run wrote is removed again (each is written
    # atomically: the one being written is never left either)
    files = [("result", netcdf, result.to_netcdf),
             ("lab model" if lab_out else "run file", out if result.ok else None,
              functools.partial(_write_lab_file, result) if lab_out else result.to_run_file),
             ("plot", plot, plot_fn and functools.partial(plot_fn, *views)),
             ("report", report, report_fn and functools.partial(report_fn, *views))]
    try:
        with Interrupts(escalate_after=0.3) as intr:
            intr.check()
            for what, path, write in files:
                if path is None or not write:
                    continue
                try:
                    write(path)
                    written.append((what, path))
                except ParameterError as exc:
                    if what != "lab model":
                        raise
                    lab_error = f"--out {out}: not written: {exc}"
                intr.check()
    except KeyboardInterrupt:
        for _, path in written:
            Path(path).unlink(missing_ok=True)
        raise
    lines = result.summary().splitlines()[:2] + ["", result.table()]
    lines += [f"{what:10s}{path}" for what, path in written]
    sys.stdout.write("\n".join(lines) + "\n")
    if lab_error is not None:
        raise ParameterError(lab_error)
    return result, note


def _cut(measurements, seconds: float, flag: str):
    """Pieces cut into pieces of about ``seconds`` (:meth:`Measurements.cut`); a length that
    leaves no piece is refused naming the option."""
    try:
        return measurements.cut(seconds)
    except ParameterError as exc:
        raise UsageError(f"{flag} {seconds:g}: {exc}") from None


def _say_actions(what: str, measurements) -> None:
    """Every action taken on the data (rows dropped, pieces cut, angles unwrapped or shifted), a
    line each on stderr."""
    for action in measurements.metadata.get("actions", ()):
        sys.stderr.write(f"skewpend: {what}: {action}\n")


# -- the command line's spelling in the library's messages ----------------------------------------------
def _spell(conv, **change) -> str:
    from ..analysis.hints import spell_convention

    try:
        text = spell_convention(dataclasses.replace(conv, **change), "cli")
    except Exception:  # a message naming a value no Convention takes: say it plainly
        return "--convention " + ",".join(f"{k}={v}" for k, v in change.items())
    # the key the message is about is always named, also when it goes back to skewpend's default
    # (unit=rad): never a key the user did not ask about in its place
    missing = [f"{k}={'yes' if v is True else v}" for k, v in change.items() if f"{k}=" not in text]
    if missing:
        body = text[len("--convention "):]
        stated = [] if body == "second=relative" and conv.second == "relative" else [body]
        text = "--convention " + ",".join(stated + missing)
    return text


#: The Python spellings of the library's messages and the command line's (``Convention(...)``
#: becomes the whole ``--convention`` with the change, the other keys as the user gave them).
_CLI_SPELLINGS = [
    (re.compile(r"Convention\((\w+)=True\)"), lambda m, c: _spell(c, **{m[1]: True})),
    (re.compile(r"Convention\((\w+)='([^']*)'\)"), lambda m, c: _spell(c, **{m[1]: m[2]})),
    (re.compile(r"Convention\(sign=\((-?1), (-?1)\)\)"), lambda m, c: _spell(c, sign=(int(m[1]), int(m[2])))),
    (re.compile(r"skip=\('(\w+)',\)"), lambda m, c: f"--skip {m[1]}"),
    (re.compile(r"short='drop'"), lambda m, c: "--short drop"),
    (re.compile(r"\bnonfinite=([0-9.eE+-]+)"), lambda m, c: f"--nonfinite {m[1]}"),
    (re.compile(r"\braise nonfinite\b"), lambda m, c: "raise --nonfinite (the largest fraction of rows dropped)"),
    (re.compile(r"method='output-error'"), lambda m, c: "--method output-error"),
    (re.compile(r"\bcheck zero=(?=[ ,;)]|$)"), lambda m, c: "check zero= in --convention"),
    (re.compile(r"^(skip|columns|convention|free): "), lambda m, c: f"--{m[1]}: "),
    (re.compile(r"the (?:column )?mapping\b"), lambda m, c: "--columns"),
]


def cli_message(text: str, conv=None) -> str:
    """A library message with its Python spellings (``Convention(wrapped=True)``,
    ``skip=('units',)``, ``nonfinite=0.05``, ...) in the command line's (``--convention
    wrapped=yes``, ``--skip units``, ``--nonfinite 0.05``)."""
    from ..analysis.measurements import SKEWPEND

    conv = SKEWPEND if conv is None else conv
    for pattern, to in _CLI_SPELLINGS:
        text = pattern.sub(lambda m: to(m, conv), text)
    return text


@contextmanager
def _cli_messages(conv):
    """Re-raise the library's errors with the command line's spellings."""
    try:
        yield
    except ParameterError as exc:
        text = cli_message(str(exc), conv)
        if text == str(exc):
            raise
        raise ParameterError(text) from None


def _checks(skip: Optional[str], nonfinite: Optional[float], short: Optional[str]) -> Dict[str, Any]:
    """The readers' check settings from --skip, --nonfinite, --short."""
    from ..analysis.measurements import CHECKS

    out: Dict[str, Any] = {}
    if skip is not None:
        names = [n.strip() for n in skip.split(",")]
        unknown = [n for n in names if n not in CHECKS]
        if not all(names) or unknown:
            raise UsageError(f"--skip: expected checks to leave out, comma-separated, from {', '.join(CHECKS)}; "
                             f"got {skip!r}")
        out["skip"] = tuple(names)
    if nonfinite is not None:
        if not nonfinite < 1:
            raise UsageError(f"--nonfinite: expected a fraction of rows from 0 up to (not including) 1, got {nonfinite:g}")
        out["nonfinite"] = float(nonfinite)
    if short is not None:
        if short not in ("refuse", "drop"):
            raise UsageError(f"--short: expected refuse or drop, got {short!r}")
        out["short"] = short
    return out


# -- the DFKI lab's model files --------------------------------------------------------------------------
def _check_lab_out(out: str, params0, free_names) -> None:
    """--out FILE.yml is refused before the fit when its model cannot be one of the lab's."""
    from ..analysis.measurements import dfki_lab_values

    try:
        dfki_lab_values(params0)
    except AttributeError:  # no facade's parameters: the lab's file has no place for them
        raise UsageError(f"--out FILE.yml: a DFKI lab model file holds a double pendulum; {params0.title} writes its "
                         "result with --out FILE.toml, --netcdf FILE.nc, --plot or --report") from None
    except ParameterError as exc:
        raise UsageError(f"--out {out}: params0 is not a model the lab's file can hold: {exc}") from None
    angle = next((n for n in free_names or () if n == "alpha" or n.startswith("tilt")), None)
    if angle is not None:
        raise UsageError(f"--out {out}: the DFKI lab's model is planar; leave {angle} out of --free, or write a .toml "
                         "run file")


def _write_lab_file(result, out: str) -> None:
    from .. import __version__
    from ..analysis.measurements import write_dfki_lab_parameters

    header = [f"a pendulum identified from measured motion by skewpend {__version__}, in the DFKI lab's terms",
              f"method: {result.settings.get('method', result.method)}", f"status: {result.message}",
              f"data: {len(result.pieces)} pieces",
              "I1, I2 about the joint axes (I_com + m r^2); gr the lab's sign (skewpend's -gr); b the viscous damping",
              "read it with: skewpend identify --params0 FILE, or the lab's model_parameters(filepath=FILE)"]
    write_dfki_lab_parameters(result.params, out, header=header)


# -- input ----------------------------------------------------------------------------------------------
def _data_path(text: str, where: str) -> str:
    """A path of measured data, or the name of a data set shipped with skewpend (``kaheman2023``,
    ``dfki-design-C.0/trajectory_00.csv``: :func:`skewpend.example_data`), said on stderr."""
    from ..datasets import EXAMPLE_DATA, example_data

    if Path(text).exists():
        return text
    if text.replace("\\", "/").split("/")[0] in EXAMPLE_DATA:
        found = str(example_data(text))
        sys.stderr.write(f"skewpend: {where} {text}: the example data shipped with skewpend ({found})\n")
        return found
    raise ParameterError(f"{where}: {text} does not exist (the example data shipped with skewpend: "
                         f"{', '.join(EXAMPLE_DATA)})")


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
    from ..analysis.measurements import KAHEMAN_FILE, KAHEMAN_TRIPLE_FILE

    p = Path(paths[0])
    if p.is_dir():
        if (p / KAHEMAN_FILE).is_file() or (p / KAHEMAN_TRIPLE_FILE).is_file():
            return "kaheman"
        if any(p.glob("trajectory_*.csv")):
            return "dfki"
    elif p.name in (KAHEMAN_FILE, KAHEMAN_TRIPLE_FILE):
        return "kaheman"
    elif p.suffix.lower() == ".nc":
        return "trajectory"
    elif p.suffix.lower() == ".mat" and variables is not None:
        return "mat"
    elif p.suffix.lower() == ".csv" and columns is not None:
        return "csv"
    elif p.suffix.lower() == ".csv" and p.name.startswith("trajectory_"):
        return "dfki"
    elif p.suffix.lower() == ".csv":  # skewpend's own run (its header), else a CSV of the user's (--columns)
        return "trajectory" if _header(p)[:3] == ["t", "phi", "psi"] else "csv"
    elif p.suffix.lower() == ".mat":
        return "mat"
    raise UsageError(f"DATA: cannot tell how {p} is written; give --format kaheman|dfki|csv|mat|trajectory "
                     "(csv with --columns, mat with --variables)")


def _header(path: Path) -> List[str]:
    """The first line of a CSV file, split at commas (empty when it cannot be read)."""
    try:
        with open(path, "rb") as fh:
            line = fh.readline(65536)
        return [x.strip() for x in line.decode("utf-8", "replace").strip().split(",")]
    except OSError:
        return []


def _check_combinations(kind, which, columns, variables, channels, convention) -> None:
    """Every option takes effect or is refused, before any work."""
    own = {"--which": ("kaheman",), "--columns": ("csv",), "--variables": ("mat",), "--channels": ("mat",),
           "--convention": ("csv", "mat", "dfki")}
    for (flag, kinds), value in zip(own.items(), (which, columns, variables, channels, convention)):
        if value is not None and kind not in kinds:
            raise UsageError(f"{flag} goes with --format {' or '.join(kinds)}, not {kind}")
    if kind == "csv" and columns is None:
        raise UsageError("a CSV file (--format csv) needs --columns t=COLUMN,phi=COLUMN,psi=COLUMN[,dphi=..,dpsi=..][,tau1=..,tau2=..]: "
                         "the columns holding time and the two angles")
    if kind == "mat" and variables is None:
        raise UsageError("a MATLAB file (--format mat) needs --variables DATA_VAR,TIME_VAR (or DATA_VAR,DT): the variable holding "
                         "the samples and the times")


def _free_names(text: Optional[str]) -> Optional[List[str]]:
    if text is None:
        return None
    names = [n.strip() for n in text.split(",") if n.strip()]
    if not names:
        raise UsageError(f"--free: expected base-parameter names and/or alpha or a hinge's tiltK, comma-separated, "
                         f"got {text!r}")
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
        if key in schema.TORQUE_NAMES:
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
        if not eq or key not in ("second", "zero", "sign", "unit", "wrapped", "time"):
            raise UsageError(f"--convention: expected second=, zero=, sign=, unit=, wrapped=, time= (comma-separated), got {item.strip()!r}")
        if key == "sign":
            try:
                kw[key] = tuple(int(s) for s in value.split(":"))
            except ValueError:
                raise UsageError(f"--convention: sign= expects one +1/-1 per angle as S1:S2 (S1:S2:S3 for three), e.g. 1:-1, got {value!r}") from None
        elif key == "wrapped":
            if value.lower() not in ("yes", "no", "true", "false", "1", "0"):
                raise UsageError(f"--convention: wrapped= expects yes or no, got {value!r}")
            kw[key] = value.lower() in ("yes", "true", "1")
        else:
            kw[key] = value
    try:
        return Convention(**kw)
    except ParameterError as exc:  # "Convention time must be one of 's', 'ms', 'us', got 'h'"
        raise UsageError("--convention: " + str(exc).replace("Convention ", "", 1).replace(" must be", "= must be", 1)) from None


def _reader(kind, columns, variables, channels, conv, checks):
    """``read(paths, which) -> Measurements`` for the format, its options parsed once (so a bad one
    is refused before any file is read); ``checks``: the readers' check settings."""
    from ..analysis.measurements import Measurements

    if kind == "kaheman":
        return lambda paths, which: _combine([Measurements.from_kaheman(p, which=which, **checks) for p in paths])
    if kind == "dfki":
        return lambda paths, which: Measurements.from_dfki(paths, convention=conv, **checks)
    if kind == "csv":
        cols = _columns(columns)
        return lambda paths, which: Measurements.from_csv(paths, cols, convention=conv, **checks)
    if kind == "trajectory":
        return lambda paths, which: _combine([Measurements.from_trajectory(p, **checks) for p in paths])
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
    return lambda paths, which: _combine([Measurements.from_mat(p, parts[0], convention=conv, **time_kw, **idx,
                                                                **checks) for p in paths])


def _combine(parts):
    """One :class:`~skewpend.Measurements` of several files' pieces (a name that repeats is led by
    its file's number, ``2:Y_id[0]``)."""
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


def _params0(kind: str, paths: List[str], model: dict, config: Optional[str], lab_file: Optional[str] = None):
    """The starting model: a DFKI lab model file (--params0) under the options, or the options and
    --config; the Kaheman rig's published model without any of them."""
    given = {k: v for k, v in model.items() if v is not None}
    if lab_file is not None:
        from ..analysis.measurements import dfki_lab_parameters

        if config is not None:
            raise UsageError("--params0 and --config both give params0, the starting model: give one (model options "
                             "override either)")
        if not lab_file.lower().endswith((".yml", ".yaml")):
            raise UsageError(f"--params0: expected a DFKI lab model file FILE.yml (model_*_parameters.yml), got {lab_file!r}")
        if not Path(lab_file).is_file():
            raise UsageError(f"--params0: {lab_file} does not exist")
        lab = {k: v for k, v in dfki_lab_parameters(lab_file).to_dict().items() if v is not None}
        flags = {k: f"--params0 {lab_file}: {k}" for k in lab if k not in given}
        run = resolve("identify", None, defaults=False, flags=flags, parameters={**lab, **given})
        return run.parameters()
    if kind == "kaheman" and not given and config is None:
        from ..analysis.measurements import KAHEMAN_FILE, KAHEMAN_TRIPLE_FILE, kaheman_published_chain, kaheman_published_parameters

        where = Path(paths[0])
        if where.name == KAHEMAN_TRIPLE_FILE or (where.is_dir() and (where / KAHEMAN_TRIPLE_FILE).is_file()
                                                 and not (where / KAHEMAN_FILE).is_file()):
            return kaheman_published_chain(where)  # the triple pendulum: the chain of three links
        return kaheman_published_parameters(paths[0])
    run = resolve("identify", config, defaults=False, parameters=model)
    params = run.parameters()  # the run's model (a chain where it gives links: the facade's options refused there)
    unset = () if params.is_numeric else params.symbolic_names
    if "alpha" in unset and run.raw("parameters", "alpha") is None:  # alpha not given: 0
        params, unset = params.replace(alpha=0.0), tuple(n for n in unset if n != "alpha")
    missing = [run.option("parameters", k) for k in NEEDED if k in unset]
    if missing:
        hint = "; or leave out every model option and --config to start from the published model" if kind == "kaheman" else ""
        raise UsageError(f"{', '.join(missing)}: params0, the starting model, needs numbers for a, b, m1, m2 and g "
                         f"(options or --config's [parameters]){hint}")
    return params


def _view(module: str, name: str, flag: str):
    """A figure or page function of the views, imported when asked for (before any work)."""
    try:
        return getattr(importlib.import_module(module, __package__), name)
    except (ImportError, AttributeError):
        raise ParameterError(f"{flag}: this installation has no {name} (skewpend.{module.lstrip('.')}); "
                             f"leave out {flag}") from None
