"""The API's message vocabulary (supervisord.api: framing, requests, views, translate):
framing, parsing, replies, pushes and core events."""

from __future__ import annotations

import datetime as dt
import json

import pytest

from supervisord.api.framing import ApiError, ErrorCode, LineReader, encode
from supervisord.api.pushes import RecordPush
from supervisord.api.requests import (
    OPS,
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
    Reset,
    Side,
    StartProofTest,
    Status,
    StopTest,
    Subscribe,
    Topic,
    Vibrate,
    parse_request,
    request_json,
)
from supervisord.api.translate import ClientInfo, to_core_event
from supervisord.api.views import (
    message_push,
    message_topic,
    ok_reply,
    refusal_error,
    state_push,
    state_report,
)
from supervisord.protocol.codes import DisplayMode
from supervisord.protocol.j1939 import (
    CanFrame,
    CanId,
    Hand,
    JoystickAssembler,
    JoystickBasic,
    decode_can,
)
from supervisord.protocol.jsonview import message_json
from supervisord.protocol.messages import (
    Axis,
    FeedbackName,
    FeedbackSet,
    Gps,
    Joystick,
    RemoteStatus,
    VscHeartbeat,
)
from supervisord.record.format import record_json, stop_record
from supervisord.record.jsonl import encode as encode_record
from supervisord.safety.config import SafetyConfig
from supervisord.safety.core import SafetyCore
from supervisord.safety.decision import RefusalReason
from supervisord.safety.events import (
    Caller,
    ClientCommand,
    ClientEstop,
    ClientHeartbeat,
    ClientHello,
    ClientHold,
    ClientRelease,
    DisplayUpdate,
    LocalEstop,
    LocalRelease,
    Request,
    ResetRequest,
)

ROOT = Caller(0, 42, "root", True)
USER = Caller(1000, 43, "robot", False)

EVERY_REQUEST: tuple[ApiRequest, ...] = (
    Hello("planner"),
    Heartbeat(),
    Heartbeat(0),
    Heartbeat(2**32 - 1, id=5),
    Estop(),
    Hold(),
    Release(Request.ESTOP),
    Release(Request.HOLD, id=3),
    Command(True),
    Command(False, id=7),
    Status(id="s-1"),
    Subscribe(frozenset({Topic.STATE, Topic.RECORDS})),
    Subscribe(frozenset()),
    DisplayValue(9, -(2**31)),
    DisplayLabel(1, "speed m/s"),
    DisplayRow(4, "x" * 20),
    DisplayModeRequest(DisplayMode.TEXT_ROWS),
    Vibrate(Side.LEFT),
    Reset(),
    Commission(),
    StartProofTest(),
    StopTest((("remote", 41), ("wired", 44))),
    FleetStopRequest("2026-12-06T14:00:00Z:17", "console-a", id=9),
    FleetReleaseRequest("s-1", "console.b"),
    FleetKeepaliveRequest("console-a"),
)


def code_of(line: bytes) -> str:
    with pytest.raises(ApiError) as caught:
        parse_request(line)
    return caught.value.code


# -- framing --------------------------------------------------------------------------------


def test_lines_are_cut_at_newlines() -> None:
    """Complete lines come out without their newline; a partial line waits for more bytes."""
    reader = LineReader(256)
    assert reader.feed(b'{"a":1}\n{"b"') == [b'{"a":1}']
    assert reader.pending == 4
    assert reader.feed(b":2}\n\n") == [b'{"b":2}', b""]


def test_lines_fed_byte_by_byte_come_out_the_same() -> None:
    """Feeding one byte at a time yields the same lines as feeding the whole stream."""
    stream = b'{"op":"status"}\n{"op":"hello","name":"a"}\n'
    whole = LineReader(256).feed(stream)
    reader = LineReader(256)
    pieces = [item for i in range(len(stream)) for item in reader.feed(stream[i : i + 1])]
    assert pieces == whole


