"""Before and after: the headline figure of every benchmark, at two revisions, interleaved.

Issue 15 (the redesign) asks that every benchmark stay within 5 % of its figure before the
change.  This script measures the case behind each benchmark's headline figure at two source
trees -- BASE (a git worktree of the revision before, made here with ``git worktree add``) and
HEAD (this checkout) -- in fresh processes, alternating BASE, HEAD, BASE, HEAD ... so that the
machine's load falls on both alike, each tree with its own kernel cache (``SKEWPEND_CACHE_DIR``,
warmed before timing).  It prints, for each case, the median of each tree, the ratio HEAD/BASE,
and whether it is within 5 %.  Each timed process reports the fastest call's wall time and the CPU time
(``time.process_time``: every thread of the process) of that call; a whole-process case reports the
child's wall and CPU time (``getrusage``).  Both medians are printed: on a loaded machine the CPU time is
the steadier of the two.

Results: each case that returns numbers (end states, flip and capture times, exponents) saves them in
the warming process of each tree, and the script prints the largest difference between the trees
(absolute, and relative ``|head - base| / max(|head|, |base|)``) and whether it is within 1e-12, and
the cells finite in one tree only.

``--callgrind`` also counts each in-process case's instructions inside the compiled kernels, one call
on the warm cache: ``valgrind --tool=callgrind --collect-atstart=no --toggle-collect=ffi_call`` -- every
instruction inside ctypes' foreign calls (the entry points ``sp_dop853``, ``sp_taylor``, ``sp_flip``,
``sp_capture_lanes``, ``sp_lyap`` ... and their small helpers such as the state sizes).  The count
does not depend on the machine's load; the verdict then reads the instruction ratio, else the CPU
time's.  (Toggling on the entry points themselves counts nothing: gcc turns their calls of the
integrator into jumps.)

Cases (the workloads of the benchmark scripts named):

* ``simulate``  -- bench_simulate.py: dop853, 20 s, rtol = atol = 1e-10, warm, in process;
  ``simulate-default`` -- bench_simulate.py's headline: the same with no method named (the default:
  dop853 at revisions before ``"auto"``, the rule's choice after);
* ``rk4``, ``gauss`` -- bench_simulate.py: the fixed-step methods, dt = 1e-3, 20 s;
* ``taylor-6``, ``taylor-9``, ``taylor-12`` -- bench_precision.py's and bench_model_data.py's
  work-precision case: ``simulate(method="taylor")`` over 20 s at rtol = atol = 1e-6, 1e-9, 1e-12;
* ``flipmap-2w``, ``flipmap-1w`` -- bench_flipmap.py: the 128 x 128 map, t_end = 10 s (the 1-worker map
  is bench_model_data.py's ``flip``);
* ``roa`` -- bench_roa.py: the 256 x 256 region of attraction over 10 s, alpha = 30 deg, the LQR about
  up-up with both joints and |u| <= 10 N m, both workers; ``roa-64`` -- bench_model_data.py's ROA lanes:
  the same at 64 x 64 on one worker;
* ``lyapunov``, ``lyapunov-1`` -- bench_lyapunov.py: the full spectrum over 1000 s at 1e-10, the
  largest exponent at 1e-6 (bench_model_data.py's ``lyapunov`` is the full spectrum too);
* ``derive`` -- bench_derive.py: ``derive()`` all symbolic, in a fresh process;
* ``cli-simulate`` -- bench_first_use.py: ``skewpend simulate`` on a warm cache, the whole process;
* ``report`` (with ``--views``) -- bench_views.py: ``skewpend report`` cached.

Run:  python benchmarks/compare.py [--base REV] [--repeat 5] [--views] [--callgrind] [--cache DIR] [--only CASE ...]
"""

from __future__ import annotations

import argparse
import os
import statistics
import subprocess
import sys
import tempfile
import textwrap
import time
from pathlib import Path

import numpy as np

HERE = Path(__file__).resolve().parent
HEAD = HERE.parent

