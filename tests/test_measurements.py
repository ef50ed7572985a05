"""skewpend.Measurements: measured motion in skewpend's coordinates (issue 27, the data side).

The two real rigs of ``data/`` are read once per module.  The sign conventions are checked three ways:
against the authors' own equations (the Kaheman ODE's linearisation, the DFKI lab's mass matrix and
potential), against the data (the free swing's rest and frequencies, the driven rig's torques), and by
round trips of the one conversion.
"""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest

import skewpend
from skewpend.analysis.measurements import (
    GAP_FACTOR, MIN_SAMPLES, SKEWPEND, Convention, Measurements, Piece, convert, convert_back,
)
from skewpend.errors import ParameterError

DATA = Path(__file__).resolve().parent.parent / "data"
KAHEMAN = DATA / "kaheman2023"
DFKI = DATA / "dfki-design-C.0"

#: The authors' identified values [m1 m2 a1 a2 L1 I1 I2 k1 k2 g] (EstimatedParameters_DoublePendulum.mat).
KAHEMAN_VALUES = "EstimatedParameters_DoublePendulum.mat"


@pytest.fixture(scope="module")
def kaheman():
    return Measurements.from_kaheman(KAHEMAN)


@pytest.fixture(scope="module")
def dfki():
    return Measurements.from_dfki([DFKI / "trajectory_00.csv", DFKI / "trajectory_12.csv"])


def kaheman_values():
    from scipy.io import loadmat

    return [float(x) for x in loadmat(str(KAHEMAN / KAHEMAN_VALUES))["EstimatedParameters"].ravel()]


def kaheman_parameters() -> skewpend.Parameters:
    """The authors' model in skewpend's terms: centres of mass on the rods, inertias about k."""
    m1, m2, a1, a2, L1, I1, I2, k1, k2, g = kaheman_values()
    return skewpend.Parameters(a=L1, b=2 * a2, m1=m1, m2=m2, alpha=0, g=g, c1=k1, c2=k2, com1=(0, a1, 0),
                               com2=(0, a2, 0), inertia1=((I1, 0, 0), (0, 0, 0), (0, 0, I1)),
                               inertia2=((I2, 0, 0), (0, 0, 0), (0, 0, I2)))


def dfki_model(name="h1.0"):
    import yaml

    return yaml.safe_load((DFKI / f"model_{name}_parameters.yml").read_text())


# -- the one conversion ---------------------------------------------------------------------------------
CONVENTIONS = [Convention(), Convention(second="absolute"), Convention(zero="upright"),
               Convention(second="absolute", zero="upright"), Convention(sign=(-1, 1)), Convention(sign=(1, -1)),
               Convention(unit="deg", second="absolute", zero="upright", sign=(-1, -1))]


@pytest.mark.parametrize("convention", CONVENTIONS, ids=lambda c: c.describe())
def test_conversion_round_trips(convention):
    rng = np.random.default_rng(1)
    q, dq, u = rng.normal(size=(50, 2)), rng.normal(size=(50, 2)), rng.normal(size=(50, 2))
    for a, b in zip(convert_back(*convert(q, dq, u, convention=convention), convention=convention), (q, dq, u)):
        np.testing.assert_allclose(a, b, rtol=0, atol=1e-13)
    for a, b in zip(convert(*convert_back(q, dq, u, convention=convention), convention=convention), (q, dq, u)):
        np.testing.assert_allclose(a, b, rtol=0, atol=1e-13)
    assert convert(q, convention=convention)[1:] == (None, None)


def test_conversion_values():
    upright_absolute = Convention(second="absolute", zero="upright")
    q, dq, _ = convert([[math.pi + 0.1, math.pi + 0.3]], [[1.0, 3.0]], convention=upright_absolute)
    np.testing.assert_allclose(q, [[0.1, 0.2]], atol=1e-15)
    np.testing.assert_allclose(dq, [[1.0, 2.0]])
    q, dq, u = convert([[10.0, -20.0]], [[1.0, 2.0]], [[0.5, 0.25]], convention=Convention(unit="deg", sign=(-1, 1)))
    np.testing.assert_allclose(q, [[-math.radians(10), math.radians(-20)]])
    np.testing.assert_allclose(u, [[-0.5, 0.25]])  # a torque takes its angle's sign; N m always
    assert upright_absolute.describe() == "phi = theta1 - pi, psi = theta2 - theta1"
    assert SKEWPEND.describe() == "phi = theta1, psi = theta2"


