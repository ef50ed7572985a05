"""The frequency-energy plot of the nonlinear normal modes, with the orbits drawn in (phi, psi)."""

from __future__ import annotations

from typing import Optional, Sequence

import numpy as np

from ..style import SYMBOL, parameter_text, style
from .base import MODE_COLORS, heading, new_figure

__all__ = ["fep_figure", "alpha_family_figure", "FAMILY_COLORS"]

#: The colour of each family: :data:`~skewpend.views.figures.base.MODE_COLORS`.
FAMILY_COLORS = MODE_COLORS
_EVENT_MARKERS = {"branch point": ("o", "branch point (multiplier +1)"), "period doubling": ("s", "period doubling (multiplier −1)"),
                  "Krein collision": ("^", "Krein collision (a complex pair leaves the circle)"),
                  "fold": ("D", "fold"), "resonance": ("*", "internal resonance")}


def _runs(mask: np.ndarray):
    """(start, stop) index ranges where ``mask`` is constant, overlapping by one point so the
    curve is continuous where the stability changes."""
    edges = np.nonzero(mask[1:] != mask[:-1])[0] + 1
    starts = np.r_[0, edges]
    stops = np.r_[edges, len(mask)]
    return [(int(a), int(min(b + 1, len(mask))), bool(mask[a])) for a, b in zip(starts, stops)]


def _draw_family(ax, x, fam, label: str, events_at, seen: set) -> None:
    """A family's frequencies against ``x``: solid where its orbits are stable, dashed where not, and its events
    (at ``events_at(event)`` on the x axis) marked; each legend entry once (``seen``)."""
    color = FAMILY_COLORS.get(fam.mode, "0.3")
    for a, b, stable in _runs(fam.stable):
        text = label + ("" if stable else " (unstable)")
        ax.plot(x[a:b], fam.frequencies[a:b], color=color, lw=1.8 if stable else 1.4, ls="-" if stable else "--",
                label=None if text in seen else text)
        seen.add(text)
    for ev in fam.events:
        marker, text = _EVENT_MARKERS.get(ev.kind, ("x", ev.kind))
        ax.plot([events_at(ev)], [ev.frequency], marker=marker, color="k", mfc="white", ms=7, ls="none",
                label=None if text in seen else text, zorder=5)
        seen.add(text)


