"""Identify a real pendulum's parameters from its measured motion: :func:`identify` (issue 27).

This first version is the *linear* estimate, inverse dynamics on filtered signals as the DFKI lab
does it:

1. per piece: uneven time steps are first resampled onto a uniform grid (the median step) by cubic
   interpolation (``scipy.interpolate.CubicSpline``); then the angles are smoothed and
   differentiated twice by a Savitzky-Golay filter (``scipy.signal.savgol_filter``, polynomial
   order :data:`ORDER` = 4, window ``smoothing`` seconds, default :data:`SMOOTHING` = 0.05 s, i.e.
   51 samples at 1 kHz: it passes the motion below about 15 Hz); measured torques get the same
   filter (both sides of the equations filtered alike); the ``window // 2`` samples at each end,
   where the filter extrapolates, are dropped;
2. the base regressor ``Y_b(q, q', q'')`` of the model's geometry
   (:func:`skewpend.symbolic.regressor.base_parameters`) on those samples;
3. weighted least squares :func:`~skewpend.symbolic.regressor.linear_estimate`: with measured
   torques ``Y_b beta = tau``; for a free swing the homogeneous version, normalised by the
   reference ``J1zz_b`` (free motion determines ratios only: one overall scale of every inertial
   parameter and damping is undetermined; the fitted model takes it from ``params0``).

Intervals (95 %): the least-squares interval assumes independent residuals, which filtered signals
are not; so each half-width is the larger of that and the spread of re-fits on the pieces resampled
with replacement (:data:`BOOTSTRAP` resamples, seeded; with at least five pieces).  Neither covers
the bias of the filter or of noisy accelerations in the regressor (errors in the variables): the
output-error fit that comes next does not have that bias.

The fitted :class:`~skewpend.Parameters` are ``params0`` with what the base parameters determine
replaced: masses, the entries that do not enter the equations and (free swing) the overall scale
are ``params0``'s; the centres of mass, the inertia tensors about them and the damping are set so
that the model's base parameters equal the estimate (checked to 1e-9).  Where an entry that does not
enter the equations is needed to keep a body physical (the planar case: the inertia about the rod's
normal ``x``, which moves with the one about ``z`` as for mass moved along the rod) it is set so.
A base parameter that no physical body realises (a negative inertia, negative damping) gives a
non-success status instead of a model.

Held-out prediction: each validation piece is simulated with the fitted model (and with
``params0``, for comparison) from its first measured state over its duration; the RMS of the angle
error over both angles ``(phi, psi)`` and all samples is reported per piece and overall.  Pieces
with measured torques are simulated with those torques (linear between the samples); to predict
over a fixed horizon, cut the held-out pieces first (:meth:`~skewpend.Measurements.cut`).

Status: :attr:`~skewpend.Status.SUCCESS` when every step worked; :attr:`~skewpend.Status.NO_CONVERGENCE`
with a one-line message when the data do not determine a parameter (rank-deficient) or the estimate
is not physical; :attr:`~skewpend.Status.NONFINITE` when a held-out simulation failed.
"""

from __future__ import annotations

import copy
import itertools
import math
import time
from dataclasses import dataclass, field, replace
from typing import Any, ClassVar, Dict, List, Optional, Sequence, Tuple

import numpy as np

from ..errors import ParameterError
from ..numeric.conventions import TENSOR_ENTRIES, TENSOR_INDICES
from ..results import DatasetSpec, Result, agree, canonical_json, json_attr, netcdf_reader, protocol_fields
from ..status import Status
from ..config import parameters_toml
from ..schema import (CORE_NAMES, DAMPING_NAMES, FRICTION_NAMES, GEOMETRY_NAMES, MASS_NAMES, ROTOR_NAMES, TORQUE_NAMES,
                      names)
from ..symbolic.model import Parameters
from ..symbolic.regressor import PI_NAMES, SCALE_DIRECTION, base_parameters, linear_estimate, standard_parameters
from .measurements import Measurements, Piece

__all__ = ["identify", "Identification", "SMOOTHING", "ORDER", "BOOTSTRAP", "REFERENCE", "RANK_TOL", "METHODS",
           "CLUSTER_PIECES", "BLOCK", "MIN_CLUSTERS", "clusters", "ChainTerms", "chain_terms", "CHAIN_SAMPLES"]

#: Default Savitzky-Golay window [s].
SMOOTHING = 0.05
#: Savitzky-Golay polynomial order.
ORDER = 4
#: Re-fits on resampled pieces for the intervals.
BOOTSTRAP = 200
#: The base parameter a free swing's estimate is normalised by.
REFERENCE = "J1zz_b"
#: Smallest singular value (of the column-scaled regressor, relative to the largest) for a direction
#: to count as determined.
RANK_TOL = 1e-7
#: The intervals' clusters: with at least this many pieces, each piece is one cluster; with fewer (one
#: long recording is the common case), every piece is cut into blocks of about :data:`BLOCK` seconds of
#: consecutive samples (or shooting segments), each block a cluster.
CLUSTER_PIECES = 5
#: The length of one block [s] when pieces are cut for the intervals (about two swings of a
#: laboratory pendulum: the residuals' correlation -- model error -- decays within it).
BLOCK = 2.0
#: The fewest clusters an interval is computed from (the resampled re-fits need them; 4 degrees of
#: freedom of Student's t); with fewer, the intervals are reported as not available, with the reason.
MIN_CLUSTERS = 5

#: The terms beside the inertial ones that the equations are linear in: Coulomb friction and the
#: rotors' inertia (for given cfs and gr); identified when params0 has them (nonzero).
EXTRA = names(stem="cf") + names(stem="Ir")
#: Fields of Parameters that are not base parameters (they enter the equations nonlinearly or are not
#: in them); ``alpha`` is freed by the output-error fit.
_NOT_LINEAR = CORE_NAMES + tuple(n for n in FRICTION_NAMES + ROTOR_NAMES if n not in EXTRA) + GEOMETRY_NAMES + TORQUE_NAMES

_BASE_CACHE: Dict[Tuple, Any] = {}
_PI_INDEX = {n: j for j, n in enumerate(PI_NAMES)}


def standard_vector(params: Parameters) -> np.ndarray:
    """The standard parameters (:func:`standard_parameters`) and then cf1, cf2, Ir."""
    return np.concatenate([standard_parameters(params), [float(getattr(params, n) or 0.0) for n in EXTRA]])


class _Terms:
    """The base parameters of ``params``' geometry (:func:`base_parameters`) and the friction and
    rotor terms ``params`` has: their regressor columns are the derivative of the derived equations'
    ``M q'' - f`` in ``cf1``, ``cf2``, ``Ir`` (linear in each, at ``params``' ``cfs`` and ``gr``)."""

    def __init__(self, B, params: Parameters):
        import sympy as sp

        from ..symbolic.regressor import lambdify_columns

        self.B = B
        self.extra = tuple(n for n in EXTRA if getattr(params, n))
        self.names = tuple(B.names) + self.extra
        self.unidentifiable = B.unidentifiable
        self.expressions = tuple(B.expressions) + tuple(sp.Symbol(n) for n in self.extra)
        self._fx = None
        if self.extra:
            from ..symbolic.derivation import derive
            from ..symbolic.symbols import SYMBOLS

            eom = derive(params.replace(**{n: None for n in self.extra}))
            ddq = sp.Matrix([SYMBOLS["ddphi"], SYMBOLS["ddpsi"]])
            lhs = eom.mass_matrix * ddq - eom.forcing
            syms = {str(x): x for x in lhs.free_symbols}
            Yx = lhs.jacobian([syms[n] for n in self.extra]).applyfunc(sp.expand)
            if any(str(x) in self.extra for x in Yx.free_symbols):
                raise AssertionError("the equations are not linear in the friction and rotor terms")
            self._fx = lambdify_columns(Yx)

    def regressor(self, q, dq, ddq, a, alpha, g):
        Y = self.B.regressor(q, dq, ddq, a, alpha, g)
        if self._fx is None:
            return Y
        return np.concatenate([Y, self._fx(q, dq, ddq, a, alpha, g)], axis=2)

    def values(self, pi_ext, a: float, alpha: float = 0.0, g: float = 9.81) -> np.ndarray:
        """The base parameters and the terms of an extended standard vector: the standard parameters then
        cf1, cf2, Ir (:func:`standard_vector`), or then only the terms this model has (the shooting's)."""
        pi_ext = np.asarray(pi_ext, dtype=float)
        n = len(PI_NAMES)
        extra = pi_ext[n:] if len(pi_ext) == n + len(self.extra) else pi_ext[n + np.array([EXTRA.index(x) for x in self.extra], int)]
        return np.concatenate([self.B.values(pi_ext[:n], a, alpha, g), extra])


def model_terms(params: Parameters) -> _Terms:
    key = (params.axis1, params.axis2, params.a, params.alpha, params.g,
           tuple(bool(getattr(params, n)) for n in EXTRA), params.cfs, params.gr)
    if key not in _BASE_CACHE:
        inner = (params.axis1, params.axis2, params.a, params.alpha, params.g)
        if inner not in _BASE_CACHE:
            # the symbolic base parameters (seconds of SymPy) kept on disk like the kernels
            from ..numeric.pyfunctions import cached_object

            _BASE_CACHE[inner] = base_parameters(
                params, cache=lambda key, build: cached_object("base_parameters", "symbolic/regressor.py", key, build))
        _BASE_CACHE[key] = _Terms(_BASE_CACHE[inner], params)
    return _BASE_CACHE[key]


# -- the result ----------------------------------------------------------------------------------------
@dataclass(frozen=True, kw_only=True)
class Identification(Result):
    """The result of :func:`identify` (the shared result protocol; ``params`` is the fitted model,
    ``params0`` the start, when the fit is not physical ``params`` is ``params0``).

    * ``names``, ``expressions`` (text), ``values``, ``intervals`` (95 %, r x 2): the base parameters
      (free swing: in ``params0``'s scale of ``reference``);
    * ``reference``, ``ratios`` (name -> value), ``ratio_intervals``: free swing only (else empty);
    * ``undetermined``: the directions the data cannot determine, in words; ``not_entering``: the
      standard parameters that do not enter the equations;
    * ``pieces``, ``residual_rms`` (per fitting piece; N m, free swing in ``params0``'s scale);
    * ``validation``, ``heldout_rms`` (rad per validation piece, fitted model), ``heldout_rms0``
      (``params0``), ``heldout_overall``, ``heldout_overall0``; ``heldout_kind`` ``"angle"`` per piece
      (driven pieces are simulated with their measured torques).
    """

    params0: Parameters
    names: Tuple[str, ...] = ()
    expressions: Tuple[str, ...] = ()
    values: np.ndarray = field(default_factory=lambda: np.zeros(0))
    intervals: np.ndarray = field(default_factory=lambda: np.zeros((0, 2)))
    free: Tuple[str, ...] = ()
    reference: Optional[str] = None
    ratios: Dict[str, float] = field(default_factory=dict)
    ratio_intervals: Dict[str, Tuple[float, float]] = field(default_factory=dict)
    undetermined: Tuple[str, ...] = ()
    not_entering: Tuple[str, ...] = ()
    pieces: Tuple[str, ...] = ()
    residual_rms: np.ndarray = field(default_factory=lambda: np.zeros(0))
    validation: Tuple[str, ...] = ()
    heldout_kind: Tuple[str, ...] = ()
    heldout_rms: np.ndarray = field(default_factory=lambda: np.zeros(0))
    heldout_rms0: np.ndarray = field(default_factory=lambda: np.zeros(0))
    method: str = "linear"
    fit_rms: np.ndarray = field(default_factory=lambda: np.zeros(0))
    alpha: float = math.nan
    alpha_interval: Tuple[float, float] = (math.nan, math.nan)
    alpha_note: str = ""
    profile_alpha: np.ndarray = field(default_factory=lambda: np.zeros(0))
    profile_cost: np.ndarray = field(default_factory=lambda: np.zeros(0))
    correlation: np.ndarray = field(default_factory=lambda: np.zeros((0, 0)))

    result_kind: ClassVar[str] = "identification"

    def _median(self, rms) -> float:
        r = [x for x, k in zip(rms, self.heldout_kind) if k == "angle"]
        return float(np.median(r)) if r else math.nan

    @property
    def heldout_median(self) -> float:
        """The median over held-out angle pieces of each piece's RMS, fitted model [rad]."""
        return self._median(self.heldout_rms)

    @property
    def heldout_median0(self) -> float:
        return self._median(self.heldout_rms0)

    @property
    def heldout_overall(self) -> float:
        """RMS over every held-out angle sample (pieces weighted by their lengths), fitted model."""
        return float(self.stats.get("heldout_overall", math.nan))

    @property
    def heldout_overall0(self) -> float:
        return float(self.stats.get("heldout_overall0", math.nan))

    @property
    def angle(self) -> str:
        """The name of the angle in ``alpha``, ``alpha_interval`` and the profile: the double pendulum's skew angle
        ``alpha`` or a chain's hinge tilt ``tiltK`` (settings' ``angle``)."""
        return str((self.settings or {}).get("angle") or "alpha") if isinstance(self.settings, dict) else "alpha"

    @property
    def intervals_note(self) -> str:
        """What the 95 % intervals were computed from (``clusters: ...``), or why they are not available."""
        return str(self.settings.get("intervals", "")) if isinstance(self.settings, dict) else ""

    def table(self) -> str:
        lines = [f"{'base parameter':<14} {'value':>13} {'95 % interval':>30}   expression"]

        def interval(lo, hi, width=28):
            if math.isfinite(lo) and math.isfinite(hi):
                return f"[{lo:>12.6g}, {hi:>12.6g}]"
            return f"{'(not available)' if self.intervals_note.startswith('95 %') else '(undetermined)':>{width}}"

        for n, e, v, (lo, hi) in zip(self.names, self.expressions, self.values, self.intervals):
            iv = f"{'(params0: the scale)':>28}" if n == self.reference else interval(lo, hi)
            if n not in self.free:
                iv = f"{'(held at 0: its bound)' if n in (self.settings or {}).get('bounded', ()) else '(held at params0)':>28}"
            lines.append(f"{n:<14} {v:>13.6g}  {iv}   {e}")
        if self.ratios:
            lines.append(f"ratios to {self.reference} (what a free swing determines):")
            for n, v in self.ratios.items():
                lo, hi = self.ratio_intervals[n]
                lines.append(f"  {n:<18} {v:>13.6g}  {interval(lo, hi)}")
        if math.isfinite(self.alpha):
            lo, hi = self.alpha_interval
            iv = (f"95 % interval [{math.degrees(lo):.3f}, {math.degrees(hi):.3f}] deg" if math.isfinite(lo) and
                  math.isfinite(hi) else "95 % interval not available")
            lines.append(f"{_angle_words(self.angle)}: {math.degrees(self.alpha):.3f} deg, {iv}"
                         + (f" ({self.alpha_note})" if self.alpha_note else ""))
        if self.intervals_note.startswith("clusters"):
            lines.append(f"95 % intervals: cluster-robust over {self.intervals_note[len('clusters: '):]}")
        elif self.intervals_note:
            lines.append(self.intervals_note)
        lines += [f"undetermined: {u}" for u in self.undetermined]
        if len(self.fit_rms):
            which = "absolute angles" if self.settings.get("angles") == "absolute" else "angles"
            lines.append(f"output error per fitting piece ({which}): median {np.median(self.fit_rms):.4g} rad, "
                         f"max {np.max(self.fit_rms):.4g} rad")
        if len(self.pieces) and self.method == "linear":
            lines.append(f"residual RMS per fitting piece: median {np.median(self.residual_rms):.3g}, "
                         f"max {np.max(self.residual_rms):.3g} N m over {_count(len(self.pieces), 'piece')}")
        fitted = self.params is not self.params0 and self.params != self.params0
        for n, k, r, r0 in zip(self.validation, self.heldout_kind, self.heldout_rms, self.heldout_rms0):
            unit = "rad" if k == "angle" else "N m"
            got = f"{r:.4g} {unit}" if math.isfinite(r) else ("not simulated (no fitted model)" if not fitted
                                                             else "the simulation failed")
            lines.append(f"held out {n}: {k} RMS {got} (params0: {r0:.4g})")
        if len(self.validation):
            lines.append(f"held out: {HELDOUT_PROTOCOL}; the RMS in the {self._angle_words}")
            if fitted:
                lines.append(f"held out angle RMS: median over pieces {self.heldout_median:.4g} rad "
                             f"(params0: {self.heldout_median0:.4g}); overall {self.heldout_overall:.4g} rad "
                             f"(params0: {self.heldout_overall0:.4g})")
                if "heldout_median_joint" in self.stats:
                    lines.append(f"held out angle RMS in the joint angles (skewpend's coordinates): median over pieces "
                                 f"{self.stats['heldout_median_joint']:.4g} rad (params0: "
                                 f"{self.stats['heldout_median0_joint']:.4g})")
            else:
                lines.append(f"held out angle RMS of params0 (no fitted model): median over pieces "
                             f"{self.heldout_median0:.4g} rad; overall {self.heldout_overall0:.4g} rad")
        return "\n".join(lines)

    @property
    def _angle_words(self) -> str:
        if self.settings.get("angles", "relative") == "absolute":
            return "absolute angles (each rod's from the vertical), as measured"
        return "joint angles"

    def summary(self) -> str:
        lines = [f"identification ({self.settings.get('method', '')}): {self.message}",
                 f"{_count(len(self.names), 'base parameter')} from {_count(len(self.pieces), 'piece')}, "
                 f"{self.stats.get('samples', 0)} samples, {self.stats.get('seconds', 0.0):.3g} s"]
        if math.isfinite(self.alpha):
            lo, hi = self.alpha_interval
            lines.append(f"{self.angle} = {math.degrees(self.alpha):.3f} deg, 95 % [{math.degrees(lo):.3f}, {math.degrees(hi):.3f}] deg")
        if len(self.validation) and math.isfinite(self.heldout_median):
            lines.append(f"held out ({self._angle_words}): angle RMS median {self.heldout_median:.4g} rad (params0 "
                         f"{self.heldout_median0:.4g}), overall {self.heldout_overall:.4g} rad (params0 "
                         f"{self.heldout_overall0:.4g})" + (f"; joint angles: median {self.stats['heldout_median_joint']:.4g} "
                                                            f"rad (params0 {self.stats['heldout_median0_joint']:.4g})"
                                                            if "heldout_median_joint" in self.stats else ""))
        elif len(self.validation):
            lines.append(f"held out: no prediction of a fitted model; params0's angle RMS median "
                         f"{self.heldout_median0:.4g} rad, overall {self.heldout_overall0:.4g} rad")
        return "\n".join(lines)

    def _dataset(self) -> DatasetSpec:
        r, n, v = len(self.names), len(self.pieces), len(self.validation)
        ratio_names = list(self.ratios)
        text = "; ".join  # netCDF attributes hold numbers or one string: lists of text joined by "; "
        attrs = {"title": "skewpend identification", "base_names": text(self.names),
                 "base_expressions": text(self.expressions), "free": text(self.free),
                 "reference": self.reference or "", "ratio_names": text(ratio_names),
                 "ratios": [self.ratios[k] for k in ratio_names],
                 "ratio_lower": [self.ratio_intervals[k][0] for k in ratio_names],
                 "ratio_upper": [self.ratio_intervals[k][1] for k in ratio_names],
                 "undetermined": text(self.undetermined), "not_entering": text(self.not_entering),
                 "pieces": text(self.pieces), "validation": text(self.validation),
                 "heldout_kind": text(self.heldout_kind), "params0": canonical_json(self.params0.to_dict()),
                 "method": self.method, "alpha": float(self.alpha),
                 "alpha_interval": [float(x) for x in self.alpha_interval], "alpha_note": self.alpha_note,
                 **self._base_attrs()}
        vals = np.asarray(self.values, dtype=float).reshape(r)
        corr = np.asarray(self.correlation, dtype=float)
        corr = corr.copy() if corr.ndim == 2 and corr.shape[0] == corr.shape[1] else np.zeros((0, 0))
        iv = np.asarray(self.intervals, dtype=float).reshape(r, 2)
        return DatasetSpec(
            variables={
                "value": (("base",), vals.copy(), {"long_name": "base parameter estimate"}),
                "lower": (("base",), iv[:, 0].copy(), {"long_name": "95 % interval, lower end"}),
                "upper": (("base",), iv[:, 1].copy(), {"long_name": "95 % interval, upper end"}),
                "residual_rms": (("piece",), np.asarray(self.residual_rms, dtype=float).reshape(n).copy(),
                                 {"units": "N m", "long_name": "inverse-dynamics residual RMS per fitting piece"}),
                "heldout_rms": (("held_out",), np.asarray(self.heldout_rms, dtype=float).reshape(v).copy(),
                                {"long_name": "held-out RMS, fitted model (rad for angle pieces, N m for torque)"}),
                "heldout_rms0": (("held_out",), np.asarray(self.heldout_rms0, dtype=float).reshape(v).copy(),
                                 {"long_name": "held-out RMS, params0"}),
                "fit_rms": (("fit_piece",), np.asarray(self.fit_rms, dtype=float).copy(),
                            {"units": "rad", "long_name": "output-error angle RMS per fitting piece"}),
                "profile_cost": (("profile",), np.asarray(self.profile_cost, dtype=float).copy(),
                                 {"units": "rad2", "long_name": "profiled sum of squared angle residuals"}),
                "correlation": (("theta", "theta_2"), corr,
                                {"long_name": "correlation of the free parameters (settings' free, in order)"}),
            },
            coords={"base": (("base",), np.arange(r), {"long_name": "index into attribute base_names"}),
                    "piece": (("piece",), np.arange(n), {"long_name": "index into attribute pieces"}),
                    "held_out": (("held_out",), np.arange(v), {"long_name": "index into attribute validation"}),
                    "fit_piece": (("fit_piece",), np.arange(len(self.fit_rms)), {"long_name": "index into attribute pieces"}),
                    "profile": (("profile",), np.asarray(self.profile_alpha, dtype=float).copy(),
                                {"units": "rad", "long_name": "skew angle of the profile"}),
                    "theta": (("theta",), np.arange(len(corr)), {"long_name": "index into settings' free"}),
                    "theta_2": (("theta_2",), np.arange(len(corr)), {"long_name": "index into settings' free"})},
            attrs=attrs,
        )

    def to_run_file(self, path, *, force: bool = False):
        """Write the fitted model as a TOML run file (``--config`` of every command), atomically:
        a comment header saying what was identified (method, data, held-out angle RMS beside
        ``params0``'s, the skew angle if freed, status, undetermined directions), then
        ``[parameters]`` with every model key of ``params`` that is set, numbers written with
        ``repr`` (they read back exactly).  A result whose status is not success is refused
        (:class:`~skewpend.errors.ParameterError`) unless ``force=True``.  Returns the path."""
        return _write_run_file(self, path, force=force)


