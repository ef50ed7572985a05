"""Reading MuJoCo (MJCF) and URDF models into a chain (issue 54, item 1): skewpend.interop.importer.

* random serial hinge chains written as MJCF here (not by skewpend's exporter: geoms of every shape, fromto,
  densities, explicit inertials, body quat/euler rotations, tilted joint axes at joint positions, damping,
  armature): the chain's mass matrix and bias forces equal MuJoCo's (mj_fullM, qfrc_bias) to 1e-12 relative;
* skewpend's own exports read back: MJCF to 1e-14 relative (MuJoCo's compiler rounds), URDF bit for bit;
* what a chain cannot hold: one line each.
"""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest

from skewpend import Chain, Link
from skewpend.errors import ParameterError
from skewpend.interop.importer import ImportedModel, gravity_rotation, read_mjcf, read_urdf

DATA = Path(__file__).resolve().parent / "data"


# -- the chain's M and f, and MuJoCo's ------------------------------------------------------------------------
def chain_M_f(chain, q, dq):
    """The chain's mass matrix and forcing f = Q - bias (M q'' = f) by the recursive algorithms (CasADi)."""
    from skewpend.numeric import recursive

    fn = recursive.chain_functions(recursive.structure_of_chain(chain))["model"]
    packed, f, _ = fn(np.r_[q, dq], recursive.parameter_vector(chain))
    n = chain.n
    M = np.zeros((n, n))
    packed = np.asarray(packed, dtype=float).ravel()
    for k, (i, j) in enumerate((i, j) for i in range(n) for j in range(i + 1)):
        M[i, j] = M[j, i] = packed[k]
    return M, np.asarray(f, dtype=float).ravel()


def mujoco_M_f(mujoco, model, data, q, dq):
    """MuJoCo's mass matrix and forcing: f = qfrc_passive + qfrc_actuator - qfrc_bias (ctrl 0)."""
    data.qpos[:], data.qvel[:] = q, dq
    mujoco.mj_forward(model, data)
    M = np.zeros((model.nv, model.nv))
    mujoco.mj_fullM(model, data, M)
    return M, data.qfrc_passive + data.qfrc_actuator - data.qfrc_bias


def worst_disagreement(mujoco, xml: str, imported: ImportedModel, rng, states: int = 10):
    """The largest relative differences of M and f between the imported chain and MuJoCo at random states."""
    model = mujoco.MjModel.from_xml_string(xml)
    data = mujoco.MjData(model)
    n = imported.chain.n
    worst_M = worst_f = 0.0
    for _ in range(states):
        q, dq = rng.uniform(-math.pi, math.pi, n), rng.normal(scale=2.0, size=n)
        M1, f1 = chain_M_f(imported.chain, q, dq)
        M2, f2 = mujoco_M_f(mujoco, model, data, q, dq)
        worst_M = max(worst_M, np.max(np.abs(M1 - M2)) / np.max(np.abs(M2)))
        worst_f = max(worst_f, np.max(np.abs(f1 - f2)) / max(np.max(np.abs(f2)), 1e-300))
    return worst_M, worst_f


# -- random MJCF, written here ------------------------------------------------------------------------------
def _v(x) -> str:
    return " ".join(repr(float(a)) for a in x)


def _geom(rng, degree: bool) -> str:
    kind = rng.choice(["capsule", "cylinder", "box", "sphere", "ellipsoid"])
    density = f' density="{rng.uniform(200, 3000):.6g}"' if rng.random() < 0.6 else ""
    if kind in ("capsule", "cylinder") and rng.random() < 0.6 or kind in ("box", "ellipsoid") and rng.random() < 0.3:
        a, b = rng.normal(scale=0.15, size=3), rng.normal(scale=0.4, size=3)
        size = {"capsule": 1, "cylinder": 1, "box": 2, "ellipsoid": 2}[kind]
        sizes = rng.uniform(0.02, 0.08, size)
        return f'<geom type="{kind}" fromto="{_v(a)} {_v(b)}" size="{_v(sizes)}"{density}/>'
    n = {"capsule": 2, "cylinder": 2, "box": 3, "sphere": 1, "ellipsoid": 3}[kind]
    sizes = rng.uniform(0.03, 0.2, n)
    turn = _orientation(rng, degree) if rng.random() < 0.5 else ""
    return f'<geom type="{kind}" pos="{_v(rng.normal(scale=0.2, size=3))}" size="{_v(sizes)}"{turn}{density}/>'


