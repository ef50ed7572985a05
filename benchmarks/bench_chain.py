"""Chains of links side by side with MuJoCo: build time, accelerations, and a run at equal error.

For chains of ``--links`` (default 3 5 10) random links (general bodies, hinge axes near k, tilted at random,
no damping: a conservative motion whose reference is DOP853 at 1e-13):

* **build**: a fresh process with an empty kernel cache derives the chain's equations (CasADi graphs of
  the recursive algorithms), prints and compiles them -- seconds, median of ``--repeat``;
* **fidelity**: the largest relative difference of the accelerations from MuJoCo's ``mj_forward`` on the
  exported MJCF over 100 random states;
* **equal error**: the 20 s run's final-state error and wall time for skewpend's dop853 at rtol 1e-6 ...
  1e-12 and MuJoCo's RK4 (``mj_step``, the model's own integrator) at dt ``--mujoco-dts`` (default 4e-3 ...
  3.125e-5); the ratio skewpend/MuJoCo at MuJoCo's errors (skewpend's time interpolated in log-log), and the
  error below which skewpend is at least 50x faster (where the ratio, interpolated in log-log, crosses 1/50).

* **heyoka.py** (``--heyoka``): the same chain's Lagrangian written in heyoka's expressions (the kinematics
  below, ``heyoka_chain``; Euler-Lagrange equations by ``hy.lagrangian``), its Taylor integrator at tol
  ``--heyoka-tols`` (default 1e-6, 1e-9, 1e-12) -- the default full mode up to ``--compact-from`` links (default 4), the compact mode
  beyond (the full mode does not finish compiling for 10 links) -- and the ratio skewpend/heyoka.py at
  heyoka's errors; its JIT compile time beside skewpend's build.

    python benchmarks/bench_chain.py [--links 3 5 10] [--repeat 3] [--t-end 20] [--heyoka]
"""

from __future__ import annotations

import argparse
import os
import subprocess
import sys
import tempfile
import time

import numpy as np

sys.path.insert(0, os.path.dirname(__file__))
from _common import cpu_model, version  # noqa: E402


def random_chain(n, seed):
    from skewpend.symbolic.chain import Chain, Link

    rng = np.random.default_rng(seed)
    links = []
    for i in range(n):
        d = rng.uniform(0.05, 0.3, 3)
        D = np.diag([d[1] ** 2 + d[2] ** 2, d[0] ** 2 + d[2] ** 2, d[0] ** 2 + d[1] ** 2]) / 12
        R, _ = np.linalg.qr(rng.normal(size=(3, 3)))
        axis = np.array([0.0, 0.0, 1.0]) + rng.normal(scale=0.4, size=3)
        links.append(Link(axis=tuple(axis), length=0.5, mass=1.0, offset=(0.0, 0.5, 0.0) if i else (0, 0, 0),
                          com=(0.0, 0.25, 0.0) + rng.normal(scale=0.03, size=3), inertia=(R @ D @ R.T).tolist()))
    return Chain(links=tuple(links), g=9.81)


_BUILD = """
import time, sys
sys.path.insert(0, {bench!r})
t = time.perf_counter()
from bench_chain import random_chain
from skewpend.numeric.kernels import chain_kernel
chain_kernel(random_chain({n}, 1))
print(time.perf_counter() - t)
"""


def _rodrigues(c, s, e):
    x, y, z = e
    k = 1 - c
    return [[c + k * x * x, k * x * y - s * z, k * x * z + s * y],
            [k * y * x + s * z, c + k * y * y, k * y * z - s * x],
            [k * z * x - s * y, k * z * y + s * x, c + k * z * z]]


def _mat(A, B):
    return [[sum(A[i][k] * B[k][j] for k in range(3)) for j in range(3)] for i in range(3)]


def _vec(A, v):
    return [sum(A[i][k] * v[k] for k in range(3)) for i in range(3)]


def _cross(u, v):
    return [u[1] * v[2] - u[2] * v[1], u[2] * v[0] - u[0] * v[2], u[0] * v[1] - u[1] * v[0]]


