"""Model-predictive control (skewpend.analysis.mpc): its one step is the Gauss-Newton step of its stated problem
(computed here independently: the specification's SymPy equations, finite differences, SciPy's Riccati and bounded
least squares), it swings the DFKI rig up as acrobot and pendubot, it refuses bad input in one line, says what it
applied when a step fails, and speaks the DFKI lab's controller interface."""

from __future__ import annotations

import math

import numpy as np
import pytest
import scipy.linalg as sl
from scipy.optimize import lsq_linear

from skewpend.errors import ParameterError

pytest.importorskip("casadi")


@pytest.fixture(scope="module")
def rig():
    from skewpend.analysis.leaderboard import dfki_model

    return dfki_model()


@pytest.fixture(scope="module")
def acrobot_mpc(rig):
    from skewpend.analysis.mpc import MPC

    return MPC(rig, actuated=(2,), umax=6.0)


def _exact_step(rig, joints, h, substeps=1):
    """``substeps`` RK4 steps over ``h`` of the exact (SymPy) equations, the actuated joints' torques held, and the
    energy."""
    from skewpend.numeric.kernels import model_kernel, model_vector, model_vector_names

    kernel = model_kernel(rig, "exact")
    p0 = np.array(model_vector(rig, "exact"), dtype=float)
    names = model_vector_names(rig, "exact")

    def f(y, u):
        p = p0.copy()
        for j, uj in zip(joints, u):
            p[names.index(f"tau{j}")] += uj
        out = np.zeros(5)  # the state and the energy the forces do (the kernels' layout)
        kernel.rhs(np.append(np.asarray(y, dtype=float), 0.0), p, out)
        return out[:4]

    def step(y, u):
        d = h / substeps
        for _ in range(substeps):
            k1 = f(y, u)
            k2 = f(y + d / 2 * k1, u)
            k3 = f(y + d / 2 * k2, u)
            k4 = f(y + d * k3, u)
            y = y + d / 6 * (k1 + 2 * k2 + 2 * k3 + k4)
        return y

    return step, (lambda y: kernel.energy(np.asarray(y, dtype=float), p0))


def _jacobian(fn, x, eps=1e-6):
    x = np.asarray(x, dtype=float)
    cols = []
    for i in range(x.size):
        d = np.zeros_like(x)
        d[i] = eps
        cols.append((np.atleast_1d(fn(x + d)) - np.atleast_1d(fn(x - d))) / (2 * eps))
    return np.column_stack(cols)


@pytest.mark.parametrize("robot,joints", [("acrobot", (2,)), ("pendubot", (1,))])
def test_one_step_is_the_gauss_newton_step_of_the_stated_problem(rig, robot, joints):
    """From zero torques at a state, one iteration's plan equals the bounded linear least-squares step of the
    module's problem built here from the exact SymPy equations by finite differences (its error ~1e-8 in the
    Jacobians, amplified by the step's conditioning: 1e-4 N m allowed against torques of order 1-6 N m)."""
    from skewpend.analysis.mpc import MPC, MPCSettings

    s = MPCSettings(first=1)
    mpc = MPC(rig, actuated=joints, umax=6.0, settings=s)
    assert mpc.settings.horizon == 0.5  # the default on this rig: its unstable mode grows at 9.35/s (4.7 / 9.35 > 0.5)
    h, N, n = mpc.settings.horizon / s.nodes, s.nodes, 2
    step, energy = _exact_step(rig, joints, h, s.substeps)
    goal = np.array([math.pi, 0.0, 0.0, 0.0])
    A = _jacobian(lambda y: step(y, [0.0]), goal)
    B = _jacobian(lambda u: step(goal, u), np.zeros(1))
    ta, ts, tu = s.terminal
    P = sl.solve_discrete_are(A, B, np.diag([ta, ta, ts, ts]), tu * np.eye(1))
    L = np.linalg.cholesky(P).T
    e_goal, e_hang = energy(goal), energy(np.zeros(4))
    x0 = np.array([0.4, -0.7, 1.1, -0.5])
    g = goal.copy()
    g[:n] = x0[:n] + (np.mod(goal[:n] - x0[:n] + np.pi, 2 * np.pi) - np.pi)
    w = np.sqrt([s.angle, s.angle, s.speed, s.speed])

    def residual(U):
        x, r = x0, []
        for k in range(N):
            x = step(x, [U[k]])
            if k < N - 1:
                r += [math.sqrt(s.energy) * (energy(x) - e_goal) / (e_goal - e_hang), *(w * (x - g))]
            else:
                r += list(L @ (x - g))
        return np.array(r + list(math.sqrt(s.torque) * np.asarray(U)))

    U0 = np.zeros(N)
    r0, J = residual(U0), _jacobian(residual, U0)
    expected = lsq_linear(J, -r0, bounds=(-6.0, 6.0), method="bvls", tol=1e-14).x
    got = mpc(0.0, x0)
    assert np.max(np.abs(mpc.plan()[:, 0] - expected)) < 1e-4, (mpc.plan()[:, 0], expected)
    assert got[joints[0] - 1] == mpc.plan()[0, 0] and got[2 - joints[0]] == 0.0
    assert np.any(np.abs(expected) > 1.0)  # a step that moves: the comparison is not of zeros


