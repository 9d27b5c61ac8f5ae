"""``srcsctl decode`` on captures as they come from the field: every file format python-can's
own writers make, a pipe that must show each frame at once, and live sources followed
read-only (a real pty for serial, python-can buses for CAN)."""

from __future__ import annotations

import gzip
import importlib.util
import io
import json
import os
import select
import signal
import subprocess
import time
import tty
from collections.abc import Callable
from pathlib import Path
from typing import Any

import can
import pytest
import serial

from supervisord.cli import capture, decode
from supervisord.protocol.framing import encode_frame
from supervisord.protocol.j1939 import CanId
from supervisord.protocol.messages import UserHeartbeat, VscHeartbeat
from tests.protocol.test_decode_cli import SRCSCTL, run

T0 = 1_700_000_000.25  # a capture's wall-clock time, as python-can stores it
HEARTBEAT = bytes.fromhex("0400010000000000")  # VSC heartbeat: local mode, remote e-stop
FRAMES = [
    can.Message(timestamp=T0, arbitration_id=CanId.HEARTBEAT, data=HEARTBEAT, channel=0),
    can.Message(
        timestamp=T0 + 0.5,
        arbitration_id=CanId.FEEDBACK_VALUE,
        data=bytes.fromhex("5501000000FFFFFF"),
        channel=0,
    ),
    can.Message(timestamp=T0 + 1.0, arbitration_id=0x0CFDE802, data=b"\x00", channel=0),
]
WRITERS: dict[str, Callable[[Path], can.Listener]] = {
    ".asc": can.ASCWriter,
    ".blf": can.BLFWriter,
    ".csv": can.CSVWriter,
    ".db": can.SqliteWriter,
    ".log": can.CanutilsLogWriter,
    ".trc": can.TRCWriter,
}
# Python's stdout to a pipe is block-buffered unless PYTHONUNBUFFERED says otherwise: without
# it, as in anyone's shell, only decode's own flushing lets a line through before the end.
BUFFERED = {name: value for name, value in os.environ.items() if name != "PYTHONUNBUFFERED"}
LINE_WAIT_S = 10.0  # coarse: a line that comes at all comes within milliseconds


def write_capture(path: Path, messages: list[can.Message]) -> Path:
    """Write ``messages`` with python-can's own writer for ``path``'s suffix."""
    writer = WRITERS[path.suffix](path)
    for message in messages:
        writer.on_message_received(message)
    writer.stop()
    return path


def read_line(stream: Any, timeout: float = LINE_WAIT_S) -> bytes:
    """One line from a pipe or pty, or b"" when none comes in time."""
    deadline, data = time.monotonic() + timeout, b""
    fd = stream if isinstance(stream, int) else stream.fileno()
    while not data.endswith(b"\n") and time.monotonic() < deadline:
        ready, _, _ = select.select([fd], [], [], max(0.0, deadline - time.monotonic()))
        if not ready:
            break
        byte = os.read(fd, 1)
        if not byte:
            break
        data += byte
    return data


@pytest.mark.parametrize("suffix", sorted(WRITERS))
def test_every_python_can_format_decodes_with_the_capture_time(tmp_path: Path, suffix: str) -> None:
    """Each format python-can writes decodes to the same objects, each with its frame's time."""
    path = write_capture(tmp_path / f"capture{suffix}", FRAMES)
    objects, errors, status = run("--can", str(path))
    assert (errors, status) == ("", 0)
    assert [(obj["type"], obj["can_id"]) for obj in objects] == [
        ("vsc_heartbeat", CanId.HEARTBEAT),
        ("feedback_set", CanId.FEEDBACK_VALUE),
        ("rejected", 0x0CFDE802),
    ]
    assert [obj["capture_time"] for obj in objects] == pytest.approx(
        [T0, T0 + 0.5, T0 + 1.0], abs=1e-3
    )
    assert objects[0]["e_stop_sources"] == ["remote"]
    assert objects[2]["reason"] == "unknown_id"


