"""Export the skewed double pendulum to MuJoCo (MJCF) and URDF, and simulate it in MuJoCo.

The exported models are the system skewpend derives its equations for (see
:class:`~skewpend.Parameters`): basis ``i, j, k`` = ``x, y, z`` with ``j = +y`` pointing
**down**, gravity ``g`` along ``+y``; rod 1 turns about ``axis1`` through the origin, rod 2
about ``axis2`` (fixed in rod 1) through ``a j`` on rod 1; each body frame has its origin at
its hinge and is aligned with ``x, y, z`` when both rods hang (``phi = psi = 0``).  Joint
angles are right-handed about the axes, as in skewpend and MuJoCo.

Functions:

* :func:`mujoco_compatible` -- the parameters with explicit centres of mass and inertia
  tensors, including the tiny inertia MuJoCo needs (below); simulate *these* in skewpend to
  compare with MuJoCo;
* :func:`to_mjcf` -- MuJoCo MJCF XML (self-contained: gravity, damping and constant torques
  are all in the file);
* :func:`to_urdf` -- URDF (gravity and constant torques are not part of URDF; see there);
* :func:`write_model` -- either of them to a file, atomically;
* :func:`mujoco_trajectory` -- load the MJCF in MuJoCo and step it (``mujoco`` is an
  optional dependency, imported only there: ``pip install skewpend[validate]``).

The tiny inertia
----------------
MuJoCo refuses a body whose inertia tensor is not positive definite ("inertia must have
positive eigenvalues") and checks the triangle inequality of the principal moments
``A + B >= C`` exactly (no tolerance).  A thin rod has zero moment about its own axis, so
skewpend's default bodies cannot be exported as they are.  :func:`mujoco_compatible` adds
``eps`` = ``axial_inertia`` [kg m^2] (default ``max(1e-9 m l^2, 1e-12)`` per body, ``l = a``
for rod 1, ``b`` for rod 2; the floor keeps ``eps`` above MuJoCo's smallest accepted principal
moment, about 1e-14) along the principal axes that need it:

* every principal moment below ``eps / 2`` is raised by ``eps`` (the thin rod's axial
  moment ``0 -> eps``; a point mass gets ``eps`` about every axis);
* if the principal moments then satisfy the triangle inequality with a margin below
  ``eps / 2`` (a flat plate, ``C = A + B``), the smallest one is raised by ``eps`` again,
  so rounding in MuJoCo's eigen-decomposition cannot break the check.

Bodies that need none of this are exported unchanged.  The change is of relative size
``~1e-8`` and only matters when rod 2 spins about its own axis (skewed hinges): over 2 s of
large swings it moves the state by a few 1e-9.  A comparison to round-off precision must
nevertheless simulate the identical system, ``derive(mujoco_compatible(params))`` -- which
is what the exported files contain.
"""

from __future__ import annotations

import math
import os
from pathlib import Path
from typing import Optional, Sequence, Tuple, Union

from ..errors import IntegrationError, MissingExtraError, ParameterError
from ..symbolic.model import Parameters
from ..parsing import initial_state, positive_number
from ..schema import CORE_NAMES, DAMPING_NAMES, LENGTH_NAMES, MASS_NAMES, ROTOR_NAMES, TORQUE_NAMES

__all__ = [
    "FORMATS",
    "INTEGRATORS",
    "MujocoMissingError",
    "mujoco_compatible",
    "to_mjcf",
    "to_urdf",
    "write_model",
    "mujoco_trajectory",
]

#: Export formats accepted by :func:`write_model`, and the file suffixes that imply them.
FORMATS = ("mjcf", "urdf")
_SUFFIXES = {".xml": "mjcf", ".mjcf": "mjcf", ".urdf": "urdf"}
_OPTIONS = {"mjcf": ("timestep", "integrator", "axial_inertia"), "urdf": ("axial_inertia", "z_up")}

#: MuJoCo integrators accepted by :func:`to_mjcf` and :func:`mujoco_trajectory`.
INTEGRATORS = ("RK4", "Euler", "implicit", "implicitfast")

#: Most MuJoCo steps :func:`mujoco_trajectory` takes in one run (refused up front beyond it).
MAX_MUJOCO_STEPS = 100_000_000
#: MuJoCo steps per call into ``mj_step``, so Ctrl-C is honoured within a fraction of a second.
_MUJOCO_CHUNK = 20_000

#: Default tiny inertia, relative to ``m l^2`` of each body.
AXIAL_INERTIA_FACTOR = 1e-9
#: Floor of the default tiny inertia [kg m^2] (MuJoCo rejects principal moments below ~1e-14).
AXIAL_INERTIA_FLOOR = 1e-12


class MujocoMissingError(MissingExtraError):
    """The optional dependency ``mujoco`` is needed but not installed (a
    :class:`~skewpend.errors.MissingExtraError`)."""


# -- helpers -----------------------------------------------------------------------------------
def _num(x: float) -> str:
    """A float as text that reads back to the same double (shortest round-trip form)."""
    x = float(x)
    if x == 0.0:
        return "0"
    if x.is_integer() and abs(x) < 1e15:
        return str(int(x))
    return repr(x)


def _vec(v: Sequence[float]) -> str:
    return " ".join(_num(x) for x in v)


def _comment(text: str) -> str:
    """XML comment body: ``--`` is not allowed inside comments."""
    while "--" in text:
        text = text.replace("--", "- -")
    return text


