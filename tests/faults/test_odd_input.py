"""Odd strings end to end (SR-8.7, "no input string can raise"; ``docs/safety.md`` "No input can
raise"): the real ``srcsd`` against ``srcs-sim``. A request id that UTF-8
cannot hold, other odd request lines, a user whose login name is not UTF-8 running
``srcsctl estop``, a GPS sentence with ``²`` where a digit belongs while a client subscribes to
``gps``, and a config holding text no encoder takes. None of them may stop the robot with
``internal``, lose a record or silence ``status``."""

from __future__ import annotations

import contextlib
import json
import os
import pwd
import shutil
import socket
import subprocess
import sys
import tempfile
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import pytest

from supervisord.record.stop import StopRecord
from supervisord.testkit.namespaces import in_private_mount
from supervisord.testkit.robot import OutputDef, Robot
from supervisord.testkit.wait import wait_until
from supervisord.vocabulary import Cause, CauseKind, State

ODD_NAME = b"r\xe9mi"  # Latin-1, not UTF-8: how a name from an old system arrives
SHOWN_NAME = "r\\xe9mi"  # the name as records and replies show it: the byte escaped
REPLY_S = 5.0  # coarse: a shared two-core machine


def internal_records(robot: Robot) -> list[StopRecord]:
    """Every record that raised ``internal``."""
    return [r for r in robot.records() if robot.raised_in(r, CauseKind.INTERNAL)]


def assert_record_whole(robot: Robot) -> None:
    """Every line of the record is UTF-8 JSON and the sequence numbers have no gap."""
    lines = robot.record_path.read_bytes().splitlines()
    sequence = [json.loads(line.decode("utf-8"))["seq"] for line in lines]
    assert sequence == list(range(sequence[0], sequence[0] + len(sequence)))


@contextlib.contextmanager
def open_socket_dir() -> Iterator[Path]:
    """A socket directory another user can reach (pytest's own folders are root's alone)."""
    folder = Path(tempfile.mkdtemp(prefix="srcs-odd-"))
    folder.chmod(0o711)
    try:
        yield folder
    finally:
        shutil.rmtree(folder, ignore_errors=True)


def raw_exchange(path: Path, data: bytes, replies: int) -> list[dict[str, Any]]:
    """Send ``data`` on a fresh connection and read ``replies`` reply lines (no client
    library: the lines are exactly as written here)."""
    with socket.socket(socket.AF_UNIX, socket.SOCK_STREAM) as sock:
        sock.settimeout(REPLY_S)
        sock.connect(str(path))
        sock.sendall(data)
        buffer = b""
        while buffer.count(b"\n") < replies:
            chunk = sock.recv(65536)
            assert chunk, f"the server closed after {buffer!r}"
            buffer += chunk
    return [json.loads(line.decode("utf-8")) for line in buffer.splitlines()]


# -- a request id and other lines that UTF-8 or Python cannot take ----------------------------

ODD_LINES = [
    (b'{"op":"status","id":"\\ud800"}', "bad_request"),  # a lone surrogate
    # Not a hold: a malformed hold still holds (SR-8.13, tests/faults/test_malformed_stop.py).
    (b'{"op":"release","id":"a\\udce9"}', "bad_request"),
    (b'{"op":"status","\\udfff":1}', "bad_request"),  # a field name no encoder takes
    (b'{"op":"\\ud800"}', "unknown_op"),
    (b'{"op":"status","id":' + b"[" * 900 + b"]" * 900 + b"}", "bad_json"),
    (b'{"op":"display","mode":' + b"9" * 2000 + b"}", "bad_request"),
    (b'{"op":"display","mode":1e400}', "bad_request"),
    (b'{"op":"display","mode":NaN}', "bad_json"),
    (b'{"op":"status"\x0b}', "bad_json"),  # whitespace that is not JSON's
    (b'{"op":"status","op":"status"}', "bad_json"),
    (b'{"op":"status","id":"r\xe9mi"}', "bad_json"),  # not UTF-8
]


