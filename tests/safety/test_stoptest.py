"""The field stop test's verdict and record (SR-12.1; ``supervisord/safety/stoptest.py``):
pure values judged against the limit, and the safety core's ``stoptest`` record."""

from __future__ import annotations

import datetime as dt

import pytest

from supervisord.record.format import record_json
from supervisord.safety.decision import RecordNote
from supervisord.safety.events import StopTested
from supervisord.safety.stoptest import (
    LIMIT_MS,
    OutputOff,
    Source,
    StopStep,
    StopTestFormatError,
    StopTestResult,
    result_from_json,
)
from supervisord.safety.transitions import State
from tests.safety.rig import ADMIN, Rig

MS = 1_000_000


def _result(*offs: int | None, limit: int = LIMIT_MS) -> StopTestResult:
    outputs = tuple(OutputOff(f"out{i}", off) for i, off in enumerate(offs))
    return StopTestResult((StopStep(Source.REMOTE, 41, 5 * MS, outputs),), limit)


def test_the_limit_is_every_output_of_every_press() -> None:
    """SR-12.1: passed when every output of every press went off within the limit, the
    limit itself included; one output a nanosecond late, one never off (``None``), a press
    without outputs, or no press at all fails."""
    assert _result(0, LIMIT_MS * MS).passed
    assert not _result(0, LIMIT_MS * MS + 1).passed
    assert not _result(1 * MS, None).passed
    assert not _result().passed
    assert not StopTestResult(()).passed
    assert not _result(-1).passed  # an off before the frame's read is no measurement
    wired = StopStep(Source.WIRED, 44, 9 * MS, (OutputOff("out0", 80 * MS),))
    assert not StopTestResult((*_result(1 * MS).steps, wired)).passed


def test_a_category_1_output_is_judged_after_its_off_delay() -> None:
    """SR-12.1, SR-1.4: a power output with an off delay is meant to stay on that long: it
    passes when it went off within the limit after its delay, and fails past it; the record's
    line says the limit counts from each output's delay."""
    delayed = OutputOff("power", (200 + LIMIT_MS) * MS, off_delay_ms=200)
    step = StopStep(Source.REMOTE, 41, 5 * MS, (OutputOff("drive", 1 * MS), delayed))
    result = StopTestResult((step,))
    assert result.passed
    assert result.text.startswith(f"passed (limit {LIMIT_MS} ms after each output's off delay)")
    late = OutputOff("power", (200 + LIMIT_MS) * MS + 1, off_delay_ms=200)
    assert not StopTestResult((StopStep(Source.REMOTE, 41, 5 * MS, (late,)),)).passed
    assert result_from_json(result.json()) == result


def test_the_result_says_each_output_and_its_verdict() -> None:
    """SR-12.1: the record's object names each press's source, stop record and time, each
    output's time in ns and ms and its own verdict, the limit and a line for people."""
    result = _result(2_500_000, None)
    data = result.json()
    assert data["result"] == "failed"
    assert data["limit_ms"] == LIMIT_MS
    steps = data["steps"]
    assert isinstance(steps, list)
    [step] = steps
    assert step["source"] == "remote"
    assert step["seq"] == 41
    assert step["stop_ns"] == 5 * MS
    assert step["outputs"] == [
        {"name": "out0", "off_ns": 2_500_000, "off_ms": 2.5, "off_delay_ms": 0, "passed": True},
        {"name": "out1", "off_ns": None, "off_ms": None, "off_delay_ms": 0, "passed": False},
    ]
    assert data["text"] == f"FAILED (limit {LIMIT_MS} ms): remote: not off: out1"
    assert (
        _result(2_500_000).text
        == f"passed (limit {LIMIT_MS} ms): remote: every output off within 2.5 ms"
    )


def test_a_result_reads_back_and_its_verdict_is_recomputed() -> None:
    """SR-12.1, SR-7.10: the flight recorder reads a result back equal; a verdict or a time
    in ms written into the JSON is never trusted, only the measured ns; garbage is refused."""
    result = _result(3 * MS, 70 * MS)
    assert result_from_json(result.json()) == result
    forged = result.json()
    forged["result"] = "passed"
    assert not result_from_json(forged).passed
    for bad in (None, {}, {"steps": [1]}, {"steps": [{"source": "x", "outputs": []}]}):
        with pytest.raises(StopTestFormatError):
            result_from_json(bad)


def test_the_core_records_a_stop_test_without_changing_the_state() -> None:
    """SR-12.1, SR-7.1: the daemon's judged result is a ``stoptest`` record of its own, with
    the verdict as its reason and the numbers as its ``stoptest`` object; the state and the
    causes stay as they were."""
    rig = Rig()
    rig.bring_up()
    result = _result(1 * MS, 4 * MS)
    decision = rig.feed(StopTested(rig.now, ADMIN, result))
    [record] = decision.records
    assert record.note is RecordNote.STOPTEST
    assert record.reason == result.text
    assert record.previous is record.state is decision.state is State.RUN
    assert record.changes == ()
    data = record_json(record, dt.datetime(2026, 11, 25, tzinfo=dt.timezone.utc))
    assert data["kind"] == "stoptest"
    assert data["stoptest"] == result.json()
    assert data["trigger"]["event"] == "stop_tested"
    assert "result" not in data["trigger"]  # the numbers once, in ``stoptest``