@pytest.mark.slow
@pytest.mark.parametrize("joints", [(2,), (1,)], ids=["acrobot", "pendubot"])
def test_it_swings_the_rig_up_and_holds_it_by_the_leaderboards_protocol(rig, joints):
    """Hanging at rest, the leaderboard's protocol (RK4, 2 ms, 10 s, |u| <= 6 N m): the rig swings up and ends at
    the goal (within 0.35 rad and 1 rad/s, the robustness board's test), no step fell back."""
    from skewpend.analysis.leaderboard import criteria, run_protocol
    from skewpend.analysis.mpc import MPC
    from skewpend.analysis.robustness import at_goal

    mpc = MPC(rig, actuated=joints, umax=6.0)
    run = run_protocol(rig, mpc, actuated=joints, umax=6.0)
    c = criteria(run.t, run.x, run.u, run.heights, run.reach)
    assert run.ok and c.success and c.swingup_time < 5.0, c
    assert at_goal(run.final)
    assert mpc.fallbacks == 0 and mpc.message == ""
    assert np.max(np.abs(run.u[:, joints[0] - 1])) <= 6.0 and np.all(run.u[:, 2 - joints[0]] == 0.0)
    assert mpc.solve_times.size == run.t.size and np.all(mpc.solve_times > 0)
    assert mpc.solve_cpu_times.size == run.t.size and np.all(mpc.solve_cpu_times >= 0)


def test_a_failed_step_is_solved_again_from_zero_else_brakes_and_says_so(acrobot_mpc, monkeypatch):
    mpc = acrobot_mpc
    mpc.reset()
    x = np.array([0.3, 0.2, 0.4, -1.5])
    mpc(0.0, x)
    real = mpc._iterate
    calls = []

    def first_fails(*args):  # the plan's step fails, the restart from zero torques succeeds
        calls.append(np.array(mpc.plan()))
        return False if len(calls) == 1 else real(*args)

    monkeypatch.setattr(mpc, "_iterate", first_fails)
    u = mpc(0.002, x)
    assert len(calls) == 2 and np.all(calls[1] == 0.0) and mpc.restarts == 1 and mpc.fallbacks == 0
    assert u[1] == mpc.plan()[0, 0] and mpc.message == ""
    monkeypatch.setattr(mpc, "_iterate", lambda *a: False)
    u = mpc(0.004, x)  # both fail: the motor brakes its joint (q2' = -1.5 rad/s: +umax)
    assert u[1] == pytest.approx(6.0) and u[0] == 0.0 and mpc.fallbacks == 1 and np.all(mpc.plan() == 0.0)
    assert "braked the motors' joints" in mpc.message and "t = 0.004" in mpc.message
    u = mpc(0.006, np.array([0.3, 0.2, 0.0, 0.5]))  # a slow joint: proportional
    assert u[1] == pytest.approx(-3.0) and mpc.message.startswith("2 step(s)") and "t = 0.004" in mpc.message
    monkeypatch.undo()
    mpc.reset()
    assert mpc.fallbacks == 0 and mpc.restarts == 0 and mpc.message == "" and np.all(mpc.plan() == 0.0)


