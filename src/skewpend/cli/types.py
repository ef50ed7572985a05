"""Parameter types of the command line: each parses a typed value once and names the option
in its one-line refusal.

They play the part of click's ``ParamType`` (pyhf's ``cli/``): the option is declared as text
and its type rides along in the ``Annotated`` metadata (``Annotated[Optional[str],
typer.Option("--a"), Scalar()]``); :func:`skewpend.cli.options.command` converts every given
value with :meth:`ParamType.convert` before the command runs.  (Typer 0.29 vendors click and
exposes no ``ParamType`` to subclass; this keeps the parsing in one place all the same.)  The
parsers themselves are the library's (:mod:`skewpend.parsing`), shared with run files.
Errors are :class:`~skewpend.parsing.UsageError`: one line, exit status 2.
"""

from __future__ import annotations

import sys

import ipaddress
import math
import re
from typing import Any, Optional, Tuple

from ..parsing import UsageError, parse_inertia, parse_scalar, parse_vector, parse_whole

__all__ = [
    "ParamType", "Scalar", "Angle", "Positive", "NonNegative", "Whole", "Range", "Interval", "Window", "Vector",
    "Inertia", "OutPath", "Scheduler", "Port", "Host", "Size", "Section", "Energy", "Offsets", "Plane", "EquilibriumChoice",
]


class ParamType:
    """Text typed for an option -> its value (``convert``), or a :class:`UsageError` naming the option."""

    metavar = "VALUE"

    def convert(self, text: str, flag: str) -> Any:  # pragma: no cover - every type overrides it
        raise NotImplementedError


class Scalar(ParamType):
    """A model parameter: a finite number, or ``sym`` (kept as the text ``"sym"``: symbolic)."""

    metavar = "NUMBER|sym"
    angle = False

    def __init__(self, metavar: Optional[str] = None) -> None:
        if metavar is not None:
            self.metavar = metavar

    def convert(self, text, flag):
        value = parse_scalar(text, flag, angle=self.angle)
        return "sym" if value is None else value


class Angle(Scalar):
    """An angle: radians, a ``deg`` suffix (``30deg``) or a multiple of pi (``pi/2``); or ``sym``."""

    metavar = "ANGLE|sym"
    angle = True


class Positive(ParamType):
    """A positive finite number (``sym`` refused: a setting is never symbolic)."""

    metavar = "NUMBER"
    angle = False
    strict = True  # > 0; NonNegative: >= 0

    def __init__(self, what: str = "number", *, at_most: Optional[float] = None, at_least: Optional[float] = None) -> None:
        self.what = what
        self.at_most = at_most
        self.at_least = sys.float_info.min if at_least is None else at_least

    def convert(self, text, flag):
        value = parse_scalar(text, flag, angle=self.angle)
        sign = "positive" if self.strict else "non-negative"
        if value is None or not (value > 0 if self.strict else value >= 0):
            raise UsageError(f"{flag}: expected a {sign} {self.what}{'' if self.strict else ' (>= 0)'}, got {text!r}")
        if 0 < value < self.at_least:  # by default subnormal: the compiled code may flush it to 0
            least = "the smallest normal float" if self.at_least == sys.float_info.min else ""
            raise UsageError(f"{flag}: expected a {sign} {self.what} of at least {self.at_least:.3g}"
                             f"{f' ({least})' if least else ''}{'' if self.strict else ' or 0'}, got {text!r}")
        if self.at_most is not None and value > self.at_most:
            raise UsageError(f"{flag}: expected a {sign} {self.what} of at most {self.at_most:g}, got {text!r}")
        return abs(value)  # -0 is 0


class NonNegative(Positive):
    strict = False


class PositiveAngle(Positive):
    """An angle in (0, ``at_most``), radians or ``deg`` or a multiple of pi."""

    angle = True
    metavar = "ANGLE"


class Whole(ParamType):
    """A whole number from ``lo`` to ``hi`` (``1e3`` is a whole number too)."""

    metavar = "N"

    def __init__(self, lo: int, hi: int) -> None:
        self.lo, self.hi = lo, hi

    def convert(self, text, flag):
        return parse_whole(text, flag, self.lo, self.hi)


class Range(ParamType):
    """``START:STOP:COUNT`` -> evenly spaced values (see :func:`skewpend.parsing.parse_range`)."""

    metavar = "START:STOP:COUNT"

    def __init__(self, *, angle: bool) -> None:
        self.angle = angle

    def convert(self, text, flag):
        from ..parsing import parse_range

        return parse_range(text, flag, angle=self.angle)


