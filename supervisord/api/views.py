"""What the client API's server sends (SR-8, ``docs/api.md``): replies and pushes; sans-IO.

Replies answer a request (:func:`ok_reply`, :func:`refusal_error`); pushes carry safety
decisions, stop records and VSC messages to subscribers. The causes in ``status`` and ``state``
are the stop record's own cause objects (:func:`supervisord.record.format.cause_json`), so a
client reads both the same way.

Nothing here touches a socket or a clock.
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import Final

from supervisord.api.framing import ApiError, ErrorCode, JsonDict
from supervisord.api.requests import ApiRequest, Topic
from supervisord.histogram import Histogram
from supervisord.protocol.jsonview import message_json
from supervisord.protocol.messages import Gps, Joystick, Message, RemoteStatus
from supervisord.record.format import cause_json
from supervisord.safety.decision import Decision, Refusal, RefusalReason

# -- replies -------------------------------------------------------------------------------


def ok_reply(request: ApiRequest, **fields: object) -> JsonDict:
    """The success reply to ``request``, with extra ``fields``."""
    reply: JsonDict = {"ok": True, "op": request.OP}
    if request.id is not None:
        reply["id"] = request.id
    reply.update(fields)
    return reply


_HELLO_CODES: Final[Mapping[RefusalReason, ErrorCode]] = {
    RefusalReason.ALREADY_NAMED: ErrorCode.ALREADY_NAMED,
    RefusalReason.NAME_IN_USE: ErrorCode.NAME_IN_USE,
    RefusalReason.WRONG_USER: ErrorCode.NOT_ALLOWED,
}
"""The core's refusals of a ``hello`` that have codes of their own (docs/api.md "hello")."""


def refusal_error(request: ApiRequest, refusal: Refusal) -> ApiError:
    """The error for a request the safety core declined: a refused ``hello`` by its own code
    (``already_named``, ``name_in_use``, ``not_allowed``), any other refusal as ``refused``
    with ``reason``, the refusal's stable name in lower case (e.g. ``conditions_active``)."""
    code = _HELLO_CODES.get(refusal.reason)
    if code is not None:
        return ApiError(code, refusal.message, op=request.OP, request_id=request.id)
    return ApiError(
        ErrorCode.REFUSED,
        refusal.message,
        op=request.OP,
        request_id=request.id,
        extra={"reason": refusal.reason.name.lower()},
    )


# -- the state of the supervisor -----------------------------------------------------------


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


def histograms_json(histograms: Mapping[str, Histogram]) -> JsonDict:
    """The ``histograms`` of ``status``'s ``daemon`` object (docs/api.md, docs/fleet.md):
    for each, the buckets' upper bounds in seconds (``le``), the cumulative count at each
    (``counts``; the ``+Inf`` bucket is ``count``), the ``sum`` in seconds and the ``count``,
    all since the daemon started."""
    out: JsonDict = {}
    for name, histogram in histograms.items():
        snapshot = histogram.snapshot()
        out[name] = {
            "le": list(snapshot.le),
            "counts": list(snapshot.counts),
            "sum": round(snapshot.sum, 9),
            "count": snapshot.count,
        }
    return out


# -- pushes --------------------------------------------------------------------------------


def state_push(decision: Decision) -> JsonDict:
    """The ``state`` push for a decision."""
    return {"event": Topic.STATE.event, **decision_json(decision)}


def record_push(record: Mapping[str, object]) -> JsonDict:
    """The ``record`` push for a record as written to the store
    (:func:`supervisord.record.format.record_json`)."""
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
