"""The robot's configuration, declared: every section and key with its type, default, range,
example and documentation, in one place (SR-11.2).

The loader (:mod:`supervisord.config.loader`) reads the file through these declarations
(:mod:`supervisord.strict`), and :func:`json_schema` turns the same declarations into the JSON
Schema editors validate against (``python -m supervisord.config.schema`` prints it; the
committed copy is ``config/srcsd.schema.json``). Rules between keys that JSON Schema cannot
say (cross-checks: path owners, unique names, existing users and groups...) are listed in
:data:`CROSS_CHECKS` and in docs/configuration.md; the loader alone enforces them.

Each output kind declares its own options (``supervisord.outputs``), so the schema of
``[[outputs]]`` is built from the plugins (importing every plugin, which only
:func:`json_schema` does, never the loader). ``[record]`` and ``[api]``'s two sockets are
declared in :mod:`supervisord.config.paths`, below this module, which the clients read them
with without the safety core this module imports (SR-8.8).
"""

from __future__ import annotations

import dataclasses
import json
import re
from collections.abc import Mapping
from typing import Final

from supervisord import strict
from supervisord.api.framing import SOCKET_PATH_MAX_BYTES
from supervisord.api.server import DEFAULT_MAX_CLIENTS, MAX_CLIENTS_RANGE, MAX_LINE_RANGE
from supervisord.config.paths import API_OPERATOR_SOCKET, API_SOCKET, RECORD
from supervisord.config.periodic import DEFAULT_INTERVAL_DAYS, INTERVAL_RANGE_DAYS
from supervisord.config.realtime import REALTIME
from supervisord.outputs.registry import KIND, OFF_DELAY, ROLE
from supervisord.safety.availability import (
    DEFAULT_MIN_REMOTE_BATTERY,
    MIN_REMOTE_BATTERY_RANGE,
    Reaction,
)
from supervisord.safety.config import (
    CLIENT_TIMEOUT_RANGE_MS,
    CONSOLE_TIMEOUT_RANGE_MS,
    DEFAULT_CLIENT_TIMEOUT_MS,
    DEFAULT_CONSOLE_TIMEOUT_MS,
    DEFAULT_PROOFTEST_CLEAR_MS,
    HEARTBEAT_HZ_RANGE,
    PROOFTEST_CLEAR_RANGE_MS,
    REARM_HOLD_RANGE_MS,
    UID_RANGE,
    VSC_TIMEOUT_MS,
    Transport,
)
from supervisord.safety.prooftest import ProofTestPolicy

SERIAL_BAUD: Final = 115_200
"""The VSC's serial speed: fixed by the SRCS manual, so no other value is accepted."""
DEFAULT_SERIAL_PORT: Final = "/dev/srcs-vsc"
"""The udev symlink the shipped rule creates for the VSC's USB serial port."""
DEFAULT_REOPEN_MIN_MS: Final = 100
DEFAULT_REOPEN_MAX_MS: Final = 5_000
REOPEN_MIN_RANGE_MS: Final = (10, 10_000)
REOPEN_MAX_RANGE_MS: Final = (100, 60_000)
DEFAULT_CAN_INTERFACE: Final = "socketcan"
DEFAULT_CAN_CHANNEL: Final = "can0"
DEFAULT_CAN_BITRATE: Final = 250_000  # J1939's usual rate
CAN_BITRATES: Final = (
    10_000,
    20_000,
    50_000,
    100_000,
    125_000,
    250_000,
    500_000,
    800_000,
    1_000_000,
)
DEFAULT_CAN_ERROR_LIMIT: Final = 16
"""docs/safety.md "CAN error frames": more than this many error frames within the window break
the link. CAN's fault confinement adds 8 per error and takes 1 per good frame: 16 errors with
no good frame between are 128, the error-passive threshold (``links.can_link.ERROR_LIMIT``)."""
DEFAULT_CAN_ERROR_WINDOW_MS: Final = 1_000
DEFAULT_CAN_ERROR_PASSIVE_MS: Final = 1_000
CAN_ERROR_LIMIT_RANGE: Final = (0, 1_000)  # 0: every error frame is a fault (the strictest)
CAN_ERROR_WINDOW_RANGE_MS: Final = (100, 10_000)
CAN_ERROR_PASSIVE_RANGE_MS: Final = (0, 10_000)
DEFAULT_MAX_MESSAGE_BYTES: Final = 65_536
ROBOT_NAME_MAX: Final = 64