def _integrator(name: str) -> str:
    for allowed in INTEGRATORS:
        if isinstance(name, str) and name.lower() == allowed.lower():
            return allowed
    raise ParameterError(f"unknown MuJoCo integrator {name!r}; allowed: {', '.join(INTEGRATORS)}")


def _axes(params: Parameters) -> Tuple[Tuple[float, float, float], Tuple[float, float, float]]:
    axis1 = params.axis1 if params.axis1 is not None else (0.0, 0.0, 1.0)
    if params.axis2 is not None:
        axis2 = params.axis2
    else:
        alpha = float(params.alpha)
        axis2 = (math.sin(alpha), 0.0, math.cos(alpha))  # e0 = cos(alpha) k + sin(alpha) i
    return tuple(map(float, axis1)), tuple(map(float, axis2))  # type: ignore[return-value]


def _regularised_inertia(inertia, eps: float):
    """``inertia`` (3x3) plus ``eps`` along the principal axes that MuJoCo would reject."""
    import numpy as np

    orig = np.array(inertia, dtype=float)
    if not np.all(np.isfinite(orig)) or not math.isfinite(eps):
        return tuple(tuple(float(x) for x in row) for row in orig)  # refused by the caller
    # overflow (entries near 1e308) leaves inf/nan in the result, which the caller refuses
    with np.errstate(over="ignore", invalid="ignore"):
        m = 0.5 * orig + 0.5 * orig.T  # = (orig + orig.T) / 2, without overflow for entries near 1e308
        scale = float(np.max(np.abs(m)))
        if scale > 1e150:  # keep LAPACK's sums of squares finite
            lam, vec = np.linalg.eigh(m / scale)  # ascending
            lam = lam * scale
        else:
            lam, vec = np.linalg.eigh(m)  # ascending
        add = np.where(lam < 0.5 * eps, eps, 0.0)
        lam2 = lam + add
        margin = float(np.min(lam2.sum() - 2.0 * lam2))  # min over i of (sum of the others - lam_i)
        if margin < 0.5 * eps:
            add[0] += eps
        if not np.any(add):
            return tuple(tuple(float(x) for x in row) for row in orig)
        out = m + (vec * add) @ vec.T
        out = 0.5 * (out + out.T)
        # entries that were exactly zero and moved by round-off only stay exactly zero
        # (a thin rod along y: only the yy entry changes)
        out[(orig == 0.0) & (np.abs(out) < 1e-3 * eps)] = 0.0
        return tuple(tuple(float(x) for x in row) for row in out)


def _default_bodies(params: Parameters):
    a, b, m1, m2 = (float(getattr(params, n)) for n in LENGTH_NAMES + MASS_NAMES)
    com1 = params.com1 if params.com1 is not None else (0.0, a / 2, 0.0)
    com2 = params.com2 if params.com2 is not None else (0.0, b / 2, 0.0)

    def rod(m, length):
        k = m * (length * length) / 12  # inf, not OverflowError, when it overflows (refused by the caller)
        return ((k, 0.0, 0.0), (0.0, 0.0, 0.0), (0.0, 0.0, k))

    inertia1 = params.inertia1 if params.inertia1 is not None else rod(m1, a)
    inertia2 = params.inertia2 if params.inertia2 is not None else rod(m2, b)
    return com1, com2, inertia1, inertia2


# -- public API --------------------------------------------------------------------------------
def mujoco_compatible(params: Parameters, axial_inertia: Optional[float] = None) -> Parameters:
    """``params`` with explicit ``com1, com2, inertia1, inertia2`` that MuJoCo accepts.

    The thin-rod defaults are written out, and each body gets the tiny inertia described
    in the module docstring: ``axial_inertia`` [kg m^2] for both bodies if given, otherwise
    ``max(1e-9 m1 a^2, 1e-12)`` for rod 1 and ``max(1e-9 m2 b^2, 1e-12)`` for rod 2.  Everything else (scalars,
    axes, ``alpha``) is unchanged.  This is exactly the system :func:`to_mjcf` and
    :func:`to_urdf` export; ``derive(mujoco_compatible(p))`` is the reference for comparing
    skewpend with MuJoCo.  Idempotent for the default ``axial_inertia``.
    """
    params.require_numeric("export")
    eps = positive_number("axial_inertia", axial_inertia, allow_none=True)
    a, b, m1, m2 = (float(getattr(params, n)) for n in LENGTH_NAMES + MASS_NAMES)
    eps1 = eps if eps is not None else max(AXIAL_INERTIA_FACTOR * m1 * a * a, AXIAL_INERTIA_FLOOR)
    eps2 = eps if eps is not None else max(AXIAL_INERTIA_FACTOR * m2 * b * b, AXIAL_INERTIA_FLOOR)
    com1, com2, inertia1, inertia2 = _default_bodies(params)
    bodies = []
    for k, (inertia, eps_k) in enumerate(((inertia1, eps1), (inertia2, eps2)), start=1):
        given = getattr(params, f"inertia{k}") is not None
        what = f"the inertia tensor of body {k}" + ("" if given else f" (thin rod m{k} l^2/12)")
        if not _finite(inertia):
            raise _overflow(params, what)
        if not math.isfinite(eps_k):
            raise _overflow(params, f"the tiny axial inertia of body {k} (1e-9 m{k} l^2)")
        try:
            regularised = _regularised_inertia(inertia, eps_k)
        except (ArithmeticError, ValueError):  # numpy.linalg.LinAlgError is a ValueError
            raise _overflow(params, what) from None
        if not _finite(regularised):
            raise _overflow(params, what)
        bodies.append(regularised)
    return params.replace(
        com1=tuple(map(float, com1)),
        com2=tuple(map(float, com2)),
        inertia1=bodies[0],
        inertia2=bodies[1],
    )


