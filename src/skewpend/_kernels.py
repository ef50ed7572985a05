"""Compiled ODE integrators -- a *template* appended to every generated kernel module.

Contract with the code generator (:mod:`skewpend.codegen`)
------------------------------------------------------------
The generated module defines, **before** the text of this file is appended to it::

    import math
    import numpy as np
    import numba as nb

    @nb.njit(cache=True, error_model="numpy")
    def rhs(y, p, out):       # dy/dt of the autonomous ODE y' = F(y; p) into out
        ...

    @nb.njit(cache=True, error_model="numpy")
    def ham_rhs(z, p, out):   # the same, in canonical Hamiltonian variables
        ...

(``y``, ``z``, ``p`` and ``out`` are 1-D float64 arrays; ``out`` has the length of ``y``.)
The integrators below call the module-level globals ``rhs`` / ``ham_rhs`` directly, so numba
compiles them together and caches everything (``cache=True``) next to the single generated
file.  Passing jitted functions as arguments would defeat numba's disk cache, hence the
template.  This file is also importable on its own: it then defines placeholder ``rhs`` /
``ham_rhs`` (which raise), guarded by ``if "rhs" not in globals()`` so that the generated
definitions win when the text is appended after them.  The file must therefore not contain a
``from __future__`` import, and must not rebind ``rhs`` / ``ham_rhs`` unconditionally.

Numba freezes module-level globals at compile time (the coefficient tables below become
constants of the machine code; a global function is compiled into its caller).  Numba's cache
is invalidated by a change of the file holding the function, which is why everything has to
live in the one generated file.

Integrators (autonomous systems; ``t`` is only the independent variable; ``t_end >= t0``):

* ``dop853(y0, t0, t_end, p, rtol, atol, h0, max_steps, t_out)``
  -> ``(ts, ys, status, nfev, naccept, nreject)``;
* ``rk4(y0, t0, dt, nsteps, p, stride)`` -> ``(ts, ys, status, nfev)``;
* ``gauss_legendre(z0, t0, dt, nsteps, p, stride, tol, max_iter)`` -> ``(ts, zs, status, nfev)``.

``ts`` has shape (m,), ``ys`` shape (m, n); rows are never non-finite.  ``status``:

* 0 -- reached the end;
* 1 -- the state or its derivative became non-finite (output stops at the last finite state);
* 2 -- step size underflow (dop853);
* 3 -- more than ``max_steps`` attempted steps (dop853);
* 4 -- the implicit stage equations did not converge (gauss_legendre).
"""

import math

import numba as nb
import numpy as np
from scipy.integrate._ivp import dop853_coefficients as _dop853_tables

# -- placeholders (overridden by the generated module, which defines them first) ---------------
if "rhs" not in globals():

    @nb.njit
    def rhs(y, p, out):
        """Placeholder: the generated module defines the real right-hand side."""
        raise NotImplementedError("rhs: append _kernels.py to a module that defines rhs(y, p, out)")


if "ham_rhs" not in globals():

    @nb.njit
    def ham_rhs(z, p, out):
        """Placeholder: the generated module defines the real Hamiltonian vector field."""
        raise NotImplementedError("ham_rhs: append _kernels.py to a module that defines ham_rhs(z, p, out)")


# -- DOP853 coefficient tables (Hairer's DOP853, as tabulated in scipy) ------------------------
_DOP_NS = 12  # stages of the main method; K has one more row for f(t + h, y_new) (FSAL)
_DOP_C = np.ascontiguousarray(_dop853_tables.C, dtype=np.float64)  # (16,)
_DOP_A = np.ascontiguousarray(_dop853_tables.A, dtype=np.float64)  # (16, 16); row 12 = weights b
_DOP_B = np.ascontiguousarray(_dop853_tables.A[_DOP_NS, :_DOP_NS], dtype=np.float64)  # (12,)
_DOP_E3 = np.ascontiguousarray(_dop853_tables.E3, dtype=np.float64)  # (13,)
_DOP_E5 = np.ascontiguousarray(_dop853_tables.E5, dtype=np.float64)  # (13,)
_DOP_D = np.ascontiguousarray(_dop853_tables.D, dtype=np.float64)  # (4, 16) dense output
del _dop853_tables

