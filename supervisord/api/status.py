"""The supervisor's state as the client API says it (docs/api.md "status"): typed, frozen.

:class:`StateReport` is what a ``status`` reply and a ``state`` push share (the state, its
causes, the outputs, the proof test); :class:`DaemonStatus` is ``status``'s ``daemon`` object,
built from the daemon loop's own :class:`LoopStatus` snapshot and what the API listener saw.
Each type has one encoder (``json``, to the object on the wire) and one decoder
(``read``, from a :class:`~supervisord.api.wire.Fields`; unknown fields are ignored, docs/api.md
"Framing").

Pure and small: the client library imports it (docs/ros2.md "The client library").
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, field

from supervisord.api.wire import Fields, JsonDict


@dataclass(frozen=True, slots=True, kw_only=True)
class Cause:
    """One cause, as ``status``, ``state`` pushes and stop records show it (docs/record.md)."""

    name: str
    severity: str  # "stop" (latches) or "hold"
    active: bool
    latched: bool
    raised_ns: int | None
    cleared_ns: int | None
    details: Mapping[str, str] = field(default_factory=dict)

    @property
    def held(self) -> bool:
        """Cleared, and held only by its latch until a re-arm (SR-4)."""
        return self.latched and not self.active

    def json(self) -> JsonDict:
        return {
            "name": self.name,
            "severity": self.severity,
            "active": self.active,
            "latched": self.latched,
            "raised_ns": self.raised_ns,
            "cleared_ns": self.cleared_ns,
            "details": dict(self.details),
        }

    @classmethod
    def read(cls, f: Fields) -> Cause:
        return cls(
            name=f.text("name"),
            severity=f.text("severity"),
            active=f.flag("active"),
            latched=f.flag("latched"),
            raised_ns=f.maybe_integer("raised_ns"),
            cleared_ns=f.maybe_integer("cleared_ns"),
            details=f.mapping("details").text_values() if f.has("details") else {},
        )


@dataclass(frozen=True, slots=True, kw_only=True)
class ProofTestResult:
    """A finished proof test of the VSC's watchdog (docs/safety.md "The proof test")."""

    result: str  # "passed" or "failed"
    failure: str | None  # why it failed, by name (e.g. "no_trip")
    trip_ms: int | None
    cleared: str | None  # "by_itself" or "held"
    cleared_ms: int | None
    text: str

    @property
    def passed(self) -> bool:
        return self.result == "passed"

    def json(self) -> JsonDict:
        return {
            "result": self.result,
            "failure": self.failure,
            "trip_ms": self.trip_ms,
            "cleared": self.cleared,
            "cleared_ms": self.cleared_ms,
            "text": self.text,
        }

    @classmethod
    def read(cls, f: Fields) -> ProofTestResult:
        return cls(
            result=f.text("result"),
            failure=f.maybe_text("failure"),
            trip_ms=f.maybe_integer("trip_ms"),
            cleared=f.maybe_text("cleared"),
            cleared_ms=f.maybe_integer("cleared_ms"),
            text=f.maybe_text("text") or "",
        )


@dataclass(frozen=True, slots=True, kw_only=True)
class ProofTestStatus:
    """Where the proof test is: ``policy`` (block, record, off), ``phase`` (waiting,
    withholding, resumed, passed, failed, off) and the ``last`` result."""

    policy: str
    phase: str
    last: ProofTestResult | None

    def json(self) -> JsonDict:
        return {
            "policy": self.policy,
            "phase": self.phase,
            "last": None if self.last is None else self.last.json(),
        }

    @classmethod
    def read(cls, f: Fields) -> ProofTestStatus:
        last = f.maybe_obj("last")
        return cls(
            policy=f.text("policy"),
            phase=f.text("phase"),
            last=None if last is None else ProofTestResult.read(last),
        )


