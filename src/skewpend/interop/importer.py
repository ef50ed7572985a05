"""Read MuJoCo (MJCF) and URDF models into a chain of links: :func:`read_mjcf`, :func:`read_urdf`.

The inverse of :mod:`skewpend.interop.export` where it can be.  Both readers return an
:class:`ImportedModel`: the :class:`~skewpend.Chain`, the actuated joints (1-based), their gears and
torque limits, and ``notes`` -- one line per mapping that is not one-to-one.

Frames
------
skewpend's chain hangs in its reference configuration (every ``q = 0``) with every body frame
parallel to the world's ``x, y, z`` and gravity along **+y** (``y`` points down); link ``k``'s hinge
axis and hinge position (``offset``, from the parent's hinge) live in the parent's frame, its centre
of mass and inertia (about the centre of mass) in its own frame with the origin at its hinge.  So a
model is read at its own zero configuration (MuJoCo's ``qpos = 0``, URDF's joint angles 0), every
vector and tensor expressed in the world's axes, and the world turned by one rotation ``R`` that takes
the model's gravity direction to ``+y``:

* gravity ``(0, 0, -g)`` (z up, MuJoCo's default, URDF's convention): ``(x, y, z) -> (x, -z, y)``;
* gravity ``(0, +g, 0)`` (skewpend's own exports): the identity;
* any other direction ``d``: the smallest rotation taking ``d`` to ``+y`` (about ``d x y``); ``d = -y``:
  the half turn about ``z``; no gravity: the identity.

Joint angles are MuJoCo's ``qpos`` (URDF's joint positions) unchanged: right-handed about the axes, zero
in the model's own zero configuration -- which need not be hanging: the dm_control acrobot's zero
points its arms up, so its imported chain has its centres of mass above the hinges (``-y``).

``length``: a chain's link needs a rod length (its tip, the drawings' scale; the dynamics do not use
it when the centre of mass and inertia are given, as here).  It is the farthest reach of the link's
geometry from its hinge -- a capsule's or cylinder's axis end, any other geom's centre (MJCF: the
compiled geoms of the body and the bodies merged into it; URDF: the visual and collision origins and
cylinder lengths) -- so skewpend's own exports read back their lengths; without geometry the distance to
the next hinge, else twice the distance to the centre of mass, else the longest other link's length.
Only its size is read: a :class:`~skewpend.Link`'s rod runs along its body's ``+j`` and cannot point
elsewhere without moving the model's zero (the dynamics, equal to MuJoCo's, would change coordinates), so
where the geometry runs the other way -- the dm_control acrobot's lower arm, up from the elbow at ``q = 0``
-- the drawings take the side of the centre of mass (:func:`skewpend.views.drawing.last_link_sign`; the
links before are drawn hinge to hinge).
"""

from __future__ import annotations

import math
import os
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, List, Optional, Sequence, Tuple

from ..errors import MissingExtraError, ParameterError

if TYPE_CHECKING:  # pragma: no cover
    from ..symbolic.chain import Chain

__all__ = ["MODEL_SUFFIXES", "read_model", "run_sections", "ImportedModel", "read_mjcf", "read_urdf", "gravity_rotation", "ARMATURE_GEAR"]

#: The gear of the rotor that holds a MuJoCo ``armature`` on a joint after the first (see :func:`read_mjcf`).
ARMATURE_GEAR = 1e6


@dataclass(frozen=True)
class ImportedModel:
    """A model read from MJCF or URDF.

    ``chain`` -- the :class:`~skewpend.Chain`; ``actuated`` -- the joints (1-based) with an actuator (MJCF) or
    an effort limit (URDF); ``gear`` -- each actuated joint's gear (joint torque per unit of actuator
    force); ``torque_limits`` -- each actuated joint's largest torque [N m] (MJCF: ``ctrlrange`` x gain x gear
    and/or ``forcerange`` x gear, the smaller; URDF: ``effort``), None where unlimited; ``notes`` -- one line
    per mapping that is not one-to-one; ``source`` -- the file read."""

    chain: "Chain"
    actuated: Tuple[int, ...] = ()
    gear: Tuple[float, ...] = ()
    torque_limits: Tuple[Optional[float], ...] = ()
    notes: Tuple[str, ...] = ()
    source: str = ""


# -- small linear algebra on tuples (numpy only where it is worth it) ---------------------------------------
def _matvec(R, v):
    return tuple(R[i][0] * v[0] + R[i][1] * v[1] + R[i][2] * v[2] for i in range(3))


def _matmul(A, B):
    return tuple(tuple(A[i][0] * B[0][j] + A[i][1] * B[1][j] + A[i][2] * B[2][j] for j in range(3)) for i in range(3))


def _transpose(A):
    return tuple(tuple(A[j][i] for j in range(3)) for i in range(3))


def _sandwich(R, inertia):
    """``R I R^T``, kept symmetric."""
    out = _matmul(_matmul(R, inertia), _transpose(R))
    return tuple(tuple(out[i][j] if i <= j else out[j][i] for j in range(3)) for i in range(3))


def _sub(a, b):
    return tuple(x - y for x, y in zip(a, b))