_SAFETY = 0.9
_MIN_FACTOR = 0.2
_MAX_FACTOR = 10.0
_ERR_EXPONENT = -1.0 / 8.0  # the error estimate is O(h^8)


@nb.njit(cache=True, error_model="numpy")
def _all_finite(x):
    for i in range(x.shape[0]):
        if not math.isfinite(x[i]):
            return False
    return True


@nb.njit(cache=True, error_model="numpy")
def _put_row(a, r, x):
    # an explicit loop: numba's a[r] = x compiles a shape check that costs seconds
    for i in range(x.shape[0]):
        a[r, i] = x[i]


@nb.njit(cache=True, error_model="numpy")
def _rms(x, scale):
    s = 0.0
    for i in range(x.shape[0]):
        v = x[i] / scale[i]
        s += v * v
    return math.sqrt(s / x.shape[0])


@nb.njit(cache=True, error_model="numpy")
def _dop853_step(y, h, p, K, ynew, ytmp):
    """One DOP853 step from y (K[0] = f(y) given): stages K[1:13], ynew; returns nfev."""
    n = y.shape[0]
    for s in range(1, _DOP_NS):
        for i in range(n):
            acc = 0.0
            for j in range(s):
                acc += _DOP_A[s, j] * K[j, i]
            ytmp[i] = y[i] + h * acc
        rhs(ytmp, p, K[s])
    for i in range(n):
        acc = 0.0
        for j in range(_DOP_NS):
            acc += _DOP_B[j] * K[j, i]
        ynew[i] = y[i] + h * acc
    rhs(ynew, p, K[_DOP_NS])
    return _DOP_NS


@nb.njit(cache=True, error_model="numpy")
def _dop853_error(K, h, y, ynew, rtol, atol):
    """Hairer's combined 5th/3rd-order error norm (inf if anything is non-finite)."""
    n = y.shape[0]
    e5 = 0.0
    e3 = 0.0
    for i in range(n):
        sc = atol + rtol * max(abs(y[i]), abs(ynew[i]))
        a5 = 0.0
        a3 = 0.0
        for j in range(_DOP_NS + 1):
            a5 += _DOP_E5[j] * K[j, i]
            a3 += _DOP_E3[j] * K[j, i]
        a5 /= sc
        a3 /= sc
        e5 += a5 * a5
        e3 += a3 * a3
    if not (math.isfinite(e5) and math.isfinite(e3)):
        return np.inf
    if e5 == 0.0 and e3 == 0.0:
        return 0.0
    return abs(h) * e5 / math.sqrt((e5 + 0.01 * e3) * n)


@nb.njit(cache=True, error_model="numpy")
def _dop853_dense_coeffs(y, ynew, h, p, K, F, ytmp):
    """The 3 extra stages and the 7 coefficient rows F of the 7th-order interpolant; returns nfev."""
    n = y.shape[0]
    for s in range(_DOP_NS + 1, _DOP_A.shape[0]):
        for i in range(n):
            acc = 0.0
            for j in range(s):
                acc += _DOP_A[s, j] * K[j, i]
            ytmp[i] = y[i] + h * acc
        rhs(ytmp, p, K[s])
    for i in range(n):
        dy = ynew[i] - y[i]
        F[0, i] = dy
        F[1, i] = h * K[0, i] - dy
        F[2, i] = 2.0 * dy - h * (K[_DOP_NS, i] + K[0, i])
        for r in range(_DOP_D.shape[0]):
            acc = 0.0
            for j in range(_DOP_A.shape[0]):
                acc += _DOP_D[r, j] * K[j, i]
            F[3 + r, i] = h * acc
    return _DOP_A.shape[0] - _DOP_NS - 1


