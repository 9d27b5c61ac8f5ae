"""The one face every machine of the safety core shows it (docs/safety.md "The core").

The core composes machines (the link to the VSC, the clients, the record budget, the outputs,
the remote's battery and display, the proof test); each answers the same questions about a
view of the step (:class:`Seen`, built as ``view.View``), so that the canonical form
(``SafetyCore.canonical``), the next deadline (``deadline.py``) and the cheap path
(``cheap.py``) iterate over the machines instead of naming them one by one (SR-2.11, SR-9.4;
docs/verification.md "The time abstraction").

The core builds its view once (``SafetyCore._compose``): the machines live as long as the
core, and the cheap path, which answers most inputs, must not pay for a tuple per input
(SR-9.4; docs/performance.md "The cheap path").
"""

from __future__ import annotations

from typing import Protocol

from supervisord.safety.canonical import Canonical


class LinkSeen(Protocol):
    """What the other machines read of the link to the VSC: whether it is open, and the VSC's
    answer to key 85 (the display's frames and the proof test's limits)."""

    @property
    def open(self) -> bool: ...

    @property
    def key85(self) -> int | None: ...


class BudgetSeen(Protocol):
    """What the clients read of the record budget: when a user is within it again (a
    deferred end, SR-8.5)."""

    def free_at(self, uid: int | None, now: int) -> int | None: ...


class Seen(Protocol):
    """The view of the step as a machine reads it (``view.View`` is the one the core builds):
    the time asked about, the latest stop raised (the canonical form, SR-4.3), and of the
    others only what a machine's deadlines need. Named by these faces alone, so that no
    machine imports another through the view (one-way imports)."""

    @property
    def now(self) -> int: ...

    @property
    def last_stop_raised_ns(self) -> int | None: ...

    @property
    def vsc(self) -> LinkSeen: ...

    @property
    def budget(self) -> BudgetSeen: ...


class Machine(Protocol):
    """One machine of the core, as the core composes it."""

    def canonical(self, view: Seen) -> Canonical:
        """Its facts, as flat ``(name, value)`` pairs, and its clocks at ``view.now``
        (docs/verification.md): what the exploration compares states by."""
        ...

    def next_deadline(self, view: Seen) -> int | None:
        """The earliest time after ``view.now`` at which time alone moves it, or ``None``
        (SR-2.11: the core's deadline is the earliest of these)."""
        ...

    def can_move(self) -> bool:
        """Whether time can ever move it between its deadlines, by its configuration: asked
        once, when the core composes its machines; only those that can are asked
        :meth:`moving` for each input (SR-9.4)."""
        ...

    def moving(self) -> bool:
        """Whether time moves it now between its deadlines (a proof test running, a deferred
        end, an output braking): then the cheap path declines every input (SR-9.4). Read
        from its own state alone: asked for every input the cheap path sees."""
        ...

    def due_by(self, view: Seen) -> bool:
        """Whether one of its deadlines, the user heartbeat's aside, falls at or before
        ``view.now``: then the full step has work beyond sending the beat (SR-9.4)."""
        ...
