"""The client API's requests (SR-8, ``docs/api.md`` "Requests"): sans-IO.

:func:`parse_request` turns one request line into a frozen request value or raises
:class:`~supervisord.api.framing.ApiError` with a stable ``code``: garbage from a peer either
parses or raises ``ApiError``, nothing else. :func:`readable_stop` reads the e-stop or hold a
refused line still asks for (SR-8.13). The values and :func:`request_json`, the inverse
for clients, live in :mod:`supervisord.api.ops` (the client library imports only that) and
are re-exported here.

Nothing here touches a socket or a clock.
"""

from __future__ import annotations

import enum
import json
import re
from collections.abc import Callable, Mapping
from typing import Final

from supervisord import strict
from supervisord.api.framing import MAX_ID_LENGTH, MAX_NESTING, ApiError, ErrorCode
from supervisord.api.jsonscan import STOP_OP_NAMES, brackets_outside_strings, op_in_broken
from supervisord.api.ops import (
    ApiRequest,
    Command,
    Commission,
    DisplayLabel,
    DisplayModeRequest,
    DisplayRow,
    DisplayValue,
    Estop,
    FleetKeepaliveRequest,
    FleetReleaseRequest,
    FleetStopRequest,
    Heartbeat,
    Hello,
    Hold,
    Release,
    RequestId,
    Reset,
    Side,
    StartProofTest,
    Status,
    StopTest,
    Subscribe,
    Topic,
    Vibrate,
    request_json,
)
from supervisord.protocol.codes import USER_VALUE_KEYS, DisplayMode
from supervisord.protocol.messages import I32, NAME_TEXT_LENGTH, check_text
from supervisord.protocol.text import clean, is_clean
from supervisord.release import Request
from supervisord.safety.config import NAME_PATTERN
from supervisord.safety.fleet import FLEET_TEXT
from supervisord.safety.progress import PROGRESS_MODULUS

__all__ = [
    "ADMIN_REQUESTS",
    "NAMED_REQUESTS",
    "OPS",
    "ApiRequest",
    "Command",
    "Commission",
    "DisplayLabel",
    "DisplayModeRequest",
    "DisplayRow",
    "DisplayValue",
    "Estop",
    "FleetKeepaliveRequest",
    "FleetReleaseRequest",
    "FleetStopRequest",
    "Heartbeat",
    "Hello",
    "Hold",
    "Release",
    "RequestId",
    "Reset",
    "Side",
    "StartProofTest",
    "Status",
    "StopTest",
    "Subscribe",
    "Topic",
    "Vibrate",
    "honoured_error",
    "parse_request",
    "read_request",
    "readable_stop",
    "request_json",
]

ADMIN_REQUESTS: Final = (Reset, Commission, StartProofTest, StopTest)
"""Requests only an admin may make (SR-8)."""
NAMED_REQUESTS: Final = (Heartbeat, Command)
"""Requests that need a connection that said hello."""

_ROWS = range(1, 5)


def _reject_constant(name: str) -> object:
    raise ValueError(f"{name} is not JSON")


def _unique_keys(pairs: list[tuple[str, object]]) -> dict[str, object]:
    result: dict[str, object] = {}
    for key, value in pairs:
        if key in result:
            raise ValueError(f"duplicate key {_shown(key)}")
        result[key] = value
    return result


_INNERMOST = re.compile(rb"\[\]|\{\}")  # among brackets alone


def _too_deep(line: bytes) -> bool:
    """Whether ``line`` nests arrays and objects deeper than :data:`MAX_NESTING`.

    Decided before parsing, so the answer never depends on how deep the caller's stack is
    (Python's parser raises ``RecursionError`` near its limit, wherever that is). Brackets
    inside strings do not count. Cost: a count, and only for lines with many brackets, the
    brackets outside strings taken (linear at C speed, SR-10.5: :mod:`supervisord.api.jsonscan`)
    and at most ``MAX_NESTING`` passes over them of a regular expression (C speed, linear)."""
    if line.count(b"[") + line.count(b"{") <= MAX_NESTING:
        return False
    rest = brackets_outside_strings(line)
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


_DECODER: Final = json.JSONDecoder(parse_constant=_reject_constant, object_pairs_hook=_unique_keys)
"""The one decoder of request lines: ``json.loads`` with these hooks would build a decoder
per line (SR-9.4: a client's heartbeat at 10 Hz pays for its line's parse, nothing else).
It holds no state between lines."""


