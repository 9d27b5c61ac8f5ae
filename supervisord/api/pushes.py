"""The pushes of the client API (docs/api.md "Pushes"), typed and frozen: what a subscriber
receives between replies. Each has one encoder (``json``: the object on the wire, ``event``
first) and :func:`read_push` is their one decoder (tolerant: unknown fields are ignored, and a
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
from supervisord.api.records import StopRecord
from supervisord.api.status import StateReport
from supervisord.api.wire import Fields, JsonDict


@dataclass(frozen=True, slots=True)
class StatePush:
    """The state changed (the state, a cause or an output), or the first after subscribing."""

    event: ClassVar[str] = "state"
    report: StateReport

    def json(self) -> JsonDict:
        return {"event": self.event, **self.report.json()}


@dataclass(frozen=True, slots=True)
class RecordPush:
    """A stop record, as written to the record file (docs/record.md)."""

    event: ClassVar[str] = "record"
    record: StopRecord

    def json(self) -> JsonDict:
        return {"event": self.event, **self.record.json()}


@dataclass(frozen=True, slots=True)
class JoystickPush:
    """A joystick message from the VSC (meaningful only in RUN: the VSC zeroes it otherwise)."""

    event: ClassVar[str] = "joystick"
    message: JoystickReport

    def json(self) -> JsonDict:
        return {"event": self.event, **self.message.json()}


@dataclass(frozen=True, slots=True)
class GpsPush:
    """A GPS message from the VSC."""

    event: ClassVar[str] = "gps"
    message: GpsReport

    def json(self) -> JsonDict:
        return {"event": self.event, **self.message.json()}


@dataclass(frozen=True, slots=True)
class RemoteStatusPush:
    """A remote-status message from the VSC (1 Hz once commissioned)."""

    event: ClassVar[str] = "remote_status"
    message: RemoteStatusReport

    def json(self) -> JsonDict:
        return {"event": self.event, **self.message.json()}


@dataclass(frozen=True, slots=True)
class OtherPush:
    """A push of an event this side does not know (a newer daemon's): kept as it came."""

    event: str
    data: Mapping[str, object]

    def json(self) -> JsonDict:
        return {"event": self.event, **{k: v for k, v in self.data.items() if k != "event"}}


Push = StatePush | RecordPush | JoystickPush | GpsPush | RemoteStatusPush | OtherPush


def read_push(obj: object) -> Push:
    """The push in one JSON object that has ``event``; raises
    :class:`~supervisord.api.wire.WireError` for one that is not what docs/api.md says."""
    f = Fields(obj, "push")
    event = f.text("event")
    f = Fields(obj, event)
    if event == StatePush.event:
        return StatePush(StateReport.read(f))
    if event == RecordPush.event:
        return RecordPush(StopRecord.read(f))
    if event == JoystickPush.event:
        check_type(f, JoystickReport.TYPE)
        return JoystickPush(JoystickReport.read(f))
    if event == GpsPush.event:
        check_type(f, GpsReport.TYPE)
        return GpsPush(GpsReport.read(f))
    if event == RemoteStatusPush.event:
        check_type(f, RemoteStatusReport.TYPE)
        return RemoteStatusPush(RemoteStatusReport.read(f))
    assert isinstance(obj, Mapping)  # Fields checked it
    return OtherPush(event, {str(k): v for k, v in obj.items() if k != "event"})
