"""`skewpend report` against a `skewpend simulate` process, warm and cold, as whole processes (issue 28, goal 4).

Every figure is the wall time of a whole new process (interpreter start-up, imports, kernels compiled
or loaded, the work, the file written), time.perf_counter around subprocess.run, output captured:

* simulate warm: `skewpend simulate` (the built-in defaults: 20 s, dop853 at 1e-10), its kernel cached;
* report warm:   `skewpend report -q` with the kernels and the report's symbolic sections (2, 3) cached;
* report cold:   `skewpend report -q` with SKEWPEND_CACHE_DIR an EMPTY directory (a new one each run):
  every kernel the report loads is compiled (by whatever compiler skewpend finds first: CC, cc, gcc,
  clang, else the packaged zig cc) and sections 2 and 3 are computed by SymPy.

The three are interleaved run by run (simulate, warm, cold, simulate, ...) so that all see the same
load; the machine may be shared, so medians are quoted, with the ratios taken pair by pair too.
Goals (issue 28): report warm <= 25x simulate warm; report cold <= 2x report warm.

After the runs the report's own timings table (section 10, "how it was made") of the last warm and the
last cold report is printed side by side: the parts of the report, and the whole process's time
outside them (start-up, imports, writing the file).

Run:  python benchmarks/bench_report.py [--repeat 3] [--no-cold]
"""

from __future__ import annotations

import argparse
import html
import os
import platform
import re
import shutil
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))
from _common import cpu_model, print_report_timings, version  # noqa: E402

GOAL_WARM = 25.0  # report warm <= 25x a warm simulate process
GOAL_COLD = 2.0  # report cold <= 2x report warm
TIMEOUT = 900.0


def skewpend() -> list[str]:
    exe = Path(sys.executable).parent / ("skewpend.exe" if os.name == "nt" else "skewpend")
    return [str(exe)] if exe.exists() else [sys.executable, "-m", "skewpend"]


def run(args: list[str], cache: Path, cwd: Path) -> float:
    env = {**os.environ, "SKEWPEND_CACHE_DIR": str(cache)}
    t0 = time.perf_counter()
    proc = subprocess.run(skewpend() + args, env=env, cwd=cwd, capture_output=True, text=True, timeout=TIMEOUT)
    dt = time.perf_counter() - t0
    if proc.returncode != 0:
        raise SystemExit(f"skewpend {' '.join(args)} failed ({proc.returncode}):\n{proc.stderr}")
    return dt


def timings(report: Path) -> dict[str, float]:
    """Section 10's timings table: part -> seconds."""
    text = report.read_text(encoding="utf-8")
    start = text.find("<h3>Timings</h3>")
    if start < 0:
        return {}
    table = text[start:text.find("</table>", start)]
    rows = re.findall(r"<tr><td>(.*?)</td><td class=num>([0-9.]+)</td></tr>", table)
    return {html.unescape(re.sub(r"<[^>]+>", "", k)): float(v) for k, v in rows}


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--repeat", type=int, default=3, help="timed runs of each (median reported; default 3)")
    ap.add_argument("--no-cold", action="store_true", help="skip the cold reports (each takes a minute or so)")
    args = ap.parse_args()

    print("machine")
    print(f"  cpu        {cpu_model()}")
    print(f"  nproc      {len(os.sched_getaffinity(0)) if hasattr(os, 'sched_getaffinity') else os.cpu_count()}")
    print(f"  platform   {platform.platform()}")
    print(f"  python     {platform.python_version()}   skewpend {version('skewpend')}   matplotlib "
          f"{version('matplotlib')}   sympy {version('sympy')}   mujoco {version('mujoco')}")
    print(f"  command    {' '.join(skewpend())}")
    print(f"  load       {' '.join(f'{x:.2f}' for x in os.getloadavg())} at the start (1, 5, 15 min; the machine "
          "may be shared)")
    print(f"repetitions: {args.repeat}, interleaved (median reported)\n", flush=True)

    times: dict[str, list[float]] = {"simulate warm": [], "report warm": [], "report cold": []}
    tables: dict[str, dict[str, float]] = {}
    work = Path(tempfile.mkdtemp(prefix="skewpend-bench-report-"))
    try:
        warm = work / "warm-cache"
        t = run(["report", "-q", "-o", "warm.html"], warm, work)  # fills the cache: kernels, sections 2 and 3
        print(f"  (untimed) first report, filling the cache: {t:.2f} s", flush=True)
        run(["simulate"], warm, work)
        for i in range(args.repeat):
            times["simulate warm"].append(run(["simulate"], warm, work))
            times["report warm"].append(run(["report", "-q", "-o", "warm.html"], warm, work))
            line = (f"  run {i + 1}: simulate warm {times['simulate warm'][-1]:.3f} s   "
                    f"report warm {times['report warm'][-1]:.2f} s")
            if not args.no_cold:
                cold = work / f"cold-cache-{i}"
                times["report cold"].append(run(["report", "-q", "-o", "cold.html"], cold, work))
                shutil.rmtree(cold, ignore_errors=True)
                line += f"   report cold {times['report cold'][-1]:.2f} s"
            print(line, flush=True)
        tables["warm"] = timings(work / "warm.html")
        if not args.no_cold:
            tables["cold"] = timings(work / "cold.html")
    finally:
        shutil.rmtree(work, ignore_errors=True)

    med = {k: statistics.median(v) for k, v in times.items() if v}
    print(f"\n{'case':<16} {'n':>2} {'median s':>9} {'min s':>8} {'max s':>8}")
    for k, v in times.items():
        if v:
            print(f"{k:<16} {len(v):>2} {med[k]:>9.3f} {min(v):>8.3f} {max(v):>8.3f}")

    def pairwise(a: str, b: str) -> float:
        return statistics.median(x / y for x, y in zip(times[a], times[b]))

    print()
    r = med["report warm"] / med["simulate warm"]
    print(f"report warm / simulate warm: {r:.1f}x (of medians; pair by pair {pairwise('report warm', 'simulate warm'):.1f}x)"
          f"   goal <= {GOAL_WARM:g}x: {'met' if r <= GOAL_WARM else 'NOT met'}")
    if "report cold" in med:
        r = med["report cold"] / med["report warm"]
        print(f"report cold / report warm:   {r:.2f}x (of medians; pair by pair {pairwise('report cold', 'report warm'):.2f}x)"
              f"   goal <= {GOAL_COLD:g}x: {'met' if r <= GOAL_COLD else 'NOT met'}")

    if tables:
        kinds = list(tables)
        print_report_timings(tables, 9)
        last = {"warm": times["report warm"][-1], "cold": times["report cold"][-1] if times["report cold"] else None}
        print(f"{'whole process (this benchmark)':<44}" + "".join(f"{last[k]:>9.2f}" for k in kinds))
        print(f"{'  outside the table: start-up, imports, file':<44}"
              + "".join(f"{last[k] - tables[k].get('total', float('nan')):>9.2f}" for k in kinds))
    print(f"\nload average at the end: {' '.join(f'{x:.2f}' for x in os.getloadavg())}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
