"""Small oscillations about the hanging equilibrium: normal modes and how they depend on α.

From the linearised equations ``M0 q'' + C0 q' + K0 q = 0`` of
:meth:`skewpend.EquationsOfMotion.linearize`:

* :func:`normal_modes` -- natural frequencies, periods, M0-normalised mode shapes,
  the beat period, the closed-form linear response to a small initial state, and,
  with joint damping, the complex eigenvalues, damped frequencies and damping ratios;
* :func:`characteristic_equation` -- ``det(K0 - w^2 M0) = 0`` and its two roots in
  closed form (SymPy), in α and the parameters;
* :func:`sweep` -- the modes along a parameter (α, a length, a mass or a ratio), with
  internal resonances ``w2/w1 ~ 1, 2, 3`` located.

The linear matrices are derived once per body geometry and evaluated numerically.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from functools import lru_cache
from typing import Callable, Dict, List, Optional, Sequence, Tuple

import numpy as np

from .errors import EquilibriumError, ParameterError
from .model import SCALAR_NAMES, Parameters

__all__ = [
    "Modes",
    "normal_modes",
    "linear_matrices",
    "characteristic_equation",
    "Sweep",
    "Resonance",
    "sweep",
    "parse_sweep",
    "SWEEPABLE",
]


# -- the linear matrices, numerically -------------------------------------------------------------
@lru_cache(maxsize=32)
def _matrix_function(geometry: Parameters) -> Callable:
    import sympy as sp

    from .derivation import SYMBOLS, derive

    lin = derive(geometry).linearize()
    args = [SYMBOLS[n] for n in SCALAR_NAMES]
    return sp.lambdify(args, [lin.M, lin.C, lin.K], "numpy")


def _geometry(params: Parameters) -> Parameters:
    keep = ("com1", "com2", "inertia1", "inertia2", "axis1", "axis2")
    return Parameters(
        **{k: getattr(params, k) for k in keep},
        **{k: None for k in SCALAR_NAMES if k not in ("tau1", "tau2")},
        tau1=0.0,
        tau2=0.0,
    )


def linear_matrices(params: Parameters) -> Tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Numeric ``(M0, C0, K0)`` (2x2 each, SI units) of the linearisation about ``q = 0``."""
    params.require_numeric("normal modes")
    if params.tau1 or params.tau2:
        raise EquilibriumError(
            "phi = psi = 0 is not an equilibrium with constant joint torques; normal modes need tau1 = tau2 = 0"
        )
    f = _matrix_function(_geometry(params))
    values = [0.0 if (n == "alpha" and not params.uses_alpha) else float(getattr(params, n)) for n in SCALAR_NAMES]
    M, C, K = (np.array(x, dtype=float) for x in f(*values))
    return M, C, K


