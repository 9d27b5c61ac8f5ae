"""The simulator's edge on a serial device that already exists: the device's end of a real
line, such as ``/dev/ttyGS0`` of a USB CDC ACM gadget (the host then sees a real
``/dev/ttyACMn``, made and named by its own kernel and udev) or a serial port cabled to the host.

The simulator does not own the device, so it cannot unplug it: whoever owns it does (for the
gadget, an empty write to its UDC file). It notices: the kernel hangs up the device's end when
the host goes away, reads then return nothing or fail, and the side opens the path again at its
next ``receive`` (on a gadget the path stays while unbound, and the reopened end works again
once the gadget is bound). ``unplug`` and ``replug`` close and reopen this end only: the VSC
stops talking, and the host sees silence, not a removed device.

What nobody reads: a gadget's serial function keeps what is written while the host does not
read (up to 8 KiB in its buffer, and more in requests queued to the controller), and hands it
all to the host when it opens the port, where it would pass for current traffic. It cannot be
flushed from this end (the driver has no flush, and a close waits up to 15 s for the host).
So this side stops writing while more than ``STALE_LIMIT`` bytes wait in the driver (its
output queue, ``TIOCOUTQ``): an absent host then finds at most that much old traffic, as from
the pty side (``serial_side.py``).
"""

from __future__ import annotations

import array
import contextlib
import errno
import fcntl
import os
import termios
import tty
from pathlib import Path

from supervisord.protocol.framing import Decoded, FrameDecoder
from supervisord.sim.serial_side import MAX_BACKLOG, READ_LIMIT, STALE_LIMIT

# What a read or write on the device's end returns once the host is gone (a hung-up tty, a
# removed device): the end is closed and opened again.
GONE = (errno.EIO, errno.ENODEV, errno.ENXIO, errno.ESHUTDOWN, errno.EPIPE)


class TtySide:
    """The device's end of an existing serial line at ``path``, opened raw and non-blocking."""

    kind = "serial"

    def __init__(self, path: Path) -> None:
        self.path = path
        self._fd: int | None = None
        self._held = False  # unplugged by request: stays closed until ``replug``
        self._decoder = FrameDecoder()
        self._backlog = bytearray()
        self.hangups = 0  # how often the host went away (the end was hung up)
        self._open()  # an error here is the caller's: a path that cannot be opened at start

    @property
    def description(self) -> str:
        return str(self.path)

    @property
    def device(self) -> str:
        """The device the path names ("" while closed)."""
        return os.path.realpath(self.path) if self._fd is not None else ""

    @property
    def plugged(self) -> bool:
        return self._fd is not None

    def fileno(self) -> int | None:
        return self._fd

    def _open(self) -> None:
        fd = os.open(self.path, os.O_RDWR | os.O_NOCTTY | os.O_NONBLOCK)
        try:
            tty.setraw(fd)  # no line discipline on this end: bytes pass as on the wire
        except termios.error:
            os.close(fd)
            raise
        self._fd = fd
        self._decoder = FrameDecoder()
        self._backlog.clear()

    def _reopen(self) -> None:
        if self._fd is None and not self._held:
            with contextlib.suppress(OSError, termios.error):
                self._open()

    def _lost(self) -> None:
        """The host went away: close this end; the next ``receive`` opens it again."""
        self.hangups += 1
        self._close()

    def receive(self) -> list[Decoded]:
        """Decode what the host wrote since the last call."""
        self._reopen()
        if self._fd is None:
            return []
        try:
            data = os.read(self._fd, READ_LIMIT)
        except (BlockingIOError, InterruptedError):
            return []
        except OSError as error:
            if error.errno in GONE:
                self._lost()
            return []
        if not data:  # a hung-up tty reads as end of file
            self._lost()
            return []
        return self._decoder.feed(data)

    def write(self, data: bytes) -> None:
        """Send ``data`` without blocking; what the driver will not take waits in a backlog,
        and nothing is written while the host leaves more than ``STALE_LIMIT`` unread."""
        if self._fd is None:
            return
        self._backlog += data
        if len(self._backlog) > MAX_BACKLOG:
            del self._backlog[: len(self._backlog) - MAX_BACKLOG]
        if self._queued() > STALE_LIMIT:
            self._backlog.clear()  # the host is not reading: this traffic is lost, as sent
            return
        while self._backlog and self._fd is not None:
            try:
                written = os.write(self._fd, self._backlog)
            except (BlockingIOError, InterruptedError):
                break
            except OSError as error:
                self._backlog.clear()
                if error.errno in GONE:
                    self._lost()
                break
            del self._backlog[:written]

    def _queued(self) -> int:
        """Bytes written to the driver that the host has not taken yet (0 if it cannot say)."""
        waiting = array.array("i", [0])
        if self._fd is None:
            return 0
        try:
            fcntl.ioctl(self._fd, termios.TIOCOUTQ, waiting)
        except OSError:
            return 0
        return waiting[0]

    def unplug(self) -> None:
        """The VSC's end stops: closed until ``replug`` (the device itself stays)."""
        self._held = True
        self._close()

    def replug(self) -> None:
        """Open the end again."""
        self._held = False
        self._close()
        self._open()

    def _close(self) -> None:
        fd, self._fd = self._fd, None
        self._backlog.clear()
        if fd is not None:
            os.close(fd)

    def close(self) -> None:
        self._held = True
        self._close()
