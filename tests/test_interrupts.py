"""Ctrl-C is never lost (``skewpend.interrupts``): recorded at the signal, raised at a check."""

from __future__ import annotations

import os
import signal
import threading
import time

import pytest

from skewpend.interrupts import Interrupts, Terminated, terminate_like_interrupt


def _sigint_to_self():
    os.kill(os.getpid(), signal.SIGINT)
    time.sleep(0.05)  # the handler runs in the main thread between bytecodes, here


def test_a_signal_is_recorded_and_raised_at_the_check():
    calls = []
    with pytest.raises(KeyboardInterrupt):
        with Interrupts(on_signal=lambda: calls.append(1)) as intr:
            _sigint_to_self()  # no exception here ...
            assert intr.pending and calls == [1]
            intr.check()  # ... but here
    assert signal.getsignal(signal.SIGINT) is signal.default_int_handler  # restored


def test_a_signal_inside_a_destructor_is_not_swallowed():
    """Without the guard, KeyboardInterrupt raised inside __del__ is only reported ("Exception
    ignored") and the run goes on; with it, the next check raises."""

    class Interrupted:
        def __del__(self):
            _sigint_to_self()

    with pytest.raises(KeyboardInterrupt):
        with Interrupts() as intr:
            Interrupted()  # collected at once: the signal is handled inside __del__
            intr.check()


def test_a_signal_in_the_last_stretch_raises_on_leaving():
    with pytest.raises(KeyboardInterrupt):
        with Interrupts():
            _sigint_to_self()


def test_a_handler_of_the_application_is_left_alone():
    seen = []
    old = signal.signal(signal.SIGINT, lambda s, f: seen.append(s))
    try:
        with Interrupts() as intr:
            _sigint_to_self()
            intr.check()  # not ours to raise
        assert seen == [signal.SIGINT]
    finally:
        signal.signal(signal.SIGINT, old)


def test_outside_the_main_thread_nothing_changes():
    out = []

    def run():
        with Interrupts() as intr:
            out.append(intr._previous is None and signal.getsignal(signal.SIGINT) is signal.default_int_handler)

    t = threading.Thread(target=run)
    t.start()
    t.join()
    assert out == [True]


# -- SIGTERM: what Ctrl-C gets, once an application asks for it ---------------------------------------------
def _sigterm_to_self():
    os.kill(os.getpid(), signal.SIGTERM)
    time.sleep(0.05)


def test_sigterm_is_recorded_and_raised_as_terminated_at_the_check():
    calls = []
    with terminate_like_interrupt():
        with pytest.raises(Terminated):
            with Interrupts(on_signal=lambda: calls.append(1)) as intr:
                _sigterm_to_self()  # recorded, not raised here
                assert intr.pending is Terminated and calls == [1]
                intr.check()
        assert signal.getsignal(signal.SIGTERM) is not signal.SIG_DFL  # ours again, until the CLI leaves
    assert signal.getsignal(signal.SIGTERM) is signal.SIG_DFL


def test_terminated_is_a_keyboardinterrupt_so_every_ctrl_c_clean_up_runs():
    assert issubclass(Terminated, KeyboardInterrupt)
    with terminate_like_interrupt():
        with pytest.raises(KeyboardInterrupt):
            _sigterm_to_self()  # outside Interrupts: raised where the main thread is


def test_sigterm_outranks_an_earlier_ctrl_c():
    with terminate_like_interrupt():
        with pytest.raises(Terminated):
            with Interrupts() as intr:
                _sigint_to_self()
                _sigterm_to_self()
                intr.check()


def test_without_the_request_sigterm_is_left_alone():
    with Interrupts() as intr:
        assert signal.getsignal(signal.SIGTERM) is signal.SIG_DFL
        assert intr._previous is None or signal.SIGTERM not in intr._previous


def test_nested_interrupts_share_one_signal():
    """A report records a signal between its sections; a simulation inside it raises it at its first
    check, once; a signal during the inner work reaches the outer's on_signal too."""
    import os
    import signal
    import time

    from skewpend.interrupts import Interrupts

    told = []
    with Interrupts(on_signal=lambda: told.append("outer")) as outer:
        os.kill(os.getpid(), signal.SIGINT)
        time.sleep(0.01)  # the handler runs: recorded, nothing raised here
        with Interrupts() as inner:
            with pytest.raises(KeyboardInterrupt):
                inner.check()
            inner.check()  # raised once
        outer.check()  # ... and not again by the enclosing work
        with pytest.raises(KeyboardInterrupt):  # raised when the inner work ends (its last stretch counts)
            with Interrupts():
                os.kill(os.getpid(), signal.SIGINT)
                time.sleep(0.01)
                assert told == ["outer", "outer"] and outer.pending is KeyboardInterrupt
        outer.pending = None  # handled here: leaving the outer block raises nothing more