# -- normal modes -------------------------------------------------------------------------------------
@dataclass(frozen=True)
class Modes:
    """Normal modes of the small oscillations about the hanging equilibrium.

    * ``frequencies`` -- natural (undamped) angular frequencies ``w_k`` [rad/s], ascending, (2,);
    * ``periods`` -- ``2 pi / w_k`` [s], (2,);
    * ``shapes`` -- mode shapes as columns ``[phi, psi]`` normalised so ``v_k^T M0 v_k = 1``
      (sign: the larger component positive), (2, 2);
    * ``ratios`` -- amplitude ratio ``psi/phi`` of each mode (``inf`` when phi does not move);
    * ``beat_period`` -- ``2 pi / (w2 - w1)`` [s] (``inf`` at a 1:1 resonance);
    * ``eigenvalues`` -- with damping, the state-space eigenvalues with positive imaginary part
      (or real, overdamped), one per mode; ``damped_frequencies`` [rad/s] and
      ``damping_ratios`` follow from them (undamped: ``w_k`` and 0);
    * ``M``, ``C``, ``K`` -- the linear matrices; ``params``.
    """

    frequencies: np.ndarray
    periods: np.ndarray
    shapes: np.ndarray
    ratios: np.ndarray
    beat_period: float
    eigenvalues: np.ndarray
    damped_frequencies: np.ndarray
    damping_ratios: np.ndarray
    M: np.ndarray
    C: np.ndarray
    K: np.ndarray
    params: Parameters = field(repr=False)

    def modal_coordinates(self, q: np.ndarray) -> np.ndarray:
        """``eta = V^T M0 q`` for angles ``q`` of shape (..., 2)."""
        return np.asarray(q) @ (self.M @ self.shapes)

    def decompose(self, q0: Sequence[float], dq0: Sequence[float]) -> Dict[str, np.ndarray]:
        """Modal amplitudes and phases of a small initial state (undamped linear solution).

        ``q(t) = sum_k v_k A_k cos(w_k t - delta_k)``; returns ``amplitude`` (A_k) and
        ``phase`` (delta_k) [rad], each (2,).
        """
        a = self.modal_coordinates(np.asarray(q0, float))
        b = self.modal_coordinates(np.asarray(dq0, float)) / self.frequencies
        return {"amplitude": np.hypot(a, b), "phase": np.arctan2(b, a)}

    def linear_response(self, q0: Sequence[float], dq0: Sequence[float], t: np.ndarray) -> np.ndarray:
        """Closed-form solution of the undamped linear equations: states ``(phi, psi, dphi, dpsi)``
        at the times ``t`` (n,) -> (n, 4)."""
        t = np.asarray(t, float)[:, None]
        a = self.modal_coordinates(np.asarray(q0, float))
        b = self.modal_coordinates(np.asarray(dq0, float))
        w = self.frequencies
        eta = a * np.cos(w * t) + b / w * np.sin(w * t)
        deta = -a * w * np.sin(w * t) + b * np.cos(w * t)
        return np.hstack([eta @ self.shapes.T, deta @ self.shapes.T])

    def to_dict(self) -> Dict:
        """The JSON form: ``frequencies`` (rad/s, ascending), ``periods`` (s), ``mode_shapes``
        (list of [phi, psi] vectors), and more."""
        damped = bool(np.any(self.C != 0))
        d = {
            "frequencies": self.frequencies.tolist(),
            "periods": self.periods.tolist(),
            "mode_shapes": self.shapes.T.tolist(),
            "amplitude_ratios_psi_over_phi": [None if not np.isfinite(r) else float(r) for r in self.ratios],
            "beat_period": None if not np.isfinite(self.beat_period) else float(self.beat_period),
            "frequency_ratio": float(self.frequencies[1] / self.frequencies[0]),
            "M0": self.M.tolist(),
            "K0": self.K.tolist(),
        }
        if damped:
            d["C0"] = self.C.tolist()
            d["eigenvalues"] = [[float(z.real), float(z.imag)] for z in self.eigenvalues]
            d["damped_frequencies"] = self.damped_frequencies.tolist()
            d["damping_ratios"] = self.damping_ratios.tolist()
        return d


