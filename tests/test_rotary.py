"""The rotary (Furuta) pendulum, Quanser's QUBE-Servo 2 (issue 54, item 4): ``examples/qube_servo2.toml``.

* Its equations against the open ``quanser-openai-driver`` simulator's ODE, re-typed below from its public
  source -- github.com/BlueRiverTech/quanser-openai-driver, ``gym_brt/quanser/qube_simulator.py``,
  ``diff_forward_model_ode``, commit 2695c3c4ae1804ad17d4565a62e9b450bd8ac6d6 (2023-01-17) -- at random states
  and voltages, to 1e-12 relative.  The conventions, mapped explicitly: the simulator's ``theta`` is ``q1`` (the
  run file's arm axis is the upward vertical), its ``alpha`` is ``q2 - pi`` (0 upright), its voltage ``Vm`` turns
  the arm the other way (``V = -Vm``: its torque is ``-kt Vm / Rm``).  One difference is no convention: the
  simulator's back-EMF term has the wrong sign (``tau = -(km (Vm - km theta')) / Rm`` is ``+km^2 theta' / Rm``
  at 0 V, a torque along the arm's motion that feeds it energy).  So the run file (the physical motor: damping
  ``Dr + kt km / Rm``) equals the simulator's ODE with the sign corrected (``tau = -kt (Vm + km theta') / Rm``),
  and the simulator's ODE as published equals the run file's chain with joint 1's damping ``Dr - kt km / Rm``.
* The run file's ``[motor]``: read into the damping and the torque limit, said on stderr; bad input refused.
* Swing-up and balance by the MPC within the voltage limit; identification from recorded angles (slow).
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from skewpend.config import Motor, Run
from skewpend.numeric.kernels import model_kernel, model_vector, model_vector_names
from skewpend.parsing import UsageError

ROOT = Path(__file__).resolve().parents[1]
RUN_FILE = ROOT / "examples" / "qube_servo2.toml"

# -- the simulator's ODE, re-typed from qube_simulator.py (commit 2695c3c, lines 9-49) ------------------------------
Rm = 8.4  # Resistance
kt = 0.042  # Current-torque (N-m/A)
km = 0.042  # Back-emf constant (V-s/rad)
mr = 0.095  # Mass (kg)
Lr = 0.085  # Total length (m)
Jr = mr * Lr ** 2 / 12  # Moment of inertia about pivot (kg-m^2)
Dr = 0.00027  # Equivalent viscous damping coefficient (N-m-s/rad)
mp = 0.024  # Mass (kg)
Lp = 0.129  # Total length (m)
Jp = mp * Lp ** 2 / 12  # Moment of inertia about pivot (kg-m^2)
Dp = 0.00005  # Equivalent viscous damping coefficient (N-m-s/rad)
g = 9.81  # Gravity constant
VMAX = 3.0  # gym_brt/envs/qube_base_env.py: MAX_MOTOR_VOLTAGE = 3


def diff_forward_model_ode(state, t, action, dt, corrected=False):
    theta, alpha, theta_dot, alpha_dot = state
    Vm = action
    tau = -(km * (Vm - km * theta_dot)) / Rm  # torque
    if corrected:  # (not in the source) the back-EMF opposing the arm's motion
        tau = -(kt * (Vm + km * theta_dot)) / Rm
    # fmt: off
    # From Rotary Pendulum Workbook
    theta_dot_dot = (-Lp*Lr*mp*(-8.0*Dp*alpha_dot + Lp**2*mp*theta_dot**2*np.sin(2.0*alpha) + 4.0*Lp*g*mp*np.sin(alpha))*np.cos(alpha) + (4.0*Jp + Lp**2*mp)*(4.0*Dr*theta_dot + Lp**2*alpha_dot*mp*theta_dot*np.sin(2.0*alpha) + 2.0*Lp*Lr*alpha_dot**2*mp*np.sin(alpha) - 4.0*tau))/(4.0*Lp**2*Lr**2*mp**2*np.cos(alpha)**2 - (4.0*Jp + Lp**2*mp)*(4.0*Jr + Lp**2*mp*np.sin(alpha)**2 + 4.0*Lr**2*mp))
    alpha_dot_dot = (2.0*Lp*Lr*mp*(4.0*Dr*theta_dot + Lp**2*alpha_dot*mp*theta_dot*np.sin(2.0*alpha) + 2.0*Lp*Lr*alpha_dot**2*mp*np.sin(alpha) - 4.0*tau)*np.cos(alpha) - 0.5*(4.0*Jr + Lp**2*mp*np.sin(alpha)**2 + 4.0*Lr**2*mp)*(-8.0*Dp*alpha_dot + Lp**2*mp*theta_dot**2*np.sin(2.0*alpha) + 4.0*Lp*g*mp*np.sin(alpha)))/(4.0*Lp**2*Lr**2*mp**2*np.cos(alpha)**2 - (4.0*Jp + Lp**2*mp)*(4.0*Jr + Lp**2*mp*np.sin(alpha)**2 + 4.0*Lr**2*mp))
    # fmt: on
    return np.array([theta_dot, alpha_dot, theta_dot_dot, alpha_dot_dot])


# -- the mapping -----------------------------------------------------------------------------------------------------
def to_simulator(y):
    """skewpend's state ``(q1, q2, q1', q2')`` as the simulator's ``(theta, alpha, theta', alpha')``."""
    return np.array([y[0], y[1] - np.pi, y[2], y[3]])


def rhs_function(chain, motor):
    """The chain's right-hand side ``(y, V) -> (q', q'')`` (its compiled kernel, as :func:`skewpend.simulate`
    integrates it) with the motor at voltage ``V``: its input ``kt V / R`` the joint's constant torque (``tau1``
    in the kernel's run-time parameters), its back-EMF in the joint's damping."""
    kernel = model_kernel(chain)
    p = np.array(model_vector(chain, kernel.form), dtype=float)
    tau = model_vector_names(chain, kernel.form).index(f"tau{motor.joint}")
    assert p[tau] == 0.0
    out = np.zeros(2 * chain.n + 1)

    def f(y, V):
        p[tau] = motor.gain * V
        kernel.rhs(np.r_[y, 0.0], p, out)
        return out[:2 * chain.n].copy()

    return f


def rotary():
    run = Run("simulate", str(RUN_FILE))
    return run.chain(), run.motor


def _random_states(rng, count):
    """Random states over every angle, speeds up to 20 rad/s (the arm) and 30 rad/s (the pendulum), voltages
    within the amplifier's +-10 V."""
    y = np.column_stack([rng.uniform(-np.pi, np.pi, count), rng.uniform(-np.pi, np.pi, count),
                         rng.uniform(-20, 20, count), rng.uniform(-30, 30, count)])
    return y, rng.uniform(-10, 10, count)


