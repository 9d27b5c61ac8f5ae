"""One connection of the client API, both ends of it, without any I/O (SR-8, ``docs/api.md``
"Framing").

Bytes in, events out; messages in, bytes out. No socket, no clock, no thread: the server
(:mod:`supervisord.api.server`, driven by the daemon's loop) and the client library
(:mod:`supervisord.client`, used by ``srcsctl``, the exporter and the ROS 2 bridge) each own
the sockets and the waiting, and drive one of these per connection, so that both ends frame,
order and pair lines by the same code.

- :class:`ServerConnection` cuts the request stream into bounded lines (the limits and
  refusals of :class:`~supervisord.api.framing.LineReader`: ``too_long``, then ``flood``),
  gives every non-blank line its place in the connection's reply order and lets a reply leave
  only once every reply before it has (a malformed line's as any other), and holds the output
  waiting for the socket, whose size (replies waiting for an earlier one included) it
  measures against ``max_output``. Parsing a line into a request stays the server's
  (:func:`~supervisord.api.requests.parse_request`): this module must load on the ROS
  bridge's Python, which never loads the parser (docs/ros2.md "The client library").
- :class:`ClientConnection` writes requests and reads the server's lines one at a time: a
  line with ``"event"`` is a push; any other is the reply to the oldest request not yet
  answered (the server answers in request order), and an ``id`` the reply echoes must be that
  request's. A reply with no request is a protocol error, unless it is an error reply (the
  server's last words before it closes, e.g. ``too_many_clients``).
"""

from __future__ import annotations

import collections
import json
from dataclasses import dataclass
from typing import Any, Final

from supervisord.api.framing import (
    DEFAULT_MAX_DISCARD,
    DEFAULT_MAX_LINE,
    ApiError,
    ErrorCode,
    LineReader,
    encode,
)
from supervisord.api.ops import ApiRequest, request_json
from supervisord.api.pushes import Push, read_push
from supervisord.api.replies import Reply, read_reply
from supervisord.api.wire import WireError
from supervisord.errors import SrcsError

DEFAULT_MAX_OUTPUT: Final = 256 * 1024
"""Bytes of replies and pushes a server connection holds for a client that does not read."""
MAX_REPLY_LINE: Final = 1 << 20
"""The longest line a client reads from the server (docs/api.md "Framing": 1 MiB)."""


class ClientError(SrcsError):
    """The client could not talk to the supervisor (not a refusal: see ``ApiError``)."""


class ProtocolError(ClientError):
    """The supervisor sent something this client cannot read."""


# -- the server's end ----------------------------------------------------------------------


class Place:
    """One reply's place in its connection's order: made when its request line is read,
    filled when it is answered. ``malformed``: the error of a malformed e-stop or hold that
    is honoured anyway (SR-8.13), sent in place of its ok."""

    __slots__ = ("line", "malformed")

    def __init__(self) -> None:
        self.line: bytes | None = None
        self.malformed: ApiError | None = None


@dataclass(frozen=True, slots=True)
class RequestLine:
    """A non-blank request line (without its newline), and the place of its reply."""

    line: bytes
    place: Place


@dataclass(frozen=True, slots=True)
class BlankLine:
    """A blank line: allowed, and answered by nothing (docs/api.md "Framing")."""


@dataclass(frozen=True, slots=True)
class LineRefused:
    """A line over the limit, discarded: ``error`` (``too_long``) is its reply at ``place``."""

    error: ApiError
    place: Place


@dataclass(frozen=True, slots=True)
class Flooded:
    """An endless line: ``error`` (``flood``) is the last line sent; the connection ends."""

    error: ApiError


ServerEvent = RequestLine | BlankLine | LineRefused | Flooded


class ServerConnection:
    """The server's end of one connection (see the module docstring).

    :meth:`receive_data` takes what the socket read; :meth:`answer` fills a reply's place and
    :meth:`send` queues a push (or a last error line); :attr:`outgoing` is what waits for the
    socket and :meth:`sent` drops what it took. Both queueing calls return ``False`` once the
    output held passes ``max_output``: the server then ends the connection (a client that
    does not read can never make the server wait)."""

    __slots__ = ("_flooded", "_held", "_lines", "_out", "_places", "max_output")

    def __init__(
        self,
        max_line: int = DEFAULT_MAX_LINE,
        max_discard: int = DEFAULT_MAX_DISCARD,
        max_output: int = DEFAULT_MAX_OUTPUT,
    ) -> None:
        self._lines = LineReader(max_line, max_discard)
        self.max_output = max_output
        self._out = bytearray()
        # Replies not yet sent, in request order: one waits for those before it (docs/api.md).
        self._places: collections.deque[Place] = collections.deque()
        self._held = 0  # bytes of replies answered but waiting for an earlier one
        self._flooded = False

    def receive_data(self, data: bytes) -> list[ServerEvent]:
        """The events of ``data``, in order: one per line (complete or refused), then
        :class:`Flooded` once the line being discarded passed ``max_discard`` (after which
        nothing more is read)."""
        events: list[ServerEvent] = []
        for item in self._lines.feed(data):
            if isinstance(item, ApiError):
                events.append(LineRefused(item, self._place()))
            elif not item.strip():
                events.append(BlankLine())
            else:
                events.append(RequestLine(item, self._place()))
        if self._lines.flooded and not self._flooded:
            self._flooded = True  # said once: the server ends the connection on it
            events.append(
                Flooded(ApiError(ErrorCode.FLOOD, "an endless line: the connection is closed"))
            )
        return events

    def answer(self, place: Place, line: bytes) -> bool:
        """Fill ``place`` with its reply line (once), then queue every reply now at the front,
        in order: a reply never overtakes the one of an earlier request (docs/api.md)."""
        if place.line is not None:
            return True
        place.line = line
        self._held += len(line)
        ready = bytearray()
        while self._places and (front := self._places[0].line) is not None:
            self._places.popleft()
            self._held -= len(front)
            ready += front
        return self.send(bytes(ready))

    def send(self, line: bytes) -> bool:
        """Queue ``line`` (a push, or an error sent before closing) at once; ``False`` when
        the output held is now over ``max_output``."""
        self._out += line
        # Replies held for an earlier one wait for this client as much as its unsent output.
        return len(self._out) + self._held <= self.max_output

    @property
    def outgoing(self) -> bytearray:
        """The bytes waiting for the socket (read-only for the caller: see :meth:`sent`)."""
        return self._out

    def sent(self, count: int) -> None:
        """The socket took the first ``count`` bytes of :attr:`outgoing`."""
        del self._out[:count]

    def clear(self) -> None:
        """The connection ended: drop its output and its waiting replies."""
        self._out.clear()
        self._places.clear()
        self._held = 0

    def _place(self) -> Place:
        place = Place()
        self._places.append(place)
        return place


