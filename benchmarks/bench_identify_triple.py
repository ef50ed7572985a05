"""The real triple pendulum (issue 38): skewpend.identify on the free swing of Kaheman et al. (2023)'s
triple pendulum (data/kaheman2023-triple: 22 fitting pieces of 1.54 s, 4 held out, 1 kHz) beside the
authors' own model.

1. The fit from the authors' published model as params0 (a chain of three links; it supplies the masses,
   the overall scale and the start), the default protocol (issue 53: the output error in the absolute angles
   the data measured, each 1.54 s piece one shooting segment): the 12 base parameters, the held-out angle RMS
   (each held-out piece simulated from its first measured state over its 1.54 s; median over the pieces) of
   the fit and of the authors' model under the same protocol -- in the data's absolute angles (each arm's
   from the vertical, the authors' state) and in skewpend's joint angles -- and the time of the whole
   ``identify()`` call, warm (best of ``--repeat``) and in a fresh process with an empty kernel cache
   (``--cold``: the shooting and the chain kernels compiled).
2. The same over the segment length (0.5, 1.0, 1.6 s: one segment a piece) and the angles the output
   error measures (``angles="relative"`` / ``"absolute"``).

3. ``--coverage SEEDS``: the intervals' coverage -- the authors' model as the truth, free swings from the
   22 fitting pieces' first states (1.54 s at 1 kHz, angles only, white noise ``--noise`` rad), fitted from
   a wrong start (masses x1.1, damping x1.5) over SEEDS noise seeds: how often each ratio's 95 % interval
   covers the truth's ratio.

The goals: issue 38, a held-out median angle RMS <= 0.0028 rad in the joint angles and the whole fit <= 30 s on
2 cores; issue 53, <= 0.00270 rad in the absolute angles (the authors' model 0.00278), the joint-angle figure no
worse than 0.00247.

    python benchmarks/bench_identify_triple.py [--repeat 3] [--cold] [--coverage 20] [--noise 5e-4]
"""

from __future__ import annotations

import argparse
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, os.path.dirname(__file__))
from _common import cpu_model, version  # noqa: E402

ROOT = Path(__file__).resolve().parent.parent
DATA = ROOT / "data" / "kaheman2023-triple"


def absolute_median(chain, pieces) -> float:
    from skewpend.analysis.identify import predict_piece

    rms = []
    for p in pieces:
        e = np.cumsum(predict_piece(chain, p) - np.asarray(p.q), axis=1)
        rms.append(float(np.sqrt(np.mean(e**2))))
    return float(np.median(rms))


