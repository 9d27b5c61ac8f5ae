"""The client API of the real ``srcsd`` process, used through the shipped client library."""

from __future__ import annotations

import json
import os
import time
from pathlib import Path
from typing import Any

import pytest

from supervisord.api.framing import ApiError
from supervisord.client import SupervisorClient
from supervisord.protocol.codes import VscMode
from supervisord.sim.pty import PtyPort
from supervisord.testkit.daemon import LONGEST_CLIENT_TIMEOUT_MS, SrcsdProcess
from supervisord.vocabulary import State
from tests.daemon.peer import VscPeer
from tests.daemon.test_srcsd import CONFIG, SERVED_CONFIG, wait

REQUIRED_CLIENT = f'\n[[clients]]\nname = "autonomy"\ntimeout_ms = {LONGEST_CLIENT_TIMEOUT_MS}\n'
"""The client is this test process: the longest client timeout (SR-8), as RUN must last while
it blocks on its own requests; ``tests/faults/test_clients.py`` proves the timeout itself."""


def test_client_keeps_the_robot_running_and_local_commands_stop_it(tmp_path: Path) -> None:
    """SR-0.2, SR-8.1, SR-8.2: a required client's hello and heartbeats let a takeover run the
    robot; an operator's local e-stop over the socket stops it; a reset without local_reset
    is refused with the core's reason; a state push reaches subscribers. The VSC and the
    client are this process: their timeouts are the longest allowed (a client's silence
    stopping the robot is ``tests/faults/test_clients.py``'s, with a client of its own)."""
    (tmp_path / "robot.toml").write_text(SERVED_CONFIG + REQUIRED_CLIENT)
    with PtyPort(tmp_path / "vsc") as port:
        peer = VscPeer(port)
        with (
            SrcsdProcess(tmp_path / "robot.toml").start(serve=peer.serve) as daemon,
            SupervisorClient.connect(daemon.socket) as robot,
        ):
            robot.hello("autonomy")
            robot.subscribe("state")
            deadline = time.monotonic() + 10
            # Heartbeats at 10 Hz, VSC traffic flowing, until the proof test of the VSC's
            # watchdog has passed (SR-5.3: it comes before any RUN), then for
            # longer than the re-arm hold.
            while robot.status().json()["prooftest"]["phase"] != "passed":
                assert time.monotonic() < deadline, robot.status().json()["prooftest"]
                robot.heartbeat()
                peer.serve()
                time.sleep(0.02)
            clear = time.monotonic() + 0.4
            while time.monotonic() < clear:
                robot.heartbeat()
                peer.serve()
                time.sleep(0.02)
            assert "client_lost:autonomy" not in {
                c["name"] for c in robot.status().json()["causes"] if c["active"]
            }
            peer.mode = VscMode.OPERATIONAL
            deadline = time.monotonic() + 5
            while robot.status().json()["state"] != "RUN":
                assert time.monotonic() < deadline
                robot.heartbeat()
                peer.serve()
                time.sleep(0.02)
            assert (tmp_path / "drive").read_text() == "1\n"

            with SupervisorClient.connect(tmp_path / "api.sock") as operator:
                operator.estop()  # no hello: the operator's local e-stop
                status = operator.status()
                assert status.report.state is State.STOPPED
                assert "local_estop" in status.report.active()
                assert (tmp_path / "drive").read_text() == "0\n"
                operator.release("estop")
                with pytest.raises(ApiError, match="local reset is not allowed"):
                    operator.reset()

            pushes = []
            while (push := robot.next_event(timeout=0.2)) is not None:
                pushes.append(push)
            assert any(p.event == "state" and p.json()["state"] == "STOPPED" for p in pushes)
    assert daemon.exit_status == 0
    assert not (tmp_path / "api.sock").exists()


def _daemon(tmp_path: Path, peer: VscPeer | None = None) -> SrcsdProcess:
    (tmp_path / "robot.toml").write_text(CONFIG)
    return SrcsdProcess(tmp_path / "robot.toml").start(serve=peer.serve if peer else lambda: None)


def _commissionings(tmp_path: Path) -> list[dict[str, Any]]:
    """The records a commissioning made, found by their trigger: the record's ``kind`` is
    ``commissioned`` unless a cause changed in the same step (docs/record.md: ``cause_raised``
    comes first), as when a late turn also finds the VSC silent on a busy machine. A proof
    test the same step settles has a record of its own (kind ``prooftest``), not counted: it
    comes when the proof test was waiting for the commissioning, which depends on timing."""
    lines = (tmp_path / "stops.jsonl").read_text().splitlines()
    records = [json.loads(line) for line in lines]
    return [
        r for r in records if r["trigger"]["event"] == "commissioned" and r["kind"] != "prooftest"
    ]


def _active(status: dict[str, object]) -> set[str]:
    causes = status["causes"]
    assert isinstance(causes, list)
    return {c["name"] for c in causes if c["active"]}


def test_commissioning_writes_key85_reads_it_back_and_records_it(tmp_path: Path) -> None:
    """SR-5: a VSC whose watchdog is off keeps the robot STOPPED with
    vsc_watchdog_off; an admin's commission writes key 85 and enables remote status, the reply
    carries what was read back, the record has a ``commissioned`` entry, and the cause clears."""
    with PtyPort(tmp_path / "vsc") as port:
        peer = VscPeer(port, key85=0)
        with _daemon(tmp_path, peer) as daemon, SupervisorClient.connect(daemon.socket) as admin:
            wait(peer, lambda: "vsc_watchdog_off" in _active(admin.status().json()))
            with peer.serving():
                reply = admin.commission().json()
            assert (reply["key85"], reply["remote_status"]) == (1, True)
            assert peer.key85 == 1
            assert peer.remote_status_ms == 1000
            wait(peer, lambda: "vsc_watchdog_off" not in _active(admin.status().json()))
    assert daemon.exit_status == 0
    [entry] = _commissionings(tmp_path)
    assert entry["reason"] == "key85=1 remote_status=on"
    assert entry["trigger"]["caller"]["uid"] == os.getuid()


def test_commissioning_that_reads_nothing_back_fails_and_is_recorded(tmp_path: Path) -> None:
    """SR-5, SR-7.1: a VSC that never answers Feedback Get: the reply is ``failed`` after the
    procedure's timeout, naming what was read (nothing), and the attempt is still recorded."""
    with PtyPort(tmp_path / "vsc") as port:
        peer = VscPeer(port, key85=0)
        peer.answers_feedback = False
        with (
            _daemon(tmp_path, peer) as daemon,
            SupervisorClient.connect(daemon.socket) as admin,
            peer.serving(),
        ):
            with pytest.raises(ApiError, match="key 85 reads back no answer") as failure:
                admin.commission()
            assert failure.value.code == "failed"
            assert failure.value.extra["key85"] is None
    assert daemon.exit_status == 0
    [entry] = _commissionings(tmp_path)
    assert str(entry["reason"]).startswith("key85=no answer "), entry


def test_commissioning_without_a_link_is_unavailable(tmp_path: Path) -> None:
    """No VSC at the port: nothing to write to, said at once."""
    with _daemon(tmp_path) as daemon, SupervisorClient.connect(daemon.socket) as admin:
        with pytest.raises(ApiError, match="no link to the VSC") as failure:
            admin.commission()
        assert failure.value.code == "unavailable"
    assert daemon.exit_status == 0
