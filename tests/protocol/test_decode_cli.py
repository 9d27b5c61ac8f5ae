"""``srcsctl decode`` as an integrator runs it: the installed executable on files and stdin."""

from __future__ import annotations

import json
import shutil
import subprocess
from pathlib import Path
from typing import Any

import pytest

from supervisord.protocol.framing import encode_frame
from supervisord.protocol.messages import UserHeartbeat, VscHeartbeat
from supervisord.testkit.traffic import vsc_stream

SRCSCTL = shutil.which("srcsctl") or str(Path(__file__).parents[2] / ".venv/bin/srcsctl")
HB_LOCAL_ESTOP = "10 01 20 06 04 00 01 00 00 00 3C EF"


def run(*args: str, stdin: bytes = b"") -> tuple[list[dict[str, Any]], str, int]:
    done = subprocess.run(
        [SRCSCTL, "decode", *args], input=stdin, capture_output=True, timeout=60, check=False
    )
    lines = done.stdout.decode().splitlines()
    return [json.loads(line) for line in lines], done.stderr.decode(), done.returncode


def test_hex_capture_with_a_bad_line_keeps_decoding(tmp_path: Path) -> None:
    """A bad line is reported with its number and exit 2; frames before and after decode."""
    capture = tmp_path / "capture.hex"
    capture.write_text(f"# from robot 7\n10 01 21 01 00 33 B9\nnot hex here\n{HB_LOCAL_ESTOP}\n")
    objects, errors, status = run(str(capture))
    assert status == 2
    assert errors == f"srcsctl decode: {capture}:3: not hex: 'not'\n"
    assert [obj["type"] for obj in objects] == ["user_heartbeat", "vsc_heartbeat"]
    assert objects[1] == {
        "type": "vsc_heartbeat",
        "vsc_mode": 4,
        "vsc_mode_name": "local",
        "autonomy_mode": 0,
        "autonomy_mode_name": "user",
        "e_stop_indication": 1,
        "e_stop_sources": ["remote"],
        "offset": 7,
    }


def test_frames_may_span_lines_and_use_separators() -> None:
    """Hex may be split across lines anyhow and written with 0x, commas or colons."""
    objects, errors, status = run(stdin=b"0x10,0x01:21\n01 00\n33b9\n")
    assert (objects, errors, status) == (
        [{"type": "user_heartbeat", "e_stop_indication": 0, "offset": 0}],
        "",
        0,
    )


def test_raw_capture_reports_rejections_with_offsets(tmp_path: Path) -> None:
    """--raw reads binary; noise and a bad checksum are rejections at their stream offsets."""
    bad = bytearray(encode_frame(VscHeartbeat(9)))
    bad[-1] ^= 1
    capture = tmp_path / "capture.bin"
    capture.write_bytes(b"\x00\xff" + bytes(bad) + encode_frame(UserHeartbeat(1)))
    objects, _, status = run("--raw", str(capture))
    assert status == 0
    assert [(obj["type"], obj.get("reason"), obj["offset"]) for obj in objects] == [
        ("rejected", "noise", 0),
        ("rejected", "bad_checksum", 2),
        ("rejected", "noise", 3),
        ("user_heartbeat", None, 14),
    ]


def test_raw_stream_of_realistic_traffic_decodes_completely() -> None:
    """A second of realistic VSC traffic without garbage decodes to its 71 messages."""
    objects, errors, status = run("--raw", stdin=vsc_stream(1.0, garbage=0.0))
    assert (errors, status) == ("", 0)
    kinds = [obj["type"] for obj in objects]
    assert (kinds.count("joystick"), kinds.count("vsc_heartbeat"), kinds.count("gps")) == (
        50,
        20,
        1,
    )
    gps = objects[kinds.index("gps")]
    assert (gps["fix_quality"], gps["utc_time"]) == (1, "12:35:19+00:00")


def test_candump_formats() -> None:
    """--can reads ID#DATA, candump -L lines and candump's default columns, each line's time
    (candump -L, or -ta before the columns) as its capture_time, null when it has none."""
    capture = (
        b"0CFDE801#0400010000000000\n"
        b"(1700000000.000001) can0 0CFDE900#5501000000FFFFFF\n"
        b"(1700000000.250000)  can0  0CFDD934   [8]  01 00 FF FF FF FF FF FF\n"
        b"0CFDE802#00\n"
        b"0CFDE801#XYZ\n"
    )
    objects, errors, status = run("--can", stdin=capture)
    assert status == 2
    assert errors == "srcsctl decode: <stdin>:5: not a candump frame: '0CFDE801#XYZ'\n"
    assert [obj["type"] for obj in objects] == [
        "vsc_heartbeat",
        "feedback_set",
        "joystick_extended",
        "rejected",
    ]
    assert objects[1]["user_feedback_key_name"] == "user_estop_timeout"
    assert objects[2]["z_joystick_value"]["value"] == 0
    assert [obj["capture_time"] for obj in objects] == [
        None,
        1700000000.000001,
        1700000000.25,
        None,
    ]
    assert objects[3] == {
        "type": "rejected",
        "reason": "unknown_id",
        "can_id": 0x0CFDE802,
        "length": 1,
        "capture_time": None,
        "line": 4,
    }


def test_hid_reports() -> None:
    """--hid reads one report per line: 9 bytes input, 26 output, anything else rejected."""
    objects, _, status = run("--hid", stdin=b"7f 81 00 00 00 00 32 09 01\n00 00\n")
    assert status == 0
    assert objects[0]["type"] == "hid_input"
    assert (objects[0]["left_x"], objects[0]["pressed"], objects[0]["src_state_name"]) == (
        127,
        [1, 2],
        "operational",
    )
    assert objects[1] == {
        "type": "rejected",
        "reason": "wrong_length",
        "length": 2,
        "expected": 26,
        "line": 2,
    }


def test_missing_file_is_one_line_and_exit_2() -> None:
    """A capture that does not exist gives one error line naming it, and exit status 2."""
    objects, errors, status = run("/nonexistent/capture.hex")
    assert (objects, status) == ([], 2)
    assert errors == "srcsctl decode: /nonexistent/capture.hex: No such file or directory\n"


@pytest.mark.parametrize("flags", [["--raw", "--can"], ["--bogus"]])
def test_usage_errors_exit_2(flags: list[str]) -> None:
    """Conflicting or unknown options are usage errors with argparse's exit status 2."""
    _, errors, status = run(*flags)
    assert status == 2
    assert "usage:" in errors
