"""The RealAIGym robustness board (v2) in skewpend: the disturbed protocol loop against a NumPy loop that
follows the lab's simulator step by step (simulation.py) on the lab's own plant equations (plant.py: the
rotor, damping and Coulomb friction included, negative values too); the varied models against the numbers
the lab published with its results (benchmark_parameters.yml); the perturbation profiles' law; the success
test; the compiled tracking law against its Python form; and a small evaluation end to end."""

from __future__ import annotations

import math

import numpy as np
import pytest

import skewpend
from skewpend.analysis import leaderboard as lb
from skewpend.analysis import robustness as rb
from skewpend.errors import ParameterError


def _lab_rhs(v, x, u, b=(0.0, 0.0), cf=(0.0, 0.0), Ir=0.0, gr=6.0):
    """The lab's plant (plant.py, "UnderactuatedLecture"): M q'' = B u - C q' + G - F, the rotor in M."""
    q1, q2, w1, w2 = x
    I1, I2, l1, m1, m2, r1, r2, g = (v[k] for k in ("I1", "I2", "l1", "m1", "m2", "r1", "r2", "g"))
    c2, s2 = math.cos(q2), math.sin(q2)
    M = np.array([[I1 + I2 + m2 * l1**2 + 2 * m2 * l1 * r2 * c2 + gr**2 * Ir + Ir, I2 + m2 * l1 * r2 * c2 - gr * Ir],
                  [I2 + m2 * l1 * r2 * c2 - gr * Ir, I2 + gr**2 * Ir]])
    C = np.array([[-2 * m2 * l1 * r2 * s2 * w2, -m2 * l1 * r2 * s2 * w2], [m2 * l1 * r2 * s2 * w1, 0.0]])
    G = np.array([-m1 * g * r1 * math.sin(q1) - m2 * g * (l1 * math.sin(q1) + r2 * math.sin(q1 + q2)),
                  -m2 * g * r2 * math.sin(q1 + q2)])
    F = np.array([b[i] * w + cf[i] * math.atan(100 * w) for i, w in enumerate((w1, w2))])
    qdd = np.linalg.solve(M, u - C @ np.array([w1, w2]) + G - F)
    return np.array([w1, w2, qdd[0], qdd[1]])


def _lab_loop(v, law, steps, dt, *, delay=0, resp=1.0, vnoise=None, unoise=None, pert=None, actuated=1, **plant):
    """The lab's Simulator.controller_step, in its order: the delayed state, noise on the speeds, the law, the
    response to the last applied torque, torque noise, the clip (the passive joint to 0), the perturbation
    (the passive joint's dropped by the plant), RK4 with the torque held."""
    xs, us = [np.zeros(4)], []
    last = np.zeros(2)
    mask = np.zeros(2)
    mask[actuated] = 1.0
    for k in range(steps):
        seen = xs[max(k - delay, 0)].copy()
        if vnoise is not None:
            seen[2:] += vnoise[k]
        u = np.asarray(law(k * dt, seen), dtype=float) * mask
        u = last + resp * (u - last)
        if unoise is not None:
            u = u + unoise[k] * mask
        u = np.clip(u, -6 * mask, 6 * mask)
        if pert is not None:
            u = u + pert[k] * mask
        last = u
        us.append(u)
        x = xs[-1]
        k1 = _lab_rhs(v, x, u, **plant)
        k2 = _lab_rhs(v, x + dt / 2 * k1, u, **plant)
        k3 = _lab_rhs(v, x + dt / 2 * k2, u, **plant)
        k4 = _lab_rhs(v, x + dt * k3, u, **plant)
        xs.append(x + dt / 6 * (k1 + 2 * k2 + 2 * k3 + k4))
    return np.array(xs), np.array(us)


def _law(t, x):
    return np.array([0.0, 5.0 * math.sin(7.0 * t) - 0.5 * x[3] - 0.3 * x[1]])


