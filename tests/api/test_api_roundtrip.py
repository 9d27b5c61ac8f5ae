"""Every reply and push of the client API, both ends (docs/api.md "Framing"): what the server
encodes (each type's one encoder, then the server's line encoder) reads back on the client
(:func:`~supervisord.api.replies.read_reply`, :func:`~supervisord.api.pushes.read_push`) as
the same value, and fields the client does not know, as a newer daemon may send them, are
ignored. A reply or push that is not what docs/api.md says is a ``WireError``, never another
exception."""

from __future__ import annotations

import dataclasses
import json
from collections.abc import Callable
from typing import Any, TypeVar

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from supervisord.api.framing import ApiError, encode
from supervisord.api.messages import (
    LEFT_BUTTONS,
    RIGHT_BUTTONS,
    AxisReport,
    ButtonsReport,
    GpsFixReport,
    GpsReport,
    JoystickReport,
    RemoteStatusReport,
)
from supervisord.api.pushes import (
    GpsPush,
    JoystickPush,
    OtherPush,
    Push,
    RecordPush,
    RemoteStatusPush,
    StatePush,
    read_push,
)
from supervisord.api.replies import (
    CommissionReply,
    FleetOutput,
    FleetStopReply,
    OkReply,
    Reply,
    StatusReply,
    StopTestReply,
    read_reply,
)
from supervisord.api.status import (
    SINK_COUNTERS,
    Cause,
    ClientStatus,
    DaemonStatus,
    EstopAvailable,
    HistogramStatus,
    LinkStatus,
    LoopStatus,
    Maintenance,
    PeriodicDue,
    ProofTestResult,
    ProofTestStatus,
    RemoteReport,
    StateReport,
)
from supervisord.api.views import joystick_report
from supervisord.api.wire import WireError
from supervisord.protocol.codes import FieldStatus
from supervisord.protocol.messages import DPad, Joystick, NumberedButtons
from supervisord.record.stop import (
    Caller,
    Change,
    OutputOffReport,
    Rearm,
    StopRecord,
    StopStepReport,
    StopTestReport,
)
from supervisord.record.stop import RecordKind as RK
from supervisord.vocabulary import (
    Cause as Named,
)
from supervisord.vocabulary import (
    CauseKind,
    ChangeKind,
    Phase,
    ProofTestPolicy,
    RearmKind,
    Severity,
    State,
    UnknownCause,
    UnknownCauseKind,
)

T = TypeVar("T")

# Text a client may meet: any character JSON carries as UTF-8 (the server cleans lone
# surrogates at their source, docs/safety.md "No input can raise").
TEXT = st.text(st.characters(exclude_categories=["Cs"]), max_size=12)
NAMES = st.text("abcdefghijklmnopqrstuvwxyz_:0123456789", min_size=1, max_size=12)
INTS = st.integers(-(2**63), 2**63 - 1)
COUNTS = st.integers(0, 2**63 - 1)
SECONDS = st.none() | st.floats(0, 1e9, allow_nan=False).map(lambda s: round(s, 3))
FLOATS = st.floats(allow_nan=False, allow_infinity=False)
IDS = st.none() | INTS | TEXT
SUBJECTS = st.text("abcdefghijklmnopqrstuvwxyz_:0123456789", min_size=1, max_size=8)
CAUSE_NAMES = st.builds(
    lambda kind, subject: Named(kind, subject if kind.has_subject else None),
    st.sampled_from(CauseKind),
    SUBJECTS,
) | st.builds(
    # A kind a newer daemon added: kept as written (docs/api.md).
    UnknownCause,
    st.from_regex(r"new_[a-z_]{1,8}", fullmatch=True).map(UnknownCauseKind),
    st.none() | SUBJECTS,
)


def kw(cls: Callable[..., T], **fields: st.SearchStrategy[Any]) -> st.SearchStrategy[T]:
    return st.builds(cls, **fields)