def _orientation(rng, degree: bool) -> str:
    if rng.random() < 0.5:
        quat = rng.normal(size=4)
        return f' quat="{_v(quat)}"'  # MuJoCo normalises it
    angles = rng.uniform(-math.pi, math.pi, 3)
    return f' euler="{_v(np.degrees(angles) if degree else angles)}"'


def random_mjcf(rng, n: int) -> str:
    """A serial chain of ``n`` hinged bodies with geoms of every shape, written by hand."""
    degree = bool(rng.random() < 0.5)
    seq = rng.choice(["xyz", "XYZ", "zyx", "xzy"])
    gravity = "0 0 -9.81" if rng.random() < 0.6 else _v(rng.normal(size=3) * 4)
    lines = [f'<mujoco model="random{n}">',
             f'  <compiler angle="{"degree" if degree else "radian"}" eulerseq="{seq}" inertiafromgeom="auto"/>',
             f'  <option gravity="{gravity}" timestep="0.001"/>',
             '  <default><geom density="800"/></default>',
             '  <worldbody>',
             '    <geom type="plane" size="5 5 0.1"/>']
    for k in range(1, n + 1):
        pos = rng.normal(scale=0.4, size=3)
        lines.append("  " * (k + 1) + f'<body name="b{k}" pos="{_v(pos)}"{_orientation(rng, degree) if rng.random() < 0.8 else ""}>')
        armature = f' armature="{rng.uniform(0.001, 0.05):.6g}"' if rng.random() < 0.4 else ""
        lines.append("  " * (k + 2) + f'<joint name="j{k}" type="hinge" pos="{_v(rng.normal(scale=0.1, size=3))}" '
                     f'axis="{_v(rng.normal(size=3))}" damping="{rng.uniform(0, 0.3):.6g}"{armature}/>')
        if rng.random() < 0.3:
            d = rng.uniform(0.01, 0.1, 3)
            lines.append("  " * (k + 2) + f'<inertial pos="{_v(rng.normal(scale=0.2, size=3))}" mass="{rng.uniform(0.2, 2):.6g}" '
                         f'diaginertia="{_v([d[1] + d[2], d[0] + d[2], d[0] + d[1]])}"{_orientation(rng, degree)}/>')
        for _ in range(int(rng.integers(1, 4))):
            lines.append("  " * (k + 2) + _geom(rng, degree))
    lines += ["  " * (k + 1) + "</body>" for k in range(n, 0, -1)]
    lines += ["  </worldbody>", "</mujoco>", ""]
    return "\n".join(lines)


def _write(tmp_path, name: str, text: str) -> Path:
    path = tmp_path / name
    path.write_text(text)
    return path


@pytest.mark.slow
@pytest.mark.parametrize("seed", range(10))
def test_random_mjcf_chains_equal_mujoco(seed, tmp_path):
    """10 random chains of 2 to 5 bodies written as MJCF: M and f = passive - bias equal MuJoCo's to 1e-12."""
    mujoco = pytest.importorskip("mujoco")
    pytest.importorskip("casadi")
    rng = np.random.default_rng(5400 + seed)
    n = int(rng.integers(2, 6))
    xml = random_mjcf(rng, n)
    imported = read_mjcf(_write(tmp_path, "random.xml", xml))
    assert imported.chain.n == n
    worst_M, worst_f = worst_disagreement(mujoco, xml, imported, rng)
    assert worst_M <= 1e-12 and worst_f <= 1e-12, (worst_M, worst_f, xml)