def test_odd_request_lines_each_get_a_reply_and_the_robot_keeps_running(tmp_path: Path) -> None:
    """SR-8, SR-2.9 ``internal``: a request whose ``id`` holds a lone surrogate raised in the reply
    encoder: no reply, and an ``internal`` stop. Now it and every other odd line
    (surrogates in names and ops, deep nesting, 2000 digits, 1e400, NaN, a vertical tab, a
    duplicate key, bytes that are not UTF-8) get exactly one error reply each, in order; the
    running robot keeps running, and no record raises ``internal``."""
    with Robot(tmp_path, outputs=(OutputDef("drive"),)) as robot:
        robot.arm()
        t0 = robot.now()
        data = b"".join(line + b"\n" for line, _ in ODD_LINES) + b'{"op":"status","id":7}\n'
        replies = raw_exchange(robot.socket_path, data, len(ODD_LINES) + 1)
        assert [r["code"] for r in replies[:-1]] == [code for _, code in ODD_LINES]
        assert all("id" not in r for r in replies[:-1])  # none could be echoed
        assert replies[-1]["ok"] is True
        assert replies[-1]["id"] == 7
        assert replies[-1]["state"] == "RUN"
        assert robot.watcher is not None
        assert robot.watcher.ons_between(t0, robot.now()) == []  # no new edge: still on
        assert robot.output_file("drive") is True
        assert internal_records(robot) == []
        assert_record_whole(robot)


# -- a user whose login name is not UTF-8 -------------------------------------------------------


def _free_uid() -> int:
    for uid in range(4242, 60000):
        try:
            pwd.getpwuid(uid)
        except KeyError:
            return uid
    raise AssertionError("no free uid")


class OddUserRobot(Robot):
    """The daemon sees ``passwd`` as ``/etc/passwd``: bind-mounted over it in a private mount
    namespace of its own, so the machine's user database is left alone. (Debian's ``useradd``
    refuses a name that is not UTF-8, and a real entry would outlive a failed test.)"""

    passwd: Path | None = None

    def daemon_command(self) -> list[str]:
        command = super().daemon_command()
        assert self.passwd is not None
        return in_private_mount('mount --bind "$0" /etc/passwd', self.passwd, command)


needs_root = pytest.mark.skipif(
    os.geteuid() != 0 or shutil.which("setpriv") is None or shutil.which("unshare") is None,
    reason="needs root, setpriv and unshare (a private mount namespace, another uid)",
)


@needs_root
def test_a_user_whose_name_is_not_utf8_can_estop_and_the_stop_is_recorded(
    tmp_path: Path,
) -> None:
    """SR-2.6 ``local_estop``, SR-7 every stop recorded: a user whose login name is not UTF-8 ran
    ``srcsctl estop``: the output went off but no stop record was written,
    ``status`` stopped answering and later records were lost (the name carried surrogates into
    the record and reply encoders). Now the e-stop answers, turns the output off, is recorded
    as ``local_estop`` naming the user (the undecodable byte escaped), and ``status`` answers,
    also to that user. The user's name is looked up off the loop when the user first connects
    (SR-10.3): a ``hello`` of that user first, answered once the name is known, so that the
    e-stop, served at once whatever the lookup, finds it known."""
    uid = _free_uid()
    passwd = tmp_path / "passwd"
    passwd.write_bytes(
        Path("/etc/passwd").read_bytes() + ODD_NAME + f":x:{uid}:0::/:/bin/sh\n".encode()
    )
    with open_socket_dir() as folder:
        robot = OddUserRobot(tmp_path / "robot", outputs=(OutputDef("drive"),))
        robot.passwd = passwd
        robot.socket_path = folder / "api.sock"
        with robot:
            robot.arm()
            as_user = ["setpriv", f"--reuid={uid}", "--regid=0", "--clear-groups", "--"]
            srcsctl = [sys.executable, "-m", "supervisord.cli.srcsctl"]
            socket_arg = ["--socket", str(robot.socket_path)]
            hello = (
                "from supervisord.client import SupervisorClient\n"
                f"with SupervisorClient.connect({str(robot.socket_path)!r}) as api:\n"
                "    api.hello('odd-user')\n"
            )
            named = subprocess.run(
                [*as_user, sys.executable, "-c", hello],
                capture_output=True,
                timeout=30,
                check=False,
                env={**os.environ, "PYTHONPATH": os.pathsep.join(sys.path)},
            )
            assert named.returncode == 0, named.stderr.decode(errors="replace")
            t0 = robot.now()
            estop = subprocess.run(
                [*as_user, *srcsctl, "estop", *socket_arg],
                capture_output=True,
                timeout=30,
                check=False,
            )
            assert estop.returncode == 0, estop.stderr.decode(errors="replace")
            # Off at once: by the time srcsctl has its answer (outputs are set before the
            # reply, SR-6.1), whatever its interpreter's start took on a busy machine.
            robot.expect_stop("local_estop", t0, robot.now() - t0)
            status = robot.status()
            local = next(c for c in status.report.causes if c.kind is CauseKind.LOCAL_ESTOP)
            assert local.active
            assert local.details["caller"] == SHOWN_NAME
            [record] = [
                r
                for r in robot.records_since(t0)
                if robot.raised_in(r, Cause(CauseKind.LOCAL_ESTOP))
            ]
            assert record.trigger["caller"] == {
                "uid": uid,
                "pid": record.trigger["caller"]["pid"],
                "name": SHOWN_NAME,
                "admin": False,
            }
            shown = subprocess.run(
                [*as_user, *srcsctl, "status", *socket_arg],
                capture_output=True,
                timeout=30,
                check=False,
            )
            assert shown.returncode == 0, shown.stderr.decode(errors="replace")
            assert "local_estop" in shown.stdout.decode()
            assert internal_records(robot) == []
            assert_record_whole(robot)


