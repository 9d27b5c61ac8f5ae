"""A queue served by a thread of its own: how slow work leaves the loop (SR-7.5, SR-7.7;
``supervisord/daemon/sink.py`` gives each kind of work a lane).

The one place besides the loop's clock where the daemon's code reads time: a lane's thread
waits on a condition, and a thread's wait runs on the real monotonic clock. It happens only at
the exit (:meth:`Lane.finish`), after the loop has stopped, so the loop's world keeps one
clock (the one injected into it).
"""

from __future__ import annotations

import collections
import select
import threading
import time
from collections.abc import Callable
from typing import Generic, TypeVar

from supervisord import threads

T = TypeVar("T")


def deadline_after(seconds: float) -> float:
    """The monotonic time ``seconds`` from now: a deadline for :meth:`Lane.finish`."""
    return time.monotonic() + seconds


class Lane(Generic[T]):
    """A bounded queue and one daemon thread that serves its items in order with ``serve``
    (which must not raise), up to ``batch`` of them at a time. :meth:`put` never waits;
    :meth:`finish` waits at most until a deadline. The thread (:func:`supervisord.threads.start`)
    is a daemon thread: one stuck in a device (a pipe nobody reads) never holds the process's
    exit. ``name`` is the thread's, in the kernel too: 15 bytes at most."""

    def __init__(
        self, name: str, capacity: int, serve: Callable[[list[T]], None], batch: int = 1
    ) -> None:
        self.capacity, self.batch = capacity, batch
        self.dropped = 0
        """Items refused (queue full, or closed) or left unserved at :meth:`finish`."""
        self._serve = serve
        self._items: collections.deque[T] = collections.deque()
        self._busy = 0  # items being served
        self._closed = False
        self._cond = threading.Condition()
        self.name = name
        self._thread: threading.Thread | None = None

    def start(self) -> None:
        """Start the lane's thread: named, at ordinary priority (SR-9.7, SR-9.8)."""
        self._thread = threads.start(self._run, self.name)

    def _alive(self) -> bool:
        return self._thread is not None and self._thread.is_alive()

    def put(self, item: T) -> bool:
        """Queue ``item``; ``False`` (counted in :attr:`dropped`) when full or finished."""
        with self._cond:
            if self._closed or len(self._items) >= self.capacity:
                self.dropped += 1
                return False
            self._items.append(item)
            self._cond.notify_all()
        return True

    @property
    def pending(self) -> int:
        """Items queued or being served."""
        with self._cond:
            return len(self._items) + self._busy

    @property
    def idle(self) -> bool:
        """Nothing queued, nothing being served."""
        return self.pending == 0

    def finish(self, deadline: float) -> list[T]:
        """Take no more items, and wait until every queued item is served or the monotonic
        ``deadline`` (seconds, :func:`deadline_after`) has passed. Returns the items left
        unserved, which are taken out of the queue (never served later) and counted in
        :attr:`dropped`."""
        with self._cond:
            self._closed = True
            self._cond.notify_all()
            while (self._items or self._busy) and self._alive():
                remaining = deadline - time.monotonic()
                if remaining <= 0:
                    break
                self._cond.wait(remaining)
            left = list(self._items)
            self._items.clear()
            self.dropped += len(left)
            self._cond.notify_all()
            ending = self._alive() and not self._busy
        if ending and self._thread is not None:  # nothing left: the thread ends at once
            self._thread.join(max(0.0, deadline - time.monotonic()))
        return left

    def _run(self) -> None:
        while True:
            with self._cond:
                while not self._items and not self._closed:
                    self._cond.wait()
                if not self._items:
                    return  # finished, and everything is served
                taken = [self._items.popleft() for _ in range(min(self.batch, len(self._items)))]
                self._busy = len(taken)
            try:
                self._serve(taken)
            finally:
                with self._cond:
                    self._busy = 0
                    self._cond.notify_all()


def hand_over() -> None:
    """Let another thread have the interpreter's lock for a moment (the loop's, SR-7.12): a wait
    of zero, which releases it. ``select`` rather than ``time.sleep(0)``: under libfaketime
    (the fleet tier's robots with a skewed clock) ``time.sleep`` fails with EINVAL (its
    absolute ``clock_nanosleep`` on the monotonic clock), and every flight recorder window of
    those robots was lost to it (docs/fleet.md "The fleet tier")."""
    select.select([], [], [], 0)
