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
"""

from __future__ import annotations

import dataclasses
import functools
from collections.abc import Callable, Mapping
from dataclasses import dataclass
from types import MappingProxyType
from typing import Any, Final

from supervisord.protocol.codes import FeedbackKey, VscMode, estop_sources
from supervisord.protocol.messages import (
    FeedbackGet,
    FeedbackSet,
    Gps,
    Joystick,
    Message,
    RemoteStatus,
    UserHeartbeat,
    VscHeartbeat,
)
from supervisord.safety.availability import (
    BATTERY_SETTLE_NS,
    REMOTE_STATUS_FRESH_NS,
    Reaction,
    battery_missing,
    stale_words,
)
from supervisord.safety.book import CauseBook
from supervisord.safety.budget import RecordBudget, Uid
from supervisord.safety.canonical import Canonical, Clock, clock
from supervisord.safety.causes import Cause, CauseKind, Details, make_details
from supervisord.safety.config import NAME_PATTERN, OutputRole, SafetyConfig, Transport
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
from supervisord.safety.display import DisplayStore, Notice
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
    InternalFault,
    LinkBroken,
    LinkClosed,
    LinkOpened,
    LocalEstop,
    LocalRelease,
    OutputReadback,
    ProofTestRequest,
    Request,
    ResetRequest,
    Shutdown,
    StopTested,
    Tick,
    VscReceived,
    is_event,
)
from supervisord.safety.progress import ProgressBook
from supervisord.safety.prooftest import (
    USER_BITS,
    Outcome,
    Phase,
    ProofTest,
    ProofTestPolicy,
)
from supervisord.safety.transitions import IllegalTransition, Situation, State, next_state
from supervisord.timebase import NS_PER_MS, NS_PER_S, next_due

KEY85_RETRY_NS = NS_PER_S  # re-ask key 85 every second until it reads 1 (SR-5)
IDLE_NS = NS_PER_S  # the longest the core sleeps when nothing else is due
TAKEOVER_DWELL_NS = 200 * NS_PER_MS
"""docs/safety.md "Re-arming" rule 4: a takeover needs the non-Operational mode reported by an
unbroken run of VSC heartbeats whose first and last are at least this far apart. Longer than
any mode glitch or chatter, shorter than any person's takeover on the remote."""
VSC_MIN_INTERVAL_NS = 20 * NS_PER_MS
"""The shortest interval a VSC can be set to send its heartbeat at (manual §8.3.6 message
control: 20 ms; the manual's rates are 20 Hz serial, 10 Hz CAN). Faster heartbeats are not
a VSC's, and are no evidence of a takeover (rule 4)."""
VSC_SLOWEST_RATE_INTERVAL_NS = 100 * NS_PER_MS
"""The longest heartbeat interval of the manual's documented rates (10 Hz on CAN, table 23;
20 Hz on serial, table 5)."""
TAKEOVER_MIN_HEARTBEATS = TAKEOVER_DWELL_NS // VSC_SLOWEST_RATE_INTERVAL_NS + 1
"""Re-arm rule 4: the non-Operational heartbeats a run must hold, however long its span (3:
what a VSC at its slowest documented rate sends in the dwell). A span is measured between read
stamps, and a loop that was starved reads a heartbeat late, stretching the span; the number of
heartbeats cannot be stretched (seen: a VSC flapping every 100 ms, Local at 0 and 50 ms, the
50 ms one read at 210 ms, re-armed a starved supervisor)."""
BATTERY_SEEN_CLIP_NS = REMOTE_STATUS_FRESH_NS + 10 * NS_PER_MS
"""Where ``canonical`` clips the age of the last battery report (SR-8.12): past the 3.5 s
limit, so that the age exactly at it (a report arriving then refreshes it) and one past it (a
report arriving then finds it stale) are two forms; every age beyond is alike."""
SETTLE_DWELL_NS = TAKEOVER_DWELL_NS
"""docs/safety.md "Leaving a hold of the VSC's mode" (SR-3.3): after a non-Operational mode
that was no operator's act (a glitch, a flap), the hold ends once the VSC has reported
Operational in an unbroken run of heartbeats at least this far apart (and at least
``TAKEOVER_MIN_HEARTBEATS``): the takeover's own evidence, in Operational. The same 200 ms also
spaces the renames of the hold when the VSC flaps between two modes that are not Operational."""
READ_TOGETHER_ALLOWANCE = 2
"""Heartbeats a run may hold beyond what its span allows at ``VSC_MIN_INTERVAL_NS``: frames
read in one loop turn share one time, so a late read makes a span look shorter."""
RATE_SLACK_NS = 3 * VSC_MIN_INTERVAL_NS
"""Where ``canonical`` clips the run's rate clock (rule 4), above and below: a run that could
take three more heartbeats at once than the VSC's fastest rate allows counts as the same state
as one that could take more, and one three heartbeats past it as one further past it
(docs/verification.md "The one inexact clip")."""
NOTICE_WIDTH = 20  # characters in a row of the remote's text page (manual table 18)
REFUSAL_QUIET_NS = NS_PER_S
"""The same takeover refusal is reported (and recorded) at most once per this: a flapping VSC
would otherwise fill the record, whose rotation drops the stop the refusals are about."""
LINKED_MODES = frozenset(
    {VscMode.LOCAL, VscMode.REMOTE, VscMode.OPERATIONAL, VscMode.MENU, VscMode.PAUSE}
)
"""Modes in which a remote is linked to the VSC; a move into one of them from Searching, an
unknown mode or no heartbeat is a re-link that loses the remote's display (PR-2)."""
INERT_VSC_MESSAGES = (Joystick, Gps, RemoteStatus)
"""VSC messages that change no fact the core keeps (``_on_vsc`` ignores them): in a steady
state they take the cheap path (docs/performance.md "The cheap path"). A whitelist, so that a
message type added later takes the full path until someone decides otherwise. Remote status
is inert only while the core does not react to the remote's battery (SR-8.12)."""


def mode_name(mode: int) -> str:
    """The ``NAME`` of ``vsc_mode:NAME``: the mode in lower case, or ``unknown_0x42``."""
    known = VscMode.parse(mode)
    return known.name.lower() if known is not None else f"unknown_0x{mode:02x}"


@dataclass(slots=True)
class _Unnamed:
    """A request (e-stop or hold) made before hello, filed under its user (choice 11): the
    connections that asked for it and have not released it. With none left it ends, unless
    the user is past its record budget: then it ends once the budget allows (SR-8.5)."""

    uid: Uid
    holders: set[int]


@dataclass(frozen=True, slots=True)
class _Run:
    """An unbroken run of non-Operational VSC heartbeats (re-arm rule 4): none Operational,
    none ``vsc_timeout`` or more after the one before, all since the link last opened."""

    first_ns: int
    last_ns: int
    heartbeats: int

    def then(self, now: int) -> _Run:
        return _Run(self.first_ns, now, self.heartbeats + 1)


