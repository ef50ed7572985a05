"""The derivation against the specification and against independent computations.

Ladder of evidence used here:
1. symbolic identity with the specification's planar case (alpha = 0);
2. the kinetic energy recomputed from finite-difference velocities of points along
   the rods (SciPy rotations, Gauss quadrature) -- no code shared with skewpend;
3. the accelerations against sympy.physics.mechanics' KanesMethod;
4. properties: power balance dE/dt = Q . q', symmetry, the alpha = 90 deg decoupling.
"""

from __future__ import annotations

import numpy as np
import pytest
import sympy as sp
from scipy.spatial.transform import Rotation

from skewpend import EquilibriumError, ParameterError, Parameters, derive
from skewpend.symbolic.derivation import SYMBOLS as S
from skewpend.symbolic.specification import check_planar, planar_formulas

a, b, m1, m2, g, alpha = (S[n] for n in ("a", "b", "m1", "m2", "g", "alpha"))
phi, psi, dphi, dpsi = (S[n] for n in ("phi", "psi", "dphi", "dpsi"))


@pytest.fixture(scope="module")
def eom():
    return derive()


def _numeric(expr, names=("a", "b", "m1", "m2", "alpha", "g", "c1", "c2", "tau1", "tau2")):
    args = [S[n] for n in ("phi", "psi", "dphi", "dpsi") + tuple(names)]
    return sp.lambdify(args, expr, "numpy")


# -- 1. the specification ----------------------------------------------------------------------
# The specification's planar formulas are typed once, in skewpend.symbolic.specification (from
# its text, not from the derivation); these tests hold the derivation to them.
def test_alpha_zero_linear_equations_are_the_specifications(eom):
    """The specification's linear equations (its Russian half)."""
    spec = planar_formulas()
    M_spec, K_spec = spec["M0"], spec["K0"]
    lin = derive(Parameters(alpha=0)).linearize()
    assert sp.simplify(lin.M - M_spec) == sp.zeros(2, 2)
    assert sp.simplify(lin.K - K_spec) == sp.zeros(2, 2)
    assert lin.C == sp.zeros(2, 2)
    # the general-alpha linearisation at alpha = 0 gives the same
    general = eom.linearize()
    assert sp.simplify(general.M.subs(alpha, 0) - M_spec) == sp.zeros(2, 2)
    assert sp.simplify(general.K.subs(alpha, 0) - K_spec) == sp.zeros(2, 2)


def test_alpha_zero_energies_and_kinematics_are_the_specifications():
    spec = planar_formulas()
    eom0 = derive(Parameters(alpha=0))
    assert sp.simplify(eom0.kinetic_energy - spec["T"]) == 0
    # skewpend puts Pi = 0 with both rods hanging; the specification's Pi2 is m2 g b/2 there
    assert sp.simplify(eom0.potential_energy - spec["Pi"] + m2 * g * b / 2) == 0
    steps = eom0.steps
    assert sp.simplify(steps["omega2"] - spec["omega2"]) == sp.zeros(3, 1)
    assert sp.simplify(steps["e"] - spec["e"]) == sp.zeros(3, 1)
    assert sp.simplify(steps["P"] - spec["P"]) == sp.zeros(3, 3)
    v = steps["v_c"]
    assert sp.simplify((v.T * v)[0, 0] - spec["v2"]) == 0
    # the library's check says the same, quantity by quantity
    verdicts = {c.key: c.identical for c in check_planar(eom0)}
    assert verdicts == dict.fromkeys(("e", "P", "omega2", "v2", "T", "Pi", "M0", "K0", "C0"), True)


def test_the_planar_check_catches_a_wrong_sign():
    """check_planar is not a check that cannot fail: a derivation with one sign flipped in its
    potential (a stand-in for a wrong derivation) differs."""
    eom0 = derive(Parameters(alpha=0))

    class Wrong:
        steps, kinetic_energy = eom0.steps, eom0.kinetic_energy
        potential_energy = eom0.potential_energy.subs(S["g"], -S["g"])

        def linearize(self):
            return eom0.linearize()

    verdicts = {c.key: c.identical for c in check_planar(Wrong())}
    assert not verdicts["Pi"] and verdicts["T"] and verdicts["M0"]


