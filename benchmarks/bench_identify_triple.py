"""The real triple pendulum (issue 38): skewpend.identify on the free swing of Kaheman et al. (2023)'s
triple pendulum (data/kaheman2023-triple: 22 fitting pieces of 1.54 s, 4 held out, 1 kHz) beside the
authors' own model.

1. The fit from the authors' published model as params0 (a chain of three links; it supplies the masses,
   the overall scale and the start), the default protocol (segments of 0.5 s, the output error in the
   joint angles): the 12 base parameters, the held-out angle RMS (each held-out piece simulated from its
   first measured state over its 1.54 s; median over the pieces) of the fit and of the authors' model
   under the same protocol -- in skewpend's joint angles and in the data's absolute angles (each arm's
   from the vertical, the authors' state) -- and the time of the whole ``identify()`` call, warm (best
   of ``--repeat``) and in a fresh process with an empty kernel cache (``--cold``: the shooting and the
   chain kernels compiled).
2. The same over the segment length (0.5, 1.0, 1.6 s: one segment a piece) and the angles the output
   error measures (``angles="relative"`` / ``"absolute"``).

The goal (issue 38): a held-out median angle RMS <= 0.0028 rad, the authors' own model's figure under
the same protocol, and the whole fit <= 30 s on 2 cores.

    python benchmarks/bench_identify_triple.py [--repeat 3] [--cold]
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


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--repeat", type=int, default=3)
    ap.add_argument("--cold", action="store_true", help="also time a fresh process with an empty kernel cache")
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
    print(f"held-out median angle RMS, joint angles: fit {result.heldout_median:.5f} rad, authors "
          f"{result.heldout_median0:.5f} rad (ratio {result.heldout_median / result.heldout_median0:.3f})")
    print(f"held-out median angle RMS, absolute angles: fit {absolute_median(result.params, val):.5f} rad, authors "
          f"{absolute_median(authors, val):.5f} rad")
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
    print("\nsegment [s]  angles    fit RMS     held out (fitted / authors), joint angles   absolute angles")
    for angles in ("relative", "absolute"):
        for segment in (0.5, 1.0, 1.6):
            r = skewpend.identify(fit, authors, validation=val, segment=segment, angles=angles, bootstrap=0)
            print(f"{segment:>10.1f}  {angles:<9} {np.median(r.fit_rms):.5f}   {r.heldout_median:.5f} / "
                  f"{r.heldout_median0:.5f} ({angles})        {absolute_median(r.params, val):.5f} / "
                  f"{absolute_median(authors, val):.5f}" + ("" if r.ok else f"  [{r.message}]"))


if __name__ == "__main__":
    main()
