"""The simulator's USB HID edge: the device's end of a HID function, such as ``/dev/hidg0``
of a USB HID gadget (the host then sees a real ``hidraw`` node through its own HID drivers).

A VSC in HID mode (manual §10) is a game controller: it sends the 9-byte input report about
16 times a second and takes 26-byte output reports (display values and labels). Each write
here is one input report, each read one output report. HID has no host heartbeat, so this
edge has no watchdog and nothing of the serial protocol.

A report the host has not taken yet holds the next one back (the write would block): the
newer one is dropped, as a device replaces its pending report. Once the host is gone (the
gadget unbound) writes fail and the device node goes away; the side closes its end and opens
the path again at each ``receive`` until the node is back.
"""

from __future__ import annotations

import contextlib
import errno
import os
from pathlib import Path

from supervisord.protocol.hid import (
    HidInput,
    HidOutput,
    HidRejection,
    decode_hid_output,
    encode_hid_input,
)

REPORT_LIMIT = 64  # an output report is 26 bytes: a read takes one whole
HID_PERIOD_S = 0.0625  # manual table 37: the input report at ~16 Hz
GONE = (errno.EIO, errno.ENODEV, errno.ENXIO, errno.ESHUTDOWN, errno.EPIPE, errno.ENOENT)


class HidSide:
    """The HID function's end at ``path``; ``send`` writes one input report."""

    kind = "hid"

    def __init__(self, path: Path) -> None:
        self.path = path
        self._fd: int | None = None
        self._held = False  # unplugged by request: stays closed until ``replug``
        self.reports_sent = 0
        self.reports_dropped = 0  # not taken by the host in time (or no host at all)
        self._open()  # an error here is the caller's: a path that cannot be opened at start

    @property
    def description(self) -> str:
        return str(self.path)

    @property
    def device(self) -> str:
        return os.path.realpath(self.path) if self._fd is not None else ""

    @property
    def plugged(self) -> bool:
        return self._fd is not None

    def fileno(self) -> int | None:
        return self._fd

    def _open(self) -> None:
        self._fd = os.open(self.path, os.O_RDWR | os.O_NONBLOCK | os.O_CLOEXEC)

    def _reopen(self) -> None:
        if self._fd is None and not self._held:
            with contextlib.suppress(OSError):
                self._open()

    def receive(self) -> list[HidOutput | HidRejection]:
        """The output reports the host wrote since the last call."""
        self._reopen()
        received: list[HidOutput | HidRejection] = []
        while self._fd is not None:
            try:
                report = os.read(self._fd, REPORT_LIMIT)
            except (BlockingIOError, InterruptedError):
                break
            except OSError as error:
                if error.errno in GONE:
                    self._close()
                break
            if not report:
                self._close()
                break
            received.append(decode_hid_output(report))
        return received

    def send(self, report: HidInput) -> None:
        """Write one input report, or drop it if the host has not taken the last one."""
        if self._fd is None:
            return
        try:
            os.write(self._fd, encode_hid_input(report))
        except (BlockingIOError, InterruptedError):
            self.reports_dropped += 1
            return
        except OSError as error:
            self.reports_dropped += 1
            if error.errno in GONE:
                self._close()
            return
        self.reports_sent += 1

    def unplug(self) -> None:
        """The VSC's end stops: closed until ``replug`` (the function itself stays)."""
        self._held = True
        self._close()

    def replug(self) -> None:
        self._held = False
        self._close()
        self._open()

    def _close(self) -> None:
        fd, self._fd = self._fd, None
        if fd is not None:
            os.close(fd)

    def close(self) -> None:
        self._held = True
        self._close()
