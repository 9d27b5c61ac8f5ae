"""The fleet's stop in the safety core (SR-8.19): a stop of its own kind, latched, heard only
from the fleet agent's user, idempotent per stop id, and nothing of it can re-arm or turn an
output on."""

from __future__ import annotations

from dataclasses import replace

from hypothesis import given, settings
from hypothesis import strategies as st

from supervisord.safety import Caller, Decision, RefusalReason, State
from supervisord.safety.config import FleetSpec
from supervisord.safety.events import FleetKeepalive, FleetRelease, FleetStop
from supervisord.safety.fleet import SEEN_MAX
from tests.safety.rig import ROBOT, Rig

AGENT = Caller(uid=998, pid=77, name="srcs-fleet", admin=False)
OTHER = Caller(uid=1000, pid=78, name="robot", admin=False)
FLEET_ROBOT = replace(ROBOT, fleet=FleetSpec(frozenset({AGENT.uid})))


def fleet_stop(
    rig: Rig, stop_id: str = "s-1", sender: str = "console-a", caller: Caller = AGENT
) -> Decision:
    return rig.feed(FleetStop(rig.now, 50, caller, stop_id, sender))


def fleet_release(
    rig: Rig, stop_id: str = "s-1", sender: str = "console-a", caller: Caller = AGENT
) -> Decision:
    return rig.feed(FleetRelease(rig.now, 50, caller, stop_id, sender))


def test_a_fleet_stop_stops_a_running_robot_and_is_recorded_with_its_sender_and_id() -> None:
    """SR-8.19: in RUN a fleet stop is a stop: every output off, ``fleet_stop:SENDER`` raised and
    recorded with the sender and the stop id, the trigger naming both."""
    rig = Rig(FLEET_ROBOT)
    rig.bring_up()
    rig.advance(10)
    decision = fleet_stop(rig)
    assert decision.state is State.STOPPED
    assert not any(decision.outputs.values())
    assert "fleet_stop:console-a" in decision.active_names
    (record,) = decision.records
    cause = next(c for c in record.causes if c.name == "fleet_stop:console-a")
    assert cause.detail("sender") == "console-a"
    assert cause.detail("stop_id") == "s-1"
    assert record.trigger == FleetStop(rig.now, 50, AGENT, "s-1", "console-a")


def test_the_same_stop_id_again_changes_nothing_and_makes_no_record() -> None:
    """SR-8.19: a repeat of a stop id already taken (the agent sends it again after a lost
    reply) is no second record and no refusal."""
    rig = Rig(FLEET_ROBOT)
    rig.bring_up()
    fleet_stop(rig)
    rig.advance(5)
    again = fleet_stop(rig)
    assert again.records == ()
    assert again.refusals == ()
    assert again.state is State.STOPPED


def test_only_the_agents_user_is_heard() -> None:
    """SR-8.19: any other connection is refused, and nothing is raised."""
    rig = Rig(FLEET_ROBOT)
    rig.bring_up()
    decision = fleet_stop(rig, caller=OTHER)
    assert [r.reason for r in decision.refusals] == [RefusalReason.NOT_FLEET_AGENT]
    assert decision.state is State.RUN
    # A robot whose config names no agent hears nobody.
    bare = Rig()
    bare.bring_up()
    assert fleet_stop(bare).refusals[0].reason is RefusalReason.NOT_FLEET_AGENT


def test_text_the_parser_would_refuse_is_refused_by_the_core_too() -> None:
    """The core does not trust the parser: a stop id or sender outside the rule is refused."""
    rig = Rig(FLEET_ROBOT)
    refused = fleet_stop(rig, stop_id="a b")
    assert refused.refusals[0].reason is RefusalReason.BAD_FLEET_TEXT
    assert fleet_stop(rig, sender="x" * 65).refusals[0].reason is RefusalReason.BAD_FLEET_TEXT