def _worst(chain, motor, corrected):
    rng = np.random.default_rng(54)
    ys, Vs = _random_states(rng, 200)
    worst, f = 0.0, rhs_function(chain, motor)
    for y, V in zip(ys, Vs):
        ours = f(y, V)
        theirs = diff_forward_model_ode(to_simulator(y), 0.0, -V, 0.0, corrected=corrected)  # V = -Vm
        worst = max(worst, float(np.max(np.abs(ours - theirs)) / np.max(np.abs(theirs))))
    return worst


def test_the_run_file_is_the_simulators_ode_with_the_back_emf_opposing_the_motion():
    """The run file's chain and motor equal the simulator's equations (the back-EMF's sign corrected) to 1e-12
    relative (the state derivative's largest entry) at 200 random states and voltages."""
    chain, motor = rotary()
    assert _worst(chain, motor, corrected=True) < 1e-12


def test_the_simulators_ode_as_published_is_the_chain_with_the_back_emf_reversed():
    """The simulator's ODE as published: the run file's chain with joint 1's damping ``Dr - kt km / Rm`` (its
    back-EMF pushing), to 1e-12 relative; with the run file's (physical) damping it differs by far more."""
    chain, motor = rotary()
    assert chain.links[0].damping == pytest.approx(Dr + kt * km / Rm, rel=1e-15)
    published = chain.replace_link(1, damping=Dr - kt * km / Rm)
    assert _worst(published, motor, corrected=False) < 1e-12
    assert _worst(chain, motor, corrected=False) > 1e-3


