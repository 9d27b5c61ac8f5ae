"""Faults of the VSC as a device and of the daemon as a process: unplug and replug, a VSC
reboot with its bootloader delay, a VSC whose watchdog is off, the daemon hung or killed.
Real ``srcsd`` against ``srcs-sim`` on a real pty (``docs/faults.md``)."""

from __future__ import annotations

import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest

from supervisord.record.stop import StopRecord
from supervisord.testkit.robot import ALLOWANCE_S, Robot, Stop
from supervisord.testkit.wait import wait_until
from supervisord.vocabulary import Cause, CauseKind, State

WATCHDOG_S = 0.5  # the VSC's key-85 watchdog trips after 500 ms without our heartbeat (SR-5)


@pytest.mark.parametrize("unplugged_s", [0.0, 0.5], ids=["glitch", "half_a_second"])
def test_unplug_is_a_transport_fault_and_replug_is_a_new_start(
    tmp_path: Path, unplugged_s: float
) -> None:
    """SR-2.3 ``transport_fault``, SR-4.4 "a reconnect of the VSC is a new start": the USB cable is
    pulled (for an instant, or for half a second) while the remote is in Operational. Off at
    once; after the replug the first heartbeats still say Operational, which is no takeover,
    so the robot stays STOPPED until the operator takes over again. Key 85 is read again
    (SR-5)."""
    with Robot(tmp_path) as robot:
        robot.arm()
        opens = robot.counters().link.opens
        t0 = robot.now()
        robot.vsc.unplug()
        time.sleep(unplugged_s)
        robot.vsc.replug()
        stop = robot.expect_stop("transport_fault", t0, 0.0)
        wait_until(lambda: robot.counters().link.opens > opens, what="the reopen")
        wait_until(lambda: not robot.active_stops(), what="the link back")
        time.sleep(0.5)
        assert robot.status().report.state is State.STOPPED
        assert not [r for r in robot.records_since(t0) if r.rearm]
        wait_until(lambda: robot.record_raising("vsc_watchdog_off", t0), what="key 85 read again")
        robot.recover(stop)


def test_vsc_reboot_over_usb_with_its_bootloader_delay(tmp_path: Path) -> None:
    """SR-2, SR-4, SR-5: the VSC reboots; over USB it leaves the bus while its bootloader runs
    (1 s here, one or two minutes on the real device), then comes back Searching with the
    remote-link e-stop bit. Off at once (``transport_fault``); the new VSC's e-stop word and
    its key 85 are checked again; a takeover after the remote links runs the robot."""
    with Robot(tmp_path, boot_delay=1.0) as robot:
        robot.arm()
        t0 = robot.now()
        robot.vsc.reboot()
        stop = robot.expect_stop("transport_fault", t0, 0.0)
        robot.vsc.wait_for(lambda s: s["plugged"] and not s["booting"])
        wait_until(lambda: robot.record_raising("vsc_estop", t0), what="Searching")
        wait_until(lambda: robot.record_raising("vsc_watchdog_off", t0), what="key 85 read again")
        robot.recover(stop)


def test_vsc_reboot_on_rs232_is_a_silent_line(tmp_path: Path) -> None:
    """SR-2: on RS-232 the port stays while the VSC reboots; the line is silent for the
    bootloader's second (``vsc_link_lost`` within the timeout), then the VSC reports
    Searching with its remote-link e-stop bit (``vsc_estop``, source ``remote``)."""
    with Robot(tmp_path, boot_delay=1.0) as robot:
        robot.arm()
        t0 = robot.now()
        robot.vsc.reboot(unplug=False)
        stop = robot.expect_stop("vsc_link_lost", t0, robot.vsc_timeout_s)
        record: StopRecord = wait_until(lambda: robot.record_raising(CauseKind.VSC_ESTOP, t0))
        estop = record.cause(CauseKind.VSC_ESTOP)
        assert "remote" in str(estop), estop
        robot.recover(stop)


def test_replacement_vsc_without_its_watchdog_cannot_be_rearmed(tmp_path: Path) -> None:
    """SR-5: after a reconnect key 85 is read back; a VSC that comes back with it off (a
    replacement never commissioned) keeps the robot STOPPED with ``vsc_watchdog_off``, and
    our heartbeat's e-stop byte holds the VSC in e-stop too. A takeover seen by the daemon
    (the mode forced to Operational) is refused and recorded. Once key 85 reads 1 (re-read
    every second) the robot can be re-armed."""
    with Robot(tmp_path, boot_delay=0.5) as robot:
        robot.arm()
        t0 = robot.now()
        robot.vsc.key(85, 0)
        robot.vsc.reboot()
        stop = robot.expect_stop("transport_fault", t0, 0.0)
        robot.vsc.wait_for(lambda s: s["linked"])
        wait_until(lambda: "vsc_watchdog_off" in robot.active_stops(), what="key 85 read as 0")
        assert "user_request" in robot.vsc.state()["estop_bits"]
        assert "vsc_watchdog_off" in (robot.refused_takeover().reason or "")
        assert robot.watcher is not None
        assert robot.watcher.ons_between(t0, robot.now()) == []
        # The forced mode is a test lever that outlasts an e-stop; a remote action ends it, so
        # that the proof test's trip returns the VSC to Local as a real one does (manual §6.6).
        robot.vsc.pause()
        robot.vsc.key(85, 1)
        wait_until(lambda: not robot.active_stops(), what="key 85 read back as 1, then proven")
        robot.recover(stop)


