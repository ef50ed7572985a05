"""Values as users type them: numbers, angles with a ``deg`` suffix, vectors, inertia tensors.

Shared by the command line, configuration files and sweep specifications.
"""

from __future__ import annotations

import math
import sys
import re
from typing import Any, Optional, Sequence, Tuple

from .errors import ParameterError

__all__ = ["UsageError", "parse_scalar", "parse_whole", "parse_vector", "parse_inertia", "positive_number", "initial_state"]


class UsageError(ParameterError):
    """A malformed command-line or configuration value."""


# -- parsing of values --------------------------------------------------------------------------
_SYMBOLIC = ("sym", "symbolic")


#: A multiple of pi as an angle may be written: ``pi``, ``-pi``, ``pi/2``, ``2pi``, ``0.5*pi``, ``3pi/4``.
_PI = re.compile(r"([+-]?(?:\d+(?:\.\d*)?|\.\d+)?)\*?(?:pi|π)(?:/((?:\d+(?:\.\d*)?|\.\d+)(?:e[+-]?\d+)?))?")


def _number(t: str) -> float:
    """``float(t)`` for ASCII text only (Python's float also reads other scripts' digits)."""
    if not t.isascii():
        raise ValueError(t)
    return float(t)


def parse_scalar(text: Any, option: str, *, angle: bool = False) -> Optional[float]:
    """A number; for angles radians, a ``deg`` or ``rad`` suffix or a multiple of pi (``pi/2``); ``sym``
    leaves it symbolic (None).  A number already parsed (a run file's int or float, not bool) is checked only.

    An angle given as a bare number (typed, or a run file's number) is radians, and beyond one turn
    (2 pi) it is refused with the spelling that was likely meant (``30`` -> ``30deg``); ``30rad``
    (in a run file ``"30rad"``) keeps 30 rad.  Python's API takes radians and never comes here."""
    if text is None:
        return None
    if isinstance(text, (int, float)) and not isinstance(text, bool):
        value, text = float(text), repr(text)
    else:
        value = None
    t = str(text).strip().lower()
    if value is None and t in _SYMBOLIC:
        return None
    scale = 1.0
    unit = None  # an angle's unit as written: 'deg', 'rad' or 'pi' (None: a bare number, radians)
    if value is None and angle:
        for suffix, name, factor in (("deg", "deg", math.pi / 180), ("°", "deg", math.pi / 180), ("rad", "rad", 1.0)):
            if t.endswith(suffix):
                t, scale, unit = t[: -len(suffix)].strip(), factor, name
                break
        m = _PI.fullmatch(t) if unit is None else None
        if m:
            unit = "pi"
            factor = m.group(1)
            factor = -1.0 if factor == "-" else (1.0 if factor in ("", "+") else float(factor))
            divisor = float(m.group(2)) if m.group(2) else 1.0
            if not divisor > 0:
                raise UsageError(f"{option}: a multiple of pi divides by a positive number, got {text!r}")
            value = factor * math.pi / divisor
    if value is None:
        try:
            value = _number(t)
        except ValueError:
            allowed = "a number in radians, with a deg or rad suffix (e.g. 30deg) or a multiple of pi (e.g. pi/2)" if angle else "a number"
            raise UsageError(f"{option}: expected {allowed}, or 'sym' for symbolic; got {text!r}") from None
    value *= scale
    if not math.isfinite(value):
        raise UsageError(f"{option}: expected a finite number, got {text!r}")
    if angle and abs(value) > MAX_ANGLE:  # cos and sin of it would be digits of rounding
        raise UsageError(f"{option}: expected an angle of at most {MAX_ANGLE:g} rad in magnitude, got {text!r}")
    if angle and unit is None and abs(value) > _TURN:
        raise UsageError(f"{option}: {str(text).strip()!r} has no unit, so it would be {value:g} rad (more than one turn); "
                         f"write {t}deg for degrees, or {t}rad if radians are meant")
    return value


#: One turn [rad], with a margin of rounding: an angle typed without a unit beyond it is refused as a
#: likely slip of degrees for radians (``--alpha 30`` would be 1719 deg); ``30deg`` or ``30rad`` say which.
_TURN = 2 * math.pi * (1 + 1e-12)