@pytest.mark.parametrize("bad", [dict(second="abs"), dict(zero="down"), dict(sign=(1, 2)), dict(sign=(1,)),
                                 dict(unit="grad"), dict(sign=(1.5, 1))])
def test_convention_refuses(bad):
    with pytest.raises(ParameterError, match="Convention"):
        Convention(**bad)


# -- the free swing (Kaheman et al. 2023) ------------------------------------------------------------------
def test_kaheman_pieces(kaheman):
    assert len(kaheman) == 30 and kaheman.metadata["format"] == "kaheman"
    fit, held = kaheman.split("validation")
    assert len(fit) == 26 and len(held) == 4
    assert all(len(p) == 2667 and p.group == "fit" for p in fit)
    assert [len(p) for p in held] == [2667, 2667, 2667, 2658]  # the file's last piece is shorter
    for p in kaheman:
        assert p.dq is not None and p.u is None and p.q.shape == (len(p), 2)
        assert abs(p.dt - 0.001) < 1e-9 and np.ptp(np.diff(p.t)) < 1e-9
    assert kaheman.metadata["conversion"] == "phi = theta1 - pi, psi = theta2 - theta1"
    assert kaheman.metadata["actions"] == ()  # nothing needed fixing
    assert [len(Measurements.from_kaheman(KAHEMAN / "DoublePendulumDataForParameterEstimation.mat", which=w))
            for w in ("validation",)] == [4]


def test_kaheman_rests_hanging(kaheman):
    """After conversion each piece swings about phi = psi = 0 (the hanging rest): its mean is within
    0.15 rad of it (a few incomplete periods per piece; 0.035 rad for the last ten, smaller swings), far
    from pi; over all 80 s within 0.01 rad."""
    means = np.array([p.q.mean(axis=0) for p in kaheman])
    assert np.abs(means).max() < 0.15 and np.abs(means[-10:]).max() < 0.035, means
    assert np.abs(np.concatenate([p.q for p in kaheman]).mean(axis=0)).max() < 0.01
    # speeds are the rates of change of the converted angles
    p = kaheman[-1]
    for k in range(2):
        assert np.corrcoef(np.gradient(p.q[:, k], p.t), p.dq[:, k])[0, 1] > 0.99


def authors_acceleration(y, m1, m2, a1, a2, L1, I1, I2, k1, k2, g):
    """DoublePendulumODE_Mounted.m (data/kaheman2023), transcribed: y = [th1, th2, dth1, dth2]."""
    s, c = np.sin, np.cos
    den = (I1 * I2 + L1**2 * a2**2 * m2**2 + I2 * L1**2 * m2 + I2 * a1**2 * m1 + I1 * a2**2 * m2
           - L1**2 * a2**2 * m2**2 * c(y[0] - y[1])**2 + a1**2 * a2**2 * m1 * m2)
    d3 = -(I2 * y[2] * k1 + I2 * y[2] * k2 - I2 * y[3] * k2 + a2**2 * y[2] * k1 * m2 + a2**2 * y[2] * k2 * m2
           - a2**2 * y[3] * k2 * m2 + L1 * a2**3 * y[3]**2 * m2**2 * s(y[0] - y[1])
           - (L1 * a2**2 * g * m2**2 * s(y[0])) / 2 - I2 * L1 * g * m2 * s(y[0])
           - (L1 * a2**2 * g * m2**2 * s(y[0] - 2 * y[1])) / 2 - I2 * a1 * g * m1 * s(y[0])
           + (L1**2 * a2**2 * y[2]**2 * m2**2 * s(2 * y[0] - 2 * y[1])) / 2
           + L1 * a2 * y[2] * k2 * m2 * c(y[0] - y[1]) - L1 * a2 * y[3] * k2 * m2 * c(y[0] - y[1])
           + I2 * L1 * a2 * y[3]**2 * m2 * s(y[0] - y[1]) - a1 * a2**2 * g * m1 * m2 * s(y[0])) / den
    d4 = (I1 * y[2] * k2 - I1 * y[3] * k2 + L1**2 * y[2] * k2 * m2 - L1**2 * y[3] * k2 * m2 + a1**2 * y[2] * k2 * m1
          - a1**2 * y[3] * k2 * m1 + L1**3 * a2 * y[2]**2 * m2**2 * s(y[0] - y[1]) + L1**2 * a2 * g * m2**2 * s(y[1])
          + I1 * a2 * g * m2 * s(y[1]) + (L1**2 * a2**2 * y[3]**2 * m2**2 * s(2 * y[0] - 2 * y[1])) / 2
          + L1 * a2 * y[2] * k1 * m2 * c(y[0] - y[1]) + L1 * a2 * y[2] * k2 * m2 * c(y[0] - y[1])
          - L1 * a2 * y[3] * k2 * m2 * c(y[0] - y[1]) - L1**2 * a2 * g * m2**2 * c(y[0] - y[1]) * s(y[0])
          + I1 * L1 * a2 * y[2]**2 * m2 * s(y[0] - y[1]) + a1**2 * a2 * g * m1 * m2 * s(y[1])
          + L1 * a1**2 * a2 * y[2]**2 * m1 * m2 * s(y[0] - y[1]) - L1 * a1 * a2 * g * m1 * m2 * c(y[0] - y[1]) * s(y[0])
          ) / den
    return np.array([d3, d4])


