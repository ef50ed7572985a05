"""Identification tells the truth (issue 51, item 1): a status is a claim.

The recording: a rig with alpha = 35 deg (a = 0.5, b = 0.4, m1 = 0.8, m2 = 0.5, g = 9.81, thin rods)
swinging freely from (1.2, -0.8) rad for 15 s, sampled at 500 Hz, angles with 0.3 mrad of seeded
Gaussian noise.  Made by skewpend (an independent integrator run, DOP853 at its default tolerances,
against which the fit's RK4 on the data is checked), written as a user's logger would, then fitted
from wrong starting skews with alpha freed; spoiled copies must be named, never "identified".

Measured (identify.py at this commit): from 0, 10, 30 and 35 deg, alpha = 35.005 deg with the 95 %
interval [34.999, 35.012]; output error 0.292 mrad against a noise estimate of 0.299 mrad.  Before,
from 30 deg: "identified", alpha 30.6 deg [6.6, 54.5], output error 0.058 rad (200x the noise); from
10 deg: "the start model's simulation is not finite".
"""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest
from helpers import assert_refused, run_cli, snapshot

ALPHA = 35.0
NOISE = 3e-4
MODEL = ["--a", "0.5", "--b", "0.4", "--m1", "0.8", "--m2", "0.5", "--g", "9.81"]
COLUMNS = ["--columns", "t=time,phi=theta1,psi=theta2"]


def params(alpha_deg: float = ALPHA):
    import skewpend

    return skewpend.Parameters(a=0.5, b=0.4, m1=0.8, m2=0.5, alpha=math.radians(alpha_deg), g=9.81)


@pytest.fixture(scope="module")
def recording():
    """``(t, q)``: the rig's free swing, noisy angles [rad]."""
    import skewpend

    tr = skewpend.simulate(params(), (1.2, -0.8, 0.0, 0.0), 15.0, dt_out=0.002)
    assert tr.ok
    y = np.asarray(tr.y)
    q = y[:, :2] + NOISE * np.random.default_rng(1).standard_normal((len(tr.t), 2))
    return np.asarray(tr.t), q


def write(path: Path, t, a, b) -> Path:
    np.savetxt(path, np.column_stack([t, a, b]), delimiter=",", header="time,theta1,theta2", comments="")
    return path


def measurements(recording):
    from skewpend import Measurements

    t, q = recording
    return Measurements.from_arrays([{"t": t, "q": q, "name": "swing"}])


# -- the fit from wrong starting skews ---------------------------------------------------------------
@pytest.mark.parametrize("start", [0.0, 10.0, 30.0, 35.0])
def test_the_skewed_rig_is_found_from_every_starting_skew(recording, start):
    """The issue's goal: from each starting skew, 35 deg within its 95 % interval (and that interval
    under a degree wide), a success only with the output error at the noise: its mean square within
    the chi-square test of ``identify.consistency`` against the data's own noise estimate, which
    must itself be the noise put in (0.3 mrad) to within 10 % (the estimate's filter correction)."""
    from skewpend.analysis.identify import identify

    r = identify(measurements(recording), params(start), free=["alpha"], bootstrap=50)
    assert r.ok, r.message
    lo, hi = r.alpha_interval
    assert lo <= math.radians(ALPHA) <= hi and hi - lo < math.radians(1.0), (math.degrees(lo), math.degrees(hi))
    assert r.params.alpha == pytest.approx(r.alpha, abs=1e-12)
    noise, miss = r.stats["noise"], r.stats["output_error"]
    assert abs(noise / NOISE - 1) < 0.1
    assert not set(r.not_entering) & set(r.free)  # the not-entering list names no fitted entry
    if "nearest physical body" in r.message:
        # from 0 deg the estimate's slender rod lands outside the physical bodies (its two transverse
        # moments 0.15 % apart, no moment about its axis): the model returned is the nearest body, whose
        # own output error is the one tested and said (3.4 times the noise, measured)
        assert f"{miss / noise:.3g} times the data's noise" in r.message and miss <= 5 * noise, r.message
    else:  # the model is the estimate: its output error is the noise
        assert miss <= 1.05 * noise, (miss, noise)


def test_an_unusable_linear_estimate_falls_back_to_params0_and_says_so(recording):
    """At 30 deg the linear estimate (noisy accelerations in a skewed regressor) is no body; the
    output-error fit then starts from params0, and the result says so (message and settings)."""
    from skewpend.analysis.identify import identify

    r = identify(measurements(recording), params(30.0), free=["alpha"], bootstrap=0)
    assert r.ok, r.message
    assert r.settings["start"] == "params0"
    assert "started from params0" in r.message


# -- the test itself ---------------------------------------------------------------------------------
class _Segments:
    """Segments of white noise about a motion: ``q`` the measured angles, ``y0`` the start states."""

    def __init__(self, rng, S=40, L=100, h=0.004):
        t = np.arange(L + 1) * h
        self.h = h
        self.mask = np.ones((S, L + 1))
        self.y0 = np.column_stack([rng.normal(0, 1, (S, 2)), rng.normal(0, 3, (S, 2))])
        line = self.y0[:, None, :2] + t[None, :, None] * self.y0[:, None, 2:]
        self.motion = 0.5 * np.sin(7 * t)[None, :, None]  # what the dynamics add to the straight line
        self.q = line + self.motion


