"""Before and after issue 37 (the model as data): the flip map, the ROA lanes, the Taylor series and a
Lyapunov spectrum, at a BASELINE revision and at the CURRENT tree, interleaved, in fresh processes.

Issue 37 asks that making the parameters run-time inputs (and one linear solve for every kernel)
keep each of these workloads within 5 % of the code before it.  This script measures them:

* the BASELINE source (default ``da6199b``, the code before issue 37) is extracted with
  ``git archive`` into a temporary directory (no worktree, nothing left in the repository);
* every measurement is a fresh process (``PYTHONPATH=<tree>/src``), each tree with its own kernel
  cache (``SKEWPEND_CACHE_DIR``), warmed by one untimed process per workload and tree first, so
  that no compile is timed; the process checks that it imported skewpend from the tree it was meant to;
* in each round every workload runs once per tree, the two alternating (B C, then C B in the next
  round, so that neither always runs second), and the machine's load average is recorded: the
  machine is shared (2 cores, other jobs), medians over rounds are the figures, minima beside them;
* inside a process one untimed call loads the kernel, then the workload is timed ``inner`` times and
  the process reports its fastest call.

Workloads (the cases of the benchmark scripts named; one worker each unless ``--workers``):

* ``flip``     -- bench_flipmap.py: ``flip_map(P, 128)``, t_end = 10 s, default tolerance (DOP853 1e-10);
* ``roa``      -- bench_roa.py: ``region_of_attraction(P30, n=64, design=lqr(up-up, both, umax=10),
  t_end=10)`` (the closed loop in SIMD lanes; alpha = 30 deg);
* ``taylor``   -- bench_precision.py's case: ``simulate(P, y0, 20, method="taylor", rtol=atol=tol)``
  at tol 1e-6, 1e-9, 1e-12 (one line each).  At equal tolerance both trees take the same steps, so
  their times compare at equal error -- the script prints each tree's error at 5 s against one
  reference (the current tree's taylor at 1e-15) to show that it is so;
* ``lyapunov`` -- bench_lyapunov.py: ``lyapunov(P, y0, t_end=1000, renorm_every=1, rtol=atol=1e-10)``, 4 exponents.

P: a=1, b=0.8, m1=1, m2=0.7, alpha=0.6, g=9.81; y0 = (1.2, -0.8, 0, 0).  Each workload's results
are compared between the trees too (flip times, capture times, states, exponents): the change is to
keep them within rounding.  A ratio current/baseline above 1.05 is flagged ``SLOWER``.

``--current REV`` measures a committed revision instead of the working tree (others' half-done edits
then do not break the run); ``--current`` equal to ``--baseline`` is an A/A run: the ratios show the
harness's own noise on this machine.

Run:  python benchmarks/bench_model_data.py [--baseline da6199b] [--current REV] [--repeat 7]
      [--only flip roa taylor lyapunov] [--workers 1] [--keep DIR]    (progress on stderr, the table on stdout)
"""

from __future__ import annotations

import argparse
import json
import math
import os
import shutil
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

HERE = Path(__file__).resolve().parent
CURRENT = HERE.parent
WORKLOADS = ("flip", "roa", "taylor", "lyapunov")
TAYLOR_TOLS = (1e-6, 1e-9, 1e-12)
REF_TOL = 1e-15
FLAG = 1.05
#: timed calls inside one process (its fastest reported): the short Taylor runs more often
INNER = {"flip": 5, "roa": 5, "taylor": 25, "lyapunov": 5}


def say(msg: str) -> None:
    print(f"[bench_model_data] {msg}", file=sys.stderr, flush=True)


