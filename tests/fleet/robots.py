"""The fleet tier's robots (docs/fleet.md "The fleet tier"): the package installed once into
a layer, then each robot started by ``tests/fleet/robot`` in mount, UTS and PID namespaces of
its own, and driven from here as an operator would, through the simulator's control socket:
the takeover, the remote's e-stop, its release."""

from __future__ import annotations

import json
import socket
import subprocess
import time
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import Any

HERE = Path(__file__).resolve().parent

LAYER_SCRIPT = r"""
set -eu
mkdir -p "$LAYER/upper" "$LAYER/ovl" "$LAYER/root"
root=$LAYER/root
mount -t overlay overlay -o "lowerdir=/,upperdir=$LAYER/upper,workdir=$LAYER/ovl" "$root"
mount -t proc proc "$root/proc"
mount -t tmpfs -o mode=0755 dev "$root/dev"
mknod -m 0666 "$root/dev/null" c 1 3
mknod -m 0666 "$root/dev/urandom" c 1 9
mount -t tmpfs run "$root/run"
mount -t tmpfs tmp "$root/tmp"
mkdir -p "$root/srv/deb"
mount --bind "$(dirname "$DEB")" "$root/srv/deb"
# No systemd runs in the root: the postinst skips systemctl; sysusers, tmpfiles and the
# byte-compilation write into this layer only.
chroot "$root" /usr/bin/env -i PATH=/usr/sbin:/usr/bin:/sbin:/bin DEBIAN_FRONTEND=noninteractive \
    dpkg -i "/srv/deb/$(basename "$DEB")"
umount "$root/srv/deb" "$root/tmp" "$root/run" "$root/dev" "$root/proc" "$root"
"""


def make_layer(work: Path, deb: Path, name: str = "layer") -> Path:
    """The package installed with ``dpkg -i`` into an overlay over this machine's ``/``; its
    upper directory is the layer every robot shares (``layer``), or the collector's
    (``collector-layer``). Runs in a mount namespace of its own."""
    subprocess.run(
        ["unshare", "--mount", "--propagation", "private", "--pid", "--fork", "sh", "-c",
         LAYER_SCRIPT],
        env={"PATH": "/usr/sbin:/usr/bin:/sbin:/bin", "LAYER": str(work / name), "DEB": str(deb)},
        check=True,
        capture_output=True,
    )  # fmt: skip
    return work / name / "upper"


def poll(done: Callable[[], bool], limit: float, step: float = 0.05) -> float | None:
    """Seconds until ``done()``, or ``None`` when ``limit`` passed first."""
    start = time.monotonic()
    while time.monotonic() - start < limit:
        try:
            if done():
                return time.monotonic() - start
        except (OSError, ValueError, KeyError):
            pass  # not up yet: the socket is missing, a reply incomplete
        time.sleep(step)
    return None


