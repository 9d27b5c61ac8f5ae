"""What the bridge tells the supervisor of the motion commanded on ``cmd_vel_in`` (SR-4.6,
docs/ros2.md "Re-arm only at zero command"). Pure: no ROS, no socket.

The latest command decides: non-zero from a command with any component not zero until a
zero command arrives (a planner that stopped publishing mid-motion still blocks a re-arm:
its controller's setpoint may still be that command). The supervisor is told on a change,
and again on every new connection, where it starts from "undeclared", which is zero.
"""

from __future__ import annotations

from collections.abc import Iterable


def nonzero(components: Iterable[float]) -> bool:
    """Whether a command moves the robot: any component other than zero. NaN counts as
    non-zero: a command nobody can read is no zero command."""
    return any(value != 0.0 for value in components)


class Declaration:
    """The latest command's verdict and what the supervisor was last told of it on the
    current connection."""

    def __init__(self) -> None:
        self.nonzero = False
        self._told = False  # a new connection is undeclared, which the supervisor takes as zero

    def command(self, moving: bool) -> None:
        """The latest command on ``cmd_vel_in`` is non-zero (``moving``) or zero."""
        self.nonzero = moving

    def connected(self) -> None:
        """A new connection: the supervisor knows no declaration of it yet."""
        self._told = False

    def due(self) -> bool | None:
        """The declaration to send now, or ``None`` when the supervisor has it already."""
        return None if self._told is self.nonzero else self.nonzero

    def sent(self, value: bool) -> None:
        """The supervisor answered the declaration ``value`` (or refused it: not sent again
        on this connection, a supervisor that refuses it refuses it every time)."""
        self._told = value
