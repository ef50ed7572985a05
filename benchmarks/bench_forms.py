"""The forms of one model's generated code side by side (issue 52): ``exact`` (the specification's derivation,
two links), ``straight`` and ``compact`` (the recursive algorithms, any chain) -- the crossover in N that
``kernels.model_form`` follows by default.

For chains of ``--links`` (default 2 3 4 6 10; thin rods, hinge 2 skewed 0.4 rad, the others along k) each
form that prints the chain runs the same motion (20 s from every angle 0.6 rad at rest, DOP853 at
rtol = atol = 1e-10, and for two links the Taylor method at 1e-12) ``--repeat`` times in this process; the
median CPU time of each and its ratio to the fastest form are printed, with the end states' largest difference
from the first form's (the same motion, differently rounded).  Counting instructions is steadier on a busy
machine: ``valgrind --tool=callgrind --collect-atstart=no --toggle-collect=dop853_run python
benchmarks/bench_forms.py --links 2 --repeat 1``.

    python benchmarks/bench_forms.py [--links 2 3 4 6 10] [--repeat 7]
"""

from __future__ import annotations

import argparse
import os
import statistics
import sys
import time

import numpy as np

sys.path.insert(0, os.path.dirname(__file__))
from _common import cpu_model, version  # noqa: E402


def chain(n: int):
    from skewpend.symbolic.chain import Chain

    axes = [(0.0, 0.0, 1.0), (np.sin(0.4), 0.0, np.cos(0.4))] + [(0.0, 0.0, 1.0)] * (n - 2)
    return Chain.from_lists(n, length=[1.0, 0.8] + [0.6] * (n - 2), mass=[1.0, 0.7] + [0.5] * (n - 2),
                            axis=axes[:n])


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--links", type=int, nargs="+", default=[2, 3, 4, 6, 10])
    ap.add_argument("--repeat", type=int, default=7)
    ap.add_argument("--t-end", type=float, default=20.0)
    args = ap.parse_args()
    import skewpend
    from skewpend.errors import ParameterError
    from skewpend.numeric.conventions import SERIES_MAX_LINKS
    from skewpend.numeric.kernels import FORMS, model_form

    print(f"skewpend {version('skewpend')} on {cpu_model()}; 20 s runs, median CPU time of {args.repeat}",
          file=sys.stderr)
    print(f"{'links':>5} {'method':>7} {'form':>9} {'CPU ms':>9} {'x fastest':>9} {'end diff':>9}  default")
    for n in args.links:
        model = chain(n)
        y0 = [0.6] * n + [0.0] * n
        default = model_form(model)[0]
        for method, tol in (("dop853", 1e-10), ("taylor", 1e-12)):
            if method == "taylor" and n > SERIES_MAX_LINKS:
                continue  # beyond, auto takes dop853 (the model as polynomials grows too many terms)
            rows, first = [], None
            for form in FORMS:
                try:
                    skewpend.simulate(model, y0, 1.0, method=method, rtol=tol, atol=tol, form=form)  # build, warm
                except ParameterError:
                    continue  # a form that does not print this chain (exact beyond two links)
                times = []
                for _ in range(args.repeat):
                    t0 = time.process_time()
                    tr = skewpend.simulate(model, y0, args.t_end, method=method, rtol=tol, atol=tol, form=form)
                    times.append(time.process_time() - t0)
                first = tr.y[-1] if first is None else first
                rows.append((form, statistics.median(times), float(np.max(np.abs(tr.y[-1] - first)))))
            fastest = min(t for _, t, _ in rows)
            for form, t, diff in rows:
                print(f"{n:5d} {method:>7} {form:>9} {t * 1e3:9.2f} {t / fastest:9.2f} {diff:9.1e}  "
                      f"{'<-' if form == default and method == 'dop853' else ''}")


if __name__ == "__main__":
    main()