OUTPUT_NAME: Final = re.compile(r"[A-Za-z0-9_-]{1,32}")
"""Output names: the safety core allows ``.`` too, the output plugins do not; both must hold."""
CLIENT_NAME: Final = re.compile(r"[A-Za-z0-9_.-]{1,32}")
GROUP_NAME: Final = re.compile(r"[A-Za-z_][A-Za-z0-9_.-]{0,31}")
USER_NAME: Final = GROUP_NAME


def _can_interfaces() -> dict[str, str]:
    # Imported only when a config uses CAN (or the JSON Schema is built), as the outputs
    # import their plugins: a serial robot never imports python-can.
    from can import VALID_INTERFACES  # noqa: PLC0415

    return dict.fromkeys(sorted(VALID_INTERFACES), "")


# ---------------------------------------------------------------------------------------------
# [robot]

ROBOT_NAME: Final = strict.Text(
    name="name",
    doc="Who this is: shown by --check-config, in the logs and in status.",
    max_length=ROBOT_NAME_MAX,
    example="mower-3",
)

# ---------------------------------------------------------------------------------------------
# [vsc]: the keys of every transport, then each transport's own

TRANSPORT: Final = strict.Choice(
    name="transport",
    doc="How the VSC is connected (PR-1, PR-3, PR-4).",
    values={
        Transport.SERIAL.value: "USB or RS-232",
        Transport.CAN.value: "J1939",
        Transport.HID.value: "never leaves STOPPED",
    },
    example="serial",
)
REQUIRE_WATCHDOG: Final = strict.Flag(
    name="require_watchdog",
    doc="Stay STOPPED until the VSC's user watchdog (key 85) reads 1 (SR-5). Must be written "
    'as false for transport "can", which has no user watchdog.',
    default=True,
    example=True,
)
PROOFTEST: Final = strict.Choice(
    name="prooftest",
    doc="The start-up proof test of the VSC's watchdog (SR-5.3, docs/safety.md); a trip later "
    "than 700 ms fails, whatever timeout_ms is (SR-5.7). Default: "
    '"block" on serial with the watchdog required, "record" without; "off" on CAN and HID, '
    "the only value they accept.",
    values={
        ProofTestPolicy.BLOCK.value: "stay STOPPED until it passes",
        ProofTestPolicy.RECORD.value: "record a failure and run",
        ProofTestPolicy.OFF.value: "no proof test",
    },
    default=None,
    example="block",
)
PROOFTEST_CLEAR: Final = strict.Whole(
    name="prooftest_clear_ms",
    doc="How long the proof test waits for a held e-stop bit to clear.",
    default=DEFAULT_PROOFTEST_CLEAR_MS,
    example=DEFAULT_PROOFTEST_CLEAR_MS,
    low=PROOFTEST_CLEAR_RANGE_MS[0],
    high=PROOFTEST_CLEAR_RANGE_MS[1],
)
MIN_REMOTE_BATTERY: Final = strict.Whole(
    name="min_remote_battery",
    doc="Below this battery percent of the remote, or with its battery not reported for 3.5 s, "
    'the e-stop counts as not available (SR-8.11, docs/safety.md "Is the e-stop available?"); '
    "on_estop_unavailable says what follows. 0: no battery check.",
    default=DEFAULT_MIN_REMOTE_BATTERY,
    example=DEFAULT_MIN_REMOTE_BATTERY,
    low=MIN_REMOTE_BATTERY_RANGE[0],
    high=MIN_REMOTE_BATTERY_RANGE[1],
)
ON_ESTOP_UNAVAILABLE: Final = strict.Choice(
    name="on_estop_unavailable",
    doc="What the remote's battery below min_remote_battery, or not reported, does (SR-8.12, "
    'docs/safety.md "Is the e-stop available?").',
    values={
        Reaction.WARN.value: "a warning in status, the exporter and the ROS 2 bridge",
        Reaction.HOLD.value: "HOLD (cause estop_unavailable_hold) until the battery is back",
        Reaction.STOP.value: "STOPPED (cause estop_unavailable), a takeover once it is back",
    },
    default=Reaction.WARN.value,
    example=Reaction.HOLD.value,
)
REOPEN_MIN: Final = strict.Whole(
    name="reopen_min_ms",
    doc="After a lost link, the first wait before reopening it.",
    default=DEFAULT_REOPEN_MIN_MS,
    example=DEFAULT_REOPEN_MIN_MS,
    low=REOPEN_MIN_RANGE_MS[0],
    high=REOPEN_MIN_RANGE_MS[1],
)
REOPEN_MAX: Final = strict.Whole(
    name="reopen_max_ms",
    doc="The wait doubles up to this; at least reopen_min_ms.",
    default=DEFAULT_REOPEN_MAX_MS,
    example=DEFAULT_REOPEN_MAX_MS,
    low=REOPEN_MAX_RANGE_MS[0],
    high=REOPEN_MAX_RANGE_MS[1],
)
PORT: Final = strict.Text(
    name="port",
    doc="The VSC's serial port; relative to the config file's directory.",
    default=DEFAULT_SERIAL_PORT,
    not_dir=True,
    example="/dev/ttyACM0",
)
BAUD: Final = strict.Whole(
    name="baud",
    doc="The serial speed: fixed at 115200 by the SRCS manual (may be written out).",
    low=SERIAL_BAUD,
    high=SERIAL_BAUD,
    default=SERIAL_BAUD,
    hint=f"remove it or set {SERIAL_BAUD}: the SRCS manual fixes the VSC's serial speed at "
    f"{SERIAL_BAUD} baud",
)
HEARTBEAT_HZ: Final = strict.Whole(
    name="heartbeat_hz",
    doc="The user heartbeat's rate (SR-5).",
    default=20,
    example=20,
    low=HEARTBEAT_HZ_RANGE[0],
    high=HEARTBEAT_HZ_RANGE[1],
)
CAN_INTERFACE: Final = strict.Choice(
    name="interface",
    doc='A python-can interface name, e.g. "socketcan", "pcan", "virtual" or "udp_multicast".',
    values=_can_interfaces,
    rule='a python-can interface name, e.g. "socketcan", "pcan", "virtual" or "udp_multicast"',
    default=DEFAULT_CAN_INTERFACE,
    example=DEFAULT_CAN_INTERFACE,
)
CAN_CHANNEL: Final = strict.Either(
    name="channel",
    doc="The interface's channel: a name, or a number for interfaces that number them.",
    options=(
        strict.Text(
            name="channel",
            doc="",
            pattern="^[^ \\u0000-\\u001f\\u007f-\\u009f]+$",
            rule="a channel name without spaces in double quotes",
            example=DEFAULT_CAN_CHANNEL,
        ),
        strict.Whole(name="channel", doc="", low=0, high=2**31 - 1),
    ),
    default=DEFAULT_CAN_CHANNEL,
    example=DEFAULT_CAN_CHANNEL,
)
CAN_BITRATE: Final = strict.Whole(
    name="bitrate",
    doc="The bus's bit rate, one of the standard rates.",
    low=CAN_BITRATES[0],
    high=CAN_BITRATES[-1],
    values=CAN_BITRATES,
    default=DEFAULT_CAN_BITRATE,
    example=DEFAULT_CAN_BITRATE,
)
ERROR_LIMIT: Final = strict.Whole(
    name="error_limit",
    doc="More error frames than this within error_window_ms break the link "
    '(docs/safety.md "CAN error frames"); 0: every error frame does.',
    default=DEFAULT_CAN_ERROR_LIMIT,
    example=DEFAULT_CAN_ERROR_LIMIT,
    low=CAN_ERROR_LIMIT_RANGE[0],
    high=CAN_ERROR_LIMIT_RANGE[1],
)
ERROR_WINDOW: Final = strict.Whole(
    name="error_window_ms",
    doc="The window error_limit counts in.",
    default=DEFAULT_CAN_ERROR_WINDOW_MS,
    example=DEFAULT_CAN_ERROR_WINDOW_MS,
    low=CAN_ERROR_WINDOW_RANGE_MS[0],
    high=CAN_ERROR_WINDOW_RANGE_MS[1],
)
ERROR_PASSIVE: Final = strict.Whole(
    name="error_passive_ms",
    doc="A controller error-passive this long breaks the link.",
    default=DEFAULT_CAN_ERROR_PASSIVE_MS,
    example=DEFAULT_CAN_ERROR_PASSIVE_MS,
    low=CAN_ERROR_PASSIVE_RANGE_MS[0],
    high=CAN_ERROR_PASSIVE_RANGE_MS[1],
)
HIDRAW: Final = strict.Text(
    name="hidraw",
    doc="The VSC's hidraw device (never a safety channel).",
    not_dir=True,
    example="/dev/hidraw0",
)

