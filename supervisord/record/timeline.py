"""A stop's window as signals on one time axis: what the MCAP export writes and the stop's picture
draws (SR-7.15; ``docs/record.md`` "Looking at a stop").

One :class:`Signal` per thing a person looks at: the VSC's heartbeats (mode, each e-stop source),
the link, the remote's sticks and buttons, its battery and link, each client's heartbeats and
requests (its holds among them), the operator's commands, the core's state and causes, each
record the replay made, the proof test's phase, each output's commanded level and its
read-back, each user heartbeat sent. The inputs come from the window, the rest from the replay
of it (:mod:`supervisord.record.replay`): the decisions are the core's own, made again.

Times are the window's monotonic stamps (``mono_ns``, the clock every deadline is measured on);
:meth:`Timeline.utc_ns` maps one to the wall clock by the stop record's ``utc``: the stop's
``mono_ns`` is its ``utc``, and every other moment is as far from it as on the monotonic clock
(the daemon stamps ``utc`` when it writes the record, so the mapping is off by that delay, a
few milliseconds, and the same for every moment).

Pure: no I/O; the callers write the file.
"""

from __future__ import annotations

import dataclasses
import datetime as dt
from collections.abc import Mapping
from typing import Any, Final

from supervisord.protocol.codes import EstopSource, estop_sources
from supervisord.protocol.jsonview import message_json
from supervisord.protocol.messages import (
    Joystick,
    Message,
    RemoteStatus,
    UserHeartbeat,
    VscHeartbeat,
)
from supervisord.record.flight import LoadedWindow
from supervisord.record.flight_codec import caller_to_json
from supervisord.record.flight_times import parse_utc, utc_ns
from supervisord.record.replay import Replay, ReplayError, Step, differing, start_core
from supervisord.safety.events import (
    ClientCommand,
    ClientConnected,
    ClientDisconnected,
    ClientEstop,
    ClientHeartbeat,
    ClientHello,
    ClientHold,
    ClientRelease,
    Commissioned,
    Event,
    LinkBroken,
    LinkClosed,
    LinkOpened,
    LocalEstop,
    LocalRelease,
    OutputReadback,
    ProofTestRequest,
    ResetRequest,
    StopTested,
    Tick,
    VscReceived,
)

Json = Any

_MONO: Final = {"type": "integer", "description": "the daemon's monotonic clock, ns"}
_FROM_STOP: Final = {"type": "number", "description": "seconds from the stop (negative: before)"}
_INT_OR_NULL: Final = {"type": ["integer", "null"]}
_TEXTS: Final = {"type": "array", "items": {"type": "string"}}


def _schema(title: str, properties: Mapping[str, Json]) -> dict[str, Json]:
    """A JSON Schema of one channel's messages: every message has its ``mono_ns`` and
    ``from_stop_s`` besides ``properties``, all required."""
    fields = {"mono_ns": _MONO, "from_stop_s": _FROM_STOP, **properties}
    return {
        "$schema": "https://json-schema.org/draft/2020-12/schema",
        "title": title,
        "type": "object",
        "properties": fields,
        "required": sorted(fields),
    }


