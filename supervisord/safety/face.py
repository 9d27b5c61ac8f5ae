"""The one face every machine of the safety core shows it (docs/safety.md "The core").

The core composes machines (the link to the VSC, the clients, the record budget, the outputs,
the remote's battery and display, the proof test); each answers the same four questions about
a :class:`View` of the step, so that the canonical form (``SafetyCore.canonical``), the next
deadline (``deadline.py``) and the cheap path (``cheap.py``) iterate over the machines instead
of naming them one by one (SR-2.11, SR-9.4; docs/verification.md "The time abstraction").
"""

from __future__ import annotations

from typing import TYPE_CHECKING, NamedTuple, Protocol

from supervisord.safety.canonical import Canonical

if TYPE_CHECKING:
    from supervisord.safety.battery import RemoteBattery
    from supervisord.safety.budget import RecordBudget
    from supervisord.safety.clients import Clients
    from supervisord.safety.display import DisplayStore
    from supervisord.safety.outputs import Outputs
    from supervisord.safety.prooftest import ProofTest
    from supervisord.safety.vsc import VscLink


class View(NamedTuple):
    """What a machine may read of the step and of the other machines, at ``now``. A tuple:
    made for every input the cheap path answers, so as cheap to make as two calls (SR-9.4)."""

    now: int
    key85: int | None  # the VSC's answer to key 85 (the proof test's wait for it; SR-5.3)
    link_open: bool  # the display's frames and the proof test's limits need the link
    budget: RecordBudget  # when a user's deferred end may come (SR-8.5)
    last_stop_raised_ns: int | None = None  # the takeover's run is ordered against it (SR-4.3)


class Machine(Protocol):
    """One machine of the core, as the core composes it."""

    def canonical(self, view: View) -> Canonical:
        """Its facts, as flat ``(name, value)`` pairs, and its clocks at ``view.now``
        (docs/verification.md): what the exploration compares states by."""
        ...

    def next_deadline(self, view: View) -> int | None:
        """The earliest time after ``view.now`` at which time alone moves it, or ``None``
        (SR-2.11: the core's deadline is the earliest of these)."""
        ...

    def moving(self, view: View) -> bool:
        """Whether time moves it between its deadlines (a proof test running, a deferred end,
        an output braking): then the cheap path declines every input (SR-9.4)."""
        ...

    def due_by(self, view: View) -> bool:
        """Whether one of its deadlines, the user heartbeat's aside, falls at or before
        ``view.now``: then the full step has work beyond sending the beat (SR-9.4)."""
        ...


class Machines(NamedTuple):
    """The core's machines, made by the core when a step needs them (never kept: the
    exploration copies the core attribute by attribute, and a tuple would be shared). Iterated
    as :class:`Machine` wherever the core composes them; named only where an input speaks to
    one of them (its handler)."""

    vsc: VscLink
    clients: Clients
    budget: RecordBudget
    outputs: Outputs
    battery: RemoteBattery
    display: DisplayStore
    proof: ProofTest

    def view(self, now: int, last_stop_raised_ns: int | None = None) -> View:
        """The view of the step at ``now``."""
        vsc = self.vsc
        return View(now, vsc.key85, vsc.open, self.budget, last_stop_raised_ns)
