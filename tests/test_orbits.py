"""Periodic orbits, their stability, and the nonlinear normal modes (skewpend.nnm).

Independent evidence: closed forms (at alpha = 90 deg each family is a simple pendulum in one
hinge, whose period is 4 K(k) / w0 with the complete elliptic integral from SciPy); the compiled
simulation (every orbit closes; the monodromy matrix agrees with finite differences of the flow);
the small-amplitude limit (the linear frequency, and the shift measured by check_nonlinear);
collocation (SciPy's solve_bvp on the generated Python right-hand side) against shooting; and the
symmetries alpha -> -alpha and (q, q') -> -(q, q').
"""

from __future__ import annotations

import math

import numpy as np
import pytest

import skewpend
from skewpend.analysis.orbits import backbones, flip_energy, nnm, periodic_orbit
from skewpend.errors import EquilibriumError, IntegrationError, ParameterError
from skewpend.status import Status


@pytest.fixture(scope="module")
def families():
    p = skewpend.reference_parameters()
    return p, {m: nnm(p, mode=m) for m in (1, 2)}


def test_families_reach_the_flip_energy_with_enough_orbits(families):
    p, fams = families
    E_flip = flip_energy(p)
    # the lowest energy at which a joint can flip, worked out by hand for thin rods: rod 2 upright
    assert E_flip == pytest.approx(0.7 * 9.81 * 0.8, rel=1e-12)
    for f in fams.values():
        assert f.ok and f.status == Status.SUCCESS
        assert len(f) >= 200
        assert f.energies[-1] == pytest.approx(E_flip, rel=1e-10)
        assert np.all(np.diff(f.energies) > 0)  # no fold for these families


def test_small_energy_limit_is_the_linear_mode(families):
    p, fams = families
    modes = skewpend.normal_modes(p)
    for m, f in fams.items():
        # frequency shift is second order in the amplitude, i.e. first order in the energy
        assert f.frequencies[0] == pytest.approx(modes.frequencies[m - 1], rel=5e-4 * 1)
        slope = (f.frequencies[1] - f.frequencies[0]) / (f.energies[1] - f.energies[0])
        extrapolated = f.frequencies[0] - slope * f.energies[0]
        assert extrapolated == pytest.approx(modes.frequencies[m - 1], rel=1e-7)


def test_nonlinear_shift_matches_check_nonlinear(families):
    """check_nonlinear starts each mode shape at rest with a largest angle of 10 deg and measures
    the frequency from zero crossings; the family at that start's energy has the same frequency."""
    from skewpend.analysis.equilibria import potential_function
    from skewpend.analysis.modes import check_nonlinear

    p, fams = families
    amplitude = math.radians(10)
    check = check_nonlinear(p, amplitude)
    modes = skewpend.normal_modes(p)
    V = potential_function(p)
    for m, f in fams.items():
        v = modes.shapes[:, m - 1]
        start = amplitude * v / np.abs(v).max()
        E = V(*start)
        w = np.interp(E, f.energies, f.frequencies)
        shift_family = w / modes.frequencies[m - 1] - 1
        assert shift_family == pytest.approx(check.relative_shift[m - 1], rel=0.02, abs=2e-6)


def test_every_orbit_closes_in_the_simulation(families):
    p, fams = families
    for f in fams.values():
        for k in np.linspace(0, len(f) - 1, 9).astype(int):
            tr = skewpend.simulate(p, f.states[k], f.periods[k], rtol=1e-13, atol=1e-13)
            assert np.max(np.abs(tr.y[-1] - f.states[k])) < 2e-9, (f.mode, k)


def test_multipliers_of_a_conservative_orbit(families):
    p, fams = families
    for f in fams.values():
        for k in np.linspace(0, len(f) - 1, 7).astype(int):
            mu = f.multipliers[k]
            # a double multiplier at 1 (time shift, energy): a Jordan block, so its eigenvalues
            # are perturbed by the square root of the monodromy's error (~1e-12): 1e-5 allowed
            near_one = np.sort(np.abs(mu - 1))
            assert near_one[1] < 1e-5
            rest = mu[np.argsort(np.abs(mu - 1))[2:]]
            assert abs(np.prod(rest) - 1) < 1e-7  # the other two are reciprocal
            # the determinant: volume in (q, q') changes by det M(q0) / det M(q(T)) = 1 over a period
            assert np.linalg.det(f.monodromies[k]) == pytest.approx(1.0, abs=1e-8)


