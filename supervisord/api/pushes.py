"""The pushes of the client API (docs/api.md "Pushes"), typed and frozen: what a subscriber
receives between replies. Each declares its fields once (:class:`~supervisord.wire.Wire`),
its encoder (``json``: the object on the wire, ``event`` first) follows from it, and
:func:`read_push` is their one decoder (tolerant: unknown fields are ignored, and a
push of an event this side does not know is an :class:`OtherPush`, since a client may talk
to a newer daemon).

Pure and small: the client library imports it (docs/ros2.md "The client library").
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass
from typing import ClassVar

from supervisord.api.messages import (
    GpsReport,
    JoystickReport,
    RemoteStatusReport,
    check_type,
)
from supervisord.api.status import StateReport
from supervisord.record.stop import StopRecord
from supervisord.wire import Fields, JsonDict, Wire, wire


@dataclass(frozen=True, slots=True)
class StatePush(Wire):
    """The state changed (the state, a cause or an output), or the first after subscribing."""

    event: ClassVar[str] = "state"
    WIRE_HEAD: ClassVar[JsonDict] = {"event": event}
    report: StateReport = wire(flat=True)


@dataclass(frozen=True, slots=True)
class RecordPush(Wire):
    """A stop record, as written to the record file (docs/record.md)."""

    event: ClassVar[str] = "record"
    WIRE_HEAD: ClassVar[JsonDict] = {"event": event}
    record: StopRecord = wire(flat=True)


@dataclass(frozen=True, slots=True)
class JoystickPush(Wire):
    """A joystick message from the VSC (meaningful only in RUN: the VSC zeroes it otherwise)."""

    event: ClassVar[str] = "joystick"
    WIRE_HEAD: ClassVar[JsonDict] = {"event": event}
    message: JoystickReport = wire(flat=True)


@dataclass(frozen=True, slots=True)
class GpsPush(Wire):
    """A GPS message from the VSC."""

    event: ClassVar[str] = "gps"
    WIRE_HEAD: ClassVar[JsonDict] = {"event": event}
    message: GpsReport = wire(flat=True)


@dataclass(frozen=True, slots=True)
class RemoteStatusPush(Wire):
    """A remote-status message from the VSC (1 Hz once commissioned)."""

    event: ClassVar[str] = "remote_status"
    WIRE_HEAD: ClassVar[JsonDict] = {"event": event}
    message: RemoteStatusReport = wire(flat=True)


@dataclass(frozen=True, slots=True)
class OtherPush:
    """A push of an event this side does not know (a newer daemon's): kept as it came."""

    event: str
    data: Mapping[str, object]

    def json(self) -> JsonDict:
        return {"event": self.event, **{k: v for k, v in self.data.items() if k != "event"}}


_PUSHES: dict[str, type[StatePush | RecordPush | JoystickPush | GpsPush | RemoteStatusPush]] = {
    kind.event: kind for kind in (StatePush, RecordPush, JoystickPush, GpsPush, RemoteStatusPush)
}
_MESSAGE_TYPES: dict[type, str] = {
    JoystickPush: JoystickReport.TYPE,
    GpsPush: GpsReport.TYPE,
    RemoteStatusPush: RemoteStatusReport.TYPE,
}
"""A message push names its message's ``type``: it must be the push's own."""

Push = StatePush | RecordPush | JoystickPush | GpsPush | RemoteStatusPush | OtherPush


def read_push(obj: object) -> Push:
    """The push in one JSON object that has ``event``; raises
    :class:`~supervisord.api.wire.WireError` for one that is not what docs/api.md says."""
    f = Fields(obj, "push")
    event = f.text("event")
    f = Fields(obj, event)
    kind = _PUSHES.get(event)
    if kind is not None:
        if kind in _MESSAGE_TYPES:
            check_type(f, _MESSAGE_TYPES[kind])
        return kind.read(f)
    assert isinstance(obj, Mapping)  # Fields checked it
    return OtherPush(event, {str(k): v for k, v in obj.items() if k != "event"})
