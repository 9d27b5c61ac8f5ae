"""The fleet tier's collector (docs/fleet.md "The fleet tier"): the collector's package
(``srcs-collector``) installed with dpkg into a layer, mounted as a root of its own over this
machine's ``/``, and its servers run in that root (chroot) as its shipped files say, unchanged
(SR-13.10): systemd's ``systemd-journal-remote`` as Debian's unit starts it, over HTTPS on the
fleet's address 127.0.0.10, with the package's ``journal-remote.conf.d`` drop-in (a file per
sender, the collector's certificate); Prometheus and Alertmanager with the command lines of the
package's drop-ins for their units and the package's ``prometheus.yml`` (15 s scrapes, the
shipped rules, targets made by ``srcs-fleet-targets`` from the list of robots) and
``alertmanager.yml`` (routes by robot, to the webhook at 127.0.0.1:9095 that :class:`Webhook`
serves here). Only their ``$ARGS`` (where to keep their data) and journal-remote's listening
address (its unit gets a socket) are the tier's.

:func:`held` answers "what the collector holds" through the journal's own tool,
``journalctl --directory DIR -o json``; it is the one place to read the collector's records,
beside :func:`fleet_answer`, the fleet's own answer, the installed ``srcsctl fleet -o json``,
which holds each record once (SR-13.1)."""

from __future__ import annotations

import contextlib
import json
import os
import re
import shlex
import subprocess
import threading
import time
import urllib.request
from dataclasses import dataclass, field
from http.server import BaseHTTPRequestHandler, ThreadingHTTPServer
from pathlib import Path
from typing import Any

from tests.fleet.pki import COLLECTOR_ADDRESS

JOURNAL_PORT = 19532
PROMETHEUS = f"{COLLECTOR_ADDRESS}:9090"
ALERTMANAGER = f"{COLLECTOR_ADDRESS}:9093"
EXPORTER_PORT = 9817
REMOTE = "var/log/journal/remote"
"""systemd-journal-remote's directory in the collector's root (its unit's --output=)."""
UNITS = "usr/lib/systemd/system"

ROOT_SCRIPT = r"""
set -eu
mkdir -p "$DIR/upper" "$DIR/ovl" "$DIR/root"
mount -t overlay overlay -o "lowerdir=$LAYER:/,upperdir=$DIR/upper,workdir=$DIR/ovl" "$DIR/root"
mount --rbind /dev "$DIR/root/dev"
mount -t proc proc "$DIR/root/proc"
mount -t tmpfs tmp "$DIR/root/tmp"
mount -t tmpfs run "$DIR/root/run"
"""


def exec_start(unit_file: Path, args: list[str]) -> list[str]:
    """The last ``ExecStart=`` of a unit or drop-in, as argv, ``$ARGS`` replaced by ``args``."""
    lines = [line for line in unit_file.read_text().splitlines() if line.startswith("ExecStart=")]
    argv = shlex.split(lines[-1].removeprefix("ExecStart="))
    return [word for item in argv for word in (args if item == "$ARGS" else [item])]


class Webhook:
    """The team's receiver of the shipped alertmanager.yml: a tiny HTTP server at its URL
    that keeps every notification with the wall-clock time it arrived."""

    def __init__(self, url: str) -> None:
        found = re.fullmatch(r"http://([\d.]+):(\d+)(/.*)", url)
        assert found, url
        self.received: list[tuple[float, dict[str, Any]]] = []
        received = self.received

        class Handler(BaseHTTPRequestHandler):
            def do_POST(self) -> None:
                body = self.rfile.read(int(self.headers.get("Content-Length", "0")))
                with contextlib.suppress(ValueError):
                    received.append((time.time(), json.loads(body)))
                self.send_response(200)
                self.end_headers()

            def log_message(self, format: str, *args: Any) -> None:
                pass

        self.server = ThreadingHTTPServer((found[1], int(found[2])), Handler)
        threading.Thread(target=self.server.serve_forever, daemon=True).start()

    def first_firing(self, alertname: str) -> dict[str, float]:
        """Each robot's first notification of ``alertname`` firing: its arrival time."""
        first: dict[str, float] = {}
        for when, payload in list(self.received):
            for alert in payload.get("alerts", []):
                labels = alert.get("labels", {})
                if alert.get("status") == "firing" and labels.get("alertname") == alertname:
                    first.setdefault(str(labels.get("robot")), when)
        return first

    def stop(self) -> None:
        self.server.shutdown()


