"""Between the linear modes and chaos: ``equilibria`` (every equilibrium, its stability and
linearisation), ``orbit`` (one periodic orbit, from a guess or a nonlinear normal mode) and ``nnm``
(the families of periodic orbits continuing the linear modes: the backbones)."""

from __future__ import annotations

import sys
from enum import Enum
from typing import Annotated

import typer

from ..parsing import UsageError
from . import types as T
from ..progress import stage
from .options import CONFIG, INITIAL, MODEL, QUIET, RUN, command, option, plot_option, progress, resolve
from .simulate import check_plot

COMMANDS = ("equilibria", "orbit", "nnm")
_ENERGY = T.Positive("number of joules")


class EquilibriaFormat(str, Enum):
    text = "text"
    json = "json"


@command(MODEL)
def equilibria(
    model: dict,
    fmt: Annotated[EquilibriaFormat, typer.Option("--format", "-f", help="text (a table) or json")] = EquilibriaFormat.text,
    config: CONFIG = None,
) -> None:
    """Every equilibrium on the torus (constant torques allowed): its energy, stability, Morse index, frequencies and growth rates.

    From a --config run file it takes [parameters].
    """
    from ..analysis.equilibria import equilibria as find

    params = resolve("equilibria", config, parameters=model).parameters()
    result = find(params)
    if fmt is EquilibriaFormat.json:
        import json

        from ..results import plain

        data = {
            "equilibria": [
                {"label": e.label, **({"phi": e.q[0], "psi": e.q[1]} if len(e.q) == 2 else {"q": list(e.q)}),
                 "potential": e.potential, "morse_index": e.morse_index,
                 "stable": e.stable, "frequencies": e.frequencies, "growth_rates": e.growth_rates,
                 "unstable_directions": e.unstable_directions.T, "eigenvalues": [[z.real, z.imag] for z in e.eigenvalues],
                 "M": e.M, "C": e.C, "K": e.K}
                for e in result
            ],
            "index_sum": result.index_sum,
            "status": result.status.name,
            "message": result.message,
        }
        sys.stdout.write(json.dumps(plain(data), indent=2, allow_nan=False) + "\n")
    else:
        sys.stdout.write(result.table() + "\n" + result.message + "\n")
    return result


@command(MODEL, INITIAL)
def orbit(
    model: dict,
    initial: dict,
    mode: option("--mode", T.Whole(1, 64), "the orbit of nonlinear normal mode 1 or 2 (a chain's 1 to n) at --energy (continued from the linear mode; default: none, the orbit through the guess: --phi0 --psi0 --dphi0 --dpsi0, a chain's --q0 --dq0)") = None,
    energy: option("--energy", _ENERGY, "the orbit's energy [J] (with --mode; with a guess, default the guess's energy)") = None,
    period: option("--period", T.Positive("number of seconds"), "with a guess (--phi0 --psi0 --dphi0 --dpsi0, a chain's --q0 --dq0): its period [s] (required with a guess)") = None,
    rotation: option("--rotation", T.Numbers(most=64, whole=True, metavar="R1,R2,..."), "whole turns of each joint per period: phi and psi, R1,R2 (a chain's one a link; a rotating orbit; default none)") = None,
    out: option("--out", T.OutPath((".nc",)), "write the orbit (start, period, monodromy matrix, multipliers) to FILE.nc", RUN, "-o") = None,
    plot: plot_option("the orbit over one period") = None,
    quiet: QUIET = False,
    config: CONFIG = None,
):
    """A periodic orbit and its stability (Floquet multipliers): from a guess (the initial-state options and --period) or as a nonlinear normal mode at an energy (--mode, --energy).

    From a --config run file it takes [parameters] and [initial]; or a chain of links ([[links]], [chain], or --links N: its guess --q0 --dq0, --mode 1 to n), conservative (no damping, friction or torques).
    """
    from ..analysis.orbits import periodic_orbit

    guessed = any(v is not None for v in initial.values())
    run = resolve("orbit", config, parameters=model, initial=initial)  # the model, once: it spells its start
    start = " ".join(run.start_options())
    if mode is not None and (guessed or period is not None or rotation is not None):
        raise UsageError(f"--mode finds the orbit of a nonlinear normal mode; a guess ({start}, --period, --rotation) goes without it")
    if mode is not None and energy is None:
        raise UsageError("--mode needs --energy (the energy of the orbit wanted) [J]")
    if mode is None and period is None:
        raise UsageError(f"an orbit needs a guess ({start} and --period) or --mode and --energy")
    check_plot(plot)
    params = run.parameters()
    if mode is not None:
        with progress(f"continuing nonlinear normal mode {mode} up to {energy:g} J", "J", quiet) as bar:
            result = periodic_orbit(params, mode=mode, energy=energy, progress=bar)
    else:
        turns = (0, 0) if rotation is None else tuple(rotation)  # whole numbers of turns, one a joint: the library checks them
        with progress("finding the periodic orbit (Newton iterations)", "", quiet) as bar:
            result = periodic_orbit(params, run.initial_state(), period, energy=energy, rotation=turns, progress=bar)
    sys.stdout.write(result.table() + "\n")
    if result.ok:
        if out is not None:
            result.to_netcdf(out)
        if plot is not None:
            stage(f"drawing {plot}")
            from ..views import figures

            figures.save_figure(figures.simulation_figure(result.trajectory()), plot)
    return result


