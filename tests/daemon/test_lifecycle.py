"""The daemon's life above its loop (``supervisord/daemon/lifecycle.py``) on real parts: a
pseudo-terminal VSC, sim outputs mirrored to files, the JSON Lines record, a real datagram
socket as systemd's notify socket, and a real SIGTERM sent to this process."""

from __future__ import annotations

import contextlib
import json
import os
import signal
import socket
import threading
import time
from pathlib import Path

from supervisord.daemon import lifecycle
from supervisord.daemon.loop import Supervisor
from supervisord.daemon.notify import Notifier
from supervisord.links.base import Backoff
from supervisord.links.serial_link import SerialLink
from supervisord.outputs import create_output, parse_output_spec
from supervisord.record.jsonl import RecordWriter
from supervisord.safety.config import OutputRole, OutputSpec, SafetyConfig
from supervisord.safety.transitions import State
from supervisord.sim.pty import PtyPort


def _loop(tmp_path: Path, notifier: Notifier | None = None) -> Supervisor:
    drive = parse_output_spec("drive", {"kind": "sim", "path": str(tmp_path / "drive")})
    return Supervisor(
        SafetyConfig(outputs=(OutputSpec("drive", OutputRole.MOTION),)),
        SerialLink(str(tmp_path / "vsc")),
        [create_output(drive)],
        RecordWriter(tmp_path / "stops.jsonl"),
        backoff=Backoff(first_ms=10, max_ms=20),
        notifier=notifier,
    )


def test_the_start_says_ready_only_with_the_outputs_off_and_the_link_open(tmp_path: Path) -> None:
    """SR-6, SR-0.2: the outputs off before anything else, then the core, then the link; READY
    once the startup decision is applied, with its status line."""
    path = str(tmp_path / "notify")
    with socket.socket(socket.AF_UNIX, socket.SOCK_DGRAM) as systemd, PtyPort(tmp_path / "vsc"):
        systemd.bind(path)
        supervisor = _loop(tmp_path, Notifier({"NOTIFY_SOCKET": path}))
        try:
            decision = lifecycle.start(supervisor)
            assert decision is supervisor.decision
            assert decision.state is State.STOPPED
            assert (tmp_path / "drive").read_text().strip() == "0"
            assert supervisor.link.is_open
            said = []
            systemd.setblocking(False)
            with contextlib.suppress(BlockingIOError):
                while True:
                    said.append(systemd.recv(4096))
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


def _sigterm_once_running(supervisor: Supervisor, installed_before: object) -> None:
    """SIGTERM to this process once ``run`` has installed its handler and started (a SIGTERM
    before would end pytest itself)."""
    end = time.monotonic() + 10.0
    while time.monotonic() < end:
        if signal.getsignal(signal.SIGTERM) is not installed_before and supervisor.decision:
            os.kill(os.getpid(), signal.SIGTERM)
            return
        time.sleep(0.01)


def test_sigterm_ends_the_run_with_the_outputs_off_and_the_shutdown_recorded(
    tmp_path: Path,
) -> None:
    """SR-6.6, SR-7.14, SR-7.7: a real SIGTERM only asks the loop to end; the run shuts down
    (outputs off, the ``shutdown:SIGTERM`` stop recorded and drained to the file), exits 0,
    and puts the signal's handler back."""
    before = signal.getsignal(signal.SIGTERM)
    with PtyPort(tmp_path / "vsc"):
        supervisor = _loop(tmp_path)
        sender = threading.Thread(target=_sigterm_once_running, args=(supervisor, before))
        sender.start()
        try:
            status = lifecycle.run(supervisor)
        finally:
            sender.join()
    assert status == 0
    assert signal.getsignal(signal.SIGTERM) is before
    assert (tmp_path / "drive").read_text().strip() == "0"
    last = json.loads((tmp_path / "stops.jsonl").read_text().splitlines()[-1])
    assert "shutdown:SIGTERM" in json.dumps(last)
