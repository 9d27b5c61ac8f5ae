"""The main loop with real parts: a pseudo-terminal VSC, sim outputs mirrored to files, the
JSON Lines stop record. A small VSC peer in the test answers key 85 and sends heartbeats."""

from __future__ import annotations

import fcntl
import json
import os
import socket
import struct
import termios
import threading
import time
from collections.abc import Callable, Iterable, Iterator, Mapping, Sequence
from pathlib import Path
from typing import Any

import pytest

from supervisord.daemon import lifecycle, link_port, loop
from supervisord.daemon.loop import Listener, Supervisor
from supervisord.links.base import Backoff
from supervisord.links.hid_link import HidLink
from supervisord.links.serial_link import SerialLink
from supervisord.outputs import create_output, parse_output_spec
from supervisord.protocol.codes import VscMode
from supervisord.protocol.hid import HidInput, encode_hid_input
from supervisord.protocol.messages import UserHeartbeat, VscHeartbeat
from supervisord.record.jsonl import RecordWriter, StoredRecord, read_records
from supervisord.safety.config import OutputRole, OutputSpec, SafetyConfig
from supervisord.safety.transitions import State
from supervisord.sim.pty import PtyPort
from tests.api.samples import status_reply
from tests.daemon.peer import VscPeer
from tests.record.conftest import full_disk

START_OFFSET_NS = 10 * 3600 * 1_000_000_000
"""A manual clock starts this far from the real one: a part of the loop that read the real
clock instead of the loop's would see its deadlines hours away and fail the test (SR-2.11)."""


class ManualClock:
    """The daemon's monotonic clock in these tests (nanoseconds): it stands still until the
    test moves it, so a deadline (the re-arm hold, the takeover dwell, the link timeout)
    passes exactly when the test says, with no waiting. ``seconds`` is the same clock for the
    VSC peer. It starts hours away from the real clock: the loop has one clock."""

    def __init__(self) -> None:
        self.now = time.monotonic_ns() + START_OFFSET_NS

    def __call__(self) -> int:
        return self.now

    def seconds(self) -> float:
        return self.now / 1e9

    def advance(self, ns: int) -> None:
        self.now += ns


@pytest.fixture
def rig(tmp_path: Path) -> Iterator[tuple[Supervisor, VscPeer, Path]]:
    port = PtyPort(tmp_path / "vsc")
    clock = ManualClock()
    outputs = [
        create_output(parse_output_spec("drive", {"kind": "sim", "path": str(tmp_path / "drive")})),
        create_output(
            parse_output_spec(
                "lamp", {"kind": "sim", "role": "power", "path": str(tmp_path / "lamp")}
            )
        ),
    ]
    safety = SafetyConfig(
        rearm_hold_ms=100,
        outputs=(OutputSpec("drive", OutputRole.MOTION), OutputSpec("lamp", OutputRole.POWER)),
    )
    supervisor = Supervisor(
        safety,
        SerialLink(str(port.path)),
        outputs,
        RecordWriter(tmp_path / "stops.jsonl"),
        backoff=Backoff(first_ms=20, max_ms=100),
        clock=clock,
    )
    yield supervisor, VscPeer(port, clock=clock.seconds), tmp_path
    lifecycle.shutdown(supervisor)
    port.close()


def turn(supervisor: Supervisor, peer: VscPeer) -> None:
    """One turn of the peer and the loop. On a ``ManualClock`` the clock first moves to the
    next thing due ahead, the peer's heartbeat or the core's deadline, so the loop's wait ends
    at once: it never waits for time that the test can simply let pass. What the peer sent is
    then let arrive before the loop turns (the kernel hands a pty's bytes over on its own
    time): each frame is read on the manual clock's instant it was sent, however busy the
    machine is."""
    clock = supervisor.clock
    if isinstance(clock, ManualClock):
        due = [int(peer.next_due * 1e9) + 1_000]  # + 1 us: the peer's float seconds, rounded
        if supervisor.decision is not None:
            due.append(supervisor.decision.next_deadline)
        clock.now = min((t for t in due if t > clock.now), default=clock.now + 1_000_000)
    written = peer.written
    if peer.serve() and isinstance(clock, ManualClock):
        arrived(supervisor, peer.written - written)
    supervisor.step()


