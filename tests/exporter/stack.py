"""A real Prometheus server and the real ``srcs-exporter`` as processes, for the tests.

Prometheus is Debian's ``prometheus`` package, run by hand on loopback with a config and a
database in the test's directory (never the packaged service). Both listen on free ports of
127.0.0.1 only (docs/testing.md "Network")."""

from __future__ import annotations

import json
import shutil
import socket
import subprocess
import sys
import urllib.error
import urllib.parse
import urllib.request
from pathlib import Path
from typing import Any

from supervisord.testkit.wait import wait_until
from supervisord.tooling.children import terminate

PROMETHEUS = shutil.which("prometheus") or "/usr/bin/prometheus"
PROMTOOL = shutil.which("promtool") or "/usr/bin/promtool"
REPO = Path(__file__).resolve().parents[2]
RULES = REPO / "config" / "prometheus" / "srcs-alerts.yml"
DASHBOARD = REPO / "config" / "prometheus" / "srcs-dashboard.json"
SCRAPE_S = 0.25


def free_port() -> int:
    """A port of 127.0.0.1 free now (bound to 0 and released)."""
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        port: int = s.getsockname()[1]
        return port


def http_get(url: str, accept: str | None = None, timeout: float = 5.0) -> tuple[str, str]:
    """The body and content type of ``url``."""
    request = urllib.request.Request(url, headers={"Accept": accept} if accept else {})  # noqa: S310 - loopback URLs of our own
    with urllib.request.urlopen(request, timeout=timeout) as response:  # noqa: S310
        return response.read().decode(), response.headers.get("Content-Type", "")


def _answers(url: str) -> bool:
    """Whether ``url`` answers 200 within a second. An error status comes as an
    ``HTTPError`` that holds the response open: it is closed here, or Python 3.14 warns of
    it (an error in this suite; seen under Debian unstable's 3.14 while Prometheus started)."""
    try:
        http_get(url, timeout=1.0)
    except urllib.error.HTTPError as error:
        error.close()
        return False
    except OSError:
        return False
    return True


class Exporter:
    """``python -m supervisord.cli.exporter --socket SOCKET --listen 127.0.0.1:PORT``."""

    def __init__(
        self, socket_path: Path, log: Path, poll: float = 0.2, rv_file: Path | None = None
    ) -> None:
        self.port = free_port()
        # The kernel judge's file (SR-9.9): the test's own, never the machine's /run.
        rv_file = rv_file or log.with_name(f"{log.name}.no-rv-file.json")
        self.url = f"http://127.0.0.1:{self.port}/metrics"
        with log.open("ab") as out:
            self.process = subprocess.Popen(
                [
                    sys.executable,
                    "-m",
                    "supervisord.cli.exporter",
                    "--socket",
                    str(socket_path),
                    "--listen",
                    f"127.0.0.1:{self.port}",
                    "--poll",
                    str(poll),
                    "--rv-file",
                    str(rv_file),
                ],
                stdin=subprocess.DEVNULL,
                stdout=out,
                stderr=out,
            )
        self.log = log
        wait_until(self._answers, 15.0, what="srcs-exporter's HTTP port")

    def _answers(self) -> bool:
        if self.process.poll() is not None:
            raise AssertionError(f"srcs-exporter exited: {self.log.read_text()}")
        return _answers(self.url)

    def stop(self) -> int:
        return terminate(self.process, 10)


class Prometheus:
    """``prometheus`` scraping ``targets`` every SCRAPE_S, with the project's alert rules."""

    def __init__(self, workdir: Path, targets: list[str], robot: str) -> None:
        workdir.mkdir(parents=True, exist_ok=True)
        self.port = free_port()
        self.base = f"http://127.0.0.1:{self.port}"
        config = workdir / "prometheus.yml"
        config.write_text(
            json.dumps(  # JSON is YAML
                {
                    "global": {
                        "scrape_interval": f"{int(SCRAPE_S * 1000)}ms",
                        "scrape_timeout": f"{int(SCRAPE_S * 800)}ms",
                        "evaluation_interval": f"{int(SCRAPE_S * 1000)}ms",
                    },
                    "rule_files": [str(RULES)],
                    "scrape_configs": [
                        {
                            "job_name": "srcs",
                            "static_configs": [{"targets": targets, "labels": {"robot": robot}}],
                        }
                    ],
                }
            )
        )
        self.log = workdir / "prometheus.log"
        with self.log.open("ab") as out:
            self.process = subprocess.Popen(
                [
                    PROMETHEUS,
                    f"--config.file={config}",
                    f"--storage.tsdb.path={workdir / 'data'}",
                    f"--web.listen-address=127.0.0.1:{self.port}",
                    "--log.level=warn",
                ],
                stdin=subprocess.DEVNULL,
                stdout=out,
                stderr=out,
            )
        # Startup is slow on two busy cores: wait for its own readiness endpoint.
        wait_until(self._ready, 60.0, poll=0.1, what="prometheus /-/ready")

    def _ready(self) -> bool:
        if self.process.poll() is not None:
            raise AssertionError(f"prometheus exited: {self.log.read_text()[-2000:]}")
        return _answers(f"{self.base}/-/ready")

    def api(self, path: str, **params: str) -> Any:
        """``/api/v1/PATH`` with ``params``: its ``data`` (raises on an error status)."""
        body, _ = http_get(f"{self.base}/api/v1/{path}?{urllib.parse.urlencode(params)}")
        reply = json.loads(body)
        if reply.get("status") != "success":
            raise AssertionError(f"prometheus: {reply}")
        return reply["data"]

    def query(self, expr: str) -> list[tuple[dict[str, str], float]]:
        """An instant query: each series's labels and value."""
        data = self.api("query", query=expr)
        return [(item["metric"], float(item["value"][1])) for item in data["result"]]

    def value(self, expr: str) -> float | None:
        """The value of a query that gives at most one series (``None``: none)."""
        result = self.query(expr)
        assert len(result) <= 1, f"{expr} gave {result}"
        return result[0][1] if result else None

    def wait_value(self, expr: str, want: float, timeout: float = 15.0) -> None:
        wait_until(lambda: self.value(expr) == want, timeout, poll=0.1, what=f"{expr} == {want}")

    def stop(self) -> int:
        return terminate(self.process, 10)
