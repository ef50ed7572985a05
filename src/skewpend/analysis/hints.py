"""Hints that point at the data when an identification goes wrong.

Data can pass every reader's check (:mod:`skewpend.analysis.measurements`) and still be wrong in a
way the fit only shows as "the estimate is not physical" or a poor prediction.  The likely
mistakes, and the checks here, cheap ones first:

* **time in milliseconds** (or microseconds): before the fit, the median time step against the
  period of ``params0``'s fastest mode about hanging, of its ``n`` (:func:`check_sampling`, a
  refusal: such data would make thousands of shooting segments);
* **far too short**: the fitting data's total duration against the slowest mode's period;
* **an encoder's sign flipped**, **the second angle absolute declared relative** (or the reverse):
  the linear estimate (inverse dynamics, a fraction of a second) with the data re-read under
  each alternative convention -- each joint's sign flipped alone, the later angles (the model's
  coordinates after the first) of the other kind -- one whose residual is three times smaller or
  less is named.  A planar pendulum moves alike mirrored as a whole (every sign turned), so of two
  angles ``sign=1:-1`` and ``-1:1`` cannot be told apart: the hint names both, and which encoder
  is flipped cannot be said; of more angles one joint flipped is its mirror's all the others, so
  the hint names the joint (``the sign of q3 (joint 3) looks flipped``) and both spellings;
* **speeds inconsistent** with the angles' rate of change: a reader's check already
  (``skip=('velocities',)``).

Each message names the fix in the spelling of the interface in use: ``interface="python"``
(``Convention(sign=(1, -1))``) or ``"cli"`` (``--convention sign=1:-1``).
"""

from __future__ import annotations

import math
from dataclasses import fields, replace
from typing import List, Optional, Sequence, Tuple

import numpy as np

from ..errors import ParameterError, SkewpendError
from .measurements import SKEWPEND, Convention, Measurements, Piece, convert, convert_back

__all__ = ["spell_convention", "mode_periods", "check_sampling", "suspect", "diagnose", "SAMPLES_PER_SWING",
           "SWINGS_NEEDED", "BETTER", "CHECK_WINDOW", "CHECK_SECONDS", "NOISE_FACTOR", "noise_level", "report"]

#: Fewer samples than this per swing of ``params0``'s fastest mode: the time column is refused.
SAMPLES_PER_SWING = 4
#: Swings of the slowest mode an identification needs, at least (the hint's advice).
SWINGS_NEEDED = 3
#: An alternative convention is named when its linear estimate's residual is at most this
#: fraction of the data's as read.
BETTER = 1 / 3
#: The Savitzky-Golay window of the convention checks [s], at most (a quarter of the fastest
#: mode's period when shorter): wide, so that noise in the accelerations does not hide the model
#: error of a wrong convention (on 6 s of a skewed rig with 0.5 mrad noise the residuals are
#: 0.004 as read correctly, 0.04 with the second angle absolute, 0.13 with a sign flipped).
CHECK_WINDOW = 0.2
#: The convention checks look at the first this many seconds of the fitting data (whole pieces,
#: a longer one cut): the residuals' ratio needs no more, and the checks stay a few seconds.
CHECK_SECONDS = 20.0


def spell_convention(convention: Convention, interface: str = "python") -> str:
    """How a user states ``convention``: ``Convention(second='absolute', sign=(1, -1))`` in
    Python, ``--convention second=absolute,sign=1:-1`` on the command line (only the fields that
    differ from skewpend's own)."""
    changed = [f.name for f in fields(Convention) if (any(s != 1 for s in convention.sign) if f.name == "sign" else
                                                       getattr(convention, f.name) != getattr(SKEWPEND, f.name))]
    if interface == "cli":
        parts = [f"{k}={':'.join(str(s) for s in v)}" if k == "sign" else f"{k}={'yes' if v is True else v}"
                 for k, v in ((k, getattr(convention, k)) for k in changed)]
        return "--convention " + (",".join(parts) if parts else "second=relative")
    return "Convention(" + ", ".join(f"{k}={getattr(convention, k)!r}" for k in changed) + ")"


def mode_periods(params0) -> Optional[Tuple[float, ...]]:
    """The periods [s] of ``params0``'s ``n`` modes about hanging (undamped), one a coordinate, the
    slowest first and the fastest last (``(slow, fast)`` for the double pendulum), or None when they
    cannot be had (symbolic or unstable)."""
    from .modes import linear_matrices

    try:
        M, _, K = linear_matrices(params0)
        w2 = np.linalg.eigvals(np.linalg.solve(M, K)).real
    except (SkewpendError, np.linalg.LinAlgError, TypeError, ValueError):
        return None
    if not np.all(np.isfinite(w2)) or np.any(w2 <= 0):
        return None
    return tuple(float(x) for x in 2 * math.pi / np.sqrt(np.sort(w2)))


def _extreme(periods: Sequence[float], which: str) -> str:
    """``params0``'s ``which`` (``"fast"``, ``"slow"``) mode in words: the comparative between two
    modes (``faster``), the superlative among more (``fastest``)."""
    return f"params0's {which}{'er' if len(periods) == 2 else 'est'} mode"


