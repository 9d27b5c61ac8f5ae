"""Re-arm only at zero command (SR-4.6): a client's declaration that it commands motion
refuses every re-arm while it holds, the refusal is recorded and shown on the remote."""

from __future__ import annotations

import dataclasses
from collections.abc import Callable

from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from supervisord.protocol.messages import FeedbackName, FeedbackSet, Message, VscHeartbeat
from supervisord.safety import (
    ClientCommand,
    ClientConnected,
    ClientDisconnected,
    ClientHello,
    Decision,
    DisplayUpdate,
    Event,
    RearmKind,
    RecordNote,
    RefusalReason,
    SafetyCore,
    State,
    VscReceived,
)
from tests.safety.rig import ADMIN, LOCAL, MS, OPERATIONAL, ROBOT, START_NS, Rig
from tests.safety.test_properties import _bring_up, _healthy, _single_events

LOCAL_RESET = dataclasses.replace(ROBOT, local_reset=True)
NOTICE = {
    90: "NOT RE-ARMED",
    91: "COMMAND NOT ZERO:",
    92: "planner",
    93: "ZERO IT, TAKE OVER",
}


def command(rig: Rig, nonzero: bool, connection: int = 1) -> Decision:
    return rig.feed(ClientCommand(rig.now, connection, nonzero))


def refused_takeover() -> Rig:
    """RUN, an e-stop released, the planner declaring a non-zero command, a takeover."""
    rig = Rig()
    rig.stopped_and_cleared()
    command(rig, True)
    decision = rig.take_over(500)
    assert decision.state is State.STOPPED
    return rig


def rows_sent(rig: Rig, since: int = 0) -> dict[int, str]:
    """The latest text of each string key sent to the VSC in the decisions from ``since``."""
    rows: dict[int, str] = {}
    for decision in rig.decisions[since:]:
        for frame in decision.frames:
            if isinstance(frame, FeedbackName):
                rows[frame.key] = frame.text
    return rows


def values_sent(rig: Rig, since: int = 0) -> list[FeedbackSet]:
    return [f for d in rig.decisions[since:] for f in d.frames if isinstance(f, FeedbackSet)]


def test_a_takeover_while_a_client_commands_motion_is_refused_and_recorded() -> None:
    """SR-4.6: with every other rule of SR-4 met, a takeover while the planner declares a
    non-zero command does not re-arm; the refusal names the client and is recorded."""
    rig = refused_takeover()
    decision = rig.last
    assert [r.reason for r in decision.refusals] == [RefusalReason.COMMAND_NONZERO]
    assert decision.refusals[0].detail == "planner"
    (record,) = decision.records
    assert record.note is RecordNote.REARM_REFUSED
    assert record.reason == decision.refusals[0].message
    assert record.rearm is None
    assert not any(decision.outputs.values())


def test_zero_command_then_a_new_takeover_rearms_and_zero_alone_does_not() -> None:
    """SR-4.6, SR-4.2 (choice 2): declaring zero does not re-arm by itself; the refused
    takeover is not remembered; the operator's next takeover re-arms."""
    rig = refused_takeover()
    assert command(rig, False).state is State.STOPPED
    rig.run_for(300, OPERATIONAL)
    assert rig.state is State.STOPPED
    decision = rig.take_over(250)
    assert decision.state is State.RUN
    assert decision.rearm is not None
    assert decision.rearm.kind is RearmKind.TAKEOVER


def test_a_local_reset_is_refused_too() -> None:
    """SR-4.6: any re-arm, the admin's local reset as well, waits for zero command."""
    rig = Rig(LOCAL_RESET)
    rig.stopped_and_cleared()
    command(rig, True)
    rig.run_for(600, OPERATIONAL)
    refused = rig.reset(ADMIN)
    assert refused.state is State.STOPPED
    assert [r.reason for r in refused.refusals] == [RefusalReason.COMMAND_NONZERO]
    assert refused.records[0].note is RecordNote.REARM_REFUSED
    command(rig, False)
    assert rig.reset(ADMIN).state is State.RUN


