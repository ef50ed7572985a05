"""A chain of links on skewed hinges: the model as data, of any length.

A :class:`Chain` is a list of :class:`Link` objects and the gravitational acceleration.  Link ``i``
hangs from hinge ``i``; its hinge axis and the hinge's position are given in the frame of the link
before it (the roof for the first link), with the whole chain hanging straight down (the
specification's reference configuration: every body frame parallel to ``i, j, k``, ``j`` down).
Its coordinate ``q_i`` is the rotation in hinge ``i`` relative to the link before, zero hanging.

The double pendulum is the chain of two (:meth:`Chain.from_parameters`): link 1 is rod ``a`` on the
roof hinge (axis ``k`` or ``axis1``), link 2 rod ``b`` on the hinge at ``a j`` (axis
``e0 = cos(alpha) k + sin(alpha) i`` or ``axis2``), ``q = (phi, psi)``.

Per link (SI units; the defaults are the specification's thin uniform rods):

* ``axis`` -- the hinge axis in the parent's frame (any non-zero vector, normalised; default ``k``);
* ``offset`` -- the hinge's position in the parent's frame, from the parent's hinge (default: the
  parent's end ``(0, l_parent, 0)``; the roof hinge at the origin);
* ``length`` -- the rod's length ``l`` > 0 (its end carries the next hinge by default and is the
  chain's tip for the last link);
* ``mass`` > 0; ``com`` -- the centre of mass in the link's frame (default ``(0, l/2, 0)``);
  ``inertia`` -- about the centre of mass, in the link's frame (default ``m l^2/12 (E - j j)``);
* per joint: ``damping`` (viscous, N m s, >= 0), ``coulomb`` (N m, >= 0: the torque
  ``-coulomb atan(cfs q_i')``), ``torque`` (constant, N m), ``rotor`` (the axial inertia of a
  geared motor's rotor carried by the parent, kg m^2, >= 0) and ``gear`` (its speed relative to the
  parent over the joint's, default 1).

Everything is numeric: a chain is a model to compute with (the two-link :class:`~skewpend.Parameters`
keep symbolic values for the derivation's display).  This module imports nothing heavy.
"""

from __future__ import annotations

import math
import numbers
from dataclasses import dataclass, field, fields, replace
from typing import Any, Iterable, Mapping, Optional, Tuple

from ..errors import ParameterError
from ..schema import (CHAIN_NAMES, LINK_FIELDS, LINK_KEYS, MAX_LINKS, coordinate_names, did_you_mean, link_bound,
                      link_field_of, model_title, nearest, nearest_link_key)
from .values import Mat3, Vec3, as_real, as_vector, check_inertia

__all__ = ["Link", "Chain", "LINK_KEYS", "MAX_LINKS"]

# MAX_LINKS: the largest chain the generated code is built for (the state of 2 N + 1 numbers); LINK_KEYS: a
# link's keys, as run files and Link.from_mapping spell them -- both declared in the schema.
#: The exact symbolic equations of a chain (``derive(chain)`` by SymPy, then printed) grow about
#: :data:`SYMBOLIC_GROWTH`-fold in time a link: measured on a 2-core machine (``skewpend derive --links N
#: --format text``, derivation and printing) 4 links 2 s, 5 links 11 s, 6 links 60 s.  Beyond
#: :data:`SYMBOLIC_LINKS_MAX` the command line refuses them (the recursive algorithms' code is the way).
SYMBOLIC_SECONDS = {4: 2.0, 5: 11.0, 6: 60.0}
SYMBOLIC_GROWTH = 5.5
SYMBOLIC_LINKS_MAX = 7


def symbolic_seconds(n: int) -> float:
    """The estimated time [s] of a chain of ``n`` links' exact symbolic equations (see :data:`SYMBOLIC_SECONDS`)."""
    last = max(SYMBOLIC_SECONDS)
    if n in SYMBOLIC_SECONDS:
        return SYMBOLIC_SECONDS[n]
    if n < min(SYMBOLIC_SECONDS):
        return SYMBOLIC_SECONDS[min(SYMBOLIC_SECONDS)]
    return SYMBOLIC_SECONDS[last] * SYMBOLIC_GROWTH ** (n - last)


