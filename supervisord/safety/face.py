"""The one face every machine of the safety core shows it (docs/safety.md "The core").

The core composes machines (the link to the VSC, the clients, the record budget, the outputs,
the remote's battery and display, the proof test); each answers the same questions about a
:class:`View` of the step, so that the canonical form (``SafetyCore.canonical``), the next
deadline (``deadline.py``) and the cheap path (``cheap.py``) iterate over the machines instead
of naming them one by one (SR-2.11, SR-9.4; docs/verification.md "The time abstraction").

The core builds its :class:`View` once (``SafetyCore._compose``): the machines live as long as
the core, and the cheap path, which answers most inputs, must not pay for a tuple per input
(SR-9.4; docs/performance.md "The cheap path").
"""

from __future__ import annotations

from typing import TYPE_CHECKING, Protocol

from supervisord.safety.canonical import Canonical

if TYPE_CHECKING:
    from supervisord.safety.battery import RemoteBattery
    from supervisord.safety.budget import RecordBudget
    from supervisord.safety.clients import Clients
    from supervisord.safety.display import DisplayStore
    from supervisord.safety.outputs import Outputs
    from supervisord.safety.prooftest import ProofTest
    from supervisord.safety.vsc import VscLink


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

    def due_by(self, view: View) -> bool:
        """Whether one of its deadlines, the user heartbeat's aside, falls at or before
        ``view.now``: then the full step has work beyond sending the beat (SR-9.4)."""
        ...


class View:
    """The core's machines as each machine sees the others, at :attr:`now`: what every
    question of the face is asked about. Built once by the core (``SafetyCore._compose``),
    as its machines live as long as it does; :attr:`now` (and, for the canonical form, the
    time of the last stop) is set before each question (:meth:`at`), so that no input pays for
    a tuple or a view (SR-9.4; docs/performance.md "The cheap path"). A machine reads of the
    others only what its deadlines need: the link's answer to key 85 and whether it is open
    (the display's frames and the proof test's limits), the record budget (a deferred end).
    Named where an input speaks to one machine (its handler), iterated as :attr:`machines`
    everywhere the core composes them."""

    __slots__ = (
        "battery",
        "budget",
        "clients",
        "display",
        "last_stop_raised_ns",
        "machines",
        "movers",
        "now",
        "outputs",
        "proof",
        "vsc",
    )

    def __init__(  # noqa: PLR0917 -- one per machine, once per core
        self,
        vsc: VscLink,
        clients: Clients,
        budget: RecordBudget,
        outputs: Outputs,
        battery: RemoteBattery,
        display: DisplayStore,
        proof: ProofTest,
    ) -> None:
        self.vsc = vsc
        self.clients = clients
        self.budget = budget
        self.outputs = outputs
        self.battery = battery
        self.display = display
        self.proof = proof
        self.machines: tuple[Machine, ...] = (
            vsc,
            clients,
            budget,
            outputs,
            battery,
            display,
            proof,
        )
        """Every machine, in the order the canonical form lists them."""
        self.movers = tuple(machine for machine in self.machines if machine.can_move())
        """The machines that time can move between their deadlines (``Machine.can_move``):
        the only ones asked ``moving`` for each input."""
        self.now = 0
        self.last_stop_raised_ns: int | None = None  # the takeover's run is ordered against it

    def at(self, now: int, last_stop_raised_ns: int | None = None) -> View:
        """This view, at ``now`` (and the latest stop raised at ``last_stop_raised_ns``,
        SR-4.3: read by the canonical form alone)."""
        self.now = now
        self.last_stop_raised_ns = last_stop_raised_ns
        return self
