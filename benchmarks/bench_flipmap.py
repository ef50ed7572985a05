"""Flip-time map: skewpend's flip_map against heyoka.py's batch mode, side by side in one run.

Case (issue 9): the 128 x 128 map, t_end = 10 s, a=1 b=0.8 m1=1 m2=0.7 alpha=0.6 g=9.81, window
(-pi, pi)^2, released at rest; flip time = first time either joint angle leaves (-pi, pi).

* skewpend: ``skewpend.analysis.flipmap.flip_map(params, 128)`` at its default settings (DOP853,
  rtol = atol = 1e-10, every core, energy bound and mirror symmetry on); warm (the flip kernel is
  compiled or loaded by an untimed first call).  For context also with one worker, and with the
  shortcuts off (every cell integrated).
* heyoka.py: ``taylor_adaptive_batch`` (batch size = ``hy.recommended_simd_size()``, tol 1e-8,
  terminal events ``phi^2 - pi^2`` and ``psi^2 - pi^2``).  The equations are NOT typed: they are
  skewpend's derivation (SymPy ``M(q)``, ``f(q, q')``) converted with ``hy.from_sympy`` (rationals
  and constants of the parameters turned into doubles first, which it requires), and
  ``q'' = M^-1 f`` solved as in skewpend.  A terminal event in one lane stops the whole batch
  (heyoka's batch semantics), so the harness records the lane's flip, refills the lane with the
  next cell (its own time reset to 0, cooldowns reset) and propagates on: no lane idles while
  cells remain.  heyoka's ``propagate_until`` holds the GIL (two threads run no faster than
  one, measured below), so "both cores" means two worker processes, each with its own batch
  integrator over half of the cells (built and warmed up untimed; the timed part is the
  propagation of the map, dispatched to both and gathered back).  Its 1-thread run is shown too.

Accuracy: every map is compared with a reference, skewpend's flip_map at rtol = atol = 1e-13
(untimed; tests/test_flipmap.py checks that one against ``simulate`` at 1e-12 with the crossing
interpolated), over the cells where both flip (max |difference|) and in the outcome (flip or
not, and which joint).  heyoka at its default tolerance (machine epsilon) is an independent
second reference.

The machine may be shared: skewpend and heyoka runs are interleaved (rep by rep) so that both
see the same load; medians are reported.

Run:  python benchmarks/bench_flipmap.py [--repeat 5] [--n 128]
      heyoka is optional (pip install heyoka): without it only skewpend is measured.
"""

from __future__ import annotations

import argparse
import math
import multiprocessing as mp
import os
import statistics
import sys
import threading
import time

import numpy as np

A, B, M1, M2, ALPHA, G = 1.0, 0.8, 1.0, 0.7, 0.6, 9.81
T_END = 10.0
HY_TOL = 1e-8
REF_TOL = 1e-13
GOAL, AMBITION = 1.0, 2.0  # skewpend time <= heyoka time / GOAL (and / AMBITION)
GOAL_28 = 3.0  # issue 28: the flip map stays >= 3x faster than heyoka's batch mode (best configuration)


def params():
    import skewpend

    return skewpend.Parameters(a=A, b=B, m1=M1, m2=M2, alpha=ALPHA, g=G)


from _common import heyoka_first_order, heyoka_header  # noqa: E402  (benchmarks/ is on sys.path when run)


def cells(n: int) -> np.ndarray:
    """The cell centres (phi0, psi0) of the map, row-major (phi0 along axis 0), as skewpend's."""
    from skewpend.analysis.flipmap import cell_centres

    c = cell_centres(-math.pi, math.pi, n)
    PHI, PSI = np.meshgrid(c, c, indexing="ij")
    return np.column_stack([PHI.ravel(), PSI.ravel()])


# ----------------------------------------------------------------------------- heyoka
def heyoka_system():
    """The equations of motion for heyoka, from skewpend's derivation via hy.from_sympy."""
    import heyoka as hy

    import skewpend
    from skewpend.symbolic.derivation import SYMBOLS

    eom = skewpend.derive(params().replace(c1=0.0, c2=0.0, tau1=0.0, tau2=0.0))
    names = ("phi", "psi", "dphi", "dpsi")
    hv = hy.make_vars(*names)
    s_dict = {SYMBOLS[nm]: v for nm, v in zip(names, hv)}

    return heyoka_first_order(eom, s_dict, hv), hv


def heyoka_integrator(tol: float):
    import heyoka as hy

    sys_, (phi, psi, _, _) = heyoka_system()
    batch = hy.recommended_simd_size()
    pi2 = math.pi**2
    events = [hy.t_event_batch(phi * phi - pi2), hy.t_event_batch(psi * psi - pi2)]
    return hy.taylor_adaptive_batch(sys_, np.zeros((4, batch)), tol=tol, t_events=events)


