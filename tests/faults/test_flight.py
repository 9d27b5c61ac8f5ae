"""The flight recorder with the real ``srcsd`` and ``srcs-sim`` (``docs/record.md`` "The flight
recorder", ``docs/faults.md``): a stop leaves its window beside the record and ``srcsctl
replay`` reproduces it; a tampered window is a mismatch; a disk under the windows that hangs or
is full costs windows, counted, never the outputs, a stop record or the exit."""

from __future__ import annotations

import json
import os
import subprocess
import sys
import time
from pathlib import Path

import pytest

from supervisord.record.flight import flight_dir, read_window, window_path
from supervisord.record.replay import replay
from supervisord.record.stop import StopRecord, read_record
from supervisord.testkit.robot import Robot
from supervisord.testkit.wait import wait_until
from tests.faults.test_record_faults import (
    ROOT,
    RecordRobot,
    _disk,
    _frozen,
    _record_image,
    _running,
)

ROOT_ONLY = pytest.mark.skipif(os.geteuid() != 0, reason="mounting a file system needs root")


def srcsctl(*args: str) -> subprocess.CompletedProcess[str]:
    """The real ``srcsctl``, as the operator runs it."""
    return subprocess.run(
        [sys.executable, "-m", "supervisord.cli.srcsctl", *args],
        capture_output=True,
        text=True,
        timeout=120,
        cwd=ROOT,
        env={**os.environ, "PYTHONPATH": str(ROOT)},
        check=False,
    )


def _window_of(robot: Robot, record: StopRecord) -> Path:
    path = window_path(robot.record_path, record.seq)
    wait_until(path.exists, what=f"the window of record {record.seq}")
    return path


def _stop_heartbeat_cleared(window: Path, into: Path) -> None:
    """A copy of ``window`` whose stopping heartbeat (the last input) says no e-stop."""
    lines = window.read_text().splitlines()
    last = json.loads(lines[-2])
    assert last["event"] == "vsc_received", last
    payload = bytes.fromhex(last["message"]["payload"])
    assert payload[2:] != bytes(4), last  # the e-stop word is set
    last["message"]["payload"] = (payload[:2] + bytes(4)).hex()
    lines[-2] = json.dumps(last)
    into.write_text("\n".join(lines) + "\n")


def _stop_word_and_copy_forged(window: Path, into: Path) -> None:
    """A copy of ``window`` whose stopping heartbeat says e-stop word 0x04 and whose copy of the
    stop record was edited to what a core makes of that."""
    lines = window.read_text().splitlines()
    last = json.loads(lines[-2])
    payload = bytes.fromhex(last["message"]["payload"])
    last["message"]["payload"] = (payload[:2] + (4).to_bytes(4, "little")).hex()
    lines[-2] = json.dumps(last)
    into.write_text("\n".join(lines) + "\n")
    made = replay(read_window(into), {}).steps[-1].records[0][0]
    header = json.loads(lines[0])
    header["stop"] = {**made, "utc": header["stop"]["utc"]}
    lines[0] = json.dumps(header)
    into.write_text("\n".join(lines) + "\n")


