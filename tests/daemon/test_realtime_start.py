"""The real ``srcsd``'s start for real time: its memory locked (SR-9.6), every thread named
(SR-9.7), and every thread but the loop at ordinary priority (SR-9.8).

The real daemon against the real simulated VSC on a pty, started as root under SCHED_FIFO 10
as the unit starts it (``chrt``; with ``-R``, the unit's ``CPUSchedulingResetOnFork=yes``, and
without it, where each thread lowers itself), and under the unit's ``LimitMEMLOCK=`` without
``CAP_IPC_LOCK`` (``setpriv --bounding-set=-ipc_lock``: root's capabilities at an exec are its
bounding set, so the limit binds as it binds the unit's user). What is judged is what the
kernel says: ``/proc/PID/task/*/comm`` and the policy field of ``/proc/PID/task/*/stat``, and
``VmLck`` in ``/proc/PID/status``."""

from __future__ import annotations

import os
import re
import resource
import subprocess
import sys
import time
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path

import pytest

from supervisord.client import SupervisorClient
from supervisord.daemon.service_manager_absent import Part
from supervisord.sim.process import SimProcess
from supervisord.testkit.daemon import MINIMAL_CONFIG, SrcsdProcess
from supervisord.threads import LOOP_NAME
from tests.daemon.fifo import needs_fifo
from tests.daemon.test_unit_realtime import UNIT, settings

THREAD_NAMES = {"srcsd-names", "srcsd-record", "srcsd-journal", "srcsd-log", "srcsd-flight"}
"""Every thread the daemon starts besides its loop (supervisord/daemon/sink.py's lanes and the
user names' lookup, supervisord/api/names.py), on a serial VSC: a HID link's open adds
``srcsd-open`` while it runs, and a broken serial port's close ``srcsd-close``
(supervisord/daemon/link_port.py)."""

SCHED_POLICY_FIELD = 41
"""``policy`` in proc(5)'s ``/proc/PID/stat``: the field's number, counted from 1."""

JOURNAL_CONFIG = MINIMAL_CONFIG.replace("journal = false", "journal = true")
"""With the journal's copy of each record: its lane starts where a journal runs."""


needs_realtime = needs_fifo(
    "SCHED_FIFO, and a memory lock limit that binds root", "chrt", "setpriv", "prlimit"
)


def tasks(pid: int) -> list[tuple[str, int]]:
    """Each thread of ``pid``: its name (comm) and its scheduling policy, as the kernel has
    them."""
    found = []
    for tid in sorted(os.listdir(f"/proc/{pid}/task")):
        comm = Path(f"/proc/{pid}/task/{tid}/comm").read_text().strip()
        stat = Path(f"/proc/{pid}/task/{tid}/stat").read_text()
        # The fields after the name's closing parenthesis start at field 3 (state).
        fields = stat[stat.rindex(")") + 2 :].split()
        found.append((comm, int(fields[SCHED_POLICY_FIELD - 3]) & ~os.SCHED_RESET_ON_FORK))
    return found


def status_kb(pid: int, field: str) -> int:
    match = re.search(rf"^{field}:\s+(\d+) kB$", Path(f"/proc/{pid}/status").read_text(), re.M)
    assert match is not None, field
    return int(match.group(1))


def unit_memlock_bytes() -> int:
    """The unit's ``LimitMEMLOCK=`` in bytes (a number with K, M or G, systemd's binary
    units)."""
    (value,) = settings(UNIT)["LimitMEMLOCK"]
    match = re.fullmatch(r"(\d+)([KMG]?)", value)
    assert match is not None, f"LimitMEMLOCK={value}: not a finite size"
    return int(match.group(1)) << {"": 0, "K": 10, "M": 20, "G": 30}[match.group(2)]


def without_ipc_lock(limit: int) -> list[str]:
    """Exec the daemon as root without CAP_IPC_LOCK, its RLIMIT_MEMLOCK ``limit`` bytes: the
    lock binds as under the unit's user."""
    return ["setpriv", "--bounding-set=-ipc_lock", "prlimit", f"--memlock={limit}:{limit}"]


