"""What the client API's server sends (SR-8, ``docs/api.md``): the daemon's values as the
typed replies and pushes of :mod:`.replies`, :mod:`.pushes` and :mod:`.status`; sans-IO.

Replies answer a request (:func:`ok_reply`, :func:`refusal_error`); pushes carry safety
decisions, stop records and VSC messages to subscribers. The causes in ``status`` and ``state``
are the stop record's own cause objects (:func:`supervisord.record.format.cause_report`), so a
client reads both the same way; a stop record is pushed as the typed record the daemon made
(:class:`~supervisord.api.pushes.RecordPush`). The wire's JSON is each type's one encoder.

Nothing here touches a socket or a clock.
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import Final

from supervisord.api.framing import ApiError, ErrorCode
from supervisord.api.messages import (
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
    RemoteStatusPush,
    StatePush,
)
from supervisord.api.replies import OkReply
from supervisord.api.requests import ApiRequest, Topic
from supervisord.api.status import HistogramStatus, RearmStatus, RemoteReport, StateReport
from supervisord.histogram import Histogram
from supervisord.protocol.messages import (
    Axis,
    DPad,
    Gps,
    Joystick,
    Message,
    NumberedButtons,
    RemoteStatus,
)
from supervisord.record.format import cause_report, proof_status
from supervisord.safety.causes import Severity
from supervisord.safety.decision import Decision, Refusal, RefusalReason
from supervisord.timebase import NS_PER_MS, seconds_since

# -- replies -------------------------------------------------------------------------------


def ok_reply(request: ApiRequest) -> OkReply:
    """The success reply to ``request`` that says nothing more."""
    return OkReply(request.OP, request.id)


_HELLO_CODES: Final[Mapping[RefusalReason, ErrorCode]] = {
    RefusalReason.ALREADY_NAMED: ErrorCode.ALREADY_NAMED,
    RefusalReason.NAME_IN_USE: ErrorCode.NAME_IN_USE,
    RefusalReason.WRONG_USER: ErrorCode.NOT_ALLOWED,
    RefusalReason.NOT_FLEET_AGENT: ErrorCode.NOT_ALLOWED,  # SR-8.19
}
"""The core's refusals that have codes of their own (docs/api.md "hello", "fleet_stop")."""


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