VSC_COMMON: Final = (
    TRANSPORT,
    VSC_TIMEOUT_MS,  # the safety core's own rule (supervisord.safety.config)
    REQUIRE_WATCHDOG,
    PROOFTEST,
    PROOFTEST_CLEAR,
    MIN_REMOTE_BATTERY,
    ON_ESTOP_UNAVAILABLE,
    REOPEN_MIN,
    REOPEN_MAX,
)
CAN_BUS: Final = (CAN_INTERFACE, CAN_CHANNEL, CAN_BITRATE)
"""A CAN bus: the VSC's on transport "can", or ``[output_bus]``."""
VSC_BY_TRANSPORT: Final[Mapping[Transport, tuple[strict.Key, ...]]] = {
    Transport.SERIAL: (PORT, BAUD, HEARTBEAT_HZ),
    Transport.CAN: (*CAN_BUS, ERROR_LIMIT, ERROR_WINDOW, ERROR_PASSIVE),
    Transport.HID: (HIDRAW,),
}

# ---------------------------------------------------------------------------------------------
# [rearm], [[clients]], [[outputs]], [record], [api]

REARM: Final = (
    strict.Whole(
        name="hold_ms",
        doc="Every stop condition must be clear this long before a re-arm (SR-4).",
        default=500,
        example=500,
        low=REARM_HOLD_RANGE_MS[0],
        high=REARM_HOLD_RANGE_MS[1],
    ),
    strict.Flag(
        name="local_reset",
        doc="Also re-arm by srcsctl reset, not only by the operator's takeover on the remote.",
        default=False,
        example=False,
    ),
)
CLIENTS: Final = (
    strict.Text(
        name="name",
        doc="The name the client gives in its hello; cause client_lost:NAME (SR-8).",
        pattern=CLIENT_NAME.pattern,
        rule="1 to 32 characters from letters, digits, '_', '.' and '-'",
        example="autonomy",
    ),
    strict.Whole(
        name="timeout_ms",
        doc="Its heartbeat deadline.",
        default=DEFAULT_CLIENT_TIMEOUT_MS,
        example=DEFAULT_CLIENT_TIMEOUT_MS,
        low=CLIENT_TIMEOUT_RANGE_MS[0],
        high=CLIENT_TIMEOUT_RANGE_MS[1],
    ),
    strict.Text(
        name="user",
        doc="Only a process of this user may say hello under the name (it must exist). "
        "Give user or uid, not both; neither: any user who can reach the socket.",
        pattern=USER_NAME.pattern,
        rule="a user name in double quotes",
        default=None,
        example="robot",
    ),
    strict.Whole(
        name="uid",
        doc="As user, by number.",
        default=None,
        example=1000,
        low=UID_RANGE[0],
        high=UID_RANGE[1],
    ),
    strict.Flag(
        name="progress",
        doc="Every heartbeat must carry a progress value newer than the last (SR-8.16); one "
        "that does not keeps no deadline, so a stuck control loop is client_lost.",
        default=False,
        example=True,
    ),
)
OUTPUT_NAME_KEY: Final = strict.Text(
    name="name",
    doc="The output's name: it appears in the stop cause output_fault:NAME.",
    pattern=OUTPUT_NAME.pattern,
    rule="1 to 32 characters from letters, digits, '_' and '-'",
    example="drive",
)
OUTPUT_COMMON: Final = (OUTPUT_NAME_KEY, KIND, ROLE, OFF_DELAY)


