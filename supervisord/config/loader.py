"""The loader: the robot's TOML file, read with ``tomllib``, validated completely into a
:class:`~supervisord.config.model.DaemonConfig` (SR-11.2).

:func:`load_config` reads every key through its declaration in
:mod:`supervisord.config.schema` with the one strict reader (:mod:`supervisord.strict`), then
applies the rules between keys (:data:`~supervisord.config.schema.CROSS_CHECKS`): the
transport's own keys, the outputs' exclusive claims, path owners, groups and users that must
exist. It raises :class:`~supervisord.errors.ConfigError` naming the file, the key (a dotted
path such as ``vsc.timeout_ms`` or ``outputs[1].chip``), the value and the fix, for the first
mistake it meets; the daemon refuses to start. (``--check-config`` and the daemon's refusal
list every mistake at once: :mod:`supervisord.config.collect` runs this loader again past
each one.) Every section's own keys are read first, and the rules between entries and
sections (:func:`broken_rules`: one owner per device and per path, a motion output, the
output bus) only after all of them, so that a rule between sections never hides a mistake in
one key; ``every_rule`` hands every broken rule over at once (:class:`RulesBroken`) instead
of the first, so that ``--check-config`` lists them all (SR-11.2).

A key the schema does not declare is an error, never ignored: a misspelt safety option must not
silently fall back to its default. Relative paths are resolved against the config file's
directory (or ``base_dir``), so that a self-contained config such as the demo's works from any
working directory.
"""

from __future__ import annotations

import dataclasses
import grp
import os
import pwd
from collections.abc import Callable, Hashable, Iterator, Sequence
from pathlib import Path
from typing import Final

from supervisord import strict
from supervisord.config.model import (
    ApiConfig,
    CanBus,
    CanErrors,
    DaemonConfig,
    HidDevice,
    MaintenanceConfig,
    RecordConfig,
    Reopen,
    RobotConfig,
    SerialPort,
    VscConfig,
)
from supervisord.config.paths import (
    RECORD_FLIGHT_MAX_BYTES,
    RECORD_JOURNAL,
    RECORD_KEEP,
    RECORD_MAX_BYTES,
    RECORD_PATH,
    RENAMED,
    api_sockets,
    check_record_files,
    file_path,
)
from supervisord.config.schema import (
    API,
    BAUD,
    CAN_BITRATE,
    CAN_CHANNEL,
    CAN_INTERFACE,
    CLIENTS,
    ERROR_LIMIT,
    ERROR_PASSIVE,
    ERROR_WINDOW,
    FLEET,
    HEARTBEAT_HZ,
    HIDRAW,
    MAINTENANCE,
    MIN_REMOTE_BATTERY,
    ON_ESTOP_UNAVAILABLE,
    OUTPUT_NAME_KEY,
    PORT,
    PROOFTEST,
    PROOFTEST_CLEAR,
    REOPEN_MAX,
    REOPEN_MIN,
    REQUIRE_WATCHDOG,
    ROBOT_NAME,
    SECTION,
    SECTIONS,
    SERIAL_BAUD,
    TRANSPORT,
    VSC_BY_TRANSPORT,
    VSC_COMMON,
    Section,
)
from supervisord.config.toml_file import read_toml
from supervisord.errors import ConfigError
from supervisord.outputs.base import DeviceSpec, OutputKind
from supervisord.outputs.registry import KIND, option_names, read_spec
from supervisord.record.jsonl import record_paths
from supervisord.safety.availability import Reaction
from supervisord.safety.config import (
    VSC_TIMEOUT_MS,
    ClientSpec,
    FleetSpec,
    OutputRole,
    SafetyConfig,
    Transport,
)
from supervisord.safety.prooftest import ProofTestPolicy

