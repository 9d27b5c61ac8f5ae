"""The supervisor's state as the client API says it (docs/api.md "status"): typed, frozen.

:class:`StateReport` is what a ``status`` reply and a ``state`` push share (the state, its
causes, the outputs, the proof test); :class:`DaemonStatus` is ``status``'s ``daemon`` object,
built from the daemon loop's own :class:`LoopStatus` snapshot and what the API listener saw.
Each type declares each field once (:class:`~supervisord.wire.Wire`): its encoder (``json``)
and decoder (``read``; unknown fields are ignored, docs/api.md "Framing") follow from it. The
causes and the proof test are the stop record's own (:mod:`supervisord.record.stop`).

Pure and small: the client library imports it (docs/ros2.md "The client library").
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass

from supervisord.record.stop import Cause, ProofTestResult, ProofTestStatus
from supervisord.vocabulary import CauseKind, State, UnknownCauseKind
from supervisord.wire import Fields, Wire, wire

__all__ = [
    "SINK_COUNTERS",
    "Cause",
    "ClientStatus",
    "DaemonStatus",
    "EstopAvailable",
    "HistogramStatus",
    "LinkStatus",
    "LoopStatus",
    "Maintenance",
    "PeriodicDue",
    "ProofTestResult",
    "ProofTestStatus",
    "RearmStatus",
    "RemoteReport",
    "StateReport",
]


@dataclass(frozen=True, slots=True, kw_only=True)
class StateReport(Wire):
    """The state after one decision: what ``status`` and a ``state`` push share."""

    state: State = wire(by_name=True)  # STOPPED, HOLD or RUN on the wire (SR-1)
    mono_ns: int
    causes: tuple[Cause, ...]
    outputs: Mapping[str, bool]
    heartbeat_estop: int
    prooftest: ProofTestStatus | None = None

    def active(self) -> frozenset[str]:
        """The names of the active causes."""
        return frozenset(c.name.name for c in self.causes if c.active)

    def active_kinds(self) -> frozenset[CauseKind | UnknownCauseKind]:
        """The kinds of the active causes (one this client does not know, as its text)."""
        return frozenset(c.name.kind for c in self.causes if c.active)


@dataclass(frozen=True, slots=True, kw_only=True)
class EstopAvailable(Wire):
    """Whether the remote e-stop is available (SR-8.11), and each part missing in words."""

    available: bool
    missing: tuple[str, ...] = ()


@dataclass(frozen=True, slots=True, kw_only=True)
class RearmStatus(Wire):
    """What a re-arm waits for now (SR-4.1, SR-8.10): ``hold_ms`` is ``rearm.hold_ms``;
    ``clear_for_s`` how long every stop condition has been clear since the last latched one
    cleared (``None`` while one is active, or nothing is latched); ``accepted_in_s`` the
    seconds until a takeover's hold is met (0: now; ``None`` while a stop condition is
    active: the hold has not begun). The operator's act and a zero command are not in it."""

    hold_ms: int
    clear_for_s: float | None
    accepted_in_s: float | None


@dataclass(frozen=True, slots=True, kw_only=True)
class LinkStatus(Wire):
    """The link to the VSC: ``since_s`` since it last opened or broke, ``last_error`` why it
    last broke or failed to open (``None`` once it opened again, SR-8.18), ``error_frames``
    CAN's error frames (``None`` elsewhere)."""

    description: str
    open: bool
    opens: int
    open_failures: int
    since_s: float | None
    last_error: str | None
    error_frames: int | None


@dataclass(frozen=True, slots=True, kw_only=True)
class HistogramStatus(Wire):
    """One of the loop's timing histograms (docs/fleet.md "Timing histograms"): the buckets'
    upper bounds in seconds, the cumulative count at each, the sum (s) and the count."""

    le: tuple[float, ...]
    counts: tuple[int, ...]
    sum: float
    count: int


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


def _sink_counters(f: Fields, _key: str) -> dict[str, int]:
    """The record lanes' counters, written into ``daemon`` itself: those the daemon says."""
    return {name: f.integer(name) for name in SINK_COUNTERS if f.has(name)}


