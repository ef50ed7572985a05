"""Chains of links (issue 38): the chain as data, its equations by recursive algorithms, checked against
the symbolic derivation (the double pendulum as the chain of two), MuJoCo (3 to 8 links), a physical
pendulum's known period, and the energy account of the integrators."""

from __future__ import annotations

import math

import numpy as np
import pytest

import skewpend
from skewpend.errors import ParameterError
from skewpend.numeric import kernels, recursive
from skewpend.numeric.conventions import parameter_vector
from skewpend.symbolic.chain import Chain, Link



def _body(rng):
    """A physical inertia tensor: a box of random sides, turned at random (the triangle inequality holds)."""
    d = rng.uniform(0.05, 0.5, 3)
    D = np.diag([d[1] ** 2 + d[2] ** 2, d[0] ** 2 + d[2] ** 2, d[0] ** 2 + d[1] ** 2]) * rng.uniform(0.2, 2.0) / 12
    R, _ = np.linalg.qr(rng.normal(size=(3, 3)))
    return (R @ D @ R.T).tolist()


def random_chain(n, rng, *, damping=True, torque=True) -> Chain:
    links = []
    for i in range(n):
        links.append(Link(axis=tuple(rng.normal(size=3)), offset=tuple(rng.normal(scale=0.3, size=3)) if i else (0, 0, 0),
                          length=float(rng.uniform(0.3, 1.2)), mass=float(rng.uniform(0.2, 2.0)),
                          com=tuple(rng.normal(scale=0.3, size=3)), inertia=_body(rng),
                          damping=float(rng.uniform(0, 0.3)) if damping else 0.0,
                          torque=float(rng.normal(scale=0.5)) if torque else 0.0))
    return Chain(links=tuple(links), g=9.81)


# -- the chain as data ----------------------------------------------------------------------------------
@pytest.mark.parametrize("build, words", [
    (lambda: Chain(links=()), "at least 1 link, got 0"),
    (lambda: Link(axis=(0, 0, 0)), "link axis must be a non-zero vector"),
    (lambda: Chain.from_mapping({"links": [{}, {"axis": [0, 0, 0]}]}), "link 2 axis must be a non-zero vector"),
    (lambda: Chain.from_mapping({"links": [{}, {"mass": -1.0}]}), "link 2 mass must be > 0, got -1"),
    (lambda: Chain.from_lists(mass=[1.0, -2.0]), "link 2 mass must be > 0, got -2"),
    (lambda: Chain(links=(Link(inertia=(1.0, 1.0, 5.0)),)), "triangle inequality"),
    (lambda: Chain(links=(Link(inertia=(-1.0, 1.0, 1.0)),)), "positive semi-definite"),
    (lambda: Chain.from_lists(1, length=0.0), "link 1 length must be > 0"),
    (lambda: Chain.from_lists(mass=[1, 2, 3], length=[1, 2]), "per-link lists of different lengths"),
    (lambda: Chain.from_mapping({"links": [{"mass": 1.0, "colour": "red"}]}), "unknown key 'colour'"),
    (lambda: Chain.from_mapping({"g": 9.8}), "needs its links"),
    (lambda: Chain(links=(Link(),), g=-1.0), "g must be >= 0"),
    (lambda: Chain(links=(Link(),) * 3).require_links((2,), "a Poincare section"),
     "a Poincare section is defined for a chain of 2 links, this chain has 3"),
])
def test_bad_chains_are_one_line(build, words):
    with pytest.raises(ParameterError) as info:
        build()
    message = str(info.value)
    assert words in message and "\n" not in message


def test_defaults_are_the_thin_rods_hanging_end_to_end():
    chain = Chain.from_lists(3, length=[1.0, 0.5, 0.25], mass=[1.0, 2.0, 3.0])
    one, two, three = chain.links
    assert (one.offset, two.offset, three.offset) == ((0, 0, 0), (0, 1.0, 0), (0, 0.5, 0))
    assert two.com == (0, 0.25, 0) and two.inertia == ((2.0 * 0.25 / 12, 0, 0), (0, 0, 0), (0, 0, 2.0 * 0.25 / 12))
    assert chain.coordinates == ("q1", "q2", "q3")
    again = Chain.from_mapping(chain.to_dict())
    assert again == chain


def test_the_double_pendulum_is_the_chain_of_two():
    params = skewpend.Parameters(a=1.0, b=0.7, m1=1.1, m2=0.6, alpha=0.4, g=9.81, c1=0.1, tau2=0.3)
    chain = Chain.from_parameters(params)
    assert chain.n == 2 and chain.coordinates == ("phi", "psi")
    assert chain.links[1].axis == pytest.approx((math.sin(0.4), 0.0, math.cos(0.4)), abs=1e-16)
    assert chain.links[1].offset == (0.0, 1.0, 0.0)
    back = skewpend.Parameters.from_chain(chain)
    assert Chain.from_parameters(back) == chain


