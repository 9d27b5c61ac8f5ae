"""The safety core's configuration as frozen values that validate themselves.

Every value the requirements (``docs/requirements.md``) leave to the robot's configuration
arrives here, typed and checked once. A wrong value raises
:class:`~supervisord.errors.ConfigError` naming the key, the value and the fix; the daemon
prints it and refuses to start. The core itself never sees an unchecked value.
"""

from __future__ import annotations

import enum
import re
from collections.abc import Mapping
from dataclasses import dataclass

from supervisord.compat import StrEnum
from supervisord.errors import ConfigError
from supervisord.safety.prooftest import ProofTestPolicy

NS_PER_MS = 1_000_000

NAME_PATTERN = re.compile(r"[A-Za-z0-9_.-]{1,32}")
"""Client and output names: they become part of cause names such as ``client_lost:NAME``."""


class Transport(enum.Enum):
    """How the VSC is connected (PR-1, PR-3, PR-4)."""

    SERIAL = "serial"  # HRI packets over USB CDC or RS-232: user heartbeat and key 85 exist
    CAN = "can"  # J1939 frames: no user heartbeat, no key 85 (PR-3)
    HID = "hid"  # USB game controller: never a safety channel (PR-4)


class OutputRole(StrEnum):
    """What an output enables (SR-1.2; the config file spells it ``role``)."""

    MOTION = "motion"  # on only in RUN
    POWER = "power"  # on in HOLD and RUN


DEFAULT_VSC_TIMEOUT_MS = {Transport.SERIAL: 200, Transport.CAN: 300, Transport.HID: 200}
"""SR-2.2 ``vsc_link_lost``: 200 ms on serial, 300 ms on CAN."""

VSC_TIMEOUT_RANGE_MS = (50, 1000)
HEARTBEAT_HZ_RANGE = (20, 50)  # SR-5
REARM_HOLD_RANGE_MS = (100, 60_000)
CLIENT_TIMEOUT_RANGE_MS = (20, 10_000)
PROOFTEST_CLEAR_RANGE_MS = (1_000, 600_000)
DEFAULT_PROOFTEST_CLEAR_MS = 10_000  # docs/safety.md "The proof test": a held bit's wait
DEFAULT_CLIENT_TIMEOUT_MS = 500  # SR-8
UID_RANGE = (0, (1 << 32) - 2)  # (uid_t) -1 means "no user" to the kernel


def _whole_number(key: str, value: object, bounds: tuple[int, int]) -> int:
    low, high = bounds
    if isinstance(value, bool) or not isinstance(value, int) or not low <= value <= high:
        raise ConfigError(key, value, f"use a whole number from {low} to {high}")
    return value


def _flag(key: str, value: object) -> bool:
    if not isinstance(value, bool):
        raise ConfigError(key, value, "use true or false")
    return value


def _name(key: str, value: object) -> str:
    if not isinstance(value, str) or NAME_PATTERN.fullmatch(value) is None:
        raise ConfigError(
            key, value, "use 1 to 32 characters from letters, digits, '_', '.' and '-'"
        )
    return value


def _unique(key: str, names: list[str]) -> None:
    seen: set[str] = set()
    for name in names:
        if name in seen:
            raise ConfigError(key, name, "give every entry its own name")
        seen.add(name)


@dataclass(frozen=True, slots=True)
class ClientSpec:
    """A required client of the robot's software (SR-8).

    Until it has connected, said hello and sent a heartbeat, and whenever it stays silent for
    ``timeout_ms``, the cause ``client_lost:NAME`` is active. With ``uid``, only a process of
    that user may say hello under the name (docs/safety.md "Clients bound to a user");
    ``None``, the default, lets any user who can reach the socket.
    """

    name: str
    timeout_ms: int = DEFAULT_CLIENT_TIMEOUT_MS
    uid: int | None = None

    def __post_init__(self) -> None:
        _name("clients.name", self.name)
        _whole_number(f"clients.{self.name}.timeout_ms", self.timeout_ms, CLIENT_TIMEOUT_RANGE_MS)
        if self.uid is not None:
            _whole_number(f"clients.{self.name}.uid", self.uid, UID_RANGE)

    @property
    def timeout_ns(self) -> int:
        return self.timeout_ms * NS_PER_MS


