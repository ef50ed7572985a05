"""``modes``: the normal modes about the hanging equilibrium, a sweep of them over a parameter,
their closed-form characteristic equation, and a check against the nonlinear motion."""

from __future__ import annotations

import sys
from enum import Enum
from typing import Annotated, Optional

import typer

from ..parsing import UsageError
from . import types as T
from .equations import Coulomb
from .options import CONFIG, MODEL_NO_TORQUE, command, option, resolve

COMMANDS = ("modes",)


class ModesFormat(str, Enum):
    text = "text"
    json = "json"
    latex = "latex"


@command(MODEL_NO_TORQUE)
def modes(
    model: dict,
    fmt: Annotated[ModesFormat, typer.Option("--format", "-f", help="text, json, or latex (the closed-form characteristic equation in the parameters not given; not with --sweep, --plot, --out, --tolerance, --check-nonlinear)")] = ModesFormat.text,
    sweep_spec: Annotated[Optional[str], typer.Option("--sweep", help="NAME=START:STOP:COUNT over alpha, a, b, m1, m2, g, b/a or m2/m1, or a link's length, mass, damping or tilt and its number (e.g. alpha=0:180deg:181, tilt2=0:90deg:31; a unit on either end applies to the whole range, plain numbers are radians; default: no sweep, the modes of the one model)")] = None,
    plot: Annotated[Optional[str], typer.Option("--plot", help="with --sweep: write the frequency curves to FILE (.png, .pdf, .svg)")] = None,
    out: Annotated[Optional[str], typer.Option("--out", "-o", help="with --sweep: write the table to FILE (.csv or .json; alpha in rad plus alpha_deg)")] = None,
    # parsed after the check that it goes with --sweep (a misplaced option is the first thing to say)
    tolerance: Annotated[Optional[str], typer.Option("--tolerance", metavar="NUMBER", help="with --sweep: flag the neighbouring modes' w(k+1)/w(k) (w2/w1) within tolerance*n of n = 1, 2, 3 (a positive number; default 0.01)")] = None,
    check_nonlinear: option("--check-nonlinear", T.Angle("ANGLE"), "AMPLITUDE [rad or deg]: measure the frequencies of the nonlinear motion started from each mode (undamped, no --sweep; default: not measured)", None) = None,
    about: option("--about", T.EquilibriumChoice(), "the modes about another equilibrium: a label (down-up, up-down, up-up; see skewpend equilibria) or PHI,PSI near one; an unstable direction is given as a growth rate (not with --sweep, --check-nonlinear, --format latex)", None) = None,
    coulomb: Annotated[Optional[Coulomb], typer.Option("--coulomb", help="Coulomb friction (cf1, cf2) in the linearisation: exclude (default: it is non-smooth at rest, cf sign(q') has no slope there) or smoothed (the slope cfs*cf of its smoothed form cf atan(cfs q') as viscous damping); not with --sweep, --format latex")] = None,
    config: CONFIG = None,
) -> None:
    """Normal modes of the small oscillations about the hanging equilibrium or another one (and how alpha shapes them).

    A model whose centres of mass lie a little off the rods' lines (a fitted one: skewpend identify
    --out fit.toml) hangs at rest slightly away from phi = psi = 0: its modes are taken about that
    rest (down-down), and the output says so; so are a model file's whose zero is upright (the
    DeepMind acrobot's: its hanging rest is phi = 180 deg).
    """
    given = model
    # every option takes effect or is refused, before any work is done
    if coulomb is not None and (fmt is ModesFormat.latex or sweep_spec is not None):
        raise UsageError("--coulomb sets how Coulomb friction enters the damping; --format latex and --sweep give undamped "
                         "frequencies, so it has no effect there: leave it out")
    if fmt is ModesFormat.latex:
        extra = [o for o, v in (("--sweep", sweep_spec), ("--plot", plot), ("--out", out), ("--tolerance", tolerance),
                                ("--check-nonlinear", check_nonlinear), ("--about", about)) if v is not None]
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
    if about is not None and (sweep_spec is not None or check_nonlinear is not None):
        raise UsageError("--about goes without --sweep and --check-nonlinear (they are about the hanging equilibrium)")
    from ..analysis import modes as md

    run = resolve("modes", config, parameters=given)
    params = run.parameters()
    if sweep_spec is not None:
        tol = 0.01 if tolerance is None else T.Positive().convert(tolerance, "--tolerance")
        _modes_sweep(params, sweep_spec, plot, out, tol, fmt, given)
        return
    amplitude = check_nonlinear
    if amplitude is not None and (amplitude == "sym" or not 0 < amplitude < 3.141592653589793):
        raise UsageError(
            f"--check-nonlinear: expected an amplitude between 0 and 180 deg exclusive (radians, or e.g. 10deg), got {amplitude!r}"
        )
    how = "exclude" if coulomb is None else coulomb.value
    result, rest, upright = _modes_of(md, params, about, how, amplitude is None)
    check = md.check_nonlinear(params, amplitude) if amplitude is not None else None
    if fmt is ModesFormat.json:
        import json

        data = result.to_dict()
        if rest:
            data["about"] = rest
        if "coulomb_note" in data:
            data["coulomb_note"] = _coulomb_line(result)
        if check is not None:
            data["nonlinear_check"] = {
                "amplitude": check.amplitude,
                "measured_frequencies": check.measured.tolist(),
                "relative_shift": check.relative_shift.tolist(),
            }
        sys.stdout.write(json.dumps(data, indent=2) + "\n")
        return
    sys.stdout.write(_modes_text(result, check, rest, upright))


