"""The client API server: a non-blocking Unix socket driven by the daemon's one loop.

SR-8 and ``docs/api.md``. There are no threads. Before each wait the loop asks
:meth:`ApiServer.descriptors` which descriptors to watch (and which have output waiting), and
hands every ready one back to :meth:`ApiServer.handle`. What happens is queued, in order, and
the daemon takes it with :meth:`ApiServer.take`, one result at a time:

- :class:`Accepted` - a client connected (``ClientConnected`` for the core);
- :class:`Received` - a valid request the daemon must act on and answer with :meth:`reply`
  or :meth:`reply_error`, exactly once (before it takes the next result, but for the few
  answered later, as ``commission``);
- :class:`Denied` - an admin-only request from a non-admin, already answered ``not_allowed``;
- :class:`Closed` - a connection ended (``ClientDisconnected``), queued once per
  :class:`Accepted`, wherever it ended: while reading, while answering, while pushing.

One queue is the one place the daemon learns of every end, so no end can be dropped on the
way (a lost ``Closed`` would keep its client's name in use in the core). A request is turned
into its result only when it is taken, so it sees the answers to the requests before it: a
``hello`` answered ok names the connection for the requests after it, even in one write.

**Replies leave in the order the requests came** (``docs/api.md`` "Framing"), on each
connection, whatever answers them (the server at once, for a malformed line, or the daemon,
later): every request line read takes its place in its connection's order, and a reply
waits until every reply before it has left. A client that pipelines without ids reads each
reply as its own request's. Pushes are no replies: they leave at once.

**A malformed e-stop or hold still stops** (SR-8.13): a line refused as malformed whose op
can still be read as ``estop`` or ``hold`` (:func:`~supervisord.api.requests.read_request`)
is acted on as that request, and its reply is the error that says what was wrong, with
``"honoured": true``.

The server holds no rules of the safety core's: whether a ``hello`` may name the connection
(a second hello, a name in use, a client bound to another user) is the core's to judge; the
daemon answers with the core's refusal (:func:`~supervisord.api.views.refusal_error`).

:func:`core_event` turns a result into the safety core's event. Every socket is
non-blocking; output waits in a bounded buffer per connection, and a client whose buffer
overflows (stopped, or too slow to read) is disconnected: it can never block the loop.

Two rules keep the stop path open whatever the other programs do (SR-8.4,
``docs/safety.md`` "The client socket cannot shut out a stop"):

- **e-stop slots**: past ``max_clients`` a connection takes one of ``reserved_slots`` slots on
  which only ``estop`` and ``status`` are served; an admin's connection evicts a non-admin's
  from a full reserve, and a slot idle for ``slot_idle_ms`` is closed;
- **a read budget**: one :meth:`ApiServer.handle` call handles at most ``requests_per_call``
  requests of a connection, and one turn (from one :meth:`ApiServer.descriptors` call to the
  next) at most ``requests_per_turn`` shared evenly among the connections; what is not read
  stays in the socket, so its descriptor is readable again next turn;
- **an operator socket** (SR-8.14): a second listening socket at ``operator_path`` that only
  root and ``operator_group`` can reach, with its own backlog and its own
  ``operator_max_clients`` connections, outside ``max_clients`` and the e-stop slots, accepted
  first whenever the server is handed a listening socket (:meth:`ApiServer.urgent` tells the
  loop to hand it first). The same protocol, every op but a robot program's (``heartbeat``,
  ``command``). Past its connections it has e-stop slots of its own, ``reserved_slots`` more,
  with the client socket's rules (SR-8.17): whatever its members hold, root's e-stop gets in;
- **accepting never spins** (SR-10.4): an ``accept`` that fails for lack of a resource
  (descriptors, memory) leaves the connection in the backlog, so the listening socket stays
  readable; the server then stops watching its listening sockets until a descriptor of its
  own is released or ``ACCEPT_PAUSE_NS`` has passed, and says so once a minute at most.
"""

from __future__ import annotations

import collections
import contextlib
import enum
import errno
import logging
import os
import socket
import stat
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import TYPE_CHECKING, Final

from supervisord.api.connection import (
    DEFAULT_MAX_OUTPUT,
    Flooded,
    LineRefused,
    Place,
    RequestLine,
    ServerConnection,
    server_line,
)
from supervisord.api.credentials import caller, group_id, peer_credentials, user_name
from supervisord.api.framing import (
    DEFAULT_MAX_DISCARD,
    DEFAULT_MAX_LINE,
    DEFAULT_SOCKET_PATH,
    ApiError,
    ErrorCode,
    staging_socket_path,
)
from supervisord.api.names import NAME_POLL_NS, NAME_WAIT_NS, UserNames
from supervisord.api.pushes import Push
from supervisord.api.replies import OkReply, Reply
from supervisord.api.requests import (
    ADMIN_REQUESTS,
    NAMED_REQUESTS,
    ApiRequest,
    Command,
    Estop,
    FleetStopRequest,
    Heartbeat,
    Hello,
    Status,
    Subscribe,
    Topic,
    honoured_error,
    read_request,
)
from supervisord.api.translate import ClientInfo, to_core_event
from supervisord.api.views import ok_reply
from supervisord.errors import ConfigError, SrcsError
from supervisord.safety.events import ClientConnected, ClientDisconnected, ClientHello, Event
from supervisord.timebase import NS_PER_MS

if TYPE_CHECKING:
    from typing_extensions import Self

