"""The loop has one clock (SR-2.11): the loop reads it and hands ``now`` to everything it drives.

A static check that no module of the daemon or of the API server reads a clock of its own, and
the whole loop (the real API server and listener on a real Unix socket, a real pty VSC peer,
sim outputs) driven on a manual clock that starts ten hours away from the real one."""

from __future__ import annotations

import ast
import json
import socket
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import pytest

from supervisord.api.server import ApiServer, ServerConfig
from supervisord.daemon import lifecycle
from supervisord.daemon.api_listener import ApiListener
from supervisord.daemon.loop import Supervisor
from supervisord.links.base import Backoff
from supervisord.links.serial_link import SerialLink
from supervisord.outputs import create_output, parse_output_spec
from supervisord.safety.config import OutputRole, OutputSpec, SafetyConfig
from supervisord.sim.pty import PtyPort
from tests.daemon.peer import VscPeer
from tests.daemon.test_loop import START_OFFSET_NS, ManualClock, turn

MS = 1_000_000
PACKAGE = Path(__file__).resolve().parents[2] / "supervisord"
CLOCK_READS = {"monotonic", "monotonic_ns", "perf_counter", "perf_counter_ns", "time", "time_ns"}


def _clock_reads(path: Path) -> list[str]:
    """Every ``time.X`` of :data:`CLOCK_READS` in a module (and ``from time import X``)."""
    tree = ast.parse(path.read_text(), str(path))
    found = []
    for node in ast.walk(tree):
        if (
            isinstance(node, ast.Attribute)
            and isinstance(node.value, ast.Name)
            and node.value.id == "time"
            and node.attr in CLOCK_READS
        ):
            found.append(f"{path.name}:{node.lineno} time.{node.attr}")
        if isinstance(node, ast.ImportFrom) and node.module == "time":
            found += [f"{path.name}:{node.lineno} from time import {a.name}" for a in node.names]
    return found


THREAD_WAITS = {"sink.py"}
"""Modules that wait for threads of their own with deadlines: the sink's shutdown joins its
writer threads for at most a few seconds (SR-7.5). A wait for another thread runs on real time
(``Condition.wait``, ``Thread.join``), never on the loop's clock, and no loop deadline comes
of it."""


def test_no_part_of_the_loop_reads_a_clock_of_its_own() -> None:
    """SR-2.11: nothing under ``supervisord/daemon`` or ``supervisord/api`` reads the clock
    (but the real-time waits for threads of :data:`THREAD_WAITS`); the loop's one clock is
    ``supervisord/clock.py``'s, injected into ``Supervisor``."""
    modules = sorted((PACKAGE / "daemon").glob("*.py")) + sorted((PACKAGE / "api").glob("*.py"))
    assert len(modules) > 10
    reads = [
        read
        for module in modules
        if module.name not in THREAD_WAITS
        for read in _clock_reads(module)
    ]
    assert reads == []
    waits = {
        read.split()[-1]
        for name in THREAD_WAITS
        for read in _clock_reads(PACKAGE / "daemon" / name)
    }
    assert waits <= {"time.monotonic"}
    # The check itself sees a clock read where there is one.
    assert [read.split()[-1] for read in _clock_reads(PACKAGE / "clock.py")] == [
        "time.monotonic_ns"
    ]


@pytest.fixture
def api_rig(tmp_path: Path) -> Iterator[tuple[Supervisor, VscPeer, ManualClock, Path]]:
    clock = ManualClock()
    port = PtyPort(tmp_path / "vsc")
    sock = tmp_path / "api.sock"
    server = ApiServer(ServerConfig(sock, max_clients=1, slot_idle_ms=200))
    supervisor = Supervisor(
        SafetyConfig(rearm_hold_ms=100, outputs=(OutputSpec("drive", OutputRole.MOTION),)),
        SerialLink(str(port.path)),
        [create_output(parse_output_spec("drive", {"kind": "sim"}))],
        None,
        listener=ApiListener(server),
        backoff=Backoff(first_ms=20, max_ms=100),
        clock=clock,
    )
    yield supervisor, VscPeer(port, clock=clock.seconds), clock, sock
    lifecycle.shutdown(supervisor)
    port.close()


def _connect(path: Path) -> socket.socket:
    client = socket.socket(socket.AF_UNIX, socket.SOCK_STREAM)
    client.connect(str(path))
    client.setblocking(False)
    return client


def _lines(client: socket.socket) -> list[dict[str, Any]] | None:
    """What arrived so far (``None``: the server closed the connection)."""
    data = b""
    while True:
        try:
            chunk = client.recv(65536)
        except BlockingIOError:
            return [json.loads(line) for line in data.splitlines()]
        if not chunk:
            return None if not data else [json.loads(line) for line in data.splitlines()]
        data += chunk


def test_the_whole_loop_runs_on_a_clock_hours_from_the_real_one(
    api_rig: tuple[Supervisor, VscPeer, ManualClock, Path],
) -> None:
    """SR-2.11, SR-8.4: on a manual clock ten hours ahead of the real one, the API's e-stop
    slot is closed when ``slot_idle_ms`` of the loop's clock has passed, not before and not
    by the real clock; a client's heartbeat age in ``status`` is the loop's clock too."""
    supervisor, peer, clock, path = api_rig
    assert clock() - START_OFFSET_NS > 0
    lifecycle.start(supervisor)
    client = _connect(path)
    client.sendall(b'{"op":"hello","name":"nav","id":1}\n')
    replies: list[dict[str, Any]] = []
    for _ in range(100):
        turn(supervisor, peer)
        replies += _lines(client) or []
        if replies:
            break
    assert replies == [{"ok": True, "op": "hello", "id": 1}]

    extra = _connect(path)  # past max_clients: an e-stop slot
    server = supervisor.listener.server  # type: ignore[attr-defined]
    while len(server._connections) < 2:
        turn(supervisor, peer)
    accepted_at = clock()
    while clock() < accepted_at + 200 * MS:
        assert _lines(extra) == [], f"closed {(clock() - accepted_at) / MS} ms after accept"
        turn(supervisor, peer)
    turn(supervisor, peer)
    closing = _lines(extra)
    assert closing is not None
    assert [reply["code"] for reply in closing] == ["too_many_clients"]

    client.sendall(b'{"op":"heartbeat"}\n')
    while not _lines(client):
        turn(supervisor, peer)
    beat_at = clock()
    for _ in range(3):  # 150 ms of the loop's clock: three of the peer's heartbeats
        turn(supervisor, peer)
    client.sendall(b'{"op":"status"}\n')
    status: list[dict[str, Any]] = []
    while not status:
        turn(supervisor, peer)  # the clock stands still while the loop turns
        status = _lines(client) or []
    asked_at = clock()
    (nav,) = [c for c in status[0]["daemon"]["clients"] if c["name"] == "nav"]
    assert nav["heartbeat_age_s"] == pytest.approx((asked_at - beat_at) / 1e9, abs=0.001)
    assert 0.1 <= nav["heartbeat_age_s"] < 0.5
    client.close()
    extra.close()
