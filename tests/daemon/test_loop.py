"""The main loop with real parts: a pseudo-terminal VSC, sim outputs mirrored to files, the
JSON Lines stop record. A small VSC peer in the test answers key 85 and sends heartbeats."""

from __future__ import annotations

import json
import time
from collections.abc import Callable, Iterator
from pathlib import Path

import pytest

from supervisord.daemon.loop import Supervisor
from supervisord.links.base import Backoff
from supervisord.links.serial_link import SerialLink
from supervisord.outputs import create_output, parse_output_spec
from supervisord.protocol.codes import VscMode
from supervisord.protocol.messages import UserHeartbeat
from supervisord.record.jsonl import Record, RecordWriter, read_records
from supervisord.safety.config import OutputRole, OutputSpec, SafetyConfig
from supervisord.safety.transitions import State
from supervisord.testkit.pty_port import PtyPort
from tests.daemon.peer import VscPeer


@pytest.fixture
def rig(tmp_path: Path) -> Iterator[tuple[Supervisor, VscPeer, Path]]:
    port = PtyPort(tmp_path / "vsc")
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
    )
    yield supervisor, VscPeer(port), tmp_path
    supervisor.shutdown()
    port.close()


def run_until(
    supervisor: Supervisor, peer: VscPeer, done: Callable[[], bool], limit: float = 5.0
) -> None:
    end = time.monotonic() + limit
    while not done():
        assert time.monotonic() < end, f"timed out in {supervisor.decision}"
        peer.serve()
        supervisor.step()


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
    supervisor.start()
    assert (level(tmp, "drive"), level(tmp, "lamp")) == ("0", "0")

    run_until(
        supervisor,
        peer,
        lambda: supervisor.decision is not None and not supervisor.decision.stop_active,
    )
    time.sleep(0.15)  # conditions clear for longer than the 100 ms re-arm hold
    peer.mode = VscMode.OPERATIONAL
    run_until(supervisor, peer, lambda: state(supervisor) is State.RUN)
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
    assert supervisor.counters.link_opens == 2
    assert state(supervisor) is State.STOPPED  # a reconnect is a new start

    lines = (tmp / "stops.jsonl").read_text().splitlines()
    assert len([r for r in read_records(tmp / "stops.jsonl") if isinstance(r, Record)]) == len(
        lines
    )
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
        decision = supervisor.start()
        assert "transport_fault" in decision.active_names
        with PtyPort(tmp_path / "vsc") as port:
            peer = VscPeer(port)
            run_until(supervisor, peer, lambda: supervisor.link.is_open)
            assert supervisor.counters.link_failures >= 1
    finally:
        supervisor.shutdown()


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
        decision = supervisor.start()
        assert "output_fault:brake" in decision.active_names
        assert decision.state is State.STOPPED
        assert level(tmp_path, "drive") == "0"
        supervisor.step()  # the loop goes on
    finally:
        supervisor.shutdown()


def test_an_output_acquired_later_clears_its_fault_condition(tmp_path: Path) -> None:
    """An output that cannot be acquired at start is tried again with a backoff; once it is
    acquired (off) its fault's condition clears, and its stop stays latched for a re-arm."""
    late = tmp_path / "late"
    outputs = [
        create_output(parse_output_spec("drive", {"kind": "sim", "path": str(late / "drive")}))
    ]
    supervisor = Supervisor(
        SafetyConfig(outputs=(OutputSpec("drive", OutputRole.MOTION),)),
        SerialLink(str(tmp_path / "vsc")),
        outputs,
        None,
    )
    try:
        assert "output_fault:drive" in supervisor.start().active_names
        assert supervisor.info()["outputs_not_acquired"] == ["drive"]
        late.mkdir()  # the device appears
        end = time.monotonic() + 5
        while "output_fault:drive" in active(supervisor):
            assert time.monotonic() < end, "never acquired"
            supervisor.step()
        assert level(late, "drive") == "0"
        assert supervisor.info()["outputs_not_acquired"] == []
        assert supervisor.decision is not None
        fault = supervisor.decision.cause("output_fault:drive")
        assert fault is not None
        assert fault.latched
        assert supervisor.decision.state is State.STOPPED
    finally:
        supervisor.shutdown()


def test_outputs_are_off_before_the_stop_is_recorded(rig: tuple[Supervisor, VscPeer, Path]) -> None:
    """On a stop the output is already off when its record is written: outputs first,
    logging after (safety-rules.md §6)."""
    supervisor, peer, tmp = rig
    seen: list[tuple[str, str]] = []
    supervisor.journal = lambda entry: seen.append((str(entry["to"]), level(tmp, "drive")))
    supervisor.start()
    run_until(
        supervisor,
        peer,
        lambda: supervisor.decision is not None and not supervisor.decision.stop_active,
    )
    time.sleep(0.15)
    peer.mode = VscMode.OPERATIONAL
    run_until(supervisor, peer, lambda: state(supervisor) is State.RUN)
    peer.mode, peer.estop = VscMode.LOCAL, 1
    run_until(supervisor, peer, lambda: state(supervisor) is State.STOPPED)
    after_run = seen[[to for to, _ in seen].index("RUN") :]
    stops = [drive for to, drive in after_run if to == "STOPPED"]
    assert stops
    assert set(stops) == {"0"}
