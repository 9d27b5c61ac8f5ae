"""The outputs as the loop uses them: acquire, apply a decision's levels, read back, all off.

The loop asks and the bank answers with values, never calling back into the loop: what the
core must be fed of the outputs comes back as ``OutputReadback`` events (a write's read-back,
a periodic duty's that failed, an output acquired at last), and the loop feeds them and applies
each decision in its order: outputs, frames, records, pushes (SR-6).

- ``open(now)``: every output acquired off, before anything else (SR-6); one that cannot be
  acquired reads back "no level" (``output_fault:NAME``) and is retried with a backoff
  (SR-4: the daemon stays up, STOPPED, and says so in ``not_acquired()``).
- ``due(now)``: the periodic duties (a CAN enable frame, a GPIO pulse) and the retries that
  are due, one read-back event at a time, each to be fed before the next duty runs.
- ``heard(message, now, core)``: a VSC heartbeat, before the core's full step: the reflex's
  off writes (:class:`~supervisord.daemon.reflex.EarlyOff`, SR-9.5).
- ``unchanged(levels)``: the steady path's test (SR-9.4): every output already at these
  levels and no early write to hand on, so applying them would write nothing.
- ``apply(decision, stopping)``: the decision's levels set, the reflex's writes taken as its
  own, each stop's times to off told to the stop times (SR-12.1); the read-backs for the
  core, and on a stop when its last off write returned (SR-9.2).
- ``all_off(now, close=...)``: every output driven off outside any decision (the loop's
  internal fault, SR-2) and released at the shutdown (SR-6.6).
"""

from __future__ import annotations

import contextlib
import logging
from collections.abc import Iterable, Iterator, Mapping

from supervisord.clock import Clock
from supervisord.daemon.reflex import EarlyOff
from supervisord.daemon.stoptimes import StopTimes
from supervisord.links.base import Backoff
from supervisord.outputs.base import Output, OutputError, ReadBack
from supervisord.protocol.messages import VscHeartbeat
from supervisord.safety.core import SafetyCore
from supervisord.safety.decision import Decision
from supervisord.safety.events import OutputReadback

log = logging.getLogger("srcsd")

ACQUIRE_FIRST_MS, ACQUIRE_MAX_MS = 500, 10_000  # retrying an output that could not be acquired


def readback_event(readback: ReadBack, now: int) -> OutputReadback:
    """The core's event for one write's read-back at ``now`` (a fault has no level seen)."""
    observed = readback.observed if readback.fault is None else None
    if readback.fault is None and observed is None:
        observed = readback.written  # CAN: a frame that went out is the read-back
    return OutputReadback(now, readback.name, readback.requested, observed)