def test_line_at_the_limit_passes_and_one_more_byte_is_too_long() -> None:
    """max_line counts the newline: 255 bytes and a newline pass, 256 and a newline do not."""
    reader = LineReader(256)
    assert reader.feed(b"a" * 255 + b"\n") == [b"a" * 255]
    items = reader.feed(b"b" * 256 + b"\nnext\n")
    assert isinstance(items[0], ApiError)
    assert items[0].code == ErrorCode.TOO_LONG
    assert items[1:] == [b"next"]


def test_too_long_is_reported_once_and_the_rest_discarded() -> None:
    """An over-long line sent in pieces gives one error, then lines after it read normally."""
    reader = LineReader(256, 4096)
    errors = [item for _ in range(10) for item in reader.feed(b"z" * 100)]
    assert [e.code for e in errors if isinstance(e, ApiError)] == [ErrorCode.TOO_LONG]
    assert reader.pending == 0
    assert reader.feed(b"zz\nok\n") == [b"ok"]
    assert not reader.flooded


def test_endless_line_floods_and_the_reader_stops() -> None:
    """More than max_discard bytes of one line set flooded, and nothing more is read."""
    reader = LineReader(256, 1024)
    reader.feed(b"z" * 1000)
    before = reader.flooded
    reader.feed(b"z" * 100)
    assert (before, reader.flooded) == (False, True)
    assert reader.feed(b"\nok\n") == []


def test_encode_is_one_compact_line() -> None:
    """Replies are compact UTF-8 JSON with one newline at the end, even with newlines inside."""
    line = encode({"ok": True, "text": "a\nb é"})
    assert line.count(b"\n") == 1
    assert line.endswith(b"\n")
    assert json.loads(line) == {"ok": True, "text": "a\nb é"}


def test_encode_refuses_values_json_cannot_hold() -> None:
    """NaN or a Python object in a reply is our mistake: ValueError, nothing encoded."""
    with pytest.raises(ValueError, match="JSON"):
        encode({"x": float("nan")})
    with pytest.raises(ValueError, match="JSON"):
        encode({"x": object()})


# -- parsing --------------------------------------------------------------------------------


@pytest.mark.parametrize("request_value", EVERY_REQUEST, ids=repr)
def test_every_request_round_trips(request_value: ApiRequest) -> None:
    """What request_json writes, parse_request reads back as the same value."""
    line = encode(request_json(request_value))[:-1]
    assert parse_request(line) == request_value


def test_every_op_is_covered_by_the_examples() -> None:
    """The round-trip examples use every op the server knows."""
    assert {r.OP for r in EVERY_REQUEST} == set(OPS)


@pytest.mark.parametrize(
    "line",
    [
        b"{",
        b"not json",
        b'{"op":"status"} trailing',
        b"\xff\xfe",
        b'{"op":"status","op":"reset"}',
        b'{"op":"display","mode":NaN}',
        b"[" * 5000 + b"]" * 5000,
    ],
)
def test_garbage_is_bad_json(line: bytes) -> None:
    """Undecodable text, trailing bytes, duplicate keys, NaN and deep nesting are bad_json."""
    assert code_of(line) == ErrorCode.BAD_JSON


