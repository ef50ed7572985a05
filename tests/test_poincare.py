"""Poincare sections on an energy surface: where the points lie (on the section, in the
direction asked, on the energy surface, in canonical coordinates -- checked with the symbolic
derivation, not the generated code), the two ways of locating a crossing, regular orbits on
smooth closed curves against chaotic ones filling an area, the seeds, bad input, output files.

Parameters: thin rods, ``a = b = 1 m``, ``m1 = m2 = 1 kg``, ``alpha = 0.6``; the potential's
minimum is 0 J at rest; at 1 J the section phi = 0 is covered by invariant curves, at 25 J
(far above the ~8-16 J where chaos sets in) it is a chaotic sea.
"""

from __future__ import annotations

import math

import numpy as np
import pytest
import sympy as sp

from skewpend import SYMBOLS, ParameterError, Parameters, derive
from skewpend.analysis.poincare import (EnergySurface, PoincareSection, energy_minimum, parse_section, poincare,
                                        section_seeds)
from skewpend.numeric.kernels import kernel_module, parameter_vector

P = Parameters(a=1.0, b=1.0, m1=1.0, m2=1.0, g=9.81, alpha=0.6)
Q = [SYMBOLS["phi"], SYMBOLS["psi"]]
DQ = [SYMBOLS["dphi"], SYMBOLS["dpsi"]]
TWO_PI = 2.0 * math.pi
#: At rtol = atol = 1e-12 DOP853 drifts in energy by ~1e-12 per step at worst; runs here take
#: <= ~1e5 steps, and the drift of a good integrator is far below that sum: 1e-8 relative.
ENERGY_TOL = 1e-8


@pytest.fixture(scope="module")
def sym():
    """The mass matrix, the potential and the energy from derive() (independent of the generated C)."""
    eom = derive(P)
    M = [[sp.lambdify(Q, eom.mass_matrix[i, j], "numpy") for j in range(2)] for i in range(2)]

    def mass(q):  # rows of (phi, psi) -> (m, 2, 2)
        out = np.empty((q.shape[0], 2, 2))
        for i in range(2):
            for j in range(2):
                out[:, i, j] = M[i][j](q[:, 0], q[:, 1])
        return out

    pot = sp.lambdify(Q, eom.potential_energy, "numpy")
    energy = sp.lambdify(Q + DQ, eom.kinetic_energy + eom.potential_energy, "numpy")
    return {"mass": mass, "potential": lambda q: pot(q[:, 0], q[:, 1]) + 0.0 * q[:, 0],
            "energy": lambda y: energy(y[:, 0], y[:, 1], y[:, 2], y[:, 3])}


def wrapped_residue(x, value):
    """Distance of x from value + 2 pi Z [rad]."""
    return np.abs(np.remainder(x - value + math.pi, TWO_PI) - math.pi)


def check_points(sec: PoincareSection, sym, energy: float, coord: int, value: float, direction: int):
    """Every point: on the section, crossed in the direction asked, on the energy surface, with
    its canonical momentum and wrapped angle."""
    o = 1 - coord
    s = sec.states
    assert sec.n_points == s.shape[0] == sec.q.size == sec.p.size == sec.t.size == sec.orbit.size > 0
    # the section coordinate is written as the exact section level value + 2 pi j: from value
    # modulo 2 pi by rounding only (a few roundings of numbers up to |angle| + |value| + pi here
    # and in the kernel: 8 ulps)
    scale = np.maximum(np.abs(s[:, coord]) + abs(value), TWO_PI)
    assert np.all(wrapped_residue(s[:, coord], value) <= 8 * np.spacing(scale))
    speed = s[:, 2 + coord]
    if direction > 0:
        assert np.all(speed > 0)
    elif direction < 0:
        assert np.all(speed < 0)
    # on the energy surface: the symbolic energy of each state, within the integrator's drift
    e_sym = sym["energy"](s)
    assert np.all(np.abs(e_sym - energy) <= ENERGY_TOL * max(1.0, energy))
    # energy_error is E(state) - energy (the same quantity from the generated energy: rounding only)
    np.testing.assert_allclose(sec.energy_error, e_sym - energy, rtol=0, atol=1e-12 * max(1.0, energy))
    # canonical coordinates of the other joint: p = (M(q) q')_other, q wrapped to [-pi, pi)
    p = np.einsum("ij,ij->i", sym["mass"](s[:, :2])[:, o, :], s[:, 2:])
    np.testing.assert_allclose(sec.p, p, rtol=1e-12, atol=1e-12)
    assert np.all((sec.q >= -math.pi) & (sec.q < math.pi))
    assert np.all(wrapped_residue(sec.q - s[:, o], 0.0) <= 1e-12 * np.maximum(1.0, np.abs(s[:, o])))
    assert np.array_equal(sec.dq, s[:, 2 + o])
    # points in time order within each orbit, orbits as counted
    for k in range(sec.seeds.shape[0]):
        assert np.all(np.diff(sec.t[sec.orbit == k]) > 0)
    assert np.array_equal(np.bincount(sec.orbit, minlength=sec.seeds.shape[0]), sec.crossings)