VSC_HEARTBEAT: Final = _schema(
    "srcs.VscHeartbeat",
    {
        "vsc_mode": {"type": "integer"},
        "vsc_mode_name": {"type": "string"},
        "autonomy_mode": {"type": "integer"},
        "e_stop_word": {"type": "integer", "description": "the heartbeat's e-stop indication"},
        "e_stop_remote": {"type": "boolean", "description": "bits 0-1"},
        "e_stop_wired": {"type": "boolean", "description": "bits 2-3"},
        "e_stop_user": {"type": "boolean", "description": "bits 6-7"},
        "e_stop_unknown": {"type": "boolean", "description": "any other bit"},
    },
)
LINK: Final = _schema(
    "srcs.Link",
    {"event": {"enum": ["opened", "broken", "closed"]}, "reason": {"type": "string"}},
)
VSC_MESSAGE: Final = _schema(
    "srcs.VscMessage",
    {"type": {"type": "string"}, "message": {"type": "object", "description": "as srcsctl decode"}},
)
STICKS: Final = _schema(
    "srcs.RemoteSticks",
    {
        **{
            name: {**_INT_OR_NULL, "description": "deflection; null: invalid"}
            for name in Joystick.AXES
        },
        "left_buttons": _TEXTS,
        "right_buttons": _TEXTS,
    },
)
REMOTE_STATUS: Final = _schema(
    "srcs.RemoteStatus",
    {
        name: {"type": "integer"}
        for name in (
            "battery_level",
            "battery_charging",
            "connection_strength_vsc",
            "connection_strength_src",
            "rssi_vsc",
            "rssi_src",
        )
    },
)
CLIENT_HEARTBEAT: Final = _schema(
    "srcs.ClientHeartbeat",
    {
        "connection": {"type": "integer"},
        "progress": _INT_OR_NULL,
        "accepted": {"type": "boolean", "description": "false: refused, it kept no deadline"},
        "refusal": {"type": ["string", "null"]},
        "timeout_ms": _INT_OR_NULL,
    },
)
CLIENT_REQUEST: Final = _schema(
    "srcs.ClientRequest",
    {
        "connection": {"type": "integer"},
        "request": {
            "enum": [
                "connected",
                "hello",
                "estop",
                "hold",
                "release",
                "command",
                "disconnected",
            ]
        },
        "detail": {"type": "string"},
        "accepted": {"type": "boolean"},
        "refusal": {"type": ["string", "null"]},
    },
)
OPERATOR: Final = _schema(
    "srcs.OperatorCommand",
    {
        "command": {"type": "string", "description": "the input's name, as a record's trigger"},
        "caller": {"type": "object"},
        "accepted": {"type": "boolean"},
        "refusal": {"type": ["string", "null"]},
    },
)
OTHER_INPUT: Final = _schema(
    "srcs.OtherInput",
    {"event": {"type": "string"}, "fields": {"type": "object"}},
)
STATE: Final = _schema(
    "srcs.CoreState",
    {
        "state": {"enum": ["STOPPED", "HOLD", "RUN"]},
        "causes": _TEXTS,
        "active": _TEXTS,
        "latched": _TEXTS,
    },
)
RECORD: Final = _schema(
    "srcs.Record",
    {
        "record": {"type": "object", "description": "the record the replay made"},
        "verdict": {"enum": ["as recorded", "differs", "not in the record files"]},
    },
)
PROOFTEST: Final = _schema(
    "srcs.ProofTest",
    {"phase": {"enum": ["waiting", "withholding", "resumed", "passed", "failed", "off"]}},
)
COMMANDED: Final = _schema("srcs.OutputCommanded", {"on": {"type": "boolean"}})
READ_BACK: Final = _schema(
    "srcs.OutputReadBack",
    {"requested": {"type": "boolean"}, "read_back": {"type": ["boolean", "null"]}},
)
USER_HEARTBEAT: Final = _schema("srcs.UserHeartbeat", {"e_stop_indication": {"type": "integer"}})


@dataclasses.dataclass(frozen=True)
class Sample:
    """One message of a signal: when (``mono_ns``) and what (the JSON object, which holds
    ``mono_ns`` and ``from_stop_s`` too)."""

    mono_ns: int
    value: Mapping[str, Json]


@dataclasses.dataclass
class Signal:
    """One channel: its topic (``/vsc/heartbeat``), its messages' JSON Schema, its samples in
    time order."""

    topic: str
    schema: Mapping[str, Json]
    samples: list[Sample] = dataclasses.field(default_factory=list)


@dataclasses.dataclass
class Timeline:
    """The window's signals, the stop record, the replay's verdict and where the window starts
    and stops on the monotonic clock."""

    window: LoadedWindow
    start_ns: int
    stop_ns: int
    stop_utc: dt.datetime | None
    matches: bool
    signals: dict[str, Signal] = dataclasses.field(default_factory=dict)

    @property
    def seq(self) -> int:
        return self.window.seq

    @property
    def stop(self) -> Mapping[str, Json]:
        return self.window.stop

    def utc_ns(self, mono_ns: int) -> int:
        """The wall-clock time (ns since the epoch) of a moment on the monotonic clock, by the
        stop record's ``utc``; with no readable ``utc``, the monotonic time itself."""
        return utc_ns(self.stop_utc, self.stop_ns, mono_ns)

    def signal(self, topic: str, schema: Mapping[str, Json]) -> Signal:
        if topic not in self.signals:
            self.signals[topic] = Signal(topic, schema)
        return self.signals[topic]

    def add(self, topic: str, schema: Mapping[str, Json], mono_ns: int, **value: Json) -> None:
        from_stop = round((mono_ns - self.stop_ns) / 1e9, 9)
        self.signal(topic, schema).samples.append(
            Sample(mono_ns, {"mono_ns": mono_ns, "from_stop_s": from_stop, **value})
        )

    def cause_names(self) -> list[str]:
        """The stop record's causes, by name."""
        causes = self.stop.get("causes")
        if not isinstance(causes, list):
            return []
        return [str(c.get("name")) for c in causes if isinstance(c, dict) and "name" in c]


