"""The properties the exploration checks in every state it reaches and every step it takes
(docs/verification.md "Properties"), each tied to the requirements it proves.

The checker keeps a *ghost* of its own: what it has seen of the inputs (the link, the VSC's
heartbeats and the run before a takeover, key 85, the required client, the e-stops asked for,
the proof test's passes), computed from the inputs and the decisions' records, never from the
core's private facts, with the rules' numbers written here again from the requirements. So a
core that forgets a fact, or a constant that drifts, disagrees with the ghost. Only P8 (the
deadline) also reads the core's own timers, since the deadline is a promise about them.
"""

from __future__ import annotations

from collections.abc import Callable, Iterator, Sequence
from dataclasses import dataclass, field, fields, replace
from typing import Any

from supervisord.protocol.codes import VscMode
from supervisord.protocol.messages import (
    FeedbackGet,
    FeedbackSet,
    RemoteStatus,
    UserHeartbeat,
    VscHeartbeat,
)
from supervisord.safety import (
    ClientCommand,
    ClientConnected,
    ClientDisconnected,
    ClientEstop,
    ClientHeartbeat,
    ClientHello,
    ClientRelease,
    Decision,
    Event,
    InternalFault,
    LinkBroken,
    LinkClosed,
    LinkOpened,
    LocalEstop,
    LocalRelease,
    OutputRole,
    Request,
    ResetRequest,
    SafetyConfig,
    SafetyCore,
    State,
    Transport,
    VscReceived,
)
from supervisord.safety.availability import Reaction
from supervisord.safety.canonical import Canonical, Clock, clock
from supervisord.safety.decision import ChangeKind, RefusalReason
from supervisord.safety.events import FleetKeepalive, FleetRelease, FleetStop, ProofTestRequest
from supervisord.safety.prooftest import (
    KEY85_WAIT_NS,
    WITHHOLD_LIMIT_NS,
    Phase,
    ProofTestPolicy,
)
from supervisord.safety.reflex import Reflex
from verify.clone import clone
from verify.model import MODELS

MS = 1_000_000
DWELL_NS = 200 * MS  # SR-4.5: the non-Operational run spans at least 200 ms
MIN_HEARTBEATS = 3  # SR-4.5: and holds at least three heartbeats
FASTEST_NS = 20 * MS  # SR-4.5: at no more than one heartbeat per 20 ms (manual §8.3.6)
BATTERY_FRESH_NS = 3_500 * MS  # SR-8.12: a battery report 3.5 s old is no report
BATTERY_SETTLE_NS = 1_000 * MS  # SR-3.4: a second of good reports ends the battery's condition
READ_TOGETHER = 2  # docs/safety.md rule 4: plus two frames read in one loop turn
RATE_SLACK_NS = 60 * MS  # where the ghost clips its rate clock, as the core's canonical form
OPERATIONAL = VscMode.OPERATIONAL.value
HOLDS = frozenset({"vsc_mode", "client_hold", "estop_unavailable_hold"})  # SR-3, SR-8.12
BATTERY = frozenset({"estop_unavailable", "estop_unavailable_hold"})  # SR-8.12
OURS = frozenset(  # SR-5.2, docs/safety.md choice 6: the stops that set the heartbeat's byte
    {
        "vsc_link_lost",
        "transport_fault",
        "client_lost",
        "client_estop",
        "local_estop",
        "output_fault",
        "vsc_watchdog_off",
        "internal",
        "estop_unavailable",  # SR-8.12
        "shutdown",  # SR-7.14 (the daemon's exit: the link is closed by then)
        "fleet_stop",  # SR-8.19
        "fleet_console_lost",  # SR-8.21
    }
)
QUIET_IN_PROOF = frozenset({"client_lost"})  # SR-8.15: no byte while a proof test is unfinished
UNFINISHED = frozenset({Phase.WAITING, Phase.WITHHOLDING, Phase.RESUMED})
USER_BITS = 0xC0  # PR-2.6: bits 6-7 of the VSC's e-stop word, the user e-stop