def _group(name: str, doc: str, example: str) -> strict.Text:
    return strict.Text(
        name=name,
        doc=doc,
        pattern=GROUP_NAME.pattern,
        rule="a group name in double quotes",
        default=None,
        example=example,
    )


API: Final = (
    API_SOCKET,
    _group("group", "Owns the socket (mode 0660); it must exist. Default: the daemon's.", "srcs"),
    _group(
        "admin_group",
        "May re-arm (reset) and write the VSC (commission); it must exist. "
        "Default: none (root and the daemon's user only).",
        "srcs-admin",
    ),
    API_OPERATOR_SOCKET,
    _group(
        "operator_group",
        "May connect to the operator socket (mode 0660); it must exist, and robot programs "
        "must not be in it. Default: none (mode 0600: root and the daemon's user only).",
        "srcs-operator",
    ),
    strict.Whole(
        name="max_clients",
        doc="Connections at once, srcsctl included; at least the required clients and one.",
        default=DEFAULT_MAX_CLIENTS,
        example=DEFAULT_MAX_CLIENTS,
        low=MAX_CLIENTS_RANGE[0],
        high=MAX_CLIENTS_RANGE[1],
    ),
    strict.Whole(
        name="max_message_bytes",
        doc="The largest request line a client may send.",
        default=DEFAULT_MAX_MESSAGE_BYTES,
        example=DEFAULT_MAX_MESSAGE_BYTES,
        low=MAX_LINE_RANGE[0],
        high=MAX_LINE_RANGE[1],
    ),
)