def test_alpha_zero_nonlinear_equations_from_the_specifications_energies():
    """Lagrange's equations applied (by SymPy's generic calculus) to the specification's T and Pi."""
    t = sp.Symbol("t")
    q1, q2 = sp.Function("q1")(t), sp.Function("q2")(t)
    spec = planar_formulas()
    to_time = {phi: q1, psi: q2, dphi: q1.diff(t), dpsi: q2.diff(t)}
    T_spec, Pi_spec = spec["T"].xreplace(to_time), spec["Pi"].xreplace(to_time)
    L = [sp.diff(T_spec.diff(q.diff(t)), t) - T_spec.diff(q) + Pi_spec.diff(q) for q in (q1, q2)]
    eom0 = derive(Parameters(alpha=0))
    mine = list(eom0.mass_matrix * eom0.ddq - eom0.forcing)
    back = {
        q1.diff(t, 2): S["ddphi"], q2.diff(t, 2): S["ddpsi"],
        q1.diff(t): dphi, q2.diff(t): dpsi, q1: phi, q2: psi,
    }
    for spec_eq, my_eq in zip(L, mine):
        assert sp.simplify(spec_eq.subs(back) - my_eq) == 0


# -- 2. alpha = 90 deg ------------------------------------------------------------------------
def test_alpha_ninety_degrees_decouples_linear_equations():
    lin = derive(Parameters(alpha=np.pi / 2)).linearize()
    assert lin.M[0, 1] == 0 and lin.M[1, 0] == 0
    assert lin.K[0, 1] == 0 and lin.K[1, 0] == 0
    assert sp.simplify(lin.M[1, 1] - m2 * b**2 / 3) == 0
    assert sp.simplify(lin.K[1, 1] - m2 * g * b / 2) == 0


# -- 3. kinetic and potential energy, computed independently ------------------------------------
def _independent_energies(p, q, dq, h=1e-6, nodes=8):
    """T and Pi of two thin uniform rods from point positions (SciPy rotations)."""
    e0 = np.array([np.sin(p["alpha"]), 0.0, np.cos(p["alpha"])])
    jd = np.array([0.0, 1.0, 0.0])

    def points(ph, ps, s1, s2):
        R1 = Rotation.from_rotvec(ph * np.array([0.0, 0.0, 1.0]))
        R2 = R1 * Rotation.from_rotvec(ps * e0)
        rod1 = R1.apply(np.outer(s1, jd))
        rod2 = R1.apply(p["a"] * jd) + R2.apply(np.outer(s2, jd))
        return rod1, rod2

    x, w = np.polynomial.legendre.leggauss(nodes)
    s1, w1 = p["a"] * (x + 1) / 2, w * p["a"] / 2
    s2, w2 = p["b"] * (x + 1) / 2, w * p["b"] / 2
    plus = points(q[0] + h * dq[0], q[1] + h * dq[1], s1, s2)
    minus = points(q[0] - h * dq[0], q[1] - h * dq[1], s1, s2)
    v1 = (plus[0] - minus[0]) / (2 * h)
    v2 = (plus[1] - minus[1]) / (2 * h)
    T = 0.5 * p["m1"] / p["a"] * np.sum(w1 * np.sum(v1**2, axis=1))
    T += 0.5 * p["m2"] / p["b"] * np.sum(w2 * np.sum(v2**2, axis=1))
    r1, r2 = points(q[0], q[1], s1, s2)
    z1, z2 = points(0.0, 0.0, s1, s2)
    # gravity along +j: Pi = -g * sum(m y), relative to the hanging configuration
    Pi = -p["g"] * (
        p["m1"] / p["a"] * np.sum(w1 * (r1[:, 1] - z1[:, 1])) + p["m2"] / p["b"] * np.sum(w2 * (r2[:, 1] - z2[:, 1]))
    )
    return T, Pi