def _no_friction(params: Parameters, fmt: str) -> None:
    if params.has_friction:
        raise ParameterError(
            f"export {fmt}: Coulomb friction (cf1 = {params.cf1:g}, cf2 = {params.cf2:g}) has no exact counterpart: "
            "skewpend's torque is the smooth -cf atan(cfs q'), MuJoCo's frictionloss a dry-friction constraint "
            "(up to frictionloss, sticking exactly) and URDF's <dynamics friction> is left to the simulator; export "
            "the model with cf1 = cf2 = 0 (set frictionloss yourself if you want MuJoCo's model: cf pi/2 is the "
            "same largest torque)")


def _rotor_split(p: Parameters) -> Tuple[Parameters, Tuple[float, float]]:
    """The rotors' kinetic energy as MuJoCo can hold it, exactly: ``armature`` on the hinges
    and an axial inertia about the second hinge's axis ``e0`` in each rod.  With ``c = n1 . e0``
    the rotors add ``Ir gr^2 + Ir c^2``, ``Ir gr c``, ``Ir gr^2`` to ``M``; an inertia ``J e0 e0^T``
    in rod 2 adds ``J (c^2, c, 1)``, in rod 1 ``J (c^2, 0, 0)``, an armature ``A_i`` adds to
    ``M_ii`` alone; so ``J2 = Ir gr``, ``J1 = Ir (1 - gr)``, ``A1 = Ir gr^2``, ``A2 = Ir gr (gr - 1)``.
    Returns the model with those inertias added (``Ir = 0``) and ``(A1, A2)``; refuses a split a
    simulator cannot take (a negative armature, a body inertia no longer physical)."""
    import numpy as np

    if not p.has_rotor:
        return p, (0.0, 0.0)
    Ir, gr = float(p.Ir), float(p.gr)
    _, e0 = _axes(p)
    ee = np.outer(e0, e0)
    A1, A2 = Ir * gr * gr, Ir * gr * (gr - 1.0)
    J1, J2 = Ir * (1.0 - gr), Ir * gr
    why = ("the rotors' inertia Ir (reflected through the gear gr) maps exactly onto MuJoCo only as armature "
           f"A1 = Ir gr^2, A2 = Ir gr (gr - 1) and axial inertias Ir (1 - gr) (rod 1) and Ir gr (rod 2) about "
           f"hinge 2's axis; for Ir = {Ir:g}, gr = {gr:g}")
    if A2 < 0:
        raise ParameterError(f"export: {why} the armature A2 = {A2:g} would be negative (0 < gr < 1)")
    try:
        q = p.replace(Ir=0.0, inertia1=(np.array(p.inertia1, dtype=float) + J1 * ee).tolist(),
                      inertia2=(np.array(p.inertia2, dtype=float) + J2 * ee).tolist())
    except ParameterError as exc:
        raise ParameterError(f"export: {why} a body's inertia would not be physical: {exc}") from None
    return q, (A1, A2)


def _finite(values) -> bool:
    """Every number in a (nested) sequence of floats is finite."""
    if isinstance(values, (list, tuple)):
        return all(_finite(v) for v in values)
    return math.isfinite(float(values))


def _overflow(params: Parameters, what: str) -> ParameterError:
    sizes = ", ".join(f"{n} = {float(getattr(params, n)):g}" for n in LENGTH_NAMES + MASS_NAMES)
    return ParameterError(
        f"export: {what} is not a finite number (overflow) for {sizes}; allowed: parameters of moderate size, "
        "for which every number in the model (lengths, masses, m l^2, inertia tensors) is a finite double"
    )


def _fullinertia(m) -> str:
    """MuJoCo's ``fullinertia`` order: Ixx Iyy Izz Ixy Ixz Iyz."""
    return _vec((m[0][0], m[1][1], m[2][2], m[0][1], m[0][2], m[1][2]))


def _header(params: Parameters, fmt: str) -> str:
    from .. import __version__

    values = ", ".join(
        f"{n}={_num(getattr(params, n))}"
        for n in CORE_NAMES + DAMPING_NAMES + TORQUE_NAMES + ROTOR_NAMES * params.has_rotor
        if getattr(params, n) is not None
    )
    return _comment(
        f"Skewed double pendulum exported by skewpend {__version__} ({fmt}). "
        f"Parameters: {values}. Frame: x, y, z = i, j, k of skewpend with y pointing DOWN; "
        "gravity g acts along +y. Joint angles hinge1 = phi, hinge2 = psi (right-handed, "
        "zero with both rods hanging along +y). Inertias include skewpend's tiny axial "
        "inertia (skewpend.export.mujoco_compatible)."
    )


