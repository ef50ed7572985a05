"""Region of attraction: skewpend's region_of_attraction against heyoka.py's batch mode, side by side.

Case: a=1 b=0.8 m1=1 m2=0.7 alpha=30 deg g=9.81, the LQR about up-up with both joints actuated and
|u_j| <= 10 N m (``skewpend.lqr(params, "up-up", "both", umax=10)``: gain K (2 x 4), estimate
``dx^T P dx < rho``), the ``--n`` x ``--n`` map (default 256 x 256) of starts (phi0, psi0) = the
cell centres of the target +- pi in both angles, released at rest, t_end = 10 s.  The closed loop:
``M(q) q'' = f(q, q') + u`` with ``u = clip(-K dx, -10, 10)`` per joint, ``dx = x - x*`` with its
two angle components wrapped to (-pi, pi]; a start is *captured* at the first time
``dx^T P dx < rho`` (its integration stops there), else it runs to t_end.

* skewpend: ``region_of_attraction(params, n=n, design=design, t_end=10, workers=<cores>)`` at its
  defaults (DOP853, rtol = atol = 1e-8, the inputs inside the compiled code: ``sp_capture_lanes``,
  eight starts side by side in SIMD lanes on the flip map's trigonometry-free state, each step
  stopped at the law's switches -- saturation kinks predicted, wrap jumps on rejection);
  warm (the kernel is compiled or loaded by an untimed small map first).  It locates the entry
  within the step that enters (on DOP853's dense output).
* heyoka.py: ``taylor_adaptive_batch`` (batch size = ``hy.recommended_simd_size()``, tol 1e-8 --
  heyoka has one tolerance, relative and absolute).  The equations are NOT typed: they are
  skewpend's derivation with the torques left symbolic (``Parameters(tau1=None, tau2=None)``:
  SymPy ``M(q)``, ``f(q, q', tau)``), converted with ``hy.from_sympy`` with ``tau1 -> u1(x)``,
  ``tau2 -> u2(x)`` substituted as heyoka expressions (rationals and constants turned into doubles
  first, which it requires), ``q'' = M^-1 f`` solved as in skewpend; checked against skewpend's
  closed-loop right-hand side at random states (untimed).  The wrap is ``atan2(sin(d), cos(d))``
  (skewpend's fmod wrap is the same function but at exactly +-pi, which no cell centre hits), the
  saturation ``clip(u, -U, U) = relu(u + U) - relu(u - U) - U``.  The capture is the terminal
  event ``v(x) - rho = 0``, v = dx^T P dx with the wrapped dx, direction negative (heyoka locates
  the crossing, a root of the step's Taylor polynomial); a start already inside at t = 0 (no
  crossing to detect) is recorded with time 0 by the harness, as skewpend does.  A terminal event
  in one lane stops the whole batch (heyoka's batch semantics), so the harness records the lane's
  capture, refills the lane with the next start (its own time reset to 0, cooldowns reset) and
  propagates on: no lane idles while starts remain.  heyoka's ``propagate_until`` holds the GIL,
  so "both cores" means one worker process per core, each with its own batch integrator over
  every <cores>-th start (interleaved, so that both get a similar mix of quick captures and full
  10 s runs); the workers are built and warmed up untimed, the timed part is the propagation of
  the map, dispatched to them and gathered back.  heyoka's JIT compilation is timed on its own
  (cold, and from heyoka's on-disk cache) and is not in the ratio.

heyoka and the non-smooth law.  The law has kinks (the saturation) and jumps (the wrap, where an
angle is opposite its target), and a Taylor step does not see them: the Taylor coefficients of
``relu`` and ``atan2(sin, cos)`` at the start of a step are those of the branch it starts on, so
the step's polynomial carries that branch across the switch, and the error estimate (from the
last coefficients) does not notice -- the rest of the step integrates the wrong branch, whatever
the tolerance (DOP853's error control does see a switch: rejected steps shrink around it, and
skewpend cuts its steps at the switches besides).  So heyoka is timed twice:

* "heyoka batch": the law as written above (what a user would write first);
* "heyoka batch + switch events": the same integrator with four more terminal events at the
  switches -- ``raw_r^2 - U_r^2`` (raw = -K dx, the saturation kinks of joint r) and
  ``cos((q_i - q_i*) / 2)`` (zero exactly where the wrap of angle i jumps) -- so that no step
  crosses one: at a switch event the harness moves the lane NUDGE = 1e-11 s on along the step's
  polynomial (the event leaves it on the switch, to rounding, where the next step could take
  either branch's coefficients) and propagates on; a start with more than MAX_SWITCHES switch
  events would be given up (a sliding mode; skewpend's max_steps plays that part).  This is the
  heyoka run that solves the same problem to the tolerance.

The agreement with skewpend of each heyoka map is printed: the cells where both say captured /
both not, where only one does, and the |difference| of the capture times where both capture;
``--reference`` adds skewpend at rtol = atol = 1e-11 (untimed) and compares every map with it.

skewpend and heyoka runs are interleaved (rep by rep) so that both see the same load; the best
(minimum) of ``--repeat`` reps is reported, the median alongside.  The issue's goal for skewpend:
the 256 x 256 map over 10 s in <= 10 s (PASS/FAIL is printed for n = 256).

Run:  python benchmarks/bench_roa.py [--n 256] [--repeat 1] [--reference]
      heyoka is optional (pip install heyoka): without it only skewpend is measured.
"""

