"""The ways slow work leaves the loop: the stop record (with its fsync), the journal copy of
each record, and log lines, each on a lane of its own (SR-7.5, SR-7.7; ``docs/record.md`` "How
a record leaves the loop").

The loop hands work to :class:`Sink` and never waits for it: every hand-over puts an item on a
bounded queue and returns at once. Each kind of work has a :class:`Lane`, a queue and one owned
thread that serves it in order:

- ``srcsd-record``: the JSON Lines file (write and fsync: a record is acknowledged only then);
- ``srcsd-journal``: the journal copy of each record (a stuck journald costs up to 2 s each);
- ``srcsd-log``: log lines, written to the descriptors of the handlers the process had;
- ``srcsd-flight``: the flight recorder's window of each stop (encoded, written, fsynced and
  renamed into place beside the record: ``supervisord/record/flight.py``, SR-7.12), then its
  copy to the journal, an entry of its own, for the fleet's collector
  (``supervisord/record/flight_journal.py``, SR-13.12): after the file, so a journald that is
  stuck (up to 2 s an entry) costs the copy, never the window's file or anything of the loop.

No lane waits for another, so a journald or a stderr that nobody reads costs journal copies
and log lines, counted (``journal_dropped``, ``log_lines_dropped`` in ``status``), never a
record. Each record's outcome comes back to the loop as a :class:`Written` through
:meth:`Sink.take_written`, in the order the records were given, and a byte on
:meth:`Sink.fileno` wakes the loop for it; only then does the loop push the record to the
API's subscribers, so a pushed record is an acknowledged one (SR-7.4).

A full queue never blocks the loop: a record that does not fit comes back at once as a
:class:`Written` with ``dropped`` set (``record_errors``, ``records_dropped``).

Shutdown has a deadline well inside the unit's stop timeout (``TimeoutStopSec=10``):
:meth:`Sink.drain_records` first gives the record file up to :data:`RECORD_DRAIN_S` to take
every queued record, then :meth:`Sink.close` gives the journal copies and log lines what is
left of :data:`SIDE_DRAIN_S`, best effort. What is still queued then is counted, not waited
for: a daemon that systemd has to kill loses everything, a deadline loses only what a stuck
device would never have taken.
"""

from __future__ import annotations

import collections
import contextlib
import logging
import os
import socket
import threading
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass
from typing import Final

from supervisord.lane import Lane, deadline_after
from supervisord.record.flight import FlightError, FlightWriter, Window
from supervisord.record.flight_journal import window_entry
from supervisord.record.jsonl import RecordError, RecordUsageError, RecordWriter
from supervisord.record.stop import StopRecord

RECORD_CAPACITY: Final = 4096
"""Records waiting for the disk at most (about a minute of the worst client traffic the
record budget allows on a disk that takes 10 ms per fsync)."""
JOURNAL_CAPACITY: Final = 1024
"""Journal copies waiting at most; past it copies are dropped (counted), never records."""
RECORD_BATCH: Final = 256
"""Records queued together go to the file with one write and one fsync, up to this many."""
LOG_CAPACITY: Final = 1024
"""Log lines waiting at most; past it log lines are dropped (counted), never records."""
FLIGHT_CAPACITY: Final = 2
"""Windows waiting at most (each holds a tuple of up to a ring's inputs); past it a window is
dropped (``flight_dropped``). Stops come no faster than their re-arms allow (SR-7.8)."""
RECORD_DRAIN_S: Final = 4.0
"""At exit, how long the record file may take to write what is queued (SR-7.7)."""
SIDE_DRAIN_S: Final = 1.0
"""At exit, after the records, how long journal copies and log lines may take together. With
:data:`RECORD_DRAIN_S`, 5 s: half the unit's ``TimeoutStopSec=10`` (units/srcsd@.service)."""

IDLE_STATUS: Final[Mapping[str, int]] = {
    "records_pending": 0,
    "journal_errors": 0,
    "journal_dropped": 0,
    "log_lines_dropped": 0,
    "record_reopens": 0,
    "flight_windows": 0,
    "flight_errors": 0,
    "flight_dropped": 0,
}
"""What :meth:`Sink.status` says before the sink exists."""

JournalWrite = Callable[[Mapping[str, object]], object]
JournalSend = Callable[[Sequence[tuple[str, str]]], object]

log = logging.getLogger("srcsd")


@dataclass(frozen=True, slots=True)
class Written:
    """What became of one record: acknowledged (``error`` ``None``, not ``dropped``), or not
    written because the file refused it (``error``) or the queue was full (``dropped``). The
    typed record the loop handed over itself, never one read back from its JSON."""

    record: StopRecord
    error: str | None = None
    disk_full: bool = False
    dropped: bool = False

    @property
    def acknowledged(self) -> bool:
        return self.error is None and not self.dropped


