"""docs/containers.md's recipe, run as written with the installed package: srcsd without
systemd, as a container runs it (SR-0.4).

Inside a root with the package installed (``tests/platforms/package.py``), in a network
namespace of the root's own (loopback only): ``srcs-sim`` is the VSC on a pty, linked as
``/dev/srcs-vsc``; the page's two shell blocks are read from the page the package installs
(``/usr/share/doc/srcs-supervisord/docs/containers.md``), so the page cannot drift from what
runs: the block that prepares (the runtime and record directories, the device's group, the
check) and the start (srcsd as PID 1 of a PID namespace of its own, SCHED_FIFO 10, as the
user srcsd with no new privileges). Checked: ``srcsctl status`` answers and the proof test
of the VSC's watchdog passes; srcsd is PID 1 in its namespace, runs as srcsd in FIFO with
NoNewPrivs; its log says each part it runs without once (the watchdog, a restart, a runtime
directory, udev's group) and not real-time scheduling nor the sandbox; SIGTERM, as an engine
sends it to PID 1 at the stop, ends it with exit 0. And all of it without udev, which the
package only recommends and the root, installing no recommended package, does not have.

Prints ``check: ok WHAT`` or ``check: FAILED WHAT: SEEN`` per check and exits 1 if one failed.
Standard library only, Python 3.10 and newer.

usage: container.py [--slow FACTOR]
"""

from __future__ import annotations

import argparse
import json
import os
import pwd
import re
import signal
import socket
import subprocess
import sys
import time
from collections.abc import Callable
from pathlib import Path
from typing import Any

PAGE = Path("/usr/share/doc/srcs-supervisord/docs/containers.md")
CONFIG = Path("/etc/srcs/robot-a.toml")
RUN = Path("/run/srcs-container")
VSC = Path("/dev/srcs-vsc")
CONTROL = RUN / "sim.sock"
LOG = RUN / "srcsd.log"
UDEV = Path("/run/udev/control")

ROBOT = f"""\
[robot]
name = "robot-a"

[vsc]
transport = "serial"
port = "{VSC}"
# The largest allowed: under qemu-user the simulator's heartbeats reach srcsd late.
timeout_ms = 1000

[[outputs]]
name = "drive"
kind = "sim"
role = "motion"
path = "/run/srcsd/robot-a/drive"

[record]
path = "/var/lib/srcsd/robot-a/stops.jsonl"
journal = false

[api]
socket = "/run/srcsd/robot-a/api.sock"
"""

SAID = {
    "systemd's watchdog": 1,
    "real-time scheduling": 0,
    "a sandbox": 0,
    "a restart": 1,
    "a runtime directory": 1,
    "udev's group on the device": 1,
}
"""How often the start says it runs without each part, started by the recipe (SR-0.4)."""

failures: list[str] = []


def check(passed: bool, what: str, seen: object = "") -> bool:
    if passed:
        print(f"check: ok {what}", flush=True)
    else:
        failures.append(what)
        print(f"check: FAILED {what}: {seen}", flush=True)
    return passed


def poll(done: Callable[[], bool], limit: float) -> bool:
    end = time.monotonic() + limit
    while time.monotonic() < end:
        try:
            if done():
                return True
        except (OSError, ValueError, KeyError, TypeError, subprocess.TimeoutExpired):
            pass  # not up yet
        time.sleep(0.05)
    return False


def control(request: dict[str, Any]) -> dict[str, Any]:
    with socket.socket(socket.AF_UNIX, socket.SOCK_STREAM) as conn:
        conn.settimeout(30)
        conn.connect(str(CONTROL))
        conn.sendall(json.dumps(request).encode() + b"\n")
        reply = b""
        while not reply.endswith(b"\n"):
            chunk = conn.recv(65536)
            if not chunk:
                raise OSError("the simulator closed the control socket")
            reply += chunk
    answer: dict[str, Any] = json.loads(reply)
    return answer


def blocks(page: str) -> list[str]:
    """The page's ``sh`` blocks, in order."""
    return re.findall(r"^```sh\n(.*?)^```$", page, flags=re.MULTILINE | re.DOTALL)


def status(limit: float) -> dict[str, Any]:
    result = subprocess.run(
        ["srcsctl", "--config", str(CONFIG), "status", "--json"],
        capture_output=True,
        text=True,
        timeout=limit,
        check=False,
    )
    if result.returncode != 0:
        raise OSError(result.stderr.strip())
    reply: dict[str, Any] = json.loads(result.stdout)
    return reply


