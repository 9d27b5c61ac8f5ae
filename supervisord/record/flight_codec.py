"""The flight recorder's encoding of the safety core's inputs and configuration as JSON, both ways
(SR-7.10, ``docs/record.md`` "The flight recorder"): stable and versioned.

Every input event type of :mod:`supervisord.safety.events` has one entry in :data:`FIELDS`: its
name in the file (the same fixed names as a record's ``trigger``, ``TRIGGER_EVENTS``, never a
class name) and each of its fields with the kind of value it holds. A VSC message is written
as its wire bytes (the type and the payload of its HRI packet, PR-2), the most stable encoding
there is. ``tests/record/test_flight_codec.py`` fails when an event type, or a field of one,
has no entry, and round-trips every type.

:data:`VERSION` counts incompatible changes of this encoding; a reader refuses any other.
Pure: no I/O.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Callable, Mapping
from typing import Any, Final

from supervisord.protocol.codes import MessageType
from supervisord.protocol.messages import FeedbackName, FeedbackSet, Message
from supervisord.protocol.payload import decode_payload, encode_payload, payload_length_ok
from supervisord.record.format import TRIGGER_EVENTS
from supervisord.safety.availability import DEFAULT_MIN_REMOTE_BATTERY, Reaction
from supervisord.safety.config import (
    ClientSpec,
    FleetSpec,
    OutputRole,
    OutputSpec,
    SafetyConfig,
    Transport,
)
from supervisord.safety.events import EVENT_TYPES, Caller, Event, Request
from supervisord.safety.prooftest import ProofTestPolicy
from supervisord.safety.stoptest import StopTestFormatError, StopTestResult, result_from_json

VERSION: Final = 1
"""The encoding's version: a reader takes only this one."""

JsonDict = dict[str, Any]
INT_LIMIT: Final = 2**63
"""Every integer of an input lies from -2**63 to 2**63 - 1: what a signed 64-bit field holds
(the daemon writes none larger; a larger one is damage, SR-7.13)."""
MOMENT_LIMIT: Final = 2**63
"""A moment, a reading of the daemon's monotonic clock in ns, lies from 0 to 2**63 - 1: what
every export's 64-bit time fields take (``flight_times``, SR-7.13)."""


class FlightFormatError(ValueError):
    """A value this encoding cannot write, or a line that is not one it wrote."""


def _int(value: object) -> int:
    if isinstance(value, bool) or not isinstance(value, int):
        raise FlightFormatError(f"not an integer: {value!r}")
    if not -INT_LIMIT <= value < INT_LIMIT:
        raise FlightFormatError(f"an integer out of 64 bits: {preview(value)}")
    return value


def preview(value: object) -> str:
    """``value`` for a message: short, and never an integer's every digit (the interpreter
    refuses to print one of more than 4300)."""
    if isinstance(value, int) and value.bit_length() > 64:
        return f"an integer of {value.bit_length()} bits"
    return repr(value)[:40]


def is_moment(value: object) -> bool:
    """Whether ``value`` is a reading of the monotonic clock (an int from 0 to 2**63 - 1)."""
    return isinstance(value, int) and not isinstance(value, bool) and 0 <= value < MOMENT_LIMIT


def moment(value: object, what: str = "an input's now") -> int:
    """``value`` as a moment (SR-7.13); :class:`FlightFormatError` naming ``what`` when it is
    none: a replay or an export would otherwise carry a time no 64-bit field takes."""
    if isinstance(value, bool) or not isinstance(value, int) or not 0 <= value < MOMENT_LIMIT:
        raise FlightFormatError(
            f"{what} is not a time of the monotonic clock (an integer from 0 to 2**63 - 1 ns): "
            f"{preview(value)}"
        )
    return value


def _optional_int(value: object) -> int | None:
    return None if value is None else _int(value)


def _flag(value: object) -> bool:
    if not isinstance(value, bool):
        raise FlightFormatError(f"not true or false: {value!r}")
    return value


def _optional_flag(value: object) -> bool | None:
    return None if value is None else _flag(value)


def _text(value: object) -> str:
    if not isinstance(value, str):
        raise FlightFormatError(f"not text: {value!r}")
    return value


def caller_to_json(caller: Caller) -> JsonDict:
    return {"uid": caller.uid, "pid": caller.pid, "name": caller.name, "admin": caller.admin}


def caller_from_json(value: object) -> Caller:
    if not isinstance(value, dict):
        raise FlightFormatError(f"not a caller: {value!r}")
    return Caller(
        _int(value.get("uid")),
        _int(value.get("pid")),
        _text(value.get("name")),
        _flag(value.get("admin")),
    )


def message_to_json(message: Message) -> JsonDict:
    """A VSC message as its HRI packet's type and payload (hex): the wire's own encoding."""
    return {"type": int(message.TYPE), "payload": encode_payload(message).hex()}