CAUSES = kw(
    Cause,
    name=CAUSE_NAMES,
    severity=st.sampled_from(Severity),
    active=st.booleans(),
    latched=st.booleans(),
    raised_ns=st.none() | COUNTS,
    cleared_ns=st.none() | COUNTS,
    details=st.dictionaries(NAMES, TEXT, max_size=3),
)
PROOF_RESULTS = kw(
    ProofTestResult,
    result=st.sampled_from(["passed", "failed"]),
    failure=st.none() | st.sampled_from(["no_trip", "late", "key85_off"]),
    trip_ms=st.none() | COUNTS,
    cleared=st.none() | st.sampled_from(["by_itself", "held"]),
    cleared_ms=st.none() | COUNTS,
    text=TEXT,
)
PROOF = kw(
    ProofTestStatus,
    policy=st.sampled_from(ProofTestPolicy),
    phase=st.sampled_from(Phase),
    last=st.none() | PROOF_RESULTS,
)
REPORTS = kw(
    StateReport,
    state=st.sampled_from(State),
    mono_ns=INTS,
    causes=st.lists(CAUSES, max_size=3).map(tuple),
    outputs=st.dictionaries(NAMES, st.booleans(), max_size=3),
    heartbeat_estop=st.integers(0, 255),
    prooftest=st.none() | PROOF,
)
HISTOGRAMS = kw(
    HistogramStatus,
    le=st.lists(FLOATS, max_size=4).map(tuple),
    counts=st.lists(COUNTS, max_size=4).map(tuple),
    sum=FLOATS,
    count=COUNTS,
)
DUES = kw(
    PeriodicDue, interval_days=st.integers(0, 3650), last_pass_age_s=SECONDS, overdue=st.booleans()
)
LOOPS = kw(
    LoopStatus,
    pid=COUNTS,
    version=TEXT,
    uptime_s=SECONDS,
    link=kw(
        LinkStatus,
        description=TEXT,
        open=st.booleans(),
        opens=COUNTS,
        open_failures=COUNTS,
        since_s=SECONDS,
        last_error=st.none() | TEXT,
        error_frames=st.none() | COUNTS,
    ),
    outputs_not_acquired=st.lists(NAMES, max_size=2).map(tuple),
    outputs_off_delay_ms=st.dictionaries(NAMES, COUNTS, max_size=2),
    messages=COUNTS,
    rejections=st.dictionaries(NAMES, COUNTS, max_size=3),
    record_errors=COUNTS,
    records_dropped=COUNTS,
    sink=st.fixed_dictionaries(dict.fromkeys(SINK_COUNTERS, COUNTS)),
    rate_limited=COUNTS,
    internal_faults=COUNTS,
    histograms=st.dictionaries(NAMES, HISTOGRAMS, max_size=3),
    maintenance=st.none()
    | kw(
        Maintenance,
        stoptest=st.none() | DUES,
        prooftest=st.none() | DUES,
    ),
)
REMOTES = kw(
    RemoteReport,
    battery_level=st.integers(0, 255),
    battery_charging=st.integers(0, 255),
    connection_strength_vsc=st.integers(0, 255),
    connection_strength_src=st.integers(0, 255),
    rssi_vsc=st.integers(0, 255),
    rssi_src=st.integers(0, 255),
    age_s=SECONDS,
)
DAEMONS = kw(
    DaemonStatus,
    robot=st.none() | TEXT,
    loop=LOOPS,
    clients=st.lists(
        kw(
            ClientStatus,
            name=NAMES,
            required=st.booleans(),
            connected=st.booleans(),
            heartbeat_age_s=SECONDS,
            command_nonzero=st.booleans(),
            timeout_ms=st.none() | COUNTS,
        ),
        max_size=3,
    ).map(tuple),
    connections=COUNTS,
    remote=st.none() | REMOTES,
    in_state_s=SECONDS,
)
OPS = st.sampled_from(["hello", "heartbeat", "estop", "hold", "release", "subscribe",
                       "display", "vibrate", "reset", "prooftest", "a_newer_op"])  # fmt: skip
STOPTESTS = kw(
    StopTestReport,
    result=st.sampled_from(["passed", "failed"]),
    limit_ms=COUNTS,
    steps=st.lists(
        kw(
            StopStepReport,
            source=st.sampled_from(["remote", "wired"]),
            seq=COUNTS,
            stop_ns=INTS,
            passed=st.booleans(),
            outputs=st.lists(
                kw(
                    OutputOffReport,
                    name=NAMES,
                    off_ns=st.none() | INTS,
                    off_ms=st.none() | FLOATS,
                    off_delay_ms=COUNTS,
                    passed=st.booleans(),
                ),
                max_size=3,
            ).map(tuple),
        ),
        max_size=2,
    ).map(tuple),
    text=TEXT,
)
REPLIES: st.SearchStrategy[Reply] = st.one_of(
    kw(OkReply, op=OPS, id=IDS),
    kw(
        StatusReply,
        id=IDS,
        report=REPORTS,
        estop_available=st.none()
        | kw(
            EstopAvailable, available=st.booleans(), missing=st.lists(TEXT, max_size=3).map(tuple)
        ),
        daemon=DAEMONS,
    ),
    kw(CommissionReply, id=IDS, key85=st.none() | st.integers(0, 255), remote_status=st.booleans()),
    kw(StopTestReply, id=IDS, stoptest=STOPTESTS),
    kw(
        FleetStopReply,  # SR-8.20
        id=IDS,
        stop_id=NAMES,
        state=st.sampled_from(State),
        outputs=st.lists(
            kw(FleetOutput, name=NAMES, level=st.booleans(), readback=st.none() | st.booleans()),
            max_size=3,
        ).map(tuple),
        record_seq=st.none() | COUNTS,
        arrival_to_off_ms=FLOATS,
        repeat=st.booleans(),
    ),
)
CALLERS = kw(Caller, uid=COUNTS, pid=COUNTS, name=TEXT, admin=st.booleans())
RECORDS = kw(
    StopRecord,
    seq=COUNTS,
    mono_ns=INTS,
    utc=TEXT,
    kind=st.none() | st.sampled_from(RK),
    from_state=st.sampled_from(State),
    to_state=st.sampled_from(State),
    causes=st.lists(CAUSES, max_size=3).map(tuple),
    changes=st.none()
    | st.lists(
        kw(Change, name=CAUSE_NAMES, change=st.sampled_from(ChangeKind)),
        max_size=3,
    ).map(tuple),
    trigger=st.fixed_dictionaries(
        {"event": st.sampled_from(["tick", "local_estop"])},
        optional={"connection": COUNTS, "reason": TEXT, "caller": CALLERS.map(Caller.json)},
    ),
    reason=st.none() | TEXT,
    prooftest=st.none() | PROOF_RESULTS,
    stoptest=st.none() | STOPTESTS,
    rearm=st.none() | kw(Rearm, kind=st.sampled_from(RearmKind), caller=st.none() | CALLERS),
    version=st.none() | TEXT,
)
AXES = kw(
    AxisReport,
    value=st.none() | st.integers(-1023, 1023),
    magnitude=st.integers(0, 1023),
    neutral_status=st.integers(0, 3),
    negative_status=st.integers(0, 3),
    positive_status=st.integers(0, 3),
)