@dataclass(frozen=True, slots=True)
class OutputSpec:
    """An enable line the supervisor gates, and its role (SR-1, SR-6)."""

    name: str
    role: OutputRole

    def __post_init__(self) -> None:
        _name("outputs.name", self.name)
        if not isinstance(self.role, OutputRole):
            raise ConfigError(f"outputs.{self.name}.role", self.role, 'use "motion" or "power"')


@dataclass(frozen=True, slots=True)
class SafetyConfig:
    """Everything the safety core needs to know about the robot (SR-2 to SR-5, SR-8).

    ``vsc_timeout_ms`` left as ``None`` takes the transport's default (200 ms serial, 300 ms
    CAN; see ``effective_vsc_timeout_ms``). A CAN-connected VSC has no user watchdog, so
    ``require_watchdog`` must be set to false explicitly there: the integrator has to
    acknowledge that the supervisor's own outputs carry the duty alone (SR-5).

    ``prooftest`` (docs/safety.md "The proof test", SR-5.3) is ``OFF`` unless given: the
    robot's file sets it (``vsc.prooftest``, default ``block`` on serial, see
    ``supervisord.config``); a core built in code for tests of other rules runs none. On CAN
    and HID only ``OFF`` is accepted: there is no user heartbeat to withhold.
    """

    transport: Transport = Transport.SERIAL
    vsc_timeout_ms: int | None = None
    heartbeat_hz: int = 20
    rearm_hold_ms: int = 500
    local_reset: bool = False
    require_watchdog: bool = True
    clients: tuple[ClientSpec, ...] = ()
    outputs: tuple[OutputSpec, ...] = ()
    prooftest: ProofTestPolicy = ProofTestPolicy.OFF
    prooftest_clear_ms: int = DEFAULT_PROOFTEST_CLEAR_MS

    def __post_init__(self) -> None:
        if not isinstance(self.transport, Transport):
            raise ConfigError("transport", self.transport, 'use "serial", "can" or "hid"')
        _whole_number("vsc_timeout_ms", self.effective_vsc_timeout_ms, VSC_TIMEOUT_RANGE_MS)
        _whole_number("heartbeat_hz", self.heartbeat_hz, HEARTBEAT_HZ_RANGE)
        _whole_number("rearm_hold_ms", self.rearm_hold_ms, REARM_HOLD_RANGE_MS)
        _flag("local_reset", self.local_reset)
        _flag("require_watchdog", self.require_watchdog)
        if self.transport is Transport.CAN and self.require_watchdog:
            raise ConfigError(
                "require_watchdog",
                True,
                'set it to false for transport "can": a CAN-connected VSC has no user '
                "heartbeat and no key 85, so the supervisor's outputs carry the duty alone",
            )
        if not isinstance(self.prooftest, ProofTestPolicy):
            raise ConfigError("prooftest", self.prooftest, 'use "block", "record" or "off"')
        if self.transport is not Transport.SERIAL and self.prooftest is not ProofTestPolicy.OFF:
            raise ConfigError(
                "prooftest",
                self.prooftest.value,
                f'set it to "off" for transport "{self.transport.value}": there is no user '
                "heartbeat to withhold, so the VSC's watchdog cannot be proven",
            )
        _whole_number("prooftest_clear_ms", self.prooftest_clear_ms, PROOFTEST_CLEAR_RANGE_MS)
        if not isinstance(self.clients, tuple) or not all(
            isinstance(c, ClientSpec) for c in self.clients
        ):
            raise ConfigError("clients", self.clients, "give a list of client tables")
        if not isinstance(self.outputs, tuple) or not all(
            isinstance(o, OutputSpec) for o in self.outputs
        ):
            raise ConfigError("outputs", self.outputs, "give a list of output tables")
        _unique("clients.name", [c.name for c in self.clients])
        _unique("outputs.name", [o.name for o in self.outputs])

    @property
    def effective_vsc_timeout_ms(self) -> int:
        """``vsc_timeout_ms``, or the transport's default when it is left as ``None``.

        The default is resolved here rather than stored, so that ``dataclasses.replace`` with
        another transport picks that transport's default.
        """
        if self.vsc_timeout_ms is None:
            return DEFAULT_VSC_TIMEOUT_MS[self.transport]
        return self.vsc_timeout_ms

    @property
    def vsc_timeout_ns(self) -> int:
        return self.effective_vsc_timeout_ms * NS_PER_MS

    @property
    def heartbeat_period_ns(self) -> int:
        return 1_000_000_000 // self.heartbeat_hz

    @property
    def rearm_hold_ns(self) -> int:
        return self.rearm_hold_ms * NS_PER_MS

    @property
    def prooftest_clear_ns(self) -> int:
        return self.prooftest_clear_ms * NS_PER_MS

    @classmethod
    def from_mapping(cls, data: Mapping[str, object], file: str | None = None) -> SafetyConfig:
        """Build a config from parsed TOML-like data; unknown keys are errors, not ignored.

        ``clients`` is a list of tables with ``name`` and optional ``timeout_ms`` and ``uid``;
        ``outputs`` a list of tables with ``name`` and ``class`` ("motion" or "power").
        """
        try:
            return cls._from_mapping(data)
        except ConfigError as error:
            raise error.in_file(file) if file else error from None

    @classmethod
    def _from_mapping(cls, data: Mapping[str, object]) -> SafetyConfig:
        known = {
            "transport",
            "vsc_timeout_ms",
            "heartbeat_hz",
            "rearm_hold_ms",
            "local_reset",
            "require_watchdog",
            "clients",
            "outputs",
        }
        for key in data:
            if key not in known:
                raise ConfigError(key, data[key], f"remove it; known keys: {sorted(known)}")
        transport_text = data.get("transport", Transport.SERIAL.value)
        try:
            transport = Transport(transport_text)
        except ValueError:
            raise ConfigError("transport", transport_text, 'use "serial", "can" or "hid"') from None
        clients = []
        for entry in _list("clients", data.get("clients", [])):
            table = _table("clients", entry, {"name", "timeout_ms", "uid"})
            name = _name("clients.name", table.get("name"))
            timeout = _whole_number(
                f"clients.{name}.timeout_ms",
                table.get("timeout_ms", DEFAULT_CLIENT_TIMEOUT_MS),
                CLIENT_TIMEOUT_RANGE_MS,
            )
            uid = table.get("uid")
            if uid is not None:
                uid = _whole_number(f"clients.{name}.uid", uid, UID_RANGE)
            clients.append(ClientSpec(name, timeout, uid))
        outputs = []
        for entry in _list("outputs", data.get("outputs", [])):
            table = _table("outputs", entry, {"name", "role"})
            name = _name("outputs.name", table.get("name"))
            role_text = table.get("role")
            try:
                role = OutputRole(str(role_text))
            except ValueError:
                raise ConfigError(
                    f"outputs.{name}.role", role_text, 'use "motion" or "power"'
                ) from None
            outputs.append(OutputSpec(name, role))
        timeout_value = data.get("vsc_timeout_ms")
        return cls(
            transport=transport,
            vsc_timeout_ms=(
                None
                if timeout_value is None
                else _whole_number("vsc_timeout_ms", timeout_value, VSC_TIMEOUT_RANGE_MS)
            ),
            heartbeat_hz=_whole_number(
                "heartbeat_hz", data.get("heartbeat_hz", 20), HEARTBEAT_HZ_RANGE
            ),
            rearm_hold_ms=_whole_number(
                "rearm_hold_ms", data.get("rearm_hold_ms", 500), REARM_HOLD_RANGE_MS
            ),
            local_reset=_flag("local_reset", data.get("local_reset", False)),
            # The default stays true on every transport: a CAN config must say false itself.
            require_watchdog=_flag("require_watchdog", data.get("require_watchdog", True)),
            clients=tuple(clients),
            outputs=tuple(outputs),
        )


def _list(key: str, value: object) -> list[object]:
    if not isinstance(value, list | tuple):
        raise ConfigError(key, value, "give a list of tables")
    return list(value)


def _table(key: str, value: object, allowed: set[str]) -> dict[str, object]:
    if not isinstance(value, Mapping) or not all(isinstance(k, str) for k in value):
        raise ConfigError(key, value, f"give a table with keys {sorted(allowed)}")
    for k in value:
        if k not in allowed:
            raise ConfigError(f"{key}.{k}", value[k], f"remove it; known keys: {sorted(allowed)}")
    return {str(k): v for k, v in value.items()}
