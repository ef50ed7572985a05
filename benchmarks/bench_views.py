"""The views against their goals, as whole processes on this machine.

* ``skewpend animate --t-end 10 --out motion.mp4`` (and ``.gif``): 10 s at 30 fps, goal <= 20 s
  (issue 8);
* ``skewpend report`` cold -- an empty cache: every kernel compiled, the symbolic sections
  computed (issue 19: goal <= 15 s) -- and warm -- the kernels and the report's symbolic sections
  cached (issue 19: goal <= 8 s); the report's size (goal <= 10 MB).

Run:  python benchmarks/bench_views.py [--repeat 3]
"""

from __future__ import annotations

import argparse
import os
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path


def timed(args, env=None, cwd=None) -> float:
    start = time.perf_counter()
    subprocess.run([sys.executable, "-m", "skewpend", *args], check=True, capture_output=True, cwd=cwd,
                   env={**os.environ, **(env or {})})
    return time.perf_counter() - start


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--repeat", type=int, default=3)
    args = ap.parse_args()
    rows = []
    with tempfile.TemporaryDirectory() as tmp:
        warm_cache = {"SKEWPEND_CACHE_DIR": str(Path(tmp) / "cache")}
        timed(["simulate", "--t-end", "1"], env=warm_cache)  # the default model's kernel, cached
        for suffix in ("mp4", "gif"):
            times = [timed(["animate", "--t-end", "10", "--quiet", "--out", f"motion.{suffix}"], env=warm_cache, cwd=tmp)
                     for _ in range(args.repeat)]
            size = (Path(tmp) / f"motion.{suffix}").stat().st_size
            rows.append((f"animate 10 s at 30 fps, {suffix} ({size / 1e6:.2f} MB)", times, 20.0))
        cold = []
        for k in range(args.repeat):
            cold.append(timed(["report", "--quiet", "--out", "cold.html"], env={"SKEWPEND_CACHE_DIR": str(Path(tmp) / f"c{k}")}, cwd=tmp))
        rows.append(("report, cold (empty cache)", cold, 15.0))
        timed(["report", "--quiet", "--out", "warm.html"], env=warm_cache, cwd=tmp)  # fills the cache
        warm = [timed(["report", "--quiet", "--out", "warm.html"], env=warm_cache, cwd=tmp) for _ in range(args.repeat)]
        size = (Path(tmp) / "warm.html").stat().st_size
        rows.append((f"report, warm ({size / 1e6:.1f} MB, goal <= 10 MB)", warm, 8.0))
    print(f"{os.cpu_count()} cores, Python {sys.version.split()[0]}; median of {args.repeat} whole processes")
    print(f"{'case':58s} {'median s':>9s} {'min s':>7s} {'goal s':>7s}")
    for name, times, goal in rows:
        med = statistics.median(times)
        print(f"{name:58s} {med:9.2f} {min(times):7.2f} {goal:7.1f}  {'PASS' if med <= goal else 'FAIL'}")


if __name__ == "__main__":
    main()