@dataclass(frozen=True, slots=True, kw_only=True)
class StateReport:
    """The state after one decision: what ``status`` and a ``state`` push share."""

    state: str  # STOPPED, HOLD or RUN (SR-1)
    mono_ns: int
    causes: tuple[Cause, ...]
    outputs: Mapping[str, bool]
    heartbeat_estop: int
    prooftest: ProofTestStatus | None = None

    def active(self) -> frozenset[str]:
        """The names of the active causes."""
        return frozenset(c.name for c in self.causes if c.active)

    def json(self) -> JsonDict:
        return {
            "state": self.state,
            "mono_ns": self.mono_ns,
            "causes": [c.json() for c in self.causes],
            "outputs": dict(self.outputs),
            "heartbeat_estop": self.heartbeat_estop,
            "prooftest": None if self.prooftest is None else self.prooftest.json(),
        }

    @classmethod
    def read(cls, f: Fields) -> StateReport:
        proof = f.maybe_obj("prooftest")
        return cls(
            state=f.text("state"),
            mono_ns=f.integer("mono_ns"),
            causes=tuple(Cause.read(c) for c in f.objects("causes")),
            outputs=f.mapping("outputs").flag_values(),
            heartbeat_estop=f.integer("heartbeat_estop"),
            prooftest=None if proof is None else ProofTestStatus.read(proof),
        )


@dataclass(frozen=True, slots=True, kw_only=True)
class EstopAvailable:
    """Whether the remote e-stop is available (SR-8.11), and each part missing in words."""

    available: bool
    missing: tuple[str, ...] = ()

    def json(self) -> JsonDict:
        return {"available": self.available, "missing": list(self.missing)}

    @classmethod
    def read(cls, f: Fields) -> EstopAvailable:
        return cls(available=f.flag("available"), missing=f.texts("missing"))


@dataclass(frozen=True, slots=True, kw_only=True)
class RearmStatus:
    """What a re-arm waits for now (SR-4.1, SR-8.10): ``hold_ms`` is ``rearm.hold_ms``;
    ``clear_for_s`` how long every stop condition has been clear since the last latched one
    cleared (``None`` while one is active, or nothing is latched); ``accepted_in_s`` the
    seconds until a takeover's hold is met (0: now; ``None`` while a stop condition is
    active: the hold has not begun). The operator's act and a zero command are not in it."""

    hold_ms: int
    clear_for_s: float | None
    accepted_in_s: float | None

    def json(self) -> JsonDict:
        return {
            "hold_ms": self.hold_ms,
            "clear_for_s": self.clear_for_s,
            "accepted_in_s": self.accepted_in_s,
        }

    @classmethod
    def read(cls, f: Fields) -> RearmStatus:
        return cls(
            hold_ms=f.integer("hold_ms"),
            clear_for_s=f.maybe_number("clear_for_s"),
            accepted_in_s=f.maybe_number("accepted_in_s"),
        )


@dataclass(frozen=True, slots=True, kw_only=True)
class LinkStatus:
    """The link to the VSC: ``since_s`` since it last opened or broke, ``last_error`` why it
    last broke or failed to open, ``error_frames`` CAN's error frames (``None`` elsewhere)."""

    description: str
    open: bool
    opens: int
    open_failures: int
    since_s: float | None
    last_error: str | None
    error_frames: int | None

    def json(self) -> JsonDict:
        return {
            "description": self.description,
            "open": self.open,
            "opens": self.opens,
            "open_failures": self.open_failures,
            "since_s": self.since_s,
            "last_error": self.last_error,
            "error_frames": self.error_frames,
        }

    @classmethod
    def read(cls, f: Fields) -> LinkStatus:
        return cls(
            description=f.text("description"),
            open=f.flag("open"),
            opens=f.integer("opens"),
            open_failures=f.integer("open_failures"),
            since_s=f.maybe_number("since_s"),
            last_error=f.maybe_text("last_error"),
            error_frames=f.maybe_integer("error_frames"),
        )


@dataclass(frozen=True, slots=True, kw_only=True)
class HistogramStatus:
    """One of the loop's timing histograms (docs/fleet.md "Timing histograms"): the buckets'
    upper bounds in seconds, the cumulative count at each, the sum (s) and the count."""

    le: tuple[float, ...]
    counts: tuple[int, ...]
    sum: float
    count: int

    def json(self) -> JsonDict:
        return {
            "le": list(self.le),
            "counts": list(self.counts),
            "sum": self.sum,
            "count": self.count,
        }

    @classmethod
    def read(cls, f: Fields) -> HistogramStatus:
        return cls(
            le=f.numbers("le"),
            counts=f.integers("counts"),
            sum=f.number("sum"),
            count=f.integer("count"),
        )


SINK_COUNTERS = (
    "records_pending",
    "journal_errors",
    "journal_dropped",
    "log_lines_dropped",
    "record_reopens",
    "flight_windows",
    "flight_errors",
    "flight_dropped",
)
"""The record lanes' counters in ``status``'s ``daemon`` object, in their wire order."""


