"""Control under attack (issue 29): nested Python laws, Ctrl-C in a slow law, absurd targets,
a certified region estimate, infeasible runs refused before any work, arguments of every kind."""

from __future__ import annotations

import math
import os
import re
import signal
import time

import numpy as np
import pytest

import skewpend
from skewpend.errors import ParameterError
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
def test_ctrl_c_stops_a_slow_python_law_at_its_next_call(ref):
    """A law of 2 ms a call: the first compiled call alone would run it some 26000 times (2000 steps
    of 13 stages, about a minute); Ctrl-C, arriving while the run is inside the law, stops it at the
    law's next call -- counted in calls of the law, not in seconds (issue 36: no absolute times)."""
    calls = []

    def slow(t, x):
        calls.append(t)
        if len(calls) == 3:  # inside the law, as a user's Ctrl-C during a slow law arrives
            os.kill(os.getpid(), signal.SIGINT)
        time.sleep(0.002)
        return (0.0, 0.0)

    with pytest.raises(KeyboardInterrupt):
        skewpend.simulate(ref, (0.5, 0.0, 0, 0), 1000.0, controller=Controller.function(slow))
    # the signal is recorded during the third call; the fourth is refused before the law runs
    assert len(calls) == 3, f"the law ran {len(calls) - 3} times after Ctrl-C"
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


# -- item 4: the region estimate is certified ----------------------------------------------------------------------
def dfki_rig():
    """The DFKI double pendulum (design C.0, identified model h1.0: Wiebe et al., IEEE RAM 31(2),
    2024; dfki-ric-underactuated-lab/double_pendulum): planar, inertias about the joints turned
    into inertias about the centres of mass; the rotor inertia, friction and damping left out, as
    the lab's own LQR examples do."""
    m1, m2, l1, l2, r1, r2 = 0.5476215952387185, 0.5978621372377623, 0.2, 0.3, 0.2, 0.275
    I1, I2 = 0.024210710672023246 - m1 * r1 ** 2, 0.053450262258304355 - m2 * r2 ** 2
    return skewpend.Parameters(a=l1, b=l2, m1=m1, m2=m2, alpha=0.0, g=9.81, com1=(0, r1, 0), com2=(0, r2, 0),
                               inertia1=np.diag([I1, 0, I1]).tolist(), inertia2=np.diag([I2, 0, I2]).tolist())


#: The lab's published LQR weights (its realistic LQR example for design C.0), with its 6 N m motor.
DFKI_LQR = {"acrobot": (np.diag([0.64, 0.99, 0.78, 0.64]), [[0.27]]),
            "pendubot": (np.diag([0.0125, 6.5, 6.88, 9.36]), [[2.4]])}