def authors_linearisation(relative_sign=1.0):
    """d(ddphi, ddpsi)/d(phi, psi, dphi, dpsi) at hanging, of the authors' ODE seen through the
    conversion phi = theta1 - pi, psi = relative_sign * (theta2 - theta1)."""
    values = kaheman_values()

    def f(x):  # x = (phi, psi, dphi, dpsi) -> (ddphi, ddpsi)
        phi, psi, dphi, dpsi = x
        th = [math.pi + phi, math.pi + phi + relative_sign * psi, dphi, dphi + relative_sign * dpsi]
        a = authors_acceleration(th, *values)
        return np.array([a[0], relative_sign * (a[1] - a[0])])

    h = 1e-6
    return np.column_stack([(f(h * e) - f(-h * e)) / (2 * h) for e in np.eye(4)])


def test_kaheman_convention_matches_the_authors_equations():
    """The authors' ODE has theta = 0 upright (its gravity terms push away from 0: +g sin(theta1)
    in theta1''), absolute angles (cos(theta1 - theta2) couples them) in one sense.  Through
    phi = theta1 - pi, psi = theta2 - theta1 its linearisation at hanging is skewpend's
    -M0^-1 [K0 C0] with the authors' parameters, to rounding; psi = theta1 - theta2 would not be."""
    from skewpend.analysis.modes import linear_matrices

    values = kaheman_values()
    # leaning off theta = 0, rod 1 falls further (0 is the top); off theta = pi it comes back
    assert authors_acceleration([1e-3, 1e-3, 0, 0], *values)[0] > 0
    assert authors_acceleration([math.pi + 1e-3, math.pi + 1e-3, 0, 0], *values)[0] < 0
    M0, C0, K0 = linear_matrices(kaheman_parameters())
    ours = -np.linalg.solve(M0, np.hstack([K0, C0]))
    theirs = authors_linearisation()
    np.testing.assert_allclose(theirs, ours, rtol=1e-6, atol=1e-6 * np.abs(ours).max())
    assert not np.allclose(authors_linearisation(relative_sign=-1.0), ours, rtol=1e-2)


def dominant_frequency(x: np.ndarray, dt: float) -> float:
    """The highest peak of the Hann-windowed spectrum, zero-padded 64 times [Hz]."""
    n = len(x)
    spectrum = np.abs(np.fft.rfft((x - x.mean()) * np.hanning(n), 64 * n))
    return float(np.fft.rfftfreq(64 * n, dt)[spectrum.argmax()])


def two_modes(t, A, w, ph, c, B, w2, ph2):
    return A * np.cos(w * t + ph) + c + B * np.cos(w2 * t + ph2)


def test_kaheman_frequencies_match_the_authors_model(kaheman):
    """The last twelve pieces swing by 0.1 to 0.2 rad: skewpend's hanging modes with the authors'
    parameters (0.909 and 2.013 Hz) are their measured frequencies.  The spectrum's peak (mode 1,
    0.902..0.908 Hz on the held-out pieces) within 1 %; a least-squares fit of two sinusoids per piece
    (0.905 Hz; mode 2, weaker, 2.00 Hz as the median over the pieces) within 1 %."""
    from scipy.optimize import curve_fit

    modes = skewpend.normal_modes(kaheman_parameters())
    f1, f2 = (float(w) / (2 * math.pi) for w in modes.frequencies)
    assert abs(f1 - 0.909) < 1e-3 and abs(f2 - 2.013) < 1e-3
    for p in kaheman.select(group="validation"):
        assert abs(dominant_frequency(p.q[:, 0], p.dt) / f1 - 1) < 0.01
    fitted = []
    for p in kaheman.select(list(range(18, 30))):
        phi, t = p.q[:, 0], p.t - p.t[0]
        fit, _ = curve_fit(two_modes, t, phi, p0=[1.4 * phi.std(), 2 * math.pi * f1, 0, 0, 0.01, 2 * math.pi * f2, 0])
        fitted.append(np.abs(fit[[1, 5]]) / (2 * math.pi))
    measured = np.median(fitted, axis=0)
    assert abs(measured[0] / f1 - 1) < 0.01 and abs(measured[1] / f2 - 1) < 0.01, (measured, f1, f2)


