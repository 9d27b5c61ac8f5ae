"""``Robot`` hands out typed records: the record file read with the parser the API's clients
use, states and causes the vocabulary's members (no daemon needed to check the reading)."""

from __future__ import annotations

from pathlib import Path

from supervisord.record.jsonl import encode
from supervisord.record.stop import Cause, Change, StopRecord
from supervisord.testkit.robot import Robot, names_cause
from supervisord.vocabulary import Cause as Named
from supervisord.vocabulary import CauseKind, ChangeKind, Severity, State

ESTOP = Named(CauseKind.VSC_ESTOP)
FAULT = Named(CauseKind.OUTPUT_FAULT, "drive")


def _record(seq: int, mono_ns: int, raised: Named) -> StopRecord:
    return StopRecord(
        seq=seq,
        mono_ns=mono_ns,
        utc="2026-12-06T10:00:00.000000+00:00",
        from_state=State.RUN,
        to_state=State.STOPPED,
        causes=(
            Cause(
                name=raised,
                severity=Severity.STOP,
                active=True,
                latched=True,
                raised_ns=mono_ns,
                cleared_ns=None,
            ),
        ),
        changes=(Change(name=raised, change=ChangeKind.RAISED),),
        trigger={"event": "vsc_heartbeat"},
    )


def test_records_are_typed_and_causes_found_by_kind_cause_or_name(tmp_path: Path) -> None:
    robot = Robot(tmp_path)
    written = [_record(1, 5_000_000_000, ESTOP), _record(2, 7_000_000_000, FAULT)]
    robot.record_path.write_bytes(b"".join(encode(r.json()) for r in written))
    assert robot.records() == written
    assert all(isinstance(r, StopRecord) for r in robot.records())
    assert robot.records()[0].to_state is State.STOPPED
    assert robot.records_since(6.0) == written[1:]
    assert robot.record_raising(CauseKind.VSC_ESTOP, 0.0) == written[0]
    assert robot.record_raising(CauseKind.OUTPUT_FAULT, 0.0) == written[1]
    assert robot.record_raising(FAULT, 0.0) == written[1]
    assert robot.record_raising("output_fault:drive", 0.0) == written[1]
    assert robot.record_raising("output_fault", 0.0, prefix=True) == written[1]
    assert robot.record_raising("output_fault", 0.0) is None  # a name is the whole name
    assert robot.record_raising(CauseKind.VSC_ESTOP, 6.0) is None
    assert robot.record_lines() == [r.json() for r in written]  # the file's own form


def test_a_cause_is_named_by_its_kind_itself_or_its_text() -> None:
    assert names_cause(FAULT, CauseKind.OUTPUT_FAULT)
    assert names_cause(FAULT, FAULT)
    assert not names_cause(FAULT, Named(CauseKind.OUTPUT_FAULT, "power"))
    assert names_cause(FAULT, "output_fault:drive")
    assert names_cause(FAULT, "output_", prefix=True)
    assert not names_cause(ESTOP, CauseKind.OUTPUT_FAULT)
