"""The CAN (SAE J1939 style) messages of manual §9 and PR-3, without any I/O.

Frames are ``CanFrame`` values (29-bit id and data) that the daemon turns into python-can
messages. Ids are matched on PGN and source address; the 3 priority bits are ignored, as
J1939 receivers do. Unused bytes are sent as ``FF`` and not checked on receipt.

A joystick axis magnitude of 1022 means error and 1023 not available (PR-3.2, J1939's
convention for the top values of a parameter), whatever the axis's statuses say; 0..1021 are
deflections. The frames (``decode_can``) keep the bits as sent; ``j1939_value`` reads them.
The ``JoystickAssembler`` turns a reserved magnitude into the error or not-available status,
so that the serial ``Joystick`` it builds means the same to every reader of ``Axis.value``
(the API's joystick push, the ROS bridge). ``j1939_axis`` is the other direction: a
deflection past 1021 is sent as 1021, never as a marker.
"""

from __future__ import annotations

import enum
import struct
from dataclasses import dataclass

from supervisord.compat import IntEnum
from supervisord.protocol.codes import FieldStatus
from supervisord.protocol.messages import (
    Axis,
    DPad,
    FeedbackSet,
    Joystick,
    NumberedButtons,
    RemoteStatus,
    VscHeartbeat,
    check_range,
    check_text,
)

CAN_ID_MASK = 0x1FFF_FFFF
_PRIORITY_MASK = 0x1C00_0000
_PRIORITY_3 = 0x0C00_0000
PAD = 0xFF
SEGMENT_TEXT_LENGTH = 6
SEGMENT_COUNT = 3  # the VSC joins three 6-character segments into 18 characters (manual §9.2.7)


MAGNITUDE_ERROR = 1022  # PR-3.2
MAGNITUDE_NOT_AVAILABLE = 1023  # PR-3.2
MAGNITUDE_MAX = 1021
"""PR-3.2: the largest magnitude a J1939 joystick frame carries as a deflection."""
_RESERVED = {MAGNITUDE_ERROR: FieldStatus.ERROR, MAGNITUDE_NOT_AVAILABLE: FieldStatus.NOT_AVAILABLE}


def serial_axis(axis: Axis) -> Axis:
    """``axis`` from a J1939 frame in the serial message's terms (PR-3.2): a reserved
    magnitude becomes the error or not-available status on all three, so ``value`` is
    ``None``; any other axis is returned as it is."""
    status = _RESERVED.get(axis.magnitude)
    return axis if status is None else Axis(status, status, status, axis.magnitude)


def j1939_value(axis: Axis) -> int | None:
    """The deflection of an axis from a J1939 frame, ``None`` when invalid (PR-2.2, PR-3.2)."""
    return serial_axis(axis).value


def j1939_axis(axis: Axis) -> Axis:
    """``axis`` as a J1939 frame may carry it (PR-3.2): a valid deflection past 1021 is sent
    as 1021, the nearest deflection that is not a marker; an invalid axis goes unchanged."""
    if axis.magnitude <= MAGNITUDE_MAX or axis.value is None:
        return axis
    return Axis(axis.neutral, axis.negative, axis.positive, MAGNITUDE_MAX)


class CanId(IntEnum):
    """The 29-bit ids of manual table 23 and PR-3 (priority 3)."""

    LEFT_BASIC = 0x0CFDD633
    LEFT_EXTENDED = 0x0CFDD733
    RIGHT_BASIC = 0x0CFDD834
    RIGHT_EXTENDED = 0x0CFDD934
    HEARTBEAT = 0x0CFDE801
    REMOTE_STATUS = 0x0CFDE861  # not in the manual; PR-3 (a public CAN database)
    FEEDBACK_VALUE = 0x0CFDE900
    FEEDBACK_STRING = 0x0CFDEA00


@dataclass(frozen=True, slots=True)
class CanFrame:
    """One CAN data frame: the id and up to 8 data bytes."""

    arbitration_id: int
    data: bytes
    is_extended_id: bool = True

    def __post_init__(self) -> None:
        limit = CAN_ID_MASK if self.is_extended_id else 0x7FF
        check_range("CAN id", self.arbitration_id, (0, limit))
        if not isinstance(self.data, bytes) or len(self.data) > 8:
            raise ValueError("CAN data must be at most 8 bytes")


