"""The JSON Lines record store: writing, rotation, torn tails, errors and reading
(supervisord.record.jsonl)."""

from __future__ import annotations

import datetime as dt
import errno
import json
import os
from pathlib import Path

import pytest

from supervisord.record import jsonl
from supervisord.record.jsonl import (
    BadLine,
    BadLineReason,
    RecordError,
    RecordUsageError,
    RecordWriter,
    StoredRecord,
    last_record,
    read_records,
    record_files,
    scan_file,
)
from tests.record.conftest import EPOCH, full_disk, make_record, records_in, seqs_in


def test_append_writes_one_line_per_record(tmp_path: Path) -> None:
    """Each record is one compact JSON line that reads back equal."""
    path = tmp_path / "stops.jsonl"
    with RecordWriter(path) as w:
        w.append(make_record(0))
        w.append(make_record(1, causes=("client_lost:autonomy", "vsc_link_lost")))
    lines = path.read_bytes().split(b"\n")
    assert lines[-1] == b""
    assert [json.loads(line)["seq"] for line in lines[:-1]] == [0, 1]
    [first, second] = records_in(path)
    assert first.data == make_record(0)
    assert second.cause_names == ("client_lost:autonomy", "vsc_link_lost")
    assert (second.file, second.line) == (path, 2)


def test_file_mode_is_not_world_readable(tmp_path: Path) -> None:
    """A new record file is created with mode 0640 (before the umask)."""
    path = tmp_path / "stops.jsonl"
    RecordWriter(path).close()
    assert path.stat().st_mode & 0o007 == 0


