"""Simulation speed and accuracy: skewpend against SciPy and MuJoCo, side by side in one run.

Case (issue 3): a=1, b=0.8, m1=1, m2=0.7, alpha=0.6, g=9.81, y0=(1.2, -0.8, 0, 0),
20 s of motion, warm (compiled code loaded before timing), in process.

* skewpend's default, ``simulate(P, y0, 20, rtol=1e-10, atol=1e-10)`` with no method named (``"auto"``:
  taylor here), and dop853 and taylor named, at rtol = atol = 1e-10, own steps;
* skewpend rk4, dt = 1e-3 (compiled fixed step) and gauss (symplectic), dt = 1e-3;
* SciPy ``solve_ivp(method="DOP853", rtol=atol=1e-10)`` on skewpend's generated
  standalone Python right-hand side (math/NumPy scalar code, no compilation);
* MuJoCo, the exported MJCF, RK4 at dt = 1e-3 (stepping only; model compiled before);
* heyoka.py's ``taylor_adaptive`` at tol 1e-10 on the same equations (from skewpend's derivation).

The error is the max-norm state error at t = 5 s against SciPy DOP853 at rtol = atol = 1e-13.
(For MuJoCo the thin rods carry the tiny axial inertia it needs; its reference uses the same.)

Last, issue 36's goal: the default against heyoka.py, timed in pairs (default, heyoka.py, default,
...: both see the same load), the ratio of the medians (goal <= 1.0).

Run:  python benchmarks/bench_simulate.py [--repeat 7]
"""

from __future__ import annotations

import argparse
import time

import numpy as np
from scipy.integrate import solve_ivp

from skewpend import Parameters, simulate
from skewpend.numeric.codegen import generate, parameter_vector

P = Parameters(a=1.0, b=0.8, m1=1.0, m2=0.7, alpha=0.6, g=9.81)
Y0 = np.array([1.2, -0.8, 0.0, 0.0])
T_END, T_ERR = 20.0, 5.0


def best_of(fn, repeat):
    times = []
    for _ in range(repeat):
        t0 = time.perf_counter()
        result = fn()
        times.append(time.perf_counter() - t0)
    return min(times), float(np.median(times)), result


def scipy_rhs(params):
    ns: dict = {}
    exec(generate(params, "python"), ns)
    return ns["rhs"], parameter_vector(params).tolist()


