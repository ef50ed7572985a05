"""Issue 51, control and the leaderboard: hostile input refused in one line, a failed run called failed, the lab's
controller interface complete (save, reset, init; the time required), IPOPT's progress said while it runs, and a
cancel that stops a region-of-attraction's compiled call within a step."""

from __future__ import annotations

import json
import math
import threading
import time

import numpy as np
import pytest

import skewpend
from skewpend.analysis import leaderboard as lb
from skewpend.errors import IntegrationError, ParameterError

GOAL = np.array([math.pi, 0.0, 0.0, 0.0])


def _three_links():
    from skewpend.symbolic.chain import Chain, Link

    return Chain(links=(Link(length=0.2, mass=0.5), Link(length=0.2, mass=0.4, axis=(0.3, 0, 1)),
                        Link(length=0.15, mass=0.3)))


@pytest.fixture(scope="module")
def held():
    """A 'swing-up' that holds the acrobot at the top for 0.2 s (a valid OptimalTrajectory without IPOPT) and its
    tracking."""
    from skewpend.analysis.trajopt import OptimalTrajectory, tvlqr
    from skewpend.symbolic.chain import Chain

    t = np.linspace(0.0, 0.2, 11)
    traj = OptimalTrajectory(t, np.tile(GOAL, (11, 1)), np.zeros((11, 2)), Chain.from_parameters(lb.dfki_model()), (2,),
                             GOAL.copy(), 6.0, True, "held at the goal")
    return traj, tvlqr(traj)


# -- the command line ------------------------------------------------------------------------------------------------
def test_cli_leaderboard_refuses_a_symbolic_skew_in_one_line(tmp_path):
    from helpers import run_cli

    ran = run_cli(["control", "leaderboard", "--robot", "acrobot", "--alpha", "sym"], cwd=tmp_path)
    assert ran.code == 2, ran.report()
    assert "--alpha" in ran.err and "sym" in ran.err and len(ran.err.strip().splitlines()) == 1, ran.report()
    assert not list(tmp_path.iterdir())


# -- tvlqr -------------------------------------------------------------------------------------------------------
@pytest.mark.parametrize("kwargs, words", [
    ({"trajectory": "x"}, "trajectory must be an OptimalTrajectory"),
    ({"trajectory": None}, "trajectory must be an OptimalTrajectory"),
    ({"dt": 0}, "dt must be a positive sampling step"),
    ({"dt": -0.002}, "dt must be a positive sampling step"),
    ({"dt": math.nan}, "dt must be a positive sampling step"),
    ({"dt": True}, "dt must be a positive sampling step"),
    ({"dt": 1.0}, "dt must be at most the swing-up's duration"),
    ({"dt": 1e-9}, "at most 1e+06"),
    ({"R": -np.eye(1)}, "R must be a finite, symmetric, positive definite 1 x 1"),
    ({"R": 0.0}, "R must be a finite, symmetric, positive definite"),
    ({"R": np.eye(2)}, "R must be a 1x1 matrix"),
    ({"Q": -np.eye(4)}, "Q must be a finite, symmetric, positive semi-definite 4 x 4"),
    ({"Q": np.triu(np.ones((4, 4)))}, "Q must be a finite, symmetric"),
    ({"Qf": np.ones((3, 3))}, "Qf must be a 4x4 matrix"),
    ({"Qf": np.diag([1.0, 1.0, 1.0, -1.0])}, "Qf must be a finite, symmetric, positive semi-definite"),
])
def test_tvlqr_refuses_bad_input_naming_the_argument(held, kwargs, words):
    from skewpend.analysis.trajopt import tvlqr

    kwargs = dict(kwargs)
    trajectory = kwargs.pop("trajectory", held[0])
    with pytest.raises(ParameterError, match=words.replace("+", r"\+")):
        tvlqr(trajectory, **kwargs)


def test_tvlqr_along_the_goal_is_the_goals_lqr(held):
    """Tracking a motion that stays at the goal: the Riccati recursion starts at the goal's discrete-time solution,
    its fixed point, so every gain along it is the goal's (to round-off) -- and R as a number is R for one motor."""
    from skewpend.analysis.trajopt import tvlqr

    _, tracking = held
    assert tracking.K.shape == (100, 1, 4)
    scale = np.abs(tracking.K_goal).max()
    assert np.abs(tracking.K - tracking.K_goal[None]).max() <= 1e-9 * scale
    assert np.array_equal(tvlqr(held[0], R=20.0).K, tracking.K)


