"""Inputs that vary, LQR at any equilibrium, swing-up (issue 18).

Independent evidence: the acrobot's published model (Spong 1995) typed here and linearised by
SymPy at the top; the Riccati solution from the Hamiltonian matrix's stable eigenvectors, written
here; the simulated decay of a small perturbation against the slowest closed-loop eigenvalue; the
energy balance E - W with the inputs' work, and W against the work integrated from the inputs;
the decoupling at alpha = 90 deg, where one motor cannot reach the other joint.
"""

from __future__ import annotations

import math

import numpy as np
import pytest

import skewpend
from skewpend.analysis.control import controllability, linearization, lqr, swingup
from skewpend.errors import EquilibriumError, ParameterError
from skewpend.numeric.control import Controller


def thin(alpha=0.6, **kw):
    return skewpend.Parameters(a=1.0, b=0.8, m1=1.0, m2=0.7, alpha=alpha, g=9.81, **kw)


def test_acrobot_at_the_top_equals_spongs_published_model():
    """Spong, 'The swing up control problem for the Acrobot', IEEE Control Systems 15(1), 1995:
    d11 q1'' + d12 q2'' + h1 + phi1 = 0, d21 q1'' + d22 q2'' + h2 + phi2 = tau, with
    d11 = m1 lc1^2 + m2 (l1^2 + lc2^2 + 2 l1 lc2 cos q2) + I1 + I2, d12 = m2 (lc2^2 + l1 lc2 cos q2) + I2,
    d22 = m2 lc2^2 + I2, phi1 = (m1 lc1 + m2 l1) g cos q1 + phi2, phi2 = m2 lc2 g cos(q1 + q2),
    q1 measured from the horizontal (the top: q1 = pi/2, q2 = 0).  Thin rods: lc = l/2, I = m l^2/12.
    skewpend's phi is measured from hanging, with j down: q1 = phi + pi/2 ... up to the sense of
    rotation, which the comparison fixes by the map (q1, q2) = (pi/2 - (phi - pi), -psi)."""
    import sympy as sp

    l1, l2, m1, m2, g = 1.0, 0.8, 1.0, 0.7, 9.81
    lc1, lc2, I1, I2 = l1 / 2, l2 / 2, m1 * l1 ** 2 / 12, m2 * l2 ** 2 / 12
    q1, q2, u = sp.symbols("q1 q2 u")
    d11 = m1 * lc1 ** 2 + m2 * (l1 ** 2 + lc2 ** 2 + 2 * l1 * lc2 * sp.cos(q2)) + I1 + I2
    d12 = m2 * (lc2 ** 2 + l1 * lc2 * sp.cos(q2)) + I2
    d22 = m2 * lc2 ** 2 + I2
    phi2 = m2 * lc2 * g * sp.cos(q1 + q2)
    phi1 = (m1 * lc1 + m2 * l1) * g * sp.cos(q1) + phi2
    D = sp.Matrix([[d11, d12], [d12, d22]])
    acc = D.inv() * (sp.Matrix([0, u]) - sp.Matrix([phi1, phi2]))  # at rest h = 0
    top = {q1: sp.pi / 2, q2: 0, u: 0}
    dA = np.array([[float(sp.diff(acc[i], v).subs(top)) for v in (q1, q2)] for i in range(2)])
    dB = np.array([float(sp.diff(acc[i], u).subs(top)) for i in range(2)])
    lin = linearization(thin(alpha=0.0), "up-up", "acrobot")
    # skewpend (phi, psi) -> Spong (q1, q2): q1 = 3 pi/2 - phi, q2 = -psi (both senses reversed)
    S = np.diag([-1.0, -1.0])
    A_spong = S @ dA @ S  # d(accelerations)/d(angles) in skewpend's coordinates
    B_spong = S @ dB      # the elbow torque acts in Spong's sense: reversed
    assert np.allclose(lin.A[2:, :2], A_spong, rtol=1e-12, atol=1e-12)
    assert np.allclose(lin.B[2:, 0], -B_spong, rtol=1e-12, atol=1e-12) or np.allclose(lin.B[2:, 0], B_spong, rtol=1e-12)
    assert np.allclose(lin.A[:2, 2:], np.eye(2)) and np.allclose(lin.A[2:, 2:], 0)


