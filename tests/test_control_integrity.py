"""Control under attack (issue 29): nested Python laws, Ctrl-C in a slow law, absurd targets,
a certified region estimate, infeasible runs refused before any work, arguments of every kind."""

from __future__ import annotations

import os
import re
import signal
import threading
import time

import numpy as np
import pytest

import skewpend
from skewpend.numeric.control import Controller

K_OUTER = np.array([[20.0, 5.0, 4.0, 1.0], [3.0, 15.0, 1.0, 3.0]])


@pytest.fixture(scope="module")
def ref():
    return skewpend.reference_parameters()


# -- item 3: a Python law may run a simulation of its own --------------------------------------------------------
def test_a_simulation_inside_a_python_law_gets_its_own_control(ref):
    """The inner run equals the same run alone, and the outer run (which ignores the inner one's
    output) equals the outer law alone -- bitwise here; 1e-12 is the stated tolerance."""
    inner = Controller.feedback(0.5 * K_OUTER, [0, 0, 0, 0], umax=3.0)
    start = (0.4, -0.3, 0.0, 0.0)
    runs = []

    def plain(t, x):
        return -K_OUTER @ x

    def nesting(t, x):
        if len(runs) < 3:  # at the first stages of the first step
            runs.append(skewpend.simulate(ref, start, 0.5, dt_out=0.01, controller=inner))
        return -K_OUTER @ x

    alone = skewpend.simulate(ref, start, 0.5, dt_out=0.01, controller=inner)
    outer = skewpend.simulate(ref, (0.2, 0.1, 0, 0), 1.0, dt_out=0.01, controller=Controller.function(plain, umax=8.0))
    both = skewpend.simulate(ref, (0.2, 0.1, 0, 0), 1.0, dt_out=0.01, controller=Controller.function(nesting, umax=8.0))
    assert len(runs) == 3
    assert max(np.abs(r.y - alone.y).max() for r in runs) <= 1e-12
    assert np.abs(both.y - outer.y).max() <= 1e-12
    assert np.abs(both.inputs() - outer.inputs()).max() <= 1e-12
    # the inner law is really applied (a feedback, not the outer torques nor none)
    free = skewpend.simulate(ref, start, 0.5, dt_out=0.01)
    assert np.abs(alone.y - free.y).max() > 0.1


def test_a_python_law_nested_in_a_python_law(ref):
    """Two Python laws, one inside the other: each run sees its own law."""
    seen = {"inner": 0}

    def inner_law(t, x):
        seen["inner"] += 1
        return (1.0, -1.0)

    alone = skewpend.simulate(ref, (0.1, 0.0, 0, 0), 0.3, dt_out=0.05, controller=Controller.function(inner_law))
    kept = []

    def outer_law(t, x):
        if not kept:
            kept.append(skewpend.simulate(ref, (0.1, 0.0, 0, 0), 0.3, dt_out=0.05,
                                          controller=Controller.function(inner_law)))
        return (-2.0, 0.5)

    def outer_only(t, x):
        return (-2.0, 0.5)

    got = skewpend.simulate(ref, (0.3, 0.2, 0, 0), 0.5, dt_out=0.05, controller=Controller.function(outer_law))
    want = skewpend.simulate(ref, (0.3, 0.2, 0, 0), 0.5, dt_out=0.05, controller=Controller.function(outer_only))
    assert np.abs(kept[0].y - alone.y).max() <= 1e-12
    assert np.abs(got.y - want.y).max() <= 1e-12
    assert np.allclose(got.inputs(), [-2.0, 0.5]) and np.allclose(kept[0].inputs(), [1.0, -1.0])


# -- item 9: Ctrl-C during a slow Python law ------------------------------------------------------------------------
def test_ctrl_c_stops_a_slow_python_law_within_a_second(ref):
    """A law of 2 ms a call: the first compiled call alone would take about a minute (2000 steps
    of 13 stages); Ctrl-C, sent once the run is inside the law, stops it within 1 s."""
    sent = []

    def slow(t, x):
        if not sent:
            sent.append(time.perf_counter())
            threading.Timer(0.2, os.kill, (os.getpid(), signal.SIGINT)).start()
        time.sleep(0.002)
        return (0.0, 0.0)

    with pytest.raises(KeyboardInterrupt):
        skewpend.simulate(ref, (0.5, 0.0, 0, 0), 1000.0, controller=Controller.function(slow))
    took = time.perf_counter() - sent[0] - 0.2
    assert took < 1.0, f"stopped {took:.2f} s after Ctrl-C"
    assert signal.getsignal(signal.SIGINT) is signal.default_int_handler


# -- the widget's run(): no OverflowError, dt checked -------------------------------------------------------------
@pytest.mark.parametrize("t_end, options, words", [
    (1e308, {}, "t_end = 1e+308 s is more than 20000 frames"),
    (1e6, {}, "more than 20000 frames"),
    (1.0, {"method": "rk4", "dt": 0}, "dt must be"),
    (1.0, {"method": "rk4", "dt": 1e-320}, "dt must be at least"),
    (1.0, {"method": "rk4", "dt": "x"}, "dt must be"),
])
def test_widget_run_refuses_in_one_line(t_end, options, words):
    pytest.importorskip("anywidget")
    with pytest.raises(skewpend.errors.ParameterError, match=re.escape(words)):
        skewpend.widget().run(t_end, **options)
