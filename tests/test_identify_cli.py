"""``skewpend identify`` (issue 27): the real free swing of Kaheman et al. (2023) end to end, the run
file it writes (``Identification.to_run_file``) read back exactly and taken by the other commands,
the exit statuses (0, 1 for a fit that does not succeed, 2 for bad input, 130 on Ctrl-C) and the
published model as the default start.  One fit is shared by the module (a few seconds, in process)."""

from __future__ import annotations

import dataclasses
import importlib.util
import math
import re
import signal
import subprocess
import threading
from pathlib import Path

import numpy as np
import pytest
from helpers import SKEWPEND, Ran, assert_refused, run_cli, snapshot

from skewpend import Status
from skewpend.progress import STAGE_LINE
from skewpend.errors import ParameterError

KAHEMAN = Path(__file__).resolve().parent.parent / "data" / "kaheman2023"


@pytest.fixture(scope="module")
def fitted(tmp_path_factory):
    """``skewpend identify data/kaheman2023 --format kaheman --out fit.toml --netcdf fit.nc``, once."""
    pytest.importorskip("netCDF4")
    d = tmp_path_factory.mktemp("identify")
    ran = run_cli(["identify", KAHEMAN, "--format", "kaheman", "--out", "fit.toml", "--netcdf", "fit.nc"], cwd=d)
    return d, ran


@pytest.fixture(scope="module")
def result(fitted):
    """The fit's Identification, read back from its --netcdf file."""
    from skewpend.analysis.readback import open_result

    return open_result(fitted[0] / "fit.nc")


# -- the real free swing, end to end -------------------------------------------------------------------
def test_kaheman_end_to_end_prints_the_table_and_writes_the_run_file(fitted):
    d, ran = fitted
    assert ran.code == 0, ran.report()
    assert "Traceback" not in ran.err and "error" not in ran.err and "%" not in ran.err  # no progress bar off a terminal
    for text in ("identified (output error", "base parameter", "J1zz_b", "ratios to J1zz_b", "held out Y_vad[3]",
                 "held out angle RMS: median over pieces", "undetermined: one overall scale",
                 "held out: each piece simulated from its first measured state",
                 "the RMS in the absolute angles (each rod's from the vertical), as measured"):
        assert text in ran.out, text
    assert re.search(r"^run file\s+fit\.toml$", ran.out, re.M) and re.search(r"^result\s+fit\.nc$", ran.out, re.M)
    # the held-out figures of the default start (the published model) are printed beside the fit's: in the
    # absolute angles the rig measured, then in the joint angles
    m = re.search(r"angle RMS: median over pieces ([\d.]+) rad \(params0: ([\d.]+)\)", ran.out)
    assert m and float(m[1]) <= float(m[2]), m
    m = re.search(r"in the joint angles \(skewpend's coordinates\): median over pieces ([\d.]+) rad \(params0: ([\d.]+)\)",
                  ran.out)
    assert m and float(m[1]) <= 0.0033 and float(m[1]) <= float(m[2]), m
    assert sorted(p.name for p in d.iterdir()) == ["fit.nc", "fit.toml"]  # no temporary file left


def test_run_file_header_says_what_was_identified(fitted, result):
    text = (fitted[0] / "fit.toml").read_text()
    header = [line for line in text.splitlines() if line.startswith("#")]
    joined = "\n".join(header)
    for part in ("# method: output-error", "# data: 26 pieces (Y_id[0]", "# held out: 4 pieces",
                 f"median over pieces {result.heldout_median:.4g} rad (params0: {result.heldout_median0:.4g})",
                 f"overall {result.heldout_overall:.4g} rad (params0: {result.heldout_overall0:.4g})",
                 "# status: success", "# undetermined: one overall scale"):
        assert part in joined, part
    assert "skew angle" not in joined  # alpha was not freed
    body = text.split("[parameters]\n", 1)[1]
    keys = [line.split(" = ")[0] for line in body.splitlines() if line]
    # every model key that is set; the optional terms that are off, the torques (0) and the axes are not
    assert keys == ["a", "b", "m1", "m2", "alpha", "g", "c1", "c2", "com1", "com2", "inertia1", "inertia2"]


def test_run_file_reads_back_exactly(fitted, result):
    """skewpend.config reads the run file back to the fitted Parameters bit for bit."""
    from skewpend.config import Run, build_parameters
    from skewpend.io import read_config

    path = fitted[0] / "fit.toml"
    assert result.ok and result.params != result.params0
    assert Run("simulate", str(path)).parameters() == result.params
    assert build_parameters(read_config(path)["parameters"]) == result.params


