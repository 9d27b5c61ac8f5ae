"""A small, blocking Python client of the supervisor's API for the robot's programs.

``docs/api.md`` describes the protocol this speaks (JSON lines over a Unix socket). A typical
robot program names itself and sends a heartbeat every 100 ms::

    with SupervisorClient.connect(DEFAULT_SOCKET_PATH, name="planner") as srcs:
        while running:
            srcs.heartbeat()
            time.sleep(0.1)

Every method sends one request and waits for its reply, which it returns as the typed value
of :mod:`supervisord.api.replies` (``status`` a :class:`~supervisord.api.replies.StatusReply`).
A refused request raises :class:`~supervisord.api.framing.ApiError` with the server's stable
``code``; pushes that arrive meanwhile are kept for :meth:`SupervisorClient.next_event`, as
the typed values of :mod:`supervisord.api.pushes`. Replies and pushes are read tolerantly:
fields this library does not know (a newer daemon's) are ignored. Every exception raised on
purpose is a :class:`~supervisord.errors.SrcsError`. Not thread-safe: one client per thread.

It imports only the standard library and a small, named set of this package's modules, none
of the daemon's dependencies, so that it also runs on a ROS installation's own Python inside
the ROS 2 bridge's package (docs/ros2.md "The client library"; tests/ros2/test_imports.py).
"""

from __future__ import annotations

import collections
import socket
import struct
import time
from pathlib import Path
from typing import TYPE_CHECKING, Final, TypeVar

# ClientError and ProtocolError are defined beside the protocol that raises them; this
# library's names (``__all__``).
from supervisord.api.connection import (
    MAX_REPLY_LINE,
    ClientConnection,
    ClientError,
    ErrorWithoutRequest,
    ProtocolError,
    PushReceived,
    ReplyReceived,
)

# The library's too (as its example above uses it): the alias is the explicit re-export.
from supervisord.api.framing import DEFAULT_SOCKET_PATH as DEFAULT_SOCKET_PATH  # noqa: PLC0414
from supervisord.api.framing import ApiError
from supervisord.api.ops import (
    ApiRequest,
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
    StopTest,
    Subscribe,
    Topic,
    Vibrate,
)
from supervisord.api.pushes import Push
from supervisord.api.replies import (
    CommissionReply,
    OkReply,
    Reply,
    StatusReply,
    StopTestReply,
)
from supervisord.protocol.codes import DisplayMode
from supervisord.release import Request

if TYPE_CHECKING:
    from typing_extensions import Self

R = TypeVar("R", StatusReply, CommissionReply, StopTestReply)

DEFAULT_TIMEOUT: Final = 5.0
MAX_KEPT_EVENTS: Final = 4096
BACKLOG_WAIT_S: Final = 3.0
"""The longest a full listen backlog is waited out (bounded by the client's timeout too)."""
BACKLOG_SLICE_S: Final = 0.05


class ConnectError(ClientError):
    """The socket could not be reached (no daemon, wrong path, no permission)."""


class ConnectionClosedError(ClientError):
    """The supervisor closed the connection (it stopped, or disconnected this client)."""


class ClientTimeoutError(ClientError, TimeoutError):
    """No reply came in time; the connection is closed because its replies would be out of
    step with its requests."""


__all__ = [
    "DEFAULT_SOCKET_PATH",
    "ApiError",
    "ClientError",
    "ClientTimeoutError",
    "CommissionReply",
    "ConnectError",
    "ConnectionClosedError",
    "OkReply",
    "ProtocolError",
    "Push",
    "Reply",
    "StatusReply",
    "StopTestReply",
    "SupervisorClient",
]


