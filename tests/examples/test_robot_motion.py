"""The motion service example (examples/motion, examples/systemd; docs/bringup.md): its unit
verifies beside the units it depends on, and the program, a required client, drives its wheel
only in RUN against the real ``srcsd`` and ``srcs-sim`` (SR-8.10, SR-8.15, SR-1.3, SR-4)."""

from __future__ import annotations

import os
import shutil
import signal
import subprocess
import sys
from pathlib import Path

import pytest

from supervisord.testkit.robot import Robot
from supervisord.testkit.wait import wait_until
from supervisord.vocabulary import State

REPO = Path(__file__).resolve().parents[2]
PROGRAM = REPO / "examples/motion/robot_motion.py"
UNIT = REPO / "examples/systemd/robot-motion@.service"
LOST = "client_lost:motion"


@pytest.mark.skipif(shutil.which("systemd-analyze") is None, reason="needs systemd-analyze")
def test_the_motion_unit_passes_systemd_analyze_verify(tmp_path: Path) -> None:
    """SR-8.10: systemd-analyze verify accepts the motion service's unit beside srcsd@ and the
    exporter (its commands pointed at this checkout: /opt/srcsd is the installed location)."""
    srcsctl = shutil.which("srcsctl") or str(REPO / ".venv/bin/srcsctl")
    text = (
        UNIT.read_text()
        .replace("/usr/bin/srcsctl", srcsctl)
        .replace("/opt/srcsd/bin/python3", sys.executable)
    )
    (tmp_path / UNIT.name).write_text(text)
    for name in ("srcsd@.service", "srcs-exporter@.service"):
        shutil.copy(REPO / "units" / name, tmp_path / name)
    result = subprocess.run(
        ["systemd-analyze", "verify", str(tmp_path / "robot-motion@robot-a.service")],
        check=False,
        capture_output=True,
        text=True,
        timeout=60,
    )
    assert result.returncode == 0, result.stderr
    assert result.stderr.strip() == "", result.stderr


def test_the_motion_unit_is_bound_to_srcsd_and_gated_by_wait_ready() -> None:
    """SR-8.10, SR-8.15: the unit starts behind the gate on its robot's socket, after srcsd@ and
    bound to it (stopped and restarted with it), restarted on failure, as its own user. The
    program reads the socket from the robot's config (``-R %i``) as the gate does: no socket
    of its own that could differ from the config's."""
    lines = set(UNIT.read_text().splitlines())
    assert not [line for line in lines if "--socket" in line or "/run/srcsd" in line]
    for line in (
        "BindsTo=srcsd@%i.service",
        "After=srcsd@%i.service",
        "ExecStartPre=/usr/bin/srcsctl -R %i wait-ready --timeout 60",
        "ExecStart=/opt/srcsd/bin/python3 /usr/local/lib/robot-motion/robot_motion.py -R %i "
        "--name motion --wheel /run/robot-motion/%i/wheel",
        "Restart=on-failure",
        "User=robot-motion",
        "SupplementaryGroups=srcsd",
    ):
        assert line in lines, line


def wheel(path: Path) -> float | None:
    try:
        return float(path.read_text())
    except (OSError, ValueError):
        return None


def test_the_motion_example_drives_only_in_run_and_stops_its_wheel(tmp_path: Path) -> None:
    """SR-1.3, SR-4, SR-8.10, SR-8.15: the example, the required client ``motion``, finds the
    socket in the robot's config (``--config``; the test robot's is not the default) and clears
    ``client_lost:motion``; its wheel stands while STOPPED, turns after the operator's takeover
    (RUN), stands again on the remote's e-stop, and stands when SIGTERM ends the program
    (exit 0)."""
    wheel_file = tmp_path / "wheel"
    with Robot(tmp_path / "robot", clients=("motion",)) as robot:
        env = {**os.environ, "PYTHONPATH": str(REPO)}
        # Its socket from the robot's config, as the unit's -R %i reads /etc/srcs/%i.toml.
        command = [sys.executable, str(PROGRAM), "--config", str(robot.config_path)]
        command += ["--wheel", str(wheel_file), "--speed", "0.4"]
        with subprocess.Popen(command, env=env) as program:
            try:
                wait_until(lambda: LOST not in robot.active(), what="the motion client beating")
                assert robot.status().report.state is State.STOPPED
                assert wheel(wheel_file) == 0.0
                robot.rearm()
                wait_until(lambda: wheel(wheel_file) == 0.4, what="the wheel turning in RUN")
                robot.sim.control.estop()
                wait_until(lambda: robot.status().report.state is State.STOPPED, what="STOPPED")
                wait_until(lambda: wheel(wheel_file) == 0.0, what="the wheel standing")
                robot.sim.control.release()
                robot.rearm()  # the command is zero again: the takeover re-arms (SR-4.6)
                wait_until(lambda: wheel(wheel_file) == 0.4, what="the wheel turning again")
                program.send_signal(signal.SIGTERM)
                assert program.wait(timeout=30) == 0
                assert wheel(wheel_file) == 0.0
            finally:
                if program.poll() is None:
                    program.kill()


def test_the_motion_example_refuses_a_missing_config_with_its_name(tmp_path: Path) -> None:
    """SR-8.10: a robot without its config is a typed refusal naming the file (status 2), not a
    traceback, and the wheel stands."""
    wheel_file = tmp_path / "wheel"
    missing = tmp_path / "robot-z.toml"
    command = [sys.executable, str(PROGRAM), "--config", str(missing), "--wheel", str(wheel_file)]
    env = {**os.environ, "PYTHONPATH": str(REPO)}
    result = subprocess.run(
        command, env=env, capture_output=True, text=True, timeout=60, check=False
    )
    assert result.returncode == 2, result.stderr
    assert str(missing) in result.stderr
    assert "Traceback" not in result.stderr
    assert wheel(wheel_file) == 0.0
