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

The linear matrices are derived once per body geometry and evaluated numerically.  Coulomb
friction is left out of them by default, as non-smooth at rest (``coulomb="exclude"``; see
:mod:`skewpend.symbolic.friction`); ``coulomb="smoothed"`` linearises its smoothed form.
"""

from __future__ import annotations

import itertools
import math
from dataclasses import dataclass, field
from functools import lru_cache
from typing import Any, Callable, ClassVar, Dict, Iterable, List, Optional, Sequence, Tuple

import numpy as np

from ..errors import EquilibriumError, NotNumericError, ParameterError, SkewpendError
from ..results import DatasetSpec, ResultProtocol, agree, netcdf_reader, protocol_fields
from ..status import Status
from ..symbolic.friction import DEFAULT_COULOMB, check_coulomb, coulomb_note, friction_terms
from ..schema import CORE_NAMES, DAMPING_NAMES, GEOMETRY_NAMES, LENGTH_NAMES, MASS_NAMES, TORQUE_NAMES, names, unit
from ..symbolic.model import SCALAR_NAMES, Parameters

__all__ = [
    "Modes",
    "normal_modes",
    "chain_modes",
    "pairs_of_chain",
    "linear_matrices",
    "characteristic_equation",
    "Sweep",
    "Resonance",
    "sweep",
    "parse_sweep",
    "SWEEPABLE",
]


class NotFinite(ParameterError):
    """A result of the modes is not a finite number (``reason`` is a short phrase); the modes
    turn it into one message naming the parameters."""

    def __init__(self, reason: str) -> None:
        super().__init__(reason)
        self.reason = reason



# -- the linear matrices, numerically -------------------------------------------------------------
@lru_cache(maxsize=32)
def _matrix_function(geometry: Parameters) -> Callable:
    from ..numeric.pyfunctions import cached_lambdify

    def build():
        from ..symbolic.derivation import SYMBOLS, derive

        # C with Coulomb friction's smoothed slope cfs cf: _matrices evaluates it at cf = 0 to exclude it
        lin = derive(geometry).linearize(coulomb="smoothed")
        return [SYMBOLS[n] for n in SCALAR_NAMES], [lin.M, lin.C, lin.K]

    return cached_lambdify("linear_matrices", "analysis/modes.py", geometry, build)


def _geometry(params: Parameters) -> Parameters:
    return Parameters(
        **{k: getattr(params, k) for k in GEOMETRY_NAMES},
        **{k: None for k in SCALAR_NAMES if k not in TORQUE_NAMES},
        **{k: 0.0 for k in TORQUE_NAMES},
    )


def _describe(model) -> str:
    """The model's values in its own names: the facade's scalars where it answers them, else its links'."""
    shown = [(n, getattr(model, n, None)) for n in CORE_NAMES + DAMPING_NAMES if n != "alpha" or getattr(model, "uses_alpha", False)]
    if all(v is not None for _, v in shown):
        return ", ".join(f"{n} = {v:g}" for n, v in shown if isinstance(v, float))
    links = model.as_chain().links
    return ", ".join(f"{what} = ({', '.join(f'{getattr(link, key):g}' for link in links)})"
                     for what, key in (("lengths", "length"), ("masses", "mass"), ("damping", "damping"))) + f", g = {model.g:g}"


def _not_finite_message(exc: "NotFinite", params: Parameters) -> str:
    return (
        f"normal modes: {exc.reason} for {_describe(params)}; allowed: parameters of moderate size, for which M0, "
        "C0, K0, the eigenvalues and their squares are finite, normal double-precision numbers (about 1e-150 .. 1e150)"
    )


def _require_finite(**arrays: np.ndarray) -> None:
    """Raise :class:`NotFinite` naming the first array (keyword = its name) with a non-finite entry."""
    for name, x in arrays.items():
        if not np.all(np.isfinite(np.asarray(x))):
            plural = name.startswith("the ") and name.endswith("s")
            raise NotFinite(f"{name} {'are' if plural else 'is'} not finite (overflow)")


def _matrices(params, coulomb: str = DEFAULT_COULOMB) -> Tuple[np.ndarray, np.ndarray, np.ndarray]:
    """``(M0, C0, K0)`` about ``q = 0`` from the cheapest printer the model provides (a strategy by what it
    provides, as :mod:`~skewpend.analysis.equilibria` picks): the exact derivation where the model keeps its
    bodies' geometry apart from its scalars (one generated function, cached on disk, serves every value), else
    the recursive algorithms' exact derivatives (CasADi; a chain's values are numeric data)."""
    params.require_numeric("normal modes")
    exact = params.exact_model()  # the parameters the exact derivation prints, or None: the recursive algorithms
    if exact is None:
        from ..numeric.recursive import linear_matrices as recursive_matrices

        with np.errstate(all="ignore"):
            M, C, K = recursive_matrices(params.as_chain(), coulomb)
    else:
        params, geometry = exact, _geometry(exact)
        if any(getattr(params, n) for n in TORQUE_NAMES):
            raise EquilibriumError(f"{' = '.join(params.coordinates)} = 0 is not an equilibrium with constant joint "
                                   f"torques; normal modes need {' = '.join(TORQUE_NAMES)} = 0")
        f = _matrix_function(geometry)
        # Coulomb friction enters C0 only (its slope cfs cf); excluded, it is evaluated at cf = 0
        left_out = () if coulomb == "smoothed" else names(stem="cf")
        values = [
            np.float64(0.0 if (n == "alpha" and not params.uses_alpha) or n in left_out else float(getattr(params, n)))
            for n in SCALAR_NAMES
        ]
        with np.errstate(all="ignore"):
            try:
                M, C, K = (np.array(x, dtype=float) for x in f(*values))
            except (OverflowError, ZeroDivisionError, FloatingPointError):
                raise NotFinite("the linear matrices M0, C0, K0 are not finite (overflow)") from None
    _require_finite(M0=M, C0=C, K0=K)
    tiny = np.finfo(float).tiny
    for name, X in (("M0", M), ("K0", K), ("C0", C)):
        if np.any((X != 0) & (np.abs(X) < tiny)):
            raise NotFinite(f"{name} underflows (entries below {tiny:.3g})")
    return M, C, K


