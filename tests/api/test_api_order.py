"""Replies in request order and malformed stops that still stop, on the real API server over
real Unix sockets (docs/api.md "Framing", SR-8.13): the loop of ``test_api_server``."""

from __future__ import annotations

import json
import tempfile
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from supervisord.api.requests import Estop, Hold, readable_stop
from supervisord.api.server import Accepted, Closed, Received, ServerConfig, core_event
from supervisord.safety.events import LocalEstop
from tests.api.test_api_server import Loop, Peer

DEEP = b'{"a":' * 17 + b"1" + b"}" * 17  # nested one deeper than MAX_NESTING: bad_json


@pytest.fixture
def loop(tmp_path: Path) -> Iterator[Loop]:
    # Slots never idle out here: a busy machine may be slow between accept and request.
    config = ServerConfig(tmp_path / "api.sock", max_clients=2, max_line=256, slot_idle_ms=60_000)
    the_loop = Loop(config)
    yield the_loop
    the_loop.close()


@pytest.fixture
def peer(tmp_path: Path, loop: Loop) -> Iterator[Peer]:
    the_peer = Peer(tmp_path / "api.sock")
    yield the_peer
    the_peer.close()


# -- replies in request order ---------------------------------------------------------------


def test_a_malformed_line_after_valid_ones_is_answered_after_them(loop: Loop, peer: Peer) -> None:
    """SR-8.13, docs/api.md "exactly one reply, in the order the requests were sent": ``hello``,
    ``estop`` and a 17-deep object in one write were answered ``bad_json`` first; now the
    replies are hello's, estop's, then ``bad_json``."""
    peer.send(b'{"op":"hello","name":"nav"}\n{"op":"estop"}\n' + DEEP + b"\n")
    replies = peer.read(loop, 3)
    assert [(r["ok"], r.get("op"), r.get("code")) for r in replies] == [
        (True, "hello", None),
        (True, "estop", None),
        (False, None, "bad_json"),
    ]


def test_a_reply_answered_later_holds_back_the_malformed_ones_behind_it(
    tmp_path: Path,
) -> None:
    """docs/api.md "Framing": a request the daemon answers on a later turn (as ``commission``)
    keeps every reply after it waiting, the server's own errors included, then all leave in
    order."""
    loop = Loop(ServerConfig(tmp_path / "api.sock"), answer=False)
    peer = Peer(tmp_path / "api.sock")
    try:
        peer.send(b'{"op":"status","id":1}\n{nope\n{"op":"fly","id":3}\n')
        loop.until(lambda: bool(loop.of_type(Received)))
        for _ in range(20):
            loop.turn(0.001)
        assert not peer.has(1)  # the errors wait for the status reply
        (status,) = loop.of_type(Received)
        loop.server.reply(status)
        replies = peer.read(loop, 3)
        assert [(r.get("id"), r.get("code")) for r in replies] == [
            (1, None),
            (None, "bad_json"),
            (3, "unknown_op"),
        ]
    finally:
        peer.close()
        loop.close()


VALID = [
    (lambda i: {"op": "status", "id": i}, None),
    (lambda i: {"op": "subscribe", "topics": [], "id": i}, None),
    (lambda i: {"op": "heartbeat", "id": i}, "not_hello"),  # refused: no hello
    (lambda i: {"op": "fly", "id": i}, "unknown_op"),
    (lambda i: {"op": "status", "id": i, "extra": 1}, "bad_request"),
    (lambda i: {"op": "vibrate", "side": "up", "id": i}, "bad_request"),
]
"""Lines with an id: the reply must carry it (``None``: ok, else the error code)."""
NAMELESS = [
    (b"{nope", "bad_json"),
    (b"[1]", "bad_request"),
    (DEEP, "bad_json"),
    (b'{"op":"status","op":"status"}', "bad_json"),
    (b"x" * 300, "too_long"),  # past the 256-byte line limit
]
"""Lines whose reply carries no id."""


@st.composite
def pipelines(draw: st.DrawFn) -> tuple[list[bytes], list[tuple[int | None, str | None]], int]:
    """Request lines, the (id, code) each reply must have, and a read budget."""
    lines: list[bytes] = []
    expected: list[tuple[int | None, str | None]] = []
    for i in range(draw(st.integers(1, 24))):
        if draw(st.booleans()):
            make, code = draw(st.sampled_from(VALID))
            lines.append(json.dumps(make(i)).encode())
            expected.append((i, code))
        else:
            line, code = draw(st.sampled_from(NAMELESS))
            lines.append(line)
            expected.append((None, code))
    return lines, expected, draw(st.integers(1, 8))


@settings(
    max_examples=60,
    deadline=None,
    suppress_health_check=[HealthCheck.too_slow, HealthCheck.data_too_large],
)
@given(pipelines())
def test_any_mix_of_lines_gets_its_replies_in_order(
    case: tuple[list[bytes], list[tuple[int | None, str | None]], int],
) -> None:
    """docs/api.md "Framing" (SR-8.13's neighbour rule): any sequence of valid, refused and
    malformed lines on one connection, in one write and under any read budget, gets exactly
    one reply per line, in order, each with its line's id and code."""
    lines, expected, budget = case
    with tempfile.TemporaryDirectory() as folder:
        config = ServerConfig(
            Path(folder) / "api.sock",
            max_line=256,
            requests_per_call=budget,
            requests_per_turn=budget,
        )
        loop = Loop(config)
        peer = Peer(config.path)
        try:
            peer.send(b"".join(line + b"\n" for line in lines))
            replies = peer.read(loop, len(lines))
            assert [(r.get("id"), r.get("code")) for r in replies] == expected
            assert not loop.of_type(Closed)
        finally:
            peer.close()
            loop.close()


