"""What one full step of the safety core decides as it goes (docs/safety.md "The core").

A :class:`Step` is made at the start of every full step of
:class:`~supervisord.safety.core.SafetyCore` and handed to what needs it: the handlers add
their refusals and notes to it, the conditions what the step took in, the re-arm check its
re-arm, the frames what goes to the VSC; the step's :class:`~supervisord.safety.decision.
Decision` is made from it. It lives for one step only, so nothing of one step can leak into
the next (SR-1: a decision is a function of the state and the input), and it is no part of the
core's state (``SafetyCore.canonical``, the snapshot).
"""

from __future__ import annotations

from dataclasses import dataclass, field

from supervisord.protocol.messages import Message
from supervisord.safety.budget import Uid
from supervisord.safety.decision import Rearm, RecordNote, Refusal, RefusalReason
from supervisord.safety.prooftest import Outcome


@dataclass(slots=True)
class Step:
    """One step's own values, from its input to its decision."""

    now: int
    frames: list[Message] = field(default_factory=list)
    refusals: list[Refusal] = field(default_factory=list)
    rearm: Rearm | None = None  # a re-arm accepted in this step (SR-4)
    note: tuple[RecordNote, str] | None = None  # what the step's record is about, if not a change
    charged: tuple[Uid] | None = None  # whom the step's records are charged to (SR-8.5)
    limited: bool = False  # the input's user is past its record budget (SR-8.5)
    proof_outcome: Outcome | None = None  # a proof test finished in this step, for its record
    # SR-8.12: the input is a watched remote status, and it has been taken in (a report is
    # taken in before the old one is judged stale).
    arriving: bool = False
    taken_in: bool = False

    def refuse(self, reason: RefusalReason, detail: str, event: object) -> None:
        self.refusals.append(Refusal(reason, detail, event))

    def refuse_if(self, refusal: Refusal | None) -> None:
        if refusal is not None:
            self.refusals.append(refusal)
