"""The Taylor method's step rule over several motions: skewpend's rule (step exponent L by tolerance
band, ``kernels.TAYLOR_L_BANDS``) against heyoka's L = 2, each against heyoka.py, at equal error.

Why: ``simulate(method="taylor")`` takes larger steps at a higher order than heyoka.py's rule at
tolerances down to 1e-11 (L = 1.5, then 1.75, where heyoka.py's Jorba-Zou rule has L = 2); the
bands were chosen on these five motions, not on bench_precision's case alone.  This script shows,
per motion, the time ratio to heyoka.py at equal error, decade by decade, for skewpend's rule and for
skewpend with heyoka's rule (the same compiled series: only L and the order differ).

Motions (all undamped, 10-20 s; the error is max_i |y_i(T) - y_ref,i(T)| at the end):

* ``chaotic 5 s`` / ``chaotic 20 s``: bench_precision's case (issue 3: a=1, b=0.8, m1=1, m2=0.7,
  alpha=0.6; y0 = (1.2, -0.8, 0, 0)), errors at 5 s and at 20 s, times of the 20 s run;
* ``regular``: the same rods, y0 = (0.3, -0.2, 0, 0), 20 s (small swings);
* ``skewed``: a=0.5, b=1.1, m1=2, m2=0.4, alpha=1.2, y0 = (2, 1, 0, 0.5), 10 s;
* ``spinning``: a=b=1, m1=m2=1, alpha=0.3, y0 = (0, 0, 9, -3), 10 s (the rods go round).

Reference: heyoka.py in quadruple precision (real128, tol 1e-32) on the same double-precision
equations (skewpend's derivation with these parameters, via ``hy.from_sympy``).  Tolerances 1e-3 ...
1e-14 for every method; timing: ``--repeat`` rounds, in each round every method and tolerance (the
three side by side per tolerance); medians; fronts and log-log interpolation as bench_precision.

Run:  python benchmarks/bench_taylor_rule.py [--repeat 9]
"""

from __future__ import annotations

import argparse
import os
import statistics
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
from _common import heyoka_first_order, heyoka_header  # noqa: E402
from bench_precision import front, max_error, reference_system, time_at  # noqa: E402

NAMES = ("phi", "psi", "dphi", "dpsi")
RODS = dict(a=1.0, b=0.8, m1=1.0, m2=0.7, alpha=0.6, g=9.81)
MOTIONS = {  # name: (parameters, y0, run time, error time)
    "chaotic 5 s": (RODS, (1.2, -0.8, 0.0, 0.0), 20.0, 5.0),
    "chaotic 20 s": (RODS, (1.2, -0.8, 0.0, 0.0), 20.0, 20.0),
    "regular": (RODS, (0.3, -0.2, 0.0, 0.0), 20.0, 20.0),
    "skewed": (dict(a=0.5, b=1.1, m1=2.0, m2=0.4, alpha=1.2, g=9.81), (2.0, 1.0, 0.0, 0.5), 10.0, 10.0),
    "spinning": (dict(a=1.0, b=1.0, m1=1.0, m2=1.0, alpha=0.3, g=9.81), (0.0, 0.0, 9.0, -3.0), 10.0, 10.0),
}
TOLS = tuple(10.0**-k for k in range(3, 15))
TARGETS = tuple(10.0**-k for k in range(5, 13))
HEYOKA_RULE = ((0.0, 2.0),)