class SupervisorClient:
    """One connection to the supervisor. Use :meth:`connect`; close it (or use ``with``)."""

    def __init__(self, sock: socket.socket, timeout: float = DEFAULT_TIMEOUT) -> None:
        self._sock = sock
        self.timeout = timeout
        # Framing, and the pairing of replies with requests: the sans-IO connection's.
        self._protocol = ClientConnection()
        self._events: collections.deque[Push] = collections.deque(maxlen=MAX_KEPT_EVENTS)
        self.name: str | None = None

    @classmethod
    def connect(
        cls, path: str | Path, name: str | None = None, timeout: float = DEFAULT_TIMEOUT
    ) -> Self:
        """Connect to the socket at ``path`` and, with a ``name``, say hello.

        A full listen backlog (``EAGAIN``: the supervisor is accepting a burst of connections)
        is waited out for at most ``min(timeout, BACKLOG_WAIT_S)``; then, or at once for any
        other failure, it raises :class:`ConnectError`; ``ApiError`` if the hello is refused."""
        sock = _connect(Path(path), timeout)
        client = cls(sock, timeout)
        try:
            if name is not None:
                client.hello(name)
        except BaseException:
            client.close()
            raise
        return client

    # -- requests -------------------------------------------------------------------------

    def hello(self, name: str) -> None:
        """Name this connection (SR-8); required clients must, before heartbeats."""
        self.call(Hello(name))
        self.name = name

    def heartbeat(self, progress: int | None = None) -> None:
        """Tell the supervisor this client is alive (at least every timeout, default 500 ms).

        ``progress`` (0 to 2**32 - 1, wrapping to 0) is a counter the control loop moves on
        each turn: once given, a heartbeat keeps the client alive only with a new one, so a
        loop that is stuck while the heartbeat's thread goes on is lost (SR-8.16). A repeated
        or older value raises ``ApiError`` (``refused``, reason ``stale_progress``)."""
        self.call(Heartbeat(progress))

    def estop(self) -> None:
        """Ask for an e-stop: ``client_estop:NAME`` after hello, ``local_estop`` before."""
        self.call(Estop())

    def hold(self) -> None:
        """Ask for a hold (``client_hold:NAME``) until :meth:`release` of ``"hold"``."""
        self.call(Hold())

    def release(self, what: str = "estop") -> None:
        """End this client's own ``"estop"`` or ``"hold"``; a stop stays latched until re-armed."""
        self.call(Release(Request(what)))

    def command(self, nonzero: bool) -> None:
        """Declare whether the motion this client commands is non-zero (SR-4.6): while any
        client's is, no re-arm. After hello; kept until the next call or the connection's end."""
        self.call(Command(nonzero))

    def status(self) -> StatusReply:
        """The state, causes and outputs, and the daemon's own view (``docs/api.md``
        "status")."""
        return _expect(self.call(Status()), StatusReply)

    def subscribe(self, *topics: str) -> None:
        """Receive pushes of these topics (replacing earlier ones); none: unsubscribe."""
        self.call(Subscribe(frozenset(Topic(t) for t in topics)))

    def display_value(self, key: int, value: int) -> None:
        """Show ``value`` in user value ``key`` (1-9) on the remote."""
        self.call(DisplayValue(key, value))

    def display_label(self, key: int, text: str) -> None:
        """Label user value ``key`` (1-9), at most 20 characters."""
        self.call(DisplayLabel(key, text))

    def display_row(self, index: int, text: str) -> None:
        """Set text row ``index`` (1-4), at most 20 characters."""
        self.call(DisplayRow(index, text))

    def display_mode(self, mode: int | DisplayMode) -> None:
        """Choose the remote's page: 0 GPS, 1 text rows, 2 labelled values, 3 values."""
        self.call(DisplayModeRequest(DisplayMode(mode)))

    def vibrate(self, side: str = "both") -> None:
        """Vibrate the ``"left"``, ``"right"`` or ``"both"`` handles of the remote."""
        self.call(Vibrate(Side(side)))

    def reset(self) -> None:
        """A local re-arm (SR-4); root or the admin group only."""
        self.call(Reset())

    def commission(self) -> CommissionReply:
        """Turn the VSC's key-85 watchdog on and enable remote-status messages, permanently.
        Root or the admin group only; the reply carries what was read back."""
        return _expect(self.call(Commission()), CommissionReply)

    def stoptest(self, steps: tuple[tuple[str, int], ...]) -> StopTestReply:
        """Judge and record a field stop test's presses (SR-12.1): each its source
        (``remote``, ``wired``) and the ``seq`` of the stop record it made. Admins only."""
        return _expect(self.call(StopTest(steps)), StopTestReply)

    def call(self, request: ApiRequest) -> Reply:
        """Send any request and return its success reply (raises ``ApiError`` on an error)."""
        self._send(self._protocol.send(request))
        deadline = time.monotonic() + self.timeout
        while True:
            event = self._read_event(deadline)
            if isinstance(event, PushReceived):
                self._events.append(event.push)
                continue
            # The one request waits (a timeout closes the connection): this is its reply.
            reply = event.reply if isinstance(event, ReplyReceived) else event.error
            if isinstance(reply, ApiError):
                raise reply
            return reply

    def next_event(self, timeout: float | None = None) -> Push | None:
        """The next push, waiting up to ``timeout`` seconds (default: the client's timeout);
        ``None`` when none came. Pushes are kept in order, the newest 4096 at most."""
        if self._events:
            return self._events.popleft()
        deadline = time.monotonic() + (self.timeout if timeout is None else timeout)
        while True:
            try:
                event = self._read_event(deadline, closing=False)
            except ClientTimeoutError:
                return None
            if isinstance(event, PushReceived):
                return event.push
            if isinstance(event, ErrorWithoutRequest):  # e.g. too_many_clients, then closed
                raise event.error
            raise ProtocolError(f"a reply without a request: {event.reply!r}"[:200])

    # -- lifetime -------------------------------------------------------------------------

    def close(self) -> None:
        """Close the connection (the supervisor then reports the client as disconnected)."""
        self._sock.close()

    def fileno(self) -> int:
        """The socket's descriptor, to wait for pushes in a ``select`` loop."""
        return self._sock.fileno()

    def __enter__(self) -> Self:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()

    # -- inside ---------------------------------------------------------------------------

    def _send(self, line: bytes) -> None:
        if self._sock.fileno() < 0:
            raise ConnectionClosedError("the client is closed")
        try:
            self._sock.settimeout(self.timeout)
            self._sock.sendall(line)
        except TimeoutError as e:
            self.close()
            raise ClientTimeoutError("the supervisor does not read its requests") from e
        except OSError as e:
            last = self._last_words()
            self.close()
            if last is not None:  # e.g. too_many_clients, sent before the server closed
                raise last from e
            raise ConnectionClosedError(f"the connection broke: {e.strerror or e}") from e

    def _last_words(self) -> ApiError | None:
        """The error line a server sent before it closed the connection, if any."""
        try:
            self._sock.setblocking(False)
            while self._protocol.held <= MAX_REPLY_LINE and (data := self._sock.recv(65536)):
                self._protocol.receive_data(data)
        except OSError:
            pass
        return self._protocol.last_error()

    def _read_event(
        self, deadline: float, *, closing: bool = True
    ) -> ReplyReceived | PushReceived | ErrorWithoutRequest:
        while True:
            try:
                event = self._protocol.next_event()
            except ProtocolError:
                self.close()
                raise
            if event is not None:
                return event
            self._fill(deadline, closing=closing)

    def _fill(self, deadline: float, *, closing: bool) -> None:
        if self._sock.fileno() < 0:
            raise ConnectionClosedError("the client is closed")
        remaining = deadline - time.monotonic()
        try:
            if remaining <= 0:
                raise TimeoutError
            self._sock.settimeout(remaining)
            data = self._sock.recv(65536)
        except TimeoutError as e:
            if closing:
                self.close()
            raise ClientTimeoutError("no answer from the supervisor in time") from e
        except OSError as e:
            self.close()
            raise ConnectionClosedError(f"the connection broke: {e.strerror or e}") from e
        if not data:
            self.close()
            raise ConnectionClosedError("the supervisor closed the connection")
        self._protocol.receive_data(data)


