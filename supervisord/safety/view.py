"""The view of the core's machines that the core builds once and every question of their one
face is asked about (``face.py``; docs/safety.md "The core"). It names each machine, for the
handlers, and holds them as a tuple, for the compositions; the machines read it only through
``face.Seen``, so this module alone imports them (SR-2.11, SR-9.4)."""

from __future__ import annotations

from supervisord.safety.battery import RemoteBattery
from supervisord.safety.budget import RecordBudget
from supervisord.safety.clients import Clients
from supervisord.safety.display import DisplayStore
from supervisord.safety.face import Machine
from supervisord.safety.outputs import Outputs
from supervisord.safety.prooftest import ProofTest
from supervisord.safety.vsc import VscLink


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
