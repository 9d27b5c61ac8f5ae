"""When the periodic tests are due (SR-12.2; docs/safety-manual.md "Periodic tests"): the age
of the last passed field stop test (``stoptest``, SR-12.1) and proof test of the VSC's
watchdog (``prooftest``, SR-5.6), and whether it is past its interval.

A warning, never a stop: an overdue test says the evidence is old, not that the stop path
fails. The age survives a restart: at start the daemon reads the newest pass of each test
from the record file (:mod:`supervisord.record.passes`); at run time every passing record it
writes resets it. Every age is kept as the monotonic time of the pass, so a wall clock set
back or forward while the daemon runs changes none; a pass read from the file is placed on
the monotonic clock once, at start, from its UTC time. Fail safe: a pass that cannot be read,
or is dated after the daemon's start (a wall clock that was wrong when it was written, or is
now), counts as never passed, so the test is overdue.

Pure: the loop passes its clocks' readings (SR-2.11).
"""

from __future__ import annotations

import datetime as dt
import enum
from collections.abc import Mapping
from dataclasses import dataclass
from typing import Final

from supervisord.api.status import Maintenance, PeriodicDue
from supervisord.record.stop import RecordKind, StopRecord
from supervisord.timebase import NS_PER_S

NS_PER_DAY: Final = 86_400 * NS_PER_S


class PeriodicTest(enum.Enum):
    """A periodic test: its value is the record ``kind`` of its result (docs/record.md)."""

    STOPTEST = "stoptest"
    PROOFTEST = "prooftest"


@dataclass(frozen=True, slots=True)
class Due:
    """One test's schedule now: ``age_s`` of its last pass (``None``: never passed, or not
    known), and whether it is ``overdue`` (never passed counts; interval 0: never overdue)."""

    test: PeriodicTest
    interval_days: int
    age_s: float | None
    overdue: bool

    def report(self) -> PeriodicDue:
        """As ``status`` says it (docs/api.md): the age rounded to the millisecond."""
        return PeriodicDue(
            interval_days=self.interval_days,
            last_pass_age_s=None if self.age_s is None else round(self.age_s, 3),
            overdue=self.overdue,
        )


def due(test: PeriodicTest, interval_days: int, passed_ns: int | None, now_ns: int) -> Due:
    """``test``'s schedule at ``now_ns`` when it last passed at ``passed_ns`` (both on the
    monotonic clock; ``None``: never, as far as anyone can tell)."""
    age_ns = None if passed_ns is None else max(0, now_ns - passed_ns)
    overdue = interval_days > 0 and (age_ns is None or age_ns > interval_days * NS_PER_DAY)
    return Due(test, interval_days, None if age_ns is None else age_ns / NS_PER_S, overdue)


def on_monotonic(passed: dt.datetime | None, wall_now: dt.datetime, now_ns: int) -> int | None:
    """A pass at UTC ``passed`` placed on the monotonic clock, given both clocks' readings now;
    ``None`` for no pass or one dated after now (fail safe: its age is not known)."""
    if passed is None:
        return None
    age = wall_now - passed
    if age < dt.timedelta(0):
        return None
    return now_ns - (age // dt.timedelta(microseconds=1)) * 1000


def passed(record: StopRecord) -> PeriodicTest | None:
    """The test a record says passed (a ``stoptest`` or ``prooftest`` record whose result is
    ``passed``), or ``None``. The typed record the core made (docs/record.md), not its JSON."""
    kind = record.kind
    if kind is RecordKind.STOPTEST:
        return (
            PeriodicTest.STOPTEST
            if record.stoptest is not None and record.stoptest.passed
            else None
        )
    if kind is RecordKind.PROOFTEST:
        proof = record.prooftest
        return PeriodicTest.PROOFTEST if proof is not None and proof.passed else None
    return None


class Schedule:
    """The daemon's view of both tests: their intervals and last passes (monotonic ns)."""

    def __init__(self, intervals: Mapping[PeriodicTest, int]) -> None:
        self.intervals = dict(intervals)
        self.found: dict[PeriodicTest, dt.datetime] = {}  # from the record file, before the start
        self.passed_ns: dict[PeriodicTest, int | None] = dict.fromkeys(PeriodicTest)

    def start(self, wall_now: dt.datetime, now_ns: int) -> None:
        """Place the passes read from the file on the monotonic clock (once, at start)."""
        for test in PeriodicTest:
            self.passed_ns[test] = on_monotonic(self.found.get(test), wall_now, now_ns)

    def recorded(self, record: StopRecord) -> None:
        """A record the daemon wrote: a pass resets its test's age, at its ``mono_ns``."""
        test = passed(record)
        if test is not None:
            self.passed_ns[test] = record.mono_ns

    def status(self, now_ns: int) -> Maintenance:
        """For ``status`` (docs/api.md): each test's interval, last pass's age, overdue."""

        def now(test: PeriodicTest) -> PeriodicDue:
            return due(test, self.intervals.get(test, 0), self.passed_ns[test], now_ns).report()

        return Maintenance(
            stoptest=now(PeriodicTest.STOPTEST), prooftest=now(PeriodicTest.PROOFTEST)
        )
