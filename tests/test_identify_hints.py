"""Bad data at ``skewpend identify`` (issue 36): each kind of mistake in the issue's list gets one line
naming the data problem and its fix in the command line's spelling, exit 2 (refused) or 1 (a fit that
did not succeed, with the hint); every action on the data is a line on stderr; ``--cut``, ``--skip``,
``--nonfinite``, ``--short``.  The data are made by skewpend: a skewed rig (alpha = 20 deg) swinging
freely for 4 s, sampled at 500 Hz with 0.5 mrad of seeded noise, written as CSV the way a user's
logger might get it wrong.  The hints' own checks are tested in Python too (``skewpend.analysis.hints``).
"""

from __future__ import annotations

import math
import re
from pathlib import Path

import numpy as np
import pytest
from helpers import assert_refused, run_cli, snapshot

from skewpend.analysis.measurements import Convention, Measurements
from skewpend.errors import ParameterError

ALPHA = 20.0
MODEL = ["--a", "0.2", "--b", "0.25", "--m1", "0.3", "--m2", "0.25", "--alpha", f"{ALPHA}deg", "--g", "9.81"]
COLUMNS = ["--columns", "t=time,phi=th1,psi=th2"]
#: What a message on the command line must not say: the Python spellings.
PYTHON_SPELLING = re.compile(r"Convention\(|skip=\(|short='|nonfinite=|raise nonfinite\b|method='")


def params():
    import skewpend

    return skewpend.Parameters(a=0.2, b=0.25, m1=0.3, m2=0.25, alpha=math.radians(ALPHA), g=9.81, c1=0.002, c2=0.001)


@pytest.fixture(scope="module")
def swing():
    """``(t, q, dq)``: the rig's free swing from phi = 1, psi = -0.6 rad, 4 s at 500 Hz, noisy angles."""
    import skewpend

    tr = skewpend.simulate(params(), (1.0, -0.6, 0.0, 0.0), 4.0, dt_out=0.002)
    y = np.asarray(tr.y)
    q = y[:, :2] + 5e-4 * np.random.default_rng(0).standard_normal((len(tr.t), 2))
    return np.asarray(tr.t), q, y[:, 2:]


def write(path: Path, t, **cols) -> Path:
    names = list(cols)
    np.savetxt(path, np.column_stack([t] + [cols[k] for k in names]), delimiter=",",
               header=",".join(["time"] + names), comments="")
    return path


def identify(tmp_path, name, *extra):
    return run_cli(["identify", name, *COLUMNS, *MODEL, "--method", "linear", "--quiet", *extra], cwd=tmp_path)


def hint_lines(ran):
    return [line for line in ran.err.splitlines() if line.startswith("skewpend: hint:")]


def assert_fit_failed_with_hint(ran, *fragments):
    """Exit 1: the hint lines, the table on stdout, and the failure's one line last."""
    assert ran.code == 1, ran.report()
    hints = hint_lines(ran)
    assert len(hints) == 1, ran.report()
    for f in fragments:
        assert f in hints[0], (f, ran.report())
    assert not PYTHON_SPELLING.search(ran.err), ran.report()
    assert ran.err.splitlines()[-1].startswith("skewpend: identify: "), ran.report()
    assert "base parameter" in ran.out and "Traceback" not in ran.err


# -- the mistakes the fit shows: exit 1 with the hint -------------------------------------------------
@pytest.mark.slow
def test_a_flipped_encoder_sign_is_named(swing, tmp_path):
    t, q, _ = swing
    write(tmp_path / "flip.csv", t, th1=q[:, 0], th2=-q[:, 1])
    ran = identify(tmp_path, "flip.csv")
    assert_fit_failed_with_hint(ran, "an encoder's sign looks flipped", "--convention sign=1:-1",
                                "--convention sign=-1:1")


@pytest.mark.slow
def test_an_absolute_second_angle_declared_relative_is_named(swing, tmp_path):
    t, q, _ = swing
    write(tmp_path / "abs.csv", t, th1=q[:, 0], th2=q[:, 0] + q[:, 1])
    ran = identify(tmp_path, "abs.csv")
    assert_fit_failed_with_hint(ran, "the second angle looks absolute", "--convention second=absolute")


