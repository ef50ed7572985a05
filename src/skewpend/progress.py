"""Saying what a command is doing: its stages (:class:`Stages`) and progress bars (:class:`ProgressBar`).

No silent waits (issue 36): every ``skewpend`` command says what it is doing within a second of
starting.  The command wrapper (:func:`skewpend.cli.options.command`) opens a :class:`Stages` for
the command before any heavy import; the command and the library name each stage as it begins
(:func:`stage`, a no-op when no command runs, so library functions may call it freely), and the
progress callbacks of long computations (``progress(done, total)``) move the current stage's bar.

* On a terminal (stderr is one): one live line on stderr, drawn by Rich -- a spinner, the stage and
  its sub-step (:func:`detail`), a bar (its real fraction; a pulse where the fraction is not known), the time elapsed and, with a
  fraction, the time left -- redrawn ten times a second, gone when the command ends or writes its
  own output (the next stage draws it again).
* Off a terminal (pipes, files, CI): one line per stage on stderr, ``skewpend CMD: [k/n] STAGE...
  (T s)`` (T: seconds since the command started), never on stdout, which may be data.
* ``--quiet`` or ``SKEWPEND_QUIET=1``: nothing.

A command that has named no stage after :data:`GRACE` seconds (its checks, heavy imports) gets its
first stage said for it (the wrapper's text for that command), so even a command that names none
says something within a second; a command refused by its checks (which take milliseconds) stays
one line.

:class:`ProgressBar` is the stand-alone bar for Python code (a Rich bar after ``delay`` seconds,
only on a terminal); library functions take a plain ``progress(done, total)`` callable either way.
"""

from __future__ import annotations

import os
import re
import sys
import threading
import time
from typing import Any, List, Optional

__all__ = ["ProgressBar", "Stages", "stage", "detail", "active", "GRACE", "FIRST_BY", "STAGE_LINE"]

#: A stage's line off a terminal, ``skewpend CMD: [k/n] STAGE... (T s)`` (T: seconds since the command
#: started; ``[k/n]`` when the stages are counted) -- for a script that reads stderr and wants them apart.
STAGE_LINE = re.compile(r"^skewpend [a-z][a-z-]*: .*\.\.\. \(\d+\.\d s\)$")

#: Seconds after a command starts by which it has said its first stage (else it is said for it).
GRACE = 0.3
#: A command run as a program says its first stage by this many seconds after its process started
#: (``started``: when the command line was imported, ~0.1 s after the interpreter started; the command
#: line's own imports take ~0.2-0.4 s of them), or ``GRACE`` after the command began if that comes first.
FIRST_BY = 0.5
#: The live line is redrawn at most this often by progress calls [s] (Rich also redraws it 10 times a second).
_REDRAW = 0.1
#: Seconds after a note on stderr before the live line is drawn again below it.
_RESHOW = 0.2

_ACTIVE: List["Stages"] = []


def active() -> Optional["Stages"]:
    """The :class:`Stages` of the command now running in this process, or None."""
    return _ACTIVE[-1] if _ACTIVE else None


def stage(name: str, step: Optional[int] = None, steps: Optional[int] = None) -> None:
    """Say that the running command begins the stage ``name`` (its ``step`` of ``steps``, when
    counted); nothing when no command runs (a library call from Python) or it is quiet."""
    reporter = active()
    if reporter is not None:
        reporter.stage(name, step, steps)


def detail(text: str) -> None:
    """Say what the current stage is doing now -- its iteration, continuation step, frame or
    sub-step (issue 51: no silence over 2 s on a terminal) -- shown after the stage on the live line;
    nothing off a terminal (a line per stage there), when no command runs, or when it is quiet."""
    reporter = active()
    if reporter is not None:
        reporter.detail(text)


def _quiet_environment() -> bool:
    return os.environ.get("SKEWPEND_QUIET", "") not in ("", "0")


