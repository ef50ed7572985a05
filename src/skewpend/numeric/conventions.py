"""Conventions shared by every generated numeric routine: the order of the state and of the
parameter array, and the split of a model into geometry (baked into code) and scalars
(run-time inputs)."""

from __future__ import annotations

from typing import Tuple

from ..symbolic.model import SCALAR_NAMES, Parameters

__all__ = ["PARAMETER_ORDER", "STATE_ORDER", "GEOMETRY", "geometry_of", "parameter_vector"]

#: Order of the parameter array ``p`` of every generated routine.
PARAMETER_ORDER: Tuple[str, ...] = SCALAR_NAMES
#: Order of the state ``y``.
STATE_ORDER: Tuple[str, ...] = ("phi", "psi", "dphi", "dpsi")
#: The bodies and axes: baked into generated code as numbers (or symbols).
GEOMETRY: Tuple[str, ...] = ("com1", "com2", "inertia1", "inertia2", "axis1", "axis2")


def geometry_of(params: Parameters) -> Parameters:
    """The same bodies and axes with every scalar parameter symbolic (a runtime input)."""
    return Parameters(**{k: getattr(params, k) for k in GEOMETRY}, **{k: None for k in SCALAR_NAMES})


def parameter_vector(params: Parameters):
    """The float64 parameter array ``p`` in :data:`PARAMETER_ORDER` (``alpha`` = 0 when unused)."""
    import numpy as np

    params.require_numeric("numeric evaluation")
    return np.array(
        [0.0 if (n == "alpha" and not params.uses_alpha) else float(getattr(params, n)) for n in PARAMETER_ORDER]
    )