@command(MODEL)
def nnm(
    model: dict,
    mode: option("--mode", T.Whole(1, 64), "the family: 1 (from the lower linear mode) or 2 (a chain's 1 to n); default every one, with their internal resonances") = None,
    energy_max: option("--energy-max", _ENERGY, "continue up to this energy [J] (default: the lowest energy at which a joint can flip)") = None,
    resolution: option("--resolution", T.Whole(1, 100000), "at least this many orbits per family up to --energy-max (default 200)") = None,
    orbits_at: option("--orbits-at", T.Numbers(most=4, metavar="E1,E2,..."), "with --plot: draw the orbits at these energies E1,E2,... [J] beside the curves (at most 4; default two)") = None,
    alphas: option("--alphas", T.Range(angle=True), "instead of energy: follow the orbit at --energy along the skew angles START:STOP:COUNT (e.g. 0:90deg:46; needs --mode)") = None,
    energy: option("--energy", _ENERGY, "with --alphas: the fixed energy [J]") = None,
    out: option("--out", T.OutPath((".nc",)), "write the family (energies, periods, starts, multipliers) to FILE.nc (needs --mode)", RUN, "-o") = None,
    plot: plot_option("the frequency-energy plot") = None,
    quiet: QUIET = False,
    config: CONFIG = None,
):
    """Nonlinear normal modes: the families of periodic orbits continuing the linear modes as the energy grows (the backbones), their stability, bifurcations and internal resonances.

    From a --config run file it takes [parameters]; or a chain of links ([[links]], [chain]): its n families.
    """
    from ..analysis.orbits import backbones, nnm as continue_mode

    if (alphas is None) != (energy is None):
        raise UsageError("--alphas and --energy go together: the orbit at a fixed energy followed along alpha")
    if alphas is not None:
        return _along_alpha(model, mode, alphas, energy, energy_max, resolution, orbits_at, out, plot, quiet, config)
    if out is not None and mode is None:
        raise UsageError("--out writes one family: give --mode 1 or --mode 2")
    if orbits_at is not None and plot is None:
        raise UsageError("--orbits-at chooses the orbits drawn by --plot; give --plot FILE")
    if orbits_at is not None and any(not e > 0 for e in orbits_at):
        raise UsageError(f"--orbits-at: expected at most four positive energies E1,E2,... [J], got {orbits_at!r}")
    check_plot(plot)
    params = resolve("nnm", config, parameters=model).parameters()
    kw = {} if resolution is None else {"resolution": resolution}
    with progress("continuing the nonlinear normal modes" if mode is None else f"continuing nonlinear normal mode {mode}", "J", quiet) as bar:
        if mode is None:
            result = backbones(params, energy_max=energy_max, progress=bar, **kw)
            fams, resonances = result.families, result.resonances
        else:
            result = continue_mode(params, mode=mode, energy_max=energy_max, progress=bar, **kw)
            fams, resonances = [result], []
    lines = []
    for f in fams:
        lines += [f"mode {f.mode}: linear frequency {f.linear_frequency:.9g} rad/s; {f.message}", f.table(), ""]
    for r in resonances:
        lines.append(f"internal resonance {r.detail} at E = {r.energy:.6g} J")
    if out is not None:
        fams[0].to_netcdf(out)
        lines.append(f"written       {out}")
    if plot is not None:
        stage(f"drawing {plot}")
        from ..views import figures

        energies = list(orbits_at) if orbits_at is not None else [0.2 * fams[0].energy_max, 0.9 * fams[0].energy_max]
        drawn = [(f.mode, float(E), f.at_energy(E).trajectory()) for f in fams for E in energies
                 if E <= f.energies.max()]
        figures.save_figure(figures.fep_figure(fams, orbits=drawn[:4], resonances=resonances), plot)
        lines.append(f"plot          {plot}")
    sys.stdout.write("\n".join(lines).rstrip() + "\n")
    return result


def _along_alpha(model, mode, alphas, energy, energy_max, resolution, orbits_at, out, plot, quiet, config):
    from ..analysis.orbits import nnm_alpha

    if mode is None:
        raise UsageError("--alphas follows one family: give --mode 1 or --mode 2")
    extra = [o for o, v in (("--energy-max", energy_max), ("--resolution", resolution), ("--orbits-at", orbits_at))
             if v is not None]
    if extra:
        raise UsageError(f"{', '.join(extra)} go with the continuation in energy, not with --alphas")
    if model.get("alpha") is not None:
        raise UsageError("--alpha: the continuation varies alpha itself; give the angles with --alphas START:STOP:COUNT")
    check_plot(plot)
    params = resolve("nnm", config, parameters={**model, "alpha": float(alphas[0])}).parameters()
    with progress(f"following nonlinear normal mode {mode} along alpha", "angles", quiet) as bar:
        fam = nnm_alpha(params, mode, energy=energy, alphas=alphas, progress=bar)
    lines = [f"mode {fam.mode} at E = {fam.energy:g} J: {fam.message}", fam.table()]
    if out is not None:
        fam.to_netcdf(out)
        lines.append(f"written       {out}")
    if plot is not None:
        stage(f"drawing {plot}")
        from ..views import figures

        figures.save_figure(figures.alpha_family_figure(fam), plot)
        lines.append(f"plot          {plot}")
    sys.stdout.write("\n".join(lines) + "\n")
    return fam
