"""The client API's message vocabulary (SR-8, ``docs/api.md``): sans-IO.

Requests are JSON objects, one per line. :class:`LineReader` cuts a byte stream into bounded
lines; :func:`parse_request` turns one line into a frozen request value or raises
:class:`ApiError` with a stable ``code``: garbage from a peer either parses or raises
``ApiError``, nothing else. The reply and push builders turn requests, safety decisions,
records and VSC messages into the JSON objects the server sends.

Nothing here touches a socket or a clock.
"""

from __future__ import annotations

import dataclasses
import datetime as dt
import enum
import json
import re
from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any, Final, get_args

from supervisord.compat import StrEnum
from supervisord.errors import SrcsError
from supervisord.protocol.codes import DisplayMode, FeedbackKey, StringKey
from supervisord.protocol.jsonview import message_json
from supervisord.protocol.messages import (
    I32,
    NAME_TEXT_LENGTH,
    FeedbackName,
    FeedbackSet,
    Gps,
    Joystick,
    Message,
    RemoteStatus,
    check_text,
)
from supervisord.protocol.text import clean, clean_json, is_clean
from supervisord.safety.causes import CauseState
from supervisord.safety.config import NAME_PATTERN
from supervisord.safety.decision import ChangeKind, Decision, Record, RecordNote, Refusal
from supervisord.safety.events import (
    Caller,
    ClientEstop,
    ClientHeartbeat,
    ClientHello,
    ClientHold,
    ClientRelease,
    DisplayUpdate,
    Event,
    LocalEstop,
    LocalRelease,
    ProofTestRequest,
    ResetRequest,
)
from supervisord.safety.events import Request as Releasable

JsonDict = dict[str, Any]

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


def encode(obj: Mapping[str, object]) -> bytes:
    """One reply or push as its line: compact UTF-8 JSON and a newline.

    Text that UTF-8 cannot hold (a lone surrogate that escaped the checks at its source) is
    written escaped (:func:`supervisord.protocol.text.clean`): a reply is never lost to its text.
    Raises ``ValueError`` (our own mistake) for a value JSON cannot hold (NaN, an object)."""
    try:
        text = json.dumps(obj, ensure_ascii=False, separators=(",", ":"), allow_nan=False)
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


# -- requests ------------------------------------------------------------------------------


class Topic(enum.Enum):
    """What a subscriber receives (``docs/api.md`` "Pushes")."""

    STATE = "state"  # every decision that changed the state, the causes or the outputs
    JOYSTICK = "joystick"  # every joystick message (meaningful only in RUN)
    GPS = "gps"
    REMOTE_STATUS = "remote_status"
    RECORDS = "records"  # every stop record, as written

    @property
    def event(self) -> str:
        """The ``event`` field of this topic's pushes."""
        return "record" if self is Topic.RECORDS else self.value


class Side(enum.Enum):
    """Which handle of the remote vibrates (feedback keys 10-12)."""

    LEFT = "left"
    RIGHT = "right"
    BOTH = "both"

    @property
    def key(self) -> FeedbackKey:
        return _VIBRATE_KEYS[self]


_VIBRATE_KEYS = {
    Side.LEFT: FeedbackKey.VIBRATE_LEFT,
    Side.RIGHT: FeedbackKey.VIBRATE_RIGHT,
    Side.BOTH: FeedbackKey.VIBRATE_BOTH,
}

RequestId = int | str | None


@dataclass(frozen=True, slots=True, kw_only=True)
class _Request:
    """``id``: the caller's optional tag, echoed in the reply."""

    OP = ""
    id: RequestId = None


@dataclass(frozen=True, slots=True)
class Hello(_Request):
    """Name this connection: it becomes the client ``name`` (SR-8)."""

    OP = "hello"
    name: str


@dataclass(frozen=True, slots=True)
class Heartbeat(_Request):
    """A named client is alive."""

    OP = "heartbeat"