class Hand(enum.Enum):
    LEFT = "left"
    RIGHT = "right"


@dataclass(frozen=True, slots=True)
class JoystickBasic:
    """Basic joystick message 1 (left, with the D-pad) or 2 (right, buttons 1-4), manual
    §9.2.1 and §9.2.3."""

    hand: Hand
    x: Axis
    y: Axis
    buttons: DPad | NumberedButtons

    def __post_init__(self) -> None:
        wanted = DPad if self.hand is Hand.LEFT else NumberedButtons
        if not isinstance(self.buttons, wanted):
            raise ValueError(f"the {self.hand.value} hand's buttons must be {wanted.__name__}")


@dataclass(frozen=True, slots=True)
class JoystickExtended:
    """Extended joystick message 1 or 2: the hand's Z axis (manual §9.2.2/4)."""

    hand: Hand
    z: Axis


@dataclass(frozen=True, slots=True)
class FeedbackStringSegment:
    """One third of an 18-character feedback string, to the VSC (manual §9.2.7)."""

    key: int
    segment: int
    text: str

    def __post_init__(self) -> None:
        check_range("feedback string key", self.key, (0, 0xFF))
        check_range("segment", self.segment, (0, SEGMENT_COUNT - 1))
        check_text("segment text", self.text, SEGMENT_TEXT_LENGTH)


CanMessage = (
    JoystickBasic
    | JoystickExtended
    | VscHeartbeat
    | RemoteStatus
    | FeedbackSet
    | FeedbackStringSegment
)


class CanRejectReason(enum.Enum):
    UNKNOWN_ID = "unknown_id"  # not a frame of manual §9 / PR-3
    WRONG_LENGTH = "wrong_length"  # fewer data bytes than the message needs
    STANDARD_ID = "standard_id"  # an 11-bit frame: every SRCS message has a 29-bit id
    BAD_VALUE = "bad_value"  # a field outside what the message can mean (segment over 2)


@dataclass(frozen=True, slots=True)
class CanRejection:
    """A CAN frame that is not a valid SRCS message."""

    reason: CanRejectReason
    arbitration_id: int
    length: int


_BASIC = struct.Struct("<HHBB")  # X, Y, unused (FF), buttons
_FEEDBACK = struct.Struct("<Bi")
_HEARTBEAT = struct.Struct("<BBI")
# Bytes each message needs; the rest of an 8-byte frame is padding.
_MIN_LENGTH: dict[CanId, int] = {
    CanId.LEFT_BASIC: 6,
    CanId.RIGHT_BASIC: 6,
    CanId.LEFT_EXTENDED: 2,
    CanId.RIGHT_EXTENDED: 2,
    CanId.HEARTBEAT: 6,
    CanId.REMOTE_STATUS: 6,
    CanId.FEEDBACK_VALUE: 5,
    CanId.FEEDBACK_STRING: 2 + SEGMENT_TEXT_LENGTH,
}


def _pad(data: bytes) -> bytes:
    return data.ljust(8, bytes((PAD,)))


def encode_can(message: CanMessage) -> CanFrame:
    """The CAN frame of ``message``, padded with ``FF`` to 8 bytes."""
    match message:
        case JoystickBasic(hand=hand, x=x, y=y, buttons=buttons):
            ident = CanId.LEFT_BASIC if hand is Hand.LEFT else CanId.RIGHT_BASIC
            return CanFrame(
                ident, _pad(_BASIC.pack(x.to_word(), y.to_word(), PAD, buttons.to_byte()))
            )
        case JoystickExtended(hand=hand, z=z):
            ident = CanId.LEFT_EXTENDED if hand is Hand.LEFT else CanId.RIGHT_EXTENDED
            return CanFrame(ident, _pad(struct.pack("<H", z.to_word())))
        case VscHeartbeat(mode=mode, autonomy_mode=autonomy, estop=estop):
            return CanFrame(CanId.HEARTBEAT, _pad(_HEARTBEAT.pack(mode, autonomy, estop)))
        case RemoteStatus():
            values = (
                message.battery_level,
                message.battery_charging,
                message.connection_strength_vsc,
                message.connection_strength_src,
                message.rssi_vsc,
                message.rssi_src,
            )
            return CanFrame(CanId.REMOTE_STATUS, _pad(bytes(values)))
        case FeedbackSet(key=key, value=value):
            return CanFrame(CanId.FEEDBACK_VALUE, _pad(_FEEDBACK.pack(key, value)))
        case FeedbackStringSegment(key=key, segment=segment, text=text):
            body = text.encode("latin-1").ljust(SEGMENT_TEXT_LENGTH, b"\0")
            return CanFrame(CanId.FEEDBACK_STRING, _pad(bytes((key, segment)) + body))