def _add(a, b):
    return tuple(x + y for x, y in zip(a, b))


def _norm(v) -> float:
    return math.sqrt(sum(x * x for x in v))


_IDENTITY = ((1.0, 0.0, 0.0), (0.0, 1.0, 0.0), (0.0, 0.0, 1.0))


def gravity_rotation(gravity: Sequence[float]):
    """``(R, g)``: the rotation taking the gravity direction to ``+y`` (see the module's text) and ``|gravity|``."""
    gx, gy, gz = (float(x) for x in gravity)
    g = _norm((gx, gy, gz))
    if g == 0.0:
        return _IDENTITY, 0.0
    d = (gx / g, gy / g, gz / g)
    if d == (0.0, 1.0, 0.0):
        return _IDENTITY, g
    if d == (0.0, 0.0, -1.0):
        return ((1.0, 0.0, 0.0), (0.0, 0.0, -1.0), (0.0, 1.0, 0.0)), g
    if d == (0.0, -1.0, 0.0):
        return ((-1.0, 0.0, 0.0), (0.0, -1.0, 0.0), (0.0, 0.0, 1.0)), g
    # the smallest rotation: about k = d x y, by the angle between d and y (Rodrigues)
    k = (d[1] * 0.0 - d[2] * 1.0, d[2] * 0.0 - d[0] * 0.0, d[0] * 1.0 - d[1] * 0.0)
    s, c = _norm(k), d[1]
    if s < 1e-300:
        return _IDENTITY, g
    k = tuple(x / s for x in k)
    K = ((0.0, -k[2], k[1]), (k[2], 0.0, -k[0]), (-k[1], k[0], 0.0))
    KK = _matmul(K, K)
    R = tuple(tuple(_IDENTITY[i][j] + s * K[i][j] + (1.0 - c) * KK[i][j] for j in range(3)) for i in range(3))
    return R, g


def _combine(parts):
    """One body from ``(mass, com, inertia about com)`` parts in one frame: ``(mass, com, inertia)``."""
    mass = sum(m for m, _, _ in parts)
    if not mass > 0:
        return 0.0, (0.0, 0.0, 0.0), ((0.0,) * 3,) * 3
    if len(parts) == 1:
        return parts[0]
    com = tuple(sum(m * c[i] for m, c, _ in parts) / mass for i in range(3))
    out = [[0.0] * 3 for _ in range(3)]
    for m, c, inertia in parts:
        r = _sub(c, com)
        rr = sum(x * x for x in r)
        for i in range(3):
            for j in range(3):
                out[i][j] += inertia[i][j] + m * ((rr if i == j else 0.0) - r[i] * r[j])
    return mass, com, tuple(tuple(row) for row in out)


def _check_file(path, what: str) -> Path:
    if not isinstance(path, (str, os.PathLike)):
        raise ParameterError(f"{what}: expected a file name, got {path!r}")
    p = Path(path)
    if not p.exists():
        raise ParameterError(f"{what}: no such file {str(p)!r}")
    if not p.is_file():
        raise ParameterError(f"{what}: {str(p)!r} is not a file")
    return p


def _armature_rotor(k: int, armature: float, links: list, notes: list) -> None:
    """Hold MuJoCo's ``armature`` on joint ``k`` (1-based) as a geared rotor, exactly (see :func:`read_mjcf`)."""
    from ..symbolic.values import check_inertia

    link = links[k - 1]
    if k == 1:
        links[0] = dict(link, rotor=armature, gear=1.0)
        notes.append(f"joint 1 armature {armature:g} kg m^2: rotor = {armature:g}, gear = 1 (exact)")
        return
    e = link["axis"]
    ee = tuple(tuple(e[i] * e[j] for j in range(3)) for i in range(3))
    for gr in (ARMATURE_GEAR, -ARMATURE_GEAR):
        Ir = armature / (gr * (gr - 1.0))
        take_child, take_parent = Ir * gr, Ir * (1.0 - gr)  # what the rotor's energy adds to link k, link k - 1
        child = tuple(tuple(link["inertia"][i][j] - take_child * ee[i][j] for j in range(3)) for i in range(3))
        parent_inertia = links[k - 2]["inertia"]
        parent = tuple(tuple(parent_inertia[i][j] - take_parent * ee[i][j] for j in range(3)) for i in range(3))
        try:
            check_inertia(f"link {k} inertia", child)
            check_inertia(f"link {k - 1} inertia", parent)
        except ParameterError:
            continue
        links[k - 1] = dict(link, rotor=Ir, gear=gr, inertia=child)
        links[k - 2] = dict(links[k - 2], inertia=parent)
        notes.append(f"joint {k} armature {armature:g} kg m^2: a rotor Ir = {Ir:.6g} with gear {gr:g} on link {k - 1} "
                     f"(energy Ir/2 (w + gr q{k}')^2), its share Ir gr = {take_child:.3g} taken from link {k}'s and "
                     f"Ir (1 - gr) = {take_parent:.3g} from link {k - 1}'s inertia about the axis: exactly the armature")
        return
    raise ParameterError(f"joint {k}: its armature {armature:g} kg m^2 cannot be held exactly by a geared rotor "
                         f"(links {k - 1} and {k} have no inertia about the hinge's axis to spare); allowed: armature "
                         "on joint 1, or on bodies with some inertia about their hinge's axis")