# -- 1. dense output and Henon's trick ------------------------------------------------------------------------------
@pytest.mark.parametrize("energy, n_orbits", [(1.0, 3), (25.0, 2)])
def test_dense_and_henon_locate_the_same_points(sym, energy, n_orbits):
    """Both use the same DOP853 steps (the location never feeds back into the integration), so
    they find the same crossings; they differ by the interpolant's error (~ tol |y| ~ 1e-11 in
    the section coordinate, i.e. |dt| ~ 1e-11 / |q_c'|) and by Hénon's RK4 error (substeps of
    <= 5e-4 rad in the coordinate: ~1e-13 relative where |q_c'| is not small).  States are
    compared where |q_c'| > 0.3, where the 1/|q_c'| amplification is bounded; 1e-7 is generous."""
    kw = dict(n_orbits=n_orbits, n_crossings=100, workers=1)
    dense = poincare(P, energy, locate="dense", **kw)
    henon = poincare(P, energy, locate="henon", **kw)
    assert dense.n_points == henon.n_points == n_orbits * 100
    assert np.array_equal(dense.orbit, henon.orbit) and np.array_equal(dense.seeds, henon.seeds)
    assert dense.settings["locate"] == "dense" and henon.settings["locate"] == "henon"
    speed = dense.states[:, 2]
    # the offset in time times the crossing speed: the offset in the section coordinate
    assert np.max(np.abs(dense.t - henon.t) * np.abs(speed)) <= 1e-9
    fast = np.abs(speed) > 0.3
    assert fast.mean() > 0.5
    assert np.max(np.abs(dense.states[fast] - henon.states[fast])) <= 1e-7
    for sec in (dense, henon):
        check_points(sec, sym, energy, 0, 0.0, +1)


# -- 2. on the section, in the direction, on the energy surface -----------------------------------------------------
@pytest.mark.parametrize("energy, section, coord, value, direction", [
    (1.0, "phi=0", 0, 0.0, +1),
    (25.0, "psi=0.5", 1, 0.5, -1),
    (25.0, "psi=4.0", 1, 4.0, 0),  # beyond pi: taken modulo 2 pi
    (25.0, "phi=-30deg", 0, -math.pi / 6, +1),
])
def test_points_lie_on_the_section_and_the_energy_surface(sym, energy, section, coord, value, direction):
    sec = poincare(P, energy, section=section, direction=direction, n_orbits=3, n_crossings=60, workers=1)
    assert sec.coord_names[0] == section[:3] and sec.settings["value"] == pytest.approx(value, rel=1e-15)
    assert np.all(sec.status == 0) and np.all(sec.crossings == 60) and sec.unreachable.shape == (0, 2)
    check_points(sec, sym, energy, coord, value, direction)
    if direction == 0:
        # both directions occur (the psi rotations at 25 J cross both ways)
        speed = sec.states[:, 2 + coord]
        assert np.any(speed > 0) and np.any(speed < 0)


# -- 3. regular orbits on smooth closed curves, chaotic ones fill an area -------------------------------------------
def curve_residual(q, p, order=8):
    """RMS residual, relative to the mean radius, of a Fourier series of the given order fitted
    (least squares) to the radius against the polar angle about the centroid of the points,
    each coordinate scaled by its spread.  A smooth closed curve around its centroid has an
    analytic r(theta): the residual falls geometrically with the order (<= 1e-4 at order 8 for
    the curves here); points filling an area leave a residual of order the radius itself."""
    x = (q - q.mean()) / q.std()
    y = (p - p.mean()) / p.std()
    theta, r = np.arctan2(y, x), np.hypot(x, y)
    A = np.column_stack([np.ones_like(theta)] + [f(k * theta) for k in range(1, order + 1) for f in (np.cos, np.sin)])
    coef, *_ = np.linalg.lstsq(A, r, rcond=None)
    return float(np.sqrt(np.mean((A @ coef - r) ** 2)) / r.mean())


