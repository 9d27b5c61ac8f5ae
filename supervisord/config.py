"""The robot's configuration: one TOML file, read with ``tomllib`` and validated completely.

:func:`load_config` turns the file into a :class:`DaemonConfig` of frozen values, or raises
:class:`~supervisord.errors.ConfigError` naming the file, the key (as a dotted path such as
``vsc.timeout_ms`` or ``outputs[1].chip``), the value and the fix; the daemon prints it and
refuses to start. ``docs/configuration.md`` lists every key with its default and range.

What this module checks, and what it leaves to others:

- the safety values go through :class:`~supervisord.safety.config.SafetyConfig`, which checks
  their ranges itself; its errors are renamed here to the TOML key they came from;
- each ``[[outputs]]`` table is parsed by its kind's plugin (``supervisord.outputs``), which
  checks that kind's options; this module adds the cross-checks between outputs;
- everything else (the robot, the VSC link, the record, the API socket) is checked here.

A key this module does not know is an error, never ignored: a misspelt safety option must not
silently fall back to its default. Relative paths are resolved against the config file's
directory (or ``base_dir``), so that a self-contained config such as the demo's works from any
working directory. Only the first error is reported.
"""

from __future__ import annotations

import dataclasses
import difflib
import grp
import os
import pwd
import re
import sys
import tomllib
from collections.abc import Callable, Mapping, Sequence
from pathlib import Path
from typing import Final

from supervisord.errors import ConfigError
from supervisord.outputs import (
    OutputKind,
    OutputSpec,
    parse_output_spec,
    spec_class,
)
from supervisord.record.jsonl import (
    DEFAULT_KEEP,
    DEFAULT_MAX_BYTES,
    KEEP_RANGE,
    MAX_BYTES_RANGE,
    rotated,
)
from supervisord.safety.config import (
    CLIENT_TIMEOUT_RANGE_MS,
    DEFAULT_CLIENT_TIMEOUT_MS,
    DEFAULT_PROOFTEST_CLEAR_MS,
    HEARTBEAT_HZ_RANGE,
    PROOFTEST_CLEAR_RANGE_MS,
    REARM_HOLD_RANGE_MS,
    UID_RANGE,
    VSC_TIMEOUT_RANGE_MS,
    ClientSpec,
    OutputRole,
    SafetyConfig,
    Transport,
)
from supervisord.safety.config import OutputSpec as SafetyOutputSpec
from supervisord.safety.prooftest import ProofTestPolicy

# ---------------------------------------------------------------------------------------------
# Defaults and ranges (docs/configuration.md lists each one)

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
DEFAULT_RECORD_PATH: Final = "/var/lib/srcsd/stops.jsonl"
DEFAULT_SOCKET: Final = "/run/srcsd/api.sock"
SOCKET_PATH_MAX_BYTES: Final = 107  # sun_path holds 108 bytes, the last one the NUL
DEFAULT_MAX_CLIENTS: Final = 16
MAX_CLIENTS_RANGE: Final = (2, 256)
DEFAULT_MAX_MESSAGE_BYTES: Final = 65_536
MAX_MESSAGE_BYTES_RANGE: Final = (1_024, 1_048_576)
ROBOT_NAME_MAX: Final = 64

OUTPUT_NAME: Final = re.compile(r"[A-Za-z0-9_-]{1,32}")
"""Output names: the safety core allows ``.`` too, the output plugins do not; both must hold."""
CLIENT_NAME: Final = re.compile(r"[A-Za-z0-9_.-]{1,32}")
GROUP_NAME: Final = re.compile(r"[A-Za-z_][A-Za-z0-9_.-]{0,31}")
KERNEL_CHIP_NAME: Final = re.compile(r"gpiochip[0-9]+")
"""A GPIO chip's kernel name: the device ``/dev/NAME`` (supervisord.outputs.gpio)."""
USER_NAME: Final = GROUP_NAME

SECTIONS: Final = ("robot", "vsc", "rearm", "clients", "outputs", "output_bus", "record", "api")
ROBOT_KEYS: Final = ("name",)
VSC_COMMON_KEYS: Final = (
    "transport",
    "timeout_ms",
    "require_watchdog",
    "prooftest",
    "prooftest_clear_ms",
    "reopen_min_ms",
    "reopen_max_ms",
)
VSC_TRANSPORT_KEYS: Final[Mapping[Transport, tuple[str, ...]]] = {
    Transport.SERIAL: ("port", "baud", "heartbeat_hz"),
    Transport.CAN: (
        "interface",
        "channel",
        "bitrate",
        "error_limit",
        "error_window_ms",
        "error_passive_ms",
    ),
    Transport.HID: ("hidraw",),
}
CAN_BUS_KEYS: Final = ("interface", "channel", "bitrate")
REARM_KEYS: Final = ("hold_ms", "local_reset")
CLIENT_KEYS: Final = ("name", "timeout_ms", "user", "uid")
RECORD_KEYS: Final = ("path", "max_bytes", "keep", "journal")
API_KEYS: Final = ("socket", "group", "admin_group", "max_clients", "max_message_bytes")

RENAMED: Final[Mapping[str, str]] = {"log": "record", "class": "role", "rearm_hold_ms": "hold_ms"}
"""Names an integrator may try from older sketches, and the name this file uses instead."""


