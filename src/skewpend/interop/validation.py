"""Validation against an independent engine: the exported MJCF simulated by MuJoCo."""

from __future__ import annotations

from dataclasses import dataclass
from typing import Dict, Sequence

import numpy as np

from ..errors import IntegrationError, ParameterError
from ..symbolic.model import Parameters
from ..parsing import initial_state

__all__ = ["ValidationReport", "compare_with_mujoco"]


@dataclass(frozen=True)
class ValidationReport:
    """skewpend against MuJoCo on the same time grid.

    ``max_abs_diff`` maps ``phi, psi, dphi, dpsi`` (a chain's ``q1 … qn, dq1 … dqn``) to the
    largest absolute difference [rad, rad/s]; ``t``, ``skewpend``, ``mujoco`` hold the compared
    samples (k,), (k, 4) (a chain's (k, 2 n)).
    """

    t: np.ndarray
    skewpend: np.ndarray
    mujoco: np.ndarray
    max_abs_diff: Dict[str, float]
    dt: float
    t_end: float
    samples: int
    energy_drift: float
    mujoco_version: str

    @property
    def max_difference(self) -> float:
        return max(self.max_abs_diff.values())


def _segments(nsteps: int, most: int = 200) -> int:
    """The largest divisor of ``nsteps`` not above ``most`` (so sample times coincide exactly)."""
    return max(d for d in range(1, min(most, nsteps) + 1) if nsteps % d == 0)


def compare_with_mujoco(params: Parameters, y0: Sequence[float], t_end: float = 2.0, *, dt: float = 1e-4) -> ValidationReport:
    """Simulate ``params`` (or a chain of links) from ``y0`` with skewpend (dop853, rtol = atol = 1e-12) and with
    MuJoCo (exported MJCF, RK4, step ``dt``) and compare on a common grid.

    Both simulate :func:`skewpend.export.mujoco_compatible` ``(params)``: the thin rods get the same tiny
    axial inertia MuJoCo needs.

    Everything is checked before any work starts: ``t_end`` and ``dt`` must be positive and
    finite, ``t_end`` a whole number of steps ``dt``, and ``t_end / dt`` at most
    :data:`skewpend.export.MAX_MUJOCO_STEPS` (1e8); otherwise
    :class:`~skewpend.errors.ParameterError`.  MuJoCo is stepped in bounded chunks, so
    Ctrl-C (``KeyboardInterrupt``) stops a long comparison promptly.
    """
    from .export import import_mujoco, mujoco_compatible, mujoco_steps, mujoco_trajectory, numeric_chain
    from ..numeric.simulation import simulate
    from ..schema import state_coordinates

    numeric_chain(params, "validation")  # symbolic values are refused first
    y0 = initial_state(y0, params.coordinates)
    for name, value in (("t_end (--t-end)", t_end), ("dt (--dt)", dt)):
        if value is None:
            raise ParameterError(f"{name} must be a positive number of seconds, not symbolic")
    nsteps = mujoco_steps(t_end, dt)
    mujoco = import_mujoco()
    n_seg = _segments(max(nsteps, 1))
    t_mj, y_mj = mujoco_trajectory(params, y0, t_end, dt=dt, n_out=n_seg + 1)
    same = mujoco_compatible(params)
    tr = simulate(same, y0, t_end, dt_out=t_end / n_seg, method="dop853", rtol=1e-12, atol=1e-12)  # as documented
    if not tr.success:
        raise IntegrationError(f"skewpend: {tr.message}")
    if tr.t.size != t_mj.size or not np.allclose(tr.t, t_mj, rtol=0, atol=1e-9 * max(1.0, t_end)):
        raise IntegrationError("internal error: the sample times of skewpend and MuJoCo differ")
    diff = np.max(np.abs(tr.y - y_mj), axis=0)
    names = state_coordinates(params.n)
    return ValidationReport(
        t=tr.t,
        skewpend=tr.y,
        mujoco=y_mj,
        max_abs_diff={n: float(d) for n, d in zip(names, diff)},
        dt=float(dt),
        t_end=float(t_end),
        samples=int(tr.t.size),
        energy_drift=tr.energy_drift,
        mujoco_version=str(getattr(mujoco, "__version__", "?")),
    )

