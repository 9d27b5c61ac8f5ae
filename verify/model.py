"""What the exploration feeds the core: the configs and the finite alphabet of inputs
(docs/verification.md "The model").

An input is a function of the time it arrives at. Every input is offered at the current
instant; at a boundary of a clock (one nanosecond before, at and after each constant it is
compared with) only the inputs whose handling can see that clock or the state it changes
(:data:`SEEN_BY`; docs/verification.md "The time model"), the others following at that
instant after a tick. Every input is printed as the Python that builds it, so a
counterexample is a test anyone can run (``verify.explore``).
"""

from __future__ import annotations

import dataclasses
import enum
from collections.abc import Callable, Mapping
from dataclasses import dataclass
from types import MappingProxyType
from typing import Final

from supervisord.protocol.codes import VscMode
from supervisord.protocol.messages import FeedbackSet, RemoteStatus, VscHeartbeat
from supervisord.safety import (
    Caller,
    ClientCommand,
    ClientConnected,
    ClientDisconnected,
    ClientEstop,
    ClientHeartbeat,
    ClientHello,
    ClientHold,
    ClientRelease,
    ClientSpec,
    Event,
    InternalFault,
    LinkClosed,
    LinkOpened,
    LocalEstop,
    LocalRelease,
    OutputReadback,
    OutputRole,
    OutputSpec,
    Request,
    ResetRequest,
    SafetyConfig,
    SafetyCore,
    Tick,
    Transport,
    VscReceived,
)
from supervisord.safety.availability import Reaction
from supervisord.safety.budget import RECORDS_OF_ALL_CLIENTS, RecordBudget
from supervisord.safety.config import FleetSpec
from supervisord.safety.events import FleetKeepalive, FleetRelease, FleetStop, ProofTestRequest
from supervisord.safety.prooftest import ProofTestPolicy

START_NS = 1_000_000_000_000
"""The core's start on the monotonic clock (any value: every clock is relative)."""

OPERATIONAL = VscMode.OPERATIONAL.value
LOCAL = VscMode.LOCAL.value
PAUSE = VscMode.PAUSE.value
SEARCHING = VscMode.SEARCHING.value
REMOTE_ESTOP = 0x01  # e-stop word: the remote's button (PR-2.6)
USER_ESTOP = 0x80  # e-stop word: the user bits, as the VSC's watchdog raises them (PR-2.6)

REQUIRED = "r"  # the required client, connection 1
OPTIONAL = "o"  # a client the config does not name, connection 2
REQUIRED_CONNECTION, OPTIONAL_CONNECTION = 1, 2
REQUIRED_UID, OPTIONAL_UID = 1001, 1002
ADMIN = Caller(uid=0, pid=1, name="root", admin=True)

_OUTPUTS = (OutputSpec("drive", OutputRole.MOTION), OutputSpec("lights", OutputRole.POWER))
_REQUIRED_SPEC = ClientSpec(REQUIRED, timeout_ms=500)
BRAKE_DELAY_MS = 150
"""The category-1 output's delay in the ``category1`` model (SR-1.4): three grid steps, so
that a stop from HOLD comes within it and after it, and no other constant of the model."""
_CATEGORY_1_OUTPUTS = (
    *_OUTPUTS,
    OutputSpec("brake", OutputRole.POWER, off_delay_ms=BRAKE_DELAY_MS),
)
BASE = SafetyConfig(
    transport=Transport.SERIAL,
    vsc_timeout_ms=200,
    heartbeat_hz=20,
    rearm_hold_ms=100,
    local_reset=True,
    require_watchdog=True,
    outputs=_OUTPUTS,
)
"""Serial, a motion and a power output, a local reset allowed, the VSC's watchdog required, the
shortest re-arm hold; the VSC's timeout at its default (docs/verification.md "Models")."""

SMALL = dataclasses.replace(
    BASE,
    clients=(_REQUIRED_SPEC,),
    prooftest=ProofTestPolicy.BLOCK,
    prooftest_clear_ms=1000,
)
"""Everything together: one required client (and one the config does not name), the proof
test blocking, its shortest wait for the bits to clear."""


