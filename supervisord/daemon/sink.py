"""The one way slow work leaves the loop: the stop record (with its fsync), the journal and
log lines (issue 11, ``docs/record.md`` "How a record leaves the loop").

The loop hands work to :class:`Sink` and never waits for it: :meth:`Sink.record` and the log
handler put an item on a bounded queue and return at once. One owned, named thread
(``srcsd-sink``) takes the items in order: for a record, it appends it to the JSON Lines file
(write and fsync: the record is acknowledged only then), then sends it to the journal; for a
log line, it hands it to the handlers the process had. Each record's outcome comes back to
the loop as a :class:`Written` through :meth:`Sink.take_written`, in the order the records
were given, and a byte on :meth:`Sink.fileno` wakes the loop for it; only then does the loop
push the record to the API's subscribers, so a pushed record is an acknowledged one
(SR-7, the power-cut scenario of ``docs/system-tier.md``).

A full queue never blocks the loop: the record is not written, and comes back at once as a
:class:`Written` with ``dropped`` set (counted in ``status`` as ``record_errors`` and
``records_dropped``). :meth:`Sink.close` drains every queued item and joins the thread (the
SIGTERM path).
"""

from __future__ import annotations

import collections
import contextlib
import logging
import socket
import threading
from collections.abc import Callable, Mapping
from dataclasses import dataclass
from typing import Final

from supervisord.record.jsonl import RecordError, RecordUsageError, RecordWriter

RECORD_CAPACITY: Final = 4096
"""Records waiting for the disk at most (about a minute of the worst client traffic the
record budget allows on a disk that takes 10 ms per fsync)."""
LOG_CAPACITY: Final = 1024
"""Log lines waiting at most; past it log lines are dropped (counted) before any record."""

JournalWrite = Callable[[Mapping[str, object]], object]


@dataclass(frozen=True, slots=True)
class Written:
    """What became of one record: acknowledged (``error`` ``None``, not ``dropped``), or not
    written because the file refused it (``error``) or the queue was full (``dropped``)."""

    entry: Mapping[str, object]
    error: str | None = None
    disk_full: bool = False
    dropped: bool = False

    @property
    def acknowledged(self) -> bool:
        return self.error is None and not self.dropped


class Sink:
    """The bounded queue and its writer thread (see the module docstring).

    ``writer``: the record file (``None``: no file, records are acknowledged as they come);
    ``journal``: a callable sending one record to the journal (its failures are counted in
    ``journal_errors``, never raised). Construct, then :meth:`start`; :meth:`close` once.
    """

    def __init__(
        self,
        writer: RecordWriter | None,
        journal: JournalWrite | None = None,
        *,
        capacity: int = RECORD_CAPACITY,
        log_capacity: int = LOG_CAPACITY,
    ) -> None:
        self.writer, self.journal = writer, journal
        self.capacity, self.log_capacity = capacity, log_capacity
        self.journal_errors = 0
        self.logs_dropped = 0
        self._items: collections.deque[tuple[str, object]] = collections.deque()
        self._records_queued = 0
        self._logs_queued = 0
        self._written: collections.deque[Written] = collections.deque()
        self._cond = threading.Condition()
        self._closing = False
        self._wake_r, self._wake_w = socket.socketpair()
        self._wake_r.setblocking(False)
        self._wake_w.setblocking(False)
        self._thread = threading.Thread(target=self._run, name="srcsd-sink")
        self._handlers: list[logging.Handler] = []
        self._logger: logging.Logger | None = None

    # -- the loop's side -------------------------------------------------------------------

    def start(self) -> None:
        """Start the writer thread."""
        self._thread.start()

    def record(self, entry: Mapping[str, object]) -> bool:
        """Queue one record; never waits. ``False``: the queue was full, the record is not
        written, and its :class:`Written` (``dropped``) is ready at once."""
        with self._cond:
            if self._closing or self._records_queued >= self.capacity:
                self._written.append(Written(entry, "the record queue is full", dropped=True))
                self._wake()
                return False
            self._items.append(("record", entry))
            self._records_queued += 1
            self._cond.notify()
        return True

    def log(self, record: logging.LogRecord) -> None:
        """Queue one log line for the handlers captured by :meth:`capture_logging`."""
        with self._cond:
            if self._closing or self._logs_queued >= self.log_capacity:
                self.logs_dropped += 1
                return
            self._items.append(("log", record))
            self._logs_queued += 1
            self._cond.notify()

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
        return self._records_queued

    def capture_logging(self, logger: logging.Logger) -> None:
        """Route ``logger``'s lines (the root logger: every line of the process) through the
        queue: its handlers are replaced by one that queues, and run on the thread."""
        self._logger = logger
        self._handlers = list(logger.handlers)
        for handler in self._handlers:
            logger.removeHandler(handler)
        logger.addHandler(_QueueHandler(self))

    def close(self) -> None:
        """Finish every queued item, join the thread, give the logger its handlers back.
        Idempotent. The outcomes of the last records stay available to take_written."""
        with self._cond:
            if self._closing and not self._thread.is_alive():
                return
            self._closing = True
            self._cond.notify()
        if self._thread.is_alive():
            self._thread.join()
        if self._logger is not None:
            for handler in list(self._logger.handlers):
                if isinstance(handler, _QueueHandler):
                    self._logger.removeHandler(handler)
            for handler in self._handlers:
                self._logger.addHandler(handler)
            self._logger = None
        self._wake_r.close()
        self._wake_w.close()

    # -- the thread ------------------------------------------------------------------------

    def _run(self) -> None:
        while True:
            with self._cond:
                while not self._items and not self._closing:
                    self._cond.wait()
                if not self._items:
                    return  # closing, and everything is done
                kind, item = self._items.popleft()
            if kind == "record":
                assert isinstance(item, Mapping)
                written = self._write(item)
                with self._cond:
                    self._records_queued -= 1
                    self._written.append(written)
                self._wake()
            else:
                assert isinstance(item, logging.LogRecord)
                with self._cond:
                    self._logs_queued -= 1
                for handler in self._handlers:
                    with contextlib.suppress(Exception):
                        handler.handle(item)

    def _write(self, entry: Mapping[str, object]) -> Written:
        written = Written(entry)
        if self.writer is not None:
            try:
                self.writer.append(entry)
            except RecordError as error:
                written = Written(entry, str(error), disk_full=error.disk_full)
            except RecordUsageError as error:
                written = Written(entry, str(error))
            except Exception as error:  # the thread must outlive any failure: counted, not lost
                written = Written(entry, f"{type(error).__name__}: {error}")
        if self.journal is not None:
            try:
                self.journal(entry)
            except Exception:  # the journal is a copy; the file is the record (docs/record.md)
                self.journal_errors += 1
        return written

    def _wake(self) -> None:
        with contextlib.suppress(BlockingIOError, OSError):
            self._wake_w.send(b"\0")


class _QueueHandler(logging.Handler):
    """Queues a log line for the sink's thread; the message is formatted here, in the loop,
    so that later changes to its arguments cannot change it."""

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
