"""What the exporter knows, as metric values: pure (no socket, no clock, no prometheus-client).

The follower feeds it ``status`` replies and pushes as the client library reads them (the
typed values of ``supervisord.api``, ``docs/api.md``); :meth:`ExporterModel.families` gives the
metric families to serve. A reply or push the client cannot read never gets here (the
follower reconnects, ``srcs_up`` 0 meanwhile); values this code does not expect (a state it
does not know, a histogram Prometheus cannot take, a new kind of push) are skipped, never
raised: the exporter must keep serving whatever the daemon says.

Two kinds of values (docs/fleet.md "Metrics"):

- **The daemon's** (state, causes, outputs, link, the loop's counters, the remote's status):
  exported only while connected. When the connection ends they go, so a scrape never shows
  a state the exporter cannot vouch for; ``srcs_up`` says 0.
- **The exporter's own counters** (stops, re-arms, raised causes, transitions, records seen
  and missed), counted from the ``records`` push stream: they start at 0 when the exporter
  starts and keep counting across daemon restarts; records the exporter could not see are
  counted, by their sequence numbers, in ``srcs_records_missed_total``.
"""

from __future__ import annotations

import enum
import math
from collections.abc import Iterable
from dataclasses import dataclass, field
from typing import Final, Protocol

from supervisord.api.messages import RemoteStatusReport
from supervisord.api.pushes import Push, RecordPush, RemoteStatusPush, StatePush
from supervisord.api.replies import StatusReply
from supervisord.api.status import DaemonStatus, HistogramStatus, Maintenance, StateReport
from supervisord.exporter.judge import JudgeTotals
from supervisord.record.counted import counted, trigger
from supervisord.record.stop import RecordKind, StopRecord
from supervisord.timebase import NS_PER_S
from supervisord.vocabulary import ChangeKind, Counted, State

STATES: Final = tuple(state.name for state in State)
"""The supervisor's states (SR-1), one ``srcs_state`` series each."""
MAX_LABEL_VALUES: Final = 64
"""Distinct values one label may take (cause, reason, output); past it, ``other``. Cause
names carry client names (``client_lost:NAME``), which any process that may connect can
choose: the cap keeps a misbehaving client from growing the fleet's database without end."""
OVERFLOW: Final = "other"
REMOTE_STALE_NS: Final = 5_000_000_000
"""A remote status older than this is not exported: the VSC sends one a second once
commissioned (docs/api.md "commission"), and does not clear it when the remote's link drops
(manual §8.3.4), so only a fresh one describes the remote now."""


class Kind(enum.Enum):
    """A metric family's type (the OpenMetrics types this exporter uses)."""

    GAUGE = "gauge"
    COUNTER = "counter"  # ``name`` without ``_total``; the serving edge adds it
    INFO = "info"  # ``name`` without ``_info``; one sample of value 1
    HISTOGRAM = "histogram"  # ``name`` without ``_bucket``/``_sum``/``_count``; no samples


Labels = tuple[tuple[str, str], ...]


@dataclass(frozen=True, slots=True)
class Sample:
    labels: Labels
    value: float


@dataclass(frozen=True, slots=True)
class HistogramValue:
    """A histogram the daemon measured (docs/api.md "status" ``histograms``): cumulative
    counts at each upper bound ``le`` (seconds), the sum in seconds and the count (``+Inf``)."""

    buckets: tuple[tuple[float, int], ...]
    sum: float
    count: int


@dataclass(frozen=True, slots=True)
class Family:
    """One metric family: its name, type, help text and samples (a histogram family: its
    ``histogram`` instead)."""

    name: str
    kind: Kind
    help: str
    samples: tuple[Sample, ...] = ()
    histogram: HistogramValue | None = None