@pytest.mark.slow
def test_a_relative_second_angle_declared_absolute_is_named(swing, tmp_path):
    """The reverse, with the user's other convention keys kept in the fix (degrees here)."""
    t, q, _ = swing
    d = np.degrees(q)
    write(tmp_path / "rel.csv", t, th1=d[:, 0], th2=d[:, 1])
    ran = identify(tmp_path, "rel.csv", "--convention", "second=absolute,unit=deg")
    assert_fit_failed_with_hint(ran, "the second angle looks relative", "--convention unit=deg")


@pytest.mark.slow  # 0.1 s after another fit, 13 s alone (the base regressor's derivation)
def test_far_too_short_data_say_how_long_is_needed(swing, tmp_path):
    t, q, _ = swing
    keep = t <= 0.2
    write(tmp_path / "short.csv", t[keep], th1=q[keep, 0], th2=q[keep, 1])
    ran = identify(tmp_path, "short.csv")
    assert_fit_failed_with_hint(ran, "far too short", "0.2 s in all", "record at least 3.3 s")


@pytest.mark.slow
def test_right_data_get_no_hint_naming_a_mistake(swing, tmp_path):
    """The linear estimate alone lands just outside the physical bodies on these noisy data (a damping
    a little below 0): the checks run and find nothing -- no false alarm."""
    t, q, _ = swing
    write(tmp_path / "ok.csv", t, th1=q[:, 0], th2=q[:, 1])
    ran = identify(tmp_path, "ok.csv")
    assert ran.code in (0, 1), ran.report()
    assert not any("looks" in line or "too short" in line for line in hint_lines(ran)), ran.report()


# -- refused before the fit: exit 2, one line --------------------------------------------------------
@pytest.mark.slow  # 3-4 s alone: the first linear matrices of params0's geometry
def test_time_in_milliseconds_is_refused_naming_the_unit(swing, tmp_path):
    t, q, _ = swing
    write(tmp_path / "ms.csv", t * 1000, th1=q[:, 0], th2=q[:, 1])
    before = snapshot(tmp_path)
    ran = identify(tmp_path, "ms.csv", "--out", "fit.toml")
    assert_refused(ran, ["the times look in milliseconds", "--convention time=ms", "median time step is 2 s"],
                   tmp_path, before)


@pytest.mark.parametrize("case, fragments", [
    ("wrapped", ["look wrapped into one turn", "--convention wrapped=yes"]),
    ("degrees", ["look like degrees", "--convention unit=deg", "--skip units"]),
    ("speed sign", ["dphi runs against phi's rate", "--columns", "--skip velocities"]),
    ("speed column", ["dpsi does not follow psi's rate", "--skip velocities"]),
    ("speed unit", [re.compile(r"dphi is 5\d\.\d times phi's rate"), "check --columns", "--skip velocities"]),
    ("nan", ["3 of 2001 rows hold NaN or inf", "--nonfinite 0 allows", "raise --nonfinite"]),
    ("upright", ["zero upright", "--convention zero=upright", "--skip mean"]),
    ("tracking", ["psi follows phi", "--convention second=absolute", "--skip tracking"]),
])
def test_reader_refusals_name_the_command_lines_spelling(swing, tmp_path, case, fragments):
    t, q, dq = swing
    speeds = ["--columns", "t=time,phi=th1,psi=th2,dphi=w1,dpsi=w2"]
    cols, extra = dict(th1=q[:, 0], th2=q[:, 1]), []
    if case == "wrapped":
        cols["th1"] = np.mod(4 * q[:, 0] + math.pi, 2 * math.pi) - math.pi
    elif case == "degrees":
        cols = dict(th1=np.degrees(q[:, 0]), th2=np.degrees(q[:, 1]))
    elif case.startswith("speed"):
        w1, w2 = dq[:, 0], dq[:, 1]
        w1, w2 = {"speed sign": (-w1, w2), "speed column": (w1, np.std(w2) * np.random.default_rng(1).standard_normal(len(w2))),
                  "speed unit": (np.degrees(w1), w2)}[case]
        cols.update(w1=w1, w2=w2)
        extra = speeds
    elif case == "nan":
        cols["th1"] = cols["th1"].copy()
        cols["th1"][[5, 50, 500]] = np.nan
        extra = ["--nonfinite", "0"]
    elif case == "upright":
        cols["th1"] = q[:, 0] + math.pi
    elif case == "tracking":
        cols = dict(th1=q[:, 0], th2=1.05 * q[:, 0] + 0.01 * q[:, 1])
    write(tmp_path / "data.csv", t, **cols)
    before = snapshot(tmp_path)
    ran = run_cli(["identify", "data.csv", *(extra if "--columns" in extra else COLUMNS + extra), *MODEL,
                   "--quiet", "--out", "fit.toml"], cwd=tmp_path)
    line = assert_refused(ran, fragments, tmp_path, before)
    assert not PYTHON_SPELLING.search(line), line