class Interval(ParamType):
    """``START:STOP`` -> ``(start, stop)``."""

    metavar = "START:STOP"

    def __init__(self, *, angle: bool) -> None:
        self.angle = angle

    def convert(self, text, flag):
        from ..parsing import parse_interval

        return parse_interval(text, flag, angle=self.angle)


class Plane(ParamType):
    """``A,B``: two different coordinates of the state, of ``phi, psi, dphi, dpsi`` (a chain of links':
    ``q1 … qn, dq1 … dqn``; the model's own are checked by the library)."""

    metavar = "A,B"
    NAMES = ("phi", "psi", "dphi", "dpsi")
    NAME = re.compile(r"^d?(phi|psi|q[1-9][0-9]*)$")

    def convert(self, text, flag):
        parts = [p.strip().lower() for p in text.split(",")]
        if len(parts) != 2 or any(not self.NAME.match(p) for p in parts) or parts[0] == parts[1]:
            raise UsageError(f"{flag}: expected two different coordinates of {', '.join(self.NAMES)} "
                             f"(e.g. phi,psi or phi,dphi; a chain's q1,q3 or q2,dq2), got {text!r}")
        return tuple(parts)


class Actuation(ParamType):
    """Which joints have a motor: ``both``, ``acrobot`` (the elbow), ``pendubot`` (the shoulder), ``all``, or the
    joints' numbers ``2`` / ``1,3`` (a chain of links)."""

    metavar = "both|acrobot|pendubot|all|J1,J2,..."
    LABELS = ("both", "acrobot", "pendubot", "all")

    def convert(self, text, flag):
        t = text.strip().lower()
        if t in self.LABELS:
            return t
        parts = [p.strip() for p in t.split(",")]
        if not all(p.isdigit() and int(p) >= 1 for p in parts) or len(set(parts)) != len(parts):
            raise UsageError(f"{flag}: expected {', '.join(self.LABELS)} or the numbers of the joints with a motor "
                             f"(e.g. 2 or 1,3), got {text!r}")
        return tuple(sorted(int(p) for p in parts))


class Offsets(ParamType):
    """``LO:HI,LO:HI`` -> two increasing intervals (radians or deg; rad/s or deg/s), each within
    ``[-within, within]`` when ``within`` is set."""

    metavar = "LO:HI,LO:HI"
    names: Tuple[str, str] = ("", "")
    within: Optional[float] = None

    def convert(self, text, flag):
        from ..parsing import parse_interval

        parts = text.split(",")
        if len(parts) != 2:
            raise UsageError(f"{flag}: expected {self.metavar} (e.g. -90:90deg,-180:180deg), got {text!r}")
        where = [f"{flag} ({name})" if name else flag for name in self.names]
        # the unit rule for bare numbers beyond a turn where both are angles (a Window); an Offsets plane
        # may hold speeds (rad/s), whose bare numbers beyond 2 pi are ordinary
        ranges = tuple(parse_interval(part, at, angle=True, turn=self.within is not None) for part, at in zip(parts, where))
        for (lo, hi), at in zip(ranges, where):
            if not lo < hi:
                raise UsageError(f"{at}: expected START < STOP, got {lo:.6g}:{hi:.6g}")
            if self.within is not None and not -self.within - 1e-12 <= lo < hi <= self.within + 1e-12:
                raise UsageError(f"{at}: expected START < STOP within -180..180 deg, got {lo:.6g}:{hi:.6g} rad")
        return ranges


class Window(Offsets):
    """``PHI0:PHI1,PSI0:PSI1`` -> two increasing angle intervals within -180..180 deg."""

    metavar = "PHI0:PHI1,PSI0:PSI1"
    names = ("phi", "psi")
    within = math.pi


class EquilibriumChoice(ParamType):
    """An equilibrium: a label (``down-down``, ``down-up``, ``up-down``, ``up-up``, ...: rod 1 then
    rod 2; a chain's ``up-down-down``, a word a link) or ``PHI,PSI`` angles near one (radians, ``deg``
    suffix or multiples of pi)."""

    metavar = "LABEL|PHI,PSI"
    LABEL = re.compile(r"^(down|up|level)(-(down|up|level))+$")  # a chain's labels have a word per link

    def convert(self, text, flag):
        from ..parsing import parse_scalar

        if self.LABEL.match(text.strip().lower()):
            return text.strip().lower()
        parts = text.split(",")
        if len(parts) != 2:
            raise UsageError(f"{flag}: expected a label (down-down, down-up, up-down, up-up, ...) or PHI,PSI "
                             f"(e.g. 180deg,0), got {text!r}")
        values = []
        for part, name in zip(parts, ("phi", "psi")):
            v = parse_scalar(part.strip(), f"{flag} ({name})", angle=True)
            if v is None:
                raise UsageError(f"{flag} ({name}): an equilibrium's angle must be a number, not 'sym'")
            values.append(v)
        return tuple(values)


