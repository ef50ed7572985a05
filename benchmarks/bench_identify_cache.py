"""Identification's compiles and warm time (issue 37's goals), whole processes from the command line.

1. An empty kernel cache (a fresh ``SKEWPEND_CACHE_DIR``): ``skewpend identify kaheman2023 --out
   fit.toml``; printed: the time, when its first line came, and every "compiling ..." note (each
   library must be built once: no note twice).
2. Different data of the same structure in that cache: a synthetic free swing of another rig (the
   published model with other masses, centres of mass and inertias; 20 s at 1 kHz, one CSV file, the
   published model as params0 from a run file); goal: no compile note at all.
3. The warm cache: ``skewpend identify kaheman2023 --out fit.toml`` ``--repeat`` times; printed: min,
   median, max of the whole process (goal <= 3 s) and of the first line (goal <= 1 s).

Run:  python benchmarks/bench_identify_cache.py [--repeat 5]      (the table on stdout)
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

import numpy as np

HERE = Path(__file__).resolve().parent


def run(cmd, env):
    """The process's seconds, the seconds to its first stderr line, and its stderr lines."""
    t0 = time.perf_counter()
    proc = subprocess.Popen(cmd, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True, env=env)
    first = proc.stderr.readline()
    t_first = time.perf_counter() - t0
    rest = proc.stderr.read()
    code = proc.wait()
    seconds = time.perf_counter() - t0
    lines = ([first] if first else []) + rest.splitlines()
    if code != 0:
        raise SystemExit(f"{' '.join(map(str, cmd))} failed ({code}):\n" + "".join(lines[-5:]))
    return seconds, t_first, [line.strip() for line in lines]


def compiles(lines):
    return [line for line in lines if "compiling" in line]


def synthetic(tmp: Path):
    """A free swing of another rig of the same structure, as a CSV, and params0's run file."""
    import skewpend
    from skewpend.analysis.measurements import kaheman_published_parameters

    p0 = kaheman_published_parameters(skewpend.example_data("kaheman2023"))
    rig = p0.replace(m1=1.3 * p0.m1, m2=0.8 * p0.m2,
                     com1=(0.0, 0.9 * p0.com1[1], 0.0), com2=(0.0, 1.1 * p0.com2[1], 0.0),
                     inertia1=tuple(tuple(1.2 * x for x in row) for row in p0.inertia1))
    tr = skewpend.simulate(rig, (1.1, -0.7, 0.0, 0.4), 20.0, dt_out=1e-3, rtol=1e-11, atol=1e-11)
    q = np.asarray(tr.y)[:, :2] + np.random.default_rng(0).normal(0, 5e-4, (len(tr.t), 2))
    csv = tmp / "other_rig.csv"
    np.savetxt(csv, np.column_stack([tr.t, q]), delimiter=",", header="time,phi,psi", comments="", fmt="%.12g")
    rows = []
    for k, v in p0.to_dict().items():
        if v is None:
            continue
        text = repr(np.asarray(v, float).tolist()) if isinstance(v, (list, tuple)) else repr(float(v))
        rows.append(f"{k} = {text}")
    (tmp / "p0.toml").write_text("[parameters]\n" + "\n".join(rows) + "\n")
    return csv, tmp / "p0.toml"


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--repeat", type=int, default=5)
    args = ap.parse_args()
    skewpend_cmd = [sys.executable, "-m", "skewpend"]
    with tempfile.TemporaryDirectory() as tmp:
        tmp = Path(tmp)
        env = dict(os.environ, SKEWPEND_CACHE_DIR=str(tmp / "cache"))
        print(f"load {os.getloadavg()[0]:.2f}; {os.cpu_count()} cores", file=sys.stderr)
        fit = tmp / "fit.toml"
        s, f, lines = run(skewpend_cmd + ["identify", "kaheman2023", "--out", str(fit)], env)
        notes = compiles(lines)
        print(f"1. empty cache: identify kaheman2023 --out fit.toml: {s:.2f} s, first line {f:.2f} s; "
              f"{len(notes)} compile notes (params0's bodies and the fit's have their own zero patterns)")
        for n in notes:
            print(f"     {n}")
        csv, p0 = synthetic(tmp)
        s, f, lines = run(skewpend_cmd + ["identify", str(csv), "--format", "csv", "--columns", "t=time,phi=phi,psi=psi",
                                          "--config", str(p0),
                                          "--out", str(tmp / "other.toml")], env)
        notes = compiles(lines)
        print(f"2. another rig of the same structure (20 s, one CSV): {s:.2f} s, first line {f:.2f} s; "
              f"{len(notes)} compile notes" + "".join(f"\n     {n}" for n in notes))
        totals, firsts = [], []
        for _ in range(args.repeat):
            fit.unlink()
            s, f, _ = run(skewpend_cmd + ["identify", "kaheman2023", "--out", str(fit)], env)
            totals.append(s)
            firsts.append(f)
        fmt = lambda v: f"min {min(v):.2f}  median {statistics.median(v):.2f}  max {max(v):.2f} s"  # noqa: E731
        print(f"3. warm cache, {args.repeat} runs: whole process {fmt(totals)} (goal <= 3 s); "
              f"first line {fmt(firsts)} (goal <= 1 s); load {os.getloadavg()[0]:.2f}")
        ok = statistics.median(totals) <= 3.0 and max(firsts) <= 1.0
        print("PASS" if ok else "over a goal", file=sys.stderr)


if __name__ == "__main__":
    main()