from __future__ import annotations

import argparse
import math
import multiprocessing as mp
import os
import statistics
import sys
import time

import numpy as np

from _common import heyoka_first_order, heyoka_header, compile_times  # benchmarks/ is on sys.path when run

A, B, M1, M2, ALPHA_DEG, G = 1.0, 0.8, 1.0, 0.7, 30.0, 9.81
TARGET, ACTUATED, UMAX = "up-up", "both", 10.0
T_END = 10.0
TOL = 1e-8  # skewpend rtol = atol, heyoka tol
REF_TOL = 1e-11
NUDGE = 1e-11  # s past a switch event (heyoka with switch events)
MAX_SWITCHES = 10_000  # switch events of one start before it is given up (a sliding mode)
GOAL_N, GOAL_S = 256, 10.0  # the issue: the 256 x 256 map over 10 s in <= 10 s


def params():
    import skewpend

    return skewpend.Parameters(a=A, b=B, m1=M1, m2=M2, alpha=math.radians(ALPHA_DEG), g=G)


def design(p):
    import skewpend

    return skewpend.lqr(p, TARGET, ACTUATED, umax=UMAX)


def law(d):
    """The design's numbers as plain arrays (picklable for the workers): K, x*, P, rho, umax."""
    return (np.asarray(d.gain, dtype=float), np.asarray(d.linearization.target, dtype=float),
            np.asarray(d.P, dtype=float), float(d.rho), tuple(float(u) for u in d.umax))


def cells(xs: np.ndarray, n: int) -> np.ndarray:
    """The starts of the map, (n * n, 4), row-major (phi0 along axis 0), as region_of_attraction's."""
    from skewpend.analysis.flipmap import cell_centres

    cx = cell_centres(xs[0] - math.pi, xs[0] + math.pi, n)
    cy = cell_centres(xs[1] - math.pi, xs[1] + math.pi, n)
    out = np.tile(xs, (n * n, 1))
    out[:, 0] = np.repeat(cx, n)
    out[:, 1] = np.tile(cy, n)
    return out


def lyap_value(x: np.ndarray, xs: np.ndarray, P: np.ndarray) -> np.ndarray:
    """v = dx^T P dx at states x (m, 4), the angles of dx wrapped."""
    dx = x - xs
    dx[:, :2] = np.arctan2(np.sin(dx[:, :2]), np.cos(dx[:, :2]))
    return np.einsum("mi,ij,mj->m", dx, P, dx)


