"""The fleet tier's ``windows_at_collector`` scenario (SR-13.12, SR-13.10; docs/fleet.md "A
stop's evidence at the collector"): after the other scenarios' stops (an e-stop on every robot,
three more on each of four robots during the collector's outage), every stop's flight recorder
window is at the collector, and the collector package's installed ``srcsctl fleet replay ROBOT
SEQ``, run in the collector's root as its administrator would, says what the robot's own
``srcsctl replay --file RECORD SEQ`` says of its window file, exit 0 ("replay matches the
record"), line for line but for the files' names. Once, the installed command also draws the
stop (``--plot``: the standard library only) and writes its MCAP file (``--mcap``, SR-7.15:
the collector's package bundles mcap, pure Python, and the file is written uncompressed), which
mcap's reader (the package's own, in its root) reads whole.

Both are the shipped commands: the robot's replay is the robot package's installed ``srcsctl``
(from the robots' layer, on the robot's record file), the reference the collector's answer is
held to; two Python starts a stop (some 18 stops: about 30 s of the tier on two cores).
"""

from __future__ import annotations

import json
import subprocess
import time
from collections.abc import Callable
from pathlib import Path
from typing import Any

from tests.fleet.collector import REMOTE, Collector
from tests.fleet.robots import Robot, poll

FLIGHT_MESSAGE_ID = "75233db4b0b14222b4593748065a0c40"
"""A window's entry (docs/record.md "The systemd journal")."""
EVIDENCE = "srv/evidence"
"""Where the installed command writes its files, in the collector's root."""
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


def robots_replay(srcsctl: Path, robot: Robot, seq: int) -> tuple[int, str, str]:
    """The robot package's installed ``srcsctl replay --file RECORD SEQ`` (its tree in the
    robots' shared layer, on this machine's python3, as in the robot's root) on the robot's
    own record: its exit status, standard output and standard error."""
    done = subprocess.run(
        [str(srcsctl), "replay", "--file", str(robot.record_file), str(seq)],
        env={"PATH": "/usr/sbin:/usr/bin:/sbin:/bin", "LANG": "C.UTF-8"},
        capture_output=True,
        check=False,
        timeout=60,
    )
    return (
        done.returncode,
        done.stdout.decode(errors="replace"),
        done.stderr.decode(errors="replace"),
    )


def collectors_replay(
    collector: Collector, label: str, seq: int, *options: str
) -> tuple[int, str, str]:
    """The collector package's ``srcsctl fleet replay`` on its receiver's directory, in the
    collector's root (SR-13.10): its exit status, standard output and standard error (each
    apart: a process's two streams reach one pipe in the order of their buffers' flushes)."""
    argv = ["srcsctl", "fleet", "replay", label, str(seq), "-D", f"/{REMOTE}", *options]
    done = collector.chroot(argv)
    return (
        done.returncode,
        done.stdout.decode(errors="replace"),
        done.stderr.decode(errors="replace"),
    )


def first_difference(mine: str, theirs: str) -> str:
    """The robot's line and the collector's where they first differ, and how many each has."""
    ours, others = mine.splitlines(), theirs.splitlines()
    pairs = zip([*ours, ""], [*others, ""], strict=False)
    first = next(((a, b) for a, b in pairs if a != b), ("(the same lines)", "(but the ends)"))
    return f"the robot's {len(ours)} lines, the collector's {len(others)}, first {first!r}"


