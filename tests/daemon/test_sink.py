"""The record sink (supervisord/daemon/sink.py; SR-7.5): the loop's one way out for records, journal
entries and log lines, a bounded queue and one owned thread (docs/record.md "How a record
leaves the loop")."""

from __future__ import annotations

import logging
import threading
import time
from collections.abc import Mapping
from pathlib import Path

from supervisord.daemon.loop import OVERRUN_NS
from supervisord.daemon.sink import Sink, Written
from supervisord.record.jsonl import RecordWriter
from tests.record.conftest import make_record, seqs_in


class _GatedWriter(RecordWriter):
    """A record file on a disk that answers only when the test opens the gate."""

    def __init__(self, path: Path) -> None:
        super().__init__(path)
        self.gate = threading.Event()

    def append(self, record: Mapping[str, object]) -> None:
        self.gate.wait(10)
        super().append(record)


def _wait_written(sink: Sink, count: int) -> list[Written]:
    taken: list[Written] = []
    end = time.monotonic() + 5
    while len(taken) < count:
        assert time.monotonic() < end, taken
        taken += sink.take_written()
        time.sleep(0.005)
    return taken


def test_records_are_written_in_order_and_reported_once_fsynced(tmp_path: Path) -> None:
    """Records queued by the loop come back as acknowledged in the order given, and are in
    the file by then; the journal sees each after the file."""
    journal: list[object] = []
    writer = RecordWriter(tmp_path / "stops.jsonl")
    sink = Sink(writer, lambda entry: journal.append(entry["seq"]))
    sink.start()
    try:
        for seq in range(1, 51):
            assert sink.record(make_record(seq))
        taken = _wait_written(sink, 50)
        assert [w.entry["seq"] for w in taken] == list(range(1, 51))
        assert all(w.acknowledged for w in taken)
        assert seqs_in(tmp_path / "stops.jsonl") == list(range(1, 51))
        assert journal == list(range(1, 51))
    finally:
        sink.close()
        writer.close()


def test_a_full_queue_drops_at_once_and_never_waits(tmp_path: Path) -> None:
    """With the disk hung and the queue full, queuing another record returns at once with
    ``False``; that record comes back as dropped and is counted as such; the queued ones are
    written, in order, once the disk answers.

    "At once" takes its margin from the loop's rule: a call that held the loop for its overrun
    limit (``OVERRUN_NS``, 250 ms) would itself be an ``internal`` stop (SR-2.9), while the
    disk here stays hung for 10 s, so any wait for it shows; a busy machine's preemption of a
    few tens of milliseconds does not."""
    writer = _GatedWriter(tmp_path / "stops.jsonl")
    sink = Sink(writer, capacity=3)
    sink.start()
    try:
        for seq in range(1, 4):
            assert sink.record(make_record(seq))
        started = time.monotonic_ns()
        assert not sink.record(make_record(4))  # records 1-3 wait for the hung disk
        assert time.monotonic_ns() - started < OVERRUN_NS
        dropped = sink.take_written()
        assert [(w.entry["seq"], w.dropped) for w in dropped] == [(4, True)]
        writer.gate.set()
        later = _wait_written(sink, 3)
        assert [(w.entry["seq"], w.acknowledged) for w in later] == [
            (1, True),
            (2, True),
            (3, True),
        ]
    finally:
        writer.gate.set()
        sink.close()
        writer.close()
    assert seqs_in(tmp_path / "stops.jsonl") == [1, 2, 3]


def test_close_drains_every_queued_record_and_joins_the_thread(tmp_path: Path) -> None:
    """A clean stop: close() returns only once every queued record is on disk, and the
    sink's named thread is gone."""
    writer = RecordWriter(tmp_path / "stops.jsonl")
    sink = Sink(writer)
    sink.start()
    for seq in range(1, 201):
        sink.record(make_record(seq))
    sink.close()
    writer.close()
    assert seqs_in(tmp_path / "stops.jsonl") == list(range(1, 201))
    assert not [t for t in threading.enumerate() if t.name == "srcsd-sink"]


def test_log_lines_go_through_the_thread_and_the_handlers_come_back(tmp_path: Path) -> None:
    """Once the sink captures a logger, its lines reach the original handler from the
    sink's thread, formatted as they were when logged; close() gives the handler back."""
    seen: list[tuple[str, str]] = []

    class Remember(logging.Handler):
        def emit(self, record: logging.LogRecord) -> None:
            seen.append((threading.current_thread().name, record.getMessage()))

    logger = logging.getLogger("test-sink")
    logger.propagate = False
    handler = Remember()
    logger.addHandler(handler)
    sink = Sink(None)
    sink.start()
    sink.capture_logging(logger)
    values = [1]
    logger.warning("value %s", values)
    values.append(2)  # changed after logging: the line keeps what was logged
    sink.close()
    assert seen == [("srcsd-sink", "value [1]")]
    assert logger.handlers == [handler]
    logger.removeHandler(handler)