@pytest.mark.parametrize("args, fragments", [
    (["--skip", "nothing"], ["--skip", "mean, tracking, velocities, units"]),
    (["--skip", ","], ["--skip"]),
    (["--nonfinite", "1"], ["--nonfinite", "up to (not including) 1"]),
    (["--nonfinite", "-0.1"], ["--nonfinite", "non-negative"]),
    (["--short", "keep"], ["--short", "refuse or drop"]),
    (["--cut", "0"], ["--cut", "positive"]),
    (["--cut", "1e-5"], ["--cut 1e-05", "no piece of 10 samples"]),
    (["--convention", "time=h"], ["--convention", "time= must be one of 's', 'ms', 'us'"]),
    (["--params0", "nowhere.yml"], ["--params0", "nowhere.yml does not exist"]),
    (["--params0", "model.toml"], ["--params0", "FILE.yml"]),
    (["--params0", "lab.yml", "--config", "run.toml"], ["--params0 and --config both give params0"]),
    (["--out", "fit.yml", "--free", "alpha"], ["--out fit.yml", "planar", "alpha"]),
    (["--out", "fit.yml"], ["--out fit.yml", "params0", "planar", "alpha = 20 deg"]),
])
def test_the_new_options_refuse_bad_values_in_one_line(swing, tmp_path, args, fragments):
    t, q, _ = swing
    write(tmp_path / "ok.csv", t, th1=q[:, 0], th2=q[:, 1])
    (tmp_path / "run.toml").write_text("[parameters]\na = 0.2\n")
    (tmp_path / "model.toml").write_text("[parameters]\na = 0.2\n")
    lab = Path(__file__).resolve().parent.parent / "data" / "dfki-design-C.0" / "model_h1.0_parameters.yml"
    (tmp_path / "lab.yml").write_text(lab.read_text())
    before = snapshot(tmp_path)
    ran = identify(tmp_path, "ok.csv", *args)
    assert_refused(ran, fragments, tmp_path, before)


# -- every action on the data is a line on stderr -----------------------------------------------------
def test_dropped_rows_and_cut_pieces_are_said_on_stderr(swing, tmp_path, monkeypatch):
    """NaN rows dropped and --cut's pieces: each a line on stderr; the fit gets the pieces cut to about
    1 s (the fit is stood in for: what it is handed is tested)."""
    import skewpend.analysis.identify as I
    from skewpend import Status
    from skewpend.analysis.identify import Identification

    t, q, _ = swing
    th1 = q[:, 0].copy()
    th1[[5, 50, 500]] = np.nan
    write(tmp_path / "nan.csv", t, th1=th1, th2=q[:, 1])
    handed = {}

    def fit(measurements, params0, **kw):
        handed["m"] = measurements
        return Identification(params=params0, params0=params0, status=Status.SUCCESS, message="stood in",
                              settings={})

    monkeypatch.setattr(I, "identify", fit)
    ran = identify(tmp_path, "nan.csv", "--cut", "1")
    assert ran.code == 0, ran.report()
    assert "skewpend: data: nan.csv: nan: dropped 3 of 2001 rows holding NaN or inf" in ran.err.splitlines()
    assert "skewpend: data: cut into pieces of about 1 s" in ran.err.splitlines()
    m = handed["m"]
    assert len(m) == 4 and all(0.95 < p.duration < 1.05 for p in m)
    assert m.samples == 2001 - 3 + 3  # neighbours share their boundary sample


def test_short_drop_and_skip_reach_the_readers(swing, tmp_path, monkeypatch):
    """--short drop drops a piece of fewer than 10 samples after a gap (said on stderr); --skip units
    lets degrees declared radians through (said, as the check the user turned off)."""
    import skewpend.analysis.identify as I
    from skewpend import Status
    from skewpend.analysis.identify import Identification

    t, q, _ = swing
    tt = np.concatenate([t, t[-1] + 1.0 + 0.002 * np.arange(5)])  # 5 samples after a 1 s gap
    qq = np.vstack([q, q[-5:]])
    write(tmp_path / "gap.csv", tt, th1=qq[:, 0], th2=qq[:, 1])
    handed = {}

    def fit(measurements, params0, **kw):
        handed["m"] = measurements
        return Identification(params=params0, params0=params0, status=Status.SUCCESS, message="stood in",
                              settings={})

    monkeypatch.setattr(I, "identify", fit)
    ran = identify(tmp_path, "gap.csv")
    line = assert_refused(ran, ["fewer than 10", "--short drop"])
    assert not PYTHON_SPELLING.search(line)
    ran = identify(tmp_path, "gap.csv", "--short", "drop", "--skip", "units,mean")
    assert ran.code == 0, ran.report()
    assert any("gap part 2: dropped, 5 samples" in line for line in ran.err.splitlines()), ran.err
    assert len(handed["m"]) == 1 and handed["m"].metadata["checks"]["skip"] == ("units", "mean")


