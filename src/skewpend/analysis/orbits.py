"""Periodic orbits, their stability, and the nonlinear normal modes as the energy grows.

**A periodic orbit** (:func:`periodic_orbit`) is found by single shooting: the unknowns are the
start ``x0 = (phi, psi, phi', psi')`` and the period ``T``; the equations are

* ``phi_T(x0) - x0 = s``: the orbit closes after ``T``, up to ``s = 2 pi (r1, r2, 0, 0)`` for a
  rotation in which the angles advance by whole turns (``rotation = (r1, r2)``);
* ``<f(x_ref), x0 - x_ref> = 0``: the phase condition (the start lies on the plane through the
  reference point across the flow, so the orbit is not slid along itself);
* ``H(x0) = E``: the energy ``H = T + Pi - tau . q``, for the conservative model.

Six equations in five unknowns, consistent at a solution (the energy is conserved); each
Gauss-Newton step solves them in the least-squares sense with the Jacobian from the variational
equations (``d phi_T / d x0`` is the state-transition matrix of :mod:`skewpend.numeric.variational`,
``d phi_T / d T = f(phi_T(x0))``).  Over the converged period the state-transition matrix is the
monodromy matrix; its eigenvalues are the Floquet multipliers.  For a conservative model with two
degrees of freedom they are ``{1, 1, mu, 1/mu}``; ``sigma = trace - 2 = mu + 1/mu`` decides the
stability: ``|sigma| < 2`` stable (a pair on the unit circle), ``sigma > 2`` unstable through +1,
``sigma < -2`` unstable through -1 (period doubling).  Newton's failure is a status, never an orbit.

**Nonlinear normal modes** (:func:`nnm`) continue the family of periodic orbits that each linear
mode starts, by pseudo-arclength continuation in ``(x0, T, E)`` (a step along the secant, then the
corrector with the arclength condition added), the step adapted to how fast the corrector
converges, up to an energy limit -- by default the lowest energy at which a joint can flip (the
minimum of ``V`` on the boundary of the square ``|phi|, |psi| <= pi``).  Along the family it
reports folds (the energy turns back), stability changes (``sigma`` crossing +2: a multiplier
leaving the unit circle through +1, a branch point; crossing -2: through -1, a period doubling).
:func:`backbones` computes both families and the internal resonances between them (one family's
frequency crossing a small rational multiple of the other's at the same energy).
"""

from __future__ import annotations

import contextvars
import math
import numbers
from dataclasses import dataclass, field
from fractions import Fraction
from typing import Callable, ClassVar, Dict, List, Optional, Sequence, Tuple

import numpy as np

from ..checks import angle, numeric_model, numeric_params, positive, progress_callable, tolerances, whole
from ..errors import EquilibriumError, IntegrationError, ParameterError, SkewpendError
from ..progress import detail as _detail
from ..results import DatasetSpec, Result, agree, netcdf_reader, protocol_fields
from ..schema import count_text, state_coordinates, state_text
from ..status import Status
from ..symbolic.model import AnyModel
from ..symbolic.model import Parameters

__all__ = ["PeriodicOrbit", "periodic_orbit", "NNMFamily", "nnm", "Backbones", "backbones", "flip_energy",
           "BranchEvent", "AlphaFamily", "nnm_alpha"]

#: Newton tolerance on the scaled residual, and the most iterations.
NEWTON_TOL = 1e-10
NEWTON_MAX = 25
#: The variational integration's tolerances (the monodromy matrix is as accurate as the orbit).
ORBIT_TOL = 1e-12
#: ``|sigma| - 2`` beyond this counts as unstable (the multipliers' accuracy, from ORBIT_TOL).
STABILITY_MARGIN = 1e-6
#: The Newton tolerance a caller may ask for: from machine precision to 1e-6.
TOL_RANGE = (1e-15, 1e-6)
#: The most Newton iterations a caller may ask for.
MAX_ITERATIONS_LIMIT = 1000
#: The steps one shooting (one flow over a period, with its state-transition matrix) may take:
#: about 5 s of compiled work; a period that needs more is refused before any work, from a trial
#: flow of the orbit's own start (:func:`skewpend.numeric.grid.probe_durations`).
ORBIT_MAX_STEPS = 1_000_000
#: The most whole turns per period a rotating orbit may make (the closure is tested to the Newton
#: tolerance in angles that advance by 2 pi r: beyond this their doubles keep too few digits).
ROTATION_LIMIT = 1000
#: An orbit whose motion is smaller than this [rad] (or 100 x the Newton tolerance) is an
#: equilibrium: the amplitude ``|q'| / w + |q''| / w^2`` at its start (``w = 2 pi / T``), in
#: the angle unit of the shooting (1 rad).
TRIVIAL_AMPLITUDE = 1e-6


#: The family :func:`backbones` is following (``"mode 2 of 4: "``), said before each sub-step.
_FAMILY: "contextvars.ContextVar[str]" = contextvars.ContextVar("skewpend_nnm_family", default="")


def _say(text: str) -> None:
    """The sub-step on the running command's live line (:func:`skewpend.progress.detail`), after its family."""
    _detail(_FAMILY.get() + text)


def _torques(params) -> np.ndarray:
    """The model's constant joint torques, a coordinate each."""
    return np.array([link.torque for link in params.as_chain().links], dtype=float)


def energy_function(params: Parameters) -> Callable[[np.ndarray], np.ndarray]:
    """``H(y) = T + Pi - tau . q`` of states ``y`` (n, 4), the energy an orbit keeps, from the
    model's kernel."""
    from ..numeric.kernels import model_kernel, model_vector

    kernel = model_kernel(params)
    p = model_vector(params)
    tau = _torques(params)

    def H(y: np.ndarray) -> np.ndarray:
        y = np.atleast_2d(np.asarray(y, dtype=float))
        return kernel.energies(y, p) - y[:, :tau.size] @ tau

    return H


def _orbit_energy_check(path, params: Parameters, states: np.ndarray, energies, what: str) -> None:
    """Refuse a file whose stored orbit energies are not ``H`` of its stored starts."""
    ok = np.all(np.isfinite(states), axis=1) & np.isfinite(energies)
    if ok.any():
        agree(path, f"{what} energy", np.asarray(energies)[ok], energy_function(params)(states[ok]))


class _Model:
    """What shooting needs of one model: the flow with its derivative, the vector field, the energy."""

    def __init__(self, params, rtol: float, atol: float):
        from ..numeric.kernels import model_kernel, model_vector
        from ..numeric.variational import FlowIntegrator

        self.params = params
        self.flow = FlowIntegrator(params, rtol=rtol, atol=atol, max_steps=ORBIT_MAX_STEPS)
        self.kernel = model_kernel(params)
        self.p = model_vector(params)
        self.nq = self.kernel.nq  # 2, or a chain's links
        self.tau = _torques(params)
        self.calls = 0
        self.steps = 0

    def field(self, y: np.ndarray) -> np.ndarray:
        n2 = 2 * self.nq
        out = np.empty(n2 + 1)
        self.kernel.rhs(np.append(y, 0.0), self.p, out)
        return out[:n2]

    def energy(self, y: np.ndarray) -> float:
        return self.kernel.energy(np.append(y, 0.0), self.p) - float(self.tau @ y[:self.nq])

    def energy_gradient(self, y: np.ndarray) -> np.ndarray:
        n2 = 2 * self.nq
        g = np.empty(n2)
        for i in range(n2):  # central differences of the energy
            h = 1e-6 * max(1.0, abs(y[i]))
            e = np.zeros(n2)
            e[i] = h
            g[i] = (self.energy(y + e) - self.energy(y - e)) / (2 * h)
        return g

    def amplitude(self, y: np.ndarray, T: float) -> float:
        """How far the motion through ``y`` goes in a period ``T`` [rad], from its velocity and
        acceleration there: ``|q'| / w + |q''| / w^2``, ``w = 2 pi / T`` (0 at an equilibrium)."""
        f = self.field(y)
        w = 2 * math.pi / T
        return float(np.max(np.abs(f[:self.nq])) / w + np.max(np.abs(f[self.nq:])) / w ** 2)

    def check_work(self, x0: np.ndarray, T: float) -> float:
        """Refuse, before any work, a shooting over the period ``T`` that could not finish within
        :data:`ORBIT_MAX_STEPS` steps, estimated from a trial flow from ``x0`` (the grid's probe:
        :func:`~skewpend.numeric.grid.probe_durations`, :func:`~skewpend.numeric.grid.steps_per_second`).
        Returns the estimated steps of one shooting."""
        from ..numeric.grid import PROBE_STEPS, probe_durations, steps_per_second
        from ..numeric.variational import FlowIntegrator

        trial = FlowIntegrator(self.params, rtol=self.flow.rtol, atol=self.flow.atol, max_steps=PROBE_STEPS)
        rate, ok = math.inf, False
        for t in probe_durations(T, self.params):  # a trial that fails is tried over a shorter time
            fl = trial(x0, t)
            rate = steps_per_second(np.array([fl.steps + fl.rejected]), np.array([t]))
            ok = fl.status == Status.SUCCESS
            if ok or rate * T > ORBIT_MAX_STEPS:  # a failed trial's rate is a lower bound: enough to refuse
                break
        need = rate * T
        if not need <= ORBIT_MAX_STEPS:
            about = f"{'about' if ok else 'at least'} {need:.3g}" if math.isfinite(need) else "more than 1e308"
            how = f"~{rate:.3g} steps per simulated second" if math.isfinite(rate) else "a trial flow could not advance"
            raise ParameterError(
                f"period must be short enough to shoot: {T:g} s needs {about} steps per shooting from this start ({how} at rtol={self.flow.rtol:g}, "
                f"atol={self.flow.atol:g}), more than the {ORBIT_MAX_STEPS:g} one shooting may take; a periodic "
                "orbit's period is a few swings: give a shorter period or a slower start")
        return need

    def shoot(self, x0: np.ndarray, T: float, check=None):
        if not (T > 0) or not math.isfinite(T):
            return None
        fl = self.flow(x0, T, check=check)
        self.calls += 1
        self.steps += fl.steps
        if fl.status != Status.SUCCESS or not np.all(np.isfinite(fl.stm)):
            return None
        return fl


