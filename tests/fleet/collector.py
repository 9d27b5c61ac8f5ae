"""The fleet tier's collector (docs/fleet.md "The fleet tier"): systemd's own
``systemd-journal-remote`` over HTTPS, writing one journal per robot into a directory, and a
real Prometheus (1 s scrapes of every robot's exporter, the robot's name as the target label
``robot``, the shipped ``config/prometheus/srcs-alerts.yml`` unchanged as its rules) with a
real Alertmanager, all on the fleet's loopback address 127.0.0.10.

:func:`held` answers "what the collector holds" through the journal's own tool,
``journalctl --directory DIR -o json``; it is the one place to read the collector's records,
beside :func:`fleet_answer`, the fleet's own answer, ``srcsctl fleet -o json --directory DIR``,
which holds each record once (SR-13.1)."""

from __future__ import annotations

import json
import os
import subprocess
import sys
import urllib.request
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from tests.fleet.pki import COLLECTOR_ADDRESS

ROOT = Path(__file__).resolve().parents[2]
RULES = ROOT / "config/prometheus/srcs-alerts.yml"
JOURNAL_REMOTE = "/lib/systemd/systemd-journal-remote"
JOURNAL_PORT = 19532
PROMETHEUS = f"{COLLECTOR_ADDRESS}:9090"
ALERTMANAGER = f"{COLLECTOR_ADDRESS}:9093"
EXPORTER_PORT = 9817

PROMETHEUS_CONFIG = """\
# The fleet tier's Prometheus (tests/fleet/collector.py): docs/fleet.md's scrape config at
# a 1 s interval, the shipped rules unchanged.
global:
  scrape_interval: 1s
  scrape_timeout: 1s
  evaluation_interval: 1s
rule_files: ['{rules}']
alerting:
  alertmanagers:
    - static_configs:
        - targets: ['{alertmanager}']
scrape_configs:
  - job_name: srcs
    static_configs:
{targets}
"""

ALERTMANAGER_CONFIG = """\
# The fleet tier's Alertmanager: it keeps the alerts (read through its API v2), sends none.
route:
  receiver: keep
  group_wait: 1s
receivers:
  - name: keep
"""


@dataclass
class Collector:
    """The collector's three servers, each a child process of the tier."""

    work: Path
    pki: Path
    robots: dict[str, str]
    """Each robot's name and its exporter's address."""
    processes: dict[str, subprocess.Popen[bytes]] = field(default_factory=dict)
    journal_remote_cpu: float = 0.0
    """CPU seconds of every journal-remote process ended so far."""

    @property
    def journal(self) -> Path:
        return self.work / "collector/journal"

    def start(self) -> None:
        base = self.work / "collector"
        (base / "prometheus").mkdir(parents=True, exist_ok=True)
        (base / "alertmanager").mkdir(parents=True, exist_ok=True)
        self.journal.mkdir(parents=True, exist_ok=True)
        targets = "".join(
            f"        - targets: ['{address}']\n          labels: {{robot: {robot}}}\n"
            for robot, address in self.robots.items()
        )
        config = base / "prometheus.yml"
        config.write_text(
            PROMETHEUS_CONFIG.format(rules=RULES, alertmanager=ALERTMANAGER, targets=targets)
        )
        (base / "alertmanager.yml").write_text(ALERTMANAGER_CONFIG)
        self._spawn(
            "alertmanager",
            [
                "prometheus-alertmanager",
                f"--config.file={base / 'alertmanager.yml'}",
                f"--storage.path={base / 'alertmanager'}",
                f"--web.listen-address={ALERTMANAGER}",
                "--cluster.listen-address=",  # no gossip port: one Alertmanager, no peers
            ],
        )
        self._spawn(
            "prometheus",
            [
                "prometheus",
                f"--config.file={config}",
                f"--storage.tsdb.path={base / 'prometheus'}",
                f"--web.listen-address={PROMETHEUS}",
            ],
        )
        self.start_journal_remote()

    def start_journal_remote(self) -> None:
        self._spawn(
            "journal-remote",
            [
                JOURNAL_REMOTE,
                f"--listen-https={COLLECTOR_ADDRESS}:{JOURNAL_PORT}",
                f"--key={self.pki / 'collector.key'}",
                f"--cert={self.pki / 'collector.pem'}",
                # No --trust: Debian 12 builds journal-remote without GnuTLS ("Option --trust
                # is not available"), so it cannot check the robots' certificates; it splits
                # its files by the sender's address, and the robot is the entry's _HOSTNAME.
                "--split-mode=host",
                f"--output={self.journal}",
            ],
        )

    def kill_journal_remote(self) -> None:
        """SIGKILL: the collector's machine lost, not a clean stop."""
        process = self.processes.pop("journal-remote")
        self.journal_remote_cpu += cpu_seconds(process.pid)
        process.kill()
        process.wait()

    def journal_remote_cpu_now(self) -> float:
        running = self.processes.get("journal-remote")
        return self.journal_remote_cpu + (cpu_seconds(running.pid) if running else 0.0)

    def _spawn(self, name: str, argv: list[str]) -> None:
        log = (self.work / "collector" / f"{name}.log").open("ab")
        self.processes[name] = subprocess.Popen(
            argv, stdout=log, stderr=subprocess.STDOUT, stdin=subprocess.DEVNULL
        )

    def stop(self) -> None:
        for process in self.processes.values():
            process.terminate()
        for process in self.processes.values():
            try:
                process.wait(timeout=10)
            except subprocess.TimeoutExpired:
                process.kill()
                process.wait()
        self.processes.clear()

    def alerts(self) -> list[dict[str, Any]]:
        """Alertmanager's alerts (API v2), active and otherwise."""
        with urllib.request.urlopen(f"http://{ALERTMANAGER}/api/v2/alerts", timeout=5) as reply:
            answer: list[dict[str, Any]] = json.load(reply)
        return answer

    def targets_up(self) -> dict[str, float]:
        """Prometheus's ``up`` for each robot."""
        query = f"http://{PROMETHEUS}/api/v1/query?query=up"
        with urllib.request.urlopen(query, timeout=5) as reply:
            answer = json.load(reply)
        return {
            item["metric"].get("robot", ""): float(item["value"][1])
            for item in answer["data"]["result"]
        }

    def bytes_per_file(self) -> dict[str, int]:
        """Each file of the collector's journal, those it set aside (``*.journal~``) too."""
        return {path.name: path.stat().st_size for path in sorted(self.journal.glob("*.journal*"))}


