"""The demo's NEXT line (``supervisord/cli/demo_view.py``): the one thing to do, and never a
takeover the supervisor would refuse as too early (docs/srcsctl.md "The demo")."""

from __future__ import annotations

from supervisord.api.status import Cause, StateReport
from supervisord.cli.demo_view import next_step
from supervisord.vocabulary import Cause as Named
from supervisord.vocabulary import CauseKind, Severity, State

PLUGGED = {"plugged": True, "remote_estop": False}
MS = 1_000_000


def _state(state: State, *causes: Cause) -> StateReport:
    return StateReport(state=state, mono_ns=0, causes=causes, outputs={}, heartbeat_estop=1)


def _stopped(*causes: Cause) -> StateReport:
    return _state(State.STOPPED, *causes)


def _cause(kind: CauseKind, *, active: bool, cleared_ns: int | None = None) -> Cause:
    return Cause(
        name=Named(kind),
        severity=Severity.STOP,
        active=active,
        latched=True,
        raised_ns=0,
        cleared_ns=cleared_ns,
    )


def test_next_waits_for_the_proof_test_and_the_rearm_hold() -> None:
    """SR-4: while a stop condition holds, NEXT says what it waits for; once none does, it
    waits out the re-arm hold from the last clearing (a takeover before it is refused), then
    says to take over."""
    proving = _cause(CauseKind.VSC_WATCHDOG_UNTESTED, active=True)
    assert next_step(PLUGGED, _stopped(proving), now_ns=0, hold_ms=500) == (
        "wait: the supervisor is proving the VSC's watchdog (about 1 s)"
    )
    status = _stopped(_cause(CauseKind.VSC_ESTOP, active=False, cleared_ns=1_000 * MS))
    assert next_step(PLUGGED, status, now_ns=1_499 * MS, hold_ms=500).startswith(
        "wait: the stop conditions must stay clear for 500 ms"
    )
    assert next_step(PLUGGED, status, now_ns=1_500 * MS, hold_ms=500).startswith(
        "press [t] to take over"
    )


def test_next_names_what_the_operator_must_undo_first() -> None:
    """A cut link and a pressed e-stop come before anything else; RUN and HOLD say what the
    keys do there."""
    assert next_step({"plugged": False}, _stopped()).startswith("the link is cut: press [l]")
    pressed = {"plugged": True, "remote_estop": True}
    assert next_step(pressed, _stopped()).startswith("the remote's e-stop is pressed: press [e]")
    assert next_step(PLUGGED, _state(State.RUN)).startswith("RUN, the outputs are on")
    assert next_step(PLUGGED, _state(State.HOLD)).startswith("HOLD (motion off, power on)")
    assert next_step(PLUGGED, None) == "wait: the supervisor is not answering yet"