@netcdf_reader(Identification.result_kind)
def read_identification(path, variables, attrs) -> Identification:
    """An :class:`Identification` from its ``*.nc`` file (``read_identification(path)``, for
    :func:`skewpend.open_result`): a successful fit's stored base parameters must be those of its
    stored model (a model projected onto the nearest physical body, or a failed fit, keeps the
    estimate itself)."""
    from ..errors import SkewpendError
    from ..symbolic.model import AnyModel

    proto = protocol_fields(path, attrs, AnyModel)
    try:
        params0 = AnyModel.from_mapping(json_attr(attrs, "params0"))
    except SkewpendError as exc:
        raise ParameterError(f"{path}: its starting parameters cannot be read back ({exc})") from None

    def names(key):
        return tuple(x for x in str(attrs.get(key, "")).split("; ") if x)

    def numbers(key):
        return [float(x) for x in np.atleast_1d(np.asarray(attrs.get(key, []), dtype=float))]

    ratio_names = names("ratio_names")
    ratios = dict(zip(ratio_names, numbers("ratios")))
    ratio_iv = {k: (lo, hi) for k, lo, hi in zip(ratio_names, numbers("ratio_lower"), numbers("ratio_upper"))}
    values = np.asarray(variables["value"], dtype=float)
    intervals = np.column_stack([np.asarray(variables["lower"], dtype=float), np.asarray(variables["upper"], dtype=float)])
    alpha_iv = numbers("alpha_interval") or [math.nan, math.nan]
    def get(key, empty=(0,)):
        return np.asarray(variables[key], dtype=float) if key in variables else np.zeros(empty)

    result = Identification(
        params0=params0, names=names("base_names"), expressions=names("base_expressions"), values=values,
        intervals=intervals, free=names("free"), reference=str(attrs.get("reference", "")) or None, ratios=ratios,
        ratio_intervals=ratio_iv, undetermined=names("undetermined"), not_entering=names("not_entering"),
        pieces=names("pieces"), residual_rms=get("residual_rms"), validation=names("validation"),
        heldout_kind=names("heldout_kind"), heldout_rms=get("heldout_rms"), heldout_rms0=get("heldout_rms0"),
        method=str(attrs.get("method", "linear")), fit_rms=get("fit_rms"),
        alpha=float(attrs.get("alpha", math.nan)), alpha_interval=(alpha_iv[0], alpha_iv[-1]),
        alpha_note=str(attrs.get("alpha_note", "")),
        profile_alpha=get("profile"), profile_cost=get("profile_cost"), correlation=get("correlation", (0, 0)), **proto)
    if result.status is Status.SUCCESS and "nearest physical body" not in result.message and len(values):
        freed = (result.settings.get("angle") or "alpha") if result.settings.get("alpha_free") else None
        B = _basis(params0, freed)
        if tuple(B.names) != result.names:
            raise ParameterError(f"{path} was written by another model: its base parameters are {list(result.names)}, "
                                 f"the model's are {list(B.names)}")
        agree(path, "base parameters", values, B.beta(B.pi_ext(result.params), B.angle_of(result.params)))
    return result


def _expression_text(expr) -> str:
    """A base parameter's expression as text, long exact rationals (``a**2`` at a measured ``a``)
    shown as 6-digit decimals."""
    import re

    text = str(expr)
    text = re.sub(r"(\d+)\*(\w+)/(\d+)", lambda m: f"{int(m[1]) / int(m[3]):.6g}*{m[2]}", text)
    return re.sub(r"(?<![\w.])(\d+)/(\d+)", lambda m: f"{int(m[1]) / int(m[2]):.6g}", text)


# -- signals ------------------------------------------------------------------------------------------
def _window(dt: float, smoothing: float) -> int:
    w = int(round(smoothing / dt))
    w += 1 - w % 2  # odd
    return max(w, ORDER + 3 - (ORDER % 2))  # at least order + 2, odd


def _uniform(piece: Piece, step: Optional[float] = None):
    """``(t, q, u, dt)``: the piece on a uniform grid of ``step`` (default its median step), uneven or
    other steps resampled by cubic interpolation."""
    from scipy.interpolate import CubicSpline

    t, q, u = np.asarray(piece.t, float), np.asarray(piece.q, float), piece.u
    u = None if u is None else np.asarray(u, float)
    d = np.diff(t)
    dt = float(np.median(d)) if step is None else float(step)
    if d.max() - d.min() > 1e-6 * dt or abs(float(np.median(d)) - dt) > 1e-6 * dt:
        grid = t[0] + dt * np.arange(int(math.floor((t[-1] - t[0]) / dt + 1e-9)) + 1)
        q = CubicSpline(t, q, axis=0)(grid)
        u = None if u is None else CubicSpline(t, u, axis=0)(grid)
        t = grid
    return t, q, u, dt


def _filtered(piece: Piece, smoothing: float):
    """Uniform grid, smoothed q, q', q'', torques, with the edges dropped; and the window."""
    from scipy.signal import savgol_filter

    t, q, u, dt = _uniform(piece)
    w = _window(dt, smoothing)
    if len(t) < 2 * w + ORDER:
        raise ParameterError(f"piece {piece.name!r} has {len(t)} samples, too few for the smoothing window of "
                             f"{w} samples ({smoothing:g} s): pass a smaller smoothing or drop the piece")
    qs, dq, ddq = (savgol_filter(q, w, ORDER, deriv=k, delta=dt, axis=0) for k in range(3))
    us = None if u is None else savgol_filter(u, w, ORDER, axis=0)
    e = w // 2
    s = slice(e, len(t) - e)
    return t[s], qs[s], dq[s], ddq[s], (None if us is None else us[s]), w, dt


# -- the intervals' clusters -------------------------------------------------------------------------
def clusters(piece: np.ndarray, t: np.ndarray, spans: Sequence[Tuple[float, float]]) -> Tuple[np.ndarray, int, str]:
    """The clusters of the intervals for items (samples or shooting segments) of the pieces.

    ``piece`` (n,): each item's piece index; ``t`` (n,): its time; ``spans``: each piece's (first,
    last) time.  Returns ``(cluster, count, text)``: each item's cluster index, the number of
    clusters and a sentence saying what they are.  With at least :data:`CLUSTER_PIECES` pieces the
    clusters are the pieces; with fewer, each piece is cut into ``max(1, floor(duration / BLOCK))``
    blocks of equal length (items by their time), so that one long recording gives a cluster every
    :data:`BLOCK` seconds.  Residuals of different clusters are taken as independent: a block is long
    against the correlation of the noise and, for the output-error fit, holds whole segments, each
    started from its own free state."""
    piece = np.asarray(piece, dtype=int)
    t = np.asarray(t, dtype=float)
    n_pieces = len(spans)
    if n_pieces >= CLUSTER_PIECES:
        return piece.copy(), n_pieces, f"{n_pieces} pieces"
    out = np.zeros(len(piece), dtype=int)
    count = 0
    for k, (t0, t1) in enumerate(spans):
        sel = np.flatnonzero(piece == k)
        if not len(sel):
            continue
        blocks = int(min(max(1, math.floor((t1 - t0) / BLOCK + 1e-9)), len(np.unique(t[sel]))))
        edges = np.linspace(t0, t1, blocks + 1)
        out[sel] = count + np.clip(np.searchsorted(edges, t[sel], side="right") - 1, 0, blocks - 1)
        count += blocks
    # renumber the clusters that hold items 0..count-1
    used, out = np.unique(out, return_inverse=True)
    count = len(used)
    what = "piece" if n_pieces == 1 else f"{n_pieces} pieces"
    return out, count, (f"{_count(count, 'block')} of about {BLOCK:g} s cut from {'the one' if n_pieces == 1 else 'the'} {what}, "
                        f"as there are fewer than {CLUSTER_PIECES} pieces")


def _no_intervals(count: int, text: str, seconds: float) -> str:
    """Why the intervals are not available (fewer than :data:`MIN_CLUSTERS` clusters)."""
    return (f"95 % intervals not available: the data give {count} independent "
            f"{'cluster' if count == 1 else 'clusters'} ({text}), at least {MIN_CLUSTERS} needed -- record at least "
            f"{MIN_CLUSTERS * BLOCK:g} s of motion ({seconds:.3g} s here), or {CLUSTER_PIECES} or more pieces")


# -- the fit ------------------------------------------------------------------------------------------
def _check_input(measurements, params0, validation, smoothing):
    if not isinstance(measurements, Measurements):
        raise ParameterError(f"measurements must be a skewpend Measurements, got {type(measurements).__name__}")
    if len(measurements) == 0:
        raise ParameterError("measurements hold no pieces")
    if validation is not None and not isinstance(validation, Measurements):
        raise ParameterError(f"validation must be a skewpend Measurements or None, got {type(validation).__name__}")
    if not callable(getattr(params0, "as_chain", None)):
        raise ParameterError(f"params0 must be a skewpend Parameters or Chain, got {type(params0).__name__}")
    if not params0.is_numeric:
        raise ParameterError(f"params0 must be numeric; symbolic: {', '.join(params0.symbolic_names)}")
    from ..schema import model_title

    for what, data in (("measurements", measurements), ("validation", validation)):
        if data is not None and data.nq != params0.n:
            raise ParameterError(f"the {what} hold {data.nq} angles, {params0.title} has {params0.n} (one angle a "
                                 f"link): identify {model_title(data.nq)} (params0 a skewpend.Chain of {data.nq} links)")
    from ..checks import positive

    return positive("smoothing", smoothing, cap=60.0)  # a window in seconds


#: The declared unit of the angles is doubted where the free swings' kinetic and potential energies, read as
#: declared, exchange amounts more than this factor apart (log10; a motion of the model exchanges them equally:
#: measured within 1.004 on Kaheman et al.'s rigs; a unit wrong by 180/pi puts them 25-270 times apart) ...
UNIT_IMBALANCE = 1.0
#: ... and read in the other unit, within this one (3.2 times; 1.3 measured there, the angles' offsets unknown).
UNIT_BALANCE = 0.5


