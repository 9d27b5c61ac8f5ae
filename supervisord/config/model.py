"""The robot's configuration as frozen values: what :func:`~supervisord.config.load_config`
returns, and what the daemon is assembled from (``supervisord.daemon.assemble``)."""

from __future__ import annotations

import dataclasses
import json
from pathlib import Path

from supervisord.api.framing import operator_socket_path
from supervisord.api.server import DEFAULT_MAX_CLIENTS
from supervisord.config.paths import DEFAULT_RECORD_PATH, DEFAULT_SOCKET
from supervisord.config.periodic import DEFAULT_INTERVAL_DAYS
from supervisord.config.realtime import LockMode
from supervisord.config.schema import (
    DEFAULT_CAN_BITRATE,
    DEFAULT_CAN_CHANNEL,
    DEFAULT_CAN_ERROR_LIMIT,
    DEFAULT_CAN_ERROR_PASSIVE_MS,
    DEFAULT_CAN_ERROR_WINDOW_MS,
    DEFAULT_CAN_INTERFACE,
    DEFAULT_MAX_MESSAGE_BYTES,
    DEFAULT_REOPEN_MAX_MS,
    DEFAULT_REOPEN_MIN_MS,
    DEFAULT_SERIAL_PORT,
    SERIAL_BAUD,
)
from supervisord.outputs.base import DeviceSpec, OutputKind
from supervisord.record.jsonl import DEFAULT_FLIGHT_MAX_BYTES, DEFAULT_KEEP, DEFAULT_MAX_BYTES
from supervisord.safety.config import SafetyConfig, Transport
from supervisord.safety.prooftest import ProofTestPolicy


@dataclasses.dataclass(frozen=True, slots=True)
class RobotConfig:
    """``[robot]``: who this is (shown in ``--check-config`` and the logs)."""

    name: str


@dataclasses.dataclass(frozen=True, slots=True)
class SerialPort:
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
class HidDevice:
    """``[vsc]`` with ``transport = "hid"``: the VSC's hidraw device (never a safety channel)."""

    hidraw: Path


@dataclasses.dataclass(frozen=True, slots=True)
class Reopen:
    """How long the daemon waits before reopening a lost VSC link: ``min_ms`` after the first
    failure, doubling up to ``max_ms`` (the daemon's ``links.base.Backoff`` keeps the time)."""

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
    link: SerialPort | CanBus | HidDevice
    reopen: Reopen = Reopen()
    can_errors: CanErrors = CanErrors()
    """Used only on CAN (``[output_bus]`` errors are not read: it only sends)."""


@dataclasses.dataclass(frozen=True, slots=True)
class RecordConfig:
    """``[record]``: the record of stops (``docs/record.md``)."""

    path: Path = Path(DEFAULT_RECORD_PATH)
    max_bytes: int = DEFAULT_MAX_BYTES
    keep: int = DEFAULT_KEEP
    journal: bool = True
    flight_max_bytes: int = DEFAULT_FLIGHT_MAX_BYTES
    """The flight recorder's windows together, at most (SR-7.12)."""


@dataclasses.dataclass(frozen=True, slots=True)
class MaintenanceConfig:
    """``[maintenance]``: when the periodic tests are overdue (SR-12.2); 0: no schedule."""

    stoptest_interval_days: int = DEFAULT_INTERVAL_DAYS
    prooftest_interval_days: int = DEFAULT_INTERVAL_DAYS


@dataclasses.dataclass(frozen=True, slots=True)
class RealtimeConfig:
    """``[realtime]``: whether the start locks the daemon's memory (SR-9.6)."""

    lock_memory: LockMode = LockMode.ON


@dataclasses.dataclass(frozen=True, slots=True)
class ApiConfig:
    """``[api]``: the Unix socket the robot's software and ``srcsctl`` talk to.

    ``group`` owns the socket (mode 0660): the robot's programs must be in it to connect
    (``None``: the daemon's own group). ``admin_group`` ``None`` means no group: commands that
    can re-enable motion or write the VSC are then allowed only to root and to the daemon's
    own user. ``operator_socket`` is the operators' own socket (SR-8.14; ``None``: the one
    beside ``socket``, :func:`~supervisord.api.framing.operator_socket_path`), reachable by
    root and ``operator_group`` only (``None``: root and the daemon's user).
    """

    socket: Path = Path(DEFAULT_SOCKET)
    group: str | None = None
    admin_group: str | None = None
    max_clients: int = DEFAULT_MAX_CLIENTS
    max_message_bytes: int = DEFAULT_MAX_MESSAGE_BYTES
    operator_socket: Path | None = None
    operator_group: str | None = None

    def __post_init__(self) -> None:
        if self.operator_socket is None:
            object.__setattr__(self, "operator_socket", operator_socket_path(self.socket))

    @property
    def operator_path(self) -> Path:
        """The operator socket's path, named or derived (never ``None`` once built)."""
        assert self.operator_socket is not None
        return self.operator_socket


