"""Every validation rule of supervisord.config, one parametrized case per rule.

Each case starts from a small valid config, changes one thing, and checks that the loader
refuses it with the dotted key, the value and a fix; or, for the cases that must pass, checks
the value it produced.
"""

from __future__ import annotations

import copy
import grp
import json
import os
from collections.abc import Mapping
from pathlib import Path

import pytest

from supervisord import strict
from supervisord.api.framing import SOCKET_PATH_MAX_BYTES
from supervisord.config import (
    DEFAULT_CAN_BITRATE,
    DEFAULT_SERIAL_PORT,
    MISSING,
    SERIAL_BAUD,
    CanBus,
    DaemonConfig,
    HidDevice,
    SerialPort,
    load_config,
)
from supervisord.config.paths import RECORD
from supervisord.errors import ConfigError
from supervisord.outputs import OutputKind, OutputRole
from supervisord.safety.availability import Reaction
from supervisord.safety.config import Transport
from supervisord.strict import shown
from supervisord.timebase import NS_PER_MS as MS

DELETE = object()
"""A change that removes the key."""

BASE: dict[str, object] = {
    "robot": {"name": "test-bot"},
    "vsc": {"transport": "serial", "port": "/dev/ttyACM0"},
    "clients": [{"name": "autonomy"}],
    "outputs": [{"name": "drive", "kind": "sim", "role": "motion"}],
}

CAN_VSC = {"transport": "can", "require_watchdog": False}
GPIO = {"kind": "gpio", "chip": "gpiochip0", "line": 17}
CAN_OUT = {"kind": "can", "arbitration_id": 0x201, "data_on": "01", "data_off": "00"}


def _literal(value: object) -> str:
    if isinstance(value, bool):
        return "true" if value else "false"
    if isinstance(value, int | float):
        return repr(value)
    if isinstance(value, str):
        return json.dumps(value)  # a JSON string is a TOML basic string for this text
    if isinstance(value, list):
        return "[" + ", ".join(_literal(v) for v in value) + "]"
    assert isinstance(value, Mapping)
    return "{ " + ", ".join(f"{k} = {_literal(v)}" for k, v in value.items()) + " }"


def dump(data: Mapping[str, object]) -> str:
    """``data`` as TOML: top-level scalars, then tables, then arrays of tables."""
    lines = [f"{k} = {_literal(v)}" for k, v in data.items() if not isinstance(v, dict | list)]
    for section, value in data.items():
        entries = value if isinstance(value, list) else [value]
        if not all(isinstance(e, dict) for e in entries):
            if isinstance(value, list):  # a plain array at the top level
                lines.insert(0, f"{section} = {_literal(value)}")
            continue
        for entry in entries:
            assert isinstance(entry, dict)
            lines.append(f"[[{section}]]" if isinstance(value, list) else f"[{section}]")
            lines += [f"{k} = {_literal(v)}" for k, v in entry.items()]
    return "\n".join(lines) + "\n"


def changed(changes: Mapping[str, object]) -> dict[str, object]:
    """BASE with each dotted path (``vsc.port``, ``outputs[0].role``) set, or removed."""
    data = copy.deepcopy(BASE)
    for path, value in changes.items():
        node: object = data
        parts = path.replace("[", ".").replace("]", "").split(".")
        for part in parts[:-1]:
            if isinstance(node, list):
                node = node[int(part)]
            else:
                assert isinstance(node, dict)
                node = node.setdefault(part, {})
        last = parts[-1]
        if isinstance(node, list):
            index = int(last)
            if value is DELETE:
                del node[index]
            elif index == len(node):
                node.append(value)
            else:
                node[index] = value
        else:
            assert isinstance(node, dict)
            if value is DELETE:
                node.pop(last, None)
            else:
                node[last] = value
    return data


def load(tmp_path: Path, changes: Mapping[str, object], **kwargs: object) -> DaemonConfig:
    """Write BASE with ``changes`` to a file and load it (every group exists)."""
    file = tmp_path / "robot.toml"
    file.write_text(dump(changed(changes)))
    base_dir = kwargs.get("base_dir")
    assert base_dir is None or isinstance(base_dir, Path)
    return load_config(file, base_dir=base_dir, group_exists=lambda name: name != "nobody-here")


def refused(tmp_path: Path, changes: Mapping[str, object]) -> ConfigError:
    """The error loading BASE with ``changes`` raises."""
    with pytest.raises(ConfigError) as caught:
        load(tmp_path, changes)
    return caught.value


def check(tmp_path: Path, changes: Mapping[str, object], key: str, fix: str) -> None:
    """Loading BASE with ``changes`` is refused naming ``key``, with ``fix`` in the message."""
    error = refused(tmp_path, changes)
    assert error.key == key
    assert fix in error.fix
    assert error.file == str(tmp_path / "robot.toml")
    assert str(error).startswith(f"{error.file}: {key} = {shown(error.value)}: ")


