"""The replay window: a stop is forwarded once, and only while it is fresh (SR-13.14).

A message is refused when

- its ``nonce`` was seen already (``replayed``): a captured message sent again, or the
  broker's second delivery of a QoS 1 message, is answered once;
- it is older than ``window_s`` by the robot's wall clock (``stale``): a message queued for a
  robot that was away (a persistent session), a retained one, or one an attacker held back;
- it is from more than ``skew_s`` in the robot's future (``future``): kept, it would stay fresh
  longer than the window says.

Clock skew: the age compares the console's wall clock with the robot's, so a difference
between them shifts it. ``skew_s`` (default 5 s) is the difference tolerated either way, so a
stop is fresh from ``skew_s`` before the robot's clock up to ``window_s`` after; keep the
clocks synchronised (systemd-timesyncd, as the collector's records ask, SR-13.3). A nonce is
remembered for ``window_s + skew_s`` by the monotonic clock from when it was seen, so a wall
clock step cannot shorten the memory; once forgotten, the age refuses it unless the robot's
wall clock was stepped back by more than the window meanwhile.

The memory is bounded (``max_seen``): when it is full the oldest nonce goes, and from then on
nothing sent at or before that nonce's send time is accepted (the ``floor``), so forgetting
never lets a replay through; it only refuses some old messages a little early.

Why refusing is safe: a refused message is a stop that does not happen, so the window is
generous (30 s) and every refusal is acknowledged with its reason, which the console shows as
"not stopped" (SR-13.15). A replayed stop could only stop a robot again; the window keeps an
attacker or a late queue from stopping robots at will, and from making an old stop look like
a new one's acknowledgement. Pure: the caller passes both clocks.
"""

from __future__ import annotations

import collections
from dataclasses import dataclass
from typing import Final

from supervisord.fleet_agent.message import StopMessage

WINDOW_S: Final = 30.0
SKEW_S: Final = 5.0
MAX_SEEN: Final = 10_000


@dataclass(frozen=True, slots=True)
class _Seen:
    nonce: str
    sent_utc: float
    forget_at: float  # monotonic


class ReplayGuard:
    def __init__(
        self, window_s: float = WINDOW_S, skew_s: float = SKEW_S, max_seen: int = MAX_SEEN
    ) -> None:
        self.window_s = window_s
        self.skew_s = skew_s
        self.max_seen = max_seen
        self._seen: dict[str, _Seen] = {}
        self._order: collections.deque[_Seen] = collections.deque()
        self.floor = -float("inf")

    def check(self, message: StopMessage, now_utc: float, now_mono: float) -> str | None:
        """``None`` when ``message`` is fresh (and now remembered), else why not."""
        self._forget(now_mono)
        if message.nonce in self._seen:
            return "replayed"
        age = now_utc - message.sent_utc
        if age > self.window_s:
            return "stale"
        if age < -self.skew_s:
            return "future"
        if message.sent_utc <= self.floor:
            return "stale"
        seen = _Seen(message.nonce, message.sent_utc, now_mono + self.window_s + self.skew_s)
        if len(self._order) >= self.max_seen:
            oldest = self._order.popleft()
            del self._seen[oldest.nonce]
            self.floor = max(self.floor, oldest.sent_utc)
        self._seen[message.nonce] = seen
        self._order.append(seen)
        return None

    def __len__(self) -> int:
        return len(self._seen)

    def _forget(self, now_mono: float) -> None:
        # Entries are appended in order of forget_at (one duration from a monotonic clock).
        while self._order and self._order[0].forget_at <= now_mono:
            del self._seen[self._order.popleft().nonce]