def test_a_stop_leaves_its_window_and_srcsctl_replay_reproduces_it(tmp_path: Path) -> None:
    """SR-7.10, SR-7.12, SR-7.13: a remote e-stop in RUN. Its window appears beside the record
    (``stops.jsonl.flight/SEQ.jsonl``), its last input the stopping heartbeat; ``srcsctl
    replay SEQ --config`` runs it through a fresh core and reproduces every record, the stop's
    included (exit 0). A copy whose stopping heartbeat was edited to say no e-stop is a
    mismatch (exit 1, the first differing step named). A copy whose stopping e-stop word says
    0x04 and whose copy of the stop record was edited to match is not the record: the record
    file's stop record says otherwise (exit 5, the fields named). The robot then re-arms and
    runs."""
    with Robot(tmp_path) as robot:
        robot.arm()
        stop = robot.remote_estop()
        path = _window_of(robot, stop.record)
        window = read_window(path)
        assert read_record(window.stop) == stop.record
        assert window.inputs[-1].now == stop.record.mono_ns
        done = srcsctl("replay", str(stop.record.seq), "--config", str(robot.config_path))
        assert done.returncode == 0, done.stdout + done.stderr
        assert "replay matches the record" in done.stdout, done.stdout
        reproduced = f"the stop #{stop.record.seq} RUN -> STOPPED state_change [vsc_estop"
        assert reproduced in done.stdout, done.stdout
        tampered = tmp_path / "tampered.jsonl"
        _stop_heartbeat_cleared(path, tampered)
        bad = srcsctl("replay", str(tampered), "--file", str(robot.record_path))
        assert bad.returncode == 1, bad.stdout + bad.stderr
        assert "MISMATCH at " in bad.stdout, bad.stdout
        assert f": record #{stop.record.seq}\n" in bad.stdout, bad.stdout
        forged = tmp_path / "forged.jsonl"
        _stop_word_and_copy_forged(path, forged)
        done = srcsctl("replay", str(forged), "--file", str(robot.record_path))
        assert done.returncode == 5, done.stdout + done.stderr
        assert "differing fields: causes" in done.stdout, done.stdout
        assert "replay matches" not in done.stdout, done.stdout
        robot.vsc.release()
        robot.recover(stop)


@ROOT_ONLY
def test_a_hung_disk_under_the_windows_never_delays_the_outputs_or_a_record(
    tmp_path: Path,
) -> None:
    """SR-7.12, SR-7.5, SR-7.7: the windows' folder is a file system of its own (ext4 on a loop
    device) that stops answering (frozen). A remote e-stop turns every output off at once and
    its record is in the file, while its window waits for the disk (the flight lane's thread
    hangs in the kernel); the robot re-arms and runs, and a second e-stop is as quick, with
    no window written and ``status`` answering. SIGTERM while the disk still hangs, thawed a
    second later: exit 0 within the unit's stop timeout, both stop records in the file."""
    image = _record_image(tmp_path)
    robot = RecordRobot(tmp_path / "robot")
    folder = flight_dir(robot.record_path)
    folder.mkdir()
    with _disk(image, folder), _running(robot):
        robot.arm()
        with _frozen(folder):
            first = robot.remote_estop()
            robot.vsc.release()
            robot.recover(first)
            second = robot.remote_estop()
            counters = robot.counters()
            assert counters.sink["flight_windows"] == 0, counters
            assert counters.record_errors == 0, counters
            sent = robot.sigterm()
            time.sleep(1.0)  # the disk hangs a while longer
        robot.exit_within_stop_timeout(sent)
        records = robot.records()
        assert first.record in records
        assert second.record in records


@ROOT_ONLY
def test_a_full_disk_under_the_windows_is_counted_and_stops_nothing(tmp_path: Path) -> None:
    """SR-7.12, SR-7.6: the windows' file system is full. A remote e-stop turns every output
    off at once and is recorded; its window cannot be written: counted (``flight_errors``)
    and logged, no stop of its own. With room again, the next stop's window is written and
    replays."""
    with Robot(tmp_path) as robot:
        folder = flight_dir(robot.record_path)
        folder.mkdir()
        mount = ["mount", "-t", "tmpfs", "-o", "size=1m", "srcs-full", str(folder)]
        subprocess.run(mount, check=True, timeout=30)
        try:
            filler = folder / "filler"
            with filler.open("wb", buffering=0) as file:
                try:
                    while True:
                        file.write(b"\0" * 4096)
                except OSError:
                    pass
            robot.arm()
            stop = robot.remote_estop()
            wait_until(
                lambda: robot.counters().sink["flight_errors"] >= 1, what="a window not written"
            )
            # The log line takes the sink's log lane, on its own thread's time (SR-7.7).
            wait_until(lambda: "flight recorder window not written" in robot.log(), what="its log")
            robot.vsc.release()
            robot.recover(stop)
            filler.unlink()
            again = robot.remote_estop()
            _window_of(robot, again.record)
            done = srcsctl("replay", "--file", str(robot.record_path))
            assert done.returncode == 0, done.stdout + done.stderr
            robot.vsc.release()
            robot.recover(again)
        finally:
            subprocess.run(["umount", "-l", str(folder)], check=False, timeout=30)
