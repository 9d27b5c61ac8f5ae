"""The fleet's stop on the real ``srcsd`` against ``srcs-sim`` (SR-8.19, SR-8.20; docs/api.md
"fleet_stop"): the agent's stop stops a running robot, its acknowledgement says what the
outputs read back and which record raised it, a repeat is the same acknowledgement and no
second record, the release leaves the robot STOPPED until the takeover, and a connection of
any other user is refused."""

from __future__ import annotations

import os
import threading
from pathlib import Path

import pytest

from supervisord.api.framing import ApiError
from supervisord.api.ops import FleetKeepaliveRequest, FleetReleaseRequest, FleetStopRequest
from supervisord.api.replies import FleetStopReply, OkReply
from supervisord.testkit.robot import OutputDef, Robot
from supervisord.testkit.wait import wait_until
from supervisord.vocabulary import CauseKind, State

OUTPUTS = (OutputDef("drive"), OutputDef("lights", role="power"))


def fleet_robot(tmp_path: Path, agent_uid: int, more: str = "") -> Robot:
    """A robot whose ``[fleet]`` names ``agent_uid`` as the agent's user."""
    return Robot(tmp_path, outputs=OUTPUTS, extra_toml=f"[fleet]\nagent_uid = {agent_uid}\n{more}")


def test_the_agents_stop_stops_the_robot_and_is_acknowledged_with_the_facts(
    tmp_path: Path,
) -> None:
    """SR-8.19, SR-8.20: in RUN, ``fleet_stop`` from the agent's user switches every output
    off before its reply; the reply says STOPPED, each output off and read back off, the
    ``seq`` of the record that raised ``fleet_stop:console-a`` (which names the sender and the
    stop id) and a time from arrival to off. The same stop id again gets the same facts, marked
    a repeat, and writes no record."""
    with fleet_robot(tmp_path, os.getuid()) as robot:
        robot.arm()
        before = len(robot.records())
        with robot.client() as agent:
            ack = agent.call(FleetStopRequest("s-1", "console-a", id=7))
            assert isinstance(ack, FleetStopReply)
            # Off by the time the reply came: the outputs are set before it (SR-6.1, SR-8.20).
            assert robot.output_file("drive") is False
            assert robot.output_file("lights") is False
            assert (ack.id, ack.stop_id, ack.state) == (7, "s-1", State.STOPPED)
            assert {(o.name, o.level, o.readback) for o in ack.outputs} == {
                ("drive", False, False),
                ("lights", False, False),
            }
            assert ack.arrival_to_off_ms > 0
            assert not ack.repeat
            # The record is written by the record's lane after the reply went (SR-7.7): its
            # seq is in the acknowledgement at once, the record on disk soon after.
            wait_until(
                lambda: any(r.seq == ack.record_seq for r in robot.records()[before:]),
                what=f"record {ack.record_seq} on disk",
            )
            records = robot.records()
            raised = [r for r in records[before:] if r.seq == ack.record_seq]
            assert len(raised) == 1, [r.seq for r in records]
            cause = next(c for c in raised[0].causes if c.kind is CauseKind.FLEET_STOP)
            assert cause.name.name == "fleet_stop:console-a"
            assert dict(cause.details) == {"sender": "console-a", "stop_id": "s-1"}
            assert raised[0].trigger["stop_id"] == "s-1"

            again = agent.call(FleetStopRequest("s-1", "console-a", id=8))
            assert again == FleetStopReply(
                id=8,
                stop_id="s-1",
                state=ack.state,
                outputs=ack.outputs,
                record_seq=ack.record_seq,
                arrival_to_off_ms=ack.arrival_to_off_ms,
                repeat=True,
            )
            # Other records may follow (the VSC reports our user e-stop), none of this stop.
            later = robot.records()[len(records) :]
            assert not [r for r in later if r.trigger.get("event") == "fleet_stop"], later

            released = agent.call(FleetReleaseRequest("s-1", "console-a"))
            assert isinstance(released, OkReply)
        # SR-8.19: the release alone re-arms nothing; the operator's takeover does.
        status = robot.status()
        assert status.report.state is State.STOPPED
        assert "fleet_stop:console-a" not in status.report.active()
        robot.rearm()
        assert robot.status().report.state is State.RUN


def test_a_connection_of_another_user_is_refused_and_stops_nothing(tmp_path: Path) -> None:
    """SR-8.19: only the user ``[fleet] agent_uid`` names is heard: anyone else gets
    ``not_allowed`` and the robot runs on."""
    with fleet_robot(tmp_path, os.getuid() + 1) as robot:
        robot.arm()
        with robot.client() as other, pytest.raises(ApiError) as refused:
            other.call(FleetStopRequest("s-1", "console-a"))
        assert refused.value.code == "not_allowed"
        assert robot.status().report.state is State.RUN
        assert robot.output_file("drive") is True


class Console:
    """The fleet agent's keepalives on a connection of its own, every ``period_s``, until
    stopped (a console closed, a broker down, a network cut: the agent goes quiet)."""

    def __init__(self, robot: Robot, period_s: float) -> None:
        self.client = robot.client()
        self.period_s = period_s
        self.quiet = threading.Event()
        self.thread = threading.Thread(target=self._run, daemon=True)
        self.thread.start()

    def _run(self) -> None:
        while not self.quiet.is_set():
            self.client.call(FleetKeepaliveRequest("console-a"))
            self.quiet.wait(self.period_s)

    def stop(self) -> None:
        self.quiet.set()
        self.thread.join()
        self.client.close()


CONSOLE_TIMEOUT_MS = 2000  # ten keepalive periods: a busy machine misses none


def test_a_required_console_that_goes_quiet_stops_the_robot(tmp_path: Path) -> None:
    """SR-8.21: with ``console_required``, the robot starts with ``fleet_console_lost``
    (never heard) and re-arms only once keepalives come; when they stop, every output is off
    within ``console_timeout_ms`` (plus the harness's allowance) and the record names
    ``fleet_console_lost`` with the reason ``timeout``; keepalives that come back leave it
    STOPPED until the takeover."""
    more = f"console_required = true\nconsole_timeout_ms = {CONSOLE_TIMEOUT_MS}\n"
    with fleet_robot(tmp_path, os.getuid(), more) as robot:
        assert "fleet_console_lost" in robot.active_stops()
        console = Console(robot, CONSOLE_TIMEOUT_MS / 10_000)
        try:
            robot.arm()
        finally:
            console.stop()
        t0 = robot.now()
        stop = robot.expect_stop(CauseKind.FLEET_CONSOLE_LOST, t0, CONSOLE_TIMEOUT_MS / 1000)
        cause = next(c for c in stop.record.causes if c.kind is CauseKind.FLEET_CONSOLE_LOST)
        assert dict(cause.details) == {"reason": "timeout", "timeout_ms": str(CONSOLE_TIMEOUT_MS)}
        console = Console(robot, CONSOLE_TIMEOUT_MS / 10_000)
        try:
            wait_until(lambda: "fleet_console_lost" not in robot.active(), what="the console back")
            assert robot.status().report.state is State.STOPPED  # latched: no re-arm by it
            robot.rearm()
            assert robot.status().report.state is State.RUN
        finally:
            console.stop()