class Sink:
    """The record, journal and log lanes (see the module docstring).

    ``writer``: the record file (``None``: no file, records are acknowledged as they come);
    ``journal``: a callable sending one record to the journal (its failures are counted in
    ``journal_errors``, never raised); ``flight``: where the flight recorder's windows go
    (``None``: nowhere); ``flight_journal``: a callable sending one journal entry's fields,
    each window's copy (its failures counted in ``journal_errors`` too). Construct, then
    :meth:`start`; at the end :meth:`drain_records`, then :meth:`close`.
    """

    def __init__(
        self,
        writer: RecordWriter | None,
        journal: JournalWrite | None = None,
        *,
        flight: FlightWriter | None = None,
        flight_journal: JournalSend | None = None,
        capacity: int = RECORD_CAPACITY,
        journal_capacity: int = JOURNAL_CAPACITY,
        log_capacity: int = LOG_CAPACITY,
        flight_capacity: int = FLIGHT_CAPACITY,
    ) -> None:
        self.writer, self.journal, self.flight = writer, journal, flight
        self.flight_journal = flight_journal
        self.journal_errors = 0
        self.flight_windows = self.flight_errors = 0
        # The typed records travel the lanes; each lane makes the JSON it writes or sends, off
        # the loop's thread (docs/record.md "How a record leaves the loop").
        self._records: Lane[StopRecord] = Lane("srcsd-record", capacity, self._write, RECORD_BATCH)
        self._journal: Lane[StopRecord] = Lane(
            "srcsd-journal", journal_capacity, self._send_journal
        )
        self._logs: Lane[logging.LogRecord] = Lane("srcsd-log", log_capacity, self._emit)
        self._flight: Lane[Window] = Lane("srcsd-flight", flight_capacity, self._write_windows)
        self._written: collections.deque[Written] = collections.deque()
        self._wake_r, self._wake_w = socket.socketpair()
        self._wake_r.setblocking(False)
        self._wake_w.setblocking(False)
        self._handlers: list[logging.Handler] = []
        self._logger: logging.Logger | None = None
        self._closed = False
        self._records_drained = False
        # Every record given to the record lane and not finished yet, in record order (keyed by
        # the record's identity): at the exit's deadline these are the ones not written, the one
        # in the disk's hands included (SR-7.14). Each is finished exactly once, under the lock:
        # by the lane, or by the deadline, never both.
        self._unfinished: dict[int, StopRecord] = {}
        self._unfinished_lock = threading.Lock()

    # -- the loop's side -------------------------------------------------------------------

    def start(self) -> None:
        """Start the lanes' threads."""
        self._records.start()
        if self.journal is not None:
            self._journal.start()
        if self.flight is not None:
            self._flight.start()
        self._logs.start()

    def record(self, record: StopRecord) -> bool:
        """Queue one record for the file and its copy for the journal; never waits.
        ``False``: the record queue was full, the record is not written, and its
        :class:`Written` (``dropped``) is ready at once (its journal copy is still sent)."""
        if self.journal is not None:
            self._journal.put(record)  # a full journal lane counts the copy, nothing more
        with self._unfinished_lock:  # before the lane may serve it
            self._unfinished[id(record)] = record
        if self._records.put(record):
            return True
        with self._unfinished_lock:
            del self._unfinished[id(record)]
        self._finished(Written(record, "the record queue is full", dropped=True))
        return False

    def window(self, window: Window) -> bool:
        """Queue a stop's flight recorder window; never waits. ``False``: none is written (no
        flight writer, or the queue is full: ``flight_dropped``)."""
        return self.flight is not None and self._flight.put(window)

    def log(self, record: logging.LogRecord) -> None:
        """Queue one log line for the handlers captured by :meth:`capture_logging` (any
        thread); a full queue drops it, counted in ``log_lines_dropped``."""
        self._logs.put(record)

    def take_written(self) -> list[Written]:
        """The outcomes of the records finished since the last call, in order."""
        with contextlib.suppress(OSError):  # BlockingIOError: nothing more; closed: drained
            while self._wake_r.recv(4096):
                pass
        taken = []
        while self._written:
            taken.append(self._written.popleft())
        return taken

    def fileno(self) -> int:
        """Readable when :meth:`take_written` has something."""
        return self._wake_r.fileno()

    @property
    def pending(self) -> int:
        """Records queued and not yet finished."""
        return self._records.pending

    def status(self) -> dict[str, int]:
        """The counters ``status`` shows (docs/api.md)."""
        return {
            "records_pending": self.pending,
            "journal_errors": self.journal_errors,
            "journal_dropped": self._journal.dropped,
            "log_lines_dropped": self._logs.dropped,
            "record_reopens": self.writer.reopens if self.writer is not None else 0,
            "flight_windows": self.flight_windows,
            "flight_errors": self.flight_errors,
            "flight_dropped": self._flight.dropped,
        }

    def capture_logging(self, logger: logging.Logger) -> None:
        """Route ``logger``'s lines (the root logger: every line of the process) through the
        log lane: its handlers are replaced by one that queues, and run on the lane."""
        self._logger = logger
        self._handlers = list(logger.handlers)
        for handler in self._handlers:
            with contextlib.suppress(Exception):
                handler.flush()  # what they hold goes out before the lane writes past them
            logger.removeHandler(handler)
        logger.addHandler(_QueueHandler(self))

    def drain_records(self, timeout_s: float = RECORD_DRAIN_S) -> bool:
        """At exit, first: wait until the record file has taken every queued record, at most
        ``timeout_s``. Every record not finished then, the queued ones and the ones whose write
        the disk still holds, comes back as not written (``dropped``), and one error line says
        how many and which (SR-7.14: the exit's own ``shutdown`` record is usually among them);
        a write the disk finishes later changes nothing. ``True`` when every record was
        finished. Idempotent: the records get their time once (a second call, from
        :meth:`close`, does not wait again for a disk that hangs)."""
        if not self._records_drained:
            self._records_drained = True
            self._records.finish(deadline_after(timeout_s))
            with self._unfinished_lock:
                left = list(self._unfinished.values())
                self._unfinished.clear()
            if left:
                _say_not_written(left, timeout_s)
            for record in left:
                reason = f"the record file did not take it within {timeout_s:g} s of the exit"
                self._finished(Written(record, reason, dropped=True))
        return self._records.idle

    def close(self, timeout_s: float = SIDE_DRAIN_S) -> None:
        """At exit, after :meth:`drain_records` (called here if it was not): journal copies
        and log lines get ``timeout_s`` together, best effort; what is left is counted. The
        logger gets its handlers back only when every line was written (else a stuck stderr
        would hold the exit of the thread that logs next); the writer is closed only when no
        write is in progress. Idempotent. The last outcomes stay available to take_written."""
        if self._closed:
            return
        self._closed = True
        self.drain_records()
        deadline = deadline_after(timeout_s)
        flight_left = len(self._flight.finish(deadline)) + self._flight.pending
        if flight_left:  # said before the log lane's own deadline, so it goes out below
            log.error(
                "%d flight recorder window(s) not written: the disk took none of them within "
                "the exit's deadline",
                flight_left,
            )
        self._journal.finish(deadline)
        self._logs.finish(deadline)
        if self._logger is not None and self._logs.idle:
            for handler in list(self._logger.handlers):
                if isinstance(handler, _QueueHandler):
                    self._logger.removeHandler(handler)
            for handler in self._handlers:
                self._logger.addHandler(handler)
            self._logger = None
        if self.writer is not None and self._records.idle:
            self.writer.close()
        self._wake_r.close()
        self._wake_w.close()

    # -- the lanes -------------------------------------------------------------------------

    def _write(self, records: list[StopRecord]) -> None:
        """The records queued together: as many as fit go to the file with one fsync
        (:meth:`RecordWriter.append_fitting`); after a failure, one alone, for its own
        outcome (a full disk, a record the store cannot file). Each record's JSON is made
        here, where its bytes are written."""
        while records:
            if self.writer is None:
                done, outcomes = len(records), [Written(record) for record in records]
            elif len(records) == 1:
                done, outcomes = 1, [self._write_one(records[0])]
            else:
                reopens = self.writer.reopens
                try:
                    done = self.writer.append_fitting([record.json() for record in records])
                    outcomes = [Written(record) for record in records[:done]]
                except Exception:
                    done, outcomes = 1, [self._write_one(records[0])]
                self._said_reopened(reopens, records[0])
            for written in outcomes:
                self._served(written)
            records = records[done:]

    def _write_one(self, record: StopRecord) -> Written:
        assert self.writer is not None
        reopens = self.writer.reopens
        try:
            self.writer.append(record.json())
            written = Written(record)
        except RecordError as error:
            written = Written(record, str(error), disk_full=error.disk_full)
        except RecordUsageError as error:
            written = Written(record, str(error))
        except Exception as error:  # the lane must outlive any failure: counted, not lost
            written = Written(record, f"{type(error).__name__}: {error}")
        self._said_reopened(reopens, record)
        return written

    def _said_reopened(self, before: int, record: StopRecord) -> None:
        """SR-7.9: a record file found removed or replaced is said at error priority (and
        counted by the writer: ``record_reopens``)."""
        assert self.writer is not None
        if self.writer.reopens != before:
            log.error(
                "record file %s was %s: opened it again; the record with seq %s and those "
                "after it are in the new file",
                self.writer.path,
                self.writer.last_reopen,
                record.seq,
            )

    def _served(self, written: Written) -> None:
        """The record lane's outcome of one record, unless the exit's deadline has already
        said it was not written (:meth:`drain_records`)."""
        with self._unfinished_lock:
            if self._unfinished.pop(id(written.record), None) is None:
                return
        self._finished(written)

    def _finished(self, written: Written) -> None:
        self._written.append(written)
        with contextlib.suppress(OSError):  # full (the loop will read) or closed (exiting)
            self._wake_w.send(b"\0")

    def _write_windows(self, windows: list[Window]) -> None:
        """The flight lane: each window to its file (SR-7.12). A failure is counted and logged,
        never raised: a window is evidence, as a record is (SR-7.6)."""
        assert self.flight is not None
        for window in windows:
            try:
                _, data = self.flight.write_bytes(window)
                self.flight_windows += 1
            except FlightError as error:
                self.flight_errors += 1
                log.error("flight recorder window not written: %s", error)
                continue
            except Exception as error:  # the lane must outlive any failure: counted, not lost
                self.flight_errors += 1
                log.error("flight recorder window not written: %s: %s", type(error).__name__, error)
                continue
            if self.flight_journal is not None:
                self._send_window(data, window)

    def _send_window(self, data: bytes, window: Window) -> None:
        """The window's copy to the journal, after its file (SR-13.12): a failure is a journal
        copy's, counted in ``journal_errors`` and logged; the file is the robot's evidence."""
        assert self.flight_journal is not None
        try:
            self.flight_journal(window_entry(data, window.stop.json()))
        except Exception as error:  # the journal is a copy; the lane must outlive it
            self.journal_errors += 1
            log.error(
                "the journal copy of record %s's flight recorder window not sent: %s",
                window.stop.seq,
                error,
            )

    def _send_journal(self, records: list[StopRecord]) -> None:
        assert self.journal is not None
        for record in records:
            try:
                self.journal(record.json())  # its JSON made here, where it is sent
            except Exception:  # the journal is a copy; the file is the record (docs/record.md)
                self.journal_errors += 1

    def _emit(self, lines: list[logging.LogRecord]) -> None:
        for line in lines:
            for handler in self._handlers:
                with contextlib.suppress(Exception):
                    _emit_unlocked(handler, line)


