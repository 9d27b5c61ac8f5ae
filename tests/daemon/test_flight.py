"""The flight recorder in the real loop (SR-7.10 to SR-7.13; docs/record.md "The flight
recorder"): a pseudo-terminal VSC, sim outputs, the JSON Lines record, on the loop's manual
clock. Each stop's window appears beside its record and replays to the same records."""

from __future__ import annotations

import io
import socket
import time
from collections.abc import Iterator
from pathlib import Path

import pytest

from supervisord.cli.replay import run_replay
from supervisord.daemon import lifecycle
from supervisord.daemon.flight import FlightSettings
from supervisord.daemon.loop import Supervisor
from supervisord.links.base import Backoff
from supervisord.links.serial_link import SerialLink
from supervisord.outputs import create_output, parse_output_spec
from supervisord.protocol.codes import VscMode
from supervisord.record.flight import read_window, window_path, windows
from supervisord.record.flight_journal import window_bytes
from supervisord.record.journal import SEND_TIMEOUT_S, JournalSink
from supervisord.record.jsonl import RecordWriter, StoredRecord, read_records
from supervisord.safety.config import OutputRole, OutputSpec, SafetyConfig
from supervisord.safety.transitions import State
from supervisord.sim.pty import PtyPort
from supervisord.testkit.wait import wait_until
from tests.daemon.peer import VscPeer
from tests.daemon.test_loop import ManualClock, _arm, run_until, serve_for, state


def _supervisor(
    tmp_path: Path, settings: FlightSettings, flight_journal: JournalSink | None = None
) -> Iterator[tuple[Supervisor, VscPeer]]:
    port = PtyPort(tmp_path / "vsc")
    clock = ManualClock()
    supervisor = Supervisor(
        SafetyConfig(
            rearm_hold_ms=100,
            outputs=(OutputSpec("drive", OutputRole.MOTION), OutputSpec("lamp", OutputRole.POWER)),
        ),
        SerialLink(str(port.path)),
        [
            create_output(parse_output_spec("drive", {"kind": "sim"})),
            create_output(parse_output_spec("lamp", {"kind": "sim", "role": "power"})),
        ],
        RecordWriter(tmp_path / "stops.jsonl", max_bytes=1 << 20, keep=2),
        backoff=Backoff(first_ms=20, max_ms=100),
        clock=clock,
        flight=settings,
        flight_journal=None if flight_journal is None else flight_journal.send,
    )
    try:
        yield supervisor, VscPeer(port, clock=clock.seconds)
    finally:
        lifecycle.shutdown(supervisor)
        port.close()


@pytest.fixture
def short(tmp_path: Path) -> Iterator[tuple[Supervisor, VscPeer]]:
    """A window of 0.5 s: the windows below start from a snapshot of the core."""
    yield from _supervisor(tmp_path, FlightSettings(window_s=0.5))


def _stop(supervisor: Supervisor, peer: VscPeer) -> int:
    """The remote's e-stop in RUN; the stop record's seq once its window is written."""
    peer.mode, peer.estop = VscMode.OPERATIONAL, 1
    run_until(supervisor, peer, lambda: state(supervisor) is State.STOPPED)
    sink = supervisor.records.sink
    assert sink is not None
    wait_until(lambda: sink.status()["flight_windows"] >= 1 and not sink.pending, what="window")
    return windows(supervisor.records.writer.path)[-1][0]  # type: ignore[union-attr]


def test_a_stop_writes_its_window_beside_the_record_and_it_replays(
    short: tuple[Supervisor, VscPeer], tmp_path: Path
) -> None:
    """SR-7.10, SR-7.12, SR-7.13: a remote e-stop in RUN, after the loop has run longer than
    the window (so the window starts from a snapshot): its window is ``stops.jsonl.flight/
    SEQ.jsonl``, starts at least the window's length before the stop, and ``srcsctl
    replay`` reproduces every record in it, the stop's included."""
    supervisor, peer = short
    lifecycle.start(supervisor)
    _arm(supervisor, peer)
    serve_for(supervisor, peer, 1.2)
    seq = _stop(supervisor, peer)
    path = window_path(tmp_path / "stops.jsonl", seq)
    window = read_window(path)
    assert window.base["kind"] == "snapshot"
    assert window.stop["to"] == "STOPPED"
    assert window.stop["seq"] == seq
    stop_ns = window.stop["mono_ns"]
    assert isinstance(stop_ns, int)
    assert stop_ns - window.base["now_ns"] >= 0.5e9
    out, errors = io.StringIO(), io.StringIO()
    assert run_replay(str(seq), tmp_path / "stops.jsonl", out, errors) == 0, out.getvalue()
    assert "replay matches the record" in out.getvalue(), out.getvalue()
    assert f"#{seq} RUN -> STOPPED" in out.getvalue()


def test_a_stop_soon_after_the_start_replays_from_the_start(tmp_path: Path) -> None:
    """SR-7.11, SR-7.13: a stop before the first snapshot: the window starts at the daemon's
    start (a fresh core with the recorded configuration), and its replay reproduces every
    record from the startup stop on."""
    for supervisor, peer in _supervisor(tmp_path, FlightSettings(window_s=60)):
        lifecycle.start(supervisor)
        _arm(supervisor, peer)
        seq = _stop(supervisor, peer)
        window = read_window(window_path(tmp_path / "stops.jsonl", seq))
        assert window.base["kind"] == "start"
        out = io.StringIO()
        assert run_replay(None, tmp_path / "stops.jsonl", out, io.StringIO()) == 0, out.getvalue()
        assert f"{seq} records compared" in out.getvalue()