def joint_median(chain, pieces) -> float:
    from skewpend.analysis.identify import predict_piece

    return float(np.median([np.sqrt(np.mean((predict_piece(chain, p) - np.asarray(p.q)) ** 2)) for p in pieces]))


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--repeat", type=int, default=3)
    ap.add_argument("--cold", action="store_true", help="also time a fresh process with an empty kernel cache")
    ap.add_argument("--coverage", type=int, default=0, help="noise seeds of the intervals' coverage check (0: none)")
    ap.add_argument("--noise", type=float, default=5e-4, help="the coverage check's angle noise [rad]")
    args = ap.parse_args()

    import skewpend
    from skewpend.analysis.measurements import kaheman_published_chain

    print(f"# {cpu_model()}; skewpend {version('skewpend')}, casadi {version('casadi')}")
    fit = skewpend.Measurements.from_kaheman(DATA, which="fit")
    val = skewpend.Measurements.from_kaheman(DATA, which="validation")
    authors = kaheman_published_chain(DATA)
    skewpend.identify(fit, authors, validation=val, bootstrap=0)  # warm: the kernels compiled once
    times = []
    for _ in range(args.repeat):
        t0 = time.perf_counter()
        result = skewpend.identify(fit, authors, validation=val)
        times.append(time.perf_counter() - t0)
    print(result.table())
    print(f"\nwhole identify() call, warm: best {min(times):.2f} s of {args.repeat} (fit {result.stats['fit_seconds']:.2f} s, "
          f"{result.settings['iterations']} iterations, {result.settings['segments']} segments)")
    print(f"held-out median angle RMS, the fit's angles ({result.settings['angles']}): fit {result.heldout_median:.5f} "
          f"rad, authors {result.heldout_median0:.5f} rad (ratio {result.heldout_median / result.heldout_median0:.3f})")
    print(f"held-out median angle RMS, absolute angles: fit {absolute_median(result.params, val):.5f} rad, authors "
          f"{absolute_median(authors, val):.5f} rad")
    print(f"held-out median angle RMS, joint angles: fit {joint_median(result.params, val):.5f} rad, authors "
          f"{joint_median(authors, val):.5f} rad")
    if args.cold:
        with tempfile.TemporaryDirectory() as cache:
            env = dict(os.environ, SKEWPEND_CACHE_DIR=cache)
            code = ("import skewpend; from skewpend.analysis.measurements import kaheman_published_chain as k; "
                    f"d = {str(DATA)!r}; f = skewpend.Measurements.from_kaheman(d, which='fit'); "
                    "v = skewpend.Measurements.from_kaheman(d, which='validation'); "
                    "r = skewpend.identify(f, k(d), validation=v); assert r.ok")
            t0 = time.perf_counter()
            subprocess.run([sys.executable, "-c", code], env=env, check=True, capture_output=True)
            print(f"fresh process, empty kernel cache (import, read, compile, fit, predict): {time.perf_counter() - t0:.2f} s")
    if args.coverage:
        coverage(fit, authors, args.coverage, args.noise)
    print("\nsegment [s]  angles    fit RMS     held out (fitted / authors): joint angles   absolute angles")
    for angles in ("relative", "absolute"):
        for segment in (0.5, 1.0, 1.6):
            r = skewpend.identify(fit, authors, validation=val, segment=segment, angles=angles, bootstrap=0)
            print(f"{segment:>10.1f}  {angles:<9} {np.median(r.fit_rms):.5f}   {joint_median(r.params, val):.5f} / "
                  f"{joint_median(authors, val):.5f}        {absolute_median(r.params, val):.5f} / "
                  f"{absolute_median(authors, val):.5f}" + ("" if r.ok else f"  [{r.message}]"))


def coverage(fit, truth, seeds: int, noise: float) -> None:
    import skewpend
    from skewpend.analysis.identify import chain_terms

    runs = [skewpend.simulate(truth, np.concatenate([p.q[0], p.dq[0]]), float(p.t[-1] - p.t[0]), dt_out=float(p.dt),
                              rtol=1e-12, atol=1e-12) for p in fit]
    start = truth
    for i, link in enumerate(truth.links, start=1):
        start = start.replace_link(i, mass=link.mass * 1.1, damping=link.damping * 1.5)
    terms = chain_terms(truth)
    beta = terms.values(terms.standard(truth))
    ref = terms.names.index("J1zz_b")
    hits, count, times = {}, 0, []
    for seed in range(seeds):
        rng = np.random.default_rng(seed)
        pieces = [{"t": r.t, "q": np.asarray(r.y)[:, :3] + noise * rng.normal(size=(len(r.t), 3)), "name": f"p{k}"}
                  for k, r in enumerate(runs)]
        data = skewpend.Measurements.from_arrays(pieces, skip=("mean",))
        t0 = time.perf_counter()
        result = skewpend.identify(data, start, bootstrap=200, seed=seed)
        times.append(time.perf_counter() - t0)
        if not result.ok:
            print(f"seed {seed}: {result.message}")
            continue
        count += 1
        for name, (lo, hi) in result.ratio_intervals.items():
            j = terms.names.index(name.split("/")[0])
            want = beta[j] / beta[ref]
            hits[name] = hits.get(name, 0) + int(lo <= want <= hi)
    print(f"\ncoverage over {count} of {seeds} seeds (noise {noise:g} rad, {np.median(times):.2f} s a fit): "
          + ", ".join(f"{k} {v}/{count}" for k, v in hits.items()))
    print(f"all ratios together: {sum(hits.values())}/{count * len(hits)} "
          f"({100 * sum(hits.values()) / max(count * len(hits), 1):.1f} %; nominal 95 %)")


if __name__ == "__main__":
    main()