@dataclass(frozen=True, slots=True)
class Estop(_Request):
    """An e-stop: the client's own (``client_estop:NAME``) or, before hello, ``local_estop``."""

    OP = "estop"


@dataclass(frozen=True, slots=True)
class Hold(_Request):
    """A hold: ``client_hold:NAME`` until this client releases it."""

    OP = "hold"


@dataclass(frozen=True, slots=True)
class Release(_Request):
    """End this caller's own e-stop or hold request (a stop stays latched until re-armed)."""

    OP = "release"
    what: Releasable


@dataclass(frozen=True, slots=True)
class Status(_Request):
    """The current state, causes and outputs."""

    OP = "status"


@dataclass(frozen=True, slots=True)
class Subscribe(_Request):
    """Receive pushes of these topics from now on (replaces the previous set; empty: none)."""

    OP = "subscribe"
    topics: frozenset[Topic]


@dataclass(frozen=True, slots=True)
class DisplayValue(_Request):
    """Show a number in user value ``key`` (1-9) on the remote."""

    OP = "display"
    key: int
    value: int


@dataclass(frozen=True, slots=True)
class DisplayLabel(_Request):
    """Label user value ``key`` (1-9): at most 20 single-byte characters."""

    OP = "display"
    key: int
    text: str


@dataclass(frozen=True, slots=True)
class DisplayRow(_Request):
    """Text row ``index`` (1-4) of the remote's text page: at most 20 characters."""

    OP = "display"
    index: int
    text: str


@dataclass(frozen=True, slots=True)
class DisplayModeRequest(_Request):
    """Which page the remote shows (feedback key 99)."""

    OP = "display"
    mode: DisplayMode


@dataclass(frozen=True, slots=True)
class Vibrate(_Request):
    """Vibrate a handle of the remote once."""

    OP = "vibrate"
    side: Side


@dataclass(frozen=True, slots=True)
class Reset(_Request):
    """``srcsctl reset``: a local re-arm (SR-4). Admins only."""

    OP = "reset"


@dataclass(frozen=True, slots=True)
class Commission(_Request):
    """Turn the VSC's key-85 watchdog on and enable remote-status messages, permanently
    (SR-5). Admins only; the request must carry ``"confirm": true``."""

    OP = "commission"


@dataclass(frozen=True, slots=True)
class ProofTest(_Request):
    """Run the proof test of the VSC's watchdog again (SR-5.3; docs/safety.md "The proof
    test"). Admins only; the core refuses it in RUN and HOLD. The reply comes at once; the
    result follows in ``status`` (``prooftest``) and a ``prooftest`` record."""

    OP = "prooftest"


Request = (
    Hello
    | Heartbeat
    | Estop
    | Hold
    | Release
    | Status
    | Subscribe
    | DisplayValue
    | DisplayLabel
    | DisplayRow
    | DisplayModeRequest
    | Vibrate
    | Reset
    | Commission
    | ProofTest
)

ADMIN_REQUESTS: Final = (Reset, Commission, ProofTest)
"""Requests only an admin may make (SR-8)."""
NAMED_REQUESTS: Final = (Heartbeat,)
"""Requests that need a connection that said hello."""

_USER_VALUE_KEYS = range(1, 10)
_ROWS = range(1, 5)
_TEXT_ROW_1 = StringKey.TEXT_ROW_1.value


def _reject_constant(name: str) -> object:
    raise ValueError(f"{name} is not JSON")


def _unique_keys(pairs: list[tuple[str, object]]) -> dict[str, object]:
    result: dict[str, object] = {}
    for key, value in pairs:
        if key in result:
            raise ValueError(f"duplicate key {_shown(key)}")
        result[key] = value
    return result


_JSON_STRING = re.compile(rb'"(?:[^"\\]|\\.)*"')
_INNERMOST = re.compile(rb"\[[^\[\]{}]*\]|\{[^\[\]{}]*\}")