@pytest.mark.parametrize(
    "obj",
    [
        [],
        "status",
        {},
        {"op": 1},
        {"op": "hello"},
        {"op": "hello", "name": ""},
        {"op": "hello", "name": "a" * 33},
        {"op": "hello", "name": "bad name"},
        {"op": "status", "extra": 1},
        {"op": "status", "id": True},
        {"op": "status", "id": "x" * 65},
        {"op": "status", "id": 2**63},
        {"op": "release"},
        {"op": "release", "what": "all"},
        {"op": "subscribe", "topics": "state"},
        {"op": "subscribe", "topics": ["weather"]},
        {"op": "display"},
        {"op": "display", "mode": 1, "row": {"index": 1, "text": "a"}},
        {"op": "display", "mode": 4},
        {"op": "display", "mode": True},
        {"op": "display", "value": {"key": 10, "value": 1}},
        {"op": "display", "value": {"key": 1, "value": 2**31}},
        {"op": "display", "value": {"key": 1}},
        {"op": "display", "value": [1, 2]},
        {"op": "display", "label": {"key": 0, "text": "a"}},
        {"op": "display", "label": {"key": 1, "text": "x" * 21}},
        {"op": "display", "label": {"key": 1, "text": "nul\u0000"}},
        {"op": "display", "label": {"key": 1, "text": "snow \u2603"}},
        {"op": "display", "row": {"index": 5, "text": "a"}},
        {"op": "display", "row": {"index": 1, "text": "a", "colour": "red"}},
        {"op": "vibrate", "side": "middle"},
        {"op": "heartbeat", "progress": -1},
        {"op": "heartbeat", "progress": 2**32},
        {"op": "heartbeat", "progress": 1.0},
        {"op": "heartbeat", "progress": "1"},
        {"op": "heartbeat", "progress": True},
        {"op": "heartbeat", "progress": None},
        {"op": "command"},
        {"op": "command", "nonzero": 1},
        {"op": "command", "nonzero": "true"},
        {"op": "command", "nonzero": None},
        {"op": "command", "nonzero": True, "speed": 1.0},
        {"op": "commission"},
        {"op": "commission", "confirm": "yes"},
    ],
    ids=repr,
)
def test_invalid_requests_are_bad_request(obj: object) -> None:
    """A request that is not an object, lacks a field, has an unknown one or is out of range."""
    assert code_of(json.dumps(obj).encode()) == ErrorCode.BAD_REQUEST


def test_unknown_op_echoes_the_id() -> None:
    """An unknown op is unknown_op, and the error reply carries the request's id."""
    with pytest.raises(ApiError) as caught:
        parse_request(b'{"op":"launch","id":12}')
    assert caught.value.code == ErrorCode.UNKNOWN_OP
    assert caught.value.reply() == {
        "ok": False,
        "code": "unknown_op",
        "error": "unknown op launch",
        "id": 12,
    }


def test_field_errors_name_the_op_and_field() -> None:
    """A bad field's error names the field and echoes the op, so a C programmer sees why."""
    with pytest.raises(ApiError) as caught:
        parse_request(b'{"op":"display","row":{"index":9,"text":"a"},"id":"r"}')
    reply = caught.value.reply()
    assert reply["op"] == "display"
    assert reply["id"] == "r"
    assert "row.index" in reply["error"]


# -- replies and pushes ---------------------------------------------------------------------


def test_ok_reply_echoes_op_and_id() -> None:
    """A success reply names the op and echoes the id."""
    assert ok_reply(Status(id=5)).json() == {"ok": True, "op": "status", "id": 5}
    assert ok_reply(Heartbeat()).json() == {"ok": True, "op": "heartbeat"}


def test_refusal_error_carries_the_reason_name() -> None:
    """A refusal by the safety core becomes a refused error with its stable reason name."""
    core = SafetyCore(SafetyConfig(local_reset=True), 0)
    decision = core.handle(ResetRequest(1, USER))
    (refusal,) = decision.refusals
    assert refusal.reason is RefusalReason.NOT_ADMIN
    reply = refusal_error(Reset(id=1), refusal).reply()
    assert reply["code"] == "refused"
    assert reply["reason"] == "not_admin"
    assert reply["error"] == refusal.message


def test_state_push_describes_the_decision() -> None:
    """The state push names the state, every cause with its details, outputs and e-stop byte."""
    decision = SafetyCore(SafetyConfig(), 7).decision
    push = state_push(decision).json()
    assert push["event"] == "state"
    assert push == {"event": "state", **state_report(decision).json()}
    assert push["state"] == "STOPPED"
    assert push["mono_ns"] == 7
    assert push["heartbeat_estop"] == 1
    names = [c["name"] for c in push["causes"]]
    assert "startup" in names
    watchdog = next(c for c in push["causes"] if c["name"] == "vsc_watchdog_off")
    assert watchdog["details"] == {"key85": "no answer"}
    assert watchdog["severity"] == "stop"
    json.dumps(push, allow_nan=False)


def test_message_pushes_use_the_topic_as_event() -> None:
    """Joystick, GPS and remote-status messages are pushed under their topic; others are not."""
    assert message_push(Joystick()).json()["event"] == "joystick"
    assert message_push(Joystick()).json()["type"] == "joystick"
    assert message_push(Gps(1, "$GPGGA,,")).json()["event"] == "gps"
    assert message_push(RemoteStatus(80)).json()["battery_level"] == 80
    assert message_topic(RemoteStatus(80)) is Topic.REMOTE_STATUS
    assert message_topic(VscHeartbeat(mode=9)) is None


