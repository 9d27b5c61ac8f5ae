"""The ROS 2 bridge's distribution, ``srcs_ros2`` (docs/ros2.md "Install"): a wheel with pip,
an ament_python package with colcon, ``python3-srcs-ros2`` with packaging/build_ros2_deb.py.

Name, version, description and licence come from ``package.xml``. The wheel requires nothing
from pip: rclpy and the message packages are the ``exec_depend``s there, which rosdep installs
from the robot's ROS distribution. The modules under ``supervisord/`` here are links into the
repository's own: the bridge and the client library it imports, nothing of the daemon
(docs/ros2.md "The client library")."""

from pathlib import Path
from xml.etree import ElementTree

from setuptools import setup

MANIFEST = Path(__file__).resolve().parent / "package.xml"
PACKAGE = ElementTree.parse(MANIFEST).getroot()  # noqa: S314 -- our own file, not a peer's


def _field(name: str) -> str:
    return " ".join(PACKAGE.findtext(name, "").split())


NAME = _field("name")

setup(
    name=NAME,
    version=_field("version"),
    description=_field("description"),
    license=_field("license"),
    python_requires=">=3.10",
    packages=[
        "supervisord",
        "supervisord.api",
        "supervisord.cli",
        "supervisord.protocol",
        "supervisord.record",
        "supervisord.ros2",
    ],
    package_data={"supervisord": ["py.typed"]},
    data_files=[
        # What makes it a ROS package in a colcon install: the ament index marker and the
        # manifest. In a wheel they are data, installed under the environment's share/.
        ("share/ament_index/resource_index/packages", [f"resource/{NAME}"]),
        (f"share/{NAME}", ["package.xml"]),
    ],
    entry_points={"console_scripts": ["srcs-ros2 = supervisord.cli.ros2:main"]},
)
