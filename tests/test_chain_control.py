"""Inputs that vary for a chain of links (issue 38): the compiled controllers of ``integrators.c`` for any
number of joints.  The chain of two against the double pendulum's own kernel under every law, a triple
pendulum's saturated LQR loop against a NumPy law written here, the energy balance with inputs, a Python law
and the one-line refusals."""

from __future__ import annotations

import numpy as np
import pytest

import skewpend
from skewpend.errors import ParameterError
from skewpend.numeric.control import Controller
from skewpend.numeric.kernels import chain_kernel
from skewpend.numeric.recursive import parameter_vector
from skewpend.symbolic.chain import Chain

from test_chain_dynamics import _balance_chain, reference_closed_loop

PARAMS = skewpend.Parameters(a=1.0, b=0.8, m1=1.0, m2=0.7, alpha=0.3, g=9.81, c1=0.03, c2=0.02)
TOL = dict(rtol=1e-12, atol=1e-12)


def _pair(double_ctl, chain_ctl, y0, t_end=3.0):
    a = skewpend.simulate(PARAMS, y0, t_end, dt_out=0.01, controller=double_ctl, **TOL)
    b = skewpend.simulate(Chain.from_parameters(PARAMS), y0, t_end, dt_out=0.01, controller=chain_ctl, **TOL)
    assert a.ok and b.ok, (a.message, b.message)
    return a, b


def test_the_chain_of_two_under_feedback_is_the_double_pendulum_under_it(recursive_forms):
    """The acrobot's saturated LQR on the double pendulum's symbolic kernel and on the chain of two's recursive
    kernel (its actuated joint named by number): the same states and inputs.  Both integrate with DOP853 at
    rtol = atol = 1e-12 near the top, where the loop is stable: the runs agree to ~1e3 times the tolerance."""
    design = skewpend.lqr(PARAMS, "up-up", "acrobot", umax=5.0)
    y0 = [np.pi + 0.01, -0.005, 0.0, 0.0]
    for umax in (None, 1.0):  # 1 N m: the law saturates at the start
        a, b = _pair(Controller.feedback(design.gain, design.linearization.target, actuated="acrobot", umax=umax),
                     Controller.feedback(design.gain, design.linearization.target, actuated=(2,), umax=umax), y0)
        np.testing.assert_allclose(b.y, a.y, rtol=0, atol=1e-9)
        np.testing.assert_allclose(b.inputs(), a.inputs(), rtol=0, atol=1e-9 * np.abs(a.inputs()).max())
        assert b.inputs().shape == (len(b.t), 2) and np.all(b.inputs()[:, 0] == 0.0)
    assert np.abs(a.inputs()[:, 1]).max() == pytest.approx(1.0)  # the limit held


def test_the_chain_of_two_under_a_table_and_a_swing_up_law_is_the_double_pendulum(recursive_forms):
    """A torque table (both joints) and the energy-shaping swing-up law (the energy from each kernel's own
    generated E): the chain of two and the double pendulum give the same runs.  The table's knots are kinks
    of u(t); every step ends on a knot (integrators.c's table_stop), so both runs are within ~3e-11 of a
    DOP853 run at 1e-14 (measured): 1e-9 as for the smooth feedback.  (Steps across the knots left each
    run's error to where its steps fell: 3.6e-10 and 3.7e-8 measured.)"""
    t = np.linspace(0.0, 3.0, 31)
    torques = np.column_stack([0.5 * np.sin(3 * t), -0.3 * np.cos(2 * t)])
    a, b = _pair(Controller.table(t, torques), Controller.table(t, torques), [0.3, -0.2, 0.0, 0.0])
    np.testing.assert_allclose(b.y, a.y, rtol=0, atol=1e-9)
    design = skewpend.lqr(PARAMS, "up-up", "both", umax=4.0)
    lin = design.linearization
    kw = dict(elbow_gains=(20.0, 4.0), umax=4.0)
    double = Controller.swingup(2.0, lin.equilibrium.potential, design.gain, lin.target, design.P, design.rho, **kw)
    chained = Controller.swingup(2.0, lin.equilibrium.potential, design.gain, lin.target, design.P, design.rho,
                                 actuated="all", **kw)
    a, b = _pair(double, chained, [0.05, 0.0, 0.0, 0.0], t_end=2.0)
    assert np.abs(a.inputs()).max() > 1.0  # the law did pump
    # the law at the same states on both kernels: equal to rounding; the runs (the saturation's kinks, a motion
    # that grows) to 1e-6
    from skewpend.numeric.kernels import kernel_module, parameter_vector as double_vector

    u_double = double.inputs(kernel_module(PARAMS), double_vector(PARAMS), a.t, a.y)
    u_chain = chained.inputs(chain_kernel(Chain.from_parameters(PARAMS)), parameter_vector(Chain.from_parameters(PARAMS)),
                             a.t, a.y)
    np.testing.assert_allclose(u_chain, u_double, rtol=0, atol=1e-11 * np.abs(u_double).max())
    np.testing.assert_allclose(b.y, a.y, rtol=0, atol=1e-6)


