"""Faults of the vehicle computer around the daemon: its wall clock jumps, the disk under
the stop record fills up, an output line reads back something else than was written
(``docs/faults.md``)."""

from __future__ import annotations

import datetime as dt
import os
import time
from pathlib import Path

import pytest

from supervisord.client import SupervisorClient
from supervisord.testkit.faketime import SEEN_WITHIN_S, FakeWallClock
from supervisord.testkit.robot import ALLOWANCE_S, OutputDef, Robot
from supervisord.testkit.wait import wait_until
from supervisord.vocabulary import Cause as Named
from supervisord.vocabulary import CauseKind, State

LINK_TIMEOUT_MS = 1000  # vsc.timeout_ms at its largest (docs/configuration.md)


@pytest.mark.parametrize("jump_s", [3600, -86400], ids=["forward_1h", "back_1d"])
def test_wall_clock_jump_changes_nothing(tmp_path: Path, jump_s: int) -> None:
    """SR-2.11 "every deadline is measured on the monotonic clock; a wall-clock jump changes
    nothing": the daemon's wall clock jumps an hour forward or a day back while the robot
    runs. No stop, no output off. A remote e-stop afterwards is still off at once; its record
    carries the jumped UTC time (so the daemon really saw the jump) and a monotonic time that
    agrees with ours (so its deadlines did not move).

    The margins come from the jump: an hour (or a day) is far longer than any deadline, so
    a deadline kept on the wall clock would trip at the jump whatever its length. The link
    timeout is therefore the longest the configuration allows (1 s, SR-2.2), so that a busy
    machine's scheduling does not stop the robot in the scenario's stead. The window without
    a stop is counted from the rule's side: the daemon sees the jump at its next wall-clock
    read within ``SEEN_WITHIN_S`` of ``jump`` (libfaketime's cache), and a deadline on the
    wall clock would then trip within its own length plus the allowance."""
    clock = FakeWallClock(tmp_path)
    with Robot(tmp_path, clock=clock, extra_vsc=f"timeout_ms = {LINK_TIMEOUT_MS}") as robot:
        robot.arm()
        clock.jump(jump_s)
        robot.stays_running(SEEN_WITHIN_S + LINK_TIMEOUT_MS / 1000 + ALLOWANCE_S)
        stop = robot.remote_estop()
        utc = dt.datetime.fromisoformat(stop.record.utc)
        shift = (utc - dt.datetime.now(dt.timezone.utc)).total_seconds()
        assert abs(shift - jump_s) < 60, (stop.record.utc, jump_s)
        assert stop.t_fault * 1e9 <= stop.record.mono_ns <= stop.t_off * 1e9
        robot.vsc.release()
        clock.jump(-jump_s)  # and back: a second jump, the other way
        robot.recover(stop)


@pytest.mark.skipif(os.geteuid() != 0, reason="mounting a size-limited tmpfs needs root")
def test_full_disk_under_the_record_still_stops(tmp_path: Path) -> None:
    """SR-6.1 "set off first on every stop, before logging or anything slower", SR-7: the record's
    file system is full. A remote e-stop still turns every output off at once; the record
    that cannot be written is counted in ``status`` (``record_errors``) and logged, and it
    still reaches the API's subscribers with its cause. The daemon stays up; once there is
    room again the record goes on with the next sequence number."""
    with Robot(tmp_path, record_tmpfs_bytes=256 * 1024) as robot:
        robot.arm()
        assert robot.fill_record_disk() > 0
        with SupervisorClient.connect(robot.socket_path, name="watch") as watch:
            watch.subscribe("records")
            # Use up the slack of the record file's last page: holds and releases make
            # records until one of them does not fit.
            wait_until(lambda: _hold_and_release(watch) or robot.counters().record_errors)
            errors = robot.counters().record_errors
            stop = robot.remote_estop_unrecorded(watch)
        assert robot.counters().record_errors >= errors >= 1
        # The log line takes the sink's log lane, on its own thread's time (SR-7.7).
        wait_until(lambda: "stop record not written" in robot.log(), what="its log line")
        assert robot.daemon is not None
        assert robot.daemon.poll() is None
        robot.vsc.release()
        last_seq = robot.records()[-1].seq
        robot.free_record_disk()
        rearm = robot.recover(stop)
        assert rearm.seq > last_seq
        assert rearm in robot.records()


def _hold_and_release(client: SupervisorClient) -> bool:
    client.hold()
    client.release("hold")
    return False


STUCK_OFF = (OutputDef("drive", "motion", stuck_at="off"), OutputDef("power", "power"))


def test_output_stuck_off_is_an_output_fault(tmp_path: Path) -> None:
    """SR-6.2 "every write is read back; a mismatch is ``output_fault``": the motion line is
    stuck off (a broken driver). A takeover re-arms; switching it on reads back off, which
    is ``output_fault:drive``: the power output, switched on with it, is off again at once
    and the robot is STOPPED with the cause latched. The motion line never read on; the
    daemon keeps serving, and the next takeover meets the same fault."""
    with Robot(tmp_path, outputs=STUCK_OFF) as robot:
        assert robot.watcher is not None
        for _ in range(2):
            t0 = robot.now()
            rearm = robot.rearm()
            on = robot.watcher.wait("power", True, t0)
            off = robot.watcher.wait("power", False, on.t)
            assert off.t - rearm.mono_ns / 1e9 <= ALLOWANCE_S
            status = robot.wait_state(State.STOPPED)
            fault = next(
                c for c in status.report.causes if c.name == Named(CauseKind.OUTPUT_FAULT, "drive")
            )
            assert fault.latched, fault
            assert status.report.outputs == {"drive": False, "power": False}
            assert robot.watcher.first("drive", True, 0.0) is None
            assert robot.output_file("power") is False


def test_output_fault_stop_is_recorded(tmp_path: Path) -> None:
    """SR-7.1 "every change of state and every cause raised or cleared is one record": the stop
    of ``test_output_stuck_off_is_an_output_fault`` (RUN -> STOPPED, ``output_fault:drive``
    raised) is in the stop record."""
    with Robot(tmp_path, outputs=STUCK_OFF) as robot:
        t0 = robot.now()
        robot.rearm()
        robot.wait_state(State.STOPPED)
        stop = robot.expect_stop("output_fault:drive", t0, 0.0)
        assert stop.record.from_state is State.RUN


def test_output_stuck_on_never_lets_the_robot_run(tmp_path: Path) -> None:
    """SR-6, SR-4.1: the motion line is stuck on from the start (a welded contact). The read-back
    of the first "off" differs: ``output_fault:drive`` from the start, a condition that stays
    active, so a takeover seen by the daemon (the mode forced to Operational: the VSC itself
    is held in e-stop by our heartbeat's byte) is refused and recorded, and the power line is
    never switched on."""
    outputs = (OutputDef("drive", "motion", stuck_at="on"), OutputDef("power", "power"))
    with Robot(tmp_path, outputs=outputs) as robot:
        assert robot.watcher is not None
        wait_until(lambda: robot.record_raising("output_fault:drive", 0.0), what="the fault")
        robot.vsc.wait_for(lambda s: s["linked"])
        time.sleep(0.3)
        assert "output_fault:drive" in robot.active_stops()
        assert "user_request" in robot.vsc.state()["estop_bits"]
        assert "output_fault:drive" in (robot.refused_takeover().reason or "")
        time.sleep(0.3)
        assert robot.status().report.state is State.STOPPED
        assert robot.watcher.first("power", True, 0.0) is None
        assert robot.output_file("drive") is True  # stuck: what the line really does
