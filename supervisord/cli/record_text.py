"""A stop record in words: the one line ``srcsctl log``, ``srcsctl watch`` and the demo print
for each record (docs/srcsctl.md "Reading a record").

A line says what happened, not the whole state: the time, the state change if any, the
record's kind, which causes were raised, cleared or released (the record's ``changes``, the
safety core's own difference from the record before; for a record without them, the
difference from the previous record's causes), and the reason in words: a refused re-arm's,
a proof test's verdict, what a commissioning read back, why a link broke. The whole cause
set is one option away (``--causes``).

One marker everywhere (:data:`MARK`): a cause whose condition has cleared and that only its
latch still holds, waiting for a re-arm (SR-4), is written ``NAME*``, in ``status`` as here.
"""

from __future__ import annotations

from collections.abc import Iterable, Mapping, Sequence
from typing import Any, Final

from supervisord.timebase import NS_PER_MS

MARK: Final = "*"
"""After a cause's name: cleared, held only by its latch until a re-arm."""
MARK_MEANS: Final = "* cleared; its latch holds the stop until a re-arm (takeover or reset)"
"""The legend printed once under a list that uses :data:`MARK`."""
RELEASED_LISTED: Final = 3
"""A re-arm releasing more latches than this says how many, not which (``--causes`` lists
them)."""
_DETAIL_CHARS: Final = 80


def mark(name: object, *, held: bool) -> str:
    """A cause's name with :data:`MARK` when it has cleared and its latch holds it."""
    return f"{name}{MARK if held else ''}"


def marked(cause: Mapping[str, Any]) -> str:
    """:func:`mark` for a cause of a written record."""
    return mark(cause.get("name"), held=bool(cause.get("latched") and not cause.get("active")))


def cause_set(causes: object) -> str:
    """Every cause of a record or state, marked: ``vsc_estop*, vsc_mode:local``."""
    if not isinstance(causes, list) or not causes:
        return "none"
    return ", ".join(marked(c) for c in causes if isinstance(c, Mapping))


def verdict(prooftest: Mapping[str, Any]) -> str:
    """A proof test's result as a verdict: ``proof test passed: tripped after 532 ms, limit
    700 ms; cleared by itself 49 ms after the heartbeat resumed``, or ``proof test FAILED:``
    and why. The limit and the failures' words are the safety core's, read here only: the
    lines of every other record, ``srcsctl fleet``'s on a collector included, need no module
    of the safety core."""
    from supervisord.safety.prooftest import TRIP_LATE_NS, Failure  # noqa: PLC0415

    limit_ms = TRIP_LATE_NS // NS_PER_MS  # docs/safety.md "The proof test"
    trip = prooftest.get("trip_ms")
    tripped = (
        f"tripped after {trip} ms, limit {limit_ms} ms" if trip is not None else "no trip seen"
    )
    if prooftest.get("result") == "passed":
        how = "cleared by itself" if prooftest.get("cleared") == "by_itself" else "held, cleared"
        after = prooftest.get("cleared_ms")
        cleared = f"; {how} {after} ms after the heartbeat resumed" if after is not None else ""
        return f"proof test passed: {tripped}{cleared}"
    failure = prooftest.get("failure")
    why = (
        Failure[failure.upper()].value
        if failure and failure.upper() in Failure.__members__
        else failure
    )
    return f"proof test FAILED: {why or 'no reason given'}; {tripped}"


RAW_DETAILS: Final = frozenset({"word", "mode"})
"""Details that repeat a VSC's raw bits (the e-stop word, the mode byte): in the line with
``--causes`` only; ``sources`` and ``mode``'s cause name say them in words."""


def _details(cause: Mapping[str, Any] | None, every: bool) -> str:
    """A cause's details in brackets: its ``reason`` in its own words, the rest as
    ``key=value`` (without the raw bits unless ``every``)."""
    details = (cause or {}).get("details")
    if not isinstance(details, Mapping) or not details:
        return ""
    words = [
        str(value) if key == "reason" else f"{key}={value}"
        for key, value in details.items()
        if every or key not in RAW_DETAILS
    ]
    text = "; ".join(words)
    if not text:
        return ""
    if every or len(text) <= _DETAIL_CHARS:
        return f" ({text})"
    return f" ({text[: _DETAIL_CHARS - 3]}...)"


