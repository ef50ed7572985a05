"""Ctrl-C and SIGTERM that are never lost: recorded at the signal, raised at the next safe point.

Python raises :class:`KeyboardInterrupt` wherever the main thread happens to be when the signal
is handled -- also inside a ``__del__`` or a callback whose exceptions Python only reports as
"Exception ignored", where the interrupt is swallowed and a long run goes on.  The long loops of
the library (the chunked integrators, the ensemble engine) therefore run inside
:class:`Interrupts`: while it is active, SIGINT only sets a flag, and :meth:`Interrupts.check`,
called between the bounded calls into compiled code (a few ms to ~0.05 s apart), raises the
:class:`KeyboardInterrupt` there.  A handler the application installed itself is left alone, and
outside the main thread nothing changes.

SIGTERM (``kill``, ``timeout``, a CI cancel) gets what SIGINT gets once an application asks for
it with :func:`terminate_like_interrupt` (the command line does, for its whole lifetime): the
signal raises :class:`Terminated`, a :class:`KeyboardInterrupt`, so every clean-up that runs on
Ctrl-C (temporary files, worker threads, child processes) runs on SIGTERM too; inside
:class:`Interrupts` it is recorded and raised at the next check like SIGINT.  Without that call a
library user's SIGTERM keeps Python's default (the process ends at once).

Work that spends seconds in plain Python between checks (the report's drawing and SymPy) asks for
``Interrupts(escalate_after=0.3)``: a signal that no check has taken within that time is raised
in the main thread where it is (the signal is sent again to the main thread, whose handler then
raises) -- unless the main thread is inside a ``__del__``, where it would be swallowed: then it
tries again shortly.  The flag stays set, so an exception swallowed anyway is raised at the next
check.  It is not for loops that call Python from compiled code (a ctypes callback would only
print the exception).
"""

from __future__ import annotations

import contextlib
import signal
import threading
from typing import Callable, Iterator, Optional

__all__ = ["Interrupts", "Terminated", "terminate_like_interrupt"]


class Terminated(KeyboardInterrupt):
    """SIGTERM, raised where Ctrl-C's :class:`KeyboardInterrupt` would be."""


def _raise_terminated(signum, frame) -> None:
    """The SIGTERM handler of :func:`terminate_like_interrupt` (outside :class:`Interrupts`)."""
    raise Terminated


@contextlib.contextmanager
def terminate_like_interrupt() -> Iterator[None]:
    """While active (in the main thread), SIGTERM raises :class:`Terminated` -- and is recorded by
    :class:`Interrupts` like SIGINT; the previous handler is restored on leaving."""
    if threading.current_thread() is not threading.main_thread():
        yield
        return
    previous = signal.signal(signal.SIGTERM, _raise_terminated)
    try:
        yield
    finally:
        signal.signal(signal.SIGTERM, previous)


