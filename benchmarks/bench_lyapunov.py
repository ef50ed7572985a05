"""Lyapunov spectrum: skewpend against heyoka.py's variational equations, side by side in one run.

Case: a=1, b=0.8, m1=1, m2=0.7, alpha=0.6, g=9.81, y0 = (phi, psi, dphi, dpsi) = (1.2, -0.8, 0, 0)
(chaotic), t_end = 1000 s, Benettin's method: the state plus k tangent vectors (identity columns at
the start), re-orthonormalised every 1 s by ``numpy.linalg.qr`` (sum of log|diag R|), exponents =
sums / t_end.  Warm: one untimed call first; best and median of ``--repeat`` runs, interleaved
(skewpend and heyoka rep by rep, so both see the same machine load).

* full spectrum (k = 4), tolerance 1e-10:
  - heyoka.py: ``hy.var_ode_sys(sys, hy.var_args.vars, order=1)`` (the 4x4 matrix of first
    derivatives, at ``state[4 + 4 i + j]`` = d x_i / d x0_j, checked with ``get_mindex``) in a
    ``taylor_adaptive(..., tol=1e-10, compact_mode=False)``; each second ``propagate_until``,
    QR of the 4x4 matrix, Q written back into the variational part of ``ta.state``;
  - ``skewpend.lyapunov(params, y0, t_end=1000, renorm_every=1, rtol=1e-10, atol=1e-10, n_exponents=4)``.
* largest exponent only (k = 1), tolerance 1e-6:
  - heyoka.py: the state plus one tangent vector u with du/dt = J(x) u, J the Jacobian of the
    right-hand side obtained by SymPy differentiation of skewpend's derived right-hand side and
    converted with ``hy.from_sympy`` (a var_ode_sys would carry all 16 derivatives);
  - ``skewpend.lyapunov(..., rtol=1e-6, atol=1e-6, n_exponents=1)``.

The equations are not typed: they are skewpend's derivation (SymPy M(q), f(q, q')), q'' = M^-1 f,
converted with ``hy.from_sympy`` as in bench_simulate.py.  heyoka's JIT compilation is timed on its
own, cold (in-memory cache cleared, on-disk cache disabled for the measurement), with the time of a
build from heyoka's on-disk cache alongside.

Checks.  The state (phi, psi, dphi, dpsi) is not canonical: the flow preserves volume in (q, p),
p = M(q) q', so sum(exponents) * t_end = log(det M(q0) / det M(q(t_end))), not 0 (it is O(1/t_end)
per second); the script prints both sides.  The exponents come in +- pairs (up to O(1/t_end)),
the middle pair -> 0.  Finite-time exponents of a chaotic orbit depend on the trajectory, and at
1e-10 the trajectories of two integrators part after ~30 s: heyoka is also run at tol 1e-12
(untimed) to show that spread, against which the skewpend-heyoka difference is to be judged.

Run:  python benchmarks/bench_lyapunov.py [--repeat 5]
"""

from __future__ import annotations

import argparse
import os
import platform
import time

import numpy as np

from _common import compile_times, cpu_model, version  # benchmarks/ is on sys.path when run

T_END, RENORM = 1000.0, 1.0
TOL_FULL, TOL_LLE, TOL_SPREAD = 1e-10, 1e-6, 1e-12
NAMES = ("phi", "psi", "dphi", "dpsi")
GOAL = 0.5  # skewpend time <= GOAL x heyoka time (full spectrum; issue 28, was 1.5x in issue 12)


def case():
    from skewpend import Parameters

    return Parameters(a=1.0, b=0.8, m1=1.0, m2=0.7, alpha=0.6, g=9.81), np.array([1.2, -0.8, 0.0, 0.0])


def equations(params):
    """skewpend's derived equations: SymPy right-hand side, its heyoka form, and det M(q)."""
    import heyoka as hy
    import sympy as sp

    from skewpend import SYMBOLS, derive

    eom = derive(params.replace(c1=0.0, c2=0.0, tau1=0.0, tau2=0.0))
    M, f = eom.mass_matrix, eom.forcing
    det = M[0, 0] * M[1, 1] - M[0, 1] ** 2
    qdd = [sp.N((M[1, 1] * f[0] - M[0, 1] * f[1]) / det, 17), sp.N((M[0, 0] * f[1] - M[0, 1] * f[0]) / det, 17)]
    X = [SYMBOLS[n] for n in NAMES]
    rhs = [X[2], X[3], qdd[0], qdd[1]]
    v = hy.make_vars(*NAMES)
    names = dict(zip(X, v))
    sys_ = [(v[0], v[2]), (v[1], v[3]), (v[2], hy.from_sympy(qdd[0], names)), (v[3], hy.from_sympy(qdd[1], names))]
    det_m = sp.lambdify([X[0], X[1]], sp.N(det, 17))
    return sys_, rhs, X, names, det_m