def _length(reach: float, span: float, com) -> Optional[float]:
    """A link's rod length: its geometry's reach, else the next hinge's distance, else twice its centre of mass's."""
    if reach > 0:
        return reach
    if span > 0:
        return span
    d = 2.0 * _norm(com)
    return d if d > 0 else None


def _finish(links: list, g: float, notes: list, source: str, actuated, gear, limits, reaches, spans):
    from ..symbolic.chain import Chain, Link

    lengths = [_length(reach, span, link["com"]) for link, reach, span in zip(links, reaches, spans)]
    fallback = max((x for x in lengths if x), default=1.0)
    out = []
    for k, (link, length) in enumerate(zip(links, lengths), start=1):
        if not link["mass"] > 0:
            raise ParameterError(f"link {k} ({link['name']}) has no mass (URDF: no <inertial>, whose inertia no mesh "
                                 "gives; MJCF: no inertial and no geom with mass); a chain's link needs a mass > 0")
        fields = {key: value for key, value in link.items() if key != "name"}
        out.append(Link(length=length or fallback, index=k, **fields))
    chain = Chain(links=tuple(out), g=g)
    for link, given in zip(chain.links, links):
        # an axis given unit (to rounding) is kept as given: normalising it again may move its last bit, and a
        # file skewpend wrote should read back bit for bit
        axis = tuple(float(x) for x in given["axis"])
        if link.axis != axis and abs(sum(x * x for x in axis) - 1.0) <= 4.5e-16:
            object.__setattr__(link, "axis", axis)
    return ImportedModel(chain=chain, actuated=tuple(actuated), gear=tuple(gear), torque_limits=tuple(limits),
                         notes=tuple(notes), source=source)


# -- MJCF ---------------------------------------------------------------------------------------------------
def read_mjcf(path) -> ImportedModel:
    """Read an MJCF file into a chain: MuJoCo compiles it (``mujoco.MjModel.from_xml_path``: its defaults,
    includes, ``inertiafromgeom``, geom densities and shapes, ``fromto``, angle units, Euler sequences) and
    the compiled model is read at ``qpos = 0``.

    Mapped: hinge axes and positions, body masses, centres of mass and inertias, ``opt.gravity`` (the frames:
    see the module's text), joint ``damping``, ``frictionloss`` f as Coulomb friction ``coulomb = 2 f / pi``
    (the same largest torque; MuJoCo's dry friction sticks exactly, skewpend's ``-coulomb atan(cfs q')`` is
    smooth: a note says so), ``armature`` -- on joint 1 ``rotor = armature, gear = 1``; on a later joint
    ``k`` a rotor geared :data:`ARMATURE_GEAR` (or its negative) with ``Ir = A / (gr (gr - 1))`` whose small
    shares of the links' axial inertia (``Ir gr`` from link ``k``, ``Ir (1 - gr)`` from link ``k - 1``) are
    taken from the bodies -- the kinetic energy is then exactly MuJoCo's (export's split, inverted); refused
    if neither body can spare it -- joint actuators (``trntype`` joint: gear, ``ctrlrange`` x gain x gear,
    ``forcerange`` x gear; a constant ``biasprm[0]`` of an affine bias as the joint's constant torque).
    Bodies welded (no joint) to a jointed body with nothing jointed below them are merged into it; bodies
    welded to the world before the first joint are the roof.

    Refused, one line naming it: a joint that is not a hinge, two joints in a body, a jointless body
    between jointed ones, a branch, equality constraints, tendons, springs (``stiffness``), an actuator on
    anything but a joint or with position/velocity feedback, two actuators on one joint, fluid forces,
    a massless link.  Noted and ignored: enabled joint limits (skewpend's joints turn freely), contacts,
    actuator activation dynamics.

    ``mujoco`` is an optional dependency: ``pip install skewpend[validate]``."""
    p = _check_file(path, "read_mjcf")
    try:
        import mujoco
    except ImportError:  # pragma: no cover - depends on the environment
        raise MissingExtraError("read_mjcf needs the optional dependency mujoco, which is not installed: "
                                "pip install \"skewpend[validate]\"") from None
    try:
        model = mujoco.MjModel.from_xml_path(str(p))
    except ValueError as exc:
        detail = " ".join(str(exc).split())
        raise ParameterError(f"read_mjcf: MuJoCo cannot compile {p.name}: {detail}") from None
    return _from_mujoco(mujoco, model, str(p))


def _name(mujoco, model, kind, i: int) -> str:
    name = mujoco.mj_id2name(model, kind, i)
    return repr(name) if name else f"#{i}"