@pytest.mark.parametrize("factor, ok", [(1.0, True), (1.02, True), (1.5, True), (10.0, False)])  # 1.02: in the slack
def test_consistency_passes_the_noise_and_refuses_a_miss(factor, ok):
    """``consistency``: an output error at the noise (the cost n s^2, n residuals) passes, as does a
    model error within MODEL_ERROR of the motion (1.5 s beside a motion of 0.35 rad: 0.1 %, said in
    the text); ten times a noise the size of 5 % of the motion is refused."""
    from skewpend.analysis import identify as I
    from skewpend.analysis.measurements import Measurements

    rng = np.random.default_rng(3)
    seg = _Segments(rng)
    s = 0.02 if not ok else 5e-4
    t = np.arange(0, 10, 0.002)
    data = Measurements.from_arrays([{"t": t, "q": np.column_stack([np.sin(t), np.cos(t)]) + rng.normal(0, s, (len(t), 2)),
                                      "name": "x"}], skip=("mean", "tracking"))
    n = seg.mask.size * 2
    v = I.consistency(n * (factor * s) ** 2, seg, data)
    assert v.ok is ok, v
    assert abs(v.stats["noise"] / s - 1) < 0.05
    if factor <= 1.02:
        assert v.text == ""
    elif ok:
        assert "model error" in v.text
    else:
        assert "not a fit of these data" in v.text


# -- spoiled copies, alpha freed: each named with its fix, no run file ---------------------------------
def _identify(tmp_path, name, *extra):
    return run_cli(["identify", name, *COLUMNS, *MODEL, "--alpha", "30deg", "--free", "alpha", "--quiet",
                    "--out", "fit.toml", *extra], cwd=tmp_path)


@pytest.mark.parametrize("case, extra, fragments", [
    ("deg_as_rad", [], ["look like degrees", "--convention unit=deg"]),
    ("rad_as_deg", ["--convention", "unit=deg"], ["look like radians", "--convention unit=rad"]),
    ("deg_as_rad", ["--convention", "wrapped=yes"], ["look like degrees", "unit=deg"]),
    ("ms", [], ["milliseconds", "--convention time=ms"]),
])
def test_unit_mistakes_are_named_before_any_fit(recording, tmp_path, case, extra, fragments):
    """Refused on reading (exit 2, one line, nothing written): degrees read as radians are named as a
    unit mistake before the wraps they look like, radians declared as degrees too, time in ms."""
    t, q = recording
    if case == "deg_as_rad":
        write(tmp_path / "x.csv", t, np.degrees(q[:, 0]), np.degrees(q[:, 1]))
    elif case == "rad_as_deg":
        write(tmp_path / "x.csv", t, q[:, 0], q[:, 1])
    else:
        write(tmp_path / "x.csv", 1000 * t, q[:, 0], q[:, 1])
    before = snapshot(tmp_path)
    ran = _identify(tmp_path, "x.csv", *extra)
    line = assert_refused(ran, fragments, tmp_path, before)
    assert "wrapped" not in line or "wrapped=yes" in " ".join(extra)


@pytest.mark.parametrize("case, fragments", [
    ("flip", ["an encoder's sign looks flipped", "--convention sign=1:-1"]),
    ("absolute", ["the second angle looks absolute", "--convention second=absolute"]),
])
def test_convention_mistakes_are_named_with_alpha_freed(recording, tmp_path, case, fragments):
    """Alpha freed (a rig of unknown skew), from 30 deg: a flipped encoder and an absolute second angle
    end in exit 1 with the hint naming the fix, and no run file (before: "identified", a run file)."""
    t, q = recording
    b = -q[:, 1] if case == "flip" else q[:, 0] + q[:, 1]
    write(tmp_path / "x.csv", t, q[:, 0], b)
    ran = _identify(tmp_path, "x.csv")
    assert ran.code == 1, ran.report()
    hints = [line for line in ran.err.splitlines() if line.startswith("skewpend: hint:")]
    assert len(hints) == 1 and all(f in hints[0] for f in fragments), ran.report()
    assert not (tmp_path / "fit.toml").exists()
    assert "Traceback" not in ran.err


# -- the reader's refusals -----------------------------------------------------------------------------
@pytest.mark.parametrize("content, fragments", [
    ("time,theta1,theta2\n0,1,2\n0.002,oops,2\n", ["line 3", "'theta1'", "'oops' is not a number"]),
    ("time,theta1,theta2\n", ["a header line and no rows of data"]),
    ("time,theta1,theta2\n0,1,2\n0.002,1\n0.004,1,2\n", ["line 3 has 2 field(s)", "header 3"]),
])
def test_csv_refusals_name_line_and_column(tmp_path, content, fragments):
    (tmp_path / "x.csv").write_text(content)
    before = snapshot(tmp_path)
    ran = _identify(tmp_path, "x.csv")
    assert_refused(ran, fragments, tmp_path, before)


def test_a_sparse_two_gigabyte_csv_is_refused_at_once(tmp_path):
    """A file of holes: refused from its first and last bytes (not read whole: a generous bound of
    20 s where reading it took 15-50 s and ended in a traceback)."""
    import time

    path = tmp_path / "big.csv"
    with open(path, "wb") as fh:
        fh.write(b"time,theta1,theta2\n")
        fh.truncate(2 * 1024**3)
    before = snapshot(tmp_path)
    t0 = time.perf_counter()
    ran = _identify(tmp_path, "big.csv")
    assert time.perf_counter() - t0 < 20
    assert_refused(ran, ["NUL bytes", "not a text table"], tmp_path, before)


def test_an_empty_item_in_skip_is_refused(tmp_path):
    (tmp_path / "x.csv").write_text("time,theta1,theta2\n0,1,2\n")
    before = snapshot(tmp_path)
    ran = _identify(tmp_path, "x.csv", "--skip", "mean,,units")
    assert_refused(ran, ["--skip", "mean,,units"], tmp_path, before)


def test_counts_agree_with_their_nouns():
    from skewpend.analysis.identify import _count

    assert (_count(1, "piece"), _count(2, "piece"), _count(0, "piece")) == ("1 piece", "2 pieces", "0 pieces")
