"""The stop record's making (SR-7, ``docs/record.md`` "Fields"): one JSON object per record.

:func:`stop_record` turns the safety core's record into the typed record
(:class:`~supervisord.record.stop.StopRecord`, whose one encoder writes it), and
:func:`record_json` turns the safety core's :class:`~supervisord.safety.decision.Record` into
the object that the JSON Lines store, the journal and the API's ``record`` push all carry;
:class:`RecordKind` names what a record reports, :func:`record_kind` derives it from the
core's record and :func:`written_kind` reads it back from a written one. The cause and caller
objects are shared with the API's ``status`` (``docs/api.md``), so both read the same.
:class:`RecordKind` is the typed record's (re-exported here).

Pure: no clock (the daemon passes the wall-clock time it stamps), no I/O.
"""

from __future__ import annotations

import dataclasses
import datetime as dt
import enum
import re
from collections.abc import Mapping
from typing import Any, Final, get_args

from supervisord.protocol.jsonview import message_json
from supervisord.protocol.messages import Message
from supervisord.protocol.text import clean
from supervisord.record.jsonl import RecordUsageError
from supervisord.record.stop import Caller as CallerReport
from supervisord.record.stop import (
    Cause,
    Change,
    OutputOffReport,
    ProofTestResult,
    ProofTestStatus,
    Rearm,
    RecordKind,
    StopRecord,
    StopStepReport,
    StopTestReport,
)
from supervisord.safety.causes import CauseState
from supervisord.safety.decision import ChangeKind, Record
from supervisord.safety.events import (
    Caller,
    ClientCommand,
    ClientConnected,
    ClientDisconnected,
    ClientEstop,
    ClientHeartbeat,
    ClientHello,
    ClientHold,
    ClientRelease,
    Commissioned,
    DisplayUpdate,
    FleetKeepalive,
    FleetRelease,
    FleetStop,
    InternalFault,
    LinkBroken,
    LinkClosed,
    LinkOpened,
    LocalEstop,
    LocalRelease,
    OutputReadback,
    ProofTestRequest,
    ResetRequest,
    Shutdown,
    StopTested,
    Tick,
    VscReceived,
)
from supervisord.safety.prooftest import Outcome, ProofStatus
from supervisord.safety.stoptest import StopTestResult

JsonDict = dict[str, Any]


def record_kind(record: Record) -> RecordKind:
    """``state_change``, ``prooftest``, ``cause_raised``, the record's note
    (``rearm_refused``, ``commissioned``) or ``cause_cleared``, in that order of precedence
    (``docs/record.md``)."""
    if record.previous is not record.state:
        return RecordKind.STATE_CHANGE
    if record.prooftest is not None:
        return RecordKind.PROOFTEST  # its outcome is what the record is about
    if any(c.kind in (ChangeKind.RAISED, ChangeKind.UPDATED) for c in record.changes):
        return RecordKind.CAUSE_RAISED
    if record.note is not None:
        return RecordKind(record.note.value)  # every note is a kind (tests/record pin it)
    return RecordKind.CAUSE_CLEARED


def written_kind(record: Mapping[str, object]) -> RecordKind:
    """The kind a written record states (its ``kind`` field; a state change when absent).

    Raises :class:`~supervisord.record.jsonl.RecordUsageError` for an unknown kind."""
    kind = record.get("kind", RecordKind.STATE_CHANGE.value)
    if isinstance(kind, str) and kind in RecordKind.__members__.values():
        return RecordKind(kind)
    raise RecordUsageError(f"unknown record kind {kind!r}")


def caller_report(caller: Caller) -> CallerReport:
    """The caller; its login name escaped if it is not UTF-8 (``credentials.user_name``
    escapes it at the source already; this keeps every record and reply encodable)."""
    return CallerReport(uid=caller.uid, pid=caller.pid, name=clean(caller.name), admin=caller.admin)


def caller_json(caller: Caller) -> JsonDict:
    return caller_report(caller).json()


def cause_report(cause: CauseState) -> Cause:
    """One cause: ``name``, ``severity`` (``stop``/``hold``), ``active``, ``latched``, the
    monotonic times, and ``details`` (text values, e.g. ``{"sources": "remote"}``)."""
    return Cause(
        name=cause.cause,
        severity=cause.severity,
        active=cause.active,
        latched=cause.latched,
        raised_ns=cause.raised_ns,
        cleared_ns=cause.cleared_ns,
        details={clean(k): clean(v) for k, v in cause.details},  # may quote input text
    )


def cause_json(cause: CauseState) -> JsonDict:
    return cause_report(cause).json()


def proof_result(outcome: Outcome) -> ProofTestResult:
    """A finished proof test (docs/safety.md "The proof test"), as records and ``status``
    show it."""
    return ProofTestResult(
        result="passed" if outcome.passed else "failed",
        failure=None if outcome.failure is None else outcome.failure.name.lower(),
        trip_ms=outcome.trip_ms,
        cleared=None if outcome.cleared is None else outcome.cleared.value,
        cleared_ms=outcome.cleared_ms,
        text=outcome.text,
    )


def proof_status(status: ProofStatus) -> ProofTestStatus:
    """Where the proof test is, as ``status`` and ``state`` pushes show it."""
    return ProofTestStatus(
        policy=status.policy,
        phase=status.phase,
        last=None if status.last is None else proof_result(status.last),
    )


