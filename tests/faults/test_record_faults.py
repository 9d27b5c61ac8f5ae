"""Faults around the stop record with the real ``srcsd`` (``docs/record.md`` "How a record
leaves the loop", "What the record file is"; ``docs/faults.md``): a stderr nobody reads, a
journald that stopped reading, a disk that does not answer for a while, the record file
removed or replaced by a cleanup job, a FIFO at the record's path.

Each promise is "every acknowledged stop is in the file": a stop's record reaches the file
whatever the journal or stderr do, and SIGTERM ends the daemon within the unit's stop timeout
with the stop records on disk."""

from __future__ import annotations

import configparser
import contextlib
import os
import shutil
import signal
import socket
import subprocess
import sys
import threading
import time
from collections.abc import Iterator
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import pytest

from supervisord.api.framing import ApiError
from supervisord.client import ClientError, SupervisorClient
from supervisord.testkit.daemon import MINIMAL_CONFIG
from supervisord.testkit.namespaces import in_private_mount
from supervisord.testkit.robot import Robot, Stop
from supervisord.testkit.wait import WAIT_S, wait_until
from supervisord.vocabulary import CauseKind, State

ROOT = Path(__file__).resolve().parents[2]
ROOT_ONLY = pytest.mark.skipif(os.geteuid() != 0, reason="a private mount namespace needs root")


def unit_stop_timeout_s() -> float:
    """``TimeoutStopSec=`` of units/srcsd@.service: after it systemd kills the daemon, and
    whatever it had not written is lost. Every SIGTERM below must end well inside it."""
    unit = configparser.ConfigParser(strict=False, interpolation=None)
    unit.read(ROOT / "units" / "srcsd@.service")
    return float(unit["Service"]["TimeoutStopSec"])


@dataclass
class RecordRobot(Robot):
    """A :class:`Robot` whose daemon runs with its stderr on ``stderr_to`` (a FIFO of the
    test's) and, when ``journal_dir`` is given, with ``journal = true`` and that directory at
    /run/systemd/journal in a private mount namespace (the test's socket as journald's)."""

    stderr_to: Path | None = None
    journal_dir: Path | None = None

    def config_text(self) -> str:
        text = super().config_text()
        return text.replace("journal = false", "journal = true") if self.journal_dir else text

    def daemon_command(self) -> list[str]:
        command = super().daemon_command()
        if self.journal_dir is not None:
            mount = (
                "mount -t tmpfs srcs-run /run && mkdir -p /run/systemd/journal && "
                'mount --bind "$0" /run/systemd/journal'
            )
            command = in_private_mount(mount, self.journal_dir, command)
        if self.stderr_to is not None:
            command = ["sh", "-c", 'exec "$@" 2>"$0"', str(self.stderr_to), *command]
        return command

    def sigterm(self) -> float:
        """SIGTERM; the monotonic time it was sent."""
        assert self.daemon is not None
        sent = time.monotonic()
        self.daemon.send_signal(signal.SIGTERM)
        return sent

    def exit_within_stop_timeout(self, sent: float) -> float:
        """Wait for the exit; assert a clean one (status 0) within the unit's stop timeout
        of ``sent``. The seconds it took."""
        assert self.daemon is not None
        limit = unit_stop_timeout_s()
        try:
            code = self.daemon.wait(limit + WAIT_S)
        except subprocess.TimeoutExpired:
            code = None
        took = time.monotonic() - sent
        said = f"srcsd {'still ran' if code is None else f'exited {code}'} {took:.1f} s after "
        said += f"SIGTERM; systemd kills it at {limit:g} s and its queue is lost"
        assert code == 0, said
        assert took < limit, said
        print(f"SIGTERM to exit: {took:.2f} s (the unit allows {limit:g} s)")
        return took


@contextlib.contextmanager
def _running(robot: RecordRobot) -> Iterator[RecordRobot]:
    """The robot started, and closed on leaving (without ``Robot.finish``: these tests end
    the daemon themselves)."""
    try:
        robot.start()
        yield robot
    finally:
        robot.close()


def _stop_in_file(robot: Robot, stop: Stop) -> None:
    records = robot.records()
    assert stop.record in records, f"the stop record seq {stop.record.seq} is not in the file"


def _refused_requests(robot: Robot, count: int) -> None:
    """``count`` refused re-arms (``reset`` with ``local_reset`` off): a log line each."""
    with robot.client() as api:
        for _ in range(count):
            with contextlib.suppress(ApiError):
                api.reset()


# ----------------------------------------------------------------------------- stderr


def _fill(fd: int) -> int:
    """Write to the non-blocking ``fd`` until the pipe or socket behind it is full."""
    filled = 0
    with contextlib.suppress(BlockingIOError):
        while True:
            filled += os.write(fd, b"x" * 4096)
    return filled