def reference(eom, y0, t):
    import heyoka as hy
    import mpmath

    ta = hy.taylor_adaptive(reference_system(113, eom=eom), [hy.real128(x) for x in y0], tol=hy.real128(1e-32),
                            compact_mode=True, fp_type=hy.real128)
    ta.propagate_until(hy.real128(t))
    with mpmath.workprec(200):
        return [mpmath.mpf(str(v)) for v in ta.state]


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--repeat", type=int, default=9, help="interleaved rounds (median)")
    args = ap.parse_args()
    hy = heyoka_header(len(os.sched_getaffinity(0)), sympy=True)
    if hy is None:
        sys.exit("heyoka.py is not installed (pip install heyoka): nothing to compare with")
    from skewpend import Parameters, derive, simulate
    from skewpend.numeric import kernels, simulation
    from skewpend.symbolic.derivation import SYMBOLS

    rule = kernels.TAYLOR_L_BANDS
    print(f"skewpend's bands (lowest rtol, L): {rule}; heyoka's rule: L = 2 at every tolerance\n")
    rows = []
    for name, (kw, y0, t_run, t_err) in MOTIONS.items():
        P = Parameters(**kw)
        eom = derive(P)
        hv = hy.make_vars(*NAMES)
        hsys = heyoka_first_order(eom, {SYMBOLS[n]: v for n, v in zip(NAMES, hv)}, hv)
        ref = reference(eom, y0, t_err)
        y0a = np.array(y0)

        def hey(tol, t_end, ta_of={}):
            ta = ta_of.get(tol)
            if ta is None:
                ta = ta_of[tol] = hy.taylor_adaptive(hsys, list(y0), tol=tol)
            ta.time = 0.0
            ta.state[:] = y0a
            ta.propagate_until(t_end)
            return ta.state.copy()

        # skewpend with a rule: its own Parameters object each (simulate keeps (order, L) per rtol)
        Ps = {"skewpend": P, "heyoka's rule": Parameters(**kw)}

        def sk(which, tol, t_end):
            kernels.TAYLOR_L_BANDS = rule if which == "skewpend" else HEYOKA_RULE
            try:
                return simulate(Ps[which], y0, t_end, method="taylor", rtol=tol, atol=tol).y[-1]
            finally:
                kernels.TAYLOR_L_BANDS = rule

        methods = {("heyoka", tol): (lambda tol=tol, t=t_run: hey(tol, t)) for tol in TOLS}
        for which in Ps:
            for tol in TOLS:
                methods[(which, tol)] = lambda which=which, tol=tol, t=t_run: sk(which, tol, t)
        err = {}
        for (who, tol) in methods:
            y = hey(tol, t_err) if who == "heyoka" else sk(who, tol, t_err)
            err[who, tol] = max_error(y, ref)
        times = {k: [] for k in methods}
        order = [(w, tol) for tol in TOLS for w in ("skewpend", "heyoka's rule", "heyoka")]
        for key in order:
            methods[key]()
        for _ in range(args.repeat):
            for key in order:
                t0 = time.perf_counter()
                methods[key]()
                times[key].append(time.perf_counter() - t0)
        med = {k: statistics.median(v) for k, v in times.items()}
        fh = front([(err["heyoka", t], med["heyoka", t]) for t in TOLS])
        line = {}
        for who in Ps:
            fs = front([(err[who, t], med[who, t]) for t in TOLS])
            ratios = []
            for e in TARGETS:
                a, b = time_at(fs, e), time_at(fh, e)
                ratios.append(None if a is None or b is None else a / b)
            line[who] = ratios
        rows.append((name, line))
        simulation._PREPARED.clear()

    head = "  ".join(f"{e:7.0e}" for e in TARGETS)
    print(f"time / heyoka.py's time at equal error (-: an error one of the fronts does not reach); {args.repeat} rounds")
    print(f"{'motion':14s} {'rule':14s} {head}   max")
    for name, line in rows:
        for who, ratios in line.items():
            got = [r for r in ratios if r is not None]
            cells = "  ".join(f"{r:7.2f}" if r is not None else f"{'-':>7s}" for r in ratios)
            print(f"{name:14s} {who:14s} {cells}   {max(got):.2f}" if got else f"{name:14s} {who:14s} {cells}")
    for who in ("skewpend", "heyoka's rule"):
        allr = [r for _, line in rows for r in line[who] if r is not None]
        print(f"all motions, {who:14s}: max {max(allr):.2f}, median {statistics.median(allr):.2f}, "
              f"mean {statistics.fmean(allr):.2f} ({len(allr)} errors)")
    print(f"load avg    {' '.join(f'{x:.2f}' for x in os.getloadavg())} (1, 5, 15 min) at end")


if __name__ == "__main__":
    main()