def _connect(path: Path, timeout: float) -> socket.socket:
    """A connected socket (in ``timeout`` mode), waiting out a full listen backlog.

    The wait is the kernel's own: a blocking ``connect`` with a send timeout sleeps until the
    server accepts and makes room, in slices so a missed wake-up costs one slice at most. The
    server's backlog is large (docs/api.md "The socket"), but connection churn by other
    programs can still fill it, and the operator's ``srcsctl estop`` must not fail on that
    (SR-8.4: without the wait, 7 of 10 ``srcsctl status`` calls failed at once under churn)."""
    budget = max(0.0, min(timeout, BACKLOG_WAIT_S))
    deadline = time.monotonic() + budget
    while True:
        sock = socket.socket(socket.AF_UNIX, socket.SOCK_STREAM)
        try:
            remaining = max(0.001, min(BACKLOG_SLICE_S, deadline - time.monotonic()))
            seconds = int(remaining)
            wait = struct.pack("ll", seconds, int((remaining - seconds) * 1e6))
            sock.settimeout(None)  # blocking, whatever socket.setdefaulttimeout says
            sock.setsockopt(socket.SOL_SOCKET, socket.SO_SNDTIMEO, wait)
            sock.connect(str(path))
            sock.setsockopt(socket.SOL_SOCKET, socket.SO_SNDTIMEO, struct.pack("ll", 0, 0))
            sock.settimeout(timeout)
            return sock
        except BlockingIOError as e:  # EAGAIN: the backlog stayed full for the whole slice
            sock.close()
            if time.monotonic() >= deadline:
                raise ConnectError(
                    f"cannot connect to {path}: the supervisor is busy (its listen backlog "
                    f"stayed full for {budget:.1f} s)"
                ) from e
        except OSError as e:
            sock.close()
            raise ConnectError(f"cannot connect to {path}: {e.strerror or e}") from e


def _expect(reply: Reply, kind: type[R]) -> R:
    """The reply as the type its request gets (a reply of another op is out of step)."""
    if not isinstance(reply, kind):
        raise ProtocolError(f"a {reply.json().get('op')!r} reply where {kind.__name__} belongs")
    return reply
