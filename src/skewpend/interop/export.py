"""Export a model -- the double pendulum or a chain of links -- to MuJoCo (MJCF) and URDF, and
simulate it in MuJoCo.

One writer per format takes any model and works on its chain (``model.as_chain()``: the double
pendulum is the chain of two).  The exported models are the system skewpend derives its equations
for: basis ``i, j, k`` = ``x, y, z`` with ``j = +y`` pointing **down**, gravity ``g`` along ``+y``;
link ``i`` turns about its hinge's axis (given in the frame of the link before it, the roof's for the
first) through the hinge's offset in that frame (the double pendulum's rod 1 about ``axis1`` through the
origin, rod 2 about ``axis2`` through ``a j``); each body frame has its origin at its hinge and is
aligned with ``x, y, z`` when the chain hangs (every coordinate zero).  Joint angles are right-handed
about the axes, as in skewpend and MuJoCo; bodies are named ``rod1`` to ``rodn``, hinges ``hinge1`` to
``hingen``.

Functions:

* :func:`mujoco_compatible` -- the model with explicit centres of mass and inertia tensors,
  including the tiny inertia MuJoCo needs (below); simulate *this* in skewpend to compare with
  MuJoCo;
* :func:`to_mjcf` -- MuJoCo MJCF XML (self-contained: gravity, damping, constant torques and the
  geared motors' rotors are all in the file);
* :func:`to_urdf` -- URDF (gravity and constant torques are not part of URDF; see there);
* :func:`write_model` -- either of them to a file, atomically;
* :func:`mujoco_trajectory` -- load the MJCF in MuJoCo and step it (``mujoco`` is an
  optional dependency, imported only there: ``pip install skewpend[validate]``).

Coulomb friction has no exact counterpart in either format and is refused.

The tiny inertia
----------------
MuJoCo refuses a body whose inertia tensor is not positive definite ("inertia must have
positive eigenvalues") and checks the triangle inequality of the principal moments
``A + B >= C`` exactly (no tolerance).  A thin rod has zero moment about its own axis, so
skewpend's default bodies cannot be exported as they are.  :func:`mujoco_compatible` adds
``eps`` = ``axial_inertia`` [kg m^2] (default ``max(1e-9 m l^2, 1e-12)`` per body, ``l`` the
link's length: ``a`` for rod 1, ``b`` for rod 2 of the double pendulum; the floor keeps ``eps`` above
MuJoCo's smallest accepted principal moment, about 1e-14) along the principal axes that need it:

* every principal moment below ``eps / 2`` is raised by ``eps`` (the thin rod's axial
  moment ``0 -> eps``; a point mass gets ``eps`` about every axis);
* if the principal moments then satisfy the triangle inequality with a margin below
  ``eps / 2`` (a flat plate, ``C = A + B``), the smallest one is raised by ``eps`` again,
  so rounding in MuJoCo's eigen-decomposition cannot break the check.

Bodies that need none of this are exported unchanged.  The change is of relative size
``~1e-8`` and only matters when a rod spins about its own axis (skewed hinges): over 2 s of
large swings it moves the state by a few 1e-9.  A comparison to round-off precision must
nevertheless simulate the identical system, ``mujoco_compatible(model)`` -- which is what the
exported files contain.
"""

from __future__ import annotations

import math
import os
from pathlib import Path
from typing import Any, Callable, Optional, Sequence, Union

from ..errors import IntegrationError, MissingExtraError, NotNumericError, ParameterError
from ..parsing import initial_state, positive_number
from ..schema import LINK_FIELDS, name_of

__all__ = ["FORMATS", "INTEGRATORS", "MujocoMissingError", "mujoco_compatible", "to_mjcf", "to_urdf", "write_model",
           "mujoco_trajectory"]

#: Export formats accepted by :func:`write_model`, and the file suffixes that imply them.
FORMATS = ("mjcf", "urdf")
_SUFFIXES = {".xml": "mjcf", ".mjcf": "mjcf", ".urdf": "urdf"}
_OPTIONS = {"mjcf": ("timestep", "integrator", "axial_inertia", "motor"), "urdf": ("axial_inertia", "z_up", "motor")}

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

