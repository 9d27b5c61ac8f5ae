"""The replies of the client API (docs/api.md "Requests and replies"), typed and frozen.

Every request gets one reply: :class:`OkReply` for most, :class:`StatusReply`,
:class:`CommissionReply` and :class:`StopTestReply` with their fields, or an error
(:class:`~supervisord.api.framing.ApiError`, whose encoder is ``ApiError.reply``). Each has
one encoder (``json``) and :func:`read_reply` is their one decoder: tolerant of fields it
does not know (a client may talk to a newer daemon), an error reply read back as the
``ApiError`` it was.

Pure and small: the client library imports it (docs/ros2.md "The client library").
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass
from typing import ClassVar

from supervisord.api.framing import ApiError
from supervisord.api.ops import RequestId
from supervisord.api.records import StopTestReport
from supervisord.api.status import DaemonStatus, EstopAvailable, RearmStatus, StateReport
from supervisord.api.wire import Fields, JsonDict, WireError

_ERROR_FIELDS = ("ok", "code", "error", "op", "id")


def _head(op: str, request_id: RequestId) -> JsonDict:
    head: JsonDict = {"ok": True, "op": op}
    if request_id is not None:
        head["id"] = request_id
    return head


def _id(f: Fields) -> RequestId:
    """The request's ``id`` echoed: an integer or text, absent when the request had none."""
    value = f.raw_value("id") if f.has("id") else None
    if value is None or isinstance(value, str):
        return value
    return f.integer("id")


@dataclass(frozen=True, slots=True)
class OkReply:
    """Success, with nothing more to say (``hello``, ``heartbeat``, ``estop`` ...)."""

    op: str
    id: RequestId = None

    def json(self) -> JsonDict:
        return _head(self.op, self.id)


@dataclass(frozen=True, slots=True, kw_only=True)
class StatusReply:
    """``status``: the state (as in a ``state`` push), whether the remote e-stop is
    available (``None``: a daemon older than SR-8.11 does not say), and the daemon's own view
    (docs/api.md "status")."""

    OP: ClassVar[str] = "status"
    id: RequestId = None
    report: StateReport
    estop_available: EstopAvailable | None
    daemon: DaemonStatus
    rearm: RearmStatus | None = None  # None: a daemon older than this field does not say

    def json(self) -> JsonDict:
        out = {**_head(self.OP, self.id), **self.report.json()}
        if self.estop_available is not None:
            out["estop_available"] = self.estop_available.json()
        if self.rearm is not None:
            out["rearm"] = self.rearm.json()
        out["daemon"] = self.daemon.json()
        return out

    @classmethod
    def read(cls, f: Fields) -> StatusReply:
        available = f.maybe_obj("estop_available")
        rearm = f.maybe_obj("rearm")
        return cls(
            id=_id(f),
            report=StateReport.read(f),
            estop_available=None if available is None else EstopAvailable.read(available),
            daemon=DaemonStatus.read(f.obj("daemon")),
            rearm=None if rearm is None else RearmStatus.read(rearm),
        )


@dataclass(frozen=True, slots=True, kw_only=True)
class CommissionReply:
    """``commission`` succeeded: key 85 read back (1), and whether a remote status came."""

    OP: ClassVar[str] = "commission"
    id: RequestId = None
    key85: int | None
    remote_status: bool

    def json(self) -> JsonDict:
        return {**_head(self.OP, self.id), "key85": self.key85, "remote_status": self.remote_status}

    @classmethod
    def read(cls, f: Fields) -> CommissionReply:
        return cls(id=_id(f), key85=f.maybe_integer("key85"), remote_status=f.flag("remote_status"))


@dataclass(frozen=True, slots=True, kw_only=True)
class StopTestReply:
    """``stoptest`` was judged and recorded (SR-12.1): the result, as its record holds it."""

    OP: ClassVar[str] = "stoptest"
    id: RequestId = None
    stoptest: StopTestReport

    def json(self) -> JsonDict:
        return {**_head(self.OP, self.id), "stoptest": self.stoptest.json()}

    @classmethod
    def read(cls, f: Fields) -> StopTestReply:
        return cls(id=_id(f), stoptest=StopTestReport.read(f.obj("stoptest")))


Reply = OkReply | StatusReply | CommissionReply | StopTestReply


def read_reply(obj: object) -> Reply | ApiError:
    """The reply in one JSON object that has ``ok``: the success reply of its ``op``, or the
    error. Raises :class:`~supervisord.api.wire.WireError` for one docs/api.md does not allow."""
    f = Fields(obj, "reply")
    if not f.flag("ok"):
        return read_error(f)
    op = f.text("op")
    f = Fields(obj, op)
    if op == StatusReply.OP:
        return StatusReply.read(f)
    if op == CommissionReply.OP:
        return CommissionReply.read(f)
    if op == StopTestReply.OP:
        return StopTestReply.read(f)
    return OkReply(op, _id(f))


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
    "OkReply",
    "Reply",
    "RequestId",
    "StatusReply",
    "StopTestReply",
    "WireError",
    "read_error",
    "read_reply",
]
