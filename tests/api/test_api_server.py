"""The API server over real Unix sockets, driven by a selectors loop as the daemon drives it."""

from __future__ import annotations

import grp
import json
import os
import selectors
import signal
import socket
import stat
import subprocess
import sys
import tempfile
import threading
import time
from collections.abc import Callable, Iterator
from pathlib import Path
from typing import Any, TypeVar

import pytest

from supervisord.api.credentials import PeerCredentials, caller, process_groups
from supervisord.api.names import UserNames
from supervisord.api.pushes import OtherPush
from supervisord.api.replies import CommissionReply, Reply
from supervisord.api.requests import Commission, Estop, Hello, Reset, Status, Topic
from supervisord.api.server import (
    Accepted,
    ApiServer,
    Closed,
    CloseReason,
    Denied,
    Received,
    Result,
    ServerConfig,
    ServerError,
    core_event,
)
from supervisord.api.views import refusal_error, state_push, state_report
from supervisord.clock import MONOTONIC
from supervisord.errors import ConfigError
from supervisord.safety.config import SafetyConfig
from supervisord.safety.core import SafetyCore
from supervisord.safety.decision import RefusalReason
from supervisord.safety.events import (
    ClientConnected,
    ClientDisconnected,
    ClientEstop,
    LocalEstop,
    ResetRequest,
)
from tests.api.samples import status_reply

NOBODY = 65534
READ, WRITE = selectors.EVENT_READ, selectors.EVENT_WRITE
T = TypeVar("T")


class Loop:
    """The daemon's loop in miniature: one selector, the server, and a stand-in for the
    daemon that answers every request ``ok`` (``status`` with the safety core's state; a
    ``hello`` as a core that takes every name would)."""

    def __init__(
        self,
        config: ServerConfig,
        answer: bool = True,
        clock: Callable[[], int] = MONOTONIC,
        names: UserNames | None = None,
    ) -> None:
        self.server = ApiServer(config, names)
        self.clock = clock  # the loop's clock: the real one unless a test drives it
        self.selector = selectors.DefaultSelector()
        self.watched: dict[int, int] = {}
        self.answer = answer
        self.before_reply: Callable[[Received], object] | None = None
        self.results: list[Result] = []
        self.core = SafetyCore(SafetyConfig(), 0)

    def sync(self) -> None:
        """Watch exactly what the server asks for, as the daemon's loop does."""
        wanted = {
            fd: READ | (WRITE if out else 0) for fd, out in self.server.descriptors(self.clock())
        }
        for fd in set(self.watched) - set(wanted):
            self.selector.unregister(fd)
        for fd, events in wanted.items():
            if fd not in self.watched:
                self.selector.register(fd, events)
            elif self.watched[fd] != events:
                self.selector.modify(fd, events)
        self.watched = wanted

    def turn(self, timeout: float = 0.0) -> list[Result]:
        self.sync()
        new: list[Result] = []
        for key, mask in self.selector.select(timeout):
            self.server.handle(key.fd, bool(mask & READ), bool(mask & WRITE), self.clock())
            new += self.take()
        due = self.server.next_deadline()
        if due is not None and self.clock() >= due:
            self.server.due(self.clock())
        return new + self.take()

    def take(self) -> list[Result]:
        """Take every queued result, answering each request as it is taken."""
        new: list[Result] = []
        while (result := self.server.take()) is not None:
            new.append(result)
            if isinstance(result, Received) and self.before_reply is not None:
                self.before_reply(result)
            if isinstance(result, Received) and self.answer:
                request = result.request
                reply: Reply | None = None
                if isinstance(request, Status):
                    reply = status_reply(state_report(self.core.decision), request.id)
                elif isinstance(request, Commission):
                    reply = CommissionReply(id=request.id, key85=1, remote_status=True)
                self.server.reply(result, reply)
        self.results += new
        return new

    def until(self, done: Callable[[], bool], turns: int = 5000) -> None:
        for _ in range(turns):
            if done():
                return
            self.turn(0.01)
        raise AssertionError("the loop did not get there")

    def of_type(self, kind: type[T]) -> list[T]:
        return [r for r in self.results if isinstance(r, kind)]

    def close(self) -> list[Closed]:
        """Close the server; the ends it reports on closing."""
        self.server.close()
        self.selector.close()
        return [r for r in self.take() if isinstance(r, Closed)]