def message_from_json(value: object) -> Message:
    if not isinstance(value, dict):
        raise FlightFormatError(f"not a message: {value!r}")
    known = MessageType.parse(_int(value.get("type")))
    try:
        payload = bytes.fromhex(_text(value.get("payload")))
    except ValueError as error:
        raise FlightFormatError(f"a message payload that is not hex: {error}") from error
    if known is None or not payload_length_ok(known, len(payload)):
        raise FlightFormatError(f"not an HRI packet: type {value.get('type')!r}, {payload.hex()}")
    try:
        return decode_payload(known, payload)
    except ValueError as error:
        raise FlightFormatError(f"not an HRI packet: {error}") from error


def _display_from_json(value: object) -> FeedbackSet | FeedbackName:
    message = message_from_json(value)
    if not isinstance(message, FeedbackSet | FeedbackName):
        raise FlightFormatError(f"not display content: {type(message).__name__}")
    return message


def _request_from_json(value: object) -> Request:
    try:
        return Request(_text(value))
    except ValueError as error:
        raise FlightFormatError(str(error)) from error


@dataclasses.dataclass(frozen=True)
class Kind:
    """How one field's value is written and read."""

    write: Callable[[Any], Any]
    read: Callable[[Any], Any]


def _same(value: Any) -> Any:
    return value


INT = Kind(_same, _int)
OPTIONAL_INT = Kind(_same, _optional_int)
FLAG = Kind(_same, _flag)
OPTIONAL_FLAG = Kind(_same, _optional_flag)
TEXT = Kind(_text, _text)
CALLER = Kind(caller_to_json, caller_from_json)
OPTIONAL_CALLER = Kind(
    lambda c: None if c is None else caller_to_json(c),
    lambda v: None if v is None else caller_from_json(v),
)
MESSAGE = Kind(message_to_json, message_from_json)
DISPLAY = Kind(message_to_json, _display_from_json)
REQUEST = Kind(lambda r: r.value, _request_from_json)


def _stoptest_to_json(result: StopTestResult) -> JsonDict:
    return result.json()


def _stoptest_from_json(value: object) -> StopTestResult:
    try:
        return result_from_json(value)
    except StopTestFormatError as error:
        raise FlightFormatError(str(error)) from error


STOPTEST = Kind(_stoptest_to_json, _stoptest_from_json)

_CONNECTION = (("connection", INT),)
_CALLER = (("caller", CALLER),)
_FLEET = (("connection", INT), ("caller", OPTIONAL_CALLER))

FIELDS: Final[Mapping[str, tuple[tuple[str, Kind], ...]]] = {
    "tick": (),
    "vsc_received": (("message", MESSAGE),),
    "link_opened": (),
    "link_broken": (("reason", TEXT),),
    "link_closed": (("reason", TEXT),),
    "client_connected": (("connection", INT), ("uid", OPTIONAL_INT)),
    "client_hello": (("connection", INT), ("name", TEXT), ("caller", OPTIONAL_CALLER)),
    # progress: absent in windows written before SR-8.16, read as None (no value given).
    "client_heartbeat": (("connection", INT), ("progress", OPTIONAL_INT)),
    "client_estop": _CONNECTION,
    "client_hold": _CONNECTION,
    "client_command": (("connection", INT), ("nonzero", FLAG)),
    "client_release": (("connection", INT), ("request", REQUEST)),
    "client_disconnected": _CONNECTION,
    "local_estop": _CALLER,
    "local_release": _CALLER,
    "reset_request": _CALLER,
    "output_readback": (("output", TEXT), ("requested", FLAG), ("read_back", OPTIONAL_FLAG)),
    "internal_fault": (("reason", TEXT),),
    "shutdown": (("reason", TEXT),),
    "display_update": (("message", DISPLAY),),
    "commissioned": (("caller", CALLER), ("key85", OPTIONAL_INT), ("remote_status", FLAG)),
    "proof_test_request": _CALLER,
    "stop_tested": (("caller", CALLER), ("result", STOPTEST)),
    "fleet_stop": (*_FLEET, ("stop_id", TEXT), ("sender", TEXT)),
    "fleet_release": (*_FLEET, ("stop_id", TEXT), ("sender", TEXT)),
    "fleet_keepalive": (*_FLEET, ("sender", TEXT)),
}
"""Each input's fields by its name in the file (the field names are the file's keys too, so a
field renamed in the code needs its old key here: ``tests/record/test_flight_codec.py``)."""

CLASSES: Final[Mapping[str, type]] = {
    name: cls for cls, name in TRIGGER_EVENTS.items() if cls in EVENT_TYPES
}


