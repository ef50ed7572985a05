"""The optional model terms of issue 27: Coulomb friction ``-cf atan(cfs q')`` and the geared
motors' rotor inertia ``Ir`` (gear ratio ``gr``) -- the lab's mass matrix, the energy account,
Coulomb's linear decay, the DFKI rig's measured motion, linearisation, export, defaults off."""

from __future__ import annotations

import csv
import math
from pathlib import Path

import numpy as np
import pytest
import sympy as sp

import skewpend
from skewpend import Parameters, derive
from skewpend.errors import ParameterError
from skewpend.numeric.conventions import geometry_of
from skewpend.symbolic.derivation import SYMBOLS

S = SYMBOLS
DFKI = Path(__file__).resolve().parents[1] / "data" / "dfki-design-C.0"  # in the repository


def dfki_model(**changes) -> Parameters:
    """The lab's identified model h1.0 of design C.0 (model_h1.0_parameters.yml): inertias about
    the joints turned into inertias about the centres of mass; the lab's gr = 6 is skewpend's
    gr = -6 (its rotor term -gr Ir in M12 is a rotor turning against the joint, see the guide)."""
    m1, m2, l1, l2, r1, r2 = 0.5476215952387185, 0.5978621372377623, 0.2, 0.3, 0.2, 0.275
    I1, I2 = 0.024210710672023246 - m1 * r1**2, 0.053450262258304355 - m2 * r2**2
    values = dict(a=l1, b=l2, m1=m1, m2=m2, alpha=0.0, g=9.81, com1=(0, r1, 0), com2=(0, r2, 0),
                  inertia1=np.diag([I1, 0, I1]).tolist(), inertia2=np.diag([I2, 0, I2]).tolist(),
                  c1=0.011078054769767294, c2=0.004396496974140761, cf1=0.09284176227841016,
                  cf2=0.07708291842936994, cfs=100.0, Ir=6.287203962819607e-05, gr=-6.0)
    values.update(changes)
    return Parameters(**values)


# -- the derivation --------------------------------------------------------------------------------
def test_lab_mass_matrix_at_alpha_zero():
    """dynamics.rst's M for the planar rig: I1, I2 about the joints, Ir, gr -- reproduced exactly
    by skewpend's rotors' kinetic energy with gr -> -gr (the lab's cross term -gr Ir is a rotor
    turning at -gr q2' relative to link 1)."""
    r1, r2, J1, J2, grl = sp.symbols("r1 r2 Jc1 Jc2 g_lab", real=True)
    p = Parameters(alpha=0, com1=(0, "r1", 0), com2=(0, "r2", 0), inertia1=(("Jc1", 0, 0), (0, 0, 0), (0, 0, "Jc1")),
                   inertia2=(("Jc2", 0, 0), (0, 0, 0), (0, 0, "Jc2")), Ir=None, gr=None)
    M = derive(p).mass_matrix.subs(S["gr"], -grl)
    a, m1, m2, Ir = S["a"], S["m1"], S["m2"], S["Ir"]
    I1, I2 = J1 + m1 * r1**2, J2 + m2 * r2**2  # about the joints
    c2 = sp.cos(S["psi"])
    lab = sp.Matrix([[I1 + I2 + a**2 * m2 + 2 * a * m2 * r2 * c2 + grl**2 * Ir + Ir, I2 + a * m2 * r2 * c2 - grl * Ir],
                     [I2 + a * m2 * r2 * c2 - grl * Ir, I2 + grl**2 * Ir]])
    assert sp.simplify(M - lab) == sp.zeros(2, 2)


def test_rotor_terms_on_skewed_axes():
    """Skewed: the rotor at hinge 2 spins about e0 while rod 1 turns about n1, so its axial speed is
    (n1 . e0) phi' + gr psi' = cos(alpha) phi' + gr psi'."""
    base = derive(Parameters(Ir=0.0)).mass_matrix
    M = derive(Parameters(Ir=None, gr=None)).mass_matrix
    Ir, gr, ca = S["Ir"], S["gr"], sp.cos(S["alpha"])
    extra = sp.Matrix([[Ir * (gr**2 + ca**2), Ir * gr * ca], [Ir * gr * ca, Ir * gr**2]])
    assert sp.simplify(M - base - extra) == sp.zeros(2, 2)


def test_friction_is_a_generalised_force_and_linearises_as_damping():
    eom = derive(Parameters(alpha=0, cf1=None, cf2=None, cfs=None, c1=None, c2=None))
    Q = eom.generalized_forces
    for i, (c, cf, v) in enumerate((("c1", "cf1", "dphi"), ("c2", "cf2", "dpsi"))):
        assert sp.simplify(Q[i] - (-S[c] * S[v] - S[cf] * sp.atan(S["cfs"] * S[v]))) == 0
    # Coulomb friction is non-smooth at rest: left out of C0 by default (issue 36), its smoothed slope on request
    lin = eom.linearize()
    assert lin.C == sp.diag(S["c1"], S["c2"]) and lin.coulomb == "exclude" and "cf1, cf2 excluded" in lin.note
    smoothed = eom.linearize(coulomb="smoothed")
    assert smoothed.C == sp.diag(S["c1"] + S["cf1"] * S["cfs"], S["c2"] + S["cf2"] * S["cfs"])