def _energy_imbalance(model, pieces, q_of, smoothing: float, centre: bool = False) -> float:
    """How far the free-swing ``pieces`` are from a motion of the model, by its energy: the median over pieces of
    ``log10`` of the spread (5-95 % percentiles) of the kinetic energy over that of the potential energy along
    the piece -- 0 for a free swing, which exchanges the two (damping takes a few % of either), far from it for
    numbers that are no motion of the model.  ``q_of(q, dq) -> (q, dq)`` gives the angles and speeds (speeds
    None: their Savitzky-Golay estimate); ``centre``: each rod's angle from the vertical taken about its median
    (a free swing's is about the hanging rest; a reader's whole-turn shifts in one unit are no whole turns of
    the other).  NaN where there is no free swing."""
    from scipy.signal import savgol_filter

    from ..numeric.kernels import model_kernel, model_vector

    kernel, p = model_kernel(model), model_vector(model)

    def spread(x):
        lo, hi = np.percentile(x, [5.0, 95.0])
        return float(hi - lo)

    logs = []
    for piece in pieces:
        if piece.u is not None and np.any(np.asarray(piece.u, float) != 0.0):
            continue  # driven: the torques' work enters the balance
        w = min(_window(piece.dt, smoothing), len(piece.t) - (len(piece.t) + 1) % 2)
        if w <= ORDER:
            continue
        q, dq = q_of(np.asarray(piece.q, float), None if piece.dq is None else np.asarray(piece.dq, float))
        if centre:
            a = np.cumsum(q, axis=1)
            a -= np.median(a, axis=0)
            q = np.column_stack([a[:, :1], np.diff(a, axis=1)])
        if dq is None:
            dq = savgol_filter(q, w, ORDER, deriv=1, delta=piece.dt, axis=0)
        with np.errstate(all="ignore"):
            e = kernel.energies(np.column_stack([q, dq]), p)
            v = kernel.energies(np.column_stack([q, np.zeros_like(dq)]), p)
        if np.all(np.isfinite(e)) and np.all(np.isfinite(v)) and spread(v) > 0 and spread(e - v) > 0:
            logs.append(math.log10(spread(e - v) / spread(v)))
    return float(np.median(logs)) if logs else math.nan


def unit_check(measurements: Measurements, params0, smoothing: float = SMOOTHING) -> Optional[str]:
    """One line where the unit the measurements declare for their angles (``unit=rad`` or ``unit=deg`` of their
    reader's convention) makes the motion implausible for ``params0`` and the other unit does not: read as
    declared, the free swings' kinetic and potential energies do not exchange (:func:`_energy_imbalance`,
    :data:`UNIT_IMBALANCE`), read in the other unit they do (:data:`UNIT_BALANCE`).  Radians read as degrees
    shrink a large swing into a few degrees whose speeds are far too small for its rises and falls; degrees read
    as radians make it whirl faster than any fall explains.  None where the declared unit is plausible or nothing
    can tell (driven pieces only; a small swing, linear in either unit)."""
    from .measurements import Convention, convert, convert_back

    stated = measurements.metadata.get("convention")
    if not stated or stated.get("unit") not in ("rad", "deg"):
        return None
    declared = Convention(**{**stated, "sign": tuple(stated.get("sign", (1, 1)))})
    other = replace(declared, unit="deg" if declared.unit == "rad" else "rad")

    def reread(q, dq):
        raw, raw_dq, _ = convert_back(q, dq, convention=declared)
        q2, dq2, _ = convert(raw, raw_dq, convention=other)
        return q2, dq2

    try:
        as_declared = _energy_imbalance(params0, measurements, lambda q, dq: (q, dq), smoothing)
        as_other = _energy_imbalance(params0, measurements, reread, smoothing, centre=True)
    except (ParameterError, ValueError, ArithmeticError):
        return None
    if abs(as_declared) > UNIT_IMBALANCE and abs(as_other) <= UNIT_BALANCE:
        names = {"rad": "radians", "deg": "degrees"}
        return (f"the angles look like {names[other.unit]}, not {names[declared.unit]} (unit={declared.unit} declared): "
                f"read so, the free swings' kinetic energy varies {10 ** abs(as_declared):.3g} times "
                f"{'more' if as_declared > 0 else 'less'} than the potential energy a swing exchanges it with (read as "
                f"{names[other.unit]}: within a factor {10 ** abs(as_other):.2g}); give unit={other.unit}")
    return None


def _name_list(free) -> List[str]:
    """``free`` as a list of names (one name alone is a list of one); else one ParameterError."""
    if isinstance(free, str):
        return [free]
    try:
        return [str(f) for f in free]
    except TypeError:
        raise ParameterError(f"free must be a list of names, got {free!r}") from None


def _free(free, names) -> Tuple[str, ...]:
    if free is None:
        return tuple(names)
    free = _name_list(free)
    for f in free:
        if f in names:
            continue
        if f in EXTRA:
            raise ParameterError(f"free: {f} is not in params0's model (it is 0): give params0 a nonzero {f} to "
                                 "identify it")
        if f in _NOT_LINEAR:
            raise ParameterError(f"free: {f} cannot be freed by the linear first estimate (it enters the equations "
                                 f"nonlinearly or is not in them); free base parameters {list(names)}")
        if f in PI_NAMES:
            raise ParameterError(f"free: {f} is not a base parameter of this model; free base parameters "
                                 f"{list(names)}")
        raise ParameterError(f"free: unknown name {f!r}; free base parameters {list(names)}")
    if not free:
        raise ParameterError("free names no parameter")
    return tuple(n for n in names if n in free)


def _solve(G, b, homogeneous, k):
    """Least squares from the normal equations: homogeneous -> eigenvector of the smallest
    eigenvalue normalised so entry k is 1."""
    if homogeneous:
        v = np.linalg.eigh(G)[1][:, 0]
        return v / v[k]
    return np.linalg.solve(G, b)


def _linear(measurements: Measurements, params0, basis, *, free: Optional[Sequence[str]] = None,
            validation: Optional[Measurements] = None, smoothing: float = SMOOTHING,
            bootstrap: int = BOOTSTRAP, seed: int = 0, angles: str = "relative",
            _at_bound: Tuple[str, ...] = ()) -> Identification:
    """The linear first estimate of :func:`identify` (see the module): the base parameters of ``basis``
    (:func:`_basis`) by least squares on the filtered signals, their intervals, the model realising them and
    its held-out prediction."""
    from ..results import t_quantile

    t_start = time.perf_counter()
    B = basis
    names = B.names
    free_names = _free(free, names)
    fi = [names.index(n) for n in free_names]
    xi = [j for j in range(len(names)) if j not in fi]
    angle = B.angle0
    beta0 = B.beta(B.pi_ext(params0), angle)
    driven = [p.u is not None for p in measurements]
    if any(driven) and not all(driven):
        raise ParameterError("measurements mix pieces with and without torques: identify them separately")
    has_tau = all(driven)
    # a free swing stays homogeneous when the held base parameters are all 0 (a joint term held at its
    # bound): they add nothing to either side
    homogeneous = not has_tau and not np.any(beta0[xi])
    k = next((j for j, n in enumerate(names) if _stem(n) == _stem(REFERENCE)), 0)

    # 1-2: filtered signals and the base regressor, per piece
    rows, rhs, times, torques, windows = [], [], [], [], set()
    for p in measurements:
        tf, q, dq, ddq, u, w, _ = _filtered(p, smoothing)
        times.append(tf)
        torques.append(u)
        windows.add(w)
        Y = B.rows(q, dq, ddq, angle)  # (N, n, r)
        tau = np.zeros(q.shape) if u is None else u
        rows.append(Y)
        rhs.append(tau - np.einsum("nij,j->ni", Y[:, :, xi], beta0[xi]) if xi else tau)
    samples = int(sum(len(Y) for Y in rows))
    settings = {"method": "linear (inverse dynamics on Savitzky-Golay filtered signals)",
                "smoothing": smoothing, "order": ORDER, "windows": sorted(windows), "free": list(free_names),
                "reference": names[k] if homogeneous else None, "bootstrap": int(bootstrap), "seed": int(seed),
                "pieces": [p.name for p in measurements], "links": params0.n,
                "validation": [] if validation is None else [p.name for p in validation]}
    not_entering = tuple(B.unidentifiable)
    undetermined = []
    if not has_tau:
        undetermined.append(SCALE_DIRECTION + (" (taken from params0's " + names[k] + ")" if homogeneous
                                               else " (fixed by the base parameters held at params0's values)"))
    if not_entering:
        undetermined.append("do not enter the equations: " + ", ".join(not_entering))
    common = dict(params0=params0, free=free_names, names=names, expressions=B.expressions,
                  undetermined=tuple(undetermined), not_entering=not_entering,
                  pieces=tuple(p.name for p in measurements), settings=settings)

    def failed(message: str) -> Identification:
        data = {"values": np.full(len(names), np.nan), "intervals": np.full((len(names), 2), np.nan), **common}
        return Identification(params=params0, status=Status.NO_CONVERGENCE, message=message,
                              stats={"seconds": time.perf_counter() - t_start, "samples": samples}, **data)

    # rank: singular values of the column-scaled free regressor
    Yf = np.concatenate([Y[:, :, fi] for Y in rows]).reshape(-1, len(fi))
    scale = np.sqrt(np.mean(Yf**2, axis=0))
    if np.any(scale == 0):
        missing = [free_names[j] for j in np.flatnonzero(scale == 0)]
        return failed(f"the data do not determine {', '.join(missing)}; free fewer parameters or add excitation")
    _, s, vt = np.linalg.svd(Yf / scale, full_matrices=False)
    deficient = s[-2] if homogeneous else s[-1]
    if deficient < RANK_TOL * s[0]:
        v = vt[-2] if homogeneous else vt[-1]
        worst = free_names[int(np.argmax(np.abs(v)))]
        return failed(f"the data do not determine {worst}; free fewer parameters or add excitation")

    # 3: the estimate (scaled columns), nominal intervals, then the bootstrap over clusters (pieces, or
    # blocks of them when there are few)
    Ys = Yf / scale
    T = np.concatenate(rhs).reshape(-1)
    est = linear_estimate(Ys, None if homogeneous else T, reference=fi.index(k) if homogeneous else None,
                          names=[names[j] for j in fi])
    # back from the scaled columns: x = y / scale (homogeneous: ratios to the reference)
    unit = scale[fi.index(k)] / scale if homogeneous else 1.0 / scale
    x = est.values * unit
    half = (est.intervals[:, 1] - est.intervals[:, 0]) / 2 * unit
    owner = np.concatenate([np.full(len(Y), j) for j, Y in enumerate(rows)])
    cl, n_cl, cl_text = clusters(owner, np.concatenate(times), [(float(p.t[0]), float(p.t[-1])) for p in measurements])
    seconds = float(sum(p.t[-1] - p.t[0] for p in measurements))
    settings["intervals"] = f"clusters: {cl_text}"
    if n_cl < MIN_CLUSTERS:
        half = np.full(len(fi), np.nan)
        settings["intervals"] = _no_intervals(n_cl, cl_text, seconds)
    elif bootstrap:
        rows_cl = np.repeat(cl, params0.n)  # one equation a joint and sample
        G = np.array([Ys[rows_cl == c].T @ Ys[rows_cl == c] for c in range(n_cl)])  # each cluster's normal equations
        bv = np.array([Ys[rows_cl == c].T @ T[rows_cl == c] for c in range(n_cl)])
        rng = np.random.default_rng(seed)
        draws = []
        for _ in range(int(bootstrap)):
            pick = rng.integers(0, n_cl, n_cl)
            try:
                yb = _solve(G[pick].sum(0), bv[pick].sum(0), homogeneous, fi.index(k) if homogeneous else 0)
            except np.linalg.LinAlgError:
                continue
            draws.append(yb * unit)
        if len(draws) >= 20:
            sd = np.std(np.array(draws), axis=0, ddof=1)
            # the spread over G resampled clusters has G - 1 degrees of freedom (as the output-error sandwich)
            half = np.maximum(half, t_quantile(0.975, n_cl - 1) * sd)
            settings["bootstrap_used"] = len(draws)
    # in params0's units: free swing scaled by params0's reference
    ref_value = beta0[k] if homogeneous else 1.0
    values, halves = beta0.copy(), np.zeros(len(names))
    values[fi], halves[fi] = x * ref_value, half * abs(ref_value)
    intervals = np.column_stack([values - halves, values + halves])
    if homogeneous:  # the scale is params0's: no interval
        intervals[k] = (math.nan, math.nan)
    ratios, ratio_iv = {}, {}
    if homogeneous:
        for j, n in enumerate(free_names):
            if fi[j] != k:
                ratios[f"{n}/{names[k]}"] = float(x[j])
                ratio_iv[f"{n}/{names[k]}"] = (float(x[j] - half[j]), float(x[j] + half[j]))
    resid = []
    for Y, u in zip(rows, torques):  # driven: compared with the filtered torques
        pred = np.einsum("nij,j->ni", Y, values)
        resid.append(float(np.sqrt(np.mean((pred - (0.0 if u is None else u)) ** 2))))
    common.update(values=values, intervals=intervals, reference=names[k] if homogeneous else None, ratios=ratios,
                  ratio_intervals=ratio_iv, residual_rms=np.array(resid))

    # the fitted model
    try:
        fitted, note = B.realise(params0, values, angle, exact=True)
    except ParameterError as exc:
        # a joint term (damping, friction, rotor) below zero with 0 inside its interval: held at the bound
        # and the rest re-estimated (once), as the output-error fit does
        neg = [n for j, n in enumerate(names) if n in free_names and n.rstrip("0123456789") in ("c", "cf", "Ir")
               and values[j] < 0 and values[j] + halves[j] >= 0]
        if neg and not _at_bound:
            again = _linear(measurements, B.zeroed(params0, neg), B, free=[n for n in free_names if n not in neg],
                            validation=validation, smoothing=smoothing, bootstrap=bootstrap, seed=seed, angles=angles,
                            _at_bound=tuple(neg))
            if again.status is not Status.NO_CONVERGENCE or not again.message.startswith("the estimate is not physical"):
                return again
        return failed(f"the estimate is not physical: {exc}")
    check = B.beta(B.pi_ext(fitted), angle)
    if np.abs(check - values).max() > 1e-9 * max(np.abs(values).max(), 1e-300):
        return failed("the fitted model does not reproduce the estimated base parameters")

    # held-out prediction
    status, message = Status.SUCCESS, "identified (linear first estimate)" + (f"; {note}" if note else "")
    if _at_bound:
        message += (f"; held at 0, the bound their estimates crossed within their 95 % intervals (no physical joint "
                    f"has a negative one): {', '.join(_at_bound)}")
        settings["bounded"] = list(_at_bound)
    if not settings["intervals"].startswith("clusters"):
        message += f"; {settings['intervals']}"
    from .shooting import angle_frame

    vnames, kinds, hr, hr0, heldout = _heldout(fitted, params0, validation, smoothing,
                                               frame=angle_frame(params0.n, angles))
    failed_pieces = [n for n, x, x0 in zip(vnames, hr, hr0) if not (math.isfinite(x) and math.isfinite(x0))]
    if failed_pieces:
        status, message = Status.NONFINITE, f"the held-out simulation of {failed_pieces[0]} failed"
    stats = {"seconds": time.perf_counter() - t_start, "samples": samples, "equations": params0.n * samples,
             "sigma2": est.sigma2, "dof": est.dof, **heldout}
    common.pop("params0")
    return Identification(params=fitted, params0=params0, status=status, message=message, stats=stats,
                          validation=tuple(vnames), heldout_kind=tuple(kinds), heldout_rms=np.array(hr),
                          heldout_rms0=np.array(hr0), **common)


#: How a held-out piece is predicted (said with the held-out figures).
HELDOUT_PROTOCOL = ("each piece simulated from its first measured state (its angles and rates) over its length, "
                    "adaptive steps, rtol = atol = 1e-10")
#: The shooting segments' length [s] where the pieces are longer than :data:`WHOLE_PIECES`.
SEGMENT = 0.5
#: Pieces of at most this length [s] are fitted whole (one shooting segment each, from its first state).
#: Measured on Kaheman et al.'s rigs (held-out median angle RMS, each held-out piece simulated from its first
#: measured state; docs/guide/identification.md): the double pendulum's 2.67 s pieces 0.00398 rad in the
#: absolute angles it measured, 0.00293 in the joint angles (segments of 0.5 s: 0.00475 and 0.00316; the
#: authors' model 0.00420 and 0.00328); the triple's 1.54 s pieces 0.00290 and 0.00265 (0.5 s: 0.00338 and
#: 0.00248).  The rigs' long driven pieces (6-10 s) keep :data:`SEGMENT`: a chaotic or driven motion over
#: longer spans is not a well-posed single shooting problem.
WHOLE_PIECES = 3.0