def to_mjcf(
    params: Parameters,
    *,
    timestep: float = 1e-4,
    integrator: str = "RK4",
    axial_inertia: Optional[float] = None,
) -> str:
    """A MuJoCo MJCF model (XML text) of the pendulum ``params`` (all numeric).

    * ``<option gravity="0 g 0">`` -- gravity along **+y** (skewpend's ``j`` points down);
      ``timestep`` [s] and ``integrator`` (``RK4`` default; ``Euler``, ``implicit``,
      ``implicitfast``); contacts disabled (``<flag contact="disable"/>``), energy enabled.
    * Bodies ``rod1`` (child of the world, origin at the roof hinge) and ``rod2`` (at
      ``0 a 0`` in rod1), each with an explicit ``<inertial pos=com mass=m
      fullinertia="Ixx Iyy Izz Ixy Ixz Iyz"/>`` from :func:`mujoco_compatible` (so
      including the tiny ``axial_inertia``; see the module docstring) and
      ``<compiler inertiafromgeom="false">``: the capsules drawn along the rods
      (``contype=conaffinity=0``) are for viewing only and carry no mass.
    * Hinge joints ``hinge1`` (axis ``axis1``, default ``0 0 1``) and ``hinge2`` (axis
      ``axis2``, default ``sin(alpha) 0 cos(alpha)``) at the body origins, ``damping`` =
      ``c1``, ``c2`` (passive torque ``-c qdot``), ``limited="false"``, ``frictionloss=0``,
      ``stiffness=0``, ``armature=0`` -- or, with the geared motors' rotors (``Ir``), the exact split
      of their kinetic energy into armature and axial inertias of the rods (:func:`_rotor_split`).
      Coulomb friction (``cf1, cf2``) is refused: MuJoCo's ``frictionloss`` is another model.
    * Constant joint torques: two ``<general>`` actuators ``tau1``, ``tau2`` on the hinges
      with ``biastype="affine" biasprm="tau_i 0 0"`` and ``gainprm="1"``, unlimited: the
      actuator force is ``ctrl + tau_i``, and ``ctrl`` is 0 unless set.  So the file is
      self-contained: loading it and calling ``mj_step`` reproduces skewpend's model,
      torques included, with nothing to set at run time (``data.ctrl`` stays free for an
      extra torque on top).

    Numbers are written in shortest round-trip form, so MuJoCo reads exactly the doubles
    of :func:`mujoco_compatible`.  Raises :class:`~skewpend.errors.NotNumericError` for
    symbolic parameters and :class:`~skewpend.errors.ParameterError` for a bad
    ``timestep``, ``integrator`` or ``axial_inertia``.
    """
    p = mujoco_compatible(params, axial_inertia)
    _no_friction(p, "MJCF")
    header = _header(p, "MJCF")
    p, (arm1, arm2) = _rotor_split(p)
    timestep = positive_number("timestep", timestep)
    integrator = _integrator(integrator)
    axis1, axis2 = _axes(p)
    a, b = float(p.a), float(p.b)
    radius = 0.01 * a + 0.01 * b
    lines = [
        '<mujoco model="skewpend">',
        f"  <!-- {header} -->",
        "  <!-- Constant joint torques: actuators tau1, tau2 with force = ctrl + tau_i "
        "(affine bias); ctrl defaults to 0. -->",
        '  <compiler angle="radian" inertiafromgeom="false" autolimits="true"/>',
        f'  <option gravity="0 {_num(p.g)} 0" timestep="{_num(timestep)}" integrator="{integrator}">',
        '    <flag contact="disable" energy="enable"/>',
        "  </option>",
        "  <worldbody>",
        '    <body name="rod1" pos="0 0 0">',
        f'      <joint name="hinge1" type="hinge" pos="0 0 0" axis="{_vec(axis1)}" '
        f'damping="{_num(p.c1)}" limited="false" armature="{_num(arm1)}" frictionloss="0" stiffness="0"/>',
        f'      <inertial pos="{_vec(p.com1)}" mass="{_num(p.m1)}" fullinertia="{_fullinertia(p.inertia1)}"/>',
        f'      <geom name="rod1" type="capsule" fromto="0 0 0 0 {_num(a)} 0" size="{_num(radius)}" '
        'contype="0" conaffinity="0" rgba="0.2 0.4 0.8 1"/>',
        f'      <body name="rod2" pos="0 {_num(a)} 0">',
        f'        <joint name="hinge2" type="hinge" pos="0 0 0" axis="{_vec(axis2)}" '
        f'damping="{_num(p.c2)}" limited="false" armature="{_num(arm2)}" frictionloss="0" stiffness="0"/>',
        f'        <inertial pos="{_vec(p.com2)}" mass="{_num(p.m2)}" fullinertia="{_fullinertia(p.inertia2)}"/>',
        f'        <geom name="rod2" type="capsule" fromto="0 0 0 0 {_num(b)} 0" size="{_num(radius)}" '
        'contype="0" conaffinity="0" rgba="0.8 0.3 0.2 1"/>',
        "      </body>",
        "    </body>",
        "  </worldbody>",
        "  <actuator>",
        f'    <general name="tau1" joint="hinge1" gainprm="1" biastype="affine" biasprm="{_num(p.tau1)} 0 0" '
        'ctrllimited="false" forcelimited="false"/>',
        f'    <general name="tau2" joint="hinge2" gainprm="1" biastype="affine" biasprm="{_num(p.tau2)} 0 0" '
        'ctrllimited="false" forcelimited="false"/>',
        "  </actuator>",
        "</mujoco>",
        "",
    ]
    return "\n".join(lines)


