"""What every link offers the daemon's loop, and the reopen backoff."""

from __future__ import annotations

import abc
from collections.abc import Callable

from supervisord.errors import SrcsError
from supervisord.protocol.framing import Rejection
from supervisord.protocol.hid import HidInput, HidRejection
from supervisord.protocol.j1939 import CanRejection
from supervisord.protocol.messages import Message
from supervisord.timebase import NS_PER_MS

Incoming = Message | HidInput | Rejection | CanRejection | HidRejection
"""What a link hands the loop: a message (a HID input report on HID), or a rejection of what
arrived and was not one."""


class LinkError(SrcsError):
    """The port or bus could not be opened, or failed. ``reason`` says why in a few words."""

    def __init__(self, reason: str) -> None:
        super().__init__(reason)
        self.reason = reason


class LinkBrokenError(LinkError):
    """The world broke an open link: unplugged, I/O error, bus-off (trio's "broken")."""


class Link(abc.ABC):
    """One connection to the VSC. Life cycle: ``open``, then ``receive``/``send`` until a
    ``LinkBrokenError`` or ``close``; then ``open`` again for a new start."""

    @abc.abstractmethod
    def open(self) -> None:
        """Open the port or bus; raises ``LinkError`` (missing, busy, refused)."""

    prepares_open = False
    """Whether the link's open has work that may sleep in the kernel, which :meth:`prepare`
    does off the loop (the HID link: usbhid sleeps 50 ms in a node's first open)."""

    def prepare(self) -> None:
        """The open's sleeping part, done on a thread of its own before :meth:`open`, which
        then takes what it made (or raises what it met). Called only when
        :attr:`prepares_open`, never beside another call on the link; never raises."""
        return  # a link whose open does not sleep has nothing to prepare

    @abc.abstractmethod
    def fileno(self) -> int | None:
        """The descriptor to wait on while open: ``receive`` is called when it is readable (a
        serial port that has nothing reads as empty, which is how it tells an unplug).
        ``None`` if the interface has none: the loop then polls ``receive`` every few
        milliseconds, and with nothing arrived it returns nothing."""

    @abc.abstractmethod
    def receive(self) -> list[Incoming]:
        """Everything that has arrived, decoded, without blocking: a frame that fails the
        protocol's check is a rejection, never a message. Raises ``LinkBrokenError``, also
        when not open."""

    @abc.abstractmethod
    def send(self, messages: list[Message]) -> None:
        """Write ``messages`` at once, in order, each in the transport's form (one it has no
        form for is not sent); raises ``LinkBrokenError``, also when not open."""

    @abc.abstractmethod
    def close(self) -> None:
        """Release the port or bus. Safe to call twice and after a failure."""

    def detach(self) -> Callable[[], None] | None:
        """Close the link to the loop at once, after a break: not open, no descriptor. What is
        left to release, when its release may sleep in the kernel, comes back to be called off
        the loop (the serial link: a tty's close waits for the tty's lock), or ``None`` when
        all is released here (the default: ``close``)."""
        self.close()
        return None

    @property
    @abc.abstractmethod
    def is_open(self) -> bool: ...

    @property
    @abc.abstractmethod
    def description(self) -> str:
        """Where the link goes, for the log and the status."""


class Backoff:
    """When to try opening a link again: ``first_ms``, doubling to ``max_ms``; a successful
    open resets it. Pure: times are monotonic nanoseconds passed in."""

    def __init__(self, first_ms: int = 100, max_ms: int = 5000) -> None:
        self._first = first_ms * NS_PER_MS
        self._max = max_ms * NS_PER_MS
        self._delay = self._first
        self.next_attempt = 0

    def failed(self, now: int) -> None:
        self.next_attempt = now + self._delay
        self._delay = min(self._delay * 2, self._max)

    def succeeded(self) -> None:
        self._delay = self._first