@pytest.mark.parametrize("magnitude", [1020, 1021, 1022, 1023])
def test_can_joystick_push_agrees_with_decode_on_reserved_magnitudes(magnitude: int) -> None:
    """PR-3.2: a CAN joystick axis of magnitude 1022/1023 is null in the API's joystick push
    as in ``srcsctl decode --can``, and 1020/1021 are the same number in both."""
    word = Axis.from_value(-magnitude).to_word()
    frame = CanFrame(CanId.LEFT_BASIC, (word | 0x0001 << 16).to_bytes(4, "little") + b"\xff\0")
    basic = decode_can(frame)
    assert isinstance(basic, JoystickBasic)
    assert basic.hand is Hand.LEFT
    decoded_value = message_json(basic)["x_joystick_value"]["value"]
    pushed = message_push(JoystickAssembler().update(basic)).json()
    assert pushed["left_x_joystick_value"]["value"] == decoded_value
    assert decoded_value == (None if magnitude >= 1022 else -magnitude)
    assert pushed["left_x_joystick_value"]["magnitude"] == magnitude


def test_serial_joystick_push_keeps_1023_as_full_deflection() -> None:
    """PR-3.2, PR-2.1: on serial the reserved pair does not exist: 1023 is a full deflection."""
    pushed = message_push(Joystick(right_z=Axis.from_value(1023))).json()
    assert pushed["right_z_joystick_value"]["value"] == 1023


# -- safety-core events ---------------------------------------------------------------------

NAMED = ClientInfo(4, USER, "planner")
ANONYMOUS = ClientInfo(5, ROOT, None)


@pytest.mark.parametrize(
    ("request_value", "client", "expected"),
    [
        (Hello("planner"), NAMED, ClientHello(9, 4, "planner")),
        (Heartbeat(), NAMED, ClientHeartbeat(9, 4)),
        (Heartbeat(), ANONYMOUS, None),
        (Heartbeat(12), NAMED, ClientHeartbeat(9, 4, 12)),
        (Estop(), NAMED, ClientEstop(9, 4)),
        (Estop(), ANONYMOUS, LocalEstop(9, ROOT)),
        (Hold(), NAMED, ClientHold(9, 4)),
        (Hold(), ANONYMOUS, ClientHold(9, 5)),
        (Release(Request.ESTOP), NAMED, ClientRelease(9, 4, Request.ESTOP)),
        (Release(Request.ESTOP), ANONYMOUS, LocalRelease(9, ROOT)),
        (Release(Request.HOLD), ANONYMOUS, ClientRelease(9, 5, Request.HOLD)),
        (Command(True), NAMED, ClientCommand(9, 4, True)),
        (Command(False), NAMED, ClientCommand(9, 4, False)),
        (DisplayValue(3, 42), NAMED, DisplayUpdate(9, FeedbackSet(3, 42))),
        (DisplayLabel(3, "v"), NAMED, DisplayUpdate(9, FeedbackName(3, "v"))),
        (DisplayRow(1, "top"), ANONYMOUS, DisplayUpdate(9, FeedbackName(90, "top"))),
        (DisplayRow(4, "end"), ANONYMOUS, DisplayUpdate(9, FeedbackName(93, "end"))),
        (DisplayModeRequest(DisplayMode.VALUES), NAMED, DisplayUpdate(9, FeedbackSet(99, 3))),
        (Vibrate(Side.LEFT), NAMED, DisplayUpdate(9, FeedbackSet(10, 1))),
        (Vibrate(Side.RIGHT), NAMED, DisplayUpdate(9, FeedbackSet(11, 1))),
        (Vibrate(Side.BOTH), NAMED, DisplayUpdate(9, FeedbackSet(12, 1))),
        (Reset(), NAMED, ResetRequest(9, USER)),
        (Status(), NAMED, None),
        (Subscribe(frozenset()), NAMED, None),
        (Commission(), ANONYMOUS, None),
    ],
    ids=repr,
)
def test_requests_become_core_events(
    request_value: ApiRequest, client: ClientInfo, expected: object
) -> None:
    """Each request maps to the safety core's event: a named client's own, else the local one."""
    assert to_core_event(request_value, client, 9) == expected


