"""The API server's limits that keep the stop path open (SR-8.4, SR-8.6, SR-10.1;
docs/api.md "Limits"): e-stop slots past ``max_clients``, the read budget per connection and
per turn, clients bound to a user, and the socket file of a start that failed."""

from __future__ import annotations

import grp
import json
import os
import socket
import subprocess
import sys
import time
from collections.abc import Callable, Iterator
from pathlib import Path
from typing import Any

import pytest

from supervisord.api.requests import Estop, Hello
from supervisord.api.server import (
    Accepted,
    ApiServer,
    Closed,
    CloseReason,
    Received,
    ServerConfig,
    ServerError,
    core_event,
)
from supervisord.safety.config import ClientSpec, SafetyConfig
from supervisord.safety.core import SafetyCore
from supervisord.safety.decision import RefusalReason
from supervisord.safety.events import ClientConnected, ClientHello
from supervisord.testkit.daemon import MINIMAL_CONFIG
from tests.api.test_api_listener import Judged
from tests.api.test_api_server import NOBODY, Loop, Peer, shared_dir  # noqa: F401 -- a fixture

REPO = Path(__file__).parents[2]


@pytest.fixture
def made(tmp_path: Path) -> Iterator[Callable[..., Loop]]:
    """Loops over ``tmp_path/api.sock`` built from ServerConfig keywords, closed at the end."""
    loops: list[Loop] = []

    def make(**options: Any) -> Loop:
        loops.append(Loop(ServerConfig(tmp_path / "api.sock", **options)))
        return loops[-1]

    yield make
    for each in loops:
        each.close()


@pytest.fixture
def peers(tmp_path: Path) -> Iterator[Callable[[], Peer]]:
    opened: list[Peer] = []

    def make() -> Peer:
        opened.append(Peer(tmp_path / "api.sock"))
        return opened[-1]

    yield make
    for peer in opened:
        peer.close()


def pipeline(count: int) -> bytes:
    return b"".join(b'{"op":"status","id":%d}\n' % i for i in range(count))


# -- e-stop slots ---------------------------------------------------------------------------


def test_every_ordinary_slot_taken_an_estop_still_gets_through(
    made: Callable[..., Loop], peers: Callable[[], Peer]
) -> None:
    """With max_clients idle connections open, one more connection may still send estop and
    status (an e-stop slot), and its estop becomes the core's local e-stop."""
    loop = made(max_clients=3)
    for _ in range(3):
        peers()
    loop.until(lambda: len(loop.of_type(Accepted)) == 3)
    operator = peers()
    assert operator.ask(loop, {"op": "estop"})["ok"] is True
    assert operator.ask(loop, {"op": "status"})["ok"] is True
    estop = [r for r in loop.of_type(Received) if isinstance(r.request, Estop)]
    assert len(estop) == 1
    assert type(core_event(estop[0], 1)).__name__ == "LocalEstop"


def test_an_estop_slot_refuses_anything_but_estop_and_status(
    made: Callable[..., Loop], peers: Callable[[], Peer]
) -> None:
    """On an e-stop slot a hello (or any request other than estop and status) is answered
    too_many_clients and the connection is closed: a slot is no way in for a client."""
    loop = made(max_clients=2)
    peers(), peers()
    loop.until(lambda: len(loop.of_type(Accepted)) == 2)
    extra = peers()
    reply = extra.ask(loop, {"op": "hello", "name": "nav"})
    assert (reply["ok"], reply["code"], reply["op"]) == (False, "too_many_clients", "hello")
    extra.wait_eof(loop)
    assert not [r for r in loop.of_type(Received) if isinstance(r.request, Hello)]
    assert len(loop.of_type(Accepted)) == 2  # an e-stop slot is not a client of the core


