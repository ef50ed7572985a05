"""Progress for long work: a Rich bar with an ETA on stderr, only when stderr is a terminal.

Library functions take a plain ``progress(done, total)`` callable; this module turns such
calls into a bar that appears only once the work has run for ``delay`` seconds (short
runs print nothing) and disappears when it ends.  Nothing is shown when stderr is not a
terminal (pipes, files, CI) or when the user asked for ``--quiet``.
"""

from __future__ import annotations

import sys
import time
from typing import Any, Optional

__all__ = ["ProgressBar"]


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

    def __call__(self, done: float, total: float) -> None:
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
