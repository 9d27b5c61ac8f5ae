"""Login names of the clients' users, looked up off the loop (SR-10.3).

A uid's name comes from the system's user database through NSS, which may ask another
process: Debian's default ``nsswitch.conf`` asks systemd's userdb service for a uid that
``/etc/passwd`` does not have (a ``DynamicUser=`` service, a container's uid), and LDAP or
sssd may sit behind it. Such a lookup can wait for tens of seconds. The loop never makes it:
:class:`UserNames` keeps a cache that the loop reads, and one owned thread
(``srcsd-names``) that makes the lookups the loop asks for and wakes the loop through
:meth:`UserNames.fileno` when one is done.

The loop's side never waits: :meth:`UserNames.name` answers from the cache or says "not
yet" (``None``) and queues the lookup. A name older than ``ttl_ns`` is still answered (a
rename is rare, a wait is not allowed) and looked up again. A hung lookup holds only the
thread: the lookups queued behind it wait, and the server gives each connection at most
``NAME_WAIT_NS`` before it names the caller by its uid (``docs/api.md`` "Who is calling").
"""

from __future__ import annotations

import collections
import contextlib
import socket
import threading
from collections.abc import Callable
from typing import Final

from supervisord import threads
from supervisord.timebase import NS_PER_S

NAME_WAIT_NS: Final = 2 * NS_PER_S
"""How long a connection waits for its user's name before the uid stands in for it."""
NAME_TTL_NS: Final = 600 * NS_PER_S
"""How long a looked-up name is used before it is looked up again (still used meanwhile)."""
CACHE_SIZE: Final = 4096
"""Names kept at most (the oldest lookups are forgotten first)."""
MAX_QUEUED: Final = 256
"""Lookups waiting at most; past it a uid is named by its number at once."""


def uid_text(uid: int) -> str:
    """The name of a uid that has none (or none yet): the number as text, as ``ls -l`` shows."""
    return str(uid)


class UserNames:
    """The cache and its lookup thread (see the module docstring). ``lookup`` is the blocking
    lookup (:func:`supervisord.api.credentials.user_name`), run on the thread only."""

    def __init__(
        self,
        lookup: Callable[[int], str],
        *,
        ttl_ns: int = NAME_TTL_NS,
        cache_size: int = CACHE_SIZE,
        max_queued: int = MAX_QUEUED,
    ) -> None:
        self._lookup = lookup
        self.ttl_ns, self.cache_size, self.max_queued = ttl_ns, cache_size, max_queued
        # The loop's alone: uid -> (name, when it was looked up), oldest first.
        self._cache: collections.OrderedDict[int, tuple[str, int]] = collections.OrderedDict()
        self._asked: set[int] = set()  # queued or being looked up (the loop's view)
        # Shared with the thread, under the condition's lock.
        self._cond = threading.Condition()
        self._queue: collections.deque[int] = collections.deque()
        self._done: collections.deque[tuple[int, str]] = collections.deque()
        self._closing = False
        self._wake_r, self._wake_w = socket.socketpair()
        self._wake_r.setblocking(False)
        self._wake_w.setblocking(False)
        # A daemon thread: a lookup that never returns must not hold the process at exit.
        # Named, and at ordinary priority: a lookup is never the loop's work (SR-9.7, SR-9.8).
        self._thread = threads.start(self._run, "srcsd-names")

    # -- the loop's side -------------------------------------------------------------------

    def name(self, uid: int, now: int) -> str | None:
        """The name of ``uid`` if known (a lookup is queued when it is old), else ``None``
        and the lookup is queued. Never waits."""
        cached = self._cache.get(uid)
        if cached is None or now - cached[1] >= self.ttl_ns:
            self.ask(uid)
        return None if cached is None else cached[0]

    def ask(self, uid: int) -> None:
        """Queue a lookup of ``uid`` (once; dropped when the queue is full)."""
        if uid in self._asked or len(self._asked) >= self.max_queued:
            return
        self._asked.add(uid)
        with self._cond:
            self._queue.append(uid)
            self._cond.notify()

    def take(self, now: int) -> list[tuple[int, str]]:
        """The lookups finished since the last call, now in the cache: ``(uid, name)``."""
        with contextlib.suppress(OSError):  # BlockingIOError: nothing more to drain
            while self._wake_r.recv(4096):
                pass
        with self._cond:
            done = list(self._done)
            self._done.clear()
        for uid, name in done:
            self._asked.discard(uid)
            self._cache.pop(uid, None)
            self._cache[uid] = (name, now)
            while len(self._cache) > self.cache_size:
                self._cache.popitem(last=False)
        return done

    def fileno(self) -> int:
        """Readable when :meth:`take` has something."""
        return self._wake_r.fileno()

    def close(self) -> None:
        """Stop the thread once its current lookup returns (never waited for)."""
        with self._cond:
            self._closing = True
            self._cond.notify()
        self._wake_r.close()
        with self._cond:
            self._wake_w.close()

    # -- the thread ------------------------------------------------------------------------

    def _run(self) -> None:
        while True:
            with self._cond:
                while not self._queue and not self._closing:
                    self._cond.wait()
                if self._closing:
                    return
                uid = self._queue.popleft()
            try:
                name = self._lookup(uid)
            except Exception:  # the thread must outlive any failure: the uid stands in
                name = uid_text(uid)
            with self._cond:
                if self._wake_w.fileno() < 0:
                    return  # closed while the lookup ran
                self._done.append((uid, name))
                with contextlib.suppress(OSError):
                    self._wake_w.send(b"\0")
