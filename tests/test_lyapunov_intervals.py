"""Lyapunov error bars that cover (issue 29, item 5).

The intervals are batch means (Student's t over equal time windows) and a run is checked to have
settled (``settle_check``: the halves agree, the windows are independent).  Evidence:

* on the README's tour case (the built-in rods and start), seeded starts 1e-6 rad/(rad/s) apart
  (same energy to ~1e-5 J; independent after ~30 s, since lambda_1 ~ 0.7 1/s) measured over
  300 s: the settled runs' 95 % intervals contain the long-run value at the claimed rate;
* the tour at t_end = 100 s (the issue's 0.224 +- 0.1 against a long-run 0.69-0.71) is not
  reported as settled, in the library and in the CLI;
* the check itself, on synthetic window values: independent ones pass at about its stated
  rate, a drift or serially correlated ones fail;
* a conservative model has no Kaplan-Yorke dimension; a damped one has it.

The long-run lambda_1 of the tour case, ``REFERENCE``, was established once (not in the suite: it
takes about a minute) by two independent ensembles of the same start perturbed by 1e-6:
16 runs of 20 000 s after a 100 s transient, 4 vectors at tol 1e-10, gave 0.7058 (standard error
over the runs 0.0034); 60 runs of 3000 s gave 0.7139 (0.0033).  Their combination 0.709, with an
error taken as +-0.006 (the two differ by 1.7 of their own errors: long-memory stickiness makes
the spread over runs a slight underestimate), is 30x smaller than the intervals tested here
(half-widths ~0.2 1/s at 300 s).  The issue's "0.690 +- 0.024 at 1e4 s" is one such run.
"""

from __future__ import annotations

import json
import math
import re

import numpy as np
import pytest

from skewpend import Parameters, Status
from skewpend.analysis.lyapunov import CHECK_LEVEL, MIN_WINDOWS, lyapunov, settle_check
from skewpend.cli import main

TOUR = Parameters(a=1.0, b=0.8, m1=1.0, m2=0.7, alpha=0.6, g=9.81)  # the CLI's built-in model
TOUR_Y0 = np.array([1.2, -0.8, 0.0, 0.0])  # and its built-in start
REFERENCE = 0.709  # long-run lambda_1 of the tour case [1/s], +-0.006 (see the module)


def run_cli(capsys, *args):
    from helpers import without_stages

    with pytest.raises(SystemExit) as exc:
        main(list(args))
    out = capsys.readouterr()
    return exc.value.code, out.out, without_stages(out.err)[0]  # the stage lines (issue 36) apart


# -- (a) the intervals cover at the rate they claim -------------------------------------------------------------
@pytest.mark.slow
def test_settled_intervals_cover_the_long_run_value_at_their_rate():
    """32 seeded starts, 300 s each (10 windows of 30 s), largest exponent at tol 1e-8 (the
    statistics of a chaotic orbit do not depend on the tolerance; ~2 s in all).  Claimed: 95 %.
    Observed when this was written, over 200 such runs: 86.5 % settled, of which 94.8 % covered;
    the old +- (one standard error) covered 61.5 %.  Tolerances: with n ~ 27 settled runs and a
    true rate of 0.95, fewer than 80 % covering has probability ~0.3 % (binomial); at the old
    bar's 0.62 at least 80 % has probability ~1 %.  At least 60 % must settle (observed 86.5 %;
    fewer has probability < 0.1 %), so that the check is not passing by refusing everything."""
    rng = np.random.default_rng(2024)
    settled, covered, covered_1se = 0, 0, 0
    n = 32
    for _ in range(n):
        r = lyapunov(TOUR, TOUR_Y0 + 1e-6 * rng.standard_normal(4), t_end=300.0, n_exponents=1, rtol=1e-8,
                     atol=1e-8)
        assert r.status in (Status.SUCCESS, Status.NOT_SETTLED), r.message
        if r.ok:
            settled += 1
            err = abs(r.exponents[0] - REFERENCE)
            covered += bool(err <= r.interval[0])
            covered_1se += bool(err <= r.uncertainty[0])
    assert settled >= 0.6 * n, settled
    assert covered >= 0.8 * settled, (covered, settled)
    assert covered > covered_1se  # the t interval is the wider one, and it is the one that covers