def _riccati_by_hamiltonian(A, B, Q, R):
    """P from the stable invariant subspace of the Hamiltonian matrix (written here, not SciPy's ARE)."""
    Ri = np.linalg.inv(R)
    H = np.block([[A, -B @ Ri @ B.T], [-Q, -A.T]])
    w, V = np.linalg.eig(H)
    stable = V[:, w.real < 0]
    X, Y = stable[:4], stable[4:]
    return np.real(Y @ np.linalg.inv(X))


@pytest.mark.parametrize("actuated", ["both", "acrobot", "pendubot"])
@pytest.mark.parametrize("alpha", [0.0, 0.6, 1.2])
def test_lqr_gain_equals_the_hamiltonian_solution(actuated, alpha):
    Q = np.diag([10.0, 10.0, 1.0, 1.0])
    d = lqr(thin(alpha=alpha), "up-up", actuated, Q=Q, estimate=False)
    lin = d.linearization
    P = _riccati_by_hamiltonian(lin.A, lin.B, Q, d.R)
    K = np.linalg.solve(d.R, lin.B.T @ P)
    assert np.allclose(d.P, P, rtol=1e-8, atol=1e-8 * np.abs(P).max())
    assert np.allclose(d.K, K, rtol=1e-8, atol=1e-8 * np.abs(K).max())
    assert np.all(d.eigenvalues.real < 0)


def test_a_small_perturbation_decays_at_the_slowest_closed_loop_rate():
    p = thin(alpha=0.6)
    d = lqr(p, "up-up", "both", estimate=False)
    slowest = d.eigenvalues.real.max()
    x0 = d.linearization.target + np.array([1e-6, -1e-6, 0.0, 0.0])
    tr = skewpend.simulate(p, x0, 8.0, dt_out=0.05, controller=d.controller(), rtol=1e-13, atol=1e-15)
    dev = np.linalg.norm(np.c_[(tr.y[:, :2] - d.linearization.target[:2] + np.pi) % (2 * np.pi) - np.pi, tr.y[:, 2:]], axis=1)
    late = tr.t > 3.0  # after the faster modes have died out
    slope = np.polyfit(tr.t[late], np.log(dev[late]), 1)[0]
    assert slope == pytest.approx(slowest, rel=0.03)


@pytest.mark.parametrize("kind", ["feedback", "swingup", "table"])
def test_energy_balance_includes_the_inputs_work(kind):
    p = thin(alpha=0.6, c1=0.05)
    if kind == "table":
        ctl = Controller.table([0, 1, 2, 3], [[0, 0], [2, -1], [-1, 1], [0, 0.5]])
        y0 = (0.3, -0.2, 0.0, 0.0)
    elif kind == "feedback":
        ctl = Controller.feedback(np.array([[20.0, 2.0, 5.0, 1.0], [1.0, 10.0, 0.5, 2.0]]), [0, 0, 0, 0], umax=3.0)
        y0 = (0.8, -0.5, 0.0, 0.0)
    else:
        d = lqr(p, "up-up", "both", estimate=False)
        ctl = Controller.swingup(2.0, d.linearization.equilibrium.potential, d.gain, d.linearization.target, d.P, 0.1,
                                 elbow_gains=(20, 4), umax=8.0)
        y0 = (0.05, 0.0, 0.0, 0.0)
    tr = skewpend.simulate(p, y0, 3.0, dt_out=0.001, controller=ctl, rtol=1e-12, atol=1e-12)
    assert tr.ok and tr.energy_drift < 1e-8
    # W against the work integrated here: the inputs' and the damping's power, by the trapezoid rule
    u = tr.inputs()
    power = np.sum(u * tr.y[:, 2:], axis=1) - 0.05 * tr.y[:, 2] ** 2
    W = np.concatenate([[0.0], np.cumsum(0.5 * (power[1:] + power[:-1]) * np.diff(tr.t))])
    # the trapezoid rule on a 1 ms grid: O(dt^2) where the power is smooth; where the input jumps
    # (the swing-up switching to the LQR, on and off at the region's edge) each jump of the power
    # costs up to |jump| dt / 2, so that law gets ten times the room
    room = 2e-3 if kind == "swingup" else 2e-4
    assert np.max(np.abs(W - tr.work)) < room * max(1.0, np.abs(tr.work).max())
    assert np.any(np.abs(u) > 0.1)


