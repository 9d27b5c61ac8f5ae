"""The real srcs-exporter between the real srcsd (against srcs-sim) and a real Prometheus
server, queried through Prometheus's HTTP API (docs/fleet.md). Loopback only, in the
session's private network namespace (docs/testing.md "Network")."""

from __future__ import annotations

import json
import re
import shutil
from collections.abc import Iterator
from pathlib import Path

import pytest

from supervisord.exporter.model import scraped_names
from supervisord.testkit.robot import ALLOWANCE_S, Robot
from supervisord.testkit.wait import wait_until
from tests.exporter.stack import DASHBOARD, PROMETHEUS, Exporter, Prometheus, http_get

pytestmark = pytest.mark.skipif(
    shutil.which("prometheus") is None and not Path(PROMETHEUS).exists(),
    reason="needs Debian's prometheus package (./dev installs it)",
)


class Stack:
    def __init__(self, robot: Robot, exporter: Exporter, prometheus: Prometheus) -> None:
        self.robot, self.exporter, self.prometheus = robot, exporter, prometheus


@pytest.fixture(scope="module")
def stack(tmp_path_factory: pytest.TempPathFactory) -> Iterator[Stack]:
    """One robot, its exporter and a Prometheus scraping it, shared by this module's tests
    (Prometheus takes seconds to start on two cores)."""
    from tests.conftest import NO_PRIVATE_NETWORK  # noqa: PLC0415 - set when the session starts

    if NO_PRIVATE_NETWORK is not None:
        pytest.skip(
            f"Prometheus listens on TCP: only in a private namespace ({NO_PRIVATE_NETWORK})"
        )
    workdir = tmp_path_factory.mktemp("fleet")
    robot = Robot(workdir / "robot")
    exporter = prometheus = None
    try:
        robot.start()
        exporter = Exporter(robot.socket_path, workdir / "exporter.log")
        prometheus = Prometheus(workdir / "prometheus", [f"127.0.0.1:{exporter.port}"], "robot-a")
        yield Stack(robot, exporter, prometheus)
        robot.finish()
        assert exporter.stop() == 0, exporter.log.read_text()
        assert "Traceback" not in exporter.log.read_text()
    finally:
        if prometheus is not None:
            prometheus.stop()
        if exporter is not None:
            exporter.stop()
        robot.close()


def test_a_remote_estop_is_a_stop_prometheus_sees(private_network: None, stack: Stack) -> None:
    """RUN shows as srcs_state RUN; the remote's e-stop makes srcs_stops_total{cause=
    "vsc_estop"} go up, the state STOPPED and the cause latched; the takeover re-arm counts
    in srcs_rearms_total; the remote's battery arrives once the VSC is commissioned."""
    robot, prom = stack.robot, stack.prometheus
    robot.arm()
    prom.wait_value('srcs_state{state="RUN"}', 1)
    assert prom.value('srcs_up{robot="robot-a"}') == 1
    assert prom.value("srcs_link_up") == 1
    wait_until(lambda: (prom.value("srcs_messages_total") or 0) > 0, what="messages counted")
    stops = prom.value('srcs_stops_total{cause="vsc_estop"}') or 0
    # The start-up proof test trips the VSC's user e-stop bits (SR-5.6), so arm()'s takeover
    # may already have re-armed a vsc_estop: count from here.
    rearm = 'srcs_rearms_total{cause="vsc_estop", kind="takeover"}'
    rearms = prom.value(rearm) or 0

    robot.sim.control.estop()
    prom.wait_value('srcs_stops_total{cause="vsc_estop"}', stops + 1)
    prom.wait_value('srcs_state{state="STOPPED"}', 1)
    assert prom.value('srcs_cause_latched{cause="vsc_estop"}') == 1
    assert prom.value('srcs_state{state="RUN"}') == 0
    assert prom.value('srcs_output_on{output="drive"}') == 0

    robot.sim.control.release()
    robot.rearm()
    prom.wait_value(rearm, rearms + 1)
    prom.wait_value('srcs_state{state="RUN"}', 1)
    assert prom.value('srcs_cause_latched{cause="vsc_estop"}') == 0

    with robot.client() as api:  # root is an admin (docs/api.md "Who may do what")
        assert api.commission().remote_status is True
    robot.sim.control.request("remote_status", battery_level=60, connection_strength_src=1)
    prom.wait_value("srcs_remote_battery_percent", 60)
    assert prom.value('srcs_remote_link_strength{seen_by="remote"}') == 1