@dataclass(frozen=True, slots=True)
class Spec:
    """A family the exporter may serve: its name as scraped, its type, its labels."""

    name: str
    kind: Kind
    help: str
    labels: tuple[str, ...] = ()

    @property
    def scraped(self) -> str:
        """The sample name Prometheus stores (``_total`` and ``_info`` added)."""
        return self.scraped_names[0]

    @property
    def scraped_names(self) -> tuple[str, ...]:
        """Every sample name Prometheus stores for this family (a histogram has three)."""
        if self.kind is Kind.HISTOGRAM:
            return tuple(self.name + suffix for suffix in ("_bucket", "_sum", "_count"))
        suffix = {Kind.COUNTER: "_total", Kind.INFO: "_info", Kind.GAUGE: ""}[self.kind]
        return (self.name + suffix,)


def _specs(*specs: Spec) -> dict[str, Spec]:
    return {spec.name: spec for spec in specs}


G, C, INFO, H = Kind.GAUGE, Kind.COUNTER, Kind.INFO, Kind.HISTOGRAM
HISTOGRAMS: Final = {
    "vsc_heartbeat_period_seconds": "srcs_vsc_heartbeat_period_seconds",
    "user_heartbeat_period_seconds": "srcs_user_heartbeat_period_seconds",
    "stop_to_off_seconds": "srcs_stop_to_off_seconds",
}
"""The daemon's histograms (``status``'s ``daemon.histograms``) and their metric names."""
PROOFTEST_RESULTS: Final = {Counted.PROOFTEST_PASSED: "passed", Counted.PROOFTEST_FAILED: "failed"}
"""``srcs_prooftests_total``'s ``result`` label: both always served, from 0, so that an alert
on its increase sees the first failure (a series that appears at 1 has no increase)."""
SPECS: Final = _specs(
    Spec("srcs_up", G, "1 while the exporter is connected to srcsd's API socket, else 0"),
    Spec("srcs_daemon", INFO, "the daemon this exporter reads (from its status reply)", ("robot",)),
    Spec("srcs_state", G, "1 for the supervisor's current state, 0 for the others", ("state",)),
    Spec(
        "srcs_cause_active",
        G,
        "1 while the cause's condition holds (every cause seen since the exporter started)",
        ("cause", "severity"),
    ),
    Spec(
        "srcs_cause_latched",
        G,
        "1 while a stop cause waits for a re-arm (SR-4)",
        ("cause", "severity"),
    ),
    Spec("srcs_output_on", G, "1 while the output is on", ("output",)),
    Spec("srcs_outputs_not_acquired", G, "outputs the daemon could not acquire yet"),
    Spec("srcs_link_up", G, "1 while the daemon's link to the VSC is open"),
    Spec(
        "srcs_estop_available",
        G,
        "1 while the remote e-stop is available: VSC heard, remote linked, battery reported "
        "and not low, watchdog proven (SR-8.11; from the last status reply)",
    ),
    Spec(
        "srcs_test_last_pass_age_seconds",
        G,
        "seconds since the periodic test last passed (stoptest: srcsctl stoptest; prooftest: "
        "the VSC's watchdog), from the record; absent when it never passed (SR-12.2)",
        ("test",),
    ),
    Spec(
        "srcs_test_overdue",
        G,
        "1 while the periodic test is past its [maintenance] interval, or never passed; "
        "a warning, the robot is not stopped for it (SR-12.2)",
        ("test",),
    ),
    Spec("srcs_link_opens", C, "times the daemon opened its link to the VSC (since it started)"),
    Spec("srcs_link_open_failures", C, "failed attempts to open the link (since srcsd started)"),
    Spec("srcs_messages", C, "valid messages from the VSC (since srcsd started)"),
    Spec(
        "srcs_rejections",
        C,
        "input from the VSC the decoder rejected, by reason (since srcsd started)",
        ("reason",),
    ),
    Spec("srcs_record_errors", C, "stop records that could not be written (since srcsd started)"),
    Spec("srcs_internal_faults", C, "internal faults the loop caught (since srcsd started)"),
    Spec(
        "srcs_memory_locked",
        G,
        "1 when srcsd's start locked its memory, 0 when it runs without the lock (refused, or "
        '[realtime] lock_memory = "off"): its loop may then wait on a page fault (SR-9.6)',
    ),
    Spec(
        "srcs_vsc_heartbeat_period_seconds",
        H,
        "time between successive VSC heartbeats as srcsd's loop read them (since it started)",
    ),
    Spec(
        "srcs_user_heartbeat_period_seconds",
        H,
        "time between successive user heartbeats srcsd sent to the VSC (since it started)",
    ),
    Spec(
        "srcs_stop_to_off_seconds",
        H,
        "from the input or deadline that stopped the robot to its outputs written off",
    ),
    Spec("srcs_remote_battery_percent", G, "the remote's battery level (10 % steps)"),
    Spec("srcs_remote_battery_charging", G, "1 while the remote's battery charges"),
    Spec(
        "srcs_remote_link_strength",
        G,
        "the radio link's strength, 0 low, 1 medium, 2 high, as seen by the VSC or the remote",
        ("seen_by",),
    ),
    Spec(
        "srcs_remote_rssi",
        G,
        "the raw RSSI byte as seen by the VSC or the remote (the manual reserves it)",
        ("seen_by",),
    ),
    Spec("srcs_remote_status_age_seconds", G, "time since the last remote-status message"),
    Spec(
        "srcs_stops",
        C,
        "stops (RUN or HOLD to STOPPED), by each cause of their trigger: the stop causes "
        "raised in that change, never a follow-up raised while STOPPED (seen by this exporter)",
        ("cause",),
    ),
    Spec("srcs_startups", C, "daemon start-ups (records that raised startup; seen here)"),
    Spec(
        "srcs_prooftests",
        C,
        "proof tests of the VSC's watchdog by result, passed or failed (seen here; SR-5.3)",
        ("result",),
    ),
    Spec(
        "srcs_rearms",
        C,
        "re-arms out of STOPPED, by each latched cause they released and the re-arm's kind",
        ("cause", "kind"),
    ),
    Spec("srcs_rearm_refusals", C, "re-arms asked for and refused (seen by this exporter)"),
    Spec("srcs_causes_raised", C, "causes raised, stop or hold, in any state", ("cause",)),
    Spec(
        "srcs_state_transitions",
        C,
        "changes of state (seen by this exporter)",
        ("from_state", "to_state"),
    ),
    Spec("srcs_records_seen", C, "stop records this exporter received"),
    Spec(
        "srcs_records_missed",
        C,
        "stop records this exporter did not receive (gaps in their sequence numbers)",
    ),
    Spec("srcs_record_last_seq", G, "the sequence number of the newest record received"),
    Spec("srcs_api_connects", C, "connections this exporter made to srcsd's API socket"),
    Spec(
        "srcs_rt_judge_on",
        G,
        "1 while the kernel's rtapp monitors judge srcsd's real time (srcs-rv.service, "
        "SR-9.9); absent on a robot without the judge",
    ),
    Spec(
        "srcs_rt_violations",
        C,
        "violations the kernel's rtapp monitors found in srcsd's threads, by monitor and "
        "thread (srcsd: the loop; other: past the watch's cap of series; SR-9.9)",
        ("monitor", "thread"),
    ),
    Spec(
        "srcs_rt_last_violation_timestamp_seconds",
        G,
        "when the judge last found a violation by srcsd's threads (Unix time; SR-9.9)",
    ),
    Spec("srcs_rt_lost_events", C, "events the judge's trace ring overwrote unread (SR-9.9)"),
    Spec(
        "srcs_rt_unreadable_lines",
        C,
        "lines of the judge's trace srcs-rv could not read (SR-9.9)",
    ),
    Spec(
        "srcs_rt_file_refusals",
        C,
        "reads of srcs-rv's file this exporter refused, by reason (seen here; SR-9.9)",
        ("reason",),
    ),
    Spec("srcs_daemon_restarts", C, "times srcsd's pid changed between two connections"),
)
"""Every family the exporter serves (docs/fleet.md lists them; the dashboard test checks its
expressions against this table)."""


