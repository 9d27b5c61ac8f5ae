"""Faults of the robot's own programs (clients of the API socket), made by the harness: a
required client killed, stopped, hung with unread replies; a program flooding the socket or
taking every connection; a client's e-stop outliving the client (``docs/faults.md``)."""

from __future__ import annotations

import signal
import socket
import time
from pathlib import Path

from supervisord.client import SupervisorClient
from supervisord.testkit.robot import Robot
from supervisord.testkit.wait import wait_until
from supervisord.vocabulary import CauseKind, State

CLIENT_TIMEOUT_S = 0.5  # the required client's heartbeat deadline (SR-8 default)
MAX_CLIENTS = 16  # api.max_clients default (docs/configuration.md)


def test_required_client_killed_is_lost_at_once(tmp_path: Path) -> None:
    """SR-2.4 ``client_lost:NAME``, SR-4.4 "a client's reconnection is a new start": the required
    client ``nav`` is killed (SIGKILL). Its connection ends with it: off at once. Restarted,
    it says hello and beats again; the stop stays latched until a takeover."""
    with Robot(tmp_path, clients=("nav",)) as robot:
        robot.arm()
        t0 = robot.now()
        robot.client_processes["nav"].kill()
        stop = robot.expect_stop("client_lost:nav", t0, 0.0)
        robot.start_clients()
        wait_until(lambda: not robot.active_stops(), what="nav back")
        time.sleep(0.3)
        assert robot.status().report.state is State.STOPPED
        robot.recover(stop)


def test_required_client_stopped_is_lost_after_its_timeout(tmp_path: Path) -> None:
    """SR-2, SR-8: the required client is stopped (SIGSTOP): its connection stays open but it is
    silent. Off within its 500 ms timeout. When it runs again (SIGCONT) its heartbeats clear
    the condition, and the stop stays latched until a takeover."""
    with Robot(tmp_path, clients=("nav",)) as robot:
        robot.arm()
        nav = robot.client_processes["nav"]
        t0 = robot.now()
        nav.signal(signal.SIGSTOP)
        try:
            stop = robot.expect_stop("client_lost:nav", t0, CLIENT_TIMEOUT_S)
        finally:
            nav.signal(signal.SIGCONT)
        wait_until(lambda: not robot.active_stops(), what="nav beating again")
        time.sleep(0.3)
        assert robot.status().report.state is State.STOPPED
        robot.recover(stop)


def test_required_client_whose_progress_stops_is_lost_after_its_timeout(tmp_path: Path) -> None:
    """SR-8.16: the required client ``nav`` (``progress = true``) freezes its progress value
    while its heartbeats go on, as a control loop stuck while the heartbeat's thread runs.
    Its heartbeats are refused (``stale_progress``) and keep nothing alive: off within its
    500 ms timeout, ``client_lost:nav`` with the reason ``stale progress``. Restarted, it
    beats with progress again and a takeover runs the robot."""
    with Robot(tmp_path, clients=("nav",), progress_clients=("nav",)) as robot:
        robot.arm()
        nav = robot.client_processes["nav"]
        t0 = robot.now()
        nav.signal(signal.SIGUSR2)
        stop = robot.expect_stop("client_lost:nav", t0, CLIENT_TIMEOUT_S)
        lost = stop.record.cause(CauseKind.CLIENT_LOST)
        assert lost is not None, stop.record
        assert str(lost.name) == "client_lost:nav", stop.record
        assert lost.details["reason"] == "stale progress", stop.record
        nav.wait_log("refused: stale_progress")
        assert "client_lost:nav" in robot.active_stops()  # its beats go on, and count for nothing
        nav.kill()
        robot.start_clients()
        robot.recover(stop)


def test_required_client_that_stops_reading_is_dropped_and_lost(tmp_path: Path) -> None:
    """SR-8 "the supervisor never waits for a client": the required client pipelines 4096
    requests, never reads a reply and hangs (SIGSTOP). The daemon does not block on it: it
    drops the connection when its replies fill the buffer, which is ``client_lost:nav``,
    within the client's timeout at the latest; the loop carries on serving."""
    with Robot(tmp_path, clients=("nav",)) as robot:
        robot.arm()
        nav = robot.client_processes["nav"]
        t0 = robot.now()
        nav.signal(signal.SIGUSR1)
        stop = robot.expect_stop("client_lost:nav", t0, CLIENT_TIMEOUT_S)
        nav.wait_log("stalled")
        assert robot.status().report.state is State.STOPPED
        nav.kill()
        robot.start_clients()
        robot.recover(stop)


