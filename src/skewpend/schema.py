"""The model's parameters, declared once: the one place that lists their names.

Every field of the double pendulum's model is declared here with its unit, whether it belongs to a
body (one value per link) or to the whole model, its default, its bound, its role and the texts a
person reads (the command line's help, a table's meaning, the symbol of a picture and of a
formula).  Everything else derives from this table: :class:`skewpend.Parameters` (its fields,
defaults and checks), run files and their refusals, the command line's model options, the SymPy
symbols' assumptions, the order of the kernels' parameter array ``p``, the report's and the
explorer's texts, the NetCDF attributes.  No other module spells a parameter's name in a list (a
test enforces it: ``tests/test_schema.py``).

Per-body fields are declared once and named per link: ``m`` gives ``m1, m2``; the rod lengths
keep the specification's names ``a, b``.  The scalars come first, in the order of the kernels'
parameter array; then the bodies' geometry and the hinge axes.

This module imports nothing heavy (no NumPy, no SymPy).
"""

from __future__ import annotations

import difflib
import math
import os
from dataclasses import dataclass
from typing import Any, Dict, Iterable, Optional, Tuple

__all__ = [
    "Field", "FIELDS", "LINKS", "NAMES", "SCALAR_NAMES", "GEOMETRY_NAMES", "CORE_NAMES", "DAMPING_NAMES",
    "TORQUE_NAMES", "FRICTION_NAMES", "ROTOR_NAMES", "NONCONSERVATIVE_NAMES", "LENGTH_NAMES", "MASS_NAMES",
    "COM_NAMES", "INERTIA_NAMES", "AXIS_NAMES", "OPTIONAL_DEFAULTS", "field", "names", "unit", "meaning",
    "symbol", "tex", "help_text", "default", "nearest", "unknown_names_message", "check_bound", "body_of",
    "name_of", "LINK_FIELDS", "CHAIN_NAMES", "link_bound", "link_field_of", "coordinate_names", "state_coordinates", "count_text",
    "state_text",
    "MAX_LINKS", "LINK_KEYS", "nearest_link_key", "did_you_mean", "MOTOR_FIELDS", "MOTOR_KEYS",
]

#: The links of today's model: the double pendulum is the chain of two.
LINKS = 2

#: The roles of the fields (what a field does in the model):
#: ``body`` (lengths, masses, centres of mass, inertias), ``axis`` (the hinge axes and alpha),
#: ``world`` (g), ``damping`` (viscous), ``torque`` (constant joint torques), ``friction``
#: (Coulomb), ``rotor`` (geared motors' rotors).  Damping, friction and torques make a model
#: non-conservative: its energy E = T + Pi is not conserved.
ROLES = ("body", "axis", "world", "damping", "torque", "friction", "rotor")
NONCONSERVATIVE_ROLES = ("damping", "torque", "friction")

#: The bounds a scalar may have: ``positive`` (> 0), ``nonnegative`` (>= 0), ``real`` (any),
#: ``angle`` (any, in radians).
BOUNDS = {"positive": "> 0", "nonnegative": ">= 0", "real": "any real number", "angle": "an angle in radians"}