# The keys of [[clients]], [record] and [api], by name (strict.named).
CLIENT_NAME: Final = strict.named(CLIENTS, "name", strict.Text)
CLIENT_TIMEOUT: Final = strict.named(CLIENTS, "timeout_ms", strict.Whole)
CLIENT_USER: Final = strict.named(CLIENTS, "user", strict.Text)
CLIENT_UID: Final = strict.named(CLIENTS, "uid", strict.Whole)
CLIENT_PROGRESS: Final = strict.named(CLIENTS, "progress", strict.Flag)
STOPTEST_INTERVAL: Final = strict.named(MAINTENANCE, "stoptest_interval_days", strict.Whole)
PROOFTEST_INTERVAL: Final = strict.named(MAINTENANCE, "prooftest_interval_days", strict.Whole)
FLEET_AGENT_USER: Final = strict.named(FLEET, "agent_user", strict.Text)
FLEET_AGENT_UID: Final = strict.named(FLEET, "agent_uid", strict.Whole)
FLEET_CONSOLE_REQUIRED: Final = strict.named(FLEET, "console_required", strict.Flag)
FLEET_CONSOLE_TIMEOUT: Final = strict.named(FLEET, "console_timeout_ms", strict.Whole)
API_GROUP: Final = strict.named(API, "group", strict.Text)
API_ADMIN_GROUP: Final = strict.named(API, "admin_group", strict.Text)
API_MAX_CLIENTS: Final = strict.named(API, "max_clients", strict.Whole)
API_MAX_MESSAGE: Final = strict.named(API, "max_message_bytes", strict.Whole)
API_OPERATOR_GROUP: Final = strict.named(API, "operator_group", strict.Text)


class RulesBroken(Exception):
    """Every rule between entries and sections that the file breaks, in the order of the
    rules (raised by :func:`build_config` with ``every_rule``): each section's own keys were
    read and found valid, so nothing else is left to judge."""

    def __init__(self, errors: Sequence[ConfigError]) -> None:
        super().__init__(f"{len(errors)} rules between sections broken")
        self.errors = tuple(errors)


class NotOnMachine(ConfigError):
    """A user, group or directory the config names does not exist on this machine: a mistake
    of the machine (a package not installed yet, a developer's laptop) rather than of the
    file. The daemon refuses to start all the same, and so does ``--check-config``; only
    ``--check-config --portable`` calls it a warning (docs/configuration.md "Checking a
    config"). Directories are judged by :mod:`supervisord.config.collect`."""

    def in_file(self, file: str) -> ConfigError:
        return NotOnMachine(self.key, self.value, self.fix, file)


def load_config(
    path: str | Path,
    *,
    base_dir: str | Path | None = None,
    group_exists: Callable[[str], bool] | None = None,
    user_uid: Callable[[str], int | None] | None = None,
) -> DaemonConfig:
    """Read and validate the robot's TOML file at ``path``.

    Relative paths in the file are resolved against ``base_dir`` (default: the file's own
    directory). ``group_exists`` says whether a group name exists (default: ask the system
    with ``grp.getgrnam``), ``user_uid`` a user's uid, ``None`` when it does not exist
    (default: ``pwd.getpwnam``). Raises :class:`ConfigError` naming ``path``, the key, the value and
    the fix for the first problem found: a missing or unreadable file, a TOML syntax error
    (key ``line L, column C``), an unknown section or key, a bad value or a contradiction
    between sections.
    """
    source = Path(path)
    try:
        data = read_toml(source)
    except ConfigError as error:
        raise (error if error.file else error.in_file(str(path))) from None
    return build_config(
        data, source, base_dir=base_dir, group_exists=group_exists, user_uid=user_uid
    )


