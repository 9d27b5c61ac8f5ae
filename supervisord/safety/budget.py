"""How many records one client may cause (docs/safety.md, "How many records one client may
cause"): a sliding window per client, pure (time is an argument).

Every record is fsynced to disk, journalled and pushed to subscribers; a client that could
cause one per request at any rate could fill the record, wear the disk and make the motion
output switch as fast as it sends. So each client (a named client by its name, an unnamed
connection by its number, a local command by its caller's uid and pid) may cause at most
:data:`RECORDS_PER_CLIENT` records in any :data:`BUDGET_WINDOW_NS`. The core asks
:meth:`RecordBudget.exhausted` before an input that would take a reason to stop away.
"""

from __future__ import annotations

from collections import deque
from collections.abc import Hashable
from typing import Final

from supervisord.timebase import NS_PER_S

RECORDS_PER_CLIENT: Final = 20
"""Records one client may cause in any window (10 hold/release pairs a second)."""
BUDGET_WINDOW_NS: Final = NS_PER_S
"""The window: one second of the monotonic clock."""
MAX_TRACKED: Final = 4096
"""Clients remembered at once; the oldest are forgotten first (a bound on memory)."""


class RecordBudget:
    """The records each client caused within the last window."""

    def __init__(self, limit: int = RECORDS_PER_CLIENT, window_ns: int = BUDGET_WINDOW_NS) -> None:
        self.limit, self.window_ns = limit, window_ns
        self._times: dict[Hashable, deque[int]] = {}

    def exhausted(self, client: Hashable, now: int) -> bool:
        """Whether ``client`` has caused ``limit`` records in the window ending at ``now``."""
        times = self._times.get(client)
        if times is None:
            return False
        while times and now - times[0] >= self.window_ns:
            times.popleft()
        if not times:
            del self._times[client]
            return False
        return len(times) >= self.limit

    def charge(self, client: Hashable, now: int) -> None:
        """``client`` caused a record at ``now``."""
        times = self._times.pop(client, None)
        if times is None:
            times = deque(maxlen=self.limit)
            if len(self._times) >= MAX_TRACKED:
                del self._times[next(iter(self._times))]
        times.append(now)
        self._times[client] = times  # re-inserted: the dict stays ordered by last use