#: The bodies' colours in the MJCF (link 1, 2, ... in turn).
_COLOURS = ("0.2 0.4 0.8 1", "0.8 0.3 0.2 1", "0.3 0.7 0.3 1", "0.7 0.6 0.2 1")


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


def numeric_chain(model, what: str = "export"):
    """The model as a chain (``model.as_chain()``); a model with symbolic values is refused as
    ``what`` needing numeric values."""
    try:
        return model.as_chain()
    except NotNumericError as exc:
        raise NotNumericError(f"{what} needs{str(exc).partition(' needs')[2]}") from None


def _namer(model) -> Callable[[str, int], str]:
    """How ``model`` names link ``i``'s field ``key`` in messages: by its own parameter's name where it
    has one (the double pendulum's ``a``, ``m2``, ``cf1``, ``Ir``: the keys of its dict), else as
    ``link i key``."""
    own = model.to_dict()
    stems = {key: stem for key, stem, _ in LINK_FIELDS}

    def name(key: str, i: int) -> str:
        try:
            alias = name_of(stems[key], i)
        except (KeyError, IndexError):
            alias = None
        return alias if alias in own else f"link {i} {key}"

    return name


def _listed(pairs) -> str:
    """``name = value`` for each distinct name, in order (the double pendulum's ``Ir`` is both links')."""
    seen: dict = {}
    for name, value in pairs:
        seen.setdefault(name, value)
    return ", ".join(f"{name} = {value:g}" for name, value in seen.items())


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


def _finite(values) -> bool:
    """Every number in a (nested) sequence of floats is finite."""
    if isinstance(values, (list, tuple)):
        return all(_finite(v) for v in values)
    return math.isfinite(float(values))


def _overflow(chain, name, what: str) -> ParameterError:
    sizes = ", ".join(f"{name(key, link.index)} = {getattr(link, key):g}"
                      for key in ("length", "mass") for link in chain.links)
    return ParameterError(
        f"export: {what} is not a finite number (overflow) for {sizes}; allowed: parameters of moderate size, "
        "for which every number in the model (lengths, masses, m l^2, inertia tensors) is a finite double"
    )


def _compatible_chain(model, axial_inertia: Optional[float]):
    """``(chain, name)``: the model's chain with each body made acceptable to MuJoCo (the tiny inertia),
    and the model's :func:`_namer`."""
    chain = numeric_chain(model)
    eps = positive_number("axial_inertia", axial_inertia, allow_none=True)
    name = _namer(model)
    for link in chain.links:
        k = link.index
        eps_k = eps if eps is not None else max(AXIAL_INERTIA_FACTOR * link.mass * link.length * link.length,
                                                AXIAL_INERTIA_FLOOR)
        what = f"the inertia tensor of body {k}"
        if not _finite(link.inertia):
            raise _overflow(chain, name, what)
        if not math.isfinite(eps_k):
            raise _overflow(chain, name, f"the tiny axial inertia of body {k} (1e-9 {name('mass', k)} l^2)")
        try:
            regularised = _regularised_inertia(link.inertia, eps_k)
        except (ArithmeticError, ValueError):  # numpy.linalg.LinAlgError is a ValueError
            raise _overflow(chain, name, what) from None
        if not _finite(regularised):
            raise _overflow(chain, name, what)
        if regularised != link.inertia:
            chain = chain.replace_link(k, inertia=regularised)
    return chain, name