@pytest.mark.parametrize("argv", [
    ["simulate", "--t-end", "1"],
    # the fitted centres of mass sit a little off the rods' lines (h1x, h2x, both determined): the model
    # hangs at phi = -0.019 deg, psi = 0.093 deg, so modes are taken about that rest (plain `modes`
    # refuses, phi = psi = 0 being no equilibrium of it)
    ["modes", "--about", "down-down"],
    ["control", "lqr"],
    ["export"],
    ["validate", "--t-end", "0.5"],
], ids=lambda a: " ".join(a))
def test_commands_accept_the_run_file(fitted, argv):
    if argv[0] == "validate" and importlib.util.find_spec("mujoco") is None:
        pytest.skip("MuJoCo is not installed (pip install -e '.[test]')")
    d, _ = fitted
    before = snapshot(d)
    ran = run_cli([*argv, "--config", "fit.toml"], cwd=d)
    assert ran.code == 0, ran.report()
    assert snapshot(d) == before
    if argv[0] == "modes":  # the identified model's modes: the rig's measured 0.905 and 2.00 Hz (guide: Conventions)
        f = [float(line.split()[2]) for line in ran.out.splitlines() if re.match(r"\s+[12]\s+[\d.]+\s+[\d.]+", line)]
        assert len(f) == 2 and abs(f[0] / 0.905 - 1) < 0.01 and abs(f[1] / 2.00 - 1) < 0.01, ran.out


def test_to_run_file_writes_what_is_set_and_reads_back(result, tmp_path):
    """Torques written only when non-zero, the axes only when set (alpha then left out); exact round trip."""
    from skewpend.config import Run

    cases = [dict(tau1=0.25, tau2=-1e-300), dict(alpha=None, axis2=(0.1, 0.2, 1.0)),
             dict(axis1=(0.01, 0.0, 1.0), alpha=math.radians(20))]
    for k, changes in enumerate(cases):
        r = dataclasses.replace(result, params=result.params.replace(**changes))
        path = r.to_run_file(tmp_path / f"case{k}.toml")
        body = path.read_text().split("[parameters]\n", 1)[1]
        keys = {line.split(" = ")[0] for line in body.splitlines() if line}
        assert set(changes) - {"alpha"} <= keys, (changes, keys)
        assert ("alpha" in keys) == (r.params.axis2 is None)
        assert Run("simulate", str(path)).parameters() == r.params, changes
    assert sorted(p.name for p in tmp_path.iterdir()) == ["case0.toml", "case1.toml", "case2.toml"]


def test_to_run_file_refuses_a_fit_that_did_not_succeed(result, tmp_path):
    failed = dataclasses.replace(result, status=Status.NO_CONVERGENCE, message="the data do not determine c2")
    with pytest.raises(ParameterError) as info:
        failed.to_run_file(tmp_path / "fit.toml")
    assert "\n" not in str(info.value) and "force=True" in str(info.value)
    assert list(tmp_path.iterdir()) == []
    failed.to_run_file(tmp_path / "fit.toml", force=True)
    assert "NOT a fitted model" in (tmp_path / "fit.toml").read_text()


def test_a_fit_that_does_not_succeed_exits_1_without_a_run_file(result, tmp_path, monkeypatch):
    """Exit status 1 (the result's status, mapped by skewpend.cli.main) with one line, the table still printed."""
    import skewpend.analysis.identify as ident

    failed = dataclasses.replace(result, status=Status.NO_CONVERGENCE, message="the data do not determine c2")
    monkeypatch.setattr(ident, "identify", lambda *args, **kwargs: failed)
    ran = run_cli(["identify", KAHEMAN, "--out", "fit.toml"], cwd=tmp_path)
    assert ran.code == 1, ran.report()
    assert ran.err.splitlines() == ["skewpend: identify: the data do not determine c2; fit.toml not written "
                                    "(the fit did not succeed)"]
    assert "base parameter" in ran.out and list(tmp_path.iterdir()) == []


def test_the_published_model_is_the_default_start():
    """--format kaheman without model options starts from the authors' model, built by the library (as
    tests/test_identify.py builds it)."""
    from test_identify import kaheman_parameters

    from skewpend.analysis.measurements import kaheman_published_parameters

    p = kaheman_published_parameters(KAHEMAN)
    assert p == kaheman_parameters()
    assert kaheman_published_parameters(KAHEMAN / "DoublePendulumDataForParameterEstimation.mat") == p


