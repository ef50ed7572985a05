"""The test loop's speed (issue 51, item 7): the whole suite (the README's test command, ``python -m
pytest``: every core, slow tests included) and the quick set (``python -m pytest -m "not slow"``), timed
as whole processes, with the ten slowest tests of each run (setup + call + teardown, from pytest's
JUnit XML).

Goals: whole suite <= 8 min, quick set <= 90 s on the 2-core machine.

``--cache warm`` (the default) runs with the project's test cache of compiled kernels
(``.skewpend-test-cache``) as a developer has it after a first run; ``--cache cold`` points
``SKEWPEND_CACHE_DIR`` at a fresh folder first, as a fresh clone (CI) has it. ``--only quick|whole``
runs one of the two. Extra arguments after ``--`` go to pytest.

Run:  python benchmarks/bench_suite.py [--cache warm|cold] [--only quick|whole] [-- -x]
"""

from __future__ import annotations

import argparse
import os
import subprocess
import sys
import tempfile
import time
import xml.etree.ElementTree as ET
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))
from _common import cpu_model  # noqa: E402

ROOT = Path(__file__).resolve().parents[1]
GOALS = {"whole": 8 * 60.0, "quick": 90.0}


def slowest(xml: Path, n: int = 10):
    """The ``n`` slowest test cases of a JUnit XML file: (seconds, node id), and the totals by outcome."""
    cases, outcomes = [], {"passed": 0, "failed": 0, "skipped": 0}
    for case in ET.parse(xml).getroot().iter("testcase"):
        name = f"{case.get('classname', '').replace('.', '/')}.py::{case.get('name')}"
        cases.append((float(case.get("time", 0.0)), name))
        kind = "failed" if case.find("failure") is not None or case.find("error") is not None else \
            "skipped" if case.find("skipped") is not None else "passed"
        outcomes[kind] += 1
    return sorted(cases, reverse=True)[:n], outcomes


def run(which: str, env: dict, extra: list) -> float:
    with tempfile.TemporaryDirectory() as tmp:
        xml = Path(tmp) / "junit.xml"
        argv = [sys.executable, "-m", "pytest", "-q", "-p", "no:cacheprovider", f"--junitxml={xml}", *extra]
        if which == "quick":
            argv[4:4] = ["-m", "not slow"]
        print(f"$ {' '.join(argv[2:])}", flush=True)
        start = time.perf_counter()
        proc = subprocess.run(argv, cwd=ROOT, env=env, stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True)
        took = time.perf_counter() - start
        tail = [line for line in proc.stdout.splitlines() if line.strip()][-1:]
        print(f"  {which}: {took:7.1f} s (goal <= {GOALS[which]:.0f} s: {'met' if took <= GOALS[which] else 'NOT met'}), "
              f"pytest exit {proc.returncode}: {tail[0] if tail else ''}", flush=True)
        if xml.exists():
            cases, outcomes = slowest(xml)
            print(f"  {outcomes}; the ten slowest:")
            for seconds, name in cases:
                print(f"    {seconds:7.2f} s  {name}")
        return took


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--cache", choices=("warm", "cold"), default="warm")
    ap.add_argument("--only", choices=("quick", "whole"), default=None)
    ap.add_argument("pytest_args", nargs="*")
    args = ap.parse_args()
    print(f"machine: {cpu_model()}, {os.cpu_count()} cores; kernel cache: {args.cache}\n", flush=True)
    env = dict(os.environ)
    with tempfile.TemporaryDirectory() as cold:
        if args.cache == "cold":
            env["SKEWPEND_CACHE_DIR"] = cold
        for which in ("quick", "whole"):
            if args.only in (None, which):
                run(which, env, args.pytest_args)
    return 0


if __name__ == "__main__":
    sys.exit(main())