# -- the recursive algorithms against the symbolic derivation (two links) -----------------------------------
_TWO_LINK_CASES = {
    "thin rods, skewed": dict(a=1.0, b=0.8, m1=1.2, m2=0.7, alpha=0.5, g=9.81),
    "general bodies, given axes": dict(a=0.9, b=1.3, m1=0.8, m2=1.5, g=9.81, axis1=(0.2, 0.1, 1.0), axis2=(1.0, -0.3, 0.4),
                                       com1=(0.05, 0.4, -0.02), com2=(-0.1, 0.6, 0.08),
                                       inertia1=((0.09, 0.01, 0.0), (0.01, 0.02, 0.005), (0.0, 0.005, 0.1)),
                                       inertia2=((0.2, 0.0, 0.03), (0.0, 0.15, 0.0), (0.03, 0.0, 0.22))),
    "damping, torques, friction, rotors": dict(a=0.3, b=0.2, m1=0.6, m2=0.6, alpha=1.2, g=9.81, c1=0.08, c2=0.02,
                                               tau1=0.4, tau2=-0.25, cf1=0.05, cf2=0.03, cfs=50.0, Ir=6e-5, gr=-6.0),
}


@pytest.mark.parametrize("case", list(_TWO_LINK_CASES))
def test_two_links_equal_the_symbolic_derivation(case, recursive_forms):
    """Two independent derivations: the specification's (rotation tensors, Lagrange's equations, SymPy) and
    the recursive algorithms (composite rigid bodies, Newton-Euler), equal to rounding."""
    params = skewpend.Parameters(**_TWO_LINK_CASES[case])
    chain = Chain.from_parameters(params)
    K1, p1 = kernels.kernel_module(params), parameter_vector(params)
    K2, p2 = kernels.chain_kernel(chain), recursive.parameter_vector(chain)
    rng = np.random.default_rng(11)
    for _ in range(20):
        y = np.r_[rng.uniform(-3, 3, 2), rng.normal(scale=3, size=2), 0.0]
        for name, size in (("rhs", 5), ("ham_rhs", 5), ("momenta", 2), ("velocities", 2), ("tips", 6)):
            a, b = np.zeros(size), np.zeros(size)
            getattr(K1, name)(y, p1, a)
            getattr(K2, name)(y, p2, b)
            assert np.max(np.abs(a - b)) <= 1e-12 * max(1.0, np.max(np.abs(a))), (name, a, b)
        e1, e2 = K1.energy(y, p1), K2.energy(y, p2)
        assert abs(e1 - e2) <= 1e-12 * max(1.0, abs(e1))


# -- MuJoCo, 3 to 8 links -------------------------------------------------------------------------------------
def _accelerations_equal_mujocos(mujoco, model, data, K, p, n: int, rng):
    """At a random state: the chain kernel's accelerations equal MuJoCo's (mj_forward) to 1e-12 relative;
    returns the state."""
    q, dq = rng.uniform(-3, 3, n), rng.normal(scale=2, size=n)
    data.qpos[:], data.qvel[:] = q, dq
    mujoco.mj_forward(model, data)
    out = np.zeros(2 * n + 1)
    K.rhs(np.r_[q, dq, 0.0], p, out)
    assert np.max(np.abs(out[n:2 * n] - data.qacc)) <= 1e-12 * np.max(np.abs(data.qacc))
    return q, dq


@pytest.mark.parametrize("n", [3, 5, 8])
def test_chains_equal_mujoco(n):
    """Random chains (general bodies, arbitrary axes and hinge offsets, damping, torques): the accelerations
    equal MuJoCo's from the exported MJCF to 1e-12 relative."""
    mujoco = pytest.importorskip("mujoco")
    from skewpend.interop.export import mujoco_compatible, to_mjcf

    rng = np.random.default_rng(100 + n)
    chain = mujoco_compatible(random_chain(n, rng))
    K, p = kernels.chain_kernel(chain), recursive.parameter_vector(chain)
    model = mujoco.MjModel.from_xml_string(to_mjcf(chain))
    data = mujoco.MjData(model)
    for _ in range(10):
        q, dq = _accelerations_equal_mujocos(mujoco, model, data, K, p, n, rng)
        # the energy: MuJoCo's potential is zero at the origin, skewpend's with the chain hanging
        mujoco.mj_energyPos(model, data)
        mujoco.mj_energyVel(model, data)
        hanging = mujoco.MjData(model)
        mujoco.mj_forward(model, hanging)
        mujoco.mj_energyPos(model, hanging)
        e_mj = data.energy[0] - hanging.energy[0] + data.energy[1]
        assert abs(K.energy(np.r_[q, dq, 0.0], p) - e_mj) <= 1e-12 * max(1.0, abs(e_mj))


@pytest.mark.parametrize("n", [3, 5, 8])
def test_chains_equal_pinocchio(n):
    """The same random chains exported to URDF: Pinocchio's articulated-body algorithm (a third derivation,
    another code base) gives the same accelerations to 1e-12 relative (its continuous joints take
    (cos q, sin q); the damping and the constant torques are applied as joint torques, as URDF holds neither)."""
    pin = pytest.importorskip("pinocchio")
    from skewpend.interop.export import mujoco_compatible, to_urdf

    rng = np.random.default_rng(100 + n)
    chain = mujoco_compatible(random_chain(n, rng))
    model = pin.buildModelFromXML(to_urdf(chain))
    data = model.createData()
    model.gravity.linear = np.array([0.0, chain.g, 0.0])
    K, p = kernels.chain_kernel(chain), recursive.parameter_vector(chain)
    c = np.array([link.damping for link in chain.links])
    tau = np.array([link.torque for link in chain.links])
    assert model.nv == n
    for _ in range(10):
        q, v = rng.uniform(-3, 3, n), rng.normal(scale=2, size=n)
        expected = pin.aba(model, data, np.ravel(np.column_stack([np.cos(q), np.sin(q)])), v, tau - c * v)
        out = np.zeros(2 * n + 1)
        K.rhs(np.r_[q, v, 0.0], p, out)
        assert np.max(np.abs(out[n:2 * n] - expected)) <= 1e-12 * np.max(np.abs(expected))