Case = tuple[dict[str, object], str, str]


def test_base_config_is_valid(tmp_path: Path) -> None:
    """The starting point of every case loads, with the documented defaults filled in."""
    config = load(tmp_path, {})
    assert config.robot.name == "test-bot"
    assert config.vsc.link == SerialPort(Path("/dev/ttyACM0"), SERIAL_BAUD)
    assert config.safety.vsc_timeout_ns == 200 * MS
    assert config.safety.heartbeat_hz == 20
    assert config.safety.require_watchdog is True
    assert config.safety.rearm_hold_ms == 500
    assert config.safety.local_reset is False
    assert [(c.name, c.timeout_ms) for c in config.safety.clients] == [("autonomy", 500)]
    assert [(o.name, o.role) for o in config.safety.outputs] == [("drive", OutputRole.MOTION)]
    assert config.vsc.reopen.min_ms == 100
    assert config.vsc.reopen.max_ms == 5000
    assert config.record.path == Path("/var/lib/srcsd/stops.jsonl")
    assert (config.record.max_bytes, config.record.keep, config.record.journal) == (
        4 * 1024 * 1024,
        4,
        True,
    )
    assert config.api.socket == Path("/run/srcsd/api.sock")
    assert (config.api.group, config.api.admin_group) == (None, None)
    assert (config.api.max_clients, config.api.max_message_bytes) == (16, 65536)
    assert config.output_bus is None
    assert config.can_output_bus is None


FILE_CASES: list[Case] = [
    ({"robt": {"name": "x"}}, "robt", "did you mean 'robot'?"),
    ({"log": {"path": "/x"}}, "log", "did you mean 'record'?"),
    ({"unheard_of": 1}, "unheard_of", "unknown key: remove it"),
    ({"robot": "test-bot"}, "robot", "make it a table: a line [robot]"),
    ({"vsc": ["serial"]}, "vsc", "make it a table"),
]


@pytest.mark.parametrize(("changes", "key", "fix"), FILE_CASES, ids=lambda c: str(c)[:30])
def test_sections(tmp_path: Path, changes: dict[str, object], key: str, fix: str) -> None:
    """Unknown sections (with a did-you-mean hint) and sections that are not tables are refused."""
    check(tmp_path, changes, key, fix)


ROBOT_CASES: list[Case] = [
    ({"robot": DELETE}, "robot.name", 'non-empty string in double quotes, e.g. "mower-3"'),
    ({"robot.name": DELETE}, "robot.name", 'non-empty string in double quotes, e.g. "mower-3"'),
    ({"robot.name": ""}, "robot.name", 'non-empty string in double quotes, e.g. "mower-3"'),
    ({"robot.name": "  "}, "robot.name", 'non-empty string in double quotes, e.g. "mower-3"'),
    (
        {"robot.name": "bad\tname"},
        "robot.name",
        'non-empty string in double quotes, e.g. "mower-3"',
    ),
    ({"robot.name": 7}, "robot.name", 'non-empty string in double quotes, e.g. "mower-3"'),
    ({"robot.name": "x" * 65}, "robot.name", "use at most 64 characters"),
    ({"robot.nmae": "x"}, "robot.nmae", "did you mean 'name'?"),
]


@pytest.mark.parametrize(("changes", "key", "fix"), ROBOT_CASES, ids=lambda c: str(c)[:30])
def test_robot(tmp_path: Path, changes: dict[str, object], key: str, fix: str) -> None:
    """[robot] needs a printable name of 1-64 characters and nothing else."""
    check(tmp_path, changes, key, fix)