def heyoka_flip(ta, starts: np.ndarray, t_end: float):
    """Flip times and joints of ``starts`` (rows phi0, psi0) with the batch integrator ``ta``."""
    B_ = ta.batch_size
    m = starts.shape[0]
    out_t = np.full(m, np.nan)
    out_w = np.full(m, -1, dtype=np.int8)
    lane = [-1] * B_
    nxt = 0
    st = ta.state  # a writable view of the integrator's state, shape (4, batch)
    times = np.zeros(B_)

    def load(k):
        nonlocal nxt
        if nxt < m:
            lane[k] = nxt
            st[:, k] = (starts[nxt, 0], starts[nxt, 1], 0.0, 0.0)
            times[k] = 0.0
            nxt += 1
        else:  # no cell left: an idle lane, already at t_end
            lane[k] = -1
            st[:, k] = 0.0
            times[k] = t_end

    for k in range(B_):
        load(k)
    ta.set_time(times)
    ta.reset_cooldowns()
    while any(c >= 0 for c in lane):
        ta.propagate_until(t_end)
        res = ta.propagate_res
        times[:] = ta.time
        for k in range(B_):
            c = lane[k]
            if c < 0:
                continue
            outcome = int(res[k][0])
            if -10 < outcome < 0:  # terminal event -1 - i stopped the batch in this lane
                out_t[c] = times[k]
                out_w[c] = -1 - outcome
                load(k)
            elif times[k] >= t_end:
                load(k)
        ta.set_time(times)
        ta.reset_cooldowns()
    return out_t, out_w


_WORKER = {}


def _worker_init(tol):
    _WORKER["ta"] = heyoka_integrator(tol)
    heyoka_flip(_WORKER["ta"], np.array([[2.0, 2.0], [0.5, 0.3]]), 1.0)  # warm up, untimed


def _worker_run(starts):
    return heyoka_flip(_WORKER["ta"], starts, T_END)