def _from_mujoco(mujoco, model, source: str) -> ImportedModel:
    import numpy as np

    obj = mujoco.mjtObj
    where = Path(source).name
    body = lambda b: f"body {_name(mujoco, model, obj.mjOBJ_BODY, b)}"  # noqa: E731
    joint = lambda j: f"joint {_name(mujoco, model, obj.mjOBJ_JOINT, j)}"  # noqa: E731
    notes: List[str] = []
    kinds = {int(mujoco.mjtJoint.mjJNT_FREE): "free", int(mujoco.mjtJoint.mjJNT_BALL): "ball",
             int(mujoco.mjtJoint.mjJNT_SLIDE): "slide", int(mujoco.mjtJoint.mjJNT_HINGE): "hinge"}
    for j in range(model.njnt):
        kind = kinds.get(int(model.jnt_type[j]), str(model.jnt_type[j]))
        if kind != "hinge":
            raise ParameterError(f"{where}: {joint(j)} in {body(int(model.jnt_bodyid[j]))} is a {kind} joint; "
                                 "a chain holds hinge joints only")
    if model.njnt == 0:
        raise ParameterError(f"{where}: the model has no joint; a chain needs at least one hinge")
    for b in range(1, model.nbody):
        if model.body_jntnum[b] > 1:
            raise ParameterError(f"{where}: {body(b)} has {model.body_jntnum[b]} joints; a chain's body turns on one hinge")
    if model.neq:
        raise ParameterError(f"{where}: {model.neq} equality constraint(s) (first: "
                             f"{_name(mujoco, model, obj.mjOBJ_EQUALITY, 0)}); a chain holds none")
    if model.ntendon:
        raise ParameterError(f"{where}: {model.ntendon} tendon(s) (first: {_name(mujoco, model, obj.mjOBJ_TENDON, 0)}); "
                             "a chain holds none")
    for j in range(model.njnt):
        if model.jnt_stiffness[j] != 0:
            raise ParameterError(f"{where}: {joint(j)} has a spring (stiffness {model.jnt_stiffness[j]:g}); "
                                 "a chain holds no joint springs")
    if model.opt.density or model.opt.viscosity:
        raise ParameterError(f"{where}: fluid forces (option density {model.opt.density:g}, viscosity "
                             f"{model.opt.viscosity:g}); a chain holds none")
    # the chain: the jointed bodies, each the next one's jointed ancestor
    parent = [int(x) for x in model.body_parentid]
    jointed = [b for b in range(1, model.nbody) if model.body_jntnum[b] == 1]

    def jointed_ancestor(b: int) -> int:
        a = parent[b]
        while a != 0 and model.body_jntnum[a] == 0:
            a = parent[a]
        return a

    children: dict = {}
    for b in jointed:
        children.setdefault(jointed_ancestor(b), []).append(b)
    for a, kids in children.items():
        if len(kids) > 1:
            what = "the world" if a == 0 else body(a)
            raise ParameterError(f"{where}: a branch: {what} carries jointed {body(kids[0])} and {body(kids[1])}; "
                                 "a chain is serial")
    order = []
    b = children[0][0]
    while True:
        order.append(b)
        if b not in children:
            break
        b = children[b][0]
    for b in order[1:]:
        a = parent[b]
        if a != order[order.index(b) - 1]:
            raise ParameterError(f"{where}: {body(a)} has no joint but sits between jointed {body(order[order.index(b) - 1])} "
                                 f"and {body(b)}; a chain's bodies turn on hinges (give it a joint or merge it)")
    link_of = {b: k for k, b in enumerate(order, start=1)}
    welded: dict = {k: [] for k in link_of.values()}
    for b in range(1, model.nbody):
        if b in link_of:
            continue
        a = jointed_ancestor(b)
        if a in link_of:
            welded[link_of[a]].append(b)

    data = mujoco.MjData(model)
    data.qpos[:] = 0.0
    mujoco.mj_kinematics(model, data)
    R, g = gravity_rotation(model.opt.gravity)
    if model.opt.disableflags & int(mujoco.mjtDisableBit.mjDSBL_GRAVITY):
        g = 0.0
        notes.append("gravity is disabled in the model (option flag gravity): g = 0")
    if g == 0.0:
        notes.append("no gravity: g = 0, the world's axes kept")
    elif R != _IDENTITY:
        d = tuple(float(x) / g for x in model.opt.gravity)
        notes.append(f"frame: gravity along ({d[0]:.6g}, {d[1]:.6g}, {d[2]:.6g}) turned to skewpend's +y (y down)"
                     + (": (x, y, z) -> (x, -z, y)" if d == (0.0, 0.0, -1.0) else ""))
    damper = not model.opt.disableflags & int(mujoco.mjtDisableBit.mjDSBL_DAMPER)
    constraint = not model.opt.disableflags & int(mujoco.mjtDisableBit.mjDSBL_CONSTRAINT)  # no limits, contacts, friction
    friction = constraint and not model.opt.disableflags & int(mujoco.mjtDisableBit.mjDSBL_FRICTIONLOSS)
    Rt = np.array(R)
    links, anchors, reaches = [], [], []
    jnt_of = {int(model.jnt_bodyid[j]): j for j in range(model.njnt)}
    for k, b in enumerate(order, start=1):
        j = jnt_of[b]
        anchor = np.array(data.xanchor[j], dtype=float)
        anchors.append(tuple(float(x) for x in Rt @ anchor))
        parts = []
        geoms = []
        for c in [b] + welded[k]:
            m = float(model.body_mass[c])
            X = np.array(data.ximat[c], dtype=float).reshape(3, 3)
            inertia = Rt @ X @ np.diag(model.body_inertia[c]) @ X.T @ Rt.T
            parts.append((m, tuple(float(x) for x in Rt @ (data.xipos[c] - anchor)),
                          tuple(tuple(float(x) for x in row) for row in 0.5 * (inertia + inertia.T))))
            geoms += [i for i in range(model.ngeom) if model.geom_bodyid[i] == c]
        if welded[k]:
            notes.append(f"link {k}: {', '.join(body(c) for c in welded[k])} welded to {body(b)} (no joint), merged")
        mass, com, inertia = _combine(parts)
        reach = 0.0
        for i in geoms:
            centre = np.array(data.geom_xpos[i]) - anchor
            ends = [centre]
            if int(model.geom_type[i]) in (int(mujoco.mjtGeom.mjGEOM_CAPSULE), int(mujoco.mjtGeom.mjGEOM_CYLINDER)):
                half = np.array(data.geom_xmat[i]).reshape(3, 3)[:, 2] * model.geom_size[i][1]
                ends = [centre + half, centre - half]
            reach = max([reach] + [float(np.linalg.norm(e)) for e in ends])
        reaches.append(reach)
        axis = tuple(float(x) for x in Rt @ np.array(data.xaxis[j], dtype=float))
        frictionloss = float(model.dof_frictionloss[model.jnt_dofadr[j]]) if friction else 0.0
        links.append(dict(name=body(b), axis=axis, offset=None, mass=mass, com=com, inertia=inertia,
                          damping=float(model.dof_damping[model.jnt_dofadr[j]]) if damper else 0.0,
                          coulomb=2.0 * frictionloss / math.pi))
        if frictionloss:
            notes.append(f"joint {k} frictionloss {frictionloss:g} N m as Coulomb friction coulomb = 2 f / pi = "
                         f"{2.0 * frictionloss / math.pi:.6g} (the same largest torque; MuJoCo's dry friction sticks "
                         "exactly, skewpend's -coulomb atan(cfs q') is smooth)")
        if model.qpos0[model.jnt_qposadr[j]] != 0:
            notes.append(f"joint {k} ({joint(j)}): its ref (qpos0) {model.qpos0[model.jnt_qposadr[j]]:g} is not skewpend's "
                         "zero; q is MuJoCo's qpos, zero in the model as written")
        if model.jnt_limited[j] and constraint and not model.opt.disableflags & int(mujoco.mjtDisableBit.mjDSBL_LIMIT):
            lo, hi = model.jnt_range[j]
            notes.append(f"joint {k} ({joint(j)}): its limits [{lo:g}, {hi:g}] are ignored (skewpend's joints turn freely)")
    for k in range(1, len(links) + 1):
        links[k - 1]["offset"] = tuple(_sub(anchors[k - 1], anchors[k - 2])) if k > 1 else anchors[0]
    for k, b in enumerate(order, start=1):
        arm = float(model.dof_armature[model.jnt_dofadr[jnt_of[b]]])
        if arm:
            _armature_rotor(k, arm, links, notes)
    # actuators
    actuated, gears, limits = [], [], []
    joint_link = {jnt_of[b]: k for k, b in enumerate(order, start=1)}
    torques = [0.0] * len(links)
    affine = int(mujoco.mjtBias.mjBIAS_AFFINE)
    for a in range(model.nu):
        name = f"actuator {_name(mujoco, model, obj.mjOBJ_ACTUATOR, a)}"
        if int(model.actuator_trntype[a]) != int(mujoco.mjtTrn.mjTRN_JOINT):
            raise ParameterError(f"{where}: {name} drives no joint (transmission type {int(model.actuator_trntype[a])}); "
                                 "a chain's actuators are joint torques")
        j = int(model.actuator_trnid[a][0])
        if j not in joint_link:
            raise ParameterError(f"{where}: {name} drives {joint(j)}, which is not in the chain")
        k = joint_link[j]
        if k in actuated:
            raise ParameterError(f"{where}: {name} is a second actuator on joint {k} ({joint(j)}); one a joint")
        gear = float(model.actuator_gear[a][0])
        gain = float(model.actuator_gainprm[a][0]) if int(model.actuator_gaintype[a]) == int(mujoco.mjtGain.mjGAIN_FIXED) else None
        if gain is None:
            raise ParameterError(f"{where}: {name} has a gain that is not fixed; a chain's actuators are torques")
        if int(model.actuator_biastype[a]) == affine:
            bias = model.actuator_biasprm[a]
            if bias[1] or bias[2]:
                raise ParameterError(f"{where}: {name} has position/velocity feedback (biasprm {bias[0]:g} {bias[1]:g} "
                                     f"{bias[2]:g}); a chain's actuators are torques")
            if bias[0]:
                torques[k - 1] += gear * float(bias[0])
                notes.append(f"{name}: its constant bias force {bias[0]:g} x gear {gear:g} as joint {k}'s constant torque")
        elif int(model.actuator_biastype[a]) != int(mujoco.mjtBias.mjBIAS_NONE):
            raise ParameterError(f"{where}: {name} has a bias type skewpend cannot hold; a chain's actuators are torques")
        if int(model.actuator_dyntype[a]) != int(mujoco.mjtDyn.mjDYN_NONE):
            notes.append(f"{name}: its activation dynamics are ignored (the control is the force)")
        limit = math.inf
        if model.actuator_ctrllimited[a]:
            limit = min(limit, abs(gear * gain) * float(np.max(np.abs(model.actuator_ctrlrange[a]))))
            lo, hi = model.actuator_ctrlrange[a]
            if lo != -hi:
                notes.append(f"{name}: its ctrlrange [{lo:g}, {hi:g}] is not symmetric; the torque limit is the larger side's")
        if model.actuator_forcelimited[a]:
            limit = min(limit, abs(gear) * float(np.max(np.abs(model.actuator_forcerange[a]))))
        actuated.append(k)
        gears.append(gear)
        limits.append(limit if math.isfinite(limit) else None)
    for k, tau in enumerate(torques, start=1):
        if tau:
            links[k - 1]["torque"] = tau
    contacts = [i for i in range(model.ngeom)
                if (model.geom_contype[i] or model.geom_conaffinity[i]) and model.geom_bodyid[i] in link_of]
    if contacts and constraint and not model.opt.disableflags & int(mujoco.mjtDisableBit.mjDSBL_CONTACT):
        notes.append(f"contacts ignored: {len(contacts)} geom(s) of the chain's bodies may collide in MuJoCo "
                     "(contype/conaffinity), a chain has no contacts")
    ordered = sorted(range(len(actuated)), key=lambda i: actuated[i])
    spans = [_norm(_sub(anchors[k], anchors[k - 1])) for k in range(1, len(anchors))] + [0.0]
    return _finish(links, g, notes, source, [actuated[i] for i in ordered], [gears[i] for i in ordered],
                   [limits[i] for i in ordered], reaches, spans)