def _declared(measurements: Measurements, convention: Optional[Convention]) -> Convention:
    if convention is not None:
        return convention
    stated = dict(measurements.metadata.get("convention", {}) or {})
    try:
        return Convention(**{k: (tuple(v) if k == "sign" else v) for k, v in stated.items()})
    except (TypeError, ParameterError):
        return SKEWPEND


def check_sampling(measurements: Measurements, params0, *, convention: Optional[Convention] = None,
                   interface: str = "python") -> None:
    """Refuse (:class:`~skewpend.errors.ParameterError`) data sampled with fewer than
    :data:`SAMPLES_PER_SWING` samples per swing of ``params0``'s fastest mode (of its ``n``): naming the time
    column's unit when the steps read in milliseconds (or microseconds) make a plausible rate (at
    least 20 samples per swing) over a plausible duration (at least half a swing)."""
    periods = mode_periods(params0)
    if periods is None:
        return
    fast = periods[-1]
    dt = float(np.median([p.dt for p in measurements]))
    if dt <= fast / SAMPLES_PER_SWING:
        return
    conv = _declared(measurements, convention)
    total = measurements.duration
    what = (f"the median time step is {dt:.4g} s, {fast / dt:.2g} samples per swing of {_extreme(periods, 'fast')} "
            f"({fast:.3g} s), over {total:.4g} s in all")
    for unit, scale in (("ms", 1e-3), ("us", 1e-6)):
        if conv.time == "s" and dt * scale <= fast / 20 and total * scale >= fast / 2:
            fix = spell_convention(replace(conv, time=unit), interface)
            raise ParameterError(f"{what}: the times look in {'milliseconds' if unit == 'ms' else 'microseconds'} "
                                 f"(steps of {dt * scale:.4g} s then); state {fix}")
    raise ParameterError(f"{what}: too coarse to identify a pendulum (give at least {SAMPLES_PER_SWING * 5} samples "
                         f"per swing, steps of at most {fast / 20:.3g} s), or check the time column's unit")


#: An output-error fit whose angle error is more than this many times the data's own noise may be
#: wrong (a model error, or data read wrongly): the checks run, and they decide.  Only a trigger:
#: good fits of real data reach it too (the free swing 23x, the driven rig 8-40x: model error),
#: where the checks then find nothing and nothing is said.
NOISE_FACTOR = 10.0


def noise_level(measurements: Measurements) -> float:
    """The angles' noise [rad] (:func:`skewpend.analysis.identify.angle_noise`: what a short
    Savitzky-Golay filter removes, corrected for the noise it keeps)."""
    from .identify import angle_noise

    return angle_noise(measurements)


def suspect(result, measurements: Optional[Measurements] = None) -> Optional[str]:
    """Why a fit's result looks wrong, in words, or None: a status that is not success, a held-out
    prediction worse than ``params0``'s, or (output error) an angle error above a tenth of the
    angles' spread or :data:`NOISE_FACTOR` times their noise."""
    if not result.ok:
        return result.message
    if len(result.validation) and math.isfinite(result.heldout_median0) and \
            not result.heldout_median <= result.heldout_median0:
        return (f"the held-out prediction ({result.heldout_median:.4g} rad) is worse than params0's "
                f"({result.heldout_median0:.4g} rad)")
    if len(result.fit_rms) and measurements is not None:
        spread = float(np.median([np.std(p.q) for p in measurements]))
        miss = float(np.median(result.fit_rms))
        if miss > 0.1 * spread:
            return (f"the fitted model misses the angles by {miss:.3g} rad, more than a tenth of their spread "
                    f"({spread:.3g} rad)")
        noise = noise_level(measurements)
        if math.isfinite(noise) and miss > NOISE_FACTOR * noise:
            return (f"the fitted model misses the angles by {miss:.3g} rad, {miss / noise:.3g} times their noise "
                    f"({noise:.3g} rad)")
    return None


def _reread(measurements: Measurements, declared: Convention, other: Convention) -> Measurements:
    """The measurements as if the file had been read with ``other`` instead of ``declared``."""
    pieces = []
    for p in measurements:
        raw = convert_back(p.q, p.dq, p.u, convention=declared)
        q, dq, u = convert(*raw, convention=other)
        pieces.append(Piece(t=p.t, q=q, dq=dq, u=u, name=p.name, source=p.source, group=p.group, note=p.note))
    return Measurements(pieces=tuple(pieces), metadata={"format": measurements.metadata.get("format", ""),
                                                        "convention": other.to_dict()})


def _first_seconds(measurements: Measurements, seconds: float) -> Measurements:
    """The first pieces making up about ``seconds`` (a longer piece cut first)."""
    if any(p.duration > 1.5 * seconds for p in measurements):
        measurements = measurements.cut(seconds)
    k = int(np.searchsorted(np.cumsum([p.duration for p in measurements]), seconds)) + 1  # until the total reaches it
    return measurements if k >= len(measurements) else measurements.select(list(range(k)))


