"""Optimal swing-ups beyond the leaderboard's case: the optimiser's knots checked interval by interval by
skewpend's compiled integrators (the torques as a table, linear between the knots as the optimiser holds
them): its RK4 steps reproduced by the generated kernel, their convergence at RK4's order against DOP853;
other goals, both motors, a stated cost, a start off the rest, a chain of three links, a skew."""

from __future__ import annotations

import math

import numpy as np
import pytest

import skewpend
from skewpend.analysis import leaderboard as lb
from skewpend.analysis.trajopt import Cost, optimal_swingup, tvlqr
from skewpend.errors import ParameterError


def _interval(model, traj, k: int, **method) -> np.ndarray:
    """Knot interval k run again by skewpend's compiled integrator from the optimiser's state at its start, the
    torques a two-row table (linear across the interval, as the optimiser holds them)."""
    n = traj.u.shape[1]
    h = float(traj.t[k + 1] - traj.t[k])
    ctl = skewpend.Controller.table([0.0, h], traj.u[k:k + 2], actuated=traj.actuated, nq=n)
    run = skewpend.simulate(model, t_end=h, y0=tuple(traj.x[k]), controller=ctl, dt_out=h, **method)
    return run.y[-1, :2 * n]


def _check_discretisation(model, traj) -> None:
    """The optimiser's knots are RK4 steps of the model's own equations: skewpend's compiled RK4 (one step of
    the interval, the generated kernel -- not the optimiser's CasADi graph) reproduces every knot to 1e-8
    relative (the same equations evaluated twice: round-off through the mass matrix's solve, 1e-10 to 2e-9
    measured); and the step converges: against DOP853 at 1e-12, halving the step cuts the error on the
    intervals where it is largest by more than 8 (measured 15-16: fourth order)."""
    hs = np.diff(traj.t)
    one = np.array([np.max(np.abs(_interval(model, traj, k, method="rk4", dt=float(h)) - traj.x[k + 1])
                           / max(1.0, np.max(np.abs(traj.x[k + 1])))) for k, h in enumerate(hs)])
    assert one.max() < 1e-8, one.max()
    exact = {k: _interval(model, traj, k, rtol=1e-12, atol=1e-12) for k in range(len(hs))}
    err = np.array([np.max(np.abs(traj.x[k + 1] - exact[k])) for k in range(len(hs))])
    for k in np.argsort(err)[-3:]:
        half = np.max(np.abs(_interval(model, traj, int(k), method="rk4", dt=float(hs[k]) / 2) - exact[int(k)]))
        assert err[k] / half > 8, (k, err[k], half)


def test_the_optimised_knots_are_rk4_steps_of_the_model():
    model = lb.dfki_model()
    traj = optimal_swingup(model, actuated=(2,), knots=100, attempts=1)
    assert traj.ok, traj.message
    _check_discretisation(model, traj)
    assert np.allclose(traj.x[-1], [math.pi, 0, 0, 0], atol=1e-9) and np.all(traj.u[:, 0] == 0.0)


@pytest.mark.parametrize("alpha_deg, joints, hold", [(0.0, (2,), 0.8), (30.0, (1,), 0.8), (30.0, (1, 2), 1.0)])
def test_the_structured_derivatives_are_casadis_own(alpha_deg, joints, hold):
    """The NLP's constraint Jacobian and Lagrangian Hessian, assembled from one knot interval's derivatives
    (``jac_g``, ``hess_lag``), equal CasADi's automatic derivatives of the whole expanded NLP at a random point
    with random multipliers: the same sparsity, the values to round-off (1e-12 relative to the largest entry;
    measured 1e-16 and 2e-16), for a skew, both motors and the phase without the success line."""
    from skewpend.analysis import trajopt

    chain = trajopt._as_chain(lb.dfki_model(math.radians(alpha_deg)))
    ca, _, step, tip = trajopt.casadi_dynamics(chain, joints)
    N = 20
    N1 = 16 if hold < 1 else N
    nlp, derivatives, _ = trajopt._transcription(ca, step, tip, n=2, m=len(joints), N=N, N1=N1, joints=joints,
                                                 up_line=0.45 if hold < 1 else 0.0,
                                                 weights=dict(zip(trajopt.COST_TERMS, (1.0, 0.5, 1.0, 2.0, 1.0))),
                                                 dt_score=0.002, steps_score=5000)
    whole = ca.Function("nlp", [nlp["x"]], [nlp["f"], nlp["g"]]).expand()
    z = ca.SX.sym("z", nlp["x"].shape[0])
    f, g = whole(z)
    lam_f, lam_g = ca.SX.sym("lam_f"), ca.SX.sym("lam_g", g.shape[0])
    jac = ca.Function("auto_jac", [z], [ca.jacobian(g, z)])
    hess = ca.Function("auto_hess", [z, lam_f, lam_g], [ca.triu(ca.hessian(lam_f * f + ca.dot(lam_g, g), z)[0])])
    rng = np.random.default_rng(3)
    zv = rng.normal(size=z.shape[0])
    zv[-7:] = np.abs(zv[-7:]) + 0.5  # the slacks and durations where the criteria are smooth
    lv = rng.normal(size=g.shape[0])
    none = np.zeros((0, 1))
    mine_g, mine_J = derivatives["jac_g"](zv, none)
    mine_H = derivatives["hess_lag"](zv, none, 0.7, lv)
    auto_J, auto_H = jac(zv), hess(zv, 0.7, lv)
    assert mine_J.sparsity() == auto_J.sparsity() and mine_H.sparsity() == auto_H.sparsity()
    for mine, auto in ((mine_J, auto_J), (mine_H, auto_H), (mine_g, whole(zv)[1])):
        a, b = np.array(mine), np.array(auto)
        assert np.max(np.abs(a - b)) <= 1e-12 * np.max(np.abs(b)), np.max(np.abs(a - b))


