"""Lyapunov spectra, the state-transition flow, periodic orbits and LQR of a chain of links (issue 38): the
chain's variational equations against differences of its flow, the exact volume identity of the Lagrangian
flow in ``(q, q')``, the chain of two against the double pendulum's own kernels, a region of attraction
against the nonlinear loop, and the command line."""

from __future__ import annotations

import json
import subprocess
import sys

import numpy as np
import pytest

import skewpend
import skewpend.numeric.kernels
from skewpend.analysis.modes import check_nonlinear
from skewpend.errors import ParameterError
from skewpend.numeric import recursive
from skewpend.numeric.variational import flow
from skewpend.symbolic.chain import Chain


def _triple(damping=0.0) -> Chain:
    return Chain.from_lists(3, axis=[(0, 0, 1), (0.3, 0.1, 1), (1, 0.2, 0.4)], mass=[0.3, 0.25, 0.1],
                            length=[0.2, 0.25, 0.24], damping=damping,
                            com=[(0.01, 0.1, 0.0), (0.0, 0.12, 0.01), (0.002, 0.1, 0.0)])


Y0 = [1.2, -0.8, 0.6, 0.5, 0.0, -1.0]


def _log_det_mass(chain, q) -> float:
    fn = recursive.chain_functions(recursive.structure_of_chain(chain))["mass"]
    n = chain.n
    M = np.zeros((n, n))
    M[np.tril_indices(n)] = np.array(fn(q, recursive.parameter_vector(chain)), dtype=float).ravel()
    M = M + np.tril(M, -1).T
    return float(np.linalg.slogdet(M)[1])


def test_the_chains_state_transition_matrix_equals_differences_of_its_flow():
    """``d y(t)/d y0`` of the variational equations (rhs_jac from CasADi's derivative) against central
    differences of the flow itself (step 1e-6, tolerance 1e-10: the difference quotient's error is
    ~h^2 |y'''| + tol/h ~ 1e-7 of the entries); the flow's state is the chain's motion (the chain's own
    kernel's DOP853 on the plain equations: a kernel of its own; a Taylor library of order 16 for this chain
    alone cost more than the rest of the module)."""
    chain = _triple(damping=[0.01, 0.02, 0.005])
    t = 1.5
    got = flow(chain, Y0, t, rtol=1e-13, atol=1e-13)
    assert got.status == 0 and got.stm.shape == (6, 6)
    h = 1e-6
    diff = np.column_stack([(flow(chain, np.add(Y0, h * e), t, rtol=1e-13, atol=1e-13).y
                             - flow(chain, np.subtract(Y0, h * e), t, rtol=1e-13, atol=1e-13).y) / (2 * h)
                            for e in np.eye(6)])
    assert np.abs(got.stm - diff).max() <= 1e-6 * np.abs(got.stm).max()
    sim = skewpend.simulate(chain, Y0, t, method="dop853", rtol=1e-13, atol=1e-13)
    np.testing.assert_allclose(got.y, np.asarray(sim.y)[-1, :6], rtol=0, atol=1e-10)


def test_a_conservative_chains_spectrum_obeys_the_volume_identity():
    """Without damping the flow keeps phase-space volume in (q, p); in (q, q') the volume element is
    dq dp / det M(q), so the whole spectrum times the time it covers is exactly
    ``log det M(q0) - log det M(q(T))`` (to the integration's error), whatever the motion."""
    chain = _triple()
    T = 3.0
    spec = skewpend.lyapunov(chain, Y0, t_end=T, renorm_every=0.5, windows=4, rtol=1e-12, atol=1e-12)
    assert spec.k == 6 and spec.full
    end = flow(chain, Y0, T, rtol=1e-13, atol=1e-13).y
    expected = _log_det_mass(chain, Y0[:3]) - _log_det_mass(chain, end[:3])
    assert abs(expected) > 0.05  # the identity is tested, not a zero
    assert abs(spec.sum * T - expected) <= 1e-7


def test_the_chain_of_two_has_the_double_pendulums_exponents(recursive_forms):
    """The double pendulum's chaos kernel (its Jacobian from the symbolic derivation) and the chain of two
    (CasADi's derivative of the recursive algorithms): the same exponents over a short run, before
    rounding differences grow (to 1e-7 of the largest)."""
    params = skewpend.Parameters(a=1.0, b=0.8, m1=1.0, m2=0.7, alpha=0.4, g=9.81, c1=0.02)
    y0 = [2.0, 1.0, 0.0, 0.5]
    a = skewpend.lyapunov(params, y0, t_end=6, renorm_every=0.5, windows=4, rtol=1e-12, atol=1e-12)
    b = skewpend.lyapunov(Chain.from_parameters(params), y0, t_end=6, renorm_every=0.5, windows=4, rtol=1e-12,
                          atol=1e-12)
    np.testing.assert_allclose(b.exponents, a.exponents, rtol=0, atol=1e-7 * np.abs(a.exponents).max())