def heyoka_chain(chain):
    """The chain's Euler-Lagrange equations in heyoka.py, written here for the peer: each link's rotation
    composed with Rodrigues' formula, its hinge's axis a_k = R_{k-1} e_k, angular velocity
    omega_k = sum_j a_j v_j, centre-of-mass velocity sum_j v_j a_j x (c_k - o_j); T and V from them."""
    import heyoka as hy

    n = chain.n
    qs = [hy.expression(f"q{i}") for i in range(n)]
    vs = [hy.expression(f"v{i}") for i in range(n)]
    R = [[1.0 if i == j else 0.0 for j in range(3)] for i in range(3)]
    o = [0.0, 0.0, 0.0]
    T, V = 0.0, 0.0
    hanging = 0.0
    axes, hinges = [], []
    for k, link in enumerate(chain.links):
        o = [o[i] + x for i, x in enumerate(_vec(R, link.offset))]
        hanging += link.offset[1]
        axes.append(_vec(R, link.axis))
        hinges.append(o)
        R = _mat(R, _rodrigues(hy.cos(qs[k]), hy.sin(qs[k]), link.axis))
        c = [o[i] + x for i, x in enumerate(_vec(R, link.com))]
        w = [sum(axes[j][i] * vs[j] for j in range(k + 1)) for i in range(3)]
        vc = [0.0, 0.0, 0.0]
        for j in range(k + 1):
            arm = _cross(axes[j], [c[i] - hinges[j][i] for i in range(3)])
            vc = [vc[i] + vs[j] * arm[i] for i in range(3)]
        wb = [sum(R[m][i] * w[m] for m in range(3)) for i in range(3)]  # R^T omega, the body frame's
        J = link.inertia
        T += 0.5 * link.mass * sum(x * x for x in vc) + 0.5 * sum(wb[i] * J[i][j] * wb[j] for i in range(3) for j in range(3))
        V += -chain.g * link.mass * (c[1] - (hanging + link.com[1]))
    return hy.lagrangian(T - V, qs, vs), qs + vs


def heyoka_runs(chain, y0, T, tols, compact, repeat):
    import heyoka as hy

    sys_, state = heyoka_chain(chain)
    out, build = [], []
    for tol in tols:
        t = time.perf_counter()
        ta = hy.taylor_adaptive(sys_, list(y0), tol=tol, compact_mode=compact)
        build.append(time.perf_counter() - t)
        times = []
        for _ in range(repeat):
            ta.time = 0.0
            ta.state[:] = y0
            t = time.perf_counter()
            ta.propagate_until(T)
            times.append(time.perf_counter() - t)
        out.append((np.array(ta.state, dtype=float), float(np.median(times))))
    return out, float(np.median(build))


