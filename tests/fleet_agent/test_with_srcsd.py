"""The acknowledged fleet stop end to end (SR-13.13, SR-13.15, SR-8.19, SR-8.20): the console's
``srcsctl fleet stop`` through a real mosquitto with mutual TLS, the real agent process, the
real ``srcsd`` against ``srcs-sim``. The robot in RUN stops; the console shows it stopped with
every output read back off and the record that raised ``fleet_stop:console-1``; the release
through the network leaves it STOPPED (nothing that arrives over the network re-arms it);
only the operator's takeover does."""

from __future__ import annotations

import os
import re
import subprocess
import sys
from collections.abc import Iterator
from pathlib import Path

import pytest

from supervisord.testkit.robot import OutputDef, Robot
from supervisord.testkit.wait import wait_until
from supervisord.vocabulary import CauseKind, State
from tests.fleet_agent.agents import console, running_agents
from tests.fleet_agent.broker import FLEET, Broker, running_broker, tls

OUTPUTS = (OutputDef("drive"), OutputDef("lights", role="power"))


@pytest.fixture
def broker(tmp_path: Path) -> Iterator[Broker]:
    with running_broker(tmp_path / "broker") as running:
        yield running


def test_the_console_stops_a_running_robot_and_shows_its_outputs_read_back(
    tmp_path: Path, broker: Broker, capsys: pytest.CaptureFixture[str]
) -> None:
    workdir = tmp_path / "robot-a"
    workdir.mkdir()
    fleet = f"[fleet]\nagent_uid = {os.getuid()}\n"
    with (
        Robot(workdir, outputs=OUTPUTS, extra_toml=fleet) as robot,
        running_agents(broker, {"robot-a": robot.socket_path}, tmp_path),
    ):
        robot.arm()
        assert robot.output_file("drive") is True
        status, out = console(broker, capsys, "stop", "robot-a", "--deadline", "15")
        assert status == 0, out
        assert robot.output_file("drive") is False
        assert robot.output_file("lights") is False
        line = next(line for line in out.splitlines() if line.startswith("robot-a"))
        assert "stopped STOPPED drive=off(read off) lights=off(read off)" in line
        seq = int(re.search(r"record (\d+)", line).group(1))  # type: ignore[union-attr]
        raised = next(r for r in robot.records() if r.seq == seq)
        cause = next(c for c in raised.causes if c.kind is CauseKind.FLEET_STOP)
        assert cause.name.name == "fleet_stop:console-1"
        assert "every robot answered (1)" in out
        stop_id = dict(cause.details)["stop_id"]

        # The console withdraws its stop: released, and the robot stays STOPPED (SR-8.19).
        status, out = console(
            broker, capsys, "stop", "robot-a", "--release", "--stop-id", str(stop_id)
        )
        assert status == 0, out
        assert "released" in out
        report = robot.status().report
        assert report.state is State.STOPPED
        assert "fleet_stop:console-1" not in report.active()
        assert robot.output_file("drive") is False
        robot.rearm()  # the operator's takeover, and only it


def test_a_required_console_keeps_the_robot_going_and_its_end_stops_it(
    tmp_path: Path, broker: Broker
) -> None:
    """SR-8.21 through the network: a robot whose config requires the fleet's console can be
    armed once ``srcsctl fleet keepalive`` runs (its keepalives passed on by the agent), and
    stops with ``fleet_console_lost`` when the console ends."""
    workdir = tmp_path / "robot-a"
    workdir.mkdir()
    fleet = (
        f"[fleet]\nagent_uid = {os.getuid()}\nconsole_required = true\nconsole_timeout_ms = 1500\n"
    )
    keys = tls(broker.pki, "console-1")
    keepalive_command = [
        sys.executable, "-m", "supervisord.cli.srcsctl", "fleet", "keepalive",
        "--period", "0.2", "--fleet", FLEET, "--broker", f"127.0.0.1:{broker.port}",
        "--cafile", str(keys.cafile), "--cert", str(keys.certfile), "--key", str(keys.keyfile),
        "--name", "console-1",
    ]  # fmt: skip
    with (
        Robot(workdir, outputs=OUTPUTS, extra_toml=fleet) as robot,
        running_agents(broker, {"robot-a": robot.socket_path}, tmp_path),
    ):
        console_process = subprocess.Popen(
            keepalive_command, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL
        )
        try:
            wait_until(
                lambda: "fleet_console_lost" not in robot.status().report.active(),
                30,
                what="the console's keepalives to end fleet_console_lost",
            )
            robot.arm()
            assert robot.output_file("drive") is True
            t0 = robot.now()
        finally:
            console_process.terminate()
            console_process.wait(10)
        stop = robot.expect_stop(CauseKind.FLEET_CONSOLE_LOST, t0, deadline_s=1.5 + 1.0)
        assert stop.record.to_state is State.STOPPED
