"""The listener's asks answered, one at a time, in one place for the loop and its tests.

A listener's work that needs the loop comes back as :data:`~supervisord.daemon.listener.Asks`
(an event to feed, a look at the loop, the outputs' off checked, frames to send). :func:`serve`
takes each ask in turn and sends back its answer before the work goes on (SR-6: an event's
decision is applied before the next ask), with what answers it given as a narrow face,
:class:`Answers` (the daemon's loop gives its own; a test gives a core and a fixed status), so
the order of the asks and the kind of each answer are decided here once, and a test drives
this code, not a copy of it.

The listener's side asks through :func:`look` and :func:`check_off`, which narrow the answer
to its type: a loop that answered with something else yields ``None``, which the listener
turns into a typed refusal (``unavailable``) rather than raising in the loop (SR-6, SR-8).
"""

from __future__ import annotations

from collections.abc import Generator
from typing import Protocol

from supervisord.daemon.listener import Answer, Ask, Asks, CheckOff, Look, Send, Snapshot
from supervisord.daemon.offcheck import OffCheck
from supervisord.protocol.messages import Message
from supervisord.safety.decision import Decision
from supervisord.safety.events import Event

__all__ = ["Answers", "check_off", "look", "serve"]


class Answers(Protocol):
    """What answers each kind of ask."""

    def decide(self, event: Event) -> Decision:
        """The event fed to the core and its decision applied (outputs, frames, records,
        pushes: SR-6); the decision is the answer."""

    def look(self, now: int) -> Snapshot:
        """The loop's status and stop times at ``now`` (a ``status``, a ``stoptest``)."""

    def check_off(self, now: int) -> OffCheck:
        """Every output that is off written off again and read back (SR-8.20)."""

    def send(self, frames: tuple[Message, ...], now: int) -> None:
        """``frames`` sent to the VSC (a commissioning's key-85 requests)."""


def serve(work: Asks | None, answers: Answers) -> None:
    """Answer every ask of ``work`` in its order (``None``: no work)."""
    if work is None:
        return
    answer: Answer = None
    while True:
        try:
            asked = work.send(answer)
        except StopIteration:
            return
        if isinstance(asked, Look):
            answer = answers.look(asked.now)
        elif isinstance(asked, CheckOff):
            answer = answers.check_off(asked.now)
        elif isinstance(asked, Send):
            answer = None
            answers.send(asked.frames, asked.now)
        else:
            answer = answers.decide(asked)


def look(now: int) -> Generator[Ask, Answer, Snapshot | None]:
    """Ask to look at the loop at ``now``: its snapshot, ``None`` if the answer was none."""
    answer = yield Look(now)
    return answer if isinstance(answer, Snapshot) else None


def check_off(now: int) -> Generator[Ask, Answer, OffCheck | None]:
    """Ask for the outputs' off checked at ``now``: the check, ``None`` if the answer was none."""
    answer = yield CheckOff(now)
    return answer if isinstance(answer, OffCheck) else None
