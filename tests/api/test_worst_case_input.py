"""Every piece of code that runs in the loop on a client's bytes costs time linear in them
(SR-10.5, docs/api.md "Limits"): lines built to be slow for it, at the line limit, against
the same at 1/16 of it.

The cost is the CPU time of this thread (``time.thread_time_ns``: what the loop would spend,
not what a busy machine withholds), the least of a few tries; linear growth is 16 times the
cost for 16 times the bytes, and the bound asserted is 64 times, so that a noisy machine
cannot fail it while a quadratic cost (256 times) does by far. The figures themselves are
``bench/client_input.py``'s (docs/performance.md "Client input").

The pieces: the framing (``LineReader``, ``ServerConnection``: a line assembled from the
socket's chunks, one byte at a time included), the server's read of one connection
(``ApiServer``: one call takes a bounded number of lines and bytes), the parser and the
SR-8.13 reader of a refused line (``parse_request``, ``readable_stop``, ``jsonscan``), the
client's name (``hello``), and the reply built from what the client sent (``views``,
``server_line``). ``names.py`` never sees a client's bytes: only the peer's uid, from the
kernel.
"""

from __future__ import annotations

import re
import socket
import time
from collections.abc import Callable, Iterator
from pathlib import Path

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from supervisord.api.connection import ServerConnection
from supervisord.api.framing import ApiError, LineReader
from supervisord.api.requests import parse_request, read_request, readable_stop
from supervisord.api.server import RECV_SIZE, ServerConfig
from supervisord.config.schema import DEFAULT_MAX_MESSAGE_BYTES
from supervisord.testkit.worst_input import LINES, serve_line
from tests.api.test_api_server import Loop, Peer

LIMIT = DEFAULT_MAX_MESSAGE_BYTES  # the default line limit, newline included (64 KiB)
LONG = LIMIT - 1  # the longest line under it, without its newline
SHORT = LONG // 16
LINEAR_BOUND = 64  # the cost ratio allowed for 16 times the bytes (linear: 16; quadratic: 256)


def cost_ns(action: Callable[[], object], tries: int) -> int:
    """The least CPU time of this thread ``action`` took over ``tries`` runs."""
    best = None
    for _ in range(tries):
        start = time.thread_time_ns()
        action()
        took = time.thread_time_ns() - start
        best = took if best is None else min(best, took)
    assert best is not None
    return max(best, 1)


def assert_linear(name: str, action: Callable[[int], Callable[[], object]]) -> None:
    """``action(size)`` gives the work for ``size`` bytes; its cost at ``LONG`` bytes must be
    within ``LINEAR_BOUND`` times its cost at ``SHORT``."""
    short = cost_ns(action(SHORT), tries=15)
    long = cost_ns(action(LONG), tries=5)
    assert long < LINEAR_BOUND * short, (
        f"{name}: {long / 1e3:.0f} us for {LONG} bytes, {short / 1e3:.0f} us for {SHORT}: "
        f"{long / short:.0f} times for 16 times the bytes"
    )


# -- break 1: the SR-8.13 reader on a string that never closes ------------------------------


def test_the_op_of_a_line_of_escaped_quotes_is_looked_for_in_linear_time() -> None:
    """SR-10.5, SR-8.13: ``"\\"\\"\\"...`` (a quote, then escaped quotes, never closed) cost
    O(n^2) to look for a readable ``estop`` in: every quote began a scan of the rest of the
    line (4 KiB 36 ms, 64 KiB about 10 s, in the loop, for every refused line); now each byte
    is looked at a bounded number of times."""
    assert_linear("readable_stop", lambda n: lambda: readable_stop(LINES["escaped quotes"](n)))


# -- the whole line path: parser, SR-8.13 reader, reply --------------------------------------


@pytest.mark.parametrize("family", list(LINES))
def test_a_worst_case_line_costs_time_linear_in_its_bytes(family: str) -> None:
    """SR-10.5: what the server does with one line it read (the parser, the SR-8.13 reader of
    a refused line, the reply built and encoded) costs time linear in the line, for every
    family of lines built to be slow: strings that never close, nesting, long runs of one
    bracket, comma or quote pair, many keys in an op's place, escapes, unknown keys, long
    numbers, lone surrogates in a key, bytes that are not UTF-8."""
    make = LINES[family]
    assert_linear(family, lambda n: lambda: serve_line(make(n)))


@pytest.mark.parametrize("family", list(LINES))
def test_the_reply_to_a_worst_case_line_is_short(family: str) -> None:
    """SR-10.5, SR-8.7: the reply quotes at most a bounded part of what the client sent, so
    the output a line costs does not grow with it (one reply per line: docs/api.md)."""
    reply = serve_line(LINES[family](LONG))
    assert reply.endswith(b"\n")
    assert len(reply) < 600, reply[:200]


