"""A chain's default ``simulate`` against heyoka.py on explicit recursive equations, at equal error (issue 38).

The issue's goal: a three-link chain's default ``simulate`` (20 s at rtol = atol = 1e-10) in <= 0.3x heyoka.py's
time at equal error, heyoka given the same chain as explicit heyoka expressions in its full mode (not
``hy.lagrangian``, whose system is slow: ``bench_chain.py --heyoka``); a ten-link chain <= 0.3x heyoka's compact
mode; the ten-link chain builds in <= 3 s in a fresh process.

**heyoka's model** (:func:`heyoka_equations`, written here on ``heyoka.expression``): the recursive algorithms of
``skewpend.numeric.recursive`` -- kinematics by Rodrigues' rotations about each hinge's numeric unit axis
(``R_i = R_{i-1} P(q_i, e_i)``, ``o_i = o_{i-1} + R_{i-1} h_i``, ``a_i = R_{i-1} e_i``), the mass matrix by the
composite-rigid-body algorithm (``M_kl = a_k . ang_l + (o_k x a_k) . lin_l``), the bias ``C q' + dPi/dq`` by the
recursive Newton-Euler algorithm at ``q'' = 0``, then ``q''`` from ``M q'' = Q - bias`` by an explicit symbolic
LDL^T factorisation and the two triangular solves, all as heyoka expressions.  Every parameter value (axes,
offsets, masses, centres of mass, inertias, g) is baked in as a number -- what a user hands heyoka's full mode --
and constants are folded in Python before heyoka sees them (zeros dropped, products of numbers multiplied out,
the rotated inertia's 6 distinct entries only, sums as ``hy.sum``).  Checked against skewpend's compiled kernel
(``K.rhs``) at 20 random states before any timing (printed: the largest relative difference of q'').

**Runs** (chains ``bench_chain.random_chain(n, 1)``: general bodies, hinge axes near ``k``, no damping; 20 s from
every link at ``0.6 min(1, 3/n)`` rad at rest, as ``bench_chain.py``):

* skewpend ``simulate(chain, y0, 20, rtol=1e-10, atol=1e-10)`` -- the default method (``auto``: taylor up to
  ``conventions.SERIES_MAX_LINKS`` links, its library built before the timing, ``SKEWPEND_TAYLOR_BUILD=foreground``;
  dop853 beyond), its own steps returned -- and the same with ``method="dop853"`` and ``method="taylor"`` named
  (``--taylor-links``, default 3: the chain's Taylor libraries compile for each order);
* heyoka.py ``taylor_adaptive(sys, y0, tol=tol)`` at ``--tols`` (default 1e-6 ... 1e-12), full mode below
  ``--compact-from`` links (default 4), ``compact_mode=True`` from there; timed as resetting time and state and
  ``propagate_until(20)``.  Its JIT compile (cold: heyoka's on-disk and in-memory caches off) is timed apart,
  wall and CPU, and reported, never included.

**Error**: max over the state of |y(20) - y_ref(20)|, the reference heyoka.py in long double (80-bit x87,
``fp_type=numpy.longdouble``) at tol 1e-19 on the same expressions (compact mode), cross-checked against heyoka
in double at tol 1e-15 and skewpend's dop853 at rtol = atol = 1e-15 (printed).

**Timing**: CPU time (``time.process_time``; the machine is shared), ``--repeat`` rounds, each round every
skewpend configuration and every heyoka tolerance in turn (skewpend, heyoka, skewpend, ... alternating), medians.
**Equal error**: heyoka's points (error, median time) reduced to their work-precision front and log(time)
interpolated in log(error) at skewpend's error (``bench_precision.front`` / ``time_at``); the ratio
skewpend / heyoka there, also as the median of the per-round ratios.  The ten-link fresh-process build is
``bench_chain``'s child with an empty kernel cache (wall time, and CPU time of the child and its compiler;
medians of ``--build-repeat``).

    python benchmarks/bench_chain_heyoka.py [--links 3 10] [--repeat 21] [--tols 1e-6 ... 1e-12]
"""