class Interrupts:
    """``with Interrupts() as intr: ... intr.check() ...`` -- see the module.  ``on_signal`` is
    called at the signal too (it must be quick and thread-safe, e.g. ``threading.Event.set``)."""

    def __init__(self, on_signal: Optional[Callable[[], None]] = None, *,
                 escalate_after: Optional[float] = None) -> None:
        self.pending: Optional[type] = None  # the exception to raise at the next check, if any
        self.on_signal = on_signal  # also run at the signal (e.g. tell worker threads to stop)
        self.escalate_after = escalate_after  # seconds a signal may wait for a check (None: forever)
        self._previous: Optional[dict] = None  # the handlers replaced, by signal number
        self._outer: Optional["Interrupts"] = None  # an enclosing Interrupts (nested: a report's simulations)
        self._timer: Optional[threading.Timer] = None
        self._raise_now = False  # set by the timer: the handler, run again, raises
        self._closing = False  # leaving the block: the timer's call raises nothing (the exit's check does)

    def _record(self, signum, frame) -> None:
        if self._raise_now:  # the timer's call, not a new signal
            self._raise_now = False
            if self.pending is None or self._closing:
                return  # a check took it meanwhile, or the block is ending (its exit raises it)
            if _in_destructor(frame):  # it would be swallowed there: a little later
                self._arm(0.05, signum)
                return
            raise self.pending  # it stays pending: swallowed anyway, the next check raises it
        # SIGTERM outranks a Ctrl-C recorded before it: the process is asked to end
        if self.pending is not Terminated:
            self.pending = Terminated if signum == signal.SIGTERM else KeyboardInterrupt
        if self.on_signal is not None:
            self.on_signal()
        if self._outer is not None:  # the enclosing work hears of it too (its on_signal, its checks)
            self._outer._record(signum, frame)
        if self.escalate_after is not None and self._timer is None and not self._closing:
            self._arm(self.escalate_after, signum)

    def _arm(self, delay: float, signum: int) -> None:
        timer = threading.Timer(delay, self._escalate, args=(signum,))
        timer.daemon = True
        self._timer = timer
        timer.start()

    def _escalate(self, signum: int) -> None:
        """In the timer's thread: a signal no check has taken is raised by the handler, run again
        (sent to the main thread as a real signal, so that a blocking wait -- a compiler's
        subprocess, a pipe -- is interrupted too)."""
        if self.pending is not None and self._previous is not None and not self._closing:
            self._raise_now = True
            signal.pthread_kill(threading.main_thread().ident, signum)

    def __enter__(self) -> "Interrupts":
        if threading.current_thread() is threading.main_thread():
            for signum, ours in ((signal.SIGINT, signal.default_int_handler), (signal.SIGTERM, _raise_terminated)):
                handler = signal.getsignal(signum)
                outer = getattr(handler, "__self__", None)
                nested = isinstance(outer, Interrupts) and getattr(handler, "__func__", None) is Interrupts._record
                if handler is ours or nested:  # a handler of the application is left alone
                    self._previous = self._previous or {}
                    self._previous[signum] = signal.signal(signum, self._record)
                    if nested:
                        self._outer = outer
        return self

    def check(self) -> None:
        """Raise :class:`KeyboardInterrupt` (or :class:`Terminated`) if a signal came since the last
        check -- here, or, nested, in the enclosing :class:`Interrupts` before this one began."""
        if self.pending is None and self._outer is not None and self._outer.pending is not None:
            self.pending = self._outer.pending
        if self.pending is not None:
            kind, self.pending = self.pending, None
            if self._outer is not None:
                self._outer.pending = None  # raised once, here; it travels out through the enclosing work
            raise kind

    def __exit__(self, exc_type, exc, tb) -> None:
        self._closing = True
        timer, self._timer = self._timer, None
        if timer is not None:
            timer.cancel()
            timer.join()  # no signal re-sent once the handlers below are restored
        self._raise_now = False
        for signum, previous in (self._previous or {}).items():
            signal.signal(signum, previous)
        self._previous = None
        self._outer = None
        self._closing = False
        if self.pending is not None and exc_type is None:  # a signal during the last stretch still counts
            self.check()


def _in_destructor(frame) -> bool:
    """Whether ``frame`` runs inside a ``__del__``, a garbage collector's callback (``gc.callbacks``,
    which a profiler or test plugin may install) or a weak reference's callback: an exception raised
    there is only reported."""
    import gc

    callbacks = {getattr(cb, "__code__", None) for cb in gc.callbacks}
    while frame is not None:
        code = frame.f_code
        if code.co_name == "__del__" or code in callbacks or code.co_filename.endswith(_WEAKREF_FILES):
            return True  # (weak references' callbacks, e.g. a WeakKeyDictionary's remove, report only too)
        frame = frame.f_back
    return False


#: The standard library's weak-reference modules: their callbacks run where exceptions are only reported.
_WEAKREF_FILES = ("/weakref.py", "/_weakrefset.py")
