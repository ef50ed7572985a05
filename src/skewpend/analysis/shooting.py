"""The output-error fit of :func:`skewpend.identify`: multiple shooting with exact sensitivities.

The model is written in its base parameters ``beta`` (:mod:`skewpend.symbolic.regressor`): the
equations ``Y_b(q, q', q''; a, alpha, g) beta = tau`` are linear in ``q''``,
``Y_b = Yh(q, q') + YM_1(q) q1'' + YM_2(q) q2''``, so ``M(q) = [YM_1 beta, YM_2 beta]`` and
``q'' = M^-1 (tau - Yh beta)``.  Everything a step needs -- ``YM_i``, ``Yh`` and their
derivatives in ``q``, ``q'`` and the skew angle ``alpha`` -- is generated once from the symbolic
base regressor (SymPy ``lambdify`` with common subexpressions); ``beta`` and ``alpha`` are run-time
inputs, so a fit generates its functions once and never per iteration.  The sensitivities follow
from differentiating ``Y_b beta = tau``:

    d q''/d x = -M^-1 (d Y_b/d x) beta  (x = q, q', alpha; q'' held),   d q''/d beta_k = -M^-1 Y_b[:, k].

The measured pieces are cut into segments (default :data:`SEGMENT` = 0.5 s); each segment starts
from its own free state ``(q, q')`` (the *shooting nodes*; continuity between segments is not
imposed, so a segment never carries another's error) and is integrated by the classical RK4 at a
fixed step (a multiple of the sampling step near :data:`STEP`) together with its variational
equations: applied to the state and its sensitivities at once, RK4 gives the exact derivative of
its own discrete map, so the Jacobian of the residuals is exact for the model that is fitted.  All
segments advance together (NumPy arrays over segments).  The residuals are the simulated minus the
measured angles at every step.

Gauss-Newton with Levenberg-Marquardt damping; each segment's 4 start values are eliminated per
segment (Schur complement), so the linear algebra is that of the few global parameters.  It stops
when the cost stops falling (relative ``tol``), or when the undamped Gauss-Newton step, or each of
the last :data:`STALLED` accepted steps, moves every free parameter by less than :data:`STEP_HALF`
of its 95 % half-width: on a real rig with Coulomb friction the quadratic model of the cost holds in
a small region only and the iteration creeps, its steps alternating and shrinking slowly, long
after the parameters stopped moving on the scale of what the data determine.

Intervals: residuals of a real rig are mostly model error, correlated along a piece, so the
Gauss-Newton covariance ``sigma^2 (J^T J)^-1`` is far too narrow.  The covariance used is the
*cluster-robust sandwich* over pieces, ``S^-1 (sum_c g_c g_c^T) S^-1`` (``S`` the reduced
Gauss-Newton matrix, ``g_c`` piece ``c``'s reduced gradient at the optimum), which holds for any
correlation within a piece, with Student's t quantile at ``pieces - 1`` degrees of freedom; it is checked against one-step re-fits on the pieces resampled with
replacement (seeded) and against the jackknife over pieces (each left out in turn, one step from the
optimum: the sandwich is too narrow with few clusters), and each half-width is the largest of the three.  With few pieces (one long
recording), the clusters are blocks of consecutive segments instead of pieces
(:func:`skewpend.analysis.identify.clusters`, the ``cluster`` argument of :func:`fit`).  A direction whose reduced
curvature is below :data:`FLAT` of the largest (column-scaled) is undetermined: it gets no interval.
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass, field
from typing import Callable, Dict, Optional, Sequence, Tuple

import numpy as np
import sympy as sp

from ..errors import ParameterError
from ..schema import LENGTH_NAMES
from ..symbolic.symbols import SYMBOLS

__all__ = ["SEGMENT", "STEP", "FLAT", "STEP_HALF", "STALLED", "ShootingFit", "Segments", "segments", "fit"]

#: Default length of a shooting segment [s].
SEGMENT = 0.5
#: Target RK4 step [s] (rounded to a whole number of sampling steps).
STEP = 0.004
#: Smallest relative curvature (reduced, column-scaled Gauss-Newton matrix) of a determined direction.
FLAT = 1e-9

_VARS = ("phi", "psi", "dphi", "dpsi", "alpha")


_GENERATED: Dict[str, Tuple[Callable, Callable, int]] = {}


def _generated(Yb: sp.Matrix) -> Tuple[Callable, Callable, int]:
    """Two compiled functions generated from ``Y_b`` (cached, on disk like the kernels), each
    ``fn(y (S, 4), alpha, a, g) -> (entries, S)``: ``base`` gives ``[YM1, YM2, Yh]`` and ``full`` in
    addition ``dYh/dphi, dYh/dpsi, dYM1/dphi, dYM1/dpsi, dYM2/dphi, dYM2/dpsi, dYh/ddphi, dYh/ddpsi,
    dYh/dalpha, dYM1/dalpha, dYM2/dalpha``: each entry flattened (2 x r per matrix).  C, from the
    expressions with common subexpressions eliminated (NumPy on a few hundred segments spent its time
    on the calls, not the arithmetic: 0.4 ms a call against a few microseconds)."""
    key = sp.srepr(Yb)
    if key in _GENERATED:
        return _GENERATED[key]
    S = SYMBOLS
    Y = Yb
    YM1, YM2 = Y.diff(S["ddphi"]), Y.diff(S["ddpsi"])
    Yh = Y.xreplace({S["ddphi"]: 0, S["ddpsi"]: 0})
    for M in (YM1, YM2):
        if M.free_symbols & {S["ddphi"], S["ddpsi"], S["dphi"], S["dpsi"]}:
            raise AssertionError("the mass matrix of the base regressor depends on the speeds")
    d = lambda M, n: M.diff(S[n])  # noqa: E731
    mats_base = [YM1, YM2, Yh]
    mats_full = mats_base + [d(Yh, "phi"), d(Yh, "psi"), d(YM1, "phi"), d(YM1, "psi"), d(YM2, "phi"), d(YM2, "psi"),
                             d(Yh, "dphi"), d(Yh, "dpsi"), d(Yh, "alpha"), d(YM1, "alpha"), d(YM2, "alpha")]
    source = "\n".join(["#include <math.h>", "#include <stdint.h>",
                        _c_function("sp_regressor_base", [e for M in mats_base for e in M]),
                        _c_function("sp_regressor_full", [e for M in mats_full for e in M])])
    from ..numeric.kernels import source_library

    lib = source_library(source, "regressor")
    _GENERATED[key] = (_caller(lib.sp_regressor_base, 3 * Yb.rows * Yb.shape[1]),
                       _caller(lib.sp_regressor_full, 14 * Yb.rows * Yb.shape[1]), Yb.shape[1])
    return _GENERATED[key]


#: The inputs of the generated functions, in the order of their C arguments after the state.
_INPUTS = ("phi", "psi", "dphi", "dpsi", "alpha") + (LENGTH_NAMES[0], "g")  # the regressor's STRUCTURE


def _c_function(name: str, exprs: Sequence[sp.Expr]) -> str:
    """``void name(int64_t n, const double *y, double alpha, double a, double g, double *out)``: the
    expressions at each of the ``n`` states ``y`` (n, 4), entry k of state i in ``out[k n + i]``."""
    from sympy.printing.c import C99CodePrinter

    local = sp.symbols("v_phi v_psi v_dphi v_dpsi v_alpha v_a v_g")
    to_local = {SYMBOLS[n]: v for n, v in zip(_INPUTS, local)}
    exprs = [sp.sympify(e).xreplace(to_local) for e in exprs]
    if set().union(*(e.free_symbols for e in exprs)) - set(local):
        raise AssertionError("the base regressor has symbols besides the state, alpha, a and g")
    temps, reduced = sp.cse(exprs, symbols=sp.numbered_symbols("t"))
    printer = C99CodePrinter()
    lines = [f"void {name}(int64_t n, const double *y, double v_alpha, double v_a, double v_g, double *out) {{",
             "  (void)v_alpha; (void)v_a; (void)v_g;",
             "  for (int64_t i = 0; i < n; i++) {",
             "    const double v_phi = y[4 * i], v_psi = y[4 * i + 1], v_dphi = y[4 * i + 2], v_dpsi = y[4 * i + 3];",
             "    (void)v_phi; (void)v_psi; (void)v_dphi; (void)v_dpsi;"]
    lines += [f"    const double {t} = {printer.doprint(e)};" for t, e in temps]
    lines += [f"    out[{k} * n + i] = {printer.doprint(e)};" for k, e in enumerate(reduced)]
    return "\n".join(lines + ["  }", "}"])


def _caller(fn, entries: int) -> Callable:
    """``call(y, alpha, a, g) -> (entries, S)`` around the C function ``fn``."""
    import ctypes

    vp, d = ctypes.c_void_p, ctypes.c_double
    fn.argtypes, fn.restype = [ctypes.c_int64, vp, d, d, d, vp], None

    def call(y: np.ndarray, alpha: float, a: float, g: float) -> np.ndarray:
        y = np.ascontiguousarray(y, dtype=float)
        out = np.empty((entries, len(y)))
        fn(len(y), y.ctypes.data, float(alpha), a, g, out.ctypes.data)
        return out

    return call


class _Model:
    """The segment dynamics in base parameters (see the module)."""

    def __init__(self, Yb: sp.Matrix, a: float, g: float):
        self.base, self.full, self.r = _generated(Yb)
        self.a, self.g = float(a), float(g)

    def _eval(self, fn, y, alpha, count):
        return fn(y, alpha, self.a, self.g).reshape(count, 2, self.r, len(y))

    def accel(self, y, beta, alpha, tau):
        """q'' (S, 2) of states ``y`` (S, 4)."""
        arr = self._eval(self.base, y, alpha, 3)
        P = np.einsum("kirs,r->kis", arr, beta)
        return _solve2(P[0], P[1], tau.T - P[2]).T

    def rhs(self, y, beta, alpha, tau, free_idx, alpha_free):
        """(y', A, B): y' (S, 4); A = d y'/d y (S, 4, 4); B = d y'/d theta (S, 4, p), theta the free
        base parameters then alpha."""
        arr = self._eval(self.full, y, alpha, 14)
        P = np.einsum("kirs,r->kis", arr, beta)  # (14, 2, S)
        ddq = _solve2(P[0], P[1], tau.T - P[2])  # (2, S)
        d1, d2 = ddq
        n = len(y)
        v = np.empty((4 + 1, 2, n))  # d(Y beta)/d(phi, psi, dphi, dpsi, alpha) at the current q''
        v[0] = P[3] + P[5] * d1 + P[7] * d2
        v[1] = P[4] + P[6] * d1 + P[8] * d2
        v[2] = P[9]
        v[3] = P[10]
        v[4] = P[11] + P[12] * d1 + P[13] * d2
        cols = [arr[2][:, j] + arr[0][:, j] * d1 + arr[1][:, j] * d2 for j in free_idx]  # Y_b[:, j], (2, S)
        rhs_v = np.concatenate([v[:4], np.array(cols).reshape(-1, 2, n)] + ([v[4:5]] if alpha_free else []))
        sol = -_solve2(P[0], P[1], rhs_v)  # (m, 2, S): -M^-1 v
        dy = np.empty((n, 4))
        dy[:, :2] = y[:, 2:]
        dy[:, 2:] = ddq.T
        A = np.zeros((n, 4, 4))
        A[:, 0, 2] = A[:, 1, 3] = 1.0
        A[:, 2:, :] = np.transpose(sol[:4], (2, 1, 0))
        B = np.zeros((n, 4, len(sol) - 4))
        B[:, 2:, :] = np.transpose(sol[4:], (2, 1, 0))
        return dy, A, B


def _solve2(c1, c2, rhs):
    """Solve [c1 c2] x = rhs for 2 x 2 matrices given by columns c1, c2 (2, S); rhs (..., 2, S)."""
    det = c1[0] * c2[1] - c2[0] * c1[1]
    r0, r1 = rhs[..., 0, :], rhs[..., 1, :]
    out = np.empty(np.shape(rhs))
    out[..., 0, :] = (c2[1] * r0 - c2[0] * r1) / det
    out[..., 1, :] = (-c1[1] * r0 + c1[0] * r1) / det
    return out


# -- the data cut into segments -----------------------------------------------------------------------------
@dataclass
class Segments:
    """Every segment of every piece, padded to one length: ``q`` (S, L+1, 2) the measured angles at
    the steps, ``mask`` (S, L+1), ``tau`` (S, 2L+1, 2) torques at the steps and half steps (zeros
    for a free swing), ``y0`` (S, 4) the filtered start states, ``piece`` (S,) the piece index,
    ``h`` the RK4 step, ``every`` sampling steps per RK4 step, ``t0`` (S,) start times."""

    q: np.ndarray
    mask: np.ndarray
    tau: np.ndarray
    y0: np.ndarray
    piece: np.ndarray
    t0: np.ndarray
    h: float
    every: int
    names: Tuple[str, ...] = ()

    def __len__(self) -> int:
        return len(self.q)


def segments(filtered: Sequence[Tuple], names: Sequence[str], segment: float = SEGMENT, step: float = STEP) -> Segments:
    """Cut filtered pieces ``(t, q_raw, q_smooth, dq_smooth, u)`` (uniform grids) into segments."""
    dts = [float(t[1] - t[0]) for t, *_ in filtered]
    dt = float(np.median(dts))
    if max(dts) - min(dts) > 1e-6 * dt:
        raise ParameterError("the pieces are sampled at different rates: identify them separately")
    every = max(1, int(round(step / dt)))
    h = every * dt
    L = max(2, int(round(segment / h)))
    cuts = []
    for k, (t, *_rest) in enumerate(filtered):
        n_steps = (len(t) - 1) // every
        if n_steps < 2:
            continue
        count = max(1, int(round(n_steps / L)))
        bounds = np.linspace(0, n_steps, count + 1).round().astype(int)
        cuts += [(k, int(s0), int(s1)) for s0, s1 in zip(bounds[:-1], bounds[1:])]
    if not cuts:
        raise ParameterError("no piece is long enough for one shooting segment")
    Lmax = max(s1 - s0 for _, s0, s1 in cuts)
    qs, masks, taus, y0s, owner, t0s = [], [], [], [], [], []
    for k, s0, s1 in cuts:
        t, q, qf, dqf, u = filtered[k]
        idx = np.arange(s0, s1 + 1) * every
        m = len(idx)
        Q = np.zeros((Lmax + 1, 2))
        Q[:m] = q[idx]
        M = np.zeros(Lmax + 1)
        M[:m] = 1.0
        T = np.zeros((2 * Lmax + 1, 2))
        if u is not None:
            half = np.arange(s0 * 2, s1 * 2 + 1) * every / 2.0  # sample index of the steps and half steps
            lo = np.floor(half).astype(int)
            hi = np.minimum(lo + 1, len(t) - 1)
            f = (half - lo)[:, None]
            T[:len(half)] = (1 - f) * u[lo] + f * u[hi]
        qs.append(Q)
        masks.append(M)
        taus.append(T)
        y0s.append(np.concatenate([qf[idx[0]], dqf[idx[0]]]))
        owner.append(k)
        t0s.append(float(t[idx[0]]))
    return Segments(q=np.array(qs), mask=np.array(masks), tau=np.array(taus),
                    y0=np.array(y0s), piece=np.array(owner), t0=np.array(t0s), h=h, every=every, names=tuple(names))


# -- integration ----------------------------------------------------------------------------------------------
def _simulate(model: _Model, seg: Segments, y0, beta, alpha):
    """Angles (S, L+1, 2) by RK4 from ``y0`` (no sensitivities)."""
    h = seg.h
    L = seg.q.shape[1] - 1
    y = np.array(y0, dtype=float)
    out = np.empty(seg.q.shape)
    out[:, 0] = y[:, :2]

    def f(y, k):
        dy = np.empty_like(y)
        dy[:, :2] = y[:, 2:]
        dy[:, 2:] = model.accel(y, beta, alpha, seg.tau[:, k])
        return dy

    with np.errstate(all="ignore"):
        for i in range(L):
            k1 = f(y, 2 * i)
            k2 = f(y + 0.5 * h * k1, 2 * i + 1)
            k3 = f(y + 0.5 * h * k2, 2 * i + 1)
            k4 = f(y + h * k3, 2 * i + 2)
            y = y + h / 6.0 * (k1 + 2 * k2 + 2 * k3 + k4)
            out[:, i + 1] = y[:, :2]
    return out


def _linearise(model: _Model, seg: Segments, y0, beta, alpha, free_idx, alpha_free):
    """Residuals and the accumulated Gauss-Newton blocks per segment:
    ``e`` (S, L+1, 2), ``Hll`` (S, 4, 4), ``Hlg`` (S, 4, p), ``Hgg`` (S, p, p), ``gl`` (S, 4), ``gg`` (S, p)."""
    h = seg.h
    S, L1 = seg.q.shape[:2]
    p = len(free_idx) + (1 if alpha_free else 0)
    y = np.array(y0, dtype=float)
    Z = np.zeros((S, 4, 4 + p))
    Z[:, :, :4] = np.eye(4)
    e = np.empty(seg.q.shape)
    Hll = np.zeros((S, 4, 4))
    Hlg = np.zeros((S, 4, p))
    Hgg = np.zeros((S, p, p))
    gl = np.zeros((S, 4))
    gg = np.zeros((S, p))

    def accumulate(i):
        w = seg.mask[:, i]
        r = (y[:, :2] - seg.q[:, i]) * w[:, None]
        e[:, i] = r
        Jl, Jg = Z[:, :2, :4] * w[:, None, None], Z[:, :2, 4:] * w[:, None, None]
        Hll[:] += np.einsum("sia,sib->sab", Jl, Jl)
        Hlg[:] += np.einsum("sia,sib->sab", Jl, Jg)
        Hgg[:] += np.einsum("sia,sib->sab", Jg, Jg)
        gl[:] += np.einsum("sia,si->sa", Jl, r)
        gg[:] += np.einsum("sia,si->sa", Jg, r)

    def f(y, Z, k):
        dy, A, B = model.rhs(y, beta, alpha, seg.tau[:, k], free_idx, alpha_free)
        dZ = A @ Z
        dZ[:, :, 4:] += B
        return dy, dZ

    accumulate(0)
    with np.errstate(all="ignore"):
        for i in range(L1 - 1):
            k1, K1 = f(y, Z, 2 * i)
            k2, K2 = f(y + 0.5 * h * k1, Z + 0.5 * h * K1, 2 * i + 1)
            k3, K3 = f(y + 0.5 * h * k2, Z + 0.5 * h * K2, 2 * i + 1)
            k4, K4 = f(y + h * k3, Z + h * K3, 2 * i + 2)
            y = y + h / 6.0 * (k1 + 2 * k2 + 2 * k3 + k4)
            Z = Z + h / 6.0 * (K1 + 2 * K2 + 2 * K3 + K4)
            accumulate(i + 1)
    return e, Hll, Hlg, Hgg, gl, gg


def _reduce(Hll, Hlg, Hgg, gl, gg, lam):
    """Eliminate each segment's start values: the reduced matrix and gradient per segment, and the
    factors to recover the local steps."""
    D = np.einsum("sii->si", Hll)
    A = Hll + lam * D[:, :, None] * np.eye(4)
    Ainv = np.linalg.inv(A)
    AinvB = Ainv @ Hlg
    Sred = Hgg - np.einsum("sab,sac->sbc", Hlg, AinvB)
    gred = gg - np.einsum("sab,sa->sb", AinvB, gl)
    return Sred, gred, Ainv, AinvB


#: Converged when the undamped Gauss-Newton step, or each of the last :data:`STALLED` accepted steps,
#: moves every free parameter by less than this fraction of the half-width of its 95 % interval (the
#: cluster-robust sandwich reported, see the module).
STEP_HALF = 0.02
#: Accepted steps in a row below :data:`STEP_HALF` of every half-width that end the iteration.
STALLED = 3


def _halves(Hll, Hlg, Hgg, gl, gg, owner: np.ndarray, pieces: int):
    """The undamped Gauss-Newton step from here and the 95 % half-widths of the sandwich over clusters
    (``owner``: each segment's cluster, ``pieces`` of them: the pieces, or blocks of them)
    (as reported at the end); None where they are not defined.

    Why a stopping rule on this scale: on real data the residuals are mostly model error and the
    Gauss-Newton model of the cost holds in a small region only (Coulomb friction's ``atan(cfs q')``
    makes the angles' response to the parameters strongly nonlinear), so Levenberg-Marquardt creeps
    towards the optimum with the relative fall of the cost above any fixed tolerance for many
    iterations, long after the parameters stopped moving on the scale of what the data determine."""
    p = Hgg.shape[1]
    if p == 0 or pieces < 2:
        return None
    try:
        Sred, gred, _, _ = _reduce(Hll, Hlg, Hgg, gl, gg, 0.0)
        Sinv = np.linalg.inv(Sred.sum(0))
    except np.linalg.LinAlgError:
        return None
    step = -Sinv @ gred.sum(0)
    gc = np.zeros((pieces, p))
    np.add.at(gc, owner, gred)
    var = np.diag(Sinv @ (gc.T @ gc * pieces / (pieces - 1)) @ Sinv)
    from scipy.stats import t as student_t

    half = float(student_t.ppf(0.975, pieces - 1)) * np.sqrt(np.maximum(var, 0.0))
    if not (np.all(np.isfinite(step)) and np.all(np.isfinite(half)) and np.all(half > 0)):
        return None
    return step, half


@dataclass
class ShootingFit:
    """What :func:`fit` returns (the caller turns it into an :class:`~skewpend.Identification`)."""

    beta: np.ndarray
    alpha: float
    y0: np.ndarray
    theta_names: Tuple[str, ...]
    theta: np.ndarray
    half: np.ndarray  # 95 % half-widths of theta (NaN: undetermined)
    flat: Tuple[str, ...]
    cost: float
    rms_piece: np.ndarray  # angle RMS per fitting piece [rad]
    ssr_piece: np.ndarray  # sum of squared angle residuals per fitting piece [rad^2]
    iterations: int
    converged: bool
    message: str
    seconds: float
    segments: int
    step: float
    correlation: np.ndarray = field(default_factory=lambda: np.zeros((0, 0)))
    sandwich_half: np.ndarray = field(default_factory=lambda: np.zeros(0))
    bootstrap_half: np.ndarray = field(default_factory=lambda: np.zeros(0))
    newton_step: np.ndarray = field(default_factory=lambda: np.zeros(0))  # undamped Gauss-Newton step at the end
    ssr_cluster: np.ndarray = field(default_factory=lambda: np.zeros(0))  # per cluster of the intervals [rad^2]


def fit(Yb: sp.Matrix, names: Sequence[str], beta0: np.ndarray, free: Sequence[str], alpha0: float,
        alpha_free: bool, seg: Segments, a: float, g: float, *, pieces: int, max_iterations: int = 60,
        bootstrap: int = 200, seed: int = 0, tol: float = 1e-10, progress: Optional[Callable[[int, float], None]] = None,
        alpha_bounds: Tuple[float, float] = (-math.pi / 2, math.pi / 2),
        cluster: Optional[np.ndarray] = None) -> ShootingFit:
    """Levenberg-Marquardt on the segments' residuals; see the module.  ``cluster``: each segment's
    cluster of the intervals (default its piece; :func:`skewpend.analysis.identify.clusters` cuts few
    pieces into blocks)."""
    from scipy.stats import t as student_t

    owner = np.asarray(seg.piece if cluster is None else cluster, dtype=int)
    if owner.shape != (len(seg),):
        raise ParameterError(f"cluster must give one cluster a segment ({len(seg)}), got shape {owner.shape}")
    n_cl = int(owner.max()) + 1 if len(owner) else 0

    t_start = time.perf_counter()
    model = _Model(Yb, a, g)
    names = list(names)
    free_idx = [names.index(n) for n in free]
    theta_names = tuple(free) + (("alpha",) if alpha_free else ())
    beta = np.array(beta0, dtype=float)
    alpha = float(alpha0)
    y0 = np.array(seg.y0, dtype=float)

    def unpack(theta):
        b = beta.copy()
        b[free_idx] = theta[:len(free_idx)]
        return b, (float(theta[-1]) if alpha_free else alpha)

    theta = np.concatenate([beta[free_idx], [alpha] if alpha_free else []])
    lam = 1e-3
    e, Hll, Hlg, Hgg, gl, gg = _linearise(model, seg, y0, *unpack(theta), free_idx, alpha_free)
    cost = float(np.sum(e**2))
    if not math.isfinite(cost):
        raise FloatingPointError("the start model's simulation is not finite")
    converged, it, message, stalled = False, 0, "", 0
    for it in range(1, max_iterations + 1):
        accepted = False
        while lam < 1e12:
            Sred, gred, Ainv, AinvB = _reduce(Hll, Hlg, Hgg, gl, gg, lam)
            Ssum, gsum = Sred.sum(0), gred.sum(0)
            dgg = np.diag(Hgg.sum(0))
            Ssum = Ssum + lam * np.diag(np.maximum(dgg, 1e-12 * max(dgg.max(), 1e-300)))
            try:
                dg = -np.linalg.solve(Ssum, gsum)
            except np.linalg.LinAlgError:
                lam *= 10
                continue
            dl = -np.einsum("sab,sb->sa", Ainv, gl) - np.einsum("sab,b->sa", AinvB, dg)
            new_theta = theta + dg
            if alpha_free:
                new_theta[-1] = min(max(new_theta[-1], alpha_bounds[0]), alpha_bounds[1])
            new_y0 = y0 + dl
            q_new = _simulate(model, seg, new_y0, *unpack(new_theta))
            new_cost = float(np.sum(((q_new - seg.q) * seg.mask[:, :, None]) ** 2))
            if math.isfinite(new_cost) and new_cost < cost:
                accepted = True
                break
            lam *= 10
        if not accepted:
            message = "no step lowers the cost (a local minimum or the limit of rounding)"
            converged = True
            break
        rel = (cost - new_cost) / max(cost, 1e-300)
        theta, y0, cost = new_theta, new_y0, new_cost
        lam = max(lam / 10, 1e-12)
        e, Hll, Hlg, Hgg, gl, gg = _linearise(model, seg, y0, *unpack(theta), free_idx, alpha_free)
        cost = float(np.sum(e**2))
        if progress is not None:
            progress(it, cost)
        step_small = np.all(np.abs(dg) <= 1e-8 * np.maximum(np.abs(theta), 1e-12))
        if rel < tol or step_small:
            converged, message = True, "converged"
            break
        sh = _halves(Hll, Hlg, Hgg, gl, gg, owner, n_cl)
        if sh is not None:
            stalled = stalled + 1 if np.all(np.abs(dg) <= STEP_HALF * sh[1]) else 0
            if np.all(np.abs(sh[0]) <= STEP_HALF * sh[1]) or stalled >= STALLED:
                converged, message = True, (f"converged (the {'next step is' if stalled < STALLED else 'last steps are'} "
                                            f"below {100 * STEP_HALF:g} % of every parameter's 95 % interval)")
                break
    else:
        message = f"not converged in {max_iterations} iterations"

    # intervals at the optimum (no damping)
    Sred, gred, Ainv, AinvB = _reduce(Hll, Hlg, Hgg, gl, gg, 0.0)
    p = len(theta)
    Ssum = Sred.sum(0)
    scale = np.sqrt(np.maximum(np.diag(Ssum), 1e-300))
    Sn = Ssum / np.outer(scale, scale)
    lam_e, vec = np.linalg.eigh(Sn)
    flat_dirs = lam_e < FLAT * lam_e.max()
    flat = tuple(theta_names[int(np.argmax(np.abs(vec[:, k])))] for k in np.flatnonzero(flat_dirs))
    # the sandwich over G clusters has G - 1 degrees of freedom: Student's t (8 clusters: 2.36, not 1.96)
    z = float(student_t.ppf(0.975, max(n_cl - 1, 1)))
    half = np.full(p, np.nan)
    sand = np.full(p, np.nan)
    boot = np.full(p, np.nan)
    corr = np.full((p, p), np.nan)
    step = np.full(p, np.nan)
    if not flat:
        Sinv = np.linalg.inv(Ssum)
        step = -Sinv @ gred.sum(0)
        gc = np.zeros((n_cl, p))
        Sc = np.zeros((n_cl, p, p))
        np.add.at(gc, owner, gred)
        np.add.at(Sc, owner, Sred)
        meat = gc.T @ gc * n_cl / max(n_cl - 1, 1)
        cov = Sinv @ meat @ Sinv
        sand = z * np.sqrt(np.maximum(np.diag(cov), 0))
        d = np.sqrt(np.maximum(np.diag(cov), 1e-300))
        corr = cov / np.outer(d, d)
        if bootstrap and n_cl >= 5:
            rng = np.random.default_rng(seed)
            draws = []
            for _ in range(int(bootstrap)):
                pick = rng.integers(0, n_cl, n_cl)
                try:
                    draws.append(-np.linalg.solve(Sc[pick].sum(0), gc[pick].sum(0)))
                except np.linalg.LinAlgError:
                    continue
            if len(draws) >= 20:
                boot = z * np.std(np.array(draws), axis=0, ddof=1)
        # the jackknife over clusters (CR3: each cluster left out in turn, one step from the optimum):
        # the sandwich underestimates the spread with few clusters (a single recording cut into ten
        # blocks: by about a quarter, measured over 20 noise seeds); the jackknife does not
        jack = np.full(p, np.nan)
        if n_cl >= 3:
            gsum = gc.sum(0)
            leave = []
            for c in range(n_cl):
                try:
                    leave.append(-np.linalg.solve(Ssum - Sc[c], gsum - gc[c]))
                except np.linalg.LinAlgError:
                    continue
            if len(leave) == n_cl:
                L = np.array(leave)
                jack = z * np.sqrt((n_cl - 1) / n_cl * np.sum((L - L.mean(0)) ** 2, axis=0))
        half = np.fmax(np.fmax(sand, boot), jack)
    res = (e**2).sum(axis=(1, 2))
    npts = seg.mask.sum(1) * 2
    sq = np.zeros(pieces)
    cnt = np.zeros(pieces)
    np.add.at(sq, seg.piece, res)
    np.add.at(cnt, seg.piece, npts)
    rms = np.sqrt(sq / np.maximum(cnt, 1))
    sq_cl = np.zeros(n_cl)
    np.add.at(sq_cl, owner, res)
    b, al = unpack(theta)
    return ShootingFit(beta=b, alpha=al, y0=y0, theta_names=theta_names, theta=theta, half=half, flat=flat, cost=cost,
                       rms_piece=rms, ssr_piece=sq, iterations=it, converged=converged, message=message,
                       seconds=time.perf_counter() - t_start, segments=len(seg), step=seg.h, correlation=corr,
                       sandwich_half=sand, bootstrap_half=boot, newton_step=step, ssr_cluster=sq_cl)