def parse_whole(text: Any, option: str, lo: int, hi: int) -> int:
    """A whole number from ``lo`` to ``hi``: digits, or a float spelling of one (``1e3``)."""
    try:
        value = _number(str(text).strip()) if not isinstance(text, bool) else math.nan
    except ValueError:
        value = math.nan
    if not (math.isfinite(value) and value == int(value) and lo <= value <= hi):
        raise UsageError(f"{option}: expected a whole number from {lo} to {hi}, got {text!r}")
    return int(value)


def _entry(text: Any, option: str, sizes) -> object:
    if isinstance(text, (int, float)) and not isinstance(text, bool):
        text = repr(text)
    try:
        value = _number(text)
    except ValueError:
        if text.isidentifier():
            return text  # a symbol name, left symbolic
        raise UsageError(
            f"{option}: expected {' or '.join(map(str, sizes))} comma-separated numbers or symbol names, got {text!r}"
        ) from None
    if not math.isfinite(value):
        raise UsageError(f"{option}: expected finite numbers, got {text!r}")
    return value


def parse_vector(text: Optional[str], option: str, sizes=(3,)):
    """Comma-separated numbers or symbol names, e.g. ``0,0.4,0`` or ``0,d,0``; ``sym`` alone
    makes every component symbolic."""
    if text is None:
        return None
    if text.strip().lower() in _SYMBOLIC:
        return "sym"
    values = [_entry(x, option, sizes) for x in text.replace(" ", "").split(",") if x != ""]
    if len(values) not in sizes:
        raise UsageError(
            f"{option}: expected {' or '.join(map(str, sizes))} comma-separated numbers or symbol names, got {len(values)}"
        )
    return values


def parse_inertia(text: Optional[str], option: str):
    """``Ixx,Iyy,Izz`` (principal, body axes) or ``Ixx,Iyy,Izz,Ixy,Ixz,Iyz`` or 9 entries;
    ``sym`` for a general symbolic tensor."""
    v = parse_vector(text, option, sizes=(3, 6, 9))
    if v is None or v == "sym":
        return v
    if len(v) == 3:
        return [[v[0], 0, 0], [0, v[1], 0], [0, 0, v[2]]]
    if len(v) == 6:
        xx, yy, zz, xy, xz, yz = v
        return [[xx, xy, xz], [xy, yy, yz], [xz, yz, zz]]
    return [v[0:3], v[3:6], v[6:9]]


def positive_number(name: str, value: Any, *, allow_none: bool = False) -> Optional[float]:
    """``value`` as a positive finite float, not subnormal (``None`` passes through with
    ``allow_none``)."""
    if value is None and allow_none:
        return None
    try:
        x = float(value)
    except (TypeError, ValueError):
        raise ParameterError(f"{name} must be a positive number, got {value!r}") from None
    if isinstance(value, bool) or not math.isfinite(x) or not x > 0:
        raise ParameterError(f"{name} must be a positive finite number, got {value!r}")
    if x < sys.float_info.min:  # subnormal: compiled code may flush it to 0
        raise ParameterError(f"{name} must be at least {sys.float_info.min:.3g} (the smallest normal float), "
                             f"got {value!r}")
    return x


#: Largest initial angle [rad]: beyond it an angle has no precision left for its fraction of a turn.
MAX_ANGLE = 1e6


def initial_state(y0: Sequence[float], coordinates: Sequence[str] = ("phi", "psi")):
    """``y0 = (phi, psi, dphi, dpsi)`` (a chain's angles and speeds: ``coordinates``) as a
    finite float array of shape (2 n,); angles at most :data:`MAX_ANGLE` in magnitude."""
    import numpy as np

    n = len(coordinates)
    names = ", ".join(list(coordinates) + [f"d{c}" for c in coordinates]) if n <= 3 else \
        f"{coordinates[0]} ... {coordinates[-1]}, d{coordinates[0]} ... d{coordinates[-1]}"
    try:
        y = np.asarray(y0, dtype=float).reshape(-1)
    except (TypeError, ValueError):
        raise ParameterError(f"y0 must be {2 * n} numbers ({names}), got {y0!r}") from None
    if y.shape != (2 * n,):
        raise ParameterError(f"y0 must be {2 * n} numbers ({names}), got {y.size}")
    if not np.all(np.isfinite(y)):
        raise ParameterError(f"y0 must be finite, got {y.tolist()}")
    if np.any(np.abs(y[:n]) > MAX_ANGLE):
        raise ParameterError(f"the initial angles must be at most {MAX_ANGLE:g} rad in magnitude, got {y[:n].tolist()}")
    return y


