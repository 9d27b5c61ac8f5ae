"""The daemon's own exit is a stop, and a record (SR-7.14; docs/record.md "The exit's
record"): the real ``srcsd`` against the simulator, in RUN with every output on, ended by a
signal. Every output is off, and the last record in the file names the signal, with the next
sequence number."""

from __future__ import annotations

import re
import signal
import time
from pathlib import Path

from supervisord.daemon import signals
from supervisord.record.stop import RecordKind, StopRecord
from supervisord.testkit.robot import Robot
from supervisord.testkit.wait import WAIT_S, wait_until
from supervisord.vocabulary import Cause, CauseKind, ChangeKind, State
from tests.faults.test_record_faults import (
    ROOT_ONLY,
    Journald,
    RecordRobot,
    _disk,
    _frozen,
    _record_image,
    _running,
    unit_stop_timeout_s,
)

# SIGTERM is systemd's stop (``systemctl stop``, KillSignal's default), SIGINT a terminal's
# Ctrl-C, SIGHUP one of the others that stop as SIGTERM does (SR-6.6).
SIGNALS = (signal.SIGTERM, signal.SIGHUP, signal.SIGINT)


def _end(robot: Robot, sig: signal.Signals) -> tuple[int, list[StopRecord]]:
    """Send ``sig``, wait for the exit; the exit status and the records before it."""
    daemon = robot.daemon
    assert daemon is not None
    before = robot.records()
    daemon.send_signal(sig)
    return daemon.wait(unit_stop_timeout_s() + WAIT_S), before


def _the_exit_record(
    robot: Robot, sig: signal.Signals, before: list[StopRecord], state: State
) -> None:
    """The file's last record is the exit's: ``shutdown:SIG``, from ``state`` to STOPPED,
    triggered by the ``shutdown`` input, one after the record before it."""
    records = robot.records()
    what = f"{sig.name}: {records[-3:]} {robot.log()}"
    last = records[-1]
    cause = Cause(CauseKind.SHUTDOWN, sig.name)
    assert [c.change for c in last.changes or () if c.name == cause] == [ChangeKind.RAISED], what
    assert {c.name for c in last.causes if c.latched} >= {cause}, what
    assert last.trigger == {"event": "shutdown", "reason": sig.name}, what
    assert (last.from_state, last.to_state) == (state, State.STOPPED), what
    assert records[: len(before)] == before, what
    assert last.seq == records[-2].seq + 1, what  # the sequence continues
    exits = [r for r in records[len(before) :] if r.event == "shutdown"]
    assert exits == [last], what


def test_each_shutdown_in_run_is_the_last_record(tmp_path: Path) -> None:
    """SR-7.14, SR-6.6: SIGTERM, SIGHUP and SIGINT to srcsd in RUN with every output on:
    every output is off, the exit status is the signal's, and the last record in the file is
    the stop RUN -> STOPPED naming ``shutdown:SIGNAL``, with the next sequence number."""
    with Robot(tmp_path) as robot:
        for sig in SIGNALS:
            if robot.daemon is None or robot.daemon.poll() is not None:
                robot.start_daemon()
            robot.arm()
            assert all(robot.output_file(name) for name in robot.output_paths)
            code, before = _end(robot, sig)
            assert code == signals.exit_status(sig), f"{sig.name}: {robot.log()}"
            for name in robot.output_paths:
                assert robot.output_file(name) is False, f"{name} left on after {sig.name}"
            _the_exit_record(robot, sig, before, State.RUN)
            assert "Traceback" not in robot.log(), robot.log()
        robot.start_daemon()  # for the harness's own end: status, SIGTERM, exit 0


def test_a_shutdown_in_stopped_is_a_record_too(tmp_path: Path) -> None:
    """SR-7.14: every exit of the daemon is recorded: SIGTERM while STOPPED (just started,
    never armed) leaves a ``cause_raised`` record of ``shutdown:SIGTERM`` last in the file."""
    with Robot(tmp_path) as robot:
        robot.wait_state(State.STOPPED)
        code, before = _end(robot, signal.SIGTERM)
        assert code == 0, robot.log()
        _the_exit_record(robot, signal.SIGTERM, before, State.STOPPED)
        assert robot.records()[-1].kind is RecordKind.CAUSE_RAISED
        robot.start_daemon()


