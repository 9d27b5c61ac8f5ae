"""The VSC's messages as the client API pushes them (docs/api.md "Pushes"): the joystick, GPS
and remote-status messages, typed and frozen. Their JSON is the one ``srcsctl decode`` prints
(docs/protocol.md), which ``tests/api/test_api_roundtrip.py`` checks against the daemon's.

Each has one encoder (``json``) and one decoder (``read``; unknown fields are ignored). Pure
and small: the client library imports it, and it imports none of the protocol's parsers
(docs/ros2.md "The client library").
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import ClassVar

from supervisord.api.wire import Fields, JsonDict, WireError

LEFT_BUTTONS: tuple[str, ...] = ("down", "right", "up", "left")
"""The left hand's pad in wire order (PR-2.4); on the wire each is ``NAME_status``."""
RIGHT_BUTTONS: tuple[str, ...] = ("button_1", "button_2", "button_3", "button_4")
"""The right hand's buttons in wire order (PR-2.4)."""
JOYSTICK_AXES: tuple[str, ...] = ("left_x", "left_y", "left_z", "right_x", "right_y", "right_z")
"""The axes in wire order; on the wire each is ``NAME_joystick_value``."""


@dataclass(frozen=True, slots=True, kw_only=True)
class AxisReport:
    """One stick axis: ``value`` -1023..1023, ``None`` when invalid (PR-2.2), and its bits."""

    value: int | None
    magnitude: int
    neutral_status: int
    negative_status: int
    positive_status: int

    def json(self) -> JsonDict:
        return {
            "value": self.value,
            "magnitude": self.magnitude,
            "neutral_status": self.neutral_status,
            "negative_status": self.negative_status,
            "positive_status": self.positive_status,
        }

    @classmethod
    def read(cls, f: Fields) -> AxisReport:
        return cls(
            value=f.maybe_integer("value"),
            magnitude=f.integer("magnitude"),
            neutral_status=f.integer("neutral_status"),
            negative_status=f.integer("negative_status"),
            positive_status=f.integer("positive_status"),
        )


@dataclass(frozen=True, slots=True, kw_only=True)
class ButtonsReport:
    """One hand's button byte: each button's 2-bit status by name (``down`` ... ``left``, or
    ``button_1`` ... ``button_4``; ``NAME_status`` on the wire), and the names pressed."""

    byte: int
    statuses: tuple[tuple[str, int], ...]
    pressed: tuple[str, ...]

    def json(self) -> JsonDict:
        out: JsonDict = {"byte": self.byte}
        out.update((f"{name}_status", status) for name, status in self.statuses)
        out["pressed"] = list(self.pressed)
        return out

    @classmethod
    def read(cls, f: Fields, names: tuple[str, ...]) -> ButtonsReport:
        """The buttons ``names`` (``LEFT_BUTTONS`` or ``RIGHT_BUTTONS``): a newer daemon's
        field that happens to end in ``_status`` is no button."""
        return cls(
            byte=f.integer("byte"),
            statuses=tuple((name, f.integer(f"{name}_status")) for name in names),
            pressed=f.texts("pressed"),
        )


@dataclass(frozen=True, slots=True, kw_only=True)
class JoystickReport:
    """A joystick message (manual §8.3.1): the six axes and both hands' buttons."""

    TYPE: ClassVar[str] = "joystick"
    left_x: AxisReport
    left_y: AxisReport
    left_z: AxisReport
    right_x: AxisReport
    right_y: AxisReport
    right_z: AxisReport
    left_buttons: ButtonsReport
    right_buttons: ButtonsReport

    def axes(self) -> dict[str, AxisReport]:
        """The axes by name, in wire order."""
        return {name: getattr(self, name) for name in JOYSTICK_AXES}

    @property
    def pressed(self) -> tuple[str, ...]:
        """Every button pressed, the left hand's first."""
        return self.left_buttons.pressed + self.right_buttons.pressed

    def json(self) -> JsonDict:
        out: JsonDict = {"type": self.TYPE}
        out.update((f"{name}_joystick_value", axis.json()) for name, axis in self.axes().items())
        out["left_button_values"] = self.left_buttons.json()
        out["right_button_values"] = self.right_buttons.json()
        return out

    @classmethod
    def read(cls, f: Fields) -> JoystickReport:
        axes = {name: AxisReport.read(f.obj(f"{name}_joystick_value")) for name in JOYSTICK_AXES}
        return cls(
            **axes,
            left_buttons=ButtonsReport.read(f.obj("left_button_values"), LEFT_BUTTONS),
            right_buttons=ButtonsReport.read(f.obj("right_button_values"), RIGHT_BUTTONS),
        )


