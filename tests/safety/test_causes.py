"""Every cause of SR-2 and SR-3 is raised, cleared, and (for stops) latched."""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import pytest

from supervisord.safety import (
    ChangeKind,
    Decision,
    InternalFault,
    LinkBroken,
    LinkClosed,
    LocalEstop,
    LocalRelease,
    OutputReadback,
    RearmKind,
    RefusalReason,
    Request,
    State,
)
from supervisord.safety.causes import Cause, CauseKind
from tests.safety.rig import ADMIN, LOCAL, NOBODY, OPERATIONAL, PAUSE, Rig


@dataclass(frozen=True)
class Scenario:
    cause: str
    raise_: Callable[[Rig], Decision]
    clear: Callable[[Rig], Decision]

    def __str__(self) -> str:
        return self.cause


def _reopen(rig: Rig) -> Decision:
    rig.open_link()
    rig.key85(1)
    return rig.vsc(LOCAL)


def _lose_vsc(rig: Rig) -> Decision:
    rig.advance(200)
    return rig.tick()


def _reconnect(rig: Rig) -> Decision:
    rig.connect()
    return rig.beat()


STOPS = [
    Scenario("vsc_estop", lambda r: r.vsc(LOCAL, estop=0b11), lambda r: r.vsc(LOCAL)),
    Scenario("vsc_link_lost", _lose_vsc, lambda r: r.vsc(LOCAL)),
    Scenario("transport_fault", lambda r: r.feed(LinkBroken(r.now, "unplugged")), _reopen),
    Scenario("client_lost:planner", lambda r: r.disconnect(), _reconnect),
    Scenario("client_estop:planner", lambda r: r.estop(), lambda r: r.release()),
    Scenario(
        "local_estop",
        lambda r: r.feed(LocalEstop(r.now, ADMIN)),
        lambda r: r.feed(LocalRelease(r.now, ADMIN)),
    ),
    Scenario(
        "output_fault:drive",
        lambda r: r.feed(OutputReadback(r.now, "drive", True, False)),
        lambda r: r.feed(OutputReadback(r.now, "drive", False, False)),
    ),
    Scenario("vsc_watchdog_off", lambda r: r.key85(0), lambda r: r.key85(1)),
]


@pytest.mark.parametrize("scenario", STOPS, ids=str)
def test_stop_cause_is_raised_latched_cleared_and_rearmed(scenario: Scenario) -> None:
    """Each stop cause stops at once, stays latched after its condition clears, and only a
    takeover after the hold time ends STOPPED."""
    rig = Rig()
    rig.bring_up()
    rig.advance(10)
    raised = scenario.raise_(rig)
    state = raised.cause(scenario.cause)
    assert state is not None
    assert state.active
    assert state.latched
    assert raised.state is State.STOPPED
    assert not any(raised.outputs.values())
    (record,) = raised.records
    assert record.previous is State.RUN
    assert record.state is State.STOPPED
    assert any(
        c.cause.name == scenario.cause and c.kind is ChangeKind.RAISED for c in record.changes
    )

    rig.advance(10)
    cleared = scenario.clear(rig)
    state = cleared.cause(scenario.cause)
    assert state is not None
    assert not state.active
    assert state.latched
    assert cleared.state is State.STOPPED

    rig.run_for(600, LOCAL)
    assert rig.state is State.STOPPED  # never leaves STOPPED on its own (SR-1)
    rig.advance(50)
    rearmed = rig.vsc(OPERATIONAL)
    assert rearmed.state is State.RUN
    assert rearmed.cause(scenario.cause) is None
    assert rearmed.rearm is not None
    assert rearmed.rearm.kind is RearmKind.TAKEOVER


def test_internal_fault_is_momentary_but_latches() -> None:
    """The ``internal`` cause fires and is clear at once, yet keeps the supervisor STOPPED
    until a re-arm."""
    rig = Rig()
    rig.bring_up()
    rig.advance(10)
    decision = rig.feed(InternalFault(rig.now, "loop overran by 30 ms"))
    state = decision.cause("internal")
    assert state is not None
    assert not state.active
    assert state.latched
    assert state.detail("reason") == "loop overran by 30 ms"
    assert decision.state is State.STOPPED
    assert rig.take_over(600).state is State.RUN


HOLDS = [
    # The operator's pause: 200 ms of Pause heartbeats, then Operational (SR-3.3).
    Scenario(
        "vsc_mode:pause",
        lambda r: r.vsc(PAUSE),
        lambda r: (r.run_for(200, PAUSE), r.advance(50), r.vsc(OPERATIONAL))[-1],
    ),
    Scenario("client_hold:planner", lambda r: r.hold(), lambda r: r.release(request=Request.HOLD)),
]


