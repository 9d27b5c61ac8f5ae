"""The fleet tier's ``windows_at_collector`` scenario (SR-13.12; docs/fleet.md "A stop's evidence
at the collector"): after the other scenarios' stops (an e-stop on every robot, three more on
each of four robots during the collector's outage), every stop's flight recorder window is at
the collector, and ``srcsctl fleet replay ROBOT SEQ`` there says what the robot's own
``srcsctl replay --file RECORD SEQ`` says of its window file, exit 0 ("replay matches the
record"), line for line but for the files' names.

Both replays run in this process, through the commands' own entry points
(``supervisord.cli.fleet.main``, ``supervisord.cli.replay.run_replay``): two Python starts a
stop would cost the shared machine some seconds each, for no other code.
"""

from __future__ import annotations

import contextlib
import io
import json
import subprocess
import sys
import time
from collections.abc import Callable
from pathlib import Path
from typing import Any

from tests.fleet.robots import Robot, poll

FLIGHT_MESSAGE_ID = "75233db4b0b14222b4593748065a0c40"
"""A window's entry (docs/record.md "The systemd journal")."""
ARRIVE_LIMIT_S = 60.0
"""How long the last window may take to reach the collector after the other scenarios: the
skewed robots' uploaders were started again by the outage; one upload round."""


def stops(robot: Robot) -> list[int]:
    """The ``seq`` of each stop in the robot's own record: a change into STOPPED from RUN or
    HOLD, the records that have a window (SR-7.12)."""
    return [
        int(r["seq"])
        for r in robot.own_records()
        if str(r.get("to")).upper() == "STOPPED" and str(r.get("from")).upper() != "STOPPED"
    ]


def windows_there(directory: Path) -> dict[str, dict[int, dict[str, Any]]]:
    """The windows' entries at the collector by robot (``_HOSTNAME``) and ``SRCS_SEQ``, without
    the window itself (its length and the field's)."""
    result = subprocess.run(
        ["journalctl", "--directory", str(directory), "--all", "-o", "json", "--no-pager",
         f"MESSAGE_ID={FLIGHT_MESSAGE_ID}"],
        capture_output=True,
        check=False,
        timeout=60,
    )  # fmt: skip
    found: dict[str, dict[int, dict[str, Any]]] = {}
    for line in result.stdout.decode().splitlines():
        entry = json.loads(line)
        sent = {
            "bytes": int(entry["SRCS_FLIGHT_BYTES"]),
            "field": len(entry["SRCS_FLIGHT"]),
        }
        found.setdefault(entry["_HOSTNAME"], {})[int(entry["SRCS_SEQ"])] = sent
    return found


def _run(main: Callable[[], int]) -> tuple[int, str]:
    out = io.StringIO()
    with contextlib.redirect_stdout(out), contextlib.redirect_stderr(out):
        status = main()
    return status, out.getvalue()


def replay_both(robot: Robot, seq: int, directory: Path) -> str | None:
    """``None`` when the collector's replay of ``seq`` says what the robot's own does and
    matches the record; else what differs."""
    from supervisord.cli.fleet import main as fleet_main  # noqa: PLC0415 -- the tree under test
    from supervisord.cli.replay import run_replay  # noqa: PLC0415

    record = robot.record_file
    # sys.stdout read when the call runs: the redirected one.
    own_status, own = _run(lambda: run_replay(str(seq), record, sys.stdout, sys.stderr))
    label = f"{robot.name}@{robot.address}"
    status, there = _run(lambda: fleet_main(["replay", label, str(seq), "-D", str(directory)]))
    named = f"{label}'s window of #{seq} at the collector"
    expected = own.replace(f"{record}.flight/{seq}.jsonl", named)
    if own_status != 0 or "replay matches the record" not in own:
        return f"{label} #{seq}: the robot's own replay exit {own_status}: {own[-300:]}"
    if status != 0 or there != expected:
        return f"{label} #{seq}: the collector's replay exit {status}: {there[-300:]}"
    return None


def windows_at_collector(
    directory: Path, robots: list[Robot], down: Robot, result: Callable[[str, bool, str], None]
) -> None:
    """SR-13.12: every stop of every robot that is up has its window at the collector, and each
    replays there as on the robot. The robot killed for the alert is shown, not judged: its
    uploader died with it, perhaps before its last window was sent."""
    started = time.monotonic()
    made = {robot.name: stops(robot) for robot in robots}
    judged = [robot for robot in robots if robot is not down]

    def arrived() -> bool:
        there = windows_there(directory)
        return all(set(made[r.name]) <= set(there.get(r.name, {})) for r in judged)

    took = poll(arrived, ARRIVE_LIMIT_S, step=0.5)
    there = windows_there(directory)
    problems: list[str] = []
    replayed = 0
    for robot in judged:
        missing = sorted(set(made[robot.name]) - set(there.get(robot.name, {})))
        if missing:
            problems.append(f"{robot.name}: no window at the collector for {missing}")
        for seq in made[robot.name]:
            if seq in there.get(robot.name, {}):
                differs = replay_both(robot, seq, directory)
                replayed += 1
                if differs:
                    problems.append(differs)
    sizes = [w for robot in there.values() for w in robot.values()]
    count = sum(len(seqs) for seqs in made.values())
    down_there = len(set(made[down.name]) & set(there.get(down.name, {})))
    detail = (
        f"{count} stops on {len(robots)} robots; every window of the {len(judged)} up at the "
        f"collector {took:.1f} s after the other scenarios"
        if took is not None
        else f"{count} stops on {len(robots)} robots; windows missing after {ARRIVE_LIMIT_S:.0f} s"
    )
    detail += (
        f" ({down.name}, killed: {down_there} of {len(made[down.name])}); {replayed} replayed at "
        "the collector, each as the robot's own replay, matching its record"
    )
    if sizes:
        raw = sorted(w["bytes"] for w in sizes)
        sent = sorted(w["field"] for w in sizes)
        detail += (
            f"; window {raw[0] / 1024:.1f} to {raw[-1] / 1024:.1f} KiB, sent as "
            f"{sent[0] / 1024:.1f} to {sent[-1] / 1024:.1f} KiB of base64; "
            f"scenario {time.monotonic() - started:.1f} s"
        )
    if problems:
        detail += "; " + "; ".join(problems[:4])
    result("windows_at_collector", not problems and took is not None, detail)
