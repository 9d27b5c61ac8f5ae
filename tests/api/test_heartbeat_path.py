"""A client's heartbeat costs the server its line and nothing more (SR-9.4), and decides
exactly what it decided before (SR-8.1, SR-8.16).

- the plain heartbeat's reader (``requests._plain_heartbeat``) gives the request, or the
  refusal, that the full field reader gives, for every shape of heartbeat object;
- a heartbeat's line is read and answered without building a JSON decoder or encoder;
- a turn with named clients connected and nothing new looks at no connection one by one,
  and hands the loop the same watch list as the turn before, which is the list the server's
  state calls for, turn after turn, as clients come, go and leave output waiting.
"""

from __future__ import annotations

import json
import socket
from collections.abc import Callable, Iterator
from pathlib import Path
from typing import Any

import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from supervisord.api import requests
from supervisord.api.framing import ApiError
from supervisord.api.ops import ApiRequest
from supervisord.api.requests import read_request
from supervisord.api.server import Received, ServerConfig
from tests.api.test_api_server import Loop, Peer

# -- the plain heartbeat's reader against the full one --------------------------------------


def full_reader(obj: dict[str, Any]) -> ApiRequest | ApiError:
    """What ``requests._request`` answered for a heartbeat object before the plain reader:
    the id, then the field reader (``_heartbeat``) and its check of every field."""
    try:
        request_id = requests._request_id(obj)
        fields = requests._Fields(obj, "heartbeat", request_id)
        request = requests._heartbeat(fields)
        fields.finish()
    except ApiError as error:
        return error
    return request


def plain_reader(obj: dict[str, Any]) -> ApiRequest | ApiError:
    try:
        return requests._request(obj)
    except ApiError as error:
        return error


def same(a: ApiRequest | ApiError, b: ApiRequest | ApiError) -> bool:
    if isinstance(a, ApiError) and isinstance(b, ApiError):
        return (a.code, a.message, a.op, a.request_id) == (b.code, b.message, b.op, b.request_id)
    return a == b


values = st.one_of(
    st.none(),
    st.booleans(),
    st.integers(min_value=-(2**64), max_value=2**64),
    st.sampled_from([0, 1, 2**31, 2**32 - 1, 2**32, -1, 2**63 - 1, 2**63, -(2**63)]),
    st.floats(allow_nan=False, allow_infinity=False),
    st.text(max_size=70),
    st.lists(st.integers(), max_size=2),
    st.dictionaries(st.text(max_size=3), st.integers(), max_size=2),
)