def test_a_triple_pendulums_compiled_loop_is_the_numpy_law():
    """The compiled saturated feedback of a skewed triple pendulum (elbow motor only, 20 N m) against the NumPy
    law of ``reference_closed_loop`` at 200 seeded states around the top, the saturation and the angles' wrap
    included: equal to rounding (1e-12 of the largest acceleration)."""
    chain = _balance_chain()
    design = skewpend.lqr(chain, "up-up-up", (2,), umax=20.0, estimate=False)
    target = design.linearization.target
    rng = np.random.default_rng(5)
    X = target + rng.normal(scale=[0.6, 0.6, 0.6, 2.0, 2.0, 2.0], size=(200, 6))
    ctl = design.controller(umax=20.0)
    got = ctl.closed_loop(chain_kernel(chain), parameter_vector(chain), np.zeros(len(X)), X)
    want = reference_closed_loop(chain, design.gain, target, (20.0,) * 3)(X)
    np.testing.assert_allclose(got, want, rtol=0, atol=1e-12 * np.abs(want).max())
    u = ctl.inputs(chain_kernel(chain), parameter_vector(chain), np.zeros(len(X)), X)
    assert u.shape == (200, 3) and np.all(u[:, [0, 2]] == 0.0) and np.abs(u[:, 1]).max() == pytest.approx(20.0)


def test_a_triple_pendulum_balanced_on_its_elbow_motor_in_simulate():
    """``simulate(chain, controller=lqr(...).controller())`` from starts on the region estimate's boundary
    (V = 0.9 rho): the saturated loop brings the triple pendulum to the top (|dx| < 1e-3 after 8 s), with the
    energy balance E - W = E0 (the inputs' work counted in W) to the integrator's tolerance."""
    chain = _balance_chain()
    design = skewpend.lqr(chain, "up-up-up", (2,), umax=20.0)
    target = design.linearization.target
    L = np.linalg.cholesky(design.P)
    rng = np.random.default_rng(3)
    for _ in range(3):
        z = rng.normal(size=6)
        x0 = target + np.linalg.solve(L.T, z / np.linalg.norm(z)) * np.sqrt(0.9 * design.rho)
        tr = skewpend.simulate(chain, x0, 8.0, dt_out=0.05, controller=design.controller(), rtol=1e-10, atol=1e-10)
        assert tr.ok, tr.message
        end = tr.y[-1] - target
        assert np.abs(end).max() < 1e-3, end
        assert tr.energy_drift < 1e-7
        assert tr.inputs().shape == (len(tr.t), 3)


def test_a_chains_torque_table_and_python_law_agree():
    """A triple's one-motor torque table (1-D torques for joint 3) and the same torques by a Python law
    ``f(t, x)`` returning three torques: the same run.  The 201 knots are kinks of u(t): the table's steps
    end on them (one step a knot interval here, 201 steps, 7e-14 from a run at 1e-14 -- measured), the
    law's cannot see them, and DOP853's order and error estimate fail across each (1,345 steps, 3.7e-7 from
    it): allowed 1e-6.  With damping the energy balance holds (1e-8)."""
    chain = Chain.from_lists(3, length=[0.5, 0.4, 0.3], mass=[1.0, 0.8, 0.5], damping=0.05,
                             axis=[(0, 0, 1), (0.5, 0, 1), (1, 0, 0)])
    t = np.linspace(0.0, 2.0, 201)
    u3 = 0.4 * np.sin(4 * t)
    table = Controller.table(t, u3, actuated=(3,), nq=3)
    assert table.torques.shape == (201, 3) and np.all(table.torques[:, :2] == 0.0)

    def law(time, x):
        return [0.0, 0.0, float(np.interp(time, t, u3))]

    py = Controller.function(law, actuated=(3,), nq=3)
    y0 = [0.4, -0.3, 0.2, 0.0, 0.0, 0.0]
    a = skewpend.simulate(chain, y0, 2.0, dt_out=0.02, controller=table, rtol=1e-11, atol=1e-11)
    b = skewpend.simulate(chain, y0, 2.0, dt_out=0.02, controller=py, rtol=1e-11, atol=1e-11)
    assert a.ok and b.ok
    exact = skewpend.simulate(chain, y0, 2.0, dt_out=0.02, controller=table, rtol=1e-14, atol=1e-14)
    np.testing.assert_allclose(a.y, exact.y, rtol=0, atol=1e-11)
    assert a.stats["steps"] <= 2 * (len(t) - 1)  # a step or two a knot interval: nothing rejected at the kinks
    np.testing.assert_allclose(b.y, a.y, rtol=0, atol=1e-6)
    assert a.energy_drift < 1e-8
    np.testing.assert_allclose(a.inputs()[:, 2], np.interp(a.t, t, u3), atol=1e-12)