def test_an_idle_estop_slot_is_closed(made: Callable[..., Loop], peers: Callable[[], Peer]) -> None:
    """An e-stop slot that sends nothing for slot_idle_ms gets too_many_clients and is closed,
    so idle connections cannot keep the reserve.

    Timed from the rule alone: the slot is accepted (and its idle time starts) in a turn after
    ``t0``, so it cannot be closed before ``t0`` + slot_idle_ms, however busy the machine; no
    upper bound but the loop's own (``until`` fails a slot that is never closed)."""
    loop = made(max_clients=1, slot_idle_ms=200)
    peers()
    loop.until(lambda: len(loop.of_type(Accepted)) == 1)
    extra = peers()
    t0 = time.monotonic_ns()
    (reply,) = extra.read(loop)
    assert reply["code"] == "too_many_clients"
    extra.wait_eof(loop)
    assert time.monotonic_ns() - t0 >= 200 * 1_000_000


def test_past_every_slot_a_connection_is_refused(
    made: Callable[..., Loop], peers: Callable[[], Peer]
) -> None:
    """With the ordinary slots and the e-stop slots all taken by admins, the next connection
    gets too_many_clients at once."""
    loop = made(max_clients=1, reserved_slots=2)
    held = [peers() for _ in range(3)]
    loop.until(lambda: len(loop.of_type(Accepted)) == 1)
    for peer in held[1:]:
        assert peer.ask(loop, {"op": "status"})["ok"] is True
    extra = peers()
    (reply,) = extra.read(loop)
    assert reply["code"] == "too_many_clients"
    extra.wait_eof(loop)


def hold_connections_as_nobody(path: Path, count: int) -> tuple[int, int]:
    """Fork a child that becomes nobody, connects ``count`` times and waits for its stdin
    pipe to close; returns (pid, write end of that pipe)."""
    read_end, write_end = os.pipe()
    pid = os.fork()
    if pid == 0:
        code = 1
        try:
            os.close(write_end)
            os.setgroups([])
            os.setgid(NOBODY)
            os.setuid(NOBODY)
            held = []
            for _ in range(count):
                sock = socket.socket(socket.AF_UNIX, socket.SOCK_STREAM)
                sock.connect(str(path))
                held.append(sock)
            os.read(read_end, 1)
            code = 0
        finally:
            os._exit(code)
    os.close(read_end)
    return pid, write_end


def test_an_admin_evicts_a_non_admin_from_a_full_reserve(
    shared_dir: Path,  # noqa: F811 -- the fixture of test_api_server
) -> None:
    """When every ordinary and e-stop slot is taken and programs that are not admins hold
    e-stop slots, an admin's connection takes the oldest of those slots (evicted) and its
    estop gets through."""
    nogroup = grp.getgrgid(NOBODY).gr_name
    path = shared_dir / "api.sock"
    loop = Loop(ServerConfig(path, group=nogroup, max_clients=2, reserved_slots=2))
    pid, release = hold_connections_as_nobody(path, 4)
    try:
        loop.until(lambda: len(loop.of_type(Accepted)) == 2)
        for _ in range(20):
            loop.turn(0.01)
        operator = Peer(path)
        try:
            assert operator.ask(loop, {"op": "estop"})["ok"] is True
        finally:
            operator.close()
    finally:
        os.close(release)
        os.waitpid(pid, 0)
        loop.close()


# -- the read budget ------------------------------------------------------------------------


def test_a_pipelining_client_is_served_a_bounded_number_per_turn(
    made: Callable[..., Loop], peers: Callable[[], Peer]
) -> None:
    """200 requests in one write are handled at most requests_per_call (default 8) per turn
    (the rest wait in the socket, readable the next turn), and every one is answered, in
    order."""
    loop = made()
    peer = peers()
    peer.send(pipeline(200))
    per_turn = []
    while len(loop.of_type(Received)) < 200:
        per_turn.append(sum(isinstance(r, Received) for r in loop.turn(0.05)))
        assert len(per_turn) < 1000, "the loop did not get there"
    assert max(per_turn) <= 8
    replies = peer.read(loop, 200)
    assert [r["id"] for r in replies] == list(range(200))