# ----------------------------------------------------------------------------- heyoka
def heyoka_system(p, K, xs, umax):
    """The closed loop for heyoka from skewpend's derivation, the torques symbolic and replaced by
    u(x): (equations, variables, wrapped dx, the unsaturated inputs -K dx)."""
    import heyoka as hy

    import skewpend
    from skewpend.symbolic.derivation import SYMBOLS

    eom = skewpend.derive(p.replace(c1=0.0, c2=0.0, tau1=None, tau2=None))
    names = ("phi", "psi", "dphi", "dpsi")
    hv = hy.make_vars(*names)
    phi, psi, dphi, dpsi = hv
    dx = [hy.atan2(hy.sin(phi - xs[0]), hy.cos(phi - xs[0])), hy.atan2(hy.sin(psi - xs[1]), hy.cos(psi - xs[1])),
          dphi - xs[2], dpsi - xs[3]]
    raws, u = [], []
    for r in range(2):
        raw = hy.sum([-float(K[r, j]) * dx[j] for j in range(4)])
        U = float(umax[r])
        raws.append(raw)
        u.append(hy.relu(raw + U) - hy.relu(raw - U) - U)  # clip(raw, -U, U)
    s_dict = {SYMBOLS[nm]: v for nm, v in zip(names, hv)}
    s_dict[SYMBOLS["tau1"]], s_dict[SYMBOLS["tau2"]] = u

    if not {SYMBOLS["tau1"], SYMBOLS["tau2"]} <= eom.forcing.free_symbols:
        raise ValueError("the derivation's forcing does not contain the torques tau1, tau2")
    sys_ = heyoka_first_order(eom, s_dict, hv)
    return sys_, hv, dx, raws


def heyoka_integrator(p, K, xs, P, rho, umax, tol, switches=False):
    """The batch integrator: event 0 the capture; with ``switches`` also events 1-4 at the law's
    switches (saturation kinks raw_r^2 = U_r^2, wrap jumps cos((q_i - q_i*) / 2) = 0)."""
    import heyoka as hy

    sys_, hv, dx, raws = heyoka_system(p, K, xs, umax)
    v = hy.sum([float(P[i, j]) * dx[i] * dx[j] for i in range(4) for j in range(4)])
    events = [hy.t_event_batch(v - float(rho), direction=hy.event_direction.negative)]
    if switches:
        events += [hy.t_event_batch(raw * raw - float(umax[r]) ** 2) for r, raw in enumerate(raws)]
        events += [hy.t_event_batch(hy.cos(0.5 * (q - float(xs[i])))) for i, q in enumerate(hv[:2])]
    batch = hy.recommended_simd_size()
    return hy.taylor_adaptive_batch(sys_, np.zeros((4, batch)), tol=tol, t_events=events)


def heyoka_capture(ta, starts: np.ndarray, t_end: float, xs, P, rho):
    """Capture times (NaN: not by t_end) of ``starts`` (m, 4) with the batch integrator ``ta``; the
    batch's steps, the batch's stops, and the starts given up (a non-finite state, or more than
    MAX_SWITCHES switch events: a sliding mode)."""
    import heyoka as hy

    B_ = ta.batch_size
    m = starts.shape[0]
    out = np.full(m, np.nan)
    inside = lyap_value(starts.copy(), xs, P) < rho
    out[inside] = 0.0  # captured at the start: no crossing for the event to find
    queue = iter(np.flatnonzero(~inside).tolist())
    lane = [-1] * B_
    nsw = [0] * B_
    st = ta.state  # a writable view of the integrator's state, shape (4, batch)
    times = np.zeros(B_)
    steps = stops = failed = 0
    err_nf = int(hy.taylor_outcome.err_nf_state)

    def load(k):
        c = next(queue, -1)
        lane[k], nsw[k] = c, 0
        if c >= 0:
            st[:, k] = starts[c]
            times[k] = 0.0
        else:  # no start left: an idle lane, already at t_end
            st[:, k] = xs
            times[k] = t_end

    for k in range(B_):
        load(k)
    ta.set_time(times)
    ta.reset_cooldowns()
    while any(c >= 0 for c in lane):
        ta.propagate_until(t_end)
        res = ta.propagate_res
        steps += max(int(r[3]) for r in res)
        stops += 1
        times[:] = ta.time
        switched = []
        for k in range(B_):
            c = lane[k]
            if c < 0:
                continue
            outcome = int(res[k][0])
            if outcome == -1:  # the capture event stopped the batch in this lane
                out[c] = times[k]
                load(k)
            elif -10 < outcome < -1:  # a switch of the law (events 1-4)
                nsw[k] += 1
                if nsw[k] > MAX_SWITCHES:
                    failed += 1
                    load(k)
                else:
                    switched.append(k)
            elif times[k] >= t_end:
                load(k)
            elif outcome == err_nf:
                failed += 1
                load(k)
        if switched:
            # the lane stopped on the switch, to rounding: move it NUDGE s past it along the step's
            # polynomial, so that the next step's Taylor coefficients are those of the new branch
            tt = times.copy()
            tt[switched] += NUDGE
            y = ta.update_d_output(tt)
            for k in switched:
                st[:, k] = y[:, k]
                times[k] = tt[k]
        ta.set_time(times)
        ta.reset_cooldowns()
    return out, steps, stops, failed