class Peer:
    """A client over a raw socket: what a C program would do."""

    def __init__(self, path: Path) -> None:
        self.sock = socket.socket(socket.AF_UNIX, socket.SOCK_STREAM)
        self.sock.connect(str(path))
        self.sock.setblocking(False)
        self.buffer = b""
        self.eof = False

    def send(self, data: bytes | dict[str, Any]) -> None:
        raw = data if isinstance(data, bytes) else json.dumps(data).encode() + b"\n"
        self.sock.sendall(raw)

    def _pump(self) -> None:
        while not self.eof:
            try:
                data = self.sock.recv(65536)
            except BlockingIOError:
                return
            except ConnectionResetError:
                self.eof = True
                return
            if not data:
                self.eof = True
            self.buffer += data

    def has(self, count: int) -> bool:
        self._pump()
        return self.buffer.count(b"\n") >= count

    def read(self, loop: Loop, count: int = 1) -> list[dict[str, Any]]:
        loop.until(lambda: self.has(count))
        lines = self.buffer.split(b"\n")
        self.buffer = b"\n".join(lines[count:])
        return [json.loads(line) for line in lines[:count]]

    def ask(self, loop: Loop, obj: dict[str, Any]) -> dict[str, Any]:
        self.send(obj)
        (reply,) = self.read(loop)
        return reply

    def wait_eof(self, loop: Loop) -> None:
        def closed() -> bool:
            self._pump()
            return self.eof

        loop.until(closed)

    def close(self) -> None:
        self.sock.close()


@pytest.fixture
def sock_path(tmp_path: Path) -> Path:
    return tmp_path / "api.sock"


@pytest.fixture
def loop(sock_path: Path) -> Iterator[Loop]:
    the_loop = Loop(ServerConfig(sock_path, max_clients=3, max_line=256, max_discard=1024))
    yield the_loop
    the_loop.close()


@pytest.fixture
def peers(sock_path: Path) -> Iterator[Callable[[], Peer]]:
    made: list[Peer] = []

    def make() -> Peer:
        made.append(Peer(sock_path))
        return made[-1]

    yield make
    for peer in made:
        peer.close()


# -- the socket file ------------------------------------------------------------------------


def test_socket_file_is_0660_and_not_world_writable(loop: Loop, sock_path: Path) -> None:
    """The server creates a socket with mode 0660: owner and group only."""
    info = sock_path.stat()
    assert stat.S_ISSOCK(info.st_mode)
    assert stat.S_IMODE(info.st_mode) == 0o660
    assert not info.st_mode & stat.S_IWOTH


def test_world_writable_mode_is_refused(sock_path: Path) -> None:
    """A configured mode that lets others connect is a ConfigError naming api.mode."""
    with pytest.raises(ConfigError, match=r"api\.mode"):
        ServerConfig(sock_path, mode=0o666)


def test_socket_group_is_set(sock_path: Path) -> None:
    """The socket file belongs to the configured group, so its members can connect."""
    nogroup = grp.getgrgid(NOBODY).gr_name
    the_loop = Loop(ServerConfig(sock_path, group=nogroup))
    try:
        assert sock_path.stat().st_gid == NOBODY
    finally:
        the_loop.close()


def test_stale_socket_is_replaced(sock_path: Path, peers: Callable[[], Peer]) -> None:
    """A socket file left by a crashed server (nobody listening) is removed and served anew."""
    stale = socket.socket(socket.AF_UNIX, socket.SOCK_STREAM)
    stale.bind(str(sock_path))
    stale.close()
    the_loop = Loop(ServerConfig(sock_path))
    try:
        peer = peers()
        assert peer.ask(the_loop, {"op": "status"})["ok"] is True
    finally:
        the_loop.close()