def test_monodromy_equals_finite_differences_of_the_flow(families):
    p, fams = families
    f = fams[2]
    k = len(f) // 2
    x, T = f.states[k], f.periods[k]
    h = 1e-6
    fd = np.zeros((4, 4))
    for j in range(4):
        e = np.zeros(4)
        e[j] = h
        a = skewpend.simulate(p, x + e, T, rtol=1e-13, atol=1e-13).y[-1]
        b = skewpend.simulate(p, x - e, T, rtol=1e-13, atol=1e-13).y[-1]
        fd[:, j] = (a - b) / (2 * h)
    # central differences: error ~ h^2 |third derivative| + 1e-13 / h
    assert np.max(np.abs(fd - f.monodromies[k])) < 1e-6 * np.abs(fd).max()


@pytest.mark.parametrize("mode", [1, 2])
def test_closed_form_pendulum_families_at_90_degrees(mode):
    """At alpha = 90 deg, psi = 0 and phi = 0 are invariant: mode 1 swings rod 1 (and rod 2 with it)
    about k as one compound pendulum, mode 2 swings rod 2 alone about the horizontal i.  Each is
    I theta'' + k sin(theta) = 0, with period 4 K(m) / sqrt(k / I), m = E / (2 k)."""
    from scipy.special import ellipk

    a, b, m1, m2, g = 1.0, 0.8, 1.0, 0.7, 9.81
    p = skewpend.Parameters(a=a, b=b, m1=m1, m2=m2, alpha=math.pi / 2, g=g)
    if mode == 1:
        k, inertia = g * (m1 * a / 2 + m2 * a + m2 * b / 2), m1 * a * a / 3 + m2 * a * a + m2 * a * b + m2 * b * b / 3
        E_max = 0.99 * flip_energy(p)
    else:
        k, inertia = g * m2 * b / 2, m2 * b * b / 3
        E_max = 0.99 * 2 * k  # 99 % of the way to the separatrix (rod 2 upright)
    f = nnm(p, mode=mode, energy_max=E_max)
    assert f.ok and len(f) >= 200
    T = 4 * ellipk(f.energies / (2 * k)) / math.sqrt(k / inertia)
    assert np.max(np.abs(f.periods - T) / T) < 1e-9
    other = 1 if mode == 1 else 0
    assert np.max(np.abs(f.states[:, other])) < 1e-12 and np.max(np.abs(f.states[:, 2 + other])) < 1e-12


def test_collocation_agrees_with_shooting(families):
    """SciPy's solve_bvp (collocation) on the generated Python right-hand side: the brake orbit
    (both speeds zero at t = 0) at the energy of an orbit of the family has the same period."""
    from scipy.integrate import solve_bvp

    from skewpend.numeric.codegen import generate

    p, fams = families
    ns: dict = {}
    exec(generate(p, "python"), ns)  # the standalone generated module: rhs(t, y, p), energy(y, p)
    rhs, energy = ns["rhs"], ns["energy"]
    f = fams[1]
    k = len(f) * 2 // 3
    E = f.energies[k]
    # the family's orbit, restarted at its turning point (both speeds ~ 0), as the guess
    tr = skewpend.simulate(p, f.states[k], f.periods[k], rtol=1e-12, atol=1e-12, dt_out=f.periods[k] / 400)
    speed = np.hypot(tr.y[:, 2], tr.y[:, 3] * 0.3)
    i0 = int(np.argmin(speed))
    y_guess = np.roll(tr.y[:-1, :4], -i0, axis=0)
    y_guess = np.vstack([y_guess, y_guess[:1]]).T
    s = np.linspace(0, 1, y_guess.shape[1])

    def fun(s, y, par):
        return par[0] * np.array([rhs(0.0, np.r_[y[:, i], 0.0])[:4] for i in range(y.shape[1])]).T

    def bc(ya, yb, par):
        return np.array([yb[0] - ya[0], yb[1] - ya[1], ya[2], ya[3], energy(np.r_[ya, 0.0]) - E])

    sol = solve_bvp(fun, bc, s, y_guess, p=[f.periods[k]], tol=1e-9, max_nodes=20000)
    assert sol.success
    assert sol.p[0] == pytest.approx(f.periods[k], rel=1e-7)


