"""Lyapunov exponents: how fast nearby motions separate, by Benettin's method.

``lyapunov(params, y0, t_end=...)`` integrates the state together with ``k`` tangent vectors
(the variational equations ``v' = J(y) v``, with ``J`` the Jacobian generated from the
derivation, evaluated along the trajectory inside the same adaptive DOP853 steps as the state
-- not frozen over a step), and every ``renorm_every`` seconds replaces the vectors by the
``Q`` of their QR decomposition, adding ``log |r_jj|`` to the growth of the ``j``-th direction.
The exponents are the growths divided by the time: ``k = 4`` the full spectrum (in the order
of the QR, which is descending once the vectors have aligned), ``k = 1`` the largest alone
(about 3x cheaper).  The code is ``sp_lyap`` in ``chaos.c`` (the *chaos kernel*).

Checks that hold for this system (tested): without damping and torques the spectrum is
``(l, 0, 0, -l)`` up to the finite time (a Hamiltonian, autonomous system: pairs ``+-`` and
two zeros), so its sum is ~0; with damping the sum is the time average of the trace of
``J`` (phase-space volume contracts at that rate); near the stable equilibrium every exponent
tends to 0; the mirror start ``-y0`` has the same spectrum when the equations are odd.

Error bars are batch means over ``windows`` equal blocks of the measured time (Student's t, 95 %),
meaningful only once :func:`settle_check` finds the blocks independent and the estimate no longer
drifting; a run that fails it is :attr:`~skewpend.status.Status.NOT_SETTLED` and says how much longer to run.

``lyapunov_map(params, n, ...)`` is the largest exponent over a grid of starts at rest, like
:func:`~skewpend.analysis.flipmap.flip_map`, on every core.
"""

from __future__ import annotations

import ctypes
import json
import math
import time
from dataclasses import dataclass
from typing import Any, Callable, ClassVar, Dict, Optional, Sequence

import numpy as np

from ..errors import IntegrationError, ParameterError
from ..checks import DEFAULT_TOL, MAX_STEPS, max_steps as check_max_steps, numeric_model, numeric_params, tolerances
from ..checks import finite_seconds, progress_callable, whole
from ..interrupts import Interrupts
from ..numeric.driver import check_step_estimate, drive
from ..numeric.ensemble import Cancelled
from ..numeric.grid import PROBE_STEPS, ArraySpec, GridJob, cell_centres, check_feasible, check_n, check_range
from ..numeric.grid import check_run_options, read_grid_result, steps_per_second
from ..results import DatasetSpec, Result, canonical_json, grid_status, netcdf_reader, normal_quantile, plain
from ..results import protocol_fields, t_quantile
from ..schema import state_coordinates
from ..status import Status
from ..parsing import initial_state, positive_number
from ..symbolic.model import AnyModel
from ..symbolic.model import Parameters

__all__ = ["lyapunov", "LyapunovSpectrum", "lyapunov_map", "LyapunovMap", "LyapunovMapJob", "open_lyapunov_map",
           "largest_exponents", "DEFAULT_TOL"]

#: Accepted steps per call into the compiled code (a few milliseconds: Ctrl-C stops within that).
_BUDGET = 4000
#: Renormalisation rows handed back per call.
_ROWS = 4096
#: Points kept of the running estimate (history), whatever the number of renormalisations.
_HISTORY = 2000
#: Confidence of the intervals (``LyapunovSpectrum.interval``).
CONFIDENCE = 0.95
#: Level of each of the two tests of :func:`settle_check` (a settled run fails one or the other
#: about 5-10 % of the time: the price of catching the unsettled ones).
CHECK_LEVEL = 0.05
#: Fewest windows :func:`settle_check` can work with (two halves of two).
MIN_WINDOWS = 4
#: Failure codes of the compiled integrators.
_STATUS = {
    1: "the state or its derivative became non-finite",
    2: "the step size underflowed",
    3: "more than max_steps steps were attempted",
}