VSC_CASES: list[Case] = [
    ({"vsc": DELETE}, "vsc.transport", '"serial" (USB or RS-232)'),
    ({"vsc.transport": "usb"}, "vsc.transport", '"can" (J1939)'),
    ({"vsc.transport": 1}, "vsc.transport", "use "),
    ({"vsc.heartbeat_hx": 20}, "vsc.heartbeat_hx", "did you mean 'heartbeat_hz'?"),
    ({"vsc.speed": 20}, "vsc.speed", "unknown key"),
    ({"vsc.channel": "can0"}, "vsc.channel", 'applies to transport "can", not "serial"'),
    ({"vsc.hidraw": "/dev/hidraw0"}, "vsc.hidraw", 'applies to transport "hid"'),
    ({"vsc": {**CAN_VSC, "heartbeat_hz": 20}}, "vsc.heartbeat_hz", 'transport "serial"'),
    ({"vsc": {**CAN_VSC, "port": "/dev/ttyACM0"}}, "vsc.port", 'transport "serial"'),
    ({"vsc.baud": 9600}, "vsc.baud", "fixes the VSC's serial speed at 115200"),
    ({"vsc.baud": "115200"}, "vsc.baud", "115200"),
    ({"vsc.port": ""}, "vsc.port", "use a non-empty string"),
    ({"vsc.port": 0}, "vsc.port", "use a non-empty string"),
    ({"vsc.port": "/dev/"}, "vsc.port", "not a directory's"),
    ({"vsc": {"transport": "hid"}}, "vsc.hidraw", '"/dev/hidraw0"'),
    ({"vsc.reopen_min_ms": 5}, "vsc.reopen_min_ms", "from 10 to 10000"),
    ({"vsc.reopen_min_ms": 1.5}, "vsc.reopen_min_ms", "whole number"),
    ({"vsc.reopen_max_ms": 60_001}, "vsc.reopen_max_ms", "from 100 to 60000"),
    (
        {"vsc.reopen_min_ms": 2000, "vsc.reopen_max_ms": 1000},
        "vsc.reopen_max_ms",
        "at least reopen_min_ms (2000)",
    ),
    ({"vsc.min_remote_battery": -1}, "vsc.min_remote_battery", "from 0 to 100"),
    ({"vsc.min_remote_battery": 101}, "vsc.min_remote_battery", "from 0 to 100"),
    ({"vsc.min_remote_battery": "20"}, "vsc.min_remote_battery", "without quotes"),
    ({"vsc.on_estop_unavailable": "halt"}, "vsc.on_estop_unavailable", '"hold"'),
    ({"vsc.on_estop_unavailable": True}, "vsc.on_estop_unavailable", '"warn"'),
    ({"vsc.timeout_ms": 49}, "vsc.timeout_ms", "from 50 to 1000"),
    ({"vsc.timeout_ms": 1001}, "vsc.timeout_ms", "from 50 to 1000"),
    ({"vsc.timeout_ms": "200"}, "vsc.timeout_ms", "without quotes"),
    ({"vsc.heartbeat_hz": 19}, "vsc.heartbeat_hz", "from 20 to 50"),
    ({"vsc.heartbeat_hz": 51}, "vsc.heartbeat_hz", "from 20 to 50"),
    ({"vsc.heartbeat_hz": True}, "vsc.heartbeat_hz", "whole number"),
    ({"vsc.require_watchdog": "yes"}, "vsc.require_watchdog", "true or false"),
    ({"vsc": {"transport": "can"}}, "vsc.require_watchdog", "set it to false"),
    ({"vsc": {**CAN_VSC, "require_watchdog": True}}, "vsc.require_watchdog", "no key 85"),
    ({"vsc": {**CAN_VSC, "interface": "sockecan"}}, "vsc.interface", "did you mean 'socketcan'?"),
    ({"vsc": {**CAN_VSC, "interface": "zzz"}}, "vsc.interface", "python-can interface"),
    ({"vsc": {**CAN_VSC, "bitrate": 123_456}}, "vsc.bitrate", "use one of 10000, 20000"),
    ({"vsc": {**CAN_VSC, "bitrate": "250k"}}, "vsc.bitrate", "without quotes"),
    ({"vsc": {**CAN_VSC, "channel": "can 0"}}, "vsc.channel", "a channel name without spaces"),
    ({"vsc": {**CAN_VSC, "channel": ""}}, "vsc.channel", "a channel name without spaces"),
    ({"vsc": {**CAN_VSC, "channel": -1}}, "vsc.channel", "a channel name without spaces"),
]


@pytest.mark.parametrize(("changes", "key", "fix"), VSC_CASES, ids=lambda c: str(c)[:40])
def test_vsc(tmp_path: Path, changes: dict[str, object], key: str, fix: str) -> None:
    """[vsc]: transport, its own keys only, fixed baud, backoff, and the safety values."""
    check(tmp_path, changes, key, fix)


def test_serial_defaults_and_fixed_baud(tmp_path: Path) -> None:
    """A serial VSC defaults to the udev symlink and accepts baud = 115200 said aloud."""
    config = load(tmp_path, {"vsc": {"transport": "serial", "baud": 115_200}})
    assert config.vsc.link == SerialPort(Path(DEFAULT_SERIAL_PORT), SERIAL_BAUD)


@pytest.mark.parametrize(
    ("changes", "expected"),
    [({}, 20), ({"vsc.min_remote_battery": 0}, 0), ({"vsc.min_remote_battery": 100}, 100)],
)
def test_min_remote_battery(tmp_path: Path, changes: dict[str, object], expected: int) -> None:
    """vsc.min_remote_battery (SR-8.11): 20 % by default, 0 (no battery check) to 100, on
    every transport."""
    assert load(tmp_path, changes).safety.min_remote_battery == expected
    can = {**CAN_VSC, **{key.removeprefix("vsc."): value for key, value in changes.items()}}
    assert load(tmp_path, {"vsc": can}).safety.min_remote_battery == expected


