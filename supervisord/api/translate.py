"""Client API requests as safety-core events (SR-8, ``docs/api.md``): sans-IO.

:func:`to_core_event` decides whose request a request is (a named client's own, or before
hello the local operator's) and what the safety core sees of it.
"""

from __future__ import annotations

from dataclasses import dataclass

from supervisord.api.requests import (
    ApiRequest,
    Command,
    Commission,
    DisplayLabel,
    DisplayModeRequest,
    DisplayRow,
    DisplayValue,
    Estop,
    FleetKeepaliveRequest,
    FleetReleaseRequest,
    FleetStopRequest,
    Heartbeat,
    Hello,
    Hold,
    Release,
    Reset,
    StartProofTest,
    Status,
    StopTest,
    Subscribe,
    Vibrate,
)
from supervisord.protocol.codes import FeedbackKey, StringKey
from supervisord.protocol.messages import FeedbackName, FeedbackSet
from supervisord.safety.events import (
    Caller,
    ClientCommand,
    ClientEstop,
    ClientHeartbeat,
    ClientHello,
    ClientHold,
    ClientRelease,
    DisplayUpdate,
    Event,
    FleetKeepalive,
    FleetRelease,
    FleetStop,
    LocalEstop,
    LocalRelease,
    ProofTestRequest,
    Request,
    ResetRequest,
)

_TEXT_ROW_1 = StringKey.TEXT_ROW_1.value


def display_message(
    request: DisplayValue | DisplayLabel | DisplayRow | DisplayModeRequest | Vibrate,
) -> FeedbackSet | FeedbackName:
    """The VSC message a display or vibrate request asks for (manual §8.3.7, §8.3.10)."""
    match request:
        case DisplayValue(key=key, value=value):
            return FeedbackSet(key, value)
        case DisplayLabel(key=key, text=text):
            return FeedbackName(key, text)
        case DisplayRow(index=index, text=text):
            return FeedbackName(_TEXT_ROW_1 + index - 1, text)
        case DisplayModeRequest(mode=mode):
            return FeedbackSet(FeedbackKey.DISPLAY_MODE, int(mode))
        case Vibrate(side=side):
            return FeedbackSet(side.key, 1)  # PR-2: vibrate takes the value 1


@dataclass(frozen=True, slots=True)
class ClientInfo:
    """One connection as the safety core knows it: its number, who is at the other end
    (from the peer credentials) and the name it gave in ``hello`` (``None`` before)."""

    connection: int
    caller: Caller
    name: str | None = None


def to_core_event(  # noqa: PLR0912 -- one case per request, flat as docs/api.md lists them
    request: ApiRequest, client: ClientInfo, now: int
) -> Event | None:
    """The safety-core event for a request from ``client`` received at ``now``, or ``None``
    for requests the daemon answers itself (``status``, ``subscribe``, ``commission``,
    ``stoptest``).

    E-stops and releases of a named client are its own (``client_estop:NAME``); before hello
    they are the local operator's (``local_estop``, with the caller). A hold before hello is
    filed by the core under the peer's user and ends with the last of that user's connections
    that asked for it (docs/safety.md choice 11). ``reset`` always becomes a
    :class:`ResetRequest`, also from a non-admin, so that the core records the refusal.
    """
    connection, named = client.connection, client.name is not None
    match request:
        case Hello(name=name):
            return ClientHello(now, connection, name)
        case Heartbeat(progress=progress):
            return ClientHeartbeat(now, connection, progress) if named else None
        case Estop():
            return ClientEstop(now, connection) if named else LocalEstop(now, client.caller)
        case Hold():
            return ClientHold(now, connection)
        case Release(what=Request.ESTOP) if not named:
            return LocalRelease(now, client.caller)
        case Release(what=what):
            return ClientRelease(now, connection, what)
        case Command(nonzero=nonzero):
            return ClientCommand(now, connection, nonzero)
        case DisplayValue() | DisplayLabel() | DisplayRow() | DisplayModeRequest() | Vibrate():
            return DisplayUpdate(now, display_message(request))
        case Reset():
            return ResetRequest(now, client.caller)
        case StartProofTest():
            return ProofTestRequest(now, client.caller)
        case FleetStopRequest(stop_id=stop_id, sender=sender):
            # SR-8.19: the core judges who sent it (the caller's uid) and raises the stop.
            return FleetStop(now, connection, client.caller, stop_id, sender)
        case FleetReleaseRequest(stop_id=stop_id, sender=sender):
            return FleetRelease(now, connection, client.caller, stop_id, sender)
        case FleetKeepaliveRequest(sender=sender):
            return FleetKeepalive(now, connection, client.caller, sender)
        case Status() | Subscribe() | Commission() | StopTest():
            return None