def test_the_back_emf_of_the_published_simulator_feeds_energy():
    """Why the sign is a mistake and not a convention: at 0 V the simulator's motor torque times the arm's speed
    is ``+km^2 theta'^2 / Rm > 0`` (power into the arm from a motor at rest), at any sign of ``theta``."""
    for theta_dot in (-3.0, 0.5, 7.0):
        tau = -(km * (0.0 - km * theta_dot)) / Rm
        assert tau * theta_dot > 0


@pytest.mark.slow
def test_the_upright_rest_of_a_cyclic_arm_is_an_equilibrium():
    """The arm's angle is cyclic (every q1 an equilibrium: the potential's Hessian is singular everywhere): the
    upright rest given by its angles is found (Newton needs no step at a root), its linearisation has the arm's
    zero stiffness and one unstable direction, and the search lists the hanging and upright rests as degenerate."""
    from skewpend.analysis.equilibria import equilibria, equilibrium_at

    chain, _ = rotary()
    top = equilibrium_at(chain, [0.0, np.pi])
    assert top.label == "down-up" and top.morse_index == 1
    assert top.K[0, 0] == 0.0 and top.q[1] == pytest.approx(np.pi, abs=1e-12)
    assert top.potential == pytest.approx(mp * g * Lp, rel=1e-12)
    found = equilibria(chain)
    assert {p.label for p in found.points} == {"down-down", "down-up"}
    with pytest.raises(Exception, match="not an equilibrium"):
        equilibrium_at(chain, [0.0, 1.0])


# -- the run file's motor ----------------------------------------------------------------------------------------------
def test_the_motor_is_read_into_the_damping_and_the_torque_limit():
    chain, motor = rotary()
    assert motor == Motor(joint=1, resistance=8.4, torque_constant=0.042, back_emf_constant=0.042, voltage_limit=3.0)
    assert motor.damping == kt * km / Rm and motor.gain == kt / Rm
    assert motor.torque_limit == pytest.approx(kt * VMAX / Rm, rel=1e-15)
    assert chain.links[0].damping == pytest.approx(Dr + kt * km / Rm, rel=1e-15)
    assert chain.links[1].damping == Dp
    # its torque is kt (V - km q') / R: the input gain times V, the damping times the speed
    assert motor.torque(2.0, 5.0) == pytest.approx(motor.gain * 2.0 - motor.damping * 5.0, rel=1e-15)
    assert motor.voltage(motor.torque_limit) == pytest.approx(VMAX, rel=1e-15)


def test_the_motor_is_said_once_in_a_note():
    run = Run("simulate", str(RUN_FILE))
    notes = [n for n in run.notes if "[motor]" in n]
    assert len(notes) == 1
    assert "0.00021 N m s added to joint 1's damping" in notes[0] and "|u| <= 0.015 N m" in notes[0]


def _file(tmp_path, motor: str, links: bool = True) -> str:
    text = RUN_FILE.read_text()
    head, _, tail = text.partition("\n[motor]\n")
    tail = tail[tail.index("[initial]"):]
    if not links:
        head = "[parameters]\na = 1.0\n"
    path = tmp_path / "rig.toml"
    path.write_text(head + "\n[motor]\n" + motor + "\n" + tail)
    return str(path)


GOOD = "joint = 1\nresistance = 8.4\ntorque_constant = 0.042\nback_emf_constant = 0.042\nvoltage_limit = 3\n"