def test_a_chains_lyapunov_refuses_what_it_cannot_do():
    chain = _triple()
    with pytest.raises(ParameterError, match="n_exponents must be a whole number from 1 to 6"):
        skewpend.lyapunov(chain, Y0, t_end=10, n_exponents=7)
    with pytest.raises(ParameterError, match=r"y0 must be 6 numbers \(q1, q2, q3, dq1, dq2, dq3\)"):
        skewpend.lyapunov(chain, [1, 2, 0, 0], t_end=10)


def test_the_cli_gives_a_chains_spectrum(tmp_path):
    out = tmp_path / "spectrum.json"
    run = subprocess.run([sys.executable, "-m", "skewpend", "lyapunov", "--config", "examples/skewed_triple.toml",
                          "--t-end", "20", "--out", str(out)], capture_output=True, text=True)
    assert run.returncode in (0, 1), run.stderr  # 1: not settled in 20 s (said in one line)
    assert "lambda_6" in run.stdout and "Traceback" not in run.stderr
    data = json.loads(out.read_text())
    assert len(data["exponents"]) == 6 and len(data["params"]["links"]) == 3


def test_a_chains_spectrum_reads_back(tmp_path):
    chain = _triple(damping=0.01)
    spec = skewpend.lyapunov(chain, Y0, t_end=8, windows=4)
    back = skewpend.open_result(spec.to_netcdf(tmp_path / "spectrum.nc"))
    assert back.params == chain and back.k == 6
    np.testing.assert_array_equal(back.exponents, spec.exponents)
    assert np.isfinite(spec.kaplan_yorke_dimension)  # damped: an attractor's dimension


# -- periodic orbits -------------------------------------------------------------------------------------------
def _orbit_chain() -> Chain:
    return Chain.from_lists(3, length=1.0, mass=1.0, axis=[(0, 0, 1), (0.2, 0, 1), (0, 0.3, 1)])


def _mode_guess(chain, k, amplitude):
    modes = skewpend.normal_modes(chain)
    v = np.real(np.asarray(modes.shapes)[:, k])
    return list(v / np.abs(v).max() * amplitude) + [0.0] * chain.n, 2 * np.pi / modes.frequencies[k]


@pytest.mark.parametrize("k", [0, 2])
def test_a_chains_small_orbits_approach_the_linear_modes(k):
    """Orbits of a skewed triple pendulum from its linear modes' shapes: each closes (simulate, another
    integrator, returns to the start over the period to 1e-8), its multipliers' product is 1
    (det of the monodromy = det M(q0)/det M(q(T)) = 1 on a closed orbit), and its period tends to the
    linear one as the amplitude squared (halving the amplitude divides the deviation by about 4).  The Taylor
    run at rtol 1e-12 (order 15, the library tests/test_identify_chain.py's chain of this structure loads; its
    error ~1e-11 over a period, far below the 1e-8 asserted)."""
    chain = _orbit_chain()
    deviation = []
    for amplitude in (0.1, 0.05):
        y0, T0 = _mode_guess(chain, k, amplitude)
        orbit = skewpend.periodic_orbit(chain, y0, T0)
        assert orbit.ok, orbit.message
        assert orbit.stable and orbit.multipliers.shape == (6,)
        assert abs(np.prod(orbit.multipliers) - 1) <= 1e-8
        sim = skewpend.simulate(chain, orbit.state, orbit.period, rtol=1e-12, atol=1e-12)
        np.testing.assert_allclose(np.asarray(sim.y)[-1, :6], orbit.state, rtol=0, atol=1e-8)
        deviation.append(orbit.period / T0 - 1)
    assert 3.5 < deviation[0] / deviation[1] < 4.5


def test_the_chain_of_twos_orbit_is_the_double_pendulums(recursive_forms):
    params = skewpend.Parameters(a=1.0, b=0.8, m1=1.0, m2=0.7, alpha=0.6, g=9.81)
    guess, period = [0.6, 0.5, 0.0, 0.0], 2.3
    a = skewpend.periodic_orbit(params, guess, period)
    b = skewpend.periodic_orbit(Chain.from_parameters(params), guess, period)
    assert a.ok and b.ok
    assert abs(a.period - b.period) <= 1e-9 * a.period
    np.testing.assert_allclose(b.state, a.state, rtol=0, atol=1e-8)
    np.testing.assert_allclose(np.sort(np.abs(b.multipliers)), np.sort(np.abs(a.multipliers)), rtol=0, atol=1e-6)