def test_the_release_ends_the_condition_and_only_the_takeover_re_arms() -> None:
    """SR-8.19, SR-4: the release ends the condition; the stop stays latched until the
    operator's takeover on the remote, which then re-arms."""
    rig = Rig(FLEET_ROBOT)
    rig.bring_up()
    fleet_stop(rig)
    rig.advance(10)
    released = fleet_release(rig)
    assert released.state is State.STOPPED
    assert "fleet_stop:console-a" not in released.active_names
    assert "fleet_stop:console-a" in released.latched_names
    assert rig.take_over(600).state is State.RUN


def test_a_release_of_another_senders_or_an_unknown_stop_is_refused() -> None:
    """A release must name an active stop of its own sender: anything else is refused and the
    stop stands."""
    rig = Rig(FLEET_ROBOT)
    rig.bring_up()
    fleet_stop(rig)
    wrong = fleet_release(rig, sender="console-b")
    assert wrong.refusals[0].reason is RefusalReason.NOTHING_TO_RELEASE
    assert "fleet_stop:console-a" in wrong.active_names
    assert fleet_release(rig, "s-9").refusals[0].reason is RefusalReason.NOTHING_TO_RELEASE


def test_while_a_fleet_stop_is_active_the_takeover_does_not_re_arm() -> None:
    """SR-4: a takeover while the fleet's stop is still asked for leaves the robot STOPPED."""
    rig = Rig(FLEET_ROBOT)
    rig.bring_up()
    fleet_stop(rig)
    assert rig.take_over(600).state is State.STOPPED


def test_a_repeat_older_than_the_ids_kept_is_a_new_stop() -> None:
    """SR-8.19: the core keeps the last SEEN_MAX ids; an older repeat can only stop again."""
    rig = Rig(FLEET_ROBOT)
    for n in range(SEEN_MAX + 1):
        fleet_stop(rig, f"s-{n}")
        fleet_release(rig, f"s-{n}")
    again = fleet_stop(rig, "s-0")
    assert "fleet_stop:console-a" in again.active_names


_FLEET_INPUTS = st.lists(
    st.tuples(
        st.sampled_from(["stop", "release", "keepalive"]),
        st.sampled_from(["s-1", "s-2"]),
        st.sampled_from(["console-a", "console-b"]),
        st.sampled_from([AGENT, OTHER]),
        st.integers(0, 400),
    ),
    max_size=12,
)


@settings(max_examples=60, deadline=None)
@given(inputs=_FLEET_INPUTS, start_in_run=st.booleans(), required=st.booleans())
def test_no_fleet_input_turns_an_output_on_or_leaves_stopped(
    inputs: list[tuple[str, str, str, Caller, int]], start_in_run: bool, required: bool
) -> None:
    """SR-8.19, SR-8.21: whatever the agent (or anyone) sends, in any order and at any time,
    no output comes on that was off, and no state moves towards RUN."""
    fleet = FleetSpec(frozenset({AGENT.uid}), console_required=required, console_timeout_ms=500)
    rig = Rig(replace(ROBOT, fleet=fleet))
    if start_in_run:
        if required:
            rig.feed(FleetKeepalive(rig.now, 50, AGENT, "console-a"))
        rig.open_link()
        rig.key85(1)
        rig.connect()
        for _ in range(12):
            rig.advance(50)
            rig.vsc(3)
            rig.beat()
            if required:
                rig.feed(FleetKeepalive(rig.now, 50, AGENT, "console-a"))
        rig.advance(50)
        rig.vsc()
        assert rig.state is State.RUN
    for op, stop_id, sender, caller, gap in inputs:
        before = rig.last
        rig.advance(gap)
        if op == "stop":
            after = rig.feed(FleetStop(rig.now, 50, caller, stop_id, sender))
        elif op == "release":
            after = rig.feed(FleetRelease(rig.now, 50, caller, stop_id, sender))
        else:
            after = rig.feed(FleetKeepalive(rig.now, 50, caller, sender))
        for name, on in after.outputs.items():
            assert not on or before.outputs[name], f"{op} turned {name} on"
        assert after.rearm is None
        rank = {State.STOPPED: 0, State.HOLD: 1, State.RUN: 2}
        assert rank[after.state] <= rank[before.state]