@pytest.mark.parametrize("name, value, plant", [
    ("b1", -0.08, {"b": (-0.08, 0.0)}),
    ("cf2", -0.2, {"cf": (0.0, -0.2)}),
    ("cf1", 0.14, {"cf": (0.14, 0.0)}),
    ("Ir", 1e-4, {"Ir": 1e-4}),
])
def test_varied_plants_are_the_labs(name, value, plant):
    """Each varied plant of the model criterion (negative damping and friction past the model's checks, the
    rotor with the lab's gear ratio) against the lab's plant equations: the rows agree to 1e-9 over 1 s."""
    nominal = lb.lab_values()
    (_, v, over), = [row for row in rb.model_variations(name, nominal) if row[0] == pytest.approx(value)]
    protocol = lb.Protocol(t_final=1.0)
    run = lb.run_protocol(lb.dfki_model(), _law, actuated=(2,), protocol=protocol, plant=lb.dfki_model(0.0, v),
                          plant_values=over)
    xs, us = _lab_loop(nominal, _law, protocol.steps, protocol.dt, **plant)
    assert np.ptp(run.x[:, 1]) > 1.0
    assert np.allclose(run.x, xs[:-1], rtol=0, atol=1e-9) and np.allclose(run.final, xs[-1], rtol=0, atol=1e-9)
    assert np.allclose(run.u, us, rtol=0, atol=1e-12)


def test_the_disturbed_loop_is_the_labs():
    """Delay, speed noise, torque response, torque noise and perturbations together, the noise drawn as
    run_protocol draws it (one generator of the seed: the speeds' then the torques'), against the lab's order
    of operations: the rows agree to 1e-9."""
    protocol = lb.Protocol(t_final=1.0)
    steps = protocol.steps
    pert = np.zeros((steps, 2))
    pert[:, 1] = 2.0 * np.exp(-((np.arange(steps) * protocol.dt - 0.5) ** 2) / (2 * 0.05**2))
    pert[:, 0] = 1.0  # on the passive joint: dropped
    d = lb.Disturbance(delay=7, velocity_noise=0.2, torque_noise=0.3, responsiveness=1.6, perturbation=pert, seed=11)
    run = lb.run_protocol(lb.dfki_model(), _law, actuated=(2,), protocol=protocol, disturbance=d)
    rng = np.random.default_rng(11)
    vnoise, unoise = rng.normal(0, 0.2, (steps, 2)), rng.normal(0, 0.3, (steps, 2))
    xs, us = _lab_loop(lb.lab_values(), _law, steps, protocol.dt, delay=7, resp=1.6, vnoise=vnoise, unoise=unoise,
                       pert=pert)
    assert np.allclose(run.x, xs[:-1], rtol=0, atol=1e-9) and np.allclose(run.u, us, rtol=0, atol=1e-9)
    assert np.all(run.u[:, 0] == 0.0)
    # the perturbation comes after the clip; the response follows the applied torque from 0
    short = lb.Protocol(t_final=0.01)
    hard = lb.run_protocol(lb.dfki_model(), lambda t, x: (0.0, 100.0), protocol=short,
                           disturbance=lb.Disturbance(perturbation=np.ones((short.steps, 2))))
    assert np.all(hard.u[:, 1] == 7.0) and np.all(hard.u[:, 0] == 0.0)
    slow = lb.run_protocol(lb.dfki_model(), lambda t, x: (0.0, 4.0), protocol=short,
                           disturbance=lb.Disturbance(responsiveness=0.5))
    assert np.allclose(slow.u[:4, 1], [2.0, 3.0, 3.5, 3.75], rtol=0, atol=1e-15)
    with pytest.raises(ParameterError, match="delay must be a whole number"):
        lb.Disturbance(delay=0.5)
    with pytest.raises(ParameterError, match="responsiveness must be a positive"):
        lb.Disturbance(responsiveness=0.0)
    with pytest.raises(ParameterError, match="perturbation must be finite torques of shape"):
        lb.run_protocol(lb.dfki_model(), _law, protocol=short, disturbance=lb.Disturbance(perturbation=np.ones(3)))


