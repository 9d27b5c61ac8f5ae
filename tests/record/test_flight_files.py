"""The flight recorder's window files (SR-7.10, SR-7.12; ``supervisord/record/flight.py``,
docs/record.md "The flight recorder"): written whole or not at all, beside the record, only
regular files in only a directory, each bounded in size by the record's ``max_bytes`` and all
together by its ``flight_max_bytes``, and read back as written."""

from __future__ import annotations

import dataclasses
import errno
import json
import os
import stat
from pathlib import Path

import pytest

from supervisord.record.flight import (
    FlightError,
    FlightWriter,
    flight_dir,
    read_window,
    record_of,
    window_path,
    windows,
)
from supervisord.record.flight_codec import FlightFormatError
from tests.record.conftest import full_disk
from tests.record.flight_rig import CONFIG, run, story

ROOT_ONLY = pytest.mark.skipif(os.geteuid() != 0, reason="mounting a full tmpfs needs root")


def test_a_window_is_read_back_as_written(tmp_path: Path) -> None:
    """SR-7.10, SR-7.12: the header, the snapshot base and every input come back; the file is
    PATH.flight/SEQ.jsonl, mode 0640, with no temporary file left."""
    story_run = run(story(), snapshot_at=[30])
    writer = FlightWriter(tmp_path / "stops.jsonl", 1 << 20)
    path = writer.write(story_run.window())
    seq = story_run.stop["seq"]
    assert path == tmp_path / "stops.jsonl.flight" / f"{seq}.jsonl"
    assert stat.S_IMODE(path.stat().st_mode) == 0o640
    assert os.listdir(path.parent) == [path.name]
    window = read_window(path)
    assert window.seq == seq
    assert window.config == CONFIG
    assert window.stop == story_run.stop
    assert window.base["kind"] == "start"  # the oldest base that fits
    assert window.inputs == story_run.inputs
    assert record_of(path) == tmp_path / "stops.jsonl"


def test_a_window_too_large_starts_from_a_later_base_or_from_none(tmp_path: Path) -> None:
    """SR-7.12: a window is at most the record's ``max_bytes``: past it, it starts from the
    newer base (a snapshot, fewer inputs); past that too, it keeps no base (replay says
    why) and only the newest inputs that fit, for a person to read."""
    story_run = run(story(4.0), snapshot_at=[len(story(4.0)) - 40])
    window = story_run.window()
    whole = len(FlightWriter(tmp_path / "a", 1 << 20).write(window).read_bytes())
    later = FlightWriter(tmp_path / "b", whole - 1).write(window)
    loaded = read_window(later)
    assert loaded.base["kind"] == "snapshot"
    assert len(loaded.inputs) == 40
    assert later.stat().st_size <= whole - 1
    tiny = FlightWriter(tmp_path / "c", 4096).write(window)
    loaded = read_window(tiny)
    assert loaded.base["kind"] == "none"
    assert "max_bytes" in loaded.base["reason"]
    assert 0 < len(loaded.inputs) < 40
    assert loaded.inputs == story_run.inputs[-len(loaded.inputs) :]
    assert tiny.stat().st_size <= 4096


