"""The book of causes keeps the latch rule in one place (SR-2, SR-3, SR-4): what it keeps of a
momentary cause, what a re-arm releases, and which entries count as a hold. The core reaches
these rules only along its own paths; here each is stated once, for the book itself."""

from __future__ import annotations

from supervisord.safety.book import CauseBook
from supervisord.safety.causes import Cause, CauseKind
from supervisord.safety.decision import CauseChange, ChangeKind
from tests.safety.rig import START_NS

ESTOP = Cause(CauseKind.CLIENT_ESTOP, "planner")
HOLD = Cause(CauseKind.CLIENT_HOLD, "planner")


def test_a_momentary_stop_stays_latched_and_a_momentary_hold_leaves_nothing() -> None:
    """SR-2, SR-3: a stop that fires for an instant stays in the book, clear and latched, until
    a re-arm; a hold that fires for an instant clears by itself and leaves no entry."""
    book = CauseBook()
    book.pulse(Cause(CauseKind.INTERNAL), START_NS)
    book.pulse(HOLD, START_NS)
    ((cause, active, latched),) = [(s.name, s.active, s.latched) for s in book.snapshot()]
    assert (cause, active, latched) == ("internal", False, True)
    assert not book.any_hold()
    assert [(ch.cause, ch.kind) for ch in book.take_changes()] == [
        (Cause(CauseKind.INTERNAL), ChangeKind.RAISED),
        (HOLD, ChangeKind.RAISED),
    ]


def test_a_rearm_keeps_the_latch_of_a_stop_whose_condition_is_active() -> None:
    """SR-4.1: a re-arm releases the latch of a stop whose condition is clear, never of one
    whose condition still holds, and leaves an active hold alone."""
    book = CauseBook()
    book.set(ESTOP, True, START_NS)
    book.pulse(Cause(CauseKind.INTERNAL), START_NS)
    book.set(HOLD, True, START_NS)
    book.take_changes()
    book.release_latches()
    assert [(s.name, s.active, s.latched) for s in book.snapshot()] == [
        ("client_estop:planner", True, True),
        ("client_hold:planner", True, False),
    ]
    assert book.take_changes() == (CauseChange(Cause(CauseKind.INTERNAL), ChangeKind.RELEASED),)


def test_only_an_active_hold_is_a_hold() -> None:
    """SR-3: a stop, active or latched, is not a hold; a hold counts while its condition
    holds and not after it cleared."""
    book = CauseBook()
    book.set(ESTOP, True, START_NS)
    assert not book.any_hold()
    book.set(ESTOP, False, START_NS + 1)
    assert not book.any_hold()
    book.set(HOLD, True, START_NS + 2)
    assert book.any_hold()
    book.set(HOLD, False, START_NS + 3)
    assert not book.any_hold()
