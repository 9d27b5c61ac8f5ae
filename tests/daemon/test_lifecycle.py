"""The daemon's life above its loop (``supervisord/daemon/lifecycle.py``) on real parts: a
pseudo-terminal VSC, sim outputs mirrored to files, the JSON Lines record, a real datagram
socket as systemd's notify socket, and a real SIGTERM sent to this process."""

from __future__ import annotations

import contextlib
import datetime as dt
import gc
import json
import logging
import os
import signal
import socket
import threading
import time
from pathlib import Path

import pytest

from supervisord.api.server import ApiServer, ServerConfig
from supervisord.daemon import lifecycle
from supervisord.daemon.api_listener import ApiListener
from supervisord.daemon.listener import Listener
from supervisord.daemon.loop import Supervisor
from supervisord.daemon.maintenance import PeriodicTest
from supervisord.daemon.notify import Notifier
from supervisord.links.base import Backoff
from supervisord.links.serial_link import SerialLink
from supervisord.outputs import create_output, parse_output_spec
from supervisord.record.jsonl import RecordWriter
from supervisord.record.stop import StopRecord
from supervisord.safety.config import OutputRole, OutputSpec, SafetyConfig
from supervisord.safety.transitions import State
from supervisord.sim.pty import PtyPort


def _loop(
    tmp_path: Path, notifier: Notifier | None = None, listener: Listener | None = None
) -> Supervisor:
    drive = parse_output_spec("drive", {"kind": "sim", "path": str(tmp_path / "drive")})
    return Supervisor(
        SafetyConfig(outputs=(OutputSpec("drive", OutputRole.MOTION),)),
        SerialLink(str(tmp_path / "vsc")),
        [create_output(drive)],
        RecordWriter(tmp_path / "stops.jsonl"),
        backoff=Backoff(first_ms=10, max_ms=20),
        notifier=notifier,
        listener=listener,
    )


def _said(systemd: socket.socket) -> list[bytes]:
    """Every datagram the service manager's socket holds now."""
    said = []
    systemd.setblocking(False)
    with contextlib.suppress(BlockingIOError):
        while True:
            said.append(systemd.recv(4096))
    return said


def test_the_start_says_ready_only_with_the_outputs_off_and_the_link_open(tmp_path: Path) -> None:
    """SR-6, SR-0.2: the outputs off before anything else, then the core, then the link; READY
    once the startup decision is applied, with its status line."""
    path = str(tmp_path / "notify")
    with socket.socket(socket.AF_UNIX, socket.SOCK_DGRAM) as systemd, PtyPort(tmp_path / "vsc"):
        systemd.bind(path)
        supervisor = _loop(tmp_path, Notifier({"NOTIFY_SOCKET": path}))
        # A stop test's pass the record file held, an hour before the start (SR-12.2).
        wall_now = supervisor.records.wall_clock()
        supervisor.schedule.found[PeriodicTest.STOPTEST] = wall_now - dt.timedelta(hours=1)
        try:
            before = time.monotonic_ns()
            decision = lifecycle.start(supervisor)
            assert supervisor.core is not None
            assert decision is supervisor.decision is supervisor.core.decision
            assert decision.state is State.STOPPED
            assert (tmp_path / "drive").read_text().strip() == "0"
            assert supervisor.link.is_open
            # The uptime and the link's time since counted from the start's clock reading.
            started = supervisor.counters.started_ns
            assert started is not None
            assert before <= started <= time.monotonic_ns()
            assert supervisor.port.since_ns == started
            # The pass placed on the monotonic clock, about an hour before the start.
            passed = supervisor.schedule.passed_ns[PeriodicTest.STOPTEST]
            assert passed is not None
            assert started - 3700 * 10**9 < passed < started - 3500 * 10**9
            said = _said(systemd)
            # Status lines as the start's decisions are applied, then READY, once, last.
            assert [line.startswith(b"READY=1\n") for line in said][-1:] == [True]
            assert sum(b"READY=1" in line for line in said) == 1
        finally:
            lifecycle.shutdown(supervisor)


def test_a_shutdown_of_a_loop_never_started_records_nothing_and_raises_nothing(
    tmp_path: Path,
) -> None:
    """SR-7.14: no core (its start failed), no sequence to continue: no ``shutdown`` record;
    the outputs and the link are released all the same (SR-6.6)."""
    supervisor = _loop(tmp_path)
    lifecycle.shutdown(supervisor)
    assert supervisor.core is None
    assert not supervisor.link.is_open
    record = tmp_path / "stops.jsonl"
    assert not record.exists() or not record.read_text().strip()


def test_a_stop_asked_wakes_the_loops_wait(tmp_path: Path) -> None:
    """SR-6.6: a signal's handler only asks and wakes: the loop's wait returns at once, not
    at its timeout, so the outputs go off without waiting for the next input."""
    supervisor = _loop(tmp_path)
    quiet_r, quiet_w = os.pipe()  # the sink's place in the wait: never ready here
    try:
        supervisor.waiter.start(quiet_r)
        lifecycle.request_stop(supervisor, signal.SIGTERM)
        assert supervisor.stop.asked
        # Ready at once with the wake pair's byte (without it: nothing after 30 s).
        ready = supervisor.waiter.wait(30.0)
        assert ready
        assert all(fd != quiet_r for fd, _ in ready)
    finally:
        lifecycle.shutdown(supervisor)
        os.close(quiet_r)
        os.close(quiet_w)


