"""The RealAIGym leaderboard in skewpend: its score from the published numbers, its criteria from rows whose
values are known in closed form, its protocol's plant against the lab's own equations, and skewpend's optimal
swing-ups (trajectory optimisation, time-varying LQR) run and scored by that protocol.

The published numbers: ``scores.csv`` of every simulation_v2 entry of dfki-ric-underactuated-lab/
real_ai_gym_leaderboard (commit 81ea5bc): success, swing-up time, energy, torque cost, smoothness, velocity
cost and the score the lab computed.  (skewpend's criteria recomputed from those entries' published
trajectories, ``sim_swingup.csv``, give the same numbers to 1e-14: benchmarks/bench_leaderboard.py
--published.)"""

from __future__ import annotations

import math
import re
from pathlib import Path

import numpy as np
import pytest

from skewpend.analysis import leaderboard as lb
from skewpend.errors import EquilibriumError, ParameterError

# robot, entry: success, swing-up time [s], energy [J], torque cost, smoothness, velocity cost, score (the lab's)
PUBLISHED = {
    ("acrobot", "ar_eapo"): (1, 1.394000000000001, 8.322843658448338, 1.5169970532884, 0.008076883429364525,
                             117.96157720290056, 0.6326131852346231),
    ("acrobot", "evolsac"): (1, 0.9640000000000007, 9.260615537277895, 2.713043878883556, 0.0300476622396909,
                             96.56281902349662, 0.5240572289076553),
    ("acrobot", "history_sac"): (1, 1.0000000000000007, 8.077749161960673, 1.8037118196867141, 0.009546752841345449,
                                 88.4965605525382, 0.6552699844147534),
    ("acrobot", "ilqr_ilqrmpc_lqr"): (1, 4.857999999999687, 11.541617494570433, 2.6822333268242105,
                                      0.09562800767173717, 110.40383014232302, 0.3447891161284079),
    ("acrobot", "ilqr_riccati_lqr"): (1, 4.043999999999777, 10.55354541082145, 1.9803183449555875, 0.0673906486953918,
                                      106.49145812533652, 0.39583488165025016),
    ("acrobot", "ilqr_tvlqr"): (1, 4.045999999999776, 10.433058105019839, 1.8688740810272428, 0.015537700445571286,
                                105.83028573430587, 0.5042327646623914),
    ("acrobot", "mcpilco"): (1, 1.446000000000001, 19.42529671831582, 3.220376833800871, 0.09690809960262078,
                             253.58977826055238, 0.3164769436997448),
    ("pendubot", "ar_eapo"): (1, 1.1500000000000008, 7.719128043253907, 2.426981034454814, 0.010329143078101377,
                              64.32603787855236, 0.6588462186786841),
    ("pendubot", "evolsac"): (1, 0.7060000000000005, 9.827938629838249, 4.373127468653795, 0.013972766079172845,
                              58.15285978325633, 0.5959660563516244),
    ("pendubot", "history_sac"): (1, 1.1520000000000008, 7.673973574502183, 2.359531440786147, 0.007146586919567306,
                                  62.072620040729596, 0.6823779743749803),
    ("pendubot", "ilqr_ilqrmpc_lqr"): (1, 4.121999999999768, 9.905201139883978, 1.76547788718716, 0.0834364604895879,
                                       211.98358215816341, 0.35252012356567786),
    ("pendubot", "ilqr_riccati_lqr"): (1, 4.129999999999767, 9.529696854965655, 1.2545789509915404,
                                       0.005226075499991789, 211.340945049372, 0.5360782661781311),
    ("pendubot", "ilqr_tvlqr_lqr"): (1, 4.129999999999767, 9.531744032050831, 1.2566299624568558,
                                     0.006820170383116629, 211.1212410729301, 0.5263820174708814),
    ("pendubot", "mcpilco"): (1, 1.1380000000000008, 8.346170584799614, 2.424529125027399, 0.05389399646663416,
                              114.2579014428372, 0.4797920906741808),
}


