"""The simulator's serial edge: the VSC's end of a pseudo-terminal (manual §8, 115200 8N1).

The host opens the symlink (``PtyPort``) as it would open ``/dev/ttyACM0``. A pty has no
baud rate, so bytes arrive as fast as they are written; ``Pacer`` (``faults.py``) slows
them down when a test asks for slow or partial writes.

A real USB CDC device drops what it sends while no program has the port open; a pty keeps
it in the slave's input queue, and a host that opens the port later would read seconds-old
heartbeats as if they were new. So the queue is watched and flushed when it holds more
than ``STALE_LIMIT`` bytes (under a second of the VSC's traffic): a reading host keeps it
near empty, only an absent or stalled one loses those bytes, as on the real line.
"""

from __future__ import annotations

import array
import contextlib
import fcntl
import os
import termios
from pathlib import Path

from supervisord.protocol.framing import Decoded, FrameDecoder
from supervisord.sim.pty import PtyPort

READ_LIMIT = 4096
STALE_LIMIT = 1024  # bytes waiting unread in the host's queue before they count as stale
MAX_BACKLOG = 65536  # bytes the pty would not take; beyond this the oldest are dropped


class SerialSide:
    """A pseudo-terminal at ``path`` (a symlink), with unplug and replug."""

    kind = "serial"

    def __init__(self, path: Path) -> None:
        self.path = path
        self._port = PtyPort(path)
        self._decoder = FrameDecoder()
        self._backlog = bytearray()
        self._probe: int | None = None
        self._open_probe()

    @property
    def description(self) -> str:
        return str(self.path)

    @property
    def device(self) -> str:
        """The pty device the symlink points at ("" while unplugged)."""
        return os.readlink(self.path) if self.plugged else ""

    @property
    def plugged(self) -> bool:
        return self._port.plugged

    def fileno(self) -> int | None:
        return self._port.fd if self._port.plugged else None

    def _open_probe(self) -> None:
        # Our own descriptor on the host's side, only to measure and flush its input queue.
        self._probe = os.open(self.path, os.O_RDWR | os.O_NOCTTY | os.O_NONBLOCK)

    def _close_probe(self) -> None:
        if self._probe is not None:
            os.close(self._probe)
            self._probe = None

    def receive(self) -> list[Decoded]:
        """Decode what the host wrote since the last call."""
        if not self._port.plugged:
            return []
        try:
            data = os.read(self._port.fd, READ_LIMIT)
        except (BlockingIOError, InterruptedError):
            return []
        except OSError:
            return []  # EIO while nothing is attached to the slave: nothing to read
        return self._decoder.feed(data)

    def write(self, data: bytes) -> None:
        """Send ``data`` without blocking; what the pty will not take waits in a backlog."""
        if not self._port.plugged:
            return
        self._backlog += data
        if len(self._backlog) > MAX_BACKLOG:
            del self._backlog[: len(self._backlog) - MAX_BACKLOG]
        self._drop_stale()
        while self._backlog:
            try:
                written = os.write(self._port.fd, self._backlog)
            except (BlockingIOError, InterruptedError):
                break
            except OSError:
                self._backlog.clear()
                break
            del self._backlog[:written]

    def _drop_stale(self) -> None:
        if self._probe is None:
            return
        waiting = array.array("i", [0])
        with contextlib.suppress(OSError):
            fcntl.ioctl(self._probe, termios.FIONREAD, waiting)
            if waiting[0] > STALE_LIMIT:
                termios.tcflush(self._probe, termios.TCIFLUSH)

    def unplug(self) -> None:
        """Pull the USB cable: the host's reads fail and the symlink disappears."""
        self._close_probe()
        self._port.unplug()
        self._backlog.clear()

    def replug(self) -> None:
        """A new device at the same symlink; the host must open it again."""
        self._close_probe()
        self._port.replug()
        self._decoder = FrameDecoder()
        self._backlog.clear()
        self._open_probe()

    def close(self) -> None:
        self._close_probe()
        self._port.close()