@pytest.mark.parametrize("actuated", ["acrobot", "pendubot"])
def test_no_state_inside_the_estimate_where_v_grows(actuated):
    """An adversary with its own seed: 200 000 points in the ellipsoid V < rho (half of them in its
    outer shell), 4096 rays and SLSQP from 24 random starts (minimise V subject to V'/V >= 0) find
    no state with V < rho and V' >= 0 for the saturated loop; and rho is not vacuous: the smallest growing
    level it finds (with 4096 rays too) is within 20 % of rho / 0.95 (the old sampled estimate was
    12 % above the smallest growing level for the acrobot, 69 % for the pendubot)."""
    from scipy.optimize import minimize

    from skewpend.numeric.kernels import kernel_module, parameter_vector

    p = dfki_rig()
    Q, R = DFKI_LQR[actuated]
    d = skewpend.lqr(p, "up-up", actuated, Q=Q, R=R, umax=6.0)
    lin = d.linearization
    f = Controller.feedback(d.gain, lin.target, actuated=actuated, umax=6.0).closed_loop_function(
        kernel_module(p), parameter_vector(p))
    P = d.P

    def vdot(dx):
        dx = np.atleast_2d(dx)
        return 2.0 * np.einsum("ki,ij,kj->k", dx, P, f(lin.target + dx))

    def V(dx):
        return np.einsum("...i,ij,...j->...", dx, P, dx)

    rng = np.random.default_rng(20290)
    L = np.linalg.cholesky(P)
    z = rng.normal(size=(200_000, 4))
    z /= np.linalg.norm(z, axis=1, keepdims=True)
    unit = np.linalg.solve(L.T, z.T).T
    radius = np.concatenate([rng.uniform(0, 1, 100_000) ** 0.25, rng.uniform(0.9, 1.0, 100_000)])
    x = unit * (math.sqrt(d.rho) * radius * (1 - 1e-12))[:, None]
    assert np.all(V(x) < d.rho) and np.all(vdot(x) < 0)
    growing = []
    for k in range(24):
        z0 = unit[k] * math.sqrt(d.rho) * rng.uniform(0.3, 3.0)
        res = minimize(lambda z: float(V(z)), z0, jac=lambda z: 2 * P @ z, method="SLSQP",
                       constraints=[{"type": "ineq", "fun": lambda z: float(vdot(z)[0] / V(z))}],
                       options={"maxiter": 100})
        if np.all(np.isfinite(res.x)) and vdot(res.x)[0] >= 0:
            growing.append(float(V(res.x)))
    # rays: 4096 directions, 64 radii each from 0.3 to 2 times the estimate's
    s = math.sqrt(d.rho) * np.geomspace(0.3, 2.0, 64)
    rays = (unit[:4096, None, :] * s[None, :, None]).reshape(-1, 4)
    grows = vdot(rays) >= 0
    growing += list(V(rays[grows]))
    assert growing and min(growing) >= d.rho
    assert min(growing) <= 1.2 * d.rho / 0.95


# -- items 1, 7, 8: targets, weights, arguments ---------------------------------------------------------------------
def test_target_angles_are_reduced_or_refused(ref):
    with pytest.raises(ParameterError, match=r"equilibrium\[0\] must be a finite angle of at most 1e\+06 rad"):
        skewpend.lqr(ref, (1e308, 0.0), estimate=False)
    with pytest.raises(ParameterError, match=r"target\[0\]"):
        skewpend.swingup(ref, (1e17, 0.0))
    with pytest.raises(ParameterError, match=r"target\[1\]"):
        skewpend.region_of_attraction(ref, (0.0, -1e7))
    top = skewpend.lqr(ref, "up-up", estimate=False)
    for turns in (1, -3, 1000):  # pi + 2 pi k: the same top, the same gain
        d = skewpend.lqr(ref, (math.pi + 2 * math.pi * turns, np.float32(0.0)), estimate=False)
        assert d.linearization.equilibrium.label == "up-up"
        assert np.allclose(d.K, top.K, rtol=1e-9, atol=1e-9)


def test_a_semidefinite_q_is_solved_or_refused_in_one_line(ref):
    """Q = 0 at the top: the Riccati equation's stabilising solution mirrors the unstable
    eigenvalues (closed loop -lambda), P is singular, so there is no region estimate (rho = 0);
    at up-down the oscillating mode stays undamped: one ParameterError, never a LinAlgError."""
    d = skewpend.lqr(ref, "up-up", Q=np.zeros((4, 4)), umax=10.0)
    open_loop = np.linalg.eigvals(d.linearization.A)
    assert np.allclose(np.sort(d.eigenvalues.real), np.sort(-np.abs(open_loop.real)), rtol=1e-6)
    assert d.rho == 0.0
    with pytest.raises(ParameterError, match=r"Q must make \(A, Q\^1/2\) detectable at up-down"):
        skewpend.lqr(ref, "up-down", Q=np.zeros((4, 4)))
    with pytest.raises(skewpend.errors.EquilibriumError, match="P is singular"):
        skewpend.swingup(ref, Q=np.zeros((4, 4)))


def test_controllability_takes_sequences_and_numpy_scalars(ref):
    lin = skewpend.linearization(ref, "up-up", "acrobot")
    want = skewpend.controllability(lin.A, lin.B)
    got = skewpend.controllability(lin.A.tolist(), [np.float32(v) for v in lin.B[:, 0]])
    assert got["rank"] == want["rank"] == 4
    assert got["distance"] == pytest.approx(want["distance"], rel=1e-6)


