"""Section 8 of the report: beyond small oscillations -- every equilibrium, and the nonlinear
normal modes (the backbones) up to the energy at which a joint can flip."""

from __future__ import annotations

import math
from typing import List

from ...errors import SkewpendError
from .common import Context, esc, facts_html, fig_png, figure_html, fmt_num, prose, table_html

#: Orbits per family in the report (the library's default is 200; the curve is as smooth).
REPORT_RESOLUTION = 80


def _equilibria_html(ctx: Context) -> List[str]:
    from ...analysis.equilibria import equilibria

    try:
        eq = equilibria(ctx.params)
    except SkewpendError as exc:
        return [f'<p class="callout warn">The equilibria could not be found: {esc(exc)}</p>']
    rows = []
    for e in eq:
        kind = {0: "stable (minimum of V)", 1: "saddle", 2: "maximum of V"}[e.morse_index]
        freq = ", ".join(fmt_num(w, 5) for w in e.frequencies) or "—"
        grow = ", ".join(fmt_num(s, 5) for s in e.growth_rates) or "—"
        rows.append([esc(e.label), fmt_num(math.degrees(e.q[0]), 5), fmt_num(math.degrees(e.q[1]), 5),
                     fmt_num(e.potential, 5), f"{e.morse_index}: {kind}", freq, grow])
    ctx.notes["equilibria"] = eq.message
    return [
        prose("<p>At rest the equations of motion reduce to $\\partial\\Pi/\\partial q = \\tau$: an equilibrium is a "
              "critical point of $V = \\Pi - \\tau\\cdot q$. All of them, found by Newton's method from a grid of starts "
              "over the torus and checked complete by the Morse indices (their alternating sum is 0 on a torus), each "
              "with the frequencies of its oscillating directions and the growth rates of its unstable ones (a "
              "disturbance grows like $e^{s t}$):</p>"),
        table_html(["rods (1-2)", "φ [deg]", "ψ [deg]", "V [J]", "Morse index", "frequencies [rad/s]",
                    "growth rates s [1/s]"], rows, numeric=(1, 2, 3), caption=esc(eq.message)),
    ]


def backbone_facts(bb) -> List:
    """What the families of nonlinear normal modes found (the double pendulum's two or a chain's n): each
    family's orbits and frequency change, its stability changes, the internal resonances (label, HTML)."""
    import re

    facts = []
    for fam in bb.families:
        drop = 100 * (1 - fam.frequencies[-1] / fam.linear_frequency)
        facts.append((f"mode {fam.mode}", f"{len(fam)} orbits; frequency {fmt_num(fam.linear_frequency, 5)} → "
                                          f"{fmt_num(fam.frequencies[-1], 5)} rad/s ({fmt_num(abs(drop), 3)} % "
                                          f"{'lower' if drop > 0 else 'higher'}) at {fmt_num(fam.energies[-1], 4)} J"))
        for ev in fam.events:
            facts.append((f"mode {fam.mode}: {esc(ev.kind)}", f"E = {fmt_num(ev.energy, 4)} J — {esc(ev.detail)}"))
    sub = str.maketrans("0123456789", "₀₁₂₃₄₅₆₇₈₉")
    for r in bb.resonances:
        detail = re.sub(r"w(\d+)", lambda m: "ω" + m.group(1).translate(sub), r.detail)
        facts.append(("internal resonance", f"{esc(detail)} at E = {fmt_num(r.energy, 4)} J"))
    return facts


def section_orbits(ctx: Context) -> str:
    from dataclasses import replace

    from ...analysis.orbits import backbones
    from .. import figures as F

    out = [prose(
        "<p>Between the small oscillations of section 4 and the chaos of section 7 lie the other equilibria and the "
        "<b>nonlinear normal modes</b>: the families of periodic orbits that continue each linear mode as the energy "
        "grows.</p>")]
    out += _equilibria_html(ctx)
    p = ctx.params
    if p.tau1 or p.tau2:
        out.append('<p class="callout">With constant torques the modes start from a shifted equilibrium; the backbones '
                   "are drawn for the model without torques by <code>skewpend nnm</code> (<code>--tau1 0 --tau2 0</code>).</p>")
        ctx.notes["orbits"] = "backbones not drawn (torques)"
        return "\n".join(out)
    damped = bool(p.c1 or p.c2)
    q = replace(p, c1=0.0, c2=0.0) if damped else p
    try:
        bb = backbones(q, resolution=REPORT_RESOLUTION)
    except SkewpendError as exc:
        ctx.notes["orbits"] = "could not be computed"
        out.append(f'<p class="callout warn">The nonlinear normal modes could not be computed: {esc(exc)}</p>')
        return "\n".join(out)
    f1, f2 = bb.families
    E_max = max(f1.energy_max, f2.energy_max)
    orbits = []
    for fam in (f1, f2):
        for frac in (0.25, 0.95):
            E = frac * E_max
            if fam.energies.size and E <= fam.energies.max():
                orbits.append((fam.mode, E, fam.at_energy(E).trajectory(200)))
    fig = F.fep_figure(bb, orbits=orbits)
    caption = prose(
        "Frequency $2\\pi/T$ of each nonlinear normal mode against its energy above the hanging rest, from the linear "
        "frequencies of section 4 (◀) up to " + f"{fmt_num(E_max, 4)} J, the lowest energy at which a joint can flip "
        "(the lowest potential on the boundary of the square |φ|, |ψ| ≤ 180°). Solid: stable orbits (the Floquet "
        "multipliers on the unit circle); dashed: unstable; circles: a multiplier passing +1 (branch point), squares: "
        "−1 (period doubling); dotted: an internal resonance, where the two frequencies are in a small whole-number "
        "ratio. Right: four of the orbits in the (φ, ψ) plane (the dot: the start).")
    if damped:
        caption += " Drawn for the undamped model (c₁ = c₂ = 0): with damping no motion is periodic."
    out.append(prose(
        "<p>Each orbit is found by <b>shooting</b>: Newton's method on the start and the period so that the motion "
        "closes after one period at the given energy, with the derivative of the flow from the variational equations "
        "(the same compiled code as the Lyapunov exponents); the family is followed by pseudo-arclength continuation. "
        "The eigenvalues of the monodromy matrix (the flow's derivative over one period) decide the stability.</p>"))
    out.append(figure_html(fig_png(fig), caption, "frequency-energy plot of the nonlinear normal modes"))
    out.append(facts_html(backbone_facts(bb)))
    ctx.notes["orbits"] = (f"{len(f1)} + {len(f2)} orbits up to {fmt_num(E_max, 4)} J"
                           + (" (undamped model)" if damped else ""))
    return "\n".join(out)
