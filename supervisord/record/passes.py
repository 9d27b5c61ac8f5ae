"""The newest passed ``stoptest`` and ``prooftest`` records of a record file and its rotated
files, read once at the daemon's start (SR-12.2: the age of each test's last pass survives a
restart; docs/record.md "The last passes").

Bounded: the files are read newest first, whole lines only, at most :data:`MAX_SCAN_BYTES` in
all, and only lines that name such a kind and a passed result are parsed. Fail safe: a file
that cannot be read, is not a regular file or holds garbage is skipped, never raised, and a
test whose pass was not found counts as never passed (overdue). A pass the rotation dropped
is not found either: run the test again.
"""

from __future__ import annotations

import datetime as dt
import json
import os
import stat
from collections.abc import Iterable
from pathlib import Path
from typing import Final

from supervisord.record.jsonl import not_a_regular_file, parse_utc, record_files

MAX_SCAN_BYTES: Final = 64 * 1024 * 1024
"""At most this much of the record is read at start: the default record (five files of
4 MiB) whole, and a bound on the start-up time of a robot configured for far more."""
_PASSED: Final = b'"result":"passed"'


def last_passes(
    path: Path | str, kinds: Iterable[str], max_bytes: int = MAX_SCAN_BYTES
) -> dict[str, dt.datetime]:
    """For each record kind of ``kinds``, the UTC time of its newest record whose object of
    that name says ``"result": "passed"``; kinds not found are left out."""
    wanted = {kind: f'"kind":"{kind}"'.encode() for kind in kinds}
    found: dict[str, dt.datetime] = {}
    budget = max_bytes
    for file in reversed(record_files(Path(path))):
        if budget <= 0 or len(found) == len(wanted):
            break
        data = _read(file, budget)
        budget -= len(data)
        newest: dict[str, dt.datetime] = {}
        for line in data.split(b"\n"):
            for kind, marker in wanted.items():
                if kind in found or marker not in line or _PASSED not in line:
                    continue
                when = _passed_at(line, kind)
                if when is not None:
                    newest[kind] = when  # later lines of a file are newer
        found.update(newest)
    return found


def _read(file: Path, budget: int) -> bytes:
    """The last ``budget`` bytes of ``file`` (whole lines: a cut first line is dropped), or
    nothing when it cannot be read as a regular file (SR-7.9: never through a link, never
    a FIFO)."""
    if not_a_regular_file(file) is not None:
        return b""
    flags = os.O_RDONLY | os.O_CLOEXEC | os.O_NOFOLLOW | os.O_NONBLOCK | os.O_NOCTTY
    try:
        fd = os.open(file, flags)
    except OSError:
        return b""
    try:
        info = os.fstat(fd)
        if not stat.S_ISREG(info.st_mode):
            return b""  # replaced since the look
        start = max(0, info.st_size - budget)
        os.lseek(fd, start, os.SEEK_SET)
        chunks, left = [], info.st_size - start
        while left > 0:
            chunk = os.read(fd, min(left, 1 << 20))
            if not chunk:
                break
            chunks.append(chunk)
            left -= len(chunk)
        data = b"".join(chunks)
    except OSError:
        return b""
    finally:
        os.close(fd)
    if start > 0:
        data = data.partition(b"\n")[2]
    return data


def _passed_at(line: bytes, kind: str) -> dt.datetime | None:
    try:
        record = json.loads(line)
    except (ValueError, RecursionError):  # RecursionError: nested thousands deep (SR-8.7)
        return None  # a torn or damaged line is no pass
    if not isinstance(record, dict) or record.get("kind") != kind:
        return None
    outcome = record.get(kind)
    if not isinstance(outcome, dict) or outcome.get("result") != "passed":
        return None
    return parse_utc(record.get("utc"))
