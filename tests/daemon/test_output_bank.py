"""The output bank with real output drivers: sim outputs mirrored to files (a folder that is
not there yet is an output that cannot be acquired), a CAN enable output on python-can's
virtual bus with an observer on the same channel, and the safety core's own decisions (the
safety tests' rig) applied to them; time passed as ``now`` and a clock the test moves
(SR-4, SR-6, SR-9.4, SR-9.5, SR-12.1). The bank in the real loop, with a pty VSC, is
``tests/daemon/test_loop.py``, ``test_reflex.py`` and ``test_steady_path.py``."""

from __future__ import annotations

import logging
import uuid
from collections.abc import Iterator
from pathlib import Path

import can
import pytest

from supervisord.daemon.output_bank import ACQUIRE_FIRST_MS, OutputBank
from supervisord.daemon.stoptimes import StopTimes
from supervisord.outputs.base import OutputFault
from supervisord.outputs.can_enable import CanEnableOutput
from supervisord.outputs.gpio import GpioOutput, GpioSpec
from supervisord.outputs.sim import SimOutput, SimSpec
from supervisord.protocol.codes import VscMode
from supervisord.protocol.messages import VscHeartbeat
from supervisord.safety.events import OutputReadback
from supervisord.safety.transitions import State
from supervisord.testkit.clock import FakeClock
from tests.outputs.conftest import CAN_SPEC, BusWatcher
from tests.safety.rig import MS, OPERATIONAL, START_NS, Rig

REMOTE_ESTOP = 0x01


def sim(tmp_path: Path, name: str) -> SimOutput:
    return SimOutput(SimSpec(name=name, path=tmp_path / name))


def level(tmp_path: Path, name: str) -> str:
    return (tmp_path / name).read_text().strip()


def drive_and_lights(tmp_path: Path) -> tuple[FakeClock, StopTimes, OutputBank]:
    """A bank of two simulated outputs, ``drive`` and ``lights``, opened on a fake clock, with
    its stop times: built in the test's body, where the mutation runner traces it."""
    clock = FakeClock(START_NS)
    times = StopTimes()
    bank = OutputBank([sim(tmp_path, "drive"), sim(tmp_path, "lights")], clock, times)
    bank.open(clock())
    return clock, times, bank


@pytest.fixture
def rig() -> Rig:
    """The core of a robot with a motion output ``drive`` and a power output ``lights``."""
    return Rig()


@pytest.fixture
def buses() -> Iterator[tuple[can.BusABC, can.BusABC]]:
    channel = f"bank-{uuid.uuid4()}"
    mine = can.Bus(interface="virtual", channel=channel)
    theirs = can.Bus(interface="virtual", channel=channel)
    yield mine, theirs
    mine.shutdown()
    theirs.shutdown()


def test_an_output_that_cannot_be_acquired_is_retried_with_a_backoff_until_it_is(
    tmp_path: Path,
) -> None:
    """SR-4, SR-6: every output is acquired off at the start; one that cannot be (its folder
    is missing) reads back no level, is named in ``not_acquired``, and is retried at its
    backoff's times, doubling, until it opens off; then nothing is left to retry."""
    clock = FakeClock(START_NS)
    now = clock()
    drive = sim(tmp_path, "drive")
    lights = SimOutput(SimSpec(name="lights", path=tmp_path / "later" / "lights"))
    bank = OutputBank([drive, lights], clock, StopTimes())
    events = bank.open(now)
    assert events == [
        OutputReadback(now, "drive", False, False),
        OutputReadback(now, "lights", False, None),  # no level: output_fault:lights
    ]
    assert level(tmp_path, "drive") == "0"
    assert bank.not_acquired() == ("lights",)
    first = now + ACQUIRE_FIRST_MS * MS
    assert bank.next_deadline(now + 10_000 * MS) == first
    assert list(bank.due(first - 1)) == []
    assert list(bank.due(first)) == []  # still missing: the next try twice as late
    assert bank.next_deadline(now + 10_000 * MS) == first + 2 * ACQUIRE_FIRST_MS * MS
    (tmp_path / "later").mkdir()
    later = first + 2 * ACQUIRE_FIRST_MS * MS
    assert list(bank.due(later)) == [OutputReadback(later, "lights", False, False)]
    assert lights.is_open
    assert (tmp_path / "later" / "lights").read_text() == "0\n"
    assert bank.not_acquired() == ()
    assert bank.next_deadline(later + 10_000 * MS) == later + 10_000 * MS  # nothing of its own


