"""The VSC's messages as the client API pushes them (docs/api.md "Pushes"): the joystick, GPS
and remote-status messages, typed and frozen. Their JSON is the one ``srcsctl decode`` prints
(docs/protocol.md), which ``tests/api/test_api_roundtrip.py`` checks against the daemon's.

Each declares each field once (:class:`~supervisord.wire.Wire`); its encoder (``json``) and
decoder (``read``; unknown fields are ignored) follow from it. Pure and small: the client
library imports it, and it imports none of the protocol's parsers (docs/ros2.md "The client
library").
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any, ClassVar

from supervisord.wire import Fields, JsonDict, Wire, WireError, wire

LEFT_BUTTONS: tuple[str, ...] = ("down", "right", "up", "left")
"""The left hand's pad in wire order (PR-2.4); on the wire each is ``NAME_status``."""
RIGHT_BUTTONS: tuple[str, ...] = ("button_1", "button_2", "button_3", "button_4")
"""The right hand's buttons in wire order (PR-2.4)."""
JOYSTICK_AXES: tuple[str, ...] = ("left_x", "left_y", "left_z", "right_x", "right_y", "right_z")
"""The axes in wire order; on the wire each is ``NAME_joystick_value``."""


@dataclass(frozen=True, slots=True, kw_only=True)
class AxisReport(Wire):
    """One stick axis: ``value`` -1023..1023, ``None`` when invalid (PR-2.2), and its bits."""

    value: int | None
    magnitude: int
    neutral_status: int
    negative_status: int
    positive_status: int


@dataclass(frozen=True, slots=True, kw_only=True)
class ButtonsReport:
    """One hand's button byte: each button's 2-bit status by name (``down`` ... ``left``, or
    ``button_1`` ... ``button_4``; ``NAME_status`` on the wire), and the names pressed. Its
    fields' names on the wire are its buttons' (the hand's, which the object does not say),
    so it reads with the hand's names (:meth:`read`)."""

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

    @staticmethod
    def hand(names: tuple[str, ...]) -> Any:
        """A joystick's field of one hand's buttons, read with that hand's ``names``."""
        return wire(
            name=f"{'left' if names is LEFT_BUTTONS else 'right'}_button_values",
            decode=lambda f, key: ButtonsReport.read(f.obj(key), names),
        )


def _axis(name: str) -> Any:
    return wire(name=f"{name}_joystick_value")


@dataclass(frozen=True, slots=True, kw_only=True)
class JoystickReport(Wire):
    """A joystick message (manual §8.3.1): the six axes and both hands' buttons."""

    TYPE: ClassVar[str] = "joystick"
    WIRE_HEAD: ClassVar[JsonDict] = {"type": TYPE}
    left_x: AxisReport = _axis("left_x")
    left_y: AxisReport = _axis("left_y")
    left_z: AxisReport = _axis("left_z")
    right_x: AxisReport = _axis("right_x")
    right_y: AxisReport = _axis("right_y")
    right_z: AxisReport = _axis("right_z")
    left_buttons: ButtonsReport = ButtonsReport.hand(LEFT_BUTTONS)
    right_buttons: ButtonsReport = ButtonsReport.hand(RIGHT_BUTTONS)

    def axes(self) -> dict[str, AxisReport]:
        """The axes by name, in wire order."""
        return {name: getattr(self, name) for name in JOYSTICK_AXES}

    @property
    def pressed(self) -> tuple[str, ...]:
        """Every button pressed, the left hand's first."""
        return self.left_buttons.pressed + self.right_buttons.pressed


@dataclass(frozen=True, slots=True, kw_only=True)
class GpsFixReport(Wire):
    """What the sentence says, where it could be read (``None`` where it leaves it empty)."""

    sentence_type: str
    utc_time: str | None
    latitude: float | None
    longitude: float | None
    fix_quality: int | None
    valid: bool


@dataclass(frozen=True, slots=True, kw_only=True)
class GpsReport(Wire):
    """A GPS message (manual §8.3.2): the source byte and the NMEA sentence as sent, and the
    fix read from it (``None``: the sentence could not be read; its fields are the message's
    own on the wire)."""

    TYPE: ClassVar[str] = "gps"
    WIRE_HEAD: ClassVar[JsonDict] = {"type": TYPE}
    source: int
    string: str
    fix: GpsFixReport | None = wire(flat=True, default=None)


@dataclass(frozen=True, slots=True, kw_only=True)
class RemoteStatusReport(Wire):
    """A remote-status message (manual §8.3.4): the remote's battery and link strengths."""

    TYPE: ClassVar[str] = "remote_status"
    WIRE_HEAD: ClassVar[JsonDict] = {"type": TYPE}
    battery_level: int
    battery_charging: int
    connection_strength_vsc: int
    connection_strength_src: int
    rssi_vsc: int
    rssi_src: int


MessageReport = JoystickReport | GpsReport | RemoteStatusReport


def check_type(f: Fields, expected: str) -> None:
    """A message push names its message's ``type``: it must be the push's own."""
    if f.has("type") and f.text("type") != expected:
        raise WireError(f"{f.where}: type {f.text('type')!r}, not {expected!r}")
