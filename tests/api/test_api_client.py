"""The Python client library against a real server (served from a helper thread in the test:
the client blocks, the daemon's loop must keep turning meanwhile)."""

from __future__ import annotations

import contextlib
import socket
import threading
import time
from collections.abc import Callable
from pathlib import Path
from types import TracebackType

import pytest

from supervisord.api.framing import ApiError, ErrorCode
from supervisord.api.replies import CommissionReply
from supervisord.api.requests import (
    Command,
    Commission,
    DisplayLabel,
    DisplayModeRequest,
    DisplayRow,
    DisplayValue,
    Estop,
    Heartbeat,
    Hello,
    Hold,
    Release,
    Reset,
    Side,
    Status,
    Subscribe,
    Topic,
    Vibrate,
)
from supervisord.api.server import Closed, Received, ServerConfig
from supervisord.api.views import state_push
from supervisord.client import (
    ClientTimeoutError,
    ConnectError,
    ConnectionClosedError,
    Push,
    SupervisorClient,
)
from supervisord.protocol.codes import DisplayMode
from supervisord.safety.events import Request
from supervisord.vocabulary import CauseKind, State
from tests.api.test_api_server import Loop


class Served:
    """A :class:`Loop` turning in a helper thread until the ``with`` block ends; read its
    results only after that. A heartbeat makes it push the state before replying."""

    def __init__(self, config: ServerConfig, answer: bool = True) -> None:
        self.loop = Loop(config, answer)
        self.loop.before_reply = self._push_on_heartbeat
        self._stop = threading.Event()
        self._turned = threading.Condition()
        self._thread = threading.Thread(target=self._run, name="test-loop")

    def _push_on_heartbeat(self, received: Received) -> None:
        if isinstance(received.request, Heartbeat):
            self.loop.server.broadcast(Topic.STATE, state_push(self.loop.core.decision))

    def _run(self) -> None:
        while not self._stop.is_set():
            with self._turned:
                self.loop.turn(0.005)
                self._turned.notify_all()

    def until(self, done: Callable[[Loop], bool]) -> None:
        """Wait (in the test's thread) until ``done(loop)`` holds after a turn of the loop."""
        with self._turned:
            assert self._turned.wait_for(lambda: done(self.loop), timeout=30)

    def __enter__(self) -> Served:
        self._thread.start()
        return self

    def __exit__(
        self,
        kind: type[BaseException] | None,
        error: BaseException | None,
        tb: TracebackType | None,
    ) -> None:
        if not self._stop.is_set():
            self._stop.set()
            self._thread.join()
            self.loop.close()

    def requests(self) -> list[object]:
        return [r.request for r in self.loop.of_type(Received)]


@pytest.fixture
def sock_path(tmp_path: Path) -> Path:
    return tmp_path / "api.sock"


def test_connect_with_name_says_hello_and_heartbeats(sock_path: Path) -> None:
    """connect(name=...) says hello; heartbeat and status get their replies; with closes."""
    with Served(ServerConfig(sock_path)) as served:
        with SupervisorClient.connect(sock_path, name="planner") as client:
            assert client.name == "planner"
            for _ in range(3):
                client.heartbeat()
            status = client.status()
            assert status.report.state is State.STOPPED
            assert CauseKind.STARTUP in {c.kind for c in status.report.causes}
        assert client.fileno() < 0
        served.until(lambda loop: bool(loop.of_type(Closed)))
    assert served.requests() == [Hello("planner"), Heartbeat(), Heartbeat(), Heartbeat(), Status()]
    assert served.loop.of_type(Closed)[0].client.name == "planner"


def test_every_method_sends_its_request(sock_path: Path) -> None:
    """Each client method sends the request docs/api.md describes."""
    with Served(ServerConfig(sock_path)) as served, SupervisorClient.connect(sock_path) as client:
        client.estop()
        client.hold()
        client.release("hold")
        client.release()
        client.display_value(2, -7)
        client.display_label(2, "torque")
        client.display_row(1, "hello remote")
        client.display_mode(DisplayMode.TEXT_ROWS)
        client.vibrate("left")
        client.subscribe("state", "records")
        client.subscribe()
        client.reset()
        assert client.commission() == CommissionReply(key85=1, remote_status=True)
    assert served.requests() == [
        Estop(),
        Hold(),
        Release(Request.HOLD),
        Release(Request.ESTOP),
        DisplayValue(2, -7),
        DisplayLabel(2, "torque"),
        DisplayRow(1, "hello remote"),
        DisplayModeRequest(DisplayMode.TEXT_ROWS),
        Vibrate(Side.LEFT),
        Subscribe(frozenset({Topic.STATE, Topic.RECORDS})),
        Subscribe(frozenset()),
        Reset(),
        Commission(),
    ]


def test_refusals_raise_api_error_and_the_client_goes_on(sock_path: Path) -> None:
    """An error reply raises ApiError with its code; the connection stays usable."""
    with Served(ServerConfig(sock_path)), SupervisorClient.connect(sock_path) as client:
        with pytest.raises(ApiError) as caught:
            client.heartbeat()
        assert caught.value.code == ErrorCode.NOT_HELLO
        assert caught.value.op == "heartbeat"
        with pytest.raises(ApiError) as caught:
            client.display_row(9, "no such row")
        assert caught.value.code == ErrorCode.BAD_REQUEST
        client.hello("nav")
        client.heartbeat()


