"""Model parameters of the skewed double pendulum.

Geometry (the specification's notation): basis ``i, j, k`` with ``j`` pointing
**down**; the first (roof) hinge turns about ``k`` at the origin, the first rod
hangs along ``j`` and carries the second hinge at its end ``a j``; the second
hinge axis, with both rods vertical, is ``e0 = cos(alpha) k + sin(alpha) i``;
the second rod hangs from it along ``j``.  ``phi`` and ``psi`` are the rotation
angles in the first and second hinge, zero with both rods vertical.

Every quantity is in SI units (m, kg, s, rad, N m, N m s).  A scalar parameter
is either a real number or ``None``, which leaves it **symbolic** (a SymPy
symbol of the same name in the derived equations).  This module does not
import SymPy or NumPy at import time.
"""

from __future__ import annotations

import math
from dataclasses import asdict, field, replace
from typing import Any, Mapping, Optional, Tuple

from ..errors import ParameterError
from ..parsing import MAX_ANGLE
from ..schema import (AXIS_NAMES, COM_NAMES, FRICTION_NAMES, GEOMETRY_NAMES, INERTIA_NAMES, NAMES,  # noqa: F401
                      LENGTH_NAMES, NONCONSERVATIVE_NAMES, ROTOR_NAMES, SCALAR_NAMES, check_bound, default,
                      field as schema_field,
                      names, sym_prefix, unknown_names_message)

__all__ = ["Parameters", "SCALAR_NAMES", "FRICTION_NAMES", "ROTOR_NAMES", "GEOMETRY_NAMES", "RESERVED_NAMES", "Vec3", "Mat3"]

from .values import (MAX_INERTIA, MAX_MAGNITUDE, RESERVED_NAMES, SYMBOLIC_WORDS, Mat3, Scalar, Vec3,  # noqa: F401
                     as_entry, as_matrix, as_real, as_vector, check_inertia, is_numeric, symbol_names)
from .chain import EXACT_OF, Chain, Link