# -- the driven rig (DFKI design C.0) ---------------------------------------------------------------------
def test_dfki_pieces(dfki):
    import csv

    assert dfki.names == ("trajectory_00", "trajectory_12") and dfki.has_torques and dfki.has_velocities
    with open(DFKI / "trajectory_12.csv") as fh:
        header = next(csv.reader(fh))
    raw = np.loadtxt(DFKI / "trajectory_12.csv", delimiter=",", skiprows=1)
    p = dfki["trajectory_12"]
    np.testing.assert_array_equal(p.t, raw[:, header.index("time")])  # measured, uneven steps kept
    steps = np.diff(p.t)
    assert steps.max() > 3 * steps.min() and steps.max() < GAP_FACTOR * np.median(steps)
    for k, name in enumerate(("1", "2")):
        np.testing.assert_array_equal(p.q[:, k], raw[:, header.index(f"pos_meas{name}")])
        np.testing.assert_array_equal(p.u[:, k], raw[:, header.index(f"tau_meas{name}")])
    filtered = Measurements.from_dfki(DFKI / "trajectory_00.csv", filtered=True)
    assert filtered.metadata["filtered"] is True and len(filtered) == 1
    assert len(Measurements.from_dfki(DFKI)) == 9  # a folder: every trajectory_*.csv in it (all nine runs)
    assert dfki.metadata["actions"] == ()


def test_dfki_convention_matches_the_lab_model():
    """The lab's q1, q2 are skewpend's phi, psi: at alpha = 0 skewpend's potential is the lab's
    E_pot (dynamics.rst) plus a constant at any angles, and its M0, K0 at hanging are the lab's
    M(0) and -dG/dq (the lab's I1, I2 are about the joint axes; skewpend's about the centres of mass)."""
    from skewpend.analysis.equilibria import potential_on_arrays
    from skewpend.analysis.modes import linear_matrices

    lab = dfki_model("h1.0")
    m1, m2, l1, l2, r1, r2, I1, I2, g = (lab[k] for k in ("m1", "m2", "l1", "l2", "r1", "r2", "I1", "I2", "g"))
    J1, J2 = I1 - m1 * r1**2, I2 - m2 * r2**2
    assert J1 > 0 and J2 > 0
    params = skewpend.Parameters(a=l1, b=l2, m1=m1, m2=m2, alpha=0, g=g, com1=(0, r1, 0), com2=(0, r2, 0),
                                 inertia1=((J1, 0, 0), (0, 0, 0), (0, 0, J1)),
                                 inertia2=((J2, 0, 0), (0, 0, 0), (0, 0, J2)))
    rng = np.random.default_rng(2)
    q1, q2 = rng.uniform(-math.pi, math.pi, (2, 40))
    e_pot = -m1 * g * r1 * np.cos(q1) - m2 * g * (l1 * np.cos(q1) + r2 * np.cos(q1 + q2))
    V = potential_on_arrays(params)(q1, q2)
    np.testing.assert_allclose(V - e_pot, (V - e_pot)[0], atol=1e-12)
    M0, C0, K0 = linear_matrices(params)
    M_lab = np.array([[I1 + I2 + l1**2 * m2 + 2 * l1 * m2 * r2, I2 + l1 * m2 * r2], [I2 + l1 * m2 * r2, I2]])
    K_lab = g * np.array([[m1 * r1 + m2 * (l1 + r2), m2 * r2], [m2 * r2, m2 * r2]])  # -dG/dq at 0
    np.testing.assert_allclose(M0, M_lab, rtol=1e-12)
    np.testing.assert_allclose(K0, K_lab, rtol=1e-12)