def test_path_that_is_not_a_socket_is_refused(sock_path: Path) -> None:
    """A regular file at the path stops the server from starting and is left alone."""
    sock_path.write_text("keep me")
    with pytest.raises(ServerError, match="not a socket"):
        ApiServer(ServerConfig(sock_path))
    assert sock_path.read_text() == "keep me"


def test_second_server_on_a_live_socket_is_refused(loop: Loop, sock_path: Path) -> None:
    """A server that finds another one listening at its path refuses to start."""
    with pytest.raises(ServerError, match="another server"):
        ApiServer(ServerConfig(sock_path))
    assert sock_path.exists()


def test_close_removes_the_socket_file(sock_path: Path) -> None:
    """Closing the server unlinks its socket file; closing again does nothing."""
    the_loop = Loop(ServerConfig(sock_path))
    the_loop.close()
    assert not sock_path.exists()
    the_loop.server.close()
    assert the_loop.server.take() is None


def test_close_leaves_a_newer_socket_alone(sock_path: Path) -> None:
    """If another socket replaced ours at the path, closing does not remove that one."""
    the_loop = Loop(ServerConfig(sock_path))
    sock_path.unlink()
    newer = socket.socket(socket.AF_UNIX, socket.SOCK_STREAM)
    try:
        newer.bind(str(sock_path))
        the_loop.close()
        assert sock_path.exists()
    finally:
        newer.close()


# -- requests -------------------------------------------------------------------------------


def test_hello_heartbeat_and_status_round_trip(loop: Loop, peers: Callable[[], Peer]) -> None:
    """A client says hello, sends heartbeats and asks for the status; each gets its reply."""
    peer = peers()
    assert peer.ask(loop, {"op": "hello", "name": "planner", "id": 1}) == {
        "ok": True,
        "op": "hello",
        "id": 1,
    }
    assert peer.ask(loop, {"op": "heartbeat"}) == {"ok": True, "op": "heartbeat"}
    status = peer.ask(loop, {"op": "status", "id": "s"})
    assert status["state"] == "STOPPED"
    assert status["id"] == "s"
    (accepted,) = loop.of_type(Accepted)
    received = loop.of_type(Received)
    assert [type(r.request).__name__ for r in received] == ["Hello", "Heartbeat", "Status"]
    assert received[1].client.name == "planner"
    assert received[1].client.connection == accepted.client.connection


def test_requests_pipelined_in_one_write_are_answered_in_order(
    loop: Loop, peers: Callable[[], Peer]
) -> None:
    """Several requests in one write get their replies in the same order."""
    peer = peers()
    peer.send(b"".join(json.dumps({"op": "status", "id": i}).encode() + b"\n" for i in range(20)))
    assert [r["id"] for r in peer.read(loop, 20)] == list(range(20))


def test_peer_credentials_are_read(loop: Loop, peers: Callable[[], Peer]) -> None:
    """The server knows the peer's uid and pid from SO_PEERCRED; root is an admin. The login
    name is looked up off the loop (SR-10.3): the connection is named once it is known."""
    peers()
    loop.until(lambda: bool(loop.of_type(Accepted)))
    (accepted,) = loop.of_type(Accepted)
    assert accepted.client.caller.uid == os.getuid()
    assert accepted.client.caller.pid == os.getpid()
    assert accepted.client.caller.admin is True
    loop.until(lambda: loop.server.clients()[0].caller.name == "root")


def test_bad_json_gets_an_error_and_the_connection_stays(
    loop: Loop, peers: Callable[[], Peer]
) -> None:
    """Bad JSON, a non-object and an unknown op each get an error; the next request works."""
    peer = peers()
    peer.send(b"{nope\n[1]\n" + b'{"op":"fly","id":9}\n' + b'{"op":"status"}\n')
    bad_json, not_object, unknown, status = peer.read(loop, 4)
    assert (bad_json["ok"], bad_json["code"]) == (False, "bad_json")
    assert not_object["code"] == "bad_request"
    assert (unknown["code"], unknown["id"]) == ("unknown_op", 9)
    assert status["ok"] is True
    assert not loop.of_type(Closed)