def test_the_loops_timing_histograms_reach_prometheus(private_network: None, stack: Stack) -> None:
    """The daemon's VSC and user heartbeat periods arrive as Prometheus histograms whose
    median (histogram_quantile over the _bucket series) is near the sim's 50 ms and the
    default 20 Hz; a remote e-stop in RUN adds one stop-to-off observation, in seconds
    (docs/fleet.md "Timing histograms"). Its bound is the fault kit's "at once"
    (``ALLOWANCE_S``, a busy machine's scheduling): how fast a stop is, under 2 ms at p99
    (SR-9.1), is the benches' to measure."""
    robot, prom = stack.robot, stack.prometheus
    prom.wait_value('srcs_state{state="RUN"}', 1)  # the module's first test ends in RUN
    for name in ("srcs_vsc_heartbeat_period_seconds", "srcs_user_heartbeat_period_seconds"):
        count = f"{name}_count"
        wait_until(lambda: (prom.value(count) or 0) >= 20, what=f"{name} counted")  # noqa: B023
        median = prom.value(f"histogram_quantile(0.5, {name}_bucket)")
        # Generous around 50 ms: the sim and the daemon share two busy cores.
        assert median is not None, name
        assert 0.03 <= median <= 0.075, (name, median)
    stops = prom.value("srcs_stop_to_off_seconds_count") or 0
    robot.sim.control.estop()
    prom.wait_value("srcs_stop_to_off_seconds_count", stops + 1)
    assert prom.value('srcs_stop_to_off_seconds_bucket{le="+Inf"}') == stops + 1
    assert ALLOWANCE_S <= 1.0  # the largest finite bucket: in seconds, not milliseconds
    assert prom.value('srcs_stop_to_off_seconds_bucket{le="1.0"}') == stops + 1
    assert (prom.value("srcs_stop_to_off_seconds_sum") or 0) > 0
    robot.sim.control.release()
    robot.rearm()
    prom.wait_value('srcs_state{state="RUN"}', 1)


def test_the_periodic_tests_reach_prometheus(private_network: None, stack: Stack) -> None:
    """SR-12.2: a fresh robot whose proof test passed at start and whose field stop test
    never ran: Prometheus sees the proof test's last pass a few seconds old and not overdue,
    the stop test overdue with no age at all (never passed), each labelled with its test."""
    prom = stack.prometheus
    prom.wait_value('srcs_test_overdue{test="stoptest"}', 1)
    assert prom.value('srcs_test_overdue{test="prooftest"}') == 0
    age = prom.value('srcs_test_last_pass_age_seconds{test="prooftest"}')
    assert age is not None
    assert 0 <= age < 600, age  # passed at this module's start
    assert prom.value('count(srcs_test_last_pass_age_seconds{test="stoptest"}) or vector(0)') == 0


def test_srcsd_gone_is_srcs_up_zero_and_no_state(private_network: None, stack: Stack) -> None:
    """Killing srcsd: the exporter still answers (up 1), srcs_up is 0, no state series is
    left, and the SrcsSupervisorDown alert is pending; a new srcsd is followed again, with
    the exporter's own counters kept and the restart counted."""
    robot, prom = stack.robot, stack.prometheus
    prom.wait_value("srcs_up", 1)
    stops = prom.value("sum(srcs_stops_total)")
    robot.kill_daemon()
    prom.wait_value("srcs_up", 0)
    prom.wait_value("count(srcs_state) or vector(0)", 0)
    assert prom.value('up{job="srcs"}') == 1
    assert prom.value("count(srcs_link_up) or vector(0)") == 0
    wait_until(
        lambda: any(
            a["labels"]["alertname"] == "SrcsSupervisorDown" for a in prom.api("alerts")["alerts"]
        ),
        what="SrcsSupervisorDown pending",
    )
    robot.start_daemon()
    prom.wait_value("srcs_up", 1)
    prom.wait_value('srcs_state{state="STOPPED"}', 1)  # a new daemon starts STOPPED (SR-1)
    prom.wait_value("srcs_daemon_restarts_total", 1)
    assert prom.value("sum(srcs_stops_total)") == stops


def test_every_dashboard_query_runs(private_network: None, stack: Stack) -> None:
    """Prometheus accepts every expression of the Grafana dashboard, the alert rules loaded,
    and every srcs_* name the dashboard uses is one the exporter serves."""
    prom = stack.prometheus
    dashboard = json.loads(DASHBOARD.read_text())
    served = set(scraped_names())
    exprs = [t["expr"] for p in dashboard["panels"] for t in p["targets"]]
    assert exprs
    for expr in exprs:
        assert set(re.findall(r"\bsrcs_\w+", expr)) <= served, expr
        concrete = expr.replace("$robot", ".*").replace("$__rate_interval", "1m")
        prom.query(concrete.replace("$__range", "1h"))  # raises on a parse error
    groups = prom.api("rules")["groups"]
    assert {r["name"] for g in groups for r in g["rules"]} >= {
        "SrcsSupervisorDown",
        "SrcsStoppedTooLong",
        "SrcsLinkFlapping",
        "SrcsRecordErrors",
    }


def test_openmetrics_is_served_to_who_asks(private_network: None, stack: Stack) -> None:
    """The exporter answers OpenMetrics to an OpenMetrics Accept header (as Prometheus sends)."""
    body, kind = http_get(stack.exporter.url, accept="application/openmetrics-text; version=1.0.0")
    assert kind.startswith("application/openmetrics-text")
    assert body.rstrip().endswith("# EOF")
    assert "srcs_up 1.0" in body
