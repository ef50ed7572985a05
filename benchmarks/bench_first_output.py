"""No silent waits (issue 36, goal 4): every command's first output within 1 s of its start.

Each command below runs as a whole new process (``python -m skewpend ...``, as a user or a script
starts it), on a short, cheap instance; the time from ``Popen`` to the first byte on stdout or
stderr is measured (``time.perf_counter``; both streams are pipes, read as the bytes arrive), and
so is the whole run.  Also printed: the longest silence while the process ran (the largest gap
between two arrivals of output, or from the last one to the exit) -- off a terminal a command writes
one line per stage, so a long stage is a long silence there; on a terminal (``--tty``: stderr is a
pseudo-terminal) Rich's live line moves several times a second.

Cache: ``fresh`` runs have an empty kernel cache (``SKEWPEND_CACHE_DIR`` a new temporary directory
per run: the kernels are generated and compiled, the report's symbolic sections derived);
``warm`` runs share one cache directory that an untimed run of the same command filled first.
``serve`` is stopped (by its process id) once it has said where it serves.

    python benchmarks/bench_first_output.py [--only NAME[,NAME...]] [--tty] [--no-fresh] [--limit 1.0]

Goal: first output <= ``--limit`` seconds (1 s) for every row: PASS / FAIL in the table.
"""

from __future__ import annotations

import argparse
import os
import platform
import re
import selectors
import shutil
import socket
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
KAHEMAN = ROOT / "data" / "kaheman2023"

#: (name, arguments, cases): the cheap instance of each command; ``{tmp}`` is a scratch directory,
#: ``{port}`` a free TCP port; cases: "warm" and/or "fresh".
COMMANDS = [
    ("derive", ["derive"], ("warm",)),
    ("derive --steps", ["derive", "--steps", "--linear"], ("warm",)),
    ("simulate", ["simulate", "--t-end", "2"], ("fresh", "warm")),
    ("animate", ["animate", "--t-end", "1", "--fps", "10", "--size", "160x120", "--out", "{tmp}/a.gif"], ("warm",)),
    ("report", ["report", "--t-end", "2", "--out", "{tmp}/r.html"], ("fresh", "warm")),
    ("flipmap", ["flipmap", "--n", "16", "--t-end", "2"], ("fresh", "warm")),
    ("lyapunov", ["lyapunov", "--t-end", "20"], ("fresh", "warm")),
    ("poincare", ["poincare", "--energy", "5", "--orbits", "4", "--crossings", "20"], ("warm",)),
    ("chaos-diagram", ["chaos-diagram", "--alphas", "0:90deg:2", "--energies", "1:5:2", "--samples", "2",
                       "--t-end", "10"], ("warm",)),
    ("serve", ["serve", "--port", "{port}"], ("warm",)),
    ("serve --export", ["serve", "--export", "{tmp}/site"], ("warm",)),
    ("export", ["export"], ("warm",)),
    ("validate", ["validate", "--t-end", "0.2"], ("warm",)),
    ("modes", ["modes"], ("warm",)),
    ("modes --sweep", ["modes", "--sweep", "alpha=0:180deg:19"], ("warm",)),
    ("equilibria", ["equilibria"], ("warm",)),
    ("orbit", ["orbit", "--mode", "1", "--energy", "0.5"], ("warm",)),
    ("nnm", ["nnm", "--mode", "1", "--energy-max", "1", "--resolution", "10"], ("warm",)),
    ("control lqr", ["control", "lqr"], ("warm",)),
    ("control swingup", ["control", "swingup", "--t-end", "5"], ("warm",)),
    ("control roa", ["control", "roa", "--n", "8", "--t-end", "2"], ("warm",)),
    ("identify", ["identify", str(KAHEMAN), "--method", "linear"], ("fresh", "warm")),
    ("identify output-error", ["identify", str(KAHEMAN)], ("warm",)),
]


def free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def run(args, env, *, tty: bool, stop_at_first: bool, timeout: float = 900.0):
    """(seconds to the first byte, whole run, longest silence, exit status, the first line)."""
    master = None
    if tty:
        import pty

        master, slave = pty.openpty()
        stderr = slave
    else:
        stderr = subprocess.PIPE
    start = time.perf_counter()
    proc = subprocess.Popen([sys.executable, "-m", "skewpend", *args], stdout=subprocess.PIPE, stderr=stderr,
                            stdin=subprocess.DEVNULL, env=env, cwd=env["BENCH_CWD"])
    if tty:
        os.close(slave)
    sel = selectors.DefaultSelector()
    streams = [proc.stdout.fileno(), master if tty else proc.stderr.fileno()]
    for fd in streams:
        os.set_blocking(fd, False)
        sel.register(fd, selectors.EVENT_READ)
    first, last, gap, text = None, start, 0.0, b""
    open_fds = set(streams)
    try:
        first, last, gap, text = _read(proc, sel, open_fds, start, timeout, stop_at_first)
    finally:
        if proc.poll() is None and stop_at_first or sys.exc_info()[0] is not None:
            proc.terminate()  # this benchmark's own child, by its process id (serve; or on Ctrl-C)
    code = proc.wait(timeout=60)
    end = time.perf_counter()
    gap = max(gap, end - last) if not stop_at_first else gap
    if master is not None:
        os.close(master)
    shown = re.sub(r"\x1b\[[0-9;?]*[A-Za-z]", "", text.decode("utf-8", "replace"))  # a terminal's colours and moves
    line = shown.replace("\r", "\n").strip().splitlines()
    return first, end - start, gap, code, (line[0] if line else "")