def lab_inverse_dynamics(p: Piece, lab, sign=1.0):
    """The lab's torques (dynamics.rst, with rotor inertia and Coulomb friction) along the measured
    angles, low-passed at 8 Hz on a uniform 2 ms grid; with ``sign = -1`` the angles are mirrored."""
    from scipy.signal import butter, filtfilt

    t = np.arange(p.t[0], p.t[-1], 0.002)
    b, a = butter(4, 8 / 250)

    def smooth(x):
        return filtfilt(b, a, np.interp(t, p.t, x))

    q = sign * np.column_stack([smooth(p.q[:, 0]), smooth(p.q[:, 1])])
    v = np.gradient(q, t, axis=0)
    acc = np.gradient(v, t, axis=0)
    m1, m2, l1, r1, r2, I1, I2, Ir, gr, b1, b2, cf1, cf2, g = (
        lab[k] for k in "m1 m2 l1 r1 r2 I1 I2 Ir gr b1 b2 cf1 cf2 g".split())
    c2, s2 = np.cos(q[:, 1]), np.sin(q[:, 1])
    M11 = I1 + I2 + l1**2 * m2 + 2 * l1 * m2 * r2 * c2 + gr**2 * Ir + Ir
    M12 = I2 + l1 * m2 * r2 * c2 - gr * Ir
    M22 = I2 + gr**2 * Ir
    C1 = -2 * v[:, 1] * l1 * m2 * r2 * s2 * v[:, 0] - v[:, 1] ** 2 * l1 * m2 * r2 * s2
    C2 = v[:, 0] ** 2 * l1 * m2 * r2 * s2
    G1 = -g * m1 * r1 * np.sin(q[:, 0]) - g * m2 * (l1 * np.sin(q[:, 0]) + r2 * np.sin(q[:, 0] + q[:, 1]))
    G2 = -g * m2 * r2 * np.sin(q[:, 0] + q[:, 1])
    u1 = M11 * acc[:, 0] + M12 * acc[:, 1] + C1 - G1 + b1 * v[:, 0] + cf1 * np.arctan(100 * v[:, 0])
    u2 = M12 * acc[:, 0] + M22 * acc[:, 1] + C2 - G2 + b2 * v[:, 1] + cf2 * np.arctan(100 * v[:, 1])
    return np.column_stack([u1, u2]), np.column_stack([smooth(p.u[:, 0]), smooth(p.u[:, 1])])


def test_dfki_torques_act_in_the_sense_of_the_angles(dfki):
    """The measured motor torques are the lab's model's torques along the measured motion in
    skewpend's coordinates (correlation 0.90 and 0.99 on trajectory_12, which swings rod 1 to the
    top); mirrored angles with the same torques anticorrelate: the torque sign is the angle's."""
    lab = dfki_model("h1.0")
    model, measured = lab_inverse_dynamics(dfki["trajectory_12"], lab)
    r = [np.corrcoef(model[:, k], measured[:, k])[0, 1] for k in range(2)]
    assert r[0] > 0.85 and r[1] > 0.95, r
    model, measured = lab_inverse_dynamics(dfki["trajectory_12"], lab, sign=-1.0)
    assert all(np.corrcoef(model[:, k], measured[:, k])[0, 1] < -0.85 for k in range(2))


def dfki_raw(name="trajectory_00"):
    import csv

    with open(DFKI / f"{name}.csv") as fh:
        header = next(csv.reader(fh))
    raw = np.loadtxt(DFKI / f"{name}.csv", delimiter=",", skiprows=1)
    col = {h: raw[:, i] for i, h in enumerate(header)}
    return {"t": col["time"], "q": np.column_stack([col["pos_meas1"], col["pos_meas2"]]),
            "dq": np.column_stack([col["vel_meas1"], col["vel_meas2"]]),
            "u": np.column_stack([col["tau_meas1"], col["tau_meas2"]]), "name": name}


def cut(raw, rows):
    return {k: (v[rows] if isinstance(v, np.ndarray) else v) for k, v in raw.items()}