@dataclass(frozen=True)
class Input:
    """One letter of the alphabet: ``build(now)`` is the event; ``kind`` says at which
    boundaries it is offered (:data:`SEEN_BY`)."""

    name: str
    build: Callable[[int], Event]
    kind: str
    connection: int | None = None  # a client's input: offered only while it is connected,
    connects: bool = False  # or, for its connection, only while it is not (the API's order)


TICK, VSC, BEAT, CLIENT, REARM, PROOF, KEY85_ANSWER, BATTERY, OTHER = (
    "tick",
    "vsc",
    "beat",
    "client",
    "rearm",
    "proof",
    "key85",
    "battery",
    "other",
)
TIMED = frozenset({TICK, VSC, BEAT, REARM, PROOF})
"""Inputs offered one grid step on directly, not only after a tick: their handling reads the
time or the state, which a tick at that instant could change first."""
GRID_NS = 50_000_000
"""The time grid the exploration continues on (docs/verification.md "The time model"): one VSC
heartbeat interval at the manual's 20 Hz, and the user heartbeat's period; every constant a
clock of the core is compared with is a whole number of grid steps but the 20 ms of the
takeover's rate."""
_STATE_READERS = frozenset({VSC, REARM, PROOF})  # handlers that read the state (a takeover, a
# reset, a proof test's request), so a tick before them at the same instant can change them
SEEN_BY: dict[str, frozenset[str]] = {
    # the VSC's silence changes the state; the next heartbeat reads its age
    "vsc": frozenset({TICK, BEAT}) | _STATE_READERS,
    # the takeover's run, the mode's hold and its settling, the refusal's quiet: heartbeats
    "run": frozenset({VSC}),
    "settling": frozenset({VSC}),
    "held_since": frozenset({VSC}),
    "quiet": frozenset({VSC}),
    "clear_since": frozenset({VSC, REARM}),
    # the required client's silence changes the state
    "client": frozenset({TICK, BEAT}) | _STATE_READERS,
    # what falls due by itself: a tick
    "key85": frozenset({TICK}),
    "heartbeat": frozenset({TICK}),
    "decision": frozenset({TICK}),
    "display": frozenset({TICK}),
    # the proof test: a tick for its limits, the VSC's heartbeats for the trip and the clearing
    "proof:heard": frozenset({TICK, KEY85_ANSWER}),
    "proof:withheld": frozenset({TICK, VSC}),
    "proof:resumed": frozenset({TICK, VSC}),
    "proof:sent": frozenset(),
    # the remote's battery report goes stale by itself; a new report restarts it (SR-8.12)
    "battery": frozenset({TICK, BATTERY}) | _STATE_READERS,
    # SR-8.21: the fleet console's silence changes the state; its next keepalive reads it
    "fleet": frozenset({TICK, BEAT}) | _STATE_READERS,
    # the record budget: the inputs it limits or charges, and a deferred end
    "budget": frozenset({TICK, BEAT, CLIENT, REARM, PROOF}),
    # SR-1.4: a stop from HOLD reads when the motion outputs went off; a category-1 output
    # goes off with time (every step computes the levels at its ``now``)
    "motion_off": frozenset({TICK, VSC, REARM}),
    "braking": frozenset({TICK, VSC}),
}
"""For each clock (by the start of its name), the kinds of input offered at its boundaries."""


def seen_by(name: str) -> frozenset[str]:
    """The kinds of input offered at the boundaries of the clock called ``name``."""
    for prefix, kinds in SEEN_BY.items():
        if name.startswith(prefix):
            return kinds
    raise KeyError(f"clock {name!r} is not in verify.model.SEEN_BY")


def _vsc(mode: int, word: int) -> Input:
    mode_name = VscMode(mode).name.lower()
    return Input(
        f"vsc {mode_name} {word:#04x}",
        lambda now: VscReceived(now, VscHeartbeat(mode, 0, word)),
        VSC,
    )