# -- URDF ---------------------------------------------------------------------------------------------------
def _floats(text, n: int, what: str):
    try:
        values = tuple(float(x) for x in (text or "").split())
    except ValueError:
        raise ParameterError(f"{what}: expected {n} numbers, got {text!r}") from None
    if len(values) != n or not all(math.isfinite(x) for x in values):
        raise ParameterError(f"{what}: expected {n} finite numbers, got {text!r}")
    return values


def _cs(angle: float):
    """cos and sin, exact at the quarter turns (so a frame turned by pi/2 reads back exactly)."""
    quarter = {0.0: (1.0, 0.0), math.pi / 2: (0.0, 1.0), -math.pi / 2: (0.0, -1.0), math.pi: (-1.0, 0.0),
               -math.pi: (-1.0, 0.0)}
    return quarter.get(angle, (math.cos(angle), math.sin(angle)))


def _rpy(rpy):
    """URDF's fixed-axis roll, pitch, yaw: ``Rz(yaw) Ry(pitch) Rx(roll)``."""
    (cr, sr), (cp, sp), (cy, sy) = (_cs(a) for a in rpy)
    if rpy == (0.0, 0.0, 0.0):
        return _IDENTITY
    Rx = ((1.0, 0.0, 0.0), (0.0, cr, -sr), (0.0, sr, cr))
    Ry = ((cp, 0.0, sp), (0.0, 1.0, 0.0), (-sp, 0.0, cp))
    Rz = ((cy, -sy, 0.0), (sy, cy, 0.0), (0.0, 0.0, 1.0))
    return _matmul(Rz, _matmul(Ry, Rx))