@dataclass(frozen=True, slots=True)
class CauseFlags:
    severity: str
    active: bool
    latched: bool


@dataclass(frozen=True, slots=True)
class DaemonInfo:
    """The ``daemon`` object of a ``status`` reply, the fields this exporter reads."""

    robot: str | None = None
    pid: int | None = None
    link_open: bool | None = None
    link_opens: int | None = None
    link_open_failures: int | None = None
    messages: int | None = None
    rejections: tuple[tuple[str, int], ...] = ()
    record_errors: int | None = None
    internal_faults: int | None = None
    memory_locked: bool | None = None
    outputs_not_acquired: int | None = None
    histograms: tuple[tuple[str, HistogramValue], ...] = ()  # by metric name
    tests: tuple[tuple[str, float | None, bool], ...] = ()  # test, age, overdue


@dataclass(frozen=True, slots=True)
class RemoteSeen:
    """What the exporter keeps of a remote-status push (the VSC's ``RemoteStatus``, manual
    §8.3.4) and when it arrived (the caller's clock)."""

    received_ns: int
    battery_level: int | None
    battery_charging: int | None
    strength_vsc: int | None
    strength_src: int | None
    rssi_vsc: int | None
    rssi_src: int | None


@dataclass
class _Labels:
    """The values one label has taken, capped at :data:`MAX_LABEL_VALUES`."""

    seen: dict[str, None] = field(default_factory=dict)

    def admit(self, value: str) -> str:
        if value in self.seen:
            return value
        if len(self.seen) >= MAX_LABEL_VALUES:
            return OVERFLOW
        self.seen[value] = None
        return value