@dataclass(frozen=True)
class Field:
    """One declared parameter (per body: one value per link, named by :meth:`name`).

    ``kind`` is ``scalar``, ``vector`` (3 components) or ``inertia`` (a symmetric 3x3 tensor).
    ``default``: the value when not given (``None``: symbolic for a scalar; for geometry, the
    specification's thin rods and axes, described by ``default_text``).  ``help`` and ``meaning``
    may hold ``{i}`` (the link) and ``{q}`` (the link's coordinate)."""

    stem: str
    kind: str
    unit: str
    role: str
    meaning: str
    help: str
    bound: str = "real"
    default: Any = None
    per_body: bool = False
    #: the names per link when they are not ``stem`` + link (the rods' lengths ``a, b``)
    link_names: Tuple[str, ...] = ()
    #: the symbol as a picture writes it (``m{i}`` -> ``m₁``) and as TeX writes it
    text_symbol: str = ""
    tex_symbol: str = ""
    default_text: str = ""
    #: a symbolic vector's or tensor's entry names (``"sym"``): ``r{i}`` -> ``r1x, r1y, r1z``
    sym_prefix: Tuple[str, ...] = ()
    #: the explorer's slider (none: no slider): ``(place, (min, max, step), shown in degrees, the word after its
    #: name)`` -- the sliders shown in the order of their places (``views.frontend.SLIDER_RANGES``)
    slider: Tuple[Any, ...] = ()

    def name(self, i: Optional[int] = None) -> str:
        """The field's name for link ``i`` (1-based), or the global field's name."""
        if not self.per_body:
            return self.stem
        if self.link_names:
            return self.link_names[i - 1]
        return f"{self.stem}{i}"

    @property
    def names(self) -> Tuple[str, ...]:
        return tuple(self.name(i) for i in range(1, LINKS + 1)) if self.per_body else (self.stem,)


_SUB = str.maketrans("0123456789", "₀₁₂₃₄₅₆₇₈₉")
_COORD = {1: "dphi", 2: "dpsi"}

#: The declarations, in the order of the kernels' parameter array (scalars), then the geometry.
FIELDS: Tuple[Field, ...] = (
    Field("l", "scalar", "m", "body", "length of rod {i}", "length of rod {i} [m]", "positive", per_body=True,
          link_names=("a", "b"), text_symbol="{name}", tex_symbol="{name}", slider=(1, (0.2, 3.0, 0.05), False, "rod {i}")),
    Field("m", "scalar", "kg", "body", "mass of rod {i}", "mass of rod {i} [kg]", "positive", per_body=True,
          text_symbol="m{sub}", tex_symbol="m_{i}", slider=(2, (0.1, 5.0, 0.05), False, "")),
    Field("alpha", "scalar", "rad", "axis", "angle between the hinge axes with the rods hanging",
          "skew angle of the hinges [rad, e.g. 30deg, or a multiple of pi]", "angle", text_symbol="α",
          tex_symbol=r"\alpha", slider=(0, (-180.0, 180.0, 0.5), True, "skew")),
    Field("g", "scalar", "m/s²", "world", "gravitational acceleration", "gravitational acceleration [m/s^2]",
          "nonnegative", text_symbol="g", tex_symbol="g", slider=(3, (0.0, 20.0, 0.01), False, "")),
    Field("c", "scalar", "N m s", "damping", "viscous damping in hinge {i}",
          "viscous damping in hinge {i} [N m s] (default 0)", "nonnegative", 0.0, per_body=True,
          text_symbol="c{sub}", tex_symbol="c_{i}", slider=(4, (0.0, 2.0, 0.01), False, "damping")),
    Field("tau", "scalar", "N m", "torque", "constant torque in hinge {i}",
          "constant torque in hinge {i} [N m] (default 0)", "real", 0.0, per_body=True,
          text_symbol="τ{sub}", tex_symbol=r"\tau_{i}"),
    Field("cf", "scalar", "N m", "friction", "Coulomb friction in hinge {i}",
          "Coulomb friction in hinge {i} [N m]: torque -cf{i} atan(cfs {q}), at most cf{i} pi/2 (default 0)",
          "nonnegative", 0.0, per_body=True, text_symbol="cf{sub}", tex_symbol=r"c_{{f{i}}}"),
    Field("cfs", "scalar", "s/rad", "friction", "smoothing rate of the Coulomb friction's atan",
          "smoothing rate of the Coulomb friction's atan [s/rad], > 0 (default 100)", "positive", 100.0,
          text_symbol="cfs", tex_symbol=r"c_{{fs}}"),
    Field("Ir", "scalar", "kg m²", "rotor", "rotor inertia of each geared motor",
          "rotor inertia of each geared motor [kg m^2] (default 0: no motors)", "nonnegative", 0.0,
          text_symbol="Iᵣ", tex_symbol="I_r"),
    Field("gr", "scalar", "1", "rotor", "gear ratio of the motors",
          "gear ratio: rotor speed over joint speed, negative if the gear reverses (default 1)", "real", 1.0,
          text_symbol="gᵣ", tex_symbol="g_r"),
    Field("com", "vector", "m", "body", "centre of mass of body {i}, in its frame",
          "centre of mass of body {i}, 'x,y,z' in its frame [m]", per_body=True,
          tex_symbol=r"\underline{{c}}_{i}", default_text="rod midpoint (0, {l}/2, 0)", sym_prefix=("r{i}",)),
    Field("inertia", "inertia", "kg m²", "body", "inertia tensor of body {i} about its centre of mass",
          "inertia of body {i} about its centre of mass: 'Ixx,Iyy,Izz[,Ixy,Ixz,Iyz]' [kg m^2]", per_body=True,
          tex_symbol=r"\underline{{\underline{{\Theta}}}}{{}}^0_{i}", default_text="thin rod m{sub}{l}²/12 (E − jj)",
          sym_prefix=("I{i}",)),
    Field("axis", "vector", "", "axis", "axis of hinge {i}", "axis of hinge {i}, 'x,y,z' (default k)", per_body=True,
          tex_symbol=r"\underline{{n}}_1", default_text="k", sym_prefix=("n1", "e0")),
)

