"""Payload bytes of each HRI packet message type, both ways (manual §8.3, PR-2).

``decode_payload`` is only called with a payload of the length ``payload_length_ok``
accepted; with such a payload it cannot fail.
"""

from __future__ import annotations

import struct

from supervisord.protocol.codes import MessageType
from supervisord.protocol.messages import (
    _AXES_BY_WORD,
    NAME_TEXT_LENGTH,
    Axis,
    DPad,
    FeedbackGet,
    FeedbackName,
    FeedbackSet,
    Gps,
    Joystick,
    Message,
    MessageControl,
    NumberedButtons,
    RemoteStatus,
    UserHeartbeat,
    VscHeartbeat,
)

# Fixed payload lengths (manual §8.3); GPS is 1..248 (source byte plus the sentence).
FIXED_LENGTH: dict[MessageType, int] = {
    MessageType.JOYSTICK: 14,
    MessageType.VSC_HEARTBEAT: 6,
    MessageType.USER_HEARTBEAT: 1,
    MessageType.REMOTE_STATUS: 6,
    MessageType.MESSAGE_CONTROL: 4,
    MessageType.FEEDBACK_SET: 5,
    MessageType.FEEDBACK_NAME: 1 + NAME_TEXT_LENGTH,
    MessageType.FEEDBACK_GET: 1,
}
GPS_MIN_LENGTH = 1

_JOYSTICK = struct.Struct("<6HBB")
_VSC_HEARTBEAT = struct.Struct("<BBI")
_REMOTE_STATUS = struct.Struct("<6B")
_MESSAGE_CONTROL = struct.Struct("<BBH")
_FEEDBACK = struct.Struct("<Bi")


_SETTERS = tuple(
    Joystick.__dict__[name].__set__ for name in (*Joystick.AXES, "left_buttons", "right_buttons")
)
"""The slots of a joystick value, set directly by :func:`decode_joystick`."""
_DPADS: dict[int, DPad] = {}  # by wire byte: at most 256 each
_NUMBERED: dict[int, NumberedButtons] = {}


def decode_joystick(data: bytes, offset: int = 0) -> Joystick:
    """The joystick message whose 14-byte payload starts at ``offset`` of ``data``.

    Every moving-stick frame is new (50 a second, SR-9.4), so this is the decoder's one
    decode per input: its parts are the wire's immutable values (``Axis.from_word``,
    ``from_byte``: each a value the validating constructors made once), so the value is
    put together without running ``Joystick``'s checks again; it equals the one the
    constructor makes (``tests/protocol/test_decode_reuse.py``)."""
    lx, ly, lz, rx, ry, rz, left, right = _JOYSTICK.unpack_from(data, offset)
    axis, word = _AXES_BY_WORD.get, Axis.from_word
    joystick = _NEW(Joystick)
    set_lx, set_ly, set_lz, set_rx, set_ry, set_rz, set_left, set_right = _SETTERS
    set_lx(joystick, axis(lx) or word(lx))
    set_ly(joystick, axis(ly) or word(ly))
    set_lz(joystick, axis(lz) or word(lz))
    set_rx(joystick, axis(rx) or word(rx))
    set_ry(joystick, axis(ry) or word(ry))
    set_rz(joystick, axis(rz) or word(rz))
    dpad = _DPADS.get(left)
    if dpad is None:
        dpad = _DPADS[left] = DPad.from_byte(left)
    numbered = _NUMBERED.get(right)
    if numbered is None:
        numbered = _NUMBERED[right] = NumberedButtons.from_byte(right)
    set_left(joystick, dpad)
    set_right(joystick, numbered)
    return joystick


_NEW = object.__new__


def payload_length_ok(message_type: MessageType, length: int) -> bool:
    if message_type is MessageType.GPS:
        return length >= GPS_MIN_LENGTH
    return FIXED_LENGTH[message_type] == length


def encode_payload(message: Message) -> bytes:
    """The payload bytes of ``message``."""
    match message:
        case Joystick():
            words = (axis.to_word() for axis in message.axes)
            return _JOYSTICK.pack(
                *words, message.left_buttons.to_byte(), message.right_buttons.to_byte()
            )
        case Gps(source=source, sentence=sentence):
            return bytes((source,)) + sentence.encode("latin-1")
        case VscHeartbeat(mode=mode, autonomy_mode=autonomy, estop=estop):
            return _VSC_HEARTBEAT.pack(mode, autonomy, estop)
        case UserHeartbeat(estop=estop):
            return bytes((estop,))
        case RemoteStatus():
            return _REMOTE_STATUS.pack(
                message.battery_level,
                message.battery_charging,
                message.connection_strength_vsc,
                message.connection_strength_src,
                message.rssi_vsc,
                message.rssi_src,
            )
        case MessageControl(message_type=kind, enabled=enabled, interval=interval):
            return _MESSAGE_CONTROL.pack(kind, enabled, interval)
        case FeedbackSet(key=key, value=value):
            return _FEEDBACK.pack(key, value)
        case FeedbackName(key=key, text=text):
            return bytes((key,)) + text.encode("latin-1").ljust(NAME_TEXT_LENGTH, b"\0")
        case FeedbackGet(key=key):
            return bytes((key,))


def decode_payload(message_type: MessageType, payload: bytes) -> Message:
    """The message in ``payload``, whose length ``payload_length_ok`` has accepted."""
    match message_type:
        case MessageType.JOYSTICK:
            return decode_joystick(payload)
        case MessageType.GPS:
            return Gps(payload[0], payload[1:].decode("latin-1"))
        case MessageType.VSC_HEARTBEAT:
            return VscHeartbeat(*_VSC_HEARTBEAT.unpack(payload))
        case MessageType.USER_HEARTBEAT:
            return UserHeartbeat(payload[0])
        case MessageType.REMOTE_STATUS:
            return RemoteStatus(*_REMOTE_STATUS.unpack(payload))
        case MessageType.MESSAGE_CONTROL:
            return MessageControl(*_MESSAGE_CONTROL.unpack(payload))
        case MessageType.FEEDBACK_SET:
            return FeedbackSet(*_FEEDBACK.unpack(payload))
        case MessageType.FEEDBACK_NAME:
            text = payload[1:].split(b"\0", 1)[0]
            return FeedbackName(payload[0], text.decode("latin-1"))
        case MessageType.FEEDBACK_GET:
            return FeedbackGet(payload[0])