def _modes_from_matrices(M: np.ndarray, C: np.ndarray, K: np.ndarray, params: Parameters) -> Modes:
    from scipy.linalg import eigh

    lam, V = eigh(K, M)
    if lam[0] <= 1e-12 * max(abs(lam[1]), 1e-300):
        raise EquilibriumError(
            f"the hanging position is not a stable equilibrium (w^2 = {lam.tolist()}); normal modes need g > 0"
        )
    for k in range(2):
        col = V[:, k]
        col[np.abs(col) < 1e-13 * np.abs(col).max()] = 0.0  # round-off where a hinge stands still
        if col[np.argmax(np.abs(col))] < 0:
            V[:, k] = -col
    w = np.sqrt(lam)
    with np.errstate(divide="ignore"):
        ratios = np.where(np.abs(V[0]) > 1e-14 * np.abs(V).max(), V[1] / np.where(V[0] == 0, 1, V[0]), np.inf)
        beat = 2 * np.pi / (w[1] - w[0]) if w[1] > w[0] else np.inf
    if np.any(C != 0):
        Minv = np.linalg.inv(M)
        A = np.block([[np.zeros((2, 2)), np.eye(2)], [-Minv @ K, -Minv @ C]])
        ev = np.linalg.eigvals(A)
        # one eigenvalue per mode: the upper half plane; overdamped pairs are real
        ev = ev[np.argsort(np.abs(ev))]
        chosen: List[complex] = []
        for z in ev:
            if z.imag > 0 or (abs(z.imag) < 1e-12 * abs(z) and len(chosen) < 2):
                chosen.append(z)
        eig = np.array(sorted(chosen, key=abs)[:2])
        damped_w = np.abs(eig.imag)
        zeta = -eig.real / np.abs(eig)
    else:
        eig = 1j * w
        damped_w = w.copy()
        zeta = np.zeros(2)
    return Modes(
        frequencies=w,
        periods=2 * np.pi / w,
        shapes=V,
        ratios=ratios,
        beat_period=float(beat),
        eigenvalues=eig,
        damped_frequencies=damped_w,
        damping_ratios=zeta,
        M=M,
        C=C,
        K=K,
        params=params,
    )


def normal_modes(params: Parameters) -> Modes:
    """Normal modes of the numeric model ``params`` about ``phi = psi = 0``.

    Raises :class:`~skewpend.errors.EquilibriumError` when the hanging position is not an
    equilibrium (torques, offset centres of mass) or not stable (``g = 0``).
    """
    M, C, K = linear_matrices(params)
    return _modes_from_matrices(M, C, K, params)


# -- closed form ------------------------------------------------------------------------------------
def characteristic_equation(params: Optional[Parameters] = None):
    """``det(K0 - w^2 M0) = 0`` in closed form, and its roots ``w^2``.

    Returns ``(equation, (w2_low, w2_high))`` as SymPy objects in the symbol ``omega``
    and the parameters left symbolic (default: all, thin rods).  The equation is
    ``det(K0 - w^2 M0)`` divided by its constant content, ``A w^4 + B w^2 + D = 0``; the
    roots are ``(-B -/+ sqrt(B^2 - 4 A D)) / (2 A)``.
    """
    import sympy as sp

    from .derivation import derive

    lin = derive(params if params is not None else Parameters()).linearize()
    M, K = lin.M, lin.K
    w = sp.Symbol("omega", positive=True)
    lam = sp.Symbol("lam")
    # det(K - lam M) as a polynomial in lam = omega**2, with its content divided out
    poly = sp.Poly(sp.expand((K - lam * M).det()), lam)
    content, prim = poly.primitive()
    A, B, D = (sp.factor(c) for c in prim.all_coeffs())  # A lam^2 + B lam + D
    equation = sp.Eq(A * w**4 + B * w**2 + D, 0)
    disc = sp.factor(sp.expand(B**2 - 4 * A * D))
    roots = tuple(sp.factor_terms((-B + sign * sp.sqrt(disc)) / (2 * A)) for sign in (-1, 1))
    return equation, roots


# -- sweeps -----------------------------------------------------------------------------------------
#: What ``sweep`` can vary: a parameter, or a ratio (the numerator is scaled, the denominator kept).
SWEEPABLE = ("alpha", "a", "b", "m1", "m2", "g", "b/a", "m2/m1")