@ROOT_ONLY
def test_the_shutdown_record_reaches_the_journal(tmp_path: Path) -> None:
    """SR-7.14: with ``journal = true``, the exit's stop in RUN is also a journal entry
    before the process ends (the journal lane drains after the record, docs/record.md),
    with ``SRCS_CAUSE=shutdown:SIGTERM`` at priority 2 (a stop)."""
    sig = signal.SIGTERM
    journal = Journald(tmp_path / "journal")
    try:
        robot = RecordRobot(tmp_path / "robot", journal_dir=journal.path.parent)
        try:
            robot.start()
            robot.arm()
            wait_until(lambda: journal.entries, what="journal entries from srcsd")
            code, before = _end(robot, sig)
            assert code == 0, robot.log()
            _the_exit_record(robot, sig, before, State.RUN)
        finally:
            robot.close()
        cause = f"\nSRCS_CAUSE=shutdown:{sig.name}\n".encode()
        mine = [e for e in journal.entries if cause in e]
        assert mine, f"no journal entry names shutdown:{sig.name}"
        assert b"\nPRIORITY=2\n" in mine[-1]
        assert b"\nSRCS_TO=STOPPED\n" in mine[-1]
    finally:
        journal.close()


NOT_WRITTEN = re.compile(r"(\d+) stop record\(s\) not written: .*(shutdown:SIGTERM)")
"""The line the exit's deadline says when the disk took none of its last records (SR-7.14)."""


def _main_thread_ended(pid: int) -> bool:
    """The process's first thread has ended (its ``/proc`` state is Z while a thread of the
    process still sleeps in the kernel), or the whole process has."""
    try:
        stat = Path(f"/proc/{pid}/stat").read_text()
    except FileNotFoundError:
        return True
    return stat[stat.rindex(")") + 2] in "ZX"


@ROOT_ONLY
def test_a_record_disk_that_hangs_past_the_deadline_costs_the_exit_record_said(
    tmp_path: Path,
) -> None:
    """SR-7.14, SR-7.7: the record's file system (ext4 on a loop device) is frozen and SIGTERM
    comes in RUN. Every output goes off; the exit's own record ``shutdown:SIGTERM`` cannot be
    written, and at the record lane's deadline an error line on stderr says so, with the count
    of records lost; the daemon's own part of the exit is done within the unit's
    ``TimeoutStopSec`` (its main thread has ended: what holds the process then is its write
    asleep in the kernel until the disk answers, docs/record.md). Thawed, it exits 0."""
    image = _record_image(tmp_path)
    robot = RecordRobot(tmp_path / "robot")
    with _disk(image, robot.record_dir), _running(robot):
        robot.arm()
        daemon = robot.daemon
        assert daemon is not None
        limit = unit_stop_timeout_s()
        with _frozen(robot.record_dir):
            sent = robot.sigterm()
            wait_until(
                lambda: all(robot.output_file(name) is False for name in robot.output_paths),
                what="every output off after SIGTERM",
            )

            def said() -> re.Match[str] | None:
                return NOT_WRITTEN.search(robot.log())

            wait_until(
                lambda: said() is not None and _main_thread_ended(daemon.pid),
                limit,
                what=f"the lost exit record said and the main thread ended: {robot.log()}",
            )
            took = time.monotonic() - sent
            line = said()
            assert line is not None
            assert int(line.group(1)) >= 1, line.group(0)
            print(f"SIGTERM to the line and the main thread's end: {took:.2f} s")
        code = daemon.wait(WAIT_S)  # the disk answers: the kernel lets the process go
        assert code == 0, robot.log()
        assert "Traceback" not in robot.log(), robot.log()
