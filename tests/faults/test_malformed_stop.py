"""A malformed e-stop or hold still stops, and replies leave in request order, on the real
``srcsd`` against ``srcs-sim`` (SR-8.13, docs/api.md "A malformed e-stop or hold")."""

from __future__ import annotations

import json
import socket
import time
from pathlib import Path
from typing import Any

from supervisord.config.schema import DEFAULT_MAX_MESSAGE_BYTES
from supervisord.testkit.robot import OutputDef, Robot
from supervisord.testkit.worst_input import LINES
from supervisord.vocabulary import State
from tests.faults.test_flood import WATCHDOG_S, HeartbeatWatch
from tests.faults.test_odd_input import REPLY_S, raw_exchange

DEEP = b'{"a":' * 17 + b"1" + b"}" * 17  # nested one deeper than the limit: bad_json


def test_an_estop_with_a_field_too_many_stops_the_running_robot(tmp_path: Path) -> None:
    """SR-8.13: ``{"op":"estop","reason":"operator"}`` got ``bad_request`` and the robot stayed
    in RUN; now the drive goes off as for any local e-stop, the stop is recorded as
    ``local_estop``, and the reply is the error with ``"honoured": true``."""
    with Robot(tmp_path, outputs=(OutputDef("drive"),)) as robot:
        robot.arm()
        t0 = robot.now()
        (reply,) = raw_exchange(robot.socket_path, b'{"op":"estop","reason":"operator"}\n', 1)
        assert (reply["ok"], reply["code"], reply["op"], reply["honoured"]) == (
            False,
            "bad_request",
            "estop",
            True,
        )
        # Off by the time the reply came (outputs are set before it, SR-6.1).
        robot.expect_stop("local_estop", t0, robot.now() - t0)
        assert robot.status().report.state is State.STOPPED


def test_a_hold_with_a_wrong_id_holds_until_its_connection_ends(tmp_path: Path) -> None:
    """SR-8.13: ``{"op":"hold","id":1.5}`` was refused and the robot ran on; now it holds the
    running robot (a hold before hello: the operator's, ended by its connection's end) and the
    robot runs again once that connection closes."""
    with Robot(tmp_path, outputs=(OutputDef("drive"),)) as robot:
        robot.arm()
        with socket.socket(socket.AF_UNIX, socket.SOCK_STREAM) as sock:
            sock.settimeout(REPLY_S)
            sock.connect(str(robot.socket_path))
            sock.sendall(b'{"op":"hold","id":1.5}\n{"op":"status","id":2}\n')
            hold, status = _read_lines(sock, 2)
            assert (hold["code"], hold["op"], hold["honoured"]) == ("bad_request", "hold", True)
            assert "id" not in hold
            assert (status["id"], status["state"]) == (2, "HOLD")
            assert robot.output_file("drive") is False
        robot.wait_state(State.RUN)


def test_pipelined_replies_come_back_in_request_order(tmp_path: Path) -> None:
    """docs/api.md "exactly one reply, in the order the requests were sent" (SR-8.13's
    companion): ``hello``, ``estop`` and a 17-deep object in one write were answered
    ``bad_json`` first, so a client reading replies in order took it for its e-stop's; now the
    daemon answers hello, estop, then ``bad_json``."""
    with Robot(tmp_path, outputs=(OutputDef("drive"),)) as robot:
        data = b'{"op":"hello","name":"nav"}\n{"op":"estop"}\n' + DEEP + b"\n"
        replies = raw_exchange(robot.socket_path, data, 3)
        assert [(r["ok"], r.get("op"), r.get("code")) for r in replies] == [
            (True, "hello", None),
            (True, "estop", None),
            (False, None, "bad_json"),
        ]


def test_a_broken_line_at_the_limit_delays_neither_a_remote_estop_nor_the_heartbeat(
    tmp_path: Path,
) -> None:
    """SR-10.5, SR-8.13, SR-5.1: one line of a quote and escaped quotes, never closed, at the
    line limit (``"\\"\\"\\"...``, 64 KiB) held the loop for seconds while its op was looked
    for (quadratic; a 24 KB line: a remote e-stop 150 ms later switched the drive off after
    1.0-1.2 s, recorded as ``vsc_link_lost``, and the user heartbeat stopped for 1.26 s). Now
    the line is refused ``bad_json`` and, sent 150 ms before the remote's e-stop, neither
    delays the stop (off within the next VSC heartbeat and the allowance, recorded as
    ``vsc_estop``, no ``vsc_link_lost``, no internal fault) nor lets the VSC's watchdog miss
    the user heartbeat (500 ms, read on the VSC's side)."""
    line = LINES["escaped quotes"](DEFAULT_MAX_MESSAGE_BYTES - 1) + b"\n"
    with Robot(tmp_path, outputs=(OutputDef("drive"),)) as robot:
        robot.arm()
        t_line = robot.now()
        with (
            HeartbeatWatch(robot.sim.control_path) as beats,
            socket.socket(socket.AF_UNIX, socket.SOCK_STREAM) as sock,
        ):
            sock.settimeout(REPLY_S)
            sock.connect(str(robot.socket_path))
            sock.sendall(line)
            time.sleep(0.15)
            stop = robot.remote_estop()  # asserts: off within the VSC heartbeat + allowance
            (reply,) = _read_lines(sock, 1)
            time.sleep(0.3)  # the watch goes on past the stop
        assert (reply["ok"], reply["code"], "honoured" in reply) == (False, "bad_json", False)
        assert robot.record_raising("vsc_link_lost", t_line) is None, robot.records_since(t_line)
        assert robot.counters().internal_faults == 0
        assert beats.samples > 20
        assert not beats.tripped, "the VSC's key-85 watchdog tripped"
        assert beats.worst_age < WATCHDOG_S, beats.worst_age
        print(
            f"drive off {1000 * (stop.t_off - stop.t_fault):.0f} ms after the e-stop; user "
            f"heartbeat's worst age on the VSC's side {1000 * beats.worst_age:.0f} ms"
        )


def _read_lines(sock: socket.socket, count: int) -> list[dict[str, Any]]:
    buffer = b""
    while buffer.count(b"\n") < count:
        chunk = sock.recv(65536)
        assert chunk, f"the server closed after {buffer!r}"
        buffer += chunk
    return [json.loads(line) for line in buffer.splitlines()[:count]]
