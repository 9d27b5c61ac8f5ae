"""Crash safety of the record store: a crash at every step of a rotation, a writer process
killed with SIGKILL while it appends, a file cut at any byte (SR-7: nothing
acknowledged is lost)."""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import tempfile
import textwrap
from collections.abc import Callable
from pathlib import Path

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from supervisord.record import jsonl
from supervisord.record.jsonl import (
    RecordWriter,
    StoredRecord,
    last_record,
    read_records,
    record_files,
)
from tests.record.conftest import make_record, seqs_in

MAX_BYTES = 4096


class Crash(BaseException):
    """The process 'dies' here: nothing after this point runs (not an OSError to handle)."""


def _rotation_steps(monkeypatch: pytest.MonkeyPatch, crash_at: int) -> list[str]:
    """Make the ``crash_at``-th rotation step (rename or directory fsync) crash; return the
    log of steps taken."""
    steps: list[str] = []
    real_replace, real_fsync_dir = os.replace, jsonl.fsync_dir

    def step(name: str, action: Callable[[], None]) -> None:
        if len(steps) == crash_at:
            raise Crash(name)
        steps.append(name)
        action()

    def replace(src: str | Path, dst: str | Path) -> None:
        step(f"rename {Path(src).name} {Path(dst).name}", lambda: real_replace(src, dst))

    def fsync_dir(folder: Path) -> None:
        step("fsync dir", lambda: real_fsync_dir(folder))

    monkeypatch.setattr(os, "replace", replace)
    monkeypatch.setattr(jsonl, "fsync_dir", fsync_dir)
    return steps


def _fill_to_rotation(w: RecordWriter, seq: int) -> int:
    """Append records until the next one needs a rotation; return the next seq."""
    while w.size + len(jsonl.encode(make_record(seq, pad=100))) <= w.max_bytes:
        w.append(make_record(seq, pad=100))
        seq += 1
    return seq


@pytest.mark.parametrize("crash_at", range(5))
def test_crash_at_each_rotation_step_loses_nothing(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch, crash_at: int
) -> None:
    """SR-7.2, SR-7.4: a crash at any step of a rotation (keep=3: two renames of old files, the
    rename of the current file, two directory fsyncs) leaves every acknowledged record readable, in
    order, once; a new writer then carries on and rotation stays bounded."""
    path = tmp_path / "stops.jsonl"
    w = RecordWriter(path, max_bytes=MAX_BYTES, keep=3)
    seq = 0
    for _ in range(2):  # two rotations first, so that there are old files to shift
        seq = _fill_to_rotation(w, seq)
        w.append(make_record(seq, pad=100))
        seq += 1
    seq = _fill_to_rotation(w, seq)
    acknowledged = seq

    steps = _rotation_steps(monkeypatch, crash_at)
    with pytest.raises(Crash):
        w.append(make_record(seq, pad=100))
    w.close()  # the dead process's descriptor; closing it writes nothing
    monkeypatch.undo()

    assert seqs_in(path) == list(range(acknowledged)), steps
    w = RecordWriter(path, max_bytes=MAX_BYTES, keep=3)
    for more in range(seq, seq + 40):
        w.append(make_record(more, pad=100))
    w.close()
    after = seqs_in(path)
    assert after == list(range(after[0], seq + 40))
    assert len(record_files(path)) <= 4
    assert max(int(f.name.rsplit(".", 1)[1]) for f in record_files(path)[:-1]) <= 3


def test_a_rotation_has_the_expected_steps(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    """A rotation renames oldest first, then fsyncs the directory before the new file is used."""
    path = tmp_path / "stops.jsonl"
    with RecordWriter(path, max_bytes=MAX_BYTES, keep=3, keep_transitions=False) as w:
        seq = 0
        for _ in range(3):
            seq = _fill_to_rotation(w, seq)
            w.append(make_record(seq, pad=100))
            seq += 1
        seq = _fill_to_rotation(w, seq)
        steps = _rotation_steps(monkeypatch, crash_at=-1)
        w.append(make_record(seq, pad=100))
    assert steps == [
        "rename stops.jsonl.2 stops.jsonl.3",
        "rename stops.jsonl.1 stops.jsonl.2",
        "rename stops.jsonl stops.jsonl.1",
        "fsync dir",
        "fsync dir",
    ]


CHILD = textwrap.dedent(
    """
    import sys
    from supervisord.record.jsonl import RecordWriter, last_record
    from tests.record.conftest import make_record

    path = sys.argv[1]
    last = last_record(path)
    seq = 0 if last is None else last.seq + 1
    with RecordWriter(path, max_bytes=4096, keep=99) as w:
        print(f"repaired {w.repaired_bytes}", flush=True)
        while True:
            w.append(make_record(seq, pad=100))
            print(seq, flush=True)  # acknowledged: append returned
            seq += 1
    """
)


@pytest.mark.parametrize("kills", [(40, 97, 160, 23, 211, 77)])
def test_sigkill_while_appending_loses_nothing_acknowledged(
    tmp_path: Path, kills: tuple[int, ...]
) -> None:
    """SR-7.4: a writer process killed with SIGKILL at arbitrary moments (rotations included) never
    loses a record it acknowledged; each restart continues the sequence after the last record, and
    the files hold one gap-free, duplicate-free sequence."""
    path = tmp_path / "stops.jsonl"
    acknowledged: list[int] = []
    root = Path(__file__).resolve().parents[2]
    for count in kills:
        child = subprocess.Popen(
            [sys.executable, "-c", CHILD, str(path)],
            stdout=subprocess.PIPE,
            text=True,
            cwd=root,
        )
        assert child.stdout is not None
        with child, child.stdout:
            assert child.stdout.readline().startswith("repaired ")
            for _ in range(count):
                acknowledged.append(int(child.stdout.readline()))
            child.send_signal(signal.SIGKILL)
            child.wait()
        assert child.returncode == -signal.SIGKILL
        on_disk = seqs_in(path)
        assert set(acknowledged) <= set(on_disk)
        assert on_disk == list(range(len(on_disk)))  # in order, no gap, no duplicate
    assert len(record_files(path)) > 3  # the kills happened across rotations
    last = last_record(path)
    assert last is not None
    assert last.seq >= acknowledged[-1]


@settings(max_examples=150, deadline=None)
@given(cut=st.floats(min_value=0.0, max_value=1.0), count=st.integers(min_value=1, max_value=12))
def test_cut_at_any_byte_keeps_every_whole_record(cut: float, count: int) -> None:
    """Whatever byte a power cut stops the file at, reopening keeps exactly the whole records
    before the cut, and the next record lands on a line of its own."""
    with tempfile.TemporaryDirectory() as folder:
        path = Path(folder) / "stops.jsonl"
        # The main series alone: a cut of acknowledged records cannot happen for real, and
        # the kept stop transitions would still hold them (SR-7.8).
        with RecordWriter(path, keep_transitions=False) as w:
            for seq in range(count):
                w.append(make_record(seq))
        data = path.read_bytes()
        kept = data[: int(len(data) * cut)]
        path.write_bytes(kept)
        whole = kept.count(b"\n")
        with RecordWriter(path, keep_transitions=False) as w:
            assert w.repaired_bytes == len(kept) - (kept.rfind(b"\n") + 1)
            w.append(make_record(100))
        assert seqs_in(path) == [*range(whole), 100]
        assert all(isinstance(item, StoredRecord) for item in read_records(path))