def test_free_alpha_reaches_the_fit_and_its_angle_the_table_and_the_run_file(result, tmp_path, monkeypatch):
    """--free alpha asks the fit for the skew angle (every base parameter still free), and the angle it
    returns is printed with its interval, stated in the run file's header, and is the run file's alpha.
    The fit itself is stood in for by the module's fit with an angle put in: the real one on this rig
    (about 15 s; 0 deg within its interval) is tests/test_identify.py's
    test_kaheman_skew_angle_freed_is_zero_within_its_interval."""
    import skewpend.analysis.identify as I
    from skewpend.config import Run

    asked = {}
    angle, lo, hi = math.radians(0.3), math.radians(-1.5), math.radians(2.1)

    def fit(measurements, params0, **kw):
        asked.update(kw, params0=params0)
        return dataclasses.replace(result, alpha=angle, alpha_interval=(lo, hi), alpha_note="",
                                   params=result.params.replace(alpha=angle))

    monkeypatch.setattr(I, "identify", fit)
    ran = run_cli(["identify", KAHEMAN, "--free", "alpha", "--quiet", "--out", "alpha.toml"], cwd=tmp_path)
    assert ran.code == 0, ran.report()
    assert "alpha" in asked["free"] and asked["params0"].alpha == 0.0
    m = re.search(r"skew angle alpha: (\S+) deg, 95 % interval \[(\S+), (\S+)\] deg", ran.out)
    assert m, ran.out
    assert [float(x) for x in m.groups()] == pytest.approx([0.3, -1.5, 2.1], abs=1e-3)
    text = (tmp_path / "alpha.toml").read_text()
    assert "# skew angle alpha: 0.3 deg, 95 % interval [-1.5, 2.1] deg" in text
    assert text.split("# free: ")[1].split("\n")[0].endswith("alpha")
    assert Run("simulate", str(tmp_path / "alpha.toml")).parameters().alpha == angle


@pytest.mark.parametrize("extra", [[], ["--validate", "KAHEMAN"]], ids=["own held-out pieces", "--validate"])
def test_horizon_cuts_the_held_out_pieces(result, tmp_path, monkeypatch, extra):
    """--horizon 1 hands the fit the held-out pieces cut into pieces of about 1 s (Measurements.cut, as
    the driven rig's protocol): each of the 4 Kaheman pieces of 2.66 s into 3.  The fit is stood in for
    by the module's (the cutting is what is tested); the table names the cut pieces."""
    import skewpend.analysis.identify as I
    from skewpend.analysis.measurements import Measurements

    asked = {}

    def fit(measurements, params0, **kw):
        asked.update(kw)
        v = kw["validation"]
        return dataclasses.replace(result, validation=tuple(p.name for p in v), heldout_kind=("angle",) * len(v),
                                   heldout_rms=np.full(len(v), 0.003), heldout_rms0=np.full(len(v), 0.004))

    monkeypatch.setattr(I, "identify", fit)
    argv = [str(KAHEMAN) if a == "KAHEMAN" else a for a in extra]
    ran = run_cli(["identify", KAHEMAN, *argv, "--horizon", "1", "--quiet"], cwd=tmp_path)
    assert ran.code == 0, ran.report()
    held = asked["validation"]
    whole = Measurements.from_kaheman(KAHEMAN, which="validation")
    assert len(held) == 12 and [p.name for p in held][:3] == ["Y_vad[0] [0]", "Y_vad[0] [1]", "Y_vad[0] [2]"]
    assert all(0.85 < p.duration < 0.9 for p in held)
    assert [p.name for p in held] == [p.name for p in whole.cut(1.0)]
    assert "held out Y_vad[3] [2]" in ran.out and "cut into pieces of about 1 s" in held.metadata["actions"][-1]
    assert list(tmp_path.iterdir()) == []


def test_horizon_help_shows_its_default():
    ran = run_cli(["identify", "--help"])
    assert ran.code == 0
    line = " ".join(ran.out.split())  # the help wraps its lines
    assert re.search(r"--horizon SECONDS cut every held-out piece [^-]*?\(default: whole pieces\)", line), line[:3000]