def test_blank_lines_are_ignored(loop: Loop, peers: Callable[[], Peer]) -> None:
    """Empty lines (and a CR before the newline) are allowed, for people typing requests."""
    peer = peers()
    peer.send(b"\n  \n" + b'{"op":"status"}\r\n')
    assert peer.read(loop)[0]["ok"] is True


def test_oversized_line_is_discarded_and_the_connection_stays(
    loop: Loop, peers: Callable[[], Peer]
) -> None:
    """A line over the limit gets too_long once; the requests after it are served."""
    peer = peers()
    peer.send(b'{"op":"status","pad":"' + b"x" * 600 + b'"}\n{"op":"status"}\n')
    too_long, status = peer.read(loop, 2)
    assert too_long["code"] == "too_long"
    assert status["ok"] is True
    assert not loop.of_type(Closed)


def test_flooding_client_is_disconnected(loop: Loop, peers: Callable[[], Peer]) -> None:
    """A client that sends an endless line gets too_long, then flood, then is disconnected."""
    peer = peers()
    peer.send(b"x" * 5000)
    too_long, flood = peer.read(loop, 2)
    assert (too_long["code"], flood["code"]) == ("too_long", "flood")
    peer.wait_eof(loop)
    (closed,) = loop.of_type(Closed)
    assert closed.reason is CloseReason.FLOOD


def test_too_many_clients_get_an_error_line_then_eof(loop: Loop, peers: Callable[[], Peer]) -> None:
    """Past max_clients a connection gets one too_many_clients line and is closed, unreported."""
    first, _second, _third = peers(), peers(), peers()
    loop.until(lambda: len(loop.of_type(Accepted)) == 3)
    extra = peers()
    (error,) = extra.read(loop)
    assert error["code"] == "too_many_clients"
    extra.wait_eof(loop)
    assert len(loop.of_type(Accepted)) == 3
    first.close()
    loop.until(lambda: bool(loop.of_type(Closed)))
    again = peers()
    assert again.ask(loop, {"op": "status"})["ok"] is True
    assert len(loop.of_type(Accepted)) == 4


def test_peer_closing_is_reported_once(loop: Loop, peers: Callable[[], Peer]) -> None:
    """A client that closes its end is reported as Closed (peer_closed) exactly once."""
    peer = peers()
    assert peer.ask(loop, {"op": "hello", "name": "nav"})["ok"] is True
    peer.close()
    loop.until(lambda: bool(loop.of_type(Closed)))
    for _ in range(5):
        loop.turn(0.001)
    (closed,) = loop.of_type(Closed)
    assert closed.reason is CloseReason.PEER_CLOSED
    assert closed.client.name == "nav"
    assert loop.server.clients() == ()


def test_a_command_declaration_needs_hello(loop: Loop, peers: Callable[[], Peer]) -> None:
    """SR-4.6: only a named client declares its commanded motion; before hello the
    declaration is ``not_hello`` and reaches nothing, after it the reply is ok."""
    peer = peers()
    refused = peer.ask(loop, {"op": "command", "nonzero": True})
    assert (refused["ok"], refused["code"]) == (False, "not_hello")
    assert peer.ask(loop, {"op": "hello", "name": "nav"})["ok"] is True
    assert peer.ask(loop, {"op": "command", "nonzero": True})["ok"] is True
    assert peer.ask(loop, {"op": "command", "nonzero": False})["ok"] is True


def test_subscribers_receive_broadcasts(loop: Loop, peers: Callable[[], Peer]) -> None:
    """SR-8.2: only connections subscribed to a topic receive its pushes."""
    watcher, other = peers(), peers()
    assert watcher.ask(loop, {"op": "subscribe", "topics": ["state", "gps"]})["ok"] is True
    assert loop.server.subscribed(Topic.STATE)
    assert not loop.server.subscribed(Topic.JOYSTICK)
    loop.server.broadcast(Topic.STATE, state_push(loop.core.decision))
    (push,) = watcher.read(loop)
    assert (push["event"], push["state"]) == ("state", "STOPPED")
    assert other.ask(loop, {"op": "status"})["ok"] is True
    assert other.buffer == b""