@dataclass
class _Scales:
    """Units of the unknowns for the least-squares problem: angles, speeds, period, energy."""

    angle: float
    speed: float
    period: float
    energy: float
    nq: int = 2

    def vector(self) -> np.ndarray:
        return np.array([self.angle] * self.nq + [self.speed] * self.nq + [self.period, self.energy])


def _newton(model: _Model, x0: np.ndarray, T: float, E: float, shift: np.ndarray, ref: np.ndarray, scales: _Scales,
            arclength: Optional[Tuple[np.ndarray, np.ndarray]] = None, free_energy: bool = False, check=None,
            tol: float = NEWTON_TOL, max_iterations: int = NEWTON_MAX, progress=None):
    """Gauss-Newton on the shooting equations.  Unknowns ``(x0, T)`` and, with ``free_energy``,
    ``E``; ``arclength = (u_pred, tangent)`` in scaled unknowns adds the pseudo-arclength row.
    Returns ``(x0, T, E, flow, iterations, residual)`` or None when it does not converge;
    ``progress(iteration, max_iterations)`` after each iteration."""
    f_ref = model.field(ref)
    n2 = 2 * model.nq
    su = scales.vector()
    n_ref = float(np.linalg.norm(f_ref / su[:n2])) or 1.0
    x0, T, E = np.array(x0, dtype=float), float(T), float(E)
    residual = math.inf
    for it in range(1, max_iterations + 1):
        fl = model.shoot(x0, T, check)
        if fl is None:
            return None
        r_close = (fl.y - x0 - shift) / su[:n2]
        r_phase = float(f_ref @ (x0 - ref)) / (n_ref * scales.angle)
        r_energy = (model.energy(x0) - E) / scales.energy
        rows = [r_close, [r_phase], [r_energy]]
        J_close = np.hstack([(fl.stm - np.eye(n2)) * su[None, :n2] / su[:n2, None],
                             (model.field(fl.y) * su[n2] / su[:n2])[:, None]])
        J_phase = np.r_[f_ref * su[:n2] / (n_ref * scales.angle), 0.0]
        J_energy = np.r_[model.energy_gradient(x0) * su[:n2] / scales.energy, 0.0]
        J = np.vstack([J_close, J_phase, J_energy])
        if free_energy:
            J = np.hstack([J, np.zeros((J.shape[0], 1))])
            J[-1, -1] = -1.0  # d(H - E)/dE, in units of the energy scale
        if arclength is not None:
            u_pred, tangent = arclength
            u = np.r_[x0, T, E] / su
            rows.append([float(tangent @ (u - u_pred))])
            J = np.vstack([J, tangent])
        r = np.concatenate([np.ravel(x) for x in rows])
        residual = float(np.max(np.abs(r)))
        if not np.all(np.isfinite(r)) or not np.all(np.isfinite(J)):
            return None
        du, *_ = np.linalg.lstsq(J, -r, rcond=None)
        step = float(np.max(np.abs(du)))
        if step > 0.5:  # a wild step: damp it (the corrector is a local method)
            du *= 0.5 / step
        x0 = x0 + du[:n2] * su[:n2]
        T = T + du[n2] * su[n2]
        if free_energy:
            E = E + du[n2 + 1] * su[n2 + 1]
        if progress is not None:
            progress(it, max_iterations)
        if residual < tol and step < 1e3 * tol:
            fl = model.shoot(x0, T, check)
            if fl is None:
                return None
            return x0, T, E, fl, it, residual
    return None


def _multipliers(stm: np.ndarray) -> Tuple[np.ndarray, float]:
    mu = np.linalg.eigvals(stm)
    mu = mu[np.argsort(-np.abs(mu))]
    return mu, float(np.trace(stm) - 2.0)


def _stable_multipliers(mu: np.ndarray) -> bool:
    """Linear stability for any number of degrees of freedom: every Floquet multiplier on or inside the
    unit circle (a Hamiltonian flow's come in pairs mu, 1/mu: on it), within :data:`STABILITY_MARGIN`."""
    return bool(np.all(np.isfinite(mu)) and np.max(np.abs(mu)) <= 1.0 + STABILITY_MARGIN)


@dataclass(frozen=True)
class PeriodicOrbit(Result):
    """A periodic orbit (:func:`periodic_orbit`), or the failure to find one (``ok`` False).

    * ``state`` -- the start ``(phi, psi, phi', psi')`` on the orbit (a chain's ``2 n`` angles and
      speeds); ``period`` [s]; ``frequency`` ``2 pi / T`` [rad/s]; ``energy`` ``H = T + Pi - tau . q``
      [J]; ``rotation`` -- whole turns of each angle per period (``(0, 0)``: a libration);
    * ``monodromy`` (4, 4), ``multipliers`` (4,) complex, largest modulus first; ``sigma`` --
      ``trace - 2``; ``stable`` -- ``|sigma| <= 2`` (within :data:`STABILITY_MARGIN`); a chain's: every
      multiplier on the unit circle (``sigma`` is then NaN: the criterion of two degrees of freedom);
    * ``trajectory(rows)`` -- the orbit over one period as a :class:`~skewpend.Trajectory`
      (integrated anew by :func:`skewpend.simulate`);
    * the result protocol: ``params``, ``settings``, ``stats`` (``newton_iterations``,
      ``residual``, ``flows``, ``steps``), ``status``, ``message``, ``ok``, ``to_xarray()``,
      ``to_netcdf()``, ``summary()``.
    """

    state: np.ndarray
    period: float
    energy: float
    rotation: Tuple[int, ...]
    monodromy: np.ndarray = field(repr=False)
    multipliers: np.ndarray = field(init=False, repr=False)
    sigma: float = field(init=False)

    result_kind: ClassVar[str] = "periodic orbit"

    def __post_init__(self):
        super().__post_init__()
        mono = np.asarray(self.monodromy, dtype=float)
        object.__setattr__(self, "state", np.asarray(self.state, dtype=float))
        object.__setattr__(self, "rotation", tuple(int(r) for r in self.rotation))
        object.__setattr__(self, "monodromy", mono)
        n2 = mono.shape[0] if mono.ndim == 2 else 4
        mu, sigma = _multipliers(mono) if np.all(np.isfinite(mono)) else (np.full(n2, np.nan + 0j), math.nan)
        if n2 != 4:
            sigma = math.nan
        object.__setattr__(self, "multipliers", mu)
        object.__setattr__(self, "sigma", sigma)

    @property
    def frequency(self) -> float:
        return 2 * math.pi / self.period if self.period > 0 else math.nan

    @property
    def stable(self) -> bool:
        if np.size(self.state) != 4:  # a chain: every multiplier on the unit circle
            return bool(self.ok and _stable_multipliers(self.multipliers))
        return bool(self.ok and abs(self.sigma) <= 2.0 + STABILITY_MARGIN)

    def trajectory(self, rows: int = 400, *, rtol: float = 1e-12, atol: float = 1e-12):
        """The orbit over one period, integrated anew by :func:`skewpend.simulate` (``rows + 1`` rows)."""
        from ..numeric.simulation import simulate

        if not self.ok:
            raise IntegrationError(f"no orbit to draw: {self.message}")
        return simulate(self.params, self.state, self.period, rtol=rtol, atol=atol, dt_out=self.period / rows)

    def table(self) -> str:
        if not self.ok:
            return f"no periodic orbit: {self.message}"
        mu = ", ".join(f"{abs(m):.6g}" + (f" (arg {math.degrees(np.angle(m)):.3g} deg)" if abs(m.imag) > 1e-12 else "")
                       for m in self.multipliers)
        n = np.size(self.state) // 2
        if math.isnan(self.sigma):  # no criterion of two degrees of freedom: every multiplier on the unit circle
            start = ("q = (" + ", ".join(f"{x:.9g}" for x in self.state[:n]) + ") rad, q' = ("
                     + ", ".join(f"{x:.9g}" for x in self.state[n:]) + ") rad/s")
            why = f"largest |mu| = {np.max(np.abs(self.multipliers)):.9g}; stable when every |mu| <= 1"
        else:
            start = (f"phi = {self.state[0]:.9g}, psi = {self.state[1]:.9g} rad, "
                     f"phi' = {self.state[2]:.9g}, psi' = {self.state[3]:.9g} rad/s")
            why = f"sigma = trace - 2 = {self.sigma:.9g}; stable when |sigma| <= 2"
        return "\n".join([
            f"start      {start}",
            f"period     {self.period:.12g} s (frequency {self.frequency:.9g} rad/s)",
            f"energy     {self.energy:.9g} J" + (f"; rotation {self.rotation}" if any(self.rotation) else ""),
            f"Floquet    |mu| = {mu}",
            f"stability  {'stable' if self.stable else 'unstable'} ({why})",
        ])

    def _dataset(self) -> DatasetSpec:
        return DatasetSpec(
            variables={
                "state": (("component",), self.state, {"long_name": "start on the orbit (the angles, then their speeds)"}),
                "period": ((), np.float64(self.period), {"units": "s"}),
                "energy": ((), np.float64(self.energy), {"units": "J"}),
                "monodromy": (("component", "component_2"), self.monodromy, {}),
                "multiplier_real": (("multiplier",), self.multipliers.real, {}),
                "multiplier_imag": (("multiplier",), self.multipliers.imag, {}),
            },
            coords={},
            attrs={"title": f"periodic orbit of {self.params.title} (skewpend)",
                   "components": ", ".join(_names(self.params) + [f"d{c}" for c in _names(self.params)]),
                   **self._base_attrs()},
        )


