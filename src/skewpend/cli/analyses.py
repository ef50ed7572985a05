"""The analyses over many trajectories or a long one: ``flipmap``, ``lyapunov``, ``poincare``,
``chaos-diagram``.  Each parses, calls one library function and prints its summary; a result
that is partly failed makes the exit status 1 (:func:`skewpend.cli.main`)."""

from __future__ import annotations

import sys
import warnings
from enum import Enum
from typing import Annotated, Optional

import typer

from ..parsing import UsageError
from . import types as T
from ..progress import stage
from .options import CONFIG, ENSEMBLE, INITIAL, INTEGRATION, MODEL, QUIET, RUN, command, option, plot_option, progress, resolve, tolerances

COMMANDS = ("flipmap", "lyapunov", "poincare", "chaos_diagram")

_SECONDS = T.Positive("number of seconds")
_STORE = T.OutPath((".zarr", ".nc"), check=False)
RESUME = "with --out FILE.zarr: compute only the {} an interrupted run left missing"


def _dop853(name: str, config, model, initial=None, **simulation):
    """The run of a DOP853 analysis: the model, [initial] where it reads one, t_end, rtol, atol."""
    run = resolve(name, config, parameters=model, initial=initial or {}, simulation=simulation)
    run.integration(methods=("dop853",))  # a run file's method must be dop853, tolerances positive
    return run


def ensemble_outputs(workers, scheduler, out, resume: bool, plot) -> Optional[str]:
    """The checks of an ensemble command's outputs before any work; the store (FILE.zarr) or None."""
    from ..io import check_output_path

    if scheduler is not None and workers is not None:
        raise UsageError("--workers counts threads on this machine; with --scheduler the cluster's workers do the work")
    store = out if out is not None and out.lower().endswith(".zarr") else None
    if out is not None and store is None:
        check_output_path(out, (".nc",), option="--out")
    if resume and store is None:
        raise UsageError("--resume continues a store: give --out FILE.zarr (a .nc file is written whole at the end)")
    from .simulate import check_plot

    check_plot(plot)
    return store


def _written(*pairs) -> list:
    return [f"{what:10s}{path}" for what, path in pairs if path is not None]


def draw_figure(plot, figure: str, *args, **kwargs) -> None:
    if plot is not None:
        stage(f"drawing {plot}")
        from ..views import figures

        figures.save_figure(getattr(figures, figure)(*args, **kwargs), plot)


#: The tolerance and step-cap options of these commands (named: an annotation is no place for a subscript).
ATOL_E10 = tolerances("1e-10")["atol"]
ATOL_E12 = tolerances("1e-12")["atol"]
ATOL_E8 = tolerances("1e-8")["atol"]
MAX_STEPS_OPTION = INTEGRATION["max_steps"]
RTOL_E10 = tolerances("1e-10")["rtol"]
RTOL_E12 = tolerances("1e-12")["rtol"]
RTOL_E8 = tolerances("1e-8")["rtol"]