def test_chain_controllers_refuse_in_one_line():
    chain = _balance_chain()
    two = Controller.feedback(np.zeros((2, 4)), np.zeros(4))
    with pytest.raises(ParameterError, match=r"drives 2 joints; a chain of 3 links has 3"):
        skewpend.simulate(chain, [0.1, 0, 0, 0, 0, 0], 1.0, controller=two)
    three = Controller.feedback(np.zeros((3, 6)), np.zeros(6), actuated=(1, 3))
    with pytest.raises(ParameterError, match=r"drives 3 joints; the skewed double pendulum has 2"):
        skewpend.simulate(PARAMS, [0.1, 0, 0, 0], 1.0, controller=three)
    with pytest.raises(ParameterError, match=r"K must have shape \(n, 2 n\)"):
        Controller.feedback(np.zeros((3, 4)), np.zeros(6))
    with pytest.raises(ParameterError, match=r"actuated must be 'all' or the numbers of the joints with a motor, 1 to 3"):
        Controller.feedback(np.zeros((3, 6)), np.zeros(6), actuated=(4,))
    with pytest.raises(ParameterError, match=r"actuated must be one of both, pendubot, acrobot \(acrobot: the elbow only"):
        Controller.feedback(np.zeros((2, 4)), np.zeros(4), actuated="elbow")
    with pytest.raises(ParameterError, match=r"torques must have 3 columns"):
        Controller.table([0.0, 1.0], [0.0, 1.0], actuated="all", nq=3)
    with pytest.raises(ParameterError, match=r"umax must be positive torque limits \[N m\] \(one, or one per joint: 3"):
        Controller.feedback(np.zeros((3, 6)), np.zeros(6), umax=[1.0, 2.0])
    bad = Controller.function(lambda t, x: [0.0, 0.0], nq=3)
    with pytest.raises(ParameterError, match=r"must return three torques \(u1, u2, u3\)"):
        skewpend.simulate(chain, [0.1, 0, 0, 0, 0, 0], 0.5, controller=bad)


# -- regions of attraction over a plane of two coordinates ----------------------------------------------------------
def test_the_chain_of_twos_region_of_attraction_is_the_double_pendulums(recursive_forms):
    """The pendubot's region of attraction on the double pendulum (its flip kernel's SIMD lanes) and on the chain
    of two (the recursive kernel, ``sp_capture_many`` one start at a time): the same cells captured but for
    starts within the integrators' tolerance of the boundary (at most 2 of 256), and the same capture times where
    both captured (1e-4 s: two DOP853 step sequences at rtol 1e-8 locate the entry on different dense outputs)."""
    params = skewpend.Parameters(a=1.0, b=0.8, m1=1.0, m2=0.7, alpha=0.3, g=9.81)
    chain = Chain.from_parameters(params)
    kw = dict(n=16, umax=6.0, window=((-0.6, 0.6), (-0.6, 0.6)), t_end=4.0, workers=1)
    a = skewpend.region_of_attraction(params, "up-up", "pendubot", **kw)
    b = skewpend.region_of_attraction(chain, "up-up", (1,), plane=("phi", "psi"), **kw)
    assert a.ok and b.ok and b.plane == ("phi", "psi")
    np.testing.assert_allclose(b.K, a.K, rtol=1e-7, atol=1e-7 * np.abs(a.K).max())
    assert 0.05 < a.captured_fraction < 0.95
    assert np.count_nonzero(a.outcome != b.outcome) <= 2
    both = a.captured & b.captured
    np.testing.assert_allclose(b.capture_time[both], a.capture_time[both], atol=1e-4)