@dataclass(frozen=True, slots=True, kw_only=True)
class PeriodicDue:
    """One periodic test's schedule (SR-12.2): its interval (0: no schedule), the age of its
    last pass (``None``: never passed, or not known) and whether it is overdue."""

    interval_days: int
    last_pass_age_s: float | None
    overdue: bool

    def json(self) -> JsonDict:
        return {
            "interval_days": self.interval_days,
            "last_pass_age_s": self.last_pass_age_s,
            "overdue": self.overdue,
        }

    @classmethod
    def read(cls, f: Fields) -> PeriodicDue:
        return cls(
            interval_days=f.integer("interval_days"),
            last_pass_age_s=f.maybe_number("last_pass_age_s"),
            overdue=f.flag("overdue"),
        )


@dataclass(frozen=True, slots=True, kw_only=True)
class Maintenance:
    """``daemon.maintenance``: the periodic tests (SR-12.2; docs/safety-manual.md "Periodic
    tests"), the field stop test (``stoptest``) and the VSC watchdog's proof test
    (``prooftest``); ``None`` for a test the daemon does not name. Tests a newer daemon adds
    are ignored."""

    stoptest: PeriodicDue | None = None
    prooftest: PeriodicDue | None = None

    def tests(self) -> tuple[tuple[str, PeriodicDue], ...]:
        """Each test the daemon named, by its name on the wire, in wire order."""
        named = (("stoptest", self.stoptest), ("prooftest", self.prooftest))
        return tuple((name, due) for name, due in named if due is not None)

    def json(self) -> JsonDict:
        return {name: due.json() for name, due in self.tests()}

    @classmethod
    def read(cls, f: Fields) -> Maintenance:
        stop, proof = f.maybe_obj("stoptest"), f.maybe_obj("prooftest")
        return cls(
            stoptest=None if stop is None else PeriodicDue.read(stop),
            prooftest=None if proof is None else PeriodicDue.read(proof),
        )


@dataclass(frozen=True, slots=True, kw_only=True)
class LoopStatus:
    """What the daemon's loop says about itself in ``status`` (docs/api.md "status"): one
    snapshot, taken when a ``status`` is answered."""

    pid: int
    version: str
    uptime_s: float | None
    link: LinkStatus
    outputs_not_acquired: tuple[str, ...]
    outputs_off_delay_ms: Mapping[str, int]  # category-1 outputs only (SR-1.4)
    messages: int
    rejections: Mapping[str, int]
    record_errors: int
    records_dropped: int
    sink: Mapping[str, int]  # SINK_COUNTERS by name
    rate_limited: int
    internal_faults: int
    histograms: Mapping[str, HistogramStatus]
    maintenance: Maintenance | None = None  # None: a daemon older than SR-12.2

    def json(self) -> JsonDict:
        out: JsonDict = {
            "pid": self.pid,
            "version": self.version,
            "uptime_s": self.uptime_s,
            "link": self.link.json(),
            "outputs_not_acquired": list(self.outputs_not_acquired),
            "outputs_off_delay_ms": dict(self.outputs_off_delay_ms),
            "messages": self.messages,
            "rejections": dict(self.rejections),
            "record_errors": self.record_errors,
            "records_dropped": self.records_dropped,
            **self.sink,
            "rate_limited": self.rate_limited,
            "internal_faults": self.internal_faults,
            "histograms": {name: h.json() for name, h in self.histograms.items()},
        }
        if self.maintenance is not None:
            out["maintenance"] = self.maintenance.json()
        return out

    @classmethod
    def read(cls, f: Fields) -> LoopStatus:
        # A daemon older than its timing histograms (docs/fleet.md) has none to say.
        histograms = f.mapping("histograms") if f.has("histograms") else Fields({}, f.where)
        maintenance = f.maybe_obj("maintenance")  # a daemon older than SR-12.2 has none
        return cls(
            pid=f.integer("pid"),
            version=f.text("version"),
            uptime_s=f.maybe_number("uptime_s"),
            link=LinkStatus.read(f.obj("link")),
            outputs_not_acquired=f.texts("outputs_not_acquired"),
            # A daemon older than stop categories (SR-1.4) has every output category 0.
            outputs_off_delay_ms=f.mapping("outputs_off_delay_ms").integer_values()
            if f.has("outputs_off_delay_ms")
            else {},
            messages=f.integer("messages"),
            rejections=f.mapping("rejections").integer_values(),
            record_errors=f.integer("record_errors"),
            records_dropped=f.integer("records_dropped"),
            sink={name: f.integer(name) for name in SINK_COUNTERS if f.has(name)},
            rate_limited=f.integer("rate_limited"),
            internal_faults=f.integer("internal_faults"),
            histograms={
                name: HistogramStatus.read(histograms.obj(name)) for name in histograms.names()
            },
            maintenance=None if maintenance is None else Maintenance.read(maintenance),
        )


