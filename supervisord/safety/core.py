"""The safety core: a pure state machine that turns events and ``now`` into decisions.

No I/O, no clock, no threads (``tests/safety/test_purity.py`` checks the imports). The daemon
feeds every input through :meth:`SafetyCore.handle` and calls :meth:`SafetyCore.tick` at the
decision's ``next_deadline`` when nothing else arrives. The core never raises: an input that
makes no sense becomes a :class:`~supervisord.safety.decision.Refusal`, and a failure of the
core itself becomes the ``internal`` stop cause.

Each step runs in a fixed order:

1. time passes: deadlines up to ``now`` expire (a heartbeat that arrives exactly at its
   timeout is too late, because its deadline expires first);
2. the event updates the facts the core tracks;
3. every condition is recomputed from the facts (safety-rules.md §2, §3);
4. a re-arm the event gave is checked (§4);
5. the transition table gives the new state (§1);
6. outputs, frames, the next deadline and the record follow.
"""

from __future__ import annotations

from dataclasses import dataclass
from types import MappingProxyType

from supervisord.protocol.codes import FeedbackKey, VscMode, estop_sources
from supervisord.protocol.messages import (
    FeedbackGet,
    FeedbackSet,
    Message,
    UserHeartbeat,
    VscHeartbeat,
)
from supervisord.safety.book import CauseBook
from supervisord.safety.causes import Cause, CauseKind, Details, make_details
from supervisord.safety.config import NAME_PATTERN, NS_PER_MS, OutputRole, SafetyConfig, Transport
from supervisord.safety.decision import (
    ChangeKind,
    Decision,
    Rearm,
    RearmKind,
    Record,
    RecordNote,
    Refusal,
    RefusalReason,
)
from supervisord.safety.display import DisplayStore
from supervisord.safety.events import (
    Caller,
    ClientConnected,
    ClientDisconnected,
    ClientEstop,
    ClientHeartbeat,
    ClientHello,
    ClientHold,
    ClientRelease,
    Commissioned,
    DisplayUpdate,
    Event,
    InternalFault,
    LinkBroken,
    LinkClosed,
    LinkOpened,
    LocalEstop,
    LocalRelease,
    OutputReadback,
    Request,
    ResetRequest,
    Tick,
    VscReceived,
    is_event,
)
from supervisord.safety.transitions import IllegalTransition, Situation, State, next_state

KEY85_RETRY_NS = 1_000_000_000  # re-ask key 85 every second until it reads 1 (§5)
IDLE_NS = 1_000_000_000  # the longest the core sleeps when nothing else is due
LINKED_MODES = frozenset(
    {VscMode.LOCAL, VscMode.REMOTE, VscMode.OPERATIONAL, VscMode.MENU, VscMode.PAUSE}
)
"""Modes in which a remote is linked to the VSC; a move into one of them from Searching, an
unknown mode or no heartbeat is a re-link that loses the remote's display (notes §2)."""


def mode_name(mode: int) -> str:
    """The ``NAME`` of ``vsc_mode:NAME``: the mode in lower case, or ``unknown_0x42``."""
    known = VscMode.parse(mode)
    return known.name.lower() if known is not None else f"unknown_0x{mode:02x}"


def _anonymous(connection: int) -> str:
    # '#' cannot appear in a configured name (NAME_PATTERN), so this never clashes with one.
    return f"#{connection}"


@dataclass(frozen=True, slots=True)
class _RearmRequest:
    kind: RearmKind
    caller: Caller | None
    takeover_began_ns: int | None  # the non-Operational heartbeat before the Operational one