def test_other_rules_are_reported_first() -> None:
    """SR-4.6 is checked last: a takeover too short is refused as too short, so the
    operator's display is told about the command only when nothing else is wrong."""
    rig = Rig()
    rig.stopped_and_cleared()
    command(rig, True)
    rig.run_for(600, OPERATIONAL)
    rig.run_for(100, LOCAL)
    rig.advance(50)
    decision = rig.vsc(OPERATIONAL)
    assert [r.reason for r in decision.refusals] == [RefusalReason.TAKEOVER_TOO_SHORT]
    assert 92 not in rows_sent(rig)


def test_an_undeclared_client_counts_as_zero() -> None:
    """SR-4.6: a client that never declares (every client written before the rule) does not
    block a re-arm; nor does one that declared zero."""
    rig = Rig()
    rig.stopped_and_cleared()
    assert rig.take_over(500).state is State.RUN
    other = Rig()
    other.stopped_and_cleared()
    command(other, False)
    assert other.take_over(500).state is State.RUN


def test_every_declaring_client_must_be_at_zero() -> None:
    """SR-4.6: while any one client declares non-zero, no re-arm; the refusal names all."""
    rig = Rig()
    rig.open_link()
    rig.key85(1)
    rig.connect()
    rig.connect(2, "arm")
    rig.take_over(600, clients=(1, 2))
    rig.estop()
    rig.release()
    command(rig, True)
    command(rig, True, connection=2)
    refused = rig.take_over(500, clients=(1, 2))
    assert refused.refusals[0].detail == "arm, planner"
    command(rig, False)
    rig.run_for(600, OPERATIONAL)  # past the quiet second of a repeated takeover refusal
    assert rig.take_over(500, clients=(1, 2)).refusals[0].detail == "arm"
    command(rig, False, connection=2)
    rig.run_for(300, OPERATIONAL)
    assert rig.take_over(500, clients=(1, 2)).state is State.RUN


def test_a_declaration_ends_with_its_connection() -> None:
    """SR-4.6: a client's declaration is forgotten when its connection ends (the process
    commanding the motion is gone); a new connection of that name starts undeclared."""
    rig = Rig()
    rig.open_link()
    rig.key85(1)
    rig.connect()
    rig.connect(2, "arm")
    rig.take_over(600, clients=(1, 2))
    rig.estop()
    rig.release()
    command(rig, True, connection=2)
    rig.disconnect(2)
    rig.connect(3, "arm")
    assert rig.take_over(500).state is State.RUN


def test_a_declaration_before_hello_is_refused() -> None:
    """SR-4.6, SR-8.7: only a named client declares; before hello the declaration is refused
    (``NO_HELLO``) and blocks nothing."""
    rig = Rig()
    rig.stopped_and_cleared()
    rig.feed(ClientConnected(rig.now, 2))
    refused = command(rig, True, connection=2)
    assert [r.reason for r in refused.refusals] == [RefusalReason.NO_HELLO]
    unknown = command(rig, True, connection=9)
    assert [r.reason for r in unknown.refusals] == [RefusalReason.UNKNOWN_CONNECTION]
    assert rig.take_over(500, clients=(1,)).state is State.RUN


def test_a_declaration_is_no_cause_and_makes_no_record() -> None:
    """SR-4.6, SR-7.1: a declaration changes no state and no cause, so it writes no record;
    in RUN a non-zero command is the normal case and changes nothing."""
    rig = Rig()
    rig.bring_up()
    decision = command(rig, True)
    assert decision.state is State.RUN
    assert decision.records == ()
    assert decision.refusals == ()
    assert command(rig, False).records == ()


def test_the_refusal_is_shown_on_the_remotes_text_page() -> None:
    """SR-4.6: the refused takeover puts the notice on the remote's text page (the rows
    first, within the rate limit of strings), switches it to the text page and vibrates it
    once; the same refusal again sends nothing new."""
    rig = Rig()
    rig.stopped_and_cleared()
    command(rig, True)
    start = len(rig.decisions)
    refused = rig.take_over(500)
    first = [f for f in refused.frames if isinstance(f, FeedbackName)]
    assert first == [FeedbackName(90, "NOT RE-ARMED")]
    assert FeedbackSet(99, 1) in values_sent(rig, start)
    rig.run_for(800, OPERATIONAL)
    assert rows_sent(rig, start) == NOTICE
    sent = values_sent(rig, start)
    assert sent.count(FeedbackSet(12, 1)) == 1  # both motors, once
    again = len(rig.decisions)
    assert rig.take_over(500).refusals[0].reason is RefusalReason.COMMAND_NONZERO
    rig.run_for(800, OPERATIONAL)
    assert rows_sent(rig, again) == {}
    assert values_sent(rig, again) == []