def _load(line: bytes) -> object:
    if _too_deep(line):
        raise ApiError(
            ErrorCode.BAD_JSON, f"arrays and objects may be nested at most {MAX_NESTING} deep"
        )
    try:
        text = line.decode("utf-8")
        return _DECODER.decode(text)
    except UnicodeDecodeError as e:
        raise ApiError(ErrorCode.BAD_JSON, f"the line is not UTF-8: {e.reason}") from e
    except RecursionError as e:
        raise ApiError(ErrorCode.BAD_JSON, "the JSON is nested too deeply") from e
    except ValueError as e:  # json.JSONDecodeError is a ValueError
        raise ApiError(ErrorCode.BAD_JSON, f"not JSON: {e}") from e


class _Fields:
    """Reads the fields of one request object through the one strict reader of untrusted
    tables (``supervisord.strict``), raising ``bad_request`` with its wording: the field's
    path, its value (shown bounded) and the fix."""

    def __init__(
        self, obj: Mapping[str, object], op: str, request_id: RequestId, where: str = ""
    ) -> None:
        self.obj, self.op, self.id = obj, op, request_id
        self.fields = strict.Fields(obj, where)
        if not where:
            self.fields.used.update({"op": None, "id": None})

    def error(self, message: str) -> ApiError:
        # clean: a field name from a peer may hold lone surrogates; 200: a bounded reply, cut
        # first, as clean goes character by character (SR-10.5); it only ever lengthens them.
        return ApiError(
            ErrorCode.BAD_REQUEST, clean(message[:200])[:200], op=self.op, request_id=self.id
        )

    def _read(self, key: strict.Key) -> object:
        try:
            return self.fields.read(key)
        except strict.Invalid as e:
            raise self.error(str(e)) from None

    def get(self, name: str) -> object:
        value = self.fields.raw(name)
        if value is strict.MISSING:
            raise self.error(
                str(strict.Invalid(self.fields.key(name), value, f"{self.op} needs it"))
            )
        return value

    def nested(self, name: str) -> _Fields:
        value = self.get(name)
        if not isinstance(value, dict):
            raise self.error(str(strict.Invalid(self.fields.key(name), value, "make it an object")))
        return _Fields(value, self.op, self.id, self.fields.key(name))

    def integer(self, name: str, low: int, high: int) -> int:
        value = self._read(strict.Whole(name=name, doc="", low=low, high=high))
        assert isinstance(value, int)
        return value

    def text(self, name: str) -> str:
        value = self.get(name)
        try:
            check_text(name, value, NAME_TEXT_LENGTH)  # type: ignore[arg-type]
        except ValueError:
            fix = f"use at most {NAME_TEXT_LENGTH} single-byte characters without NUL, as text"
            raise self.error(str(strict.Invalid(self.fields.key(name), value, fix))) from None
        assert isinstance(value, str)
        return value

    def choice(self, name: str, members: tuple[enum.Enum, ...]) -> enum.Enum:
        by_value = {str(member.value): member for member in members}
        value = self._read(strict.Choice(name=name, doc="", values=dict.fromkeys(by_value, "")))
        return by_value[str(value)]

    def finish(self) -> None:
        try:
            self.fields.finish()
        except strict.Invalid as e:
            raise self.error(str(e)) from None


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
        # the reply, so the request is refused without an id (SR-8.7).
        raise ApiError(ErrorCode.BAD_REQUEST, "id text must be Unicode (no lone surrogates)")
    if isinstance(value, int) and not -(2**63) <= value < 2**63:
        raise ApiError(ErrorCode.BAD_REQUEST, "id must fit in 64 signed bits")
    return value


def _hello(f: _Fields) -> ApiRequest:
    name = f.get("name")
    if not isinstance(name, str) or NAME_PATTERN.fullmatch(name) is None:
        raise f.error("name must be 1-32 letters, digits, '_', '.' or '-'")
    return Hello(name, id=f.id)


def _release(f: _Fields) -> ApiRequest:
    what = f.choice("what", tuple(Request))
    assert isinstance(what, Request)
    return Release(what, id=f.id)


def _heartbeat(f: _Fields) -> ApiRequest:
    if f.fields.raw("progress") is strict.MISSING:
        return Heartbeat(id=f.id)
    return Heartbeat(f.integer("progress", 0, PROGRESS_MODULUS - 1), id=f.id)


def _command(f: _Fields) -> ApiRequest:
    nonzero = f.get("nonzero")
    if not isinstance(nonzero, bool):
        raise f.error(f"nonzero must be true or false, not {_shown(nonzero)}")
    return Command(nonzero, id=f.id)


def _subscribe(f: _Fields) -> ApiRequest:
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