class Angles(ParamType):
    """``A1,A2,...``: angles (radians, a ``deg`` suffix or multiples of pi), 1 to ``most`` of them."""

    metavar = "A1,A2,..."

    def __init__(self, most: int = 64) -> None:
        self.most = most

    def convert(self, text, flag):
        from ..parsing import parse_scalar

        parts = [s.strip() for s in text.split(",")]
        if not 1 <= len(parts) <= self.most:
            raise UsageError(f"{flag}: expected 1 to {self.most} comma-separated angles, got {text!r}")
        values = []
        for part in parts:
            v = parse_scalar(part, flag, angle=True)
            if v is None:
                raise UsageError(f"{flag}: expected angles, not 'sym'")
            values.append(v)
        return tuple(values)


class Numbers(ParamType):
    """``X1,X2,...``: finite numbers, ``count`` of them (or 1 to ``most``), whole ones with ``whole``."""

    def __init__(self, count: Optional[int] = None, most: int = 16, whole: bool = False, metavar: str = "X1,X2,...") -> None:
        self.count, self.most, self.whole, self.metavar = count, most, whole, metavar

    def convert(self, text, flag):
        parts = [s.strip() for s in text.split(",")]
        want = f"{self.count}" if self.count else f"1 to {self.most}"
        kind = "whole numbers" if self.whole else "numbers"
        if (self.count and len(parts) != self.count) or not (1 <= len(parts) <= (self.count or self.most)):
            raise UsageError(f"{flag}: expected {want} comma-separated {kind}, got {text!r}")
        values = []
        for s in parts:
            v = parse_scalar(s, flag, angle=False)
            if v is None:
                raise UsageError(f"{flag}: expected {kind}, not 'sym'")
            if self.whole and v != int(v):
                raise UsageError(f"{flag}: expected whole numbers, got {s!r}")
            values.append(int(v) if self.whole else v)
        return tuple(values)


class PerLink(ParamType):
    """A chain's values of one link field, one for every link or one a link, as a list (1 to ``most``
    entries): numbers ``1,0.8,0.5`` (``kind`` ``"scalar"``), vectors ``x,y,z;x,y,z`` (``"vector"``) or
    inertias ``Ixx,Iyy,Izz[,Ixy,Ixz,Iyz];...`` (``"inertia"``: 3x3 lists) -- numbers only: a chain is a
    model to compute with."""

    def __init__(self, kind: str, most: int = 64) -> None:
        self.kind, self.most = kind, most
        self.metavar = {"scalar": "V1,V2,...", "vector": "X,Y,Z;X,Y,Z;...", "inertia": "I1;I2;..."}[kind]

    def convert(self, text, flag):
        sep = "," if self.kind == "scalar" else ";"
        parts = [s.strip() for s in text.split(sep)]
        if not 1 <= len(parts) <= self.most or any(not s for s in parts):
            raise UsageError(f"{flag}: expected one value for every link or one a link ({'comma' if sep == ',' else 'semicolon'}"
                             f"-separated, at most {self.most}), got {text!r}")
        out = []
        for part in parts:
            if self.kind == "scalar":
                value = parse_scalar(part, flag, angle=False)
            else:
                value = parse_vector(part, flag) if self.kind == "vector" else parse_inertia(part, flag)
                flat = [] if value in (None, "sym") else [x for row in value for x in row] if self.kind == "inertia" else list(value)
                if value in (None, "sym") or not all(isinstance(x, (int, float)) for x in flat):
                    value = None
            if value is None:
                raise UsageError(f"{flag}: a chain's values are numbers (not symbol names or 'sym'), got {part!r}")
            out.append(value)
        return out


class Vector(ParamType):
    """``x,y,z`` numbers or symbol names, or ``sym``."""

    metavar = "X,Y,Z"

    def convert(self, text, flag):
        return parse_vector(text, flag)


class Inertia(ParamType):
    """``Ixx,Iyy,Izz[,Ixy,Ixz,Iyz]`` (or 9 entries), or ``sym``."""

    metavar = "I"

    def convert(self, text, flag):
        value = parse_inertia(text, flag)
        return value if value == "sym" else ",".join(str(x) for row in value for x in row)


