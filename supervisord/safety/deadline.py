"""The core's next deadline: the earliest time at which one of its machines has something due.

Each machine gives its own next deadline through its face (``face.Machine.next_deadline``: the
link to the VSC, the clients with the record budget's deferred ends, the outputs' delayed
stops, the remote's battery report going stale, the display's frames and the proof test's
limits); :func:`next_deadline` takes the earliest, or ``now + IDLE_NS`` when none is ahead
(SR-2.11, SR-10.1; property P8 of docs/verification.md). Both the full step and the cheap path
end with it.
"""

from __future__ import annotations

from typing import Final

from supervisord.safety.view import View
from supervisord.timebase import NS_PER_S

IDLE_NS: Final = NS_PER_S  # the longest the core sleeps when nothing else is due


def next_deadline(view: View) -> int:
    """The earliest future time at which something falls due; never ``view.now`` or earlier."""
    # A deadline already passed has been acted on in this step (an expired timeout stays
    # expired until a new heartbeat), so each machine gives only future times.
    earliest = view.now + IDLE_NS
    for machine in view.machines:
        later = machine.next_deadline(view)
        if later is not None and later < earliest:
            earliest = later
    return earliest
