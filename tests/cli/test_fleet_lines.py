"""One robot's day (tests/cli/fleet_robot.py: the real srcsd against srcs-sim, its records
written to a private journald as well as to its file) seen from both ends: ``srcsctl log`` on
the robot's record file, and ``srcsctl fleet`` on a collector directory the real
systemd-journal-remote wrote from the robot's journal export (SR-13.4, SR-13.9).

The lines are the same (a proof test's verdict, a re-arm's kind, every detail), and the
robot's stops are counted alike by ``fleet --summary``, ``log --summary``, the exporter's
model fed the same record file and a real Prometheus scraping that model, with the shipped
alert rules loaded."""

from __future__ import annotations

import json
import shutil
import subprocess
import sys
from collections.abc import Iterator
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import pytest

from supervisord.api.pushes import RecordPush
from supervisord.cli.fleet_journal import entry
from supervisord.exporter.collector import serve
from supervisord.exporter.model import ExporterModel, Family
from supervisord.record.journal import journal_fields
from supervisord.record.stop import read_record, read_written
from tests.exporter.stack import PROMETHEUS, Prometheus
from tests.journald import collect, robot_export

SRCSCTL = str(Path(sys.executable).with_name("srcsctl"))
ROBOT = "robot-d"
SENDER = "127.0.1.4"
DAY = """
start_journald ""
"$PYTHON" -m tests.cli.fleet_robot "$DIR"
"""


@dataclass(frozen=True)
class Day:
    record: Path  # the robot's record file
    collector: Path  # the collector's directory, the robot's upload in it


@pytest.fixture(scope="module")
def day(tmp_path_factory: pytest.TempPathFactory) -> Day:
    base = tmp_path_factory.mktemp("day")
    robot = base / ROBOT
    export = robot_export(ROBOT, DAY, {"DIR": str(robot), "PYTHON": sys.executable})
    collector = base / "remote"
    collector.mkdir()
    collect(export, collector / f"remote-{SENDER}.journal")
    return Day(robot / "record" / "stops.jsonl", collector)


def srcsctl(*args: str) -> str:
    done = subprocess.run([SRCSCTL, *args], capture_output=True, text=True, timeout=60, check=False)
    assert done.returncode == 0, done.stderr
    assert "Traceback" not in done.stderr
    return done.stdout


def records(path: Path) -> list[dict[str, Any]]:
    return [json.loads(line) for line in path.read_text().splitlines()]


@pytest.mark.parametrize("mode", [[], ["--causes"], ["-o", "verbose"]])
def test_the_collectors_line_is_the_robots_line(day: Day, mode: list[str]) -> None:
    """SR-13.4: every record's line at the collector, past the robot's label, is the line
    ``srcsctl log`` prints on the robot: the proof test's verdict (passed, and FAILED with its
    reason), "re-armed by takeover", every cause's details."""
    robot = srcsctl("log", "--file", str(day.record), "--utc", *mode).splitlines()
    fleet = srcsctl("fleet", "-D", str(day.collector), "--utc", *mode).splitlines()
    head = f"{ROBOT}@{SENDER}  "
    assert all(line.startswith(head) for line in fleet), fleet
    assert [line[len(head) :] for line in fleet] == robot
    text = "\n".join(robot)
    assert "proof test passed: tripped after" in text
    assert "proof test FAILED: the VSC did not report the user-timeout e-stop" in text
    assert "re-armed by takeover" in text


def test_the_journal_carries_every_field_of_the_record(day: Day) -> None:
    """SR-13.4: each record, written as the journal entry srcsd sends and read back as the
    collector's journalctl gives it, is the record the robot wrote, field for field."""
    for data in records(day.record):
        fields: dict[str, Any] = {}
        for name, value in journal_fields(data):
            fields[name] = [*fields[name], value] if name in fields else value
        fields |= {"__CURSOR": "c", "_HOSTNAME": ROBOT}
        rebuilt = entry(json.dumps(fields))
        assert not isinstance(rebuilt, str), rebuilt
        assert rebuilt.record == read_record(data), data["seq"]


WANTED_TRIGGERS = {"client_lost:motion": 1, "vsc_estop": 1, "shutdown:SIGTERM": 1}
"""The day's stops by trigger: the motion client killed (not the supervisor's own
``vsc_estop (sources=user)`` that follows it), the remote's e-stop, SIGTERM in RUN."""


def _counts(summary: dict[str, Any]) -> dict[str, Any]:
    return {k: summary[k] for k in ("stops", "startups", "prooftests", "rearms", "triggers")}


