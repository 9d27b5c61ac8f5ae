"""The transition table (SR-1, SR-4) and the core's refusal to ever raise."""

from __future__ import annotations

import dataclasses
import itertools
from typing import Any

import pytest

from supervisord.protocol.messages import UserHeartbeat
from supervisord.safety import TABLE, IllegalTransition, RefusalReason, SafetyCore, Situation, State
from supervisord.safety import cheap as cheap_module
from supervisord.safety.book import CauseBook
from supervisord.safety.clients import Clients
from supervisord.safety.transitions import Transition, _index, next_state
from tests.safety.rig import ROBOT, Rig

ILLEGAL = {
    (State.STOPPED, Situation.HOLD),
    (State.STOPPED, Situation.CLEAR),
    (State.HOLD, Situation.REARMED_HOLD),
    (State.HOLD, Situation.REARMED_CLEAR),
    (State.RUN, Situation.REARMED_HOLD),
    (State.RUN, Situation.REARMED_CLEAR),
}


def test_table_covers_exactly_the_legal_moves() -> None:
    """Every (state, situation) pair has exactly one row, except the illegal ones: leaving
    STOPPED without a re-arm, and re-arming outside STOPPED."""
    pairs = [(row.source, row.situation) for row in TABLE]
    assert len(pairs) == len(set(pairs))
    assert set(pairs) | ILLEGAL == set(itertools.product(State, Situation))
    assert not set(pairs) & ILLEGAL


def test_the_index_is_the_table_and_refuses_two_rows_for_one_move() -> None:
    """SR-1: ``next_state`` answers from an index of the table, one target per move, and a
    table with two rows for one move (even if they agree) contradicts itself and is refused."""
    assert _index(TABLE) == {(row.source, row.situation): row.target for row in TABLE}
    again = Transition(State.RUN, Situation.CLEAR, State.HOLD, "a contradiction")
    with pytest.raises(IllegalTransition) as refused:
        _index((*TABLE, again))
    assert (refused.value.state, refused.value.situation) == (State.RUN, Situation.CLEAR)
    with pytest.raises(IllegalTransition):
        _index((*TABLE, TABLE[0]))


@pytest.mark.parametrize(("state", "situation"), sorted(ILLEGAL, key=str))
def test_illegal_move_raises_a_typed_error(state: State, situation: Situation) -> None:
    """``next_state`` raises ``IllegalTransition`` for a pair with no row."""
    with pytest.raises(IllegalTransition):
        next_state(state, situation)


def test_every_stop_goes_to_stopped_and_only_rearms_leave_it() -> None:
    """A stop leads to STOPPED from every state; only re-arm situations lead out of it."""
    for row in TABLE:
        if row.situation is Situation.STOP:
            assert row.target is State.STOPPED
        if row.source is State.STOPPED and row.target is not State.STOPPED:
            assert row.situation in {Situation.REARMED_HOLD, Situation.REARMED_CLEAR}


def test_core_turns_an_illegal_transition_into_internal(monkeypatch: pytest.MonkeyPatch) -> None:
    """If the table ever refuses a move, the core stops with ``internal`` instead of raising."""
    rig = Rig()
    rig.bring_up()
    real = next_state

    def refusing(state: State, situation: Situation) -> State:
        if situation is not Situation.STOP:
            raise IllegalTransition(state, situation)
        return real(state, situation)

    monkeypatch.setattr("supervisord.safety.core.next_state", refusing)
    monkeypatch.setattr("supervisord.safety.cheap.next_state", refusing)  # its fixed point
    rig.advance(10)
    # A client's command takes the full step (the table is asked at each full step's end,
    # so a tick of the cheap path still answers from the state the real table left).
    decision = rig.command()
    assert decision.state is State.STOPPED
    internal = decision.cause("internal")
    assert internal is not None
    assert internal.latched
    assert "no transition from RUN" in (internal.detail("reason") or "")