def test_zero_command_gives_the_clients_display_back() -> None:
    """SR-4.6: while the notice shows, a client's rows and mode are kept, not sent; once no
    client commands motion they come back, and rows no client set are cleared."""
    rig = Rig()
    rig.bring_up()
    rig.feed(DisplayUpdate(rig.now, FeedbackName(90, "mission: survey")))
    rig.feed(DisplayUpdate(rig.now, FeedbackSet(99, 2)))
    rig.run_for(300, OPERATIONAL)
    rig.estop()
    rig.release()
    command(rig, True)
    rig.take_over(500)
    during = len(rig.decisions)
    rig.feed(DisplayUpdate(rig.now, FeedbackName(91, "leg 2")))
    rig.feed(DisplayUpdate(rig.now, FeedbackSet(99, 3)))
    rig.feed(DisplayUpdate(rig.now, FeedbackName(1, "speed")))  # not the notice's: sent
    rig.feed(DisplayUpdate(rig.now, FeedbackSet(2, 7)))
    rig.run_for(1000, OPERATIONAL)
    assert rows_sent(rig, during) == {1: "speed", **{k: v for k, v in NOTICE.items() if k != 90}}
    assert FeedbackSet(99, 3) not in values_sent(rig, during)
    assert FeedbackSet(2, 7) in values_sent(rig, during)
    after = len(rig.decisions)
    command(rig, False)
    rig.run_for(1100, OPERATIONAL)
    assert rows_sent(rig, after) == {90: "mission: survey", 91: "leg 2", 92: "", 93: ""}
    assert values_sent(rig, after)[-1:] == [FeedbackSet(99, 3)]


def test_the_notice_is_sent_again_when_the_remote_relinks() -> None:
    """SR-4.6, PR-2.12: the remote forgets its display when it re-links; the notice comes
    back with it, before the clients' content."""
    rig = refused_takeover()
    rig.run_for(1000, OPERATIONAL)
    rig.advance(50)
    rig.vsc(0x01)  # Searching: the remote lost its link
    start = len(rig.decisions)
    rig.run_for(1000, LOCAL)
    assert rows_sent(rig, start) == NOTICE
    assert FeedbackSet(99, 1) in values_sent(rig, start)


def test_a_client_disconnecting_ends_the_notice() -> None:
    """SR-4.6: the notice lasts while a client commands motion; a connection's end ends its
    declaration, and the text page is given back."""
    rig = Rig()
    rig.open_link()
    rig.key85(1)
    rig.connect()
    rig.connect(2, "arm")
    rig.take_over(600, clients=(1, 2))
    rig.estop()
    rig.release()
    command(rig, True, connection=2)
    rig.take_over(500)
    assert rig.core._display.showing_notice
    rig.disconnect(2)
    assert not rig.core._display.showing_notice


# -- the property


def _declarations() -> st.SearchStrategy[Callable[[int], Event]]:
    return st.builds(
        lambda c, nonzero: lambda now: ClientCommand(now, c, nonzero),
        st.integers(1, 3),
        st.sampled_from([True, True, False]),
    )


_makers = st.one_of(
    st.one_of(_single_events(), _declarations(), _declarations()).map(
        lambda make: lambda now: [make(now)]
    ),
    st.just(lambda now: _healthy(now, VscReceived(now + 700 * MS, VscHeartbeat(OPERATIONAL)))),
    st.builds(
        lambda nonzero: (
            lambda now: [
                *_healthy(now, ClientCommand(now + 650 * MS, 1, nonzero)),
                VscReceived(now + 700 * MS, VscHeartbeat(OPERATIONAL)),
            ]
        ),
        st.booleans(),
    ),
)