class _Missing:
    """The value of a key that is not set (shown as ``(not set)`` in error messages)."""

    def __repr__(self) -> str:
        return "(not set)"


MISSING: Final = _Missing()


# ---------------------------------------------------------------------------------------------
# The configuration as frozen values


@dataclasses.dataclass(frozen=True, slots=True)
class RobotConfig:
    """``[robot]``: who this is (shown in ``--check-config`` and the logs)."""

    name: str


@dataclasses.dataclass(frozen=True, slots=True)
class SerialLink:
    """``[vsc]`` with ``transport = "serial"``: the VSC's USB CDC or RS-232 port."""

    port: Path = Path(DEFAULT_SERIAL_PORT)
    baud: int = SERIAL_BAUD


@dataclasses.dataclass(frozen=True, slots=True)
class CanBus:
    """A CAN bus opened with python-can: the VSC's (``[vsc]`` with ``transport = "can"``) or
    the enable frames' own (``[output_bus]``)."""

    interface: str = DEFAULT_CAN_INTERFACE
    channel: str | int = DEFAULT_CAN_CHANNEL
    bitrate: int = DEFAULT_CAN_BITRATE

    def bus_options(self) -> dict[str, str | int]:
        """The keyword arguments for ``can.Bus``."""
        return {"interface": self.interface, "channel": self.channel, "bitrate": self.bitrate}


@dataclasses.dataclass(frozen=True, slots=True)
class HidLink:
    """``[vsc]`` with ``transport = "hid"``: the VSC's hidraw device (never a safety channel)."""

    hidraw: Path


@dataclasses.dataclass(frozen=True, slots=True)
class Backoff:
    """How long the daemon waits before reopening a lost VSC link: ``min_ms`` after the first
    failure, doubling up to ``max_ms``."""

    min_ms: int = DEFAULT_REOPEN_MIN_MS
    max_ms: int = DEFAULT_REOPEN_MAX_MS


@dataclasses.dataclass(frozen=True, slots=True)
class CanErrors:
    """``[vsc]`` on CAN: when error frames become a link fault (docs/safety.md "CAN error
    frames"). More than ``limit`` within ``window_ms``, or a controller error-passive for
    ``passive_ms``, break the link; fewer are counted, shown in ``status`` and stop nothing."""

    limit: int = DEFAULT_CAN_ERROR_LIMIT
    window_ms: int = DEFAULT_CAN_ERROR_WINDOW_MS
    passive_ms: int = DEFAULT_CAN_ERROR_PASSIVE_MS


@dataclasses.dataclass(frozen=True, slots=True)
class VscConfig:
    """``[vsc]``: how the VSC is connected. The safety values of the same section (timeout,
    heartbeat rate, watchdog) are in :attr:`DaemonConfig.safety`."""

    transport: Transport
    link: SerialLink | CanBus | HidLink
    reopen: Backoff = Backoff()
    can_errors: CanErrors = CanErrors()
    """Used only on CAN (``[output_bus]`` errors are not read: it only sends)."""


@dataclasses.dataclass(frozen=True, slots=True)
class RecordConfig:
    """``[record]``: the record of stops (``docs/record.md``)."""

    path: Path = Path(DEFAULT_RECORD_PATH)
    max_bytes: int = DEFAULT_MAX_BYTES
    keep: int = DEFAULT_KEEP
    journal: bool = True


@dataclasses.dataclass(frozen=True, slots=True)
class ApiConfig:
    """``[api]``: the Unix socket the robot's software and ``srcsctl`` talk to.

    ``group`` owns the socket (mode 0660): the robot's programs must be in it to connect
    (``None``: the daemon's own group). ``admin_group`` ``None`` means no group: commands that
    can re-enable motion or write the VSC are then allowed only to root and to the daemon's
    own user.
    """

    socket: Path = Path(DEFAULT_SOCKET)
    group: str | None = None
    admin_group: str | None = None
    max_clients: int = DEFAULT_MAX_CLIENTS
    max_message_bytes: int = DEFAULT_MAX_MESSAGE_BYTES


@dataclasses.dataclass(frozen=True, slots=True)
class DaemonConfig:
    """One robot's whole configuration, validated (build it with :func:`load_config`).

    ``outputs`` holds each output kind's own spec, in file order; ``safety.outputs`` the same
    outputs by name and class, for the safety core. ``output_bus`` is the ``[output_bus]``
    section, if any; :attr:`can_output_bus` is the bus CAN outputs actually send on.
    """

    source: Path
    robot: RobotConfig
    vsc: VscConfig
    safety: SafetyConfig
    outputs: tuple[OutputSpec, ...]
    output_bus: CanBus | None = None
    record: RecordConfig = RecordConfig()
    api: ApiConfig = ApiConfig()

    @property
    def can_output_bus(self) -> CanBus | None:
        """The bus the ``kind = "can"`` outputs send on: ``[output_bus]`` when given, else the
        VSC's own bus when the VSC is on CAN, else ``None`` (then there are no CAN outputs)."""
        if self.output_bus is not None:
            return self.output_bus
        return self.vsc.link if isinstance(self.vsc.link, CanBus) else None

    def warnings(self) -> tuple[str, ...]:
        """What is valid but deserves a loud word at start and in ``--check-config``."""
        notes = []
        if self.vsc.transport is Transport.HID:
            notes.append(
                'transport "hid" is never a safety channel: the supervisor stays STOPPED '
                "and its outputs stay off (docs/configuration.md, [vsc])"
            )
        if self.vsc.transport is Transport.SERIAL and not self.safety.require_watchdog:
            notes.append(
                "vsc.require_watchdog = false: the VSC's own user watchdog (key 85) is not "
                "checked, so the VSC does not stop when the supervisor falls silent"
            )
        if self.vsc.transport is Transport.SERIAL and self.safety.prooftest is ProofTestPolicy.OFF:
            notes.append(
                'vsc.prooftest = "off": the VSC\'s watchdog is never seen to act, so a VSC that '
                "reads key 85 = 1 but ignores a missing heartbeat goes unnoticed (docs/safety.md)"
            )
        notes += [
            f"outputs[{i}] ({spec.name}) is simulated: it drives no hardware"
            for i, spec in enumerate(self.outputs)
            if spec.kind is OutputKind.SIM
        ]
        return tuple(notes)