def test_applying_sets_each_level_once_and_the_steady_test_holds_until_something_else_drives(
    tmp_path: Path, rig: Rig
) -> None:
    """SR-6, SR-9.4: the core's decision in RUN switches both outputs on (one read-back each,
    for the core); applied again, nothing is written and ``unchanged`` says so for that very
    mapping, and for no other; an output not acquired, or acquired since, makes the next
    decision set every level again."""
    clock = FakeClock(START_NS)
    drive = sim(tmp_path, "drive")
    lights = SimOutput(SimSpec(name="lights", path=tmp_path / "later" / "lights"))
    bank = OutputBank([drive, lights], clock, StopTimes())
    bank.open(clock())
    running = rig.bring_up()
    readbacks, off_ns = bank.apply(running, stopping=False)
    assert [(r.name, r.requested, r.ok) for r in readbacks] == [("drive", True, True)]
    assert off_ns is None
    assert level(tmp_path, "drive") == "1"
    assert not bank.unchanged(running.outputs)  # lights is not acquired: not every level set
    (tmp_path / "later").mkdir()
    acquired = list(bank.due(clock.advance(ms=ACQUIRE_FIRST_MS)))
    assert [e.output for e in acquired] == ["lights"]
    assert not bank.unchanged(running.outputs)  # opened off: the next decision sets all
    readbacks, _ = bank.apply(running, stopping=False)
    assert [(r.name, r.requested) for r in readbacks] == [("lights", True)]
    assert bank.unchanged(running.outputs)
    assert not bank.unchanged(dict(running.outputs))  # equal levels, another decision's
    assert bank.apply(running, stopping=False) == ([], None)  # nothing written again


def test_the_reflexs_writes_are_the_stopping_decisions_own_and_time_the_stop(
    tmp_path: Path, rig: Rig
) -> None:
    """SR-9.5, SR-12.1, SR-9.2: a remote e-stop heartbeat heard in RUN switches every output
    off before the core is fed it; the steady test fails while those writes wait; the stop's
    decision writes nothing more, takes their read-backs, their times to off go to the stop
    times, and the stop is off when the reflex's last write returned."""
    clock, times, bank = drive_and_lights(tmp_path)
    rig.bring_up()
    rig.advance(20)
    clock.advance_to(rig.now)
    running = rig.last
    bank.apply(running, stopping=False)
    assert bank.unchanged(running.outputs)
    bank.heard(VscHeartbeat(OPERATIONAL, 0, REMOTE_ESTOP), rig.now, rig.core)
    written_ns = clock()
    assert (level(tmp_path, "drive"), level(tmp_path, "lights")) == ("0", "0")
    assert not bank.unchanged(running.outputs)  # the full path hands the writes on
    stop = rig.vsc(OPERATIONAL, REMOTE_ESTOP)
    assert stop.state is State.STOPPED
    record = next(r for r in stop.records if r.state is State.STOPPED)
    times.stopped(record, 1, bank.on())  # both on as the stop began: the reflex's
    clock.advance(ms=3)  # the stop's decision is applied later than the writes returned
    readbacks, off_ns = bank.apply(stop, stopping=True)
    assert sorted(r.name for r in readbacks) == ["drive", "lights"]
    assert all(r.ok and r.requested is False for r in readbacks)
    assert off_ns == written_ns  # the reflex wrote them all: its time, not the apply's
    measured = times.find(1)
    assert measured is not None
    assert measured.off_ns == {"drive": written_ns - stop.now, "lights": written_ns - stop.now}
    assert bank.unchanged(stop.outputs)