def test_gravity_rotation_takes_gravity_to_plus_y():
    for gravity in ((0, 0, -9.81), (0, 9.81, 0), (0, -3.0, 0), (1.0, -2.0, 0.5), (0.0, 0.0, 2.0)):
        R, g = gravity_rotation(gravity)
        R = np.array(R)
        assert np.allclose(R @ R.T, np.eye(3), atol=1e-15) and abs(np.linalg.det(R) - 1) < 1e-15
        assert np.allclose(R @ np.array(gravity, dtype=float), (0, g, 0), atol=1e-14)
    assert gravity_rotation((0, 0, -9.81))[0] == ((1.0, 0.0, 0.0), (0.0, 0.0, -1.0), (0.0, 1.0, 0.0))


# -- skewpend's own exports read back -------------------------------------------------------------------------
def _random_chain(rng, n: int) -> Chain:
    links = []
    for i in range(n):
        d = rng.uniform(0.05, 0.5, 3)
        D = np.diag([d[1] ** 2 + d[2] ** 2, d[0] ** 2 + d[2] ** 2, d[0] ** 2 + d[1] ** 2]) * rng.uniform(0.2, 2.0) / 12
        R, _ = np.linalg.qr(rng.normal(size=(3, 3)))
        inertia = R @ D @ R.T
        links.append(Link(axis=tuple(rng.normal(size=3)), offset=tuple(rng.normal(scale=0.3, size=3)) if i else (0, 0, 0),
                          length=float(rng.uniform(0.3, 1.2)), mass=float(rng.uniform(0.2, 2.0)),
                          com=tuple(rng.normal(scale=0.3, size=3)), inertia=(0.5 * (inertia + inertia.T)).tolist(),
                          damping=float(rng.uniform(0, 0.3))))
    return Chain(links=tuple(links), g=9.81)


@pytest.mark.parametrize("n", [1, 2, 3, 5])
def test_urdf_export_reads_back_bit_identical(n, tmp_path):
    from skewpend.interop.export import mujoco_compatible, to_urdf

    chain = mujoco_compatible(_random_chain(np.random.default_rng(60 + n), n))
    for z_up in (False, True):
        back = read_urdf(_write(tmp_path, f"m{z_up}.urdf", to_urdf(chain, z_up=z_up)))
        assert back.chain == chain, z_up
        assert back.notes == () and back.actuated == ()
    thin = mujoco_compatible(Chain.from_lists(n))  # the default thin rods, the tiny axial inertia
    assert read_urdf(_write(tmp_path, "thin.urdf", to_urdf(thin))).chain == thin


@pytest.mark.parametrize("n", [1, 2, 3, 5])
def test_mjcf_export_reads_back(n, tmp_path):
    """MuJoCo compiles the inertia (its eigen-decomposition) and the anchors: equal to 1e-14 relative."""
    pytest.importorskip("mujoco")
    from skewpend.interop.export import mujoco_compatible, to_mjcf

    rng = np.random.default_rng(70 + n)
    chain = mujoco_compatible(_random_chain(rng, n))
    chain = chain.replace_link(n, torque=0.25)
    back = read_mjcf(_write(tmp_path, "m.xml", to_mjcf(chain)))
    assert back.chain.n == n and back.chain.g == chain.g and back.actuated == tuple(range(1, n + 1))
    for a, b in zip(back.chain.links, chain.links):
        for key in ("axis", "offset", "com", "inertia", "length", "mass", "damping", "torque", "rotor", "gear"):
            x, y = np.array(getattr(a, key), dtype=float), np.array(getattr(b, key), dtype=float)
            assert np.max(np.abs(x - y)) <= 1e-14 * max(1.0, np.max(np.abs(y))), (key, x, y)


