"""The record sink (supervisord/daemon/sink.py; SR-7.5): the loop's one way out for records, journal
entries and log lines, a bounded queue and one owned thread (docs/record.md "How a record
leaves the loop")."""

from __future__ import annotations

import logging
import os
import threading
import time
from collections.abc import Mapping, Sequence
from pathlib import Path

import pytest

from supervisord.daemon.loop import OVERRUN_NS
from supervisord.daemon.sink import RECORD_DRAIN_S, Sink, Written
from supervisord.record.jsonl import RecordWriter
from supervisord.testkit.wait import wait_until
from tests.record.conftest import make_stop_record, seqs_in


class _GatedWriter(RecordWriter):
    """A record file on a disk that answers only when the test opens the gate."""

    def __init__(self, path: Path) -> None:
        super().__init__(path)
        self.gate = threading.Event()
        self.entered = threading.Event()  # a write is waiting at the gate

    def append_fitting(self, records: Sequence[Mapping[str, object]]) -> int:
        self.entered.set()
        self.gate.wait(10)
        return super().append_fitting(records)


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
            assert sink.record(make_stop_record(seq))
        taken = _wait_written(sink, 50)
        assert [w.record.seq for w in taken] == list(range(1, 51))
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
        assert sink.record(make_stop_record(1))
        assert writer.entered.wait(10)  # record 1 is in the hung write: 2 and 3 wait
        for seq in range(2, 5):
            assert sink.record(make_stop_record(seq))
        started = time.monotonic_ns()
        assert not sink.record(make_stop_record(5))  # records 2-4 wait behind the hung disk
        assert time.monotonic_ns() - started < OVERRUN_NS
        dropped = sink.take_written()
        assert [(w.record.seq, w.dropped) for w in dropped] == [(5, True)]
        writer.gate.set()
        later = _wait_written(sink, 4)
        assert [(w.record.seq, w.acknowledged) for w in later] == [
            (1, True),
            (2, True),
            (3, True),
            (4, True),
        ]
    finally:
        writer.gate.set()
        sink.close()
        writer.close()
    assert seqs_in(tmp_path / "stops.jsonl") == [1, 2, 3, 4]


def test_close_drains_every_queued_record_and_joins_the_thread(tmp_path: Path) -> None:
    """A clean stop: close() returns only once every queued record is on disk, and the
    sink's named thread is gone."""
    writer = RecordWriter(tmp_path / "stops.jsonl")
    sink = Sink(writer)
    sink.start()
    for seq in range(1, 201):
        sink.record(make_stop_record(seq))
    sink.close()
    writer.close()
    assert seqs_in(tmp_path / "stops.jsonl") == list(range(1, 201))
    assert not [t for t in threading.enumerate() if t.name.startswith("srcsd-")]


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
    assert seen == [("srcsd-log", "value [1]")]
    assert logger.handlers == [handler]
    logger.removeHandler(handler)


def test_a_hung_journal_holds_no_record_and_close_does_not_wait_for_it(tmp_path: Path) -> None:
    """SR-7.5, SR-7.7: the journal never answers. Every record is still written and
    acknowledged (the journal copy has a lane of its own); close() returns although the
    journal still hangs (a deadline, not a join), and the copies it never sent are counted
    in ``journal_dropped``."""
    hung = threading.Event()
    writer = RecordWriter(tmp_path / "stops.jsonl")
    sink = Sink(writer, lambda entry: hung.wait(), journal_capacity=4)
    sink.start()
    try:
        for seq in range(1, 21):
            assert sink.record(make_stop_record(seq))
        taken = _wait_written(sink, 20)
        assert all(w.acknowledged for w in taken)
        assert seqs_in(tmp_path / "stops.jsonl") == list(range(1, 21))
        sink.drain_records()
        sink.close(timeout_s=0.0)
        assert (
            sink.status()["journal_dropped"] >= 20 - 4 - 1
        )  # all but the queued and the one in hand
    finally:
        hung.set()
        sink.close()
        writer.close()