def test_validation_and_defaults():
    p = Parameters()
    assert (p.cf1, p.cf2, p.cfs, p.Ir, p.gr) == (0.0, 0.0, 100.0, 0.0, 1.0)
    assert not p.has_friction and not p.has_rotor
    for bad in (dict(cf1=-0.1), dict(cf2=-1e-3), dict(cfs=0.0), dict(cfs=-5.0), dict(Ir=-1e-6), dict(gr=math.inf)):
        with pytest.raises(ParameterError):
            Parameters(**bad)
    assert Parameters(gr=-6.0).gr == -6.0
    q = dfki_model()
    assert Parameters.from_mapping(q.to_dict()) == q


# -- defaults off: today's code and results -------------------------------------------------------
def test_off_terms_leave_the_code_and_results_alone(reference):
    """Without friction and rotor the compiled code is today's (the geometry holds them as 0, so
    no atan and no Ir in the source), whatever cfs and gr say; the results agree to the bit."""
    from skewpend.numeric.kernel_source import kernel_c_source

    g = geometry_of(reference)
    assert g == geometry_of(reference.replace(cfs=3.0, gr=-6.0))
    src = kernel_c_source(g)
    assert "atan" not in src and "Ir" not in src.split("*/", 1)[1] and "cf1" not in src.split("*/", 1)[1]
    y0 = (1.2, -0.8, 0.0, 0.0)
    a = skewpend.simulate(reference, y0, 2.0)
    b = skewpend.simulate(reference.replace(cfs=3.0, gr=-6.0), y0, 2.0)
    assert np.array_equal(a.y, b.y) and np.array_equal(a.t, b.t)


# -- the energy account -----------------------------------------------------------------------------
def test_energy_balance_with_friction_and_rotor():
    """W' = Q . q' books the work of the friction: E - W = E(0) to 1e-9 relative at rtol 1e-12,
    for the skewed model with both terms and the lab's rig."""
    skew = Parameters(a=1.0, b=0.8, m1=1.0, m2=0.7, alpha=0.5, g=9.81, c1=0.02, cf1=0.3, cf2=0.1, cfs=50.0,
                      Ir=2e-3, gr=-7.0, tau2=0.05)
    for p, y0 in ((skew, (1.2, -0.8, 0.0, 0.0)), (dfki_model(), (1.0, -1.5, 2.0, 0.0))):
        tr = skewpend.simulate(p, y0, 5.0, rtol=1e-12, atol=1e-12)
        assert tr.ok
        assert np.max(np.abs(tr.energy - tr.work - tr.energy[0])) < 1e-9 * np.max(np.abs(tr.energy))
        assert tr.work[-1] < -0.1  # the friction took energy out


def test_coulomb_friction_decays_linearly():
    """Coulomb's signature: a nearly single pendulum (m2 and b tiny) with friction only, released
    at 0.25 rad, loses the same amplitude every swing, 2 F / K per half period with the saturated
    torque F = cf pi/2 and K = dPi/dphi's slope -- to 10 % while the amplitude falls to a third
    (viscous damping would lose a fixed fraction instead)."""
    p = Parameters(a=1.0, b=0.01, m1=1.0, m2=1e-4, alpha=0.0, g=9.81, cf1=0.05, cfs=100.0)
    tr = skewpend.simulate(p, (0.25, 0.0, 0.0, 0.0), 8.0, dt_out=1e-3, rtol=1e-10, atol=1e-10)
    phi = tr.y[:, 0]
    k = np.flatnonzero((phi[1:-1] > phi[:-2]) & (phi[1:-1] >= phi[2:])) + 1  # maxima
    k2 = np.flatnonzero((phi[1:-1] < phi[:-2]) & (phi[1:-1] <= phi[2:])) + 1  # minima
    peaks = np.abs(phi[np.sort(np.concatenate([k, k2]))])
    K = float(derive(p).linearize().K[0, 0])
    drop = 2 * (0.05 * math.pi / 2) / K
    steps = -np.diff(np.concatenate([[0.25], peaks]))
    live = peaks > drop  # before it sticks (measured: 0.0317 per half swing, 1 % below 2 F / K)
    assert live.sum() >= 4 and peaks[live][-1] < 0.25 / 3
    assert np.allclose(steps[: live.sum()], drop, rtol=0.10)
    ratios = peaks[1: live.sum()] / peaks[: live.sum() - 1]
    assert ratios[-1] < ratios[0] - 0.05  # not geometric