from __future__ import annotations

import argparse
import math
import os
import statistics
import sys
import time

import numpy as np

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from _common import cpu_model, version  # noqa: E402
from bench_chain import _BUILD, random_chain  # noqa: E402
from bench_precision import front, time_at  # noqa: E402

T_END = 20.0
TOL = 1e-10


# ---------------------------------------------------------------- arithmetic on numbers and heyoka expressions
def _num(x) -> bool:
    return isinstance(x, float)


def mul(a, b):
    """a * b with numbers folded (0 drops the product, 1 and -1 vanish)."""
    if _num(a) and _num(b):
        return a * b
    if _num(b):
        a, b = b, a
    if _num(a):
        if a == 0.0:
            return 0.0
        if a == 1.0:
            return b
        if a == -1.0:
            return -b
    return a * b


def add(*terms):
    """The sum of ``terms``: numbers added up, zeros dropped, expressions summed by one ``hy.sum``."""
    import heyoka as hy

    const = math.fsum(t for t in terms if _num(t))
    exprs = [t for t in terms if not _num(t)]
    if const != 0.0:
        exprs.append(hy.expression(const))
    if not exprs:
        return 0.0
    return exprs[0] if len(exprs) == 1 else hy.sum(exprs)


def sub(a, b):
    return add(a, mul(-1.0, b))


def dot(u, v):
    return add(*(mul(x, y) for x, y in zip(u, v)))


def cross(u, v):
    return [sub(mul(u[1], v[2]), mul(u[2], v[1])), sub(mul(u[2], v[0]), mul(u[0], v[2])),
            sub(mul(u[0], v[1]), mul(u[1], v[0]))]


def vadd(*vs):
    return [add(*(v[i] for v in vs)) for i in range(3)]


def vscale(s, v):
    return [mul(s, x) for x in v]


def matvec(A, v):
    return [dot(A[i], v) for i in range(3)]


def matmul(A, B):
    return [[dot(A[i], [B[k][j] for k in range(3)]) for j in range(3)] for i in range(3)]


def symvec(S, v):
    """S v for a symmetric S given as its 6 entries (xx, xy, xz, yy, yz, zz)."""
    xx, xy, xz, yy, yz, zz = S
    return [dot((xx, xy, xz), v), dot((xy, yy, yz), v), dot((xz, yz, zz), v)]


def rotation(c, s, e):
    """Rodrigues' P(q, e) = cos q E + sin q [e]x + (1 - cos q) e e^T for the numeric unit e, each entry
    folded to ``e_i e_j + (delta_ij - e_i e_j) c + eps s``."""
    x, y, z = e
    eps = [[0.0, -z, y], [z, 0.0, -x], [-y, x, 0.0]]
    out = []
    for i in range(3):
        row = []
        for j in range(3):
            ee = e[i] * e[j]
            row.append(add(ee, mul((1.0 if i == j else 0.0) - ee, c), mul(eps[i][j], s)))
        out.append(row)
    return out