def heyoka_full(sys_, y0, tol):
    """The variational integrator (state + 4x4 matrix of first derivatives)."""
    import heyoka as hy

    vsys = hy.var_ode_sys(sys_, hy.var_args.vars, order=1)
    return lambda: hy.taylor_adaptive(vsys, list(y0), tol=tol, compact_mode=False)


def check_layout(ta):
    """state[4 + 4 i + j] must be d x_i / d x0_j (multiindex [i, e_j]): W's columns are the vectors."""
    sl = ta.get_vslice(order=1)
    want = [[i] + [int(k == j) for k in range(4)] for i in range(4) for j in range(4)]
    assert (sl.start, sl.stop) == (4, 20) and [list(ta.get_mindex(n)) for n in range(4, 20)] == want, "layout"


def heyoka_lle(sys_, rhs, X, names, y0, tol):
    """State + one tangent vector u, du/dt = J u with J = d rhs / d x by SymPy (see docstring)."""
    import heyoka as hy
    import sympy as sp

    u = hy.make_vars("u_phi", "u_psi", "u_dphi", "u_dpsi")
    tangent = []
    for r in rhs:
        terms = [hy.from_sympy(d, names) * u[j] for j, d in enumerate(sp.diff(r, x) for x in X) if d != 0]
        tangent.append(hy.sum(terms))
    eqs = sys_ + list(zip(u, tangent))
    return lambda: hy.taylor_adaptive(eqs, list(y0) + [1.0, 0.0, 0.0, 0.0], tol=tol, compact_mode=False)


def benettin(ta, y0, k, t_end=T_END, every=RENORM):
    """Benettin/QR with heyoka integrator ``ta`` whose state is [x (4), W (4 x k, row-major)]."""
    ta.time = 0.0
    st = ta.state  # writable view
    st[:4] = y0
    st[4:] = np.eye(4)[:, :k].ravel()
    sums, steps = np.zeros(k), 0
    for n in range(1, int(round(t_end / every)) + 1):
        res = ta.propagate_until(n * every)
        steps += res[3]
        Q, R = np.linalg.qr(st[4:].reshape(4, k))
        sums += np.log(np.abs(np.diag(R)))
        st[4:] = Q.ravel()
    return sums / t_end, st[:4].copy(), steps


def measure(fns, repeat):
    """Warm-up call each, then ``repeat`` interleaved timed calls: {label: (best, median, result)}."""
    times = {lab: [] for lab in fns}
    out = {lab: fn() for lab, fn in fns.items()}
    for _ in range(repeat):
        for lab, fn in fns.items():
            t0 = time.perf_counter()
            out[lab] = fn()
            times[lab].append(time.perf_counter() - t0)
    return {lab: (min(t), float(np.median(t)), out[lab]) for lab, t in times.items()}