# -- the hints' checks, in Python ----------------------------------------------------------------------
@pytest.mark.slow
def test_diagnose_names_each_convention_mistake_in_pythons_spelling(swing):
    """The checks behind the hints, on the data re-read three wrong ways and the right one: each
    mistake named with the Python fix, the right data with none."""
    from skewpend.analysis.hints import diagnose

    t, q, _ = swing
    p0 = params().replace(c1=0.0, c2=0.0)
    cases = [(q, Convention(), None),
             (q * [1, -1], Convention(), "Convention(sign=(1, -1)) (or Convention(sign=(-1, 1))"),
             (q * [-1, 1], Convention(), "Convention(sign=(1, -1))"),
             (np.column_stack([q[:, 0], q.sum(axis=1)]), Convention(), "Convention(second='absolute')"),
             (q, Convention(second="absolute"), "Convention()")]
    for qq, conv, fix in cases:
        m = Measurements.from_arrays([{"t": t, "q": qq}], convention=conv, skip=("tracking", "mean"))
        found = diagnose(m, p0)
        if fix is None:
            assert found == [], found
        else:
            assert len(found) == 1 and f"state {fix}" in found[0], (fix, found)


def test_check_sampling_names_the_time_unit(swing):
    from skewpend.analysis.hints import check_sampling

    t, q, _ = swing
    p0 = params()
    check_sampling(Measurements.from_arrays([{"t": t, "q": q}]), p0)  # seconds: passes
    for scale, says in ((1e3, "look in milliseconds (steps of 0.002 s then); state Convention(time='ms')"),
                        (1e6, "look in microseconds (steps of 0.002 s then); state Convention(time='us')")):
        with pytest.raises(ParameterError, match=re.escape(says)):
            check_sampling(Measurements.from_arrays([{"t": t * scale, "q": q}]), p0)
        m = Measurements.from_arrays([{"t": t * scale, "q": q}], convention=Convention(time="ms" if scale == 1e3 else "us"))
        assert np.allclose(m[0].t, t, rtol=1e-12, atol=0)
        check_sampling(m, p0)
    coarse = Measurements.from_arrays([{"t": t[::200], "q": q[::200]}])  # 0.4 s steps: no unit makes it right
    with pytest.raises(ParameterError, match="too coarse to identify"):
        check_sampling(coarse, p0)


@pytest.mark.parametrize("conv", [Convention(), Convention(second="absolute", unit="deg"),
                                  Convention(sign=(1, -1), wrapped=True, time="ms"),
                                  Convention(zero="upright", sign=(-1, -1), second="absolute"),
                                  Convention(sign=(1, -1, 1), second="absolute"), Convention(sign=(1, 1, 1, -1))])
def test_the_spelled_conventions_are_what_the_command_line_reads(conv):
    """spell_convention(..., "cli") is --convention's own syntax: parsed back, the same Convention;
    the Python spelling evaluates to it too."""
    from skewpend.analysis.hints import spell_convention
    from skewpend.cli.identify import _convention

    text = spell_convention(conv, "cli")
    assert text.startswith("--convention ")
    assert _convention(text[len("--convention "):]) == conv
    assert eval(spell_convention(conv), {"Convention": Convention}) == conv


