"""A stop record in words: the one line ``srcsctl log``, ``srcsctl watch`` and the demo print
for each record (docs/srcsctl.md "Reading a record").

A line says what happened, not the whole state: the time, the state change if any, the
record's kind, which causes were raised, cleared or released (the record's ``changes``, the
safety core's own difference from the record before; for a record without them, the
difference from the previous record's causes), and the reason in words: a refused re-arm's,
a proof test's verdict, what a commissioning read back, why a link broke. The whole cause
set is one option away (``--causes``).

Every text of a record is another party's (a record file, a robot's upload at a fleet's
collector, SR-13.7): a line is escaped whole (:func:`~supervisord.cli.terminal_text.
printable`) before it is handed out, so no field's control or bidi character reaches a
terminal raw. Our own words hold none of the characters escaped, so the line escaped whole
is each field escaped.

One marker everywhere (:data:`MARK`): a cause whose condition has cleared and that only its
latch still holds, waiting for a re-arm (SR-4), is written ``NAME*``, in ``status`` as here.
"""

from __future__ import annotations

from collections.abc import Iterable, Mapping, Sequence
from typing import Any, Final

from supervisord.cli.terminal_text import printable
from supervisord.record.counted import changes
from supervisord.record.stop import Cause, ProofTestResult, RecordKind, StopRecord
from supervisord.timebase import NS_PER_MS
from supervisord.vocabulary import TRIP_LATE_NS, CauseName, ChangeKind, ProofTestFailure

MARK: Final = "*"
"""After a cause's name: cleared, held only by its latch until a re-arm."""
MARK_MEANS: Final = "* cleared; its latch holds the stop until a re-arm (takeover or reset)"
"""The legend printed once under a list that uses :data:`MARK`."""
RELEASED_LISTED: Final = 3
"""A re-arm releasing more latches than this says how many, not which (``--causes`` lists
them)."""
_DETAIL_CHARS: Final = 80
_CHANGES_SHOWN: Final = (
    ChangeKind.RAISED,
    ChangeKind.UPDATED,
    ChangeKind.CLEARED,
    ChangeKind.RELEASED,
)
"""The order a line names a record's changes in."""


def mark(name: object, *, held: bool) -> str:
    """A cause's name with :data:`MARK` when it has cleared and its latch holds it."""
    return f"{name}{MARK if held else ''}"


def marked(cause: Cause) -> str:
    """:func:`mark` for a cause of a written record."""
    return mark(cause.name, held=cause.held)


def cause_set(causes: Sequence[Cause]) -> str:
    """Every cause of a record or state, marked: ``vsc_estop*, vsc_mode:local``."""
    return ", ".join(marked(c) for c in causes) if causes else "none"


def verdict(prooftest: ProofTestResult | None) -> str:
    """A proof test's result as a verdict: ``proof test passed: tripped after 532 ms, limit
    700 ms; cleared by itself 49 ms after the heartbeat resumed``, or ``proof test FAILED:``
    and why (none known: ``None``). The limit and the failures' words are the vocabulary's,
    the safety core's own (SR-8.8: printing a record loads no module of the core)."""
    limit_ms = TRIP_LATE_NS // NS_PER_MS  # docs/safety.md "The proof test"
    trip = None if prooftest is None else prooftest.trip_ms
    tripped = (
        f"tripped after {trip} ms, limit {limit_ms} ms" if trip is not None else "no trip seen"
    )
    if prooftest is not None and prooftest.passed:
        how = "cleared by itself" if prooftest.cleared_by_itself else "held, cleared"
        after = prooftest.cleared_ms
        cleared = f"; {how} {after} ms after the heartbeat resumed" if after is not None else ""
        return f"proof test passed: {tripped}{cleared}"
    failure = None if prooftest is None else prooftest.failed_for
    why = failure.value if isinstance(failure, ProofTestFailure) else failure
    return f"proof test FAILED: {why or 'no reason given'}; {tripped}"


RAW_DETAILS: Final = frozenset({"word", "mode"})
"""Details that repeat a VSC's raw bits (the e-stop word, the mode byte): in the line with
``--causes`` only; ``sources`` and ``mode``'s cause name say them in words."""


def _details(cause: Cause | None, every: bool) -> str:
    """A cause's details in brackets: its ``reason`` in its own words, the rest as
    ``key=value`` (without the raw bits unless ``every``)."""
    details = {} if cause is None else cause.details
    words = [
        value if key == "reason" else f"{key}={value}"
        for key, value in details.items()
        if every or key not in RAW_DETAILS
    ]
    text = "; ".join(words)
    if not text:
        return ""
    if every or len(text) <= _DETAIL_CHARS:
        return f" ({text})"
    return f" ({text[: _DETAIL_CHARS - 3]}...)"


def _by_name(causes: Iterable[Cause]) -> dict[CauseName, Cause]:
    return {c.name: c for c in causes}


