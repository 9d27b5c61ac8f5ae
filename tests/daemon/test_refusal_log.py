"""The refusals under the record budget (SR-8.5): each counted, their count logged at most
once a second on the loop's clock, never a line per refusal."""

from __future__ import annotations

import dataclasses
import logging

import pytest

from supervisord.daemon.refusal_log import LIMIT_LOG_NS, RefusalLog
from supervisord.safety.config import SafetyConfig
from supervisord.safety.core import SafetyCore
from supervisord.safety.decision import Refusal, RefusalReason
from supervisord.timebase import NS_PER_MS

MS = NS_PER_MS
START = 5_000 * MS


def _lines(caplog: pytest.LogCaptureFixture) -> list[str]:
    return [r.getMessage() for r in caplog.records if r.name == "srcsd"]


def test_a_flood_of_refusals_is_one_line_a_second_with_the_count_since_the_last(
    caplog: pytest.LogCaptureFixture,
) -> None:
    """SR-8.5: the first refusal is logged at once; those in the next second only counted; the
    first at or after that second logs the count since the last line, itself included."""
    refusals = RefusalLog()
    caplog.set_level(logging.WARNING, logger="srcsd")
    refusals.refused(START)
    for n in range(1, 5):  # within the second after the first line
        refusals.refused(START + n * 100 * MS)
    assert _lines(caplog) == ["1 client requests refused: record budget exceeded (docs/safety.md)"]
    refusals.refused(START + LIMIT_LOG_NS)  # a second after the line: its turn
    refusals.refused(START + LIMIT_LOG_NS + 1)
    assert _lines(caplog)[1:] == [
        "5 client requests refused: record budget exceeded (docs/safety.md)"
    ]
    assert refusals.count == 7  # every refusal counted, logged or not


def test_a_refusal_after_a_quiet_spell_is_logged_at_once(
    caplog: pytest.LogCaptureFixture,
) -> None:
    """SR-8.5: the count holds no refusal over from a line already written."""
    refusals = RefusalLog()
    caplog.set_level(logging.WARNING, logger="srcsd")
    refusals.refused(START)
    refusals.refused(START + 60 * LIMIT_LOG_NS)
    assert (
        _lines(caplog) == ["1 client requests refused: record budget exceeded (docs/safety.md)"] * 2
    )
    assert refusals.count == 2


def test_a_decisions_refusals_are_counted_when_rate_limited_and_logged_otherwise(
    caplog: pytest.LogCaptureFixture,
) -> None:
    """SR-8.5, SR-4: of an applied decision's refusals, the ``rate_limited`` are counted (and
    logged as a count, at the decision's time), any other is logged as it is, a line each.
    Mutants caught: the reason's test inverted, the decision's time not passed, the other
    refusals not logged."""
    caplog.set_level(logging.INFO, logger="srcsd")
    core = SafetyCore(SafetyConfig(), START)
    decision = dataclasses.replace(
        core.decision,
        now=START + LIMIT_LOG_NS,
        refusals=(
            Refusal(RefusalReason.RATE_LIMITED, "", None),
            Refusal(RefusalReason.NOT_STOPPED, "", None),
            Refusal(RefusalReason.RATE_LIMITED, "", None),
        ),
    )
    refusals = RefusalLog()
    refusals.refused(START)  # a line now; the next may go out a second later
    refusals.decided(decision)
    assert refusals.count == 3  # the third counted, for the next line
    assert _lines(caplog) == [
        "1 client requests refused: record budget exceeded (docs/safety.md)",
        "1 client requests refused: record budget exceeded (docs/safety.md)",  # its second
        f"refused: {RefusalReason.NOT_STOPPED.value}",
    ]


def test_the_first_refusal_is_logged_at_once_whatever_the_clock_reads(
    caplog: pytest.LogCaptureFixture,
) -> None:
    """SR-8.5: no line was written before the first refusal, so it is logged at once, also at
    the clock's zero (the loop's clock is ``time.monotonic_ns()``, which starts at a boot)."""
    refusals = RefusalLog()
    caplog.set_level(logging.WARNING, logger="srcsd")
    refusals.refused(0)
    assert _lines(caplog) == ["1 client requests refused: record budget exceeded (docs/safety.md)"]