@dataclass(frozen=True, slots=True)
class Ghost:
    """What the checker has seen (module docstring). Times are absolute; :meth:`key` gives
    them as clipped clocks, as the core's canonical form does."""

    link_open: bool = False
    last_hb: int | None = None  # the VSC's last heartbeat since the link opened
    mode: int | None = None
    word: int = 0
    run: tuple[int, int, int] | None = None  # first, last, count of the non-Operational run
    stop_after_run: bool = False  # a stop raised later than the run's last heartbeat
    key85_one: bool = False
    connected: frozenset[int] = frozenset()  # client connections open
    names: tuple[tuple[int, str], ...] = ()  # connections that said hello, and their names
    required_beat: int | None = None  # the required client's last beat since its hello
    required_progress: int | None = None  # its last progress value accepted (SR-8.16)
    progress_bound: bool = False  # its heartbeats must carry a new value (SR-8.16)
    estops: frozenset[str] = frozenset()  # named clients' e-stops not released
    nonzero: frozenset[int] = frozenset()  # named connections declaring a non-zero command
    local_estop: bool = False
    proven: bool = False  # a proof test passed since the last new start
    beat_sent: bool = False  # a user heartbeat went out since the link opened
    battery: tuple[int, int] | None = None  # the remote's last battery report: level, when
    # SR-3.4: the battery's condition as the checker judges it, the first report of the good
    # run that may end it, and the reason the core gives it and since when (its last change)
    battery_held: bool = True
    battery_good: int | None = None
    battery_reason: str | None = None
    battery_renamed: int | None = None
    # SR-1.4, only with a category-1 output: the state after the last step, when the motion
    # outputs last went off (RUN left), and when the current stop's brake time began
    state: State = State.STOPPED
    motion_off: int | None = None
    braking: int | None = None
    fleet_keepalive: int | None = None  # SR-8.21: the agent's last keepalive accepted
    sequence: int = field(default=0, compare=False)  # the last record's (not part of the key)

    def key(self, now: int, config: SafetyConfig) -> tuple[object, ...]:
        clocks: list[Clock] = []
        if self.last_hb is not None:
            clocks.append(clock("vsc", self.last_hb, now, config.vsc_timeout_ns))
        run: object = None
        if self.run is not None:
            first, last, count = self.run
            run = (min(count, MIN_HEARTBEATS), last - first >= DWELL_NS)
            clocks.append(clock("run:first", first, now, DWELL_NS))
            allowed = first + FASTEST_NS * (count - READ_TOGETHER)
            slack = max(now - allowed, -RATE_SLACK_NS)  # clipped below as the core's form
            clocks.append(clock("run:rate", now - slack, now, 0, FASTEST_NS, RATE_SLACK_NS))
        if self.required_beat is not None:
            timeout = config.clients[0].timeout_ns
            clocks.append(clock("client", self.required_beat, now, timeout))
        battery_low = None
        if _watches_battery(config) and self.battery is not None:
            level, seen = self.battery
            clocks.append(clock("battery", seen, now, BATTERY_FRESH_NS, BATTERY_FRESH_NS + 10 * MS))
            battery_low = level < config.min_remote_battery
        if self.battery_good is not None:
            clocks.append(clock("battery:good", self.battery_good, now, BATTERY_SETTLE_NS))
        if self.battery_renamed is not None:
            clocks.append(clock("battery:renamed", self.battery_renamed, now, BATTERY_SETTLE_NS))
        if config.fleet.console_required and self.fleet_keepalive is not None:  # SR-8.21
            clocks.append(
                clock("fleet", self.fleet_keepalive, now, config.fleet.console_timeout_ns)
            )
        delays = _delays(config)
        if delays:  # SR-1.4 (no clock without a category-1 output: the other models' keys)
            for name, at in (("motion_off", self.motion_off), ("braking", self.braking)):
                if at is not None:
                    clocks.append(clock(name, at, now, *sorted(set(delays.values()))))
        return (
            self.link_open,
            self.mode,
            self.word,
            run,
            self.stop_after_run,
            self.key85_one,
            self.connected,
            self.names,
            self.required_beat is None,
            self.required_progress,
            self.progress_bound,
            self.estops,
            self.nonzero,
            self.local_estop,
            self.proven,
            self.beat_sent,
            battery_low,
            self.battery_held,
            self.battery_reason,
            self.fleet_keepalive is None,
            tuple(clocks),
        )


Violation = tuple[str, str]
"""A property's ID and what was seen."""


def _kind(name: str) -> str:
    return name.partition(":")[0]


def _raised(decision: Decision) -> list[str]:
    return [
        ch.cause.name
        for record in decision.records
        for ch in record.changes
        if ch.kind is ChangeKind.RAISED
    ]


def _name_of(ghost: Ghost, connection: int) -> str | None:
    return dict(ghost.names).get(connection)


# -- the ghost


@dataclass(frozen=True, slots=True)
class _Seen:
    """One step as the ghost takes it in."""

    config: SafetyConfig
    event: Any
    after: Decision
    refused: bool  # the core declined the input (a refusal in its decision)

    @property
    def now(self) -> int:
        return self.after.now

    @property
    def required(self) -> str | None:
        return self.config.clients[0].name if self.config.clients else None


def first_ghost(first: Decision) -> Ghost:
    """The ghost after the core's startup decision: its record's sequence number, and the
    battery's reason it raised then (SR-3.4: renames are counted from it)."""
    reasons = [c.detail("reason") for c in first.causes if c.active and _kind(c.name) in BATTERY]
    return Ghost(
        sequence=first.records[-1].sequence if first.records else 0,
        battery_reason=reasons[0] if reasons else None,
        battery_renamed=first.now if reasons else None,
    )


def _battery_missing(
    battery: tuple[int, int] | None, config: SafetyConfig, now: int, *, arriving: bool
) -> bool:
    """SR-8.12: no report, one below the minimum, or one too old: from 3.5 s on, or past it
    when a new report arrives at ``now`` (the new one is taken in first)."""
    if battery is None or battery[0] < config.min_remote_battery:
        return True
    age = now - battery[1]
    return age > BATTERY_FRESH_NS if arriving else age >= BATTERY_FRESH_NS


def _battery_judged(ghost: Ghost, was: tuple[int, int] | None, seen: _Seen) -> Ghost:
    """SR-8.12, SR-3.4: held from a step that finds the battery missing until a good report
    at least 1 s after the first of an unbroken run of good ones; the reason the core gives."""
    now, config = seen.now, seen.config
    report = ghost.battery is not was  # a report taken in
    held, good = ghost.battery_held, ghost.battery_good
    if _battery_missing(was, config, now, arriving=report):
        held, good = True, None
    if report:
        if _battery_missing(ghost.battery, config, now, arriving=False):
            held, good = True, None
        elif held:
            good = now if good is None else good
            if now - good >= BATTERY_SETTLE_NS:
                held, good = False, None
    reasons = [
        c.detail("reason") for c in seen.after.causes if c.active and _kind(c.name) in BATTERY
    ]
    reason = reasons[0] if reasons else None
    renamed = ghost.battery_renamed
    if reason != ghost.battery_reason:
        renamed = now if reason is not None else None
    return replace(
        ghost, battery_held=held, battery_good=good, battery_reason=reason, battery_renamed=renamed
    )