@pytest.mark.parametrize("key", sorted(PUBLISHED), ids=lambda k: f"{k[0]}-{k[1]}")
def test_the_published_criteria_give_the_published_scores(key):
    success, time, energy, tau, smooth, vel, published = PUBLISHED[key]
    got = lb.score({"success": success, "swingup_time": time, "energy": energy, "tau_cost": tau,
                    "tau_smoothness": smooth, "velocity_cost": vel})
    assert got == pytest.approx(published, rel=1e-13, abs=0)


def test_the_best_published_entries_are_stated():
    best = {r: max(v[-1] for (robot, _), v in PUBLISHED.items() if robot == r) for r in ("acrobot", "pendubot")}
    for robot in best:
        assert round(best[robot], 3) == lb.PUBLISHED[robot]["simulation"][1]


def _rows(k=5000, dt=0.002):
    return np.arange(k) * dt


def test_criteria_of_rows_known_in_closed_form():
    """Constant speeds, a torque ramp and a height that crosses the line once: each criterion as the
    leaderboard's definitions give it by hand."""
    t = _rows()
    k = t.size
    v = np.array([0.3, -0.2])
    x = np.zeros((k, 4))
    x[:, 0], x[:, 1] = v[0] * t, v[1] * t
    x[:, 2:] = v
    u = np.zeros((k, 2))
    u[:, 1] = 0.01 * np.arange(k)  # steps of exactly 0.01
    heights = np.where(t >= 1.5, 0.48, 0.0)
    c = lb.criteria(t, x, u, heights, 0.5)
    assert c.success and c.swingup_time == pytest.approx(1.5, abs=1e-12)
    assert c.velocity_cost == pytest.approx((k - 1) * 0.002 * (v @ v), rel=1e-12)
    assert c.tau_cost == pytest.approx(0.002 * np.sum((0.01 * np.arange(k - 1)) ** 2), rel=1e-12)
    assert c.tau_smoothness == pytest.approx(0.0, abs=1e-12)  # every step of u the same: no spread
    assert c.energy == pytest.approx(abs(v[1]) * 0.002 * np.sum(0.01 * np.arange(k - 1)), rel=1e-12)
    assert c.max_tau == pytest.approx(0.01 * (k - 1))


def test_the_success_test_is_the_leaderboards():
    """The last unbroken run of rows above the line, the last row not looked at; a run that ended early fails."""
    t = _rows()
    x, u = np.zeros((t.size, 4)), np.zeros((t.size, 2))
    up = np.full(t.size, 0.5)
    up[1000:1010] = 0.0  # a dip at 2 s: the time is after it
    c = lb.criteria(t, x, u, up, 0.5)
    assert c.success and c.swingup_time == pytest.approx(t[1010])
    down_at_the_end = up.copy()
    down_at_the_end[-2] = 0.0  # the last looked-at row is down: no success
    assert not lb.criteria(t, x, u, down_at_the_end, 0.5).success
    only_the_last_row = np.zeros(t.size)
    only_the_last_row[-1] = 0.5
    assert not lb.criteria(t, x, u, only_the_last_row, 0.5).success
    short = lb.criteria(t[:4000], x[:4000], u[:4000], up[:4000], 0.5)
    assert not short.success and short.swingup_time == math.inf and short.score == 0.0


def test_smoothness_is_the_spread_of_the_torque_steps():
    rng = np.random.default_rng(3)
    t = _rows(2000)
    u = np.zeros((t.size, 2))
    u[:, 0] = np.cumsum(rng.normal(0.0, 0.02, t.size))
    u[:, 1] = np.sin(t)
    c = lb.criteria(t, np.zeros((t.size, 4)), u, np.full(t.size, 1.0), 0.5)
    assert c.tau_smoothness == pytest.approx(np.std(np.diff(u[:, 0])) + np.std(np.diff(u[:, 1])), rel=1e-12)