@pytest.mark.slow
def test_other_formats_from_a_skewpend_run(tmp_path):
    """A run of skewpend as CSV (with --columns) and as NetCDF (--format from the suffix), params0 from
    the options; the output-error fit recovers the model that made it."""
    pytest.importorskip("netCDF4")
    model = ["--a", "1", "--b", "0.8", "--m1", "1", "--m2", "0.7", "--alpha", "0.6", "--g", "9.81"]
    run = ["--t-end", "2", "--dt-out", "0.002", "--phi0", "0.5", "--psi0", "-0.3", "--c1", "0.01", "--c2", "0.005"]
    for out in ("run.csv", "run.nc"):
        assert run_cli(["simulate", *run, "--out", out], cwd=tmp_path).code == 0
    from skewpend.config import Run

    ran = run_cli(["identify", "run.nc", *model, "--out", "nc.toml"], cwd=tmp_path)
    assert ran.code == 0, ran.report()
    p = Run("simulate", str(tmp_path / "nc.toml")).parameters()
    assert (p.c1, p.c2) == pytest.approx((0.01, 0.005), rel=1e-4)
    ran = run_cli(["identify", "run.csv", "--columns", "t=t,phi=phi,psi=psi,dphi=dphi,dpsi=dpsi", *model,
                   "--segment", "0.25", "--out", "csv.toml"], cwd=tmp_path)
    assert ran.code == 0, ran.report()
    q = Run("simulate", str(tmp_path / "csv.toml")).parameters()
    assert np.allclose([q.c1, q.c2], [0.01, 0.005], rtol=1e-3)


def test_plot_and_report_when_the_views_have_them(tmp_path):
    """--plot and --report call the views' identification figure and page; where this installation has
    none, they are refused before any work, in one line."""
    have = {flag: importlib.util.find_spec(module) is not None for flag, module in
            (("--plot", "skewpend.views.figures.identification"), ("--report", "skewpend.views.report.identification"))}
    outputs = {"--plot": "fit.png", "--report": "fit.html"}
    for flag in [f for f in have if not have[f]]:
        before = snapshot(tmp_path)
        ran = run_cli(["identify", KAHEMAN, "--method", "linear", flag, outputs[flag]], cwd=tmp_path)
        assert_refused(ran, [flag, "this installation has no"], tmp_path, before)
    wanted = [x for f in have if have[f] for x in (f, outputs[f])]
    if wanted:
        ran = run_cli(["identify", KAHEMAN, "--method", "linear", *wanted], cwd=tmp_path)
        assert ran.code == 0, ran.report()
        for f in have:
            if have[f]:
                assert (tmp_path / outputs[f]).stat().st_size > 1000
                assert re.search(rf"^{'plot' if f == '--plot' else 'report'}\s+{re.escape(outputs[f])}$", ran.out, re.M)


