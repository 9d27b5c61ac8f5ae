"""The remote's battery as the e-stop's availability (SR-8.12): under
``vsc.on_estop_unavailable`` a battery below ``vsc.min_remote_battery``, or not reported for
3.5 s or more, is a warning only, holds the robot, or stops it. Time is the rig's own."""

from __future__ import annotations

import dataclasses

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from supervisord.protocol.messages import Joystick, RemoteStatus, UserHeartbeat
from supervisord.safety import SafetyConfig, State, Transport
from supervisord.safety.availability import (
    BATTERY_SETTLE_NS,
    REMOTE_STATUS_FRESH_NS,
    Reaction,
    battery_missing,
)
from supervisord.safety.deadline import IDLE_NS
from tests.safety.rig import MS, OPERATIONAL, ROBOT, Rig

HOLD = dataclasses.replace(ROBOT, on_estop_unavailable=Reaction.HOLD)
STOP = dataclasses.replace(ROBOT, on_estop_unavailable=Reaction.STOP)


def running(config: SafetyConfig, battery: int = 80) -> Rig:
    """RUN with the remote reporting ``battery`` percent twice, a second apart, before the
    takeover (SR-3.4: a run of good reports at least 1 s long)."""
    rig = Rig(config)
    rig.open_link()
    rig.key85(1)
    rig.connect()
    rig.from_vsc(RemoteStatus(battery))
    rig.run_for(BATTERY_SETTLE_NS // MS)
    rig.from_vsc(RemoteStatus(battery))
    decision = rig.take_over(600)
    assert decision.state is State.RUN, decision.causes
    return rig


def reported_until_stale(rig: Rig) -> int:
    """A good report now, then the VSC and the client beating every 50 ms up to the last step
    before the report turns 3.5 s old; the time of the report."""
    rig.from_vsc(RemoteStatus(80))
    seen = rig.now
    while rig.now + 50 * MS < seen + REMOTE_STATUS_FRESH_NS:
        rig.advance(50)
        rig.vsc()
        rig.beat()
    return seen


def active(rig: Rig) -> set[str]:
    return {c.name for c in rig.last.causes if c.active}


def test_a_low_battery_is_only_a_warning_by_default() -> None:
    """``warn`` (the default): the core does not read the battery; RUN stays RUN."""
    rig = running(ROBOT)
    rig.advance(10)
    rig.from_vsc(RemoteStatus(10))
    assert rig.state is State.RUN
    assert rig.run_for(REMOTE_STATUS_FRESH_NS * 3 // MS, OPERATIONAL).state is State.RUN


def test_a_low_battery_holds_and_a_good_one_runs_again() -> None:
    """``hold``: 10 % (below 20) holds with ``estop_unavailable_hold`` naming it; motion off,
    power on; reports of 80 % end the hold once they have run unbroken for 1 s (SR-3.4)."""
    rig = running(HOLD)
    rig.advance(10)
    decision = rig.from_vsc(RemoteStatus(10))
    assert decision.state is State.HOLD
    (cause,) = [c for c in decision.causes if c.active]
    assert cause.name == "estop_unavailable_hold"
    assert cause.detail("reason") == "the remote's battery is 10 %, below 20 %"
    assert decision.outputs == {"drive": False, "lights": True}
    rig.advance(10)
    assert rig.from_vsc(RemoteStatus(80)).state is State.HOLD
    rig.run_for(BATTERY_SETTLE_NS // MS - 10, OPERATIONAL, step_ms=10)
    assert rig.from_vsc(RemoteStatus(80)).state is State.HOLD
    rig.advance(10)
    assert rig.from_vsc(RemoteStatus(80)).state is State.RUN


def test_a_low_battery_stops_latches_and_sets_the_heartbeat_byte() -> None:
    """``stop``: STOPPED in the same step with ``estop_unavailable``, every output off and the
    user heartbeat's e-stop byte set (SR-5.2); a good report clears the condition but only a
    takeover re-arms (SR-4)."""
    rig = running(STOP)
    rig.advance(10)
    decision = rig.from_vsc(RemoteStatus(19))
    assert decision.state is State.STOPPED
    assert active(rig) == {"estop_unavailable"}
    assert not any(decision.outputs.values())
    assert decision.heartbeat_estop == 1
    rig.advance(10)
    rig.from_vsc(RemoteStatus(20))  # the minimum itself counts as enough
    rig.run_for(BATTERY_SETTLE_NS // MS, OPERATIONAL)
    rig.from_vsc(RemoteStatus(20))  # and the run is 1 s long (SR-3.4)
    rig.run_for(600, OPERATIONAL)
    assert rig.state is State.STOPPED
    assert active(rig) == set()
    assert rig.take_over(600).state is State.RUN


def test_a_report_as_old_as_the_limit_holds_at_that_nanosecond() -> None:
    """SR-8.12: the last report counts while younger than 3.5 s; the core's deadline is the
    nanosecond it turns 3.5 s old, and a tick there holds (heartbeats and the client keep
    coming meanwhile)."""
    rig = running(HOLD)
    rig.advance(10)
    seen = reported_until_stale(rig)
    assert rig.state is State.RUN
    assert rig.last.next_deadline <= seen + REMOTE_STATUS_FRESH_NS
    rig.now = seen + REMOTE_STATUS_FRESH_NS - 1
    assert rig.tick().state is State.RUN
    rig.now += 1
    decision = rig.tick()
    assert decision.state is State.HOLD
    (cause,) = [c for c in decision.causes if c.active]
    assert cause.detail("reason") == "the remote's battery has not been reported for 3.5 s"
    since = len(rig.decisions)
    rig.run_for(500, OPERATIONAL)  # the same words as time goes on: nothing new to record
    assert [d.records for d in rig.decisions[since:] if d.records] == []


def test_no_report_at_all_keeps_a_takeover_from_running() -> None:
    """``hold`` with no remote status yet (a VSC not commissioned): a takeover reaches HOLD,
    not RUN, until the first good report."""
    rig = Rig(HOLD)
    rig.open_link()
    rig.key85(1)
    rig.connect()
    decision = rig.take_over(600)
    assert decision.state is State.HOLD
    assert active(rig) == {"estop_unavailable_hold"}
    rig.advance(10)
    assert rig.from_vsc(RemoteStatus(90)).state is State.HOLD
    rig.run_for(BATTERY_SETTLE_NS // MS, OPERATIONAL)
    assert rig.from_vsc(RemoteStatus(90)).state is State.RUN


def test_a_minimum_of_zero_watches_nothing() -> None:
    """``min_remote_battery = 0`` turns the check off, whatever the reaction."""
    rig = running(dataclasses.replace(STOP, min_remote_battery=0), battery=0)
    assert rig.run_for(REMOTE_STATUS_FRESH_NS * 2 // MS, OPERATIONAL).state is State.RUN


@settings(max_examples=60, deadline=None)
@given(
    reaction=st.sampled_from([Reaction.HOLD, Reaction.STOP]),
    reports=st.lists(st.tuples(st.integers(20, 600), st.integers(0, 100)), min_size=1, max_size=12),
    minimum=st.integers(1, 100),
)
def test_the_cause_is_active_exactly_until_a_second_of_good_reports(
    reaction: Reaction, reports: list[tuple[int, int]], minimum: int
) -> None:
    """SR-8.12, SR-3.4: for any sequence of fresh reports, the cause is active from the start
    and after every report below the minimum, until a report at or above it that is at least
    1 s after the first of the good reports since."""
    config = dataclasses.replace(ROBOT, on_estop_unavailable=reaction, min_remote_battery=minimum)
    rig = Rig(config)
    rig.open_link()
    name = "estop_unavailable_hold" if reaction is Reaction.HOLD else "estop_unavailable"
    held, good_since = True, None
    for gap_ms, level in reports:
        rig.advance(gap_ms)
        rig.vsc()
        rig.from_vsc(RemoteStatus(level))
        if level < minimum:
            held, good_since = True, None
        elif held:
            good_since = rig.now if good_since is None else good_since
            held = rig.now - good_since < BATTERY_SETTLE_NS
        assert (name in active(rig)) == held


@pytest.mark.parametrize("reaction", [Reaction.HOLD, Reaction.STOP])
def test_remote_status_is_not_cheap_when_watched(reaction: Reaction) -> None:
    """A remote status takes the full step when the core reacts to the battery: the same
    decisions with the cheap path off (SR-9.4)."""
    config = dataclasses.replace(ROBOT, on_estop_unavailable=reaction)
    rigs = [running(config), running(config)]
    rigs[1].core.cheap_path = False
    for rig in rigs:
        for level in (80, 80, 10, 10, 90):
            rig.advance(20)
            rig.vsc()
            rig.beat()
            rig.from_vsc(RemoteStatus(level))
    assert [d.state for d in rigs[0].decisions] == [d.state for d in rigs[1].decisions]
    assert rigs[0].last.causes == rigs[1].last.causes


def test_a_heartbeat_due_with_the_report_going_stale_takes_the_full_step() -> None:
    """The report goes stale at the very instant a user heartbeat is due, and a VSC heartbeat
    arrives then: the step holds (the cheap path, which would only send the heartbeat,
    declines at the report's deadline)."""
    rig = running(HOLD)
    while not any(isinstance(f, UserHeartbeat) for f in rig.last.frames):
        rig.advance(10)  # to an instant at which a user heartbeat is due, and sent
        rig.vsc()
    seen = reported_until_stale(rig)
    rig.now = seen + REMOTE_STATUS_FRESH_NS
    decision = rig.vsc()
    assert any(isinstance(f, UserHeartbeat) for f in decision.frames)  # the heartbeat was due
    assert decision.state is State.HOLD


@pytest.mark.parametrize("reaction", list(Reaction))
def test_an_inert_message_is_cheap_and_a_remote_status_only_when_not_watched(
    reaction: Reaction,
) -> None:
    """In a steady RUN a joystick frame takes the cheap path whatever the reaction; a remote
    status does under ``warn``, and takes the full step when the core reacts to it (SR-9.4)."""
    rig = running(dataclasses.replace(ROBOT, on_estop_unavailable=reaction))
    refreshes = rig.count_refreshes()
    rig.advance(1)
    rig.from_vsc(Joystick())
    assert refreshes == []
    rig.advance(1)
    rig.from_vsc(RemoteStatus(80))
    assert (refreshes == []) is (reaction is Reaction.WARN)


def test_a_minimum_of_zero_sets_no_deadline_for_the_report() -> None:
    """With ``min_remote_battery = 0`` no report is watched, so none has a deadline: on CAN
    (no user heartbeat) with the VSC silent, the core sleeps its whole idle second right up to
    and past the instant a watched report would have gone stale."""
    config = dataclasses.replace(
        STOP, transport=Transport.CAN, require_watchdog=False, clients=(), min_remote_battery=0
    )
    rig = Rig(config)
    rig.open_link()
    rig.from_vsc(RemoteStatus(80))
    seen = rig.now
    rig.now = seen + REMOTE_STATUS_FRESH_NS - 500 * MS
    decision = rig.tick()
    assert decision.next_deadline == decision.now + IDLE_NS


def test_the_rule_checks_nothing_at_a_minimum_of_zero_and_names_a_missing_report() -> None:
    """``battery_missing``, the one rule of the core and of ``status``: a minimum of 0 checks
    nothing, whatever was reported; a report of which either half is missing is no report."""
    assert battery_missing(0, None, None, 0) is None
    assert battery_missing(REMOTE_STATUS_FRESH_NS * 9, 0, 0, 0) is None
    for level, seen in ((None, None), (50, None), (None, 0)):
        assert (battery_missing(0, level, seen, 20) or "").startswith(
            "the remote's battery is not reported"
        )
