"""The bridge's two ``diagnostic_msgs/DiagnosticStatus`` values: pure, no ROS import.

One status for the supervisor (level from its state, message the causes, a key-value per
cause with its details, the link and the counters) and one for the remote (battery, link
strength, RSSI). docs/ros2.md "Diagnostics" lists every key.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any, Final

from supervisord.compat import IntEnum
from supervisord.ros2.mapping import State, state_of

SUPERVISOR_NAME: Final = "srcs: supervisor"
REMOTE_NAME: Final = "srcs: remote"
LOW_BATTERY_PERCENT: Final = 20


class Level(IntEnum):
    """``diagnostic_msgs/DiagnosticStatus`` levels."""

    OK = 0
    WARN = 1
    ERROR = 2
    STALE = 3


@dataclass(frozen=True, slots=True)
class Status:
    """One ``DiagnosticStatus``: level, name, message, hardware id and key-values."""

    level: Level
    name: str
    message: str
    hardware_id: str
    values: tuple[tuple[str, str], ...]


@dataclass(frozen=True, slots=True)
class GateCounts:
    """The velocity gate's counters since the bridge started (docs/ros2.md "cmd_vel")."""

    forwarded: int = 0
    not_run: int = 0
    too_old: int = 0
    zeros: int = 0


_STATE_LEVEL: Final = {State.RUN: Level.OK, State.HOLD: Level.WARN, State.STOPPED: Level.ERROR}


def supervisor_status(
    status: Mapping[str, Any] | None,
    daemon: Mapping[str, Any] | None,
    *,
    socket: str,
    client_name: str,
    gate: GateCounts,
    unreachable: str = "",
    estop_available: tuple[bool, tuple[str, ...]] | None = None,
) -> Status:
    """The supervisor's status from its latest ``state`` push or ``status`` reply
    (``status``) and the ``daemon`` block of its latest ``status`` reply. ``status`` None:
    the supervisor cannot be reached (``unreachable`` says why), an ERROR (docs/ros2.md
    "Reconnects"). ``estop_available``: whether the remote e-stop is available and what is
    missing (SR-8.11), from the latest ``status`` reply; not available in RUN is a WARN."""
    robot = _text(daemon.get("robot")) if daemon else ""
    values: list[tuple[str, str]] = [("socket", socket), ("client name", client_name)]
    if status is None:
        values += [("connected", "false"), ("error", unreachable)]
        values += _gate_values(gate)
        message = f"supervisor unreachable: {unreachable}" if unreachable else "unreachable"
        return Status(Level.ERROR, SUPERVISOR_NAME, message, robot, tuple(values))
    state = state_of(status)
    causes = [c for c in status.get("causes", []) if isinstance(c, Mapping)]
    names = [_text(c.get("name")) for c in causes]
    values += [("connected", "true"), ("state", state.value)]
    values += [(_text(c.get("name")), _cause_text(c)) for c in causes]
    outputs = status.get("outputs")
    if isinstance(outputs, Mapping):
        values += [(f"output {name}", _flag(on)) for name, on in sorted(outputs.items())]
    values += [("heartbeat e-stop", _text(status.get("heartbeat_estop")))]
    level = _STATE_LEVEL[state]
    if estop_available is not None:
        available, parts = estop_available
        values += [("e-stop available", _flag(available))]
        values += [("e-stop missing", "; ".join(parts))] if not available else []
        if not available and level is Level.OK:
            level = Level.WARN  # RUN without a working remote e-stop: said, not stopped
    overdue: list[str] = []
    if daemon:
        values += _daemon_values(daemon)
        tests, overdue = _periodic_tests(daemon.get("maintenance"))
        values += tests
        if overdue and level is Level.OK:
            level = Level.WARN  # the evidence is old: said, the robot is not stopped (SR-12.2)
    values += _gate_values(gate)
    message = state.value + (": " + ", ".join(names) if names else "")
    if estop_available is not None and not estop_available[0]:
        message += "; remote e-stop not available"
    if overdue:
        message += f"; overdue: {', '.join(overdue)}"
    return Status(level, SUPERVISOR_NAME, message, robot, tuple(values))


