"""Replay a flight recorder window through a fresh safety core and compare its decisions with the
record (SR-7.13; ``docs/record.md`` "Replay").

The window's base gives the core's state where the window starts: a fresh
:class:`~supervisord.safety.core.SafetyCore` built from the recorded configuration at the
daemon's start, or one restored from the snapshot the daemon took then. Each input is fed as
the daemon fed it, and each record the replayed core makes is compared with the record of the
same sequence number in the record files, the record that counts; the stop record the window
carries stands in for its own only where the files do not hold it (the caller says so:
``srcsctl replay`` exits 3 then, and 5 when the window's copy differs from the file's).
Every field counts but the two the daemon stamps from outside the core (``utc``, the wall
clock; ``version``, on a start's first record).

A replayed record that differs from the recorded one, a recorded record in the window's span
that the replay does not make, or a stop record the replay does not reach, is a mismatch: the
first one ends the replay (:attr:`Replay.mismatch`). A record the files no longer hold (rotated
away, or never written: a full disk) is counted as not compared.

Pure: the caller reads the files.
"""

from __future__ import annotations

import dataclasses
import datetime as dt
import json
from collections import deque
from collections.abc import Iterator, Mapping
from typing import Any, Final

from supervisord.record.flight import LoadedWindow
from supervisord.record.flight_codec import is_moment, preview
from supervisord.record.format import record_json
from supervisord.safety.core import SafetyCore
from supervisord.safety.decision import Decision
from supervisord.safety.events import Event
from supervisord.safety.snapshot import SnapshotError, restore
from supervisord.safety.transitions import State

STAMPED: Final = frozenset({"utc", "version"})
"""Fields the daemon adds to a record from outside the core: never compared."""
_ANY_TIME = dt.datetime(2000, 1, 1, tzinfo=dt.timezone.utc)

Json = Any


class ReplayError(Exception):
    """The window cannot be replayed (no base, or a snapshot this code cannot restore)."""


@dataclasses.dataclass(frozen=True)
class Step:
    """One input (``None``: the start of a fresh core), the decision the replay made of it and
    the records it made, each with what the record says (``None``: not in the record)."""

    number: int
    event: Event | None
    decision: Decision
    records: tuple[tuple[Mapping[str, Json], Mapping[str, Json] | None], ...]
    previous: State


@dataclasses.dataclass(frozen=True)
class Mismatch:
    """Where the replay first parts from the record: the step (``None`` at the end of the
    window), the sequence number, what the record says and what the replay made (either may
    be missing), and the fields that differ."""

    step: Step | None
    seq: int
    recorded: Mapping[str, Json] | None
    replayed: Mapping[str, Json] | None
    fields: tuple[str, ...]


@dataclasses.dataclass
class Replay:
    """The outcome: every step, the first mismatch (if any), how many records were compared."""

    steps: list[Step] = dataclasses.field(default_factory=list)
    mismatch: Mismatch | None = None
    compared: int = 0
    not_compared: int = 0

    @property
    def matches(self) -> bool:
        return self.mismatch is None


def comparable(record: Mapping[str, Json]) -> dict[str, Json]:
    """A record as JSON reads it back, without the fields stamped outside the core."""
    plain: dict[str, Json] = json.loads(json.dumps(dict(record)))
    return {key: value for key, value in plain.items() if key not in STAMPED}


def differing(recorded: Mapping[str, Json], replayed: Mapping[str, Json]) -> tuple[str, ...]:
    a, b = comparable(recorded), comparable(replayed)
    return tuple(sorted(key for key in a.keys() | b.keys() if a.get(key) != b.get(key)))


def copy_differs(
    window: LoadedWindow, recorded: Mapping[int, Mapping[str, Json]]
) -> tuple[str, ...]:
    """The fields in which the window's copy of its stop record differs from the record files'
    record of the same ``seq`` (none when the files do not hold it): a window edited since, or
    another record's (SR-7.13)."""
    on_file = recorded.get(window.seq)
    return () if on_file is None else differing(on_file, window.stop)


def start_core(window: LoadedWindow) -> tuple[SafetyCore, Decision | None]:
    """The core where the window starts, and the start's decision for a fresh one."""
    kind = window.base.get("kind")
    if kind == "start":
        now = window.base.get("now_ns")
        if not isinstance(now, int):
            raise ReplayError("the window's start has no time")
        core = SafetyCore(window.config, now)
        return core, core.decision
    if kind == "snapshot":
        try:
            return restore(window.snapshot, window.config), None
        except SnapshotError as error:
            raise ReplayError(
                f"cannot restore the core's state of srcsd {window.header.get('srcsd')}: {error}"
            ) from error
    reason = window.base.get("reason", "no base")
    raise ReplayError(f"the window cannot be replayed: {reason}")


def replay(window: LoadedWindow, recorded: Mapping[int, Mapping[str, Json]]) -> Replay:
    """Run the window through a core and compare every record it makes with ``recorded``
    (records by ``seq``, from the record files). The stop record is the files' where they hold
    it, else the window's own copy (SR-7.13: the record file is the record that counts)."""
    core, first = start_core(window)
    offset = window.header.get("sequence_offset")
    after = window.base.get("after_seq")
    if not isinstance(offset, int) or not isinstance(after, int):
        raise ReplayError("the window's header lacks its sequence numbers")
    expected = {seq: record for seq, record in recorded.items() if seq > after}
    expected.setdefault(window.seq, window.stop)
    waiting = deque(sorted(expected))  # the recorded numbers the replay must make, in order
    result = Replay()
    seen: set[int] = set()
    state = core.state if first is None else State.STOPPED

    def steps() -> Iterator[tuple[Event | None, Decision]]:
        if first is not None:
            yield None, first
        for event in window.inputs:
            yield event, core.handle(event)

    for number, (event, decision) in enumerate(steps()):
        if not is_moment(decision.now):
            # The core keeps the latest time it was given: a snapshot's own, out of the
            # clock's range, would be every later step's and no export could write it.
            raise ReplayError(
                f"the core's time at step {number} is no time of the monotonic clock "
                f"(0 to 2**63 - 1 ns): {preview(decision.now)}; the snapshot is damaged"
            )
        made = []
        for record in decision.records:
            entry = record_json(record, _ANY_TIME, offset)
            seen.add(entry["seq"])
            made.append((entry, expected.get(entry["seq"])))
        step = Step(number, event, decision, tuple(made), state)
        state = decision.state
        result.steps.append(step)
        for entry, wanted in made:
            if wanted is None:
                result.not_compared += 1
                continue
            fields = differing(wanted, entry)
            result.compared += 1
            if fields:
                result.mismatch = Mismatch(step, entry["seq"], wanted, entry, fields)
                return result
        if made:
            # A recorded record the replay went past without making: the input that made it
            # is missing from the window, or was changed.
            newest = max(seen)
            while waiting and waiting[0] <= newest:
                seq = waiting.popleft()
                if seq not in seen:
                    result.mismatch = Mismatch(step, seq, expected[seq], None, ("seq",))
                    return result
    if window.seq not in seen:
        result.mismatch = Mismatch(None, window.seq, window.stop, None, ("seq",))
    return result