# ---------------------------------------------------------------------------------------------
# Loading


def load_config(
    path: str | Path,
    *,
    base_dir: str | Path | None = None,
    group_exists: Callable[[str], bool] | None = None,
) -> DaemonConfig:
    """Read and validate the robot's TOML file at ``path``.

    Relative paths in the file are resolved against ``base_dir`` (default: the file's own
    directory). ``group_exists`` says whether a group name exists (default: ask the system
    with ``grp.getgrnam``). Raises :class:`ConfigError` naming ``path``, the key, the value and
    the fix for the first problem found: a missing or unreadable file, a TOML syntax error
    (key ``line L, column C``), an unknown section or key, a bad value or a contradiction
    between sections.
    """
    file = str(path)
    source = Path(path)
    base = Path(base_dir) if base_dir is not None else source.parent
    try:
        data = _read_toml(source)
        return _Loader(source, base.absolute(), group_exists or _group_exists).build(data)
    except ConfigError as error:
        raise (error if error.file else error.in_file(file)) from None


def check_config_main(path: str | Path) -> int:
    """``srcsd --check-config FILE``: print ``FILE: OK — ...`` and any warnings and return 0,
    or print the error (to stderr) and return 1."""
    try:
        config = load_config(path)
    except ConfigError as error:
        print(error, file=sys.stderr)
        return 1
    outputs, clients = len(config.outputs), len(config.safety.clients)
    print(
        f"{path}: OK — robot {config.robot.name}, transport {config.vsc.transport.value}, "
        f"{outputs} output{'s' * (outputs != 1)}, {clients} client{'s' * (clients != 1)}"
    )
    for note in config.warnings():
        print(f"{path}: warning: {note}", file=sys.stderr)
    return 0


def _group_exists(name: str) -> bool:
    try:
        grp.getgrnam(name)
    except KeyError:
        return False
    return True


_POSITION = re.compile(r"\(at line (\d+), column (\d+)\)$")


def _read_toml(source: Path) -> dict[str, object]:
    """The parsed file; a syntax error names its line and column (key ``line L, column C``)
    and carries the text of that line as the value."""
    try:
        raw = source.read_bytes()
    except OSError as error:
        raise ConfigError(
            "file", str(source), f"give the path of a readable TOML file ({error.strerror})"
        ) from None
    try:
        text = raw.decode("utf-8")
    except UnicodeDecodeError as error:
        line = raw.count(b"\n", 0, error.start) + 1
        column = error.start - (raw.rfind(b"\n", 0, error.start) + 1) + 1
        raise ConfigError(
            f"line {line}, column {column}", raw[error.start : error.end], "save the file as UTF-8"
        ) from None
    try:
        return tomllib.loads(text)
    except tomllib.TOMLDecodeError as error:
        message = str(error)
        lines = text.splitlines() or [""]
        found = _POSITION.search(message)
        if found:
            line, column = int(found[1]), int(found[2])
        else:  # "(at end of document)"
            line, column = len(lines), len(lines[-1]) + 1
        reason = re.sub(r"\s*\(at [^)]*\)$", "", message)
        shown = lines[line - 1] if line <= len(lines) else ""
        raise ConfigError(
            f"line {line}, column {column}",
            shown,
            f"correct the TOML syntax there ({reason[:1].lower()}{reason[1:]})",
        ) from None


# ---------------------------------------------------------------------------------------------
# Readers of single values: each raises ConfigError naming the full key


def _unknown_key(key: str, name: str, value: object, known: Sequence[str]) -> ConfigError:
    hint = RENAMED.get(name) if RENAMED.get(name) in known else None
    close = difflib.get_close_matches(name, known, n=1, cutoff=0.6)
    hint = hint or (close[0] if close else None)
    listed = ", ".join(known)
    if hint:
        return ConfigError(key, value, f"unknown key: did you mean {hint!r}? (known: {listed})")
    return ConfigError(key, value, f"unknown key: remove it (known: {listed})")


def _check_keys(prefix: str, table: Mapping[str, object], known: Sequence[str]) -> None:
    for name, value in table.items():
        if name not in known:
            raise _unknown_key(_join(prefix, name), name, value, known)


def _join(prefix: str, name: str) -> str:
    return f"{prefix}.{name}" if prefix else name


def _integer(key: str, raw: object, default: int, bounds: tuple[int, int]) -> int:
    """A whole number within ``bounds``; ``MISSING`` gives ``default``."""
    value = _integer_type(key, raw, default, bounds)
    low, high = bounds
    if not low <= value <= high:
        raise ConfigError(key, raw, f"use a whole number from {low} to {high}")
    return value


