"""The record path: each record the core makes, from the loop to the disk, the journal and the
flight window, and back to the loop once it is finished (SR-7.4, SR-7.7, SR-7.10 to SR-7.12;
``docs/record.md`` "How a record leaves the loop").

The loop hands it each record in the apply order and is handed back the records that are
finished (on disk, or counted as not written), in record order, to push; it keeps nothing of
the record's bookkeeping itself (``docs/safety.md`` "The loop's parts"). The part holds:

- the :class:`~supervisord.daemon.sink.Sink` and its lanes (record file, journal, log lines,
  flight windows), which the loop never waits for;
- the typed record, from the core's :class:`~supervisord.safety.decision.Record` to the disk,
  the journal, the flight window, the schedule and the pushes: its JSON is made only where
  its bytes are written or sent (the sink's lanes), and what the sink hands back is the typed
  record itself, never one read back from its JSON (SR-7.4);
- the flight recorder's ring (:attr:`RecordPath.flight`: the loop appends each input the core
  is given to its ``inputs``, SR-7.10) and its snapshots of the core (SR-7.11);
- the counts of records not written (``record_errors``, ``records_dropped``).

It never calls into the loop, the core or the listener: it is told what it needs as arguments
and answers with values. No clock of its own but the wall clock the record is stamped with
(the loop's ``now`` is handed in, SR-2.11).
"""

from __future__ import annotations

import dataclasses
import datetime as dt
import logging
from collections.abc import Callable, Sequence

from supervisord import __version__
from supervisord.daemon.flight import FlightRecorder, FlightSettings
from supervisord.daemon.sink import IDLE_STATUS, JournalSend, JournalWrite, Sink, Written
from supervisord.record.flight import FlightWriter
from supervisord.record.format import stop_record
from supervisord.record.jsonl import RecordWriter
from supervisord.record.stop import StopRecord
from supervisord.safety.config import SafetyConfig
from supervisord.safety.core import SafetyCore
from supervisord.safety.decision import Record
from supervisord.safety.transitions import State

log = logging.getLogger("srcsd")

NOT_RUNNING = "the record sink is not running"


class RecordPath:
    """The sink, the first record's version, the flight ring and the counts (see the module
    docstring).

    ``writer``: the record file (``None``: records go nowhere and are acknowledged as they
    come; no flight ring either, as its windows go beside the file); ``journal`` and
    ``flight_journal``: each record's journal copy, each stop window's (SR-13.12);
    ``flight``: the ring's settings (``None``: no flight recorder). Construct, :meth:`start`
    once the loop starts, :meth:`began` once the core exists; at the end :meth:`drain`, then
    :meth:`close`.
    """

    def __init__(
        self,
        safety: SafetyConfig,
        writer: RecordWriter | None,
        *,
        journal: JournalWrite | None = None,
        flight_journal: JournalSend | None = None,
        flight: FlightSettings | None = None,
        wall_clock: Callable[[], dt.datetime],
    ) -> None:
        self.writer, self.wall_clock = writer, wall_clock
        self.journal, self.flight_journal = journal, flight_journal
        self.sink: Sink | None = None
        self.sequence_offset = 0
        """Added to the core's record numbers: the record continues across restarts."""
        self.record_errors = self.records_dropped = 0
        self._version_due = True  # the first record of this start names the version
        # The flight recorder (SR-7.10): beside a record file only, as its windows are.
        self.flight: FlightRecorder | None = None
        self._flight_writer: FlightWriter | None = None
        if writer is not None and flight is not None:
            self.flight = FlightRecorder(safety, flight)
            self._flight_writer = FlightWriter(writer.path, writer.max_bytes, flight.max_bytes)

    def start(self) -> int:
        """Start the sink's lanes; returns its descriptor, readable once a record is
        finished (the loop watches it and then calls :meth:`take_written`)."""
        self.sink = Sink(
            self.writer,
            self.journal,
            flight=self._flight_writer,
            flight_journal=self.flight_journal,
        )
        self.sink.start()
        return self.sink.fileno()

    def began(self, now: int) -> None:
        """The core was made at ``now``: a flight window can start from here."""
        if self.flight is not None:
            self.flight.start(now, self.sequence_offset)

    def rebase(self, core: SafetyCore | None, now: int) -> None:
        """Between two turns: a snapshot of the core for the flight recorder's next windows
        when one is due (SR-7.11); never between an input and its outputs."""
        flight = self.flight
        if flight is None or core is None or not flight.due(now):
            return
        error = flight.rebase(core, now)
        if error is not None:
            name = type(error).__name__
            log.error("flight recorder: no snapshot of the core: %s: %s", name, error)

    def write(self, record: Record) -> Sequence[StopRecord]:
        """Hand ``record`` to the sink (never waits; the stop itself has already happened,
        outputs first, SR-6). Returns the records finished by it, in order: none, unless the
        sink is not running or its queue is full (the record is then counted as not written
        and handed back in its place in the order)."""
        typed = stop_record(record, self.wall_clock(), self.sequence_offset)
        if self._version_due:
            # The first record of a start (the startup stop) names the build that made it, so
            # a stop record says which version was running (docs/record.md).
            typed = dataclasses.replace(typed, version=__version__)
            self._version_due = False
        sink = self.sink
        if sink is None:  # not started: nothing can be written yet
            return self._finished([Written(typed, NOT_RUNNING, dropped=True)])
        finished: Sequence[StopRecord] = ()
        if not sink.record(typed):  # the typed record: its JSON is made where it is written
            finished = self.take_written()  # the dropped record, in its place in the order
        flight = self.flight
        if flight is not None:
            flight.last_seq = typed.seq
            if record.state is State.STOPPED and record.previous is not State.STOPPED:
                # A stop: its window goes to the flight lane, after the record (SR-7.12).
                sink.window(flight.window(typed, self.sequence_offset))
        return finished

    def take_written(self) -> list[StopRecord]:
        """The records the sink finished since the last call, in record order."""
        if self.sink is None:
            return []
        return self._finished(self.sink.take_written())

    def drain(self) -> list[StopRecord]:
        """At exit: every queued record written and fsynced within the sink's deadline
        (SR-7.7); returns the records finished since the last take, to push."""
        if self.sink is None:
            return []
        self.sink.drain_records()
        return self.take_written()

    def close(self) -> None:
        """Journal copies and log lines best effort, then the writer (:meth:`Sink.close`)."""
        if self.sink is not None:
            self.sink.close()  # closes the writer, unless a write is stuck in the disk
        elif self.writer is not None:
            self.writer.close()

    def status(self) -> dict[str, int]:
        """The sink's counters for ``status`` (docs/api.md), the ring's snapshot errors in
        ``flight_errors``."""
        status = dict(self.sink.status() if self.sink is not None else IDLE_STATUS)
        if self.flight is not None:
            status["flight_errors"] += self.flight.snapshot_errors
        return status

    def _finished(self, written: list[Written]) -> list[StopRecord]:
        """Each outcome counted; the typed records, in order. Not written (a full disk, a full
        queue) is counted and logged, never a stop of its own: docs/record.md "A full
        disk"."""
        finished = []
        for one in written:
            if not one.acknowledged:
                self.record_errors += 1
                self.records_dropped += one.dropped
                log.error("stop record not written: %s", one.error)
            finished.append(one.record)
        return finished
