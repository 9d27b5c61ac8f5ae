"""Steps 1 and 3 of the safety core's full step: every lasting condition recomputed at ``now``.

Plain functions of the step (:class:`~supervisord.safety.step.Step`) and of the machines they
read, called by :class:`~supervisord.safety.core.SafetyCore` (its ``_refresh``) before the
event (time passes) and after it (the conditions). :func:`refresh` first moves the proof test
on (:func:`advance_proof`: start, abort, time out; docs/safety.md "The proof test"), then sets
every condition of the causes' book from the machines' conditions at ``now`` (SR-2, SR-3). The
core's own fact, the local e-stop's caller, and its state are arguments: the functions keep
nothing, so the core's attributes stay the state the exploration compares.
"""

from __future__ import annotations

from typing import Final

from supervisord.safety.battery import RemoteBattery
from supervisord.safety.book import CauseBook
from supervisord.safety.causes import Cause, CauseKind, caller_details, make_details
from supervisord.safety.clients import Clients
from supervisord.safety.events import Caller
from supervisord.safety.outputs import Outputs
from supervisord.safety.prooftest import USER_BITS, ProofTest, ProofTestPolicy
from supervisord.safety.step import Step
from supervisord.safety.transitions import State
from supervisord.safety.vsc import VscLink

VSC_WATCHDOG_UNTESTED: Final = Cause(CauseKind.VSC_WATCHDOG_UNTESTED)
LOCAL_ESTOP: Final = Cause(CauseKind.LOCAL_ESTOP)
FLEET_CONSOLE_LOST: Final = Cause(CauseKind.FLEET_CONSOLE_LOST)


def refresh(
    step: Step,
    *,
    state: State,
    local_estop: Caller | None,
    book: CauseBook,
    vsc: VscLink,
    proof: ProofTest,
    clients: Clients,
    outputs: Outputs,
    battery: RemoteBattery,
) -> None:
    """Recompute every lasting condition from the facts (SR-2, SR-3). A condition's
    details are built only when it holds: the book reads them only then."""
    now = step.now
    advance_proof(step, state=state, local_estop=local_estop, book=book, vsc=vsc, proof=proof)
    for cause, details in vsc.link_conditions(now):
        book.set(cause, details is not None, now, details or ())
    untested = proof.untested
    book.set(VSC_WATCHDOG_UNTESTED, untested, now, proof.details() if untested else ())
    book.sync(CauseKind.CLIENT_LOST, clients.lost(now), now)
    book.sync(CauseKind.CLIENT_ESTOP, clients.estops(), now)
    book.set(LOCAL_ESTOP, local_estop is not None, now, caller_details(local_estop))
    book.sync(CauseKind.OUTPUT_FAULT, outputs.faults(), now)
    book.sync(CauseKind.VSC_MODE, vsc.mode_hold(), now)
    book.sync(CauseKind.CLIENT_HOLD, clients.holds(), now)
    book.sync(CauseKind.FLEET_STOP, clients.fleet.stops(), now)  # SR-8.19
    lost = clients.fleet.console_lost(now)  # SR-8.21
    book.set(FLEET_CONSOLE_LOST, lost is not None, now, lost or ())
    if battery.cause is not None:  # SR-8.12: when watched
        words = battery.judge(now, arriving=step.arriving, taken_in=step.taken_in)
        details = make_details([("reason", words)]) if words is not None else ()
        book.set(battery.cause, words is not None, now, details)


def advance_proof(
    step: Step,
    *,
    state: State,
    local_estop: Caller | None,
    book: CauseBook,
    vsc: VscLink,
    proof: ProofTest,
) -> None:
    """Start, abort or time out the proof test (docs/safety.md "The proof test"). It runs
    only while STOPPED, with the VSC heard and nothing of ours asking it to stop (the
    heartbeat's byte at 0, so bits 6-7 are the watchdog's alone, PR-2.6)."""
    if proof.policy is ProofTestPolicy.OFF:
        return
    now = step.now
    heard = vsc.heard(now)
    stopped = state is State.STOPPED
    # SR-8.15: a required client not there yet is no reason to wait (its service may
    # start behind ``srcsctl wait-ready``, which waits for this test).
    calm = not book.user_estop(proof.quiet(stopped)) and local_estop is None
    if proof.running and not (heard and calm and stopped):
        proof.abort()  # our own stop must reach the VSC at once (SR-5.2)
    ready = heard and calm and stopped and vsc.estop_word & USER_BITS == 0
    proof.advance(now, ready, vsc.key85, vsc.mode)
    outcome = proof.take_outcome()
    if outcome is not None:
        step.proof_outcome = outcome
        if not outcome.passed and proof.policy is ProofTestPolicy.RECORD:
            # The record policy: a failure is a momentary stop, latched until a re-arm.
            book.pulse(
                Cause(CauseKind.VSC_WATCHDOG_UNTESTED),
                now,
                make_details([("observed", outcome.text)]),
            )