def test_display_events_are_accepted_by_the_core() -> None:
    """Every display and vibrate request gives a message the core's display rules accept."""
    core = SafetyCore(SafetyConfig(), 0)
    for request_value in EVERY_REQUEST:
        event = to_core_event(request_value, NAMED, 1)
        if isinstance(event, DisplayUpdate):
            assert core.handle(event).refusals == (), request_value


# -- odd text (SR-8.7: no input string can raise) --------------------------------------------


def strict_utf8(obj: object) -> bytes:
    """The strictest encoding any sink uses: UTF-8 JSON, no NaN, no lone surrogates."""
    return json.dumps(obj, ensure_ascii=False, allow_nan=False).encode("utf-8")


@pytest.mark.parametrize("text_id", ["\\ud800", "\\udfff", "a\\udce9b", "\\ud83d"])
def test_an_id_with_a_lone_surrogate_is_refused_and_the_refusal_encodes(text_id: str) -> None:
    """An ``id`` that JSON can spell but UTF-8 cannot (a lone surrogate) is ``bad_request``,
    and the error reply, which then carries no id, encodes (it used to raise in the reply
    encoder and the loop stopped the robot with ``internal``)."""
    line = b'{"op":"status","id":"' + text_id.encode() + b'"}'
    with pytest.raises(ApiError) as caught:
        parse_request(line)
    assert caught.value.code == ErrorCode.BAD_REQUEST
    assert "id" not in caught.value.reply()
    strict_utf8(caught.value.reply())
    assert json.loads(encode(caught.value.reply()))["code"] == "bad_request"


def test_a_proper_surrogate_pair_in_an_id_is_text_and_echoed() -> None:
    """An escaped pair (``\\ud83d\\ude00``) is one character: a valid id, echoed as sent."""
    request = parse_request(b'{"op":"status","id":"\\ud83d\\ude00"}')
    assert request.id == "\U0001f600"
    assert json.loads(encode(ok_reply(request).json()))["id"] == "\U0001f600"


@pytest.mark.parametrize(
    "line",
    [
        b'{"op":"status","\\ud800":1}',
        b'{"op":"display","row":{"index":1,"text":"a","\\udc80":2}}',
        b'{"op":"\\ud800x"}',
        b'{"op":"release","what":"\\udfff"}',
        b'{"op":"subscribe","topics":["\\ud800"]}',
        b'{"op":"display","label":{"key":1,"text":"\\ud800"}}',
        b'{"op":"hello","name":"\\ud800"}',
        b'{"op":"status","\\ud800":1,"\\ud800":2}',
    ],
)
def test_every_error_about_odd_text_encodes(line: bytes) -> None:
    """Field names, ops and values with lone surrogates are refused with a reply that encodes
    strictly: the error text shows them escaped, never raw."""
    with pytest.raises(ApiError) as caught:
        parse_request(line)
    strict_utf8(caught.value.reply())
    assert encode(caught.value.reply()).endswith(b"\n")


@pytest.mark.parametrize(
    "line",
    [
        b'{"op":"display","mode":' + b"[" * 900 + b"]" * 900 + b"}",
        b'{"op":"display","value":' + b'{"a":' * 500 + b"1" + b"}" * 500 + b"}",
        b'{"op":"status","id":' + b"[" * 40 + b"]" * 40 + b"}",
        b"[" * 2000 + b"]" * 2000,
    ],
    ids=["list-900", "object-500", "list-40", "list-2000"],
)
def test_deep_nesting_is_bad_json_whatever_the_stack(line: bytes) -> None:
    """Arrays or objects nested deeper than any request needs are ``bad_json`` at any depth of
    the caller's stack, never a ``RecursionError`` (the answer must not depend on how deep the
    loop happens to be when it parses)."""

    def at_depth(n: int) -> str:
        return code_of(line) if n == 0 else at_depth(n - 1)

    assert {at_depth(n) for n in (0, 100, 400, 800)} == {ErrorCode.BAD_JSON}