def _residual(measurements: Measurements, params0, free, window: float) -> float:
    from .identify import identify

    if free is not None:  # the linear estimate holds a hinge's tilt at params0's (a wrong skew is a small model
        # error beside a flipped sign or a wrong second angle): a freed alpha or tiltK is left out, the rest kept
        from .identify import freed_angle

        def angle(f: str) -> bool:
            try:
                return freed_angle(f, params0) is not None
            except SkewpendError:
                return True

        free = [f for f in ([free] if isinstance(free, str) else list(free)) if not angle(f)] or None
    import warnings

    try:
        with warnings.catch_warnings():  # the data's own fit has said its warnings; a variant's are no news
            warnings.simplefilter("ignore", UserWarning)
            r = identify(measurements, params0, free=free, method="linear", smoothing=window, bootstrap=0)
    except (SkewpendError, ValueError, np.linalg.LinAlgError):  # a check never stops the run: no answer
        return math.nan
    rms = np.asarray(r.residual_rms, dtype=float)
    return float(np.median(rms)) if rms.size and np.all(np.isfinite(rms)) else math.nan


def diagnose(measurements: Measurements, params0, *, convention: Optional[Convention] = None,
             free: Optional[Sequence[str]] = None, interface: str = "python",
             conventions: bool = True) -> List[str]:
    """The likely data mistakes behind a fit that went wrong, each one line naming the fix (empty:
    none found).  ``convention``: how the data were read (default: as their metadata says);
    ``conventions=False`` leaves out the sign and second-angle checks (data whose convention is
    the reader's own, as the Kaheman rig's).  The checks are the model's: one a joint of
    ``params0.coordinates`` (its sign flipped alone; two angles make one check, the mirror image's),
    and the angles after the first of the other kind (absolute or relative)."""
    hints: List[str] = []
    periods = mode_periods(params0)
    total = measurements.duration
    if periods is not None and total < SWINGS_NEEDED * periods[0]:
        hints.append(f"far too short: the fitting data last {total:.3g} s in all, "
                     f"{total / periods[0]:.2g} swings of {_extreme(periods, 'slow')} ({periods[0]:.3g} s); record at least "
                     f"{SWINGS_NEEDED * periods[0]:.2g} s ({SWINGS_NEEDED} swings) of motion")
    if not conventions:
        return hints
    declared = _declared(measurements, convention)
    measurements = _first_seconds(measurements, CHECK_SECONDS)
    window = CHECK_WINDOW if periods is None else min(CHECK_WINDOW, periods[-1] / 4)
    window = max(window, 7 * float(np.median([p.dt for p in measurements])))
    if window > 0.5 * min(p.duration for p in measurements):
        return hints
    base = _residual(measurements, params0, free, window)
    if not math.isfinite(base) or base <= 0:
        return hints
    names = tuple(params0.coordinates)
    n = len(names)
    sign = tuple(int(x) for x in declared.signs(n))
    later = names[1:]
    other = replace(declared, second="absolute" if declared.second == "relative" else "relative")
    candidates: List[Tuple[Convention, str, Optional[Convention]]] = []
    # one joint's sign flipped at a time, the later joints first; the mirror image (every sign turned) moves
    # alike, so flipping joint k is flipping all the others: between two angles one class (the joint cannot
    # be told), among more each joint its own (named: its mirror flips more than one)
    seen = set()
    for k in [*range(1, n), 0]:
        flip = tuple(-x if i == k else x for i, x in enumerate(sign))
        mirror = tuple(-x for x in flip)
        if flip in seen or mirror in seen:
            continue
        seen.add(flip)
        what = (f"the sign of {names[k]} (joint {k + 1}) looks flipped" if n - 1 > 1  # the mirror flips more
                else "an encoder's sign looks flipped")
        candidates.append((replace(declared, sign=flip), what, replace(declared, sign=mirror)))
    candidates.append((other, (f"the second angle looks {other.second}" if len(later) == 1 else
                               f"the angles {', '.join(later)} look {other.second}") + f", not {declared.second}",
                       None))
    found: List[Tuple[float, str]] = []
    for cand, what, mirror in candidates:
        r = _residual(_reread(measurements, declared, cand), params0, free, window)
        if math.isfinite(r) and r <= BETTER * base:
            fix = spell_convention(cand, interface)
            if mirror is not None:
                fix += f" (or {spell_convention(mirror, interface)}: the mirror image moves alike)"
            found.append((r, f"{what}: read so, the inverse dynamics fit {base / r:.3g} times better; state {fix}"))
    found.sort()
    hints += [text for _, text in found[:1]]
    return hints


def report(hints: Sequence[str], checked: bool = True) -> List[str]:
    """Lines to show: the hints, or (``checked``: the convention checks ran) that none of the
    checks found a data mistake."""
    if hints:
        return [f"hint: {h}" for h in hints]
    return ["hint: the data checks (time unit, duration, encoder signs, second angle absolute or relative) found "
            "no mistake"] if checked else []

