"""The record of stops (SR-7, ``docs/record.md``): its format (:mod:`.format`), an
append-only JSON Lines file with fsync per record and crash-safe rotation (:mod:`.jsonl`), and
the systemd journal (:mod:`.journal`)."""

from supervisord.record.format import RecordKind, record_json, record_kind, written_kind
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