# -- public API --------------------------------------------------------------------------------
def mujoco_compatible(model, axial_inertia: Optional[float] = None):
    """``model`` (the double pendulum's :class:`~skewpend.Parameters` or a chain of links) with explicit
    centres of mass and inertia tensors that MuJoCo accepts, in the model's own form.

    The thin-rod defaults are written out, and each body gets the tiny inertia described
    in the module docstring: ``axial_inertia`` [kg m^2] for every body if given, otherwise
    ``max(1e-9 m l^2, 1e-12)`` per body (``max(1e-9 m1 a^2, 1e-12)`` for the double pendulum's rod 1).
    Everything else (scalars, axes, ``alpha``) is unchanged.  This is exactly the system
    :func:`to_mjcf` and :func:`to_urdf` export; ``derive(mujoco_compatible(p))`` is the reference for
    comparing skewpend with MuJoCo.  Idempotent for the default ``axial_inertia``.
    """
    chain, _ = _compatible_chain(model, axial_inertia)
    # the double pendulum keeps its own names for the bodies (com1, inertia2, ...; its dict's keys)
    bodies = {}
    for link in chain.links:
        for key in ("com", "inertia"):
            try:
                bodies[name_of(key, link.index)] = getattr(link, key)
            except IndexError:
                pass
    return model.replace(**bodies) if set(bodies) <= set(model.to_dict()) else chain


def _no_friction(chain, name, fmt: str) -> None:
    if chain.has_friction:
        names = [name("coulomb", link.index) for link in chain.links]
        raise ParameterError(
            f"export {fmt}: Coulomb friction ({_listed((n, link.coulomb) for n, link in zip(names, chain.links))}) "
            "has no exact counterpart: skewpend's torque is the smooth -cf atan(cfs q'), MuJoCo's frictionloss a "
            "dry-friction constraint (up to frictionloss, sticking exactly) and URDF's <dynamics friction> is left to "
            f"the simulator; export the model with {' = '.join(dict.fromkeys(names))} = 0 (set frictionloss yourself "
            "if you want MuJoCo's model: cf pi/2 is the same largest torque)")


def _rotor_split(chain, name):
    """The rotors' kinetic energy as MuJoCo can hold it, exactly: ``armature`` on the hinges and axial
    inertias about the hinges' axes in the links.  The rotor of hinge ``k`` rides on link ``k - 1`` and
    spins at ``w + gr q_k'`` about the axis ``e`` (``w = omega_{k-1} . e``): its energy
    ``Ir/2 (w + gr q_k')^2`` is that of an inertia ``Ir gr e e^T`` in link ``k`` (which spins at
    ``w + q_k'``), ``Ir (1 - gr) e e^T`` in link ``k - 1`` and an armature ``Ir gr (gr - 1)``; on the
    roof (``k = 1``, ``w = 0``) the armature ``Ir gr^2`` alone.  Returns the chain with those inertias
    added and the armatures; refuses a split a simulator cannot take (a negative armature, a body
    inertia no longer physical)."""
    import numpy as np

    from ..symbolic.model import check_inertia

    armature = [0.0] * chain.n
    if not chain.has_rotor:
        return chain, armature
    extra = [np.array(link.inertia, dtype=float) for link in chain.links]

    def why(k):
        link = chain.links[k - 1]
        return ("the rotors' inertia Ir (reflected through the gear gr) maps exactly onto MuJoCo only as armature "
                f"A1 = Ir gr^2, A{k} = Ir gr (gr - 1) and axial inertias Ir (1 - gr) (rod {k - 1}) and Ir gr (rod {k}) "
                f"about hinge {k}'s axis; for {_listed(((name('rotor', k), link.rotor), (name('gear', k), link.gear)))}")

    for link in chain.links:
        k, Ir, gr = link.index, link.rotor, link.gear
        if k == 1:  # the roof carries the first rotor
            armature[0] = Ir * gr * gr
            continue
        armature[k - 1] = Ir * gr * (gr - 1.0)
        if armature[k - 1] < 0:
            raise ParameterError(f"export: {why(k)} the armature A{k} = {armature[k - 1]:g} would be negative "
                                 "(0 < gr < 1)")
        if Ir:
            ee = np.outer(link.axis, link.axis)
            extra[k - 2] = extra[k - 2] + Ir * (1.0 - gr) * ee
            extra[k - 1] = extra[k - 1] + Ir * gr * ee
    for link, inertia in zip(chain.links, extra):
        k = link.index
        tensor = tuple(tuple(float(x) for x in row) for row in inertia)
        try:
            check_inertia(name("inertia", k), tensor)
        except ParameterError as exc:
            culprit = k if k > 1 and link.rotor else k + 1
            raise ParameterError(f"export: {why(culprit)} a body's inertia would not be physical: {exc}") from None
        chain = chain.replace_link(k, inertia=tensor)
    return chain, armature