class Stages:
    """The stages of one command: ``with Stages("report") as st: st.stage("deriving"); ...``.

    ``enabled=False`` (``--quiet``) says nothing; ``terminal=None``: whether stderr is a terminal;
    ``first``: the stage said for the command if it names none within ``grace`` seconds (default
    :data:`GRACE`), or by :data:`FIRST_BY` seconds after ``started`` (a ``time.monotonic()`` time: the
    start of the process when the command is its program) if that comes sooner;
    ``console`` (a ``rich.console.Console``) and ``clock`` are for tests.
    """

    def __init__(self, command: str, *, enabled: bool = True, terminal: Optional[bool] = None,
                 first: str = "starting", grace: Optional[float] = None, started: Optional[float] = None,
                 console: Any = None, clock=time.monotonic):
        self.command, self.first, self.started = command, first, started
        self.grace = GRACE if grace is None else grace
        self.enabled = bool(enabled) and not _quiet_environment()
        if terminal is None:
            try:
                terminal = sys.stderr.isatty()
            except (AttributeError, ValueError):  # a closed or missing stderr
                terminal = False
        self.terminal = bool(terminal) and self.enabled
        self._console, self._clock = console, clock
        self._lock = threading.RLock()
        self._start = clock()
        self._name: Optional[str] = None
        self._step: Optional[int] = None
        self._steps: Optional[int] = None
        self._fraction: Optional[float] = None
        self._stage_start = self._start
        self._said = False
        self._closed = False
        self._timer: Optional[threading.Timer] = None
        self._progress = None
        self._task = None
        self._live = False
        self._drawn = 0.0
        self._streams = None
        self._token = 0  # counts the stages (a held stage's timer says it only if it is still the current one)
        self._made_way = 0  # counts the writes the live line made way for (the last one draws it again)
        self._drawn_stage = -1  # the stage the live line last drew
        self._first_by = float("inf")  # when the first line is due (set on entering)
        self._pending = False
        self.lines: List[str] = []  # every stage said, as its line (for tests and the benchmark)
        self._detail: Optional[str] = None
        #: when the live line's text or fraction last changed (a clock time per change: stages, bars,
        #: details) -- on a terminal only; for tests and the benchmark (the longest gap is a silence)
        self.moves: List[float] = []

    # -- the command's side ------------------------------------------------------------------
    def __enter__(self) -> "Stages":
        self._start = self._stage_start = self._clock()
        _ACTIVE.append(self)
        if self.enabled and self.terminal:
            self._wrap_streams()
            # Rich takes ~0.1 s to import: readied now, beside the command's own imports, the first draw is at once
            threading.Thread(target=self._ready, name="skewpend-stages", daemon=True).start()
        within = self.grace
        if self.started is not None:
            within = min(within, max(0.05, self.started + FIRST_BY - self._start))
        self._first_by = self._start + within  # a held stage that follows does not put the first line off
        self.stage(self.first, hold=True, within=within)
        return self

    def __exit__(self, *exc) -> None:
        self.close()

    def close(self) -> None:
        with self._lock:
            self._closed = True
            self._token += 1
            if self._timer is not None:
                self._timer.cancel()
            self._hide()
            self._unwrap_streams()
        if self in _ACTIVE:
            _ACTIVE.remove(self)

    def stage(self, name: str, step: Optional[int] = None, steps: Optional[int] = None, *, hold: bool = False,
              within: Optional[float] = None) -> None:
        """The stage ``name`` begins (``step`` of ``steps`` when counted: the bar starts at
        (step - 1)/steps; otherwise its fraction is unknown until :meth:`update`).

        ``hold=True``: a stage whose work may still refuse its input (a library function checks its
        arguments first): said at its first :meth:`update` -- the work has begun -- or once it has
        lasted ``grace`` seconds (``within``, if given), so that a refusal stays one line."""
        with self._lock:
            self._name, self._step, self._steps = str(name), step, steps
            self._detail = None
            self._fraction = (step - 1) / steps if step is not None and steps else None
            self._stage_start = self._clock()
            self._token += 1
            self._pending = True
            if self._timer is not None:
                self._timer.cancel()
                self._timer = None
            if not hold:
                self._say()
            elif self.enabled and not self._closed:
                delay = self.grace if within is None else within
                if not self._said:  # nothing said yet: the command's first line is due by its deadline
                    delay = min(delay, max(0.0, self._first_by - self._clock()))
                self._timer = threading.Timer(delay, self._held, args=(self._token,))
                self._timer.daemon = True
                self._timer.start()

    def update(self, done: float, total: float) -> None:
        """The current stage's fraction ``done / total`` (drawn on a terminal; off one, stages only);
        a stage held until its work began is said now."""
        if not self.enabled or self._closed:
            return
        if self._pending:
            with self._lock:
                if self._pending:
                    self._say()
        if not self.terminal:
            return
        try:
            fraction = min(max(float(done) / float(total), 0.0), 1.0) if total else None
        except (TypeError, ValueError, ZeroDivisionError):
            fraction = None
        with self._lock:
            if fraction != self._fraction:
                self.moves.append(self._clock())
            self._fraction = fraction
            now = self._clock()
            if self._said and (now - self._drawn >= _REDRAW or fraction == 1.0):
                self._draw()

    def detail(self, text: str) -> None:
        """The current stage's sub-step now (``"orbit 12, Newton iteration 3"``, ``"frame 40 of 120"``):
        on a terminal shown after the stage on the live line (redrawn at most ten times a second);
        off a terminal nothing (a line per stage there).  A stage held until its work began is said now."""
        if not self.enabled or self._closed or not self.terminal:
            return
        if self._pending:
            with self._lock:
                if self._pending:
                    self._say()
        text = str(text)
        with self._lock:
            if text == self._detail:
                return
            self._detail = text
            now = self._clock()
            self.moves.append(now)
            if self._said and now - self._drawn >= _REDRAW:
                self._draw()

    def bar(self, label: str, unit: str = "") -> "StageBar":
        """A ``progress(done, total)`` callable for a library function: the stage ``label``."""
        return StageBar(self, label, unit)

    @property
    def elapsed(self) -> float:
        """Seconds since the command started (its process's start when given, else since ``with``)."""
        return self._clock() - (self._start if self.started is None else min(self.started, self._start))

    # -- saying it ------------------------------------------------------------------------------
    def _held(self, token: int) -> None:
        """A held stage has lasted ``grace`` seconds: it is said."""
        with self._lock:
            if token == self._token and self._pending and not self._closed:
                self._say()

    def _text(self) -> str:
        count = f"[{self._step}/{self._steps}] " if self._step is not None and self._steps else ""
        return f"{count}{self._name}"

    def _live_text(self) -> str:
        return self._text() + (f": {self._detail}" if self._detail else "")

    def _say(self) -> None:
        self._pending = False
        if not self.enabled or self._closed or self._name is None:
            return
        line = f"skewpend {self.command}: {self._text()}... ({self.elapsed:.1f} s)"
        self.lines.append(line)
        self._said = True
        if self.terminal:
            self.moves.append(self._clock())
            self._draw()
            return
        try:
            sys.stderr.write(line + "\n")
            sys.stderr.flush()
        except (OSError, ValueError, AttributeError):  # a closed or missing stderr: nothing to say it on
            pass

    # -- the live line (a terminal) ---------------------------------------------------------------
    def _draw(self) -> None:
        try:
            if self._progress is None:
                self._progress = self._make_progress()
            description = f"skewpend {self.command}: {self._live_text()}"
            if self._task is None:
                self._task = self._progress.add_task(description, total=None)
            if self._drawn_stage != self._token:  # a new stage: not finished, whatever the last one reached
                self._progress.reset(self._task)
                self._drawn_stage = self._token
            total = None if self._fraction is None else 1.0
            self._progress.update(self._task, description=description, total=total,
                                  completed=0.0 if self._fraction is None else self._fraction)
            if not self._live:
                self._progress.start()
                self._live = True
            self._drawn = self._clock()
        except Exception:  # noqa: BLE001 - a display that fails must never stop the work
            self._live = False

    def _ready(self) -> None:
        try:
            import rich.progress  # noqa: F401 - the import is the work (outside the lock)

            with self._lock:
                if self._progress is None and not self._closed:
                    self._progress = self._make_progress()
        except Exception:  # noqa: BLE001 - the first draw tries again, and a display never stops the work
            pass

    def _make_progress(self):
        from rich.console import Console
        from rich.progress import BarColumn, Progress, ProgressColumn, SpinnerColumn
        from rich.text import Text

        owner = self

        class Clock(ProgressColumn):
            """Seconds since the command started; with a fraction, the time left for this stage."""

            def render(self, task) -> Text:
                elapsed = owner.elapsed
                text = _clock_text(elapsed)
                fraction, began = owner._fraction, owner._stage_start
                if fraction is not None and 0.01 < fraction < 1.0 and owner._step is None:
                    spent = owner._clock() - began
                    text += f"  ETA {_clock_text(spent * (1.0 - fraction) / fraction)}"
                return Text(text, style="progress.elapsed")

        class Description(ProgressColumn):
            """The stage and its sub-step as they are now (a detail said between two draws shows at the next refresh)."""

            def render(self, task) -> Text:
                return Text(f"skewpend {owner.command}: {owner._live_text()}")

        class Share(ProgressColumn):
            def render(self, task) -> Text:
                fraction = owner._fraction
                return Text("" if fraction is None else f"{100.0 * fraction:5.1f}%", style="progress.percentage")

        real = self._streams[1] if self._streams else sys.stderr
        console = self._console or Console(file=real)
        return Progress(SpinnerColumn(), Description(), BarColumn(), Share(), Clock(),
                        console=console, transient=True, redirect_stdout=False, redirect_stderr=False,
                        refresh_per_second=10)

    def _hide(self) -> None:
        if self._live and self._progress is not None:
            try:
                self._progress.stop()
            except Exception:  # noqa: BLE001
                pass
        self._live = False

    def _make_way(self, stderr: bool) -> None:
        """Something else writes to the terminal: the live line makes way.  After a note on stderr (a
        compiler's, a warning) it is drawn again below it once the note is written (:data:`_RESHOW`);
        after the command's own output on stdout, at its next stage or progress call."""
        with self._lock:
            self._hide()
            self._made_way += 1
            if stderr and self._said and not self._closed:
                timer = threading.Timer(_RESHOW, self._reshow, args=(self._made_way,))
                timer.daemon = True
                timer.start()

    def _reshow(self, token: int) -> None:
        with self._lock:
            if token == self._made_way and not self._live and not self._closed:
                self._draw()

    def _wrap_streams(self) -> None:
        self._streams = (sys.stdout, sys.stderr)
        sys.stdout = _MakeWay(sys.stdout, self, stderr=False)
        sys.stderr = _MakeWay(sys.stderr, self, stderr=True)

    def _unwrap_streams(self) -> None:
        if self._streams is not None:
            if isinstance(sys.stdout, _MakeWay) and sys.stdout._owner is self:
                sys.stdout = self._streams[0]
            if isinstance(sys.stderr, _MakeWay) and sys.stderr._owner is self:
                sys.stderr = self._streams[1]
            self._streams = None