def changes(data: Mapping[str, Any], previous: Mapping[str, Any] | None) -> list[tuple[str, str]]:
    """``(change, cause name)`` pairs: the record's ``changes``, or for a record without them
    the difference from ``previous`` (raised: new and active; cleared: active before, not
    now)."""
    changes = data.get("changes")
    if isinstance(changes, list) and changes:
        return [
            (str(c.get("change")), str(c.get("name"))) for c in changes if isinstance(c, Mapping)
        ]
    if previous is None or isinstance(changes, list):
        return []
    before = _by_name(previous.get("causes"))
    now = _by_name(data.get("causes"))
    found = [("raised", n) for n, c in now.items() if c.get("active") and n not in before]
    found += [
        ("cleared", n)
        for n, c in before.items()
        if c.get("active") and not (now.get(n) or {}).get("active")
    ]
    return found


def _by_name(causes: object) -> dict[str, Mapping[str, Any]]:
    if not isinstance(causes, list):
        return {}
    return {str(c.get("name")): c for c in causes if isinstance(c, Mapping)}


def _names(
    names: Iterable[str], causes: Mapping[str, Mapping[str, Any]], details: bool, every: bool
) -> str:
    shown = []
    for name in names:
        cause = causes.get(name)
        text = marked(cause) if cause else name
        shown.append(text + (_details(cause, every) if details else ""))
    return ", ".join(shown)


def what_changed(
    data: Mapping[str, Any], previous: Mapping[str, Any] | None = None, *, every: bool = False
) -> str:
    """The causes raised, updated, cleared and released by a record, in words:
    ``raised vsc_estop (sources=remote); cleared vsc_mode:local``. A cleared cause that its
    latch still holds is marked. ``every``: every released latch by name, not their number,
    and every detail of a raised cause in full."""
    pairs = changes(data, previous)
    causes = _by_name(data.get("causes"))
    parts = []
    prooftest = data.get("kind") == "prooftest"  # its verdict says what the update was
    for change in ("raised", "updated", "cleared", "released"):
        names = [name for kind, name in pairs if kind == change]
        if not names or (change == "updated" and prooftest):
            continue
        if change == "released" and len(names) > RELEASED_LISTED and not every:
            parts.append(f"released {len(names)} latches")
            continue
        details = change in ("raised", "updated")
        parts.append(f"{change} {_names(names, causes, details, every)}")
    return "; ".join(parts)


def happening(data: Mapping[str, Any]) -> str:
    """What the record is about besides its causes, in words: a re-arm, a refusal and its
    reason, a proof test's verdict, a commissioning. (Why a link broke is the raised cause's
    own detail.)"""
    kind = data.get("kind") or "state_change"
    reason = data.get("reason") or ""
    trigger = data.get("trigger")
    event = trigger.get("event") if isinstance(trigger, Mapping) else trigger
    if kind == "prooftest" and isinstance(data.get("prooftest"), Mapping):
        return verdict(data["prooftest"])
    if kind == "rearm_refused":
        what = "reset" if event == "reset_request" else "takeover"
        return f"{what} refused: {reason or 'no reason given'}"
    if kind == "commissioned":
        return f"commissioned: {reason}" if reason else "commissioned"
    if kind == "hello_refused":
        return f"hello refused: {reason}" if reason else "hello refused"
    if kind == "stoptest":
        return f"stop test {reason}" if reason else "stop test"
    rearm = data.get("rearm")
    if isinstance(rearm, Mapping):
        caller = rearm.get("caller")
        by = (
            f" ({caller.get('name')}, uid {caller.get('uid')})"
            if isinstance(caller, Mapping)
            else ""
        )
        return f"re-armed by {rearm.get('kind')}{by}"
    return ""


def move(data: Mapping[str, Any]) -> str:
    """``RUN -> STOPPED`` for a change of state, else the state the record was made in."""
    before, after = str(data.get("from")), str(data.get("to"))
    return after if before == after else f"{before} -> {after}"


def record_line(
    data: Mapping[str, Any],
    when: str,
    *,
    previous: Mapping[str, Any] | None = None,
    causes: bool = False,
) -> str:
    """One record in one line, after ``when`` (the time as the caller shows it):
    ``WHEN  #SEQ  MOVE  KIND  what happened``. ``causes``: the whole cause set and the
    trigger too, and every released latch by name."""
    kind = str(data.get("kind") or "state_change")
    words = [w for w in (happening(data), what_changed(data, previous, every=causes)) if w]
    text = "; ".join(words) or ("causes " + cause_set(data.get("causes")))
    seq = f"#{data.get('seq')}"
    line = f"{when}  {seq:6} {move(data):16} {kind:14} {text}"
    if causes:
        trigger = data.get("trigger")
        event = trigger.get("event") if isinstance(trigger, Mapping) else trigger
        line += f"  [causes: {cause_set(data.get('causes'))}; trigger {event}]"
    return line


def legend(records: Sequence[Mapping[str, Any]]) -> list[str]:
    """:data:`MARK_MEANS`, once, if any of the records' lines used the marker."""
    return [MARK_MEANS] if any(MARK in record_line(r, "") for r in records) else []
