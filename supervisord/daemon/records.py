"""The safety core's records as the JSON objects of the stop record (safety-rules.md §7).

The core has no wall clock: the daemon stamps UTC here, once, when it writes the record.
Field names are those ``supervisord.record`` files and filters on; ``docs/record.md`` lists
them.
"""

from __future__ import annotations

import dataclasses
import datetime as dt
import enum
from typing import Any

from supervisord.protocol.jsonview import message_json
from supervisord.protocol.messages import Message
from supervisord.record.jsonl import format_utc
from supervisord.safety.causes import CauseState
from supervisord.safety.decision import ChangeKind, Record
from supervisord.safety.events import Caller, Event, VscReceived

JsonDict = dict[str, Any]


def _snake(name: str) -> str:
    return "".join(f"_{ch.lower()}" if ch.isupper() else ch for ch in name).lstrip("_")


def cause_json(cause: CauseState) -> JsonDict:
    return {
        "name": cause.name,
        "severity": cause.severity.value,
        "active": cause.active,
        "latched": cause.latched,
        "raised_ns": cause.raised_ns,
        "cleared_ns": cause.cleared_ns,
        **dict(cause.details),
    }


def trigger_json(event: Event) -> JsonDict:
    """The input that caused the record: its kind and its fields (a VSC message as decoded)."""
    body: JsonDict = {"event": _snake(type(event).__name__)}
    if isinstance(event, VscReceived):
        body["message"] = message_json(event.message)
        return body
    for field in dataclasses.fields(event):
        if field.name == "now":
            continue
        value = getattr(event, field.name)
        if isinstance(value, Caller):
            value = dataclasses.asdict(value)
        elif isinstance(value, enum.Enum):
            value = value.value
        elif isinstance(value, Message):
            value = message_json(value)
        body[field.name] = value
    return body


def record_kind(record: Record) -> str:
    """Which MESSAGE_ID the journal gives it (``supervisord.record.journal``)."""
    if record.previous is not record.state:
        return "state_change"
    if any(change.kind is ChangeKind.RAISED for change in record.changes):
        return "cause_raised"
    return "cause_cleared"


def record_json(record: Record, utc: dt.datetime, sequence_offset: int = 0) -> JsonDict:
    """The stop-record entry for ``record``, written at wall-clock time ``utc``; its ``seq``
    continues after ``sequence_offset``, the last one in the file."""
    result: JsonDict = {
        "seq": sequence_offset + record.sequence,
        "mono_ns": record.monotonic_ns,
        "utc": format_utc(utc),
        "kind": record_kind(record),
        "from": record.previous.value,
        "to": record.state.value,
        "causes": [cause_json(cause) for cause in record.causes],
        "changes": [{"name": c.cause.name, "change": c.kind.value} for c in record.changes],
        "trigger": trigger_json(record.trigger),
    }
    if record.rearm is not None:
        caller = record.rearm.caller
        result["rearm"] = {
            "kind": record.rearm.kind.value,
            "caller": dataclasses.asdict(caller) if caller else None,
        }
    return result