_CHAIN_KEYS = ("links",) + CHAIN_NAMES
_BOUNDS = {key: link_bound(key) for key, _, kind in LINK_FIELDS if kind == "scalar"}


def _unit(name: str, v) -> Vec3:
    v = tuple(as_real(f"{name}[{i}]", x) for i, x in enumerate(as_vector(name, v)))
    big = max(abs(x) for x in v)
    norm = big * math.sqrt(sum((x / big) ** 2 for x in v)) if big > 0 else 0.0
    if not norm > 1e-12:
        raise ParameterError(f"{name} must be a non-zero vector (a hinge axis), got {v}")
    return tuple(x / norm for x in v)  # type: ignore[return-value]


def _inertia(name: str, value) -> Mat3:
    """A 3x3 tensor, or 3 (principal: Ixx, Iyy, Izz) or 6 numbers (Ixx, Iyy, Izz, Ixy, Ixz, Iyz)."""
    try:
        items = list(value)
    except TypeError:
        raise ParameterError(f"{name} must be a 3x3 matrix or 3 or 6 numbers (Ixx, Iyy, Izz[, Ixy, Ixz, Iyz]), "
                             f"got {value!r}") from None
    mat: Any
    if len(items) in (3, 6) and not any(isinstance(x, (list, tuple)) for x in items):
        e = [as_real(f"{name}[{i}]", x, 1e300) for i, x in enumerate(items)] + [0.0] * (6 - len(items))
        mat = ((e[0], e[3], e[4]), (e[3], e[1], e[5]), (e[4], e[5], e[2]))
    elif len(items) == 3:
        mat = tuple(tuple(as_real(f"{name}[{i}][{j}]", x, 1e300) for j, x in enumerate(as_vector(f"{name}[{i}]", r)))
                    for i, r in enumerate(items))
    else:
        raise ParameterError(f"{name} must be a 3x3 matrix or 3 or 6 numbers (Ixx, Iyy, Izz[, Ixy, Ixz, Iyz]), "
                             f"got {len(items)} entries")
    check_inertia(name, mat)  # type: ignore[arg-type]
    return mat  # type: ignore[return-value]


@dataclass(frozen=True)
class Link:
    """One link of a :class:`Chain` (validated when built; see the module's text for the fields).

    ``offset``, ``com`` and ``inertia`` may be None: the chain fills in the thin rod's values
    (:attr:`Chain.links` holds them resolved)."""

    axis: Vec3 = (0.0, 0.0, 1.0)
    offset: Optional[Vec3] = None
    length: float = 1.0
    mass: float = 1.0
    com: Optional[Vec3] = None
    inertia: Optional[Mat3] = None
    damping: float = 0.0
    coulomb: float = 0.0
    torque: float = 0.0
    rotor: float = 0.0
    gear: float = 1.0
    #: the place of the link in its chain (1-based) for messages; 0 when alone
    index: int = field(default=0, compare=False, repr=False)

    def __post_init__(self) -> None:
        at = f"link {self.index}" if self.index else "link"
        for key, bound in _BOUNDS.items():
            x = as_real(f"{at} {key}", getattr(self, key))
            if bound == "positive" and not x > 0 or bound == "nonnegative" and x < 0:
                raise ParameterError(f"{at} {key} must be {'> 0' if bound == 'positive' else '>= 0'}, got {x:g}")
            object.__setattr__(self, key, x)
        object.__setattr__(self, "axis", _unit(f"{at} axis", self.axis))
        for key in ("offset", "com"):
            if getattr(self, key) is not None:
                v = as_vector(f"{at} {key}", getattr(self, key))
                object.__setattr__(self, key, tuple(as_real(f"{at} {key}[{i}]", x) for i, x in enumerate(v)))
        if self.inertia is not None:
            object.__setattr__(self, "inertia", _inertia(f"{at} inertia", self.inertia))

    @property
    def rod_inertia(self) -> Mat3:
        """The thin rod's inertia about its midpoint, ``m l^2/12 (E - j j)``."""
        k = self.mass * self.length ** 2 / 12.0
        return ((k, 0.0, 0.0), (0.0, 0.0, 0.0), (0.0, 0.0, k))

    def to_dict(self) -> dict:
        """Plain-data form, a run file's ``[[links]]`` table."""
        out: dict = {}
        for key in LINK_KEYS:
            v = getattr(self, key)
            if v is not None:
                out[key] = [list(r) for r in v] if key == "inertia" else (list(v) if isinstance(v, tuple) else v)
        return out

    @classmethod
    def from_mapping(cls, data: Mapping[str, Any], index: int = 0) -> "Link":
        """A link from a mapping (a run file's ``[[links]]`` table); an unknown key is an error."""
        if not isinstance(data, Mapping):
            raise ParameterError(f"link {index or ''} must be a table of {', '.join(LINK_KEYS)}, got {data!r}".replace("  ", " "))
        unknown = [k for k in data if k not in LINK_KEYS]
        if unknown:
            raise ParameterError(f"link {index}: unknown key {unknown[0]!r}{did_you_mean(nearest_link_key(unknown[0]))}; "
                                 f"a link takes {', '.join(LINK_KEYS)}")
        return cls(**dict(data), index=index)


