"""End to end: the real ``srcsd`` against the real ``srcs-sim`` over a pseudo-terminal.

The supervisor feeds the simulated VSC's key-85 watchdog, a takeover on the remote arms it
(its output goes on), and the remote's e-stop stops it (the output goes off, the record
names the VSC e-stop)."""

from __future__ import annotations

import json
import time
from collections.abc import Callable
from pathlib import Path

from supervisord.sim.process import SimControl, SimError, SimProcess
from supervisord.testkit.daemon import MINIMAL_CONFIG, SrcsdProcess


def wait(done: Callable[[], bool], limit: float = 15.0) -> None:
    end = time.monotonic() + limit
    while not done():
        assert time.monotonic() < end, "timed out"
        time.sleep(0.01)


def output(path: Path) -> str:
    return path.read_text() if path.exists() else ""


def take_over(control: SimControl, limit: float = 10.0) -> None:
    """Take over as an operator would: retry while the supervisor's own stop still holds
    the VSC's user e-stop bit."""
    end = time.monotonic() + limit
    while True:
        try:
            control.takeover()
            return
        except SimError:
            if time.monotonic() > end:
                raise
            time.sleep(0.05)


def test_srcsd_is_armed_by_a_takeover_and_stopped_by_the_remote_estop(tmp_path: Path) -> None:
    (tmp_path / "robot.toml").write_text(MINIMAL_CONFIG)
    drive = tmp_path / "drive"
    log = tmp_path / "srcsd.log"
    with SimProcess(tmp_path, serial="vsc") as sim:
        assert sim.control.key(85, 1) == 1  # commissioned: the VSC watches the host
        with SrcsdProcess(tmp_path / "robot.toml", log=log) as daemon:
            # The supervisor reads key 85 back and feeds the watchdog at 20 Hz.
            state = sim.control.wait_for(
                lambda s: (
                    s["user_heartbeat_age"] is not None
                    and s["user_heartbeat_age"] < 0.2
                    and s["estop"] == 0
                    and s["mode_name"] == "local"
                ),
                timeout=15,
            )
            assert state["host_frames"] > 0
            wait(lambda: output(drive) == "0\n")
            # SR-5.3: the proof test of the VSC's watchdog comes before any RUN.
            wait(lambda: '"kind":"prooftest"' in output(tmp_path / "stops.jsonl"))
            time.sleep(0.3)  # longer than the 100 ms re-arm hold
            assert output(drive) == "0\n"  # Local is not a re-arm
            take_over(sim.control)
            wait(lambda: output(drive) == "1\n")
            sim.control.estop()
            wait(lambda: output(drive) == "0\n")
            assert sim.control.state()["mode_name"] == "local"
            time.sleep(0.3)
            assert output(drive) == "0\n"  # latched
        assert daemon.exit_status == 0
        assert "Traceback" not in log.read_text()
    records = [json.loads(line) for line in (tmp_path / "stops.jsonl").read_text().splitlines()]
    to_run = [r for r in records if r["to"] == "RUN"]
    assert to_run
    assert to_run[0]["rearm"]["kind"] == "takeover"
    stops = [r for r in records if r["to"] == "STOPPED" and r is not records[0]]
    assert any(
        cause["name"] == "vsc_estop" for record in stops for cause in record.get("causes", [])
    ), stops
