"""What the daemon tells the safety core: every input is a frozen event carrying ``now``.

``now`` is the monotonic clock in integer nanoseconds (``time.monotonic_ns()`` in the daemon),
taken when the input arrived: SR-2 measures every deadline "from the moment the
frame was received". The core never reads a clock of its own.

Clients are named by the daemon's connection number (``connection``) until they say hello;
``Caller`` carries the identity the daemon read from a local command's peer credentials.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import TypeGuard, get_args

from supervisord import release
from supervisord.protocol.messages import FeedbackName, FeedbackSet, Message
from supervisord.safety.stoptest import StopTestResult


def _check_int(name: str, value: object) -> None:
    if isinstance(value, bool) or not isinstance(value, int):
        raise ValueError(f"{name} must be an integer, not {value!r}")


@dataclass(frozen=True, slots=True)
class _Event:
    now: int

    def __post_init__(self) -> None:
        if type(self.now) is not int:  # every input comes here: one type test when it is right
            _check_int("now", self.now)


@dataclass(frozen=True, slots=True)
class Tick(_Event):
    """No input: the deadline the core asked for has come (``SafetyCore.tick``)."""


@dataclass(frozen=True, slots=True)
class VscReceived(_Event):
    """A decoded message from the VSC that passed the checksum and length checks (SR-2)."""

    message: Message


@dataclass(frozen=True, slots=True)
class LinkOpened(_Event):
    """The port or bus to the VSC is open: a new start (SR-4.4)."""


@dataclass(frozen=True, slots=True)
class LinkBroken(_Event):
    """The world broke the link: I/O error, device gone (USB unplug) -> ``transport_fault``."""

    reason: str


@dataclass(frozen=True, slots=True)
class LinkClosed(_Event):
    """We closed the link (e.g. to reopen it) -> ``transport_fault`` until it opens again."""

    reason: str


@dataclass(frozen=True, slots=True)
class ClientConnected(_Event):
    """A client opened a connection on the local socket (SR-8); ``uid`` is the peer's user as
    the kernel reported it (``SO_PEERCRED``), whom the records its inputs cause are charged
    to (SR-8.5); ``None``: not known, one budget for all such connections."""

    connection: int
    uid: int | None = None


@dataclass(frozen=True, slots=True)
class ClientHello(_Event):
    """A connected client named itself; ``caller`` is who is at the other end (``None``:
    unknown, which a client bound to a user refuses)."""

    connection: int
    name: str
    caller: Caller | None = None


@dataclass(frozen=True, slots=True)
class ClientHeartbeat(_Event):
    """A named client's heartbeat, with the progress value its control loop moves on each turn
    (0 to 2**32 - 1; ``None``: none sent; SR-8.16)."""

    connection: int
    progress: int | None = None


@dataclass(frozen=True, slots=True)
class ClientEstop(_Event):
    """A client asked for an e-stop -> ``client_estop:NAME`` until that client releases it."""

    connection: int


@dataclass(frozen=True, slots=True)
class ClientHold(_Event):
    """A client asked for a hold -> ``client_hold:NAME`` until that client releases it."""

    connection: int


@dataclass(frozen=True, slots=True)
class ClientCommand(_Event):
    """A named client declared whether the motion it commands is non-zero (SR-4.6): held for
    its connection until it declares again or the connection ends; while any client's is
    non-zero, no re-arm is honoured."""

    connection: int
    nonzero: bool


Request = release.Request
"""What a client's release ends: one enum with the client API's (``supervisord.release``)."""


@dataclass(frozen=True, slots=True)
class ClientRelease(_Event):
    """A client ended its own e-stop or hold request (a stop stays latched until re-armed)."""

    connection: int
    request: Request


@dataclass(frozen=True, slots=True)
class ClientDisconnected(_Event):
    """A client's connection ended; a required client is then lost at once."""

    connection: int


@dataclass(frozen=True, slots=True)
class Caller:
    """Who sent a local command, from the socket peer's credentials (SR-8).

    ``admin`` is decided by the daemon (membership of the admin group).
    """

    uid: int
    pid: int
    name: str
    admin: bool


@dataclass(frozen=True, slots=True)
class LocalEstop(_Event):
    """``srcsctl estop``: ``local_estop`` until a local release."""

    caller: Caller


@dataclass(frozen=True, slots=True)
class LocalRelease(_Event):
    """``srcsctl release``: ends ``local_estop``'s condition (the stop stays latched)."""

    caller: Caller