def test_chain_export_refuses_what_mujoco_cannot_hold():
    from skewpend.interop.export import to_mjcf, to_urdf

    for change, words in ((dict(coulomb=0.1), "frictionloss"), (dict(rotor=1e-4, gear=0.5), "armature")):
        chain = Chain.from_lists(3).replace_link(2, **change)
        with pytest.raises(ParameterError, match=words):
            to_mjcf(chain)
    with pytest.raises(ParameterError, match="link 2 rotor = 0.0001, link 2 gear = 1.*export MJCF"):
        to_urdf(Chain.from_lists(3).replace_link(2, rotor=1e-4))


@pytest.mark.parametrize("n", [3, 5])
def test_chain_rotors_equal_mujoco(n):
    """Geared motors' rotors on every hinge (gears reversing, speeding up, or 1): the exported MJCF holds them
    exactly (armatures and axial inertias), the accelerations equal skewpend's to 1e-12 relative."""
    mujoco = pytest.importorskip("mujoco")
    from skewpend.interop.export import mujoco_compatible, to_mjcf

    rng = np.random.default_rng(200 + n)
    chain = random_chain(n, rng)
    for i, gear in enumerate(rng.choice([-6.0, -1.5, 1.0, 2.5, 6.0], size=n), start=1):
        chain = chain.replace_link(i, rotor=float(rng.uniform(1e-6, 5e-6)), gear=float(gear))
    chain = mujoco_compatible(chain)
    K, p = kernels.chain_kernel(chain), recursive.parameter_vector(chain)
    model = mujoco.MjModel.from_xml_string(to_mjcf(chain))
    assert np.all(model.dof_armature >= 0) and np.any(model.dof_armature > 0)
    data = mujoco.MjData(model)
    for _ in range(10):
        _accelerations_equal_mujocos(mujoco, model, data, K, p, n, rng)


# -- known values and conservation ---------------------------------------------------------------------------
def test_one_link_is_a_physical_pendulum():
    """Small swings of one link: the period 2 pi sqrt(J / (m g d)), J about the hinge, d the centre of mass's
    distance below it (here the axis is turned out of the plane: J = n . J_hinge n, d the projection)."""
    axis = np.array([0.3, 0.0, 1.0]) / math.hypot(0.3, 1.0)
    chain = Chain(links=(Link(axis=tuple(axis), length=1.0, mass=2.0),), g=9.81)
    link = chain.links[0]
    c = np.array(link.com)
    J_hinge = np.array(link.inertia) + link.mass * (c @ c * np.eye(3) - np.outer(c, c))
    J = axis @ J_hinge @ axis
    d = np.linalg.norm(c - (c @ axis) * axis)  # the centre of mass's distance from the axis
    # gravity's component across the axis acts: g_eff = g |j x n|
    g_eff = 9.81 * np.linalg.norm(np.cross([0.0, 1.0, 0.0], axis))
    period = 2 * math.pi * math.sqrt(J / (link.mass * g_eff * d))
    amplitude = 1e-4
    traj = skewpend.simulate(chain, [amplitude, 0.0], 3 * period, method="dop853", rtol=1e-12, atol=1e-14,
                             dt_out=period / 200)
    q = traj.y[:, 0]
    crossings = [traj.t[k] - q[k] * (traj.t[k + 1] - traj.t[k]) / (q[k + 1] - q[k])
                 for k in range(len(q) - 1) if q[k] > 0 >= q[k + 1]]
    measured = crossings[-1] - crossings[-2]
    # the finite amplitude lengthens the period by amplitude^2 / 16: 6e-10 relative
    assert measured == pytest.approx(period, rel=1e-8)


@pytest.mark.parametrize("method, settings, tol", [
    ("dop853", dict(rtol=1e-12, atol=1e-12), 1e-10),
    ("gauss", dict(dt=1e-3), 1e-8),
])
def test_energy_minus_work_is_conserved(method, settings, tol):
    """A damped, driven chain of 4 links: E - W stays at E(0) to the integrator's tolerance (dop853 at 1e-12;
    gauss, symplectic of order 4 at dt = 1e-3: its error ~ (dt omega)^4 with omega ~ 10 rad/s)."""
    chain = random_chain(4, np.random.default_rng(7))
    traj = skewpend.simulate(chain, [0.4, -0.3, 0.2, 0.1, 1.0, 0.0, -1.0, 0.5], 5.0, method=method, **settings)
    assert traj.ok and traj.y.shape[1] == 8
    assert traj.energy_drift <= tol
    assert np.all(np.diff(traj.work) <= 1e-9) or any(link.torque for link in chain.links)