def parse_sweep(spec: str) -> Tuple[str, np.ndarray]:
    """``"alpha=0:180deg:181"`` -> ``("alpha", values in radians)``; ``"b/a=0.2:5:100"``."""
    from .parsing import parse_scalar  # the same number syntax as the options

    if "=" not in spec:
        raise ParameterError(f"--sweep: expected NAME=START:STOP:COUNT (e.g. alpha=0:180deg:181), got {spec!r}")
    name, rng = (x.strip() for x in spec.split("=", 1))
    if name not in SWEEPABLE:
        raise ParameterError(f"--sweep: cannot sweep {name!r}; allowed: {', '.join(SWEEPABLE)}")
    parts = rng.split(":")
    if len(parts) != 3:
        raise ParameterError(f"--sweep: expected START:STOP:COUNT, got {rng!r}")
    start, stop, count = parts
    if stop.strip().lower().endswith("deg") and not start.strip().lower().endswith("deg"):
        start = start + "deg"
    angle = name == "alpha"
    lo = parse_scalar(start, "--sweep start", angle=angle)
    hi = parse_scalar(stop, "--sweep stop", angle=angle)
    try:
        n = int(count)
    except ValueError:
        raise ParameterError(f"--sweep: COUNT must be a whole number, got {count!r}") from None
    if lo is None or hi is None or not 2 <= n <= 100_000:
        raise ParameterError(f"--sweep: need numeric START, STOP and 2 <= COUNT <= 100000, got {rng!r}")
    return name, np.linspace(lo, hi, n)


def _with_value(params: Parameters, name: str, value: float, base: Parameters) -> Parameters:
    if name == "b/a":
        return params.replace(b=value * base.a)
    if name == "m2/m1":
        return params.replace(m2=value * base.m1)
    return params.replace(**{name: value})


@dataclass(frozen=True)
class Resonance:
    """An internal resonance ``w2/w1 ~ n`` along a sweep: where it is closest (or crossed)."""

    order: int
    value: float  # the swept variable there (radians for alpha)
    ratio: float  # w2/w1 there
    crossed: bool  # the ratio passes through n (exact resonance, interpolated)


@dataclass(frozen=True)
class Sweep:
    """Modes along a swept variable: ``values`` (n,), ``frequencies`` (n, 2) [rad/s],
    ``shapes`` (n, 2, 2) (columns = modes), ``ratios`` (n, 2) psi/phi, ``resonances``."""

    name: str
    values: np.ndarray
    frequencies: np.ndarray
    shapes: np.ndarray
    ratios: np.ndarray
    resonances: List[Resonance]
    tolerance: float
    params: Parameters = field(repr=False)

    @property
    def frequency_ratio(self) -> np.ndarray:
        return self.frequencies[:, 1] / self.frequencies[:, 0]

    def table(self) -> Tuple[List[str], np.ndarray]:
        """Columns and rows for CSV output."""
        cols = [
            self.name, "omega1", "omega2", "period1", "period2", "omega2_over_omega1",
            "mode1_phi", "mode1_psi", "mode2_phi", "mode2_psi",
        ]
        rows = np.column_stack([
            self.values, self.frequencies, 2 * np.pi / self.frequencies, self.frequency_ratio,
            self.shapes[:, :, 0], self.shapes[:, :, 1],
        ])
        return cols, rows

    def to_dict(self) -> Dict:
        cols, rows = self.table()
        return {
            "swept": self.name,
            "columns": cols,
            "rows": rows.tolist(),
            "resonance_tolerance": self.tolerance,
            "resonances": [r.__dict__ for r in self.resonances],
        }


def _resonances(values: np.ndarray, ratio: np.ndarray, tol: float) -> List[Resonance]:
    found: List[Resonance] = []
    for n in (1, 2, 3):
        d = ratio - n
        # exact crossings, interpolated
        for i in np.nonzero(np.sign(d[:-1]) * np.sign(d[1:]) < 0)[0]:
            s = d[i] / (d[i] - d[i + 1])
            found.append(Resonance(n, float(values[i] + s * (values[i + 1] - values[i])), float(n), True))
        # near approaches: local minima of |d| within tolerance (relative to n), not at a crossing
        near = np.abs(d) <= tol * n
        i = 0
        while i < len(values):
            if not near[i]:
                i += 1
                continue
            j = i
            while j + 1 < len(values) and near[j + 1]:
                j += 1
            k = i + int(np.argmin(np.abs(d[i : j + 1])))
            lo, hi = sorted((values[max(i - 1, 0)], values[min(j + 1, len(values) - 1)]))
            if not any(r.order == n and r.crossed and lo <= r.value <= hi for r in found):
                found.append(Resonance(n, float(values[k]), float(ratio[k]), False))
            i = j + 1
    return sorted(found, key=lambda r: (r.value, r.order))