def test_mjcf_export_with_rotors_keeps_the_dynamics(tmp_path):
    """Rotors on every joint: the file holds armatures and axial inertias; read back, M and f are MuJoCo's."""
    mujoco = pytest.importorskip("mujoco")
    pytest.importorskip("casadi")
    from skewpend.interop.export import to_mjcf

    rng = np.random.default_rng(81)
    chain = _random_chain(rng, 3)
    for i, gear in enumerate((-6.0, 2.5, 6.0), start=1):
        chain = chain.replace_link(i, rotor=1e-5, gear=gear)
    xml = to_mjcf(chain)
    back = read_mjcf(_write(tmp_path, "rotors.xml", xml))
    assert back.chain.links[0].rotor == pytest.approx(1e-5 * 36, rel=1e-15) and back.chain.links[0].gear == 1.0
    assert any("armature" in note for note in back.notes)
    worst_M, worst_f = worst_disagreement(mujoco, xml, back, rng, states=5)
    assert worst_M <= 1e-12 and worst_f <= 1e-12


# -- mappings that are not one-to-one ------------------------------------------------------------------------
ACTUATED = """<mujoco>
  <compiler angle="radian"/>
  <worldbody>
    <body name="base" pos="0 0 1">
      <geom type="box" size="0.1 0.1 0.1" contype="0" conaffinity="0"/>
      <body name="arm">
        <joint name="shoulder" axis="0 1 0" frictionloss="0.3" limited="true" range="-1 1"/>
        <geom type="capsule" fromto="0 0 0 0 0 -0.5" size="0.02" mass="0.4"/>
        <body name="forearm" pos="0 0 -0.5">
          <joint name="elbow" axis="0 1 0" damping="0.05"/>
          <geom type="capsule" fromto="0 0 0 0 0 -0.4" size="0.02" mass="0.3"/>
          <body name="hand" pos="0 0 -0.4"><geom type="sphere" size="0.05" mass="0.1"/></body>
        </body>
      </body>
    </body>
  </worldbody>
  <actuator>
    <motor joint="elbow" gear="2" ctrlrange="-1 1"/>
    <motor joint="shoulder" gear="3" forcerange="-0.5 0.5" ctrlrange="-2 2"/>
  </actuator>
</mujoco>
"""


def test_actuators_friction_limits_and_welded_bodies(tmp_path):
    pytest.importorskip("mujoco")
    model = read_mjcf(_write(tmp_path, "arm.xml", ACTUATED))
    chain = model.chain
    assert chain.n == 2 and model.actuated == (1, 2) and model.gear == (3.0, 2.0)
    assert model.torque_limits == (1.5, 2.0)  # min(2 x 3, 0.5 x 3); 1 x 2
    assert chain.links[0].coulomb == pytest.approx(2 * 0.3 / math.pi, rel=1e-15)
    assert chain.links[1].damping == 0.05
    text = "\n".join(model.notes)
    assert "frictionloss" in text and "sticks" in text and "limits" in text and "welded" in text
    assert "contacts ignored" in text
    # z up -> y down: the hanging arm points along +y; the hand is merged into the forearm
    assert chain.links[0].axis == pytest.approx((0.0, 0.0, 1.0), abs=1e-15)
    assert chain.links[1].offset == pytest.approx((0.0, 0.5, 0.0), abs=1e-15)
    assert chain.links[1].mass == pytest.approx(0.4, rel=1e-14)
    assert chain.links[1].com[1] == pytest.approx((0.3 * 0.2 + 0.1 * 0.4) / 0.4, rel=1e-12)
    assert chain.links[0].length == pytest.approx(0.5, rel=1e-14)