def test_the_newest_windows_within_the_byte_budget_are_kept(tmp_path: Path) -> None:
    """SR-7.12: the windows take at most the budget (``flight_max_bytes``) together, not a
    count: the newest that fit stay, the oldest go first; a window numbered above the newest
    (of a record removed since) and a temporary file left by a write that never finished go
    too; an operator's file is left alone."""
    story_run = run(story(0.6))
    record = tmp_path / "stops.jsonl"
    folder = flight_dir(record)
    window = story_run.window()
    size = len(FlightWriter(tmp_path / "probe", 1 << 20).write(window).read_bytes())
    folder.mkdir()
    (folder / "9999.jsonl").write_text("{}\n")
    (folder / ".7.jsonl.tmp").write_text("half")
    (folder / "notes.txt").write_text("an operator's")
    writer = FlightWriter(record, 1 << 20, budget=3 * size + size // 2)
    for seq in range(41, 47):
        writer.write(dataclasses.replace(window, stop=dataclasses.replace(window.stop, seq=seq)))
    assert [seq for seq, _ in windows(record)] == [44, 45, 46]
    assert sorted(os.listdir(folder)) == ["44.jsonl", "45.jsonl", "46.jsonl", "notes.txt"]
    taken = sum(path.stat().st_size for _, path in windows(record))
    assert taken <= writer.budget


def test_many_small_windows_stay_where_a_count_kept_five(tmp_path: Path) -> None:
    """SR-7.12: at the default budget (64 MiB) the windows of 40 stops all stay; the old rule
    kept the record's ``keep`` + 1 (5)."""
    story_run = run(story(0.6))
    record = tmp_path / "stops.jsonl"
    writer = FlightWriter(record, 1 << 20)
    window = story_run.window()
    for seq in range(1, 41):
        writer.write(dataclasses.replace(window, stop=dataclasses.replace(window.stop, seq=seq)))
    assert [seq for seq, _ in windows(record)] == list(range(1, 41))


def test_a_window_larger_than_the_budget_is_cut_to_it(tmp_path: Path) -> None:
    """SR-7.12: one window is at most the budget as well as ``max_bytes``: the budget holds
    for the newest window alone too (it starts from a later base, or keeps none)."""
    story_run = run(story(4.0), snapshot_at=[len(story(4.0)) - 40])
    window = story_run.window()
    whole = len(FlightWriter(tmp_path / "a", 1 << 20).write(window).read_bytes())
    cut = FlightWriter(tmp_path / "b", 1 << 20, budget=whole - 1).write(window)
    assert cut.stat().st_size <= whole - 1
    assert read_window(cut).base["kind"] == "snapshot"


def test_only_a_directory_is_the_windows_folder(tmp_path: Path) -> None:
    """SR-7.9, SR-7.12: a symbolic link or a file where the windows' folder should be is
    refused (``FlightError``), and nothing is written through the link."""
    story_run = run(story(0.6))
    elsewhere = tmp_path / "elsewhere"
    elsewhere.mkdir()
    record = tmp_path / "stops.jsonl"
    flight_dir(record).symlink_to(elsewhere)
    with pytest.raises(FlightError, match="symbolic link"):
        FlightWriter(record, 1 << 20).write(story_run.window())
    assert os.listdir(elsewhere) == []
    other = tmp_path / "other.jsonl"
    flight_dir(other).write_text("")
    with pytest.raises(FlightError, match="not a directory"):
        FlightWriter(other, 1 << 20).write(story_run.window())


def test_a_fifo_at_a_windows_name_is_replaced_never_opened(tmp_path: Path) -> None:
    """SR-7.9, SR-7.12: a FIFO at the window's name would hang an open; the window is renamed
    over it, never opening it."""
    story_run = run(story(0.6))
    record = tmp_path / "stops.jsonl"
    path = window_path(record, story_run.stop["seq"])
    path.parent.mkdir()
    os.mkfifo(path)
    FlightWriter(record, 1 << 20).write(story_run.window())
    assert stat.S_ISREG(path.lstat().st_mode)


@ROOT_ONLY
def test_a_full_disk_is_an_error_with_its_number(tmp_path: Path) -> None:
    """SR-7.6, SR-7.12: a window that cannot be written (a full file system) raises
    ``FlightError`` with ``ENOSPC``; no partial window is left under its name."""
    story_run = run(story(0.6))
    with full_disk(tmp_path / "disk") as record:
        flight_dir(record).mkdir()
        with pytest.raises(FlightError) as raised:
            FlightWriter(record, 1 << 20).write(story_run.window())
        assert raised.value.errno == errno.ENOSPC
        assert windows(record) == []


@pytest.mark.parametrize("damage", ["cut", "version", "format", "not json", "snapshot gone"])
def test_a_damaged_window_is_refused(tmp_path: Path, damage: str) -> None:
    """SR-7.10: a window cut short (its trailer missing), of another version or format, or
    otherwise damaged is refused with a reason, never replayed in part."""
    story_run = run(story(), snapshot_at=[20])
    path = FlightWriter(tmp_path / "stops.jsonl", 1 << 20).write(
        story_run.window(bases=story_run.bases[1:])
    )
    lines = path.read_text().splitlines()
    header = json.loads(lines[0])
    if damage == "cut":
        lines = lines[:-1]
    elif damage == "version":
        lines[0] = json.dumps(header | {"version": 99})
    elif damage == "format":
        lines[0] = json.dumps(header | {"format": "something"})
    elif damage == "not json":
        lines[5] = lines[5][:-3]
    else:
        del lines[1]
    path.write_text("\n".join(lines) + "\n")
    with pytest.raises(FlightFormatError):
        read_window(path)
