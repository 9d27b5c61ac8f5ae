"""Login names of the clients' users, looked up off the loop (SR-10.3).

A uid's name comes from the system's user database through NSS, which may ask another
process: Debian's default ``nsswitch.conf`` asks systemd's userdb service for a uid that
``/etc/passwd`` does not have (a ``DynamicUser=`` service, a container's uid), and LDAP or
sssd may sit behind it. Such a lookup can wait for tens of seconds. The loop never makes it:
:class:`UserNames` keeps a cache that the loop reads, and one owned thread
(``srcsd-names``) that makes the lookups the loop asks for.

The thread never wakes the loop (SR-10.7): it is of ordinary priority and the loop
``SCHED_FIFO``, and a wake of a real-time thread by a lower-priority one makes the loop's
turn wait on that thread's scheduling (the kernel's rtapp monitors flag each one; the
system tier saw this thread wake the loop up to 146 times in 15 s when it wrote a byte to a
socket the loop watched for each finished lookup). A finished lookup is left where the loop
takes it (:meth:`UserNames.take`) at its own turns: every turn looks, and while a connection
waits for its name the server asks for a turn every ``NAME_POLL_NS`` (its own deadline, a
timer the kernel fires in a hard interrupt). Nothing is shared under a lock the loop could
wait for: the asks go through a :class:`queue.SimpleQueue` (whose ``put`` never blocks) and
the answers through a deque (``append`` and ``popleft`` are atomic).

The loop's side never waits: :meth:`UserNames.name` answers from the cache or says "not
yet" (``None``) and queues the lookup. A name older than ``ttl_ns`` is still answered (a
rename is rare, a wait is not allowed) and looked up again. A hung lookup holds only the
thread: the lookups queued behind it wait, and the server gives each connection at most
``NAME_WAIT_NS`` before it names the caller by its uid (``docs/api.md`` "Who is calling").
"""

from __future__ import annotations

import collections
import queue
from collections.abc import Callable
from typing import Final

from supervisord import threads
from supervisord.timebase import NS_PER_MS, NS_PER_S

NAME_WAIT_NS: Final = 2 * NS_PER_S
"""How long a connection waits for its user's name before the uid stands in for it."""
NAME_POLL_NS: Final = 20 * NS_PER_MS
"""How often the loop looks for a finished lookup while a connection waits for its name (its
own deadline: no lookup wakes it, SR-10.7). A new user's first requests but an e-stop wait at
most a lookup and this long."""
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
        # Shared with the thread, with no lock the loop could wait for (SR-10.7): the loop
        # puts uids (None: end), the thread appends what it found.
        self._queue: queue.SimpleQueue[int | None] = queue.SimpleQueue()
        self._done: collections.deque[tuple[int, str]] = collections.deque()
        self._closing = False
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
        self._queue.put(uid)  # never blocks; wakes the thread, which is not real-time

    def waiting(self) -> bool:
        """A lookup is queued, running, or finished and not taken yet."""
        return bool(self._asked)

    def take(self, now: int) -> list[tuple[int, str]]:
        """The lookups finished since the last call, now in the cache: ``(uid, name)``. Cheap
        when there are none: the loop calls it every turn."""
        done = self._done
        if not done:
            return []
        taken: list[tuple[int, str]] = []
        while done:
            taken.append(done.popleft())
        for uid, name in taken:
            self._asked.discard(uid)
            self._cache.pop(uid, None)
            self._cache[uid] = (name, now)
            while len(self._cache) > self.cache_size:
                self._cache.popitem(last=False)
        return taken

    def close(self) -> None:
        """Stop the thread once its current lookup returns (never waited for)."""
        self._closing = True
        self._queue.put(None)

    # -- the thread ------------------------------------------------------------------------

    def _run(self) -> None:
        while True:
            uid = self._queue.get()
            if uid is None or self._closing:
                return
            try:
                name = self._lookup(uid)
            except Exception:  # the thread must outlive any failure: the uid stands in
                name = uid_text(uid)
            # Left for the loop's next look (SR-10.7): no wake.
            self._done.append((uid, name))
