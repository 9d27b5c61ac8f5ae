"""A takeover is an operator's act (SR-4.5; docs/safety.md "Re-arming" rule 4): the
real ``srcsd`` against ``srcs-sim`` whose VSC flaps its mode after an e-stop. No flapping
re-arms the robot; the operator's own takeover afterwards does (``docs/faults.md``)."""

from __future__ import annotations

import time
from pathlib import Path
from typing import Any

import pytest

from supervisord.client import SupervisorClient
from supervisord.protocol.codes import VscMode
from supervisord.record.stop import RecordKind, StopRecord
from supervisord.safety.decision import RefusalReason
from supervisord.testkit.robot import Robot
from supervisord.testkit.wait import wait_until
from supervisord.vocabulary import State

FLAP_S = 2.0  # twenty times the 100 ms re-arm hold the harness configures


def _refused(records: list[StopRecord], until: float) -> list[StopRecord]:
    """The ``rearm_refused`` records up to ``until`` (monotonic s)."""
    return [r for r in records if r.kind is RecordKind.REARM_REFUSED and r.mono_ns <= until * 1e9]


@pytest.mark.parametrize(
    "flap",
    [
        pytest.param({"flap_period_s": 0.01, "flap_heartbeats": True}, id="chatter_every_10_ms"),
        pytest.param({"flap_period_s": 0.1}, id="every_100_ms_at_20_hz"),
    ],
)
def test_a_flapping_vsc_never_rearms_after_an_estop(tmp_path: Path, flap: dict[str, Any]) -> None:
    """SR-4 (rule 4 of docs/safety.md): after the remote's e-stop has been released, the VSC's
    mode flaps Local/Operational (every 10 ms with a heartbeat at each change, as one VSC
    did, or every 100 ms on its 20 Hz schedule) for twenty re-arm holds. The robot stays
    STOPPED with every output off and no re-arm; the refused takeovers are recorded at most
    once a second; once the VSC is sane, the operator's takeover re-arms.

    The flapping starts while the e-stop is still pressed and the release comes amid it: a
    VSC that sat in Local for a while after the e-stop and then reported Operational would
    be an operator's takeover by every rule (SR-4.5), and a flap that began after the hold
    time would be taken for one; the scenario would then depend on how fast its own
    requests are served."""
    with Robot(tmp_path) as robot:
        assert robot.watcher is not None
        robot.arm()
        stop = robot.remote_estop()
        robot.vsc.fault(flap_mode=VscMode.OPERATIONAL.value, **flap)
        robot.vsc.release()
        wait_until(lambda: not robot.active_stops(), what="the e-stop released")
        t0 = robot.now()
        time.sleep(FLAP_S)
        t1 = robot.now()
        counts = robot.vsc.state()["fault_counts"]
        robot.vsc.fault()
        assert counts.get("flap_mode", 0) >= 10, counts  # the VSC did report Operational
        records = robot.records_since(t0)
        assert not [r for r in records if r.rearm], records
        assert all(r.to_state is State.STOPPED for r in records), records
        assert robot.watcher.ons_between(t0, t1) == []
        assert robot.status().report.state is State.STOPPED
        refused = _refused(records, t1)
        assert 1 <= len(refused) <= FLAP_S + 1, refused
        too_short = RefusalReason.TAKEOVER_TOO_SHORT.value
        assert all((r.reason or "").startswith(too_short) for r in refused), refused
        robot.recover(stop)


NOTICE = {"90": "NOT RE-ARMED", "91": "COMMAND NOT ZERO:", "92": "planner"}


def test_a_takeover_while_a_client_commands_motion_is_refused_and_shown_on_the_remote(
    tmp_path: Path,
) -> None:
    """SR-4.6: a client (``planner``, not required) declares a non-zero command; after the
    remote's e-stop is released, the operator's takeover on ``srcs-sim`` (every other rule
    met) does not re-arm: the refusal is recorded with ``command_nonzero`` naming the client,
    no output comes on, ``status`` shows the declaration, and the simulated remote shows the
    notice on its text page and vibrates. Once the planner declares zero, the remote's page
    is given back, and the operator's next takeover re-arms."""
    with Robot(tmp_path) as robot:
        assert robot.watcher is not None
        robot.arm()
        with SupervisorClient.connect(robot.socket_path, name="planner") as planner:
            planner.command(True)
            vibrations = robot.vsc.state()["vibration_count"]
            stop = robot.remote_estop()
            robot.vsc.release()
            # every rule of SR-4 met but the command's
            refused = robot.refused_rearm(RefusalReason.COMMAND_NONZERO.value)
            assert refused.reason == f"{RefusalReason.COMMAND_NONZERO.value}: planner"
            assert not [r for r in robot.records_since(stop.t_fault) if r.rearm]
            assert robot.watcher.ons_between(stop.t_fault, robot.now()) == []
            status = robot.status()
            assert status.report.state is State.STOPPED
            (entry,) = [c for c in status.daemon.clients if c.name == "planner"]
            assert entry.command_nonzero is True
            shown = robot.vsc.wait_for(
                lambda s: (
                    s["display_mode"] == 1
                    and all(s["labels"].get(k) == v for k, v in NOTICE.items())
                    and s["vibration_count"] > vibrations
                )
            )
            assert "NOT RE-ARMED" in shown["lcd"], shown["lcd"]
            planner.command(False)
            robot.vsc.wait_for(lambda s: s["display_mode"] == 0 and s["labels"].get("90") == "")
            robot.recover(stop)
