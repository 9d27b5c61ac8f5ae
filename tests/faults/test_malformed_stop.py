"""A malformed e-stop or hold still stops, and replies leave in request order, on the real
``srcsd`` against ``srcs-sim`` (SR-8.13, docs/api.md "A malformed e-stop or hold")."""

from __future__ import annotations

import json
import socket
from pathlib import Path
from typing import Any

from supervisord.testkit.robot import OutputDef, Robot
from supervisord.vocabulary import State
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
        robot.wait_state("RUN")


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


def _read_lines(sock: socket.socket, count: int) -> list[dict[str, Any]]:
    buffer = b""
    while buffer.count(b"\n") < count:
        chunk = sock.recv(65536)
        assert chunk, f"the server closed after {buffer!r}"
        buffer += chunk
    return [json.loads(line) for line in buffer.splitlines()[:count]]