def _origin(el, what: str):
    o = el.find("origin") if el is not None else None
    if o is None:
        return (0.0, 0.0, 0.0), _IDENTITY
    xyz = _floats(o.get("xyz", "0 0 0"), 3, f"{what} origin xyz")
    rpy = _floats(o.get("rpy", "0 0 0"), 3, f"{what} origin rpy")
    return xyz, _rpy(rpy)


def _inertial(link, name: str):
    """``(mass, com, inertia about com)`` in the link's frame (zero mass without <inertial>)."""
    el = link.find("inertial")
    if el is None:
        return 0.0, (0.0, 0.0, 0.0), ((0.0,) * 3,) * 3
    xyz, R = _origin(el, f"link {name!r} inertial")
    m = el.find("mass")
    mass = _floats(m.get("value") if m is not None else None, 1, f"link {name!r} mass")[0]
    i = el.find("inertia")
    if i is None:
        raise ParameterError(f"link {name!r}: <inertial> without <inertia>")
    e = {key: _floats(i.get(key, "0"), 1, f"link {name!r} inertia {key}")[0]
         for key in ("ixx", "ixy", "ixz", "iyy", "iyz", "izz")}
    tensor = ((e["ixx"], e["ixy"], e["ixz"]), (e["ixy"], e["iyy"], e["iyz"]), (e["ixz"], e["iyz"], e["izz"]))
    return mass, xyz, (tensor if R is _IDENTITY else _sandwich(R, tensor))