@nb.njit(cache=True, error_model="numpy")
def _dop853_dense_eval(y, F, x, out):
    """The interpolant at x = (t - t_old) / h in [0, 1] into out; False if non-finite."""
    n = y.shape[0]
    m = F.shape[0]
    ok = True
    for i in range(n):
        v = 0.0
        for k in range(m - 1, -1, -1):
            v += F[k, i]
            v *= x if (m - 1 - k) % 2 == 0 else 1.0 - x
        out[i] = y[i] + v
        if not math.isfinite(out[i]):
            ok = False
    return ok


@nb.njit(cache=True, error_model="numpy")
def dop853(y0, t0, t_end, p, rtol, atol, h0, max_steps, t_out):
    """Adaptive Dormand-Prince 8(5,3) (Hairer's DOP853) for y' = rhs(y, p), t0 -> t_end.

    Error control per step with the combined 5th/3rd-order estimate, scaled by
    ``atol + rtol * max(|y|, |y_new|)`` (RMS norm); step-size factor
    ``0.9 * err^(-1/8)`` bounded by [0.2, 10] (no increase right after a rejection).
    ``h0 <= 0`` selects the initial step automatically (Hairer's ``hinit``).  A trial step
    that produces a non-finite value is rejected like a failed one (factor 0.2).

    ``t_out``: increasing output times in [t0, t_end] (a point up to 1e-10 of the interval
    beyond t_end gets the final state), evaluated with the 7th-order dense output; if empty,
    the accepted steps are returned (t0 first; the last lands exactly on t_end).

    Returns ``(ts, ys, status, nfev, naccept, nreject)``: status 0 reached t_end, 1 non-finite
    state/derivative (no step size avoids it, or y0 / f(y0) non-finite), 2 step size underflow
    (h < 10 ulp(t)), 3 more than ``max_steps`` attempted (accepted + rejected) steps.  Output
    stops at the last accepted state (own steps) or the last output time reached (``t_out``).
    """
    n = y0.shape[0]
    nout = t_out.shape[0]
    dense = nout > 0
    if t_end < t0:
        raise ValueError("dop853: t_end must be >= t0")
    if not (rtol >= 0.0 and atol >= 0.0 and rtol + atol > 0.0):
        raise ValueError("dop853: rtol and atol must be >= 0, not both 0")
    span = t_end - t0
    slack = 1e-10 * max(span, abs(t_end))
    for k in range(nout):
        if k > 0 and t_out[k] < t_out[k - 1]:
            raise ValueError("dop853: t_out must be non-decreasing")
        if t_out[k] < t0 - slack or t_out[k] > t_end + slack:
            raise ValueError("dop853: t_out must lie in [t0, t_end]")

    K = np.empty((_DOP_A.shape[0], n))
    F = np.empty((_DOP_D.shape[0] + 3, n))
    y = y0.copy()
    ynew = np.empty(n)
    ytmp = np.empty(n)

    if dense:
        cap = nout
    else:
        cap = min(max_steps + 1, 1024)
        if cap < 2:
            cap = 2
    ts = np.empty(cap)
    ys = np.empty((cap, n))
    m = 0  # rows stored
    nfev = 0
    nacc = 0
    nrej = 0

    if not _all_finite(y):
        return ts[:0].copy(), ys[:0].copy(), 1, nfev, nacc, nrej
    # output at t0
    if dense:
        while m < nout and t_out[m] <= t0:
            ts[m] = t_out[m]
            _put_row(ys, m, y)
            m += 1
    else:
        ts[0] = t0
        _put_row(ys, 0, y)
        m = 1

    rhs(y, p, K[0])
    nfev += 1
    if not _all_finite(K[0]):
        return ts[:m].copy(), ys[:m].copy(), 1, nfev, nacc, nrej
    if span == 0.0:
        while m < nout:
            ts[m] = t_out[m]
            _put_row(ys, m, y)
            m += 1
        return ts[:m].copy(), ys[:m].copy(), 0, nfev, nacc, nrej

    # initial step (Hairer, Norsett & Wanner I, II.4; as scipy's select_initial_step)
    if h0 > 0.0:
        h_abs = min(h0, span)
    else:
        sc = np.empty(n)
        for i in range(n):
            sc[i] = atol + abs(y[i]) * rtol
        d0 = _rms(y, sc)
        d1 = _rms(K[0], sc)
        if d0 < 1e-5 or d1 < 1e-5:
            ha = 1e-6
        else:
            ha = 0.01 * d0 / d1
        ha = min(ha, span)
        for i in range(n):
            ytmp[i] = y[i] + ha * K[0, i]
        rhs(ytmp, p, ynew)
        nfev += 1
        for i in range(n):
            ynew[i] -= K[0, i]
        d2 = _rms(ynew, sc) / ha
        if not math.isfinite(d2):
            h1 = ha * 1e-3
        elif d1 <= 1e-15 and d2 <= 1e-15:
            h1 = max(1e-6, ha * 1e-3)
        else:
            h1 = (0.01 / max(d1, d2)) ** (1.0 / 8.0)
        h_abs = min(100.0 * ha, h1, span)

    t = t0
    status = 0
    while t < t_end:
        # one accepted step (or failure)
        rejected = False
        nonfinite = False
        while True:
            if nacc + nrej >= max_steps:
                status = 3
                break
            min_step = 10.0 * (np.nextafter(t, np.inf) - t)
            if h_abs < min_step:
                status = 1 if nonfinite else 2
                break
            t_new = t + h_abs
            if t_new >= t_end:
                t_new = t_end
            h = t_new - t
            nfev += _dop853_step(y, h, p, K, ynew, ytmp)
            if _all_finite(ynew) and _all_finite(K[_DOP_NS]):
                err = _dop853_error(K, h, y, ynew, rtol, atol)
            else:
                err = np.inf
            nonfinite = not math.isfinite(err)
            if err < 1.0:
                if err == 0.0:
                    fac = _MAX_FACTOR
                else:
                    fac = min(_MAX_FACTOR, _SAFETY * err**_ERR_EXPONENT)
                if rejected:
                    fac = min(1.0, fac)
                h_abs = h * fac
                break
            if nonfinite:
                fac = _MIN_FACTOR
            else:
                fac = max(_MIN_FACTOR, _SAFETY * err**_ERR_EXPONENT)
            h_abs = h * fac
            rejected = True
            nrej += 1
        if status != 0:
            break
        nacc += 1

        # output
        if dense:
            have_coeffs = False
            while m < nout and t_out[m] <= t_new:
                if t_out[m] == t_new:
                    _put_row(ys, m, ynew)
                else:
                    if not have_coeffs:
                        nfev += _dop853_dense_coeffs(y, ynew, h, p, K, F, ytmp)
                        have_coeffs = True
                    if not _dop853_dense_eval(y, F, (t_out[m] - t) / h, ys[m]):
                        status = 1
                        break
                ts[m] = t_out[m]
                m += 1
            if status != 0:
                break
        else:
            if m == cap:
                cap2 = min(2 * cap, max_steps + 1)
                ts2 = np.empty(cap2)
                ys2 = np.empty((cap2, n))
                for r in range(m):
                    ts2[r] = ts[r]
                    _put_row(ys2, r, ys[r])
                ts = ts2
                ys = ys2
                cap = cap2
            ts[m] = t_new
            _put_row(ys, m, ynew)
            m += 1

        # advance (FSAL: K[12] = f(t_new, y_new) becomes K[0])
        t = t_new
        for i in range(n):
            y[i] = ynew[i]
            K[0, i] = K[_DOP_NS, i]

    if status == 0 and dense:
        # output times within rounding beyond t_end
        while m < nout:
            ts[m] = t_out[m]
            _put_row(ys, m, y)
            m += 1
    return ts[:m].copy(), ys[:m].copy(), status, nfev, nacc, nrej


