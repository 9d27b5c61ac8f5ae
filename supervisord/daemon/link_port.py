"""The link to the VSC as the loop uses it: open with a backoff, receive, send, and count.

The loop asks and the port answers with values, never calling back into the loop: what the
core must be fed of the link comes back as an event (``LinkOpened``, ``LinkBroken``) or as the
messages read with the time they were read; the loop feeds them and applies each decision in
its order (SR-6).

- ``open(now)``: ``LinkOpened``, or ``LinkBroken`` with the reason it could not open (the
  backoff then says when to try again, ``next_attempt``; SR-2.5 ``transport_fault``). A link
  whose open may sleep in the kernel (``prepares_open``: serial and HID) first has its
  ``prepare`` run on a thread of its own (``srcsd-open``): ``None`` until it has returned,
  asked again every ``PREPARE_POLL_NS``, so the loop never waits in the open (SR-9.8).
- ``receive(events)``: the messages read and the clock read right after the read (what was
  read counts as received then, SR-2), rejections counted by reason and left out (SR-2.1); or
  ``LinkBroken``, the link closed to the loop and the backoff started. What of its release
  may sleep in the kernel (a tty's close) runs on a thread of its own (``srcsd-close``), and
  the next ``open`` waits for it as for a ``prepare`` (SR-9.8). ``events`` is what epoll said of
  the link's descriptor: one that hung up with nothing to read is broken without a read
  (``HUNG_UP``, SR-9.8).
- ``send(frames, now)``: the frames written at once, in order; ``LinkBroken`` if the write
  broke the link. When a user heartbeat's write returned is its period as the VSC's watchdog
  sees it (SR-5.1, SR-9.3).
- ``heard(now)``: a read that brought VSC heartbeats, after their decisions were applied: one
  period each (SR-2.2).
- ``status(now)``: the link's part of ``srcsctl status`` (SR-8.18).
"""

from __future__ import annotations

import contextlib
import logging
import select
import threading
from collections.abc import Callable, Sequence

from supervisord import threads
from supervisord.api.status import LinkStatus
from supervisord.clock import Clock
from supervisord.daemon.timings import Timings
from supervisord.links.base import Backoff, Link, LinkBrokenError, LinkError
from supervisord.protocol.framing import Rejection
from supervisord.protocol.hid import HidInput, HidRejection
from supervisord.protocol.j1939 import CanRejection
from supervisord.protocol.messages import Message, UserHeartbeat
from supervisord.safety.events import LinkBroken, LinkOpened
from supervisord.timebase import NS_PER_MS, seconds_since

log = logging.getLogger("srcsd")

_REJECTIONS = frozenset((Rejection, CanRejection, HidRejection))  # final classes: by type
FAILURES_LOGGED_EVERY = 50  # a link that keeps failing to open: its first failure, then 1 in 50
HUNG_UP = "hung up, nothing to read"
"""Why a link broke whose descriptor hung up with nothing left to read: an unplugged hidraw
node says ``EPOLLHUP | EPOLLERR`` without ``EPOLLIN`` (the kernel's drivers/hid/hidraw.c), and
a read then would only find the device gone after hidraw has marked the reader sleeping,
which the kernel's rtapp monitor judges a real-time thread's sleep (SR-9.8). A tty that hangs
up (a USB serial unplug) says ``EPOLLIN`` too: it is read, and its read says why."""
_READ_OR_HANG_UP = select.EPOLLIN | select.EPOLLHUP
PREPARE_POLL_NS = 10 * NS_PER_MS
"""How often the loop looks whether a link's ``prepare`` (usbhid's takes 50 ms and more) or
its last close has returned: a look is a thread's ``is_alive``, nothing waits."""
PREPARE_THREAD = "srcsd-open"
CLOSE_THREAD = "srcsd-close"
CLOSE_WAIT_S = 1.0
"""How long the daemon's exit waits for a broken link's close or a ``prepare`` still under
way: the exit goes on after it (SR-6.6); the kernel releases what is left when the process
ends."""