def test_a_periodic_duty_runs_at_its_deadline_and_a_failing_one_comes_back_as_an_event(
    buses: tuple[can.BusABC, can.BusABC],
) -> None:
    """SR-6: the CAN enable frame goes out every period from ``due`` (seen on the bus); the
    bank's deadline is the output's; a frame the bus refuses is a read-back with no level,
    handed back for the core (``output_fault:drive``)."""
    mine, theirs = buses
    clock = FakeClock(START_NS)
    drive = CanEnableOutput(CAN_SPEC, mine)
    watcher = BusWatcher(theirs, CAN_SPEC)
    bank = OutputBank([drive], clock, StopTimes())
    now = clock()
    assert [e.read_back for e in bank.open(now)] == [False]  # the off frame went out: read back
    watcher.drain()
    deadline = drive.next_deadline()
    assert deadline is not None
    assert bank.next_deadline(deadline + 1) == deadline
    assert list(bank.due(deadline - 1)) == []
    assert watcher.drain() == []
    assert list(bank.due(deadline)) == []  # a frame that went out: nothing to feed
    assert [watcher.level(m) for m in watcher.drain()] == [False]
    mine.shutdown()
    following = drive.next_deadline()
    assert following is not None
    assert following > deadline
    assert list(bank.due(following)) == [OutputReadback(following, "drive", False, None)]


def test_all_off_drives_every_output_off_though_one_fails_and_releases_them_at_the_end(
    tmp_path: Path, rig: Rig
) -> None:
    """SR-2, SR-6.6: the loop's internal fault drives every output off outside any decision
    (an output not acquired refuses the write; the others go off all the same) and the next
    decision sets every level again; the shutdown drives them off and releases them."""
    clock = FakeClock(START_NS)
    missing = SimOutput(SimSpec(name="gone", path=tmp_path / "nowhere" / "gone"))
    drive, lights = sim(tmp_path, "drive"), sim(tmp_path, "lights")
    bank = OutputBank([missing, drive, lights], clock, StopTimes())
    bank.open(clock())
    running = rig.bring_up()
    bank.apply(running, stopping=False)
    assert (level(tmp_path, "drive"), level(tmp_path, "lights")) == ("1", "1")
    bank.all_off(clock())
    assert (level(tmp_path, "drive"), level(tmp_path, "lights")) == ("0", "0")
    assert [o.is_open for o in (drive, lights)] == [True, True]  # driven off, still held
    assert not bank.unchanged(running.outputs)
    readbacks, _ = bank.apply(running, stopping=False)  # the core's levels again
    assert sorted(r.name for r in readbacks) == ["drive", "lights"]
    bank.all_off(clock(), close=True)
    assert (level(tmp_path, "drive"), level(tmp_path, "lights")) == ("0", "0")
    assert [o.is_open for o in (drive, lights)] == [False, False]  # released


def test_a_stuck_output_reads_back_its_fault_for_the_core(tmp_path: Path, rig: Rig) -> None:
    """SR-6: a line stuck off does not go on: the read-back carries the mismatch and the
    steady test still holds for those levels (they were written; the core decides the fault)."""
    clock = FakeClock(START_NS)
    drive, lights = sim(tmp_path, "drive"), sim(tmp_path, "lights")
    bank = OutputBank([drive, lights], clock, StopTimes())
    bank.open(clock())
    drive.stick(False)
    running = rig.bring_up()
    readbacks, _ = bank.apply(running, stopping=False)
    faults = {r.name: r.fault for r in readbacks}
    assert faults == {"drive": OutputFault.MISMATCH, "lights": None}
    assert level(tmp_path, "drive") == "0"
    assert bank.unchanged(running.outputs)


# The tests below build the bank in their body: the mutation runner traces a test's body, not
# its fixtures (docs/verification.md "The daemon's parts").