DEFAULT_MODE: Final = 0o660
DEFAULT_MAX_CLIENTS: Final = 16
MAX_CLIENTS_RANGE: Final = (1, 256)
"""``api.max_clients``: the one range, for the robot's file as for a server built in code."""
MAX_LINE_RANGE: Final = (256, 1 << 20)
"""``api.max_message_bytes`` (``max_line`` here): the one range, as ``MAX_CLIENTS_RANGE``."""
RECV_SIZE: Final = 16 * 1024  # bytes looked at per readable event: bounded work per loop turn
ACCEPTS_PER_CALL: Final = 32
# Connections the kernel queues before we accept them. Under connect/disconnect churn 16 was
# full at once and the operator's srcsctl got EAGAIN (SR-8.4); the kernel caps it at
# net.core.somaxconn. The client also retries a full backlog briefly (supervisord/client.py).
BACKLOG: Final = 512
DEFAULT_RESERVED_SLOTS: Final = 4
DEFAULT_SLOT_IDLE_MS: Final = 1000
DEFAULT_REQUESTS_PER_CALL: Final = 8
DEFAULT_REQUESTS_PER_TURN: Final = 64
DEFAULT_OPERATOR_MAX_CLIENTS: Final = 8
ACCEPT_PAUSE_NS: Final = 100 * NS_PER_MS
"""How long the listening sockets go unwatched after ``accept`` failed for lack of a resource
(SR-10.4), unless a descriptor is released sooner: the connection waits in the backlog, and
a retry costs two system calls a tenth of a second, not a loop turn each."""
ACCEPT_SAY_NS: Final = 60_000 * NS_PER_MS
"""At most one log line about failed accepts per minute (SR-10.4), with the count since."""
OPERATOR_MODE_GROUP: Final = 0o660  # root, the daemon's user and operator_group (SR-8.14)
OPERATOR_MODE_OWNER: Final = 0o600  # no operator_group: root and the daemon's user only
ROBOT_REQUESTS: Final = (Heartbeat, Command)
"""What the operator socket does not serve: a robot program's own requests (SR-8.14), which
belong on the client socket, where ``api.max_clients`` counts them."""
SLOT_REQUESTS: Final = (Estop, Status)
"""What an e-stop slot serves: the operator's stop and a look at the state (docs/api.md)."""
NAMELESS_REQUESTS: Final = (Estop, Status, FleetStopRequest)
"""What a connection is served while its user's name is being looked up (SR-10.3): what
needs no name (a fleet stop is judged by the peer's uid, SR-8.19, and must not wait). Its
other requests wait, in order, until the name is known."""
MAX_DEFERRED: Final = 64
"""Requests read and kept waiting for a name, per connection; past it the rest stay in the
socket (read once the name is known)."""


log = logging.getLogger("srcsd")


class ServerError(SrcsError):
    """The server cannot start at its path; the message names the path and the fix."""


@dataclass(frozen=True, slots=True)
class ServerConfig:
    """Where and how the API socket is served (``docs/api.md`` "Configuration").

    ``mode`` must not let others write (connect to) the socket; ``group`` owns the socket
    file (``None``: the daemon's group); ``admin_group`` grants ``reset`` and ``commission``
    (``None``: only root). ``known_uids``: users whose login names are looked up at start
    (the bound clients' users), so that their connections never wait for a name (SR-10.3).
    ``reserved_slots``, ``slot_idle_ms``, ``requests_per_call`` and ``requests_per_turn`` are
    the limits of the module docstring. ``operator_path`` (``None``: none) is the operator
    socket (SR-8.14), mode 0660 and group ``operator_group``, or mode 0600 without one; it
    takes ``operator_max_clients`` connections.
    Raises :class:`ConfigError` for a value out of range.
    """

    path: Path = DEFAULT_SOCKET_PATH
    mode: int = DEFAULT_MODE
    group: str | None = None
    admin_group: str | None = None
    max_clients: int = DEFAULT_MAX_CLIENTS
    max_line: int = DEFAULT_MAX_LINE
    max_discard: int | None = None
    max_output: int = DEFAULT_MAX_OUTPUT
    known_uids: tuple[int, ...] = ()
    reserved_slots: int = DEFAULT_RESERVED_SLOTS
    slot_idle_ms: int = DEFAULT_SLOT_IDLE_MS
    requests_per_call: int = DEFAULT_REQUESTS_PER_CALL
    requests_per_turn: int = DEFAULT_REQUESTS_PER_TURN
    operator_path: Path | None = None
    operator_group: str | None = None
    operator_max_clients: int = DEFAULT_OPERATOR_MAX_CLIENTS

    @property
    def operator_mode(self) -> int:
        """The operator socket's mode: its group may connect only if there is one."""
        return OPERATOR_MODE_GROUP if self.operator_group is not None else OPERATOR_MODE_OWNER

    @property
    def discard_limit(self) -> int:
        """Bytes of one over-long line discarded before the sender is disconnected."""
        return (
            self.max_discard
            if self.max_discard is not None
            else max(DEFAULT_MAX_DISCARD, 4 * self.max_line)
        )

    def __post_init__(self) -> None:
        object.__setattr__(self, "path", Path(self.path))
        if self.operator_path is not None:
            object.__setattr__(self, "operator_path", Path(self.operator_path))
            if self.operator_path == self.path:
                raise ConfigError(
                    "api.operator_socket", str(self.operator_path), "use a path of its own"
                )
        if not isinstance(self.mode, int) or self.mode & ~0o770 or not self.mode & 0o200:
            raise ConfigError(
                "api.mode", self.mode, "use 0600, 0620 or 0660: owner and group only, never others"
            )
        for key, value, low, high in (
            ("api.max_clients", self.max_clients, *MAX_CLIENTS_RANGE),
            ("api.max_line", self.max_line, *MAX_LINE_RANGE),
            ("api.max_discard", self.discard_limit, self.max_line, 1 << 26),
            ("api.max_output", self.max_output, 4096, 1 << 28),
            ("api.reserved_slots", self.reserved_slots, 1, 64),
            ("api.slot_idle_ms", self.slot_idle_ms, 10, 60_000),
            ("api.requests_per_call", self.requests_per_call, 1, 1024),
            ("api.requests_per_turn", self.requests_per_turn, 1, 1 << 16),
            ("api.operator_max_clients", self.operator_max_clients, 1, 256),
        ):
            if isinstance(value, bool) or not isinstance(value, int) or not low <= value <= high:
                raise ConfigError(key, value, f"use a whole number from {low} to {high}")


