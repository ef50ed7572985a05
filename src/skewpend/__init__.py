"""skewpend: the double pendulum with skewed hinge axes.

Derive its equations of motion by the specification's method (rotation tensors,
Lagrange's equations), for any skew angle ``alpha`` and general rigid bodies.

Heavy parts (SymPy) are imported on first use, so ``import skewpend`` is cheap.
"""

from __future__ import annotations

from importlib import import_module
from typing import TYPE_CHECKING, Any

from .errors import EquilibriumError, IntegrationError, NotNumericError, ParameterError, SkewpendError
from .status import Status
from .symbolic.model import Parameters

__version__ = "0.1.0"

_LAZY = {
    "derive": "symbolic.derivation",
    "Chain": "symbolic.chain",
    "Link": "symbolic.chain",
    "EquationsOfMotion": "symbolic.derivation",
    "LinearEquations": "symbolic.derivation",
    "SYMBOLS": "symbolic.symbols",
    "simulate": "numeric.simulation",
    "Trajectory": "numeric.simulation",
    "open_trajectory": "numeric.simulation",
    "reference_parameters": "config",
    "reference_state": "config",
    "normal_modes": "analysis.modes",
    "Modes": "analysis.modes",
    "sweep": "analysis.modes",
    "characteristic_equation": "analysis.modes",
    "equilibria": "analysis.equilibria",
    "Equilibria": "analysis.equilibria",
    "Equilibrium": "analysis.equilibria",
    "periodic_orbit": "analysis.orbits",
    "PeriodicOrbit": "analysis.orbits",
    "nnm": "analysis.orbits",
    "NNMFamily": "analysis.orbits",
    "backbones": "analysis.orbits",
    "nnm_alpha": "analysis.orbits",
    "Controller": "numeric.control",
    "linearization": "analysis.control",
    "controllability": "analysis.control",
    "lqr": "analysis.control",
    "LQR": "analysis.control",
    "swingup": "analysis.control",
    "SwingUp": "analysis.control",
    "MPC": "analysis.mpc",
    "MPCSettings": "analysis.mpc",
    "mpc_swingup": "analysis.mpc",
    "region_of_attraction": "analysis.roa",
    "RegionOfAttraction": "analysis.roa",
    "open_region_of_attraction": "analysis.roa",
    "flip_map": "analysis.flipmap",
    "FlipMap": "analysis.flipmap",
    "open_flip_map": "analysis.flipmap",
    "lyapunov": "analysis.lyapunov",
    "LyapunovSpectrum": "analysis.lyapunov",
    "lyapunov_map": "analysis.lyapunov",
    "LyapunovMap": "analysis.lyapunov",
    "open_lyapunov_map": "analysis.lyapunov",
    "run_grid": "numeric.grid",
    "GridJob": "numeric.grid",
    "poincare": "analysis.poincare",
    "PoincareSection": "analysis.poincare",
    "chaos_diagram": "analysis.chaos",
    "ChaosDiagram": "analysis.chaos",
    "open_chaos_diagram": "analysis.chaos",
    "open_result": "analysis.readback",
    "Measurements": "analysis.measurements",
    "identify": "analysis.identify",
    "Identification": "analysis.identify",
    "Convention": "analysis.measurements",
    "example_data": "datasets",
    "example_run_file": "datasets",
    "read_mjcf": "interop.importer",
    "read_urdf": "interop.importer",
    "widget": "views.widget",
    "PendulumWidget": "views.widget",
}