@dataclass(frozen=True)
class LyapunovSpectrum(Result):
    """The result of :func:`lyapunov`.

    * ``exponents`` -- shape ``(k,)`` [1/s], in the order of the QR (descending once converged);
    * ``uncertainty`` -- shape ``(k,)`` [1/s]: the standard error of the mean of the exponents
      measured over ``windows`` equal time windows (their spread / sqrt(windows): batch means);
      NaN with fewer than 2 windows; ``interval`` is the half-width of the 95 % confidence
      interval (Student's t quantile times that); both mean what they say only when ``status``
      is not ``NOT_SETTLED`` (:func:`settle_check`);
    * ``t``, ``history`` -- the running estimates: ``history[i]`` is the exponents measured from
      the end of the transient to ``t[i]`` [s] (at most 2000 points, evenly thinned);
    * ``window_exponents`` -- shape ``(windows, k)``: the exponents of each window;
    * ``params``, ``y0``, ``settings`` (t_end, renorm_every, transient, rtol, atol, ...), ``stats``
      (steps, rejected, renormalisations, wall time, and the convergence check's
      ``halves_sigma``, ``von_neumann_sigma``), ``status`` (0: reached t_end and settled;
      NOT_SETTLED: reached t_end, but the check failed -- the message says why and how long to
      run) and ``message``.
    """

    exponents: np.ndarray
    uncertainty: np.ndarray
    t: np.ndarray
    history: np.ndarray
    window_exponents: np.ndarray
    y0: np.ndarray

    result_kind: ClassVar[str] = "Lyapunov spectrum"

    @property
    def k(self) -> int:
        return int(self.exponents.size)

    @property
    def sum(self) -> float:
        """Sum of the exponents [1/s] (the rate of phase-space volume change, for the full spectrum)."""
        return float(np.sum(self.exponents))

    @property
    def full(self) -> bool:
        """Whether every exponent was measured (as many as the state has components: 4, or 2 n for a chain)."""
        return self.k == int(np.size(self.y0))

    @property
    def windows_measured(self) -> int:
        """How many windows hold a measurement (fewer than ``settings['windows']`` if the run stopped)."""
        return int(np.count_nonzero(np.all(np.isfinite(self.window_exponents), axis=1)))

    @property
    def interval(self) -> np.ndarray:
        """Half-width [1/s] of each exponent's 95 % confidence interval: Student's t quantile
        (``windows - 1`` degrees of freedom) times ``uncertainty``; NaN with fewer than 2 windows."""
        n = self.windows_measured
        if n < 2:
            return np.full(self.k, np.nan)
        return t_quantile(0.5 + CONFIDENCE / 2, n - 1) * np.asarray(self.uncertainty, dtype=float)

    @property
    def conservative(self) -> bool:
        """Without damping the flow preserves phase-space volume (constant torques derive from a
        potential): the spectrum sums to 0 and comes in pairs +-l."""
        return not self.params.dissipative

    @property
    def kaplan_yorke_dimension(self) -> float:
        """The Kaplan-Yorke (Lyapunov) dimension ``j + (l_1 + … + l_j) / |l_{j+1}|``, with ``j``
        the largest index with a non-negative partial sum: an attractor's dimension, so NaN for a
        conservative system (no damping: the phase-space volume is preserved, there is no
        attractor, and the formula would give about 4 whatever the motion) and NaN without the
        full spectrum."""
        if not self.full or self.conservative:
            return math.nan
        lam = np.sort(self.exponents)[::-1]
        partial = np.cumsum(lam)
        j = int(np.count_nonzero(partial >= 0))
        if j == 0:
            return 0.0
        if j >= lam.size:
            return float(lam.size)
        return j + float(partial[j - 1]) / abs(float(lam[j]))

    def table(self) -> str:
        """The exponents with their 95 % intervals, one per line (text), the sum and (full
        spectrum) the Kaplan-Yorke dimension.  Nothing non-finite is printed as a number: an
        exponent that could not be measured reads "not measured", an interval from fewer than 2
        windows is left out (and said so); a run that has not settled (``NOT_SETTLED``) prints
        its exponents without error bars, and a conservative system's Kaplan-Yorke dimension
        is said to be meaningless rather than printed."""
        settled = self.status != Status.NOT_SETTLED
        lines = []
        for i, (v, u) in enumerate(zip(self.exponents, self.interval)):
            value = f"{v:+.6f}" if math.isfinite(v) else "not measured"
            spread = f" +- {u:.2g}" if settled and math.isfinite(u) and math.isfinite(v) else ""
            lines.append(f"lambda_{i + 1} = {value}{spread} 1/s" if math.isfinite(v) else f"lambda_{i + 1} = {value}")
        if self.full and math.isfinite(self.sum):
            lines.append(f"sum      = {self.sum:+.3e} 1/s")
        if self.full:
            if self.conservative:
                lines.append("Kaplan-Yorke dimension: not meaningful for a conservative system "
                             "(no damping: the phase-space volume is preserved)")
            elif math.isfinite(self.kaplan_yorke_dimension):
                lines.append(f"Kaplan-Yorke dimension {self.kaplan_yorke_dimension:.4f}")
        n = self.windows_measured
        if not np.isfinite(self.exponents).any():
            pass
        elif n < 2:
            lines.append("(no uncertainty: it needs at least 2 windows after the transient)")
        elif not settled:
            lines.append("(no error bars: the exponents have not settled, see the status)")
        else:
            lines.append(f"(+-: {100 * CONFIDENCE:g} % intervals from the spread of {n} windows, Student's t)")
        return "\n".join(lines)

    def _dataset(self) -> DatasetSpec:
        k = np.arange(1, self.k + 1)
        return DatasetSpec(
            variables={
                "exponent": (("k",), self.exponents, {"units": "1/s", "long_name": "Lyapunov exponent (QR order)"}),
                "uncertainty": (("k",), self.uncertainty, {"units": "1/s", "long_name": "standard error over windows"}),
                "interval": (("k",), self.interval, {"units": "1/s", "long_name": "half-width of the 95 % interval"}),
                "history": (("time", "k"), self.history, {"units": "1/s", "long_name": "running estimate"}),
                "window_exponent": (("window", "k"), self.window_exponents, {"units": "1/s"}),
                "y0": (("state",), self.y0, {"long_name": "initial state (" + ", ".join(state_coordinates(self.y0.size // 2)) + ")"}),
            },
            coords={"k": (("k",), k, {}), "time": (("time",), self.t, {"units": "s"})},
            attrs={"title": f"Lyapunov spectrum of {self.params.title} (skewpend)", **self._base_attrs()},
        )

    def to_dict(self) -> Dict[str, Any]:
        """Plain data (JSON-ready): exponents, uncertainties, settings, statistics, parameters."""
        return plain({  # strict JSON: a non-finite value is null
            "exponents": self.exponents,
            "uncertainty": self.uncertainty,
            "interval": self.interval,
            "confidence": CONFIDENCE,
            "sum": self.sum,
            "kaplan_yorke_dimension": self.kaplan_yorke_dimension,  # null: conservative, or not the full spectrum
            "y0": self.y0,
            "status": int(self.status),
            "message": self.message,
            "settings": dict(self.settings),
            "stats": dict(self.stats),
            "params": self.params.to_dict(),
        })


@netcdf_reader(LyapunovSpectrum.result_kind)
def read_lyapunov_spectrum(path, variables, attrs) -> LyapunovSpectrum:
    """A :class:`LyapunovSpectrum` from its ``*.nc`` file (every part of it is stored); called as
    ``read_lyapunov_spectrum(path)`` by :func:`skewpend.open_result`."""
    return LyapunovSpectrum(
        exponents=np.asarray(variables["exponent"], dtype=float), uncertainty=np.asarray(variables["uncertainty"], dtype=float),
        t=np.asarray(variables["time"], dtype=float), history=np.asarray(variables["history"], dtype=float),
        window_exponents=np.asarray(variables["window_exponent"], dtype=float), y0=np.asarray(variables["y0"], dtype=float),
        **protocol_fields(path, attrs, AnyModel))


def _longer(seconds: float) -> float:
    """A round time about 20 times ``seconds`` (1, 2 or 5 times a power of ten, at least that)."""
    target = 20.0 * seconds
    exp = math.floor(math.log10(target))
    for m in (1.0, 2.0, 5.0, 10.0):
        if m * 10.0 ** exp >= target * (1 - 1e-12):
            return m * 10.0 ** exp
    return target


def settle_check(window_exponents, *, level: float = CHECK_LEVEL):
    """Whether the exponents measured over equal time windows have settled: the stated rule.

    ``window_exponents`` has shape ``(K, k)`` (K >= 4 windows of equal length, in time order).
    The exponents checked are the first (the largest: whether the motion is chaotic) and every
    other one clearly away from 0 (whose 95 % interval, mean +- ``t_{0.975, K-1} s / sqrt(K)``,
    excludes 0): an exponent that tends to 0 (the flow direction, a conservative system's second
    zero) grows by a bounded amount, so its windows' spread overstates its error -- its interval
    contains 0 and covers, while its window values, anticorrelated, would fail the tests below
    at random. For each checked exponent, with ``x`` its K window values, ``s`` their standard
    deviation and ``h = K // 2``:

    * **the halves agree**: the means of the first ``h`` and the last ``h`` windows differ by at
      most ``t_{1-level/2, K-1}`` times their standard error ``s sqrt(2/h)`` -- a drifting
      estimate (a transient, an orbit stuck near an island, a regular orbit's ``ln T / T``)
      fails this;
    * **the windows are independent**: von Neumann's ratio ``sum (x_{i+1} - x_i)^2 / sum (x_i -
      mean)^2`` (2 for independent windows, variance ``4 (K-2)/(K^2-1)``) is not below 2 by
      more than the one-sided normal quantile ``z_{1-level}`` of its standard deviation --
      windows too short to be independent make the standard error too small, and fail this.

    Returns ``(settled, halves_sigma, von_neumann_sigma, detail)``: the largest statistics over
    the exponents in units of their own standard deviation, and, when not settled, a sentence
    about the worst exponent (``lambda_j ...``).  Windows with identical values (no spread)
    count as settled."""
    x = np.asarray(window_exponents, dtype=float)
    K = x.shape[0]
    if K < MIN_WINDOWS or not np.all(np.isfinite(x)):
        raise ValueError(f"settle_check needs at least {MIN_WINDOWS} finite windows, got {x.shape}")
    h = K // 2
    first, second = x[:h].mean(axis=0), x[K - h:].mean(axis=0)
    s = x.std(axis=0, ddof=1)
    dev = np.sum((x - x.mean(axis=0)) ** 2, axis=0)
    with np.errstate(divide="ignore", invalid="ignore"):
        z_halves = np.where(s > 0, np.abs(second - first) / (s * math.sqrt(2.0 / h)), 0.0)
        ratio = np.where(dev > 0, np.sum(np.diff(x, axis=0) ** 2, axis=0) / dev, 2.0)
    z_vn = (2.0 - ratio) / math.sqrt(4.0 * (K - 2) / (K * K - 1))
    t_crit, z_crit = t_quantile(1 - level / 2, K - 1), normal_quantile(1 - level)
    checked = np.abs(x.mean(axis=0)) > t_quantile(0.5 + CONFIDENCE / 2, K - 1) * s / math.sqrt(K)
    checked[0] = True
    z_halves, z_vn = np.where(checked, z_halves, -np.inf), np.where(checked, z_vn, -np.inf)
    bad_h, bad_v = z_halves > t_crit, z_vn > z_crit
    settled = not (bad_h.any() or bad_v.any())
    detail = None
    if not settled:
        j = int(np.argmax(np.maximum(z_halves / t_crit, z_vn / z_crit)))
        parts = []
        if bad_h[j]:
            parts.append(f"its two halves give {first[j]:+.3f} and {second[j]:+.3f} 1/s, "
                         f"{z_halves[j]:.1f} standard errors apart (at most {t_crit:.2f} if settled)")
        if bad_v[j]:
            parts.append(f"its {K} window values are correlated (von Neumann ratio {ratio[j]:.2f}, "
                         f"{z_vn[j]:.1f} sigma below the 2 of independent windows)")
        detail = f"lambda_{j + 1}: " + "; ".join(parts)
    return settled, float(np.max(z_halves)), float(np.max(z_vn)), detail


def check_times(t_end, renorm_every, transient):
    """``(t_end, renorm_every, transient)`` of a Lyapunov computation, checked together."""
    t_end = positive_number("t_end", t_end)
    renorm_every = positive_number("renorm_every", renorm_every)
    transient = finite_seconds("transient", transient)
    if renorm_every > t_end:
        raise ParameterError(f"renorm_every ({renorm_every:g} s) must not exceed t_end ({t_end:g} s)")
    if transient + renorm_every > t_end:
        raise ParameterError(
            f"transient ({transient:g} s) leaves less than one renormalisation interval ({renorm_every:g} s) "
            f"before t_end ({t_end:g} s); use a longer t_end or a shorter transient"
        )
    if t_end / renorm_every > 1e12:
        raise ParameterError(f"t_end / renorm_every = {t_end / renorm_every:.3g} renormalisations is too many (at most 1e12)")
    return t_end, renorm_every, transient


def skipped_renormalisations(transient: float, renorm_every: float) -> int:
    """How many renormalisations the transient covers: those at or before ``transient`` (with a
    relative slack of 1e-12, so that ``transient = 3 x 0.1`` skips three).  The one rule of
    :func:`lyapunov` and of the ensembles (``sp_lyap1_many``)."""
    return int(math.floor(transient / renorm_every * (1 + 1e-12)))


def lyapunov(
    params: Parameters,
    y0: Sequence[float],
    *,
    t_end: float,
    renorm_every: float = 1.0,
    transient: float = 0.0,
    n_exponents: Optional[int] = None,
    rtol: Optional[float] = None,
    atol: Optional[float] = None,
    windows: int = 10,
    max_steps: int = MAX_STEPS,
    progress: Optional[Callable[[float, float], None]] = None,
    throw: bool = False,
) -> LyapunovSpectrum:
    """The Lyapunov spectrum [1/s] of the motion from ``y0 = (phi, psi, dphi, dpsi)``.

    ``params`` may be a :class:`~skewpend.Chain` of ``n`` links (``y0`` its ``2 n`` angles and speeds):
    the same method on the chain's compiled variational equations (the Jacobian from CasADi's
    derivative of the recursive algorithms), ``2 n`` exponents.

    Benettin's method on the variational equations: the state and ``n_exponents`` (1 to 4, or
    ``2 n``; default all) tangent vectors -- starting as the first columns of the identity (one
    vector: the unit diagonal ``(1, 1, 1, 1)/2``) -- integrated together by adaptive DOP853 (``rtol``/``atol``,
    default 1e-10, on every component), re-orthonormalised by QR every ``renorm_every``
    seconds.  The first ``transient`` seconds align the vectors and are not counted (the
    measurement starts at the last renormalisation at or before ``transient``).  The
    uncertainty is the standard error from the spread of the exponents over ``windows`` equal
    time windows (batch means), ``interval`` its 95 % half-width (Student's t); both hold only if
    the run has settled, which :func:`settle_check` tests on the windows (at least 4): a run that
    fails -- or has fewer than 4 windows to tell -- has status ``NOT_SETTLED``, ``ok`` False,
    its exponents kept and a message saying how long to run.
    ``progress(t, t_end)`` is called between bounded calls (Ctrl-C stops within a few ms).

    A run that stops early (non-finite state, step underflow, ``max_steps``) returns the exponents
    up to where it got, with ``status``/``message`` set and ``ok`` False -- as every result does
    (:func:`skewpend.simulate` too); with ``throw=True`` it raises
    :class:`~skewpend.errors.IntegrationError` instead.
    """
    from ..numeric.kernels import model_kernel, model_vector, model_vector_names

    params = numeric_model(params, "Lyapunov exponents")
    y = initial_state(y0, params.coordinates)
    n2 = y.size
    t_end, renorm_every, transient = check_times(t_end, renorm_every, transient)
    k = n2 if n_exponents is None else whole("n_exponents", n_exponents, 1, n2, what="the state's components")
    rtol, atol = tolerances(rtol, atol)
    max_steps = check_max_steps(max_steps)
    windows = whole("windows", windows, 1, 1000)
    progress_callable(progress, "progress(t, t_end)")

    kernel = model_kernel(params, chaos=True)
    p = model_vector(params)
    from ..numeric.simulation import check_start

    check_start(kernel, p, y, model_vector_names(params))
    state = kernel.LyapState()
    state.k, state.every, state.t0 = k, renorm_every, 0.0
    tangent = np.eye(n2)[:, :k] if k > 1 else np.full((n2, 1), 1.0 / math.sqrt(n2))
    state.y[:n2 * (k + 1)] = np.concatenate([y, tangent.T.ravel()]).tolist()  # the state, then each vector

    # the measured part: renormalisations after the transient, cut into windows of whole intervals
    n_total = int(math.ceil(t_end / renorm_every * (1 - 1e-12)))
    n_skip = skipped_renormalisations(transient, renorm_every)
    n_meas = n_total - n_skip
    n_win = min(int(windows), n_meas)
    bounds = np.linspace(0, n_meas, n_win + 1).round().astype(np.int64)  # window w: rows bounds[w] .. bounds[w+1]-1
    stride = max(1, int(math.ceil(n_meas / _HISTORY)))

    win_sum = np.zeros((n_win, k))
    win_time = np.zeros(n_win)
    total = np.zeros(k)
    t_from = n_skip * renorm_every if n_skip else 0.0
    t_prev_row = 0.0
    t_last = t_from  # time of the last measured renormalisation
    hist_t, hist = [], []
    seen = 0  # measured rows so far

    rows = np.empty((_ROWS, k + 1))
    dp = ctypes.POINTER(ctypes.c_double)
    m = ctypes.c_int64(0)
    call_args = (ctypes.byref(state), p.ctypes.data_as(dp), t_end, rtol, atol, max_steps, _BUDGET,
                 rows.ctypes.data_as(dp), _ROWS, ctypes.byref(m))
    start = time.perf_counter()
    renorms = 0

    def take() -> None:
        nonlocal renorms, t_from, t_last, t_prev_row, seen
        for row in rows[: m.value]:
            renorms += 1
            t = float(row[0])
            if renorms <= n_skip:
                t_from = t_last = t_prev_row = t
                continue
            logs = row[1:]
            total[:] += logs
            w = min(int(np.searchsorted(bounds, seen, side="right") - 1), n_win - 1)
            win_sum[w] += logs
            win_time[w] += t - t_prev_row
            t_prev_row = t_last = t
            seen += 1
            if seen % stride == 0 or seen == n_meas:
                hist_t.append(t)
                hist.append(total / (t - t_from))

    with Interrupts() as intr:  # Ctrl-C raised between the bounded calls, never lost
        # after the first bounded call: refuse what cannot finish, as simulate does
        status = int(drive(lambda budget: kernel.lib.sp_lyap(*call_args), budget=_BUDGET, take=take, check=intr.check,
                       progress=None if progress is None else (lambda: progress(state.t, t_end)),
                       estimate=lambda: check_step_estimate(state, t_end, max_steps), name="sp_lyap"))
    wall = time.perf_counter() - start

    t_reached = float(state.t)
    span = t_last - t_from
    exponents = total / span if span > 0 else np.full(k, np.nan)
    filled = win_time > 0
    win_exp = np.where(filled[:, None], win_sum / np.where(filled, win_time, 1.0)[:, None], np.nan)
    n_filled = int(np.count_nonzero(filled))
    uncertainty = (np.nanstd(win_exp[filled], axis=0, ddof=1) / math.sqrt(n_filled) if n_filled >= 2
                   else np.full(k, np.nan))
    message = "reached t_end" if status == 0 else f"stopped at t = {t_reached:.6g} s: {_STATUS.get(status, f'status {status}')}"
    check = {"halves_sigma": math.nan, "von_neumann_sigma": math.nan}
    if status == 0 and span > 0 and n_filled >= MIN_WINDOWS and np.all(np.isfinite(win_exp)):
        settled, check["halves_sigma"], check["von_neumann_sigma"], detail = settle_check(win_exp)
        if not settled:
            status = int(Status.NOT_SETTLED)
            message = (f"{detail.split(':')[0]} has not settled in {span:g} s: {detail.split(': ', 1)[1]}; "
                       f"run longer, e.g. t_end = {_longer(t_end):g} s")
    elif status == 0:
        status = int(Status.NOT_SETTLED)
        message = (f"reached t_end, but whether the exponents have settled cannot be told from {n_filled} "
                   f"window{'s' if n_filled != 1 else ''}: the check needs at least {MIN_WINDOWS} (windows >= "
                   f"{MIN_WINDOWS} and as many renormalisations after the transient)")
    settings = {
        "t_end": t_end, "renorm_every": renorm_every, "transient": transient, "measured_from": t_from,
        "n_exponents": k, "rtol": rtol, "atol": atol, "windows": n_win, "max_steps": max_steps,
        "method": "dop853 on the state and tangent vectors (Benettin, QR)",
    }
    stats = {
        "steps": int(state.naccept), "rejected": int(state.nreject), "nfev": int(state.nfev),
        "renormalisations": int(state.nrenorm), "t_reached": t_reached, "wall_time": wall,
        "kernel": kernel.origin, "kernel_build_time": kernel.build_time, **check,
    }
    result = LyapunovSpectrum(
        exponents=exponents, uncertainty=uncertainty, t=np.asarray(hist_t), history=np.asarray(hist).reshape(-1, k),
        window_exponents=win_exp, params=params, y0=y, settings=settings, stats=stats, status=Status.of(int(status)),
        message=message,
    )
    if status not in (0, int(Status.NOT_SETTLED)) and throw:
        raise IntegrationError(f"lyapunov: {message}; the exponents up to there are in the result with throw=False")
    return result


# -- many trajectories: the largest exponent on the ensemble engine ----------------------------------------
def largest_exponents(kernel, p, starts, *, t_end: float, renorm_every: float, transient: float, rtol: float,
                      atol: float, max_steps: int, cancel=None, group: int = 1):
    """The largest exponent of each state in ``starts`` (shape ``(m, 4)``), by ``sp_lyap1_many``
    (one tangent vector from ``(1, 1, 1, 1)/2``), ``group`` trajectories per call into C (``cancel``
    is checked between calls).  Returns ``(lambda, status, steps, rejected)``: the accepted and
    the rejected steps of each; ``lambda`` is NaN where a trajectory failed."""
    starts = np.ascontiguousarray(starts, dtype=np.float64).reshape(-1, 4)
    m = starts.shape[0]
    lam, status = np.full(m, np.nan), np.zeros(m, dtype=np.int32)
    steps, rejected = np.zeros(m, dtype=np.int64), np.zeros(m, dtype=np.int64)
    pp = np.ascontiguousarray(p, dtype=np.float64)
    dp, i32p, i64p = (ctypes.POINTER(t) for t in (ctypes.c_double, ctypes.c_int32, ctypes.c_int64))
    for a in range(0, m, group):
        if cancel is not None and cancel.is_set():
            raise Cancelled()
        b = min(m, a + group)
        kernel.lib.sp_lyap1_many(pp.ctypes.data_as(dp), starts[a:b].ctypes.data_as(dp), b - a, t_end, renorm_every,
                                 skipped_renormalisations(transient, renorm_every), rtol, atol, max_steps,
                                 *(x[a:].ctypes.data_as(t) for x, t in zip((lam, status, steps, rejected),
                                                                           (dp, i32p, i64p, i64p))))
    return lam, status, steps, rejected


@dataclass(frozen=True)
class LyapunovMap(Result):
    """The result of :func:`lyapunov_map`: the largest exponent [1/s] for starts at rest from the
    cell centres ``phi0`` (axis 0) x ``psi0`` (axis 1) [rad], shape ``(n, n)`` (NaN where the
    integration failed), with the result protocol's fields: ``stats`` (``cells``, ``failed``, ``steps``,
    ``rejected``; the run's chunks, store and cluster), ``status`` (PARTIAL when cells failed)."""

    phi0: np.ndarray
    psi0: np.ndarray
    exponent: np.ndarray

    result_kind: ClassVar[str] = "Lyapunov map"

    @property
    def n(self) -> int:
        return int(self.exponent.shape[0])

    def _dataset(self) -> DatasetSpec:
        return DatasetSpec(
            variables={"exponent": (("phi0", "psi0"), self.exponent, dict(_MAP_VARIABLES["exponent"]))},
            coords={"phi0": (("phi0",), self.phi0[:, 0].copy(), dict(_MAP_VARIABLES["phi0"])),
                    "psi0": (("psi0",), self.psi0[0].copy(), dict(_MAP_VARIABLES["psi0"]))},
            attrs={"title": LyapunovMapJob.title, **self._base_attrs()},
        )


_MAP_VARIABLES = {
    "exponent": {"units": "1/s", "long_name": "largest Lyapunov exponent of a start at rest; NaN: failed"},
    "phi0": {"units": "rad", "long_name": "initial angle of hinge 1"},
    "psi0": {"units": "rad", "long_name": "initial angle of hinge 2"},
}
#: Statistics per row (and per store chunk) of a Lyapunov map.
MAP_STATS = ("cells", "failed", "steps", "rejected")


@dataclass(frozen=True)
class LyapunovMapJob(GridJob):
    """A Lyapunov map as a job of the grid driver (small and picklable)."""

    params: Parameters
    n: int
    t_end: float
    renorm_every: float
    transient: float
    phi_range: tuple
    psi_range: tuple
    rtol: float
    atol: float
    max_steps: int
    version: str

    kind: ClassVar[str] = "skewpend lyapunov map"
    what: ClassVar[str] = "a Lyapunov map"
    stat_names: ClassVar[tuple] = MAP_STATS
    title: ClassVar[str] = "largest Lyapunov exponent of starts at rest (skewpend)"

    def shape(self):
        return self.n, self.n

    def arrays(self):
        return {"exponent": ArraySpec("float64", np.nan, _MAP_VARIABLES["exponent"])}

    def coords(self):
        return {"phi0": (cell_centres(*self.phi_range, self.n), _MAP_VARIABLES["phi0"]),
                "psi0": (cell_centres(*self.psi_range, self.n), _MAP_VARIABLES["psi0"])}

    def settings(self):
        return {"kind": "lyapunov_map", "params": self.params.to_dict(), "n": self.n, "t_end": self.t_end,
                "renorm_every": self.renorm_every, "transient": self.transient, "phi_range": list(self.phi_range),
                "psi_range": list(self.psi_range), "rtol": self.rtol, "atol": self.atol,
                "max_steps": self.max_steps, "skewpend_version": self.version}

    def setup(self):
        from ..numeric.kernels import kernel_module, parameter_vector

        return kernel_module(self.params, chaos=True), parameter_vector(self.params)

    def compute(self, state, rows, cancel=None):
        kernel, p = state
        phi, psi = (values for values, _ in self.coords().values())
        shape = (rows.size, self.n)
        starts = np.zeros((rows.size * self.n, 4))
        starts[:, 0], starts[:, 1] = np.repeat(phi[rows], self.n), np.tile(psi, rows.size)
        lam, status, steps, rejected = largest_exponents(
            kernel, p, starts, t_end=self.t_end, renorm_every=self.renorm_every, transient=self.transient,
            rtol=self.rtol, atol=self.atol, max_steps=self.max_steps, cancel=cancel)
        stats = np.column_stack([np.full(rows.size, self.n), (status != 0).reshape(shape).sum(1),
                                 steps.reshape(shape).sum(1), rejected.reshape(shape).sum(1)]).astype(float)
        return {"exponent": lam.reshape(shape)}, stats

    def result(self, run) -> LyapunovMap:
        n = self.n
        totals = run.totals(MAP_STATS)
        settings = {k: tuple(v) if isinstance(v, list) else v for k, v in self.settings().items()
                    if k not in ("kind", "params", "skewpend_version")}  # the ranges as tuples
        stats = {"cells": n * n, **{k: int(totals[k]) for k in MAP_STATS[1:]}, **run.info}
        status, message = grid_status(stats["failed"], n * n, "cells")
        phi, psi = (values for values, _ in self.coords().values())
        return LyapunovMap(phi0=np.broadcast_to(phi[:, None], (n, n)), psi0=np.broadcast_to(psi[None, :], (n, n)),
                           exponent=run.data["exponent"], params=self.params, settings=settings, stats=stats,
                           status=status, message=message)

    def result_attrs(self, result):
        return {"lyapunov_map_settings": canonical_json(result.settings),
                "lyapunov_map_stats": canonical_json(result.stats)}


def lyapunov_map(
    params: Parameters,
    n: int,
    *,
    t_end: float = 100.0,
    renorm_every: float = 1.0,
    transient: float = 0.0,
    phi_range: Sequence[float] = (-math.pi, math.pi),
    psi_range: Sequence[float] = (-math.pi, math.pi),
    rtol: Optional[float] = 1e-8,
    atol: Optional[float] = 1e-8,
    workers: Optional[int] = None,
    max_steps: int = MAX_STEPS,
    progress: Optional[Callable[[int, int], None]] = None,
    store=None,
    resume: bool = False,
    scheduler=None,
) -> LyapunovMap:
    """The largest Lyapunov exponent [1/s] over ``t_end`` seconds for the starts at rest from the
    centres of an ``n x n`` grid over ``phi_range x psi_range`` [rad] (as :func:`flip_map`):
    one tangent vector per start, renormalised every ``renorm_every`` s, DOP853 at
    ``rtol``/``atol`` (default 1e-8: the exponent, not the trajectory, is wanted), rows of cells
    on ``workers`` threads (default: every core), ``progress(done_cells, total_cells)``;
    ``store`` (``*.zarr``), ``resume`` and ``scheduler`` as for
    :func:`~skewpend.analysis.flipmap.flip_map` (a :class:`LyapunovMapJob` on
    :func:`skewpend.numeric.grid.run_grid`).  Bitwise the same whatever the number of workers,
    the chunking or the cluster."""
    from .. import __version__
    from ..numeric.grid import run_grid  # looked up here: a test's stand-in for the driver is called

    params = numeric_params(params, "a Lyapunov map")
    n = check_n(n)
    if n > 1024:
        raise ParameterError(f"n must be at most 1024 for a Lyapunov map (each cell is a long integration), got {n}")
    t_end, renorm_every, transient = check_times(t_end, renorm_every, transient)
    phi_range = check_range("phi_range", phi_range)
    psi_range = check_range("psi_range", psi_range)
    rtol, atol = tolerances(rtol, atol)
    max_steps = check_max_steps(max_steps)
    workers = check_run_options(workers=workers, scheduler=scheduler, store=store, resume=resume, progress=progress)
    job = LyapunovMapJob(params=params, n=n, t_end=t_end, renorm_every=renorm_every, transient=transient,
                         phi_range=tuple(phi_range), psi_range=tuple(psi_range), rtol=rtol, atol=atol,
                         max_steps=max_steps, version=__version__)
    state = job.setup()
    corner = (max(map(abs, phi_range)), max(map(abs, psi_range)))
    probe = [(0.9 * corner[0], 0.9 * corner[1], 0.0, 0.0), (0.9 * corner[0], -0.9 * corner[1], 0.0, 0.0),
             (0.5 * corner[0], 0.0, 0.0, 0.0)]
    check_exponent_work(state, probe, params=params, t_end=t_end, rtol=rtol, atol=atol, max_steps=max_steps,
                        what="this Lyapunov map")
    return run_grid(job, workers=workers, scheduler=scheduler, store=store, resume=bool(resume), progress=progress,
                    state=state)


def check_exponent_work(state, probe, *, params, t_end: float, rtol: float, atol: float, max_steps: int,
                        what: str, time_name: str = "t_end", advice: Optional[str] = None) -> None:
    """Refuse up front work of largest exponents that cannot finish within ``max_steps`` per
    trajectory: a trial run of the chaos kernel (``state`` = (kernel, p)) from ``probe``."""
    kernel, p = state

    def trial(t):
        _, status, steps, rejected = largest_exponents(kernel, p, np.asarray(probe, dtype=float), t_end=t,
                                                       renorm_every=t, transient=0.0, rtol=rtol, atol=atol,
                                                       max_steps=PROBE_STEPS)
        # a trial that stopped early made at most its steps in t: a lower bound of the rate
        return steps_per_second(steps + rejected, np.full(steps.shape, t)), bool(np.all(status == 0))

    check_feasible(trial, params=params, t_end=t_end, rtol=rtol, atol=atol, max_steps=max_steps, what=what,
                   time_name=time_name, advice=advice)


def open_lyapunov_map(path) -> LyapunovMap:
    """A :class:`LyapunovMap` read back from a complete store ``*.zarr`` or a file ``*.nc``."""
    def build(arrays, attrs, settings, stats):
        params = Parameters.from_mapping(json.loads(attrs["params"]) if "params" in attrs
                                         else json.loads(attrs["settings"])["params"])
        phi, psi = (np.asarray(arrays[k], dtype=float) for k in ("phi0", "psi0"))
        for key in ("phi_range", "psi_range"):
            settings[key] = tuple(settings[key])
        n = phi.size
        status, message = grid_status(int(stats.get("failed", 0)), n * n, "cells")
        return LyapunovMap(phi0=np.broadcast_to(phi[:, None], (n, n)), psi0=np.broadcast_to(psi[None, :], (n, n)),
                           exponent=np.asarray(arrays["exponent"], dtype=float), params=params, settings=settings,
                           stats=stats, status=status, message=message)

    return read_grid_result(path, build, store_kind=LyapunovMapJob.kind, result_kind=LyapunovMap.result_kind,
                            what="a Lyapunov map", store_keys=("lyapunov_map_settings", "lyapunov_map_stats"))