def test_a_triple_pendulums_region_of_attraction_on_a_chosen_plane(tmp_path):
    """A skewed triple pendulum with every joint driven, mapped over (q1, dq3) with the others at the top: the
    cells inside the LQR estimate at the start are captured at t = 0; captured and not captured cells checked
    by ``simulate`` with the same controller (the former end at the top, the latter not by t_end); the map
    reads back from NetCDF with its chain."""
    chain = _balance_chain()
    r = skewpend.region_of_attraction(chain, "up-up-up", "all", n=13, plane=("q1", "dq3"), umax=10.0,
                                      window=((-1.6, 1.6), (-6.0, 6.0)), t_end=6.0, workers=1)
    assert r.ok and r.K.shape == (3, 6) and 0.1 < r.captured_fraction < 0.95
    inside = r.capture_time == 0.0
    assert np.count_nonzero(inside) == round(r.inner_fraction * r.capture_time.size) > 0
    design = skewpend.lqr(chain, "up-up-up", "all", umax=10.0)
    ctl = design.controller()
    for want in (True, False):
        i, j = np.argwhere(r.captured == want)[0]
        x0 = r.target.copy()
        x0[0], x0[5] = r.x0[i], r.y0[j]
        tr = skewpend.simulate(chain, x0, 6.0, dt_out=0.05, controller=ctl, rtol=1e-8, atol=1e-8)
        assert bool(design.inside(tr.y).any()) == want
    back = skewpend.open_result(r.to_netcdf(tmp_path / "roa.nc"))
    assert back.params == chain and back.plane == ("q1", "dq3")
    np.testing.assert_array_equal(back.outcome, r.outcome)
    with pytest.raises(ParameterError, match=r"plane must be two different coordinates of q1, q2, q3, dq1, dq2, dq3"):
        skewpend.region_of_attraction(chain, "up-up-up", "all", n=4, plane=("phi", "psi"))


# -- the command line ---------------------------------------------------------------------------------------------
def _chain_toml(tmp_path):
    path = tmp_path / "triple.toml"
    path.write_text('[chain]\ng = 9.81\n[[links]]\nlength = 0.5\nmass = 1.0\n[[links]]\nlength = 0.4\nmass = 0.8\n'
                    'axis = [0.5, 0, 1]\n[[links]]\nlength = 0.3\nmass = 0.5\naxis = [1, 0, 0]\n')
    return path


def test_the_cli_balances_and_maps_a_chain(tmp_path):
    from helpers import run_cli

    config = _chain_toml(tmp_path)
    ran = run_cli(["control", "lqr", "--config", config, "--actuated", "2", "--umax", "20"])
    assert ran.code == 0, ran.report()
    assert "actuated    joint 2; controllable (rank 6 of 6" in ran.out and "x = (q1, q2, q3, q1', q2', q3')" in ran.out
    design = skewpend.lqr(_balance_chain(), "up-up-up", (2,), umax=20.0)
    gains = [float(v) for v in ran.out.split("joint 2   ")[1].split("\n")[0].split()]
    np.testing.assert_allclose(gains, design.K[0], rtol=1e-5)
    out = tmp_path / "roa.nc"
    ran = run_cli(["control", "roa", "--config", config, "--actuated", "all", "--umax", "10", "--n", "6", "--plane",
                   "q1,q3", "--window=-1.5:1.5,-1.5:1.5", "--t-end", "4", "--out", out])
    assert ran.code == 0, ran.report()
    assert "over q1 x q3 about the target" in ran.out and skewpend.open_result(out).params.n == 3


@pytest.mark.parametrize("argv, message", [
    (["control", "lqr", "--actuated", "acrobot"], "--actuated: acrobot names a joint of the double pendulum"),
    (["control", "lqr", "--actuated", "4"], "--actuated: a chain of 3 links has joints 1 to 3, got 4"),
    (["control", "lqr", "--q", "1,1,1,1"], "--q: give 6 state weights"),
    (["control", "lqr", "--actuated", "1,3", "--r", "1"], "--r: give 2 weight(s), one per actuated joint (joints 1,3)"),
    (["control", "lqr", "--target", "180deg,0"], "--target: target must be 3 angles in radians, got 2 values"),
    (["control", "swingup", "--actuated", "pendubot"], "--actuated: pendubot names a joint of the double pendulum"),
    (["control", "roa", "--plane", "phi,psi", "--n", "4"], "plane must be two different coordinates of q1, q2, q3"),
])
def test_the_cli_refuses_what_a_chain_cannot_take(tmp_path, argv, message):
    from helpers import run_cli

    ran = run_cli([*argv, "--config", _chain_toml(tmp_path)])
    assert ran.code == 2 and message in ran.err and "Traceback" not in ran.err, ran.report()
    assert len(ran.err.strip().splitlines()) == 1


