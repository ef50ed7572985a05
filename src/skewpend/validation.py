"""Validation against an independent engine: the exported MJCF simulated by MuJoCo."""

from __future__ import annotations

from dataclasses import dataclass
from typing import Dict, Sequence

import numpy as np

from .errors import IntegrationError
from .model import Parameters

__all__ = ["ValidationReport", "compare_with_mujoco"]


@dataclass(frozen=True)
class ValidationReport:
    """skewpend against MuJoCo on the same time grid.

    ``max_abs_diff`` maps ``phi, psi, dphi, dpsi`` to the largest absolute difference
    [rad, rad/s]; ``t``, ``skewpend``, ``mujoco`` hold the compared samples (n,), (n, 4).
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
    """Simulate ``params`` from ``y0`` with skewpend (dop853, rtol = atol = 1e-12) and with
    MuJoCo (exported MJCF, RK4, step ``dt``) and compare on a common grid.

    Both simulate :func:`skewpend.export.mujoco_compatible` ``(params)``: the thin rods get
    the same tiny axial inertia MuJoCo needs.
    """
    from .export import _import_mujoco, mujoco_compatible, mujoco_trajectory
    from .integrate import simulate

    mujoco = _import_mujoco()
    nsteps = int(round(t_end / dt))
    n_seg = _segments(max(nsteps, 1))
    t_mj, y_mj = mujoco_trajectory(params, y0, t_end, dt=dt, n_out=n_seg + 1)
    same = mujoco_compatible(params)
    tr = simulate(same, y0, t_end, dt_out=t_end / n_seg, rtol=1e-12, atol=1e-12)
    if not tr.success:
        raise IntegrationError(f"skewpend: {tr.message}")
    if tr.t.size != t_mj.size or not np.allclose(tr.t, t_mj, rtol=0, atol=1e-9 * max(1.0, t_end)):
        raise IntegrationError("internal error: the sample times of skewpend and MuJoCo differ")
    diff = np.max(np.abs(tr.y - y_mj), axis=0)
    names = ("phi", "psi", "dphi", "dpsi")
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

