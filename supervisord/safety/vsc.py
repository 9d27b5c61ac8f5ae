"""The link to the VSC as the safety core sees it: the link itself, the VSC's heartbeats and
modes, the hold of a mode that is not Operational, the takeover's evidence, key 85 and the
schedule of the frames the supervisor sends (SR-2, SR-3, SR-4.5, SR-5).

Internal to the core, one of the machines :class:`~supervisord.safety.core.SafetyCore`
composes: its handlers apply one VSC input each and return what they decide (a takeover to
check) as values, :meth:`VscLink.link_conditions` and :meth:`VscLink.mode_hold` give the
conditions it raises at ``now``, :meth:`VscLink.next_deadline` its next deadline and
:meth:`VscLink.canonical` its canonical form (docs/verification.md).
"""

from __future__ import annotations

from dataclasses import dataclass

from supervisord.protocol.codes import FeedbackKey, VscMode, estop_sources
from supervisord.protocol.messages import FeedbackGet, Message, UserHeartbeat, VscHeartbeat
from supervisord.safety.canonical import Clock, clock
from supervisord.safety.causes import Cause, CauseKind, Details, make_details
from supervisord.safety.config import SafetyConfig, Transport
from supervisord.safety.decision import RefusalReason
from supervisord.safety.face import Seen
from supervisord.timebase import NS_PER_MS, NS_PER_S, next_due

KEY85_RETRY_NS = NS_PER_S  # re-ask key 85 every second until it reads 1 (SR-5)
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
REFUSAL_QUIET_NS = NS_PER_S
"""The same takeover refusal is reported (and recorded) at most once per this: a flapping VSC
would otherwise fill the record, whose rotation drops the stop the refusals are about."""
LINKED_MODES = frozenset(
    {VscMode.LOCAL, VscMode.REMOTE, VscMode.OPERATIONAL, VscMode.MENU, VscMode.PAUSE}
)
"""Modes in which a remote is linked to the VSC; a move into one of them from Searching, an
unknown mode or no heartbeat is a re-link that loses the remote's display (PR-2)."""


def mode_name(mode: int) -> str:
    """The ``NAME`` of ``vsc_mode:NAME``: the mode in lower case, or ``unknown_0x42``."""
    known = VscMode.parse(mode)
    return known.name.lower() if known is not None else f"unknown_0x{mode:02x}"


@dataclass(frozen=True, slots=True)
class Run:
    """An unbroken run of non-Operational VSC heartbeats (re-arm rule 4): none Operational,
    none ``vsc_timeout`` or more after the one before, all since the link last opened."""

    first_ns: int
    last_ns: int
    heartbeats: int

    def then(self, now: int) -> Run:
        return Run(self.first_ns, now, self.heartbeats + 1)


@dataclass(frozen=True, slots=True)
class Heard:
    """What a VSC heartbeat decided, for the core to pass on: ``silent_before``: it ends a
    silence (the VSC may have rebooted: its watchdog is proven again); ``takeover``: it is
    Operational after a mode that was not (``run``: the run before it, the takeover's
    evidence); ``relinked``: a remote linked again (its display is lost)."""

    silent_before: bool
    takeover: bool
    run: Run | None
    relinked: bool