@pytest.mark.parametrize(
    ("changes", "expected"),
    [
        ({}, Reaction.WARN),
        ({"vsc.on_estop_unavailable": "hold"}, Reaction.HOLD),
        ({"vsc.on_estop_unavailable": "stop"}, Reaction.STOP),
    ],
)
def test_on_estop_unavailable(
    tmp_path: Path, changes: dict[str, object], expected: Reaction
) -> None:
    """vsc.on_estop_unavailable (SR-8.12): a warning by default, a hold or a stop when given,
    on every transport."""
    assert load(tmp_path, changes).safety.on_estop_unavailable is expected
    can = {**CAN_VSC, **{key.removeprefix("vsc."): value for key, value in changes.items()}}
    assert load(tmp_path, {"vsc": can}).safety.on_estop_unavailable is expected


def test_can_vsc_defaults(tmp_path: Path) -> None:
    """A CAN VSC defaults to socketcan on can0 at 250 kbit/s and a 300 ms link timeout."""
    config = load(tmp_path, {"vsc": CAN_VSC})
    assert config.vsc.transport is Transport.CAN
    assert config.vsc.link == CanBus("socketcan", "can0", DEFAULT_CAN_BITRATE)
    assert config.safety.vsc_timeout_ns == 300 * MS
    assert config.vsc.link.bus_options() == {
        "interface": "socketcan",
        "channel": "can0",
        "bitrate": 250_000,
    }


@pytest.mark.parametrize(
    ("interface", "channel"), [("virtual", "srcs-test"), ("udp_multicast", "239.74.163.2")]
)
def test_can_vsc_test_interfaces(tmp_path: Path, interface: str, channel: str) -> None:
    """python-can's virtual and udp_multicast interfaces need only interface and channel."""
    config = load(tmp_path, {"vsc": {**CAN_VSC, "interface": interface, "channel": channel}})
    assert config.vsc.link == CanBus(interface, channel, DEFAULT_CAN_BITRATE)


def test_can_channel_may_be_a_number(tmp_path: Path) -> None:
    """Interfaces that number their channels (kvaser, ixxat) take an integer channel."""
    config = load(tmp_path, {"vsc": {**CAN_VSC, "interface": "kvaser", "channel": 0}})
    assert config.vsc.link == CanBus("kvaser", 0, DEFAULT_CAN_BITRATE)


def test_hid_loads_with_a_warning(tmp_path: Path) -> None:
    """transport "hid" is accepted, with its hidraw path and a warning that it never runs."""
    config = load(tmp_path, {"vsc": {"transport": "hid", "hidraw": "/dev/hidraw3"}})
    assert config.vsc.link == HidDevice(Path("/dev/hidraw3"))
    assert any("never a safety channel" in note.text for note in config.warnings())


def test_watchdog_off_on_serial_warns(tmp_path: Path) -> None:
    """require_watchdog = false on serial is allowed, with a warning."""
    config = load(tmp_path, {"vsc.require_watchdog": False})
    assert config.safety.require_watchdog is False
    assert any("key 85" in note.text for note in config.warnings())


REARM_CASES: list[Case] = [
    ({"rearm.hold_ms": 99}, "rearm.hold_ms", "from 100 to 60000"),
    ({"rearm.hold_ms": 60_001}, "rearm.hold_ms", "from 100 to 60000"),
    ({"rearm.hold_ms": "500"}, "rearm.hold_ms", "whole number"),
    ({"rearm.local_reset": 1}, "rearm.local_reset", "true or false"),
    ({"rearm.rearm_hold_ms": 500}, "rearm.rearm_hold_ms", "did you mean 'hold_ms'?"),
]


@pytest.mark.parametrize(("changes", "key", "fix"), REARM_CASES, ids=lambda c: str(c)[:30])
def test_rearm(tmp_path: Path, changes: dict[str, object], key: str, fix: str) -> None:
    """[rearm]: hold time in range (checked by SafetyConfig), local_reset a flag."""
    check(tmp_path, changes, key, fix)


CLIENT_CASES: list[Case] = [
    ({"clients": {"name": "autonomy"}}, "clients", "own [[clients]] table"),
    ({"clients": ["autonomy"]}, "clients", "own [[clients]] table"),
    ({"clients[0].name": DELETE}, "clients[0].name", "1 to 32 characters"),
    ({"clients[0].name": "auto nomy"}, "clients[0].name", "1 to 32 characters"),
    ({"clients[0].name": "x" * 33}, "clients[0].name", "1 to 32 characters"),
    ({"clients[1]": {"name": "autonomy"}}, "clients[1].name", "clients[0] has the same name"),
    ({"clients[1]": {"name": "nav", "timeout_ms": 19}}, "clients[1].timeout_ms", "20 to 10000"),
    ({"clients[0].timeout_ms": 10_001}, "clients[0].timeout_ms", "from 20 to 10000"),
    ({"clients[0].timeout_ms": 0.5}, "clients[0].timeout_ms", "whole number"),
    ({"clients[0].timeout": 500}, "clients[0].timeout", "did you mean 'timeout_ms'?"),
]


