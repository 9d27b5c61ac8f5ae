"""The client API's framing (SR-8, ``docs/api.md``): lines, limits and error replies; sans-IO.

Requests are JSON objects, one per line. :class:`LineReader` cuts a byte stream into bounded
lines; :func:`encode` writes one reply or push as its line. :class:`ApiError` is every
request the server did not accept, with a stable :class:`ErrorCode`.

Nothing here touches a socket or a clock.
"""

from __future__ import annotations

import json
from collections.abc import Mapping
from pathlib import Path
from typing import Any, Final

from supervisord.compat import StrEnum
from supervisord.errors import SrcsError
from supervisord.protocol.text import clean, clean_json

JsonDict = dict[str, Any]

DEFAULT_SOCKET_PATH: Final = Path("/run/srcsd/api.sock")
"""Where the daemon serves the API unless its config says otherwise (docs/api.md "The
socket"); the client connects there by default."""


SOCKET_ADDRESS_MAX_BYTES: Final = 107
"""The longest path a Unix socket address holds: ``sun_path`` is 108 bytes, the last the NUL."""
PID_MAX_DIGITS: Final = 7
"""The most digits a process ID has on Linux: ``pid_max`` is at most 4194304 (2^22)."""
SOCKET_PATH_MAX_BYTES: Final = SOCKET_ADDRESS_MAX_BYTES - 2 - PID_MAX_DIGITS
"""The longest socket path the config accepts (``api.socket``, ``api.operator_socket``): the
server binds :func:`staging_socket_path` first, two dots and a process ID longer, and that name
must fit a socket address too. A path the check accepts is one the daemon serves at, whatever
its process ID (SR-8.1, SR-8.14; SR-11.2: never a check that passes and a start that fails with
"AF_UNIX path too long")."""


def staging_socket_path(path: Path, pid: int) -> Path:
    """The private name the server binds and sets up a socket under before it links it into
    place at ``path`` (SR-8.3: its mode and group are right before any client can connect):
    ``api.sock`` gives ``.api.sock.PID`` beside it. At most ``2 + PID_MAX_DIGITS`` bytes
    longer than ``path``, which :data:`SOCKET_PATH_MAX_BYTES` leaves room for."""
    return path.with_name(f".{path.name}.{pid}")


def operator_socket_path(client_socket: Path) -> Path:
    """The operator socket beside a client socket (SR-8.14, docs/api.md "The operator
    socket"), unless the config names one: ``api.sock`` gives ``api-operator.sock``."""
    return client_socket.with_name(f"{client_socket.stem}-operator{client_socket.suffix}")


DEFAULT_MAX_LINE: Final = 4096
"""The longest request line in bytes, its newline included (``docs/api.md`` "Limits")."""
DEFAULT_MAX_DISCARD: Final = 64 * 1024
"""Bytes of one over-long line the server discards before it disconnects the sender."""
MAX_ID_LENGTH: Final = 64
MAX_NESTING: Final = 16
"""Arrays and objects nested deeper than this are ``bad_json`` (a request needs 2 levels)."""


class ErrorCode(StrEnum):
    """The stable ``code`` of an error reply. Values never change; new ones may be added."""

    BAD_JSON = "bad_json"  # not UTF-8 JSON, or duplicate keys, NaN, nesting too deep
    TOO_LONG = "too_long"  # the line is longer than the limit; it was discarded
    UNKNOWN_OP = "unknown_op"  # ``op`` missing from the known set
    BAD_REQUEST = "bad_request"  # not an object, a field missing, unknown or out of range
    NOT_ALLOWED = "not_allowed"  # the caller is not an admin (reset, commission)
    NOT_HELLO = "not_hello"  # the request needs a named client (hello first)
    ALREADY_NAMED = "already_named"  # a second hello on one connection
    NAME_IN_USE = "name_in_use"  # another connection already uses that name
    TOO_MANY_CLIENTS = "too_many_clients"  # sent once, then the connection is closed
    FLOOD = "flood"  # an endless line: sent once, then the connection is closed
    REFUSED = "refused"  # the safety core declined the request (``reason`` says why)
    UNAVAILABLE = "unavailable"  # the daemon cannot do it now (e.g. no link to the VSC)
    FAILED = "failed"  # the daemon tried and failed (e.g. a commissioning read-back differs)