__all__ = [
    "Parameters",
    "Chain",
    "Link",
    "example_data",
    "example_run_file",
    "derive",
    "SYMBOLS",
    "EquationsOfMotion",
    "LinearEquations",
    "simulate",
    "Trajectory",
    "open_trajectory",
    "reference_parameters",
    "reference_state",
    "normal_modes",
    "Modes",
    "sweep",
    "characteristic_equation",
    "equilibria",
    "Equilibria",
    "Equilibrium",
    "periodic_orbit",
    "PeriodicOrbit",
    "nnm",
    "NNMFamily",
    "backbones",
    "nnm_alpha",
    "Controller",
    "linearization",
    "controllability",
    "lqr",
    "LQR",
    "swingup",
    "SwingUp",
    "MPC",
    "MPCSettings",
    "mpc_swingup",
    "region_of_attraction",
    "RegionOfAttraction",
    "open_region_of_attraction",
    "flip_map",
    "FlipMap",
    "open_flip_map",
    "lyapunov",
    "LyapunovSpectrum",
    "lyapunov_map",
    "LyapunovMap",
    "open_lyapunov_map",
    "run_grid",
    "GridJob",
    "Status",
    "poincare",
    "PoincareSection",
    "chaos_diagram",
    "ChaosDiagram",
    "open_chaos_diagram",
    "open_result",
    "Measurements",
    "Convention",
    "identify",
    "Identification",
    "read_mjcf",
    "read_urdf",
    "widget",
    "PendulumWidget",
    "SkewpendError",
    "ParameterError",
    "NotNumericError",
    "EquilibriumError",
    "IntegrationError",
    "__version__",
]

if TYPE_CHECKING:  # pragma: no cover
    from .symbolic.derivation import EquationsOfMotion, LinearEquations, derive
    from .symbolic.symbols import SYMBOLS
    from .numeric.simulation import Trajectory, open_trajectory, simulate
    from .config import reference_parameters, reference_state
    from .analysis.flipmap import FlipMap, flip_map, open_flip_map
    from .analysis.modes import Modes, characteristic_equation, normal_modes, sweep
    from .analysis.equilibria import Equilibria, Equilibrium, equilibria
    from .numeric.control import Controller
    from .analysis.control import LQR, SwingUp, controllability, linearization, lqr, swingup
    from .analysis.roa import RegionOfAttraction, open_region_of_attraction, region_of_attraction
    from .analysis.orbits import NNMFamily, PeriodicOrbit, backbones, nnm, nnm_alpha, periodic_orbit
    from .analysis.lyapunov import LyapunovMap, LyapunovSpectrum, lyapunov, lyapunov_map, open_lyapunov_map
    from .numeric.grid import GridJob, run_grid
    from .analysis.poincare import PoincareSection, poincare
    from .analysis.chaos import ChaosDiagram, chaos_diagram, open_chaos_diagram
    from .analysis.readback import open_result
    from .analysis.measurements import Convention, Measurements
    from .analysis.identify import Identification, identify
    from .interop.importer import read_mjcf, read_urdf
    from .views.widget import PendulumWidget, widget
    from .datasets import example_data, example_run_file


#: Subpackages (the layers) and modules reachable as attributes after a plain ``import skewpend``
#: (imported on first use); a module's short name reaches it in its layer (``skewpend.modes`` is
#: ``skewpend.analysis.modes``).
_SUBMODULES = {
    "symbolic": "symbolic", "numeric": "numeric", "analysis": "analysis", "interop": "interop", "views": "views",
    "model": "symbolic.model", "kinematics": "symbolic.kinematics", "derivation": "symbolic.derivation",
    "render": "symbolic.render", "symbols": "symbolic.symbols", "codegen": "numeric.codegen",
    "kernels": "numeric.kernels", "simulation": "numeric.simulation", "modes": "analysis.modes",
    "export": "interop.export", "validation": "interop.validation", "figures": "views.figures",
    "flipmap": "analysis.flipmap", "chaos": "analysis.chaos", "ensemble": "numeric.ensemble", "store": "numeric.store",
    "grid": "numeric.grid", "results": "results", "status": "status", "checks": "checks",
    "io": "io", "parsing": "parsing", "progress": "progress", "interrupts": "interrupts", "errors": "errors", "cli": "cli",
    "datasets": "datasets",
}


def __getattr__(name: str) -> Any:
    if name in _SUBMODULES:
        return import_module(f".{_SUBMODULES[name]}", __name__)
    if name in _LAZY:
        value = getattr(import_module(f".{_LAZY[name]}", __name__), name)
        globals()[name] = value
        return value
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")


def __dir__() -> list:
    return sorted(set(globals()) | set(__all__))
