"""One connection's two ends against each other, without a socket (docs/api.md "Framing"):
the client library's :class:`ClientConnection` and the server's :class:`ServerConnection`,
bytes handed across by the test, the server's requests read by the daemon's own parser."""

from __future__ import annotations

import json
import random

import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from supervisord.api.connection import (
    BlankLine,
    ClientConnection,
    ClientEvent,
    ErrorWithoutRequest,
    Flooded,
    LineRefused,
    Place,
    ProtocolError,
    PushReceived,
    ReplyReceived,
    RequestLine,
    ServerConnection,
    server_line,
)
from supervisord.api.framing import ApiError, ErrorCode
from supervisord.api.ops import (
    ApiRequest,
    Estop,
    Heartbeat,
    Hello,
    Hold,
    Release,
    Status,
    Subscribe,
    Topic,
)
from supervisord.api.pushes import OtherPush
from supervisord.api.requests import honoured_error, parse_request, readable_stop
from supervisord.api.views import ok_reply
from supervisord.release import Request
from tests.api.samples import status_reply
from tests.api.test_api_properties import LINES


def serve_line(event: RequestLine) -> bytes:
    """What the server answers a request line with, as :mod:`supervisord.api.server` does
    when the daemon says ok: the plain ok (a whole ``status``), the parser's refusal, or a
    malformed stop's error with ``honoured`` (SR-8.13)."""
    try:
        request = parse_request(event.line)
    except ApiError as error:
        stop = readable_stop(event.line)
        return server_line(error if stop is None else honoured_error(error, stop))
    if isinstance(request, Status):  # the daemon's status, as tests/api/samples.py has it
        return server_line(status_reply(request_id=request.id))
    return server_line(ok_reply(request))


def answer_all(server: ServerConnection, places: list[tuple[Place, bytes]], seed: int) -> bytes:
    """Answer every place in a shuffled order; the bytes the server would send."""
    order = list(places)
    random.Random(seed).shuffle(order)
    for place, line in order:
        assert server.answer(place, line)
    out = bytes(server.outgoing)
    server.sent(len(out))
    return out


def served(server: ServerConnection, data: bytes) -> list[tuple[Place, bytes]]:
    """The places of the replies ``data`` asks for, each with its reply line."""
    places = []
    for event in server.receive_data(data):
        if isinstance(event, RequestLine):
            places.append((event.place, serve_line(event)))
        elif isinstance(event, LineRefused):
            places.append((event.place, server_line(event.error)))
    return places


def drain(client: ClientConnection, data: bytes) -> list[ClientEvent]:
    client.receive_data(data)
    events: list[ClientEvent] = []
    while (event := client.next_event()) is not None:
        events.append(event)
    return events


REQUESTS: list[ApiRequest] = [
    Hello("planner", id=1),
    Status(id="two"),
    Heartbeat(),
    Estop(id=4),
    Subscribe(frozenset({Topic.STATE})),
    Release(Request.ESTOP, id=6),
]


def test_pipelined_replies_answered_out_of_order_reach_the_client_in_request_order() -> None:
    """SR-8.13: requests pipelined on one connection and answered in any order leave the
    server in request order, and the client pairs each reply with its own request."""
    for seed in range(20):
        client, server = ClientConnection(), ServerConnection()
        data = b"".join(client.send(request) for request in REQUESTS)
        assert client.waiting == len(REQUESTS)
        events = drain(client, answer_all(server, served(server, data), seed))
        assert all(isinstance(e, ReplyReceived) for e in events)
        paired = [
            (e.request, e.reply.json()["op"])
            for e in events
            if isinstance(e, ReplyReceived) and not isinstance(e.reply, ApiError)
        ]
        assert paired == [(r, r.OP) for r in REQUESTS]
        assert client.waiting == 0


def test_a_reply_waits_for_every_earlier_one_however_it_was_answered() -> None:
    """SR-8.13: a refused line's reply and a later ok wait for the reply of the request
    before them; nothing leaves until the front is answered."""
    client, server = ClientConnection(), ServerConnection(max_line=256)
    data = client.send(Status()) + b"x" * 300 + b"\n" + client.send(Heartbeat())
    events = server.receive_data(data)
    assert [type(e) for e in events] == [RequestLine, LineRefused, RequestLine]
    first, refused, last = events
    assert isinstance(refused, LineRefused)
    assert refused.error.code == ErrorCode.TOO_LONG
    assert isinstance(last, RequestLine)
    assert isinstance(first, RequestLine)
    assert server.answer(last.place, serve_line(last))
    assert server.answer(refused.place, server_line(refused.error))
    assert bytes(server.outgoing) == b""
    assert server.answer(first.place, serve_line(first))
    replies = [json.loads(line) for line in bytes(server.outgoing).splitlines()]
    assert [(r["ok"], r.get("op"), r.get("code")) for r in replies] == [
        (True, "status", None),
        (False, None, "too_long"),
        (True, "heartbeat", None),
    ]