def test_rk4_converges_at_order_four():
    chain = random_chain(3, np.random.default_rng(3), damping=False, torque=False)
    y0 = [0.5, -0.3, 0.2, 1.0, 0.0, -0.5]
    ref = skewpend.simulate(chain, y0, 2.0, method="dop853", rtol=1e-14, atol=1e-14, dt_out=2.0).y[-1]
    errors = [np.max(np.abs(skewpend.simulate(chain, y0, 2.0, method="rk4", dt=dt, dt_out=2.0).y[-1] - ref))
              for dt in (5e-4, 2.5e-4)]
    # the observed order approaches 4 from above as dt shrinks (measured: 4.85, 4.75, 4.61, 4.47 from
    # dt = 4e-3 down: a fifth-order term still weighs); a method of order 3 or 5 would fall outside
    assert 3.7 < math.log2(errors[0] / errors[1]) < 4.7


def test_taylor_series_of_a_chain_converge_to_dop853_and_keep_the_account():
    """method="taylor" on a chain: the series recurrences printed from the recursive algorithms' graph
    (numeric.chain_taylor). A skewed triple with general bodies, damping, a torque and Coulomb friction (the
    atan recurrence): the final state approaches DOP853's at 1e-13 as the tolerance falls (each step of
    1e-3 in rtol at least 30x smaller, measured 320x and 3900x; at 1e-12 within 1e-9, measured 2.5e-14), E - W - E0 stays at the
    tolerance's size, and a dense grid (dt_out) matches DOP853's."""
    chain = _three_links(torque=0.2).replace_link(2, coulomb=0.05).replace_link(3, damping=0.03)
    y0 = [0.9, -0.4, 0.3, 0.2, -0.5, 0.1]
    ref = skewpend.simulate(chain, y0, 3.0, method="dop853", rtol=1e-13, atol=1e-13)
    errors = []
    for tol in (1e-6, 1e-9, 1e-12):
        tr = skewpend.simulate(chain, y0, 3.0, method="taylor", rtol=tol, atol=tol)
        assert tr.ok and tr.method == "taylor" and tr.stats["order"] >= 8
        errors.append(np.max(np.abs(tr.y[-1] - ref.y[-1])))
        assert abs(tr.work[-1] - ref.work[-1]) < 100 * tol
        assert tr.energy_drift < 100 * tol  # |E - W - E0| / max |E|
    assert errors[0] / errors[1] > 30 and errors[1] / errors[2] > 30 and errors[2] < 1e-9, errors
    grid = skewpend.simulate(chain, y0, 3.0, method="taylor", rtol=1e-12, atol=1e-12, dt_out=0.25)
    dense = skewpend.simulate(chain, y0, 3.0, method="dop853", rtol=1e-13, atol=1e-13, dt_out=0.25)
    np.testing.assert_allclose(grid.t, dense.t, rtol=0, atol=1e-15)
    assert np.max(np.abs(grid.y - dense.y)) < 1e-9


def test_simulate_refuses_for_a_chain_in_one_line():
    chain = Chain.from_lists(3)
    with pytest.raises(ParameterError, match=r"y0 must be 6 numbers \(q1, q2, q3, dq1, dq2, dq3\), got 4"):
        skewpend.simulate(chain, [0.1] * 4, 1.0)


# -- the specification's method for any number of links ---------------------------------------------------------
def _three_links(torque=0.2):
    return Chain(links=(
        Link(axis=(0, 0, 1), length=0.5, mass=0.8, com=(0.02, 0.2, 0.0), inertia=(0.02, 0.004, 0.021), damping=0.1),
        Link(axis=(0.3, 0, 1), length=0.4, mass=0.6, torque=torque),
        Link(axis=(1, 0.2, 0.5), length=0.3, mass=0.3, com=(0.0, 0.15, 0.01),
             inertia=((0.003, 0.0002, 0), (0.0002, 0.0005, 0), (0, 0, 0.003))),
    ), g=9.81)


def test_three_links_by_rotation_tensors_equal_the_recursive_algorithms():
    """derive(chain): rotation tensors composed link by link and Lagrange's equations, exact (SymPy); the
    recursive algorithms' compiled code agrees with it to rounding at random states."""
    import sympy as sp
    from skewpend.symbolic.derivation import coordinate_symbol

    chain = _three_links()
    eom = skewpend.derive(chain)
    assert eom.coordinates == ("q1", "q2", "q3") and eom.mass_matrix.shape == (3, 3)
    K, p = kernels.chain_kernel(chain), recursive.parameter_vector(chain)
    names = [coordinate_symbol(n) for n in ("q1", "q2", "q3", "dq1", "dq2", "dq3")]
    M, f = sp.lambdify(names, eom.mass_matrix), sp.lambdify(names, eom.forcing)
    E = sp.lambdify(names, eom.kinetic_energy + eom.potential_energy)
    rng = np.random.default_rng(0)
    for _ in range(20):
        y = np.r_[rng.uniform(-3, 3, 3), rng.normal(scale=2, size=3)]
        acc = np.linalg.solve(np.array(M(*y), float), np.array(f(*y), float).ravel())
        out = np.zeros(7)
        K.rhs(np.r_[y, 0.0], p, out)
        assert np.max(np.abs(out[3:6] - acc)) <= 1e-12 * np.max(np.abs(acc))
        assert abs(K.energy(np.r_[y, 0.0], p) - E(*y)) <= 1e-12 * abs(E(*y))
    steps = eom.steps
    assert [k for k in steps][:3] == ["P1", "e1", "omega1"] and "P3" in steps


