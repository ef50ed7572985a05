"""Values as users type them: numbers, angles with a ``deg`` suffix, vectors, inertia tensors.

Shared by the command line, configuration files and sweep specifications.
"""

from __future__ import annotations

import math
from typing import Any, Optional, Sequence

from .errors import ParameterError

__all__ = ["UsageError", "parse_scalar", "parse_vector", "parse_inertia", "positive_number", "initial_state"]


class UsageError(ParameterError):
    """A malformed command-line or configuration value."""


# -- parsing of values --------------------------------------------------------------------------
_SYMBOLIC = ("sym", "symbolic")


def parse_scalar(text: Optional[str], option: str, *, angle: bool = False) -> Optional[float]:
    """A number; for angles radians or a ``deg`` suffix; ``sym`` leaves it symbolic (None)."""
    if text is None:
        return None
    t = text.strip().lower()
    if t in _SYMBOLIC:
        return None
    scale = 1.0
    if angle:
        for suffix in ("deg", "°"):
            if t.endswith(suffix):
                t, scale = t[: -len(suffix)].strip(), math.pi / 180
                break
    try:
        value = float(t)
    except ValueError:
        allowed = "a number in radians or with a deg suffix (e.g. 30deg)" if angle else "a number"
        raise UsageError(f"{option}: expected {allowed}, or 'sym' for symbolic; got {text!r}") from None
    if not math.isfinite(value):
        raise UsageError(f"{option}: expected a finite number, got {text!r}")
    return value * scale


def _entry(text: str, option: str, sizes) -> object:
    try:
        value = float(text)
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
    """``value`` as a positive finite float (``None`` passes through with ``allow_none``)."""
    if value is None and allow_none:
        return None
    try:
        x = float(value)
    except (TypeError, ValueError):
        raise ParameterError(f"{name} must be a positive number, got {value!r}") from None
    if isinstance(value, bool) or not math.isfinite(x) or not x > 0:
        raise ParameterError(f"{name} must be a positive finite number, got {value!r}")
    return x


def initial_state(y0: Sequence[float]):
    """``y0 = (phi, psi, dphi, dpsi)`` as a finite float array of shape (4,)."""
    import numpy as np

    try:
        y = np.asarray(y0, dtype=float).reshape(-1)
    except (TypeError, ValueError):
        raise ParameterError(f"y0 must be 4 numbers (phi, psi, dphi, dpsi), got {y0!r}") from None
    if y.shape != (4,):
        raise ParameterError(f"y0 must be 4 numbers (phi, psi, dphi, dpsi), got {y.size}")
    if not np.all(np.isfinite(y)):
        raise ParameterError(f"y0 must be finite, got {y.tolist()}")
    return y