def test_a_stuck_stderr_costs_log_lines_never_a_stop_record(tmp_path: Path) -> None:
    """SR-7.5, SR-7.7: srcsd's stderr (the journal's stream) is a pipe nobody reads any more,
    full. Refused requests make log lines that cannot be written; then a remote e-stop: every
    output off at once, and its record in the file (log lines have a lane of their own; they
    are counted as dropped once their queue is full, never ahead of a record). SIGTERM: the
    daemon exits 0 within the unit's ``TimeoutStopSec`` (the margin is the rule's own: after
    it systemd kills), with the stop record on disk."""
    fifo = tmp_path / "stderr"
    os.mkfifo(fifo)
    held = os.open(fifo, os.O_RDWR | os.O_NONBLOCK)  # the reader that stops reading
    try:
        with _running(RecordRobot(tmp_path / "robot", stderr_to=fifo)) as robot:
            robot.arm()
            assert _fill(held) > 0
            _refused_requests(robot, 400)
            stop = robot.remote_estop()
            _stop_in_file(robot, stop)
            sent = robot.sigterm()
            robot.exit_within_stop_timeout(sent)
            _stop_in_file(robot, stop)
    finally:
        os.close(held)


# ----------------------------------------------------------------------------- journald


class Journald:
    """A datagram socket where journald's would be, read by a thread that keeps every entry
    until :meth:`stop`, then left full: a journald that stopped reading."""

    def __init__(self, folder: Path) -> None:
        folder.mkdir()
        self.path = folder / "socket"
        self.socket = socket.socket(socket.AF_UNIX, socket.SOCK_DGRAM)
        self.socket.bind(str(self.path))
        self.socket.settimeout(0.1)
        self.entries: list[bytes] = []
        self._reading = True
        self._thread = threading.Thread(target=self._read, daemon=True)
        self._thread.start()

    def _read(self) -> None:
        while self._reading:
            with contextlib.suppress(TimeoutError):
                self.entries.append(self.socket.recv(1 << 20))

    def stop(self) -> None:
        """Stop reading, and fill its queue so that every send waits (up to 2 s)."""
        self._reading = False
        self._thread.join()
        with socket.socket(socket.AF_UNIX, socket.SOCK_DGRAM) as filler:
            filler.setblocking(False)
            with contextlib.suppress(BlockingIOError):
                while True:
                    filler.sendto(b"MESSAGE=filler\n", str(self.path))

    def close(self) -> None:
        self._reading = False
        self._thread.join()
        self.socket.close()


@ROOT_ONLY
def test_a_stuck_journald_never_holds_a_stop_record(tmp_path: Path) -> None:
    """SR-7.5, SR-7.7: ``journal = true`` and journald's socket stops being read (its queue
    full, so each entry waits for the 2 s send timeout). Holds and releases queue records,
    then a remote e-stop: its record is in the file at once (the journal copies have a lane
    of their own and cost only themselves: ``journal_errors`` counts them). SIGTERM ends the
    daemon within the unit's ``TimeoutStopSec`` with the stop record on disk."""
    journald = Journald(tmp_path / "journal")
    try:
        robot = RecordRobot(tmp_path / "robot", journal_dir=journald.path.parent)
        with _running(robot):
            robot.arm()
            wait_until(lambda: bool(journald.entries), what="journal entries from srcsd")
            journald.stop()
            with robot.client() as api:
                for _ in range(5):
                    api.hold()
                    api.release("hold")
            stop = robot.remote_estop()
            _stop_in_file(robot, stop)
            wait_until(lambda: robot.counters().sink["journal_errors"] > 0, what="a refused entry")
            sent = robot.sigterm()
            robot.exit_within_stop_timeout(sent)
            _stop_in_file(robot, stop)
    finally:
        journald.close()


# ----------------------------------------------------------------------------- slow disk


def _record_image(tmp_path: Path) -> Path:
    mkfs = shutil.which("mkfs.ext4")
    if mkfs is None or shutil.which("fsfreeze") is None:
        pytest.skip("needs mkfs.ext4 and fsfreeze")
    image = tmp_path / "record.img"
    with image.open("wb") as file:
        file.truncate(16 << 20)
    subprocess.run([mkfs, "-q", str(image)], check=True, timeout=60)
    return image


@contextlib.contextmanager
def _disk(image: Path, folder: Path) -> Iterator[None]:
    """``image`` mounted at ``folder`` (a loop device), unmounted on leaving."""
    subprocess.run(["mount", "-o", "loop", str(image), str(folder)], check=True, timeout=30)
    try:
        yield
    finally:
        subprocess.run(["umount", "-l", str(folder)], check=False, timeout=30)


@contextlib.contextmanager
def _frozen(folder: Path) -> Iterator[None]:
    """The file system of ``folder`` frozen (FIFREEZE): every write to it waits until it
    thaws, as a disk that does not answer. Thawed on leaving, whatever happens."""
    subprocess.run(["fsfreeze", "-f", str(folder)], check=True, timeout=30)
    try:
        yield
    finally:
        subprocess.run(["fsfreeze", "-u", str(folder)], check=False, timeout=30)


def _pushed_records(watch: SupervisorClient, into: list[dict[str, Any]]) -> None:
    """The record pushes ``watch`` has received so far, into ``into`` (until the daemon's
    socket has no more, or is closed)."""
    with contextlib.suppress(ClientError, OSError):
        while (push := watch.next_event(timeout=0.2)) is not None:
            if push.event == "record":
                into.append({k: v for k, v in push.json().items() if k != "event"})


