"""Whether the remote e-stop is available (SR-8.11, docs/safety.md "Is the e-stop available?").

An e-stop device that does not work must not pass for one that does (ISO 13850). The remote's
stop button reaches the robot through the VSC: it works while the VSC is heard, a remote is
linked to it, the remote's battery is reported and not low, and the VSC's own key-85 watchdog
is proven. :func:`estop_available` says whether all of that holds, and names what does not, in
words; it is pure (no clock: the caller passes ``now`` from the loop, SR-2.11).

It is a warning, never a stop: the safety core does not read it. docs/safety.md argues why
that is safe: each part's loss is already a stop or blocks a re-arm, or comes ahead of a stop
the VSC itself makes.
"""

from __future__ import annotations

from collections.abc import Iterable
from typing import Final

from supervisord.api.readiness import BLOCKING_CAUSES
from supervisord.api.status import EstopAvailable
from supervisord.protocol.codes import VscMode
from supervisord.protocol.messages import RemoteStatus, VscHeartbeat
from supervisord.safety.core import LINKED_MODES
from supervisord.safety.prooftest import Phase, ProofStatus, ProofTestPolicy
from supervisord.timebase import NS_PER_S

DEFAULT_MIN_REMOTE_BATTERY: Final = 20
"""``vsc.min_remote_battery``: below this battery percent the e-stop counts as not available.
The remote reports its battery in 10 % steps; 20 % leaves the operator time to swap it before
the remote dies and its link drops (which the VSC turns into an e-stop)."""
MIN_REMOTE_BATTERY_RANGE: Final = (0, 100)
"""0 turns the battery check off (a VSC whose remote status is not enabled)."""
REMOTE_STATUS_FRESH_NS: Final = 3 * NS_PER_S
"""A battery report older than this is no report. The VSC sends remote status once a second
(manual §8.3.4, once commissioned): 3 s lets two reports in a row be late or lost (a busy
loop, a noisy serial line) without the condition flapping, yet a VSC that has stopped sending
them is noticed within seconds. The boundary counts as fresh."""
_WATCHDOG_CAUSES: Final = ("transport_fault", "vsc_link_lost", "vsc_watchdog_off")


def estop_available(
    now: int,
    *,
    active: Iterable[str],
    heartbeat: VscHeartbeat | None,
    remote: RemoteStatus | None,
    remote_seen: int | None,
    prooftest: ProofStatus | None,
    min_battery: int,
) -> EstopAvailable:
    """Whether the remote e-stop is available at ``now`` (ns, the loop's clock).

    ``active``: the names of the active causes (``KIND`` or ``KIND:WHICH``); ``heartbeat``: the
    VSC's last heartbeat; ``remote`` and ``remote_seen``: the last remote status and when it
    came; ``prooftest``: the core's proof-test status (``None`` or policy ``off``: the config
    has no proof test, nothing to prove); ``min_battery``: ``vsc.min_remote_battery``, 0 for
    no battery check.
    """
    kinds = {name.split(":")[0] for name in active}
    missing = [BLOCKING_CAUSES[kind] for kind in _WATCHDOG_CAUSES if kind in kinds]
    heard = not kinds & {"transport_fault", "vsc_link_lost"}
    if heartbeat is None:
        missing.append("no heartbeat from the VSC yet")
    elif heard:
        # The mode of a VSC not heard is stale: its not being heard is the reason given.
        mode = VscMode.parse(heartbeat.mode)
        if mode not in LINKED_MODES:
            name = mode.name.lower() if mode is not None else f"0x{heartbeat.mode:02x}"
            missing.append(f"no remote is linked to the VSC (its mode is {name})")
    if min_battery > 0:
        if remote is None or remote_seen is None:
            missing.append(
                "the remote's battery is not reported (the VSC sends remote status once "
                "commissioned: srcsctl commission)"
            )
        elif now - remote_seen > REMOTE_STATUS_FRESH_NS:
            age = (now - remote_seen) / NS_PER_S
            fresh = REMOTE_STATUS_FRESH_NS // NS_PER_S
            missing.append(
                f"the remote's battery was last reported {age:.1f} s ago (more than {fresh} s)"
            )
        elif remote.battery_level < min_battery:
            missing.append(
                f"the remote's battery is {remote.battery_level} %, below {min_battery} %"
            )
    if (
        prooftest is not None
        and prooftest.policy is not ProofTestPolicy.OFF
        and prooftest.phase is not Phase.PASSED
    ):
        missing.append(
            f"the VSC's key-85 watchdog is not proven (proof test {prooftest.phase.value})"
        )
    return EstopAvailable(available=not missing, missing=tuple(missing))