@pytest.mark.parametrize("change, words", [
    (("joint = 1", "joint = 3"), "[motor] joint = 3, but the chain has 2 joints"),
    (("joint = 1", "joint = 0"), "[motor] joint must be a joint's number"),
    (("joint = 1", "joint = 1.5"), "[motor] joint must be a joint's number"),
    (("joint = 1", "joint = true"), "[motor] joint must be a joint's number"),
    (("resistance = 8.4", "resistance = -8.4"), "[motor] resistance must be a finite number > 0"),
    (("voltage_limit = 3", "voltage_limit = \"3V\""), "[motor] voltage_limit must be a finite number > 0"),
    (("back_emf_constant = 0.042\n", ""), "[motor] needs back_emf_constant"),
])
def test_bad_motors_are_one_line_naming_the_key(tmp_path, change, words):
    path = _file(tmp_path, GOOD.replace(*change))
    with pytest.raises(UsageError) as err:
        Run("simulate", path)
    assert words in str(err.value) and str(err.value).startswith(path) and "\n" not in str(err.value)


def test_an_unknown_motor_key_is_refused_with_the_keys(tmp_path):
    from skewpend.errors import ParameterError

    path = _file(tmp_path, GOOD + "inductance = 0.001\n")
    with pytest.raises(ParameterError, match="unknown key.*inductance.*in \\[motor\\]"):
        Run("simulate", path)


def test_a_motor_without_links_is_refused(tmp_path):
    with pytest.raises(UsageError, match=r"\[motor\] drives a joint of a chain of links"):
        Run("simulate", _file(tmp_path, GOOD, links=False))


def test_the_motor_is_exported_as_a_voltage_actuator_that_mujoco_runs_as_skewpend(tmp_path):
    """``skewpend export`` of the rig: MJCF with the motor as joint 1's actuator whose control is the voltage (gain
    kt/R, ctrlrange +-Vmax) and its back-EMF in the joint's damping -- MuJoCo's accelerations at random states and
    voltages equal skewpend's with the motor's torque kt (V - km q1') / R to 1e-10 relative; read back, the joint is
    actuated with the torque limit kt Vmax / R (joint 2 its unlimited constant torque). URDF: the joint's effort limit kt Vmax / R (read back as actuated)
    and its velocity Vmax / km."""
    mujoco = pytest.importorskip("mujoco")
    from helpers import run_cli

    from skewpend.interop.importer import read_mjcf, read_urdf

    motor = Run("control", str(RUN_FILE)).motor
    for suffix in ("xml", "urdf"):
        r = run_cli(["export", "--config", str(RUN_FILE), "-o", str(tmp_path / f"qube.{suffix}")])
        assert r.code == 0, r.err
        assert "skewpend export writes it as joint 1's actuator" in r.err and "Traceback" not in r.err
    model = mujoco.MjModel.from_xml_path(str(tmp_path / "qube.xml"))
    data = mujoco.MjData(model)
    from skewpend.interop.export import mujoco_compatible

    params = Run("simulate", str(RUN_FILE)).parameters()  # the back-EMF in joint 1's damping
    exported = mujoco_compatible(params)  # with the exporter's tiny axial inertias, which MuJoCo needs
    kernel, p0 = model_kernel(exported), np.array(model_vector(exported), dtype=float)
    names = model_vector_names(exported)
    rng = np.random.default_rng(7)
    for _ in range(5):
        y = np.r_[rng.uniform(-np.pi, np.pi, 2), rng.uniform(-5, 5, 2)]
        volts = rng.uniform(-motor.voltage_limit, motor.voltage_limit)
        data.qpos[:], data.qvel[:], data.ctrl[:] = y[:2], y[2:], [volts, 0.0]
        mujoco.mj_forward(model, data)
        p = p0.copy()
        p[names.index("tau1")] += motor.gain * volts  # kt V / R; the back-EMF -kt km q1' / R is the damping
        out = np.zeros(5)
        kernel.rhs(np.append(y, 0.0), p, out)
        np.testing.assert_allclose(data.qacc, out[2:4], rtol=1e-10, atol=1e-10 * np.abs(out[2:4]).max())
    back = read_mjcf(tmp_path / "qube.xml")  # joint 2 keeps the exporter's unlimited constant-torque actuator
    assert back.actuated == (1, 2) and back.torque_limits[1] is None
    assert back.torque_limits[0] == pytest.approx(motor.torque_limit, rel=1e-15)
    assert back.chain.links[0].damping == pytest.approx(params.as_chain().links[0].damping, rel=1e-15)
    urdf = read_urdf(tmp_path / "qube.urdf")
    assert urdf.actuated == (1,) and urdf.torque_limits[0] == pytest.approx(motor.torque_limit, rel=1e-15)
    assert f'velocity="{motor.voltage_limit / motor.back_emf_constant!r}"' in (tmp_path / "qube.urdf").read_text()
    from dataclasses import replace

    from skewpend.errors import ParameterError
    from skewpend.interop.export import to_mjcf, to_urdf

    for writer in (to_mjcf, to_urdf):
        with pytest.raises(ParameterError, match=r"^motor must be a skewpend.config.Motor \(a run file's \[motor\]\) or None, got 'x'$"):
            writer(params, motor="x")
        with pytest.raises(ParameterError, match=r"^the motor drives joint 3, but the model has 2 joint\(s\)$"):
            writer(params, motor=replace(motor, joint=3))