def default_segment(measurements: Measurements) -> float:
    """The shooting segments' length [s] :func:`identify` takes by default: each piece whole (its length, so one
    segment a piece: the fit then predicts each piece from its first state as the held-out pieces are
    predicted) where no piece is longer than :data:`WHOLE_PIECES` s, else :data:`SEGMENT`."""
    longest = max(float(p.t[-1] - p.t[0]) for p in measurements)
    return longest + 1e-9 if longest <= WHOLE_PIECES else SEGMENT


def measured_angles(measurements: Measurements) -> str:
    """The angles the measurements measured, as their reader's convention says (``"absolute"``: each rod's
    from the vertical; ``"relative"``: the joint angles): the default of :func:`identify`'s output error."""
    return "absolute" if measurements.metadata.get("convention", {}).get("second") == "absolute" else "relative"


METHODS = ("output-error", "linear")
#: The profile's grid of |angle - angle0| [deg] near the start (extended by doubling while the cost falls).
PROFILE_GRID = (1.0, 2.0, 4.0)


def identify(measurements: Measurements, params0, *, free: Optional[Sequence[str]] = None,
             validation: Optional[Measurements] = None, method: str = "output-error", smoothing: float = SMOOTHING,
             segment: Optional[float] = None, bootstrap: int = BOOTSTRAP, seed: int = 0,
             progress: Optional[Any] = None, angles: Optional[str] = None) -> Identification:
    """Identify a measured pendulum's base parameters (and, freed, a hinge's tilt): the same stages for any
    model, the double pendulum or a chain of any number of links (the measurements one angle a link).

    ``measurements``: the motion to fit (:class:`~skewpend.Measurements`; torques where measured, a
    free swing without); ``params0``: a numeric model (:class:`~skewpend.Parameters` or
    :class:`~skewpend.Chain`) supplying the geometry (lengths, hinge axes and offsets, ``g``), the masses,
    the entries the data cannot determine, the start of the fit and, for a free swing, the overall scale;
    ``free``: the base parameters to estimate (default all), and one hinge's tilt to estimate too -- ``alpha``
    (the double pendulum's skew angle, its hinge 2's tilt) or ``tiltK`` (a chain's hinge ``K``: its axis turned
    about the vertical ``j`` from the given one; its value is the angle of the axis's projection on the ``(k,
    i)`` plane from ``k`` towards ``i``); ``validation``: held-out pieces, each simulated from its first
    measured state; ``method``: ``"output-error"`` (default: the linear estimate, then multiple shooting with
    exact sensitivities, :mod:`skewpend.analysis.shooting`) or ``"linear"`` (the first estimate alone);
    ``smoothing``: the Savitzky-Golay window [s]; ``segment``: the shooting segments' length [s] (default:
    :func:`default_segment` -- each piece whole, fitted from its first state over its length as a held-out
    piece is predicted, where every piece is at most :data:`WHOLE_PIECES` s long; else :data:`SEGMENT` s);
    ``bootstrap``, ``seed``: the resampled pieces of the intervals; ``progress``: ``callable(stage: str,
    fraction: float)``; ``angles``: the angles the output error and the held-out RMS are measured in,
    ``"relative"`` (the joint angles, skewpend's coordinates) or ``"absolute"`` (each rod's from the vertical,
    as a rig with absolute encoders measures them; :func:`skewpend.analysis.shooting.angle_frame`); default
    the angles the measurements say they measured (:func:`measured_angles`: the reader's convention).  Where
    they are absolute, the held-out RMS in the joint angles is reported beside (``stats``).

    The base parameters come from the cheapest printer the model provides (:func:`_basis`): the exact
    derivation where it keeps its symbolic form (the double pendulum's facade), else the recursive algorithms'
    regressor, found numerically (:func:`chain_terms`).

    >>> import skewpend  # doctest: +SKIP
    >>> fit = skewpend.identify(skewpend.Measurements.from_kaheman("data/kaheman2023", which="fit"),
    ...                         params0, free=None, validation=skewpend.Measurements.from_kaheman(
    ...                         "data/kaheman2023", which="validation"))  # doctest: +SKIP
    """
    if method not in METHODS:
        raise ParameterError(f"method must be one of {', '.join(METHODS)}, got {method!r}")
    from .shooting import angle_frame
    from ..checks import positive

    smoothing = _check_input(measurements, params0, validation, smoothing)
    angles = measured_angles(measurements) if angles is None else angles
    angle_frame(2, angles)  # one line for a wrong name, before any work
    names_free, angle = None, None
    if free is not None:
        names_free = _name_list(free)
        found = [(f, freed_angle(f, params0)) for f in names_free]
        freed = [a for _, a in found if a is not None]
        if len(freed) > 1:
            raise ParameterError(f"free: one hinge's tilt at a time, got {', '.join(f for f, a in found if a)}")
        angle = freed[0] if freed else None
        names_free = [f for f, a in found if a is None]
        if angle and method == "linear":
            raise ParameterError(f"free: {angle} enters the equations nonlinearly: free it with method='output-error'")
        if angle and not names_free:
            names_free = None  # the angle alone: with every base parameter
    seg_len = default_segment(measurements) if segment is None else positive("segment", segment, cap=60.0)
    t_start = time.perf_counter()
    say = progress if callable(progress) else (lambda stage, fraction: None)
    say("checking the angles' unit against params0", 0.0)
    doubt = unit_check(measurements, params0, smoothing)
    if doubt:
        import warnings

        warnings.warn(doubt, UserWarning, stacklevel=2)
    say("linear estimate", 0.0)
    basis = _basis(params0)
    lin = _linear(measurements, params0, basis, free=names_free, validation=validation if method == "linear" else None,
                  smoothing=smoothing, bootstrap=bootstrap, seed=seed, angles=angles)
    if method == "linear" or not np.all(np.isfinite(np.asarray(lin.values, float))):
        return lin  # (a linear estimate that is not physical still starts the output-error fit)
    return _output_error(lin, measurements, params0, basis, angle, validation, smoothing, seg_len, bootstrap, seed,
                         say, t_start, all_free=names_free is None, angles=angles)


# -- a chain of links: its base parameters found numerically from the recursive model ----------------------------
#: States at which a chain's regressor is sampled to find its base parameters (seeded).
CHAIN_SAMPLES = 60
#: Where a hinge's tilt is freed, its base parameters are those of a generic tilt: the given one turned by this
#: much [rad] (a planar chain's own tilt would leave entries out that the tilted chain's equations hold).
GENERIC_TURN = 0.7
#: The step [rad] of the central differences of ``T(tilt)``, and the half-distance of the two sides averaged where
#: the generic base parameters' columns are dependent (the planar tilt itself: ``T`` there is their limit).
TILT_STEP = 1e-5


def turned(axis, angle: float) -> Tuple[float, float, float]:
    """``axis`` turned about the vertical ``j`` by ``angle`` (from ``k`` towards ``i``: ``k`` -> ``(sin, 0, cos)``)."""
    x, y, z = (float(v) for v in axis)
    c, s = math.cos(angle), math.sin(angle)
    return (c * x + s * z, y, c * z - s * x)


def tilt_of(axis) -> float:
    """The tilt of a hinge axis: the angle of its projection on the ``(k, i)`` plane from ``k`` towards ``i`` (the
    double pendulum's alpha for its second hinge, a chain sweep's ``tilt``)."""
    return math.atan2(float(axis[0]), float(axis[2]))


class ChainTerms:
    """The base parameters of a chain of links (its offsets fixed), found numerically: the regressor of the
    standard parameters (``recursive.regressor_function``: ``M q'' - f + tau = Y pi``) at seeded random states,
    its columns taken greedily in the pivot order of the double pendulum's base parameters (each link's ``J zz,
    xz, yz, xy, xx, yy``, then ``h y, x, z``, ``m``; the joints' damping, friction and rotor last), the dependent
    columns as least-squares combinations of the pivots': ``beta = matrix pi``.  ``names``: the pivot's name,
    ``_b`` appended when others move with it; ``expressions`` as text (``J1zz + 0.02986*m2 + ...``);
    ``unidentifiable`` the entries whose columns are zero (they do not enter the equations).

    ``tilt`` (a link, 1-based): that hinge's tilt is a parameter (:func:`tilt_of`; the axis turned about ``j``,
    :func:`turned`): the base parameters are a generic tilt's and ``T(angle)`` (:meth:`T`) is found at each tilt
    asked, its derivative by central differences; the compiled code is the generic tilt's (``generic``)."""

    def __init__(self, chain, tilt: Optional[int] = None):
        from ..numeric.recursive import parameter_names, parameter_vector, regressor_function, standard_names
        from ..numeric.recursive import structure_of_chain
        from ..symbolic.regressor import independent_columns

        n = chain.n
        self.tilt = tilt
        self.angle0 = tilt_of(chain.links[tilt - 1].axis) if tilt else 0.0
        self.axis0 = chain.links[tilt - 1].axis if tilt else None
        self.generic = (chain.replace_link(tilt, axis=turned(self.axis0, GENERIC_TURN)) if tilt else chain)
        structure = structure_of_chain(self.generic)
        self.pi_names = names = standard_names(structure)
        self._fn = regressor_function(structure)
        self._p, self._pi = parameter_vector(chain), self.standard(chain)  # (Y does not depend on pi's value)
        self._i_axis = [parameter_names(n).index(f"e{c}{tilt}") for c in "xyz"] if tilt else []
        rng = np.random.default_rng(0)
        self._states = [(np.concatenate([rng.uniform(-math.pi, math.pi, n), rng.normal(0.0, 3.0, n)]),
                         rng.normal(0.0, 10.0, n)) for _ in range(CHAIN_SAMPLES)]
        W = self._samples(self.angle0 + GENERIC_TURN if tilt else self.angle0)
        prefer = []
        for i in range(1, n + 1):
            prefer += [f"J{i}{e}" for e in ("zz", "xz", "yz", "xy", "xx", "yy")] + [f"h{i}{x}" for x in "yxz"] + [f"m{i}"]
        prefer += [x for x in names if x not in prefer]
        greedy = independent_columns(W, [names.index(x) for x in prefer])
        self._order = sorted(range(len(greedy)), key=lambda k: greedy[k])  # the base parameters in pi's order
        self.pivots = pivots = tuple(greedy[k] for k in self._order)
        self._greedy = greedy  # (the least squares in the order found: the same bits as before the tilt)
        scale = np.linalg.norm(W, axis=0)
        self.unidentifiable = tuple(names[j] for j in np.flatnonzero(scale <= 1e-10 * scale.max()))
        self.dep = [j for j in range(len(names)) if j not in pivots]
        self._cache: Dict[float, np.ndarray] = {}
        self.matrix = self.T(self.angle0)
        out_names, texts = [], []
        for r, j in enumerate(pivots):
            terms = [names[j]] + [f"{self.matrix[r, d]:+.6g}*{names[d]}" for d in self.dep if self.matrix[r, d] != 0.0]
            out_names.append(names[j] + ("_b" if len(terms) > 1 else ""))
            texts.append(" ".join(terms).replace(" +", " + ").replace(" -", " - "))
        self.names, self.expressions = tuple(out_names), tuple(texts)
        self.extra: Tuple[str, ...] = ()

    def _at(self, angle: float) -> np.ndarray:
        p = self._p.copy()
        if self.tilt:
            p[self._i_axis] = turned(self.axis0, angle - self.angle0)
        return p

    def _samples(self, angle: float) -> np.ndarray:
        p, pi = self._at(angle), self._pi
        return np.vstack([np.array(self._fn(y, a, p, pi), dtype=float) for y, a in self._states])

    def T(self, angle: float) -> np.ndarray:
        """``beta = T(angle) pi`` (r x len(pi)): the identity on the pivots, the dependents' combinations."""
        angle = float(angle)
        if angle in self._cache:
            return self._cache[angle]
        W = self._samples(angle)
        P = W[:, list(self.pivots)]
        norms = np.linalg.norm(P, axis=0)
        s = np.linalg.svd(P / np.where(norms > 0, norms, 1.0), compute_uv=False)
        if self.tilt and not s[-1] > 1e-7 * s[0]:  # the generic columns dependent here: their limit
            T = 0.5 * (self.T(angle + TILT_STEP) + self.T(angle - TILT_STEP))
        else:
            Pg = W[:, self._greedy]
            K = np.linalg.lstsq(Pg, W[:, self.dep], rcond=None)[0] if self.dep else np.zeros((len(self.pivots), 0))
            K[np.abs(K) < 1e-10 * max(1.0, float(np.abs(K).max(initial=0.0)))] = 0.0
            miss = float(np.linalg.norm(W[:, self.dep] - Pg @ K)) if self.dep else 0.0
            K = K[self._order]
            if miss > 1e-8 * float(np.linalg.norm(W)):
                raise AssertionError(f"a chain's dependent regressor columns are not combinations of the pivots' ({miss:.3g})")
            T = np.zeros((len(self.pivots), len(self.pi_names)))
            T[np.arange(len(self.pivots)), list(self.pivots)] = 1.0
            T[:, self.dep] = K
        self._cache[angle] = T
        return T

    def dT(self, angle: float) -> np.ndarray:
        return (self.T(angle + TILT_STEP) - self.T(angle - TILT_STEP)) / (2 * TILT_STEP)

    def matrix_functions(self):
        """``(T, dT/dangle)`` as functions of ``(a, angle, g)`` (the symbolic base parameters' signature; a chain's
        lengths and ``g`` are fixed)."""
        return (lambda a, angle, g: self.T(angle)), (lambda a, angle, g: self.dT(angle))

    @staticmethod
    def standard(chain) -> np.ndarray:
        from ..numeric.recursive import standard_vector as chain_standard

        return chain_standard(chain)

    def values(self, pi, angle: Optional[float] = None) -> np.ndarray:
        return (self.matrix if angle is None else self.T(angle)) @ np.asarray(pi, dtype=float)

    def representative(self, beta, pi_ref) -> np.ndarray:
        """The standard vector of ``beta`` with the dependent entries held at ``pi_ref``'s."""
        pi = np.array(pi_ref, dtype=float)
        pi[list(self.pivots)] = np.asarray(beta, float) - self.matrix[:, self.dep] @ pi[self.dep]
        return pi

    def at(self, angle: float) -> "ChainTerms":
        """These base parameters with ``matrix`` at ``angle`` (the realisation's)."""
        if float(angle) == self.angle0:
            return self
        out = copy.copy(self)
        out.matrix = self.T(angle)
        return out

    def rows(self, q, dq, ddq, angle: float) -> np.ndarray:
        """The base regressor at the samples ``(q, q', q'')`` (N x n each): (N, n, r), the pivots' columns of the
        regressor (one function of the state, mapped over the samples)."""
        q, dq, ddq = (np.asarray(x, dtype=float) for x in (q, dq, ddq))
        N, n = q.shape
        if not hasattr(self, "_rows"):
            import casadi as ca

            y, a, p = ca.SX.sym("y", 2 * n), ca.SX.sym("a", n), ca.SX.sym("p", len(self._p))
            self._rows = ca.Function("rows", [y, a, p], [self._fn(y, a, p, self._pi)[:, list(self.pivots)]])
        r, chunk = len(self.pivots), 4096
        out = np.empty((N, n, r))
        p = self._at(angle)
        for s in range(0, N, chunk):
            k = min(chunk, N - s)
            Y = self._rows.map(k)(np.hstack([q[s:s + k], dq[s:s + k]]).T, ddq[s:s + k].T, p).full()
            out[s:s + k] = Y.reshape(n, k, r).transpose(1, 0, 2)
        return out


def chain_terms(chain, tilt: Optional[int] = None) -> ChainTerms:
    """The base parameters of ``chain``'s structure and offsets (:class:`ChainTerms`; ``tilt``: that hinge's
    tilt a parameter)."""
    from ..numeric.recursive import structure_of_chain

    key = ("chain", structure_of_chain(chain).key(), tuple((link.offset, link.axis) for link in chain.links), chain.g, chain.cfs,
           tuple(link.gear for link in chain.links), tilt, chain.links[tilt - 1].axis if tilt else None)
    if key not in _BASE_CACHE:
        _BASE_CACHE[key] = ChainTerms(chain, tilt)
    return _BASE_CACHE[key]


