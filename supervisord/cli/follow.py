"""``srcsctl log -f``: the records appended to a record file, as they are written.

The file is watched, not rescanned: an inotify watch on its directory (through ctypes, no
extra dependency) wakes a ``select`` when a file there changes, and only the bytes appended
since the last read are read and parsed. Rotation (docs/record.md "Rotation": the file is
renamed to ``PATH.1`` and a new one created) and a file removed and made again are seen as a
new file at the path: the old one is read to its end through the descriptor still open, then
the new one from its start. A file cut back (a torn tail truncated at the writer's start)
is read again from the cut. Without inotify (a kernel without it, a file system that gives
no events) the same loop wakes once a second.
"""

from __future__ import annotations

import contextlib
import ctypes
import ctypes.util
import json
import os
import select
import struct
from collections.abc import Iterator
from pathlib import Path
from typing import Final

from supervisord.record.jsonl import (
    REQUIRED_FIELDS,
    RecordUnreadable,
    StoredRecord,
    cause_names,
    parse_utc,
)

_IN_MODIFY: Final = 0x0000_0002
_IN_MOVED_FROM: Final = 0x0000_0040
_IN_MOVED_TO: Final = 0x0000_0080
_IN_CREATE: Final = 0x0000_0100
_IN_DELETE: Final = 0x0000_0200
_IN_NONBLOCK: Final = 0o4000
_IN_CLOEXEC: Final = 0o2000000
_MASK: Final = _IN_MODIFY | _IN_MOVED_FROM | _IN_MOVED_TO | _IN_CREATE | _IN_DELETE
_EVENT: Final = struct.Struct("iIII")
WAKE_S: Final = 1.0
"""How often the loop looks without an event: the fallback without inotify, and a bound on
anything the events do not show (a file replaced on another mount)."""


class _Inotify:
    """An inotify descriptor watching one directory, or ``fd`` None where there is none."""

    def __init__(self, folder: Path) -> None:
        self.fd: int | None = None
        try:
            libc = ctypes.CDLL(ctypes.util.find_library("c"), use_errno=True)
            fd = libc.inotify_init1(_IN_NONBLOCK | _IN_CLOEXEC)
        except (OSError, AttributeError):
            return
        if fd < 0:
            return
        if libc.inotify_add_watch(fd, os.fsencode(folder), _MASK) < 0:
            os.close(fd)
            return
        self.fd = fd

    def names(self) -> list[str]:
        """The names of the files events came for since the last call."""
        if self.fd is None:
            return []
        try:
            data = os.read(self.fd, 65536)
        except BlockingIOError:
            return []
        names, offset = [], 0
        while offset + _EVENT.size <= len(data):
            length = _EVENT.unpack_from(data, offset)[3]
            raw = data[offset + _EVENT.size : offset + _EVENT.size + length]
            names.append(raw.split(b"\0", 1)[0].decode(errors="replace"))
            offset += _EVENT.size + length
        return names

    def close(self) -> None:
        if self.fd is not None:
            os.close(self.fd)


def parse_record(file: Path, line: bytes) -> StoredRecord | None:
    """A complete line as a record, or ``None`` for a line that is not one (the full reader,
    ``read_records``, names bad lines; the follower shows records only)."""
    try:
        obj = json.loads(line)
    except (ValueError, RecursionError):  # RecursionError: nested thousands deep (SR-8.7)
        return None
    if not isinstance(obj, dict) or any(field not in obj for field in REQUIRED_FIELDS):
        return None
    if not isinstance(obj["seq"], int) or parse_utc(obj["utc"]) is None:
        return None
    return StoredRecord(obj, file, 0) if cause_names(obj) is not None else None


class Follower:
    """The records appended to ``path`` after it was opened here (see the module's doc)."""

    def __init__(self, path: Path) -> None:
        self.path = path
        self.watch = _Inotify(path.parent)
        self.fd: int | None = None
        self.offset = 0
        self.pending = b""  # the start of a line not yet complete
        self._open(at_end=True)

    def _open(self, *, at_end: bool) -> None:
        flags = os.O_RDONLY | os.O_CLOEXEC | os.O_NOFOLLOW | os.O_NONBLOCK | os.O_NOCTTY
        try:
            fd = os.open(self.path, flags)
        except FileNotFoundError:
            self.fd = None  # not there yet: made by the writer's first record
            return
        except OSError as error:  # there, but closed to us: never a silent follow (SR-7.9)
            raise RecordUnreadable(self.path, error) from None
        self.fd = fd
        self.offset = os.fstat(fd).st_size if at_end else 0
        self.pending = b""

    def _read(self) -> list[StoredRecord]:
        if self.fd is None:
            return []
        size = os.fstat(self.fd).st_size
        if size < self.offset:  # cut back: the line in progress starts again at the cut
            self.offset = max(0, self.offset - len(self.pending))
            self.pending = b""
        data = b""
        while chunk := os.pread(self.fd, 1 << 20, self.offset + len(data)):
            data += chunk
        self.offset += len(data)
        lines = (self.pending + data).split(b"\n")
        self.pending = lines.pop()
        return [r for line in lines if (r := parse_record(self.path, line)) is not None]

    def _moved(self) -> bool:
        """Whether the path names another file than the one open (or none is open)."""
        try:
            now = os.stat(self.path, follow_symlinks=False)
        except OSError:
            return False
        if self.fd is None:
            return True
        was = os.fstat(self.fd)
        return (now.st_dev, now.st_ino) != (was.st_dev, was.st_ino)

    def records(self) -> list[StoredRecord]:
        """The records appended since the last call, oldest first."""
        found = self._read()
        if self._moved():
            if self.fd is not None:
                found += self._read()  # what came between the read and the move
                os.close(self.fd)
            self._open(at_end=False)
            found += self._read()
        return found

    def __iter__(self) -> Iterator[list[StoredRecord]]:
        """The new records each time the directory says something changed (or a second
        passed), until the caller stops."""
        watched = [self.watch.fd] if self.watch.fd is not None else []
        while True:
            ready, _, _ = select.select(watched, [], [], WAKE_S)
            if ready:
                self.watch.names()  # drained; any change is looked at, it costs one fstat
            yield self.records()

    def close(self) -> None:
        self.watch.close()
        if self.fd is not None:
            with contextlib.suppress(OSError):
                os.close(self.fd)