def test_a_stopped_client_is_disconnected_without_blocking(
    loop: Loop, peers: Callable[[], Peer]
) -> None:
    """A subscriber that stops reading is dropped when its buffer fills; the loop never waits."""
    slow, healthy = peers(), peers()
    for peer in (slow, healthy):
        assert peer.ask(loop, {"op": "subscribe", "topics": ["state"]})["ok"] is True
    push = OtherPush("state", {**state_push(loop.core.decision).json(), "pad": "p" * 4000})
    for _ in range(2000):
        loop.server.broadcast(Topic.STATE, push)
        healthy.has(0)  # the healthy client keeps reading
        healthy.buffer = b""
        loop.turn()
        if loop.of_type(Closed):
            break
    closed = loop.of_type(Closed)
    assert [c.reason for c in closed] == [CloseReason.OUTPUT_OVERFLOW]
    assert closed[0].client.connection == loop.of_type(Accepted)[0].client.connection
    assert healthy.ask(loop, {"op": "status"})["ok"] is True


def test_a_sigstopped_process_is_disconnected(loop: Loop, sock_path: Path) -> None:
    """A real client process stopped with SIGSTOP is dropped when its buffer fills."""
    script = (
        "import socket,sys\n"
        "s=socket.socket(socket.AF_UNIX)\n"
        f"s.connect({str(sock_path)!r})\n"
        's.sendall(b\'{"op":"subscribe","topics":["state"]}\\n\')\n'
        "s.recv(100)\n"
        "print('ready', flush=True)\n"
        "sys.stdin.read()\n"
    )
    child = subprocess.Popen(
        [sys.executable, "-c", script], stdin=subprocess.PIPE, stdout=subprocess.PIPE
    )
    try:
        assert child.stdout is not None
        loop.until(lambda: bool(loop.of_type(Received)))
        loop.turn()
        assert child.stdout.readline() == b"ready\n"
        child.send_signal(signal.SIGSTOP)
        push = OtherPush("state", {**state_push(loop.core.decision).json(), "pad": "p" * 4000})
        for _ in range(2000):
            loop.server.broadcast(Topic.STATE, push)
            loop.turn()
            if loop.of_type(Closed):
                break
        assert [c.reason for c in loop.of_type(Closed)] == [CloseReason.OUTPUT_OVERFLOW]
    finally:
        child.kill()
        child.send_signal(signal.SIGCONT)
        child.communicate()


def test_close_reports_every_open_connection(loop: Loop, peers: Callable[[], Peer]) -> None:
    """Closing the server reports each open connection as Closed (shutdown) and ends it."""
    one, two = peers(), peers()
    loop.until(lambda: len(loop.of_type(Accepted)) == 2)
    closed = loop.close()
    assert [c.reason for c in closed] == [CloseReason.SHUTDOWN, CloseReason.SHUTDOWN]
    for peer in (one, two):
        peer.has(0)
        assert peer.eof


def test_reply_to_a_gone_connection_is_dropped(loop: Loop, peers: Callable[[], Peer]) -> None:
    """Answering a request after its client left does nothing and raises nothing."""
    loop.answer = False
    peer = peers()
    peer.send({"op": "status"})
    loop.until(lambda: bool(loop.of_type(Received)))
    peer.close()
    loop.until(lambda: bool(loop.of_type(Closed)))
    (received,) = loop.of_type(Received)
    loop.server.reply(received)
    assert loop.server.take() is None


# -- the safety core ------------------------------------------------------------------------