def test_the_observer_is_the_same_in_the_labs_loop():
    """SpeedObserver (the DFKI interface's observer, for the lab's Simulator) in the NumPy loop of the lab's
    order of operations, with a delay and speed noise, gives run_protocol's speeds="positions" rows to 1e-9."""
    from skewpend.analysis.trajopt import SpeedObserver

    protocol = lb.Protocol(t_final=1.0)
    steps = protocol.steps
    d = lb.Disturbance(delay=5, velocity_noise=0.3, seed=8)
    run = lb.run_protocol(lb.dfki_model(), _law, actuated=(2,), protocol=protocol, disturbance=d, speeds="positions")
    vnoise = np.random.default_rng(8).normal(0, 0.3, (steps, 2))
    observer = SpeedObserver(_law, protocol.dt)
    xs, us = _lab_loop(lb.lab_values(), lambda t, x: observer.get_control_output(x, t), steps, protocol.dt, delay=5,
                       vnoise=vnoise)
    assert np.allclose(run.x, xs[:-1], rtol=0, atol=1e-9) and np.allclose(run.u, us, rtol=0, atol=1e-9)
    assert np.ptp(run.x[:, 1]) > 1.0
    observer.reset()  # forgets the positions: the first call takes the given speeds
    x = np.array([0.1, 0.2, 0.7, -0.4])
    assert np.array_equal(observer.get_control_output(x, 0.3), _law(0.3, x))


def test_the_speed_observer_differentiates_the_positions():
    """speeds="positions": the law sees second-order backward differences of the positions (exact for a
    quadratic motion), whatever noise the measured speeds carry."""
    seen = []

    def law(t, x):
        seen.append(np.array(x))
        return np.zeros(2)

    protocol = lb.Protocol(t_final=0.2)
    run = lb.run_protocol(lb.dfki_model(), law, actuated=(2,), protocol=protocol, speeds="positions",
                          disturbance=lb.Disturbance(velocity_noise=0.5, seed=2))
    seen = np.array(seen)
    q = run.x[:, :2]
    dt = protocol.dt
    expect = (3 * q[2:] - 4 * q[1:-1] + q[:-2]) / (2 * dt)
    assert np.allclose(seen[2:, 2:], expect, rtol=0, atol=1e-9) and np.allclose(seen[:, :2], q, rtol=0, atol=0)
    assert np.allclose(seen[1, 2:], (q[1] - q[0]) / dt)
    # free fall from hanging at rest stays at rest: the differences are zero, the noise is not seen
    assert np.max(np.abs(seen[1:, 2:])) < 1e-12
    with pytest.raises(ParameterError, match="speeds must be"):
        lb.run_protocol(lb.dfki_model(), law, protocol=protocol, speeds="filtered")


def test_the_varied_models_are_the_published_lists():
    """model_variations against the lists the lab published with its results
    (real_ai_gym_leaderboard, data/acrobot/robustness_v2/*/benchmark_parameters.yml)."""
    nominal = lb.lab_values()
    published = {"I1": (0.023915399693634834, 0.039858999489391395), "I2": (0.038152386096054425, 0.06358731016009071),
                 "m1r1": (0.07851903453465406, 0.13086505755775676), "m2": (0.4691757925630828, 0.7819596542718046),
                 "m2r2": (0.1199649914324769, 0.19994165238746148), "Ir": (0.0, 1.0e-4), "b1": (-0.1, 0.1),
                 "cf2": (-0.2, 0.2)}
    for name, (first, last) in published.items():
        rows = rb.model_variations(name, nominal)
        assert len(rows) == 21
        assert rows[0][0] == pytest.approx(first, rel=1e-12, abs=1e-15)
        assert rows[-1][0] == pytest.approx(last, rel=1e-12)
    # m1 r1 by r1 at fixed m1; m2 by m2 alone; the damping's sign past the model's checks
    _, v, over = rb.model_variations("m1r1", nominal)[0]
    assert v["m1"] == nominal["m1"] and v["r1"] * v["m1"] == pytest.approx(0.07851903453465406)
    _, v, over = rb.model_variations("m2", nominal)[-1]
    assert v["r2"] == nominal["r2"] and v["m2"] == pytest.approx(0.7819596542718046)
    _, v, over = rb.model_variations("b1", nominal)[0]
    assert over == {"c1": -0.1} and v["b1"] == 0.1
    with pytest.raises(ParameterError, match="varies"):
        rb.model_variations("m1", nominal)


