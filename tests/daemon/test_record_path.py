"""The record path (``supervisord/daemon/record_path.py``; SR-7.4, SR-7.7, SR-7.12): each record
handed in the apply order comes back finished, typed and in order, as the file holds it; a
record the sink cannot take comes back at once, counted; a stop's window follows its record.
A real record file and the sink's real threads, no loop."""

from __future__ import annotations

import dataclasses
import datetime as dt
import json
import logging
import threading
import time
from collections.abc import Callable, Mapping
from pathlib import Path

import pytest

from supervisord import __version__
from supervisord.daemon.flight import FlightSettings
from supervisord.daemon.record_path import NOT_RUNNING, RecordPath
from supervisord.record.flight import windows
from supervisord.record.jsonl import RecordUsageError, RecordWriter
from supervisord.record.stop import StopRecord, read_record
from supervisord.safety.config import SafetyConfig
from supervisord.safety.core import SafetyCore
from supervisord.safety.decision import Record
from supervisord.safety.transitions import State

START = 1_000_000_000
WALL = dt.datetime(2026, 12, 6, 12, 0, tzinfo=dt.timezone.utc)


def _records(count: int) -> list[Record]:
    """The core's startup record, then ``count - 1`` more numbered after it; the last one is
    a change into STOPPED (a stop, whose window goes to the flight lane)."""
    first = SafetyCore(SafetyConfig(), START).decision.records[0]
    made = [first]
    for n in range(2, count + 1):
        stop = n == count
        made.append(
            dataclasses.replace(
                first,
                sequence=n,
                monotonic_ns=START + n,
                previous=State.RUN if stop else State.STOPPED,
                state=State.STOPPED,
            )
        )
    return made


def _path(tmp_path: Path, **kwargs: object) -> RecordPath:
    writer = RecordWriter(tmp_path / "stops.jsonl")
    return RecordPath(SafetyConfig(), writer, wall_clock=lambda: WALL, **kwargs)  # type: ignore[arg-type]


def _until(what: Callable[[], bool]) -> None:
    deadline = time.monotonic() + 30  # a margin for a busy machine: the rule is the order
    while not what():
        assert time.monotonic() < deadline, "timed out"
        time.sleep(0.005)


def test_each_record_comes_back_typed_in_order_as_the_file_holds_it(tmp_path: Path) -> None:
    """SR-7.4, SR-7.7: the records handed in come back from ``take_written`` in their order,
    each the typed record whose JSON is the file's line; ``seq`` continues after the offset,
    and only the first record of a start names the version (docs/record.md)."""
    path = _path(tmp_path)
    path.sequence_offset = 40
    path.start()
    path.began(START)
    handed = [path.write(record) for record in _records(3)]
    assert handed == [(), (), ()]  # the sink took each: nothing finished at once
    finished: list[StopRecord] = []

    def taken() -> bool:
        finished.extend(path.take_written())
        return len(finished) == 3

    _until(taken)
    assert [r.seq for r in finished] == [41, 42, 43]
    assert [r.version for r in finished] == [__version__, None, None]
    path.close()
    lines = (tmp_path / "stops.jsonl").read_text().splitlines()
    assert [json.loads(line) for line in lines] == [r.json() for r in finished]
    assert [read_record(json.loads(line)) for line in lines] == finished
    assert (path.record_errors, path.records_dropped) == (0, 0)


def test_a_record_before_the_start_comes_back_at_once_counted(tmp_path: Path) -> None:
    """docs/record.md "A full disk": a record the sink cannot take (not running) is finished
    at once, counted as not written and dropped, never a stop of its own; it is still handed
    back to be pushed, in its place in the order."""
    path = _path(tmp_path)
    finished = path.write(_records(1)[0])
    assert [r.seq for r in finished] == [1]
    assert (path.record_errors, path.records_dropped) == (1, 1)
    assert path.status()["records_pending"] == 0
    path.close()


