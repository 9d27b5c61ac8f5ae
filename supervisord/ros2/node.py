"""The rclpy edge of ``srcs-ros2``: topics, services, parameters and timers (docs/ros2.md).

Thin on purpose: field values come from :mod:`~supervisord.ros2.mapping` and
:mod:`~supervisord.ros2.diagnostics`, the velocity gate is :mod:`~supervisord.ros2.gate`, the
socket is :mod:`~supervisord.ros2.link`. Everything runs on one single-threaded executor, the
heartbeat included: a stalled ROS process stops sending heartbeats, and with the bridge's name
in ``[[clients]]`` the supervisor stops the robot (SR-8).
"""

from __future__ import annotations

import signal
import time
from collections.abc import Callable, Mapping
from types import FrameType
from typing import Any, cast

import rclpy
import rclpy.utilities
from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus, KeyValue
from geometry_msgs.msg import Twist, TwistStamped
from rclpy.executors import ExternalShutdownException, SingleThreadedExecutor
from rclpy.node import Node
from rclpy.qos import DurabilityPolicy, QoSProfile, ReliabilityPolicy
from rclpy.signals import SignalHandlerOptions
from rclpy.subscription import Subscription
from sensor_msgs.msg import Joy, NavSatFix, NavSatStatus
from std_msgs.msg import Bool, String
from std_srvs.srv import Trigger

from supervisord.api.messages import GpsReport, JoystickReport, RemoteStatusReport
from supervisord.api.pushes import GpsPush, JoystickPush, RemoteStatusPush, StatePush
from supervisord.api.readiness import missing
from supervisord.api.status import DaemonStatus, StateReport
from supervisord.client import StatusReply, SupervisorClient
from supervisord.ros2.command import Declaration, nonzero
from supervisord.ros2.diagnostics import Status, remote_status, supervisor_status
from supervisord.ros2.gate import VelocityGate, Verdict
from supervisord.ros2.link import Connected, LinkEvent, Lost, SupervisorLink
from supervisord.ros2.mapping import display_rows as rows_of
from supervisord.ros2.mapping import (
    estop_available_of,
    estop_of,
    gps_fix,
    joy_values,
    state_of,
)
from supervisord.ros2.parameters import PARAMETERS
from supervisord.vocabulary import State

NODE_NAME = "srcs_bridge"
LATCHED = QoSProfile(
    depth=1, reliability=ReliabilityPolicy.RELIABLE, durability=DurabilityPolicy.TRANSIENT_LOCAL
)
"""``state`` and ``estop``: a late subscriber gets the latest value at once."""
STREAM = QoSProfile(depth=10, reliability=ReliabilityPolicy.RELIABLE)
"""Everything else: the ROS default (reliable, volatile, keep the last 10)."""
TEXT_PAGE = 1  # the remote's display mode "text rows" (docs/api.md "display")
# rclpy from Iron on passes the middleware's source time with each message; Humble's does not.
_HAS_MESSAGE_INFO = hasattr(Subscription, "CallbackType")


