"""A robot's bringup as docs/ros2.md and docs/srcsctl.md describe it (SR-8.10, SR-8.15): a
service that is a required client starts behind ``srcsctl wait-ready``, in both orders, against
the real ``srcsd`` and ``srcs-sim`` (the simulated VSC, its key-85 watchdog commissioned)."""

from __future__ import annotations

import subprocess
from pathlib import Path

from supervisord.record.stop import RecordKind, StopRecord
from supervisord.sim.pty import PtyPort
from supervisord.testkit.daemon import MINIMAL_CONFIG, SrcsdProcess
from supervisord.testkit.robot import Robot
from supervisord.testkit.wait import wait_until
from supervisord.vocabulary import State
from tests.daemon.peer import VscPeer
from tests.daemon.test_srcsctl import SRCSCTL

GATE_S = 30
"""The gate's timeout: far beyond a start with a proof test (the simulator's 1 s boot, then
0.5 to 0.7 s of the test), so that only a gate that never opens reaches it."""
LOST = "client_lost:motion"


def _gate(robot: Robot, *options: str) -> subprocess.CompletedProcess[str]:
    """``srcsctl wait-ready`` as a unit's ``ExecStartPre`` runs it."""
    config = str(robot.config_path)
    return subprocess.run(
        [SRCSCTL, "wait-ready", "--config", config, "--timeout", str(GATE_S), *options],
        capture_output=True,
        text=True,
        timeout=GATE_S + 30,
        check=False,
    )


def test_a_required_client_started_behind_the_gate_comes_up_and_the_robot_runs(
    tmp_path: Path,
) -> None:
    """SR-8.15, SR-8.10: with the required client ``motion`` not started, the gate opens (the
    proof test passes without it, the robot STOPPED with ``client_lost:motion``) and names the
    client as what RUN still needs; the client, started after the gate, then reaches RUN with
    the operator's takeover."""
    with Robot(tmp_path, clients=("motion",)) as robot:
        gate = _gate(robot)
        assert gate.returncode == 0, gate.stderr
        assert "wait-ready: ready" in gate.stdout
        assert "also missing for RUN, not for ready: required client `motion` not connected" in (
            gate.stdout
        )
        status = robot.status()
        assert status.report.state is State.STOPPED
        assert LOST in robot.active_stops(status)
        assert status.report.prooftest is not None
        assert status.report.prooftest.last is not None
        assert status.report.prooftest.last.result == "passed", status.report.prooftest
        robot.arm()  # the service behind the gate starts; the operator takes over
        assert robot.status().report.state is State.RUN


def test_a_required_client_started_before_the_gate_comes_up_and_the_robot_runs(
    tmp_path: Path,
) -> None:
    """SR-8.15, SR-8.10: with the required client already running, the gate opens and says
    nothing more is missing; the operator's takeover reaches RUN."""
    with Robot(tmp_path, clients=("motion",)) as robot:
        robot.start_clients()
        wait_until(lambda: LOST not in robot.active(), what="the client connected and beating")
        gate = _gate(robot)
        assert gate.returncode == 0, gate.stderr
        assert "also missing" not in gate.stdout, gate.stdout
        robot.arm()
        assert robot.status().report.state is State.RUN


def test_a_takeover_right_after_wait_ready_rearmable_is_accepted(tmp_path: Path) -> None:
    """SR-8.10, SR-4.1: ``wait-ready --rearmable`` exits 0 only once a takeover would be
    accepted (every stop condition clear for ``rearm.hold_ms``, here 1.5 s); the operator's
    takeover made right after it re-arms, where one right after plain ready could be refused
    for the hold. Its ready line says a takeover is accepted now."""
    with Robot(tmp_path, clients=("motion",), rearm_hold_ms=1500) as robot:
        robot.start_clients()
        gate = _gate(robot, "--rearmable")
        assert gate.returncode == 0, gate.stderr
        assert "; a takeover is accepted now" in gate.stdout, gate.stdout
        control = robot.sim.control
        sim = control.wait_for(lambda s: s["linked"] and not s["booting"], timeout=GATE_S)
        assert sim["estop"] == 0
        assert sim["mode_name"] != "operational", sim
        t = robot.now()
        control.takeover()
        answer: list[StopRecord] = wait_until(
            lambda: [
                r
                for r in robot.records_since(t)
                if r.rearm is not None or r.kind is RecordKind.REARM_REFUSED
            ],
            what="the takeover's record",
        )
        assert answer[0].rearm is not None, answer[0]
        assert answer[0].to_state is State.RUN, answer[0]