def test_the_command_line_refuses_a_bad_motor_in_one_line_exit_2(tmp_path):
    from helpers import run_cli

    ran = run_cli(["simulate", "--config", _file(tmp_path, GOOD.replace("joint = 1", "joint = 3")), "--t-end", "1"])
    lines = ran.err.strip().splitlines()
    assert ran.code == 2 and len(lines) == 1 and lines[0].startswith("skewpend: error:"), ran.report()
    assert "[motor] joint = 3, but the chain has 2 joints" in lines[0]


# -- identification from recorded angles ------------------------------------------------------------------------------
#: The recording: the rig driven from hanging at rest by a seeded multisine voltage within the driver's 3 V, 10 s at
#: 500 Hz, its two encoder angles with seeded Gaussian noise of NOISE rad (the QUBE's 2048-count encoders quantise
#: to 3.1e-3 rad: a uniform error of 0.9e-3 rad RMS; 0.5e-3 rad is a filtered encoder's).
NOISE = 5e-4


def record(path, seed=7, seconds=10.0, dt=0.002):
    """Simulate the run file's rig under a multisine voltage and write its angles (noisy) and the motor's input
    torque ``kt V / R`` as a CSV ``t, q1, q2, tau1, tau2`` (the back-EMF is the joint's damping the fit estimates)."""
    import skewpend
    from skewpend.numeric.control import Controller

    chain, motor = rotary()
    rng = np.random.default_rng(seed)
    t = np.arange(0.0, seconds + dt / 2, dt)
    freqs = np.array([0.4, 0.9, 1.7, 2.6, 3.5, 5.0])
    phases = rng.uniform(0, 2 * np.pi, freqs.size)
    V = np.sum(np.sin(2 * np.pi * freqs[:, None] * t + phases[:, None]), axis=0)
    V *= 0.93 * motor.voltage_limit / np.max(np.abs(V))
    law = Controller.table(t, motor.gain * V, actuated=(motor.joint,), nq=2)
    run = skewpend.simulate(chain, [0.0, 0.0, 0.0, 0.0], seconds, dt_out=dt, controller=law, rtol=1e-11, atol=1e-11)
    assert run.ok, run.message
    ts = np.asarray(run.t)
    q = np.asarray(run.y)[:, :2] + rng.normal(0.0, NOISE, (ts.size, 2))
    u = np.interp(ts, t, motor.gain * V)
    np.savetxt(path, np.column_stack([ts, q, u, np.zeros_like(u)]), delimiter=",", header="t,q1,q2,tau1,tau2",
               comments="", fmt="%.12g")
    return chain, motor, float(np.max(np.abs(V)))


