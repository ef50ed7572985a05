"""The flow of the equations of motion and its derivative (the state-transition matrix).

:func:`flow` integrates the state ``y = (phi, psi, phi', psi')`` together with the variational
equations ``V' = J(y) V`` from ``V(0) = I`` (``J`` the Jacobian generated from the derivation),
with adaptive DOP853 and error control on every component -- ``sp_flow`` in ``chaos.c``, on the
same DOP853 core as the Lyapunov exponents.  Over one period of a periodic orbit ``V(T)`` is its
monodromy matrix, whose eigenvalues are the Floquet multipliers.  Like every compiled integrator it
works in bounded calls (:func:`skewpend.numeric.driver.drive`): Ctrl-C is honoured between them.
"""

from __future__ import annotations

import ctypes
from dataclasses import dataclass
from typing import Sequence

import numpy as np

from ..status import Status

__all__ = ["Flow", "flow", "FlowIntegrator"]

_BUDGET = 20_000


@dataclass(frozen=True)
class Flow:
    """``y`` (4,) (a chain's: (2 n,)): the state at ``t``; ``stm`` (4, 4): ``d y(t) / d y(0)``; ``status``; ``steps``
    (accepted) and ``rejected``; ``evaluations`` of the right-hand side."""

    t: float
    y: np.ndarray
    stm: np.ndarray
    status: Status
    steps: int
    rejected: int
    evaluations: int


class FlowIntegrator:
    """One model's compiled flow, for many calls (the kernel loaded once): the double pendulum's or a
    chain's (:class:`~skewpend.Chain`)."""

    def __init__(self, params, *, rtol: float = 1e-11, atol: float = 1e-11, max_steps: int = 10_000_000):
        from .kernels import model_kernel, model_vector

        self.kernel = model_kernel(params, chaos=True)
        self.p = model_vector(params)
        self.rtol, self.atol, self.max_steps = float(rtol), float(atol), int(max_steps)

    def __call__(self, y0: Sequence[float], t: float, *, check=None) -> Flow:
        from .driver import drive

        n2 = 2 * self.kernel.nq
        state = self.kernel.LyapState()
        state.k, state.every, state.t0 = n2, 1.0, 0.0
        # the state, then V(0) = I (column j at n2 + n2 j)
        state.y[:n2 * (n2 + 1)] = [*np.asarray(y0, dtype=float)[:n2].tolist(), *np.eye(n2).ravel().tolist()]
        dp = ctypes.POINTER(ctypes.c_double)
        args = (ctypes.byref(state), self.p.ctypes.data_as(dp), float(t), self.rtol, self.atol, self.max_steps)
        status = drive(lambda budget: self.kernel.lib.sp_flow(*args, budget), budget=_BUDGET, check=check,
                       name="sp_flow")
        values = np.array(state.y[:n2 * (n2 + 1)])
        return Flow(t=float(state.t), y=values[:n2].copy(), stm=values[n2:].reshape(n2, n2).T.copy(), status=status,
                    steps=int(state.naccept), rejected=int(state.nreject), evaluations=int(state.nfev))


def flow(params, y0: Sequence[float], t: float, *, rtol: float = 1e-11, atol: float = 1e-11,
         max_steps: int = 10_000_000) -> Flow:
    """The state at ``t`` from ``y0`` (at time 0) and the state-transition matrix ``d y(t) / d y0``."""
    return FlowIntegrator(params, rtol=rtol, atol=atol, max_steps=max_steps)(y0, t)