def test_a_stuck_log_handler_holds_no_record(tmp_path: Path) -> None:
    """SR-7.5, SR-7.7: a log handler that never returns (a stderr nobody reads): records are
    still written, log lines past the lane's queue are counted in ``log_lines_dropped``, and
    close() returns without giving the logger its stuck handler back (the next line logged
    would hang the thread that logs it)."""
    stuck = threading.Event()

    class Stuck(logging.Handler):
        def emit(self, record: logging.LogRecord) -> None:
            stuck.wait()

    logger = logging.getLogger("test-sink-stuck")
    logger.propagate = False
    handler = Stuck()
    logger.addHandler(handler)
    writer = RecordWriter(tmp_path / "stops.jsonl")
    sink = Sink(writer, log_capacity=8)
    sink.start()
    sink.capture_logging(logger)
    try:
        for n in range(50):
            logger.warning("line %d", n)
        for seq in range(1, 11):
            assert sink.record(make_stop_record(seq))
        assert all(w.acknowledged for w in _wait_written(sink, 10))
        assert sink.status()["log_lines_dropped"] >= 50 - 8 - 1
        sink.close(timeout_s=0.0)
        assert handler not in logger.handlers
    finally:
        stuck.set()
        sink.close()
        writer.close()
        for extra in list(logger.handlers):
            logger.removeHandler(extra)


def test_drain_records_gives_up_at_its_deadline_and_says_what_was_lost(
    tmp_path: Path, caplog: pytest.LogCaptureFixture
) -> None:
    """SR-7.7, SR-7.14: at exit the disk does not answer. drain_records() returns at its
    deadline (False: not everything was written); every record not finished comes back as not
    written (dropped, with the reason), in order: the one in the hung write as well as those
    queued behind it (a hung write is not a written record), and one error line says how many
    and which. When the disk answers later, that record gets no second outcome."""
    writer = _GatedWriter(tmp_path / "stops.jsonl")
    sink = Sink(writer)
    sink.start()
    try:
        assert sink.record(make_stop_record(1))
        assert writer.entered.wait(10)  # record 1 is in the hung write
        for seq in range(2, 6):
            assert sink.record(make_stop_record(seq))
        with caplog.at_level(logging.ERROR, logger="srcsd"):
            assert not sink.drain_records(timeout_s=0.0)
        lost = sink.take_written()
        assert [w.record.seq for w in lost] == [1, 2, 3, 4, 5]
        assert all(w.dropped and "exit" in (w.error or "") for w in lost)
        said = [r.getMessage() for r in caplog.records if "not written" in r.getMessage()]
        assert len(said) == 1, said
        assert said[0].startswith("5 stop record(s) not written"), said
        assert "seq 1 to 5" in said[0], said
        assert not sink.record(make_stop_record(6))  # nothing is taken after the drain
        assert [w.record.seq for w in sink.take_written()] == [6]
        # close() after the drain does not give the hung disk its time again: it returns
        # well before RECORD_DRAIN_S (the rule: the records get that time once).
        started = time.monotonic()
        sink.close(timeout_s=0.0)
        assert time.monotonic() - started < RECORD_DRAIN_S
        writer.gate.set()  # the disk answers: record 1 is written, but it was said lost
        wait_until(lambda: sink.pending == 0, what="the hung write to return")
        assert sink.take_written() == []  # the lane gives its outcomes before it is idle
    finally:
        writer.gate.set()
        sink.close()
        writer.close()


def test_records_queued_together_share_one_fsync(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """SR-7.7: records that queued up behind a slow write go to the file with one fsync,
    not one each (at the exit's deadline, a queue on a slow disk is written in one go); each
    is acknowledged, in order."""
    writer = _GatedWriter(tmp_path / "stops.jsonl")
    sink = Sink(writer)
    sink.start()
    try:
        assert sink.record(make_stop_record(1))
        assert writer.entered.wait(10)
        for seq in range(2, 102):
            assert sink.record(make_stop_record(seq))
        synced: list[int] = []
        real_fsync = os.fsync

        def fsync(fd: int) -> None:
            synced.append(fd)
            real_fsync(fd)

        monkeypatch.setattr(os, "fsync", fsync)
        writer.gate.set()
        taken = _wait_written(sink, 101)
        assert [w.record.seq for w in taken if w.acknowledged] == list(range(1, 102))
        # record 1, then 2-101 together; each a stop, also in the transitions' file; and each
        # file's directory once, before its first record (the open leaves it to the lane)
        assert len(synced) <= 2 * 2 + 2
    finally:
        writer.gate.set()
        sink.close()
        writer.close()
    assert seqs_in(tmp_path / "stops.jsonl") == list(range(1, 102))
