"""One resumable loop for every call into the compiled integrators.

Every integrator in ``integrators.c`` and ``chaos.c`` does a bounded amount of work per call and
returns either a :class:`~skewpend.status.Status` code (``>= 0``: done, with that outcome) or a
:class:`~skewpend.status.CallCode` (``< 0``: call again).  :func:`drive` is the one loop around
such a call, for ``simulate``, ``lyapunov``, Poincare sections and the flip-map lanes:

* ``-1`` (:attr:`CallCode.BUDGET`): the step budget of this call is used up -- check Ctrl-C (and
  the ensemble engine's cancel event), report progress, optionally refuse a run whose estimated work
  exceeds its cap (:func:`check_step_estimate`, once, after the first such return), retune the
  budget to about :data:`CHUNK_SECONDS` of work, and call again;
* ``-2`` (:attr:`CallCode.BUFFER_FULL`): the row buffer is full -- take the rows and call again;
* ``-3`` (:attr:`CallCode.BAD_ARGUMENTS`): the arguments were refused -- an internal error, since
  every caller checks them first;
* ``>= 0``: take the last rows and return the :class:`~skewpend.status.Status`.

The loop never changes what the C computes: results are the same bits however the work is split
into calls.
"""

from __future__ import annotations

import math
import time
from typing import Callable, Optional

from ..errors import ParameterError
from ..status import CallCode, Status

__all__ = ["drive", "check_step_estimate", "CHUNK_SECONDS"]

#: Wall time aimed at per call into the compiled code, so Ctrl-C and progress react quickly.
CHUNK_SECONDS = 0.05
#: Bounds of an adapted step budget.
_BUDGET_MIN, _BUDGET_MAX = 100, 50_000_000


def drive(
    call: Callable[[int], int],
    *,
    budget: int,
    take: Optional[Callable[[], None]] = None,
    check: Optional[Callable[[], None]] = None,
    between: Optional[Callable[[], None]] = None,
    progress: Optional[Callable[[], None]] = None,
    estimate: Optional[Callable[[], float]] = None,
    adapt: bool = False,
    name: str = "the compiled integrator",
) -> Status:
    """Call ``call(budget)`` until it returns a :class:`Status` code, and return that status.

    After every call, in this order: ``check()`` (e.g. :meth:`Interrupts.check`: raises on
    Ctrl-C); a ``-3`` is a :class:`RuntimeError` naming ``name``; ``take()`` collects the rows the
    call wrote (also after the last call); then, if the run goes on, ``estimate()`` once, after
    the first :attr:`CallCode.BUDGET` return (it raises to refuse the run), ``progress()`` (also
    after the last call) and ``between()`` (only before calling again: e.g. raise the ensemble
    engine's ``Cancelled`` when its cancel event is set).  With ``adapt`` the budget of each next
    call is scaled so that a call takes about :data:`CHUNK_SECONDS`.
    """
    estimated = estimate is None
    while True:
        started = time.perf_counter()
        code = int(call(budget))
        took = time.perf_counter() - started
        if check is not None:
            check()
        if code == CallCode.BAD_ARGUMENTS:  # pragma: no cover - the callers check the arguments first
            raise RuntimeError(f"internal error: bad arguments to {name}")
        if take is not None:
            take()
        if code >= 0:
            if progress is not None:
                progress()
            return Status.of(code)
        if code not in (CallCode.BUDGET, CallCode.BUFFER_FULL):  # pragma: no cover - the C returns no other code
            raise RuntimeError(f"internal error: {name} returned {code}")
        if not estimated and code == CallCode.BUDGET:
            estimated = True
            estimate()
        if progress is not None:
            progress()
        if between is not None:
            between()
        if adapt and code == CallCode.BUDGET:
            budget = int(min(max(budget * CHUNK_SECONDS / max(took, 1e-6), _BUDGET_MIN), _BUDGET_MAX))


def check_step_estimate(state, t_end: float, max_steps: int, *, advice: str = "shorten t_end, loosen the tolerance "
                        "or raise max_steps") -> float:
    """Refuse (:class:`ParameterError` naming ``max_steps``) a run from ``t = 0`` to ``t_end``
    whose attempted steps, extrapolated from those so far (``state.naccept + state.nreject``
    over ``state.t``), exceed ``max_steps``; else return the estimate."""
    attempted = int(state.naccept) + int(state.nreject)
    reached = float(state.t)
    estimate = attempted * t_end / reached if reached > 0 else math.inf
    if estimate > max_steps:
        about = f"about {estimate:.2g}" if math.isfinite(estimate) else "more than 1e308"
        raise ParameterError(
            f"t_end = {t_end:g} s needs {about} steps at this tolerance (from the first {attempted} steps, which "
            f"reached t = {reached:.3g} s), more than max_steps = {max_steps}; {advice}",
            parameter="max_steps",
        )
    return estimate