def test_results_become_core_events(loop: Loop, peers: Callable[[], Peer]) -> None:
    """Connect (with the peer's uid, whom its records are charged to: SR-8.5), an e-stop
    before and after hello, and the end map to the core's events."""
    peer = peers()
    peer.ask(loop, {"op": "estop"})
    peer.ask(loop, {"op": "hello", "name": "nav"})
    peer.ask(loop, {"op": "estop"})
    peer.close()
    loop.until(lambda: bool(loop.of_type(Closed)))
    events = [core_event(r, 5) for r in loop.results]
    number = loop.of_type(Accepted)[0].client.connection
    caller_ = loop.of_type(Received)[0].client.caller  # named by then (SR-10.3)
    assert events[0] == ClientConnected(5, number, os.getuid())
    assert events[1] == LocalEstop(5, caller_)
    assert events[3] == ClientEstop(5, number)
    assert events[-1] == ClientDisconnected(5, number)


def test_refusal_by_the_core_is_sent_as_refused(loop: Loop, peers: Callable[[], Peer]) -> None:
    """The daemon answers a request the core declined with a refused error and its reason."""
    loop.answer = False
    peer = peers()
    peer.send({"op": "reset", "id": 1})
    loop.until(lambda: bool(loop.of_type(Received)))
    (received,) = loop.of_type(Received)
    event = core_event(received, 10)
    assert isinstance(event, ResetRequest)
    (refusal,) = loop.core.handle(event).refusals  # local_reset is off by default
    loop.server.reply_error(received, refusal_error(received.request, refusal))
    (reply,) = peer.read(loop)
    assert (reply["code"], reply["reason"], reply["id"]) == (
        "refused",
        "local_reset_disabled",
        1,
    )


# -- wrong credentials: a client running as another user ------------------------------------


def child_requests(path: Path, uid: int, gid: int, groups: list[int], out: int) -> None:
    """In a forked child: become ``uid``, send reset, status and commission, write the replies
    to ``out`` and exit (never returns)."""
    code = 1
    try:
        os.setgroups(groups)
        os.setgid(gid)
        os.setuid(uid)
        with socket.socket(socket.AF_UNIX, socket.SOCK_STREAM) as sock:
            sock.connect(str(path))
            with sock.makefile("rwb") as stream:
                for request in (
                    {"op": "reset"},
                    {"op": "status"},
                    {"op": "commission", "confirm": True},
                ):
                    stream.write(json.dumps(request).encode() + b"\n")
                    stream.flush()
                    os.write(out, stream.readline())
        code = 0
    finally:
        os._exit(code)


@pytest.fixture
def shared_dir() -> Iterator[Path]:
    """A directory other users can reach (pytest's own tmp_path is private to root)."""
    with tempfile.TemporaryDirectory(prefix="srcs-api-") as name:
        os.chmod(name, 0o711)  # noqa: S103 -- nobody must reach the socket inside
        yield Path(name)


def run_as_nobody(
    shared_dir: Path, admin_group: str | None, extra_groups: list[int]
) -> tuple[Loop, list[dict[str, Any]]]:
    """Serve in ``shared_dir`` (socket group nogroup), fork a child that becomes nobody and
    makes its requests; return the loop and the child's replies."""
    nogroup = grp.getgrgid(NOBODY).gr_name
    path = shared_dir / "api.sock"
    the_loop = Loop(ServerConfig(path, group=nogroup, admin_group=admin_group))
    read_end, write_end = os.pipe()
    try:
        pid = os.fork()
        if pid == 0:
            child_requests(path, NOBODY, NOBODY, extra_groups, write_end)
        os.close(write_end)
        status: list[int] = []

        def exited() -> bool:
            done, code = os.waitpid(pid, os.WNOHANG)
            if done:
                status.append(code)
            return bool(done)

        the_loop.until(exited)
        assert os.waitstatus_to_exitcode(status[0]) == 0
        the_loop.until(lambda: bool(the_loop.of_type(Closed)))
        with os.fdopen(read_end, "rb") as replies:
            read_end = -1
            lines = replies.read().splitlines()
    except BaseException:
        the_loop.close()
        raise
    finally:
        if read_end >= 0:
            os.close(read_end)
    return the_loop, [json.loads(line) for line in lines]