def _read(proc, sel, open_fds, start: float, timeout: float, stop_at_first: bool):
    """Read both streams as the bytes arrive: (first arrival, last arrival, largest gap, the first bytes)."""
    first, last, gap, text = None, start, 0.0, b""
    while open_fds and time.perf_counter() - start < timeout:
        for key, _ in sel.select(timeout=0.05):
            try:
                chunk = os.read(key.fd, 65536)
            except OSError:  # a pty whose other end closed
                chunk = b""
            if not chunk:
                sel.unregister(key.fd)
                open_fds.discard(key.fd)
                continue
            now = time.perf_counter()
            gap = max(gap, now - last)
            last = now
            if first is None:
                first = now - start
            if len(text) < 400:
                text += chunk
        if first is not None and stop_at_first:
            break
    return first, last, gap, text


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--only", help="comma-separated names (a prefix matches: 'report', 'control')")
    ap.add_argument("--tty", action="store_true", help="stderr is a pseudo-terminal (Rich's live line)")
    ap.add_argument("--no-fresh", action="store_true", help="warm runs only")
    ap.add_argument("--limit", type=float, default=1.0, help="the goal for the first output [s] (default 1)")
    opts = ap.parse_args()
    only = [s.strip() for s in opts.only.split(",")] if opts.only else None
    print(f"# skewpend first output, {platform.python_version()} on {platform.machine()}, {os.cpu_count()} cores, "
          f"stderr {'a terminal' if opts.tty else 'a pipe'}; goal: first output <= {opts.limit:g} s")
    scratch = Path(tempfile.mkdtemp(prefix="skewpend-first-output-"))
    warm_cache = scratch / "warm-cache"
    base = {**os.environ, "SKEWPEND_DEBUG": "", "BENCH_CWD": str(scratch), "COLUMNS": "100"}
    base.pop("SKEWPEND_QUIET", None)
    rows, failed = [], 0
    try:
        for name, args, cases in COMMANDS:
            if only and not any(name.startswith(o) for o in only):
                continue
            if name.startswith("identify") and not KAHEMAN.is_dir():
                continue
            for case in cases:
                if case == "fresh" and opts.no_fresh:
                    continue
                tmp = Path(tempfile.mkdtemp(dir=scratch))
                argv = [a.format(tmp=tmp, port=free_port()) for a in args]
                serve = name == "serve"
                if case == "fresh":
                    env = {**base, "SKEWPEND_CACHE_DIR": str(tmp / "cache")}
                else:
                    env = {**base, "SKEWPEND_CACHE_DIR": str(warm_cache)}
                    warmup = [a.replace(str(tmp), str(tmp) + "-warmup") for a in argv]
                    Path(str(tmp) + "-warmup").mkdir(exist_ok=True)
                    run(warmup, env, tty=False, stop_at_first=serve)
                    argv = [a.format(tmp=tmp, port=free_port()) for a in args]
                first, whole, gap, code, line = run(argv, env, tty=opts.tty, stop_at_first=serve)
                ok = first is not None and first <= opts.limit
                failed += not ok
                rows.append((name, case, first, whole, gap, code, ok, line))
                print(f"  {name:24s} {case:5s} first {first if first is not None else float('nan'):6.2f} s  "
                      f"whole {whole:6.1f} s  {'PASS' if ok else 'FAIL'}  | {line[:70]}", file=sys.stderr, flush=True)
    finally:
        shutil.rmtree(scratch, ignore_errors=True)
    print()
    print("| command | cache | first output [s] | whole run [s] | longest silence [s] | exit | first line | goal |")
    print("| --- | --- | ---: | ---: | ---: | ---: | --- | --- |")
    for name, case, first, whole, gap, code, ok, line in rows:
        shown = "none" if first is None else f"{first:.2f}"
        silence = "(stopped)" if name == "serve" else f"{gap:.1f}"
        cut = line if len(line) <= 60 else line[:57] + "..."
        cut = cut.replace("|", "\\|")
        print(f"| {name} | {case} | {shown} | {whole:.1f} | {silence} | {code} | `{cut}` | {'PASS' if ok else 'FAIL'} |")
    print()
    print(f"{len(rows) - failed} of {len(rows)} PASS (first output <= {opts.limit:g} s)")


if __name__ == "__main__":
    main()