@netcdf_reader(PeriodicOrbit.result_kind)
def read_periodic_orbit(path, variables, attrs) -> PeriodicOrbit:
    """A :class:`PeriodicOrbit` from its ``*.nc`` file (``read_periodic_orbit(path)``, for
    :func:`skewpend.open_result`): its stored multipliers and energy must be those of its stored
    monodromy matrix and start (a failed orbit, without a monodromy, is read as it is)."""
    proto = protocol_fields(path, attrs, AnyModel)
    state = np.asarray(variables["state"], dtype=float)
    energy = float(variables["energy"])
    mono = np.asarray(variables["monodromy"], dtype=float)
    orbit = PeriodicOrbit(state=state, period=float(variables["period"]), energy=energy,
                          rotation=tuple(int(r) for r in proto["settings"].get("rotation", (0, 0))), monodromy=mono,
                          **proto)
    mu = np.asarray(variables["multiplier_real"], dtype=float) + 1j * np.asarray(variables["multiplier_imag"], dtype=float)
    if np.all(np.isfinite(mono)):
        agree(path, "Floquet multipliers", mu, orbit.multipliers, scale=1.0)
        _orbit_energy_check(path, proto["params"], state[None, :], np.array([energy]), "orbit's")
    object.__setattr__(orbit, "multipliers", mu)  # exactly as stored (the same values, to rounding)
    return orbit


def _scales_for(params: Parameters, T: float, E: float) -> _Scales:
    w = 2 * math.pi / T
    return _Scales(angle=1.0, speed=w, period=T, energy=max(abs(E), 1e-300), nq=params.n)


def _names(params) -> list:
    return list(getattr(params, "coordinates", ("phi", "psi")))


def _state(y0, n: int = 2) -> np.ndarray:
    """``y0 = (phi, psi, phi', psi')`` (a chain's ``n`` angles, then their speeds): real numbers (NumPy's
    too), the angles reduced modulo 2 pi (:func:`skewpend.checks.angle`: at most 1e6 rad), the speeds finite."""
    try:
        items = [v.item() if hasattr(v, "item") else v for v in list(y0)]
    except (TypeError, ValueError):
        items = None
    if items is None or len(items) != 2 * n:
        raise ParameterError(f"y0 must be {state_text(n)}, got {y0!r}")
    for i, v in enumerate(items[n:], start=n):
        if isinstance(v, bool) or not isinstance(v, numbers.Real) or not math.isfinite(float(v)):
            raise ParameterError(f"y0[{i}] must be a finite speed [rad/s] (a real number), got {v!r}")
    return np.array([angle(f"y0[{i}]", items[i]) for i in range(n)] + [float(v) for v in items[n:]])


def _real(name: str, value, unit: str) -> float:
    """A finite real number (NumPy's scalars too)."""
    if hasattr(value, "item") and getattr(value, "ndim", 0) == 0:
        value = value.item()
    if isinstance(value, bool) or not isinstance(value, numbers.Real) or not math.isfinite(float(value)):
        raise ParameterError(f"{name} must be a finite number of {unit}, got {value!r}")
    return float(value)


def _rotation(rotation, n: int = 2) -> Tuple[int, ...]:
    """``n`` whole numbers of turns (NumPy's integers too; two for the double pendulum) of at most
    :data:`ROTATION_LIMIT`."""
    try:
        turns = [v.item() if hasattr(v, "item") else v for v in list(rotation)]
    except (TypeError, ValueError):
        turns = []
    ok = len(turns) == n and all(isinstance(r, numbers.Integral) and not isinstance(r, bool) for r in turns)
    if not ok or any(abs(int(r)) > ROTATION_LIMIT for r in turns):
        shown = ", ".join((f"{float(r):.3g}" if abs(int(r)) < 10**308 else "beyond 1e308") if ok else repr(r)
                          for r in turns) if turns else repr(rotation)
        what = f"{count_text(n, 'whole numbers')} of turns ({', '.join(f'r{i}' for i in range(1, n + 1))})"
        raise ParameterError(f"rotation must be {what} from {-ROTATION_LIMIT} to {ROTATION_LIMIT}, got ({shown})")
    return tuple(int(r) for r in turns)


def _modes_text(nq: int) -> str:
    """The modes a number may name, for messages: ``1: the lowest linear frequency, 2: the highest``."""
    if nq == 1:
        return "1: the only mode"
    return "1: the lowest linear frequency, " + ("" if nq < 3 else "..., ") + f"{nq}: the highest"


def _trivial(model: "_Model", x: np.ndarray, T: float, tol: float) -> Optional[str]:
    """Why the solution ``(x, T)`` is an equilibrium, not an orbit (None when it moves): its
    amplitude is below :data:`TRIVIAL_AMPLITUDE` (or 100 x the Newton tolerance)."""
    threshold = max(TRIVIAL_AMPLITUDE, 100 * tol)
    amp = model.amplitude(x, T)
    if amp >= threshold:
        return None
    names = ", ".join(model.params.coordinates)
    where = f"({names}) = (" + ", ".join(f"{v:.6g}" for v in x[:model.nq]) + ") rad"
    try:
        from .equilibria import equilibrium_at

        eq = equilibrium_at(model.params, x[:model.nq])
        where = f"{eq.label} at ({names}) = (" + ", ".join(f"{v:.6g}" for v in eq.q) + f") rad, V = {eq.potential:.6g} J"
    except SkewpendError:
        pass
    return (f"no periodic orbit: Newton's method converged to the equilibrium {where}, where the motion vanishes "
            f"(amplitude {amp:.2g} rad, below {threshold:g} rad); start farther from it (a guess that moves, at an "
            "energy above the equilibrium's)")