def _modes_of(md, params, about, coulomb: str, fallback: bool):  # -> (modes, rest, upright)
    """The modes the user meant, the label of the hanging rest they are about when that is not q = 0
    ('' otherwise) and whether that is because the model's zero is upright: without --about, a model whose zero is upright (a model file's: the DeepMind
    acrobot) has its modes about its hanging rest (normal_modes finds it from the geometry), and a
    model with no torques whose phi = psi = 0 is no equilibrium (its centres of mass a little off the
    rods' lines, as a fitted model's are) is taken about its hanging rest, down-down."""
    from ..errors import EquilibriumError, SkewpendError

    try:
        result = md.normal_modes(params, about=about, coulomb=coulomb)
        # without --about, modes away from q = 0 are the hanging rest's: the model's zero is upright (the DeepMind
        # acrobot's; normal_modes finds its down-...-down rest from the geometry)
        upright = about is None and any(result.equilibrium)
        return result, ("-".join(["down"] * params.n) if upright else ""), upright
    except EquilibriumError as exc:
        if about is not None or not fallback or any(link.torque for link in params.as_chain().links) \
                or "not an equilibrium" not in str(exc):
            raise
        rest = "-".join(["down"] * params.n)
        try:
            result = md.normal_modes(params, about=rest, coulomb=coulomb)
        except SkewpendError:
            raise exc from None
    return result, rest, False


def _coulomb_line(m) -> str:
    """The result's Coulomb friction note, naming the option in the command line's spelling."""
    from ..symbolic.friction import coulomb_note

    return coulomb_note(m.params, m.coulomb, option="--coulomb smoothed")