_BY_NAME: Dict[str, Tuple[Field, Optional[int]]] = {}
for _f in FIELDS:
    for _i, _n in enumerate(_f.names, start=1):
        _BY_NAME[_n] = (_f, _i if _f.per_body else None)
del _f, _i, _n


def field(name: str) -> Field:
    """The declaration of the parameter ``name`` (``m1`` -> the field ``m``)."""
    try:
        return _BY_NAME[name][0]
    except KeyError:
        raise KeyError(unknown_names_message([name])) from None


def body_of(name: str) -> Optional[int]:
    """The link (1-based) a per-body parameter belongs to; None for a global one."""
    return _BY_NAME[name][1]


def name_of(stem: str, i: Optional[int] = None) -> str:
    """The parameter's name of the field ``stem`` for link ``i``: ``name_of("m", 2) == "m2"``,
    ``name_of("l", 1) == "a"``."""
    for f in FIELDS:
        if f.stem == stem:
            return f.name(i)
    raise KeyError(f"no field {stem!r}; fields: {', '.join(f.stem for f in FIELDS)}")


def names(*, kind: Optional[str] = None, role: Optional[str] = None, stem: Optional[str] = None,
          roles: Iterable[str] = ()) -> Tuple[str, ...]:
    """The parameters' names in declaration order, filtered by ``kind`` (scalar, vector,
    inertia; ``"geometry"`` for vectors and tensors), ``role``/``roles`` and ``stem``."""
    roles = tuple(roles) + ((role,) if role else ())
    out = []
    for f in FIELDS:
        if kind == "geometry" and f.kind == "scalar" or kind not in (None, "geometry") and f.kind != kind:
            continue
        if roles and f.role not in roles or stem and f.stem != stem:
            continue
        out += f.names
    return tuple(out)


#: Every parameter's name, in declaration order.
NAMES: Tuple[str, ...] = names()
#: The scalar parameters, in the order of the kernels' parameter array and of JSON.
SCALAR_NAMES: Tuple[str, ...] = names(kind="scalar")
#: The bodies' and axes' geometry (vectors and tensors; default: the specification's thin rods and axes).
GEOMETRY_NAMES: Tuple[str, ...] = names(kind="geometry")
#: The parameters every model has (rod lengths, masses, the skew, gravity).
CORE_NAMES: Tuple[str, ...] = names(kind="scalar", roles=("body", "axis", "world"))
LENGTH_NAMES: Tuple[str, ...] = names(stem="l")
MASS_NAMES: Tuple[str, ...] = names(stem="m")
COM_NAMES: Tuple[str, ...] = names(stem="com")
INERTIA_NAMES: Tuple[str, ...] = names(stem="inertia")
AXIS_NAMES: Tuple[str, ...] = names(stem="axis")
DAMPING_NAMES: Tuple[str, ...] = names(role="damping")
TORQUE_NAMES: Tuple[str, ...] = names(role="torque")
#: The optional terms, off by default: Coulomb friction (with its smoothing rate) and the rotors.
FRICTION_NAMES: Tuple[str, ...] = names(role="friction")
ROTOR_NAMES: Tuple[str, ...] = names(role="rotor")
#: The parameters whose non-zero (or symbolic) value makes a model non-conservative.
NONCONSERVATIVE_NAMES: Tuple[str, ...] = tuple(n for f in FIELDS if f.role in NONCONSERVATIVE_ROLES and f.per_body
                                               for n in f.names)