def linear_matrices(params: Parameters, coulomb: str = DEFAULT_COULOMB) -> Tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Numeric ``(M0, C0, K0)`` (n x n each, SI units) of the linearisation about ``q = 0``
    (Coulomb friction in ``C0`` only with ``coulomb="smoothed"``, see :func:`normal_modes`).

    Raises :class:`~skewpend.errors.ParameterError` when they are not finite (overflow).
    """
    coulomb = check_coulomb(coulomb)
    try:
        return _matrices(params, coulomb)
    except NotFinite as exc:
        raise ParameterError(_not_finite_message(exc, params)) from None


# -- normal modes -------------------------------------------------------------------------------------
@dataclass(frozen=True)
class Modes(ResultProtocol):
    """Normal modes of the small oscillations about an equilibrium (the hanging one by default).

    (``n`` modes of a model with ``n`` coordinates, ``model.coordinates``: ``phi, psi`` for the double pendulum)

    * ``frequencies`` -- natural (undamped) angular frequencies ``w_k`` [rad/s], ascending, (n,);
    * ``periods`` -- ``2 pi / w_k`` [s], (n,);
    * ``shapes`` -- mode shapes as columns over the coordinates normalised so ``v_k^T M0 v_k = 1``
      (sign: the larger component positive), (n, n);
    * ``ratios`` -- amplitude ratio of the last coordinate over the first of each mode (``psi/phi``;
      ``inf`` when the first does not move);
    * ``beat_period`` -- ``2 pi / (w2 - w1)`` [s] (``inf`` at a 1:1 resonance);
    * ``eigenvalue_pairs`` -- (n, 2) complex: the two state-space eigenvalues of each mode,
      row k for undamped mode k.  The 2n eigenvalues of ``l^2 M0 + l C0 + K0`` are given to
      the undamped modes by their *shapes*: the displacement part ``x`` of each eigenvector is
      compared with the undamped shapes by the M0-weighted similarity
      ``|v_k^T M0 x| / sqrt(x^H M0 x)`` (1 = same shape), and the split of the four
      eigenvalues into n pairs (complex conjugates stay together) with the largest total
      similarity is taken.  An underdamped mode has a conjugate pair (positive imaginary part
      first), an overdamped mode two negative real eigenvalues (the slower first);
    * ``eigenvalues`` -- one per mode: the first of its pair (undamped: ``i w_k``);
    * ``damped_frequencies`` -- ``|Im l|`` [rad/s] (0 for an overdamped mode);
    * ``damping_ratios`` -- ``zeta_k = -(l1 + l2) / (2 sqrt(l1 l2))`` over the mode's pair:
      ``-Re l / |l|`` for a conjugate pair (underdamped, < 1) and
      ``(|l1| + |l2|) / (2 sqrt(l1 l2))`` for two real eigenvalues (overdamped, >= 1); for a
      single degree of freedom ``m x'' + c x' + k x = 0`` both are ``c / (2 sqrt(k m))``.
      Undamped: 0;
    * ``M``, ``C``, ``K`` -- the linear matrices; ``state_matrix`` -- the 4 x 4 matrix of
      ``(dq, dq')``; ``params``;
    * ``coulomb`` -- how Coulomb friction entered ``C`` (``"exclude"``: not at all, the default,
      as it is non-smooth at rest; ``"smoothed"``: its smoothed slope ``cfs cf``);
      ``coulomb_note`` says it in one line ('' without Coulomb friction), and ``message`` and
      ``summary()`` include it;
    * ``equilibrium`` -- the coordinates [rad] the modes are about; ``growth_rates`` [1/s] --
      0 for an oscillating mode; about an unstable equilibrium (``normal_modes(params,
      about=...)``) a mode along which a disturbance grows like ``exp(s t)`` has growth rate
      ``s > 0``, frequency 0 and period ``inf`` (its eigenvalue pair is real, ``+s`` first) --
      never an imaginary frequency;
    * the result protocol: ``settings`` (the equilibrium), ``stats`` (empty), ``status``
      (always SUCCESS: what cannot be computed is refused), ``ok``, ``message``, ``to_xarray()``,
      ``to_netcdf()``, ``summary()``.
    """

    frequencies: np.ndarray
    periods: np.ndarray
    shapes: np.ndarray
    ratios: np.ndarray
    beat_period: float
    eigenvalues: np.ndarray
    damped_frequencies: np.ndarray
    damping_ratios: np.ndarray
    eigenvalue_pairs: np.ndarray
    M: np.ndarray
    C: np.ndarray
    K: np.ndarray
    params: Parameters = field(repr=False)
    growth_rates: np.ndarray = field(default_factory=lambda: np.zeros(2))
    equilibrium: Tuple[float, ...] = (0.0, 0.0)
    coulomb: str = DEFAULT_COULOMB

    result_kind: ClassVar[str] = "normal modes"
    status: ClassVar[Status] = Status.SUCCESS

    @property
    def coulomb_note(self) -> str:
        """How the Coulomb friction was treated, one line ('' for a model without it)."""
        return coulomb_note(self.params, self.coulomb)

    @property
    def message(self) -> str:
        if not any(self.equilibrium):
            text = "the modes of the linearised equations about the hanging equilibrium"
        else:
            text = ("the modes of the linearised equations about the equilibrium "
                    + ", ".join(f"{c} = {x:.6g}" for c, x in zip(self.params.coordinates, self.equilibrium)) + " rad")
        note = self.coulomb_note
        return f"{text}; {note}" if note else text

    @property
    def unstable(self) -> np.ndarray:
        """(n,) bool: the mode grows (a saddle direction of the potential)."""
        return self.growth_rates > 0

    @property
    def state_matrix(self) -> np.ndarray:
        """``[[0, I], [-M^-1 K, -M^-1 C]]``: ``d/dt (dq, dq') = A (dq, dq')``."""
        Minv = np.linalg.inv(self.M)
        n = self.M.shape[0]
        return np.block([[np.zeros((n, n)), np.eye(n)], [-Minv @ self.K, -Minv @ self.C]])

    @property
    def settings(self) -> Dict:
        settings: Dict = {"equilibrium": [float(x) for x in self.equilibrium]}
        if friction_terms(self.params):  # only where it matters (a model without friction keeps its fingerprint)
            settings["coulomb"] = self.coulomb
        return settings

    @property
    def stats(self) -> Dict:
        return {}

    def _dataset(self) -> DatasetSpec:
        pairs = self.eigenvalue_pairs
        return DatasetSpec(
            variables={
                "frequency": (("mode",), self.frequencies, {"units": "rad/s", "long_name": "natural angular frequency"}),
                "period": (("mode",), self.periods, {"units": "s"}),
                "shape": (("coordinate", "mode"), self.shapes, {"long_name": "mode shape, v^T M0 v = 1; rows " + ", ".join(self.params.coordinates)}),
                "damping_ratio": (("mode",), self.damping_ratios, {"units": "1"}),
                "damped_frequency": (("mode",), self.damped_frequencies, {"units": "rad/s"}),
                "eigenvalue_real": (("mode", "pair"), pairs.real, {"units": "1/s"}),
                "eigenvalue_imag": (("mode", "pair"), pairs.imag, {"units": "1/s"}),
                "M0": (("coordinate", "coordinate_2"), self.M, {"long_name": "linear mass matrix"}),
                "C0": (("coordinate", "coordinate_2"), self.C, {"long_name": "linear damping matrix"}),
                "K0": (("coordinate", "coordinate_2"), self.K, {"long_name": "linear stiffness matrix"}),
                "growth_rate": (("mode",), self.growth_rates, {"units": "1/s", "long_name": "growth rate (0: oscillating)"}),
            },
            coords={"mode": (("mode",), np.arange(1, len(self.frequencies) + 1), {})},
            attrs={"title": "normal modes (skewpend)", **self._base_attrs()},
        )

    @property
    def damped(self) -> bool:
        return bool(np.any(self.C != 0))

    @property
    def overdamped(self) -> np.ndarray:
        """(n,) bool: the mode's two eigenvalues are real (no oscillation)."""
        return self.damped & (self.eigenvalue_pairs[:, 0].imag == 0)

    def modal_coordinates(self, q: np.ndarray) -> np.ndarray:
        """``eta = V^T M0 q`` for angles ``q`` of shape (..., 2)."""
        return np.asarray(q) @ (self.M @ self.shapes)

    def decompose(self, q0: Sequence[float], dq0: Sequence[float]) -> Dict[str, np.ndarray]:
        """Modal amplitudes and phases of a small initial state (undamped linear solution).

        ``q(t) = sum_k v_k A_k cos(w_k t - delta_k)``; returns ``amplitude`` (A_k) and
        ``phase`` (delta_k) [rad], each (n,).  About an unstable equilibrium there is no such
        form (a growing mode has no phase): refused.
        """
        if np.any(self.unstable):
            raise EquilibriumError("decompose: a growing mode has no amplitude and phase; use linear_response")
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
        s = self.growth_rates
        with np.errstate(all="ignore"):
            # an oscillating mode: cos and sin; a growing one: cosh and sinh (of its growth rate)
            eta = np.where(s > 0, a * np.cosh(s * t) + b / np.where(s > 0, s, 1) * np.sinh(s * t),
                           a * np.cos(w * t) + b / np.where(w > 0, w, 1) * np.sin(w * t))
            deta = np.where(s > 0, a * s * np.sinh(s * t) + b * np.cosh(s * t), -a * w * np.sin(w * t) + b * np.cos(w * t))
        return np.hstack([eta @ self.shapes.T, deta @ self.shapes.T])

    def to_dict(self) -> Dict:
        """The JSON form: ``frequencies`` (rad/s, ascending), ``periods`` (s), ``mode_shapes``
        (list of [phi, psi] vectors), and more; with damping ``eigenvalues`` (one
        ``[re, im]`` per mode), ``eigenvalue_pairs`` (both of each mode), ``overdamped``,
        ``damped_frequencies`` and ``damping_ratios`` (see :class:`Modes`)."""
        d = {
            "frequencies": self.frequencies.tolist(),
            "periods": [None if not np.isfinite(x) else float(x) for x in self.periods],
            "mode_shapes": self.shapes.T.tolist(),
            f"amplitude_ratios_{self.params.coordinates[-1]}_over_{self.params.coordinates[0]}": [None if not np.isfinite(r) else float(r) for r in self.ratios],
            "beat_period": None if not np.isfinite(self.beat_period) else float(self.beat_period),
            "frequency_ratio": float(self.frequencies[1] / self.frequencies[0]) if len(self.frequencies) > 1 and self.frequencies[0] > 0 else None,
            "M0": self.M.tolist(),
            "K0": self.K.tolist(),
            "equilibrium": [float(x) for x in self.equilibrium],
            "growth_rates": self.growth_rates.tolist(),
        }
        if self.coulomb_note:
            d["coulomb"] = self.coulomb
            d["coulomb_note"] = self.coulomb_note
        if self.damped:
            d["C0"] = self.C.tolist()
            d["eigenvalues"] = [[float(z.real), float(z.imag)] for z in self.eigenvalues]
            d["eigenvalue_pairs"] = [[[float(z.real), float(z.imag)] for z in pair] for pair in self.eigenvalue_pairs]
            d["overdamped"] = [bool(x) for x in self.overdamped]
            d["damped_frequencies"] = self.damped_frequencies.tolist()
            d["damping_ratios"] = self.damping_ratios.tolist()
        return d


@netcdf_reader(Modes.result_kind)
def read_normal_modes(path, variables, attrs) -> Modes:
    """:class:`Modes` from their ``*.nc`` file (``read_normal_modes(path)``, for
    :func:`skewpend.open_result`): the modes are computed again from the parameters about the
    recorded equilibrium, and what the file stores must agree with them; the stored arrays are
    returned as stored."""
    import dataclasses

    from ..symbolic.model import AnyModel

    proto = protocol_fields(path, attrs, AnyModel)
    params = proto["params"]
    eq = tuple(float(x) for x in proto["settings"].get("equilibrium", [0.0] * params.n))
    coulomb = proto["settings"].get("coulomb", "smoothed")  # recorded since the default is "exclude"; before: smoothed
    pairs = np.asarray(variables["eigenvalue_real"], dtype=float) + 1j * np.asarray(variables["eigenvalue_imag"], dtype=float)
    try:
        if not any(eq):
            try:
                rebuilt = normal_modes(params, coulomb=coulomb)
            except EquilibriumError:
                rebuilt = normal_modes(params, about=eq, coulomb=coulomb)
        else:
            rebuilt = normal_modes(params, about=eq, coulomb=coulomb)
    except SkewpendError as exc:
        raise ParameterError(f"{path} was written by another model: its parameters give no modes there ({exc})") from None
    stored = {"M": variables["M0"], "C": variables["C0"], "K": variables["K0"], "frequencies": variables["frequency"],
              "periods": variables["period"], "shapes": variables["shape"], "damping_ratios": variables["damping_ratio"],
              "damped_frequencies": variables["damped_frequency"], "growth_rates": variables["growth_rate"]}
    stored = {k: np.asarray(v, dtype=float) for k, v in stored.items()}
    for name, value in stored.items():
        agree(path, name, value, getattr(rebuilt, name))
    agree(path, "eigenvalues", pairs, rebuilt.eigenvalue_pairs)
    return dataclasses.replace(rebuilt, **stored, eigenvalue_pairs=pairs, eigenvalues=pairs[:, 0].copy(), equilibrium=eq)


def _modes_from_matrices(M: np.ndarray, C: np.ndarray, K: np.ndarray, params: Parameters,
                         equilibrium: Optional[Tuple[float, ...]] = None, coulomb: str = DEFAULT_COULOMB) -> Modes:
    """Raises :class:`NotFinite` (short reason) when a result is not finite."""
    from scipy.linalg import LinAlgError, eigh

    with np.errstate(all="ignore"):
        try:
            lam, V = eigh(K, M)
        except (LinAlgError, ValueError):
            raise NotFinite("the eigenproblem K0 v = w^2 M0 v cannot be solved in double precision (M0 not positive definite)") from None
        _require_finite(**{"the frequencies": lam, "the mode shapes": V})
        n = M.shape[0]
        if equilibrium is None and lam[0] <= 1e-12 * max(abs(lam[-1]), 1e-300):
            raise EquilibriumError(
                f"the hanging position is not a stable equilibrium (w^2 = {lam.tolist()}); normal modes need g > 0"
                + ("" if lam[0] < 0 or float(params.g or 0) <= 0 else
                   ", and w1^2 above 1e-12 w2^2 (here it is zero to rounding: the model's scales span too many orders of magnitude)")
            )
        if equilibrium is not None and np.any(np.abs(lam) <= 1e-12 * max(np.abs(lam).max(), 1e-300)):
            raise EquilibriumError(
                f"the equilibrium ({', '.join(f'{x:.6g}' for x in equilibrium)}) is degenerate (w^2 = {lam.tolist()}): "
                "its linearisation has a zero eigenvalue")
        for k in range(n):
            col = V[:, k]
            col[np.abs(col) < 1e-13 * np.abs(col).max()] = 0.0  # round-off where a hinge stands still
            if col[np.argmax(np.abs(col))] < 0:
                V[:, k] = -col
        w = np.sqrt(np.maximum(lam, 0.0))
        growth = np.sqrt(np.maximum(-lam, 0.0))
        with np.errstate(divide="ignore"):
            periods = np.where(w > 0, 2 * np.pi / np.where(w > 0, w, 1), np.inf)
        # the last coordinate's amplitude over the first's (the double pendulum's psi/phi)
        ratios = np.where(np.abs(V[0]) > 1e-14 * np.abs(V).max(), V[-1] / np.where(V[0] == 0, 1, V[0]), np.inf)
        beat = 2 * np.pi / (w[1] - w[0]) if n > 1 and w[1] > w[0] and w[0] > 0 else np.inf  # of the two lowest modes
        _require_finite(**{"the frequencies": w, "the periods": periods[w > 0]})
        if np.any(np.isnan(ratios)) or np.isnan(beat):
            raise NotFinite("the amplitude ratios are not numbers")
        if np.any(C != 0):
            pairs = pairs_of_chain(M, C, K, V)
            eig = pairs[:, 0]
            damped_w = np.abs(eig.imag)
            prod = (pairs[:, 0] * pairs[:, 1]).real
            if np.any(~(np.abs(prod) > 0)):
                raise NotFinite("a damped mode has a zero eigenvalue (underflow)")
            # a growing mode's pair is real with opposite signs: its rate is the positive one, and
            # zeta uses |l1 l2| (for one degree of freedom m x'' + c x' - k x = 0: c / (2 sqrt(k m)))
            grows = prod < 0
            pairs[grows] = np.sort(pairs[grows].real, axis=1)[:, ::-1] + 0j  # eig: a view of pairs[:, 0]
            damped_w = np.where(grows, 0.0, damped_w)
            growth = np.where(grows, pairs[:, 0].real, 0.0)
            # C0 >= 0 makes zeta >= 0; clip the round-off of an undamped mode
            zeta = np.maximum(-(pairs[:, 0] + pairs[:, 1]).real / (2 * np.sqrt(np.abs(prod))), 0.0)
            _require_finite(**{"the damped frequencies": damped_w, "the damping ratios": zeta})
        else:
            eig = np.where(growth > 0, growth + 0j, 1j * w)
            pairs = np.column_stack([eig, np.where(growth > 0, -growth + 0j, -1j * w)])
            damped_w = w.copy()
            zeta = np.zeros(n)
    return Modes(
        frequencies=w,
        periods=periods,
        shapes=V,
        ratios=ratios,
        beat_period=float(beat),
        eigenvalues=eig,
        damped_frequencies=damped_w,
        damping_ratios=zeta,
        eigenvalue_pairs=pairs,
        M=M,
        C=C,
        K=K,
        params=params,
        growth_rates=growth,
        equilibrium=tuple([0.0] * n) if equilibrium is None else tuple(float(x) for x in equilibrium),
        coulomb=coulomb,
    )


def _scaled(z: complex, M: np.ndarray, C: np.ndarray, K: np.ndarray):
    """``Q(z) = z^2 M + z C + K`` and ``dQ/dz``, both divided by ``z^2`` when ``|z| > 1`` (nothing overflows);
    with the power of ``z`` taken out (0 or 2)."""
    if abs(z) > 1:
        w = 1.0 / z
        return M + w * C + (w * w) * K, -(w * w) * C - (2 * w ** 3) * K, 2
    return (z * z) * M + z * C + K, (2 * z) * M + C, 0


def _polish(z0: complex, M: np.ndarray, C: np.ndarray, K: np.ndarray, known: Sequence[complex] = ()) -> Tuple[complex, bool]:
    """Newton's method on ``det Q(z) = 0`` from ``z0`` (``det Q / (det Q)' = 1 / tr(Q^-1 Q')``; a real start
    stays real), the roots ``known`` deflated (Maehly: ``det Q / prod (z - r)``): the root and whether the steps
    converged to machine precision."""
    n = M.shape[0]
    z = complex(z0.real, 0.0) if z0.imag == 0 else complex(z0)
    eps, last = np.finfo(float).eps, np.inf
    for _ in range(40):
        Q, dQ, p = _scaled(z, M, C, K)
        try:
            t = np.trace(np.linalg.solve(Q, dQ))
        except np.linalg.LinAlgError:  # Q singular: z is a root to the last bit
            return z, True
        try:
            step = 1.0 / (t + p * n / z - sum(1.0 / (z - r) for r in known))
        except ZeroDivisionError:  # at 0 or on a root already known
            return z, False
        if not np.isfinite(step):
            return z, False
        if z0.imag == 0:
            step = complex(step.real, 0.0)
        z -= step
        # converged: a step at machine precision, or steps that stopped shrinking at the rounding level
        if abs(step) <= 4 * eps * abs(z) or (abs(step) <= 64 * eps * abs(z) and abs(step) > 0.5 * last):
            return z, True
        last = abs(step)
    return z, False


def _state_eigen(M: np.ndarray, C: np.ndarray, K: np.ndarray, V: np.ndarray) -> Tuple[np.ndarray, np.ndarray]:
    """The ``2 n`` roots of ``det(l^2 M + l C + K) = 0`` (the state matrix's eigenvalues) and the displacement
    parts ``x`` (n, 2n) of their eigenvectors ``[x; l x]`` (unit length; a zero column where ``Q(l) ~ 0``, a
    double eigenvalue shared by two shapes), for any ``n``.

    Starting values are the eigenvalues of the state matrix, the reciprocals of those of the reversed
    problem ``K m^2 + C m + M`` (accurate for the large and for the small roots) and each undamped mode ``v``'s
    one-degree-of-freedom roots ``l^2 + (v^T C v) l + v^T K v = 0`` (a lightly damped mode beside an almost
    locked hinge, which the state matrix loses); each is polished by Newton's
    method on ``det Q`` (scaled by ``1/l^2`` for ``|l| > 1``), so the roots keep full relative accuracy when the
    damping spans many orders of magnitude (the slow creep ``~ k/c`` and fast decay ``~ c/m`` of heavy
    damping).  Near a double root Newton does not converge and the state matrix's eigenvalues are used."""
    from numpy.linalg import eigvals  # (scipy's wrapper costs more than a small matrix's eigenvalues)

    n = M.shape[0]

    def companion(A, B, D):  # the state matrix of A l^2 + B l + D
        Ainv = np.linalg.inv(A)
        S = np.zeros((2 * n, 2 * n))
        S[:n, n:] = np.eye(n)
        S[n:, :n], S[n:, n:] = -Ainv @ D, -Ainv @ B
        return S

    c, k = np.einsum("ik,ij,jk->k", V, C, V), np.einsum("ik,ij,jk->k", V, K, V)

    def small():  # the reversed problem's, computed only when the state matrix's starts did not give every root
        return 1.0 / eigvals(companion(K, C, M)).astype(complex)

    def modal():
        far = (-c - np.sqrt((c * c - 4 * k).astype(complex))) / 2  # the larger root; the other k / far
        return np.concatenate([far, k / np.where(far == 0, 1, far)])

    with np.errstate(all="ignore"):
        try:
            big = eigvals(companion(M, C, K)).astype(complex)
        except (np.linalg.LinAlgError, ValueError):
            raise NotFinite("the state-space eigenvalues are not finite (overflow)") from None
        roots: List[complex] = []  # one of each conjugate pair, imaginary part >= 0

        def found() -> int:
            return len(roots) + sum(z.imag != 0 for z in roots)

        def near(z: complex, tol: float) -> bool:
            return any(abs(complex(z.real, abs(z.imag)) - r) <= tol * abs(r) for r in roots)

        def polish(z0: complex, known: Sequence[complex] = ()) -> None:
            z, converged = _polish(z0, M, C, K, known)
            if converged and np.isfinite(z):
                z = complex(z.real, 0.0) if abs(z.imag) <= 1e-14 * abs(z) else complex(z.real, abs(z.imag))
                if not near(z, 1e-10):
                    roots.append(z)

        for more in (lambda: big, small, modal):
            if found() >= 2 * n:
                break
            try:
                starts = more()
            except (np.linalg.LinAlgError, ValueError):
                raise NotFinite("the state-space eigenvalues are not finite (overflow)") from None
            for z0 in starts:
                if found() >= 2 * n:
                    break
                if np.isfinite(z0) and z0 != 0 and z0.imag >= 0 and not near(z0, 1e-8):
                    polish(complex(z0))
        # a root no start led to (a lightly damped mode beside an almost locked hinge): Newton with the roots
        # found deflated, from each undamped frequency on the imaginary axis
        for z0 in 1j * np.sqrt(np.abs(k)) + 1e-3 * np.sqrt(np.abs(k)):
            if found() >= 2 * n:
                break
            polish(complex(z0), roots + [np.conj(r) for r in roots if r.imag != 0])
        lam = np.array(roots + [np.conj(z) for z in roots if z.imag != 0])
        if lam.size != 2 * n:  # a (near) double root: Newton converges slowly there
            lam = big
        if lam.size != 2 * n or not np.all(np.isfinite(lam)) or np.any(lam == 0):
            raise NotFinite("the state-space eigenvalues are not finite (overflow)")
        X = np.zeros((n, lam.size), complex)
        nM, nC, nK = (np.abs(A).max() for A in (M, C, K))
        Qs, scales = np.empty((lam.size, n, n), complex), np.empty(lam.size)
        for k, z in enumerate(lam):
            Qs[k], _, p = _scaled(z, M, C, K)
            scales[k] = nM + nC / abs(z) + nK / abs(z) ** 2 if p else abs(z) ** 2 * nM + abs(z) * nC + nK
        _, sv, Vh = np.linalg.svd(Qs)  # every Q(l) at once
        for k in range(lam.size):
            if n < 2 or sv[k, -2] > 1e-10 * scales[k]:
                X[:, k] = Vh[k, -1].conj()
    return lam, X


def pairs_of_chain(M: np.ndarray, C: np.ndarray, K: np.ndarray, V: np.ndarray) -> np.ndarray:
    """The ``2 n`` state-space eigenvalues of ``l^2 M + l C + K`` (:func:`_state_eigen`) as a pair per undamped
    mode (rows, the modes of ``V``, any ``n``): each eigenvalue's displacement part ``x`` is compared with the
    undamped shapes by the M-weighted similarity ``|v_k^T M x| / sqrt(x^H M x)`` (1 = same shape; 1/2 for an
    eigenvalue without a shape), and the split into pairs (complex conjugates together, a conjugate pair or two
    real eigenvalues a mode) with the largest total similarity is taken.  An underdamped mode has a conjugate
    pair (positive imaginary part first), an overdamped mode two negative real eigenvalues (the slower first)."""
    from scipy.optimize import linear_sum_assignment

    n = M.shape[0]
    lam, X = _state_eigen(M, C, K, V)
    _require_finite(**{"the state-space eigenvalues": lam, "the state-space eigenvectors": X})
    norm = np.sqrt(np.abs(np.einsum("ij,ik,kj->j", X.conj(), M, X).real))
    S = np.where(norm > 0, np.abs(V.T @ M @ X) / np.where(norm > 0, norm, 1.0), 0.5)
    complex_ = [j for j in range(2 * n) if lam[j].imag > 0]
    real = [j for j in range(2 * n) if lam[j].imag == 0]
    if len(real) % 2 or len(complex_) + len(real) // 2 != n:
        raise NotFinite("the state-space eigenvalues do not form conjugate or real pairs (numerical failure)")
    best = -np.inf
    chosen: List[List[complex]] = [[] for _ in range(n)]
    # the split with the largest total similarity: the overdamped modes (two real eigenvalues each) chosen
    # among all, the conjugate pairs and the real eigenvalues then given to their modes by linear assignment
    # (beyond a few thousand choices -- many overdamped modes of a long chain -- the modes most like the real
    # eigenvectors: one choice)
    q = len(real) // 2
    choices: Iterable[Tuple[int, ...]] = itertools.combinations(range(n), q)
    if math.comb(n, q) > 4096:
        lean = (np.sort(S[:, real], axis=1)[:, -2:].sum(axis=1) - 2 * S[:, complex_].max(axis=1, initial=0.0))
        choices = [tuple(sorted(np.argsort(-lean)[:q].tolist()))]
    for over in choices:
        rest = [k for k in range(n) if k not in over]
        score = 0.0
        picks: List[List[complex]] = [[] for _ in range(n)]
        if complex_:
            rows, cols = linear_sum_assignment(-2 * S[np.ix_(rest, complex_)])
            score += 2 * S[np.ix_(rest, complex_)][rows, cols].sum()
            for r, c in zip(rows, cols):
                z = lam[complex_[c]]
                picks[rest[r]] = [complex(z.real, abs(z.imag)), complex(z.real, -abs(z.imag))]
        if real:
            slots = [k for k in over for _ in range(2)]
            rows, cols = linear_sum_assignment(-S[np.ix_(slots, real)])
            score += S[np.ix_(slots, real)][rows, cols].sum()
            for r, c in zip(rows, cols):
                picks[slots[r]].append(complex(lam[real[c]].real, 0.0))
        if score > best:
            best, chosen = score, picks
    if any(len(z) != 2 for z in chosen):
        raise NotFinite("the state-space eigenvalues do not form conjugate or real pairs (numerical failure)")
    pairs = np.empty((n, 2), complex)
    for k, z in enumerate(chosen):
        z = np.array(z)
        pairs[k] = z if z[0].imag != 0 else z[np.argsort(np.abs(z))]
    return pairs


def chain_modes(chain, coulomb: str = DEFAULT_COULOMB) -> Modes:
    """The normal modes of a chain of links about its hanging rest: :func:`normal_modes` (kept as a name)."""
    return normal_modes(chain, coulomb=coulomb)


def normal_modes(params: Parameters, about=None, coulomb: str = DEFAULT_COULOMB) -> Modes:
    """Normal modes of the numeric model ``params`` about its hanging rest -- ``phi = psi = 0`` (``q = 0``), or,
    where the model's zero is upright (``K0`` not positive semi-definite there: a model read from MJCF, the
    DeepMind acrobot), its ``"down-...-down"`` equilibrium found from the geometry (the acrobot's ``(pi, 0)``;
    ``equilibrium`` says where) -- or about another equilibrium: ``about`` an :class:`~skewpend.analysis.equilibria.Equilibrium`, a label of one
    (``"up-up"``, see :func:`skewpend.equilibria`) or a pair ``(phi, psi)`` near one (polished by
    Newton's method).  There M, C, K are ``M(q*)``, the damping and the Hessian of
    ``V = Pi - tau . q``, constant torques are allowed, and a direction along which the
    equilibrium is unstable is a mode with a growth rate (``growth_rates``), frequency 0.

    Coulomb friction (``cf1``, ``cf2``) is non-smooth at rest: ``cf sign(q')`` has no slope at
    ``q' = 0``, and the slope ``cfs cf`` of its smoothed form ``cf atan(cfs q')`` is an artefact of
    the smoothing.  By default (``coulomb="exclude"``) it is left out of ``C``, so a model whose
    only damping is Coulomb friction has undamped modes, and the result says so
    (``coulomb_note``, ``message``); ``coulomb="smoothed"`` adds the slope as viscous damping.

    Raises :class:`~skewpend.errors.EquilibriumError` when the hanging position is not an
    equilibrium (torques, offset centres of mass) or not stable (``g = 0``), and
    :class:`~skewpend.errors.ParameterError` when a result would not be finite (overflow of
    extreme parameters): every array of the result is finite, except the documented
    ``ratios = inf`` (phi stands still) and ``beat_period = inf`` (equal frequencies).

    Equal rods of unit length at ``alpha = 0`` with ``g = 1``: the compound double pendulum,
    whose squared frequencies are ``3 -/+ 6/sqrt(7)``:

    >>> import skewpend
    >>> modes = skewpend.normal_modes(skewpend.Parameters(a=1, b=1, m1=1, m2=1, alpha=0, g=1))
    >>> [round(float(w) ** 2, 6) for w in modes.frequencies]
    [0.732213, 5.267787]
    """
    if not hasattr(params, "as_chain"):  # one line, not an AttributeError (issue 29, item 8)
        raise ParameterError(f"params must be a skewpend.Parameters or a Chain, got {type(params).__name__}")
    coulomb = check_coulomb(coulomb)
    if about is not None:
        from .equilibria import find_equilibrium

        eq = find_equilibrium(params, about, "about", coulomb=coulomb)
    try:
        if about is not None:
            return _modes_from_matrices(eq.M, eq.C, eq.K, params, equilibrium=eq.q, coulomb=coulomb)
        M, C, K = _matrices(params, coulomb)
        try:
            return _modes_from_matrices(M, C, K, params, coulomb=coulomb)
        except EquilibriumError as exc:
            rest = _hanging_rest(params, K, coulomb)  # q = 0 upright (an imported model's zero): the hanging rest
            if rest is None:
                raise exc from None
            return _modes_from_matrices(rest.M, rest.C, rest.K, params, equilibrium=rest.q, coulomb=coulomb)
    except NotFinite as exc:
        raise ParameterError(_not_finite_message(exc, params)) from None


def _hanging_rest(params, K0: np.ndarray, coulomb: str):
    """The model's hanging rest, every link's centre of mass below its hinge (``"down-...-down"``, found from the
    geometry by :func:`~skewpend.analysis.equilibria.find_equilibrium`), where ``q = 0`` is not it: ``K0`` has
    a negative eigenvalue there (a model read from MJCF whose zero is upright -- the DeepMind acrobot's hanging
    rest is ``(pi, 0)``) and the rest found is stable; else None (the modes' own refusal stands: ``g = 0``, no
    hanging rest)."""
    from .equilibria import find_equilibrium

    if not np.all(np.isfinite(K0)) or np.linalg.eigvalsh(0.5 * (K0 + K0.T))[0] >= 0:
        return None
    try:
        eq = find_equilibrium(params, "-".join(["down"] * params.n), "about", coulomb=coulomb)
    except SkewpendError:
        return None
    return eq if eq.stable else None


# -- closed form ------------------------------------------------------------------------------------
def characteristic_equation(params: Optional[Parameters] = None):
    """``det(K0 - w^2 M0) = 0`` in closed form, and its roots ``w^2``.

    Returns ``(equation, (w2_low, w2_high))`` as SymPy objects in the symbol ``omega``
    and the parameters left symbolic (default: all, thin rods).  The equation is
    ``det(K0 - w^2 M0)`` divided by its constant content, ``A w^4 + B w^2 + D = 0``; the
    roots are ``(-B -/+ sqrt(B^2 - 4 A D)) / (2 A)``.
    """
    import sympy as sp

    from ..symbolic.derivation import derive

    if params is not None:  # the double pendulum's parameters, or a chain of two they hold
        exact = params.exact_model() if hasattr(params, "exact_model") else None
        if exact is None:
            from ..checks import not_parameters

            raise ParameterError(not_parameters(params, "the closed form of the frequencies") + "; or None: all symbolic")
        params = exact
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
_RATIOS = tuple(f"{pair[1]}/{pair[0]}" for pair in (LENGTH_NAMES, MASS_NAMES))  # b/a, m2/m1
SWEEPABLE = ("alpha",) + LENGTH_NAMES + MASS_NAMES + ("g",) + _RATIOS
#: The parameter a sweep sets (a ratio sets its numerator).
SWEPT_PARAMETER = {ratio: ratio.split("/")[0] for ratio in _RATIOS}
_UNITS = {**{n: unit(n).replace("²", "^2") for n in SWEEPABLE if n not in _RATIOS}, **{r: "1" for r in _RATIOS}}


def _link_name(name: str, n: int) -> Optional[Tuple[str, int]]:
    """``"tilt2"`` -> ``("tilt", 2)`` for a link's field of :data:`CHAIN_SWEEPABLE` and a link from 1 to ``n``."""
    stem, index = name.rstrip("0123456789"), name[len(name.rstrip("0123456789")):]
    return (stem, int(index)) if stem in CHAIN_SWEEPABLE and index and 1 <= int(index) <= n else None


def _facade_names(model) -> Tuple[str, ...]:
    """The names of :data:`SWEEPABLE` the model answers (the double pendulum's facade: all; a chain: none)."""
    return SWEEPABLE if all(hasattr(model, n) for n in SWEEPABLE if "/" not in n) else ()


def _refuse(name: str, model, prefix: str = "") -> ParameterError:
    n = model.n
    facade = _facade_names(model)
    return ParameterError(f"{prefix}cannot sweep {name!r} of a chain of {n} links; allowed: "
                          + (", ".join(facade) + ", or " if facade else "")
                          + f"a link's {', '.join(CHAIN_SWEEPABLE)} and its number 1 to {n} (mass{n}, tilt2)")


def parse_sweep(spec: str, model=None) -> Tuple[str, np.ndarray]:
    """``"alpha=0:180deg:181"`` -> ``("alpha", values in radians)``; ``"b/a=0.2:5:100"``; a link's
    ``"tilt2=0:90deg:31"`` or ``"mass3=0.1:2:20"`` (``model``: the model swept, default the double pendulum;
    see :func:`sweep`).

    The range follows :func:`skewpend.parsing.parse_range`: a unit on either end (or both)
    applies to the whole range, plain numbers are radians for alpha and a tilt, mixed units are refused.
    """
    from ..parsing import parse_range

    model = Parameters() if model is None else model
    if not isinstance(spec, str) or "=" not in spec:
        raise ParameterError(f"--sweep: expected NAME=START:STOP:COUNT (e.g. alpha=0:180deg:181 or tilt2=0:90deg:31), "
                             f"got {spec!r}")
    name, rng = (x.strip() for x in spec.split("=", 1))
    if name not in _facade_names(model) and _link_name(name, model.n) is None:
        raise _refuse(name, model, "--sweep: ")
    return name, parse_range(rng, f"--sweep {name}", angle=name == "alpha" or name.startswith("tilt"))


def _changer(model, name: str) -> Callable[[float], Any]:
    """``value -> the model with name set to it``: a facade name by the model's own ``replace`` (a ratio scales
    its numerator), a link's field or tilt on its chain; anything else refused in one line."""
    if name in _facade_names(model):
        if "/" in name:
            top, bottom = name.split("/")
            return lambda v: model.replace(**{top: v * float(getattr(model, bottom))})
        return lambda v: model.replace(**{name: v})
    link = _link_name(name, model.n)
    if link is None:
        raise _refuse(name, model)
    stem, i = link
    chain = model.as_chain()
    if stem == "tilt":
        return lambda v: chain.replace_link(i, axis=(math.sin(v), 0.0, math.cos(v)))
    return lambda v: chain.replace_link(i, **{stem: float(v)})


@dataclass(frozen=True)
class Resonance:
    """An internal resonance ``w2/w1 ~ n`` along a sweep: where it is closest (or crossed); a chain's
    between neighbouring modes ``pair = (k, k + 1)``: ``w_(k+1)/w_k ~ n``."""

    order: int
    value: float  # the swept variable there (radians for alpha)
    ratio: float  # w2/w1 there
    crossed: bool  # the ratio passes through n (exact resonance, interpolated)
    pair: Tuple[int, int] = (1, 2)


@dataclass(frozen=True)
class Sweep(ResultProtocol):
    """Modes along a swept variable: ``values`` (m,) in SI units (radians for an angle),
    ``frequencies`` (m, n) [rad/s], ``shapes`` (m, n, n) (columns = modes), ``ratios`` (m, n)
    last coordinate over the first (psi/phi), ``resonances`` of neighbouring modes; the result protocol as for
    :class:`Modes`.  :meth:`columns` gives
    the CSV columns and rows, :meth:`table` a text table (as every result's ``table()``)."""

    name: str
    values: np.ndarray
    frequencies: np.ndarray
    shapes: np.ndarray
    ratios: np.ndarray
    resonances: List[Resonance]
    tolerance: float
    params: Parameters = field(repr=False)

    result_kind: ClassVar[str] = "modes sweep"
    status: ClassVar[Status] = Status.SUCCESS
    message: ClassVar[str] = "the modes at every value of the sweep"

    @property
    def settings(self) -> Dict:
        return {"swept": self.name, "values": self.values.tolist(), "resonance_tolerance": self.tolerance}

    @property
    def stats(self) -> Dict:
        return {"values": int(self.values.size), "resonances": len(self.resonances)}

    def _dataset(self) -> DatasetSpec:
        cols, rows = self.columns()
        units = self.units()
        return DatasetSpec(
            variables={c: (("value",), rows[:, i], {"units": units[c]}) for i, c in enumerate(cols) if c != self.name},
            coords={"value": (("value",), self.values, {"units": units[self.name], "long_name": self.name})},
            attrs={"title": "normal modes along a sweep (skewpend)", **self._base_attrs()},
        )

    @property
    def modes_count(self) -> int:
        return int(self.frequencies.shape[1])

    def _degrees(self) -> bool:
        return self.name == "alpha" or self.name.startswith("tilt")

    def table(self) -> str:
        """A text table: the swept value, every frequency and the ratios of neighbouring modes (the double
        pendulum's ``omega1, omega2, w2/w1``)."""
        unit = "deg" if self._degrees() else _unit_of(self.name)
        values = np.degrees(self.values) if self._degrees() else self.values
        n = self.modes_count
        head = f"{self.name + ' [' + unit + ']':>14} " + " ".join(f"{'omega' + str(k + 1):>10}" for k in range(n))
        lines = [head + "".join(f" {'w%d/w%d' % (k + 2, k + 1):>8}" for k in range(n - 1))]
        for v, w in zip(values, self.frequencies):
            lines.append(f"{v:14.6g} " + " ".join(f"{x:10.6g}" for x in w)
                         + "".join(f" {w[k + 1] / w[k]:8.4f}" for k in range(n - 1)))
        return "\n".join(lines)

    @property
    def frequency_ratio(self) -> np.ndarray:
        """``w2/w1`` at every value: the ratio of the two lowest modes."""
        return self.frequencies[:, 1] / self.frequencies[:, 0]

    def columns(self) -> Tuple[List[str], np.ndarray]:
        """Columns and rows for CSV output: the swept value (SI units: an angle in radians, with a
        ``NAME_deg`` column last), ``omega1..n``, ``period1..n``, the neighbours' ``omega(k+1)_over_omega(k)``
        and each mode's shape over the model's coordinates (``mode1_phi``, ``mode1_psi``, ... for the double
        pendulum; ``mode1_q1`` ... for a chain); see :meth:`units`."""
        n = self.modes_count
        coords = self.params.coordinates
        cols = [self.name] + [f"omega{k + 1}" for k in range(n)] + [f"period{k + 1}" for k in range(n)]
        cols += [f"omega{k + 2}_over_omega{k + 1}" for k in range(n - 1)]
        cols += [f"mode{k + 1}_{c}" for k in range(n) for c in coords]
        rows = [self.values, self.frequencies, 2 * np.pi / self.frequencies,
                self.frequencies[:, 1:] / self.frequencies[:, :-1]] + [self.shapes[:, :, k] for k in range(n)]
        if self._degrees():
            cols.append(f"{self.name}_deg")
            rows.append(np.degrees(self.values))
        return cols, np.column_stack(rows)

    def units(self) -> Dict[str, str]:
        """The unit of each column of :meth:`columns`."""
        shape = "kg^-1/2 m^-1 (v^T M0 v = 1)"
        cols, _ = self.columns()
        swept = _UNITS[self.name] if self.name in _UNITS else _unit_of(self.name)
        return {c: (swept if c == self.name else "deg" if c.endswith("_deg") else "1" if "_over_" in c else "rad/s"
                    if c.startswith("omega") else "s" if c.startswith("period") else shape) for c in cols}

    def to_dict(self) -> Dict:
        """The JSON form: ``columns``, ``units`` and ``rows`` as in :meth:`columns` (alpha in
        radians plus ``alpha_deg``), and the ``resonances`` (``value`` in the swept variable's
        SI unit, plus ``value_deg`` for alpha)."""
        cols, rows = self.columns()
        resonances = []
        for r in self.resonances:
            d = dict(r.__dict__)
            d["pair"] = list(r.pair)
            if self._degrees():
                d["value_deg"] = math.degrees(r.value)
            resonances.append(d)
        return {
            "swept": self.name,
            "columns": cols,
            "units": self.units(),
            "rows": rows.tolist(),
            "resonance_tolerance": self.tolerance,
            "resonances": resonances,
        }


@netcdf_reader(Sweep.result_kind)
def read_modes_sweep(path, variables, attrs) -> Sweep:
    """A :class:`Sweep` from its ``*.nc`` file (``read_modes_sweep(path)``, for
    :func:`skewpend.open_result`): swept again from the parameters, its frequencies and mode
    shapes checked against the stored ones, which it returns."""
    import dataclasses

    from ..symbolic.model import AnyModel

    proto = protocol_fields(path, attrs, AnyModel)
    settings = proto["settings"]
    values = np.asarray(variables["value"], dtype=float)
    name = str(settings["swept"])
    try:
        rebuilt = sweep(proto["params"], name, values.tolist(), tolerance=float(settings["resonance_tolerance"]))
    except SkewpendError as exc:
        raise ParameterError(f"{path} was written by another model: its parameters give no sweep there ({exc})") from None
    n = rebuilt.modes_count
    freqs = np.column_stack([variables[f"omega{k + 1}"] for k in range(n)]).astype(float)
    shapes = np.empty((values.size, n, n))
    for k in range(n):
        for i, c in enumerate(rebuilt.params.coordinates):
            shapes[:, i, k] = variables[f"mode{k + 1}_{c}"]
    agree(path, "frequencies", freqs, rebuilt.frequencies)
    agree(path, "mode shapes", shapes, rebuilt.shapes)
    return dataclasses.replace(rebuilt, values=values, frequencies=freqs, shapes=shapes)


def _resonances(values: np.ndarray, ratio: np.ndarray, tol: float, pair: Tuple[int, int] = (1, 2)) -> List[Resonance]:
    found: List[Resonance] = []
    for n in (1, 2, 3):
        d = ratio - n
        # exact crossings, interpolated
        for i in np.nonzero(np.sign(d[:-1]) * np.sign(d[1:]) < 0)[0].tolist():
            s = d[i] / (d[i] - d[i + 1])
            found.append(Resonance(n, float(values[i] + s * (values[i + 1] - values[i])), float(n), True, pair))
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
            lo, hi = sorted((float(values[max(i - 1, 0)]), float(values[min(j + 1, len(values) - 1)])))
            if not any(r.order == n and r.crossed and lo <= r.value <= hi for r in found):
                found.append(Resonance(n, float(values[k]), float(ratio[k]), False, pair))
            i = j + 1
    return sorted(found, key=lambda r: (r.value, r.order))


def _failure_message(name: str, failures: List[Tuple[float, str]], total: int) -> str:
    groups: Dict[str, List[float]] = {}
    for value, why in failures:
        groups.setdefault(why, []).append(value)
    parts = []
    angle = name == "alpha" or name.startswith("tilt")
    for why, vals in groups.items():
        shown = ", ".join(f"{v:.6g} rad ({math.degrees(v):.6g} deg)" if angle else f"{v:.6g}" for v in vals[:3]) + (
            f" (and {len(vals) - 3} more)" if len(vals) > 3 else "")
        parts.append(f"{name} = {shown}: {why}")
    return (
        f"sweep of {name}: {len(failures)} of {total} values failed, so nothing is reported: " + "; ".join(parts)
        + "; choose a range where every value gives finite modes of a stable hanging position"
    )


def sweep(params: Parameters, name: str, values: Sequence[float], *, tolerance: float = 0.01) -> Sweep:
    """Normal modes of the model ``params`` with ``name`` set to each of ``values``: a name the model answers
    (the double pendulum's :data:`SWEEPABLE`: alpha, a, b, m1, m2, g, b/a, m2/m1; a ratio scales its
    numerator) or a link's field of :data:`CHAIN_SWEEPABLE` and its number (``mass3``, ``tilt2``).

    Internal resonances ``w(k+1)/w(k) = n`` (n = 1, 2, 3) of neighbouring modes (the double pendulum's
    ``w2/w1``) are reported where the ratio crosses ``n`` (interpolated) or comes within ``tolerance * n``
    of it (``tolerance`` > 0).  If any value fails (not a valid parameter, an unstable or non-equilibrium
    hanging position, results not finite) the whole sweep is refused with a
    :class:`~skewpend.errors.ParameterError` naming the failing values.
    """
    if not hasattr(params, "as_chain"):
        raise ParameterError(f"params must be a skewpend.Parameters or a Chain, got {type(params).__name__}")
    change = _changer(params, name)
    grid = _sweep_grid(values, tolerance)
    if name == "alpha" and not params.uses_alpha:
        raise ParameterError("cannot sweep alpha: the hinge-2 axis is given explicitly (axis2), so alpha has no effect")
    n = params.n
    freqs, shapes, ratios = np.empty((grid.size, n)), np.empty((grid.size, n, n)), np.empty((grid.size, n))
    failures: List[Tuple[float, str]] = []
    for i, v in enumerate(grid):
        try:
            p = change(float(v))
            p.require_numeric("a sweep")
            m = _modes_from_matrices(*_matrices(p), p)
        except NotNumericError:
            raise
        except NotFinite as exc:
            failures.append((float(v), exc.reason))
        except SkewpendError as exc:
            failures.append((float(v), str(exc)))
        else:
            freqs[i], shapes[i], ratios[i] = m.frequencies, m.shapes, m.ratios
    if failures:
        raise ParameterError(_failure_message(name, failures, grid.size))
    with np.errstate(all="ignore"):
        neighbours = freqs[:, 1:] / freqs[:, :-1]
    bad = ~(np.all(np.isfinite(freqs), axis=1) & np.all(np.isfinite(shapes), axis=(1, 2)) & np.all(np.isfinite(neighbours), axis=1))
    if np.any(bad):  # pragma: no cover - every point was checked by _modes_from_matrices
        raise ParameterError(_failure_message(name, [(float(v), "results not finite") for v in grid[bad]], grid.size))
    resonances: List[Resonance] = []
    for k in range(n - 1):
        resonances += _resonances(grid, neighbours[:, k], float(tolerance), (k + 1, k + 2))
    return Sweep(name, grid, freqs, shapes, ratios, sorted(resonances, key=lambda r: (r.value, r.pair, r.order)),
                 float(tolerance), params)


#: What a chain's sweep can vary: a link's ``length``, ``mass`` or ``damping`` (``mass3``), or ``tilt``:
#: hinge ``i``'s axis turned from ``k`` towards ``i`` by the angle (``e_i = (sin t, 0, cos t)`` with the
#: chain hanging: the specification's skew angle, hinge by hinge; ``tilt2``).
CHAIN_SWEEPABLE = ("length", "mass", "damping", "tilt")


def _unit_of(name: str) -> str:
    stem = name.rstrip("0123456789")
    return {"length": "m", "mass": "kg", "damping": "N m s", "tilt": "rad"}.get(stem) or _UNITS[name]


def _sweep_grid(values, tolerance) -> np.ndarray:
    """A sweep's values as a float array (at least 2, finite) and its resonance tolerance checked, each
    refused in one line."""
    if isinstance(tolerance, bool) or not isinstance(tolerance, (int, float, np.floating)) or not (
        math.isfinite(tolerance) and tolerance > 0
    ):
        raise ParameterError(f"the resonance tolerance must be a positive number, got {tolerance!r}")
    try:
        if isinstance(values, (str, bytes)) or any(isinstance(v, (str, bytes, bool)) for v in values):
            raise TypeError
        grid = np.asarray(values, float)
    except (TypeError, ValueError):
        grid = np.zeros(0)
    if grid.ndim != 1 or grid.size < 2 or not np.all(np.isfinite(grid)):
        raise ParameterError("sweep values must be at least 2 finite numbers")
    return grid


# -- linear versus nonlinear ---------------------------------------------------------------------------
@dataclass(frozen=True)
class NonlinearCheck:
    """Frequencies measured on the full nonlinear equations started from each mode shape."""

    amplitude: float  # largest initial angle [rad]
    linear: np.ndarray  # (n,) rad/s
    measured: np.ndarray  # (n,) rad/s
    cycles: np.ndarray  # (n,) cycles used

    @property
    def relative_shift(self) -> np.ndarray:
        return self.measured / self.linear - 1


def check_nonlinear(params: Parameters, amplitude: float, *, cycles: int = 40) -> NonlinearCheck:
    """Start the nonlinear equations from each mode shape scaled so its largest angle is
    ``amplitude`` [rad], at rest; measure the frequency of the modal coordinate by upward
    zero crossings (linearly interpolated) over ``cycles`` periods (a chain: each of its ``n`` modes).

    Needs a model without losses (no damping or Coulomb friction in any joint: the check compares undamped
    frequencies) and an
    amplitude in (0, pi) rad small enough that the motion stays an oscillation about the
    hanging position: the hinges never pass the upright position and the modal coordinate
    crosses zero at least once per two linear periods; otherwise a
    :class:`~skewpend.errors.ParameterError` says so.
    """
    from ..numeric.simulation import simulate

    if isinstance(amplitude, bool) or not isinstance(amplitude, (int, float, np.floating)) or not (
        math.isfinite(amplitude) and 0 < amplitude < math.pi
    ):
        raise ParameterError(
            f"the nonlinear check needs an amplitude in (0, pi) rad, i.e. between 0 and 180 deg exclusive, got {amplitude!r}"
        )
    if isinstance(cycles, bool) or not isinstance(cycles, (int, np.integer)) or cycles < 4:
        raise ParameterError(f"the nonlinear check needs a whole number of at least 4 cycles, got {cycles!r}")
    modes = normal_modes(params)
    params.require_lossless("the nonlinear check (it measures undamped oscillation frequencies)")
    n = int(np.shape(modes.shapes)[0])
    measured = np.empty(n)
    used = np.empty(n, dtype=int)
    deg = math.degrees(amplitude)
    allowed = (
        "the check needs an amplitude small enough for oscillation about the hanging position "
        "(typically up to a few tens of degrees; the allowed range is 0 < amplitude < 180 deg)"
    )
    for k in range(n):
        v = modes.shapes[:, k]
        q0 = amplitude * v / np.max(np.abs(v))
        T = modes.periods[k]
        tr = simulate(params, list(q0) + [0.0] * n, cycles * T, dt_out=T / 400, rtol=1e-11, atol=1e-12, throw=True)
        q = tr.y[:, :n]
        if not np.all(np.isfinite(q)):
            raise ParameterError(f"the nonlinear motion from mode {k + 1} at {deg:.4g} deg is not finite; {allowed}")
        if np.max(np.abs(q)) >= math.pi:
            raise ParameterError(
                f"at {deg:.4g} deg the motion started from mode {k + 1} goes over the top (a hinge angle reaches 180 deg), "
                f"so it is not an oscillation about the hanging position; {allowed}"
            )
        # the upward zero crossings of the modal coordinate, linearly interpolated (the grid, T/400, is fine enough)
        x, t = modes.modal_coordinates(q)[:, k], tr.t
        up = np.nonzero((x[:-1] < 0) & (x[1:] >= 0))[0]
        tc = t[up] - x[up] * (t[up + 1] - t[up]) / (x[up + 1] - x[up])
        if tc.size < max(3, cycles // 2 + 1):
            raise ParameterError(
                f"at {deg:.4g} deg the motion started from mode {k + 1} is not an oscillation of that mode "
                f"(its modal coordinate crossed zero upward {tc.size} times in {cycles} linear periods); {allowed}"
            )
        measured[k], used[k] = 2 * np.pi * (tc.size - 1) / (tc[-1] - tc[0]), tc.size - 1
    if not np.all(np.isfinite(measured)):  # pragma: no cover - guarded by the checks above
        raise ParameterError(f"the measured nonlinear frequencies are not finite at {deg:.4g} deg; {allowed}")
    return NonlinearCheck(float(amplitude), modes.frequencies.copy(), measured, used)
