"""The proof test of the VSC's watchdog in the pure core (SR-5.3, SR-5.6, SR-5.7; docs/safety.md
"The proof test"): a fake VSC whose watchdog is modelled here, a fake clock, no sleeping."""

from __future__ import annotations

import itertools
from dataclasses import replace

import pytest

from supervisord.errors import ConfigError
from supervisord.protocol.messages import FeedbackSet, UserHeartbeat, VscHeartbeat
from supervisord.record.format import proof_result, proof_status
from supervisord.safety import (
    ClientConnected,
    ClientDisconnected,
    ClientEstop,
    ClientHeartbeat,
    ClientHello,
    LinkBroken,
    LinkClosed,
    LinkOpened,
    LocalEstop,
    SafetyCore,
    State,
    Tick,
    VscReceived,
)
from supervisord.safety.config import ClientSpec, SafetyConfig, Transport
from supervisord.safety.decision import ChangeKind, Decision, RecordNote, RefusalReason
from supervisord.safety.events import Commissioned, ProofTestRequest
from supervisord.safety.prooftest import (
    KEY85_WAIT_NS,
    LATE_TRIES,
    TRIP_LATE_NS,
    WITHHOLD_LIMIT_NS,
    Cleared,
    Failure,
    Phase,
    ProofStatus,
    ProofTest,
    ProofTestPolicy,
)

from .rig import ADMIN, LOCAL, MS, NOBODY, OPERATIONAL, PAUSE, ROBOT, START_NS

UNTESTED = "vsc_watchdog_untested"
BLOCK = replace(ROBOT, clients=(), prooftest=ProofTestPolicy.BLOCK)


