"""The flight recorder in the real loop (SR-7.10 to SR-7.13; docs/record.md "The flight
recorder"): a pseudo-terminal VSC, sim outputs, the JSON Lines record, on the loop's manual
clock. Each stop's window appears beside its record and replays to the same records."""

from __future__ import annotations

import io
from collections.abc import Iterator
from pathlib import Path

import pytest

from supervisord.cli.replay import run_replay
from supervisord.daemon.flight import FlightSettings
from supervisord.daemon.loop import Supervisor
from supervisord.links.base import Backoff
from supervisord.links.serial_link import SerialLink
from supervisord.outputs import create_output, parse_output_spec
from supervisord.protocol.codes import VscMode
from supervisord.record.flight import read_window, window_path, windows
from supervisord.record.jsonl import RecordWriter
from supervisord.safety.config import OutputRole, OutputSpec, SafetyConfig
from supervisord.safety.transitions import State
from supervisord.sim.pty import PtyPort
from supervisord.testkit.wait import wait_until
from tests.daemon.peer import VscPeer
from tests.daemon.test_loop import ManualClock, _arm, run_until, serve_for, state


def _supervisor(tmp_path: Path, settings: FlightSettings) -> Iterator[tuple[Supervisor, VscPeer]]:
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
    )
    try:
        yield supervisor, VscPeer(port, clock=clock.seconds)
    finally:
        supervisor.shutdown()
        port.close()


@pytest.fixture
def short(tmp_path: Path) -> Iterator[tuple[Supervisor, VscPeer]]:
    """A window of 0.5 s: the windows below start from a snapshot of the core."""
    yield from _supervisor(tmp_path, FlightSettings(window_s=0.5))


def _stop(supervisor: Supervisor, peer: VscPeer) -> int:
    """The remote's e-stop in RUN; the stop record's seq once its window is written."""
    peer.mode, peer.estop = VscMode.OPERATIONAL, 1
    run_until(supervisor, peer, lambda: state(supervisor) is State.STOPPED)
    sink = supervisor.sink
    assert sink is not None
    wait_until(lambda: sink.status()["flight_windows"] >= 1 and not sink.pending, what="window")
    return windows(supervisor.writer.path)[-1][0]  # type: ignore[union-attr]


def test_a_stop_writes_its_window_beside_the_record_and_it_replays(
    short: tuple[Supervisor, VscPeer], tmp_path: Path
) -> None:
    """SR-7.10, SR-7.12, SR-7.13: a remote e-stop in RUN, after the loop has run longer than
    the window (so the window starts from a snapshot): its window is ``stops.jsonl.flight/
    SEQ.jsonl``, starts at least the window's length before the stop, and ``srcsctl
    replay`` reproduces every record in it, the stop's included."""
    supervisor, peer = short
    supervisor.start()
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
        supervisor.start()
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
        supervisor.start()
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
    supervisor.start()
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