def test_a_gzip_compressed_capture_decodes(tmp_path: Path) -> None:
    """A ``.blf.gz`` is read as the ``.blf`` inside it."""
    blf = write_capture(tmp_path / "capture.blf", FRAMES[:1])
    packed = tmp_path / "capture.blf.gz"
    packed.write_bytes(gzip.compress(blf.read_bytes()))
    objects, errors, status = run("--can", str(packed))
    assert (errors, status) == ("", 0)
    assert [(obj["type"], obj["frame"]) for obj in objects] == [("vsc_heartbeat", 1)]


def test_mf4_decodes_or_names_its_missing_dependency(tmp_path: Path) -> None:
    """``.mf4`` decodes with asammdf installed; without it, one error line names asammdf."""
    path = tmp_path / "capture.mf4"
    if importlib.util.find_spec("asammdf") is None:
        path.write_bytes(b"MDF     4.10    ")
        objects, errors, status = run("--can", str(path))
        assert (objects, status) == ([], 2)
        assert errors.startswith(f"srcsctl decode: {path}: ")
        assert "asammdf" in errors
        return
    writer = can.MF4Writer(path)  # pragma: no cover - only where asammdf is installed
    for message in FRAMES:
        writer.on_message_received(message)
    writer.stop()
    objects, errors, status = run("--can", str(path))
    assert (errors, status) == ("", 0)
    assert [obj["type"] for obj in objects] == ["vsc_heartbeat", "feedback_set", "rejected"]


def test_error_remote_and_fd_frames_are_rejections(tmp_path: Path) -> None:
    """Error, remote and over-8-byte frames in a capture are rejections with their reason."""
    special = [
        can.Message(timestamp=T0, arbitration_id=0x04, is_error_frame=True, data=b"\0" * 8),
        can.Message(timestamp=T0, arbitration_id=CanId.HEARTBEAT, is_remote_frame=True, dlc=8),
        can.Message(timestamp=T0, arbitration_id=CanId.HEARTBEAT, is_fd=True, data=b"\0" * 12),
    ]
    path = write_capture(tmp_path / "special.blf", special)
    objects, _, status = run("--can", str(path))
    assert status == 0
    assert [obj["reason"] for obj in objects] == ["error_frame", "remote_frame", "wrong_length"]


def test_candump_remote_error_and_fd_lines_are_rejections() -> None:
    """In candump text, ``ID#R``, an error-flagged id and a CAN FD line are rejections."""
    capture_text = (
        b"(1.0) can0 0CFDE801#R\n(2.0) can0 20000004#0000000000000000\n"
        b"(3.0) can0 0CFDE801##0000000000000000000000\n"
    )
    objects, errors, status = run("--can", stdin=capture_text)
    assert [(obj["reason"], obj["capture_time"]) for obj in objects[:2]] == [
        ("remote_frame", 1.0),
        ("error_frame", 2.0),
    ]
    # CAN FD's ID##FLAGS DATA is not a classic frame: reported as an unreadable line.
    assert (status, errors) == (
        2,
        "srcsctl decode: <stdin>:3: not a candump frame: "
        "'(3.0) can0 0CFDE801##0000000000000000000000'\n",
    )


def test_a_corrupt_capture_keeps_its_frames_then_fails(tmp_path: Path) -> None:
    """python-can stops at a corrupt record: the frames before it are out, then exit 2."""
    path = write_capture(tmp_path / "capture.csv", FRAMES)
    lines = path.read_text().splitlines()
    path.write_text("\n".join([*lines[:2], "garbage", *lines[2:]]) + "\n")
    objects, errors, status = run("--can", str(path))
    assert status == 2
    assert [obj["type"] for obj in objects] == ["vsc_heartbeat"]
    assert errors.startswith(f"srcsctl decode: {path}: unreadable after 1 frames: ")


def test_a_candump_log_file_skips_a_bad_line_and_goes_on(tmp_path: Path) -> None:
    """A ``.log`` goes through decode's candump reader, which skips a bad line where
    python-can's would stop, and keeps each line's time."""
    path = write_capture(tmp_path / "candump.log", FRAMES[:2])
    first, second = path.read_text().splitlines()
    path.write_text(f"{first}\n(bad) can0 0CFDE801#00\n{second}\n")
    objects, errors, status = run("--can", str(path))
    assert status == 2
    assert errors == f"srcsctl decode: {path}:2: not a candump frame: '(bad) can0 0CFDE801#00'\n"
    assert [(obj["type"], obj["capture_time"], obj["line"]) for obj in objects] == [
        ("vsc_heartbeat", pytest.approx(T0), 1),
        ("feedback_set", pytest.approx(T0 + 0.5), 3),
    ]