URDF_ARM = """<?xml version="1.0"?>
<robot name="arm">
  <link name="base"/>
  <link name="upper"><inertial><origin xyz="0 0 -0.25" rpy="0 0 0"/><mass value="1"/>
    <inertia ixx="0.02" ixy="0" ixz="0" iyy="0.02" iyz="0" izz="0.001"/></inertial></link>
  <link name="lower"><inertial><origin xyz="0 0 -0.2" rpy="0.3 0 0"/><mass value="0.5"/>
    <inertia ixx="0.01" ixy="0" ixz="0" iyy="0.01" iyz="0" izz="0.0005"/></inertial>
    <visual><origin xyz="0 0 -0.2"/><geometry><cylinder radius="0.01" length="0.4"/></geometry></visual></link>
  <link name="tool"><inertial><origin xyz="0 0 0"/><mass value="0.2"/>
    <inertia ixx="0.001" ixy="0" ixz="0" iyy="0.001" iyz="0" izz="0.001"/></inertial></link>
  <joint name="shoulder" type="continuous"><parent link="base"/><child link="upper"/>
    <origin xyz="0 0 2" rpy="0 0 0"/><axis xyz="1 0 0"/><dynamics damping="0.1" friction="0.2"/>
    <limit effort="5" velocity="10"/></joint>
  <joint name="elbow" type="revolute"><parent link="upper"/><child link="lower"/>
    <origin xyz="0 0 -0.5" rpy="0 0 1.5707963267948966"/><axis xyz="1 0 0"/>
    <limit lower="-2" upper="2" effort="3" velocity="10"/></joint>
  <joint name="mount" type="fixed"><parent link="lower"/><child link="tool"/><origin xyz="0 0 -0.4"/></joint>
</robot>
"""


def test_urdf_with_rotations_friction_and_a_fixed_tool(tmp_path):
    model = read_urdf(_write(tmp_path, "arm.urdf", URDF_ARM))
    chain = model.chain
    assert chain.n == 2 and chain.g == 9.81
    assert model.actuated == (1, 2) and model.torque_limits == (5.0, 3.0) and model.gear == (1.0, 1.0)
    assert chain.links[0].offset == (0.0, -2.0, 0.0) and chain.links[0].axis == (1.0, 0.0, 0.0)
    assert chain.links[1].axis == pytest.approx((0.0, 0.0, 1.0), abs=1e-16)  # x turned by the yaw, z up -> y down
    assert chain.links[1].mass == pytest.approx(0.7) and chain.links[1].com[1] == pytest.approx((0.5 * 0.2 + 0.2 * 0.4) / 0.7)
    assert chain.links[0].coulomb == pytest.approx(0.4 / math.pi)
    assert chain.links[1].length == pytest.approx(0.4)
    text = "\n".join(model.notes)
    assert "friction" in text and "limits" in text and "fixed" in text and "gravity" in text
    # g and up given: y down already
    assert read_urdf(tmp_path / "arm.urdf", g=3.0, up=(0, -1, 0)).chain.links[0].offset == (0.0, 0.0, 2.0)


def test_urdf_equals_the_same_model_in_mujoco(tmp_path):
    """The URDF above, loaded by MuJoCo itself (gravity 0 0 -9.81): M and f are MuJoCo's."""
    mujoco = pytest.importorskip("mujoco")
    pytest.importorskip("casadi")
    text = URDF_ARM.replace("<robot name=\"arm\">", "<robot name=\"arm\"><mujoco><compiler fusestatic=\"false\" "
                            "discardvisual=\"true\"/></mujoco>").replace(' friction="0.2"', "")
    path = _write(tmp_path, "arm.urdf", text)
    model = read_urdf(path)
    mj = mujoco.MjModel.from_xml_path(str(path))
    data = mujoco.MjData(mj)
    rng = np.random.default_rng(3)
    for _ in range(5):
        q, dq = rng.uniform(-3, 3, 2), rng.normal(size=2)
        M1, f1 = chain_M_f(model.chain, q, dq)
        M2, f2 = mujoco_M_f(mujoco, mj, data, q, dq)
        assert np.max(np.abs(M1 - M2)) <= 1e-12 * np.max(np.abs(M2))
        assert np.max(np.abs(f1 - f2)) <= 1e-12 * np.max(np.abs(f2))


