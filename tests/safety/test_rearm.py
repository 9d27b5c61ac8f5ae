"""Re-arming after a stop (SR-4): every path, and every reason for a refusal."""

from __future__ import annotations

import dataclasses

from supervisord.safety import (
    Commissioned,
    InternalFault,
    LinkOpened,
    RearmKind,
    RecordNote,
    RefusalReason,
    State,
)
from tests.safety.rig import ADMIN, LOCAL, NOBODY, OPERATIONAL, ROBOT, Rig

LOCAL_RESET = dataclasses.replace(ROBOT, local_reset=True)


def test_takeover_rearms_after_the_hold_time() -> None:
    """A takeover (Local then Operational) given after the conditions were clear for the whole
    hold time ends STOPPED, and the record names the takeover."""
    rig = Rig()
    rig.stopped_and_cleared()
    decision = rig.take_over(500)
    assert decision.state is State.RUN
    (record,) = decision.records
    assert record.rearm is not None
    assert record.rearm.kind is RearmKind.TAKEOVER
    assert record.previous is State.STOPPED


def test_takeover_at_exactly_the_hold_time_counts() -> None:
    """Clear for exactly ``rearm_hold`` (500 ms) is enough; 499 ms is not."""
    early = Rig()
    early.stopped_and_cleared()
    early.run_for(450, LOCAL)
    early.advance(49)
    refused = early.vsc(OPERATIONAL)
    assert refused.state is State.STOPPED
    assert [r.reason for r in refused.refusals] == [RefusalReason.HOLD_TIME_NOT_ELAPSED]
    assert "clear for 499 ms of 500 ms" in refused.refusals[0].message

    exact = Rig()
    exact.stopped_and_cleared()
    assert exact.take_over(450).state is State.RUN


def test_refused_takeover_can_be_repeated_later() -> None:
    """After a too-early takeover the operator goes back to Local and takes over again."""
    rig = Rig()
    rig.stopped_and_cleared()
    # Local for the takeover dwell (rule 4), but before the hold
    assert [r.reason for r in rig.take_over(250).refusals] == [RefusalReason.HOLD_TIME_NOT_ELAPSED]
    rig.run_for(600, OPERATIONAL)
    assert rig.state is State.STOPPED  # staying in Operational is no new takeover
    assert rig.take_over(250).state is State.RUN


def test_no_takeover_after_the_stop_keeps_stopped() -> None:
    """A takeover made before the stop does not count: with the VSC staying Operational the
    supervisor stays STOPPED however long the conditions are clear."""
    rig = Rig()
    rig.bring_up()
    rig.advance(10)
    rig.estop()
    rig.advance(10)
    rig.release()
    final = rig.run_for(3000, OPERATIONAL)
    assert final.state is State.STOPPED
    assert final.latched_names == {"client_estop:planner"}


def test_takeover_while_a_condition_is_active_is_refused_and_does_not_count() -> None:
    """Safe choice: a re-arm given while a stop condition is still active is refused and is not
    remembered for when the condition clears."""
    rig = Rig()
    rig.bring_up()
    rig.advance(10)
    rig.estop()
    refused = rig.take_over(600)
    assert refused.state is State.STOPPED
    assert [r.reason for r in refused.refusals] == [RefusalReason.CONDITIONS_ACTIVE]
    assert "client_estop:planner" in refused.refusals[0].detail
    rig.advance(10)
    rig.release()
    assert rig.run_for(2000, OPERATIONAL).state is State.STOPPED


def test_new_cause_during_the_takeover_aborts_it() -> None:
    """SR-4.3: a stop cause raised between the Local heartbeat and the Operational one aborts the
    takeover, even if the cause is momentary."""
    rig = Rig()
    rig.stopped_and_cleared()
    rig.run_for(1000, LOCAL)
    rig.advance(10)
    rig.feed(InternalFault(rig.now, "overrun"))
    rig.advance(10)
    refused = rig.vsc(OPERATIONAL)
    assert refused.state is State.STOPPED
    assert [r.reason for r in refused.refusals] == [RefusalReason.NEW_CAUSE_DURING_REARM]


def test_local_reset_rearms_when_allowed_and_admin() -> None:
    """``srcsctl reset`` by an admin re-arms when the config allows it; with the VSC still in
    Local the state becomes HOLD, and RUN follows when the operator goes Operational."""
    rig = Rig(LOCAL_RESET)
    rig.stopped_and_cleared()
    rig.run_for(500, LOCAL)
    decision = rig.reset()
    assert decision.state is State.HOLD
    assert decision.rearm is not None
    assert decision.rearm.kind is RearmKind.LOCAL_RESET
    assert decision.rearm.caller is not None
    assert decision.rearm.caller.name == "alice"
    rig.advance(50)
    assert rig.vsc(OPERATIONAL).state is State.RUN


def test_local_reset_goes_straight_to_run_when_nothing_holds() -> None:
    """A local reset while the VSC is Operational and nothing holds goes to RUN."""
    rig = Rig(LOCAL_RESET)
    rig.stopped_and_cleared()
    rig.run_for(500, OPERATIONAL)
    assert rig.reset().state is State.RUN


def test_local_reset_refused_when_the_config_does_not_allow_it() -> None:
    """With ``local_reset = false`` (the default) a reset is refused, even from an admin."""
    rig = Rig()
    rig.stopped_and_cleared()
    rig.run_for(600, LOCAL)
    decision = rig.reset()
    assert decision.state is State.STOPPED
    assert [r.reason for r in decision.refusals] == [RefusalReason.LOCAL_RESET_DISABLED]


