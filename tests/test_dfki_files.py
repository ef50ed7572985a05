"""The DFKI lab's model files (``model_*_parameters.yml``, issue 36): read as ``params0`` (on the
command line ``--params0 FILE.yml``) and written back in the lab's form (``--out FILE.yml``,
``write_dfki_lab_parameters``).  Checked against the lab's own files in ``data/dfki-design-C.0/`` and
against the lab's published equations (``dynamics.rst`` there: the mass matrix and the gravity
vector), read with PyYAML as the lab's ``model_parameters.load_yaml`` reads them."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from helpers import run_cli, snapshot

from skewpend import Parameters
from skewpend.analysis.measurements import (DFKI_KEYS, dfki_lab_parameters, dfki_lab_values,
                                            write_dfki_lab_parameters)
from skewpend.errors import ParameterError

DFKI = Path(__file__).resolve().parent.parent / "data" / "dfki-design-C.0"
MODELS = ["model_h1.0_parameters.yml", "model_3.0_parameters.yml", "model_3.1_parameters.yml"]


def lab_read(path) -> dict:
    """A model file as the lab reads it (``yaml.safe_load``)."""
    yaml = pytest.importorskip("yaml")
    with open(path) as fh:
        return yaml.safe_load(fh)


def base(p: Parameters) -> np.ndarray:
    """What the motion depends on (the lab's planar model): J1 = I1 + m2 l1^2 about joint 1, h1 = m1 r1 +
    m2 l1, I2 about joint 2, h2 = m2 r2, the damping, friction and rotor; computed from the lab's values."""
    v = dfki_lab_values(p)
    return np.array([v["I1"] + v["m2"] * v["l1"] ** 2, v["m1"] * v["r1"] + v["m2"] * v["l1"], v["I2"],
                     v["m2"] * v["r2"], v["b1"], v["b2"], v["cf1"], v["cf2"], v["Ir"], v["gr"], v["g"], v["l1"]])


@pytest.mark.parametrize("name", MODELS)
def test_lab_file_round_trip(name, tmp_path):
    """lab yml -> Parameters -> yml -> Parameters: the same Parameters bit for bit, and the same numbers
    as the lab's file where its split is a physical body (h1.0); model 3.0's and 3.1's ``I2 < m2 r2^2``
    (a negative inertia about the centre of mass) is realised with a heavier rod 2 by the reader, so
    there the written file keeps every base parameter (to rounding) instead."""
    original = lab_read(DFKI / name)
    p = dfki_lab_parameters(DFKI / name)
    out = write_dfki_lab_parameters(p, tmp_path / "fit.yml", header=["written by a test", "two: lines"])
    assert dfki_lab_parameters(out) == p
    written = lab_read(out)
    assert list(written) == sorted(DFKI_KEYS) and all(isinstance(v, float) for v in written.values())
    assert set(original) - set(written) == {"tl1", "tl2"}  # the torque limits: skewpend's model has none
    if name.startswith("model_h1.0"):
        assert written == {k: original[k] for k in written}
    else:
        assert written["I2"] < original["m2"] * original["r2"] ** 2 and written["m2"] > original["m2"]
        lab = dict(original)
        lab_base = np.array([lab["I1"] + lab["m2"] * lab["l1"] ** 2, lab["m1"] * lab["r1"] + lab["m2"] * lab["l1"],
                             lab["I2"], lab["m2"] * lab["r2"], lab["b1"], lab["b2"], lab["cf1"], lab["cf2"], lab["Ir"],
                             lab["gr"], lab["g"], lab["l1"]])
        assert np.allclose(base(p), lab_base, rtol=1e-13, atol=0)
    text = out.read_text()
    assert text.startswith("# written by a test\n# two: lines\nI1: ")


def test_written_values_follow_the_labs_conventions(tmp_path):
    """A model built by hand, written: inertia about the joint axis I = I_zz + m r^2 (the lab's I, its
    dynamics.rst), the gear's sign the lab's (``gr_lab = -gr``), b = c, l = the rod, r = the centre of
    mass along it; entries that do not enter a planar model (I_xx, h_z) are not carried."""
    p = Parameters(a=0.25, b=0.3, m1=0.5, m2=0.4, alpha=0.0, g=9.81, c1=0.01, c2=0.003, cf1=0.09, cf2=0.07,
                   Ir=7e-5, gr=-6.0, com1=(0, 0.11, 0.02), com2=(0, 0.17, 0),
                   inertia1=((0.003, 0, 0), (0, 0.0001, 0), (0, 0, 0.0031)), inertia2=((0.004, 0, 0), (0, 0, 0), (0, 0, 0.004)))
    v = lab_read(write_dfki_lab_parameters(p, tmp_path / "m.yml"))
    assert v["I1"] == pytest.approx(0.0031 + 0.5 * 0.11**2, rel=1e-15)
    assert v["I2"] == pytest.approx(0.004 + 0.4 * 0.17**2, rel=1e-15)
    assert (v["l1"], v["l2"], v["r1"], v["r2"], v["m1"], v["m2"]) == (0.25, 0.3, 0.11, 0.17, 0.5, 0.4)
    assert (v["b1"], v["b2"], v["cf1"], v["cf2"], v["Ir"], v["gr"], v["g"]) == (0.01, 0.003, 0.09, 0.07, 7e-5, 6.0, 9.81)
    back = dfki_lab_parameters(tmp_path / "m.yml")
    assert back.gr == -6.0 and back.com1[0] == back.com1[2] == 0 and back.com1[1] == pytest.approx(0.11, rel=1e-14)
    assert back.inertia1[2][2] == pytest.approx(0.0031, rel=1e-13)
    # thin rods (no com, no inertia given): the rod's midpoint and m l^2/12 + m (l/2)^2 = m l^2/3
    v = dfki_lab_values(Parameters(a=0.3, b=0.2, m1=0.6, m2=0.3, alpha=0, g=9.81))
    assert (v["r1"], v["r2"]) == (0.15, 0.1)
    assert v["I1"] == pytest.approx(0.6 * 0.3**2 / 3, rel=1e-14) and v["I2"] == pytest.approx(0.3 * 0.2**2 / 3, rel=1e-14)


def test_written_file_moves_as_the_labs_equations_say(tmp_path):
    """The written numbers put into the lab's published mass matrix and gravity vector (dynamics.rst:
    M = [[I1 + I2 + l1^2 m2 + 2 l1 m2 r2 c2 + gr^2 Ir + Ir, I2 + l1 m2 r2 c2 - gr Ir], [.., I2 + gr^2 Ir]],
    G = [-g m1 r1 s1 - g m2 (l1 s1 + r2 s12), -g m2 r2 s12]) at hanging: skewpend's own M0 and K0 of the
    model written (derived from its Lagrangian), to rounding."""
    from skewpend.analysis.modes import linear_matrices

    p = dfki_lab_parameters(DFKI / "model_h1.0_parameters.yml").replace(com1=(0, 0.19, 0), m1=0.61)
    v = lab_read(write_dfki_lab_parameters(p, tmp_path / "m.yml"))
    I1, I2, Ir, gr, l1, m1, m2, r1, r2, g = (v[k] for k in ("I1", "I2", "Ir", "gr", "l1", "m1", "m2", "r1", "r2", "g"))
    M_lab = np.array([[I1 + I2 + l1**2 * m2 + 2 * l1 * m2 * r2 + gr**2 * Ir + Ir, I2 + l1 * m2 * r2 - gr * Ir],
                      [I2 + l1 * m2 * r2 - gr * Ir, I2 + gr**2 * Ir]])
    # K = -dG/dq at q = 0 (cos = 1)
    K_lab = np.array([[g * m1 * r1 + g * m2 * (l1 + r2), g * m2 * r2], [g * m2 * r2, g * m2 * r2]])
    M0, _, K0 = linear_matrices(p)
    assert np.allclose(M0, M_lab, rtol=1e-12, atol=0) and np.allclose(K0, K_lab, rtol=1e-12, atol=0)


@pytest.mark.parametrize("change, says", [
    (dict(alpha=0.1), "planar; this model has alpha = 5.72958 deg"),
    (dict(com2=(0.001, 0.2, 0)), "com2 is 0.001 m off it"),
    (dict(cf1=0.1, cfs=50.0), "cf atan(100 q'); this model has cfs = 50"),
    (dict(tau1=0.2), "no constant joint torques"),
    (dict(alpha=None, axis2=(0.1, 0, 1)), "both hinge axes along k; axis2 = (0.0995037, 0, 0.995037)"),
    (dict(a=None), "needs numeric values"),
])
def test_models_the_labs_file_cannot_hold_are_refused(change, says, tmp_path):
    p = dfki_lab_parameters(DFKI / "model_h1.0_parameters.yml")
    bad = p.replace(**change)
    with pytest.raises(Exception) as info:
        write_dfki_lab_parameters(bad, tmp_path / "m.yml")
    assert says in str(info.value)
    assert list(tmp_path.iterdir()) == []
    with pytest.raises(ParameterError, match="written as .yml"):
        write_dfki_lab_parameters(p, tmp_path / "m.toml")


def test_numbers_read_back_exactly_and_as_yaml_numbers(tmp_path):
    """Numbers are written with repr (exact), with a dot before any exponent (PyYAML reads ``1e-05`` as
    text, ``1.0e-05`` as a number); the reader takes the lab's ``.inf`` torque limits and comments."""
    p = dfki_lab_parameters(DFKI / "model_h1.0_parameters.yml").replace(Ir=1e-05, c1=3e-300, c2=1.2345678901234567e-4)
    path = write_dfki_lab_parameters(p, tmp_path / "m.yml")
    assert "Ir: 1.0e-05\n" in path.read_text()
    v = lab_read(path)
    assert (v["Ir"], v["b1"], v["b2"]) == (1e-05, 3e-300, 1.2345678901234567e-4)
    assert dfki_lab_parameters(path) == p
    path.write_text("# a comment: with a colon\n" + path.read_text() + "tl1: .inf\ntl2: 10.0  # N m\n")
    assert dfki_lab_parameters(path) == p
    path.write_text(path.read_text().replace("g: 9.81", "g: nine"))
    with pytest.raises(ParameterError, match="g is not a number: 'nine'"):
        dfki_lab_parameters(path)


# -- the command line -------------------------------------------------------------------------------------
@pytest.mark.slow  # 3-4 s alone: the first linear matrices of params0's geometry
def test_params0_from_a_lab_file_with_options_over_it(tmp_path, monkeypatch):
    """--params0 FILE.yml is the reader's model; a model option overrides one value (--g here); the fit
    is stood in for (what it starts from is tested)."""
    import skewpend.analysis.identify as I
    from skewpend import Status
    from skewpend.analysis.identify import Identification

    t = np.linspace(0, 3, 1501)
    np.savetxt(tmp_path / "run.csv", np.column_stack([t, 0.5 * np.cos(6 * t), -0.3 * np.cos(13 * t)]),
               delimiter=",", header="time,q1,q2", comments="")
    started = {}

    def fit(measurements, params0, **kw):
        started["p"] = params0
        return Identification(params=params0, params0=params0, status=Status.SUCCESS, message="stood in", settings={})

    monkeypatch.setattr(I, "identify", fit)
    lab = DFKI / "model_h1.0_parameters.yml"
    ran = run_cli(["identify", "run.csv", "--columns", "t=time,phi=q1,psi=q2", "--params0", lab, "--quiet"], cwd=tmp_path)
    assert ran.code == 0, ran.report()
    assert started["p"] == dfki_lab_parameters(lab)
    ran = run_cli(["identify", "run.csv", "--columns", "t=time,phi=q1,psi=q2", "--params0", lab, "--g", "9.80",
                   "--quiet"], cwd=tmp_path)
    assert ran.code == 0, ran.report()
    assert started["p"] == dfki_lab_parameters(lab).replace(g=9.80)


@pytest.mark.slow
def test_identify_from_and_to_the_labs_files(tmp_path):
    """A free swing made by skewpend from the lab's model h1.0 (6 s at 500 Hz, no noise), fitted from
    --params0 model_h1.0_parameters.yml with the inverse dynamics (the rods' centres of mass held on
    their lines: the lab's model has no others), written with --out fit.yml: the lab's numbers come
    back within the filter's bias (2 % on the inertial ones, 5 % on the damping), the held ones exactly."""
    import skewpend

    lab = DFKI / "model_h1.0_parameters.yml"
    truth = dfki_lab_parameters(lab)
    tr = skewpend.simulate(truth, (1.2, -0.8, 0.0, 0.0), 6.0, dt_out=0.002)
    y = np.asarray(tr.y)
    np.savetxt(tmp_path / "swing.csv", np.column_stack([tr.t, y[:, 0], y[:, 1]]), delimiter=",",
               header="time,q1,q2", comments="")
    ran = run_cli(["identify", "swing.csv", "--columns", "t=time,phi=q1,psi=q2", "--params0", lab,
                   "--free", "J1zz_b,h1y_b,J2zz,h2y,c1,c2", "--method", "linear", "--quiet", "--out", "fit.yml"],
                  cwd=tmp_path)
    assert ran.code == 0, ran.report()
    assert "lab model fit.yml" in " ".join(ran.out.split())
    got, want = lab_read(tmp_path / "fit.yml"), lab_read(lab)
    for k in ("I1", "I2"):
        assert got[k] == pytest.approx(want[k], rel=0.02), k
    assert got["m2"] * got["r2"] == pytest.approx(want["m2"] * want["r2"], rel=0.02)
    for k in ("b1", "b2"):
        assert got[k] == pytest.approx(want[k], rel=0.05), k
    for k in ("cf1", "cf2", "Ir", "gr", "l1", "l2", "g", "m1", "m2"):
        assert got[k] == want[k], k
    header = [line for line in (tmp_path / "fit.yml").read_text().splitlines() if line.startswith("#")]
    assert any("skewpend identify --params0 FILE" in line for line in header)


def test_out_yml_refused_after_a_fit_whose_centre_of_mass_is_off_the_rod(tmp_path, monkeypatch):
    """A fitted model the lab's file cannot hold (h2x freed and determined): the table is printed, then
    one line says why the file is not written (exit 2), and no file is left."""
    import skewpend.analysis.identify as I
    from skewpend import Status
    from skewpend.analysis.identify import Identification

    lab = DFKI / "model_h1.0_parameters.yml"
    p0 = dfki_lab_parameters(lab)
    t = np.linspace(0, 3, 1501)
    np.savetxt(tmp_path / "run.csv", np.column_stack([t, 0.5 * np.cos(6 * t), -0.3 * np.cos(13 * t)]),
               delimiter=",", header="time,q1,q2", comments="")
    fitted = p0.replace(com2=(0.003, 0.27, 0))
    monkeypatch.setattr(I, "identify", lambda m, params0, **kw: Identification(
        params=fitted, params0=params0, status=Status.SUCCESS, message="stood in", settings={}))
    before = snapshot(tmp_path)
    ran = run_cli(["identify", "run.csv", "--columns", "t=time,phi=q1,psi=q2", "--params0", lab, "--quiet",
                   "--out", "fit.yml"], cwd=tmp_path)
    assert ran.code == 2, ran.report()
    assert ran.err.splitlines() == ["skewpend: error: --out fit.yml: not written: the DFKI lab's model has each centre "
                                    "of mass on its rod's line; com2 is 0.003 m off it (identify with --free leaving "
                                    "out h2x, or write a .toml run file instead)"]
    assert snapshot(tmp_path) == before
