"""The pure mapping from API pushes to the bridge's message fields (docs/ros2.md)."""

from __future__ import annotations

import dataclasses
import math

import pytest

from supervisord.api.messages import AxisReport, GpsReport
from supervisord.api.pushes import read_push
from supervisord.api.status import EstopAvailable, StateReport
from supervisord.api.views import gps_report, joystick_report
from supervisord.protocol.codes import FieldStatus
from supervisord.protocol.messages import Axis, DPad, Gps, Joystick, NumberedButtons
from supervisord.ros2.mapping import (
    FixStatus,
    axis_value,
    display_rows,
    estop_available_of,
    estop_of,
    gps_fix,
    joy_values,
    state_of,
)
from supervisord.vocabulary import State
from supervisord.wire import WireError
from tests.api.samples import status_reply

SET = FieldStatus.SET
GGA = "$GPGGA,123519,4807.038,N,01131.000,E,1,08,0.9,545.4,M,46.9,M,,*47"


def _joystick(**values: int) -> Joystick:
    axes = {name: Axis.from_value(value) for name, value in values.items()}
    return Joystick(
        **axes,
        left_buttons=DPad(left=SET),
        right_buttons=NumberedButtons(button_1=SET, button_4=SET),
    )


def _quality(quality: int, *, valid: bool) -> GpsReport:
    """The GGA push with another fix quality and validity."""
    report = gps_report(Gps(1, GGA))
    assert report.fix is not None
    fix = dataclasses.replace(report.fix, fix_quality=quality, valid=valid)
    return dataclasses.replace(report, fix=fix)


def _state(state: State) -> StateReport:
    return StateReport(state=state, mono_ns=0, causes=(), outputs={}, heartbeat_estop=1)


def test_axes_scale_to_unit_range_in_driver_order() -> None:
    """Full deflection is exactly +-1, and the axes keep the public drivers' order."""
    values = joy_values(joystick_report(_joystick(left_x=1023, left_y=-1023, right_z=512)))
    assert values.axes == (1.0, -1.0, 0.0, 0.0, 0.0, 512 / 1023)


def test_invalid_or_out_of_range_axis_is_zero() -> None:
    """An invalid axis (value null) or one out of range reads as neutral."""
    invalid = Axis(FieldStatus.ERROR, FieldStatus.NOT_SET, FieldStatus.NOT_SET, 500)
    report = joystick_report(Joystick(left_x=invalid))
    assert report.left_x.value is None
    assert joy_values(report).axes == (0.0,) * 6
    assert axis_value(dataclasses.replace(report.left_y, value=4000)) == 0.0
    assert axis_value(AxisReport(value=-4000, magnitude=0, neutral_status=0,
                                 negative_status=1, positive_status=0)) == 0.0  # fmt: skip


def test_buttons_left_pad_then_numbered() -> None:
    """Buttons 0-3 are the left pad (down, right, up, left), 4-7 the right buttons 1-4."""
    assert joy_values(joystick_report(_joystick())).buttons == (0, 0, 0, 1, 1, 0, 0, 1)
    assert joy_values(joystick_report(Joystick())).buttons == (0,) * 8


def test_state_and_estop_rule() -> None:
    """estop is true unless the supervisor is reached and in RUN or HOLD; no supervisor
    counts as STOPPED, and a state outside SR-1's three (``run``) is refused by the client's
    reader (the shared vocabulary is strict), never read as RUN."""
    assert state_of(_state(State.RUN)) is State.RUN
    odd = {"event": "state", "state": "run", "mono_ns": 0, "causes": [], "outputs": {}}
    with pytest.raises(WireError, match="not a State"):
        read_push({**odd, "heartbeat_estop": 1})
    assert state_of(None) is State.STOPPED
    assert [estop_of(s) for s in (State.RUN, State.HOLD, State.STOPPED)] == [False, False, True]


def test_estop_available_only_when_the_status_reply_says_so() -> None:
    """SR-8.11: the ``estop_available`` topic is true only for a ``status`` reply saying
    ``available: true``; no supervisor or a reply without the field (an older daemon) is
    false, with the reason."""
    low = "the remote's battery is 10 %, below 20 %"
    reply = status_reply(_state(State.RUN))
    available = EstopAvailable(available=True, missing=())
    not_available = EstopAvailable(available=False, missing=(low,))
    yes = dataclasses.replace(reply, estop_available=available)
    no = dataclasses.replace(reply, estop_available=not_available)
    assert estop_available_of(yes) == (True, ())
    assert estop_available_of(no) == (False, (low,))
    assert estop_available_of(None) == (False, ("the supervisor is not reached",))
    older = dataclasses.replace(reply, estop_available=None)
    assert estop_available_of(older) == (False, ("the supervisor does not say",))


def test_gga_becomes_a_fix_with_ellipsoid_altitude() -> None:
    """A GGA push gives its position, its quality as a NavSatStatus and the altitude above
    the ellipsoid (MSL plus geoid separation)."""
    fix = gps_fix(gps_report(Gps(1, GGA)))
    assert fix is not None
    assert fix.status is FixStatus.FIX
    assert (fix.latitude, fix.longitude) == (48.1173, 11.516666666666667)
    assert math.isclose(fix.altitude, 545.4 + 46.9)
    assert gps_fix(_quality(5, valid=True)).status is FixStatus.GBAS_FIX  # type: ignore[union-attr]


def test_no_fix_and_other_sentences() -> None:
    """A GGA without a fix is NO_FIX with NaN position; an RMC or an unreadable sentence
    gives no message at all."""
    fix = gps_fix(_quality(0, valid=False))
    assert fix is not None
    assert fix.status is FixStatus.NO_FIX
    assert math.isnan(fix.latitude)
    rmc = "$GPRMC,123519,A,4807.038,N,01131.000,E,022.4,084.4,230394,003.1,W*6A"
    assert gps_fix(gps_report(Gps(1, rmc))) is None
    assert gps_fix(gps_report(Gps(1, "$GPGGA,,"))) is None


def test_display_rows_cut_cleaned_and_padded() -> None:
    """Four rows of at most 20 Latin-1 printable characters: longer lines cut, characters
    the remote cannot show replaced, missing rows blank, a fifth line dropped."""
    assert display_rows("a\nb") == ("a", "b", "", "")
    assert display_rows("x" * 30)[0] == "x" * 20
    assert display_rows("caf\u00e9 \u2603\ttab\0") == ("caf\u00e9 ??tab?", "", "", "")
    assert display_rows("1\r\n2\n3\n4\n5") == ("1", "2", "3", "4")