def build_config(
    data: dict[str, object],
    source: Path,
    *,
    base_dir: str | Path | None = None,
    group_exists: Callable[[str], bool] | None = None,
    every_rule: bool = False,
    user_uid: Callable[[str], int | None] | None = None,
) -> DaemonConfig:
    """:func:`load_config` of the parsed ``data`` of the file ``source``. ``every_rule``: when
    every section's own keys are valid but rules between them are broken, raise
    :class:`RulesBroken` with all of them rather than the first (what ``--check-config``
    lists; the verdict is the same)."""
    base = Path(base_dir) if base_dir is not None else source.parent
    loader = _Loader(
        source, base.absolute(), group_exists or _group_exists, user_uid or _user_uid, every_rule
    )
    try:
        return loader.build(data)
    except ConfigError as error:
        raise (error if error.file else error.in_file(str(source))) from None
    except RulesBroken as broken:
        raise RulesBroken(
            [error if error.file else error.in_file(str(source)) for error in broken.errors]
        ) from None


def _user_uid(name: str) -> int | None:
    try:
        return pwd.getpwnam(name).pw_uid
    except KeyError:
        return None


def _group_exists(name: str) -> bool:
    try:
        grp.getgrnam(name)
    except KeyError:
        return False
    return True


def _section(root: strict.Fields, section: Section) -> strict.Fields:
    fields = root.table_at(section.name)
    fields.check_keys(key.name for key in section.keys)
    return fields


