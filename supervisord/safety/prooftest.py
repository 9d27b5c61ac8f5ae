"""The proof test of the VSC's own watchdog (key 85): docs/safety.md "The proof test".

Before the first RUN after every start, every reconnect and every silence of the VSC (a
reboot), and on demand (``srcsctl prooftest``), the supervisor proves the second stop path
(SR-0.1, SR-5.3): while STOPPED, it withholds the user heartbeat for longer than the VSC's
500 ms watchdog (PR-2.8), confirms that the VSC reports the user e-stop bits (bits 6-7 of
the e-stop word, PR-2.6) and leaves Operational if it was there, then resumes the heartbeat
and confirms that the bits clear, by themselves or held until the operator's takeover.

Pure: :class:`ProofTest` takes the VSC's heartbeats and ``now`` (monotonic ns) and says
whether the core must withhold the heartbeat; the core owns every other fact.
"""

from __future__ import annotations

import enum
from dataclasses import dataclass
from typing import Final

from supervisord.protocol.codes import VscMode
from supervisord.safety.canonical import Canonical, clock
from supervisord.safety.causes import CauseKind
from supervisord.safety.face import Seen
from supervisord.timebase import NS_PER_MS
from supervisord.vocabulary import (
    READING_MARGIN_NS,
    TRIP_LATE_NS,
    WATCHDOG_NS,
    Phase,
    ProofTestPolicy,
)
from supervisord.vocabulary import ProofTestFailure as Failure

USER_BITS: Final = 0xC0
"""Bits 6-7 of the VSC's e-stop word: the user computer's e-stop, from its heartbeat's byte
or from the key-85 watchdog (PR-2.6)."""
LATE_TRIES: Final = 3
"""How many times a trip seen late is measured before the test fails (SR-5.7). A trip can be
seen later than it happened (a late VSC heartbeat, a stalled vehicle computer), never sooner:
one trip seen within 700 ms proves the watchdog, and a watchdog that is late every time fails.
Between two tries the heartbeat resumes and the bits clear, as after a pass."""
WITHHOLD_LIMIT_NS: Final = TRIP_LATE_NS + 800 * NS_PER_MS
"""How long the heartbeat is withheld at most: no trip by then (1.5 s, three times the
watchdog), the VSC ignores it."""


EARLY_NS: Final = WATCHDOG_NS - 100 * NS_PER_MS
"""A trip seen sooner than this after the last heartbeat sent cannot be the watchdog's answer
to the withheld heartbeat (it needs 500 ms; 100 ms is two VSC heartbeat intervals of
slack): the bits were on their way before the test (a trip of the loop's own, a stall of the
vehicle computer). It proves nothing, so the test starts again once the bits clear (SR-5.6)."""
CLEARS_ITSELF_NS: Final = 500 * NS_PER_MS
"""Bits that clear within this of the heartbeat resuming cleared by themselves; later, the
VSC held them (until the operator's takeover, the manual does not say which it does)."""
KEY85_WAIT_NS: Final = 3_000 * NS_PER_MS
"""How long the test waits for key 85 to answer once the VSC is heard (it is asked every
second, SR-5.3): no answer by then and the watchdog cannot be proven."""


NOT_IN_THE_WAY: Final = frozenset({CauseKind.CLIENT_LOST})
"""The stop causes that neither keep an unfinished proof test from starting nor set the user
heartbeat's byte while it is unfinished and the supervisor STOPPED (SR-8.15): a required
client not connected yet. Its service may itself start behind ``srcsctl wait-ready``, which
waits for the proof test; the test needs the byte at 0 (PR-2.6). It cannot move the robot:
the outputs are off (STOPPED) and ``client_lost`` stays active, latched and blocking every
re-arm; the withholding itself opens the VSC's relays, and once the test is over the byte is
1 again until the client is there."""

SETTLED: Final = frozenset({Phase.OFF, Phase.PASSED})
"""Phases in which neither time nor an unchanged heartbeat moves the test (its face's
``moving``; the cheap path's ``SETTLED_PROOF``)."""


class Cleared(enum.Enum):
    """How the user bits cleared after the heartbeat resumed (docs/safety.md: both pass)."""

    BY_ITSELF = "by_itself"
    HELD = "held"  # held until the operator's takeover (or another act on the remote)


