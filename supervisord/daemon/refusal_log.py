"""The refusals under the record budget, counted and logged as a count at most once a second.

A client flooding releases or resets is refused ``rate_limited`` (SR-8.5, docs/safety.md "How
many records the clients may cause"); a line per refusal would turn that flood into a flood of
log lines through the sink, so each is counted and the count not logged yet goes out once a
second, on the loop's clock, when the next refusal comes. The loop tells it each decision
that refused (:meth:`RefusalLog.decided`: the rate-limited counted, any other logged as a line
of its own) and reads the total for ``status`` (:attr:`RefusalLog.count`).
"""

from __future__ import annotations

import logging

from supervisord.safety.decision import Decision, RefusalReason
from supervisord.timebase import NS_PER_S

__all__ = ["LIMIT_LOG_NS", "RefusalLog"]

log = logging.getLogger("srcsd")

LIMIT_LOG_NS = NS_PER_S  # rate-limited refusals are logged as a count, once a second


class RefusalLog:
    """The ``rate_limited`` refusals: their count, and the count not logged yet (SR-8.5)."""

    __slots__ = ("_next_log", "_unlogged", "count")

    def __init__(self) -> None:
        self.count = 0  # every refusal since the start, for ``status``
        self._unlogged = 0  # refused since the last line
        self._next_log = 0  # the loop's clock at which the next line may go out

    def decided(self, decision: Decision) -> None:
        """The refusals of ``decision``, one applied: each ``rate_limited`` one counted (and
        logged as a count), any other logged as it is (a reset or takeover refused, SR-4)."""
        for refusal in decision.refusals:
            if refusal.reason is RefusalReason.RATE_LIMITED:
                self.refused(decision.now)
            else:
                log.info("refused: %s", refusal.message)

    def refused(self, now: int) -> None:
        """One release or reset refused under the record budget at ``now`` (the loop's
        clock): counted, and the count logged if a second has passed since the last line."""
        self.count += 1
        self._unlogged += 1
        if now >= self._next_log:
            log.warning(
                "%d client requests refused: record budget exceeded (docs/safety.md)",
                self._unlogged,
            )
            self._unlogged = 0
            self._next_log = now + LIMIT_LOG_NS