# -- refused: one line each --------------------------------------------------------------------------------
def _chain_xml(joint2: str = '<joint name="j2" axis="0 1 0"/>', extra: str = "", after: str = "") -> str:
    return f"""<mujoco><worldbody>
  <body name="a"><joint name="j1" axis="0 1 0"/><geom size="0.1" pos="0 0 -0.5"/>
    <body name="b" pos="0 0 -0.5">{joint2}<geom size="0.1" pos="0 0 -0.5"/>{extra}</body>
  </body></worldbody>{after}</mujoco>"""


REFUSED = {
    "ball": (_chain_xml('<joint name="j2" type="ball"/>'), "joint 'j2' in body 'b' is a ball joint"),
    "slide": (_chain_xml('<joint name="j2" type="slide" axis="1 0 0"/>'), "joint 'j2' in body 'b' is a slide joint"),
    "free": (_chain_xml(joint2="", extra='<body name="c"><freejoint name="f"/><geom size="0.1"/></body>'), "free joint"),
    "two joints": (_chain_xml('<joint name="j2" axis="0 1 0"/><joint name="j3" axis="1 0 0"/>'), "body 'b' has 2 joints"),
    "branch": (_chain_xml(extra='<body name="c"><joint axis="1 0 0"/><geom size="0.1"/></body>'
                                '<body name="d"><joint axis="1 0 0"/><geom size="0.1"/></body>'),
               "a branch: body 'b' carries jointed body 'c' and body 'd'"),
    "gap": (_chain_xml(extra='<body name="c"><geom size="0.1"/><body name="d"><joint axis="1 0 0"/>'
                             '<geom size="0.1"/></body></body>'), "body 'c' has no joint but sits between"),
    "equality": (_chain_xml(after='<equality><joint joint1="j1" joint2="j2"/></equality>'), "equality constraint"),
    "spring": (_chain_xml('<joint name="j2" axis="0 1 0" stiffness="3"/>'), "joint 'j2' has a spring"),
    "servo": (_chain_xml(after='<actuator><position joint="j2" kp="10"/></actuator>'), "position/velocity feedback"),
}


@pytest.mark.parametrize("case", list(REFUSED))
def test_what_a_chain_cannot_hold_is_one_line(case, tmp_path):
    pytest.importorskip("mujoco")
    xml, words = REFUSED[case]
    with pytest.raises(ParameterError) as info:
        read_mjcf(_write(tmp_path, "bad.xml", xml))
    assert words in str(info.value) and "\n" not in str(info.value), str(info.value)


def test_files_that_are_not_models_are_one_line(tmp_path):
    for reader in (read_mjcf, read_urdf):
        for path, words in ((tmp_path, "is not a file"), (tmp_path / "missing.xml", "no such file"), (3, "file name")):
            with pytest.raises(ParameterError) as info:
                reader(path)
            assert words in str(info.value) and "\n" not in str(info.value)
    broken = _write(tmp_path, "broken.xml", "<mujoco><worldbody><body>")
    pytest.importorskip("mujoco")
    with pytest.raises(ParameterError, match="MuJoCo cannot compile broken.xml") as info:
        read_mjcf(broken)
    assert "\n" not in str(info.value)
    with pytest.raises(ParameterError, match="not XML"):
        read_urdf(broken)
    branch = URDF_ARM.replace('<joint name="mount" type="fixed"><parent link="lower"/>',
                              '<joint name="mount" type="continuous"><parent link="upper"/>')
    with pytest.raises(ParameterError, match="a branch: link 'upper' carries joints") as info:
        read_urdf(_write(tmp_path, "branch.urdf", branch))
    loop = URDF_ARM.replace('</robot>', '<joint name="back" type="continuous"><parent link="tool"/><child link="upper"/>'
                                        '</joint></robot>')
    with pytest.raises(ParameterError, match="link 'upper' is the child of joints 'shoulder' and 'back'"):
        read_urdf(_write(tmp_path, "loop.urdf", loop))
    prismatic = URDF_ARM.replace('type="revolute"', 'type="prismatic"')
    with pytest.raises(ParameterError, match="joint 'elbow' is 'prismatic'"):
        read_urdf(_write(tmp_path, "slide.urdf", prismatic))