def test_wait_ready_says_when_a_takeover_is_accepted(tmp_path: Path) -> None:
    """SR-8.10: plain ``wait-ready`` says in its ready line when a takeover will be accepted:
    with the required client missing, once its ``client_lost`` clears and stays clear for the
    re-arm hold; ``status`` carries the hold and no time while a stop condition is active."""
    with Robot(tmp_path, clients=("motion",), rearm_hold_ms=1500) as robot:
        gate = _gate(robot)
        assert gate.returncode == 0, gate.stderr
        said = gate.stdout.partition("; a takeover is accepted once: ")[2]
        # vsc_estop may be among them: the VSC's user bits clear just after the proof test.
        assert LOST in said.partition(" to clear")[0], gate.stdout
        assert " to clear and stay clear for 1500 ms (the re-arm hold)" in said, gate.stdout
        rearm = robot.status().rearm
        assert rearm is not None
        assert (rearm.hold_ms, rearm.clear_for_s, rearm.accepted_in_s) == (1500, None, None)


def test_wait_ready_names_a_missing_required_client_and_what_the_proof_test_waits_for(
    tmp_path: Path,
) -> None:
    """SR-8.15, SR-8.10, SR-8.18: while it waits, and when it gives up, ``wait-ready`` names each
    part missing in words: the VSC not heard, key 85 unread, the proof test with what it waits
    for, the required client ``motion`` by its name and what brings it, as something RUN needs
    and ready does not."""
    config = tmp_path / "robot.toml"
    config.write_text(MINIMAL_CONFIG + '[[clients]]\nname = "motion"\n')
    with PtyPort(tmp_path / "vsc"), SrcsdProcess(config).start():
        silent = subprocess.run(
            [SRCSCTL, "wait-ready", "--config", str(config), "--timeout", "1"],
            capture_output=True,
            text=True,
            timeout=30,
            check=False,
        )
    assert silent.returncode == 1, silent.stderr
    parts = (
        "the VSC is not heard; the VSC's key-85 watchdog is off; the proof test of the VSC's "
        "watchdog has not passed (waiting for the VSC to be heard and key 85 to read 1); also "
        "missing for RUN, not for ready: required client `motion` not connected (start its "
        "program, as the user its [[clients]] entry names)"
    )
    assert f"wait-ready: waiting for: {parts}\n" in silent.stderr
    assert f"wait-ready: not ready after 1 s: {parts}\n" in silent.stderr
    # Key 85 not read yet (the VSC not heard): no commissioning is asked for (SR-8.18).
    assert "commission" not in silent.stderr


def test_wait_ready_names_a_stop_of_ours_that_keeps_the_proof_test_waiting(
    tmp_path: Path,
) -> None:
    """SR-8.15, SR-8.10: a local e-stop pressed before the VSC is heard keeps the proof test
    from starting once it is heard, and ``wait-ready`` names it as what the test waits for."""
    config = tmp_path / "robot.toml"
    config.write_text(MINIMAL_CONFIG)
    with PtyPort(tmp_path / "vsc") as port, SrcsdProcess(config).start() as daemon:
        pressed = subprocess.run(
            [SRCSCTL, "estop", "--config", str(config)],
            capture_output=True,
            text=True,
            timeout=30,
            check=False,
        )
        assert pressed.returncode == 0, pressed.stderr
        peer = VscPeer(port)
        with peer.serving():
            waiting = subprocess.run(
                [SRCSCTL, "wait-ready", "--config", str(config), "--timeout", "3"],
                capture_output=True,
                text=True,
                timeout=30,
                check=False,
            )
    assert daemon.exit_status == 0
    assert waiting.returncode == 1, waiting.stderr
    assert "has not passed (waiting for local_estop to clear)" in waiting.stderr, waiting.stderr