def _integer_type(key: str, raw: object, default: int, bounds: tuple[int, int]) -> int:
    """A whole number (its range is left to a validator downstream, e.g. SafetyConfig)."""
    if raw is MISSING:
        return default
    if isinstance(raw, bool) or not isinstance(raw, int):
        low, high = bounds
        raise ConfigError(key, raw, f"use a whole number from {low} to {high}, without quotes")
    return raw


def _flag(key: str, raw: object, default: bool) -> bool:
    if raw is MISSING:
        return default
    if not isinstance(raw, bool):
        raise ConfigError(key, raw, "use true or false, without quotes")
    return raw


def _text(key: str, raw: object, default: str | None, example: str) -> str:
    """A non-empty string without control characters; ``MISSING`` gives ``default``."""
    if raw is MISSING and default is not None:
        return default
    if not isinstance(raw, str) or not raw.strip() or not raw.isprintable():
        raise ConfigError(key, raw, f"give a non-empty string in double quotes, e.g. {example}")
    return raw


def _path(key: str, raw: object, default: str | None, base: Path, example: str) -> Path:
    """A file path; a relative one is resolved against ``base``."""
    text = _text(key, raw, default, example)
    if text.endswith("/"):
        raise ConfigError(key, raw, f"give a file's path, not a directory's, e.g. {example}")
    path = Path(text)
    return path if path.is_absolute() else base / path


def _table(key: str, raw: object) -> Mapping[str, object]:
    """A section: absent gives an empty table."""
    if raw is MISSING:
        return {}
    if not isinstance(raw, dict):
        raise ConfigError(key, raw, f"make it a table: a line [{key}] followed by its keys")
    return raw


def _array_of_tables(key: str, raw: object, example: str) -> list[Mapping[str, object]]:
    if raw is MISSING:
        return []
    if not isinstance(raw, list) or not all(isinstance(entry, dict) for entry in raw):
        raise ConfigError(
            key, raw, f"write each entry as its own [[{key}]] table, e.g. [[{key}]] {example}"
        )
    return raw


# ---------------------------------------------------------------------------------------------
# Sections

_SAFETY_KEYS: Final[Mapping[str, str]] = {
    "transport": "vsc.transport",
    "vsc_timeout_ms": "vsc.timeout_ms",
    "heartbeat_hz": "vsc.heartbeat_hz",
    "require_watchdog": "vsc.require_watchdog",
    "prooftest": "vsc.prooftest",
    "prooftest_clear_ms": "vsc.prooftest_clear_ms",
    "rearm_hold_ms": "rearm.hold_ms",
    "local_reset": "rearm.local_reset",
}
"""SafetyConfig's own key names, and the TOML keys they come from."""