def test_the_shutdown_says_stopping_turns_an_output_on_off_releases_it_and_the_api(
    tmp_path: Path,
) -> None:
    """SR-6.5, SR-6.6: STOPPING to the service manager first; an output found on is driven
    off and released (the next owner of the line finds it off); the API's socket is closed."""
    path = str(tmp_path / "notify")
    sock = tmp_path / "api.sock"
    server = ApiServer(ServerConfig(sock, max_clients=1, slot_idle_ms=200))
    with socket.socket(socket.AF_UNIX, socket.SOCK_DGRAM) as systemd, PtyPort(tmp_path / "vsc"):
        systemd.bind(path)
        supervisor = _loop(tmp_path, Notifier({"NOTIFY_SOCKET": path}), ApiListener(server))
        try:
            lifecycle.start(supervisor)
            drive = supervisor.outputs["drive"]
            drive.set(True, supervisor.clock())  # on, as in RUNNING
            assert (tmp_path / "drive").read_text().strip() == "1"
            _said(systemd)
        finally:
            lifecycle.shutdown(supervisor)
        assert any(b"STOPPING=1" in line for line in _said(systemd))
    assert (tmp_path / "drive").read_text().strip() == "0"
    assert not drive.is_open
    with (
        socket.socket(socket.AF_UNIX, socket.SOCK_STREAM) as client,
        contextlib.suppress(FileNotFoundError, ConnectionRefusedError),
    ):
        client.connect(str(sock))
        raise AssertionError("the API's socket still accepts after the shutdown")


class _Subscriber(Listener):
    """A listener that keeps the records handed to it, as the API pushes them to a
    subscriber (SR-7.4)."""

    def __init__(self) -> None:
        self.records: list[StopRecord] = []

    def recorded(self, record: StopRecord) -> None:
        self.records.append(record)


def test_the_records_drained_at_the_shutdown_are_pushed_with_the_shutdown_stop(
    tmp_path: Path,
) -> None:
    """SR-7.4, SR-7.7, SR-7.14: the records the drain at exit finishes, the shutdown's own
    among them, are handed on to subscribers, not only written to the file."""
    subscriber = _Subscriber()
    with PtyPort(tmp_path / "vsc"):
        supervisor = _loop(tmp_path, listener=subscriber)
        lifecycle.start(supervisor)
        lifecycle.request_stop(supervisor, signal.SIGTERM)
        lifecycle.shutdown(supervisor)
    assert subscriber.records
    assert "SIGTERM" in repr(subscriber.records[-1])


def _sigterm_once_running(
    supervisor: Supervisor, installed_before: object, seen: dict[str, bool]
) -> None:
    """SIGTERM to this process once ``run`` has installed its handler and started (a SIGTERM
    before would end pytest itself), and log lines go through the sink and the heap is
    frozen and the loop has turned (or 10 s passed)."""
    end = time.monotonic() + 10.0
    while time.monotonic() < end:
        if signal.getsignal(signal.SIGTERM) is not installed_before and supervisor.decision:
            root = logging.getLogger().handlers
            seen["captured"] = any(type(h).__name__ == "_QueueHandler" for h in root)
            seen["frozen"] = gc.get_freeze_count() > 0
            # A turn watches the open link in its wait (the start does not).
            seen["turned"] = supervisor.waiter.link_fd is not None
            if all(seen.values()) or time.monotonic() > end - 1.0:
                os.kill(os.getpid(), signal.SIGTERM)
                return
        time.sleep(0.01)


def test_sigterm_ends_the_run_with_the_outputs_off_and_the_shutdown_recorded(
    tmp_path: Path, caplog: pytest.LogCaptureFixture
) -> None:
    """SR-6.6, SR-7.14, SR-7.7: a real SIGTERM only asks the loop to end; the run shuts down
    (outputs off, the ``shutdown:SIGTERM`` stop recorded and drained to the file), exits 0,
    and puts the signal's handler back. While it runs, log lines leave through the sink
    (SR-7.5) and start-up's heap is frozen (SR-9.1); the signal is logged before the
    shutdown."""
    caplog.set_level(logging.INFO)
    before = signal.getsignal(signal.SIGTERM)
    seen: dict[str, bool] = {}
    gc.unfreeze()  # whatever a test before froze: this run's freeze is seen
    with PtyPort(tmp_path / "vsc"):
        supervisor = _loop(tmp_path)
        sender = threading.Thread(target=_sigterm_once_running, args=(supervisor, before, seen))
        sender.start()
        try:
            status = lifecycle.run(supervisor)
        finally:
            sender.join()
            gc.unfreeze()  # a test runner goes on allocating and dropping (heap.settle)
    assert seen == {"captured": True, "frozen": True, "turned": True}
    assert "SIGTERM: stopping, every output off" in caplog.text
    assert status == 0
    assert signal.getsignal(signal.SIGTERM) is before
    assert (tmp_path / "drive").read_text().strip() == "0"
    last = json.loads((tmp_path / "stops.jsonl").read_text().splitlines()[-1])
    assert "shutdown:SIGTERM" in json.dumps(last)