@dataclass(frozen=True, slots=True)
class ResetRequest(_Event):
    """``srcsctl reset``: a local re-arm, honoured only when the config allows it and the caller
    is an admin (SR-4)."""

    caller: Caller


@dataclass(frozen=True, slots=True)
class OutputReadback(_Event):
    """The result of setting an output: what was requested and what was read back.

    ``read_back`` is ``None`` when the output could not be set or read at all.
    """

    output: str
    requested: bool
    read_back: bool | None


@dataclass(frozen=True, slots=True)
class InternalFault(_Event):
    """The daemon's own loop failed or overran its deadline -> ``internal``."""

    reason: str


@dataclass(frozen=True, slots=True)
class Shutdown(_Event):
    """The daemon is exiting (SR-7.14): ``reason`` is the signal that asked for it
    (``SIGTERM``, ``SIGHUP``, ...) or ``error`` when the daemon's start failed. The daemon's
    outputs are already off; the core records the stop, ``shutdown:REASON``."""

    reason: str


@dataclass(frozen=True, slots=True)
class DisplayUpdate(_Event):
    """A client's display content for the remote: a value (keys 1-12, 99) or a label or text
    row (keys 1-9, 90-93). The core forwards it within the manual's rate limits and sends it
    again after the remote re-links."""

    message: FeedbackSet | FeedbackName


@dataclass(frozen=True, slots=True)
class Commissioned(_Event):
    """``srcsctl commission`` ran: key 85 was written and read back (``key85``, ``None`` when the
    VSC did not answer) and remote-status messages were enabled (``remote_status``: one was
    seen since). Stored permanently on the VSC, so it is recorded (SR-5)."""

    caller: Caller
    key85: int | None
    remote_status: bool


@dataclass(frozen=True, slots=True)
class ProofTestRequest(_Event):
    """``srcsctl prooftest``: run the proof test of the VSC's watchdog again (SR-5.3; docs/
    safety.md "The proof test"). Admins only, and only while STOPPED."""

    caller: Caller


@dataclass(frozen=True, slots=True)
class StopTested(_Event):
    """``srcsctl stoptest`` finished (SR-12.1; docs/srcsctl.md "The field stop test"): the
    daemon's measurement of each press and each output, judged. Admins only; recorded as a
    ``stoptest`` record, the evidence of the periodic test (SR-12.2)."""

    caller: Caller
    result: StopTestResult


@dataclass(frozen=True, slots=True)
class FleetStop(_Event):
    """A fleet console's stop, carried by the robot's fleet agent (SR-8.19): raises
    ``fleet_stop:SENDER``, a latched stop, until the agent sends its release. ``caller`` is
    who is at the other end of the connection (only the config's agent users are heard);
    ``stop_id`` names the console's stop: a repeat of one already taken changes nothing."""

    connection: int
    caller: Caller | None
    stop_id: str
    sender: str


@dataclass(frozen=True, slots=True)
class FleetRelease(_Event):
    """The console withdrew its stop ``stop_id`` (SR-8.19): the condition ends; the stop stays
    latched until the operator's takeover on the remote, as every stop (SR-4)."""

    connection: int
    caller: Caller | None
    stop_id: str
    sender: str


@dataclass(frozen=True, slots=True)
class FleetKeepalive(_Event):
    """The fleet console is there (SR-8.21): with ``[fleet] console_required``, its absence
    for ``console_timeout_ms`` is ``fleet_console_lost``, a stop."""

    connection: int
    caller: Caller | None
    sender: str


Event = (
    Tick
    | VscReceived
    | LinkOpened
    | LinkBroken
    | LinkClosed
    | ClientConnected
    | ClientHello
    | ClientHeartbeat
    | ClientEstop
    | ClientHold
    | ClientCommand
    | ClientRelease
    | ClientDisconnected
    | LocalEstop
    | LocalRelease
    | ResetRequest
    | OutputReadback
    | InternalFault
    | Shutdown
    | DisplayUpdate
    | Commissioned
    | ProofTestRequest
    | StopTested
    | FleetStop
    | FleetRelease
    | FleetKeepalive
)

EVENT_TYPES: tuple[type, ...] = get_args(Event)


def is_event(value: object) -> TypeGuard[Event]:
    """Whether ``value`` is one of the safety core's input events."""
    return isinstance(value, EVENT_TYPES)
