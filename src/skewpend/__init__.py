"""skewpend: the double pendulum with skewed hinge axes.

Derive its equations of motion by the specification's method (rotation tensors,
Lagrange's equations), for any skew angle ``alpha`` and general rigid bodies.

Heavy parts (SymPy) are imported on first use, so ``import skewpend`` is cheap.
"""

from __future__ import annotations

from importlib import import_module
from typing import TYPE_CHECKING, Any

from .errors import EquilibriumError, IntegrationError, NotNumericError, ParameterError, SkewpendError
from .model import Parameters

__version__ = "0.1.0"

_LAZY = {
    "derive": "derivation",
    "EquationsOfMotion": "derivation",
    "LinearEquations": "derivation",
    "simulate": "integrate",
    "Trajectory": "integrate",
    "normal_modes": "modes",
    "Modes": "modes",
    "sweep": "modes",
    "characteristic_equation": "modes",
}

__all__ = [
    "Parameters",
    "derive",
    "EquationsOfMotion",
    "LinearEquations",
    "simulate",
    "Trajectory",
    "normal_modes",
    "Modes",
    "sweep",
    "characteristic_equation",
    "SkewpendError",
    "ParameterError",
    "NotNumericError",
    "EquilibriumError",
    "IntegrationError",
    "__version__",
]

if TYPE_CHECKING:  # pragma: no cover
    from .derivation import EquationsOfMotion, LinearEquations, derive
    from .integrate import Trajectory, simulate
    from .modes import Modes, characteristic_equation, normal_modes, sweep


#: Submodules reachable as attributes after a plain ``import skewpend`` (imported on first use).
_SUBMODULES = {
    "derivation", "kinematics", "render", "codegen", "kernelgen", "compiled", "integrate", "io", "export",
    "validation", "modes", "views", "parsing", "progress", "model", "errors",
}


def __getattr__(name: str) -> Any:
    if name in _SUBMODULES:
        return import_module(f".{name}", __name__)
    if name in _LAZY:
        value = getattr(import_module(f".{_LAZY[name]}", __name__), name)
        globals()[name] = value
        return value
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")


def __dir__() -> list:
    return sorted(set(globals()) | set(__all__))
