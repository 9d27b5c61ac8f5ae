"""Whether the remote e-stop is available (SR-8.11, docs/safety.md "Is the e-stop available?").

An e-stop device that does not work must not pass for one that does (ISO 13850). The remote's
stop button reaches the robot through the VSC: it works while the VSC is heard, a remote is
linked to it, the remote's battery is reported and not low, and the VSC's own key-85 watchdog
is proven. :func:`estop_available` says whether all of that holds, and names what does not, in
words; it is pure (no clock: the caller passes ``now`` from the loop, SR-2.11).

What the supervisor does when it is lost is the core's: each part's loss is a stop of its own
or blocks a re-arm, but for the remote's battery, whose judgement (one rule,
:func:`~supervisord.safety.availability.battery_missing`) the core reacts to as
``vsc.on_estop_unavailable`` says (SR-8.12, docs/safety.md "Is the e-stop available?").
"""

from __future__ import annotations

from collections.abc import Iterable
from typing import Final

from supervisord.api.status import EstopAvailable
from supervisord.protocol.codes import VscMode
from supervisord.protocol.messages import RemoteStatus, VscHeartbeat
from supervisord.safety.availability import battery_missing
from supervisord.safety.core import LINKED_MODES
from supervisord.safety.prooftest import Phase, ProofStatus, ProofTestPolicy
from supervisord.vocabulary import STOP_PATH_CAUSES, Cause, CauseKind

_WATCHDOG_CAUSES: Final = (
    CauseKind.TRANSPORT_FAULT,
    CauseKind.VSC_LINK_LOST,
    CauseKind.VSC_WATCHDOG_OFF,
)


def estop_available(
    now: int,
    *,
    active: Iterable[Cause],
    heartbeat: VscHeartbeat | None,
    remote: RemoteStatus | None,
    remote_seen: int | None,
    prooftest: ProofStatus | None,
    min_battery: int,
) -> EstopAvailable:
    """Whether the remote e-stop is available at ``now`` (ns, the loop's clock).

    ``active``: the active causes; ``heartbeat``: the
    VSC's last heartbeat; ``remote`` and ``remote_seen``: the last remote status and when it
    came; ``prooftest``: the core's proof-test status (``None`` or policy ``off``: the config
    has no proof test, nothing to prove); ``min_battery``: ``vsc.min_remote_battery``, 0 for
    no battery check.
    """
    kinds = {cause.kind for cause in active}
    missing = [STOP_PATH_CAUSES[kind] for kind in _WATCHDOG_CAUSES if kind in kinds]
    heard = not kinds & {CauseKind.TRANSPORT_FAULT, CauseKind.VSC_LINK_LOST}
    if heartbeat is None:
        missing.append("no heartbeat from the VSC yet")
    elif heard:
        # The mode of a VSC not heard is stale: its not being heard is the reason given.
        mode = VscMode.parse(heartbeat.mode)
        if mode not in LINKED_MODES:
            name = mode.name.lower() if mode is not None else f"0x{heartbeat.mode:02x}"
            missing.append(f"no remote is linked to the VSC (its mode is {name})")
    level = None if remote is None else remote.battery_level
    battery = battery_missing(now, level, remote_seen, min_battery)
    if battery is not None:
        missing.append(battery)
    if (
        prooftest is not None
        and prooftest.policy is not ProofTestPolicy.OFF
        and prooftest.phase is not Phase.PASSED
    ):
        missing.append(
            f"the VSC's key-85 watchdog is not proven (proof test {prooftest.phase.value})"
        )
    return EstopAvailable(available=not missing, missing=tuple(missing))