def client(name: str, connection: int, uid: int, beat: str = CLIENT) -> list[Input]:
    """A client's inputs on its connection: connect, hello, heartbeat, e-stop, hold, the two
    releases, its declarations of a non-zero and a zero command (SR-4.6) and its end; each
    only while connected, as the API server sends them."""
    return [
        Input(
            f"{name} connect",
            lambda now: ClientConnected(now, connection, uid),
            CLIENT,
            connection,
            connects=True,
        ),
        Input(f"{name} hello", lambda now: ClientHello(now, connection, name), CLIENT, connection),
        Input(f"{name} beat", lambda now: ClientHeartbeat(now, connection), beat, connection),
        Input(f"{name} estop", lambda now: ClientEstop(now, connection), CLIENT, connection),
        Input(f"{name} hold", lambda now: ClientHold(now, connection), CLIENT, connection),
        Input(
            f"{name} release estop",
            lambda now: ClientRelease(now, connection, Request.ESTOP),
            CLIENT,
            connection,
        ),
        Input(
            f"{name} release hold",
            lambda now: ClientRelease(now, connection, Request.HOLD),
            CLIENT,
            connection,
        ),
        Input(
            f"{name} command nonzero",
            lambda now: ClientCommand(now, connection, True),
            CLIENT,
            connection,
        ),
        Input(
            f"{name} command zero",
            lambda now: ClientCommand(now, connection, False),
            CLIENT,
            connection,
        ),
        Input(f"{name} bye", lambda now: ClientDisconnected(now, connection), CLIENT, connection),
    ]


def vsc(modes: tuple[int, ...], words: tuple[int, ...]) -> list[Input]:
    """The VSC's heartbeats: each mode with each e-stop word."""
    return [_vsc(mode, word) for mode in modes for word in words]


KEY85 = [
    Input("key85 1", lambda now: VscReceived(now, FeedbackSet(85, 1)), KEY85_ANSWER),
    Input("key85 0", lambda now: VscReceived(now, FeedbackSet(85, 0)), KEY85_ANSWER),
]
LINK = [
    Input("link open", LinkOpened, OTHER),
    Input("link close", lambda now: LinkClosed(now, "reopen"), OTHER),
]
LOCAL_COMMANDS = [
    Input("local estop", lambda now: LocalEstop(now, ADMIN), CLIENT),
    Input("local release", lambda now: LocalRelease(now, ADMIN), CLIENT),
    Input("reset", lambda now: ResetRequest(now, ADMIN), REARM),
]
PROOF_REQUEST = [Input("prooftest", lambda now: ProofTestRequest(now, ADMIN), PROOF)]
FAULTS = [
    Input("internal fault", lambda now: InternalFault(now, "overrun"), OTHER),
    Input("drive fails", lambda now: OutputReadback(now, "drive", True, None), OTHER),
    Input("drive reads back", lambda now: OutputReadback(now, "drive", False, False), OTHER),
]
TICKS = [Input("tick", Tick, TICK)]
BATTERY_REPORTS = [
    Input("battery 80", lambda now: VscReceived(now, RemoteStatus(80)), BATTERY),
    Input("battery 10", lambda now: VscReceived(now, RemoteStatus(10)), BATTERY),
    Input("battery 0", lambda now: VscReceived(now, RemoteStatus(0)), BATTERY),
]
"""The remote's battery above and below the minimum (20 %) of ``vsc.min_remote_battery``, and
a second level below it, whose reason renames the cause (SR-3.4)."""
BATTERY_GRID_NS = 500_000_000
"""The battery models' grid: 3.5 s, the age at which a report goes stale, is seven steps, and
the 1 s of good reports that ends its condition (SR-3.4) two."""
REQUIRED_CLIENT = client(REQUIRED, REQUIRED_CONNECTION, REQUIRED_UID, BEAT)
PROGRESS_VALUES = (0, 0x5555_5556, 0xAAAA_AAAB)
"""Three progress values a third of the 32-bit circle apart: each is ahead of the one before it
and 0 of the last (the wrap-around), each behind the one after it (a replay), SR-8.16."""