def test_symmetries_map_families_onto_families(families):
    p, fams = families
    mirrored = skewpend.Parameters(a=p.a, b=p.b, m1=p.m1, m2=p.m2, alpha=-p.alpha, g=p.g)
    f = fams[2]
    g = nnm(mirrored, mode=2, energy_max=f.energies[-1])
    # alpha -> -alpha with psi -> -psi is a symmetry: the same frequencies at the same energies
    w = np.interp(f.energies[5:-5], g.energies, g.frequencies)
    assert np.max(np.abs(w - f.frequencies[5:-5])) < 1e-6 * f.frequencies.max()
    # (q, q') -> -(q, q'): the mirrored start is on an orbit of the same period
    k = len(f) // 3
    tr = skewpend.simulate(p, -f.states[k], f.periods[k], rtol=1e-13, atol=1e-13)
    assert np.max(np.abs(tr.y[-1] + f.states[k])) < 2e-9


def test_periodic_orbit_from_a_guess_and_from_a_mode(families):
    p, fams = families
    f = fams[1]
    k = len(f) // 2
    guess = f.states[k] * (1 + 1e-3)
    orbit = periodic_orbit(p, guess, f.periods[k] * 1.001, energy=f.energies[k])
    assert orbit.ok and orbit.period == pytest.approx(f.periods[k], rel=1e-8)
    assert orbit.stable == bool(f.stable[k])
    tr = orbit.trajectory(200)
    assert np.max(np.abs(tr.y[-1, :4] - orbit.state)) < 1e-8
    by_mode = periodic_orbit(p, mode=2, energy=2.0)
    assert by_mode.ok and by_mode.energy == pytest.approx(2.0, rel=1e-10)
    # against the family interpolated linearly between its orbits (energy steps of E_flip / 200)
    assert by_mode.frequency == pytest.approx(np.interp(2.0, fams[2].energies, fams[2].frequencies), rel=1e-5)
    assert "period" in by_mode.table() and "nan" not in by_mode.table().lower()


def test_rotating_orbit():
    """Rod 1 whirling over the top with rod 2 nearly locked: phi advances by 2 pi per period."""
    p = skewpend.reference_parameters()
    y0 = (0.0, 0.0, 8.0, 0.0)
    # a guess for the period: one turn at about the mean speed
    orbit = periodic_orbit(p, y0, 2 * math.pi / 7.5, rotation=(1, 0))
    assert orbit.ok, orbit.message
    tr = skewpend.simulate(p, orbit.state, orbit.period, rtol=1e-13, atol=1e-13)
    end = tr.y[-1]
    assert end[0] - orbit.state[0] == pytest.approx(2 * math.pi, abs=1e-8)
    assert np.max(np.abs(end[1:4] - orbit.state[1:])) < 1e-8


def test_failure_is_a_status_never_a_wrong_orbit():
    p = skewpend.reference_parameters()
    bad = periodic_orbit(p, (2.5, -2.0, 3.0, -4.0), 0.37, max_iterations=3)
    assert not bad.ok and bad.status == Status.NO_CONVERGENCE and "did not converge" in bad.message
    assert "no periodic orbit" in bad.table()
    with pytest.raises(IntegrationError):
        periodic_orbit(p, (2.5, -2.0, 3.0, -4.0), 0.37, max_iterations=3, throw=True)


def test_refusals():
    p = skewpend.reference_parameters()
    damped = skewpend.Parameters(a=1, b=0.8, m1=1, m2=0.7, alpha=0.6, g=9.81, c1=0.1)
    with pytest.raises(ParameterError, match="conservative"):
        nnm(damped)
    with pytest.raises(ParameterError, match="conservative"):
        periodic_orbit(damped, (0.1, 0, 0, 0), 2.0)
    with pytest.raises(EquilibriumError):
        nnm(skewpend.Parameters(a=1, b=0.8, m1=1, m2=0.7, alpha=0.6, g=9.81, tau1=1.0))
    with pytest.raises(ParameterError, match="mode"):
        nnm(p, mode=3)
    with pytest.raises(ParameterError, match="y0"):
        periodic_orbit(p, (0.1, math.nan, 0, 0), 2.0)
    with pytest.raises(ParameterError, match="period"):
        periodic_orbit(p, (0.1, 0, 0, 0), -1.0)
    with pytest.raises(ParameterError, match="energy="):
        periodic_orbit(p, mode=1)