_SETUP = """
import math, os, time, numpy as np
from skewpend import Parameters
P = Parameters(a=1.0, b=0.8, m1=1.0, m2=0.7, alpha=0.6, g=9.81)
Y0 = np.array([1.2, -0.8, 0.0, 0.0])
def timed(fn, n):
    out = fn()  # warm: the kernel compiled or loaded, caches filled
    if os.environ.get("COMPARE_CALLGRIND"):  # one call, counted by callgrind in the C entry point
        return out
    ts = []
    for _ in range(n):
        t0, c0 = time.perf_counter(), time.process_time()
        out = fn()
        ts.append((time.perf_counter() - t0, time.process_time() - c0))
    print(*min(ts))
    return out
def keep(*arrays):  # the case's results, saved by the warming process for the comparison of the trees
    path = os.environ.get("COMPARE_OUT")
    if path:
        np.save(path, np.concatenate([np.asarray(a, dtype=float).ravel() for a in arrays]))
"""

#: case -> (Python code printing one time in seconds, or a command line timed whole)
_ROA = ("from skewpend import lqr\nfrom skewpend.analysis.roa import region_of_attraction\n"
        "P30 = P.replace(alpha=math.radians(30.0))\nd = lqr(P30, 'up-up', 'both', umax=10.0)\n"
        "r = timed(lambda: region_of_attraction(P30, n={n}, design=d, t_end=10.0, workers={w}), {k})\n"
        "keep(r.capture_time, r.outcome)")
_TAYLOR = ("from skewpend import simulate\n"
           "r = timed(lambda: simulate(P, Y0, 20.0, method='taylor', rtol={tol}, atol={tol}), 25)\nkeep(r.y[-1])")
CASES = {
    "simulate": ("from skewpend import simulate\n"
                 "r = timed(lambda: simulate(P, Y0, 20.0, method='dop853', rtol=1e-10, atol=1e-10), 15)\nkeep(r.y[-1])"),
    "simulate-default": ("from skewpend import simulate\n"
                         "r = timed(lambda: simulate(P, Y0, 20.0, rtol=1e-10, atol=1e-10), 15)\nkeep(r.y[-1])"),
    "rk4": ("from skewpend import simulate\n"
            "r = timed(lambda: simulate(P, Y0, 20.0, method='rk4', dt=1e-3), 7)\nkeep(r.y[-1])"),
    "gauss": ("from skewpend import simulate\n"
              "r = timed(lambda: simulate(P, Y0, 20.0, method='gauss', dt=1e-3), 5)\nkeep(r.y[-1])"),
    "taylor-6": _TAYLOR.format(tol=1e-6),
    "taylor-9": _TAYLOR.format(tol=1e-9),
    "taylor-12": _TAYLOR.format(tol=1e-12),
    "flipmap-2w": "from skewpend import flip_map\nr = timed(lambda: flip_map(P, 128, workers=2), 9)\nkeep(r.flip_time)",
    "flipmap-1w": "from skewpend import flip_map\nr = timed(lambda: flip_map(P, 128, workers=1), 7)\nkeep(r.flip_time)",
    "roa": _ROA.format(n=256, w=2, k=3),
    "roa-64": _ROA.format(n=64, w=1, k=5),
    "lyapunov": "from skewpend import lyapunov\nr = timed(lambda: lyapunov(P, Y0, t_end=1000.0), 5)\nkeep(r.exponents)",
    "lyapunov-1": ("from skewpend import lyapunov\n"
                   "r = timed(lambda: lyapunov(P, Y0, t_end=1000.0, n_exponents=1, rtol=1e-6, atol=1e-6), 7)\n"
                   "keep(r.exponents)"),
    "derive": ("import time\nt0, c0 = time.perf_counter(), time.process_time()\nimport skewpend\nskewpend.derive()\n"
               "print(time.perf_counter() - t0, time.process_time() - c0)"),
    "cli-simulate": ["-m", "skewpend", "simulate", "--quiet"],
}
VIEWS = {"report": ["-m", "skewpend", "report", "--quiet", "--out", "{tmp}/report.html"]}
#: callgrind counts inside ctypes' foreign calls: the kernels' entry points (sp_dop853, sp_taylor, sp_flip,
#: sp_capture_lanes, sp_lyap ...) are entered by jumps gcc makes of tail calls at both revisions, which
#: ``--toggle-collect=<entry>`` does not see as calls (it counted 0); libffi's ffi_call is called every time
TOGGLE = "ffi_call"