def periodic_orbit(params: Parameters, y0: Optional[Sequence[float]] = None, period: Optional[float] = None, *,
                   mode: Optional[int] = None, energy: Optional[float] = None, rotation: Tuple[int, int] = (0, 0),
                   rtol: float = ORBIT_TOL, atol: float = ORBIT_TOL, tol: float = NEWTON_TOL,
                   max_iterations: int = NEWTON_MAX, throw: bool = False,
                   progress: Optional[Callable[[float, float], None]] = None) -> PeriodicOrbit:
    """A periodic orbit near a guess ``(y0, period)`` at the energy ``energy`` (default: the
    guess's), or, with ``mode`` (1 or 2; a chain's 1 to n) and ``energy``, the orbit of that nonlinear
    normal mode at that energy (continued from the linear mode by :func:`nnm`).

    ``y0``'s angles are reduced modulo 2 pi (at most 1e6 rad); ``period`` [s] is refused before
    any work when one shooting over it would need more than :data:`ORBIT_MAX_STEPS` steps (a
    trial flow from ``y0`` estimates them).  ``rotation = (r1, r2)``: whole turns of
    ``(phi, psi)`` per period (a chain's: one a link) (a rotating orbit; at most :data:`ROTATION_LIMIT`).  ``tol``:
    Newton's tolerance on the scaled residual (1e-15 to 1e-6); ``max_iterations`` (1 to 1000).
    ``progress(iteration, max_iterations)`` after each Newton iteration (with ``mode``:
    ``progress(energy, energy)`` along the continuation).

    The result's ``ok`` is False, with the reason in ``message``, when Newton's method does not
    converge (status ``NO_CONVERGENCE``) or converges to an equilibrium -- a solution whose
    amplitude is below :data:`TRIVIAL_AMPLITUDE` (status ``TRIVIAL``: an equilibrium is never
    reported as a periodic orbit); ``throw=True`` raises :class:`~skewpend.errors.IntegrationError`
    instead.
    """
    from ..interrupts import Interrupts

    params = numeric_model(params, "periodic orbits")
    params.require_lossless("a periodic orbit")  # H = T + Pi - tau . q is kept: torques allowed
    nq = params.n
    rtol, atol = tolerances(rtol, atol, default=ORBIT_TOL)
    tol = positive("tol", tol)
    if not TOL_RANGE[0] <= tol <= TOL_RANGE[1]:
        raise ParameterError(f"tol must be from {TOL_RANGE[0]:g} to {TOL_RANGE[1]:g} (Newton's tolerance on the scaled "
                             f"residual), got {tol:g}")
    max_iterations = whole("max_iterations", max_iterations, 1, MAX_ITERATIONS_LIMIT)
    if throw not in (True, False):
        raise ParameterError(f"throw must be True or False, got {throw!r}")
    progress = progress_callable(progress, "progress(done, total)")
    if mode is not None:
        if y0 is not None or period is not None:
            raise ParameterError("give either a guess (y0, period) or mode=, not both")
        if energy is None:
            raise ParameterError("mode= needs energy= (the energy of the orbit wanted) [J]")
        mode = whole("mode", mode, 1, nq, what=_modes_text(nq))
        energy = _energy_limit(params, "energy", energy)
        family = nnm(params, mode=mode, energy_max=energy, rtol=rtol, atol=atol, progress=progress)
        if not family.energies.size or family.energies[-1] < energy * (1 - 1e-9):
            return _failed(params, "the family stops before this energy: " + family.message, (0, 0), throw)
        return family.orbit(len(family.energies) - 1)
    if y0 is None or period is None:
        raise ParameterError("a periodic orbit needs a guess: y0 (phi, psi, phi', psi') and period [s], or mode= and energy=")
    x0 = _state(y0, nq)
    period = positive("period", period)
    if not period < 1e6:
        raise ParameterError(f"period must be a positive number of seconds below 1e6, got {period:g}")
    if isinstance(rotation, tuple) and rotation == (0, 0):  # the default: no turn of any joint
        rotation = (0,) * nq
    rotation = _rotation(rotation, nq)
    if energy is not None:
        energy = _real("energy", energy, "joules")
    model = _Model(params, rtol, atol)
    model.check_work(x0, period)
    E = model.energy(x0) if energy is None else energy
    if not math.isfinite(E):
        raise ParameterError(f"y0: the energy of the guess is not finite ({E!r}); give a slower start")
    shift = np.array([2 * math.pi * r for r in rotation] + [0.0] * nq)
    scales = _scales_for(params, period, E if E != 0 else 1.0)
    with Interrupts() as intr:
        out = _newton(model, x0, period, E, shift, x0, scales, tol=tol, max_iterations=max_iterations,
                      check=intr.check, progress=progress)
    settings = {"guess": x0.tolist(), "period_guess": period, "energy": E, "rotation": list(rotation),
                "rtol": rtol, "atol": atol, "tol": tol}
    if out is None:
        return _failed(params, f"Newton's method did not converge from this guess in {max_iterations} iterations "
                               "(try a better guess, e.g. from skewpend.nnm)", rotation, throw, settings, model)
    x, T, E, fl, its, res = out
    trivial = _trivial(model, x, T, tol) if not any(rotation) else None
    if trivial is not None:
        return _failed(params, trivial, rotation, throw, settings, model, status=Status.TRIVIAL)
    stats = {"newton_iterations": its, "residual": res, "flows": model.calls, "steps": model.steps}
    return PeriodicOrbit(state=x, period=T, energy=E, rotation=rotation, monodromy=fl.stm, params=params,
                         settings=settings, stats=stats, status=Status.SUCCESS,
                         message="a periodic orbit: closes to the Newton tolerance")


def _failed(params, why, rotation, throw, settings=None, model=None, status=Status.NO_CONVERGENCE) -> PeriodicOrbit:
    if throw:
        raise IntegrationError(why)
    stats = {} if model is None else {"flows": model.calls, "steps": model.steps}
    n2 = 2 * len(rotation)
    return PeriodicOrbit(state=np.full(n2, np.nan), period=math.nan, energy=math.nan, rotation=rotation,
                         monodromy=np.full((n2, n2), np.nan), params=params, settings=settings or {}, stats=stats,
                         status=status, message=why)


# -- nonlinear normal modes ------------------------------------------------------------------------


#: A chain's flip energy: seeded samples on each face of the cube, and the local minimisations from the best.
FLIP_SAMPLES, FLIP_STARTS = 4000, 6


#: The flip energies of the models met last (seconds each for a long chain: nnm, its energy check and
#: backbones' families ask for the same model's).
_FLIP_ENERGIES: Dict[object, float] = {}
#: A face of one free angle (two links) is sampled at this many points, then refined by a bounded
#: scalar search; a face of more is sampled at :data:`FLIP_SAMPLES` seeded points, then L-BFGS-B from the
#: :data:`FLIP_STARTS` lowest.
FLIP_LINE_SAMPLES = 2049


def flip_energy(params) -> float:
    """The lowest energy at which a joint can flip: the minimum of ``V = Pi - tau . q`` (the kernel's energy
    at rest minus the torques' work) on the boundary of the cube ``|q_i| <= pi``, face by face (one angle at
    +-pi): a face of one free angle (the double pendulum's square's sides) sampled densely and refined by a
    bounded scalar search, a face of more by seeded samples and L-BFGS-B from the lowest."""
    cached = _FLIP_ENERGIES.get(params)
    if cached is not None:
        return cached
    _say("the lowest flip energy: loading SciPy's minimiser")
    from scipy.optimize import minimize, minimize_scalar

    H = energy_function(params)
    n = params.n
    rng = np.random.default_rng(0)
    best = math.inf

    def V(q):
        q = np.atleast_2d(q)
        return H(np.concatenate([q, np.zeros((q.shape[0], n))], axis=1))

    for i in range(n):
        for half, side in enumerate((-math.pi, math.pi)):
            free = [j for j in range(n) if j != i]
            face = f"face {2 * i + half + 1} of {2 * n}"
            if len(free) <= 1:  # a line (or a point): dense samples, then the bracketing interval refined
                s = np.linspace(-math.pi, math.pi, FLIP_LINE_SAMPLES)
                Q = np.full((s.size, n), side)
                Q[:, free] = s[:, None]
                values = V(Q)
                k = int(np.argmin(values))
                best = min(best, float(values[k]))
                if free:
                    lo, hi = s[max(k - 1, 0)], s[min(k + 1, s.size - 1)]

                    def on_line(t):
                        q = np.full(n, side)
                        q[free] = t
                        return float(V(q)[0])

                    res = minimize_scalar(on_line, bounds=(lo, hi), method="bounded", options={"xatol": 1e-12})
                    best = min(best, float(res.fun))
                continue
            Q = rng.uniform(-math.pi, math.pi, size=(FLIP_SAMPLES, n))
            Q[:, i] = side
            _say(f"the lowest flip energy: {face}, {FLIP_SAMPLES} samples")
            values = V(Q)
            for start, k in enumerate(np.argsort(values)[:FLIP_STARTS], 1):
                _say(f"the lowest flip energy: {face}, search {start} of {FLIP_STARTS}")

                def f(x, k=k):
                    q = Q[k].copy()
                    q[free] = x
                    return float(V(q)[0])

                res = minimize(f, Q[k, free], method="L-BFGS-B", bounds=[(-math.pi, math.pi)] * len(free),
                               options={"ftol": 1e-15, "gtol": 1e-12})
                best = min(best, float(values[k]), float(res.fun))
    if len(_FLIP_ENERGIES) >= 16:  # a few models at a time (a continuation asks for its model's more than once)
        _FLIP_ENERGIES.pop(next(iter(_FLIP_ENERGIES)))
    _FLIP_ENERGIES[params] = best
    return best


