"""The journal sink: MESSAGE_IDs, priorities, the field mapping, and the real wire format on
a journal socket of our own (supervisord.record.journal)."""

from __future__ import annotations

import errno
import json
import shutil
import struct
import subprocess
import sys
import textwrap
import uuid
from pathlib import Path

import pytest

from supervisord.record import (
    MESSAGE_IDS,
    JournalError,
    JournalSink,
    Priority,
    RecordKind,
    RecordUsageError,
    journal_fields,
    priority,
)
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


def test_sink_without_a_socket_is_unavailable(tmp_path: Path) -> None:
    """Without a journal socket the sink says why and its writes return False."""
    sent: list[tuple[str, ...]] = []
    sink = JournalSink(sendv=lambda *a: sent.append(a), socket_path=str(tmp_path / "nothing"))
    assert not sink.available
    assert sink.unavailable_reason is not None
    assert "no journal socket" in sink.unavailable_reason
    assert sink.write(make_record(0)) is False
    assert sent == []


def test_sink_on_a_plain_file_is_unavailable(tmp_path: Path) -> None:
    """A path that exists but is not a socket does not count as a journal."""
    (tmp_path / "socket").write_text("")
    sink = JournalSink(sendv=lambda *a: None, socket_path=str(tmp_path / "socket"))
    assert not sink.available


def _bound_socket(tmp_path: Path) -> str:
    import socket  # noqa: PLC0415  (only this helper needs it)

    path = str(tmp_path / "journal.sock")
    with socket.socket(socket.AF_UNIX, socket.SOCK_DGRAM) as s:
        s.bind(path)
    return path


def test_sink_passes_field_strings_to_sendv(tmp_path: Path) -> None:
    """With a journal socket, write hands sendv one "FIELD=value" string per field."""
    sent: list[tuple[str, ...]] = []
    sink = JournalSink(sendv=lambda *a: sent.append(a), socket_path=_bound_socket(tmp_path))
    assert sink.available
    assert sink.write(make_record(3)) is True
    assert sent == [tuple(f"{k}={v}" for k, v in journal_fields(make_record(3)))]


def test_sink_reports_a_refusal(tmp_path: Path) -> None:
    """An OSError from sendv becomes JournalError with its errno."""

    def refuse(*_: str) -> None:
        raise OSError(errno.ECONNREFUSED, "Connection refused")

    sink = JournalSink(sendv=refuse, socket_path=_bound_socket(tmp_path))
    with pytest.raises(JournalError) as e:
        sink.write(make_record(0))
    assert e.value.errno == errno.ECONNREFUSED


# The real thing: systemd.journal.sendv (libsystemd) always sends to the fixed path
# /run/systemd/journal/socket. In a private mount namespace with a fresh tmpfs on /run, the
# child binds that path itself and reads what libsystemd sends: the journal's native protocol.
NAMESPACE_CHILD = textwrap.dedent(
    """
    import os, socket, sys
    os.makedirs("/run/systemd/journal")
    s = socket.socket(socket.AF_UNIX, socket.SOCK_DGRAM)
    s.bind("/run/systemd/journal/socket")
    from supervisord.record import JournalSink
    from tests.record.conftest import make_record
    sink = JournalSink()
    assert sink.available, sink.unavailable_reason
    record = make_record(9, causes=("client_lost:nav", "vsc_estop"))
    record["trigger"] = "line one\\nline two"
    assert sink.write(record)
    sys.stdout.buffer.write(s.recv(1 << 16))
    """
)


def _parse_native(data: bytes) -> list[tuple[str, str]]:
    """Fields of one datagram in the journal's native protocol ("K=V\\n", or "K\\n" + 64-bit
    little-endian length + value + "\\n" for values with newlines)."""
    fields = []
    while data:
        head, _, rest = data.partition(b"\n")
        if b"=" in head:
            key, _, value = head.partition(b"=")
            data = rest
        else:
            key, (size,) = head, struct.unpack("<Q", rest[:8])
            value, data = rest[8 : 8 + size], rest[8 + size + 1 :]
        fields.append((key.decode(), value.decode()))
    return fields


def test_wire_format_on_a_journal_socket(tmp_path: Path) -> None:
    """systemd.journal.sendv delivers every field, repeated SRCS_CAUSE and multi-line values
    included, to a journal socket (our own, in a private mount namespace)."""
    unshare = shutil.which("unshare")
    if unshare is None:
        pytest.skip("no unshare(1): cannot give the child its own /run")
    root = Path(__file__).resolve().parents[2]
    script = f'mount -t tmpfs tmpfs /run && exec "{sys.executable}" -c "$0"'
    result = subprocess.run(
        [unshare, "--mount", "--propagation", "private", "sh", "-c", script, NAMESPACE_CHILD],
        capture_output=True,
        cwd=root,
        timeout=30,
        check=False,
    )
    if result.returncode != 0 and b"Operation not permitted" in result.stderr:
        pytest.skip("no permission for a private mount namespace (needs root)")
    assert result.returncode == 0, result.stderr.decode()
    received = _parse_native(result.stdout)
    record = make_record(9, causes=("client_lost:nav", "vsc_estop"))
    record["trigger"] = "line one\nline two"
    assert received == journal_fields(record)
    assert uuid.UUID(dict(received)["MESSAGE_ID"]) == MESSAGE_IDS[RecordKind.STATE_CHANGE]