PERIODIC_TESTS: Final = (("stoptest", "stop test"), ("prooftest", "proof test"))
"""The periodic tests of ``status``'s ``daemon.maintenance`` (SR-12.2) and their keys' names."""


def _periodic_tests(schedule: object) -> tuple[list[tuple[str, str]], list[str]]:
    """``stop test last pass age s``, ``stop test overdue`` and the proof test's two, and the
    names of the overdue tests."""
    values: list[tuple[str, str]] = []
    overdue: list[str] = []
    if not isinstance(schedule, Mapping):
        return values, overdue
    for test, name in PERIODIC_TESTS:
        due = schedule.get(test)
        if not isinstance(due, Mapping):
            continue
        age = due.get("last_pass_age_s")
        values.append((f"{name} last pass age s", "never" if age is None else _text(age)))
        values.append((f"{name} overdue", _flag(due.get("overdue"))))
        if due.get("overdue") is True:
            overdue.append(name)
    return values, overdue


def remote_status(push: Mapping[str, Any] | None, robot: str) -> Status:
    """The remote's status from its latest ``remote_status`` push. None yet: STALE, because
    the VSC sends it only once commissioned (``srcsctl commission``, docs/api.md)."""
    if push is None:
        message = "no remote status yet (the VSC sends it once commissioned)"
        return Status(Level.STALE, REMOTE_NAME, message, robot, ())
    battery = push.get("battery_level")
    strengths = (push.get("connection_strength_vsc"), push.get("connection_strength_src"))
    keys = (
        ("battery level %", "battery_level"),
        ("battery charging", "battery_charging"),
        ("link strength at the VSC", "connection_strength_vsc"),
        ("link strength at the remote", "connection_strength_src"),
        ("RSSI at the VSC", "rssi_vsc"),
        ("RSSI at the remote", "rssi_src"),
    )
    values = tuple((key, _text(push.get(field))) for key, field in keys)
    warnings = []
    if isinstance(battery, int) and battery < LOW_BATTERY_PERCENT:
        warnings.append(f"battery {battery} %")
    if any(s == 0 for s in strengths):
        warnings.append("no radio link")
    if warnings:
        return Status(Level.WARN, REMOTE_NAME, ", ".join(warnings), robot, values)
    return Status(Level.OK, REMOTE_NAME, f"battery {_text(battery)} %", robot, values)


def _cause_text(cause: Mapping[str, Any]) -> str:
    """``stop, active, latched; sources=remote`` for one cause of a ``status``."""
    words = [_text(cause.get("severity"))]
    words += [w for w in ("active", "latched") if cause.get(w) is True]
    details = cause.get("details")
    text = ", ".join(words)
    if isinstance(details, Mapping) and details:
        text += "; " + ", ".join(f"{k}={_text(v)}" for k, v in sorted(details.items()))
    return text


def _daemon_values(daemon: Mapping[str, Any]) -> list[tuple[str, str]]:
    values = [("robot", _text(daemon.get("robot"))), ("pid", _text(daemon.get("pid")))]
    link = daemon.get("link")
    if isinstance(link, Mapping):
        for key in ("description", "open", "opens", "open_failures"):
            value = link.get(key)
            values.append(
                (f"link {key}", _flag(value) if isinstance(value, bool) else _text(value))
            )
    values.append(("messages", _text(daemon.get("messages"))))
    rejections = daemon.get("rejections")
    if isinstance(rejections, Mapping):
        counts = [v for v in rejections.values() if isinstance(v, int)]
        values.append(("rejections", str(sum(counts))))
        values += [(f"rejections {k}", _text(v)) for k, v in sorted(rejections.items())]
    values += [(key, _text(daemon.get(key))) for key in ("record_errors", "internal_faults")]
    return values


def _gate_values(gate: GateCounts) -> list[tuple[str, str]]:
    return [
        ("cmd_vel forwarded", str(gate.forwarded)),
        ("cmd_vel dropped: not RUN", str(gate.not_run)),
        ("cmd_vel dropped: too old", str(gate.too_old)),
        ("cmd_vel zero commands", str(gate.zeros)),
    ]


def _flag(value: object) -> str:
    return "true" if value is True else "false"


def _text(value: object) -> str:
    return "" if value is None else str(value)