@pytest.mark.parametrize("scenario", HOLDS, ids=str)
def test_hold_cause_is_raised_and_clears_by_itself(scenario: Scenario) -> None:
    """SR-1.2, SR-3.1, SR-3.2: each hold cause moves RUN to HOLD (motion off, power on) and back to
    RUN when it clears, without a re-arm."""
    rig = Rig()
    rig.bring_up()
    rig.advance(10)
    held = scenario.raise_(rig)
    state = held.cause(scenario.cause)
    assert state is not None
    assert state.active
    assert not state.latched
    assert held.state is State.HOLD
    assert dict(held.outputs) == {"drive": False, "lights": True}
    rig.advance(10)
    released = scenario.clear(rig)
    assert released.state is State.RUN
    assert released.cause(scenario.cause) is None
    assert dict(released.outputs) == {"drive": True, "lights": True}


def test_startup_is_stopped_with_cause_startup() -> None:
    """SR-1.3: the core starts STOPPED with the latched cause ``startup`` and every output off."""
    rig = Rig()
    first = rig.last
    assert first.state is State.STOPPED
    startup = first.cause("startup")
    assert startup is not None
    assert startup.latched
    assert not startup.active
    assert not any(first.outputs.values())
    assert first.records
    assert first.records[0].sequence == 1


def test_startup_names_exactly_the_causes_of_a_new_start() -> None:
    """SR-1.3, SR-2.2, SR-2.3, SR-2.4, SR-5.3, docs/safety.md choices 4 and 5: at start the
    link is not open, no VSC heartbeat and no client has been seen, key 85 has not answered;
    nothing else is a cause (no e-stop word before any heartbeat)."""
    first = Rig().last
    assert first.active_names == {
        "transport_fault",
        "vsc_link_lost",
        "vsc_watchdog_off",
        "client_lost:planner",
    }
    assert first.latched_names == first.active_names | {"startup"}


def test_a_vsc_message_before_the_link_opened_is_refused_and_changes_nothing() -> None:
    """SR-2.3, SR-2.10: the link is closed until the daemon says it opened (docs/safety.md
    choice 5): a VSC message before that is refused, and neither clears the silence nor moves
    any other cause."""
    rig = Rig()
    first = rig.last
    rig.advance(10)
    decision = rig.vsc(OPERATIONAL)
    assert [r.reason for r in decision.refusals] == [RefusalReason.LINK_NOT_OPEN]
    assert decision.active_names == first.active_names
    assert not decision.records


def test_vsc_estop_record_names_the_sources() -> None:
    """SR-2.1, PR-6.6: a VSC e-stop's details name every source in the e-stop word, and a new source
    while active is recorded as an update."""
    rig = Rig()
    rig.bring_up()
    rig.advance(10)
    first = rig.vsc(LOCAL, estop=0b0000_0001)
    state = first.cause("vsc_estop")
    assert state is not None
    assert state.detail("sources") == "remote"
    assert state.detail("word") == "0x00000001"
    rig.advance(10)
    second = rig.vsc(LOCAL, estop=0b0000_0101)
    state = second.cause("vsc_estop")
    assert state is not None
    assert state.detail("sources") == "remote,wired"
    (record,) = second.records
    assert [c.kind for c in record.changes] == [ChangeKind.UPDATED]


def test_every_record_has_a_rising_sequence_number() -> None:
    """Records are numbered 1, 2, 3... in the order the core produced them."""
    rig = Rig()
    rig.bring_up()
    rig.advance(10)
    rig.estop()
    numbers = [r.sequence for d in rig.decisions for r in d.records]
    assert numbers == list(range(1, len(numbers) + 1))


def test_output_that_cannot_be_set_is_a_fault() -> None:
    """SR-2.7: a failed write (no read-back at all) raises ``output_fault:NAME`` with the
    details."""
    rig = Rig()
    rig.bring_up()
    decision = rig.feed(OutputReadback(rig.now, "lights", True, None))
    fault = decision.cause("output_fault:lights")
    assert fault is not None
    assert fault.active
    assert fault.detail("read_back") == "failed"
    assert decision.state is State.STOPPED


def test_read_back_of_an_unknown_output_is_internal() -> None:
    """A read-back for an output the config does not name is our own side's error: it is
    refused and stops with ``internal``."""
    rig = Rig()
    rig.bring_up()
    decision = rig.feed(OutputReadback(rig.now, "ghost", True, True))
    assert decision.refusals[0].reason is RefusalReason.UNKNOWN_OUTPUT
    assert "internal" in decision.latched_names
    assert decision.state is State.STOPPED


def test_only_startup_internal_and_shutdown_are_momentary() -> None:
    """SR-1.3, SR-2, SR-7.14: ``startup``, ``internal`` and ``shutdown`` fire and are clear at
    once (only their latch remains); every other cause lasts as long as its condition."""
    assert {k for k in CauseKind if k.momentary} == {
        CauseKind.STARTUP,
        CauseKind.INTERNAL,
        CauseKind.SHUTDOWN,
    }