class Vsc:
    """A core fed by a VSC whose key-85 watchdog trips ``trip_ms`` after the last user
    heartbeat (``None``: never) and clears when heartbeats resume (``holds``: only at a
    takeover), sending its heartbeat every 50 ms (manual table 5)."""

    def __init__(self, config: SafetyConfig = BLOCK, trip_ms: int | None = 500) -> None:
        self.now = START_NS
        self.core = SafetyCore(config, self.now)
        self.trip_ms = trip_ms
        self.holds = False
        self.held = False
        self.never_clears = False
        self.mode = LOCAL
        self.last_user = self.now
        self.decisions: list[Decision] = []
        self.feed(LinkOpened(self.now))
        self.feed(VscReceived(self.now, FeedbackSet(85, 1)))

    def feed(self, event: object) -> Decision:
        decision = self.core.handle(event)  # type: ignore[arg-type]
        if any(isinstance(f, UserHeartbeat) for f in decision.frames):
            self.last_user = decision.now
        self.decisions.append(decision)
        return decision

    def word(self) -> int:
        tripped = self.trip_ms is not None and self.now - self.last_user >= self.trip_ms * MS
        if tripped and (self.holds or self.never_clears):
            self.held = True
        return 0x80 if tripped or self.held else 0

    def beat(self, ms: int = 50) -> Decision:
        self.now += ms * MS
        word = self.word()
        if word:
            self.mode = LOCAL  # manual §6.6: an e-stop reverts to Local
        return self.feed(VscReceived(self.now, VscHeartbeat(self.mode, 0, word)))

    def run(self, ms: int) -> Decision:
        decision = self.decisions[-1]
        for _ in range(ms // 50):
            decision = self.beat()
        return decision

    @property
    def proof(self) -> Decision:
        return self.decisions[-1]

    def status(self) -> ProofStatus:
        """The proof test's status in the latest decision (a serial core always has one)."""
        status = self.proof.prooftest
        assert status is not None
        return status

    def failure(self) -> str:
        """The name of the failure the finished proof test reports."""
        status = self.status()
        assert status.phase is Phase.FAILED
        assert status.last is not None
        assert status.last.failure is not None
        return status.last.failure.name

    def records(self) -> list[str]:
        return [r.prooftest.text for d in self.decisions for r in d.records if r.prooftest]

    def takeover(self) -> Decision:
        """The operator: Pause long enough for rule 4, then Operational."""
        self.mode = PAUSE
        self.run(300)
        self.mode = OPERATIONAL
        return self.beat()


def test_a_healthy_watchdog_passes_with_its_trip_time_and_then_a_takeover_runs() -> None:
    """SR-5.3: the heartbeat is withheld, the trip is measured (500 ms, seen with the next
    VSC heartbeat), the bit clears by itself; one record; then a takeover reaches RUN."""
    vsc = Vsc()
    assert UNTESTED in vsc.proof.active_names
    vsc.run(1000)
    status = vsc.status()
    assert status.phase is Phase.PASSED
    assert status.last is not None
    assert status.last.trip_ms == 500
    assert status.last.cleared is not None
    assert status.last.cleared.value == "by_itself"
    assert len(vsc.records()) == 1
    assert UNTESTED not in vsc.proof.active_names
    assert vsc.takeover().state is State.RUN


def test_no_heartbeat_goes_out_while_withheld_and_the_robot_stays_stopped() -> None:
    """SR-5.3, SR-1.1: during the withholding no user heartbeat goes out until the VSC
    reports the trip, at least 500 ms, and the state is STOPPED throughout."""
    vsc = Vsc()
    sent = []
    for _ in range(30):
        decision = vsc.beat()
        sent += [decision.now for f in decision.frames if isinstance(f, UserHeartbeat)]
        assert decision.state is State.STOPPED
    gaps = [b - a for a, b in itertools.pairwise(sent)]
    assert max(gaps) >= 500 * MS


@pytest.mark.parametrize(
    ("trip_ms", "failure"), [(None, "NO_TRIP"), (900, "LATE")], ids=["ignores", "late"]
)
def test_a_watchdog_that_ignores_or_trips_late_fails_and_blocks(
    trip_ms: int | None, failure: str
) -> None:
    """SR-5.3: no trip within 1.5 s, or a trip later than 700 ms, fails: the cause stays
    active with the observation, and a takeover is refused."""
    vsc = Vsc(trip_ms=trip_ms)
    vsc.run(6000)  # a late trip is measured LATE_TRIES times
    assert vsc.failure() == failure
    cause = vsc.proof.cause(UNTESTED)
    assert cause is not None
    assert cause.active
    assert "failed" in (cause.detail("observed") or "")
    assert vsc.takeover().state is State.STOPPED


@pytest.mark.parametrize("timeout_ms", [100, 200, 1000])
@pytest.mark.parametrize(("trip_ms", "failure"), [(650, None), (750, "LATE"), (1200, "LATE")])
def test_the_late_limit_is_700_ms_whatever_the_vsc_timeout(
    timeout_ms: int, trip_ms: int, failure: str | None
) -> None:
    """SR-5.7: a trip later than 700 ms fails and one at 650 ms passes, with ``vsc.timeout_ms``
    at 100, 200 or 1000 ms: the limit judges the VSC's watchdog (the manual's 500 ms plus the
    reading margin) and does not move with how long the link may be silent (a 1000 ms timeout
    once let a watchdog tripping at 1.2 s pass)."""
    vsc = Vsc(replace(BLOCK, vsc_timeout_ms=timeout_ms), trip_ms=trip_ms)
    vsc.run(6000)  # a late trip is measured LATE_TRIES times
    if failure is None:
        assert vsc.status().phase is Phase.PASSED
        last = vsc.status().last
        assert last is not None
        assert last.trip_ms == trip_ms
    else:
        assert vsc.failure() == failure
        assert vsc.takeover().state is State.STOPPED


@pytest.mark.parametrize(("after_ns", "late"), [(TRIP_LATE_NS, False), (TRIP_LATE_NS + 1, True)])
def test_a_trip_at_exactly_700_ms_passes_and_one_nanosecond_later_is_late(
    after_ns: int, late: bool
) -> None:
    """SR-5.7: "later than 700 ms" is late, so a trip seen exactly 700 ms after the last
    heartbeat sent passes and one seen a nanosecond later fails (``>``, not ``>=``)."""
    assert TRIP_LATE_NS == 700 * MS
    proof = ProofTest(ProofTestPolicy.BLOCK, 10_000 * MS, late_tries=1)
    proof.sent(START_NS)
    proof.advance(START_NS + 10 * MS, True, 1, LOCAL)
    assert proof.withholding
    proof.heartbeat(LOCAL, 0x80, START_NS + after_ns)
    outcome = proof.take_outcome()
    if late:
        assert outcome is not None
        assert outcome.failure is Failure.LATE
        assert proof.phase is Phase.FAILED
    else:
        assert outcome is None
        assert proof.phase is Phase.RESUMED


@pytest.mark.parametrize("user_bit", [0x40, 0x80])
def test_only_the_user_bits_of_the_estop_word_are_the_watchdogs_trip(user_bit: int) -> None:
    """SR-5.6 and PR-2.6: the watchdog's trip is the user e-stop bits, 6-7 of the e-stop word.
    The remote's and the wired input's bits (0-5), all set, are another stop, not the trip:
    the heartbeat stays withheld; then bit 6 alone, or bit 7 alone, is the trip."""
    proof = ProofTest(ProofTestPolicy.BLOCK, 10_000 * MS, late_tries=1)
    proof.sent(START_NS)
    proof.advance(START_NS + 10 * MS, True, 1, LOCAL)
    assert proof.withholding
    proof.heartbeat(LOCAL, 0x3F, START_NS + 550 * MS)
    assert proof.phase is Phase.WITHHOLDING
    proof.heartbeat(LOCAL, user_bit, START_NS + 600 * MS)
    assert proof.take_outcome() is None
    assert proof.status().phase is Phase.RESUMED


def _passed(cleared_after_ns: int) -> ProofTest:
    """A proof test whose trip is seen 600 ms after the last heartbeat sent, and whose bits
    clear ``cleared_after_ns`` after the heartbeat resumed (50 ms after the trip)."""
    proof = ProofTest(ProofTestPolicy.BLOCK, 10_000 * MS, late_tries=1)
    proof.sent(START_NS)
    proof.advance(START_NS + 10 * MS, True, 1, LOCAL)
    proof.heartbeat(LOCAL, 0x80, START_NS + 600 * MS)
    resumed = START_NS + 650 * MS
    proof.sent(resumed)
    proof.heartbeat(LOCAL, 0, resumed + cleared_after_ns)
    return proof


@pytest.mark.parametrize(
    ("after_ns", "how"), [(500 * MS, Cleared.BY_ITSELF), (500 * MS + 1, Cleared.HELD)]
)
def test_bits_clear_by_themselves_within_500_ms_and_one_nanosecond_later_were_held(
    after_ns: int, how: Cleared
) -> None:
    """SR-5.6 (docs/safety.md "The proof test", step 4): bits that clear within 500 ms of
    the heartbeat resuming cleared by themselves, so exactly 500 ms is "by itself" and a
    nanosecond later the VSC held them; both pass, and the record says which."""
    outcome = _passed(after_ns).take_outcome()
    assert outcome is not None
    assert outcome.passed
    assert outcome.cleared is how


def test_the_prooftest_record_and_status_give_the_measured_times() -> None:
    """SR-5.6: the result is a ``prooftest`` record with the measured trip time: a pass gives
    the trip and how the bits cleared, a late trip its failure and the trip, and ``status``
    shows the latest result (none before the first)."""
    proof = _passed(120 * MS)
    passed = proof.take_outcome()
    assert passed is not None
    assert proof_status(proof.status()).json() == {
        "policy": "block",
        "phase": "passed",
        "last": proof_result(passed).json(),
    }
    assert passed.text == (
        "passed: trip 600 ms (manual: 500 ms); cleared by itself 120 ms after the heartbeat resumed"
    )
    assert proof_result(passed).json() == {
        "result": "passed",
        "failure": None,
        "trip_ms": 600,
        "cleared": "by_itself",
        "cleared_ms": 120,
        "text": passed.text,
    }
    held = _passed(800 * MS).take_outcome()
    assert held is not None
    assert held.text.endswith("; cleared held, then cleared 800 ms after the heartbeat resumed")

    late = ProofTest(ProofTestPolicy.BLOCK, 10_000 * MS, late_tries=1)
    assert proof_status(late.status()).json() == {
        "policy": "block",
        "phase": "waiting",
        "last": None,
    }
    late.sent(START_NS)
    late.advance(START_NS + 10 * MS, True, 1, LOCAL)
    late.heartbeat(LOCAL, 0x80, START_NS + 750 * MS)
    failed = late.take_outcome()
    assert failed is not None
    assert failed.text == (
        "failed: the VSC reported the user-timeout e-stop late; trip 750 ms (manual: 500 ms)"
    )
    assert proof_result(failed).json() == {
        "result": "failed",
        "failure": "late",
        "trip_ms": 750,
        "cleared": None,
        "cleared_ms": None,
        "text": failed.text,
    }
    assert proof_status(late.status()).json() == {
        "policy": "block",
        "phase": "failed",
        "last": proof_result(failed).json(),
    }


def _try(proof: ProofTest, sent_ns: int, trip_after_ns: int) -> int:
    """One try on a VSC whose bits are seen ``trip_after_ns`` after the last heartbeat sent
    (at ``sent_ns``) and clear 50 ms after the heartbeat resumed; when the try ended."""
    proof.sent(sent_ns)
    proof.advance(sent_ns + 10 * MS, True, 1, LOCAL)
    assert proof.withholding
    proof.heartbeat(LOCAL, 0x80, sent_ns + trip_after_ns)
    if proof.phase is Phase.FAILED:
        return sent_ns + trip_after_ns
    proof.sent(sent_ns + trip_after_ns + 50 * MS)
    proof.heartbeat(LOCAL, 0, sent_ns + trip_after_ns + 100 * MS)
    return sent_ns + trip_after_ns + 100 * MS


def test_a_new_start_counts_the_late_tries_again() -> None:
    """SR-5.7 with SR-5.6 (a new start proves the watchdog again): a restart forgets the late
    tries of the test it interrupts, so a trip in time then passes at once, and a watchdog
    late every time fails on the LATE_TRIES-th late try after the restart, not sooner or later."""
    late, in_time = 750 * MS, 550 * MS
    proof = ProofTest(ProofTestPolicy.BLOCK, 10_000 * MS, late_tries=2)
    end = _try(proof, START_NS, late)
    assert proof.phase is Phase.WAITING  # late once of two: measured again
    proof.restart()
    _try(proof, end + 1_000 * MS, in_time)
    outcome = proof.take_outcome()
    assert outcome is not None
    assert outcome.passed

    proof = ProofTest(ProofTestPolicy.BLOCK, 10_000 * MS, late_tries=2)
    end = _try(proof, START_NS, late)
    proof.restart()
    end = _try(proof, end + 1_000 * MS, late)
    assert proof.phase is Phase.WAITING
    assert proof.take_outcome() is None
    _try(proof, end + 1_000 * MS, late)
    outcome = proof.take_outcome()
    assert outcome is not None
    assert outcome.failure is Failure.LATE


def test_the_wait_for_key_85_runs_from_the_first_heartbeat_since_the_restart() -> None:
    """SR-5.3: key 85 is waited for 3 s from the first VSC heartbeat since the (re)start, not
    from one heard before it: a restart starts the wait again."""
    proof = ProofTest(ProofTestPolicy.BLOCK, 10_000 * MS)
    proof.heartbeat(LOCAL, 0, START_NS)
    assert proof.next_limit(None) == START_NS + KEY85_WAIT_NS
    proof.restart()
    assert proof.next_limit(None) is None
    proof.heartbeat(LOCAL, 0, START_NS + 2_000 * MS)
    assert proof.next_limit(None) == START_NS + 2_000 * MS + KEY85_WAIT_NS
    proof.advance(START_NS + 2_000 * MS + KEY85_WAIT_NS - 1, False, None, LOCAL)
    assert proof.phase is Phase.WAITING


def test_the_next_deadline_is_the_phase_s_own() -> None:
    """SR-5.6, SR-5.7: the proof test moves with time alone at the end of the withholding
    (1.5 s after the last heartbeat sent) and at the end of the wait for the bits to clear
    (counted from the first heartbeat sent again); nothing before that heartbeat and nothing
    once it has passed."""
    proof = ProofTest(ProofTestPolicy.BLOCK, 2_000 * MS)
    proof.sent(START_NS)
    proof.advance(START_NS + 10 * MS, True, 1, LOCAL)
    assert proof.next_limit(1) == START_NS + WITHHOLD_LIMIT_NS
    proof.heartbeat(LOCAL, 0x80, START_NS + 600 * MS)
    assert proof.phase is Phase.RESUMED
    assert proof.next_limit(1) is None  # no heartbeat sent again yet
    proof.sent(START_NS + 650 * MS)
    assert proof.next_limit(1) == START_NS + 650 * MS + 2_000 * MS
    proof.heartbeat(LOCAL, 0, START_NS + 700 * MS)
    assert proof.status().phase is Phase.PASSED
    assert proof.next_limit(1) is None


def test_the_cause_shows_the_failure_only_while_failed() -> None:
    """SR-5.7: ``vsc_watchdog_untested`` shows what was observed while the test has failed;
    after a restart (a pass or a failure before it) it shows why: not proven since the link
    opened."""
    reason = (("reason", "the VSC's watchdog is not proven since the link opened"),)
    proof = ProofTest(ProofTestPolicy.BLOCK, 10_000 * MS, late_tries=1)
    end = _try(proof, START_NS, 750 * MS)
    assert proof.phase is Phase.FAILED
    outcome = proof.take_outcome()
    assert outcome is not None
    assert proof.details() == (("observed", outcome.text),)
    proof.restart()
    assert proof.details() == reason
    proof = ProofTest(ProofTestPolicy.BLOCK, 10_000 * MS)
    _try(proof, end, 550 * MS)
    assert proof.phase is Phase.PASSED
    proof.restart()
    assert proof.untested
    assert proof.details() == reason


def test_a_key_85_failure_restarts_once_key_85_reads_1() -> None:
    """SR-5.3, SR-5.4: a test failed because key 85 does not read 1 starts again once it reads
    1 (commissioned since), and only then: another reading of 0 is no new failure, and once
    started, a later reading of 1 does not interrupt the withholding."""
    proof = ProofTest(ProofTestPolicy.BLOCK, 10_000 * MS)
    proof.sent(START_NS)
    proof.advance(START_NS, True, 0, LOCAL)
    outcome = proof.take_outcome()
    assert outcome is not None
    assert outcome.failure is Failure.KEY85_OFF
    proof.advance(START_NS + 1_000 * MS, True, 0, LOCAL)
    assert proof.phase is Phase.FAILED
    assert proof.take_outcome() is None
    proof.sent(START_NS + 2_000 * MS)
    proof.advance(START_NS + 2_000 * MS, True, 1, LOCAL)
    assert proof.withholding
    proof.advance(START_NS + 2_100 * MS, True, 1, LOCAL)
    assert proof.withholding


def test_a_late_failure_does_not_restart_when_key_85_reads_1() -> None:
    """SR-5.7: only a key-85 failure waits for key 85; a watchdog that tripped late stays
    failed whatever key 85 reads."""
    proof = ProofTest(ProofTestPolicy.BLOCK, 10_000 * MS, late_tries=1)
    end = _try(proof, START_NS, 750 * MS)
    proof.advance(end + 1_000 * MS, True, 1, LOCAL)
    assert proof.phase is Phase.FAILED


@pytest.mark.parametrize("mode", [OPERATIONAL, LOCAL])
def test_a_vsc_operational_at_the_start_must_leave_operational(mode: int) -> None:
    """SR-5.6: the test sees the VSC report the bits and leave Operational if it was there: a
    VSC Operational at the start that reports the bits but stays Operational is no pass, and
    is the failure ``stayed_operational`` at the withholding's limit; a VSC not Operational at
    the start passes on the bits alone."""
    proof = ProofTest(ProofTestPolicy.BLOCK, 10_000 * MS, late_tries=1)
    proof.sent(START_NS)
    proof.advance(START_NS + 10 * MS, True, 1, mode)
    proof.heartbeat(OPERATIONAL, 0x80, START_NS + 600 * MS)
    if mode == OPERATIONAL:
        assert proof.withholding
        proof.advance(START_NS + WITHHOLD_LIMIT_NS, True, 1, OPERATIONAL)
        outcome = proof.take_outcome()
        assert outcome is not None
        assert outcome.failure is Failure.STAYED_OPERATIONAL
    else:
        assert proof.phase is Phase.RESUMED


@pytest.mark.parametrize("interrupt", ["abort", "restart"])
def test_an_interrupted_test_leaves_no_trip_time_behind(interrupt: str) -> None:
    """SR-5.6: the record carries the trip time measured by its own test: a test interrupted
    after its trip (a stop of the supervisor's own, or a new start) and then failed because
    key 85 no longer reads 1 records no trip."""
    proof = ProofTest(ProofTestPolicy.BLOCK, 10_000 * MS)
    proof.sent(START_NS)
    proof.advance(START_NS + 10 * MS, True, 1, LOCAL)
    proof.heartbeat(LOCAL, 0x80, START_NS + 600 * MS)
    proof.sent(START_NS + 650 * MS)
    assert proof.phase is Phase.RESUMED
    getattr(proof, interrupt)()
    proof.advance(START_NS + 700 * MS, True, 0, LOCAL)
    outcome = proof.take_outcome()
    assert outcome is not None
    assert outcome.failure is Failure.KEY85_OFF
    assert outcome.trip_ms is None


@pytest.mark.parametrize(
    ("after_ns", "failed"), [(WITHHOLD_LIMIT_NS - 1, False), (WITHHOLD_LIMIT_NS, True)]
)
def test_no_trip_fails_at_exactly_1_5_s_of_withholding(after_ns: int, failed: bool) -> None:
    """SR-5.7 (docs/safety.md "The proof test", step 5: no trip within 1.5 s is ``no_trip``):
    a nanosecond before 1.5 s the heartbeat is still withheld; at 1.5 s the test fails."""
    assert WITHHOLD_LIMIT_NS == 1_500 * MS
    proof = ProofTest(ProofTestPolicy.BLOCK, 10_000 * MS, late_tries=1)
    proof.sent(START_NS)
    proof.advance(START_NS + 10 * MS, True, 1, LOCAL)
    proof.advance(START_NS + after_ns, True, 1, LOCAL)
    outcome = proof.take_outcome()
    if failed:
        assert outcome is not None
        assert outcome.failure is Failure.NO_TRIP
    else:
        assert outcome is None
        assert proof.withholding


@pytest.mark.parametrize(("after_ns", "counted"), [(400 * MS - 1, False), (400 * MS, True)])
def test_a_trip_sooner_than_400_ms_proves_nothing(after_ns: int, counted: bool) -> None:
    """SR-5.6 (docs/safety.md "The proof test"): bits seen sooner than 400 ms after the last
    heartbeat sent were on their way before the test: it starts again; from 400 ms on they
    are the watchdog's trip."""
    proof = ProofTest(ProofTestPolicy.BLOCK, 10_000 * MS, late_tries=1)
    proof.sent(START_NS)
    proof.advance(START_NS + 10 * MS, True, 1, LOCAL)
    proof.heartbeat(LOCAL, 0x80, START_NS + after_ns)
    assert proof.phase is (Phase.RESUMED if counted else Phase.WAITING)


def test_a_watchdog_late_three_times_fails_on_the_third() -> None:
    """SR-5.7: a trip late on each of three tries fails, on the third and not sooner."""
    assert LATE_TRIES == 3
    proof = ProofTest(ProofTestPolicy.BLOCK, 10_000 * MS)
    end = START_NS
    for _ in range(LATE_TRIES - 1):
        end = _try(proof, end + 1_000 * MS, 750 * MS)
        assert proof.phase is Phase.WAITING
        assert proof.take_outcome() is None
    _try(proof, end + 1_000 * MS, 750 * MS)
    outcome = proof.take_outcome()
    assert outcome is not None
    assert outcome.failure is Failure.LATE


def test_bits_cleared_after_the_clear_limit_turn_the_failure_into_a_pass() -> None:
    """SR-5.6 (docs/safety.md "The proof test", step 5): bits not clear within
    ``prooftest_clear_ms`` fail the test, and bits that clear later still turn it into a pass
    (held); a test failed otherwise (late) stays failed when its bits clear."""
    proof = ProofTest(ProofTestPolicy.BLOCK, 1_000 * MS)
    proof.sent(START_NS)
    proof.advance(START_NS + 10 * MS, True, 1, LOCAL)
    proof.heartbeat(LOCAL, 0x80, START_NS + 550 * MS)
    resumed = START_NS + 600 * MS
    proof.sent(resumed)
    proof.advance(resumed + 1_000 * MS, True, 1, LOCAL)
    failed = proof.take_outcome()
    assert failed is not None
    assert failed.failure is Failure.NOT_CLEARED
    proof.heartbeat(LOCAL, 0, resumed + 1_200 * MS)
    passed = proof.take_outcome()
    assert passed is not None
    assert passed.passed
    assert passed.cleared is Cleared.HELD
    assert passed.cleared_ms == 1_200

    late = ProofTest(ProofTestPolicy.BLOCK, 10_000 * MS, late_tries=1)
    end = _try(late, START_NS, 750 * MS)
    late.sent(end + 50 * MS)
    late.heartbeat(LOCAL, 0, end + 100 * MS)
    assert late.phase is Phase.FAILED


def test_a_late_try_that_clears_only_after_the_clear_limit_is_measured_again() -> None:
    """SR-5.7: a late trip proves nothing, however its bits clear. A late try (not the last)
    whose bits stay set past ``prooftest_clear_ms`` fails ``not_cleared``; when they clear
    later the test runs again, and is no pass with the late trip's time (the late clear that
    turns a trip in time into a pass, held, does not apply to a late one)."""
    proof = ProofTest(ProofTestPolicy.BLOCK, 1_000 * MS, late_tries=2)
    proof.sent(START_NS)
    proof.advance(START_NS + 10 * MS, True, 1, LOCAL)
    proof.heartbeat(LOCAL, 0x80, START_NS + 750 * MS)  # late: 750 ms after the last heartbeat
    resumed = START_NS + 800 * MS
    proof.sent(resumed)
    proof.advance(resumed + 1_000 * MS, True, 1, LOCAL)
    failed = proof.take_outcome()
    assert failed is not None
    assert failed.failure is Failure.NOT_CLEARED
    proof.heartbeat(LOCAL, 0, resumed + 1_200 * MS)
    assert proof.take_outcome() is None  # no pass
    assert proof.phase is Phase.WAITING  # measured again
    _try(proof, resumed + 2_000 * MS, 550 * MS)
    passed = proof.take_outcome()
    assert passed is not None
    assert passed.passed
    assert passed.trip_ms == 550


def test_a_try_in_time_after_an_aborted_late_try_passes_at_once() -> None:
    """SR-5.7, SR-5.6: a late try interrupted while its bits clear (a stop of our own aborts
    it) leaves nothing pending: the next try, in time, passes when its bits clear, and is not
    measured yet again."""
    proof = ProofTest(ProofTestPolicy.BLOCK, 10_000 * MS, late_tries=3)
    proof.sent(START_NS)
    proof.advance(START_NS + 10 * MS, True, 1, LOCAL)
    proof.heartbeat(LOCAL, 0x80, START_NS + 750 * MS)  # late
    assert proof.status().phase is Phase.RESUMED
    proof.abort()
    assert proof.status().phase is Phase.WAITING
    _try(proof, START_NS + 2_000 * MS, 550 * MS)
    passed = proof.take_outcome()
    assert passed is not None
    assert passed.passed
    assert passed.trip_ms == 550


def test_a_late_try_measured_again_leaves_no_trip_time_behind() -> None:
    """SR-5.6, SR-5.7: a late try whose bits cleared is measured again from nothing: failed
    then because key 85 no longer reads 1, the record has no trip time of the late try."""
    proof = ProofTest(ProofTestPolicy.BLOCK, 10_000 * MS, late_tries=2)
    end = _try(proof, START_NS, 750 * MS)
    assert proof.phase is Phase.WAITING
    proof.advance(end + 50 * MS, True, 0, LOCAL)
    outcome = proof.take_outcome()
    assert outcome is not None
    assert outcome.failure is Failure.KEY85_OFF
    assert outcome.trip_ms is None


def test_a_late_reading_is_measured_again_and_one_in_time_passes() -> None:
    """SR-5.7: a trip seen late because the reading was late (here the VSC's heartbeat that
    carries the bits came 300 ms late, as on a stalled machine, within a 1 s link timeout) is no
    failure yet: the bits clear, the test runs again, and a trip seen in time passes. A
    watchdog late on every one of the LATE_TRIES tries fails
    (``test_the_late_limit_is_700_ms_whatever_the_vsc_timeout``)."""
    vsc = Vsc(replace(BLOCK, vsc_timeout_ms=1000))
    vsc.run(450)  # withholding since the heartbeat sent at 50 ms: the trip is due at 550 ms
    vsc.beat(350)  # read at 800 ms: 750 ms after the last heartbeat, late
    assert vsc.status().phase is Phase.RESUMED
    assert vsc.records() == []
    vsc.run(2000)
    status = vsc.status()
    assert status.phase is Phase.PASSED
    assert status.last is not None
    assert status.last.trip_ms is not None
    assert status.last.trip_ms <= 700
    assert len(vsc.records()) == 1
    assert LATE_TRIES == 3


def test_a_trip_too_soon_after_the_last_heartbeat_proves_nothing_and_the_test_runs_again() -> None:
    """SR-5.6: bits that show 50 ms into the withholding were on their way before it (the VSC
    tripped on an earlier gap): no pass is recorded for them; once they clear the test runs
    again and passes on a real 500 ms trip."""
    vsc = Vsc()

    def phase() -> Phase:
        status = vsc.status()
        return status.phase

    for _ in range(20):  # until the withholding begins (the VSC heard, key 85 read back)
        vsc.beat()
        if vsc.status().phase is Phase.WITHHOLDING:
            break
    assert vsc.status().phase is Phase.WITHHOLDING
    vsc.held = True  # an old trip: the VSC reports the bits at once
    vsc.beat()
    vsc.held = False
    assert vsc.records() == []
    assert vsc.status().phase is Phase.WAITING
    vsc.run(2000)
    status = vsc.status()
    assert status.phase is Phase.PASSED
    assert status.last is not None
    assert status.last.trip_ms is not None
    assert status.last.trip_ms >= 500
    assert len(vsc.records()) == 1


def test_a_bit_that_never_clears_fails_after_the_clear_limit() -> None:
    """SR-5.3: a bit still set ``prooftest_clear_ms`` after the heartbeat resumed fails."""
    vsc = Vsc(replace(BLOCK, prooftest_clear_ms=1000))
    vsc.never_clears = True
    vsc.run(2500)
    assert vsc.failure() == "NOT_CLEARED"


def test_a_bit_held_until_a_takeover_passes_as_held() -> None:
    """SR-5.3: a bit that clears later than 500 ms after the heartbeat resumed passes, and
    the record says it was held."""
    vsc = Vsc()
    vsc.holds = True
    vsc.run(2000)
    status = vsc.status()
    assert status.phase is Phase.RESUMED
    vsc.held = False  # the operator's gesture on the remote
    vsc.holds = False
    vsc.beat()
    status = vsc.status()
    assert status.phase is Phase.PASSED
    assert status.last is not None
    assert status.last.cleared is not None
    assert status.last.cleared.value == "held"


def test_key85_off_cannot_pass() -> None:
    """SR-5.3: with key 85 reading 0 there is nothing to prove: the proof test fails."""
    vsc = Vsc(replace(BLOCK, require_watchdog=False))
    vsc.feed(VscReceived(vsc.now, FeedbackSet(85, 0)))
    vsc.run(200)
    assert vsc.failure() == "KEY85_OFF"


def test_the_record_policy_records_a_failure_and_lets_a_takeover_run() -> None:
    """The ``record`` policy: a failure is a momentary stop, latched until a re-arm."""
    vsc = Vsc(replace(BLOCK, prooftest=ProofTestPolicy.RECORD), trip_ms=None)
    vsc.run(2500)
    cause = vsc.proof.cause(UNTESTED)
    assert cause is not None
    assert cause.latched
    assert not cause.active
    assert vsc.takeover().state is State.RUN


@pytest.mark.parametrize("by", ["local", "client"])
def test_a_stop_of_our_own_aborts_the_withholding_at_once(by: str) -> None:
    """SR-5.2: a local or a client's e-stop during the withholding sends the heartbeat with
    the byte at once; the proof test waits and runs again once the stop condition is clear."""
    vsc = Vsc()
    vsc.feed(ClientConnected(vsc.now, 1))
    vsc.run(200)
    assert vsc.proof.prooftest is not None
    assert vsc.proof.prooftest.phase is Phase.WITHHOLDING
    stop = LocalEstop(vsc.now, ADMIN) if by == "local" else ClientEstop(vsc.now, 1)
    decision = vsc.feed(stop)
    assert UserHeartbeat(1) in decision.frames
    assert decision.prooftest is not None
    assert decision.prooftest.phase is Phase.WAITING


def test_a_required_client_not_there_yet_does_not_keep_the_proof_test_waiting() -> None:
    """SR-8.15: with a required client never connected, the proof test runs and passes with
    the byte at 0, the byte is 1 again once it passed, the robot stays STOPPED until the
    client is there, and then the operator's takeover reaches RUN."""
    vsc = Vsc(replace(BLOCK, clients=(ClientSpec("motion"),)))
    lost = "client_lost:motion"
    vsc.run(1000)
    status = vsc.status()
    assert status.phase is Phase.PASSED, status
    assert lost in vsc.proof.active_names
    withholding = [
        d for d in vsc.decisions if d.prooftest and d.prooftest.phase is Phase.WITHHOLDING
    ]
    assert withholding, "the heartbeat was never withheld"
    unfinished = [  # once the VSC is heard: until then vsc_link_lost sets the byte
        d
        for d in vsc.decisions
        if d.prooftest
        and d.prooftest.phase is not Phase.PASSED
        and "vsc_link_lost" not in d.active_names
    ]
    assert {d.heartbeat_estop for d in unfinished} == {0}
    assert [f for d in unfinished for f in d.frames if f == UserHeartbeat(1)] == []
    assert vsc.proof.heartbeat_estop == 1  # the test is over: the missing client's byte again
    assert vsc.takeover().state is State.STOPPED  # refused: the client is missing (SR-2.4)
    vsc.feed(ClientConnected(vsc.now, 1))
    vsc.feed(ClientHello(vsc.now, 1, "motion"))
    vsc.mode = LOCAL
    for _ in range(20):  # 1 s in Local with the client beating: every stop clear
        vsc.beat()
        vsc.feed(ClientHeartbeat(vsc.now, 1))
    assert lost not in vsc.proof.active_names
    assert vsc.proof.heartbeat_estop == 0
    vsc.mode = PAUSE
    for _ in range(6):
        vsc.beat()
        vsc.feed(ClientHeartbeat(vsc.now, 1))
    vsc.mode = OPERATIONAL
    assert vsc.beat().state is State.RUN


def test_a_required_client_lost_after_the_proof_test_sets_the_byte_at_once() -> None:
    """SR-8.15, SR-5.2: the exception ends with the proof test: a required client that goes
    silent once the test has passed sends the byte at 1 at once, as every stop of ours."""
    vsc = Vsc(replace(BLOCK, clients=(ClientSpec("motion"),)))
    vsc.feed(ClientConnected(vsc.now, 1))
    vsc.feed(ClientHello(vsc.now, 1, "motion"))
    vsc.feed(ClientHeartbeat(vsc.now, 1))
    for _ in range(8):  # within the client's 500 ms timeout
        vsc.beat()
        vsc.feed(ClientHeartbeat(vsc.now, 1))
    vsc.run(1000)  # the client silent: lost during the test, which still passes
    assert vsc.status().phase is Phase.PASSED
    assert "client_lost:motion" in vsc.proof.active_names
    assert vsc.proof.heartbeat_estop == 1
    decision = vsc.feed(ClientDisconnected(vsc.now, 1))
    assert decision.heartbeat_estop == 1


def test_a_reconnect_and_a_silent_vsc_repeat_the_proof_test() -> None:
    """SR-4.4: a link that opens again, or a VSC silent for ``vsc_timeout`` (a reboot),
    is proven again before RUN."""
    vsc = Vsc()
    vsc.run(1000)
    vsc.now += 400 * MS  # silent: longer than the 200 ms timeout
    vsc.beat()
    assert UNTESTED in vsc.proof.active_names
    vsc.run(1000)
    assert len(vsc.records()) == 2
    vsc.feed(LinkOpened(vsc.now))
    assert UNTESTED in vsc.proof.active_names


def test_prooftest_request_admin_only_and_only_while_stopped() -> None:
    """SR-8.3: ``srcsctl prooftest`` is refused to a non-admin and in RUN; an admin's
    request while STOPPED starts a new proof test."""
    vsc = Vsc()
    vsc.run(1000)
    refused = vsc.feed(ProofTestRequest(vsc.now, NOBODY))
    assert [r.reason for r in refused.refusals] == [RefusalReason.NOT_ADMIN]
    started = vsc.feed(ProofTestRequest(vsc.now, ADMIN))
    assert not started.refusals
    assert UNTESTED in started.active_names
    vsc.run(1000)
    assert vsc.takeover().state is State.RUN
    in_run = vsc.feed(ProofTestRequest(vsc.now, ADMIN))
    assert [r.reason for r in in_run.refusals] == [RefusalReason.PROOFTEST_NOT_STOPPED]
    assert in_run.state is State.RUN


def test_can_and_hid_cannot_have_a_proof_test() -> None:
    """Choice 8: CAN and HID have no user heartbeat to withhold: only ``off`` is accepted,
    and the core built in code runs none unless asked (the TOML default is ``block``)."""
    with pytest.raises(ConfigError, match="cannot be proven"):
        SafetyConfig(
            transport=Transport.CAN, require_watchdog=False, prooftest=ProofTestPolicy.RECORD
        )
    core = SafetyCore(replace(ROBOT, clients=()), START_NS)
    assert core.decision.prooftest is not None
    assert core.decision.prooftest.phase is Phase.OFF
    assert UNTESTED not in core.handle(Tick(START_NS + 1)).active_names


def _at_a_failing_clear_limit() -> tuple[Vsc, int]:
    """A proof test whose VSC never clears, at the nanosecond its clear limit falls due (it
    fails with the next input); that time."""
    vsc = Vsc(replace(BLOCK, prooftest_clear_ms=1000))
    vsc.never_clears = True
    proof = vsc.core._proof  # the one deadline these tests need exactly
    while proof.phase is not Phase.RESUMED:
        vsc.beat()
    due = proof.next_limit(1)  # key 85 read as 1
    assert due is not None
    while vsc.now + 50 * MS < due:
        vsc.beat()
    vsc.now = due
    return vsc, due


def test_a_commissioning_and_a_proof_outcome_in_one_step_are_two_records() -> None:
    """SR-7.1: a commissioning that ends in the very step in which the proof test fails (its
    clear limit falls due then) gives two records, each of its own kind, the outcome only in
    the proof test's (seen in the daemon: the commissioning was filed as a prooftest record)."""
    vsc, due = _at_a_failing_clear_limit()
    decision = vsc.feed(Commissioned(due, ADMIN, None, remote_status=False))
    assert vsc.status().phase is Phase.FAILED
    notes = [r.note for r in decision.records]
    assert notes == [RecordNote.COMMISSIONED, RecordNote.PROOFTEST], notes
    assert decision.records[0].prooftest is None
    assert decision.records[1].prooftest is not None
    assert decision.records[1].sequence == decision.records[0].sequence + 1


def test_the_record_after_a_step_of_two_records_numbers_on_from_the_second() -> None:
    """SR-7.1: after a step that gives two records (a commissioning and a proof test's outcome),
    the next record's sequence number follows the second's: no number is given twice."""
    vsc, due = _at_a_failing_clear_limit()
    two = vsc.feed(Commissioned(due, ADMIN, None, remote_status=False)).records
    assert len(two) == 2
    vsc.now += 10 * MS
    after = vsc.feed(LocalEstop(vsc.now, ADMIN)).records  # a cause raised: one record
    assert [r.sequence for r in after] == [two[1].sequence + 1]


THIRTY_HZ = replace(BLOCK, heartbeat_hz=30)  # 3 s is no whole number of its periods


def _unanswered_key85() -> tuple[SafetyCore, int, list[Decision]]:
    """A core whose VSC is heard once and never answers key 85, with a user heartbeat whose
    cadence does not fall on 3 s after that; then only what the core asks for: a tick at each
    decision's deadline, as the daemon's loop does."""
    core = SafetyCore(THIRTY_HZ, START_NS)
    core.handle(LinkOpened(START_NS))
    heard = START_NS + 20 * MS
    decisions = [core.handle(VscReceived(heard, VscHeartbeat(LOCAL)))]
    while decisions[-1].now < heard + KEY85_WAIT_NS + 100 * MS:
        decisions.append(core.tick(decisions[-1].next_deadline))
    return core, heard, decisions


def test_key85_unanswered_fails_the_proof_test_at_3_s_exactly() -> None:
    """SR-5.7, SR-10.1: key 85 not answered within 3 s of the VSC being heard fails the proof
    test (``key85_off``) at exactly 3 s: the core asks to be woken then (found by the
    exhaustive exploration: the wait was no deadline, so the failure came with the next user
    heartbeat, up to 50 ms late), and not 1 ns before."""
    _, heard, decisions = _unanswered_key85()
    failed = [d for d in decisions for r in d.records if r.prooftest is not None]
    assert [d.now for d in failed] == [heard + KEY85_WAIT_NS]
    status = failed[0].prooftest
    assert status is not None
    assert status.last is not None
    assert status.last.failure is Failure.KEY85_OFF
    core = SafetyCore(THIRTY_HZ, START_NS)
    core.handle(LinkOpened(START_NS))
    core.handle(VscReceived(heard, VscHeartbeat(LOCAL)))
    before = core.tick(heard + KEY85_WAIT_NS - 1)
    assert before.prooftest is not None
    assert before.prooftest.phase is Phase.WAITING


def test_every_deadline_is_ahead_of_now_through_a_proof_test() -> None:
    """SR-10.1, docs/safety.md choice 17: while the user heartbeat is withheld its schedule
    stays in the past, and a step at its very time still asks for a later deadline, as every
    step does, before, during and after the proof test."""
    vsc = Vsc()
    vsc.run(1500)
    assert vsc.status().phase is Phase.PASSED
    assert all(d.next_deadline > d.now for d in vsc.decisions)


def test_a_proof_test_asked_for_as_the_last_withholding_ends_asks_for_a_later_deadline() -> None:
    """SR-2.11, SR-10.1 (P8): an admin's proof test asked for at the very nanosecond the last
    one's withholding reaches 1.5 s fails that one (``no_trip``) and withholds again from the
    last heartbeat sent, so the new withholding's limit is now; the decision still asks to be
    woken later than now, never at it."""
    vsc = Vsc(trip_ms=None)  # a watchdog that never trips
    while vsc.status().phase is not Phase.WITHHOLDING:
        vsc.beat()
    end = vsc.last_user + WITHHOLD_LIMIT_NS  # the withholding counts from the last beat sent
    while vsc.now + 50 * MS < end:
        vsc.beat()
    vsc.now = end
    decision = vsc.feed(ProofTestRequest(end, ADMIN))
    assert not decision.refusals
    status = decision.prooftest
    assert status is not None
    assert status.last is not None
    assert status.last.failure is Failure.NO_TRIP
    assert status.phase is Phase.WITHHOLDING  # the new test's limit: the last beat + 1.5 s, now
    assert decision.next_deadline > decision.now


def test_a_passed_proof_test_asks_for_no_more_deadlines() -> None:
    """SR-9.4, SR-10.1: once the proof test has passed it falls due at no time: no decision
    asks to be woken at the end of the withholding it no longer does (a 30 Hz heartbeat, so
    that the end falls between the user heartbeat's deadlines)."""
    vsc = Vsc(THIRTY_HZ)
    while vsc.status().phase is not Phase.WITHHOLDING:
        vsc.beat()
    withheld = vsc.core._proof._withheld_from  # the start the withholding's limit counts from
    assert withheld is not None
    while vsc.status().phase is not Phase.PASSED:
        vsc.beat()
    passed = len(vsc.decisions)
    end = withheld + WITHHOLD_LIMIT_NS
    while vsc.now < end + 100 * MS:
        if vsc.decisions[-1].next_deadline < vsc.now + 50 * MS:
            vsc.feed(Tick(vsc.decisions[-1].next_deadline))
        else:
            vsc.beat()
    assert vsc.status().phase is Phase.PASSED
    assert end not in [d.next_deadline for d in vsc.decisions[passed:]]


@pytest.mark.parametrize("policy", [ProofTestPolicy.BLOCK, ProofTestPolicy.RECORD])
def test_an_outcome_is_one_record_of_its_own_kind(policy: ProofTestPolicy) -> None:
    """SR-5.3, SR-7.1: the step in which a proof test passes makes one record, a ``prooftest``
    record whose text is the outcome's and which carries the outcome, whether or not a cause
    changed with it (under ``block`` the untested cause clears, under ``record`` nothing does)."""
    vsc = Vsc(replace(BLOCK, prooftest=policy))
    vsc.run(1000)
    assert vsc.status().phase is Phase.PASSED
    (decision,) = [d for d in vsc.decisions if any(r.prooftest for r in d.records)]
    (record,) = decision.records
    assert record.note is RecordNote.PROOFTEST
    assert record.prooftest is not None
    assert record.reason == record.prooftest.text
    untested = [c.kind for c in record.changes if c.cause.name == UNTESTED]
    assert untested == [ChangeKind.CLEARED]  # a pass raises nothing


def test_under_record_a_failure_is_a_stop_raised_with_what_was_observed() -> None:
    """SR-5.3, docs/safety.md "The proof test": under ``record`` the step in which the test
    fails raises ``vsc_watchdog_untested`` as a momentary stop (raised and clear, latched, a
    stop a takeover must come after) with what was observed in its details."""
    vsc = Vsc(replace(BLOCK, prooftest=ProofTestPolicy.RECORD), trip_ms=None)
    vsc.run(2500)
    (decision,) = [d for d in vsc.decisions if any(r.prooftest for r in d.records)]
    (record,) = decision.records
    assert record.prooftest is not None
    assert not record.prooftest.passed
    kinds = [c.kind for c in record.changes if c.cause.name == UNTESTED]
    assert kinds == [ChangeKind.RAISED]  # and clear at once: no condition of its own
    cause = decision.cause(UNTESTED)
    assert cause is not None
    assert (cause.active, cause.latched) == (False, True)
    assert cause.detail("observed") == record.prooftest.text


def test_a_vsc_silent_for_its_timeout_aborts_the_test_at_that_nanosecond() -> None:
    """SR-5.3, SR-2.2: a VSC silent for ``vsc_timeout`` is not heard, to the nanosecond: a
    test whose wait for the bits to clear ends at that very instant is aborted (tried again
    once the VSC is back), not failed on a VSC that is gone."""
    vsc = Vsc(replace(BLOCK, prooftest_clear_ms=1000))
    vsc.never_clears = True
    proof = vsc.core._proof  # the one deadline this test needs exactly
    for _ in range(60):  # within 3 s the heartbeat is withheld, the bit trips, it resumes
        if proof.phase is Phase.RESUMED and proof.next_limit(1) is not None:
            break
        vsc.beat()
    due = proof.next_limit(1)
    assert due is not None
    silent_from = due - 200 * MS  # the VSC's last heartbeat: its timeout falls on the due time
    while vsc.now + 50 * MS <= silent_from:  # at most 1 s of heartbeats
        vsc.beat()
    vsc.beat((silent_from - vsc.now) // MS)
    assert vsc.now == silent_from
    assert vsc.status().phase is Phase.RESUMED
    vsc.now = due
    decision = vsc.feed(Tick(due))
    assert "vsc_link_lost" in decision.active_names
    assert vsc.status().phase is Phase.WAITING
    assert not any(r.prooftest for r in decision.records)


def test_a_vsc_silent_for_its_timeout_is_proven_again() -> None:
    """SR-5.6, docs/safety.md "The proof test": a VSC silent for ``vsc_timeout`` (200 ms, to
    the nanosecond, as for ``vsc_link_lost``) may have rebooted, so its watchdog is proven
    again; a gap 1 ms shorter is no silence and keeps the pass."""
    vsc = Vsc()
    vsc.run(1000)
    assert vsc.status().phase is Phase.PASSED
    vsc.beat(199)
    assert vsc.status().phase is Phase.PASSED
    vsc.beat(200)
    assert vsc.status().phase is not Phase.PASSED
    assert UNTESTED in vsc.proof.active_names


@pytest.mark.parametrize("down", [LinkBroken, LinkClosed])
def test_a_link_that_went_down_is_proven_again(down: type[LinkBroken | LinkClosed]) -> None:
    """SR-5.6: a link that broke or closed may come back to another VSC, or to one that
    rebooted: from the moment it went down, the watchdog is untested again."""
    vsc = Vsc()
    vsc.run(1000)
    assert vsc.status().phase is Phase.PASSED
    vsc.now += 10 * MS
    decision = vsc.feed(down(vsc.now, "unplugged"))
    assert UNTESTED in decision.active_names
    assert vsc.status().phase is Phase.WAITING


def test_a_proof_test_is_refused_when_there_is_none_or_one_runs() -> None:
    """SR-5.3, docs/safety.md "The proof test": ``srcsctl prooftest`` is refused by name when
    the policy is ``off`` (``prooftest_not_possible``) and while a test runs
    (``prooftest_running``)."""
    core = SafetyCore(replace(ROBOT, clients=()), START_NS)
    off = core.handle(ProofTestRequest(START_NS + 1, ADMIN))
    assert [r.reason for r in off.refusals] == [RefusalReason.PROOFTEST_NOT_POSSIBLE]
    vsc = Vsc()
    while vsc.status().phase is not Phase.WITHHOLDING:
        vsc.beat()
    running = vsc.feed(ProofTestRequest(vsc.now, ADMIN))
    assert [r.reason for r in running.refusals] == [RefusalReason.PROOFTEST_RUNNING]
    assert vsc.status().phase is Phase.WITHHOLDING


@pytest.mark.parametrize("cheap_path", [True, False])
def test_a_proof_test_asked_for_as_the_withholding_begins_is_refused_as_running(
    cheap_path: bool,
) -> None:
    """SR-5.3, SR-9.4: the first input after the VSC is heard and key 85 answered begins the
    withholding before it is applied (step 1, also before the next deadline and with the
    cheap path on), so an admin's ``srcsctl prooftest`` then is refused as running."""
    core = SafetyCore(BLOCK, START_NS)
    core.cheap_path = cheap_path
    core.handle(LinkOpened(START_NS))
    core.handle(VscReceived(START_NS, VscHeartbeat(OPERATIONAL, 0, 0)))
    ready = core.handle(VscReceived(START_NS, FeedbackSet(85, 1)))
    assert ready.prooftest is not None
    assert ready.prooftest.phase is Phase.WAITING
    now = START_NS + 10 * MS
    assert now < ready.next_deadline
    decision = core.handle(ProofTestRequest(now, ADMIN))
    assert [r.reason for r in decision.refusals] == [RefusalReason.PROOFTEST_RUNNING]
    assert decision.prooftest is not None
    assert decision.prooftest.phase is Phase.WITHHOLDING
