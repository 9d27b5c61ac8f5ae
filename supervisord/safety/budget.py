"""How many records the clients may cause (docs/safety.md, "How many records the clients may
cause"): a sliding window per user and one for all of them together, pure (time is an
argument).

Every record is fsynced to disk, journalled and pushed to subscribers; clients that could
cause one per request at any rate could fill the record, wear the disk and make the motion
output switch as fast as they send. So the records caused by the inputs of one user (the uid
the kernel reports for the peer, ``SO_PEERCRED``: whatever connection, named or not, and
whatever process of that user sent them) count against :data:`RECORDS_PER_UID` in any
:data:`BUDGET_WINDOW_NS`, and the records of all clients together against
:data:`RECORDS_OF_ALL_CLIENTS`. A uid cannot be forged or multiplied by opening connections,
which a connection number or a client's name could. The core asks :meth:`RecordBudget.exhausted`
before an input that would take a reason to stop away, and defers the end of a request made
before hello whose last connection closed while its user is past the budget.
"""

from __future__ import annotations

from collections import deque
from typing import Final

from supervisord.safety.canonical import Canonical, clock
from supervisord.safety.face import Seen
from supervisord.timebase import NS_PER_S

RECORDS_PER_UID: Final = 20
"""Records the inputs of one user may cause in any window (10 hold/release pairs a second)."""
RECORDS_OF_ALL_CLIENTS: Final = 640
"""Records the inputs of all users together may cause in any window (32 users' worth); the
record sink's queue (4096) absorbs six seconds of it."""
BUDGET_WINDOW_NS: Final = NS_PER_S
"""The window: one second of the monotonic clock."""
KEPT: Final = 4
"""Each window keeps the times of up to this many times its limit of records, a bound on
memory: a user's stops and holds are never refused (SR-0), so it can pass its limit. Only the
``limit`` newest times decide an answer (``exhausted``, ``free_at``), so any bound of at least
one limit answers the same; the margin keeps the past-limit records visible to a reader."""
MAX_TRACKED: Final = 4096
"""Users remembered at once; the least recently charged are forgotten first (a bound on
memory: more users than this cannot be in one window, since all share
``RECORDS_OF_ALL_CLIENTS``)."""

Uid = int | None
"""Whom a record is charged to: the peer's uid, ``None`` when it is not known (one budget for
every such input)."""


class RecordBudget:
    """The records each user, and all users together, caused within the last window."""

    def __init__(
        self,
        limit: int = RECORDS_PER_UID,
        total: int = RECORDS_OF_ALL_CLIENTS,
        window_ns: int = BUDGET_WINDOW_NS,
    ) -> None:
        self.limit, self.total, self.window_ns = limit, total, window_ns
        self._times: dict[Uid, deque[int]] = {}
        self._all: deque[int] = deque(maxlen=KEPT * total)

    def _recent(self, times: deque[int], now: int) -> int:
        while times and now - times[0] >= self.window_ns:
            times.popleft()
        return len(times)

    def exhausted(self, uid: Uid, now: int) -> bool:
        """Whether ``uid`` has caused ``limit`` records, or all users ``total``, in the window
        ending at ``now`` (a record exactly one window old no longer counts)."""
        if self._recent(self._all, now) >= self.total:
            return True
        times = self._times.get(uid)
        return times is not None and self._recent(times, now) >= self.limit

    def free_at(self, uid: Uid, now: int) -> int | None:
        """When ``uid`` will be within its budget again, if it is past it at ``now``."""
        if not self.exhausted(uid, now):
            return None
        due = [
            times[len(times) - cap] + self.window_ns  # when all but cap - 1 have aged out
            for times, cap in ((self._all, self.total), (self._times.get(uid), self.limit))
            if times is not None and self._recent(times, now) >= cap
        ]
        return max(due)

    # ----------------------------------------------------------------- the face (face.py)

    def can_move(self) -> bool:
        """A window ageing out changes nothing by itself: the clients' deferred ends, which
        wait for it, are theirs (``Clients.next_deadline``)."""
        return False

    def moving(self) -> bool:
        return False

    def due_by(self, view: Seen) -> bool:
        return False

    def next_deadline(self, view: Seen) -> int | None:
        return None

    def canonical(self, view: Seen) -> Canonical:
        """The records that can still change an answer, per user and for all, as clocks
        (docs/verification.md): a window is exhausted exactly while its ``limit``-th newest
        record is less than a window old, so only the ``limit`` newest inside the window
        count (``total`` for all users). ``limit``, ``total`` and ``window_ns`` are constants."""
        now, window = view.now, self.window_ns

        def newest(times: deque[int], cap: int) -> list[int]:
            return [t for t in list(times)[-cap:] if now - t < window]

        users = sorted(self._times.items(), key=lambda item: (item[0] is None, item[0] or 0))
        clocks = [
            clock(f"budget:{uid}", t, now, window)
            for uid, times in users
            for t in newest(times, self.limit)
        ]
        clocks += [clock("budget:all", t, now, window) for t in newest(self._all, self.total)]
        return (), tuple(clocks)

    @property
    def tracked(self) -> int:
        """Users whose records are remembered (at most :data:`MAX_TRACKED`)."""
        return len(self._times)

    def charge(self, uid: Uid, now: int) -> None:
        """``uid`` caused a record at ``now``."""
        times = self._times.pop(uid, None)
        if times is None:
            times = deque(maxlen=KEPT * self.limit)
            if len(self._times) >= MAX_TRACKED:
                del self._times[next(iter(self._times))]
        times.append(now)
        self._times[uid] = times  # re-inserted: the dict stays ordered by last use
        self._all.append(now)