def arrived(supervisor: Supervisor, count: int, limit: float = 10.0) -> None:
    """Wait (in real time: the manual clock stands still) until the link has at least
    ``count`` bytes to read: a pty may hand a write over in parts."""
    fd = supervisor.link.fileno() if supervisor.link.is_open else None
    end = time.monotonic() + limit
    while fd is not None and _waiting(fd) < count:
        assert time.monotonic() < end, f"{count} bytes did not arrive on the link in {limit} s"
        time.sleep(0.0005)


def _waiting(fd: int) -> int:
    """Bytes waiting to be read on a tty (``FIONREAD``)."""
    (count,) = struct.unpack("i", fcntl.ioctl(fd, termios.FIONREAD, bytes(4)))
    return int(count)


def run_until(
    supervisor: Supervisor, peer: VscPeer, done: Callable[[], bool], limit: float = 5.0
) -> None:
    end = time.monotonic() + limit
    while not done():
        assert time.monotonic() < end, f"timed out in {supervisor.decision}"
        turn(supervisor, peer)


def serve_for(supervisor: Supervisor, peer: VscPeer, seconds: float) -> None:
    """Run the loop and the peer for ``seconds`` of the loop's clock (e.g. the re-arm hold and
    the takeover's non-Operational dwell, docs/safety.md "Re-arming")."""
    if isinstance(clock := supervisor.clock, ManualClock):
        end = clock.now + int(seconds * 1e9)
        while clock.now < end:
            turn(supervisor, peer)
        return
    end_s = time.monotonic() + seconds  # the real clock: a test of real time (a hung disk)
    while time.monotonic() < end_s:
        turn(supervisor, peer)


def level(tmp_path: Path, name: str) -> str:
    return (tmp_path / name).read_text().strip()


def active(supervisor: Supervisor) -> frozenset[str]:
    return supervisor.decision.active_names if supervisor.decision else frozenset()


def state(supervisor: Supervisor) -> State | None:
    return supervisor.decision.state if supervisor.decision else None


def test_start_takeover_estop_silence_unplug(rig: tuple[Supervisor, VscPeer, Path]) -> None:
    """Outputs start off; a takeover runs them; a remote e-stop, VSC silence and an unplug
    each stop them and are recorded with their cause; the user heartbeat flows meanwhile."""
    supervisor, peer, tmp = rig
    lifecycle.start(supervisor)
    assert (level(tmp, "drive"), level(tmp, "lamp")) == ("0", "0")

    _arm(supervisor, peer)
    assert (level(tmp, "drive"), level(tmp, "lamp")) == ("1", "1")
    run_until(supervisor, peer, lambda: UserHeartbeat(0) in peer.received)

    peer.mode, peer.estop = VscMode.LOCAL, 1
    run_until(supervisor, peer, lambda: state(supervisor) is State.STOPPED)
    assert (level(tmp, "drive"), level(tmp, "lamp")) == ("0", "0")

    peer.silent = True
    run_until(supervisor, peer, lambda: "vsc_link_lost" in active(supervisor))

    peer.port.unplug()
    run_until(supervisor, peer, lambda: "transport_fault" in active(supervisor))
    peer.port.replug()
    peer.silent = False
    run_until(supervisor, peer, lambda: "transport_fault" not in active(supervisor))
    assert supervisor.port.opens == 2
    assert state(supervisor) is State.STOPPED  # a reconnect is a new start

    # Records reach the file on the sink's thread: read it once every record is written.
    sink = supervisor.records.sink
    run_until(supervisor, peer, lambda: sink is not None and not sink.pending)
    lines = (tmp / "stops.jsonl").read_text().splitlines()
    stored = [r for r in read_records(tmp / "stops.jsonl") if isinstance(r, StoredRecord)]
    assert len(stored) == len(lines)
    raised = {
        change["name"]
        for line in lines
        for change in json.loads(line)["changes"]
        if change["change"] == "raised"
    }
    assert {"vsc_estop", "vsc_link_lost", "transport_fault"} <= raised
    assert json.loads((tmp / "stops.jsonl").read_text().splitlines()[0])["to"] == "STOPPED"


