"""Fresh heartbeats (SR-8.16): a required client's heartbeat keeps it alive only when its
progress value is new.

Internal to the core. A heartbeat may carry ``progress``, a counter from 0 to 2**32 - 1 that
the client's control loop moves on each turn. A value is *new* when it is ahead of the last one
accepted on the same connection by 1 to 2**31 - 1 steps around the circle (serial-number
arithmetic): 2**32 - 1 is followed by 0, and a duplicate, an older value replayed, or one
exactly half the circle away is not new. Once a connection's heartbeat has carried a value, or
its ``[[clients]]`` entry says ``progress = true``, every later heartbeat of that connection
must carry a new one; one that does not is refused and extends no deadline, so a thread that
beats while the loop it reports on is stuck lets the client's timeout expire
(``client_lost:NAME``, reason ``stale progress``).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Final

from supervisord.safety.decision import RefusalReason

PROGRESS_MODULUS: Final = 2**32
"""Progress values are 0 to 2**32 - 1 and wrap around (SR-8.16)."""
_AHEAD_LIMIT: Final = PROGRESS_MODULUS // 2
"""A value is new when it is 1 to this minus 1 steps ahead of the last (serial arithmetic)."""

STALE_PROGRESS: Final = "stale progress"
"""The reason of ``client_lost`` when the heartbeats since the last fresh one were not new."""
NO_PROGRESS: Final = "heartbeat without progress"
"""The reason when they carried no progress value although it is demanded."""


def is_new(value: int, last: int | None) -> bool:
    """Whether ``value`` moves on from ``last`` (``None``: nothing accepted yet, so any value
    is new); both within 0 to 2**32 - 1 (SR-8.16)."""
    return last is None or 0 < (value - last) % PROGRESS_MODULUS < _AHEAD_LIMIT


def in_range(value: object) -> bool:
    """Whether ``value`` is a progress value at all (an int, never a bool, in range)."""
    return type(value) is int and 0 <= value < PROGRESS_MODULUS


@dataclass(slots=True)
class _Connection:
    last: int | None = None  # the last progress value accepted on this connection
    bound: bool = False  # every heartbeat must carry a new value (config, or given once)
    stale: str | None = None  # why heartbeats since the last accepted one did not count


class ProgressBook:
    """Each required client's progress on its current connection (SR-8.16)."""

    def __init__(self, demanded: frozenset[str]) -> None:
        self._demanded = demanded  # the clients whose config says progress = true
        self._clients: dict[str, _Connection] = {}

    def restart(self, name: str) -> None:
        """A new connection of ``name`` (its hello) or its end: its counter starts again."""
        self._clients[name] = _Connection(bound=name in self._demanded)

    def beat(self, name: str, progress: int | None) -> RefusalReason | None:
        """Judge a heartbeat of ``name``, a required client whose hello :meth:`restart` saw:
        ``None`` when it keeps the client alive, else the refusal (the heartbeat then extends
        no deadline)."""
        client = self._clients[name]
        if progress is None:
            if client.bound:
                client.stale = NO_PROGRESS
                return RefusalReason.NO_PROGRESS
            return None
        if not in_range(progress) or not is_new(progress, client.last):
            client.stale = STALE_PROGRESS
            return RefusalReason.STALE_PROGRESS
        client.last, client.bound, client.stale = progress, True, None
        return None

    def unbound(self, name: str) -> bool:
        """Whether ``name``'s heartbeats count without a progress value: not bound to one by
        its config nor by a value it sent on this connection (a heartbeat without one then
        changes nothing here)."""
        client = self._clients.get(name)
        return client is not None and not client.bound

    def stale(self, name: str) -> str | None:
        """Why ``name``'s heartbeats since its last accepted one did not count, if any did not."""
        client = self._clients.get(name)
        return None if client is None else client.stale

    def canonical(self) -> tuple[object, ...]:
        """Every client's last value, whether bound and why stale (docs/verification.md)."""
        return tuple((name, c.last, c.bound, c.stale) for name, c in sorted(self._clients.items()))
