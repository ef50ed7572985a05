"""A chain's figures and its comparison with MuJoCo, as the chain report uses them: the phase portraits
draw each joint's own speed, the frequency sweep draws every mode, MuJoCo simulates the exported chain."""

from __future__ import annotations

import math

import numpy as np
import pytest

pytest.importorskip("matplotlib")

import skewpend  # noqa: E402
from skewpend.symbolic.chain import Chain  # noqa: E402

TRIPLE = Chain.from_lists(3, length=[0.5, 0.4, 0.3], mass=[1.0, 0.8, 0.5],
                          axis=[(0, 0, 1), (0.5, 0, 1), (1, 0, 0)])
Y0 = (1.0, -0.3, 0.2, 0.0, 0.5, 0.0)


def test_each_phase_portrait_is_its_joints_angle_and_speed():
    from skewpend.views.figures import phase_figure

    tr = skewpend.simulate(TRIPLE, Y0, 2.0, dt_out=0.01)
    fig = phase_figure(tr)
    axes = [ax for ax in fig.axes if ax.get_visible()]
    assert len(axes) == 3
    for k, ax in enumerate(axes):
        x, y = (np.asarray(v, float) for v in ax.lines[0].get_data())
        keep = np.isfinite(x)
        # no wrap in 2 s of these swings: the path is the rows themselves
        assert keep.all() and np.allclose(y, tr.y[:, 3 + k], rtol=0, atol=1e-12)
        assert np.allclose(x, np.degrees(tr.y[:, k]), rtol=0, atol=1e-9)
        assert f"q_{{{k + 1}}}" in ax.get_xlabel() and "dot q" in ax.get_ylabel()


def test_the_double_pendulums_phase_portraits_are_unchanged():
    from skewpend.views.figures import phase_figure

    tr = skewpend.simulate(skewpend.reference_parameters(), (0.5, -0.3, 0.0, 0.2), 1.0, dt_out=0.01)
    fig = phase_figure(tr)
    for k, ax in enumerate(fig.axes):
        _, y = ax.lines[0].get_data()
        assert np.allclose(np.asarray(y, float), tr.y[:, 2 + k], atol=1e-12)
    assert "varphi" in fig.axes[0].get_xlabel() and "psi" in fig.axes[1].get_xlabel()


def test_a_chains_sweep_draws_every_mode():
    from skewpend.views.figures import plot_sweep

    sw = skewpend.sweep(TRIPLE, "tilt2", np.radians(np.linspace(0, 180, 7)))
    fig = plot_sweep(sw)
    ax = fig.axes[0]
    curves = [line for line in ax.lines if len(line.get_xdata()) == 7]
    assert len(curves) == 3
    for k, line in enumerate(curves):
        assert np.allclose(line.get_xdata(), np.linspace(0, 180, 7))  # degrees
        assert np.allclose(line.get_ydata(), sw.frequencies[:, k])
    assert "tilt2 [deg]" in ax.get_xlabel()


def test_mujoco_simulates_the_exported_chain(recursive_forms):
    pytest.importorskip("mujoco")
    from skewpend.interop.validation import compare_with_mujoco

    damped = TRIPLE.replace_link(3, damping=0.02, torque=0.05)
    rep = compare_with_mujoco(damped, Y0, 0.5, dt=1e-4)
    # RK4 at 1e-4 s: a local error of about (omega dt)^5 ~ 1e-15 a step, over 5000 steps
    assert list(rep.max_abs_diff) == ["q1", "q2", "q3", "dq1", "dq2", "dq3"]
    assert rep.mujoco.shape == (rep.samples, 6) and rep.max_difference <= 1e-9
    # the chain of two is the double pendulum, in MuJoCo too
    params = skewpend.reference_parameters()
    one = compare_with_mujoco(params, (0.5, -0.3, 0.0, 0.2), 0.5)
    two = compare_with_mujoco(Chain.from_parameters(params), (0.5, -0.3, 0.0, 0.2), 0.5)
    assert list(two.max_abs_diff) == ["phi", "psi", "dphi", "dpsi"]
    assert np.max(np.abs(one.mujoco - two.mujoco)) <= 1e-9
    with pytest.raises(skewpend.ParameterError, match="q1"):
        compare_with_mujoco(TRIPLE, (0.1, 0.2), 0.5)
    assert math.isfinite(rep.energy_drift)
