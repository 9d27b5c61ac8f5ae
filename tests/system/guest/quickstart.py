"""The system tier's ``quickstart`` scenario: the first-hour page run as written under systemd
(docs/quickstart.md; tests/docs/quickstart.py reads it).

On the booted guest, with the package installed by the ``install`` scenario, every block of
the page tagged ``guest`` runs in order, each as written by ``bash``, with the page's names
set as its step 0 says the test sets them: the robot ``robot-a``, the VSC the tier's
``srcs-sim`` on its pty at ``/dev/srcs-vsc`` (its key 85 set back to 0 first: a VSC fresh
from the box, which the page's commissioning must switch on), the motion output gpio-sim's
line 0. The page's hand steps are the simulator's: the takeover until RUN, the remote's e-stop
pressed when ``srcsctl stoptest`` asks for it, the e-stop released. After the config block,
both ``timeout_ms`` are set to 1000, as the page says (software emulation).

Checked beside the page's own commands (each of which must exit 0): RUN only after the
takeover, the motion line on in RUN and off after the stop test and after the motion
service's death; the stop test recorded as passed; the death a ``client_lost:motion`` stop
from RUN; systemd restarting the service behind the gate; STOPPED until the takeover after it.
The units are disabled and stopped at the end.
"""

from __future__ import annotations

import contextlib
import os
import subprocess
import threading
import time
from pathlib import Path
from typing import Any

from supervisord.client import SupervisorClient
from supervisord.record.jsonl import StoredRecord, read_records
from supervisord.safety.core import TAKEOVER_DWELL_NS
from supervisord.sim.process import SimError
from tests.docs.quickstart import PAGE, blocks
from tests.system.guest.scenarios import (
    DRIVE,
    Bench,
    Failed,
    Measured,
    Timeline,
    check,
    log,
    prop,
    run,
    wait_for,
)

ROBOT = "robot-a"
NAMES = {"ROBOT": ROBOT, "VSC": "/dev/srcs-vsc", "CHIP": "srcs-sim-gpio", "LINE": "0"}
"""Step 0 of the page, as the test sets it (the page says so)."""
SOCKET = Path("/run/srcsd/api.sock")  # the page's config keeps the default
RECORD = Path("/var/lib/srcsd/stops.jsonl")
CONFIG = Path("/etc/srcs", f"{ROBOT}.toml")
SRCSD = f"srcsd@{ROBOT}.service"
MOTION = f"robot-motion@{ROBOT}.service"
WHEEL = Path("/run/robot-motion", ROBOT, "wheel")
BLOCK_LIMIT_S = 600
"""A block's bound: the page's own waits are 120 s each, under emulation."""


def status() -> dict[str, Any]:
    with SupervisorClient.connect(SOCKET, timeout=10) as client:
        return client.status().json()


def state() -> str:
    try:
        return str(status()["state"])
    except Exception:  # not up yet, or restarting: no state
        return "DOWN"


def quiet() -> bool:
    try:
        causes = status()["causes"]
    except Exception:  # not up yet
        return False
    return not any(c["active"] and c["severity"] == "stop" for c in causes)


def take_over(bench: Bench, timeout: float = 120) -> float:
    """The operator's takeover on the remote until RUN (as scenarios.take_over, on this
    robot's socket); the seconds from the takeover that re-armed it."""
    start = time.monotonic()
    while time.monotonic() - start < timeout:
        wait_for("stop conditions clear", quiet, timeout, 0.2)
        time.sleep(0.7)  # the re-arm hold (500 ms)
        try:
            if bench.sim.control.state()["mode_name"] == "operational":
                bench.sim.control.pause()
                time.sleep(TAKEOVER_DWELL_NS / 1e9 + 0.15)
            took = time.monotonic()
            bench.sim.control.takeover()
        except SimError as refused:
            log(f"quickstart: the remote refused: {refused}")
            continue
        with contextlib.suppress(Failed):
            wait_for("RUN", lambda: state() == "RUN", 5, 0.1)
            return time.monotonic() - took
    raise Failed(f"{ROBOT} not in RUN within {timeout:.0f} s of takeovers")


def records() -> list[StoredRecord]:
    if not RECORD.exists():
        return []
    return [item for item in read_records(RECORD) if isinstance(item, StoredRecord)]


def run_block(step: str, text: str, bench: Bench) -> str:
    """One block of the page by bash, as written, with the page's names; its output. What
    the person does while a command waits for it (``srcsctl stoptest`` asks for the e-stop,
    and for a takeover when not in RUN) the simulator does when the command asks."""
    env = {**os.environ, **NAMES}
    process = subprocess.Popen(
        ["bash", "-c", "set -euo pipefail\n" + text],
        stdout=subprocess.PIPE,
        stderr=subprocess.STDOUT,
        text=True,
        env=env,
        cwd="/",
    )
    timer = threading.Timer(BLOCK_LIMIT_S, process.kill)
    timer.start()
    lines: list[str] = []
    try:
        assert process.stdout is not None
        for line in process.stdout:
            lines.append(line)
            log(f"quickstart {step}: {line.rstrip()}")
            if "press the remote's e-stop now" in line:
                bench.sim.control.estop()
            elif "take over on the remote (the supervisor must be in RUN" in line:
                take_over(bench)
        code = process.wait()
    finally:
        timer.cancel()
    output = "".join(lines)
    check(code == 0, f"the page's step {step} exited {code}: {output[-1500:]}")
    return output


