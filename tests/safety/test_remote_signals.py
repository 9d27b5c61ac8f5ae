"""What the safety core makes of two remote signals that differ by hardware: a switched-off
remote (PR-2.6) and a CAN joystick axis with a reserved magnitude (PR-3.2)."""

from __future__ import annotations

import pytest

from supervisord.protocol.codes import FieldStatus
from supervisord.protocol.messages import Axis, Joystick
from supervisord.safety import State
from tests.safety.rig import LOCAL, SEARCHING, Rig

REMOTE_BUTTON, REMOTE_LINK = 0x01, 0x02


@pytest.mark.parametrize(
    ("mode", "estop"),
    [(SEARCHING, REMOTE_LINK), (LOCAL, REMOTE_BUTTON)],
    ids=["searching-0x02", "local-0x01"],
)
def test_a_switched_off_remote_stops_however_the_vsc_reports_it(mode: int, estop: int) -> None:
    """PR-2.6, SR-2.1: a remote switched off, reported as Searching with bit 0x02 or as Local
    with the remote's e-stop bit 0x01, stops a running robot and names the e-stop bits."""
    rig = Rig()
    rig.bring_up()
    rig.advance(10)
    decision = rig.vsc(mode, estop)
    assert decision.state is State.STOPPED
    assert not any(decision.outputs.values())
    assert any(name.startswith("vsc_estop") for name in decision.active_names)


@pytest.mark.parametrize("magnitude", [1021, 1022, 1023])
def test_a_reserved_axis_magnitude_neither_stops_nor_starts_anything(magnitude: int) -> None:
    """PR-3.2, SR-3.1: the core gates motion on the VSC's mode and e-stop word, never on the
    sticks, so a joystick whose axes are invalid (a J1939 error or not-available magnitude)
    changes no state and no output, while running and while stopped."""
    invalid = Axis(FieldStatus.ERROR, FieldStatus.ERROR, FieldStatus.ERROR, magnitude)
    joystick = Joystick(left_x=invalid, right_y=Axis.from_value(magnitude))
    rig = Rig()
    running = rig.bring_up()
    rig.advance(10)
    after = rig.from_vsc(joystick)
    assert after.state is State.RUN
    assert after.outputs == running.outputs
    assert after.active_names == running.active_names
    rig.advance(10)
    stopped = rig.vsc(LOCAL, REMOTE_BUTTON)
    assert stopped.state is State.STOPPED
    rig.advance(10)
    assert rig.from_vsc(joystick).state is State.STOPPED
