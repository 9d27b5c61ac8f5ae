"""The daemon's exit as the core sees it: the ``shutdown`` input (SR-7.14)."""

from __future__ import annotations

from supervisord.safety import ChangeKind, Shutdown, State
from tests.safety.rig import Rig


def test_a_shutdown_in_run_is_a_stop_with_one_record() -> None:
    """SR-7.14: the shutdown input in RUN stops (every output off) with one ``state_change``
    record RUN -> STOPPED that raises ``shutdown:SIGTERM``, latched and momentary."""
    rig = Rig()
    rig.bring_up()
    rig.advance(10)
    decision = rig.feed(Shutdown(rig.now, "SIGTERM"))
    assert decision.state is State.STOPPED
    assert not any(decision.outputs.values())
    (record,) = decision.records
    assert (record.previous, record.state) == (State.RUN, State.STOPPED)
    assert [(c.cause.name, c.kind) for c in record.changes] == [
        ("shutdown:SIGTERM", ChangeKind.RAISED)
    ]
    state = decision.cause("shutdown:SIGTERM")
    assert state is not None
    assert state.latched
    assert not state.active


def test_a_shutdown_in_hold_is_a_stop() -> None:
    """SR-7.14: in HOLD the shutdown input is a stop too: HOLD -> STOPPED, naming SIGHUP."""
    rig = Rig()
    rig.bring_up()
    rig.advance(10)
    assert rig.hold().state is State.HOLD
    rig.advance(10)
    decision = rig.feed(Shutdown(rig.now, "SIGHUP"))
    (record,) = decision.records
    assert (record.previous, record.state) == (State.HOLD, State.STOPPED)
    assert "shutdown:SIGHUP" in decision.latched_names


def test_a_shutdown_in_stopped_is_a_cause_raised() -> None:
    """SR-7.14: every exit is recorded: STOPPED stays STOPPED with a record that raises
    ``shutdown:SIGINT`` (a cause raised, not a change of state)."""
    rig = Rig()
    rig.stopped_and_cleared()
    rig.advance(10)
    decision = rig.feed(Shutdown(rig.now, "SIGINT"))
    (record,) = decision.records
    assert (record.previous, record.state) == (State.STOPPED, State.STOPPED)
    assert record.note is None
    assert [c.cause.name for c in record.changes] == ["shutdown:SIGINT"]


def test_a_shutdown_without_a_reason_is_still_named() -> None:
    """SR-7.14: a shutdown input with an empty reason is ``shutdown:unknown``, never a
    refusal or an ``internal`` (a cause needs a non-empty subject)."""
    rig = Rig()
    rig.bring_up()
    decision = rig.feed(Shutdown(rig.now, ""))
    assert decision.state is State.STOPPED
    assert "shutdown:unknown" in decision.latched_names
    assert "internal" not in decision.latched_names