def _link_opened(ghost: Ghost, seen: _Seen) -> Ghost:
    return replace(_link_down(ghost, seen), link_open=True, key85_one=False)


def _link_down(ghost: Ghost, seen: _Seen) -> Ghost:
    return replace(
        ghost,
        link_open=False,
        last_hb=None,
        mode=None,
        word=0,
        run=None,
        proven=False,
        beat_sent=False,
    )


def _vsc(ghost: Ghost, seen: _Seen) -> Ghost:
    message, now = seen.event.message, seen.now
    if not ghost.link_open:
        return ghost
    if isinstance(message, FeedbackSet) and message.key == 85:
        return replace(ghost, key85_one=message.value == 1)
    if isinstance(message, RemoteStatus):
        return replace(ghost, battery=(message.battery_level, now))
    if not isinstance(message, VscHeartbeat):
        return ghost
    last, run = ghost.last_hb, ghost.run
    unbroken = last is not None and now - last < seen.config.vsc_timeout_ns
    if message.mode == OPERATIONAL:
        run = None
    elif run is None or not unbroken:
        run = (now, now, 1)  # a silent gap starts the run again
    else:
        run = (run[0], now, run[2] + 1)
    return replace(
        ghost,
        last_hb=now,
        mode=message.mode,
        word=message.estop,
        run=run,
        stop_after_run=ghost.stop_after_run and message.mode == OPERATIONAL,
        proven=ghost.proven and (last is None or unbroken),  # a silence is a new start
    )


def _connected(ghost: Ghost, seen: _Seen) -> Ghost:
    if seen.refused:
        return ghost
    return replace(ghost, connected=ghost.connected | {seen.event.connection})


def _hello(ghost: Ghost, seen: _Seen) -> Ghost:
    if seen.refused:
        return ghost
    names = tuple(sorted((*ghost.names, (seen.event.connection, seen.event.name))))
    if seen.event.name != seen.required:
        return replace(ghost, names=names)
    return _progress_restarts(replace(ghost, names=names, required_beat=None), seen.config)


def _progress_restarts(ghost: Ghost, config: SafetyConfig) -> Ghost:
    """SR-8.16: a new connection of the required client starts its counter again, bound to
    progress only when its config says so."""
    return replace(ghost, required_progress=None, progress_bound=config.clients[0].progress)


PROGRESS_CIRCLE = 2**32  # SR-8.16: progress values are 0 to 2**32 - 1 and wrap around
PROGRESS_REFUSALS = frozenset({RefusalReason.STALE_PROGRESS, RefusalReason.NO_PROGRESS})


def fresh(ghost: Ghost, progress: int | None) -> bool:
    """SR-8.16, written again: whether the required client's heartbeat with ``progress``
    keeps it alive: none is fine while not bound, a value must be 1 to 2**31 - 1 ahead."""
    if progress is None:
        return not ghost.progress_bound
    last = ghost.required_progress
    return last is None or 0 < (progress - last) % PROGRESS_CIRCLE < PROGRESS_CIRCLE // 2


def _beat(ghost: Ghost, seen: _Seen) -> Ghost:
    if _name_of(ghost, seen.event.connection) != seen.required:
        return ghost
    progress = seen.event.progress
    if not fresh(ghost, progress):
        return ghost  # SR-8.16: it extends no deadline
    if progress is None:
        return replace(ghost, required_beat=seen.now)
    return replace(ghost, required_beat=seen.now, required_progress=progress, progress_bound=True)


def _estop(ghost: Ghost, seen: _Seen) -> Ghost:
    name = _name_of(ghost, seen.event.connection)
    return ghost if name is None else replace(ghost, estops=ghost.estops | {name})


def _release(ghost: Ghost, seen: _Seen) -> Ghost:
    name = _name_of(ghost, seen.event.connection)
    if seen.refused or name is None or seen.event.request is not Request.ESTOP:
        return ghost
    return replace(ghost, estops=ghost.estops - {name})


def _disconnected(ghost: Ghost, seen: _Seen) -> Ghost:
    connection = seen.event.connection
    names = tuple(n for n in ghost.names if n[0] != connection)
    required = _name_of(ghost, connection) == seen.required
    beat = None if required else ghost.required_beat
    if required:
        ghost = _progress_restarts(ghost, seen.config)
    return replace(
        ghost,
        names=names,
        connected=ghost.connected - {connection},
        required_beat=beat,
        nonzero=ghost.nonzero - {connection},  # a declaration ends with its connection
    )


def _command(ghost: Ghost, seen: _Seen) -> Ghost:
    connection = seen.event.connection
    if _name_of(ghost, connection) is None:  # only a named client declares (SR-4.6)
        return ghost
    if seen.event.nonzero:
        return replace(ghost, nonzero=ghost.nonzero | {connection})
    return replace(ghost, nonzero=ghost.nonzero - {connection})


def _local_estop(ghost: Ghost, seen: _Seen) -> Ghost:
    return replace(ghost, local_estop=True)


def _local_release(ghost: Ghost, seen: _Seen) -> Ghost:
    return ghost if seen.refused else replace(ghost, local_estop=False)


def _prooftest(ghost: Ghost, seen: _Seen) -> Ghost:
    return ghost if seen.refused else replace(ghost, proven=False)


def _fleet_keepalive(ghost: Ghost, seen: _Seen) -> Ghost:
    """SR-8.21: a keepalive the core took (from the agent's user) restarts the console's
    deadline; one it refused does not."""
    return ghost if seen.refused else replace(ghost, fleet_keepalive=seen.now)


