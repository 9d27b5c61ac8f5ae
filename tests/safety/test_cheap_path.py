"""The cheap path (docs/performance.md "The cheap path", SR-9.4) is the full path, faster.

A core answers an input that cannot change a decision (a tick, a joystick frame, a GPS
sentence, a heartbeat identical to the last, a client's heartbeat in time, before the next
deadline) without the full step.
These tests run two cores side by side, one with the cheap path and one without, over random
input sequences, and require the same decision for every input: state, causes, outputs, the
user heartbeat's byte, the next deadline, frames, records and refusals.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Callable
from typing import Any
from unittest import mock

from hypothesis import HealthCheck, given, settings
from hypothesis import event as note
from hypothesis import strategies as st

from supervisord.protocol.messages import Axis, Gps, Joystick, RemoteStatus, VscHeartbeat
from supervisord.safety import (
    ClientHeartbeat,
    Decision,
    Event,
    OutputRole,
    OutputSpec,
    RefusalReason,
    SafetyConfig,
    SafetyCore,
    State,
    Tick,
    Transport,
    VscReceived,
)
from supervisord.safety import cheap as cheap_module
from supervisord.safety import core as core_module
from supervisord.safety.prooftest import ProofTestPolicy
from tests.safety.rig import MS, OPERATIONAL, ROBOT, Rig
from tests.safety.test_properties import CONFIGS, _bring_up, _event_makers, modes

Maker = Callable[[int], list[Event]]

JOYSTICK = Joystick(left_y=Axis.from_value(300))


def _steady_inputs() -> st.SearchStrategy[Maker]:
    """The inputs the cheap path is for, often repeated so that steady states occur."""
    return st.one_of(
        st.just(lambda now: [VscReceived(now, JOYSTICK)]),
        st.just(lambda now: [VscReceived(now, Joystick())]),
        st.just(lambda now: [VscReceived(now, Gps(1, "$GPGGA,1*00"))]),
        st.just(lambda now: [VscReceived(now, RemoteStatus(50, 0, 2, 2))]),
        st.just(lambda now: [Tick(now)]),
        st.builds(lambda m: lambda now: [VscReceived(now, VscHeartbeat(m))], modes),
        st.just(lambda now: [VscReceived(now, VscHeartbeat(OPERATIONAL))]),
        # a client's heartbeat: connection 1 is the required client of _bring_up, 2 unknown;
        # a progress value takes the full path, and binds the client to progress (SR-8.16)
        st.builds(
            lambda c, p: lambda now: [ClientHeartbeat(now, c, p)],
            st.sampled_from([1, 1, 1, 2]),
            st.sampled_from([None, None, None, 1, 2]),
        ),
        st.just(
            lambda now: [
                e
                for i in range(12)
                for e in (
                    VscReceived(now + i * 20 * MS, VscHeartbeat(OPERATIONAL)),
                    ClientHeartbeat(now + i * 20 * MS + 10 * MS, 1),
                )
            ]
        ),
        st.just(
            lambda now: [
                VscReceived(now + i * 20 * MS, m)
                for i in range(12)
                for m in (VscHeartbeat(OPERATIONAL), JOYSTICK)
            ]
        ),
    )


CHEAP_CONFIGS = [
    *CONFIGS,
    dataclasses.replace(ROBOT, prooftest=ProofTestPolicy.BLOCK),  # the serial default
    dataclasses.replace(ROBOT, prooftest=ProofTestPolicy.RECORD, local_reset=True),
    # a category-1 output: the full path switches it off with time (SR-1.4)
    dataclasses.replace(
        ROBOT,
        outputs=(
            OutputSpec("drive", OutputRole.MOTION),
            OutputSpec("lights", OutputRole.POWER, off_delay_ms=150),
        ),
    ),
]

steps = st.lists(
    st.tuples(
        st.one_of(st.integers(-5, 60), st.integers(0, 400), st.just(None)),  # None: the deadline
        st.one_of(_steady_inputs(), _steady_inputs(), _event_makers()),
    ),
    max_size=80,
)


@settings(max_examples=400, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(config=st.sampled_from(CHEAP_CONFIGS), start_in_run=st.booleans(), plan=steps)
def test_the_cheap_path_decides_exactly_as_the_full_path(
    config: SafetyConfig, start_in_run: bool, plan: list[tuple[int | None, Maker]]
) -> None:
    """For any input sequence, a core with the cheap path and one without give equal decisions
    (same state, causes, outputs, byte, deadline, frames, records, refusals) for every input."""
    now = 10_000 * MS
    cheap, full = SafetyCore(config, now), SafetyCore(config, now)
    full.cheap_path = False
    answered: list[bool] = []  # a spy on the cheap path: whether it answered, for coverage
    real_cheap = cheap_module.cheap

    def spying(event: Event, *parts: Any) -> Decision | None:
        decision = real_cheap(event, *parts)
        answered.append(decision is not None)
        return decision

    # Only ``cheap`` calls it: ``full`` has no cheap path.
    with mock.patch.object(core_module, "cheap", spying):
        assert cheap.decision == full.decision
        if start_in_run and config.prooftest is ProofTestPolicy.OFF:  # RUN needs a passed proof
            now = _bring_up(cheap, now)
            _bring_up(full, 10_000 * MS)
            assert cheap.decision == full.decision
        for step, make in plan:
            now = cheap.decision.next_deadline if step is None else now + step * MS
            for event in make(now):
                now = max(now, event.now)
                expected = full.handle(event)
                got = cheap.handle(event)
                assert got == expected, event
    note(f"cheap answers: {'some' if any(answered) else 'none'}")  # shown in statistics


def test_a_joystick_frame_in_run_skips_the_recomputation() -> None:
    """In RUN, a joystick frame before any deadline is answered without recomputing a cause,
    and its decision equals the previous one but for ``now`` and the next deadline."""
    rig = Rig()
    rig.bring_up()
    assert rig.state is State.RUN
    before = rig.last
    refreshes = rig.count_refreshes()
    rig.advance(1)
    decision = rig.from_vsc(JOYSTICK)
    assert refreshes == []
    assert decision.state is State.RUN
    assert (decision.causes, decision.outputs) == (before.causes, before.outputs)
    assert decision.now == before.now + MS
    assert not decision.frames
    assert not decision.records
    assert not decision.refusals


def test_a_client_heartbeat_in_time_skips_the_recomputation_and_moves_its_deadline() -> None:
    """SR-8.1, SR-9.4: in RUN, the required client's heartbeat within its timeout is answered
    without recomputing a cause and still restarts the client's timeout: heartbeats every
    400 ms (timeout 500 ms) keep RUN for 4 s without one recomputation; silence still stops."""
    rig = Rig(dataclasses.replace(ROBOT, transport=Transport.CAN, require_watchdog=False))
    rig.bring_up()
    refreshes = rig.count_refreshes()
    for _ in range(10):
        for _ in range(2):
            rig.advance(200)
            rig.vsc()
        decision = rig.beat()
        assert decision.state is State.RUN
        assert not decision.records
    assert refreshes == []
    for _ in range(3):
        rig.advance(200)
        rig.vsc()
    assert rig.last.state is State.STOPPED  # 600 ms without a client heartbeat: client_lost
    assert "client_lost:planner" in rig.last.active_names


def test_the_heartbeat_of_a_client_no_rule_waits_for_skips_the_recomputation() -> None:
    """SR-9.4: a named client that is not required changes nothing with its heartbeat, which
    is answered in RUN without recomputing a cause; an unnamed connection's is refused by the
    full step (SR-8: ``no_hello``)."""
    rig = Rig()
    rig.bring_up()
    rig.connect(2, "viewer")
    refreshes = rig.count_refreshes()
    rig.advance(1)
    decision = rig.beat(2)
    assert refreshes == []
    assert decision.state is State.RUN
    assert not decision.refusals
    rig.connect(3, None)
    rig.advance(1)
    before = len(refreshes)
    refused = rig.beat(3)
    assert len(refreshes) > before
    assert [r.reason for r in refused.refusals] == [RefusalReason.NO_HELLO]


def test_a_client_heartbeat_at_the_instant_of_its_loss_takes_the_full_path() -> None:
    """SR-8.1, SR-2.4: a client's heartbeat that comes at the very instant its timeout was
    declared (a tick there raised ``client_lost``) is counted by the full step: the loss
    clears in that step's decision and record, as it does without the cheap path."""
    rig = Rig(dataclasses.replace(ROBOT, transport=Transport.CAN, require_watchdog=False))
    rig.bring_up()
    rig.advance(1)
    rig.beat()
    beat = rig.now
    rig.advance(200)
    rig.vsc()
    rig.advance(200)
    rig.vsc()
    rig.now = beat + 500 * MS  # the client's timeout, exactly
    lost = rig.tick()
    assert "client_lost:planner" in lost.active_names
    back = rig.beat()  # the same instant
    assert "client_lost:planner" not in back.active_names
    assert back.records
    assert back.state is State.STOPPED  # a stop stays latched until a re-arm (SR-4)