def test_energies_match_points_along_the_rods(eom):
    rng = np.random.default_rng(20261121)
    T_f = _numeric(eom.kinetic_energy)
    Pi_f = _numeric(eom.potential_energy)
    for _ in range(25):
        p = dict(
            a=rng.uniform(0.2, 2), b=rng.uniform(0.2, 2), m1=rng.uniform(0.1, 3), m2=rng.uniform(0.1, 3),
            alpha=rng.uniform(-np.pi, np.pi), g=9.81, c1=0.0, c2=0.0, tau1=0.0, tau2=0.0,
        )
        q = rng.uniform(-np.pi, np.pi, 2)
        dq = rng.uniform(-3, 3, 2)
        T_ref, Pi_ref = _independent_energies(p, q, dq)
        T = T_f(*q, *dq, *p.values())
        Pi = Pi_f(*q, *dq, *p.values())
        # finite differences with h = 1e-6: relative error ~1e-9
        assert T == pytest.approx(T_ref, rel=1e-7, abs=1e-9)
        assert Pi == pytest.approx(Pi_ref, rel=1e-10, abs=1e-10)


# -- 4. against sympy.physics.mechanics (Kane's method) -------------------------------------------
def _kane_accelerations():
    from sympy.physics import mechanics as me

    q1, q2 = me.dynamicsymbols("q1 q2")
    u1, u2 = me.dynamicsymbols("u1 u2")
    N = me.ReferenceFrame("N")
    A = me.ReferenceFrame("A")
    B = me.ReferenceFrame("B")
    A.orient_axis(N, N.z, q1)
    B.orient_axis(A, sp.cos(alpha) * A.z + sp.sin(alpha) * A.x, q2)
    A.set_ang_vel(N, u1 * N.z)
    B.set_ang_vel(A, u2 * (sp.cos(alpha) * A.z + sp.sin(alpha) * A.x))
    O = me.Point("O")
    O.set_vel(N, 0)
    G1 = O.locatenew("G1", a / 2 * A.y)
    H = O.locatenew("H", a * A.y)
    G2 = H.locatenew("G2", b / 2 * B.y)
    G1.v2pt_theory(O, N, A)
    H.v2pt_theory(O, N, A)
    G2.v2pt_theory(H, N, B)
    rod1 = me.RigidBody("rod1", G1, A, m1, (me.inertia(A, 1, 0, 1) * m1 * a**2 / 12, G1))
    rod2 = me.RigidBody("rod2", G2, B, m2, (me.inertia(B, 1, 0, 1) * m2 * b**2 / 12, G2))
    loads = [(G1, m1 * g * N.y), (G2, m2 * g * N.y)]
    kane = me.KanesMethod(N, q_ind=[q1, q2], u_ind=[u1, u2], kd_eqs=[q1.diff() - u1, q2.diff() - u2])
    kane.kanes_equations([rod1, rod2], loads)
    sub = {q1: phi, q2: psi, u1: dphi, u2: dpsi}
    return kane.mass_matrix.subs(sub), kane.forcing.subs(sub)


@pytest.mark.slow
def test_accelerations_match_kanes_method(eom):
    Mk, fk = _kane_accelerations()
    names = ("a", "b", "m1", "m2", "alpha", "g")
    mine = _numeric([eom.mass_matrix, eom.forcing], names)
    kane = _numeric([Mk, fk], names)
    rng = np.random.default_rng(7)
    for _ in range(20):
        args = np.concatenate(
            [rng.uniform(-np.pi, np.pi, 2), rng.uniform(-4, 4, 2), rng.uniform(0.2, 2, 4), [rng.uniform(-np.pi, np.pi)], [9.81]]
        )
        M, f = (np.array(x, dtype=float) for x in mine(*args))
        Mk_, fk_ = (np.array(x, dtype=float) for x in kane(*args))
        np.testing.assert_allclose(np.linalg.solve(M, f.ravel()), np.linalg.solve(Mk_, fk_.ravel()), rtol=1e-10, atol=1e-10)


# -- 5. properties --------------------------------------------------------------------------------
def test_power_balance_with_damping_and_torques():
    """dE/dt along M q'' = f equals the power of Q = tau - c q' (ties f to T and Pi)."""
    p = Parameters(c1=None, c2=None, tau1=None, tau2=None)
    e = derive(p)
    ddq = e.mass_matrix.LUsolve(e.forcing)
    E = e.kinetic_energy + e.potential_energy
    dE = sum(E.diff(q) * dq for q, dq in zip(e.q, e.dq)) + sum(E.diff(dq) * dd for dq, dd in zip(e.dq, ddq))
    Q = [S["tau1"] - S["c1"] * dphi, S["tau2"] - S["c2"] * dpsi]
    residual = _numeric(dE - (Q[0] * dphi + Q[1] * dpsi))
    rng = np.random.default_rng(3)
    for _ in range(20):
        args = np.concatenate([rng.uniform(-3, 3, 4), rng.uniform(0.2, 2, 4), [rng.uniform(-3, 3), 9.81], rng.uniform(0, 1, 4)])
        assert abs(residual(*args)) < 1e-9