def _too_deep(line: bytes) -> bool:
    """Whether ``line`` nests arrays and objects deeper than :data:`MAX_NESTING`.

    Decided before parsing, so the answer never depends on how deep the caller's stack is
    (Python's parser raises ``RecursionError`` near its limit, wherever that is). Brackets
    inside strings do not count. Cost: a count, and only for lines with many brackets, at
    most ``MAX_NESTING`` passes of two regular expressions (C speed, linear)."""
    if line.count(b"[") + line.count(b"{") <= MAX_NESTING:
        return False
    rest = _JSON_STRING.sub(b"", line)
    for _ in range(MAX_NESTING):
        rest, removed = _INNERMOST.subn(b"", rest)
        if not removed:
            return False  # unbalanced, not deep: the parser says what is wrong
    return b"[" in rest or b"{" in rest


def _shown(value: object) -> str:
    """A short, encodable description of a request's value for an error message: never the
    repr of a container (unbounded, recursive) or of a huge number (Python limits the digits
    it converts), text escaped and cut."""
    if isinstance(value, str):
        return clean(repr(value[:40]) + ("..." if len(value) > 40 else ""))
    if isinstance(value, bool) or value is None:
        return json.dumps(value)
    if isinstance(value, int):
        return str(value) if -(10**30) < value < 10**30 else "an integer that long"
    if isinstance(value, float):
        return repr(value)
    return "a list" if isinstance(value, list) else "an object"


def _load(line: bytes) -> object:
    if _too_deep(line):
        raise ApiError(
            ErrorCode.BAD_JSON, f"arrays and objects may be nested at most {MAX_NESTING} deep"
        )
    try:
        text = line.decode("utf-8")
        return json.loads(text, parse_constant=_reject_constant, object_pairs_hook=_unique_keys)
    except UnicodeDecodeError as e:
        raise ApiError(ErrorCode.BAD_JSON, f"the line is not UTF-8: {e.reason}") from e
    except RecursionError as e:
        raise ApiError(ErrorCode.BAD_JSON, "the JSON is nested too deeply") from e
    except ValueError as e:  # json.JSONDecodeError is a ValueError
        raise ApiError(ErrorCode.BAD_JSON, f"not JSON: {e}") from e


class _Fields:
    """Reads the fields of one request object, raising ``bad_request`` that names the field."""

    def __init__(
        self, obj: Mapping[str, object], op: str, request_id: RequestId, where: str = ""
    ) -> None:
        self.obj, self.op, self.id, self.where = obj, op, request_id, where
        self.used = {"op", "id"} if not where else set()

    def error(self, message: str) -> ApiError:
        return ApiError(ErrorCode.BAD_REQUEST, message, op=self.op, request_id=self.id)

    def get(self, name: str) -> object:
        self.used.add(name)
        if name not in self.obj:
            raise self.error(f"{self.op} needs the field {self.where}{name!r}")
        return self.obj[name]

    def nested(self, name: str) -> _Fields:
        value = self.get(name)
        if not isinstance(value, dict):
            raise self.error(f"{self.where}{name} must be an object, not {_shown(value)}")
        return _Fields(value, self.op, self.id, f"{self.where}{name}.")

    def integer(self, name: str, low: int, high: int) -> int:
        value = self.get(name)
        if isinstance(value, bool) or not isinstance(value, int) or not low <= value <= high:
            raise self.error(
                f"{self.where}{name} must be an integer {low}..{high}, not {_shown(value)}"
            )
        return value

    def text(self, name: str) -> str:
        value = self.get(name)
        if not isinstance(value, str):
            raise self.error(f"{self.where}{name} must be text, not {_shown(value)}")
        try:
            check_text(f"{self.where}{name}", value, NAME_TEXT_LENGTH)
        except ValueError as e:
            raise self.error(
                f"{self.where}{name} must be at most {NAME_TEXT_LENGTH} single-byte "
                f"characters without NUL, not {_shown(value)}"
            ) from e
        return value

    def choice(self, name: str, members: tuple[enum.Enum, ...]) -> enum.Enum:
        value = self.get(name)
        for member in members:
            if member.value == value:
                return member
        allowed = ", ".join(repr(m.value) for m in members)
        raise self.error(f"{self.where}{name} must be one of {allowed}, not {_shown(value)}")

    def finish(self) -> None:
        unknown = sorted(set(self.obj) - self.used)
        if unknown:
            shown = ", ".join(clean(f"{self.where}{name}") for name in unknown)
            raise self.error(f"unknown field(s) for {self.op}: {shown}"[:200])


