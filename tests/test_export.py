"""MJCF/URDF export: MuJoCo simulates the same system as skewpend's own equations.

The reference is skewpend's symbolic ``M(q) q'' = f(q, q')`` for the exported system
(``mujoco_compatible(params)``: explicit bodies with the tiny axial inertia), lambdified and
integrated by SciPy's DOP853 at rtol = atol = 1e-12.  MuJoCo (RK4, dt = 1e-4) must agree to
1e-6 in every state component over 2 s of large swings.  Also checked: what MuJoCo compiles
from the files (masses, inertia eigenvalues, axes, damping, torques, options), the URDF as XML
and as compiled by MuJoCo, the tiny-inertia rule, file writing and argument errors.
"""

from __future__ import annotations

import subprocess
import sys
import xml.etree.ElementTree as ET

import numpy as np
import pytest
import sympy as sp
from scipy.integrate import solve_ivp
from scipy.spatial.transform import Rotation

from skewpend import NotNumericError, ParameterError, Parameters, SkewpendError, derive
from skewpend.symbolic.derivation import SYMBOLS
from skewpend.errors import IntegrationError
from skewpend.interop.export import (
    MujocoMissingError,
    mujoco_compatible,
    mujoco_trajectory,
    to_mjcf,
    to_urdf,
    write_model,
)

mujoco = pytest.importorskip("mujoco")

T_END = 2.0
DT = 1e-4
N_OUT = 401  # every 50th MuJoCo step
TOL = 1e-6


# -- the reference: skewpend's equations -------------------------------------------------------
def _reference(params: Parameters, y0, t_eval) -> np.ndarray:
    eom = derive(mujoco_compatible(params))
    args = [SYMBOLS[n] for n in ("phi", "psi", "dphi", "dpsi")]
    assert (eom.mass_matrix.free_symbols | eom.forcing.free_symbols) <= set(args)
    mass = sp.lambdify(args, eom.mass_matrix, "numpy")
    force = sp.lambdify(args, eom.forcing, "numpy")

    def rhs(t, y):
        M = np.array(mass(*y), dtype=float)
        f = np.array(force(*y), dtype=float).reshape(2)
        return np.concatenate([y[2:], np.linalg.solve(M, f)])

    sol = solve_ivp(rhs, (0.0, t_eval[-1]), y0, method="DOP853", rtol=1e-12, atol=1e-12, t_eval=t_eval)
    assert sol.success, sol.message
    return sol.y.T


def _random_inertia(rng, mass, size):
    """A rigid body's tensor about its centre of mass: a box, turned (off-diagonal terms)."""
    x, y, z = size
    principal = mass / 12 * np.array([y * y + z * z, x * x + z * z, x * x + y * y])
    R = Rotation.from_rotvec(rng.uniform(-1, 1, 3)).as_matrix()
    m = R @ np.diag(principal) @ R.T
    return tuple(map(tuple, 0.5 * (m + m.T)))


def _cases():
    rng = np.random.default_rng(20240611)

    def scalars():
        return dict(
            a=rng.uniform(0.4, 1.5), b=rng.uniform(0.4, 1.5),
            m1=rng.uniform(0.3, 2.0), m2=rng.uniform(0.3, 2.0), g=rng.uniform(8.0, 12.0),
        )

    def state():
        return np.r_[rng.uniform(-1.5, 1.5, 2), rng.uniform(-2.0, 2.0, 2)]

    cases = [
        ("thin rods, alpha = 0 (planar)", Parameters(alpha=0.0, **scalars()), state()),
        ("thin rods, alpha = 90 deg", Parameters(alpha=np.pi / 2, **scalars()), state()),
        ("thin rods, random alpha", Parameters(alpha=rng.uniform(0, np.pi), **scalars()), state()),
        ("thin rods, negative alpha", Parameters(alpha=-rng.uniform(0, np.pi / 2), **scalars()), state()),
    ]
    s = scalars()
    general = Parameters(
        **s,
        com1=(rng.uniform(-0.05, 0.05), 0.45 * s["a"], rng.uniform(-0.05, 0.05)),
        com2=(0.08, 0.6 * s["b"], -0.05),
        inertia1=_random_inertia(rng, s["m1"], (0.06, s["a"], 0.04)),
        inertia2=_random_inertia(rng, s["m2"], (0.1, s["b"], 0.05)),
        axis1=tuple(rng.uniform(-0.3, 0.3, 2)) + (1.0,),
        axis2=(1.0, rng.uniform(-0.4, 0.4), rng.uniform(0.2, 1.0)),
    )
    assert abs(general.inertia2[0][1]) > 1e-4 and abs(general.inertia2[1][2]) > 1e-4
    cases.append(("general bodies and axes", general, state()))
    cases.append((
        "damping and constant torques",
        Parameters(alpha=rng.uniform(0.2, 1.4), c1=rng.uniform(0.05, 0.5), c2=rng.uniform(0.05, 0.5),
                   tau1=rng.uniform(0.2, 1.0), tau2=-rng.uniform(0.2, 1.0), **scalars()),
        state(),
    ))
    s = scalars()
    cases.append((
        "point-mass bob, damping, torque, alpha = 90 deg",
        Parameters(alpha=np.pi / 2, c2=0.1, tau1=-0.3, com2=(0.0, s["b"], 0.0),
                   inertia2=((0.0, 0.0, 0.0),) * 3, **s),
        state(),
    ))
    return cases