_TAKE_IN: dict[type, Callable[[Ghost, _Seen], Ghost]] = {
    LinkOpened: _link_opened,
    LinkClosed: _link_down,
    LinkBroken: _link_down,
    VscReceived: _vsc,
    ClientConnected: _connected,
    ClientHello: _hello,
    ClientHeartbeat: _beat,
    ClientEstop: _estop,
    ClientRelease: _release,
    ClientCommand: _command,
    ClientDisconnected: _disconnected,
    LocalEstop: _local_estop,
    LocalRelease: _local_release,
    ProofTestRequest: _prooftest,
    FleetKeepalive: _fleet_keepalive,
}
"""How each input changes what the checker has seen; inputs not listed change nothing."""


def advance(ghost: Ghost, config: SafetyConfig, event: Event, after: Decision) -> Ghost:
    """The ghost after ``event`` and the decision it brought."""
    seen = _Seen(config, event, after, bool(after.refusals))
    was_battery = ghost.battery
    take_in = _TAKE_IN.get(type(event))
    if take_in is not None:
        ghost = take_in(ghost, seen)
    if _watches_battery(config):
        ghost = _battery_judged(ghost, was_battery, seen)
    if any(r.prooftest is not None and r.prooftest.passed for r in after.records):
        ghost = replace(ghost, proven=True)
    if ghost.link_open and any(isinstance(f, UserHeartbeat) for f in after.frames):
        ghost = replace(ghost, beat_sent=True)
    stop = any(_kind(name) not in HOLDS for name in _raised(after))
    if stop and ghost.run is not None and after.now > ghost.run[1]:
        ghost = replace(ghost, stop_after_run=True)
    if after.records:
        ghost = replace(ghost, sequence=after.records[-1].sequence)
    if _delays(config):
        ghost = _braked(ghost, after)
    return ghost


def _delays(config: SafetyConfig) -> dict[str, int]:
    """Each category-1 output's delay (SR-1.4)."""
    return {o.name: o.off_delay_ns for o in config.outputs if o.off_delay_ms}


def _braked(ghost: Ghost, after: Decision) -> Ghost:
    """SR-1.4: the motion outputs go off when RUN is left; a stop begun in HOLD or RUN (the
    power outputs on) keeps a category-1 output on until its delay after that."""
    motion_off, braking = ghost.motion_off, ghost.braking
    if ghost.state is State.RUN and after.state is not State.RUN:
        motion_off = after.now
    if after.state is not State.STOPPED:
        braking = None
    elif ghost.state is not State.STOPPED:
        braking = motion_off
    return replace(ghost, state=after.state, motion_off=motion_off, braking=braking)


# -- the properties


@dataclass(frozen=True)
class Step:
    """One step to check: the decision before and after ``event``, the core after it (P8 reads
    its timers), the ghost before (``was``) and after (``seen``), ``full``: a copy of the
    core before the step fed the same input with its cheap path off (P17), and ``reflex``:
    the core's reflex before the step (P23)."""

    config: SafetyConfig
    core: SafetyCore
    before: Decision
    after: Decision
    event: Event
    was: Ghost
    seen: Ghost
    full: SafetyCore
    reflex: Reflex | None  # None: time decides too at the heartbeat (SR-9.5)

    def __post_init__(self) -> None:
        causes = [(c.name, c.active, c.latched) for c in self.after.causes]
        object.__setattr__(self, "active", {n for n, on, _ in causes if on})
        object.__setattr__(self, "present", {n for n, on, latch in causes if on or latch})
        object.__setattr__(self, "raised", _raised(self.after))

    active: set[str] = field(init=False)  # causes whose condition holds after the step
    present: set[str] = field(init=False)  # active or latched
    raised: list[str] = field(init=False)  # raised in the step

    @property
    def now(self) -> int:
        return self.after.now

    @property
    def state(self) -> State:
        return self.after.state

    @property
    def stopped(self) -> bool:
        return self.after.state is State.STOPPED

    @property
    def beats(self) -> list[int]:
        return [f.estop for f in self.after.frames if isinstance(f, UserHeartbeat)]


def _p1(step: Step) -> Iterator[str]:
    braking = step.seen.braking
    for spec in step.config.outputs:
        on = step.state is State.RUN if spec.role is OutputRole.MOTION else not step.stopped
        if spec.off_delay_ms and step.stopped and braking is not None:
            on = step.now - braking < spec.off_delay_ns  # SR-1.4: braking under power
        if step.after.outputs.get(spec.name) is not on:
            yield f"{spec.name} is {dict(step.after.outputs)} in {step.state.name}"


def _p2(step: Step) -> Iterator[str]:
    if step.before.state is State.STOPPED and not step.stopped:
        why = _rearm_refusal(step.config, step.before, step.after, step.event, step.was)
        if why:
            yield why


def _p3(step: Step) -> Iterator[str]:
    stops = {n for n in step.present if _kind(n) not in HOLDS}
    holds = {n for n in step.active if _kind(n) in HOLDS}
    want = State.STOPPED if stops else State.HOLD if holds else State.RUN
    if step.state is not want:
        yield f"{step.state.name} with stops {sorted(stops)}, holds {sorted(holds)}"


def _p4(step: Step) -> Iterator[str]:
    timeout, was, seen, now = step.config.vsc_timeout_ns, step.was, step.seen, step.now
    was_silent = was.link_open and (was.last_hb is None or now - was.last_hb >= timeout)
    if was_silent and ("vsc_link_lost" not in step.present or not step.stopped):
        yield f"the VSC silent, {step.state.name} with {sorted(step.present)}"
    if seen.link_open:
        silent = seen.last_hb is None or now - seen.last_hb >= timeout
        if ("vsc_link_lost" in step.active) is not silent:
            yield f"the VSC silent: {silent}, active {sorted(step.active)}"


