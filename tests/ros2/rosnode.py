"""A test's own rclpy node, in the test process, and the bridge as a process (docs/ros2.md
"Testing"): each test gets a ROS domain of its own and localhost-only discovery, inside the
session's private network namespace (docs/testing.md "Network")."""

from __future__ import annotations

import itertools
import os
import sys
import warnings
from collections.abc import Callable
from pathlib import Path
from typing import Any

import rclpy
from diagnostic_msgs.msg import DiagnosticArray
from geometry_msgs.msg import Twist
from rclpy.context import Context
from rclpy.executors import SingleThreadedExecutor
from rclpy.signals import SignalHandlerOptions
from sensor_msgs.msg import Joy, NavSatFix
from std_msgs.msg import Bool, String
from std_srvs.srv import Trigger

from supervisord.ros2.node import LATCHED, NODE_NAME, STREAM

with warnings.catch_warnings():
    # rclpy loads the message type support through rosidl's parser, which imports lark,
    # which imports the deprecated sre_parse: not ours to fix, and the session makes every
    # warning an error. Loading it once here keeps the deprecation out of the tests.
    warnings.simplefilter("ignore", DeprecationWarning)
    import rosidl_generator_py  # noqa: F401
from supervisord.testkit.clients import ClientProcess
from supervisord.testkit.wait import WAIT_S, wait_until
from supervisord.tooling.polling import poll_until

_DOMAINS = itertools.count()


def ros_environment() -> dict[str, str]:
    """A ROS domain for one test (0-101 are safe with Fast DDS's port formula; the session's
    network namespace keeps other runs apart anyway) and discovery on localhost only, the
    way Jazzy asks for it (its ``ROS_LOCALHOST_ONLY`` is deprecated and would override it)."""
    return {
        "ROS_DOMAIN_ID": str((os.getpid() + next(_DOMAINS)) % 100 + 1),
        "ROS_AUTOMATIC_DISCOVERY_RANGE": "LOCALHOST",
    }


class BridgeProcess(ClientProcess):
    """``srcs-ros2`` as a process (``python -m supervisord.cli.ros2``), for ``Robot``'s
    ``client_processes`` so that ``arm`` counts it as the required client ``ros``."""

    def __init__(self, socket_path: Path, log: Path, *params: str) -> None:
        super().__init__(socket_path, "client", log, name="ros")
        args = [f"socket:={socket_path}", "client_name:=ros", *params]
        self.command = [sys.executable, "-m", "supervisord.cli.ros2", "--ros-args"]
        self.command += [word for arg in args for word in ("-p", arg)]


class RosPeer:
    """The test's node: records every message of the bridge's topics, publishes its inputs,
    calls its services. Only this thread spins it (``spin_until``)."""

    def __init__(self) -> None:
        self.context = Context()
        rclpy.init(context=self.context, signal_handler_options=SignalHandlerOptions.NO)
        self.node = rclpy.create_node("srcs_test", context=self.context)
        self.executor = SingleThreadedExecutor(context=self.context)
        self.executor.add_node(self.node)
        self.joy: list[Joy] = []
        self.state: list[str] = []
        self.estop: list[bool] = []
        self.ready: list[bool] = []
        self.available: list[bool] = []
        self.gps: list[NavSatFix] = []
        self.cmd_out: list[Twist] = []
        self.diagnostics: list[DiagnosticArray] = []
        n = self.node
        n.create_subscription(Joy, "joy", self.joy.append, STREAM)
        n.create_subscription(String, "state", self._on_state, LATCHED)
        n.create_subscription(Bool, "estop", self._on_estop, LATCHED)
        n.create_subscription(Bool, "ready", self._on_ready, LATCHED)
        n.create_subscription(Bool, "estop_available", self._on_available, LATCHED)
        n.create_subscription(NavSatFix, "gps", self.gps.append, STREAM)
        n.create_subscription(Twist, "cmd_vel_out", self.cmd_out.append, STREAM)
        n.create_subscription(DiagnosticArray, "/diagnostics", self.diagnostics.append, STREAM)
        self.cmd_in = n.create_publisher(Twist, "cmd_vel_in", STREAM)
        self.display = n.create_publisher(String, "display", STREAM)
        self.services = {
            name: n.create_client(Trigger, name)
            for name in ("estop", "release_estop", "hold", "release_hold")
        }

    def _on_state(self, msg: String) -> None:
        self.state.append(msg.data)

    def _on_estop(self, msg: Bool) -> None:
        self.estop.append(msg.data)

    def _on_ready(self, msg: Bool) -> None:
        self.ready.append(msg.data)

    def _on_available(self, msg: Bool) -> None:
        self.available.append(msg.data)

    def spin_until(
        self, condition: Callable[[], Any], timeout: float = WAIT_S, what: str = ""
    ) -> Any:
        """Spin until ``condition`` returns something true; that value, or a failure naming
        ``what`` after ``timeout`` seconds."""
        return wait_until(
            condition,
            timeout,
            poll=0.02,
            what=what,
            pause=lambda seconds: self.executor.spin_once(timeout_sec=seconds),
        )

    def call(self, service: str) -> Trigger.Response:
        """Call one of the bridge's Trigger services and wait for its response."""
        client = self.services[service]
        self.spin_until(client.service_is_ready, what=f"the {service} service")
        future = client.call_async(Trigger.Request())
        self.spin_until(future.done, what=f"the {service} response")
        response = future.result()
        assert response is not None
        return response

    def supervisor(self) -> dict[str, str] | None:
        """The key-values of the latest supervisor diagnostic, with ``level`` and
        ``message`` added; None before the first."""
        for array in reversed(self.diagnostics):
            for status in array.status:
                if status.name == "srcs: supervisor":
                    values = {kv.key: kv.value for kv in status.values}
                    values["level"] = str(status.level[0])
                    values["message"] = status.message
                    return values
        return None

    def close(self) -> None:
        """Destroy the node once the bridge's departure is seen in the graph. Fast DDS has
        crashed this process twice in ``destroy_node`` (a segmentation fault that ended the
        whole run), each time just after the bridge's process ended: its discovery thread
        taking the leaving participant while the node is torn down. Spinning until the bridge
        is gone from the graph (or for at most ``WAIT_S``) lets that work finish first; the
        node leaves the executor before it is destroyed."""
        poll_until(
            lambda: NODE_NAME not in self.node.get_node_names(),
            bool,
            WAIT_S,
            lambda seconds: self.executor.spin_once(timeout_sec=seconds),
            0.05,
        )
        self.executor.remove_node(self.node)
        self.executor.shutdown()
        self.node.destroy_node()
        self.context.try_shutdown()
