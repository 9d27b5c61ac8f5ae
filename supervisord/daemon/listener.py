"""The face between the loop and what else it serves (the client API's listener).

The loop tells the listener what it needs to know (every decision applied, every valid VSC
message, every finished stop record) and asks it for its descriptors and deadline; the work
the listener then has that needs the loop (a safety input fed to the core, a look at the
loop's status and stop times, frames for the VSC) comes back as :data:`Asks`, a generator the
loop answers one ask at a time (``daemon/answer.py``'s ``serve``), so the listener holds
nothing of the loop's and never calls into it, and each request is answered with the decision
of the moment it was fed (SR-6, SR-8; docs/api.md "status").
"""

from __future__ import annotations

from collections.abc import Generator, Iterable
from dataclasses import dataclass

from supervisord.api.status import LoopStatus
from supervisord.daemon.offcheck import OffCheck
from supervisord.daemon.stoptimes import StopTimes
from supervisord.protocol.hid import HidInput
from supervisord.protocol.messages import Message
from supervisord.record.stop import StopRecord
from supervisord.safety.decision import Decision
from supervisord.safety.events import Event


@dataclass(frozen=True, slots=True)
class Snapshot:
    """What the loop shows the listener when it asks (:class:`Look`): ``status``, the loop's
    own status at the time asked (:meth:`Supervisor.snapshot`, for a ``status`` reply), and
    ``stop_times``, the last stops' outputs' times to off, measured by the loop (for a
    ``stoptest``, SR-12.1)."""

    status: LoopStatus
    stop_times: StopTimes


@dataclass(frozen=True, slots=True)
class Look:
    """The listener asks to see the loop at ``now``: answered with a :class:`Snapshot`."""

    now: int


@dataclass(frozen=True, slots=True)
class Send:
    """The listener asks the loop to send ``frames`` to the VSC at ``now`` (a commissioning's
    key-85 requests): answered with ``None``."""

    frames: tuple[Message, ...]
    now: int


@dataclass(frozen=True, slots=True)
class CheckOff:
    """The listener asks the loop to write every output that is off off again and read it
    back, at ``now`` (a fleet stop's acknowledgement, SR-8.20): answered with an
    :class:`~supervisord.daemon.offcheck.OffCheck`."""

    now: int


Ask = Event | Look | CheckOff | Send
"""What a listener asks of the loop: an event is fed to the core and applied at once
(outputs, frames, records, pushes: SR-6), and answered with its decision."""

Answer = Decision | Snapshot | OffCheck | None
"""The loop's answer to an :data:`Ask`: the event's decision, the snapshot, the off check,
``None``."""

Asks = Generator[Ask, Answer, None]
"""A listener's work that needs the loop: the loop takes each ask in turn and sends back its
answer before the work goes on, so the listener never calls into the loop and every answer
(a refusal, a status) is the one of the moment asked (``daemon/answer.py``'s ``serve``)."""


class Listener:
    """Something else the loop serves (the client API): descriptors to watch, and work.

    ``handle``, ``settle`` and ``due`` return the work they need the loop for, as
    :data:`Asks` (``None``: none); the loop answers every ask in order. ``decided`` and
    ``received`` are told every decision and every valid VSC message, so clients see state,
    records and traffic as they happen.
    """

    def descriptors(self, now: int) -> Iterable[tuple[int, bool]]:
        """(fd, wants_write) pairs to watch now (``now``: the loop's clock, as everywhere)."""
        return ()

    def urgent(self) -> frozenset[int]:
        """Descriptors (of :meth:`descriptors`) served before the other client descriptors
        and outside ``loop.MAX_CLIENTS_PER_TURN``: the operator socket (SR-8.14)."""
        return frozenset()

    def handle(self, fd: int, readable: bool, writable: bool, now: int) -> Asks | None:
        """Serve ``fd``; every safety input it brought is asked of the loop as an event (the
        answer, the core's decision, to answer the client with its refusals); a ``status``
        asks to :class:`Look` at the loop, a ``stoptest`` too (its stops' measured times)."""
        return None

    def settle(self, now: int) -> Asks | None:
        """The safety inputs that arose outside ``handle`` (e.g. a client dropped while a push
        was written to it), asked as for :meth:`handle`. Called once at the end of a turn."""
        return None

    def due(self, now: int) -> Asks | None:
        """Work of the listener's own that is due (commissioning, requests that waited for
        the caller's name), asked as for :meth:`handle`; frames for the VSC as :class:`Send`."""
        return None

    def next_deadline(self) -> int | None:
        """When ``due`` must be called next, if the listener has work of its own."""
        return None

    def decided(self, decision: Decision) -> None:
        """A decision was applied (outputs set, frames sent)."""

    def recorded(self, record: StopRecord) -> None:
        """A stop record is finished: on disk, or counted as not written. Called in record
        order, after the decision that made it."""

    def received(self, message: Message | HidInput, now: int) -> None:
        """A valid message arrived from the VSC, read at ``now``."""

    def close(self) -> None:
        """Release everything."""