class _Model:
    """Parameters of the skewed double pendulum (immutable, validated when built).

    The fields are declared once, in :mod:`skewpend.schema` (names, units, defaults, bounds).

    Scalars (``None`` = symbolic):

    * ``a``, ``b`` -- rod lengths [m], > 0; the second hinge sits at ``a j`` on rod 1.
    * ``m1``, ``m2`` -- masses [kg], > 0.
    * ``alpha`` -- skew angle between the hinge axes [rad]; ``e0 = cos(alpha) k + sin(alpha) i``.
    * ``g`` -- gravitational acceleration [m/s^2] along ``+j`` (down), >= 0.
    * ``c1``, ``c2`` -- viscous joint damping [N m s/rad], >= 0 (default 0).
    * ``tau1``, ``tau2`` -- constant joint torques [N m] (default 0).

    Optional terms (off by default; the DFKI rig's model, ``docs/guide/model.md``):

    * ``cf1``, ``cf2`` -- Coulomb friction [N m], >= 0 (default 0): the joint torque
      ``-cf_i atan(cfs q_i')``, the lab's smooth sign *without* a factor ``2/pi``, so the torque
      saturates at ``cf_i pi/2`` (its value at ``cfs q' = 1`` is ``cf_i pi/4``).
    * ``cfs`` -- the friction's smoothing rate [s/rad], > 0 (default 100, the lab's).
    * ``Ir`` -- axial inertia of each geared motor's rotor [kg m^2], >= 0 (default 0): a rotor
      fixed to the roof turning ``gr`` times as fast as hinge 1, and one carried by rod 1
      (spinning about hinge 2's axis) turning at ``gr psi'`` relative to rod 1.
    * ``gr`` -- gear ratio, any real number (default 1, direct drive): the rotor's speed relative
      to its carrier over the joint's; negative for a gear that reverses the direction.  The lab's
      equations correspond to ``gr = -6`` for its 6:1 motors (see the guide).

    Rigid-body generalisations (``None`` = the specification's thin rods).  Each entry is a
    number or a symbol name (an identifier, left symbolic; a scalar parameter's name refers
    to that parameter); the word ``"sym"`` makes the whole vector or tensor symbolic
    (``com2`` -> ``r2x, r2y, r2z``; ``inertia2`` -> ``I2xx, I2xy, ...``; ``axis1`` ->
    ``n1x, n1y, n1z``; ``axis2`` -> ``e0x, e0y, e0z``).  Numeric inertia tensors are
    checked; a symbolic axis is taken to be a unit vector (its components must satisfy
    ``|n| = 1``; the derivation uses that relation).

    * ``com1``, ``com2`` -- centres of mass in the body frames [m].  Body 1's frame has
      its origin at the roof hinge, body 2's at the second hinge; both coincide in
      orientation with ``i, j, k`` when the rods hang vertically.  Default: rod
      midpoints ``(0, a/2, 0)`` and ``(0, b/2, 0)``.
    * ``inertia1``, ``inertia2`` -- 3x3 inertia tensors about the centres of mass, body
      frame [kg m^2].  Default: thin rods ``m l^2/12 (E - j j)``.
    * ``axis1`` -- first hinge axis (default ``k``); ``axis2`` -- second hinge axis in the
      vertical configuration (default ``e0(alpha)``; when given, ``alpha`` is not used).
      Any non-zero vectors; they are normalised.
    """

    def __post_init__(self) -> None:
        for name in SCALAR_NAMES:
            value = getattr(self, name)
            if value is None:
                continue
            x = as_real(name, value)
            broken = check_bound(name, x)
            if broken:
                raise ParameterError(broken)
            bound = schema_field(name).bound
            if bound == "positive" and isinstance(x, float) and x < 2.2250738585072014e-308:  # subnormal: 0 to the C code
                raise ParameterError(f"{name} must be a normal number (at least 2.2e-308: the compiled code may flush a "
                                     f"subnormal one to 0, a degenerate model), got {x:g}")
            if bound == "angle" and isinstance(x, float) and abs(x) > MAX_ANGLE:
                raise ParameterError(f"{name} must be an angle of at most {MAX_ANGLE:g} rad in magnitude (its cosine "
                                     f"and sine would be digits of rounding), got {x:g}")
            object.__setattr__(self, name, x)
        for name in COM_NAMES:
            value = getattr(self, name)
            if value is not None:
                object.__setattr__(self, name, as_vector(name, value, tuple(f"{sym_prefix(name)}{x}" for x in "xyz")))
        for name in AXIS_NAMES:
            value = getattr(self, name)
            if value is not None:
                v = as_vector(name, value, tuple(f"{sym_prefix(name)}{x}" for x in "xyz"))
                if is_numeric(v):
                    big = max(abs(x) for x in v)
                    norm = big * math.sqrt(sum((x / big) ** 2 for x in v)) if big > 0 else 0.0
                    if not norm > 1e-12:
                        raise ParameterError(f"{name} must be a non-zero vector, got {v}")
                    v = tuple(x / norm for x in v)
                elif any(x in SCALAR_NAMES for x in v if isinstance(x, str)):
                    raise ParameterError(f"{name}: a symbolic axis component needs its own name, not a parameter's: {v}")
                elif sum(x * x for x in v if not isinstance(x, str)) > 1:
                    raise ParameterError(f"{name}: the numeric components of a unit axis exceed 1, got {v}")
                object.__setattr__(self, name, v)
        if self.axis2 is not None and self.alpha is not None:
            raise ParameterError(
                "alpha sets the default second axis e0 = cos(alpha) k + sin(alpha) i; with axis2 given it would have "
                "no effect: give alpha or axis2, not both"
            )
        for name in INERTIA_NAMES:
            value = getattr(self, name)
            if value is not None:
                mat = as_matrix(name, value, prefix=sym_prefix(name))
                if is_numeric(mat):
                    check_inertia(name, mat)
                object.__setattr__(self, name, mat)

    # -- queries -------------------------------------------------------------------
    @property
    def uses_alpha(self) -> bool:
        """Whether ``alpha`` enters the model (it does unless ``axis2`` is given)."""
        return self.axis2 is None

    @property
    def symbolic_names(self) -> Tuple[str, ...]:
        """Names of the parameters left symbolic that enter the model: scalars, then the
        symbol names used in ``com*``, ``inertia*``, ``axis*``."""
        scalars = tuple(
            n for n in SCALAR_NAMES if getattr(self, n) is None and (n != "alpha" or self.uses_alpha)
            and (n != "cfs" or self.has_friction) and (n != "gr" or self.has_rotor)
        )
        extra = []
        for k in GEOMETRY_NAMES:
            value = getattr(self, k)
            if value is not None:
                extra += [x for x in symbol_names(value) if x not in scalars and x not in extra and x not in SCALAR_NAMES]
        referenced = [n for k in GEOMETRY_NAMES if getattr(self, k) is not None for n in symbol_names(getattr(self, k))]
        scalars_used = tuple(
            n for n in SCALAR_NAMES if getattr(self, n) is None and n in referenced and n not in scalars
        )
        return scalars + scalars_used + tuple(extra)

    @property
    def has_friction(self) -> bool:
        """Whether Coulomb friction enters the model (``cf1`` or ``cf2`` non-zero or symbolic)."""
        return any(self._on(n) for n in names(stem="cf"))

    @property
    def has_rotor(self) -> bool:
        """Whether the rotor inertia enters the model (``Ir`` non-zero or symbolic)."""
        return self.Ir is None or self.Ir != 0

    def _on(self, name: str) -> bool:
        value = getattr(self, name)
        return value is None or value != 0

    @property
    def dissipative(self) -> bool:
        """Whether energy is dissipated: viscous damping or Coulomb friction (non-zero or symbolic)."""
        return bool(self.dissipative_terms)

    @property
    def conservative(self) -> bool:
        """Whether the energy ``E = T + Pi`` is conserved: no viscous damping, no Coulomb friction and
        no constant torques (each zero, not symbolic).  The one rule every analysis that needs a
        conservative model (Poincare sections, the chaos diagram, energy checks, the report's sections)
        asks; the rotors' inertia stores energy but loses none, so it does not count."""
        return not any(self._on(n) for n in NONCONSERVATIVE_NAMES)

    @property
    def nonconservative_terms(self) -> Tuple[str, ...]:
        """The parameters that make the model non-conservative (non-zero or symbolic), in the schema's order."""
        return tuple(n for n in NONCONSERVATIVE_NAMES if self._on(n))

    @property
    def dissipative_terms(self) -> Tuple[str, ...]:
        """The parameters that dissipate energy (viscous damping, Coulomb friction; non-zero or symbolic)."""
        return tuple(n for n in names(role="damping") + names(stem="cf") if self._on(n))

    def _terms_text(self, terms) -> str:
        return ", ".join(f"{n} = {getattr(self, n):g}" if getattr(self, n) is not None else f"{n} symbolic" for n in terms)

    def require_conservative(self, what: str) -> "Parameters":
        """Return self, or raise :class:`~skewpend.errors.ParameterError` (one line naming the terms) when
        the energy ``E = T + Pi`` is not conserved: damping, Coulomb friction or torques."""
        if not self.conservative:
            terms = self.nonconservative_terms
            raise ParameterError(f"{what} needs a conservative model (E = T + Pi constant), but "
                                 f"{self._terms_text(terms)}; set {', '.join(terms)} to 0")
        return self

    def require_lossless(self, what: str) -> "Parameters":
        """Return self, or raise :class:`~skewpend.errors.ParameterError` when energy is dissipated
        (damping or Coulomb friction; constant torques derive from a potential and are allowed)."""
        if self.dissipative:
            terms = self.dissipative_terms
            raise ParameterError(f"{what} needs a conservative model without losses (the energy T + Pi - tau . q decays "
                                 f"otherwise; constant torques are allowed), but {self._terms_text(terms)}; "
                                 f"set {', '.join(terms)} to 0")
        return self

    @property
    def is_numeric(self) -> bool:
        """True when every parameter that enters the model has a value."""
        return not self.symbolic_names

    @property
    def is_thin_rods(self) -> bool:
        """True for the specification's model: thin uniform rods, default hinge axes."""
        return all(getattr(self, n) is None for n in GEOMETRY_NAMES)

    # -- the model's questions, answered as a chain answers them (issue 52: ask the model, never its type) --
    @property
    def n(self) -> int:
        """The number of links (and of coordinates): 2."""
        return 2

    @property
    def coordinates(self) -> Tuple[str, ...]:
        """The coordinates' names, ``phi, psi``."""
        from ..schema import coordinate_names

        return coordinate_names(2)

    @property
    def title(self) -> str:
        """The model in words, ``"the skewed double pendulum"`` (as the chain of two answers)."""
        from ..schema import model_title

        return model_title(2)

    def value(self, name: str):
        """A value by its name (None: symbolic), as a chain answers ``value``: the fields' own names."""
        if name not in NAMES:
            raise ParameterError(unknown_names_message([name]))
        return getattr(self, name)

    def exact_model(self) -> "Parameters":
        """The model the specification's exact derivation prints (the ``exact`` form): itself."""
        return self

    def as_chain(self) -> Chain:
        """The double pendulum as the chain of two (numeric parameters only): link 1 rod ``a`` on the roof
        hinge (axis ``k`` or ``axis1``), link 2 rod ``b`` on the hinge at ``a j`` with the axis
        ``e0 = cos(alpha) k + sin(alpha) i`` (or ``axis2``); one rotor inertia and gear for both joints."""
        params = self.require_numeric("a chain")
        e0 = params.axis2 if params.axis2 is not None else (math.sin(params.alpha), 0.0, math.cos(params.alpha))
        links = []
        for i, (length, axis) in enumerate(((params.a, params.axis1 or (0.0, 0.0, 1.0)), (params.b, e0)), start=1):
            links.append(Link(axis=axis, length=length, mass=getattr(params, f"m{i}"), com=getattr(params, f"com{i}"),
                              inertia=getattr(params, f"inertia{i}"), damping=getattr(params, f"c{i}"),
                              coulomb=getattr(params, f"cf{i}"), torque=getattr(params, f"tau{i}"),
                              rotor=params.Ir, gear=params.gr, index=i))
        return Chain(links=tuple(links), g=params.g, cfs=params.cfs)

    @classmethod
    def from_chain(cls, chain: Chain) -> "Parameters":
        """The chain of two as the double pendulum's parameters (one line if it is not a double pendulum of
        that form: hinge 1 at the roof's origin, hinge 2 on rod 1's end, equal rotors)."""
        chain.require_links((2,), "the double pendulum's parameters")
        one, two = chain.links
        if one.offset != (0.0, 0.0, 0.0) or two.offset != (0.0, one.length, 0.0):
            raise ParameterError("the double pendulum's parameters need hinge 1 at the origin and hinge 2 at the end of "
                                 f"rod 1 (0, a, 0); this chain's offsets are {one.offset} and {two.offset}")
        if (one.rotor, one.gear) != (two.rotor, two.gear):
            raise ParameterError("the double pendulum's parameters have one rotor inertia and gear for both joints; "
                                 f"this chain has ({one.rotor:g}, {one.gear:g}) and ({two.rotor:g}, {two.gear:g})")
        return cls(a=one.length, b=two.length, m1=one.mass, m2=two.mass, g=chain.g, axis1=one.axis,
                   axis2=two.axis, com1=one.com, com2=two.com, inertia1=one.inertia, inertia2=two.inertia,
                   c1=one.damping, c2=two.damping, tau1=one.torque, tau2=two.torque, cf1=one.coulomb,
                   cf2=two.coulomb, cfs=chain.cfs, Ir=one.rotor, gr=one.gear)

    def replace(self, **changes: Any) -> "Parameters":
        """A copy with some fields changed (validated again)."""
        unknown = [k for k in changes if k not in NAMES]
        if unknown:
            raise ParameterError(unknown_names_message(unknown))
        return replace(self, **changes)

    def to_dict(self) -> dict:
        """Plain-data form (JSON/TOML friendly); ``None`` marks a symbolic parameter."""
        d = asdict(self)
        for k, v in d.items():
            if isinstance(v, tuple):
                d[k] = [list(r) if isinstance(r, tuple) else r for r in v]
        return d

    @classmethod
    def from_mapping(cls, data: Mapping[str, Any]) -> "Parameters":
        """Build from a mapping (e.g. a TOML table); unknown keys are an error."""
        unknown = [k for k in data if k not in NAMES]
        if unknown:
            raise ParameterError(unknown_names_message(unknown))
        return cls(**dict(data))

    def require_numeric(self, what: str = "this operation") -> "Parameters":
        """Return self, or raise :class:`NotNumericError` naming the symbolic parameters."""
        from ..errors import NotNumericError

        if not self.is_numeric:
            raise NotNumericError(
                f"{what} needs numeric values; symbolic: {', '.join(self.symbolic_names)}"
            )
        return self