def _lab_rhs(v, x, u):
    """The lab's published equations (dynamics.rst) with Ir, b, cf zero: M q'' = D u - C q' + G."""
    q1, q2, w1, w2 = x
    I1, I2, l1, m1, m2, r1, r2, g = (v[k] for k in ("I1", "I2", "l1", "m1", "m2", "r1", "r2", "g"))
    c2, s2 = math.cos(q2), math.sin(q2)
    M = np.array([[I1 + I2 + l1**2 * m2 + 2 * l1 * m2 * r2 * c2, I2 + l1 * m2 * r2 * c2], [I2 + l1 * m2 * r2 * c2, I2]])
    C = np.array([[-2 * w2 * l1 * m2 * r2 * s2, -w2 * l1 * m2 * r2 * s2], [w1 * l1 * m2 * r2 * s2, 0.0]])
    G = np.array([-g * m1 * r1 * math.sin(q1) - g * m2 * (l1 * math.sin(q1) + r2 * math.sin(q1 + q2)),
                  -g * m2 * r2 * math.sin(q1 + q2)])
    qdd = np.linalg.solve(M, u - C @ np.array([w1, w2]) + G)
    return np.array([w1, w2, qdd[0], qdd[1]])


def test_the_protocols_plant_and_step_are_the_labs():
    """run_protocol on the leaderboard's plant (skewpend's derivation, compiled, its RK4 with the torque held)
    against a NumPy RK4 of the lab's own equations of motion with the lab's own numbers (model 1.1), under a
    law that swings the pendulum hard for 1 s: the rows agree to 1e-9."""
    from skewpend.datasets import example_data

    lab = {}
    for line in example_data("dfki-design-C.1/model_1.1_parameters.yml").read_text().splitlines():
        key, value = line.split(":")
        lab[key.strip()] = float(value)

    def law(t, x):
        return np.array([0.0, 5.0 * math.sin(7.0 * t) - 0.5 * x[3]])

    protocol = lb.Protocol(t_final=1.0)
    run = lb.run_protocol(lb.dfki_model(), law, actuated=(2,), protocol=protocol)
    x = np.zeros(4)
    dt = protocol.dt
    for k in range(protocol.steps):
        assert np.allclose(run.x[k], x, rtol=0, atol=1e-9), k
        u = np.clip(law(k * dt, x), -6, 6)
        assert np.allclose(run.u[k], u, rtol=0, atol=1e-9)
        k1 = _lab_rhs(lab, x, u)
        k2 = _lab_rhs(lab, x + dt / 2 * k1, u)
        k3 = _lab_rhs(lab, x + dt / 2 * k2, u)
        k4 = _lab_rhs(lab, x + dt * k3, u)
        x = x + dt / 6 * (k1 + 2 * k2 + 2 * k3 + k4)
    assert np.ptp(run.x[:, 1]) > 1.0  # it did swing
    # the heights: the lab's forward kinematics, y = -l1 cos q1 - l2 cos(q1 + q2)
    y = -lab["l1"] * np.cos(run.x[:, 0]) - lab["l2"] * np.cos(run.x[:, 0] + run.x[:, 1])
    assert np.allclose(run.heights, y, rtol=0, atol=1e-12) and run.reach == pytest.approx(0.5)


def test_the_protocol_steps_as_the_optimiser_does():
    """One model optimised and scored (issue 52): every step of run_protocol is the optimiser's own RK4 step
    (trajopt's CasADi graph of the chain, the torque held) to rounding, on the planar and a skewed rig, the
    double pendulum's facade and its chain alike -- 0.2 s of a hard swing, each row from the run's previous one."""
    from skewpend.analysis.trajopt import casadi_dynamics

    def law(t, x):
        return np.array([0.0, 5.0 * math.sin(7.0 * t) - 0.5 * x[3]])

    protocol = lb.Protocol(t_final=0.2)
    for model in (lb.dfki_model(), lb.dfki_model(0.4).as_chain()):
        run = lb.run_protocol(model, law, actuated=(2,), protocol=protocol)
        _, _, step, _ = casadi_dynamics(model.as_chain(), (2,))
        ends = np.vstack([run.x[1:], run.final])
        for k in range(protocol.steps):
            u = run.u[k, 1:]
            want = np.array(step(run.x[k], u, u, protocol.dt)).ravel()
            assert np.allclose(ends[k], want, rtol=1e-13, atol=1e-13), k
        assert np.ptp(run.x[:, 1]) > 0.1


