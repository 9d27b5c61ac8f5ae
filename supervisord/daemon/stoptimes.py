"""Each stop's time to off, per output, for the field stop test (SR-12.1; docs/safety.md
"The field stop test").

The loop tells :class:`StopTimes` of every stop (a change into STOPPED: the stop record's
``seq``, its ``mono_ns``, which for a VSC frame is the frame's read stamp, and the outputs on
at that moment) and of every off write to an output it waits for: the clock read right after
that write returned, and whether its read-back matched. ``srcsctl stoptest`` then names the
stops its presses made; :meth:`StopTimes.result` judges them. Only the last :data:`KEEP`
stops are kept: a test's two presses are never more than a few stops apart.

No clock of its own: the loop passes its readings (SR-2.11).
"""

from __future__ import annotations

from collections import deque
from collections.abc import Callable, Iterable, Mapping
from dataclasses import dataclass, field
from typing import Final

from supervisord.outputs.base import ReadBack
from supervisord.safety.causes import CauseKind
from supervisord.safety.decision import Record
from supervisord.safety.events import VscReceived
from supervisord.safety.stoptest import OutputOff, Source, StopStep, StopTestResult
from supervisord.safety.transitions import State

KEEP: Final = 4
"""Stops kept: the two presses of a test, and a stop or two between them."""


@dataclass
class MeasuredStop:
    """One stop: ``off_ns`` per output that was on at the stop, ``None`` until its off write
    returns with a matching read-back, and for good if it returned without one."""

    seq: int
    stop_ns: int
    previous: State
    from_vsc: bool  # raised by a VSC frame (not a deadline, a client, a read-back)
    sources: frozenset[str]  # the e-stop word's named sources, when the frame carried one
    off_ns: dict[str, int | None] = field(default_factory=dict)
    faulted: set[str] = field(default_factory=set)  # off written, read-back not matching

    def waiting(self, name: str) -> bool:
        return name in self.off_ns and self.off_ns[name] is None and name not in self.faulted


def _verified_off(readback: ReadBack) -> bool:
    """The off write is verified: no fault, and the level read back (or, for a kind that
    cannot read back, the frame that went out) is off."""
    level = readback.observed if readback.observed is not None else readback.written
    return readback.ok and not readback.requested and not level


class StopTimes:
    """The last :data:`KEEP` stops and their outputs' times to off."""

    def __init__(self, keep: int = KEEP, delays: Mapping[str, int] | None = None) -> None:
        """``delays``: each category-1 output's ``off_delay_ms`` (SR-1.4), judged after it."""
        self._delays = dict(delays or {})
        self._stops: deque[MeasuredStop] = deque(maxlen=keep)
        self._open: MeasuredStop | None = None  # the stop whose outputs are still going off

    def stopped(self, record: Record, seq: int, on: Iterable[str]) -> None:
        """A change into STOPPED was decided by ``record`` (its ``seq`` in the file), with the
        outputs ``on`` still on: their off writes are timed from the record's ``mono_ns``."""
        sources: frozenset[str] = frozenset()
        for cause in record.causes:
            if cause.name == CauseKind.VSC_ESTOP.value and cause.active:
                text = dict(cause.details).get("sources", "")
                sources = frozenset(s for s in text.split(",") if s)
        stop = MeasuredStop(
            seq,
            record.monotonic_ns,
            record.previous,
            isinstance(record.trigger, VscReceived),
            sources,
            dict.fromkeys(on),
        )
        self._stops.append(stop)
        self._open = stop

    def began(
        self, records: Iterable[Record], offset: int, on: Callable[[], Iterable[str]]
    ) -> None:
        """A decision changed into STOPPED with ``records``: the first change into STOPPED
        among them is the stop, numbered ``offset`` + its sequence in the file, timing the
        outputs ``on()`` says are on, or off already by the reflex ahead of the decision
        (SR-9.5, SR-12.1); asked only when there is such a record."""
        for record in records:
            if record.state is State.STOPPED and record.previous is not State.STOPPED:
                self.stopped(record, offset + record.sequence, on())
                return

    def waiting(self, name: str) -> bool:
        """Whether an off write to ``name`` is to be timed (cheap: called per off write)."""
        stop = self._open
        return stop is not None and stop.waiting(name)

    def off(self, readback: ReadBack, returned_ns: int) -> None:
        """The off write to ``readback.name`` returned at ``returned_ns``."""
        stop = self._open
        if stop is None or not stop.waiting(readback.name):
            return
        if _verified_off(readback):
            stop.off_ns[readback.name] = returned_ns - stop.stop_ns
        else:
            stop.faulted.add(readback.name)  # never timed later: the test fails (SR-12.1)

    def ended(self) -> None:
        """The robot left STOPPED: outputs not off by now stay unmeasured."""
        self._open = None

    def find(self, seq: int) -> MeasuredStop | None:
        return next((stop for stop in self._stops if stop.seq == seq), None)

    def result(self, steps: Iterable[tuple[str, int]], limit_ms: int) -> StopTestResult | str:
        """The judged result of the presses ``steps`` (source, stop seq), or why they are not
        a stop test: a stop not kept, not from RUN, or not the VSC reporting that e-stop."""
        judged = []
        for source, seq in steps:
            stop = self.find(seq)
            if stop is None:
                return f"stop #{seq} is not among the last {KEEP} stops this daemon measured"
            why = _not_a_press(stop, source)
            if why is not None:
                return f"stop #{seq} was not the {source} e-stop pressed in RUN: {why}"
            outputs = tuple(
                OutputOff(name, ns, self._delays.get(name, 0))
                for name, ns in sorted(stop.off_ns.items())
            )
            judged.append(StopStep(Source(source), stop.seq, stop.stop_ns, outputs))
        return StopTestResult(tuple(judged), limit_ms)


def _not_a_press(stop: MeasuredStop, source: str) -> str | None:
    if stop.previous is not State.RUN:
        return f"the supervisor was {stop.previous.name}, not RUN"
    if not stop.from_vsc:
        return "no VSC frame raised it"
    if source not in stop.sources:
        named = ", ".join(sorted(stop.sources)) or "none"
        return f"the VSC reported e-stop sources {named}"
    if not stop.off_ns:
        return "no output was on"
    return None