def test_heartbeat_sends_its_progress_value(sock_path: Path) -> None:
    """SR-8.16: ``heartbeat(progress=n)`` sends the value docs/api.md describes; without it the
    heartbeat carries none."""
    with (
        Served(ServerConfig(sock_path)) as served,
        SupervisorClient.connect(sock_path, name="planner") as client,
    ):
        client.heartbeat(progress=7)
        client.heartbeat(progress=2**32 - 1)
        client.heartbeat()
    assert served.requests() == [Hello("planner"), Heartbeat(7), Heartbeat(2**32 - 1), Heartbeat()]


def test_command_declares_the_clients_motion(sock_path: Path) -> None:
    """SR-4.6: ``command`` sends the declaration docs/api.md describes, after hello."""
    with (
        Served(ServerConfig(sock_path)) as served,
        SupervisorClient.connect(sock_path, name="planner") as client,
    ):
        client.command(True)
        client.command(False)
    assert served.requests() == [Hello("planner"), Command(True), Command(False)]


def test_pushes_during_a_call_are_kept_for_next_event(sock_path: Path) -> None:
    """A push that arrives before a reply is kept, in order, for next_event."""
    with Served(ServerConfig(sock_path)), SupervisorClient.connect(sock_path, "nav") as client:
        client.subscribe("state")
        client.heartbeat()
        client.heartbeat()
        first, second = client.next_event(), client.next_event()
        assert isinstance(first, Push)
        assert first.event == "state"
        assert first.json()["state"] == "STOPPED"
        assert second is not None
        assert client.next_event(timeout=0.01) is None


def test_next_event_waits_for_a_push(sock_path: Path) -> None:
    """next_event reads a push that arrives while it waits (another client's heartbeat)."""
    with (
        Served(ServerConfig(sock_path)),
        SupervisorClient.connect(sock_path) as watcher,
        SupervisorClient.connect(sock_path, "nav") as robot,
    ):
        watcher.subscribe("state")
        robot.heartbeat()
        push = watcher.next_event(timeout=10)
        assert push is not None
        assert push.event == "state"


def test_missing_socket_is_a_connect_error(tmp_path: Path) -> None:
    """Connecting where no server listens raises ConnectError naming the path."""
    with pytest.raises(ConnectError, match=r"absent\.sock"):
        SupervisorClient.connect(tmp_path / "absent.sock")


def test_server_shutdown_is_connection_closed(sock_path: Path) -> None:
    """When the server goes away the next call raises ConnectionClosedError."""
    served = Served(ServerConfig(sock_path))
    with served, SupervisorClient.connect(sock_path, "nav") as client:
        client.heartbeat()
        served.__exit__(None, None, None)  # stop the loop and close the server early
        with pytest.raises(ConnectionClosedError):
            client.heartbeat()


def test_too_many_clients_raises_on_hello(sock_path: Path) -> None:
    """A client past max_clients gets ApiError too_many_clients from its hello."""
    with (
        Served(ServerConfig(sock_path, max_clients=1)),
        SupervisorClient.connect(sock_path, "first") as first,
    ):
        first.heartbeat()
        with pytest.raises(ApiError) as caught:
            SupervisorClient.connect(sock_path, "second")
        assert caught.value.code == ErrorCode.TOO_MANY_CLIENTS


def test_no_reply_in_time_is_a_timeout_and_closes(sock_path: Path) -> None:
    """A server that does not answer makes the call raise ClientTimeoutError and close."""
    with (
        Served(ServerConfig(sock_path), answer=False),
        SupervisorClient.connect(sock_path, timeout=0.05) as client,
    ):
        with pytest.raises(ClientTimeoutError):
            client.status()
        assert client.fileno() < 0
        with pytest.raises(ConnectionClosedError):
            client.status()


def fill_backlog(path: Path) -> tuple[socket.socket, list[socket.socket]]:
    """A listening socket with a backlog of 1 that accepts nothing, and the connections that
    filled its backlog: the next connect gets EAGAIN, as under connection churn."""
    listener = socket.socket(socket.AF_UNIX, socket.SOCK_STREAM)
    listener.bind(str(path))
    listener.listen(1)
    queued: list[socket.socket] = []
    while True:
        sock = socket.socket(socket.AF_UNIX, socket.SOCK_STREAM | socket.SOCK_NONBLOCK)
        try:
            sock.connect(str(path))
        except BlockingIOError:
            sock.close()
            return listener, queued
        queued.append(sock)


def test_connect_waits_out_a_full_backlog(tmp_path: Path) -> None:
    """A full listen backlog (EAGAIN) is retried: once the server accepts again, within the
    client's bounded wait, the connection is made."""
    path = tmp_path / "api.sock"
    listener, queued = fill_backlog(path)
    accepted: list[socket.socket] = []

    def accept_later() -> None:
        time.sleep(0.3)
        listener.settimeout(5.0)
        with contextlib.suppress(TimeoutError):  # the old client had given up already
            for _ in range(len(queued) + 1):
                accepted.append(listener.accept()[0])

    helper = threading.Thread(target=accept_later)
    helper.start()
    try:
        client = SupervisorClient.connect(path, timeout=5.0)
        client.close()
    finally:
        helper.join()
        for sock in [listener, *queued, *accepted]:
            sock.close()


def test_connect_gives_up_on_a_full_backlog_after_a_bounded_time(tmp_path: Path) -> None:
    """A backlog that stays full is a ConnectError after the bounded wait (here the client's
    0.3 s timeout), not a hang and not an instant failure."""
    path = tmp_path / "api.sock"
    listener, queued = fill_backlog(path)
    try:
        t0 = time.monotonic()
        with pytest.raises(ConnectError, match="busy"):
            SupervisorClient.connect(path, timeout=0.3)
        took = time.monotonic() - t0
        assert 0.2 < took < 3.0
    finally:
        for sock in [listener, *queued]:
            sock.close()