def _request_id(obj: Mapping[str, object]) -> RequestId:
    value = obj.get("id")
    if value is None:
        return None
    if isinstance(value, bool) or not isinstance(value, int | str):
        raise ApiError(ErrorCode.BAD_REQUEST, "id must be an integer or text")
    if isinstance(value, str) and len(value) > MAX_ID_LENGTH:
        raise ApiError(ErrorCode.BAD_REQUEST, f"id text may be at most {MAX_ID_LENGTH} long")
    if isinstance(value, str) and not is_clean(value):
        # A lone surrogate ("\ud800") is valid JSON but no UTF-8: it could not be echoed in
        # the reply, so the request is refused without an id (issue 11).
        raise ApiError(ErrorCode.BAD_REQUEST, "id text must be Unicode (no lone surrogates)")
    if isinstance(value, int) and not -(2**63) <= value < 2**63:
        raise ApiError(ErrorCode.BAD_REQUEST, "id must fit in 64 signed bits")
    return value


def _hello(f: _Fields) -> Request:
    name = f.get("name")
    if not isinstance(name, str) or NAME_PATTERN.fullmatch(name) is None:
        raise f.error("name must be 1-32 letters, digits, '_', '.' or '-'")
    return Hello(name, id=f.id)


def _release(f: _Fields) -> Request:
    what = f.choice("what", tuple(Releasable))
    assert isinstance(what, Releasable)
    return Release(what, id=f.id)


def _subscribe(f: _Fields) -> Request:
    topics = f.get("topics")
    if not isinstance(topics, list) or len(topics) > len(Topic):
        raise f.error(f"topics must be a list of at most {len(Topic)} topic names")
    by_value = {t.value: t for t in Topic}
    chosen = set()
    for topic in topics:
        if not isinstance(topic, str) or topic not in by_value:
            raise f.error(f"unknown topic {topic!r}; topics are {', '.join(by_value)}"[:200])
        chosen.add(by_value[topic])
    return Subscribe(frozenset(chosen), id=f.id)


_DISPLAY_FORMS = ("value", "label", "row", "mode")


def _display(f: _Fields) -> Request:
    forms = [form for form in _DISPLAY_FORMS if form in f.obj]
    if len(forms) != 1:
        raise f.error(f"display takes exactly one of {', '.join(_DISPLAY_FORMS)}")
    form = forms[0]
    if form == "mode":
        mode = f.integer("mode", 0, max(DisplayMode))
        return DisplayModeRequest(DisplayMode(mode), id=f.id)
    inner = f.nested(form)
    request: Request
    if form == "value":
        key = inner.integer("key", _USER_VALUE_KEYS.start, _USER_VALUE_KEYS.stop - 1)
        request = DisplayValue(key, inner.integer("value", *I32), id=f.id)
    elif form == "label":
        key = inner.integer("key", _USER_VALUE_KEYS.start, _USER_VALUE_KEYS.stop - 1)
        request = DisplayLabel(key, inner.text("text"), id=f.id)
    else:
        index = inner.integer("index", _ROWS.start, _ROWS.stop - 1)
        request = DisplayRow(index, inner.text("text"), id=f.id)
    inner.finish()
    return request


def _vibrate(f: _Fields) -> Request:
    side = f.choice("side", tuple(Side))
    assert isinstance(side, Side)
    return Vibrate(side, id=f.id)