def _env(tree: Path, cache: Path, **extra) -> dict:
    env = dict(os.environ, PYTHONPATH=str(tree / "src"), SKEWPEND_CACHE_DIR=str(cache), **extra)
    env.pop("SKEWPEND_PROGRESS", None)
    # a user's install keeps the compiled bytecode (__pycache__); without it every process compiles every
    # module it imports from source, and a whole-process case counts the compiler (more code, more instructions)
    env.pop("PYTHONDONTWRITEBYTECODE", None)
    return env


def _run(argv, env, tmp: Path) -> subprocess.CompletedProcess:
    out = subprocess.run(argv, env=env, capture_output=True, text=True, cwd=tmp)
    if out.returncode != 0:
        raise RuntimeError(f"{argv[:3]} failed ({out.returncode}) with PYTHONPATH={env['PYTHONPATH']}:\n"
                           f"{out.stderr[-3000:]}")
    return out


def run_case(tree: Path, cache: Path, case, tmp: Path, keep: Path = None) -> tuple:
    """(wall s, CPU s) of one fresh process's measurement; ``keep``: where the case saves its results."""
    env = _env(tree, cache, **({"COMPARE_OUT": str(keep)} if keep else {}))
    if isinstance(case, str):
        out = _run([sys.executable, "-c", textwrap.dedent(_SETUP) + case], env, tmp)
        wall, cpu = out.stdout.strip().splitlines()[-1].split()
        return float(wall), float(cpu)
    import resource

    argv = [a.replace("{tmp}", str(tmp)) for a in case]
    r0 = resource.getrusage(resource.RUSAGE_CHILDREN)
    t0 = time.perf_counter()
    _run([sys.executable, *argv], env, tmp)
    wall = time.perf_counter() - t0
    r1 = resource.getrusage(resource.RUSAGE_CHILDREN)
    return wall, (r1.ru_utime - r0.ru_utime) + (r1.ru_stime - r0.ru_stime)


def instructions(tree: Path, cache: Path, name: str, case: str, tmp: Path) -> int:
    """Instructions executed inside the case's C entry points in one call (callgrind, warm cache)."""
    outfile = tmp / f"callgrind.{name}.{tree.name}.out"
    argv = ["valgrind", "--tool=callgrind", "--collect-atstart=no", f"--callgrind-out-file={outfile}",
            f"--toggle-collect={TOGGLE}",
            sys.executable, "-c", textwrap.dedent(_SETUP) + case]
    _run(argv, _env(tree, cache, COMPARE_CALLGRIND="1"), tmp)
    for line in outfile.read_text().splitlines():
        if line.startswith(("summary:", "totals:")):
            return int(line.split()[1])
    raise RuntimeError(f"no totals in {outfile}")