@dataclasses.dataclass
class _Loader:
    source: Path
    base: Path
    group_exists: Callable[[str], bool]
    user_uid: Callable[[str], int | None]
    every_rule: bool = False

    def build(self, data: dict[str, object]) -> DaemonConfig:
        root = strict.Fields(data, error=ConfigError, renamed=RENAMED)
        root.check_keys(section.name for section in SECTIONS)
        robot = RobotConfig(_section(root, SECTION["robot"]).text(ROBOT_NAME))
        vsc_fields = self.vsc_fields(root)
        vsc = self.vsc(vsc_fields)
        clients = self.clients(root)
        outputs = self.outputs(root)
        rearm = _section(root, SECTION["rearm"])
        api = self.api(_section(root, SECTION["api"]), len(clients))
        record = self.record(_section(root, SECTION["record"]))
        maintenance = _section(root, SECTION["maintenance"])
        intervals = (maintenance.whole(STOPTEST_INTERVAL), maintenance.whole(PROOFTEST_INTERVAL))
        output_bus = self.output_bus(root)
        fleet = self.fleet(_section(root, SECTION["fleet"]))
        safety = self.safety(vsc, vsc_fields, rearm, clients, outputs, fleet)
        # The rules between entries and sections last, once every section's own keys have
        # been read: a clash between two outputs must not hide a wrong key after them
        # (SR-11.2). ``--check-config`` gets every broken rule, the daemon the first.
        broken = list(broken_rules(vsc, outputs, output_bus, record, api))
        if broken:
            raise RulesBroken(broken) if self.every_rule else broken[0]
        return DaemonConfig(
            source=self.source,
            robot=robot,
            vsc=vsc,
            safety=safety,
            outputs=outputs,
            output_bus=output_bus,
            record=record,
            api=api,
            maintenance=MaintenanceConfig(*intervals),
        )

    def path(self, fields: strict.Fields, key: strict.Text) -> Path:
        """A file path; a relative one is resolved against the config file's directory."""
        return file_path(fields, key, self.base)

    # [vsc] --------------------------------------------------------------------------------

    @staticmethod
    def vsc_fields(root: strict.Fields) -> strict.Fields:
        fields = root.table_at(SECTION["vsc"].name)
        # An unknown key's hint lists the keys this transport takes, never another
        # transport's (those are errors here); every key when the transport is unknown.
        written = fields.table.get(TRANSPORT.name)
        chosen = next((t for t in Transport if t.value == written), None)
        known = VSC_COMMON + VSC_BY_TRANSPORT[chosen] if chosen else SECTION["vsc"].keys
        declared = {key.name for key in SECTION["vsc"].keys}
        for name, value in fields.table.items():
            if name not in declared:
                raise strict.unknown_key(
                    fields.key(name),
                    name,
                    value,
                    [key.name for key in known],
                    renamed=fields.renamed,
                    error=ConfigError,
                )
        transport = Transport(fields.read(TRANSPORT))
        allowed = {key.name for key in VSC_COMMON + VSC_BY_TRANSPORT[transport]}
        for name in fields.table:
            if name not in allowed:
                owner = next(
                    t for t, keys in VSC_BY_TRANSPORT.items() if name in {k.name for k in keys}
                )
                raise fields.refuse(
                    name,
                    fields.table[name],
                    f'remove it: it applies to transport "{owner.value}", not "{transport.value}"',
                )
        return fields

    def vsc(self, fields: strict.Fields) -> VscConfig:
        transport = Transport(fields.read(TRANSPORT))
        link: SerialPort | CanBus | HidDevice
        can_errors = CanErrors()
        if transport is Transport.SERIAL:
            port = self.path(fields, PORT)
            fields.read(BAUD)
            link = SerialPort(port, SERIAL_BAUD)
        elif transport is Transport.CAN:
            link = self.can_bus(fields)
            can_errors = CanErrors(
                fields.whole(ERROR_LIMIT), fields.whole(ERROR_WINDOW), fields.whole(ERROR_PASSIVE)
            )
        else:
            link = HidDevice(self.path(fields, HIDRAW))
        low = fields.whole(REOPEN_MIN)
        high = (
            fields.whole(REOPEN_MAX)
            if fields.has(REOPEN_MAX.name)
            else max(
                REOPEN_MAX.default,
                low,  # type: ignore[call-overload]
            )
        )
        if high < low:
            raise fields.refuse(REOPEN_MAX.name, high, f"make it at least reopen_min_ms ({low})")
        return VscConfig(transport, link, Reopen(low, high), can_errors)

    @staticmethod
    def can_bus(fields: strict.Fields) -> CanBus:
        interface = fields.read(CAN_INTERFACE)
        channel = fields.read(CAN_CHANNEL)
        assert isinstance(interface, str)
        assert isinstance(channel, str | int)
        return CanBus(interface, channel, fields.whole(CAN_BITRATE))

    # [[clients]] --------------------------------------------------------------------------

    def clients(self, root: strict.Fields) -> tuple[ClientSpec, ...]:
        section = SECTION["clients"]
        clients: list[ClientSpec] = []
        for fields in root.tables_at(section.name, section.example):
            fields.check_keys(key.name for key in section.keys)
            name = fields.text(CLIENT_NAME)
            timeout = fields.whole(CLIENT_TIMEOUT)
            for j, earlier in enumerate(clients):
                if earlier.name == name:
                    raise fields.refuse("name", name, f"rename it: clients[{j}] has the same name")
            progress = fields.flag(CLIENT_PROGRESS)
            clients.append(ClientSpec(name, timeout, self.client_user(fields), progress))
        return tuple(clients)

    def client_user(self, fields: strict.Fields) -> int | None:
        """The uid a client is bound to (``user`` by name or ``uid`` by number), or ``None``:
        unbound, any user who can reach the socket may say hello under the name
        (docs/safety.md "Clients bound to a user")."""
        user, uid = fields.read(CLIENT_USER), fields.read(CLIENT_UID)
        if user is not None and uid is not None:
            raise fields.refuse("uid", uid, "give user or uid, not both")
        if uid is not None:
            assert isinstance(uid, int)
            return uid
        if user is None:
            return None
        assert isinstance(user, str)
        uid = self.user_uid(user)
        if uid is None:
            raise NotOnMachine(
                fields.key("user"),
                user,
                f"no such user on this machine: create it (useradd --system {user}) or name "
                "the user the client runs as",
            )
        return uid

    # [fleet] ------------------------------------------------------------------------------

    def fleet(self, fields: strict.Fields) -> FleetSpec:
        """``[fleet]`` (SR-8.19 to SR-8.21): the agent's user, by name or number, and whether
        the console is a required stop source. Its errors name the file's keys."""
        user, uid = fields.read(FLEET_AGENT_USER), fields.read(FLEET_AGENT_UID)
        if user is not None and uid is not None:
            raise fields.refuse("agent_uid", uid, "give agent_user or agent_uid, not both")
        if isinstance(user, str):
            uid = self.user_uid(user)
            if uid is None:
                raise NotOnMachine(
                    fields.key("agent_user"),
                    user,
                    f"no such user on this machine: create it (useradd --system {user}) or "
                    "name the user the fleet agent runs as",
                )
        required = fields.flag(FLEET_CONSOLE_REQUIRED)
        if required and uid is None:
            raise fields.refuse(
                "console_required",
                True,
                "name the fleet agent's user (agent_user): without it no keepalive can "
                "arrive, and the robot would never leave STOPPED",
            )
        agents = frozenset[int]() if uid is None else frozenset({int(uid)})  # type: ignore[call-overload]
        return FleetSpec(agents, required, fields.whole(FLEET_CONSOLE_TIMEOUT))

    # [[outputs]] --------------------------------------------------------------------------

    def outputs(self, root: strict.Fields) -> tuple[DeviceSpec, ...]:
        section = SECTION["outputs"]
        raw = root.table.get(section.name, strict.MISSING)
        if isinstance(raw, dict) and raw and all(isinstance(v, dict) for v in raw.values()):
            first = next(iter(raw))
            raise root.refuse(
                f"{section.name}.{first}",
                raw[first],
                f'write [[outputs]] with name = "{first}" instead of [outputs.{first}]',
            )
        entries = root.tables_at(section.name, section.example)
        if not entries:
            raise root.refuse(
                section.name,
                strict.MISSING,
                "add at least one [[outputs]] table: without an enable line to gate, the "
                "supervisor holds nothing",
            )
        specs: list[DeviceSpec] = []
        for fields in entries:
            name = fields.text(OUTPUT_NAME_KEY)
            kind = fields.read(KIND)
            fields.check_keys(option_names(str(kind)))
            for i, earlier in enumerate(specs):
                if earlier.name == name:
                    raise fields.refuse(
                        OUTPUT_NAME_KEY.name, name, f"rename it: outputs[{i}] ({name}) has it"
                    )
            specs.append(read_spec(name, fields).resolved(self.base))
        return tuple(specs)

    @staticmethod
    def output_bus(root: strict.Fields) -> CanBus | None:
        """``[output_bus]``'s own keys; whether it may or must be there is a rule between
        sections (:func:`broken_rules`)."""
        if not root.has("output_bus"):
            return None
        return _Loader.can_bus(_section(root, SECTION["output_bus"]))

    # SafetyConfig -------------------------------------------------------------------------

    def safety(  # noqa: PLR0917 -- one argument per section the core's config is read from
        self,
        vsc: VscConfig,
        fields: strict.Fields,
        rearm: strict.Fields,
        clients: tuple[ClientSpec, ...],
        outputs: Sequence[DeviceSpec],
        fleet: FleetSpec,
    ) -> SafetyConfig:
        hold, local_reset = (rearm.read(key) for key in SECTION["rearm"].keys)
        require_watchdog = fields.flag(REQUIRE_WATCHDOG)
        vsc_timeout_ms, heartbeat_hz = fields.whole(VSC_TIMEOUT_MS), fields.whole(HEARTBEAT_HZ)
        prooftest = self.prooftest(vsc.transport, require_watchdog, fields)
        prooftest_clear = fields.whole(PROOFTEST_CLEAR)
        # Its errors (the checks across keys: a watchdog or a proof test on CAN) name the keys
        # as the file spells them.
        return SafetyConfig(
            transport=vsc.transport,
            vsc_timeout_ms=vsc_timeout_ms,
            heartbeat_hz=heartbeat_hz,
            rearm_hold_ms=hold,  # type: ignore[arg-type]
            local_reset=local_reset,  # type: ignore[arg-type]
            require_watchdog=require_watchdog,
            prooftest=prooftest,
            prooftest_clear_ms=prooftest_clear,
            min_remote_battery=fields.whole(MIN_REMOTE_BATTERY),
            on_estop_unavailable=Reaction(fields.read(ON_ESTOP_UNAVAILABLE)),
            clients=clients,
            outputs=tuple(outputs),
            fleet=fleet,
        )

    @staticmethod
    def prooftest(
        transport: Transport, require_watchdog: bool, fields: strict.Fields
    ) -> ProofTestPolicy:
        """``vsc.prooftest`` (docs/safety.md "The proof test", SR-5.3). The default: ``block``
        on serial when the watchdog is required, ``record`` on serial when it is not (then a
        VSC with key 85 off is recorded at every start, and runs), ``off`` on CAN and HID,
        which have no user heartbeat to withhold."""
        raw = fields.read(PROOFTEST)
        if raw is not None:
            return ProofTestPolicy(raw)
        if transport is not Transport.SERIAL:
            return ProofTestPolicy.OFF
        return ProofTestPolicy.BLOCK if require_watchdog else ProofTestPolicy.RECORD

    # [record], [api] ----------------------------------------------------------------------

    def record(self, fields: strict.Fields) -> RecordConfig:
        config = RecordConfig(
            path=self.path(fields, RECORD_PATH),
            max_bytes=fields.whole(RECORD_MAX_BYTES),
            keep=fields.whole(RECORD_KEEP),
            journal=fields.flag(RECORD_JOURNAL),
            flight_max_bytes=fields.whole(RECORD_FLIGHT_MAX_BYTES),
        )
        check_record_files(fields, config.path, config.keep)  # SR-7.9
        return config

    def group(self, fields: strict.Fields, key: strict.Key) -> str | None:
        group = fields.read(key)
        if group is None:
            return None
        assert isinstance(group, str)
        if not self.group_exists(group):
            raise NotOnMachine(
                fields.key(key.name),
                group,
                f"no such group on this machine: create it (groupadd --system {group}) and "
                "add the users to it, or name an existing group",
            )
        return group

    def api(self, fields: strict.Fields, required_clients: int) -> ApiConfig:
        socket, operator = api_sockets(fields, self.base)
        group = self.group(fields, API_GROUP)
        admin_group = self.group(fields, API_ADMIN_GROUP)
        operator_group = self.group(fields, API_OPERATOR_GROUP)
        max_clients = fields.whole(API_MAX_CLIENTS)
        if max_clients < required_clients + 1:
            raise fields.refuse(
                "max_clients",
                max_clients,
                f"raise it to at least {required_clients + 1}: the {required_clients} required "
                "clients and one srcsctl must fit",
            )
        return ApiConfig(
            socket=socket,
            group=group,
            admin_group=admin_group,
            max_clients=max_clients,
            max_message_bytes=fields.whole(API_MAX_MESSAGE),
            operator_socket=operator,
            operator_group=operator_group,
        )


