"""What a record counts as, the one meaning of "a stop" for a robot and its fleet (SR-13.9,
docs/record.md "What counts as a stop").

A **stop**: the robot was in RUN or HOLD and a stop cause took it to STOPPED. Its
**trigger** is the stop cause(s) raised in that change; never a cause raised afterwards while
STOPPED, such as the supervisor's own user e-stop that the VSC reports back
(``vsc_estop (sources=user)`` after ``client_lost:motion``). A **start-up** (the record that
raised ``startup``), a **proof test** (passed or failed) and a **re-arm** (STOPPED to RUN or
HOLD) are told apart and counted on their own; nothing else counts.

``srcsctl fleet --summary``, ``srcsctl log --summary`` (through :class:`Tally`), the
exporter's ``srcs_stops_total``, ``srcs_startups_total``, ``srcs_prooftests_total`` and
``srcs_rearms_total`` (through :func:`counted` and :func:`trigger`) and the alert rules built
on them all count by this module, so that the fleet's views cannot disagree about a stop.

Pure and small: it imports the typed record and the vocabulary only (SR-13.6: a collector
loads it without the safety core).
"""

from __future__ import annotations

from collections.abc import Iterable
from dataclasses import dataclass, field
from typing import Final

from supervisord.record.stop import Cause, RecordKind, StopRecord
from supervisord.vocabulary import CauseKind, CauseName, ChangeKind, Counted, Severity, State

UNKNOWN_TRIGGER: Final = "unknown"
"""The trigger of a stop whose record names no stop cause (none is ever written: every stop
has one, SR-2; a record from elsewhere may lack it). It is still counted."""


def changes(record: StopRecord, previous: StopRecord | None) -> list[tuple[ChangeKind, CauseName]]:
    """``(change, cause name)`` pairs: the record's ``changes``, or for a record without them
    the difference from ``previous`` (raised: new and active; cleared: active before, not
    now)."""
    if record.changes:
        return [(c.change, c.name) for c in record.changes]
    if previous is None or record.changes is not None:
        return []
    before = _by_name(previous.causes)
    now = _by_name(record.causes)
    found = [(ChangeKind.RAISED, n) for n, c in now.items() if c.active and n not in before]
    found += [
        (ChangeKind.CLEARED, n)
        for n, c in before.items()
        if c.active and not (n in now and now[n].active)
    ]
    return found


def _by_name(causes: Iterable[Cause]) -> dict[CauseName, Cause]:
    return {c.name: c for c in causes}


def counted(record: StopRecord, previous: StopRecord | None = None) -> Counted | None:
    """What ``record`` counts as (``previous``: the robot's record before it, for a record
    written without ``changes``); ``None`` for a record that counts as nothing."""
    if record.record_kind is RecordKind.PROOFTEST:
        passed = record.prooftest is not None and record.prooftest.passed
        return Counted.PROOFTEST_PASSED if passed else Counted.PROOFTEST_FAILED
    before, after = record.from_state, record.to_state
    if before is not State.STOPPED and after is State.STOPPED:
        return Counted.STOP
    if before is State.STOPPED and after is not State.STOPPED:
        return Counted.REARM
    if any(n.kind is CauseKind.STARTUP for n in _raised(record, previous)):
        return Counted.STARTUP
    return None


def _raised(record: StopRecord, previous: StopRecord | None) -> list[CauseName]:
    """The causes ``record`` raised: its ``changes`` say; a record written without them
    raised those it holds (active or latched) that ``previous`` did not, a momentary one
    (``startup``, ``shutdown``) included, which is latched only by the time it is written."""
    if record.changes is not None:
        return [n for change, n in changes(record, previous) if change is ChangeKind.RAISED]
    held = set() if previous is None else {c.name for c in previous.causes if c.active or c.latched}
    return [c.name for c in record.causes if (c.active or c.latched) and c.name not in held]


def trigger(record: StopRecord, previous: StopRecord | None = None) -> tuple[str, ...]:
    """A stop's trigger: the names of the stop causes raised in it (:func:`_raised`), else
    :data:`UNKNOWN_TRIGGER`; ``()`` for a record that is no stop."""
    if counted(record, previous) is not Counted.STOP:
        return ()
    severity = {c.name: c.severity for c in record.causes}
    raised = [n for n in _raised(record, previous) if _stop(severity.get(n), n)]
    return tuple(str(name) for name in raised) or (UNKNOWN_TRIGGER,)


def _stop(severity: Severity | None, name: CauseName) -> bool:
    """Whether a raised cause is a stop cause: by the record's own word for it, or, where the
    record does not list it, by its kind (one this reader does not know: no stop)."""
    if severity is not None:
        return severity is Severity.STOP
    kind = name.kind
    return isinstance(kind, CauseKind) and kind.severity is Severity.STOP


@dataclass(frozen=True, slots=True)
class LastStop:
    """The newest stop a :class:`Tally` counted: its record's ``seq``, time and trigger."""

    seq: int
    utc: str
    trigger: tuple[str, ...]


@dataclass
class Tally:
    """One robot's records counted (SR-13.9): :meth:`add` each in the robot's order."""

    records: int = 0
    counts: dict[Counted, int] = field(default_factory=lambda: dict.fromkeys(Counted, 0))
    triggers: dict[str, int] = field(default_factory=dict)
    """Stops by each cause of their trigger (a stop with two counts under both, as
    ``srcs_stops_total{cause}`` does)."""
    last_stop: LastStop | None = None

    def add(self, record: StopRecord | None, previous: StopRecord | None = None) -> None:
        """Count ``record`` (``None``: a line that is no typed record, counted as a record
        only)."""
        self.records += 1
        what = None if record is None else counted(record, previous)
        if record is None or what is None:
            return
        self.counts[what] += 1
        if what is Counted.STOP:
            why = trigger(record, previous)
            for name in why:
                self.triggers[name] = self.triggers.get(name, 0) + 1
            self.last_stop = LastStop(record.seq, record.utc, why)

    @property
    def stops(self) -> int:
        return self.counts[Counted.STOP]