def test_fsync_per_record_and_directory_on_create(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """SR-7.2: every append fsyncs the file before returning; a created file's directory is
    fsynced before its first record goes in, by the first append, not by the open, which the
    daemon's start does on the real-time loop's thread (SR-7.5, SR-9.8)."""
    synced: list[str] = []
    real_fsync = os.fsync

    def fsync(fd: int) -> None:
        synced.append("dir" if os.path.isdir(f"/proc/self/fd/{fd}") else "file")
        real_fsync(fd)

    monkeypatch.setattr(os, "fsync", fsync)
    with RecordWriter(tmp_path / "stops.jsonl", keep_transitions=False) as w:
        assert synced == []
        w.append(make_record(0))
        w.append(make_record(1))
    assert synced == ["dir", "file", "file"]


def test_unicode_and_newlines_stay_on_one_line(tmp_path: Path) -> None:
    """Text with newlines and non-ASCII characters stays inside one line and reads back."""
    path = tmp_path / "stops.jsonl"
    record = make_record(0) | {"trigger": "operator:\nJürgen"}
    with RecordWriter(path) as w:
        w.append(record)
    assert path.read_bytes().count(b"\n") == 1
    assert records_in(path)[0].data["trigger"] == "operator:\nJürgen"


@pytest.mark.parametrize(
    "change",
    [
        {"seq": None},
        {"seq": True},
        {"mono_ns": 1.5},
        {"utc": "2026-03-01T12:00:00"},
        {"utc": "yesterday"},
        {"causes": "vsc_estop"},
        {"causes": [{"details": 1}]},
        {"trigger": float("nan")},
        {"trigger": object()},
    ],
)
def test_malformed_record_is_refused_and_nothing_written(
    tmp_path: Path, change: dict[str, object]
) -> None:
    """A record the store cannot file raises RecordUsageError and writes nothing."""
    path = tmp_path / "stops.jsonl"
    with RecordWriter(path) as w:
        with pytest.raises(RecordUsageError):
            w.append(make_record(0) | change)
        w.append(make_record(1))
    assert seqs_in(path) == [1]


def test_missing_field_is_refused(tmp_path: Path) -> None:
    """A record without a required field raises RecordUsageError naming it."""
    record = make_record(0)
    del record["trigger"]
    with RecordWriter(tmp_path / "s.jsonl") as w, pytest.raises(RecordUsageError, match="trigger"):
        w.append(record)


def test_closed_writer_refuses(tmp_path: Path) -> None:
    """Appending after close raises RecordUsageError; close is idempotent."""
    w = RecordWriter(tmp_path / "s.jsonl")
    w.close()
    w.close()
    with pytest.raises(RecordUsageError, match="closed"):
        w.append(make_record(0))


@pytest.mark.parametrize(("max_bytes", "keep"), [(4095, 1), (4096, 0), (4096, 100)])
def test_bounds_are_checked(tmp_path: Path, max_bytes: int, keep: int) -> None:
    """max_bytes below 4096 or keep outside 1-99 is refused before any file is made."""
    with pytest.raises(RecordUsageError):
        RecordWriter(tmp_path / "s.jsonl", max_bytes=max_bytes, keep=keep)
    assert list(tmp_path.iterdir()) == []


def test_rotation_is_bounded_and_drops_the_oldest(tmp_path: Path) -> None:
    """SR-7.2: files never exceed max_bytes, at most keep rotated files remain, and what remains is
    the newest records, in order, without a gap."""
    path = tmp_path / "stops.jsonl"
    with RecordWriter(path, max_bytes=4096, keep=3) as w:
        for seq in range(200):
            w.append(make_record(seq, pad=100))
    files = record_files(path)
    assert files == [path.with_name(f"stops.jsonl.{n}") for n in (3, 2, 1)] + [path]
    assert all(f.stat().st_size <= 4096 for f in files)
    seqs = seqs_in(path)
    assert seqs == list(range(seqs[0], 200))
    assert seqs[0] > 0


def test_oversized_record_gets_a_file_of_its_own(tmp_path: Path) -> None:
    """A record larger than max_bytes is still written, alone in a fresh file."""
    path = tmp_path / "stops.jsonl"
    with RecordWriter(path, max_bytes=4096, keep=2) as w:
        w.append(make_record(0))
        w.append(make_record(1, pad=5000))
        w.append(make_record(2))
    assert [len(list(scan_file(f))) for f in record_files(path)] == [1, 1, 1]
    assert seqs_in(path) == [0, 1, 2]


def test_torn_tail_is_truncated_on_open(tmp_path: Path) -> None:
    """SR-7.2: a partial last line left by a crash is cut off on open, so the next record starts on
    a line of its own, and nothing acknowledged is lost."""
    path = tmp_path / "stops.jsonl"
    with RecordWriter(path) as w:
        w.append(make_record(0))
    whole = path.read_bytes()
    torn = json.dumps(make_record(1)).encode()[:37]
    path.write_bytes(whole + torn)
    with RecordWriter(path) as w:
        assert w.repaired_bytes == len(torn)
        assert path.read_bytes() == whole
        w.append(make_record(2))
    assert seqs_in(path) == [0, 2]
    assert not any(isinstance(i, BadLine) for i in read_records(path))


def test_a_torn_tails_cut_is_made_durable_by_the_first_append_not_by_the_open(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """SR-7.2, SR-7.5, SR-9.8: the open cuts a torn tail and waits on no disk (the daemon's
    start opens on the real-time loop's thread); the first append makes the directory and the
    cut durable before its record goes in, then the record."""
    path = tmp_path / "stops.jsonl"
    with RecordWriter(path, keep_transitions=False) as w:
        w.append(make_record(0))
    path.write_bytes(path.read_bytes() + b'{"seq": 1, "mo')
    steps: list[str] = []
    real_fsync, real_write = os.fsync, os.write

    def fsync(fd: int) -> None:
        steps.append("fsync dir" if os.path.isdir(f"/proc/self/fd/{fd}") else "fsync file")
        real_fsync(fd)

    def write(fd: int, data: bytes) -> int:
        steps.append("write")
        return real_write(fd, data)

    monkeypatch.setattr(os, "fsync", fsync)
    monkeypatch.setattr(os, "write", write)
    with RecordWriter(path, keep_transitions=False) as w:
        assert w.repaired_bytes == 14
        assert steps == []
        w.append(make_record(2))
    assert steps == ["fsync dir", "fsync file", "write", "fsync file"]
    assert seqs_in(path) == [0, 2]


def test_torn_only_line_is_truncated(tmp_path: Path) -> None:
    """A file holding nothing but a torn line is emptied on open."""
    path = tmp_path / "stops.jsonl"
    path.write_bytes(b'{"seq": 0, "mono' * 500)
    with RecordWriter(path) as w:
        assert w.repaired_bytes == 8000
        assert w.size == 0


def test_reader_reports_torn_tail_without_misreading(tmp_path: Path) -> None:
    """SR-7.2: a torn or undecodable last line is reported as TORN_TAIL and never yields a
    record."""
    path = tmp_path / "stops.jsonl"
    with RecordWriter(path) as w:
        w.append(make_record(0))
    good = path.read_bytes()
    for tail in (
        b'{"seq":1,"mono_ns":',
        b"\x00\x00\x00\x00\n",
        json.dumps(make_record(1)).encode(),
    ):
        path.write_bytes(good + tail)
        items = list(read_records(path))
        assert [type(i) for i in items] == [StoredRecord, BadLine]
        bad = items[1]
        assert isinstance(bad, BadLine)
        assert (bad.reason, bad.line) == (BadLineReason.TORN_TAIL, 2)


def test_reader_reports_bad_lines_in_the_middle(tmp_path: Path) -> None:
    """Damaged lines before the end are reported (NOT_JSON, NOT_A_RECORD) and reading goes on."""
    path = tmp_path / "stops.jsonl"
    lines = [
        json.dumps(make_record(0)),
        "garbage",
        json.dumps({"seq": 1}),
        "[1, 2]",
        json.dumps(make_record(2)),
    ]
    path.write_text("\n".join(lines) + "\n")
    items = list(read_records(path))
    kinds = [i.reason if isinstance(i, BadLine) else i.seq for i in items]
    assert kinds == [
        0,
        BadLineReason.NOT_JSON,
        BadLineReason.NOT_A_RECORD,
        BadLineReason.NOT_JSON,
        2,
    ]


def test_reading_nothing(tmp_path: Path) -> None:
    """A path with no files, or in a missing directory, has no records."""
    assert list(read_records(tmp_path / "stops.jsonl")) == []
    assert list(read_records(tmp_path / "none" / "stops.jsonl")) == []
    assert last_record(tmp_path / "stops.jsonl") is None


def test_filters_by_time_and_cause(tmp_path: Path) -> None:
    """since is inclusive, until exclusive; a cause matches itself and names under it."""
    path = tmp_path / "stops.jsonl"
    causes = [("vsc_estop",), ("client_lost:autonomy",), ("client_lost_x",), ("client_lost",)]
    with RecordWriter(path) as w:
        for seq, names in enumerate(causes):
            w.append(make_record(seq, causes=names))
    at = [EPOCH + dt.timedelta(seconds=s) for s in range(4)]

    def seqs(**filters: object) -> list[int]:
        return [i.seq for i in read_records(path, **filters) if isinstance(i, StoredRecord)]  # type: ignore[arg-type]

    assert seqs(since=at[1]) == [1, 2, 3]
    assert seqs(until=at[2]) == [0, 1]
    assert seqs(since=at[1], until=at[3]) == [1, 2]
    assert seqs(cause="client_lost") == [1, 3]
    assert seqs(cause="client_lost:autonomy") == [1]
    assert seqs(cause="client") == []
    local = dt.timezone(dt.timedelta(hours=2))
    assert seqs(since=at[2].astimezone(local)) == [2, 3]


def test_reading_spans_rotated_files_oldest_first(tmp_path: Path) -> None:
    """Records come back across rotated files in the order they were written, with gaps in
    the numbering (left by a crash) skipped."""
    path = tmp_path / "stops.jsonl"
    with RecordWriter(path, max_bytes=4096, keep=5) as w:
        for seq in range(60):
            w.append(make_record(seq, pad=100))
    assert len(record_files(path)) == 5
    path.with_name("stops.jsonl.4").rename(path.with_name("stops.jsonl.5"))  # gap at 4
    assert seqs_in(path) == list(range(60))
    last = last_record(path)
    assert last is not None
    assert last.seq == 59


def test_last_record_looks_past_an_empty_current_file(tmp_path: Path) -> None:
    """After a rotation left the current file empty, the last record is the newest rotated."""
    path = tmp_path / "stops.jsonl"
    with RecordWriter(path, max_bytes=4096, keep=2, keep_transitions=False) as w:
        for seq in range(30):
            w.append(make_record(seq, pad=100))
    path.write_bytes(b"")
    last = last_record(path)
    assert last is not None
    assert last.file == path.with_name("stops.jsonl.1")


@pytest.mark.skipif(os.geteuid() != 0, reason="mounting a tmpfs needs root")
def test_disk_full_is_a_typed_error(tmp_path: Path) -> None:
    """A write the disk refuses (ENOSPC, a full tmpfs) raises RecordError with disk_full,
    and so does every retry until there is room."""
    with full_disk(tmp_path / "full") as path, RecordWriter(path) as w:
        for _ in range(2):
            with pytest.raises(RecordError) as e:
                w.append(make_record(0))
            assert e.value.errno == errno.ENOSPC
            assert e.value.disk_full
            assert "stops.jsonl" in str(e.value)


def test_cannot_open_is_a_typed_error(tmp_path: Path) -> None:
    """A record file in a missing directory raises RecordError on open."""
    with pytest.raises(RecordError) as e:
        RecordWriter(tmp_path / "missing" / "stops.jsonl")
    assert e.value.errno == errno.ENOENT
    assert not e.value.disk_full


def test_partial_write_is_cut_off_before_the_next_record(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """When the disk fills in the middle of a record, the part written is removed before the
    next append, so the next record is not glued onto it."""
    path = tmp_path / "stops.jsonl"
    real_write = os.write
    with RecordWriter(path) as w:
        w.append(make_record(0))

        def half_then_full(fd: int, data: bytes | memoryview) -> int:
            if len(data) > 20:
                return real_write(fd, bytes(data)[:20])
            raise OSError(errno.ENOSPC, "No space left on device")

        monkeypatch.setattr(os, "write", half_then_full)
        with pytest.raises(RecordError):
            w.append(make_record(1))
        assert not path.read_bytes().endswith(b"\n")  # the torn part is there for now
        monkeypatch.setattr(os, "write", real_write)
        w.append(make_record(2))
    assert seqs_in(path) == [0, 2]
    assert not any(isinstance(i, BadLine) for i in read_records(path))


def test_writer_reopens_after_a_failed_rotation(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """A rotation that fails raises RecordError; the next append rotates and writes."""
    path = tmp_path / "stops.jsonl"
    real_replace = os.replace
    with RecordWriter(path, max_bytes=4096, keep=3) as w:
        for seq in range(20):
            w.append(make_record(seq, pad=100))
        failing = True

        def replace(src: str | Path, dst: str | Path) -> None:
            if failing and Path(src) == path:
                raise OSError(errno.EIO, "I/O error")
            real_replace(src, dst)

        monkeypatch.setattr(os, "replace", replace)
        seq = 20
        while w.size + len(jsonl.encode(make_record(seq, pad=100))) <= w.max_bytes:
            w.append(make_record(seq, pad=100))
            seq += 1
        with pytest.raises(RecordError) as e:  # this record needs a rotation, which fails
            w.append(make_record(seq, pad=100))
        assert e.value.errno == errno.EIO
        failing = False
        for retry in range(seq, seq + 5):  # the refused record first, then more
            w.append(make_record(retry, pad=100))
    assert seqs_in(path) == list(range(seq + 5))


def test_encode_is_compact_and_ends_in_a_newline() -> None:
    """encode gives compact JSON with one trailing newline."""
    line = jsonl.encode(make_record(3))
    assert line.endswith(b"}\n")
    assert b", " not in line
    assert line.count(b"\n") == 1
