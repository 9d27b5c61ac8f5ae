"""The client API's requests as values, and their JSON: what a client sends (SR-8,
``docs/api.md`` "Requests"). Sans-IO.

The client library (:mod:`supervisord.client`, and through it the ROS 2 bridge) builds these
and sends :func:`request_json`; the daemon reads them back with
:func:`supervisord.api.requests.parse_request`, which re-exports every name here. This module
imports only the small set the client library is allowed (docs/ros2.md "The client library"):
never the parser's strict reader, the VSC's messages or the safety core.
"""

from __future__ import annotations

import enum
from dataclasses import dataclass

from supervisord.api.framing import JsonDict
from supervisord.protocol.codes import DisplayMode, FeedbackKey
from supervisord.release import Request


class Topic(enum.Enum):
    """What a subscriber receives (``docs/api.md`` "Pushes")."""

    STATE = "state"  # every decision that changed the state, the causes or the outputs
    JOYSTICK = "joystick"  # every joystick message (meaningful only in RUN)
    GPS = "gps"
    REMOTE_STATUS = "remote_status"
    RECORDS = "records"  # every stop record, as written

    @property
    def event(self) -> str:
        """The ``event`` field of this topic's pushes."""
        return "record" if self is Topic.RECORDS else self.value


class Side(enum.Enum):
    """Which handle of the remote vibrates (feedback keys 10-12)."""

    LEFT = "left"
    RIGHT = "right"
    BOTH = "both"

    @property
    def key(self) -> FeedbackKey:
        return _VIBRATE_KEYS[self]


_VIBRATE_KEYS = {
    Side.LEFT: FeedbackKey.VIBRATE_LEFT,
    Side.RIGHT: FeedbackKey.VIBRATE_RIGHT,
    Side.BOTH: FeedbackKey.VIBRATE_BOTH,
}

RequestId = int | str | None


@dataclass(frozen=True, slots=True, kw_only=True)
class _Request:
    """``id``: the caller's optional tag, echoed in the reply."""

    OP = ""
    id: RequestId = None


@dataclass(frozen=True, slots=True)
class Hello(_Request):
    """Name this connection: it becomes the client ``name`` (SR-8)."""

    OP = "hello"
    name: str


@dataclass(frozen=True, slots=True)
class Heartbeat(_Request):
    """A named client is alive; ``progress`` (0 to 2**32 - 1, or ``None``) is the value its
    control loop moves on each turn: once sent, only a new one keeps it alive (SR-8.16)."""

    OP = "heartbeat"
    progress: int | None = None


@dataclass(frozen=True, slots=True)
class Estop(_Request):
    """An e-stop: the client's own (``client_estop:NAME``) or, before hello, ``local_estop``."""

    OP = "estop"


@dataclass(frozen=True, slots=True)
class Hold(_Request):
    """A hold: ``client_hold:NAME`` until this client releases it."""

    OP = "hold"


@dataclass(frozen=True, slots=True)
class Release(_Request):
    """End this caller's own e-stop or hold request (a stop stays latched until re-armed)."""

    OP = "release"
    what: Request


@dataclass(frozen=True, slots=True)
class Command(_Request):
    """Whether the motion this client commands is non-zero (SR-4.6): no re-arm while any
    client's last declaration says so. Kept until the next one or the connection's end."""

    OP = "command"
    nonzero: bool


@dataclass(frozen=True, slots=True)
class Status(_Request):
    """The current state, causes and outputs."""

    OP = "status"


@dataclass(frozen=True, slots=True)
class Subscribe(_Request):
    """Receive pushes of these topics from now on (replaces the previous set; empty: none)."""

    OP = "subscribe"
    topics: frozenset[Topic]


@dataclass(frozen=True, slots=True)
class DisplayValue(_Request):
    """Show a number in user value ``key`` (1-9) on the remote."""

    OP = "display"
    key: int
    value: int


@dataclass(frozen=True, slots=True)
class DisplayLabel(_Request):
    """Label user value ``key`` (1-9): at most 20 single-byte characters."""

    OP = "display"
    key: int
    text: str


@dataclass(frozen=True, slots=True)
class DisplayRow(_Request):
    """Text row ``index`` (1-4) of the remote's text page: at most 20 characters."""

    OP = "display"
    index: int
    text: str


@dataclass(frozen=True, slots=True)
class DisplayModeRequest(_Request):
    """Which page the remote shows (feedback key 99)."""

    OP = "display"
    mode: DisplayMode


@dataclass(frozen=True, slots=True)
class Vibrate(_Request):
    """Vibrate a handle of the remote once."""

    OP = "vibrate"
    side: Side


@dataclass(frozen=True, slots=True)
class Reset(_Request):
    """``srcsctl reset``: a local re-arm (SR-4). Admins only."""

    OP = "reset"


