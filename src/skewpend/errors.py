"""Exceptions raised by skewpend.

Every error a user can cause is a :class:`SkewpendError`; the command-line tool
turns these into one line on stderr and exit status 2.
"""

from __future__ import annotations

__all__ = [
    "SkewpendError",
    "ParameterError",
    "NotNumericError",
    "EquilibriumError",
    "IntegrationError",
    "MissingExtraError",
    "require",
    "EXTRAS",
]


class SkewpendError(Exception):
    """Base class of every error skewpend raises on purpose."""


class ParameterError(SkewpendError, ValueError):
    """A model parameter is invalid (wrong sign, not finite, unphysical inertia, ...).

    ``parameter`` optionally names the parameter at fault (``"max_steps"``), for a front end
    to show as its own spelling (the command line: ``--max-steps``)."""

    def __init__(self, *args, parameter=None) -> None:
        super().__init__(*args)
        self.parameter = parameter


class NotNumericError(SkewpendError, ValueError):
    """A numeric operation needs a parameter that was left symbolic."""


class EquilibriumError(SkewpendError, ValueError):
    """The requested linearisation point is not an equilibrium of the model."""


class IntegrationError(SkewpendError, RuntimeError):
    """A simulation stopped early (non-finite state, step size underflow, too many steps)."""


class MissingExtraError(SkewpendError, ImportError):
    """An optional dependency is not installed; the message names the extra that installs it
    (pyhf's ``ImportBackendError``).  The one exception for every missing extra."""


#: The extras of ``pyproject.toml`` and what each brings, by importable module name.
EXTRAS = {
    "netCDF4": "netcdf", "mujoco": "validate", "zarr": "cluster", "distributed": "cluster", "dask": "cluster",
    "fastapi": "web", "uvicorn": "web", "heyoka": "bench", "anywidget": "notebook", "casadi": None, "pinocchio": "validate", "xarray": None,
}


def require(module: str, what: str):
    """``import module`` for ``what`` ("writing .nc", "a Zarr store", ...), or one
    :class:`MissingExtraError` saying what to install."""
    import importlib

    try:
        return importlib.import_module(module)
    except ImportError:
        extra = EXTRAS.get(module)
        how = f'pip install "skewpend[{extra}]"' if extra else f"pip install {module.lower()}"
        raise MissingExtraError(f"{what} needs {module}, which is not installed: {how}") from None