def test_a_chains_orbit_refuses_losses_and_other_shapes(tmp_path):
    with pytest.raises(ParameterError, match="needs a conservative model without losses .* link 2 damping = 0.1"):
        skewpend.periodic_orbit(_triple(damping=[0.0, 0.1, 0.0]), Y0, 2.0)
    with pytest.raises(ParameterError, match=r"y0 must be six numbers \(q1, q2, q3, q1', q2', q3'\)"):
        skewpend.periodic_orbit(_orbit_chain(), [0.1, 0.1, 0, 0], 2.0)
    with pytest.raises(ParameterError, match=r"mode must be a whole number from 1 to 3 .*got 4"):
        skewpend.periodic_orbit(_orbit_chain(), mode=4, energy=0.1)  # modes 1 to n work since issue 51
    y0, T0 = _mode_guess(_orbit_chain(), 0, 0.05)
    orbit = skewpend.periodic_orbit(_orbit_chain(), y0, T0)
    back = skewpend.open_result(orbit.to_netcdf(tmp_path / "orbit.nc"))
    assert back.params == orbit.params and back.period == orbit.period and back.stable


# -- LQR ---------------------------------------------------------------------------------------------------------
def reference_closed_loop(chain: Chain, K: np.ndarray, target: np.ndarray, umax):
    """The saturated LQR loop of a chain written here in NumPy, independently of ``integrators.c``'s law:
    ``u = clip(-K dx)`` (the angles of ``dx`` wrapped) added to each joint's constant torque, then the
    compiled right-hand side, for rows of states."""
    kernel = skewpend.numeric.kernels.chain_kernel(chain)
    p0 = recursive.parameter_vector(chain)
    n = chain.n
    names = recursive.parameter_names(n)
    tau = np.array([names.index(f"tau{i}") for i in range(1, n + 1)])
    limit = np.asarray(umax, dtype=float)

    def rhs(X: np.ndarray) -> np.ndarray:
        X = np.atleast_2d(np.asarray(X, dtype=float))
        dx = X - target
        dx[:, :n] = (dx[:, :n] + np.pi) % (2 * np.pi) - np.pi
        U = np.clip(-dx @ K.T, -limit, limit)
        out = np.empty((len(X), 2 * n))
        y, res, p = np.zeros(2 * n + 1), np.empty(2 * n + 1), p0.copy()
        for k in range(len(X)):
            y[:2 * n] = X[k]
            p[tau] = p0[tau] + U[k]
            kernel.rhs(y, p, res)
            out[k] = res[:2 * n]
        return out

    return rhs


def _balance_chain() -> Chain:
    return Chain.from_lists(3, length=[0.5, 0.4, 0.3], mass=[1.0, 0.8, 0.5], axis=[(0, 0, 1), (0.5, 0, 1), (1, 0, 0)])


def test_the_chain_of_twos_lqr_is_the_double_pendulums(recursive_forms):
    """The double pendulum's LQR (its linearisation from the symbolic derivation) and the chain of two's
    (CasADi's exact linearisation of the recursive algorithms): the same gain, for both robots' joints."""
    params = skewpend.Parameters(a=1.0, b=0.8, m1=1.0, m2=0.7, alpha=0.6, g=9.81, c1=0.05)
    chain = Chain.from_parameters(params)
    for actuated, joints in (("both", "all"), ("acrobot", (2,)), ("pendubot", (1,))):
        a = skewpend.lqr(params, "up-up", actuated, estimate=False)
        b = skewpend.lqr(chain, "up-up", joints, estimate=False)
        np.testing.assert_allclose(b.K, a.K, rtol=1e-8, atol=1e-8 * np.abs(a.K).max())
        np.testing.assert_allclose(np.sort_complex(b.eigenvalues), np.sort_complex(a.eigenvalues), rtol=1e-8)


def test_a_chains_lqr_region_holds_for_the_saturated_nonlinear_loop():
    """A skewed triple pendulum balanced upright by its elbow joint alone (joint 2), torques limited: from
    starts on the estimate's boundary (V = 0.9 rho) the saturated nonlinear closed loop converges to the
    top (SciPy's DOP853 on the compiled right-hand side, another integrator than the estimate's search)."""
    from scipy.integrate import solve_ivp

    chain = _balance_chain()
    design = skewpend.lqr(chain, "up-up-up", (2,), umax=20.0)
    assert design.K.shape == (1, 6) and design.eigenvalues.real.max() < 0 and 0 < design.rho < np.inf
    loop = reference_closed_loop(chain, design.gain, design.linearization.target, (20.0,) * 3)
    rng = np.random.default_rng(2)
    L = np.linalg.cholesky(design.P)
    for _ in range(4):
        z = rng.normal(size=6)
        dx = np.linalg.solve(L.T, z / np.linalg.norm(z)) * np.sqrt(0.9 * design.rho)
        x0 = design.linearization.target + dx
        assert design.inside(x0)
        sol = solve_ivp(lambda t, x: loop(x[None, :])[0], (0, 8), x0, method="DOP853", rtol=1e-9, atol=1e-9)
        end = sol.y[:, -1] - design.linearization.target
        assert np.abs(end).max() < 1e-3, end


