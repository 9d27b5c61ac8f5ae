"""The few inotify calls the test kit needs (``watcher.OutputWatcher``), through ctypes: no
extra dependency."""

from __future__ import annotations

import ctypes
import ctypes.util
import os
import struct
from pathlib import Path

IN_CLOSE_WRITE = 0x0000_0008
IN_MOVED_TO = 0x0000_0080
IN_CREATE = 0x0000_0100
_IN_NONBLOCK = 0o4000
_IN_CLOEXEC = 0o2000000
_EVENT = struct.Struct("iIII")


class Inotify:
    """The few inotify calls the watcher needs, through ctypes (no extra dependency)."""

    def __init__(self) -> None:
        self._libc = ctypes.CDLL(ctypes.util.find_library("c"), use_errno=True)
        fd = self._libc.inotify_init1(_IN_NONBLOCK | _IN_CLOEXEC)
        if fd < 0:
            raise OSError(ctypes.get_errno(), "inotify_init1 failed")
        self.fd: int = fd

    def watch(self, folder: Path, mask: int) -> None:
        if self._libc.inotify_add_watch(self.fd, os.fsencode(folder), mask) < 0:
            error = ctypes.get_errno()
            raise OSError(error, f"inotify_add_watch {folder}: {os.strerror(error)}")

    def read(self) -> list[str]:
        """The names of the files that events arrived for, in order (may repeat)."""
        try:
            data = os.read(self.fd, 65536)
        except BlockingIOError:
            return []
        names = []
        offset = 0
        while offset + _EVENT.size <= len(data):
            _, _, _, length = _EVENT.unpack_from(data, offset)
            raw = data[offset + _EVENT.size : offset + _EVENT.size + length]
            names.append(raw.split(b"\0", 1)[0].decode(errors="replace"))
            offset += _EVENT.size + length
        return names

    def close(self) -> None:
        os.close(self.fd)