def test_gaps_split_pieces_and_are_recorded():
    raw = dfki_raw()
    keep = np.ones(len(raw["t"]), bool)
    keep[1000:1100] = False  # 0.2 s missing: 100 median steps
    m = Measurements.from_arrays(cut(raw, keep), source="rig.csv")
    assert m.names == ("trajectory_00 part 1", "trajectory_00 part 2")
    assert [len(p) for p in m] == [1000, len(raw["t"]) - 1100]
    assert m[1].note == "part 2 of 2, cut at gaps"
    assert "cut into 2 pieces at 1 gap(s)" in m.metadata["actions"][0] and "cut at gaps" in m.summary()
    # a gap leaving a sliver: refused, or dropped when asked (recorded)
    keep[:1000] = True
    keep[5:1000] = False
    with pytest.raises(ParameterError, match=r"trajectory_00 part 1: 5 samples .*short='drop'"):
        Measurements.from_arrays(cut(raw, keep), source="rig.csv")
    m = Measurements.from_arrays(cut(raw, keep), source="rig.csv", short="drop")
    assert len(m) == 1 and any("dropped, 5 samples" in a for a in m.metadata["actions"])


# -- skewpend's own trajectories ----------------------------------------------------------------------------
def test_from_trajectory_files(tmp_path, reference):
    traj = skewpend.simulate(reference, (0.8, -0.4, 0.0, 0.0), 1.0, dt_out=0.01, out=tmp_path / "run.csv")
    traj.to_netcdf(tmp_path / "run.nc")
    direct = Measurements.from_trajectory(traj)
    assert direct[0].u is None and direct.metadata["format"] == "trajectory"
    np.testing.assert_array_equal(direct[0].y, traj.y)
    for suffix in (".nc", ".csv"):
        m = Measurements.from_trajectory(tmp_path / f"run{suffix}")
        np.testing.assert_allclose(m[0].t, traj.t, rtol=1e-15, atol=0)
        np.testing.assert_allclose(m[0].y, traj.y, rtol=1e-15, atol=0)
        assert m.names == ("run",) and m.metadata["params"]["a"] == reference.a


def test_from_trajectory_with_torques(reference):
    traj = skewpend.simulate(reference.replace(tau1=0.5), (0.3, 0.1, 0.0, 0.0), 0.5, dt_out=0.01)
    m = Measurements.from_trajectory(traj)
    np.testing.assert_array_equal(m[0].u, np.tile([0.5, 0.0], (len(traj.t), 1)))


# -- CSV with a column mapping; a file in the wrong convention --------------------------------------------
@pytest.fixture(scope="module")
def kaheman_csv(tmp_path_factory):
    """The last validation piece written back in the authors' convention (absolute, zero upright), in
    degrees, as a CSV with its own column names."""
    m = Measurements.from_kaheman(KAHEMAN, which="validation")
    p = m[-1]
    q, dq, _ = convert_back(p.q + 0.0, p.dq, convention=Convention(second="absolute", zero="upright", unit="deg"))
    path = tmp_path_factory.mktemp("csv") / "swing.csv"
    table = np.column_stack([p.t, q, dq])
    np.savetxt(path, table, delimiter=",", header="time,th1,th2,w1,w2", comments="")
    return path, p


COLUMNS = {"t": "time", "phi": "th1", "psi": "th2", "dphi": "w1", "dpsi": "w2"}


def test_from_csv_reads_a_mapping(kaheman_csv):
    path, piece = kaheman_csv
    m = Measurements.from_csv(path, COLUMNS, convention=Convention(second="absolute", zero="upright", unit="deg"))
    assert m.names == ("swing",) and m[0].u is None and m.metadata["format"] == "csv"
    np.testing.assert_allclose(m[0].q, piece.q, atol=1e-9)
    np.testing.assert_allclose(m[0].dq, piece.dq, atol=1e-9)
    only_angles = Measurements.from_csv(path, {"t": "time", "phi": "th1", "psi": "th2"},
                                        convention=Convention(second="absolute", zero="upright", unit="deg"))
    assert only_angles[0].dq is None


@pytest.mark.parametrize("convention, says", [
    (Convention(second="absolute", unit="deg"), "look measured with zero upright"),
    (Convention(zero="upright", unit="deg"), "second angle looks absolute"),
    (Convention(second="absolute", zero="upright"), r"look like degrees; state Convention\(unit='deg'\)"),
])
def test_a_file_in_the_wrong_convention_is_caught(kaheman_csv, convention, says):
    with pytest.raises(ParameterError, match=says) as info:
        Measurements.from_csv(kaheman_csv[0], COLUMNS, convention=convention)
    assert "\n" not in str(info.value) and str(info.value).startswith("swing.csv: swing:")