#: The scalars with a numeric default (the others are symbolic unless given).
#: A chain's link (:class:`skewpend.symbolic.chain.Chain`): its keys as run files' ``[[links]]`` tables
#: spell them, each with the stem of the double pendulum's field it is per link (``length`` is ``a, b``,
#: ``mass`` is ``m1, m2``; the rotors' ``Ir``, ``gr``, one pair for both joints there, are per joint in a
#: chain) and its kind; ``offset`` -- the hinge's position in the parent's frame -- is the chain's own (the
#: double pendulum's second hinge sits at ``(0, a, 0)``).
LINK_FIELDS: Tuple[Tuple[str, str, str], ...] = (
    ("axis", "axis", "vector"), ("offset", "h", "vector"), ("length", "l", "scalar"), ("mass", "m", "scalar"),
    ("com", "com", "vector"), ("inertia", "inertia", "inertia"), ("damping", "c", "scalar"),
    ("coulomb", "cf", "scalar"), ("torque", "tau", "scalar"), ("rotor", "Ir", "scalar"), ("gear", "gr", "scalar"),
)
#: A link's keys, in order.
LINK_KEYS: Tuple[str, ...] = tuple(key for key, _, _ in LINK_FIELDS)
#: The largest chain of links (the generated code is built for it; the command line's --links takes 1 to it).
MAX_LINKS = 32
#: A voltage-driven DC motor on one joint of a chain (a run file's ``[motor]``, :class:`skewpend.config.Motor`):
#: its keys, each with its unit and meaning.  Its torque ``kt (V - km q') / R`` is the joint's viscous damping
#: ``kt km / R`` (the back-EMF) and an input ``kt V / R`` bounded by ``kt Vmax / R``.
MOTOR_FIELDS: Tuple[Tuple[str, str, str], ...] = (
    ("joint", "", "the joint it drives (1 to the number of links)"),
    ("resistance", "ohm", "the armature's resistance R"),
    ("torque_constant", "N m/A", "the torque constant kt"),
    ("back_emf_constant", "V s/rad", "the back-EMF constant km"),
    ("voltage_limit", "V", "the largest voltage |V| the amplifier applies"),
)
#: The motor's keys, in order.
MOTOR_KEYS: Tuple[str, ...] = tuple(key for key, _, _ in MOTOR_FIELDS)
#: The chain's own fields (the whole chain's, not a link's): the global scalars that are no axis and no rotor.
CHAIN_NAMES: Tuple[str, ...] = tuple(f.stem for f in FIELDS if f.kind == "scalar" and not f.per_body
                                     and f.role not in ("axis", "rotor"))


def coordinate_names(n: int) -> Tuple[str, ...]:
    """The coordinates of a chain of ``n`` links: ``phi, psi`` for two (the specification's), ``q1`` to ``qn``
    otherwise."""
    return ("phi", "psi") if n == 2 else tuple(f"q{i}" for i in range(1, n + 1))


_WORDS = ("no", "one", "two", "three", "four", "five", "six", "seven", "eight", "nine", "ten", "eleven", "twelve")


def count_text(k: int, what: str) -> str:
    """``k`` things in words for messages: ``count_text(4, "numbers")`` -> ``"four numbers"`` (digits from 13)."""
    return f"{_WORDS[k] if 0 <= k < len(_WORDS) else k} {what}"