@dataclass
class Robot:
    number: int
    work: Path
    skew: str = ""
    """libfaketime's offset of the robot's wall clock (``-7m``), or none."""
    console_ms: str = ""
    """The fleet's console is a required stop source with this timeout (SR-8.21), or not."""
    process: subprocess.Popen[bytes] | None = None

    @property
    def name(self) -> str:
        return f"robot-{self.number}"

    @property
    def address(self) -> str:
        return f"127.0.1.{self.number}"

    @property
    def dir(self) -> Path:
        return self.work / "robots" / self.name

    @property
    def run(self) -> Path:
        """The robot's /run, seen from the tier."""
        return self.dir / "run"

    @property
    def record_file(self) -> Path:
        return self.dir / f"upper/var/lib/srcsd/{self.name}/stops.jsonl"

    def start(self, layer: Path, pki: Path) -> None:
        self.dir.mkdir(parents=True, exist_ok=True)
        log = (self.dir / "robot.log").open("ab")
        self.process = subprocess.Popen(
            ["unshare", "--mount", "--uts", "--pid", "--fork", "--kill-child",
             str(HERE / "robot"), str(self.number), str(self.work), str(layer), str(pki),
             self.skew, self.console_ms],
            stdout=log,
            stderr=subprocess.STDOUT,
            stdin=subprocess.DEVNULL,
        )  # fmt: skip

    @property
    def netns(self) -> Path:
        """The agent's network namespace, made by the tier (tests/fleet/broker.py)."""
        return self.dir / "agent.netns"

    def kill(self) -> None:
        """Every process of the robot at once: its unshare's child is the first process of
        the robot's PID namespace, and the kernel ends the rest with it."""
        if self.process is not None:
            self.process.kill()
            self.process.wait()

    def control(self, request: dict[str, Any]) -> dict[str, Any]:
        """One request to srcs-sim's control socket (docs/simulator.md "The control API")."""
        with socket.socket(socket.AF_UNIX, socket.SOCK_STREAM) as conn:
            conn.settimeout(20)
            conn.connect(str(self.run / "fleet/sim.sock"))
            conn.sendall(json.dumps(request).encode() + b"\n")
            reply = b""
            while not reply.endswith(b"\n"):
                chunk = conn.recv(65536)
                if not chunk:
                    raise OSError("the simulator closed the control socket")
                reply += chunk
        answer: dict[str, Any] = json.loads(reply)
        return answer

    def drive(self) -> str:
        """The simulated motion output: ``1`` on (RUN), ``0`` off."""
        path = self.run / "fleet/drive"
        return path.read_text().strip() if path.exists() else ""

    def up(self, limit: float) -> bool:
        """The simulator answers, the VSC is commissioned (key 85, the watchdog srcsd feeds)
        and srcsd's API socket is there."""
        if poll(lambda: bool(self.control({"cmd": "state"})["ok"]), limit) is None:
            return False
        self.control({"cmd": "key", "key": 85, "value": 1})
        api = self.run / f"srcsd/{self.name}/api.sock"
        return poll(api.is_socket, limit) is not None

    def take_over(self, limit: float) -> bool:
        """The operator's takeover until srcsd is in RUN (the output on). A takeover within
        the re-arm hold, or before the proof test of the watchdog passed, is refused and
        leaves the remote in Operational: pause, wait out the hold, again."""

        def once() -> bool:
            state = self.control({"cmd": "state"})
            if state.get("estop"):
                self.control({"cmd": "release"})
            if state.get("mode_name") == "operational":
                self.control({"cmd": "pause"})
                time.sleep(0.5)  # the hold (100 ms), the takeover's 200 ms dwell, heartbeats
            if not self.control({"cmd": "takeover"})["ok"]:
                return False
            return poll(lambda: self.drive() == "1", 5) is not None

        return poll(once, limit, step=0.2) is not None

    def estop(self, limit: float) -> float | None:
        """The remote's e-stop pressed; the seconds until the output is off."""
        if not self.control({"cmd": "estop"})["ok"]:
            return None
        return poll(lambda: self.drive() == "0", limit, step=0.01)

    def own_records(self) -> list[dict[str, Any]]:
        """The robot's own record file, the record that counts (docs/record.md)."""
        if not self.record_file.exists():
            return []
        return [json.loads(line) for line in self.record_file.read_text().splitlines() if line]

    def own_journal(self) -> list[dict[str, Any]]:
        """srcsd's entries in the robot's own journal: in its /run until a flush request
        (systemd-journal-flush.service's, which no boot sends here), in /var/log after."""
        files = [
            *sorted((self.run / "log/journal").glob("*/*.journal")),
            *sorted((self.dir / "upper/var/log/journal").glob("*/*.journal")),
        ]
        if not files:
            return []
        result = subprocess.run(
            ["journalctl", *(f"--file={path}" for path in files), "--all", "-o", "json",
             "--no-pager", "SYSLOG_IDENTIFIER=srcsd"],
            capture_output=True,
            check=False,
            timeout=60,
        )  # fmt: skip
        return [json.loads(line) for line in result.stdout.decode().splitlines() if line]