@command(MODEL, ENSEMBLE)
def flipmap(
    model: dict,
    ensemble: dict,
    n: option("--n", T.Whole(1, 16384), "cells per side: an n x n map (default 256)") = None,
    t_end: option("--t-end", _SECONDS, "longest time looked at [s] (default 10)") = None,
    window: option("--window", T.Window(), "PHI0:PHI1,PSI0:PSI1 (radians, or e.g. -90:90deg,-180:180deg; default the whole square; a chain's: the plane's two angles)") = None,
    plane: option("--plane", T.Plane(), "a chain of links: the two angles varied, e.g. q1,q3 (default q1,q2)") = None,
    held: option("--held", T.Angles(), "a chain of links: every angle at release, the plane's two ignored (radians or deg; default 0: hanging)") = None,
    rtol: RTOL_E10 = None,
    atol: ATOL_E10 = None,
    out: option("--out", _STORE, "write the map to FILE.zarr (chunk by chunk, resumable) or FILE.nc", RUN, "-o") = None,
    plot: plot_option("the map") = None,
    resume: Annotated[bool, typer.Option("--resume", help=RESUME.format("chunks"), rich_help_panel=RUN)] = False,
    quiet: QUIET = False,
    config: CONFIG = None,
):
    """The flip-time map: for each start (phi0, psi0) at rest on an n x n grid, the first time either
    hinge angle leaves (-180 deg, 180 deg) -- on every core, or on a Dask cluster.

    From a --config run file it takes [parameters] and [simulation] t_end, rtol, atol; or a chain of links
    ([[links]], [chain]): the map over --plane of two of its angles, the others at --held.
    """
    run = _dop853("flipmap", config, model, t_end=t_end, rtol=rtol, atol=atol)
    params = run.parameters()
    angles = params.coordinates
    sliced = len(angles) > 2  # angles beyond a plane's two: the map is a slice, --plane and --held choose it
    if not sliced and (plane is not None or held is not None):
        raise UsageError(f"{'--plane' if plane is not None else '--held'} goes with a chain of links (--config with "
                         "[[links]]); the double pendulum's map is over phi0 x psi0 (--window)")
    if plane is not None and any(name.startswith("d") for name in plane):
        raise UsageError(f"--plane: a flip map starts at rest; give two angles (e.g. q1,q3), got {','.join(plane)}")
    store = ensemble_outputs(ensemble["workers"], ensemble["scheduler"], out, resume, plot)
    from ..analysis.flipmap import flip_map

    kw = run.settings(("t_end", "rtol", "atol"))
    kw.update({k: v for k, v in (("plane", plane), ("held", held), ("ranges", window)) if v is not None})
    with progress(f"computing the flip map ({256 if n is None else n} x {256 if n is None else n} starts)", "cells", quiet) as bar, warnings.catch_warnings():
        # flip_map also warns of failed cells; its status says so, and main() prints it once
        warnings.filterwarnings("ignore", message="flip_map: ", category=RuntimeWarning)
        fm = flip_map(params, 256 if n is None else n, progress=bar, store=store, resume=resume, **ensemble, **kw)
    if out is not None and store is None:
        fm.to_netcdf(out)
    draw_figure(plot, "flipmap_figure", fm)
    flipped = int(fm.flipped.sum())
    st = fm.stats
    wall = f"{st.get('wall_time', float('nan')):.3g} s on {st.get('workers', '?')} workers"
    lines = [
        f"flip map      {fm.n} x {fm.n} starts at rest" + (f" over {fm.plane[0]} x {fm.plane[1]}" if sliced else "")
        + f", t_end = {fm.settings['t_end']:g} s",
        f"flipped       {flipped} of {fm.n * fm.n} ({100 * flipped / (fm.n * fm.n):.1f} %)",
        f"work          {st['integrated']} cells integrated, " + (
            f"{st['skipped_energy']} ruled out by energy, {st['mirrored']} by symmetry; " if fm.settings["energy_bound"]
            else f"{st['steps']} steps; ") + wall,
    ]
    if sliced:  # which angle flipped: the plane's or a held one
        import numpy as np

        counts = np.bincount(np.asarray(fm.which).ravel() + 1, minlength=len(angles) + 1)[1:]
        lines.insert(2, "by joint      " + ", ".join(f"{c}: {k}" for c, k in zip(angles, counts)))
    if "chunks_computed" in st:
        lines.append(f"store         {st['chunks_computed']} chunks computed now, {st.get('chunks_resumed', 0)} already done"
                     + (f"; {st['tasks']} tasks on {st['scheduler']}" if st.get("scheduler") else ""))
    if st.get("failed"):
        lines.append(f"failed        {st['failed']} cells (left NaN: the integration stopped early)")
    lines += [f"{what:14s}{path}" for what, path in (("written", out), ("plot", plot)) if path is not None]
    sys.stdout.write("\n".join(lines) + "\n")
    return fm