def child_of(pid: int) -> int:
    """The one child of ``pid`` (unshare's: srcsd, as PID 1 of its namespace)."""
    children = Path(f"/proc/{pid}/task/{pid}/children").read_text().split()
    return int(children[0])


def status_fields(pid: int) -> dict[str, str]:
    lines = Path(f"/proc/{pid}/status").read_text().splitlines()
    return {k: v.strip() for k, _, v in (line.partition(":") for line in lines)}


def _three() -> tuple[str, str, str]:
    """The recipe's blocks: the preparation, the start, the health check."""
    found = [b for b in blocks(PAGE.read_text()) if "robot-a" in b]
    return found[0], found[1], found[2]


def main() -> int:
    parser = argparse.ArgumentParser()
    parser.add_argument("--slow", type=float, default=1.0)
    slow = parser.parse_args().slow
    # A container has no udev, and the package must not need it: it only recommends udev
    # (docs/containers.md "The package's dependencies"), and the platform roots install no
    # recommended package, as an image's build with --no-install-recommends.
    state = subprocess.run(
        ["dpkg-query", "-W", "-f", "${Status} ${Package}\n", "srcs-supervisord", "udev"],
        capture_output=True,
        text=True,
        check=False,
    ).stdout.splitlines()
    check(
        "install ok installed srcs-supervisord" in state
        and "install ok installed udev" not in state,
        "the package installed without udev",
        state,
    )
    check(not UDEV.exists(), "udev does not run here", UDEV)
    if not check(PAGE.exists(), "the package installs docs/containers.md", PAGE):
        return 1
    prepare, start, health = _three()
    RUN.mkdir(parents=True, exist_ok=True)
    CONFIG.parent.mkdir(parents=True, exist_ok=True)
    CONFIG.write_text(ROBOT)
    sim = subprocess.Popen(
        ["srcs-sim", "--serial", str(RUN / "vsc"), "--control", str(CONTROL)],
        stdout=(RUN / "sim.log").open("w"),
        stderr=subprocess.STDOUT,
    )
    daemon: subprocess.Popen[bytes] | None = None
    try:
        if not check(poll(lambda: control({"cmd": "state"})["ok"], 30 * slow), "srcs-sim up"):
            return 1
        check(control({"cmd": "key", "key": 85, "value": 1}).get("value") == 1, "key 85 set")
        VSC.symlink_to(os.path.realpath(RUN / "vsc"))  # as the host's udev names it
        prepared = subprocess.run(
            ["sh", "-ec", prepare], capture_output=True, text=True, timeout=120 * slow, check=False
        )
        if not check(prepared.returncode == 0, "the page's preparation", prepared.stderr):
            return 1
        daemon = subprocess.Popen(
            ["sh", "-ec", start], stdout=LOG.open("w"), stderr=subprocess.STDOUT
        )
        up = poll(lambda: status(10 * slow)["prooftest"]["phase"] == "passed", 90 * slow)
        check(
            up, "srcsctl status: up, the proof test of the VSC's watchdog passed", LOG.read_text()
        )
        checked = subprocess.run(
            ["sh", "-ec", health], capture_output=True, text=True, timeout=120 * slow, check=False
        )
        check(checked.returncode == 0, "the page's health check and readiness", checked.stderr)
        srcsd = child_of(daemon.pid)
        fields = status_fields(srcsd)
        check(
            fields["NSpid"].split()[-1] == "1", "srcsd is PID 1 of its namespace", fields["NSpid"]
        )
        user = pwd.getpwnam("srcsd").pw_uid
        check(fields["Uid"].split()[0] == str(user), "srcsd runs as the user srcsd", fields["Uid"])
        check(
            fields["NoNewPrivs"] == "1", "srcsd runs with no new privileges", fields["NoNewPrivs"]
        )
        check(os.sched_getscheduler(srcsd) == os.SCHED_FIFO, "srcsd runs SCHED_FIFO")
        os.kill(srcsd, signal.SIGTERM)  # what an engine sends PID 1 at the stop
        code = daemon.wait(timeout=30 * slow)
        check(code == 0, "SIGTERM: srcsd stops, exit 0", code)
        text = LOG.read_text()
        for part, times in SAID.items():
            count = text.count(f"runs without {part} (")
            check(count == times, f"the start says it runs without {part} {times} times", text)
        check("Traceback" not in text, "no traceback", text)
    finally:
        CONFIG.unlink(missing_ok=True)  # the purge's check finds /etc/srcs as the root had it
        for process in (daemon, sim):
            if process is not None and process.poll() is None:
                process.kill()
                process.wait()
    return 1 if failures else 0


if __name__ == "__main__":
    sys.exit(main())
