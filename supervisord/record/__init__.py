"""The record of stops (SR-7, ``docs/record.md``): an append-only JSON Lines file
with fsync per record and crash-safe rotation, and the systemd journal."""

from supervisord.record.journal import (
    JOURNAL_SOCKET,
    MESSAGE_IDS,
    JournalError,
    JournalSink,
    Priority,
    RecordKind,
    journal_fields,
    priority,
    record_kind,
)
from supervisord.record.jsonl import (
    REQUIRED_FIELDS,
    BadLine,
    BadLineReason,
    Record,
    RecordError,
    RecordUsageError,
    RecordWriter,
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
    "Record",
    "RecordError",
    "RecordKind",
    "RecordUsageError",
    "RecordWriter",
    "format_utc",
    "journal_fields",
    "last_record",
    "priority",
    "read_records",
    "record_files",
    "record_kind",
    "scan_file",
]