def _urdf_inertial(com, mass, m) -> list:
    return [
        "    <inertial>",
        f'      <origin xyz="{_vec(com)}" rpy="0 0 0"/>',
        f'      <mass value="{_num(mass)}"/>',
        f'      <inertia ixx="{_num(m[0][0])}" ixy="{_num(m[0][1])}" ixz="{_num(m[0][2])}" '
        f'iyy="{_num(m[1][1])}" iyz="{_num(m[1][2])}" izz="{_num(m[2][2])}"/>',
        "    </inertial>",
    ]


def _urdf_visual(length, radius) -> list:
    # a URDF cylinder lies along its z axis; turn it onto y, centred on the rod
    return [
        "    <visual>",
        f'      <origin xyz="0 {_num(length / 2)} 0" rpy="{_num(math.pi / 2)} 0 0"/>',
        f'      <geometry><cylinder radius="{_num(radius)}" length="{_num(length)}"/></geometry>',
        "    </visual>",
    ]


def _urdf_joint(name, parent, child, xyz, axis, damping) -> list:
    return [
        f'  <joint name="{name}" type="continuous">',
        f'    <parent link="{parent}"/>',
        f'    <child link="{child}"/>',
        f'    <origin xyz="{xyz}" rpy="0 0 0"/>',
        f'    <axis xyz="{_vec(axis)}"/>',
        f'    <dynamics damping="{_num(damping)}" friction="0"/>',
        "  </joint>",
    ]


def to_urdf(params: Parameters, *, axial_inertia: Optional[float] = None, z_up: bool = False) -> str:
    """A URDF model (XML text) of the pendulum ``params`` (all numeric).

    Links ``world`` (fixed), ``rod1``, ``rod2``; ``continuous`` (unlimited revolute) joints
    ``hinge1`` (``world -> rod1``, origin 0, axis ``axis1``) and ``hinge2`` (``rod1 ->
    rod2``, origin ``0 a 0``, axis ``axis2``) with ``<dynamics damping=c_i friction=0>``.
    Inertials: ``<origin xyz=com rpy="0 0 0">``, mass, and the full tensor about the centre
    of mass in link axes, from :func:`mujoco_compatible` (tiny ``axial_inertia`` included).

    **Gravity** is not part of URDF.  With ``z_up=False`` (default) the URDF's frame is
    skewpend's, ``y`` pointing down: the simulator must apply gravity ``(0, +g, 0)``.
    With ``z_up=True`` a massless link ``roof`` is fixed to ``world`` with ``rpy="-pi/2 0
    0"`` (skewpend's ``+y`` becomes the world's ``-z``), for simulators with the usual
    gravity ``(0, 0, -g)``; joint angles are the same either way.  A ``<mujoco>`` block
    (MuJoCo's URDF extension, ignored by other tools) sets MuJoCo's ``<option gravity>``
    accordingly, with ``RK4``, ``timestep=1e-4`` and contacts disabled.

    **Constant torques** ``tau1, tau2`` have no place in URDF: they are listed in a comment
    and must be applied by the simulator (e.g. MuJoCo ``data.qfrc_applied``).
    """
    p = mujoco_compatible(params, axial_inertia)
    _no_friction(p, "URDF")
    if p.has_rotor:
        raise ParameterError(f"export URDF: the geared motors' rotor inertia (Ir = {p.Ir:g}, gr = {p.gr:g}) has no place "
                             "in URDF (no armature, no coupling of joint inertias); export MJCF, which holds it exactly")
    axis1, axis2 = _axes(p)
    a, b = float(p.a), float(p.b)
    radius = 0.01 * a + 0.01 * b
    gravity = f"0 0 {_num(-p.g)}" if z_up else f"0 {_num(p.g)} 0"
    root = "roof" if z_up else "world"

    frame_note = (
        "Frame z_up: link roof carries skewpend's frame (y down) turned so that +y is the world's -z; "
        "apply gravity (0, 0, -g)."
        if z_up
        else "Apply gravity (0, +g, 0): this URDF uses skewpend's frame, y pointing DOWN."
    )
    lines = [
        '<?xml version="1.0"?>',
        '<robot name="skewpend">',
        f"  <!-- {_header(p, 'URDF')} -->",
        f"  <!-- {_comment(frame_note)} -->",
        f"  <!-- {_comment(f'Constant joint torques (not representable in URDF; apply them in the simulator): hinge1 {_num(p.tau1)} N m, hinge2 {_num(p.tau2)} N m.')} -->",
        "  <mujoco>",
        '    <compiler angle="radian" discardvisual="true" fusestatic="true"/>',
        f'    <option gravity="{gravity}" timestep="0.0001" integrator="RK4">',
        '      <flag contact="disable"/>',
        "    </option>",
        "  </mujoco>",
        '  <link name="world"/>',
    ]
    if z_up:
        lines += [
            '  <link name="roof"/>',
            '  <joint name="roof_fixed" type="fixed">',
            '    <parent link="world"/>',
            '    <child link="roof"/>',
            f'    <origin xyz="0 0 0" rpy="{_num(-math.pi / 2)} 0 0"/>',
            "  </joint>",
        ]
    lines += ['  <link name="rod1">', *_urdf_inertial(p.com1, p.m1, p.inertia1), *_urdf_visual(a, radius), "  </link>"]
    lines += ['  <link name="rod2">', *_urdf_inertial(p.com2, p.m2, p.inertia2), *_urdf_visual(b, radius), "  </link>"]
    lines += _urdf_joint("hinge1", root, "rod1", "0 0 0", axis1, p.c1)
    lines += _urdf_joint("hinge2", "rod1", "rod2", f"0 {_num(a)} 0", axis2, p.c2)
    lines += ["</robot>", ""]
    return "\n".join(lines)


