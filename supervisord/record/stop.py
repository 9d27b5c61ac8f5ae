"""The stop record as a typed value (docs/record.md "What a record holds"): what the daemon
writes to the record file, the journal and the API's ``record`` push, and what every reader
(``srcsctl log``, ``srcsctl replay``, the exporter, the ROS 2 bridge) reads back.

Typed and frozen, each field declared once: :meth:`~supervisord.wire.Wire.json` writes the
record's object and :meth:`~supervisord.wire.Wire.read` reads it (unknown fields are
ignored; a field of the wrong type is a :class:`~supervisord.wire.WireError`).
:mod:`supervisord.record.format` builds it from the safety core's record.

Pure and small: the client library imports it, so it imports nothing of the safety core, the
daemon or the API (docs/ros2.md "The client library"); its words are the shared vocabulary's.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any

from supervisord.compat import StrEnum
from supervisord.vocabulary import (
    CauseKind,
    CauseName,
    ChangeKind,
    Phase,
    ProofTestFailure,
    ProofTestPolicy,
    RearmKind,
    Severity,
    State,
    UnknownCauseKind,
    read_cause,
)
from supervisord.wire import Fields, Wire, WireError, wire

__all__ = [
    "Caller",
    "Cause",
    "CauseName",
    "Change",
    "OutputOffReport",
    "ProofTestResult",
    "ProofTestStatus",
    "Rearm",
    "RecordKind",
    "StopRecord",
    "StopStepReport",
    "StopTestReport",
    "read_record",
    "read_written",
]


def _cause_name(f: Fields, key: str) -> CauseName:
    """A cause's name, a kind this client does not know kept as written (docs/api.md "Cause
    kinds a client does not know"); text that names nothing is a ``WireError``."""
    text = f.text(key)
    try:
        return read_cause(text)
    except ValueError as error:
        raise f.wrong(key, f"a cause name ({error})", text) from None


class RecordKind(StrEnum):
    """What a record reports, as its optional ``kind`` field says (absent: a state change)."""

    STATE_CHANGE = "state_change"
    """The state changed (a stop is a change into STOPPED)."""
    CAUSE_RAISED = "cause_raised"
    """A stop or hold cause became active."""
    CAUSE_CLEARED = "cause_cleared"
    """A cause's condition cleared."""
    REARM_REFUSED = "rearm_refused"
    """A re-arm was asked for and refused."""
    COMMISSIONED = "commissioned"
    """Key 85 was written to the VSC (``srcsctl commission``)."""
    PROOFTEST = "prooftest"
    """A proof test of the VSC's watchdog finished (SR-5.3, docs/safety.md "The proof test")."""
    HELLO_REFUSED = "hello_refused"
    """A hello as a client bound to another user was refused (SR-8)."""
    STOPTEST = "stoptest"
    """A field stop test finished (SR-12.1, ``srcsctl stoptest``)."""


@dataclass(frozen=True, slots=True, kw_only=True)
class Cause(Wire):
    """One cause, as ``status``, ``state`` pushes and stop records show it (docs/record.md):
    its name (a kind, and a subject for some), ``severity``, ``active``, ``latched``, the
    monotonic times, and ``details`` (text values, e.g. ``{"sources": "remote"}``)."""

    name: CauseName = wire(decode=_cause_name)
    severity: Severity  # stop (latches) or hold
    active: bool
    latched: bool
    raised_ns: int | None
    cleared_ns: int | None
    details: Mapping[str, str] = wire(absent={}, default_factory=dict)

    @property
    def kind(self) -> CauseKind | UnknownCauseKind:
        """The cause's kind; one this client does not know is kept as its text."""
        return self.name.kind

    @property
    def held(self) -> bool:
        """Cleared, and held only by its latch until a re-arm (SR-4)."""
        return self.latched and not self.active


@dataclass(frozen=True, slots=True, kw_only=True)
class ProofTestResult(Wire):
    """A finished proof test of the VSC's watchdog (docs/safety.md "The proof test")."""

    result: str  # "passed" or "failed"
    failure: str | None  # why it failed, by name (e.g. "no_trip")
    trip_ms: int | None
    cleared: str | None  # "by_itself" or "held"
    cleared_ms: int | None
    text: str = wire(absent="", default="")

    @property
    def passed(self) -> bool:
        return self.result == "passed"

    @property
    def failed_for(self) -> ProofTestFailure | str | None:
        """Why it failed: the vocabulary's failure its ``failure`` names (``late``), or the
        text as written where this client knows no such failure."""
        if self.failure is None:
            return None
        return ProofTestFailure.__members__.get(self.failure.upper(), self.failure)

    @property
    def cleared_by_itself(self) -> bool:
        """The VSC cleared the user bits by itself once the heartbeat resumed (not held)."""
        return self.cleared == "by_itself"


@dataclass(frozen=True, slots=True, kw_only=True)
class ProofTestStatus(Wire):
    """Where the proof test is: its ``policy`` and ``phase``, and the ``last`` result."""

    policy: ProofTestPolicy
    phase: Phase
    last: ProofTestResult | None

    @property
    def proven(self) -> bool:
        """Nothing stands in for the watchdog's proof: the test passed, or there is none."""
        return self.policy is ProofTestPolicy.OFF or self.phase is Phase.PASSED


@dataclass(frozen=True, slots=True, kw_only=True)
class Caller(Wire):
    """Who asked (docs/api.md "Who may do what"): the peer's uid, pid, login name, admin."""

    uid: int
    pid: int
    name: str
    admin: bool


@dataclass(frozen=True, slots=True, kw_only=True)
class Change(Wire):
    """One cause's change in a record: ``raised``, ``updated``, ``cleared`` or ``released``."""

    name: CauseName = wire(decode=_cause_name)
    change: ChangeKind