class CloseReason(enum.Enum):
    """Why a connection ended: closed by the peer, broken by the world, or closed by us."""

    PEER_CLOSED = "peer_closed"  # the client closed its end
    BROKEN = "broken"  # a read or write failed (e.g. connection reset)
    OUTPUT_OVERFLOW = "output_overflow"  # the client did not read its replies and pushes
    FLOOD = "flood"  # the client sent an endless line
    SHUTDOWN = "shutdown"  # the server closed
    EVICTED = "evicted"  # an e-stop slot taken over by an admin, or left idle


@dataclass(frozen=True, slots=True)
class Accepted:
    client: ClientInfo


@dataclass(frozen=True, slots=True)
class Received:
    """A valid request; ``client`` is the connection as it was when the request was taken
    (named once a ``hello`` was answered ok). ``place`` is where its reply goes in its
    connection's order (the server's own)."""

    client: ClientInfo
    request: ApiRequest
    place: Place = field(compare=False, repr=False)


@dataclass(frozen=True, slots=True)
class Denied:
    """A request the server refused for lack of rights, already answered with ``error``."""

    client: ClientInfo
    request: ApiRequest
    error: ApiError


@dataclass(frozen=True, slots=True)
class Closed:
    client: ClientInfo
    reason: CloseReason


Result = Accepted | Received | Denied | Closed


def core_event(result: Result, now: int) -> Event | None:
    """The safety core's event for one server result at ``now``, or ``None``.

    A :class:`Denied` ``reset`` still becomes a ``ResetRequest`` (with ``admin`` false), so
    the core refuses it and the refusal is recorded (SR-4, SR-7)."""
    match result:
        case Accepted(client=client):
            return ClientConnected(now, client.connection, client.caller.uid)  # SR-8.5
        case Closed(client=client):
            return ClientDisconnected(now, client.connection)
        case Received(client=client, request=Hello(name=name)):
            # With the caller, so the core checks a bound client's user and records a refused
            # hello (docs/safety.md "Clients bound to a user").
            return ClientHello(now, client.connection, name, client.caller)
        case Received(client=client, request=request) | Denied(client=client, request=request):
            return to_core_event(request, client, now)


class _Connection:
    __slots__ = (
        "accepted",
        "credentials",
        "dead",
        "deferred",
        "info",
        "last_ns",
        "naming_until",
        "operator",
        "protocol",
        "slot",
        "sock",
        "taken",
        "topics",
        "turn",
        "writing",
    )

    def __init__(self, sock: socket.socket, info: ClientInfo, protocol: ServerConnection) -> None:
        # The framing, the reply order and the output buffer: the sans-IO connection's.
        self.sock, self.info, self.protocol = sock, info, protocol
        self.naming_until: int | None = None  # its user's name is awaited until then (SR-10.3)
        self.deferred: list[_Waiting] = []  # requests that wait for that name, in order
        self.topics: frozenset[Topic] = frozenset()
        self.accepted = True  # reported as Accepted, so its end is reported as Closed
        self.dead = False  # ended: shut down, its descriptor released at the next descriptors()
        self.slot = False  # an e-stop slot: estop and status only, never reported to the core
        self.operator = False  # came through the operator socket (SR-8.14)
        self.last_ns = 0  # when it was accepted or last sent a request (e-stop slots expire)
        self.taken = 0  # requests handled in turn ``turn`` (the read budget)
        self.turn = 0  # the server's turn ``taken`` counts in: an older one counts as 0
        self.writing = False  # whether the loop watches it for writing (output waits)

    @property
    def naming(self) -> bool:
        return self.naming_until is not None


@dataclass(frozen=True, slots=True)
class _Waiting:
    """A request read and queued: checked and turned into its result when it is taken."""

    conn: _Connection
    request: ApiRequest
    place: Place


_Queued = Accepted | Closed | _Waiting