def fmt(ex):
    return "[" + " ".join(f"{e:+.5f}" for e in np.atleast_1d(ex)) + "]"


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--repeat", type=int, default=5)
    args = ap.parse_args()
    import skewpend

    params, y0 = case()
    print("Lyapunov spectrum, skewed double pendulum: a=1 b=0.8 m1=1 m2=0.7 alpha=0.6 g=9.81, y0=(1.2, -0.8, 0, 0)")
    print(f"  t_end {T_END:g} s, QR every {RENORM:g} s; full spectrum at tol {TOL_FULL:g}, largest at {TOL_LLE:g}")
    print(f"  cpu        {cpu_model()}")
    print(f"  python     {platform.python_version()}   numpy {version('numpy')}   sympy {version('sympy')}")
    print(f"  skewpend   {version('skewpend')}   heyoka {version('heyoka')}")

    sys_, rhs, X, names, det_m = equations(params)
    c_full, d_full, ta4 = compile_times(heyoka_full(sys_, y0, TOL_FULL))
    check_layout(ta4)
    c_lle, d_lle, ta1 = compile_times(heyoka_lle(sys_, rhs, X, names, y0, TOL_LLE))
    fns = {"heyoka full": lambda: benettin(ta4, y0, 4), "heyoka largest": lambda: benettin(ta1, y0, 1)}
    try:
        lyap = skewpend.lyapunov
    except AttributeError:
        print("(skewpend.lyapunov not available yet)")
        lyap = None
    if lyap is not None:
        kw = dict(t_end=T_END, renorm_every=RENORM)
        fns["skewpend full"] = lambda: lyap(params, y0, rtol=TOL_FULL, atol=TOL_FULL, n_exponents=4, **kw)
        fns["skewpend largest"] = lambda: lyap(params, y0, rtol=TOL_LLE, atol=TOL_LLE, n_exponents=1, **kw)
    res = measure(fns, args.repeat)

    def exps(lab):
        r = res[lab][2]
        return np.asarray(r[0] if lab.startswith("heyoka") else r.exponents, dtype=float)

    def steps(lab):
        r = res[lab][2]
        return r[2] if lab.startswith("heyoka") else (r.stats or {}).get("steps", "")

    label = {
        "heyoka full": f"heyoka var_ode_sys 4 vec tol={TOL_FULL:g}",
        "skewpend full": f"skewpend lyapunov 4 vec tol={TOL_FULL:g}",
        "heyoka largest": f"heyoka J*u 1 vec tol={TOL_LLE:g}",
        "skewpend largest": f"skewpend lyapunov 1 vec tol={TOL_LLE:g}",
    }
    print(f"\nwarm; best and median of {args.repeat} interleaved runs")
    print(f"{'method':40s} {'best ms':>9s} {'median ms':>10s} {'steps':>8s}  exponents (1/s)")
    print(f"{'heyoka compile, 4 vec (cold JIT)':40s} {c_full * 1e3:9.1f} {c_full * 1e3:10.1f} {'':8s}  "
          f"(from heyoka's disk cache: {d_full * 1e3:.0f} ms)")
    print(f"{'heyoka compile, 1 vec (cold JIT)':40s} {c_lle * 1e3:9.1f} {c_lle * 1e3:10.1f} {'':8s}  "
          f"(from heyoka's disk cache: {d_lle * 1e3:.0f} ms)")
    for lab in ("heyoka full", "skewpend full", "heyoka largest", "skewpend largest"):
        if lab in res:
            best, med, _ = res[lab]
            print(f"{label[lab]:40s} {best * 1e3:9.1f} {med * 1e3:10.1f} {steps(lab)!s:>8s}  {fmt(exps(lab))}")

    # heyoka sanity: pairs, Liouville in (q, p), and the spread of finite-time exponents
    ex, yT, _ = res["heyoka full"][2]
    liou = np.log(det_m(*y0[:2]) / det_m(*yT[:2]))
    print("\nheyoka full spectrum checks")
    print(f"  pairs  l1+l4 = {ex[0] + ex[3]:+.2e}   l2+l3 = {ex[1] + ex[2]:+.2e}   (O(1/t_end) expected)")
    print(f"  sum    {ex.sum():+.3e} /s;  sum*t_end = {ex.sum() * T_END:+.9f},  log(det M(q0)/det M(q(T))) = "
          f"{liou:+.9f},  residual {abs(ex.sum() * T_END - liou) / T_END:.1e} /s")
    ex12 = benettin(heyoka_full(sys_, y0, TOL_SPREAD)(), y0, 4)[0]
    print(f"  tol {TOL_SPREAD:g}: {fmt(ex12)}   max |diff| to tol {TOL_FULL:g}: "
          f"{np.max(np.abs(ex12 - ex)):.2e}  (spread of finite-time exponents)")

    if lyap is None:
        return
    print("\nskewpend / heyoka (time ratio best, median; exponents max |difference|)")
    for kind, goal in (("full", f"   goal <= {GOAL:g}x"), ("largest", "")):
        s, h = res[f"skewpend {kind}"], res[f"heyoka {kind}"]
        d = np.max(np.abs(exps(f"skewpend {kind}")[: exps(f"heyoka {kind}").size] - exps(f"heyoka {kind}")))
        if goal:
            goal += f" (median): {'met' if s[1] / h[1] <= GOAL else 'NOT met'}"
        print(f"  {kind:8s} {s[0] / h[0]:5.2f}x  {s[1] / h[1]:5.2f}x{goal}   max |dl| = {d:.2e} /s")
    print(f"  skewpend stats (full): {res['skewpend full'][2].stats}")
    print(f"load average at the end: {os.getloadavg()[0]:.2f} (the machine may be shared)")


if __name__ == "__main__":
    main()
