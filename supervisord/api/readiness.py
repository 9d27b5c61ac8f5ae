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

Each part missing names what fixes it (SR-8.18): the VSC's watchdog off, the command that
commissions it (``srcsctl -R ROBOT commission``, with the way this ``srcsctl`` reached the
daemon: :func:`srcsctl_for`); the link not open, why it last failed (a device the daemon may
not open names its group and ``usermod -aG``, :mod:`supervisord.links.base`); a required client
not there, the program to start.

Ready is not *re-armable*: a takeover is accepted only once every stop condition has been clear
for ``rearm.hold_ms`` (SR-4.1), so one right after ready may still be refused. When it will be
accepted is said too (:func:`takeover_said`), and ``wait-ready --rearmable`` waits for it
(:func:`for_takeover`, SR-8.10).
"""

from __future__ import annotations

import shlex
from collections.abc import Mapping
from pathlib import PurePosixPath
from typing import Final

from supervisord.api.replies import StatusReply
from supervisord.vocabulary import (
    PROOFTEST_BLOCKERS,
    STOP_PATH_CAUSES,
    CauseKind,
    Phase,
    Severity,
    State,
)

BLOCKING_CAUSES: Final[Mapping[CauseKind, str]] = STOP_PATH_CAUSES
"""Active causes that mean the stop path does not work, and how each is said."""
OURS_IN_THE_WAY: Final = PROOFTEST_BLOCKERS
"""The stop causes that keep a proof test from starting: those that set the user heartbeat's
byte, ``client_lost`` aside (SR-8.15), as the shared vocabulary derives them from the cause
kinds (the bridge imports this module without the safety core)."""
USER_BITS: Final = 0xC0
"""Bits 6-7 of the VSC's e-stop word: the user e-stop, which must clear before the test."""

_CLIENT_REASONS: Final[Mapping[str, str]] = {
    "never connected": "not connected",
    "disconnected": "not connected",
    "no heartbeat since hello": "connected, no heartbeat yet",
    "timeout": "silent for its timeout",
    "stale progress": "beating without new progress (SR-8.16)",
    "heartbeat without progress": "beating without a progress value (SR-8.16)",
}


CONFIG_DIR: Final = "/etc/srcs"
"""Where ``srcsd@NAME`` reads ``NAME.toml`` (docs/install.md): a config there is ``-R NAME``."""
DEFAULT_SRCSCTL: Final = "srcsctl -R ROBOT"
"""How a text names the command when it does not know how the daemon is reached."""


def srcsctl_for(
    *,
    robot: str | None = None,
    config: str | None = None,
    socket: str | None = None,
    demo: bool = False,
) -> str:
    """The ``srcsctl`` command line that reaches this daemon, to name in a fix: ``-R NAME``
    for a robot (or a config in /etc/srcs), else ``--config FILE``, ``--socket PATH``,
    ``--demo``; the placeholder ``-R ROBOT`` when none is known."""
    if robot:
        return f"srcsctl -R {robot.removeprefix('srcsd@').removesuffix('.service')}"
    if demo:
        return "srcsctl --demo"
    if config:
        path = PurePosixPath(config)
        if str(path.parent) == CONFIG_DIR and path.suffix == ".toml" and _plain(path.stem):
            return f"srcsctl -R {path.stem}"
        return f"srcsctl --config {shlex.quote(config)}"
    if socket:
        return f"srcsctl --socket {shlex.quote(socket)}"
    return DEFAULT_SRCSCTL


def _plain(name: str) -> bool:
    return bool(name) and shlex.quote(name) == name and not name.startswith("-")


def commission_fix(srcsctl: str = DEFAULT_SRCSCTL) -> str:
    """What turns the VSC's key-85 watchdog on: commissioning it, once per VSC (SR-8.18)."""
    return (
        f"commission the VSC once: {srcsctl} commission "
        "(as root or a member of the config's api.admin_group, srcs-admin as installed)"
    )


def key85_read_off(status: StatusReply) -> bool:
    """Whether the VSC answered key 85 with a value other than 1: its watchdog is off and
    commissioning is the fix. Not before it answered (``key85 = "no answer"``): a VSC not
    heard yet, or heard and not asked yet, is no reason to commission (SR-8.18)."""
    for cause in status.report.causes:
        if cause.active and cause.kind is CauseKind.VSC_WATCHDOG_OFF:
            return cause.details.get("key85", NO_ANSWER) != NO_ANSWER
    return False


NO_ANSWER: Final = "no answer"
"""``vsc_watchdog_off``'s ``key85`` detail before the VSC answered."""


