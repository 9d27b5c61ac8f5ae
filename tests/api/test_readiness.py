"""What ``srcsctl wait-ready`` counts as missing (SR-8.10), from ``status`` replies as the
daemon writes them; the waiting itself runs against the real daemon in
``tests/daemon/test_srcsctl.py``."""

from __future__ import annotations

import dataclasses
from typing import Any

import pytest

from supervisord.api.readiness import (
    BLOCKING_CAUSES,
    OURS_IN_THE_WAY,
    commission_fix,
    for_run,
    for_takeover,
    missing,
    srcsctl_for,
    takeover_said,
)
from supervisord.api.replies import StatusReply
from supervisord.api.status import Cause, ClientStatus, ProofTestStatus, RearmStatus, StateReport
from supervisord.api.views import rearm_status
from supervisord.safety.causes import CauseKind
from supervisord.safety.prooftest import NOT_IN_THE_WAY
from supervisord.vocabulary import Cause as CauseName
from supervisord.vocabulary import Phase, ProofTestPolicy, Severity, State
from tests.api.samples import LOOP, status_reply
from tests.safety.rig import Rig

WORKING_LINK = dataclasses.replace(LOOP.link, open=True, description="serial /dev/srcs-vsc")


def status(
    *active: str, phase: str = "passed", policy: str = "block", state: str = "STOPPED"
) -> StatusReply:
    """A ``status`` reply of a supervisor whose stop path works, but for ``active``."""
    causes = tuple(
        Cause(
            name=CauseName.from_text(name),
            severity=Severity.STOP,
            active=True,
            latched=True,
            raised_ns=1,
            cleared_ns=None,
        )
        for name in active
    )
    report = StateReport(
        state=State[state],
        mono_ns=1,
        causes=causes,
        outputs={},
        heartbeat_estop=1,
        prooftest=ProofTestStatus(policy=ProofTestPolicy(policy), phase=Phase(phase), last=None),
    )
    reply = status_reply(report)
    loop = dataclasses.replace(reply.daemon.loop, link=WORKING_LINK)
    return dataclasses.replace(reply, daemon=dataclasses.replace(reply.daemon, loop=loop))


def latched_only(reply: StatusReply) -> StatusReply:
    """``reply`` with its causes cleared, held by their latches only."""
    causes = tuple(dataclasses.replace(c, active=False) for c in reply.report.causes)
    return dataclasses.replace(reply, report=dataclasses.replace(reply.report, causes=causes))


def test_a_working_stop_path_is_ready_whatever_the_state_and_the_stops() -> None:
    assert missing(status()) == []
    assert missing(status(state="RUN")) == []
    # a pressed e-stop, a held client: the stop path working, not missing
    assert missing(status("vsc_estop", "client_hold:planner", "startup")) == []


@pytest.mark.parametrize(
    "cause",
    [CauseName(k, "drive" if k.has_subject else None) for k in BLOCKING_CAUSES],
    ids=str,
)
def test_each_cause_that_breaks_the_stop_path_is_named(cause: CauseName) -> None:
    """SR-8.10: an active cause that breaks the stop path is named in its words; latched only,
    it is not missing."""
    assert missing(status(cause.name)) == [BLOCKING_CAUSES[cause.kind]]
    assert missing(latched_only(status(cause.name))) == []


@pytest.mark.parametrize("phase", ["waiting", "withholding", "resumed", "failed"])
def test_the_proof_test_must_have_passed(phase: str) -> None:
    assert missing(status(phase=phase)) == [
        f"the proof test of the VSC's watchdog has not passed ({phase})"
    ]


def test_a_config_without_a_proof_test_does_not_wait_for_one() -> None:
    assert missing(status(phase="off", policy="off")) == []


def test_a_closed_link_and_outputs_not_held_are_named() -> None:
    reply = status()
    loop = dataclasses.replace(
        reply.daemon.loop,
        link=dataclasses.replace(WORKING_LINK, open=False),
        outputs_not_acquired=("drive", "brake"),
    )
    reply = dataclasses.replace(reply, daemon=dataclasses.replace(reply.daemon, loop=loop))
    assert missing(reply) == [
        "the link to the VSC is not open (serial /dev/srcs-vsc: no such device)",
        "outputs not held by the supervisor: drive, brake",
    ]


def with_details(reply: StatusReply, name: str, **details: str) -> StatusReply:
    """``reply`` with ``details`` on its cause ``name``."""
    causes = tuple(
        dataclasses.replace(c, details=details) if c.name.name == name else c
        for c in reply.report.causes
    )
    return dataclasses.replace(reply, report=dataclasses.replace(reply.report, causes=causes))


def test_a_missing_required_client_is_no_gap_and_is_named_for_run() -> None:
    """SR-8.15: a required client not there keeps nothing from ready (its service may be
    behind the gate) and is named, by its name and in words, as what RUN still needs."""
    reply = status("client_lost:motion", "client_lost:bridge")
    reply = with_details(reply, "client_lost:motion", reason="never connected")
    reply = with_details(reply, "client_lost:bridge", reason="timeout")
    assert missing(reply) == []
    assert for_run(reply) == [
        "required client `motion` not connected (start its program, as the user its "
        "[[clients]] entry names)",
        "required client `bridge` silent for its timeout",
    ]
    assert for_run(latched_only(reply)) == []