# -- (b) the README's tour at 100 s is not a settled claim --------------------------------------------------------
def test_the_tour_at_100_s_is_not_settled_or_covers():
    """The issue: lambda_1 = 0.224 +- 0.1 at 100 s, 4.7 of its own sigmas from the long-run value.
    Either it says it has not settled or its interval covers the long-run value (it does the first:
    its ten 10-s windows are serially correlated -- the orbit sticks near an island from ~20 s)."""
    r = lyapunov(TOUR, TOUR_Y0, t_end=100.0)
    assert r.exponents[0] == pytest.approx(0.2245, abs=1e-3)  # the number: the same run
    covers = abs(r.exponents[0] - REFERENCE) <= r.interval[0]
    assert (r.status is Status.NOT_SETTLED and not r.ok) or (r.ok and covers)
    assert r.status is Status.NOT_SETTLED  # what it does today (either would be honest)
    assert r.message.startswith("lambda_1 has not settled in 100 s") and "t_end = 2000 s" in r.message
    assert "+-" not in r.table() and "not settled" in r.table()  # no error bars printed
    # the numbers are kept, with the check's statistics
    assert np.all(np.isfinite(r.exponents)) and r.stats["von_neumann_sigma"] > 1.645
    # a long run of the same start settles and covers (2000 s: ~0.5 s)
    long = lyapunov(TOUR, TOUR_Y0, t_end=2000.0, n_exponents=1)
    assert long.ok and abs(long.exponents[0] - REFERENCE) <= long.interval[0]


def test_the_cli_tour_at_100_s_prints_its_numbers_and_exits_1_with_one_line(capsys):
    code, out, err = run_cli(capsys, "lyapunov", "--t-end", "100")
    assert code == 1
    # the 100 s finite-time exponent at the CLI's rtol 1e-10: 0.224464 here; the same run at 1e-11,
    # 1e-12, 1e-13 gives 0.223737, 0.223703, 0.223709 (a chaotic motion: the method's error, not
    # rounding, sets the spread, 7.6e-4) -- allowed 2e-3 around it, printed to 6 digits
    m = re.search(r"lambda_1 = ([+-][0-9.]+) 1/s", out)
    assert m and len(m.group(1).split(".")[1]) == 6 and abs(float(m.group(1)) - 0.224464) <= 2e-3, out
    assert "+-" not in out.split("run ")[0]
    assert len(err.strip().splitlines()) == 1
    assert err.startswith("skewpend: lyapunov: lambda_1 has not settled in 100 s") and "--t-end 2000" in err
    assert "cover the time up to there" not in err  # that note is for a run that stopped early


# -- the check, on synthetic windows -----------------------------------------------------------------------------
def test_independent_windows_pass_at_about_the_stated_rate():
    """Two tests at 5 % each: independent normal windows fail one or the other 5-10 % of the time
    (exactly for the halves' t test; the von Neumann ratio's normal approximation is close at
    K = 10).  600 sets: the false-alarm rate lies in [0.04, 0.14] (binomial sd ~0.011 about 0.09)."""
    rng = np.random.default_rng(7)
    fails = sum(not settle_check(0.7 + 0.2 * rng.standard_normal((10, 1)))[0] for _ in range(600))
    assert CHECK_LEVEL == 0.05 and 0.04 <= fails / 600 <= 0.14, fails / 600


def test_a_drift_or_correlated_windows_fail():
    rng = np.random.default_rng(8)
    # a trend of 6 noise standard deviations across the run (a transient, a sticky episode): the halves
    # differ by ~5 standard errors of their difference (critical 2.26)
    drift = sum(not settle_check((0.5 + np.linspace(0, 1.2, 10) + 0.2 * rng.standard_normal(10))[:, None])[0]
                for _ in range(200))
    assert drift / 200 >= 0.9, drift
    # AR(1) with coefficient 0.9: windows far too short to be independent
    ar = 0
    for _ in range(200):
        x = np.empty(10)
        x[0] = rng.standard_normal()
        for i in range(1, 10):
            x[i] = 0.9 * x[i - 1] + math.sqrt(1 - 0.81) * rng.standard_normal()
        ar += not settle_check(0.7 + 0.2 * x[:, None])[0]
    assert ar / 200 >= 0.5, ar
    # identical windows (no spread) are settled; the message names the exponent
    assert settle_check(np.full((6, 2), 0.3))[0]
    ok, zh, zv, detail = settle_check(np.column_stack([np.linspace(0.1, 1.0, 8), np.zeros(8)]))
    assert not ok and detail.startswith("lambda_1: ") and "von Neumann ratio" in detail  # a straight line: zv ~ 2.6
    with pytest.raises(ValueError):
        settle_check(np.ones((MIN_WINDOWS - 1, 1)))