# -- ranges -------------------------------------------------------------------------------------
#: Units a range end may carry (angles only), as written -> canonical name.
_RANGE_UNITS = (("deg", "deg"), ("°", "deg"), ("rad", "rad"))
_MAX_RANGE_COUNT = 100_000


def parse_interval(text: Optional[str], option: str, *, angle: bool, example: str = "-90:90deg",
                   tail: str = "", turn: bool = True) -> Tuple[float, float]:
    """``START:STOP`` -> ``(start, stop)`` in SI units, with the unit rule of :func:`parse_range`
    (``tail``: what followed the interval as typed, e.g. a range's ``:COUNT``, for the messages).
    ``turn``: bare numbers beyond one turn refused as a likely slip of degrees (off for an interval
    that may be a speed's, rad/s: a region of attraction's window over any plane)."""
    if not isinstance(text, str) or len(text.split(":")) != 2:
        raise UsageError(f"{option}: expected START:STOP (e.g. {example}), got {text!r}")
    ends, units = [], []
    for part, which in zip(text.split(":"), ("START", "STOP")):
        t, unit = part.strip().lower(), None
        for suffix, name in _RANGE_UNITS:
            if t.endswith(suffix):
                t, unit = t[: -len(suffix)].strip(), name
                break
        if unit is not None and not angle:
            raise UsageError(f"{option}: {which} {part.strip()!r} has a unit; this range takes plain numbers (e.g. {example})")
        try:
            value = _number(t)
        except ValueError:
            allowed = "a number in radians or with a deg suffix" if angle else "a number"
            raise UsageError(f"{option}: {which} must be {allowed}, got {part.strip()!r} (e.g. {example})") from None
        if not math.isfinite(value):
            raise UsageError(f"{option}: {which} must be finite, got {part.strip()!r}")
        ends.append(value)
        units.append(unit)
    explicit = sorted({u for u in units if u is not None})
    if len(explicit) > 1:
        raise UsageError(
            f"{option}: START is in {units[0]} but STOP in {units[1]} ({text.strip()!r}); write one unit, "
            "on either end or both (it applies to the whole range)"
        )
    scale = math.pi / 180 if explicit == ["deg"] else 1.0  # the factor parse_scalar uses for 'deg'
    if angle and turn and not explicit and _TURN < max(abs(e) for e in ends) <= MAX_ANGLE:  # beyond: refused as absurd below
        plain = ":".join(part.strip() for part in text.split(":"))
        raise UsageError(f"{option}: {plain + tail!r} has no unit, so it would be radians beyond one turn; write "
                         f"{plain}deg{tail} for degrees, or {plain}rad{tail} if radians are meant")
    return ends[0] * scale, ends[1] * scale


def parse_range(text: Optional[str], option: str, *, angle: bool):
    """``START:STOP:COUNT`` -> ``numpy.linspace(START, STOP, COUNT)`` (floats, SI units).

    The one rule for units in a range: a unit written on either end, or on both, applies
    to the whole range, so ``0:180deg:5``, ``0deg:180:5``, ``0deg:180deg:5`` and
    ``0°:180°:5`` are the same five angles; plain numbers are radians (``0:3.14:5``,
    ``0rad:3.14:5``); different units on the two ends (``0deg:1rad:5``) are refused.
    Angles are returned in radians.  A range that is not an angle (``angle=False``) takes
    plain numbers only.  COUNT is a whole number from 2 to 100000; the values must be
    finite.  Errors are :class:`UsageError` naming ``option``.
    """
    import numpy as np

    example = "0:180deg:181" if angle else "0.5:2:31"
    if not isinstance(text, str) or len(text.split(":")) != 3:
        raise UsageError(f"{option}: expected START:STOP:COUNT (e.g. {example}), got {text!r}")
    head, count = text.rsplit(":", 1)
    lo, hi = parse_interval(head, option, angle=angle, example=example, tail=":" + count.strip())
    count = count.strip()
    try:
        n = int(count)
    except ValueError:
        n = None
    if n is None or not 2 <= n <= _MAX_RANGE_COUNT:
        raise UsageError(f"{option}: COUNT must be a whole number from 2 to {_MAX_RANGE_COUNT}, got {count!r}")
    with np.errstate(all="ignore"):
        values = np.linspace(lo, hi, n)
    if not np.all(np.isfinite(values)):
        raise UsageError(f"{option}: the range {text.strip()!r} is too wide for double precision (STOP - START overflows)")
    return values


__all__ += ["parse_range", "parse_interval"]