CASES = _cases()
GENERAL = dict((name, p) for name, p, _ in CASES)["general bodies and axes"]
TORQUES = dict((name, p) for name, p, _ in CASES)["damping and constant torques"]


# -- trajectories ------------------------------------------------------------------------------
@pytest.mark.slow
@pytest.mark.parametrize("name, params, y0", CASES, ids=[c[0] for c in CASES])
def test_mujoco_trajectory_matches_skewpend_equations(name, params, y0):
    t, y = mujoco_trajectory(params, y0, T_END, dt=DT, n_out=N_OUT)
    assert t.shape == (N_OUT,) and y.shape == (N_OUT, 4)
    assert t[0] == 0.0 and t[-1] == pytest.approx(T_END)
    np.testing.assert_array_equal(y[0], y0)
    ref = _reference(params, y0, t)
    err = np.abs(y - ref).max(axis=0)
    print(f"{name}: max |MuJoCo - skewpend| (phi, psi, dphi, dpsi) = {err}")
    assert err.max() < TOL, f"{name}: {err}"
    # large swings, not a linear test
    assert np.abs(y[:, :2]).max() > 0.8


@pytest.mark.slow
def test_comparison_detects_a_slightly_different_model():
    """Negative control: a change of 1e-3 rad in alpha is far outside the tolerance."""
    name, params, y0 = CASES[2]
    t, y = mujoco_trajectory(params, y0, 1.0, dt=DT, n_out=101)
    ref = _reference(params.replace(alpha=params.alpha + 1e-3), y0, t)
    assert np.abs(y - ref).max() > 100 * TOL


def test_every_step_returned_by_default_and_torques_need_nothing_at_run_time():
    t, y = mujoco_trajectory(TORQUES, [0.3, -0.2, 0.0, 0.5], 0.01, dt=1e-3)
    assert t.shape == (11,) and y.shape == (11, 4)
    np.testing.assert_allclose(t, np.arange(11) * 1e-3, rtol=0, atol=1e-15)
    t2, y2 = mujoco_trajectory(TORQUES, [0.3, -0.2, 0.0, 0.5], 0.01, dt=1e-3, n_out=3)
    np.testing.assert_allclose(t2, [0.0, 0.005, 0.01], atol=1e-15)
    np.testing.assert_allclose(y2, y[[0, 5, 10]], rtol=0, atol=1e-15)


# -- what MuJoCo compiles from the MJCF --------------------------------------------------------
def _tensor(m):
    return np.array(m, dtype=float)