def cpu_seconds(pid: int) -> float:
    """User and system CPU seconds of a process, from /proc."""
    fields = Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()
    return (int(fields[11]) + int(fields[12])) / os.sysconf("SC_CLK_TCK")


def held(directory: Path) -> list[dict[str, Any]]:
    """What the collector holds: every srcsd journal entry in ``directory``, as
    ``journalctl -o json`` gives it, in the journal's own order."""
    result = subprocess.run(
        [
            "journalctl", "--directory", str(directory), "--all", "-o", "json", "--no-pager",
            "SYSLOG_IDENTIFIER=srcsd",
        ],
        capture_output=True,
        check=False,
        timeout=60,
    )  # fmt: skip
    return [json.loads(line) for line in result.stdout.decode().splitlines() if line.strip()]


def fleet_answer(directory: Path) -> list[dict[str, Any]]:
    """The fleet's answer: ``srcsctl fleet -o json --directory DIR`` of the tree under test
    (SR-13.1), every robot's records as JSON lines, each record once however often the
    collector holds it, in journalctl's order."""
    result = subprocess.run(
        [
            sys.executable,
            "-m",
            "supervisord.cli.fleet",
            "-o",
            "json",
            "--directory",
            str(directory),
        ],
        capture_output=True,
        check=True,
        timeout=60,
        cwd=ROOT,
    )
    return [json.loads(line) for line in result.stdout.decode().splitlines() if line.strip()]


def raw_copies(entries: list[dict[str, Any]]) -> int:
    """How many of the collector's entries repeat a robot's ``SRCS_SEQ`` and stamps: the
    copies systemd-journal-upload sent again, which the journal holds as it got them."""
    keys = [
        tuple(str(e.get(k)) for k in ("_HOSTNAME", "_BOOT_ID", "__MONOTONIC_TIMESTAMP", "SRCS_SEQ"))
        for e in entries
        if "SRCS_SEQ" in e
    ]
    return len(keys) - len(set(keys))


def by_robot(
    entries: list[dict[str, Any]], key: str = "_HOSTNAME"
) -> dict[str, list[dict[str, Any]]]:
    """The entries of each robot (``_HOSTNAME``, or the fleet's answer's ``robot``), in the
    order given."""
    robots: dict[str, list[dict[str, Any]]] = {}
    for entry in entries:
        robots.setdefault(str(entry.get(key, "")), []).append(entry)
    return robots