class _Declared:
    """The declarations as the test sees them from the inputs and the core's refusals alone:
    each connection's name from an accepted hello, each named connection's last declaration."""

    def __init__(self) -> None:
        self.names: dict[int, str] = {}
        self.nonzero: dict[int, bool] = {}

    def take(self, event: Event, decision: Decision) -> None:
        refused = any(r.trigger == event for r in decision.refusals)
        if isinstance(event, ClientHello) and not refused:
            self.names[event.connection] = event.name
        elif isinstance(event, ClientDisconnected) and not refused:
            self.names.pop(event.connection, None)
            self.nonzero.pop(event.connection, None)
        elif isinstance(event, ClientCommand) and not refused:
            assert event.connection in self.names  # a declaration is a named client's
            self.nonzero[event.connection] = event.nonzero

    @property
    def any(self) -> bool:
        return any(self.nonzero.values())


@settings(
    max_examples=150,
    deadline=None,
    suppress_health_check=[HealthCheck.too_slow, HealthCheck.data_too_large],
)
@given(
    config=st.sampled_from([ROBOT, LOCAL_RESET]),
    start_running=st.booleans(),
    steps=st.lists(st.tuples(st.one_of(st.integers(0, 700), st.just(None)), _makers), max_size=60),
)
def test_no_rearm_while_any_client_commands_motion(
    config: object, start_running: bool, steps: list[tuple[int | None, object]]
) -> None:
    """SR-4.6: whatever the inputs and their times, STOPPED is never left while a named,
    connected client's last declaration is non-zero; the notice shows only while STOPPED and
    a client commands motion; and with every client at zero the rule refuses nothing."""
    assert isinstance(config, type(ROBOT))
    core = SafetyCore(config, START_NS)
    now = START_NS
    declared = _Declared()
    if start_running:
        now = _bring_up(core, now)
        declared.names[1] = "planner"
    before = core.decision
    for delay, make in steps:
        now = before.next_deadline if delay is None else now + delay * MS
        assert callable(make)
        for event in make(now):
            now = max(now, event.now)
            after = core.handle(event)
            declared.take(event, after)
            if before.state is State.STOPPED and after.state is not State.STOPPED:
                assert not declared.any, (event, declared.nonzero)
            reasons = {r.reason for r in after.refusals}
            if RefusalReason.COMMAND_NONZERO in reasons:
                assert declared.any
            if core._display.showing_notice:
                assert after.state is State.STOPPED
                assert declared.any
            before = after


def _long_named_and_stopped(other: str) -> Rig:
    """RUN with two clients, none required: connection 1 named with 32 characters, connection
    2 named ``other``; then an e-stop, released."""
    rig = Rig(dataclasses.replace(ROBOT, clients=()))
    rig.open_link()
    rig.key85(1)
    rig.connect(1, "n" * 32)
    rig.connect(2, other)
    assert rig.take_over(600, clients=()).state is State.RUN
    rig.estop()
    rig.release()
    return rig


def test_frames_of_the_notice_are_valid_messages() -> None:
    """SR-4.6, PR-2.12: a client name of 32 characters still makes a row of at most 20."""
    rig = _long_named_and_stopped("a")
    command(rig, True)
    command(rig, True, connection=2)
    assert rig.take_over(500, clients=()).refusals[0].reason is RefusalReason.COMMAND_NONZERO
    rig.run_for(800, OPERATIONAL, clients=())
    frames: list[Message] = [f for d in rig.decisions for f in d.frames]
    rows = [f for f in frames if isinstance(f, FeedbackName) and f.key == 92]
    assert rows
    assert all(len(f.text) <= 20 for f in rows)
    assert rows[-1].text == "a +1"


def test_the_row_of_names_is_the_remotes_twenty_characters() -> None:
    """SR-4.6, PR-2.12: the row that names who commands motion fills the remote's 20
    characters and no more: a name of 32 shows its first 20; with a second client declaring,
    its first 17 and " +1"."""
    rig = _long_named_and_stopped("o")
    command(rig, True)
    assert rig.take_over(500, clients=()).refusals[0].reason is RefusalReason.COMMAND_NONZERO
    rig.run_for(800, OPERATIONAL, clients=())
    assert rows_sent(rig)[92] == "n" * 20
    since = len(rig.decisions)
    command(rig, True, connection=2)
    assert rig.take_over(500, clients=()).refusals[0].reason is RefusalReason.COMMAND_NONZERO
    rig.run_for(800, OPERATIONAL, clients=())
    assert rows_sent(rig, since)[92] == "n" * 17 + " +1"