def _p5(step: Step) -> Iterator[str]:
    proof = step.after.prooftest
    unfinished = proof is not None and proof.phase in UNFINISHED and step.stopped
    counted = OURS - QUIET_IN_PROOF if unfinished else OURS  # SR-8.15
    ours = [n for n in step.raised if _kind(n) in counted]
    serial = step.config.transport is Transport.SERIAL
    if ours and step.seen.link_open and serial and 1 not in step.beats:
        yield f"raised {ours}, user heartbeats {step.beats}"
    byte = 1 if ours or any(_kind(n) in counted for n in step.active) else 0
    if step.after.heartbeat_estop != byte:
        yield f"byte {step.after.heartbeat_estop}, active {sorted(step.active)}"


def _p20(step: Step) -> Iterator[str]:
    proof = step.after.prooftest
    if proof is None or proof.phase is not Phase.WAITING:
        return
    was, seen = step.was, step.seen
    if step.before.state is not State.STOPPED or not step.stopped:
        return
    if not (was.link_open and was.beat_sent and seen.link_open and seen.key85_one):
        return
    if seen.last_hb is None or step.now - seen.last_hb >= step.config.vsc_timeout_ns:
        return
    if seen.word & USER_BITS:
        return
    # The test reads the conditions as the previous step left them (it moves first in the
    # step's refresh): a stop of ours that clears in this step lets it start in the next.
    before = {c.name for c in step.before.causes if c.active}
    ours = {n for n in {*before, *step.active, *step.raised} if _kind(n) in OURS}
    if all(_kind(n) in QUIET_IN_PROOF for n in ours):
        yield f"the proof test waits, STOPPED with {sorted(ours)} of ours"


def _p6(step: Step) -> Iterator[str]:
    config = step.config
    blocks = config.prooftest is ProofTestPolicy.BLOCK and config.transport is Transport.SERIAL
    if blocks and not step.stopped and not step.seen.proven:
        yield f"{step.state.name} with no proof test passed"


def _p7(step: Step) -> Iterator[str]:
    yield from _unrecorded(step.before, step.after, step.was)


def _p8(step: Step) -> Iterator[str]:
    now, deadline = step.now, step.after.next_deadline
    if deadline <= now:
        yield f"deadline {deadline - now} ns from now"
    for name, due in _pending(step.config, step.core, step.seen):
        if now < due < deadline:
            yield f"{name} due in {due - now} ns, deadline in {deadline - now} ns"


def _p9(step: Step) -> Iterator[str]:
    seen = step.seen
    if seen.link_open and seen.mode not in (None, OPERATIONAL) and step.state is State.RUN:
        yield f"RUN in mode {seen.mode:#x}"


def _p10(step: Step) -> Iterator[str]:
    if step.seen.link_open and step.seen.word and not step.stopped:
        yield f"{step.state.name} with e-stop word {step.seen.word:#x}"


def _p11(step: Step) -> Iterator[str]:
    if not step.config.clients:
        return
    required = step.config.clients[0]
    cause = f"client_lost:{required.name}"

    def lost(ghost: Ghost) -> bool:
        beat = ghost.required_beat
        named = required.name in dict(ghost.names).values()
        return not named or beat is None or step.now - beat >= required.timeout_ns

    if lost(step.was) and (cause not in step.present or not step.stopped):
        yield f"{required.name} lost, {step.state.name} with {sorted(step.present)}"
    if (cause in step.active) is not lost(step.seen):
        yield f"{required.name} lost: {lost(step.seen)}, active {sorted(step.active)}"


def _p22(step: Step) -> Iterator[str]:
    event = step.event
    if not isinstance(event, ClientHeartbeat):
        return
    refused = {r.reason for r in step.after.refusals} & PROGRESS_REFUSALS
    clients = step.config.clients
    if not clients or _name_of(step.was, event.connection) != clients[0].name:
        if refused:
            yield f"a heartbeat of a client not required refused: {refused}"
    elif fresh(step.was, event.progress) is bool(refused):
        yield f"progress {event.progress} after {step.was.required_progress}: refused {refused}"


def _p12(step: Step) -> Iterator[str]:
    wanted = {f"client_estop:{n}" for n in step.seen.estops}
    if step.seen.local_estop:
        wanted.add("local_estop")
    if wanted and (not wanted <= step.active or not step.stopped):
        yield f"{sorted(wanted)} asked, {step.state.name} with {sorted(step.active)}"


def _p13(step: Step) -> Iterator[str]:
    config = step.config
    required = config.transport is Transport.SERIAL and config.require_watchdog
    if required and not step.seen.key85_one and not step.stopped:
        yield f"{step.state.name} with key 85 not read as 1"


def _p14(step: Step) -> Iterator[str]:
    if not step.seen.link_open and not step.stopped:
        yield f"{step.state.name} with the link not open"


def _p15(step: Step) -> Iterator[str]:
    if "internal" in step.raised and not isinstance(step.event, InternalFault):
        yield f"internal raised on {type(step.event).__name__}"
    if any(r.reason is RefusalReason.INTERNAL_ERROR for r in step.after.refusals):
        yield f"the core failed: {step.after.refusals}"


def _p16(step: Step) -> Iterator[str]:
    frames = step.after.frames
    if not step.seen.link_open and any(isinstance(f, UserHeartbeat | FeedbackGet) for f in frames):
        yield f"frames to a closed link: {frames}"
    if any(b != step.after.heartbeat_estop for b in step.beats):
        yield f"heartbeats {step.beats}, byte {step.after.heartbeat_estop}"