@pytest.mark.parametrize("params", [GENERAL, TORQUES], ids=["general", "thin-rods"])
def test_mjcf_compiles_to_the_right_bodies_joints_and_options(params):
    xml = to_mjcf(params, timestep=2e-4)
    root = ET.fromstring(xml)  # well-formed XML
    assert root.tag == "mujoco"
    model = mujoco.MjModel.from_xml_string(xml)
    p = mujoco_compatible(params)
    assert (model.nbody, model.njnt, model.nq, model.nv, model.nu) == (3, 2, 2, 2, 2)
    np.testing.assert_allclose(model.body_mass, [0.0, p.m1, p.m2], rtol=1e-15)
    np.testing.assert_allclose(model.body_pos[2], [0.0, p.a, 0.0], rtol=1e-15)
    for body, com, tensor in ((1, p.com1, p.inertia1), (2, p.com2, p.inertia2)):
        np.testing.assert_allclose(model.body_ipos[body], com, rtol=1e-12, atol=1e-15)
        # MuJoCo diagonalises fullinertia: body_inertia are the eigenvalues of our tensor,
        # and turning diag(body_inertia) by body_iquat gives the tensor back
        I = _tensor(tensor)
        scale = np.abs(I).max()
        np.testing.assert_allclose(np.sort(model.body_inertia[body]), np.linalg.eigvalsh(I), rtol=0, atol=1e-12 * scale)
        R = np.empty(9)
        mujoco.mju_quat2Mat(R, model.body_iquat[body])
        R = R.reshape(3, 3)
        np.testing.assert_allclose(R @ np.diag(model.body_inertia[body]) @ R.T, I, rtol=0, atol=1e-12 * scale)
    axis1 = p.axis1 if p.axis1 is not None else (0, 0, 1)
    axis2 = p.axis2 if p.axis2 is not None else (np.sin(p.alpha), 0, np.cos(p.alpha))
    np.testing.assert_allclose(model.jnt_axis, [axis1, axis2], rtol=0, atol=1e-15)
    np.testing.assert_allclose(model.jnt_pos, 0.0)
    assert list(model.jnt_type) == [mujoco.mjtJoint.mjJNT_HINGE] * 2
    assert not model.jnt_limited.any()
    np.testing.assert_allclose(model.dof_damping, [p.c1, p.c2], rtol=1e-15)
    np.testing.assert_array_equal(model.dof_armature, 0.0)
    np.testing.assert_array_equal(model.dof_frictionloss, 0.0)
    np.testing.assert_array_equal(model.jnt_stiffness, 0.0)
    np.testing.assert_allclose(model.opt.gravity, [0.0, p.g, 0.0], rtol=1e-15)
    assert model.opt.timestep == 2e-4
    assert model.opt.integrator == mujoco.mjtIntegrator.mjINT_RK4
    assert model.opt.disableflags & mujoco.mjtDisableBit.mjDSBL_CONTACT
    assert not model.geom_contype.any() and not model.geom_conaffinity.any()
    # constant torques through the actuators, damping as passive force, nothing set by hand
    data = mujoco.MjData(model)
    data.qpos[:] = [0.4, -0.7]
    data.qvel[:] = [1.3, -0.6]
    mujoco.mj_forward(model, data)
    np.testing.assert_allclose(data.qfrc_actuator, [p.tau1, p.tau2], rtol=1e-15, atol=0)
    np.testing.assert_allclose(data.qfrc_passive, [-p.c1 * 1.3, p.c2 * 0.6], rtol=1e-14, atol=1e-15)
    np.testing.assert_array_equal(data.qfrc_applied, 0.0)


def test_mjcf_mass_matrix_is_skewpends():
    """MuJoCo's joint-space inertia at a random configuration equals skewpend's M(q)."""
    p = GENERAL
    model = mujoco.MjModel.from_xml_string(to_mjcf(p))
    data = mujoco.MjData(model)
    eom = derive(mujoco_compatible(p))
    M = sp.lambdify([SYMBOLS["phi"], SYMBOLS["psi"]], eom.mass_matrix, "numpy")
    for q in ([0.0, 0.0], [0.7, -1.9], [-2.5, 0.4]):
        data.qpos[:] = q
        mujoco.mj_forward(model, data)
        full = np.empty((2, 2))
        for col, unit in enumerate(np.eye(2)):
            res = np.empty(2)
            mujoco.mj_mulM(model, data, res, unit)
            full[:, col] = res
        np.testing.assert_allclose(full, np.array(M(*q), dtype=float), rtol=1e-12)


@pytest.mark.parametrize("integrator", ["Euler", "implicitfast", "implicit"])
def test_other_integrators(integrator):
    model = mujoco.MjModel.from_xml_string(to_mjcf(TORQUES, integrator=integrator.lower()))
    assert model.opt.integrator == getattr(mujoco.mjtIntegrator, f"mjINT_{integrator.upper()}")
    t, y = mujoco_trajectory(TORQUES, [0.5, 0.5, 0.0, 0.0], 0.01, dt=1e-3, integrator=integrator)
    assert np.all(np.isfinite(y))


