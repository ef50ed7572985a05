"""No silent waits (issue 36): a command says its stages (skewpend.progress.Stages) -- off a terminal one
line per stage on stderr, never on stdout; on a terminal one live line (Rich) that makes way for the
command's own output; ``--quiet`` and ``SKEWPEND_QUIET=1`` silence it; a command that names no stage
gets its first said for it.  Nothing here is timed: the order and the place of the lines are checked
(the first output's time is measured by benchmarks/bench_first_output.py)."""

from __future__ import annotations

import io
import re
import sys
import time

import pytest

from helpers import run_cli
from skewpend import progress as P

STAGE = P.STAGE_LINE


def _stderr_to(buf):
    class Swap:
        def __enter__(self):
            self.old, sys.stderr = sys.stderr, buf

        def __exit__(self, *exc):
            sys.stderr = self.old

    return Swap()


# -- the command line ---------------------------------------------------------------------------------
def test_stage_lines_go_to_stderr_never_to_stdout():
    """(tests/helpers.py puts the stage lines of stderr in ``ran.stages``, the rest in ``ran.err``.)"""
    ran = run_cli(["simulate", "--t-end", "0.2"])
    assert ran.code == 0 and ran.err == "", ran.report()
    assert any(line.startswith("skewpend simulate: simulating... (") for line in ran.stages), ran.stages
    assert "skewpend simulate:" not in ran.out and "status" in ran.out  # stdout: the summary only
    assert not any("\r" in line or "\x1b" in line or "%" in line for line in ran.stages)  # no bar off a terminal


def test_each_analysis_names_its_stage():
    ran = run_cli(["nnm", "--mode", "1", "--energy-max", "0.05", "--resolution", "3"])
    assert ran.code == 0 and ran.err == "", ran.report()
    assert ran.stages[-1].startswith("skewpend nnm: continuing nonlinear normal mode 1... ("), ran.stages


@pytest.mark.parametrize("argv", [["simulate", "--t-end", "0.2", "--quiet"], ["simulate", "--t-end", "0.2", "-q"],
                                  ["equilibria", "--quiet"], ["export", "--quiet"]])
def test_quiet_says_nothing(argv):
    """--quiet silences the stages -- also of a command without a progress bar of its own, which
    takes --quiet from the command wrapper."""
    ran = run_cli(argv)
    assert ran.code == 0 and ran.err == "" and ran.stages == () and ran.out, ran.report()


def test_skewpend_quiet_environment_says_nothing(monkeypatch):
    monkeypatch.setenv("SKEWPEND_QUIET", "1")
    ran = run_cli(["simulate", "--t-end", "0.2"])
    assert ran.code == 0 and ran.err == "" and ran.stages == (), ran.report()


def test_a_refused_command_is_one_line(monkeypatch):
    """A stage whose work may still refuse its input is held until the work begins (its first
    progress call) -- or for GRACE seconds, here made long: a refusal stays the one error line."""
    monkeypatch.setattr(P, "GRACE", 60.0)
    ran = run_cli(["simulate", "--t-end", "0.2", "--rtol", "-1"])
    assert ran.code == 2 and ran.err.startswith("skewpend: error:") and ran.stages == (), ran.report()
    ran = run_cli(["simulate", "--t-end", "1e9", "--method", "rk4"])  # refused by the library: the stage is held
    assert ran.code == 2 and "max_steps" in ran.err and ran.stages == (), ran.report()


def test_every_command_takes_quiet():
    from skewpend.cli import _group

    for name, command in _group().commands.items():
        assert any("--quiet" in p.opts for p in command.params), name


# -- the reporter ---------------------------------------------------------------------------------------
def test_lines_off_a_terminal_one_per_stage():
    buf = io.StringIO()
    with _stderr_to(buf), P.Stages("demo", terminal=False) as st:
        P.stage("reading")
        with st.bar("working", "s") as bar:
            for k in range(5):
                bar(k, 4)  # a bar's moves are not lines
        P.stage("writing", 2, 3)
    lines = buf.getvalue().splitlines()
    assert [re.sub(r" \(\d+\.\d s\)$", "", line) for line in lines] == [
        "skewpend demo: reading...", "skewpend demo: working...", "skewpend demo: [2/3] writing..."]
    assert all(STAGE.match(line) for line in lines) and st.lines == lines
    P.stage("after the command")  # no command runs: nothing, nowhere
    assert P.active() is None and len(buf.getvalue().splitlines()) == 3


def test_a_library_reporting_stages_by_name_says_each_once():
    """``progress(done, total, label)`` (skewpend.identify's stages): a line per new label."""
    buf = io.StringIO()
    with _stderr_to(buf), P.Stages("identify", terminal=False) as st:
        with st.bar("identify", "%") as bar:  # named as its command only: nothing to add
            bar(0, 100, "linear estimate")
            bar(10, 100, "output-error fit")
            bar(10, 100, "output-error fit")
            bar(50, 100)
            bar(90, 100, "held-out prediction")
    assert [line.split("... (")[0] for line in buf.getvalue().splitlines()] == [
        "skewpend identify: linear estimate", "skewpend identify: output-error fit",
        "skewpend identify: held-out prediction"]