def test_a_chains_lqr_refuses_what_it_cannot_take():
    chain = _balance_chain()
    with pytest.raises(ParameterError, match=r"actuated must be 'all' or the numbers of the joints with a motor, 1 to 3"):
        skewpend.lqr(chain, actuated=(4,), estimate=False)
    with pytest.raises(ParameterError, match="Q must be a 6x6 matrix"):
        skewpend.lqr(chain, Q=np.eye(4), estimate=False)
    with pytest.raises(ParameterError, match="equilibrium must be 3 angles in radians, got 2 values"):
        skewpend.lqr(chain, equilibrium=(3.1, 0.0), estimate=False)
    # angles near an equilibrium are that equilibrium, as for the double pendulum (one linearisation, issue 52)
    near = skewpend.lqr(chain, equilibrium=(3.1, 0.0, 0.0), estimate=False)
    top = skewpend.lqr(chain, estimate=False)
    assert near.linearization.equilibrium.label == "up-up-up"
    np.testing.assert_allclose(near.K, top.K, rtol=1e-12, atol=1e-12 * np.abs(top.K).max())


# -- mode sweeps ---------------------------------------------------------------------------------------------------
def test_the_chain_of_twos_tilt_sweep_is_the_double_pendulums_alpha_sweep(recursive_forms):
    """Hinge 2 of the chain of two turned from k towards i by t is the double pendulum's skew alpha = t:
    the same frequencies, shapes and resonances along the sweep (the symbolic model against the recursive one)."""
    params = skewpend.Parameters(a=1.0, b=0.8, m1=1.0, m2=0.7, alpha=0.0, g=9.81)
    grid = np.radians(np.linspace(0, 180, 19))
    a = skewpend.sweep(params, "alpha", grid)
    b = skewpend.sweep(Chain.from_parameters(params), "tilt2", grid)
    np.testing.assert_allclose(b.frequencies, a.frequencies, rtol=1e-10)
    np.testing.assert_allclose(np.abs(b.shapes), np.abs(a.shapes), rtol=1e-8, atol=1e-10)
    assert [(r.order, r.crossed) for r in b.resonances] == [(r.order, r.crossed) for r in a.resonances]
    np.testing.assert_allclose([r.value for r in b.resonances], [r.value for r in a.resonances], rtol=1e-8)


def test_a_chains_sweep_finds_the_crossings_of_neighbouring_modes(tmp_path):
    chain = _balance_chain()
    sw = skewpend.sweep(chain, "tilt2", np.radians(np.linspace(0, 90, 31)))
    assert sw.frequencies.shape == (31, 3) and sw.shapes.shape == (31, 3, 3)
    crossing = [r for r in sw.resonances if r.crossed and r.pair == (2, 3) and r.order == 2]
    assert len(crossing) == 1
    # at the crossing the ratio is 2: a sweep through it from the modes there
    at = skewpend.normal_modes(chain.replace_link(2, axis=(np.sin(crossing[0].value), 0.0, np.cos(crossing[0].value))))
    assert abs(at.frequencies[2] / at.frequencies[1] - 2) < 2e-3
    back = skewpend.open_result(sw.to_netcdf(tmp_path / "sweep.nc"))
    np.testing.assert_array_equal(back.frequencies, sw.frequencies)
    with pytest.raises(ParameterError, match="cannot sweep 'alpha' of a chain of 3 links"):
        skewpend.sweep(chain, "alpha", [0, 1])
    with pytest.raises(ParameterError, match="cannot sweep 'mass4' of a chain of 3 links"):
        skewpend.sweep(chain, "mass4", [0.1, 1])


def test_a_chains_nonlinear_frequencies_tend_to_its_linear_modes():
    """Started from each linear mode's shape, the nonlinear chain oscillates at the mode's frequency up to a
    shift that scales as the amplitude squared (halving it divides the shift by about 4, every mode)."""
    chain = _balance_chain()
    big = check_nonlinear(chain, np.radians(4.0))
    small = check_nonlinear(chain, np.radians(2.0))
    assert big.measured.shape == (3,)
    ratio = big.relative_shift / small.relative_shift
    assert np.all((3.3 < ratio) & (ratio < 4.7)), ratio
    assert np.all(np.abs(small.relative_shift) < 1e-3)
    with pytest.raises(ParameterError, match="needs a conservative model without losses"):
        check_nonlinear(_balance_chain().replace_link(1, damping=0.01), 0.05)