@dataclass
class Collector:
    """The collector's three servers, each a child process of the tier in the collector's
    root."""

    work: Path
    robots: dict[str, str]
    """Each robot's name and its exporter's address."""
    processes: dict[str, subprocess.Popen[bytes]] = field(default_factory=dict)
    journal_remote_cpu: float = 0.0
    """CPU seconds of every journal-remote process ended so far."""
    webhook: Webhook | None = None

    @property
    def base(self) -> Path:
        return self.work / "collector"

    @property
    def root(self) -> Path:
        """The collector's root: the installed package over this machine's ``/``."""
        return self.base / "root"

    @property
    def pki(self) -> Path:
        return self.root / "etc/srcs-collector/pki"

    @property
    def journal(self) -> Path:
        return self.root / REMOTE

    def mount(self, layer: Path) -> None:
        """The collector's root, ready before the certificates are made into it."""
        self.base.mkdir(parents=True, exist_ok=True)
        subprocess.run(
            ["sh", "-c", ROOT_SCRIPT],
            env={"PATH": "/usr/sbin:/usr/bin:/sbin:/bin", "DIR": str(self.base),
                 "LAYER": str(layer)},
            check=True,
            capture_output=True,
        )  # fmt: skip

    def start(self) -> None:
        # The list of robots, as the fleet's administrator writes it; the targets are the
        # package's generator's (the path unit runs it on a change; here it is run once).
        (self.root / "etc/srcs-collector/robots").write_text(
            "".join(f"{robot} {address}\n" for robot, address in self.robots.items())
        )
        self.chroot(["srcs-fleet-targets"], check=True)
        self.journal.mkdir(parents=True, exist_ok=True)  # the unit's LogsDirectory=
        config = (self.root / "etc/srcs-collector/alertmanager.yml").read_text()
        self.webhook = Webhook(re.findall(r"url: (\S+)", config)[0])
        dropins = self.root / UNITS
        self._spawn(
            "alertmanager",
            exec_start(
                dropins / "prometheus-alertmanager.service.d/srcs-collector.conf",
                ["--storage.path=/var/lib/srcs-collector/alertmanager"],
            ),
        )
        self._spawn(
            "prometheus",
            exec_start(
                dropins / "prometheus.service.d/srcs-collector.conf",
                ["--storage.tsdb.path=/var/lib/srcs-collector/tsdb"],
            ),
        )
        self.start_journal_remote()

    def start_journal_remote(self) -> None:
        # Debian's unit, its socket's descriptor replaced by the address it would listen on;
        # the key, certificate, CA and split mode from the package's drop-in. Debian 12's
        # build checks no client certificate ("Certificate checking disabled"); the robots
        # still check the collector's.
        argv = exec_start(self.root / "lib/systemd/system/systemd-journal-remote.service", [])
        argv = [
            f"--listen-https={COLLECTOR_ADDRESS}:{JOURNAL_PORT}"
            if word.startswith("--listen-https=")
            else word
            for word in argv
        ]
        self._spawn("journal-remote", argv)

    def chroot(self, argv: list[str], check: bool = False) -> subprocess.CompletedProcess[bytes]:
        """A command run in the collector's root, as its administrator would."""
        return subprocess.run(
            ["chroot", str(self.root), "/usr/bin/env", "-i",
             "PATH=/usr/sbin:/usr/bin:/sbin:/bin", "LANG=C.UTF-8", *argv],
            capture_output=True,
            check=check,
            timeout=60,
        )  # fmt: skip

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
        log = (self.base / f"{name}.log").open("ab")
        self.processes[name] = subprocess.Popen(
            ["chroot", str(self.root), *argv],
            stdout=log,
            stderr=subprocess.STDOUT,
            stdin=subprocess.DEVNULL,
        )

    def stop(self) -> None:
        if self.webhook is not None:
            self.webhook.stop()
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


def fleet_answer(collector: Collector) -> list[dict[str, Any]]:
    """The fleet's answer: the collector package's ``srcsctl fleet -o json`` on its
    receiver's directory (SR-13.1), every robot's records as JSON lines, each record once
    however often the collector holds it, in journalctl's order."""
    result = collector.chroot(["srcsctl", "fleet", "-o", "json", "--directory", f"/{REMOTE}"])
    if result.returncode not in (0, 1):  # 1: no entries yet
        raise OSError(f"srcsctl fleet: {result.stderr.decode(errors='replace')[-400:]}")
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