def _format_for(path: Path, fmt: Optional[str]) -> str:
    if fmt is None:
        guess = _SUFFIXES.get(path.suffix.lower())
        if guess is None:
            raise ParameterError(
                f"cannot tell the export format from the file name {path.name!r} "
                f"(.xml/.mjcf: mjcf, .urdf: urdf); allowed: {', '.join(FORMATS)}"
            )
        return guess
    if not isinstance(fmt, str) or fmt.lower() not in FORMATS:
        raise ParameterError(f"unknown export format {fmt!r}; allowed: {', '.join(FORMATS)}")
    return fmt.lower()


def write_model(
    params: Parameters,
    path: Union[str, os.PathLike],
    format: Optional[str] = None,
    **options,
) -> Path:
    """Write :func:`to_mjcf` or :func:`to_urdf` of ``params`` to ``path``; return the path.

    ``format``: ``"mjcf"`` or ``"urdf"``; ``None`` infers it from the suffix (``.xml``,
    ``.mjcf`` -> MJCF; ``.urdf`` -> URDF).  ``options`` go to the exporter (``timestep``,
    ``integrator``, ``axial_inertia`` for MJCF; ``axial_inertia``, ``z_up`` for URDF).
    The text is built first, then written to a temporary file in the same directory and
    moved into place (``os.replace``): an existing file is either replaced whole or left
    untouched.  Errors: :class:`~skewpend.errors.ParameterError` (unknown format, missing
    directory, bad option), :class:`~skewpend.errors.NotNumericError`.
    """
    from ..io import atomic_path

    path = Path(path)
    if path.is_dir():
        raise ParameterError(
            f"cannot write {path}: it is a directory; give a file name (e.g. pendulum.xml for mjcf, pendulum.urdf for urdf)"
        )
    fmt = _format_for(path, format)
    implied = _SUFFIXES.get(path.suffix.lower())
    if implied is not None and implied != fmt and path.suffix.lower() != ".xml":  # .xml: either (URDF is XML too)
        raise ParameterError(
            f"the file name {path.name!r} says {implied} but the format is {fmt}; give a name ending in "
            f"{' or '.join(k for k, v in _SUFFIXES.items() if v == fmt)} for {fmt}, or use the format {implied}"
        )
    if path.exists() and not path.is_file():
        raise ParameterError(f"cannot write {path}: it exists and is not a regular file")
    exporter = to_mjcf if fmt == "mjcf" else to_urdf
    unknown = sorted(set(options) - set(_OPTIONS[fmt]))
    if unknown:
        raise ParameterError(
            f"unknown {fmt} export option(s) {', '.join(unknown)}; allowed: {', '.join(_OPTIONS[fmt])}"
        )
    text = exporter(params, **options)
    with atomic_path(path) as tmp:
        with open(tmp, "w", encoding="utf-8", newline="\n") as fh:
            fh.write(text)
    return path


def import_mujoco():
    """The ``mujoco`` module, or a :class:`MujocoMissingError` naming the extra to install."""
    try:
        import mujoco  # noqa: F401
    except ImportError:  # pragma: no cover - depends on the environment
        raise MujocoMissingError(
            "this needs the optional dependency 'mujoco', which is not installed: pip install \"skewpend[validate]\" "
            "(or pip install mujoco)"
        ) from None
    return mujoco


def mujoco_steps(t_end: float, dt: float) -> int:
    """The number of MuJoCo steps ``t_end / dt``: a whole number, at most :data:`MAX_MUJOCO_STEPS`."""
    t_end = positive_number("t_end", t_end)
    dt = positive_number("dt", dt)
    n_float = t_end / dt
    if not n_float <= MAX_MUJOCO_STEPS:
        raise ParameterError(
            f"t_end/dt = {n_float:.4g} MuJoCo steps (t_end = {t_end:g} s, dt = {dt:g} s) is more than the "
            f"{MAX_MUJOCO_STEPS:.0e} allowed; use a shorter t_end or a larger dt"
        )
    nsteps = int(round(n_float))
    if nsteps < 1 or abs(nsteps * dt - t_end) > 1e-9 * t_end:
        raise ParameterError(f"t_end ({t_end:g} s) must be a whole number of MuJoCo steps dt ({dt:g} s)")
    return nsteps


