"""Identification from one recording (issue 36): the intervals' clusters are blocks of the one piece,
never a zero-width interval; too little data gives no interval, with the reason; the table says what
the intervals were computed from and never calls a parameter the user held "undetermined"."""

from __future__ import annotations

import math
import sys
from pathlib import Path

import numpy as np
import pytest

import skewpend
from skewpend import Measurements
from skewpend.analysis.identify import BLOCK, CLUSTER_PIECES, MIN_CLUSTERS, clusters, identify
from skewpend.analysis.measurements import Piece
from skewpend.status import Status

sys.path.insert(0, str(Path(__file__).resolve().parent))
from test_identify import chi2_bound, kaheman_parameters  # noqa: E402

ALPHA = math.radians(20.0)
NOISE = 5e-4


# -- the clusters ------------------------------------------------------------------------------------------
def test_many_pieces_are_their_own_clusters():
    piece = np.repeat(np.arange(CLUSTER_PIECES), 7)
    t = np.tile(np.linspace(0, 3, 7), CLUSTER_PIECES)
    cl, n, text = clusters(piece, t, [(0.0, 3.0)] * CLUSTER_PIECES)
    assert n == CLUSTER_PIECES and np.array_equal(cl, piece) and text == f"{CLUSTER_PIECES} pieces"


def test_one_long_piece_is_cut_into_blocks_of_consecutive_items():
    """20 s, items every 0.5 s (shooting segments): floor(20 / BLOCK) blocks of equal length, each a run
    of consecutive items, numbered in time order."""
    t = np.arange(0, 20.0, 0.5)
    cl, n, text = clusters(np.zeros(len(t), int), t, [(0.0, 20.0)])
    assert n == math.floor(20.0 / BLOCK) == 10
    assert np.all(np.diff(cl) >= 0) and cl[0] == 0 and cl[-1] == n - 1
    assert np.array_equal(np.bincount(cl), np.full(n, len(t) // n))  # 4 segments a block
    assert "10 blocks of about 2 s" in text and "the one piece" in text


def test_few_pieces_are_cut_each_and_numbered_apart():
    t = np.concatenate([np.arange(0, 6.0, 0.5), np.arange(0, 4.0, 0.5)])
    piece = np.array([0] * 12 + [1] * 8)
    cl, n, _ = clusters(piece, t, [(0.0, 6.0), (0.0, 4.0)])
    assert n == 3 + 2
    assert set(cl[piece == 0]) == {0, 1, 2} and set(cl[piece == 1]) == {3, 4}


def test_a_short_piece_is_one_cluster():
    cl, n, _ = clusters(np.zeros(3, int), np.array([0.0, 0.5, 1.0]), [(0.0, 1.5)])
    assert n == 1 and np.all(cl == 0)


# -- one recording ---------------------------------------------------------------------------------------
def _one_recording(seconds: float, seed: int, alpha: float = ALPHA):
    truth = kaheman_parameters(alpha=alpha)
    # rtol 1e-12 (Taylor order 15, the library the Kaheman fits load; 1e-11 took order 16, built for this alone)
    tr = skewpend.simulate(truth, (1.2, -0.8, 0.0, 0.5), seconds, dt_out=1e-3, rtol=1e-12, atol=1e-12)
    rng = np.random.default_rng(seed)
    q = np.asarray(tr.y)[:, :2] + rng.normal(0, NOISE, (len(tr.t), 2))
    return truth, Measurements([Piece(t=np.asarray(tr.t), q=q, name="one")])


def test_too_short_a_recording_has_no_interval_and_says_why():
    """6 s in one piece: 3 blocks, fewer than MIN_CLUSTERS: the estimate is reported with no interval,
    the message and the table say why and how much data would do."""
    truth, M = _one_recording(6.0, 0, alpha=0.0)
    r = identify(M, truth, method="linear")
    assert r.ok, r.message
    assert np.all(np.isnan(r.intervals[[j for j, n in enumerate(r.names) if n != r.reference]]))
    assert "95 % intervals not available" in r.message and f"at least {MIN_CLUSTERS} needed" in r.message
    assert f"{MIN_CLUSTERS * BLOCK:g} s" in r.message
    table = r.table()
    assert "(not available)" in table and "[" not in table.split("ratios")[1].splitlines()[1]
    assert "nan" not in table.lower()


def test_a_long_recording_gets_intervals_over_its_blocks():
    """20 s in one piece, the linear estimate: 10 blocks, every free interval of positive width."""
    truth, M = _one_recording(20.0, 0, alpha=0.0)
    r = identify(M, truth, method="linear")
    assert r.ok, r.message
    free = [j for j, n in enumerate(r.names) if n != r.reference]
    widths = r.intervals[free, 1] - r.intervals[free, 0]
    assert np.all(np.isfinite(widths)) and np.all(widths > 0)
    assert "cluster-robust over 10 blocks of about 2 s" in r.table()


@pytest.mark.slow
def test_one_recording_skew_angle_intervals_cover_the_truth():
    """The issue's rig: alpha = 20 deg, one free swing of 20 s at 1 kHz, noise 0.5 mrad, fitted with
    alpha free from params0 at alpha = 0 (the profile, then the fit with alpha free); the sandwich over
    the recording's 10 blocks of 2 s (t quantile at 9 degrees of freedom).  Before issue 36 every
    interval had zero width here.  bench_identify.py --only onefile runs 20 seeds through the CLI;
    here four seeds: each interval has a positive width below 1 deg and covers 20 deg (the chance
    that a correct 95 % interval misses in at least one of four is 19 %: the seeds are fixed and were
    checked; a miss would be a change of the method, to be judged against the benchmark's 20).  The
    model returned misses the angles by the noise (identify.consistency's chi-square test)."""
    for seed in range(4):
        truth, M = _one_recording(20.0, seed)
        r = identify(M, kaheman_parameters(), free=["alpha"], bootstrap=50, seed=seed)
        assert r.status is Status.SUCCESS, r.message
        lo, hi = r.alpha_interval
        assert 0 < hi - lo < math.radians(1.0), (seed, lo, hi)
        assert lo <= ALPHA <= hi, (seed, math.degrees(lo), math.degrees(hi))
        assert r.intervals_note.startswith("clusters: 10 blocks")
        # the profile's minimum is the estimate (the fit's own point is in it; mirrored: alpha0 = 0)
        k = int(np.argmin(r.profile_cost))
        assert abs(r.profile_alpha[k]) == pytest.approx(r.alpha, abs=1e-12)
        # the model returned misses the angles by the noise (chi-square test; measured 0.98-1.00 times: a
        # fit over physical bodies where the estimate is none or on the mirror side; before, up to 2.4 times)
        assert r.stats["output_error"] <= chi2_bound(r.stats["residuals"]) * r.stats["noise"], (seed, r.message)