def reference(params, t):
    rhs, p = scipy_rhs(params)
    sol = solve_ivp(rhs, (0, t), Y0, method="DOP853", rtol=1e-13, atol=1e-13, args=(p,))
    return sol.y[:, -1]


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--repeat", type=int, default=7)
    args = ap.parse_args()
    rows = []
    ref5 = reference(P, T_ERR)

    # skewpend (warm-up loads or compiles the machine code); the default first: the ratios' base
    tol = {"rtol": 1e-10, "atol": 1e-10}
    for method, kw in ((None, tol), ("dop853", tol), ("taylor", tol), ("rk4", {"dt": 1e-3}), ("gauss", {"dt": 1e-3})):
        kw = kw if method is None else {"method": method, **kw}
        simulate(P, Y0, 1.0, **kw)
        best, med, tr = best_of(lambda: simulate(P, Y0, T_END, **kw), args.repeat)
        err = np.max(np.abs(simulate(P, Y0, T_ERR, **kw).y[-1] - ref5))
        label = (f"skewpend default (auto: {tr.method})" if method is None else f"skewpend {method}") + \
            (" rtol=atol=1e-10" if "rtol" in kw else " dt=1e-3")
        rows.append((label, best, med, err, tr.stats["steps"]))

    # SciPy DOP853 with the generated (uncompiled) Python right-hand side
    rhs, p = scipy_rhs(P)
    best, med, sol = best_of(
        lambda: solve_ivp(rhs, (0, T_END), Y0, method="DOP853", rtol=1e-10, atol=1e-10, args=(p,)), max(1, args.repeat // 3)
    )
    sol5 = solve_ivp(rhs, (0, T_ERR), Y0, method="DOP853", rtol=1e-10, atol=1e-10, args=(p,))
    rows.append(("scipy solve_ivp DOP853 1e-10", best, med, np.max(np.abs(sol5.y[:, -1] - ref5)), sol.t.size - 1))

    # MuJoCo RK4 dt = 1e-3
    try:
        import mujoco

        from skewpend.interop.export import mujoco_compatible, to_mjcf

        same = mujoco_compatible(P)
        model = mujoco.MjModel.from_xml_string(to_mjcf(P, timestep=1e-3))
        data = mujoco.MjData(model)

        def run_mujoco(t_end):
            mujoco.mj_resetData(model, data)
            data.qpos[:] = Y0[:2]
            data.qvel[:] = Y0[2:]
            mujoco.mj_step(model, data, nstep=int(round(t_end / 1e-3)))
            return np.concatenate([data.qpos, data.qvel])

        best, med, _ = best_of(lambda: run_mujoco(T_END), args.repeat)
        err = np.max(np.abs(run_mujoco(T_ERR) - reference(same, T_ERR)))
        rows.append((f"MuJoCo {mujoco.__version__} RK4 dt=1e-3", best, med, err, int(round(T_END / 1e-3))))
    except ImportError:
        print("(mujoco not installed: pip install 'skewpend[validate]')")

    # heyoka.py's Taylor integrator on the same equations (converted from skewpend's derivation)
    try:
        import heyoka as hy
        import sympy as sp

        from skewpend import SYMBOLS, derive

        eom = derive(P.replace(c1=0.0, c2=0.0, tau1=0.0, tau2=0.0))
        M, f = eom.mass_matrix, eom.forcing
        det = M[0, 0] * M[1, 1] - M[0, 1] ** 2
        qdd = [sp.N((M[1, 1] * f[0] - M[0, 1] * f[1]) / det, 17), sp.N((M[0, 0] * f[1] - M[0, 1] * f[0]) / det, 17)]
        v = hy.make_vars("phi", "psi", "dphi", "dpsi")
        names = {SYMBOLS[n]: x for n, x in zip(("phi", "psi", "dphi", "dpsi"), v)}
        ta = hy.taylor_adaptive([(v[0], v[2]), (v[1], v[3]), (v[2], hy.from_sympy(qdd[0], names)),
                                 (v[3], hy.from_sympy(qdd[1], names))], list(Y0), tol=1e-10)

        def run_heyoka(t_end):
            ta.time = 0.0
            ta.state[:] = Y0
            ta.propagate_until(t_end)
            return ta.state.copy()

        best, med, _ = best_of(lambda: run_heyoka(T_END), args.repeat)
        err = np.max(np.abs(run_heyoka(T_ERR) - ref5))
        rows.append((f"heyoka.py {hy.__version__} taylor tol=1e-10", best, med, err, 0))
    except ImportError:
        run_heyoka = None
        print("(heyoka.py not installed: pip install '.[bench]')")

    base = rows[0][2]
    print(f"20 s of motion, warm; best and median of {args.repeat} runs; error = max |y(5 s) - reference|")
    print(f"{'method':50s} {'best ms':>9s} {'median ms':>10s} {'error@5s':>10s} {'steps':>7s} {'median / skewpend default':>26s}")
    for name, best, med, err, steps in rows:
        print(f"{name:50s} {best * 1e3:9.2f} {med * 1e3:10.3f} {err:10.1e} {steps:7d} {med / base:26.2f}")

    if run_heyoka is not None:  # issue 36's goal, in pairs
        ours, theirs = [], []
        for _ in range(max(args.repeat, 21)):
            t0 = time.perf_counter()
            simulate(P, Y0, T_END, rtol=1e-10, atol=1e-10)
            t1 = time.perf_counter()
            run_heyoka(T_END)
            t2 = time.perf_counter()
            ours.append(t1 - t0)
            theirs.append(t2 - t1)
        ratio = float(np.median(ours) / np.median(theirs))
        print(f"goal (issue 36): simulate(P, y0, 20, rtol=1e-10, atol=1e-10), no method named, against heyoka.py at tol "
              f"1e-10, {len(ours)} pairs: {np.median(ours) * 1e3:.3f} ms / {np.median(theirs) * 1e3:.3f} ms = "
              f"{ratio:.2f}x ({'PASS' if ratio <= 1.0 else 'FAIL'}: <= 1.0)")


if __name__ == "__main__":
    main()
