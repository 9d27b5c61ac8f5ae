"""The stop record's format (SR-7, docs/record.md "Fields"): what the daemon writes for a core
record (supervisord.record.format)."""

from __future__ import annotations

import dataclasses
import datetime as dt

import pytest

from supervisord.protocol.messages import VscHeartbeat
from supervisord.record.format import (
    TRIGGER_EVENTS,
    record_json,
    trigger_json,
    written_kind,
)
from supervisord.record.journal import MESSAGE_IDS, journal_fields
from supervisord.record.jsonl import REQUIRED_FIELDS, RecordUsageError
from supervisord.record.jsonl import encode as encode_record
from supervisord.record.stop import RecordKind
from supervisord.safety.config import SafetyConfig
from supervisord.safety.core import SafetyCore
from supervisord.safety.decision import Record, RecordNote
from supervisord.safety.events import EVENT_TYPES, Caller, ClientHello, LocalEstop, VscReceived
from supervisord.safety.transitions import State

UTC = dt.datetime(2026, 3, 1, 12, tzinfo=dt.timezone.utc)
ROOT = Caller(0, 42, "root", True)

TRIGGERS = {
    "tick": (),
    "vsc_received": ("message",),
    "link_opened": (),
    "link_broken": ("reason",),
    "link_closed": ("reason",),
    "client_connected": ("connection", "uid"),
    "client_hello": ("connection", "name", "caller"),
    "client_heartbeat": ("connection", "progress"),
    "client_estop": ("connection",),
    "client_hold": ("connection",),
    "client_command": ("connection", "nonzero"),
    "client_release": ("connection", "request"),
    "client_disconnected": ("connection",),
    "local_estop": ("caller",),
    "local_release": ("caller",),
    "reset_request": ("caller",),
    "output_readback": ("output", "requested", "read_back"),
    "internal_fault": ("reason",),
    "shutdown": ("reason",),
    "display_update": ("message",),
    "commissioned": ("caller", "key85", "remote_status"),
    "proof_test_request": ("caller",),
    "stop_tested": ("caller", "result"),
    "fleet_stop": ("connection", "caller", "stop_id", "sender"),  # SR-8.19
    "fleet_release": ("connection", "caller", "stop_id", "sender"),
    "fleet_keepalive": ("connection", "caller", "sender"),  # SR-8.21
}
"""Every trigger's ``event`` name and its fields, as records written so far carry them."""


def test_record_json_is_a_record_the_store_accepts() -> None:
    """SR-7: record_json has every field docs/record.md requires, and the JSON Lines store
    files it."""
    (record,) = SafetyCore(SafetyConfig(), 0).decision.records
    utc = dt.datetime(2026, 3, 1, 12, tzinfo=dt.timezone.utc)
    obj = record_json(record, utc)
    assert set(REQUIRED_FIELDS) <= set(obj)
    assert obj["utc"] == "2026-03-01T12:00:00.000000+00:00"
    assert obj["from"] == "STOPPED"
    assert obj["trigger"] == {"event": "tick"}
    assert encode_record(obj).endswith(b"\n")


def test_record_kind_and_trigger_follow_the_change() -> None:
    """SR-7: a local e-stop while already STOPPED is a cause_raised record naming its caller."""
    core = SafetyCore(SafetyConfig(), 0)
    decision = core.handle(LocalEstop(5, ROOT))
    (record,) = decision.records
    obj = record_json(record, dt.datetime(2026, 3, 1, tzinfo=dt.timezone.utc))
    assert obj["kind"] == "cause_raised"
    assert obj["trigger"] == {
        "event": "local_estop",
        "caller": {"uid": 0, "pid": 42, "name": "root", "admin": True},
    }
    assert {"name": "local_estop", "change": "raised"} in obj["changes"]


def test_trigger_of_a_vsc_message_uses_the_protocol_json() -> None:
    """SR-7: a VSC message in a trigger is shown with the same JSON as srcsctl decode."""
    obj = trigger_json(VscReceived(1, VscHeartbeat(mode=9)))
    assert obj["event"] == "vsc_received"
    assert obj["message"]["type"] == "vsc_heartbeat"
    assert obj["message"]["vsc_mode_name"] == "operational"


def test_every_core_event_keeps_its_trigger_name_and_fields() -> None:
    """SR-7: each core event type appears in a record's trigger under its fixed name with its
    fixed fields, so renaming a class or adding an event cannot change what older records and
    their readers mean (a new event must be given a name here and in the format)."""
    assert set(TRIGGER_EVENTS) == set(EVENT_TYPES)
    found = {
        TRIGGER_EVENTS[t]: tuple(f.name for f in dataclasses.fields(t) if f.name != "now")
        for t in EVENT_TYPES
    }
    assert found == TRIGGERS


@pytest.mark.parametrize("note", list(RecordNote))
def test_every_note_the_core_makes_is_a_kind_the_journal_files(note: RecordNote) -> None:
    """SR-7: a record the core notes (e.g. ``hello_refused``, SR-8.6) gets a kind of its own in
    the record and a MESSAGE_ID in the journal, so the journal's copy is never lost to it."""
    record = Record(
        sequence=1,
        monotonic_ns=5,
        previous=State.STOPPED,
        state=State.STOPPED,
        causes=(),
        changes=(),
        trigger=ClientHello(5, 1, "nav"),
        note=note,
    )
    obj = record_json(record, UTC)
    assert obj["kind"] == note.value
    assert written_kind(obj) is RecordKind(note.value)
    fields = dict(journal_fields(obj))
    assert fields["SRCS_KIND"] == note.value
    assert fields["MESSAGE_ID"] == MESSAGE_IDS[RecordKind(note.value)].hex


def test_a_written_kind_is_read_back_and_an_unknown_one_refused() -> None:
    """SR-7: a written record without ``kind`` is a state change; an unknown kind is a usage
    error, never a guess."""
    assert written_kind({}) is RecordKind.STATE_CHANGE
    assert written_kind({"kind": "cause_cleared"}) is RecordKind.CAUSE_CLEARED
    with pytest.raises(RecordUsageError, match="unknown record kind"):
        written_kind({"kind": "sideways"})