@dataclass(frozen=True, slots=True)
class Outcome:
    """A finished proof test, for the record (``kind: prooftest``) and ``status``."""

    passed: bool
    failure: Failure | None
    trip_ms: int | None
    cleared: Cleared | None
    cleared_ms: int | None  # from the heartbeat resuming to the bits clearing
    at_ns: int

    @property
    def text(self) -> str:
        trip = "no trip" if self.trip_ms is None else f"trip {self.trip_ms} ms (manual: 500 ms)"
        if self.passed:
            how = "by itself" if self.cleared is Cleared.BY_ITSELF else "held, then cleared"
            return f"passed: {trip}; cleared {how} {self.cleared_ms} ms after the heartbeat resumed"
        assert self.failure is not None
        return f"failed: {self.failure.value}; {trip}"


@dataclass(frozen=True, slots=True)
class ProofStatus:
    """What ``status`` shows: the policy, the phase and the latest finished proof test."""

    policy: ProofTestPolicy
    phase: Phase
    last: Outcome | None


class ProofTest:
    """One proof test at a time; :meth:`restart` begins a new one (a new start, SR-4.4).

    The core calls :meth:`heartbeat` for every VSC heartbeat, :meth:`advance` once per step
    with whether it may start (STOPPED, the VSC heard, key 85 = 1, nothing asking the VSC
    to stop), :meth:`sent` when a user heartbeat goes out, and reads :attr:`withholding`.
    """

    def __init__(
        self, policy: ProofTestPolicy, clear_limit_ns: int, late_tries: int = LATE_TRIES
    ) -> None:
        self.policy = policy
        self.clear_limit_ns = clear_limit_ns
        self.late_tries = late_tries
        self._late = 0  # tries of this test whose trip was seen late
        self._again = False  # this try was late: once the bits clear, the test runs again
        self.phase = Phase.OFF if policy is ProofTestPolicy.OFF else Phase.WAITING
        self.last: Outcome | None = None  # the latest finished proof test
        self._new: Outcome | None = None  # finished in this step, not yet taken
        self._heard_ns: int | None = None  # first VSC heartbeat of this attempt
        self._sent_ns: int | None = None  # the last user heartbeat that went out
        self._withheld_from: int | None = None  # that heartbeat, when withholding began
        self._was_operational = False
        self._trip_ns: int | None = None
        self._resumed_ns: int | None = None

    # -- what the core reads

    @property
    def withholding(self) -> bool:
        return self.phase is Phase.WITHHOLDING

    @property
    def running(self) -> bool:
        return self.phase in (Phase.WITHHOLDING, Phase.RESUMED)

    @property
    def untested(self) -> bool:
        """The condition of ``vsc_watchdog_untested``: not proven yet (a test pending or
        running blocks RUN under every policy: it must come before the first RUN), or
        failed under the ``block`` policy."""
        if self.phase in (Phase.OFF, Phase.PASSED):
            return False
        return self.phase is not Phase.FAILED or self.policy is ProofTestPolicy.BLOCK

    @property
    def unfinished(self) -> bool:
        """Pending or running: neither passed nor failed since the last new start."""
        return self.phase in (Phase.WAITING, Phase.WITHHOLDING, Phase.RESUMED)

    def quiet(self, stopped: bool) -> frozenset[CauseKind]:
        """The cause kinds that do not count against the test now (SR-8.15): those of
        :data:`NOT_IN_THE_WAY` while it is unfinished and the supervisor ``stopped``."""
        return NOT_IN_THE_WAY if stopped and self.unfinished else frozenset()

    def details(self) -> tuple[tuple[str, str], ...]:
        if self.phase is Phase.FAILED and self.last is not None:
            return (("observed", self.last.text),)
        return (("reason", "the VSC's watchdog is not proven since the link opened"),)

    def take_outcome(self) -> Outcome | None:
        """The proof test that finished in this step, once."""
        outcome, self._new = self._new, None
        return outcome

    def status(self) -> ProofStatus:
        """For ``status``: the phase and the latest result."""
        return ProofStatus(self.policy, self.phase, self.last)

    # ----------------------------------------------------------------- the face (face.py)

    def can_move(self) -> bool:
        """No test ever runs while the policy is off (its phase stays OFF)."""
        return self.policy is not ProofTestPolicy.OFF

    def moving(self) -> bool:
        """A test pending or running moves with time and heartbeats (docs/safety.md "The
        proof test")."""
        return self.phase not in SETTLED

    def due_by(self, view: Seen) -> bool:
        """Whether the test withholds the user heartbeat or one of its limits has come."""
        if self.phase is Phase.WITHHOLDING:
            return True
        due = self.next_limit(view.vsc.key85)
        return due is not None and due <= view.now

    def next_deadline(self, view: Seen) -> int | None:
        """The next of its limits after ``view.now``, while the link is open."""
        due = self.next_limit(view.vsc.key85) if view.vsc.open else None
        return due if due is not None and due > view.now else None

    def next_limit(self, key85: int | None) -> int | None:
        """When the test next moves with time alone; ``key85`` is the core's answer to key 85
        (while none came, the wait for it ends 3 s after the VSC was first heard)."""
        if self.phase is Phase.WAITING and key85 is None and self._heard_ns is not None:
            return self._heard_ns + KEY85_WAIT_NS
        if self.phase is Phase.WITHHOLDING and self._withheld_from is not None:
            return self._withheld_from + WITHHOLD_LIMIT_NS
        if self.phase is Phase.RESUMED and self._resumed_ns is not None:
            return self._resumed_ns + self.clear_limit_ns
        return None

    def canonical(self, view: Seen) -> Canonical:
        """The phase and every fact a later step reads, the times as clocks while a guard can
        still read them (docs/verification.md). ``key85`` is the core's answer to key 85, which
        decides whether the wait for it runs. Outcomes keep whether they passed and why not:
        their measured times are the record's text (a failure's text is also the cause's
        details, which the core's book keeps); the trip keeps only whether it was late.
        ``policy``, ``clear_limit_ns`` and ``late_tries`` are constants."""
        if self.policy is ProofTestPolicy.OFF:
            # No test ever runs: the times it keeps are never read.
            return (("proof", (self.phase,)),), ()
        now, key85 = view.now, view.vsc.key85

        def outcome(done: Outcome | None) -> object:
            return None if done is None else (done.passed, done.failure)

        phase = self.phase
        trip, withheld = self._trip_ns, self._withheld_from
        live = {
            # name: (time, its constants, whether a guard can still read it)
            "proof:heard": (
                self._heard_ns,
                (KEY85_WAIT_NS,),
                phase is Phase.WAITING and key85 is None,
            ),
            "proof:sent": (
                self._sent_ns,
                (WITHHOLD_LIMIT_NS,),
                True,
            ),  # becomes the withholding's start
            "proof:withheld": (
                withheld,
                (EARLY_NS, TRIP_LATE_NS, WITHHOLD_LIMIT_NS),
                phase is Phase.WITHHOLDING,
            ),
            "proof:resumed": (self._resumed_ns, (self.clear_limit_ns,), phase is Phase.RESUMED),
        }
        facts = (
            phase,
            self._late,
            self._again,
            self._was_operational,
            outcome(self.last),
            outcome(self._new),
            None if trip is None else withheld is None or trip - withheld > TRIP_LATE_NS,
            tuple(at is not None for at, _, _ in live.values()),  # the rest read only whether set
        )
        clocks = tuple(
            clock(name, at, now, *limits)
            for name, (at, limits, read) in live.items()
            if at is not None and read
        )
        return (("proof", facts),), clocks

    # -- inputs

    def restart(self) -> None:
        """A new start (link opened, the VSC silent, or asked for): not proven any more."""
        if self.policy is ProofTestPolicy.OFF:
            return
        self.phase = Phase.WAITING
        self._heard_ns = None
        self._withheld_from = self._trip_ns = self._resumed_ns = None
        self._late, self._again = 0, False

    def sent(self, now: int) -> None:
        """A user heartbeat went out at ``now``."""
        self._sent_ns = now
        if self.phase is Phase.RESUMED and self._resumed_ns is None:
            self._resumed_ns = now

    def abort(self) -> None:
        """A stop condition of the supervisor's own came up during the test: its byte must
        reach the VSC at once, and it would hide the bits' clearing. Try again later."""
        if self.running:
            self.phase = Phase.WAITING
            self._withheld_from = self._trip_ns = self._resumed_ns = None
            self._again = False  # the next try is a measurement of its own

    def advance(self, now: int, ready: bool, key85: int | None, mode: int | None) -> None:
        """Start when ``ready``; fail an impossible test; end a withholding that timed out."""
        if (
            self.phase is Phase.FAILED
            and self.last is not None
            and self.last.failure is Failure.KEY85_OFF
            and key85 == 1
        ):
            self.restart()  # commissioned since: now there is something to prove
        if self.phase is Phase.WAITING:
            if key85 is not None and key85 != 1:
                self._finish(now, Failure.KEY85_OFF)
            elif key85 is None:
                if self._heard_ns is not None and now - self._heard_ns >= KEY85_WAIT_NS:
                    self._finish(now, Failure.KEY85_OFF)
            elif ready and self._sent_ns is not None:
                self.phase = Phase.WITHHOLDING
                self._withheld_from = self._sent_ns
                self._was_operational = mode == VscMode.OPERATIONAL
                self._trip_ns = None
        elif self.phase is Phase.WITHHOLDING:
            assert self._withheld_from is not None
            if now - self._withheld_from >= WITHHOLD_LIMIT_NS:
                failure = Failure.NO_TRIP if self._trip_ns is None else Failure.STAYED_OPERATIONAL
                self._resume(now, failure)
        elif (
            self.phase is Phase.RESUMED
            and self._resumed_ns is not None
            and now - self._resumed_ns >= self.clear_limit_ns
        ):
            self._finish(now, Failure.NOT_CLEARED)

    def heartbeat(self, mode: int, word: int, now: int) -> None:
        """A VSC heartbeat with its mode and e-stop word, received at ``now``."""
        if self._heard_ns is None:
            self._heard_ns = now
        tripped = word & USER_BITS != 0
        if self.phase is Phase.WITHHOLDING and tripped:
            assert self._withheld_from is not None
            if self._trip_ns is None and now - self._withheld_from < EARLY_NS:
                self.abort()  # too early to be this test's trip: again once the bits clear
                return
            if self._trip_ns is None:
                self._trip_ns = now
            if self._trip_ns - self._withheld_from > TRIP_LATE_NS:  # later than 700 ms (SR-5.7)
                self._late += 1
                self._again = self._late < self.late_tries
                self._resume(now, None if self._again else Failure.LATE)
            elif not (self._was_operational and mode == VscMode.OPERATIONAL):
                self._resume(now, None)
        elif self.phase is Phase.RESUMED and not tripped and self._resumed_ns is not None:
            self._cleared(now)
        elif (
            self.phase is Phase.FAILED
            and self.last is not None
            and self.last.failure is Failure.NOT_CLEARED
            and not tripped
            and self._resumed_ns is not None
        ):
            self._cleared(now)  # held longer than the limit, then cleared: a late pass

    # -- steps

    def _resume(self, now: int, failure: Failure | None) -> None:
        """Stop withholding; the next heartbeat goes out in this step."""
        if failure is not None:
            self._finish(now, failure)
            return
        self.phase = Phase.RESUMED
        self._resumed_ns = None  # set by the first heartbeat that goes out

    def _trip_ms(self) -> int | None:
        if self._trip_ns is None or self._withheld_from is None:
            return None
        return (self._trip_ns - self._withheld_from) // NS_PER_MS

    def _cleared(self, now: int) -> None:
        assert self._resumed_ns is not None
        if self._again:  # a late try cleared: measure again (LATE_TRIES)
            self.phase, self._again = Phase.WAITING, False
            self._withheld_from = self._trip_ns = self._resumed_ns = None
            return
        after = now - self._resumed_ns
        how = Cleared.BY_ITSELF if after <= CLEARS_ITSELF_NS else Cleared.HELD
        self.last = self._new = Outcome(True, None, self._trip_ms(), how, after // NS_PER_MS, now)
        self.phase = Phase.PASSED

    def _finish(self, now: int, failure: Failure) -> None:
        # ``_again`` is kept: a late try whose bits clear only after the clear limit sends the
        # test round again when they do (SR-5.7: a late trip proves nothing, nor its late clear).
        self.last = self._new = Outcome(False, failure, self._trip_ms(), None, None, now)
        self.phase = Phase.FAILED
        if failure is Failure.NOT_CLEARED:
            return  # keep watching: a held bit that clears later still passes
        self._resumed_ns = None


__all__ = [
    "CLEARS_ITSELF_NS",
    "EARLY_NS",
    "KEY85_WAIT_NS",
    "LATE_TRIES",
    "NOT_IN_THE_WAY",
    "READING_MARGIN_NS",
    "TRIP_LATE_NS",
    "USER_BITS",
    "WATCHDOG_NS",
    "WITHHOLD_LIMIT_NS",
    "Cleared",
    "Failure",
    "Outcome",
    "Phase",
    "ProofStatus",
    "ProofTest",
    "ProofTestPolicy",
]