def test_an_earlier_time_starts_a_new_run(acrobot_mpc):
    mpc = acrobot_mpc
    mpc.reset()
    x = np.array([0.3, 0.2, 0.0, 0.0])
    first = mpc(0.0, x).copy()
    for k in range(1, 5):
        mpc(k * 0.002, x)
    assert np.array_equal(mpc(0.0, x), first)  # the same start, the same torques: nothing kept from the run


@pytest.mark.parametrize("kwargs,words", [
    ({"umax": math.inf}, "umax must be a finite positive torque"),
    ({"umax": None}, "umax must be"),
    ({"umax": -1.0}, "umax must be"),
    ({"umax": (1.0, 2.0)}, "umax must be"),
    ({"umax": True}, "umax must be"),
    ({"actuated": (3,)}, "joint"),
    ({"settings": "fast"}, "settings must be an MPCSettings"),
    ({"period": 0.0}, "period must be a positive"),
])
def test_bad_input_is_one_line(rig, kwargs, words):
    from skewpend.analysis.mpc import MPC

    with pytest.raises(ParameterError) as err:
        MPC(rig, **{"actuated": (2,), "umax": 6.0, **kwargs})
    assert words in str(err.value) and "\n" not in str(err.value)


@pytest.mark.parametrize("field,value,words", [
    ("horizon", 0.0, "horizon must be a positive"), ("nodes", 1, "nodes must be a whole number from 2"),
    ("nodes", 2.5, "nodes must be"), ("torque", 0.0, "torque must be a positive"), ("energy", -1.0, "energy must be"),
    ("iterations", 0, "iterations must be"), ("terminal", (1.0, 1.0), "terminal must be"),
    ("terminal", (1.0, 0.0, 1.0), "terminal speed must be"), ("delay", -0.01, "delay must be a non-negative"),
    ("delay", math.nan, "delay must be"), ("delay", True, "delay must be"),
    ("max_delay", -1.0, "max_delay must be a non-negative"),
])
def test_bad_settings_are_one_line(field, value, words):
    from dataclasses import replace

    from skewpend.analysis.mpc import MPCSettings

    with pytest.raises(ParameterError) as err:
        replace(MPCSettings(), **{field: value}).check()
    assert words in str(err.value)


@pytest.mark.parametrize("name,delay", [("delay", 0.0009), ("delay", 0.5), ("max_delay", 0.0009), ("max_delay", 0.5)])
def test_a_delay_off_the_periods_is_refused(rig, name, delay):
    """The predictor carries the state over whole sampling periods, 1 to MAX_DELAY_STEPS of them."""
    from skewpend.analysis.mpc import MAX_DELAY_STEPS, MPC, MPCSettings

    with pytest.raises(ParameterError) as err:
        MPC(rig, actuated=(2,), umax=6.0, settings=MPCSettings(**{name: delay}))
    assert str(err.value) == (f"{name} must be 0 or 0.001 to {MAX_DELAY_STEPS * 0.002:g} s (half a sampling period "
                              f"to {MAX_DELAY_STEPS} of them; period 0.002 s), got {delay!r}")
    with pytest.raises(ParameterError, match=r"delay \(the first estimate\) must be at most max_delay, got 0.03 > 0.02"):
        MPC(rig, actuated=(2,), umax=6.0, settings=MPCSettings(delay=0.03, max_delay=0.02))