class ApiServer:
    """The API socket at ``config.path``, its connections and their buffers.

    Construction creates the socket (mode ``config.mode``, group ``config.group``). A stale
    socket file left by a crash is replaced; a path that is not a socket, or a socket another
    server still listens on, raises :class:`ServerError` and nothing is changed.
    :meth:`close` ends every connection and removes the socket file.

    A connection that ends is shut down at once (its peer sees the end), but its descriptor
    stays open until the next :meth:`descriptors` call, so the loop can drop it from its
    watch list before the number can be reused by a new connection.

    Nothing is returned by the calls that do I/O: what happens is queued for :meth:`take`.
    """

    def __init__(self, config: ServerConfig, names: UserNames | None = None) -> None:
        self.config = config
        self._admin_gid = group_id(config.admin_group)
        socket_gid = group_id(config.group, "api.group")
        operator_gid = group_id(config.operator_group, "api.operator_group")
        self._own_uid = os.geteuid()
        self._connections: dict[int, _Connection] = {}  # by connection number
        self._by_fd: dict[int, _Connection] = {}
        self._ended: list[socket.socket] = []
        self._results: collections.deque[_Queued] = collections.deque()  # for take(), in order
        self._next_number = 1
        self._closed = False
        self._share = config.requests_per_call  # requests per connection in this turn
        self._turn_left = config.requests_per_turn
        self._turn = 0  # counts descriptors() calls with connections: a connection's
        # ``taken`` of an older turn is 0, so a turn renews no connection one by one (SR-9.4)
        # What the loop watches while connections are open, kept until a descriptor comes or
        # goes, starts or stops waiting to write, or the listening sockets' pause changes: the
        # same list turn after turn, which the loop compares and leaves alone (SR-9.4).
        self._watched: list[tuple[int, bool]] | None = None
        self._watched_paused = False
        # Whether a connection may have a deadline (an e-stop slot, or a name awaited): false
        # only once a look found none, so a turn of named clients asks none (SR-9.4).
        self._timed = False
        self._topics: frozenset[Topic] = frozenset()  # the topics some connection wants
        # accept failed for lack of a resource: the listening sockets unwatched until then
        # (SR-10.4); the failures not yet said, and when the last line said them
        self._accept_paused_until: int | None = None
        self._accept_failures = 0
        self._accept_said: int | None = None
        self._listener, self._identity = _listen(config.path, config.mode, socket_gid)
        self._listen_fd = self._listener.fileno()
        self._operator: socket.socket | None = None
        self._operator_identity = (0, 0)
        if config.operator_path is not None:
            try:
                self._operator, self._operator_identity = _listen(
                    config.operator_path, config.operator_mode, operator_gid
                )
            except ServerError:  # a start that fails removes the socket it made (rule 4)
                self._listener.close()
                _unlink_if_ours(config.path, self._identity)
                raise
        self._operator_fd = self._operator.fileno() if self._operator is not None else -1
        # Login names are looked up off the loop (SR-10.3); the users known ahead are asked for
        # now, so their connections never wait. Made once the socket is ours: nothing to undo.
        self._names = names if names is not None else UserNames(user_name)
        # The next turn that looks for a finished lookup while a connection waits for its
        # name: the loop's own deadline, as no lookup wakes it (SR-10.7).
        self._names_look_at: int | None = None
        self._idle_watched = self._sockets_watched()  # what a turn without connections watches
        for uid in (0, self._own_uid, *config.known_uids):
            self._names.ask(uid)

    # -- the loop's side ------------------------------------------------------------------

    def descriptors(self, now: int) -> list[tuple[int, bool]]:
        """``(fd, wants_write)`` for every descriptor to watch now: the listening sockets and
        each connection (always for reading). Releases the
        descriptors of ended connections, so call it once per turn, before the wait, and watch
        exactly what it returns. ``now``: the loop's clock, as for every method here."""
        # No lookup wakes the loop (SR-10.7): while one is out and someone is connected (a
        # connection may wait for that name), the loop looks at its own deadline, every
        # NAME_POLL_NS, kept across the turns in between (a busy loop still gets there).
        if not self._connections or not self._names.waiting():  # no call in a turn alone
            self._names_look_at = None
        elif self._names_look_at is None:
            self._names_look_at = now + NAME_POLL_NS
        if (
            not self._connections
            and not self._ended
            and not self._by_fd
            and not self._closed
            and self._accept_paused_until is None
        ):
            # Nobody connected, the usual turn (SR-9.4): the budget a turn of no connection
            # gets and the same list as the last such turn (the loop compares it and leaves
            # its watches alone); the caller must not change it.
            config = self.config
            self._share = max(1, min(config.requests_per_call, config.requests_per_turn))
            self._turn_left = config.requests_per_turn
            return self._idle_watched
        self._release_ended()
        if self._closed:
            return []
        self._new_turn(now)
        paused = self._accept_paused_until
        if paused is not None and now >= paused:
            self._accept_paused_until = paused = None  # the short deadline passed: try again
        watched = self._watched
        if watched is not None and self._watched_paused is (paused is not None):
            return watched  # nothing came, went or began or ended waiting to write
        # While paused the listening sockets are not watched: their backlog keeps them
        # readable, and a watched readable socket that cannot be accepted is a spin (SR-10.4).
        watched = self._sockets_watched() if paused is None else []
        for fd, conn in self._by_fd.items():
            conn.writing = bool(conn.protocol.outgoing)
            watched.append((fd, conn.writing))
        self._watched, self._watched_paused = watched, paused is not None
        return watched

    def _sockets_watched(self) -> list[tuple[int, bool]]:
        """The listening sockets' descriptors, for reading."""
        watched = [(self._listen_fd, False)]
        if self._operator is not None:
            watched.insert(0, (self._operator_fd, False))
        return watched

    def next_deadline(self) -> int | None:
        """When :meth:`due` has work: an idle e-stop slot to close or paused accepts to try
        again (both in :meth:`descriptors`) or a name waited for long enough, if any."""
        look = self._names_look_at  # set only while someone is connected (SR-10.7)
        if not self._connections or not self._timed:
            # None, the usual case, asked twice a turn (SR-9.4): no connection, or none that
            # is an e-stop slot or awaits its name.
            paused = self._accept_paused_until
            if look is None:
                return paused
            return look if paused is None else min(look, paused)
        idle = self.config.slot_idle_ms * NS_PER_MS
        ends = [
            end
            for c in self._connections.values()
            if (end := c.last_ns + idle if c.slot else c.naming_until) is not None
        ]
        self._timed = bool(ends)  # none: not looked for again until a connection may have one
        if self._accept_paused_until is not None:
            ends.append(self._accept_paused_until)
        if look is not None:
            ends.append(look)
        return min(ends) if ends else None

    def due(self, now: int) -> None:
        """Connections whose user's name did not come within ``NAME_WAIT_NS`` go on under
        their uid (SR-10.3): what they sent meanwhile is queued now. A name found meanwhile
        is taken first (SR-10.7)."""
        if self._names_look_at is not None and now >= self._names_look_at:
            self._names_look_at = None  # the next turn sets the next look, if still needed
            self._names_known(now)
        for conn in list(self._connections.values()):
            if conn.naming_until is not None and now >= conn.naming_until:
                self._named(conn, conn.info.caller.name)

    def urgent(self) -> frozenset[int]:
        """The descriptors the loop serves before every other client descriptor, outside its
        per-turn count: the operator socket's (SR-8.14), so no number of busy connections
        delays the operator's accept."""
        return frozenset((self._operator_fd,)) if self._operator is not None else frozenset()

    def turn_limit(self) -> int:
        """The most requests one turn can hand to the loop: ``requests_per_turn``, or one per
        connection when there are more connections than that (every one gets its turn)."""
        return max(self.config.requests_per_turn, len(self._connections))

    def handle(self, fd: int, readable: bool, writable: bool, now: int) -> None:
        """Act on one ready descriptor; what happened is queued for :meth:`take`."""
        if self._closed:
            return
        if fd in (self._listen_fd, self._operator_fd):
            if readable:
                # The operator's waiting connections first, whichever socket is ready
                # (SR-8.14): a turn that accepts churn accepts the operator before it.
                self.accept_operators(now)
                if fd == self._listen_fd:
                    self.accept(now)
        else:
            if writable:
                self.on_writable(fd)
            if readable:
                self.on_readable(fd, now)

    def take(self) -> Result | None:
        """The next result, in the order things happened, or ``None`` when there is none.

        A request is checked when it is taken, so answer each :class:`Received` before taking
        the next: the answer to a ``hello`` names the connection for what follows. Requests of
        a connection that ended before they were taken are dropped (nobody is there to answer);
        its :class:`Closed` comes after them."""
        queue = self._results
        while queue:
            item = queue.popleft()
            if not isinstance(item, _Waiting):
                return item
            if not item.conn.dead:
                result = self._serve(item)
                if result is not None:
                    return result
        return None

    def accept(self, now: int) -> None:
        """Accept the waiting connections (a bounded number per call)."""
        self._accept_from(self._listener, now, operator=False)

    def accept_operators(self, now: int) -> None:
        """Accept the operator socket's waiting connections (SR-8.14), a bounded number."""
        if self._operator is not None:
            self._accept_from(self._operator, now, operator=True)

    def _accept_from(self, listener: socket.socket, now: int, *, operator: bool) -> None:
        if self._accept_paused_until is not None:
            return  # handed a socket made ready before the pause: its turn comes after it
        for _ in range(ACCEPTS_PER_CALL):
            try:
                sock, _address = listener.accept()
            except (BlockingIOError, InterruptedError):
                return
            except ConnectionAbortedError:
                continue  # that peer gave up in the backlog; the next one is there
            except OSError as error:  # out of descriptors or memory, or worse (SR-10.4)
                self._pause_accepts(now, error)
                return
            self._adopt(sock, now, operator=operator)

    def _pause_accepts(self, now: int, error: OSError) -> None:
        """``accept`` failed and the connection stays in the backlog, its socket readable:
        stop watching the listening sockets until a descriptor of ours is released or
        :data:`ACCEPT_PAUSE_NS` has passed, so the loop does not spin on it (SR-10.4), and
        say so at most once per :data:`ACCEPT_SAY_NS`, with how often it failed since."""
        self._accept_paused_until = now + ACCEPT_PAUSE_NS
        self._accept_failures += 1
        said = self._accept_said
        if said is None or now - said >= ACCEPT_SAY_NS:
            log.warning(
                "cannot accept API connections: %s (%d time(s) since the last such line); "
                "they wait in the backlog until a descriptor is free, tried again every %d ms",
                error.strerror or error,
                self._accept_failures,
                ACCEPT_PAUSE_NS // NS_PER_MS,
            )
            self._accept_said, self._accept_failures = now, 0

    def on_readable(self, fd: int, now: int) -> None:
        """Read what one connection sent and queue its requests (and its end, if it ended).

        At most the connection's share of this turn's budget is read: lines past it stay in
        the socket, which is therefore readable again on the next turn (SR-10.1: one client
        pipelining 16 KiB of requests used to make ~350 requests, each a record, in one turn)."""
        conn = self._by_fd.get(fd)
        if conn is None:
            return
        if conn.turn != self._turn:  # its first read in this turn: its share is whole
            conn.turn, conn.taken = self._turn, 0
        allowed = min(self._share - conn.taken, self._turn_left)
        if allowed <= 0 or len(conn.deferred) >= MAX_DEFERRED:
            return  # its share of this turn is used: the rest waits in the socket
        try:
            data = self._receive_lines(conn.sock, allowed)
        except (BlockingIOError, InterruptedError):
            return
        except OSError:
            self._end(conn, CloseReason.BROKEN)
            return
        if not data:
            if conn.protocol.outgoing:  # a peer that only shut down its sending side gets it
                with contextlib.suppress(OSError):
                    conn.sock.send(conn.protocol.outgoing, socket.MSG_NOSIGNAL)
            self._end(conn, CloseReason.PEER_CLOSED)
            return
        for event in conn.protocol.receive_data(data):
            if isinstance(event, Flooded):
                self._queue(conn, server_line(event.error))
                self._end(conn, CloseReason.FLOOD)
                return
            conn.taken += 1
            self._turn_left -= 1
            if isinstance(event, LineRefused):
                self._answer(conn, event.place, server_line(event.error))
            elif isinstance(event, RequestLine):
                self._dispatch(conn, event, now)
            if conn.dead:  # ended while answering: nothing more to read
                return

    def on_writable(self, fd: int) -> None:
        """Send what waits for one connection."""
        conn = self._by_fd.get(fd)
        if conn is not None and conn.protocol.outgoing:
            self._flush(conn)

    # -- the daemon's side ----------------------------------------------------------------

    def reply(self, received: Received, reply: Reply | None = None) -> None:
        """Answer a request with success: ``reply``, else the plain ok of its op. Nothing
        happens if the connection is gone. A ``hello`` answered ok names the connection: the
        daemon says ok only when the safety core took the name."""
        conn = self._connections.get(received.client.connection)
        if conn is None:
            return
        if isinstance(received.request, Hello):
            conn.info = replace(conn.info, name=received.request.name)
        malformed = received.place.malformed
        if malformed is not None:  # honoured, but what was wrong is said (SR-8.13)
            line = server_line(honoured_error(malformed, received.request))
        elif reply is None and received.request.id is None:
            line = _ok_line(received.request.OP)  # a heartbeat's, mostly: made once (SR-9.4)
        else:
            line = server_line(reply if reply is not None else ok_reply(received.request))
        self._answer(conn, received.place, line)

    def reply_error(self, received: Received, error: ApiError) -> None:
        """Answer a request with an error (e.g. :func:`~supervisord.api.views.refusal_error`)."""
        conn = self._connections.get(received.client.connection)
        if conn is not None:
            self._answer(conn, received.place, server_line(error))

    def send(self, connection: int, message: Reply | Push) -> None:
        """Send one reply or push to one connection (if it is still there)."""
        self._send_line(connection, server_line(message))

    def _send_line(self, connection: int, line: bytes) -> None:
        conn = self._connections.get(connection)
        if conn is not None:
            self._queue(conn, line)

    def broadcast(self, topic: Topic, push: Push) -> None:
        """Send one push to every connection subscribed to ``topic``."""
        line: bytes | None = None
        for conn in list(self._connections.values()):
            if topic in conn.topics:
                line = line if line is not None else server_line(push)
                self._queue(conn, line)

    def subscribed(self, topic: Topic) -> bool:
        """Whether any connection wants ``topic`` (so a push is worth building)."""
        # Asked per input (SR-9.4): the topics are gathered when a subscription comes or a
        # connection goes, not looked up connection by connection.
        return topic in self._topics

    def _gather_topics(self) -> None:
        """The topics some open connection wants (:meth:`subscribed`)."""
        self._topics = frozenset().union(*(c.topics for c in self._connections.values()))

    def clients(self) -> tuple[ClientInfo, ...]:
        """The open connections, oldest first."""
        return tuple(c.info for c in self._connections.values() if c.accepted)

    @property
    def path(self) -> Path:
        return self.config.path

    def close(self) -> None:
        """End every connection and remove the socket file (only if it is still ours).

        The ends not reported before are queued for :meth:`take`; closing twice does
        nothing."""
        if self._closed:
            return
        self._closed = True
        for conn in list(self._connections.values()):
            self._end(conn, CloseReason.SHUTDOWN)
        self._release_ended()
        self._listener.close()
        self._names.close()
        _unlink_if_ours(self.config.path, self._identity)
        if self._operator is not None and self.config.operator_path is not None:
            self._operator.close()
            _unlink_if_ours(self.config.operator_path, self._operator_identity)

    def __enter__(self) -> Self:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()

    # -- inside ---------------------------------------------------------------------------

    @staticmethod
    def _receive_lines(sock: socket.socket, lines: int) -> bytes:
        """Take from the socket at most ``lines`` lines (or the start of one long line): a
        look first, then exactly those bytes, so the rest stays in the kernel's buffer."""
        data = sock.recv(RECV_SIZE, socket.MSG_PEEK)
        end = 0
        for _ in range(lines):
            newline = data.find(b"\n", end)
            if newline < 0:
                end = len(data)
                break
            end = newline + 1
        if not data:
            return sock.recv(1)  # the end of the stream (or an error), as a plain read says
        return sock.recv(end)

    def _release_ended(self) -> None:
        if not self._ended:
            return
        for sock in self._ended:
            sock.close()
        self._ended.clear()
        self._accept_paused_until = None  # a descriptor is free: accept again (SR-10.4)

    def _new_turn(self, now: int) -> None:
        """A turn begins: the read budget is shared anew and idle e-stop slots are closed."""
        config = self.config
        even = config.requests_per_turn // max(1, len(self._connections))
        self._share = max(1, min(config.requests_per_call, even))
        self._turn_left = max(config.requests_per_turn, len(self._connections))
        self._turn += 1  # every connection's ``taken`` is 0 from here (``on_readable``)
        if not self._timed:
            return  # no e-stop slot is open (SR-9.4: no look at each connection)
        idle = config.slot_idle_ms * NS_PER_MS
        for conn in list(self._connections.values()):
            if conn.slot and now - conn.last_ns >= idle:
                self._refuse_slot(conn, "an e-stop slot left idle is closed")

    def _adopt(self, sock: socket.socket, now: int, *, operator: bool = False) -> None:
        sock.setblocking(False)
        try:
            credentials = peer_credentials(sock)
        except OSError:
            sock.close()
            return
        # The name from the cache, or not yet: the lookup is made off the loop (SR-10.3).
        # Lookups finished since the last look are taken first (SR-10.7: none woke the loop).
        self._names_known(now)
        name = self._names.name(credentials.uid, now)
        who = caller(credentials, self._admin_gid, own_uid=self._own_uid, name=name)
        number = self._next_number
        self._next_number += 1
        protocol = ServerConnection(
            self.config.max_line, self.config.discard_limit, self.config.max_output
        )
        conn = _Connection(sock, ClientInfo(number, who), protocol)
        conn.last_ns = now
        if name is None:
            conn.naming_until = now + NAME_WAIT_NS
            self._timed = True
        conn.operator = operator
        # Each socket's own count: the operator socket's is outside max_clients and the
        # client socket's e-stop slots (SR-8.14), so no robot program can fill it.
        held = sum(not c.slot and c.operator is operator for c in self._connections.values())
        self._connections[number] = conn
        self._by_fd[sock.fileno()] = conn
        self._watched = None  # a descriptor more to watch
        if held < (self.config.operator_max_clients if operator else self.config.max_clients):
            self._results.append(Accepted(conn.info))
            return
        # Every ordinary slot of its socket is taken: an e-stop slot of that socket's own
        # reserve, so the operator's stop gets through (docs/safety.md "The client socket
        # cannot shut out a stop"; on the operator socket, SR-8.17).
        conn.accepted, conn.slot = False, True
        self._timed = True  # its idle end (next_deadline, _new_turn)
        slots = [
            c
            for c in self._connections.values()
            if c.slot and c.operator is operator and c is not conn
        ]
        if len(slots) >= self.config.reserved_slots:
            others = [c for c in slots if not c.info.caller.admin]
            if who.admin and others:
                self._refuse_slot(others[0], "an admin needed this e-stop slot")
            else:
                self._refuse_slot(conn, "and every e-stop slot is taken")

    def _full(self, conn: _Connection) -> str:
        """What a refusal on ``conn``'s socket says first: that socket's limit."""
        if conn.operator:
            return (
                f"the operator socket takes at most {self.config.operator_max_clients} connections"
            )
        return f"the server takes at most {self.config.max_clients} clients"

    def _refuse_slot(self, conn: _Connection, why: str) -> None:
        """Close an e-stop slot with one ``too_many_clients`` line (a fresh socket has room)."""
        error = ApiError(ErrorCode.TOO_MANY_CLIENTS, f"{self._full(conn)}; {why}")
        self._queue(conn, server_line(error))
        self._end(conn, CloseReason.EVICTED)

    def _names_known(self, now: int) -> None:
        """Names the lookup thread found: each waiting connection of those users goes on, and
        a connection already going on under its uid is named from now on."""
        for uid, name in self._names.take(now):
            for conn in list(self._connections.values()):
                if conn.info.caller.uid == uid:
                    self._named(conn, name)

    def _named(self, conn: _Connection, name: str) -> None:
        """``conn``'s caller is ``name`` from now on; the requests it kept waiting are queued,
        in the order they came."""
        if name != conn.info.caller.name:
            conn.info = replace(conn.info, caller=replace(conn.info.caller, name=name))
        waiting, conn.deferred, conn.naming_until = conn.deferred, [], None
        self._results.extend(waiting)

    def _dispatch(self, conn: _Connection, event: RequestLine, now: int) -> None:
        # Blank lines never get here: allowed, answered by nothing (handy when typing).
        line, place = event.line, event.place
        read, error = read_request(line)  # parsed once, in time linear in it (SR-10.5)
        if read is None:
            assert error is not None
            self._answer(conn, place, server_line(error))
            return
        request: ApiRequest = read
        # A malformed e-stop or hold still stops (SR-8.13): acted on as the request it names,
        # on every connection and e-stop slot; its reply says what was wrong.
        place.malformed = error
        conn.last_ns = now
        waiting = _Waiting(conn, request, place)
        if conn.naming and not conn.slot and not isinstance(request, NAMELESS_REQUESTS):
            conn.deferred.append(waiting)  # served once the name is known (SR-10.3)
            return
        self._results.append(waiting)

    def _serve(self, waiting: _Waiting) -> Received | Denied | None:
        """A request taken: its result, or ``None`` when the server answered it itself."""
        conn, request = waiting.conn, waiting.request
        error = self._check(conn, request)
        if error is not None:
            self._answer(conn, waiting.place, server_line(error))
            if conn.slot:  # an e-stop slot is no way in for a client: closed (docs/api.md)
                self._end(conn, CloseReason.EVICTED)
            if error.code == ErrorCode.NOT_ALLOWED:
                return Denied(conn.info, request, error)
            return None
        if isinstance(request, Subscribe):
            conn.topics = request.topics
            self._gather_topics()
        return Received(conn.info, request, waiting.place)

    def _check(self, conn: _Connection, request: ApiRequest) -> ApiError | None:
        def error(code: ErrorCode, message: str) -> ApiError:
            return ApiError(code, message, op=request.OP, request_id=request.id)

        if conn.slot and not isinstance(request, SLOT_REQUESTS):
            return error(
                ErrorCode.TOO_MANY_CLIENTS,
                f"{self._full(conn)}; this e-stop slot serves estop and status only",
            )
        if conn.operator and isinstance(request, ROBOT_REQUESTS):
            # Not Denied: the core never sees it (a heartbeat is no reset to record).
            return error(
                ErrorCode.BAD_REQUEST,
                f"{request.OP} is a robot program's: use the client socket (SR-8.14)",
            )
        if isinstance(request, ADMIN_REQUESTS) and not conn.info.caller.admin:
            return error(ErrorCode.NOT_ALLOWED, f"{request.OP} needs root or the admin group")
        # Whether a hello may name the connection is the core's to judge (module docstring);
        # that a heartbeat or a command needs a name is a fact the server holds: it said ok to
        # the hello.
        if isinstance(request, NAMED_REQUESTS) and conn.info.name is None:
            return error(ErrorCode.NOT_HELLO, f"say hello with a name before {request.OP}")
        return None

    def _answer(self, conn: _Connection, place: Place, line: bytes) -> None:
        """Fill ``place`` with its reply; the connection sends every reply now at the front,
        in order: a reply never overtakes the one of an earlier request (docs/api.md)."""
        if conn.dead:
            return
        self._sent_or_ended(conn, conn.protocol.answer(place, line))

    def _queue(self, conn: _Connection, line: bytes) -> None:
        if not conn.dead:
            self._sent_or_ended(conn, conn.protocol.send(line))

    def _sent_or_ended(self, conn: _Connection, within_limit: bool) -> None:
        if within_limit:
            self._flush(conn)
        else:  # the client does not read its replies and pushes
            self._end(conn, CloseReason.OUTPUT_OVERFLOW)

    def _flush(self, conn: _Connection) -> None:
        """Send what the socket takes now; never waits."""
        if not conn.protocol.outgoing:
            return
        try:
            sent = conn.sock.send(conn.protocol.outgoing, socket.MSG_NOSIGNAL)
        except (BlockingIOError, InterruptedError):
            self._watch_writing(conn)
            return
        except OSError:
            self._end(conn, CloseReason.BROKEN)
            return
        conn.protocol.sent(sent)
        self._watch_writing(conn)

    def _watch_writing(self, conn: _Connection) -> None:
        """The loop watches ``conn`` for writing exactly while output waits for it: a change
        makes :meth:`descriptors` build its list again."""
        if bool(conn.protocol.outgoing) is not conn.writing:
            self._watched = None

    def _end(self, conn: _Connection, reason: CloseReason) -> None:
        """Shut the connection down now (dropping its output) and queue its end, once."""
        if conn.dead:
            return
        conn.dead = True
        self._connections.pop(conn.info.connection, None)
        self._by_fd.pop(conn.sock.fileno(), None)
        self._watched = None  # a descriptor fewer to watch
        if conn.topics:
            self._gather_topics()
        conn.protocol.clear()
        with contextlib.suppress(OSError):
            conn.sock.shutdown(socket.SHUT_RDWR)
        self._ended.append(conn.sock)
        if conn.accepted:
            self._results.append(Closed(conn.info, reason))