@nb.njit(cache=True, error_model="numpy")
def _n_rows(nsteps, stride):
    rows = nsteps // stride + 1
    if nsteps % stride != 0:
        rows += 1
    return rows


@nb.njit(cache=True, error_model="numpy")
def rk4(y0, t0, dt, nsteps, p, stride):
    """Classical fixed-step Runge-Kutta of order 4 for y' = rhs(y, p): nsteps steps of dt.

    Stores y0 and every ``stride``-th state (and the final one if nsteps is not a multiple
    of stride); ``ts[k] = t0 + step * dt``.  Returns ``(ts, ys, status, nfev)``; status 1 when
    a stage or the state becomes non-finite -- the output then ends with the last finite
    state (stored even if it is not on the stride).
    """
    n = y0.shape[0]
    if stride < 1:
        raise ValueError("rk4: stride must be >= 1")
    if nsteps < 0:
        raise ValueError("rk4: nsteps must be >= 0")
    rows = _n_rows(nsteps, stride)
    ts = np.empty(rows)
    ys = np.empty((rows, n))
    y = y0.copy()
    k1 = np.empty(n)
    k2 = np.empty(n)
    k3 = np.empty(n)
    k4 = np.empty(n)
    tmp = np.empty(n)
    nfev = 0
    if not _all_finite(y):
        return ts[:0].copy(), ys[:0].copy(), 1, nfev
    ts[0] = t0
    _put_row(ys, 0, y)
    m = 1
    h = dt
    half = 0.5 * dt
    sixth = dt / 6.0
    status = 0
    last = 0  # step index of the last stored row
    step = 0
    for step in range(1, nsteps + 1):
        rhs(y, p, k1)
        for i in range(n):
            tmp[i] = y[i] + half * k1[i]
        rhs(tmp, p, k2)
        for i in range(n):
            tmp[i] = y[i] + half * k2[i]
        rhs(tmp, p, k3)
        for i in range(n):
            tmp[i] = y[i] + h * k3[i]
        rhs(tmp, p, k4)
        nfev += 4
        for i in range(n):
            tmp[i] = y[i] + sixth * (k1[i] + 2.0 * (k2[i] + k3[i]) + k4[i])
        if not _all_finite(tmp):
            status = 1
            step -= 1
            break
        for i in range(n):
            y[i] = tmp[i]
        if step % stride == 0 or step == nsteps:
            ts[m] = t0 + step * dt
            _put_row(ys, m, y)
            m += 1
            last = step
    if status != 0 and last != step:
        ts[m] = t0 + step * dt
        _put_row(ys, m, y)
        m += 1
    return ts[:m].copy(), ys[:m].copy(), status, nfev


