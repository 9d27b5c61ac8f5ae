"""The bridge's ROS parameters and their defaults (docs/ros2.md "Parameters"): pure, so the
docs and examples can be checked against them without rclpy."""

from __future__ import annotations

from collections.abc import Mapping

PARAMETERS: Mapping[str, object] = {
    "socket": "/run/srcsd/api.sock",
    "client_name": "ros",
    "heartbeat_period": 0.1,
    "request_timeout": 0.3,
    "reconnect_period": 0.5,
    "poll_period": 0.01,
    "diagnostics_period": 1.0,
    "frame_id": "srcs",
    "cmd_vel_stamped": False,
    "cmd_vel_max_age": 0.2,
}
"""Every parameter and its default (docs/ros2.md "Parameters")."""