def test_run_protocol_clips_and_refuses():
    run = lb.run_protocol(lb.dfki_model(), lambda t, x: (100.0, 100.0), actuated=(2,), protocol=lb.Protocol(t_final=0.02))
    assert np.all(run.u[:, 0] == 0.0) and np.all(run.u[:, 1] == 6.0)
    with pytest.raises(ParameterError, match="must return 2 torques"):
        lb.run_protocol(lb.dfki_model(), lambda t, x: (1.0, 2.0, 3.0), protocol=lb.Protocol(t_final=0.02))
    bad = lb.run_protocol(lb.dfki_model(), lambda t, x: (0.0, math.nan), protocol=lb.Protocol(t_final=0.02))
    assert not bad.ok and "non-finite" in bad.message and bad.score == 0.0


def test_the_csv_round_trip(tmp_path):
    t = _rows(10)
    x = np.arange(40, dtype=float).reshape(10, 4) / 7
    u = np.arange(20, dtype=float).reshape(10, 2) / 3
    lb.write_csv(tmp_path / "r.csv", t, x, u)
    assert (tmp_path / "r.csv").read_text().splitlines()[0] == ",".join(lb.CSV_COLUMNS)
    t2, x2, u2 = lb.read_csv(tmp_path / "r.csv")
    assert np.array_equal(t, t2) and np.array_equal(x, x2) and np.array_equal(u, u2)
    (tmp_path / "bad.csv").write_text("time,pos1\n0,1\n")
    with pytest.raises(ParameterError, match="pos_meas1 is missing"):
        lb.read_csv(tmp_path / "bad.csv")


# -- skewpend's swing-ups, run and scored by the protocol ---------------------------------------------------------
@pytest.fixture(scope="module")
def acrobot():
    from skewpend.analysis.trajopt import optimal_swingup, tvlqr

    model = lb.dfki_model()
    traj = optimal_swingup(model, actuated=(2,))
    return model, traj, tvlqr(traj)


def test_the_optimal_acrobot_beats_the_published_best(acrobot):
    """The goal of issue 39: >= 0.70 with success (the best published, History SAC, 0.655); the optimiser's
    own prediction of the criteria agrees with the protocol's run (the tracking keeps it on the motion)."""
    model, traj, tracking = acrobot
    assert traj.ok, traj.message
    run = lb.run_protocol(model, tracking, actuated=(2,))
    c = run.criteria
    assert c.success and c.score >= 0.70
    assert c.energy == pytest.approx(traj.predicted["energy"], rel=0.02)
    assert c.velocity_cost == pytest.approx(traj.predicted["velocity_cost"], rel=0.02)
    assert c.tau_cost == pytest.approx(traj.predicted["tau_cost"], rel=0.02)
    assert np.all(np.abs(run.u[:, 1]) <= 6.0) and np.all(run.u[:, 0] == 0.0)
    # the end: held at the top, at rest
    assert np.allclose(run.x[-1], [math.pi, 0, 0, 0], atol=1e-6)


def test_the_acrobots_robustness_beats_the_published_best(acrobot):
    """The robustness goal of issue 39: the full board (722 runs, seed 0, the speeds from the positions) scores
    >= 0.80 (the best published, History SAC, 0.751); the nominal plant of every model list succeeds, and the
    controller with the measured speeds loses the speed-noise criterion (the observer is what carries it)."""
    from skewpend.analysis import robustness as rb

    _, _, tracking = acrobot
    r = rb.robustness(tracking, actuated=(2,), speeds="positions")
    assert r.simulations == 722 and r.score >= 0.80, r.criteria
    assert all(v[10] for v in r.model.values())
    measured = rb.robustness(tracking, actuated=(2,), speeds="measured",
                             settings=rb.RobustnessSettings(values=5, repetitions=4, perturbation_runs=2))
    assert measured.criteria["velocity_noise"] < r.criteria["velocity_noise"] == 1.0