def test_non_admin_peer_is_refused_reset_and_commission(shared_dir: Path) -> None:
    """A client running as nobody, not in the admin group, gets not_allowed for both."""
    the_loop, replies = run_as_nobody(shared_dir, "root", [])
    try:
        reset, status, commission = replies
        assert (reset["ok"], reset["code"], reset["op"]) == (False, "not_allowed", "reset")
        assert status["ok"] is True
        assert commission["code"] == "not_allowed"
        denied = the_loop.of_type(Denied)
        assert [type(d.request) for d in denied] == [Reset, Commission]
        assert denied[0].client.caller.uid == NOBODY
        assert denied[0].client.caller.admin is False
        # The core still sees the reset, so that the refusal is recorded.
        event = core_event(denied[0], 1)
        assert isinstance(event, ResetRequest)
        core = SafetyCore(SafetyConfig(local_reset=True), 0)
        (refusal,) = core.handle(event).refusals
        assert refusal.reason is RefusalReason.NOT_ADMIN
        assert core_event(denied[1], 1) is None
    finally:
        the_loop.close()


def test_admin_group_member_by_primary_group_is_accepted(shared_dir: Path) -> None:
    """nobody, whose primary group is the admin group, may reset and commission."""
    the_loop, replies = run_as_nobody(shared_dir, grp.getgrgid(NOBODY).gr_name, [])
    try:
        assert [r["ok"] for r in replies] == [True, True, True]
        assert not the_loop.of_type(Denied)
        received = the_loop.of_type(Received)
        assert received[0].client.caller.admin is True
        assert received[0].client.caller.uid == NOBODY
    finally:
        the_loop.close()


def test_admin_group_member_by_supplementary_group_is_accepted(shared_dir: Path) -> None:
    """nobody with the admin group (gid 0's) as a supplementary group may reset."""
    the_loop, replies = run_as_nobody(shared_dir, grp.getgrgid(0).gr_name, [0])
    try:
        assert [r["ok"] for r in replies] == [True, True, True]
        assert the_loop.of_type(Received)[0].client.caller.admin is True
    finally:
        the_loop.close()


# -- credentials ----------------------------------------------------------------------------


def fake_proc(root: Path, pid: int, uid: str, groups: str) -> Path:
    (root / str(pid)).mkdir(parents=True)
    (root / str(pid) / "status").write_text(
        f"Name:\tplanner\nUid:\t{uid}\t{uid}\t{uid}\t{uid}\nGroups:\t{groups}\n"
    )
    return root


def test_supplementary_groups_come_from_proc(tmp_path: Path) -> None:
    """The peer's groups are its primary gid plus the Groups: line of /proc/PID/status."""
    proc = fake_proc(tmp_path, 77, "1000", "20 27 44")
    credentials = PeerCredentials(77, 1000, 1000)
    assert process_groups(credentials, proc) == {1000, 20, 27, 44}
    assert caller(credentials, 27, proc).admin is True
    assert caller(credentials, 28, proc).admin is False
    assert caller(credentials, None, proc).admin is False


def test_recycled_pid_lends_no_groups(tmp_path: Path) -> None:
    """If /proc/PID belongs to another user now, only the kernel-reported gid counts."""
    proc = fake_proc(tmp_path, 77, "0", "0 27")
    assert process_groups(PeerCredentials(77, 1000, 1000), proc) == {1000}
    assert process_groups(PeerCredentials(78, 1000, 1000), proc) == {1000}


def test_root_and_the_daemons_own_user_are_admins(tmp_path: Path) -> None:
    """uid 0 and the daemon's own uid are admins even with no admin group configured."""
    assert caller(PeerCredentials(1, 0, 0), None, tmp_path).admin is True
    assert caller(PeerCredentials(1, 999, 999), None, tmp_path, own_uid=999).admin is True
    assert caller(PeerCredentials(1, 998, 999), None, tmp_path, own_uid=999).admin is False