def _chain_of(chain0, terms: ChainTerms, pi: np.ndarray, project: bool = False, as_is: bool = False):
    """The chain whose standard parameters are ``pi`` (bodies through ``c = h/m``, ``I_c = J - (|h|^2 E -
    h h^T)/m``); one ParameterError when a body is no body.  The entries of ``J`` that do not enter the
    equations (:attr:`ChainTerms.unidentifiable`) are set so that the inertia about the centre of mass
    keeps ``chain0``'s there (a rod's moment about its normal ``x`` moves with the one about ``z``).
    ``project``: each inertia about the centre of mass replaced by the nearest physical one (negative
    principal moments raised to 0, then the two smaller raised alike to meet the triangle inequality).
    ``as_is``: every entry ``pi``'s own (a body the fit over physical bodies made)."""
    at = dict(zip(terms.pi_names, pi))
    links = []
    for i, link in enumerate(chain0.links, start=1):
        m = at[f"m{i}"]
        h = np.array([at[f"h{i}{x}"] for x in "xyz"])
        shift = (float(h @ h) * np.eye(3) - np.outer(h, h)) / m
        J = np.zeros((3, 3))
        held = set() if as_is else {e for e in TENSOR_ENTRIES if f"J{i}{e}" in terms.unidentifiable}
        for e, (r, c) in zip(TENSOR_ENTRIES, TENSOR_INDICES):
            J[r, c] = J[c, r] = at[f"J{i}{e}"]
        Ic = J - shift
        I0 = np.asarray(link.inertia, dtype=float)
        for e, (r, c) in zip(TENSOR_ENTRIES, TENSOR_INDICES):
            if e in held:
                Ic[r, c] = Ic[c, r] = I0[r, c]
        for e, other, k in (("xx", "zz", 0), ("zz", "xx", 2)):  # across the rod: the held one moves with the other
            if e in held and other not in held:
                Ic[k, k] = I0[k, k] + (Ic[2 - k, 2 - k] - I0[2 - k, 2 - k])
        if project:
            w, V = np.linalg.eigh((Ic + Ic.T) / 2)
            w = np.maximum(w, 0.0)
            short = w[2] - w[0] - w[1]
            if short > 0:
                w[:2] += short / 2
            Ic = (V * w) @ V.T
        changes = dict(mass=float(m), com=tuple(float(x) for x in h / m), inertia=tuple(tuple(float(x) for x in row) for row in Ic),
                       damping=float(at[f"c{i}"]))
        for stem, key in (("cf", "coulomb"), ("Ir", "rotor")):
            if f"{stem}{i}" in at:
                changes[key] = float(at[f"{stem}{i}"])
        links.append(replace(link, **changes))
    return replace(chain0, links=tuple(links))


def _realise_chain(chain0, terms: ChainTerms, beta: np.ndarray, pi0: np.ndarray, halves: Optional[np.ndarray] = None,
                   start: bool = False):
    """A physical chain with the base parameters ``beta``: ``chain0``'s masses first; else the masses
    that do not enter the equations at all (the first link's, whose first moment and inertia about its
    fixed hinge say everything) scaled by the factor nearest to 1 that realises it (81 factors from 1/5
    to 5, the range of :data:`MASS_FACTORS`), else every mass so (the masses are not determined where
    they are lumped into the first moments and inertias; the base parameters are kept exactly).  A body on the edge of the physical (a slender rod: no
    moment about its own axis) may land a little outside: then the nearest physical bodies, accepted
    when they move no base parameter both by more than 1 % and beyond its 95 % half-width ``halves``
    (the note says by how much); ``start``: the nearest physical bodies whatever they move (the start of
    the fit over physical bodies, not a model).  Returns ``(chain, note)``, or ``(None, why)``."""
    pi = terms.representative(beta, pi0)
    for j, name in enumerate(terms.pi_names):  # the joints' terms do not move with the masses
        stem = name.rstrip("0123456789")
        if stem in ("c", "cf", "Ir") and pi[j] < 0:
            what = {"c": "viscous damping", "cf": "Coulomb friction", "Ir": "rotor inertia"}[stem]
            return None, (f"{name} = {pi[j]:.4g} < 0: the data want a negative {what} in joint {name[len(stem):]} "
                          f"(the model's joint terms do not fit there); hold {name} at params0's value (free=)")
    masses = [terms.pi_names.index(f"m{i}") for i in range(1, chain0.n + 1)]
    loose = [j for j in masses if terms.pi_names[j] in terms.unidentifiable]
    # a fine grid of factors from 1/5 to 5, the nearest to params0's first (MASS_FACTORS' range)
    grid = np.geomspace(1.0 / MASS_FACTORS[-1], MASS_FACTORS[-1], 81)
    factors = [float(x) for x in grid[np.argsort(np.abs(np.log(grid)))] if abs(math.log(x)) > 1e-12]
    trials = [(1.0, masses)] + [(k, loose) for k in factors if loose] + [(k, masses) for k in factors]
    def scaled(k, which):  # the standard vector of beta, the masses ``which`` scaled by k
        ref = pi0.copy()
        ref[which] *= k
        return terms.representative(beta, ref)

    first, last = "", ""
    for k, which in trials:
        try:
            chain = _chain_of(chain0, terms, scaled(k, which))
        except ParameterError as exc:
            first, last = first or str(exc), str(exc)
            continue
        what = "every mass" if which is masses else ", ".join(terms.pi_names[j] for j in which)
        return chain, ("" if k == 1.0 else f"{what} scaled x{k:.3g} from params0's, which cannot realise the "
                       f"estimate ({first}); a free swing does not determine {'the masses' if which is masses else 'it'}")
    # the nearest physical bodies, at the masses (of those tried) where they move the base parameters least
    big = 1e-2 * float(np.max(np.abs(beta)))  # a near-zero entry (a product of inertia) on the others' scale
    half = np.full(len(beta), np.inf) if halves is None else np.where(np.isfinite(halves), halves, np.inf)
    best = None
    for k, which in trials:
        chain = _chain_of(chain0, terms, scaled(k, which), project=True)
        moved = terms.values(terms.standard(chain)) - np.asarray(beta, float)
        rel = np.abs(moved) / np.maximum(np.abs(beta), big)
        if best is None or rel.max() < best[1].max():
            best = (chain, rel, moved)
    chain, rel, moved = best
    over = [terms.names[j] for j in range(len(beta)) if rel[j] > 0.01 and abs(moved[j]) > half[j]]
    if not over or start:
        return chain, (f"the estimate lies just outside the physical bodies ({first}); the model is the nearest "
                       f"physical body (base parameters moved by at most {100 * float(rel.max()):.2g} %)")
    return None, first if last == first else f"{first} (with the masses scaled x{factors[-1]:g}: {last})"


# -- the model's base parameters: one interface, two printers -----------------------------------------------
class _Exact:
    """The base parameters from the specification's exact derivation (:mod:`skewpend.symbolic.regressor`), for a
    model that keeps its symbolic form (the double pendulum's facade): ``generic`` -- the skew angle alpha a
    parameter (every skew's base parameters).  The interface :func:`identify` asks (:class:`_Recursive` is the
    other): ``names``, ``expressions``, ``unidentifiable``, ``terms`` (for the shooting), ``angle`` (the freed
    angle's name, or None) and ``angle0``; ``beta``, ``pi_ext``, ``rows``, ``with_angle``, ``angle_of``,
    ``zeroed``, ``realise``, ``nearest``, ``model_of``."""

    def __init__(self, params, generic: bool = False):
        self.terms = model_terms(params.replace(alpha=None) if generic else params)
        self.a, self.g = float(params.a), float(params.g)
        self.angle = "alpha" if generic else None
        self.name = "alpha"  # the model's skew angle, freed or not
        self.angle0 = self.angle_of(params)
        self.names, self.unidentifiable = self.terms.names, tuple(self.terms.unidentifiable)
        self.expressions = tuple(_expression_text(e) for e in self.terms.expressions)

    @staticmethod
    def angle_of(model) -> float:
        return float(model.alpha) if model.alpha is not None else 0.0

    def beta(self, pi, angle: float) -> np.ndarray:
        return self.terms.values(pi, self.a, angle, self.g)

    def rows(self, q, dq, ddq, angle: float) -> np.ndarray:
        return self.terms.regressor(q, dq, ddq, self.a, angle, self.g)

    @staticmethod
    def with_angle(model, angle: float):
        return model.replace(alpha=angle)

    @staticmethod
    def zeroed(model, names: Sequence[str]):
        return model.replace(**{n: 0.0 for n in names})

    def realise(self, model0, beta, angle: float, held: Sequence[str] = (), halves=None, exact: bool = False):
        """``(model, note)`` with the base parameters ``beta``; one ParameterError when no physical model has them
        (``exact``: params0's masses and free entries only)."""
        if exact:
            return _realise(model0, self.terms, beta, self.a, angle, self.g), ""
        return _realise_masses(model0, self.terms, beta, self.a, angle, self.g, held=held)

    def nearest(self, model0, beta, angle: float, held: Sequence[str]):
        return _realise(model0, self.terms, beta, self.a, angle, self.g, held=held, project=True)

    def pi_ext(self, model) -> np.ndarray:
        """The standard vector with the friction and rotor terms after it (the shooting's ``pi``)."""
        return np.concatenate([standard_parameters(model), [float(getattr(model, x) or 0.0) for x in self.terms.extra]])

    def model_of(self, model0, pi, angle: float):
        """The model of a physical fit's standard vector ``pi`` (bodies as masses, centres and inertias)."""
        changes: Dict[str, Any] = {n: float(pi[_PI_INDEX[n]]) for n in DAMPING_NAMES}
        changes.update({x: float(v) for x, v in zip(self.terms.extra, pi[len(PI_NAMES):])})
        for i in (1, 2):
            m = float(pi[_PI_INDEX[f"m{i}"]])
            c, _, ic = _body(pi, i, m)
            changes[f"m{i}"] = m
            changes.update(_body_changes(i, c, ic))
        if self.angle:
            changes["alpha"] = float(angle)
        return model0.replace(**changes)


#: The joint terms of a chain's link, by the stem of their standard parameter.
_JOINT_KEYS = {"c": "damping", "cf": "coulomb", "Ir": "rotor"}


class _Recursive:
    """The base parameters found numerically from the recursive algorithms (:class:`ChainTerms`), for any chain
    of links; ``tilt`` (a link): that hinge's tilt a parameter.  The interface of :class:`_Exact`."""

    def __init__(self, chain, tilt: Optional[int] = None):
        self.terms = chain_terms(chain, tilt)
        self.tilt = tilt
        self.angle = f"tilt{tilt}" if tilt else None
        self.name = self.angle
        self.angle0 = self.terms.angle0
        self.names, self.unidentifiable, self.expressions = self.terms.names, self.terms.unidentifiable, self.terms.expressions

    def angle_of(self, model) -> float:
        return tilt_of(model.links[self.tilt - 1].axis) if self.tilt else 0.0

    def standard(self, model) -> np.ndarray:
        return self.terms.standard(model)

    pi_ext = standard

    def beta(self, pi, angle: float) -> np.ndarray:
        return self.terms.values(pi, angle)

    def rows(self, q, dq, ddq, angle: float) -> np.ndarray:
        return self.terms.rows(q, dq, ddq, angle)

    def with_angle(self, model, angle: float):
        if not self.tilt:
            return model
        return model.replace_link(self.tilt, axis=turned(self.terms.axis0, angle - self.angle0))

    @staticmethod
    def zeroed(model, names: Sequence[str]):
        for n in names:
            stem = n.rstrip("0123456789")
            model = model.replace_link(int(n[len(stem):]), **{_JOINT_KEYS[stem]: 0.0})
        return model

    def _held(self, model0, terms: ChainTerms, beta, held: Sequence[str]) -> np.ndarray:
        """``beta`` with the held inertia entries (the data do not determine them here) taken from ``model0``'s own
        inertia about each body's new centre of mass, as the double pendulum's realisation holds them (held about
        the hinge, a centre moved by the fit would leave a slender rod no body)."""
        rows = [k for k, n in enumerate(self.names) if n in held and n.startswith("J")]
        if not rows:
            return np.asarray(beta, float)
        pi = terms.representative(beta, self.standard(model0))
        for k in rows:
            j = terms.pivots[k]
            name = terms.pi_names[j]  # J{i}{entry}
            i, entry = int(name[1:-2]), name[-2:]
            m = pi[terms.pi_names.index(f"m{i}")]
            c = np.array([pi[terms.pi_names.index(f"h{i}{x}")] for x in "xyz"]) / m
            J = np.asarray(model0.links[i - 1].inertia, float) + m * (float(c @ c) * np.eye(3) - np.outer(c, c))
            pi[j] = J[TENSOR_INDICES[TENSOR_ENTRIES.index(entry)]]
        out = np.array(beta, float)
        out[rows] = terms.values(pi)[rows]
        return out

    def realise(self, model0, beta, angle: float, held: Sequence[str] = (), halves=None, exact: bool = False):
        model0, terms = self.with_angle(model0, angle), self.terms.at(angle)
        fitted, note = _realise_chain(model0, terms, self._held(model0, terms, beta, held), self.standard(model0), halves)
        if fitted is None or "nearest physical body" in note:  # a projection is a start, never the model
            raise ParameterError(note)
        return fitted, note

    def nearest(self, model0, beta, angle: float, held: Sequence[str]):
        model0, terms = self.with_angle(model0, angle), self.terms.at(angle)
        fitted, note = _realise_chain(model0, terms, self._held(model0, terms, beta, held), self.standard(model0),
                                      start=True)
        if fitted is None:
            raise ParameterError(note)
        return fitted

    def model_of(self, model0, pi, angle: float):
        return _chain_of(self.with_angle(model0, angle), self.terms, pi, as_is=True)


def _basis(model, angle: Optional[str] = None):
    """The base parameters of ``model`` (``angle``: the name of a hinge's tilt it frees, checked), from the cheapest
    printer it provides: the exact derivation where it keeps its symbolic form, else the recursive algorithms."""
    try:
        return _Exact(model, generic=angle is not None)
    except AttributeError:  # no symbolic form (a chain of links): its numbers
        return _Recursive(model, int(angle[len("tilt"):]) if angle else None)


def freed_angle(name: str, model) -> Optional[str]:
    """``name`` as the angle a fit frees (``alpha`` where the model has it in ``p``, else ``tiltK``), None if it
    names no angle; one line when it names one this model cannot free."""
    from ..numeric.kernels import model_vector_names
    from ..schema import link_field_of

    has_alpha = "alpha" in model_vector_names(model)
    if name == "alpha":
        if has_alpha:
            return "alpha"
        raise ParameterError(f"free: alpha is the double pendulum's skew angle; {model.title} frees its hinge "
                             f"{link_field_of('alpha')[1]}'s tilt as tilt{link_field_of('alpha')[1]} (tilt1 to tilt{model.n})")
    stem, digits = name.rstrip("0123456789"), name[len(name.rstrip("0123456789")):]
    if stem != "tilt":
        return None
    k = int(digits) if digits else 0
    if not 1 <= k <= model.n:
        raise ParameterError(f"free: {name!r} names no hinge of {model.title}: tilt1 to tilt{model.n}")
    if has_alpha:
        if k == link_field_of("alpha")[1]:
            return "alpha"
        raise ParameterError(f"free: {name}: {model.title} frees its skew angle alpha (tilt{link_field_of('alpha')[1]}) "
                             "only")
    axis = model.as_chain().links[k - 1].axis
    if abs(axis[0]) < 1e-12 and abs(axis[2]) < 1e-12:
        raise ParameterError(f"free: {name}: hinge {k}'s axis is the vertical j, which turning about j does not move; "
                             "free another hinge's tilt")
    return name


def _angle_words(name: str) -> str:
    """The freed angle in words: ``skew angle alpha``, ``hinge 3's tilt (tilt3)``."""
    return "skew angle alpha" if name == "alpha" else f"hinge {name[len('tilt'):]}'s tilt ({name})"


def _signals(piece: Piece, smoothing: float, step: Optional[float] = None):
    """A piece on a uniform grid of ``step`` (default its median step): ``(t, q, q_smooth,
    dq_smooth, u)`` (the whole length; smoothed start states for the shooting nodes)."""
    from scipy.signal import savgol_filter

    t, q, u, dt = _uniform(piece, step)
    w = min(_window(dt, smoothing), len(t) - (len(t) + 1) % 2)
    qs = savgol_filter(q, w, ORDER, axis=0)
    dqs = savgol_filter(q, w, ORDER, deriv=1, delta=dt, axis=0)
    return t, q, qs, dqs, u


def _stem(name: str) -> str:
    return name[:-2] if name.endswith("_b") else name