def test_regular_orbits_lie_on_smooth_curves_chaotic_ones_fill_an_area():
    # two orbits around the two centres of the section phi = 0 at 1 J (q = psi, p = p_psi)
    regular = poincare(P, 1.0, seeds=[[0.0, 0.65], [0.0, -0.45]], n_crossings=300, workers=1)
    chaotic = poincare(P, 25.0, seeds=[[0.5, 0.0], [-1.0, 1.0]], n_crossings=300, workers=1)
    reg = [curve_residual(*regular.orbit_points(k)) for k in range(2)]
    cha = [curve_residual(*chaotic.orbit_points(k)) for k in range(2)]
    assert max(reg) <= 1e-4, reg
    assert min(cha) >= 0.1, cha
    assert min(cha) >= 1e3 * max(reg)
    # and the regular curves are closed: every point returns within a small part of the curve's
    # extent -- the 300 points cover the polar angle with no gap wider than 30 degrees
    for k in range(2):
        q, p = regular.orbit_points(k)
        theta = np.sort(np.arctan2((p - p.mean()) / p.std(), (q - q.mean()) / q.std()))
        gaps = np.diff(np.concatenate([theta, [theta[0] + TWO_PI]]))
        assert gaps.max() < math.radians(30)


# -- 5. the directions ----------------------------------------------------------------------------------------------
def test_direction_zero_counts_both_crossings(sym):
    """Same seeds, same start (direction 0 starts like +1), same steps: the increasing crossings
    of the both-ways run are exactly those of the +1 run, and alternate with the decreasing ones
    (at 1 J psi oscillates: it crosses 0 up and down in turn) -- twice the points per time."""
    seeds = [[0.1, 0.2], [-0.2, 0.0]]
    up = poincare(P, 1.0, section="psi=0", direction=+1, seeds=seeds, n_crossings=40, workers=1)
    both = poincare(P, 1.0, section="psi=0", direction=0, seeds=seeds, n_crossings=80, workers=1)
    down = poincare(P, 1.0, section="psi=0", direction=-1, seeds=seeds, n_crossings=40, workers=1)
    check_points(down, sym, 1.0, 1, 0.0, -1)
    check_points(both, sym, 1.0, 1, 0.0, 0)
    for k in range(2):
        b = both.orbit == k
        speed = both.states[b, 3]
        signs = np.sign(speed)
        assert np.all(signs[1:] == -signs[:-1])  # alternating
        ups = both.states[b][speed > 0]
        assert np.array_equal(ups, up.states[up.orbit == k])
        assert np.array_equal(both.t[b][speed > 0], up.t[up.orbit == k])
        # 80 crossings both ways took as long as 40 one way (to within one crossing interval)
        t_up, t_both = up.t[up.orbit == k][-1], both.t[b][-1]
        assert abs(t_both - t_up) <= np.max(np.diff(both.t[b]))
    # a decreasing start: the seed's section speed is negative
    assert np.all(down.states[:, 3] < 0) and not np.array_equal(down.t, up.t)


# -- 6. seeds -------------------------------------------------------------------------------------------------------
def test_unreachable_seeds_are_reported_and_the_rest_used(sym):
    energy = 1.0
    given = np.array([[0.0, 0.6], [0.0, 100.0], [3.0, 0.0], [0.0, -0.45], [0.3, 0.8]])
    # reachable on phi = 0 at E exactly when E - Pi(0, psi) - p^2 / (2 M_psipsi) >= 0 (symbolic)
    q = np.column_stack([np.zeros(len(given)), given[:, 0]])
    margin = energy - sym["potential"](q) - given[:, 1] ** 2 / (2.0 * sym["mass"](q)[:, 1, 1])
    ok = margin >= 0
    assert ok.tolist() == [True, False, False, True, False]  # (0.3, 0.8) is just outside
    sec = poincare(P, energy, seeds=given, n_crossings=5, workers=1)
    assert np.array_equal(sec.seeds, given[ok]) and np.array_equal(sec.unreachable, given[~ok])
    assert sec.stats["unreachable"] == 3 and sec.stats["orbits"] == 2 and sec.settings["seeds"] == "given"
    assert np.array_equal(sec.crossings, [5, 5])
    with pytest.raises(ParameterError, match="none of the 2 seeds can lie on the energy surface"):
        poincare(P, energy, seeds=given[~ok][:2], n_crossings=5)


