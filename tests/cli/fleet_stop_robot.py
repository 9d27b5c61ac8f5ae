"""robot-d of ``tests/cli/test_fleet.py``: the real ``srcsd`` against ``srcs-sim``, run inside
``tests/journald.robot_export``'s namespaces (journald's socket where srcsd looks for it), with
two remote e-stops in RUN. Each stop's window is awaited in the journal (the copy the flight
lane sends after the file, SR-13.12), and the robot's own ``srcsctl replay --file RECORD SEQ
--plot`` of each is written beside it for the test to compare with the collector's.

usage: python -m tests.cli.fleet_stop_robot FOLDER JOURNAL_DIR
Writes FOLDER/stops.json: the stops' ``seq`` and the record file's path; FOLDER/robot-SEQ.txt
(``replay``'s output and exit status) and FOLDER/robot-SEQ.svg."""

from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path

from supervisord.journal_ids import FLIGHT_WINDOW_MESSAGE_ID
from supervisord.testkit.robot import Robot
from supervisord.testkit.wait import wait_until

ROOT = Path(__file__).resolve().parents[2]
STOPS = 2


class JournalRobot(Robot):
    """A :class:`Robot` whose records (and windows) also go to the journal."""

    def config_text(self) -> str:
        return super().config_text().replace("journal = false", "journal = true")


def windows_in_journal(journal: str) -> int:
    found = subprocess.run(
        ["journalctl", f"--directory={journal}", "--no-pager", "-o", "cat",
         f"MESSAGE_ID={FLIGHT_WINDOW_MESSAGE_ID.hex}"],
        capture_output=True,
        text=True,
        check=False,
    )  # fmt: skip
    return len(found.stdout.splitlines())


def main(folder: Path, journal: str) -> None:
    seqs = []
    with JournalRobot(folder / "robot") as robot:
        robot.arm()
        for number in range(STOPS):
            stop = robot.remote_estop()
            seqs.append(stop.record.seq)

            def sent(count: int = number + 1) -> bool:
                return windows_in_journal(journal) >= count

            wait_until(sent, what="the window's entry in the journal")
            robot.vsc.release()
            robot.recover(stop)
        record = robot.record_path
    for seq in seqs:
        own = subprocess.run(
            [sys.executable, "-m", "supervisord.cli.srcsctl", "replay", "--file", str(record),
             str(seq), "--plot", str(folder / f"robot-{seq}.svg")],
            capture_output=True,
            text=True,
            cwd=ROOT,
            env={**os.environ, "PYTHONPATH": str(ROOT)},
            check=False,
        )  # fmt: skip
        (folder / f"robot-{seq}.txt").write_text(f"{own.returncode}\n{own.stdout}")
    (folder / "stops.json").write_text(json.dumps({"seqs": seqs, "record": str(record)}))


if __name__ == "__main__":
    main(Path(sys.argv[1]), sys.argv[2])