def start_file(path):
    """The run file with every inertial parameter and damping off by 20-100 % (the fit's start), its motor kept."""
    text = RUN_FILE.read_text()
    for old, new in (("inertia = [0, 4.055691666666668e-05, 4.055691666666668e-05]", "inertia = [0, 5e-05, 5e-05]"),
                     ("inertia = [3.3282000000000004e-05, 1.6641000000000002e-05, 1.6641000000000002e-05]",
                      "inertia = [2.5e-05, 1.25e-05, 1.25e-05]"),
                     ("damping = 0.00027 ", "damping = 0.0005 "), ("damping = 5e-05 ", "damping = 1e-04 "),
                     ("com = [0, 0.0645, 0]", "com = [0, 0.06, 0]")):
        assert old in text
        text = text.replace(old, new)
    path.write_text(text)
    return str(path)


@pytest.mark.slow
def test_identify_recovers_the_rigs_damping_and_inertias_from_its_recorded_angles(tmp_path):
    """``skewpend identify`` on the recording, from a start 20-100 % off: every base parameter's truth within its
    reported 95 % interval widened twice (4 standard errors: the intervals are cluster-robust estimates over five
    2 s blocks, themselves uncertain), and the nonzero ones within 1 % (the noise gives 0.03-0.2 %); the arm's
    joint damping is the bearing's Dr plus the motor's back-EMF kt km / R, so Dr = c1 - kt km / R."""
    from helpers import run_cli

    import skewpend
    from skewpend.analysis.identify import ChainTerms, chain_terms

    chain, motor, vmax = record(tmp_path / "qube.csv")
    assert vmax <= motor.voltage_limit
    ran = run_cli(["identify", tmp_path / "qube.csv", "--format", "csv", "--columns",
                   "t=t,phi=q1,psi=q2,tau1=tau1,tau2=tau2", "--config", start_file(tmp_path / "start.toml"),
                   "--netcdf", tmp_path / "fit.nc", "--out", tmp_path / "fit.toml"])
    assert ran.code == 0, ran.report()
    assert "[motor] on joint 1: back-EMF kt km/R = 0.00021 N m s" in ran.err
    result = skewpend.open_result(tmp_path / "fit.nc")
    terms = chain_terms(chain)
    truth = dict(zip(terms.names, terms.values(ChainTerms.standard(chain))))
    names = list(result.names)
    assert set(names) == set(truth) and len(names) == 10
    for name, value, (lo, hi) in zip(names, result.values, result.intervals):
        half = (hi - lo) / 2
        assert abs(value - truth[name]) <= 2 * half, (name, value, truth[name], lo, hi)
        if abs(truth[name]) > 1e-6:
            assert value == pytest.approx(truth[name], rel=1e-2), name
    fitted = dict(zip(names, result.values))
    assert fitted["c1"] - motor.damping == pytest.approx(Dr, rel=1e-2)
    assert fitted["c2"] == pytest.approx(Dp, rel=1e-2)
    # the written run file is the fitted model: its base parameters are the table's
    back = Run("simulate", str(tmp_path / "fit.toml")).chain()
    again = dict(zip(terms.names, terms.values(ChainTerms.standard(back))))
    for name in names:
        assert again[name] == pytest.approx(fitted[name], rel=1e-6, abs=1e-12), name


# -- swing-up and balance by the model-predictive controller ----------------------------------------------------------
def _mpc_run(settings, y0, t_end, volts=None):
    """The MPC on the run file's rig within its motor's limit (``umax = kt Vmax / R``), sampled every 2 ms and held
    (as :meth:`MPC.controller`), its torques recorded unsaturated by anything but the MPC itself: the states, the
    torques and the times each torque was applied from.  ``volts``: another limit than the run file's."""
    import skewpend
    from skewpend.analysis.mpc import MPC, PERIOD
    from skewpend.numeric.control import Controller

    chain, motor = rotary()
    if volts is not None:
        motor = Motor(motor.joint, motor.resistance, motor.torque_constant, motor.back_emf_constant, volts)
    mpc = MPC(chain, actuated=(1,), umax=motor.torque_limit, goal=[0.0, np.pi], settings=settings)
    applied = {}

    def law(t, x):
        k = int(np.floor(t / PERIOD + 0.5))
        if k not in applied:
            applied[k] = mpc(k * PERIOD, x)
        return applied[k]

    run = skewpend.simulate(chain, y0, t_end, dt_out=0.01, controller=Controller.function(law, actuated=(1,), nq=2,
                                                                                           hold=PERIOD))
    assert run.ok, run.message
    u = np.array([applied[k] for k in sorted(applied)])
    return np.asarray(run.t), np.asarray(run.y), u, motor, mpc


