"""`skewpend simulate | export | validate`: files, configs, overrides, errors (real processes)."""

from __future__ import annotations

import re
from pathlib import Path

import numpy as np
import pytest
from helpers import completed

import skewpend

EXAMPLES = Path(__file__).resolve().parent.parent / "examples"


def run(*args, cwd=None, check=True):
    return completed(args, cwd, timeout=600, check=check)


def test_default_run_prints_a_summary():
    out = run("simulate", "--t-end", "2").stdout
    assert "reached t_end" in out and "energy drift" in out and "wall time" in out


def test_csv_output_columns_and_content(tmp_path):
    """The CSV is the header and plain numbers: pandas.read_csv(path) and numpy.genfromtxt(path,
    delimiter=",", names=True) with no options give the 13 named float columns and exactly the rows
    written (issue 36: trailing '# key: value' lines gave junk rows and a text column); how the run
    was made is in run.csv.json beside it, which open_trajectory reads back."""
    import json

    path = tmp_path / "run.csv"
    run("simulate", "--t-end", "1", "--dt-out", "0.1", "--c1", "0.1", "--out", path)
    header = path.read_text().splitlines()[0]
    assert header == "t,phi,psi,dphi,dpsi,energy,work,x1,y1,z1,x2,y2,z2" and "#" not in path.read_text()
    data = np.loadtxt(path, delimiter=",", skiprows=1)
    assert data.shape == (11, 13) and np.all(np.isfinite(data))
    np.testing.assert_allclose(data[:, 0], np.linspace(0, 1, 11), atol=1e-12)
    np.testing.assert_allclose(data[0, 1:5], [1.2, -0.8, 0, 0])
    assert np.ptp(data[:, 5] - data[:, 6]) < 1e-8  # E - W conserved
    # no temporary files left; the metadata beside the CSV
    assert sorted(p.name for p in tmp_path.iterdir()) == ["run.csv", "run.csv.json"]
    arr = np.genfromtxt(path, delimiter=",", names=True)
    assert arr.dtype.names == tuple(header.split(",")) and arr.shape == (11,)
    np.testing.assert_array_equal(np.column_stack([arr[n] for n in arr.dtype.names]), data)
    pd = pytest.importorskip("pandas")
    df = pd.read_csv(path)
    assert list(df.columns) == header.split(",") and all(dtype == np.float64 for dtype in df.dtypes)  # z1 = 0: float
    np.testing.assert_array_equal(df.to_numpy(), data)
    meta = json.loads((tmp_path / "run.csv.json").read_text())
    assert meta["kind"] == "skewpend trajectory" and meta["status"] == 0 and meta["param_c1"] == 0.1
    assert meta["columns"] == list(df.columns) and meta["units"][:2] == ["s", "rad"] and meta["csv_rows"] == 11
    back = skewpend.open_trajectory(path)  # the library reads both files back
    np.testing.assert_array_equal(back.y, data[:, 1:5])
    assert back.params.c1 == 0.1 and back.method == meta["method"]


def test_netcdf_output_has_metadata(tmp_path):
    xr = pytest.importorskip("xarray")
    path = tmp_path / "run.nc"
    run("simulate", "--t-end", "1", "--dt-out", "0.5", "--alpha", "30deg", "--out", path)
    with xr.open_dataset(path) as ds:
        assert list(ds["phi"].values.shape) == [3]
        assert ds.attrs["param_alpha"] == pytest.approx(np.pi / 6)
        assert ds.attrs["method"] == "taylor" and ds.attrs["skewpend_version"]  # the default, auto, chose taylor
        assert ds["phi"].attrs["units"] == "rad"


def test_config_file_and_command_line_override(tmp_path):
    cfg = tmp_path / "run.toml"
    cfg.write_text(
        '[parameters]\na = 0.5\nb = 0.5\nm1 = 1\nm2 = 1\nalpha = "90deg"\ng = 9.81\n'
        '[initial]\nphi0 = "10deg"\npsi0 = 0\n[simulation]\nt_end = 1.0\ndt_out = 0.5\nout = "from_config.csv"\n'
    )
    run("simulate", "--config", cfg, cwd=tmp_path)
    a = np.loadtxt(tmp_path / "from_config.csv", delimiter=",", skiprows=1)
    run("simulate", "--config", cfg, "--phi0", "20deg", "--out", "override.csv", cwd=tmp_path)
    b = np.loadtxt(tmp_path / "override.csv", delimiter=",", skiprows=1)
    assert a[0, 1] == pytest.approx(np.radians(10)) and b[0, 1] == pytest.approx(np.radians(20))
    # alpha = 90 deg, psi0 = 0, psi' = 0: the second rod stays aligned (decoupled linear motion)
    assert np.max(np.abs(a[:, 2])) < 1e-3