def test_missing_port_at_start_is_not_fatal(tmp_path: Path) -> None:
    """With no VSC at start the daemon runs, holds the outputs off with transport_fault, and
    opens the port when it appears."""
    supervisor = Supervisor(
        SafetyConfig(outputs=(OutputSpec("drive", OutputRole.MOTION),)),
        SerialLink(str(tmp_path / "vsc")),
        [create_output(parse_output_spec("drive", {"kind": "sim"}))],
        None,
        backoff=Backoff(first_ms=10, max_ms=20),
    )
    try:
        decision = lifecycle.start(supervisor)
        assert "transport_fault" in decision.active_names
        with PtyPort(tmp_path / "vsc") as port:
            peer = VscPeer(port)
            run_until(supervisor, peer, lambda: supervisor.link.is_open)
            assert supervisor.port.failures >= 1
    finally:
        lifecycle.shutdown(supervisor)


def test_an_output_that_cannot_be_acquired_keeps_the_daemon_up_and_stopped(tmp_path: Path) -> None:
    """A GPIO output on a chip that does not exist is output_fault:NAME from the start; the
    daemon runs on, STOPPED, and the other outputs stay off."""
    outputs = [
        create_output(parse_output_spec("drive", {"kind": "sim", "path": str(tmp_path / "drive")})),
        create_output(
            parse_output_spec(
                "brake", {"kind": "gpio", "chip": str(tmp_path / "no-chip"), "line": 3}
            )
        ),
    ]
    supervisor = Supervisor(
        SafetyConfig(
            outputs=(
                OutputSpec("drive", OutputRole.MOTION),
                OutputSpec("brake", OutputRole.MOTION),
            )
        ),
        SerialLink(str(tmp_path / "vsc")),
        outputs,
        None,
    )
    try:
        decision = lifecycle.start(supervisor)
        assert "output_fault:brake" in decision.active_names
        assert decision.state is State.STOPPED
        assert level(tmp_path, "drive") == "0"
        supervisor.step()  # the loop goes on
    finally:
        lifecycle.shutdown(supervisor)


def test_an_output_acquired_later_clears_its_fault_condition(tmp_path: Path) -> None:
    """An output that cannot be acquired at start is tried again with a backoff; once it is
    acquired (off) its fault's condition clears, and its stop stays latched for a re-arm."""
    late = tmp_path / "late"
    outputs = [
        create_output(parse_output_spec("drive", {"kind": "sim", "path": str(late / "drive")}))
    ]
    clock = ManualClock()
    supervisor = Supervisor(
        SafetyConfig(outputs=(OutputSpec("drive", OutputRole.MOTION),)),
        SerialLink(str(tmp_path / "vsc")),
        outputs,
        None,
        clock=clock,
    )
    try:
        assert "output_fault:drive" in lifecycle.start(supervisor).active_names
        assert supervisor.snapshot(clock()).outputs_not_acquired == ("drive",)
        late.mkdir()  # the device appears
        for _ in range(50):  # 100 ms of the loop's clock a turn: the retry's backoff passes
            if "output_fault:drive" not in active(supervisor):
                break
            clock.advance(100_000_000)
            supervisor.step()
        assert "output_fault:drive" not in active(supervisor), "never acquired"
        assert level(late, "drive") == "0"
        assert supervisor.snapshot(clock()).outputs_not_acquired == ()
        assert supervisor.decision is not None
        fault = supervisor.decision.cause("output_fault:drive")
        assert fault is not None
        assert fault.latched
        assert supervisor.decision.state is State.STOPPED
    finally:
        lifecycle.shutdown(supervisor)