def test_a_step_that_ends_off_the_tables_fixed_point_leaves_the_next_input_to_the_full_step(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    """SR-1, SR-9.4: the cheap path answers only after a step that ended where the table keeps
    the state with nothing changing; were the table ever to say otherwise at a step's end,
    the next input is decided by the full step, every condition recomputed."""
    rig = Rig()
    rig.bring_up()
    real = next_state

    def moving(state: State, situation: Situation) -> State:
        return State.HOLD if state is State.RUN else real(state, situation)

    monkeypatch.setattr("supervisord.safety.cheap.next_state", moving)  # only its fixed point
    rig.advance(10)
    assert rig.command().state is State.RUN  # a full step, ending off the patched fixed point
    refreshes = rig.count_refreshes()
    rig.advance(10)
    assert rig.tick().state is State.RUN
    assert refreshes == [rig.now, rig.now]  # step 1 and step 3 of the full step


def test_a_step_that_ends_where_the_table_refuses_to_stay_leaves_the_next_input_to_the_full_step(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    """SR-1, SR-9.4: were the table ever to refuse the row of staying where a step ended (no
    fixed point at all), the next input is decided by the full step, every condition
    recomputed, not by the cheap path."""
    rig = Rig()
    rig.bring_up()

    def refusing(state: State, situation: Situation) -> State:
        raise IllegalTransition(state, situation)

    monkeypatch.setattr("supervisord.safety.cheap.next_state", refusing)  # only its fixed point
    rig.advance(10)
    assert rig.command().state is State.RUN  # a full step, ending where the table refuses
    refreshes = rig.count_refreshes()
    rig.advance(10)
    assert rig.tick().state is State.RUN
    assert refreshes == [rig.now, rig.now]  # step 1 and step 3 of the full step


def test_core_never_raises_when_its_own_code_fails(monkeypatch: pytest.MonkeyPatch) -> None:
    """A bug inside the core becomes the ``internal`` cause and a refusal, never an exception."""
    rig = Rig()
    rig.bring_up()

    def broken(self: SafetyCore, event: object, step: object) -> None:
        raise RuntimeError("boom")

    monkeypatch.setattr(SafetyCore, "_apply", broken)
    rig.advance(10)
    decision = rig.command()  # a zero command takes the full step (a heartbeat is cheap)
    assert decision.state is State.STOPPED
    assert not any(decision.outputs.values())
    assert decision.refusals[0].reason is RefusalReason.INTERNAL_ERROR
    assert "internal" in decision.latched_names


@pytest.mark.parametrize(("owner", "name"), [(SafetyCore, "_finish"), (CauseBook, "pulse")])
def test_core_survives_even_when_the_fail_safe_fails(
    monkeypatch: pytest.MonkeyPatch, owner: type, name: str
) -> None:
    """When even the normal fail-safe path fails (its record, or its very first act, the
    ``internal`` cause), a bare all-off STOPPED decision comes back, and the core is STOPPED."""
    rig = Rig()
    rig.bring_up()

    def broken(*args: object) -> None:
        raise RuntimeError("boom")

    monkeypatch.setattr(SafetyCore, "_apply", broken)
    monkeypatch.setattr(owner, name, broken)
    rig.advance(10)
    decision = rig.command()  # a zero command takes the full step (a heartbeat is cheap)
    assert decision.state is State.STOPPED
    assert rig.core.state is State.STOPPED  # the core's own state says so too
    assert not any(decision.outputs.values())
    assert decision.heartbeat_estop == 1
    assert decision.frames == (UserHeartbeat(1),)  # SR-5: the stop reaches the VSC at once
    assert decision.next_deadline > decision.now


def test_the_last_line_of_defence_sends_no_heartbeat_on_a_closed_link(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    """SR-2.3, SR-5: when even the fail-safe path fails, the bare decision asks for a user
    heartbeat only on an open serial link: nothing can be sent on a closed one."""
    rig = Rig()  # the link not opened yet

    def broken(*args: object) -> None:
        raise RuntimeError("boom")

    monkeypatch.setattr(SafetyCore, "_apply", broken)
    monkeypatch.setattr(SafetyCore, "_finish", broken)
    rig.advance(10)
    decision = rig.connect(name=None)
    assert decision.state is State.STOPPED
    assert decision.frames == ()


def _fails_once(monkeypatch: pytest.MonkeyPatch, name: str, owner: type = SafetyCore) -> None:
    """Make ``owner.<name>`` (the core's or one of its machines') raise the first time it is
    called, as a bug of the core would, and work from then on."""
    real = getattr(owner, name)
    calls = []

    def once(self: object, *args: object) -> object:
        calls.append(name)
        if len(calls) == 1:
            raise RuntimeError("boom")
        return real(self, *args)

    monkeypatch.setattr(owner, name, once)


def _fails_once_in_module(monkeypatch: pytest.MonkeyPatch, module: object, name: str) -> None:
    """Make the function ``module.<name>`` raise the first time it is called, as a bug of the
    core would, and work from then on."""
    real = getattr(module, name)
    calls = []

    def once(*args: object) -> object:
        calls.append(name)
        if len(calls) == 1:
            raise RuntimeError("boom")
        return real(*args)

    monkeypatch.setattr(module, name, once)


def test_after_a_failure_in_a_step_the_next_input_sees_every_condition(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    """SR-2.9, SR-2.5, SR-5: a step that fails half way stops with ``internal`` with its event
    applied but the conditions not recomputed; the next input recomputes them (no shortcut
    trusts a decision the core failed on), so a client's e-stop of that step is a cause and
    sets the user heartbeat's e-stop byte at once."""
    rig = Rig()
    rig.bring_up()
    _fails_once(monkeypatch, "end_due", Clients)  # step 2 is done, step 3 not yet
    rig.advance(10)
    failed = rig.estop()
    assert "internal" in failed.latched_names
    assert "client_estop:planner" not in failed.active_names
    rig.advance(10)
    after = rig.tick()
    assert "client_estop:planner" in after.active_names
    assert after.heartbeat_estop == 1
    assert after.state is State.STOPPED


def test_after_a_failure_in_the_cheap_path_the_next_input_takes_the_full_step(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    """SR-2.9, docs/performance.md "The cheap path": the cheap path answers only after a step
    that ended normally; once the core failed on an input (here inside the cheap path itself),
    the next input is decided by the full step, every condition recomputed."""
    rig = Rig()
    rig.bring_up()
    _fails_once_in_module(monkeypatch, cheap_module, "again")  # only the cheap path asks it
    rig.advance(10)
    failed = rig.tick()
    assert failed.state is State.STOPPED
    assert "internal" in failed.latched_names
    refreshes = rig.count_refreshes()
    rig.advance(10)
    after = rig.tick()
    assert refreshes == [rig.now, rig.now]  # step 1 and step 3 of the full step
    assert after.state is State.STOPPED


def test_a_rearm_after_a_failed_fail_safe_is_refused(monkeypatch: pytest.MonkeyPatch) -> None:
    """SR-4.1, SR-2.9: when the fail-safe could not even latch ``internal`` (the last line of
    defence left the core STOPPED with nothing latched), a local reset is still refused:
    nothing latched is no evidence that stop conditions were clear for the hold time; the
    table's refusal of STOPPED without a latch then latches ``internal``."""
    rig = Rig(dataclasses.replace(ROBOT, local_reset=True))
    rig.bring_up()
    real = CauseBook.pulse
    calls: list[int] = []

    def pulse_fails_once(book: CauseBook, *args: Any) -> None:
        calls.append(1)
        if len(calls) == 1:
            raise RuntimeError("boom")
        real(book, *args)

    monkeypatch.setattr(CauseBook, "pulse", pulse_fails_once)
    _fails_once(monkeypatch, "_apply")
    rig.advance(10)
    bare = rig.command()
    assert bare.state is State.STOPPED
    assert bare.latched_names == set()
    rig.advance(10)
    refused = rig.reset()
    assert [(r.reason, r.detail) for r in refused.refusals] == [
        (RefusalReason.HOLD_TIME_NOT_ELAPSED, "clear for 0 ms of 500 ms")
    ]
    assert refused.state is State.STOPPED
    assert "internal" in refused.latched_names


def test_input_that_is_not_an_event_is_refused() -> None:
    """Anything that is not a safety event is refused by name and changes nothing."""
    rig = Rig()
    rig.bring_up()
    decision = rig.core.handle("reset please")  # type: ignore[arg-type]
    assert decision.refusals[0].reason is RefusalReason.NOT_AN_EVENT
    assert decision.state is State.RUN
