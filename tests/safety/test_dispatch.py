"""The core's step 2 is a table from event type to handler: none is missing, none is extra."""

from __future__ import annotations

import inspect
from dataclasses import dataclass

from supervisord.safety import RefusalReason, State, Tick
from supervisord.safety.core import _HANDLERS, SafetyCore
from supervisord.safety.events import EVENT_TYPES
from tests.safety.rig import Rig


def test_every_event_type_has_a_handler_and_the_table_has_no_other_key() -> None:
    """SR-2.9: every input event type the core accepts has its handler in the dispatch table, so
    a new event added to ``Event`` without one fails here instead of being ignored in silence."""
    missing = [t.__name__ for t in EVENT_TYPES if t not in _HANDLERS]
    assert missing == []
    extra = [t.__name__ for t in _HANDLERS if t not in EVENT_TYPES]
    assert extra == []


def test_every_handler_is_a_method_of_the_core_taking_the_event_and_the_step() -> None:
    """SR-2.9: each handler in the table is the core's own method with the uniform signature
    ``(self, event, step)`` the dispatch calls it with (``step``: the step's own values, its
    ``now`` among them)."""
    for event_type, handler in _HANDLERS.items():
        assert getattr(SafetyCore, handler.__name__) is handler, event_type.__name__
        assert list(inspect.signature(handler).parameters) == ["self", "event", "step"], (
            handler.__name__
        )


@dataclass(frozen=True, slots=True)
class _StrayTick(Tick):
    """An event subclass the table has no row for: what a forgotten handler looks like."""


def test_an_event_without_a_handler_stops_with_internal() -> None:
    """SR-2.9: an event of a type with no handler is not dropped: the core refuses it as an
    internal error and stops with ``internal`` (fail safe), and keeps answering afterwards."""
    rig = Rig()
    rig.bring_up()
    assert rig.state is State.RUN
    decision = rig.feed(_StrayTick(rig.now))
    assert decision.state is State.STOPPED
    assert "internal" in decision.latched_names
    assert [r.reason for r in decision.refusals] == [RefusalReason.INTERNAL_ERROR]
    assert "_StrayTick" in decision.refusals[0].message
    rig.advance(10)
    assert rig.vsc().state is State.STOPPED  # still deciding, and the stop stays latched