def test_saturation_and_actuation_are_applied():
    K = np.array([[100.0, 0, 0, 0], [0, 100.0, 0, 0]])
    ctl = Controller.feedback(K, [0, 0, 0, 0], actuated="acrobot", umax=(1.0, 2.5))
    tr = skewpend.simulate(thin(), (0.5, 0.5, 0, 0), 0.5, dt_out=0.01, controller=ctl)
    u = tr.inputs()
    assert np.all(u[:, 0] == 0) and np.max(np.abs(u[:, 1])) == pytest.approx(2.5)


def test_starts_inside_the_estimate_are_captured():
    p = thin(alpha=0.6)
    d = lqr(p, "up-up", "both", umax=10.0)
    assert 0 < d.rho < math.inf
    rng = np.random.default_rng(3)
    L = np.linalg.cholesky(d.P)
    ctl = d.controller()
    for _ in range(12):
        z = rng.normal(size=4)
        z *= 0.999 * math.sqrt(d.rho) * rng.uniform() ** 0.25 / np.linalg.norm(z)
        dx = np.linalg.solve(L.T, z)
        assert d.inside(d.linearization.target + dx)
        tr = skewpend.simulate(p, d.linearization.target + dx, 10.0, controller=ctl)
        end = tr.y[-1]
        err = np.r_[(end[:2] - d.linearization.target[:2] + np.pi) % (2 * np.pi) - np.pi, end[2:]]
        assert np.max(np.abs(err)) < 1e-6


@pytest.mark.parametrize("alpha_deg", [0, 30, 60])
def test_swingup_reaches_and_holds_the_top(alpha_deg):
    s = swingup(thin(alpha=math.radians(alpha_deg)), "up-up", "both", umax=10.0, t_end=15.0)
    assert s.captured, s.message
    assert s.capture_time < 10.0
    assert np.max(np.abs(s.trajectory.inputs())) <= 10.0 + 1e-12
    end = s.trajectory.y[-1]
    wrap = lambda x: (x + math.pi) % (2 * math.pi) - math.pi
    assert abs(wrap(end[0] - math.pi)) < 1e-3 and abs(wrap(end[1])) < 1e-3 and np.max(np.abs(end[2:])) < 1e-3
    assert s.trajectory.energy_drift < 1e-8


def test_one_motor_cannot_balance_at_90_degrees():
    """At alpha = 90 deg the linearisation about the top decouples (M0 and K0 diagonal): a motor at
    one joint cannot reach the other, so the acrobot and the pendubot lose controllability there."""
    for actuated in ("acrobot", "pendubot"):
        lin = linearization(thin(alpha=math.pi / 2), "up-up", actuated)
        c = controllability(lin.A, lin.B)
        assert c["rank"] == 2 and c["distance"] < 1e-12
        assert controllability(*_pair(thin(alpha=1.2), actuated))["rank"] == 4
        with pytest.raises(EquilibriumError, match="not controllable"):
            lqr(thin(alpha=math.pi / 2), "up-up", actuated, estimate=False)
    both = linearization(thin(alpha=math.pi / 2), "up-up", "both")
    assert controllability(both.A, both.B)["rank"] == 4