@dataclass(frozen=True, slots=True)
class Commission(_Request):
    """Turn the VSC's key-85 watchdog on and enable remote-status messages, permanently
    (SR-5). Admins only; the request must carry ``"confirm": true``."""

    OP = "commission"


@dataclass(frozen=True, slots=True)
class StartProofTest(_Request):
    """Run the proof test of the VSC's watchdog again (SR-5.3; docs/safety.md "The proof
    test"). Admins only; the core refuses it in RUN and HOLD. The reply comes at once; the
    result follows in ``status`` (``prooftest``) and a ``prooftest`` record."""

    OP = "prooftest"


@dataclass(frozen=True, slots=True)
class StopTest(_Request):
    """Record a field stop test (SR-12.1; docs/srcsctl.md "The field stop test"): ``steps``
    names each press as its source (``remote``, ``wired``) and the sequence number of the
    stop record it made. The daemon measures and judges; admins only; the reply carries the
    result (the ``stoptest`` record's object)."""

    OP = "stoptest"
    steps: tuple[tuple[str, int], ...]


@dataclass(frozen=True, slots=True)
class _FleetOrder(_Request):
    """What a fleet console says about its stop ``stop_id``, passed on by the robot's fleet
    agent (SR-8.19): the console's name, ``sender``, is its own claim. One shape for the stop
    and its release, read and written once (requests.py, :func:`request_json`)."""

    stop_id: str
    sender: str


@dataclass(frozen=True, slots=True)
class FleetStopRequest(_FleetOrder):
    """A fleet console's stop, sent by the robot's fleet agent (SR-8.19): ``fleet_stop:SENDER``
    until ``fleet_release``; the reply, sent once the outputs are set, says what they read
    back (SR-8.20). Only from a user of ``[fleet] agent_users``."""

    OP = "fleet_stop"


@dataclass(frozen=True, slots=True)
class FleetReleaseRequest(_FleetOrder):
    """The console withdrew its stop ``stop_id`` (SR-8.19): the robot stays STOPPED until the
    operator's takeover on the remote."""

    OP = "fleet_release"


@dataclass(frozen=True, slots=True)
class FleetKeepaliveRequest(_Request):
    """The fleet console is there (SR-8.21), for a robot that requires it."""

    OP = "fleet_keepalive"
    sender: str


ApiRequest = (
    Hello
    | Heartbeat
    | Estop
    | Hold
    | Release
    | Command
    | Status
    | Subscribe
    | DisplayValue
    | DisplayLabel
    | DisplayRow
    | DisplayModeRequest
    | Vibrate
    | Reset
    | Commission
    | StartProofTest
    | StopTest
    | FleetStopRequest
    | FleetReleaseRequest
    | FleetKeepaliveRequest
)
"""Any request of the client API. Not :class:`supervisord.release.Request` (what a
``release`` ends; the safety core's ``supervisord.safety.events.Request``), which
:class:`Release` carries."""


def _display_json(
    request: DisplayValue | DisplayLabel | DisplayRow | DisplayModeRequest,
) -> JsonDict:
    """The fields of a ``display`` request: exactly one of value, label, row and mode."""
    match request:
        case DisplayValue(key=key, value=value):
            return {"value": {"key": key, "value": value}}
        case DisplayLabel(key=key, text=text):
            return {"label": {"key": key, "text": text}}
        case DisplayRow(index=index, text=text):
            return {"row": {"index": index, "text": text}}
        case DisplayModeRequest(mode=mode):
            return {"mode": int(mode)}


def request_json(request: ApiRequest) -> JsonDict:
    """The request as its JSON object: what a client sends (the inverse of parsing)."""
    obj: JsonDict = {"op": request.OP}
    match request:
        case Hello(name=name):
            obj["name"] = name
        case Release(what=what):
            obj["what"] = what.value
        case Command(nonzero=nonzero):
            obj["nonzero"] = nonzero
        case Heartbeat(progress=progress) if progress is not None:
            obj["progress"] = progress
        case Subscribe(topics=topics):
            obj["topics"] = sorted(t.value for t in topics)
        case DisplayValue() | DisplayLabel() | DisplayRow() | DisplayModeRequest():
            obj.update(_display_json(request))
        case Vibrate(side=side):
            obj["side"] = side.value
        case Commission():
            obj["confirm"] = True
        case StopTest(steps=steps):
            obj["steps"] = [{"source": source, "seq": seq} for source, seq in steps]
        case _FleetOrder(stop_id=stop_id, sender=sender):
            obj["stop_id"], obj["sender"] = stop_id, sender
        case FleetKeepaliveRequest(sender=sender):
            obj["sender"] = sender
    if request.id is not None:
        obj["id"] = request.id
    return obj