#: The double pendulum's parameters of a chain of two, or None (``[exact_of_chain]``: set by
#: :mod:`skewpend.symbolic.model`, which imports this module, so that this one imports nothing of the facade).
EXACT_OF: list = [None]


@dataclass(frozen=True)
class Chain:
    """A chain of ``n`` links hanging from the roof (``n >= 1``), the gravitational acceleration
    ``g`` (along ``+j``, down) and the Coulomb friction's smoothing rate ``cfs``.

    The links are stored resolved: every ``offset``, ``com`` and ``inertia`` has its value (the thin
    rods' where none was given), each link knows its place (``index``)."""

    links: Tuple[Link, ...]
    g: float = 9.81
    cfs: float = 100.0

    def __post_init__(self) -> None:
        try:
            links = list(self.links)
        except TypeError:
            raise ParameterError(f"a chain's links must be a list of links, got {self.links!r}") from None
        if not links:
            raise ParameterError("a chain needs at least 1 link, got 0")
        if len(links) > MAX_LINKS:
            raise ParameterError(f"a chain may have at most {MAX_LINKS} links, got {len(links)}")
        out = []
        parent_length = 0.0
        for i, link in enumerate(links, start=1):
            if isinstance(link, Mapping):
                link = Link.from_mapping(link, i)
            elif not isinstance(link, Link):
                raise ParameterError(f"link {i} must be a Link or a table, got {link!r}")
            link = replace(link, index=i)
            offset = link.offset if link.offset is not None else (0.0, parent_length, 0.0)
            com = link.com if link.com is not None else (0.0, link.length / 2.0, 0.0)
            inertia = link.inertia if link.inertia is not None else link.rod_inertia
            out.append(replace(link, offset=offset, com=com, inertia=inertia, index=i))
            parent_length = link.length
        object.__setattr__(self, "links", tuple(out))
        g = as_real("g", self.g)
        if g < 0:
            raise ParameterError(f"g must be >= 0, got {g:g}")
        cfs = as_real("cfs", self.cfs)
        if not cfs > 0:
            raise ParameterError(f"cfs must be > 0, got {cfs:g}")
        object.__setattr__(self, "g", g)
        object.__setattr__(self, "cfs", cfs)

    # -- queries ----------------------------------------------------------------------------------------
    @property
    def n(self) -> int:
        """The number of links (and of coordinates)."""
        return len(self.links)

    def __len__(self) -> int:
        return self.n

    @property
    def is_numeric(self) -> bool:
        """True: a chain's values are numbers (the double pendulum's facade may keep symbols for display)."""
        return True

    def require_numeric(self, what: str = "this operation") -> "Chain":
        """Return self (a chain is numeric), as :meth:`skewpend.Parameters.require_numeric` answers."""
        return self

    def as_chain(self) -> "Chain":
        """The model as a chain: itself (the double pendulum's :class:`~skewpend.Parameters` answer the same
        question with the chain of two)."""
        return self

    def value(self, name: str):
        """A value by its name: the chain's own (``g``, ``cfs``), a link's field by its stem and the link's
        number (``m3``, ``l2``, ``c1``, ``cf2``, ``tau3``, ``Ir1``: ``links[k - 1]``'s), and the double pendulum's
        names of its links' fields (``a``, ``b``: ``links[0].length``, ``links[1].length``).  An unknown
        name, or a link that does not exist: one line."""
        if name in CHAIN_NAMES:
            return getattr(self, name)
        stem = name.rstrip("0123456789")
        number = name[len(stem):]
        key = next((k for k, st, kind in LINK_FIELDS if st == stem and kind == "scalar"), None)
        if key is None or not number:
            alias = link_field_of(name) if name != "alpha" else None  # a, b: links 1 and 2's lengths
            if alias is None or alias[1] is None:
                raise ParameterError(f"unknown parameter {name!r} of {self.title}: a link's scalar is its stem and "
                                     f"number ({', '.join(st + '1' for _, st, kind in LINK_FIELDS if kind == 'scalar')}), "
                                     f"or {', '.join(CHAIN_NAMES)}")
            key, number = alias[0], str(alias[1])
        k = int(number)
        if not 1 <= k <= self.n:
            raise ParameterError(f"{name!r}: {self.title} has links 1 to {self.n}")
        return getattr(self.links[k - 1], key)

    def exact_model(self):
        """The model the specification's exact derivation prints (the ``exact`` form of the generated code):
        for two links that the double pendulum's parameters hold (hinge 2 on rod 1's end, one rotor for both
        joints) with the specification's axes -- hinge 1 along ``k``, hinge 2 in the plane of ``k`` and ``i``,
        its tilt the run-time skew ``alpha`` -- those parameters; None otherwise: the recursive algorithms'
        forms print every chain and read every axis at run time (the exact form would compile each other
        axis's values).  (:func:`skewpend.symbolic.model.exact_of_chain`, which the facade's module registers
        here: this module imports nothing of the facade.)"""
        if EXACT_OF[0] is None:
            return None
        exact = self.__dict__.get("_exact", False)  # once per chain (immutable): asked at every kernel look-up
        if exact is False:
            exact = EXACT_OF[0](self)
            object.__setattr__(self, "_exact", exact)
        return exact

    @property
    def coordinates(self) -> Tuple[str, ...]:
        """The coordinates' names: ``phi, psi`` for two links (the specification's), ``q1`` to ``qn`` otherwise."""
        return coordinate_names(self.n)

    @property
    def title(self) -> str:
        """The model in words: ``"the skewed double pendulum"`` for two links, ``"a chain of n links"`` otherwise."""
        return model_title(self.n)

    @property
    def has_friction(self) -> bool:
        return any(link.coulomb != 0 for link in self.links)

    @property
    def has_rotor(self) -> bool:
        return any(link.rotor != 0 for link in self.links)

    @property
    def dissipative(self) -> bool:
        """Viscous damping or Coulomb friction in some joint: the flow shrinks phase-space volume (constant
        torques derive from a potential and keep it)."""
        return any(link.damping or link.coulomb for link in self.links)

    def require_lossless(self, what: str) -> "Chain":
        """Return self, or one line when energy is dissipated (damping or Coulomb friction in a joint;
        constant torques derive from a potential and are allowed)."""
        lossy = [f"link {link.index} {key} = {getattr(link, key):g}" for link in self.links
                 for key in ("damping", "coulomb") if getattr(link, key)]
        if lossy:
            raise ParameterError(f"{what} needs a conservative model without losses (the energy T + Pi - tau . q decays "
                                 f"otherwise; constant torques are allowed), but {', '.join(lossy)}; set them to 0")
        return self

    @property
    def conservative(self) -> bool:
        """No damping, Coulomb friction or constant torque in any joint (E = T + Pi conserved)."""
        return not any(link.damping or link.coulomb or link.torque for link in self.links)

    def require_links(self, allowed: Iterable[int], what: str) -> "Chain":
        """Return self, or raise one line: ``what`` is defined for these numbers of links only."""
        allowed = tuple(allowed)
        if self.n not in allowed:
            counts = " or ".join(str(k) for k in allowed)
            raise ParameterError(f"{what} is defined for a chain of {counts} links, this chain has {self.n}",
                                 parameter="links")
        return self

    def replace_link(self, i: int, **changes: Any) -> "Chain":
        """A copy with link ``i`` (1-based) changed (validated again)."""
        links = list(self.links)
        links[i - 1] = replace(links[i - 1], **changes)
        return replace(self, links=tuple(links))

    # -- plain data ---------------------------------------------------------------------------------------
    def to_dict(self) -> dict:
        """Plain-data form (a run file: ``g``, ``cfs`` and a ``[[links]]`` table per link)."""
        return {**{k: getattr(self, k) for k in CHAIN_NAMES}, "links": [link.to_dict() for link in self.links]}

    @classmethod
    def from_mapping(cls, data: Mapping[str, Any]) -> "Chain":
        """A chain from a mapping with ``links`` (a list of tables), ``g`` and ``cfs``; unknown keys
        are an error."""
        unknown = [k for k in data if k not in _CHAIN_KEYS]
        if unknown:
            raise ParameterError(f"unknown key {unknown[0]!r}{did_you_mean(nearest(unknown[0], _CHAIN_KEYS))} in a chain; "
                                 f"a chain takes {', '.join(_CHAIN_KEYS)} "
                                 f"(each link: {', '.join(LINK_KEYS)})")
        if "links" not in data:
            raise ParameterError("a chain needs its links: a list of [[links]] tables")
        links = data["links"]
        if isinstance(links, (str, bytes)) or not isinstance(links, Iterable):
            raise ParameterError(f"a chain's links must be a list of tables, got {links!r}")
        return cls(links=tuple(Link.from_mapping(d, i) if not isinstance(d, Link) else d
                               for i, d in enumerate(links, start=1)),
                   **{k: data[k] for k in CHAIN_NAMES if k in data})

    @classmethod
    def from_lists(cls, n: Optional[int] = None, *, g: float = 9.81, cfs: float = 100.0, **per_link: Any) -> "Chain":
        """A chain from per-link lists (``mass=[1, 1, 0.5]``, ``axis=[(0, 0, 1), (1, 0, 0)]``); every list has
        the same length (``n`` links, a whole number from 1 to :data:`MAX_LINKS`; a single value is every link's)."""
        if n is not None and (isinstance(n, bool) or not isinstance(n, numbers.Integral) or not 1 <= n <= MAX_LINKS):
            raise ParameterError(f"n must be the number of links, a whole number from 1 to {MAX_LINKS}, got {n!r}",
                                 parameter="n")
        lengths = {k: len(v) for k, v in per_link.items() if isinstance(v, (list, tuple)) and
                   not (k in ("axis", "offset", "com") and len(v) == 3 and not isinstance(v[0], (list, tuple)))
                   and not (k == "inertia" and len(v) in (3, 6) and not isinstance(v[0], (list, tuple)))}
        unknown = [k for k in per_link if k not in LINK_KEYS]
        if unknown:
            raise ParameterError(f"unknown per-link key {unknown[0]!r}{did_you_mean(nearest_link_key(unknown[0]))}; "
                                 f"a link takes {', '.join(LINK_KEYS)}")
        counts = set(lengths.values()) | ({n} if n is not None else set())
        if len(counts) > 1:
            told = ", ".join(f"{k}: {v}" for k, v in lengths.items())
            raise ParameterError(f"per-link lists of different lengths ({told}{', links: ' + str(n) if n else ''}); "
                                 "give one value a link, or one value for all")
        if not counts:
            raise ParameterError("a chain from per-link values needs the number of links or a list")
        count = counts.pop()
        links = [Link(**{k: (v[i] if k in lengths else v) for k, v in per_link.items()}, index=i + 1)
                 for i in range(count)]
        return cls(links=tuple(links), g=g, cfs=cfs)

    # -- the double pendulum --------------------------------------------------------------------------------
    @classmethod
    def from_parameters(cls, params) -> "Chain":
        """The double pendulum ``params`` as the chain of two: ``params.as_chain()`` (numeric parameters
        only; :meth:`skewpend.Parameters.from_chain` is the way back)."""
        return params.as_chain()


def _link_fields() -> Tuple[str, ...]:
    return tuple(f.name for f in fields(Link) if f.name != "index")


assert _link_fields() == LINK_KEYS, "Link's fields must be the schema's LINK_FIELDS, in order"
assert tuple(f.name for f in fields(Chain) if f.name != "links") == CHAIN_NAMES, "Chain's fields must be the schema's"
