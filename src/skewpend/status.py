"""Every status code of skewpend, listed once.

:class:`Status` is the outcome of a computation, carried by every result (``result.status``,
``result.message``, ``result.ok``), in the manner of diffrax's ``RESULTS`` and SciPy's
``MESSAGES``: the codes 0-5 are also the codes the compiled integrators return for one
trajectory (``integrators.c``, ``chaos.c``; the C ``#define``\\ s are generated from this
enum), :attr:`Status.PARTIAL` is the outcome of a grid of many trajectories of which some
failed, :attr:`Status.TRIVIAL` a search for a periodic orbit that found an equilibrium, and
:attr:`Status.NOT_SETTLED` a time average (a Lyapunov exponent) whose convergence check failed.

:class:`CallCode` are the compiled integrators' *control* returns -- "call again" -- that the
resumable C-call driver handles and no result ever carries.
"""

from __future__ import annotations

from enum import IntEnum

__all__ = ["Status", "CallCode"]


class Status(IntEnum):
    """The outcome of a computation; ``int(status)`` is the code, :attr:`message` says it.

    >>> from skewpend import Status
    >>> Status(6)
    <Status.PARTIAL: 6>
    >>> Status.SUCCESS.ok, Status.PARTIAL.ok
    (True, False)
    """

    SUCCESS = 0
    NONFINITE = 1
    STEP_UNDERFLOW = 2
    MAX_STEPS = 3
    NO_CONVERGENCE = 4
    SHORT = 5
    PARTIAL = 6
    TRIVIAL = 7
    NOT_SETTLED = 8

    @property
    def message(self) -> str:
        return _MESSAGES[self]

    @property
    def ok(self) -> bool:
        """True for :attr:`SUCCESS` only."""
        return self is Status.SUCCESS

    @classmethod
    def of(cls, code) -> "Status":
        """The member for ``code`` (an int from C or a file), or a ValueError naming it."""
        try:
            return cls(int(code))
        except (ValueError, TypeError):
            raise ValueError(f"unknown status code {code!r}") from None


_MESSAGES = {
    Status.SUCCESS: "reached t_end",
    Status.NONFINITE: "stopped: the state or its derivative became non-finite",
    Status.STEP_UNDERFLOW: "stopped: step size underflow",
    Status.MAX_STEPS: "stopped: maximum number of steps exceeded",
    Status.NO_CONVERGENCE: "stopped: the implicit stage equations did not converge",
    Status.SHORT: "stopped: t_max reached before the wanted number of crossings",
    Status.PARTIAL: "some of the trajectories failed",
    Status.TRIVIAL: "no periodic orbit: the solution found is an equilibrium (its motion vanishes)",
    Status.NOT_SETTLED: "the estimate has not settled: run longer",
}


class CallCode(IntEnum):
    """Control returns of a resumable call into compiled code (never a result's status)."""

    BUDGET = -1  #: this call's step budget is used up: call again
    BUFFER_FULL = -2  #: the output buffer is full: take the rows and call again
    BAD_ARGUMENTS = -3  #: the arguments were refused (a bug: the callers check them first)