# -- the protocol -----------------------------------------------------------------------------------------------------
def test_run_protocol_refuses_a_law_designed_for_other_motors(held):
    _, tracking = held  # an acrobot's law (the elbow's motor)
    short = lb.Protocol(t_final=0.02)
    with pytest.raises(ParameterError, match=r"actuated \(1\) must be the joints the law was designed for \(2\)"):
        lb.run_protocol(lb.dfki_model(), tracking, actuated=(1,), protocol=short)
    both = skewpend.Controller.feedback(np.zeros((2, 4)), GOAL)  # both motors
    with pytest.raises(ParameterError, match=r"designed for \(1, 2\)"):
        lb.run_protocol(lb.dfki_model(), both, actuated=(2,), protocol=short)
    for bad in ((True,), (2, 2), (2.0,), "2"):
        with pytest.raises(ParameterError, match="actuated must be the numbers of the joints"):
            lb.run_protocol(lb.dfki_model(), tracking, actuated=bad, protocol=short)
    run = lb.run_protocol(lb.dfki_model(), tracking, actuated=(2,), protocol=short)
    assert run.ok and np.all(run.u[:, 0] == 0.0)


def test_a_law_returning_nan_is_a_failed_run_without_criteria():
    protocol = lb.Protocol(t_final=0.1)

    def law(t, x):
        return (0.0, math.nan if t >= 0.05 else 0.1)

    run = lb.run_protocol(lb.dfki_model(), law, actuated=(2,), protocol=protocol)
    assert not run.ok and run.score == 0.0
    assert "non-finite torques at t = 0.05 s" in run.message
    assert np.all(np.isfinite(run.u)) and len(run.t) == 25  # the rows before it, no NaN among them
    with pytest.raises(IntegrationError, match="a failed run has no leaderboard criteria .*non-finite torques"):
        run.criteria


# -- lqr and the chain's labels and joints ---------------------------------------------------------------------------
def test_lqr_of_a_chain_takes_a_word_per_link_and_each_joint_once():
    chain = _three_links()
    for label in ("up-up", "up-up-up-up"):
        with pytest.raises(ParameterError, match=f"equilibrium '{label}' names .* a chain of 3 links has 3"):
            skewpend.lqr(chain, label, estimate=False)
    with pytest.raises(ParameterError, match="target 'up-up' names 2 links"):
        skewpend.region_of_attraction(chain, "up-up", n=4)
    design = skewpend.lqr(chain, estimate=False)  # the default: every link up
    assert design.linearization.equilibrium.label == "up-up-up"
    assert skewpend.lqr(skewpend.reference_parameters(), estimate=False).linearization.equilibrium.label == "up-up"
    for bad in ((True,), (2, 2), (1.0,), (0,), (4,), "2", ()):
        with pytest.raises(ParameterError, match="actuated must be 'all' or the numbers of the joints"):
            skewpend.lqr(chain, actuated=bad, estimate=False)
    both = skewpend.lqr(chain, actuated=np.array([3, 1]), estimate=False)
    assert both.linearization.joints == (0, 2)


def test_optimal_swingup_checks_its_arguments_before_any_work():
    from skewpend.analysis.trajopt import optimal_swingup

    model = lb.dfki_model()
    cases = [
        (dict(start=(math.nan, 0, 0, 0)), "start must be 4 finite numbers"),
        (dict(start=(0, 0, 0)), "start must be 4 finite numbers"),
        (dict(start="hanging"), "start must be 4 finite numbers"),
        (dict(attempts=0), "attempts must be a whole number >= 1"),
        (dict(max_iter=2.5), "max_iter must be a whole number"),
        (dict(actuated=(True,)), "actuated must be one of both, pendubot, acrobot"),
        (dict(actuated=(2, 2)), "actuated must be one of both, pendubot, acrobot"),
        (dict(umax=True), "umax must be a positive torque limit"),
        (dict(guess=math.inf), "guess must be a duration"),
        (dict(iterations=3), "iterations must be a callable"),
    ]
    for kwargs, words in cases:
        with pytest.raises(ParameterError, match=words):
            optimal_swingup(model, **kwargs)
    with pytest.raises(ParameterError, match="goal 'up-up' names 2 links; a chain of 3 links has 3"):
        optimal_swingup(_three_links(), actuated="all", goal="up-up")