@command(MODEL, INITIAL)
def lyapunov(
    model: dict,
    initial: dict,
    t_end: option("--t-end", _SECONDS, "length of the run [s] (default 1000)") = None,
    renorm_every: option("--renorm-every", _SECONDS, "QR re-orthonormalisation interval [s] (default 1)") = None,
    transient: option("--transient", T.NonNegative("number of seconds"), "seconds at the start not counted, a whole number of --renorm-every intervals (default 0)") = None,
    exponents: option("--exponents", T.Whole(1, 64), "how many exponents: all (the spectrum: 4, or 2 n for a chain of n links; default) or 1 (the largest, cheaper)") = None,
    rtol: RTOL_E10 = None,
    atol: ATOL_E10 = None,
    windows: option("--windows", T.Whole(1, 1000), "time windows for the 95 % intervals and the check that the exponents settled, at least 4 for the check (default 10)") = None,
    max_steps: MAX_STEPS_OPTION = None,
    out: option("--out", T.OutPath((".json", ".csv")), "write the result to FILE.json (exponents, settings) or FILE.csv (running estimates)", RUN, "-o") = None,
    plot: plot_option("the running estimates") = None,
    quiet: QUIET = False,
    config: CONFIG = None,
):
    """Lyapunov exponents of the motion from the initial state: Benettin's method (QR) on the
    variational equations generated from the derivation.

    The +- are 95 % intervals from the spread over --windows equal time windows. A run whose
    exponents have not settled (its two halves disagree, or its windows are correlated) prints its
    numbers without error bars and exits 1 with one line saying so and how long to run.

    From a --config run file it takes [parameters], [initial] and [simulation] t_end, rtol, atol, max_steps;
    or a chain of links ([[links]], [chain], [initial] q0, dq0): its 2 n exponents.
    """
    from ..config import whole_multiple

    run = _dop853("lyapunov", config, model, initial, t_end=t_end, rtol=rtol, atol=atol, max_steps=max_steps)
    params, y0 = run.parameters(), run.initial_state()
    every = 1.0 if renorm_every is None else renorm_every
    if transient is not None and not whole_multiple(transient, every):
        raise UsageError(f"--transient: {transient:g} s is not a whole number of renormalisation intervals "
                         f"(--renorm-every {every:g} s): the measurement starts at a renormalisation")
    from .simulate import check_plot

    check_plot(plot)
    import re
    from dataclasses import replace

    from ..analysis.lyapunov import lyapunov as run_lyapunov
    from ..status import Status

    kw = {k: v for k, v in dict(renorm_every=renorm_every, transient=transient, n_exponents=exponents,
                                windows=windows).items() if v is not None}
    kw.update(run.integration(methods=("dop853",)))
    kw.pop("method")
    with progress(f"computing the Lyapunov exponents over {run.number('t_end'):g} s", "s", quiet) as bar:
        spec = run_lyapunov(params, y0, t_end=run.number("t_end"), progress=bar, throw=False, **kw)
    if out is not None:
        _write_lyapunov(spec, out)
    draw_figure(plot, "lyapunov_figure", spec)
    st = spec.stats
    lines = [spec.table()]  # with the Kaplan-Yorke dimension where it means something
    lines.append(f"run      {spec.settings['measured_from']:g} .. {st['t_reached']:g} s, QR every {every:g} s, "
                 f"{st['steps']} steps ({st['rejected']} rejected), {st['wall_time']:.3g} s")
    lines += [f"{what:9s}{path}" for what, path in (("written", out), ("plot", plot)) if path is not None]
    sys.stdout.write("\n".join(lines) + "\n")
    if spec.status == Status.NOT_SETTLED:  # the library's advice in the option the user types
        return replace(spec, message=re.sub(r"e\.g\. t_end = (\S+) s", r"e.g. --t-end \1", spec.message)), ""
    return spec, "; the exponents above cover the time up to there"


