"""The rotary (Furuta) pendulum's swing-up within the driver's 3 V (issue 54's goal): ``examples/qube_servo2.toml``.

* Feasibility, by the optimiser (:func:`skewpend.analysis.trajopt.timed_swingup`): from hanging (nudged 0.05 rad)
  to upright at rest, the arm's end angle free, every torque within ``kt Vmax / R`` = 0.015 N m, is reached in
  1.2 s and not in 1.0 s (the shortest measured: 1.1-1.2 s, ``benchmarks/bench_rotary_swingup.py``); the reach's
  torques applied open-loop in :func:`skewpend.simulate` follow its knots (the two models are one: their right-hand
  sides agree to 1e-15; what differs is the optimiser's one RK4 step per interval).
* The goal, in closed loop (:func:`skewpend.analysis.trajopt.swingup_tracking`): the 1.5 s reach at 90 % of the
  limit tracked by time-varying LQR, then the top's LQR, sampled every 2 ms and held: up within 0.1 rad for every
  t >= 2 s, every torque within the limit, from nudges of 0.05, -0.05, 0.02 and 0.1 rad.
* Nothing of it is the rotary pendulum's: the DFKI pendubot reaches its top in 2 s the same way.
* Bad arguments: one line naming the argument, before any solve.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from skewpend.config import Run
from skewpend.errors import ParameterError

RUN_FILE = Path(__file__).resolve().parents[1] / "examples" / "qube_servo2.toml"
UP = [0.0, np.pi]
START = [0.0, 0.05, 0.0, 0.0]  # hanging, the pendulum nudged 0.05 rad


def rotary():
    run = Run("simulate", str(RUN_FILE))
    return run.chain(), run.motor


def _from_upright(y):
    return np.abs((y[:, 1] % (2 * np.pi)) - np.pi)


@pytest.mark.slow
def test_the_shortest_swingup_within_3_volts_takes_between_1_and_1_2_s():
    """At 3 V the optimiser reaches the top at rest in 1.2 s (every torque within the limit, the arm under a
    fifth of a turn) and, from each of its 4 starts, not in 1.0 s: the closest end is still > 0.1 off (the
    error is the largest of the end angle's cosine and sine differences and 0.1 s x the speeds)."""
    from skewpend.analysis.trajopt import timed_swingup

    chain, motor = rotary()
    umax = motor.torque_limit
    reach = timed_swingup(chain, 1.2, actuated=(1,), umax=umax, goal=UP, start=START, free=(1,))
    assert reach.ok, reach.message
    assert np.max(np.abs(reach.u[:, 0])) <= umax * (1 + 1e-12) and np.all(reach.u[:, 1] == 0)
    assert _from_upright(reach.x[-1:])[0] < 1e-6 and np.max(np.abs(reach.x[-1, 2:])) < 1e-5
    assert np.max(np.abs(reach.x[:, 0])) < 2 * np.pi / 5
    short = timed_swingup(chain, 1.0, actuated=(1,), umax=umax, goal=UP, start=START, free=(1,))
    assert not short.ok and short.predicted["end_error"] > 0.1, short.message
    assert "not reached in 1 s" in short.message


@pytest.fixture(scope="module")
def tracking():
    from skewpend.analysis.trajopt import swingup_tracking

    chain, motor = rotary()
    return swingup_tracking(chain, 1.5, actuated=(1,), umax=motor.torque_limit, goal=UP, start=START, free=(1,))


@pytest.mark.slow
def test_the_reachs_torques_applied_open_loop_in_simulate_follow_its_knots(tracking):
    """The model the optimiser integrates is the simulator's: the right-hand sides agree to 1e-13 (relative) at
    random states and torques; the reach's torques (linear between knots, as :class:`skewpend.Controller`'s
    tracking with no gain applies them) simulated open-loop stay within 0.01 rad and 0.1 rad/s of the knots over
    the 1.5 s (the tracked swing-up's reach, 200 knots at 90 % of the limit: RK4's error per 7.5 ms step ~3e-3,
    measured; not more, though the motion ends on the unstable top)."""
    import skewpend
    from skewpend.analysis.trajopt import casadi_dynamics
    from skewpend.numeric.control import Controller
    from skewpend.numeric.kernels import model_kernel, model_vector, model_vector_names

    chain, motor = rotary()
    umax = motor.torque_limit
    _, rhs, _, _ = casadi_dynamics(chain, (1,))
    kernel = model_kernel(chain)
    p = np.array(model_vector(chain, kernel.form), dtype=float)
    tau = model_vector_names(chain, kernel.form).index("tau1")
    out = np.zeros(2 * chain.n + 1)
    rng = np.random.default_rng(54)
    for _ in range(50):
        y = np.r_[rng.uniform(-np.pi, np.pi, 2), rng.uniform(-20, 20), rng.uniform(-30, 30)]
        p[tau] = u = rng.uniform(-umax, umax)
        kernel.rhs(np.r_[y, 0.0], p, out)
        ours = np.array(rhs(y, [u])).ravel()
        assert np.max(np.abs(ours - out[:4])) <= 1e-13 * np.max(np.abs(out[:4]))
    reach = tracking.trajectory
    assert reach.ok and len(reach.t) == 201 and reach.duration == pytest.approx(1.5), reach.message
    assert np.max(np.abs(reach.u[:, 0])) <= 0.9 * umax * (1 + 1e-12)
    N = len(reach.t) - 1
    law = Controller.tracking(1.5 / N, reach.x, reach.u, np.zeros((N + 1, 2, 4)), np.zeros((2, 4)), reach.goal,
                              actuated=(1,), umax=umax)
    run = skewpend.simulate(chain, reach.x[0], 1.5, dt_out=1.5 / N, controller=law, rtol=1e-11, atol=1e-12)
    gap = np.abs(np.asarray(run.y) - reach.x)
    assert np.max(gap[:, :2]) < 0.01 and np.max(gap[:, 2:]) < 0.1, np.max(gap, axis=0)


@pytest.mark.slow
@pytest.mark.parametrize("nudge", [0.05, -0.05, 0.02, 0.1])
def test_the_tracked_swingup_holds_the_pendulum_up_from_2_s_within_the_voltage_limit(tracking, nudge):
    """Issue 54's goal: from hanging nudged ``nudge`` rad, the tracked 1.5 s swing-up (planned once, from 0.05
    rad) sampled every 2 ms and held as a digital controller: within 0.1 rad of upright for every t >= 2 s (it is
    up from 1.5 s), 1e-3 rad at 4 s, every torque applied within kt Vmax / R (3 V), the largest above the plan's
    90 % of it, the arm under a third of a turn."""
    import skewpend
    from skewpend.analysis.mpc import PERIOD
    from skewpend.numeric.control import Controller

    chain, motor = rotary()
    applied = {}

    def law(t, x):
        k = int(np.floor(t / PERIOD + 0.5))
        if k not in applied:
            applied[k] = tracking(k * PERIOD, np.array(x))
        return applied[k]

    run = skewpend.simulate(chain, [0.0, nudge, 0.0, 0.0], 4.0, dt_out=0.01,
                            controller=Controller.function(law, actuated=(1,), nq=2, hold=PERIOD))
    assert run.ok, run.message
    t, y = np.asarray(run.t), np.asarray(run.y)
    u = np.array([applied[k] for k in sorted(applied)])
    off = _from_upright(y)
    assert np.all(off[t >= 2.0] < 0.1) and np.all(off[t >= 1.5] < 0.1) and off[-1] < 1e-3
    assert np.max(np.abs(u[:, 0])) <= motor.torque_limit * (1 + 1e-12) and np.all(u[:, 1] == 0)
    assert np.max(np.abs(motor.voltage(u[:, 0]))) <= motor.voltage_limit * (1 + 1e-9)
    assert np.max(np.abs(u[:, 0])) > 0.89 * motor.torque_limit  # the plan's 90 % of the limit, and more
    assert np.max(np.abs(y[:, 0])) < 2 * np.pi / 3


@pytest.mark.parametrize("call, words", [
    (lambda f, c: f(c, 0.0, actuated=(1,), umax=0.015, goal=UP), "duration must be a duration in (0, 60] s"),
    (lambda f, c: f(c, 1.0, actuated=(1,), umax=0.015, goal=UP, free=(3,)), "free must be joints' numbers (1 .. 2)"),
    (lambda f, c: f(c, 1.0, actuated=(1,), umax=0.015, goal=UP, free=(1, 2)), "at least one joint's end angle"),
    (lambda f, c: f(c, 1.0, actuated=(1,), umax=-1.0, goal=UP), "umax must be a positive torque limit"),
    (lambda f, c: f(c, 1.0, actuated=(1,), umax=0.015, goal=UP, knots=5), "knots must be a whole number"),
])
def test_bad_reach_arguments_are_one_line(call, words):
    from skewpend.analysis.trajopt import timed_swingup

    chain, _ = rotary()
    with pytest.raises(ParameterError) as err:
        call(timed_swingup, chain)
    assert words in str(err.value) and "\n" not in str(err.value)


def test_bad_shortest_and_tracking_arguments_are_one_line():
    from skewpend.analysis.trajopt import shortest_swingup, swingup_tracking

    chain, _ = rotary()
    with pytest.raises(ParameterError, match=r"durations must be \(shortest, longest\)"):
        shortest_swingup(chain, actuated=(1,), umax=0.015, goal=UP, durations=(2.0, 1.0))
    with pytest.raises(ParameterError, match=r"resolution must be a duration"):
        shortest_swingup(chain, actuated=(1,), umax=0.015, goal=UP, resolution=-1)
    with pytest.raises(ParameterError, match=r"margin must be the share of the torque limit"):
        swingup_tracking(chain, 1.5, actuated=(1,), umax=0.015, goal=UP, margin=1.5)


@pytest.mark.slow
def test_the_reach_is_any_chains_the_dfki_pendubot_in_2_s():
    """Nothing in the reach is the rotary pendulum's: the DFKI double pendulum with its shoulder actuated (6 N m)
    reaches every link up at rest in 2 s (its end angles up modulo turns), its torques within the limit, the
    elbow's zero, the knots' end an equilibrium of the model (no acceleration without torque)."""
    from skewpend.analysis import leaderboard as lb
    from skewpend.analysis.trajopt import casadi_dynamics, timed_swingup

    model = lb.dfki_model()
    reach = timed_swingup(model, 2.0, actuated=(1,), umax=6.0)
    assert reach.ok, reach.message
    assert np.max(np.abs(reach.u[:, 0])) <= 6.0 * (1 + 1e-12) and np.all(reach.u[:, 1] == 0)
    up = np.array([np.pi, 0.0])  # the first link up, the second along it (relative angles)
    assert np.max(np.abs(np.angle(np.exp(1j * (reach.x[-1, :2] - up))))) < 1e-6
    assert np.max(np.abs(reach.x[-1, 2:])) < 1e-5
    _, rhs, _, _ = casadi_dynamics(reach.chain, (1,))
    assert np.max(np.abs(np.array(rhs(reach.goal, [0.0])).ravel())) < 1e-6


@pytest.mark.slow
def test_the_shortest_swingup_is_bisected_to_its_resolution():
    """``shortest_swingup`` over 1.0-1.25 s to 0.2 s at 3 V, one start a trial (the hanging state held, then the
    shortest reach so far): reached at 1.25 s, not at 1.125 s (below the 1.18 s bound measured to 0.01 s) -- the
    shortest returned is 1.25 s, said with the 1.125 s not reached, an end at rest on the top within the limit."""
    from skewpend.analysis.trajopt import shortest_swingup

    chain, motor = rotary()
    r = shortest_swingup(chain, actuated=(1,), umax=motor.torque_limit, goal=UP, start=START, free=(1,),
                         durations=(1.0, 1.25), resolution=0.2, attempts=1)
    assert r.ok, r.message
    assert r.duration == pytest.approx(1.25) and "not reached in 1.125 s" in r.message
    assert np.max(np.abs(r.u[:, 0])) <= motor.torque_limit * (1 + 1e-12)
    assert _from_upright(r.x[-1:])[0] < 1e-6 and np.max(np.abs(r.x[-1, 2:])) < 1e-5