def _modes_text(m, check, rest: str = "", upright: bool = False) -> str:
    """The modes as text: a row a mode, its shape over the model's coordinates and the amplitude ratio of the
    last coordinate over the first (the double pendulum's psi/phi); the beat period of the two lowest modes."""
    import numpy as np

    coords = m.params.coordinates
    n = len(coords)
    at = ", ".join(f"{c} = {np.degrees(x):.6g} deg" for c, x in zip(coords, m.equilibrium))
    if not any(m.equilibrium):
        lines = [f"Normal modes about the hanging equilibrium ({' = '.join(coords)} = 0)", ""]
    elif rest and not upright:
        lines = [f"Normal modes about the hanging rest ({rest}) at {at}: {' = '.join(coords)} = 0 is no equilibrium of "
                 "this model (its centres of mass lie off the rods' lines)", ""]
    elif rest:
        lines = [f"Normal modes about the hanging rest ({rest}) at {at}: the model's zero, {' = '.join(coords)} = 0, "
                 "is not hanging (a model file's own zero, upright for the DeepMind acrobot)", ""]
    else:
        lines = [f"Modes about the equilibrium {at}", ""]
    head = f"shape ({', '.join(coords)}), M0-normalised"
    width = max(34, len(head), 12 * n)
    ratio_head = f"{coords[-1]}/{coords[0]}" if n > 1 else ""
    lines.append(f"{'mode':>4}  {'omega [rad/s]':>14}  {'f [Hz]':>10}  {'period [s]':>11}  {head:>{width}}"
                 + (f"  {ratio_head:>9}" if ratio_head else ""))
    for k in range(n):
        shape = "(" + ", ".join(f"{x:+.6f}" for x in m.shapes[:, k]) + ")"
        ratio = ("inf" if not np.isfinite(m.ratios[k]) else f"{m.ratios[k]:.5g}") if ratio_head else ""
        columns = f"{shape:>{width}}" + (f"  {ratio:>9}" if ratio_head else "")
        if m.unstable[k]:
            lines.append(f"{k + 1:>4}  {'--':>14}  {'--':>10}  {'--':>11}  {columns}  unstable: "
                         f"grows like exp({m.growth_rates[k]:.8g} t / s)")
            continue
        lines.append(f"{k + 1:>4}  {m.frequencies[k]:14.8g}  {m.frequencies[k] / (2 * np.pi):10.6g}  "
                     f"{m.periods[k]:11.6g}  {columns}")
    if n > 1 and not np.any(m.unstable):
        beat = "inf (1:1)" if not np.isfinite(m.beat_period) else f"{m.beat_period:.6g} s"
        lines.append(f"beat period 2 pi/(w2 - w1) = {beat};  w2/w1 = {m.frequencies[1] / m.frequencies[0]:.6g}")
    if m.damped:
        lines.append("with damping (eigenvalues matched to the modes by shape; zeta = -(l1 + l2)/(2 sqrt(l1 l2))):")
        for k in range(n):
            l1, l2 = m.eigenvalue_pairs[k]
            if m.unstable[k]:
                lines.append(f"  mode {k + 1}: unstable, lambda = {l1.real:.6g} and {l2.real:.6g} (real), "
                             f"growth rate {m.growth_rates[k]:.6g} 1/s")
            elif m.overdamped[k]:
                lines.append(
                    f"  mode {k + 1}: overdamped, lambda = {l1.real:.6g} and {l2.real:.6g} (real), zeta = {m.damping_ratios[k]:.4g}"
                )
            else:
                lines.append(
                    f"  mode {k + 1}: lambda = {l1.real:.6g} +/- {abs(l1.imag):.6g} i, "
                    f"damped omega = {m.damped_frequencies[k]:.6g} rad/s, zeta = {m.damping_ratios[k]:.4g}"
                )
    if m.coulomb_note:
        lines.append(_coulomb_line(m))
    if check is not None:
        lines.append("")
        lines.append(f"nonlinear check, largest initial angle {check.amplitude:.6g} rad ({np.degrees(check.amplitude):.4g} deg):")
        for k in range(len(check.measured)):
            lines.append(
                f"  mode {k + 1}: linear {check.linear[k]:.8g} rad/s, measured {check.measured[k]:.8g} rad/s "
                f"over {check.cycles[k]} cycles, shift {check.relative_shift[k]:+.3e}"
            )
    return "\n".join(lines) + "\n"