@dataclass(frozen=True, slots=True, kw_only=True)
class Rearm(Wire):
    """How a stop was re-armed (``takeover``, ``local_reset``) and who asked."""

    kind: RearmKind
    caller: Caller | None = wire(omit_none=True, default=None)


@dataclass(frozen=True, slots=True, kw_only=True)
class OutputOffReport(Wire):
    """One output in one press of a field stop test (SR-12.1): ``off_ns`` from the e-stop's
    frame to its verified off (``None``: not off), ``off_ms`` the same in ms, its category-1
    ``off_delay_ms`` (SR-1.4) and whether it passed."""

    name: str
    off_ns: int | None
    off_ms: float | None
    off_delay_ms: int = wire(absent=0)
    passed: bool


@dataclass(frozen=True, slots=True, kw_only=True)
class StopStepReport(Wire):
    """One press of a field stop test: its ``source`` (``remote``, ``wired``), the stop record
    it made (``seq``) and that record's ``mono_ns`` (``stop_ns``), and each output."""

    source: str
    seq: int
    stop_ns: int
    passed: bool
    outputs: tuple[OutputOffReport, ...]


@dataclass(frozen=True, slots=True, kw_only=True)
class StopTestReport(Wire):
    """A finished field stop test (SR-12.1; docs/srcsctl.md "The field stop test"): the
    ``stoptest`` object of its record and of the ``stoptest`` reply."""

    result: str  # "passed" or "failed"
    limit_ms: int
    steps: tuple[StopStepReport, ...]
    text: str = wire(absent="", default="")

    @property
    def passed(self) -> bool:
        return self.result == "passed"


@dataclass(frozen=True, slots=True, kw_only=True)
class StopRecord(Wire):
    """One record (docs/record.md): ``from_state`` and ``to_state`` are ``from`` and ``to`` on
    the wire; ``trigger`` stays JSON (its fields depend on its ``event``). The optional fields
    are absent on the wire when ``None``."""

    seq: int
    mono_ns: int
    utc: str
    kind: RecordKind | None = wire(omit_none=True, default=None)
    from_state: State = wire(name="from", by_name=True)
    to_state: State = wire(name="to", by_name=True)
    causes: tuple[Cause, ...]
    changes: tuple[Change, ...] | None = wire(omit_none=True, default=None)
    trigger: dict[str, Any]
    reason: str | None = wire(omit_none=True, default=None)
    prooftest: ProofTestResult | None = wire(omit_none=True, default=None)
    stoptest: StopTestReport | None = wire(omit_none=True, default=None)
    rearm: Rearm | None = wire(omit_none=True, default=None)
    version: str | None = wire(omit_none=True, default=None)

    @property
    def record_kind(self) -> RecordKind:
        """``kind``, or a state change where a record leaves it out (docs/record.md)."""
        return self.kind or RecordKind.STATE_CHANGE

    @property
    def event(self) -> str | None:
        """The trigger's ``event`` name (``client_estop``, ``tick`` ...), if it says one."""
        event = self.trigger.get("event")
        return event if isinstance(event, str) else None

    @property
    def is_stop(self) -> bool:
        """A change into STOPPED (SR-7: the records a stop is counted from)."""
        return self.to_state is State.STOPPED and self.from_state is not State.STOPPED

    def cause(self, kind: CauseKind) -> Cause | None:
        """The record's first cause of ``kind``, if it names one."""
        return next((c for c in self.causes if c.name.kind is kind), None)


def read_record(obj: object, where: str = "record") -> StopRecord:
    """The stop record in one JSON object, as a file, the journal or a push holds it; raises
    :class:`~supervisord.wire.WireError` for one that is not (docs/record.md)."""
    return StopRecord.read(Fields(obj, where))


def read_written(obj: Mapping[str, Any]) -> StopRecord | None:
    """A line the record store took (docs/record.md "What a record holds"), typed, for showing
    it: :func:`read_record`'s value where the line is a typed record. A line another tool wrote
    with fewer fields is read leniently, what it lacks or holds otherwise kept as written: a
    ``trigger`` as text is the trigger's ``event``; a cause without ``active`` or ``latched``
    is neither, without ``severity`` its kind's (one this client does not know: a hold),
    without its times or ``details`` has none, and a detail that is not text is its text.
    ``None`` for a line that still is no typed record (a state, kind or change this client
    does not know): it is shown from the store's own fields."""
    try:
        return read_record(obj)
    except WireError:
        pass
    trigger = obj.get("trigger")
    causes = obj.get("causes")
    loose = {
        **obj,
        "trigger": trigger if isinstance(trigger, dict) else {"event": str(trigger)},
        "causes": [_loose_cause(c) for c in causes] if isinstance(causes, list) else causes,
    }
    try:
        return read_record(loose)
    except WireError:
        return None


def _loose_cause(cause: object) -> object:
    """One cause of a line :func:`read_written` reads leniently, what it lacks filled in."""
    if not isinstance(cause, Mapping) or not isinstance(cause.get("name"), str):
        return cause
    try:
        kind = read_cause(cause["name"]).kind
    except ValueError:
        return cause
    details = cause.get("details")
    severity = kind.severity if isinstance(kind, CauseKind) else Severity.HOLD
    return {
        "severity": severity.value,
        "raised_ns": None,
        "cleared_ns": None,
        **cause,
        "active": bool(cause.get("active")),
        "latched": bool(cause.get("latched")),
        "details": (
            {str(k): str(v) for k, v in details.items()} if isinstance(details, Mapping) else {}
        ),
    }