@pytest.mark.parametrize(("changes", "key", "fix"), CLIENT_CASES, ids=lambda c: str(c)[:30])
def test_clients(tmp_path: Path, changes: dict[str, object], key: str, fix: str) -> None:
    """[[clients]]: an array of tables, unique valid names, timeouts in SafetyConfig's range."""
    check(tmp_path, changes, key, fix)


def test_no_clients_is_allowed(tmp_path: Path) -> None:
    """A robot with no required client (the demo) loads with an empty client list."""
    assert load(tmp_path, {"clients": DELETE}).safety.clients == ()


OUTPUT_CASES: list[Case] = [
    ({"outputs": DELETE}, "outputs", "add at least one [[outputs]]"),
    (
        {"outputs": {"drive": {"kind": "sim"}}},
        "outputs.drive",
        'write [[outputs]] with name = "drive"',
    ),
    ({"outputs": ["drive"]}, "outputs", "own [[outputs]] table"),
    ({"outputs[0].name": DELETE}, "outputs[0].name", "1 to 32 characters"),
    ({"outputs[0].name": "dr.ive"}, "outputs[0].name", "'_' and '-'"),
    (
        {"outputs[0].kind": DELETE},
        "outputs[0].kind",
        '"sim" (simulated), "gpio" (a GPIO line), "can"',
    ),
    (
        {"outputs[0].kind": "relay"},
        "outputs[0].kind",
        '"sim" (simulated), "gpio" (a GPIO line), "can"',
    ),
    ({"outputs[0].class": "motion"}, "outputs[0].class", "did you mean 'role'?"),
    ({"outputs[0].pathh": "x"}, "outputs[0].pathh", "did you mean 'path'?"),
    ({"outputs[0].chip": "gpiochip0"}, "outputs[0].chip", "unknown key"),
    ({"outputs[0].role": "drive"}, "outputs[0].role", '"motion", "power"'),
    ({"outputs[0].stuck_at": "maybe"}, "outputs[0].stuck_at", '"on", "off"'),
    ({"outputs[0]": {"name": "drive", "kind": "gpio", "line": 17}}, "outputs[0].chip", "string"),
    (
        {"outputs[0]": {"name": "d", **GPIO, "pulse_period_ms": 1}},
        "outputs[0].pulse_period_ms",
        "2 to 1000",
    ),
    ({"outputs[0]": {"name": "d", **CAN_OUT, "period_ms": 4}}, "outputs[0].period_ms", "5 to 1000"),
    ({"outputs[0]": {"name": "d", **CAN_OUT, "data_on": "00"}}, "outputs[0].data_on", "differ"),
    (
        {"outputs[0]": {"name": "d", **CAN_OUT, "arbitration_id": 0x800}},
        "outputs[0].arbitration_id",
        "extended",
    ),
    (
        {"outputs[1]": {"name": "drive", "kind": "sim"}},
        "outputs[1].name",
        "rename it: outputs[0] (drive) has it",
    ),
    (
        {"outputs[0]": {"name": "a", **GPIO}, "outputs[1]": {"name": "b", **GPIO}},
        "outputs[1].line",
        "its own line: outputs[0] (a) has it",
    ),
    (
        {"outputs[0].path": "run/x", "outputs[1]": {"name": "b", "kind": "sim", "path": "run/x"}},
        "outputs[1].path",
        "its own file",
    ),
    (
        {
            "vsc": CAN_VSC,
            "outputs[0]": {"name": "a", **CAN_OUT},
            "outputs[1]": {"name": "b", **CAN_OUT, "data_on": "02"},
        },
        "outputs[1].arbitration_id",
        "its own id: outputs[0] (a) has it",
    ),
    ({"outputs[0].role": "power"}, "outputs", 'at least one output role = "motion"'),
    # SR-1.4: a stop category of 1 for power outputs only, within its bound
    ({"outputs[0].off_delay_ms": 300}, "outputs[0].off_delay_ms", 'role = "power"'),
    (
        {"outputs[1]": {"name": "p", "kind": "sim", "role": "power", "off_delay_ms": 5001}},
        "outputs[1].off_delay_ms",
        "0 to 5000",
    ),
    ({"outputs[0]": {"name": "d", **CAN_OUT}}, "outputs[0].kind", "add an [output_bus] section"),
    ({"output_bus": {"channel": "can1"}}, "output_bus", 'no output has kind = "can"'),
    (
        {"vsc": CAN_VSC, "outputs[0]": {"name": "d", **CAN_OUT}, "output_bus": {"channel": "can0"}},
        "output_bus.channel",
        "already send on the VSC's bus",
    ),
    (
        {"outputs[0]": {"name": "d", **CAN_OUT}, "output_bus": {"chanel": "can1"}},
        "output_bus.chanel",
        "did you mean 'channel'?",
    ),
    (
        {"outputs[0]": {"name": "d", **CAN_OUT}, "output_bus": {"bitrate": 1}},
        "output_bus.bitrate",
        "use one of 10000, 20000",
    ),
    ({"output_bus": "can1"}, "output_bus", "make it a table"),
]


