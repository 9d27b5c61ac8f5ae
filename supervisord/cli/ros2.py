"""``srcs-ros2``: the ROS 2 bridge (docs/ros2.md). Parameters come the ROS way::

    srcs-ros2 --ros-args -p socket:=/run/srcsd/api.sock -p client_name:=ros

rclpy is not a dependency of this package: on a robot it comes from the ROS installation
(``source /opt/ros/jazzy/setup.bash``). Without it the program says so and exits 2; ``--help``
and ``--version`` need no rclpy.
"""

from __future__ import annotations

import argparse
import sys
import textwrap

from supervisord import __version__
from supervisord.ros2.parameters import PARAMETERS

ROS_ARGS = "--ros-args"


def build_parser() -> argparse.ArgumentParser:
    """The bridge's own options (``--help``, ``--version``); everything from ``--ros-args`` on
    is ROS's, read by rclpy."""
    defaults = ", ".join(f"{name} ({value!r})" for name, value in PARAMETERS.items())
    parser = argparse.ArgumentParser(
        prog="srcs-ros2",
        usage="%(prog)s [-h] [--version] [--ros-args -p NAME:=VALUE ... | --params-file FILE]",
        description=textwrap.fill(
            "The ROS 2 bridge to srcsd, the safety supervisor: its state, causes and remote as "
            "topics, its e-stop, hold and display as services, a client heartbeat (ros2.md in "
            "/usr/share/doc/srcs-supervisord/docs). Needs rclpy from a ROS 2 installation "
            "(source /opt/ros/DISTRO/setup.bash)."
        ),
        epilog=textwrap.fill(f"Parameters, with their defaults: {defaults}.")
        + "\n\nexample:\n  srcs-ros2 --ros-args -p socket:=/run/srcsd/api.sock",
        formatter_class=argparse.RawDescriptionHelpFormatter,  # the example's own line
    )
    parser.add_argument("--version", action="version", version=f"%(prog)s {__version__}")
    return parser


def main(argv: list[str] | None = None) -> int:
    args = sys.argv if argv is None else ["srcs-ros2", *argv]
    own = args[1 : args.index(ROS_ARGS)] if ROS_ARGS in args else args[1:]
    # Other words before --ros-args are left to rclpy, as before (a launch file's own).
    build_parser().parse_known_args(own)
    try:
        from supervisord.ros2.node import run  # noqa: PLC0415 -- rclpy only when asked for
    except ImportError as e:
        print(f"srcs-ros2: cannot load rclpy ({e}); source the ROS 2 setup first", flush=True)
        return 2
    return run(args)


if __name__ == "__main__":
    sys.exit(main())