def read_urdf(path, g: Optional[float] = None, up: Optional[Sequence[float]] = None) -> ImportedModel:
    """Read a URDF file into a chain (pure Python, :mod:`xml.etree.ElementTree`).

    Links' ``<inertial>`` (origin ``xyz rpy``, mass, inertia), ``revolute`` and ``continuous`` joints (origin,
    ``<axis>``, parent and child), ``<dynamics damping friction>`` (friction f as Coulomb friction
    ``coulomb = 2 f / pi``, noted), ``<limit effort>`` (the joint counts as actuated, gear 1, the effort its
    torque limit; a revolute joint's position limits are ignored, noted).  ``fixed`` joints are welds: the
    child's mass is merged into the link it hangs on (before the first hinge: the roof).

    Gravity is not part of URDF: ``g`` [m/s^2] along ``-up`` (in the URDF's root frame).  Left None, they come
    from the file's ``<mujoco><option gravity>`` block if it has one (skewpend's exports write it: ``0 g 0``
    in skewpend's own frame, ``0 0 -g`` with ``z_up``), else ``g = 9.81`` and ``up = (0, 0, 1)``.  The frames:
    see the module's text.  Refused, one line: a joint of another type (prismatic, floating, planar), a
    branch, a malformed file."""
    import xml.etree.ElementTree as ET

    p = _check_file(path, "read_urdf")
    where = p.name
    try:
        root = ET.parse(p).getroot()
    except ET.ParseError as exc:
        raise ParameterError(f"read_urdf: {where} is not XML: {exc}") from None
    if root.tag != "robot":
        raise ParameterError(f"read_urdf: {where} is not a URDF (its root element is <{root.tag}>, not <robot>)")
    notes: List[str] = []
    gravity = None
    option = root.find("mujoco/option")
    if option is not None and option.get("gravity") is not None:
        gravity = _floats(option.get("gravity"), 3, f"{where}: <mujoco><option gravity>")
    if g is not None or up is not None or gravity is None:
        gv = 9.81 if g is None else float(g)
        u = (0.0, 0.0, 1.0) if up is None else tuple(float(x) for x in up)
        nu = _norm(u)
        if len(u) != 3 or not nu > 0 or not math.isfinite(gv) or gv < 0:
            raise ParameterError(f"read_urdf: up must be a non-zero 3-vector and g >= 0, got up={up!r}, g={g!r}")
        gravity = tuple(-gv * x / nu for x in u)
        notes.append(f"gravity (not part of URDF): g = {gv:g} along -up = ({-u[0] / nu:g}, {-u[1] / nu:g}, {-u[2] / nu:g})")
    R, gm = gravity_rotation(gravity)
    links = {el.get("name"): el for el in root.findall("link")}
    joints = root.findall("joint")
    child_of: dict = {}
    kids: dict = {}
    for jel in joints:
        jname = jel.get("name")
        kind = jel.get("type")
        if kind not in ("revolute", "continuous", "fixed"):
            raise ParameterError(f"{where}: joint {jname!r} is {kind!r}; a chain holds revolute and continuous "
                                 "joints (fixed ones are merged)")
        par, ch = jel.find("parent"), jel.find("child")
        if par is None or ch is None or par.get("link") not in links or ch.get("link") not in links:
            raise ParameterError(f"{where}: joint {jname!r} needs <parent link> and <child link> naming links of the file")
        if ch.get("link") in child_of:
            raise ParameterError(f"{where}: link {ch.get('link')!r} is the child of joints "
                                 f"{child_of[ch.get('link')].get('name')!r} and {jname!r}; a chain is a tree without loops")
        child_of[ch.get("link")] = jel
        kids.setdefault(par.get("link"), []).append(jel)
    roots = [name for name in links if name not in child_of]
    if len(roots) != 1:
        raise ParameterError(f"{where}: expected one root link, found {len(roots)} ({', '.join(map(repr, roots[:3]))})")

    def moving_below(name: str) -> bool:
        return any(j.get("type") != "fixed" or moving_below(j.find("child").get("link")) for j in kids.get(name, []))

    # walk down: world transform (rotation W, position x) of each link frame at q = 0
    chain: list = []  # per hinge: dict of the link being built
    reaches: list = []
    actuated, gears, limits = [], [], []
    stack = [(roots[0], _IDENTITY, (0.0, 0.0, 0.0), 0)]  # link, rotation, position (world, turned by R), link number
    parts: dict = {0: []}
    frames = {0: (_IDENTITY, (0.0, 0.0, 0.0))}
    while stack:
        name, W, x, k = stack.pop()
        if k:
            mass, com, inertia = _inertial(links[name], name)
            Wk, xk = frames[k]
            # the inertial in the hinge link's axes (world-parallel), about its hinge
            parts[k].append((mass, _add(_matvec(W, com), _sub(x, xk)) if W is not _IDENTITY or x != xk else
                             _matvec(W, com), _sandwich(W, inertia) if W is not _IDENTITY else inertia))
            for tag in ("visual", "collision"):
                for el in links[name].findall(tag):
                    o, Ro = _origin(el, f"link {name!r} {tag}")
                    ends = [o]
                    shape = el.find("geometry/cylinder")
                    shape = shape if shape is not None else el.find("geometry/capsule")
                    if shape is not None and shape.get("length") is not None:
                        half = _floats(shape.get("length"), 1, f"link {name!r} {tag} length")[0] / 2.0
                        ez = (Ro[0][2] * half, Ro[1][2] * half, Ro[2][2] * half)
                        ends = [_add(o, ez), _sub(o, ez)]
                    for end in ends:
                        reaches[k - 1] = max(reaches[k - 1], _norm(_add(_matvec(W, end), _sub(x, xk))))
        moving = [j for j in kids.get(name, []) if j.get("type") != "fixed" or moving_below(j.find("child").get("link"))]
        if len(moving) > 1:
            raise ParameterError(f"{where}: a branch: link {name!r} carries joints {moving[0].get('name')!r} and "
                                 f"{moving[1].get('name')!r}; a chain is serial")
        for jel in kids.get(name, []):
            jname, child = jel.get("name"), jel.find("child").get("link")
            xyz, Rj = _origin(jel, f"joint {jname!r}")
            Wc = W if Rj is _IDENTITY else _matmul(W, Rj)
            if jel.get("type") == "fixed":
                if k and moving_below(child):
                    raise ParameterError(f"{where}: fixed joint {jname!r} between hinges; merge link {child!r} into "
                                         f"{name!r} or give it a hinge")
                if k and links[child].find("inertial") is not None:  # before the first hinge: the roof
                    notes.append(f"link {k}: link {child!r} fixed (joint {jname!r}) to it, merged")
                stack.append((child, Wc, _add(x, _matvec(W, xyz)), k))
                continue
            kc = len(chain) + 1
            RW = _matmul(R, W)
            offset = _matvec(RW, xyz)
            if kc == 1:
                offset = _add(_matvec(R, x), offset) if x != (0.0, 0.0, 0.0) else offset
            ax = jel.find("axis")
            axis = _floats(ax.get("xyz") if ax is not None else "1 0 0", 3, f"joint {jname!r} axis")
            dyn = jel.find("dynamics")
            damping = _floats(dyn.get("damping", "0"), 1, f"joint {jname!r} damping")[0] if dyn is not None else 0.0
            fric = _floats(dyn.get("friction", "0"), 1, f"joint {jname!r} friction")[0] if dyn is not None else 0.0
            if fric:
                notes.append(f"joint {kc} friction {fric:g} N m as Coulomb friction coulomb = 2 f / pi = "
                             f"{2 * fric / math.pi:.6g} (the same largest torque; skewpend's is smooth)")
            lim = jel.find("limit")
            if lim is not None and lim.get("effort") is not None:
                effort = _floats(lim.get("effort"), 1, f"joint {jname!r} effort")[0]
                if effort > 0:
                    actuated.append(kc)
                    gears.append(1.0)
                    limits.append(effort)
            if jel.get("type") == "revolute" and lim is not None and (lim.get("lower") or lim.get("upper")):
                notes.append(f"joint {kc} ({jname!r}): its limits [{lim.get('lower', '0')}, {lim.get('upper', '0')}] "
                             "are ignored (skewpend's joints turn freely)")
            chain.append(dict(name=f"link {child!r}", axis=_matvec(RW, _matvec(Rj, axis)) if (RW is not _IDENTITY or
                              Rj is not _IDENTITY) else axis, offset=offset, damping=damping, coulomb=2 * fric / math.pi))
            reaches.append(0.0)
            parts[kc] = []
            frames[kc] = (Wc, _add(x, _matvec(W, xyz)))
            stack.append((child, Wc, frames[kc][1], kc))
    if not chain:
        raise ParameterError(f"{where}: no revolute or continuous joint; a chain needs at least one hinge")
    for k, link in enumerate(chain, start=1):
        mass, com, inertia = _combine(parts[k])
        link.update(mass=mass, com=_matvec(R, com) if R is not _IDENTITY else com,
                    inertia=_sandwich(R, inertia) if R is not _IDENTITY else inertia)
    spans = [_norm(chain[k]["offset"]) for k in range(1, len(chain))] + [0.0]
    return _finish(chain, gm, notes, str(p), actuated, gears, limits, reaches, spans)


#: The suffixes of the model files :func:`read_model` reads, and their readers.
MODEL_SUFFIXES = {".xml": "mjcf", ".mjcf": "mjcf", ".urdf": "urdf"}


def read_model(path) -> ImportedModel:
    """An MJCF (``.xml``, ``.mjcf``) or URDF (``.urdf``) file, by its suffix (:func:`read_mjcf`,
    :func:`read_urdf` with the file's gravity, else 9.81 with +z up)."""
    kind = MODEL_SUFFIXES.get(Path(path).suffix.lower())
    if kind is None:
        raise ParameterError(f"{path}: a model file is MJCF ({', '.join(k for k, v in MODEL_SUFFIXES.items() if v == 'mjcf')}) "
                             "or URDF (.urdf)")
    return read_mjcf(path) if kind == "mjcf" else read_urdf(path)


def run_sections(model: ImportedModel) -> dict:
    """The run file's sections of an imported model -- ``chain`` (g, cfs) and ``links`` (one table a link, as
    ``[[links]]`` tables hold them) -- so that every command that reads a chain's run file reads the model."""
    data = model.chain.to_dict()
    links = data.pop("links")
    return {"chain": data, "links": links}