def buttons(names: tuple[str, ...]) -> st.SearchStrategy[ButtonsReport]:
    return kw(
        ButtonsReport,
        byte=st.integers(0, 255),
        statuses=st.tuples(*(st.tuples(st.just(n), st.integers(0, 3)) for n in names)),
        pressed=st.lists(st.sampled_from(names), unique=True).map(tuple),
    )


PUSHES: st.SearchStrategy[Push] = st.one_of(
    st.builds(StatePush, REPORTS),
    st.builds(RecordPush, RECORDS),
    st.builds(
        JoystickPush,
        kw(
            JoystickReport,
            left_x=AXES,
            left_y=AXES,
            left_z=AXES,
            right_x=AXES,
            right_y=AXES,
            right_z=AXES,
            left_buttons=buttons(LEFT_BUTTONS),
            right_buttons=buttons(RIGHT_BUTTONS),
        ),
    ),
    st.builds(
        GpsPush,
        kw(
            GpsReport,
            source=st.integers(0, 255),
            string=TEXT,
            fix=st.none()
            | kw(
                GpsFixReport,
                sentence_type=TEXT,
                utc_time=st.none() | TEXT,
                latitude=st.none() | FLOATS,
                longitude=st.none() | FLOATS,
                fix_quality=st.none() | st.integers(0, 9),
                valid=st.booleans(),
            ),
        ),
    ),
    st.builds(
        RemoteStatusPush,
        kw(
            RemoteStatusReport,
            battery_level=st.integers(0, 255),
            battery_charging=st.integers(0, 255),
            connection_strength_vsc=st.integers(0, 255),
            connection_strength_src=st.integers(0, 255),
            rssi_vsc=st.integers(0, 255),
            rssi_src=st.integers(0, 255),
        ),
    ),
    kw(OtherPush, event=st.just("a_newer_event"), data=st.dictionaries(NAMES, TEXT, max_size=3)),
)

DATA_KEYED = frozenset(
    {"outputs", "outputs_off_delay_ms", "details", "rejections", "histograms", "trigger", "extra"}
)
"""Objects whose keys are data, not field names: a new field cannot appear in them."""
NEW_NAMES = st.text("abcdefghijklmnopqrstuvwxyz", min_size=1, max_size=8).map("new_".__add__)
NEW_VALUES = st.none() | st.booleans() | INTS | TEXT | st.lists(INTS, max_size=2)


def wire(obj: dict[str, Any]) -> object:
    """What the client reads: the server's line, parsed."""
    line = encode(obj)
    assert line.endswith(b"\n")
    assert line.count(b"\n") == 1
    return json.loads(line)


@st.composite
def newer(draw: st.DrawFn, obj: object) -> object:
    """``obj`` with new fields in every object of it, as a newer daemon might send."""
    if isinstance(obj, list):
        return [draw(newer(item)) for item in obj]
    if not isinstance(obj, dict):
        return obj
    out = {k: v if k in DATA_KEYED else draw(newer(v)) for k, v in obj.items()}
    for name in draw(st.lists(NEW_NAMES, max_size=2)):
        out.setdefault(name, draw(NEW_VALUES))
    return out