def server_line(message: Reply | Push | ApiError) -> bytes:
    """One reply, push or error reply as the line the server sends."""
    return encode(message.reply() if isinstance(message, ApiError) else message.json())


# -- the client's end ----------------------------------------------------------------------


@dataclass(frozen=True, slots=True)
class ReplyReceived:
    """The reply (or error reply) to ``request``, the oldest request not yet answered."""

    request: ApiRequest
    reply: Reply | ApiError


@dataclass(frozen=True, slots=True)
class PushReceived:
    push: Push


@dataclass(frozen=True, slots=True)
class ErrorWithoutRequest:
    """An error reply when no request waits: the server's last words before it closes."""

    error: ApiError


ClientEvent = ReplyReceived | PushReceived | ErrorWithoutRequest


class ClientConnection:
    """The client's end of one connection (see the module docstring).

    :meth:`send` gives a request's line and remembers the request; :meth:`receive_data` takes
    what the socket read; :meth:`next_event` reads one line into its event, or ``None`` when
    no whole line is held. Raises :class:`ProtocolError` for a line the client cannot read
    (not JSON, a reply or push docs/api.md does not allow, a reply to no request, an echoed
    ``id`` that is not its request's, a line over ``max_line``)."""

    __slots__ = ("_buffer", "_waiting", "max_line")

    def __init__(self, max_line: int = MAX_REPLY_LINE) -> None:
        self.max_line = max_line
        self._buffer = bytearray()
        self._waiting: collections.deque[ApiRequest] = collections.deque()

    def send(self, request: ApiRequest) -> bytes:
        """The line that sends ``request``; its reply is expected after those sent before."""
        line = encode(request_json(request))
        self._waiting.append(request)
        return line

    @property
    def waiting(self) -> int:
        """Requests sent and not yet answered."""
        return len(self._waiting)

    @property
    def held(self) -> int:
        """Bytes received and not yet read as a line."""
        return len(self._buffer)

    def receive_data(self, data: bytes) -> None:
        self._buffer += data

    def next_event(self) -> ClientEvent | None:
        newline = self._buffer.find(b"\n")
        if newline < 0:
            if len(self._buffer) > self.max_line:
                raise ProtocolError("a line from the supervisor is too long")
            return None
        line = bytes(self._buffer[:newline])
        del self._buffer[: newline + 1]
        obj = _decode(line)
        if "event" in obj:
            return PushReceived(_push(obj))
        reply = _reply(obj)
        if not self._waiting:
            if isinstance(reply, ApiError):  # e.g. too_many_clients, sent before closing
                return ErrorWithoutRequest(reply)
            raise ProtocolError(f"a reply without a request: {obj!r}"[:200])
        request = self._waiting.popleft()
        echoed = reply.request_id if isinstance(reply, ApiError) else obj.get("id")
        if request.id is not None and echoed is not None and echoed != request.id:
            raise ProtocolError(f"a reply to id {echoed!r} where id {request.id!r} was due"[:200])
        return ReplyReceived(request, reply)

    def last_error(self) -> ApiError | None:
        """The first error reply among the lines held (the server's last words before it
        closed, e.g. ``too_many_clients``), if any; lines that cannot be read are skipped."""
        for line in bytes(self._buffer).split(b"\n"):
            try:
                reply = _reply(_decode(line))
            except ProtocolError:
                continue
            if isinstance(reply, ApiError):
                return reply
        return None


def _reply(obj: dict[str, Any]) -> Reply | ApiError:
    try:
        return read_reply(obj)
    except WireError as e:
        raise ProtocolError(
            f"a reply from the supervisor that docs/api.md does not allow: {e}"
        ) from e


def _push(obj: dict[str, Any]) -> Push:
    try:
        return read_push(obj)
    except WireError as e:
        raise ProtocolError(
            f"a push from the supervisor that docs/api.md does not allow: {e}"
        ) from e


def _decode(line: bytes) -> dict[str, Any]:
    try:
        obj = json.loads(line)
    except (ValueError, RecursionError) as e:  # RecursionError: nested thousands deep
        raise ProtocolError(f"not JSON from the supervisor: {line[:80]!r}") from e
    if not isinstance(obj, dict):
        raise ProtocolError(f"not a JSON object from the supervisor: {line[:80]!r}")
    return obj
