"""The book of causes: which conditions hold, which stops are latched, and what changed.

Internal to the core. It enforces the latch rule of SR-2 in one place: a stop
cause, once raised, stays in the book until :meth:`CauseBook.release_latches` (a valid re-arm,
SR-4) finds its condition clear.
"""

from __future__ import annotations

from dataclasses import dataclass

from supervisord.safety.causes import Cause, CauseKind, CauseState, Details, Severity
from supervisord.safety.decision import CauseChange, ChangeKind


@dataclass(slots=True)
class _Entry:
    active: bool
    latched: bool
    raised_ns: int
    cleared_ns: int | None
    details: Details


class CauseBook:
    """Mutable store of cause entries; every change is remembered until :meth:`take_changes`."""

    def __init__(self) -> None:
        self._entries: dict[Cause, _Entry] = {}
        self._changes: list[CauseChange] = []
        self.last_stop_raised_ns: int | None = None
        """When the latest stop cause was raised: re-arms must come after it (SR-4.2)."""

    def set(self, cause: Cause, active: bool, now: int, details: Details = ()) -> None:
        """Make ``cause``'s condition active or clear at ``now``."""
        entry = self._entries.get(cause)
        if active:
            if entry is None or not entry.active:
                self._raise(cause, entry, now, details)
            elif entry.details != details:
                entry.details = details
                self._changes.append(CauseChange(cause, ChangeKind.UPDATED))
        elif entry is not None and entry.active:
            entry.active = False
            entry.cleared_ns = now
            self._changes.append(CauseChange(cause, ChangeKind.CLEARED))
            if not entry.latched:
                del self._entries[cause]

    def pulse(self, cause: Cause, now: int, details: Details = ()) -> None:
        """Fire a momentary cause: raised and clear at ``now``; a stop stays latched."""
        self._raise(cause, self._entries.get(cause), now, details)
        entry = self._entries[cause]
        entry.active = False
        entry.cleared_ns = now
        if not entry.latched:
            del self._entries[cause]

    def _raise(self, cause: Cause, entry: _Entry | None, now: int, details: Details) -> None:
        stop = cause.severity is Severity.STOP
        if entry is None:
            self._entries[cause] = _Entry(True, stop, now, None, details)
        else:
            entry.active, entry.latched = True, entry.latched or stop
            entry.raised_ns, entry.cleared_ns, entry.details = now, None, details
        if stop:
            self.last_stop_raised_ns = now
        self._changes.append(CauseChange(cause, ChangeKind.RAISED))

    def sync(self, kind: CauseKind, wanted: dict[Cause, Details], now: int) -> None:
        """Make exactly the causes in ``wanted`` active among those of ``kind``."""
        for cause in [c for c, e in self._entries.items() if c.kind is kind and e.active]:
            if cause not in wanted:
                self.set(cause, False, now)
        for cause, details in wanted.items():
            self.set(cause, True, now, details)

    def release_latches(self) -> None:
        """A valid re-arm (SR-4): drop every latched stop cause. Callers check that no stop
        condition is active first; an active one would keep its latch."""
        for cause, entry in list(self._entries.items()):
            if entry.latched and not entry.active:
                del self._entries[cause]
                self._changes.append(CauseChange(cause, ChangeKind.RELEASED))

    def active_stops(self) -> list[Cause]:
        return sorted(
            c for c, e in self._entries.items() if e.active and c.severity is Severity.STOP
        )

    def any_latched(self) -> bool:
        return any(e.latched for e in self._entries.values())

    def any_hold(self) -> bool:
        return any(e.active and c.severity is Severity.HOLD for c, e in self._entries.items())

    def user_estop(self, quiet: frozenset[CauseKind] = frozenset()) -> bool:
        """Whether any condition that sets the user heartbeat's e-stop byte is active (SR-5),
        those of the kinds in ``quiet`` aside (SR-8.15: a missing required client during a
        proof test)."""
        return any(
            e.active and c.kind.sets_user_estop and c.kind not in quiet
            for c, e in self._entries.items()
        )

    def stops_clear_since(self) -> int | None:
        """When the last latched stop condition cleared; ``None`` if any is still active
        or nothing is latched."""
        times: list[int] = []
        for entry in self._entries.values():
            if entry.latched:
                if entry.active or entry.cleared_ns is None:
                    return None
                times.append(entry.cleared_ns)
        return max(times) if times else None

    def snapshot(self) -> tuple[CauseState, ...]:
        return tuple(
            CauseState(c, e.active, e.latched, e.raised_ns, e.cleared_ns, e.details)
            for c, e in sorted(self._entries.items(), key=lambda item: item[0].name)
        )

    def canonical(self) -> tuple[object, ...]:
        """Each cause's name, whether active and latched, and its details (docs/verification.md).
        Raise and clear times are left out: only the latest clearing of a latched stop is read
        (``stops_clear_since``, a clock of the core's), and the latest raise of a stop only
        against the takeover's run (a fact of the core's). ``_changes`` is empty between steps."""
        return tuple(
            (c.name, e.active, e.latched, e.details)
            for c, e in sorted(self._entries.items(), key=lambda item: item[0].name)
        )

    def take_changes(self) -> tuple[CauseChange, ...]:
        changes, self._changes = tuple(self._changes), []
        return changes