@dataclass(frozen=True, slots=True, kw_only=True)
class ClientStatus:
    """A required client, or a connection that said ``hello``: ``heartbeat_age_s`` since its
    last accepted heartbeat (``None``: none yet); ``command_nonzero``: its connection's last
    ``command`` declared a non-zero command (SR-4.6); ``timeout_ms`` for a required one."""

    name: str
    required: bool
    connected: bool
    heartbeat_age_s: float | None
    command_nonzero: bool = False
    timeout_ms: int | None = None

    def json(self) -> JsonDict:
        out: JsonDict = {
            "name": self.name,
            "required": self.required,
            "connected": self.connected,
            "heartbeat_age_s": self.heartbeat_age_s,
            "command_nonzero": self.command_nonzero,
        }
        if self.timeout_ms is not None:
            out["timeout_ms"] = self.timeout_ms
        return out

    @classmethod
    def read(cls, f: Fields) -> ClientStatus:
        return cls(
            name=f.text("name"),
            required=f.flag("required"),
            connected=f.flag("connected"),
            heartbeat_age_s=f.maybe_number("heartbeat_age_s"),
            # A daemon older than SR-4.6 knows no declaration: every command counts as zero.
            command_nonzero=f.maybe_flag("command_nonzero") or False,
            timeout_ms=f.maybe_integer("timeout_ms"),
        )


@dataclass(frozen=True, slots=True, kw_only=True)
class RemoteReport:
    """The last remote-status message (manual §8.3.4) and its age (the VSC keeps the values
    when the remote's link is lost, PR-2.10)."""

    battery_level: int
    battery_charging: int
    connection_strength_vsc: int
    connection_strength_src: int
    rssi_vsc: int
    rssi_src: int
    age_s: float | None

    def json(self) -> JsonDict:
        return {
            "battery_level": self.battery_level,
            "battery_charging": self.battery_charging,
            "connection_strength_vsc": self.connection_strength_vsc,
            "connection_strength_src": self.connection_strength_src,
            "rssi_vsc": self.rssi_vsc,
            "rssi_src": self.rssi_src,
            "age_s": self.age_s,
        }

    @classmethod
    def read(cls, f: Fields) -> RemoteReport:
        return cls(
            battery_level=f.integer("battery_level"),
            battery_charging=f.integer("battery_charging"),
            connection_strength_vsc=f.integer("connection_strength_vsc"),
            connection_strength_src=f.integer("connection_strength_src"),
            rssi_vsc=f.integer("rssi_vsc"),
            rssi_src=f.integer("rssi_src"),
            age_s=f.maybe_number("age_s"),
        )


@dataclass(frozen=True, slots=True, kw_only=True)
class DaemonStatus:
    """``status``'s ``daemon`` object: the robot's name, the loop's snapshot, and what the
    API listener saw (the clients, the connections, the remote, the time in this state). On
    the wire it is one flat object."""

    robot: str | None
    loop: LoopStatus
    clients: tuple[ClientStatus, ...]
    connections: int
    remote: RemoteReport | None
    in_state_s: float | None

    def json(self) -> JsonDict:
        return {
            "robot": self.robot,
            **self.loop.json(),
            "clients": [c.json() for c in self.clients],
            "connections": self.connections,
            "remote": None if self.remote is None else self.remote.json(),
            "in_state_s": self.in_state_s,
        }

    @classmethod
    def read(cls, f: Fields) -> DaemonStatus:
        remote = f.maybe_obj("remote")
        return cls(
            robot=f.maybe_text("robot"),
            loop=LoopStatus.read(f),
            clients=tuple(ClientStatus.read(c) for c in f.objects("clients")),
            connections=f.integer("connections"),
            remote=None if remote is None else RemoteReport.read(remote),
            in_state_s=f.maybe_number("in_state_s"),
        )