MAINTENANCE: Final = (
    strict.Whole(
        name="stoptest_interval_days",
        doc="Days after the last passed field stop test (srcsctl stoptest) when it is overdue: "
        "a warning in status, the exporter and the ROS 2 bridge, never a stop (SR-12.2). "
        "0: no schedule.",
        default=DEFAULT_INTERVAL_DAYS,
        example=DEFAULT_INTERVAL_DAYS,
        low=INTERVAL_RANGE_DAYS[0],
        high=INTERVAL_RANGE_DAYS[1],
    ),
    strict.Whole(
        name="prooftest_interval_days",
        doc="Days after the last passed proof test of the VSC's watchdog when it is overdue "
        "(it runs at every start and reconnect, and on srcsctl prooftest); a warning as "
        "above. 0: no schedule.",
        default=DEFAULT_INTERVAL_DAYS,
        example=DEFAULT_INTERVAL_DAYS,
        low=INTERVAL_RANGE_DAYS[0],
        high=INTERVAL_RANGE_DAYS[1],
    ),
)


FLEET: Final = (
    strict.Text(
        name="agent_user",
        doc="The fleet agent's user: only its connections may send fleet_stop, fleet_release "
        "and fleet_keepalive (SR-8.19; it must exist). Give agent_user or agent_uid, not both; "
        "neither: the fleet ops are refused.",
        pattern=USER_NAME.pattern,
        rule="a user name in double quotes",
        default=None,
        example="srcs-fleet",
    ),
    strict.Whole(
        name="agent_uid",
        doc="As agent_user, by number.",
        default=None,
        example=998,
        low=UID_RANGE[0],
        high=UID_RANGE[1],
    ),
    strict.Flag(
        name="console_required",
        doc="The fleet's console is a required stop source: no fleet_keepalive for "
        "console_timeout_ms (or none since the start) stops the robot, fleet_console_lost "
        "(SR-8.21).",
        default=False,
        example=False,
    ),
    strict.Whole(
        name="console_timeout_ms",
        doc="The console's keepalive deadline; the agent sends one at least every third of it.",
        default=DEFAULT_CONSOLE_TIMEOUT_MS,
        example=DEFAULT_CONSOLE_TIMEOUT_MS,
        low=CONSOLE_TIMEOUT_RANGE_MS[0],
        high=CONSOLE_TIMEOUT_RANGE_MS[1],
    ),
)