def _fullinertia(m) -> str:
    """MuJoCo's ``fullinertia`` order: Ixx Iyy Izz Ixy Ixz Iyz."""
    return _vec((m[0][0], m[1][1], m[2][2], m[0][1], m[0][2], m[1][2]))


def _header(model, chain, fmt: str) -> str:
    from .. import __version__

    values = ", ".join(f"{key}={_num(value)}" for key, value in model.to_dict().items()
                       if isinstance(value, (int, float)) and not isinstance(value, bool))
    angles = ", ".join(f"hinge{i} = {c}" for i, c in enumerate(model.coordinates, start=1))
    return _comment(
        f"A chain of {chain.n} links exported by skewpend {__version__} ({fmt}). Parameters: {values}. "
        "Frame: x, y, z = i, j, k of skewpend with y pointing DOWN; gravity g acts along +y. "
        f"Joint angles {angles} (right-handed, each relative to the link before, zero with the chain hanging "
        "along +y). Inertias include skewpend's tiny axial inertia (skewpend.interop.export.mujoco_compatible)."
    )


def _motor_of(motor, c) -> Optional[Any]:  # a config.Motor (config is a lower layer, imported when asked)
    """``motor`` checked: None, or a :class:`~skewpend.config.Motor` on a joint of the chain ``c``."""
    if motor is None:
        return None
    from ..config import Motor

    if not isinstance(motor, Motor):
        raise ParameterError(f"motor must be a skewpend.config.Motor (a run file's [motor]) or None, got {motor!r}")
    if motor.joint > c.n:
        raise ParameterError(f"the motor drives joint {motor.joint}, but the model has {c.n} joint(s)")
    return motor