def test_energy_surface_and_default_seeds(sym):
    kernel, p = kernel_module(P, chaos=True), parameter_vector(P)
    e_min, where = energy_minimum(kernel, p)
    # the potential's minimum is 0 at rest; Nelder-Mead to fatol 1e-15 on a quadratic bowl with
    # curvature ~5 J/rad^2 locates it to ~sqrt(1e-15 / 5) ~ 1e-8 rad
    assert abs(e_min) <= 1e-12 and np.max(np.abs(where)) <= 1e-6
    u = np.linspace(-math.pi, math.pi, 201)
    grid = np.array(np.meshgrid(u, u, indexing="ij")).reshape(2, -1).T
    assert sym["potential"](grid).min() >= e_min - 1e-12
    surface = EnergySurface(kernel, p, 2.0, 1, 0.3, e_min)  # the section psi = 0.3 at 2 J
    seeds = section_seeds(surface, 20)
    assert seeds.shape == (20, 2) and np.array_equal(seeds, section_seeds(surface, 20))  # deterministic
    assert np.all(surface.reach(seeds[:, 0], seeds[:, 1]) > 0)
    for direction in (+1, -1):
        y = surface.states(seeds[:, 0], seeds[:, 1], direction)
        assert np.all(y[:, 1] == 0.3) and np.array_equal(y[:, 0], seeds[:, 0])
        assert np.all(np.sign(y[:, 3]) == direction)
        # on the energy surface, with the seed's canonical momentum (symbolic M and energy)
        np.testing.assert_allclose(sym["energy"](y), 2.0, rtol=1e-12)
        mom = np.einsum("ij,ij->i", sym["mass"](y[:, :2])[:, 0, :], y[:, 2:])
        np.testing.assert_allclose(mom, seeds[:, 1], rtol=1e-12, atol=1e-12)
    # the reach margin is the symbolic one
    q = np.column_stack([seeds[:, 0], np.full(20, 0.3)])
    margin = 2.0 - sym["potential"](q) - seeds[:, 1] ** 2 / (2.0 * sym["mass"](q)[:, 0, 0])
    np.testing.assert_allclose(surface.reach(seeds[:, 0], seeds[:, 1]), margin, rtol=1e-12, atol=1e-12)


def test_parse_section():
    assert parse_section("phi=0") == ("phi", 0.0)
    assert parse_section(" psi = 30deg ") == ("psi", pytest.approx(math.pi / 6, rel=1e-15))
    assert parse_section("psi=-1.5") == ("psi", -1.5)


def test_workers_do_not_change_the_points():
    kw = dict(n_orbits=4, n_crossings=30)
    a = poincare(P, 25.0, workers=1, **kw)
    b = poincare(P, 25.0, workers=2, **kw)
    assert a.states.tobytes() == b.states.tobytes() and a.t.tobytes() == b.t.tobytes()


# -- 7. bad input ---------------------------------------------------------------------------------------------------
@pytest.mark.parametrize("params, energy, kwargs, match", [
    (P, -1.0, {}, "below the minimum"),
    (P, 1.0, dict(section="psi=3.14"), "never reaches the section 'psi=3.14'"),
    (P, 1.0, dict(section="phi=180deg"), "never reaches"),
    (P, 1.0, dict(section="phi=pi"), "never reaches"),  # pi is a section value; at 1 J out of reach
    (P.replace(c1=0.1), 5.0, {}, "conservative.*c1 = 0.1"),
    (P.replace(c2=0.1), 5.0, {}, "conservative.*c2 = 0.1"),
    (P.replace(tau2=0.5), 5.0, {}, "conservative.*tau2 = 0.5"),
    (P, 5.0, dict(section="theta=0"), "section must be 'phi=VALUE' or 'psi=VALUE'"),
    (P, 5.0, dict(section="phi=abc"), "section phi"),
    (P, 5.0, dict(section="phi=sym"), "multiple of pi"),
    (P, 5.0, dict(section=0), "section must be a string"),
    (P, 5.0, dict(direction=2), "direction"),
    (P, 5.0, dict(direction=True), "direction"),
    (P, 5.0, dict(locate="foo"), "locate must be one of dense, henon"),
    (P, math.nan, {}, "energy must be a finite number"),
    (P, "hot", {}, "energy must be a number"),
    (P, 5.0, dict(n_orbits=0), "n_orbits"),
    (P, 5.0, dict(n_crossings=0), "n_crossings"),
    (P, 5.0, dict(seeds=[[0.0, math.nan]]), "seeds"),
    (P, 5.0, dict(seeds=[]), "seeds"),
    (P, 5.0, dict(t_max=-1.0), "t_max"),
    (Parameters(), 5.0, {}, "numeric values"),
])
def test_bad_input_is_refused(params, energy, kwargs, match):
    kwargs = {"n_orbits": 2, "n_crossings": 3, **kwargs}
    with pytest.raises(ParameterError, match=match):
        poincare(params, energy, **kwargs)