@dataclasses.dataclass(frozen=True, slots=True)
class DaemonConfig:
    """One robot's whole configuration, validated (build it with :func:`load_config`).

    ``outputs`` holds each output kind's own spec, in file order; ``safety.outputs`` the same
    specs (each is the core's ``OutputSpec``: a name and a role). ``output_bus`` is the
    ``[output_bus]`` section, if any; :attr:`can_output_bus` is the bus CAN outputs actually
    send on.
    """

    source: Path
    robot: RobotConfig
    vsc: VscConfig
    safety: SafetyConfig
    outputs: tuple[DeviceSpec, ...]
    output_bus: CanBus | None = None
    record: RecordConfig = RecordConfig()
    api: ApiConfig = ApiConfig()
    maintenance: MaintenanceConfig = MaintenanceConfig()
    realtime: RealtimeConfig = RealtimeConfig()

    @property
    def can_output_bus(self) -> CanBus | None:
        """The bus the ``kind = "can"`` outputs send on: ``[output_bus]`` when given, else the
        VSC's own bus when the VSC is on CAN, else ``None`` (then there are no CAN outputs)."""
        if self.output_bus is not None:
            return self.output_bus
        return self.vsc.link if isinstance(self.vsc.link, CanBus) else None

    def warnings(self) -> tuple[ConfigWarning, ...]:
        """What is valid but deserves a loud word at start and in ``--check-config``, each at
        the key it is about (so that ``--check-config`` gives its line)."""
        notes = []
        if self.vsc.transport is Transport.HID:
            notes.append(
                ConfigWarning(
                    "vsc.transport",
                    "hid",
                    "never a safety channel: the supervisor stays STOPPED and its outputs "
                    "stay off (docs/configuration.md, [vsc])",
                )
            )
        if self.vsc.transport is Transport.SERIAL and not self.safety.require_watchdog:
            notes.append(
                ConfigWarning(
                    "vsc.require_watchdog",
                    False,
                    "the VSC's own user watchdog (key 85) is not checked, so the VSC does not "
                    "stop when the supervisor falls silent",
                )
            )
        if self.vsc.transport is Transport.SERIAL and self.safety.prooftest is ProofTestPolicy.OFF:
            notes.append(
                ConfigWarning(
                    "vsc.prooftest",
                    "off",
                    "the VSC's watchdog is never seen to act, so a VSC that reads key 85 = 1 "
                    "but ignores a missing heartbeat goes unnoticed (docs/safety.md)",
                )
            )
        # An unbound required client (SR-8.6's hazard, docs/safety.md "Clients bound to a
        # user"): valid, as configurations written before the key must keep starting, but
        # said at every check and start.
        notes += [
            ConfigWarning(
                f"clients[{i}].user",
                None,
                f'unbound: any program that can reach the socket may say hello as "{client.name}" '
                "and keep it alive after it died: bind it to the user it runs as "
                '(user = "NAME", or uid = N)',
            )
            for i, client in enumerate(self.safety.clients)
            if client.uid is None
        ]
        notes += [
            ConfigWarning(
                f"outputs[{i}].kind", "sim", f"{spec.name} is simulated: it drives no hardware"
            )
            for i, spec in enumerate(self.outputs)
            if spec.kind is OutputKind.SIM
        ]
        return tuple(notes)


@dataclasses.dataclass(frozen=True, slots=True)
class ConfigWarning:
    """A warning of a valid config: the ``key`` it is about (a dotted path, as errors name
    keys), its ``value`` (``None``: not set) and what it means (``text``)."""

    key: str
    value: str | bool | None
    text: str

    def __str__(self) -> str:
        """``key = value: text``, the value as TOML writes it, as the daemon logs it."""
        if self.value is None:
            shown = "(not set)"
        elif isinstance(self.value, bool):
            shown = "true" if self.value else "false"
        else:
            shown = json.dumps(self.value)
        return f"{self.key} = {shown}: {self.text}"