def said(log: str) -> int:
    return log.count(f"runs without {Part.MEMORY_LOCK.value} (")


@contextmanager
def robot(
    tmp_path: Path, prefix: list[str], config: str = MINIMAL_CONFIG
) -> Iterator[tuple[SrcsdProcess, Path]]:
    """The simulated VSC, commissioned, and the real srcsd started under ``prefix``."""
    (tmp_path / "robot.toml").write_text(config)
    log = tmp_path / "srcsd.log"
    with SimProcess(tmp_path, serial="vsc") as sim:
        assert sim.control.key(85, 1) == 1
        with SrcsdProcess(tmp_path / "robot.toml", log=log, prefix=prefix) as daemon:
            yield daemon, log
        assert daemon.exit_status == 0, log.read_text()


def served(daemon: SrcsdProcess) -> bool | None:
    """What ``status`` says of the lock, once the loop answers."""
    with SupervisorClient.connect(daemon.socket) as client:
        return client.status().daemon.loop.memory_locked


STARTED_EVERYWHERE = {"srcsd-names", "srcsd-record", "srcsd-log"}
"""The threads every start has: the journal's lane needs a journal, the flight's a window
directory."""


def _named(found: list[tuple[str, int]]) -> bool:
    names = [comm for comm, _policy in found]
    return set(names) >= STARTED_EVERYWHERE and names.count(LOOP_NAME) == 1


def settle(daemon: SrcsdProcess, log: Path) -> None:
    """Wait until the start is over: the link open, and the lanes and the names' thread
    started, each past its first step (a new thread has its creator's name until then). The
    log's lane starts last: a count of four threads can be met before it is there."""
    end = time.monotonic() + 30
    while "open" not in log.read_text() or not _named(tasks(daemon.pid)):
        assert time.monotonic() < end, log.read_text()
        time.sleep(0.05)


@needs_realtime
@pytest.mark.parametrize(
    "chrt", [["chrt", "-f", "10"], ["chrt", "-R", "-f", "10"]], ids=["threads", "reset-on-fork"]
)
def test_every_thread_is_named_and_only_the_loop_is_real_time(
    tmp_path: Path, chrt: list[str]
) -> None:
    """SR-9.7, SR-9.8: under SCHED_FIFO 10, the loop (the main thread) is named ``srcsd`` and
    keeps FIFO; every other thread has its own name (the kernel's, which a trace shows) and
    runs SCHED_OTHER: lowered by the thread itself, or started there by SCHED_RESET_ON_FORK
    (the unit's CPUSchedulingResetOnFork=yes), which leaves the loop in real time and not said
    to run without it."""
    with robot(tmp_path, chrt, JOURNAL_CONFIG) as (daemon, log):
        settle(daemon, log)
        listed = tasks(daemon.pid)
    found = dict(listed)
    assert len(found) == len(listed), listed  # no two threads share a name
    assert found.pop(LOOP_NAME) == os.SCHED_FIFO, found
    assert set(found) <= THREAD_NAMES, found
    assert set(found) >= STARTED_EVERYWHERE, found
    assert all(policy == os.SCHED_OTHER for policy in found.values()), found
    text = log.read_text()
    # SCHED_RESET_ON_FORK is or'ed into the policy: still real time (SR-0.4's line).
    assert f"runs without {Part.REALTIME.value} (" not in text
    assert "Traceback" not in text


@needs_realtime
def test_the_memory_is_locked_and_fits_the_units_limit(tmp_path: Path) -> None:
    """SR-9.6: started as the unit starts it, the daemon locks its memory and runs: serves
    status, keeps the VSC's link, no allocation fails (MCL_FUTURE locks every later mapping),
    and every page it has is locked; what it locks (``VmLck``, the count RLIMIT_MEMLOCK is
    judged against) is at most half the unit's LimitMEMLOCK=."""
    limit = unit_memlock_bytes()
    with robot(tmp_path, ["chrt", "-R", "-f", "10"]) as (daemon, log):
        settle(daemon, log)
        assert served(daemon) is True
        time.sleep(2.0)  # the VSC's traffic and the lanes' work meanwhile
        assert served(daemon) is True
        locked = status_kb(daemon.pid, "VmLck")
        assert 0 < locked * 1024 <= limit // 2, locked
        assert status_kb(daemon.pid, "VmRSS") <= locked  # every page it has is locked
    text = log.read_text()
    assert said(text) == 0, text
    assert "MemoryError" not in text
    assert "Traceback" not in text