def _display(f: _Fields) -> ApiRequest:
    forms = [form for form in _DISPLAY_FORMS if form in f.obj]
    if len(forms) != 1:
        raise f.error(f"display takes exactly one of {', '.join(_DISPLAY_FORMS)}")
    form = forms[0]
    if form == "mode":
        mode = f.integer("mode", 0, max(DisplayMode))
        return DisplayModeRequest(DisplayMode(mode), id=f.id)
    inner = f.nested(form)
    request: ApiRequest
    if form == "value":
        key = inner.integer("key", USER_VALUE_KEYS.start, USER_VALUE_KEYS.stop - 1)
        request = DisplayValue(key, inner.integer("value", *I32), id=f.id)
    elif form == "label":
        key = inner.integer("key", USER_VALUE_KEYS.start, USER_VALUE_KEYS.stop - 1)
        request = DisplayLabel(key, inner.text("text"), id=f.id)
    else:
        index = inner.integer("index", _ROWS.start, _ROWS.stop - 1)
        request = DisplayRow(index, inner.text("text"), id=f.id)
    inner.finish()
    return request


def _vibrate(f: _Fields) -> ApiRequest:
    side = f.choice("side", tuple(Side))
    assert isinstance(side, Side)
    return Vibrate(side, id=f.id)


def _commission(f: _Fields) -> ApiRequest:
    if f.get("confirm") is not True:
        raise f.error('commission writes the VSC permanently: send "confirm": true')
    return Commission(id=f.id)


def _prooftest(f: _Fields) -> ApiRequest:
    return StartProofTest(id=f.id)


STOPTEST_SOURCES: Final = ("remote", "wired")
"""The e-stops a field stop test presses, at most once each (SR-12.1)."""


def _stoptest(f: _Fields) -> ApiRequest:
    steps = f.get("steps")
    if not isinstance(steps, list) or not 1 <= len(steps) <= len(STOPTEST_SOURCES):
        raise f.error(f"steps must be a list of 1 to {len(STOPTEST_SOURCES)} objects")
    parsed: list[tuple[str, int]] = []
    for index in range(len(steps)):
        value = steps[index]
        if not isinstance(value, dict):
            raise f.error(f"steps[{index}] must be an object with source and seq")
        inner = _Fields(value, f.op, f.id, f.fields.key("steps") + f"[{index}]")
        source = inner.get("source")
        if source not in STOPTEST_SOURCES or any(source == s for s, _ in parsed):
            raise f.error(f"steps[{index}].source must be one of remote, wired, each once")
        assert isinstance(source, str)
        parsed.append((source, inner.integer("seq", 1, 2**63 - 1)))
        inner.finish()
    return StopTest(tuple(parsed), id=f.id)


def _fleet_text(f: _Fields, name: str) -> str:
    value = f.get(name)
    if not isinstance(value, str) or FLEET_TEXT.fullmatch(value) is None:
        raise f.error(f"{name} must be 1-64 letters, digits, '_', '.', ':' or '-'")
    return value


def _fleet_order(
    kind: type[FleetStopRequest | FleetReleaseRequest],
) -> Callable[[_Fields], ApiRequest]:
    """The parser of a fleet console's stop or its release: the same two fields."""

    def parse(f: _Fields) -> ApiRequest:
        return kind(_fleet_text(f, "stop_id"), _fleet_text(f, "sender"), id=f.id)

    return parse


def _fleet_keepalive(f: _Fields) -> ApiRequest:
    return FleetKeepaliveRequest(_fleet_text(f, "sender"), id=f.id)


_PARSERS = {
    "hello": _hello,
    "heartbeat": _heartbeat,
    "estop": lambda f: Estop(id=f.id),
    "hold": lambda f: Hold(id=f.id),
    "release": _release,
    "command": _command,
    "status": lambda f: Status(id=f.id),
    "subscribe": _subscribe,
    "display": _display,
    "vibrate": _vibrate,
    "reset": lambda f: Reset(id=f.id),
    "commission": _commission,
    "prooftest": _prooftest,
    "stoptest": _stoptest,
    "fleet_stop": _fleet_order(FleetStopRequest),
    "fleet_release": _fleet_order(FleetReleaseRequest),
    "fleet_keepalive": _fleet_keepalive,
}
OPS: Final = tuple(_PARSERS)
"""Every request op, in the order ``docs/api.md`` documents them."""


def parse_request(line: bytes) -> ApiRequest:
    """One request line (without its newline) as a request value.

    Raises :class:`ApiError` (``bad_json``, ``bad_request`` or ``unknown_op``) for anything
    else; it carries the ``op`` and ``id`` when they could be read, for the error reply.
    """
    return _request(_load(line))