@dataclasses.dataclass(frozen=True)
class Section:
    """A top-level section: its ``name``, ``doc`` and ``keys``; ``many``: an array of tables
    (``[[name]]``) with an ``example`` first line for the hint."""

    name: str
    doc: str
    keys: tuple[strict.Key, ...]
    many: bool = False
    example: str = ""


SECTIONS: Final = (
    Section("robot", "Who this is.", (ROBOT_NAME,)),
    Section(
        "vsc",
        "How the VSC is connected, and the safety values of its link.",
        VSC_COMMON + tuple(dict.fromkeys(k for ks in VSC_BY_TRANSPORT.values() for k in ks)),
    ),
    Section("rearm", "How the supervisor re-arms after a stop (SR-4).", REARM),
    Section(
        "clients",
        "The robot's programs that must keep a heartbeat (SR-8).",
        CLIENTS,
        many=True,
        example='name = "autonomy"',
    ),
    Section(
        "outputs",
        "The enable lines the supervisor gates (SR-6, docs/outputs.md).",
        OUTPUT_COMMON,
        many=True,
        example='name = "drive", kind = "gpio", role = "motion", ...',
    ),
    Section(
        "output_bus",
        'A CAN bus of its own for kind = "can" outputs (default: the VSC\'s, on CAN).',
        CAN_BUS,
    ),
    Section("record", "The record of stops (docs/record.md).", RECORD),
    Section("api", "The Unix socket the robot's software and srcsctl use.", API),
    Section(
        "maintenance",
        "When the periodic tests are overdue (SR-12.2, docs/safety-manual.md).",
        MAINTENANCE,
    ),
    Section(
        "realtime",
        "What the start does for the loop's real time (SR-9.6, docs/safety-manual.md).",
        REALTIME,
    ),
    Section(
        "fleet",
        "The fleet's stop through the robot's fleet agent (SR-8.19 to SR-8.21, docs/safety.md).",
        FLEET,
    ),
)
SECTION: Final = {section.name: section for section in SECTIONS}

CROSS_CHECKS: Final[Mapping[str, str]] = {
    "vsc.reopen_max_ms": "at least reopen_min_ms",
    "clients[].name": "unique among the clients",
    "clients[].user": "an existing user on this machine",
    "fleet.agent_user": "an existing user on this machine; not with agent_uid",
    "fleet.console_required": "needs agent_user or agent_uid",
    "outputs[].name": "unique among the outputs",
    "outputs[].line": "one GPIO line per output (a chip by path, kernel name or label)",
    "outputs[].arbitration_id": "one CAN identifier per output",
    "outputs[].data_on": "different from data_off, the counter bits aside",
    "outputs[].counter_byte": "below the length of data_on and data_off",
    "output_bus": 'given only with a kind = "can" output, and then needed unless the VSC is on '
    "CAN; not the VSC's own bus",
    "api.group": "an existing group on this machine",
    "api.admin_group": "an existing group on this machine",
    "api.operator_group": "an existing group on this machine",
    "api.operator_socket": f"at most {SOCKET_PATH_MAX_BYTES} bytes once resolved; not the socket",
    "api.max_clients": "at least the number of required clients plus one",
    "api.socket": f"at most {SOCKET_PATH_MAX_BYTES} bytes once resolved",
    "paths": "every file the config names (port, hidraw, sim outputs' paths, the record and "
    "its rotated files, the socket) has one owner once resolved",
}
"""The rules only the loader enforces: they relate keys to one another or to the machine, which
JSON Schema cannot say (docs/configuration.md "The JSON Schema")."""


# ---------------------------------------------------------------------------------------------
# The JSON Schema

JSON_SCHEMA_DIALECT: Final = "https://json-schema.org/draft/2020-12/schema"


