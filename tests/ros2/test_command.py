"""What the bridge declares of ``cmd_vel_in`` (SR-4.6, docs/ros2.md "Re-arm only at zero
command"), without ROS: the verdict on a command and when the supervisor is told."""

from __future__ import annotations

import math

from supervisord.ros2.command import Declaration, nonzero


def test_any_component_other_than_zero_is_motion() -> None:
    """SR-4.6: a command moves the robot when any of its six components is not zero; minus
    zero is zero, and NaN is no zero command."""
    assert not nonzero((0.0,) * 6)
    assert not nonzero((-0.0, 0.0, 0.0, 0.0, 0.0, -0.0))
    for index in range(6):
        components = [0.0] * 6
        components[index] = 1e-9
        assert nonzero(components)
    assert nonzero((math.nan, 0.0, 0.0, 0.0, 0.0, 0.0))


def test_the_supervisor_is_told_on_a_change_and_again_after_a_reconnect() -> None:
    """SR-4.6: nothing is due while the command is zero (undeclared is zero); a non-zero
    command is due once, and stays the verdict until a zero command; a new connection
    starts undeclared, so a non-zero verdict is due again there, a zero one is not."""
    declaration = Declaration()
    assert declaration.due() is None
    declaration.command(True)
    assert declaration.due() is True
    declaration.sent(True)
    assert declaration.due() is None
    declaration.command(True)
    assert declaration.due() is None
    declaration.connected()
    assert declaration.due() is True
    declaration.sent(True)
    declaration.command(False)
    assert declaration.due() is False
    declaration.sent(False)
    declaration.connected()
    assert declaration.due() is None


def test_a_declaration_not_sent_stays_due() -> None:
    """SR-4.6: until the supervisor has answered, the declaration stays due (the bridge
    sends it again at its next poll)."""
    declaration = Declaration()
    declaration.command(True)
    assert declaration.due() is True
    assert declaration.due() is True