@pytest.mark.parametrize("call, words", [
    (lambda: skewpend.controllability("x", [1, 0]), "A must be"),
    (lambda: skewpend.controllability([[1, 2], [3]], [1, 0]), "A must be"),
    (lambda: skewpend.controllability(np.eye(3)[:2], [1, 0]), "A must be a square matrix"),
    (lambda: skewpend.controllability(np.eye(2), [[1], [0], [0]]), "B must have as many rows as A"),
    (lambda: skewpend.controllability([[np.nan, 0], [0, 1]], [1, 0]), "A must hold finite numbers"),
    (lambda: skewpend.controllability(None, None), "A must be"),
    (lambda: skewpend.linearization(skewpend.reference_parameters(), None), "equilibrium must be"),
    (lambda: skewpend.linearization(skewpend.reference_parameters(), "up-up", ["both"]), "actuated must be one of"),
    (lambda: skewpend.lqr(skewpend.reference_parameters(), Q="x"), "Q must be a 4x4 matrix"),
    (lambda: skewpend.lqr(skewpend.reference_parameters(), Q=-np.eye(4)), "positive semi-definite"),
    (lambda: skewpend.lqr(skewpend.reference_parameters(), R=[1, 1]), "R must be a 2x2 matrix"),
    (lambda: skewpend.lqr(skewpend.reference_parameters(), umax="x"), "umax must be"),
    (lambda: skewpend.lqr(skewpend.reference_parameters(), umax=[1, 2, 3]), "umax must be"),
    (lambda: skewpend.lqr(skewpend.reference_parameters(), umax=1e-320), "umax must be"),
    (lambda: skewpend.lqr(skewpend.reference_parameters(), estimate="no"), "estimate must be"),
    (lambda: skewpend.lqr("params"), "params must be"),
    (lambda: skewpend.swingup(skewpend.reference_parameters(), energy_gain="x"), "energy_gain must be a real number"),
    (lambda: skewpend.swingup(skewpend.reference_parameters(), elbow_gains="ab"), "elbow_gains must be"),
    (lambda: skewpend.swingup(skewpend.reference_parameters(), y0=(1e308, 0, 0, 0)), "y0[0]"),
    (lambda: skewpend.swingup(skewpend.reference_parameters(), y0=(0, 0, math.inf, 0)), "y0 must hold finite"),
    (lambda: skewpend.swingup(skewpend.reference_parameters(), progress=3), "progress must be a callable"),
    (lambda: skewpend.swingup(skewpend.reference_parameters(), dt_out=1e-9), "use a larger dt_out"),
    (lambda: Controller.table("abc", [[0, 0]] * 3), "times must be"),
    (lambda: Controller.table([0, 1], object()), "torques must be"),
    (lambda: Controller.feedback("K", [0, 0, 0, 0]), "K must be"),
    (lambda: Controller.function(len, actuated=None), "actuated must be one of"),
])
def test_hostile_arguments_are_one_parameter_error(call, words):
    with pytest.raises(ParameterError, match=re.escape(words)):
        call()


# -- items 6/7: infeasible work refused before it starts -------------------------------------------------------------
@pytest.mark.parametrize("t_end", [1e308, 1e6, 3601.0])
def test_swingup_refuses_a_long_run_before_any_work(ref, t_end, monkeypatch):
    """Refused before the LQR design (the first work) -- the design counted, not timed."""
    import skewpend.analysis.control as control

    calls, designs = [], []
    monkeypatch.setattr(control, "lqr", lambda *a, **k: designs.append(a) or pytest.fail("designed"))
    with pytest.raises(ParameterError, match="t_end must be at most 3600"):
        skewpend.swingup(ref, t_end=t_end, progress=lambda t, total: calls.append(t))
    assert calls == [] and designs == []