@dataclass(frozen=True, slots=True)
class _RearmRequest:
    kind: RearmKind
    caller: Caller | None
    run: _Run | None = None  # a takeover's evidence: the run before the Operational heartbeat


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
        self._required = {c.name: c for c in config.clients}
        self._output_names = frozenset(o.name for o in config.outputs)
        self._levels_by_state: dict[State, MappingProxyType[str, bool]] = {}
        # Read for every input; the config is frozen, so computed once.
        self._vsc_timeout_ns = config.vsc_timeout_ns
        self._heartbeat_period_ns = config.heartbeat_period_ns
        self._client_timeout_ns = {c.name: c.timeout_ns for c in config.clients}
        self._serial = config.transport is Transport.SERIAL
        # The link to the VSC (closed until the daemon says it opened).
        self._link_open = False
        self._link_fault: str | None = "not opened yet"
        self._last_vsc_ns: int | None = None
        self._vsc_mode: int | None = None
        self._run: _Run | None = None  # the current non-Operational run (re-arm rule 4)
        # The hold of the VSC's mode (SR-3.1, SR-3.3): the mode it names, since when it has
        # named it, and the Operational run that may end it after a glitch or a flap.
        self._held_mode: int | None = None
        self._held_since = 0
        self._settling: _Run | None = None
        self._quiet: tuple[RefusalReason, int] | None = None  # the last takeover refusal
        self._vsc_estop_word = 0
        self._remote_linked = False
        self._key85: int | None = None
        self._next_key85_ns: int | None = None
        self._next_heartbeat_ns: int | None = None
        # The proof test of the VSC's watchdog (SR-5.3; docs/safety.md "The proof test").
        self._proof = ProofTest(
            config.prooftest if self._serial else ProofTestPolicy.OFF,
            config.prooftest_clear_ns,
        )
        self._proof_outcome: Outcome | None = None  # finished in this step, for its record
        # Clients (SR-8).
        self._connections: dict[int, str | None] = {}
        self._by_name: dict[str, int] = {}
        self._client_beat_ns: dict[str, int | None] = {}
        # SR-8.16: only a heartbeat with new progress counts, where the client is bound to it.
        self._progress = ProgressBook(frozenset(c.name for c in config.clients if c.progress))
        self._ever_connected: set[str] = set()
        self._client_estops, self._client_holds = set[str](), set[str]()  # by client name
        self._nonzero: set[str] = set()  # named clients commanding motion now (SR-4.6)
        self._uid_of: dict[int, Uid] = {}  # connection -> the peer's uid (SR-8.5)
        self._unnamed: dict[tuple[Request, str], _Unnamed] = {}  # requests before hello
        self._limited = False  # the input's user is past its record budget (SR-8.5)
        self._charged: tuple[Uid] | None = None  # whom the step's records are charged to
        self._local_estop: Caller | None = None
        self._output_faults: dict[str, Details] = {}
        self._display = DisplayStore()
        self._budget = RecordBudget()  # records per user (SR-8.5)
        # Per-step scratch.
        self._frames: list[Message] = []
        self._refusals: list[Refusal] = []
        self._rearm: Rearm | None = None
        self._note: tuple[RecordNote, str] | None = None
        self._book.pulse(Cause(CauseKind.STARTUP), now)  # SR-1: start STOPPED, cause startup
        self.decision: Decision = self.handle(Tick(now))
        """The latest decision returned (the startup decision until the first input)."""

    # ----------------------------------------------------------------- public API

    @functools.cached_property
    def _battery_cause(self) -> Cause | None:
        """The cause the remote's battery raises (SR-8.12), or ``None`` when the core does not
        watch it (``on_estop_unavailable = "warn"``, or no battery check); computed once."""
        config = self._config
        if config.min_remote_battery <= 0:
            return None
        return _BATTERY_CAUSES.get(config.on_estop_unavailable)

    @functools.cached_property
    def _off_delays_ns(self) -> dict[str, int]:
        """Each category-1 output's delay (SR-1.4); the config is frozen: computed once."""
        return {o.name: o.off_delay_ns for o in self._config.outputs if o.off_delay_ms}

    @property
    def state(self) -> State:
        return self._state

    @property
    def config(self) -> SafetyConfig:
        return self._config

    def tick(self, now: int) -> Decision:
        """No input arrived by the deadline: let time pass to ``now``."""
        return self.handle(Tick(now))

    def canonical(self, now: int | None = None) -> Canonical:
        """The state as the exhaustive exploration compares it (``verify/``, docs/verification.md
        "The time abstraction"): every fact a later input can depend on, and every time kept
        as a clock clipped above the largest constant its guards compare it with. Two states
        with the same form answer every later input alike, ``now`` and the record's text
        aside. ``now`` (default: the latest input's) may only be later than that.

        Left out: the config and what is computed from it once, the per-step scratch, the
        record's sequence number and ``decision`` but for its deadline (``_NOT_CANONICAL``;
        ``tests/safety/test_canonical.py`` checks that every other attribute is read here).
        Two guards are not of the form ``age >= constant`` and are kept as facts or clocks of
        their own: the span of the takeover's run (first to last heartbeat, a fact once the
        run stops growing) and its rate (``_act_refusal``: a count against the age of its
        first heartbeat, kept as the age at which the count is allowed, clipped at
        ``RATE_SLACK_NS``: the one inexact clip, docs/verification.md).
        """
        now = self._now if now is None else max(now, self._now)
        book = self._book
        clocks: list[Clock] = []

        def keep(name: str, at: int | None, *limits: int) -> None:
            if at is not None:
                clocks.append(clock(name, at, now, *limits))

        run = self._run
        run_facts: object = None
        if run is not None:
            last_stop = book.last_stop_raised_ns
            run_facts = (
                min(run.heartbeats, TAKEOVER_MIN_HEARTBEATS),
                run.last_ns - run.first_ns >= TAKEOVER_DWELL_NS,
                last_stop is not None and run.last_ns < last_stop,  # SR-4.3 against the run
            )
            keep("run:first", run.first_ns, TAKEOVER_DWELL_NS)
            # The rate (rule 4) allows the run's count once ``now - first`` reaches this; the
            # one clock clipped below too, as a flood of heartbeats can push it back for ever.
            allowed = run.first_ns + VSC_MIN_INTERVAL_NS * (
                run.heartbeats - READ_TOGETHER_ALLOWANCE
            )
            slack = max(now - allowed, -RATE_SLACK_NS)
            clocks.append(
                clock("run:rate", now - slack, now, 0, VSC_MIN_INTERVAL_NS, RATE_SLACK_NS)
            )
        settling = self._settling
        if settling is not None:
            keep("settling:first", settling.first_ns, SETTLE_DWELL_NS)
        if self._held_mode is not None:
            keep("held_since", self._held_since, SETTLE_DWELL_NS)
        quiet = self._quiet
        if quiet is not None:
            keep("quiet", quiet[1], REFUSAL_QUIET_NS)
        keep("vsc:last", self._last_vsc_ns, self._vsc_timeout_ns)
        keep("key85:next", self._next_key85_ns, 0)
        keep("heartbeat:next", self._next_heartbeat_ns, 0, self._heartbeat_period_ns)
        keep("clear_since", book.stops_clear_since(), self._config.rearm_hold_ns)
        if self._off_delays_ns:  # SR-1.4: read only when an output has a delay
            delays = sorted(set(self._off_delays_ns.values()))
            keep("motion_off", self._motion_off_ns, *delays)
            keep("braking", self._braking_since, *delays)
        if self._steady:  # read only by the cheap path and step 1, after a normal step
            keep("decision:next", self.decision.next_deadline, 0)
        for name, beat in sorted(self._client_beat_ns.items()):
            keep(f"client:{name}", beat, self._client_timeout_ns[name])
        battery_low = None
        battery = self._battery
        if self._battery_cause is not None and battery is not None:  # SR-8.12: when watched
            # A report arriving judges the old one ``age > FRESH`` (report_stale): the clock
            # runs on 10 ms past the limit, so that an age exactly at it stays told apart.
            keep("battery:seen", battery[1], REMOTE_STATUS_FRESH_NS, BATTERY_SEEN_CLIP_NS)
            battery_low = battery[0] < self._config.min_remote_battery
        if self._battery_words is not None:  # SR-3.4: the condition's reason and its run
            keep("battery:words_since", self._battery_words_since, BATTERY_SETTLE_NS)
            keep("battery:good_since", self._battery_good_since, BATTERY_SETTLE_NS)
        proof_facts, proof_clocks = self._proof.canonical(now, self._key85)
        display_facts, display_clocks = self._display.canonical(now)
        clocks += [*proof_clocks, *display_clocks, *self._budget.canonical(now)]
        facts = (
            ("state", self._state),
            ("cheap_path", self.cheap_path),
            ("steady", self._steady),
            ("steady_estop", self._steady and self._steady_estop),
            ("causes", book.canonical()),
            ("link_open", self._link_open),
            ("link_fault", self._link_fault),
            ("vsc_mode", self._vsc_mode),
            ("vsc_estop_word", self._vsc_estop_word),
            ("remote_linked", self._remote_linked),
            ("key85", self._key85),
            ("held_mode", self._held_mode),
            ("run", run_facts),
            (
                "settling",
                None if settling is None else min(settling.heartbeats, TAKEOVER_MIN_HEARTBEATS),
            ),
            ("quiet", None if quiet is None else quiet[0]),
            ("connections", tuple(sorted(self._connections.items()))),
            ("by_name", tuple(sorted(self._by_name.items()))),
            ("beaten", tuple(sorted((n, b is None) for n, b in self._client_beat_ns.items()))),
            ("progress", self._progress.canonical()),
            ("ever_connected", tuple(sorted(self._ever_connected))),
            ("client_estops", tuple(sorted(self._client_estops))),
            ("client_holds", tuple(sorted(self._client_holds))),
            ("nonzero", tuple(sorted(self._nonzero))),
            ("uid_of", tuple(sorted(self._uid_of.items(), key=lambda item: item[0]))),
            (
                "unnamed",
                tuple(
                    sorted(
                        (kind.value, name, entry.uid, tuple(sorted(entry.holders)))
                        for (kind, name), entry in self._unnamed.items()
                    )
                ),
            ),
            ("local_estop", self._local_estop),
            ("output_faults", tuple(sorted(self._output_faults.items()))),
            ("battery_low", battery_low),
            ("battery_words", self._battery_words),
            ("battery_good", self._battery_good_since is not None),
            ("proof", proof_facts),
            ("display", display_facts),
        )
        return facts, tuple(clocks)

    _NOT_CANONICAL = frozenset(
        {
            # The config, and what is computed from it once (constants of the exploration).
            "_config",
            "_required",
            "_output_names",
            "_levels_by_state",
            "_off_delays_ns",
            "_vsc_timeout_ns",
            "_heartbeat_period_ns",
            "_client_timeout_ns",
            "_serial",
            "_battery_cause",
            # The reference every clock is measured from; the record's sequence number.
            "_now",
            "_sequence",
            # Per-step scratch, reset at the start of every step.
            "_frames",
            "_refusals",
            "_rearm",
            "_note",
            "_charged",
            "_limited",
            "_proof_outcome",
            "_arriving",
            "_taken_in",
        }
    )
    """Attributes ``canonical`` leaves out, and why (``decision`` is read for its deadline)."""

    cheap_path = True
    """Answer inputs that cannot change a decision without the full step (``_cheap``). The
    full path is the reference: ``tests/safety/test_cheap_path.py`` switches this off on one
    of two cores and checks that both give the same decisions for random inputs (SR-9.4)."""
    _steady = False  # the last step ended normally: its decision is the state's fixed point
    _steady_estop = 0  # the user heartbeat's byte from the conditions alone (no urgent raise)
    # SR-1.4: when the motion outputs last went off (RUN left), and, in a stop begun with power
    # on while a category-1 output may still be on, that time again.
    _motion_off_ns: int | None = None
    _braking_since: int | None = None
    # SR-8.12: the last remote status's battery percent and when it came, kept while watched.
    _battery: tuple[int, int] | None = None
    # SR-3.4: the battery's condition: its reason (``None``: clear) and since when it has had
    # it, and the first report of the unbroken run of good reports that may end it.
    _battery_words: str | None = None
    _battery_words_since = 0
    _battery_good_since: int | None = None
    # Per-step scratch (SR-8.12): the step's input is a watched remote status, and it has been
    # taken in (a report is taken in before the old one is judged stale).
    _arriving = False
    _taken_in = False

    def handle(self, event: Event) -> Decision:
        """Feed one input; never raises (a failure of the core stops with ``internal``)."""
        try:
            cheap = self._cheap(event) if self._steady and self.cheap_path else None
            self.decision = cheap if cheap is not None else self._step(event)
        except Exception as error:  # the core must never raise: stop with ``internal`` instead
            self._steady = False
            self.decision = self._fail_safe(event, error)
        return self.decision

    def _cheap(self, event: Event) -> Decision | None:
        """The decision for an input that cannot change one, or ``None`` for the full step.

        Cheap are a :class:`Tick`, an inert VSC message (:data:`INERT_VSC_MESSAGES`) and a VSC
        heartbeat with the same mode and e-stop word as the last, while the last step ended
        normally on a fixed point of the table and, either before the previous decision's
        ``next_deadline`` or when the user heartbeat is the only thing due
        (:meth:`_only_heartbeat_due`). Then no timeout expires and no other frame is due
        (``_next_deadline`` lists every one of them), so step 1 of the full path changes
        nothing; such an input changes no condition (a heartbeat after an expired timeout
        clears ``vsc_link_lost`` and is not cheap, and so is one while the mode's hold names
        another mode, which it renames after the dwell) (step 3), asks no re-arm (the mode did not
        change, step 4), so the state is the previous step's fixed point (step 5) and no
        record follows (step 6); the one frame is the user heartbeat at its cadence, with the
        byte of the conditions (SR-5.1, SR-5.2). What can differ is ``now``, the facts the
        heartbeat moves (its time, the takeover run) and so ``next_deadline``, which are
        computed as the full path does (SR-2.2, SR-2.11: the heartbeat still restarts the link
        deadline). docs/performance.md "The cheap path".
        """
        if type(event) not in _CHEAP_EVENTS or self._proof.phase not in _SETTLED_PROOF:
            return None  # a proof test pending or running moves with time and heartbeats
        if self._pending_ends():
            return None  # a deferred end moves with time (SR-8.5)
        if self._braking_since is not None:
            return None  # a category-1 output goes off with time (SR-1.4)
        previous = self.decision
        now = event.now if event.now > self._now else self._now
        beat_due = now >= previous.next_deadline
        if (beat_due and not self._only_heartbeat_due(now)) or not self._fixed_point():
            return None
        if type(event) is VscReceived:
            message = event.message
            if not self._link_open:
                return None  # the full path refuses it (LINK_NOT_OPEN)
            if type(message) is VscHeartbeat:
                last = self._last_vsc_ns
                if (
                    last is None  # the first heartbeat clears "never seen" (SR-2.2)
                    or now - last >= self._vsc_timeout_ns  # this one clears the timeout
                    or message.mode != self._vsc_mode
                    or message.estop != self._vsc_estop_word
                    or self._settling is not None  # it may end the hold (SR-3.3)
                    # the hold names another mode: after the dwell it takes this one's name
                    or (self._held_mode is not None and message.mode != self._held_mode)
                ):
                    return None
            elif type(message) not in _INERT_TYPES or (
                self._battery_cause is not None and type(message) is RemoteStatus
            ):
                return None
            self._now = now
            if self._on_vsc(event, now) is not None:  # cannot happen: the mode is unchanged
                raise AssertionError("a heartbeat of an unchanged mode asked for a re-arm")
        else:
            self._now = now
        frames: tuple[Message, ...] = ()
        estop = self._steady_estop
        if beat_due:
            # What ``_emit_link_frames`` does for a heartbeat that is not urgent (SR-5.1).
            frames = (UserHeartbeat(estop),)
            self._proof.sent(now)
            beat = self._next_heartbeat_ns
            assert beat is not None  # _only_heartbeat_due checked it
            self._next_heartbeat_ns = next_due(beat, now, self._heartbeat_period_ns)
        # Every other field as the previous decision has it, as the full step would compute it
        # again; ``tests/safety/test_cheap_heartbeat.py`` checks that this lists every field.
        return Decision(
            now=now,
            state=previous.state,
            causes=previous.causes,
            outputs=previous.outputs,
            heartbeat_estop=estop,
            next_deadline=self._next_deadline(now),
            frames=frames,
            records=(),
            refusals=(),
            rearm=None,
            prooftest=previous.prooftest,
        )

    def _only_heartbeat_due(self, now: int) -> bool:
        """Whether, of everything ``_next_deadline`` lists, the user heartbeat is due at
        ``now`` and nothing else is (and the proof test does not withhold it): the time at
        which the full step's only work is to send it."""
        beat = self._next_heartbeat_ns
        if not self._link_open or beat is None or now < beat or self._proof.withholding:
            return False
        last = self._last_vsc_ns
        if last is None or now - last >= self._vsc_timeout_ns:
            return False  # the VSC's timeout expires: the full path raises vsc_link_lost
        for name, client_beat in self._client_beat_ns.items():
            if client_beat is not None and now - client_beat >= self._client_timeout_ns[name]:
                return False
        key85 = self._next_key85_ns
        display = self._display.next_due()
        proof = self._proof.next_deadline(self._key85)
        stale = self._battery_stale_at()
        return (
            (stale is None or stale > now)
            and (key85 is None or key85 > now)
            and (display is None or display > now)
            and (proof is None or proof > now)
        )

    # ----------------------------------------------------------------- the step

    def _fixed_point(self) -> bool:
        """Whether the table keeps the state where it is when nothing changes (SR-1): true for
        every legal row a step can end on; checked anyway, so that a table that ever says
        otherwise is met by the full step, which turns its refusal into ``internal``."""
        book = self._book
        if book.any_latched():
            situation = Situation.STOP
        else:
            situation = Situation.HOLD if book.any_hold() else Situation.CLEAR
        try:
            return next_state(self._state, situation) is self._state
        except IllegalTransition:
            return False

    def _step(self, event: object) -> Decision:
        steady, self._steady = self._steady and self.cheap_path, False
        self._frames, self._refusals = [], []
        self._rearm = None
        self._note = None
        self._charged, self._limited = None, False
        self._arriving = self._taken_in = False
        request: _RearmRequest | None = None
        if not is_event(event):
            self._refuse(RefusalReason.NOT_AN_EVENT, type(event).__name__, event)
            now = self._now
            event = Tick(now)
        else:
            # A clock that goes back is treated as not moving: no deadline is ever un-expired.
            now = self._now = max(self._now, event.now)
            self._arriving = (
                self._battery_cause is not None
                and type(event) is VscReceived
                and type(event.message) is RemoteStatus
            )
            if not (
                # Before the previous decision's deadline, after a normal step, with the proof
                # test settled, time passing changes no condition (the cheap path's argument,
                # ``_cheap``): step 1 would recompute them to the same (SR-9.4).
                steady and now < self.decision.next_deadline and self._proof.phase in _SETTLED_PROOF
            ):
                self._refresh(now)  # 1. time passes
            # 2. the event, unless its user is past its record budget and it would take a
            # reason to stop away (SR-8.5)
            # Whom to charge is read before the event is applied (a disconnection forgets
            # its connection's uid).
            self._charged = (self._uid(event),) if isinstance(event, _CLIENT_EVENTS) else None
            self._limited = self._charged is not None and self._budget.exhausted(
                self._charged[0], now
            )
            if self._limited and isinstance(event, _LIMITED_EVENTS):
                self._refuse(RefusalReason.RATE_LIMITED, type(event).__name__, event)
            else:
                request = self._apply(event, now)
        self._end_unnamed_due(now)
        self._refresh(now)  # 3. conditions
        if request is not None:  # 4. re-arm (SR-4)
            refused = len(self._refusals)
            self._check_rearm(request, event, now)
            if len(self._refusals) > refused:  # every refused re-arm is recorded (docs/record.md)
                self._note = (RecordNote.REARM_REFUSED, self._refusals[-1].message)
        if not self._nonzero:
            self._display.end_notice()  # nothing commands motion any more (SR-4.6)
        previous = self._state
        self._state = self._transition(now)  # 5. the table
        decision = self._finish(event, previous, now)  # 6.
        self._steady = True  # a normal end: the next input may take the cheap path
        return decision

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
        self._emit_link_frames(now, estop, urgent=raised_user_estop)
        causes = self._book.snapshot()
        proof, self._proof_outcome = self._proof_outcome, None
        # A note of the event's own (a commissioning) and a proof test's outcome in one step are
        # two records: each kind is what its record is about (SR-7.1).
        proof_apart = proof if proof is not None and self._note is not None else None
        if proof is not None and self._note is None:
            self._note = (RecordNote.PROOFTEST, proof.text)  # a record even if nothing changed
        records: tuple[Record, ...] = ()
        if changes or previous is not self._state or self._note is not None:
            note, reason = self._note or (None, "")
            self._sequence += 1
            if self._charged is not None:
                self._budget.charge(self._charged[0], now)
            carried = None if proof_apart is not None else proof
            records = (
                Record(
                    sequence=self._sequence,
                    monotonic_ns=now,
                    previous=previous,
                    state=self._state,
                    causes=causes,
                    changes=changes,
                    trigger=event,
                    rearm=self._rearm,
                    note=note,
                    reason=reason,
                    prooftest=carried,
                ),
            )
        if proof_apart is not None:
            self._sequence += 1
            records += (
                Record(
                    sequence=self._sequence,
                    monotonic_ns=now,
                    previous=self._state,
                    state=self._state,
                    causes=causes,
                    changes=(),
                    trigger=event,
                    rearm=None,
                    note=RecordNote.PROOFTEST,
                    reason=proof_apart.text,
                    prooftest=proof_apart,
                ),
            )
        return Decision(
            now=now,
            state=self._state,
            causes=causes,
            outputs=self._outputs(previous, now),
            heartbeat_estop=estop,
            next_deadline=self._next_deadline(now),
            frames=tuple(self._frames),
            records=records,
            refusals=tuple(self._refusals),
            rearm=self._rearm,
            prooftest=self._proof.status(),
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
            decision = self._finish(event if is_event(event) else Tick(now), previous, now)
            # The core's own failure is a stop of category 0 (SR-1.4): no output stays on.
            self._motion_off_ns = self._braking_since = None
            return dataclasses.replace(decision, outputs=self._levels(State.STOPPED))
        except Exception:  # the last line of defence: all off, ask again soon
            self._state = State.STOPPED
            self._motion_off_ns = self._braking_since = None  # category 0 (SR-1.4)
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

    def _apply(self, event: Event, now: int) -> _RearmRequest | None:
        """Step 2: the event updates the facts, through its handler in :data:`_HANDLERS`
        (one per event type; ``tests/safety/test_dispatch.py`` checks that none is missing)."""
        handler = _HANDLERS.get(type(event))
        if handler is None:  # a type with no handler is not ignored: the core stops (SR-0)
            raise LookupError(f"no handler for {type(event).__name__}")
        return handler(self, event, now)

    def _on_tick(self, event: Tick, now: int) -> None:
        """Time passing is step 1's and step 3's work; a tick brings no fact of its own."""

    def _on_command(self, event: ClientCommand, now: int) -> None:
        """A named client's declaration of its commanded motion (SR-4.6), kept until it
        declares again or its connection ends; before hello it is refused (``NO_HELLO``)."""
        name = self._named(event, event.connection)
        if name is None:
            return
        if event.nonzero:
            self._nonzero.add(name)
        else:
            self._nonzero.discard(name)

    def _on_client_heartbeat(self, event: ClientHeartbeat, now: int) -> None:
        name = self._named(event, event.connection)
        if name is None or name not in self._client_beat_ns:
            return
        stale = self._progress.beat(name, event.progress)
        if stale is None:
            self._client_beat_ns[name] = now
        else:  # SR-8.16: a duplicate, a replay or a missing value extends no deadline
            self._refuse(stale, f"{name} progress {event.progress}", event)

    def _on_local_estop(self, event: LocalEstop, now: int) -> None:
        # Past the budget an active local e-stop keeps its caller: a new one would only
        # change the record's words (SR-8.5); the stop stands either way.
        if self._local_estop is None or not self._limited:
            self._local_estop = event.caller

    def _on_local_release(self, event: LocalRelease, now: int) -> None:
        if self._local_estop is None:
            self._refuse(RefusalReason.NOTHING_TO_RELEASE, "local_estop", event)
        self._local_estop = None

    def _on_reset(self, event: ResetRequest, now: int) -> _RearmRequest:
        return _RearmRequest(RearmKind.LOCAL_RESET, event.caller)

    def _on_internal_fault(self, event: InternalFault, now: int) -> None:
        self._book.pulse(
            Cause(CauseKind.INTERNAL), now, make_details([("reason", event.reason[:200])])
        )

    def _on_shutdown(self, event: Shutdown, now: int) -> None:
        # SR-7.14: the daemon exits, its outputs already off; the stop is the core's like any
        # other, so its record continues the sequence and a replay makes it again (SR-7.13).
        # Momentary and latched, as ``internal``: in RUN or HOLD a stop, in STOPPED a cause
        # raised, so every exit of the daemon is a record.
        reason = event.reason[:60] if event.reason else "unknown"
        self._book.pulse(Cause(CauseKind.SHUTDOWN, reason), now, ())

    def _on_commissioned(self, event: Commissioned, now: int) -> None:
        key85 = "no answer" if event.key85 is None else str(event.key85)
        result = f"key85={key85} remote_status={'on' if event.remote_status else 'not seen'}"
        self._note = (RecordNote.COMMISSIONED, result)

    def _on_stoptested(self, event: StopTested, now: int) -> None:
        # Measured and judged by the daemon (SR-12.1); the core gives it its place in the
        # record, so that a replay makes it again (SR-7.13).
        self._note = (RecordNote.STOPTEST, event.result.text)

    def _on_display(self, event: DisplayUpdate, now: int) -> None:
        reason = self._display.accept(event.message)
        if reason is not None:
            self._refuse(reason, f"key {event.message.key}", event)

    def _on_vsc(self, event: VscReceived, now: int) -> _RearmRequest | None:
        message = event.message
        if not self._link_open:
            self._refuse(RefusalReason.LINK_NOT_OPEN, type(message).__name__, event)
            return None
        request = None
        if isinstance(message, VscHeartbeat):
            # SR-2: only a valid heartbeat is liveness; the daemon passes only checked frames.
            previous_ns, self._last_vsc_ns = self._last_vsc_ns, now
            if previous_ns is not None and now - previous_ns >= self._vsc_timeout_ns:
                # The VSC was silent: it may have rebooted (a firmware update can reset key
                # 85), so its watchdog is proven again (docs/safety.md "The proof test").
                self._proof.restart()
            self._proof.heartbeat(message.mode, message.estop, now)
            self._vsc_estop_word = message.estop
            unbroken = previous_ns is not None and now - previous_ns < self._vsc_timeout_ns
            request = self._on_mode(message.mode, now, unbroken)
            self._vsc_mode = message.mode
            linked = VscMode.parse(message.mode) in LINKED_MODES
            if linked and not self._remote_linked:
                self._display.relink()
            self._remote_linked = linked
        elif isinstance(message, RemoteStatus):
            if self._battery_cause is not None:
                self._battery = (message.battery_level, now)
                self._taken_in = True
        elif isinstance(message, FeedbackSet):
            if message.key == FeedbackKey.USER_ESTOP_TIMEOUT:
                self._key85 = message.value
                if message.value == 1:
                    self._next_key85_ns = None
            else:
                self._display.edited_on_remote(message)
        return request

    def _on_mode(self, mode: int, now: int, unbroken: bool) -> _RearmRequest | None:
        """The mode of a VSC heartbeat at ``now`` (``unbroken``: less than ``vsc_timeout``
        after the one before): the takeover run (SR-4.5) and the mode's hold (SR-3)."""
        request = None
        if mode == VscMode.OPERATIONAL:
            previous = self._vsc_mode
            if previous is not None and previous != VscMode.OPERATIONAL:
                # SR-4: the operator's takeover, not Operational followed by Operational;
                # whether the run before it is an operator's act is rule 4 (_check_rearm).
                request = _RearmRequest(RearmKind.TAKEOVER, None, self._run)
            self._settle(now, unbroken)
            self._run = None
        else:
            self._hold_mode(mode, now)
            if self._run is None or not unbroken:
                self._run = _Run(now, now, 1)  # rule 4: a silent gap starts the run again
            else:
                self._run = self._run.then(now)
        return request

    def _hold_mode(self, mode: int, now: int) -> None:
        """A heartbeat in ``mode``, not Operational: the hold names it (SR-3.1). A hold that
        has named another mode for less than the dwell keeps that name, so a VSC flapping
        between two such modes renames it at most once per 200 ms (SR-3.3)."""
        self._settling = None
        if self._held_mode is None or (
            mode != self._held_mode and now - self._held_since >= SETTLE_DWELL_NS
        ):
            self._held_mode, self._held_since = mode, now

    def _settle(self, now: int, unbroken: bool) -> None:
        """An Operational heartbeat at ``now`` while the mode's hold may be on (SR-3.3): it
        ends at once when the run before it was an operator's act (re-arm rule 4: a pause and
        its end), else once Operational has been reported for the dwell, unbroken."""
        if self._held_mode is None:
            return
        settling = self._settling
        if settling is None:
            run = self._run
            if run is not None and self._act_refusal(run) is None:
                self._held_mode = None  # the operator resumed: no wait
                return
            self._settling = _Run(now, now, 1)
            return
        self._settling = settling = settling.then(now) if unbroken else _Run(now, now, 1)
        if (
            settling.last_ns - settling.first_ns >= SETTLE_DWELL_NS
            and settling.heartbeats >= TAKEOVER_MIN_HEARTBEATS
        ):
            self._held_mode = self._settling = None

    def _on_link_opened(self, event: LinkOpened, now: int) -> None:
        # SR-4: a reconnect of the VSC is a new start. Liveness starts over ("never seen since
        # link open" counts as lost, SR-2) and key 85 is read back again (SR-5).
        self._link_open = True
        if self._config.transport is not Transport.HID:
            self._link_fault = None
        self._last_vsc_ns = None
        self._vsc_mode = None
        self._run = None
        self._held_mode = self._settling = None
        self._remote_linked = False
        self._key85 = None
        self._next_key85_ns = now if self._serial else None
        self._next_heartbeat_ns = now if self._serial else None
        self._proof.restart()  # SR-4.4 a new start: the VSC's watchdog is proven again

    def _on_link_down(self, event: LinkBroken | LinkClosed, now: int) -> None:
        word = "broken" if isinstance(event, LinkBroken) else "closed"
        self._link_open = False
        self._link_fault = f"{word}: {event.reason}"[:200]
        self._last_vsc_ns = None
        self._vsc_mode = None
        self._run = None
        self._held_mode = self._settling = None
        self._remote_linked = False
        self._next_key85_ns = None
        self._next_heartbeat_ns = None
        self._proof.restart()

    def _on_prooftest(self, event: ProofTestRequest, now: int) -> None:
        """``srcsctl prooftest``: admins only, only while STOPPED, one at a time."""
        if self._proof.policy is ProofTestPolicy.OFF:
            self._refuse(RefusalReason.PROOFTEST_NOT_POSSIBLE, self._config.transport.value, event)
        elif not event.caller.admin:
            self._refuse(RefusalReason.NOT_ADMIN, event.caller.name[:60], event)
        elif self._state is not State.STOPPED:
            self._refuse(RefusalReason.PROOFTEST_NOT_STOPPED, self._state.name, event)
        elif self._proof.running:
            self._refuse(RefusalReason.PROOFTEST_RUNNING, self._proof.phase.value, event)
        else:
            self._proof.restart()

    def _on_connected(self, event: ClientConnected, now: int) -> None:
        if event.connection in self._connections:
            self._refuse(RefusalReason.DUPLICATE_CONNECTION, str(event.connection), event)
            return
        self._connections[event.connection] = None
        self._uid_of[event.connection] = event.uid

    def _on_hello(self, event: ClientHello, now: int) -> None:
        connection, name = event.connection, event.name
        if connection not in self._connections:
            self._refuse(RefusalReason.UNKNOWN_CONNECTION, str(connection), event)
        elif self._connections[connection] is not None:
            self._refuse(RefusalReason.ALREADY_NAMED, str(self._connections[connection]), event)
        elif self._wrong_user(event):
            # docs/safety.md "Clients bound to a user": refused and recorded, before the name
            # is looked up, so an attempt is recorded also while the real client is connected.
            who = "an unknown caller" if event.caller is None else f"uid {event.caller.uid}"
            self._refuse(RefusalReason.WRONG_USER, f"{name} from {who}", event)
            self._note = (RecordNote.HELLO_REFUSED, self._refusals[-1].message)
        elif not isinstance(name, str) or NAME_PATTERN.fullmatch(name) is None:
            self._refuse(RefusalReason.BAD_NAME, repr(name)[:60], event)
        elif name in self._by_name:
            self._refuse(RefusalReason.NAME_IN_USE, name, event)
        else:
            self._connections[connection] = name
            self._by_name[name] = connection
            self._ever_connected.add(name)
            if name in self._required:
                # SR-4: a client's (re)connection is a new start; it must send a heartbeat.
                self._client_beat_ns[name] = None
                self._progress.restart(name)  # SR-8.16: its counter starts again

    def _wrong_user(self, event: ClientHello) -> bool:
        spec = self._required.get(event.name) if isinstance(event.name, str) else None
        if spec is None or spec.uid is None:
            return False
        return event.caller is None or event.caller.uid != spec.uid

    def _named(self, event: Event, connection: int) -> str | None:
        if connection not in self._connections:
            self._refuse(RefusalReason.UNKNOWN_CONNECTION, str(connection), event)
            return None
        name = self._connections[connection]
        if name is None:
            self._refuse(RefusalReason.NO_HELLO, str(connection), event)
        return name

    def _unnamed_name(self, connection: int) -> str:
        """Where a request before hello is filed (choice 11): under the peer's uid, so that
        no number of connections multiplies its records (SR-8.5); under the connection when
        the uid is not known. '#' cannot appear in a configured name (NAME_PATTERN)."""
        uid = self._uid_of.get(connection)
        return f"#{connection}" if uid is None else f"#uid{uid}"

    def _requests(self, kind: Request) -> set[str]:
        return self._client_estops if kind is Request.ESTOP else self._client_holds

    def _on_request(self, event: ClientEstop | ClientHold, now: int) -> None:
        # An e-stop or hold is always honoured, even before hello: it can only add a reason
        # to stop (SR-0). Before hello it is filed under the user ("#uid<UID>"), held by
        # every connection of that user that asked for it.
        connection = event.connection
        kind = Request.ESTOP if isinstance(event, ClientEstop) else Request.HOLD
        name = self._connections.get(connection)
        if name is None:
            name = self._unnamed_name(connection)
            entry = self._unnamed.setdefault(
                (kind, name), _Unnamed(self._uid_of.get(connection), set())
            )
            entry.holders.add(connection)
        self._requests(kind).add(name)

    def _on_release(self, event: ClientRelease, now: int) -> None:
        connection, kind = event.connection, event.request
        requests = self._requests(kind)
        name = self._connections.get(connection)
        released = name is not None and name in requests
        if released:
            requests.discard(name)
        unnamed = self._unnamed_name(connection)
        entry = self._unnamed.get((kind, unnamed))
        if entry is not None and connection in entry.holders:
            released = True
            entry.holders.discard(connection)
            if not entry.holders:
                self._end_unnamed(kind, unnamed)
        if not released:
            self._refuse(RefusalReason.NOTHING_TO_RELEASE, kind.value, event)

    def _end_unnamed(self, kind: Request, name: str) -> None:
        del self._unnamed[(kind, name)]
        self._requests(kind).discard(name)

    def _pending_ends(self) -> list[tuple[Request, str]]:
        """Requests before hello whose connections all closed while their user was past its
        record budget: they end once it allows (SR-8.5)."""
        return [key for key, entry in self._unnamed.items() if not entry.holders]

    def _end_unnamed_due(self, now: int) -> None:
        """End the deferred requests whose user is within its budget again, charging it the
        record their end makes (SR-8.5)."""
        for kind, name in self._pending_ends():
            uid = self._unnamed[(kind, name)].uid
            if not self._budget.exhausted(uid, now):
                self._end_unnamed(kind, name)
                self._budget.charge(uid, now)

    def _on_disconnected(self, event: ClientDisconnected, now: int) -> None:
        connection = event.connection
        if connection not in self._connections:
            self._refuse(RefusalReason.UNKNOWN_CONNECTION, str(connection), event)
            return
        name = self._connections.pop(connection)
        # Requests made before hello end with the last connection that asked for them
        # (nobody else can release them); their stop stays latched. Past the user's record
        # budget the end waits until the budget allows (SR-8.5): the robot stays held or
        # stopped meanwhile, the safe side. Named requests wait for a client of that name.
        for (kind, unnamed), entry in list(self._unnamed.items()):
            entry.holders.discard(connection)
            if not entry.holders and not self._limited:
                self._end_unnamed(kind, unnamed)
        self._uid_of.pop(connection, None)
        if name is not None:
            del self._by_name[name]
            self._nonzero.discard(name)  # the process commanding it is gone (SR-4.6)
            if name in self._client_beat_ns:
                self._client_beat_ns[name] = None
                self._progress.restart(name)

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
            # SR-6: the condition clears when a later read-back matches what was set.
            self._output_faults.pop(event.output, None)

    def _uid(self, event: Event) -> Uid:
        """Whom the records a client's input causes are charged to (SR-8.5; docs/safety.md
        "How many records the clients may cause"): the user at the other end, whatever its
        connection, name or process, as the kernel reported it."""
        caller = getattr(event, "caller", None)
        if isinstance(caller, Caller):
            return caller.uid
        if isinstance(event, ClientConnected):
            return event.uid
        connection = getattr(event, "connection", None)
        return self._uid_of.get(connection) if isinstance(connection, int) else None

    def _refuse(self, reason: RefusalReason, detail: str, event: object) -> None:
        self._refusals.append(Refusal(reason, detail, event))

    # ----------------------------------------------------------------- conditions

    def _refresh(self, now: int) -> None:
        """Recompute every lasting condition from the facts (SR-2, SR-3). A condition's
        details are built only when it holds: the book reads them only then."""
        self._advance_proof(now)
        book, config = self._book, self._config
        hid = config.transport is Transport.HID
        fault = "hid is not a safety channel" if hid else self._link_fault
        book.set(
            _TRANSPORT_FAULT,
            fault is not None,
            now,
            make_details([("reason", fault)]) if fault else (),
        )
        last = self._last_vsc_ns
        lost = last is None or now - last >= self._vsc_timeout_ns  # ">=": 200 ms is lost
        book.set(
            _VSC_LINK_LOST,
            lost,
            now,
            make_details(
                [
                    ("reason", "no heartbeat since link open" if last is None else "timeout"),
                    ("timeout_ms", str(config.vsc_timeout_ns // NS_PER_MS)),
                ]
            )
            if lost
            else (),
        )
        word = self._vsc_estop_word
        book.set(
            _VSC_ESTOP,
            word != 0,
            now,
            make_details([("sources", _sources(word)), ("word", f"0x{word:08x}")]) if word else (),
        )
        watchdog_off = self._serial and config.require_watchdog and self._key85 != 1
        book.set(
            _VSC_WATCHDOG_OFF,
            watchdog_off,
            now,
            make_details([("key85", "no answer" if self._key85 is None else str(self._key85))])
            if watchdog_off
            else (),
        )
        proof = self._proof
        untested = proof.untested
        book.set(_VSC_WATCHDOG_UNTESTED, untested, now, proof.details() if untested else ())
        book.sync(CauseKind.CLIENT_LOST, self._lost_clients(now), now)
        book.sync(
            CauseKind.CLIENT_ESTOP,
            {Cause(CauseKind.CLIENT_ESTOP, n): () for n in self._client_estops},
            now,
        )
        book.set(
            _LOCAL_ESTOP,
            self._local_estop is not None,
            now,
            _caller_details(self._local_estop),
        )
        book.sync(
            CauseKind.OUTPUT_FAULT,
            {Cause(CauseKind.OUTPUT_FAULT, n): d for n, d in self._output_faults.items()},
            now,
        )
        mode = self._held_mode
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
        battery_cause = self._battery_cause
        if battery_cause is not None:
            words = self._judge_battery(now)
            book.set(
                battery_cause,
                words is not None,
                now,
                make_details([("reason", words)]) if words is not None else (),
            )

    def _judge_battery(self, now: int) -> str | None:
        """The battery's condition at ``now`` (SR-8.12, SR-3.4): its reason, or ``None``.

        Raised in the step that sees the battery missing. It ends only at a good report that
        completes an unbroken run of good reports (none missing between them) whose first and
        last are at least ``BATTERY_SETTLE_NS`` apart; while it lasts, a report renames it at
        most once per that, and a report going stale at once (a silence of 3.5 s is its own
        bound). Both happen only at a report or at the report's deadline, steps the cheap path
        never takes, so the two paths agree (SR-9.4). So the condition ends at most once per
        second, whatever a VSC reports, and a 50 Hz flap around the minimum holds once."""
        battery = self._battery
        level, seen = (None, None) if battery is None else battery
        taken_in = self._taken_in
        missing = battery_missing(
            now,
            level,
            seen,
            self._config.min_remote_battery,
            arriving=self._arriving and not taken_in,  # SR-8.12: the report first
        )
        words = self._battery_words
        if missing is not None:
            self._battery_good_since = None  # the good run is broken
            if (
                words is None
                or missing == stale_words() != words
                or (
                    missing != words
                    and taken_in
                    and now - self._battery_words_since >= BATTERY_SETTLE_NS
                )
            ):
                self._battery_words, self._battery_words_since = missing, now
        elif words is not None and taken_in:
            first = self._battery_good_since
            if first is None:
                self._battery_good_since = now
            elif now - first >= BATTERY_SETTLE_NS:
                self._battery_words = self._battery_good_since = None
        return self._battery_words

    def _battery_stale_at(self) -> int | None:
        """When the last battery report stops counting (SR-8.12), if the core watches it."""
        battery = self._battery
        if self._battery_cause is None or battery is None:
            return None
        return battery[1] + REMOTE_STATUS_FRESH_NS

    def _advance_proof(self, now: int) -> None:
        """Start, abort or time out the proof test (docs/safety.md "The proof test"). It runs
        only while STOPPED, with the VSC heard and nothing of ours asking it to stop (the
        heartbeat's byte at 0, so bits 6-7 are the watchdog's alone, PR-2.6)."""
        proof = self._proof
        if proof.policy is ProofTestPolicy.OFF:
            return
        heard = (
            self._link_open
            and self._last_vsc_ns is not None
            and now - self._last_vsc_ns < self._vsc_timeout_ns
        )
        stopped = self._state is State.STOPPED
        # SR-8.15: a required client not there yet is no reason to wait (its service may
        # start behind ``srcsctl wait-ready``, which waits for this test).
        calm = not self._book.user_estop(proof.quiet(stopped)) and self._local_estop is None
        if proof.running and not (heard and calm and stopped):
            proof.abort()  # our own stop must reach the VSC at once (SR-5.2)
        ready = heard and calm and stopped and self._vsc_estop_word & USER_BITS == 0
        proof.advance(now, ready, self._key85, self._vsc_mode)
        outcome = proof.take_outcome()
        if outcome is not None:
            self._proof_outcome = outcome
            if not outcome.passed and proof.policy is ProofTestPolicy.RECORD:
                # The record policy: a failure is a momentary stop, latched until a re-arm.
                self._book.pulse(
                    Cause(CauseKind.VSC_WATCHDOG_UNTESTED),
                    now,
                    make_details([("observed", outcome.text)]),
                )

    def _lost_clients(self, now: int) -> dict[Cause, Details]:
        lost: dict[Cause, Details] = {}
        for name, spec in self._required.items():
            if name not in self._by_name:
                reason = "disconnected" if name in self._ever_connected else "never connected"
            else:
                beat = self._client_beat_ns.get(name)
                # SR-8.16: heartbeats that came but did not count are named as such.
                stale = self._progress.stale(name)
                if beat is None:
                    reason = stale or "no heartbeat since hello"
                elif now - beat >= spec.timeout_ns:  # ">=": a beat 500 ms late is too late
                    reason = stale or "timeout"
                else:
                    continue
            lost[Cause(CauseKind.CLIENT_LOST, name)] = make_details(
                [("reason", reason), ("timeout_ms", str(spec.timeout_ms))]
            )
        return lost

    # ----------------------------------------------------------------- re-arm (SR-4)

    def _check_rearm(self, request: _RearmRequest, event: Event, now: int) -> None:
        takeover = request.kind is RearmKind.TAKEOVER
        if takeover and self._state is not State.STOPPED:
            return  # a takeover outside STOPPED is just the remote leaving pause (SR-3)
        refusal = self._rearm_refusal(request, now)
        if refusal is None:
            self._quiet = None
            self._book.release_latches()
            self._rearm = Rearm(request.kind, request.caller)
            return
        reason, detail = refusal
        if reason is RefusalReason.COMMAND_NONZERO:
            self._display.notice(self._notice_rows())  # tell the operator (SR-4.6)
        if takeover:
            # The same takeover refusal again within a second is not reported (a flapping
            # VSC, docs/safety.md "Re-arming"); a new reason always is. A local reset always
            # gets its answer: a person asked.
            quiet = self._quiet
            if quiet is not None and quiet[0] is reason and now - quiet[1] < REFUSAL_QUIET_NS:
                return
            self._quiet = (reason, now)
        self._refuse(reason, detail, event)

    def _rearm_refusal(self, request: _RearmRequest, now: int) -> tuple[RefusalReason, str] | None:
        """Why the re-arm is refused, or ``None`` when every rule of SR-4 holds."""
        takeover = request.kind is RearmKind.TAKEOVER
        if not takeover:
            caller = request.caller
            if not self._config.local_reset:
                return RefusalReason.LOCAL_RESET_DISABLED, ""
            if caller is None or not caller.admin:
                return RefusalReason.NOT_ADMIN, caller.name if caller else ""
            if self._state is not State.STOPPED:
                return RefusalReason.NOT_STOPPED, self._state.name
        active = self._book.active_stops()
        if active:
            # Safe choice: a re-arm while a stop condition is active does not count, even
            # later; it must be given after the conditions clear.
            return RefusalReason.CONDITIONS_ACTIVE, ", ".join(c.name for c in active)
        if takeover:
            refusal = self._takeover_refusal(request.run)
            if refusal is not None:
                return refusal
        clear_since = self._book.stops_clear_since()
        hold = self._config.rearm_hold_ns
        if clear_since is None or now - clear_since < hold:
            clear_ms = 0 if clear_since is None else (now - clear_since) // NS_PER_MS
            return (
                RefusalReason.HOLD_TIME_NOT_ELAPSED,
                f"clear for {clear_ms} ms of {hold // NS_PER_MS} ms",
            )
        if self._nonzero:
            # SR-4.6, checked last: the re-arm breaks no other rule, and the operator is told
            # the one thing left to do.
            return RefusalReason.COMMAND_NONZERO, ", ".join(sorted(self._nonzero))
        return None

    def _notice_rows(self) -> Notice:
        """The remote's text page while a re-arm is refused for a non-zero command (SR-4.6):
        what happened, who commands motion, what to do (20 characters a row)."""
        names = sorted(self._nonzero)
        more = f" +{len(names) - 1}" if len(names) > 1 else ""
        who = names[0][: NOTICE_WIDTH - len(more)] + more
        return ("NOT RE-ARMED", "COMMAND NOT ZERO:", who, "ZERO IT, TAKE OVER")

    def _takeover_refusal(self, run: _Run | None) -> tuple[RefusalReason, str] | None:
        """Re-arming rules 2-4 for a takeover: is the run before this Operational heartbeat an
        operator's act (docs/safety.md "Re-arming")? ``self._now`` is the Operational one."""
        last_stop = self._book.last_stop_raised_ns
        if run is None or (last_stop is not None and run.last_ns < last_stop):
            # Rule 2 and 3: the non-Operational heartbeat must come after the last stop began.
            return RefusalReason.NEW_CAUSE_DURING_REARM, ""
        return self._act_refusal(run)

    def _act_refusal(self, run: _Run) -> tuple[RefusalReason, str] | None:
        """Re-arming rule 4: why the non-Operational run before this Operational heartbeat
        (``self._now``) is no operator's act, or ``None`` when it is one."""
        span = run.last_ns - run.first_ns
        if span < TAKEOVER_DWELL_NS:  # rule 4: two heartbeats at least the dwell apart
            beats = f"{run.heartbeats} heartbeat{'s' if run.heartbeats != 1 else ''}"
            return (
                RefusalReason.TAKEOVER_TOO_SHORT,
                f"not Operational for {span // NS_PER_MS} ms in {beats}; "
                f"{TAKEOVER_DWELL_NS // NS_PER_MS} ms needed",
            )
        if run.heartbeats < TAKEOVER_MIN_HEARTBEATS:  # rule 4: a late read stretches a span
            return (
                RefusalReason.TAKEOVER_TOO_SHORT,
                f"not Operational in only {run.heartbeats} heartbeats over "
                f"{span // NS_PER_MS} ms; {TAKEOVER_MIN_HEARTBEATS} needed",
            )
        heartbeats = run.heartbeats + 1  # with the Operational one
        window = self._now - run.first_ns
        allowed = window // VSC_MIN_INTERVAL_NS + 1 + READ_TOGETHER_ALLOWANCE
        if heartbeats > allowed:  # rule 4: no faster than a VSC can send them
            return (
                RefusalReason.VSC_TOO_FAST,
                f"{heartbeats} heartbeats in {window // NS_PER_MS} ms; a VSC sends at most one "
                f"per {VSC_MIN_INTERVAL_NS // NS_PER_MS} ms",
            )
        return None

    # ----------------------------------------------------------------- outputs and frames

    def _outputs(self, previous: State, now: int) -> MappingProxyType[str, bool]:
        """The outputs' levels after a step from ``previous``. SR-1.4: a stop begun while the
        power outputs were on (from HOLD or RUN) leaves each category-1 output on until its
        delay after the motion outputs went off, then off; a failure of the core itself (which
        forgets when motion went off: ``_fail_safe``) and a stop begun in STOPPED leave none
        on."""
        state, delays = self._state, self._off_delays_ns
        if not delays:
            return self._levels(state)
        if previous is State.RUN and state is not State.RUN:
            self._motion_off_ns = now
        if state is not State.STOPPED:
            self._braking_since = None
        elif previous is not State.STOPPED:
            self._braking_since = self._motion_off_ns
        since = self._braking_since
        if since is None:
            return self._levels(state)
        if now - since >= max(delays.values()):
            self._braking_since = None  # every delay is over: off for the rest of this stop
            return self._levels(state)
        return MappingProxyType(
            {
                o.name: o.name in delays and now - since < delays[o.name]
                for o in self._config.outputs
            }
        )

    def _levels(self, state: State) -> MappingProxyType[str, bool]:
        # SR-1: motion outputs on only in RUN; power outputs on in HOLD and RUN. Read-only
        # and the same for every step in a state, so built once per state.
        levels = self._levels_by_state.get(state)
        if levels is None:
            levels = self._levels_by_state[state] = MappingProxyType(
                {
                    o.name: state is State.RUN
                    if o.role is OutputRole.MOTION
                    else state is not State.STOPPED
                    for o in self._config.outputs
                }
            )
        return levels

    def _emit_link_frames(self, now: int, estop: int, *, urgent: bool) -> None:
        if not self._link_open:
            return
        if urgent:
            self._proof.abort()  # a new stop reaches the VSC at once, proof test or not
        if (
            self._next_heartbeat_ns is not None
            and (urgent or now >= self._next_heartbeat_ns)
            and not self._proof.withholding  # the proof test withholds it (SR-5.3)
        ):
            # SR-5: user heartbeat at heartbeat_hz; a new stop goes out at once.
            self._frames.append(UserHeartbeat(estop))
            self._proof.sent(now)
            period = self._heartbeat_period_ns
            # SR-5.1: keep the cadence; an urgent heartbeat restarts it from now.
            self._next_heartbeat_ns = (
                now + period if urgent else next_due(self._next_heartbeat_ns, now, period)
            )
        if self._next_key85_ns is not None and now >= self._next_key85_ns:
            self._frames.append(FeedbackGet(FeedbackKey.USER_ESTOP_TIMEOUT))
            self._next_key85_ns = now + KEY85_RETRY_NS
        self._frames.extend(self._display.due(now))

    def _next_deadline(self, now: int) -> int:
        """The earliest future time at which something falls due; never ``now`` or earlier."""
        # A deadline already passed has been acted on in this step (an expired timeout stays
        # expired until a new heartbeat), so only future times count.
        earliest = now + IDLE_NS
        for kind, name in self._pending_ends():
            free = self._budget.free_at(self._unnamed[(kind, name)].uid, now)
            if free is not None and now < free < earliest:
                earliest = free
        last = self._last_vsc_ns
        if last is not None and now < (due := last + self._vsc_timeout_ns) < earliest:
            earliest = due
        stale = self._battery_stale_at()
        if stale is not None and now < stale < earliest:  # SR-8.12: the report is too old
            earliest = stale
        since = self._braking_since
        if since is not None:  # SR-1.4: a category-1 output goes off at its delay, never later
            for delay in self._off_delays_ns.values():
                if now < (due := since + delay) < earliest:
                    earliest = due
        for name, beat in self._client_beat_ns.items():
            if beat is not None and now < (due := beat + self._client_timeout_ns[name]) < earliest:
                earliest = due
        if self._link_open:
            for later in (
                self._next_heartbeat_ns,
                self._next_key85_ns,
                self._display.next_due(),
                self._proof.next_deadline(self._key85),
            ):
                if later is not None and now < later < earliest:
                    earliest = later
        return earliest


_Handler = Callable[[SafetyCore, Any, int], "_RearmRequest | None"]
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
    }
)
"""Step 2's dispatch: each event type to the handler that applies it to the facts. Every type
of :data:`~supervisord.safety.events.Event` has one (``tests/safety/test_dispatch.py``), so a
new event cannot be ignored by omission. Keyed by the exact type: events are final."""


_TRANSPORT_FAULT = Cause(CauseKind.TRANSPORT_FAULT)
_VSC_LINK_LOST = Cause(CauseKind.VSC_LINK_LOST)
_VSC_ESTOP = Cause(CauseKind.VSC_ESTOP)
_VSC_WATCHDOG_OFF = Cause(CauseKind.VSC_WATCHDOG_OFF)
_VSC_WATCHDOG_UNTESTED = Cause(CauseKind.VSC_WATCHDOG_UNTESTED)
_LOCAL_ESTOP = Cause(CauseKind.LOCAL_ESTOP)
_BATTERY_CAUSES: Final[Mapping[Reaction, Cause]] = MappingProxyType(
    {
        Reaction.HOLD: Cause(CauseKind.ESTOP_UNAVAILABLE_HOLD),
        Reaction.STOP: Cause(CauseKind.ESTOP_UNAVAILABLE),
    }
)
"""SR-8.12: the cause the remote's battery raises under each ``vsc.on_estop_unavailable``
(none under ``warn``)."""
_CHEAP_EVENTS = frozenset({Tick, VscReceived})
_CLIENT_EVENTS = (
    ClientConnected,
    ClientHello,
    ClientHeartbeat,
    ClientEstop,
    ClientHold,
    ClientCommand,
    ClientRelease,
    ClientDisconnected,
    LocalEstop,
    LocalRelease,
    ResetRequest,
    ProofTestRequest,
    Commissioned,
    StopTested,
)
"""Inputs from the client socket: the records they cause are charged to their user (SR-8.5)."""
_LIMITED_EVENTS = (ClientRelease, LocalRelease, ResetRequest, ClientHello)
"""Past its user's budget these are refused (``RATE_LIMITED``): each can take a reason to stop
away (a release, a re-arm, a hello that ends a required client's loss or names a new
requester); refusing them leaves the robot held or stopped, the safe side (SR-8.5)."""
_INERT_TYPES = frozenset(INERT_VSC_MESSAGES)
"""The only event types ``SafetyCore._cheap`` considers; every other takes the full step."""
_SETTLED_PROOF = frozenset({Phase.OFF, Phase.PASSED})
"""Proof-test phases in which neither time nor an unchanged heartbeat moves the proof test
(docs/safety.md "The proof test"); in any other the cheap path declines."""


def _sources(word: int) -> str:
    return ",".join(sorted(s.value for s in estop_sources(word)))


def _caller_details(caller: Caller | None) -> Details:
    if caller is None:
        return ()
    return make_details(
        [("caller", caller.name[:60]), ("uid", str(caller.uid)), ("pid", str(caller.pid))]
    )