class SafetyCore:
    """The supervisor's decision-making heart (safety-rules.md §1-5, §8).

    ``SafetyCore(config, now)`` starts STOPPED with the cause ``startup``; :attr:`decision`
    holds the startup decision (all outputs off, the first record). Then feed every input to
    :meth:`handle` and call :meth:`tick` at ``decision.next_deadline``.
    """

    def __init__(self, config: SafetyConfig, now: int) -> None:
        self._config = config
        self._now = now
        self._book = CauseBook()
        self._state = State.STOPPED
        self._sequence = 0
        self._required = {c.name: c for c in config.clients}
        self._output_names = frozenset(o.name for o in config.outputs)
        self._serial = config.transport is Transport.SERIAL
        # The link to the VSC (closed until the daemon says it opened).
        self._link_open = False
        self._link_fault: str | None = "not opened yet"
        self._last_vsc_ns: int | None = None
        self._vsc_mode: int | None = None
        self._non_operational_ns: int | None = None
        self._vsc_estop_word = 0
        self._remote_linked = False
        self._key85: int | None = None
        self._next_key85_ns: int | None = None
        self._next_heartbeat_ns: int | None = None
        # Clients (safety-rules.md §8).
        self._connections: dict[int, str | None] = {}
        self._by_name: dict[str, int] = {}
        self._client_beat_ns: dict[str, int | None] = {}
        self._ever_connected: set[str] = set()
        self._client_estops: set[str] = set()
        self._client_holds: set[str] = set()
        self._local_estop: Caller | None = None
        self._output_faults: dict[str, Details] = {}
        self._display = DisplayStore()
        # Per-step scratch.
        self._frames: list[Message] = []
        self._refusals: list[Refusal] = []
        self._rearm: Rearm | None = None
        self._note: tuple[RecordNote, str] | None = None
        self._book.pulse(Cause(CauseKind.STARTUP), now)  # §1: start STOPPED, cause startup
        self.decision: Decision = self.handle(Tick(now))
        """The latest decision returned (the startup decision until the first input)."""

    # ----------------------------------------------------------------- public API

    @property
    def state(self) -> State:
        return self._state

    @property
    def config(self) -> SafetyConfig:
        return self._config

    def tick(self, now: int) -> Decision:
        """No input arrived by the deadline: let time pass to ``now``."""
        return self.handle(Tick(now))

    def handle(self, event: Event) -> Decision:
        """Feed one input; never raises (a failure of the core stops with ``internal``)."""
        try:
            self.decision = self._step(event)
        except Exception as error:  # the core must never raise: stop with ``internal`` instead
            self.decision = self._fail_safe(event, error)
        return self.decision

    # ----------------------------------------------------------------- the step

    def _step(self, event: object) -> Decision:
        self._frames, self._refusals = [], []
        self._rearm = None
        self._note = None
        request: _RearmRequest | None = None
        if not is_event(event):
            self._refuse(RefusalReason.NOT_AN_EVENT, type(event).__name__, event)
            now = self._now
            event = Tick(now)
        else:
            # A clock that goes back is treated as not moving: no deadline is ever un-expired.
            now = self._now = max(self._now, event.now)
            self._refresh(now)  # 1. time passes
            request = self._apply(event, now)  # 2. the event
        self._refresh(now)  # 3. conditions
        if request is not None:  # 4. re-arm (§4)
            refused = len(self._refusals)
            self._check_rearm(request, event, now)
            if len(self._refusals) > refused:  # every refused re-arm is recorded (docs/record.md)
                self._note = (RecordNote.REARM_REFUSED, self._refusals[-1].message)
        previous = self._state
        self._state = self._transition(now)  # 5. the table
        return self._finish(event, previous, now)  # 6.

    def _transition(self, now: int) -> State:
        try:
            return next_state(self._state, self._situation())
        except IllegalTransition as error:
            self._book.pulse(Cause(CauseKind.INTERNAL), now, make_details([("reason", str(error))]))
            return next_state(self._state, Situation.STOP)

    def _situation(self) -> Situation:
        if self._book.any_latched():
            return Situation.STOP
        hold = self._book.any_hold()
        if self._rearm is not None:
            return Situation.REARMED_HOLD if hold else Situation.REARMED_CLEAR
        return Situation.HOLD if hold else Situation.CLEAR

    def _finish(self, event: Event, previous: State, now: int) -> Decision:
        estop = 1 if self._book.user_estop() else 0
        changes = self._book.take_changes()
        raised_user_estop = any(
            ch.cause.kind.sets_user_estop for ch in changes if ch.kind is ChangeKind.RAISED
        )
        if raised_user_estop:
            estop = 1  # a momentary cause (``internal``) still reaches the VSC once (§5)
        self._emit_link_frames(now, estop, urgent=raised_user_estop)
        causes = self._book.snapshot()
        records: tuple[Record, ...] = ()
        if changes or previous is not self._state or self._note is not None:
            note, reason = self._note or (None, "")
            self._sequence += 1
            records = (
                Record(
                    self._sequence,
                    now,
                    previous,
                    self._state,
                    causes,
                    changes,
                    event,
                    self._rearm,
                    note,
                    reason,
                ),
            )
        return Decision(
            now=now,
            state=self._state,
            causes=causes,
            outputs=self._levels(self._state),
            heartbeat_estop=estop,
            next_deadline=self._next_deadline(now),
            frames=tuple(self._frames),
            records=records,
            refusals=tuple(self._refusals),
            rearm=self._rearm,
        )

    def _fail_safe(self, event: object, error: Exception) -> Decision:
        """The core itself failed: stop with ``internal`` and keep going (never raise)."""
        now = self._now
        refusal = Refusal(RefusalReason.INTERNAL_ERROR, f"{type(error).__name__}: {error}", event)
        previous = self._state
        try:
            self._book.pulse(
                Cause(CauseKind.INTERNAL),
                now,
                make_details([("reason", f"{type(error).__name__}: {error}"[:200])]),
            )
            self._state = State.STOPPED
            self._refusals = [refusal]
            return self._finish(event if is_event(event) else Tick(now), previous, now)
        except Exception:  # the last line of defence: all off, ask again soon
            self._state = State.STOPPED
            return Decision(
                now=now,
                state=State.STOPPED,
                causes=(),
                outputs=MappingProxyType(dict.fromkeys(self._output_names, False)),
                heartbeat_estop=1,
                next_deadline=now + NS_PER_MS,
                frames=(UserHeartbeat(1),) if self._serial and self._link_open else (),
                refusals=(refusal,),
            )

    # ----------------------------------------------------------------- events

    def _apply(self, event: Event, now: int) -> _RearmRequest | None:  # noqa: PLR0912 -- one branch per event
        if isinstance(event, VscReceived):
            return self._on_vsc(event, now)
        if isinstance(event, LinkOpened):
            self._on_link_opened(now)
        elif isinstance(event, LinkBroken | LinkClosed):
            self._on_link_down(event)
        elif isinstance(event, ClientConnected):
            self._on_connected(event)
        elif isinstance(event, ClientHello):
            self._on_hello(event)
        elif isinstance(event, ClientHeartbeat):
            name = self._named(event, event.connection)
            if name is not None and name in self._client_beat_ns:
                self._client_beat_ns[name] = now
        elif isinstance(event, ClientEstop | ClientHold):
            self._on_request(event)
        elif isinstance(event, ClientRelease):
            self._on_release(event)
        elif isinstance(event, ClientDisconnected):
            self._on_disconnected(event)
        elif isinstance(event, LocalEstop):
            self._local_estop = event.caller
        elif isinstance(event, LocalRelease):
            if self._local_estop is None:
                self._refuse(RefusalReason.NOTHING_TO_RELEASE, "local_estop", event)
            self._local_estop = None
        elif isinstance(event, ResetRequest):
            return _RearmRequest(RearmKind.LOCAL_RESET, event.caller, None)
        elif isinstance(event, OutputReadback):
            self._on_readback(event, now)
        elif isinstance(event, InternalFault):
            self._book.pulse(
                Cause(CauseKind.INTERNAL), now, make_details([("reason", event.reason[:200])])
            )
        elif isinstance(event, Commissioned):
            key85 = "no answer" if event.key85 is None else str(event.key85)
            result = f"key85={key85} remote_status={'on' if event.remote_status else 'not seen'}"
            self._note = (RecordNote.COMMISSIONED, result)
        elif isinstance(event, DisplayUpdate):
            reason = self._display.accept(event.message)
            if reason is not None:
                self._refuse(reason, f"key {event.message.key}", event)
        return None

    def _on_vsc(self, event: VscReceived, now: int) -> _RearmRequest | None:
        message = event.message
        if not self._link_open:
            self._refuse(RefusalReason.LINK_NOT_OPEN, type(message).__name__, event)
            return None
        request = None
        if isinstance(message, VscHeartbeat):
            # §2: only a valid heartbeat is liveness; the daemon passes only checked frames.
            self._last_vsc_ns = now
            self._vsc_estop_word = message.estop
            previous_mode = self._vsc_mode
            if (
                message.mode == VscMode.OPERATIONAL
                and previous_mode is not None
                and previous_mode != VscMode.OPERATIONAL
            ):
                # §4: the operator's takeover, not Operational followed by Operational.
                request = _RearmRequest(RearmKind.TAKEOVER, None, self._non_operational_ns)
            if message.mode != VscMode.OPERATIONAL:
                self._non_operational_ns = now
            self._vsc_mode = message.mode
            linked = VscMode.parse(message.mode) in LINKED_MODES
            if linked and not self._remote_linked:
                self._display.relink()
            self._remote_linked = linked
        elif isinstance(message, FeedbackSet):
            if message.key == FeedbackKey.USER_ESTOP_TIMEOUT:
                self._key85 = message.value
                if message.value == 1:
                    self._next_key85_ns = None
            else:
                self._display.edited_on_remote(message)
        return request

    def _on_link_opened(self, now: int) -> None:
        # §4: a reconnect of the VSC is a new start. Liveness starts over ("never seen since
        # link open" counts as lost, §2) and key 85 is read back again (§5).
        self._link_open = True
        if self._config.transport is not Transport.HID:
            self._link_fault = None
        self._last_vsc_ns = None
        self._vsc_mode = None
        self._non_operational_ns = None
        self._remote_linked = False
        self._key85 = None
        self._next_key85_ns = now if self._serial else None
        self._next_heartbeat_ns = now if self._serial else None

    def _on_link_down(self, event: LinkBroken | LinkClosed) -> None:
        word = "broken" if isinstance(event, LinkBroken) else "closed"
        self._link_open = False
        self._link_fault = f"{word}: {event.reason}"[:200]
        self._last_vsc_ns = None
        self._vsc_mode = None
        self._remote_linked = False
        self._next_key85_ns = None
        self._next_heartbeat_ns = None

    def _on_connected(self, event: ClientConnected) -> None:
        if event.connection in self._connections:
            self._refuse(RefusalReason.DUPLICATE_CONNECTION, str(event.connection), event)
            return
        self._connections[event.connection] = None

    def _on_hello(self, event: ClientHello) -> None:
        connection, name = event.connection, event.name
        if connection not in self._connections:
            self._refuse(RefusalReason.UNKNOWN_CONNECTION, str(connection), event)
        elif self._connections[connection] is not None:
            self._refuse(RefusalReason.ALREADY_NAMED, str(self._connections[connection]), event)
        elif not isinstance(name, str) or NAME_PATTERN.fullmatch(name) is None:
            self._refuse(RefusalReason.BAD_NAME, repr(name)[:60], event)
        elif name in self._by_name:
            self._refuse(RefusalReason.NAME_IN_USE, name, event)
        else:
            self._connections[connection] = name
            self._by_name[name] = connection
            self._ever_connected.add(name)
            if name in self._required:
                # §4: a client's (re)connection is a new start; it must send a heartbeat.
                self._client_beat_ns[name] = None

    def _named(self, event: Event, connection: int) -> str | None:
        if connection not in self._connections:
            self._refuse(RefusalReason.UNKNOWN_CONNECTION, str(connection), event)
            return None
        name = self._connections[connection]
        if name is None:
            self._refuse(RefusalReason.NO_HELLO, str(connection), event)
        return name

    def _subjects(self, connection: int) -> set[str]:
        name = self._connections.get(connection)
        return {_anonymous(connection)} if name is None else {name, _anonymous(connection)}

    def _on_request(self, event: ClientEstop | ClientHold) -> None:
        # An e-stop or hold is always honoured, even before hello: it can only add a reason
        # to stop (§0). Before hello it is filed under "#<connection>".
        name = self._connections.get(event.connection) or _anonymous(event.connection)
        requests = self._client_estops if isinstance(event, ClientEstop) else self._client_holds
        requests.add(name)

    def _on_release(self, event: ClientRelease) -> None:
        requests = self._client_estops if event.request is Request.ESTOP else self._client_holds
        mine = self._subjects(event.connection) & requests
        if not mine:
            self._refuse(RefusalReason.NOTHING_TO_RELEASE, event.request.value, event)
        requests.difference_update(mine)

    def _on_disconnected(self, event: ClientDisconnected) -> None:
        connection = event.connection
        if connection not in self._connections:
            self._refuse(RefusalReason.UNKNOWN_CONNECTION, str(connection), event)
            return
        name = self._connections.pop(connection)
        # Requests made before hello end with their connection (nobody could release them);
        # their stop stays latched. Named requests wait for a client of that name to release.
        self._client_estops.discard(_anonymous(connection))
        self._client_holds.discard(_anonymous(connection))
        if name is not None:
            del self._by_name[name]
            if name in self._client_beat_ns:
                self._client_beat_ns[name] = None

    def _on_readback(self, event: OutputReadback, now: int) -> None:
        if event.output not in self._output_names:
            self._refuse(RefusalReason.UNKNOWN_OUTPUT, event.output[:60], event)
            # The daemon and the config disagree: our own side's fault, so stop.
            self._book.pulse(
                Cause(CauseKind.INTERNAL),
                now,
                make_details([("reason", f"read-back of unknown output {event.output[:60]!r}")]),
            )
            return
        if event.read_back is None:
            self._output_faults[event.output] = make_details(
                [("requested", str(event.requested)), ("read_back", "failed")]
            )
        elif event.read_back != event.requested:
            self._output_faults[event.output] = make_details(
                [("requested", str(event.requested)), ("read_back", str(event.read_back))]
            )
        else:
            # §6: the condition clears when a later read-back matches what was set.
            self._output_faults.pop(event.output, None)

    def _refuse(self, reason: RefusalReason, detail: str, event: object) -> None:
        self._refusals.append(Refusal(reason, detail, event))

    # ----------------------------------------------------------------- conditions

    def _refresh(self, now: int) -> None:
        """Recompute every lasting condition from the facts (safety-rules.md §2, §3)."""
        book, config = self._book, self._config
        hid = config.transport is Transport.HID
        fault = "hid is not a safety channel" if hid else self._link_fault
        book.set(
            Cause(CauseKind.TRANSPORT_FAULT),
            fault is not None,
            now,
            make_details([("reason", fault)]) if fault else (),
        )
        last = self._last_vsc_ns
        lost = last is None or now - last >= config.vsc_timeout_ns  # ">=": 200 ms is lost
        book.set(
            Cause(CauseKind.VSC_LINK_LOST),
            lost,
            now,
            make_details(
                [
                    ("reason", "no heartbeat since link open" if last is None else "timeout"),
                    ("timeout_ms", str(config.vsc_timeout_ns // NS_PER_MS)),
                ]
            ),
        )
        word = self._vsc_estop_word
        book.set(
            Cause(CauseKind.VSC_ESTOP),
            word != 0,
            now,
            make_details([("sources", _sources(word)), ("word", f"0x{word:08x}")]),
        )
        watchdog_off = self._serial and config.require_watchdog and self._key85 != 1
        book.set(
            Cause(CauseKind.VSC_WATCHDOG_OFF),
            watchdog_off,
            now,
            make_details([("key85", "no answer" if self._key85 is None else str(self._key85))]),
        )
        book.sync(CauseKind.CLIENT_LOST, self._lost_clients(now), now)
        book.sync(
            CauseKind.CLIENT_ESTOP,
            {Cause(CauseKind.CLIENT_ESTOP, n): () for n in self._client_estops},
            now,
        )
        book.set(
            Cause(CauseKind.LOCAL_ESTOP),
            self._local_estop is not None,
            now,
            _caller_details(self._local_estop),
        )
        book.sync(
            CauseKind.OUTPUT_FAULT,
            {Cause(CauseKind.OUTPUT_FAULT, n): d for n, d in self._output_faults.items()},
            now,
        )
        mode = self._vsc_mode
        book.sync(
            CauseKind.VSC_MODE,
            {}
            if mode is None or mode == VscMode.OPERATIONAL
            else {
                Cause(CauseKind.VSC_MODE, mode_name(mode)): make_details(
                    [("mode", f"0x{mode:02x}")]
                )
            },
            now,
        )
        book.sync(
            CauseKind.CLIENT_HOLD,
            {Cause(CauseKind.CLIENT_HOLD, n): () for n in self._client_holds},
            now,
        )

    def _lost_clients(self, now: int) -> dict[Cause, Details]:
        lost: dict[Cause, Details] = {}
        for name, spec in self._required.items():
            if name not in self._by_name:
                reason = "disconnected" if name in self._ever_connected else "never connected"
            else:
                beat = self._client_beat_ns.get(name)
                if beat is None:
                    reason = "no heartbeat since hello"
                elif now - beat >= spec.timeout_ns:  # ">=": a beat 500 ms late is too late
                    reason = "timeout"
                else:
                    continue
            lost[Cause(CauseKind.CLIENT_LOST, name)] = make_details(
                [("reason", reason), ("timeout_ms", str(spec.timeout_ms))]
            )
        return lost

    # ----------------------------------------------------------------- re-arm (§4)

    def _check_rearm(self, request: _RearmRequest, event: Event, now: int) -> None:
        takeover = request.kind is RearmKind.TAKEOVER
        if not takeover:
            caller = request.caller
            if not self._config.local_reset:
                self._refuse(RefusalReason.LOCAL_RESET_DISABLED, "", event)
                return
            if caller is None or not caller.admin:
                self._refuse(RefusalReason.NOT_ADMIN, caller.name if caller else "", event)
                return
        if self._state is not State.STOPPED:
            if not takeover:  # a takeover outside STOPPED is just the remote leaving pause
                self._refuse(RefusalReason.NOT_STOPPED, self._state.name, event)
            return
        active = self._book.active_stops()
        if active:
            # Safe choice: a re-arm while a stop condition is active does not count, even
            # later; it must be given after the conditions clear.
            self._refuse(RefusalReason.CONDITIONS_ACTIVE, ", ".join(c.name for c in active), event)
            return
        last_stop = self._book.last_stop_raised_ns
        began = request.takeover_began_ns
        if takeover and (began is None or (last_stop is not None and began < last_stop)):
            self._refuse(RefusalReason.NEW_CAUSE_DURING_REARM, "", event)
            return
        clear_since = self._book.stops_clear_since()
        hold = self._config.rearm_hold_ns
        if clear_since is None or now - clear_since < hold:
            clear_ms = 0 if clear_since is None else (now - clear_since) // NS_PER_MS
            self._refuse(
                RefusalReason.HOLD_TIME_NOT_ELAPSED,
                f"clear for {clear_ms} ms of {hold // NS_PER_MS} ms",
                event,
            )
            return
        self._book.release_latches()
        self._rearm = Rearm(request.kind, request.caller)

    # ----------------------------------------------------------------- outputs and frames

    def _levels(self, state: State) -> MappingProxyType[str, bool]:
        # §1: motion outputs on only in RUN; power outputs on in HOLD and RUN.
        return MappingProxyType(
            {
                o.name: state is State.RUN
                if o.role is OutputRole.MOTION
                else state is not State.STOPPED
                for o in self._config.outputs
            }
        )

    def _emit_link_frames(self, now: int, estop: int, *, urgent: bool) -> None:
        if not self._link_open:
            return
        if self._next_heartbeat_ns is not None and (urgent or now >= self._next_heartbeat_ns):
            # §5: user heartbeat at heartbeat_hz; a new stop goes out at once.
            self._frames.append(UserHeartbeat(estop))
            self._next_heartbeat_ns = _after(
                self._next_heartbeat_ns, now, self._config.heartbeat_period_ns, urgent
            )
        if self._next_key85_ns is not None and now >= self._next_key85_ns:
            self._frames.append(FeedbackGet(FeedbackKey.USER_ESTOP_TIMEOUT))
            self._next_key85_ns = now + KEY85_RETRY_NS
        self._frames.extend(self._display.due(now))

    def _next_deadline(self, now: int) -> int:
        """The earliest future time at which something falls due; never ``now`` or earlier."""
        candidates = [now + IDLE_NS]
        if self._last_vsc_ns is not None:
            candidates.append(self._last_vsc_ns + self._config.vsc_timeout_ns)
        for name, beat in self._client_beat_ns.items():
            if beat is not None:
                candidates.append(beat + self._required[name].timeout_ns)
        if self._link_open:
            for due in (self._next_heartbeat_ns, self._next_key85_ns, self._display.next_due()):
                if due is not None:
                    candidates.append(due)
        # A deadline already passed has been acted on in this step (an expired timeout stays
        # expired until a new heartbeat), so only future times count.
        return min(t for t in candidates if t > now)


def _after(scheduled: int, now: int, period: int, restart: bool) -> int:
    """The next heartbeat time: keep the cadence, but never fall behind ``now``."""
    if restart:
        return now + period
    following = scheduled + period
    return following if following > now else now + period


def _sources(word: int) -> str:
    return ",".join(sorted(s.value for s in estop_sources(word)))


def _caller_details(caller: Caller | None) -> Details:
    if caller is None:
        return ()
    return make_details(
        [("caller", caller.name[:60]), ("uid", str(caller.uid)), ("pid", str(caller.pid))]
    )