def _watches_battery(config: SafetyConfig) -> bool:
    return config.on_estop_unavailable is not Reaction.WARN and config.min_remote_battery > 0


def _p19(step: Step) -> Iterator[str]:
    config = step.config
    if not _watches_battery(config):
        return
    battery = step.seen.battery
    unavailable = step.seen.battery_held
    stop = config.on_estop_unavailable is Reaction.STOP
    name = "estop_unavailable" if stop else "estop_unavailable_hold"
    if (name in step.active) != unavailable:
        yield f"{name} active: {name in step.active}, battery {battery} at {step.now}"
    if unavailable and step.state is State.RUN:
        yield f"RUN with the remote's battery {battery} at {step.now}"
    if unavailable and stop and step.state is not State.STOPPED:
        yield f"{step.state.name} under stop with the remote's battery {battery}"


def _p21(step: Step) -> Iterator[str]:
    was, seen = step.was.battery_reason, step.seen.battery_reason
    if was is None or seen is None or was == seen:
        return
    if seen.startswith("the remote's battery has not been reported"):
        return  # a report gone stale: bounded by its own 3.5 s of silence
    report = isinstance(step.event, VscReceived) and isinstance(step.event.message, RemoteStatus)
    renamed = step.was.battery_renamed
    if not report or renamed is None or step.now - renamed < BATTERY_SETTLE_NS:
        yield f"renamed {was!r} to {seen!r} at {step.now}, last at {renamed}"


def _p18(step: Step) -> Iterator[str]:
    nonzero = sorted(step.seen.nonzero)
    if step.before.state is State.STOPPED and not step.stopped and nonzero:
        yield f"re-armed into {step.state.name} with connections {nonzero} declaring non-zero"
    refused = any(r.reason is RefusalReason.COMMAND_NONZERO for r in step.after.refusals)
    if refused and not nonzero:
        yield "a re-arm refused for a non-zero command that no client declares"


CHEAP_ONLY = frozenset({"cheap_path", "steady", "steady_estop", "decision:next"})
"""What of the canonical form only the cheap path reads (its facts and its clock)."""


def without_cheap(form: Canonical) -> Canonical:
    """The canonical form without what only the cheap path reads."""
    facts, clocks = form
    kept = tuple(f for f in facts if not (isinstance(f, tuple) and f[0] in CHEAP_ONLY))
    return kept, tuple(c for c in clocks if c[0] not in CHEAP_ONLY)


def _p17(step: Step) -> Iterator[str]:
    reference = step.full.decision
    if reference != step.after:
        differ = [
            f.name
            for f in fields(Decision)
            if getattr(reference, f.name) != getattr(step.after, f.name)
        ]
        yield f"the cheap path's decision differs in {differ}"
    elif without_cheap(step.full.canonical()) != without_cheap(step.core.canonical()):
        yield "the cheap path left another state than the full step"


def _p23(step: Step) -> Iterator[str]:
    event = step.event
    if type(event) is not VscReceived or type(event.message) is not VscHeartbeat:
        return
    if step.reflex is None:
        return  # time decides too: the loop leaves such a heartbeat to the full step (SR-9.5)
    message = event.message
    early = step.reflex.off(message.mode, message.estop, event.now)
    before, after = step.before.outputs, step.after.outputs
    at_once = [name for name, on in before.items() if on and not after.get(name, False)]
    if len(set(early)) != len(early) or sorted(early) != sorted(at_once):
        yield f"the reflex switches off {sorted(early)}, the full step {sorted(at_once)}"


@dataclass(frozen=True)
class Property:
    """A property: what it says (with the requirements it proves) and its check."""

    text: str
    check: Callable[[Step], Iterator[str]]

    @property
    def requirements(self) -> str:
        return self.text.split(": ", 1)[0]


_RANK = {State.STOPPED: 0, State.HOLD: 1, State.RUN: 2}
FLEET_EVENTS = (FleetStop, FleetRelease, FleetKeepalive)


def _p24(step: Step) -> Iterator[str]:
    if not isinstance(step.event, FLEET_EVENTS):
        return
    name = type(step.event).__name__
    for output, on in step.after.outputs.items():
        if on and not step.before.outputs.get(output, False):
            yield f"{name} turned {output} on"
    if step.after.rearm is not None:
        yield f"{name} re-armed: {step.after.rearm}"
    if _RANK[step.state] > _RANK[step.before.state]:
        yield f"{name} moved {step.before.state.name} to {step.state.name}"


def _p25(step: Step) -> Iterator[str]:
    fleet = step.config.fleet
    if not fleet.console_required:
        return
    cause = "fleet_console_lost"

    def lost(ghost: Ghost) -> bool:
        last = ghost.fleet_keepalive
        return last is None or step.now - last >= fleet.console_timeout_ns

    if lost(step.was) and (cause not in step.present or not step.stopped):
        yield f"console lost, {step.state.name} with {sorted(step.present)}"
    if (cause in step.active) is not lost(step.seen):
        yield f"console lost: {lost(step.seen)}, active {sorted(step.active)}"