@dataclass(frozen=True, slots=True, kw_only=True)
class GpsFixReport:
    """What the sentence says, where it could be read (``None`` where it leaves it empty)."""

    sentence_type: str
    utc_time: str | None
    latitude: float | None
    longitude: float | None
    fix_quality: int | None
    valid: bool


@dataclass(frozen=True, slots=True, kw_only=True)
class GpsReport:
    """A GPS message (manual §8.3.2): the source byte and the NMEA sentence as sent, and the
    fix read from it (``None``: the sentence could not be read)."""

    TYPE: ClassVar[str] = "gps"
    source: int
    string: str
    fix: GpsFixReport | None = None

    def json(self) -> JsonDict:
        out: JsonDict = {"type": self.TYPE, "source": self.source, "string": self.string}
        fix = self.fix
        if fix is not None:
            out.update(
                sentence_type=fix.sentence_type,
                utc_time=fix.utc_time,
                latitude=fix.latitude,
                longitude=fix.longitude,
                fix_quality=fix.fix_quality,
                valid=fix.valid,
            )
        return out

    @classmethod
    def read(cls, f: Fields) -> GpsReport:
        fix = None
        if f.has("sentence_type"):
            fix = GpsFixReport(
                sentence_type=f.text("sentence_type"),
                utc_time=f.maybe_text("utc_time"),
                latitude=f.maybe_number("latitude"),
                longitude=f.maybe_number("longitude"),
                fix_quality=f.maybe_integer("fix_quality"),
                valid=f.flag("valid"),
            )
        return cls(source=f.integer("source"), string=f.text("string"), fix=fix)


@dataclass(frozen=True, slots=True, kw_only=True)
class RemoteStatusReport:
    """A remote-status message (manual §8.3.4): the remote's battery and link strengths."""

    TYPE: ClassVar[str] = "remote_status"
    battery_level: int
    battery_charging: int
    connection_strength_vsc: int
    connection_strength_src: int
    rssi_vsc: int
    rssi_src: int

    def json(self) -> JsonDict:
        return {
            "type": self.TYPE,
            "battery_level": self.battery_level,
            "battery_charging": self.battery_charging,
            "connection_strength_vsc": self.connection_strength_vsc,
            "connection_strength_src": self.connection_strength_src,
            "rssi_vsc": self.rssi_vsc,
            "rssi_src": self.rssi_src,
        }

    @classmethod
    def read(cls, f: Fields) -> RemoteStatusReport:
        return cls(
            battery_level=f.integer("battery_level"),
            battery_charging=f.integer("battery_charging"),
            connection_strength_vsc=f.integer("connection_strength_vsc"),
            connection_strength_src=f.integer("connection_strength_src"),
            rssi_vsc=f.integer("rssi_vsc"),
            rssi_src=f.integer("rssi_src"),
        )


MessageReport = JoystickReport | GpsReport | RemoteStatusReport


def check_type(f: Fields, expected: str) -> None:
    """A message push names its message's ``type``: it must be the push's own."""
    if f.has("type") and f.text("type") != expected:
        raise WireError(f"{f.where}: type {f.text('type')!r}, not {expected!r}")