def test_flood_on_the_socket_neither_stops_nor_starves_the_robot(tmp_path: Path) -> None:
    """SR-8 limits, SR-2.6 ``local_estop``: a program writes one endless line into the socket. The
    daemon cuts it off (``flood``) and closes it; meanwhile the required client's heartbeats
    are served and the robot keeps running. Right after, the operator's e-stop over the same
    socket stops the robot at once."""
    with Robot(tmp_path, clients=("nav",)) as robot:
        robot.arm()
        flooder = robot.run_client("", mode="flood")
        t = robot.now()
        flooder.wait_log("closed after")
        robot.stays_running(max(0.0, 0.5 - (robot.now() - t)))
        assert '"code": "flood"' in flooder.log() or "flood" in flooder.log()
        assert not [r for r in robot.records_since(t) if r.to_state is not State.RUN]
        t0 = robot.now()
        with robot.client() as operator:
            operator.estop()
            stop = robot.expect_stop("local_estop", t0, 0.0)
            operator.release("estop")
        robot.recover(stop)


def test_client_estop_outlives_the_client(tmp_path: Path) -> None:
    """SR-2.5 ``client_estop:NAME``, SR-8: a client (not a required one) asks for an e-stop and
    its connection ends at once, as when it crashes. Off at once; the e-stop stays active
    after the disconnect, so no takeover helps (one seen by the daemon, the mode forced to
    Operational, is refused and recorded), until a client of the same name releases it."""
    with Robot(tmp_path, clients=("nav",)) as robot:
        robot.arm()
        t0 = robot.now()
        with SupervisorClient.connect(robot.socket_path, name="arm") as arm:
            arm.estop()
        stop = robot.expect_stop("client_estop:arm", t0, 0.0)
        time.sleep(0.3)
        assert "client_estop:arm" in robot.active_stops()
        assert "client_estop:arm" in (robot.refused_takeover().reason or "")
        with SupervisorClient.connect(robot.socket_path, name="arm") as arm:
            arm.release("estop")
        robot.recover(stop)


def test_connections_exhausted_keep_a_dropped_client_out_and_the_robot_stopped(
    tmp_path: Path,
) -> None:
    """SR-8 limits, SR-2.4 ``client_lost:NAME``: a program takes every free connection of the
    socket. The robot keeps running (the required client is connected); the next connection
    is refused (``too_many_clients``). Then the required client dies: off at once, and while
    the slots stay taken it cannot come back, so the robot stays STOPPED. Once the program
    lets go, the client reconnects and a takeover runs the robot."""
    with Robot(tmp_path, clients=("nav",)) as robot:
        robot.arm()
        hogs: list[socket.socket] = []
        try:
            for _ in range(MAX_CLIENTS - 1):
                hog = socket.socket(socket.AF_UNIX, socket.SOCK_STREAM)
                hogs.append(hog)
                hog.connect(str(robot.socket_path))
            time.sleep(0.2)
            with socket.socket(socket.AF_UNIX, socket.SOCK_STREAM) as extra:
                extra.settimeout(5.0)
                extra.connect(str(robot.socket_path))
                assert b"too_many_clients" in extra.recv(4096)
            assert robot.watcher is not None
            assert robot.watcher.level("drive") is True
            t0 = robot.now()
            robot.client_processes["nav"].kill()
            assert robot.watcher is not None
            robot.watcher.wait("drive", False, t0)
            hog = socket.socket(socket.AF_UNIX, socket.SOCK_STREAM)
            hogs.append(hog)
            hog.connect(str(robot.socket_path))
            time.sleep(0.2)
            robot.start_clients()
            robot.client_processes["nav"].wait_log("closed")
            time.sleep(0.5)
            assert robot.watcher.ons_between(t0, robot.now()) == []
        finally:
            for hog in hogs:
                hog.close()
        stop = robot.expect_stop("client_lost:nav", t0, 0.0)
        robot.recover(stop)