def test_a_long_name_in_a_hello_is_refused_at_once() -> None:
    """SR-10.5: a client's name is checked against a bounded pattern (at most 32 characters),
    whatever its length."""
    assert_linear(
        "hello", lambda n: lambda: serve_line(b'{"op":"hello","name":"' + b"a" * n + b'"}')
    )


_SAMPLES = [
    b'{"op":"estop"}',
    b'{"op":"estop","id":1.5}',
    b'{"op":"hold","x":1}',
    b'{"op":"status","id":7}',
    b'{"op":"estop",',
    b"[1]",
    b"",
]


@pytest.mark.parametrize("line", [*_SAMPLES, *(make(300) for make in LINES.values())])
def test_the_server_reads_a_line_once_as_parse_request_and_readable_stop_do(line: bytes) -> None:
    """SR-10.5, SR-8.13: ``read_request``, which parses a line once, gives what the parser
    and the SR-8.13 reader give: the request, or the refusal and the stop it still asks for."""
    try:
        expected: tuple[object, object] = (parse_request(line), None)
    except ApiError as refused:
        expected = (readable_stop(line), refused.reply())
    request, error = read_request(line)
    assert (request, None if error is None else error.reply()) == expected


# -- the SR-8.13 reader is the one it replaced, only linear --------------------------------

_OLD_STRING = re.compile(rb'"(?:[^"\\]|\\.)*"')
_OLD_TOKEN = re.compile(rb'"(?:[^"\\]|\\.)*"|[{}\[\]:,]')
_OLD_GAP = re.compile(rb"[ \t\r\n]*")


def _old_op_in_broken(line: bytes) -> str | None:
    """The SR-8.13 reader before it was linear: every token, from a search of the line."""
    import json  # noqa: PLC0415 -- only the oracle needs it

    def string(token: bytes) -> str | None:
        try:
            value = json.loads(token)
        except ValueError:
            return None
        return value if isinstance(value, str) else None

    tokens = list(_OLD_TOKEN.finditer(line))
    found: set[str] = set()
    depth: list[bytes] = []
    for i, token in enumerate(tokens):
        text = token.group()
        if text in (b"{", b"["):
            depth.append(text)
        elif text in (b"}", b"]"):
            if depth:
                depth.pop()
        elif (
            text.startswith(b'"')
            and depth == [b"{"]
            and i >= 1
            and tokens[i - 1].group() in (b"{", b",")
            and i + 2 < len(tokens)
            and tokens[i + 1].group() == b":"
            and tokens[i + 2].group().startswith(b'"')
            and all(
                _OLD_GAP.fullmatch(line, a.end(), b.start())
                for a, b in zip(tokens[i - 1 : i + 2], tokens[i : i + 3], strict=True)
            )
            and string(text) == "op"
        ):
            op = string(tokens[i + 2].group())
            if op in ("estop", "hold"):
                found.add(op)
    return "estop" if "estop" in found else ("hold" if found else None)


_PIECES = [
    b'"', b"\\", b"{", b"}", b"[", b"]", b":", b",", b" ", b"\n", b"\t", b"x", b"op", b"\xff",
    b'"op"', b'"estop"', b'"hold"', b'"\\u006fp"', b'"\\u006F\\u0070"', b'"\\u0065stop"',
    b'"ho\\u006Cd"', b'"\\u0068old"', b"\\u006f", b'\\"', b'"status"',
]  # fmt: skip


@settings(max_examples=3000, deadline=None)
@given(
    st.sampled_from([b"", b"{", b'{"op":"estop"', b'{"op":"hold"', b'{"a":1,', b"[{"]),
    st.lists(st.sampled_from(_PIECES), max_size=16),
)
def test_the_linear_reader_reads_what_the_quadratic_one_read(
    head: bytes, pieces: list[bytes]
) -> None:
    """SR-8.13 unchanged: on any line (here: short ones made of the pieces that matter, a
    newline and unclosed strings among them), the linear reader finds the op the old one
    found, and the nesting check sees the brackets the old one saw."""
    # Here, not at the top: the rest of this file runs against any version of the reader.
    from supervisord.api.jsonscan import brackets_outside_strings, op_in_broken  # noqa: PLC0415

    line = head + b"".join(pieces)
    assert op_in_broken(line) == _old_op_in_broken(line)
    brackets = bytes(sorted(set(range(256)) - set(b"{}[]")))
    assert brackets_outside_strings(line) == _OLD_STRING.sub(b"", line).translate(None, brackets)


# -- the framing: a line assembled from the socket's chunks ---------------------------------


