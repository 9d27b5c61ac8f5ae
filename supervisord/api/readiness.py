"""What a ``status`` reply says about readiness: whether the stop path works (SR-8.10).

Ready means the stop path works, not that the robot may move: the supervisor answers, the VSC
is heard, its key-85 watchdog is on and proven by a proof test (unless the configuration has no
proof test: CAN, HID, ``vsc.prooftest = "off"``), every output is held by the supervisor and
reads back what it was told, and no internal fault stands. The state is not asked for: a
supervisor that is STOPPED until the operator's takeover is ready, and one already in RUN (a
robot service restarted) is ready too. ``srcsctl wait-ready`` waits for it; the ROS 2 bridge
publishes it on ``ready`` (docs/srcsctl.md "Starting behind the supervisor").

A required client is not part of it (SR-8.15): its own service may start behind the gate, and
the proof test runs without it. What it still keeps from RUN is said apart (:func:`for_run`).
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

OURS_IN_THE_WAY: Final = frozenset(
    {"transport_fault", "vsc_link_lost", "client_estop", "local_estop", "output_fault"}
    | {"vsc_watchdog_off", "internal", "estop_unavailable", "shutdown"}
)
"""The stop causes that keep a proof test from starting: those that set the user heartbeat's
byte, ``client_lost`` aside (SR-8.15). Written out here, since the ROS 2 bridge imports this
module without the safety core; ``tests/api/test_readiness.py`` holds it to the core's rule."""
USER_BITS: Final = 0xC0
"""Bits 6-7 of the VSC's e-stop word: the user e-stop, which must clear before the test."""

_CLIENT_REASONS: Final[Mapping[str, str]] = {
    "never connected": "not connected",
    "disconnected": "not connected",
    "no heartbeat since hello": "connected, no heartbeat yet",
    "timeout": "silent for its timeout",
}


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
        waits = _proof_waits_for(status) if proof.phase == "waiting" else []
        why = f"waiting for {' and '.join(waits)}" if waits else proof.phase
        gaps.append(f"the proof test of the VSC's watchdog has not passed ({why})")
    not_held = status.daemon.loop.outputs_not_acquired
    if not_held:
        gaps.append(f"outputs not held by the supervisor: {', '.join(not_held)}")
    return gaps


def for_run(status: StatusReply) -> list[str]:
    """What a ready supervisor still misses before RUN that its gate does not wait for, in
    words: each required client not there, by its name (SR-8.15)."""
    said = []
    for cause in status.report.causes:
        kind, _, name = cause.name.partition(":")
        if cause.active and kind == "client_lost":
            how = _CLIENT_REASONS.get(cause.details.get("reason", ""), "lost")
            said.append(f"required client `{name}` {how}")
    return said


def _proof_waits_for(status: StatusReply) -> list[str]:
    """Why a proof test that has not started waits, in words (docs/safety.md "The proof
    test", 2): nothing of ours asking the VSC to stop, its user bits clear, STOPPED."""
    active = {c.name: c for c in status.report.causes if c.active}
    kinds = {name.split(":")[0] for name in active}
    waits = []
    if not status.daemon.loop.link.open or kinds & {"vsc_link_lost", "transport_fault"}:
        waits.append("the VSC to be heard")
    if "vsc_watchdog_off" in kinds:
        waits.append("key 85 to read 1")
    ours = sorted(n for n in active if n.split(":")[0] in OURS_IN_THE_WAY - _SAID_APART)
    if ours:
        waits.append(f"{', '.join(ours)} to clear")
    estop = active.get("vsc_estop")
    if estop is not None and _word(estop.details.get("word", "")) & USER_BITS:
        waits.append("the VSC's user e-stop bits to clear")
    if status.report.state != "STOPPED":
        waits.append("the supervisor to be STOPPED")
    return waits


_SAID_APART: Final = frozenset({"vsc_link_lost", "transport_fault", "vsc_watchdog_off"})


def _word(text: str) -> int:
    """The e-stop word of a ``vsc_estop`` cause's details (``0x00000080``); 0 if unreadable."""
    try:
        return int(text, 16) if text.isascii() else 0
    except ValueError:
        return 0
