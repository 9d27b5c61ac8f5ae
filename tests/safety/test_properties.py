"""Property tests: random inputs at random times never break the safety invariants.

Invariants checked after every input (SR-1 to SR-5):
- no output is on while a stop cause is active or latched, nor before a valid re-arm;
- a motion output is on only in RUN, a power output only in HOLD or RUN;
- STOPPED is left only by a re-arm: a takeover heartbeat or an admin's allowed local reset;
- the next deadline is always later than ``now``; ``now`` never goes back;
- the user heartbeat's e-stop byte is 1 whenever a supervisor-side stop condition is active;
- the core never raises.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Callable

from hypothesis import HealthCheck, given, settings
from hypothesis import event as note
from hypothesis import strategies as st

from supervisord.protocol.messages import (
    FeedbackGet,
    FeedbackName,
    FeedbackSet,
    UserHeartbeat,
    VscHeartbeat,
)
from supervisord.safety import (
    ClientConnected,
    ClientDisconnected,
    ClientEstop,
    ClientHeartbeat,
    ClientHello,
    ClientHold,
    ClientRelease,
    Decision,
    DisplayUpdate,
    Event,
    InternalFault,
    LinkBroken,
    LinkClosed,
    LinkOpened,
    LocalEstop,
    LocalRelease,
    OutputReadback,
    OutputRole,
    RearmKind,
    Request,
    ResetRequest,
    SafetyConfig,
    SafetyCore,
    Severity,
    State,
    Tick,
    Transport,
    VscReceived,
)
from tests.safety.rig import ADMIN, LOCAL, MS, NOBODY, OPERATIONAL, PAUSE, ROBOT, SEARCHING

CONFIGS = [
    ROBOT,
    dataclasses.replace(ROBOT, local_reset=True, heartbeat_hz=50),
    dataclasses.replace(ROBOT, transport=Transport.CAN, require_watchdog=False),
    dataclasses.replace(ROBOT, transport=Transport.HID),
    dataclasses.replace(ROBOT, clients=(), require_watchdog=False, local_reset=True),
]

Maker = Callable[[int], list[Event]]

modes = st.sampled_from([LOCAL, OPERATIONAL, OPERATIONAL, OPERATIONAL, PAUSE, SEARCHING, 0x42])
estop_words = st.sampled_from([0, 0, 0, 0, 0b11, 0b1100_0000, 0x100])
connections = st.integers(1, 3)
names = st.sampled_from(["planner", "planner", "arm", "bad name"])
callers = st.sampled_from([ADMIN, NOBODY])


def _healthy(now: int, last: Event) -> list[Event]:
    """650 ms of a healthy VSC in Local and a beating client, then ``last``: a chance to re-arm."""
    events: list[Event] = [LinkOpened(now), VscReceived(now, FeedbackSet(85, 1))]
    events += [ClientConnected(now, 1), ClientHello(now, 1, "planner")]
    for i in range(1, 14):
        events += [VscReceived(now + i * 50 * MS, VscHeartbeat(LOCAL))]
        events += [ClientHeartbeat(now + i * 50 * MS, 1)]
    return [*events, last]


def _single_events() -> st.SearchStrategy[Callable[[int], Event]]:
    """Each strategy yields a function from ``now`` to one event."""
    return st.one_of(
        st.builds(
            lambda m, e: lambda now: VscReceived(now, VscHeartbeat(m, 0, e)), modes, estop_words
        ),
        st.builds(lambda m: lambda now: VscReceived(now, VscHeartbeat(m)), modes),
        st.builds(
            lambda v: lambda now: VscReceived(now, FeedbackSet(85, v)), st.sampled_from([0, 1])
        ),
        st.just(LinkOpened),
        st.just(lambda now: LinkBroken(now, "EIO")),
        st.just(lambda now: LinkClosed(now, "reopen")),
        st.builds(lambda c: lambda now: ClientConnected(now, c), connections),
        st.builds(lambda c, n: lambda now: ClientHello(now, c, n), connections, names),
        st.builds(lambda c: lambda now: ClientHeartbeat(now, c), connections),
        st.builds(lambda c: lambda now: ClientHeartbeat(now, c), connections),
        st.builds(lambda c: lambda now: ClientEstop(now, c), connections),
        st.builds(lambda c: lambda now: ClientHold(now, c), connections),
        st.builds(
            lambda c, r: lambda now: ClientRelease(now, c, r), connections, st.sampled_from(Request)
        ),
        st.builds(lambda c: lambda now: ClientDisconnected(now, c), connections),
        st.builds(lambda c: lambda now: LocalEstop(now, c), callers),
        st.builds(lambda c: lambda now: LocalRelease(now, c), callers),
        st.builds(lambda c: lambda now: ResetRequest(now, c), callers),
        st.builds(
            lambda o, r, b: lambda now: OutputReadback(now, o, r, b),
            st.sampled_from(["drive", "lights", "ghost"]),
            st.booleans(),
            st.sampled_from([True, False, None]),
        ),
        st.just(lambda now: InternalFault(now, "overrun")),
        st.builds(
            lambda k, v: lambda now: DisplayUpdate(now, FeedbackSet(k, v)),
            st.sampled_from([1, 12, 85, 99]),
            st.integers(-1, 4),
        ),
        st.builds(
            lambda k: lambda now: DisplayUpdate(now, FeedbackName(k, "text")),
            st.sampled_from([1, 90, 50]),
        ),
        st.just(Tick),
    )


def _event_makers() -> st.SearchStrategy[Maker]:
    """Single events, and now and then a healthy stretch ending in a takeover or a reset."""
    end = 700 * MS
    return st.one_of(
        _single_events().map(lambda make: lambda now: [make(now)]),
        st.just(lambda now: _healthy(now, VscReceived(now + end, VscHeartbeat(OPERATIONAL)))),
        st.builds(lambda c: lambda now: _healthy(now, ResetRequest(now + end, c)), callers),
    )


steps = st.lists(
    st.tuples(
        st.one_of(st.integers(-20, 60), st.integers(0, 700), st.just(None)),  # None: the deadline
        _event_makers(),
    ),
    max_size=80,
)


def _bring_up(core: SafetyCore, now: int) -> int:
    """Feed a healthy start-up so that random sequences also begin in RUN."""
    config = core.config
    core.handle(LinkOpened(now))
    core.handle(VscReceived(now, FeedbackSet(85, 1)))
    core.handle(ClientConnected(now, 1))
    core.handle(ClientHello(now, 1, "planner"))
    for _ in range(13):
        now += 50 * MS
        core.handle(VscReceived(now, VscHeartbeat(LOCAL)))
        core.handle(ClientHeartbeat(now, 1))
    now += 50 * MS
    decision = core.handle(VscReceived(now, VscHeartbeat(OPERATIONAL)))
    assert decision.state is (State.STOPPED if config.transport is Transport.HID else State.RUN)
    return now


def _check(config: SafetyConfig, before: Decision, after: Decision, event: Event) -> None:
    assert after.now >= before.now
    assert after.next_deadline > after.now
    stop_causes = [c for c in after.causes if c.severity is Severity.STOP]
    if any(c.active or c.latched for c in stop_causes):
        assert after.state is State.STOPPED
    for spec in config.outputs:
        on = after.outputs[spec.name]
        if spec.role is OutputRole.MOTION:
            assert not on or after.state is State.RUN
        else:
            assert not on or after.state is not State.STOPPED
    if after.state is State.STOPPED:
        assert not any(after.outputs.values())
    if before.state is State.STOPPED and after.state is not State.STOPPED:
        assert after.rearm is not None
        if after.rearm.kind is RearmKind.TAKEOVER:
            assert isinstance(event, VscReceived)
            assert isinstance(event.message, VscHeartbeat)
            assert event.message.mode == OPERATIONAL
        else:
            assert isinstance(event, ResetRequest)
            assert event.caller.admin
            assert config.local_reset
        assert not any(c.active for c in stop_causes)
    if after.rearm is not None:
        assert before.state is State.STOPPED
    if config.transport is Transport.HID:
        assert after.state is State.STOPPED
    if any(c.active and c.cause.kind.sets_user_estop for c in after.causes):
        assert after.heartbeat_estop == 1
    if config.transport is not Transport.SERIAL:
        assert not any(isinstance(f, UserHeartbeat | FeedbackGet) for f in after.frames)
    assert len(after.records) <= 1


@settings(max_examples=300, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(
    config=st.sampled_from(CONFIGS),
    start_in_run=st.booleans(),
    plan=steps,
)
def test_random_inputs_keep_every_invariant(
    config: SafetyConfig, start_in_run: bool, plan: list[tuple[int | None, Maker]]
) -> None:
    """Whatever arrives, whenever it arrives, every safety invariant holds after every input."""
    now = 10_000 * MS
    core = SafetyCore(config, now)
    if start_in_run:
        now = _bring_up(core, now)
    before = core.decision
    sequence = [r.sequence for r in before.records]
    for step, make in plan:
        now = before.next_deadline if step is None else now + step * MS
        for event in make(now):
            now = max(now, event.now)
            after = core.handle(event)
            _check(config, before, after, event)
            sequence.extend(r.sequence for r in after.records)
            if after.rearm is not None:
                note(f"re-armed by {after.rearm.kind.value}")  # coverage, shown in statistics
            before = after
    note(f"ends in {before.state.name}")
    assert sequence == sorted(set(sequence))


@settings(max_examples=100, deadline=None)
@given(plan=steps)
def test_nothing_is_on_before_the_first_valid_rearm(plan: list[tuple[int | None, Maker]]) -> None:
    """From startup, every output stays off until a decision that carries a re-arm."""
    now = 10_000 * MS
    core = SafetyCore(dataclasses.replace(ROBOT, local_reset=True), now)
    decision = core.decision
    for step, make in plan:
        now = decision.next_deadline if step is None else now + step * MS
        for event in make(now):
            now = max(now, event.now)
            decision = core.handle(event)
            if decision.rearm is not None:
                return
            assert not any(decision.outputs.values())
            assert decision.state is State.STOPPED