def _progress_beat(value: int) -> Input:
    return Input(
        f"{REQUIRED} beat {value:#x}",
        lambda now: ClientHeartbeat(now, REQUIRED_CONNECTION, value),
        BEAT,
        REQUIRED_CONNECTION,
    )


PROGRESS_BEATS = [_progress_beat(value) for value in PROGRESS_VALUES]
"""The required client's heartbeats with a progress value (SR-8.16)."""
OPTIONAL_CLIENT = client(OPTIONAL, OPTIONAL_CONNECTION, OPTIONAL_UID)
FLEET_CONNECTION, STRANGER_CONNECTION = 3, 4
FLEET_AGENT = Caller(uid=1003, pid=3, name="srcs-fleet", admin=False)
STRANGER = Caller(uid=OPTIONAL_UID, pid=4, name="o", admin=False)
FLEET_CONSOLE_MS = 200  # the shortest console_timeout_ms: four grid steps


def _fleet(kind: type[FleetStop | FleetRelease], stop_id: str) -> Input:
    """The agent's stop or release of ``stop_id`` (SR-8.19)."""
    word = "stop" if kind is FleetStop else "release"
    return Input(
        f"fleet {word} {stop_id}",
        lambda now: kind(now, FLEET_CONNECTION, FLEET_AGENT, stop_id, "console"),
        CLIENT,
    )


FLEET_INPUTS = [
    *[_fleet(kind, stop_id) for kind in (FleetStop, FleetRelease) for stop_id in ("s1", "s2")],
    Input(
        "fleet stop s3 by another user",
        lambda now: FleetStop(now, STRANGER_CONNECTION, STRANGER, "s3", "console"),
        CLIENT,
    ),
    Input(
        "fleet release s1 by another user",
        lambda now: FleetRelease(now, STRANGER_CONNECTION, STRANGER, "s1", "console"),
        CLIENT,
    ),
    Input(
        "fleet keepalive",
        lambda now: FleetKeepalive(now, FLEET_CONNECTION, FLEET_AGENT, "console"),
        BEAT,
    ),
    Input(
        "fleet keepalive by another user",
        lambda now: FleetKeepalive(now, STRANGER_CONNECTION, STRANGER, "console"),
        BEAT,
    ),
]
"""The fleet agent's stops (two ids, so that a repeat and a second stop of one console are
in reach), releases and keepalives, and the same from a user the config does not name
(SR-8.19 to SR-8.21)."""
ALL_MODES = (OPERATIONAL, LOCAL, PAUSE)
ALL_WORDS = (0, REMOTE_ESTOP, USER_ESTOP)


def alphabet() -> tuple[Input, ...]:
    """Every input of every model: each VSC mode with each e-stop word that matters (none,
    the remote's, the user bits), key 85's answers, the link, both clients, the local
    commands, the proof test's request, a fault, an output's read-back and a tick."""
    return (
        *vsc(ALL_MODES, ALL_WORDS),
        *KEY85,
        *LINK,
        *REQUIRED_CLIENT,
        *OPTIONAL_CLIENT,
        *LOCAL_COMMANDS,
        *PROOF_REQUEST,
        *FAULTS,
        *TICKS,
    )


def code(value: object, start: str = "START_NS") -> str:
    """``value`` (an event or anything in one) as the Python that builds it; times (the field
    ``now``) relative to ``start``."""
    if isinstance(value, enum.Enum):
        return f"{type(value).__name__}.{value.name}"
    if dataclasses.is_dataclass(value) and not isinstance(value, type):
        fields = []
        for field in dataclasses.fields(value):
            item = getattr(value, field.name)
            if field.name == "now" and isinstance(item, int):
                fields.append(f"{start} + {item - START_NS:_}")
            else:
                fields.append(code(item, start))
        return f"{type(value).__name__}({', '.join(fields)})"
    if isinstance(value, int) and not isinstance(value, bool) and abs(value) > 9:
        return f"{value:#x}" if 0 < value < 0x100 else f"{value:_}"
    return repr(value)