def _say_not_written(records: list[StopRecord], timeout_s: float) -> None:
    """One error line for the records the exit's deadline left unwritten: how many, their
    ``seq`` range, and the exit's own ``shutdown:REASON`` when it is among them (SR-7.14; it
    goes out on the log lane, to stderr and the journal, not to the disk that hangs)."""
    seqs = [record.seq for record in records]
    span = f"seq {min(seqs)} to {max(seqs)}" if seqs else "no seq"
    exits = [
        f"the exit's own shutdown:{record.trigger.get('reason')}"
        for record in records
        if record.event == "shutdown"
    ]
    log.error(
        "%d stop record(s) not written: the record file took none of them within %g s of the "
        "exit (%s%s); every output is off",
        len(records),
        timeout_s,
        span,
        "".join(f", {name}" for name in exits),
    )


def _emit_unlocked(handler: logging.Handler, record: logging.LogRecord) -> None:
    """Hand one line to ``handler``. A handler that writes to a descriptor (stderr) gets the
    line written there directly, holding none of its locks: a write that never returns (a
    pipe nobody reads) must not hold what the exit takes (logging's shutdown takes every
    handler's lock; the interpreter flushes ``sys.stderr``). Others get ``handle``."""
    if record.levelno < handler.level or not handler.filter(record):
        return
    fd = _descriptor(handler)
    if fd is None:
        handler.handle(record)
        return
    assert isinstance(handler, logging.StreamHandler)
    encoding = getattr(handler.stream, "encoding", None) or "utf-8"
    data = (handler.format(record) + handler.terminator).encode(encoding, "backslashreplace")
    view = memoryview(data)
    while view:
        view = view[os.write(fd, view) :]


def _descriptor(handler: logging.Handler) -> int | None:
    if not isinstance(handler, logging.StreamHandler):
        return None
    try:
        fd = handler.stream.fileno()
    except (AttributeError, OSError, ValueError):  # io.UnsupportedOperation is both
        return None
    return fd if isinstance(fd, int) else None


class _QueueHandler(logging.Handler):
    """Queues a log line for the log lane; the message is formatted here, in the thread
    that logs, so that later changes to its arguments cannot change it."""

    def __init__(self, sink: Sink) -> None:
        super().__init__()
        self.sink = sink

    def emit(self, record: logging.LogRecord) -> None:
        try:
            record.msg = record.getMessage()
            record.args = None
        except Exception:  # a bad log call must not unwind the loop
            self.handleError(record)
            return
        self.sink.log(record)