def test_a_later_armature_that_no_body_can_spare_is_refused(tmp_path):
    pytest.importorskip("mujoco")
    xml = """<mujoco><compiler inertiafromgeom="false"/><worldbody>
      <body><joint axis="0 1 0"/><inertial pos="0 0 -1" mass="1" diaginertia="1e-12 1e-12 1e-12"/>
        <body pos="0 0 -1"><joint name="two" axis="0 1 0" armature="0.1"/>
          <inertial pos="0 0 -1" mass="1" diaginertia="1e-12 1e-12 1e-12"/></body></body></worldbody></mujoco>"""
    with pytest.raises(ParameterError, match="joint 2: its armature 0.1 kg m\\^2 cannot be held exactly") as info:
        read_mjcf(_write(tmp_path, "arm.xml", xml))
    assert "\n" not in str(info.value)


# -- the dm_control acrobot -----------------------------------------------------------------------------------
def test_dm_control_acrobot_equals_mujoco():
    """dm_control's suite acrobot (Apache-2.0, its includes inlined in tests/data/dm_control_acrobot.xml): two
    links on parallel hinges, their arms up at qpos = 0, the elbow's motor geared 2 with |ctrl| <= 1."""
    mujoco = pytest.importorskip("mujoco")
    pytest.importorskip("casadi")
    path = DATA / "dm_control_acrobot.xml"
    if not path.exists():
        pytest.skip("the acrobot's MJCF is not in tests/data")
    model = read_mjcf(path)
    assert model.chain.n == 2 and model.actuated == (2,) and model.gear == (2.0,) and model.torque_limits == (2.0,)
    assert model.chain.links[1].offset == pytest.approx((0.0, -1.0, 0.0), abs=1e-15) and model.chain.links[0].damping == 0.05
    assert not any("contacts" in note for note in model.notes)  # constraints disabled in the file
    worst_M, worst_f = worst_disagreement(mujoco, path.read_text(), model, np.random.default_rng(9), states=20)
    assert worst_M <= 1e-12 and worst_f <= 1e-12


def test_without_mujoco_read_mjcf_says_what_to_install(tmp_path, monkeypatch):
    import sys

    from skewpend.errors import MissingExtraError

    path = _write(tmp_path, "arm.xml", ACTUATED)
    monkeypatch.setitem(sys.modules, "mujoco", None)  # import mujoco raises ImportError
    with pytest.raises(MissingExtraError, match=r'pip install "skewpend\[validate\]"') as info:
        read_mjcf(path)
    assert "\n" not in str(info.value)
    assert read_urdf(_write(tmp_path, "arm.urdf", URDF_ARM)).chain.n == 2  # URDF needs no MuJoCo


def test_a_joint_ref_and_a_tilted_gravity_are_said(tmp_path):
    pytest.importorskip("mujoco")
    xml = _chain_xml('<joint name="j2" axis="0 1 0" ref="0.5"/>').replace("<mujoco>", '<mujoco><compiler angle="radian"/><option gravity="3 0 -4"/>')
    model = read_mjcf(_write(tmp_path, "ref.xml", xml))
    assert model.chain.g == pytest.approx(5.0, rel=1e-15)
    text = "\n".join(model.notes)
    assert "ref (qpos0) 0.5" in text and "gravity along (0.6, 0, -0.8)" in text