def stoptest_report(result: StopTestResult) -> StopTestReport:
    """A finished field stop test (SR-12.1), as its record and the ``stoptest`` reply show
    it; the same object as :meth:`StopTestResult.json`, which the flight recorder keeps."""
    limit = result.limit_ms
    return StopTestReport(
        result="passed" if result.passed else "failed",
        limit_ms=limit,
        steps=tuple(
            StopStepReport(
                source=step.source.value,
                seq=step.seq,
                stop_ns=step.stop_ns,
                passed=step.passed(limit),
                outputs=tuple(
                    OutputOffReport(
                        name=o.name,
                        off_ns=o.off_ns,
                        off_ms=o.off_ms,
                        off_delay_ms=o.off_delay_ms,
                        passed=o.passed(limit),
                    )
                    for o in step.outputs
                ),
            )
            for step in result.steps
        ),
        text=result.text,
    )


def _plain(value: object) -> object:
    """A trigger's field as JSON: messages through the protocol's JSON view."""
    if isinstance(value, Caller):
        return caller_report(value).json()
    if isinstance(value, enum.Enum):
        return value.value
    if isinstance(value, str):
        return clean(value)  # e.g. a link's or a fault's reason, which may quote input
    if isinstance(value, bool | int) or value is None:
        return value
    if isinstance(value, tuple):
        return [_plain(v) for v in value]
    if isinstance(value, _MESSAGE_TYPES):
        return message_json(value)
    return clean(repr(value)[:200])


_MESSAGE_TYPES: Final = get_args(Message)
_CAMEL = re.compile(r"(?<!^)(?=[A-Z])")

TRIGGER_EVENTS: Final[Mapping[type, str]] = {
    Tick: "tick",
    VscReceived: "vsc_received",
    LinkOpened: "link_opened",
    LinkBroken: "link_broken",
    LinkClosed: "link_closed",
    ClientConnected: "client_connected",
    ClientHello: "client_hello",
    ClientHeartbeat: "client_heartbeat",
    ClientEstop: "client_estop",
    ClientHold: "client_hold",
    ClientCommand: "client_command",
    ClientRelease: "client_release",
    ClientDisconnected: "client_disconnected",
    LocalEstop: "local_estop",
    LocalRelease: "local_release",
    ResetRequest: "reset_request",
    OutputReadback: "output_readback",
    InternalFault: "internal_fault",
    Shutdown: "shutdown",
    DisplayUpdate: "display_update",
    Commissioned: "commissioned",
    ProofTestRequest: "proof_test_request",
    StopTested: "stop_tested",
    FleetStop: "fleet_stop",
    FleetRelease: "fleet_release",
    FleetKeepalive: "fleet_keepalive",
}
"""A trigger's ``event`` name in the record, per core event type. Written out, not derived
from the class name, so that renaming a class in the code cannot change the record's format
(SR-7; ``tests/record/test_record_format.py`` checks every event type has its name)."""


def trigger_json(event: object) -> JsonDict:
    """What triggered a record: ``{"event": "client_estop", "connection": 3, ...}``; the
    fields of the event but its time, as JSON."""
    name = TRIGGER_EVENTS.get(type(event))
    if name is None:  # not a core event (never from the core): its class name, as text
        name = _CAMEL.sub("_", type(event).__name__).lower()
    result: JsonDict = {"event": name}
    if dataclasses.is_dataclass(event) and not isinstance(event, type):
        for field in dataclasses.fields(event):
            value = getattr(event, field.name)
            # A stop test's numbers are the record's own ``stoptest`` field, not repeated here.
            if field.name != "now" and not isinstance(value, StopTestResult):
                result[field.name] = _plain(value)
    return result


def record_json(record: Record, utc: dt.datetime, sequence_offset: int = 0) -> JsonDict:
    """A stop record as JSON, with the fields ``docs/record.md`` requires; ``utc`` (aware) is
    the wall-clock time the daemon stamped on it. ``seq`` continues after ``sequence_offset``,
    the last sequence number already in the store (the core counts from 1 at every start)."""
    return stop_record(record, utc, sequence_offset).json()


def stop_record(record: Record, utc: dt.datetime, sequence_offset: int = 0) -> StopRecord:
    """The record as the client API's typed value, whose encoder writes the record's JSON
    (:func:`record_json`): one encoder for the file, the journal and the ``record`` push."""
    rearm = None
    if record.rearm is not None:
        caller = record.rearm.caller
        rearm = Rearm(
            kind=record.rearm.kind,
            caller=None if caller is None else caller_report(caller),
        )
    return StopRecord(
        seq=sequence_offset + record.sequence,
        mono_ns=record.monotonic_ns,
        utc=utc.astimezone(dt.timezone.utc).isoformat(timespec="microseconds"),
        kind=record_kind(record),
        from_state=record.previous,
        to_state=record.state,
        causes=tuple(cause_report(c) for c in record.causes),
        changes=tuple(Change(name=c.cause, change=c.kind) for c in record.changes),
        trigger=trigger_json(record.trigger),
        reason=clean(record.reason) if record.reason else None,
        prooftest=None if record.prooftest is None else proof_result(record.prooftest),
        # A stop test's numbers are the record's own ``stoptest`` field (SR-12.1).
        stoptest=stoptest_report(record.trigger.result)
        if isinstance(record.trigger, StopTested)
        else None,
        rearm=rearm,
    )