def test_quiet_reporter_says_nothing():
    buf = io.StringIO()
    with _stderr_to(buf), P.Stages("demo", enabled=False, terminal=False, grace=0.0) as st:
        P.stage("reading")
        st.bar("working")(1, 2)
        _wait_for(lambda: False, 0.2)
    assert buf.getvalue() == "" and st.lines == []


def _wait_for(condition, limit: float) -> bool:
    """Poll ``condition`` up to ``limit`` seconds (a generous bound for a timer thread; nothing timed)."""
    end = time.monotonic() + limit
    while time.monotonic() < end:
        if condition():
            return True
        time.sleep(0.01)
    return condition()


def test_a_command_that_names_no_stage_gets_its_first_said():
    buf = io.StringIO()
    with _stderr_to(buf), P.Stages("derive", terminal=False, first="deriving the equations", grace=0.0) as st:
        assert _wait_for(lambda: st.lines, 30.0)
        P.stage("rendering")
    lines = [line.split("... (")[0] for line in buf.getvalue().splitlines()]
    assert lines == ["skewpend derive: deriving the equations", "skewpend derive: rendering"]


def test_a_program_says_its_first_stage_soon_after_its_process_started():
    """Run as the process's program, the command's start is the process's (``started``): a process that
    spent its grace on imports already says its first stage at once, timed from the process's start."""
    buf = io.StringIO()
    with _stderr_to(buf), P.Stages("modes", terminal=False, first="computing", grace=60.0,
                                   started=time.monotonic() - 10.0) as st:
        assert _wait_for(lambda: st.lines, 30.0)  # not GRACE (60 s): FIRST_BY after the start is long past
    [line] = buf.getvalue().splitlines()
    assert line.startswith("skewpend modes: computing... (") and float(line.split("(")[1].split()[0]) >= 10.0


def test_the_first_is_not_said_once_a_stage_was():
    buf = io.StringIO()
    with _stderr_to(buf), P.Stages("demo", terminal=False, first="starting", grace=60.0):
        P.stage("reading")
    assert [line.split("... (")[0] for line in buf.getvalue().splitlines()] == ["skewpend demo: reading"]


# -- on a terminal --------------------------------------------------------------------------------------
def _terminal():
    from rich.console import Console

    screen = io.StringIO()
    return screen, Console(file=screen, force_terminal=True, width=100, color_system=None)


def test_on_a_terminal_one_live_line_with_the_stage_and_its_fraction():
    screen, console = _terminal()
    plain = io.StringIO()
    with _stderr_to(plain):
        with P.Stages("flipmap", terminal=True, console=console) as st:
            with st.bar("computing the flip map", "cells") as bar:
                bar(3, 4)
                st._progress.refresh()
                drawn = screen.getvalue()
        assert plain.getvalue() == ""  # no line: the live line only
    assert "skewpend flipmap: computing the flip map" in drawn and "75.0%" in drawn
    assert not st._live  # gone when the command ends


def test_on_a_terminal_the_live_line_makes_way_for_output():
    screen, console = _terminal()
    out, err = io.StringIO(), io.StringIO()
    old = sys.stdout, sys.stderr
    sys.stdout, sys.stderr = out, err
    try:
        with P.Stages("simulate", terminal=True, console=console) as st:
            P.stage("simulating")
            assert st._live
            sys.stdout.write("the summary\n")  # the command's own output: the line goes
            assert not st._live and out.getvalue() == "the summary\n"
            P.stage("drawing the figure")  # the next stage draws it again
            assert st._live
            sys.stderr.write("skewpend: warning: a note\n")  # a note on stderr: the line goes, then returns
            assert not st._live and err.getvalue() == "skewpend: warning: a note\n"
            assert _wait_for(lambda: st._live, 30.0)
        assert sys.stdout is out and sys.stderr is err  # the streams are given back
    finally:
        sys.stdout, sys.stderr = old
    assert not st._live


def test_on_a_terminal_output_does_not_cancel_a_held_stage():
    screen, console = _terminal()
    out = io.StringIO()
    old = sys.stdout, sys.stderr
    sys.stdout, sys.stderr = out, io.StringIO()
    try:
        with P.Stages("demo", terminal=True, console=console, grace=60.0) as st:
            st.stage("computing", hold=True, within=0.2)
            sys.stdout.write("a line of output\n")  # the line makes way; the held stage is still said
            assert _wait_for(lambda: st.lines, 30.0)
    finally:
        sys.stdout, sys.stderr = old
    assert [line.split("... (")[0] for line in st.lines] == ["skewpend demo: computing"]


def test_a_held_stage_does_not_put_the_first_line_off():
    """The command's first line is due by its deadline (here GRACE = 0.1 s) even when a held stage
    (a progress bar's, whose own hold would be 120 s) replaced its first stage before it was said."""
    buf = io.StringIO()
    with _stderr_to(buf), P.Stages("demo", terminal=False, first="starting", grace=0.1) as st:
        st.stage("computing", hold=True, within=120.0)
        assert _wait_for(lambda: st.lines, 30.0)
    assert [line.split("... (")[0] for line in buf.getvalue().splitlines()] == ["skewpend demo: computing"]
