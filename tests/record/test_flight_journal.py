"""A stop's flight recorder window as a journal entry of its own (SR-13.12,
``supervisord/record/flight_journal.py``): the file's bytes come back whole or not at all, the
entry stays within the journal's limits, and the real journald takes one too large for a
datagram (the sealed memfd) and gives it back as the same text."""

from __future__ import annotations

import base64
import hashlib
import os
import subprocess
import sys
import zlib
from pathlib import Path

import pytest

from supervisord.journal_ids import FLIGHT_WINDOW_MESSAGE_ID, MESSAGE_IDS_BY_KIND
from supervisord.record.flight import FlightWriter, read_window
from supervisord.record.flight_journal import (
    MAX_FIELD,
    WindowEntryError,
    window_bytes,
    window_entry,
)
from supervisord.record.journal import FIELD_NAME, encode_native
from tests.journald import journal_entries
from tests.record.flight_rig import run, story


def _window_file(tmp_path: Path) -> tuple[bytes, dict[str, object]]:
    story_run = run(story(4.0), snapshot_at=[40])
    path = FlightWriter(tmp_path / "stops.jsonl", 1 << 20).write(story_run.window())
    (tmp_path / "written").symlink_to(path)
    return path.read_bytes(), story_run.stop


def test_a_window_comes_back_byte_for_byte(tmp_path: Path) -> None:
    """SR-13.12: the entry names its stop record (seq, mono_ns, utc) and holds the file's bytes,
    compressed: read back they are the file, which reads as the window; every field name is one
    journald keeps, the window's field one line of ASCII, and the MESSAGE_ID is no record
    kind's (the fleet's record lines never select it)."""
    data, stop = _window_file(tmp_path)
    fields = window_entry(data, stop)
    named = dict(fields)
    assert named["SRCS_SEQ"] == str(stop["seq"])
    assert named["SRCS_MONO_NS"] == str(stop["mono_ns"])
    assert named["SRCS_UTC"] == stop["utc"]
    assert named["SYSLOG_IDENTIFIER"] == "srcsd-flight"
    assert named["MESSAGE_ID"] == FLIGHT_WINDOW_MESSAGE_ID.hex
    assert FLIGHT_WINDOW_MESSAGE_ID not in MESSAGE_IDS_BY_KIND.values()
    assert all(FIELD_NAME.fullmatch(key) for key, _ in fields)
    text = named["SRCS_FLIGHT"]
    assert text.isascii()
    assert "\n" not in text
    assert len(text) < len(data) / 2  # JSON lines compress well
    encode_native(fields)  # journald's wire format takes it
    assert window_bytes(named) == data
    copy = tmp_path / "copy.jsonl"
    copy.write_bytes(window_bytes(named))
    assert read_window(copy).inputs == read_window((tmp_path / "written").resolve()).inputs