def test_a_waiting_proof_test_says_what_it_waits_for() -> None:
    """SR-8.15, SR-8.10: a proof test that has not started names what it waits for: a stop
    of ours by its name, the VSC's user e-stop bits, never a missing required client."""
    reply = status("local_estop", "client_lost:motion", "vsc_estop", phase="waiting")
    reply = with_details(reply, "vsc_estop", word="0x00000080", sources="user_timeout")
    assert missing(reply) == [
        "the proof test of the VSC's watchdog has not passed (waiting for local_estop to clear "
        "and the VSC's user e-stop bits to clear)"
    ]
    remote = with_details(status("vsc_estop", phase="waiting"), "vsc_estop", word="0x00000001")
    assert missing(remote) == ["the proof test of the VSC's watchdog has not passed (waiting)"]


def test_the_stops_named_in_the_way_are_the_core_s() -> None:
    """SR-8.15: the stops readiness names as keeping the proof test from starting are exactly
    those that set the user heartbeat's byte, less the ones the proof test lets pass."""
    core = {k for k in CauseKind if k.sets_user_estop and k not in NOT_IN_THE_WAY}
    assert core == OURS_IN_THE_WAY


def _rearm(reply: StatusReply, clear_for_s: float | None, in_s: float | None) -> StatusReply:
    return dataclasses.replace(
        reply, rearm=RearmStatus(hold_ms=500, clear_for_s=clear_for_s, accepted_in_s=in_s)
    )


def test_wait_ready_says_when_a_takeover_is_accepted() -> None:
    """SR-8.10, SR-4.1: the ready line says a takeover is accepted now, in the hold's time left,
    or once the active stops clear and stay clear for the hold; a client commanding motion is
    named; in RUN no takeover is needed."""
    clear = latched_only(status("startup"))
    assert takeover_said(_rearm(clear, 0.6, 0.0)) == "; a takeover is accepted now"
    assert for_takeover(_rearm(clear, 0.6, 0.0)) == []
    assert takeover_said(_rearm(clear, 0.251, 0.249)) == (
        "; a takeover is accepted in 0.249 s (the re-arm hold)"
    )
    stopped = _rearm(status("client_lost:nav", "vsc_estop"), None, None)
    assert takeover_said(stopped) == (
        "; a takeover is accepted once: client_lost:nav, vsc_estop to clear and stay clear "
        "for 500 ms (the re-arm hold)"
    )
    moving = ClientStatus(
        name="nav", required=True, connected=True, heartbeat_age_s=0.1, command_nonzero=True
    )
    busy = _rearm(clear, 0.6, 0.0)
    busy = dataclasses.replace(busy, daemon=dataclasses.replace(busy.daemon, clients=(moving,)))
    assert for_takeover(busy) == ["a zero command from nav"]
    assert takeover_said(_rearm(status(state="RUN"), None, 0.0)) == "; RUN: no takeover needed"


def test_rearm_status_follows_the_cores_hold() -> None:
    """SR-4.1, SR-8.10: ``status``'s ``rearm`` from the core's own decision: no time while a
    stop condition is active, then the time clear and the time left of the hold, rounded up to
    the millisecond, 0 from the hold's end on: the instant the core accepts a re-arm."""
    rig = Rig()
    rig.stopped_and_cleared()
    cleared_at = rig.now
    hold_ms = 500
    assert rearm_status(rig.last, rig.now, hold_ms) == RearmStatus(
        hold_ms=hold_ms, clear_for_s=0.0, accepted_in_s=0.5
    )
    rig.advance(250.4)
    assert rearm_status(rig.last, rig.now, hold_ms) == RearmStatus(
        hold_ms=hold_ms, clear_for_s=0.25, accepted_in_s=0.25
    )
    assert rearm_status(rig.last, cleared_at + hold_ms * 1_000_000, hold_ms).accepted_in_s == 0
    rig.estop()
    assert rearm_status(rig.last, rig.now, hold_ms) == RearmStatus(
        hold_ms=hold_ms, clear_for_s=None, accepted_in_s=None
    )


def test_the_watchdog_off_names_the_command_that_commissions_this_robot() -> None:
    """SR-8.18: key 85 read off names ``commission`` with the robot the caller named, and who
    may run it; key 85 not answered yet names nothing to do."""
    how = srcsctl_for(robot="srcsd@robot-a.service")
    read = with_details(status("vsc_watchdog_off"), "vsc_watchdog_off", key85="0")
    (gap,) = missing(read, how)
    assert gap == f"the VSC's key-85 watchdog is off: {commission_fix(how)}"
    assert "srcsctl -R robot-a commission (as root or a member of" in gap
    # Not before the VSC answered: a VSC not heard, or not asked yet, needs no commissioning.
    unread = with_details(status("vsc_watchdog_off"), "vsc_watchdog_off", key85="no answer")
    assert missing(unread, how) == ["the VSC's key-85 watchdog is off"]


@pytest.mark.parametrize(
    ("given", "said"),
    [
        ({"robot": "robot-a"}, "srcsctl -R robot-a"),
        ({"config": "/etc/srcs/robot-b.toml"}, "srcsctl -R robot-b"),
        ({"config": "/home/me/robot c.toml"}, "srcsctl --config '/home/me/robot c.toml'"),
        ({"config": "/etc/srcs/sub/robot.toml"}, "srcsctl --config /etc/srcs/sub/robot.toml"),
        ({"socket": "/run/srcsd/api.sock"}, "srcsctl --socket /run/srcsd/api.sock"),
        ({"demo": True}, "srcsctl --demo"),
        ({}, "srcsctl -R ROBOT"),
    ],
)
def test_the_fix_names_srcsctl_as_the_caller_reached_the_daemon(
    given: dict[str, Any], said: str
) -> None:
    """SR-8.18: a config in /etc/srcs is its robot (``-R``, as srcsd@NAME reads it); any
    other names itself, quoted for a shell."""
    assert srcsctl_for(**given) == said
