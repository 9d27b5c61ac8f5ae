"""Whom a step's records are charged to, and which inputs are refused past the budget (SR-8.5).

One of the parts :class:`~supervisord.safety.core.SafetyCore` composes: in step 2, before the
event is applied, :func:`charge_step` sets whom the step's records are charged to and whether
that user is past its record budget (:mod:`~supervisord.safety.budget`), and says whether the
event is refused for it; the core charges the step's records when it makes them (step 6).
docs/safety.md "How many records the clients may cause".
"""

from __future__ import annotations

from typing import Final

from supervisord.safety.budget import RecordBudget
from supervisord.safety.clients import Clients
from supervisord.safety.events import (
    ClientCommand,
    ClientConnected,
    ClientDisconnected,
    ClientEstop,
    ClientHeartbeat,
    ClientHello,
    ClientHold,
    ClientRelease,
    Commissioned,
    Event,
    FleetKeepalive,
    FleetRelease,
    FleetStop,
    LocalEstop,
    LocalRelease,
    ProofTestRequest,
    ResetRequest,
    StopTested,
)
from supervisord.safety.step import Step

CLIENT_EVENTS: Final = (
    ClientConnected,
    ClientHello,
    ClientHeartbeat,
    ClientEstop,
    ClientHold,
    ClientCommand,
    ClientRelease,
    ClientDisconnected,
    LocalEstop,
    LocalRelease,
    ResetRequest,
    ProofTestRequest,
    Commissioned,
    StopTested,
    FleetStop,
    FleetRelease,
    FleetKeepalive,
)
"""Inputs from the client socket: the records they cause are charged to their user (SR-8.5)."""
LIMITED_EVENTS: Final = (ClientRelease, LocalRelease, ResetRequest, ClientHello, FleetRelease)
"""Past its user's budget these are refused (``RATE_LIMITED``): each can take a reason to stop
away (a release, a re-arm, a hello that ends a required client's loss or names a new
requester); refusing them leaves the robot held or stopped, the safe side (SR-8.5)."""


def charge_step(step: Step, event: Event, clients: Clients, budget: RecordBudget) -> bool:
    """Set whom the step's records are charged to (``step.charged``) and whether that user is
    past its budget at ``step.now`` (``step.limited``); true when ``event`` is to be refused
    for it (``RATE_LIMITED``, SR-8.5). Called before the event is applied: a disconnection
    forgets its connection's uid."""
    step.charged = (clients.uid(event),) if isinstance(event, CLIENT_EVENTS) else None
    step.limited = step.charged is not None and budget.exhausted(step.charged[0], step.now)
    return step.limited and isinstance(event, LIMITED_EVENTS)
