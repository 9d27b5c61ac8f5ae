"""Time units and the one rule for periodic duties, shared by the pure safety core, the loop,
the outputs and the benches.

Every time in the project is an integer of monotonic nanoseconds (SR-2.11); this module only
does arithmetic on such integers and imports nothing, so the pure core may use it
(``tests/safety/test_purity.py``).
"""

from __future__ import annotations

from typing import Final

NS_PER_MS: Final = 1_000_000
NS_PER_S: Final = 1_000_000_000


def seconds_since(now: int, since: int | None) -> float | None:
    """``now - since`` in seconds, milliseconds kept (as ``status`` shows ages, never below
    0), ``None`` when ``since`` is unknown (never happened)."""
    return None if since is None else round(max(0, now - since) / NS_PER_S, 3)


def next_due(scheduled: int, now: int, period: int) -> int:
    """The next time a periodic duty is due after the one due at ``scheduled`` was done at
    ``now``: one ``period`` after ``scheduled``, so that the cadence holds and a late turn
    does not accumulate (SR-5.1, SR-9.3); but if that time has already passed (the loop was
    late by a whole period or more), one ``period`` after ``now``, so that a late loop
    restarts the cadence instead of bursting to catch up."""
    following = scheduled + period
    return following if following > now else now + period
