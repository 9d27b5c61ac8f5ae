"""A robot's day for the fleet's tests (tests/cli/test_fleet_lines.py): the real ``srcsd``
against ``srcs-sim``, its records written to the journal too, through every kind of record a
fleet must tell apart (SR-13.9):

1. a start-up, whose proof test passes, and the operator's takeover (a re-arm);
2. the motion client killed: the stop ``client_lost:motion``, after which the supervisor's
   own user e-stop comes back from the VSC as ``vsc_estop (sources=user)`` while STOPPED;
3. a re-arm, then the remote's e-stop (a stop ``vsc_estop``), released and re-armed;
4. SIGTERM while in RUN (a stop ``shutdown:SIGTERM``);
5. a second start against a VSC whose watchdog ignores the missing heartbeat: its proof test
   FAILED; SIGTERM while STOPPED (no stop).

Run as ``python -m tests.cli.fleet_robot DIR`` beside a journald (tests/journald.py); the
record file is ``DIR/record/stops.jsonl``."""

from __future__ import annotations

import sys
import time
from dataclasses import dataclass
from pathlib import Path

from supervisord.testkit.robot import Robot
from supervisord.testkit.wait import WAIT_S, wait_until
from supervisord.vocabulary import Phase


@dataclass
class JournalRobot(Robot):
    """:class:`Robot` whose records go to the journal as well as to the file."""

    def config_text(self) -> str:
        return super().config_text().replace("journal = false", "journal = true")


def _phase(robot: Robot, *phases: Phase) -> Phase:
    def reached() -> Phase | None:
        proof = robot.status().report.prooftest
        return proof.phase if proof is not None and proof.phase in phases else None

    found = wait_until(reached, WAIT_S * 2, what=f"proof test {phases}")
    assert isinstance(found, Phase)
    return found


def _raised(robot: Robot, name: str, since: float) -> None:
    wait_until(lambda: robot.record_raising(name, since), what=f"a record raising {name}")


def day(workdir: Path) -> None:
    robot = JournalRobot(workdir, clients=("motion",))
    with robot:
        assert _phase(robot, Phase.PASSED, Phase.FAILED) is Phase.PASSED
        robot.arm()
        t = robot.now()
        robot.client_processes["motion"].kill()
        robot.expect_stop("client_lost:motion", t, 1.0)
        _raised(robot, "vsc_estop", t)  # the VSC echoes our own user e-stop (SR-5)
        robot.start_clients()
        robot.rearm()
        robot.remote_estop()
        robot.vsc.release()
        robot.rearm()
        assert robot.stop_daemon() == 0  # SIGTERM in RUN: shutdown:SIGTERM
        robot.vsc.fault(watchdog="ignores")
        robot.start_daemon()
        assert _phase(robot, Phase.PASSED, Phase.FAILED) is Phase.FAILED
        time.sleep(0.2)  # the proof test's record reaches the file on its own lane (SR-7.5)


if __name__ == "__main__":
    day(Path(sys.argv[1]))