def event_to_json(event: Event) -> JsonDict:
    """One input as a JSON object: ``{"event": NAME, "now": NS, FIELD: VALUE...}``."""
    name = TRIGGER_EVENTS.get(type(event))
    spec = FIELDS.get(name) if name is not None else None
    if name is None or spec is None:
        raise FlightFormatError(f"no encoding for {type(event).__name__}")
    result: JsonDict = {"event": name, "now": event.now}
    for key, kind in spec:
        result[key] = kind.write(getattr(event, key))
    return result


def event_from_json(data: object) -> Event:
    """The input :func:`event_to_json` wrote. Raises :class:`FlightFormatError`."""
    if not isinstance(data, dict):
        raise FlightFormatError(f"not an input: {str(data)[:80]}")
    name = data.get("event")
    cls = CLASSES.get(name) if isinstance(name, str) else None
    if cls is None or not isinstance(name, str):
        raise FlightFormatError(f"unknown input {name!r}")
    values = {key: kind.read(data.get(key)) for key, kind in FIELDS[name]}
    try:
        event: Event = cls(now=moment(data.get("now")), **values)
    except (TypeError, ValueError) as error:
        raise FlightFormatError(f"{name}: {error}") from error
    return event


def config_to_json(config: SafetyConfig) -> JsonDict:
    """The safety core's configuration (only what the core reads: an output's name, role and
    stop category, not the output kind's own options)."""
    return {
        "transport": config.transport.value,
        "vsc_timeout_ms": config.vsc_timeout_ms,
        "heartbeat_hz": config.heartbeat_hz,
        "rearm_hold_ms": config.rearm_hold_ms,
        "local_reset": config.local_reset,
        "require_watchdog": config.require_watchdog,
        "clients": [
            {"name": c.name, "timeout_ms": c.timeout_ms, "uid": c.uid} for c in config.clients
        ],
        "outputs": [
            {"name": o.name, "role": o.role.value, "off_delay_ms": o.off_delay_ms}
            for o in config.outputs
        ],
        "prooftest": config.prooftest.value,
        "prooftest_clear_ms": config.prooftest_clear_ms,
        "min_remote_battery": config.min_remote_battery,
        "on_estop_unavailable": config.on_estop_unavailable.value,
        "fleet": {
            "agent_uids": sorted(config.fleet.agent_uids),
            "console_required": config.fleet.console_required,
            "console_timeout_ms": config.fleet.console_timeout_ms,
        },
    }


def _fleet_from_json(data: object) -> FleetSpec:
    """``[fleet]`` as written (SR-8.19); a window written before it: the default, no fleet."""
    if data is None:
        return FleetSpec()
    if not isinstance(data, dict) or not isinstance(data.get("agent_uids"), list):
        raise FlightFormatError("the configuration's fleet is not a table")
    return FleetSpec(
        frozenset(_int(uid) for uid in data["agent_uids"]),
        _flag(data.get("console_required")),
        _int(data.get("console_timeout_ms")),
    )


def config_from_json(data: object) -> SafetyConfig:
    """The configuration :func:`config_to_json` wrote, validated again as any other
    (``ConfigError`` for a value the core would refuse; :class:`FlightFormatError` for a
    shape that is not one)."""
    if not isinstance(data, dict):
        raise FlightFormatError("no configuration")
    clients, outputs = data.get("clients"), data.get("outputs")
    if not isinstance(clients, list) or not isinstance(outputs, list):
        raise FlightFormatError("the configuration's clients and outputs are not lists")
    try:
        return SafetyConfig(
            transport=Transport(data.get("transport")),
            vsc_timeout_ms=_optional_int(data.get("vsc_timeout_ms")),
            heartbeat_hz=_int(data.get("heartbeat_hz")),
            rearm_hold_ms=_int(data.get("rearm_hold_ms")),
            local_reset=_flag(data.get("local_reset")),
            require_watchdog=_flag(data.get("require_watchdog")),
            clients=tuple(
                ClientSpec(_text(c.get("name")), _int(c.get("timeout_ms")), c.get("uid"))
                for c in clients
            ),
            outputs=tuple(
                OutputSpec(
                    _text(o.get("name")),
                    OutputRole(o.get("role")),
                    _int(o.get("off_delay_ms", 0)),  # a window written before SR-1.4: none
                )
                for o in outputs
            ),
            prooftest=ProofTestPolicy(data.get("prooftest")),
            prooftest_clear_ms=_int(data.get("prooftest_clear_ms")),
            # A window written before SR-8.12: the defaults it ran with.
            min_remote_battery=_int(data.get("min_remote_battery", DEFAULT_MIN_REMOTE_BATTERY)),
            on_estop_unavailable=Reaction(data.get("on_estop_unavailable", Reaction.WARN.value)),
            fleet=_fleet_from_json(data.get("fleet")),
        )
    except (AttributeError, ValueError) as error:  # ConfigError is a ValueError too
        raise FlightFormatError(f"not a configuration: {error}") from error