def test_a_missing_capture_file_in_a_python_can_format_is_one_line() -> None:
    """A ``.blf`` that does not exist is one error line naming it, and exit 2."""
    objects, errors, status = run("--can", "/nonexistent/capture.blf")
    assert (objects, status) == ([], 2)
    assert errors == "srcsctl decode: /nonexistent/capture.blf: No such file or directory\n"


@pytest.mark.parametrize(
    ("flags", "line"),
    [
        (["--can", "-"], b"(1700000000.250000) can0 0CFDE801#0400010000000000\n"),
        (["--raw", "-"], encode_frame(UserHeartbeat(0))),
        (["-"], b"10 01 21 01 00 33 B9\n"),
    ],
)
def test_a_pipe_shows_each_frame_before_the_input_ends(flags: list[str], line: bytes) -> None:
    """Through a real pipe, a frame's JSON line comes out while stdin is still open."""
    with subprocess.Popen(
        [SRCSCTL, "decode", *flags],
        stdin=subprocess.PIPE,
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        env=BUFFERED,
    ) as process:
        assert process.stdin is not None
        process.stdin.write(line)
        process.stdin.flush()
        first = read_line(process.stdout)
        process.stdin.close()
        assert process.wait(timeout=60) == 0
    assert json.loads(first)["type"] in ("vsc_heartbeat", "user_heartbeat")


def test_follow_a_serial_port_reads_and_never_writes(pty_pair: tuple[int, str]) -> None:
    """``--raw --follow PORT`` decodes bytes as the port delivers them, with their wall-clock
    time, writes nothing to the port, and ends with exit 0 on SIGTERM."""
    master, path = pty_pair
    with subprocess.Popen(
        [SRCSCTL, "decode", "--raw", "--follow", path],
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        env=BUFFERED,
    ) as process:
        # The port is open once a frame written now comes back decoded; write until it does.
        first = b""
        deadline = time.monotonic() + LINE_WAIT_S
        while not first and time.monotonic() < deadline:
            before = time.time()
            os.write(master, encode_frame(VscHeartbeat(4, 0, 1)))
            first = read_line(process.stdout, timeout=0.5)
        written_back, _, _ = select.select([master], [], [], 0.3)
        process.send_signal(signal.SIGTERM)
        status = process.wait(timeout=60)
    obj = json.loads(first)
    assert (obj["type"], obj["e_stop_sources"], status) == ("vsc_heartbeat", ["remote"], 0)
    assert before - 1.0 <= obj["capture_time"] <= time.time()
    assert written_back == []


def test_follow_ends_with_exit_2_when_the_port_goes_away() -> None:
    """A port that vanishes under ``--follow`` (the pty's master closed) is one error line
    naming the port, and exit 2."""
    master, slave = os.openpty()
    tty.setraw(master)
    path = os.ttyname(slave)
    os.close(slave)
    with subprocess.Popen(
        [SRCSCTL, "decode", "--raw", "--follow", path],
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        env=BUFFERED,
    ) as process:
        first, deadline = b"", time.monotonic() + LINE_WAIT_S
        while not first and time.monotonic() < deadline:
            os.write(master, encode_frame(UserHeartbeat(0)))
            first = read_line(process.stdout, timeout=0.5)
        os.close(master)
        status = process.wait(timeout=60)
        errors = process.stderr.read().decode() if process.stderr else ""
    assert json.loads(first)["type"] == "user_heartbeat"
    assert status == 2
    assert errors.startswith(f"srcsctl decode: {path}: ")


def test_follow_needs_raw_or_can_and_a_source() -> None:
    """``--follow`` without --raw/--can or without a port is one usage line and exit 2."""
    for flags in (["--follow", "/dev/null"], ["--hid", "--follow", "x"], ["--can", "--follow"]):
        objects, errors, status = run(*flags)
        assert (objects, status) == ([], 2)
        assert errors == "srcsctl decode: --follow needs --raw PORT or --can CHANNEL\n"