# -- the lab's rig: measured torques in, measured motion out ---------------------------------------------
def test_dfki_rig_follows_its_measured_motion():
    """trajectory_00: the lab's model h1.0 driven by the measured torques from the measured start
    follows the measured angles over the first 0.5 s within 0.15 rad (phi) and 0.2 rad (psi), while
    the angles swing 0.5 and 1 rad; without the friction and the rotor it is off by more than 3x
    (measured: 0.098 and 0.116 rad; 0.44 and 0.73 rad without)."""
    from skewpend.numeric.control import Controller

    with open(DFKI / "trajectory_00.csv") as fh:
        rows = list(csv.DictReader(fh))
    col = {k: np.array([float(r[k]) for r in rows]) for k in rows[0]}
    sel = col["time"] <= 0.5
    t = col["time"][sel]
    ctl = Controller.table(t, np.column_stack([col["tau_meas1"][sel], col["tau_meas2"][sel]]))
    y0 = [col["pos_meas1"][0], col["pos_meas2"][0], col["vel_filt1"][0], col["vel_filt2"][0]]
    errors = {}
    for name, p in (("lab", dfki_model()), ("without", dfki_model(cf1=0.0, cf2=0.0, Ir=0.0))):
        tr = skewpend.simulate(p, y0, 0.5, dt_out=0.01, controller=ctl)
        assert tr.ok
        meas = [np.interp(tr.t, t, col[f"pos_meas{i}"][sel]) for i in (1, 2)]
        errors[name] = [float(np.max(np.abs(tr.y[:, i] - meas[i]))) for i in range(2)]
    assert errors["lab"][0] < 0.15 and errors["lab"][1] < 0.2, errors
    assert errors["without"][0] > 3 * errors["lab"][0] and errors["without"][1] > 3 * errors["lab"][1], errors


# -- modes, control, export ----------------------------------------------------------------------------
def test_modes_see_rotor_and_friction():
    p = dfki_model()
    m = skewpend.normal_modes(p)
    M0 = derive(p.replace(cf1=0.0, cf2=0.0, c1=0.0, c2=0.0)).linearize().M
    assert np.allclose(m.M, np.array(M0, dtype=float), rtol=1e-12)
    assert np.allclose(np.diag(m.C), [p.c1, p.c2], rtol=1e-12)  # Coulomb friction left out by default (issue 36)
    smoothed = skewpend.normal_modes(p, coulomb="smoothed")
    assert np.allclose(np.diag(smoothed.C), [p.c1 + p.cf1 * p.cfs, p.c2 + p.cf2 * p.cfs], rtol=1e-12)
    assert not np.allclose(m.M, skewpend.normal_modes(p.replace(Ir=0.0)).M)


def test_mjcf_holds_the_rotor_exactly_and_refuses_friction():
    from skewpend.interop.export import mujoco_compatible, to_mjcf, to_urdf

    with pytest.raises(ParameterError, match="frictionloss"):
        to_mjcf(dfki_model())
    p = Parameters(a=1.0, b=0.8, m1=1.0, m2=0.7, alpha=0.5, g=9.81, Ir=1e-3, gr=-6.0)
    with pytest.raises(ParameterError, match="URDF"):
        to_urdf(p)
    with pytest.raises(ParameterError, match="armature"):
        to_mjcf(p.replace(gr=0.5))
    with pytest.raises(ParameterError, match="not be physical"):
        to_mjcf(p)  # thin rods have no inertia to spare for the rotor's negative share
    mujoco = pytest.importorskip("mujoco")
    fat = p.replace(inertia1=((0.05, 0, 0), (0, 0.04, 0), (0, 0, 0.05)), inertia2=((0.04, 0, 0), (0, 0.03, 0), (0, 0, 0.04)))
    for gr in (-6.0, 6.0):
        q = fat.replace(gr=gr)
        model = mujoco.MjModel.from_xml_string(to_mjcf(q))
        data = mujoco.MjData(model)
        Mexpr = derive(mujoco_compatible(q)).mass_matrix
        for phi, psi in ((0.0, 0.0), (0.7, -1.1), (2.0, 0.4)):
            data.qpos[:] = (phi, psi)
            mujoco.mj_forward(model, data)
            full = np.zeros((2, 2))
            mujoco.mj_fullM(model, data, full)
            ours = np.array(Mexpr.subs({S["phi"]: phi, S["psi"]: psi}), dtype=float)
            assert np.allclose(full, ours, rtol=1e-10, atol=1e-14), (gr, full, ours)


def test_explorer_refuses_the_terms():
    from skewpend.numeric.explorer_source import explorer_js

    with pytest.raises(ParameterError, match="explorer"):
        explorer_js(Parameters(cf1=0.1))
    with pytest.raises(ParameterError, match="explorer"):
        explorer_js(Parameters(Ir=1e-4))
