"""SR-0.4: srcsd says at its start, once, each part it runs without when no service manager
gives it, with what to provide instead; started as systemd starts it, it says none.

The real ``srcsd`` against the real ``srcs-sim`` over a pseudo-terminal, started by hand
(no NOTIFY_SOCKET, INVOCATION_ID, RUNTIME_DIRECTORY) and then as the unit starts it: a
notify socket of the test's own that it reads, WATCHDOG_USEC, INVOCATION_ID,
RUNTIME_DIRECTORY, SCHED_FIFO 10 (``chrt``), no new privileges (``setpriv``), and a udev
control socket in a private mount of ``/run``."""

from __future__ import annotations

import dataclasses
import os
import socket
import sys
import time
from collections.abc import Callable
from pathlib import Path
from typing import Any

from supervisord.config import load_config
from supervisord.config.realtime import LockMode
from supervisord.daemon.memory_lock import MemoryLock
from supervisord.daemon.service_manager_absent import (
    UDEV_CONTROL,
    Absent,
    Device,
    Part,
    Surroundings,
    absent,
    devices,
)
from supervisord.sim.process import SimProcess
from supervisord.testkit.daemon import MINIMAL_CONFIG, SrcsdProcess
from supervisord.tooling.children import spawn, terminate, wait_started
from tests.daemon.fifo import needs_fifo

MANAGER_VARIABLES = (
    "NOTIFY_SOCKET",
    "WATCHDOG_USEC",
    "WATCHDOG_PID",
    "INVOCATION_ID",
    "RUNTIME_DIRECTORY",
    "JOURNAL_STREAM",
)
"""What systemd puts in a unit's environment (systemd.exec(5)), none of it in a start by hand."""


def by_hand() -> dict[str, str]:
    return {k: v for k, v in os.environ.items() if k not in MANAGER_VARIABLES}


def said(log: str, part: Part) -> int:
    """How many lines of the log say the daemon runs without ``part``."""
    return log.count(f"runs without {part.value} (")


def wait(done: Callable[[], bool], limit: float = 30.0) -> None:
    end = time.monotonic() + limit
    while not done():
        assert time.monotonic() < end, "timed out"
        time.sleep(0.02)


def proof_done(tmp_path: Path) -> Callable[[], bool]:
    """The proof test of the VSC's watchdog recorded: the start is long over (SR-5.3)."""
    record = tmp_path / "stops.jsonl"
    return lambda: record.exists() and '"kind":"prooftest"' in record.read_text()


def udev_here() -> bool:
    try:
        return UDEV_CONTROL.is_socket()
    except OSError:
        return False


def no_new_privs(pid: int) -> bool:
    status = Path(f"/proc/{pid}/status").read_text()
    return any(line.split() == ["NoNewPrivs:", "1"] for line in status.splitlines())


def test_started_by_hand_it_says_each_missing_part_once(tmp_path: Path) -> None:
    """SR-0.4: by hand, the log says the watchdog, restarts and the runtime directory once
    each, with what to do instead; real-time scheduling, the sandbox and udev's group once
    each exactly when this machine and process lack them; and nothing more after the start."""
    (tmp_path / "robot.toml").write_text(MINIMAL_CONFIG)
    log = tmp_path / "srcsd.log"
    with SimProcess(tmp_path, serial="vsc") as sim:
        assert sim.control.key(85, 1) == 1
        with SrcsdProcess(tmp_path / "robot.toml", env=by_hand(), log=log) as daemon:
            wait(proof_done(tmp_path))
            expected = {
                Part.WATCHDOG: True,
                Part.RESTART: True,
                Part.RUNTIME_DIRECTORY: True,
                Part.REALTIME: os.sched_getscheduler(daemon.pid) == os.SCHED_OTHER,
                Part.SANDBOX: not no_new_privs(daemon.pid),
                Part.DEVICE_GROUP: not udev_here(),
            }
            time.sleep(1.0)  # a running daemon's turns say none of it again
            running = log.read_text()
        assert daemon.exit_status == 0
    text = log.read_text()
    for part, missing in expected.items():
        assert said(running, part) == (1 if missing else 0), (part, running)
        assert said(text, part) == said(running, part), (part, text)
    assert f"{tmp_path} must exist before the start" in running
    assert "--restart=on-failure" in running
    assert "docs/containers.md" in running
    assert "Traceback" not in text