def read_request(line: bytes) -> tuple[ApiRequest | None, ApiError | None]:
    """What the server reads from one request line: ``(request, None)``, or, for a line
    :func:`parse_request` refuses, ``(stop, error)``: the e-stop or hold it still asks for
    (SR-8.13, :func:`readable_stop`; ``None`` when none) and the refusal. The line is parsed
    once (SR-10.5: a refused line's JSON is not read again to look for its op)."""
    try:
        obj = _load(line)
    except ApiError as error:
        return _broken_stop(line), error
    try:
        return _request(obj), None
    except ApiError as error:
        return _stop_in(obj), error


def _request(obj: object) -> ApiRequest:
    if not isinstance(obj, dict):
        raise ApiError(ErrorCode.BAD_REQUEST, "a request must be a JSON object")
    request_id = _request_id(obj)
    op = obj.get("op")
    if not isinstance(op, str):
        raise ApiError(ErrorCode.BAD_REQUEST, "a request needs an op", request_id=request_id)
    if op == "heartbeat":
        beat = _plain_heartbeat(obj, request_id)
        if beat is not None:
            return beat
    parser = _PARSERS.get(op)
    if parser is None:
        shown = op if len(op) <= 40 and op.isprintable() else repr(op[:40])
        raise ApiError(ErrorCode.UNKNOWN_OP, f"unknown op {shown}", request_id=request_id)
    fields = _Fields(obj, op, request_id)
    request = parser(fields)
    fields.finish()
    return request


def _plain_heartbeat(obj: Mapping[str, object], request_id: RequestId) -> Heartbeat | None:
    """A heartbeat whose only fields are ``op``, ``id`` (read already) and a ``progress``
    that is a whole number in range, read without the field reader (SR-9.4: what every
    robot program sends at 10 Hz or more); ``None`` for any other, which the full reader
    (:func:`_heartbeat`) reads, refuses and words. The same request as the full reader's:
    checked for every shape by ``tests/api/test_heartbeat_path.py`` (SR-8.16)."""
    fields = len(obj) - ("id" in obj)
    if fields == 1:
        return Heartbeat(id=request_id)
    progress = obj.get("progress")
    if fields == 2 and type(progress) is int and 0 <= progress < PROGRESS_MODULUS:
        return Heartbeat(progress, id=request_id)
    return None


# -- a malformed e-stop or hold (SR-8.13) ---------------------------------------------------

STOP_OPS: Final[dict[str, type[Estop] | type[Hold]]] = {"estop": Estop, "hold": Hold}
"""The ops honoured even in a malformed request: the ones that only add a reason to stop."""
assert tuple(STOP_OPS) == STOP_OP_NAMES  # the e-stop first: it wins in a broken line


def readable_stop(line: bytes) -> Estop | Hold | None:
    """The e-stop or hold a line :func:`parse_request` refused still asks for, or ``None``.

    SR-8.13 (``docs/api.md`` "A malformed e-stop or hold"): the op is read as ``estop`` or
    ``hold`` when the line is a JSON object whose ``"op"`` is that text (whatever its other
    fields, its ``id``, or a missing one), or, when the line is no JSON (a syntax error, a
    duplicate key, ``NaN``, nesting too deep, bytes that are not UTF-8), when a key ``"op"``
    of the outermost object is followed by ``:`` and that text as a whole JSON string
    (:func:`~supervisord.api.jsonscan.op_in_broken`). An e-stop wins over a hold when a
    broken line names both. The ``id`` is kept when it is valid, in a JSON object only.
    Never raises; linear in the line (SR-10.5)."""
    try:
        obj = _load(line)
    except ApiError:
        return _broken_stop(line)
    return _stop_in(obj)


def _broken_stop(line: bytes) -> Estop | Hold | None:
    """The e-stop or hold of a line that is no JSON (SR-8.13)."""
    op = op_in_broken(line)
    return None if op is None else STOP_OPS[op]()


def _stop_in(obj: object) -> Estop | Hold | None:
    """The e-stop or hold of a line that is JSON, ``obj`` (SR-8.13)."""
    op = obj.get("op") if isinstance(obj, dict) else None
    if not isinstance(op, str) or op not in STOP_OPS:
        return None
    try:
        request_id = _request_id(obj)  # type: ignore[arg-type]
    except ApiError:
        request_id = None  # a wrong id is answered without one, as every refused request
    return STOP_OPS[op](id=request_id)


def honoured_error(error: ApiError, request: ApiRequest) -> ApiError:
    """The reply to a malformed e-stop or hold that was honoured (SR-8.13): the error that
    says what was wrong, with the op and id that were read and ``"honoured": true``."""
    return ApiError(
        error.code,
        f"{error.message}; the {request.OP} was honoured",
        op=request.OP,
        request_id=request.id,
        extra={"honoured": True},
    )