def test_the_summaries_count_stops_by_their_trigger(day: Day) -> None:
    """SR-13.9: ``fleet --summary`` at the collector and ``log --summary`` on the robot count
    the same: three stops, each by its trigger; two start-ups, one proof test passed and one
    FAILED, three re-arms, apart; the last stop named by its trigger."""
    fleet = json.loads(srcsctl("fleet", "-D", str(day.collector), "--summary", "-o", "json"))
    robot = json.loads(srcsctl("log", "--file", str(day.record), "--summary", "-o", "json"))
    assert (fleet["robot"], fleet["sender"]) == (ROBOT, SENDER)
    assert _counts(fleet) == _counts(robot)
    assert fleet["last_stop"] == robot["last_stop"]
    for name, count in WANTED_TRIGGERS.items():
        assert fleet["triggers"].get(name) == count, fleet
    assert fleet["startups"] == 2, fleet
    assert fleet["prooftests"] == {"passed": 1, "failed": 1}, fleet
    assert fleet["rearms"] == 3, fleet
    line = srcsctl("fleet", "-D", str(day.collector), "--summary")
    assert line.startswith(f"{ROBOT}@{SENDER}  {fleet['stops']} stops, 2 start-ups, ")
    assert "proof tests 1 passed 1 FAILED, 3 re-arms, " in line
    assert line.rstrip().endswith(f"#{fleet['last_stop']['seq']} shutdown:SIGTERM")


def _fed(path: Path, count: int | None = None) -> ExporterModel:
    model = ExporterModel()
    model.connected()
    for data in records(path)[:count]:
        model.push(RecordPush(record=read_record(data)), 0)
    return model


def _samples(families: list[Family], name: str) -> dict[str, float]:
    family = next(f for f in families if f.name == name)
    return {",".join(v for _, v in s.labels): s.value for s in family.samples}


def test_the_exporter_counts_what_the_summary_counts(day: Day) -> None:
    """SR-13.9: the exporter's model, fed the robot's record file as pushes, counts the stops
    by trigger, the start-ups, the proof tests and the re-arms as ``log --summary`` does."""
    summary = json.loads(srcsctl("log", "--file", str(day.record), "--summary", "-o", "json"))
    families = _fed(day.record).families(0)
    assert _samples(families, "srcs_stops") == summary["triggers"]
    assert sum(_samples(families, "srcs_rearms").values()) >= summary["rearms"]
    assert _samples(families, "srcs_startups") == {"": summary["startups"]}
    assert _samples(families, "srcs_prooftests") == summary["prooftests"]


@pytest.fixture
def served(day: Day) -> Iterator[tuple[ExporterModel, int]]:
    """The exporter's model fed the day's records up to the failed proof test's, served by
    the exporter's own HTTP edge on a free port of loopback."""
    failed = next(
        i for i, r in enumerate(records(day.record)) if r.get("kind") == "prooftest" and i > 10
    )
    model = _fed(day.record, failed)
    server, thread = serve(lambda: model.families(0), "127.0.0.1", 0)
    try:
        yield model, server.server_port
    finally:
        server.shutdown()
        server.server_close()
        thread.join(timeout=10)


def test_prometheus_and_the_rules_count_what_the_summary_counts(
    private_network: None, day: Day, served: tuple[ExporterModel, int], tmp_path: Path
) -> None:
    """SR-13.9: a real Prometheus scraping the exporter's model with the shipped rules loaded
    sees the summary's stops by trigger, and the rule on failed proof tests fires once the
    day's failed proof test is counted."""
    if shutil.which("prometheus") is None and not Path(PROMETHEUS).exists():
        pytest.skip("needs Debian's prometheus package (./dev installs it)")
    model, port = served
    prometheus = Prometheus(tmp_path / "prometheus", [f"127.0.0.1:{port}"], ROBOT)
    try:
        prometheus.wait_value('srcs_prooftests_total{result="failed"}', 0)
        for data in records(day.record)[model.records_seen :]:
            model.push(RecordPush(record=read_record(data)), 0)
        prometheus.wait_value('srcs_prooftests_total{result="failed"}', 1)
        summary = json.loads(srcsctl("log", "--file", str(day.record), "--summary", "-o", "json"))
        stops = prometheus.query("sum by (cause) (srcs_stops_total)")
        assert {labels["cause"]: value for labels, value in stops} == summary["triggers"]
        expr = _rule(prometheus, "SrcsProofTestFailed")
        fired = prometheus.query(expr)
        assert [labels["robot"] for labels, _ in fired] == [ROBOT], fired
    finally:
        prometheus.stop()


def _rule(prometheus: Prometheus, alert: str) -> str:
    """The expression of the shipped rule ``alert`` as Prometheus loaded it."""
    groups = prometheus.api("rules")["groups"]
    return str(next(r["query"] for g in groups for r in g["rules"] if r["name"] == alert))


def test_a_record_without_changes_is_counted_by_its_difference(day: Day) -> None:
    """SR-13.9: a record written before records carried ``changes`` (none in its line) is
    counted by what it changed since the one before: the same stops and triggers."""
    old = [{k: v for k, v in r.items() if k != "changes"} for r in records(day.record)]
    path = day.record.with_name("old.jsonl")
    path.write_text("".join(json.dumps(r) + "\n" for r in old))
    now = json.loads(srcsctl("log", "--file", str(day.record), "--summary", "-o", "json"))
    before = json.loads(srcsctl("log", "--file", str(path), "--summary", "-o", "json"))
    assert before["triggers"] == now["triggers"]
    assert _counts(before) == _counts(now)
    assert read_written(old[0]) is not None