# -- a GPS sentence with "²" where a digit belongs ----------------------------------------------

SUPERSCRIPT_GGA = "$GPGGA,123519,4807.038,N,01131.000,E,\u00b2,08,0.9,545.4,M,46.9,M,,"


def test_a_gga_with_a_superscript_digit_is_pushed_and_stops_nothing(tmp_path: Path) -> None:
    """SR-2.9 ``internal``, SR-8 pushes: a GGA sentence whose fix quality is ``²`` (``str.isdigit``
    takes it; ``int`` does not) raised in the NMEA parser while a client subscribed to ``gps``:
    four ``internal`` stops in three seconds. Now the running robot keeps running,
    the subscriber gets the sentence with no fix quality, and no record raises ``internal``."""
    with Robot(tmp_path, outputs=(OutputDef("drive"),)) as robot:
        robot.arm()
        with robot.client() as api:
            api.subscribe("gps")
            t0 = robot.now()
            robot.sim.control.request("gps", sentence=SUPERSCRIPT_GGA)
            pushes: list[dict[str, Any]] = []

            def two_odd_pushes() -> bool:
                while (push := api.next_event(timeout=0.1)) is not None:
                    if push.event == "gps" and push.json()["string"] == SUPERSCRIPT_GGA:
                        pushes.append(push.json())
                return len(pushes) >= 2  # the simulator sends GPS once a second

            wait_until(two_odd_pushes, 10.0, what="two pushes of the odd GGA")
        assert pushes[0]["fix_quality"] is None
        assert pushes[0]["latitude"] == pytest.approx(48.1173)
        status = robot.status()
        assert status.report.state is State.RUN
        assert robot.watcher is not None
        assert robot.watcher.ons_between(t0, robot.now()) == []
        assert internal_records(robot) == []
        assert_record_whole(robot)


# -- config text no encoder takes -------------------------------------------------------------


@pytest.mark.parametrize(
    ("text", "hint"),
    [
        (b'name = "\\ud800"', b"Unicode scalar"),
        (b'name = "r\xe9mi"', b"UTF-8"),
    ],
    ids=["escaped-surrogate", "not-utf8"],
)
def test_config_text_no_encoder_takes_is_refused_before_start(
    tmp_path: Path, text: bytes, hint: bytes
) -> None:
    """SR-7, SR-8: config values reach ``status`` and the record (the robot's name, output and
    client names, paths in reasons): a file that is not UTF-8, or that escapes a lone surrogate, is
    refused by ``--check-config`` (and so by the daemon at start) with the line and the fix, never
    let into the loop."""
    config = tmp_path / "robot.toml"
    config.write_bytes(b"[robot]\n" + text + b"\n")
    checked = subprocess.run(
        [sys.executable, "-m", "supervisord.cli.srcsd", "--check-config", str(config)],
        capture_output=True,
        timeout=60,
        check=False,
    )
    assert checked.returncode != 0
    assert b"line 2" in checked.stderr + checked.stdout
    assert hint in checked.stderr + checked.stdout
    assert b"Traceback" not in checked.stderr
