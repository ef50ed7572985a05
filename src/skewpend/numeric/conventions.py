"""Conventions shared by every generated numeric routine: the order of the state and of the
parameter array, and the split of a model into geometry (baked into code) and scalars
(run-time inputs; the optional friction and rotor terms are in the code only when a model has
them, see :func:`geometry_of`)."""

from __future__ import annotations

from typing import Tuple

from ..schema import FRICTION_NAMES, GEOMETRY_NAMES, ROTOR_NAMES, SCALAR_NAMES
from ..symbolic.model import Parameters

__all__ = ["METHODS", "ADAPTIVE", "PARAMETER_ORDER", "STATE_ORDER", "GEOMETRY", "geometry_of", "optional_terms", "parameter_vector"]

#: The integrators of ``simulate`` (here, where the command line's --help reads them without NumPy).
METHODS: Tuple[str, ...] = ("dop853", "rk4", "gauss", "taylor")
#: The methods that choose their own steps (rtol, atol); the others take a fixed step dt.
ADAPTIVE: Tuple[str, ...] = ("dop853", "taylor")
#: Order of the parameter array ``p`` of every generated routine.
PARAMETER_ORDER: Tuple[str, ...] = SCALAR_NAMES
#: Order of the state ``y``.
STATE_ORDER: Tuple[str, ...] = ("phi", "psi", "dphi", "dpsi")
#: The bodies and axes: baked into generated code as numbers (or symbols).
GEOMETRY: Tuple[str, ...] = GEOMETRY_NAMES


def optional_terms(params: Parameters) -> Tuple[bool, bool]:
    """Which optional terms the compiled code of ``params`` holds: (Coulomb friction, rotor inertia)."""
    return params.has_friction, params.has_rotor


def geometry_of(params: Parameters) -> Parameters:
    """The same bodies and axes with every scalar parameter symbolic (a runtime input).

    The optional terms are structural: Coulomb friction (``cf1, cf2, cfs``) and the rotor inertia
    (``Ir, gr``) are runtime inputs when ``params`` has them (non-zero or symbolic), and are left
    out of the code otherwise -- so a model without them runs exactly today's code (bit for bit),
    and its ``p`` entries for them are not read.  Code for a model with friction reads any ``cf``,
    0 included."""
    friction, rotor = optional_terms(params)
    off = {n: getattr(Parameters(), n) for n in FRICTION_NAMES * (not friction) + ROTOR_NAMES * (not rotor)}
    scalars = {k: None for k in SCALAR_NAMES if k not in off}
    return Parameters(**{k: getattr(params, k) for k in GEOMETRY}, **scalars, **off)


def parameter_vector(params: Parameters):
    """The float64 parameter array ``p`` in :data:`PARAMETER_ORDER` (``alpha`` = 0 when unused)."""
    import numpy as np

    params.require_numeric("numeric evaluation")
    return np.array(
        [0.0 if (n == "alpha" and not params.uses_alpha) else float(getattr(params, n)) for n in PARAMETER_ORDER]
    )