def test_local_reset_refused_for_a_caller_outside_the_admin_group() -> None:
    """A reset from a caller who is not in the admin group is refused and names the caller."""
    rig = Rig(LOCAL_RESET)
    rig.stopped_and_cleared()
    rig.run_for(600, LOCAL)
    decision = rig.reset(NOBODY)
    assert decision.state is State.STOPPED
    assert [r.reason for r in decision.refusals] == [RefusalReason.NOT_ADMIN]
    assert decision.refusals[0].detail == "bob"


def test_local_reset_refused_while_conditions_are_active_or_too_recent() -> None:
    """A reset is refused while a condition is active, and again until it has been clear for
    the hold time."""
    rig = Rig(LOCAL_RESET)
    rig.bring_up()
    rig.advance(10)
    rig.estop()
    assert [r.reason for r in rig.reset().refusals] == [RefusalReason.CONDITIONS_ACTIVE]
    rig.release()
    rig.run_for(300, LOCAL)
    assert [r.reason for r in rig.reset().refusals] == [RefusalReason.HOLD_TIME_NOT_ELAPSED]
    rig.run_for(200, LOCAL)
    assert rig.reset().state is State.HOLD


def test_local_reset_outside_stopped_is_refused_harmlessly() -> None:
    """A reset in RUN changes nothing and says there is nothing to re-arm."""
    rig = Rig(LOCAL_RESET)
    rig.bring_up()
    decision = rig.reset()
    assert decision.state is State.RUN
    assert [r.reason for r in decision.refusals] == [RefusalReason.NOT_STOPPED]


def test_vsc_reconnect_is_a_new_start() -> None:
    """Opening the link again (a VSC reconnect) stops, even from RUN, until re-armed."""
    rig = Rig()
    rig.bring_up()
    rig.advance(10)
    decision = rig.feed(LinkOpened(rig.now))
    assert decision.state is State.STOPPED
    assert "vsc_link_lost" in decision.active_names
    assert "vsc_watchdog_off" in decision.active_names


def test_a_vsc_reconnect_forgets_the_mode_seen_before_it() -> None:
    """SR-4.4, SR-4.5: a VSC reconnect is a new start also for the takeover: the mode reported
    before it is forgotten, so the first heartbeat after it, Operational, is no takeover edge
    (nothing to refuse), however long the VSC was in Local before."""
    rig = Rig()
    rig.stopped_and_cleared()
    rig.run_for(600, LOCAL)
    rig.advance(10)
    rig.feed(LinkOpened(rig.now))  # reported again, without a close first
    rig.key85(1)
    rig.advance(50)
    decision = rig.vsc(OPERATIONAL)
    assert decision.state is State.STOPPED
    assert decision.rearm is None
    assert decision.refusals == ()


def test_a_vsc_reconnect_ends_the_hold_of_its_mode() -> None:
    """SR-4.4, SR-3.1: the hold of the VSC's mode names a mode the VSC reported before the
    reconnect; the new start forgets it: the causes are the reconnect's own (the link and key
    85 not heard yet), and the mode's hold comes back only with a heartbeat that reports it."""
    rig = Rig()
    rig.bring_up()
    rig.advance(10)
    assert "vsc_mode:local" in rig.vsc(LOCAL).active_names
    rig.advance(10)
    decision = rig.feed(LinkOpened(rig.now))  # reported again, without a close first
    assert not any(name.startswith("vsc_mode:") for name in decision.active_names)
    assert decision.state is State.STOPPED
    rig.key85(1)
    rig.advance(10)
    assert "vsc_mode:local" in rig.vsc(LOCAL).active_names


def test_client_reconnection_is_a_new_start() -> None:
    """A required client that disconnects and reconnects keeps the supervisor STOPPED until a
    re-arm, even once it beats again."""
    rig = Rig()
    rig.bring_up()
    rig.advance(10)
    rig.disconnect()
    rig.advance(10)
    rig.connect(2)
    decision = rig.run_for(1000, OPERATIONAL, clients=(2,))
    assert decision.state is State.STOPPED
    assert decision.latched_names == {"client_lost:planner"}
    # the takeover dwell (rule 4)
    assert rig.take_over(250, clients=(2,)).state is State.RUN


def test_every_refused_rearm_is_recorded_with_its_reason() -> None:
    """docs/record.md: a refused reset or takeover is a ``rearm_refused`` record naming why,
    without any change of state."""
    rig = Rig(LOCAL_RESET)
    rig.bring_up()
    rig.advance(10)
    rig.estop()
    decision = rig.reset()
    [record] = decision.records
    assert record.note is RecordNote.REARM_REFUSED
    assert record.previous is record.state is State.STOPPED
    assert record.reason.startswith(RefusalReason.CONDITIONS_ACTIVE.value)
    assert "client_estop:planner" in record.reason


def test_a_granted_rearm_is_not_noted_as_refused() -> None:
    """The note is for refusals only: a granted reset is an ordinary change of state."""
    rig = Rig(LOCAL_RESET)
    rig.stopped_and_cleared()
    rig.run_for(500, LOCAL)
    [record] = rig.reset().records
    assert record.note is None
    assert record.state is not State.STOPPED


def test_commissioning_is_recorded_with_what_was_read_back() -> None:
    """SR-5.4: writing key 85 is stored on the VSC for good, so it is recorded."""
    rig = Rig()
    rig.bring_up()
    decision = rig.feed(Commissioned(rig.now, ADMIN, key85=1, remote_status=False))
    [record] = decision.records
    assert record.note is RecordNote.COMMISSIONED
    assert record.reason == "key85=1 remote_status=not seen"
    assert decision.state is State.RUN
    silent = rig.feed(Commissioned(rig.now, ADMIN, key85=None, remote_status=True))
    assert silent.records[0].reason == "key85=no answer remote_status=on"
