"""The fleet stop's broker in the fleet tier (docs/fleet.md "The fleet tier"): a real
mosquitto with the fleet's mutual TLS and the ACL the agent's code writes
(``supervisord/fleet_agent/acl.py``, SR-13.13), on the tier's own network namespace at
:data:`~tests.fleet.pki.BROKER_ADDRESS`; and each robot's link to it.

Each robot's agent runs in a network namespace of its own (``Robot.netns``, made here before
the robot starts), joined to the tier's by a veth pair: ``vr-N`` on the tier's side
(198.18.N.1), ``eth0`` in the robot's (198.18.N.2, its default route). A robot's network cut
is its ``vr-N`` down; loss on the robots' links is nftables dropping at random on every
``vr-*`` (this kernel has no ``netem``). Nothing here has a route out of the tier's namespace.
"""

from __future__ import annotations

import shutil
import socket
import subprocess
import time
from dataclasses import dataclass
from pathlib import Path

from supervisord.fleet_agent.acl import acl_text, broker_conf
from tests.fleet.pki import BROKER_ADDRESS, CONSOLE

FLEET = "fleet-1"
PORT = 8883
GROUPS = {1: "site-1", 2: "site-1", 3: "site-1", 4: "site-2", 5: "site-2"}
"""Each robot's group (its agent's ``--group``, tests/fleet/robot)."""
LOSS_TABLE = "fleet_loss"


def run(*argv: str, check: bool = True) -> subprocess.CompletedProcess[bytes]:
    return subprocess.run(list(argv), check=check, capture_output=True)


def link(number: int, netns: Path) -> None:
    """Robot ``number``'s agent namespace at ``netns`` (a file, kept by a bind mount in the
    tier's mount namespace), its veth to the tier and its addresses."""
    netns.parent.mkdir(parents=True, exist_ok=True)
    netns.touch()
    run("unshare", f"--net={netns}", "true")
    run("ip", "link", "add", "name", f"vr-{number}", "type", "veth", "peer", "name", "eth0",
        "netns", str(netns))  # fmt: skip
    run("ip", "addr", "add", f"198.18.{number}.1/24", "dev", f"vr-{number}")
    run("ip", "link", "set", f"vr-{number}", "up")
    inside = ["nsenter", f"--net={netns}"]
    run(*inside, "ip", "link", "set", "lo", "up")
    run(*inside, "ip", "addr", "add", f"198.18.{number}.2/24", "dev", "eth0")
    run(*inside, "ip", "link", "set", "eth0", "up")
    run(*inside, "ip", "route", "add", "default", "via", f"198.18.{number}.1")


def cut(number: int, down: bool) -> None:
    """Robot ``number``'s link to the broker down (or up again)."""
    run("ip", "link", "set", f"vr-{number}", "down" if down else "up")


def loss(percent: float) -> None:
    """``percent`` of the packets on every robot's link lost, both ways."""
    share = round(percent * 10)
    rules = (
        f"table inet {LOSS_TABLE} {{\n"
        "  chain in { type filter hook input priority 0;\n"
        f'    iifname "vr-*" numgen random mod 1000 < {share} drop\n  }}\n'
        "  chain out { type filter hook output priority 0;\n"
        f'    oifname "vr-*" numgen random mod 1000 < {share} drop\n  }}\n'
        "}\n"
    )
    subprocess.run(["nft", "-f", "-"], input=rules.encode(), check=True, capture_output=True)


def no_loss() -> None:
    run("nft", "delete", "table", "inet", LOSS_TABLE, check=False)


@dataclass
class Broker:
    """mosquitto, as root in the tier's namespace, its files in ``WORK/broker``."""

    work: Path
    process: subprocess.Popen[bytes] | None = None

    @property
    def dir(self) -> Path:
        return self.work / "broker"

    @property
    def log(self) -> Path:
        return self.dir / "mosquitto.log"

    def configure(self, pki: Path, robots: list[str]) -> None:
        """Its certificate (the collector's, which names the broker's address too), the
        fleet's CA, and the ACL for ``robots`` (their groups) and the console."""
        self.dir.mkdir(parents=True, exist_ok=True)
        run("ip", "addr", "add", f"{BROKER_ADDRESS}/32", "dev", "lo")
        shutil.copy(pki / "ca.pem", self.dir / "ca.pem")
        shutil.copy(pki / "collector.pem", self.dir / "broker.pem")
        shutil.copy(pki / "collector.key", self.dir / "broker.key")
        roster = {name: frozenset({GROUPS[int(name.split("-")[1])]}) for name in robots}
        (self.dir / "acl").write_text(acl_text(FLEET, roster, [CONSOLE]))
        (self.dir / "mosquitto.conf").write_text(
            broker_conf(PORT, str(self.dir), str(self.dir / "acl"), bind=BROKER_ADDRESS)
            # Its files are the tier's (root's); clean sessions, nothing kept on disk.
            + f"user root\npersistence false\nlog_dest file {self.log}\n"
            + "log_timestamp_format %H:%M:%S\n"
        )

    def start(self) -> None:
        self.process = subprocess.Popen(
            [shutil.which("mosquitto", path="/usr/sbin:/usr/bin") or "mosquitto", "-c",
             str(self.dir / "mosquitto.conf")],
            stdout=subprocess.DEVNULL,
            stderr=subprocess.DEVNULL,
        )  # fmt: skip
        limit = time.monotonic() + 20
        while time.monotonic() < limit and self.process.poll() is None:
            try:
                socket.create_connection((BROKER_ADDRESS, PORT), timeout=1).close()
                return
            except OSError:
                time.sleep(0.05)
        raise RuntimeError(f"mosquitto did not listen: {self.log.read_text()[-800:]}")

    def kill(self) -> None:
        """SIGKILL: the broker's machine lost, not a clean stop."""
        if self.process is not None:
            self.process.kill()
            self.process.wait()
            self.process = None
