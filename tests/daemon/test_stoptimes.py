"""Each stop's time to off per output, as the daemon keeps it for the field stop test
(SR-12.1; ``supervisord/daemon/stoptimes.py``): timed from the stop record's ``mono_ns``,
only verified off writes, and only a press of the named e-stop in RUN is a stop test."""

from __future__ import annotations

from supervisord.daemon.stoptimes import KEEP, StopTimes
from supervisord.outputs.base import OutputFault, ReadBack
from supervisord.protocol.messages import VscHeartbeat
from supervisord.safety.causes import Cause, CauseKind, CauseState, make_details
from supervisord.safety.decision import Record
from supervisord.safety.events import LocalEstop, VscReceived
from supervisord.safety.stoptest import LIMIT_MS
from supervisord.safety.transitions import State
from tests.safety.rig import ADMIN

MS = 1_000_000
STOP_NS = 1_000 * MS


def _stop(seq: int, sources: str = "remote", previous: State = State.RUN) -> Record:
    estop = CauseState(
        Cause(CauseKind.VSC_ESTOP), True, True, STOP_NS, None, make_details([("sources", sources)])
    )
    trigger = VscReceived(STOP_NS, VscHeartbeat(9, 0, 1))
    return Record(
        sequence=seq,
        monotonic_ns=STOP_NS,
        previous=previous,
        state=State.STOPPED,
        causes=(estop,),
        changes=(),
        trigger=trigger,
    )


def _off(name: str, *, fault: bool = False) -> ReadBack:
    if fault:
        return ReadBack(name, False, False, True, OutputFault.MISMATCH)
    return ReadBack(name, False, False, False)


def test_each_output_is_timed_from_the_frame_to_its_verified_off() -> None:
    """SR-12.1: an output's time is its off write's return, less the stop record's
    ``mono_ns`` (the frame's read stamp); the first verified off write counts, and an output
    whose off write did not read back off is never timed (it fails the test)."""
    times = StopTimes()
    times.stopped(_stop(41), 41, ["drive", "power", "brake"])
    assert times.waiting("drive")
    assert not times.waiting("lamp")  # not on at the stop: nothing to time
    times.off(_off("drive"), STOP_NS + 2 * MS)
    times.off(_off("drive"), STOP_NS + 9 * MS)  # a later write changes nothing
    times.off(_off("power", fault=True), STOP_NS + 3 * MS)
    times.off(_off("power"), STOP_NS + 4 * MS)
    stop = times.find(41)
    assert stop is not None
    assert stop.off_ns == {"drive": 2 * MS, "power": None, "brake": None}
    result = times.result([("remote", 41)], LIMIT_MS)
    assert not isinstance(result, str)
    assert [(o.name, o.off_ns) for o in result.steps[0].outputs] == [
        ("brake", None),
        ("drive", 2 * MS),
        ("power", None),
    ]
    assert not result.passed


def test_a_category_1_output_is_judged_after_its_configured_delay() -> None:
    """SR-12.1, SR-1.4: the daemon gives each output its configured ``off_delay_ms``, and a
    power output that went off 230 ms after the frame passes with a 200 ms delay."""
    times = StopTimes(delays={"power": 200})
    times.stopped(_stop(41), 41, ["drive", "power"])
    times.off(_off("drive"), STOP_NS + MS)
    times.off(_off("power"), STOP_NS + 230 * MS)
    result = times.result([("remote", 41)], LIMIT_MS)
    assert not isinstance(result, str)
    assert [(o.name, o.off_delay_ms) for o in result.steps[0].outputs] == [
        ("drive", 0),
        ("power", 200),
    ]
    assert result.passed


def test_an_output_that_goes_off_after_the_robot_left_stopped_is_not_timed() -> None:
    """SR-12.1: once the robot leaves STOPPED the stop is closed: outputs not off by then
    stay unmeasured."""
    times = StopTimes()
    times.stopped(_stop(41), 41, ["drive"])
    times.ended()
    times.off(_off("drive"), STOP_NS + MS)
    stop = times.find(41)
    assert stop is not None
    assert stop.off_ns == {"drive": None}


def test_only_a_press_of_the_named_estop_in_run_is_a_stop_test() -> None:
    """SR-12.1: a stop not kept (older than the last few), one from a state other than RUN,
    one no VSC frame raised, or one whose e-stop sources do not include the press's is no
    stop test: refused with the reason, never judged."""
    times = StopTimes()
    times.stopped(_stop(1), 1, ["drive"])
    for seq in range(2, KEEP + 2):
        times.stopped(_stop(seq), seq, ["drive"])
    assert "not among the last" in str(times.result([("remote", 1)], LIMIT_MS))
    times.stopped(_stop(50, previous=State.HOLD), 50, ["drive"])
    assert "was HOLD, not RUN" in str(times.result([("remote", 50)], LIMIT_MS))
    times.stopped(_stop(51, sources="wired"), 51, ["drive"])
    assert "sources wired" in str(times.result([("remote", 51)], LIMIT_MS))
    local = Record(
        sequence=52,
        monotonic_ns=STOP_NS,
        previous=State.RUN,
        state=State.STOPPED,
        causes=(),
        changes=(),
        trigger=LocalEstop(STOP_NS, ADMIN),
    )
    times.stopped(local, 52, ["drive"])
    assert "no VSC frame" in str(times.result([("remote", 52)], LIMIT_MS))
    times.stopped(_stop(53, sources="remote,wired"), 53, ["drive"])
    times.off(_off("drive"), STOP_NS + MS)
    judged = times.result([("wired", 53)], LIMIT_MS)
    assert not isinstance(judged, str)
    assert judged.passed


def test_a_stopping_decision_times_the_outputs_on_from_its_first_record_into_stopped() -> None:
    """SR-12.1, SR-9.5: of a decision's records, the first change into STOPPED is the stop,
    numbered in the file (``offset`` + its sequence); the outputs on are asked only then. A
    decision with no such record (a record in STOPPED already) times nothing. Mutants caught:
    the offset dropped, the first record taken whatever it is, ``on`` asked up front, a
    second change into STOPPED timed over the first."""
    asked: list[str] = []

    def on() -> list[str]:
        asked.append("on")
        return ["drive"]

    times = StopTimes()
    still = _stop(3, previous=State.STOPPED)  # STOPPED to STOPPED: no stop begins
    times.began([still], 40, on)
    assert asked == []
    assert not times.waiting("drive")
    times.began([still, _stop(4), _stop(5)], 40, on)
    assert asked == ["on"]
    assert times.find(44) is not None
    assert times.find(45) is None
    assert times.waiting("drive")
