"""The remote switched off while the robot runs, reported both ways VSC hardware reports it
(PR-2.6): the real ``srcsd`` against ``srcs-sim --remote-off-reports`` (``docs/faults.md``)."""

from __future__ import annotations

from pathlib import Path

import pytest

from supervisord.testkit.robot import Robot


@pytest.mark.parametrize(
    ("reports", "reported"),
    [
        pytest.param("searching", ("searching", 0x02), id="searching"),
        pytest.param("local", ("local", 0x01), id="local"),
    ],
)
def test_remote_switched_off_stops_however_the_vsc_reports_it(
    tmp_path: Path, reports: str, reported: tuple[str, int]
) -> None:
    """PR-2.6, SR-2.1: the operator switches the remote off in RUN; the VSC reports it as
    Searching with bit 0x02 or as Local with the remote's e-stop bit 0x01. Either way every
    output is off by the next VSC heartbeat with ``vsc_estop`` recorded, and the robot runs
    again only after the remote is back and the operator takes over."""
    with Robot(tmp_path, sim_args=("--remote-off-reports", reports)) as robot:
        robot.arm()
        t0 = robot.now()
        state = robot.vsc.power(False)
        assert (state["mode_name"], state["estop"]) == reported
        stop = robot.expect_stop("vsc_estop", t0, robot.beat_s)
        robot.vsc.power(True)
        robot.recover(stop)