@settings(max_examples=300, deadline=None)
@given(REPLIES)
def test_every_reply_reads_back_as_sent(reply: Reply) -> None:
    """SR-8: server encode, JSON bytes, client decode: the same reply."""
    assert read_reply(wire(reply.json())) == reply


@settings(max_examples=300, deadline=None)
@given(PUSHES)
def test_every_push_reads_back_as_sent(push: Push) -> None:
    """SR-8: server encode, JSON bytes, client decode: the same push."""
    assert read_push(wire(push.json())) == push


@settings(max_examples=200, deadline=None)
@given(REPLIES.flatmap(lambda r: st.tuples(st.just(r), newer(wire(r.json())))))
def test_a_reply_with_new_fields_reads_as_without(pair: tuple[Reply, object]) -> None:
    """Fields the client does not know, anywhere in a reply, are ignored."""
    reply, sent = pair
    assert read_reply(sent) == reply


@settings(max_examples=200, deadline=None)
@given(PUSHES.flatmap(lambda p: st.tuples(st.just(p), newer(wire(p.json())))))
def test_a_push_with_new_fields_reads_as_without(pair: tuple[Push, object]) -> None:
    """Fields the client does not know, anywhere in a push, are ignored (a push of an event it
    does not know keeps them all: it has nothing to read them by)."""
    push, sent = pair
    read = read_push(sent)
    if isinstance(push, OtherPush):
        assert isinstance(read, OtherPush)
        assert read.event == push.event
        assert dict(read.data).items() >= dict(push.data).items()
    else:
        assert read == push


@pytest.mark.parametrize("hand", ["left_button_values", "right_button_values"])
def test_a_new_field_named_like_a_button_is_no_button(hand: str) -> None:
    """SR-8: a newer daemon's field that ends in ``_status`` inside a hand's buttons (which
    Hypothesis drew once as ``new_status``) is ignored like any other: each hand's buttons are
    the ones the manual names, not whatever the wire's keys end in."""
    pressed = Joystick(
        left_buttons=DPad(up=FieldStatus.SET),
        right_buttons=NumberedButtons(button_2=FieldStatus.SET),
    )
    push = JoystickPush(joystick_report(pressed))
    sent = json.loads(json.dumps(push.json()))
    sent[hand]["new_status"] = None
    sent[hand]["spare_status"] = 3
    assert read_push(sent) == push


def test_the_hands_buttons_are_the_protocols() -> None:
    """PR-2.4: the client's names of each hand's buttons, in wire order, are the decoder's."""
    assert tuple(f.name for f in dataclasses.fields(DPad)) == LEFT_BUTTONS
    assert tuple(f.name for f in dataclasses.fields(NumberedButtons)) == RIGHT_BUTTONS


@settings(max_examples=100, deadline=None)
@given(
    st.sampled_from(["bad_request", "refused", "failed", "a_newer_code"]),
    TEXT,
    st.none() | OPS,
    IDS,
    st.dictionaries(NEW_NAMES, NEW_VALUES, max_size=2),
)
def test_an_error_reads_back_as_the_error_sent(
    code: str, text: str, op: str | None, request_id: int | str | None, extra: dict[str, object]
) -> None:
    """An error reply is read back as the ``ApiError`` it was: code, text, op, id and its
    other fields (``reason``, ``key85`` ...), whatever the code."""
    error = ApiError(code, text, op=op, request_id=request_id, extra=extra)
    read = read_reply(wire(error.reply()))
    assert isinstance(read, ApiError)
    assert (read.code, read.message, read.op, read.request_id) == (code, text, op, request_id)
    assert read.extra == extra


@pytest.mark.parametrize(
    "obj",
    [
        [],
        {"ok": "yes"},
        {"ok": True},
        {"ok": True, "op": "status"},
        {"ok": True, "op": "commission", "key85": "1", "remote_status": True},
        {"ok": True, "op": "status", "state": "RUN", "mono_ns": 1.5},
        {"ok": False, "error": "no code"},
    ],
)
def test_a_reply_that_is_not_one_is_a_wire_error(obj: object) -> None:
    """A reply missing what docs/api.md says it has, or with the wrong type, is refused by
    name (``WireError``), not a ``KeyError`` or ``TypeError``."""
    with pytest.raises(WireError):
        read_reply(obj)


@pytest.mark.parametrize(
    "obj",
    [
        {"event": 1},
        {"event": "state", "state": "RUN"},
        {"event": "record", "seq": "1"},
        {"event": "joystick", "type": "gps"},
        {"event": "remote_status", "type": "remote_status", "battery_level": True},
        {"event": "gps", "type": "gps", "source": 1, "string": "x", "sentence_type": "GGA"},
    ],
)
def test_a_push_that_is_not_one_is_a_wire_error(obj: object) -> None:
    """The same for pushes."""
    with pytest.raises(WireError):
        read_push(obj)