@ROOT_ONLY
def test_a_slow_disk_delays_records_never_the_stop_and_loses_none(tmp_path: Path) -> None:
    """SR-7.4, SR-7.5, SR-7.7: the record's file system (ext4 on a loop device) stops
    answering (frozen). A remote e-stop still turns every output off at once and ``status``
    answers, with the stop record pending; it is not pushed to subscribers (a pushed record
    is an acknowledged one). SIGTERM while the disk still hangs, and the disk answers again
    a second later (inside the sink's 4 s for the records): the daemon writes the queued
    records first and exits 0 within the unit's ``TimeoutStopSec``; every record ever pushed,
    and the stop record, is in the file."""
    image = _record_image(tmp_path)
    robot = RecordRobot(tmp_path / "robot")
    pushed: list[dict[str, Any]] = []
    with _disk(image, robot.record_dir), _running(robot):
        robot.arm()
        with robot.client() as watch:
            watch.subscribe("records")
            with _frozen(robot.record_dir):
                t = robot.now()
                robot.vsc.estop()
                robot.expect_off(t, robot.beat_s)
                status = robot.status()
                assert status.report.state is State.STOPPED, status
                assert status.daemon.loop.sink["records_pending"] >= 1, status
                _pushed_records(watch, pushed)
                early = [r for r in pushed if r["mono_ns"] >= t * 1e9]
                assert not early, f"pushed before the disk took them: {early}"
                sent = robot.sigterm()
                time.sleep(1.0)  # the disk hangs a while longer
            robot.exit_within_stop_timeout(sent)
            _pushed_records(watch, pushed)
        records = robot.record_lines()  # the pushes are the file's lines, as written
        assert robot.record_raising(CauseKind.VSC_ESTOP, t), (records[-3:], robot.log())
        in_file = {r["seq"]: r for r in records}
        missing = [r for r in pushed if in_file.get(r["seq"]) != r]
        assert not missing, (missing, records[-3:])


# ----------------------------------------------------------------------------- the file itself


@pytest.mark.parametrize("how", ["removed", "replaced"], ids=["removed", "replaced"])
def test_a_record_file_removed_or_replaced_is_opened_again(tmp_path: Path, how: str) -> None:
    """SR-7.9: a cleanup job removes the record file, or a log rotation renames it and
    creates an empty one, while the robot runs. The next stop's record is in the file at the
    record's path, where ``srcsctl log`` reads (not in the orphaned or renamed file); the
    reopening is counted in ``status`` (``record_reopens``) and logged at error priority."""
    with Robot(tmp_path) as robot:
        robot.arm()
        path = robot.record_path
        if how == "removed":
            path.unlink()
        else:
            path.rename(path.with_name("stops.jsonl.old"))
            path.write_text("")
        stop = robot.remote_estop()
        assert stop.record.seq > 1
        assert robot.counters().sink["record_reopens"] == 1
        said = f"record file {path} was {how}"
        wait_until(lambda: said in robot.log(), what="the reopening logged")


def _srcsd(folder: Path, *args: str) -> subprocess.CompletedProcess[str]:
    """``srcsd ARGS`` in ``folder``, waiting the fault suite's WAIT_S three times at most: a
    hang, not a slow start, is what fails."""
    try:
        return subprocess.run(
            [sys.executable, "-m", "supervisord.cli.srcsd", *args],
            cwd=folder,
            env={**os.environ, "PYTHONPATH": str(ROOT)},
            capture_output=True,
            text=True,
            timeout=WAIT_S * 3,
            check=False,
        )
    except subprocess.TimeoutExpired as hung:
        raise AssertionError(f"srcsd {' '.join(args)} hung: {hung}") from None


def _fifo_as_record(folder: Path) -> None:
    (folder / "robot.toml").write_text(MINIMAL_CONFIG)
    os.mkfifo(folder / "stops.jsonl")


def test_check_config_refuses_a_fifo_as_the_record(tmp_path: Path) -> None:
    """SR-7.9, SR-11.2: a FIFO where the record file should be: ``srcsd --check-config``
    refuses the configuration, naming ``record.path`` and what is there."""
    _fifo_as_record(tmp_path)
    checked = _srcsd(tmp_path, "--check-config", "robot.toml")
    assert checked.returncode != 0, checked.stdout
    assert "record.path" in checked.stderr, checked.stderr
    assert "FIFO" in checked.stderr, checked.stderr


def test_srcsd_refuses_a_fifo_as_the_record_instead_of_hanging(tmp_path: Path) -> None:
    """SR-7.9, SR-11.2: with a FIFO where the record file should be, ``srcsd`` exits with the
    configuration error status (78, which systemd does not restart) and says why, instead of
    hanging at start with its socket bound (its last record was read from the FIFO: a read
    that never returns)."""
    _fifo_as_record(tmp_path)
    started = _srcsd(tmp_path, "--config", "robot.toml")
    assert started.returncode == 78, started.stderr
    assert "FIFO" in started.stderr, started.stderr
    assert not (tmp_path / "api.sock").exists()