def test_a_chain_of_two_derives_the_double_pendulums_equations(recursive_forms):
    import sympy as sp

    params = skewpend.Parameters(a=1, b=0.5, m1=2, m2=1, alpha=0.3, g=9.81, c2=0.1)
    one, two = skewpend.derive(params), skewpend.derive(Chain.from_parameters(params))
    assert two.coordinates == ("phi", "psi")
    for x, y in zip(list(one.mass_matrix) + list(one.forcing), list(two.mass_matrix) + list(two.forcing)):
        d = sp.lambdify(list(one.q) + list(one.dq), x - y)
        for state in ((0.3, -1.0, 0.5, 2.0), (2.0, 0.7, -1.0, 0.1)):
            assert abs(d(*state)) <= 1e-12


def test_linearising_a_chain_needs_its_rest_and_gives_the_small_swings():
    from skewpend.errors import EquilibriumError

    with pytest.raises(EquilibriumError, match="q = 0 is not an equilibrium"):
        skewpend.derive(_three_links()).linearize()
    # planar thin rods, equal: the stiffness of the hanging rest is the gravity moments of the links below
    chain = Chain.from_lists(3, length=1.0, mass=1.0, g=9.81)
    lin = skewpend.derive(chain).linearize()
    # relative angles: K0 = g * [[5/2, 3/2, 1/2], [3/2, 3/2, 1/2], [1/2, 1/2, 1/2]] (absolute angles: diag(5/2, 3/2, 1/2))
    T = np.tril(np.ones((3, 3)))  # absolute = T relative
    expected = 9.81 * T.T @ np.diag([2.5, 1.5, 0.5]) @ T
    assert np.allclose(np.array(lin.K, dtype=float), expected, rtol=1e-14, atol=1e-12)


def test_the_compact_and_straight_forms_agree():
    """The two printings of the same recursions (straight-line code for short chains, one step of each
    recursion looped over the links for long ones) give the same functions to rounding."""
    chain = random_chain(4, np.random.default_rng(4))
    p = recursive.parameter_vector(chain)
    A, B = kernels.chain_kernel(chain, "straight"), kernels.chain_kernel(chain, "compact")
    assert recursive.chain_form(recursive.structure_of_chain(chain)) == "compact"
    rng = np.random.default_rng(5)
    for _ in range(10):
        y = np.r_[rng.uniform(-3, 3, 4), rng.normal(scale=2, size=4), 0.0]
        for name, size in (("rhs", 9), ("ham_rhs", 9), ("momenta", 4), ("velocities", 4), ("tips", 12)):
            a, b = np.zeros(size), np.zeros(size)
            getattr(A, name)(y, p, a)
            getattr(B, name)(y, p, b)
            assert np.max(np.abs(a - b)) <= 1e-12 * max(1.0, np.max(np.abs(a))), name
        assert abs(A.energy(y, p) - B.energy(y, p)) <= 1e-12 * max(1.0, abs(A.energy(y, p)))
    with_rotor = chain.replace_link(2, rotor=1e-3, gear=-3.0)
    assert recursive.chain_form(recursive.structure_of_chain(with_rotor)) == "straight"


# -- the command line: a chain from a run file ---------------------------------------------------------------
def test_simulate_a_chain_from_a_run_file(tmp_path):
    from helpers import run_cli

    ran = run_cli(["simulate", "--config", EXAMPLES / "skewed_triple.toml", "--t-end", "2", "--rtol", "1e-12",
                   "--atol", "1e-12"])
    assert ran.code == 0, ran.err
    assert "final state   t=2 s  q1=" in ran.out and "dq3=" in ran.out
    # the same run from the library: the run file's chain and start
    chain = Chain.from_mapping({"g": 9.81, "links": [
        dict(length=0.5, mass=1.0), dict(length=0.4, mass=0.8, axis=(0.5, 0, 1)),
        dict(length=0.3, mass=0.5, axis=(1, 0, 0), damping=0.01)]})
    traj = skewpend.simulate(chain, [math.radians(60), -0.3, 0.2, 0, 0, 0], 2.0, rtol=1e-12, atol=1e-12)
    q1 = float(ran.out.split("q1=")[1].split()[0])
    assert q1 == pytest.approx(traj.y[-1, 0], abs=1e-11)


@pytest.mark.parametrize("text, extra, words", [
    ("[[links]]\nmass = -1\n", [], "link 1 mass must be > 0"),
    ("[[links]]\nmass = 1\ncolour = 2\n", [], "[[links]] 1: unknown key 'colour'"),
    ("[[links]]\n[[links]]\n[initial]\nq0 = [1, 2, 3]\n", [], "q0: expected 2 values (one a link), got 3"),
    ("[[links]]\n[[links]]\n", ["--m1", "2"], "--m1: a chain of links ([[links]] or --links) does not take"),
    ("[[links]]\n[[links]]\n[initial]\nphi0 = 1\n", [], "a chain's start is --q0 and --dq0 or [initial] q0 and dq0"),
    ("[[links]]\n[[links]]\n", ["--links", "3"], "--links 3: the run file"),
    ("[[links]]\n[[links]]\n", ["--link-mass", "1,2,3"], "--link-mass: expected 1 or 2 values"),
])
def test_bad_chain_run_files_are_one_line_exit_2(tmp_path, text, extra, words):
    from helpers import run_cli

    path = tmp_path / "chain.toml"
    path.write_text(text)
    ran = run_cli(["simulate", "--config", path, *extra], cwd=tmp_path)
    assert ran.code == 2 and words in ran.err and len(ran.err.strip().splitlines()) == 1, ran.err