@pytest.mark.slow
def test_the_delays_predictor_undoes_a_known_delay(rig):
    """The pendubot's swing-up by the leaderboard's protocol, the law shown the state 10 steps (0.02 s) old: an MPC
    told of that delay carries the state over it by the torques it applied, RK4 steps of the period as the protocol's
    plant takes them, so its run is the undelayed MPC's run to rounding (the start is a rest: the steps before the
    run change nothing) -- 1e-9 rad over the 10 s; the MPC not told leaves that run by radians."""
    from skewpend.analysis.leaderboard import Disturbance, run_protocol
    from skewpend.analysis.mpc import MPC, MPCSettings

    late = Disturbance(delay=10)
    now = run_protocol(rig, MPC(rig, actuated=(1,), umax=6.0), actuated=(1,))
    told = MPC(rig, actuated=(1,), umax=6.0, settings=MPCSettings(delay=0.02))
    assert told.past == 10 and "a delay of 0.02 s" in repr(told)
    predicted = run_protocol(rig, told, actuated=(1,), disturbance=late)
    blind = run_protocol(rig, MPC(rig, actuated=(1,), umax=6.0), actuated=(1,), disturbance=late)
    assert now.ok and predicted.ok and np.abs(predicted.x - now.x).max() < 1e-9
    assert np.abs(blind.x - now.x).max() > 0.5


@pytest.mark.slow
@pytest.mark.parametrize("joints,steps", [((1,), 0), ((1,), 7), ((2,), 17), ((1,), 20)])
def test_the_delay_is_estimated_from_the_positions(rig, joints, steps):
    """``max_delay``: the law shown the state ``steps`` periods old, speeds from the positions (the robustness board's
    delay runs), the MPC finds that delay exactly -- the one under which its torques explain the positions' second
    differences (no noise: the true delay's misfit is the differences' O(dt^2) error, any other's the torques'
    change) -- and swings the rig up to the goal; the delay unknown to it, 17 or 20 steps lose the goal."""
    from skewpend.analysis.leaderboard import Disturbance, run_protocol
    from skewpend.analysis.mpc import MPC, MPCSettings
    from skewpend.analysis.robustness import at_goal

    mpc = MPC(rig, actuated=joints, umax=6.0, settings=MPCSettings(max_delay=0.04))
    assert mpc.delay == 0.0 and "the delay estimated from 0 to 0.04 s" in repr(mpc)
    run = run_protocol(rig, mpc, actuated=joints, disturbance=Disturbance(delay=steps), speeds="positions")
    assert mpc.delay == pytest.approx(0.002 * steps, abs=1e-12)
    assert run.ok and at_goal(run.final) and mpc.fallbacks == 0
    if steps == 0:  # no delay: the estimate stays at none, and the run is the MPC's without a predictor
        plain = run_protocol(rig, MPC(rig, actuated=joints, umax=6.0), actuated=joints, speeds="positions")
        assert np.abs(plain.x - run.x).max() < 1e-9
    if steps >= 17:
        blind = run_protocol(rig, MPC(rig, actuated=joints, umax=6.0), actuated=joints,
                             disturbance=Disturbance(delay=steps), speeds="positions")
        assert not at_goal(blind.final)


@pytest.mark.slow
def test_torque_noise_does_not_fool_the_delays_estimate(rig):
    """No delay, Gaussian noise of 1.1 N m on the applied torque (the torque-noise criterion's largest): the noise
    adds the same misfit to every delay, so the estimate stays near none (within 0.01 s, a quarter of the range) and
    the pendubot still reaches the goal."""
    from skewpend.analysis.leaderboard import Disturbance, run_protocol
    from skewpend.analysis.mpc import MPC, MPCSettings
    from skewpend.analysis.robustness import at_goal

    mpc = MPC(rig, actuated=(1,), umax=6.0, settings=MPCSettings(max_delay=0.04))
    for seed in range(3):
        run = run_protocol(rig, mpc, actuated=(1,), disturbance=Disturbance(torque_noise=1.1, seed=seed),
                           speeds="positions")
        assert run.ok and at_goal(run.final) and mpc.delay <= 0.01


def test_bad_states_and_times_are_refused(acrobot_mpc):
    with pytest.raises(ParameterError, match="x must be the state, 4 finite numbers"):
        acrobot_mpc(0.0, [0.0, 0.0, np.nan, 0.0])
    with pytest.raises(ParameterError, match="x must be the state"):
        acrobot_mpc(0.0, [0.0, 0.0])
    with pytest.raises(ParameterError, match="t must be given"):
        acrobot_mpc.get_control_output([0.0] * 4)