# -- the lab's controller interface -----------------------------------------------------------------------------------
def test_the_lab_interface_needs_the_time_and_saves_readable_files(held, tmp_path):
    from skewpend.analysis.trajopt import SpeedObserver

    _, tracking = held
    x = GOAL + np.array([0.05, -0.02, 0.1, 0.0])
    with pytest.raises(ParameterError, match="t must be given"):
        tracking.get_control_output(x)
    with pytest.raises(ParameterError, match="x must be the state, 4 finite numbers"):
        tracking.get_control_output(x[:3], 0.1)
    assert np.array_equal(tracking.get_control_output(x, 0.1), tracking(0.1, x))
    assert tracking.init() is None and tracking.reset() is None
    params, table = tracking.save(tmp_path / "tvlqr")
    entries = {}
    for line in params.read_text().splitlines():
        key, value = line.split(": ", 1)
        entries[key] = json.loads(value)
    assert entries["dt"] == tracking.dt and entries["samples"] == len(tracking.K)
    assert entries["actuated_joints"] == [2] and entries["R"] == [[20.0]]
    assert np.array_equal(entries["K_goal"], tracking.K_goal)
    header = table.read_text().splitlines()[0].split(",")
    assert header[:6] == ["time", "pos1", "pos2", "vel1", "vel2", "tau2"] and header[6:] == [f"K2_{c}" for c in range(1, 5)]
    rows = np.loadtxt(table, delimiter=",", skiprows=1)
    assert np.array_equal(rows[:, 1:5], tracking.x_ref) and np.array_equal(rows[:, 5:6], tracking.u_ref)
    assert np.array_equal(rows[:, 6:], tracking.K.reshape(len(rows), -1))
    assert np.allclose(rows[:, 0], np.arange(len(rows)) * tracking.dt, rtol=0, atol=1e-15)
    with pytest.raises(ParameterError, match="save_dir .* is a file"):
        tracking.save(table)
    observer = SpeedObserver(tracking)
    with pytest.raises(ParameterError, match="t must be given"):
        observer.get_control_output(x)
    saved = observer.save(tmp_path / "observed")
    assert [p.name for p in saved] == ["controller_observer_parameters.yml", "controller_tvlqr_parameters.yml",
                                       "controller_tvlqr_reference.csv"]


# -- IPOPT's progress ---------------------------------------------------------------------------------------------
def test_ipopt_reports_each_iteration_of_each_start():
    """In this process every IPOPT iteration of every start is reported, the count one more each time; from forked
    workers the counts read every POLL s never go back and the last report has every start solved."""
    from skewpend.analysis.trajopt import optimal_swingup

    model = lb.dfki_model()
    for workers in (1, 2):
        seen, done = [], []
        optimal_swingup(model, actuated=(2,), knots=20, attempts=2, max_iter=25, workers=workers,
                        iterations=lambda running, solved, total: seen.append((dict(running), solved, total)),
                        progress=lambda k, total: done.append((k, total)))
        assert done == [(1, 2), (2, 2)]
        assert seen and all(total == 2 for _, _, total in seen)
        per = {0: [], 1: []}
        for running, solved, _ in seen:
            for k, count in running.items():
                per[k].append(count)
        if workers == 1:
            assert [len(r) for r, _, _ in seen] == [1] * len(seen)  # one start at a time
            for k in (0, 1):
                assert per[k] == list(range(len(per[k]))) and 1 < len(per[k]) <= 26, per[k]
            assert [s for r, s, _ in seen if 0 in r] == [0] * len(per[0])
            assert [s for r, s, _ in seen if 1 in r] == [1] * len(per[1])
        else:
            assert all(np.all(np.diff(per[k]) >= 0) for k in (0, 1))
            assert seen[-1][:2] == ({}, 2)
            assert [s for _, s, _ in seen] == sorted(s for _, s, _ in seen)