def _from_upright(y):
    return np.abs((y[:, 1] % (2 * np.pi)) - np.pi)


@pytest.mark.slow
@pytest.mark.parametrize("settings", [{}, dict(horizon=0.1, nodes=5, energy=0.0)], ids=["defaults", "0.1 s"])
def test_the_mpc_balances_the_pendulum_within_the_voltage_limit(settings):
    """From 0.05 rad off upright at rest, the MPC -- its defaults (the horizon 4.7 time constants of the top's
    unstable mode: 0.32 s here) or a 0.1 s horizon of 5 nodes without the energy term -- holds the pendulum: within
    0.06 rad of upright from 0.5 s on, 1e-3 rad at 2 s, the arm back within 0.01 rad of where it started; its every
    torque within kt Vmax / R (3 V) and no fallback."""
    from skewpend.analysis.mpc import MPCSettings

    t, y, u, motor, mpc = _mpc_run(MPCSettings(**settings), [0.0, np.pi - 0.05, 0.0, 0.0], 2.0)
    off = _from_upright(y)
    assert np.all(off[t >= 0.5] < 0.06) and off[-1] < 1e-3
    assert abs(y[-1, 0]) < 0.01
    assert np.max(np.abs(u[:, 0])) <= motor.torque_limit * (1 + 1e-9) and np.all(u[:, 1] == 0)
    assert np.max(np.abs(motor.voltage(u[:, 0]))) <= motor.voltage_limit * (1 + 1e-9)
    assert mpc.fallbacks == 0


# Issue 54's goal -- from hanging up and held from 2 s on within the driver's 3 V -- is met by the optimal swing-up
# tracked (trajopt.swingup_tracking; tests/test_rotary_swingup.py); the MPC alone does not swing it up within 3 V
# (docs/guide/rotary-pendulum.md, benchmarks/bench_rotary_mpc.py).


@pytest.mark.slow
def test_with_10_volts_the_mpc_swings_the_pendulum_up_within_2_s():
    """Not the run file's limit (the driver's 3 V): with 10 V (0.05 N m) ``mpc_swingup`` with a 0.15 s horizon (6
    nodes) swings the pendulum up from hanging (nudged 0.05 rad) and holds it -- within 0.1 rad of upright from 1 s
    on (measured 0.64 s; 0.64-0.83 s from nudges of -0.05, 0.02 and 0.1 rad), 1e-3 rad at 2 s --, every torque the
    controller applied within the limit, the arm under a third of a turn.  (8 V: up at 1.4 s after a turn of the
    arm; 6 V and 3 V: not; benchmarks/bench_rotary_mpc.py --volts 10.)"""
    from skewpend.analysis.mpc import MPCSettings, mpc_swingup

    chain, motor = rotary()
    umax = motor.gain * 10.0
    r = mpc_swingup(chain, target=[0.0, np.pi], actuated=(1,), umax=umax, y0=[0.0, 0.05, 0.0, 0.0], t_end=2.0,
                    settings=MPCSettings(horizon=0.15, nodes=6))
    t, y = np.asarray(r.trajectory.t), np.asarray(r.trajectory.y)
    off = _from_upright(y)
    assert np.all(off[t >= 1.0] < 0.1) and off[-1] < 1e-3
    assert np.max(np.abs(y[:, 0])) < 2 * np.pi / 3
    kernel = model_kernel(chain)
    u = r.controller.inputs(kernel, np.asarray(model_vector(chain, kernel.form), dtype=float), t, y)
    assert np.max(np.abs(u[:, 0])) <= umax * (1 + 1e-9) and np.max(np.abs(u[:, 0])) > 0.9 * umax
    assert r.mpc.fallbacks == 0
