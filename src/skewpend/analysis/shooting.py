"""The output-error fit of :func:`skewpend.identify`: multiple shooting with exact sensitivities,
on the house integrator.

The model is written in its base parameters ``beta`` (:mod:`skewpend.symbolic.regressor`): the data
determine ``beta = T(a, alpha, g) pi``, the pivots of the standard parameters ``pi`` (each body's
mass, first moment ``h = m c`` and inertia ``J`` about its hinge; damping, friction, rotor) plus the
entries that move with them.  The dynamics are the compiled kernels' (the same derivation every
simulation runs), for a representative of ``beta``: ``pi`` with its dependent entries held at the
start model's and its pivots ``beta - T_D pi_D`` -- every such ``pi`` has the same equations.  The
kernels read the bodies as centres of mass and inertias at run time (:mod:`skewpend.numeric.conventions`),
``c = h/m``, ``I_c = J - (|h|^2 E - h h^T)/m`` (the masses are dependents: the start's, positive), so
a fit compiles one library for its hinge axes and optional terms (``kernel_module(..., shooting=True)``,
every body entry a run-time input) and never one per iteration or per rig.  Its sensitivities are the
kernel's ``d q''/d y`` and ``d q''/d p`` (generated from the derivation, one LDL^T solve a column);
the fit's parameters ``theta`` (free base parameters, then ``alpha``) enter through the chain rule
``G = dp/dtheta`` computed here: ``d p/d beta_k`` is the column of its pivot, and a freed ``alpha`` moves
both ``p``'s ``alpha`` and, at fixed ``beta``, the pivots (``-dT_D/dalpha pi_D``).

The measured pieces are cut into segments (default :data:`SEGMENT` = 0.5 s); each segment starts
from its own free state ``(q, q')`` (the *shooting nodes*; continuity between segments is not
imposed, so a segment never carries another's error) and is integrated by the classical RK4 at a
fixed step (a multiple of the sampling step near :data:`STEP`) together with its variational
equations, in C (``sp_shoot``, ``numeric/shooting.c``): applied to the state and its sensitivities
at once, RK4 gives the exact derivative of its own discrete map, so the Jacobian of the residuals is
exact for the model that is fitted.  The residuals are the simulated minus the measured angles at
every step.

Gauss-Newton with Levenberg-Marquardt damping; each segment's 2 nq start values (4 for the double pendulum) are eliminated per
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

Physical bodies: the fit above is in the base parameters, and its estimate may be no body at all (a
slender rod is on the edge of the physical ones: no moment about its own axis).  :func:`fit_physical`
runs the same Levenberg-Marquardt over physical models only: each body's 4 x 4 pseudo-inertia is
``L L^T`` (``L`` lower triangular, :func:`pseudo_inertia`), so that every iterate is a body and every
body, the semidefinite edge included, is reached (Wensing, Kim and Slotine 2017).
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass, field
from typing import Callable, Optional, Sequence, Tuple

import numpy as np

from ..errors import ParameterError
from ..schema import LENGTH_NAMES
from ..numeric.conventions import TENSOR_INDICES
from ..symbolic.model import Parameters

__all__ = ["SEGMENT", "STEP", "FLAT", "STEP_HALF", "STALLED", "ShootingFit", "Segments", "segments", "fit", "angle_frame",
           "start_cost", "fit_physical", "PhysicalFit", "pseudo_inertia"]

#: Default length of a shooting segment [s].
SEGMENT = 0.5
#: Target RK4 step [s] (rounded to a whole number of sampling steps).
STEP = 0.004
#: Smallest relative curvature (reduced, column-scaled Gauss-Newton matrix) of a determined direction.
FLAT = 1e-9

#: Segments a call of the compiled integrator takes (Ctrl-C is honoured between calls).
_CHUNK = 32


class _Model:
    """The segment dynamics of base parameters on the compiled kernels (see the module): ``terms`` the
    base parameters (a :class:`~skewpend.symbolic.regressor.BaseParameters`, identification's terms with
    friction and rotor columns beside them, or a chain's :class:`~skewpend.analysis.identify.ChainTerms`),
    ``params0`` the start model (its hinge axes, optional terms, lengths, ``g``, ``cfs``, gears and the values
    of the entries held), asked for its kernel, its run-time array ``p`` and that array's names.  The angle
    a fit may free is ``p``'s ``alpha`` (the double pendulum's skew angle) or, where ``terms`` frees a
    hinge's tilt, that hinge's axis turned about ``j``."""

    def __init__(self, terms, params0):
        from ..numeric.conventions import TENSOR_ENTRIES
        from ..numeric.kernels import model_kernel, model_vector, model_vector_names
        from ..symbolic.regressor import PI_NAMES, standard_parameters

        self.nq = params0.n
        base = getattr(terms, "B", terms)
        self.names = tuple(terms.names)
        self.extra = tuple(getattr(terms, "extra", ()))
        self.pivots = list(base.pivots)
        self.r0 = len(base.names)
        self.pi_names = tuple(getattr(base, "pi_names", PI_NAMES)) + self.extra
        self.n_pi = len(self.pi_names) - len(self.extra)
        self.dep = [j for j in range(self.n_pi) if j not in self.pivots]
        self.p0 = model_vector(params0)
        order = list(model_vector_names(params0))
        at = dict(zip(order, self.p0))
        self.a, self.g = float(at.get(LENGTH_NAMES[0], 0.0)), float(at["g"])
        self.tilt = getattr(terms, "tilt", None)
        self.kernel = model_kernel(getattr(terms, "generic", params0), shooting=True)
        self._T, self._dT = base.matrix_functions()
        if self.tilt:  # a hinge's axis turned about j
            self.i_axis = [order.index(f"e{c}{self.tilt}") for c in "xyz"]
            self.axis0, self.alpha_ref = terms.axis0, terms.angle0
            self.i_alpha = None
        else:
            self.i_alpha = order.index("alpha") if "alpha" in order else None
            self.alpha_ref = float(at["alpha"]) if self.i_alpha is not None else 0.0
        self.has_angle = bool(self.tilt) or self.i_alpha is not None
        standard = getattr(base, "standard", None)  # a chain's numbers; else the derivation's PI_NAMES
        self.pi_ref = (np.asarray(standard(params0), float) if standard is not None else
                       np.concatenate([standard_parameters(params0), [float(getattr(params0, x) or 0.0) for x in self.extra]]))
        # where each standard parameter lands in p: the scalars directly, the bodies through (c, I_c)
        self.i_scalar = {n: order.index(n) for n in self.pi_names if n in order}
        # each body: where its mass, first moment and hinge inertia are in pi, where its centre of mass
        # and inertia about it are in p (the facade's names r1x, I1xx or the chain's rx1, Ixx1)
        self.bodies = []
        for i in range(1, self.nq + 1):
            r = [_entry(order, "r", i, x) for x in "xyz"]
            J = [_entry(order, "I", i, e) for e in TENSOR_ENTRIES]
            h_pi = [self.pi_names.index(f"h{i}{x}") for x in "xyz"]
            J_pi = [self.pi_names.index(f"J{i}{e}") for e in TENSOR_ENTRIES]
            self.bodies.append((self.pi_names.index(f"m{i}"), h_pi, J_pi, r, J))
        T = self.T(self.alpha_ref)
        if not np.allclose(T[:, self.pivots], np.eye(self.r0), rtol=0, atol=1e-12):
            raise AssertionError("the base parameters are not their pivots plus dependents")

    def set_angle(self, p: np.ndarray, alpha: float) -> np.ndarray:
        """Set the angle in ``p`` (in place); its column ``d p / d alpha``."""
        col = np.zeros(len(p))
        if self.tilt:
            c, s = math.cos(alpha - self.alpha_ref), math.sin(alpha - self.alpha_ref)
            x, y, z = self.axis0
            e = (c * x + s * z, y, c * z - s * x)
            p[self.i_axis] = e
            col[self.i_axis] = (e[2], 0.0, -e[0])
        elif self.i_alpha is not None:
            p[self.i_alpha] = alpha
            col[self.i_alpha] = 1.0
        return col

    def T(self, alpha: float) -> np.ndarray:
        return np.array(self._T(self.a, alpha, self.g), dtype=float).reshape(self.r0, self.n_pi)

    def standard(self, beta: np.ndarray, alpha: float) -> np.ndarray:
        """The representative ``pi`` (with the extra terms after it) of ``beta`` at ``alpha``."""
        pi = self.pi_ref.copy()
        pi[self.pivots] = beta[:self.r0] - self.T(alpha)[:, self.dep] @ self.pi_ref[self.dep]
        pi[self.n_pi:] = beta[self.r0:]
        return pi

    def p_of(self, pi: np.ndarray, alpha: float):
        """The kernel's ``p`` of a standard vector and ``dp/dpi`` (NP x len(pi))."""
        p = self.p0.copy()
        D = np.zeros((len(p), len(pi)))
        self.set_angle(p, alpha)
        for n, i in self.i_scalar.items():
            j = self.pi_names.index(n)
            p[i] = pi[j]
            D[i, j] = 1.0
        E = np.eye(3)
        for k, hk, Jk, ri, Ii in self.bodies:
            m, h = pi[k], pi[hk]
            Jm = _full(pi[Jk])
            hh = float(h @ h)
            p[ri] = h / m
            Ic = Jm - (hh * E - np.outer(h, h)) / m
            p[Ii] = _packed(Ic)
            D[ri, k] = -h / m**2  # c = h / m
            D[np.ix_(ri, hk)] = E / m
            D[Ii, k] = _packed((hh * E - np.outer(h, h)) / m**2)  # I_c = J - (|h|^2 E - h h^T) / m
            for a in range(3):
                dh = -(2 * h[a] * E - np.outer(E[a], h) - np.outer(h, E[a])) / m
                D[Ii, hk[a]] = _packed(dh)
            D[np.ix_(Ii, Jk)] = np.eye(6)
        return p, D

    def point(self, beta, alpha: float, free_idx: Sequence[int], alpha_free: bool):
        """``p`` at (beta, alpha) and ``G = dp/dtheta`` (NP x k), theta the free base parameters then alpha."""
        pi = self.standard(np.asarray(beta, float), alpha)
        p, D = self.p_of(pi, alpha)
        cols = [D[:, self.pivots[j]] if j < self.r0 else D[:, self.n_pi + (j - self.r0)] for j in free_idx]
        if alpha_free:
            dpi = np.zeros(len(pi))
            dpi[self.pivots] = -(np.array(self._dT(self.a, alpha, self.g), dtype=float).reshape(self.r0, self.n_pi)[:, self.dep]
                                 @ self.pi_ref[self.dep])
            col = D @ dpi
            col += self.set_angle(p, alpha)
            cols.append(col)
        G = np.ascontiguousarray(np.array(cols).T if cols else np.zeros((len(p), 0)))
        return p, G

    def shoot(self, seg: "Segments", y0, p, G=None):
        """``sp_shoot`` over the segments: the angles (S, L+1, nq) and, with ``G``, their derivatives
        (S, L+1, nq, 2 nq + k) in the start values and theta."""
        import ctypes

        from ..parsing import UsageError

        S, L1 = seg.q.shape[:2]
        nq, n2 = self.nq, 2 * self.nq
        k = 0 if G is None else G.shape[1]
        y0 = np.ascontiguousarray(y0, dtype=float)
        p = np.ascontiguousarray(p, dtype=float)
        tau = None if not np.any(seg.tau) else np.ascontiguousarray(seg.tau, dtype=float)
        q = np.empty((S, L1, nq))
        J = np.empty((S, L1, nq, n2 + k)) if G is not None else None
        dp = ctypes.POINTER(ctypes.c_double)
        null = ctypes.cast(None, dp)

        def ptr(a, offset=0):
            return null if a is None else ctypes.cast(a.ctypes.data + 8 * offset, dp)

        G = None if G is None else np.ascontiguousarray(G, dtype=float)  # held here while C reads it
        Gp = ptr(G)
        for s0 in range(0, S, _CHUNK):
            n = min(_CHUNK, S - s0)
            code = self.kernel.lib.sp_shoot(
                ptr(p), Gp, k, n, L1 - 1, seg.h, ptr(y0, n2 * s0),
                ptr(tau, s0 * tau.shape[1] * nq) if tau is not None else null,
                ptr(q, s0 * L1 * nq), ptr(J, s0 * L1 * nq * (n2 + k)) if J is not None else null)
            if code != 0:
                raise UsageError(f"multiple shooting refused its arguments (code {code}): at most 64 free parameters")
        return q, J


