"""Faults on a CAN-connected VSC (J1939 over python-can's ``udp_multicast`` between the real
``srcsd`` and ``srcs-sim --can``, each scenario in a private network namespace where it can
have one). On CAN there is no user heartbeat and no key 85: the supervisor's outputs carry
the duty alone (SR-5), so every silence must become a stop (``docs/faults.md``)."""

from __future__ import annotations

import time
from pathlib import Path

import pytest

from supervisord.testkit.robot import Robot
from supervisord.testkit.wait import wait_until
from supervisord.vocabulary import State

# Every scenario multicasts: only inside the session's private network (docs/testing.md).
pytestmark = pytest.mark.usefixtures("private_network")

HEARTBEAT = 0x20  # the heartbeat's serial type; the simulator's CAN faults use the same names
JOYSTICK = 0x10  # the joystick frames (basic and extended, both hands) by the same name


def test_can_silence_is_a_lost_link(tmp_path: Path) -> None:
    """SR-2.2 ``vsc_link_lost`` on CAN, 300 ms: the VSC stops sending (its transceiver fails
    quietly). Off within the timeout; the heartbeats coming back are no takeover."""
    with Robot(tmp_path, transport="can") as robot:
        robot.arm()
        t0 = robot.now()
        robot.vsc.silence(True)
        stop = robot.expect_stop("vsc_link_lost", t0, robot.vsc_timeout_s)
        robot.vsc.silence(False)
        wait_until(lambda: not robot.active_stops(), what="heartbeats again")
        time.sleep(0.4)
        assert robot.status().report.state is State.STOPPED
        robot.recover(stop)


@pytest.mark.parametrize(
    ("fault", "rejection"),
    [
        pytest.param({"drop": 1.0}, None, id="dropped"),
        pytest.param({"wrong_length": 1.0}, "wrong_length", id="wrong_length"),
    ],
)
def test_can_heartbeats_that_do_not_arrive_whole_are_a_lost_link(
    tmp_path: Path, fault: dict[str, float], rejection: str | None
) -> None:
    """SR-2: heartbeat frames dropped, or cut short (fewer data bytes than the message needs),
    while the joystick frames keep coming: no valid heartbeat, off within 300 ms."""
    with Robot(tmp_path, transport="can") as robot:
        robot.arm()
        t0 = robot.now()
        robot.vsc.fault(**fault, only_types=[HEARTBEAT])
        stop = robot.expect_stop("vsc_link_lost", t0, robot.vsc_timeout_s)
        if rejection is not None:
            assert robot.counters().rejections.get(rejection, 0) > 0
        robot.vsc.fault()
        robot.recover(stop)


def test_can_bus_off_is_a_transport_fault(tmp_path: Path) -> None:
    """SR-2.3 ``transport_fault``: the VSC's controller goes bus-off (an error frame, then
    nothing). Off at once; the daemon reopens the bus and finds it silent
    (``vsc_link_lost``); when the VSC recovers, its heartbeats (still Operational) are no
    takeover: STOPPED until the operator takes over."""
    with Robot(tmp_path, transport="can") as robot:
        robot.arm()
        t0 = robot.now()
        robot.vsc.bus_off(True)
        stop = robot.expect_stop("transport_fault", t0, 0.0)
        wait_until(lambda: robot.counters().link.open, what="the bus reopened")
        wait_until(lambda: "vsc_link_lost" in robot.active_stops(), what="the silent bus")
        robot.vsc.bus_off(False)
        wait_until(lambda: not robot.active_stops(), what="heartbeats again")
        time.sleep(0.4)
        assert robot.status().report.state is State.STOPPED
        robot.recover(stop)


def test_can_crc_errors_on_every_frame_are_a_transport_fault(tmp_path: Path) -> None:
    """SR-2.3 ``transport_fault``, SR-2.12: every frame of the VSC is hit
    on the wire, so the receiving controller signals an error frame for each, far above 16 a second:
    a sustained error rate is a ``transport_fault``."""
    with Robot(tmp_path, transport="can") as robot:
        robot.arm()
        t0 = robot.now()
        robot.vsc.fault(corrupt=1.0)
        stop = robot.expect_stop("transport_fault", t0, 1.0)
        robot.vsc.fault()
        robot.recover(stop)


def test_isolated_can_error_frames_are_counted_and_stop_nothing(tmp_path: Path) -> None:
    """SR-2.12, docs/safety.md "CAN error frames": one joystick frame in fifty hit on the
    wire (a few error frames a second, below the limit) is retransmitted by CAN in practice;
    the robot keeps running."""
    with Robot(tmp_path, transport="can") as robot:
        robot.arm()
        robot.vsc.fault(corrupt=0.02, only_types=[JOYSTICK])
        robot.stays_running(2.0)
        robot.vsc.fault()


def test_can_noise_keeps_running_and_still_carries_the_estop(tmp_path: Path) -> None:
    """SR-2: frames of unknown identifiers, random frames and every frame twice on the bus;
    the robot keeps running, and the remote's e-stop gets through at once (``vsc_estop``)."""
    with Robot(tmp_path, transport="can") as robot:
        robot.arm()
        robot.vsc.fault(duplicate=1.0, unknown_type=0.5, garbage=0.3)
        robot.stays_running(1.0)
        assert robot.counters().rejections.get("unknown_id", 0) > 0
        stop = robot.remote_estop()
        robot.vsc.release()
        robot.vsc.fault()
        robot.recover(stop)


def test_can_vsc_reboot_is_silence_then_searching(tmp_path: Path) -> None:
    """SR-2: the VSC reboots; on CAN the bus stays and the VSC is silent for its bootloader's
    second (``vsc_link_lost`` within 300 ms), then reports Searching with the remote-link
    e-stop bit (``vsc_estop``) until the remote links."""
    with Robot(tmp_path, transport="can", boot_delay=1.0) as robot:
        robot.arm()
        t0 = robot.now()
        robot.vsc.reboot()
        stop = robot.expect_stop("vsc_link_lost", t0, robot.vsc_timeout_s)
        wait_until(lambda: robot.record_raising("vsc_estop", t0), what="Searching")
        robot.recover(stop)


def test_can_vsc_unplugged_and_back(tmp_path: Path) -> None:
    """SR-2, SR-4: the VSC leaves the bus (its connector pulled) and comes back. On CAN the
    bus itself stays up, so the daemon sees silence: off within 300 ms; the VSC's return,
    still in Operational, is no takeover."""
    with Robot(tmp_path, transport="can") as robot:
        robot.arm()
        t0 = robot.now()
        robot.vsc.unplug()
        stop = robot.expect_stop("vsc_link_lost", t0, robot.vsc_timeout_s)
        time.sleep(0.3)
        robot.vsc.replug()
        wait_until(lambda: not robot.active_stops(), what="heartbeats again")
        assert robot.vsc.state()["mode_name"] == "operational"
        time.sleep(0.4)
        assert robot.status().report.state is State.STOPPED
        robot.recover(stop)