def _output_error(lin: Identification, measurements, params0, basis, angle, validation, smoothing, segment,
                  bootstrap, seed, say, t_start, all_free: bool = True, angles: str = "relative") -> Identification:
    from . import shooting
    from ..symbolic.regressor import independent_columns, sample_states

    angle_free = angle is not None
    alpha0 = basis.angle0
    homogeneous = lin.reference is not None
    ref = lin.reference
    # one sampling step for every piece (the coarsest piece's median step; finer ones resampled)
    step = max(float(np.median(np.diff(np.asarray(p.t, float)))) for p in measurements)
    signals = [_signals(p, smoothing, step) for p in measurements]
    seg = shooting.segments(signals, [p.name for p in measurements], segment)
    n_pieces = len(measurements)
    start_y0 = seg.y0.copy()
    spans = [(float(s[0][0]), float(s[0][-1])) for s in signals]
    cl, n_cl, cl_text = clusters(seg.piece, seg.t0, spans)
    freed = tuple(lin.free) + tuple(lin.settings.get("bounded", ()))  # (the linear estimate's bound freed again)
    stems = {_stem(n) for n in freed}
    settings = dict(lin.settings)
    settings.update(method="output-error (multiple shooting, RK4 with exact sensitivities)", segment=segment, angles=angles,
                    whole_pieces=bool(seg.piece.size == len(measurements) and len(np.unique(seg.piece)) == len(seg)),
                    step=seg.h, segments=len(seg), alpha_free=angle_free, angle=angle or basis.name,
                    intervals=f"clusters: {cl_text}" if n_cl >= MIN_CLUSTERS else
                    _no_intervals(n_cl, cl_text, float(sum(b - a for a, b in spans))))
    if not angle_free:
        B = basis
        names = B.names
        # the linear estimate starts the fit; where it is not physical (noisy accelerations), params0 does
        beta0 = np.asarray(lin.values if lin.status is Status.SUCCESS else B.beta(B.pi_ext(params0), alpha0), float)
        free = [n for n in names if n in freed and n != ref]
    else:
        B = _basis(params0, angle)  # every tilt: the generic base parameters
        alpha0 = B.angle0
        settings["angle0"] = alpha0
        names = B.names
        if lin.status is Status.SUCCESS:
            beta0 = B.beta(B.pi_ext(lin.params), alpha0)
        elif tuple(lin.names) == tuple(B.names):
            beta0 = np.asarray(lin.values, float)
        else:
            beta0 = B.beta(B.pi_ext(params0), alpha0)
        # the base parameters the data determine near alpha0 (the others are held at the start's values)
        q, dq, ddq = sample_states(40, 0, params0.n)
        A = B.rows(q, dq, ddq, alpha0).reshape(-1, len(names))
        det = [names[j] for j in independent_columns(A, range(len(names)))]
        free = [n for n in names if n in det and _stem(n) in stems and n != ref]

        def refree(alpha: float) -> None:
            """Free every base parameter the data determine at ``alpha`` (away from alpha0 the tilt
            brings the inertia entries the near-planar fit held into the equations)."""
            A = B.rows(q, dq, ddq, alpha).reshape(-1, len(names))
            det = [names[j] for j in independent_columns(A, range(len(names)))]
            free[:] = [n for n in names if n in det and (_stem(n) in stems or n not in lin_names) and n != ref]

        lin_names = set(lin.names)
    # the start: the linear estimate where it is usable, else params0 (said in the message).  At a
    # nonzero skew with noisy accelerations the linear estimate can be far off or no body at all; the
    # start whose segments miss the data less (before any iteration) is taken
    beta_p0 = np.asarray(B.beta(B.pi_ext(params0), alpha0), float)
    frame = shooting.angle_frame(params0.n, angles)
    start_note = ""
    if not np.array_equal(np.asarray(beta0, float), beta_p0):
        c_lin = shooting.start_cost(B.terms, params0, beta0, alpha0, seg, frame)
        c_p0 = shooting.start_cost(B.terms, params0, beta_p0, alpha0, seg, frame)
        if not c_lin <= c_p0:
            npts = params0.n * float(seg.mask.sum())
            if not math.isfinite(c_lin) or lin.status is not Status.SUCCESS:
                why = "; ".join(x for x in ((_one_line(lin.message) if lin.status is not Status.SUCCESS else ""),
                                            ("" if math.isfinite(c_lin) else "its simulation is not finite")) if x)
                start_note = (f"the linear estimate is unusable as the start ({why}): the output-error fit started "
                              "from params0")
            else:
                start_note = (f"the output-error fit started from params0, whose segments miss the angles less than the "
                              f"linear estimate's ({math.sqrt(c_p0 / npts):.3g} against {math.sqrt(c_lin / npts):.3g} rad)")
            beta0 = beta_p0
    elif lin.status is not Status.SUCCESS:
        start_note = (f"the linear estimate is unusable as the start ({_one_line(lin.message)}): the output-error fit "
                      "started from params0")
    settings["start"] = "params0" if start_note else "linear estimate"

    def run(beta, alpha, free_alpha, y0, iterations=60, boot=0, tol=1e-10):
        seg.y0[:] = y0
        try:
            sf = shooting.fit(B.terms, params0, beta, free, alpha, free_alpha, seg, pieces=n_pieces,
                              max_iterations=iterations, bootstrap=boot, seed=seed, tol=tol, cluster=cl, frame=frame,
                              angle_name=angle or "alpha")
        except np.linalg.LinAlgError as exc:  # a normal matrix LAPACK cannot take (no information, or not finite)
            raise FloatingPointError(f"its normal equations cannot be solved ({str(exc).lower()})") from None
        if n_cl < MIN_CLUSTERS:  # too few clusters for an interval: none (the reason is in settings)
            sf.half = np.full_like(sf.half, np.nan)
        return sf

    say("output-error fit", 0.1)
    try:
        sf = run(beta0, alpha0, False, start_y0, boot=0 if angle_free else bootstrap)
    except FloatingPointError as exc:
        return _oe_failed(lin, f"the output-error fit failed: {exc}", settings, t_start)
    alpha_hat, a_lo, a_hi, note = math.nan, math.nan, math.nan, ""
    prof_a: List[float] = []  # the profile: angles, costs
    prof_c: List[float] = []
    try:  # a later fit (the angle's profile, a refit at a bound) can fail as the first can
        if angle_free:
            sf, alpha_hat, (a_lo, a_hi), note, prof_a, prof_c = _skew_search(run, sf, alpha0, bootstrap, seed, say, refree,
                                                                              angle)
        # a joint term (damping, friction, rotor inertia) estimated below zero with 0 inside its interval: no
        # physical joint has it, so it is held at the bound 0 and the rest re-fitted -- the model is then that
        # fit's estimate, not the estimate with one entry clipped (which misses the data by more)
        bounded: List[str] = []
        if sf.converged and not sf.flat:
            th, hw = dict(zip(sf.theta_names, sf.theta)), dict(zip(sf.theta_names, sf.half))
            neg = [n for n in free if _stem(n).rstrip("0123456789") in ("c", "cf", "Ir") and th.get(n, 0.0) < 0]
            if neg and all(math.isfinite(hw.get(n, math.nan)) and th[n] + hw[n] >= 0 for n in neg):
                b = np.array(sf.beta, float)
                b[[names.index(n) for n in neg]] = 0.0
                kept = list(free)
                free[:] = [n for n in free if n not in neg]
                refit = run(b, sf.alpha, angle in sf.theta_names, sf.y0, boot=bootstrap)
                if refit.converged and not refit.flat:
                    bounded = [f"{n} (estimate {th[n]:.3g} +- {hw[n]:.2g})" for n in neg]
                    sf = refit
                    if angle in sf.theta_names and math.isfinite(float(sf.half[-1])):
                        h = float(sf.half[-1])
                        est = float(sf.alpha)
                        if "mirror" in note:  # reported on alpha0's side, as the skew search does
                            est = _start_side(est, alpha0)
                        alpha_hat, a_lo, a_hi = est, est - h, est + h
                else:
                    free[:] = kept
    except FloatingPointError as exc:
        return _oe_failed(lin, f"the output-error fit failed: {exc}", settings, t_start)
    at_bound = {b.split(" ")[0] for b in bounded}
    held = [n for n in names if n not in free and n != ref]
    beta = sf.beta
    theta = dict(zip(sf.theta_names, sf.theta))
    half = dict(zip(sf.theta_names, sf.half))
    values = np.asarray(beta, float)
    halves = np.array([half.get(n, 0.0) for n in names])
    intervals = np.column_stack([values - halves, values + halves])
    for j, n in enumerate(names):
        if n in sf.flat or (n in half and not math.isfinite(half[n])) or n == ref:  # (the scale: params0's)
            intervals[j] = (math.nan, math.nan)
    ratios, ratio_iv = _ratios(names, values, intervals, ref, theta) if homogeneous else ({}, {})
    alpha_fit = alpha_hat if angle_free else alpha0
    unphysical, realised, phys, why = "", "", None, None
    # reported on alpha0's side of a mirror-symmetric profile, the model at alpha_fit is the estimate's mirror
    # image, which is not the estimate's base parameters at -alpha: it is fitted there (below), not assumed
    mirrored = angle in sf.theta_names and math.isfinite(alpha_hat) and alpha_hat != float(sf.alpha)
    model0 = B.with_angle(params0, alpha_fit) if angle_free else params0
    try:
        fitted, realised = B.realise(model0, values, alpha_fit, held=held,
                                     halves=np.where(np.isfinite(halves) & (halves > 0), halves, np.inf))
    except ParameterError as exc:
        fitted, why = None, exc
    # the estimate is the best the data allow near here: where even it is no fit of the data (a wrong model, the
    # data read wrongly), no physical model is either, and the fit over physical bodies is not run
    seg.y0[:] = sf.y0
    estimate = consistency(float(sf.cost), seg, measurements, frame)
    hopeless = not (sf.converged and not sf.flat and estimate.ok)
    if hopeless and why is not None:
        unphysical = estimate.text if not estimate.ok else f"the output-error estimate is not physical: {why}"
    if (why is not None or mirrored) and not hopeless:
        # no physical body has these base parameters (a slender rod is on the edge of the physical: no moment
        # about its own axis, and the estimate lands a little outside), or the model is the mirror image: the
        # output-error fit again over the physical bodies only, from the nearest one (a projection or a
        # realisation is a start, never the model)
        # (it stops when an iteration gains less than a thousandth of the noise's chi-square allowance)
        n_res = float(seg.mask.sum()) * seg.q.shape[2]
        fitted, phys, unphysical = _fit_physical(params0, B, values, sf, seg, held, ref, alpha_fit, angle_free, why,
                                                 frame, fitted,
                                                 1e-3 * _allowance(n_res) * n_res * angle_noise(measurements) ** 2)
        realised = ""
    if phys is not None:  # the constrained fit's estimate, the unconstrained intervals' half-widths about it
        settings["physical_fit"] = {"iterations": phys.iterations, "converged": phys.converged,
                                    "message": phys.message, "seconds": phys.seconds}
        alpha_fit = phys.alpha if angle_free else alpha0
        values = np.asarray(phys.beta, float)
        intervals = values[:, None] + (intervals - np.asarray(beta, float)[:, None])
        if len(prof_a) and math.isfinite(alpha_hat):
            # the profile's own point is the model's (and, mirrored, its mirror image's), not the estimate it replaced
            mirror = {alpha_hat: phys.alpha, 2 * alpha0 - alpha_hat: 2 * alpha0 - phys.alpha}
            pts = sorted((mirror.get(x, x), phys.cost if x in mirror else c) for x, c in zip(prof_a, prof_c))
            prof_a, prof_c = [x for x, _ in pts], [c for _, c in pts]
        if angle_free and math.isfinite(alpha_hat):
            a_lo, a_hi = alpha_fit + (a_lo - alpha_hat), alpha_fit + (a_hi - alpha_hat)
            alpha_hat = alpha_fit
        if homogeneous:
            ratios, ratio_iv = _ratios(names, values, intervals, ref, theta)
    if fitted is not None:
        check = B.beta(B.pi_ext(fitted), alpha_fit)
        keep = [j for j, n in enumerate(names) if n not in held]
        tol = 1e-9 * max(np.abs(values).max(), 1e-300)
        values = np.where([n in held for n in names], check, values)  # held: the body's own, at its new centre
        if np.abs(check[keep] - values[keep]).max() > tol:
            return _oe_failed(lin, "the fitted model does not reproduce the estimated base parameters", settings,
                              t_start)
    # the realisation's status, unless the fit did not converge or left a direction undetermined; no model: the
    # estimate and its intervals are reported, the model stays params0
    status, message = Status.SUCCESS, "identified (output error, multiple shooting)" + (f"; {realised}" if realised else "")
    if not sf.converged:
        status, message = Status.NO_CONVERGENCE, f"the output-error fit did not converge: {sf.message}"
    elif sf.flat:
        status, message = Status.NO_CONVERGENCE, (f"the data do not determine {', '.join(sf.flat)}: free fewer "
                                                  "parameters or add excitation")
    elif fitted is None:
        status, message = Status.NO_CONVERGENCE, unphysical
    # the claim: the model returned explains the data to their noise, or to a model error small beside the
    # motion (see consistency) -- its own output error; a model constrained to the physical bodies besides
    # misses the angles by no more than the estimate does plus the noise's chi-square allowance
    seg.y0[:] = sf.y0
    if phys is not None:
        model_cost = phys.cost
    elif realised:  # the same base parameters with other masses: its own simulation
        model_cost = shooting.start_cost(B.terms, params0, B.beta(B.pi_ext(fitted), alpha_fit), alpha_fit, seg, frame)
    else:
        model_cost = float(sf.cost)
    verdict = consistency(model_cost, seg, measurements, frame)
    if status is Status.SUCCESS and not verdict.ok:
        status, message = Status.NO_CONVERGENCE, verdict.text
    elif status is Status.SUCCESS and verdict.text:
        message += f"; {verdict.text}"
    if phys is not None:
        excess = physical_excess(phys.cost, float(sf.cost), seg, measurements,
                                 "the estimate lies outside the physical bodies" if why is not None else
                                 f"the estimate is at {angle} = {math.degrees(sf.alpha):.6g} deg, the mirror image of "
                                 "the side reported")
        verdict.stats.update(excess.stats)
        if status is Status.SUCCESS and excess.ok:
            message += f"; {excess.text}"
        elif status is Status.SUCCESS:
            status, message = Status.NO_CONVERGENCE, excess.text
    if bounded and status is Status.SUCCESS:
        message += (f"; held at 0, the bound their estimates crossed within their 95 % intervals (no physical joint "
                    f"has a negative one): {', '.join(bounded)}")
    settings["bounded"] = sorted(at_bound) if bounded else []
    if start_note:
        message += f"; {start_note}"
    say("held-out prediction", 0.9)
    vnames, kinds, hr, hr0, stats_extra = _heldout(fitted, params0, validation, smoothing, frame=frame)
    stats_extra.update(verdict.stats)
    if any(not math.isfinite(x) for x in hr) and status is Status.SUCCESS:
        status, message = Status.NONFINITE, "a held-out simulation failed"
    if status is Status.SUCCESS and not settings["intervals"].startswith("clusters"):
        message += f"; {settings['intervals']}"
    # the entries that do not enter the equations are the fitted model's (with the tilt freed, the generic
    # tilt's: a near-planar start's list would name entries the fit estimated, J2xy ...)
    undetermined = [u for u in lin.undetermined if not u.startswith("do not enter the equations")]
    if B.unidentifiable:
        undetermined.append("do not enter the equations: " + ", ".join(B.unidentifiable))
    # what the user freed: a parameter the user held is not a finding about the data
    not_determined = [n for n in held if n not in at_bound and (all_free or _stem(n) in stems)]
    if not_determined:
        near = f" near {basis.name} = {math.degrees(alpha0):g} deg" if basis.name else ""
        undetermined.append(f"held at the start's values (the data do not determine them{near}): "
                            + ", ".join(not_determined))
    settings.update(iterations=sf.iterations, converged=sf.converged, free=list(sf.theta_names))
    stats = dict(lin.stats)
    stats.update(seconds=time.perf_counter() - t_start, fit_seconds=sf.seconds, cost=sf.cost, **stats_extra)
    return Identification(
        params=fitted if fitted is not None else params0, params0=params0, status=status, message=message, stats=stats, settings=settings,
        names=names, expressions=B.expressions, values=values, intervals=intervals,
        free=tuple(n for n in names if n in theta or n == ref), reference=ref, ratios=ratios,
        ratio_intervals=ratio_iv, undetermined=tuple(undetermined), not_entering=tuple(B.unidentifiable),
        pieces=lin.pieces, residual_rms=lin.residual_rms, validation=tuple(vnames), heldout_kind=tuple(kinds),
        heldout_rms=np.array(hr), heldout_rms0=np.array(hr0), method="output-error", fit_rms=sf.rms_piece,
        alpha=float(alpha_hat), alpha_interval=(float(a_lo), float(a_hi)), alpha_note=note,
        profile_alpha=np.array(prof_a), profile_cost=np.array(prof_c), correlation=sf.correlation)