def test_unknown_admin_group_is_a_config_error(sock_path: Path) -> None:
    """A server configured with a group that does not exist refuses to start."""
    with pytest.raises(ConfigError, match=r"api\.admin_group"):
        ApiServer(ServerConfig(sock_path, admin_group="no-such-group-xyz"))
    assert not sock_path.exists()


def test_hello_named_connection_keeps_its_name_in_results(
    loop: Loop, peers: Callable[[], Peer]
) -> None:
    """Results after hello carry the client's name; the Hello itself names the request."""
    peer = peers()
    peer.ask(loop, {"op": "hello", "name": "arm"})
    peer.ask(loop, {"op": "estop"})
    hello, estop = loop.of_type(Received)
    assert hello.request == Hello("arm")
    assert estop.request == Estop()
    assert estop.client.name == "arm"
    assert [c.name for c in loop.server.clients()] == ["arm"]


def test_a_turn_without_connections_watches_and_budgets_as_a_full_turn(
    loop: Loop, peers: Callable[[], Peer]
) -> None:
    """SR-9.4, SR-10.1: a turn with nobody connected takes the server's idle path; it watches
    the same descriptors and renews the same read budget as the full turn would, also after
    a client that used up a turn's budget has gone, and a client that comes next is served."""
    server = loop.server

    def full_turn() -> tuple[list[tuple[int, bool]], int, int]:
        # What descriptors() computes with its idle path set aside, on the same server.
        server._release_ended()
        server._new_turn(loop.clock())
        return server._sockets_watched(), server._share, server._turn_left

    idle = server.descriptors(loop.clock())
    assert (idle, server._share, server._turn_left) == full_turn()
    peer = peers()
    for i in range(3 * server.config.requests_per_turn):  # more than a turn's budget
        peer.send({"op": "heartbeat", "id": i})
    loop.until(lambda: peer.has(10))
    peer.close()
    loop.until(lambda: bool(loop.of_type(Closed)))
    loop.turn()  # the ended connection's descriptor is released
    idle = server.descriptors(loop.clock())
    assert server._connections == {}
    assert (idle, server._share, server._turn_left) == full_turn()
    assert server.descriptors(loop.clock()) is idle  # the same list: the loop compares it
    late = peers()
    assert late.ask(loop, {"op": "status", "id": 1})["id"] == 1


def test_a_caller_whose_groups_decide_nothing_costs_no_proc_read(tmp_path: Path) -> None:
    """SR-10.8: root, the daemon's own user, a caller whose primary group is the admin group
    and any caller where no admin group is configured are judged without opening
    ``/proc/PID/status`` (an open the SCHED_FIFO loop can sleep in). The status file is a FIFO
    here: a writer waiting on it learns whether anyone opened it."""
    (tmp_path / "77").mkdir()
    fifo = tmp_path / "77" / "status"
    os.mkfifo(fifo)
    opened = threading.Event()

    def writer() -> None:
        with fifo.open("w") as handle:  # returns once a reader opened it
            opened.set()
            handle.write("Uid:\t1000\t1000\t1000\t1000\nGroups:\t27\n")

    thread = threading.Thread(target=writer, daemon=True)
    thread.start()
    try:
        assert caller(PeerCredentials(77, 0, 0), 27, tmp_path).admin is True
        time.sleep(0.2)  # a reader's open would have released the writer by now
        assert not opened.is_set(), "the status file was opened for root"
        assert caller(PeerCredentials(77, 999, 999), 27, tmp_path, own_uid=999).admin is True
        assert caller(PeerCredentials(77, 1000, 27), 27, tmp_path).admin is True
        assert caller(PeerCredentials(77, 1000, 1000), None, tmp_path).admin is False
        time.sleep(0.2)  # a reader's open would have released the writer by now
        assert not opened.is_set(), "the status file was opened for a caller it decides nothing for"
    finally:
        reader = os.open(fifo, os.O_RDONLY | os.O_NONBLOCK)  # releases the writer
        thread.join(10)
        os.close(reader)