def _commission(f: _Fields) -> Request:
    if f.get("confirm") is not True:
        raise f.error('commission writes the VSC permanently: send "confirm": true')
    return Commission(id=f.id)


def _prooftest(f: _Fields) -> Request:
    return ProofTest(id=f.id)


_PARSERS = {
    "hello": _hello,
    "heartbeat": lambda f: Heartbeat(id=f.id),
    "estop": lambda f: Estop(id=f.id),
    "hold": lambda f: Hold(id=f.id),
    "release": _release,
    "status": lambda f: Status(id=f.id),
    "subscribe": _subscribe,
    "display": _display,
    "vibrate": _vibrate,
    "reset": lambda f: Reset(id=f.id),
    "commission": _commission,
    "prooftest": _prooftest,
}
OPS: Final = tuple(_PARSERS)
"""Every request op, in the order ``docs/api.md`` documents them."""


def parse_request(line: bytes) -> Request:
    """One request line (without its newline) as a request value.

    Raises :class:`ApiError` (``bad_json``, ``bad_request`` or ``unknown_op``) for anything
    else; it carries the ``op`` and ``id`` when they could be read, for the error reply.
    """
    obj = _load(line)
    if not isinstance(obj, dict):
        raise ApiError(ErrorCode.BAD_REQUEST, "a request must be a JSON object")
    request_id = _request_id(obj)
    op = obj.get("op")
    if not isinstance(op, str):
        raise ApiError(ErrorCode.BAD_REQUEST, "a request needs an op", request_id=request_id)
    parser = _PARSERS.get(op)
    if parser is None:
        shown = op if len(op) <= 40 and op.isprintable() else repr(op[:40])
        raise ApiError(ErrorCode.UNKNOWN_OP, f"unknown op {shown}", request_id=request_id)
    fields = _Fields(obj, op, request_id)
    request = parser(fields)
    fields.finish()
    return request


def request_json(request: Request) -> JsonDict:
    """The request as its JSON object: what a client sends (the inverse of parsing)."""
    obj: JsonDict = {"op": request.OP}
    match request:
        case Hello(name=name):
            obj["name"] = name
        case Release(what=what):
            obj["what"] = what.value
        case Subscribe(topics=topics):
            obj["topics"] = sorted(t.value for t in topics)
        case DisplayValue(key=key, value=value):
            obj["value"] = {"key": key, "value": value}
        case DisplayLabel(key=key, text=text):
            obj["label"] = {"key": key, "text": text}
        case DisplayRow(index=index, text=text):
            obj["row"] = {"index": index, "text": text}
        case DisplayModeRequest(mode=mode):
            obj["mode"] = int(mode)
        case Vibrate(side=side):
            obj["side"] = side.value
        case Commission():
            obj["confirm"] = True
        case _:
            pass
    if request.id is not None:
        obj["id"] = request.id
    return obj


# -- replies -------------------------------------------------------------------------------


def ok_reply(request: Request, **fields: object) -> JsonDict:
    """The success reply to ``request``, with extra ``fields``."""
    reply: JsonDict = {"ok": True, "op": request.OP}
    if request.id is not None:
        reply["id"] = request.id
    reply.update(fields)
    return reply


def refusal_error(request: Request, refusal: Refusal) -> ApiError:
    """The ``refused`` error for a request the safety core declined; ``reason`` is the
    refusal's stable name in lower case (e.g. ``conditions_active``)."""
    return ApiError(
        ErrorCode.REFUSED,
        refusal.message,
        op=request.OP,
        request_id=request.id,
        extra={"reason": refusal.reason.name.lower()},
    )


# -- JSON of safety values -----------------------------------------------------------------


def caller_json(caller: Caller) -> JsonDict:
    """The caller; its login name escaped if it is not UTF-8 (``credentials.user_name``
    escapes it at the source already; this keeps every record and reply encodable)."""
    return {"uid": caller.uid, "pid": caller.pid, "name": clean(caller.name), "admin": caller.admin}