def _entry(order: Sequence[str], stem: str, i: int, part: str) -> int:
    """The index in ``p``'s names of body ``i``'s entry: the facade's ``r1x``, ``I1xx`` or the chain's ``rx1``, ``Ixx1``."""
    return order.index(f"{stem}{i}{part}") if f"{stem}{i}{part}" in order else order.index(f"{stem}{part}{i}")


def _full(v) -> np.ndarray:
    """A symmetric tensor from its entries xx, xy, xz, yy, yz, zz."""
    out = np.empty((3, 3))
    for (i, j), x in zip(TENSOR_INDICES, v):
        out[i, j] = out[j, i] = x
    return out


def _packed(T: np.ndarray) -> np.ndarray:
    return np.array([T[i, j] for i, j in TENSOR_INDICES])


# -- the data cut into segments -----------------------------------------------------------------------------
@dataclass
class Segments:
    """Every segment of every piece, padded to one length: ``q`` (S, L+1, nq) the measured angles at
    the steps, ``mask`` (S, L+1), ``tau`` (S, 2L+1, nq) torques at the steps and half steps (zeros
    for a free swing), ``y0`` (S, 2 nq) the filtered start states, ``piece`` (S,) the piece index,
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
    nq = np.shape(filtered[0][1])[1]
    S = len(cuts)
    Q, M, T = np.zeros((S, Lmax + 1, nq)), np.zeros((S, Lmax + 1)), np.zeros((S, 2 * Lmax + 1, nq))
    y0, t0 = np.empty((S, 2 * nq)), np.empty(S)
    for c, (k, s0, s1) in enumerate(cuts):
        t, q, qf, dqf, u = filtered[k]
        idx = np.arange(s0, s1 + 1) * every
        Q[c, :len(idx)] = q[idx]
        M[c, :len(idx)] = 1.0
        if u is not None:
            half = np.arange(s0 * 2, s1 * 2 + 1) * every / 2.0  # sample index of the steps and half steps
            lo = np.floor(half).astype(int)
            hi = np.minimum(lo + 1, len(t) - 1)
            f = (half - lo)[:, None]
            T[c, :len(half)] = (1 - f) * u[lo] + f * u[hi]
        y0[c] = np.concatenate([qf[idx[0]], dqf[idx[0]]])
        t0[c] = t[idx[0]]
    return Segments(q=Q, mask=M, tau=T, y0=y0, piece=np.array([k for k, _, _ in cuts]), t0=t0, h=h, every=every,
                    names=tuple(names))


def angle_frame(nq: int, angles: str = "relative") -> Optional[np.ndarray]:
    """The matrix taking the relative joint angles (skewpend's coordinates) to the angles an output
    error is measured in: None for ``"relative"``; for ``"absolute"`` (each rod's angle from the
    vertical, the sum of the joint angles up to it) the lower triangle of ones."""
    if angles == "relative":
        return None
    if angles == "absolute":
        return np.tril(np.ones((nq, nq)))
    raise ParameterError(f"angles must be 'relative' or 'absolute', got {angles!r}", parameter="angles")


# -- integration ----------------------------------------------------------------------------------------------
def _simulate(model: _Model, seg: Segments, y0, beta, alpha):
    """Angles (S, L+1, nq) by RK4 from ``y0`` (no sensitivities)."""
    p, _ = model.point(beta, alpha, (), False)
    return model.shoot(seg, y0, p)[0]


def _cost(model: _Model, seg: Segments, q, frame=None) -> float:
    """The sum of squared residuals [rad^2] of the simulated angles ``q`` (S, L+1, nq), in the angles of
    ``frame`` (:func:`angle_frame`)."""
    e = (q - seg.q) * seg.mask[:, :, None]
    return float(np.sum((e if frame is None else e @ np.asarray(frame).T) ** 2))


def start_cost(terms, params0: Parameters, beta, alpha: float, seg: Segments, frame=None) -> float:
    """The cost (sum of squared angle residuals [rad^2]) of the segments simulated from their start states
    with the base parameters ``beta`` at ``alpha``: how well a start of the fit explains the data before any
    iteration; ``inf`` where the simulation is not finite (a start that is no body, or one that runs away)."""
    try:
        model = _Model(terms, params0)
        with np.errstate(all="ignore"):
            cost = _cost(model, seg, _simulate(model, seg, seg.y0, np.asarray(beta, float), float(alpha)), frame)
    except (ParameterError, FloatingPointError, ZeroDivisionError, ValueError, np.linalg.LinAlgError):
        return math.inf
    return cost if math.isfinite(cost) else math.inf


def _linearise(model: _Model, seg: Segments, y0, beta, alpha, free_idx, alpha_free, frame=None):
    """Residuals and the accumulated Gauss-Newton blocks per segment (``n2 = 2 nq`` start values):
    ``e`` (S, L+1, nq), ``Hll`` (S, n2, n2), ``Hlg`` (S, n2, p), ``Hgg`` (S, p, p), ``gl`` (S, n2), ``gg`` (S, p)."""
    p, G = model.point(beta, alpha, free_idx, alpha_free)
    return _linearise_at(model, seg, y0, p, G, frame)


def _linearise_at(model: _Model, seg: Segments, y0, p, G, frame=None):
    """:func:`_linearise` at the kernel's parameters ``p``, with ``G = dp/dtheta``."""
    q, J = model.shoot(seg, y0, p, G)
    w = seg.mask[:, :, None]
    e = (q - seg.q) * w
    J = J * w[..., None]
    if frame is not None:  # the residuals in the angles the rig measured (absolute: sums of the relative)
        e = np.einsum("ij,slj->sli", frame, e)
        J = np.einsum("ij,sljc->slic", frame, J)
    n2 = 2 * model.nq
    Jl, Jg = J[..., :n2], J[..., n2:]
    Hll = np.einsum("slia,slib->sab", Jl, Jl)
    Hlg = np.einsum("slia,slib->sab", Jl, Jg)
    Hgg = np.einsum("slia,slib->sab", Jg, Jg)
    gl = np.einsum("slia,sli->sa", Jl, e)
    gg = np.einsum("slia,sli->sa", Jg, e)
    return e, Hll, Hlg, Hgg, gl, gg


def _damped_step(Hll, Hlg, Hgg, gl, gg, lam: float, floor: float, extra=None):
    """One Levenberg-Marquardt step with the segments' start states eliminated (:func:`_reduce`): the
    parameters' step ``dg`` and the starts' ``dl``, damped by ``lam`` times the diagonal of the parameters'
    normal matrix (floored at ``floor`` times its largest entry); ``extra``: a penalty's normal matrix and
    gradient ``(S, g)``, added to the system and to the damping's diagonal. None when singular."""
    Sred, gred, Ainv, AinvB = _reduce(Hll, Hlg, Hgg, gl, gg, lam)
    Ssum, gsum = Sred.sum(0), gred.sum(0)
    dgg = np.diag(Hgg.sum(0))
    dgg = np.maximum(dgg, floor * max(float(dgg.max()), 1e-300))
    if extra is not None:
        Ssum, gsum, dgg = Ssum + extra[0], gsum + extra[1], dgg + np.diag(extra[0])
    try:
        dg = -np.linalg.solve(Ssum + lam * np.diag(dgg), gsum)
    except np.linalg.LinAlgError:
        return None
    return dg, -np.einsum("sab,sb->sa", Ainv, gl) - np.einsum("sab,b->sa", AinvB, dg)


def _reduce(Hll, Hlg, Hgg, gl, gg, lam):
    """Eliminate each segment's start values: the reduced matrix and gradient per segment, and the
    factors to recover the local steps."""
    D = np.einsum("sii->si", Hll)
    A = Hll + lam * D[:, :, None] * np.eye(Hll.shape[1])
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


def _sandwich(Sred, gred, owner: np.ndarray, n_cl: int):
    """The undamped Gauss-Newton step, each cluster's reduced gradient (``owner``: each segment's cluster, ``n_cl``
    of them) and the cluster-robust sandwich covariance ``S^-1 (sum_c g_c g_c^T) S^-1`` (see the module)."""
    Sinv = np.linalg.inv(Sred.sum(0))
    gc = np.zeros((n_cl, Sred.shape[1]))
    np.add.at(gc, owner, gred)
    return -Sinv @ gred.sum(0), gc, Sinv @ (gc.T @ gc * n_cl / max(n_cl - 1, 1)) @ Sinv


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
        step, _, cov = _sandwich(*_reduce(Hll, Hlg, Hgg, gl, gg, 0.0)[:2], owner, pieces)
    except np.linalg.LinAlgError:
        return None
    from ..results import t_quantile

    half = t_quantile(0.975, pieces - 1) * np.sqrt(np.maximum(np.diag(cov), 0.0))
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


def fit(terms, params0: Parameters, beta0: np.ndarray, free: Sequence[str], alpha0: float,
        alpha_free: bool, seg: Segments, *, pieces: int, max_iterations: int = 60,
        bootstrap: int = 200, seed: int = 0, tol: float = 1e-10, progress: Optional[Callable[[int, float], None]] = None,
        alpha_bounds: Tuple[float, float] = (-math.pi / 2, math.pi / 2),
        cluster: Optional[np.ndarray] = None, frame: Optional[np.ndarray] = None,
        angle_name: str = "alpha") -> ShootingFit:
    """Levenberg-Marquardt on the segments' residuals; see the module.  ``terms``: the base parameters
    (their ``names`` the order of ``beta0``), ``params0`` the start model (:class:`_Model`); ``alpha0``,
    ``alpha_free``: the angle (``angle_name`` in ``theta_names``: alpha, a hinge's tilt).  ``cluster``: each segment's
    cluster of the intervals (default its piece; :func:`skewpend.analysis.identify.clusters` cuts few
    pieces into blocks).  ``frame``: a matrix taking the model's angles to those the residuals are
    measured in (None: the model's own; :func:`angle_frame`)."""
    from ..results import t_quantile

    owner = np.asarray(seg.piece if cluster is None else cluster, dtype=int)
    if owner.shape != (len(seg),):
        raise ParameterError(f"cluster must give one cluster a segment ({len(seg)}), got shape {owner.shape}")
    n_cl = int(owner.max()) + 1 if len(owner) else 0

    t_start = time.perf_counter()
    model = _Model(terms, params0)
    names = list(model.names)
    free_idx = [names.index(n) for n in free]
    theta_names = tuple(free) + ((angle_name,) if alpha_free else ())
    beta = np.array(beta0, dtype=float)
    alpha = float(alpha0)
    y0 = np.array(seg.y0, dtype=float)

    def unpack(theta):
        b = beta.copy()
        b[free_idx] = theta[:len(free_idx)]
        return b, (float(theta[-1]) if alpha_free else alpha)

    theta = np.concatenate([beta[free_idx], [alpha] if alpha_free else []])
    lam = 1e-3
    e, Hll, Hlg, Hgg, gl, gg = _linearise(model, seg, y0, *unpack(theta), free_idx, alpha_free, frame)
    cost = float(np.sum(e**2))
    if not math.isfinite(cost):
        raise FloatingPointError("the start model's simulation is not finite")
    converged, it, message, stalled = False, 0, "", 0
    for it in range(1, max_iterations + 1):
        accepted = False
        while lam < 1e12:
            step = _damped_step(Hll, Hlg, Hgg, gl, gg, lam, 1e-12)
            if step is None:
                lam *= 10
                continue
            dg, dl = step
            new_theta = theta + dg
            if alpha_free:
                new_theta[-1] = min(max(new_theta[-1], alpha_bounds[0]), alpha_bounds[1])
            new_y0 = y0 + dl
            new_cost = _cost(model, seg, _simulate(model, seg, new_y0, *unpack(new_theta)), frame)
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
        e, Hll, Hlg, Hgg, gl, gg = _linearise(model, seg, y0, *unpack(theta), free_idx, alpha_free, frame)
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
    z = t_quantile(0.975, max(n_cl - 1, 1))
    half = np.full(p, np.nan)
    sand = np.full(p, np.nan)
    boot = np.full(p, np.nan)
    corr = np.full((p, p), np.nan)
    step = np.full(p, np.nan)
    if not flat:
        step, gc, cov = _sandwich(Sred, gred, owner, n_cl)
        Sc = np.zeros((n_cl, p, p))
        np.add.at(Sc, owner, Sred)
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
    sq = np.bincount(seg.piece, res, pieces)
    rms = np.sqrt(sq / np.maximum(np.bincount(seg.piece, seg.mask.sum(1) * 2, pieces), 1))
    sq_cl = np.bincount(owner, res, n_cl)
    b, al = unpack(theta)
    return ShootingFit(beta=b, alpha=al, y0=y0, theta_names=theta_names, theta=theta, half=half, flat=flat, cost=cost,
                       rms_piece=rms, ssr_piece=sq, iterations=it, converged=converged, message=message,
                       seconds=time.perf_counter() - t_start, segments=len(seg), step=seg.h, correlation=corr,
                       sandwich_half=sand, bootstrap_half=boot, newton_step=step, ssr_cluster=sq_cl)


# -- the fit constrained to physical bodies ---------------------------------------------------------------------
_TRIL = tuple(zip(*np.tril_indices(4)))


def pseudo_inertia(m: float, h, J) -> np.ndarray:
    """A body's 4 x 4 pseudo-inertia ``[[S, h], [h^T, m]]`` (``S = int r r^T dm = tr(J)/2 E - J``, about the
    hinge, as ``h`` and ``J``): positive semi-definite exactly when the body is physical -- mass >= 0, every
    moment about the centre of mass >= 0 and at most the sum of the other two (Wensing, Kim and Slotine 2017,
    "Linear matrix inequalities for physically consistent inertial parameter identification")."""
    J = _full(J) if np.ndim(J) == 1 else np.asarray(J, float)
    P = np.empty((4, 4))
    P[:3, :3] = 0.5 * np.trace(J) * np.eye(3) - J
    P[:3, 3] = P[3, :3] = np.asarray(h, float)
    P[3, 3] = float(m)
    return P


def _body_of(P: np.ndarray):
    """``(m, h, J packed)`` of a pseudo-inertia (the inverse of :func:`pseudo_inertia`; linear in ``P``)."""
    S = P[:3, :3]
    return P[3, 3], P[:3, 3].copy(), _packed(np.trace(S) * np.eye(3) - S)


class _Physical:
    """``theta -> pi``: each body's pseudo-inertia ``L L^T`` (``L`` lower triangular, its 10 entries in
    ``theta``: every ``L`` gives a physical body, and every physical body, the semi-definite edge included --
    a thin rod's zero moment about its axis -- is some ``L L^T``), then the joint terms (damping, Coulomb
    friction, rotor inertia: held at >= 0 by the step), then ``alpha`` when freed."""

    def __init__(self, model: _Model, alpha_free: bool):
        self.model = model
        self.bodies = [(k, list(hk), list(Jk)) for k, hk, Jk, _, _ in model.bodies]
        in_body = {j for k, hk, Jk in self.bodies for j in [k, *hk, *Jk]}
        self.scalars = [j for j in range(len(model.pi_names)) if j not in in_body]
        self.alpha_free = alpha_free and model.has_angle
        self.n = 10 * len(self.bodies) + len(self.scalars) + (1 if self.alpha_free else 0)

    def theta_of(self, pi: np.ndarray, alpha: float, edge: float = 1e-8) -> np.ndarray:
        """``theta`` of a physical ``pi``: each pseudo-inertia's eigenvalues raised to at least ``edge`` of
        its largest (a Cholesky factor needs them > 0; the body moves by that fraction) and factored."""
        out = []
        for k, hk, Jk in self.bodies:
            w, V = np.linalg.eigh(pseudo_inertia(pi[k], pi[hk], pi[Jk]))
            w = np.maximum(w, edge * max(float(w.max()), 1e-300))
            L = np.linalg.cholesky((V * w) @ V.T)
            out += [L[i, j] for i, j in _TRIL]
        out += [max(float(pi[j]), 0.0) for j in self.scalars]
        if self.alpha_free:
            out.append(float(alpha))
        return np.array(out, float)

    def pi_of(self, theta: np.ndarray, alpha: float):
        """``(pi, alpha, dpi/dtheta)`` (the last column of the derivative is zero when alpha is freed: ``pi``
        does not move with it)."""
        n_pi = len(self.model.pi_names)
        pi = np.zeros(n_pi)
        D = np.zeros((n_pi, self.n))
        for b, (k, hk, Jk) in enumerate(self.bodies):
            L = np.zeros((4, 4))
            for v, (i, j) in zip(theta[10 * b:10 * b + 10], _TRIL):
                L[i, j] = v
            m, h, J = _body_of(L @ L.T)
            pi[k], pi[hk], pi[Jk] = m, h, J
            for c, (i, j) in enumerate(_TRIL):
                E = np.zeros((4, 4))
                E[i, j] = 1.0
                dm, dh, dJ = _body_of(E @ L.T + L @ E.T)
                col = 10 * b + c
                D[k, col], D[hk, col], D[Jk, col] = dm, dh, dJ
        off = 10 * len(self.bodies)
        for c, j in enumerate(self.scalars):
            pi[j] = theta[off + c]
            D[j, off + c] = 1.0
        if self.alpha_free:
            alpha = float(theta[-1])
        return pi, alpha, D

    def point(self, theta: np.ndarray, alpha: float):
        """The kernel's ``p`` and ``G = dp/dtheta`` (``pi`` itself, not a representative: it is a body)."""
        pi, alpha, Dpi = self.pi_of(theta, alpha)
        p, D = self.model.p_of(pi, alpha)
        G = D @ Dpi
        if self.alpha_free:
            G[:, -1] += self.model.set_angle(p, alpha)
        return p, np.ascontiguousarray(G), pi, alpha

    def beta(self, pi: np.ndarray, alpha: float) -> np.ndarray:
        m = self.model
        return np.concatenate([m.T(alpha) @ pi[:m.n_pi], pi[m.n_pi:]])


@dataclass
class PhysicalFit:
    """What :func:`fit_physical` returns: the standard parameters ``pi`` of a physical model (every body's
    pseudo-inertia positive semi-definite, the joint terms >= 0), its ``alpha``, base parameters ``beta``, the
    shooting nodes ``y0`` and its own ``cost`` (sum of squared angle residuals)."""

    pi: np.ndarray
    alpha: float
    beta: np.ndarray
    y0: np.ndarray
    cost: float
    iterations: int
    converged: bool
    message: str
    seconds: float


def fit_physical(terms, params0, pi0: np.ndarray, alpha0: float, alpha_free: bool, seg: Segments, y0: np.ndarray, *,
                 held: Sequence[int] = (), reference: Optional[int] = None, max_iterations: int = 100,
                 tol: float = 1e-10, alpha_bounds: Tuple[float, float] = (-math.pi / 2, math.pi / 2),
                 frame: Optional[np.ndarray] = None, tol_cost: float = 0.0) -> PhysicalFit:
    """The output-error fit of :func:`fit` over the physical models only: Levenberg-Marquardt (the shooting
    nodes eliminated per segment as there) in the parametrisation of :class:`_Physical`, so that every iterate
    is a physical body and no estimate has to be projected onto one.  ``pi0``: a physical start (its
    standard parameters with the joint terms after them, as :class:`_Model`'s ``pi_ref``), ``y0`` the
    shooting nodes' start.  The base parameters ``held`` (indices into ``terms.names``) stay at ``pi0``'s
    (a stiff penalty, exact to about 1e-9 of their size); a free swing's ``reference`` is kept exactly by
    scaling the whole model (a free swing's cost does not depend on the scale).  The parametrisation is
    redundant (more entries than base parameters): the damping keeps the step finite along the
    directions the equations do not see, and any point of them is a physical model.  It stops when an
    iteration lowers the cost by less than ``tol`` of it or by at most ``tol_cost`` [rad^2]."""
    from scipy.linalg import block_diag

    t_start = time.perf_counter()
    model = _Model(terms, params0)
    phys = _Physical(model, alpha_free)
    theta = phys.theta_of(np.asarray(pi0, float), alpha0)
    alpha = float(alpha0)
    y0 = np.array(y0, dtype=float)
    pi_start, a_start, _ = phys.pi_of(theta, alpha)
    target = phys.beta(pi_start, a_start)
    nb = 10 * len(phys.bodies)
    lower = np.full(phys.n, -np.inf)
    lower[nb:nb + len(phys.scalars)] = 0.0
    upper = np.full(phys.n, np.inf)
    # a held joint term (a base parameter that is one scalar: c1 ...) is held by its bounds; the others by a penalty
    scalar_names = [model.pi_names[j] for j in phys.scalars]
    held = [int(k) for k in held if k != reference]
    for k in list(held):
        if model.names[k] in scalar_names:
            c = nb + scalar_names.index(model.names[k])
            lower[c] = upper[c] = theta[c]
            held.remove(k)
    if phys.alpha_free:
        lower[-1], upper[-1] = alpha_bounds

    def rescale(th):
        """A free swing: the whole model scaled so that the reference is the start's (pi is linear in L L^T)."""
        if reference is None:
            return th
        pi, al, _ = phys.pi_of(th, alpha)
        k = target[reference] / phys.beta(pi, al)[reference]
        if not (math.isfinite(k) and k > 0):
            return th
        out = th.copy()
        out[:nb] *= math.sqrt(k)
        out[nb:nb + len(phys.scalars)] *= k
        return out

    def penalty(th):
        """Residuals (and their derivative in theta) holding the base parameters ``held``."""
        if not held:
            return np.zeros(0), np.zeros((0, phys.n))
        pi, al, Dpi = phys.pi_of(th, alpha)
        extra = len(pi) - model.n_pi  # the joint terms: beta's own entries
        Tx = block_diag(model.T(al), np.eye(extra))
        r = (Tx @ pi - target)[held]
        dr = (Tx @ Dpi)[held]
        if phys.alpha_free and model._dT is not None:
            dT = np.array(model._dT(model.a, al, model.g), float).reshape(model.r0, model.n_pi)
            dr[:, -1] = (block_diag(dT, np.zeros((extra, extra))) @ pi)[held]
        return w_pen * r, w_pen[:, None] * dr

    theta = rescale(theta)
    p, G, _, _ = phys.point(theta, alpha)
    e, Hll, Hlg, Hgg, gl, gg = _linearise_at(model, seg, y0, p, G, frame)
    cost = float(np.sum(e**2))
    if not math.isfinite(cost):
        raise FloatingPointError("the physical start's simulation is not finite")
    # a deviation of 1e-6 of a held base parameter's size (at least 1e-6 of the largest) costs as much as the
    # whole output error
    scale_h = np.maximum(np.abs(target[held]), 1e-6 * max(float(np.abs(target).max()), 1e-300)) if held else np.zeros(0)
    w_pen = math.sqrt(max(cost, 1e-300)) / (1e-6 * scale_h) if held else np.zeros(0)
    rp, dp_ = penalty(theta)
    total = cost + float(rp @ rp)
    lam, converged, message, it = 1e-3, False, "", 0
    for it in range(1, max_iterations + 1):
        accepted = False
        while lam < 1e12:
            # (the floor on the data's scale: a penalty's stiffness would freeze the rest)
            step = _damped_step(Hll, Hlg, Hgg, gl, gg, lam, 1e-9, extra=(dp_.T @ dp_, dp_.T @ rp))
            if step is None:
                lam *= 10
                continue
            dg, dl = step
            new_theta = rescale(np.clip(theta + dg, lower, upper))
            new_y0 = y0 + dl
            with np.errstate(all="ignore"):
                new_cost = _cost(model, seg, model.shoot(seg, new_y0, phys.point(new_theta, alpha)[0])[0], frame)
            rp_new, _ = penalty(new_theta)
            new_total = new_cost + float(rp_new @ rp_new)
            if math.isfinite(new_total) and new_total < total:
                accepted = True
                break
            lam *= 10
        if not accepted:
            converged, message = True, "no step lowers the cost (a local minimum or the limit of rounding)"
            break
        rel = (total - new_total) / max(total, 1e-300)
        gain = total - new_total
        theta, y0 = new_theta, new_y0
        lam = max(lam / 10, 1e-12)
        p, G, _, _ = phys.point(theta, alpha)
        e, Hll, Hlg, Hgg, gl, gg = _linearise_at(model, seg, y0, p, G, frame)
        cost = float(np.sum(e**2))
        rp, dp_ = penalty(theta)
        total = cost + float(rp @ rp)
        if rel < tol or gain <= tol_cost:
            converged, message = True, "converged"
            break
    else:
        message = f"not converged in {max_iterations} iterations"
    pi, alpha_hat, _ = phys.pi_of(theta, alpha)
    return PhysicalFit(pi=pi, alpha=float(alpha_hat), beta=phys.beta(pi, alpha_hat), y0=y0, cost=cost, iterations=it,
                       converged=converged, message=message, seconds=time.perf_counter() - t_start)
