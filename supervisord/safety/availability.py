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

from supervisord.timebase import NS_PER_MS, NS_PER_S
from supervisord.vocabulary import Reaction

DEFAULT_MIN_REMOTE_BATTERY: Final = 20
"""``vsc.min_remote_battery``: below this battery percent the e-stop counts as not available.
The remote reports its battery in 10 % steps; 20 % leaves the operator time to swap it before
the remote dies and its link drops (which the VSC turns into an e-stop)."""
MIN_REMOTE_BATTERY_RANGE: Final = (0, 100)
"""0 turns the battery check off (a VSC whose remote status is not enabled)."""
REMOTE_STATUS_FRESH_NS: Final = 3500 * NS_PER_MS
"""A battery report this old is no report (SR-8.12). The VSC sends remote status once a second
(manual §8.3.4, once commissioned): two reports in a row lost put the next one 3 s after the
last, and 3.5 s lets that next one also be up to 500 ms late (a busy loop, a noisy serial line)
without a hold or a stop; three lost in a row (4 s) are one, at 3.5 s. The boundary counts as
stale, as at every timeout of the core (a guard ``now - t >= constant``, the form
docs/verification.md's time abstraction needs), except for a report arriving at that very
instant: it is taken in before the old one is judged (:func:`report_stale`)."""
BATTERY_SETTLE_NS: Final = NS_PER_S
"""SR-3.4: the battery's hold or stop condition ends only once the battery has been reported
good in an unbroken run of reports whose first and last are at least this far apart (two
reports at the VSC's 1 Hz), and while it lasts its reason changes at most once per this but
for a report going stale. So the condition ends at most once a second however fast a VSC
reports (20 ms at the fastest)."""


def report_stale(now: int, seen_ns: int, *, arriving: bool = False) -> bool:
    """Whether the battery report of ``seen_ns`` counts as none at ``now`` (SR-8.12): from
    ``REMOTE_STATUS_FRESH_NS`` on; with a new report ``arriving`` at ``now``, only past it. The
    new report is taken in before the old one is judged, so a report exactly at the limit
    refreshes it, while a deadline that passed before it is still judged stale."""
    age = now - seen_ns
    return age > REMOTE_STATUS_FRESH_NS if arriving else age >= REMOTE_STATUS_FRESH_NS


def stale_words() -> str:
    """The reason of a report gone stale (no age in it: details that changed with every step
    would be a change of the cause, recorded at every step, SR-7.1)."""
    return f"the remote's battery has not been reported for {REMOTE_STATUS_FRESH_NS / NS_PER_S:g} s"


def battery_missing(
    now: int, level: int | None, seen_ns: int | None, min_battery: int, *, arriving: bool = False
) -> str | None:
    """What is wrong with the remote's battery at ``now`` (ns), in words, or ``None``.

    ``level`` and ``seen_ns``: the last remote status's battery percent and when it came
    (``None``: none yet); ``min_battery``: ``vsc.min_remote_battery``, 0 for no check;
    ``arriving``: a new report comes at ``now`` and is judged next (:func:`report_stale`).
    """
    if min_battery <= 0:
        return None
    if level is None or seen_ns is None:
        return (
            "the remote's battery is not reported (the VSC sends remote status once "
            "commissioned: srcsctl commission)"
        )
    if report_stale(now, seen_ns, arriving=arriving):
        return stale_words()
    if level < min_battery:
        return f"the remote's battery is {level} %, below {min_battery} %"
    return None


__all__ = [
    "BATTERY_SETTLE_NS",
    "DEFAULT_MIN_REMOTE_BATTERY",
    "MIN_REMOTE_BATTERY_RANGE",
    "REMOTE_STATUS_FRESH_NS",
    "Reaction",
    "battery_missing",
    "report_stale",
    "stale_words",
]