def test_a_vsc_heartbeat_at_the_instant_of_its_loss_takes_the_full_path() -> None:
    """SR-2.2: a VSC heartbeat identical to the last that comes at the very instant the VSC's
    timeout was declared (a tick there raised ``vsc_link_lost``) is counted by the full step:
    the loss clears in that step's decision, as it does without the cheap path."""
    config = dataclasses.replace(ROBOT, transport=Transport.CAN, require_watchdog=False, clients=())
    rig = Rig(config)
    rig.bring_up()
    last = rig.now
    rig.now = last + config.vsc_timeout_ns  # the VSC's timeout, exactly
    assert "vsc_link_lost" in rig.tick().active_names
    back = rig.vsc()  # the same mode and word, the same instant
    assert "vsc_link_lost" not in back.active_names
    assert back.records
    assert back.state is State.STOPPED  # a stop stays latched until a re-arm (SR-4)


def test_a_changed_heartbeat_takes_the_full_path() -> None:
    """A VSC heartbeat whose mode differs from the last one is recomputed and changes the
    decision (RUN -> HOLD): the cheap path never swallows a change."""
    rig = Rig()
    rig.bring_up()
    refreshes = rig.count_refreshes()
    rig.advance(1)
    decision = rig.vsc(mode=0x0B)  # Pause
    assert refreshes
    assert decision.state is State.HOLD
    assert decision.records


def test_an_identical_heartbeat_still_moves_the_link_deadline() -> None:
    """A heartbeat identical to the last takes the cheap path and still restarts the VSC
    timeout (SR-2.2): on CAN (timeout 300 ms) identical heartbeats every 250 ms keep RUN for
    3 s without one recomputation, and the deadline is always the last heartbeat + 300 ms."""
    config = dataclasses.replace(ROBOT, transport=Transport.CAN, require_watchdog=False, clients=())
    rig = Rig(config)
    rig.bring_up()
    refreshes = rig.count_refreshes()
    for _ in range(12):
        rig.advance(250)
        decision = rig.vsc()
        assert decision.state is State.RUN
        assert decision.next_deadline == decision.now + config.vsc_timeout_ns
    assert refreshes == []
    rig.advance(300)
    assert rig.tick().state is State.STOPPED  # and silence still stops (the full path)
