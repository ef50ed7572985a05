"""Helpers the tests share: running the command line in-process or as a real process, and the
checks of the project's rule for bad input (one line, exit status 2, nothing left behind)."""

from __future__ import annotations

import contextlib
import io
import os
import re
import signal
import subprocess
import sys
import time
import warnings
from dataclasses import dataclass
from pathlib import Path
from typing import Iterable, Optional, Sequence

#: Debian's Chromium, driven by Playwright in the browser tests (``playwright install`` cannot
#: download here), and its headless flags with WebGL drawn by SwiftShader.
CHROMIUM = "/usr/bin/chromium"
WEBGL_ARGS = ["--no-sandbox", "--use-angle=swiftshader", "--enable-unsafe-swiftshader", "--no-first-run",
              "--disable-background-networking", "--disable-component-update", "--disable-sync"]


def once_per_session(tmp_path_factory, name: str, make):
    """``make(directory)`` run once per test session, whichever worker (pytest-xdist) asks first, the others
    waiting for it: under a file lock in the session's shared temporary directory.  ``make`` returns a
    JSON-able value, which every caller gets (the one who made it too)."""
    import fcntl
    import json

    shared = tmp_path_factory.getbasetemp()
    shared = shared.parent if shared.name.startswith("popen-gw") else shared  # the session's, not the worker's
    folder = shared / name
    folder.mkdir(exist_ok=True)
    outcome = folder / "outcome.json"
    with open(folder / ".lock", "w") as lock:
        fcntl.flock(lock, fcntl.LOCK_EX)  # released when the file closes
        if not outcome.exists():
            outcome.write_text(json.dumps(make(folder)), encoding="utf-8")
        return json.loads(outcome.read_text(encoding="utf-8"))


#: Documented commands whose run is shared (docs/getting-started.md, docs/guide/control.md): each runs once per
#: session, exactly as written, in a working directory of its own; tests/test_readme.py checks its outcome as
#: the example's, and the tests that need the same run read its output and the file it wrote (a report is the
#: suite's most expensive run; a leaderboard's run optimises, tracks and scores: 5-10 s each).
SHARED_COMMANDS = {
    "skewpend report": "report.html",
    "skewpend report --alpha 30deg --c1 0.05 --out damped.html": "damped.html",
    # tests/test_leaderboard.py (the planar acrobot's CSV and figure), tests/test_mpc.py (v3, the MPC by default)
    "skewpend control leaderboard --robot acrobot --out acrobot.csv --plot acrobot.png": "acrobot.csv",
    "skewpend control leaderboard --robot acrobot --version v3 --out acrobot-v3.csv": "acrobot-v3.csv",
    "skewpend control leaderboard --robot pendubot --version v3": None,
}


def shared_cli_run(tmp_path_factory, command: str) -> dict:
    """``command`` (one of :data:`SHARED_COMMANDS`) run once per session by the README test's runner
    (a child of its warm interpreter, in a copy of the project's examples/), whichever test asks
    first: ``{"returncode", "output", "seconds", "dir"}``."""
    import hashlib
    import shlex

    import readme_runner as rr

    if command not in SHARED_COMMANDS:
        raise KeyError(command)

    def make(folder):
        run = rr.make_workdir(folder / "run")
        argv = shlex.split(command)[1:]
        out = rr.Warm.run(argv, run, rr.TIMEOUT) if hasattr(os, "fork") else rr.run_cli(
            rr.CliExample(line=0, command=command, block=0), run)
        return {"returncode": out.returncode, "output": out.output, "seconds": out.seconds, "dir": str(run)}

    return once_per_session(tmp_path_factory, "cli-" + hashlib.sha1(command.encode()).hexdigest()[:12], make)


def shared_report(tmp_path_factory, command: str = "skewpend report") -> Path:
    """The report written by the shared run of ``command`` (docs/getting-started.md's; read by
    tests/test_report.py and tests/test_report_browser.py); the run must have succeeded."""
    made = shared_cli_run(tmp_path_factory, command)
    assert made["returncode"] == 0, f"{command} failed (exit {made['returncode']}):\n{made['output'][-3000:]}"
    return Path(made["dir"]) / SHARED_COMMANDS[command]


def default_report(tmp_path_factory) -> Path:
    """``skewpend report`` with every default, run once per session (:func:`shared_report`)."""
    return shared_report(tmp_path_factory, "skewpend report")


def under_ci() -> bool:
    """Whether this run is CI's (``CI=true``, as CI services and ``.ci/run`` set it)."""
    return os.environ.get("CI", "").strip().lower() in ("1", "true", "yes")


def missing_browser() -> Optional[str]:
    """Why the browser tests cannot run on this machine, or None when they can."""
    import importlib.util

    if importlib.util.find_spec("playwright") is None:
        return "Playwright is not installed (pip install -e '.[test]')"
    if not os.path.exists(CHROMIUM):
        return f"Chromium is not installed at {CHROMIUM} (Debian: apt-get install chromium)"
    return None


