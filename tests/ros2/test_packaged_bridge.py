"""The bridge as it ships (packaging/build_ros2_deb.py), end to end, by two of the routes of
docs/ros2.md "Install": the ``python3-srcs-ros2`` package's launcher run by Debian's own
python3 from the unpacked package, and the wheel installed with pip into a venv on that python3
made with ``--system-site-packages``. rclpy and the messages are the ROS 2 Jazzy wheels, put on
``PYTHONPATH`` as a ROS setup file puts its own. Against the real ``srcsd`` and ``srcs-sim``,
in the session's private network namespace (docs/ros2.md "Testing")."""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import sysconfig
from collections.abc import Iterator
from pathlib import Path

import pytest

try:
    from tests.ros2.rosnode import BridgeProcess, RosPeer, ros_environment
except ImportError as error:  # rclpy's libraries are not on the library path
    if os.environ.get("SRCS_ROS2_TESTS") == "required":  # ./dev test: never a silent skip
        raise
    pytest.skip(
        f"rclpy cannot be loaded ({error}); ./dev test installs requirements/ros2.txt",
        allow_module_level=True,
    )

from supervisord.testkit.robot import Robot
from tests.packaging.test_ros2_deb import SITE, SYSTEM_PYTHON, build_packages, environment, unpack

pytestmark = pytest.mark.usefixtures("private_network")


JAZZY = sysconfig.get_paths()["purelib"]
"""Where ./dev test installs the Jazzy wheels (built for this machine's Python 3.11)."""


class PackagedBridge(BridgeProcess):
    """``launcher`` (the package's or the venv's ``srcs-ros2``) instead of ``python -m
    supervisord.cli.ros2``, with the Python path a ROS setup file would give it."""

    def __init__(self, launcher: Path, python_path: str, socket_path: Path, log: Path) -> None:
        super().__init__(socket_path, log)
        self.command[: self.command.index("--ros-args")] = [str(launcher)]
        self.env = environment(PYTHONPATH=python_path)

    def start(self) -> PackagedBridge:
        with self.log_path.open("ab") as log:
            self.process = subprocess.Popen(
                self.command, stdin=subprocess.DEVNULL, stdout=log, stderr=log, env=self.env
            )
        return self


@pytest.fixture(scope="module")
def built(tmp_path_factory: pytest.TempPathFactory) -> tuple[Path, Path]:
    """The package and the wheel, built from this tree."""
    if not SYSTEM_PYTHON.exists():
        pytest.fail(f"{SYSTEM_PYTHON} is missing: the launcher's interpreter")
    return build_packages(tmp_path_factory.mktemp("build"))


@pytest.fixture(params=["deb", "wheel"])
def route(
    request: pytest.FixtureRequest, built: tuple[Path, Path], tmp_path: Path
) -> tuple[Path, str, Path | None]:
    """The launcher to run, its Python path, and the tree it must leave without byte-code
    (the package's: dpkg would not own it; pip's venv compiles at install)."""
    deb, wheel = built
    if request.param == "deb":
        root = unpack(deb, tmp_path / "unpacked")
        return root / "usr/bin/srcs-ros2", f"{root / SITE.lstrip('/')}:{JAZZY}", root
    venv = tmp_path / "venv"
    subprocess.run(
        [SYSTEM_PYTHON, "-m", "venv", "--without-pip", "--system-site-packages", venv],
        check=True,
        timeout=120,
    )
    pip = [sys.executable, "-m", "pip", "--disable-pip-version-check", "-q"]
    pip += ["--python", str(venv / "bin/python"), "install", "--no-index", "--no-deps"]
    subprocess.run([*pip, wheel], check=True, capture_output=True, timeout=120)
    return venv / "bin/srcs-ros2", JAZZY, None


@pytest.fixture
def ros(monkeypatch: pytest.MonkeyPatch) -> Iterator[RosPeer]:
    """The test node, in a ROS domain of this test's own; the bridge inherits the domain."""
    for key, value in ros_environment().items():
        monkeypatch.setenv(key, value)
    node = RosPeer()
    try:
        yield node
    finally:
        node.close()


def test_the_packaged_bridge_runs_against_srcsd(
    route: tuple[Path, str, Path | None], tmp_path: Path, ros: RosPeer
) -> None:
    """The shipped bridge says hello to ``srcsd`` as its required client, so a takeover
    brings RUN, which it publishes on ``state`` and ``estop``; SIGTERM ends it with 0. The
    package's launcher writes no byte-code into its tree."""
    launcher, python_path, clean = route
    with Robot(tmp_path, clients=("ros",)) as running:
        bridge = PackagedBridge(launcher, python_path, running.socket_path, tmp_path / "log")
        running.client_processes["ros"] = bridge.start()
        ros.spin_until(lambda: (ros.supervisor() or {}).get("connected") == "true", what="hello")
        running.arm()
        ros.spin_until(lambda: ros.state[-1:] == ["RUN"], what="state RUN")
        ros.spin_until(lambda: ros.estop[-1:] == [False], what="estop false")
        bridge.signal(signal.SIGTERM)
        assert bridge.process is not None
        assert bridge.process.wait(timeout=10) == 0, bridge.log()
        assert "Traceback" not in bridge.log(), bridge.log()
    if clean is not None:
        assert not list(clean.rglob("__pycache__"))