def test_reflection_symmetry(eom):
    """phi, psi -> -phi, -psi (and speeds) flips the forcing and keeps M."""
    flip = {phi: -phi, psi: -psi, dphi: -dphi, dpsi: -dpsi}
    assert sp.simplify(eom.mass_matrix.xreplace(flip) - eom.mass_matrix) == sp.zeros(2, 2)
    assert sp.simplify(eom.forcing.xreplace(flip) + eom.forcing) == sp.zeros(2, 1)


def test_mass_matrix_is_symmetric_and_independent_of_phi(eom):
    M = eom.mass_matrix
    assert M[0, 1] == M[1, 0]
    assert not M.has(phi)


def test_compact_form():
    """Entries as short as a hand derivation: a handful of operations, no swell."""
    e = derive()
    ops = [sp.count_ops(x) for x in list(e.mass_matrix) + list(e.forcing)]
    assert max(ops) <= 60, ops
    assert sum(ops) <= 150, ops


# -- 6. general bodies -----------------------------------------------------------------------------
def test_general_body_model_reduces_to_thin_rods():
    """Explicit thin-rod geometry through the general-body options gives the same equations."""
    rng = np.random.default_rng(11)
    for _ in range(3):
        va, vb, vm1, vm2, val = rng.uniform(0.3, 2, 4).tolist() + [float(rng.uniform(-3, 3))]
        base = Parameters(a=va, b=vb, m1=vm1, m2=vm2, alpha=val, g=9.81)
        rod = lambda m, l: ((m * l**2 / 12, 0, 0), (0, 0, 0), (0, 0, m * l**2 / 12))
        general = base.replace(
            alpha=None, com1=(0, va / 2, 0), com2=(0, vb / 2, 0),
            inertia1=rod(vm1, va), inertia2=rod(vm2, vb),
            axis1=(0, 0, 3.0), axis2=(np.sin(val), 0, np.cos(val)),
        )
        e1, e2 = derive(base), derive(general)
        f1 = _numeric([e1.mass_matrix, e1.forcing], ())
        f2 = _numeric([e2.mass_matrix, e2.forcing], ())
        for _ in range(5):
            y = rng.uniform(-3, 3, 4)
            for x1, x2 in zip(f1(*y), f2(*y)):
                np.testing.assert_allclose(np.array(x1, float), np.array(x2, float), rtol=1e-12, atol=1e-12)


def test_general_axis_gives_unit_rotation_and_consistent_energy():
    """An arbitrary hinge axis and an offset centre of mass: T from the steps equals T."""
    p = Parameters(
        a=1.0, b=0.8, m1=1.0, m2=0.7, g=9.81,
        axis2=(1.0, 2.0, 2.0), com2=(0.05, 0.4, -0.02),
        inertia2=((0.04, 0.001, 0.0), (0.001, 0.002, 0.0), (0.0, 0.0, 0.04)),
    )
    e = derive(p)
    st = e.steps
    P = st["P"]
    check = _numeric([P.T * P, st["omega2"], st["v_c"], st["Theta2"], e.kinetic_energy], ())
    rng = np.random.default_rng(5)
    for _ in range(5):
        y = rng.uniform(-3, 3, 4)
        PtP, w, v, Th, T = check(*y)
        np.testing.assert_allclose(np.array(PtP, float), np.eye(3), atol=1e-13)
        w, v, Th = (np.array(x, float) for x in (w, v, Th))
        T1 = 0.5 * (1.0 / 3) * y[2] ** 2  # m1 a^2/3 phi'^2 / 2 for the default rod 1
        T2 = 0.5 * w.ravel() @ Th @ w.ravel() + 0.5 * 0.7 * v.ravel() @ v.ravel()
        assert T == pytest.approx(T1 + T2, rel=1e-12)