PROPERTIES = {
    "P1": Property(
        "SR-1.1, SR-1.2, SR-1.4: a motion output is on exactly in RUN, a power output in HOLD "
        "and RUN, and a category-1 power output also in a stop begun in HOLD or RUN until its "
        "delay after the motion outputs went off",
        _p1,
    ),
    "P2": Property(
        "SR-1.3, SR-4.1, SR-4.2, SR-4.3, SR-4.5: STOPPED is left only by a re-arm: a takeover "
        "whose run is an operator's act (at least 200 ms and three heartbeats, no faster than "
        "a VSC sends, unbroken, since the link opened, not older than the last stop) or an "
        "admin's allowed reset; every stop clear for the re-arm hold, none raised in that step",
        _p2,
    ),
    "P3": Property(
        "SR-1.1, SR-2, SR-3: the state follows the causes in the same step: STOPPED exactly "
        "while a stop is active or latched, else HOLD exactly while a hold is active",
        _p3,
    ),
    "P4": Property(
        "SR-2.2, SR-2.11: VSC silence of vsc_timeout (or none since the link opened) is "
        "vsc_link_lost and STOPPED at the deadline, never later; a heartbeat in time is not",
        _p4,
    ),
    "P5": Property(
        "SR-5.2, SR-8.15: every stop cause of ours raised sends a user heartbeat with its byte at "
        "1 in the same step; the byte is 1 exactly while one of ours is active or was just "
        "raised, client_lost aside while STOPPED with the proof test unfinished",
        _p5,
    ),
    "P6": Property(
        "SR-5.6, SR-5.7: under block, nothing but STOPPED until a proof test passed since the "
        "last new start (the link opened, the VSC silent, srcsctl prooftest)",
        _p6,
    ),
    "P7": Property(
        "SR-7.1: every change of state or of a cause is in a record of that step, with the "
        "states before and after and the causes after; sequence numbers are consecutive",
        _p7,
    ),
    "P8": Property(
        "SR-2.11, SR-5.1, SR-10.1: next_deadline is later than now and never later than the "
        "earliest pending timer",
        _p8,
    ),
    "P9": Property("SR-3.1: while the VSC's last heartbeat is not Operational, never RUN", _p9),
    "P10": Property("SR-2.1: while the VSC's last heartbeat carries an e-stop word, STOPPED", _p10),
    "P11": Property(
        "SR-2.4, SR-8.1: a required client not named, not beaten since hello or silent for its "
        "timeout is client_lost and STOPPED at that step; one in time is not",
        _p11,
    ),
    "P12": Property(
        "SR-2.5, SR-2.6: a named client's or the local e-stop holds STOPPED until released", _p12
    ),
    "P13": Property(
        "SR-5.3: with the watchdog required, STOPPED until key 85 read 1 since the link opened",
        _p13,
    ),
    "P14": Property("SR-2.3: with the link not open, STOPPED", _p14),
    "P15": Property(
        "SR-2.9, SR-8.7: internal only from an InternalFault input; the core never fails", _p15
    ),
    "P16": Property(
        "SR-5.1, SR-5.5: no user heartbeat or key-85 query while the link is closed; every "
        "heartbeat carries the decision's byte",
        _p16,
    ),
    "P17": Property(
        "SR-9.4, SR-8.7: the cheap path decides as the full step and leaves the same state, so "
        "the exploration need not tell apart what only the cheap path reads",
        _p17,
    ),
    "P18": Property(
        "SR-4.6: STOPPED is never left while a named client's last declaration is a non-zero "
        "command, and a re-arm is refused for one only while one is",
        _p18,
    ),
    "P19": Property(
        "SR-8.12, SR-3.4: under on_estop_unavailable hold or stop, the cause is raised in "
        "the step that finds the remote's battery not reported, reported 3.5 s ago or more "
        "(past it when a report arrives then), or below the minimum, and is active exactly "
        "until a good report at least 1 s after the first of an unbroken run of good ones; "
        "meanwhile never RUN, and under stop STOPPED",
        _p19,
    ),
    "P20": Property(
        "SR-8.15: a required client not there never keeps the proof test waiting: STOPPED, "
        "the VSC heard, key 85 read 1, its user bits clear, a user heartbeat sent since the "
        "link opened and no stop of ours but client_lost, the test has started",
        _p20,
    ),
    "P21": Property(
        "SR-3.4: while the battery's cause is active, its reason changes only at a report at "
        "least 1 s after it last changed, or to the words of a report gone stale",
        _p21,
    ),
    "P22": Property(
        "SR-8.16: a required client's heartbeat is refused exactly when its progress value is "
        "not 1 to 2**31 - 1 ahead of the last accepted on its connection (wrapping around), or "
        "it has none once one was given or the config demands it; a refused one extends no "
        "deadline (P11 against the ghost's own rule)",
        _p22,
    ),
    "P23": Property(
        "SR-9.5: for a VSC heartbeat before the deadline, or at a time when only the user "
        "heartbeat is due, the reflex prepared from the state before it switches off exactly "
        "the outputs the full step switches off at once: no more (a category-1 output within "
        "its delay stays on), no fewer",
        _p23,
    ),
    "P24": Property(
        "SR-8.19: no fleet input (a stop, a release or a keepalive, from the agent or anyone "
        "else) turns an output on, re-arms, or moves the state towards RUN",
        _p24,
    ),
    "P25": Property(
        "SR-8.21: with the console required, no keepalive from the agent for "
        "console_timeout_ms (or none since the start) is fleet_console_lost and STOPPED at the "
        "deadline, never later; a keepalive in time is not",
        _p25,
    ),
}
"""Every property, by ID (docs/verification.md "Properties")."""


def check(step: Step) -> list[Violation]:
    """Every property, for one step."""
    return [(pid, what) for pid, prop in PROPERTIES.items() for what in prop.check(step)]