@pytest.mark.parametrize("example", sorted(p.name for p in EXAMPLES.glob("*.toml") if "long" not in p.name))
def test_examples_run_as_they_are(example, tmp_path):
    proc = run("simulate", "--config", EXAMPLES / example, "--t-end", "1", cwd=tmp_path)
    assert "reached t_end" in proc.stdout


@pytest.mark.parametrize(
    "args, message",
    [
        (["simulate", "--m1", "-1"], "m1 must be > 0"),
        (["simulate", "--t-end", "-3"], "--t-end: expected a positive number"),
        (["simulate", "--phi0", "abc"], "--phi0: expected a number"),
        (["simulate", "--g", "sym"], "simulation needs numeric values"),
        (["simulate", "--out", "run.txt"], "--out: expected a file name ending in .csv or .nc"),
        (["simulate", "--method", "euler"], "--method"),
        (["simulate", "--method", "rk4", "--dt", "0.003"], "whole number of steps"),
        (["simulate", "--config", "missing.toml"], "does not exist"),
        (["export", "--format", "sdf"], "--format"),
        (["export", "--out", "no/such/dir/model.xml"], "does not exist"),
    ],
)
def test_bad_input_one_line_status_2(args, message, tmp_path):
    proc = run(*args, cwd=tmp_path, check=False)
    assert proc.returncode == 2, proc.stderr
    lines = proc.stderr.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("skewpend: error:") and message in lines[0], proc.stderr
    assert list(tmp_path.iterdir()) == []


def test_bad_config_keys(tmp_path):
    cfg = tmp_path / "bad.toml"
    cfg.write_text("[parameters]\nlength = 1\n")
    proc = run("simulate", "--config", cfg, check=False)
    assert proc.returncode == 2 and "[parameters]: unknown parameter 'length'" in proc.stderr and "allowed: a, b, m1" in proc.stderr
    cfg.write_text("[parameters\n")
    proc = run("simulate", "--config", cfg, check=False)
    assert proc.returncode == 2 and "not valid TOML" in proc.stderr


def test_failed_run_writes_what_it_computed(tmp_path):
    """A blow-up: exit status 1, the finite rows up to the failure written, the reason recorded."""
    proc = run("simulate", "--dphi0", "1e150", "--t-end", "0.01", "--method", "dop853", "--out", "x.csv", cwd=tmp_path,
               check=False)
    assert proc.returncode == 1 and "wrote the 1 rows computed to x.csv" in proc.stderr
    assert sorted(p.name for p in tmp_path.iterdir()) == ["x.csv", "x.csv.json"]
    import json

    meta = json.loads((tmp_path / "x.csv.json").read_text())
    assert meta["status"] == 2 and meta["message"] == "stopped: step size underflow"
    data = np.loadtxt(tmp_path / "x.csv", delimiter=",", skiprows=1, ndmin=2)
    assert data.shape == (1, 13) and np.all(np.isfinite(data))


def test_export_writes_a_model_mujoco_loads(tmp_path):
    mujoco = pytest.importorskip("mujoco")
    path = tmp_path / "model.xml"
    run("export", "--format", "mjcf", "--out", path, "--alpha", "20deg", "--m2", "0.5")
    model = mujoco.MjModel.from_xml_path(str(path))
    assert model.nq == 2 and model.body_mass[2] == pytest.approx(0.5)
    urdf = run("export", "--format", "urdf").stdout
    assert urdf.lstrip().startswith("<?xml") or "<robot" in urdf


def test_validate_agrees_with_mujoco():
    pytest.importorskip("mujoco")
    out = run("validate", "--alpha", "50deg", "--phi0", "1.0", "--psi0", "0.5", "--t-end", "1").stdout
    assert "AGREE within 1e-06" in out


# -- run files: every key a command reads takes effect (issue 20, class 7) ---------------------------------------
RUN_FILE = "[simulation]\nt_end = 5.5\nrtol = 1e-7\natol = 1e-9\n"
#: command, extra options, the library function it calls (module, name), the keyword -> value it must receive
HONOURED = [
    ("lyapunov", [], ("skewpend.analysis.lyapunov", "lyapunov"), {"t_end": 5.5, "rtol": 1e-7, "atol": 1e-9}),
    ("flipmap", ["--n", "4"], ("skewpend.analysis.flipmap", "flip_map"), {"t_end": 5.5, "rtol": 1e-7, "atol": 1e-9}),
    ("chaos-diagram", [], ("skewpend.analysis.chaos", "chaos_diagram"), {"t_end": 5.5, "rtol": 1e-7, "atol": 1e-9}),
    ("simulate", [], ("skewpend.numeric.simulation", "simulate"), {"rtol": 1e-7, "atol": 1e-9}),
    ("report", [], ("skewpend.views.report", "build_report"), {"t_end": 5.5, "rtol": 1e-7, "atol": 1e-9}),
]


