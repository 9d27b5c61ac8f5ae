"""Shared helpers for the record tests: building records the way the daemon does."""

from __future__ import annotations

import contextlib
import datetime as dt
import subprocess
from collections.abc import Iterator
from pathlib import Path

from supervisord.record.jsonl import BadLine, StoredRecord, format_utc, read_records
from supervisord.record.stop import StopRecord, read_written
from tests.descriptors import no_descriptor_left_open  # noqa: F401 -- an autouse fixture

EPOCH = dt.datetime(2026, 3, 1, 12, 0, tzinfo=dt.timezone.utc)


def make_record(
    seq: int,
    *,
    causes: tuple[str, ...] = ("vsc_estop",),
    to: str = "STOPPED",
    before: str = "RUN",
    kind: str | None = None,
    pad: int = 0,
) -> dict[str, object]:
    """A record with sequence ``seq``, ``seq`` seconds after EPOCH; ``pad`` adds bytes."""
    record: dict[str, object] = {
        "seq": seq,
        "mono_ns": 1_000_000_000 + seq * 1_000_000,
        "utc": format_utc(EPOCH + dt.timedelta(seconds=seq)),
        "from": before,
        "to": to,
        "causes": [{"name": c, "sources": ["remote"]} for c in causes],
        "trigger": "vsc_heartbeat",
    }
    if kind is not None:
        record["kind"] = kind
    if pad:
        record["note"] = "x" * pad
    return record


def make_stop_record(seq: int) -> StopRecord:
    """:func:`make_record`'s record typed, as the daemon hands it to its sink."""
    typed = read_written(make_record(seq))
    assert typed is not None
    return typed


def records_in(path: Path) -> list[StoredRecord]:
    """The records of ``path`` (all files), asserting there is no bad line but a torn tail."""
    found = []
    for item in read_records(path):
        if isinstance(item, BadLine):
            assert item.reason.value == "torn_tail", item
            continue
        found.append(item)
    return found


def seqs_in(path: Path) -> list[int]:
    """The sequence numbers of ``path``'s records, oldest first."""
    return [r.seq for r in records_in(path)]


@contextlib.contextmanager
def full_disk(folder: Path) -> Iterator[Path]:
    """A one-page tmpfs at ``folder``, filled to the last byte: every write to a new file
    there fails with ENOSPC (a real full file system; the record refuses a device such as
    /dev/full, SR-7.9). Yields the record's path there; unmounted on leaving. Needs root."""
    folder.mkdir()
    subprocess.run(["mount", "-t", "tmpfs", "-o", "size=4k", "srcs-full", str(folder)], check=True)
    try:
        with contextlib.suppress(OSError), (folder / "filler").open("wb", buffering=0) as filler:
            while True:
                filler.write(b"\0" * 512)
        yield folder / "stops.jsonl"
    finally:
        subprocess.run(["umount", "-l", str(folder)], check=False)