def feedback_string_frames(key: int, text: str) -> tuple[CanFrame, ...]:
    """The three segment frames that set feedback string ``key`` to ``text`` (≤ 18 chars)."""
    check_text("feedback string", text, SEGMENT_COUNT * SEGMENT_TEXT_LENGTH)
    return tuple(
        encode_can(FeedbackStringSegment(key, i, text[i * 6 : i * 6 + 6]))
        for i in range(SEGMENT_COUNT)
    )


def decode_can(frame: CanFrame) -> CanMessage | CanRejection:
    """The SRCS message in ``frame``, or why it is not one. Never raises."""
    data, ident = frame.data, frame.arbitration_id
    if not frame.is_extended_id:
        return CanRejection(CanRejectReason.STANDARD_ID, ident, len(data))
    try:
        key = CanId(ident & ~_PRIORITY_MASK | _PRIORITY_3)
    except ValueError:
        return CanRejection(CanRejectReason.UNKNOWN_ID, ident, len(data))
    needed = _MIN_LENGTH[key]
    if len(data) < needed:
        return CanRejection(CanRejectReason.WRONG_LENGTH, ident, len(data))
    match key:
        case CanId.LEFT_BASIC | CanId.RIGHT_BASIC:
            x, y, _, buttons = _BASIC.unpack_from(data)
            if key == CanId.LEFT_BASIC:
                return JoystickBasic(
                    Hand.LEFT, Axis.from_word(x), Axis.from_word(y), DPad.from_byte(buttons)
                )
            return JoystickBasic(
                Hand.RIGHT, Axis.from_word(x), Axis.from_word(y), NumberedButtons.from_byte(buttons)
            )
        case CanId.LEFT_EXTENDED | CanId.RIGHT_EXTENDED:
            hand = Hand.LEFT if key == CanId.LEFT_EXTENDED else Hand.RIGHT
            return JoystickExtended(hand, Axis.from_word(data[0] | data[1] << 8))
        case CanId.HEARTBEAT:
            return VscHeartbeat(*_HEARTBEAT.unpack_from(data))
        case CanId.REMOTE_STATUS:
            return RemoteStatus(*data[:6])
        case CanId.FEEDBACK_VALUE:
            return FeedbackSet(*_FEEDBACK.unpack_from(data))
        case CanId.FEEDBACK_STRING:
            text = data[2:8].split(b"\0", 1)[0].decode("latin-1")
            segment = data[1]
            if segment >= SEGMENT_COUNT:
                return CanRejection(CanRejectReason.BAD_VALUE, ident, len(data))
            return FeedbackStringSegment(data[0], segment, text)


class JoystickAssembler:
    """Joins the four CAN joystick messages into the serial ``Joystick`` value.

    Each basic or extended message replaces its hand's part; every message returns the whole
    joystick as it now stands. Parts never received are neutral. A reserved magnitude becomes
    the error or not-available status (``serial_axis``, PR-3.2), so ``Axis.value`` of the
    result means what ``j1939_value`` of the frame means.
    """

    def __init__(self) -> None:
        self._parts: dict[str, Axis | DPad | NumberedButtons] = {}

    def update(self, message: JoystickBasic | JoystickExtended) -> Joystick:
        side = message.hand.value
        if isinstance(message, JoystickBasic):
            self._parts[f"{side}_x"] = serial_axis(message.x)
            self._parts[f"{side}_y"] = serial_axis(message.y)
            self._parts[f"{side}_buttons"] = message.buttons
        else:
            self._parts[f"{side}_z"] = serial_axis(message.z)
        return Joystick(**self._parts)  # type: ignore[arg-type]  # keys are Joystick's fields
