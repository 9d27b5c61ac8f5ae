"""A monotonic clock a test moves by hand, for integrators' tests of time without sleeping
(docs/testing.md "The kit for integrators").

Every time in the project is an integer of monotonic nanoseconds passed in as ``now``
(SR-2.11): the safety core (``SafetyCore(config, now)``, ``tick(now)``), the outputs'
``set``/``tick``, the links' ``Backoff``, ``timebase.next_due``. A test that holds a
``FakeClock`` hands those its ``now`` and moves it with ``advance`` or ``advance_to``; a
client of the integrator's own that takes its clock and its sleep as arguments is given
``monotonic`` and ``sleep``, and a second of its timing costs no second of the test's.

The clock refuses to run backwards, as ``CLOCK_MONOTONIC`` never does: a test that moves it
back, or to a deadline already past, gets a ``ClockWentBackwardsError`` rather than a clock
no daemon will ever see (SR-2.11: deadlines on the monotonic clock). It is not the daemon's
wall-clock jump: that is ``faketime.FakeWallClock``, for the real process.
"""

from __future__ import annotations

from supervisord.errors import SrcsError
from supervisord.timebase import NS_PER_MS, NS_PER_S

START_NS = 1_000 * NS_PER_S
"""Where a new clock starts: an arbitrary time well after zero, as a booted machine's is, so
that "never happened" (``None``) and "at time zero" are never confused."""


class ClockWentBackwardsError(SrcsError, ValueError):
    """A test asked the fake monotonic clock to go back (or to stay behind a time it already
    passed): nothing moved."""

    def __init__(self, now_ns: int, asked_ns: int) -> None:
        super().__init__(f"the monotonic clock is at {now_ns} ns; {asked_ns} ns is earlier")
        self.now_ns, self.asked_ns = now_ns, asked_ns


class FakeClock:
    """A monotonic clock in integer nanoseconds that moves only when told to.

    ``now_ns`` reads it; ``advance`` moves it forward by a duration, ``advance_to`` to a
    time (a deadline a decision named); both return the new time and refuse to go back.
    ``monotonic`` and ``sleep`` have the signatures of ``time.monotonic`` and ``time.sleep``,
    for code that takes its clock as an argument."""

    def __init__(self, start_ns: int = START_NS) -> None:
        if start_ns < 0:
            raise ClockWentBackwardsError(0, start_ns)
        self._now = start_ns

    @property
    def now_ns(self) -> int:
        """The time, in monotonic nanoseconds (the ``now`` every pure part takes)."""
        return self._now

    def advance(self, ns: int = 0, *, ms: int = 0, s: float = 0.0) -> int:
        """Move forward by ``ns`` + ``ms`` + ``s``; the new time. A negative total raises
        ``ClockWentBackwardsError`` and moves nothing; zero is allowed (two inputs read at
        one instant)."""
        step = ns + ms * NS_PER_MS + round(s * NS_PER_S)
        return self.advance_to(self._now + step)

    def advance_to(self, t_ns: int) -> int:
        """Move to ``t_ns`` (e.g. ``decision.next_deadline``); the new time. Earlier than now
        raises ``ClockWentBackwardsError`` and moves nothing."""
        if t_ns < self._now:
            raise ClockWentBackwardsError(self._now, t_ns)
        self._now = t_ns
        return t_ns

    def __call__(self) -> int:
        """The time in nanoseconds: the clock a loop takes as a function (the daemon's
        ``Supervisor(clock=...)``, docs/testing.md "Time in tests")."""
        return self._now

    def monotonic(self) -> float:
        """The time in seconds, as ``time.monotonic`` gives it."""
        return self._now / NS_PER_S

    def sleep(self, seconds: float) -> None:
        """``time.sleep`` for code under test: the clock moves, the test does not wait."""
        self.advance(s=seconds)

    def __repr__(self) -> str:
        return f"FakeClock(now_ns={self._now})"