@dataclass(frozen=True)
class Model:
    """A config and the inputs explored with it. ``budget_limit`` is the records a user may
    cause per second in the explored core (the product's 20, ``RecordBudget``'s own
    parameter); ``None``: out of reach, and the budget's clocks are left out of the state."""

    name: str
    config: SafetyConfig
    inputs: tuple[Input, ...]
    budget_limit: int | None = None
    what: str = ""
    grid_ns: int = GRID_NS
    depth: int | None = None  # levels ``./dev verify`` explores; None: until no state is new

    def start(self, core_class: type[SafetyCore] = SafetyCore) -> SafetyCore:
        """The core at its start, with this model's record budget."""
        core = core_class(self.config, START_NS)
        limit = UNREACHABLE if self.budget_limit is None else self.budget_limit
        core._budget = RecordBudget(limit=limit, total=max(limit, RECORDS_OF_ALL_CLIENTS))
        core._compose()  # the view of its machines holds the new budget
        return core


UNREACHABLE = 1 << 40  # records a second: a budget no exploration exhausts


MODELS = {
    m.name: m
    for m in (
        Model(
            "takeover",
            dataclasses.replace(BASE, require_watchdog=False),
            (*vsc(ALL_MODES, (0,)), *LINK, *LOCAL_COMMANDS, *TICKS),
            what="takeovers, the mode's holds, the VSC's silence and the link",
        ),
        Model(
            "can",
            dataclasses.replace(BASE, transport=Transport.CAN, require_watchdog=False),
            (*vsc(ALL_MODES, (0, REMOTE_ESTOP)), *LINK, *LOCAL_COMMANDS, *TICKS),
            what="the same on CAN: no user heartbeat, so no deadline hides another",
        ),
        Model(
            "vsc",
            BASE,
            (
                *vsc(ALL_MODES, (0, REMOTE_ESTOP)),
                *KEY85,
                *LINK,
                *LOCAL_COMMANDS,
                FAULTS[0],
                *TICKS,
            ),
            what="the VSC, the link, key 85 and the local commands: takeovers, holds, silence",
        ),
        Model(
            "clients",
            dataclasses.replace(BASE, clients=(_REQUIRED_SPEC,), require_watchdog=False),
            (
                _vsc(OPERATIONAL, 0),
                LINK[0],
                *REQUIRED_CLIENT,
                *[i for i in OPTIONAL_CLIENT if "estop" not in i.name and "beat" not in i.name],
                LOCAL_COMMANDS[2],
                *TICKS,
            ),
            what="a required client and an optional one (holds: its e-stops are the required "
            "one's) against a VSC in Operational, re-armed by a local reset",
        ),
        Model(
            "progress",
            dataclasses.replace(BASE, clients=(_REQUIRED_SPEC,), require_watchdog=False),
            (
                _vsc(OPERATIONAL, 0),
                LINK[0],
                *[i for i in REQUIRED_CLIENT if i.name.split()[-1] in ("connect", "hello", "beat")],
                *PROGRESS_BEATS,
                REQUIRED_CLIENT[-1],
                LOCAL_COMMANDS[2],
                *TICKS,
            ),
            what="the required client's heartbeats with and without a progress value, new, "
            "repeated, replayed and wrapped around (SR-8.16), against a VSC in Operational, "
            "re-armed by a local reset",
        ),
        Model(
            "budget",
            dataclasses.replace(BASE, clients=(_REQUIRED_SPEC,), require_watchdog=False),
            (_vsc(OPERATIONAL, 0), LINK[0], *REQUIRED_CLIENT, *TICKS),
            budget_limit=2,
            what="the record budget at two records a second (the product's is 20), one user, "
            "to a bounded depth",
            depth=12,
        ),
        Model(
            "proof",
            dataclasses.replace(BASE, prooftest=ProofTestPolicy.BLOCK, prooftest_clear_ms=1000),
            (
                *vsc((OPERATIONAL, LOCAL), (0, USER_ESTOP)),
                KEY85[0],
                LINK[0],
                *PROOF_REQUEST,
                *LOCAL_COMMANDS,
                *TICKS,
            ),
            what="the proof test of the VSC's watchdog under block (the link opens once; key 85 "
            "answers 1 or never), to a bounded depth",
            depth=16,
        ),
        Model(
            "proof_clients",
            SMALL,
            (
                *vsc((LOCAL,), (0, USER_ESTOP)),
                KEY85[0],
                LINK[0],
                *[i for i in REQUIRED_CLIENT if i.name.split()[-1] in ("connect", "hello", "beat")],
                *TICKS,
            ),
            what="the proof test under block with the required client not there yet, coming and "
            "going silent (SR-8.15: the test runs without it, the byte 0 only meanwhile; the VSC "
            "in Local: no takeover, the proof model has those), to a bounded depth",
            depth=12,
        ),
        Model(
            "battery_hold",
            dataclasses.replace(
                BASE,
                vsc_timeout_ms=1000,
                require_watchdog=False,
                on_estop_unavailable=Reaction.HOLD,
            ),
            (*vsc((OPERATIONAL, LOCAL), (0,)), LINK[0], *BATTERY_REPORTS, *TICKS),
            what="the remote's battery under on_estop_unavailable = 'hold': reports above and "
            "below the minimum, and none for 3 s or more (on a grid of 500 ms, so that 3 s is "
            "within reach; the VSC's timeout at its longest to keep a takeover possible on it)",
            grid_ns=BATTERY_GRID_NS,
        ),
        Model(
            "battery_stop",
            dataclasses.replace(
                BASE,
                transport=Transport.CAN,
                vsc_timeout_ms=1000,
                require_watchdog=False,
                on_estop_unavailable=Reaction.STOP,
            ),
            (*vsc((OPERATIONAL, LOCAL), (0,)), LINK[0], *BATTERY_REPORTS, *TICKS),
            what="the same under 'stop', on CAN: no user heartbeat hides the report's deadline",
            grid_ns=BATTERY_GRID_NS,
        ),
        Model(
            "category1",
            dataclasses.replace(
                BASE,
                transport=Transport.CAN,
                require_watchdog=False,
                outputs=_CATEGORY_1_OUTPUTS,
            ),
            (*vsc((OPERATIONAL, PAUSE), (0, REMOTE_ESTOP)), LINK[0], LOCAL_COMMANDS[2], *TICKS),
            what="a category-1 power output beside the motion and the category-0 power output "
            "(SR-1.4), on CAN: the VSC's holds and e-stops from RUN and HOLD, within the brake's "
            "delay and after it; the reflex of each (SR-9.5)",
        ),
        Model(
            "fleet",
            dataclasses.replace(
                BASE,
                transport=Transport.CAN,
                require_watchdog=False,
                fleet=FleetSpec(frozenset({FLEET_AGENT.uid}), True, FLEET_CONSOLE_MS),
            ),
            (*vsc((OPERATIONAL, LOCAL), (0,)), LINK[0], LOCAL_COMMANDS[2], *FLEET_INPUTS, *TICKS),
            what="the fleet's stops, releases and the required console's keepalive (SR-8.19, "
            "SR-8.21), from the agent and from another user, against takeovers and a reset, on "
            "CAN: no user heartbeat hides the console's deadline",
        ),
        Model(
            "all",
            SMALL,
            alphabet(),
            budget_limit=2,
            what="every input together, to a bounded depth",
            depth=5,
        ),
    )
}


BOUNDED: Final[Mapping[str, int]] = MappingProxyType(
    {
        "takeover": 7,
        "can": 6,
        "vsc": 5,
        "clients": 6,
        "progress": 8,
        "budget": 6,
        "proof": 6,
        "proof_clients": 6,
        "battery_hold": 14,
        "battery_stop": 19,
        "category1": 9,
        "fleet": 6,
        "all": 3,
    }
)
"""Breadth-first levels explored per model in the bounded run (``tests/safety/
test_exploration.py``, ``verify.explore --bounded``; ``./dev verify``: no bound)."""