# 2-stage Gauss-Legendre: c = 1/2 -+ sqrt(3)/6, A = [[1/4, 1/4 - sqrt(3)/6], [1/4 + sqrt(3)/6, 1/4]], b = 1/2, 1/2
_GL_R3 = math.sqrt(3.0)
_GL_A11 = 0.25
_GL_A12 = 0.25 - _GL_R3 / 6.0
_GL_A21 = 0.25 + _GL_R3 / 6.0
_GL_A22 = 0.25
_EPS = 2.220446049250313e-16


@nb.njit(cache=True, error_model="numpy")
def gauss_legendre(z0, t0, dt, nsteps, p, stride, tol, max_iter):
    """2-stage Gauss-Legendre collocation (order 4, symplectic) for z' = ham_rhs(z, p).

    The stage equations ``K_i = f(z + dt * sum_j a_ij K_j)`` are solved by fixed-point
    iteration, started from the previous step's collocation polynomial extrapolated to the
    new stages (explicit Euler guess on the first step), until the max-norm change of the
    stage values is ``<= tol * max|z|`` -- or stops decreasing at the rounding level
    (``<= 64 eps`` of the state) -- within ``max_iter`` iterations.  The update uses
    compensated summation, so long runs do not accumulate rounding error.

    Storage as :func:`rk4`.  Returns ``(ts, zs, status, nfev)``; status 1 non-finite stage or
    state, 4 the stage equations did not converge; the output then ends with the last
    accepted state.
    """
    n = z0.shape[0]
    if stride < 1:
        raise ValueError("gauss_legendre: stride must be >= 1")
    if nsteps < 0:
        raise ValueError("gauss_legendre: nsteps must be >= 0")
    rows = _n_rows(nsteps, stride)
    ts = np.empty(rows)
    zs = np.empty((rows, n))
    z = z0.copy()
    comp = np.zeros(n)  # compensated-summation remainder
    k1 = np.empty(n)
    k2 = np.empty(n)
    f1 = np.empty(n)
    f2 = np.empty(n)
    y1 = np.empty(n)
    y2 = np.empty(n)
    nfev = 0
    if not _all_finite(z):
        return ts[:0].copy(), zs[:0].copy(), 1, nfev
    ts[0] = t0
    _put_row(zs, 0, z)
    m = 1
    h = dt
    status = 0
    last = 0
    step = 0
    # extrapolation weights of the previous collocation polynomial to the new stages
    w1 = _GL_R3
    w2 = 1.0 + _GL_R3
    if nsteps > 0:
        ham_rhs(z, p, k1)
        nfev += 1
        if not _all_finite(k1):
            return ts[:m].copy(), zs[:m].copy(), 1, nfev
        for i in range(n):
            k2[i] = k1[i]
    for step in range(1, nsteps + 1):
        scale = 0.0
        for i in range(n):
            scale = max(scale, abs(z[i]))
        converged = False
        prev = np.inf
        for it in range(max_iter):
            for i in range(n):
                y1[i] = z[i] + h * (_GL_A11 * k1[i] + _GL_A12 * k2[i])
                y2[i] = z[i] + h * (_GL_A21 * k1[i] + _GL_A22 * k2[i])
            ham_rhs(y1, p, f1)
            ham_rhs(y2, p, f2)
            nfev += 2
            if not (_all_finite(f1) and _all_finite(f2)):
                status = 1
                break
            delta = 0.0
            size = scale
            for i in range(n):
                d1 = f1[i] - k1[i]
                d2 = f2[i] - k2[i]
                delta = max(delta, abs(h * (_GL_A11 * d1 + _GL_A12 * d2)), abs(h * (_GL_A21 * d1 + _GL_A22 * d2)))
                size = max(size, abs(y1[i]), abs(y2[i]))
                k1[i] = f1[i]
                k2[i] = f2[i]
            if delta <= tol * scale or delta == 0.0:
                converged = True
                break
            if delta >= prev and delta <= 64.0 * _EPS * size:
                converged = True  # rounding level reached
                break
            prev = delta
        if status != 0:
            step -= 1
            break
        if not converged:
            status = 4
            step -= 1
            break
        # z += h/2 (k1 + k2), compensated
        ok = True
        for i in range(n):
            inc = 0.5 * h * (k1[i] + k2[i]) + comp[i]
            new = z[i] + inc
            comp[i] = inc - (new - z[i])
            y1[i] = new
            if not math.isfinite(new):
                ok = False
        if not ok:
            status = 1
            step -= 1
            break
        for i in range(n):
            z[i] = y1[i]
            # starting guess for the next step
            d = k2[i] - k1[i]
            a = k1[i]
            k1[i] = a + w1 * d
            k2[i] = a + w2 * d
        if step % stride == 0 or step == nsteps:
            ts[m] = t0 + step * dt
            _put_row(zs, m, z)
            m += 1
            last = step
    if status != 0 and last != step:
        ts[m] = t0 + step * dt
        _put_row(zs, m, z)
        m += 1
    return ts[:m].copy(), zs[:m].copy(), status, nfev