class _Called(Exception):
    pass


@pytest.mark.parametrize("command, extra, target, expected", HONOURED, ids=[h[0] for h in HONOURED])
def test_every_run_file_key_a_command_reads_takes_effect(command, extra, target, expected, tmp_path, monkeypatch):
    import importlib

    from helpers import run_cli

    seen = {}

    def spy(*args, **kwargs):
        seen.update(kwargs, args=args)
        from skewpend.errors import SkewpendError

        raise SkewpendError("spy: called")

    monkeypatch.setattr(importlib.import_module(target[0]), target[1], spy)
    (tmp_path / "run.toml").write_text(RUN_FILE)
    ran = run_cli([command, "--config", "run.toml", *extra], cwd=tmp_path)
    assert "spy: called" in ran.err, ran.report()
    for key, value in expected.items():
        assert seen.get(key) == value, (key, seen)
    if command == "simulate":
        assert seen["args"][2] == 5.5  # t_end is simulate's third argument


def test_poincare_takes_rtol_and_atol_from_a_run_file(tmp_path, monkeypatch):
    import skewpend.analysis.poincare as poincare
    from helpers import run_cli

    seen = {}
    monkeypatch.setattr(poincare, "poincare", lambda *a, **kw: seen.update(kw) or (_ for _ in ()).throw(_Called()))
    (tmp_path / "run.toml").write_text("[simulation]\nrtol = 1e-9\natol = 1e-11\n")
    ran = run_cli(["poincare", "--energy", "5", "--config", "run.toml"], cwd=tmp_path)
    assert seen["rtol"] == 1e-9 and seen["atol"] == 1e-11, ran.report()


def test_options_override_the_run_file_for_the_analyses(tmp_path, monkeypatch):
    import skewpend.analysis.lyapunov as lyapunov
    from helpers import run_cli

    seen = {}
    monkeypatch.setattr(lyapunov, "lyapunov", lambda *a, **kw: seen.update(kw) or (_ for _ in ()).throw(_Called()))
    (tmp_path / "run.toml").write_text(RUN_FILE)
    run_cli(["lyapunov", "--config", "run.toml", "--t-end", "7", "--rtol", "1e-8"], cwd=tmp_path)
    assert seen["t_end"] == 7.0 and seen["rtol"] == 1e-8 and seen["atol"] == 1e-9


def test_transient_is_honoured_or_refused_by_one_rule(tmp_path, monkeypatch):
    """A transient that is a whole number of renormalisation intervals is passed on as given; any
    other is refused (the measurement starts at a renormalisation), never silently rounded."""
    import skewpend.analysis.lyapunov as lyapunov
    from helpers import assert_refused, run_cli

    seen = {}
    monkeypatch.setattr(lyapunov, "lyapunov", lambda *a, **kw: seen.update(kw) or (_ for _ in ()).throw(_Called()))
    run_cli(["lyapunov", "--transient", "8.5", "--renorm-every", "0.5"], cwd=tmp_path)
    assert seen["transient"] == 8.5 and seen["renorm_every"] == 0.5
    line = assert_refused(run_cli(["lyapunov", "--transient", "8.5"], cwd=tmp_path), ["--transient", "8.5", "--renorm-every"])
    assert "whole number" in line


# -- exit status 1: a result that is partly failed (one rule in skewpend.cli.main) -------------------------------
class _Partial:
    """What a command returns in the result protocol's terms."""

    ok = False
    message = "3 of 8 cells failed (max_steps reached)"


def test_the_rule_reads_ok_then_success():
    from skewpend.cli import _ok

    assert _ok(object()) and _ok(type("R", (), {"ok": True})()) and not _ok(_Partial())
    assert not _ok(type("T", (), {"success": False})())  # a Trajectory before the protocol's ok


@pytest.mark.parametrize("argv, what", [
    (["chaos-diagram", "--alphas", "0:1:2", "--energies", "1:2:2", "--samples", "2", "--t-end", "5", "--rtol", "1"],
     "trajectories failed"),
    (["poincare", "--energy", "5", "--rtol", "1", "--orbits", "3", "--crossings", "5"], "orbits failed"),
    (["flipmap", "--n", "16", "--a", "1e-300"], "cells failed"),  # one line: not flip_map's warning too
])
def test_failed_trajectories_exit_1_with_one_line(argv, what, tmp_path):
    from helpers import run_process

    ran = run_process(argv, cwd=tmp_path)
    assert ran.code == 1, ran.report()
    lines = ran.err.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith(f"skewpend: {argv[0]}: ") and what in lines[0], ran.report()
    assert not re.search(r"\bnan\b(?! \(|\))", ran.out.lower().replace("left nan", ""))  # no NaN printed as a number
