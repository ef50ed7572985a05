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
]


class SkewpendError(Exception):
    """Base class of every error skewpend raises on purpose."""


class ParameterError(SkewpendError, ValueError):
    """A model parameter is invalid (wrong sign, not finite, unphysical inertia, ...)."""


class NotNumericError(SkewpendError, ValueError):
    """A numeric operation needs a parameter that was left symbolic."""


class EquilibriumError(SkewpendError, ValueError):
    """The requested linearisation point is not an equilibrium of the model."""


class IntegrationError(SkewpendError, RuntimeError):
    """A simulation stopped early (non-finite state, step size underflow, too many steps)."""