UNIT_LIKE = (
    "mount -t tmpfs -o size=1m,mode=0755 srcs-test /run && mkdir /run/udev && "
    '"$0" -c "import socket; socket.socket(socket.AF_UNIX, socket.SOCK_SEQPACKET)'
    ".bind('/run/udev/control')\" && "
    'exec chrt -f 10 setpriv --no-new-privs "$0" -m supervisord.cli.srcsd --config "$1"'
)
"""As srcsd@.service starts it: in FIFO 10 with no new privileges, on a machine where udev
runs (its control socket in a /run of the daemon's own: the host's is left as it is). Every
step execs, so the daemon keeps the PID the test started."""


@needs_fifo(
    "SCHED_FIFO and a private mount of /run, as systemd gives them", "unshare", "chrt", "setpriv"
)
def test_started_as_the_unit_starts_it_it_says_none(tmp_path: Path) -> None:
    """SR-0.4: with what the unit gives (the watchdog's socket and period, INVOCATION_ID,
    RUNTIME_DIRECTORY, SCHED_FIFO, no new privileges, udev running) the start says none of
    the parts; the notify socket the test reads gets READY=1 and WATCHDOG=1 from it."""
    (tmp_path / "robot.toml").write_text(MINIMAL_CONFIG)
    log = tmp_path / "srcsd.log"
    notify_path = tmp_path / "notify"
    env = {
        **by_hand(),
        "NOTIFY_SOCKET": str(notify_path),
        "WATCHDOG_USEC": "2000000",
        "INVOCATION_ID": "0123456789abcdef0123456789abcdef",
        "RUNTIME_DIRECTORY": str(tmp_path),
    }
    seen: list[str] = []
    with (
        socket.socket(socket.AF_UNIX, socket.SOCK_DGRAM) as notify,
        SimProcess(tmp_path, serial="vsc") as sim,
    ):
        notify.bind(str(notify_path))
        notify.setblocking(False)

        def read() -> list[str]:
            """The notifications so far (the socket queues only a few datagrams: read on)."""
            while True:
                try:
                    seen.extend(notify.recv(4096).decode().splitlines())
                except BlockingIOError:
                    return seen

        assert sim.control.key(85, 1) == 1
        command = ["unshare", "--mount", "--propagation", "private", "sh", "-c", UNIT_LIKE]
        daemon = spawn([*command, sys.executable, str(tmp_path / "robot.toml")], log, env)
        try:
            socket_path = load_config(tmp_path / "robot.toml").api.socket
            assert wait_started(daemon, socket_path.exists, 30, 0.02, read) == "ready", (
                log.read_text()
            )
            done = proof_done(tmp_path)
            wait(lambda: "READY=1" in read() and done())
            wait(lambda: "WATCHDOG=1" in read())
            assert os.sched_getscheduler(daemon.pid) == os.SCHED_FIFO
            assert no_new_privs(daemon.pid)
            assert "READY=1" in seen
        finally:
            assert terminate(daemon) == 0
    text = log.read_text()
    for part in Part:
        assert said(text, part) == 0, (part, text)
    assert "runs without" not in text
    assert "Traceback" not in text


FULL = Surroundings(
    environ={
        "NOTIFY_SOCKET": "/run/systemd/notify",
        "WATCHDOG_USEC": "2000000",
        "INVOCATION_ID": "x",
        "RUNTIME_DIRECTORY": "/run/srcsd",
    },
    pid=42,
    realtime=True,
    no_new_privs=True,
    udev=True,
    socket_dirs=(Path("/run/srcsd"),),
    devices=(Device(Path("/dev/srcs-vsc"), 0, 990, 0o660),),
    uid=995,
    groups=(990, 995),
)
"""Everything the unit gives."""


def parts(found: list[Absent]) -> list[Part]:
    return [finding.part for finding in found]


