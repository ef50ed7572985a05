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