def model_title(n: int) -> str:
    """The model in words for titles and messages: ``"the skewed double pendulum"`` for two links (any
    chain of two is the double pendulum), ``"a chain of n links"`` otherwise."""
    return "the skewed double pendulum" if n == 2 else f"a chain of {n} link{'s' if n != 1 else ''}"


def state_text(nq: int) -> str:
    """The state of ``nq`` coordinates for messages: ``"four numbers (phi, psi, phi', psi')"``."""
    names = coordinate_names(nq)
    return f"{count_text(2 * nq, 'numbers')} ({', '.join(names)}, {', '.join(c + chr(39) for c in names)})"


def state_coordinates(nq: int) -> Dict[str, int]:
    """The state's coordinates a slice may vary, by their index in ``x``: the double pendulum's ``phi,
    psi, dphi, dpsi``; a chain of ``n`` links' ``q1 … qn, dq1 … dqn``."""
    names = coordinate_names(nq)
    return {**{c: i for i, c in enumerate(names)}, **{f"d{c}": nq + i for i, c in enumerate(names)}}


def link_field_of(name: str) -> Optional[Tuple[str, Optional[int]]]:
    """The chain's link field a facade name is an alias of, and the link (1-based; None: every link's, as the
    double pendulum's one rotor): ``m1`` -> ``("mass", 1)``, ``b`` -> ``("length", 2)``, ``alpha`` ->
    ``("axis", 2)`` (hinge 2's tilt from ``k`` towards ``i``), ``Ir`` -> ``("rotor", None)``; None for the
    chain's own fields (``g``, ``cfs``) and unknown names."""
    if name == "alpha":
        return ("axis", 2)
    for f in FIELDS:
        if name in f.names:
            key = next((k for k, stem, _ in LINK_FIELDS if stem == f.stem), None)
            if key is None:
                return None
            return (key, f.names.index(name) + 1 if f.per_body else None)
    return None


def link_bound(key: str) -> str:
    """The bound of a chain link's scalar ``key`` (``mass`` -> ``positive``), the double pendulum's field's."""
    stem = next(stem for k, stem, _ in LINK_FIELDS if k == key)
    return next(f.bound for f in FIELDS if f.stem == stem)


OPTIONAL_DEFAULTS: Dict[str, float] = {n: field(n).default for n in SCALAR_NAMES if field(n).default is not None}


def _format(template: str, name: str) -> str:
    i = body_of(name)
    lengths = dict(enumerate(LENGTH_NAMES, start=1))
    return template.format(i=i or "", sub=str(i or "").translate(_SUB), q=_COORD.get(i, ""), name=name,
                           l=lengths.get(i, ""))


def unit(name: str) -> str:
    """The SI unit of ``name`` as a person reads it (``kg``, ``m/s²``; ``rad`` for alpha; ``""``
    for the axes)."""
    return field(name).unit


def _text(name: str, attribute: str, second_axis: str, empty: Optional[str] = None) -> str:
    """A field's text (``meaning``, ``help``, ``tex_symbol``, ...) for ``name``; the last link's axis
    has its own (it replaces ``alpha``); ``empty``: what an empty text gives (default: itself)."""
    if name in AXIS_NAMES and body_of(name) == LINKS:
        return second_axis
    text = getattr(field(name), attribute)
    return _format(text, name) if text or empty is None else empty


def meaning(name: str) -> str:
    """What ``name`` is, in a few words (``mass of rod 1``)."""
    return _text(name, "meaning", "axis of hinge 2 with the rods hanging")


def help_text(name: str) -> str:
    """The command line's help of ``--name``."""
    return _text(name, "help", "axis of hinge 2 with the rods vertical, 'x,y,z' (default cos(alpha) k + sin(alpha) i; "
                               "replaces --alpha)")


def symbol(name: str) -> str:
    """The symbol a picture's text writes (``m₁``, ``α``, ``τ₂``; the name when it has none)."""
    f = field(name)
    return _format(f.text_symbol, name) if f.text_symbol else name


