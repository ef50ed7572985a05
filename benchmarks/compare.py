"""Before and after: the headline figure of every benchmark, at two revisions, interleaved.

Issue 15 (the redesign) asks that every benchmark stay within 5 % of its figure before the
change.  This script measures the case behind each benchmark's headline figure at two source
trees -- BASE (a git worktree of the revision before, made here with ``git worktree add``) and
HEAD (this checkout) -- in fresh processes, alternating BASE, HEAD, BASE, HEAD ... so that the
machine's load falls on both alike, each tree with its own kernel cache (``SKEWPEND_CACHE_DIR``,
warmed before timing).  It prints, for each case, the median of each tree, the ratio HEAD/BASE,
and whether it is within 5 %.

Cases (the workloads of the benchmark scripts named):

* ``simulate``  -- bench_simulate.py: dop853, 20 s, rtol = atol = 1e-10, warm, in process;
* ``rk4``, ``gauss`` -- bench_simulate.py: the fixed-step methods, dt = 1e-3, 20 s;
* ``flipmap-2w``, ``flipmap-1w`` -- bench_flipmap.py: the 128 x 128 map, t_end = 10 s;
* ``lyapunov``, ``lyapunov-1`` -- bench_lyapunov.py: the full spectrum over 1000 s at 1e-10, the
  largest exponent at 1e-6;
* ``derive`` -- bench_derive.py: ``derive()`` all symbolic, in a fresh process;
* ``cli-simulate`` -- bench_first_use.py: ``skewpend simulate`` on a warm cache, the whole process;
* ``report`` (with ``--views``) -- bench_views.py: ``skewpend report`` cached.

Run:  python benchmarks/compare.py [--base REV] [--repeat 5] [--views] [--only CASE ...]
"""

from __future__ import annotations

import argparse
import os
import statistics
import subprocess
import sys
import tempfile
import textwrap
from pathlib import Path

HERE = Path(__file__).resolve().parent
HEAD = HERE.parent

_SETUP = """
import time, numpy as np
from skewpend import Parameters
P = Parameters(a=1.0, b=0.8, m1=1.0, m2=0.7, alpha=0.6, g=9.81)
Y0 = np.array([1.2, -0.8, 0.0, 0.0])
def timed(fn, n):
    fn()  # warm: the kernel compiled or loaded, caches filled
    ts = []
    for _ in range(n):
        t0 = time.perf_counter(); fn(); ts.append(time.perf_counter() - t0)
    print(min(ts))
"""

#: case -> (Python code printing one time in seconds, or a command line timed whole)
CASES = {
    "simulate": "from skewpend import simulate\ntimed(lambda: simulate(P, Y0, 20.0), 15)",
    "rk4": "from skewpend import simulate\ntimed(lambda: simulate(P, Y0, 20.0, method='rk4', dt=1e-3), 7)",
    "gauss": "from skewpend import simulate\ntimed(lambda: simulate(P, Y0, 20.0, method='gauss', dt=1e-3), 5)",
    "flipmap-2w": "from skewpend import flip_map\ntimed(lambda: flip_map(P, 128, workers=2), 9)",
    "flipmap-1w": "from skewpend import flip_map\ntimed(lambda: flip_map(P, 128, workers=1), 7)",
    "lyapunov": "from skewpend import lyapunov\ntimed(lambda: lyapunov(P, Y0, t_end=1000.0), 5)",
    "lyapunov-1": ("from skewpend import lyapunov\n"
                   "timed(lambda: lyapunov(P, Y0, t_end=1000.0, n_exponents=1, rtol=1e-6, atol=1e-6), 7)"),
    "derive": ("import time\nt0 = time.perf_counter()\nimport skewpend\nskewpend.derive()\n"
               "print(time.perf_counter() - t0)"),
    "cli-simulate": ["-m", "skewpend", "simulate", "--quiet"],
}
VIEWS = {"report": ["-m", "skewpend", "report", "--quiet", "--out", "{tmp}/report.html"]}


def run_case(tree: Path, cache: Path, case, tmp: Path) -> float:
    env = dict(os.environ, PYTHONPATH=str(tree / "src"), SKEWPEND_CACHE_DIR=str(cache))
    if isinstance(case, str):
        code = textwrap.dedent(_SETUP) + case
        out = subprocess.run([sys.executable, "-c", code], env=env, capture_output=True, text=True, cwd=tmp, check=True)
        return float(out.stdout.strip().splitlines()[-1])
    import time

    argv = [a.replace("{tmp}", str(tmp)) for a in case]
    t0 = time.perf_counter()
    subprocess.run([sys.executable, *argv], env=env, capture_output=True, cwd=tmp, check=True)
    return time.perf_counter() - t0


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--base", default="a22fb08", help="the revision before the change (default a22fb08)")
    ap.add_argument("--repeat", type=int, default=5, help="processes per case and tree (median reported)")
    ap.add_argument("--views", action="store_true", help="also the report (about 10 s per run)")
    ap.add_argument("--only", nargs="*", help="only these cases")
    args = ap.parse_args()
    cases = dict(CASES, **(VIEWS if args.views else {}))
    if args.only:
        cases = {k: v for k, v in cases.items() if k in args.only}
    with tempfile.TemporaryDirectory(prefix="skewpend-compare-") as tmpdir:
        tmp = Path(tmpdir)
        base = tmp / "base"
        subprocess.run(["git", "-C", str(HEAD), "worktree", "add", "--detach", "-q", str(base), args.base], check=True)
        try:
            trees = {"base": base, "head": HEAD}
            caches = {name: tmp / f"cache-{name}" for name in trees}
            times = {(c, t): [] for c in cases for t in trees}
            for c, case in cases.items():
                for t in trees:  # warm each cache, untimed
                    run_case(trees[t], caches[t], case, tmp)
                for _ in range(args.repeat):
                    for t in trees:
                        times[(c, t)].append(run_case(trees[t], caches[t], case, tmp))
            print(f"{'case':<14} {'base s':>10} {'head s':>10} {'head/base':>10}  within 5 %")
            for c in cases:
                b, h = statistics.median(times[(c, "base")]), statistics.median(times[(c, "head")])
                print(f"{c:<14} {b:10.4f} {h:10.4f} {h / b:10.3f}  {'yes' if h <= 1.05 * b else 'NO'}")
        finally:
            subprocess.run(["git", "-C", str(HEAD), "worktree", "remove", "--force", str(base)], check=False)


if __name__ == "__main__":
    main()