#: The output error is consistent with the noise when its mean square is at most the noise's times
#: 1 + this many standard deviations of a chi-square's mean (sqrt(2 / n) for n residuals) -- and at
#: least :data:`NOISE_SLACK` (the noise estimate's own bias: a filter's residual, quantised encoders).
CHI2_SIGMAS = 4.0
#: The smallest allowance over the noise's mean square (a fraction of it) in the test above.
NOISE_SLACK = 0.1
#: Beyond the noise, a model error is accepted up to this fraction of the motion the segments predict
#: (the RMS of the measured angles about each segment's straight line ``q0 + q0' t``, what the dynamics
#: explain): measured 0.05 % on the Kaheman rig's free swing (23 times its noise), 1.6 % on the DFKI rig
#: driven (21 times; segments of 0.25 s); a fit of a skewed rig in a wrong minimum 4 % (200 times).
MODEL_ERROR = 0.025


@dataclass(frozen=True)
class Consistency:
    """The output-error test of :func:`consistency`: ``ok``, ``text`` (empty when the output error is
    the noise's), ``stats`` (``output_error``, ``noise``, ``motion`` [rad], ``residuals``: their number)."""

    ok: bool
    text: str
    stats: Dict[str, float]


def angle_noise(measurements: Measurements) -> float:
    """The angles' noise [rad]: the median over pieces of the RMS of what a Savitzky-Golay filter of
    21 samples (order 3) removes from them, divided by ``sqrt(1 - c0)`` (``c0`` the filter's central
    weight: the fraction of white noise the filter keeps at its own sample), so that white noise of
    standard deviation ``s`` gives ``s``."""
    from scipy.signal import savgol_coeffs, savgol_filter

    keep = float(savgol_coeffs(21, 3)[10])
    levels = []
    for p in measurements:
        if len(p) >= 21:
            q = np.asarray(p.q, float)
            levels.append(float(np.sqrt(np.mean((q - savgol_filter(q, 21, 3, axis=0)) ** 2) / (1.0 - keep))))
    return float(np.median(levels)) if levels else math.nan


def consistency(cost: float, seg, measurements: Measurements, frame=None, what: str = "the fitted model") -> Consistency:
    """Whether an output error (``cost``: the sum of squared angle residuals over the segments ``seg``)
    is one of a fit: its mean square ``r^2`` against the data's noise ``s^2`` (:func:`angle_noise`).

    * ``r^2 <= s^2 (1 + max(CHI2_SIGMAS sqrt(2 / n), NOISE_SLACK))`` (``n`` residuals): consistent with
      the noise (a chi-square of ``n`` degrees of freedom has mean ``n``, standard deviation
      ``sqrt(2 n)``);
    * else ``r <= MODEL_ERROR * D`` (``D`` the motion the segments predict, see :data:`MODEL_ERROR`): a
      model error beside the noise, said in the text (real rigs: friction, flexible links);
    * else not a fit of these data (a local minimum, a wrong structure, data read wrongly)."""
    mask = np.asarray(seg.mask, float)
    n = float(mask.sum()) * seg.q.shape[2]
    r = math.sqrt(cost / n) if math.isfinite(cost) and n > 0 else math.inf
    noise = angle_noise(measurements)
    t = np.arange(seg.q.shape[1]) * seg.h
    nq = seg.q.shape[2]
    line = seg.y0[:, None, :nq] + t[None, :, None] * seg.y0[:, None, nq:]
    dev = (np.asarray(seg.q, float) - line) * mask[:, :, None]
    if frame is not None:
        dev = dev @ np.asarray(frame).T
    motion = float(np.sqrt(np.sum(dev**2) / n)) if n > 0 else math.nan
    stats = {"output_error": r, "noise": noise, "motion": motion, "residuals": n}
    if not math.isfinite(r):
        return Consistency(False, "the fitted model's simulation is not finite", stats)
    if math.isfinite(noise) and noise > 0:
        if r**2 <= noise**2 * (1.0 + _allowance(n)):
            return Consistency(True, "", stats)
        times = f"{r / noise:.3g} times the data's noise ({noise:.3g} rad)"
    else:
        times = "the data's noise unknown"
    share = r / motion if motion > 0 else math.inf
    if share <= MODEL_ERROR:
        return Consistency(True, f"{what} misses the angles by {r:.3g} rad, {times}: {100 * share:.2g} % of the "
                                 f"motion over a segment (a model error up to {100 * MODEL_ERROR:g} % is accepted)", stats)
    return Consistency(False, f"{what} misses the angles by {r:.3g} rad, {times} and {100 * share:.2g} % of "
                              f"the motion over a segment (at most {100 * MODEL_ERROR:g} % is a model error): not a fit "
                              "of these data (a local minimum, a wrong model, or the data read wrongly)", stats)


def _allowance(n: float) -> float:
    """The chi-square test's allowance over the noise's mean square (a fraction of it), ``n`` residuals."""
    return max(CHI2_SIGMAS * math.sqrt(2.0 / n), NOISE_SLACK)


def physical_excess(cost: float, cost_free: float, seg, measurements: Measurements,
                    why: str = "the estimate lies outside the physical bodies") -> Consistency:
    """Whether the physical bodies cost the data nothing beyond noise: the output error (``cost``, the sum of
    squared angle residuals over ``seg``) of the fit constrained to physical bodies against the unconstrained
    estimate's (``cost_free``).  Its excess mean square must be within the allowance of :func:`consistency`'s
    chi-square test, ``max(CHI2_SIGMAS sqrt(2 / n), NOISE_SLACK) s^2`` -- what noise alone can move a fit's
    output error by; a larger excess means the data want a body that is not physical (a wrong model or data
    read wrongly), whatever the model error allowed beside the noise."""
    n = float(np.asarray(seg.mask, float).sum()) * seg.q.shape[2]
    noise = angle_noise(measurements)
    excess = (cost - cost_free) / n if n > 0 else math.inf
    stats = {"physical_excess": excess, "output_error_estimate": math.sqrt(max(cost_free, 0.0) / n) if n > 0 else math.nan}
    if not (math.isfinite(excess) and math.isfinite(noise) and noise > 0):
        return Consistency(False, "the fit over the physical bodies cannot be compared with the estimate", stats)
    share = max(excess, 0.0) / noise**2
    if share <= _allowance(n):
        return Consistency(True, (f"{why}: the model is the output-error "
                                  f"fit over the physical bodies (each body's pseudo-inertia L L^T), whose mean square "
                                  f"output error exceeds the estimate's by {share:.2g} of the noise's (at most "
                                  f"{_allowance(n):.2g} is noise)"), stats)
    return Consistency(False, (f"{why}, and the best physical model there misses the angles by more than the "
                               f"estimate: its mean square output error exceeds the estimate's by {share:.3g} times the "
                               f"noise's (at most {_allowance(n):.2g} is noise): not a fit of these data (a wrong "
                               "model -- the skew, the joint terms -- or the data read wrongly)"), stats)


def _fit_physical(params0, B, values, sf, seg, held, ref, alpha_fit, alpha_free, exc, frame, start=None,
                  tol_cost=0.0):
    """The output-error fit over physical bodies only (:func:`skewpend.analysis.shooting.fit_physical`) at
    ``alpha_fit`` (the freed angle's value), from ``start`` (a physical model), else the nearest physical body
    to the estimate ``values`` (``exc``: why the estimate is none).  Returns ``(model, fit, '')`` or
    ``(None, None, why)``."""
    from . import shooting

    model0 = B.with_angle(params0, alpha_fit) if alpha_free else params0
    what = "the output-error estimate is not physical: " + str(exc) if exc is not None else \
        "the output-error estimate's mirror image"
    if start is None:
        try:
            start = B.nearest(model0, values, alpha_fit, held)
        except ParameterError as exc2:
            return None, None, f"{what} [nearest physical: {exc2}]"
    names = list(B.names)
    free_alpha = alpha_free and B.angle in sf.theta_names
    try:
        phys = shooting.fit_physical(B.terms, params0, B.pi_ext(start), alpha_fit, free_alpha, seg, sf.y0,
                                     held=[names.index(n) for n in held], reference=names.index(ref) if ref else None,
                                     frame=frame, tol_cost=tol_cost)
    except (FloatingPointError, ParameterError, np.linalg.LinAlgError) as exc2:
        return None, None, f"{what} (the fit over physical bodies failed: {exc2})"
    try:
        fitted = B.model_of(model0, phys.pi, phys.alpha)
    except ParameterError as exc2:  # (round-off beyond the model's own 1e-9: a bug, said)
        return None, None, f"{what} (the fit over physical bodies: {exc2})"
    return fitted, phys, ""


def _ratios(names, values, intervals, ref: str, freed) -> Tuple[Dict[str, float], Dict[str, Tuple[float, float]]]:
    """What a free swing determines: each freed base parameter over the reference ``ref``, with its interval."""
    k = list(names).index(ref)
    ratios, iv = {}, {}
    for j, n in enumerate(names):
        if n in freed:
            ratios[f"{n}/{ref}"] = float(values[j] / values[k])
            iv[f"{n}/{ref}"] = (float(intervals[j, 0] / values[k]), float(intervals[j, 1] / values[k]))
    return ratios, iv


def _oe_failed(lin: Identification, message: str, settings, t_start) -> Identification:
    stats = dict(lin.stats)
    stats["seconds"] = time.perf_counter() - t_start
    return replace(lin, status=Status.NO_CONVERGENCE, message=message, settings=settings, stats=stats,
                               params=lin.params0, method="output-error")


def _heldout(fitted, params0, validation, smoothing, frame=None):
    """The held-out prediction of ``fitted`` and of ``params0``; ``fitted`` None (no fitted model: the
    fit failed): its figures are NaN, never params0's under the fit's name.  ``frame``: the angles the
    errors are measured in (:func:`skewpend.analysis.shooting.angle_frame`; None: the joint angles)."""
    vnames, kinds, hr0, hr, joint0, joint = [], [], [], [], [], []
    sq, count = [0.0, 0.0], [0, 0]  # params0's, the fitted model's
    for p in validation or ():
        vnames.append(p.name)
        kinds.append("angle")  # driven pieces too: simulated with their measured torques
        for k, (model, rms, rms_joint) in enumerate(((params0, hr0, joint0), (fitted, hr, joint))):
            e = None if model is None else predict_piece(model, p, smoothing)
            if e is not None:
                e = e - np.asarray(p.q, float)  # the errors in the joint angles
                rms_joint.append(float(np.sqrt(np.mean(e**2))))
                e = e if frame is None else e @ frame.T  # ... and in the frame's
                sq[k], count[k] = sq[k] + float(np.sum(e**2)), count[k] + e.size
            else:
                rms_joint.append(math.nan)
            rms.append(math.nan if e is None else float(np.sqrt(np.mean(e**2))))
    extra = {}
    for k, (key, rms) in enumerate((("heldout_overall0", hr0), ("heldout_overall", hr))):
        if count[k] and all(math.isfinite(x) for x in rms):
            extra[key] = math.sqrt(sq[k] / count[k])
    if frame is not None and vnames:  # the measured angles are not the joint angles: these beside
        extra.update(heldout_median_joint=float(np.median(joint)), heldout_median0_joint=float(np.median(joint0)))
    return vnames, kinds, hr, hr0, extra


def _skew_search(run, sf0, alpha0, bootstrap, seed, say, refree, name: str = "alpha"):
    """The freed angle ``name`` (the skew angle alpha, a hinge's tilt): a profile of the cost over it (every
    other parameter re-fitted at each grid angle), then, where its minimum is away from alpha0's neighbourhood,
    a fit with it free.  Returns (fit, angle, (lo, hi), note, grid, costs)."""
    start = f"{name}0" if name == "alpha" else f"{name}(params0)"  # the angle's start, in words
    # alpha determined to first order at alpha0: a regular fit with alpha free
    if name not in run(sf0.beta, alpha0, True, sf0.y0, iterations=0).flat:
        sf = run(sf0.beta, alpha0, True, sf0.y0, boot=bootstrap)
        if sf.converged and name not in sf.flat:
            h = float(sf.half[-1])
            return sf, sf.alpha, (sf.alpha - h, sf.alpha + h), "", [], []
    # the profile: alpha0 + d, d from the grid, on both sides (mirror symmetry checked, not assumed)
    grid = [alpha0]
    fits = {alpha0: sf0}
    say(f"profile of the {_angle_words(name)}", 0.3)

    def at(alpha, start):
        if alpha not in fits:
            fits[alpha] = run(start.beta, alpha, False, start.y0, iterations=8, tol=1e-7)
        return fits[alpha]

    steps = [math.radians(d) for d in PROFILE_GRID]
    up = at(alpha0 + steps[0], sf0)
    down = at(alpha0 - steps[0], sf0)
    even = abs(up.cost - down.cost) <= 1e-6 * up.cost
    sides = (1,) if even else (1, -1)
    for side in sides:
        prev, d_list = sf0, list(steps)
        for i, d in enumerate(d_list):  # (the list grows while the cost falls)
            alpha = alpha0 + side * d
            if abs(alpha) > math.radians(89):
                break
            f = at(alpha, prev)
            grid.append(alpha)
            if i == len(d_list) - 1 and f.cost < prev.cost:  # still falling: extend
                d_list.append(2 * d)
            prev = f
    if even:  # mirror
        grid += [2 * alpha0 - x for x in grid if x != alpha0]
        fits.update({x: fits[2 * alpha0 - x] for x in grid if x not in fits})
    grid = sorted(set(grid))
    costs = np.array([fits[x].cost for x in grid])
    ssr = np.array([fits[x].ssr_cluster for x in grid])  # (grid, clusters of the intervals)
    best = int(np.argmin(costs))
    if 0 < best < len(grid) - 1 and abs(grid[best] - alpha0) > steps[1] * 1.01:
        # a minimum away from alpha0: a regular fit with alpha free from there
        say(f"fit with the {_angle_words(name)} free", 0.7)
        refree(grid[best])
        sf = run(fits[grid[best]].beta, grid[best], True, fits[grid[best]].y0, boot=bootstrap)
        if sf.converged and name not in sf.flat and not math.isnan(sf.alpha):
            h = float(sf.half[-1])
            est = sf.alpha
            note = ""
            if even:  # the mirror image fits as well: reported on alpha0's side (positive from 0)
                est = _start_side(est, alpha0)
                note = f"the sign of {name} - {start} is not determined (the mirror image fits as well)"
            # the profile with the fit's own point (the grid's fits stop after a few iterations: their
            # lowest point is near the minimum, the fit with alpha free at it), mirrored where it is even
            extra = {est: sf.cost}
            if even:
                extra[2 * alpha0 - est] = sf.cost
            pts = sorted({**dict(zip(grid, costs)), **extra}.items())
            return sf, est, (est - h, est + h), note, [x for x, _ in pts], [c for _, c in pts]
    if even:
        # alpha - alpha0 enters to second order only: its square u is the quantity the data determine.
        # Linearised at d = the first grid step, d y/d u = (d y/d alpha) / (2 d); u's estimate is the
        # Gauss-Newton step from d^2, its interval the sandwich / bootstrap one; |alpha - alpha0| is
        # bounded by sqrt(u's upper end)
        d = steps[0]
        at_d = fits[alpha0 + d]
        lin_u = run(at_d.beta, alpha0 + d, True, at_d.y0, iterations=0, boot=bootstrap)
        if name not in lin_u.flat and math.isfinite(lin_u.half[-1]):
            u = d * d + 2 * d * float(lin_u.newton_step[-1])
            hu = 2 * d * float(lin_u.half[-1])
            est = math.sqrt(max(u, 0.0))
            # an estimate below zero (no skew fits better than none) is bounded as one at zero: the
            # bound is never narrower than the interval's half-width allows
            bound = math.sqrt(max(u, 0.0) + hu)
            note = (f"the data determine ({name} - {start})^2 = {u:.3g} +- {hu:.3g} rad^2"
                    + (" (below zero: no skew fits better than none)" if u < 0 else "")
                    + f"; the 95 % bound on |{name} - {start}| is the square root of its upper end (from zero "
                    "where the estimate is below); the sign is not determined (mirror symmetry)")
            return sf0, alpha0 + est, (alpha0 - bound, alpha0 + bound), note, grid, list(costs)
    # near alpha0: the interval from the profile, re-minimised on pieces resampled with replacement
    x = np.array(grid)
    est = _vertex(x, costs)
    rng, n = np.random.default_rng(seed), ssr.shape[1]
    draws = [_vertex(x, ssr @ np.bincount(rng.integers(0, n, n), minlength=n)) for _ in range(int(bootstrap) or 200)]
    lo, hi = np.percentile(draws, [2.5, 97.5]) if n >= MIN_CLUSTERS else (math.nan, math.nan)
    note = "95 % interval from the profile of the cost, re-minimised on resampled clusters"
    if even:
        m = max(abs(lo - alpha0), abs(hi - alpha0), abs(est - alpha0))
        lo, hi = alpha0 - m, alpha0 + m
        note += f"; the sign of {name} - {start} is not determined (mirror symmetry)"
    sf = fits[grid[best]]
    return sf, float(est), (float(lo), float(hi)), note, grid, list(costs)