def broken_rules(
    vsc: VscConfig,
    outputs: Sequence[DeviceSpec],
    output_bus: CanBus | None,
    record: RecordConfig,
    api: ApiConfig,
) -> Iterator[ConfigError]:
    """Every broken rule between entries and sections, in this order: no two outputs hold one
    device, at least one motion output, the output bus, one owner per path (SR-11.1). Each
    names the later key of a clash, so the earlier entry stays judged."""
    yield from _device_clashes(outputs)
    if not any(spec.role is OutputRole.MOTION for spec in outputs):
        yield ConfigError(
            "outputs",
            [f"{spec.name}: {spec.role.value}" for spec in outputs],
            'give at least one output role = "motion": otherwise a hold (pause, menu, '
            "a client's hold) leaves motion enabled",
        )
    yield from _output_bus_rules(vsc, outputs, output_bus)
    yield from _path_clashes(vsc, outputs, record, api)


def _device_clashes(specs: Sequence[DeviceSpec]) -> Iterator[ConfigError]:
    """No two outputs hold the same device (what each spec claims): each later claimant."""
    seen: dict[Hashable, int] = {}
    for j, spec in enumerate(specs):
        for claim in spec.claims():
            if claim.identity is None:
                continue
            i = seen.setdefault(claim.identity, j)
            if i != j:
                yield ConfigError(
                    f"outputs[{j}].{claim.option}",
                    claim.value,
                    f"give each output its own {claim.what}: outputs[{i}] ({specs[i].name}) has it",
                )