def build_seconds(n, repeat):
    out = []
    for _ in range(repeat):
        with tempfile.TemporaryDirectory() as cache:
            env = {**os.environ, "SKEWPEND_CACHE_DIR": cache, "SKEWPEND_QUIET": "1"}
            t = time.perf_counter()
            subprocess.run([sys.executable, "-c", _BUILD.format(bench=os.path.dirname(os.path.abspath(__file__)), n=n)],
                           check=True, env=env, capture_output=True)
            out.append(time.perf_counter() - t)
    return float(np.median(out))


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--links", type=int, nargs="+", default=[3, 5, 10])
    ap.add_argument("--repeat", type=int, default=3)
    ap.add_argument("--t-end", type=float, default=20.0)
    ap.add_argument("--heyoka", action="store_true", help="also heyoka.py's Taylor integrator on the same chains")
    ap.add_argument("--compact-from", type=int, default=4, help="heyoka's compact mode from this many links")
    ap.add_argument("--heyoka-tols", type=float, nargs="+", default=[1e-6, 1e-9, 1e-12],
                    help="heyoka's tolerances (each a JIT compile: 2 min for 3 general links in full mode)")
    ap.add_argument("--mujoco-dts", type=float, nargs="+", default=[4e-3, 2e-3, 1e-3, 5e-4, 2.5e-4, 1.25e-4, 6.25e-5, 3.125e-5],
                    help="MuJoCo RK4's steps [s]")
    args = ap.parse_args(argv)
    import mujoco

    import skewpend
    from skewpend.interop.export import mujoco_compatible, to_mjcf
    from skewpend.numeric import kernels, recursive

    print(f"# {cpu_model()}, {os.cpu_count()} cores; skewpend {skewpend.__version__}, casadi {version('casadi')}, "
          f"mujoco {version('mujoco')}; load {os.getloadavg()[0]:.2f}")
    for n in args.links:
        chain = mujoco_compatible(random_chain(n, 1))
        build = build_seconds(n, args.repeat)
        K, p = kernels.chain_kernel(chain), recursive.parameter_vector(chain)
        model = mujoco.MjModel.from_xml_string(to_mjcf(chain))
        data = mujoco.MjData(model)
        rng = np.random.default_rng(2)
        worst = 0.0
        for _ in range(100):
            q, dq = rng.uniform(-3, 3, n), rng.normal(scale=2, size=n)
            data.qpos[:], data.qvel[:] = q, dq
            mujoco.mj_forward(model, data)
            out = np.zeros(2 * n + 1)
            K.rhs(np.r_[q, dq, 0.0], p, out)
            worst = max(worst, float(np.max(np.abs(out[n:2 * n] - data.qacc)) / np.max(np.abs(data.qacc))))
        y0 = np.r_[np.full(n, 0.6 * min(1.0, 3.0 / n)), np.zeros(n)]  # regular swings (a 10-link chain at 0.6 rad is chaotic)
        T = args.t_end
        ref = skewpend.simulate(chain, y0, T, method="dop853", rtol=1e-13, atol=1e-13, dt_out=T).y[-1]
        ours = []
        for rtol in (1e-6, 1e-8, 1e-10, 1e-12):
            times = []
            for _ in range(args.repeat):
                t = time.perf_counter()
                tr = skewpend.simulate(chain, y0, T, method="dop853", rtol=rtol, atol=rtol, dt_out=T)
                times.append(time.perf_counter() - t)
            ours.append((float(np.max(np.abs(tr.y[-1] - ref))), float(np.median(times))))
        theirs = []
        model.opt.integrator = mujoco.mjtIntegrator.mjINT_RK4
        for dt in args.mujoco_dts:
            model.opt.timestep = dt
            steps = int(round(T / dt))
            times = []
            for _ in range(args.repeat):
                mujoco.mj_resetData(model, data)
                data.qpos[:], data.qvel[:] = y0[:n], y0[n:]
                t = time.perf_counter()
                for _ in range(steps):
                    mujoco.mj_step(model, data)
                times.append(time.perf_counter() - t)
            theirs.append((float(np.max(np.abs(np.r_[data.qpos, data.qvel] - ref))), float(np.median(times))))
        print(f"\n## {n} links: build (fresh process, empty cache) {build:.2f} s; accelerations vs MuJoCo: max rel "
              f"{worst:.1e}")
        print("skewpend dop853: " + ", ".join(f"err {e:.1e} in {t * 1e3:.1f} ms" for e, t in ours))
        print("MuJoCo RK4:      " + ", ".join(f"err {e:.1e} in {t * 1e3:.1f} ms" for e, t in theirs))
        le, lt = np.log([e for e, _ in ours]), np.log([t for _, t in ours])
        order = np.argsort(le)
        at = []  # (log error, log ratio) at MuJoCo's errors within skewpend's range
        for e, t in theirs:
            if le.min() <= np.log(e) <= le.max():
                ratio = float(np.exp(np.interp(np.log(e), le[order], lt[order]))) / t
                at.append((np.log(e), np.log(ratio)))
                print(f"  at MuJoCo's error {e:.1e}: skewpend/MuJoCo time = {ratio:.3f} ({1 / ratio:.0f}x faster)")
        goal = np.log(1 / 50)
        cross = [np.exp(a0 + (goal - r0) * (a1 - a0) / (r1 - r0)) for (a0, r0), (a1, r1) in zip(at, at[1:])
                 if (r0 - goal) * (r1 - goal) < 0]
        if cross:
            print(f"  >= 50x faster below an error of {cross[-1]:.1e} (the ratio interpolated between MuJoCo's runs)")
        elif at:
            print(f"  >= 50x faster: {'at every' if max(r for _, r in at) <= goal else 'at none'} of MuJoCo's errors "
                  "within skewpend's range")
        if args.heyoka:
            compact = n >= args.compact_from
            runs, jit = heyoka_runs(chain, y0, T, tuple(args.heyoka_tols), compact, args.repeat)
            hy_pts = [(float(np.max(np.abs(state[:2 * n] - ref))), t) for state, t in runs]
            print(f"heyoka.py Taylor ({'compact' if compact else 'full'} mode, JIT {jit:.2f} s): "
                  + ", ".join(f"err {e:.1e} in {t * 1e3:.1f} ms" for e, t in hy_pts))
            for e, t in hy_pts:
                if le.min() <= np.log(e) <= le.max():
                    ratio = float(np.exp(np.interp(np.log(e), le[order], lt[order]))) / t
                    print(f"  at heyoka's error {e:.1e}: skewpend/heyoka.py time = {ratio:.2f}")


if __name__ == "__main__":
    main()
