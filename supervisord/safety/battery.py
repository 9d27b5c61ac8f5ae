"""The remote's battery as the safety core watches it (SR-8.12, SR-3.4).

Internal to the core, one of the machines :class:`~supervisord.safety.core.SafetyCore`
composes: :meth:`RemoteBattery.report` takes a report in, :meth:`RemoteBattery.judge` gives
the condition at ``now``, :meth:`RemoteBattery.stale_at` its next deadline and
:meth:`RemoteBattery.canonical` its canonical form (docs/verification.md). The rule itself
(what counts as missing) is :func:`~supervisord.safety.availability.battery_missing`, shared
with the status the daemon shows.
"""

from __future__ import annotations

from types import MappingProxyType
from typing import Final

from supervisord.safety.availability import (
    BATTERY_SETTLE_NS,
    REMOTE_STATUS_FRESH_NS,
    Reaction,
    battery_missing,
    stale_words,
)
from supervisord.safety.canonical import Clock, clock
from supervisord.safety.causes import Cause, CauseKind
from supervisord.safety.config import SafetyConfig
from supervisord.safety.face import Seen
from supervisord.timebase import NS_PER_MS

BATTERY_SEEN_CLIP_NS: Final = REMOTE_STATUS_FRESH_NS + 10 * NS_PER_MS
"""Where ``canonical`` clips the age of the last battery report (SR-8.12): past the 3.5 s
limit, so that the age exactly at it (a report arriving then refreshes it) and one past it (a
report arriving then finds it stale) are two forms; every age beyond is alike."""


class RemoteBattery:
    """The last battery report and the condition it raises (its reason and its runs)."""

    def __init__(self, config: SafetyConfig) -> None:
        # The cause the battery raises, or ``None`` when the core does not watch it
        # (``on_estop_unavailable = "warn"``, or no battery check).
        self.cause = (
            _CAUSES.get(config.on_estop_unavailable) if config.min_remote_battery > 0 else None
        )
        self._minimum = config.min_remote_battery
        # SR-8.12: the last remote status's battery percent and when it came, kept while watched.
        self._last: tuple[int, int] | None = None
        # SR-3.4: the condition's reason (``None``: clear) and since when it has had it, and the
        # first report of the unbroken run of good reports that may end it.
        self._words: str | None = None
        self._words_since = 0
        self._good_since: int | None = None

    def report(self, level: int, now: int) -> None:
        """A remote status with the battery at ``level`` percent, at ``now`` (watched only)."""
        self._last = (level, now)

    def judge(self, now: int, *, arriving: bool, taken_in: bool) -> str | None:
        """The battery's condition at ``now`` (SR-8.12, SR-3.4): its reason, or ``None``.
        ``arriving``: the step's input is a report; ``taken_in``: it has been reported.

        Raised in the step that sees the battery missing. It ends only at a good report that
        completes an unbroken run of good reports (none missing between them) whose first and
        last are at least ``BATTERY_SETTLE_NS`` apart; while it lasts, a report renames it at
        most once per that, and a report going stale at once (a silence of 3.5 s is its own
        bound). Both happen only at a report or at the report's deadline, steps the cheap path
        never takes, so the two paths agree (SR-9.4). So the condition ends at most once per
        second, whatever a VSC reports, and a 50 Hz flap around the minimum holds once."""
        battery = self._last
        level, seen = (None, None) if battery is None else battery
        missing = battery_missing(
            now,
            level,
            seen,
            self._minimum,
            arriving=arriving and not taken_in,  # SR-8.12: the report first
        )
        words = self._words
        if missing is not None:
            self._good_since = None  # the good run is broken
            if (
                words is None
                or missing == stale_words() != words
                or (missing != words and taken_in and now - self._words_since >= BATTERY_SETTLE_NS)
            ):
                self._words, self._words_since = missing, now
        elif words is not None and taken_in:
            first = self._good_since
            if first is None:
                self._good_since = now
            elif now - first >= BATTERY_SETTLE_NS:
                self._words = self._good_since = None
        return self._words

    def stale_at(self) -> int | None:
        """When the last battery report stops counting (SR-8.12), if the core watches it."""
        battery = self._last
        if self.cause is None or battery is None:
            return None
        return battery[1] + REMOTE_STATUS_FRESH_NS

    # ----------------------------------------------------------------- the face (face.py)

    def can_move(self) -> bool:
        """The battery moves only when its report goes stale."""
        return False

    def moving(self) -> bool:
        return False

    def due_by(self, view: Seen) -> bool:
        """Whether the last report has gone stale by ``view.now`` (SR-8.12)."""
        stale = self.stale_at()
        return stale is not None and stale <= view.now

    def next_deadline(self, view: Seen) -> int | None:
        """When the last report goes stale, if after ``view.now`` (SR-8.12)."""
        stale = self.stale_at()
        return stale if stale is not None and stale > view.now else None

    def canonical(self, view: Seen) -> tuple[tuple[object, ...], tuple[Clock, ...]]:
        """The facts and clocks of the battery (docs/verification.md): the report's age and
        whether it is low, while watched; the condition's reason and its runs."""
        now = view.now
        clocks: list[Clock] = []
        low = None
        battery = self._last
        if self.cause is not None and battery is not None:  # SR-8.12: when watched
            # A report arriving judges the old one ``age > FRESH`` (report_stale): the clock
            # runs on 10 ms past the limit, so that an age exactly at it stays told apart.
            clocks.append(
                clock("battery:seen", battery[1], now, REMOTE_STATUS_FRESH_NS, BATTERY_SEEN_CLIP_NS)
            )
            low = battery[0] < self._minimum
        if self._words is not None:  # SR-3.4: the condition's reason and its run
            clocks.append(clock("battery:words_since", self._words_since, now, BATTERY_SETTLE_NS))
            if self._good_since is not None:
                clocks.append(clock("battery:good_since", self._good_since, now, BATTERY_SETTLE_NS))
        facts = (
            ("battery_low", low),
            ("battery_words", self._words),
            ("battery_good", self._good_since is not None),
        )
        return facts, tuple(clocks)

    NOT_CANONICAL = frozenset({"cause", "_minimum"})
    """Attributes ``canonical`` leaves out: the config, and what is computed from it once."""


_CAUSES: Final = MappingProxyType(
    {
        Reaction.HOLD: Cause(CauseKind.ESTOP_UNAVAILABLE_HOLD),
        Reaction.STOP: Cause(CauseKind.ESTOP_UNAVAILABLE),
    }
)
"""SR-8.12: the cause the remote's battery raises under each ``vsc.on_estop_unavailable``
(none under ``warn``)."""