_WORKER = {}


def _worker_init(p, lw, tol):
    K, xs, P, rho, umax = lw
    _WORKER.update(xs=xs, P=P, rho=rho)
    for sw in (False, True):
        _WORKER[sw] = heyoka_integrator(p, K, xs, P, rho, umax, tol, switches=sw)
        _worker_run((np.array([[xs[0] + 2.0, xs[1] + 2.0, 0.0, 0.0], [xs[0] + 0.3, xs[1], 0.0, 0.0]]), sw), 1.0)


def _worker_run(job, t_end=T_END):
    starts, sw = job
    w = _WORKER
    return heyoka_capture(w[sw], starts, t_end, w["xs"], w["P"], w["rho"])


def check_rhs(p, d, lw) -> float:
    """max |heyoka rhs - skewpend's closed-loop rhs| / (1 + |rhs|) at random states (untimed sanity)."""
    import heyoka as hy

    from skewpend.numeric.kernels import kernel_module, parameter_vector

    K, xs, P, rho, umax = lw
    sys_, hv, _, _ = heyoka_system(p, K, xs, umax)
    cf = hy.cfunc([rhs for _, rhs in sys_], vars=list(hv))
    rng = np.random.default_rng(1)
    y = np.column_stack([rng.uniform(-4, 4, (2000, 2)), rng.uniform(-6, 6, (2000, 2))])
    ours = cf(np.ascontiguousarray(y.T)).T
    ref = d.controller().closed_loop(kernel_module(p), parameter_vector(p), np.zeros(len(y)), y)
    return float(np.max(np.abs(ours - ref) / (1 + np.abs(ref))))


# ----------------------------------------------------------------------------- comparison
def agreement(sk_t, sk_out, hy_t):
    """Counts and capture-time differences of two classifications (skewpend's outcome: 1/0/-1)."""
    sk_cap, sk_fail, hy_cap = sk_out == 1, sk_out == -1, np.isfinite(hy_t)
    both = sk_cap & hy_cap
    dt = np.abs(sk_t[both] - hy_t[both])
    return {
        "cells": sk_t.size, "both": int(both.sum()), "neither": int((~sk_cap & ~sk_fail & ~hy_cap).sum()),
        "sk_only": int((sk_cap & ~hy_cap).sum()), "hy_only": int((~sk_cap & ~sk_fail & hy_cap).sum()),
        "sk_failed": int(sk_fail.sum()), "sk_failed_hy_cap": int((sk_fail & hy_cap).sum()),
        "agree": float((both.sum() + (~sk_cap & ~sk_fail & ~hy_cap).sum()) / sk_t.size),
        "med_dt": float(np.median(dt)) if dt.size else math.nan,
        "p95_dt": float(np.percentile(dt, 95)) if dt.size else math.nan,
        "max_dt": float(dt.max()) if dt.size else math.nan,
        "over_01": int((dt > 0.1).sum()),
    }