def test_pipelining_clients_share_a_turn_alike(
    made: Callable[..., Loop], peers: Callable[[], Peer]
) -> None:
    """Four clients pipelining at once: a turn handles at most requests_per_turn requests,
    split evenly, so no client is starved and none goes first for ever."""
    loop = made(requests_per_call=8, requests_per_turn=8, max_clients=4)
    clients = [peers() for _ in range(4)]
    loop.until(lambda: len(loop.of_type(Accepted)) == 4)
    for peer in clients:
        peer.send(pipeline(40))
    while len(loop.of_type(Received)) < 160:
        results = loop.turn(0.05)
        counts: dict[int, int] = {}
        for r in results:
            if isinstance(r, Received):
                counts[r.client.connection] = counts.get(r.client.connection, 0) + 1
        assert sum(counts.values()) <= 8
        assert all(n <= 2 for n in counts.values()), counts
    for peer in clients:
        assert [r["id"] for r in peer.read(loop, 40)] == list(range(40))


def test_requests_sent_before_a_close_are_all_answered(
    made: Callable[..., Loop], peers: Callable[[], Peer]
) -> None:
    """A client that pipelines and shuts down its sending side still gets every reply: the
    end is seen only after the buffered requests."""
    loop = made(requests_per_call=4)
    peer = peers()
    peer.send(pipeline(30))
    peer.sock.shutdown(socket.SHUT_WR)
    replies = peer.read(loop, 30)
    assert [r["id"] for r in replies] == list(range(30))
    loop.until(lambda: bool(loop.of_type(Closed)))
    assert loop.of_type(Closed)[0].reason is CloseReason.PEER_CLOSED


# -- clients bound to a user ----------------------------------------------------------------


def hello_as_nobody(path: Path, name: str, out: int) -> None:
    """In a forked child: become nobody, say hello as ``name``, then heartbeat; write the two
    replies to ``out`` and exit (never returns)."""
    code = 1
    try:
        os.setgroups([])
        os.setgid(NOBODY)
        os.setuid(NOBODY)
        with socket.socket(socket.AF_UNIX, socket.SOCK_STREAM) as sock:
            sock.connect(str(path))
            with sock.makefile("rwb") as stream:
                for request in ({"op": "hello", "name": name}, {"op": "heartbeat"}):
                    stream.write(json.dumps(request).encode() + b"\n")
                    stream.flush()
                    os.write(out, stream.readline())
        code = 0
    finally:
        os._exit(code)


def test_hello_as_a_bound_client_from_another_user_is_refused_and_recorded(
    shared_dir: Path,  # noqa: F811 -- the fixture of test_api_server
) -> None:
    """A client bound to root (``ClientSpec.uid``, the one place the binding lives): nobody's
    hello under its name is refused by the safety core (``WRONG_USER``, recorded as kind
    hello_refused naming the caller), answered not_allowed, and the connection stays unnamed;
    root's own hello is accepted."""
    nogroup = grp.getgrgid(NOBODY).gr_name
    path = shared_dir / "api.sock"
    safety = SafetyConfig(clients=(ClientSpec("nav", uid=0),))
    loop = Judged(ServerConfig(path, group=nogroup), safety)
    read_end, write_end = os.pipe()
    try:
        pid = os.fork()
        if pid == 0:
            hello_as_nobody(path, "nav", write_end)
        os.close(write_end)
        loop.until(lambda: os.waitpid(pid, os.WNOHANG)[0] != 0)
        with os.fdopen(read_end, "rb") as stream:
            read_end = -1
            hello, beat = (json.loads(line) for line in stream.read().splitlines())
        assert (hello["ok"], hello["code"]) == (False, "not_allowed")
        assert "nav" in hello["error"]
        assert beat["code"] == "not_hello"
        (refused,) = [d for d in loop.decisions if d.refusals]
        (refusal,) = refused.refusals
        assert refusal.reason is RefusalReason.WRONG_USER
        assert isinstance(refusal.trigger, ClientHello)
        assert refusal.trigger.caller is not None
        assert refusal.trigger.caller.uid == NOBODY
        (record,) = refused.records
        assert record.note is not None
        assert record.note.value == "hello_refused"
        assert "nav" in record.reason
        # The right user is let in.
        root = Peer(path)
        try:
            assert root.ask(loop, {"op": "hello", "name": "nav"})["ok"] is True
            assert root.ask(loop, {"op": "heartbeat"})["ok"] is True
        finally:
            root.close()
        assert [r.reason for d in loop.decisions for r in d.refusals] == [RefusalReason.WRONG_USER]
    finally:
        if read_end >= 0:
            os.close(read_end)
        loop.close()