def _modes_latex(given: dict, config: Optional[str]) -> None:
    """The closed form for the parameters given (options over the config's [parameters]);
    the others stay symbolic.  Damping and torques do not enter det(K0 - w^2 M0): refused."""
    from ..analysis.modes import characteristic_equation
    from ..errors import EquilibriumError
    from ..schema import DAMPING_NAMES, TORQUE_NAMES
    from ..symbolic import render

    tex = render.tex  # the renderer's LaTeX of one expression
    run = resolve("modes", config, defaults=False, parameters=given)
    for keys, why in (
        (TORQUE_NAMES, "phi = psi = 0 is not an equilibrium with constant joint torques; normal modes need "
                       + " = ".join(TORQUE_NAMES) + " = 0"),
        (DAMPING_NAMES, None),
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
        r"\det\left(K_0 - \omega^2 M_0\right) = 0 \;\Longleftrightarrow\; " + tex(eq.lhs) + " &= 0",
        r"\omega_1^2 &= " + tex(roots[0]),
        r"\omega_2^2 &= " + tex(roots[1]),
    ]
    sys.stdout.write("\\[\n\\begin{aligned}\n" + " \\\\\n".join(body) + "\n\\end{aligned}\n\\]\n")


def _modes_sweep(params, spec, plot, out, tolerance, fmt, given) -> None:
    import numpy as np

    from ..analysis import modes as md

    name, values = md.parse_sweep(spec, params)
    swept = md.SWEPT_PARAMETER.get(name, name)
    if given.get(swept) is not None:
        raise UsageError(f"--{swept} and --sweep {name}=... both set {swept}; the sweep gives every value, so leave out --{swept}")
    from ..io import check_output_path

    if out is not None:
        check_output_path(out, (".csv", ".json"), option="--out")
    if plot is not None:
        check_output_path(plot, (".png", ".pdf", ".svg"), option="--plot")
    sw = md.sweep(params, name, values, tolerance=tolerance)
    if out is not None:
        from ..io import atomic_path

        with atomic_path(out) as tmp:
            if str(out).lower().endswith(".csv"):
                cols, rows = sw.columns()
                np.savetxt(tmp, rows, delimiter=",", header=",".join(cols), comments="", fmt="%.17g")
            else:
                import json

                tmp.write_text(json.dumps(sw.to_dict(), indent=2) + "\n")
    if plot is not None:
        from ..views.figures import plot_sweep, save_figure

        save_figure(plot_sweep(sw), plot)
    if fmt is ModesFormat.json:
        import json

        sys.stdout.write(json.dumps(sw.to_dict(), indent=2) + "\n")
        return
    # alpha is reported in radians (the SI unit of the files) and in degrees (the plot's axis)
    angle = name == "alpha" or name.startswith("tilt")
    show = (lambda v: f"{v:.6g} rad ({np.degrees(v):.4g} deg)") if angle else (lambda v: f"{v:.6g}")
    n = sw.modes_count
    pairs = [f"w{k + 2}/w{k + 1}" for k in range(n - 1)]
    ratios = sw.frequencies[:, 1:] / sw.frequencies[:, :-1]
    lines = [f"swept {name} over {show(values[0])} .. {show(values[-1])} ({values.size} values)",
             ";  ".join([f"omega{k + 1}: {sw.frequencies[:, k].min():.6g} .. {sw.frequencies[:, k].max():.6g} rad/s"
                         for k in range(n)] + [f"{pair}: {ratios[:, k].min():.6g} .. {ratios[:, k].max():.6g}"
                                               for k, pair in enumerate(pairs)])]
    if out is None:  # the table, unless written to a file
        lines.append(sw.table())
    which = ", ".join(pairs)
    if sw.resonances:
        lines.append(f"internal resonances ({which} within {tolerance:g}*n of n):")
        for r in sw.resonances:
            how = "crossed at" if r.crossed else f"closest ({r.ratio:.5g}) at"
            lines.append(f"  {r.order}:1  w{r.pair[1]}/w{r.pair[0]}  {how} {name} = {show(r.value)}")
    else:
        lines.append(f"no internal resonance 1:1, 2:1, 3:1 ({which}) within {tolerance:g}*n")
    for what, path in (("table", out), ("plot", plot)):
        if path is not None:
            lines.append(f"wrote {what} {path}")
    sys.stdout.write("\n".join(lines) + "\n")