def test_pushes_between_replies_are_told_apart_and_keep_the_pairing() -> None:
    """SR-8.2: a push sent between replies is a push to the client, and the replies around
    it stay paired with their requests."""
    client, server = ClientConnection(), ServerConnection()
    data = client.send(Status()) + client.send(Hold())
    [(first, first_line), (second, second_line)] = served(server, data)
    assert server.answer(second, second_line)
    assert server.send(server_line(OtherPush("newer", {"what": "a newer daemon's push"})))
    assert server.answer(first, first_line)
    events = drain(client, bytes(server.outgoing))
    assert [type(e) for e in events] == [PushReceived, ReplyReceived, ReplyReceived]
    assert [e.request for e in events if isinstance(e, ReplyReceived)] == [Status(), Hold()]


def test_the_server_end_refuses_an_endless_line_with_flood() -> None:
    """SR-8.7: a line longer than the discard limit is one ``too_long``, then ``flood``, and
    nothing after it is read; blank lines get no place (docs/api.md "Framing")."""
    server = ServerConnection(max_line=256, max_discard=1024)
    assert [type(e) for e in server.receive_data(b"\n\r\n")] == [BlankLine, BlankLine]
    events = server.receive_data(b"z" * 2000)
    assert [type(e) for e in events] == [LineRefused, Flooded]
    assert isinstance(events[1], Flooded)
    assert events[1].error.code == ErrorCode.FLOOD
    assert server.receive_data(b'\n{"op":"status"}\n') == []  # flood is said once


def test_the_server_end_says_when_its_output_passes_the_limit() -> None:
    """SR-8.4: the output held for a client that does not read, replies held for an earlier
    one included, is measured against ``max_output``; past it the server ends the client."""
    server = ServerConnection(max_output=4096)
    [(first, _), (second, _)] = served(server, b'{"op":"status"}\n{"op":"status"}\n')
    assert server.answer(second, b"r" * 4000 + b"\n")  # held for the first: counted
    assert not server.send(b"p" * 200 + b"\n")
    server.clear()
    assert server.send(b"p" * 200 + b"\n")
    assert server.answer(first, b"late\n")  # a place dropped with the connection: no effect


def test_the_client_end_refuses_what_docs_api_md_does_not_allow() -> None:
    """SR-8.13: a reply that echoes another request's id, a reply to no request, a line that
    is not JSON or one over the client's limit is a protocol error, never a reply taken as
    another request's; an error reply with no request is the server's last words."""
    client = ClientConnection(max_line=1024)
    client.send(Heartbeat(id=1))
    with pytest.raises(ProtocolError, match="where id 1 was due"):
        drain(client, b'{"ok":true,"op":"heartbeat","id":2}\n')
    with pytest.raises(ProtocolError, match="without a request"):
        drain(client, b'{"ok":true,"op":"heartbeat"}\n')
    last = drain(client, b'{"ok":false,"code":"too_many_clients","error":"full"}\n')
    assert [type(e) for e in last] == [ErrorWithoutRequest]
    with pytest.raises(ProtocolError, match="not JSON"):
        drain(ClientConnection(), b"[1,\n")
    with pytest.raises(ProtocolError, match="too long"):
        drain(ClientConnection(max_line=1024), b"x" * 1025)


def test_the_client_end_reads_the_last_error_a_closing_server_sent() -> None:
    """SR-8.4: the ``too_many_clients`` line a server sent before it closed is found among
    the lines held, past lines that cannot be read."""
    client = ClientConnection()
    client.receive_data(b'garbage\n{"ok":false,"code":"too_many_clients","error":"full"}\n')
    error = client.last_error()
    assert error is not None
    assert error.code == ErrorCode.TOO_MANY_CLIENTS


@settings(
    max_examples=200,
    deadline=None,
    suppress_health_check=[HealthCheck.too_slow, HealthCheck.data_too_large],
)
@given(
    st.lists(LINES, min_size=1, max_size=8),
    st.lists(st.integers(1, 64), min_size=1, max_size=8),
    st.integers(0, 1 << 16),
)
def test_arbitrary_lines_in_any_pieces_get_one_reply_each_in_order(
    lines: list[bytes], cuts: list[int], seed: int
) -> None:
    """SR-8.7 and SR-8.13: the API's arbitrary request lines (tests/api/test_api_properties.py),
    handed to the server's end in arbitrary pieces and answered in any order, come back as
    exactly one valid JSON reply per non-blank line, in the order the lines were sent."""
    server = ServerConnection(max_line=4096)
    stream = b"".join(line + b"\n" for line in lines)
    places: list[tuple[Place, bytes]] = []
    at = 0
    for cut in (cuts * len(stream))[: len(stream)]:
        if at >= len(stream):
            break
        places += served(server, stream[at : at + cut])
        at += cut
    expected = sum(1 for line in lines if line.strip() and len(line) < 4096)
    too_long = sum(1 for line in lines if len(line) >= 4096)
    assert len(places) == expected + too_long
    out = answer_all(server, places, seed)
    replies = [json.loads(line) for line in out.splitlines()]
    assert replies == [json.loads(line) for _, line in places]
    assert all(isinstance(r["ok"], bool) for r in replies)