def _limit_settable() -> bool:
    """Whether this process may give a child the unit's RLIMIT_MEMLOCK (a hard limit above
    its own needs CAP_SYS_RESOURCE, which a container may not have)."""
    hard = resource.getrlimit(resource.RLIMIT_MEMLOCK)[1]
    return hard == resource.RLIM_INFINITY or hard >= unit_memlock_bytes()


@needs_realtime
def test_the_units_limit_lets_the_lock_hold_without_cap_ipc_lock(tmp_path: Path) -> None:
    """SR-9.6: without CAP_IPC_LOCK and with the unit's LimitMEMLOCK=, as the unit's user has
    them, the lock holds and the daemon runs without a failed allocation."""
    limit = unit_memlock_bytes()
    if not _limit_settable():
        pytest.skip("cannot raise RLIMIT_MEMLOCK to the unit's here (no CAP_SYS_RESOURCE)")
    with robot(tmp_path, ["chrt", "-R", "-f", "10", *without_ipc_lock(limit)]) as (daemon, log):
        settle(daemon, log)
        assert served(daemon) is True
        time.sleep(2.0)
        assert served(daemon) is True
    text = log.read_text()
    assert said(text) == 0, text
    assert "Traceback" not in text


@needs_realtime
def test_a_refused_lock_is_said_once_and_the_daemon_runs(tmp_path: Path) -> None:
    """SR-9.6, SR-0.4: refused (a limit of 64 KiB, no CAP_IPC_LOCK), the daemon still runs
    (availability: the VSC still stops the robot), says it once at the start with the error
    and the limit and the fix, and ``status`` says ``memory_locked`` false."""
    with robot(tmp_path, without_ipc_lock(64 << 10)) as (daemon, log):
        settle(daemon, log)
        assert served(daemon) is False
        assert status_kb(daemon.pid, "VmLck") == 0
        time.sleep(1.0)  # the running daemon says it no more
    text = log.read_text()
    assert said(text) == 1, text
    assert "RLIMIT_MEMLOCK 64 KiB" in text
    assert "LimitMEMLOCK=" in text
    assert "CAP_IPC_LOCK" in text


@needs_realtime
def test_a_required_lock_refused_stops_the_start(tmp_path: Path) -> None:
    """SR-9.6: with ``lock_memory = "required"``, a refused lock is a failed start: exit 1
    (worth systemd's restart), the reason and the fix in the log, no socket served."""
    (tmp_path / "robot.toml").write_text(MINIMAL_CONFIG + '[realtime]\nlock_memory = "required"\n')
    log = tmp_path / "srcsd.log"
    command = [
        *without_ipc_lock(64 << 10),
        *(sys.executable, "-m", "supervisord.cli.srcsd", "--config", str(tmp_path / "robot.toml")),
    ]
    with open(log, "wb") as out:
        result = subprocess.run(command, stdout=out, stderr=out, timeout=60, check=False)
    text = log.read_text()
    assert result.returncode == 1, text
    assert "cannot start: memory not locked (mlockall: " in text
    assert not (tmp_path / "api.sock").exists()


def test_off_does_not_lock_and_says_so(tmp_path: Path) -> None:
    """SR-9.6: ``lock_memory = "off"`` (the tests' switch for a planted page fault) locks
    nothing, and the start says so as it says a refusal; ``status`` says false."""
    config = MINIMAL_CONFIG + '[realtime]\nlock_memory = "off"\n'
    with robot(tmp_path, [], config) as (daemon, log):
        settle(daemon, log)
        assert status_kb(daemon.pid, "VmLck") == 0
        assert served(daemon) is False
    text = log.read_text()
    assert said(text) == 1, text
    assert 'runs without locked memory (lock_memory = "off")' in text