@pytest.mark.parametrize("columns, says", [
    ({"t": "time", "phi": "th1"}, "must name the 'psi' column"),
    ({**COLUMNS, "dpsi": None}, "dphi and dpsi come together"),
    ({**COLUMNS, "phi": "theta"}, "no column 'theta'; its columns: time, th1"),
    ({**COLUMNS, "omega": "w1"}, "unknown key 'omega'"),
])
def test_from_csv_refuses_bad_mappings(kaheman_csv, columns, says):
    with pytest.raises(ParameterError, match=says):
        Measurements.from_csv(kaheman_csv[0], columns, convention=Convention(second="absolute", zero="upright",
                                                                                unit="deg"))


def test_from_mat_generic(tmp_path):
    from scipy.io import savemat

    t = np.arange(200) * 0.01
    x = np.vstack([0.3 * np.sin(3 * t), 0.2 * np.cos(5 * t)]).T  # samples along rows this time
    savemat(tmp_path / "run.mat", {"swing": x, "step": 0.01})
    m = Measurements.from_mat(tmp_path / "run.mat", "swing", dt="step")
    np.testing.assert_allclose(m[0].q, x) and np.testing.assert_allclose(m[0].t, t, atol=1e-12)
    assert m.names == ("swing[0]",) and m[0].dq is None
    with pytest.raises(ParameterError, match="no variable 'Y'; it holds swing, step"):
        Measurements.from_mat(tmp_path / "run.mat", "Y", dt=0.01)
    with pytest.raises(ParameterError, match="give time= .* or dt="):
        Measurements.from_mat(tmp_path / "run.mat", "swing")
    with pytest.raises(ParameterError, match=r"velocities=\(2, 3\) are not two of the 2 channels"):
        Measurements.from_mat(tmp_path / "run.mat", "swing", dt=0.01, velocities=(2, 3))


# -- every bad input: one line naming the piece and what to do ---------------------------------------------
def swing(n=500, dt=0.01):
    t = np.arange(n) * dt
    return {"t": t, "q": np.column_stack([0.4 * np.sin(2 * t), 0.3 * np.sin(4.5 * t + 1)]), "name": "p"}


def refused(raw, says, **kwargs):
    with pytest.raises(ParameterError, match=says) as info:
        Measurements.from_arrays(raw, source="lab.csv", **kwargs)
    assert "\n" not in str(info.value) and str(info.value).startswith("lab.csv: p")
    return str(info.value)


def test_wrapped_angles_refused_or_unwrapped():
    raw = swing()
    raw["q"] = raw["q"] * 10  # turns over and over
    wrapped = dict(raw, q=(raw["q"] + math.pi) % (2 * math.pi) - math.pi)
    refused(wrapped, r"jumps by .* wrapped into one turn; state Convention\(wrapped=True\)")
    m = Measurements.from_arrays(wrapped, convention=Convention(wrapped=True), skip=("tracking",))
    np.testing.assert_allclose(m[0].q, raw["q"], atol=1e-12)
    assert "unwrapped" in m.metadata["actions"][0]


def test_upright_mean_refused():
    raw = swing()
    refused(dict(raw, q=raw["q"] + [math.pi, 0]), r"mean -?3.* zero upright; state Convention\(zero='upright'\)")
    m = Measurements.from_arrays(dict(raw, q=raw["q"] + [math.pi, 0]), skip=("mean",))
    assert abs(m[0].q[:, 0].mean()) > 3  # near the top, as asked (median in (-pi, pi])
    # with torques the rig may hold it anywhere: no mean check
    Measurements.from_arrays(dict(raw, q=raw["q"] + [math.pi, 0], u=np.zeros((500, 2))))


def test_absolute_second_angle_refused():
    raw = swing()
    q = raw["q"].copy()
    q[:, 1] = q[:, 0] + 0.05 * q[:, 1]  # rod 2 nearly rigid on rod 1, written as an absolute angle
    refused(dict(raw, q=q), r"psi follows phi .* Convention\(second='absolute'\)")
    m = Measurements.from_arrays(dict(raw, q=q), convention=Convention(second="absolute"))
    np.testing.assert_allclose(m[0].q[:, 1], 0.05 * raw["q"][:, 1], atol=1e-15)