def fep_figure(families, *, orbits: Optional[Sequence] = None, resonances: Sequence = ()):
    """The frequency-energy plot: each family's frequency [rad/s] against its energy [J], solid
    where its orbits are stable and dashed where unstable, its branch points, period doublings and
    folds marked, and the ``resonances`` (of :func:`skewpend.backbones`) too.  ``orbits``: the
    orbits to draw in the (phi, psi) plane beside it, as ``(family_mode, energy, trajectory)``
    triples (trajectories over one period, e.g. ``family.at_energy(E).trajectory()``), marked on
    the curves.  ``families``: an :class:`~skewpend.NNMFamily`, a list of them, or a
    :class:`~skewpend.analysis.orbits.Backbones`.  The figure draws only what it is given.
    """
    if hasattr(families, "families"):
        resonances = list(resonances) or list(families.resonances)
        families = families.families
    if not isinstance(families, (list, tuple)):
        families = [families]
    orbits = list(orbits or [])
    with style():
        fig = new_figure((11.0, 5.6) if orbits else (7.5, 5.4))
        if orbits:
            grid = fig.add_gridspec(2, 3, width_ratios=(2.2, 1, 1))
            ax = fig.add_subplot(grid[:, 0])
            small = [fig.add_subplot(grid[i // 2, 1 + i % 2]) for i in range(min(len(orbits), 4))]
        else:
            ax, small = fig.add_subplot(1, 1, 1), []
        seen = set()
        for fam in families:
            _draw_family(ax, fam.energies, fam, f"mode {fam.mode}", lambda ev: ev.energy, seen)
            ax.plot([0.0], [fam.linear_frequency], marker="<", color=FAMILY_COLORS.get(fam.mode, "0.3"), ms=6,
                    clip_on=False)
        for ev in resonances:
            marker, text = _EVENT_MARKERS["resonance"]
            ax.axvline(ev.energy, color="0.55", lw=0.8, ls=":")
            ax.annotate(ev.detail.replace("w2/w1", "ω₂/ω₁") + " (internal resonance)", (ev.energy, 0.0),
                        xycoords=ax.get_xaxis_transform(), textcoords="offset points", xytext=(3, 5), fontsize=8,
                        color="0.3", rotation=90, va="bottom")
        ax.set_xlabel("energy E above the hanging rest [J]")
        ax.set_ylabel("frequency 2π/T [rad/s]")
        ax.set_xlim(left=0.0)
        ax.set_title("Backbones: nonlinear normal modes (◀ linear frequency)", loc="left")
        ax.legend(loc="best", fontsize=8)
        for k, (sub, (mode, energy, tr)) in enumerate(zip(small, orbits)):
            color = FAMILY_COLORS.get(mode, "0.3")
            sub.plot(np.degrees(tr.y[:, 0]), np.degrees(tr.y[:, 1]), color=color, lw=1.3)
            sub.plot(np.degrees(tr.y[0, 0]), np.degrees(tr.y[0, 1]), "o", color=color, ms=3)
            sub.set_title(f"({chr(ord('a') + k)}) mode {mode}, E = {energy:.3g} J", fontsize=9, loc="left")
            double = tr.y.shape[1] <= 5  # a chain's orbit is drawn in (q1, q2)
            sub.set_xlabel(f"{SYMBOL['phi'] if double else 'q₁'} [deg]", fontsize=8)
            sub.set_ylabel(f"{SYMBOL['psi'] if double else 'q₂'} [deg]", fontsize=8)
            sub.tick_params(labelsize=7)
            lim = max(np.abs(np.degrees(tr.y[:, :2])).max() * 1.15, 1e-9)
            sub.set_xlim(-lim, lim)
            sub.set_ylim(-lim, lim)
            sub.set_aspect("equal")
            sub.axhline(0, color="0.85", lw=0.6, zorder=0)
            sub.axvline(0, color="0.85", lw=0.6, zorder=0)
            fam = next((f for f in families if f.mode == mode), None)
            if fam is not None:
                w = float(np.interp(energy, fam.energies, fam.frequencies))
                ax.annotate(f"({chr(ord('a') + k)})", (energy, w), textcoords="offset points", xytext=(4, 4),
                            fontsize=8, color=color)
                ax.plot([energy], [w], "o", color=color, ms=4)
        params = families[0].params if families else None
        text = "Frequency-energy plot"
        if params is not None:
            text += "\n" + parameter_text(params)
        if families:
            e_max = max(f.energy_max for f in families)
            text += f"; families continued up to E = {e_max:.4g} J"
        heading(fig, text)
    return fig


def alpha_family_figure(families):
    """A nonlinear normal mode at fixed energy along the skew angle (:func:`skewpend.nnm_alpha`):
    frequency [rad/s] against alpha [deg], solid where the orbit is stable, dashed where not,
    stability changes marked.  ``families``: one :class:`~skewpend.analysis.orbits.AlphaFamily`
    or several (e.g. both modes, or several energies)."""
    if not isinstance(families, (list, tuple)):
        families = [families]
    with style():
        fig = new_figure((7.5, 4.8))
        ax = fig.add_subplot(1, 1, 1)
        seen = set()
        for fam in families:  # an event's alpha is in its detail ("alpha = 12.5 deg ...")
            _draw_family(ax, np.degrees(fam.alphas), fam, f"mode {fam.mode}, E = {fam.energy:.3g} J",
                         lambda ev: float(ev.detail.split("=")[1].split("deg")[0]), seen)
        ax.set_xlabel("skew angle α [deg]")
        ax.set_ylabel("frequency 2π/T [rad/s]")
        ax.set_title("Nonlinear normal modes at fixed energy along the skew angle", loc="left")
        ax.legend(loc="best", fontsize=8)
        params = families[0].params if families else None
        if params is not None:
            heading(fig, "Continuation in α\n" + parameter_text(params, skip=("alpha",)))
    return fig
