"""The last passes of the periodic tests, read from the record at the daemon's start (SR-12.2;
``supervisord/record/passes.py``): the newest passing record of each kind, across rotated
files, bounded, and never a failure of the start."""

from __future__ import annotations

import datetime as dt
import json
import os
from pathlib import Path

from supervisord.record.jsonl import format_utc
from supervisord.record.passes import last_passes

UTC = dt.timezone.utc
DAY = dt.datetime(2026, 11, 1, tzinfo=UTC)
KINDS = ("stoptest", "prooftest")


def _line(seq: int, kind: str, result: str, day: int) -> str:
    record = {
        "seq": seq,
        "mono_ns": seq,
        "utc": format_utc(DAY + dt.timedelta(days=day)),
        "kind": kind,
        "from": "STOPPED",
        "to": "STOPPED",
        "causes": [],
        kind: {"result": result, "text": "..."},
    }
    return json.dumps(record, separators=(",", ":")) + "\n"


def test_the_newest_pass_of_each_kind_across_the_rotated_files(tmp_path: Path) -> None:
    """SR-12.2: the newest passing record of each kind wins, in whichever file it is (the
    current file first, then the rotated ones, newest first); a failed result, another kind
    and a damaged or torn line are no pass."""
    path = tmp_path / "stops.jsonl"
    Path(f"{path}.2").write_text(
        _line(1, "stoptest", "passed", 1) + _line(2, "prooftest", "passed", 2)
    )
    Path(f"{path}.1").write_text(
        _line(3, "stoptest", "passed", 3)
        + _line(4, "stoptest", "failed", 4)
        + '{"kind":"stoptest","stoptest":{"result":"passed"} damaged\n'
    )
    path.write_text(_line(5, "cause_raised", "passed", 5) + _line(6, "prooftest", "passed", 6)[:-9])
    found = last_passes(path, KINDS)
    assert found == {
        "stoptest": DAY + dt.timedelta(days=3),
        "prooftest": DAY + dt.timedelta(days=2),
    }


def test_nothing_to_read_is_no_pass_and_never_an_error(tmp_path: Path) -> None:
    """SR-12.2, SR-7.9: no record yet, a FIFO or a symbolic link at the record's path: no
    pass (the tests are overdue), never an exception and never a read that blocks."""
    path = tmp_path / "stops.jsonl"
    assert last_passes(path, KINDS) == {}
    os.mkfifo(path)
    assert last_passes(path, KINDS) == {}
    path.unlink()
    target = tmp_path / "elsewhere.jsonl"
    target.write_text(_line(1, "stoptest", "passed", 1))
    path.symlink_to(target)
    assert last_passes(path, KINDS) == {}


def test_the_read_is_bounded_to_the_newest_bytes(tmp_path: Path) -> None:
    """SR-12.2: at most the given number of bytes is read, the newest; a pass older than that
    is not found (overdue: the fail-safe side), and the line the bound cuts is dropped."""
    path = tmp_path / "stops.jsonl"
    old = _line(1, "stoptest", "passed", 1)
    filler = "".join(_line(n, "cause_cleared", "x", 2) for n in range(2, 40))
    new = _line(40, "prooftest", "passed", 3)
    path.write_text(old + filler + new)
    bound = len(filler) + len(new)
    assert last_passes(path, KINDS, max_bytes=bound) == {"prooftest": DAY + dt.timedelta(days=3)}
    assert "stoptest" in last_passes(path, KINDS, max_bytes=bound + len(old))
    assert last_passes(path, KINDS, max_bytes=len(new) - 5) == {}