def _output_bus_rules(
    vsc: VscConfig, outputs: Sequence[DeviceSpec], bus: CanBus | None
) -> Iterator[ConfigError]:
    """``[output_bus]`` is there exactly when a CAN output needs a bus the VSC does not lend,
    and is not the VSC's own bus."""
    can_outputs = [i for i, spec in enumerate(outputs) if spec.kind is OutputKind.CAN]
    if bus is None:
        if can_outputs and vsc.transport is not Transport.CAN:
            yield ConfigError(
                f"outputs[{can_outputs[0]}].kind",
                "can",
                "add an [output_bus] section (interface, channel, bitrate) for the enable "
                'frames: only a VSC on transport = "can" lends its bus to CAN outputs',
            )
        return
    if not can_outputs:
        yield ConfigError(
            "output_bus",
            {"interface": bus.interface, "channel": bus.channel, "bitrate": bus.bitrate},
            'remove it: no output has kind = "can"',
        )
    elif isinstance(vsc.link, CanBus) and (vsc.link.interface, vsc.link.channel) == (
        bus.interface,
        bus.channel,
    ):
        yield ConfigError(
            "output_bus.channel",
            bus.channel,
            "remove [output_bus]: CAN outputs already send on the VSC's bus; give "
            "[output_bus] only for a second CAN network",
        )


