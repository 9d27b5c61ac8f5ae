"""``srcs-ros2``: the ROS 2 bridge (docs/ros2.md). Parameters come the ROS way::

    srcs-ros2 --ros-args -p socket:=/run/srcsd/api.sock -p client_name:=ros

rclpy is not a dependency of this package: on a robot it comes from the ROS installation
(``source /opt/ros/jazzy/setup.bash``). Without it the program says so and exits 2.
"""

from __future__ import annotations

import sys


def main(argv: list[str] | None = None) -> int:
    args = sys.argv if argv is None else ["srcs-ros2", *argv]
    if any(a in ("-h", "--help") for a in args[1:2]):
        print(__doc__)
        return 0
    try:
        from supervisord.ros2.node import run  # noqa: PLC0415 -- rclpy only when asked for
    except ImportError as e:
        print(f"srcs-ros2: cannot load rclpy ({e}); source the ROS 2 setup first", flush=True)
        return 2
    return run(args)


if __name__ == "__main__":
    sys.exit(main())
