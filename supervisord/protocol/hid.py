"""The USB HID game-controller reports (manual §10, PR-4), without any I/O.

HID mode carries no host heartbeat, so it is an input for monitoring and teleoperation and
never a safety channel. Reports are taken without a report-id byte, as hidraw delivers them
for a device that declares none; multi-byte fields are little-endian like the rest.
"""

from __future__ import annotations

import struct
from dataclasses import dataclass

from supervisord.compat import IntEnum
from supervisord.protocol.messages import I32, U8, check_range, check_text

INPUT_LENGTH = 9
OUTPUT_TEXT_LENGTH = 20
OUTPUT_LENGTH = 6 + OUTPUT_TEXT_LENGTH
HID_AXES = ("left_x", "left_y", "left_z", "right_x", "right_y", "right_z")
_AXIS = (-128, 127)
_NIBBLE = (0, 15)
_INPUT = struct.Struct("<6bBBB")
_OUTPUT_HEAD = struct.Struct("<BiB")


class DPadDirection(IntEnum):
    """The D-pad nibble: clockwise from up in eighths (manual table 38); 8 = not pressed."""

    UP = 0
    UP_RIGHT = 1
    RIGHT = 2
    DOWN_RIGHT = 3
    DOWN = 4
    DOWN_LEFT = 5
    LEFT = 6
    UP_LEFT = 7
    NONE = 8


@dataclass(frozen=True, slots=True)
class HidInput:
    """The 9-byte input report, ~16 Hz (manual §10.2.1).

    Axes are -127..127 (a raw -128 is kept as sent); ``buttons`` bit 0 is button 1;
    ``mode`` is the SRC mode byte of manual table 1; ``estop`` 1 = actuated.
    """

    left_x: int = 0
    left_y: int = 0
    left_z: int = 0
    right_x: int = 0
    right_y: int = 0
    right_z: int = 0
    dpad: int = DPadDirection.NONE
    buttons: int = 0
    mode: int = 0
    estop: int = 0

    def __post_init__(self) -> None:
        for name in HID_AXES:
            check_range(name, getattr(self, name), _AXIS)
        check_range("dpad", self.dpad, _NIBBLE)
        check_range("buttons", self.buttons, _NIBBLE)
        check_range("mode", self.mode, U8)
        check_range("estop", self.estop, U8)

    @property
    def dpad_direction(self) -> DPadDirection | None:
        """The pad's direction, or ``None`` for a value the manual does not define (9-15)."""
        try:
            return DPadDirection(self.dpad)
        except ValueError:
            return None

    @property
    def pressed(self) -> frozenset[int]:
        """The numbers (1-4) of the pressed buttons."""
        return frozenset(i + 1 for i in range(4) if self.buttons >> i & 1)


@dataclass(frozen=True, slots=True)
class HidOutput:
    """The output report to the SRC (manual §10.2.2): a key/value pair and a key/text pair."""

    key: int
    value: int
    string_key: int
    text: str = ""

    def __post_init__(self) -> None:
        check_range("key", self.key, U8)
        check_range("value", self.value, I32)
        check_range("string key", self.string_key, U8)
        check_text("text", self.text, OUTPUT_TEXT_LENGTH)


@dataclass(frozen=True, slots=True)
class HidRejection:
    """A report of the wrong length for its direction."""

    length: int
    expected: int


def encode_hid_input(report: HidInput) -> bytes:
    axes = (getattr(report, name) for name in HID_AXES)
    return _INPUT.pack(*axes, report.dpad | report.buttons << 4, report.mode, report.estop)


def decode_hid_input(data: bytes) -> HidInput | HidRejection:
    """The input report in ``data``, or a rejection for a wrong length. Never raises."""
    if len(data) != INPUT_LENGTH:
        return HidRejection(len(data), INPUT_LENGTH)
    lx, ly, lz, rx, ry, rz, pad, mode, estop = _INPUT.unpack(data)
    return HidInput(lx, ly, lz, rx, ry, rz, pad & 0x0F, pad >> 4, mode, estop)


def encode_hid_output(report: HidOutput) -> bytes:
    head = _OUTPUT_HEAD.pack(report.key, report.value, report.string_key)
    return head + report.text.encode("latin-1").ljust(OUTPUT_TEXT_LENGTH, b"\0")


def decode_hid_output(data: bytes) -> HidOutput | HidRejection:
    """The output report in ``data`` (what the simulator receives). Never raises."""
    if len(data) != OUTPUT_LENGTH:
        return HidRejection(len(data), OUTPUT_LENGTH)
    key, value, string_key = _OUTPUT_HEAD.unpack_from(data)
    text = data[_OUTPUT_HEAD.size :].split(b"\0", 1)[0].decode("latin-1")
    return HidOutput(key, value, string_key, text)
