"""Property tests (Hypothesis) of the simulated motion: conservation, reversibility, symmetry.

One body geometry (the thin rods) is compiled once; the scalar parameters and states vary.
"""

from __future__ import annotations

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st

from skewpend import Parameters, simulate

lengths = st.floats(0.2, 2.0)
masses = st.floats(0.1, 3.0)
angles = st.floats(-3.0, 3.0)
speeds = st.floats(-3.0, 3.0)
skews = st.floats(-np.pi, np.pi)

SETTINGS = settings(max_examples=25, deadline=None, derandomize=True)


@SETTINGS
@given(a=lengths, b=lengths, m1=masses, m2=masses, alpha=skews, q1=angles, q2=angles, w1=speeds, w2=speeds)
def test_energy_is_conserved(a, b, m1, m2, alpha, q1, q2, w1, w2):
    tr = simulate(Parameters(a=a, b=b, m1=m1, m2=m2, alpha=alpha, g=9.81), (q1, q2, w1, w2), 3.0, rtol=1e-11, atol=1e-11)
    assert tr.success
    scale = max(np.max(np.abs(tr.energy)), 9.81 * (m1 + m2) * (a + b))
    assert np.max(np.abs(tr.energy - tr.energy[0])) < 1e-7 * scale


@SETTINGS
@given(a=lengths, b=lengths, m1=masses, m2=masses, alpha=skews, q1=angles, q2=angles, w1=speeds, w2=speeds)
def test_time_reversibility(a, b, m1, m2, alpha, q1, q2, w1, w2):
    """Run forward, flip the speeds, run back: the initial state returns (conservative system)."""
    p = Parameters(a=a, b=b, m1=m1, m2=m2, alpha=alpha, g=9.81)
    fwd = simulate(p, (q1, q2, w1, w2), 1.0, rtol=1e-12, atol=1e-12)
    y = fwd.final_state
    back = simulate(p, (y[0], y[1], -y[2], -y[3]), 1.0, rtol=1e-12, atol=1e-12)
    yb = back.final_state
    np.testing.assert_allclose([yb[0], yb[1], -yb[2], -yb[3]], [q1, q2, w1, w2], atol=1e-6)


@SETTINGS
@given(a=lengths, b=lengths, m1=masses, m2=masses, alpha=skews, q1=angles, q2=angles, w1=speeds, w2=speeds)
def test_mirror_symmetry(a, b, m1, m2, alpha, q1, q2, w1, w2):
    """(phi, psi) -> (-phi, -psi) maps motions to motions; so does alpha -> -alpha (mirror i -> -i)."""
    p = Parameters(a=a, b=b, m1=m1, m2=m2, alpha=alpha, g=9.81)
    t1 = simulate(p, (q1, q2, w1, w2), 1.0, dt_out=0.25, rtol=1e-12, atol=1e-12)
    t2 = simulate(p, (-q1, -q2, -w1, -w2), 1.0, dt_out=0.25, rtol=1e-12, atol=1e-12)
    np.testing.assert_allclose(t2.y, -t1.y, atol=1e-7)
    t3 = simulate(p.replace(alpha=-alpha), (q1, q2, w1, w2), 1.0, dt_out=0.25, rtol=1e-12, atol=1e-12)
    np.testing.assert_allclose(t3.y, t1.y, atol=1e-7)


stiffness = st.floats(0.0, 20.0)
dampers = st.floats(0.0, 3.0)
limits = st.floats(0.5, 20.0)
actuations = st.sampled_from(["both", "acrobot", "pendubot"])
dampings = st.floats(0.0, 0.5)
bodies = st.floats(0.5, 2.0)


@SETTINGS
@given(a=bodies, b=bodies, m1=bodies, m2=bodies, alpha=skews, q1=angles, q2=angles, w1=speeds, w2=speeds,
       kp1=stiffness, kp2=stiffness, kd1=dampers, kd2=dampers, umax=limits, actuated=actuations, c=dampings)
def test_energy_balance_with_saturated_feedback(a, b, m1, m2, alpha, q1, q2, w1, w2, kp1, kp2, kd1, kd2, umax, actuated, c):
    """A PD law on each joint towards the upright (u = -K (x - x*), the angle errors wrapped),
    saturated, on any joints, with damping: E - W stays at E0, W the work of the inputs and the
    damping -- the balance the integrator must keep through the saturation's kinks and the jumps
    of the wrapped errors (which a PD law crosses, never slides along), at rtol 1e-11.  Bodies
    not too light: a stiff gain on a tiny inertia is a stiff problem, not this property."""
    from skewpend.numeric.control import Controller

    p = Parameters(a=a, b=b, m1=m1, m2=m2, alpha=alpha, g=9.81, c1=c, c2=0.5 * c)
    K = [[kp1, 0.0, kd1, 0.0], [0.0, kp2, 0.0, kd2]]
    ctl = Controller.feedback(K, (np.pi, 0.0, 0.0, 0.0), actuated=actuated, umax=umax)
    tr = simulate(p, (q1, q2, w1, w2), 2.0, controller=ctl, rtol=1e-11, atol=1e-11)
    assert tr.success
    u = tr.inputs()
    assert np.all(np.abs(u) <= umax + 1e-12)
    assert np.all(u[:, 0] == 0.0) if actuated == "acrobot" else True
    assert np.all(u[:, 1] == 0.0) if actuated == "pendubot" else True
    scale = max(np.max(np.abs(tr.energy)), 9.81 * (m1 + m2) * (a + b))
    assert np.max(np.abs(tr.energy - tr.work - tr.energy[0])) < 1e-7 * scale


@SETTINGS
@given(a=lengths, b=lengths, m1=masses, m2=masses, alpha=skews, q1=angles, q2=angles,
       torques=st.lists(st.floats(-5.0, 5.0), min_size=10, max_size=10))
def test_energy_balance_with_a_torque_table(a, b, m1, m2, alpha, q1, q2, torques):
    """u(t) from a table (piecewise linear): E - W = E0 and W = the integral of u . q' (trapezoid on
    a fine output grid: its error is O(dt^2) of the power's curvature, well under 1e-3 of the scale)."""
    from skewpend.numeric.control import Controller

    p = Parameters(a=a, b=b, m1=m1, m2=m2, alpha=alpha, g=9.81)
    ctl = Controller.table(np.linspace(0.0, 2.0, 5), np.reshape(torques, (5, 2)))
    tr = simulate(p, (q1, q2, 0.0, 0.0), 2.0, controller=ctl, dt_out=1e-3, rtol=1e-11, atol=1e-11)
    assert tr.success
    scale = max(np.max(np.abs(tr.energy)), 9.81 * (m1 + m2) * (a + b))
    assert np.max(np.abs(tr.energy - tr.work - tr.energy[0])) < 1e-7 * scale
    power = np.einsum("ij,ij->i", tr.inputs(), tr.y[:, 2:])
    W = np.concatenate([[0.0], np.cumsum(0.5 * (power[1:] + power[:-1]) * np.diff(tr.t))])
    assert np.max(np.abs(W - (tr.work - tr.work[0]))) < 1e-3 * scale