def test_each_fact_is_one_part() -> None:
    """SR-0.4: each missing fact is its part, alone, in the order of ``Part``."""
    assert absent(FULL) == []
    env = dict(FULL.environ)
    cases: dict[Part, dict[str, Any]] = {
        Part.WATCHDOG: {"environ": {k: v for k, v in env.items() if k != "WATCHDOG_USEC"}},
        Part.REALTIME: {"realtime": False},
        Part.SANDBOX: {"no_new_privs": False},
        Part.RESTART: {"environ": {k: v for k, v in env.items() if k != "INVOCATION_ID"}},
        Part.RUNTIME_DIRECTORY: {
            "environ": {k: v for k, v in env.items() if k != "RUNTIME_DIRECTORY"}
        },
        Part.DEVICE_GROUP: {"udev": False},
        Part.MEMORY_LOCK: {"memory": REFUSED},
    }
    for part, change in cases.items():
        found = absent(dataclasses.replace(FULL, **change))
        assert parts(found) == [part], (part, found)
        assert found[0].line().startswith(f"runs without {part.value} (")
    everything: dict[str, Any] = {k: v for change in cases.values() for k, v in change.items()}
    everything["environ"] = {}
    assert parts(absent(dataclasses.replace(FULL, **everything))) == list(Part)


REFUSED = MemoryLock(LockMode.ON, locked=False, reason="Cannot allocate memory", limit=8 << 20)
"""The lock refused under Debian's default RLIMIT_MEMLOCK (SR-9.6)."""


def test_the_memory_lock_line_names_the_refusal_the_limit_and_the_fix() -> None:
    """SR-0.4, SR-9.6: a refused lock names the error and the limit, and the fix (the unit's
    LimitMEMLOCK=, prlimit, the engine's ulimit or CAP_IPC_LOCK); the lock turned off says
    the configuration's key instead; a held lock says nothing."""
    (line,) = [f.line() for f in absent(dataclasses.replace(FULL, memory=REFUSED))]
    assert line.startswith(
        "runs without locked memory (mlockall: Cannot allocate memory, RLIMIT_MEMLOCK 8192 KiB)"
    )
    for fix in ("LimitMEMLOCK=", "prlimit --memlock=", "--ulimit memlock=", "CAP_IPC_LOCK"):
        assert fix in line
    off = MemoryLock(LockMode.OFF, locked=False)
    (line,) = [f.line() for f in absent(dataclasses.replace(FULL, memory=off))]
    assert line.startswith('runs without locked memory (lock_memory = "off")')
    assert absent(dataclasses.replace(FULL, memory=MemoryLock(LockMode.REQUIRED, True))) == []


def test_a_watchdog_for_another_process_is_none() -> None:
    """SR-0.4: WATCHDOG_PID naming another process leaves this one without a watchdog, as
    the notifier reads it."""
    other = dataclasses.replace(FULL, environ={**FULL.environ, "WATCHDOG_PID": "7"})
    assert parts(absent(other)) == [Part.WATCHDOG]


def test_the_device_line_names_its_permissions_and_a_missing_device() -> None:
    """SR-0.4: without udev, the line gives each device's owner, group and mode, or says it
    is not there yet; a CAN VSC has no device node and no such line."""
    facts = dataclasses.replace(
        FULL,
        udev=False,
        devices=(Device(Path("/dev/ttyACM0"), 0, 20, 0o660), Device(Path("/dev/x"))),
    )
    (line,) = [f.line() for f in absent(facts)]
    assert "/dev/ttyACM0 (uid 0, gid 20, mode 0660)" in line
    assert "/dev/x (not there yet)" in line
    assert "uid 995, groups 990, 995" in line
    assert absent(dataclasses.replace(FULL, udev=False, devices=())) == []


def test_the_vsc_device_of_each_transport(tmp_path: Path) -> None:
    """SR-0.4: the serial port and the hidraw node are the config's devices; CAN has none."""
    serial = tmp_path / "serial.toml"
    serial.write_text(MINIMAL_CONFIG)
    assert devices(load_config(serial)) == (tmp_path / "vsc",)
    hid = tmp_path / "hid.toml"
    hid.write_text(
        MINIMAL_CONFIG.replace(
            'transport = "serial"\nport = "vsc"', 'transport = "hid"\nhidraw = "h"'
        )
    )
    assert devices(load_config(hid)) == (tmp_path / "h",)
