"""Simulation: compiled integrators over the generated right-hand side.

``simulate`` runs one of three integrators, each compiled end to end with numba
(the whole stepping loop, not a Python loop over a compiled function):

* ``"dop853"`` (default) -- adaptive Dormand-Prince 8(5,3) with 7th-order dense output;
* ``"rk4"`` -- classical fixed-step Runge-Kutta of order 4;
* ``"gauss"`` -- 2-stage Gauss-Legendre collocation (order 4), applied to Hamilton's
  equations in the canonical variables ``(q, p = M(q) q')``: symplectic, so its energy
  error stays bounded over very long conservative runs.

The state carries a fifth component ``W``: the work done by the non-potential forces
``Q = tau - c q'``.  ``E(t) - W(t)`` is then conserved for every model, and the
energy drift every run reports is ``max |E - W - E0|`` relative to the energy scale.
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass, field
from typing import Any, Dict, Optional, Sequence

import numpy as np

from .errors import IntegrationError, ParameterError
from .model import Parameters
from .parsing import initial_state, positive_number

__all__ = ["simulate", "Trajectory", "METHODS", "STATUS_MESSAGES"]

METHODS = ("dop853", "rk4", "gauss")

STATUS_MESSAGES = {
    0: "reached t_end",
    1: "stopped: the state or its derivative became non-finite",
    2: "stopped: step size underflow",
    3: "stopped: maximum number of steps exceeded",
    4: "stopped: the implicit stage equations did not converge",
}


@dataclass(frozen=True)
class Trajectory:
    """The result of :func:`simulate`.

    * ``t`` -- times [s], shape (n,);
    * ``y`` -- states ``(phi, psi, dphi, dpsi)`` [rad, rad/s], shape (n, 4);
    * ``energy`` -- mechanical energy ``T + Pi`` [J] (``Pi = 0`` hanging), shape (n,);
    * ``work`` -- work done by damping and joint torques since ``t[0]`` [J], shape (n,);
    * ``params``, ``method``, ``settings`` (rtol, atol, dt, dt_out, ...) -- how it was made;
    * ``stats`` -- ``nfev``, ``steps`` (accepted), ``rejected``, ``wall_time`` [s] and
      ``includes_jit_load`` (the first run in a process also loads or compiles machine code);
    * ``status`` (0 = success) and ``message``;
    * ``energy_drift`` -- ``max |E - W - E(0)|`` divided by ``max(|E|)`` over the run
      (absolute when that scale is 0).
    """

    t: np.ndarray
    y: np.ndarray
    energy: np.ndarray
    work: np.ndarray
    params: Parameters
    method: str
    settings: Dict[str, Any]
    stats: Dict[str, Any]
    status: int
    message: str
    energy_drift: float
    _kernel: Any = field(default=None, repr=False, compare=False)

    @property
    def success(self) -> bool:
        return self.status == 0

    @property
    def final_state(self) -> np.ndarray:
        return self.y[-1]

    def tips(self) -> np.ndarray:
        """World positions of the rod ends ``(x1, y1, z1, x2, y2, z2)`` [m], shape (n, 6)."""
        from .compiled import parameter_vector

        return self._kernel.tips_many(self.y, parameter_vector(self.params))


def simulate(
    params: Parameters,
    y0: Sequence[float],
    t_end: float,
    *,
    dt_out: Optional[float] = None,
    method: str = "dop853",
    rtol: float = 1e-10,
    atol: float = 1e-10,
    dt: Optional[float] = None,
    max_steps: int = 50_000_000,
    throw: bool = False,
) -> Trajectory:
    """Integrate the equations of motion from ``y0 = (phi, psi, dphi, dpsi)`` over ``[0, t_end]``.

    ``method``: ``"dop853"`` (adaptive; ``rtol``, ``atol``), ``"rk4"`` or ``"gauss"``
    (fixed step ``dt`` [s], default 1e-3).  ``dt_out=None`` returns the integrator's own
    steps; otherwise the states on the grid ``0, dt_out, 2 dt_out, ...`` (dense output for
    dop853; for the fixed-step methods ``dt_out`` must be a multiple of ``dt``).

    A run that stops early (non-finite state, step-size underflow, too many steps) returns
    what it computed up to then, with ``status`` and ``message`` set -- never NaN rows;
    with ``throw=True`` it raises :class:`~skewpend.errors.IntegrationError` instead.
    """
    from .compiled import kernel_module, parameter_vector

    params.require_numeric("simulation")
    y = initial_state(y0)
    t_end = positive_number("t_end", t_end)
    dt_out = positive_number("dt_out", dt_out, allow_none=True)
    if method not in METHODS:
        raise ParameterError(f"unknown method {method!r}; allowed: {', '.join(METHODS)}")
    if dt_out is not None and dt_out > t_end:
        raise ParameterError(f"dt_out ({dt_out:g}) must not exceed t_end ({t_end:g})")
    if isinstance(max_steps, bool) or int(max_steps) != max_steps or max_steps < 1:
        raise ParameterError(f"max_steps must be a positive integer, got {max_steps!r}")
    settings: Dict[str, Any] = {"t_end": t_end, "dt_out": dt_out}
    kernel = kernel_module(params)
    p = parameter_vector(params)
    y5 = np.append(y, 0.0)
    deriv = np.empty(5)
    kernel.rhs(y5, p, deriv)
    if not (np.all(np.isfinite(deriv)) and math.isfinite(kernel.energy(y5, p))):
        raise ParameterError(f"the initial state {y.tolist()} has non-finite energy or acceleration")

    routine = {"dop853": kernel.dop853, "rk4": kernel.rk4, "gauss": kernel.gauss_legendre}[method]
    compiled_before = bool(routine.signatures)
    start = time.perf_counter()
    if method == "dop853":
        rtol = positive_number("rtol", rtol)
        atol = positive_number("atol", atol)
        settings.update(rtol=rtol, atol=atol)
        if dt_out is None:
            t_out = np.empty(0)
        else:
            n = int(math.floor(t_end / dt_out * (1 + 1e-12))) + 1
            t_out = np.arange(n) * dt_out
        ts, ys, status, nfev, nacc, nrej = kernel.dop853(y5, 0.0, t_end, p, rtol, atol, 0.0, int(max_steps), t_out)
        stats = {"nfev": int(nfev), "steps": int(nacc), "rejected": int(nrej)}
    else:
        step = 1e-3 if dt is None else positive_number("dt", dt)
        nsteps = int(round(t_end / step))
        if abs(nsteps * step - t_end) > 1e-9 * t_end:
            raise ParameterError(f"t_end ({t_end:g}) must be a whole number of steps dt ({step:g})")
        stride = 1
        if dt_out is not None:
            stride = int(round(dt_out / step))
            if stride < 1 or abs(stride * step - dt_out) > 1e-9 * dt_out:
                raise ParameterError(f"dt_out ({dt_out:g}) must be a whole multiple of dt ({step:g}) for method {method}")
        if nsteps > max_steps:
            raise ParameterError(f"t_end/dt = {nsteps} steps exceeds max_steps = {max_steps}")
        settings.update(dt=step)
        if method == "rk4":
            ts, ys, status, nfev = kernel.rk4(y5, 0.0, step, nsteps, p, stride)
        else:
            z5 = y5.copy()
            mom = np.empty(2)
            kernel.momenta(y5, p, mom)
            z5[2:4] = mom
            tol, max_iter = 1e-15, 100
            settings.update(implicit_tol=tol, implicit_max_iter=max_iter)
            ts, zs, status, nfev = kernel.gauss_legendre(z5, 0.0, step, nsteps, p, stride, tol, max_iter)
            ys = kernel.speeds_many(zs, p)
        stats = {"nfev": int(nfev), "steps": int(min(nsteps, max(0, round(ts[-1] / step)))), "rejected": 0}
    stats["wall_time"] = time.perf_counter() - start
    # the first call in a process loads (or compiles) the machine code: say so
    stats["includes_jit_load"] = not compiled_before

    ys = np.ascontiguousarray(ys)
    states = ys[:, :4].copy()
    work = ys[:, 4].copy()
    energy = kernel.energies(states, p)
    scale = float(np.max(np.abs(energy))) if energy.size else 0.0
    error = float(np.max(np.abs(energy - work - energy[0]))) if energy.size else 0.0
    drift = error / scale if scale > 0 else error
    status = int(status)
    message = STATUS_MESSAGES.get(status, f"stopped with status {status}")
    if status != 0 and throw:
        raise IntegrationError(f"{method}: {message} at t = {ts[-1]:.6g} s")
    return Trajectory(
        t=np.asarray(ts, dtype=float),
        y=states,
        energy=energy,
        work=work,
        params=params,
        method=method,
        settings=settings,
        stats=stats,
        status=status,
        message=message,
        energy_drift=drift,
        _kernel=kernel,
    )

