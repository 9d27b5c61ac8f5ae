"""The remote's battery as the e-stop's availability (SR-8.12): the real ``srcsd`` against
``srcs-sim`` whose remote's battery runs low in RUN (``docs/faults.md``)."""

from __future__ import annotations

from pathlib import Path

import pytest

from supervisord.testkit.robot import Robot
from supervisord.testkit.wait import wait_until
from supervisord.vocabulary import State
from tests.faults.test_flight import _window_of, srcsctl

REPORT_S = 1.0  # the VSC's remote status comes once a second once commissioned
CAUSES = {"hold": "estop_unavailable_hold", "stop": "estop_unavailable"}


@pytest.mark.parametrize(
    "reaction", [pytest.param("hold", id="hold"), pytest.param("stop", id="stop")]
)
def test_a_low_remote_battery_in_run_holds_or_stops_and_a_good_one_is_needed_again(
    tmp_path: Path, reaction: str
) -> None:
    """SR-8.12 with ``vsc.on_estop_unavailable`` = ``hold`` or ``stop``: the VSC commissioned
    (its remote status once a second, the battery at 80 %), the robot in RUN; the simulated
    remote's battery drops to 10 % (below the minimum of 20 %). At the next report the
    motion output goes off and the change is recorded with the cause and its reason. Under
    ``hold`` the power output stays on and RUN comes back by itself once the battery reads
    80 % again; under ``stop`` every output is off, and back at 80 % the robot stays STOPPED
    until the operator's takeover; the stop's flight window, replayed, decides the same (the
    remote status it was fed and the reaction in its configuration, SR-7.12)."""
    extra = f'on_estop_unavailable = "{reaction}"'
    # A window holds at least the last 5 s of inputs, about 200 a second from the simulator:
    # more than the test kit's 64 KiB, so the record (which bounds the window) is given 1 MiB.
    with Robot(tmp_path, extra_vsc=extra, record_max_bytes=1 << 20) as robot:
        assert robot.watcher is not None
        with robot.client() as admin:
            admin.commission()
        cause = CAUSES[reaction]
        wait_until(lambda: cause not in robot.active(), what="the first battery report")
        robot.arm()
        t0 = robot.now()
        robot.vsc.call("remote_status", battery_level=10)
        off = robot.watcher.wait("drive", False, t0, timeout=REPORT_S * 5)
        held = robot.wait_state(State.HOLD if reaction == "hold" else State.STOPPED)
        assert cause in robot.active(held)
        record = robot.record_raising(cause, t0)
        assert record is not None
        [raised] = [c for c in record.causes if str(c.name) == cause]
        reason = raised.details["reason"]
        assert reason == "the remote's battery is 10 %, below 20 %"
        assert robot.output_file("power") is (reaction == "hold")
        if reaction == "stop":  # its window, replayed, decides as the daemon did (SR-7.12)
            _window_of(robot, record)
            done = srcsctl("replay", str(record.seq), "--config", str(robot.config_path))
            assert "replay matches the record" in done.stdout, done.stdout + done.stderr
        robot.vsc.call("remote_status", battery_level=80)
        if reaction == "hold":
            robot.wait_state(State.RUN, timeout=REPORT_S * 5)
            robot.watcher.wait("drive", True, off.t)
        else:
            wait_until(lambda: cause not in robot.active(), what="the battery back")
            assert robot.status().report.state is State.STOPPED
            assert robot.watcher.ons_between(t0, robot.now()) == []
            robot.rearm()