def _one_byte_at_a_time(size: int) -> Callable[[], object]:
    data = [bytes([byte]) for byte in LINES["escaped quotes"](size)] + [b"\n"]

    def feed() -> None:
        reader = LineReader(max_line=LIMIT)
        for chunk in data:
            reader.feed(chunk)

    return feed


def test_a_line_sent_one_byte_at_a_time_is_assembled_in_linear_time() -> None:
    """SR-10.5: the reader appends each chunk and looks for the newline in the chunk alone,
    never in what it holds: a 64 KiB line sent a byte per ``send`` costs 16 times a 4 KiB one,
    not 256."""
    assert_linear("LineReader", _one_byte_at_a_time)


def test_a_connection_cuts_many_lines_in_linear_time() -> None:
    """SR-10.5: many short lines (blank ones and broken ones) in one chunk become their events
    in time linear in the chunk."""

    def cut(size: int) -> Callable[[], object]:
        data = (b"\n" + b"x\n" * 10) * (size // 21)
        return lambda: ServerConnection(max_line=LIMIT).receive_data(data)

    assert_linear("ServerConnection", cut)


def test_an_endless_line_is_discarded_in_linear_time() -> None:
    """SR-10.5: the bytes of a line past the limit are counted and dropped, a chunk at a time,
    until the flood limit: never held, never searched again."""

    def discard(size: int) -> Callable[[], object]:
        chunks = [b"x" * 64] * (16 * size // 64)

        def feed() -> None:
            reader = LineReader(max_line=256, max_discard=1 << 30)
            for chunk in chunks:
                reader.feed(chunk)

        return feed

    assert_linear("LineReader discarding", discard)


# -- the server's read of one connection: bounded per call ----------------------------------


@pytest.fixture
def loop(tmp_path: Path) -> Iterator[Loop]:
    the_loop = Loop(ServerConfig(tmp_path / "api.sock", max_line=LIMIT))
    yield the_loop
    the_loop.close()


def test_one_call_reads_a_bounded_number_of_lines_and_bytes(loop: Loop, tmp_path: Path) -> None:
    """SR-10.5, SR-10.1: a client that pipelines 64 broken lines has at most
    ``requests_per_call`` of them read in one ``handle`` call (8), and what one call parses
    is at most one line at the limit and ``RECV_SIZE`` bytes besides (here 16 KiB of 2 KiB
    lines); the rest waits in the socket for the next turns, and every line is answered."""
    peer = Peer(tmp_path / "api.sock")
    try:
        loop.until(lambda: bool(loop.server.clients()))
        line = LINES["escaped quotes"](2047) + b"\n"
        peer.sock.setblocking(True)
        peer.sock.sendall(line * 64)
        peer.sock.setblocking(False)
        fd = max(fd for fd, _ in loop.server.descriptors(loop.clock()))  # the newest
        answered = calls = 0
        while answered < 64 and calls < 64:
            loop.server.descriptors(loop.clock())  # a new turn, a new budget
            loop.server.handle(fd, True, False, loop.clock())
            loop.take()
            calls += 1
            peer.has(64)  # takes in what the server sent
            now = peer.buffer.count(b"\n")
            assert now - answered <= min(8, RECV_SIZE // len(line)), (now, answered)
            answered = now
        assert answered == 64
    finally:
        peer.close()


def test_a_line_sent_one_byte_at_a_time_to_the_server_costs_linear_time(tmp_path: Path) -> None:
    """SR-10.5: on real sockets, a line sent one byte per ``send``, the server reading after
    each: the server's work (its ``handle`` calls, timed on this thread) grows with the bytes,
    not with their square (each read peeks at what the socket holds, never at what the
    connection holds)."""

    def server_cost(size: int) -> int:
        loop = Loop(ServerConfig(tmp_path / f"api{size}.sock", max_line=LIMIT))
        sender = socket.socket(socket.AF_UNIX, socket.SOCK_STREAM)
        try:
            sender.connect(str(tmp_path / f"api{size}.sock"))
            loop.until(lambda: bool(loop.server.clients()))
            fd = max(fd for fd, _ in loop.server.descriptors(loop.clock()))
            spent = 0
            for byte in LINES["escaped quotes"](size) + b"\n":
                sender.send(bytes([byte]))
                loop.server.descriptors(loop.clock())
                start = time.thread_time_ns()
                loop.server.handle(fd, True, False, loop.clock())
                spent += time.thread_time_ns() - start
                loop.take()
            replies = b""
            sender.settimeout(5)
            while b"\n" not in replies:
                replies += sender.recv(4096)
            assert b"bad_json" in replies
            return spent
        finally:
            sender.close()
            loop.close()

    short = min(server_cost(SHORT // 4) for _ in range(3))
    long = server_cost(LONG // 4)
    assert long < LINEAR_BOUND * short, (long, short)
