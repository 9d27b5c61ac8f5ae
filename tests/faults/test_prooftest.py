"""The proof test of the VSC's watchdog (SR-5.3, SR-5.6, SR-5.7; docs/safety.md "The proof test"):
the real ``srcsd`` against ``srcs-sim`` with a healthy VSC, a VSC that holds its bit until a
takeover, and the three faulty VSCs of ``docs/simulator.md`` (``docs/faults.md``)."""

from __future__ import annotations

import os
import shutil
import subprocess
import sys
import tempfile
import time
from pathlib import Path
from typing import Any

import pytest

from supervisord.api.status import ProofTestResult, ProofTestStatus
from supervisord.record.stop import RecordKind, StopRecord
from supervisord.testkit.robot import Robot
from supervisord.testkit.wait import WAIT_S, wait_until
from supervisord.vocabulary import CauseKind, Phase, State

UNTESTED = "vsc_watchdog_untested"
CLEAR_MS = 2000  # vsc.prooftest_clear_ms for these robots: a held bit's wait, kept short


def _proof(robot: Robot) -> ProofTestStatus:
    proof = robot.status().report.prooftest
    assert proof is not None
    return proof


def _last(proof: ProofTestStatus) -> ProofTestResult:
    assert proof.last is not None, proof
    return proof.last


def _wait_phase(robot: Robot, *phases: Phase, timeout: float = WAIT_S) -> ProofTestStatus:
    wait_until(lambda: _proof(robot).phase in phases, timeout=timeout, what=f"{phases}")
    return _proof(robot)


def _proof_records(robot: Robot) -> list[StopRecord]:
    return [r for r in robot.records() if r.kind is RecordKind.PROOFTEST]


def _result(record: StopRecord) -> str | None:
    """The proof test's outcome a record holds (``passed``, ``failed``), if it holds one."""
    return record.prooftest.result if record.prooftest is not None else None


def _written(robot: Robot, count: int) -> list[StopRecord]:
    """The proof-test records once ``count`` are in the file: ``status`` shows an outcome as
    soon as the loop decided it, and the record reaches the file afterwards, on the record's
    own writer (SR-7.5)."""
    wait_until(lambda: len(_proof_records(robot)) >= count, what=f"{count} proof-test records")
    return _proof_records(robot)


def _robot(tmp_path: Path) -> Robot:
    return Robot(tmp_path, extra_vsc=f"prooftest_clear_ms = {CLEAR_MS}")


def test_a_healthy_vsc_passes_at_start_and_the_robot_then_runs(tmp_path: Path) -> None:
    """SR-5.3: at start the proof test withholds the heartbeat, sees the VSC's user-timeout
    bit within the manual's 500 ms (plus one VSC heartbeat and slack), sees it clear by
    itself, records it with the trip time; the operator's takeover then reaches RUN."""
    with _robot(tmp_path) as robot:
        proof = _wait_phase(robot, Phase.PASSED, Phase.FAILED)
        assert proof.phase is Phase.PASSED, proof
        last = _last(proof)
        assert last.trip_ms is not None
        assert 450 <= last.trip_ms <= 700, last
        assert last.cleared == "by_itself", last
        records = _written(robot, 1)
        assert [_result(r) for r in records] == ["passed"], records
        robot.arm()
        assert robot.status().report.state is State.RUN


@pytest.mark.parametrize(
    ("fault", "failure"),
    [
        pytest.param({"watchdog": "ignores"}, "no_trip", id="ignores_the_missing_heartbeat"),
        pytest.param({"watchdog": "late", "watchdog_late_s": 1.0}, "late", id="trips_late"),
        pytest.param({"watchdog": "never_clears"}, "not_cleared", id="never_clears"),
    ],
)
def test_a_faulty_vsc_is_caught_recorded_and_keeps_the_robot_stopped(
    tmp_path: Path, fault: dict[str, Any], failure: str
) -> None:
    """SR-5.3, SR-0.1: a VSC that ignores the missing heartbeat, trips late, or never clears
    its bit (not even after a takeover) fails the proof test: a ``prooftest`` record that
    failed, ``vsc_watchdog_untested`` active with the observation, and the robot STOPPED
    even after the operator's takeover (the default policy ``block`` on serial)."""
    robot = _robot(tmp_path)
    robot.sim.start()  # the fault is on before srcsd starts: its first proof test meets it
    robot.sim.control.fault(**fault)
    robot.sim.start = lambda: robot.sim  # type: ignore[method-assign]  # started above
    with robot:
        if failure == "not_cleared":
            _wait_phase(robot, Phase.RESUMED)
            time.sleep(0.3)
            with pytest.raises(Exception, match="e-stop active"):
                robot.vsc.takeover()
        proof = _wait_phase(robot, Phase.FAILED, Phase.PASSED, timeout=WAIT_S + CLEAR_MS / 1000)
        assert proof.phase is Phase.FAILED, proof
        assert _last(proof).failure == failure, proof
        cause = next(c for c in robot.status().report.causes if c.kind is CauseKind(UNTESTED))
        assert cause.active, cause
        assert "failed" in cause.details["observed"], cause
        assert [_result(r) for r in _written(robot, 1)] == ["failed"]
        if failure != "not_cleared":
            robot.vsc.wait_for(lambda s: s["estop"] & 0x80 == 0, timeout=WAIT_S)
            time.sleep(0.5)
            robot.vsc.takeover()
            time.sleep(0.5)
        assert robot.status().report.state is State.STOPPED
        assert UNTESTED in robot.active_stops()