def test_the_dfki_interface(acrobot_mpc, tmp_path):
    """``init``/``reset`` forget the run, ``get_control_output(x, t)`` is the call, ``save(dir)`` writes the
    settings (the lab's benchmark code calls all of them)."""
    import yaml

    mpc = acrobot_mpc
    mpc.init()
    x = [0.2, -0.1, 0.0, 0.3]
    u = mpc.get_control_output(x, 0.0)
    mpc.reset()
    assert np.array_equal(mpc(0.0, np.array(x)), u)
    path = mpc.save(tmp_path / "ctl")
    data = yaml.safe_load(path.read_text())
    assert data["actuated_joints"] == [2] and data["torque_limits"] == [6.0] and data["nodes"] == 20
    assert data["goal"] == pytest.approx([math.pi, 0, 0, 0])


@pytest.mark.slow
def test_it_runs_in_simulate_sampled_and_held(rig):
    """``controller()`` in :func:`skewpend.simulate`: "auto" runs the sampled law by RK4 at its period, one solve a
    step at the step's start, the torques held over the step (the trajectory's torques are those held); a pendubot
    near the top is brought to it.  An adaptive method is refused in one line."""
    import skewpend
    from skewpend.analysis.mpc import MPC

    mpc = MPC(rig, actuated=(1,), umax=6.0, period=0.01)
    res = skewpend.simulate(rig, (math.pi - 0.2, 0.3, 0.0, 0.0), t_end=3.0, controller=mpc.controller())
    assert res.method == "rk4" and "sampled" in res.settings["method_choice"]
    end = res.y[-1]
    assert abs(math.remainder(end[0] - math.pi, 2 * math.pi)) < 1e-2 and abs(math.remainder(end[1], 2 * math.pi)) < 1e-2
    assert np.all(np.abs(end[2:]) < 5e-2)
    assert mpc.solve_times.size == 300 and mpc.fallbacks == 0  # one solve a step of 0.01 s
    u = res.inputs()[:-1, 0]  # the rows are the steps' starts: the torques held from each
    assert np.max(np.abs(u)) <= 6.0 and np.std(u) > 0
    # the held torques reproduce the run: RK4 steps with each row's torque, on the exact form's equations
    from skewpend.numeric.kernels import model_kernel, model_vector, model_vector_names

    kernel, p0 = model_kernel(rig), np.array(model_vector(rig), dtype=float)
    k_tau = model_vector_names(rig).index("tau1")

    def f(y, tau):
        p = p0.copy()
        p[k_tau] += tau
        out = np.zeros(5)
        kernel.rhs(np.append(y, 0.0), p, out)
        return out[:4]

    y, h = res.y[0].copy(), 0.01
    for k in range(50):
        k1 = f(y, u[k])
        k2 = f(y + h / 2 * k1, u[k])
        k3 = f(y + h / 2 * k2, u[k])
        k4 = f(y + h * k3, u[k])
        y = y + h / 6 * (k1 + 2 * k2 + 2 * k3 + k4)
        assert np.allclose(y, res.y[k + 1], rtol=0, atol=1e-9), k
    with pytest.raises(ParameterError, match="a sampled law .* runs with method='rk4' and dt=0.01"):
        skewpend.simulate(rig, (3.0, 0.0, 0.0, 0.0), t_end=1.0, controller=mpc.controller(), method="dop853")
    with pytest.raises(ParameterError, match="dt=0.01"):
        skewpend.simulate(rig, (3.0, 0.0, 0.0, 0.0), t_end=1.0, controller=mpc.controller(), method="rk4", dt=0.005)


@pytest.mark.slow
def test_a_chain_of_three_is_held_up():
    """Any model: a triple pendulum with motors on joints 1 and 3, started near every link up, is brought there."""
    from skewpend.analysis.leaderboard import Protocol, run_protocol
    from skewpend.analysis.mpc import MPC
    from skewpend.symbolic.chain import Chain

    chain = Chain.from_lists(3, length=0.5, mass=1.0)
    mpc = MPC(chain, actuated=(1, 3), umax=(10.0, 10.0))
    run = run_protocol(chain, mpc, actuated=(1, 3), umax=10.0, protocol=Protocol(t_final=3.0),
                       x0=[math.pi - 0.15, 0.1, -0.1, 0.0, 0.0, 0.0])
    assert run.ok and mpc.fallbacks == 0
    # every link up (modulo a turn: it may take one on the way), settling: within the robustness board's goal test
    # by far, and the tip above 0.9 of its reach through the last second
    err = np.abs(np.remainder(run.final[:3] - np.array([math.pi, 0.0, 0.0]) + math.pi, 2 * math.pi) - math.pi)
    assert np.all(err < 0.05) and np.all(np.abs(run.final[3:]) < 0.2), run.final
    assert np.all(run.heights[run.t > 2.0] > 0.9 * run.reach)


