"""The USB HID link: hidraw input reports, for monitoring and teleoperation only.

HID mode carries no host heartbeat (PR-4), so it is never a safety channel: with this
link the safety core never leaves STOPPED, and the daemon says so at start.
"""

from __future__ import annotations

import os

from supervisord.links.base import Incoming, Link, LinkBrokenError, LinkError
from supervisord.links.denied import denied_advice
from supervisord.protocol.hid import HidOutput, decode_hid_input, encode_hid_output
from supervisord.protocol.messages import FeedbackName, FeedbackSet, Message

REPORT_LIMIT = 64
# hidraw's write() takes the report number first, 0 for a device without numbered reports
# such as the VSC, and the report after it (the kernel's Documentation/hid/hidraw.rst). The
# USB HID driver drops a leading 0 and sends the rest; without it, a report whose first byte
# is 0 (every label: key 0) lost that byte and reached the VSC one byte short.
NO_REPORT_ID = b"\0"


class HidLink(Link):
    """A hidraw device: each read is one input report."""

    def __init__(self, path: str) -> None:
        self._path = path
        self._fd: int | None = None

    @property
    def description(self) -> str:
        return f"HID {self._path} (no safety channel)"

    @property
    def is_open(self) -> bool:
        return self._fd is not None

    def open(self) -> None:
        if self._fd is None:
            try:
                self._fd = os.open(self._path, os.O_RDWR | os.O_NONBLOCK | os.O_CLOEXEC)
            except OSError as error:
                # A device the daemon may not open names its group and the fix (SR-8.18).
                reason = (error.strerror or str(error)) + denied_advice(self._path, error)
                raise LinkError(reason) from error

    def fileno(self) -> int | None:
        return self._fd

    def receive(self) -> list[Incoming]:
        """One input report. The loop receives when the node is readable, and hidraw keeps
        whole reports, one a read, so there is one; the next is the next turn's (the loop's
        epoll is level-triggered). No read is made to find the queue empty: hidraw marks its
        reader as sleeping before it tests O_NONBLOCK (the kernel's drivers/hid/hidraw.c),
        and the kernel's rtapp monitor judges that mark a real-time thread's sleep (SR-9.8).
        For the same reason an unplugged node, which says it hung up and not that it is
        readable, is not read: the loop's link port breaks the link without a read
        (``link_port.HUNG_UP``)."""
        fd = self._require_open()
        try:
            report = os.read(fd, REPORT_LIMIT)
        except BlockingIOError:
            return []
        except OSError as error:
            raise LinkBrokenError(error.strerror or str(error)) from error
        if not report:
            raise LinkBrokenError("device gone")
        return [decode_hid_input(report)]

    def send(self, messages: list[Message]) -> None:
        """Display values and labels as output reports (manual §10.2.2); nothing else exists.
        Each is written behind the report number 0 (``NO_REPORT_ID``)."""
        fd = self._require_open()
        for message in messages:
            if isinstance(message, FeedbackSet):
                report = HidOutput(message.key, message.value, 0, "")
            elif isinstance(message, FeedbackName):
                report = HidOutput(0, 0, message.key, message.text)
            else:
                continue
            try:
                os.write(fd, NO_REPORT_ID + encode_hid_output(report))
            except OSError as error:
                raise LinkBrokenError(error.strerror or str(error)) from error

    def close(self) -> None:
        fd, self._fd = self._fd, None
        if fd is not None:
            os.close(fd)

    def _require_open(self) -> int:
        if self._fd is None:
            raise LinkBrokenError("not open")
        return self._fd