def _known_connections(window: LoadedWindow) -> dict[int, str]:
    """The clients named before the window started (a snapshot base's core holds them)."""
    if window.base.get("kind") != "snapshot":
        return {}
    try:
        core, _ = start_core(window)
        facts, _clocks = core.canonical()
    except (ReplayError, RecursionError, ValueError, TypeError, AttributeError):
        return {}
    for fact in facts:
        if isinstance(fact, tuple) and len(fact) == 2 and fact[0] == "connections":
            pairs = fact[1]
            if isinstance(pairs, tuple):
                return {
                    number: name
                    for number, name in (p for p in pairs if isinstance(p, tuple) and len(p) == 2)
                    if isinstance(number, int) and isinstance(name, str)
                }
    return {}


def _refusal(step: Step) -> str | None:
    for refusal in step.decision.refusals:
        if refusal.trigger is step.event:
            return refusal.message
    return None


_CLIENT_REQUESTS: Final[Mapping[type, str]] = {
    ClientConnected: "connected",
    ClientHello: "hello",
    ClientEstop: "estop",
    ClientHold: "hold",
    ClientRelease: "release",
    ClientCommand: "command",
    ClientDisconnected: "disconnected",
}
_OPERATOR: Final[Mapping[type, str]] = {
    LocalEstop: "local_estop",
    LocalRelease: "local_release",
    ResetRequest: "reset_request",
    Commissioned: "commissioned",
    ProofTestRequest: "proof_test_request",
    StopTested: "stop_tested",
}


