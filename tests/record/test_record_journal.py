"""The journal sink: MESSAGE_IDs, priorities, the field mapping, and the real wire format on
a journal socket of our own (supervisord.record.journal)."""

from __future__ import annotations

import array
import errno
import fcntl
import json
import os
import socket
import struct
import sys
import time
import uuid
from collections.abc import Iterator
from pathlib import Path

import pytest

from supervisord.record.journal import (
    MESSAGE_IDS,
    SEND_TIMEOUT_S,
    JournalError,
    JournalSink,
    Priority,
    encode_native,
    journal_fields,
    priority,
)
from supervisord.record.jsonl import RecordUsageError
from supervisord.record.stop import RecordKind
from tests.journald import journal_entries
from tests.record.conftest import make_record


def test_message_ids_are_fixed_and_distinct() -> None:
    """SR-7.3: each record kind has its own MESSAGE_ID, and they never change."""
    assert {k: v.hex for k, v in MESSAGE_IDS.items()} == {
        RecordKind.STATE_CHANGE: "26c2f33dae3d4a6c8996fc9bc658ad32",
        RecordKind.CAUSE_RAISED: "820501387c1a46049b855bcae8bc9ba2",
        RecordKind.CAUSE_CLEARED: "fd9e4e6d79c643eb9a534d2f8228aa89",
        RecordKind.REARM_REFUSED: "2be6051d1b7c43d0a0bfd08ad06caac8",
        RecordKind.COMMISSIONED: "bdd0782d2f2b45a3bdc4e9984db1024d",
        RecordKind.PROOFTEST: "af4347b3c6a741d6a06ce07e58cea85a",
        RecordKind.HELLO_REFUSED: "31b39d5239c64c748a02ea76dd76a97f",
        RecordKind.STOPTEST: "55afb9fa858e45458a44937c4062ca84",
    }


@pytest.mark.parametrize(
    ("record", "expected"),
    [
        (make_record(0, before="RUN", to="STOPPED"), Priority.CRIT),
        (make_record(0, before="HOLD", to="stopped"), Priority.CRIT),
        (make_record(0, before="STOPPED", to="STOPPED"), Priority.NOTICE),
        (make_record(0, before="STOPPED", to="HOLD"), Priority.NOTICE),
        (make_record(0, before="HOLD", to="RUN"), Priority.NOTICE),
        (make_record(0, kind="cause_raised"), Priority.WARNING),
        (make_record(0, kind="rearm_refused"), Priority.WARNING),
        (make_record(0, kind="commissioned"), Priority.WARNING),
        (make_record(0, kind="cause_cleared"), Priority.NOTICE),
    ],
)
def test_priority(record: dict[str, object], expected: Priority) -> None:
    """SR-7.3: a change into STOPPED is CRIT; raised causes, refused re-arms and commissioning
    WARNING; others NOTICE."""
    assert priority(record) is expected


def test_fields_of_a_stop() -> None:
    """SR-7.3: a stop maps to MESSAGE, its MESSAGE_ID, CRIT and SRCS_* fields, one SRCS_CAUSE per
    cause."""
    record = make_record(7, causes=("vsc_estop", "client_lost:nav"))
    fields = journal_fields(record)
    as_dict = dict(fields)
    assert (
        as_dict["MESSAGE"]
        == "RUN -> STOPPED: causes vsc_estop, client_lost:nav; trigger vsc_heartbeat"
    )
    assert as_dict["MESSAGE_ID"] == "26c2f33dae3d4a6c8996fc9bc658ad32"
    assert as_dict["PRIORITY"] == "2"
    assert as_dict["SYSLOG_IDENTIFIER"] == "srcsd"
    assert as_dict["SRCS_KIND"] == "state_change"
    assert (as_dict["SRCS_SEQ"], as_dict["SRCS_FROM"], as_dict["SRCS_TO"]) == (
        "7",
        "RUN",
        "STOPPED",
    )
    assert as_dict["SRCS_MONO_NS"] == "1007000000"
    assert as_dict["SRCS_UTC"] == record["utc"]
    assert as_dict["SRCS_TRIGGER"] == "vsc_heartbeat"
    assert [v for k, v in fields if k == "SRCS_CAUSE"] == ["vsc_estop", "client_lost:nav"]
    assert json.loads(as_dict["SRCS_CAUSES"]) == record["causes"]


def test_a_reason_is_in_the_message_and_its_own_field() -> None:
    """A refused re-arm or a commissioning says why, in MESSAGE and in SRCS_REASON."""
    record = {**make_record(3, kind="commissioned", before="RUN", to="RUN"), "reason": "key85=1"}
    fields = dict(journal_fields(record))
    assert fields["MESSAGE"].startswith("VSC commissioned: key85=1")
    assert fields["SRCS_REASON"] == "key85=1"
    assert fields["MESSAGE_ID"] == MESSAGE_IDS[RecordKind.COMMISSIONED].hex
    assert "SRCS_REASON" not in dict(journal_fields(make_record(4)))