@dataclass(frozen=True, slots=True, kw_only=True)
class PeriodicDue(Wire):
    """One periodic test's schedule (SR-12.2): its interval (0: no schedule), the age of its
    last pass (``None``: never passed, or not known) and whether it is overdue."""

    interval_days: int
    last_pass_age_s: float | None
    overdue: bool


@dataclass(frozen=True, slots=True, kw_only=True)
class Maintenance(Wire):
    """``daemon.maintenance``: the periodic tests (SR-12.2; docs/safety-manual.md "Periodic
    tests"), the field stop test (``stoptest``) and the VSC watchdog's proof test
    (``prooftest``); ``None`` for a test the daemon does not name. Tests a newer daemon adds
    are ignored."""

    stoptest: PeriodicDue | None = wire(omit_none=True, default=None)
    prooftest: PeriodicDue | None = wire(omit_none=True, default=None)

    def tests(self) -> tuple[tuple[str, PeriodicDue], ...]:
        """Each test the daemon named, by its name on the wire, in wire order."""
        named = (("stoptest", self.stoptest), ("prooftest", self.prooftest))
        return tuple((name, due) for name, due in named if due is not None)


@dataclass(frozen=True, slots=True, kw_only=True)
class LoopStatus(Wire):
    """What the daemon's loop says about itself in ``status`` (docs/api.md "status"): one
    snapshot, taken when a ``status`` is answered."""

    pid: int
    version: str
    uptime_s: float | None
    link: LinkStatus
    outputs_not_acquired: tuple[str, ...]
    # Category-1 outputs only (SR-1.4); a daemon older than stop categories has none.
    outputs_off_delay_ms: Mapping[str, int] = wire(absent={})
    messages: int
    rejections: Mapping[str, int]
    record_errors: int
    records_dropped: int
    sink: Mapping[str, int] = wire(flat=True, decode=_sink_counters)  # SINK_COUNTERS by name
    rate_limited: int
    internal_faults: int
    # A daemon older than its timing histograms (docs/fleet.md) has none to say.
    histograms: Mapping[str, HistogramStatus] = wire(absent={})
    # A daemon older than SR-12.2 has none.
    maintenance: Maintenance | None = wire(omit_none=True, default=None)
    # Whether its start locked its memory (SR-9.6); a daemon older than the lock, or a loop
    # started by no srcsd, says nothing.
    memory_locked: bool | None = wire(omit_none=True, default=None)


@dataclass(frozen=True, slots=True, kw_only=True)
class ClientStatus(Wire):
    """A required client, or a connection that said ``hello``: ``heartbeat_age_s`` since its
    last accepted heartbeat (``None``: none yet); ``command_nonzero``: its connection's last
    ``command`` declared a non-zero command (SR-4.6); ``timeout_ms`` for a required one."""

    name: str
    required: bool
    connected: bool
    heartbeat_age_s: float | None
    # A daemon older than SR-4.6 knows no declaration: every command counts as zero.
    command_nonzero: bool = wire(absent=False, default=False)
    timeout_ms: int | None = wire(omit_none=True, default=None)


@dataclass(frozen=True, slots=True, kw_only=True)
class RemoteReport(Wire):
    """The last remote-status message (manual §8.3.4) and its age (the VSC keeps the values
    when the remote's link is lost, PR-2.10)."""

    battery_level: int
    battery_charging: int
    connection_strength_vsc: int
    connection_strength_src: int
    rssi_vsc: int
    rssi_src: int
    age_s: float | None


@dataclass(frozen=True, slots=True, kw_only=True)
class DaemonStatus(Wire):
    """``status``'s ``daemon`` object: the robot's name, the loop's snapshot, and what the
    API listener saw (the clients, the connections, the remote, the time in this state). On
    the wire it is one flat object."""

    robot: str | None
    loop: LoopStatus = wire(flat=True)
    clients: tuple[ClientStatus, ...]
    connections: int
    remote: RemoteReport | None
    in_state_s: float | None