def _pair(p, actuated):
    lin = linearization(p, "up-up", actuated)
    return lin.A, lin.B


def test_refusals():
    p = thin()
    with pytest.raises(ParameterError, match="actuated"):
        lqr(p, "up-up", "elbow")
    with pytest.raises(ParameterError, match="Q must be"):
        lqr(p, "up-up", "both", Q=-np.eye(4))
    with pytest.raises(ParameterError, match="R must be"):
        lqr(p, "up-up", "acrobot", R=np.zeros((1, 1)))
    with pytest.raises(EquilibriumError):
        lqr(p, (0.7, 0.2))
    with pytest.raises(ParameterError, match="dop853 or rk4"):
        skewpend.simulate(p, (0.1, 0, 0, 0), 1.0, method="gauss", controller=Controller.table([0], [[0, 0]]))
    with pytest.raises(ParameterError, match="controller must be"):
        skewpend.simulate(p, (0.1, 0, 0, 0), 1.0, controller="lqr")
    with pytest.raises(ParameterError, match="increase"):
        Controller.table([0, 0], [[0, 0], [1, 1]])
    with pytest.raises(ParameterError, match="umax"):
        Controller.feedback(np.zeros((2, 4)), [0, 0, 0, 0], umax=-1)


def test_cli_control(tmp_path):
    from helpers import run_cli

    ran = run_cli(["control", "lqr", "--umax", "10", "--q", "10,10,1,1"], cwd=tmp_path)
    assert ran.code == 0 and "closed loop" in ran.out and "controllable (rank 4" in ran.out, ran.report()
    ran = run_cli(["control", "swingup", "--alpha", "30deg", "--t-end", "8", "--out", "s.csv", "--plot", "s.png"],
                  cwd=tmp_path)
    assert ran.code == 0 and "captured by the LQR" in ran.out, ran.report()
    data = np.loadtxt(tmp_path / "s.csv", delimiter=",", skiprows=1)
    assert data.shape[1] == 9 and np.max(np.abs(data[:, 7:])) <= 10.0 + 1e-12  # t, state, E, W, u1, u2
    # not captured within the time: exit 1, the reason in one line
    ran = run_cli(["control", "swingup", "--t-end", "0.5"], cwd=tmp_path)
    assert ran.code == 1 and "not captured" in ran.err, ran.report()


@pytest.mark.parametrize("argv, text", [
    (["control"], "lqr, swingup, roa or leaderboard"),
    (["control", "balance"], "action"),
    (["control", "lqr", "--actuated", "elbow"], "--actuated"),
    (["control", "lqr", "--actuated", "acrobot", "--alpha", "90deg"], "not controllable"),
    (["control", "lqr", "--t-end", "3"], "--t-end"),
    (["control", "lqr", "--q", "1,1,1"], "--q"),
    (["control", "lqr", "--q", "1,1,-1,1"], "--q"),
    (["control", "lqr", "--r", "1,1", "--actuated", "acrobot"], "--r"),
    (["control", "lqr", "--r", "0,1"], "--r"),
    (["control", "lqr", "--umax", "0"], "--umax"),
    (["control", "lqr", "--target", "40deg,10deg"], "not an equilibrium"),
    (["control", "swingup", "--elbow-gains", "1"], "--elbow-gains"),
    (["control", "swingup", "--out", "s.txt"], "--out"),
    (["control", "swingup", "--animate", "s.avi"], "--animate"),
    (["control", "lqr", "--a", "sym"], "numeric"),
])
def test_cli_control_bad_input(argv, text, tmp_path):
    from helpers import run_cli

    ran = run_cli(argv, cwd=tmp_path)
    assert ran.code == 2, ran.report()
    assert text in ran.err and len(ran.err.strip().splitlines()) == 1, ran.report()
    assert not any(tmp_path.iterdir())