def tex(name: str) -> str:
    """The symbol in TeX (``m_1``, ``\\alpha``, ``\\underline{c}_1``)."""
    return _text(name, "tex_symbol", r"\underline{e}_0", empty=name)


def default_text(name: str) -> str:
    """The default of a geometry field in words (``rod midpoint (0, a/2, 0)``)."""
    return _text(name, "default_text", "e₀ = cos α k + sin α i")


def sym_prefix(name: str) -> str:
    """The prefix of a symbolic vector's or tensor's entries (``com2`` -> ``r2``: ``r2x, r2y, r2z``)."""
    f = field(name)
    i = body_of(name)
    prefixes = f.sym_prefix
    return (prefixes[i - 1] if len(prefixes) > 1 else prefixes[0]).format(i=i)


def default(name: str) -> Any:
    """The default value (None: symbolic, or for geometry the thin rods and default axes)."""
    return field(name).default


def nearest(name: str, allowed: Iterable[str]) -> Optional[str]:
    """The allowed name closest to a misspelled one (None when none is close)."""
    allowed = list(allowed)
    lower = {a.lower(): a for a in allowed}
    if str(name).lower() in lower:
        return lower[str(name).lower()]
    word, digits = str(name).lower().rstrip("0123456789"), str(name)[len(str(name).rstrip("0123456789")):]
    for f in FIELDS:  # a field spelled as its meaning's first word: mass1 -> m1, damping2 -> c2
        first = f.meaning.split()[0].lower()
        word = word.rstrip("_")
        common = len(os.path.commonprefix([first, word]))
        if len(word) >= 3 and common >= min(len(word), max(4, len(word) - 2)):
            i = int(digits) if digits.isdigit() and f.per_body and 1 <= int(digits) <= LINKS else None
            guess = f.name(i) if f.per_body and i else (f.stem if not f.per_body else None)
            if guess in allowed:
                return guess
    match = difflib.get_close_matches(str(name), allowed, n=1, cutoff=0.6)
    return match[0] if match else None


def nearest_link_key(name: str) -> Optional[str]:
    """The link key a misspelled one likely meant: a near spelling (``lenght`` -> ``length``), or the double
    pendulum's name of the field (``m``, ``m1`` -> ``mass``; ``a`` -> ``length``; ``tau2`` -> ``torque``)."""
    text = str(name)
    stem = text.rstrip("0123456789") or text
    by_stem = {s: key for key, s, _ in LINK_FIELDS}
    if stem in by_stem:
        return by_stem[stem]
    if text in LENGTH_NAMES:
        return "length"
    return nearest(text, LINK_KEYS)


def did_you_mean(close: Optional[str]) -> str:
    """`` (did you mean 'x'?)`` when there is a close name, else nothing."""
    return f" (did you mean {close!r}?)" if close else ""


def unknown_names_message(unknown: Iterable[str], allowed: Iterable[str] = NAMES, where: str = "") -> str:
    """One line naming unknown parameter names, the nearest allowed name of each and the allowed
    names: ``unknown parameter 'mass1' (did you mean 'm1'?); allowed: a, b, m1, ...``."""
    unknown = [str(u) for u in unknown]
    allowed = list(allowed)
    parts = []
    for u in unknown:
        close = nearest(u, allowed)
        parts.append(f"{u!r}" + (f" (did you mean {close!r}?)" if close else ""))
    what = "unknown parameter" + ("s" if len(unknown) > 1 else "")
    return f"{where + ': ' if where else ''}{what} {', '.join(parts)}; allowed: {', '.join(allowed)}"


def check_bound(name: str, x: float) -> Optional[str]:
    """The message when the number ``x`` breaks the bound of the scalar ``name`` (None when it keeps it)."""
    bound = field(name).bound
    if bound == "positive" and not x > 0:
        return f"{name} must be > 0, got {x:g}"
    if bound == "nonnegative" and x < 0:
        return f"{name} must be >= 0, got {x:g}"
    if not math.isfinite(x):
        return f"{name} must be finite, got {x}"
    return None