def mujoco_trajectory(
    params: Parameters,
    y0: Sequence[float],
    t_end: float,
    *,
    dt: float = 1e-4,
    integrator: str = "RK4",
    n_out: Optional[int] = None,
    axial_inertia: Optional[float] = None,
):
    """Simulate the exported MJCF in MuJoCo from ``y0 = (phi, psi, dphi, dpsi)`` over ``[0, t_end]``
    (a chain of links' ``y0 = (q1 … qn, dq1 … dqn)``).

    Builds :func:`to_mjcf` (a chain's :func:`chain_to_mjcf`; ``timestep=dt``, ``integrator``), loads it with
    ``mujoco.MjModel.from_xml_string``, sets ``qpos = (phi, psi)``, ``qvel = (dphi, dpsi)``
    and steps with ``mj_step``.  The constant torques are in the model (actuators with an
    affine bias, see :func:`to_mjcf`); ``ctrl`` and ``qfrc_applied`` stay zero.  ``t_end``
    must be a whole number of steps ``dt``.

    Returns ``(t, y)``: times [s], shape (n,), and states ``(phi, psi, dphi, dpsi)``, shape
    (n, 4), starting with ``t = 0, y0``.  ``n_out=None`` returns every step
    (``n = t_end/dt + 1``); otherwise ``n_out >= 2`` samples at the steps nearest to
    ``linspace(0, t_end, n_out)`` (``t`` holds the exact step times).

    The system simulated is :func:`mujoco_compatible` ``(params, axial_inertia)``.  Raises
    :class:`MujocoMissingError` (a ``SkewpendError`` and ``ImportError``) without
    ``mujoco``, :class:`~skewpend.errors.ParameterError` for bad arguments, and
    :class:`~skewpend.errors.IntegrationError` if the state becomes non-finite or MuJoCo
    reports an unstable simulation.
    """
    import numpy as np

    from ..symbolic.chain import Chain

    chain = isinstance(params, Chain)
    if not chain:
        params.require_numeric("export")
    y = initial_state(y0, params.coordinates if chain else ("phi", "psi"))
    nq = y.size // 2
    t_end = positive_number("t_end", t_end)
    dt = positive_number("dt", dt)
    integrator = _integrator(integrator)
    nsteps = mujoco_steps(t_end, dt)
    if n_out is None:
        marks = np.arange(nsteps + 1)
    else:
        if isinstance(n_out, bool) or int(n_out) != n_out or n_out < 2:
            raise ParameterError(f"n_out must be an integer >= 2 or None, got {n_out!r}")
        marks = np.unique(np.rint(np.linspace(0, nsteps, int(n_out))).astype(np.int64))

    mujoco = import_mujoco()
    make = chain_to_mjcf if chain else to_mjcf
    xml = make(params, timestep=dt, integrator=integrator, axial_inertia=axial_inertia)
    try:
        model = mujoco.MjModel.from_xml_string(xml)
    except ValueError as exc:  # MuJoCo's compiler refuses the model (e.g. a mass below its minimum)
        detail = " ".join(str(exc).split())
        raise ParameterError(
            f"MuJoCo refuses the exported model ({detail}); allowed: masses, inertias and rod lengths MuJoCo "
            "accepts (masses and principal moments above its minimum of about 1e-15)"
        ) from None
    data = mujoco.MjData(model)
    data.qpos[:] = y[:nq]
    data.qvel[:] = y[nq:]
    mujoco.mj_forward(model, data)

    out = np.empty((marks.size, 2 * nq))
    out[0] = y
    done = 0
    bad = mujoco.mjtWarning.mjWARN_BADQACC
    # MuJoCo's default warning handler prints and appends to MUJOCO_LOG.TXT in the working
    # directory; collect the messages instead and report them in the error.
    messages: list = []
    previous = mujoco.get_mju_user_warning()
    mujoco.set_mju_user_warning(lambda msg: messages.append(str(msg).strip()))
    try:
        for row, mark in enumerate(marks[1:], start=1):
            while done < mark:  # bounded calls: Ctrl-C raises KeyboardInterrupt between them
                n = int(min(mark - done, _MUJOCO_CHUNK))
                mujoco.mj_step(model, data, nstep=n)
                done += n
            out[row, :nq] = data.qpos
            out[row, nq:] = data.qvel
            if data.warning[bad].number > 0 or not np.all(np.isfinite(out[row])):
                detail = f" ({messages[0]})" if messages else ""
                raise IntegrationError(
                    f"MuJoCo {integrator}: the simulation became unstable before t = {done * dt:.6g} s{detail}"
                )
    finally:
        mujoco.set_mju_user_warning(previous)
    return marks * dt, out


# -- chains of any length ------------------------------------------------------------------------------
def mujoco_compatible_chain(chain, axial_inertia: Optional[float] = None):
    """``chain`` with each link's inertia made acceptable to MuJoCo (the tiny inertia of the module's
    text: ``axial_inertia``, default ``max(1e-9 m l^2, 1e-12)`` per link, along the principal axes that
    need it); bodies MuJoCo accepts are unchanged.  The system :func:`chain_to_mjcf` exports."""
    eps = positive_number("axial_inertia", axial_inertia, allow_none=True)
    out = chain
    for link in chain.links:
        eps_k = eps if eps is not None else max(AXIAL_INERTIA_FACTOR * link.mass * link.length ** 2, AXIAL_INERTIA_FLOOR)
        inertia = _regularised_inertia(link.inertia, eps_k)
        if not _finite(inertia):
            raise ParameterError(f"export: the inertia of link {link.index} overflows in MuJoCo's terms: {link.inertia}")
        if inertia != link.inertia:
            out = out.replace_link(link.index, inertia=inertia)
    return out