def test_a_triple_pendulum_swings_up_by_energy_shaping(tmp_path):
    """The energy-shaping swing-up on any model (issue 52): a skewed triple pendulum, every joint driven, at most
    10 N m, from hanging nudged at the first joint -- captured by the LQR and held at the top to the end, the
    energy balance with the inputs' work kept; on the command line the run file's columns are the chain's."""
    from helpers import run_cli

    chain = Chain.from_lists(3, length=[0.5, 0.4, 0.3], mass=[1.0, 0.8, 0.5], axis=[(0, 0, 1), (0.5, 0, 1), (1, 0, 0)])
    run = skewpend.swingup(chain, umax=10.0)
    tr = run.trajectory
    assert run.captured and run.capture_time < 10.0 and run.lqr.linearization.equilibrium.label == "up-up-up"
    assert np.abs(tr.inputs()).max() == pytest.approx(10.0) and tr.energy_drift < 1e-8
    assert np.all(run.lqr.inside(tr.y[tr.t >= run.capture_time]))
    out = tmp_path / "run.csv"
    ran = run_cli(["control", "swingup", "--config", _chain_toml(tmp_path), "--out", out])
    assert ran.code == 0 and "captured by the LQR" in ran.out, ran.report()
    assert out.read_text().splitlines()[0] == "t,q1,q2,q3,dq1,dq2,dq3,energy,work,u1,u2,u3"


# -- flip maps over a plane of two angles ---------------------------------------------------------------------------
def test_one_flip_map_two_strategies_and_forms(monkeypatch):
    """One flip map, two strategies: the exact form's flip kernel (SIMD lanes, its energy bound and mirror
    symmetry) -- which the chain of two runs as the double pendulum does -- and the straight form's model kernel
    (``sp_flip_many``, every cell integrated): the same cells flip, by the same joint, at the same times (1e-6 s:
    DOP853 at 1e-10 on two kernels, the crossing on each one's dense output)."""
    from skewpend.analysis import flipmap
    from skewpend.numeric.kernels import model_kernel

    params = skewpend.Parameters(a=1.0, b=0.8, m1=1.0, m2=0.7, alpha=0.3, g=9.81)
    a = skewpend.flip_map(Chain.from_parameters(params), 16, t_end=4.0, plane=("phi", "psi"), workers=1)
    monkeypatch.setattr(flipmap, "flip_kernel", lambda model: model_kernel(model, "straight"))
    b = skewpend.flip_map(params, 16, t_end=4.0, workers=1)
    assert type(b) is type(a) is skewpend.FlipMap and b.ok and 0.2 < b.flipped_fraction < 0.9
    assert a.stats["lanes"] == 8 and a.settings["symmetry"] and b.stats["lanes"] == 1 and not b.settings["energy_bound"]
    np.testing.assert_array_equal(b.flipped, a.flipped)
    np.testing.assert_array_equal(b.which, a.which)
    np.testing.assert_allclose(b.flip_time[b.flipped], a.flip_time[a.flipped], rtol=0, atol=1e-6)
    np.testing.assert_array_equal(b.x0, a.x0)
    np.testing.assert_array_equal(b.phi0, a.phi0)
    assert b.settings.keys() == a.settings.keys() and b.stats.keys() == a.stats.keys()