def _histogram(histogram: HistogramStatus | None) -> HistogramValue | None:
    """A histogram of the ``status`` reply, or ``None`` if it is not one a Prometheus
    histogram can be: finite bounds that increase, cumulative counts that do not decrease,
    one per bound, none above ``count``."""
    if histogram is None or len(histogram.le) != len(histogram.counts):
        return None
    buckets: list[tuple[float, int]] = []
    for bound, cumulative in zip(histogram.le, histogram.counts, strict=True):
        if not math.isfinite(bound) or cumulative < 0:
            return None
        if buckets and (bound <= buckets[-1][0] or cumulative < buckets[-1][1]):
            return None
        buckets.append((float(bound), cumulative))
    if buckets and buckets[-1][1] > histogram.count:
        return None
    return HistogramValue(tuple(buckets), float(histogram.sum), histogram.count)


def _tests(schedule: Maintenance | None) -> tuple[tuple[str, float | None, bool], ...]:
    """The periodic tests ``status`` reports (``daemon.maintenance``, SR-12.2): the typed
    value names a fixed set, so the ``test`` label cannot grow."""
    if schedule is None:
        return ()
    return tuple((test, due.last_pass_age_s, due.overdue) for test, due in schedule.tests())


class ExporterModel:
    """The exporter's knowledge: fed with :meth:`connected`, :meth:`status`, :meth:`push` and
    :meth:`disconnected`; read with :meth:`families`. Never raises on the daemon's data."""

    def __init__(self) -> None:
        self.up = False
        # The daemon's values: valid while connected, dropped when the connection ends.
        self.state: str | None = None
        self.state_ns: int | None = None
        self.causes: dict[str, CauseFlags] = {}
        self.outputs: dict[str, bool] = {}
        self.daemon: DaemonInfo | None = None
        self.remote: RemoteSeen | None = None
        self.estop_available: bool | None = None
        # The exporter's own: for the life of the process.
        self.known_causes: dict[str, str] = {}  # every cause seen: its severity
        self.stops: dict[str, int] = {}
        self.rearms: dict[tuple[str, str], int] = {}
        self.raised: dict[str, int] = {}
        self.transitions: dict[tuple[str, str], int] = {}
        self.startups = 0
        self.prooftests = dict.fromkeys(PROOFTEST_RESULTS.values(), 0)
        self._previous: StopRecord | None = None  # for a record without ``changes``
        self.rearm_refusals = 0
        self.records_seen = 0
        self.records_missed = 0
        self.last_seq: int | None = None
        self.connects = 0
        self.daemon_restarts = 0
        self._last_pid: int | None = None
        self._cause_labels = _Labels()
        self._reason_labels = _Labels()
        self._output_labels = _Labels()
        # The kernel's judge, from srcs-rv's file at each scrape (SR-9.9): not the daemon's.
        self.judge: JudgeTotals | None = None
        self.judge_refusals: dict[str, int] = {}

    # ------------------------------------------------------------------ feeding

    def connected(self) -> None:
        """A new connection to the API socket (before its first reply)."""
        self.up = True
        self.connects += 1

    def disconnected(self) -> None:
        """The connection ended: forget everything only a live connection can vouch for."""
        self.up = False
        self.state = None
        self.state_ns = None
        self.causes = {}
        self.outputs = {}
        self.daemon = None
        self.remote = None
        self.estop_available = None

    def status(self, reply: StatusReply) -> None:
        """A ``status`` reply: the state, ``estop_available`` and the ``daemon`` object."""
        self._state(reply.report)
        available = reply.estop_available
        self.estop_available = None if available is None else available.available
        self._daemon(reply.daemon)

    def push(self, push: Push, now_ns: int) -> None:
        """One push; ``now_ns`` is when it arrived (for the remote status's age)."""
        if isinstance(push, StatePush):
            self._state(push.report)
        elif isinstance(push, RecordPush):
            self._record(push.record)
        elif isinstance(push, RemoteStatusPush):
            self._remote(push.message, now_ns)
        # else: a topic this exporter did not ask for, or a newer one

    def _state(self, report: StateReport) -> None:
        # A push read after a newer status reply (the client keeps pushes that arrive while
        # it waits for a reply) must not turn the state back.
        if self.state_ns is not None and report.mono_ns < self.state_ns:
            return
        self.state, self.state_ns = report.state.name, report.mono_ns
        causes: dict[str, CauseFlags] = {}
        for cause in report.causes:
            name = self._cause_label(cause.name.name, cause.severity.value)
            flags = causes.get(name)
            causes[name] = CauseFlags(
                cause.severity.value,
                cause.active or (flags is not None and flags.active),
                cause.latched or (flags is not None and flags.latched),
            )
        self.causes = causes
        self.outputs = {
            self._output_labels.admit(name): level for name, level in report.outputs.items()
        }

    def _cause_label(self, name: str, severity: str | None = None) -> str:
        label = self._cause_labels.admit(name)
        if severity is not None:
            self.known_causes.setdefault(label, severity)
        return label

    def _daemon(self, daemon: DaemonStatus) -> None:
        loop = daemon.loop
        if self._last_pid is not None and loop.pid != self._last_pid:
            self.daemon_restarts += 1
        self._last_pid = loop.pid
        rejections: dict[str, int] = {}
        for reason, count in loop.rejections.items():
            label = self._reason_labels.admit(reason)
            rejections[label] = rejections.get(label, 0) + count
        histograms: list[tuple[str, HistogramValue]] = []
        for key, metric in HISTOGRAMS.items():
            parsed = _histogram(loop.histograms.get(key))
            if parsed is not None:
                histograms.append((metric, parsed))
        self.daemon = DaemonInfo(
            robot=daemon.robot,
            pid=loop.pid,
            link_open=loop.link.open,
            link_opens=loop.link.opens,
            link_open_failures=loop.link.open_failures,
            messages=loop.messages,
            rejections=tuple(sorted(rejections.items())),
            record_errors=loop.record_errors,
            internal_faults=loop.internal_faults,
            memory_locked=loop.memory_locked,
            outputs_not_acquired=len(loop.outputs_not_acquired),
            histograms=tuple(histograms),
            tests=_tests(loop.maintenance),
        )

    def _record(self, record: StopRecord) -> None:
        """Count one stop record (docs/record.md), reconciled by its sequence number."""
        seq = record.seq
        if self.last_seq is not None and seq > self.last_seq + 1:
            # Written while this exporter was not connected (or not subscribed yet).
            self.records_missed += seq - self.last_seq - 1
        # A number at or below the last one: the daemon's sequence started again (a new
        # record file); it is no repeat, since a push is sent once, to live subscribers.
        self.last_seq = seq
        self.records_seen += 1
        for cause in record.causes:
            self._cause_label(cause.name.name, cause.severity.value)
        changes = record.changes or ()
        raised = [c.name.name for c in changes if c.change is ChangeKind.RAISED]
        released = [c.name.name for c in changes if c.change is ChangeKind.RELEASED]
        for name in raised:
            label = self._cause_label(name)
            self.raised[label] = self.raised.get(label, 0) + 1
        before, after = record.from_state, record.to_state
        if before is not after:
            key = (before.name, after.name)
            self.transitions[key] = self.transitions.get(key, 0) + 1
        # What the record counts as, by the fleet's one meaning (SR-13.9): a stop by its
        # trigger only, never by a follow-up the supervisor raised while STOPPED.
        previous, self._previous = self._previous, record
        what = counted(record, previous)
        if what is Counted.STOP:
            for name in trigger(record, previous):
                label = self._cause_label(name)
                self.stops[label] = self.stops.get(label, 0) + 1
        elif what is Counted.REARM:
            kind = record.rearm.kind.value if record.rearm is not None else "unknown"
            for name in released or ["unknown"]:
                pair = (self._cause_label(name), kind)
                self.rearms[pair] = self.rearms.get(pair, 0) + 1
        elif what is Counted.STARTUP:
            self.startups += 1
        elif what in PROOFTEST_RESULTS:
            self.prooftests[PROOFTEST_RESULTS[what]] += 1
        if record.kind is RecordKind.REARM_REFUSED:
            self.rearm_refusals += 1

    def _remote(self, message: RemoteStatusReport, now_ns: int) -> None:
        self.remote = RemoteSeen(
            received_ns=now_ns,
            battery_level=message.battery_level,
            battery_charging=message.battery_charging,
            strength_vsc=message.connection_strength_vsc,
            strength_src=message.connection_strength_src,
            rssi_vsc=message.rssi_vsc,
            rssi_src=message.rssi_src,
        )

    def judge_read(self, totals: JudgeTotals | None, refused: str | None = None) -> None:
        """srcs-rv's file as this scrape read it: its totals, ``None`` when there is none (no
        judge on this robot: no metric), or ``refused`` (the reason) when it was no file the
        exporter takes: counted, and its last good totals are not served."""
        self.judge = totals
        if refused is not None:
            self.judge_refusals[refused] = self.judge_refusals.get(refused, 0) + 1

    # ------------------------------------------------------------------ reading

    def families(self, now_ns: int) -> list[Family]:
        """Every family with its samples now (``now_ns`` on the clock :meth:`push` was given)."""
        out: dict[str, list[Sample]] = {name: [] for name in SPECS}

        def put(name: str, value: float | None, **labels: str) -> None:
            if value is not None:
                out[name].append(Sample(tuple(labels.items()), float(value)))

        put("srcs_up", 1 if self.up else 0)
        self._own(put)
        self._judge_values(put)
        if self.up:
            self._daemon_values(put)
            self._remote_values(put, now_ns)
        histograms = dict(self.daemon.histograms) if self.up and self.daemon else {}
        return [
            Family(
                spec.name, spec.kind, spec.help, tuple(out[spec.name]), histograms.get(spec.name)
            )
            for spec in SPECS.values()
        ]

    def _own(self, put: _Put) -> None:
        for cause, count in sorted(self.stops.items()):
            put("srcs_stops", count, cause=cause)
        for (cause, kind), count in sorted(self.rearms.items()):
            put("srcs_rearms", count, cause=cause, kind=kind)
        for cause, count in sorted(self.raised.items()):
            put("srcs_causes_raised", count, cause=cause)
        for (before, after), count in sorted(self.transitions.items()):
            put("srcs_state_transitions", count, from_state=before, to_state=after)
        put("srcs_startups", self.startups)
        for result, count in self.prooftests.items():
            put("srcs_prooftests", count, result=result)
        put("srcs_rearm_refusals", self.rearm_refusals)
        put("srcs_records_seen", self.records_seen)
        put("srcs_records_missed", self.records_missed)
        put("srcs_record_last_seq", self.last_seq)
        put("srcs_api_connects", self.connects)
        put("srcs_daemon_restarts", self.daemon_restarts)

    def _judge_values(self, put: _Put) -> None:
        for reason, count in sorted(self.judge_refusals.items()):
            put("srcs_rt_file_refusals", count, reason=reason)
        judge = self.judge
        if judge is None:
            return
        put("srcs_rt_judge_on", judge.judge_on)
        for monitor, thread, count in judge.violations:
            put("srcs_rt_violations", count, monitor=monitor, thread=thread)
        for monitor, count in judge.overflow:
            put("srcs_rt_violations", count, monitor=monitor, thread=OVERFLOW)
        put("srcs_rt_last_violation_timestamp_seconds", judge.last_violation_unix)
        put("srcs_rt_lost_events", judge.lost_events)
        put("srcs_rt_unreadable_lines", judge.unreadable_lines)

    def _daemon_values(self, put: _Put) -> None:
        if self.state is not None:
            for state in STATES:
                put("srcs_state", 1 if state == self.state else 0, state=state)
            for cause, severity in sorted(self.known_causes.items()):
                flags = self.causes.get(cause)
                active = flags is not None and flags.active
                latched = flags is not None and flags.latched
                put("srcs_cause_active", active, cause=cause, severity=severity)
                put("srcs_cause_latched", latched, cause=cause, severity=severity)
            for output, on in sorted(self.outputs.items()):
                put("srcs_output_on", on, output=output)
        put("srcs_estop_available", self.estop_available)
        daemon = self.daemon
        if daemon is None:
            return
        if daemon.robot is not None:
            put("srcs_daemon", 1, robot=daemon.robot)
        put("srcs_link_up", daemon.link_open)
        put("srcs_link_opens", daemon.link_opens)
        put("srcs_link_open_failures", daemon.link_open_failures)
        put("srcs_messages", daemon.messages)
        for reason, count in daemon.rejections:
            put("srcs_rejections", count, reason=reason)
        put("srcs_record_errors", daemon.record_errors)
        put("srcs_internal_faults", daemon.internal_faults)
        put("srcs_memory_locked", daemon.memory_locked)
        put("srcs_outputs_not_acquired", daemon.outputs_not_acquired)
        for test, age, overdue in daemon.tests:
            put("srcs_test_last_pass_age_seconds", age, test=test)
            put("srcs_test_overdue", overdue, test=test)

    def _remote_values(self, put: _Put, now_ns: int) -> None:
        remote = self.remote
        if remote is None or now_ns - remote.received_ns > REMOTE_STALE_NS:
            return
        put("srcs_remote_battery_percent", remote.battery_level)
        put("srcs_remote_battery_charging", remote.battery_charging)
        put("srcs_remote_link_strength", remote.strength_vsc, seen_by="vsc")
        put("srcs_remote_link_strength", remote.strength_src, seen_by="remote")
        put("srcs_remote_rssi", remote.rssi_vsc, seen_by="vsc")
        put("srcs_remote_rssi", remote.rssi_src, seen_by="remote")
        put("srcs_remote_status_age_seconds", max(0, now_ns - remote.received_ns) / NS_PER_S)


class _Put(Protocol):
    """The signature of ``families``' sample writer (for the type checker)."""

    def __call__(self, name: str, value: float | None, **labels: str) -> None: ...


def scraped_names() -> Iterable[str]:
    """Every sample name a scrape may show (``_total``, ``_info`` and a histogram's
    ``_bucket``, ``_sum`` and ``_count`` included)."""
    return (name for spec in SPECS.values() for name in spec.scraped_names)
