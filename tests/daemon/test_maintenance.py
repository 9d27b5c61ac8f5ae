"""When the periodic tests are overdue (SR-12.2; ``supervisord/daemon/maintenance.py``): pure
rules on injected times, and the daemon's schedule across a wall clock that moves."""

from __future__ import annotations

import datetime as dt

from supervisord.api.status import PeriodicDue
from supervisord.daemon.maintenance import (
    NS_PER_DAY,
    PeriodicTest,
    Schedule,
    due,
    on_monotonic,
    passed,
)
from supervisord.record.stop import ProofTestResult, RecordKind, StopRecord, StopTestReport
from supervisord.safety.transitions import State
from supervisord.timebase import NS_PER_S

UTC = dt.timezone.utc
WALL = dt.datetime(2026, 11, 25, 12, 0, tzinfo=UTC)
MONO = 10_000 * NS_PER_S  # the monotonic clock at WALL


def _record(kind: RecordKind, result: str, mono_ns: int = MONO) -> StopRecord:
    """A typed record of ``kind`` whose stop or proof test says ``result``, as the core makes
    it (the schedule reads the typed record, never its JSON)."""
    stoptest = prooftest = None
    if kind is RecordKind.STOPTEST:
        stoptest = StopTestReport(result=result, limit_ms=500, steps=())
    elif kind is RecordKind.PROOFTEST:
        prooftest = ProofTestResult(
            result=result, failure=None, trip_ms=None, cleared=None, cleared_ms=None
        )
    return StopRecord(
        seq=1,
        mono_ns=mono_ns,
        utc="2026-11-25T12:00:00.000000Z",
        kind=kind,
        from_state=State.STOPPED,
        to_state=State.STOPPED,
        causes=(),
        trigger={"event": kind.value},
        stoptest=stoptest,
        prooftest=prooftest,
    )


def test_a_test_is_overdue_past_its_interval_or_never_passed() -> None:
    """SR-12.2: overdue once more than the interval has passed since the last pass (the
    interval itself is still in time), or when it never passed; interval 0 is no schedule,
    never overdue; the age is given in seconds, ``None`` for never."""
    interval = 30
    at_limit = due(PeriodicTest.STOPTEST, interval, MONO - interval * NS_PER_DAY, MONO)
    assert (at_limit.overdue, at_limit.age_s) == (False, 30 * 86_400.0)
    past = due(PeriodicTest.STOPTEST, interval, MONO - interval * NS_PER_DAY - 1, MONO)
    assert past.overdue
    never = due(PeriodicTest.PROOFTEST, interval, None, MONO)
    assert (never.overdue, never.age_s) == (True, None)
    assert not due(PeriodicTest.STOPTEST, 0, None, MONO).overdue
    assert due(PeriodicTest.STOPTEST, 1, MONO - 5 * NS_PER_S, MONO).report() == PeriodicDue(
        interval_days=1, last_pass_age_s=5.0, overdue=False
    )


def test_a_pass_from_the_file_is_placed_on_the_monotonic_clock_or_not_at_all() -> None:
    """SR-12.2: a pass read from the record is its age before now on the monotonic clock;
    one dated after now (a clock wrong then or now) has no known age: never passed, the
    fail-safe side."""
    two_days = WALL - dt.timedelta(days=2, microseconds=5)
    assert on_monotonic(two_days, WALL, MONO) == MONO - 2 * NS_PER_DAY - 5_000
    assert on_monotonic(WALL + dt.timedelta(seconds=1), WALL, MONO) is None
    assert on_monotonic(None, WALL, MONO) is None


def test_only_a_passed_stoptest_or_prooftest_record_is_a_pass() -> None:
    """SR-12.2: a ``stoptest`` or ``prooftest`` record whose result is ``passed``; a failed
    one, or another kind of record, is none."""
    assert passed(_record(RecordKind.STOPTEST, "passed")) is PeriodicTest.STOPTEST
    assert passed(_record(RecordKind.PROOFTEST, "passed")) is PeriodicTest.PROOFTEST
    assert passed(_record(RecordKind.STOPTEST, "failed")) is None
    assert passed(_record(RecordKind.PROOFTEST, "failed")) is None
    assert passed(_record(RecordKind.STATE_CHANGE, "passed")) is None


def test_the_schedule_ages_by_the_monotonic_clock_and_a_pass_resets_it() -> None:
    """SR-12.2: the daemon's schedule starts from the file's passes, ages on the monotonic
    clock (a wall clock set back after the start changes nothing), and a passing record it
    writes resets its test at the record's ``mono_ns``; a failing one does not."""
    schedule = Schedule({PeriodicTest.STOPTEST: 30, PeriodicTest.PROOFTEST: 7})
    schedule.found = {PeriodicTest.STOPTEST: WALL - dt.timedelta(days=29)}
    schedule.start(WALL, MONO)
    in_a_day = MONO + NS_PER_DAY + NS_PER_S
    view = schedule.status(in_a_day)
    assert view.stoptest == PeriodicDue(
        interval_days=30, last_pass_age_s=30 * 86_400.0 + 1, overdue=True
    )
    assert view.prooftest == PeriodicDue(interval_days=7, last_pass_age_s=None, overdue=True)
    schedule.recorded(_record(RecordKind.STOPTEST, "failed", in_a_day))
    assert schedule.status(in_a_day).stoptest == view.stoptest
    schedule.recorded(_record(RecordKind.STOPTEST, "passed", in_a_day))
    assert schedule.status(in_a_day + 3 * NS_PER_S).stoptest == PeriodicDue(
        interval_days=30, last_pass_age_s=3.0, overdue=False
    )