def cause_json(cause: CauseState) -> JsonDict:
    """One cause: ``name``, ``severity`` (``stop``/``hold``), ``active``, ``latched``, the
    monotonic times, and ``details`` (text values, e.g. ``{"sources": "remote"}``)."""
    return {
        "name": cause.name,
        "severity": cause.severity.value,
        "active": cause.active,
        "latched": cause.latched,
        "raised_ns": cause.raised_ns,
        "cleared_ns": cause.cleared_ns,
        "details": {clean(k): clean(v) for k, v in cause.details},  # may quote input text
    }


def decision_json(decision: Decision) -> JsonDict:
    """The state of the supervisor after one decision, for ``status`` and ``state`` pushes."""
    return {
        "state": decision.state.name,
        "mono_ns": decision.now,
        "causes": [cause_json(c) for c in decision.causes],
        "outputs": dict(sorted(decision.outputs.items())),
        "heartbeat_estop": decision.heartbeat_estop,
        "prooftest": None if decision.prooftest is None else decision.prooftest.json(),
    }


def _plain(value: object) -> object:
    """A trigger's field as JSON: messages through the protocol's JSON view."""
    if isinstance(value, Caller):
        return caller_json(value)
    if isinstance(value, enum.Enum):
        return value.value
    if isinstance(value, str):
        return clean(value)  # e.g. a link's or a fault's reason, which may quote input
    if isinstance(value, bool | int) or value is None:
        return value
    if isinstance(value, tuple):
        return [_plain(v) for v in value]
    if isinstance(value, _MESSAGE_TYPES):
        return message_json(value)
    return clean(repr(value)[:200])


_MESSAGE_TYPES: Final = get_args(Message)
_CAMEL = re.compile(r"(?<!^)(?=[A-Z])")


def trigger_json(event: object) -> JsonDict:
    """What triggered a record: ``{"event": "client_estop", "connection": 3, ...}``."""
    result: JsonDict = {"event": _CAMEL.sub("_", type(event).__name__).lower()}
    if dataclasses.is_dataclass(event) and not isinstance(event, type):
        for field in dataclasses.fields(event):
            if field.name != "now":
                result[field.name] = _plain(getattr(event, field.name))
    return result


def record_kind(record: Record) -> str:
    """``state_change``, ``cause_raised``, the record's note (``rearm_refused``,
    ``commissioned``) or ``cause_cleared``, in that order of precedence (``docs/record.md``)."""
    if record.previous is not record.state:
        return "state_change"
    if record.prooftest is not None:
        return RecordNote.PROOFTEST.value  # its outcome is what the record is about
    if any(c.kind in (ChangeKind.RAISED, ChangeKind.UPDATED) for c in record.changes):
        return "cause_raised"
    if record.note is not None:
        return record.note.value
    return "cause_cleared"


def record_json(record: Record, utc: dt.datetime, sequence_offset: int = 0) -> JsonDict:
    """A stop record as JSON, with the fields ``docs/record.md`` requires; ``utc`` (aware) is
    the wall-clock time the daemon stamped on it. ``seq`` continues after ``sequence_offset``,
    the last sequence number already in the store (the core counts from 1 at every start)."""
    result: JsonDict = {
        "seq": sequence_offset + record.sequence,
        "mono_ns": record.monotonic_ns,
        "utc": utc.astimezone(dt.timezone.utc).isoformat(timespec="microseconds"),  # noqa: UP017 -- dt.UTC is 3.11
        "kind": record_kind(record),
        "from": record.previous.name,
        "to": record.state.name,
        "causes": [cause_json(c) for c in record.causes],
        "changes": [{"name": c.cause.name, "change": c.kind.value} for c in record.changes],
        "trigger": trigger_json(record.trigger),
    }
    if record.reason:
        result["reason"] = clean(record.reason)
    if record.prooftest is not None:
        result["prooftest"] = record.prooftest.json()
    if record.rearm is not None:
        rearm: JsonDict = {"kind": record.rearm.kind.value}
        if record.rearm.caller is not None:
            rearm["caller"] = caller_json(record.rearm.caller)
        result["rearm"] = rearm
    return result