# -- 8. output files ------------------------------------------------------------------------------------------------
@pytest.fixture(scope="module")
def small_section():
    return poincare(P, 5.0, section="psi=0", n_orbits=2, n_crossings=10, workers=1)


def test_csv_reads_back(small_section, tmp_path):
    sec = small_section
    csv = tmp_path / "section.csv"
    sec.to_csv(csv)
    assert csv.read_text().splitlines()[0] == "orbit,t,phi,p_phi,dphi,energy_error"
    table = np.genfromtxt(csv, delimiter=",", names=True)
    assert table.size == sec.n_points == 20 and np.array_equal(table["orbit"], sec.orbit)
    for name, values in (("t", sec.t), ("phi", sec.q), ("p_phi", sec.p), ("dphi", sec.dq),
                         ("energy_error", sec.energy_error)):
        assert np.array_equal(table[name], values), name  # %.17g round-trips doubles exactly
    assert [p.name for p in tmp_path.iterdir()] == ["section.csv"]  # no temporaries left


def test_xarray_dataset(small_section):
    pytest.importorskip("xarray")
    sec = small_section
    ds = sec.to_xarray()
    assert np.array_equal(ds["phi"].values, sec.q) and np.array_equal(ds["p_phi"].values, sec.p)
    assert np.array_equal(ds["orbit_index"].values, sec.orbit) and ds["crossings"].values.tolist() == [10, 10]
    assert ds["p_phi"].attrs["units"] == "J s" and "psi=0" in ds.attrs["settings"]


def test_netcdf_reads_back(small_section, tmp_path):
    xr = pytest.importorskip("xarray")
    pytest.importorskip("netCDF4")
    sec = small_section
    nc = tmp_path / "section.nc"
    sec.to_netcdf(nc)
    with xr.open_dataset(nc) as ds:
        assert np.array_equal(ds["phi"].values, sec.q) and np.array_equal(ds["p_phi"].values, sec.p)
        assert np.array_equal(ds["t"].values, sec.t) and np.array_equal(ds["orbit_index"].values, sec.orbit)
        assert np.array_equal(ds["seed_q"].values, sec.seeds[:, 0]) and ds["crossings"].values.tolist() == [10, 10]
        assert ds["p_phi"].attrs["units"] == "J s" and "psi=0" in ds.attrs["settings"]
    assert [p.name for p in tmp_path.iterdir()] == ["section.nc"]  # no temporaries left


def test_mass_matrices_are_the_momenta_of_unit_speeds_in_one_call():
    """``mass_matrices`` (one compiled call over all rows) gives exactly -- bit for bit -- the matrices
    built column by column from the generated momenta p = M q' at q' = e_j, and M is symmetric
    positive definite at every angle (a kinetic energy)."""
    from skewpend.analysis.poincare import mass_matrices

    params = Parameters(a=1.0, b=0.8, m1=1.0, m2=0.7, alpha=0.6, g=9.81)
    kernel, p = kernel_module(params), parameter_vector(params)
    q = np.random.default_rng(11).uniform(-4.0, 4.0, (200, 2))
    M = mass_matrices(kernel, p, q)
    buf = np.empty(2)
    for i in range(len(q)):
        for j in range(2):
            y = np.array([q[i, 0], q[i, 1], float(j == 0), float(j == 1), 0.0])
            kernel.momenta(y, p, buf)
            assert np.array_equal(M[i, :, j], buf)
    np.testing.assert_allclose(M, M.transpose(0, 2, 1), rtol=1e-14, atol=1e-15)
    assert np.all(np.linalg.eigvalsh(M) > 0)