def test_structured_trigger_is_json() -> None:
    """A trigger that is an object goes to the journal as compact, sorted JSON."""
    record = make_record(1) | {"trigger": {"frame": "vsc_heartbeat", "estop": 1}}
    assert dict(journal_fields(record))["SRCS_TRIGGER"] == '{"estop":1,"frame":"vsc_heartbeat"}'


def test_bad_records_are_refused() -> None:
    """An unknown kind or malformed causes raise RecordUsageError."""
    with pytest.raises(RecordUsageError):
        journal_fields(make_record(0, kind="shrug"))
    with pytest.raises(RecordUsageError):
        journal_fields(make_record(0) | {"causes": None})


def test_field_names_journald_would_drop_are_refused() -> None:
    """SR-7.3: encode_native refuses a field name journald would drop (lower case, leading
    underscore or digit, longer than 64) instead of sending an entry that loses it."""
    for name in ("message", "_PID", "1ST", "A" * 65, "SRCS-X", ""):
        with pytest.raises(RecordUsageError):
            encode_native([(name, "x")])
    assert encode_native([("A" * 64, "x")]) == b"A" * 64 + b"=x\n"


def test_native_encoding_of_plain_and_multiline_values() -> None:
    """SR-7.3: a value without a newline is KEY=value; one with a newline takes the binary
    form, KEY, newline, its 64-bit little-endian length, the bytes, newline."""
    data = encode_native([("MESSAGE", "one"), ("SRCS_TRIGGER", "a\nb"), ("EMPTY", "")])
    assert data == b"MESSAGE=one\nSRCS_TRIGGER\n" + struct.pack("<Q", 3) + b"a\nb\nEMPTY=\n"


def test_sink_without_a_socket_is_unavailable(tmp_path: Path) -> None:
    """SR-7.3: without a journal socket the sink says why and its writes return False."""
    with JournalSink(socket_path=str(tmp_path / "nothing")) as sink:
        assert not sink.available
        assert sink.unavailable_reason is not None
        assert "no journal socket" in sink.unavailable_reason
        assert sink.write(make_record(0)) is False


def test_sink_on_a_plain_file_is_unavailable(tmp_path: Path) -> None:
    """SR-7.3: a path that exists but is not a socket does not count as a journal."""
    (tmp_path / "socket").write_text("")
    with JournalSink(socket_path=str(tmp_path / "socket")) as sink:
        assert not sink.available
        assert sink.write(make_record(0)) is False


# A journal socket of the test's own, read as journald reads it (the native protocol of
# systemd.io/JOURNAL_NATIVE_PROTOCOL): the sink's bytes are checked against the protocol, not
# against the sink's own encoder.


def _parse_native(data: bytes) -> list[tuple[str, str]]:
    """Fields of one entry in the journal's native protocol ("K=V\n", or "K\n" + 64-bit
    little-endian length + value + "\n" for values with newlines)."""
    fields = []
    while data:
        head, newline, rest = data.partition(b"\n")
        assert newline, f"field without its newline: {head[:40]!r}"
        if b"=" in head:
            key, _, value = head.partition(b"=")
            data = rest
        else:
            key, (size,) = head, struct.unpack("<Q", rest[:8])
            value = rest[8 : 8 + size]
            assert rest[8 + size : 9 + size] == b"\n", "binary value without its newline"
            data = rest[9 + size :]
        fields.append((key.decode(), value.decode()))
    return fields


class JournalReader:
    """A bound datagram socket that takes entries as datagrams or as memfds (SCM_RIGHTS)."""

    def __init__(self, path: Path) -> None:
        self.path = str(path)
        self.sock = socket.socket(socket.AF_UNIX, socket.SOCK_DGRAM)
        self.sock.bind(self.path)
        self.sock.settimeout(5)
        self.seals: int | None = None

    def receive(self) -> list[tuple[str, str]]:
        data, ancillary, _, _ = self.sock.recvmsg(1 << 16, socket.CMSG_SPACE(4))
        self.seals = None
        for level, kind, payload in ancillary:
            assert (level, kind) == (socket.SOL_SOCKET, socket.SCM_RIGHTS)
            (fd,) = array.array("i", payload[:4])
            try:
                self.seals = fcntl.fcntl(fd, fcntl.F_GET_SEALS)
                data = os.pread(fd, os.fstat(fd).st_size, 0)
            finally:
                os.close(fd)
        return _parse_native(data)

    def close(self) -> None:
        self.sock.close()