class BridgeNode(Node):
    """The bridge node. :meth:`close` before destroying it: a last zero command if the gate
    was open, ``estop`` true, and the connection closed."""

    def __init__(self, **options: Any) -> None:
        super().__init__(NODE_NAME, **options)
        for name, default in PARAMETERS.items():
            self.declare_parameter(name, default)
        p = {name: self.get_parameter(name).value for name in PARAMETERS}
        periods = ("heartbeat_period", "request_timeout", "reconnect_period", "poll_period")
        for name in (*periods, "diagnostics_period", "cmd_vel_max_age"):
            if not isinstance(p[name], float) or not p[name] > 0:
                raise ValueError(f"parameter {name} must be a positive number of seconds")
        self.socket = str(p["socket"])
        self.client_name = str(p["client_name"])
        self.frame_id = str(p["frame_id"])
        self.stamped = bool(p["cmd_vel_stamped"])
        self.link = SupervisorLink(
            self.socket,
            self.client_name,
            timeout=float(p["request_timeout"]),
            retry_s=float(p["reconnect_period"]),
        )
        self.gate = VelocityGate(int(float(p["cmd_vel_max_age"]) * 1e9))
        self.declaration = Declaration()  # SR-4.6: no re-arm while cmd_vel_in moves
        self._state: State | None = None
        self._status: StateReport | None = None
        self._daemon: DaemonStatus | None = None
        self._remote: RemoteStatusReport | None = None
        self._shown: tuple[Status, Status] | None = None
        self._last_frame = ""

        self.joy_pub = self.create_publisher(Joy, "joy", STREAM)
        self.state_pub = self.create_publisher(String, "state", LATCHED)
        self.estop_pub = self.create_publisher(Bool, "estop", LATCHED)
        self.ready_pub = self.create_publisher(Bool, "ready", LATCHED)
        self._ready: bool | None = None
        self.available_pub = self.create_publisher(Bool, "estop_available", LATCHED)
        self._available: tuple[bool, tuple[str, ...]] | None = None
        self.diag_pub = self.create_publisher(DiagnosticArray, "/diagnostics", STREAM)
        self.gps_pub = self.create_publisher(NavSatFix, "gps", STREAM)
        kind = TwistStamped if self.stamped else Twist
        self.cmd_pub = self.create_publisher(kind, "cmd_vel_out", STREAM)
        if self.stamped:
            self.create_subscription(TwistStamped, "cmd_vel_in", self._on_stamped, STREAM)
        elif _HAS_MESSAGE_INFO:
            # Iron's rclpy on passes (message, info) to a callback that takes two arguments.
            on_twist = cast("Callable[[Twist], None]", self._on_twist_info)
            self.create_subscription(Twist, "cmd_vel_in", on_twist, STREAM)
        else:
            self.create_subscription(Twist, "cmd_vel_in", self._on_twist, STREAM)
        self.create_subscription(String, "display", self._on_display, STREAM)
        for service, call in (
            ("estop", lambda c: c.estop()),
            ("release_estop", lambda c: c.release("estop")),
            ("hold", lambda c: c.hold()),
            ("release_hold", lambda c: c.release("hold")),
        ):
            self.create_service(Trigger, service, self._trigger(call))

        self._set_state(State.STOPPED)  # until the supervisor says otherwise
        self._set_ready(False)
        self._set_available(None)
        self._publish_diagnostics(force=True)
        self.create_timer(float(p["poll_period"]), self._on_poll)
        self.create_timer(float(p["heartbeat_period"]), self._on_heartbeat)
        self.create_timer(float(p["diagnostics_period"]), self._on_diagnostics)
        self._on_poll()

    # -- timers ---------------------------------------------------------------------------

    def _on_poll(self) -> None:
        was = self.link.connected
        self.link.service(time.monotonic())
        if self.link.connected and not was:
            self.link.heartbeat()  # a new start needs a heartbeat at once (docs/api.md hello)
        self._handle(self.link.take())
        self._declare()

    def _on_heartbeat(self) -> None:
        self.link.heartbeat()
        self._handle(self.link.take())

    def _on_diagnostics(self) -> None:
        status = self.link.status()
        if status is not None:
            self._on_reply(status)
        self._handle(self.link.take())
        self._publish_diagnostics(force=True)

    # -- what the supervisor says ---------------------------------------------------------

    def _handle(self, events: list[LinkEvent]) -> None:
        for event in events:
            if isinstance(event, Connected):
                self.get_logger().info(f"connected to {self.socket} as {self.client_name}")
                self.declaration.connected()
                self._on_reply(event.status)
            elif isinstance(event, Lost):
                self.get_logger().error(f"lost the supervisor: {event.reason}")
                self._status = None
                self._set_state(State.STOPPED)
                self._set_ready(False)
                self._set_available(None)
            elif isinstance(event, StatePush):
                self._on_status(event.report)
            elif isinstance(event, JoystickPush):
                self._publish_joy(event.message)
            elif isinstance(event, GpsPush):
                self._publish_gps(event.message)
            elif isinstance(event, RemoteStatusPush):
                self._remote = event.message
        self._publish_diagnostics()

    def _on_reply(self, status: StatusReply) -> None:
        """A whole ``status`` reply: the state, the daemon, readiness and the e-stop."""
        self._daemon = status.daemon
        self._on_status(status.report)
        self._set_ready(not missing(status))
        self._set_available(status)

    def _on_status(self, report: StateReport) -> None:
        self._status = report
        self._set_state(state_of(report))

    def _set_state(self, state: State) -> None:
        if self.gate.state(state):
            self._publish_zero()  # RUN just ended: one zero command at once, then nothing
        if state is self._state:
            return
        old, self._state = self._state, state
        self.state_pub.publish(String(data=state.name))
        if old is None or estop_of(old) != estop_of(state):
            self.estop_pub.publish(Bool(data=estop_of(state)))

    def _set_ready(self, ready: bool) -> None:
        """``ready``: the stop path works (SR-8.10), latched, on a change; from the full
        ``status`` the bridge asks for at each diagnostics period."""
        if ready is not self._ready:
            self._ready = ready
            self.ready_pub.publish(Bool(data=ready))

    def _set_available(self, status: StatusReply | None) -> None:
        """``estop_available``: the remote e-stop is available (SR-8.11), latched, on a
        change; from the full ``status`` (a ``state`` push does not carry it), ``None``: the
        supervisor is not reached. Kept with its missing parts for the diagnostics."""
        available = estop_available_of(status)
        if self._available is None or available[0] is not self._available[0]:
            self.available_pub.publish(Bool(data=available[0]))
        self._available = available

    def _publish_joy(self, message: JoystickReport) -> None:
        values = joy_values(message)
        msg = Joy(axes=list(values.axes), buttons=list(values.buttons))
        msg.header.stamp = self.get_clock().now().to_msg()
        msg.header.frame_id = self.frame_id
        self.joy_pub.publish(msg)

    def _publish_gps(self, message: GpsReport) -> None:
        fix = gps_fix(message)
        if fix is None:
            return
        msg = NavSatFix(latitude=fix.latitude, longitude=fix.longitude, altitude=fix.altitude)
        msg.header.stamp = self.get_clock().now().to_msg()
        msg.header.frame_id = self.frame_id
        msg.status.status = int(fix.status)
        msg.status.service = NavSatStatus.SERVICE_GPS
        msg.position_covariance_type = NavSatFix.COVARIANCE_TYPE_UNKNOWN
        self.gps_pub.publish(msg)

    def _publish_diagnostics(self, *, force: bool = False) -> None:
        supervisor = supervisor_status(
            self._status,
            self._daemon,
            socket=self.socket,
            client_name=self.client_name,
            gate=self.gate.counts,
            unreachable=self.link.reason,
            estop_available=self._available,
        )
        shown = (supervisor, remote_status(self._remote, supervisor.hardware_id))
        if not force and self._shown is not None and _same(self._shown, shown):
            return  # only on a change between the 1 Hz ones (docs/ros2.md "Diagnostics")
        self._shown = shown
        msg = DiagnosticArray(status=[_diagnostic(status) for status in shown])
        msg.header.stamp = self.get_clock().now().to_msg()
        self.diag_pub.publish(msg)

    # -- what ROS says --------------------------------------------------------------------

    def _on_twist(self, msg: Twist) -> None:
        self._gated(msg, None, 0)

    def _on_twist_info(self, msg: Twist, info: Mapping[str, int]) -> None:
        # The middleware's source time is the wall clock of the publishing process.
        self._gated(msg, info.get("source_timestamp"), time.time_ns())

    def _on_stamped(self, msg: TwistStamped) -> None:
        stamp = msg.header.stamp
        sent = stamp.sec * 1_000_000_000 + stamp.nanosec
        self._last_frame = msg.header.frame_id
        self._gated(msg, sent, self.get_clock().now().nanoseconds)

    def _gated(self, msg: Twist | TwistStamped, sent_ns: int | None, now_ns: int) -> None:
        twist = msg.twist if isinstance(msg, TwistStamped) else msg
        linear, angular = twist.linear, twist.angular
        self.declaration.command(
            nonzero((linear.x, linear.y, linear.z, angular.x, angular.y, angular.z))
        )
        self._declare()  # before anything is forwarded: the supervisor knows first (SR-4.6)
        if self.gate.command(sent_ns, now_ns) is Verdict.FORWARD:
            self.cmd_pub.publish(msg)

    def _declare(self) -> None:
        """Tell the supervisor whether ``cmd_vel_in`` commands motion, when it does not know
        yet on this connection (SR-4.6). A refusal is logged and not repeated; a lost
        connection declares again once it is back."""
        value = self.declaration.due()
        if value is None or not self.link.connected:
            return
        ok, why = self.link.request(lambda client: client.command(value))
        if ok or self.link.connected:
            self.declaration.sent(value)
        if not ok:
            self.get_logger().warning(f"cmd_vel_in {'non-zero' if value else 'zero'}: {why}")
        self._handle(self.link.take())

    def _publish_zero(self) -> None:
        if self.stamped:
            zero = TwistStamped()
            zero.header.stamp = self.get_clock().now().to_msg()
            zero.header.frame_id = self._last_frame
            self.cmd_pub.publish(zero)
        else:
            self.cmd_pub.publish(Twist())

    def _on_display(self, msg: String) -> None:
        rows = rows_of(msg.data)
        for index, row in enumerate(rows, start=1):
            ok, why = self.link.request(_row(index, row))
            if not ok:
                self.get_logger().warning(f"display row {index} not shown: {why}")
        self.link.request(lambda c: c.display_mode(TEXT_PAGE))
        self._handle(self.link.take())

    def _trigger(
        self, call: Callable[[SupervisorClient], object]
    ) -> Callable[[Trigger.Request, Trigger.Response], Trigger.Response]:
        def serve(request: Trigger.Request, response: Trigger.Response) -> Trigger.Response:
            ok, why = self.link.request(call)
            response.success, response.message = ok, why
            self._handle(self.link.take())
            return response

        return serve

    # -- the end --------------------------------------------------------------------------

    def close(self) -> None:
        """The gate closes (a zero command if it was open), ``estop`` true, the connection
        closed: if this client is required, the supervisor now stops the robot."""
        self._status = None
        self._set_state(State.STOPPED)
        self.link.close()