def test_backbones_find_the_internal_resonances():
    """For the built-in model w2/w1 = 1.963 at zero energy and falls as the energy grows (mode 2
    softens faster): every ratio p/q (p, q <= 3) that the families' frequency ratio passes is
    reported (here 3/2, near 2.76 J), where the interpolated ratio crosses it."""
    p = skewpend.reference_parameters()
    bb = backbones(p, max_order=3)
    assert bb.ok
    f1, f2 = bb.families
    ratio = np.interp(f1.energies, f2.energies, f2.frequencies) / f1.frequencies
    for r in bb.resonances:
        num, den = (int(x) for x in r.detail.split("=")[1].split("/"))
        at = np.interp(r.energy, f1.energies, ratio)
        assert at == pytest.approx(num / den, abs=2e-3)
    crossings = {r.detail for r in bb.resonances}
    expected = {f"w2/w1 = {a}/{b}" for a in range(1, 4) for b in range(1, 4)
                if math.gcd(a, b) == 1 and min(ratio) < a / b < max(ratio)}
    assert crossings == expected


def test_result_protocol(families):
    p, fams = families
    f = fams[1]
    ds = f.to_xarray()
    assert ds["energy"].shape == (len(f),) and "nan" not in f.table().lower()
    o = f.orbit(10)
    assert o.ok and o.to_xarray()["period"].values == pytest.approx(f.periods[10])


# -- the command line ------------------------------------------------------------------------------


def test_cli_orbit_and_nnm(tmp_path):
    from helpers import run_cli

    ran = run_cli(["orbit", "--mode", "2", "--energy", "3", "--out", "o.nc", "--plot", "o.png"], cwd=tmp_path)
    assert ran.code == 0, ran.report()
    assert "stable" in ran.out and (tmp_path / "o.nc").stat().st_size > 0 and (tmp_path / "o.png").stat().st_size > 0
    ran = run_cli(["orbit", "--phi0", "0", "--psi0", "0", "--dphi0", "8", "--dpsi0", "0", "--period", "0.83",
                   "--rotation", "1,0"], cwd=tmp_path)
    assert ran.code == 0 and "rotation (1, 0)" in ran.out, ran.report()
    ran = run_cli(["nnm", "--mode", "1", "--resolution", "40", "--out", "fam.nc", "--plot", "fep.png", "--orbits-at", "1,4"],
                  cwd=tmp_path)
    assert ran.code == 0, ran.report()
    import xarray as xr

    with xr.open_dataset(tmp_path / "fam.nc") as ds:
        assert ds["energy"].size >= 40 and float(ds["energy"][-1]) == pytest.approx(0.7 * 9.81 * 0.8, rel=1e-9)
    ran = run_cli(["nnm", "--resolution", "30"], cwd=tmp_path)
    assert ran.code == 0 and "internal resonance w2/w1 = 3/2" in ran.out, ran.report()


def test_cli_orbit_that_does_not_converge_exits_1(tmp_path):
    from helpers import run_cli

    ran = run_cli(["orbit", "--phi0", "2.5", "--psi0", "-2", "--dphi0", "3", "--dpsi0", "-4", "--period", "0.37",
                   "--out", "bad.nc"], cwd=tmp_path)
    assert ran.code == 1 and "did not converge" in ran.err and not (tmp_path / "bad.nc").exists(), ran.report()


@pytest.mark.parametrize("argv, text", [
    (["orbit"], "needs a guess"),
    (["orbit", "--mode", "1"], "--energy"),
    (["orbit", "--mode", "3", "--energy", "1"], "--mode"),
    (["orbit", "--mode", "1", "--energy", "1", "--period", "2"], "--mode"),
    (["orbit", "--period", "1", "--rotation", "1"], "--rotation"),
    (["orbit", "--period", "1", "--rotation", "a,b"], "--rotation"),
    (["orbit", "--period", "-1"], "--period"),
    (["orbit", "--mode", "1", "--energy", "nan"], "--energy"),
    (["orbit", "--mode", "1", "--energy", "1", "--c1", "0.1"], "conservative"),
    (["nnm", "--mode", "0"], "--mode"),
    (["nnm", "--energy-max", "-1"], "--energy-max"),
    (["nnm", "--resolution", "0"], "--resolution"),
    (["nnm", "--out", "f.nc"], "--mode"),
    (["nnm", "--orbits-at", "1,2"], "--plot"),
    (["nnm", "--plot", "f.png", "--orbits-at", "1,2,3,4,5"], "--orbits-at"),
    (["nnm", "--plot", "f.png", "--orbits-at", "-1"], "--orbits-at"),
    (["nnm", "--out", "f.txt", "--mode", "1"], "--out"),
    (["nnm", "--tau1", "1"], "torques"),
    (["nnm", "--a", "sym"], "numeric"),
    (["equilibria", "--a", "sym"], "numeric"),
])
def test_cli_bad_input(argv, text, tmp_path):
    from helpers import run_cli

    ran = run_cli(argv, cwd=tmp_path)
    assert ran.code == 2, ran.report()
    assert text in ran.err and len(ran.err.strip().splitlines()) == 1, ran.report()
    assert not any(tmp_path.iterdir())


