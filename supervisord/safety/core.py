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
3. every condition is recomputed from the facts (SR-2, SR-3);
4. a re-arm the event gave is checked (SR-4);
5. the transition table gives the new state (SR-1);
6. outputs, frames, the next deadline and the record follow.

The core composes machines of its own: the link to the VSC (``vsc``), the clients, the causes
(``book``), the record budget, the remote's display and battery, the outputs and the proof
test. Each gives the core its handlers, its conditions at ``now``, its next deadline (the
earliest of them is ``deadline.next_deadline``) and its canonical form. The parts of the step
are modules of their own, each handed the machines it reads: steps 1 and 3 (``conditions``),
step 2's charge to the record budget (``charging``), a message of the VSC (``vscmessage``)
and the proof test's request (``proofrequest``), the re-arm check of step 4 (``rearm``), the
frames and records of step 6 (``finish``), and the cheap path (``cheap``), which answers an
input that cannot change a decision before the step begins. The core keeps the order above,
the transition table and the decision. What one step decides as it goes (its refusals,
frames, re-arm, note) is a :class:`~supervisord.safety.step.Step`, made at the start of the
full step and handed to what needs it, never kept on the core. docs/safety.md "The core".
"""

from __future__ import annotations

import dataclasses
from collections.abc import Callable, Mapping
from types import MappingProxyType
from typing import Any, Final

from supervisord.protocol.messages import RemoteStatus, UserHeartbeat
from supervisord.safety.battery import RemoteBattery
from supervisord.safety.book import CauseBook
from supervisord.safety.budget import RecordBudget
from supervisord.safety.canonical import Canonical, Clock, clock
from supervisord.safety.causes import Cause, CauseKind, make_details
from supervisord.safety.charging import charge_step
from supervisord.safety.cheap import SETTLED_PROOF, cheap, fixed_point, only_the_beat_moves
from supervisord.safety.clients import Clients
from supervisord.safety.conditions import refresh
from supervisord.safety.config import SafetyConfig, Transport
from supervisord.safety.deadline import next_deadline
from supervisord.safety.decision import (
    ChangeKind,
    Decision,
    Rearm,
    RearmKind,
    RecordNote,
    Refusal,
    RefusalReason,
)
from supervisord.safety.display import DisplayStore
from supervisord.safety.events import (
    Caller,
    ClientCommand,
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
    FleetKeepalive,
    FleetRelease,
    FleetStop,
    InternalFault,
    LinkBroken,
    LinkClosed,
    LinkOpened,
    LocalEstop,
    LocalRelease,
    OutputReadback,
    ProofTestRequest,
    ResetRequest,
    Shutdown,
    StopTested,
    Tick,
    VscReceived,
    is_event,
)
from supervisord.safety.finish import link_frames, step_records
from supervisord.safety.outputs import Outputs
from supervisord.safety.proofrequest import request_prooftest
from supervisord.safety.prooftest import ProofTest, ProofTestPolicy
from supervisord.safety.rearm import RearmRequest, check_rearm
from supervisord.safety.reflex import Reflex, prepare
from supervisord.safety.step import Step
from supervisord.safety.transitions import IllegalTransition, Situation, State, next_state
from supervisord.safety.view import View
from supervisord.safety.vsc import LINKED_MODES, TAKEOVER_DWELL_NS, VscLink
from supervisord.safety.vscmessage import take_vsc_message
from supervisord.timebase import NS_PER_MS


class SafetyCore:
    """The supervisor's decision-making heart (SR-1 to SR-5, SR-8).

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
        self._outputs = Outputs(config)  # their levels, delays and read-backs (SR-1, SR-6)
        # Read for every input; the config is frozen, so computed once.
        self._serial = config.transport is Transport.SERIAL
        self._vsc = VscLink(config)  # the link, the modes, the mode's hold, the takeover
        # The proof test of the VSC's watchdog (SR-5.3; docs/safety.md "The proof test").
        self._proof = ProofTest(
            config.prooftest if self._serial else ProofTestPolicy.OFF,
            config.prooftest_clear_ns,
        )
        self._clients = Clients(config.clients, config.fleet)  # SR-8, the fleet SR-8.19
        self._local_estop: Caller | None = None
        self._display = DisplayStore()
        self._budget = RecordBudget()  # records per user (SR-8.5)
        self._battery = RemoteBattery(config)  # the remote's battery (SR-8.12)
        self._compose()
        self._book.pulse(Cause(CauseKind.STARTUP), now)  # SR-1: start STOPPED, cause startup
        self.decision: Decision = self.handle(Tick(now))
        """The latest decision returned (the startup decision until the first input)."""

    # ----------------------------------------------------------------- public API

    @property
    def state(self) -> State:
        return self._state

    @property
    def config(self) -> SafetyConfig:
        return self._config

    def reflex(self, now: int) -> Reflex | None:
        """What a stopping VSC heartbeat read at ``now`` switches off at once from this state,
        for the daemon to write before the full step (SR-9.5, :mod:`~supervisord.safety.reflex`);
        ``None`` when time decides too at ``now`` (a deadline other than the user heartbeat's
        is due: a timeout, a braking output, the proof test), the full step's alone. The user
        heartbeat's deadline alone does not count: the VSC's heartbeats and the user
        heartbeat keep one cadence, so a stop often arrives just as the beat is due. Derived
        from the state, no part of it: a pure function, kept for the last states seen."""
        if now >= self.decision.next_deadline and not only_the_beat_moves(self._view.at(now)):
            return None
        return prepare(self._state, *self._outputs.reflex_facts())

    def tick(self, now: int) -> Decision:
        """No input arrived by the deadline: let time pass to ``now``."""
        return self.handle(Tick(now))

    def canonical(self, now: int | None = None) -> Canonical:
        """The state as the exhaustive exploration compares it (``verify/``, docs/verification.md
        "The time abstraction"): every fact a later input can depend on, and every time kept
        as a clock clipped above the largest constant its guards compare it with. Two states
        with the same form answer every later input alike, ``now`` and the record's text
        aside. ``now`` (default: the latest input's) may only be later than that.

        Left out: the config and what is computed from it once, the record's sequence number
        and ``decision`` but for its deadline (``_NOT_CANONICAL``;
        ``tests/safety/test_canonical.py`` checks that every other attribute is read here);
        a step's own values are a :class:`Step`, no attribute of the core. Each machine gives
        its facts and clocks (``VscLink.canonical`` keeps the two guards of the takeover that
        are not of the form ``age >= constant``), listed here in one flat form.
        """
        now = self._now if now is None else max(now, self._now)
        book = self._book
        clocks: list[Clock] = []

        def keep(name: str, at: int | None, *limits: int) -> None:
            if at is not None:
                clocks.append(clock(name, at, now, *limits))

        keep("clear_since", book.stops_clear_since(), self._config.rearm_hold_ns)
        if self._steady:  # read only by the cheap path and step 1, after a normal step
            keep("decision:next", self.decision.next_deadline, 0)
        facts: list[object] = [
            ("state", self._state),
            ("cheap_path", self.cheap_path),
            ("steady", self._steady),
            ("steady_estop", self._steady and self._steady_estop),
            ("causes", book.canonical()),
            ("local_estop", self._local_estop),
        ]
        at = self._view.at(now, book.last_stop_raised_ns)
        for machine in at.machines:  # each machine's own facts and clocks (face.py)
            machine_facts, machine_clocks = machine.canonical(at)
            facts += machine_facts
            clocks += machine_clocks
        return tuple(facts), tuple(clocks)

    _NOT_CANONICAL = frozenset(
        {
            # The config, and what is computed from it once (constants of the exploration).
            "_config",
            "_serial",
            # The reference every clock is measured from; the record's sequence number.
            "_now",
            "_sequence",
        }
    )
    """Attributes ``canonical`` leaves out, and why (``decision`` is read for its deadline)."""

    cheap_path = True
    """Answer inputs that cannot change a decision without the full step (``cheap.py``). The
    full path is the reference: ``tests/safety/test_cheap_path.py`` switches this off on one
    of two cores and checks that both give the same decisions for random inputs (SR-9.4)."""
    _steady = False  # the last step ended normally: its decision is the state's fixed point
    _steady_estop = 0  # the user heartbeat's byte from the conditions alone (no urgent raise)

    def handle(self, event: Event) -> Decision:
        """Feed one input; never raises (a failure of the core stops with ``internal``)."""
        step: Step | None = None  # made only for the full step: the cheap path needs none
        try:
            decision = (
                cheap(event, self.decision, self._now, self._steady_estop, self._view)
                if self._steady and self.cheap_path
                else None
            )
            if decision is not None:
                self._now = decision.now
                self.decision = decision
            else:
                step = Step(self._now)
                self.decision = self._step(event, step)
        except Exception as error:  # the core must never raise: stop with ``internal`` instead
            self._steady = False
            self.decision = self._fail_safe(event, error, step or Step(self._now))
        return self.decision

    COMPOSED = frozenset({"_view"})
    """What :meth:`_compose` builds from the machines: no state of its own. A copy of the core
    (``verify/clone.py``) and a snapshot (``snapshot.py``) leave it out and compose again."""

    def _compose(self) -> None:
        """The view of the core's machines that the parts composing them read (``face.py``),
        built once: the machines live as long as the core, so that no input pays for a
        tuple or a view (SR-9.4)."""
        self._view = View(
            self._vsc,
            self._clients,
            self._budget,
            self._outputs,
            self._battery,
            self._display,
            self._proof,
        )

    # ----------------------------------------------------------------- the step

    def _step(self, event: object, step: Step) -> Decision:
        steady, self._steady = self._steady and self.cheap_path, False
        request: RearmRequest | None = None
        if not is_event(event):
            step.refuse(RefusalReason.NOT_AN_EVENT, type(event).__name__, event)
            now = self._now
            event = Tick(now)
        else:
            # A clock that goes back is treated as not moving: no deadline is ever un-expired.
            now = step.now = self._now = max(self._now, event.now)
            step.arriving = (  # a report taken in: one refused (link not open) is none (SR-8.12)
                self._battery.cause is not None
                and type(event) is VscReceived
                and type(event.message) is RemoteStatus
                and self._vsc.open
            )
            if not (
                # Before the previous decision's deadline, after a normal step, with the proof
                # test settled, time passing changes no condition (the cheap path's argument,
                # ``cheap.py``): step 1 would recompute them to the same (SR-9.4).
                steady and now < self.decision.next_deadline and self._proof.phase in SETTLED_PROOF
            ):
                self._refresh(step)  # 1. time passes
            # 2. the event, unless its user is past its record budget and it would take a
            # reason to stop away (SR-8.5, ``charging.py``)
            if charge_step(step, event, self._clients, self._budget):
                step.refuse(RefusalReason.RATE_LIMITED, type(event).__name__, event)
            else:
                request = self._apply(event, step)
        self._clients.end_due(now, self._budget)
        self._refresh(step)  # 3. conditions
        if request is not None:  # 4. re-arm (SR-4)
            rearm = check_rearm(
                request,
                event,
                now,
                state=self._state,
                config=self._config,
                book=self._book,
                vsc=self._vsc,
                clients=self._clients,
                display=self._display,
            )
            if isinstance(rearm, Rearm):
                step.rearm = rearm
            elif rearm is not None:  # every refused re-arm is recorded (docs/record.md)
                step.refusals.append(rearm)
                step.note = (RecordNote.REARM_REFUSED, rearm.message)
        if not self._clients.commanding():
            self._display.end_notice()  # nothing commands motion any more (SR-4.6)
        previous = self._state
        self._state = self._transition(step)  # 5. the table
        decision = self._finish(event, previous, step)  # 6.
        # A normal end on a fixed point of the table: the next input may take the cheap path.
        self._steady = fixed_point(self._state, self._book)
        return decision

    def _refresh(self, step: Step) -> None:
        """Steps 1 and 3: every lasting condition recomputed (``conditions.py``); a method of
        the core, so that a test can count the full path's recomputations."""
        refresh(
            step,
            state=self._state,
            local_estop=self._local_estop,
            book=self._book,
            vsc=self._vsc,
            proof=self._proof,
            clients=self._clients,
            outputs=self._outputs,
            battery=self._battery,
        )

    def _transition(self, step: Step) -> State:
        try:
            return next_state(self._state, self._situation(step.rearm))
        except IllegalTransition as error:
            details = make_details([("reason", str(error))])
            self._book.pulse(Cause(CauseKind.INTERNAL), step.now, details)
            return next_state(self._state, Situation.STOP)

    def _situation(self, rearm: Rearm | None) -> Situation:
        if self._book.any_latched():
            return Situation.STOP
        hold = self._book.any_hold()
        if rearm is not None:
            return Situation.REARMED_HOLD if hold else Situation.REARMED_CLEAR
        return Situation.HOLD if hold else Situation.CLEAR

    def _finish(self, event: Event, previous: State, step: Step) -> Decision:
        now = step.now
        # SR-8.15: while an unfinished proof test needs the byte at 0, a missing required
        # client neither sets it nor aborts the test (the outputs are off: STOPPED).
        quiet = self._proof.quiet(self._state is State.STOPPED)
        estop = self._steady_estop = 1 if self._book.user_estop(quiet) else 0
        changes = self._book.take_changes()
        raised_user_estop = any(
            ch.cause.kind.sets_user_estop and ch.cause.kind not in quiet
            for ch in changes
            if ch.kind is ChangeKind.RAISED
        )
        if raised_user_estop:
            estop = 1  # a momentary cause (``internal``) still reaches the VSC once (SR-5)
        link_frames(
            step,
            estop,
            urgent=raised_user_estop,
            vsc=self._vsc,
            proof=self._proof,
            display=self._display,
        )
        causes = self._book.snapshot()
        records = step_records(
            step,
            event,
            sequence=self._sequence,
            previous=previous,
            state=self._state,
            causes=causes,
            changes=changes,
        )
        if records:
            self._sequence = records[-1].sequence
            if step.charged is not None:
                self._budget.charge(step.charged[0], now)
        return Decision(
            now=now,
            state=self._state,
            causes=causes,
            outputs=self._outputs.levels(previous, self._state, now),
            heartbeat_estop=estop,
            next_deadline=next_deadline(self._view.at(now)),
            frames=tuple(step.frames),
            records=records,
            refusals=tuple(step.refusals),
            rearm=step.rearm,
            prooftest=self._proof.status(),
        )

    def _fail_safe(self, event: object, error: Exception, step: Step) -> Decision:
        """The core itself failed: stop with ``internal`` and keep going (never raise).
        ``step``: the full step that failed, as far as it got (its frames and note go out), or
        a new one when the cheap path failed."""
        now = step.now = self._now
        refusal = Refusal(RefusalReason.INTERNAL_ERROR, f"{type(error).__name__}: {error}", event)
        previous = self._state
        try:
            self._book.pulse(
                Cause(CauseKind.INTERNAL),
                now,
                make_details([("reason", f"{type(error).__name__}: {error}"[:200])]),
            )
            self._state = State.STOPPED
            step.refusals = [refusal]
            decision = self._finish(event if is_event(event) else Tick(now), previous, step)
            # The core's own failure is a stop of category 0 (SR-1.4): no output stays on.
            self._outputs.category_0()
            return dataclasses.replace(decision, outputs=self._outputs.of(State.STOPPED))
        except Exception:  # the last line of defence: all off, ask again soon
            self._state = State.STOPPED
            self._outputs.category_0()  # SR-1.4
            return Decision(
                now=now,
                state=State.STOPPED,
                causes=(),
                outputs=self._outputs.all_off(),
                heartbeat_estop=1,
                next_deadline=now + NS_PER_MS,
                frames=(UserHeartbeat(1),) if self._serial and self._vsc.open else (),
                refusals=(refusal,),
            )

    # ----------------------------------------------------------------- events

    def _apply(self, event: Event, step: Step) -> RearmRequest | None:
        """Step 2: the event updates the facts, through its handler in :data:`_HANDLERS`
        (one per event type; ``tests/safety/test_dispatch.py`` checks that none is missing)."""
        handler = _HANDLERS.get(type(event))
        if handler is None:  # a type with no handler is not ignored: the core stops (SR-0)
            raise LookupError(f"no handler for {type(event).__name__}")
        return handler(self, event, step)

    def _on_tick(self, event: Tick, step: Step) -> None:
        """Time passing is step 1's and step 3's work; a tick brings no fact of its own."""

    def _on_command(self, event: ClientCommand, step: Step) -> None:
        step.refuse_if(self._clients.command(event))

    def _on_client_heartbeat(self, event: ClientHeartbeat, step: Step) -> None:
        step.refuse_if(self._clients.heartbeat(event, step.now))

    def _on_local_estop(self, event: LocalEstop, step: Step) -> None:
        # Past the budget an active local e-stop keeps its caller: a new one would only
        # change the record's words (SR-8.5); the stop stands either way.
        if self._local_estop is None or not step.limited:
            self._local_estop = event.caller

    def _on_local_release(self, event: LocalRelease, step: Step) -> None:
        if self._local_estop is None:
            step.refuse(RefusalReason.NOTHING_TO_RELEASE, "local_estop", event)
        self._local_estop = None

    def _on_reset(self, event: ResetRequest, step: Step) -> RearmRequest:
        return RearmRequest(RearmKind.LOCAL_RESET, event.caller)

    def _on_internal_fault(self, event: InternalFault, step: Step) -> None:
        self._book.pulse(
            Cause(CauseKind.INTERNAL), step.now, make_details([("reason", event.reason[:200])])
        )

    def _on_shutdown(self, event: Shutdown, step: Step) -> None:
        # SR-7.14: the daemon exits, its outputs already off; the stop is the core's like any
        # other, so its record continues the sequence and a replay makes it again (SR-7.13).
        # Momentary and latched, as ``internal``: in RUN or HOLD a stop, in STOPPED a cause
        # raised, so every exit of the daemon is a record.
        reason = event.reason[:60] if event.reason else "unknown"
        self._book.pulse(Cause(CauseKind.SHUTDOWN, reason), step.now, ())

    def _on_commissioned(self, event: Commissioned, step: Step) -> None:
        key85 = "no answer" if event.key85 is None else str(event.key85)
        result = f"key85={key85} remote_status={'on' if event.remote_status else 'not seen'}"
        step.note = (RecordNote.COMMISSIONED, result)

    def _on_stoptested(self, event: StopTested, step: Step) -> None:
        # Measured and judged by the daemon (SR-12.1); the core gives it its place in the
        # record, so that a replay makes it again (SR-7.13).
        step.note = (RecordNote.STOPTEST, event.result.text)

    def _on_display(self, event: DisplayUpdate, step: Step) -> None:
        reason = self._display.accept(event.message)
        if reason is not None:
            step.refuse(reason, f"key {event.message.key}", event)

    def _on_vsc(self, event: VscReceived, step: Step) -> RearmRequest | None:
        """A message of the VSC tells the machines what it says (``vscmessage.py``)."""
        vsc, proof, display, battery = self._vsc, self._proof, self._display, self._battery
        return take_vsc_message(event, step, vsc=vsc, proof=proof, display=display, battery=battery)

    def _on_link_opened(self, event: LinkOpened, step: Step) -> None:
        self._vsc.opened(step.now)
        self._proof.restart()  # SR-4.4 a new start: the VSC's watchdog is proven again

    def _on_link_down(self, event: LinkBroken | LinkClosed, step: Step) -> None:
        word = "broken" if isinstance(event, LinkBroken) else "closed"
        self._vsc.down(f"{word}: {event.reason}")
        self._proof.restart()

    def _on_prooftest(self, event: ProofTestRequest, step: Step) -> None:
        """``srcsctl prooftest``: begun, or refused (``proofrequest.py``)."""
        step.refuse_if(request_prooftest(event, self._proof, self._state, self._config.transport))

    def _on_connected(self, event: ClientConnected, step: Step) -> None:
        step.refuse_if(self._clients.connected(event))

    def _on_hello(self, event: ClientHello, step: Step) -> None:
        refusal = self._clients.hello(event)
        step.refuse_if(refusal)
        if refusal is not None and refusal.reason is RefusalReason.WRONG_USER:
            # docs/safety.md "Clients bound to a user": refused and recorded.
            step.note = (RecordNote.HELLO_REFUSED, refusal.message)

    def _on_request(self, event: ClientEstop | ClientHold, step: Step) -> None:
        self._clients.request(event)

    def _on_release(self, event: ClientRelease, step: Step) -> None:
        step.refuse_if(self._clients.release(event))

    def _on_disconnected(self, event: ClientDisconnected, step: Step) -> None:
        step.refuse_if(self._clients.disconnected(event, step.limited))

    def _on_fleet_stop(self, event: FleetStop, step: Step) -> None:
        # SR-8.19: it can only add a reason to stop; it asks for no re-arm.
        step.refuse_if(self._clients.fleet.stop(event))

    def _on_fleet_release(self, event: FleetRelease, step: Step) -> None:
        # SR-8.19: ends the condition only; the stop stays latched until the takeover (SR-4).
        step.refuse_if(self._clients.fleet.release(event))

    def _on_fleet_keepalive(self, event: FleetKeepalive, step: Step) -> None:
        step.refuse_if(self._clients.fleet.keepalive(event, step.now))  # SR-8.21

    def _on_readback(self, event: OutputReadback, step: Step) -> None:
        refusal = self._outputs.readback(event)
        if refusal is not None:
            step.refusals.append(refusal)
            # The daemon and the config disagree: our own side's fault, so stop.
            self._book.pulse(
                Cause(CauseKind.INTERNAL),
                step.now,
                make_details([("reason", f"read-back of unknown output {event.output[:60]!r}")]),
            )


