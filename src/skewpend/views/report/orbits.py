"""Section 8 of the report: beyond small oscillations -- every equilibrium, and the nonlinear
normal modes (the backbones) up to the energy at which a joint can flip -- for any model."""

from __future__ import annotations

import math
from typing import List

from ... import schema
from ...errors import SkewpendError
from .common import Context, answers_names, detail, esc, facts_html, fig_png, figure_html, fmt_num, prose, table_html
from .system import SUBSCRIPTS, label

#: Orbits per family in the report (the library's default is 200; the curve is as smooth), past two links
#: LONG_RESOLUTION (each family is a continuation of shooting problems of 2 n + 1 unknowns).
REPORT_RESOLUTION = 80
LONG_RESOLUTION = 40
#: The longest chain whose nonlinear normal modes the report follows.
NNM_MAX_LINKS = 4


def _equilibria_html(ctx: Context) -> List[str]:
    from ...analysis.equilibria import equilibria

    n = ctx.params.n
    detail("the equilibria")
    try:
        eq = equilibria(ctx.params)
    except SkewpendError as exc:
        return [f'<p class="callout warn">The equilibria could not be found: {esc(exc)}</p>']
    rows = []
    for e in eq:
        kind = {0: "stable (minimum of V)", n: "maximum of V"}.get(e.morse_index, "saddle")
        sep = ", " if n <= 2 else "<br>"  # a list a line past two links: the table's width
        freq = sep.join(fmt_num(w, 5) for w in e.frequencies) or "—"
        grow = sep.join(fmt_num(s, 5) for s in e.growth_rates) or "—"
        rows.append([esc(e.label), *(fmt_num(math.degrees(x), 5) for x in e.q), fmt_num(e.potential, 5),
                     f"{e.morse_index}: {kind}", freq, grow])
    ctx.notes["equilibria"] = eq.message
    return [
        prose("<p>At rest the equations of motion reduce to $\\partial\\Pi/\\partial q = \\tau$: an equilibrium is a "
              "critical point of $V = \\Pi - \\tau\\cdot q$. All of them, found by Newton's method from a grid of starts "
              f"over the {'torus' if n <= 2 else f'{n}-torus'} and checked complete by the Morse indices (their "
              "alternating sum is 0 on a torus), each with the frequencies of its oscillating directions and the growth "
              "rates of its unstable ones (a disturbance grows like $e^{s t}$):</p>"),
        table_html([f"rods (1-{n})", *(f"{label(c)} [deg]" for c in ctx.params.coordinates), "V [J]", "Morse index",
                    f"frequencies{sep if n > 2 else ' '}[rad/s]", f"growth rates{sep if n > 2 else ' '}s [1/s]"], rows,
                   numeric=tuple(range(1, n + 2)),
                   caption=esc(eq.message)),
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


def _undamped(p):
    """The model without viscous damping (with it no motion is periodic): by the names it answers, else its links."""
    links = p.as_chain().links
    if not any(link.damping for link in links):
        return p, False
    if answers_names(p):
        return p.replace(**{name: 0.0 for name in schema.DAMPING_NAMES}), True
    chain = p
    for link in links:
        chain = chain.replace_link(link.index, damping=0.0) if link.damping else chain
    return chain, True


def section_orbits(ctx: Context) -> str:
    from ...analysis.orbits import backbones
    from .. import figures as F

    out = [prose(
        "<p>Between the small oscillations of section 4 and the chaos of section 7 lie the other equilibria and the "
        "<b>nonlinear normal modes</b>: the families of periodic orbits that continue each linear mode as the energy "
        "grows.</p>")]
    out += _equilibria_html(ctx)
    p, n = ctx.params, ctx.params.n
    sym = [label(c) for c in p.coordinates]
    if any(link.torque for link in p.as_chain().links) or p.has_friction:
        out.append('<p class="callout">With constant torques or Coulomb friction the backbones are not drawn (the modes '
                   "start from a shifted equilibrium, or no motion is periodic): <code>skewpend nnm</code> follows them "
                   "for the model without them.</p>")
        ctx.notes["orbits"] = "backbones not drawn (torques or friction)"
        return "\n".join(out)
    if n > NNM_MAX_LINKS:
        out.append(f'<p class="note">The nonlinear normal modes of {n} links are not followed here (up to '
                   f"{NNM_MAX_LINKS} links: <code>skewpend nnm --config</code> follows any).</p>")
        ctx.notes["orbits"] = "backbones not drawn (long chain)"
        return "\n".join(out)
    q, damped = _undamped(p)
    detail("the nonlinear normal modes")
    try:
        bb = backbones(q, resolution=REPORT_RESOLUTION if n <= 2 else LONG_RESOLUTION)
    except SkewpendError as exc:
        ctx.notes["orbits"] = "could not be computed"
        out.append(f'<p class="callout warn">The nonlinear normal modes could not be computed: {esc(exc)}</p>')
        return "\n".join(out)
    E_max = max(f.energy_max for f in bb.families)
    orbits = []
    for fam in bb.families[:2]:
        for frac in (0.25, 0.95):
            E = frac * E_max
            if fam.energies.size and E <= fam.energies.max():
                orbits.append((fam.mode, E, fam.at_energy(E).trajectory(200)))
    detail("the frequency-energy plot")
    fig = F.fep_figure(bb, orbits=orbits)
    square = f"|{sym[0]}|, |{sym[1]}|" if n <= 2 else "|q₁|, …, |q" + str(n).translate(SUBSCRIPTS) + "|"
    caption = prose(
        "Frequency $2\\pi/T$ of each nonlinear normal mode against its energy above the hanging rest, from the linear "
        "frequencies of section 4 (◀) up to " + f"{fmt_num(E_max, 4)} J, the lowest energy at which a joint can flip "
        f"(the lowest potential on the boundary of the {'square' if n <= 2 else 'cube'} {square} ≤ 180°). Solid: stable "
        "orbits (the Floquet multipliers on the unit circle); dashed: unstable; circles: a multiplier passing +1 (branch "
        "point), squares: −1 (period doubling)" + ("" if n <= 2 else ", triangles: a Krein collision") + "; dotted: an "
        "internal resonance, where two frequencies are in a small whole-number ratio. Right: "
        f"{schema.count_text(len(orbits), 'of the orbits')} in the ({sym[0]}, {sym[1]}) plane (the dot: the start).")
    if damped:
        caption += " Drawn for the undamped model: with damping no motion is periodic."
    out.append(prose(
        "<p>Each orbit is found by <b>shooting</b>: Newton's method on the start and the period so that the motion "
        "closes after one period at the given energy, with the derivative of the flow from the variational equations "
        "(the same compiled code as the Lyapunov exponents); the family is followed by pseudo-arclength continuation. "
        "The eigenvalues of the monodromy matrix (the flow's derivative over one period) decide the stability.</p>"))
    out.append(figure_html(fig_png(fig), caption, "frequency-energy plot of the nonlinear normal modes"))
    out.append(facts_html(backbone_facts(bb)))
    ctx.notes["orbits"] = (" + ".join(str(len(f)) for f in bb.families) + f" orbits up to {fmt_num(E_max, 4)} J"
                           + (" (undamped model)" if damped else ""))
    return "\n".join(out)
