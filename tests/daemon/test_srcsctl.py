"""``srcsctl``'s daemon commands, run as real processes against the real ``srcsd``."""

from __future__ import annotations

import json
import os
import shutil
import signal
import subprocess
import time
from collections.abc import Iterator
from pathlib import Path

import pytest

from supervisord.protocol.messages import FeedbackName, FeedbackSet
from supervisord.testkit.daemon import SrcsdProcess
from supervisord.testkit.pty_port import PtyPort
from tests.daemon.peer import VscPeer
from tests.daemon.test_srcsd import CONFIG

SRCSCTL = shutil.which("srcsctl") or str(Path(__file__).parents[2] / ".venv/bin/srcsctl")


class Robot:
    """A running ``srcsd`` with its VSC peer served from a thread."""

    def __init__(self, tmp_path: Path, peer: VscPeer) -> None:
        self.dir = tmp_path
        self.peer = peer
        self.config = tmp_path / "robot.toml"

    def ctl(self, *args: str, stdin: str = "") -> subprocess.CompletedProcess[str]:
        return subprocess.run(
            [SRCSCTL, *args[:1], "--config", str(self.config), *args[1:]],
            input=stdin,
            capture_output=True,
            text=True,
            timeout=30,
            check=False,
        )

    def status(self) -> dict[str, object]:
        result = self.ctl("status", "--json")
        assert result.returncode == 0, result.stderr
        status = json.loads(result.stdout)
        assert isinstance(status, dict)
        return status

    def active(self) -> set[str]:
        causes = self.status()["causes"]
        assert isinstance(causes, list)
        return {c["name"] for c in causes if c["active"]}


@pytest.fixture
def robot(tmp_path: Path) -> Iterator[Robot]:
    (tmp_path / "robot.toml").write_text(CONFIG)
    with PtyPort(tmp_path / "vsc") as port:
        peer = VscPeer(port)
        with (
            SrcsdProcess(tmp_path / "robot.toml").start(serve=peer.serve) as daemon,
            peer.serving(),
        ):
            yield Robot(tmp_path, peer)
    assert daemon.exit_status == 0


def test_status_in_both_forms(robot: Robot) -> None:
    """The human form names the robot, the state, each cause and each output; --json is the
    API's reply with the daemon's own part (link, counters)."""
    status = robot.status()
    assert status["state"] == "STOPPED"
    daemon = status["daemon"]
    assert isinstance(daemon, dict)
    assert daemon["robot"] == "test-robot"
    assert daemon["pid"] > 0
    human = robot.ctl("status")
    assert human.returncode == 0
    assert human.stdout.startswith("robot test-robot: STOPPED\n")
    assert "outputs  drive=off" in human.stdout
    assert "startup (stop, " in human.stdout
    assert f"link     serial {robot.dir / 'vsc'}" in human.stdout


def test_estop_release_hold_and_a_refused_reset(robot: Robot) -> None:
    """A local e-stop and its release; a named hold that outlives the srcsctl process until
    the same name releases it; a reset refused with the core's reason and exit status 1."""
    done = robot.ctl("estop")
    assert done.returncode == 0, done.stderr
    assert "estop (local): done; the supervisor is STOPPED" in done.stdout
    assert "local_estop" in robot.active()
    assert robot.ctl("release").returncode == 0
    assert "local_estop" not in robot.active()

    assert robot.ctl("hold").returncode == 0
    assert "client_hold:srcsctl" in robot.active()  # the process has exited; the hold stays
    assert robot.ctl("release", "hold").returncode == 0
    assert "client_hold:srcsctl" not in robot.active()

    refused = robot.ctl("reset")
    assert refused.returncode == 1
    assert "refused: local reset is not allowed" in refused.stderr
    records = (robot.dir / "stops.jsonl").read_text().splitlines()
    assert any(json.loads(line)["kind"] == "rearm_refused" for line in records)


def test_display_and_vibrate_reach_the_vsc(robot: Robot) -> None:
    """Text rows, labelled values, the page and vibration go out as the manual's frames."""
    for args in (
        ("display", "row", "1", "HELLO"),
        ("display", "value", "3", "42", "--label", "SPEED"),
        ("display", "mode", "labelled"),
        ("vibrate", "left"),
    ):
        result = robot.ctl(*args)
        assert result.returncode == 0, (args, result.stderr)
    wanted = [FeedbackSet(3, 42), FeedbackSet(99, 2), FeedbackSet(10, 1)]
    deadline = time.monotonic() + 5
    while not all(m in robot.peer.received for m in wanted):
        assert time.monotonic() < deadline, robot.peer.received
        time.sleep(0.02)
    names = [m for m in robot.peer.received if isinstance(m, FeedbackName)]
    assert any(m.text.startswith("HELLO") for m in names)
    assert any(m.text.startswith("SPEED") for m in names)
    bad = robot.ctl("display", "row", "7", "X")
    assert bad.returncode == 1
    assert "bad_request" in bad.stderr


def test_commission_asks_for_confirmation_then_writes_and_reads_back(robot: Robot) -> None:
    """Without --yes it asks; anything but 'yes' writes nothing. With --yes it commissions."""
    robot.peer.key85 = 0
    declined = robot.ctl("commission", stdin="no\n")
    assert declined.returncode == 1
    assert "Type 'yes'" in declined.stdout
    assert robot.peer.key85 == 0
    done = robot.ctl("commission", stdin="yes\n")
    assert done.returncode == 0, done.stderr
    assert "commissioned: key 85 reads 1; remote status on" in done.stdout
    assert robot.peer.key85 == 1


def test_watch_follows_a_stop_live(robot: Robot) -> None:
    """``watch`` prints the state at once, then each change and record as it happens."""
    with subprocess.Popen(
        [SRCSCTL, "watch", "--config", str(robot.config)],
        stdout=subprocess.PIPE,
        stderr=subprocess.DEVNULL,
        text=True,
    ) as watcher:
        try:
            assert watcher.stdout is not None
            first = watcher.stdout.readline()
            assert " STOPPED " in first
            assert robot.ctl("estop").returncode == 0
            lines: list[str] = []
            while not any("local_estop" in line and "record #" in line for line in lines):
                lines.append(watcher.stdout.readline())
                assert lines[-1], "watch ended early"
            watcher.send_signal(signal.SIGINT)
            assert watcher.wait(timeout=10) == 0
        finally:
            if watcher.poll() is None:
                watcher.kill()


def test_no_daemon_and_bad_config_have_their_own_exit_status(tmp_path: Path) -> None:
    """3: nobody listens at the socket; 2: the config is invalid (the message names the key)."""
    missing = subprocess.run(
        [SRCSCTL, "status", "--socket", str(tmp_path / "none.sock")],
        capture_output=True,
        text=True,
        check=False,
    )
    assert missing.returncode == 3
    assert "is srcsd running?" in missing.stderr
    (tmp_path / "bad.toml").write_text(CONFIG.replace('transport = "serial"', 'transport = "x"'))
    bad = subprocess.run(
        [SRCSCTL, "status", "--config", str(tmp_path / "bad.toml")],
        capture_output=True,
        text=True,
        check=False,
        env={**os.environ, "SRCS_SOCKET": ""},
    )
    assert bad.returncode == 2
    assert "vsc.transport" in bad.stderr