# -- 7. linearisation errors -----------------------------------------------------------------------
def test_linearize_refuses_a_non_equilibrium():
    with pytest.raises(EquilibriumError, match="not an equilibrium"):
        derive(Parameters(tau1=0.5)).linearize()
    with pytest.raises(EquilibriumError):
        derive(Parameters(a=1, b=1, m1=1, m2=1, g=9.81, alpha=0.3, com2=(0.1, 0.5, 0))).linearize()


def test_damping_enters_linearisation():
    lin = derive(Parameters(c1=0.2, c2=None)).linearize()
    assert lin.C == sp.diag(sp.Rational(1, 5), S["c2"])


# -- 8. symbolic bodies and axes ---------------------------------------------------------------------
def _values_equal(e1, e2, subs, n=5, seed=13):
    """M and f of two derivations agree at random states after substituting ``subs`` into e1."""
    f1 = _numeric([e1.mass_matrix.subs(subs), e1.forcing.subs(subs)], ())
    f2 = _numeric([e2.mass_matrix, e2.forcing], ())
    rng = np.random.default_rng(seed)
    for _ in range(n):
        y = rng.uniform(-3, 3, 4)
        for x1, x2 in zip(f1(*y), f2(*y)):
            np.testing.assert_allclose(np.array(x1, float), np.array(x2, float), rtol=1e-11, atol=1e-11)


def test_symbolic_inertia_and_centre_of_mass_substitute_to_the_numeric_model():
    base = dict(a=0.9, b=0.7, m1=1.3, m2=0.6, alpha=0.4, g=9.81)
    I2 = ((0.03, 0.002, -0.001), (0.002, 0.005, 0.0015), (-0.001, 0.0015, 0.031))
    com2 = (0.02, 0.33, -0.01)
    sym = derive(Parameters(**base, inertia2="sym", com2=(0, "d", "w")).replace(com2=("u", "d", "w")))
    assert set(sym.parameter_names) == {"u", "d", "w", "I2xx", "I2xy", "I2xz", "I2yy", "I2yz", "I2zz"}
    num = derive(Parameters(**base, inertia2=I2, com2=com2))
    names = {"I2xx": I2[0][0], "I2xy": I2[0][1], "I2xz": I2[0][2], "I2yy": I2[1][1], "I2yz": I2[1][2], "I2zz": I2[2][2],
             "u": com2[0], "d": com2[1], "w": com2[2]}
    _values_equal(sym, num, {sp.Symbol(k, real=True): v for k, v in names.items()})


def test_symbolic_unit_axis_is_the_skew_angle_model():
    """axis2 = (sa, 0, ca) with sa^2 + ca^2 = 1 reproduces e0 = cos(alpha) k + sin(alpha) i."""
    e = derive(Parameters(axis2=("sa", 0, "ca")))
    sa, ca = sp.Symbol("sa", real=True), sp.Symbol("ca", real=True)
    back = {sa: sp.sin(alpha), ca: sp.cos(alpha)}
    ref = derive()
    assert sp.simplify(e.mass_matrix.subs(back) - ref.mass_matrix) == sp.zeros(2, 2)
    assert sp.simplify(e.forcing.subs(back) - ref.forcing) == sp.zeros(2, 1)
    # the relation was used: no power of sa above one survives in M11
    assert sp.degree(sp.expand(e.mass_matrix[0, 0]), sa) <= 2 and not e.mass_matrix[0, 0].has(ca)


def test_symbolic_geometry_is_refused_where_numbers_are_needed():
    from skewpend import NotNumericError, simulate

    p = Parameters(a=1, b=1, m1=1, m2=1, alpha=0.3, g=9.81, com2=(0, "d", 0))
    with pytest.raises(NotNumericError, match="symbolic: d"):
        simulate(p, (0.1, 0, 0, 0), 1.0)
    with pytest.raises(ParameterError, match="symbol name"):
        Parameters(com2=(0, "phi", 0))
    with pytest.raises(ParameterError, match="own name"):
        Parameters(axis2=("b", 0, "c"))
    with pytest.raises(ParameterError, match="symmetric"):
        Parameters(inertia2=(("A", "B", 0), (0, "C", 0), (0, 0, "D")))
