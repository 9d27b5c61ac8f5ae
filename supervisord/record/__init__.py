"""The record of stops (SR-7, ``docs/record.md``): the typed record every reader shares
(:mod:`.stop`), its making from the safety core's record (:mod:`.format`), an
append-only JSON Lines file with fsync per record and crash-safe rotation (:mod:`.jsonl`), and
the systemd journal (:mod:`.journal`)."""

import importlib
from typing import TYPE_CHECKING, Any

if TYPE_CHECKING:  # the names' types, for the type checker; loaded lazily at run time
    from supervisord.record.format import record_json, record_kind, written_kind
    from supervisord.record.journal import (
        JOURNAL_SOCKET,
        MESSAGE_IDS,
        JournalError,
        JournalSink,
        Priority,
        journal_fields,
        priority,
    )
    from supervisord.record.jsonl import (
        REQUIRED_FIELDS,
        BadLine,
        BadLineReason,
        RecordError,
        RecordUnreadable,
        RecordUsageError,
        RecordWriter,
        StoredRecord,
        format_utc,
        last_record,
        read_records,
        record_files,
        scan_file,
    )
    from supervisord.record.stop import RecordKind

_HOMES = {
    "RecordKind": "stop",
    "record_json": "format",
    "record_kind": "format",
    "written_kind": "format",
    **dict.fromkeys(
        ("JOURNAL_SOCKET", "MESSAGE_IDS", "JournalError", "JournalSink", "Priority"), "journal"
    ),
    **dict.fromkeys(("journal_fields", "priority"), "journal"),
    **dict.fromkeys(
        ("REQUIRED_FIELDS", "BadLine", "BadLineReason", "RecordError", "RecordUnreadable"),
        "jsonl",
    ),
    **dict.fromkeys(
        ("RecordUsageError", "RecordWriter", "StoredRecord", "format_utc", "last_record"),
        "jsonl",
    ),
    **dict.fromkeys(("read_records", "record_files", "scan_file"), "jsonl"),
}
"""Where each name of the package lives. Loaded when first asked for (PEP 562), so that a
client importing the typed record (:mod:`.stop`) does not load the writers and the safety
core with it (docs/ros2.md "The client library")."""


def __getattr__(name: str) -> Any:
    home = _HOMES.get(name)
    if home is None:
        raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
    return getattr(importlib.import_module(f"{__name__}.{home}"), name)


__all__ = [
    "JOURNAL_SOCKET",
    "MESSAGE_IDS",
    "REQUIRED_FIELDS",
    "BadLine",
    "BadLineReason",
    "JournalError",
    "JournalSink",
    "Priority",
    "RecordError",
    "RecordKind",
    "RecordUnreadable",
    "RecordUsageError",
    "RecordWriter",
    "StoredRecord",
    "format_utc",
    "journal_fields",
    "last_record",
    "priority",
    "read_records",
    "record_files",
    "record_json",
    "record_kind",
    "scan_file",
    "written_kind",
]