def _row(index: int, text: str) -> Callable[[SupervisorClient], None]:
    return lambda client: client.display_row(index, text)


def _same(a: tuple[Status, Status], b: tuple[Status, Status]) -> bool:
    """Equal but for the counters that change with every command (the gate's)."""

    def strip(s: Status) -> Status:
        values = tuple(kv for kv in s.values if not kv[0].startswith("cmd_vel"))
        return Status(s.level, s.name, s.message, s.hardware_id, values)

    return [strip(s) for s in a] == [strip(s) for s in b]


def _diagnostic(status: Status) -> DiagnosticStatus:
    return DiagnosticStatus(
        level=bytes([int(status.level)]),
        name=status.name,
        message=status.message,
        hardware_id=status.hardware_id,
        values=[KeyValue(key=k, value=v) for k, v in status.values],
    )


def run(args: list[str] | None = None) -> int:
    """Run the bridge until SIGTERM or SIGINT; 0 then, 2 for a bad parameter."""
    rclpy.init(args=args, signal_handler_options=SignalHandlerOptions.NO)
    stop: list[int] = []

    def on_signal(signum: int, frame: FrameType | None) -> None:
        stop.append(signum)

    signal.signal(signal.SIGTERM, on_signal)
    signal.signal(signal.SIGINT, on_signal)
    try:
        try:
            node = BridgeNode()
        except ValueError as e:
            print(f"srcs-ros2: {e}", flush=True)
            return 2
        executor = SingleThreadedExecutor()
        executor.add_node(node)
        try:
            while not stop:
                executor.spin_once(timeout_sec=0.1)
        except ExternalShutdownException:
            pass
        finally:
            node.close()
            executor.shutdown()
            node.destroy_node()
    finally:
        rclpy.utilities.try_shutdown()
    return 0
