"""The safety core's configuration as frozen values that validate themselves.

Every value the requirements (``docs/requirements.md``) leave to the robot's configuration
arrives here, typed and checked once. A wrong value raises
:class:`~supervisord.errors.ConfigError` naming the key, the value and the fix; the daemon
prints it and refuses to start. The core itself never sees an unchecked value.
"""

from __future__ import annotations

import enum
import re
from dataclasses import dataclass
from typing import Final

from supervisord import strict
from supervisord.compat import StrEnum
from supervisord.errors import ConfigError
from supervisord.safety.availability import (
    DEFAULT_MIN_REMOTE_BATTERY,
    MIN_REMOTE_BATTERY_RANGE,
    Reaction,
)
from supervisord.safety.prooftest import ProofTestPolicy
from supervisord.timebase import NS_PER_MS, NS_PER_S

NAME_PATTERN = re.compile(r"[A-Za-z0-9_.-]{1,32}")
"""Client and output names: they become part of cause names such as ``client_lost:NAME``."""
NAME = strict.Text(
    name="name",
    doc="A client's or output's name: it becomes part of cause names such as client_lost:NAME.",
    pattern=NAME_PATTERN.pattern,
    rule="1 to 32 characters from letters, digits, '_', '.' and '-'",
    example="autonomy",
)
"""The same rule as a :class:`~supervisord.strict.Text` key, for the strict reader."""


class Transport(enum.Enum):
    """How the VSC is connected (PR-1, PR-3, PR-4)."""

    SERIAL = "serial"  # HRI packets over USB CDC or RS-232: user heartbeat and key 85 exist
    CAN = "can"  # J1939 frames: no user heartbeat, no key 85 (PR-3)
    HID = "hid"  # USB game controller: never a safety channel (PR-4)


class OutputRole(StrEnum):
    """What an output enables (SR-1.2; the config file spells it ``role``)."""

    MOTION = "motion"  # on only in RUN
    POWER = "power"  # on in HOLD and RUN


_TRANSPORTS = ", ".join(f'"{t.value}"' for t in Transport)
OFF_DELAY_RANGE_MS = (0, 5000)
"""SR-1.4: a category-1 output's delay. The bound keeps a slip of the pen (8000 for 800) from
leaving power on for seconds after a stop; drives brake well within it (docs/outputs.md "Stop
categories")."""
_ROLES = ", ".join(f'"{role.value}"' for role in OutputRole)
_POLICIES = ", ".join(f'"{p.value}"' for p in ProofTestPolicy)
_REACTIONS = ", ".join(f'"{r.value}"' for r in Reaction)

DEFAULT_VSC_TIMEOUT_MS = {Transport.SERIAL: 200, Transport.CAN: 300, Transport.HID: 200}
"""SR-2.2 ``vsc_link_lost``: 200 ms on serial, 300 ms on CAN."""

HEARTBEAT_HZ_RANGE = (20, 50)  # SR-5
REARM_HOLD_RANGE_MS = (100, 60_000)
CLIENT_TIMEOUT_RANGE_MS = (20, 10_000)
PROOFTEST_CLEAR_RANGE_MS = (1_000, 600_000)
DEFAULT_PROOFTEST_CLEAR_MS = 10_000  # docs/safety.md "The proof test": a held bit's wait
DEFAULT_CLIENT_TIMEOUT_MS = 500  # SR-8
DEFAULT_REARM_HOLD_MS: Final = 500  # rearm.hold_ms (SR-4.1)
UID_RANGE = (0, (1 << 32) - 2)  # (uid_t) -1 means "no user" to the kernel
CONSOLE_TIMEOUT_RANGE_MS = (200, 60_000)  # SR-8.21: a fleet console's keepalive deadline
DEFAULT_CONSOLE_TIMEOUT_MS = 3_000  # SR-8.21: a third of it is the console's keepalive period