def _rearm_refusal(
    config: SafetyConfig, before: Decision, after: Decision, event: Event, ghost: Ghost
) -> str:
    """Why leaving STOPPED in this step breaks SR-4, or ``""`` when it does not."""
    now = after.now
    hold = config.rearm_hold_ns
    if any(_kind(n) not in HOLDS for n in _raised(after)):
        return "a stop was raised in the re-arm's step (SR-4.3)"
    for cause in before.causes:
        if cause.latched and (cause.cleared_ns is None or now - cause.cleared_ns < hold):
            return f"{cause.name} not clear for the re-arm hold (SR-4.1)"
    if isinstance(event, ResetRequest):
        if not (config.local_reset and event.caller.admin):
            return "a reset that is not allowed (SR-4.2)"
        return ""
    if not (isinstance(event, VscReceived) and isinstance(event.message, VscHeartbeat)):
        return f"left STOPPED on {type(event).__name__} (SR-1.3)"
    if event.message.mode != OPERATIONAL or ghost.mode in (None, OPERATIONAL):
        return "no non-Operational to Operational edge (SR-4.2)"
    if ghost.run is None:
        return "no run before the takeover (SR-4.5)"
    first, last, count = ghost.run
    if last - first < DWELL_NS or count < MIN_HEARTBEATS:
        return f"run of {count} heartbeats over {(last - first) / MS} ms (SR-4.5)"
    if count + 1 > (now - first) // FASTEST_NS + 1 + READ_TOGETHER:
        return f"{count + 1} heartbeats in {(now - first) / MS} ms (SR-4.5)"
    if ghost.stop_after_run:
        return "a stop raised after the run's last heartbeat (SR-4.3)"
    return ""


def _unrecorded(before: Decision, after: Decision, ghost: Ghost) -> list[str]:
    def seen(decision: Decision) -> dict[str, tuple[bool, bool, object]]:
        return {c.name: (c.active, c.latched, c.details) for c in decision.causes}

    old, new = seen(before), seen(after)
    changed = {n for n in old.keys() | new.keys() if old.get(n) != new.get(n)}
    records = after.records
    problems = []
    if changed or before.state is not after.state:
        if not records:
            return [f"{before.state.name} -> {after.state.name}, {sorted(changed)}: no record"]
        if records[0].previous is not before.state or records[-1].state is not after.state:
            problems.append("a record with the wrong states")
        named = {ch.cause.name for r in records for ch in r.changes}
        if changed - named:
            problems.append(f"changes not in the record: {sorted(changed - named)}")
        if records[-1].causes != after.causes:
            problems.append("a record whose causes are not the decision's")
    sequences = [r.sequence for r in records]
    if sequences != list(range(ghost.sequence + 1, ghost.sequence + 1 + len(records))):
        problems.append(f"sequence {sequences} after {ghost.sequence}")
    return problems


def _ghost_timers(config: SafetyConfig, ghost: Ghost) -> list[tuple[str, int]]:
    """The timers the checker knows of by itself: the VSC's silence, the required client's,
    the remote's battery report going stale."""
    pending: list[tuple[str, int]] = []
    if ghost.link_open and ghost.last_hb is not None:
        pending.append(("vsc timeout", ghost.last_hb + config.vsc_timeout_ns))
    if ghost.required_beat is not None:
        pending.append(("client timeout", ghost.required_beat + config.clients[0].timeout_ns))
    if _watches_battery(config) and ghost.battery is not None:
        pending.append(("battery report stale", ghost.battery[1] + BATTERY_FRESH_NS))
    return pending


def _pending(config: SafetyConfig, core: SafetyCore, ghost: Ghost) -> list[tuple[str, int]]:
    """Every timer that is pending after the step: the ghost's (the VSC's silence, the
    required client's) and the core's own (the user heartbeat, key 85, the proof test, the
    display, a deferred end)."""
    pending = _ghost_timers(config, ghost)
    proof = core._proof
    if ghost.link_open:
        vsc = core._vsc
        if vsc.next_heartbeat_ns is not None and not proof.withholding:
            pending.append(("user heartbeat", vsc.next_heartbeat_ns))
        if vsc._next_key85_ns is not None:
            pending.append(("key 85 query", vsc._next_key85_ns))
        if (display := core._display.next_due()) is not None:
            pending.append(("display", display))
    if proof.phase is Phase.WITHHOLDING and proof._withheld_from is not None:
        pending.append(("withholding limit", proof._withheld_from + WITHHOLD_LIMIT_NS))
    if proof.phase is Phase.RESUMED and proof._resumed_ns is not None:
        pending.append(("clear limit", proof._resumed_ns + proof.clear_limit_ns))
    if proof.phase is Phase.WAITING and proof._heard_ns is not None and core._vsc.key85 is None:
        pending.append(("key 85 wait", proof._heard_ns + KEY85_WAIT_NS))
    for entry in core._clients._unnamed.values():
        if not entry.holders:
            free = core._budget.free_at(entry.uid, core._now)
            if free is not None:
                pending.append(("deferred end", free))
    return pending


def check_trace(
    core_class: type[SafetyCore], model_name: str, events: Sequence[Event]
) -> list[Violation]:
    """Replay ``events`` from start on the core of the model ``model_name`` and return every
    violation, in order (what a test printed by the exploration asserts is empty)."""
    model = MODELS[model_name]
    config = model.config
    core = model.start(core_class)
    before = core.decision
    ghost = first_ghost(before)
    found: list[Violation] = []
    for event in events:
        full = full_step(core, event)
        reflex = core.reflex(event.now)
        after = core.handle(event)
        seen = advance(ghost, config, event, after)
        found += check(Step(config, core, before, after, event, ghost, seen, full, reflex))
        before, ghost = after, seen
    return found


def full_step(core: SafetyCore, event: Event) -> SafetyCore:
    """A copy of ``core`` fed ``event`` with its cheap path off: the reference of P17."""
    full: SafetyCore = clone(core)
    full.cheap_path = False
    full.handle(event)
    return full