# ---------------------------------------------------------------- the chain's equations as heyoka expressions
def heyoka_equations(chain):
    """``(q, v, acc)``: heyoka variables and the chain's accelerations ``q''`` as explicit heyoka expressions
    (the recursive algorithms of ``skewpend.numeric.recursive`` in the world frame, the parameters numbers)."""
    import heyoka as hy

    n = chain.n
    q = list(hy.make_vars(*[f"q{i}" for i in range(n)]))
    v = list(hy.make_vars(*[f"v{i}" for i in range(n)]))
    g = float(chain.g)
    R = [[1.0 if i == j else 0.0 for j in range(3)] for i in range(3)]
    o = [0.0, 0.0, 0.0]
    O, A, OA, C, IW, MASS = [], [], [], [], [], []
    for i, link in enumerate(chain.links):
        for name in ("damping", "torque", "coulomb", "rotor"):
            if float(getattr(link, name, 0.0) or 0.0) != 0.0:
                raise ValueError(f"heyoka_equations: link {i + 1} has {name}; the benchmark's chains have none")
        o = vadd(o, matvec(R, [float(x) for x in link.offset]))
        e = [float(x) for x in link.axis]
        a = matvec(R, e)
        R = matmul(R, rotation(hy.cos(q[i]), hy.sin(q[i]), e))
        c = vadd(o, matvec(R, [float(x) for x in link.com]))
        Ib = [[float(x) for x in row] for row in link.inertia]
        RI = matmul(R, Ib)  # R Ib, then (R Ib R^T)'s 6 distinct entries
        Iw = [dot(RI[i1], R[j1]) for i1, j1 in ((0, 0), (0, 1), (0, 2), (1, 1), (1, 2), (2, 2))]
        O.append(o)
        A.append(a)
        OA.append(cross(o, a))
        C.append(c)
        IW.append(Iw)
        MASS.append(float(link.mass))
    # -- the mass matrix: composite rigid bodies (recursive._Graph.mass_matrix)
    M = [[None] * n for _ in range(n)]
    mC, hC, JC = 0.0, [0.0] * 3, [0.0] * 6
    for l in reversed(range(n)):
        m, c = MASS[l], C[l]
        mC += m
        hC = vadd(hC, vscale(m, c))
        cc = dot(c, c)
        outer = [mul(c[i1], c[j1]) for i1, j1 in ((0, 0), (0, 1), (0, 2), (1, 1), (1, 2), (2, 2))]
        diag = (True, False, False, True, False, True)
        JC = [add(JC[k], IW[l][k], mul(m, sub(cc, outer[k]) if diag[k] else mul(-1.0, outer[k]))) for k in range(6)]
        w, v0 = A[l], OA[l]
        lin = vadd(vscale(mC, v0), cross(w, hC))
        ang = vadd(symvec(JC, w), cross(hC, v0))
        for k in range(l + 1):
            M[k][l] = M[l][k] = add(dot(A[k], ang), dot(OA[k], lin))
    # -- the bias C q' + dPi/dq: recursive Newton-Euler at q'' = 0 (recursive._Graph.bias)
    omega, alpha, acc_o, o_prev = [0.0] * 3, [0.0] * 3, [0.0] * 3, [0.0] * 3
    F, N = [], []
    for i in range(n):
        d = [sub(O[i][k], o_prev[k]) for k in range(3)]
        acc_o = vadd(acc_o, cross(alpha, d), cross(omega, cross(omega, d)))
        alpha = vadd(alpha, cross(omega, vscale(v[i], A[i])))
        omega = vadd(omega, vscale(v[i], A[i]))
        r = [sub(C[i][k], O[i][k]) for k in range(3)]
        acc_c = vadd(acc_o, cross(alpha, r), cross(omega, cross(omega, r)))
        m = MASS[i]
        F.append(vscale(m, [acc_c[0], sub(acc_c[1], g), acc_c[2]]))  # m (a_c - g j), j down
        N.append(vadd(symvec(IW[i], alpha), cross(omega, symvec(IW[i], omega))))
        o_prev = O[i]
    bias = [None] * n
    f, nm = [0.0] * 3, [0.0] * 3
    for i in reversed(range(n)):
        if i < n - 1:
            nm = vadd(nm, cross([sub(O[i + 1][k], O[i][k]) for k in range(3)], f))
        nm = vadd(nm, N[i], cross([sub(C[i][k], O[i][k]) for k in range(3)], F[i]))
        f = vadd(f, F[i])
        bias[i] = dot(A[i], nm)
    rhs = [mul(-1.0, b) for b in bias]  # Q = 0: no torques, damping or friction
    # -- M q'' = rhs by LDL^T: W_ij = L_ij D_j, D_j = M_jj - sum_k W_jk L_jk
    L = [[None] * n for _ in range(n)]
    W = [[None] * n for _ in range(n)]
    D = [None] * n
    for j in range(n):
        D[j] = sub(M[j][j], add(*(mul(W[j][k], L[j][k]) for k in range(j))))
        for i in range(j + 1, n):
            W[i][j] = sub(M[i][j], add(*(mul(W[i][k], L[j][k]) for k in range(j))))
            L[i][j] = W[i][j] / D[j]
    z = [None] * n
    for i in range(n):
        z[i] = sub(rhs[i], add(*(mul(L[i][k], z[k]) for k in range(i))))
    x = [None] * n
    for i in reversed(range(n)):
        x[i] = sub(z[i] / D[i], add(*(mul(L[k][i], x[k]) for k in range(i + 1, n))))
    return q, v, x