@dataclass(frozen=True)
class BranchEvent:
    """A point of interest along a family: ``kind`` (``"fold"``, ``"branch point"`` -- a multiplier
    leaving or entering the unit circle through +1 --, ``"period doubling"`` -- through -1 --, or
    ``"resonance"``), the ``energy`` [J] and ``frequency`` [rad/s] there (interpolated between the
    two orbits that bracket it, ``index`` the first of them), and a ``detail``."""

    kind: str
    index: int
    energy: float
    frequency: float
    detail: str = ""


class _Orbits:
    """What a family of orbits (in energy or in alpha) derives from its ``periods`` and ``sigma``."""

    periods: np.ndarray
    sigma: np.ndarray

    @property
    def frequencies(self) -> np.ndarray:
        """``2 pi / T`` [rad/s] of each orbit."""
        return 2 * np.pi / self.periods

    @property
    def stable(self) -> np.ndarray:
        """``|sigma| <= 2`` (within :data:`STABILITY_MARGIN`): the nontrivial multipliers on the unit circle."""
        return np.abs(self.sigma) <= 2.0 + STABILITY_MARGIN


@dataclass(frozen=True)
class NNMFamily(_Orbits, Result):
    """A nonlinear normal mode: the family of periodic orbits continuing linear mode ``mode``.

    Arrays along the family (one entry per orbit, in continuation order): ``energies`` [J],
    ``periods`` [s], ``frequencies`` [rad/s], ``states`` (n, 4) the starts, ``multipliers``
    (n, 4) complex, ``sigma`` (n,) ``trace - 2``, ``stable`` (n,) bool; ``events`` -- the
    :class:`BranchEvent` found (folds, stability changes); ``linear_frequency`` -- the mode's
    frequency at zero energy; ``energy_max`` -- where it was asked to stop.  ``orbit(k)`` gives
    orbit ``k`` as a :class:`PeriodicOrbit`.  The result protocol as every result's.
    """

    mode: int
    linear_frequency: float
    energies: np.ndarray
    periods: np.ndarray
    states: np.ndarray = field(repr=False)
    monodromies: np.ndarray = field(repr=False)
    events: List["BranchEvent"]
    energy_max: float
    multipliers: np.ndarray = field(init=False, repr=False)
    sigma: np.ndarray = field(init=False, repr=False)

    result_kind: ClassVar[str] = "nonlinear normal mode"

    def __post_init__(self):
        super().__post_init__()
        object.__setattr__(self, "energies", np.asarray(self.energies, dtype=float))
        object.__setattr__(self, "periods", np.asarray(self.periods, dtype=float))
        n2 = 2 * self.params.n
        object.__setattr__(self, "states", np.asarray(self.states, dtype=float).reshape(-1, n2))
        object.__setattr__(self, "monodromies", np.asarray(self.monodromies, dtype=float).reshape(-1, n2, n2))
        mus = [_multipliers(m) for m in self.monodromies]
        object.__setattr__(self, "multipliers", np.array([m for m, _ in mus]).reshape(-1, n2))
        # trace - 2 decides stability with two degrees of freedom only; a chain's: every multiplier (NaN here)
        sigma = [s for _, s in mus] if n2 == 4 else [math.nan] * len(mus)
        object.__setattr__(self, "sigma", np.array(sigma, dtype=float))

    @property
    def stable(self) -> np.ndarray:
        """Each orbit's linear stability: ``|sigma| <= 2`` (the double pendulum), every Floquet multiplier on
        the unit circle (a chain), within :data:`STABILITY_MARGIN`."""
        if self.states.shape[1] == 4:
            return np.abs(self.sigma) <= 2.0 + STABILITY_MARGIN
        return np.array([_stable_multipliers(mu) for mu in self.multipliers], dtype=bool)

    def __len__(self) -> int:
        return len(self.energies)

    def orbit(self, k: int) -> PeriodicOrbit:
        settings = {**self.settings, "index": int(k)}
        return PeriodicOrbit(state=self.states[k], period=self.periods[k], energy=self.energies[k], rotation=(0, 0),
                             monodromy=self.monodromies[k], params=self.params, settings=settings, stats={},
                             status=Status.SUCCESS, message=f"orbit {k} of nonlinear normal mode {self.mode}")

    def at_energy(self, energy: float) -> PeriodicOrbit:
        """The computed orbit whose energy is closest to ``energy``."""
        return self.orbit(int(np.argmin(np.abs(self.energies - energy))))

    def table(self, every: int = 0) -> str:
        n = len(self)
        step = every or max(1, n // 12)
        double = self.states.shape[1] == 4  # sigma = trace - 2; a chain's: the largest multiplier's modulus
        lines = [f"{'energy [J]':>12}  {'frequency [rad/s]':>17}  {'period [s]':>11}  {'sigma' if double else 'max |mu|':>10}  "
                 "stability"]
        for k in list(range(0, n, step)) + ([n - 1] if (n - 1) % step else []):
            shown = self.sigma[k] if double else float(np.max(np.abs(self.multipliers[k])))
            lines.append(f"{self.energies[k]:12.6g}  {self.frequencies[k]:17.9g}  {self.periods[k]:11.7g}  "
                         f"{shown:10.6g}  {'stable' if self.stable[k] else 'unstable'}")
        for e in self.events:
            lines.append(f"{e.kind} at E = {e.energy:.6g} J (frequency {e.frequency:.6g} rad/s){': ' + e.detail if e.detail else ''}")
        return "\n".join(lines)

    def _dataset(self) -> DatasetSpec:
        return DatasetSpec(
            variables={
                "energy": (("orbit",), self.energies, {"units": "J"}),
                "period": (("orbit",), self.periods, {"units": "s"}),
                "frequency": (("orbit",), self.frequencies, {"units": "rad/s"}),
                "state": (("orbit", "component"), self.states, {"long_name": "start on the orbit (angles, then speeds)"}),
                "sigma": (("orbit",), self.sigma, {"long_name": "trace of the monodromy matrix - 2"}),
                "stable": (("orbit",), self.stable.astype(np.int8), {}),
                "multiplier_real": (("orbit", "multiplier"), self.multipliers.real, {}),
                "multiplier_imag": (("orbit", "multiplier"), self.multipliers.imag, {}),
            },
            coords={},
            attrs={"components": ", ".join(state_coordinates(self.states.shape[1] // 2)),
                   "title": f"nonlinear normal mode {self.mode} of "
                            f"{'the skewed double pendulum' if self.states.shape[1] == 4 else 'a chain of links'} (skewpend)",
                   "mode": self.mode, "linear_frequency": self.linear_frequency,
                   "events": "; ".join(f"{e.kind} at E = {e.energy:.9g} J" for e in self.events),
                   **self._base_attrs()},
        )


def _stability_changes(sigma, frequencies, at_energy: Callable[[int, float], float],
                       detail: Callable[[int, float, str, float], str]) -> List[BranchEvent]:
    """Where ``sigma`` crosses +2 (a branch point) or -2 (a period doubling) between neighbouring
    orbits ``k`` and ``k + 1``, at the fraction ``t`` between them (linear): the energy there is
    ``at_energy(k, t)``, the event's text ``detail(k, t, way, level)`` (``way``: the family
    "loses" or "regains" stability)."""
    out: List[BranchEvent] = []
    for k in range(len(sigma) - 1):
        for level, kind in ((2.0, "branch point"), (-2.0, "period doubling")):
            a, b = sigma[k] - level, sigma[k + 1] - level
            if a * b < 0:
                t = a / (a - b)
                way = "loses" if abs(sigma[k + 1]) > abs(sigma[k]) else "regains"
                out.append(BranchEvent(kind, k, at_energy(k, t), float(frequencies[k] + t * (frequencies[k + 1] - frequencies[k])),
                                       detail(k, t, way, level)))
    return out


def _multiplier_changes(energies, frequencies, multipliers) -> List[BranchEvent]:
    """A chain's stability changes along a family in energy: between orbits ``k`` and ``k + 1`` where the
    largest Floquet multiplier's modulus crosses ``1 + STABILITY_MARGIN``, at the fraction ``t`` of the crossing
    (linear in the modulus); the kind by that multiplier on the unstable side -- near +1 a branch point, near -1
    a period doubling, off the real axis a pair leaving the circle (a Krein collision)."""
    out: List[BranchEvent] = []
    r = np.array([np.max(np.abs(mu)) for mu in multipliers])
    level = 1.0 + STABILITY_MARGIN
    for k in range(len(r) - 1):
        a, b = r[k] - level, r[k + 1] - level
        if a * b < 0:
            t = a / (a - b)
            mu = multipliers[k + 1] if b > 0 else multipliers[k]
            lead = mu[np.argmax(np.abs(mu))]
            if abs(lead.imag) > 1e-6 * abs(lead):
                kind, where = "Krein collision", "a pair of multipliers off the real axis"
            elif lead.real > 0:
                kind, where = "branch point", "a multiplier at +1"
            else:
                kind, where = "period doubling", "a multiplier at -1"
            way = "loses" if b > 0 else "regains"
            out.append(BranchEvent(kind, k, float(energies[k] + t * (energies[k + 1] - energies[k])),
                                   float(frequencies[k] + t * (frequencies[k + 1] - frequencies[k])),
                                   f"the family {way} stability ({where})"))
    return out


def _family_events(energies, frequencies, sigma, folds: Sequence[int], multipliers=None) -> List[BranchEvent]:
    """The events of a family in energy: its stability changes (from ``sigma``; a chain's from its
    ``multipliers``), and a fold after each orbit ``k`` of ``folds`` (where the energy turns back), in the
    order of the orbits."""
    if multipliers is not None and np.shape(multipliers)[1] != 4:
        out = _multiplier_changes(energies, frequencies, multipliers)
    else:
        out = _stability_changes(
            sigma, frequencies, lambda k, t: float(energies[k] + t * (energies[k + 1] - energies[k])),
            lambda k, t, way, level: f"the family {way} stability (a multiplier at {'+' if level > 0 else '-'}1)")
    out += [BranchEvent("fold", k, float(energies[k + 1]), float(frequencies[k + 1]), "the energy turns back along the family")
            for k in folds]
    return sorted(out, key=lambda e: (e.index, e.kind == "fold"))


@netcdf_reader(NNMFamily.result_kind)
def read_nnm(path, variables, attrs) -> NNMFamily:
    """A :class:`NNMFamily` from its ``*.nc`` file (``read_nnm(path)``, for
    :func:`skewpend.open_result`): the monodromy matrices are not stored, so one period of the
    variational flow from each stored start gives them (and must close the orbit); the stored
    energies, sigma, multipliers and events must follow from them."""
    import re

    from ..numeric.variational import FlowIntegrator

    proto = protocol_fields(path, attrs, AnyModel)
    params, settings = proto["params"], proto["settings"]
    n2 = 2 * params.n
    energies = np.asarray(variables["energy"], dtype=float)
    periods = np.asarray(variables["period"], dtype=float)
    states = np.asarray(variables["state"], dtype=float).reshape(-1, n2)
    sigma = np.asarray(variables["sigma"], dtype=float)
    mu = (np.asarray(variables["multiplier_real"], dtype=float)
          + 1j * np.asarray(variables["multiplier_imag"], dtype=float)).reshape(-1, n2)
    flow = FlowIntegrator(params, rtol=float(settings.get("rtol", 1e-12)), atol=float(settings.get("atol", 1e-12)))
    monos = np.empty((len(energies), n2, n2))
    for k in range(len(energies)):
        fl = flow(states[k], float(periods[k]))
        if fl.status != Status.SUCCESS:
            raise ParameterError(f"{path}: orbit {k} cannot be integrated again ({fl.status.message})")
        agree(path, f"orbit {k} (closing after one period)", fl.y, states[k], scale=1.0 + float(np.abs(states[k]).max()))
        monos[k] = fl.stm
    _orbit_energy_check(path, params, states, energies, "orbits'")
    freq = 2 * np.pi / periods
    # folds (where the energy turns back along the family) are kept in the file's event list only
    text = str(attrs.get("events", ""))
    folds = []
    for m in re.finditer(r"fold at E = ([-+0-9.eEinfa]+) J", text):
        k = next((k for k in range(len(energies) - 1) if f"{energies[k + 1]:.9g}" == m.group(1)), None)
        if k is None:
            raise ParameterError(f"{path} is not a nonlinear normal mode made by skewpend: its fold at E = {m.group(1)} J "
                                 "is not one of its orbits")
        folds.append(k)
    events = _family_events(energies, freq, sigma, folds, mu)
    rebuilt_text = "; ".join(f"{e.kind} at E = {e.energy:.9g} J" for e in events)
    if rebuilt_text != text:
        raise ParameterError(f"{path} is not a nonlinear normal mode made by skewpend: its events ({text!r}) do not follow "
                             f"from its orbits ({rebuilt_text!r})")
    family = NNMFamily(mode=int(attrs["mode"]), linear_frequency=float(attrs["linear_frequency"]), energies=energies,
                       periods=periods, states=states, monodromies=monos, events=events,
                       energy_max=float(settings.get("energy_max", energies[-1] if energies.size else math.nan)), **proto)
    if n2 == 4:
        agree(path, "sigma (trace of the monodromy - 2)", sigma, family.sigma, scale=4.0)
    agree(path, "Floquet multipliers", mu, family.multipliers, scale=1.0)
    object.__setattr__(family, "sigma", sigma)  # exactly as stored (the same values, to rounding)
    object.__setattr__(family, "multipliers", mu)
    return family


#: The first orbit of a family lies at this fraction of the energy (``energy_max`` or the flip energy).
FIRST_ORBIT = 1e-4


def _energy_limit(params: Parameters, name: str, value, *, mode: Optional[int] = None) -> float:
    """An energy [J] a family of librations can reach: positive, at most the potential energy of
    the highest equilibrium (above it no orbit of the family has the turning point where it comes
    to rest, E = V <= max V), and -- with ``mode`` -- large enough that the family's first orbit
    (at :data:`FIRST_ORBIT` of it) moves by more than 10 x :data:`TRIVIAL_AMPLITUDE`."""
    from .equilibria import equilibria

    E = positive(name, value)
    _say("the equilibria (the highest bounds the energy)")
    points = equilibria(params).points
    if points:
        top = max(points, key=lambda e: e.potential)
        if E > top.potential:
            raise ParameterError(f"{name} must be at most {top.potential:.6g} J, the potential energy of the highest "
                                 f"equilibrium ({top.label}): no libration of a nonlinear normal mode reaches above it, "
                                 f"got {E:g}")
    if mode is not None:
        from .modes import normal_modes

        w0 = float(normal_modes(params).frequencies[mode - 1])
        first = FIRST_ORBIT * min(E, flip_energy(params))
        smallest = 0.5 * (10 * TRIVIAL_AMPLITUDE * w0) ** 2 / FIRST_ORBIT
        if math.sqrt(2 * first) / w0 < 10 * TRIVIAL_AMPLITUDE:
            raise ParameterError(f"{name} must be at least {smallest:.3g} J for mode {mode}: below it the family's "
                                 f"orbits are the linear mode's, smaller than the amplitude an orbit is told from "
                                 f"its equilibrium by (use skewpend.normal_modes), got {E:g}")
    return E


def nnm(params: Parameters, mode: int = 1, *, energy_max: Optional[float] = None, max_orbits: int = 2000,
        resolution: int = 200, step: float = 0.02, rtol: float = ORBIT_TOL, atol: float = ORBIT_TOL,
        progress: Optional[Callable[[float, float], None]] = None) -> NNMFamily:
    """The nonlinear normal mode ``mode`` (1: the lower linear frequency, 2: the higher) of the
    conservative model ``params``: its periodic orbits from near zero energy up to ``energy_max``
    [J] (default: :func:`flip_energy`, where a joint can first flip over), by pseudo-arclength
    continuation (see the module).  ``step``: the first step in the scaled unknowns (adapted);
    ``resolution``: successive orbits differ by at most ``energy_max / resolution`` in energy (so
    a family has at least that many orbits); ``max_orbits`` bounds the family's length; the last
    orbit lies exactly at ``energy_max``; ``progress(energy, energy_max)`` after each orbit.
    The result's status is SUCCESS when the family reached ``energy_max``; else ``ok`` is False
    and ``message`` says where and why it stopped (the orbits computed are kept)."""
    from .modes import normal_modes
    from ..interrupts import Interrupts

    params = numeric_model(params, "nonlinear normal modes")
    params.require_lossless("a nonlinear normal mode")
    if np.any(_torques(params)):
        raise EquilibriumError("nonlinear normal modes start from the modes about the hanging equilibrium; "
                               "with torques use skewpend.periodic_orbit about skewpend.equilibria(params)")
    nq = params.n
    n2 = 2 * nq
    mode = whole("mode", mode, 1, nq, what=_modes_text(nq))
    max_orbits = whole("max_orbits", max_orbits, lo=2, hi=100_000)
    resolution = whole("resolution", resolution, lo=1, hi=100_000)
    if resolution >= max_orbits:
        raise ParameterError(f"resolution must be below max_orbits = {max_orbits} (a family of at least resolution "
                             f"orbits cannot fit in max_orbits of them), got {resolution}")
    step = positive("step", step, cap=0.5)
    rtol, atol = tolerances(rtol, atol, default=ORBIT_TOL)
    progress = progress_callable(progress, "progress(energy, energy_max)")
    _say("the lowest energy at which a joint can flip")
    barrier = flip_energy(params)
    E_max = barrier if energy_max is None else _energy_limit(params, "energy_max", energy_max, mode=mode)
    _say("the linear modes")
    linear = normal_modes(params)
    w0 = float(linear.frequencies[mode - 1])
    v = linear.shapes[:, mode - 1]
    model = _Model(params, rtol, atol)
    T0 = 2 * math.pi / w0
    scales = _Scales(angle=1.0, speed=w0, period=T0, energy=max(E_max, 1e-300), nq=nq)
    su = scales.vector()
    # the first orbit: the linear mode at a small energy (1/2 w^2 A^2 = E with v^T M v = 1)
    E = FIRST_ORBIT * min(E_max, barrier)
    A = math.sqrt(2 * E) / w0
    x = np.r_[A * np.real(v), np.zeros(nq)]
    zero = np.zeros(n2)
    energies, periods, states, monos, tangE = [], [], [], [], []
    settings = {"mode": mode, "energy_max": E_max, "step": step, "rtol": rtol, "atol": atol, "max_orbits": max_orbits}
    status, message = Status.SUCCESS, ""

    def told(what: str):  # a Newton iteration said on the live line (issue 51: no silence over 2 s)
        return lambda it, _n: _say(f"{what}: Newton iteration {it}")

    with Interrupts() as intr:
        out = _newton(model, x, T0, E, zero, x, scales, check=intr.check, progress=told("orbit 1 (the linear mode)"))
        if out is None:
            raise IntegrationError("the continuation could not start from the linear mode (Newton failed at the first orbit)")
        x, T, E, fl, _, _ = out
        energies.append(E), periods.append(T), states.append(x), monos.append(fl.stm)
        # the first tangent: along increasing energy (a second orbit at twice the energy)
        out2 = _newton(model, x * math.sqrt(2.0), T, 2 * E, zero, x, scales, check=intr.check, progress=told("orbit 2"))
        if out2 is None:
            raise IntegrationError("the continuation could not take its first step from the linear mode")
        x2, T2, E2, fl2, _, _ = out2
        energies.append(E2), periods.append(T2), states.append(x2), monos.append(fl2.stm)
        ds = step
        failures = 0
        while True:
            u_prev = np.r_[states[-2], periods[-2], energies[-2]] / su
            u_cur = np.r_[states[-1], periods[-1], energies[-1]] / su
            tangent = u_cur - u_prev
            tangent /= np.linalg.norm(tangent)
            tangE.append(tangent[-1])
            if energies[-1] >= E_max:
                break
            if len(energies) >= max_orbits:
                status, message = Status.MAX_STEPS, f"stopped after max_orbits = {max_orbits} orbits at E = {energies[-1]:.6g} J"
                break
            u_pred = u_cur + ds * tangent
            x_p, T_p, E_p = u_pred[:n2] * su[:n2], u_pred[n2] * su[n2], u_pred[n2 + 1] * su[n2 + 1]
            here = f"orbit {len(energies) + 1} near E = {E_p:.4g} J ({100 * min(E_p / E_max, 1.0):.1f}%)"
            res = _newton(model, x_p, T_p, E_p, zero, states[-1], scales, arclength=(u_pred, tangent),
                          free_energy=True, check=intr.check, max_iterations=8, progress=told(here))
            if res is None:
                ds /= 2
                failures += 1
                _say(f"{here}: the corrector failed, the step halved")
                if ds < 1e-7:
                    status = Status.NO_CONVERGENCE
                    message = (f"the continuation stopped at E = {energies[-1]:.6g} J (frequency "
                               f"{2 * math.pi / periods[-1]:.6g} rad/s): the corrector failed with the smallest step")
                    break
                continue
            x_n, T_n, E_n, fl_n, its, _ = res
            dE = abs(E_n - energies[-1])
            if dE > E_max / resolution:  # coarser than asked: take a shorter step instead
                ds *= 0.9 * (E_max / resolution) / dE
                continue
            if E_n > E_max and energies[-1] < E_max:
                # the last orbit exactly at energy_max (energy fixed, from the interpolated orbit)
                t_ = (E_max - energies[-1]) / (E_n - energies[-1])
                guess = states[-1] + t_ * (x_n - states[-1])
                fixed = _newton(model, guess, periods[-1] + t_ * (T_n - periods[-1]), E_max, zero, states[-1],
                                scales, check=intr.check, progress=told(f"the last orbit, at E = {E_max:.4g} J"))
                if fixed is not None:
                    x_n, T_n, E_n, fl_n = fixed[0], fixed[1], fixed[2], fixed[3]
            energies.append(E_n), periods.append(T_n), states.append(x_n), monos.append(fl_n.stm)
            ds = min(ds * (1.5 if its <= 3 else (1.0 if its <= 5 else 0.5)), 0.2)
            if abs(E_n - energies[-2]) > 0:
                ds = min(ds, 0.95 * ds * (E_max / resolution) / abs(E_n - energies[-2]))
            if progress is not None:
                progress(min(E_n, E_max), E_max)
    tangE.append(tangE[-1] if tangE else 1.0)
    energies_a = np.array(energies)
    family_freq = 2 * np.pi / np.array(periods)
    sig = np.array([np.trace(m) - 2 if n2 == 4 else math.nan for m in monos])
    folds = [k for k in range(len(energies) - 1) if tangE[k] * tangE[k + 1] < 0]  # the energy turns back
    events = _family_events(energies_a, family_freq, sig, folds, np.array([_multipliers(m)[0] for m in monos]))
    if status == Status.SUCCESS:
        message = (f"{len(energies)} orbits from E = {energies[0]:.3g} J to {energies[-1]:.6g} J"
                   + (" (the lowest energy at which a joint can flip)" if energy_max is None else ""))
    stats = {"orbits": len(energies), "flows": model.calls, "steps": model.steps, "failed_steps": failures}
    return NNMFamily(mode=mode, linear_frequency=w0, energies=energies, periods=periods, states=states,
                     monodromies=monos, events=events, energy_max=E_max, params=params, settings=settings, stats=stats,
                     status=status, message=message)


@dataclass(repr=False, eq=False)
class Backbones:
    """Both nonlinear normal modes (``families[0]``: mode 1, ``families[1]``: mode 2) and the
    internal resonances between them: energies where ``w_i(E) / w_j(E)`` crosses a ratio ``p/q``
    with ``p, q <= max_order`` (``resonances``: :class:`BranchEvent` of kind ``"resonance"``)."""

    families: List[NNMFamily]
    resonances: List[BranchEvent]

    @property
    def ok(self) -> bool:
        return all(f.ok for f in self.families)

    @property
    def status(self) -> Status:
        return Status.SUCCESS if self.ok else Status.PARTIAL

    @property
    def message(self) -> str:
        return "; ".join(f"mode {f.mode}: {f.message}" for f in self.families)


def backbones(params: Parameters, *, energy_max: Optional[float] = None, max_order: int = 3, **kw) -> Backbones:
    """Every family (:func:`nnm`: both of the double pendulum, a chain's n) and their internal resonances up to
    order ``max_order`` (1 to 12): where the frequency ratio ``w_j(E) / w_i(E)`` of two families (``i < j``)
    crosses ``p/q`` with ``p, q <= max_order``."""
    max_order = whole("max_order", max_order, 1, 12)
    n = params.n
    fams = []
    for m in range(1, n + 1):  # a chain's families take minutes: the live line names each (issue 51)
        token = _FAMILY.set(f"mode {m} of {n}: ")
        try:
            fams.append(nnm(params, mode=m, energy_max=energy_max, **kw))
        finally:
            _FAMILY.reset(token)
    ratios = sorted({Fraction(p, q) for p in range(1, max_order + 1) for q in range(1, max_order + 1)})
    res: List[BranchEvent] = []

    def along(f, E):  # a family as a function of energy (valid where its energy increases along the family)
        order = np.argsort(f.energies)
        return np.interp(E, f.energies[order], f.frequencies[order])

    for i in range(n):
        for j in range(i + 1, n):
            f1, f2 = fams[i], fams[j]
            lo = max(f1.energies.min(), f2.energies.min())
            hi = min(f1.energies.max(), f2.energies.max())
            if not hi > lo:
                continue
            E = np.linspace(lo, hi, 4001)
            w1 = along(f1, E)
            ratio = along(f2, E) / w1
            for r in ratios:
                d = ratio - float(r)
                for k in np.nonzero(d[:-1] * d[1:] < 0)[0]:
                    t = d[k] / (d[k] - d[k + 1])
                    Ek = float(E[k] + t * (E[k + 1] - E[k]))
                    res.append(BranchEvent("resonance", int(k), Ek, float(np.interp(Ek, E, w1)),
                                           f"w{j + 1}/w{i + 1} = {r.numerator}/{r.denominator}"))
    return Backbones(fams, sorted(res, key=lambda e: e.energy) if n > 2 else res)


# -- continuation in alpha at fixed energy ---------------------------------------------------------


@dataclass(frozen=True)
class AlphaFamily(_Orbits, Result):
    """A nonlinear normal mode at a fixed energy followed along the skew angle (:func:`nnm_alpha`).

    Arrays over ``alphas`` [rad] (those reached): ``periods`` [s], ``frequencies`` [rad/s],
    ``states`` (n, 4), ``sigma`` (trace - 2), ``stable``; ``events`` -- stability changes between
    neighbouring angles (:class:`BranchEvent`, ``energy`` holding the angle's energy and
    ``detail`` the angle); ``energy`` [J] and ``mode``.  The result protocol as every result's.
    """

    mode: int
    energy: float
    alphas: np.ndarray
    periods: np.ndarray
    states: np.ndarray = field(repr=False)
    sigma: np.ndarray = field(repr=False)
    events: List[BranchEvent]

    result_kind: ClassVar[str] = "nonlinear normal mode along alpha"

    def __post_init__(self):
        super().__post_init__()
        for name in ("alphas", "periods", "sigma"):
            object.__setattr__(self, name, np.asarray(getattr(self, name), dtype=float))
        object.__setattr__(self, "states", np.asarray(self.states, dtype=float).reshape(-1, 4))

    def table(self) -> str:
        lines = [f"{'alpha [deg]':>11}  {'frequency [rad/s]':>17}  {'sigma':>10}  stability"]
        step = max(1, len(self.alphas) // 12)
        for k in list(range(0, len(self.alphas), step)) + ([len(self.alphas) - 1] if (len(self.alphas) - 1) % step else []):
            lines.append(f"{math.degrees(self.alphas[k]):11.4f}  {self.frequencies[k]:17.9g}  {self.sigma[k]:10.6g}  "
                         f"{'stable' if self.stable[k] else 'unstable'}")
        lines += [f"{e.kind}: {e.detail}" for e in self.events]
        return "\n".join(lines)

    def _dataset(self) -> DatasetSpec:
        return DatasetSpec(
            variables={
                "period": (("alpha",), self.periods, {"units": "s"}),
                "frequency": (("alpha",), self.frequencies, {"units": "rad/s"}),
                "state": (("alpha", "component"), self.states, {"long_name": "start on the orbit (phi, psi, phi', psi')"}),
                "sigma": (("alpha",), self.sigma, {"long_name": "trace of the monodromy matrix - 2"}),
            },
            coords={"alpha": (("alpha",), self.alphas, {"units": "rad"})},
            attrs={"title": f"nonlinear normal mode {self.mode} at {self.energy:g} J along alpha (skewpend)",
                   "energy": self.energy, "mode": self.mode, **self._base_attrs()},
        )


def _alpha_events(alphas, frequencies, sigma, energy: float) -> List[BranchEvent]:
    """The stability changes of a family along alpha at the one ``energy``."""
    return _stability_changes(
        sigma, frequencies, lambda k, t: energy,
        lambda k, t, way, level: f"at alpha = {math.degrees(alphas[k] + t * (alphas[k + 1] - alphas[k])):.4g} deg the orbit "
                                 f"{way} stability")


@netcdf_reader(AlphaFamily.result_kind)
def read_nnm_alpha(path, variables, attrs) -> AlphaFamily:
    """An :class:`AlphaFamily` from its ``*.nc`` file (``read_nnm_alpha(path)``, for
    :func:`skewpend.open_result`): each stored start must have the family's energy with its own
    skew angle; the events follow from the stored sigma."""
    proto = protocol_fields(path, attrs, Parameters)
    params = proto["params"]
    alphas = np.asarray(variables["alpha"], dtype=float)
    periods = np.asarray(variables["period"], dtype=float)
    states = np.asarray(variables["state"], dtype=float).reshape(-1, 4)
    sigma = np.asarray(variables["sigma"], dtype=float)
    energy = float(attrs["energy"])
    for a, y in zip(alphas, states):
        _orbit_energy_check(path, params.replace(alpha=float(a)), y[None, :], np.array([energy]),
                            f"orbit's at alpha = {a:.6g} rad")
    return AlphaFamily(mode=int(attrs["mode"]), energy=energy, alphas=alphas, periods=periods, states=states, sigma=sigma,
                       events=_alpha_events(alphas, 2 * np.pi / periods, sigma, energy), **proto)


def nnm_alpha(params: Parameters, mode: int = 1, *, energy: float, alphas: Sequence[float],
              rtol: float = ORBIT_TOL, atol: float = ORBIT_TOL,
              progress: Optional[Callable[[float, float], None]] = None) -> AlphaFamily:
    """The orbit of nonlinear normal mode ``mode`` at the fixed ``energy`` [J], continued along the
    skew angles ``alphas`` [rad] (increasing or decreasing, as given): the first orbit from
    :func:`nnm` at ``alphas[0]``, each next one by Newton's method at the next angle from the
    previous one (natural-parameter continuation; a step that fails is halved, down to 1e-6 rad).
    Stability changes between neighbouring angles are reported.  The thin rods' ``alpha`` only
    (general axes have no single skew angle)."""
    from dataclasses import replace

    from ..checks import ANGLE_LIMIT
    from ..interrupts import Interrupts

    params = numeric_params(params, "nonlinear normal modes")
    if not params.uses_alpha:
        raise ParameterError("continuation in alpha needs the skew angle alpha (not a general axis2)")
    params.require_lossless("a nonlinear normal mode")
    mode = whole("mode", mode, 1, 2, what="1: the lower linear frequency, 2: the higher")
    try:
        grid = np.array([a.item() if hasattr(a, "item") else a for a in list(alphas)], dtype=float)
        if any(isinstance(a, (bool, str, bytes)) for a in list(alphas)):
            raise TypeError
    except (TypeError, ValueError):
        raise ParameterError(f"alphas must be at least two angles [rad], got {alphas!r}") from None
    if grid.ndim != 1 or grid.size < 2 or not np.all(np.isfinite(grid)) or np.any(np.abs(grid) > ANGLE_LIMIT) or \
            np.any(np.diff(grid) == 0) or not (np.all(np.diff(grid) > 0) or np.all(np.diff(grid) < 0)):
        raise ParameterError(f"alphas must be at least two finite angles [rad] of at most {ANGLE_LIMIT:g} in magnitude, "
                             "strictly increasing or decreasing")
    progress = progress_callable(progress, "progress(done, total)")
    energy = _energy_limit(replace(params, alpha=float(grid[0])), "energy", energy, mode=mode)
    start = nnm(replace(params, alpha=float(grid[0])), mode=mode, energy_max=energy, rtol=rtol, atol=atol)
    if not start.ok:
        raise IntegrationError(f"the family at alpha = {grid[0]:.6g} rad does not reach {energy:g} J: {start.message}")
    x, T = start.states[-1].copy(), float(start.periods[-1])
    alphas_done, periods, states, sigma = [float(grid[0])], [T], [x.copy()], [float(np.trace(start.monodromies[-1]) - 2)]
    status, message = Status.SUCCESS, ""
    calls = 0
    with Interrupts() as intr:
        k = 1
        a_prev = float(grid[0])
        target = float(grid[1])
        while k < len(grid):
            a = target
            q = replace(params, alpha=a)
            model = _Model(q, rtol, atol)  # each angle is met once
            scales = _scales_for(q, T, energy)
            out = _newton(model, x, T, energy, np.zeros(4), x, scales, check=intr.check,
                          progress=lambda it, _n, a=a: _say(f"alpha = {math.degrees(a):.4g} deg: Newton iteration {it}"))
            calls += model.calls
            if out is None:
                h = (a - a_prev) / 2
                if abs(h) < 1e-6:
                    status = Status.NO_CONVERGENCE
                    message = f"the continuation stopped at alpha = {math.degrees(a_prev):.6g} deg: Newton failed at the next angle"
                    break
                target = a_prev + h
                continue
            x, T = out[0], out[1]
            if a == float(grid[k]):
                alphas_done.append(a), periods.append(T), states.append(x.copy())
                sigma.append(float(np.trace(out[3].stm) - 2))
                if progress is not None:
                    progress(k, len(grid) - 1)
                k += 1
            a_prev = a
            target = float(grid[k]) if k < len(grid) else a
    events = _alpha_events(alphas_done, 2 * np.pi / np.array(periods), np.array(sigma), energy)
    if status == Status.SUCCESS:
        message = f"{len(alphas_done)} orbits at E = {energy:g} J from alpha = {math.degrees(grid[0]):.4g} to {math.degrees(grid[-1]):.4g} deg"
    settings = {"mode": int(mode), "energy": energy, "alphas": grid.tolist(), "rtol": rtol, "atol": atol}
    return AlphaFamily(mode=int(mode), energy=energy, alphas=alphas_done, periods=periods, states=states, sigma=sigma,
                       events=events, params=params, settings=settings, stats={"orbits": len(alphas_done), "flows": calls},
                       status=status, message=message)