def test_every_python_spelling_of_the_readers_has_the_command_lines():
    """Each refusal of the readers that names a Python spelling, mapped for the command line, names
    none (cli_message); the user's other convention keys are kept in the fix."""
    from skewpend.cli.identify import cli_message

    t = np.linspace(0, 2, 401)
    phi, psi = 0.3 * np.sin(6 * t), 0.2 * np.sin(11 * t)
    base = {"t": t, "q": np.column_stack([phi, psi])}
    cases = [
        (dict(base, q=np.column_stack([np.mod(12 * phi + math.pi, 2 * math.pi) - math.pi, psi])), {}),
        (dict(base, q=np.degrees(base["q"])), {}),
        (dict(base, q=base["q"] + [math.pi, 0]), {}),
        (dict(base, q=base["q"] + [0, math.pi]), {}),
        (dict(base, q=np.column_stack([phi, 1.05 * phi])), {}),
        (dict(base, dq=np.column_stack([-6 * 0.3 * np.cos(6 * t), 11 * 0.2 * np.cos(11 * t)])), {}),
        (dict(base, dq=np.column_stack([6 * 0.3 * np.cos(6 * t), np.random.default_rng(1).standard_normal(401)])), {}),
        (dict(base, dq=np.column_stack([600 * 0.3 * np.cos(6 * t), 11 * 0.2 * np.cos(11 * t)])), {}),
        (dict(base, q=np.where(np.arange(401)[:, None] < 40, np.nan, base["q"])), {}),
        ({"t": np.concatenate([t, [5.0, 5.001]]), "q": np.vstack([base["q"], [[0, 0], [0.1, 0.1]]])}, {}),
    ]
    seen = set()
    for raw, kw in cases:
        with pytest.raises(ParameterError) as info:
            Measurements.from_arrays(raw, **kw)
        text = str(info.value)
        found = PYTHON_SPELLING.findall(text)
        assert found, text  # each of these names a Python spelling
        seen.update(found)
        mapped = cli_message(text)
        assert not PYTHON_SPELLING.search(mapped), mapped
        assert "--" in mapped, mapped
    assert {"Convention(", "skip=(", "short='", "nonfinite=", "raise nonfinite"} <= seen
    wrapped = cli_message("state Convention(wrapped=True)", Convention(unit="deg", second="absolute"))
    assert wrapped == "state --convention second=absolute,unit=deg,wrapped=yes"


def test_suspect_says_why_a_fit_looks_wrong(swing):
    """The triggers of the checks: a status that is not success, a held-out prediction worse than
    params0's, an output error above a tenth of the angles' spread or ten times their noise (0.5 mrad
    here, estimated within 30 %); a good fit gives None."""
    import dataclasses

    from skewpend import Status
    from skewpend.analysis.hints import noise_level, suspect
    from skewpend.analysis.identify import Identification

    t, q, _ = swing
    m = Measurements.from_arrays([{"t": t, "q": q}], skip=("tracking", "mean"))
    assert 0.7 * 5e-4 < noise_level(m) < 1.3 * 5e-4
    p = params()
    good = Identification(params=p, params0=p, status=Status.SUCCESS, message="ok", settings={},
                          fit_rms=np.array([5.5e-4]), validation=("v",), heldout_kind=("angle",),
                          heldout_rms=np.array([0.01]), heldout_rms0=np.array([0.02]))
    assert suspect(good, m) is None
    cases = [(dict(status=Status.NO_CONVERGENCE, message="the estimate is not physical"), "not physical"),
             (dict(heldout_rms=np.array([0.03])), "worse than params0's"),
             (dict(fit_rms=np.array([0.2])), "more than a tenth of their spread"),
             (dict(fit_rms=np.array([0.018])), "times their noise")]
    for change, says in cases:
        assert says in suspect(dataclasses.replace(good, **change), m), change


# -- a chain of three: the fastest of its three modes -------------------------------------------------
def _planar_triple():
    """A planar chain of three thin uniform rods, and its three periods about hanging computed here from
    the textbook's linearisation in absolute angles (rod i's angle from the vertical): ``M_ij = m_j l_i
    l_j / 2 + sum_{k>j} m_k l_i l_j`` (i < j), ``M_ii = m_i l_i^2 / 3 + sum_{k>i} m_k l_i^2``, ``K`` diagonal
    ``g (m_i l_i / 2 + sum_{k>i} m_k l_i)`` -- the relative angles' matrices are congruent to these, the
    periods the same."""
    from skewpend.symbolic.chain import Chain

    m, length, g = np.array([0.3, 0.25, 0.1]), np.array([0.2, 0.25, 0.12]), 9.81
    M, K = np.zeros((3, 3)), np.zeros((3, 3))
    for i in range(3):
        below = m[i + 1:].sum()
        M[i, i] = m[i] * length[i] ** 2 / 3 + below * length[i] ** 2
        K[i, i] = g * (m[i] * length[i] / 2 + below * length[i])
        for j in range(i + 1, 3):
            M[i, j] = M[j, i] = (m[j] / 2 + m[j + 1:].sum()) * length[i] * length[j]
    w2 = np.sort(np.linalg.eigvals(np.linalg.solve(M, K)).real)
    return Chain.from_lists(3, mass=list(m), length=list(length), g=g), 2 * np.pi / np.sqrt(w2)