def test_hung_daemon_lets_the_vsc_stop_and_wakes_as_an_internal_fault(tmp_path: Path) -> None:
    """SR-5.1 "if the loop hangs, the heartbeat must stop", SR-2.9 ``internal``: the daemon is
    stopped (SIGSTOP) in RUN. It can drive nothing now, so the VSC's own watchdog must open
    its relays: its e-stop word shows the user timeout within 500 ms. When the daemon runs
    again it finds its loop overran: off at once, cause ``internal``."""
    with Robot(tmp_path) as robot:
        robot.arm()
        assert robot.daemon is not None
        t0 = robot.now()
        robot.daemon.send_signal(signal.SIGSTOP)
        try:
            tripped = robot.vsc.wait_for(lambda s: "user_timeout" in s["estop_bits"], 5.0)
            took = robot.now() - t0
            assert took <= WATCHDOG_S + ALLOWANCE_S, (took, tripped["estop_bits"])
            time.sleep(0.5)
        finally:
            t1 = robot.now()
            robot.daemon.send_signal(signal.SIGCONT)
        stop = robot.expect_stop("internal", t1, 0.0)
        assert "late" in str(stop.record.trigger) or "late" in str(stop.record.causes)
        assert robot.counters().internal_faults == 0  # an overrun, not an exception
        robot.recover(stop)


def test_killed_daemon_restarts_stopped_and_needs_a_takeover(tmp_path: Path) -> None:
    """SR-4.4 "a restart of the supervisor is a new start", SR-5, SR-6: the daemon is killed
    (SIGKILL) in RUN. The VSC's watchdog opens its relays within 500 ms (a crash releases the lines;
    the simulated file cannot, see docs/faults.md). The restarted daemon sets every output off
    before its socket is up, stays STOPPED with ``startup`` while the remote is still Operational,
    and runs only after a new takeover."""
    with Robot(tmp_path) as robot:
        robot.arm()
        assert robot.daemon is not None
        t0 = robot.now()
        robot.daemon.kill()
        robot.daemon.wait()
        robot.vsc.wait_for(lambda s: "user_timeout" in s["estop_bits"], 5.0)
        assert robot.now() - t0 <= WATCHDOG_S + ALLOWANCE_S
        t1 = robot.now()
        robot.start_daemon()
        # Read at once, once the API answered: the killed daemon left the files at on (a file
        # is not released), so "off" now was written before the socket was up. The watcher's
        # times cannot tell the order: it notices a change on its own thread's time.
        levels = {name: robot.output_file(name) for name in robot.healthy_outputs()}
        t_up = robot.now()
        assert levels == dict.fromkeys(robot.healthy_outputs(), False), levels
        record: StopRecord = wait_until(lambda: robot.record_raising(CauseKind.STARTUP, t1))
        stop = Stop(Cause(CauseKind.STARTUP), t1, t_up, record)
        robot.vsc.wait_for(lambda s: s["estop"] == 0)
        robot.recover(stop)
        seqs = [r.seq for r in robot.records()]
        assert seqs == sorted(set(seqs)), "the record's sequence continues across the restart"


def test_local_estop_stops_and_reaches_the_vsc(tmp_path: Path) -> None:
    """SR-2.6 ``local_estop``, SR-5: the operator runs ``srcsctl estop`` on the vehicle computer.
    Off at once (before srcsctl has its answer); our heartbeat's e-stop byte is 1 while it
    is active, so the VSC's own relays open too (its word shows the user request);
    ``srcsctl release`` returns the byte to 0 so the operator can take over from the
    remote."""
    with Robot(tmp_path) as robot:
        robot.arm()
        t0 = robot.now()
        ctl = [sys.executable, "-m", "supervisord.cli.srcsctl"]
        done = subprocess.run(
            [*ctl, "estop", "--socket", str(robot.socket_path)],
            capture_output=True,
            text=True,
            timeout=30,
            check=False,
        )
        assert done.returncode == 0, done.stderr
        # Off at once: by the time srcsctl has its answer, whatever its own start-up took.
        stop = robot.expect_stop("local_estop", t0, robot.now() - t0)
        robot.vsc.wait_for(lambda s: "user_request" in s["estop_bits"], 2.0)
        done = subprocess.run(
            [*ctl, "release", "estop", "--socket", str(robot.socket_path)],
            capture_output=True,
            text=True,
            timeout=30,
            check=False,
        )
        assert done.returncode == 0, done.stderr
        robot.vsc.wait_for(lambda s: s["estop"] == 0, 2.0)
        robot.recover(stop)


def test_a_link_that_opened_again_shows_no_error_from_before(tmp_path: Path) -> None:
    """SR-8.18: ``status``'s link error is why the link is not open; once it opened again the
    error from before is gone (its count stays), and ``srcsctl status`` shows no ``last
    error`` (a team read an unplug's error, long fixed, as the fault of the day)."""
    from supervisord.cli.control import format_status  # noqa: PLC0415

    with Robot(tmp_path) as robot:
        opens = robot.counters().link.opens
        robot.vsc.unplug()
        wait_until(lambda: not robot.counters().link.open, what="the link broken")
        assert robot.counters().link.last_error
        robot.vsc.replug()
        wait_until(lambda: robot.counters().link.opens > opens, what="the reopen")
        wait_until(lambda: robot.counters().link.open, what="the link open")
        link = robot.counters().link
        assert link.last_error is None, link.last_error
        assert "last error" not in format_status(robot.status())