def _write_lyapunov(spec, out: str) -> None:
    import json

    import numpy as np

    from ..io import atomic_path

    with atomic_path(out) as tmp:
        if out.lower().endswith(".json"):
            tmp.write_text(json.dumps(spec.to_dict(), indent=2, allow_nan=False) + "\n")  # to_dict: NaN as null
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


@command(MODEL)
def poincare(
    model: dict,
    energy: option("--energy", T.Energy(), "the energy of the orbits [J] (required; 0 = at rest, for thin rods)") = None,
    section: option("--section", T.Section(), "phi=VALUE or psi=VALUE (radians, e.g. 30deg, or a multiple of pi such as pi/2; modulo 360 deg; default phi=0)") = None,
    direction: Annotated[Direction, typer.Option("--direction", help="crossings with the angle increasing (+1), decreasing (-1) or both", rich_help_panel=RUN)] = Direction.up,
    orbits: option("--orbits", T.Whole(1, 100_000), "orbits started on the section (default 50)") = None,
    crossings: option("--crossings", T.Whole(1, 10_000_000), "crossings recorded per orbit (default 500)") = None,
    locate: Annotated[Locate, typer.Option("--locate", help="crossings by the dense output and root finding, or by Henon's trick", rich_help_panel=RUN)] = Locate.dense,
    t_max: option("--t-max", _SECONDS, "longest time per orbit [s] (default 200 small-oscillation periods per crossing)") = None,
    rtol: RTOL_E12 = None,
    atol: ATOL_E12 = None,
    velocity: Annotated[bool, typer.Option("--velocity", help="plot (q, q') instead of the canonical (q, p_q)", rich_help_panel=RUN)] = False,
    out: option("--out", T.OutPath((".csv", ".nc")), "write the points to FILE.csv or FILE.nc", RUN, "-o") = None,
    plot: plot_option("the section") = None,
    workers: option("--workers", T.Whole(1, 1024), "threads (default: every core)") = None,
    quiet: QUIET = False,
    config: CONFIG = None,
):
    """A Poincare section on an energy surface: orbits started on the section, their crossings
    located on the dense output, in the area-preserving coordinates (q, p_q) of the other joint.

    Needs a conservative model (no damping, no torques). From a --config run file it takes
    [parameters] and [simulation] rtol, atol.
    """
    run = _dop853("poincare", config, model, rtol=rtol, atol=atol)
    params = run.parameters()
    if energy is None:
        raise UsageError("--energy is required: the energy of the orbits in joules (e.g. --energy 10)")
    from .simulate import check_plot

    check_plot(plot)
    if velocity and plot is None:
        raise UsageError("--velocity chooses the plot's coordinates: give --plot FILE too")
    from ..analysis.poincare import poincare as run_poincare

    sign = {"+1": 1, "-1": -1, "both": 0}[direction.value]
    kw = {k: v for k, v in dict(section=section, n_orbits=orbits, n_crossings=crossings, t_max=t_max,
                                workers=workers).items() if v is not None}
    with progress("computing the Poincare section", "crossings", quiet) as bar:
        sec = run_poincare(params, energy, direction=sign, locate=locate.value, progress=bar, **kw,
                           **run.settings(("rtol", "atol")))
    if out is not None:
        (sec.to_netcdf if out.lower().endswith(".nc") else sec.to_csv)(out)
    draw_figure(plot, "poincare_figure", sec, canonical=not velocity)
    st = sec.stats
    c, o = sec.coord_names
    lines = [
        f"section   {sec.settings['section']} ({'both directions' if sign == 0 else ('increasing' if sign > 0 else 'decreasing')}), "
        f"energy {energy:g} J (minimum {st['e_min']:.6g} J)",
        f"points    {st['points']} in ({o}, p_{o}) from {st['orbits']} orbits"
        + (f"; {st['orbits_short']} reached t_max first" if st["orbits_short"] else ""),
        f"accuracy  max |energy error| {st['max_energy_error']:.2e} J",
        f"work      {st['steps']} steps, {st['wall_time']:.3g} s on {st['workers']} workers",
    ]
    if st["failed"]:
        lines.append(f"failed    {st['failed']} orbits stopped early (non-finite state, step underflow or max steps)")
    sys.stdout.write("\n".join(lines + _written(("written", out), ("plot", plot))) + "\n")
    return sec


