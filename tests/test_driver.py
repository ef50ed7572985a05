"""The one resumable C-call loop (skewpend.numeric.driver), driven by fake compiled functions."""

from __future__ import annotations

import threading
import time
from types import SimpleNamespace

import pytest

from skewpend.errors import ParameterError
from skewpend.numeric.driver import CHUNK_SECONDS, check_step_estimate, drive
from skewpend.numeric.ensemble import Cancelled
from skewpend.status import CallCode, Status


class FakeC:
    """Returns the given codes in turn, recording the budgets it was called with."""

    def __init__(self, *codes, seconds: float = 0.0):
        self.codes, self.budgets, self.seconds = list(codes), [], seconds

    def __call__(self, budget: int) -> int:
        self.budgets.append(budget)
        if self.seconds:
            time.sleep(self.seconds)
        return self.codes.pop(0)


def test_done_at_once_returns_the_status_and_takes_the_rows():
    taken = []
    status = drive(FakeC(0), budget=10, take=lambda: taken.append(1))
    assert status is Status.SUCCESS and taken == [1]


@pytest.mark.parametrize("code", [int(s) for s in Status if s != Status.PARTIAL])
def test_every_result_code_is_decoded_to_its_status(code):
    assert drive(FakeC(-1, -2, code), budget=5) is Status(code)


def test_call_again_codes_take_rows_and_report_progress_each_time():
    log = []
    fake = FakeC(CallCode.BUDGET, CallCode.BUFFER_FULL, CallCode.BUDGET, Status.MAX_STEPS)
    status = drive(fake, budget=7, take=lambda: log.append("take"), progress=lambda: log.append("progress"),
                   check=lambda: log.append("check"))
    assert status is Status.MAX_STEPS
    assert log == ["check", "take", "progress"] * 4
    assert fake.budgets == [7, 7, 7, 7]  # a fixed budget without adapt


def test_bad_arguments_is_an_internal_error_naming_the_function():
    with pytest.raises(RuntimeError, match="bad arguments to sp_fake"):
        drive(FakeC(CallCode.BAD_ARGUMENTS), budget=1, name="sp_fake")


def test_an_unknown_negative_code_is_an_internal_error():
    with pytest.raises(RuntimeError, match="returned -7"):
        drive(FakeC(-7), budget=1, name="sp_fake")


def test_check_raises_between_calls():
    def check():
        raise KeyboardInterrupt

    fake = FakeC(-1, 0)
    with pytest.raises(KeyboardInterrupt):
        drive(fake, budget=1, check=check)
    assert fake.budgets == [1]


def test_between_runs_only_before_calling_again():
    """The ensemble engine's cancel event: checked between calls, never after the last one."""
    cancel = threading.Event()
    cancel.set()

    def between():
        if cancel.is_set():
            raise Cancelled()

    assert drive(FakeC(0), budget=1, between=between) is Status.SUCCESS  # finished: nothing to cancel
    fake = FakeC(-1, -1, 0)
    with pytest.raises(Cancelled):
        drive(fake, budget=1, between=between)
    assert len(fake.budgets) == 1
    fake = FakeC(-2, -1, 0)
    cancel.clear()
    assert drive(fake, budget=1, between=between) is Status.SUCCESS and len(fake.budgets) == 3


def test_adapted_budget_aims_at_chunk_seconds_and_only_after_a_budget_return():
    fake = FakeC(-1, -2, -1, 0, seconds=CHUNK_SECONDS / 5)
    drive(fake, budget=1000, adapt=True)
    b = fake.budgets
    assert b[0] == 1000
    # a call of at least CHUNK_SECONDS / 5 scales the budget by at most 5 (a slower call: less), never below 100
    assert 100 <= b[1] <= 5000
    assert b[2] == b[1]  # a full buffer is no reason to retune
    assert b[3] >= 100


def test_estimate_runs_once_after_the_first_budget_return():
    calls = []
    drive(FakeC(-2, -1, -1, 0), budget=1, estimate=lambda: calls.append(1))
    assert calls == [1]
    calls.clear()
    drive(FakeC(-2, 0), budget=1, estimate=lambda: calls.append(1))
    assert calls == []


def test_the_estimate_refusal_stops_the_loop():
    state = SimpleNamespace(t=1.0, naccept=900, nreject=100)
    fake = FakeC(-1, -1, 0)
    with pytest.raises(ParameterError, match=r"about 1e\+06 steps.*max_steps = 1000") as info:
        drive(fake, budget=1000, estimate=lambda: check_step_estimate(state, 1000.0, 1000))
    assert info.value.parameter == "max_steps"
    assert "--" not in str(info.value)  # the library names parameters, the CLI maps them to flags
    assert len(fake.budgets) == 1


def test_step_estimate():
    state = SimpleNamespace(t=2.0, naccept=15, nreject=5)
    assert check_step_estimate(state, 10.0, 100) == pytest.approx(100.0)
    with pytest.raises(ParameterError, match="about 1e\\+02 steps"):
        check_step_estimate(state, 10.0, 99)
    with pytest.raises(ParameterError, match="more than 1e308"):
        check_step_estimate(SimpleNamespace(t=0.0, naccept=1, nreject=0), 1.0, 10)