def to_mjcf(model, *, timestep: float = 1e-4, integrator: str = "RK4", axial_inertia: Optional[float] = None,
            motor=None) -> str:
    """A MuJoCo MJCF model (XML text) of ``model``: the double pendulum's
    :class:`~skewpend.Parameters` (all numeric) or a chain of links.

    * ``<option gravity="0 g 0">`` -- gravity along **+y** (skewpend's ``j`` points down);
      ``timestep`` [s] and ``integrator`` (``RK4`` default; ``Euler``, ``implicit``,
      ``implicitfast``); contacts disabled (``<flag contact="disable"/>``), energy enabled.
    * Bodies ``rod1`` (child of the world, origin at the roof hinge) to ``rodn``, nested link by link,
      each at its hinge's offset in its parent (the double pendulum's ``rod2`` at ``0 a 0`` in rod1),
      each with an explicit ``<inertial pos=com mass=m fullinertia="Ixx Iyy Izz Ixy Ixz Iyz"/>`` from
      :func:`mujoco_compatible` (so including the tiny ``axial_inertia``; see the module docstring) and
      ``<compiler inertiafromgeom="false">``: the capsules drawn along the rods
      (``contype=conaffinity=0``) are for viewing only and carry no mass.
    * Hinge joints ``hinge1`` to ``hingen`` at the body origins with the links' axes (the double
      pendulum's ``axis1``, default ``0 0 1``, and ``axis2``, default ``sin(alpha) 0 cos(alpha)``),
      ``damping`` (``c1``, ``c2``: passive torque ``-c qdot``), ``limited="false"``, ``frictionloss=0``,
      ``stiffness=0``, ``armature=0`` -- or, with the geared motors' rotors, the exact split of their
      kinetic energy into armatures and axial inertias of the rods (:func:`_rotor_split`).
      Coulomb friction is refused: MuJoCo's ``frictionloss`` is another model.
    * Constant joint torques: ``<general>`` actuators ``tau1`` to ``taun`` on the hinges
      with ``biastype="affine" biasprm="tau_i 0 0"`` and ``gainprm="1"``, unlimited: the
      actuator force is ``ctrl + tau_i``, and ``ctrl`` is 0 unless set.  So the file is
      self-contained: loading it and calling ``mj_step`` reproduces skewpend's model,
      torques included, with nothing to set at run time (``data.ctrl`` stays free for an
      extra torque on top).
    * A voltage-driven DC motor (``motor``, a run file's ``[motor]``, :class:`~skewpend.config.Motor`; its
      back-EMF ``kt km / R`` already in its joint's damping, as a run file's model holds it): its joint's
      actuator is ``motor`` with ``gainprm="kt/R"``, ``ctrlrange="-Vmax Vmax"`` (``ctrl`` is the voltage [V]) and
      the joint's constant torque as its bias: force ``kt V / R + tau_j``, at most ``kt Vmax / R`` from the input
      (what :func:`~skewpend.interop.importer.read_mjcf` reads back as the joint's torque limit).

    Numbers are written in shortest round-trip form, so MuJoCo reads exactly the doubles
    of :func:`mujoco_compatible`.  Raises :class:`~skewpend.errors.NotNumericError` for
    symbolic parameters and :class:`~skewpend.errors.ParameterError` for a bad
    ``timestep``, ``integrator`` or ``axial_inertia``.
    """
    c, name = _compatible_chain(model, axial_inertia)
    motor = _motor_of(motor, c)
    _no_friction(c, name, "MJCF")
    header = _header(model, c, "MJCF")
    c, armature = _rotor_split(c, name)
    timestep = positive_number("timestep", timestep)
    integrator = _integrator(integrator)
    radius = sum(0.01 * link.length for link in c.links)
    actuators = ", ".join(f"tau{link.index}" for link in c.links if motor is None or link.index != motor.joint)
    lines = [
        '<mujoco model="skewpend">',
        f"  <!-- {header} -->",
        *([f"  <!-- Constant joint torques: actuators {actuators} with force = ctrl + tau_i "
           "(affine bias); ctrl defaults to 0. -->"] if actuators else []),
        *([f"  <!-- Motor on hinge{motor.joint}: ctrl is its voltage V [V], |V| <= {_num(motor.voltage_limit)}; force = "
           f"kt V / R + tau{motor.joint}, kt/R = {_num(motor.gain)} N m/V; its back-EMF kt km/R = "
           f"{_num(motor.damping)} N m s is in hinge{motor.joint}'s damping. -->"] if motor is not None else []),
        '  <compiler angle="radian" inertiafromgeom="false" autolimits="true"/>',
        f'  <option gravity="0 {_num(c.g)} 0" timestep="{_num(timestep)}" integrator="{integrator}">',
        '    <flag contact="disable" energy="enable"/>',
        "  </option>",
        "  <worldbody>",
    ]
    for link, arm in zip(c.links, armature):
        k, pad = link.index, "  " * (link.index + 1)
        lines += [
            f'{pad}<body name="rod{k}" pos="{_vec(link.offset)}">',
            f'{pad}  <joint name="hinge{k}" type="hinge" pos="0 0 0" axis="{_vec(link.axis)}" '
            f'damping="{_num(link.damping)}" limited="false" armature="{_num(arm)}" frictionloss="0" stiffness="0"/>',
            f'{pad}  <inertial pos="{_vec(link.com)}" mass="{_num(link.mass)}" fullinertia="{_fullinertia(link.inertia)}"/>',
            f'{pad}  <geom name="rod{k}" type="capsule" fromto="0 0 0 0 {_num(link.length)} 0" size="{_num(radius)}" '
            f'contype="0" conaffinity="0" rgba="{_COLOURS[(k - 1) % len(_COLOURS)]}"/>',
        ]
    lines += ["  " * (k + 1) + "</body>" for k in range(c.n, 0, -1)]
    lines += ["  </worldbody>", "  <actuator>"]
    lines += [f'    <general name="motor" joint="hinge{link.index}" gainprm="{_num(motor.gain)}" biastype="affine" '
              f'biasprm="{_num(link.torque)} 0 0" ctrllimited="true" ctrlrange="{_num(-motor.voltage_limit)} '
              f'{_num(motor.voltage_limit)}" forcelimited="false"/>'
              if motor is not None and link.index == motor.joint else
              f'    <general name="tau{link.index}" joint="hinge{link.index}" gainprm="1" biastype="affine" '
              f'biasprm="{_num(link.torque)} 0 0" ctrllimited="false" forcelimited="false"/>' for link in c.links]
    lines += ["  </actuator>", "</mujoco>", ""]
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