def test_a_late_watchdog_fails_with_the_longest_vsc_timeout(tmp_path: Path) -> None:
    """SR-5.7: with ``vsc.timeout_ms = 1000`` (the longest the config accepts) a watchdog that
    trips at 1.2 s still fails the proof test as ``late`` and the robot stays STOPPED after the
    operator's takeover: the 700 ms limit judges the watchdog, not the link's timeout (it once
    grew with it, and this VSC passed with ``trip_ms`` 1249). No timing margin is at stake: the
    trip cannot be read sooner than the 1.2 s the simulated VSC waits."""
    robot = Robot(tmp_path, extra_vsc=f"prooftest_clear_ms = {CLEAR_MS}\ntimeout_ms = 1000")
    robot.sim.start()  # the fault is on before srcsd starts: its first proof test meets it
    robot.sim.control.fault(watchdog="late", watchdog_late_s=1.2)
    robot.sim.start = lambda: robot.sim  # type: ignore[method-assign]  # started above
    with robot:
        proof = _wait_phase(robot, Phase.FAILED, Phase.PASSED)
        assert proof.phase is Phase.FAILED, proof
        assert _last(proof).failure == "late", proof
        assert (_last(proof).trip_ms or 0) >= 1200, proof
        robot.vsc.wait_for(lambda s: s["estop"] & 0x80 == 0, timeout=WAIT_S)
        time.sleep(0.5)
        robot.vsc.takeover()
        time.sleep(0.5)
        assert robot.status().report.state is State.STOPPED
        assert UNTESTED in robot.active_stops()


def test_a_vsc_that_holds_the_bit_until_a_takeover_passes(tmp_path: Path) -> None:
    """SR-5.3: the manual leaves open whether the bit clears by itself; a VSC that holds it
    until the operator's takeover passes, and the record says ``held``."""
    robot = _robot(tmp_path)
    robot.sim.start()
    robot.sim.control.fault(watchdog="held")
    robot.sim.start = lambda: robot.sim  # type: ignore[method-assign]  # started above
    with robot:
        _wait_phase(robot, Phase.RESUMED)
        time.sleep(0.7)  # past the 500 ms in which a bit that clears by itself clears
        robot.vsc.takeover()  # acknowledges the held bit; the remote stays in Local
        proof = _wait_phase(robot, Phase.PASSED, Phase.FAILED)
        assert proof.phase is Phase.PASSED, proof
        assert _last(proof).cleared == "held", proof
        robot.arm()
        assert robot.status().report.state is State.RUN


def test_a_vsc_reboot_repeats_the_proof_test(tmp_path: Path) -> None:
    """SR-4.4 new start, SR-5.3: a VSC that falls silent (a reboot) is proven again before
    RUN."""
    with _robot(tmp_path) as robot:
        robot.arm()
        robot.vsc.call("reboot", delay=0.5, unplug=False)
        wait_until(lambda: robot.status().report.state is State.STOPPED, what="the reboot stops")
        wait_until(lambda: len(_proof_records(robot)) == 2, what="a second proof test")
        assert _result(_proof_records(robot)[-1]) == "passed"
        robot.rearm()
        assert robot.status().report.state is State.RUN


def _srcsctl(robot: Robot, *, admin: bool) -> subprocess.CompletedProcess[str]:
    env = dict(os.environ)
    code = "import sys; from supervisord.cli.srcsctl import main; sys.exit(main())"
    command = [sys.executable, "-c", code, "prooftest", "--socket", str(robot.socket_path)]
    if not admin:
        command = ["setpriv", "--reuid=65534", "--regid=65534", "--clear-groups", *command]
    return subprocess.run(command, check=False, capture_output=True, text=True, env=env, timeout=60)


def test_srcsctl_prooftest_for_an_admin_refused_otherwise_and_in_run(tmp_path: Path) -> None:
    """SR-8.3: ``srcsctl prooftest`` runs a new proof test for an admin while STOPPED (exit
    0, a second record), is refused in RUN (the test never runs in RUN or HOLD), and is
    refused to a caller who is not an admin."""
    if os.geteuid() != 0:
        pytest.skip("needs root: the daemon's admin is root, the other caller another uid")
    shared = Path(tempfile.mkdtemp(prefix="srcs-prooftest-"))
    os.chmod(shared, 0o711)  # noqa: S103 -- nobody must reach the socket inside
    try:
        _srcsctl_scenario(_robot(shared))
    finally:
        shutil.rmtree(shared, ignore_errors=True)


def _srcsctl_scenario(robot: Robot) -> None:
    with robot:
        _wait_phase(robot, Phase.PASSED)
        os.chmod(robot.socket_path, 0o777)  # noqa: S103 -- a non-admin may connect
        refused = _srcsctl(robot, admin=False)
        assert refused.returncode == 1, refused
        assert "not_allowed" in refused.stderr, refused
        done = _srcsctl(robot, admin=True)
        assert done.returncode == 0, done
        assert "passed" in done.stdout, done
        assert len(_written(robot, 2)) == 2
        robot.arm()
        in_run = _srcsctl(robot, admin=True)
        assert in_run.returncode == 1, in_run
        assert "only while STOPPED" in in_run.stderr, in_run
        assert robot.status().report.state is State.RUN