class _Builder:
    def __init__(self, timeline: Timeline) -> None:
        self.t = timeline
        self.names = _known_connections(timeline.window)
        self.timeouts = {c.name: c.timeout_ms for c in timeline.window.config.clients}
        self.state: tuple[Json, ...] | None = None
        self.levels: dict[str, bool] = {}
        self.phase: str | None = None

    def client(self, connection: int) -> str:
        return self.names.get(connection, f"connection-{connection}")

    def step(self, step: Step) -> None:
        decision, now = step.decision, step.decision.now
        if step.event is not None:
            self.input(step, step.event)
        for frame in decision.frames:
            if isinstance(frame, UserHeartbeat):
                self.t.add(
                    "/vsc/user_heartbeat", USER_HEARTBEAT, now, e_stop_indication=frame.estop
                )
        causes = sorted(c.name for c in decision.causes)
        active = sorted(decision.active_names)
        latched = sorted(decision.latched_names)
        state = (decision.state.name, causes, active, latched)
        if state != self.state:
            self.state = state
            self.t.add(
                "/core/state",
                STATE,
                now,
                state=decision.state.name,
                causes=causes,
                active=active,
                latched=latched,
            )
        for replayed, recorded in step.records:
            verdict = "not in the record files"
            if recorded is not None:
                verdict = "differs" if differing(recorded, replayed) else "as recorded"
            self.t.add("/core/record", RECORD, now, record=dict(replayed), verdict=verdict)
        if decision.prooftest is not None and decision.prooftest.phase.value != self.phase:
            self.phase = decision.prooftest.phase.value
            self.t.add("/core/prooftest", PROOFTEST, now, phase=self.phase)
        for name, on in decision.outputs.items():
            if self.levels.get(name) is not on:
                self.levels[name] = on
                self.t.add(f"/output/{name}/commanded", COMMANDED, now, on=on)

    def input(self, step: Step, event: Event) -> None:
        now = event.now
        match event:
            case Tick():
                return  # time passing: its effects are the decision's
            case VscReceived(message=message):
                self.vsc(message, now)
            case LinkOpened():
                self.t.add("/vsc/link", LINK, now, event="opened", reason="")
            case LinkBroken(reason=reason):
                self.t.add("/vsc/link", LINK, now, event="broken", reason=reason)
            case LinkClosed(reason=reason):
                self.t.add("/vsc/link", LINK, now, event="closed", reason=reason)
            case ClientHeartbeat(connection=connection, progress=progress):
                name, refusal = self.client(connection), _refusal(step)
                self.t.add(
                    f"/client/{name}/heartbeat",
                    CLIENT_HEARTBEAT,
                    now,
                    connection=connection,
                    progress=progress,
                    accepted=refusal is None,
                    refusal=refusal,
                    timeout_ms=self.timeouts.get(name),
                )
            case OutputReadback(output=output, requested=requested, read_back=read_back):
                self.t.add(
                    f"/output/{output}/read_back",
                    READ_BACK,
                    now,
                    requested=requested,
                    read_back=read_back,
                )
            case _ if type(event) in _CLIENT_REQUESTS:
                self.client_request(step, event)
            case _ if type(event) in _OPERATOR:
                caller = getattr(event, "caller", None)
                refusal = _refusal(step)
                self.t.add(
                    "/operator/command",
                    OPERATOR,
                    now,
                    command=_OPERATOR[type(event)],
                    caller={} if caller is None else caller_to_json(caller),
                    accepted=refusal is None,
                    refusal=refusal,
                )
            case _:
                fields = {
                    key: str(getattr(event, key))
                    for key in getattr(event, "__dataclass_fields__", {})
                    if key != "now"
                }
                self.t.add(
                    "/input/other",
                    OTHER_INPUT,
                    now,
                    event=type(event).__name__,
                    fields=fields,
                )

    def vsc(self, message: Message, now: int) -> None:
        if isinstance(message, VscHeartbeat):
            beat = message
            sources = estop_sources(beat.estop)
            self.t.add(
                "/vsc/heartbeat",
                VSC_HEARTBEAT,
                now,
                vsc_mode=beat.mode,
                vsc_mode_name=message_json(beat)["vsc_mode_name"],
                autonomy_mode=beat.autonomy_mode,
                e_stop_word=beat.estop,
                e_stop_remote=EstopSource.REMOTE in sources,
                e_stop_wired=EstopSource.WIRED in sources,
                e_stop_user=EstopSource.USER in sources,
                e_stop_unknown=EstopSource.UNKNOWN in sources,
            )
        elif isinstance(message, Joystick):
            sticks = message
            self.t.add(
                "/remote/sticks",
                STICKS,
                now,
                **{name: getattr(sticks, name).value for name in Joystick.AXES},
                left_buttons=sorted(sticks.left_buttons.pressed),
                right_buttons=sorted(sticks.right_buttons.pressed),
            )
        elif isinstance(message, RemoteStatus):
            status = message
            view = message_json(status)
            view.pop("type")
            self.t.add("/remote/status", REMOTE_STATUS, now, **view)
        else:
            view = message_json(message)
            self.t.add("/vsc/message", VSC_MESSAGE, now, type=view["type"], message=view)

    def client_request(self, step: Step, event: Event) -> None:
        connection = getattr(event, "connection", 0)
        refusal = _refusal(step)
        detail = ""
        if isinstance(event, ClientHello):
            detail = event.name
            if refusal is None:
                self.names[connection] = event.name
        elif isinstance(event, ClientRelease):
            detail = event.request.value
        elif isinstance(event, ClientCommand):
            detail = "nonzero" if event.nonzero else "zero"
        self.t.add(
            f"/client/{self.client(connection)}/request",
            CLIENT_REQUEST,
            event.now,
            connection=connection,
            request=_CLIENT_REQUESTS[type(event)],
            detail=detail,
            accepted=refusal is None,
            refusal=refusal,
        )
        if isinstance(event, ClientDisconnected):
            self.names.pop(connection, None)


def timeline(window: LoadedWindow, result: Replay) -> Timeline:
    """The window's inputs and the replay's decisions as signals (SR-7.15)."""
    stop_ns = window.stop.get("mono_ns")
    last = window.inputs[-1].now if window.inputs else 0
    stop_ns = stop_ns if isinstance(stop_ns, int) and not isinstance(stop_ns, bool) else last
    base = window.base.get("now_ns")
    first = window.inputs[0].now if window.inputs else stop_ns
    start_ns = min(base if isinstance(base, int) else first, first)
    made = Timeline(window, start_ns, stop_ns, parse_utc(window.stop.get("utc")), result.matches)
    builder = _Builder(made)
    for step in result.steps:
        builder.step(step)
    return made