def _urdf_joint(name, parent, child, xyz, axis, damping, motor=None) -> list:
    return [
        f'  <joint name="{name}" type="continuous">',
        f'    <parent link="{parent}"/>',
        f'    <child link="{child}"/>',
        f'    <origin xyz="{xyz}" rpy="0 0 0"/>',
        f'    <axis xyz="{_vec(axis)}"/>',
        f'    <dynamics damping="{_num(damping)}" friction="0"/>',
        *([f'    <limit effort="{_num(motor.torque_limit)}" velocity="{_num(motor.voltage_limit / motor.back_emf_constant)}"/>']
          if motor is not None else []),
        "  </joint>",
    ]


def to_urdf(model, *, axial_inertia: Optional[float] = None, z_up: bool = False, motor=None) -> str:
    """A URDF model (XML text) of ``model``: the double pendulum's :class:`~skewpend.Parameters`
    (all numeric) or a chain of links.

    Links ``world`` (fixed), ``rod1`` to ``rodn``; ``continuous`` (unlimited revolute) joints
    ``hinge1`` (``world -> rod1``) to ``hingen`` (``rod(n-1) -> rodn``), each at its hinge's offset in
    its parent (the double pendulum's ``hinge2`` at ``0 a 0``) with the link's axis (``axis1``,
    ``axis2``) and ``<dynamics damping=c_i friction=0>``.  Inertials: ``<origin xyz=com rpy="0 0 0">``,
    mass, and the full tensor about the centre of mass in link axes, from :func:`mujoco_compatible`
    (tiny ``axial_inertia`` included).

    **Gravity** is not part of URDF.  With ``z_up=False`` (default) the URDF's frame is
    skewpend's, ``y`` pointing down: the simulator must apply gravity ``(0, +g, 0)``.
    With ``z_up=True`` a massless link ``roof`` is fixed to ``world`` with ``rpy="-pi/2 0
    0"`` (skewpend's ``+y`` becomes the world's ``-z``), for simulators with the usual
    gravity ``(0, 0, -g)``; joint angles are the same either way.  A ``<mujoco>`` block
    (MuJoCo's URDF extension, ignored by other tools) sets MuJoCo's ``<option gravity>``
    accordingly, with ``RK4``, ``timestep=1e-4`` and contacts disabled.

    **Constant torques** have no place in URDF: they are listed in a comment and must be applied by
    the simulator (e.g. MuJoCo ``data.qfrc_applied``).  A voltage-driven DC motor (``motor``, its back-EMF already
    in its joint's damping) is its joint's ``<limit effort="kt Vmax / R" velocity="Vmax / km">`` (the torque the
    voltage limit gives at rest and the speed at which the back-EMF cancels it), its gain in a comment: URDF has
    no voltage input.  Neither have the geared motors' rotors
    (refused: export MJCF, which holds them exactly) nor Coulomb friction (refused).
    """
    c, name = _compatible_chain(model, axial_inertia)
    motor = _motor_of(motor, c)
    _no_friction(c, name, "URDF")
    if c.has_rotor:
        rotors = _listed((name(key, link.index), getattr(link, key)) for link in c.links if link.rotor
                         for key in ("rotor", "gear"))
        raise ParameterError(f"export URDF: the geared motors' rotor inertia ({rotors}) has no place "
                             "in URDF (no armature, no coupling of joint inertias); export MJCF, which holds it exactly")
    radius = sum(0.01 * link.length for link in c.links)
    gravity = f"0 0 {_num(-c.g)}" if z_up else f"0 {_num(c.g)} 0"
    root = "roof" if z_up else "world"

    frame_note = (
        "Frame z_up: link roof carries skewpend's frame (y down) turned so that +y is the world's -z; "
        "apply gravity (0, 0, -g)."
        if z_up
        else "Apply gravity (0, +g, 0): this URDF uses skewpend's frame, y pointing DOWN."
    )
    torques = ", ".join(f"hinge{link.index} {_num(link.torque)} N m" for link in c.links)
    lines = [
        '<?xml version="1.0"?>',
        '<robot name="skewpend">',
        f"  <!-- {_header(model, c, 'URDF')} -->",
        f"  <!-- {_comment(frame_note)} -->",
        f"  <!-- {_comment(f'Constant joint torques (not representable in URDF; apply them in the simulator): {torques}.')} -->",
        *([f"  <!-- {_comment(f'Motor on hinge{motor.joint}: voltage input V, |V| <= {_num(motor.voltage_limit)} V, torque kt V / R with kt/R = {_num(motor.gain)} N m/V (apply it in the simulator); its back-EMF kt km/R = {_num(motor.damping)} N m s is in the damping.')} -->"]
          if motor is not None else []),
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
    for link in c.links:
        lines += [f'  <link name="rod{link.index}">', *_urdf_inertial(link.com, link.mass, link.inertia),
                  *_urdf_visual(link.length, radius), "  </link>"]
    for link in c.links:
        parent = root if link.index == 1 else f"rod{link.index - 1}"
        lines += _urdf_joint(f"hinge{link.index}", parent, f"rod{link.index}", _vec(link.offset), link.axis,
                             link.damping, motor if motor is not None and link.index == motor.joint else None)
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


def write_model(model, path: Union[str, os.PathLike], format: Optional[str] = None, **options) -> Path:
    """Write :func:`to_mjcf` or :func:`to_urdf` of ``model`` (the double pendulum or a chain of links) to
    ``path``; return the path.

    ``format``: ``"mjcf"`` or ``"urdf"``; ``None`` infers it from the suffix (``.xml``,
    ``.mjcf`` -> MJCF; ``.urdf`` -> URDF).  ``options`` go to the exporter (``timestep``,
    ``integrator``, ``axial_inertia``, ``motor`` for MJCF; ``axial_inertia``, ``z_up``, ``motor`` for URDF).
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
    text = exporter(model, **options)
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


def mujoco_trajectory(model, y0: Sequence[float], t_end: float, *, dt: float = 1e-4, integrator: str = "RK4",
                      n_out: Optional[int] = None, axial_inertia: Optional[float] = None):
    """Simulate the exported MJCF of ``model`` in MuJoCo from ``y0`` over ``[0, t_end]``: the model's
    coordinates and their speeds (the double pendulum's ``(phi, psi, dphi, dpsi)``, a chain's
    ``(q1 … qn, dq1 … dqn)``).

    Builds :func:`to_mjcf` (``timestep=dt``, ``integrator``), loads it with
    ``mujoco.MjModel.from_xml_string``, sets ``qpos`` to the angles, ``qvel`` to the speeds
    and steps with ``mj_step``.  The constant torques are in the model (actuators with an
    affine bias, see :func:`to_mjcf`); ``ctrl`` and ``qfrc_applied`` stay zero.  ``t_end``
    must be a whole number of steps ``dt``.

    Returns ``(t, y)``: times [s], shape (n,), and states (angles, speeds), shape
    (n, 2 N) for N links, starting with ``t = 0, y0``.  ``n_out=None`` returns every step
    (``n = t_end/dt + 1``); otherwise ``n_out >= 2`` samples at the steps nearest to
    ``linspace(0, t_end, n_out)`` (``t`` holds the exact step times).

    The system simulated is :func:`mujoco_compatible` ``(model, axial_inertia)``.  Raises
    :class:`MujocoMissingError` (a ``SkewpendError`` and ``ImportError``) without
    ``mujoco``, :class:`~skewpend.errors.ParameterError` for bad arguments, and
    :class:`~skewpend.errors.IntegrationError` if the state becomes non-finite or MuJoCo
    reports an unstable simulation.
    """
    import numpy as np

    numeric_chain(model)  # symbolic values are refused first
    y = initial_state(y0, model.coordinates)
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
    xml = to_mjcf(model, timestep=dt, integrator=integrator, axial_inertia=axial_inertia)
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