# -- bad input: one line, exit status 2, nothing left behind ------------------------------------------
@pytest.mark.parametrize("args, fragments", [
    (["KAHEMAN", "--format", "foo"], ["--format", "foo"]),
    (["nowhere/kaheman2023"], ["DATA", "nowhere/kaheman2023 does not exist"]),
    (["KAHEMAN", "--validate", "nowhere.mat"], ["nowhere.mat does not exist"]),
    (["kaheman2024"], ["DATA: kaheman2024 does not exist", "kaheman2023, kaheman2023-triple, dfki-design-C.0"]),
    (["dfki-design-C.0/trajectory_99.csv"], ["trajectory_99.csv"]),
    (["KAHEMAN", "--free", "J9zz"], ["--free", "unknown name 'J9zz'"]),
    (["KAHEMAN", "--free", "alpha", "--method", "linear"], ["alpha", "output-error"]),
    (["KAHEMAN", "--segment", "-1"], ["--segment", "positive"]),
    (["KAHEMAN", "--segment", "100"], ["--segment", "60"]),
    (["KAHEMAN", "--method", "x"], ["--method", "'x'"]),
    (["run.csv", "--format", "csv"], ["(--format csv) needs --columns"]),
    (["user.csv"], ["a CSV file (--format csv) needs --columns"]),  # the format inferred from .csv
    (["run.csv"], ["params0", "--a, --b"]),  # a header t,phi,psi: skewpend's own run, read as one
    (["run.bin"], ["cannot tell how", "--format"]),
    (["run.csv", "--columns", "t=t,phi=nope,psi=psi", "--a", "1", "--b", "1", "--m1", "1", "--m2", "1", "--g", "9.8"],
     ["--columns", "no column 'nope'"]),
    (["run.csv", "--columns", "t=t,phi=phi,psi=psi", "--a", "1"], ["--b, --m1, --m2, --g", "params0"]),
    (["KAHEMAN", "--which", "all", "--format", "dfki"], ["--which goes with --format kaheman"]),
    (["KAHEMAN", "--out", "fit.txt"], ["--out", ".toml"]),
    (["KAHEMAN", "--horizon", "0"], ["--horizon", "positive"]),
    (["KAHEMAN", "--horizon", "-1"], ["--horizon", "positive"]),
    (["KAHEMAN", "--horizon", "nan"], ["--horizon"]),
    (["KAHEMAN", "--horizon", "1e9"], ["--horizon", "at most"]),
    (["KAHEMAN", "--horizon", "1e-5"], ["--horizon 1e-05", "no piece of 10 samples"]),
    (["KAHEMAN", "--which", "all", "--horizon", "1"], ["--horizon cuts the held-out pieces", "--validate"]),
    (["run.csv", "--columns", "t=t,phi=phi,psi=psi", "--a", "1", "--b", "1", "--m1", "1", "--m2", "1", "--g", "9.8",
      "--horizon", "1"], ["--horizon cuts the held-out pieces"]),
], ids=lambda v: " ".join(v) if isinstance(v, list) and v and v[0] in ("KAHEMAN", "run.csv", "user.csv", "run.bin", "nowhere/kaheman2023") else "")
def test_bad_input_is_one_line_exit_2_and_leaves_nothing(args, fragments, tmp_path):
    (tmp_path / "run.csv").write_text("t,phi,psi\n" + "".join(f"{k * 0.01},{0.1 * math.sin(k / 9)},0.0\n"
                                                                 for k in range(200)))
    (tmp_path / "user.csv").write_text((tmp_path / "run.csv").read_text().replace("t,phi,psi", "time,a,b", 1))
    (tmp_path / "run.bin").write_text("x")
    before = snapshot(tmp_path)
    argv = [str(KAHEMAN) if a == "KAHEMAN" else a for a in args]
    if "--out" not in argv:
        argv += ["--out", "fit.toml"]
    ran = run_cli(["identify", *argv], cwd=tmp_path)
    assert_refused(ran, fragments, tmp_path, before)


def test_a_shipped_data_set_is_found_by_its_name(capsys):
    """``skewpend identify kaheman2023`` (no such path here) reads the data shipped with skewpend, and says so."""
    from skewpend.cli.identify import _data_path
    from skewpend.datasets import example_data

    assert _data_path("kaheman2023", "DATA") == str(example_data("kaheman2023"))
    assert "the example data shipped with skewpend" in capsys.readouterr().err
    assert _data_path(str(KAHEMAN), "DATA") == str(KAHEMAN)  # an existing path is taken as it is


@pytest.mark.slow
def test_ctrl_c_stops_it_promptly_and_leaves_nothing(tmp_path):
    """SIGINT during the fit (a real process): exit 130, one line, no file -- and it stops in the
    stage it was sent in: the signal goes when the "output-error fit" stage line comes (an event, not
    a time: issue 36), and the fit's last stage ("held-out prediction", reached ~2 s after that line
    here, ~12 s before the end) is never said.  Hang guards only: 120 s for that line, 60 s for the
    exit (far longer than the whole fit, ~20 s here: they cannot tell a stop from an end, the stages do)."""
    proc = subprocess.Popen([*SKEWPEND, "identify", str(KAHEMAN), "--out", "fit.toml"], cwd=tmp_path,
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    guard = threading.Timer(120, proc.kill)  # a hang guard: the process killed if the stage line never comes
    guard.start()
    try:
        before = []
        for line in proc.stderr:
            before.append(line)
            if STAGE_LINE.match(line.rstrip("\n")) and "output-error fit" in line:
                break
        guard.cancel()
        assert proc.poll() is None, "".join(before)  # still fitting
        proc.send_signal(signal.SIGINT)
        out, err = proc.communicate(timeout=60)
    finally:
        guard.cancel()
        if proc.poll() is None:
            proc.kill()
            proc.communicate()
    ran = Ran.split(proc.returncode, out, "".join(before) + err)
    assert ran.code == 130 and ran.err == "skewpend: interrupted\n" and ran.out == "", ran.report()
    assert any("output-error fit" in line for line in ran.stages), ran.stages
    assert not any("held-out prediction" in line for line in ran.stages), ran.stages
    assert list(tmp_path.iterdir()) == []