class VscLink:
    """The link, the VSC's last heartbeat and mode, the mode's hold and the takeover's run."""

    def __init__(self, config: SafetyConfig) -> None:
        self._timeout_ns = config.vsc_timeout_ns  # read for every input: computed once
        self._period_ns = config.heartbeat_period_ns
        self._serial = config.transport is Transport.SERIAL
        self._hid = config.transport is Transport.HID
        self._require_watchdog = self._serial and config.require_watchdog
        self.open = False
        self._fault: str | None = "not opened yet"
        self.last_ns: int | None = None
        self.mode: int | None = None
        self.estop_word = 0
        self._run: Run | None = None  # the current non-Operational run (re-arm rule 4)
        # The hold of the VSC's mode (SR-3.1, SR-3.3): the mode it names, since when it has
        # named it, and the Operational run that may end it after a glitch or a flap.
        self._held_mode: int | None = None
        self._held_since = 0
        self._settling: Run | None = None
        self._quiet: tuple[RefusalReason, int] | None = None  # the last takeover refusal
        self._remote_linked = False
        self.key85: int | None = None
        self._next_key85_ns: int | None = None
        self.next_heartbeat_ns: int | None = None

    # ----------------------------------------------------------------- handlers

    def opened(self, now: int) -> None:
        # SR-4: a reconnect of the VSC is a new start. Liveness starts over ("never seen since
        # link open" counts as lost, SR-2) and key 85 is read back again (SR-5).
        self.open = True
        if not self._hid:
            self._fault = None
        self.last_ns = None
        self.mode = None
        self._run = None
        self._held_mode = self._settling = None
        self._remote_linked = False
        self.key85 = None
        self._next_key85_ns = now if self._serial else None
        self.next_heartbeat_ns = now if self._serial else None

    def down(self, fault: str) -> None:
        self.open = False
        self._fault = fault[:200]
        self.last_ns = None
        self.mode = None
        self._run = None
        self._held_mode = self._settling = None
        self._remote_linked = False
        self._next_key85_ns = None
        self.next_heartbeat_ns = None

    def heartbeat(self, message: VscHeartbeat, now: int) -> Heard:
        # SR-2: only a valid heartbeat is liveness; the daemon passes only checked frames.
        previous_ns, self.last_ns = self.last_ns, now
        silent = previous_ns is not None and now - previous_ns >= self._timeout_ns
        self.estop_word = message.estop
        unbroken = previous_ns is not None and now - previous_ns < self._timeout_ns
        mode = message.mode
        takeover = False
        run = self._run
        if mode == VscMode.OPERATIONAL:
            previous = self.mode
            # SR-4: the operator's takeover, not Operational followed by Operational; whether
            # the run before it is an operator's act is rule 4 (``act_refusal``).
            takeover = previous is not None and previous != VscMode.OPERATIONAL
            self._settle(now, unbroken)
            self._run = None
        else:
            self._hold_mode(mode, now)
            if self._run is None or not unbroken:
                self._run = Run(now, now, 1)  # rule 4: a silent gap starts the run again
            else:
                self._run = self._run.then(now)
        self.mode = mode
        linked = VscMode.parse(mode) in LINKED_MODES
        relinked = linked and not self._remote_linked
        self._remote_linked = linked
        return Heard(silent, takeover, run, relinked)

    def key85_read(self, value: int) -> None:
        """Key 85 read back (SR-5.3): 1 ends the queries."""
        self.key85 = value
        if value == 1:
            self._next_key85_ns = None

    def refusal_quiet(self, reason: RefusalReason, now: int) -> bool:
        """Whether a takeover refused for ``reason`` at ``now`` goes unreported: the same
        refusal within a second is (a flapping VSC, docs/safety.md "Re-arming"); a new reason
        never. A reported one starts the second again."""
        quiet = self._quiet
        if quiet is not None and quiet[0] is reason and now - quiet[1] < REFUSAL_QUIET_NS:
            return True
        self._quiet = (reason, now)
        return False

    def rearmed(self) -> None:
        """A re-arm was accepted: the next refusal is reported whatever its reason."""
        self._quiet = None

    def frames(self, now: int, estop: int, *, urgent: bool, withheld: bool) -> list[Message]:
        """The user heartbeat due at ``now`` (at once when ``urgent``, never while the proof
        test ``withheld`` it) and key 85's query; the link is open."""
        frames: list[Message] = []
        beat = self.next_heartbeat_ns
        if beat is not None and (urgent or now >= beat) and not withheld:
            # SR-5: user heartbeat at heartbeat_hz; a new stop goes out at once.
            frames.append(UserHeartbeat(estop))
            period = self._period_ns
            # SR-5.1: keep the cadence; an urgent heartbeat restarts it from now.
            self.next_heartbeat_ns = now + period if urgent else next_due(beat, now, period)
        if self._next_key85_ns is not None and now >= self._next_key85_ns:
            frames.append(FeedbackGet(FeedbackKey.USER_ESTOP_TIMEOUT))
            self._next_key85_ns = now + KEY85_RETRY_NS
        return frames

    def beat_sent(self, now: int) -> None:
        """The cheap path sent the user heartbeat due (``frames``, not urgent)."""
        beat = self.next_heartbeat_ns
        assert beat is not None  # the cheap path checked it
        self.next_heartbeat_ns = next_due(beat, now, self._period_ns)

    # ----------------------------------------------------------------- conditions at now

    def lost(self, now: int) -> bool:
        """No heartbeat since the link opened, or none for ``vsc_timeout`` (SR-2.2)."""
        last = self.last_ns
        return last is None or now - last >= self._timeout_ns  # ">=": 200 ms is lost

    def heard(self, now: int) -> bool:
        """The link open and the VSC heard within its timeout (the proof test's condition)."""
        return self.open and self.last_ns is not None and now - self.last_ns < self._timeout_ns

    def link_conditions(self, now: int) -> tuple[tuple[Cause, Details | None], ...]:
        """``transport_fault``, ``vsc_link_lost``, ``vsc_estop`` and ``vsc_watchdog_off`` at
        ``now``, in that order, each with its details when it holds, else ``None``."""
        fault = "hid is not a safety channel" if self._hid else self._fault
        last = self.last_ns
        word = self.estop_word
        watchdog_off = self._require_watchdog and self.key85 != 1
        return (
            (
                _TRANSPORT_FAULT,
                None if fault is None else make_details([("reason", fault)]) if fault else (),
            ),
            (
                _VSC_LINK_LOST,
                make_details(
                    [
                        ("reason", "no heartbeat since link open" if last is None else "timeout"),
                        ("timeout_ms", str(self._timeout_ns // NS_PER_MS)),
                    ]
                )
                if self.lost(now)
                else None,
            ),
            (
                _VSC_ESTOP,
                make_details([("sources", _sources(word)), ("word", f"0x{word:08x}")])
                if word
                else None,
            ),
            (
                _VSC_WATCHDOG_OFF,
                make_details([("key85", "no answer" if self.key85 is None else str(self.key85))])
                if watchdog_off
                else None,
            ),
        )

    def mode_hold(self) -> dict[Cause, Details]:
        """``vsc_mode:NAME`` while the hold names a mode (SR-3.1, SR-3.3)."""
        mode = self._held_mode
        if mode is None or mode == VscMode.OPERATIONAL:
            return {}
        details = make_details([("mode", f"0x{mode:02x}")])
        return {Cause(CauseKind.VSC_MODE, mode_name(mode)): details}

    def unchanged_by(self, message: VscHeartbeat, now: int) -> bool:
        """Whether ``message`` at ``now`` changes no condition and asks no re-arm: the same
        mode and word as the last, in time, while no hold may settle or take its name (the
        cheap path's test, ``cheap.cheap``)."""
        last = self.last_ns
        return not (
            last is None  # the first heartbeat clears "never seen" (SR-2.2)
            or now - last >= self._timeout_ns  # this one clears the timeout
            or message.mode != self.mode
            or message.estop != self.estop_word
            or self._settling is not None  # it may end the hold (SR-3.3)
            # the hold names another mode: after the dwell it takes this one's name
            or (self._held_mode is not None and message.mode != self._held_mode)
        )

    def beat_due(self, now: int) -> bool:
        """Whether the user heartbeat is due at ``now`` on an open link (SR-5.1)."""
        beat = self.next_heartbeat_ns
        return self.open and beat is not None and now >= beat

    # ----------------------------------------------------------------- the face (face.py)

    def can_move(self) -> bool:
        """The link moves only at its deadlines."""
        return False

    def moving(self) -> bool:
        return False

    def due_by(self, view: Seen) -> bool:
        """Whether the link is closed, the VSC's timeout has fallen due or key 85's query is
        due at ``view.now`` (the user heartbeat aside: :meth:`beat_due`)."""
        now = view.now
        if not self.open or self.lost(now):
            return True
        key85 = self._next_key85_ns
        return key85 is not None and key85 <= now

    def next_deadline(self, view: Seen) -> int | None:
        """The earliest time after ``view.now`` at which the VSC's timeout, the user heartbeat
        or key 85's query falls due, or ``None``."""
        now = view.now
        earliest: int | None = None
        last = self.last_ns
        candidates = [None if last is None else last + self._timeout_ns]  # SR-2.2
        if self.open:
            candidates += [self.next_heartbeat_ns, self._next_key85_ns]
        for due in candidates:
            if due is not None and now < due and (earliest is None or due < earliest):
                earliest = due
        return earliest

    # ----------------------------------------------------------------- the takeover (SR-4.5)

    def takeover_refusal(
        self, run: Run | None, last_stop_ns: int | None, now: int
    ) -> tuple[RefusalReason, str] | None:
        """Re-arming rules 2-4 for a takeover: is the run before the Operational heartbeat at
        ``now`` an operator's act (docs/safety.md "Re-arming")?"""
        if run is None or (last_stop_ns is not None and run.last_ns < last_stop_ns):
            # Rule 2 and 3: the non-Operational heartbeat must come after the last stop began.
            return RefusalReason.NEW_CAUSE_DURING_REARM, ""
        return act_refusal(run, now)

    # ----------------------------------------------------------------- the mode's hold (SR-3)

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
            if run is not None and act_refusal(run, now) is None:
                self._held_mode = None  # the operator resumed: no wait
                return
            self._settling = Run(now, now, 1)
            return
        self._settling = settling = settling.then(now) if unbroken else Run(now, now, 1)
        if (
            settling.last_ns - settling.first_ns >= SETTLE_DWELL_NS
            and settling.heartbeats >= TAKEOVER_MIN_HEARTBEATS
        ):
            self._held_mode = self._settling = None

    # ----------------------------------------------------------------- canonical form

    def canonical(self, view: Seen) -> tuple[tuple[object, ...], tuple[Clock, ...]]:
        """The facts and clocks of the link (docs/verification.md). Two guards are not of the
        form ``age >= constant`` and are kept as facts or clocks of their own: the span of the
        takeover's run (first to last heartbeat, a fact once the run stops growing) and its
        rate (``act_refusal``: a count against the age of its first heartbeat, kept as the age
        at which the count is allowed, clipped at ``RATE_SLACK_NS``: the one inexact clip).
        ``view.last_stop_raised_ns``: when the latest stop was raised (SR-4.3 orders the run
        against it)."""
        now, last_stop_ns = view.now, view.last_stop_raised_ns
        clocks: list[Clock] = []

        def keep(name: str, at: int | None, *limits: int) -> None:
            if at is not None:
                clocks.append(clock(name, at, now, *limits))

        run = self._run
        run_facts: object = None
        if run is not None:
            run_facts = (
                min(run.heartbeats, TAKEOVER_MIN_HEARTBEATS),
                run.last_ns - run.first_ns >= TAKEOVER_DWELL_NS,
                last_stop_ns is not None and run.last_ns < last_stop_ns,  # SR-4.3
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
        keep("vsc:last", self.last_ns, self._timeout_ns)
        keep("key85:next", self._next_key85_ns, 0)
        keep("heartbeat:next", self.next_heartbeat_ns, 0, self._period_ns)
        facts = (
            ("link_open", self.open),
            ("link_fault", self._fault),
            ("vsc_mode", self.mode),
            ("vsc_estop_word", self.estop_word),
            ("remote_linked", self._remote_linked),
            ("key85", self.key85),
            ("held_mode", self._held_mode),
            ("run", run_facts),
            (
                "settling",
                None if settling is None else min(settling.heartbeats, TAKEOVER_MIN_HEARTBEATS),
            ),
            ("quiet", None if quiet is None else quiet[0]),
        )
        return facts, tuple(clocks)

    NOT_CANONICAL = frozenset({"_timeout_ns", "_period_ns", "_serial", "_hid", "_require_watchdog"})
    """Attributes ``canonical`` leaves out: the config, and what is computed from it once."""


def act_refusal(run: Run, now: int) -> tuple[RefusalReason, str] | None:
    """Re-arming rule 4: why the non-Operational run before the Operational heartbeat at
    ``now`` is no operator's act, or ``None`` when it is one."""
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
    window = now - run.first_ns
    allowed = window // VSC_MIN_INTERVAL_NS + 1 + READ_TOGETHER_ALLOWANCE
    if heartbeats > allowed:  # rule 4: no faster than a VSC can send them
        return (
            RefusalReason.VSC_TOO_FAST,
            f"{heartbeats} heartbeats in {window // NS_PER_MS} ms; a VSC sends at most one "
            f"per {VSC_MIN_INTERVAL_NS // NS_PER_MS} ms",
        )
    return None


def _sources(word: int) -> str:
    return ",".join(sorted(s.value for s in estop_sources(word)))


_TRANSPORT_FAULT = Cause(CauseKind.TRANSPORT_FAULT)
_VSC_LINK_LOST = Cause(CauseKind.VSC_LINK_LOST)
_VSC_ESTOP = Cause(CauseKind.VSC_ESTOP)
_VSC_WATCHDOG_OFF = Cause(CauseKind.VSC_WATCHDOG_OFF)