def _path_claims(
    vsc: VscConfig, outputs: Sequence[DeviceSpec], record: RecordConfig, api: ApiConfig
) -> list[tuple[str, str, Path, str]]:
    """(key, value as written, file, what of the owner) for every file the config names, in
    the order of the file's sections; the record claims its rotated files too."""
    claims: list[tuple[str, str, Path, str]] = []
    link = vsc.link
    if isinstance(link, SerialPort):
        claims.append(("vsc.port", str(link.port), link.port, ""))
    elif isinstance(link, HidDevice):
        claims.append(("vsc.hidraw", str(link.hidraw), link.hidraw, ""))
    for i, spec in enumerate(outputs):
        claims += [
            (f"outputs[{i}].{claim.option}", str(claim.value), claim.path, "")
            for claim in spec.claims()
            if claim.path is not None
        ]
    claims += [
        ("record.path", str(record.path), file, part)
        for file, part in record_paths(record.path, record.keep)
    ]
    claims.append(("api.socket", str(api.socket), api.socket, ""))
    claims.append(("api.operator_socket", str(api.operator_path), api.operator_path, ""))
    return claims


def _path_clashes(
    vsc: VscConfig, outputs: Sequence[DeviceSpec], record: RecordConfig, api: ApiConfig
) -> Iterator[ConfigError]:
    """Every file has one owner (SR-11.1; docs/configuration.md "One owner per path"): two
    keys that name one file once relative paths and symlinks are resolved would destroy each
    other's file (an output's write replacing the record, the socket's start removing an
    output). The later key is refused, naming the earlier one."""
    seen: dict[str, tuple[str, str, str]] = {}
    refused: set[str] = set()  # a key once: the record's rotated files may clash each
    for key, value, path, part in _path_claims(vsc, outputs, record, api):
        resolved = os.path.realpath(path)
        first = seen.setdefault(resolved, (key, value, part))
        if first == (key, value, part) or key in refused:
            continue
        refused.add(key)
        other_key, other_value, other_part = first
        mine = f"its {part}" if part else "it"
        other = f"{other_key} = {other_value!r}" + (f" (its {other_part})" if other_part else "")
        yield ConfigError(
            key,
            value,
            f"give it its own file: {mine} and {other} are one file once relative paths and "
            "symlinks are resolved (every path in the config has one owner)",
        )
