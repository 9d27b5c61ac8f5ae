"""One stop end to end with the installed package: run inside a root by its ``/opt/srcsd``.

``srcs-sim`` is the VSC on a pseudo-terminal; ``srcsd`` runs the robot config
``/etc/srcs/platform.toml`` (one simulated motion output, the record in
``/var/lib/srcsd/platform``); ``srcsctl`` reads its state and record. The operator's takeover
arms it (the output goes on), the remote's e-stop pressed in the simulator stops it: the
output goes off, ``srcsctl status`` says STOPPED with ``vsc_estop``, and ``srcsctl log`` shows
the stop record. Then SIGTERM: a clean exit. Every program is the package's, started by the
name the package puts on the PATH (docs/install.md); only the control socket of the
simulator is spoken to directly (docs/simulator.md "The control API").

``tests/platforms/package.py`` runs this inside a network namespace of the root's own
(loopback only), as ``/opt/srcsd/bin/python3 estop.py``: the package's environment on the
root's Python. It prints one line per check, ``check: ok WHAT`` or ``check: FAILED WHAT:
SEEN``, and times as ``time: WHAT SECONDS``; the exit status is 1 when a check failed.
Standard library only, Python 3.10 and newer.

usage: estop.py [--slow FACTOR]   (FACTOR multiplies every deadline: qemu-user runs Python
                                   15-35 times slower than the host)
"""

from __future__ import annotations

import argparse
import json
import os
import signal
import socket
import subprocess
import sys
import time
from collections.abc import Callable
from pathlib import Path
from typing import Any

CONFIG = Path("/etc/srcs/platform.toml")
RUN = Path("/run/srcs-platform")
RECORD = Path("/var/lib/srcsd/platform/stops.jsonl")
SOCKET = Path("/run/srcsd/platform/api.sock")
HOLD_MS = 100
"""The robot's re-arm hold."""
DRIVE = RUN / "drive"
VSC = RUN / "vsc"
CONTROL = RUN / "sim.sock"

ROBOT = f"""\
# The platform job's robot (tests/platforms/estop.py): the VSC is srcs-sim on a pty.
[robot]
name = "platform"

[vsc]
transport = "serial"
port = "{VSC}"
require_watchdog = true
# The largest allowed: under qemu-user the simulator's 50 ms heartbeats reach srcsd late.
timeout_ms = 1000

[rearm]
hold_ms = {HOLD_MS}

[[outputs]]
name = "drive"
kind = "sim"
role = "motion"
path = "{DRIVE}"

[record]
path = "{RECORD}"
journal = false

[api]
socket = "{SOCKET}"
admin_group = "srcs-admin"
"""

failures: list[str] = []


def check(passed: bool, what: str, seen: object = "") -> bool:
    if passed:
        print(f"check: ok {what}", flush=True)
    else:
        failures.append(what)
        print(f"check: FAILED {what}: {seen}", flush=True)
    return passed


def poll(done: Callable[[], bool], limit: float) -> float | None:
    """Seconds until ``done()``, or ``None`` when ``limit`` passed first."""
    start = time.monotonic()
    while time.monotonic() - start < limit:
        try:
            if done():
                return time.monotonic() - start
        except (OSError, ValueError, KeyError, TypeError, subprocess.TimeoutExpired):
            pass  # not up yet: the socket is missing, a reply not complete
        time.sleep(0.05)
    return None


def wait(what: str, done: Callable[[], bool], limit: float) -> float | None:
    """``poll``, and a failed check when ``limit`` passed first."""
    took = poll(done, limit)
    if took is None:
        check(False, what, f"not within {limit:.0f} s")
    return took


def control(request: dict[str, Any], limit: float = 30) -> dict[str, Any]:
    """One request to the simulator's control socket, one reply line."""
    with socket.socket(socket.AF_UNIX, socket.SOCK_STREAM) as conn:
        conn.settimeout(limit)
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


def srcsctl(*args: str, limit: float = 60) -> subprocess.CompletedProcess[str]:
    return subprocess.run(
        ["srcsctl", "--config", str(CONFIG), *args],
        capture_output=True,
        text=True,
        timeout=limit,
        check=False,
    )


def status(limit: float) -> dict[str, Any]:
    result = srcsctl("status", "--json", limit=limit)
    if result.returncode != 0:
        raise OSError(result.stderr.strip())
    reply: dict[str, Any] = json.loads(result.stdout)
    return reply


def drive() -> str:
    return DRIVE.read_text() if DRIVE.exists() else ""


def stopped_by_estop(reply: dict[str, Any]) -> bool:
    names = {cause["name"] for cause in reply.get("causes", [])}
    return reply.get("state") == "STOPPED" and "vsc_estop" in names


