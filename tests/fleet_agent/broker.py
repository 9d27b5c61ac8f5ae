"""A real mosquitto with the fleet's mutual TLS and ACL file, on loopback, for the tests
(docs/fleet.md "The fleet stop"). The certificates are the fleet's own recipe,
``srcs-fleet-pki`` (a console's is a client certificate like a robot's: its CN is its name)."""

from __future__ import annotations

import shutil
import socket
import subprocess
import sys
import time
from collections.abc import Iterator, Mapping, Sequence
from contextlib import contextmanager
from dataclasses import dataclass
from pathlib import Path

import pytest

from supervisord.fleet_agent.acl import acl_text, broker_conf
from supervisord.fleet_agent.mqtt_edge import Tls

FLEET = "f1"
ROBOTS: Mapping[str, frozenset[str]] = {
    "robot-a": frozenset({"site-1"}),
    "robot-b": frozenset({"site-1"}),
    "robot-c": frozenset({"site-2"}),
}
CONSOLES = ("console-1",)


def mosquitto() -> str:
    found = shutil.which("mosquitto") or shutil.which("mosquitto", path="/usr/sbin")
    if found is None:
        pytest.skip("needs mosquitto (apt-get install mosquitto; ./dev needs test)")
    return found


def pki(directory: Path, names: Sequence[str]) -> Path:
    """A CA, the broker's certificate for 127.0.0.1, and a client certificate per name."""
    tool = [sys.executable, "-m", "supervisord.cli.fleet_pki", "--dir", str(directory)]
    for command in (["ca"], ["server", "127.0.0.1"], ["robot", *names]):
        subprocess.run([*tool, *command], check=True, capture_output=True, timeout=120)
    # The server certificate is the collector's by name in the recipe; here it is the broker's.
    (directory / "collector.pem").rename(directory / "broker.pem")
    (directory / "collector.key").rename(directory / "broker.key")
    return directory


def tls(directory: Path, name: str) -> Tls:
    return Tls(directory / "ca.pem", directory / f"{name}.pem", directory / f"{name}.key")


def free_port() -> int:
    with socket.socket() as sock:
        sock.bind(("127.0.0.1", 0))
        return int(sock.getsockname()[1])


@dataclass
class Broker:
    port: int
    pki: Path
    process: subprocess.Popen[bytes] | None = None
    config: Path | None = None

    def start(self) -> None:
        assert self.config is not None
        self.process = subprocess.Popen(
            [mosquitto(), "-c", str(self.config)],
            stdout=subprocess.DEVNULL,
            stderr=subprocess.DEVNULL,
        )
        deadline = time.monotonic() + 20
        while time.monotonic() < deadline:
            try:
                socket.create_connection(("127.0.0.1", self.port), timeout=1).close()
                return
            except OSError:
                time.sleep(0.05)
                if self.process.poll() is not None:
                    break
        self.stop()
        raise AssertionError("mosquitto did not listen within 20 s")

    def stop(self) -> None:
        if self.process is not None:
            if self.process.poll() is None:
                self.process.terminate()
            self.process.wait(10)
            self.process = None


@contextmanager
def running_broker(directory: Path) -> Iterator[Broker]:
    """The broker of :data:`ROBOTS` and :data:`CONSOLES`, its ACL the fleet's."""
    mosquitto()
    keys = pki(directory / "pki", [*ROBOTS, *CONSOLES, "stranger"])
    (directory / "acl").write_text(acl_text(FLEET, ROBOTS, CONSOLES))
    port = free_port()
    config = directory / "mosquitto.conf"
    config.write_text(
        broker_conf(port, str(keys), str(directory / "acl"), bind="127.0.0.1")
        # The test's files are root's and private: as root, mosquitto would drop to its own
        # user, which may not read them (the broker's real unit runs as that user).
        + f"user root\npersistence false\nlog_dest file {directory / 'mosquitto.log'}\n"
    )
    broker = Broker(port, keys, config=config)
    broker.start()
    try:
        yield broker
    finally:
        broker.stop()