def test_brackets_inside_text_do_not_count_as_nesting() -> None:
    """Text full of brackets is text: an id of 64 brackets is still a valid id."""
    request = parse_request(json.dumps({"op": "status", "id": "[{" * 32}).encode())
    assert request.id == "[{" * 32


@pytest.mark.parametrize(
    ("value", "code"),
    [
        (b"1e400", ErrorCode.BAD_REQUEST),
        (b"-1e400", ErrorCode.BAD_REQUEST),
        (b"1" * 4200, ErrorCode.BAD_REQUEST),
        (b"1" * 5000, ErrorCode.BAD_JSON),
        (b"0.5", ErrorCode.BAD_REQUEST),
        (b"Infinity", ErrorCode.BAD_JSON),
        (b"-Infinity", ErrorCode.BAD_JSON),
    ],
    ids=["1e400", "-1e400", "4200-digits", "5000-digits", "0.5", "Infinity", "-Infinity"],
)
def test_huge_and_unusual_numbers_are_refused_with_a_reply_that_encodes(
    value: bytes, code: ErrorCode
) -> None:
    """Numbers JSON allows but no field takes (an overflowing float, thousands of digits,
    Infinity) are refused with a short reply that encodes; nothing converts them to text
    beyond Python's limit for integers."""
    for line in (
        b'{"op":"display","mode":' + value + b"}",
        b'{"op":"status","id":' + value + b"}",
        b'{"op":"display","value":{"key":1,"value":' + value + b"}}",
    ):
        with pytest.raises(ApiError) as caught:
            parse_request(line)
        assert caught.value.code == code
        reply = encode(caught.value.reply())
        assert len(reply) < 400
        strict_utf8(caught.value.reply())


def test_json_whitespace_is_accepted_and_other_whitespace_is_bad_json() -> None:
    """Space, tab and CR around tokens are JSON; a vertical tab, form feed or no-break space
    is not, and is ``bad_json`` (never a different exception)."""
    assert parse_request(b' \t{ "op" :\t"status" }\r ') == Status()
    for odd in (b"\x0b", b"\x0c", b"\xc2\xa0", b"\xe2\x80\x83", b"\x00"):
        assert code_of(b"{" + odd + b'"op":"status"}') == ErrorCode.BAD_JSON


def test_encode_escapes_text_that_utf8_cannot_hold() -> None:
    """The last net: a lone surrogate that reached a reply is written as visible escaped text
    (``\\ud800``, ``\\xe9`` for an undecodable byte), never raised."""
    line = encode({"ok": True, "a": "x\ud800", "b": ["r\udce9mi"], "c": {"\udfff": 1}})
    assert json.loads(line.decode("utf-8")) == {
        "ok": True,
        "a": "x\\ud800",
        "b": ["r\\xe9mi"],
        "c": {"\\udfff": 1},
    }


ODD_USER = Caller(4242, 44, "r\udce9mi", False)  # a login name that is not UTF-8


def test_a_record_and_a_status_naming_an_odd_user_encode_strictly() -> None:
    """A local e-stop by a user whose name was not UTF-8 (the name carries surrogates from the
    password database) gives a record the store and the journal can encode, and a status that
    encodes: the name shows its undecodable byte escaped (the stop record used to be lost
    and ``status`` to stop answering)."""
    core = SafetyCore(SafetyConfig(), 0)
    decision = core.handle(LocalEstop(5, ODD_USER))
    (record,) = decision.records
    obj = record_json(record, dt.datetime(2026, 3, 1, tzinfo=dt.timezone.utc))
    assert encode_record(obj).endswith(b"\n")
    strict_utf8(obj)
    assert obj["trigger"]["caller"]["name"] == "r\\xe9mi"
    strict_utf8(state_push(decision).json())
    strict_utf8(
        RecordPush(stop_record(record, dt.datetime(2026, 3, 1, tzinfo=dt.timezone.utc))).json()
    )
    local = next(c for c in state_report(decision).json()["causes"] if c["name"] == "local_estop")
    strict_utf8(local)
