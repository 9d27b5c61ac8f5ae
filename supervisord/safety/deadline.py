"""The core's next deadline: the earliest time at which one of its machines has something due.

Each machine gives its own next deadline (the link to the VSC, the clients with the record
budget's deferred ends, the outputs' delayed stops, the remote's battery report going stale,
the display's frames and the proof test's limits); :func:`next_deadline` takes the earliest
one still ahead of ``now``, or ``now + IDLE_NS`` when nothing is (SR-2.11, SR-10.1; property P8
of docs/verification.md). Both the full step and the cheap path end with it.
"""

from __future__ import annotations

from typing import Final

from supervisord.safety.battery import RemoteBattery
from supervisord.safety.budget import RecordBudget
from supervisord.safety.clients import Clients
from supervisord.safety.display import DisplayStore
from supervisord.safety.outputs import Outputs
from supervisord.safety.prooftest import ProofTest
from supervisord.safety.vsc import VscLink
from supervisord.timebase import NS_PER_S

IDLE_NS: Final = NS_PER_S  # the longest the core sleeps when nothing else is due


def next_deadline(  # noqa: PLR0917 -- positional: called for every cheap input (SR-9.4)
    now: int,
    vsc: VscLink,
    clients: Clients,
    budget: RecordBudget,
    battery: RemoteBattery,
    outputs: Outputs,
    display: DisplayStore,
    proof: ProofTest,
) -> int:
    """The earliest future time at which something falls due; never ``now`` or earlier."""
    # A deadline already passed has been acted on in this step (an expired timeout stays
    # expired until a new heartbeat), so only future times count.
    earliest = now + IDLE_NS
    later = clients.next_deadline(now, budget)
    if later is not None and later < earliest:
        earliest = later
    later = vsc.next_deadline(now)
    if later is not None and later < earliest:
        earliest = later
    stale = battery.stale_at()
    if stale is not None and now < stale < earliest:  # SR-8.12: the report is too old
        earliest = stale
    later = outputs.next_deadline(now)  # SR-1.4: a category-1 output goes off
    if later is not None and later < earliest:
        earliest = later
    if vsc.open:  # the display's frames and the proof test's limits need the link
        for later in (display.next_due(), proof.next_deadline(vsc.key85)):
            if later is not None and now < later < earliest:
                earliest = later
    return earliest