def differences(a: np.ndarray, b: np.ndarray) -> str:
    """How far two trees' results are apart (NaN where a cell has no value)."""
    if a.shape != b.shape:
        return f"shapes differ: {a.shape} / {b.shape}"
    both = np.isfinite(a) & np.isfinite(b)
    one = int(np.sum(np.isfinite(a) != np.isfinite(b)))
    d = np.abs(a[both] - b[both])
    scale = np.maximum(np.abs(a[both]), np.abs(b[both]))
    rel = np.divide(d, scale, out=np.zeros_like(d), where=scale > 0)
    dabs, drel = (float(d.max()), float(rel.max())) if d.size else (0.0, 0.0)
    ok = drel <= 1e-12 and one == 0
    return (f"max |diff| {dabs:.2e}, max rel. {drel:.2e} over {int(both.sum())} values"
            + (f", {one} finite in one tree only" if one else "") + f"  {'same to 1e-12' if ok else 'DIFFER'}")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--base", default="a22fb08", help="the revision before the change (default a22fb08)")
    ap.add_argument("--repeat", type=int, default=5, help="processes per case and tree (median reported; 0: results and --callgrind only)")
    ap.add_argument("--views", action="store_true", help="also the report (about 10 s per run)")
    ap.add_argument("--callgrind", action="store_true", help="also count instructions in the C entry points")
    ap.add_argument("--cache", type=Path, help="keep both trees' kernel caches in this directory (the next run "
                    "compiles nothing)")
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
            caches = {name: (args.cache or tmp) / f"cache-{name}-{rev}"
                      for name, rev in (("base", args.base), ("head", "tree"))}
            times = {(c, t): [] for c in cases for t in trees}
            counts, results, loads = {}, {}, [os.getloadavg()[0]]
            for c, case in cases.items():
                for t in trees:  # warm each cache, untimed; the results saved
                    keep = tmp / f"result-{c}-{t}.npy" if isinstance(case, str) else None
                    run_case(trees[t], caches[t], case, tmp, keep)
                    if keep is not None and keep.exists():
                        results[(c, t)] = np.load(keep)
                for r in range(args.repeat):
                    for t in (trees if r % 2 == 0 else list(trees)[::-1]):  # B H, then H B
                        times[(c, t)].append(run_case(trees[t], caches[t], case, tmp))
                        loads.append(os.getloadavg()[0])
                if args.callgrind and isinstance(case, str):
                    for t in trees:
                        counts[(c, t)] = instructions(trees[t], caches[t], c, case, tmp)
                        print(f"[compare] {c} {t}: {counts[(c, t)]:,} instructions", file=sys.stderr, flush=True)
                med = [statistics.median(x[i] for x in times[(c, t)]) for t in trees for i in (0, 1)] \
                    if args.repeat > 0 else []
                print(f"[compare] {c} done (load {loads[-1]:.2f}); base wall, cpu, head wall, cpu: {med}",
                      file=sys.stderr, flush=True)
            print(f"base {args.base} against HEAD {HEAD}; {args.repeat} processes per case and tree, alternating; "
                  f"{os.cpu_count()} cores, 1-min load {min(loads):.2f} .. {max(loads):.2f} "
                  f"(median {statistics.median(loads):.2f}); {time.strftime('%Y-%m-%d %H:%M %Z')}")
            print(f"{'case':<12} {'base wall':>10} {'head wall':>10} {'ratio':>6}  {'base cpu':>10} {'head cpu':>10} "
                  f"{'ratio':>6}  {'instr. ratio':>12}  within 5 %")
            for c in cases if args.repeat > 0 else ():
                (bw, bc), (hw, hc) = [[statistics.median(x[i] for x in times[(c, t)]) for i in (0, 1)]
                                      for t in trees]
                line = f"{c:<12} {bw:10.4f} {hw:10.4f} {hw / bw:6.3f}  {bc:10.4f} {hc:10.4f} {hc / bc:6.3f}  "
                judged = hc / bc
                if counts.get((c, "base")) and counts.get((c, "head")):
                    ib, ih = counts[(c, "base")], counts[(c, "head")]
                    line += f"{ih / ib:12.4f}"
                    judged = ih / ib
                else:
                    line += f"{'':>12}"
                print(line + f"  {'yes' if judged <= 1.05 else 'NO'}" + ("" if counts.get((c, "base")) else " (CPU)"))
            if counts:
                print("\ninstructions in the C entry points (callgrind, one call):")
                for c in cases:
                    if (c, "base") in counts:
                        print(f"  {c:<12} base {counts[(c, 'base')]:>15,}  head {counts[(c, 'head')]:>15,}")
            if results:
                print("\nresults, head against base:")
                for c in cases:
                    if (c, "base") in results and (c, "head") in results:
                        print(f"  {c:<12} {differences(results[(c, 'base')], results[(c, 'head')])}")
        finally:
            subprocess.run(["git", "-C", str(HEAD), "worktree", "remove", "--force", str(base)], check=False)


if __name__ == "__main__":
    main()