# -- continuation in alpha --------------------------------------------------------------------------


def test_alpha_continuation_ends_on_the_closed_form_and_is_symmetric():
    """Mode 2 at 3 J from alpha = 0 to 180 deg: at 90 deg it is rod 2's pendulum (closed form), and
    the frequencies at alpha and 180 deg - alpha agree (reflecting the second axis in the plane of
    the rods, with psi -> -psi, is a symmetry of the equations)."""
    from scipy.special import ellipk

    from skewpend.analysis.orbits import nnm_alpha

    p = skewpend.reference_parameters()
    alphas = np.radians(np.linspace(0, 180, 37))
    fam = nnm_alpha(p, 2, energy=3.0, alphas=alphas)
    assert fam.ok and len(fam.alphas) == 37
    k, inertia = 9.81 * 0.7 * 0.8 / 2, 0.7 * 0.8 ** 2 / 3
    T90 = 4 * ellipk(3.0 / (2 * k)) / math.sqrt(k / inertia)
    assert fam.periods[18] == pytest.approx(T90, rel=1e-9)
    assert np.allclose(fam.frequencies, fam.frequencies[::-1], rtol=1e-8)
    # at alpha = 0.6 rad it is the orbit of the energy continuation
    f2 = nnm(p, mode=2, energy_max=3.0)
    near = skewpend.Parameters(a=1, b=0.8, m1=1, m2=0.7, alpha=float(alphas[7]), g=9.81)
    w7 = nnm(near, mode=2, energy_max=3.0).frequencies[-1]
    assert fam.frequencies[7] == pytest.approx(w7, rel=1e-9)
    assert f2.frequencies[-1] > 0


def test_cli_nnm_along_alpha(tmp_path):
    from helpers import run_cli

    ran = run_cli(["nnm", "--mode", "1", "--alphas", "0:180deg:31", "--energy", "5", "--plot", "a.png", "--out", "a.nc"],
                  cwd=tmp_path)
    assert ran.code == 0 and "branch point" in ran.out, ran.report()
    for argv, text in ((["nnm", "--alphas", "0:1:3"], "--energy"),
                       (["nnm", "--alphas", "0:1:3", "--energy", "1"], "--mode"),
                       (["nnm", "--mode", "1", "--alphas", "0:1:3", "--energy", "1", "--alpha", "1"], "--alpha"),
                       (["nnm", "--mode", "1", "--alphas", "0:1:3", "--energy", "1", "--resolution", "5"], "--resolution")):
        bad = run_cli(argv, cwd=tmp_path)
        assert bad.code == 2 and text in bad.err and len(bad.err.strip().splitlines()) == 1, bad.report()


@pytest.mark.parametrize("signum, code", [(2, 130), (15, 143)])
def test_nnm_stops_on_ctrl_c_and_sigterm_leaving_nothing(signum, code, tmp_path):
    import signal

    from helpers import signal_process

    ran, seconds = signal_process(["nnm", "--mode", "2", "--resolution", "1999", "--out", "f.nc", "--plot", "f.png"],
                                  tmp_path, after=2.0, signum=signal.Signals(signum))
    assert ran.code == code, ran.report()
    assert not any("drawing" in line for line in ran.stages), ran.stages  # stopped before the run's last stage
    # a hang guard, not a speed test (the exit takes ~0.3 s; the whole run, capped at 2000 orbits, ~17 s on
    # the 2-core machine): it tells "stopped" from "ran on to the drawing" only on machines no faster
    assert seconds < 10.0
    assert ran.err.strip().splitlines()[-1] in ("skewpend: interrupted", "skewpend: terminated")
    assert list(tmp_path.iterdir()) == []