def replay_both(collector: Collector, srcsctl: Path, robot: Robot, seq: int) -> str | None:
    """``None`` when the collector's replay of ``seq`` says what the robot's own does and
    matches the record; else what differs."""
    record = robot.record_file
    own_status, *own = robots_replay(srcsctl, robot, seq)
    label = f"{robot.name}@{robot.address}"
    status, *there = collectors_replay(collector, label, seq)
    named = f"{label}'s window of #{seq} at the collector"
    expected = [text.replace(f"{record}.flight/{seq}.jsonl", named) for text in own]
    if own_status != 0 or "replay matches the record" not in own[0]:
        return f"{label} #{seq}: the robot's own replay exit {own_status}: {own[0][-300:]}"
    if status != 0 or there != expected:
        differs = [
            f"{name}: {first_difference(mine, theirs)}"
            for name, mine, theirs in zip(("stdout", "stderr"), expected, there, strict=True)
            if mine != theirs
        ]
        return f"{label} #{seq}: the collector's replay exit {status}: {'; '.join(differs)}"
    return None


def exports(collector: Collector, robot: Robot, seq: int) -> tuple[list[str], str]:
    """The installed command's ``--plot`` (an SVG picture written in the collector's root) and
    ``--mcap`` (an MCAP file written there, exit 0, whose every message mcap's reader reads):
    what is wrong, and what was seen."""
    label = f"{robot.name}@{robot.address}"
    problems: list[str] = []
    (collector.root / EVIDENCE).mkdir(parents=True, exist_ok=True)
    picture = collector.root / EVIDENCE / f"{seq}.svg"
    status, said, _ = collectors_replay(collector, label, seq, "--plot", f"/{EVIDENCE}/{seq}.svg")
    drawn = picture.read_bytes() if picture.is_file() else b""
    if status != 0 or b"<svg" not in drawn:
        problems.append(f"--plot: exit {status}, {len(drawn)} bytes: {said[-300:]}")
    film = collector.root / EVIDENCE / f"{seq}.mcap"
    status, out, said = collectors_replay(
        collector, label, seq, "--mcap", f"/{EVIDENCE}/{seq}.mcap"
    )
    messages = mcap_messages(collector, f"/{EVIDENCE}/{seq}.mcap")
    if status != 0 or not film.is_file() or messages <= 0:
        problems.append(f"--mcap: exit {status}, {messages} messages read: {(out + said)[-300:]}")
    size = film.stat().st_size / 1024 if film.is_file() else 0.0
    return problems, (
        f"--plot {len(drawn) / 1024:.1f} KiB of SVG, --mcap {size:.1f} KiB, {messages} messages"
    )


READ_MCAP = """
import sys
from mcap.reader import make_reader
with open(sys.argv[1], "rb") as file:
    print(sum(1 for _ in make_reader(file).iter_messages()))
"""
"""Counts an MCAP file's messages with mcap's reader (the tier runs on the system's Python,
which has no mcap: the collector package's own environment reads it)."""


def mcap_messages(collector: Collector, film: str) -> int:
    """How many messages mcap's reader reads from ``film`` (a path in the collector's root),
    by the collector package's Python and its bundled mcap; -1 when it cannot read it."""
    done = collector.chroot(["/opt/srcs-collector/bin/python3", "-c", READ_MCAP, film])
    said = done.stdout.decode(errors="replace").strip()
    return int(said) if done.returncode == 0 and said.isdigit() else -1


def windows_at_collector(
    collector: Collector,
    robots: list[Robot],
    down: Robot,
    srcsctl: Path,
    result: Callable[[str, bool, str], None],
) -> None:
    """SR-13.12: every stop of every robot that is up has its window at the collector, and each
    replays there as on the robot (``srcsctl``: the robot package's installed command). The
    robot killed for the alert is shown, not judged: its uploader died with it, perhaps before
    its last window was sent."""
    started = time.monotonic()
    directory = collector.journal
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
                differs = replay_both(collector, srcsctl, robot, seq)
                replayed += 1
                if differs:
                    problems.append(differs)
    exported = ""
    shown = next((robot for robot in judged if made[robot.name]), None)
    if shown is not None and not problems:
        wrong, exported = exports(collector, shown, made[shown.name][-1])
        problems += wrong
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
        "the collector by its installed srcsctl, each as the robot's own replay, matching its "
        f"record; {exported}"
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