def test_the_core_refuses_a_bound_name_from_another_uid_and_an_unknown_caller() -> None:
    """The safety core's own check: a hello for a client bound to uid 1000 from uid 1001, or
    with no caller at all, is refused (WRONG_USER) and recorded; from uid 1000 it names the
    connection; an unbound client is open to every caller."""
    from supervisord.safety.events import Caller  # noqa: PLC0415 -- local to this test

    config = SafetyConfig(clients=(ClientSpec("nav", uid=1000), ClientSpec("map")))
    core = SafetyCore(config, 0)
    for connection in (1, 2, 3, 4):
        core.handle(ClientConnected(1, connection))
    stranger = Caller(1001, 42, "mallory", admin=False)
    owner = Caller(1000, 43, "robot", admin=False)
    for event in (ClientHello(2, 1, "nav", stranger), ClientHello(3, 1, "nav")):
        decision = core.handle(event)
        assert [r.reason for r in decision.refusals] == [RefusalReason.WRONG_USER]
        assert [r.note.value for r in decision.records if r.note] == ["hello_refused"]
    assert core.handle(ClientHello(4, 2, "nav", owner)).refusals == ()
    assert core.handle(ClientHello(5, 3, "map", stranger)).refusals == ()
    assert core.handle(ClientHello(6, 4, "map")).refusals[0].reason is RefusalReason.NAME_IN_USE


def test_a_bad_bound_uid_is_a_config_error() -> None:
    """A client's uid must be a whole number a user id can be."""
    from supervisord.errors import ConfigError  # noqa: PLC0415 -- local to this test

    for bad in (-1, 1 << 32, True, "0"):
        with pytest.raises(ConfigError, match="uid"):
            ClientSpec("nav", uid=bad)  # type: ignore[arg-type]


# -- the socket file of a start that failed -------------------------------------------------


def run_srcsd(config: Path) -> subprocess.CompletedProcess[str]:
    return subprocess.run(
        [sys.executable, "-m", "supervisord.cli.srcsd", "--config", str(config)],
        capture_output=True,
        text=True,
        timeout=60,
        cwd=REPO,
        check=False,
    )


def test_a_start_that_fails_after_binding_leaves_no_socket(tmp_path: Path) -> None:
    """srcsd whose record cannot be opened (a name longer than the file system takes: its
    directory is there, so the configuration passes) exits 1 and removes the API socket it
    had already made: no stale api.sock is left behind. (A missing directory is refused
    before the socket is made, as a configuration error: tests/config.)"""
    config = tmp_path / "robot.toml"
    config.write_text(MINIMAL_CONFIG.replace('path = "stops.jsonl"', f'path = "{"x" * 300}.jsonl"'))
    result = run_srcsd(config)
    assert result.returncode == 1, result.stderr
    assert "cannot start" in result.stderr
    assert not (tmp_path / "api.sock").exists()
    assert not [p for p in tmp_path.iterdir() if p.name.startswith(".api.sock")]


def test_a_start_replaces_a_stale_socket_but_never_a_live_one(tmp_path: Path) -> None:
    """A socket file nobody listens on is replaced by a new server; while that server lives,
    a second one refuses to start and the first keeps its file and its clients."""
    path = tmp_path / "api.sock"
    stale = socket.socket(socket.AF_UNIX, socket.SOCK_STREAM)
    stale.bind(str(path))
    stale.close()
    loop = Loop(ServerConfig(path))
    try:
        identity = path.stat().st_ino
        with pytest.raises(ServerError, match="another server"):
            ApiServer(ServerConfig(path))
        assert path.stat().st_ino == identity
        peer = Peer(path)
        try:
            assert peer.ask(loop, {"op": "status"})["ok"] is True
        finally:
            peer.close()
    finally:
        loop.close()
    assert not path.exists()