@pytest.mark.parametrize(
    "damage", ["cut", "flipped", "not base64", "length", "digest", "encoding", "missing"]
)
def test_a_damaged_entry_is_refused_never_half_a_window(tmp_path: Path, damage: str) -> None:
    """SR-13.12: a window's field cut short, changed, not base64, with another length, digest or
    encoding, or missing, is refused in words (``WindowEntryError``), never read in part."""
    data, stop = _window_file(tmp_path)
    named: dict[str, str | None] = dict(window_entry(data, stop))
    text = str(named["SRCS_FLIGHT"])
    if damage == "cut":
        named["SRCS_FLIGHT"] = text[: len(text) // 2 // 4 * 4]
    elif damage == "flipped":
        packed = bytearray(base64.b64decode(text))
        packed[len(packed) // 2] ^= 0x40
        named["SRCS_FLIGHT"] = base64.b64encode(bytes(packed)).decode()
    elif damage == "not base64":
        named["SRCS_FLIGHT"] = text[:-8] + "!!!!!!!!"
    elif damage == "length":
        named["SRCS_FLIGHT_BYTES"] = str(len(data) - 1)
    elif damage == "digest":
        named["SRCS_FLIGHT_SHA256"] = hashlib.sha256(b"another").hexdigest()
    elif damage == "encoding":
        named["SRCS_FLIGHT_ENCODING"] = "zstd+base64"
    else:
        named["SRCS_FLIGHT"] = None
    with pytest.raises(WindowEntryError):
        window_bytes(named)


def test_a_bomb_is_not_inflated_past_its_announced_length() -> None:
    """SR-13.12: a field that inflates to far more than its ``SRCS_FLIGHT_BYTES`` says is cut at
    one byte past it and refused; nothing larger than a record's ``max_bytes`` is announced."""
    bomb = base64.b64encode(zlib.compress(b"\0" * (64 << 20))).decode()
    fields = {
        "SRCS_FLIGHT_ENCODING": "zlib+base64",
        "SRCS_FLIGHT_BYTES": "100",
        "SRCS_FLIGHT_SHA256": "0" * 64,
        "SRCS_FLIGHT": bomb,
    }
    with pytest.raises(WindowEntryError, match="cut or damaged"):
        window_bytes(fields)
    with pytest.raises(WindowEntryError, match="not a window's length"):
        window_bytes({**fields, "SRCS_FLIGHT_BYTES": str(2 << 30)})


def test_a_window_past_the_journals_field_is_not_sent() -> None:
    """SR-13.12: a window whose field would pass MAX_FIELD (1 MiB; systemd 252 takes 768 MiB a
    field, but an entry must fit in one journal file) is refused before it is sent."""
    incompressible = os.urandom(MAX_FIELD)
    with pytest.raises(WindowEntryError, match="not sent"):
        window_entry(incompressible, {"seq": 7, "mono_ns": 1, "utc": "x"})


def test_the_real_journald_takes_a_window_too_large_for_a_datagram(tmp_path: Path) -> None:
    """SR-13.12: the robot's own journald (a private one) takes a window entry larger than a
    datagram (the sink passes it as a sealed memfd, as libsystemd does) and journalctl gives
    the field back as the same text, which decodes to the bytes sent."""
    script = (
        "import os, sys\n"
        "from supervisord.record.flight_journal import window_entry\n"
        "from supervisord.record.journal import JournalSink\n"
        "data = b''.join(os.urandom(32).hex().encode() + b'\\n' for _ in range(8000))\n"
        "open(sys.argv[1], 'wb').write(data)\n"
        "sink = JournalSink(sys.argv[2])\n"
        "assert sink.send(window_entry(data, {'seq': 9, 'mono_ns': 5, 'utc': 'u'}))\n"
    )
    sent = tmp_path / "sent.bin"
    entries = journal_entries(
        f'"$PYTHON" -c "$SCRIPT" {sent} "$SOCKET"', {"SCRIPT": script}, identifier="srcsd-flight"
    )
    assert len(entries) == 1
    text = entries[0]["SRCS_FLIGHT"]
    assert isinstance(text, str)
    assert len(text) > 212_992  # past the default datagram: the memfd went
    fields = {key: value for key, value in entries[0].items() if isinstance(value, str)}
    assert window_bytes(fields) == sent.read_bytes()


def test_a_window_and_its_entry_are_made_under_a_faked_wall_clock(tmp_path: Path) -> None:
    """SR-7.12, SR-13.12: under libfaketime with only the wall clock faked (the fleet tier's
    skewed robots), ``time.sleep`` fails with EINVAL; the lane's hand-overs of the interpreter
    do not use it, so the window's file and its journal entry are still made."""
    from supervisord.testkit.faketime import libfaketime  # noqa: PLC0415

    library = libfaketime()
    if library is None:
        pytest.skip("needs libfaketime (Debian package faketime)")
    script = (
        "import sys\n"
        "from supervisord.record.flight import FlightWriter\n"
        "from supervisord.record.flight_journal import window_bytes, window_entry\n"
        "from tests.record.flight_rig import run, story\n"
        "story_run = run(story(4.0))\n"
        "path = FlightWriter(sys.argv[1], 1 << 20).write(story_run.window())\n"
        "fields = dict(window_entry(path.read_bytes(), story_run.stop))\n"
        "assert window_bytes(fields) == path.read_bytes()\n"
        "print('made', path.stat().st_size)\n"
    )
    faked = {
        "LD_PRELOAD": str(library),
        "FAKETIME": "-420",
        "DONT_FAKE_MONOTONIC": "1",
        "FAKETIME_DONT_FAKE_MONOTONIC": "1",
        "FAKETIME_FORCE_MONOTONIC_FIX": "0",
    }
    done = subprocess.run(
        [sys.executable, "-c", script, str(tmp_path / "stops.jsonl")],
        capture_output=True,
        text=True,
        cwd=Path(__file__).resolve().parents[2],
        env={**os.environ, **faked},
        timeout=120,
        check=False,
    )
    assert done.returncode == 0, done.stderr[-2000:]
    assert done.stdout.startswith("made ")
