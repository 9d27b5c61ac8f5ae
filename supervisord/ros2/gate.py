"""The velocity gate: a second, software stop in front of the motion stack (docs/ros2.md
"cmd_vel"). Pure: time is an argument, in nanoseconds of whatever clock the stamps use.

A command is forwarded only while the supervisor is in RUN and only when it is at most
``max_age_ns`` old; on leaving RUN the gate asks for one zero command at once, then forwards
nothing until RUN comes back. It never repeats or replays a command. Like twist_mux's locks it
is a convenience for the motion stack: the enable lines stay the real stop (SR-1).
"""

from __future__ import annotations

import enum

from supervisord.ros2.diagnostics import GateCounts
from supervisord.vocabulary import State


class Verdict(enum.Enum):
    """What the gate does with one command."""

    FORWARD = "forward"
    NOT_RUN = "not_run"
    TOO_OLD = "too_old"


class VelocityGate:
    """The gate's state: whether the supervisor is in RUN, and its counters."""

    def __init__(self, max_age_ns: int) -> None:
        if max_age_ns <= 0:
            raise ValueError(f"the gate's max age must be positive, not {max_age_ns} ns")
        self.max_age_ns = max_age_ns
        self.running = False
        self.counts = GateCounts()

    def state(self, state: State) -> bool:
        """The supervisor's state changed (or was seen again). True exactly when a zero
        command must go out now: the gate was open and this closes it."""
        was_running, self.running = self.running, state is State.RUN
        if was_running and not self.running:
            self._count(zeros=1)
            return True
        return False

    def command(self, sent_ns: int | None, now_ns: int) -> Verdict:
        """One command arrived at ``now_ns``, sent at ``sent_ns`` (its header stamp, or the
        middleware's source time; ``None`` when it carries no time, then it counts as sent
        now). A stamp from further ahead than the max age is as untrustworthy as one too
        old: both are dropped, and so is a zero stamp (an unset header)."""
        if not self.running:
            self._count(not_run=1)
            return Verdict.NOT_RUN
        if sent_ns is not None and (sent_ns <= 0 or abs(now_ns - sent_ns) > self.max_age_ns):
            self._count(too_old=1)
            return Verdict.TOO_OLD
        self._count(forwarded=1)
        return Verdict.FORWARD

    def _count(
        self, forwarded: int = 0, not_run: int = 0, too_old: int = 0, zeros: int = 0
    ) -> None:
        c = self.counts
        self.counts = GateCounts(
            c.forwarded + forwarded, c.not_run + not_run, c.too_old + too_old, c.zeros + zeros
        )