_OK_LINES: dict[str, bytes] = {}


def _ok_line(op: str) -> bytes:
    """The plain ok of a request ``op`` without an id, as :func:`server_line` writes it: each
    op's line made once (at most one per op, a fixed set: the parser knows no other)."""
    line = _OK_LINES.get(op)
    if line is None:
        line = _OK_LINES[op] = server_line(OkReply(op))
    return line


# -- the socket file -----------------------------------------------------------------------


def _listen(path: Path, mode: int, gid: int | None) -> tuple[socket.socket, tuple[int, int]]:
    _remove_stale(path)
    sock = socket.socket(socket.AF_UNIX, socket.SOCK_STREAM | socket.SOCK_NONBLOCK)
    # Made under a private name and renamed into place once listening: a client that sees
    # the path can connect at once (no refusal between bind and listen), and the mode and
    # group are right before anyone can (SR-8: not world-writable). The private name is
    # longer than the path: the config's limit leaves room for it (SR-11.2).
    staging = staging_socket_path(path, os.getpid())
    made = False
    try:
        with contextlib.suppress(FileNotFoundError):
            os.unlink(staging)
        sock.bind(str(staging))
        os.chmod(staging, mode)
        if gid is not None:
            os.chown(staging, -1, gid)
        sock.listen(BACKLOG)
        # A link, not a rename: if another server made its socket here since the stale one
        # was removed, this fails (EEXIST) instead of stealing that live path.
        os.link(staging, path)
        made = True
        info = os.stat(path)
        os.unlink(staging)
    except OSError as e:
        sock.close()
        for leftover in (staging, path) if made else (staging,):
            with contextlib.suppress(OSError):
                if stat.S_ISSOCK(os.lstat(leftover).st_mode):
                    os.unlink(leftover)
        if e.errno == errno.EEXIST:
            raise ServerError(f"another server is listening at {path}") from None
        raise ServerError(f"cannot serve the API at {path}: {e.strerror or e}") from e
    return sock, (info.st_dev, info.st_ino)


def _remove_stale(path: Path) -> None:
    try:
        info = os.lstat(path)
    except FileNotFoundError:
        return
    except OSError as e:
        raise ServerError(f"cannot check {path}: {e.strerror or e}") from e
    if not stat.S_ISSOCK(info.st_mode):
        raise ServerError(f"{path} exists and is not a socket: remove it or choose another path")
    probe = socket.socket(socket.AF_UNIX, socket.SOCK_STREAM | socket.SOCK_NONBLOCK)
    try:
        probe.connect(str(path))
    except ConnectionRefusedError:
        pass  # nobody listens: a stale socket left by a crash
    except BlockingIOError:
        raise ServerError(f"another server is listening at {path}") from None
    except OSError as e:
        if e.errno != errno.ENOENT:
            raise ServerError(f"cannot check {path}: {e.strerror or e}") from e
    else:
        raise ServerError(f"another server is listening at {path}")
    finally:
        probe.close()
    with contextlib.suppress(FileNotFoundError):
        os.unlink(path)


def _unlink_if_ours(path: Path, identity: tuple[int, int]) -> None:
    with contextlib.suppress(OSError):
        info = os.lstat(path)
        if (info.st_dev, info.st_ino) == identity:
            os.unlink(path)