def missing_node() -> Optional[str]:
    """Why the docs' build cannot run here (it renders formulas with KaTeX under Node.js), or None."""
    import shutil

    return None if shutil.which("node") else "Node.js is not installed ('node' is not on PATH; Debian: apt-get install nodejs)"


def needs(reason: Optional[str]) -> list:
    """Marks for a module whose tests need a tool that is missing for ``reason`` (None: nothing is
    missing): the tests are skipped with the reason -- but under CI (``CI=true``) they fail with it,
    so that CI never goes green by skipping (conftest.py's ``pytest_runtest_setup``)."""
    import pytest

    return [] if reason is None else [pytest.mark.needs_tool(reason)]


def skip_or_fail(reason: Optional[str]) -> None:
    """In a test or fixture: skip for ``reason`` -- or fail under CI (see :func:`needs`)."""
    import pytest

    if reason is None:
        return
    if under_ci():
        pytest.fail(f"{reason} (CI=true: a missing tool fails the run; it is never skipped)", pytrace=False)
    pytest.skip(reason)


@contextlib.contextmanager
def chromium():
    """A headless Chromium with WebGL (for a module-scoped ``browser`` fixture)."""
    from playwright.sync_api import sync_playwright

    with sync_playwright() as pw:
        browser = pw.chromium.launch(executable_path=CHROMIUM, headless=True, args=WEBGL_ARGS)
        try:
            yield browser
        finally:
            browser.close()


#: The command line as a process.
SKEWPEND = [sys.executable, "-m", "skewpend"]


@dataclass
class Ran:
    """What a run of the command line gave: exit status, stdout, stderr -- without the lines that
    say a stage of the work (``skewpend CMD: STAGE... (T s)``, :data:`skewpend.progress.STAGE_LINE`;
    a slow check or a long run says them before its error or result line), which are in ``stages``."""

    code: int
    out: str
    err: str
    stages: tuple = ()

    @classmethod
    def split(cls, code: int, out: str, err: str) -> "Ran":
        kept, stages = without_stages(err)
        return cls(code, out, kept, stages)

    def report(self) -> str:
        return f"exit status {self.code}\nstderr: {self.err!r}\nstdout: {self.out[:300]!r}"


def run_cli(argv: Sequence[str], cwd: Optional[os.PathLike] = None) -> Ran:
    """``skewpend ARGV`` in this process (``skewpend.cli.main``), in ``cwd``; warnings always shown."""
    from skewpend.cli import main

    out, err = io.StringIO(), io.StringIO()
    here = os.getcwd()
    shown = warnings.showwarning  # main() replaces it
    debug = os.environ.pop("SKEWPEND_DEBUG", None)  # it would turn an internal error into a traceback
    try:
        if cwd is not None:
            os.chdir(cwd)
        with warnings.catch_warnings(), contextlib.redirect_stdout(out), contextlib.redirect_stderr(err):
            warnings.simplefilter("always")  # a warning printed on top of the error line must show
            try:
                main([str(a) for a in argv])
                code = 0
            except SystemExit as exc:
                code = exc.code if isinstance(exc.code, int) else (0 if exc.code is None else 1)
    finally:
        os.chdir(here)
        warnings.showwarning = shown
        if debug is not None:
            os.environ["SKEWPEND_DEBUG"] = debug
    return Ran.split(code, out.getvalue(), err.getvalue())


def without_stages(err: str):
    """``err`` without the stage lines (issue 36: off a terminal a command says each stage of its work
    on stderr), and those lines."""
    from skewpend.progress import STAGE_LINE

    lines = err.splitlines(keepends=True)
    stages = tuple(line.rstrip("\n") for line in lines if STAGE_LINE.match(line.rstrip("\n")))
    return "".join(line for line in lines if not STAGE_LINE.match(line.rstrip("\n"))), stages


def completed(argv: Sequence, cwd: Optional[os.PathLike] = None, *, timeout: float = 300, env=None,
              check: bool = False) -> subprocess.CompletedProcess:
    """``python -m skewpend ARGV`` as a real process, as a user runs it (``env`` added to this
    process's environment; ``check``: assert exit status 0, showing stderr)."""
    proc = subprocess.run([*SKEWPEND, *map(str, argv)], cwd=cwd, capture_output=True, text=True, timeout=timeout,
                          env={**os.environ, "SKEWPEND_DEBUG": "", **(env or {})})
    proc.stderr, proc.stages = without_stages(proc.stderr)  # the stage lines apart (see Ran)
    if check:
        assert proc.returncode == 0, proc.stderr
    return proc


def run_process(argv: Sequence[str], cwd: Optional[os.PathLike] = None, *, timeout: float = 120, env=None) -> Ran:
    """``python -m skewpend ARGV`` as a real process, as a :class:`Ran`."""
    proc = completed(argv, cwd, timeout=timeout, env=env)
    return Ran(proc.returncode, proc.stdout, proc.stderr, proc.stages)