_Handler = Callable[[SafetyCore, Any, Step], "RearmRequest | None"]
_HANDLERS: Final[Mapping[type, _Handler]] = MappingProxyType(
    {
        Tick: SafetyCore._on_tick,
        VscReceived: SafetyCore._on_vsc,
        LinkOpened: SafetyCore._on_link_opened,
        LinkBroken: SafetyCore._on_link_down,
        LinkClosed: SafetyCore._on_link_down,
        ClientConnected: SafetyCore._on_connected,
        ClientHello: SafetyCore._on_hello,
        ClientHeartbeat: SafetyCore._on_client_heartbeat,
        ClientEstop: SafetyCore._on_request,
        ClientHold: SafetyCore._on_request,
        ClientCommand: SafetyCore._on_command,
        ClientRelease: SafetyCore._on_release,
        ClientDisconnected: SafetyCore._on_disconnected,
        LocalEstop: SafetyCore._on_local_estop,
        LocalRelease: SafetyCore._on_local_release,
        ResetRequest: SafetyCore._on_reset,
        OutputReadback: SafetyCore._on_readback,
        InternalFault: SafetyCore._on_internal_fault,
        Shutdown: SafetyCore._on_shutdown,
        Commissioned: SafetyCore._on_commissioned,
        DisplayUpdate: SafetyCore._on_display,
        ProofTestRequest: SafetyCore._on_prooftest,
        StopTested: SafetyCore._on_stoptested,
        FleetStop: SafetyCore._on_fleet_stop,
        FleetRelease: SafetyCore._on_fleet_release,
        FleetKeepalive: SafetyCore._on_fleet_keepalive,
    }
)
"""Step 2's dispatch: each event type to the handler that applies it to the facts. Every type
of :data:`~supervisord.safety.events.Event` has one (``tests/safety/test_dispatch.py``), so a
new event cannot be ignored by omission. Keyed by the exact type: events are final."""


__all__ = ["LINKED_MODES", "TAKEOVER_DWELL_NS", "SafetyCore"]
"""``LINKED_MODES`` and ``TAKEOVER_DWELL_NS`` are the link's (``vsc.py``), read from here by the
daemon and the test kit too."""