# ----------------------------------------------------------------------------- the worker (one process)
def _worker(name: str, inner: int, workers: int) -> dict:
    """Run one workload in this process (the tree on PYTHONPATH): ``{"times": {label: s}, "check": ...}``."""
    import numpy as np

    import skewpend

    root = os.environ.get("BENCH_MODEL_DATA_ROOT")
    if root and not Path(skewpend.__file__).resolve().is_relative_to(Path(root).resolve()):
        raise SystemExit(f"skewpend imported from {skewpend.__file__}, not from {root}")
    P = skewpend.Parameters(a=1.0, b=0.8, m1=1.0, m2=0.7, alpha=0.6, g=9.81)
    Y0 = (1.2, -0.8, 0.0, 0.0)

    def best(fn):
        fn()  # untimed: the kernel loaded from the cache, caches filled
        ts, out = [], None
        for _ in range(inner):
            t0 = time.perf_counter()
            out = fn()
            ts.append(time.perf_counter() - t0)
        return min(ts), out

    def floats(a):
        return [None if not math.isfinite(x) else float(x) for x in np.asarray(a, dtype=float).ravel()]

    if name == "flip":
        t, fm = best(lambda: skewpend.flip_map(P, 128, workers=workers))
        return {"times": {"flip map 128x128": t}, "check": {"flip": floats(fm.flip_time)}}
    if name == "roa":
        from skewpend.analysis.roa import region_of_attraction

        P30 = P.replace(alpha=math.radians(30.0))
        d = skewpend.lqr(P30, "up-up", "both", umax=10.0)
        t, r = best(lambda: region_of_attraction(P30, n=64, design=d, t_end=10.0, workers=workers))
        return {"times": {"ROA lanes 64x64": t}, "check": {"capture": floats(r.capture_time)}}
    if name == "taylor":
        times, check = {}, {}
        for tol in TAYLOR_TOLS:
            t, run20 = best(lambda: skewpend.simulate(P, Y0, 20.0, method="taylor", rtol=tol, atol=tol))
            tr = skewpend.simulate(P, Y0, 5.0, method="taylor", rtol=tol, atol=tol)
            times[f"taylor 20 s tol {tol:g}"] = t
            check[f"{tol:g}"] = floats(tr.y[-1][:4])
            check[f"steps {tol:g}"] = [int(run20.stats["steps"])]
        return {"times": times, "check": check}
    if name == "taylor-ref":
        tr = skewpend.simulate(P, Y0, 5.0, method="taylor", rtol=REF_TOL, atol=REF_TOL)
        return {"times": {}, "check": {"ref": floats(tr.y[-1][:4])}}
    if name == "lyapunov":
        t, ly = best(lambda: skewpend.lyapunov(P, Y0, t_end=1000.0, renorm_every=1.0, rtol=1e-10, atol=1e-10,
                                               n_exponents=4))
        return {"times": {"Lyapunov 4 exp. 1000 s": t},
                "check": {"exponents": floats(ly.exponents), "steps": [int(ly.stats["steps"])]}}
    raise SystemExit(f"unknown workload {name!r}; allowed: {', '.join(WORKLOADS)}")


# ----------------------------------------------------------------------------- the harness
def run(tree: Path, cache: Path, name: str, inner: int, workers: int, tmp: Path) -> dict:
    env = dict(os.environ, PYTHONPATH=str(tree / "src"), SKEWPEND_CACHE_DIR=str(cache),
               BENCH_MODEL_DATA_ROOT=str(tree / "src"))
    env.pop("SKEWPEND_PROGRESS", None)
    argv = [sys.executable, str(Path(__file__).resolve()), "--worker", name, "--inner", str(inner),
            "--workers", str(workers)]
    out = subprocess.run(argv, env=env, capture_output=True, text=True, cwd=tmp)
    if out.returncode != 0:
        raise RuntimeError(f"{name} at {tree} failed ({out.returncode}):\n{out.stderr[-3000:]}")
    return json.loads(out.stdout.strip().splitlines()[-1])


def load() -> float:
    return os.getloadavg()[0]


