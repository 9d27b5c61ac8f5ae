"""What a ``status`` reply says about readiness: whether the stop path works (SR-8.10).

Ready means the stop path works, not that the robot may move: the supervisor answers, the VSC
is heard, its key-85 watchdog is on and proven by a proof test (unless the configuration has no
proof test: CAN, HID, ``vsc.prooftest = "off"``), every output is held by the supervisor and
reads back what it was told, and no internal fault stands. The state is not asked for: a
supervisor that is STOPPED until the operator's takeover is ready, and one already in RUN (a
robot service restarted) is ready too. ``srcsctl wait-ready`` waits for it; the ROS 2 bridge
publishes it on ``ready`` (docs/srcsctl.md "Starting behind the supervisor").
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import Final

from supervisord.api.replies import StatusReply

BLOCKING_CAUSES: Final[Mapping[str, str]] = {
    "vsc_link_lost": "the VSC is not heard",
    "transport_fault": "the link to the VSC has failed",
    "vsc_watchdog_off": "the VSC's key-85 watchdog is off",
    "output_fault": "an output does not read back what it was told",
    "internal": "the supervisor has an internal fault",
}
"""Active causes that mean the stop path does not work, and how each is said."""


def missing(status: StatusReply) -> list[str]:
    """What keeps the supervisor whose ``status`` reply this is from being ready, in words;
    empty when it is ready."""
    gaps: list[str] = []
    link = status.daemon.loop.link
    if not link.open:
        gaps.append(f"the link to the VSC is not open ({link.description})")
    # A cause is named KIND or KIND:WHICH (``output_fault:drive``, docs/safety.md).
    active = {name.split(":")[0] for name in status.report.active()}
    gaps += [text for name, text in BLOCKING_CAUSES.items() if name in active]
    proof = status.report.prooftest
    if proof is not None and proof.policy != "off" and proof.phase != "passed":
        gaps.append(f"the proof test of the VSC's watchdog has not passed ({proof.phase})")
    not_held = status.daemon.loop.outputs_not_acquired
    if not_held:
        gaps.append(f"outputs not held by the supervisor: {', '.join(not_held)}")
    return gaps