@pytest.mark.parametrize(
    ("kind", "subject"),
    [
        ("startup", None),  # not a CauseKind
        (CauseKind.CLIENT_LOST, None),  # a client's cause names its client
        (CauseKind.STARTUP, "planner"),  # a cause of the whole supervisor names nothing
        (CauseKind.CLIENT_LOST, ""),
        (CauseKind.CLIENT_LOST, 7),
    ],
)
def test_a_cause_is_refused_unless_its_name_is_well_formed(kind: object, subject: object) -> None:
    """SR-2: a cause is named as in the records (``client_lost:planner``, ``startup``): a kind
    that is not one, a subject missing, unwanted, empty or not text is refused."""
    with pytest.raises(ValueError, match="cause"):
        Cause(kind, subject)  # type: ignore[arg-type]


def test_causes_sort_by_name() -> None:
    """SR-2: causes are listed in the order of their names, and a cause is not before itself."""
    names = [Cause(CauseKind.VSC_MODE, "remote"), Cause(CauseKind.CLIENT_LOST, "b")]
    names += [Cause(CauseKind.CLIENT_LOST, "a"), Cause(CauseKind.STARTUP)]
    assert [c.name for c in sorted(names)] == [
        "client_lost:a",
        "client_lost:b",
        "startup",
        "vsc_mode:remote",
    ]
    assert not Cause(CauseKind.STARTUP) < Cause(CauseKind.STARTUP)


def test_stop_active_is_an_active_stop_condition_alone() -> None:
    """SR-2, SR-3: a decision's ``stop_active`` is true while a stop cause's condition holds,
    and false for a stop that is only latched and for an active hold."""
    rig = Rig()
    rig.bring_up()
    rig.advance(10)
    assert not rig.hold().stop_active  # a hold is no stop
    rig.advance(10)
    rig.release(request=Request.HOLD)
    rig.advance(10)
    assert rig.estop().stop_active
    rig.advance(10)
    released = rig.release()
    assert released.latched_names == {"client_estop:planner"}
    assert not released.stop_active  # latched, its condition clear


def test_a_second_local_estop_names_its_caller() -> None:
    """SR-2.6, SR-7: a local e-stop while one is active keeps the stop and names the newer
    caller in the cause's details (an update of the cause, recorded)."""
    rig = Rig()
    rig.bring_up()
    rig.advance(10)
    first = rig.feed(LocalEstop(rig.now, ADMIN)).cause("local_estop")
    assert first is not None
    assert first.detail("caller") == ADMIN.name
    rig.advance(10)
    decision = rig.feed(LocalEstop(rig.now, NOBODY))
    second = decision.cause("local_estop")
    assert second is not None
    assert second.active
    assert second.detail("caller") == NOBODY.name
    assert decision.records


def test_a_local_release_without_a_local_estop_is_refused() -> None:
    """SR-2.6: releasing a local e-stop that is not there is refused by name
    (``nothing_to_release``) and changes nothing."""
    rig = Rig()
    rig.bring_up()
    rig.advance(10)
    decision = rig.feed(LocalRelease(rig.now, ADMIN))
    assert [r.reason for r in decision.refusals] == [RefusalReason.NOTHING_TO_RELEASE]
    assert decision.state is State.RUN
    assert not decision.records


@pytest.mark.parametrize("down", [LinkBroken, LinkClosed])
def test_a_link_that_went_down_refuses_the_vsc_until_it_opens_again(
    down: type[LinkBroken | LinkClosed],
) -> None:
    """SR-2.3, SR-2.2, SR-4.4: a link that broke or closed stops at once with
    ``transport_fault`` and ``vsc_link_lost`` (no heartbeat since), forgets the VSC's mode and
    its hold, and refuses VSC messages (``link_not_open``) until it opens again."""
    rig = Rig()
    rig.bring_up()
    rig.advance(10)
    assert "vsc_mode:local" in rig.vsc(LOCAL).active_names
    rig.advance(10)
    decision = rig.feed(down(rig.now, "unplugged"))
    assert decision.state is State.STOPPED
    assert {"transport_fault", "vsc_link_lost"} <= decision.active_names
    assert not any(name.startswith("vsc_mode:") for name in decision.active_names)
    lost = decision.cause("vsc_link_lost")
    assert lost is not None
    assert lost.detail("reason") == "no heartbeat since link open"
    rig.advance(10)
    refused = rig.vsc(LOCAL)
    assert [r.reason for r in refused.refusals] == [RefusalReason.LINK_NOT_OPEN]
    assert refused.active_names == decision.active_names
    assert not refused.records