def test_time_nan_samples_constant_short_refused():
    raw = swing()
    t = raw["t"].copy()
    t[100] = t[98]
    refused(dict(raw, t=t), r"time does not increase at sample 100 \(counting from 0; t = 0.99 then 0.98\): sort the rows")
    refused(dict(raw, t=raw["t"][:9], q=raw["q"][:9]), "9 samples; a piece needs at least 10")
    assert MIN_SAMPLES == 10
    q = raw["q"].copy()
    q[:, 1] = 0.25
    refused(dict(raw, q=q), r"psi is constant \(0.25 rad\)")
    refused(raw, r"4.99 s \(shorter than min_duration=10 s\)", min_duration=10.0)
    q = raw["q"].copy()
    q[::10, 0] = np.nan  # 10 %
    refused(dict(raw, q=q), r"50 of 500 rows hold NaN or inf \(10.0%\), more than nonfinite=0.05")
    q = raw["q"].copy()
    q[[3, 7], 1] = np.inf
    m = Measurements.from_arrays(dict(raw, q=q), source="lab.csv")
    assert len(m[0]) == 498 and m.metadata["actions"] == ("lab.csv: p: dropped 2 of 500 rows holding NaN or inf",)
    assert "dropped 2 of 500 rows" in m.summary()


def test_velocity_sign_and_units_refused():
    raw = swing()
    t = raw["t"]
    dq = np.column_stack([0.8 * np.cos(2 * t), 1.35 * np.cos(4.5 * t + 1)])
    Measurements.from_arrays(dict(raw, dq=dq))
    refused(dict(raw, dq=dq * [-1, 1]), "dphi runs against phi's rate of change")
    refused(dict(raw, dq=dq * [1, 180 / math.pi]), r"dpsi is 57.* other units than the angles")


def test_shapes_and_options_refused():
    raw = swing()
    refused(dict(raw, u=np.zeros((499, 2))), r"torques u must have shape \(500, 2\)")
    with pytest.raises(ParameterError, match="skip: unknown check 'all'"):
        Measurements.from_arrays(raw, skip=("all",))
    with pytest.raises(ParameterError, match="gap_factor must be a number above 1"):
        Measurements.from_arrays(raw, gap_factor=0.5)
    with pytest.raises(ParameterError, match="convention must be a skewpend.Convention"):
        Measurements.from_arrays(raw, convention="relative")


# -- the object ------------------------------------------------------------------------------------------
def test_repr_summary_and_immutability(kaheman):
    text = repr(kaheman)
    assert "\n" not in text and text.startswith("<Measurements kaheman: 30 pieces (fit 26, validation 4), 80001 "
                                                "samples over 79.97 s; speeds, no torques; from DoublePendulum")
    lines = kaheman.summary().splitlines()
    assert len(lines) == 32 and lines[2] == "Y_id[0] (fit): 2667 samples, 2.666 s from t = 0 s, dt 0.001 s, no gaps"
    assert "\n" not in repr(kaheman[0])
    with pytest.raises(ValueError):
        kaheman[0].q[0, 0] = 1.0
    with pytest.raises(TypeError):
        kaheman.metadata["format"] = "x"
    with pytest.raises(AttributeError):
        kaheman.pieces = ()
    assert kaheman.metadata["sampling"][0]["samples"] == 2667


def test_split_and_select(kaheman, dfki):
    fit, held = kaheman.split(0.2)
    assert len(fit) == 24 and len(held) == 6 and held.names[0] == "Y_id[24]"
    assert fit.metadata["actions"][-1] == "split: the last 6 of 30 pieces held out"
    fit, held = kaheman.split(["Y_id[3]", 5])
    assert held.names == ("Y_id[3]", "Y_id[5]") and len(fit) == 28
    one = dfki.select("trajectory_00")
    a, b = one.split(0.25)
    assert abs(a[0].duration - 7.5) < 0.01 and abs(b[0].t[0] - 7.5) < 0.01 and len(a[0]) + len(b[0]) == len(one[0])
    window = kaheman.select(group="validation", time=(70.0, 73.0))
    assert window.names == ("Y_vad[0]", "Y_vad[1]") and window[0].t[0] >= 70.0 and window[1].t[-1] <= 73.0
    with pytest.raises(ParameterError, match="no piece is in group 'test'; the groups: fit, validation"):
        kaheman.split("test")
    with pytest.raises(ParameterError, match="held_out as a fraction must be in"):
        kaheman.split(1.5)
    with pytest.raises(ParameterError, match="leaves no piece"):
        kaheman.select(group="validation", time=(0.0, 1.0))
    with pytest.raises(ParameterError, match="no piece named 'x'"):
        kaheman.select("x")


def test_public_names():
    assert skewpend.Measurements is Measurements and skewpend.Convention is Convention
    assert "Measurements" in skewpend.__all__ and "Convention" in skewpend.__all__