def test_the_dfki_interface_is_the_same_law(acrobot):
    """get_control_output(x, t), the lab's controller call, gives the law's torques (their state order and
    angles are skewpend's: q2 relative, zero hanging)."""
    _, _, tracking = acrobot
    rng = np.random.default_rng(5)
    for t in (0.0, 0.5, 1.0, tracking.duration + 1.0):
        x = rng.normal(size=4)
        assert np.array_equal(tracking.get_control_output(x=x, t=t), tracking(t, x))


def test_the_tracking_corrects_a_perturbed_start(acrobot):
    """Start off the optimised motion (0.02 rad, 0.1 rad/s): the time-varying LQR still swings it up and holds it."""
    model, _, tracking = acrobot
    run = lb.run_protocol(model, tracking, actuated=(2,), x0=[0.02, -0.02, 0.1, 0.0])
    assert run.criteria.success


def test_bad_input_of_the_optimiser():
    from skewpend.analysis.trajopt import Cost, optimal_swingup

    with pytest.raises(ParameterError, match="weight energy must be a finite number >= 0"):
        Cost(energy=-1.0)
    with pytest.raises(ParameterError, match="at least one positive weight"):
        Cost(0, 0, 0, 0, 0)
    with pytest.raises(EquilibriumError, match="not controllable"):
        optimal_swingup(lb.dfki_model(math.pi / 2), actuated=(2,))  # the elbow's axis across: the shoulder decouples
    with pytest.raises(ParameterError, match="horizon must be"):
        optimal_swingup(lb.dfki_model(), horizon=(2.0, 1.0))
    short = optimal_swingup(lb.dfki_model(), actuated=(2,), umax=0.3, horizon=(0.3, 0.6), attempts=1)
    assert not short.ok and "no optimal swing-up" in short.message
    from skewpend.analysis.trajopt import tvlqr

    with pytest.raises(ParameterError, match="cannot track"):
        tvlqr(short)


@pytest.mark.parametrize("argv, text", [
    (["control", "leaderboard"], "give --robot acrobot or --robot pendubot"),
    (["control", "lqr", "--robot", "acrobot"], "--robot goes with 'control leaderboard'"),
    (["control", "swingup", "--robustness"], "--robustness goes with 'control leaderboard'"),
    (["control", "leaderboard", "--robot", "acrobot", "--m1", "2"], "--m1: control leaderboard runs the leaderboard's plant"),
    (["control", "leaderboard", "--robot", "acrobot", "--target", "up-up"], "--target goes with"),
    (["control", "leaderboard", "--robot", "acrobot", "--out", "r.nc"], "--out"),
    (["control", "leaderboard", "--robot", "tribot"], "tribot"),
])
def test_cli_leaderboard_bad_input(argv, text, tmp_path):
    from helpers import run_cli

    ran = run_cli(argv, cwd=tmp_path)
    assert ran.code == 2, ran.report()
    assert text in ran.err and len(ran.err.strip().splitlines()) == 1, ran.report()
    assert not list(tmp_path.iterdir())


def test_cli_leaderboard_writes_the_leaderboards_file(tmp_path_factory):
    """The command end to end (docs/guide/control.md's, run once per session as a reader runs it: the README
    test checks the same run, tests/helpers.py's SHARED_COMMANDS): exit 0, the score line, the CSV in the
    leaderboard's columns that the scorer reads back to the same score, the figure."""
    from helpers import shared_cli_run

    made = shared_cli_run(tmp_path_factory, "skewpend control leaderboard --robot acrobot --out acrobot.csv --plot acrobot.png")
    out, folder = made["output"].splitlines(), Path(made["dir"])
    assert made["returncode"] == 0, made["output"][-3000:]
    line = next(s for s in out if s.startswith("score (v2)"))
    shown = float(line.split()[2])
    t, x, u = lb.read_csv(folder / "acrobot.csv")
    from skewpend.numeric.kernels import model_kernel, model_vector

    model = lb.dfki_model()
    c = lb.criteria(t, x, u, lb.tip_heights(model_kernel(model), model_vector(model), x), 0.5)
    assert c.score == pytest.approx(shown, abs=1e-4) and shown >= 0.70
    assert (folder / "acrobot.png").stat().st_size > 10_000
    # the planar rig is compared with the published board; every duration is labelled (issue 51)
    assert "best published: 0.655 (History SAC)" in line
    optimised = next(s for s in out if s.startswith("optimised"))
    assert re.search(r"the motion takes [0-9.]+ s to the goal; solved in [0-9.]+ s \(4 seeded starts\)$", optimised)