def test_outputs_are_off_before_the_stop_is_recorded(rig: tuple[Supervisor, VscPeer, Path]) -> None:
    """On a stop the output is already off when its record is written: outputs first,
    logging after (SR-6.1, SR-10.2)."""
    supervisor, peer, tmp = rig
    seen: list[tuple[str, str]] = []
    supervisor.records.journal = lambda entry: seen.append((str(entry["to"]), level(tmp, "drive")))
    lifecycle.start(supervisor)
    run_until(
        supervisor,
        peer,
        lambda: supervisor.decision is not None and not supervisor.decision.stop_active,
    )
    serve_for(supervisor, peer, 0.3)
    peer.mode = VscMode.OPERATIONAL
    run_until(supervisor, peer, lambda: state(supervisor) is State.RUN)
    peer.mode, peer.estop = VscMode.LOCAL, 1
    run_until(supervisor, peer, lambda: state(supervisor) is State.STOPPED)

    # The journal is written on the sink's thread, after the loop has set the outputs: wait
    # for the entry of the stop after RUN (the loop's clock runs ahead of that thread).
    def stopped_after_run() -> bool:
        tos = [to for to, _ in seen]
        return "RUN" in tos and tos[-1] == "STOPPED"

    run_until(supervisor, peer, stopped_after_run)
    after_run = seen[[to for to, _ in seen].index("RUN") :]
    stops = [drive for to, drive in after_run if to == "STOPPED"]
    assert stops
    assert set(stops) == {"0"}


# ------------------------------------------------------------------- SR-10: the stop path first


class _SlowReadLink(SerialLink):
    """A serial link whose reads take 50 ms of the daemon's clock once ``slow``; remembers
    when each read that brought an e-stop ended."""

    def __init__(self, path: str, clock: ManualClock) -> None:
        super().__init__(path)
        self.clock = clock
        self.slow = False
        self.read_ends: list[int] = []

    def receive(self) -> list[Any]:
        received = super().receive()
        if self.slow:
            self.clock.advance(50 * 1_000_000)
        if any(isinstance(m, VscHeartbeat) and m.estop for m in received):
            self.read_ends.append(self.clock())  # when the e-stop's frame had been read
        return received


def _arm(supervisor: Supervisor, peer: VscPeer) -> None:
    run_until(
        supervisor,
        peer,
        lambda: supervisor.decision is not None and not supervisor.decision.stop_active,
    )
    serve_for(supervisor, peer, 0.3)  # clear for the re-arm hold, non-Operational long enough
    peer.mode = VscMode.OPERATIONAL
    run_until(supervisor, peer, lambda: state(supervisor) is State.RUN)


def test_a_record_carries_the_time_its_input_was_read(tmp_path: Path) -> None:
    """A record's ``mono_ns`` is the clock read right after the VSC frame
    that caused it was read, not the start of the loop turn (here every read ends 50 ms of
    the daemon's clock after it began)."""
    clock = ManualClock()
    with PtyPort(tmp_path / "vsc") as port:
        link = _SlowReadLink(str(port.path), clock)
        supervisor = Supervisor(
            SafetyConfig(rearm_hold_ms=100, outputs=(OutputSpec("drive", OutputRole.MOTION),)),
            link,
            [create_output(parse_output_spec("drive", {"kind": "sim"}))],
            RecordWriter(tmp_path / "stops.jsonl"),
            clock=clock,
        )
        peer = VscPeer(port, clock=clock.seconds)
        try:
            lifecycle.start(supervisor)
            _arm(supervisor, peer)
            link.slow = True
            peer.mode, peer.estop = VscMode.LOCAL, 1
            run_until(supervisor, peer, lambda: state(supervisor) is State.STOPPED)
        finally:
            lifecycle.shutdown(supervisor)
    stop = next(
        r.data
        for r in read_records(tmp_path / "stops.jsonl")
        if isinstance(r, StoredRecord) and r.data["to"] == "STOPPED" and r.data["from"] == "RUN"
    )
    stamp = stop["mono_ns"]
    assert isinstance(stamp, int)
    # The clock moves only when the test moves it: the stamp is exactly the read's end.
    assert stamp == link.read_ends[0], (stamp, link.read_ends)