@pytest.fixture
def reader(tmp_path: Path) -> Iterator[JournalReader]:
    """A journal socket of the test's own in ``tmp_path``."""
    journal = JournalReader(tmp_path / "journal.sock")
    yield journal
    journal.close()


def test_entry_on_a_journal_socket(reader: JournalReader) -> None:
    """SR-7.3: the sink sends every field to the journal socket it was given, in journald's
    native protocol, repeated SRCS_CAUSE and a multi-line value included."""
    record = make_record(9, causes=("client_lost:nav", "vsc_estop"))
    record["trigger"] = "line one\nline two"
    with JournalSink(socket_path=reader.path) as sink:
        assert sink.available, sink.unavailable_reason
        assert sink.write(record) is True
    received = reader.receive()
    assert received == journal_fields(record)
    assert uuid.UUID(dict(received)["MESSAGE_ID"]) == MESSAGE_IDS[RecordKind.STATE_CHANGE]
    assert reader.seals is None, "a small entry goes as a datagram, not a memfd"


def test_a_large_entry_goes_through_a_sealed_memfd(reader: JournalReader) -> None:
    """SR-7.3: an entry too large for one datagram is passed as a sealed memfd (SCM_RIGHTS),
    as journald's protocol allows, and arrives whole."""
    record = make_record(10) | {"trigger": "x" * 400_000 + "\nend"}
    with JournalSink(socket_path=reader.path) as sink:
        assert sink.write(record) is True
    assert reader.receive() == journal_fields(record)
    assert reader.seals is not None, "the large entry did not come as a file descriptor"
    wanted = fcntl.F_SEAL_SHRINK | fcntl.F_SEAL_GROW | fcntl.F_SEAL_WRITE
    assert reader.seals & wanted == wanted


def test_sink_reports_a_refusal(tmp_path: Path) -> None:
    """SR-7.3: a journal socket nobody listens on any more (journald gone) refuses the entry:
    JournalError with its errno."""
    journal = JournalReader(tmp_path / "journal.sock")
    with JournalSink(socket_path=journal.path) as sink:
        journal.close()  # the socket file stays, nobody reads it
        with pytest.raises(JournalError) as e:
            sink.write(make_record(0))
    assert e.value.errno == errno.ECONNREFUSED


def test_a_stuck_journal_refuses_after_a_bounded_wait(reader: JournalReader) -> None:
    """SR-7.5: when journald stops reading and its queue is full, a write gives up after
    SEND_TIMEOUT_S with JournalError instead of holding the sink thread for good."""
    refusal: JournalError | None = None
    with JournalSink(socket_path=reader.path) as sink:
        for seq in range(100_000):  # the queue holds a few hundred entries at most
            started = time.monotonic()
            try:
                sink.write(make_record(seq))
            except JournalError as error:
                refusal = error
                break
    took = time.monotonic() - started
    assert refusal is not None, "a journal that reads nothing never refused an entry"
    assert refusal.errno == errno.EAGAIN
    assert SEND_TIMEOUT_S * 0.9 <= took < SEND_TIMEOUT_S + 20


# The real journald (tests/journald.py): the sink's entries read back with journalctl.


def _journald_records() -> list[dict[str, object]]:
    stop = make_record(21, causes=("client_lost:nav", "vsc_estop"))
    stop["trigger"] = "line one\nline two"
    large = make_record(22, kind="cause_raised") | {"trigger": "y" * 300_000}
    return [stop, large]


def _send_to(socket_path: str) -> None:
    """In the journald child: send the records through the sink."""
    with JournalSink(socket_path=socket_path) as sink:
        for record in _journald_records():
            assert sink.write(record), sink.unavailable_reason


def test_a_real_journald_stores_every_field() -> None:
    """SR-7.3: systemd-journald itself (a private instance) stores each entry the sink sends,
    datagram and memfd alike, with its MESSAGE_ID, PRIORITY, every SRCS_CAUSE and the
    multi-line value, as journalctl reads them back."""
    entries = journal_entries('"$PYTHON" -m tests.record.test_record_journal "$SOCKET"')
    assert len(entries) == 2, [entry.get("MESSAGE_ID") for entry in entries]
    for entry, record in zip(entries, _journald_records(), strict=True):
        expected: dict[str, object] = {}
        for key, value in journal_fields(record):
            if key in expected:  # journalctl -o json lists a repeated field as an array
                before = expected[key]
                expected[key] = [*(before if isinstance(before, list) else [before]), value]
            else:
                expected[key] = value
        assert {k: entry.get(k) for k in expected} == expected
        assert entry["_TRANSPORT"] == "journal"


if __name__ == "__main__":  # the journald child's sender (test_a_real_journald_stores_every_field)
    _send_to(sys.argv[1])