VSC_TIMEOUT_MS: Final = strict.Whole(
    name="timeout_ms",
    doc="No valid VSC message for this long: stop with vsc_link_lost (SR-2.2). "
    "Default: 200 on serial and HID, 300 on CAN.",
    default=None,
    example=200,
    low=50,
    high=1000,
)
"""``vsc.timeout_ms``: the one rule, which the robot's file is read by (its schema lists this
key) and :class:`SafetyConfig` checks ``vsc_timeout_ms`` by. ``None``: the transport's default."""


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
    ``None``, the default, lets any user who can reach the socket. With ``progress``, every
    heartbeat must carry a new progress value (SR-8.16); one that does not keeps no deadline.
    """

    name: str
    timeout_ms: int = DEFAULT_CLIENT_TIMEOUT_MS
    uid: int | None = None
    progress: bool = False

    def __post_init__(self) -> None:
        strict.name("clients.name", self.name, NAME, ConfigError)
        strict.whole(
            f"clients.{self.name}.timeout_ms",
            self.timeout_ms,
            *CLIENT_TIMEOUT_RANGE_MS,
            ConfigError,
        )
        if self.uid is not None:
            strict.whole(f"clients.{self.name}.uid", self.uid, *UID_RANGE, ConfigError)
        if type(self.progress) is not bool:
            raise ConfigError(f"clients.{self.name}.progress must be true or false")

    @property
    def timeout_ns(self) -> int:
        return self.timeout_ms * NS_PER_MS


@dataclass(frozen=True, slots=True)
class FleetSpec:
    """The fleet's per-robot agent and console (SR-8.19 to SR-8.21; docs/safety.md "The fleet
    stop"). ``agent_uids``: the only users whose connections may send ``fleet_stop``,
    ``fleet_release`` and ``fleet_keepalive`` (the file names one, ``agent_user`` or
    ``agent_uid``; empty, the default: nobody, the fleet ops are refused).
    ``console_required``: the console is a required stop source; no keepalive for
    ``console_timeout_ms`` raises ``fleet_console_lost``, a stop."""

    agent_uids: frozenset[int] = frozenset()
    console_required: bool = False
    console_timeout_ms: int = DEFAULT_CONSOLE_TIMEOUT_MS

    def __post_init__(self) -> None:
        if not isinstance(self.agent_uids, frozenset):
            raise ConfigError("fleet.agent_uid", self.agent_uids, "give the agent's user")
        for uid in self.agent_uids:
            strict.whole("fleet.agent_uid", uid, *UID_RANGE, ConfigError)
        strict.flag("fleet.console_required", self.console_required, ConfigError)
        strict.whole(
            "fleet.console_timeout_ms",
            self.console_timeout_ms,
            *CONSOLE_TIMEOUT_RANGE_MS,
            ConfigError,
        )
        if self.console_required and not self.agent_uids:
            raise ConfigError(
                "fleet.console_required",
                True,
                "name the agent's user in fleet.agent_user: without one no keepalive can "
                "arrive, and the robot would never leave STOPPED",
            )

    @property
    def console_timeout_ns(self) -> int:
        return self.console_timeout_ms * NS_PER_MS


@dataclass(frozen=True)
class OutputSpec:
    """An enable line the supervisor gates, and its role (SR-1, SR-6): all the safety core
    knows of an output. Each output kind's spec (``supervisord.outputs``) is an
    ``OutputSpec`` with the kind's own options, so the daemon hands the same values to the
    core and to the outputs."""

    name: str
    role: OutputRole = OutputRole.MOTION
    off_delay_ms: int = 0
    """A ``power`` output's stop category (SR-1.4): 0 switches it off at once with every stop
    (category 0); more keeps it on that long after the ``motion`` outputs went off, so that
    drives can brake under power (category 1)."""

    def __post_init__(self) -> None:
        strict.name("outputs.name", self.name, NAME, ConfigError)
        if not isinstance(self.role, OutputRole):
            raise ConfigError(f"outputs.{self.name}.role", self.role, f"use one of {_ROLES}")
        key = f"outputs.{self.name}.off_delay_ms"
        strict.whole(key, self.off_delay_ms, *OFF_DELAY_RANGE_MS, ConfigError)
        if self.off_delay_ms and self.role is OutputRole.MOTION:
            raise ConfigError(
                key,
                self.off_delay_ms,
                'remove it, or give the output role = "power": a motion output is the enable '
                "that stops the drives, and goes off at once (SR-1.4)",
            )

    @property
    def off_delay_ns(self) -> int:
        return self.off_delay_ms * NS_PER_MS


@dataclass(frozen=True, slots=True)
class SafetyConfig:
    """Everything the safety core needs to know about the robot (SR-2 to SR-5, SR-8).

    ``vsc_timeout_ms`` is ``vsc.timeout_ms``; left as ``None`` it is the transport's default
    (200 ms serial, 300 ms CAN), and ``vsc_timeout_ns`` is the timeout in effect. A
    CAN-connected VSC has no user watchdog, so
    ``require_watchdog`` must be set to false explicitly there: the integrator has to
    acknowledge that the supervisor's own outputs carry the duty alone (SR-5).

    ``prooftest`` (docs/safety.md "The proof test", SR-5.3) is ``OFF`` unless given: the
    robot's file sets it (``vsc.prooftest``, default ``block`` on serial, see
    ``supervisord.config``); a core built in code for tests of other rules runs none. On CAN
    and HID only ``OFF`` is accepted: there is no user heartbeat to withhold.

    ``min_remote_battery`` and ``on_estop_unavailable`` (SR-8.11, SR-8.12): the remote's
    battery below that percent, or not reported, is warned of, or holds or stops the robot.

    Every error names the key as the robot's file spells it (``vsc.timeout_ms``,
    ``rearm.hold_ms``), for a config read from the file as for one built in code.
    """

    transport: Transport = Transport.SERIAL
    vsc_timeout_ms: int | None = None
    heartbeat_hz: int = 20
    rearm_hold_ms: int = DEFAULT_REARM_HOLD_MS
    local_reset: bool = False
    require_watchdog: bool = True
    clients: tuple[ClientSpec, ...] = ()
    outputs: tuple[OutputSpec, ...] = ()
    prooftest: ProofTestPolicy = ProofTestPolicy.OFF
    prooftest_clear_ms: int = DEFAULT_PROOFTEST_CLEAR_MS
    min_remote_battery: int = DEFAULT_MIN_REMOTE_BATTERY
    on_estop_unavailable: Reaction = Reaction.WARN
    fleet: FleetSpec = FleetSpec()

    def __post_init__(self) -> None:
        if not isinstance(self.transport, Transport):
            raise ConfigError("vsc.transport", self.transport, f"use one of {_TRANSPORTS}")
        # The ranges are the schema's own (supervisord.config.schema names the same rules), so
        # a config built in code is held to what the robot's file is.
        if self.vsc_timeout_ms is not None:
            strict.check_value(VSC_TIMEOUT_MS, self.vsc_timeout_ms, "vsc.timeout_ms", ConfigError)
        strict.whole("vsc.heartbeat_hz", self.heartbeat_hz, *HEARTBEAT_HZ_RANGE, ConfigError)
        strict.whole("rearm.hold_ms", self.rearm_hold_ms, *REARM_HOLD_RANGE_MS, ConfigError)
        strict.flag("rearm.local_reset", self.local_reset, ConfigError)
        strict.flag("vsc.require_watchdog", self.require_watchdog, ConfigError)
        if self.transport is Transport.CAN and self.require_watchdog:
            raise ConfigError(
                "vsc.require_watchdog",
                True,
                'set it to false for transport "can": a CAN-connected VSC has no user '
                "heartbeat and no key 85, so the supervisor's outputs carry the duty alone",
            )
        if not isinstance(self.prooftest, ProofTestPolicy):
            raise ConfigError("vsc.prooftest", self.prooftest, f"use one of {_POLICIES}")
        if self.transport is not Transport.SERIAL and self.prooftest is not ProofTestPolicy.OFF:
            raise ConfigError(
                "vsc.prooftest",
                self.prooftest.value,
                f'set it to "off" for transport "{self.transport.value}": there is no user '
                "heartbeat to withhold, so the VSC's watchdog cannot be proven",
            )
        strict.whole(
            "vsc.prooftest_clear_ms",
            self.prooftest_clear_ms,
            *PROOFTEST_CLEAR_RANGE_MS,
            ConfigError,
        )
        strict.whole(
            "vsc.min_remote_battery",
            self.min_remote_battery,
            *MIN_REMOTE_BATTERY_RANGE,
            ConfigError,
        )
        if not isinstance(self.on_estop_unavailable, Reaction):
            raise ConfigError(
                "vsc.on_estop_unavailable", self.on_estop_unavailable, f"use one of {_REACTIONS}"
            )
        if not isinstance(self.clients, tuple) or not all(
            isinstance(c, ClientSpec) for c in self.clients
        ):
            raise ConfigError("clients", self.clients, "give a list of client tables")
        if not isinstance(self.outputs, tuple) or not all(
            isinstance(o, OutputSpec) for o in self.outputs
        ):
            raise ConfigError("outputs", self.outputs, "give a list of output tables")
        if not isinstance(self.fleet, FleetSpec):
            raise ConfigError("fleet", self.fleet, "give a [fleet] table")
        _unique("clients.name", [c.name for c in self.clients])
        _unique("outputs.name", [o.name for o in self.outputs])

    @property
    def vsc_timeout_ns(self) -> int:
        """The VSC timeout in effect: ``vsc_timeout_ms``, or the transport's default.

        The default is resolved here rather than stored, so that ``dataclasses.replace`` with
        another transport picks that transport's default.
        """
        timeout_ms = self.vsc_timeout_ms
        if timeout_ms is None:
            timeout_ms = DEFAULT_VSC_TIMEOUT_MS[self.transport]
        return timeout_ms * NS_PER_MS

    @property
    def heartbeat_period_ns(self) -> int:
        return NS_PER_S // self.heartbeat_hz

    @property
    def rearm_hold_ns(self) -> int:
        return self.rearm_hold_ms * NS_PER_MS

    @property
    def prooftest_clear_ns(self) -> int:
        return self.prooftest_clear_ms * NS_PER_MS