def test_a_chain_from_per_link_options_is_the_run_file_s(tmp_path):
    """``--links N`` and ``--link-FIELD`` values (one for every link, or one a link), ``--g`` and ``--q0``: the same
    chain and start as examples/skewed_triple.toml, so the same final state (to the digits printed); over a run
    file, the options replace a field for every link."""
    from helpers import run_cli

    common = ["--t-end", "2", "--rtol", "1e-12", "--atol", "1e-12"]
    a = run_cli(["simulate", "--config", EXAMPLES / "skewed_triple.toml", *common])
    b = run_cli(["simulate", "--links", "3", "--link-length", "0.5,0.4,0.3", "--link-mass", "1,0.8,0.5",
                 "--link-axis", "0,0,1;0.5,0,1;1,0,0", "--link-damping", "0,0,0.01", "--g", "9.81",
                 "--q0", "60deg,-0.3,0.2", *common])
    assert a.code == 0 and b.code == 0, (a.err, b.err)
    final = lambda out: out.split("final state", 1)[1].splitlines()[0]  # noqa: E731
    assert final(a.out) == final(b.out)
    # over the run file: every link's damping 0.2, g = 5 (the library's run of that chain)
    c = run_cli(["simulate", "--config", EXAMPLES / "skewed_triple.toml", "--link-damping", "0.2", "--g", "5", *common])
    assert c.code == 0, c.err
    chain = Chain.from_mapping({"g": 5.0, "links": [
        dict(length=0.5, mass=1.0, damping=0.2), dict(length=0.4, mass=0.8, axis=(0.5, 0, 1), damping=0.2),
        dict(length=0.3, mass=0.5, axis=(1, 0, 0), damping=0.2)]})
    traj = skewpend.simulate(chain, [math.radians(60), -0.3, 0.2, 0, 0, 0], 2.0, rtol=1e-12, atol=1e-12)
    assert float(c.out.split("q1=")[1].split()[0]) == pytest.approx(traj.y[-1, 0], abs=1e-11)


@pytest.mark.parametrize("argv, words", [
    (["simulate", "--link-mass", "1"], "--link-mass: how many links? give --links N"),
    (["simulate", "--links", "3", "--link-mass", "1,2"], "--link-mass: expected 1 or 3 values"),
    (["simulate", "--links", "3", "--link-mass", "1,-1,1"], "--link-mass: link 2 mass must be > 0, got -1"),
    (["simulate", "--links", "3", "--link-axis", "0,0,0"], "--link-axis: link 1 axis must be a non-zero vector"),
    (["simulate", "--links", "3", "--link-axis", "0,0,1;1,0"], "--link-axis"),
    (["simulate", "--links", "3", "--link-inertia", "1,1,5"], "triangle inequality"),
    (["simulate", "--links", "3", "--link-com", "a,0,0"], "a chain's values are numbers"),
    (["simulate", "--links", "0"], "--links: expected a whole number from 1 to 32"),
    (["simulate", "--links", "3", "--a", "1"], "--a: a chain of links ([[links]] or --links) does not take"),
    (["simulate", "--links", "3", "--phi0", "1"], "--phi0: a chain's start is --q0"),
    (["simulate", "--links", "3", "--q0", "1,2"], "--q0: expected 3 values (one a link), got 2"),
    (["simulate", "--q0", "1,2"], "--q0: a chain's start (one value a link); the double pendulum's is phi0"),
    (["poincare", "--links", "3"], "--links: a chain of links is not taken by skewpend poincare"),
    (["modes", "--links", "3", "--link-torque", "1"], "--link-torque"),
])
def test_bad_per_link_options_are_one_line_exit_2(tmp_path, argv, words):
    from helpers import run_cli

    ran = run_cli(argv, cwd=tmp_path)
    assert ran.code == 2 and words in ran.err and len(ran.err.strip().splitlines()) == 1, ran.err


def test_commands_of_the_double_pendulum_refuse_links(tmp_path):
    from helpers import run_cli

    ran = run_cli(["poincare", "--config", EXAMPLES / "skewed_triple.toml"], cwd=tmp_path)
    assert ran.code == 2 and "[[links]] (a chain of links) is not read by skewpend poincare" in ran.err
    assert "(chains: skewpend simulate, animate, report, validate, lyapunov, flipmap, export, modes" in ran.err


EXAMPLES = __import__("pathlib").Path(__file__).resolve().parent.parent / "examples"


# -- normal modes of a chain -------------------------------------------------------------------------------------
def test_the_compound_triple_pendulum_has_its_textbook_modes():
    """Three equal uniform rods, planar: the linear matrices in absolute angles are the textbook's,
    M_ij = l^2 (m/3 + m (n - i - 1)) on the diagonal and l^2 m (1/2 + n - j - 1) off it (i < j),
    K = g l m diag(1/2 + n - i - 1); relative angles are absolute = T relative."""
    from scipy.linalg import eigh

    n, g = 3, 9.81
    chain = Chain.from_lists(n, length=1.0, mass=1.0, g=g)
    modes = skewpend.normal_modes(chain)
    M = np.array([[(1 / 3 + n - i - 1) if i == j else (0.5 + n - max(i, j) - 1) for j in range(n)] for i in range(n)])
    K = g * np.diag([0.5 + n - i - 1 for i in range(n)])
    expected = np.sqrt(eigh(K, M, eigvals_only=True))  # absolute and relative angles: the same frequencies
    assert np.allclose(modes.frequencies, expected, rtol=1e-13)
    assert modes.shapes.shape == (3, 3) and len(modes.equilibrium) == 3
    assert modes.to_xarray()["frequency"].size == 3


