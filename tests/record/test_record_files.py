"""What the record's files are (``docs/record.md`` "What the record file is", "Rotation"):
only regular files are written or read (SR-7.9), a file removed or replaced under the writer
is noticed and opened again (SR-7.9), and the stop transitions are kept apart so that no
flood of other records rotates them away (SR-7.8)."""

from __future__ import annotations

import os
import threading
from collections.abc import Callable
from pathlib import Path

import pytest

from supervisord.record.jsonl import (
    BadLine,
    BadLineReason,
    RecordError,
    RecordWriter,
    StoredRecord,
    last_record,
    read_records,
    transitions_path,
)
from tests.record.conftest import make_record, seqs_in

HANG_S = 10.0  # a read of a FIFO never returns: any generous wait tells a hang from a read


def _returns(call: Callable[[], object]) -> object:
    """``call()``'s result, asserting it returned within HANG_S (a hang fails the test
    instead of holding it)."""
    result: list[object] = []
    errors: list[BaseException] = []

    def run() -> None:
        try:
            result.append(call())
        except Exception as error:
            errors.append(error)

    thread = threading.Thread(target=run, daemon=True)
    thread.start()
    thread.join(HANG_S)
    assert not thread.is_alive(), "it hung"
    if errors:
        raise errors[0]
    return result[0]


def test_a_fifo_at_the_record_path_is_refused_without_blocking(tmp_path: Path) -> None:
    """SR-7.9: a FIFO where the record file should be: the writer refuses it with a
    RecordError that says so, and never opens it."""
    os.mkfifo(tmp_path / "stops.jsonl")
    with pytest.raises(RecordError) as refused:
        _returns(lambda: RecordWriter(tmp_path / "stops.jsonl"))
    assert "FIFO" in str(refused.value)


def test_a_symlink_at_the_record_path_is_refused(tmp_path: Path) -> None:
    """SR-7.9: a symlink where the record file should be is refused (rotation would rename
    the link, not the file; a link can point anywhere, a device included)."""
    (tmp_path / "elsewhere").write_text("")
    (tmp_path / "stops.jsonl").symlink_to(tmp_path / "elsewhere")
    with pytest.raises(RecordError) as refused:
        RecordWriter(tmp_path / "stops.jsonl")
    assert "symbolic link" in str(refused.value)


@pytest.mark.parametrize("name", ["stops.jsonl", "stops.jsonl.1", "stops.jsonl.transitions"])
def test_reading_skips_a_fifo_and_says_so(tmp_path: Path, name: str) -> None:
    """SR-7.9: a FIFO under a record file's name is one ``not_a_file`` bad line for readers,
    never opened: ``read_records`` and ``last_record`` (what the daemon reads at start)
    return instead of waiting for a writer that never comes."""
    path = tmp_path / "stops.jsonl"
    with RecordWriter(tmp_path / "other.jsonl") as w:
        w.append(make_record(1))
    os.mkfifo(tmp_path / name)
    items = _returns(lambda: list(read_records(path)))
    assert isinstance(items, list)
    assert [(i.file.name, i.reason) for i in items if isinstance(i, BadLine)] == [
        (name, BadLineReason.NOT_A_FILE)
    ]
    assert _returns(lambda: last_record(path)) is None


@pytest.mark.parametrize("how", ["removed", "replaced"])
def test_a_removed_or_replaced_file_is_opened_again(tmp_path: Path, how: str) -> None:
    """SR-7.9: the record file is removed (a cleanup job) or renamed and replaced by an empty
    one (a log rotation) under the writer. The next record goes to the file at the path,
    where readers look; the writer counts the reopening and says why."""
    path = tmp_path / "stops.jsonl"
    with RecordWriter(path) as w:
        w.append(make_record(1))
        if how == "removed":
            path.unlink()
        else:
            path.rename(tmp_path / "stops.jsonl.old")
            path.write_text("")
        w.append(make_record(2))
        w.append(make_record(3))
        assert (w.reopens, w.last_reopen) == (1, how)
    assert [int(line.split(b",")[0][7:]) for line in path.read_bytes().splitlines()] == [2, 3]


def _chatter(seq: int) -> dict[str, object]:
    """A record a client causes at will: a hold or its release (RUN <-> HOLD)."""
    before, after = ("RUN", "HOLD") if seq % 2 else ("HOLD", "RUN")
    return make_record(seq, causes=("client_hold:nav",), before=before, to=after, pad=200)


def test_a_flood_of_other_records_never_rotates_a_stop_away(tmp_path: Path) -> None:
    """SR-7.8: a stop (RUN -> STOPPED) and its re-arm, then a flood of holds and releases
    that rotates the record round many times over (4 KiB files, one kept). The main files
    hold only the newest chatter; readers still get the stop and its re-arm, oldest first,
    before it, from the stop transitions' own files; a restart continues ``seq`` after the
    newest record."""
    path = tmp_path / "stops.jsonl"
    with RecordWriter(path, max_bytes=4096, keep=1) as w:
        w.append(make_record(1, before="RUN", to="STOPPED"))
        w.append(make_record(2, causes=(), before="STOPPED", to="RUN"))
        for seq in range(3, 400):
            w.append(_chatter(seq))
    seqs = seqs_in(path)
    assert seqs[:2] == [1, 2]
    assert seqs[2] > 300  # the chatter in between rotated away
    assert seqs == sorted(seqs)
    kept = [r for r in read_records(path, cause="vsc_estop") if isinstance(r, StoredRecord)]
    assert [r.seq for r in kept] == [1]
    assert kept[0].file == transitions_path(path)
    last = last_record(path)
    assert last is not None
    assert last.seq == 399


def test_the_transitions_are_not_repeated_while_the_main_files_hold_them(tmp_path: Path) -> None:
    """SR-7.8: as long as the main files still hold a stop, readers see it once."""
    path = tmp_path / "stops.jsonl"
    with RecordWriter(path) as w:
        for seq in range(1, 6):
            w.append(make_record(seq))
    assert seqs_in(path) == [1, 2, 3, 4, 5]
    assert transitions_path(path).exists()
