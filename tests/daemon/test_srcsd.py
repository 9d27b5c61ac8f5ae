"""The real ``srcsd`` process, started as systemd starts it: notifications on a real datagram
socket, a pseudo-terminal VSC, SIGTERM at the end."""

from __future__ import annotations

import json
import os
import shutil
import signal
import socket
import subprocess
import time
from collections.abc import Callable
from pathlib import Path

from supervisord.protocol.codes import VscMode
from supervisord.testkit.pty_port import PtyPort
from tests.daemon.peer import VscPeer

SRCSD = shutil.which("srcsd") or str(Path(__file__).parents[2] / ".venv/bin/srcsd")

CONFIG = """
[robot]
name = "test-robot"
[vsc]
transport = "serial"
port = "vsc"
[rearm]
hold_ms = 100
[[outputs]]
name = "drive"
kind = "sim"
path = "drive"
[record]
path = "stops.jsonl"
journal = false
[api]
socket = "api.sock"
"""


def notifications(sock: socket.socket) -> list[str]:
    lines = []
    while True:
        try:
            lines += sock.recv(4096).decode().splitlines()
        except BlockingIOError:
            return lines


def wait(peer: VscPeer, done: Callable[[], bool], limit: float = 10.0) -> None:
    end = time.monotonic() + limit
    while not done():
        assert time.monotonic() < end, "timed out"
        peer.serve()
        time.sleep(0.005)


def test_notify_takeover_and_sigterm(tmp_path: Path) -> None:
    """READY=1 comes only once the output is off; WATCHDOG=1 keeps coming; a takeover runs
    the output; SIGTERM turns it off, flushes the record and exits 0."""
    (tmp_path / "robot.toml").write_text(CONFIG)
    notify_path = tmp_path / "notify"
    with (
        socket.socket(socket.AF_UNIX, socket.SOCK_DGRAM) as notify,
        PtyPort(tmp_path / "vsc") as port,
    ):
        notify.bind(str(notify_path))
        notify.setblocking(False)
        env = {**os.environ, "NOTIFY_SOCKET": str(notify_path), "WATCHDOG_USEC": "200000"}
        daemon = subprocess.Popen(
            [SRCSD, "--config", str(tmp_path / "robot.toml")],
            env=env,
            stderr=subprocess.PIPE,
            text=True,
        )
        try:
            peer = VscPeer(port)
            seen: list[str] = []

            def ready() -> bool:
                seen.extend(notifications(notify))
                return "READY=1" in seen

            wait(peer, ready)
            assert (tmp_path / "drive").read_text() == "0\n"
            assert any(line.startswith("STATUS=STOPPED") for line in seen)
            pause = time.monotonic() + 0.3  # clear for longer than the 100 ms re-arm hold
            wait(peer, lambda: time.monotonic() > pause)
            peer.mode = VscMode.OPERATIONAL
            wait(peer, lambda: (tmp_path / "drive").read_text() == "1\n")
            seen += notifications(notify)
            assert seen.count("WATCHDOG=1") >= 2
            assert "STATUS=RUN" in seen
            daemon.send_signal(signal.SIGTERM)
            assert daemon.wait(timeout=10) == 0
        finally:
            if daemon.poll() is None:
                daemon.kill()
            _, errors = daemon.communicate()
        assert (tmp_path / "drive").read_text() == "0\n"
        assert "STOPPING=1" in notifications(notify)
        records = [json.loads(line) for line in (tmp_path / "stops.jsonl").read_text().splitlines()]
        assert records[0]["to"] == "stopped"
        assert records[-1]["to"] == "run"
        assert records[-1]["rearm"]["kind"] == "takeover"
        assert "Traceback" not in errors


def test_bad_config_refuses_to_start(tmp_path: Path) -> None:
    """A configuration error names file, key and fix, and the daemon exits 1 without starting."""
    bad = tmp_path / "bad.toml"
    bad.write_text(CONFIG.replace("hold_ms = 100", "hold_ms = 5"))
    done = subprocess.run(
        [SRCSD, "--config", str(bad)], capture_output=True, text=True, timeout=30, check=False
    )
    assert done.returncode == 1
    assert str(bad) in done.stderr
    assert "rearm.hold_ms" in done.stderr