class ApiError(SrcsError):
    """A request the server did not accept, or an error reply the client library received.

    ``code`` is an :class:`ErrorCode` value (a client may see codes newer than itself, so it
    is typed as text); ``op`` and ``id`` echo the request when they were readable.
    """

    def __init__(
        self,
        code: str,
        message: str,
        *,
        op: str | None = None,
        request_id: int | str | None = None,
        extra: Mapping[str, object] | None = None,
    ) -> None:
        self.code, self.message, self.op, self.request_id = code, message, op, request_id
        self.extra: Mapping[str, object] = dict(extra or {})
        super().__init__(f"{code}: {message}")

    def reply(self) -> JsonDict:
        """The error reply line's object."""
        # The message may quote the request (a field name, a value): escaped, so the reply
        # always encodes (docs/safety.md "No input can raise").
        reply: JsonDict = {"ok": False, "code": str(self.code), "error": clean(self.message)}
        if self.op is not None:
            reply["op"] = self.op
        if self.request_id is not None:
            reply["id"] = self.request_id
        for key, value in self.extra.items():
            reply.setdefault(key, value)
        return reply


# -- framing -------------------------------------------------------------------------------


class LineReader:
    """Cuts a byte stream into lines of at most ``max_line`` bytes (newline included).

    :meth:`feed` returns the complete lines (without the newline) and, in their place, an
    ``ApiError`` ``too_long`` for each over-long line, reported as soon as it passes the limit.
    The rest of that line is discarded up to its newline; once more than ``max_discard``
    bytes of it were discarded, :attr:`flooded` becomes true and the reader takes no more.
    Memory use is bounded by ``max_line`` whatever the peer sends.
    """

    def __init__(self, max_line: int = DEFAULT_MAX_LINE, max_discard: int = DEFAULT_MAX_DISCARD):
        if max_line < 64 or max_discard < max_line:
            raise ValueError("max_line must be >= 64 and max_discard >= max_line")
        self.max_line, self.max_discard = max_line, max_discard
        self.flooded = False
        self._buffer = bytearray()
        self._discarded: int | None = None  # bytes dropped of the current over-long line

    @property
    def pending(self) -> int:
        """Bytes of an incomplete line held."""
        return len(self._buffer)

    def feed(self, data: bytes) -> list[bytes | ApiError]:
        out: list[bytes | ApiError] = []
        view = memoryview(data)
        start = 0
        while start < len(data) and not self.flooded:
            newline = data.find(b"\n", start)
            end = len(data) if newline < 0 else newline
            self._take(view[start:end], out)
            if newline < 0:
                break
            if self._discarded is None:
                out.append(bytes(self._buffer))
                self._buffer.clear()
            self._discarded = None
            start = newline + 1
        return out

    def _take(self, chunk: memoryview, out: list[bytes | ApiError]) -> None:
        if self._discarded is not None:
            self._discarded += len(chunk)
        elif len(self._buffer) + len(chunk) >= self.max_line:  # no room left for the newline
            self._discarded = len(self._buffer) + len(chunk)
            self._buffer.clear()
            out.append(
                ApiError(
                    ErrorCode.TOO_LONG,
                    f"a request line may be at most {self.max_line} bytes with its newline; "
                    "the line was discarded",
                )
            )
        else:
            self._buffer += chunk
        if self._discarded is not None and self._discarded > self.max_discard:
            self.flooded = True


_ENCODER: Final = json.JSONEncoder(ensure_ascii=False, separators=(",", ":"), allow_nan=False)
"""The one encoder of the server's lines: ``json.dumps`` with these options would build an
encoder per line (SR-9.4). It holds no state between lines."""


def encode(obj: Mapping[str, object]) -> bytes:
    """One reply or push as its line: compact UTF-8 JSON and a newline.

    Text that UTF-8 cannot hold (a lone surrogate that escaped the checks at its source) is
    written escaped (:func:`supervisord.protocol.text.clean`): a reply is never lost to its text.
    Raises ``ValueError`` (our own mistake) for a value JSON cannot hold (NaN, an object)."""
    try:
        text = _ENCODER.encode(obj)
    except TypeError as e:
        raise ValueError(f"not plain JSON: {e}") from e
    try:
        return text.encode() + b"\n"  # json.dumps escapes newlines inside text
    except UnicodeEncodeError:
        # The last net; the sources clean their text (docs/safety.md "No input can
        # raise"), so this costs nothing on the normal path.
        return (
            json.dumps(clean_json(obj), ensure_ascii=False, separators=(",", ":")).encode() + b"\n"
        )