class _StalledWriter(RecordWriter):
    """A record file on a disk that hangs: every append waits until released (or 60 s);
    ``hung`` is set while an append is waiting. Both ways in hang: one record alone, and the
    records queued together (which the sink writes at once when its lane wakes late)."""

    def __init__(self, path: Path) -> None:
        super().__init__(path)
        self.release = threading.Event()
        self.hung = threading.Event()

    def _hang(self) -> None:
        self.hung.set()
        self.release.wait(60.0)
        self.hung.clear()

    def append(self, record: Mapping[str, object]) -> None:
        self._hang()
        super().append(record)

    def append_fitting(self, records: Sequence[Mapping[str, object]]) -> int:
        self._hang()
        return super().append_fitting(records)


def test_a_hung_record_disk_neither_holds_the_loop_nor_loses_a_record(tmp_path: Path) -> None:
    """SR-5, SR-6, SR-7: while the record's disk hangs, the loop goes
    on: a remote e-stop turns the output off at once and the user heartbeat keeps its
    period (one per 50 ms of the loop's clock, which the test drives while the disk is still
    hung); once the disk answers, every record is in the file, in order, and a clean stop
    drains them all."""
    clock = ManualClock()
    with PtyPort(tmp_path / "vsc") as port:
        writer = _StalledWriter(tmp_path / "stops.jsonl")
        supervisor = Supervisor(
            SafetyConfig(rearm_hold_ms=100, outputs=(OutputSpec("drive", OutputRole.MOTION),)),
            SerialLink(str(port.path)),
            [
                create_output(
                    parse_output_spec("drive", {"kind": "sim", "path": str(tmp_path / "drive")})
                )
            ],
            writer,
            clock=clock,
        )
        peer = VscPeer(port, clock=clock.seconds)
        try:
            lifecycle.start(supervisor)
            assert writer.hung.wait(10.0), "the first record never reached the disk"
            _arm(supervisor, peer)
            beats_before = sum(isinstance(m, UserHeartbeat) for m in peer.received)
            peer.mode, peer.estop = VscMode.LOCAL, 1
            run_until(supervisor, peer, lambda: state(supervisor) is State.STOPPED)
            assert level(tmp_path, "drive") == "0"
            serve_for(supervisor, peer, 1.0)
            assert writer.hung.is_set(), "the disk was not hung all along"
            beats = sum(isinstance(m, UserHeartbeat) for m in peer.received) - beats_before
            # 20 Hz over the stop and the second after it; the last one may still be in the pty.
            assert beats >= 20, beats
            writer.release.set()
        finally:
            lifecycle.shutdown(supervisor)
    stored = [r for r in read_records(tmp_path / "stops.jsonl") if isinstance(r, StoredRecord)]
    seqs = [r.data["seq"] for r in stored]
    assert seqs == list(range(1, len(seqs) + 1))
    stops = [
        r.data
        for r in read_records(tmp_path / "stops.jsonl")
        if isinstance(r, StoredRecord) and (r.data["from"], r.data["to"]) == ("RUN", "STOPPED")
    ]
    assert len(stops) == 1


class _RecordingListener(Listener):
    """Client descriptors that are always ready (socket pairs with data waiting); remembers
    what each turn served, in order, with the link's reads."""

    def __init__(self, count: int, order: list[str]) -> None:
        self.pairs = [socket.socketpair() for _ in range(count)]
        for ours, theirs in self.pairs:
            theirs.send(b"x")
            ours.setblocking(False)
        self.order = order

    def descriptors(self, now: int) -> Iterable[tuple[int, bool]]:
        return [(ours.fileno(), False) for ours, _ in self.pairs]

    def handle(self, fd: int, readable: bool, writable: bool, now: int) -> None:
        self.order.append(f"client:{fd}")

    def close(self) -> None:
        for pair in self.pairs:
            for sock in pair:
                sock.close()