def test_a_triple_pendulums_flip_map_against_simulate(tmp_path):
    """A skewed triple pendulum over (q1, q3), q2 held at 0.5 rad: a flipped cell's run by ``simulate`` (another
    driver, the same kernel) has its flipping joint at +-pi at the map's flip time (1e-6 rad) and every angle
    inside (-pi, pi) before; a cell that does not flip keeps every angle inside to t_end.  Reads back from
    NetCDF with its chain."""
    chain = _balance_chain()
    fm = skewpend.flip_map(chain, 9, plane=("q1", "q3"), held=[0.0, 0.5, 0.0], t_end=4.0, workers=1)
    assert fm.ok and fm.held.tolist() == [0.0, 0.5, 0.0] and 0.1 < fm.flipped_fraction < 0.95
    for want in (True, False):
        i, j = np.argwhere(fm.flipped == want)[-1]
        y0 = [fm.x0[i], 0.5, fm.y0[j], 0.0, 0.0, 0.0]
        if want:
            t, joint = fm.flip_time[i, j], fm.which[i, j]
            tr = skewpend.simulate(chain, y0, t, dt_out=t / 400, rtol=1e-10, atol=1e-10)
            assert abs(abs(tr.y[-1, joint]) - np.pi) < 1e-6
            assert np.abs(tr.y[:-1, :3]).max() < np.pi
        else:
            tr = skewpend.simulate(chain, y0, 4.0, dt_out=0.01, rtol=1e-10, atol=1e-10)
            assert np.abs(tr.y[:, :3]).max() < np.pi and fm.which[i, j] == -1
    back = skewpend.open_result(fm.to_netcdf(tmp_path / "flip.nc"))
    assert back.params == chain and back.plane == ("q1", "q3")
    np.testing.assert_array_equal(back.which, fm.which)
    from skewpend.views.figures import flipmap_figure

    fig = flipmap_figure(fm)
    assert fig.axes[0].get_xlabel() == "q₁, hinge 1 at release [deg]" and "held q2 = 28.65°" in fig._suptitle.get_text()
    assert "q1(0) in [-180°, 180°], q3(0) in [-180°, 180°]" in fig._suptitle.get_text()


def test_flip_maps_refuse_the_others_options_in_one_line():
    chain = _balance_chain()
    with pytest.raises(ParameterError, match=r"plane must be two different angles of q1, q2, q3 \(a flip map starts at rest\)"):
        skewpend.flip_map(chain, 4, plane=("q1", "dq2"))
    with pytest.raises(ParameterError, match=r"held must be the chain's 3 angles, each within \(-pi, pi\)"):
        skewpend.flip_map(chain, 4, held=[0.0, 0.1])
    with pytest.raises(ParameterError, match=r"phi_range is the double pendulum's \(the range of its angle phi\); this "
                                              r"model's flip map takes plane=, ranges= and held= \(of q1, q2, q3\)"):
        skewpend.flip_map(chain, 4, phi_range=(-1.0, 1.0))
    with pytest.raises(ParameterError, match=r"give the ranges either as ranges= or as phi_range, not both"):
        skewpend.flip_map(PARAMS, 4, ranges=((-1.0, 1.0), (-1.0, 1.0)), phi_range=(-1.0, 1.0))
    with pytest.raises(ParameterError, match=r"plane must be two different angles of phi, psi"):
        skewpend.flip_map(PARAMS, 4, plane=("phi", "phi"))


def test_the_double_pendulums_map_over_either_plane():
    """The double pendulum's plane is a choice too: (psi, phi) is the transposed map, bit for bit (each cell's
    arithmetic is its own), its ranges named by the angles either way."""
    a = skewpend.flip_map(PARAMS, 12, t_end=3.0, phi_range=(-3.0, 2.0), workers=1)
    c = skewpend.flip_map(PARAMS, 12, t_end=3.0, plane=("psi", "phi"), phi_range=(-3.0, 2.0), workers=1)
    assert c.flip_time.T.tobytes() == a.flip_time.tobytes() and c.which.T.tobytes() == a.which.tobytes()
    assert c.plane == ("psi", "phi") and c.settings["phi_range"] == (-3.0, 2.0) and c.settings["plane"] == ("psi", "phi")
    np.testing.assert_array_equal(c.phi0, a.phi0.T)


def test_the_cli_maps_a_chains_flips(tmp_path):
    from helpers import run_cli

    config, out = _chain_toml(tmp_path), tmp_path / "flip.nc"
    ran = run_cli(["flipmap", "--config", config, "--n", "8", "--plane", "q1,q3", "--held", "0,30deg,0", "--t-end", "3",
                   "--out", out])
    assert ran.code == 0, ran.report()
    assert "starts at rest over q1 x q3" in ran.out and "by joint      q1: " in ran.out
    fm = skewpend.open_result(out)
    assert fm.plane == ("q1", "q3") and fm.held[1] == pytest.approx(np.radians(30))
    for argv, message in ((["--plane", "q1,dq3"], "--plane: a flip map starts at rest"),
                          (["--held", "0,0"], "--held: held must be the chain's 3 angles")):
        ran = run_cli(["flipmap", "--config", config, "--n", "4", *argv])
        assert ran.code == 2 and message in ran.err and len(ran.err.strip().splitlines()) == 1, ran.report()
    ran = run_cli(["flipmap", "--n", "4", "--plane", "phi,psi"])
    assert ran.code == 2 and "--plane goes with a chain of links" in ran.err, ran.report()