def missing(status: StatusReply, srcsctl: str = DEFAULT_SRCSCTL) -> list[str]:
    """What keeps the supervisor whose ``status`` reply this is from being ready, in words,
    each with what fixes it (SR-8.18; ``srcsctl``: how the fix names the command, as
    :func:`srcsctl_for` says); empty when it is ready."""
    gaps: list[str] = []
    link = status.daemon.loop.link
    if not link.open:
        why = f": {link.last_error}" if link.last_error else ""
        gaps.append(f"the link to the VSC is not open ({link.description}{why})")
    active = status.report.active_kinds()
    read_off = key85_read_off(status)
    gaps += [
        f"{text}: {commission_fix(srcsctl)}"
        if kind is CauseKind.VSC_WATCHDOG_OFF and read_off
        else text
        for kind, text in BLOCKING_CAUSES.items()
        if kind in active
    ]
    proof = status.report.prooftest
    if proof is not None and not proof.proven:
        waits = _proof_waits_for(status) if proof.phase is Phase.WAITING else []
        why = f"waiting for {' and '.join(waits)}" if waits else proof.phase.value
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
        if cause.active and cause.kind is CauseKind.CLIENT_LOST:
            how = _CLIENT_REASONS.get(cause.details.get("reason", ""), "lost")
            said.append(f"required client `{cause.name.subject}` {how}{_client_fix(how)}")
    return said


def _client_fix(how: str) -> str:
    """What brings a required client back (SR-8.18): the program that says hello under its
    name, started as the user its ``[[clients]]`` entry binds it to."""
    if how == "not connected":
        return " (start its program, as the user its [[clients]] entry names)"
    return ""


def for_takeover(status: StatusReply) -> list[str]:
    """What keeps a takeover from being accepted now, in words; empty when one would be (the
    operator's act on the remote aside, SR-4.5). Read from ``status``'s ``rearm`` (the re-arm
    hold) and its causes: every stop condition clear, clear for ``rearm.hold_ms``, and no
    client declaring a non-zero command (SR-4.6)."""
    if status.report.state is not State.STOPPED:
        return []  # nothing to re-arm: a takeover only leaves the remote's pause (SR-3)
    waits: list[str] = []
    stops = sorted(
        c.name.name for c in status.report.causes if c.active and c.severity is Severity.STOP
    )
    rearm = status.rearm
    hold = "" if rearm is None else f" and stay clear for {rearm.hold_ms} ms"
    if stops:
        waits.append(f"{', '.join(stops)} to clear{hold} (the re-arm hold)")
    elif rearm is None:
        waits.append("a supervisor that says when its re-arm hold ends (update srcsd)")
    elif rearm.accepted_in_s is None or rearm.accepted_in_s > 0:
        left = "" if rearm.accepted_in_s is None else f" {rearm.accepted_in_s:g} s more"
        waits.append(
            f"the stop conditions to stay clear{left} (the re-arm hold, {rearm.hold_ms} ms)"
        )
    nonzero = sorted(c.name for c in status.daemon.clients if c.command_nonzero)
    if nonzero:
        waits.append(f"a zero command from {', '.join(nonzero)}")
    return waits


def takeover_said(status: StatusReply) -> str:
    """When a takeover will be accepted, in words, as a tail of ``wait-ready``'s line."""
    if status.report.state is not State.STOPPED:
        return f"; {status.report.state.name}: no takeover needed"
    waits = for_takeover(status)
    if not waits:
        return "; a takeover is accepted now"
    rearm = status.rearm
    stops = any(c.active and c.severity is Severity.STOP for c in status.report.causes)
    if len(waits) == 1 and rearm is not None and rearm.accepted_in_s and not stops:
        return f"; a takeover is accepted in {rearm.accepted_in_s:g} s (the re-arm hold)"
    return f"; a takeover is accepted once: {'; '.join(waits)}"


def _proof_waits_for(status: StatusReply) -> list[str]:
    """Why a proof test that has not started waits, in words (docs/safety.md "The proof
    test", 2): nothing of ours asking the VSC to stop, its user bits clear, STOPPED."""
    active = [c for c in status.report.causes if c.active]
    kinds = {c.kind for c in active}
    waits = []
    if not status.daemon.loop.link.open or kinds & _NOT_HEARD:
        waits.append("the VSC to be heard")
    if CauseKind.VSC_WATCHDOG_OFF in kinds:
        waits.append("key 85 to read 1")
    ours = sorted(c.name.name for c in active if c.kind in OURS_IN_THE_WAY - _SAID_APART)
    if ours:
        waits.append(f"{', '.join(ours)} to clear")
    estop = next((c for c in active if c.kind is CauseKind.VSC_ESTOP), None)
    if estop is not None and _word(estop.details.get("word", "")) & USER_BITS:
        waits.append("the VSC's user e-stop bits to clear")
    if status.report.state is not State.STOPPED:
        waits.append("the supervisor to be STOPPED")
    return waits


_NOT_HEARD: Final = frozenset({CauseKind.VSC_LINK_LOST, CauseKind.TRANSPORT_FAULT})
_SAID_APART: Final = _NOT_HEARD | {CauseKind.VSC_WATCHDOG_OFF}


def _word(text: str) -> int:
    """The e-stop word of a ``vsc_estop`` cause's details (``0x00000080``); 0 if unreadable."""
    try:
        return int(text, 16) if text.isascii() else 0
    except ValueError:
        return 0