def test_following_a_can_bus_yields_frames_and_sends_none() -> None:
    """The CAN follower (python-can's in-process virtual bus) yields each frame as it comes,
    with its timestamp, and puts nothing on the bus."""
    channel = "srcs-decode-follow"
    with (
        capture.open_bus("virtual", channel) as follower,
        can.Bus(interface="virtual", channel=channel) as vsc,
        can.Bus(interface="virtual", channel=channel) as witness,
    ):
        vsc.send(can.Message(arbitration_id=CanId.HEARTBEAT, data=HEARTBEAT))
        frames = decode._Run("virtual", io.StringIO()).follow_objects(capture.follow_bus(follower))
        obj = next(frames)
        seen = witness.recv(timeout=0.2)
        assert witness.recv(timeout=0.2) is None
    assert (obj["type"], obj["frame"]) == ("vsc_heartbeat", 1)
    assert obj["capture_time"] == pytest.approx(time.time(), abs=60)
    assert seen is not None
    assert seen.arbitration_id == CanId.HEARTBEAT


@pytest.mark.usefixtures("private_network")
def test_follow_a_live_can_channel_end_to_end() -> None:
    """``--can --follow`` on a udp_multicast channel shows a frame sent on it, then exits 0
    on SIGTERM."""
    channel = "239.74.163.9"
    with (
        subprocess.Popen(
            [SRCSCTL, "decode", "--can", "--follow", "--interface", "udp_multicast", channel],
            stdout=subprocess.PIPE,
            stderr=subprocess.PIPE,
            env=BUFFERED,
        ) as process,
        capture.open_bus("udp_multicast", channel) as vsc,
    ):
        first, deadline = b"", time.monotonic() + LINE_WAIT_S
        while not first and time.monotonic() < deadline:
            vsc.send(can.Message(arbitration_id=CanId.HEARTBEAT, data=HEARTBEAT))
            first = read_line(process.stdout, timeout=0.5)
        process.send_signal(signal.SIGTERM)
        status = process.wait(timeout=60)
    obj = json.loads(first)
    assert (obj["type"], obj["can_id"], status) == ("vsc_heartbeat", CanId.HEARTBEAT, 0)
    assert obj["capture_time"] == pytest.approx(time.time(), abs=60)


def test_a_reader_that_stops_early_ends_decode_quietly(tmp_path: Path) -> None:
    """When the output's reader goes away (``| head -1``), decode exits 0 without a traceback."""
    path = write_capture(tmp_path / "long.blf", FRAMES * 20_000)
    with subprocess.Popen(
        [SRCSCTL, "decode", "--can", str(path)],
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        env=BUFFERED,
    ) as process:
        assert process.stdout is not None
        first = process.stdout.readline()
        process.stdout.close()
        status = process.wait(timeout=60)
        errors = process.stderr.read() if process.stderr else b""
    assert json.loads(first)["type"] == "vsc_heartbeat"
    assert (status, errors) == (0, b"")


def test_ctrl_c_ends_a_live_pipe_quietly() -> None:
    """SIGINT while decoding a pipe that stays open ends decode with exit 0 and no traceback,
    after the lines decoded so far."""
    with subprocess.Popen(
        [SRCSCTL, "decode", "--can", "-"],
        stdin=subprocess.PIPE,
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        env=BUFFERED,
    ) as process:
        assert process.stdin is not None
        process.stdin.write(b"0CFDE801#0400010000000000\n")
        process.stdin.flush()
        first = read_line(process.stdout)
        process.send_signal(signal.SIGINT)
        status = process.wait(timeout=60)
        errors = process.stderr.read() if process.stderr else b""
    assert json.loads(first)["type"] == "vsc_heartbeat"
    assert (status, errors) == (0, b"")


def test_follow_refuses_a_port_the_supervisor_holds(pty_pair: tuple[int, str]) -> None:
    """A port locked as srcsd's serial link locks it is refused (exit 2), so that decode
    never takes bytes from a running supervisor."""
    _, path = pty_pair
    with serial.Serial(path, 115200, exclusive=True):  # as SerialLink opens it
        objects, errors, status = run("--raw", "--follow", path)
    assert (objects, status) == ([], 2)
    assert errors.startswith(f"srcsctl decode: {path}: held by another process (srcsd?)")
