"""A serial port made of a real pseudo-terminal, reachable at a stable path.

The supervisor opens ``path`` as it would open ``/dev/ttyACM0``; the test or simulator holds
the other end. ``unplug`` closes that end (reads on the supervisor's side then fail as after
a USB unplug); ``replug`` makes a new pseudo-terminal at the same path.
"""

from __future__ import annotations

import os
import select
import tty
from pathlib import Path
from types import TracebackType


class PtyPort:
    """The device side of a pseudo-terminal serial port at ``path`` (a symlink)."""

    def __init__(self, path: str | Path) -> None:
        self.path = Path(path)
        self._master: int | None = None
        self._slave: int | None = None
        self.replug()

    def replug(self) -> None:
        """Plug a new device in at ``path`` (closing the old one if still plugged)."""
        self.unplug()
        master, slave = os.openpty()
        tty.setraw(master)
        tty.setraw(slave)  # no line discipline: bytes pass as on a serial line
        os.set_blocking(master, False)
        self._master, self._slave = master, slave
        tmp = self.path.with_name(self.path.name + ".new")
        tmp.unlink(missing_ok=True)
        tmp.symlink_to(os.ttyname(slave))
        tmp.replace(self.path)

    def unplug(self) -> None:
        """Pull the device out: close our end and remove the path."""
        for fd in (self._master, self._slave):
            if fd is not None:
                os.close(fd)
        self._master = self._slave = None
        self.path.unlink(missing_ok=True)

    @property
    def plugged(self) -> bool:
        return self._master is not None

    @property
    def fd(self) -> int:
        if self._master is None:
            raise OSError("the port is unplugged")
        return self._master

    def write(self, data: bytes) -> None:
        view = memoryview(data)
        while view:
            select.select([], [self.fd], [], 1.0)
            try:
                view = view[os.write(self.fd, view) :]
            except BlockingIOError:
                continue

    def read(self, timeout: float = 0.0) -> bytes:
        """What the supervisor wrote, waiting up to ``timeout`` seconds for the first byte."""
        ready, _, _ = select.select([self.fd], [], [], timeout)
        if not ready:
            return b""
        chunks = []
        while True:
            try:
                chunk = os.read(self.fd, 65536)
            except (BlockingIOError, OSError):
                break
            if not chunk:
                break
            chunks.append(chunk)
        return b"".join(chunks)

    def close(self) -> None:
        self.unplug()

    def __enter__(self) -> PtyPort:
        return self

    def __exit__(
        self,
        kind: type[BaseException] | None,
        error: BaseException | None,
        traceback: TracebackType | None,
    ) -> None:
        self.close()
