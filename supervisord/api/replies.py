"""The replies of the client API (docs/api.md "Requests and replies"), typed and frozen.

Every request gets one reply: :class:`OkReply` for most, :class:`StatusReply`,
:class:`CommissionReply` and :class:`StopTestReply` with their fields, or an error
(:class:`~supervisord.api.framing.ApiError`, whose encoder is ``ApiError.reply``). Each declares
each field once (:class:`~supervisord.wire.Wire`); its encoder (``json``) follows from it, and
:func:`read_reply` is their one decoder: tolerant of fields it
does not know (a client may talk to a newer daemon), an error reply read back as the
``ApiError`` it was.

Pure and small: the client library imports it (docs/ros2.md "The client library").
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any, ClassVar

from supervisord.api.framing import ApiError
from supervisord.api.ops import RequestId
from supervisord.api.status import DaemonStatus, EstopAvailable, RearmStatus, StateReport
from supervisord.record.stop import StopTestReport
from supervisord.vocabulary import State
from supervisord.wire import Fields, JsonDict, Wire, WireError, wire

_ERROR_FIELDS = ("ok", "code", "error", "op", "id")


def _id(f: Fields, key: str = "id") -> RequestId:
    """The request's ``id`` echoed: an integer or text, absent when the request had none."""
    value = f.get(key)
    if value is None or isinstance(value, str):
        return value
    return f.integer(key)


def _request_id() -> Any:
    """A reply's ``id``: the request's echoed, absent when it had none."""
    return wire(omit_none=True, decode=_id, default=None)


@dataclass(frozen=True, slots=True)
class OkReply(Wire):
    """Success, with nothing more to say (``hello``, ``heartbeat``, ``estop`` ...)."""

    WIRE_HEAD: ClassVar[JsonDict] = {"ok": True}
    op: str
    id: RequestId = _request_id()


@dataclass(frozen=True, slots=True, kw_only=True)
class StatusReply(Wire):
    """``status``: the state (as in a ``state`` push), whether the remote e-stop is
    available (``None``: a daemon older than SR-8.11 does not say), and the daemon's own view
    (docs/api.md "status")."""

    OP: ClassVar[str] = "status"
    WIRE_HEAD: ClassVar[JsonDict] = {"ok": True, "op": OP}
    id: RequestId = _request_id()
    report: StateReport = wire(flat=True)
    estop_available: EstopAvailable | None = wire(omit_none=True)
    rearm: RearmStatus | None = wire(omit_none=True, default=None)  # None: an older daemon
    daemon: DaemonStatus


@dataclass(frozen=True, slots=True, kw_only=True)
class CommissionReply(Wire):
    """``commission`` succeeded: key 85 read back (1), and whether a remote status came."""

    OP: ClassVar[str] = "commission"
    WIRE_HEAD: ClassVar[JsonDict] = {"ok": True, "op": OP}
    id: RequestId = _request_id()
    key85: int | None
    remote_status: bool


@dataclass(frozen=True, slots=True, kw_only=True)
class StopTestReply(Wire):
    """``stoptest`` was judged and recorded (SR-12.1): the result, as its record holds it."""

    OP: ClassVar[str] = "stoptest"
    WIRE_HEAD: ClassVar[JsonDict] = {"ok": True, "op": OP}
    id: RequestId = _request_id()
    stoptest: StopTestReport


@dataclass(frozen=True, slots=True, kw_only=True)
class FleetOutput(Wire):
    """One output in a fleet stop's acknowledgement (SR-8.20): the ``level`` the supervisor
    asks for and the ``readback`` the line gave when written again (``None``: not read, an
    output not open, or a category-1 output still on while the drives brake, SR-1.4)."""

    name: str
    level: bool
    readback: bool | None


@dataclass(frozen=True, slots=True, kw_only=True)
class FleetStopReply(Wire):
    """``fleet_stop``'s acknowledgement (SR-8.20), sent once the stop is applied: the state,
    every output's level and read-back, the ``record_seq`` of the record that raised the stop
    (``None``: it raised no new cause, the console's stop was already active), and
    ``arrival_to_off_ms``, monotonic, from the request's arrival to the last read-back.
    ``repeat``: the stop id was taken before; this is its first acknowledgement again."""

    OP: ClassVar[str] = "fleet_stop"
    WIRE_HEAD: ClassVar[JsonDict] = {"ok": True, "op": OP}
    id: RequestId = _request_id()
    stop_id: str
    state: State = wire(by_name=True)
    outputs: tuple[FleetOutput, ...]
    record_seq: int | None
    arrival_to_off_ms: float
    repeat: bool = wire(absent=False, default=False)


Reply = OkReply | StatusReply | CommissionReply | StopTestReply | FleetStopReply


def read_reply(obj: object) -> Reply | ApiError:
    """The reply in one JSON object that has ``ok``: the success reply of its ``op``, or the
    error. Raises :class:`~supervisord.api.wire.WireError` for one docs/api.md does not allow."""
    f = Fields(obj, "reply")
    if not f.flag("ok"):
        return read_error(f)
    op = f.text("op")
    f = Fields(obj, op)
    kind = _REPLIES.get(op)
    if kind is not None:
        return kind.read(f)
    return OkReply(op, _id(f))


_REPLIES: dict[str, type[StatusReply | CommissionReply | StopTestReply | FleetStopReply]] = {
    kind.OP: kind for kind in (StatusReply, CommissionReply, StopTestReply, FleetStopReply)
}


def read_error(f: Fields) -> ApiError:
    """An error reply as the ``ApiError`` the server sent: its code (which may be newer than
    this side), text, ``op`` and ``id``, and its other fields as ``extra``."""
    obj: Mapping[str, object] = {k: f.raw_value(k) for k in f.names()}
    return ApiError(
        f.text("code"),
        f.maybe_text("error") or "",
        op=f.maybe_text("op"),
        request_id=_id(f),
        extra={k: v for k, v in obj.items() if k not in _ERROR_FIELDS},
    )


__all__ = [
    "CommissionReply",
    "FleetOutput",
    "FleetStopReply",
    "OkReply",
    "Reply",
    "RequestId",
    "StatusReply",
    "StopTestReply",
    "WireError",
    "read_error",
    "read_reply",
]