@dataclasses.dataclass
class _Loader:
    source: Path
    base: Path
    group_exists: Callable[[str], bool]

    def build(self, data: Mapping[str, object]) -> DaemonConfig:
        _check_keys("", data, SECTIONS)
        robot = self.robot(_table("robot", data.get("robot", MISSING)))
        vsc_table = _table("vsc", data.get("vsc", MISSING))
        vsc = self.vsc(vsc_table)
        clients = self.clients(data.get("clients", MISSING))
        outputs = self.outputs(data.get("outputs", MISSING))
        rearm = _table("rearm", data.get("rearm", MISSING))
        _check_keys("rearm", rearm, REARM_KEYS)
        safety = self.safety(vsc, vsc_table, rearm, clients, outputs)
        output_bus = self.output_bus(data.get("output_bus", MISSING), vsc, outputs)
        api = self.api(_table("api", data.get("api", MISSING)), len(clients))
        record = self.record(_table("record", data.get("record", MISSING)))
        _check_path_owners(vsc, outputs, record, api)
        return DaemonConfig(
            source=self.source,
            robot=robot,
            vsc=vsc,
            safety=safety,
            outputs=outputs,
            output_bus=output_bus,
            record=record,
            api=api,
        )

    # [robot] ------------------------------------------------------------------------------

    def robot(self, table: Mapping[str, object]) -> RobotConfig:
        _check_keys("robot", table, ROBOT_KEYS)
        raw = table.get("name", MISSING)
        if not isinstance(raw, str) or not raw.strip() or not raw.isprintable():
            raise ConfigError(
                "robot.name", raw, 'give the robot\'s name in [robot], e.g. name = "mower-3"'
            )
        if len(raw) > ROBOT_NAME_MAX:
            raise ConfigError("robot.name", raw, f"shorten it to {ROBOT_NAME_MAX} characters")
        return RobotConfig(raw)

    # [vsc] --------------------------------------------------------------------------------

    def vsc(self, table: Mapping[str, object]) -> VscConfig:
        every = VSC_COMMON_KEYS + tuple(k for keys in VSC_TRANSPORT_KEYS.values() for k in keys)
        _check_keys("vsc", table, tuple(dict.fromkeys(every)))
        raw = table.get("transport", MISSING)
        choices = '"serial" (USB or RS-232), "can" (J1939) or "hid" (never leaves STOPPED)'
        try:
            transport = Transport(raw)
        except ValueError:
            raise ConfigError("vsc.transport", raw, f"use {choices}") from None
        allowed = VSC_COMMON_KEYS + VSC_TRANSPORT_KEYS[transport]
        for name in table:
            if name not in allowed:
                owner = next(t for t, keys in VSC_TRANSPORT_KEYS.items() if name in keys)
                raise ConfigError(
                    f"vsc.{name}",
                    table[name],
                    f'remove it: it applies to transport "{owner.value}", not "{transport.value}"',
                )
        link: SerialLink | CanBus | HidLink
        can_errors = CanErrors()
        if transport is Transport.SERIAL:
            link = self.serial(table)
        elif transport is Transport.CAN:
            link = self.can_bus("vsc", table)
            can_errors = self.can_errors(table)
        else:
            link = HidLink(
                _path("vsc.hidraw", table.get("hidraw", MISSING), None, self.base, '"/dev/hidraw0"')
            )
        low = _integer(
            "vsc.reopen_min_ms",
            table.get("reopen_min_ms", MISSING),
            DEFAULT_REOPEN_MIN_MS,
            REOPEN_MIN_RANGE_MS,
        )
        high = _integer(
            "vsc.reopen_max_ms",
            table.get("reopen_max_ms", MISSING),
            max(DEFAULT_REOPEN_MAX_MS, low),
            REOPEN_MAX_RANGE_MS,
        )
        if high < low:
            raise ConfigError("vsc.reopen_max_ms", high, f"make it at least reopen_min_ms ({low})")
        return VscConfig(transport, link, Backoff(low, high), can_errors)

    def serial(self, table: Mapping[str, object]) -> SerialLink:
        port = _path(
            "vsc.port", table.get("port", MISSING), DEFAULT_SERIAL_PORT, self.base, '"/dev/ttyACM0"'
        )
        baud = table.get("baud", MISSING)
        if baud is not MISSING and (type(baud) is not int or baud != SERIAL_BAUD):
            raise ConfigError(
                "vsc.baud",
                baud,
                f"remove it or set {SERIAL_BAUD}: the SRCS manual fixes the VSC's serial "
                "speed at 115200 baud",
            )
        return SerialLink(port, SERIAL_BAUD)

    def can_bus(self, prefix: str, table: Mapping[str, object]) -> CanBus:
        interface = _text(
            f"{prefix}.interface",
            table.get("interface", MISSING),
            DEFAULT_CAN_INTERFACE,
            '"socketcan"',
        )
        # Imported only when a config uses CAN, as the outputs import their plugins.
        from can import VALID_INTERFACES  # noqa: PLC0415

        if interface not in VALID_INTERFACES:
            close = difflib.get_close_matches(interface, sorted(VALID_INTERFACES), n=1)
            hint = f"did you mean {close[0]!r}? " if close else ""
            raise ConfigError(
                f"{prefix}.interface",
                interface,
                f'{hint}use a python-can interface name, e.g. "socketcan", "pcan", '
                '"virtual" or "udp_multicast"',
            )
        raw = table.get("channel", MISSING)
        channel: str | int
        if isinstance(raw, int) and not isinstance(raw, bool) and raw >= 0:
            channel = raw
        else:
            channel = _text(f"{prefix}.channel", raw, DEFAULT_CAN_CHANNEL, '"can0"')
            if channel != channel.strip() or " " in channel:
                raise ConfigError(f"{prefix}.channel", raw, 'remove the spaces, e.g. "can0"')
        bitrate = _integer_type(
            f"{prefix}.bitrate",
            table.get("bitrate", MISSING),
            DEFAULT_CAN_BITRATE,
            (CAN_BITRATES[0], CAN_BITRATES[-1]),
        )
        if bitrate not in CAN_BITRATES:
            rates = ", ".join(str(rate) for rate in CAN_BITRATES)
            raise ConfigError(f"{prefix}.bitrate", bitrate, f"use a standard rate: {rates}")
        return CanBus(interface, channel, bitrate)

    @staticmethod
    def can_errors(table: Mapping[str, object]) -> CanErrors:
        """``vsc.error_limit``, ``vsc.error_window_ms``, ``vsc.error_passive_ms``."""
        return CanErrors(
            _integer(
                "vsc.error_limit",
                table.get("error_limit", MISSING),
                DEFAULT_CAN_ERROR_LIMIT,
                CAN_ERROR_LIMIT_RANGE,
            ),
            _integer(
                "vsc.error_window_ms",
                table.get("error_window_ms", MISSING),
                DEFAULT_CAN_ERROR_WINDOW_MS,
                CAN_ERROR_WINDOW_RANGE_MS,
            ),
            _integer(
                "vsc.error_passive_ms",
                table.get("error_passive_ms", MISSING),
                DEFAULT_CAN_ERROR_PASSIVE_MS,
                CAN_ERROR_PASSIVE_RANGE_MS,
            ),
        )

    # [[clients]] --------------------------------------------------------------------------

    def clients(self, raw: object) -> tuple[ClientSpec, ...]:
        clients: list[ClientSpec] = []
        entries = _array_of_tables("clients", raw, 'name = "autonomy"')
        for i, table in enumerate(entries):
            prefix = f"clients[{i}]"
            _check_keys(prefix, table, CLIENT_KEYS)
            name = table.get("name", MISSING)
            if not isinstance(name, str) or CLIENT_NAME.fullmatch(name) is None:
                raise ConfigError(
                    f"{prefix}.name",
                    name,
                    "use 1 to 32 characters from letters, digits, '_', '.' and '-', "
                    'e.g. name = "autonomy"',
                )
            timeout = _integer_type(
                f"{prefix}.timeout_ms",
                table.get("timeout_ms", MISSING),
                DEFAULT_CLIENT_TIMEOUT_MS,
                CLIENT_TIMEOUT_RANGE_MS,
            )
            for j, earlier in enumerate(clients):
                if earlier.name == name:
                    raise ConfigError(
                        f"{prefix}.name", name, f"rename it: clients[{j}] has the same name"
                    )
            uid = self.client_user(prefix, table)
            try:
                clients.append(ClientSpec(name, timeout, uid))
            except ConfigError as error:  # its keys are clients.name, clients.NAME.timeout_ms
                field = error.key.rsplit(".", 1)[-1]
                raise ConfigError(f"{prefix}.{field}", error.value, error.fix) from None
        return tuple(clients)

    @staticmethod
    def client_user(prefix: str, table: Mapping[str, object]) -> int | None:
        """The uid a client is bound to (``user`` by name or ``uid`` by number), or ``None``:
        unbound, any user who can reach the socket may say hello under the name
        (docs/safety.md "Clients bound to a user")."""
        user, uid = table.get("user", MISSING), table.get("uid", MISSING)
        if user is not MISSING and uid is not MISSING:
            raise ConfigError(f"{prefix}.uid", uid, "give user or uid, not both")
        if uid is not MISSING:
            return _integer(f"{prefix}.uid", uid, 0, UID_RANGE)
        if user is MISSING:
            return None
        if not isinstance(user, str) or USER_NAME.fullmatch(user) is None:
            raise ConfigError(
                f"{prefix}.user", user, 'give a user name in double quotes, e.g. "robot"'
            )
        try:
            return pwd.getpwnam(user).pw_uid
        except KeyError:
            raise ConfigError(
                f"{prefix}.user",
                user,
                f"no such user on this machine: create it (useradd --system {user}) or name "
                "the user the client runs as",
            ) from None

    # [[outputs]] --------------------------------------------------------------------------

    def outputs(self, raw: object) -> tuple[OutputSpec, ...]:
        example = 'name = "drive", kind = "gpio", role = "motion", ...'
        if isinstance(raw, dict) and all(isinstance(v, dict) for v in raw.values()) and raw:
            first = next(iter(raw))
            raise ConfigError(
                f"outputs.{first}",
                raw[first],
                f'write [[outputs]] with name = "{first}" instead of [outputs.{first}]',
            )
        entries = _array_of_tables("outputs", raw, example)
        if not entries:
            raise ConfigError(
                "outputs",
                MISSING,
                "add at least one [[outputs]] table: without an enable line to gate, the "
                "supervisor holds nothing",
            )
        specs = [self.output(i, table) for i, table in enumerate(entries)]
        _check_output_cross(specs)
        return tuple(specs)

    def output(self, i: int, table: Mapping[str, object]) -> OutputSpec:
        prefix = f"outputs[{i}]"
        name = table.get("name", MISSING)
        if not isinstance(name, str) or OUTPUT_NAME.fullmatch(name) is None:
            raise ConfigError(
                f"{prefix}.name",
                name,
                "use 1 to 32 characters from letters, digits, '_' and '-', e.g. name = \"drive\"",
            )
        kind = table.get("kind", MISSING)
        kinds = ", ".join(f'"{k.value}"' for k in OutputKind)
        if not isinstance(kind, str) or kind not in {k.value for k in OutputKind}:
            raise ConfigError(f"{prefix}.kind", kind, f"use one of {kinds}")
        options = [f.name for f in dataclasses.fields(spec_class(kind))]
        _check_keys(prefix, table, ["name", "kind", *(o for o in options if o != "name")])
        spec = parse_output_spec(name, {k: v for k, v in table.items() if k != "name"}, prefix)
        if spec.kind is OutputKind.SIM:
            spec = self.resolve_sim_path(spec)
        return spec

    def resolve_sim_path(self, spec: OutputSpec) -> OutputSpec:
        # Imported only when a config names a sim output, as the registry does.
        from supervisord.outputs.sim import SimSpec  # noqa: PLC0415

        if isinstance(spec, SimSpec) and spec.path is not None and not spec.path.is_absolute():
            return dataclasses.replace(spec, path=self.base / spec.path)
        return spec

    def output_bus(
        self, raw: object, vsc: VscConfig, outputs: Sequence[OutputSpec]
    ) -> CanBus | None:
        can_outputs = [i for i, spec in enumerate(outputs) if spec.kind is OutputKind.CAN]
        if raw is MISSING:
            if can_outputs and vsc.transport is not Transport.CAN:
                raise ConfigError(
                    f"outputs[{can_outputs[0]}].kind",
                    "can",
                    "add an [output_bus] section (interface, channel, bitrate) for the enable "
                    'frames: only a VSC on transport = "can" lends its bus to CAN outputs',
                )
            return None
        table = _table("output_bus", raw)
        _check_keys("output_bus", table, CAN_BUS_KEYS)
        bus = self.can_bus("output_bus", table)
        if not can_outputs:
            raise ConfigError("output_bus", dict(table), 'remove it: no output has kind = "can"')
        if isinstance(vsc.link, CanBus) and (vsc.link.interface, vsc.link.channel) == (
            bus.interface,
            bus.channel,
        ):
            raise ConfigError(
                "output_bus.channel",
                bus.channel,
                "remove [output_bus]: CAN outputs already send on the VSC's bus; give "
                "[output_bus] only for a second CAN network",
            )
        return bus

    # SafetyConfig -------------------------------------------------------------------------

    def safety(
        self,
        vsc: VscConfig,
        vsc_table: Mapping[str, object],
        rearm: Mapping[str, object],
        clients: tuple[ClientSpec, ...],
        outputs: Sequence[OutputSpec],
    ) -> SafetyConfig:
        timeout_raw = vsc_table.get("timeout_ms", MISSING)
        timeout = (
            None
            if timeout_raw is MISSING
            else _integer_type("vsc.timeout_ms", timeout_raw, 0, VSC_TIMEOUT_RANGE_MS)
        )
        if not any(spec.role is OutputRole.MOTION for spec in outputs):
            raise ConfigError(
                "outputs",
                [f"{spec.name}: {spec.role.value}" for spec in outputs],
                'give at least one output role = "motion": otherwise a hold (pause, menu, '
                "a client's hold) leaves motion enabled",
            )
        require_watchdog = _flag(
            "vsc.require_watchdog", vsc_table.get("require_watchdog", MISSING), True
        )
        prooftest = self.prooftest(vsc.transport, require_watchdog, vsc_table)
        try:
            return SafetyConfig(
                transport=vsc.transport,
                vsc_timeout_ms=timeout,
                heartbeat_hz=_integer_type(
                    "vsc.heartbeat_hz",
                    vsc_table.get("heartbeat_hz", MISSING),
                    20,
                    HEARTBEAT_HZ_RANGE,
                ),
                rearm_hold_ms=_integer_type(
                    "rearm.hold_ms", rearm.get("hold_ms", MISSING), 500, REARM_HOLD_RANGE_MS
                ),
                local_reset=_flag("rearm.local_reset", rearm.get("local_reset", MISSING), False),
                require_watchdog=require_watchdog,
                prooftest=prooftest,
                prooftest_clear_ms=_integer_type(
                    "vsc.prooftest_clear_ms",
                    vsc_table.get("prooftest_clear_ms", MISSING),
                    DEFAULT_PROOFTEST_CLEAR_MS,
                    PROOFTEST_CLEAR_RANGE_MS,
                ),
                clients=clients,
                outputs=tuple(SafetyOutputSpec(spec.name, spec.role) for spec in outputs),
            )
        except ConfigError as error:
            key = _SAFETY_KEYS.get(error.key, error.key)
            raise ConfigError(key, error.value, error.fix) from None

    @staticmethod
    def prooftest(
        transport: Transport, require_watchdog: bool, vsc_table: Mapping[str, object]
    ) -> ProofTestPolicy:
        """``vsc.prooftest`` (docs/safety.md "The proof test", SR-5.3). The default: ``block``
        on serial when the watchdog is required, ``record`` on serial when it is not (then a
        VSC with key 85 off is recorded at every start, and runs), ``off`` on CAN and HID,
        which have no user heartbeat to withhold."""
        if transport is not Transport.SERIAL:
            default = ProofTestPolicy.OFF
        else:
            default = ProofTestPolicy.BLOCK if require_watchdog else ProofTestPolicy.RECORD
        raw = vsc_table.get("prooftest", MISSING)
        if raw is MISSING:
            return default
        try:
            return ProofTestPolicy(raw)
        except ValueError:
            raise ConfigError(
                "vsc.prooftest", raw, 'use "block", "record" or "off" (docs/safety.md)'
            ) from None

    # [record], [api] ----------------------------------------------------------------------

    def record(self, table: Mapping[str, object]) -> RecordConfig:
        _check_keys("record", table, RECORD_KEYS)
        return RecordConfig(
            path=_path(
                "record.path",
                table.get("path", MISSING),
                DEFAULT_RECORD_PATH,
                self.base,
                f'"{DEFAULT_RECORD_PATH}"',
            ),
            max_bytes=_integer(
                "record.max_bytes",
                table.get("max_bytes", MISSING),
                DEFAULT_MAX_BYTES,
                MAX_BYTES_RANGE,
            ),
            keep=_integer("record.keep", table.get("keep", MISSING), DEFAULT_KEEP, KEEP_RANGE),
            journal=_flag("record.journal", table.get("journal", MISSING), True),
        )

    def _group(self, key: str, group: object, example: str) -> str | None:
        if group is MISSING:
            return None
        if not isinstance(group, str) or GROUP_NAME.fullmatch(group) is None:
            raise ConfigError(key, group, f'give a group name in double quotes, e.g. "{example}"')
        if not self.group_exists(group):
            raise ConfigError(
                key,
                group,
                f"no such group on this machine: create it (groupadd --system {group}) and "
                "add the users to it, or name an existing group",
            )
        return group

    def api(self, table: Mapping[str, object], required_clients: int) -> ApiConfig:
        _check_keys("api", table, API_KEYS)
        socket = _path(
            "api.socket",
            table.get("socket", MISSING),
            DEFAULT_SOCKET,
            self.base,
            f'"{DEFAULT_SOCKET}"',
        )
        if len(str(socket).encode()) > SOCKET_PATH_MAX_BYTES:
            raise ConfigError(
                "api.socket",
                str(socket),
                f"use a path of at most {SOCKET_PATH_MAX_BYTES} bytes (the limit of a Unix "
                f'socket address), e.g. "{DEFAULT_SOCKET}"',
            )
        group = self._group("api.group", table.get("group", MISSING), "srcs")
        admin_group = self._group(
            "api.admin_group", table.get("admin_group", MISSING), "srcs-admin"
        )
        max_clients = _integer(
            "api.max_clients",
            table.get("max_clients", MISSING),
            DEFAULT_MAX_CLIENTS,
            MAX_CLIENTS_RANGE,
        )
        if max_clients < required_clients + 1:
            raise ConfigError(
                "api.max_clients",
                max_clients,
                f"raise it to at least {required_clients + 1}: the {required_clients} required "
                "clients and one srcsctl must fit",
            )
        return ApiConfig(
            socket=socket,
            group=group,
            admin_group=admin_group,
            max_clients=max_clients,
            max_message_bytes=_integer(
                "api.max_message_bytes",
                table.get("max_message_bytes", MISSING),
                DEFAULT_MAX_MESSAGE_BYTES,
                MAX_MESSAGE_BYTES_RANGE,
            ),
        )


