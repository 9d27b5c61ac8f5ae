"""The pure mapping from API pushes to the bridge's message fields (docs/ros2.md)."""

from __future__ import annotations

import math
from typing import Any

from supervisord.ros2.mapping import (
    FixStatus,
    State,
    display_rows,
    estop_available_of,
    estop_of,
    gps_fix,
    joy_values,
    state_of,
)


def _joystick(**values: int | None) -> dict[str, Any]:
    push: dict[str, Any] = {"event": "joystick", "type": "joystick"}
    for name in ("left_x", "left_y", "left_z", "right_x", "right_y", "right_z"):
        push[f"{name}_joystick_value"] = {"value": values.get(name, 0)}
    push["left_button_values"] = {"pressed": ["left"]}
    push["right_button_values"] = {"pressed": ["button_1", "button_4"]}
    return push


def test_axes_scale_to_unit_range_in_driver_order() -> None:
    """Full deflection is exactly +-1, and the axes keep the public drivers' order."""
    values = joy_values(_joystick(left_x=1023, left_y=-1023, right_z=512))
    assert values.axes == (1.0, -1.0, 0.0, 0.0, 0.0, 512 / 1023)


def test_invalid_or_missing_axis_is_zero() -> None:
    """An invalid axis (value null), a missing one or one out of range reads as neutral."""
    push = _joystick(left_x=None, right_x=4000)
    del push["left_y_joystick_value"]
    push["left_z_joystick_value"] = "garbage"
    assert joy_values(push).axes == (0.0,) * 6


def test_buttons_left_pad_then_numbered() -> None:
    """Buttons 0-3 are the left pad (down, right, up, left), 4-7 the right buttons 1-4."""
    assert joy_values(_joystick()).buttons == (0, 0, 0, 1, 1, 0, 0, 1)
    assert joy_values({}).buttons == (0,) * 8


def test_state_and_estop_rule() -> None:
    """estop is true unless the supervisor is reached and in RUN or HOLD; unreadable or
    unreachable counts as STOPPED."""
    assert state_of({"state": "RUN"}) is State.RUN
    assert state_of({"state": "run"}) is State.STOPPED
    assert state_of(None) is State.STOPPED
    assert [estop_of(s) for s in (State.RUN, State.HOLD, State.STOPPED)] == [False, False, True]


def test_estop_available_only_when_the_status_reply_says_so() -> None:
    """SR-8.11: the ``estop_available`` topic is true only for a ``status`` reply saying
    ``available: true``; no supervisor, a reply without the field (an older daemon) or with
    a wrong type is false, with the reason."""
    low = "the remote's battery is 10 %, below 20 %"
    assert estop_available_of({"estop_available": {"available": True, "missing": []}}) == (
        True,
        (),
    )
    assert estop_available_of({"estop_available": {"available": False, "missing": [low]}}) == (
        False,
        (low,),
    )
    assert estop_available_of(None) == (False, ("the supervisor is not reached",))
    assert estop_available_of({"state": "RUN"}) == (False, ("the supervisor does not say",))
    assert estop_available_of({"estop_available": {"available": "yes"}})[0] is False


def test_gga_becomes_a_fix_with_ellipsoid_altitude() -> None:
    """A GGA push gives its position, its quality as a NavSatStatus and the altitude above
    the ellipsoid (MSL plus geoid separation)."""
    push = {
        "sentence_type": "GGA",
        "string": "$GPGGA,123519,4807.038,N,01131.000,E,1,08,0.9,545.4,M,46.9,M,,*47",
        "latitude": 48.1173,
        "longitude": 11.516666666666667,
        "fix_quality": 1,
        "valid": True,
    }
    fix = gps_fix(push)
    assert fix is not None
    assert fix.status is FixStatus.FIX
    assert (fix.latitude, fix.longitude) == (48.1173, 11.516666666666667)
    assert math.isclose(fix.altitude, 545.4 + 46.9)
    assert gps_fix({**push, "fix_quality": 5}).status is FixStatus.GBAS_FIX  # type: ignore[union-attr]


def test_no_fix_and_other_sentences() -> None:
    """A GGA without a fix is NO_FIX with NaN position; an RMC gives no message at all."""
    fix = gps_fix({"sentence_type": "GGA", "fix_quality": 0, "valid": False})
    assert fix is not None
    assert fix.status is FixStatus.NO_FIX
    assert math.isnan(fix.latitude)
    assert gps_fix({"sentence_type": "RMC", "latitude": 1.0}) is None


def test_display_rows_cut_cleaned_and_padded() -> None:
    """Four rows of at most 20 Latin-1 printable characters: longer lines cut, characters
    the remote cannot show replaced, missing rows blank, a fifth line dropped."""
    assert display_rows("a\nb") == ("a", "b", "", "")
    assert display_rows("x" * 30)[0] == "x" * 20
    assert display_rows("caf\u00e9 \u2603\ttab\0") == ("caf\u00e9 ??tab?", "", "", "")
    assert display_rows("1\r\n2\n3\n4\n5") == ("1", "2", "3", "4")
