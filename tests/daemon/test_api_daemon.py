"""The client API of the real ``srcsd`` process, used through the shipped client library."""

from __future__ import annotations

import signal
import subprocess
import time
from pathlib import Path

import pytest

from supervisord.api.wire import ApiError
from supervisord.client import SupervisorClient
from supervisord.protocol.codes import VscMode
from supervisord.testkit.pty_port import PtyPort
from tests.daemon.peer import VscPeer
from tests.daemon.test_srcsd import CONFIG, SRCSD, wait

REQUIRED_CLIENT = '\n[[clients]]\nname = "autonomy"\ntimeout_ms = 500\n'


def test_client_keeps_the_robot_running_and_local_commands_stop_it(tmp_path: Path) -> None:
    """A required client's hello and heartbeats let a takeover run the robot; its silence
    stops it; an operator's local e-stop over the socket stops it; a reset without
    local_reset is refused with the core's reason; a state push reaches subscribers."""
    (tmp_path / "robot.toml").write_text(CONFIG + REQUIRED_CLIENT)
    with PtyPort(tmp_path / "vsc") as port:
        daemon = subprocess.Popen(
            [SRCSD, "--config", str(tmp_path / "robot.toml")], stderr=subprocess.DEVNULL
        )
        peer = VscPeer(port)
        try:
            wait(peer, (tmp_path / "api.sock").exists)
            with SupervisorClient.connect(tmp_path / "api.sock") as robot:
                robot.hello("autonomy")
                robot.subscribe("state")
                clear = time.monotonic() + 0.4
                while time.monotonic() < clear:  # heartbeats at 10 Hz, VSC traffic flowing
                    robot.heartbeat()
                    peer.serve()
                    time.sleep(0.02)
                assert "client_lost:autonomy" not in {
                    c["name"] for c in robot.status()["causes"] if c["active"]
                }
                peer.mode = VscMode.OPERATIONAL
                deadline = time.monotonic() + 5
                while robot.status()["state"] != "RUN":
                    assert time.monotonic() < deadline
                    robot.heartbeat()
                    peer.serve()
                    time.sleep(0.02)
                assert (tmp_path / "drive").read_text() == "1\n"

                with SupervisorClient.connect(tmp_path / "api.sock") as operator:
                    operator.estop()  # no hello: the operator's local e-stop
                    status = operator.status()
                    assert status["state"] == "STOPPED"
                    assert "local_estop" in {c["name"] for c in status["causes"] if c["active"]}
                    assert (tmp_path / "drive").read_text() == "0\n"
                    operator.release("estop")
                    with pytest.raises(ApiError, match="local reset is not allowed"):
                        operator.reset()

                pushes = []
                while (push := robot.next_event(timeout=0.2)) is not None:
                    pushes.append(push)
                assert any(p.event == "state" and p.data["state"] == "STOPPED" for p in pushes)
            daemon.send_signal(signal.SIGTERM)
            assert daemon.wait(timeout=10) == 0
        finally:
            if daemon.poll() is None:
                daemon.kill()
                daemon.wait()
    assert not (tmp_path / "api.sock").exists()