def emulation_timeouts() -> None:
    """What the page says the test does after its config block: both timeout_ms to 1000."""
    text = CONFIG.read_text()
    for old in ("timeout_ms = 200\n", "timeout_ms = 500\n"):
        check(old in text, f"the page's config has no {old.strip()}")
        text = text.replace(old, "timeout_ms = 1000\n")
    CONFIG.write_text(text)


def hand(step: str, bench: Bench, measured: Measured) -> None:
    """A hand step of the page, done in the simulator as the page says."""
    if step == "rearm":
        bench.sim.control.release()
    if step in ("takeover", "rearm", "again"):
        took = take_over(bench)
        check(bench.gpio.value(DRIVE) == 1, f"{step}: in RUN, the motion line is off")
        measured[f"{step}: takeover to RUN s"] = round(took, 2)


def died(bench: Bench, timeline: Timeline, seq: int, restarts: int, measured: Measured) -> None:
    """After the page's death block: the motion line went off, the record has the stop from
    RUN with client_lost:motion, systemd restarted the service, STOPPED without a takeover."""
    offs = [t for t, level in timeline.of(DRIVE) if t >= 0 and level == 0]
    check(bool(offs), f"the motion line never went off: {timeline.of(DRIVE)}")
    stops = [r for r in records() if r.seq > seq and "client_lost:motion" in r.cause_names]
    check(
        any(r.data.get("from") == "RUN" for r in stops),
        "no client_lost:motion stop from RUN in the record",
    )
    check(int(prop(MOTION, "NRestarts")) > restarts, "systemd did not restart it")
    check(state() == "STOPPED", f"{state()} after the death, before a takeover")
    check(bench.gpio.value(DRIVE) == 0, "the motion line on before a takeover")
    # From the block's start: bash and systemctl kill first, then the client's 1000 ms.
    measured["death block's start to the motion line off ms"] = round(offs[0] * 1000)


def checked(step: str, output: str, bench: Bench) -> None:
    """What each block of the page must have done, beside its commands' exit status."""
    if step == "config":
        check(f"{ROBOT}.toml: OK" in output, f"the config's check: {output[-500:]}")
        emulation_timeouts()
    elif step == "commission":
        check(bench.sim.control.key(85) == 1, "key 85 is not 1 after commissioning")
    elif step == "motion":
        check(prop(MOTION, "ActiveState") == "active", "the motion service not active")
        check(state() == "STOPPED", f"{state()} before the first takeover")
    elif step == "running":
        check(float(output.rsplit(maxsplit=1)[-1]) == 0.5, f"the wheel in RUN: {output[-200:]}")
    elif step == "stoptest":
        check("stoptest: PASSED" in output, f"the stop test: {output[-800:]}")
        check(bench.gpio.value(DRIVE) == 0, "the motion line on after the stop test")


def scenario_quickstart(bench: Bench) -> tuple[str, Measured]:
    """SR-0.2, SR-8.10, SR-8.18, SR-12.1, SR-8.15, SR-4.4: docs/quickstart.md's guest blocks
    as written, in order, from a VSC with key 85 off to a motion service behind the gate, its
    first takeover, its first field stop test and its death, with the checks above."""
    run("systemctl", "stop", bench.unit)  # the VSC and the lines are the page's robot's
    bench.sim.control.release()
    bench.sim.control.key(85, 0)  # fresh from the box: the page's commissioning must do it
    measured: Measured = {}
    steps: list[str] = []
    try:
        for block in blocks(PAGE.read_text()):
            steps.append(block.step)
            if block.by_hand:
                hand(block.step, bench, measured)
                continue
            if "guest" not in block.places:
                continue
            t0 = time.monotonic()
            timeline = Timeline(bench.gpio, (DRIVE,))
            restarts = int(prop(MOTION, "NRestarts") or 0)
            seq = max((r.seq for r in records()), default=0)
            try:
                output = run_block(block.step, block.text, bench)
            finally:
                timeline.stop()
            measured[f"{block.step} s"] = round(time.monotonic() - t0, 1)
            if block.step == "death":
                died(bench, timeline, seq, restarts, measured)
            if "takeover" not in steps:
                check(state() != "RUN", f"RUN before the first takeover, after {block.step}")
            checked(block.step, output, bench)
        check(state() == "RUN", f"the page ends in {state()}, not RUN")
        check(bench.gpio.value(DRIVE) == 1, "the page ends with the motion line off")
        enabled = [prop(unit, "UnitFileState") for unit in (SRCSD, MOTION)]
        check(enabled == ["enabled", "enabled"], f"the page's units: {enabled}")
    finally:
        subprocess.run(["systemctl", "disable", "--now", MOTION, SRCSD], check=False)
        with contextlib.suppress(Exception):
            bench.sim.control.release()
            bench.sim.control.key(85, 1)
    return f"docs/quickstart.md's guest blocks as written: {', '.join(steps)}", measured