def sweep(params: Parameters, name: str, values: Sequence[float], *, tolerance: float = 0.01) -> Sweep:
    """Normal modes of ``params`` with ``name`` (see :data:`SWEEPABLE`) set to each of ``values``.

    Resonances ``w2/w1 = n`` (n = 1, 2, 3) are reported where the ratio crosses ``n``
    (interpolated) or comes within ``tolerance * n`` of it.
    """
    if name not in SWEEPABLE:
        raise ParameterError(f"cannot sweep {name!r}; allowed: {', '.join(SWEEPABLE)}")
    values = np.asarray(values, float)
    if values.ndim != 1 or values.size < 2 or not np.all(np.isfinite(values)):
        raise ParameterError("sweep values must be at least 2 finite numbers")
    probe = _with_value(params, name, float(values[0]), params)
    probe.require_numeric("a sweep")
    freqs = np.empty((values.size, 2))
    shapes = np.empty((values.size, 2, 2))
    ratios = np.empty((values.size, 2))
    for i, v in enumerate(values):
        m = normal_modes(_with_value(params, name, float(v), params))
        freqs[i], shapes[i], ratios[i] = m.frequencies, m.shapes, m.ratios
    ratio = freqs[:, 1] / freqs[:, 0]
    return Sweep(name, values, freqs, shapes, ratios, _resonances(values, ratio, tolerance), tolerance, params)


# -- linear versus nonlinear ---------------------------------------------------------------------------
@dataclass(frozen=True)
class NonlinearCheck:
    """Frequencies measured on the full nonlinear equations started from each mode shape."""

    amplitude: float  # largest initial angle [rad]
    linear: np.ndarray  # (2,) rad/s
    measured: np.ndarray  # (2,) rad/s
    cycles: np.ndarray  # (2,) cycles used

    @property
    def relative_shift(self) -> np.ndarray:
        return self.measured / self.linear - 1


def _zero_crossing_frequency(t: np.ndarray, x: np.ndarray) -> Tuple[float, int]:
    up = np.nonzero((x[:-1] < 0) & (x[1:] >= 0))[0]
    if up.size < 3:
        raise ParameterError("too few oscillations to measure a frequency; increase the duration")
    tc = t[up] - x[up] * (t[up + 1] - t[up]) / (x[up + 1] - x[up])
    # cubic refinement would need derivatives; the grid is fine enough (dt = T/400)
    return 2 * np.pi * (up.size - 1) / (tc[-1] - tc[0]), int(up.size - 1)


def check_nonlinear(params: Parameters, amplitude: float, *, cycles: int = 40) -> NonlinearCheck:
    """Start the nonlinear equations from each mode shape scaled so its largest angle is
    ``amplitude`` [rad], at rest; measure the frequency of the modal coordinate by upward
    zero crossings (linearly interpolated) over ``cycles`` periods."""
    from .integrate import simulate

    if not (math.isfinite(amplitude) and 0 < amplitude < math.pi):
        raise ParameterError(f"amplitude must be in (0, pi) rad, got {amplitude!r}")
    modes = normal_modes(params)
    measured = np.empty(2)
    used = np.empty(2, dtype=int)
    for k in range(2):
        v = modes.shapes[:, k]
        q0 = amplitude * v / np.max(np.abs(v))
        T = modes.periods[k]
        tr = simulate(params, (q0[0], q0[1], 0.0, 0.0), cycles * T, dt_out=T / 400, rtol=1e-11, atol=1e-12, throw=True)
        eta = modes.modal_coordinates(tr.y[:, :2])[:, k]
        measured[k], used[k] = _zero_crossing_frequency(tr.t, eta)
    return NonlinearCheck(float(amplitude), modes.frequencies.copy(), measured, used)
