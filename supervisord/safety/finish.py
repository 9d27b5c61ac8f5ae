"""Step 6 of the safety core's full step: the frames to the VSC and the step's records.

Functions of the step (:class:`~supervisord.safety.step.Step`) and of what the core decided
in it, called by :meth:`~supervisord.safety.core.SafetyCore._finish` in the step's order:
:func:`link_frames` adds what goes to the VSC (the user heartbeat with its byte, key 85's
query, the display's frames; SR-5), :func:`step_records` makes the records (SR-7.1). The core
keeps the sequence number and charges the records to the step's user (SR-8.5).
"""

from __future__ import annotations

from supervisord.protocol.messages import UserHeartbeat
from supervisord.safety.causes import CauseState
from supervisord.safety.decision import CauseChange, Record, RecordNote
from supervisord.safety.display import DisplayStore
from supervisord.safety.events import Event
from supervisord.safety.prooftest import ProofTest
from supervisord.safety.step import Step
from supervisord.safety.transitions import State
from supervisord.safety.vsc import VscLink


def link_frames(
    step: Step,
    estop: int,
    *,
    urgent: bool,
    vsc: VscLink,
    proof: ProofTest,
    display: DisplayStore,
) -> None:
    """Add to ``step.frames`` what goes to the VSC at ``step.now``, on an open link: the user
    heartbeat with the byte ``estop`` when due, or at once when ``urgent`` (a new stop of
    ours, SR-5.2), key 85's query, then the display's frames."""
    now = step.now
    if not vsc.open:
        return
    if urgent:
        proof.abort()  # a new stop reaches the VSC at once, proof test or not
    # The proof test withholds the user heartbeat (SR-5.3).
    frames = vsc.frames(now, estop, urgent=urgent, withheld=proof.withholding)
    if frames and type(frames[0]) is UserHeartbeat:
        proof.sent(now)
    step.frames += frames
    step.frames.extend(display.due(now))


def step_records(
    step: Step,
    event: Event,
    *,
    sequence: int,
    previous: State,
    state: State,
    causes: tuple[CauseState, ...],
    changes: tuple[CauseChange, ...],
) -> tuple[Record, ...]:
    """The records of the step that moved ``previous`` to ``state`` with ``changes`` of the
    causes, numbered on from ``sequence``: one when the state or a cause changed or the step
    has a note; a proof test's outcome (taken from the step) is one of its own kind (SR-7.1)."""
    proof, step.proof_outcome = step.proof_outcome, None
    # A note of the event's own (a commissioning) and a proof test's outcome in one step are
    # two records: each kind is what its record is about (SR-7.1).
    proof_apart = proof if proof is not None and step.note is not None else None
    if proof is not None and step.note is None:
        step.note = (RecordNote.PROOFTEST, proof.text)  # a record even if nothing changed
    records: tuple[Record, ...] = ()
    if changes or previous is not state or step.note is not None:
        note, reason = step.note or (None, "")
        sequence += 1
        carried = None if proof_apart is not None else proof
        records = (
            Record(
                sequence=sequence,
                monotonic_ns=step.now,
                previous=previous,
                state=state,
                causes=causes,
                changes=changes,
                trigger=event,
                rearm=step.rearm,
                note=note,
                reason=reason,
                prooftest=carried,
            ),
        )
    if proof_apart is not None:
        sequence += 1
        records += (
            Record(
                sequence=sequence,
                monotonic_ns=step.now,
                previous=state,
                state=state,
                causes=causes,
                changes=(),
                trigger=event,
                rearm=None,
                note=RecordNote.PROOFTEST,
                reason=proof_apart.text,
                prooftest=proof_apart,
            ),
        )
    return records