def test_a_link_without_mass_is_one_line(tmp_path):
    mesh_only = """<robot name="mesh"><link name="base"/>
      <link name="arm"><visual><geometry><mesh filename="arm.stl"/></geometry></visual></link>
      <joint name="j" type="continuous"><parent link="base"/><child link="arm"/><axis xyz="0 1 0"/></joint></robot>"""
    with pytest.raises(ParameterError, match="link 1 \\(link 'arm'\\) has no mass \\(URDF: no <inertial>") as info:
        read_urdf(_write(tmp_path, "mesh.urdf", mesh_only))
    assert "\n" not in str(info.value)


# -- every command's --config reads a model file ------------------------------------------------------------
@pytest.mark.slow
def test_a_model_file_is_a_run_file_of_every_command_that_takes_a_chain(tmp_path):
    """``--config acrobot.xml`` (dm_control's, read by MuJoCo): simulate runs the chain its reader makes (its end
    state equals the library's run of ``read_mjcf(...).chain`` from the same default start to 1e-9), the
    importer's notes and the actuators said once on stderr; ``export`` writes it as URDF and ``--config x.urdf``
    reads that back; a file that is no chain (a ball joint) is one line, exit 2."""
    import sys

    sys.path.insert(0, str(Path(__file__).resolve().parent))
    from helpers import run_cli

    import skewpend
    from skewpend.config import CHAIN_Q0

    acrobot = DATA / "dm_control_acrobot.xml"
    ran = run_cli(["simulate", "--config", str(acrobot), "--t-end", "1", "--method", "dop853"], cwd=tmp_path)
    assert ran.code == 0, ran.report()
    assert ran.err.count("skewpend: note:") == 2 and "actuators on joint 2 |u| <= 2 N m" in ran.err, ran.err
    chain = read_mjcf(acrobot).chain
    tr = skewpend.simulate(chain, [CHAIN_Q0] * chain.n + [0.0] * chain.n, 1.0, method="dop853")
    import re

    line = ran.out.split("final state")[1].splitlines()[0]
    end = [float(v) for k, v in re.findall(r"(\S+)=(\S+)", line) if k != "t"]
    assert np.allclose(end, np.asarray(tr.y)[-1, : 2 * chain.n], atol=1e-9), (end, tr.y[-1])
    out = tmp_path / "acrobot.urdf"
    ran = run_cli(["export", "--config", str(acrobot), "--out", str(out)], cwd=tmp_path)
    assert ran.code == 0 and out.exists(), ran.report()
    from skewpend.interop.export import mujoco_compatible

    assert read_urdf(out).chain == mujoco_compatible(chain)  # the written chain, read back exactly
    ran = run_cli(["simulate", "--config", str(out), "--t-end", "0.5"], cwd=tmp_path)
    assert ran.code == 0, ran.report()
    ball = _write(tmp_path, "ball.xml", '<mujoco><worldbody><body><joint type="ball"/><geom size=".1"/></body>'
                                        '</worldbody></mujoco>')
    ran = run_cli(["simulate", "--config", str(ball)], cwd=tmp_path)
    assert ran.code == 2 and "ball joint" in ran.err and "Traceback" not in ran.err, ran.report()


def test_control_drives_the_model_files_actuators_within_their_limits():
    """``control lqr --config acrobot.xml``: the file's actuator (the elbow, gear 2 x ctrlrange 1 = 2 N m) is the
    design's joint and limit, said in a note; ``--actuated`` given takes over (and the file's limits, which belong
    to its joints, are not applied to others)."""
    from helpers import run_cli

    path = DATA / "dm_control_acrobot.xml"
    ran = run_cli(["control", "lqr", "--config", path, "--target", "0,0"])
    assert ran.code == 0, ran.report()
    assert "note: the model file's actuators: --actuated 2 and --umax 2" in ran.err
    assert "actuated    joint 2;" in ran.out and "|u| <= 2 N m" in ran.out
    ran = run_cli(["control", "lqr", "--config", path, "--target", "0,0", "--actuated", "1,2"])
    assert ran.code == 0, ran.report()
    assert "the model file's actuators" not in ran.err and "actuated    joints 1,2;" in ran.out
    assert "(no torque limit;" in ran.out