class _OrderLink(SerialLink):
    def __init__(self, path: str, order: list[str]) -> None:
        super().__init__(path)
        self.order = order

    def receive(self) -> list[Any]:
        received = super().receive()
        if received:
            self.order.append("link")
        return received


def test_each_turn_serves_the_link_first_and_a_bounded_number_of_clients(tmp_path: Path) -> None:
    """SR-10.1, SR-5: with forty client descriptors always ready, a turn
    reads the VSC's frames before any client, serves only a bounded number of clients, and
    over a few turns every client gets its turn."""
    order: list[str] = []
    listener = _RecordingListener(40, order)
    with PtyPort(tmp_path / "vsc") as port:
        supervisor = Supervisor(
            SafetyConfig(outputs=(OutputSpec("drive", OutputRole.MOTION),)),
            _OrderLink(str(port.path), order),
            [create_output(parse_output_spec("drive", {"kind": "sim"}))],
            None,
            listener=listener,
        )
        peer = VscPeer(port)
        try:
            lifecycle.start(supervisor)
            turns: list[list[str]] = []
            for _ in range(30):
                peer.serve()
                time.sleep(0.002)
                del order[:]
                supervisor.step()
                turns.append(list(order))
        finally:
            lifecycle.shutdown(supervisor)
    assert (
        max(len([o for o in t if o.startswith("client")]) for t in turns)
        <= loop.MAX_CLIENTS_PER_TURN
    )
    with_link = [t for t in turns if "link" in t]
    assert with_link
    assert all(t[0] == "link" for t in with_link), with_link
    served = {o for t in turns for o in t if o.startswith("client")}
    assert len(served) == 40


@pytest.mark.skipif(os.geteuid() != 0, reason="mounting a tmpfs needs root")
def test_a_full_record_disk_is_counted_and_stops_nothing(tmp_path: Path) -> None:
    """SR-7.6, docs/record.md "A full disk": every record fails with ENOSPC (the
    file is on a full tmpfs). The loop counts each failure in ``record_errors`` and raises no
    cause of its own for it; the stops the core decides still happen."""
    clock = ManualClock()
    with full_disk(tmp_path / "full") as record, PtyPort(tmp_path / "vsc") as port:
        supervisor = Supervisor(
            SafetyConfig(rearm_hold_ms=100, outputs=(OutputSpec("drive", OutputRole.MOTION),)),
            SerialLink(str(port.path)),
            [
                create_output(
                    parse_output_spec("drive", {"kind": "sim", "path": str(tmp_path / "drive")})
                )
            ],
            RecordWriter(record),
            clock=clock,
        )
        peer = VscPeer(port, clock=clock.seconds)
        try:
            lifecycle.start(supervisor)
            _arm(supervisor, peer)
            peer.mode, peer.estop = VscMode.LOCAL, 1
            run_until(supervisor, peer, lambda: state(supervisor) is State.STOPPED)
            assert level(tmp_path, "drive") == "0"
            run_until(supervisor, peer, lambda: supervisor.records.record_errors >= 4)
            assert supervisor.decision is not None
            assert {c.name for c in supervisor.decision.causes} <= {
                "startup",
                "vsc_estop",
                "vsc_link_lost",
                "transport_fault",
                "vsc_watchdog_off",
                "vsc_mode:local",
            }
        finally:
            lifecycle.shutdown(supervisor)