def verify(chain, q, v, acc, states=20, seed=3):
    """The largest relative difference of q'' between heyoka's expressions (``hy.cfunc``) and skewpend's
    compiled kernel at ``states`` random states."""
    import heyoka as hy

    from skewpend.numeric import kernels, recursive

    n = chain.n
    fn = hy.cfunc(acc, q + v, compact_mode=n >= 4)
    K, p = kernels.chain_kernel(chain), recursive.parameter_vector(chain)
    rng = np.random.default_rng(seed)
    worst = 0.0
    for _ in range(states):
        y = np.r_[rng.uniform(-3, 3, n), rng.normal(scale=2, size=n)]
        out = np.zeros(2 * n + 1)
        K.rhs(np.r_[y, 0.0], p, out)
        ours = out[n:2 * n]
        theirs = np.asarray(fn(y), dtype=float)
        worst = max(worst, float(np.max(np.abs(theirs - ours)) / np.max(np.abs(ours))))
    return worst


def jit(build):
    """(object, wall s, CPU s) of ``build()`` with heyoka's caches off: a cold compile."""
    import heyoka as hy

    L = hy.llvm_state
    was = L.get_diskcache_enabled()
    L.clear_memcache()
    L.set_diskcache_enabled(False)
    try:
        w, c = time.perf_counter(), time.process_time()
        obj = build()
        return obj, time.perf_counter() - w, time.process_time() - c
    finally:
        L.set_diskcache_enabled(was)
        L.clear_memcache()


def build_times(n, repeat):
    """(wall s, CPU s) medians of ``repeat`` fresh processes with an empty kernel cache that derive, print and
    compile the chain's kernel (``bench_chain``'s child; CPU: the child's and its compiler's, from
    ``getrusage(RUSAGE_CHILDREN)``)."""
    import resource
    import subprocess
    import tempfile

    wall, cpu_ = [], []
    for _ in range(repeat):
        with tempfile.TemporaryDirectory() as cache:
            env = {**os.environ, "SKEWPEND_CACHE_DIR": cache, "SKEWPEND_QUIET": "1"}
            r0 = resource.getrusage(resource.RUSAGE_CHILDREN)
            t = time.perf_counter()
            subprocess.run([sys.executable, "-c", _BUILD.format(bench=os.path.dirname(os.path.abspath(__file__)), n=n)],
                           check=True, env=env, capture_output=True)
            wall.append(time.perf_counter() - t)
            r1 = resource.getrusage(resource.RUSAGE_CHILDREN)
            cpu_.append(r1.ru_utime + r1.ru_stime - r0.ru_utime - r0.ru_stime)
    return statistics.median(wall), statistics.median(cpu_), wall