def _check_output_cross(specs: Sequence[OutputSpec]) -> None:
    """Names are unique, and no two outputs drive the same line, file or CAN identifier."""
    seen: dict[object, int] = {}
    for j, spec in enumerate(specs):
        claims: list[tuple[object, str, object, str]] = [
            (("name", spec.name), "name", spec.name, "rename it")
        ]
        claims += _device_claims(spec)
        for claim, field, value, fix in claims:
            i = seen.setdefault(claim, j)
            if i != j:
                raise ConfigError(
                    f"outputs[{j}].{field}", value, f"{fix}: outputs[{i}] ({specs[i].name}) has it"
                )


def _device_claims(spec: OutputSpec) -> list[tuple[object, str, object, str]]:
    """What a spec holds exclusively: a GPIO line, a CAN identifier. (Its file, for a sim
    output, is one of the paths :func:`_check_path_owners` compares across all sections.)"""
    chip, line = getattr(spec, "chip", None), getattr(spec, "line", None)
    if spec.kind is OutputKind.GPIO and isinstance(chip, str):
        claim = ("gpio", _chip_identity(chip), line)
        return [(claim, "line", line, "give each output its own line")]
    if spec.kind is OutputKind.CAN:
        ident = (getattr(spec, "arbitration_id", None), getattr(spec, "extended", None))
        return [(("can", ident), "arbitration_id", ident[0], "give each output its own id")]
    return []