Received = list[Message | HidInput]
"""The messages of one read, in the order they arrived."""


class LinkPort:
    """One link, its reopen backoff, its counters, and the heartbeats' periods (written into
    the loop's :class:`~supervisord.daemon.timings.Timings`, handed at construction)."""

    def __init__(
        self,
        link: Link,
        clock: Clock,
        timings: Timings,
        backoff: Backoff | None = None,
        release: Sequence[Callable[[], object]] = (),
    ) -> None:
        self.link = link
        self.release = tuple(release)  # what was opened for the link (a CAN bus it owns)
        self.clock = clock
        self.timings = timings
        self.backoff = backoff or Backoff()
        self.opens = 0
        self.failures = 0  # opens that failed
        self.messages = 0  # valid messages received
        self.rejections: dict[str, int] = {}  # what arrived and was no message, by reason
        self.since_ns: int | None = None  # when the link last opened or broke (or the start)
        self.error: str | None = None  # why it broke or failed to open, until it opens
        self._preparing: threading.Thread | None = None  # the link's prepare, under way
        self._closing: threading.Thread | None = None  # the broken link's close, under way

    @property
    def next_attempt(self) -> int:
        """When a closed link is to be opened again."""
        return self.backoff.next_attempt

    def open(self, now: int) -> LinkOpened | LinkBroken | None:
        """Try to open the link at ``now``; ``None`` while its last close or its ``prepare``
        is under way."""
        if self._under_way():
            self.backoff.next_attempt = now + PREPARE_POLL_NS
            return None
        try:
            self.link.open()
        except LinkError as error:
            self.failures += 1
            self.error = f"cannot open: {error.reason}"
            self.backoff.failed(now)
            if self.failures == 1 or self.failures % FAILURES_LOGGED_EVERY == 0:
                log.warning("%s: cannot open: %s (retrying)", self.link.description, error)
            return LinkBroken(now, f"cannot open: {error.reason}")
        self.backoff.succeeded()
        self.opens += 1
        # The error said why the link was not open; open, it is history (its count stays in
        # open_failures, the break in the record): status shows none from before (SR-8.18).
        self.since_ns, self.error = now, None
        # A period across a reopen would measure the outage, not the cadence: start afresh
        # (the outage shows in the link's counters).
        self.timings.last_vsc_heartbeat_ns = self.timings.last_user_heartbeat_ns = None
        log.info("%s: open", self.link.description)
        return LinkOpened(now)

    def broken(self, now: int, reason: str) -> LinkBroken:
        """The world broke the link at ``now``: closed to the loop at once (what may sleep of
        its release on ``srcsd-close``: the break is decided without waiting for it, SR-9.8),
        and reopened after the backoff."""
        log.warning("%s: broken: %s", self.link.description, reason)
        self.since_ns, self.error = now, reason
        release = self.link.detach()
        if release is not None:
            self._closing = threads.start(release, CLOSE_THREAD)
        self.backoff.failed(now)
        return LinkBroken(now, reason)

    def settle(self, timeout_s: float) -> None:
        """Wait, ``timeout_s`` at most, for the link's close and ``prepare`` under way (at the
        start, before the loop serves anything, and at the exit)."""
        for thread in (self._closing, self._preparing):
            if thread is not None:
                thread.join(timeout_s)

    def _under_way(self) -> bool:
        """Whether the broken link's close, or the link's ``prepare`` (started here when it
        prepares its open), is still running. The close comes first: a serial port is opened
        exclusively, so an open beside the old close would be refused as busy."""
        if self._closing is not None:
            if self._closing.is_alive():
                return True
            self._closing = None
        if self.link.prepares_open:
            if self._preparing is None:
                self._preparing = threads.start(self.link.prepare, PREPARE_THREAD)
            if self._preparing.is_alive():
                return True
            self._preparing = None
        return False

    def receive(self, events: int = select.EPOLLIN) -> tuple[int, Received] | LinkBroken:
        """What has arrived, and when it was read; or the break the read found. ``events``:
        epoll's mask for the link's descriptor (a link polled without one: ``EPOLLIN``)."""
        if events & _READ_OR_HANG_UP == select.EPOLLHUP:  # hung up, nothing left: no read
            return self.broken(self.clock(), HUNG_UP)
        try:
            received = self.link.receive()
        except LinkBrokenError as error:
            return self.broken(self.clock(), error.reason)
        now = self.clock()  # what was read counts as received now: right after the read (SR-2)
        for item in received:
            if type(item) in _REJECTIONS:
                break
        else:  # the usual read, every item a message: handed on as it is (SR-9.4)
            self.messages += len(received)
            return now, received  # type: ignore[return-value]
        messages: Received = []
        for item in received:
            kind = type(item)
            if kind in _REJECTIONS:
                reason = "wrong_length" if kind is HidRejection else item.reason.value  # type: ignore[union-attr]
                self.rejections[reason] = self.rejections.get(reason, 0) + 1
            else:
                messages.append(item)  # type: ignore[arg-type]
        self.messages += len(messages)
        return now, messages

    def heard(self, now: int) -> None:
        """A read at ``now`` brought VSC heartbeats: one period since the last such read, the
        time the link-loss timer saw between two signs of life (SR-2.2). Heartbeats read
        together (after a stall) are one sign, not periods of 0 (docs/fleet.md)."""
        timings = self.timings
        if timings.last_vsc_heartbeat_ns is not None:
            timings.vsc_heartbeat_period.observe(now - timings.last_vsc_heartbeat_ns)
        timings.last_vsc_heartbeat_ns = now

    def send(self, frames: tuple[Message, ...], now: int) -> LinkBroken | None:
        """Write ``frames`` (none, or a closed link: nothing); the break if the write broke it."""
        if not frames or not self.link.is_open:
            return None
        try:
            self.link.send(list(frames))
        except LinkBrokenError as error:
            return self.broken(now, error.reason)
        for frame in frames:
            if type(frame) is UserHeartbeat:
                # When the write returned: the period the VSC's watchdog sees, to the loop's
                # accuracy (SR-5.1, SR-9.3). One clock read per heartbeat, 20 to 50 a second.
                sent = self.clock()
                timings = self.timings
                if timings.last_user_heartbeat_ns is not None:
                    timings.user_heartbeat_period.observe(sent - timings.last_user_heartbeat_ns)
                timings.last_user_heartbeat_ns = sent
                break
        return None

    def close(self) -> None:
        """Close the link, then release what was opened for it, each release best effort:
        one that fails leaves the others to run (SR-6.6: the exit goes on). A broken link's
        close or a ``prepare`` still under way is waited for, ``CLOSE_WAIT_S`` at most."""
        self.settle(CLOSE_WAIT_S)  # first: what a prepare made is closed with the link
        self.link.close()
        for release in self.release:
            with contextlib.suppress(Exception):
                release()

    def status(self, now: int) -> LinkStatus:
        """The link as ``srcsctl status`` shows it at ``now`` (docs/api.md "status")."""
        return LinkStatus(
            description=self.link.description,
            open=self.link.is_open,
            opens=self.opens,
            open_failures=self.failures,
            # How long it has been open (or not), and why it last broke or could not open;
            # cleared when it opens (SR-8.18): a flapping link shows its count instead.
            since_s=seconds_since(now, self.since_ns),
            last_error=self.error,
            # CAN only (null on serial and HID): error frames counted since start, each
            # one stopping nothing (SR-2.12; docs/safety.md "CAN error frames").
            error_frames=_error_frames(self.link),
        )


def _error_frames(link: Link) -> int | None:
    """The link's count of CAN error frames, or ``None`` for a link that has none (read by
    attribute: the CAN link, and python-can with it, is imported only for a CAN VSC)."""
    count = getattr(link, "error_frames", None)
    return count if isinstance(count, int) else None