def rearm_status(decision: Decision, now: int, hold_ms: int) -> RearmStatus:
    """What a re-arm waits for at ``now`` after ``decision`` (docs/api.md "status", SR-4.1):
    the core's own rule, read from its causes: every stop condition clear, and the latest
    clearing of a latched one at least ``hold_ms`` ago. ``accepted_in_s`` is rounded up to the
    millisecond, so that waiting that long is always enough."""
    causes = decision.causes
    if any(c.active and c.cause.severity is Severity.STOP for c in causes):
        return RearmStatus(hold_ms=hold_ms, clear_for_s=None, accepted_in_s=None)
    cleared = [c.cleared_ns for c in causes if c.latched and c.cleared_ns is not None]
    if not cleared:
        return RearmStatus(hold_ms=hold_ms, clear_for_s=None, accepted_in_s=0.0)
    clear_for = max(0, now - max(cleared))
    left_ns = max(0, hold_ms * NS_PER_MS - clear_for)
    return RearmStatus(
        hold_ms=hold_ms,
        clear_for_s=seconds_since(now, max(cleared)),
        accepted_in_s=-(-left_ns // NS_PER_MS) / 1000,
    )


def state_report(decision: Decision) -> StateReport:
    """The state of the supervisor after one decision, for ``status`` and ``state`` pushes."""
    return StateReport(
        state=decision.state,
        mono_ns=decision.now,
        causes=tuple(cause_report(c) for c in decision.causes),
        outputs=dict(sorted(decision.outputs.items())),
        heartbeat_estop=decision.heartbeat_estop,
        prooftest=None if decision.prooftest is None else proof_status(decision.prooftest),
    )


def histogram_status(histogram: Histogram) -> HistogramStatus:
    """One of ``status``'s ``histograms`` (docs/api.md, docs/fleet.md): the buckets' upper
    bounds in seconds (``le``), the cumulative count at each (``counts``; the ``+Inf`` bucket
    is ``count``), the ``sum`` in seconds and the ``count``, all since the daemon started."""
    snapshot = histogram.snapshot()
    return HistogramStatus(
        le=tuple(snapshot.le),
        counts=tuple(snapshot.counts),
        sum=round(snapshot.sum, 9),
        count=snapshot.count,
    )


def remote_report(message: RemoteStatus, age_s: float | None) -> RemoteReport:
    """``status``'s ``daemon.remote``: the last remote status and its age."""
    return RemoteReport(
        battery_level=message.battery_level,
        battery_charging=message.battery_charging,
        connection_strength_vsc=message.connection_strength_vsc,
        connection_strength_src=message.connection_strength_src,
        rssi_vsc=message.rssi_vsc,
        rssi_src=message.rssi_src,
        age_s=age_s,
    )


# -- pushes --------------------------------------------------------------------------------


def state_push(decision: Decision) -> StatePush:
    """The ``state`` push for a decision."""
    return StatePush(state_report(decision))


MESSAGE_TOPICS: Final[Mapping[type, Topic]] = {
    Joystick: Topic.JOYSTICK,
    Gps: Topic.GPS,
    RemoteStatus: Topic.REMOTE_STATUS,
}


def message_topic(message: Message) -> Topic | None:
    """The topic a VSC message is pushed under, or ``None`` for messages that are not pushed."""
    return MESSAGE_TOPICS.get(type(message))


def message_push(
    message: Joystick | Gps | RemoteStatus,
) -> JoystickPush | GpsPush | RemoteStatusPush:
    """The push for a joystick, GPS or remote-status message: its ``srcsctl decode`` JSON
    (``docs/protocol.md``) under ``event``."""
    if isinstance(message, Joystick):
        return JoystickPush(joystick_report(message))
    if isinstance(message, Gps):
        return GpsPush(gps_report(message))
    return RemoteStatusPush(
        RemoteStatusReport(
            battery_level=message.battery_level,
            battery_charging=message.battery_charging,
            connection_strength_vsc=message.connection_strength_vsc,
            connection_strength_src=message.connection_strength_src,
            rssi_vsc=message.rssi_vsc,
            rssi_src=message.rssi_src,
        )
    )


def _axis(axis: Axis) -> AxisReport:
    return AxisReport(
        value=axis.value,
        magnitude=axis.magnitude,
        neutral_status=int(axis.neutral),
        negative_status=int(axis.negative),
        positive_status=int(axis.positive),
    )


def _buttons(buttons: DPad | NumberedButtons) -> ButtonsReport:
    names = tuple(buttons.__dataclass_fields__)
    return ButtonsReport(
        byte=buttons.to_byte(),
        statuses=tuple((name, int(getattr(buttons, name))) for name in names),
        pressed=tuple(name for name in names if name in buttons.pressed),
    )


def joystick_report(message: Joystick) -> JoystickReport:
    return JoystickReport(
        left_x=_axis(message.left_x),
        left_y=_axis(message.left_y),
        left_z=_axis(message.left_z),
        right_x=_axis(message.right_x),
        right_y=_axis(message.right_y),
        right_z=_axis(message.right_z),
        left_buttons=_buttons(message.left_buttons),
        right_buttons=_buttons(message.right_buttons),
    )


def gps_report(message: Gps) -> GpsReport:
    fix = message.fix
    return GpsReport(
        source=message.source,
        string=message.sentence,
        fix=None
        if fix is None
        else GpsFixReport(
            sentence_type=fix.sentence_type,
            utc_time=fix.utc_time.isoformat() if fix.utc_time else None,
            latitude=fix.latitude,
            longitude=fix.longitude,
            fix_quality=fix.fix_quality,
            valid=fix.valid,
        ),
    )