def test_a_chains_damped_modes_are_the_state_matrixs_eigenvalues():
    chain = Chain.from_lists(4, length=0.5, mass=[1.0, 0.8, 0.6, 0.4], damping=[0.3, 0.1, 0.05, 0.02],
                             axis=[(0, 0, 1), (0.3, 0, 1), (0, 0.2, 1), (1, 0, 1)])
    modes = skewpend.normal_modes(chain)
    expected = np.linalg.eigvals(modes.state_matrix)
    got = modes.eigenvalue_pairs.ravel()
    assert np.allclose(np.sort_complex(got), np.sort_complex(expected), rtol=1e-10, atol=1e-12)
    assert np.all((modes.damping_ratios > 0) & (modes.damping_ratios < 1))
    # each pair is the one its undamped mode's frequency is nearest to (light damping)
    assert np.allclose(modes.damped_frequencies, modes.frequencies, rtol=0.05)


def test_the_double_pendulums_modes_from_its_chain(recursive_forms):
    params = skewpend.Parameters(a=1, b=0.8, m1=1, m2=0.7, alpha=0.6, g=9.81, c1=0.3, c2=0.1)
    one, two = skewpend.normal_modes(params), skewpend.normal_modes(Chain.from_parameters(params))
    assert np.allclose(one.frequencies, two.frequencies, rtol=1e-13)
    assert np.allclose(one.eigenvalue_pairs, two.eigenvalue_pairs, rtol=1e-12)
    with pytest.raises(skewpend.errors.EquilibriumError, match="q = 0 is not an equilibrium of this chain"):
        skewpend.normal_modes(_three_links())


@pytest.mark.parametrize("call", [
    lambda c: skewpend.poincare(c, energy=1.0), lambda c: skewpend.chaos_diagram(c),
    lambda c: skewpend.nnm_alpha(c, 1, energy=0.1, alphas=[0.0, 0.1]),
])
def test_what_is_not_for_chains_yet_says_so_in_one_line(call):
    with pytest.raises(ParameterError) as info:
        call(skewpend.Chain.from_lists(3))
    assert "not a chain of 3 links" in str(info.value) and "\n" not in str(info.value)


# -- equilibria of a chain ---------------------------------------------------------------------------------------
def test_a_chain_has_its_two_to_the_n_equilibria():
    """Three equal uniform rods in a plane: 8 equilibria, every rod down or up; the potential of each is
    g times the rise of the centres of mass (rod k's centre k + 1/2 below the roof hanging, the rods above
    it turned with their own directions); the Morse index counts the upright rods; the indices sum to 0 as
    on the 3-torus."""
    chain = Chain.from_lists(3, length=1.0, mass=1.0, g=9.81)
    eq = skewpend.equilibria(chain)
    assert eq.ok and len(eq) == 8 and eq.index_sum == 0
    for e in eq:
        d = [1.0 if word == "down" else -1.0 for word in e.label.split("-")]  # each rod's direction along j
        y = [sum(d[:k]) + d[k] / 2 for k in range(3)]  # the centres of mass below the roof
        assert e.morse_index == d.count(-1.0)
        assert e.potential == pytest.approx(-9.81 * sum(y[k] - (k + 0.5) for k in range(3)), abs=1e-9)
    hanging = eq.find("down-down-down")
    assert np.allclose(hanging.frequencies, skewpend.normal_modes(chain).frequencies, rtol=1e-12)
    top = skewpend.normal_modes(chain, about="up-up-up")
    assert np.all(top.growth_rates > 0) and top.growth_rates.size == 3


def test_the_double_pendulums_equilibria_from_its_chain(recursive_forms):
    params = skewpend.Parameters(a=1, b=0.8, m1=1, m2=0.7, alpha=0.6, g=9.81, com2=(0.05, 0.4, 0.0))
    one, two = skewpend.equilibria(params), skewpend.equilibria(Chain.from_parameters(params))
    assert [e.label for e in one] == [e.label for e in two]
    for x, y in zip(one, two):
        assert np.max(np.abs(np.array(x.q) - np.array(y.q))) < 1e-10
        assert np.allclose(x.frequencies, y.frequencies, rtol=1e-10)


def test_a_skewed_chain_of_four_finds_all_sixteen():
    chain = Chain.from_lists(4, length=0.5, mass=[1.0, 0.8, 0.6, 0.4],
                             axis=[(0, 0, 1), (0.3, 0, 1), (0, 0.2, 1), (1, 0, 1)],
                             com=[(0.05, 0.25, 0), (0, 0.25, 0.02), (0, 0.25, 0), (0.01, 0.25, 0)])
    eq = skewpend.equilibria(chain)
    assert eq.ok and len(eq) == 16 and eq.index_sum == 0
    terms = recursive.potential_terms(chain)
    for e in eq:
        assert np.max(np.abs(terms(e.q)[1])) < 1e-10  # grad V = 0 there (no torques)