def print_agreement(title, a, names=("skewpend", "heyoka")):
    s, h = names
    n = a["cells"]
    print(f"{title}")
    print(f"  same classification        {a['both'] + a['neither']:>7d} of {n} cells = {100 * a['agree']:.2f} %  "
          f"(both captured {a['both']}, both not {a['neither']})")
    print(f"  captured by {s} only{'':<{12 - len(s)}}{a['sk_only']:>7d}   by {h} only {a['hy_only']}"
          + (f"   {s} failed {a['sk_failed']} (of which {h} captured {a['sk_failed_hy_cap']})" if a["sk_failed"] else ""))
    print(f"  |capture time difference|  median {a['med_dt']:.2e} s, 95th percentile {a['p95_dt']:.2e} s, "
          f"max {a['max_dt']:.2e} s; {a['over_01']} cells > 0.1 s  (over the {a['both']} cells both capture)")


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--repeat", type=int, default=1, help="timed repetitions of each method, interleaved (min reported)")
    ap.add_argument("--n", type=int, default=256, help="cells per side (default 256)")
    ap.add_argument("--reference", action="store_true",
                    help=f"also compare every map with skewpend at rtol = atol = {REF_TOL:g} (untimed)")
    args = ap.parse_args()
    n, R = args.n, max(1, args.repeat)

    from skewpend.analysis.roa import region_of_attraction
    from skewpend.numeric.ensemble import default_workers

    cores = default_workers()
    hy = heyoka_header(cores, sympy=True)
    have_heyoka = hy is not None
    p = params()
    d = design(p)
    lw = law(d)
    K, xs, P, rho, umax = lw
    print(f"case: {n} x {n} region of attraction, t_end = {T_END:g} s, a={A} b={B} m1={M1} m2={M2} alpha={ALPHA_DEG:g} deg "
          f"g={G}; LQR about {TARGET}, {ACTUATED} joints, |u| <= {UMAX:g} N m, rho = {rho:.4f}")
    print(f"  starts: (phi0, psi0) = cell centres of x* +- pi, at rest; tolerance {TOL:g} on every side "
          f"(skewpend DOP853 rtol = atol, heyoka tol)")
    print(f"repetitions: {R}, interleaved (min reported, median alongside)\n")

    t0 = time.perf_counter()
    region_of_attraction(p, n=8, design=d, t_end=T_END, workers=cores)
    print(f"skewpend warm-up (kernel compiled or loaded, an 8 x 8 map): {time.perf_counter() - t0:.2f} s (untimed)")

    starts = cells(xs, n)
    pool = None
    jit = {}
    if have_heyoka:
        err = check_rhs(p, d, lw)
        print(f"heyoka closed-loop rhs vs skewpend's (sp_rhs_ctl_many) at 2000 random states: max rel. diff {err:.1e}")
        for sw in (False, True):
            jit[sw] = compile_times(lambda: heyoka_integrator(p, K, xs, P, rho, umax, TOL, switches=sw))[:2]
            print(f"heyoka batch integrator JIT{' (with switch events)' if sw else ''}: {jit[sw][0]:.2f} s cold, "
                  f"{jit[sw][1]:.2f} s from heyoka's on-disk cache (untimed)")
        ctx = mp.get_context("spawn")
        t0 = time.perf_counter()
        pool = ctx.Pool(cores, initializer=_worker_init, initargs=(p, lw, TOL))
        pool.map(_worker_run, [(starts[:8], False)] * cores)  # every worker built and warm
        print(f"heyoka: {cores} worker processes started and warmed up in {time.perf_counter() - t0:.2f} s (untimed)")
    print(flush=True)

    times: dict[str, list[float]] = {}
    results: dict[str, tuple] = {}

    def timed(label, fn):
        t0 = time.perf_counter()
        out = fn()
        times.setdefault(label, []).append(time.perf_counter() - t0)
        results[label] = out

    def sk():
        return region_of_attraction(p, n=n, design=d, t_end=T_END, workers=cores)

    def hy_processes(sw):
        idx = [np.arange(k, len(starts), cores) for k in range(cores)]
        got = pool.map(_worker_run, [(starts[i], sw) for i in idx])
        out = np.full(len(starts), np.nan)
        for i, g in zip(idx, got):
            out[i] = g[0]
        return (out,) + tuple(sum(g[j] for g in got) for j in (1, 2, 3))

    sk_label = f"skewpend region_of_attraction, {cores} workers"
    hy_label = f"heyoka batch, {cores} processes"
    hs_label = f"heyoka batch + switch events, {cores} proc."
    for rep in range(R):
        timed(sk_label, sk)
        if have_heyoka:
            timed(hy_label, lambda: hy_processes(False))
            timed(hs_label, lambda: hy_processes(True))
        short = {sk_label: "skewpend", hy_label: "heyoka", hs_label: "heyoka + switch events"}
        print(f"  rep {rep + 1}/{R}: " + "  ".join(f"{short[k]}: {v[-1]:.3f} s" for k, v in times.items()), flush=True)
    if pool is not None:
        pool.close()
        pool.join()

    r = results[sk_label]
    sk_t, sk_out = r.capture_time.ravel(), r.outcome.ravel()
    assert np.array_equal(np.repeat(r.x0, n), starts[:, 0]) and np.array_equal(np.tile(r.y0, n), starts[:, 1]), \
        "the benchmark's starts differ from region_of_attraction's cells"
    best = {k: min(v) for k, v in times.items()}
    med = {k: statistics.median(v) for k, v in times.items()}
    print()
    print(f"{'method':<44} {'min s':>8} {'median s':>9} {'captured':>9}  work")
    print("-" * 110)
    st = r.stats
    print(f"{sk_label:<44} {best[sk_label]:>8.3f} {med[sk_label]:>9.3f} {100 * r.captured_fraction:>8.2f}%  "
          f"{st['steps']} DOP853 steps (accepted + rejected), {st['failed']} failed cells")
    if have_heyoka:
        for label, sw in ((hy_label, False), (hs_label, True)):
            t, steps, stops, failed = results[label]
            print(f"{label:<44} {best[label]:>8.3f} {med[label]:>9.3f} {100 * np.isfinite(t).mean():>8.2f}%  "
                  f"{steps} batch steps x {hy.recommended_simd_size()} lanes, {stops} batch stops, {failed} given up")
        for sw in (False, True):
            label = f"heyoka JIT{' + switch events' if sw else ''}, cold (untimed)"
            print(f"{label:<44} {jit[sw][0]:>8.3f} {'':>9} {'':>9}  from heyoka's on-disk cache {jit[sw][1]:.3f} s")
        print("\nratio skewpend / heyoka (min times)")
        for label in (hy_label, hs_label):
            ratio = best[sk_label] / best[label]
            print(f"  vs {label:<44} {ratio:6.3f}  -- "
                  + (f"skewpend {1 / ratio:.2f}x faster" if ratio < 1 else f"heyoka {ratio:.2f}x faster")
                  + f"   (medians {med[sk_label] / med[label]:.3f})")
        print()
        print_agreement(f"agreement: skewpend vs {hy_label} (the law as written)", agreement(sk_t, sk_out, results[hy_label][0]))
        print_agreement(f"agreement: skewpend vs {hs_label}", agreement(sk_t, sk_out, results[hs_label][0]))
    if args.reference:
        t0 = time.perf_counter()
        ref = region_of_attraction(p, n=n, design=d, t_end=T_END, workers=cores, rtol=REF_TOL, atol=REF_TOL)
        print(f"\nreference: skewpend at rtol = atol = {REF_TOL:g}: {time.perf_counter() - t0:.2f} s (untimed), "
              f"{ref.stats['failed']} failed cells")
        rt, ro = ref.capture_time.ravel(), ref.outcome.ravel()
        print_agreement(f"skewpend {TOL:g} vs the reference", agreement(rt, ro, np.where(sk_out == 1, sk_t, np.nan)),
                        ("reference", "skewpend"))
        if have_heyoka:
            for label in (hy_label, hs_label):
                print_agreement(f"{label} vs the reference", agreement(rt, ro, results[label][0]), ("reference", "heyoka"))
    if n == GOAL_N:
        ok = best[sk_label] <= GOAL_S
        print(f"\ngoal (the issue): {GOAL_N} x {GOAL_N} over {T_END:g} s in <= {GOAL_S:g} s: skewpend {best[sk_label]:.2f} s "
              f"(min of {R}, {cores} workers)  {'PASS' if ok else 'FAIL'}")
    else:
        print(f"\n(goal {GOAL_N} x {GOAL_N} in <= {GOAL_S:g} s: not judged at n = {n})")
    print(f"load average at the end: {os.getloadavg()[0]:.2f}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