@settings(max_examples=600, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(
    id_=st.one_of(st.just(None), values),
    has_id=st.booleans(),
    progress=values,
    has_progress=st.booleans(),
    extra=st.dictionaries(
        st.sampled_from(["x", "name", "progres", "Progress", "nonzero"]), values, max_size=2
    ),
)
def test_the_plain_heartbeat_reads_as_the_full_reader(
    id_: object, has_id: bool, progress: object, has_progress: bool, extra: dict[str, object]
) -> None:
    """SR-8.16, SR-8.7: every heartbeat object, well-formed or not (an id of every type, a
    progress of every type and range, fields more), is the same request or the same refusal
    (code, words, op, id) whichever reader takes it."""
    obj: dict[str, Any] = {"op": "heartbeat", **extra}
    if has_id:
        obj["id"] = id_
    if has_progress:
        obj["progress"] = progress
    assert same(plain_reader(obj), full_reader(obj))
    # And through the line, as the server reads it.
    line = json.dumps(obj).encode()
    request, error = read_request(line)
    expected = full_reader(obj)
    assert same(request if error is None else error, expected)  # type: ignore[arg-type]


@pytest.mark.parametrize(
    ("obj", "expected"),
    [
        ({"op": "heartbeat"}, requests.Heartbeat()),
        ({"op": "heartbeat", "id": 3}, requests.Heartbeat(id=3)),
        ({"op": "heartbeat", "progress": 0}, requests.Heartbeat(0)),
        (
            {"op": "heartbeat", "progress": 2**32 - 1, "id": "a"},
            requests.Heartbeat(2**32 - 1, id="a"),
        ),
    ],
)
def test_plain_heartbeats_are_read(obj: dict[str, Any], expected: ApiRequest) -> None:
    assert plain_reader(obj) == expected == full_reader(obj)


@pytest.mark.parametrize(
    "obj",
    [
        {"op": "heartbeat", "progress": True},
        {"op": "heartbeat", "progress": 2**32},
        {"op": "heartbeat", "progress": -1},
        {"op": "heartbeat", "progress": 1.0},
        {"op": "heartbeat", "progress": None},
        {"op": "heartbeat", "extra": 1},
        {"op": "heartbeat", "id": True},
    ],
)
def test_heartbeats_out_of_shape_are_refused_as_before(obj: dict[str, Any]) -> None:
    """The refusals of the field reader, word for word (``bad_request``, SR-8.7)."""
    refused = plain_reader(obj)
    assert isinstance(refused, ApiError)
    assert same(refused, full_reader(obj))


# -- no decoder and no encoder per line -------------------------------------------------------


@pytest.fixture
def loop(tmp_path: Path) -> Iterator[Loop]:
    the_loop = Loop(ServerConfig(tmp_path / "api.sock", max_clients=4))
    yield the_loop
    the_loop.close()


def test_a_heartbeat_builds_no_json_decoder_or_encoder(
    loop: Loop, peers: Callable[[], Peer], monkeypatch: pytest.MonkeyPatch
) -> None:
    """SR-9.4: a heartbeat's line is parsed by the one decoder and its reply written by the one
    encoder (``json.loads`` and ``json.dumps`` with options build one per call); the reply's
    bytes are those docs/api.md gives."""
    peer = peers()
    assert peer.ask(loop, {"op": "hello", "name": "planner"}) == {"ok": True, "op": "hello"}
    built: list[str] = []
    for kind in (json.JSONDecoder, json.JSONEncoder):
        original = kind.__init__

        def counting(self: Any, *args: Any, _original: Any = original, **kwargs: Any) -> None:
            built.append(type(self).__name__)
            _original(self, *args, **kwargs)

        monkeypatch.setattr(kind, "__init__", counting)
    for beat in range(5):
        peer.send(b'{"op":"heartbeat"}\n')
        loop.until(lambda: peer.has(1))
        assert peer.buffer == b'{"ok":true,"op":"heartbeat"}\n'
        peer.buffer = b""
        peer.send(b'{"op":"heartbeat","id":%d,"progress":%d}\n' % (beat, beat))
        loop.until(lambda: peer.has(1))
        assert peer.buffer == b'{"ok":true,"op":"heartbeat","id":%d}\n' % beat
        peer.buffer = b""
    assert built == []
    assert [type(r.request).__name__ for r in loop.of_type(Received)][-10:] == ["Heartbeat"] * 10


# -- a turn looks at no connection one by one -------------------------------------------------


class CountingDict(dict):  # type: ignore[type-arg]
    """The server's connections, counting each look at them all."""

    looks = 0

    def values(self) -> Any:
        CountingDict.looks += 1
        return super().values()


def expected_watch(loop: Loop) -> list[tuple[int, bool]]:
    """What the server must watch, from its state: its listening sockets and name lookups,
    and each connection, for writing while output waits for it."""
    server = loop.server
    watched = server._sockets_watched()
    watched += [(fd, bool(conn.protocol.outgoing)) for fd, conn in server._by_fd.items()]
    return watched


def test_a_quiet_turn_with_named_clients_looks_at_none_of_them(
    loop: Loop, peers: Callable[[], Peer]
) -> None:
    """SR-9.4: with named clients connected and nothing new, a turn's descriptors, deadline
    and subscription checks look at no connection one by one, and the watch list is the
    turn before's, the same object (the loop compares it and registers nothing)."""
    clients = [peers() for _ in range(3)]
    for index, peer in enumerate(clients):
        assert peer.ask(loop, {"op": "hello", "name": f"c{index}"})["ok"] is True
    server = loop.server
    loop.turn()
    before = server.descriptors(loop.clock())
    assert before == expected_watch(loop)
    server._connections = CountingDict(server._connections)
    CountingDict.looks = 0
    for _ in range(10):
        assert server.descriptors(loop.clock()) is before
        assert server.next_deadline() is None
        assert not server.subscribed(requests.Topic.STATE)
    assert CountingDict.looks == 0


def test_the_watch_list_follows_clients_and_waiting_output(
    loop: Loop, peers: Callable[[], Peer]
) -> None:
    """SR-10.1, SR-8.4: the list kept from turn to turn is, every turn, the one the server's
    state calls for: a client that comes, a client that leaves output waiting (it does not
    read: watched for writing until the output left), a client that goes."""
    server = loop.server

    def turn() -> list[tuple[int, bool]]:
        loop.turn()
        watched = server.descriptors(loop.clock())
        assert watched == expected_watch(loop)
        return watched

    first = peers()
    first.ask(loop, {"op": "hello", "name": "a"})
    assert len(turn()) == len(server._sockets_watched()) + 1
    slow = peers()
    slow.ask(loop, {"op": "hello", "name": "b"})
    slow.sock.setsockopt(socket.SOL_SOCKET, socket.SO_RCVBUF, 4096)
    assert slow.ask(loop, {"op": "subscribe", "topics": ["state"]})["ok"] is True
    assert server.subscribed(requests.Topic.STATE)
    # Fill the slow client's socket with pushes it does not read: its output waits.
    (conn,) = [c for c in server._connections.values() if c.info.name == "b"]
    line = b'{"event":"state","pad":"' + b"x" * 2000 + b'"}\n'
    for _ in range(200):
        server._queue(conn, line)
        if conn.protocol.outgoing:
            break
    assert conn.protocol.outgoing
    watched = turn()
    assert (conn.sock.fileno(), True) in watched
    slow._pump()  # it reads: the output leaves on its writable turns
    for _ in range(200):
        slow._pump()
        turn()
        if not conn.protocol.outgoing:
            break
    assert not conn.protocol.outgoing
    assert (conn.sock.fileno(), False) in turn()
    slow.close()
    loop.until(lambda: len(server._by_fd) == 1)
    assert not server.subscribed(requests.Topic.STATE)  # its subscription went with it
    assert len(turn()) == len(server._sockets_watched()) + 1
    first.close()
    loop.until(lambda: not server._by_fd)
    turn()