@pytest.mark.parametrize("suffix", [".csv", ".nc"])
def test_a_chains_run_streams_to_a_file_and_reads_back(tmp_path, suffix):
    """The file holds t, q1..qn, dq1..dqn, energy, work and every rod's end; open_trajectory and open_result
    read it back with its chain (the stored energies checked against the chain's model)."""
    chain = Chain.from_lists(3, damping=[0.05, 0.0, 0.02], axis=[(0, 0, 1), (0.4, 0, 1), (1, 0, 0)])
    path = tmp_path / f"run{suffix}"
    traj = skewpend.simulate(chain, [0.5, 0.2, 0.1, 0, 0, 0], 2.0, out=path, dt_out=0.1)
    back = skewpend.open_trajectory(path)
    assert back.params == chain and back.y.shape == (21, 6)
    assert np.array_equal(back.y, traj.y) and np.array_equal(back.energy, traj.energy)
    assert np.allclose(back.tips(), traj.tips(), rtol=0, atol=1e-15)
    again = skewpend.open_result(path)
    assert again.params.n == 3
    if suffix == ".csv":
        assert path.read_text().splitlines()[0] == "t,q1,q2,q3,dq1,dq2,dq3,energy,work,x1,y1,z1,x2,y2,z2,x3,y3,z3"


def test_a_chains_run_is_drawn(tmp_path):
    """skewpend simulate --plot for a chain: its angles, speeds, energy error and tip in one figure (a PNG
    with a drawing: the pixels vary), the trajectory beside it in a file."""
    from helpers import run_cli

    ran = run_cli(["simulate", "--config", EXAMPLES / "skewed_triple.toml", "--t-end", "3", "--plot", "run.png",
                   "--out", "run.nc", "--dt-out", "0.01"], cwd=tmp_path)
    assert ran.code == 0, ran.err
    import matplotlib.image

    image = matplotlib.image.imread(tmp_path / "run.png")
    assert image.shape[0] > 500 and float(np.std(image[..., :3])) > 0.05
    assert skewpend.open_trajectory(tmp_path / "run.nc").y.shape == (301, 6)


def test_modes_and_equilibria_of_a_chain_from_the_command_line(tmp_path):
    from helpers import run_cli

    path = tmp_path / "chain.toml"
    path.write_text("[chain]\ng = 9.81\n" + "[[links]]\nlength = 1.0\nmass = 1.0\n" * 3)
    ran = run_cli(["modes", "--config", path], cwd=tmp_path)
    assert ran.code == 0, ran.err
    assert "Normal modes about the hanging equilibrium (q1 = q2 = q3 = 0)" in ran.out
    first = float(ran.out.splitlines()[3].split()[1])
    assert first == pytest.approx(skewpend.normal_modes(Chain.from_lists(3)).frequencies[0], rel=1e-7)
    ran = run_cli(["modes", "--config", path, "--about", "up-up-up"], cwd=tmp_path)
    assert ran.code == 0 and ran.out.count("unstable: grows like") == 3, ran.out + ran.err
    ran = run_cli(["equilibria", "--config", path], cwd=tmp_path)
    assert ran.code == 0 and "8 equilibria" in ran.out and "up-up-up" in ran.out
    ran = run_cli(["equilibria", "--config", path, "--format", "json"], cwd=tmp_path)
    import json

    data = json.loads(ran.out)
    assert len(data["equilibria"]) == 8 and len(data["equilibria"][0]["q"]) == 3
    ran = run_cli(["modes", "--config", path, "--sweep", "alpha=0:90deg:3"], cwd=tmp_path)
    assert ran.code == 2 and "cannot sweep 'alpha' of a chain of 3 links" in ran.err
    ran = run_cli(["modes", "--config", path, "--sweep", "tilt3=0:90deg:4"], cwd=tmp_path)
    assert ran.code == 0 and "tilt3 [deg]" in ran.out and "omega3" in ran.out
    ran = run_cli(["modes", "--config", path, "--check-nonlinear", "2deg"], cwd=tmp_path)
    assert ran.code == 0 and "nonlinear check, largest initial angle" in ran.out and "  mode 3: linear" in ran.out


def test_auto_takes_the_taylor_series_up_to_three_links_and_dop853_beyond():
    """simulate's default on a chain: up to conventions.SERIES_MAX_LINKS links the Taylor series (printed from the
    model read as polynomials; SKEWPEND_TAYLOR_BUILD=foreground here, so the first run waits for its library), with
    the rule's words; a chain of four dop853, naming why. The Taylor run agrees with a tight dop853 to its tolerance."""
    from skewpend.numeric.conventions import SERIES_MAX_LINKS
    from skewpend.numeric.simulation import AUTO_RULE

    assert SERIES_MAX_LINKS == 3
    three, four = Chain.from_lists(3), Chain.from_lists(4)
    tr = skewpend.simulate(three, [0.5, -0.3, 0.2, 0, 0, 0], 2.0)
    assert tr.method == "taylor" and tr.settings["method_choice"] == AUTO_RULE["series"]
    ref = skewpend.simulate(three, [0.5, -0.3, 0.2, 0, 0, 0], 2.0, method="dop853", rtol=1e-13, atol=1e-13)
    assert np.max(np.abs(tr.y[-1] - ref.y[-1])) < 1e-8
    tr4 = skewpend.simulate(four, [0.1] * 4 + [0.0] * 4, 1.0)
    assert tr4.method == "dop853" and tr4.settings["method_choice"] == AUTO_RULE["recursive"]
    assert "more than 3 links" in tr4.settings["method_choice"]