@pytest.mark.parametrize(("changes", "key", "fix"), OUTPUT_CASES, ids=lambda c: str(c)[:40])
def test_outputs(tmp_path: Path, changes: dict[str, object], key: str, fix: str) -> None:
    """[[outputs]]: each kind's own checks under outputs[i], and the checks between outputs."""
    check(tmp_path, changes, key, fix)


def test_output_specs_and_safety_classes(tmp_path: Path) -> None:
    """Each output becomes its kind's spec, and the safety core gets its name and class."""
    config = load(
        tmp_path,
        {
            "outputs[1]": {"name": "relay", **GPIO, "role": "power", "pulse_period_ms": 10},
            "outputs[2]": {"name": "brake", **GPIO, "line": "BRAKE_EN"},
        },
    )
    assert [(s.name, s.kind, s.role) for s in config.outputs] == [
        ("drive", OutputKind.SIM, OutputRole.MOTION),
        ("relay", OutputKind.GPIO, OutputRole.POWER),
        ("brake", OutputKind.GPIO, OutputRole.MOTION),
    ]
    assert [(o.name, o.role) for o in config.safety.outputs] == [
        ("drive", OutputRole.MOTION),
        ("relay", OutputRole.POWER),
        ("brake", OutputRole.MOTION),
    ]
    assert getattr(config.outputs[1], "pulse_period_ms", None) == 10


def test_a_power_output_may_have_a_stop_category_of_1(tmp_path: Path) -> None:
    """SR-1.4: ``off_delay_ms`` reaches the safety core with the output of every kind; left out,
    it is 0 (category 0)."""
    config = load(
        tmp_path,
        {
            "outputs[1]": {"name": "relay", **GPIO, "role": "power", "off_delay_ms": 800},
            "outputs[2]": {"name": "lamp", "kind": "sim", "role": "power", "off_delay_ms": 0},
        },
    )
    assert [(o.name, o.off_delay_ms) for o in config.safety.outputs] == [
        ("drive", 0),
        ("relay", 800),
        ("lamp", 0),
    ]
    assert getattr(config.outputs[1], "line", None) == 17  # the kind's options are kept


def test_can_outputs_use_the_vsc_bus(tmp_path: Path) -> None:
    """With a CAN VSC and no [output_bus], CAN outputs send on the VSC's bus."""
    config = load(tmp_path, {"vsc": CAN_VSC, "outputs[0]": {"name": "d", **CAN_OUT}})
    assert config.output_bus is None
    assert config.can_output_bus == config.vsc.link


def test_can_outputs_on_their_own_bus(tmp_path: Path) -> None:
    """[output_bus] gives CAN outputs a bus of their own, with a serial or a CAN VSC."""
    serial = load(tmp_path, {"outputs[0]": {"name": "d", **CAN_OUT}, "output_bus": {}})
    assert serial.can_output_bus == CanBus("socketcan", "can0", DEFAULT_CAN_BITRATE)
    second = load(
        tmp_path,
        {
            "vsc": CAN_VSC,
            "outputs[0]": {"name": "d", **CAN_OUT},
            "output_bus": {"channel": "can1", "bitrate": 500_000},
        },
    )
    assert second.can_output_bus == CanBus("socketcan", "can1", 500_000)


def test_same_line_on_other_chips_is_allowed(tmp_path: Path) -> None:
    """Two GPIO outputs may use the same offset on different chips."""
    config = load(
        tmp_path,
        {"outputs[0]": {"name": "a", **GPIO}, "outputs[1]": {"name": "b", **GPIO, "chip": "x"}},
    )
    assert len(config.outputs) == 2


def test_relative_paths_follow_the_config_file(tmp_path: Path) -> None:
    """Relative paths (port, sim file, record, socket) are resolved against the file's folder."""
    config = load(
        tmp_path,
        {
            "vsc.port": "run/vsc",
            "outputs[0].path": "run/drive",
            "record": {"path": "run/stops.jsonl"},
            "api": {"socket": "run/api.sock"},
        },
    )
    assert config.vsc.link == SerialPort(tmp_path / "run/vsc", SERIAL_BAUD)
    assert getattr(config.outputs[0], "path", None) == tmp_path / "run/drive"
    assert config.record.path == tmp_path / "run/stops.jsonl"
    assert config.api.socket == tmp_path / "run/api.sock"