# -- a malformed e-stop or hold still stops (SR-8.13) ---------------------------------------


@pytest.mark.parametrize(
    ("line", "request_id", "code"),
    [
        (b'{"op":"estop","reason":"operator"}', None, "bad_request"),
        (b'{"op":"estop","reason":"operator","id":4}', 4, "bad_request"),
        (b'{"op":"estop","id":1.5}', None, "bad_request"),
        (b'{"op":"estop","id":"\\ud800"}', None, "bad_request"),
        (b'{"op":"estop",', None, "bad_json"),
        (b'{"op":"status","op":"estop"}', None, "bad_json"),
        (b'{"op":"estop","x":' + DEEP + b"}", None, "bad_json"),
    ],
)
def test_a_malformed_estop_is_acted_on_and_its_reply_says_what_was_wrong(
    loop: Loop, peer: Peer, line: bytes, request_id: int | None, code: str
) -> None:
    """SR-8.13: an ``estop`` with a field too many, a wrong id or broken JSON around a readable
    ``"op":"estop"`` was refused and nothing stopped; now it reaches the daemon as an e-stop
    (the operator's ``local_estop`` before hello) and the reply is its error, with the op, the
    id when valid, and ``"honoured": true``."""
    peer.send(line + b"\n")
    (reply,) = peer.read(loop)
    expected: dict[str, Any] = {"ok": False, "code": code, "op": "estop", "honoured": True}
    if request_id is not None:
        expected["id"] = request_id
    assert {k: v for k, v in reply.items() if k != "error"} == expected
    assert reply["error"].endswith("; the estop was honoured")
    (received,) = loop.of_type(Received)
    assert received.request == Estop(id=request_id)
    assert isinstance(core_event(received, 0), LocalEstop)


def test_a_malformed_hold_holds_as_the_connection_it_came_on(loop: Loop, peer: Peer) -> None:
    """SR-8.13: a ``hold`` with a wrong id reaches the daemon as that connection's hold (before
    hello: ended by its connection's end), answered with its error and ``"honoured": true``."""
    peer.send(b'{"op":"hello","name":"nav"}\n{"op":"hold","id":1.5,"why":"x"}\n')
    hello, hold = peer.read(loop, 2)
    assert hello["ok"] is True
    assert (hold["ok"], hold["code"], hold["op"], hold["honoured"]) == (
        False,
        "bad_request",
        "hold",
        True,
    )
    received = loop.of_type(Received)
    assert received[1].request == Hold()
    assert received[1].client.name == "nav"  # so it is client_hold:nav, released by nav


def test_a_malformed_estop_on_an_estop_slot_stops(loop: Loop, tmp_path: Path) -> None:
    """SR-8.13, SR-8.4 (docs/safety.md rule 1): with every ordinary slot taken, a malformed
    ``estop`` on an e-stop slot is served as the operator's e-stop; a malformed ``hold`` there
    is refused like any hold (a slot cannot hold) and the slot closed."""
    holders = [Peer(tmp_path / "api.sock") for _ in range(2)]
    slot = Peer(tmp_path / "api.sock")
    other = Peer(tmp_path / "api.sock")
    try:
        loop.until(lambda: len(loop.of_type(Accepted)) == 2)
        slot.send(b'{"op":"estop","reason":"operator","id":"s"}\n')
        (reply,) = slot.read(loop)
        assert (reply["code"], reply["id"], reply["honoured"]) == ("bad_request", "s", True)
        (received,) = loop.of_type(Received)
        assert received.request == Estop(id="s")
        assert isinstance(core_event(received, 0), LocalEstop)
        other.send(b'{"op":"hold","reason":"operator"}\n')
        (refused,) = other.read(loop)
        assert refused["code"] == "too_many_clients"
        other.wait_eof(loop)
        assert len(loop.of_type(Received)) == 1
    finally:
        for each in (*holders, slot, other):
            each.close()


@pytest.mark.parametrize(
    ("line", "expected"),
    [
        (b'{"op":"hold" , "x":1}', Hold()),
        (b'{"op":"estop","op":"hold"}', Estop()),  # both named: the e-stop wins
        (b'{"op":"\\u0065stop",NaN}', Estop()),  # an escape is the text it stands for
        (b'{"op":"estop"\xff}', Estop()),  # bytes that are not UTF-8 around it
        (b'{"op":"status","x":1}', None),
        (b'{"op":["estop"]}', None),
        (b'[{"op":"estop"}]', None),  # not an object: no op
        (b'{"a":{"op":"estop"}', None),  # not the outermost object's
        (b'{"name":"\\"op\\":\\"estop\\"",', None),  # inside a string
        (b'{"name":"op":"estop"}', None),  # "op" not in a key's place
        (b'{"op" x:"estop"}', None),  # not JSON between the key and its value
        (b'{"op":"estop', None),  # the value's string not whole
        (b"", None),
    ],
)
def test_readable_stop_reads_the_op_only_where_json_puts_it(
    line: bytes, expected: Estop | Hold | None
) -> None:
    """SR-8.13: the op of a malformed line is read as ``estop`` or ``hold`` only from the
    outermost object's key ``"op"`` and a whole string value, never from inside a string or a
    nested object; an e-stop wins over a hold."""
    assert readable_stop(line) == expected
