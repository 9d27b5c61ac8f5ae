"""Start the SRCS bridge (docs/ros2.md): ``ros2 launch srcs_bridge.launch.py``.

The bridge is the ``srcs-ros2`` program (the ``python3-srcs-ros2`` package, or ``srcs_ros2`` built
with colcon), started here as a process with its parameters file. Remap the velocity gate onto the
robot's own topics here: the teleop or planner publishes to ``cmd_vel_in``, the base
controller listens on ``cmd_vel_out``.
"""

from pathlib import Path

from launch import LaunchDescription
from launch.actions import DeclareLaunchArgument, ExecuteProcess
from launch.substitutions import LaunchConfiguration

HERE = Path(__file__).resolve().parent


def generate_launch_description() -> LaunchDescription:
    namespace = LaunchConfiguration("namespace")
    params = LaunchConfiguration("params")
    return LaunchDescription(
        [
            DeclareLaunchArgument("namespace", default_value="srcs"),
            DeclareLaunchArgument("params", default_value=str(HERE / "srcs_bridge.yaml")),
            DeclareLaunchArgument("cmd_vel_in", default_value="/cmd_vel_teleop"),
            DeclareLaunchArgument("cmd_vel_out", default_value="/cmd_vel"),
            ExecuteProcess(
                cmd=[
                    "srcs-ros2",
                    "--ros-args",
                    "-r",
                    ["__ns:=/", namespace],
                    "--params-file",
                    params,
                    "-r",
                    ["cmd_vel_in:=", LaunchConfiguration("cmd_vel_in")],
                    "-r",
                    ["cmd_vel_out:=", LaunchConfiguration("cmd_vel_out")],
                ],
                output="screen",
                # A dead bridge stops the robot (it is a required client); start it again.
                respawn=True,
                respawn_delay=1.0,
            ),
        ]
    )