def test_base_dir_overrides_the_config_folder(tmp_path: Path) -> None:
    """``base_dir`` replaces the file's folder as the root of relative paths."""
    run = tmp_path / "elsewhere"
    config = load(tmp_path, {"vsc.port": "vsc", "outputs[0].path": "drive"}, base_dir=run)
    assert config.vsc.link == SerialPort(run / "vsc", SERIAL_BAUD)
    assert getattr(config.outputs[0], "path", None) == run / "drive"


RECORD_CASES: list[Case] = [
    ({"record.max_bytes": 4095}, "record.max_bytes", "from 4096 to 1073741824"),
    ({"record.max_bytes": 1 << 31}, "record.max_bytes", "from 4096 to 1073741824"),
    ({"record.keep": 0}, "record.keep", "from 1 to 99"),
    ({"record.keep": 100}, "record.keep", "from 1 to 99"),
    ({"record.journal": "on"}, "record.journal", "true or false"),
    ({"record.path": "/var/lib/srcsd/"}, "record.path", "not a directory's"),
    ({"record.path": ""}, "record.path", "non-empty string"),
    ({"record.max_byte": 1}, "record.max_byte", "did you mean 'max_bytes'?"),
]


@pytest.mark.parametrize(("changes", "key", "fix"), RECORD_CASES, ids=lambda c: str(c)[:30])
def test_record(tmp_path: Path, changes: dict[str, object], key: str, fix: str) -> None:
    """[record]: a file path, the store's size and count bounds, the journal flag."""
    check(tmp_path, changes, key, fix)


API_CASES: list[Case] = [
    (
        {"api.socket": "/run/" + "s" * 94},
        "api.socket",
        "at most 98 bytes (a Unix socket address holds 107, and the daemon first binds the "
        "socket under a name up to 9 bytes longer)",
    ),
    (
        {"api.operator_socket": "/run/" + "o" * 94},
        "api.operator_socket",
        "at most 98 bytes",
    ),
    ({"api.socket": 1}, "api.socket", "non-empty string"),
    ({"api.admin_group": "nobody-here"}, "api.admin_group", "groupadd --system nobody-here"),
    ({"api.admin_group": "bad group"}, "api.admin_group", "use a group name"),
    ({"api.admin_group": ""}, "api.admin_group", "use a group name"),
    ({"api.group": "nobody-here"}, "api.group", "groupadd --system nobody-here"),
    ({"api.group": 7}, "api.group", 'e.g. "srcs"'),
    ({"api.max_clients": 0}, "api.max_clients", "from 1 to 256"),
    ({"api.max_clients": 257}, "api.max_clients", "from 1 to 256"),
    (
        {"clients[1]": {"name": "nav"}, "clients[2]": {"name": "map"}, "api.max_clients": 3},
        "api.max_clients",
        "at least 4: the 3 required clients and one srcsctl",
    ),
    ({"api.max_message_bytes": 255}, "api.max_message_bytes", "from 256 to 1048576"),
    ({"api.admin": "srcs"}, "api.admin", "did you mean 'admin_group'?"),
]


@pytest.mark.parametrize(("changes", "key", "fix"), API_CASES, ids=lambda c: str(c)[:30])
def test_api(tmp_path: Path, changes: dict[str, object], key: str, fix: str) -> None:
    """[api]: socket path length, existing socket and admin groups, client and message
    limits."""
    check(tmp_path, changes, key, fix)


def test_socket_path_at_the_limit_is_accepted(tmp_path: Path) -> None:
    """SR-11.2, SR-8.14: a socket path of exactly 98 bytes is accepted, the name the daemon
    binds first (two dots and a PID of up to 7 digits more) then fitting sun_path with its NUL
    (tests/daemon/test_socket_path_limit.py serves at it); the operator socket named apart (the
    one beside it would not fit), and at the limit too."""
    socket = "/run/" + "s" * 93
    operator = "/run/" + "o" * 93
    assert len(socket) == len(operator) == SOCKET_PATH_MAX_BYTES == 98
    api = load(tmp_path, {"api.socket": socket, "api.operator_socket": operator}).api
    assert (api.socket, api.operator_path) == (Path(socket), Path(operator))


def test_the_operator_socket_beside_the_socket_is_its_default_and_must_fit(
    tmp_path: Path,
) -> None:
    """SR-8.14: without the key the operator socket is the socket's path with -operator
    before its suffix; when that would not fit a socket address the config is refused with
    the fix (name one), never served without an operator socket."""
    config = load(tmp_path, {"api.socket": "/run/srcsd/robot-a.sock"})
    assert config.api.operator_path == Path("/run/srcsd/robot-a-operator.sock")
    error = refused(tmp_path, {"api.socket": "/run/" + "s" * 93})
    assert error.key.endswith("api.operator_socket")
    assert "operator" in error.fix