# -- a law written in Python: the slow path -------------------------------------------------------------
def _python_lqr(design):
    K, xs = design.gain, design.linearization.target

    def law(t, x):
        dx = x - xs
        dx[:2] = (dx[:2] + np.pi) % (2 * np.pi) - np.pi
        return -K @ dx

    return law


def test_a_python_law_is_the_built_in_law():
    """The same LQR written in Python (Controller.function) and built in: the same motion to the
    integrators' tolerance (the Python run carries the time as a sixth state, so its steps differ)."""
    from skewpend.numeric.control import Controller

    p = thin(math.radians(30))
    design = skewpend.lqr(p, "up-up", "both", umax=10.0)
    y0 = design.linearization.target + np.array([0.4, -0.3, 0.2, 0.0])
    kw = dict(dt_out=0.01, rtol=1e-11, atol=1e-11)
    a = skewpend.simulate(p, y0, 4.0, controller=Controller.function(_python_lqr(design), umax=10.0), **kw)
    b = skewpend.simulate(p, y0, 4.0, controller=design.controller(), **kw)
    assert a.ok and b.ok and np.array_equal(a.t, b.t)
    assert np.abs(a.y - b.y).max() < 1e-7
    assert np.abs(a.inputs() - b.inputs()).max() < 1e-5 and np.abs(a.inputs()).max() == pytest.approx(10.0)
    assert a.energy_drift < 1e-9  # E - W conserved: W includes the Python law's work


def test_a_python_law_s_errors_reach_the_caller():
    from skewpend.numeric.control import Controller

    p = thin(0.3)

    def broken(t, x):
        if t > 0.5:
            raise ZeroDivisionError("the law failed at t = %.3f" % t)
        return (0.0, 0.0)

    with pytest.raises(ZeroDivisionError, match="the law failed"):
        skewpend.simulate(p, (0.3, 0.1, 0, 0), 2.0, controller=Controller.function(broken))
    with pytest.raises(ParameterError, match="two torques"):
        skewpend.simulate(p, (0.3, 0.1, 0, 0), 2.0, controller=Controller.function(lambda t, x: (1.0, 2.0, 3.0)))
    with pytest.raises(ParameterError, match="callable"):
        Controller.function(3.0)

    def interrupted(t, x):
        raise KeyboardInterrupt

    with pytest.raises(KeyboardInterrupt):
        skewpend.simulate(p, (0.3, 0.1, 0, 0), 2.0, controller=Controller.function(interrupted))
    # a non-finite torque stops the run with its status, no NaN rows
    tr = skewpend.simulate(p, (0.3, 0.1, 0, 0), 2.0, controller=Controller.function(lambda t, x: (np.nan, 0.0)))
    assert not tr.ok and np.all(np.isfinite(tr.y))


@pytest.mark.parametrize("dt, k, fps", [(0.01, 4, 25.0), (0.02, 2, 25.0), (0.04, 1, 25.0), (0.05, 1, 20.0), (0.03, 2, 50 / 3)])
def test_the_swingup_animation_shows_at_most_25_frames_a_second(dt, k, fps):
    """`control swingup --animate` renders the run's rows (every 0.01 s) at most 25 per second: a GIF
    cannot show 100 (browsers draw delays under 2/100 s as 1/10 s), and four times the frames cost four
    times the rendering. Every k-th row, the frame times exactly k*dt apart, as animate() requires."""
    from skewpend.cli.control import _frames
    from skewpend.views.animation import check_frame_times

    tr = skewpend.simulate(thin(), (0.3, -0.2, 0.0, 0.0), 1.2, dt_out=dt)
    shown, got = _frames(tr)
    assert got == pytest.approx(fps, rel=1e-12)
    np.testing.assert_array_equal(shown.y, tr.y[::k])
    np.testing.assert_array_equal(shown.energy, tr.energy[::k])
    check_frame_times(shown.t, got, 1.0)