# -- pushes --------------------------------------------------------------------------------


def state_push(decision: Decision) -> JsonDict:
    """The ``state`` push for a decision."""
    return {"event": Topic.STATE.event, **decision_json(decision)}


def record_push(record: Mapping[str, object]) -> JsonDict:
    """The ``record`` push for a record as written to the store (e.g. :func:`record_json`)."""
    return {"event": Topic.RECORDS.event, **record}


_MESSAGE_TOPICS: Final[Mapping[type, Topic]] = {
    Joystick: Topic.JOYSTICK,
    Gps: Topic.GPS,
    RemoteStatus: Topic.REMOTE_STATUS,
}


def message_topic(message: Message) -> Topic | None:
    """The topic a VSC message is pushed under, or ``None`` for messages that are not pushed."""
    return _MESSAGE_TOPICS.get(type(message))


def message_push(message: Joystick | Gps | RemoteStatus) -> JsonDict:
    """The push for a joystick, GPS or remote-status message: its ``srcsctl decode`` JSON
    (``docs/protocol.md``) under ``event``."""
    topic = _MESSAGE_TOPICS[type(message)]
    return {"event": topic.event, **message_json(message)}


# -- safety-core events --------------------------------------------------------------------


def display_message(
    request: DisplayValue | DisplayLabel | DisplayRow | DisplayModeRequest | Vibrate,
) -> FeedbackSet | FeedbackName:
    """The VSC message a display or vibrate request asks for (manual §8.3.7, §8.3.10)."""
    match request:
        case DisplayValue(key=key, value=value):
            return FeedbackSet(key, value)
        case DisplayLabel(key=key, text=text):
            return FeedbackName(key, text)
        case DisplayRow(index=index, text=text):
            return FeedbackName(_TEXT_ROW_1 + index - 1, text)
        case DisplayModeRequest(mode=mode):
            return FeedbackSet(FeedbackKey.DISPLAY_MODE, int(mode))
        case Vibrate(side=side):
            return FeedbackSet(side.key, 1)  # PR-2: vibrate takes the value 1


@dataclass(frozen=True, slots=True)
class ClientInfo:
    """One connection as the safety core knows it: its number, who is at the other end
    (from the peer credentials) and the name it gave in ``hello`` (``None`` before)."""

    connection: int
    caller: Caller
    name: str | None = None


def to_core_event(request: Request, client: ClientInfo, now: int) -> Event | None:
    """The safety-core event for a request from ``client`` received at ``now``, or ``None``
    for requests the daemon answers itself (``status``, ``subscribe``, ``commission``).

    E-stops and releases of a named client are its own (``client_estop:NAME``); before hello
    they are the local operator's (``local_estop``, with the caller). A hold before hello is
    filed by the core under the connection and ends with it. ``reset`` always becomes a
    :class:`ResetRequest`, also from a non-admin, so that the core records the refusal.
    """
    connection, named = client.connection, client.name is not None
    match request:
        case Hello(name=name):
            return ClientHello(now, connection, name)
        case Heartbeat():
            return ClientHeartbeat(now, connection) if named else None
        case Estop():
            return ClientEstop(now, connection) if named else LocalEstop(now, client.caller)
        case Hold():
            return ClientHold(now, connection)
        case Release(what=Releasable.ESTOP) if not named:
            return LocalRelease(now, client.caller)
        case Release(what=what):
            return ClientRelease(now, connection, what)
        case DisplayValue() | DisplayLabel() | DisplayRow() | DisplayModeRequest() | Vibrate():
            return DisplayUpdate(now, display_message(request))
        case Reset():
            return ResetRequest(now, client.caller)
        case ProofTest():
            return ProofTestRequest(now, client.caller)
        case Status() | Subscribe() | Commission():
            return None