class OutPath(ParamType):
    """An output file with one of ``suffixes``, in an existing directory: checked before any work."""

    metavar = "FILE"

    def __init__(self, suffixes, *, check: bool = True) -> None:
        self._suffixes = suffixes  # a tuple, or "module:NAME" of the library (imported when used)
        self.check = check

    @property
    def suffixes(self) -> Tuple[str, ...]:
        if isinstance(self._suffixes, str):
            import importlib

            module, name = self._suffixes.split(":")
            return tuple(getattr(importlib.import_module(module, __package__), name))
        return tuple(self._suffixes)

    def convert(self, text, flag):
        if not text.strip():
            raise UsageError(f"{flag}: expected a file name ending in {' or '.join(self.suffixes)}, got ''")
        if not text.lower().endswith(self.suffixes):
            raise UsageError(f"{flag}: expected a file name ending in {' or '.join(self.suffixes)}, got {text!r}")
        if self.check:
            from ..io import check_output_path

            check_output_path(text, self.suffixes, option=flag)
        return text


class Scheduler(ParamType):
    """The address of a dask.distributed scheduler, ``tcp://HOST:PORT`` (or another scheme://)."""

    metavar = "tcp://HOST:PORT"

    def convert(self, text, flag):
        t = text.strip()
        m = re.fullmatch(r"([a-z][a-z0-9+.-]*)://(\[[0-9a-fA-F:.]+\]|[A-Za-z0-9_.-]+):(\d{1,5})/?", t)
        if not (t.isascii() and m and 1 <= int(m.group(3)) <= 65535):
            raise UsageError(f"{flag}: expected a scheduler address such as tcp://127.0.0.1:8786, got {text!r}")
        return t


class Port(ParamType):
    metavar = "PORT"

    def convert(self, text, flag):
        t = text.strip()
        if not (t.isascii() and t.isdigit() and len(t) <= 5 and 1 <= int(t) <= 65535):
            raise UsageError(f"{flag}: expected a whole number from 1 to 65535, got {text!r}")
        return int(t)


class Host(ParamType):
    """An IP address (``[::1]`` or ``::1``) or a host name."""

    metavar = "HOST"

    def convert(self, text, flag):
        name = text.strip()
        if not name:
            raise UsageError(f"{flag}: expected an address such as 127.0.0.1 or 0.0.0.0, got {text!r}")
        bare = name[1:-1] if name.startswith("[") and name.endswith("]") else name
        try:
            return str(ipaddress.ip_address(bare))
        except ValueError:
            if not (name.isascii() and re.fullmatch(r"[A-Za-z0-9](?:[A-Za-z0-9.-]{0,251}[A-Za-z0-9])?", name)):
                raise UsageError(f"{flag}: expected an IP address or a host name, got {text!r}") from None
            return name


class Size(ParamType):
    """``WIDTHxHEIGHT`` in pixels."""

    metavar = "WxH"

    def convert(self, text, flag) -> Tuple[int, int]:
        parts = text.strip().lower().replace("×", "x").split("x")
        if len(parts) != 2 or not all(p.strip().isascii() and p.strip().isdigit() and len(p.strip()) <= 5 for p in parts):
            raise UsageError(f"{flag}: expected WIDTHxHEIGHT in pixels (e.g. 640x480), got {text!r}")
        w, h = (int(p) for p in parts)
        if not (16 <= w <= 7680 and 16 <= h <= 4320):
            raise UsageError(f"{flag}: expected WIDTHxHEIGHT from 16x16 to 7680x4320 pixels, got {text!r}")
        return w, h


class Section(ParamType):
    """``phi=VALUE`` or ``psi=VALUE`` (an angle: radians, deg, a multiple of pi) -> the library's spelling."""

    metavar = "phi=VALUE|psi=VALUE"

    def convert(self, text, flag):
        m = re.fullmatch(r"\s*(phi|psi)\s*=\s*(\S+)\s*", text)
        if not m:
            raise UsageError(f"{flag}: expected phi=VALUE or psi=VALUE (radians, e.g. 30deg, or a multiple of pi such as pi/2), got {text!r}")
        value = parse_scalar(m.group(2), f"{flag} {m.group(1)}", angle=True)
        if value is None:
            raise UsageError(f"{flag} {m.group(1)}: the value must be a number, not 'sym'")
        return f"{m.group(1)}={value!r}"


class Energy(ParamType):
    """An energy in joules (a finite number; the library checks it against the minimum)."""

    metavar = "JOULES"

    def convert(self, text, flag):
        value = parse_scalar(text, flag)
        if value is None:
            raise UsageError(f"{flag}: expected a number of joules, got {text!r}")
        return value
