"""A takeover is an operator's act (SR-4.5; docs/safety.md "Re-arming" rule 4): the
real ``srcsd`` against ``srcs-sim`` whose VSC flaps its mode after an e-stop. No flapping
re-arms the robot; the operator's own takeover afterwards does (``docs/faults.md``)."""

from __future__ import annotations

import time
from pathlib import Path
from typing import Any

import pytest

from supervisord.protocol.codes import VscMode
from supervisord.safety.decision import RefusalReason
from supervisord.testkit.robot import Robot
from supervisord.testkit.wait import wait_until

FLAP_S = 2.0  # twenty times the 100 ms re-arm hold the harness configures


def _refused(records: list[dict[str, Any]], until: float) -> list[dict[str, Any]]:
    """The ``rearm_refused`` records up to ``until`` (monotonic s)."""
    return [r for r in records if r.get("kind") == "rearm_refused" and r["mono_ns"] <= until * 1e9]


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
        assert not [r for r in records if r.get("rearm")], records
        assert all(r["to"] == "STOPPED" for r in records), records
        assert robot.watcher.ons_between(t0, t1) == []
        assert robot.status()["state"] == "STOPPED"
        refused = _refused(records, t1)
        assert 1 <= len(refused) <= FLAP_S + 1, refused
        too_short = RefusalReason.TAKEOVER_TOO_SHORT.value
        assert all(r["reason"].startswith(too_short) for r in refused), refused
        robot.recover(stop)