def compare(name: str, base: dict, cur: dict, ref=None) -> list:
    """Lines saying how far the two trees' results are apart."""
    import numpy as np

    def arr(x):
        return np.array([np.nan if v is None else v for v in x], dtype=float)

    lines = []
    for key in base:
        if key.startswith("steps"):
            lines.append(f"  {name} {key}: baseline {base[key][0]}, current {cur[key][0]}")
            continue
        a, b = arr(base[key]), arr(cur[key])
        both = np.isfinite(a) & np.isfinite(b)
        differ = int(np.sum(np.isfinite(a) != np.isfinite(b)))
        dmax = float(np.max(np.abs(a[both] - b[both]))) if both.any() else 0.0
        line = f"  {name} {key}: max |current - baseline| = {dmax:.2e} over {int(both.sum())} values"
        if differ:
            line += f", {differ} finite in one tree only"
        if ref is not None:
            line += (f"; error at 5 s vs taylor {REF_TOL:g}: baseline {np.max(np.abs(a - ref)):.2e}, "
                     f"current {np.max(np.abs(b - ref)):.2e}")
        lines.append(line)
    return lines


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--baseline", default="da6199b", help="git revision of the baseline (default da6199b, before issue 37)")
    ap.add_argument("--current", help="a git revision to measure instead of the working tree (default: the working "
                    "tree, uncommitted edits included)")
    ap.add_argument("--repeat", type=int, default=7, help="rounds: processes per workload and tree (median reported)")
    ap.add_argument("--only", nargs="*", choices=WORKLOADS, help="only these workloads")
    ap.add_argument("--workers", type=int, default=1, help="worker threads of the flip map and the ROA (default 1)")
    ap.add_argument("--keep", type=Path, help="keep the baseline tree and both kernel caches in this directory "
                    "(reused by the next run: no compile)")
    ap.add_argument("--worker", help=argparse.SUPPRESS)
    ap.add_argument("--inner", type=int, default=3, help=argparse.SUPPRESS)
    args = ap.parse_args()
    if args.worker:
        print(json.dumps(_worker(args.worker, args.inner, args.workers)))
        return 0
    names = args.only or list(WORKLOADS)
    if args.repeat < 1 or args.workers < 1:
        print("bench_model_data: --repeat and --workers must be >= 1", file=sys.stderr)
        return 2
    tmp = Path(args.keep) if args.keep else Path(tempfile.mkdtemp(prefix="skewpend-model-data-"))
    tmp.mkdir(parents=True, exist_ok=True)
    try:
        return _measure(args, names, tmp)
    except KeyboardInterrupt:
        say("interrupted")
        return 130
    finally:
        if not args.keep:
            shutil.rmtree(tmp, ignore_errors=True)


def _extract(rev: str, tmp: Path, what: str) -> Path:
    """The ``src`` of revision ``rev`` (``git archive``) under ``tmp``, extracted once."""
    tree = tmp / f"{what}-{rev}"
    if not (tree / "src" / "skewpend").is_dir():
        say(f"extracting the {what} {rev} (git archive {rev} src) into {tree}")
        tree.mkdir(parents=True, exist_ok=True)
        archive = subprocess.Popen(["git", "-C", str(CURRENT), "archive", rev, "src"], stdout=subprocess.PIPE)
        subprocess.run(["tar", "-x", "-C", str(tree)], stdin=archive.stdout, check=True)
        if archive.wait() != 0:
            raise RuntimeError(f"git archive {rev} failed")
    return tree


def _revision(rev: str):
    out = subprocess.run(["git", "-C", str(CURRENT), "rev-parse", "--short", rev], capture_output=True, text=True)
    if out.returncode != 0:
        print(f"bench_model_data: unknown git revision {rev!r}: {out.stderr.strip()}", file=sys.stderr)
        return None
    return out.stdout.strip()