# -- the tiny inertia --------------------------------------------------------------------------
def test_mujoco_compatible_thin_rods():
    p = Parameters(a=1.2, b=0.5, m1=2.0, m2=0.4, alpha=0.3, g=9.81)
    q = mujoco_compatible(p)
    assert q.com1 == (0.0, 0.6, 0.0) and q.com2 == (0.0, 0.25, 0.0)
    k1, k2 = 2.0 * 1.2**2 / 12, 0.4 * 0.5**2 / 12
    assert q.inertia1 == ((k1, 0.0, 0.0), (0.0, 1e-9 * 2.0 * 1.2**2, 0.0), (0.0, 0.0, k1))
    assert q.inertia2 == ((k2, 0.0, 0.0), (0.0, 1e-9 * 0.4 * 0.5**2, 0.0), (0.0, 0.0, k2))
    for name in ("a", "b", "m1", "m2", "alpha", "g", "c1", "c2", "tau1", "tau2", "axis1", "axis2"):
        assert getattr(q, name) == getattr(p, name)
    assert mujoco_compatible(q) == q  # idempotent
    custom = mujoco_compatible(p, axial_inertia=1e-6)
    assert custom.inertia1[1][1] == 1e-6 and custom.inertia2[1][1] == 1e-6


def test_mujoco_compatible_leaves_proper_bodies_alone():
    q = mujoco_compatible(GENERAL)
    assert q.inertia1 == GENERAL.inertia1 and q.inertia2 == GENERAL.inertia2
    assert q.com1 == GENERAL.com1 and q.com2 == GENERAL.com2


@pytest.mark.parametrize(
    "tensor, fixed",
    [
        (((0.0, 0.0, 0.0),) * 3, "all"),  # point mass
        (((0.02, 0.0, 0.0), (0.0, 0.03, 0.0), (0.0, 0.0, 0.05)), "triangle"),  # flat plate C = A + B
        (_random_inertia(np.random.default_rng(3), 1.0, (0.0, 0.8, 0.0)), "axial"),  # a turned line
    ],
    ids=["point-mass", "flat-plate", "turned-thin-rod"],
)
def test_degenerate_bodies_become_loadable(tensor, fixed):
    p = Parameters(a=1.0, b=0.8, m1=1.0, m2=0.7, alpha=0.5, g=9.81, inertia2=tensor)
    q = mujoco_compatible(p)
    eps = 1e-9 * 0.7 * 0.8**2
    before, after = np.linalg.eigvalsh(_tensor(tensor)), np.linalg.eigvalsh(_tensor(q.inertia2))
    change = after - before
    if fixed == "all":
        np.testing.assert_allclose(after, eps, rtol=1e-12)
    else:  # only the smallest principal moment moves, by eps
        np.testing.assert_allclose(change, [eps, 0, 0], rtol=0, atol=1e-6 * eps)
    model = mujoco.MjModel.from_xml_string(to_mjcf(p))
    np.testing.assert_allclose(np.sort(model.body_inertia[2]), after, rtol=0, atol=1e-12 * max(after.max(), eps))
    mujoco.MjModel.from_xml_string(to_urdf(p))


# -- URDF --------------------------------------------------------------------------------------
def _urdf_axes(root):
    return {j.get("name"): (j.get("type"), [float(x) for x in j.find("axis").get("xyz").split()])
            for j in root.iter("joint") if j.get("type") != "fixed"}