def test_both_motors_to_another_equilibrium_from_a_swing():
    """actuated="both", the goal "up-down" (rod 1 up, rod 2 hanging from it), from a start off the rest, the
    limit 3 N m: converged, within the limit, ends at that equilibrium at rest, replayed to the RK4 bound;
    a tracking of it brings the protocol's run there."""
    model = lb.dfki_model(math.radians(20))
    start = (0.3, -0.2, 0.5, 0.0)
    traj = optimal_swingup(model, actuated="both", goal="up-down", start=start, umax=3.0, knots=100, attempts=2)
    assert traj.ok, traj.message
    assert np.allclose(traj.x[0], start) and np.max(np.abs(traj.u)) <= 3.0 + 1e-9
    q1, q2 = traj.x[-1, :2]
    assert abs(math.remainder(q1 - math.pi, 2 * math.pi)) < 1e-9 and abs(math.remainder(q2 - math.pi, 2 * math.pi)) < 1e-9
    _check_discretisation(model, traj)
    tracking = tvlqr(traj)
    run = lb.run_protocol(model, tracking, actuated=(1, 2), umax=3.0, x0=start, protocol=lb.Protocol(t_final=6.0))
    assert run.ok
    assert abs(math.remainder(run.final[0] - math.pi, 2 * math.pi)) < 1e-3
    assert abs(math.remainder(run.final[1] - math.pi, 2 * math.pi)) < 1e-3


def test_a_stated_cost_is_what_is_minimised():
    """Weighting the torque cost ten times lowers it (and the swing-up takes longer); weighting only the time
    makes the swing-up at least as fast as the default's.  (120 knots, one start: at 80 the plain start with the
    torque weighted tenfold ends in IPOPT's restoration failure -- reported as such, ``ok`` False.)"""
    model = lb.dfki_model()
    base = optimal_swingup(model, actuated=(2,), knots=120, attempts=1)
    torque = optimal_swingup(model, actuated=(2,), knots=120, attempts=1, cost=Cost(torque=10.0))
    fast = optimal_swingup(model, actuated=(2,), knots=120, attempts=1,
                           cost=Cost(time=1.0, energy=0.0, torque=0.0, smoothness=0.0, velocity=0.0))
    assert base.ok and torque.ok and fast.ok
    assert torque.predicted["tau_cost"] < base.predicted["tau_cost"]
    assert fast.predicted["swingup_time"] <= base.predicted["swingup_time"] + 1e-6


def test_a_chain_of_three_links():
    """A chain of three links (the second hinge skewed), every joint driven, to "up-up-up": converged, ends
    there at rest, replayed to the RK4 bound."""
    from skewpend.symbolic.chain import Chain, Link

    chain = Chain(links=(Link(length=0.2, mass=0.5), Link(length=0.2, mass=0.4, axis=(0.3, 0, 1)),
                         Link(length=0.15, mass=0.3)))
    traj = optimal_swingup(chain, actuated="all", goal="up-up-up", umax=4.0, knots=60, attempts=1)
    assert traj.ok, traj.message
    assert abs(math.remainder(traj.x[-1, 0] - math.pi, 2 * math.pi)) < 1e-9
    assert np.allclose(traj.x[-1, 1:], 0.0, atol=1e-9)
    _check_discretisation(chain, traj)


def test_bad_input_is_one_line():
    model = lb.dfki_model()
    with pytest.raises(ParameterError, match="workers must be a whole number"):
        optimal_swingup(model, actuated=(2,), knots=20, attempts=2, workers=0)
    with pytest.raises(ParameterError, match="cost must be a skewpend Cost"):
        optimal_swingup(model, cost={"time": 1})