def _clock_text(seconds: float) -> str:
    seconds = max(0, int(seconds))
    h, rest = divmod(seconds, 3600)
    return f"{h}:{rest // 60:02d}:{rest % 60:02d}" if h else f"{rest // 60}:{rest % 60:02d}"


class _MakeWay:
    """sys.stdout / sys.stderr while a live line is drawn: a write first clears the line."""

    def __init__(self, stream, owner: Stages, stderr: bool) -> None:
        self._stream, self._owner, self._stderr = stream, owner, stderr

    def write(self, text):
        if text:
            self._owner._make_way(self._stderr)
        return self._stream.write(text)

    def writelines(self, lines):
        for line in lines:
            self.write(line)

    def __getattr__(self, name):
        return getattr(self._stream, name)


class StageBar:
    """A stage with a bar, as a ``progress(done, total)`` callable (``with`` it, or not).

    ``bar(done, total, label)`` with a ``label`` (a library that reports stages by name, e.g.
    :func:`skewpend.identify`) begins that stage; its fraction then is unknown (the line shows the
    stage and the time moving, not a bar that sits at a stage's first fraction)."""

    def __init__(self, owner: Stages, label: str, unit: str = "") -> None:
        self.owner, self.label, self.unit = owner, label, unit
        self._said: Optional[str] = None

    def __enter__(self) -> "StageBar":
        if self.label and self.label != self.owner.command:  # a bar named only by its command adds nothing
            self.owner.stage(self.label, hold=True)  # said when the work begins: a refusal stays one line
            self._said = self.label
        return self

    def __exit__(self, *exc) -> None:
        pass

    def __call__(self, done: float, total: float, label: Optional[str] = None) -> None:
        if label is not None:
            if label != self._said:
                self._said = label
                self.owner.stage(label)
            return
        self.owner.update(done, total)

    @property
    def shown(self) -> bool:
        return self.owner._said