def signal_process(argv: Sequence[str], cwd: os.PathLike, *, after: float, signum: int = signal.SIGINT,
                   ready: Optional[str] = None):
    """Start ``python -m skewpend ARGV``, wait ``after`` seconds -- or, with ``ready`` (a glob in
    ``cwd``), until a file matches it and ``after`` seconds more -- send ``signum``; (Ran, seconds
    from the signal to the exit)."""
    proc = subprocess.Popen([*SKEWPEND, *map(str, argv)], cwd=cwd, stdout=subprocess.PIPE, stderr=subprocess.PIPE,
                            text=True)
    if ready is not None:
        limit = time.monotonic() + 120
        while not list(Path(cwd).glob(ready)) and proc.poll() is None and time.monotonic() < limit:
            time.sleep(0.05)
    deadline = time.monotonic() + after
    while time.monotonic() < deadline and proc.poll() is None:
        time.sleep(0.05)
    assert proc.poll() is None, proc.communicate()
    sent = time.monotonic()
    proc.send_signal(signum)
    out, err = proc.communicate(timeout=60)
    return Ran.split(proc.returncode, out, err), time.monotonic() - sent


def snapshot(root: Path) -> set:
    """Every file and directory under ``root`` (to tell what a run left behind)."""
    return {str(p.relative_to(root)) for p in Path(root).rglob("*")}


def matches(fragment, line: str) -> bool:
    """A plain fragment is found case-insensitively; a compiled pattern is searched."""
    if isinstance(fragment, re.Pattern):
        return fragment.search(line) is not None
    return fragment.lower() in line.lower()


def assert_refused(ran: Ran, fragments: Iterable = (), root: Optional[Path] = None, before: Optional[set] = None) -> str:
    """The rule for bad input: exit status 2, exactly one stderr line ``skewpend: error: ...``
    holding every fragment, no traceback, nothing on stdout, no file left in ``root``."""
    report = ran.report()
    assert "Traceback" not in ran.err and "Traceback" not in ran.out, report
    assert ran.code == 2, report
    lines = ran.err.splitlines()
    assert len(lines) == 1 and lines[0].startswith("skewpend: error:"), report
    missing = [f.pattern if isinstance(f, re.Pattern) else f for f in fragments if not matches(f, lines[0])]
    assert not missing, f"the message lacks {missing}\n{report}"
    assert ran.out == "", report
    if root is not None:
        left = snapshot(root) - (before or set())
        assert not left, f"files left behind: {sorted(left)}\n{report}"
    return lines[0]


def sympy_reference(params):
    """Accelerations ``acc(y)`` and energy ``en(y)`` of a numeric model straight from SymPy (the
    derivation's M and f, LU-solved and lambdified): an independent check of the generated code."""
    import numpy as np
    import sympy as sp

    from skewpend import derive
    from skewpend.symbolic.derivation import SYMBOLS

    eom = derive(params)
    args = [SYMBOLS[n] for n in ("phi", "psi", "dphi", "dpsi")]
    acc = sp.lambdify(args, eom.mass_matrix.LUsolve(eom.forcing), "numpy")
    en = sp.lambdify(args, eom.kinetic_energy + eom.potential_energy, "numpy")
    return lambda y: np.array(acc(*y), float).ravel(), lambda y: float(en(*y))



def artifacts(folder: str) -> Path:
    """Where a browser test keeps its screenshots: ``$SKEWPEND_ARTIFACTS/folder`` (default ``tests/artifacts/folder``)."""
    root = Path(os.environ.get("SKEWPEND_ARTIFACTS") or Path(__file__).resolve().parent / "artifacts")
    out = root / folder
    out.mkdir(parents=True, exist_ok=True)
    return out


def example_model(name: str = "skewed_triple.toml") -> str:
    """The model part of a shipped run file (``examples/NAME`` up to its ``[initial]``: ``[chain]`` and the
    ``[[links]]``), for a test's own run file to add its start and settings to."""
    text = (Path(__file__).resolve().parent.parent / "examples" / name).read_text(encoding="utf-8")
    return text.split("\n[initial]", 1)[0].rstrip() + "\n"


def general_body(**changes):
    """examples/general_body.toml's model (a rigid second body: its centre of mass off the rod's line, a product
    of inertia, its hinge tilted out of the (i, k) plane) with ``changes``: a test that needs some general body
    takes this one, whose compiled kernels (keyed by structure, not values: damping and torques are values) the
    README's, the docs' and the report's runs of that file build anyway -- a body of its own would compile its
    own (the model's, the flip map's, the Taylor series': seconds each, once per CI run)."""
    from skewpend.config import build_parameters
    from skewpend.io import read_config

    path = Path(__file__).resolve().parent.parent / "examples" / "general_body.toml"
    params = build_parameters(read_config(path)["parameters"])
    return params.replace(**changes) if changes else params
