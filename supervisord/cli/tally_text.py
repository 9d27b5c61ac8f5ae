"""A robot's records counted, in words and as JSON: the line ``srcsctl fleet --summary`` prints
for each robot and ``srcsctl log --summary`` for the robot's own record (docs/srcsctl.md).

What counts as what is :mod:`supervisord.record.counted`'s (SR-13.9): the stops and the last
one's trigger, then the start-ups, the proof tests (a failed one in capitals: it leaves the
robot one stop path) and the re-arms, apart. Escaped by the caller (SR-13.7)."""

from __future__ import annotations

from typing import Any

from supervisord.cli.times import show_time
from supervisord.record.counted import Tally
from supervisord.vocabulary import Counted


def _many(count: int, word: str) -> str:
    return f"{count} {word}{'' if count == 1 else 's'}"


def tally_line(tally: Tally, *, utc: bool) -> str:
    """``3 stops, 2 start-ups, proof tests 1 passed 1 FAILED, 3 re-arms, 31 records; last stop
    WHEN #22 shutdown:SIGTERM``."""
    counts = tally.counts
    passed, failed = counts[Counted.PROOFTEST_PASSED], counts[Counted.PROOFTEST_FAILED]
    proof = f"proof tests {passed} passed" + (f" {failed} FAILED" if failed else "")
    parts = [
        _many(tally.stops, "stop"),
        _many(counts[Counted.STARTUP], "start-up"),
        proof,
        _many(counts[Counted.REARM], "re-arm"),
        _many(tally.records, "record"),
    ]
    line = ", ".join(parts)
    last = tally.last_stop
    if last is not None:
        line += f"; last stop {show_time(last.utc, utc=utc)} #{last.seq} {', '.join(last.trigger)}"
    return line


def tally_json(tally: Tally) -> dict[str, Any]:
    """The counts as one JSON object's fields: ``records``, ``stops``, ``startups``,
    ``prooftests`` (``passed``, ``failed``), ``rearms``, ``triggers`` (stops by each cause of
    their trigger) and ``last_stop`` (``seq``, ``utc``, ``trigger``; ``null`` without one)."""
    counts = tally.counts
    last = tally.last_stop
    return {
        "records": tally.records,
        "stops": tally.stops,
        "startups": counts[Counted.STARTUP],
        "prooftests": {
            "passed": counts[Counted.PROOFTEST_PASSED],
            "failed": counts[Counted.PROOFTEST_FAILED],
        },
        "rearms": counts[Counted.REARM],
        "triggers": dict(sorted(tally.triggers.items())),
        "last_stop": None
        if last is None
        else {"seq": last.seq, "utc": last.utc, "trigger": list(last.trigger)},
    }