def test_mode_periods_of_a_chain_of_three_are_its_three_slowest_first():
    from skewpend.analysis.hints import mode_periods
    from skewpend.analysis.modes import normal_modes

    chain, periods = _planar_triple()
    got = mode_periods(chain)
    assert len(got) == 3
    np.testing.assert_allclose(got, periods, rtol=1e-9)
    np.testing.assert_allclose(got, normal_modes(chain).periods, rtol=1e-9)
    assert periods[2] < 0.8 * periods[1]  # the third mode is the fastest by far: the second's would not do


def test_check_sampling_of_a_chain_of_three_counts_the_fastest_mode():
    """Steps fine for the slower two modes but fewer than four a swing of the third: refused, naming the
    third mode's period; steps of a fifth of it pass.  The time-unit hint reads the fastest mode too."""
    from skewpend.analysis.hints import SAMPLES_PER_SWING, check_sampling

    chain, periods = _planar_triple()
    fast, middle = periods[2], periods[1]

    def data(dt, seconds=60.0):
        t = np.arange(0.0, seconds, dt)
        q = np.column_stack([0.2 * np.sin(2 * np.pi * t / periods[k]) for k in range(3)])
        return Measurements.from_arrays([{"t": t, "q": q}], skip=("tracking", "mean", "units"))

    dt = 0.5 * (fast + middle) / SAMPLES_PER_SWING  # 4+ samples a swing of mode 2, under 4 of mode 3
    assert middle / dt > SAMPLES_PER_SWING > fast / dt
    with pytest.raises(ParameterError, match=re.escape(f"per swing of params0's fastest mode ({fast:.3g} s)")):
        check_sampling(data(dt), chain)
    check_sampling(data(fast / 5), chain)
    with pytest.raises(ParameterError, match=re.escape("the times look in milliseconds")):
        check_sampling(Measurements.from_arrays([{"t": np.arange(0.0, 20.0, fast / 40) * 1e3,
                                                  "q": data(fast / 40, 20.0)[0].q}],
                                                skip=("tracking", "mean", "units")), chain)


@pytest.mark.slow  # about 12 s: five inverse-dynamics fits of a chain of three a case (its kernels cached)
def test_diagnose_names_the_flipped_joint_of_a_chain_of_three():
    """A skewed chain of three swinging freely (4 s at 500 Hz, 0.5 mrad of noise): its data with joint 3's
    sign flipped name joint 3 (q3) with both spellings, the mirror's too; joint 1's flipped name joint 1 (on
    the command line's spelling, which reads back); the right data name nothing."""
    import skewpend
    from skewpend.analysis.hints import diagnose
    from skewpend.cli.identify import _convention
    from skewpend.symbolic.chain import Chain

    chain = Chain.from_lists(3, axis=[(0, 0, 1), (0.3, 0, 1), (0, 0, 1)], mass=[0.3, 0.25, 0.1],
                             length=[0.2, 0.25, 0.12], damping=[1e-3, 1e-3, 3e-4])
    # DOP853 (its error far below the noise): no Taylor library built for this chain alone
    tr = skewpend.simulate(chain, (1.0, -0.6, 0.8, 0.0, 0.0, 0.0), 4.0, dt_out=0.002, method="dop853")
    t, y = np.asarray(tr.t), np.asarray(tr.y)
    q = y[:, :3] + 5e-4 * np.random.default_rng(0).standard_normal((len(t), 3))

    def found(flip, **kw):
        m = Measurements.from_arrays([{"t": t, "q": q * flip}], skip=("tracking", "mean"))
        return diagnose(m, chain, **kw)

    assert found([1, 1, 1]) == []
    hints = found([1, 1, -1])
    assert len(hints) == 1 and hints[0].startswith("the sign of q3 (joint 3) looks flipped"), hints
    assert "state Convention(sign=(1, 1, -1)) (or Convention(sign=(-1, -1, 1)): the mirror image" in hints[0], hints
    hints = found([-1, 1, 1], interface="cli")
    assert len(hints) == 1 and hints[0].startswith("the sign of q1 (joint 1) looks flipped"), hints
    fix = re.search(r"state --convention (\S+)", hints[0]).group(1)
    assert _convention(fix) == Convention(sign=(-1, 1, 1)), hints