def _measure(args, names, tmp: Path) -> int:
    base_rev = _revision(args.baseline)
    cur_rev = _revision(args.current) if args.current else ""
    if base_rev is None or cur_rev is None:
        return 2
    base = _extract(base_rev, tmp, "baseline")
    if cur_rev:
        cur, head = _extract(cur_rev, tmp, "current"), cur_rev
    else:
        cur = CURRENT
        head = "the working tree " + subprocess.run(["git", "-C", str(CURRENT), "describe", "--always", "--dirty"],
                                                    capture_output=True, text=True).stdout.strip()
    trees = {"baseline": base, "current": cur}
    caches = {"baseline": tmp / f"cache-baseline-{base_rev}", "current": tmp / f"cache-current-{cur_rev or 'tree'}"}
    loads = [load()]
    say(f"baseline {base_rev} at {base}; current {head} at {cur}; load {loads[0]:.2f}")

    # warm: one untimed process per workload and tree (compiles into that tree's cache)
    cold = {}
    for name in names:
        for t in trees:
            say(f"warming the {t} cache: {name} (compiles on first use, untimed) ...")
            t0 = time.perf_counter()
            run(trees[t], caches[t], name, 1, args.workers, tmp)
            cold[(name, t)] = time.perf_counter() - t0
            say(f"  {t} {name}: {cold[(name, t)]:.1f} s")
    ref = None
    if "taylor" in names:
        say(f"the Taylor reference: current tree, tol {REF_TOL:g}, 5 s ...")
        ref = run(trees["current"], caches["current"], "taylor-ref", 1, args.workers, tmp)["check"]["ref"]

    times: dict = {}
    checks: dict = {}
    for r in range(args.repeat):
        order = list(trees) if r % 2 == 0 else list(trees)[::-1]
        for name in names:
            for t in order:
                loads.append(load())
                res = run(trees[t], caches[t], name, INNER[name], args.workers, tmp)
                checks.setdefault((name, t), res["check"])
                for label, s in res["times"].items():
                    times.setdefault((label, t), []).append(s)
                shown = ", ".join(f"{s * 1e3:.1f} ms" for s in res["times"].values())
                say(f"round {r + 1}/{args.repeat}: {t:<8} {name:<8} {shown}  (load {loads[-1]:.2f})")
    loads.append(load())

    print(f"issue 37 before/after: baseline {base_rev} vs current {head}")
    print(f"  {args.repeat} rounds, baseline and current alternating in fresh processes, each with its own warm "
          f"kernel cache; flip/ROA workers {args.workers}; per process the fastest of its timed calls "
          f"({', '.join(f'{n} {INNER[n]}' for n in names)})")
    print(f"  machine: {os.cpu_count()} cores, shared; 1-min load average over the run {min(loads):.2f} .. "
          f"{max(loads):.2f} (median {statistics.median(loads):.2f})")
    labels = list(dict.fromkeys(label for label, _ in times))
    w = max(len(x) for x in labels) + 2
    print(f"\n{'workload':<{w}} {'base min ms':>12} {'base med ms':>12} {'cur min ms':>11} {'cur med ms':>11} "
          f"{'cur/base (med)':>15} {'(min)':>7}")
    slower = 0
    for label in labels:
        b, c = times[(label, "baseline")], times[(label, "current")]
        rm, rn = statistics.median(c) / statistics.median(b), min(c) / min(b)
        flag = "  SLOWER" if rm > FLAG else ""
        slower += bool(flag)
        print(f"{label:<{w}} {min(b) * 1e3:12.2f} {statistics.median(b) * 1e3:12.2f} {min(c) * 1e3:11.2f} "
              f"{statistics.median(c) * 1e3:11.2f} {rm:15.3f} {rn:7.3f}{flag}")
    print("\ncold first process per tree (the compiles; informative only): "
          + "; ".join(f"{n} {cold[(n, 'baseline')]:.1f} / {cold[(n, 'current')]:.1f} s" for n in names))
    print("results, current against baseline:")
    import numpy as np

    for name in names:
        rr = np.array(ref, dtype=float) if name == "taylor" else None
        for line in compare(name, checks[(name, "baseline")], checks[(name, "current")], rr):
            print(line)
    print(f"\n{slower} of {len(labels)} workloads over {FLAG:.2f} x the baseline (median)" if slower
          else f"\nevery workload within {FLAG:.2f} x the baseline (median)")
    return 0


if __name__ == "__main__":
    sys.exit(main())
