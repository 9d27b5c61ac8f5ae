"""THE transition table of the supervisor (SR-1, SR-4).

The core reduces everything it knows to one :class:`Situation` and asks :func:`next_state`
for the state that follows from the current one. Every legal move is a row of :data:`TABLE`;
anything else raises :class:`IllegalTransition`, which the core turns into the ``internal``
stop cause. ``docs/safety.md`` carries a diagram generated from this table
(``python -m supervisord.safety.diagram``); a test fails when the two disagree.
"""

from __future__ import annotations

import enum
from dataclasses import dataclass

from supervisord.errors import SrcsError
from supervisord.vocabulary import State


class Situation(enum.Enum):
    """What the causes add up to at one moment; the ``label`` names it in the diagram."""

    STOP = "stop cause active or latched"  # SR-2: every stop cause latches
    REARMED_HOLD = "valid re-arm, a hold cause active"  # SR-4 then SR-3
    REARMED_CLEAR = "valid re-arm, no hold cause"  # SR-4
    HOLD = "hold cause active"  # SR-3
    CLEAR = "no stop and no hold cause"

    @property
    def label(self) -> str:
        return self.value


@dataclass(frozen=True, slots=True)
class Transition:
    """One row: in ``source``, when ``situation`` holds, go to ``target``."""

    source: State
    situation: Situation
    target: State
    rule: str  # the requirement IDs (docs/requirements.md) the row implements


S, H, R = State.STOPPED, State.HOLD, State.RUN

TABLE: tuple[Transition, ...] = (
    # STOPPED is left only through a valid re-arm (SR-4); it never ends on its own (SR-1.3).
    Transition(S, Situation.STOP, S, "SR-1.3, SR-2"),
    Transition(S, Situation.REARMED_HOLD, H, "SR-4"),
    Transition(S, Situation.REARMED_CLEAR, R, "SR-4"),
    # From HOLD and RUN any stop cause stops at once (SR-2); holds come and go by themselves (SR-3).
    Transition(H, Situation.STOP, S, "SR-2"),
    Transition(H, Situation.HOLD, H, "SR-3"),
    Transition(H, Situation.CLEAR, R, "SR-3"),
    Transition(R, Situation.STOP, S, "SR-2"),
    Transition(R, Situation.HOLD, H, "SR-3"),
    Transition(R, Situation.CLEAR, R, "SR-1.1"),
)
"""Every legal (state, situation) -> state move. Missing pairs are illegal: STOPPED with no
latch and no re-arm, and a re-arm outside STOPPED."""


class IllegalTransition(SrcsError):
    """The core reached a (state, situation) pair the table has no row for: our own bug.

    The core converts it into the ``internal`` stop cause; it never escapes ``handle``.
    """

    def __init__(self, state: State, situation: Situation) -> None:
        self.state, self.situation = state, situation
        super().__init__(f"no transition from {state.name} when {situation.label}")


def _index(table: tuple[Transition, ...]) -> dict[tuple[State, Situation], State]:
    index: dict[tuple[State, Situation], State] = {}
    for row in table:
        key = (row.source, row.situation)
        if key in index:
            raise IllegalTransition(*key)  # two rows for one move: the table contradicts itself
        index[key] = row.target
    return index


_INDEX = _index(TABLE)


def next_state(state: State, situation: Situation) -> State:
    """The state that follows ``state`` in ``situation``; raises :class:`IllegalTransition`."""
    try:
        return _INDEX[state, situation]
    except KeyError:
        raise IllegalTransition(state, situation) from None


__all__ = ["TABLE", "IllegalTransition", "Situation", "State", "Transition", "next_state"]