def test_can_error_frames_show_in_status(tmp_path: Path) -> None:
    """SR-2.12, docs/safety.md "CAN error frames": isolated error frames on the VSC's CAN bus
    stop nothing and their count shows in ``status`` (``link.error_frames``) and in
    ``srcsctl status``; a serial link has none to count (null, and no words for it)."""
    import can  # noqa: PLC0415 -- only this test needs python-can

    from supervisord.cli.control import format_status  # noqa: PLC0415
    from supervisord.links.can_link import CanLink  # noqa: PLC0415
    from supervisord.safety.config import Transport  # noqa: PLC0415

    with can.Bus(interface="virtual", channel="loop-errors") as vsc_bus:
        supervisor = Supervisor(
            SafetyConfig(
                transport=Transport.CAN,
                require_watchdog=False,
                outputs=(OutputSpec("drive", OutputRole.MOTION),),
            ),
            CanLink("virtual", "loop-errors", 250_000),
            [create_output(parse_output_spec("drive", {"kind": "sim"}))],
            None,
        )
        try:
            lifecycle.start(supervisor)
            assert supervisor.snapshot(0).link.error_frames == 0
            for _ in range(3):
                vsc_bus.send(can.Message(arbitration_id=0x08, data=bytes(8), is_error_frame=True))
            end = time.monotonic() + 5
            while supervisor.link.error_frames < 3:  # type: ignore[attr-defined]
                assert time.monotonic() < end
                supervisor.step()
            info = supervisor.snapshot(0)
            assert info.link.error_frames == 3
            assert supervisor.link.is_open  # counted, not a fault
            assert "transport_fault" not in supervisor.decision.active_names  # type: ignore[union-attr]
            text = format_status(status_reply(loop=info))
            assert "3 CAN error frames" in text
        finally:
            lifecycle.shutdown(supervisor)


def test_a_serial_link_shows_no_error_frame_count(rig: tuple[Supervisor, VscPeer, Path]) -> None:
    """A serial link has no error frames: ``link.error_frames`` is null and ``srcsctl status``
    does not mention them."""
    from supervisord.cli.control import format_status  # noqa: PLC0415

    supervisor, _peer, _path = rig
    lifecycle.start(supervisor)
    info = supervisor.snapshot(0)
    assert info.link.error_frames is None
    assert "error frame" not in format_status(status_reply(loop=info))


class _PipeHidLink(HidLink):
    """The HID link on a pipe's read end, counting its reads. Once its writer is gone and its
    bytes are read, a pipe says what an unplugged hidraw node says: a hang-up without
    ``EPOLLIN`` (hidraw adds ``EPOLLERR``), where a read could only find the device gone."""

    def __init__(self, read_end: int) -> None:
        super().__init__("pipe")
        self._read_end = read_end
        self.reads = 0

    def prepare(self) -> None:
        """Nothing to prepare (the pipe is open): what stays is the loop's way round a
        prepare, which it never waits for."""

    def open(self) -> None:
        self._fd = self._read_end

    def receive(self) -> list[Any]:
        self.reads += 1
        return super().receive()


def test_a_link_that_hung_up_with_nothing_to_read_is_broken_without_a_read(
    tmp_path: Path,
) -> None:
    """SR-9.8, SR-2: the HID link opens once its prepare has returned, the loop turning
    meanwhile; the report still waiting when the device went is read; after it, the hang-up
    alone breaks the link (``transport_fault``, the reason ``HUNG_UP``) with no read, which on
    hidraw would mark the real-time loop sleeping before it found the device gone."""
    read_end, write_end = os.pipe()
    link = _PipeHidLink(read_end)
    clock = ManualClock()
    supervisor = Supervisor(
        SafetyConfig(outputs=(OutputSpec("drive", OutputRole.MOTION),)),
        link,
        [create_output(parse_output_spec("drive", {"kind": "sim"}))],
        None,
        clock=clock,
    )
    try:
        lifecycle.start(supervisor)
        end = time.monotonic() + 10
        while not link.is_open:
            assert time.monotonic() < end, "the prepared HID link never opened"
            clock.advance(link_port.PREPARE_POLL_NS)
            supervisor.step()
        assert supervisor.port.opens == 1
        os.write(write_end, encode_hid_input(HidInput(1, 2, 3, 4, 5, 6, mode=9)))
        os.close(write_end)
        supervisor.step()
        assert (link.reads, supervisor.port.messages) == (1, 1)
        supervisor.step()
        assert link.reads == 1
        assert link.fileno() is None  # closed
        assert supervisor.port.error == link_port.HUNG_UP
        assert "transport_fault" in active(supervisor)
    finally:
        lifecycle.shutdown(supervisor)