def test_the_operator_socket_must_not_be_the_socket(tmp_path: Path) -> None:
    """SR-8.14: an operator socket at the client socket's own path is refused (one owner
    per path)."""
    error = refused(tmp_path, {"api.socket": "a.sock", "api.operator_socket": "a.sock"})
    assert "operator_socket" in error.key


def test_admin_group_is_looked_up_on_the_system(tmp_path: Path) -> None:
    """Without an injected lookup, admin_group is checked with grp.getgrnam."""
    mine = grp.getgrgid(os.getgid()).gr_name
    file = tmp_path / "robot.toml"
    file.write_text(dump(changed({"api.admin_group": mine})))
    assert load_config(file).api.admin_group == mine
    file.write_text(dump(changed({"api.admin_group": "srcs-no-such-group-x"})))
    with pytest.raises(ConfigError, match="no such group on this machine"):
        load_config(file)


def test_missing_values_are_shown_as_not_set(tmp_path: Path) -> None:
    """A required key that is absent is named with the value "(not set)"."""
    error = refused(tmp_path, {"robot.name": DELETE})
    assert error.value is MISSING
    assert "robot.name = (not set): " in str(error)


BOUND_CLIENT_CASES: list[Case] = [
    ({"clients[0].user": "no-such-user-xyz"}, "clients[0].user", "useradd --system"),
    ({"clients[0].user": "bad user"}, "clients[0].user", "use a user name"),
    ({"clients[0].user": 0}, "clients[0].user", "use a user name"),
    ({"clients[0].uid": -1}, "clients[0].uid", "from 0 to 4294967294"),
    ({"clients[0].uid": 1 << 32}, "clients[0].uid", "from 0 to 4294967294"),
    ({"clients[0].uid": "0"}, "clients[0].uid", "whole number"),
    ({"clients[0].uid": 0, "clients[0].user": "root"}, "clients[0].uid", "not both"),
]


@pytest.mark.parametrize(("changes", "key", "fix"), BOUND_CLIENT_CASES, ids=lambda c: str(c)[:30])
def test_bound_clients(tmp_path: Path, changes: dict[str, object], key: str, fix: str) -> None:
    """[[clients]] user and uid: an existing user or a valid uid, never both."""
    check(tmp_path, changes, key, fix)


def test_a_client_is_bound_by_user_name_or_uid_and_unbound_by_default(tmp_path: Path) -> None:
    """user = "root" binds the client to uid 0, uid = 1234 to 1234; without either the
    client is unbound (uid None): any user who can reach the socket may use its name."""
    config = load(tmp_path, {"clients[0].user": "root", "clients[1]": {"name": "nav"}})
    assert [(c.name, c.uid) for c in config.safety.clients] == [("autonomy", 0), ("nav", None)]
    config = load(tmp_path, {"clients[0].uid": 1234})
    assert config.safety.clients[0].uid == 1234


@pytest.mark.parametrize(("value", "accepted"), [(1, True), (256, True), (0, False), (257, False)])
def test_max_clients_has_one_range(tmp_path: Path, value: int, accepted: bool) -> None:
    """SR-11.2: the robot's file and the API server built in code accept the same
    api.max_clients: one range, checked in one place."""
    from supervisord.api.server import ServerConfig  # noqa: PLC0415

    changes = {"clients": DELETE, "api.max_clients": value}
    if accepted:
        assert load(tmp_path, changes).api.max_clients == value
        assert ServerConfig(tmp_path / "api.sock", max_clients=value).max_clients == value
    else:
        assert refused(tmp_path, changes).key == "api.max_clients"
        with pytest.raises(ConfigError, match=r"api\.max_clients"):
            ServerConfig(tmp_path / "api.sock", max_clients=value)


def test_schema_keys_are_taken_by_name_and_kind() -> None:
    """The loader takes each key of a table by its name and kind (``strict.named``), never by
    its place in the schema: reordered, ``max_bytes`` and ``keep`` (both whole numbers) would
    otherwise swap without a sound."""
    swapped = tuple(reversed(RECORD))
    assert strict.named(swapped, "keep", strict.Whole) is strict.named(RECORD, "keep", strict.Whole)
    assert strict.named(RECORD, "max_bytes", strict.Whole).name == "max_bytes"
    with pytest.raises(LookupError, match="no Flag key 'keep'"):
        strict.named(RECORD, "keep", strict.Flag)
    with pytest.raises(LookupError, match="no Whole key 'kept'"):
        strict.named(RECORD, "kept", strict.Whole)