@pytest.mark.parametrize("z_up", [False, True])
def test_urdf_parses_with_two_hinges_and_the_right_axes(z_up):
    p = mujoco_compatible(GENERAL)
    root = ET.fromstring(to_urdf(GENERAL, z_up=z_up))
    assert root.tag == "robot"
    joints = _urdf_axes(root)
    assert set(joints) == {"hinge1", "hinge2"}
    assert all(kind in ("revolute", "continuous") for kind, _ in joints.values())
    np.testing.assert_allclose(joints["hinge1"][1], p.axis1, rtol=1e-15)
    np.testing.assert_allclose(joints["hinge2"][1], p.axis2, rtol=1e-15)
    hinge2 = next(j for j in root.iter("joint") if j.get("name") == "hinge2")
    assert [float(x) for x in hinge2.find("origin").get("xyz").split()] == [0.0, p.a, 0.0]
    assert float(hinge2.find("dynamics").get("damping")) == p.c2
    links = {link.get("name"): link for link in root.iter("link")}
    for name, mass, com, tensor in (("rod1", p.m1, p.com1, p.inertia1), ("rod2", p.m2, p.com2, p.inertia2)):
        inertial = links[name].find("inertial")
        assert float(inertial.find("mass").get("value")) == mass
        assert tuple(float(x) for x in inertial.find("origin").get("xyz").split()) == com
        i = inertial.find("inertia")
        I = [[float(i.get(f"i{r}{c}" if f"i{r}{c}" in i.attrib else f"i{c}{r}")) for c in "xyz"] for r in "xyz"]
        assert I == [list(row) for row in tensor]


@pytest.mark.parametrize("z_up", [False, True])
def test_mujoco_compiles_the_urdf_to_the_same_dynamics(z_up):
    """MuJoCo's URDF import (with the <mujoco> gravity block) moves exactly like the MJCF."""
    p = TORQUES
    model = mujoco.MjModel.from_xml_string(to_urdf(p, z_up=z_up))
    assert model.nu == 0 and model.nv == 2
    np.testing.assert_allclose(model.opt.gravity, [0, 0, -p.g] if z_up else [0, p.g, 0])
    np.testing.assert_allclose(model.dof_damping, [p.c1, p.c2])
    data = mujoco.MjData(model)
    y0 = [1.1, -0.8, 0.5, 1.5]
    data.qpos[:], data.qvel[:] = y0[:2], y0[2:]
    data.qfrc_applied[:] = [p.tau1, p.tau2]  # URDF has no constant torques
    n = 2000
    ys = np.empty((n, 4))
    for k in range(n):
        mujoco.mj_step(model, data)
        ys[k, :2], ys[k, 2:] = data.qpos, data.qvel
    _, ref = mujoco_trajectory(p, y0, n * DT, dt=DT)
    np.testing.assert_allclose(ys, ref[1:], rtol=0, atol=1e-10)


# -- files and errors --------------------------------------------------------------------------
def test_write_model_atomically(tmp_path):
    p = TORQUES
    out = write_model(p, tmp_path / "pendulum.xml")
    assert out.read_text() == to_mjcf(p)
    out = write_model(p, tmp_path / "model.txt", "urdf", z_up=True)
    assert out.read_text() == to_urdf(p, z_up=True)
    write_model(p, tmp_path / "pendulum.urdf")
    write_model(p, tmp_path / "pendulum.xml", format="MJCF", timestep=1e-3)
    assert 'timestep="0.001"' in (tmp_path / "pendulum.xml").read_text()
    assert sorted(f.name for f in tmp_path.iterdir()) == ["model.txt", "pendulum.urdf", "pendulum.xml"]


def test_write_model_errors(tmp_path):
    with pytest.raises(ParameterError, match=r"unknown export format 'sdf'; allowed: mjcf, urdf"):
        write_model(TORQUES, tmp_path / "x.sdf", "sdf")
    with pytest.raises(ParameterError, match=r"file name 'x.sdf'.*allowed: mjcf, urdf"):
        write_model(TORQUES, tmp_path / "x.sdf")
    with pytest.raises(ParameterError, match="does not exist"):
        write_model(TORQUES, tmp_path / "missing" / "x.xml")
    with pytest.raises(ParameterError, match="unknown urdf export option.*timestep; allowed: axial_inertia, z_up"):
        write_model(TORQUES, tmp_path / "x.urdf", timestep=1e-3)
    (tmp_path / "keep.xml").write_text("old")
    with pytest.raises(NotNumericError):
        write_model(Parameters(a=1, b=1, m1=1, m2=1, g=9.81), tmp_path / "keep.xml")
    assert (tmp_path / "keep.xml").read_text() == "old"
    assert [f.name for f in tmp_path.iterdir()] == ["keep.xml"]