def test_a_stop_sends_its_window_after_its_record(tmp_path: Path) -> None:
    """SR-7.12: a change into STOPPED queues the flight window of its record (named by its
    ``seq``); the records that are no stop queue none."""
    path = _path(tmp_path, flight=FlightSettings(window_s=1.0))
    path.start()
    path.began(START)
    for record in _records(3):
        path.write(record)
    sink = path.sink
    assert sink is not None
    _until(lambda: sink.status()["flight_windows"] >= 1 and not sink.pending)
    path.drain()
    path.close()
    assert [seq for seq, _ in windows(tmp_path / "stops.jsonl")] == [3]
    assert path.status()["flight_windows"] == 1


def test_the_record_is_typed_to_the_edge_its_json_made_on_the_lanes(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """SR-7.7: the loop hands the typed record on; its JSON is made only where its bytes are
    written or sent (the sink's record, journal and flight lanes), never on the loop's thread,
    and what comes back is the typed record itself, the one the flight window carries too."""
    made_on: list[str] = []
    to_json = StopRecord.json

    def json_seen(record: StopRecord) -> dict[str, object]:
        made_on.append(threading.current_thread().name)
        return to_json(record)

    monkeypatch.setattr(StopRecord, "json", json_seen)
    journal: list[Mapping[str, object]] = []
    path = _path(tmp_path, journal=journal.append, flight=FlightSettings(window_s=1.0))
    path.start()
    path.began(START)
    for record in _records(2):
        assert path.write(record) == ()
    assert threading.current_thread().name not in made_on
    finished: list[StopRecord] = []

    def taken() -> bool:
        finished.extend(path.take_written())
        return len(finished) == 2

    _until(taken)
    sink = path.sink
    assert sink is not None
    _until(lambda: sink.status()["flight_windows"] == 1 and len(journal) == 2)
    path.close()
    assert threading.current_thread().name not in made_on
    assert {"srcsd-record", "srcsd-journal", "srcsd-flight"} <= set(made_on)
    assert journal == [to_json(r) for r in finished]
    ((_, window),) = windows(tmp_path / "stops.jsonl")
    header = json.loads(window.read_text().splitlines()[0])
    assert header["stop"] == to_json(finished[1])


# The tests below build the path in their body: the mutation runner traces a test's body, not
# its fixtures (docs/verification.md "The daemon's parts").


def test_the_drain_at_exit_writes_every_queued_record_and_hands_them_back(
    tmp_path: Path,
) -> None:
    """SR-7.7: at exit, ``drain`` waits for the record file to take every record still queued
    and returns them all, in order, to push; the file holds each one when it returns (the
    records are handed in and drained at once, without waiting for the sink first)."""
    path = _path(tmp_path)
    path.start()
    path.began(START)
    many = _records(200)
    for record in many:
        assert path.write(record) == ()
    finished = path.drain()
    assert [r.seq for r in finished] == [r.sequence for r in many]
    lines = (tmp_path / "stops.jsonl").read_text().splitlines()
    assert [json.loads(line)["seq"] for line in lines] == [r.sequence for r in many]
    assert (path.record_errors, path.records_dropped) == (0, 0)
    path.close()


def test_a_path_never_started_closes_its_writer(tmp_path: Path) -> None:
    """SR-7.7: a daemon that ends before its loop started (no sink) still closes the record
    file: the writer takes no record after ``close``."""
    writer = RecordWriter(tmp_path / "stops.jsonl")
    path = RecordPath(SafetyConfig(), writer, wall_clock=lambda: WALL)
    path.close()
    with pytest.raises(RecordUsageError, match="is closed"):
        writer.append({"seq": 1})


def test_a_record_not_written_is_logged(tmp_path: Path, caplog: pytest.LogCaptureFixture) -> None:
    """docs/record.md "A full disk": a record not written is an error line in the log, with
    why (here: the sink not running), never a stop of its own."""
    caplog.set_level(logging.ERROR, logger="srcsd")
    path = _path(tmp_path)
    path.write(_records(1)[0])
    lines = [r.getMessage() for r in caplog.records if r.levelno == logging.ERROR]
    assert lines == [f"stop record not written: {NOT_RUNNING}"]
    path.close()