def chain_to_mjcf(chain, *, timestep: float = 1e-4, integrator: str = "RK4",
                  axial_inertia: Optional[float] = None) -> str:
    """A MuJoCo MJCF model (XML text) of a chain of links (:class:`skewpend.symbolic.chain.Chain`): the
    conventions of :func:`to_mjcf` (gravity along +y, bodies nested link by link, each at its hinge's
    offset in its parent, ``<inertial>`` of :func:`mujoco_compatible_chain`, hinge ``axis``, ``damping``,
    a ``<general>`` actuator with the constant torque as its affine bias).  Coulomb friction and rotors
    are refused: MuJoCo's ``frictionloss`` is another model, and a rotor's coupling to its carrier is no
    joint armature."""
    if chain.has_friction:
        raise ParameterError("export: MuJoCo's frictionloss is not skewpend's smooth Coulomb friction; export the chain "
                             "with coulomb = 0 on every link")
    if chain.has_rotor:
        raise ParameterError("export: a rotor carried by its parent link couples the joints, which MuJoCo's armature "
                             "cannot hold; export the chain with rotor = 0 on every link")
    from .. import __version__

    c = mujoco_compatible_chain(chain, axial_inertia)
    timestep = positive_number("timestep", timestep)
    integrator = _integrator(integrator)
    radius = 0.01 * sum(link.length for link in c.links) / max(1, c.n) * 2
    colours = ("0.2 0.4 0.8 1", "0.8 0.3 0.2 1", "0.3 0.7 0.3 1", "0.7 0.6 0.2 1")
    lines = [
        '<mujoco model="skewpend-chain">',
        f"  <!-- {_comment(f'A chain of {c.n} links exported by skewpend {__version__} (MJCF). Frame: x, y, z = i, j, k with y pointing DOWN; gravity g acts along +y. Joint q_i is hinge i, relative to link i-1, zero with the chain hanging along +y.')} -->",
        '  <compiler angle="radian" inertiafromgeom="false" autolimits="true"/>',
        f'  <option gravity="0 {_num(c.g)} 0" timestep="{_num(timestep)}" integrator="{integrator}">',
        '    <flag contact="disable" energy="enable"/>',
        "  </option>",
        "  <worldbody>",
    ]
    for link in c.links:
        pad = "  " * (link.index + 1)
        lines += [
            f'{pad}<body name="link{link.index}" pos="{_vec(link.offset)}">',
            f'{pad}  <joint name="hinge{link.index}" type="hinge" pos="0 0 0" axis="{_vec(link.axis)}" '
            f'damping="{_num(link.damping)}" limited="false" armature="0" frictionloss="0" stiffness="0"/>',
            f'{pad}  <inertial pos="{_vec(link.com)}" mass="{_num(link.mass)}" fullinertia="{_fullinertia(link.inertia)}"/>',
            f'{pad}  <geom name="link{link.index}" type="capsule" fromto="0 0 0 0 {_num(link.length)} 0" '
            f'size="{_num(radius)}" contype="0" conaffinity="0" rgba="{colours[(link.index - 1) % len(colours)]}"/>',
        ]
    lines += ["  " * (k + 1) + "</body>" for k in range(c.n, 0, -1)]
    lines += ["  </worldbody>", "  <actuator>"]
    lines += [f'    <general name="tau{link.index}" joint="hinge{link.index}" gainprm="1" biastype="affine" '
              f'biasprm="{_num(link.torque)} 0 0" ctrllimited="false" forcelimited="false"/>' for link in c.links]
    lines += ["  </actuator>", "</mujoco>", ""]
    return "\n".join(lines)


def chain_to_urdf(chain, *, axial_inertia: Optional[float] = None) -> str:
    """A URDF model (XML text) of a chain of links in skewpend's frame (``y`` down: apply gravity
    ``(0, +g, 0)``), the conventions of :func:`to_urdf`: links ``link1`` to ``linkn`` with the inertials of
    :func:`mujoco_compatible_chain`, ``continuous`` joints ``hinge1`` to ``hingen`` at each hinge's offset in
    its parent, with the link's axis and ``<dynamics damping>``.  Constant torques are listed in a comment
    (URDF has no place for them); Coulomb friction and rotors are refused, as for MJCF."""
    if chain.has_friction or chain.has_rotor:
        chain_to_mjcf(chain)  # the same refusals, one line each
    from .. import __version__

    c = mujoco_compatible_chain(chain, axial_inertia)
    radius = 0.02 * sum(link.length for link in c.links) / c.n
    torques = ", ".join(f"hinge{link.index} {_num(link.torque)} N m" for link in c.links)
    lines = [
        '<?xml version="1.0"?>',
        '<robot name="skewpend-chain">',
        f"  <!-- {_comment(f'A chain of {c.n} links exported by skewpend {__version__} (URDF). Apply gravity (0, +g, 0) with g = {_num(c.g)}: this URDF uses skewpend frame, y pointing DOWN.')} -->",
        f"  <!-- {_comment(f'Constant joint torques (not representable in URDF; apply them in the simulator): {torques}.')} -->",
        '  <link name="world"/>',
    ]
    for link in c.links:
        lines += [f'  <link name="link{link.index}">', *_urdf_inertial(link.com, link.mass, link.inertia),
                  *_urdf_visual(link.length, radius), "  </link>"]
    for link in c.links:
        parent = "world" if link.index == 1 else f"link{link.index - 1}"
        lines += _urdf_joint(f"hinge{link.index}", parent, f"link{link.index}", _vec(link.offset), link.axis,
                             link.damping)
    lines += ["</robot>", ""]
    return "\n".join(lines)