def test_roa_refuses_an_infeasible_t_end_before_the_map(ref):
    d = skewpend.lqr(ref, "up-up", umax=10.0)
    calls = []
    for t_end in (1e308, 1e6):
        with pytest.raises(ParameterError, match="cannot finish: t_end = .* steps per trajectory"):
            skewpend.region_of_attraction(ref, n=4, design=d, t_end=t_end, progress=lambda a, b: calls.append(a))
    assert calls == []


def test_swingup_reports_progress(ref):
    seen = []
    run = skewpend.swingup(ref, t_end=4.0, progress=lambda t, total: seen.append((t, total)))
    assert seen[0] == (0.0, 4.0) and seen[-1][0] == pytest.approx(4.0) and run.captured


def test_the_cli_takes_its_defaults_from_the_library():
    """Each default the control command's help states is the library function's (roa's n was 128
    in the CLI, 64 in the library), and the command passes nothing it was not given."""
    import inspect

    from helpers import run_cli
    from skewpend.cli.control import library_defaults

    roa = inspect.signature(skewpend.region_of_attraction).parameters
    up = inspect.signature(skewpend.swingup).parameters
    assert library_defaults("roa")["n"] == roa["n"].default == 64
    assert library_defaults("swingup")["t_end"] == up["t_end"].default
    ran = run_cli(["control", "--help"])
    text = " ".join(ran.out.split())
    assert f"n x n grid of starts (default {roa['n'].default})" in text
    assert f"length of the run [s] (default {up['t_end'].default:g})" in text
    assert f"each start is followed (default {roa['t_end'].default:g})" in text
    assert f"energy shaping [N m s/J] (default {up['energy_gain'].default:g})" in text
    assert "(default {:g},{:g})".format(*up["elbow_gains"].default) in text
    assert "10 for swingup and roa" in text and up["umax"].default == roa["umax"].default == 10.0


def test_cli_lqr_with_q_zero_says_there_is_no_region():
    from helpers import run_cli

    ran = run_cli(["control", "lqr", "--q", "0,0,0,0"])
    assert ran.code == 0, ran.report()
    assert "region      none: P is singular" in ran.out
    ran = run_cli(["control", "lqr", "--q", "0,0,0,0", "--target", "up-down"])
    assert ran.code == 2 and ran.err.count("\n") == 1 and "detectable" in ran.err, ran.report()


# -- item 8, as an adversary: what broke next ---------------------------------------------------------------------
@pytest.mark.parametrize("law, words", [
    (lambda t, x: "ab", "must return two torques"),
    (lambda t, x: {1: 2}, "must return two torques"),
    (lambda t, x: (1.0, 2.0, 3.0), "must return two torques"),
])
def test_a_python_law_returning_nonsense_is_one_parameter_error(ref, law, words):
    with pytest.raises(ParameterError, match=re.escape(words)):
        skewpend.simulate(ref, (0.1, 0, 0, 0), 0.5, dt_out=0.1, controller=Controller.function(law, umax=5.0))


def test_a_law_that_takes_no_state_is_refused_when_built():
    with pytest.raises(ParameterError, match=r"the law must take two arguments, f\(t, x\)"):
        Controller.function(lambda: (0.0, 0.0))


def test_a_swingup_whose_run_fails_is_not_captured_and_says_why(ref):
    """energy_gain = 1e308: the law's first torque is inf * 0; the run stops at once (0 rows) -- a
    failed run, never an IndexError nor a capture."""
    run = skewpend.swingup(ref, energy_gain=1e308, t_end=2.0)
    assert not run.captured and not run.ok and "the run failed" in run.message


def test_a_one_cell_map_at_the_target_needs_no_trial_rate(ref):
    """n = 1: the one start is the target, inside the estimate at once (the trial rate was 0/0)."""
    d = skewpend.lqr(ref, "up-up", umax=10.0)
    r = skewpend.region_of_attraction(ref, n=1, design=d, t_end=1e-300)
    assert r.ok and r.captured_fraction == 1.0 and r.capture_time[0, 0] == 0.0