def test_the_ring_bound_shortens_the_window_and_it_still_replays(tmp_path: Path) -> None:
    """SR-7.10, SR-7.11: with a ring of 16 inputs the snapshots come every 8 inputs, and the
    window holds at most the ring: shorter than its time, still replayable."""
    for supervisor, peer in _supervisor(tmp_path, FlightSettings(window_s=60, max_inputs=16)):
        lifecycle.start(supervisor)
        _arm(supervisor, peer)
        serve_for(supervisor, peer, 0.5)
        seq = _stop(supervisor, peer)
        window = read_window(window_path(tmp_path / "stops.jsonl", seq))
        assert window.base["kind"] == "snapshot"
        assert len(window.inputs) <= 16
        out = io.StringIO()
        assert run_replay(str(seq), tmp_path / "stops.jsonl", out, io.StringIO()) == 0, (
            out.getvalue()
        )


def test_a_snapshot_that_fails_is_counted_and_the_loop_goes_on(
    short: tuple[Supervisor, VscPeer], tmp_path: Path, caplog: pytest.LogCaptureFixture
) -> None:
    """SR-7.11, SR-8.7: the core holds something no snapshot can write (here put there by the
    test): the snapshot fails, is counted in ``flight_errors`` and logged, and the loop runs
    on; the robot still stops, and the next windows come once snapshots work again."""
    supervisor, peer = short
    lifecycle.start(supervisor)
    _arm(supervisor, peer)
    assert supervisor.core is not None
    supervisor.core.__dict__["unencodable"] = object()
    serve_for(supervisor, peer, 1.2)
    errors = supervisor.snapshot(supervisor.clock()).sink["flight_errors"]
    assert errors >= 2
    assert "no snapshot of the core" in caplog.text
    assert state(supervisor) is State.RUN
    del supervisor.core.__dict__["unencodable"]
    serve_for(supervisor, peer, 1.2)
    seq = _stop(supervisor, peer)
    out = io.StringIO()
    assert run_replay(str(seq), tmp_path / "stops.jsonl", out, io.StringIO()) == 0, out.getvalue()


def _journal_socket(tmp_path: Path) -> tuple[socket.socket, JournalSink]:
    """A journal socket of the test's own (journald's native protocol: datagrams) and the
    daemon's sink sending to it."""
    path = tmp_path / "journal.sock"
    server = socket.socket(socket.AF_UNIX, socket.SOCK_DGRAM)
    server.bind(str(path))
    return server, JournalSink(str(path))


def _fields(datagram: bytes) -> dict[str, str]:
    """One entry in journald's native protocol, every value on one line (the window's are)."""
    return dict(line.split("=", 1) for line in datagram.decode().splitlines())


def test_a_stops_window_goes_to_the_journal_after_its_file(tmp_path: Path) -> None:
    """SR-13.12, SR-7.12: with the journal on, a stop's window is written beside the record and
    then sent to the journal as an entry of its own: the stop's seq, and the file's bytes,
    which come back whole from the entry."""
    server, sink = _journal_socket(tmp_path)
    with server, sink:
        for supervisor, peer in _supervisor(tmp_path, FlightSettings(window_s=60), sink):
            lifecycle.start(supervisor)
            _arm(supervisor, peer)
            seq = _stop(supervisor, peer)
            server.settimeout(30)
            fields = _fields(server.recv(1 << 20))
            assert fields["SRCS_SEQ"] == str(seq)
            assert fields["SYSLOG_IDENTIFIER"] == "srcsd-flight"
            file = window_path(tmp_path / "stops.jsonl", seq).read_bytes()
            assert window_bytes(fields) == file
            assert supervisor.snapshot(supervisor.clock()).sink["journal_errors"] == 0


def test_a_stuck_journal_costs_the_windows_copy_never_the_stop(tmp_path: Path) -> None:
    """SR-13.12, SR-10, SR-7.12: a journald that takes nothing (its socket's queue full: the send
    waits its 2 s and is refused). A remote e-stop in RUN still stops at once: STOPPED, every
    output off, the stop record in the file and its window written; the window's journal copy
    is then counted in ``journal_errors``, nothing else."""
    server, sink = _journal_socket(tmp_path)
    filler = socket.socket(socket.AF_UNIX, socket.SOCK_DGRAM)
    filler.setblocking(False)
    with server, sink, filler:
        try:
            while True:
                filler.sendto(b"MESSAGE=fill\n", str(tmp_path / "journal.sock"))
        except BlockingIOError:
            pass  # journald's queue is full: it takes nothing more
        for supervisor, peer in _supervisor(tmp_path, FlightSettings(window_s=60), sink):
            _stop_with_the_journal_stuck(supervisor, peer, tmp_path)


def _stop_with_the_journal_stuck(supervisor: Supervisor, peer: VscPeer, tmp_path: Path) -> None:
    lifecycle.start(supervisor)
    _arm(supervisor, peer)
    peer.mode, peer.estop = VscMode.OPERATIONAL, 1
    run_until(supervisor, peer, lambda: state(supervisor) is State.STOPPED)
    assert not any(output.device_level for output in supervisor.outputs.values())  # type: ignore[attr-defined]
    lane = supervisor.records.sink
    assert lane is not None
    wait_until(lambda: lane.status()["flight_windows"] == 1, what="the window's file")
    started = time.monotonic()
    wait_until(lambda: lane.status()["journal_errors"] == 1, what="the copy refused")
    assert time.monotonic() - started < SEND_TIMEOUT_S + 30  # refused, not hung
    stops = [
        item.data
        for item in read_records(tmp_path / "stops.jsonl")
        if isinstance(item, StoredRecord) and item.data.get("to") == "STOPPED"
    ]
    assert stops[-1]["from"] == "RUN"
    assert windows(tmp_path / "stops.jsonl")[-1][0] == stops[-1]["seq"]