class ProgressBar:
    """``with ProgressBar("simulating", unit="s") as bar: work(progress=bar)``.

    ``bar(done, total)`` may be called as often as convenient (it redraws at most ~10 times a
    second).  ``enabled=None`` means: when stderr is a terminal.  ``console`` (a
    ``rich.console.Console``) is for tests.
    """

    def __init__(self, description: str, *, unit: str = "", enabled: Optional[bool] = None, delay: float = 0.5,
                 console: Any = None):
        self.description, self.unit, self.delay = description, unit, delay
        self.enabled = sys.stderr.isatty() if enabled is None else bool(enabled)
        self._console = console
        self._progress = None
        self._task = None
        self._start = time.monotonic()
        self._last = 0.0

    def __enter__(self) -> "ProgressBar":
        self._start = time.monotonic()
        return self

    def __call__(self, done: float, total: float, label: Optional[str] = None) -> None:
        if not self.enabled:
            return
        now = time.monotonic()
        if self._progress is None:
            if now - self._start < self.delay:
                return
            self._begin(total)
        if now - self._last >= 0.1 or done >= total:
            self._last = now
            self._progress.update(self._task, completed=min(done, total), total=total)

    def _begin(self, total: float) -> None:
        from rich.console import Console
        from rich.progress import BarColumn, Progress, TextColumn, TimeElapsedColumn, TimeRemainingColumn

        console = self._console or Console(stderr=True)
        unit = f" {self.unit}" if self.unit else ""
        self._progress = Progress(
            TextColumn("[bold]{task.description}"),
            BarColumn(),
            TextColumn("{task.percentage:>5.1f}%"),
            TextColumn(f"{{task.completed:.4g}}/{{task.total:.4g}}{unit}"),
            TimeElapsedColumn(),
            TextColumn("ETA"),
            TimeRemainingColumn(),
            console=console,
            transient=True,
        )
        self._progress.start()
        self._task = self._progress.add_task(self.description, total=total)

    @property
    def shown(self) -> bool:
        return self._progress is not None

    def __exit__(self, *exc) -> None:
        if self._progress is not None:
            self._progress.stop()
