"""A sampled law (``Controller.function(law, hold=period)``, a digital controller's zero-order hold): simulate runs it
by RK4 at its period, calls it once a step at the step's start with the state reached, and holds its torques over
the step's stages."""

from __future__ import annotations

import math

import numpy as np
import pytest

import skewpend
from skewpend.errors import ParameterError
from skewpend.numeric.control import Controller


def test_the_law_is_called_once_a_step_at_the_accepted_state(reference):
    calls = []

    def law(t, x):
        calls.append((t, np.array(x, dtype=float)))
        return np.array([-2.0 * x[2], -1.0 * x[3] + math.sin(t)])

    ctl = Controller.function(law, hold=0.01)
    tr = skewpend.simulate(reference, (0.4, -0.2, 0.0, 0.0), t_end=1.0, controller=ctl)
    assert tr.method == "rk4" and "sampled" in tr.settings["method_choice"] and len(tr.t) == 101
    times = np.array([c[0] for c in calls[:100]])
    assert np.allclose(times, tr.t[:100], rtol=0, atol=1e-12)  # step k's sample at k dt, in order, once
    states = np.array([c[1] for c in calls[:100]])
    assert np.array_equal(states, tr.y[:100])  # the accepted state, bit for bit
    # held: each step equals an RK4 step of the model with that step's torques as constant torques
    from dataclasses import replace

    for k in (0, 37, 99):
        u = law(tr.t[k], tr.y[k])
        calls.pop()
        step = skewpend.simulate(replace(reference, tau1=u[0], tau2=u[1]), tr.y[k], t_end=0.01, method="rk4", dt=0.01)
        assert np.allclose(step.y[-1], tr.y[k + 1], rtol=0, atol=1e-12), k


@pytest.mark.parametrize("kwargs,words", [
    ({"method": "dop853"}, "a sampled law (held every 0.01 s) runs with method='rk4' and dt=0.01"),
    ({"method": "rk4", "dt": 0.005}, "dt=0.005"),
    ({"method": "rk4"}, "method='rk4'"),
])
def test_other_steps_are_refused(reference, kwargs, words):
    ctl = Controller.function(lambda t, x: np.zeros(2), hold=0.01)
    with pytest.raises(ParameterError, match=words.replace("(", r"\(").replace(")", r"\)")):
        skewpend.simulate(reference, (0.4, -0.2, 0.0, 0.0), t_end=1.0, controller=ctl, **kwargs)


@pytest.mark.parametrize("hold,words", [(0.0, "hold must be a positive sampling period"), (-1.0, "positive"),
                                        (math.inf, "positive"), ("fast", "hold must be a real number"),
                                        (True, "hold must be a real number")])
def test_a_bad_period_is_one_line(hold, words):
    with pytest.raises(ParameterError, match=words):
        Controller.function(lambda t, x: np.zeros(2), hold=hold)


def test_an_exception_anywhere_in_the_callback_stops_the_run(reference, monkeypatch):
    """A signal handler's exception may come at any line of the C callback around a Python law -- here at its
    first, the check for a pending Ctrl-C: it stops the run and is raised (ctypes would print it and go on)."""
    import signal

    from skewpend.interrupts import Terminated

    calls = []

    def boom(sig):
        calls.append(sig)
        raise Terminated()

    monkeypatch.setattr(signal, "getsignal", boom)
    ctl = Controller.function(lambda t, x: np.zeros(2), hold=0.01)
    with pytest.raises(Terminated):
        skewpend.simulate(reference, (0.4, -0.2, 0.0, 0.0), t_end=100.0, controller=ctl)
    assert len(calls) == 1  # stopped at the first call, not 10,000 steps later
