"""The daemon's own exit is a stop, and a record (SR-7.14; docs/record.md "The exit's
record"): the real ``srcsd`` against the simulator, in RUN with every output on, ended by a
signal. Every output is off, and the last record in the file names the signal, with the next
sequence number."""

from __future__ import annotations

import signal
from pathlib import Path
from typing import Any

from supervisord.daemon import signals
from supervisord.testkit.robot import Robot
from supervisord.testkit.wait import WAIT_S, wait_until
from tests.faults.test_record_faults import ROOT_ONLY, Journald, RecordRobot, unit_stop_timeout_s

# SIGTERM is systemd's stop (``systemctl stop``, KillSignal's default), SIGINT a terminal's
# Ctrl-C, SIGHUP one of the others that stop as SIGTERM does (SR-6.6).
SIGNALS = (signal.SIGTERM, signal.SIGHUP, signal.SIGINT)


def _end(robot: Robot, sig: signal.Signals) -> tuple[int, list[dict[str, Any]]]:
    """Send ``sig``, wait for the exit; the exit status and the records before it."""
    daemon = robot.daemon
    assert daemon is not None
    before = robot.records()
    daemon.send_signal(sig)
    return daemon.wait(unit_stop_timeout_s() + WAIT_S), before


def _the_exit_record(
    robot: Robot, sig: signal.Signals, before: list[dict[str, Any]], state: str
) -> None:
    """The file's last record is the exit's: ``shutdown:SIG``, from ``state`` to STOPPED,
    triggered by the ``shutdown`` input, one after the record before it."""
    records = robot.records()
    what = f"{sig.name}: {records[-3:]} {robot.log()}"
    last = records[-1]
    cause = f"shutdown:{sig.name}"
    assert [c["change"] for c in last["changes"] if c["name"] == cause] == ["raised"], what
    assert {c["name"] for c in last["causes"] if c["latched"]} >= {cause}, what
    assert last["trigger"] == {"event": "shutdown", "reason": sig.name}, what
    assert (last["from"], last["to"]) == (state, "STOPPED"), what
    assert records[: len(before)] == before, what
    assert last["seq"] == records[-2]["seq"] + 1, what  # the sequence continues
    exits = [r for r in records[len(before) :] if r["trigger"].get("event") == "shutdown"]
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
            _the_exit_record(robot, sig, before, "RUN")
            assert "Traceback" not in robot.log(), robot.log()
        robot.start_daemon()  # for the harness's own end: status, SIGTERM, exit 0


def test_a_shutdown_in_stopped_is_a_record_too(tmp_path: Path) -> None:
    """SR-7.14: every exit of the daemon is recorded: SIGTERM while STOPPED (just started,
    never armed) leaves a ``cause_raised`` record of ``shutdown:SIGTERM`` last in the file."""
    with Robot(tmp_path) as robot:
        robot.wait_state("STOPPED")
        code, before = _end(robot, signal.SIGTERM)
        assert code == 0, robot.log()
        _the_exit_record(robot, signal.SIGTERM, before, "STOPPED")
        assert robot.records()[-1]["kind"] == "cause_raised"
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
            _the_exit_record(robot, sig, before, "RUN")
        finally:
            robot.close()
        cause = f"\nSRCS_CAUSE=shutdown:{sig.name}\n".encode()
        mine = [e for e in journal.entries if cause in e]
        assert mine, f"no journal entry names shutdown:{sig.name}"
        assert b"\nPRIORITY=2\n" in mine[-1]
        assert b"\nSRCS_TO=STOPPED\n" in mine[-1]
    finally:
        journal.close()
