"""The loop's wait: epoll and what it watches, the wake pair, and the clients' order.

The loop tells the waiter what to watch before each wait (the link's descriptor and the
listener's), waits through it, and asks it to sort what was ready and to put the ready
clients in their order; the waiter hands back values and never calls into the loop, the link
or the listener. What is served, and when, stays the loop's (``docs/safety.md`` "The stop path
first"):

- ``watch(link_fd, descriptors)``: the descriptors to watch this turn. A turn that watches the
  same as the last (the usual one) registers nothing: one comparison (SR-9.4).
- ``wait(timeout)``: epoll's own ``poll``, not the ``selectors`` wrapper, which builds a key per
  ready descriptor on every turn (SR-9.4). A bench may replace it to time the wait from outside.
- ``sort(ready)``: the link's events (0: not ready), whether the record sink is ready, and
  the ready clients; the wake pair (a stopping signal's) is drained here.
- ``order(ready, urgent)``: the urgent clients (the operator socket, SR-8.14), then the others
  starting after the one served last (``cursor``), so that every client gets its turn
  (SR-10.1).
- ``readiness(fd, mask)``: readable and writable, as ``selectors`` reads an epoll mask.
"""

from __future__ import annotations

import contextlib
import select
import socket
from collections.abc import Callable, Collection, Iterable

WAKE, SINK = "wake", "sink"

Ready = list[tuple[int, int]]
"""(fd, epoll mask) pairs, as ``epoll.poll`` returns them."""


class Waiter:
    """One epoll set, the wake pair and the clients' cursor. ``link_fd`` is the link's
    descriptor as watched for this wait (``None``: closed, or a link polled without one)."""

    def __init__(self) -> None:
        self._epoll = select.epoll()
        self.wait: Callable[..., Ready] = self._epoll.poll  # (timeout_s, maxevents=-1)
        self._tags: dict[int, str] = {}  # the wake pair's and the sink's fds
        self.watched: dict[int, int] = {}  # the link's and the clients' fds, and their events
        self._watched_api: list[tuple[int, bool]] | None = None  # the listener's, last turn
        self.link_fd: int | None = None
        self._wake_r, self._wake_w = socket.socketpair()
        # A handler's write never blocks: on a full pair (a flood of signals, none drained
        # during the shutdown) it is dropped, since one pending byte already ends the wait
        # (SR-6.6, SR-7.14).
        self._wake_w.setblocking(False)
        self.cursor = -1  # the last client descriptor served: the next turn starts after it

    def start(self, sink_fd: int) -> None:
        """Watch the wake pair and the record sink's descriptor from now on."""
        self._wake_r.setblocking(False)
        for fd, tag in ((self._wake_r.fileno(), WAKE), (sink_fd, SINK)):
            self._epoll.register(fd, select.EPOLLIN)
            self._tags[fd] = tag

    def wake(self) -> None:
        """End the current wait (from a signal handler: one byte, never blocks or raises)."""
        with contextlib.suppress(OSError):
            self._wake_w.send(b"\0")

    def watch(self, link_fd: int | None, api: Iterable[tuple[int, bool]]) -> None:
        """Watch ``link_fd`` (``None``: none) for reading and the listener's ``(fd,
        wants_write)`` pairs, and nothing else of theirs."""
        if link_fd == self.link_fd and api == self._watched_api:
            return  # the usual turn: the same list as the last, nothing to register (SR-9.4)
        if self.link_fd is not None and link_fd != self.link_fd:
            # The link's old descriptor was closed mid-turn (a break), and a client accepted
            # in the same turn may have its number now: forgotten here, so that a client of
            # that number is registered as new (the kernel dropped the closed file's watch).
            # The clients' own descriptors are closed only before a watch, never mid-turn
            # (the API server releases its ended connections in ``descriptors``).
            with contextlib.suppress(KeyError, ValueError, OSError):
                self._epoll.unregister(self.link_fd)
            self.watched.pop(self.link_fd, None)
        wanted: dict[int, int] = {}
        if link_fd is not None:
            wanted[link_fd] = select.EPOLLIN
        for api_fd, wants_write in api:
            wanted[api_fd] = select.EPOLLIN | (select.EPOLLOUT if wants_write else 0)
        for old in set(self.watched) - set(wanted):
            with contextlib.suppress(KeyError, ValueError, OSError):
                self._epoll.unregister(old)
        for new, events in wanted.items():
            if new not in self.watched:
                self._epoll.register(new, events)
            elif self.watched[new] != events:
                self._epoll.modify(new, events)
        self.watched = wanted
        self.link_fd = link_fd
        self._watched_api = api if isinstance(api, list) else None  # a list compares cheaply

    def sort(self, ready: Ready) -> tuple[int, bool, Ready]:
        """The link's epoll mask (0: not ready; the link port tells a hang-up by it), whether
        the sink is ready, and the ready clients, in the order epoll gave them. The wake pair
        is drained: its byte only ended the wait."""
        link_fd, tags, watched = self.link_fd, self._tags, self.watched
        link_events = 0
        sink_ready = False
        clients: Ready = []
        for fd, mask in ready:
            if fd == link_fd:
                link_events = mask
                continue
            tag = tags.get(fd)
            if tag == WAKE:
                with contextlib.suppress(BlockingIOError):
                    self._wake_r.recv(64)
            elif tag == SINK:
                sink_ready = True
            elif fd in watched:
                clients.append((fd, mask))
        return link_events, sink_ready, clients

    def order(self, ready: Ready, urgent: Collection[int]) -> tuple[Ready, Ready]:
        """The urgent ready clients, and the others in their turn: by descriptor, starting
        after ``cursor`` and wrapping round. The caller sets ``cursor`` to each it serves."""
        first = [item for item in ready if item[0] in urgent]
        rest = sorted(item for item in ready if item[0] not in urgent)
        cursor = self.cursor
        later = [item for item in rest if item[0] > cursor]
        return first, later + [item for item in rest if item[0] <= cursor]

    def readiness(self, fd: int, mask: int) -> tuple[bool, bool]:
        """Readable and writable, as ``selectors`` reads an epoll mask: an error or a hang-up
        counts as both, each only where it is watched."""
        watched = self.watched.get(fd, 0)
        readable = bool(mask & ~select.EPOLLOUT and watched & select.EPOLLIN)
        writable = bool(mask & ~select.EPOLLIN and watched & select.EPOLLOUT)
        return readable, writable

    def close(self) -> None:
        self._epoll.close()
        self._wake_r.close()
        self._wake_w.close()