def test_exponents_near_zero_are_not_checked_but_the_largest_always_is():
    """A neutral direction's windows telescope (anticorrelated); its interval contains 0 and is
    exempt.  The largest exponent is checked even when its interval contains 0."""
    neutral = np.array([0.01, -0.012, 0.011, -0.009, 0.012, -0.01, 0.009, -0.011, 0.01, -0.01])
    steady = 0.7 + 0.05 * np.array([0.3, -1.1, 0.8, 0.1, -0.4, 1.2, -0.7, 0.2, -0.3, 0.5])
    assert settle_check(np.column_stack([steady, neutral]))[0]
    trend = np.linspace(-0.1, 0.1, 10) + 0.01 * np.array([1, -1] * 5)
    assert not settle_check(np.column_stack([trend, neutral]))[0]


# -- too few windows, early stops ---------------------------------------------------------------------------------
def test_fewer_than_4_windows_cannot_be_settled_and_an_early_stop_keeps_its_status():
    r = lyapunov(TOUR, TOUR_Y0, t_end=3.0)  # 3 renormalisations: 3 windows
    assert r.status is Status.NOT_SETTLED and "at least 4" in r.message and not r.ok
    r = lyapunov(TOUR, TOUR_Y0, t_end=40.0, windows=3, n_exponents=1)
    assert r.status is Status.NOT_SETTLED and "3 windows" in r.message
    assert np.all(np.isfinite(r.interval))  # an interval is still computed (2+ windows) ...
    assert "+-" not in r.table()  # ... but not printed as settled
    # throw=True raises for a failed integration, never for an unsettled estimate
    assert lyapunov(TOUR, TOUR_Y0, t_end=3.0, throw=True).status is Status.NOT_SETTLED
    stopped = lyapunov(TOUR, TOUR_Y0, t_end=50.0, max_steps=300)
    assert stopped.status is Status.MAX_STEPS and math.isnan(stopped.stats["halves_sigma"])


# -- (c) the Kaplan-Yorke dimension: only where volume contracts ------------------------------------------------
def test_a_conservative_model_has_no_kaplan_yorke_dimension(capsys):
    r = lyapunov(TOUR, TOUR_Y0, t_end=40.0)
    assert r.conservative and math.isnan(r.kaplan_yorke_dimension)
    assert "not meaningful for a conservative system" in r.table()
    assert json.loads(json.dumps(r.to_dict(), allow_nan=False))["kaplan_yorke_dimension"] is None
    code, out, _ = run_cli(capsys, "lyapunov", "--t-end", "40")
    assert "Kaplan-Yorke dimension: not meaningful" in out
    assert not any(line.startswith("Kaplan-Yorke dimension ") and line[23:24].isdigit() for line in out.splitlines())


def test_a_damped_model_has_its_kaplan_yorke_dimension():
    damped = Parameters(a=1.0, b=0.8, m1=1.0, m2=0.7, alpha=0.6, g=9.81, c1=0.01)
    r = lyapunov(damped, TOUR_Y0, t_end=60.0)
    assert not r.conservative
    lam = np.sort(r.exponents)[::-1]
    part = np.cumsum(lam)
    j = int(np.count_nonzero(part >= 0))
    expected = 0.0 if j == 0 else (4.0 if j == 4 else j + part[j - 1] / abs(lam[j]))
    assert r.kaplan_yorke_dimension == pytest.approx(expected, rel=1e-12)
    assert f"Kaplan-Yorke dimension {expected:.4f}" in r.table()
    assert math.isnan(lyapunov(damped, TOUR_Y0, t_end=20.0, n_exponents=2).kaplan_yorke_dimension)  # not the full spectrum