def test_perturbation_profiles_follow_the_labs_law():
    rng = np.random.default_rng(5)
    dt, steps = 0.002, 5000
    t = np.arange(steps) * dt
    for _ in range(20):
        prof = rb.perturbation_profile(rng, steps, dt, 2)
        assert prof.shape == (steps, 2)
        peaks = []
        for j in range(2):
            y = prof[:, j]
            idx = [i for i in range(1, steps - 1) if abs(y[i]) >= abs(y[i - 1]) and abs(y[i]) > abs(y[i + 1])
                   and abs(y[i]) > 0.3]
            assert len(idx) == 3
            assert all(0.5 - 1e-3 <= abs(y[i]) <= 5.0 + 1e-3 for i in idx)
            peaks += [t[i] for i in idx]
        peaks = np.sort(peaks)
        assert peaks[0] >= 1.0 - dt and peaks[-1] <= 9.0 + dt and np.all(np.diff(peaks) >= 1.0 - 2 * dt)
    with pytest.raises(ParameterError, match="do not fit"):
        rb.perturbation_profile(rng, 1000, dt, 2)


def test_at_goal_wraps_as_the_lab():
    assert rb.at_goal([math.pi + 0.3, -0.3, 0.9, -0.9])
    assert rb.at_goal([-math.pi + 0.3, 2 * math.pi - 0.3, 0.0, 0.0])  # q1 in [0, 2 pi), q2 in [-pi, pi)
    assert rb.at_goal([3 * math.pi, 0.0, 0.0, 0.0])
    assert not rb.at_goal([math.pi + 0.36, 0.0, 0.0, 0.0])
    assert not rb.at_goal([math.pi, 0.0, 1.0, 0.0])  # strict
    assert not rb.at_goal([0.0, 0.0, 0.0, 0.0])


@pytest.fixture(scope="module")
def acrobot_tracking():
    from skewpend.analysis.trajopt import optimal_swingup, tvlqr

    return tvlqr(optimal_swingup(lb.dfki_model(), actuated=(2,), knots=100))


def test_the_compiled_tracking_is_the_python_law(acrobot_tracking):
    """Tracking.controller() in simulate: the inputs at the rows equal the Python law's to 1e-12 (the same
    samples, blend and goal LQR), at rows between the samples too, and the run ends upright."""
    trk = acrobot_tracking
    model = lb.dfki_model()
    run = skewpend.simulate(model, t_end=trk.duration + 2.0, y0=(0, 0, 0, 0), controller=trk.controller(),
                            dt_out=0.0013)
    python = np.array([trk(t, x) for t, x in zip(run.t, run.y[:, :4])])
    assert np.allclose(run.inputs(), python, rtol=0, atol=1e-12)
    assert np.max(np.abs(python[:, 1])) > 1.0 and np.all(python[:, 0] == 0.0)
    assert rb.at_goal(run.y[-1, :4])
    with pytest.raises(ParameterError, match="states must have shape"):
        skewpend.Controller.tracking(0.002, np.zeros((3, 3)), np.zeros((3, 2)), np.zeros((3, 2, 4)), np.zeros((2, 4)),
                                     np.zeros(4))
    with pytest.raises(ParameterError, match="dt must be a positive"):
        skewpend.Controller.tracking(0.0, np.zeros((3, 4)), np.zeros((3, 2)), np.zeros((3, 2, 4)), np.zeros((2, 4)),
                                     np.zeros(4))


def test_a_small_evaluation_end_to_end(acrobot_tracking):
    """robustness() with 3 values per quantity, 2 repetitions, 4 perturbations: the counts, the criteria as
    fractions of the runs, the nominal runs succeed (the middle value of each model list is the nominal plant),
    and the same seed gives the same result."""
    small = rb.RobustnessSettings(values=3, repetitions=2, perturbation_runs=4)
    r = rb.robustness(acrobot_tracking, actuated=(2,), settings=small, speeds="positions", seed=4)
    assert r.simulations == 10 * 3 + 2 * 3 * 2 + 2 * 3 + 4
    assert set(r.criteria) == set(rb.CRITERIA) and all(0.0 <= v <= 1.0 for v in r.criteria.values())
    assert all(v[1] for v in r.model.values())  # the nominal plant
    assert r.runs["velocity_noise"][0].all() and r.runs["delay"][0] and r.runs["torque_response"][1]
    assert r.criteria["model"] == pytest.approx(r.runs["model"].mean())
    assert r.score == pytest.approx(np.mean(list(r.criteria.values())))
    again = rb.robustness(acrobot_tracking, actuated=(2,), settings=small, speeds="positions", seed=4)
    assert again.criteria == r.criteria