def _names(
    names: Iterable[CauseName], causes: Mapping[CauseName, Cause], details: bool, every: bool
) -> str:
    shown = []
    for name in names:
        cause = causes.get(name)
        text = marked(cause) if cause else str(name)
        shown.append(text + (_details(cause, every) if details else ""))
    return ", ".join(shown)


def what_changed(
    record: StopRecord, previous: StopRecord | None = None, *, every: bool = False
) -> str:
    """The causes raised, updated, cleared and released by a record, in words:
    ``raised vsc_estop (sources=remote); cleared vsc_mode:local``. A cleared cause that its
    latch still holds is marked. ``every``: every released latch by name, not their number,
    and every detail of a raised cause in full."""
    pairs = changes(record, previous)
    causes = _by_name(record.causes)
    parts = []
    prooftest = record.kind is RecordKind.PROOFTEST  # its verdict says what the update was
    for change in _CHANGES_SHOWN:
        names = [name for kind, name in pairs if kind is change]
        if not names or (change is ChangeKind.UPDATED and prooftest):
            continue
        if change is ChangeKind.RELEASED and len(names) > RELEASED_LISTED and not every:
            parts.append(f"released {len(names)} latches")
            continue
        details = change in (ChangeKind.RAISED, ChangeKind.UPDATED)
        parts.append(f"{change} {_names(names, causes, details, every)}")
    return "; ".join(parts)


def happening(record: StopRecord) -> str:
    """What the record is about besides its causes, in words: a re-arm, a refusal and its
    reason, a proof test's verdict, a commissioning. (Why a link broke is the raised cause's
    own detail.)"""
    kind = record.record_kind
    reason = record.reason or ""
    if kind is RecordKind.PROOFTEST and record.prooftest is not None:
        return verdict(record.prooftest)
    if kind is RecordKind.REARM_REFUSED:
        what = "reset" if record.event == "reset_request" else "takeover"
        return f"{what} refused: {reason or 'no reason given'}"
    if kind is RecordKind.COMMISSIONED:
        return f"commissioned: {reason}" if reason else "commissioned"
    if kind is RecordKind.HELLO_REFUSED:
        return f"hello refused: {reason}" if reason else "hello refused"
    if kind is RecordKind.STOPTEST:
        return f"stop test {reason}" if reason else "stop test"
    rearm = record.rearm
    if rearm is not None:
        caller = rearm.caller
        by = f" ({caller.name}, uid {caller.uid})" if caller is not None else ""
        return f"re-armed by {rearm.kind}{by}"
    return ""


def move(record: StopRecord) -> str:
    """``RUN -> STOPPED`` for a change of state, else the state the record was made in."""
    before, after = record.from_state, record.to_state
    return str(after) if before is after else f"{before} -> {after}"


def record_line(
    record: StopRecord,
    when: str,
    *,
    previous: StopRecord | None = None,
    causes: bool = False,
) -> str:
    """One record in one line, after ``when`` (the time as the caller shows it):
    ``WHEN  #SEQ  MOVE  KIND  what happened``. ``causes``: the whole cause set and the
    trigger too, and every released latch by name. Escaped (:func:`printable`)."""
    words = [w for w in (happening(record), what_changed(record, previous, every=causes)) if w]
    text = "; ".join(words) or ("causes " + cause_set(record.causes))
    line = _line(when, record.seq, move(record), record.record_kind.value, text)
    if causes:
        line += f"  [causes: {cause_set(record.causes)}; trigger {record.event}]"
    return printable(line)  # the record's texts are another party's (SR-13.7)


def written_line(data: Mapping[str, Any], when: str) -> str:
    """A line the store took that is no typed record (:func:`~supervisord.record.stop.
    read_written`: a state, record kind or change this client does not know), from the
    fields the store holds, as written: ``WHEN  #SEQ  FROM -> TO  KIND  causes NAMES``,
    escaped (:func:`printable`)."""
    before, after = str(data.get("from")), str(data.get("to"))
    moved = after if before == after else f"{before} -> {after}"
    causes = data.get("causes")
    listed = causes if isinstance(causes, list) else []  # the store's: objects with a name
    names = [str(c.get("name")) for c in listed if isinstance(c, Mapping)]
    text = "causes " + (", ".join(names) or "none")
    kind = str(data.get("kind") or "state_change")
    return printable(_line(when, data.get("seq"), moved, kind, text))  # (SR-13.7)


def _line(when: str, seq: object, moved: str, kind: str, text: str) -> str:
    number = f"#{seq}"
    return f"{when}  {number:6} {moved:16} {kind:14} {text}"


def legend(records: Sequence[StopRecord]) -> list[str]:
    """:data:`MARK_MEANS`, once, if any of the records' lines used the marker."""
    return [MARK_MEANS] if any(MARK in record_line(r, "") for r in records) else []