def test_acquisition_is_retried_after_half_a_second_doubling_to_ten_and_logged(
    tmp_path: Path, caplog: pytest.LogCaptureFixture
) -> None:
    """SR-4, SR-6 (docs/outputs.md): an output that cannot be acquired is tried again after
    0.5 s, doubling to 10 s (the figures themselves, not the module's names for them); the
    operator's log says it cannot be acquired (an error, once), each failed retry (debug) and
    when it is acquired at last (info)."""
    caplog.set_level(logging.DEBUG, logger="srcsd")
    clock = FakeClock(START_NS)
    now = clock()
    lights = SimOutput(SimSpec(name="lights", path=tmp_path / "later" / "lights"))
    bank = OutputBank([lights], clock, StopTimes())
    bank.open(now)
    errors = [r.getMessage() for r in caplog.records if r.levelno == logging.ERROR]
    assert len(errors) == 1
    assert errors[0].startswith("output lights cannot be acquired: ")
    tries = []
    for _ in range(7):
        now = bank.next_deadline(now + 60_000 * MS)
        assert list(bank.due(now - 1)) == []  # not before its time
        assert list(bank.due(now)) == []  # tried, still missing
        tries.append(now)
    gaps_ms = [(b - a) // MS for a, b in zip([START_NS, *tries], tries, strict=False)]
    assert gaps_ms == [500, 1_000, 2_000, 4_000, 8_000, 10_000, 10_000]
    retried = [r.getMessage() for r in caplog.records if r.levelno == logging.DEBUG]
    assert len([m for m in retried if m.startswith("output lights still cannot be acq")]) == 7
    (tmp_path / "later").mkdir()
    now = bank.next_deadline(now + 60_000 * MS)
    assert list(bank.due(now)) == [OutputReadback(now, "lights", False, False)]
    infos = [r.getMessage() for r in caplog.records if r.levelno == logging.INFO]
    assert "output lights acquired (off)" in infos


def test_a_pulsed_output_not_acquired_has_no_duty_until_it_is(tmp_path: Path) -> None:
    """SR-6: a GPIO output with a pulse (a periodic duty) whose chip is not there cannot be
    acquired; while it is not, the bank runs no duty of it and asks it for no deadline of its
    own: ``due`` only retries it (the real line request, on a chip path that does not exist)."""
    clock = FakeClock(START_NS)
    chip = tmp_path / "gpiochip9"
    pulse = GpioOutput(GpioSpec(name="pulse", chip=str(chip), line=3, pulse_period_ms=20))
    bank = OutputBank([pulse], clock, StopTimes())
    assert bank.open(clock()) == [OutputReadback(clock(), "pulse", False, None)]
    retry = clock() + ACQUIRE_FIRST_MS * MS
    assert bank.next_deadline(retry + 1) == retry
    assert list(bank.due(retry)) == []  # no duty of an output not open; the retry failed
    assert not pulse.is_open
    assert bank.not_acquired() == ("pulse",)


def test_an_output_acquired_after_a_complete_apply_makes_the_next_decision_set_every_level(
    tmp_path: Path,
) -> None:
    """SR-6, SR-9.4: an output the core's levels do not name (a ``horn`` beside the core's
    ``drive`` and ``lights``) can be retried while every level named is set, so the steady
    test holds; once it is acquired (off), the steady test fails until a decision sets every
    level again: the bank never relies on every decision naming every output."""
    clock = FakeClock(START_NS)
    drive, lights = sim(tmp_path, "drive"), sim(tmp_path, "lights")
    horn = SimOutput(SimSpec(name="horn", path=tmp_path / "later" / "horn"))
    bank = OutputBank([drive, lights, horn], clock, StopTimes())
    bank.open(clock())
    running = Rig().bring_up()
    bank.apply(running, stopping=False)
    assert bank.unchanged(running.outputs)  # every output named is set: horn is not named
    (tmp_path / "later").mkdir()
    acquired = list(bank.due(clock.advance(ms=ACQUIRE_FIRST_MS)))
    assert [e.output for e in acquired] == ["horn"]
    assert not bank.unchanged(running.outputs)  # opened since: the next decision sets all
    assert bank.apply(running, stopping=False) == ([], None)  # levels already right
    assert bank.unchanged(running.outputs)


def test_an_output_acquired_with_a_fault_reads_back_no_level(tmp_path: Path) -> None:
    """SR-6: a line acquired but stuck on reads back a fault at its acquisition; the core is
    handed no level for it (``output_fault:drive``), not the level the line shows."""
    clock = FakeClock(START_NS)
    drive = sim(tmp_path, "drive")
    drive.stick(True)
    bank = OutputBank([drive], clock, StopTimes())
    assert bank.open(clock()) == [OutputReadback(clock(), "drive", False, None)]
    assert drive.is_open  # acquired, faulty: held so that it can be released
    assert bank.not_acquired() == ()


def test_an_output_released_is_not_on_as_a_stop_begins(tmp_path: Path) -> None:
    """SR-9.5, SR-12.1: ``on`` names only outputs held: one written off by the reflex and
    then released (the shutdown's ``all_off(close=True)``) is no longer on."""
    rig = Rig()
    clock = FakeClock(START_NS)
    drive, lights = sim(tmp_path, "drive"), sim(tmp_path, "lights")
    bank = OutputBank([drive, lights], clock, StopTimes())
    bank.open(clock())
    rig.bring_up()
    rig.advance(20)
    clock.advance_to(rig.now)
    bank.apply(rig.last, stopping=False)
    assert bank.on() == ["drive", "lights"]
    bank.heard(VscHeartbeat(OPERATIONAL, 0, REMOTE_ESTOP), rig.now, rig.core)
    assert bank.on() == ["drive", "lights"]  # written off early: on as the stop begins
    bank.all_off(clock(), close=True)
    assert bank.on() == []


def test_a_stop_without_the_reflex_is_off_when_the_decisions_last_write_returned(
    tmp_path: Path,
) -> None:
    """SR-12.1, SR-9.2: a stop the reflex did not write (the decision's own off writes) is
    timed by those writes: each output's time to off is when its write returned, after it."""
    rig = Rig()
    clock, times, bank = drive_and_lights(tmp_path)
    bank.apply(rig.bring_up(), stopping=False)
    stop = rig.vsc(OPERATIONAL, REMOTE_ESTOP)
    assert stop.state is State.STOPPED
    clock.advance_to(stop.now)
    record = next(r for r in stop.records if r.state is State.STOPPED)
    times.stopped(record, 1, bank.on())
    clock.advance(ms=2)
    readbacks, off_ns = bank.apply(stop, stopping=True)
    assert sorted(r.name for r in readbacks) == ["drive", "lights"]
    assert off_ns == clock()
    measured = times.find(1)
    assert measured is not None
    assert measured.off_ns == {"drive": 2 * MS, "lights": 2 * MS}


def test_only_an_off_write_times_a_stop(tmp_path: Path) -> None:
    """SR-12.1: an output switched on again while its stop waits for its off write (driven
    off outside any decision by the loop's internal fault, then set on by the core's levels)
    is not counted off, nor faulted, by that on write: its later off write times it."""
    rig = Rig()
    clock, times, bank = drive_and_lights(tmp_path)
    running = rig.bring_up()
    bank.apply(running, stopping=False)
    stop = rig.vsc(OPERATIONAL, REMOTE_ESTOP)
    clock.advance_to(stop.now)
    record = next(r for r in stop.records if r.state is State.STOPPED)
    times.stopped(record, 1, bank.on())
    bank.all_off(clock())  # untimed: outside a decision
    readbacks, _ = bank.apply(running, stopping=False)
    assert [(r.name, r.requested) for r in readbacks] == [("drive", True), ("lights", True)]
    clock.advance(ms=5)
    bank.apply(stop, stopping=True)
    measured = times.find(1)
    assert measured is not None
    assert measured.off_ns == {"drive": 5 * MS, "lights": 5 * MS}


def test_a_stop_the_reflex_wrote_in_part_is_off_when_the_decisions_last_write_returned(
    tmp_path: Path,
) -> None:
    """SR-9.5, SR-12.1, SR-9.2: the reflex wrote the motion output off (a heartbeat whose mode
    is not operational holds: the power output stays on) and the stop's decision applied next
    switches the power output off too: the stop is off when that later write returned, not
    the reflex's; each output keeps its own time to off."""
    rig = Rig()
    clock, times, bank = drive_and_lights(tmp_path)
    rig.bring_up()
    rig.advance(20)
    clock.advance_to(rig.now)
    bank.apply(rig.last, stopping=False)
    bank.heard(VscHeartbeat(VscMode.PAUSE.value, 0, 0), rig.now, rig.core)
    assert (level(tmp_path, "drive"), level(tmp_path, "lights")) == ("0", "1")
    early_ns = clock()
    stop = rig.vsc(OPERATIONAL, REMOTE_ESTOP)
    record = next(r for r in stop.records if r.state is State.STOPPED)
    times.stopped(record, 1, bank.on())
    later_ns = clock.advance(ms=3)
    readbacks, off_ns = bank.apply(stop, stopping=True)
    assert sorted(r.name for r in readbacks) == ["drive", "lights"]
    assert off_ns == later_ns
    measured = times.find(1)
    assert measured is not None
    assert measured.off_ns == {"drive": early_ns - stop.now, "lights": later_ns - stop.now}
