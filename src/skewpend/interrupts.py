"""Ctrl-C that is never lost: SIGINT recorded, raised at the next safe point.

Python raises :class:`KeyboardInterrupt` wherever the main thread happens to be when the signal
is handled -- also inside a ``__del__`` or a callback whose exceptions Python only reports as
"Exception ignored", where the interrupt is swallowed and a long run goes on.  The long loops of
the library (the chunked integrators, the ensemble engine) therefore run inside
:class:`Interrupts`: while it is active, SIGINT only sets a flag, and :meth:`Interrupts.check`,
called between the bounded calls into compiled code (a few ms to ~0.05 s apart), raises the
:class:`KeyboardInterrupt` there.  A handler the application installed itself is left alone, and
outside the main thread nothing changes.
"""

from __future__ import annotations

import signal
import threading
from typing import Any, Callable, Optional

__all__ = ["Interrupts"]


class Interrupts:
    """``with Interrupts() as intr: ... intr.check() ...`` -- see the module.  ``on_signal`` is
    called at the signal too (it must be quick and thread-safe, e.g. ``threading.Event.set``)."""

    def __init__(self, on_signal: Optional[Callable[[], None]] = None) -> None:
        self.pending = False
        self.on_signal = on_signal  # also run at the signal (e.g. tell worker threads to stop)
        self._previous: Optional[Any] = None

    def _record(self, signum, frame) -> None:
        self.pending = True
        if self.on_signal is not None:
            self.on_signal()

    def __enter__(self) -> "Interrupts":
        if threading.current_thread() is threading.main_thread() and \
                signal.getsignal(signal.SIGINT) is signal.default_int_handler:
            self._previous = signal.signal(signal.SIGINT, self._record)
        return self

    def check(self) -> None:
        """Raise :class:`KeyboardInterrupt` if Ctrl-C came since the last check."""
        if self.pending:
            self.pending = False
            raise KeyboardInterrupt

    def __exit__(self, exc_type, exc, tb) -> None:
        if self._previous is not None:
            signal.signal(signal.SIGINT, self._previous)
            self._previous = None
        if self.pending and exc_type is None:  # a Ctrl-C during the last stretch still counts
            self.pending = False
            raise KeyboardInterrupt