def _start_side(angle: float, angle0: float) -> float:
    """``angle`` mirrored about ``angle0`` onto ``angle0``'s side of zero (positive from 0)."""
    return angle0 + (math.copysign(1.0, angle0) if angle0 != 0 else 1.0) * abs(angle - angle0)


def _vertex(x: np.ndarray, c: np.ndarray) -> float:
    """The minimum of a profile: the vertex of the parabola through the lowest grid point and its
    neighbours (the grid point itself at an end)."""
    k = int(np.argmin(c))
    if k == 0 or k == len(x) - 1:
        return float(x[k])
    x0, x1, x2 = x[k - 1:k + 2]
    c0, c1, c2 = c[k - 1:k + 2]
    den = (x0 - x1) * (x0 - x2) * (x1 - x2)
    A = (x2 * (c1 - c0) + x1 * (c0 - c2) + x0 * (c2 - c1)) / den
    Bq = (x2**2 * (c0 - c1) + x1**2 * (c2 - c0) + x0**2 * (c1 - c2)) / den
    if A <= 0:
        return float(x[k])
    return float(min(max(-Bq / (2 * A), x0), x2))


def predict_piece(params: Parameters, piece: Piece, smoothing: float = SMOOTHING) -> Optional[np.ndarray]:
    """The angles (n, nq) [rad] of ``params`` (the double pendulum's or a chain) simulated from ``piece``'s first
    measured state (``q[0]``, and ``dq[0]`` where measured, else its Savitzky-Golay estimate with window
    ``smoothing`` [s]) at the piece's times: the prediction whose error the held-out RMS measures; None where the
    simulation failed.  (Used by the identification's figure.)"""
    from ..numeric.simulation import simulate

    t = np.asarray(piece.t, float) - float(piece.t[0])
    if piece.dq is not None:
        dq0 = np.asarray(piece.dq[0], float)
    else:
        from scipy.signal import savgol_filter

        w = min(_window(piece.dt, smoothing), len(t) - (len(t) + 1) % 2)
        dq0 = savgol_filter(np.asarray(piece.q, float), w, ORDER, deriv=1, delta=piece.dt, axis=0)[0]
    y0 = [float(x) for x in piece.q[0]] + [float(x) for x in dq0]
    try:
        if piece.u is None:
            tr = simulate(params, y0, float(t[-1]) + piece.dt, dt_out=piece.dt)
        else:  # driven: the measured torques, linear between the samples
            from ..numeric.control import Controller

            tr = simulate(params, y0, float(t[-1]), controller=Controller.table(t, np.asarray(piece.u, float)))
    except Exception:  # noqa: BLE001 - any failure of one held-out simulation is reported in the status
        return None
    ts, ys = np.asarray(tr.t, float), np.asarray(tr.y, float)
    if not tr.ok or ts[-1] < t[-1] - 1e-9 or not np.all(np.isfinite(ys)):
        return None
    return np.column_stack([np.interp(t, ts, ys[:, k]) for k in range(piece.nq)])


#: A body's principal moment below zero (or over the sum of the others) by at most this fraction of its
#: inertia about the hinge is round-off, set on the edge: the physical check's tolerance.
ROUND_OFF = 1e-9
#: The factors both masses are raised by, in turn, where params0's cannot realise an estimate.
MASS_FACTORS = (1.25, 1.5, 2.0, 3.0, 5.0)


def _realise_masses(params0: Parameters, W, values: np.ndarray, a: float, alpha: float, g: float,
                    held: Sequence[str] = ()) -> Tuple[Parameters, str]:
    """:func:`_realise`; where ``params0``'s masses cannot realise the estimate (a body whose inertia
    about its centre of mass would be negative: with a rod's first moment ``h`` and its inertia ``J``
    about the joint fixed, that inertia is ``J - h^2 / m``), both masses raised by the first of
    :data:`MASS_FACTORS` that can, every base parameter kept exactly (the masses themselves do not
    enter the equations apart from those combinations).  Returns the model and a note ('' when
    params0's masses did)."""
    try:
        return _realise(params0, W, values, a, alpha, g, held=held), ""
    except ParameterError as exc:
        first = exc
    B = W.B
    free_entry = _realise_free_entries(params0, W, values, a, alpha, g, held)
    if free_entry is not None:
        return free_entry
    if any(n in MASS_NAMES for n in B.names):  # a mass is itself determined: it cannot be chosen
        raise first
    for k in MASS_FACTORS:
        try:
            p = _realise(params0.replace(m1=k * float(params0.m1), m2=k * float(params0.m2)), W, values, a, alpha, g,
                         held=held)
        except ParameterError:
            continue
        keep = [j for j, n in enumerate(W.names) if n not in held]
        check = W.values(standard_vector(p), a, alpha, g)
        if np.abs(check[keep] - np.asarray(values, float)[keep]).max() <= 1e-9 * max(np.abs(values).max(), 1e-300):
            return p, (f"both masses raised x{k:g} from params0's, which cannot realise the estimate (a body's "
                       "inertia about its centre of mass would be negative; the data determine the masses only "
                       "in the base parameters' combinations)")
    raise first


#: Steps (fractions of the body's trace) tried for a diagonal inertia entry that the data do not determine.
_FREE_ENTRY_STEPS = (1e-3, 3e-3, 1e-2, 3e-2, 0.1, 0.3)


def _realise_free_entries(params0: Parameters, W, values: np.ndarray, a: float, alpha: float, g: float,
                          held: Sequence[str]) -> Optional[Tuple[Parameters, str]]:
    """Where ``params0``'s inertia entries that the data do not determine (a skewed slender rod's moment
    about its own axis) make the estimate's body unphysical, the same base parameters realised with one
    such diagonal entry (about the centre of mass) moved; every base parameter kept exactly.  None if no
    step of :data:`_FREE_ENTRY_STEPS` does."""
    B = W.B
    free_names = {PI_NAMES[j] for j in range(len(PI_NAMES)) if j not in set(B.pivots)}
    for i in (1, 2):
        given = getattr(params0, f"inertia{i}")
        if given is None:  # the specification's thin rod: m l^2 / 12 (E - j j)
            m, length = float(getattr(params0, f"m{i}")), float(params0.a if i == 1 else params0.b)
            given = m * length**2 / 12.0 * np.diag([1.0, 0.0, 1.0])
        I0 = np.array(given, dtype=float)
        scale = float(np.trace(I0))
        if not scale > 0:
            continue
        for k, p in ((1, "yy"), (0, "xx"), (2, "zz")):
            if f"J{i}{p}" not in free_names:
                continue
            for frac, sign in itertools.product(_FREE_ENTRY_STEPS, (1.0, -1.0)):
                I = I0.copy()
                I[k, k] += sign * frac * scale
                try:
                    start = params0.replace(**{f"inertia{i}": tuple(tuple(float(x) for x in row) for row in I)})
                    fitted = _realise(start, W, values, a, alpha, g, held=held)
                except ParameterError:
                    continue
                return fitted, (f"J{i}{p} about the centre of mass, which the data do not determine, set to "
                                f"{I[k, k]:.4g} (params0's {I0[k, k]:.4g} gives no physical body with these "
                                "base parameters)")
    return None


def _shift(m: float, c: np.ndarray) -> np.ndarray:
    """``m (|c|^2 E - c c^T)``: what carries an inertia about the centre of mass ``c`` to the hinge."""
    return m * (c @ c * np.eye(3) - np.outer(c, c))


def _body(pi: np.ndarray, i: int, m: float) -> Tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Body ``i`` of a standard vector (:data:`PI_NAMES`) of mass ``m``: its centre of mass ``h / m``, its
    inertia ``J`` about the hinge and the inertia about the centre of mass."""
    c = np.array([pi[_PI_INDEX[f"h{i}{x}"]] for x in "xyz"]) / m
    J = np.empty((3, 3))
    for e, (r, s) in zip(TENSOR_ENTRIES, TENSOR_INDICES):
        J[r, s] = J[s, r] = pi[_PI_INDEX[f"J{i}{e}"]]
    return c, J, J - _shift(m, c)


def _body_changes(i: int, c: np.ndarray, ic: np.ndarray) -> Dict[str, Any]:
    return {f"com{i}": tuple(float(v) for v in c),
            f"inertia{i}": tuple(tuple(float(v) for v in row) for row in 0.5 * (ic + ic.T))}


def _realise(params0: Parameters, W, values: np.ndarray, a: float, alpha: float, g: float,
             held: Sequence[str] = (), project: bool = False) -> Parameters:
    """``params0`` with the pivot entries of ``pi`` set so that its base parameters are ``values``;
    the base parameters named in ``held`` (inertia entries the fit did not free) are instead taken
    from params0's own inertia about the (new) centre of mass, like the dependent entries."""
    B = W.B
    extra = dict(zip(W.extra, (float(v) for v in values[B.rank:])))
    values = np.asarray(values, dtype=float)[:B.rank]
    pi0 = standard_parameters(params0)
    T = B.matrix_at(a, alpha, g)
    pi = pi0.copy()
    piv = list(B.pivots)
    # T[:, piv] is the identity: pi_P = beta - T_D pi_D
    dep = [j for j in range(len(pi)) if j not in piv]
    pi[piv] = values - T[:, dep] @ pi0[dep]
    idx = _PI_INDEX
    # an inertia entry that only moves inside a combination is held about the body's *centre of mass*
    # (params0's own inertia, carried to the new centre): held about the hinge, a centre moved by the
    # fit would leave e.g. a slender rod a negative moment about its own axis
    held_piv = [piv[k] for k, n in enumerate(B.names) if n in held and PI_NAMES[piv[k]].startswith("J")]
    for i in (1, 2):
        m = pi[idx[f"m{i}"]]
        c_new = np.array([pi[idx[f"h{i}{x}"]] for x in "xyz"]) / m
        c_old = np.array([pi0[idx[f"h{i}{x}"]] for x in "xyz"]) / m
        old, new = _shift(m, c_old), _shift(m, c_new)
        for e, (r, s) in zip(TENSOR_ENTRIES, TENSOR_INDICES):
            j = idx[f"J{i}{e}"]
            if j in dep or j in held_piv:
                pi[j] = pi0[j] - old[r, s] + new[r, s]
    rows = [k for k in range(len(piv)) if piv[k] not in held_piv]
    for k in rows:
        pi[piv[k]] = values[k] - T[k, dep] @ pi[dep]
    changes: Dict[str, Any] = {n: float(pi[idx[n]]) for n in DAMPING_NAMES}
    # damping, friction and rotor inertia >= 0 (project), else below zero by round-off (relative to the base
    # parameters' scale) on the bound
    tiny = 0.1 * ROUND_OFF * max(float(np.abs(values).max()), 1e-300)
    clip = (lambda v: max(v, 0.0)) if project else (lambda v: 0.0 if -tiny <= v < 0 else v)
    changes, extra = {k: clip(v) for k, v in changes.items()}, {k: clip(v) for k, v in extra.items()}
    for i in (1, 2):
        m = pi[idx[f"m{i}"]]
        c, J, ic = _body(pi, i, m)
        # entries that do not enter the equations: params0's, about the centre of mass
        ic0 = _body(pi0, i, m)[2]
        for e, (r, s) in zip(TENSOR_ENTRIES, TENSOR_INDICES):
            if f"J{i}{e}" in B.unidentifiable:
                ic[r, s] = ic[s, r] = ic0[r, s]
        if f"J{i}xx" in B.unidentifiable or any(_stem(n) == f"J{i}xx" for n in held):
            # planar (or held): x-inertia moves with z's (mass moved along the rod)
            ic[0, 0] += ic[2, 2] - ic0[2, 2]
        w, V = np.linalg.eigh(0.5 * (ic + ic.T))
        clipped = np.maximum(w, 0.0)
        d = clipped[2] - clipped[0] - clipped[1]
        if project:  # onto the nearest physical body: moments >= 0, each at most the sum of the others
            moved = True
        else:  # round-off: a slender rod's moment about its own axis a few ulps of the hinge's inertia below 0
            # (a tenth of the realisation's own check, 1e-9 of the base parameters: a clip moves up to
            # three entries of a combination)
            tol = 0.1 * ROUND_OFF * max(float(np.abs(J).max()), float(np.abs(ic).max()), 1e-300)
            moved = w[0] >= -tol and d <= tol and (w[0] < 0 or d > 0)  # only round-off is moved, never more
        if moved:
            if d > 0:  # the nearest point of the plane w0 + w1 = w2 (a slender rod's transverse moments
                # 1.5 % apart: each moment moves by d / 3, not the largest by d)
                clipped = clipped + d / 3.0 * np.array([1.0, 1.0, -1.0])
            ic = (V * clipped) @ V.T
        changes.update(_body_changes(i, c, ic))
    return params0.replace(**changes, **extra)


# -- the run file (Identification.to_run_file) ----------------------------------------------------------
def _count(n: int, noun: str) -> str:
    """``1 piece``, ``2 pieces``."""
    return f"{n} {noun}" + ("" if n == 1 else "s")


def _one_line(text: str) -> str:
    return " ".join(str(text).split())


def _names_text(names: Sequence[str]) -> str:
    names = list(names)
    return ", ".join(names) if len(names) <= 6 else f"{', '.join(names[:3])}, ..., {names[-1]}"


def _write_run_file(result: "Identification", path, *, force: bool = False):
    from pathlib import Path

    from .. import __version__
    from ..io import atomic_path

    status = Status.of(result.status)
    if status is not Status.SUCCESS and not force:
        raise ParameterError(f"the identification did not succeed ({status.name.lower()}: "
                             f"{_one_line(result.message)}), so its params are not a fitted model: no run file "
                             "written (force=True writes it anyway)")
    lines = [f"# skewpend run file: a pendulum identified from measured motion (skewpend {__version__})",
             f"# method: {_one_line(result.settings.get('method', result.method))}",
             f"# data: {_count(len(result.pieces), 'piece')} ({_names_text(result.pieces)}), "
             f"{result.stats.get('samples', 0)} samples after filtering"]
    if result.free:
        lines.append(f"# free: {', '.join(result.free)}" + (f", {result.angle}" if math.isfinite(result.alpha) else ""))
    if len(result.validation):
        lines.append(f"# held out: {_count(len(result.validation), 'piece')} ({_names_text(result.validation)})")
        if any(k == "angle" for k in result.heldout_kind):
            lines.append(f"# held-out angle RMS: median over pieces {result.heldout_median:.4g} rad "
                         f"(params0: {result.heldout_median0:.4g}), overall {result.heldout_overall:.4g} rad "
                         f"(params0: {result.heldout_overall0:.4g}), in the {result._angle_words}")
            if "heldout_median_joint" in result.stats:
                lines.append(f"# held-out angle RMS in the joint angles: median over pieces "
                             f"{result.stats['heldout_median_joint']:.4g} rad (params0: "
                             f"{result.stats['heldout_median0_joint']:.4g})")
    else:
        lines.append("# held out: none (no validation data)")
    if math.isfinite(result.alpha):
        lo, hi = result.alpha_interval
        lines.append(f"# {_angle_words(result.angle)}: {math.degrees(result.alpha):.4g} deg, 95 % interval "
                     f"[{math.degrees(lo):.4g}, {math.degrees(hi):.4g}] deg")
        if result.alpha_note:
            lines.append(f"#   ({_one_line(result.alpha_note)})")
    lines.append(f"# status: {status.name.lower()}: {_one_line(result.message)}"
                 + ("" if status is Status.SUCCESS else " -- written with force=True: NOT a fitted model"))
    lines += [f"# undetermined: {_one_line(u)}" for u in result.undetermined]
    if "links" in result.params.to_dict():  # the model's own plain data: a chain of links
        from ..config import chain_toml

        lines += ["# use it as: skewpend simulate --config FILE (the commands that take a chain's [[links]])", ""]
        lines += chain_toml(result.params)
    else:
        lines += ["# use it as: skewpend simulate --config FILE (any command that reads [parameters])", "",
                  "[parameters]"]
        lines += parameters_toml(result.params)
    text = "\n".join(lines) + "\n"
    with atomic_path(path) as tmp:  # (it refuses a path that is not one, in one line)
        tmp.write_text(text, encoding="utf-8")
    return Path(path)
