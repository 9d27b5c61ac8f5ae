"""Messages and rejections as JSON-ready dicts: the stable output of ``srcsctl decode``.

Field names are the manual's names in snake_case; raw numbers stay numbers, and names are
added beside them (``vsc_mode`` and ``vsc_mode_name``). ``docs/protocol.md`` documents every
shape; changing one is a breaking change for integrators' scripts.
"""

from __future__ import annotations

from typing import Any

from supervisord.protocol.codes import (
    AutonomyMode,
    FeedbackKey,
    MessageType,
    StringKey,
    VscMode,
    estop_sources,
    user_value_name,
)
from supervisord.protocol.framing import Rejection
from supervisord.protocol.hid import HidInput, HidOutput, HidRejection
from supervisord.protocol.j1939 import (
    CanMessage,
    CanRejection,
    FeedbackStringSegment,
    JoystickBasic,
    JoystickExtended,
    j1939_value,
)
from supervisord.protocol.messages import (
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

JsonDict = dict[str, Any]


def _name(enum_type: type[VscMode | AutonomyMode | FeedbackKey | StringKey], value: int) -> str:
    member = enum_type.parse(value)
    return member.name.lower() if member is not None else "unknown"


def axis_json(axis: Axis, *, j1939: bool = False) -> JsonDict:
    """``value`` is the signed deflection, or null when the axis is invalid (PR-2.2); in a
    J1939 frame also when the magnitude is 1022 or 1023 (PR-3.2). The rest is the bits as sent."""
    return {
        "value": j1939_value(axis) if j1939 else axis.value,
        "magnitude": axis.magnitude,
        "neutral_status": int(axis.neutral),
        "negative_status": int(axis.negative),
        "positive_status": int(axis.positive),
    }


def buttons_json(buttons: DPad | NumberedButtons) -> JsonDict:
    names = buttons.__dataclass_fields__
    result: JsonDict = {"byte": buttons.to_byte()}
    result.update({f"{name}_status": int(getattr(buttons, name)) for name in names})
    result["pressed"] = [name for name in names if name in buttons.pressed]
    return result


def _key(key: int, table: type[FeedbackKey | StringKey]) -> JsonDict:
    name = user_value_name(key) or _name(table, key)
    return {"user_feedback_key": key, "user_feedback_key_name": name}


def message_json(message: Message | CanMessage) -> JsonDict:
    """The JSON object of one decoded message (serial or CAN)."""
    if isinstance(message, JoystickBasic | JoystickExtended | FeedbackStringSegment):
        return _can_only_json(message)
    match message:
        case Joystick():
            fields: JsonDict = {
                f"{name}_joystick_value": axis_json(getattr(message, name))
                for name in Joystick.AXES
            }
            fields["left_button_values"] = buttons_json(message.left_buttons)
            fields["right_button_values"] = buttons_json(message.right_buttons)
            return {"type": "joystick", **fields}
        case Gps(source=source, sentence=sentence):
            result: JsonDict = {"type": "gps", "source": source, "string": sentence}
            fix = message.fix
            if fix is not None:
                result.update(
                    sentence_type=fix.sentence_type,
                    utc_time=fix.utc_time.isoformat() if fix.utc_time else None,
                    latitude=fix.latitude,
                    longitude=fix.longitude,
                    fix_quality=fix.fix_quality,
                    valid=fix.valid,
                )
            return result
        case VscHeartbeat(mode=mode, autonomy_mode=autonomy, estop=estop):
            return {
                "type": "vsc_heartbeat",
                "vsc_mode": mode,
                "vsc_mode_name": _name(VscMode, mode),
                "autonomy_mode": autonomy,
                "autonomy_mode_name": _name(AutonomyMode, autonomy),
                "e_stop_indication": estop,
                "e_stop_sources": sorted(source.value for source in estop_sources(estop)),
            }
        case UserHeartbeat(estop=estop):
            return {"type": "user_heartbeat", "e_stop_indication": estop}
        case RemoteStatus():
            return {
                "type": "remote_status",
                "battery_level": message.battery_level,
                "battery_charging": message.battery_charging,
                "connection_strength_vsc": message.connection_strength_vsc,
                "connection_strength_src": message.connection_strength_src,
                "rssi_vsc": message.rssi_vsc,
                "rssi_src": message.rssi_src,
            }
        case MessageControl(message_type=kind, enabled=enabled, interval=interval):
            known = MessageType.parse(kind)
            return {
                "type": "message_control",
                "message_type": kind,
                "message_type_name": known.name.lower() if known else "unknown",
                "enabled": enabled,
                "interval": interval,
            }
        case FeedbackSet(key=key, value=value):
            return {"type": "feedback_set", **_key(key, FeedbackKey), "user_feedback_value": value}
        case FeedbackName(key=key, text=text):
            return {"type": "feedback_name", **_key(key, StringKey), "user_key_string": text}
        case FeedbackGet(key=key):
            return {"type": "feedback_get", **_key(key, FeedbackKey)}


def _can_only_json(message: JoystickBasic | JoystickExtended | FeedbackStringSegment) -> JsonDict:
    match message:
        case JoystickBasic(hand=hand, x=x, y=y, buttons=buttons):
            return {
                "type": "joystick_basic",
                "hand": hand.value,
                "x_joystick_value": axis_json(x, j1939=True),
                "y_joystick_value": axis_json(y, j1939=True),
                "button_values": buttons_json(buttons),
            }
        case JoystickExtended(hand=hand, z=z):
            return {
                "type": "joystick_extended",
                "hand": hand.value,
                "z_joystick_value": axis_json(z, j1939=True),
            }
        case FeedbackStringSegment(key=key, segment=segment, text=text):
            return {
                "type": "feedback_string_segment",
                **_key(key, StringKey),
                "segment": segment,
                "user_feedback_string": text,
            }


def rejection_json(rejection: Rejection | CanRejection | HidRejection) -> JsonDict:
    """The JSON object of one rejection: ``type`` is ``rejected`` and ``reason`` says why."""
    match rejection:
        case Rejection():
            return {
                "type": "rejected",
                "reason": rejection.reason.value,
                "byte_count": rejection.byte_count,
                "message_type": rejection.message_type,
                "length": rejection.length,
                "detail": rejection.detail,
            }
        case CanRejection(reason=reason, arbitration_id=ident, length=length):
            return {"type": "rejected", "reason": reason.value, "can_id": ident, "length": length}
        case HidRejection(length=length, expected=expected):
            return {
                "type": "rejected",
                "reason": "wrong_length",
                "length": length,
                "expected": expected,
            }


def hid_json(report: HidInput | HidOutput) -> JsonDict:
    """The JSON object of one HID report."""
    match report:
        case HidInput():
            direction = report.dpad_direction
            return {
                "type": "hid_input",
                "left_x": report.left_x,
                "left_y": report.left_y,
                "left_z": report.left_z,
                "right_x": report.right_x,
                "right_y": report.right_y,
                "right_z": report.right_z,
                "directional_pad": report.dpad,
                "directional_pad_name": direction.name.lower() if direction else "unknown",
                "numbered_buttons": report.buttons,
                "pressed": sorted(report.pressed),
                "src_state": report.mode,
                "src_state_name": _name(VscMode, report.mode),
                "e_stop_value": report.estop,
            }
        case HidOutput():
            return {
                "type": "hid_output",
                **_key(report.key, FeedbackKey),
                "user_feedback_value": report.value,
                "user_feedback_string_key": report.string_key,
                "user_feedback_string_value": report.text,
            }