def test_symbolic_parameters_are_refused():
    p = Parameters(a=1, b=1, m1=1, m2=1, g=9.81)  # alpha symbolic
    for call in (lambda: to_mjcf(p), lambda: to_urdf(p), lambda: mujoco_compatible(p),
                 lambda: mujoco_trajectory(p, [0, 0, 0, 0], 0.1)):
        with pytest.raises(NotNumericError, match="alpha"):
            call()
    # alpha is not needed when axis2 is given
    mujoco.MjModel.from_xml_string(to_mjcf(p.replace(axis2=(1, 0, 1))))


@pytest.mark.parametrize(
    "kwargs, match",
    [
        (dict(y0=[0, 0, 0]), "y0"),
        (dict(y0=[0, 0, np.nan, 0]), "y0"),
        (dict(t_end=0.0), "t_end"),
        (dict(t_end=0.01, dt=0.003), "whole number"),
        (dict(dt=-1e-4), "dt"),
        (dict(n_out=1), "n_out"),
        (dict(integrator="leapfrog"), "allowed: RK4, Euler, implicit, implicitfast"),
        (dict(axial_inertia=0.0), "axial_inertia"),
    ],
)
def test_mujoco_trajectory_argument_errors(kwargs, match):
    args = dict(y0=[0.1, 0.2, 0.0, 0.0], t_end=0.01, dt=1e-3)
    args.update(kwargs)
    with pytest.raises(ParameterError, match=match):
        mujoco_trajectory(TORQUES, args.pop("y0"), args.pop("t_end"), **args)


def test_exporter_argument_errors():
    with pytest.raises(ParameterError, match="timestep"):
        to_mjcf(TORQUES, timestep=0)
    with pytest.raises(ParameterError, match="integrator"):
        to_mjcf(TORQUES, integrator="RK45")
    with pytest.raises(ParameterError, match="axial_inertia"):
        to_urdf(TORQUES, axial_inertia=-1.0)


def test_unstable_simulation_is_reported(tmp_path, monkeypatch):
    # a huge time step with a light, fast body blows up
    monkeypatch.chdir(tmp_path)
    p = Parameters(a=1, b=1, m1=1, m2=1e-3, alpha=1.0, g=9.81, tau2=50.0)
    with pytest.raises(IntegrationError, match="unstable"):
        mujoco_trajectory(p, [1.0, 1.0, 50.0, 50.0], 50.0, dt=0.5, integrator="Euler")
    assert list(tmp_path.iterdir()) == []  # no MUJOCO_LOG.TXT
    assert mujoco.get_mju_user_warning() is None  # handler restored


def test_mujoco_is_imported_lazily_and_its_absence_is_explained(monkeypatch):
    code = "import sys, skewpend.interop.export; assert 'mujoco' not in sys.modules"
    subprocess.run([sys.executable, "-c", code], check=True)
    monkeypatch.setitem(sys.modules, "mujoco", None)  # makes `import mujoco` fail
    with pytest.raises(MujocoMissingError, match="pip install") as info:
        mujoco_trajectory(TORQUES, [0, 0, 0, 0], 0.01, dt=1e-3)
    assert isinstance(info.value, SkewpendError) and isinstance(info.value, ImportError)
    to_mjcf(TORQUES)  # export itself does not need mujoco


def test_the_command_line_exports_and_validates_a_chain(tmp_path):
    """``skewpend export --links 3`` writes the chain's MJCF (three hinges, MuJoCo loads it) and ``skewpend
    validate --links 3`` agrees with MuJoCo -- the one writer takes any model on the command line too."""
    mujoco = pytest.importorskip("mujoco")
    out = tmp_path / "triple.xml"
    axes = "0,0,1;0.3,0,1;0,0.2,1"
    proc = subprocess.run([sys.executable, "-m", "skewpend", "export", "--links", "3", "--link-axis", axes, "--out",
                           str(out)], capture_output=True, text=True, timeout=300)
    assert proc.returncode == 0, proc.stderr
    model = mujoco.MjModel.from_xml_path(str(out))
    assert model.njnt == 3 and model.nu == 3
    proc = subprocess.run([sys.executable, "-m", "skewpend", "validate", "--links", "3", "--link-axis", axes,
                           "--t-end", "0.5"], capture_output=True, text=True, timeout=300)
    assert proc.returncode == 0, proc.stderr + proc.stdout
    assert "AGREE" in proc.stdout