def _vsc_schema(section: Section) -> dict[str, object]:
    schema = strict.object_schema(section.keys, doc=section.doc)
    schema["required"] = [TRANSPORT.name]
    rules: list[object] = []
    for transport, own in VSC_BY_TRANSPORT.items():
        foreign = [k.name for k in section.keys if k not in VSC_COMMON and k not in own]
        then: dict[str, object] = {"properties": dict.fromkeys(foreign, False)}
        required = [k.name for k in own if k.required]
        if transport is not Transport.SERIAL:
            # SafetyConfig: no user watchdog on CAN (said aloud), no proof test off serial.
            props = then["properties"]
            assert isinstance(props, dict)
            props[PROOFTEST.name] = {"const": ProofTestPolicy.OFF.value}
            if transport is Transport.CAN:
                props[REQUIRE_WATCHDOG.name] = {"const": False}
                required.append(REQUIRE_WATCHDOG.name)
        if required:
            then["required"] = required
        rules.append(
            {"if": {"properties": {TRANSPORT.name: {"const": transport.value}}}, "then": then}
        )
    schema["allOf"] = rules
    return schema


def _outputs_schema(section: Section) -> dict[str, object]:
    # Every plugin is imported here (gpiod, python-can): only the schema's builder does this.
    from supervisord.outputs.registry import spec_class  # noqa: PLC0415

    item = strict.object_schema(section.keys)
    properties = item["properties"]
    assert isinstance(properties, dict)
    specs = {kind: spec_class(kind) for kind in KIND.allowed}
    for spec in specs.values():
        for key in spec.options:
            assert key.name not in properties, f"two output kinds declare {key.name!r}"
            properties[key.name] = key.json_schema()
    rules: list[object] = []
    for kind, spec in specs.items():
        own = {key.name for key in spec.options}
        foreign = [
            key.name for other in specs.values() for key in other.options if key.name not in own
        ]
        then: dict[str, object] = {"properties": dict.fromkeys(foreign, False)}
        required = [key.name for key in spec.options if key.required]
        if required:
            then["required"] = required
        rules.append({"if": {"properties": {KIND.name: {"const": kind}}}, "then": then})
        rules += [
            {"if": {"properties": {KIND.name: {"const": kind}}}, "then": rule}
            for rule in spec.schema_rules()
        ]
    # SR-1.4: a delay (category 1) only on a power output.
    rules.append(
        {
            "if": {"required": [OFF_DELAY.name], "properties": {OFF_DELAY.name: {"minimum": 1}}},
            "then": {"required": [ROLE.name], "properties": {ROLE.name: {"const": "power"}}},
        }
    )
    item["allOf"] = rules
    return {
        "type": "array",
        "description": section.doc,
        "minItems": 1,
        "items": item,
        # SR-1.2: at least one output gates motion (role "motion" is the default).
        "contains": {
            "not": {"required": [ROLE.name], "properties": {ROLE.name: {"const": "power"}}}
        },
    }


def json_schema() -> dict[str, object]:
    """The JSON Schema (draft 2020-12) of the robot's TOML file, from the declarations above."""
    properties: dict[str, object] = {}
    for section in SECTIONS:
        if section.name == "vsc":
            properties[section.name] = _vsc_schema(section)
        elif section.name == "outputs":
            properties[section.name] = _outputs_schema(section)
        elif section.many:
            items = strict.object_schema(section.keys)
            if section.name == "clients":
                items["not"] = {"required": ["user", "uid"]}  # user or uid, not both
            properties[section.name] = {
                "type": "array",
                "description": section.doc,
                "items": items,
            }
        else:
            properties[section.name] = strict.object_schema(section.keys, doc=section.doc)
    return {
        "$schema": JSON_SCHEMA_DIALECT,
        "title": "srcsd robot configuration",
        "description": "The robot's TOML file for srcsd (docs/configuration.md). Generated by "
        "python -m supervisord.config.schema; srcsd --check-config also checks the rules "
        "between keys this schema cannot say.",
        "type": "object",
        "properties": properties,
        "required": ["robot", "vsc", "outputs"],
        "additionalProperties": False,
    }


def json_schema_text() -> str:
    """:func:`json_schema` as the committed file ``config/srcsd.schema.json`` holds it."""
    return json.dumps(json_schema(), indent=2, ensure_ascii=False) + "\n"