# ----------------------------------------------------------------------------- comparison
def compare(t, w, ref_t, ref_w):
    """(max |t - ref| over cells both flip, cells with another outcome or joint)."""
    ft, fr = np.isfinite(t), np.isfinite(ref_t)
    both = ft & fr
    worst = float(np.max(np.abs(t[both] - ref_t[both]))) if both.any() else 0.0
    mismatch = int(np.count_nonzero((ft != fr) | (both & (w != ref_w))))
    over = int(np.count_nonzero(np.abs(t[both] - ref_t[both]) > 1e-3))
    return worst, mismatch, over


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--repeat", type=int, default=5, help="timed repetitions of each case (median reported)")
    ap.add_argument("--n", type=int, default=128, help="cells per side (default 128)")
    args = ap.parse_args()
    n, R = args.n, max(1, args.repeat)

    from skewpend.analysis.flipmap import flip_map
    from skewpend.numeric.ensemble import default_workers

    cores = default_workers()
    hy = heyoka_header(cores)
    have_heyoka = hy is not None
    print(f"case: {n} x {n} map, t_end = {T_END:g} s, a={A} b={B} m1={M1} m2={M2} alpha={ALPHA} g={G}, released at rest")
    print(f"repetitions: {R} (median)\n")

    p = params()
    t0 = time.perf_counter()
    first = flip_map(p, n)
    print(f"skewpend first call (flip kernel {first.stats['kernel']}, build {first.stats['kernel_build_time']:.2f} s): "
          f"{time.perf_counter() - t0:.2f} s")
    t0 = time.perf_counter()
    ref = flip_map(p, n, rtol=REF_TOL, atol=REF_TOL)
    print(f"reference: skewpend at rtol = atol = {REF_TOL:g}: {time.perf_counter() - t0:.2f} s (untimed)")
    ref_t, ref_w = ref.flip_time.ravel(), ref.which.ravel()

    starts = cells(n)
    hy_ref = None
    pool = None
    if have_heyoka:
        t0 = time.perf_counter()
        ta = heyoka_integrator(HY_TOL)
        heyoka_flip(ta, starts[:8], 1.0)
        print(f"heyoka batch integrator built from skewpend's derivation in {time.perf_counter() - t0:.2f} s (untimed)")
        t0 = time.perf_counter()
        ta_ref = heyoka_integrator(sys.float_info.epsilon)
        hy_ref = heyoka_flip(ta_ref, starts, T_END)
        print(f"second reference: heyoka at tol = machine epsilon: {time.perf_counter() - t0:.2f} s (untimed)")
        ctx = mp.get_context("spawn")
        t0 = time.perf_counter()
        pool = ctx.Pool(cores, initializer=_worker_init, initargs=(HY_TOL,))
        pool.map(_worker_run, [starts[:8]] * cores)  # every worker built and warm
        print(f"heyoka: {cores} worker processes started and warmed up in {time.perf_counter() - t0:.2f} s (untimed)")
    print(flush=True)

    times: dict[str, list[float]] = {}
    results: dict[str, tuple] = {}
    order = []

    def timed(label, fn):
        t0 = time.perf_counter()
        out = fn()
        times.setdefault(label, []).append(time.perf_counter() - t0)
        if label not in order:
            order.append(label)
        results[label] = out

    def sk(**kw):
        fm = flip_map(p, n, **kw)
        return fm.flip_time.ravel(), fm.which.ravel(), fm.stats

    def hy_threads(k):
        tas = [heyoka_integrator(HY_TOL) for _ in range(k)] if k > 1 else [ta]
        parts = np.array_split(np.arange(len(starts)), k)
        out_t = np.full(len(starts), np.nan)
        out_w = np.full(len(starts), -1, dtype=np.int8)

        def run(i):
            out_t[parts[i]], out_w[parts[i]] = heyoka_flip(tas[i], starts[parts[i]], T_END)

        def go():
            th = [threading.Thread(target=run, args=(i,)) for i in range(k)]
            for x in th:
                x.start()
            for x in th:
                x.join()
            return out_t.copy(), out_w.copy(), None

        return go

    def hy_processes():
        parts = np.array_split(starts, cores)
        got = pool.map(_worker_run, parts)
        return np.concatenate([g[0] for g in got]), np.concatenate([g[1] for g in got]), None

    sk_label = f"skewpend flip_map ({cores} workers)"
    hy_label = f"heyoka batch, {cores} processes"
    if have_heyoka:
        hy_1 = hy_threads(1)
        hy_2 = hy_threads(cores) if cores > 1 else None
    for rep in range(R):
        timed(sk_label, lambda: sk())
        if have_heyoka:
            if cores > 1:
                timed(hy_label, hy_processes)
            timed("heyoka batch, 1 thread", hy_1)
        timed("skewpend flip_map (1 worker)", lambda: sk(workers=1))
        if have_heyoka and cores > 1:
            timed(f"heyoka batch, {cores} threads (GIL)", hy_2)
        timed(f"skewpend, shortcuts off ({cores} workers)", lambda: sk(shortcuts=False))
        print(f"  rep {rep + 1}/{R}: " + "  ".join(f"{k.split(' (')[0] if k.startswith('skewpend flip') else k}: {v[-1]:.3f} s"
                                             for k, v in times.items() if k in (sk_label, hy_label)), flush=True)
    if pool is not None:
        pool.close()
        pool.join()

    med = {k: statistics.median(v) for k, v in times.items()}
    sk_med = med[sk_label]
    print()
    print(f"{'method':<40} {'median s':>9} {'min s':>7} {'x skewpend':>10}  {'max|dt| vs ref':>14} {'>1e-3 s':>8} {'outcome':>8}")
    print("-" * 104)
    for label in order:
        t, w, _ = results[label]
        worst, mismatch, over = compare(t, w, ref_t, ref_w)
        print(f"{label:<40} {med[label]:>9.3f} {min(times[label]):>7.3f} {med[label] / sk_med:>10.2f}  "
              f"{worst:>14.2e} {over:>8d} {mismatch:>8d}")
    print("ref: skewpend at 1e-13; '>1e-3 s': cells off by more than 1e-3 s; 'outcome': cells with another "
          "outcome (flip or not) or joint")
    st = results[sk_label][2]
    print(f"\nskewpend's default run: {st['integrated']} of {st['cells']} cells integrated, {st['skipped_energy']} "
          f"skipped by the energy bound (barrier {st['energy_barrier']:.4f} J), {st['mirrored']} by symmetry; "
          f"{st['steps']} accepted + {st['rejected']} rejected steps; {st['chunks']} chunks of {st['chunk_size']}")
    if hy_ref is not None:
        worst, mismatch, over = compare(ref_t, ref_w, hy_ref[0], hy_ref[1])
        print(f"the two references (skewpend 1e-13, heyoka at machine epsilon): max |dt| {worst:.2e} s, "
              f"{mismatch} outcome mismatches")
        worst, mismatch, over = compare(results[sk_label][0], results[sk_label][1], hy_ref[0], hy_ref[1])
        print(f"skewpend default vs heyoka at machine epsilon: max |dt| {worst:.2e} s, {mismatch} outcome mismatches")
        t, w, _ = results[hy_label if cores > 1 else "heyoka batch, 1 thread"]
        worst, mismatch, over = compare(results[sk_label][0], results[sk_label][1], t, w)
        print(f"skewpend default vs heyoka 1e-8 (the timed runs): max |dt| {worst:.2e} s over cells both flip, "
              f"{mismatch} outcome mismatches")
        best_hy = min(v for k, v in med.items() if k.startswith("heyoka"))
        ratio = best_hy / sk_med
        print(f"\ngoal (issue 9): skewpend at least as fast as heyoka's batch mode (best heyoka configuration: "
              f"{best_hy:.3f} s): {'PASS' if ratio >= GOAL else 'FAIL'} -- skewpend is {ratio:.1f}x faster"
              f" (ambition {AMBITION:g}x: {'met' if ratio >= AMBITION else 'not met'}; "
              f"issue 28's goal {GOAL_28:g}x: {'met' if ratio >= GOAL_28 else 'NOT met'})")
    print(f"load average at the end: {os.getloadavg()[0]:.2f}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
