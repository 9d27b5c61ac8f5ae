"""The fleet stop's ends as the tests run them: ``srcs-fleet-agent`` as a process per robot,
and ``srcsctl fleet stop``/``status`` as the operator types them."""

from __future__ import annotations

import json
import queue
import subprocess
import sys
import time
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path

import pytest

from supervisord.cli import srcsctl
from supervisord.fleet_agent.mqtt_edge import Connection
from tests.fleet_agent.broker import FLEET, ROBOTS, Broker, tls


def agent_command(broker: Broker, robot: str, socket_path: Path, *extra: str) -> list[str]:
    keys = tls(broker.pki, robot)
    groups = [arg for g in sorted(ROBOTS.get(robot, ())) for arg in ("--group", g)]
    return [
        sys.executable, "-m", "supervisord.cli.fleet_agent",
        "--socket", str(socket_path), "--fleet", FLEET, "--robot", robot, *groups,
        "--broker", f"127.0.0.1:{broker.port}",
        "--cafile", str(keys.cafile), "--cert", str(keys.certfile), "--key", str(keys.keyfile),
        *extra,
    ]  # fmt: skip


@contextmanager
def running_agents(
    broker: Broker, sockets: dict[str, Path], log_dir: Path
) -> Iterator[dict[str, subprocess.Popen[bytes]]]:
    """An agent per robot of ``sockets`` (robot -> its daemon's socket), each online at the
    broker (its presence seen) before this yields."""
    started: dict[str, subprocess.Popen[bytes]] = {}
    try:
        for robot, path in sockets.items():
            log = (log_dir / f"agent-{robot}.log").open("wb")
            started[robot] = subprocess.Popen(
                agent_command(broker, robot, path), stdout=log, stderr=subprocess.STDOUT
            )
            log.close()
        wait_online(broker, set(sockets))
        yield started
    finally:
        for process in started.values():
            process.terminate()
        for process in started.values():
            process.wait(10)


def watcher(broker: Broker, topics: list[str]) -> Connection:
    """A console's connection that only listens (``console-1``'s certificate)."""
    connection = Connection(f"watch-{time.monotonic_ns()}", tls(broker.pki, "console-1"), topics)
    connection.start("127.0.0.1", broker.port)
    assert connection.subscribed.wait(20), connection.last_error
    return connection


def wait_online(broker: Broker, robots: set[str], timeout: float = 30) -> None:
    connection = watcher(broker, [f"srcs/{FLEET}/robot/+"])
    online: set[str] = set()
    deadline = time.monotonic() + timeout
    try:
        while not robots <= online:
            left = deadline - time.monotonic()
            assert left > 0, f"agents not online: {sorted(robots - online)}"
            try:
                item = connection.incoming.get(timeout=left)
            except queue.Empty:
                continue
            presence = json.loads(item.payload)
            if presence.get("online"):
                online.add(presence["robot"])
            else:
                online.discard(presence["robot"])
    finally:
        connection.stop()


def console(
    broker: Broker, capsys: pytest.CaptureFixture[str], command: str, *args: str
) -> tuple[int, str]:
    """``srcsctl fleet COMMAND ...`` as console-1, its exit status and its output."""
    keys = tls(broker.pki, "console-1")
    capsys.readouterr()
    status = srcsctl.main(
        [
            "fleet", command, *args, "--fleet", FLEET, "--broker", f"127.0.0.1:{broker.port}",
            "--cafile", str(keys.cafile), "--cert", str(keys.certfile),
            "--key", str(keys.keyfile), "--name", "console-1",
        ]
    )  # fmt: skip
    captured = capsys.readouterr()
    return status, captured.out + captured.err