@command(MODEL, ENSEMBLE)
def chaos_diagram(
    model: dict,
    ensemble: dict,
    alphas: option("--alphas", T.Range(angle=True), "skew angles START:STOP:COUNT (e.g. 0:90deg:7, the default)") = None,
    energies: option("--energies", T.Range(angle=False), "energies above the minimum START:STOP:COUNT [J] (default: 8 up to the potential's span)") = None,
    samples: option("--samples", T.Whole(1, 100_000), "starts per cell on the energy surface (default 24)") = None,
    t_end: option("--t-end", _SECONDS, "length of each run [s] (default 150)") = None,
    threshold: option("--threshold", T.Positive(), "largest exponent [1/s] above which a start counts as chaotic (default from the frequencies and t_end)") = None,
    rtol: RTOL_E8 = None,
    atol: ATOL_E8 = None,
    out: option("--out", _STORE, "write the diagram to FILE.zarr (row by row, resumable) or FILE.nc", RUN, "-o") = None,
    plot: plot_option("the diagram") = None,
    resume: Annotated[bool, typer.Option("--resume", help=RESUME.format("rows"), rich_help_panel=RUN)] = False,
    quiet: QUIET = False,
    config: CONFIG = None,
):
    """How the skew angle changes chaos: for each alpha and energy, the fraction of starts on
    that energy surface whose largest Lyapunov exponent is clearly positive.

    Needs a conservative model (no damping, no torques); alpha is the diagram's axis (use
    --alphas, not --alpha). From a --config run file it takes [parameters] (but alpha) and
    [simulation] t_end, rtol, atol.
    """
    if model.get("alpha") is not None:
        raise UsageError("--alpha: the chaos diagram varies alpha itself; give the angles with --alphas START:STOP:COUNT")
    run = _dop853("chaos-diagram", config, model, t_end=t_end, rtol=rtol, atol=atol)
    run.values["parameters"].pop("alpha", None)  # the default's: the diagram's axis replaces it
    params = run.parameters()
    store = ensemble_outputs(ensemble["workers"], ensemble["scheduler"], out, resume, plot)
    from ..analysis.chaos import chaos_diagram as run_diagram

    kw = {k: v for k, v in dict(alpha=alphas, energy=energies, samples=samples, threshold=threshold).items() if v is not None}
    kw.update(run.settings(("t_end", "rtol", "atol")))
    with progress("computing the chaos diagram", "alphas", quiet) as bar:
        d = run_diagram(params, progress=bar, store=store, resume=resume, **ensemble, **kw)
    if out is not None and store is None:
        d.to_netcdf(out)
    draw_figure(plot, "chaos_diagram_figure", d)
    st = d.stats
    lines = [
        f"chaotic fraction (largest exponent > {d.threshold:.3g} 1/s over {kw.get('t_end', 150.0):g} s, "
        f"{kw.get('samples', 24)} starts per cell on phi = 0)",
        d.table(),
        f"work      {st['trajectories']} trajectories, {st['wall_time']:.3g} s on {st['workers']} workers"
        + (f"; {st['rows_resumed']} rows already in the store" if st.get("rows_resumed") else ""),
    ]
    if st["failed"]:
        lines.append(f"failed    {st['failed']} trajectories (left NaN)")
    sys.stdout.write("\n".join(lines + _written(("written", out), ("plot", plot))) + "\n")
    return d