def cpu(fn):
    t = time.process_time()
    out = fn()
    return time.process_time() - t, out


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--links", type=int, nargs="+", default=[3, 10])
    ap.add_argument("--repeat", type=int, default=21, help="rounds of alternating timings (medians)")
    ap.add_argument("--tols", type=float, nargs="+", default=[1e-6, 1e-7, 1e-8, 1e-9, 1e-10, 1e-11, 1e-12],
                    help="heyoka.py's tolerances (each a JIT compile)")
    ap.add_argument("--compact-from", type=int, default=4, help="heyoka's compact mode from this many links")
    ap.add_argument("--taylor-links", type=int, nargs="*", default=[3], help="chains also timed with method='taylor'")
    ap.add_argument("--build-repeat", type=int, default=3, help="fresh-process builds (10 links) per chain length")
    args = ap.parse_args(argv)
    import heyoka as hy

    import skewpend

    print(f"# {time.strftime('%Y-%m-%d %H:%M UTC', time.gmtime())}; {cpu_model()}, {os.cpu_count()} cores, load "
          f"{os.getloadavg()[0]:.2f}; python {sys.version.split()[0]}, skewpend {skewpend.__version__}, casadi "
          f"{version('casadi')}, heyoka.py {version('heyoka')} (SIMD {hy.recommended_simd_size()}), numpy "
          f"{version('numpy')}; CPU times (process_time), medians of {args.repeat} alternating rounds")
    summary, jits = [], []
    for n in args.links:
        chain = random_chain(n, 1)
        compact = n >= args.compact_from
        mode = "compact" if compact else "full"
        print(f"\n## {n} links (heyoka {mode} mode)")
        q, v, acc = heyoka_equations(chain)
        sys_ = [(q[i], v[i]) for i in range(n)] + [(v[i], acc[i]) for i in range(n)]
        print(f"heyoka expressions: q'' by recursive algorithms + LDL^T, parameters as numbers; "
              f"{sum(len(str(a)) for a in acc)} characters printed")
        print(f"check against skewpend's kernel, 20 random states: max relative difference of q'' "
              f"{verify(chain, q, v, acc):.1e}")
        y0 = np.r_[np.full(n, 0.6 * min(1.0, 3.0 / n)), np.zeros(n)]
        # the reference: heyoka in long double (x87 80-bit, 64-bit significand) at tol 1e-19, compact mode,
        # cross-checked with heyoka (double) at 1e-15 and skewpend's dop853 at 1e-15
        ld = np.longdouble
        ta_ref = hy.taylor_adaptive(sys_, np.array(y0, dtype=ld), tol=ld(1e-19), compact_mode=True, fp_type=ld)
        ta_ref.propagate_until(ld(T_END))
        ref = np.array(ta_ref.state, dtype=float)
        ta_dbl = hy.taylor_adaptive(sys_, list(y0), tol=1e-15, compact_mode=True)
        ta_dbl.propagate_until(T_END)
        other = skewpend.simulate(chain, y0, T_END, method="dop853", rtol=1e-15, atol=1e-15).y[-1][:2 * n]
        print(f"reference heyoka long double tol 1e-19 (order {ta_ref.order}) at 20 s against heyoka double tol 1e-15: "
              f"{np.max(np.abs(ref - np.array(ta_dbl.state))):.1e}, skewpend dop853 1e-15: {np.max(np.abs(ref - other)):.1e}")

        def err(y):
            return float(np.max(np.abs(np.asarray(y, dtype=float)[:2 * n] - ref)))

        # skewpend's configurations (kernels compiled and loaded before timing)
        os.environ["SKEWPEND_TAYLOR_BUILD"] = "foreground"  # the default's steady state: its library built first
        methods = [("default", {}), ("dop853", {"method": "dop853"})]
        if n in args.taylor_links:
            methods.append(("taylor", {"method": "taylor"}))
        sk = {}
        for name, kw in methods:
            t = time.perf_counter()
            tr = skewpend.simulate(chain, y0, T_END, rtol=TOL, atol=TOL, **kw)
            first = time.perf_counter() - t
            sk[name] = {"kw": kw, "err": err(tr.y[-1]), "method": tr.method, "steps": tr.stats.get("steps"), "t": []}
            print(f"skewpend {name}: ran {tr.method}, {tr.stats.get('steps')} steps, first call (compile/load) "
                  f"{first:.2f} s wall")
        # heyoka's integrators, one JIT each
        hys = {}
        for tol in args.tols:
            ta, w, c = jit(lambda tol=tol: hy.taylor_adaptive(sys_, list(y0), tol=tol, compact_mode=compact))
            ta.propagate_until(T_END)
            hys[tol] = {"ta": ta, "jit": (w, c), "err": err(ta.state), "order": ta.order, "t": []}
            if len(hys) == 1:
                print(f"heyoka's Taylor decomposition: {len(ta.decomposition)} entries (variables, elementary "
                      f"operations, right-hand sides)")
            print(f"heyoka tol {tol:.0e}: order {ta.order}, JIT {w:.2f} s wall / {c:.2f} s CPU, error {hys[tol]['err']:.1e}")

        jw, jc = [h["jit"][0] for h in hys.values()], [h["jit"][1] for h in hys.values()]
        jits.append(f"  {n:2d} links, heyoka {mode} mode cold JIT: {min(jw):.1f}-{max(jw):.1f} s wall, "
                    f"{min(jc):.1f}-{max(jc):.1f} s CPU per tolerance (orders "
                    f"{min(h['order'] for h in hys.values())}-{max(h['order'] for h in hys.values())})")

        def run_sk(kw):
            return skewpend.simulate(chain, y0, T_END, rtol=TOL, atol=TOL, **kw)

        def run_hy(ta):
            ta.time = 0.0
            ta.state[:] = y0
            res = ta.propagate_until(T_END)
            if res[0] != hy.taylor_outcome.time_limit:
                raise RuntimeError(f"heyoka stopped: {res[0]}")

        load0 = os.getloadavg()[0]
        for _ in range(args.repeat):  # alternating: skewpend, heyoka, skewpend, heyoka, ...
            sk_items, hy_items = list(sk.values()), list(hys.values())
            for k in range(max(len(sk_items), len(hy_items))):
                if k < len(sk_items):
                    sk_items[k]["t"].append(cpu(lambda: run_sk(sk_items[k]["kw"]))[0])
                if k < len(hy_items):
                    hy_items[k]["t"].append(cpu(lambda: run_hy(hy_items[k]["ta"]))[0])
        load1 = os.getloadavg()[0]
        print(f"timed rounds: load {load0:.2f} -> {load1:.2f}")
        for tol, h in hys.items():
            print(f"  heyoka tol {tol:.0e}: error {h['err']:.2e}, CPU {statistics.median(h['t']) * 1e3:.3f} ms "
                  f"(min {min(h['t']) * 1e3:.3f})")
        fr = front([(h["err"], statistics.median(h["t"])) for h in hys.values()])
        for name, s in sk.items():
            med = statistics.median(s["t"])
            at = time_at(fr, s["err"])
            per_round = []
            for r in range(args.repeat):
                fr_r = front([(h["err"], h["t"][r]) for h in hys.values()])
                t_r = time_at(fr_r, s["err"])
                if t_r:
                    per_round.append(s["t"][r] / t_r)
            if at is None:
                ratio = "outside heyoka's errors"
            else:
                ratio = (f"heyoka at equal error {at * 1e3:.3f} ms -> ratio {med / at:.3f}"
                         + (f" (median per round {statistics.median(per_round):.3f})" if per_round else ""))
                summary.append((n, name, s["method"], mode, med / at,
                                statistics.median(per_round) if per_round else float("nan")))
            print(f"  skewpend {name} ({s['method']}, rtol=atol=1e-10): error {s['err']:.2e}, CPU {med * 1e3:.3f} ms "
                  f"(min {min(s['t']) * 1e3:.3f}); {ratio}")
        if n >= 10 and args.build_repeat:
            w, c, ws = build_times(n, args.build_repeat)
            print(f"skewpend build, {n} links, fresh process, empty kernel cache (median of {args.build_repeat}): "
                  f"{w:.2f} s wall (each {', '.join(f'{x:.2f}' for x in ws)}), {c:.2f} s CPU (child and compiler)")
    print("\n# summary: skewpend / heyoka.py at equal error (CPU time, 20 s, rtol = atol = 1e-10)")
    for n, name, method, mode, r, rr in summary:
        print(f"  {n:2d} links, skewpend {name:<8} ({method}) vs heyoka {mode:<7} mode: {r:.3f} (per round {rr:.3f})")
    print("\n".join(jits))


if __name__ == "__main__":
    main()
