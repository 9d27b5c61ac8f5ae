"""The reflex (SR-9.5; docs/performance.md "The reflex"): the real ``srcsd`` against
``srcs-sim``, its outputs' writes and its core's steps logged in order by a probe inside the
daemon's process, so that which came first is seen, not timed."""

from __future__ import annotations

import sys
from pathlib import Path

from supervisord.protocol.codes import VscMode
from supervisord.testkit.robot import OutputDef, Robot
from supervisord.testkit.wait import wait_until
from supervisord.vocabulary import State

DELAY_MS = 400
OUTPUTS = (
    OutputDef("drive", "motion"),
    OutputDef("brakes", "power", off_delay_ms=DELAY_MS),
    OutputDef("lights", "power"),
)
PROBE = """
import os, runpy, sys
from supervisord.outputs.sim import SimOutput
from supervisord.safety.core import SafetyCore
fd = os.open(sys.argv.pop(1), os.O_WRONLY | os.O_CREAT | os.O_APPEND, 0o644)
write, handle = SimOutput._write, SafetyCore.handle
def probed_write(self, on, now):
    os.write(fd, f"write {self.name} {int(on)}\\n".encode())
    return write(self, on, now)
def probed_handle(self, event):
    message = getattr(event, "message", None)
    mode, estop = getattr(message, "mode", None), getattr(message, "estop", None)
    os.write(fd, f"step {type(event).__name__} {mode} {estop}\\n".encode())
    return handle(self, event)
SimOutput._write = probed_write
SafetyCore.handle = probed_handle
runpy.run_module("supervisord.cli.srcsd", run_name="__main__", alter_sys=True)
"""
"""Logs, in the daemon's own process and in the order they happen, each write to a simulated
output (before it is made) and each input given to the core (before its step). It observes
and changes nothing: the daemon, its outputs and its core are the real ones."""


class ProbedRobot(Robot):
    """A robot whose daemon logs its outputs' writes and its core's steps to ``probe.log``."""

    @property
    def probe_path(self) -> Path:
        return self.workdir / "probe.log"

    def daemon_command(self) -> list[str]:
        command = super().daemon_command()
        at = command.index("-m")
        assert command[at - 1] == sys.executable
        assert command[at + 1] == "supervisord.cli.srcsd"
        return [*command[:at], "-c", PROBE, str(self.probe_path), *command[at + 2 :]]

    def probe(self) -> list[str]:
        return self.probe_path.read_text().splitlines()


def _around(lines: list[str], first_step: str) -> tuple[list[str], list[str]]:
    """The writes between the step before the first line starting ``first_step`` and it, and
    the lines after it."""
    at = next(i for i, line in enumerate(lines) if line.startswith(first_step))
    before = at
    while before > 0 and not lines[before - 1].startswith("step "):
        before -= 1
    return lines[before:at], lines[at + 1 :]


def _first_estop(line: str) -> bool:
    parts = line.split()
    return parts[:2] == ["step", "VscReceived"] and parts[3] not in ("0", "None")


def test_a_remote_estop_switches_its_outputs_off_before_the_cores_full_step(
    tmp_path: Path,
) -> None:
    """SR-9.5, SR-1.4: the first VSC heartbeat with the remote's e-stop word, in RUN, has the
    motion and the category-0 power output written off before the core is given it, and the
    category-1 output not (it stays on through its delay); the decision is the one without the
    reflex: STOPPED by ``vsc_estop``, no other write of those outputs after the step, every
    read-back matching, the category-1 output off after its delay."""
    robot = ProbedRobot(tmp_path, outputs=OUTPUTS)
    with robot:
        robot.arm()
        start = len(robot.probe())
        t = robot.now()
        robot.vsc.estop()
        stop = robot.expect_stop("vsc_estop", t, robot.beat_s)
        assert stop.record.from_state is State.RUN, stop.record
        wait_until(lambda: not robot.output_file("brakes"), what="the brakes off after the delay")
        lines = robot.probe()[start:]
        at = next(i for i, line in enumerate(lines) if _first_estop(line))
        early, after = _around(lines, lines[at])
        assert early == ["write drive 0", "write lights 0"], lines[: at + 1]
        writes = [line for line in after if line.startswith("write ")]
        assert writes == ["write brakes 0"], after  # the full step wrote nothing again
        status = robot.status()
        assert status.report.outputs == {"brakes": False, "drive": False, "lights": False}
        assert not any(name.startswith("output_fault") for name in robot.active(status))


def test_a_pause_switches_the_motion_output_off_before_the_cores_full_step(
    tmp_path: Path,
) -> None:
    """SR-9.5, SR-3.1: the first VSC heartbeat in Pause, in RUN, has the motion output written
    off before the core is given it, and no power output; the decision is HOLD by
    ``vsc_mode:pause`` with the power outputs on, and the full step writes nothing again."""
    robot = ProbedRobot(tmp_path, outputs=OUTPUTS)
    with robot:
        robot.arm()
        start = len(robot.probe())
        robot.vsc.pause()
        status = robot.wait_state(State.HOLD)
        assert "vsc_mode:pause" in robot.active(status)
        lines = robot.probe()[start:]
        pause = f"step VscReceived {int(VscMode.PAUSE)} "
        early, after = _around(lines, next(line for line in lines if line.startswith(pause)))
        assert early == ["write drive 0"], lines
        assert [line for line in after if line.startswith("write ")] == [], after
        status = robot.status()
        assert status.report.outputs == {"brakes": True, "drive": False, "lights": True}
        assert not any(name.startswith("output_fault") for name in robot.active(status))