def run(slow: float) -> None:
    for directory in (RUN, SOCKET.parent, RECORD.parent, CONFIG.parent):
        directory.mkdir(parents=True, exist_ok=True)
    CONFIG.write_text(ROBOT)
    checked = subprocess.run(
        ["srcsd", "--check-config", str(CONFIG)], capture_output=True, text=True, check=False
    )
    check(checked.returncode == 0, "srcsd --check-config of the robot", checked.stderr)

    sim_log = (RUN / "sim.log").open("w")
    sim = subprocess.Popen(
        ["srcs-sim", "--serial", str(VSC), "--control", str(CONTROL)],
        stdout=sim_log,
        stderr=subprocess.STDOUT,
    )
    daemon: subprocess.Popen[bytes] | None = None
    try:
        took = wait("srcs-sim answers", lambda: control({"cmd": "state"})["ok"], 30 * slow)
        if took is None:
            return
        print(f"time: srcs-sim up {took:.1f}", flush=True)
        # Commissioned: the VSC watches the supervisor's heartbeat (key 85), as on a robot.
        check(control({"cmd": "key", "key": 85, "value": 1}).get("value") == 1, "key 85 set")

        daemon_log = (RUN / "srcsd.log").open("w")
        started = time.monotonic()
        daemon = subprocess.Popen(
            ["srcsd", "--config", str(CONFIG)], stdout=daemon_log, stderr=subprocess.STDOUT
        )
        # Up, feeding the VSC's watchdog, its output off; and the proof test of the watchdog
        # done (SR-5.3), which comes before any RUN.
        if wait("srcsd answers srcsctl status", lambda: bool(status(10 * slow)), 60 * slow) is None:
            return
        print(f"time: srcsd up {time.monotonic() - started:.1f}", flush=True)
        proof = wait(
            "the proof test of the VSC's watchdog passed",
            lambda: status(10 * slow)["prooftest"]["phase"] == "passed",
            60 * slow,
        )
        if proof is None:
            return
        check(drive() == "0\n", "the output is off before the takeover", repr(drive()))

        def take_over() -> bool:
            # As an operator would: again while a stop still holds. A takeover that came
            # within the re-arm hold is refused and leaves the remote in Operational; the
            # operator pauses (back to Local), waits out the hold, and takes over again.
            if control({"cmd": "state"}).get("mode_name") == "operational":
                control({"cmd": "pause"})
                # the hold, the takeover's dwell of 200 ms (docs/safety.md) and heartbeats
                time.sleep(slow * (HOLD_MS + 400) / 1000)
            if not control({"cmd": "takeover"})["ok"]:
                return False
            return poll(lambda: status(10 * slow)["state"] == "RUN", 5 * slow) is not None

        if wait("a takeover arms srcsd (RUN)", take_over, 60 * slow) is None:
            return
        check(drive() == "1\n", "the output is on in RUN", repr(drive()))

        pressed = time.monotonic()
        check(control({"cmd": "estop"})["ok"], "the remote's e-stop pressed in srcs-sim")
        off = wait("the output goes off", lambda: drive() == "0\n", 10 * slow)
        if off is not None:
            print(f"time: e-stop to output off {off:.3f}", flush=True)
        wait(
            "srcsctl status: STOPPED by vsc_estop",
            lambda: stopped_by_estop(status(10 * slow)),
            30 * slow,
        )
        print(f"time: e-stop to status STOPPED {time.monotonic() - pressed:.1f}", flush=True)

        log = srcsctl("log", "--json", limit=60 * slow)
        records = [json.loads(line) for line in log.stdout.splitlines() if line.strip()]
        stops = [
            r
            for r in records
            if r.get("from") == "RUN"
            and r.get("to") == "STOPPED"
            and any(c.get("name") == "vsc_estop" for c in r.get("causes", []))
        ]
        check(
            log.returncode == 0 and bool(stops),
            "srcsctl log: the stop RUN -> STOPPED, vsc_estop",
            log.stdout[-500:] + log.stderr[-500:],
        )
        check(RECORD.is_file() and "vsc_estop" in RECORD.read_text(), f"the stop is in {RECORD}")

        daemon.send_signal(signal.SIGTERM)
        code = daemon.wait(timeout=30 * slow)
        check(code == 0, "srcsd exits 0 on SIGTERM", code)
        check(drive() == "0\n", "the output is off after the exit", repr(drive()))
        daemon = None
        log_text = (RUN / "srcsd.log").read_text()
        check("Traceback" not in log_text, "no traceback in srcsd's output", log_text[-800:])
    finally:
        if daemon is not None:
            daemon.kill()
            daemon.wait()
            print("srcsd's output:\n" + (RUN / "srcsd.log").read_text()[-3000:], flush=True)
        sim.send_signal(signal.SIGTERM)
        try:
            check(sim.wait(timeout=30 * slow) == 0, "srcs-sim exits 0 on SIGTERM")
        except subprocess.TimeoutExpired:
            sim.kill()
            check(False, "srcs-sim exits on SIGTERM", "killed")
        if failures:
            print("srcs-sim's output:\n" + (RUN / "sim.log").read_text()[-2000:], flush=True)


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--slow", type=float, default=1.0)
    args = parser.parse_args()
    if os.environ.get("SRCS_PLATFORM_ROOT") != "1":
        # Never on a real machine: it writes /etc/srcs/platform.toml and /var/lib/srcsd.
        print("estop.py runs only inside a platform root (tests/platforms/package.py)")
        return 2
    run(args.slow)
    return 1 if failures else 0


if __name__ == "__main__":
    sys.exit(main())