def test_the_leaderboard_says_ipopts_iterations_on_a_terminal_and_a_line_a_stage_off_one():
    import io

    from rich.console import Console

    from skewpend.cli.leaderboard import REDRAW, ipopt_reporter
    from skewpend.progress import Stages

    calls = [({0: 0}, 0), ({0: 1}, 0), ({0: 2, 1: 0}, 0), ({0: 3, 1: 1}, 0), ({1: 5}, 1), ({1: 6}, 1), ({}, 2)]
    now = [0.0]
    with Stages("control", terminal=False, enabled=True) as off:
        report = ipopt_reporter("optimising", stages=off, clock=lambda: now[0])
        for running, solved in calls:
            report(running, solved, 2)
    said = [line for line in off.lines if "optimising" in line]
    assert [s.split("optimising: ")[1].split("...")[0] for s in said] == [
        "IPOPT on start 1 of 2 (0 solved)", "IPOPT on starts 1, 2 of 2 (0 solved)"]  # a line as a start begins
    with Stages("control", terminal=True, console=Console(file=io.StringIO(), force_terminal=True)) as on:
        report = ipopt_reporter("optimising", stages=on, clock=lambda: now[0])
        for k, (running, solved) in enumerate(calls):
            now[0] = k * 0.6 * REDRAW  # every other call within the redraw interval of the last one drawn
            report(running, solved, 2)
    drawn = [line.split("optimising: ")[1].split("...")[0] for line in on.lines if "optimising" in line]
    assert drawn[0] == "start 1 of 2 at iteration 0"
    assert "start 1 of 2 at iteration 2; start 2 of 2 at iteration 0" in drawn  # a new start is drawn at once
    assert all("iteration" in d or "solved" in d for d in drawn) and len(drawn) < len(calls)


# -- a cancelled capture stops within a step ----------------------------------------------------------------------
def test_a_cancel_stops_a_chains_compiled_capture_within_a_step():
    """Starts that would run for minutes (a chain of three under a tiny torque limit, never captured, 1e4 s at
    rtol 1e-12) in one compiled call: a cancel 0.2 s in ends the call at once (Cancelled), where before it
    was looked at only between calls; the same starts over a short time give the same results with or without a
    watcher (the law untouched while no cancel is set)."""
    from skewpend.numeric.control import capture_many
    from skewpend.numeric.ensemble import Cancelled
    from skewpend.numeric.kernels import model_kernel, model_vector

    chain = _three_links()
    design = skewpend.lqr(chain, actuated="all", umax=0.01, estimate=False)
    kernel, p, law = model_kernel(chain), model_vector(chain), design.controller(umax=0.01)
    starts = np.tile(design.linearization.target, (4, 1))
    starts[:, 0] += [0.5, 1.0, 1.5, 2.0]
    kw = dict(rtol=1e-12, atol=1e-12, max_steps=10**9, P=design.P, rho=1e-9)
    plain = capture_many(kernel, p, law, starts, t_end=0.5, **kw)
    watched = capture_many(kernel, p, law, starts, t_end=0.5, cancel=threading.Event(), **kw)
    assert all(np.array_equal(a, b, equal_nan=True) for a, b in zip(plain, watched))
    assert np.all(plain[0] != plain[0]) and np.all(plain[3] == 0)  # not captured, completed
    cancel = threading.Event()
    outcome = []

    def run():
        try:
            capture_many(kernel, p, law, starts, t_end=1e4, cancel=cancel, **kw)
            outcome.append("finished")
        except Cancelled:
            outcome.append(time.monotonic())

    worker = threading.Thread(target=run, daemon=True)
    worker.start()
    time.sleep(0.2)
    cancel.set()
    set_at = time.monotonic()
    worker.join(timeout=30.0)
    assert outcome and outcome[0] != "finished", outcome
    assert outcome[0] - set_at < 2.0  # generous: one step and the watcher's poll (0.05 s)


def test_the_leaderboard_figure_shows_the_reference_beside_the_run(held):
    """The optimised reference is drawn as a wide light band under each run curve of its colour (a dashed line of
    the same colour and width hid under a run that follows it)."""
    import matplotlib

    matplotlib.use("Agg")
    from matplotlib.colors import to_rgba

    from skewpend.views import figures

    _, tracking = held
    run = lb.run_protocol(lb.dfki_model(), tracking, actuated=(2,), x0=GOAL, protocol=lb.Protocol(t_final=1.0))
    fig = figures.leaderboard_figure(run, tracking)
    angles, _, torques = fig.axes[:3]
    for ax in (angles, torques):
        bands = [ln for ln in ax.get_lines() if "optimised" in ln.get_label()]
        runs = [ln for ln in ax.get_lines() if "optimised" not in ln.get_label() and len(ln.get_xdata()) > 2]
        assert bands, [ln.get_label() for ln in ax.get_lines()]
        for band in bands:
            same = [ln for ln in runs if to_rgba(ln.get_color())[:3] == to_rgba(band.get_color())[:3]]
            assert same and all(band.get_linewidth() >= 4 * ln.get_linewidth() for ln in same)
            assert band.get_alpha() is not None and band.get_alpha() < 0.5 and band.get_linestyle() == "-"
