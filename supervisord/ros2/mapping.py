"""API pushes to the field values of the bridge's ROS messages: pure, no ROS import.

Each function takes one push or reply as ``supervisord.client`` returns it (the typed values
of ``supervisord.api``, ``docs/api.md`` "Pushes") and returns plain values that the rclpy edge
copies into a message. A push the client could not read never gets here (the client refuses
it and the bridge reconnects, STOPPED meanwhile); a value out of its range maps to the safe
value (an axis 0, the state STOPPED, no GPS fix).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Final

from supervisord.api.messages import AxisReport, GpsReport, JoystickReport
from supervisord.api.replies import StatusReply
from supervisord.api.status import StateReport
from supervisord.compat import IntEnum
from supervisord.vocabulary import State

AXES: Final = ("left_x", "left_y", "left_z", "right_x", "right_y", "right_z")
"""``sensor_msgs/Joy`` axes 0-5, the order of the public drivers (docs/ros2.md "joy")."""
BUTTONS: Final = (
    ("left", "down"),
    ("left", "right"),
    ("left", "up"),
    ("left", "left"),
    ("right", "button_1"),
    ("right", "button_2"),
    ("right", "button_3"),
    ("right", "button_4"),
)
"""``sensor_msgs/Joy`` buttons 0-7: the left pad in wire order, then the right buttons 1-4."""
FULL_SCALE: Final = 1023  # manual table 19: an axis is -1023..1023
TEXT_ROWS: Final = 4  # the remote's text page has four rows (docs/api.md "display")
ROW_LENGTH: Final = 20  # of 20 single-byte characters each


def state_of(report: StateReport | None) -> State:
    """The state of a ``state`` push or ``status`` reply; ``None`` (the supervisor cannot be
    reached) is STOPPED: the bridge never vouches for motion it cannot see (docs/ros2.md
    "state"); a state this bridge does not know never reads (the shared vocabulary's, strict).
    The ``state`` topic names it as the API does (``STOPPED``: :attr:`State.name`)."""
    if report is None:
        return State.STOPPED
    return report.state


def estop_of(state: State) -> bool:
    """The ``estop`` topic: true unless the supervisor is reached and in RUN or HOLD. HOLD
    is not an e-stop (SR-3: the motion outputs are off but nothing latched)."""
    return state not in (State.RUN, State.HOLD)


def estop_available_of(status: StatusReply | None) -> tuple[bool, tuple[str, ...]]:
    """The ``estop_available`` topic and the parts missing, from a ``status`` reply
    (SR-8.11, docs/api.md "status"): false unless the reply says true, so a supervisor not
    reached, or one too old to say, is never taken for an available e-stop."""
    if status is None:
        return False, ("the supervisor is not reached",)
    if status.estop_available is None:
        return False, ("the supervisor does not say",)
    return status.estop_available.available, status.estop_available.missing


@dataclass(frozen=True, slots=True)
class JoyValues:
    """``sensor_msgs/Joy`` ``axes`` (each -1..1) and ``buttons`` (each 0 or 1)."""

    axes: tuple[float, ...]
    buttons: tuple[int, ...]


def axis_value(axis: AxisReport) -> float:
    """One axis of a joystick push scaled to -1..1; an invalid axis (``value`` null) or one
    out of range is 0.0, the neutral stick (docs/ros2.md "joy")."""
    raw = axis.value
    if raw is None or abs(raw) > FULL_SCALE:
        return 0.0
    return raw / FULL_SCALE


def joy_values(message: JoystickReport) -> JoyValues:
    """The ``joy`` message of one joystick push (``docs/api.md`` "Pushes")."""
    axes = tuple(axis_value(axis) for axis in message.axes().values())
    hands = {"left": message.left_buttons.pressed, "right": message.right_buttons.pressed}
    buttons = tuple(int(name in hands[hand]) for hand, name in BUTTONS)
    return JoyValues(axes, buttons)


class FixStatus(IntEnum):
    """``sensor_msgs/NavSatStatus`` ``status`` values."""

    NO_FIX = -1
    FIX = 0
    SBAS_FIX = 1
    GBAS_FIX = 2


# GGA fix quality (NMEA 0183): 0 invalid, 1 GPS, 2 DGPS (SBAS), 4 RTK fixed, 5 RTK float.
_QUALITY: Final = {1: FixStatus.FIX, 2: FixStatus.SBAS_FIX, 4: FixStatus.GBAS_FIX}
_QUALITY_RTK_FLOAT: Final = 5


@dataclass(frozen=True, slots=True)
class Fix:
    """``sensor_msgs/NavSatFix`` values of one GGA sentence. ``altitude`` is above the WGS 84
    ellipsoid (GGA's height above mean sea level plus its geoid separation), NaN when the
    sentence lacks either."""

    status: FixStatus
    latitude: float
    longitude: float
    altitude: float


def gps_fix(message: GpsReport) -> Fix | None:
    """The ``gps`` message of a GPS push, or ``None`` when it is no GGA sentence (only GGA
    carries a position fix with its quality). A GGA without a valid fix gives ``NO_FIX``
    with NaN coordinates, as ``sensor_msgs/NavSatFix`` asks."""
    fix = message.fix
    if fix is None or fix.sentence_type != "GGA":
        return None
    latitude, longitude, quality = fix.latitude, fix.longitude, fix.fix_quality
    if not fix.valid or latitude is None or longitude is None or not quality:
        return Fix(FixStatus.NO_FIX, math.nan, math.nan, math.nan)
    if not math.isfinite(latitude) or not math.isfinite(longitude):
        return Fix(FixStatus.NO_FIX, math.nan, math.nan, math.nan)
    status = FixStatus.GBAS_FIX if quality == _QUALITY_RTK_FLOAT else _QUALITY.get(quality)
    return Fix(
        status or FixStatus.FIX, float(latitude), float(longitude), _altitude(message.string)
    )


def _altitude(sentence: str) -> float:
    """GGA fields 9 (altitude above mean sea level, m) plus 11 (geoid separation, m)."""
    fields = sentence.split("*", 1)[0].split(",")
    try:
        if fields[10] != "M" or fields[12] != "M":
            return math.nan
        total = float(fields[9]) + float(fields[11])
    except (IndexError, ValueError):
        return math.nan
    return total if math.isfinite(total) else math.nan


def display_rows(text: str) -> tuple[str, ...]:
    """The four text rows of the remote's LCD for one ``display`` message: its lines, each
    cut to 20 characters, characters the remote cannot show (beyond Latin-1, control
    characters) replaced by ``?``; missing rows are blank, lines past the fourth dropped."""
    lines = text.split("\n")[:TEXT_ROWS]
    rows = [_printable(line.rstrip("\r"))[:ROW_LENGTH] for line in lines]
    return tuple(rows + [""] * (TEXT_ROWS - len(rows)))


def _printable(line: str) -> str:
    return "".join(ch if 0x20 <= ord(ch) <= 0xFF and ord(ch) != 0x7F else "?" for ch in line)