def _build_parameters():
    """:class:`Parameters`: a frozen dataclass whose fields are the schema's, in its order."""
    from dataclasses import make_dataclass

    def annotation(name):
        kind = schema_field(name).kind
        return {"scalar": Scalar, "vector": Optional[Vec3], "inertia": Optional[Mat3]}[kind]

    cls = make_dataclass("Parameters", [(n, annotation(n), field(default=default(n))) for n in NAMES],
                         bases=(_Model,), frozen=True)
    cls.__module__, cls.__doc__ = __name__, _Model.__doc__
    generated = cls.__init__

    def __init__(self, *args, **kwargs):
        unknown = [k for k in kwargs if k not in NAMES]
        if unknown:
            raise ParameterError(unknown_names_message(unknown))
        generated(self, *args, **kwargs)

    __init__.__signature__ = __import__("inspect").signature(generated)
    __init__.__doc__ = generated.__doc__
    cls.__init__ = __init__
    return cls


Parameters = _build_parameters()


#: The checks of one scalar, vector and inertia entry, shared with the chains' links (:mod:`.chain`).


def exact_of_chain(chain: Chain) -> Optional["Parameters"]:
    """The double pendulum's parameters that the specification's derivation prints for a chain of two
    (:meth:`Chain.exact_model`): hinge 1 along ``k`` and hinge 2 in the plane of ``k`` and ``i`` (its tilt the
    run-time ``alpha``), thin rods as the facade's rods; None for other axes or a chain the facade cannot hold."""
    if chain.n != len(LENGTH_NAMES):  # the facade's links
        return None
    one, two = chain.links
    if one.axis != (0.0, 0.0, 1.0) or two.axis[1] != 0.0:
        return None
    rods = {}  # a thin rod's body as the facade's default (the exact form keys general bodies apart)
    for i, link in enumerate(chain.links, start=1):
        if link.com == (0.0, 0.5 * link.length, 0.0):
            rods[f"com{i}"] = None
        if link.inertia == link.rod_inertia:
            rods[f"inertia{i}"] = None
    try:
        return Parameters.from_chain(chain).replace(axis1=None, axis2=None, **rods,
                                                    alpha=math.atan2(two.axis[0], two.axis[2]))
    except ParameterError:
        return None


EXACT_OF[0] = exact_of_chain


def model_from_mapping(data: Mapping[str, Any]):
    """The model a result file stores: a :class:`~skewpend.symbolic.chain.Chain` (its mapping has ``links``) or
    the double pendulum's :class:`Parameters`."""
    return Chain.from_mapping(data) if "links" in data else Parameters.from_mapping(data)


class AnyModel:
    """For readers of results (``results.protocol_fields``): ``from_mapping`` gives the stored model, a chain
    or the double pendulum (:func:`model_from_mapping`)."""

    from_mapping = staticmethod(model_from_mapping)