@pytest.mark.slow
def test_the_swingup_command_runs_the_mpc_and_says_its_account(tmp_path):
    """``control swingup --controller mpc``: the reference rig with both motors is captured in the LQR's region and
    held; the MPC's problem, solves and failures are said; the figure is written (drawn from the run's held torques)."""
    from helpers import run_cli

    fig = tmp_path / "mpc.png"
    ran = run_cli(["control", "swingup", "--controller", "mpc", "--actuated", "both", "--t-end", "3", "--plot", fig])
    assert ran.code == 0, ran.report()
    assert "captured in the LQR's region at t = " in ran.out
    assert "controller  model-predictive: 20 RK4 nodes over 0.5 s, sampled every 2 ms; 1501 solves" in ran.out
    assert "no step failed" in ran.out and fig.stat().st_size > 10_000


@pytest.mark.parametrize("argv,words", [
    (["control", "swingup", "--controller", "tvlqr"], "--controller: control swingup runs energy or mpc, got 'tvlqr'"),
    (["control", "leaderboard", "--robot", "acrobot", "--controller", "energy"],
     "--controller: control leaderboard runs tvlqr or mpc, got 'energy'"),
    (["control", "lqr", "--controller", "mpc"], "--controller goes with 'control swingup' or 'control leaderboard'"),
    (["control", "swingup", "--controller", "mpc", "--energy-gain", "3"], "--energy-gain is a setting of the energy"),
    (["control", "swingup", "--controller", "mpc", "--r", "2"], "--r is a setting of the energy"),
    (["control", "swingup", "--controller", "mpc", "--umax", "0"], "--umax"),
])
def test_the_commands_refuse_what_the_mpc_does_not_take(argv, words):
    from helpers import run_cli

    ran = run_cli(argv)
    assert ran.code == 2 and words in ran.err and ran.err.count("\n") == 1, ran.report()


@pytest.mark.slow
@pytest.mark.parametrize("robot,joint", [("acrobot", 2), ("pendubot", 1)])
def test_the_leaderboard_command_scores_the_mpc_on_both_boards(robot, joint, tmp_path, tmp_path_factory):
    """``control leaderboard --controller mpc`` (v2) and ``--version v3`` (the MPC by default): the run is scored
    and its account said; the v2 swing-up succeeds (exit 0), the v3 uptime is a real fraction of the 60 s.  The
    v3 run is docs/guide/control.md's command, run once per session as a reader runs it (the README test checks
    the same run: tests/helpers.py's SHARED_COMMANDS)."""
    from helpers import run_cli, shared_cli_run

    ran = run_cli(["control", "leaderboard", "--robot", robot, "--controller", "mpc", "--out", tmp_path / "v2.csv"])
    assert ran.code == 0, ran.report()
    assert f"motor on joint {joint}" in ran.out and "controller   model-predictive" in ran.out
    assert "success                         yes" in ran.out and (tmp_path / "v2.csv").stat().st_size > 100_000
    v3 = {"acrobot": "skewpend control leaderboard --robot acrobot --version v3 --out acrobot-v3.csv",
          "pendubot": "skewpend control leaderboard --robot pendubot --version v3"}[robot]
    made = shared_cli_run(tmp_path_factory, v3)
    assert made["returncode"] == 0, made["output"][-3000:]
    assert "the MPC swings up from wherever a reset leaves the rods" in made["output"]
    uptime = float(next(line for line in made["output"].splitlines() if line.startswith("uptime [s]")).split()[-1])
    assert 20.0 < uptime < 60.0  # seed 0: 29.6 s (pendubot) measured; TVLQR's 4-11 s