def test_cli_leaderboard_at_a_skew_with_the_robustness_board(tmp_path):
    """The skewed rig (--alpha 30deg, the pendubot): the optimised swing-up succeeds by the protocol and stays
    up through the last second (the CSV's rows); the robustness board's six criteria and score are printed,
    each a fraction, the score their mean."""
    from helpers import run_cli

    ran = run_cli(["control", "leaderboard", "--robot", "pendubot", "--alpha", "30deg", "--robustness", "--out",
                   "run.csv"], cwd=tmp_path)
    assert ran.code == 0, ran.report()
    assert "alpha = 30 deg" in ran.out
    # like with like: the published boards are the planar rig's, named as not compared (issue 51)
    assert "best published" not in ran.out
    for start in ("score (v2)", "robustness score"):
        line = next(s for s in ran.out.splitlines() if s.startswith(start))
        assert "not compared: the published boards are the planar rig's (alpha = 0)" in line, line
    t, x, u = lb.read_csv(tmp_path / "run.csv")
    model = lb.dfki_model(math.radians(30))
    from skewpend.numeric.kernels import model_kernel, model_vector

    heights = lb.tip_heights(model_kernel(model), model_vector(model), x)
    c = lb.criteria(t, x, u, heights, 0.5)
    assert c.success and np.all(heights[t >= 9.0] > 0.45) and np.all(u[:, 1] == 0.0)
    rows = {}
    for line in ran.out.splitlines():
        for label in ("model errors", "speed noise", "torque noise", "torque response", "delay", "perturbations",
                      "robustness score"):
            if line.startswith(label + " "):
                rows[label] = float(line[len(label):].split()[0])
    assert len(rows) == 7 and all(0.0 <= v <= 1.0 for v in rows.values())
    assert rows["robustness score"] == pytest.approx(np.mean([v for k, v in rows.items() if k != "robustness score"]),
                                                     abs=6e-4)


def test_the_pendubot_beats_the_published_best():
    """The pendubot: the simulation score >= 0.70 with success (History SAC 0.682; issue 39's goal 0.72 is not
    reached, see docs/benchmarks.md), the robustness board >= 0.93 (AR-EAPO 0.913)."""
    from skewpend.analysis import robustness as rb
    from skewpend.analysis.trajopt import optimal_swingup, tvlqr

    model = lb.dfki_model()
    tracking = tvlqr(optimal_swingup(model, actuated=(1,)))
    run = lb.run_protocol(model, tracking, actuated=(1,))
    assert run.criteria.success and run.score >= 0.70 and np.all(run.u[:, 1] == 0.0)
    r = rb.robustness(tracking, actuated=(1,), speeds="positions")
    assert r.score >= 0.93, r.criteria


@pytest.mark.parametrize("signum, code", [(2, 130), (15, 143)])
def test_cli_leaderboard_stops_on_ctrl_c_and_sigterm(signum, code, tmp_path):
    """Ctrl-C or SIGTERM during the optimisation (CasADi building or IPOPT solving, in this process or in the
    forked workers) ends the command with 130 / 143, nothing written, no worker left behind; the hang guard:
    the build of the skewed problem is not interruptible (about 10-15 s on 2 cores), the exit comes at its end
    or sooner."""
    import signal
    import subprocess

    from helpers import signal_process

    argv = ["control", "leaderboard", "--robot", "pendubot", "--alpha", "30deg", "--umax", "5.5", "--out", "r.csv"]
    ran, seconds = signal_process(argv, tmp_path, after=6.0, signum=signal.Signals(signum))
    assert ran.code == code, ran.report()
    assert ran.err.strip().splitlines()[-1] in ("skewpend: interrupted", "skewpend: terminated")
    assert not list(tmp_path.iterdir()) and seconds < 60.0
    left = subprocess.run(["pgrep", "-f", " ".join(argv)], capture_output=True, text=True).stdout.split()
    assert not left, left