def _chip_identity(chip: str) -> tuple[str, str]:
    """What the config alone can tell of a GPIO chip (docs/configuration.md "One owner per
    path"): a device path, with symlinks resolved, and a kernel name (``gpiochip2``) are the
    same device (``/dev/gpiochip2``); a label is only known to the hardware, so it stays a
    label, and a line named by name is only known to the chip, so it stays a name."""
    if "/" in chip:
        return ("device", os.path.realpath(chip))
    if KERNEL_CHIP_NAME.fullmatch(chip):
        return ("device", os.path.realpath(f"/dev/{chip}"))
    return ("label", chip)


def _path_claims(
    vsc: VscConfig, outputs: Sequence[OutputSpec], record: RecordConfig, api: ApiConfig
) -> list[tuple[str, str, Path, str]]:
    """(key, value as written, file, what of the owner) for every file the config names, in
    the order of the file's sections; the record claims its rotated files too."""
    claims: list[tuple[str, str, Path, str]] = []
    link = vsc.link
    if isinstance(link, SerialLink):
        claims.append(("vsc.port", str(link.port), link.port, ""))
    elif isinstance(link, HidLink):
        claims.append(("vsc.hidraw", str(link.hidraw), link.hidraw, ""))
    for i, spec in enumerate(outputs):
        path = getattr(spec, "path", None)
        if spec.kind is OutputKind.SIM and isinstance(path, Path):
            claims.append((f"outputs[{i}].path", str(path), path, ""))
    claims.append(("record.path", str(record.path), record.path, ""))
    claims += [
        ("record.path", str(record.path), rotated(record.path, n), f"rotated file {n}")
        for n in range(1, record.keep + 1)
    ]
    claims.append(("api.socket", str(api.socket), api.socket, ""))
    return claims


def _check_path_owners(
    vsc: VscConfig, outputs: Sequence[OutputSpec], record: RecordConfig, api: ApiConfig
) -> None:
    """Every file has one owner (issue 11; docs/configuration.md "One owner per path"): two
    keys that name one file once relative paths and symlinks are resolved would destroy each
    other's file (an output's write replacing the record, the socket's start removing an
    output). The later key is refused, naming the earlier one."""
    seen: dict[str, tuple[str, str, str]] = {}
    for key, value, path, part in _path_claims(vsc, outputs, record, api):
        resolved = os.path.realpath(path)
        first = seen.setdefault(resolved, (key, value, part))
        if first == (key, value, part):
            continue
        other_key, other_value, other_part = first
        mine = f"its {part}" if part else "it"
        other = f"{other_key} = {other_value!r}" + (f" (its {other_part})" if other_part else "")
        raise ConfigError(
            key,
            value,
            f"give it its own file: {mine} and {other} are one file once relative paths and "
            "symlinks are resolved (every path in the config has one owner)",
        )
