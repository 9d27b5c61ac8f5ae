"""The remote's battery as a part of "the e-stop is available" (SR-8.11, SR-8.12).

The remote's stop button works only while the remote has power. Its battery is the one part of
the e-stop's availability that no stop of its own covers (the VSC not heard and no remote
linked are stops already, the watchdog's proof has its policy: docs/safety.md "Is the e-stop
available?"). :func:`battery_missing` judges it, in words, for the safety core (which reacts to
it as ``vsc.on_estop_unavailable`` says) and for the status the daemon shows: one rule for
both. Pure: the caller passes ``now``.
"""

from __future__ import annotations

from typing import Final

from supervisord.compat import StrEnum
from supervisord.timebase import NS_PER_S

DEFAULT_MIN_REMOTE_BATTERY: Final = 20
"""``vsc.min_remote_battery``: below this battery percent the e-stop counts as not available.
The remote reports its battery in 10 % steps; 20 % leaves the operator time to swap it before
the remote dies and its link drops (which the VSC turns into an e-stop)."""
MIN_REMOTE_BATTERY_RANGE: Final = (0, 100)
"""0 turns the battery check off (a VSC whose remote status is not enabled)."""
REMOTE_STATUS_FRESH_NS: Final = 3 * NS_PER_S
"""A battery report this old is no report. The VSC sends remote status once a second
(manual §8.3.4, once commissioned): 3 s lets two reports in a row be late or lost (a busy
loop, a noisy serial line) without the condition flapping, yet a VSC that has stopped sending
them is noticed within seconds. The boundary counts as stale, as at every timeout of the core
(a guard ``now - t >= constant``, the form docs/verification.md's time abstraction needs)."""


class Reaction(StrEnum):
    """``vsc.on_estop_unavailable``: what the supervisor does while the remote's battery is low
    or not reported (SR-8.12)."""

    WARN = "warn"  # say so in status, the exporter and the bridge; nothing else
    HOLD = "hold"  # the cause estop_unavailable_hold: HOLD, RUN again once it is back
    STOP = "stop"  # the cause estop_unavailable: STOPPED, latched, a takeover after it is back


def battery_missing(
    now: int, level: int | None, seen_ns: int | None, min_battery: int
) -> str | None:
    """What is wrong with the remote's battery at ``now`` (ns), in words, or ``None``.

    ``level`` and ``seen_ns``: the last remote status's battery percent and when it came
    (``None``: none yet); ``min_battery``: ``vsc.min_remote_battery``, 0 for no check.
    """
    if min_battery <= 0:
        return None
    if level is None or seen_ns is None:
        return (
            "the remote's battery is not reported (the VSC sends remote status once "
            "commissioned: srcsctl commission)"
        )
    if now - seen_ns >= REMOTE_STATUS_FRESH_NS:
        # No age in the words: they are the cause's details, and a text that changed with
        # every step would be a change of the cause, recorded at every step (SR-7.1).
        fresh = REMOTE_STATUS_FRESH_NS // NS_PER_S
        return f"the remote's battery has not been reported for {fresh} s"
    if level < min_battery:
        return f"the remote's battery is {level} %, below {min_battery} %"
    return None