class OutputBank:
    """The daemon's outputs by name, the ones still to acquire, the reflex's writes, and the
    levels the last decision left them at. Each stop's times to off go to ``stop_times``
    (handed at construction, as the link port is handed the timings)."""

    def __init__(self, outputs: Iterable[Output], clock: Clock, stop_times: StopTimes) -> None:
        self.outputs = {output.name: output for output in outputs}
        self.clock = clock
        self.stop_times = stop_times
        # The outputs with a periodic duty (their kind has a ``next_deadline`` of its own: a CAN
        # enable frame, a GPIO pulse): the only ones asked for a deadline every turn (SR-9.4);
        # the others' is always ``None``.
        self.ticking = [
            o for o in self.outputs.values() if type(o).next_deadline is not Output.next_deadline
        ]
        self.acquiring: dict[str, Backoff] = {}  # outputs not acquired yet, and when to retry
        self.early = EarlyOff(self.outputs, clock)  # the reflex's writes (SR-9.5)
        # The levels the last decision set, every one of them (each output named is open and
        # was left at its level): the mapping object itself, for the steady path. ``None``
        # once anything else drives or opens an output.
        self.applied: Mapping[str, bool] | None = None

    def not_acquired(self) -> tuple[str, ...]:
        """The outputs not acquired yet, by name (``status``'s ``outputs_not_acquired``)."""
        return tuple(sorted(self.acquiring))

    # ----------------------------------------------------------------- acquiring

    def open(self, now: int) -> list[OutputReadback]:
        """Every output acquired off at ``now``, in order; each one's read-back event. One
        that cannot be acquired reads back no level (``output_fault:NAME``) and is retried."""
        events = []
        for output in self.outputs.values():
            try:
                events.append(readback_event(output.open(now), now))
            except OutputError as error:
                log.error("output %s cannot be acquired: %s (retrying)", output.name, error)
                events.append(OutputReadback(now, output.name, False, None))
                self.acquiring[output.name] = backoff = Backoff(ACQUIRE_FIRST_MS, ACQUIRE_MAX_MS)
                backoff.failed(now)
        return events

    def next_deadline(self, deadline: int) -> int:
        """The earlier of ``deadline`` and the bank's own: a periodic duty or a retry."""
        for output in self.ticking:
            if output.is_open and (due := output.next_deadline()) is not None and due < deadline:
                deadline = due
        for backoff in self.acquiring.values():
            deadline = min(deadline, backoff.next_attempt)
        return deadline

    def due(self, now: int) -> Iterator[OutputReadback]:
        """The duties and retries due at ``now``, one event at a time: a duty whose read-back
        failed, an output acquired (off). The caller feeds and applies each before asking for
        the next, so a later duty runs with the levels the fault's decision set (SR-6)."""
        for output in self.ticking:
            deadline = output.next_deadline() if output.is_open else None
            if deadline is not None and now >= deadline:
                readback = output.tick(now)
                if readback is not None and not readback.ok:
                    yield readback_event(readback, now)
        for name, backoff in list(self.acquiring.items()):
            if now < backoff.next_attempt:
                continue
            try:
                readback = self.outputs[name].open(now)
            except OutputError as error:
                backoff.failed(now)
                log.debug("output %s still cannot be acquired: %s", name, error)
                continue
            del self.acquiring[name]
            self.applied = None  # an output opened (off): the next decision sets all
            log.info("output %s acquired (off)", name)
            yield readback_event(readback, now)

    # ----------------------------------------------------------------- applying

    def heard(self, message: VscHeartbeat, now: int, core: SafetyCore) -> None:
        """A VSC heartbeat read at ``now``, before the core is fed it: the reflex's off
        writes (SR-9.5), handed to the next :meth:`apply`."""
        self.early.heard(message, now, core)

    def unchanged(self, levels: Mapping[str, bool]) -> bool:
        """Whether applying ``levels`` would write nothing: they are the mapping the last
        decision left every output at (nothing else has driven one since) and the reflex has
        no write to hand on (SR-9.4, SR-9.5)."""
        return levels is self.applied and not self.early.written

    def on(self) -> list[str]:
        """The outputs on as a stop begins: open and on, or written off by the reflex ahead
        of the stop's decision (SR-9.5, SR-12.1)."""
        early = self.early.wrote
        return [n for n, o in self.outputs.items() if o.is_open and (o.requested or early(n))]

    def apply(self, decision: Decision, stopping: bool) -> tuple[list[ReadBack], int | None]:
        """Set ``decision``'s levels (the reflex's writes count as its own; an output already
        at its level is not written again). Returns the read-backs, for the core, and, when
        ``stopping`` (a change into STOPPED) switched outputs off, when the last off write
        returned (the reflex's if it wrote them all, SR-9.5), for the stop-to-off time."""
        times, early = self.stop_times, self.early
        readbacks: list[ReadBack] = []
        early_ns = early.take(readbacks, times) if early.written else None
        early_writes = len(readbacks)
        complete = True  # every output named is open and left at its level
        outputs = self.outputs
        for name, on in decision.outputs.items():
            output = outputs.get(name)
            if output is None or not output.is_open:
                complete = False
                continue
            if output.requested == on:
                continue
            readback = output.set(on, decision.now)
            readbacks.append(readback)
            if not on and times.waiting(name):
                # When this off write returned (SR-12.1): one clock read per output, on a stop
                # only, after the write (outputs first, SR-6.1).
                times.off(readback, self.clock())
        self.applied = decision.outputs if complete else None
        if not (stopping and readbacks):
            return readbacks, None
        only_early = len(readbacks) == early_writes  # nothing written here after the reflex
        return readbacks, early_ns if early_ns is not None and only_early else self.clock()

    def all_off(self, now: int, *, close: bool = False) -> None:
        """Every output driven off at ``now`` outside any decision, and released if ``close``;
        a failing output does not keep the others on (SR-2, SR-6.6)."""
        self.applied = None
        for output in self.outputs.values():
            with contextlib.suppress(Exception):
                output.set(False, now)
            if close:
                with contextlib.suppress(Exception):
                    output.close()
