"""The USB HID link: hidraw input reports, for monitoring and teleoperation only.

HID mode carries no host heartbeat (PR-4), so it is never a safety channel: with this
link the safety core never leaves STOPPED, and the daemon says so at start.
"""

from __future__ import annotations

import os
import threading

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

    prepares_open = True
    """usbhid's open of a device that no program has open sleeps 50 ms (``msleep`` in
    ``usbhid_open``, the kernel's drivers/hid/usbhid/hid-core.c, to let the device's queue
    empty), woken by the timer wheel's softirq: a wake from below that the kernel's rtapp
    monitor flags, and 50 ms the loop could not serve anything. So the node is opened off the
    loop (:meth:`prepare`, SR-9.8)."""

    def __init__(self, path: str) -> None:
        self._path = path
        self._fd: int | None = None
        self._prepared: int | OSError | None = None  # prepare's descriptor or error
        self._prepared_lock = threading.Lock()

    @property
    def description(self) -> str:
        return f"HID {self._path} (no safety channel)"

    @property
    def is_open(self) -> bool:
        return self._fd is not None

    def prepare(self) -> None:
        """Open the node, for :meth:`open` to take (on the link port's ``srcsd-open``
        thread, at ordinary priority)."""
        opened = self._open_node()
        with self._prepared_lock:
            self._prepared = opened

    def open(self) -> None:
        """Take the node :meth:`prepare` opened, or open it here when nothing was prepared."""
        if self._fd is not None:
            return
        with self._prepared_lock:
            opened, self._prepared = self._prepared, None
        if opened is None:
            opened = self._open_node()
        if isinstance(opened, OSError):
            # A device the daemon may not open names its group and the fix (SR-8.18).
            reason = (opened.strerror or str(opened)) + denied_advice(self._path, opened)
            raise LinkError(reason) from opened
        self._fd = opened

    def _open_node(self) -> int | OSError:
        try:
            return os.open(self._path, os.O_RDWR | os.O_NONBLOCK | os.O_CLOEXEC)
        except OSError as error:
            return error

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
        with self._prepared_lock:  # a prepared node never taken is closed too
            prepared, self._prepared = self._prepared, None
        for each in (fd, prepared):
            if isinstance(each, int):
                os.close(each)

    def _require_open(self) -> int:
        if self._fd is None:
            raise LinkBrokenError("not open")
        return self._fd
