"""Real-time budget: how long ``srcsd`` runs without blocking, and its page faults.

Run: ``.venv/bin/python -m bench.rt_budget [--stops N] [--no-perf]`` (as root, with ``perf``).

The unit runs the daemon in ``SCHED_FIFO`` with ``LimitRTTIME=soft:hard``
(``units/srcsd@.service``, docs/install.md "Scheduling"). RLIMIT_RTTIME counts the CPU time
a real-time thread uses since it last blocked (the kernel restarts the count when the thread
sleeps in a system call and is woken; a preemption does not restart it): a loop that spins
gets SIGXCPU at the soft limit and SIGKILL at the hard one. The budget must therefore be
longer than the longest stretch the daemon ever runs without blocking, start-up included
(Python's imports from the page cache do not block), and short enough that a spinning loop
is killed soon. This bench measures that stretch.

It starts the whole ``srcsd`` (``python -m supervisord.cli.srcsd``, as ``idle_cost`` does)
under the unit's own settings (``bench/unit.py``: its SCHED_FIFO priority and its
RLIMIT_RTTIME, set between fork and exec as systemd does), with a ``NOTIFY_SOCKET`` of its own
(the time of READY=1) and ``WATCHDOG_USEC`` as the unit's ``WatchdogSec=2`` gives it, a serial
VSC on a pseudo-terminal at full traffic (``bench/rig.py``); it takes over and makes
``--stops`` stops (holds, and every tenth an e-stop with its re-arm), then SIGTERM. Meanwhile
``perf sched record -a`` records every context switch; ``perf sched timehist --state`` then
gives each run of each of the daemon's threads and the state it left the CPU in, and the bench
adds up the runs that ended in a preemption (state R) until one ends in a sleep: the count the
kernel keeps for RLIMIT_RTTIME. A daemon that survived the run (exit status 0 after SIGTERM)
never reached the soft limit.

Page faults (minor and major, ``/proc/PID/stat`` fields 10 and 12) are read at READY=1, after
the takeover, after the first stop and after the last: locking memory (``mlockall``) is worth
it only if the stop path faults.
"""

from __future__ import annotations

import argparse
import contextlib
import os
import re
import shutil
import signal
import socket
import subprocess
import sys
import tempfile
import time
from collections.abc import Callable, Iterator, Sequence
from dataclasses import dataclass, field
from pathlib import Path

from bench.rig import RigError, Vsc, load, machine, table
from bench.stop_latency import CpuTimes, steal_text
from bench.unit import Scheduling, apply_in_child, read_unit
from supervisord.protocol.codes import VscMode
from supervisord.testkit.daemon import LASTING_CONFIG
from supervisord.tooling.children import terminate

ESTOP_REMOTE = 0x01  # the remote's e-stop bit of the heartbeat (PR-2)
WATCHDOG_USEC = "2000000"  # the unit's WatchdogSec=2
LONG_MS = 5.0  # runs at least this long are listed one by one
LINE = re.compile(
    r"^\s*(?P<time>\d+\.\d+)\s+\[\d+\]\s+(?P<task>.+?)\[(?P<tid>\d+)(?:/\d+)?\]\s+"
    r"(?P<wait>[\d.]+)\s+(?P<delay>[\d.]+)\s+(?P<run>[\d.]+)\s+(?P<state>\S+)\s*$"
)


@dataclass
class Bursts:
    """Per thread (``main`` or ``thread TID``): the longest run without blocking (ms) before
    READY=1 and after it; every run of :data:`LONG_MS` or more as (time, thread, ms)."""

    startup: dict[str, float] = field(default_factory=dict)
    running: dict[str, float] = field(default_factory=dict)
    long: list[tuple[float, str, float]] = field(default_factory=list)
    switches: int = 0

    @property
    def longest(self) -> float:
        return max([*self.startup.values(), *self.running.values(), 0.0])


def bursts(timehist: str, ready: float, pid: int) -> Bursts:
    """Add up each thread's runs in ``perf sched timehist --state`` output until a run ends
    in a sleep (any state but R: a preemption keeps the kernel's RLIMIT_RTTIME count going);
    ``ready`` (CLOCK_MONOTONIC seconds, as ``perf sched record -k CLOCK_MONOTONIC`` stamps)
    splits start-up from service; ``pid`` names the main thread."""
    found = Bursts()
    going: dict[str, float] = {}
    for line in timehist.splitlines():
        match = LINE.match(line)
        if match is None:
            continue
        found.switches += 1
        tid = match["tid"]
        run = going.get(tid, 0.0) + float(match["run"])
        if match["state"].startswith("R"):
            going[tid] = run
            continue
        going[tid] = 0.0
        name = "main" if tid == str(pid) else f"thread {tid}"
        when = float(match["time"])
        if run >= LONG_MS:
            found.long.append((when, name, run))
        phase = found.startup if when < ready else found.running
        phase[name] = max(phase.get(name, 0.0), run)
    return found


def page_faults(pid: int) -> tuple[int, int]:
    """Minor and major page faults of ``pid`` so far (``/proc/PID/stat`` fields 10 and 12)."""
    fields = Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()
    return int(fields[7]), int(fields[9])


@contextlib.contextmanager
def perf_sched(data: Path, enabled: bool) -> Iterator[None]:
    """``perf sched record`` of the whole machine, stamped with CLOCK_MONOTONIC, meanwhile."""
    perf = shutil.which("perf")
    if not enabled or perf is None:
        yield
        return
    recorder = subprocess.Popen(  # noqa: S603 -- perf found on PATH, fixed arguments
        [perf, "sched", "record", "-k", "CLOCK_MONOTONIC", "-a", "-o", str(data)],
        stdout=subprocess.DEVNULL,
        stderr=subprocess.DEVNULL,
    )
    time.sleep(1.5)  # its events are set up before the daemon starts
    try:
        yield
    finally:
        recorder.send_signal(signal.SIGINT)
        try:
            recorder.wait(60)
        except subprocess.TimeoutExpired:
            recorder.kill()
            recorder.wait()


def timehist(data: Path, pid: int) -> str:
    """``perf sched timehist --state`` of ``pid``'s threads ("" without perf or data)."""
    perf = shutil.which("perf")
    if perf is None or not data.exists():
        return ""
    return subprocess.run(  # noqa: S603 -- perf found on PATH, fixed arguments
        [perf, "sched", "timehist", "--state", "-i", str(data), "-p", str(pid)],
        capture_output=True,
        text=True,
        check=False,
    ).stdout


@dataclass
class Result:
    """What one run measured."""

    exec_to_ready_s: float = 0.0
    ready: float = 0.0  # CLOCK_MONOTONIC seconds of READY=1
    terminated: float = 0.0  # and of the SIGTERM
    exit_status: int | None = None
    faults: dict[str, tuple[int, int]] = field(default_factory=dict)
    stops: int = 0
    history: str = ""
    bursts: Bursts | None = None


def _wait(vsc: Vsc, predicate: Callable[[], bool], limit_s: float) -> bool:
    end = time.monotonic() + limit_s
    while time.monotonic() < end:
        vsc.pump_ms(2)
        if predicate():
            return True
    return False


class Daemon:
    """srcsd started as the unit would start it, its VSC, its notify socket, its output."""

    def __init__(self, directory: Path, scheduling: Scheduling) -> None:
        # The longest VSC timeout (SR-2.2): the VSC is this process, at an ordinary priority
        # beside a FIFO daemon, and late at times on a busy machine; the frames cost the same.
        config = LASTING_CONFIG.replace('port = "vsc"\n', 'port = "vsc"\nprooftest = "off"\n', 1)
        (directory / "robot.toml").write_text(config)
        self.level = directory / "drive"
        self.notify = socket.socket(socket.AF_UNIX, socket.SOCK_DGRAM)
        self.notify.bind(str(directory / "notify"))
        self.notify.setblocking(False)
        self.vsc = Vsc(directory / "vsc")
        self.heard = b""
        self.ready = 0.0
        self.started = time.monotonic()
        command = [sys.executable, "-m", "supervisord.cli.srcsd"]
        self.process = subprocess.Popen(  # noqa: S603 -- our own interpreter and package
            [*command, "--config", str(directory / "robot.toml")],
            cwd=directory,
            stderr=subprocess.DEVNULL,
            env={
                **os.environ,
                "NOTIFY_SOCKET": str(directory / "notify"),
                "WATCHDOG_USEC": WATCHDOG_USEC,
            },
            preexec_fn=lambda: apply_in_child(scheduling),  # noqa: PLW1509 -- no threads
        )

    def is_ready(self) -> bool:
        with contextlib.suppress(BlockingIOError):
            while True:
                self.heard += self.notify.recv(4096)
                if b"READY=1" in self.heard and not self.ready:
                    self.ready = time.monotonic()
        if self.process.poll() is not None:
            raise RigError(f"srcsd exited ({self.process.returncode}) before READY=1")
        return bool(self.ready)

    def level_is(self, text: str) -> bool:
        return self.level.exists() and self.level.read_text() == text

    def takeover(self) -> None:
        for _ in range(10):  # the operator's takeover (SR-4), as in Rig.arm
            self.vsc.set_state(VscMode.LOCAL)
            self.vsc.pump_ms(400)  # the re-arm hold, and Local heartbeats over the dwell
            self.vsc.set_state(VscMode.OPERATIONAL)
            if _wait(self.vsc, lambda: self.level_is("1\n"), 1.0):
                return
        raise RigError("srcsd did not reach RUN")

    def stop_once(self, index: int, estop: bool) -> None:
        """A hold (Pause) or an e-stop, until the output is off; then back to RUN."""
        if estop:
            self.vsc.set_state(VscMode.OPERATIONAL, ESTOP_REMOTE)
        else:
            self.vsc.set_state(VscMode.PAUSE)
        if not _wait(self.vsc, lambda: self.level_is("0\n"), 2.0):
            raise RigError(f"stop {index}: the output stayed on")
        if not estop:
            self.vsc.set_state(VscMode.OPERATIONAL)
        if estop or not _wait(self.vsc, lambda: self.level_is("1\n"), 1.0):
            self.takeover()
        self.vsc.pump_ms(20)

    def close(self) -> int:
        status = terminate(self.process)
        self.vsc.close()
        self.notify.close()
        return status


def run(directory: Path, stops: int, scheduling: Scheduling, *, use_perf: bool = True) -> Result:
    """Start srcsd under ``scheduling``, take over, make ``stops`` stops, stop it."""
    result = Result()
    data = directory / "perf.data"
    with perf_sched(data, use_perf):
        daemon = Daemon(directory, scheduling)
        try:
            if not _wait(daemon.vsc, daemon.is_ready, 60):
                raise RigError("no READY=1 within 60 s")
            result.ready = daemon.ready
            result.exec_to_ready_s = daemon.ready - daemon.started
            pid = daemon.process.pid
            result.faults["exec to READY=1"] = page_faults(pid)
            daemon.takeover()
            daemon.vsc.pump_ms(1000)
            result.faults["after the first takeover"] = page_faults(pid)
            for index in range(stops):
                daemon.stop_once(index, estop=index % 10 == 9)
                result.stops += 1
                if index == 0:
                    result.faults["after the first stop"] = page_faults(pid)
            result.faults["after the last stop"] = page_faults(pid)
        finally:
            result.terminated = time.monotonic()
            result.exit_status = daemon.close()
    result.history = timehist(data, daemon.process.pid)
    if result.history:
        result.bursts = bursts(result.history, result.ready, daemon.process.pid)
    return result


def _limit(us: int | None) -> str:
    return "infinity" if us is None else f"{us / 1000:g} ms"


def report(result: Result, scheduling: Scheduling) -> None:
    """The page faults, each thread's longest run without blocking, the long runs."""
    print(
        f"srcsd under SCHED_FIFO {scheduling.priority}, RLIMIT_RTTIME soft "
        f"{_limit(scheduling.soft_us)}, hard {_limit(scheduling.hard_us)}; "
        f"exec to READY=1 {result.exec_to_ready_s:.2f} s; {result.stops} stops; "
        f"exit status {result.exit_status} after SIGTERM (0: clean, never killed)"
    )
    print()
    rows = [[name, minor, major] for name, (minor, major) in result.faults.items()]
    print(table(["page faults of srcsd, cumulative", "minor", "major"], rows))
    first, last = (
        result.faults.get("after the first stop"),
        result.faults.get("after the last stop"),
    )
    if first and last:
        print()
        print(
            f"faults over stops 2-{result.stops}, with their re-arms and the traffic between "
            f"them: minor {last[0] - first[0]}, major {last[1] - first[1]}"
        )
    print()
    found = result.bursts
    if found is None:
        print("longest run without blocking: not measured (needs perf and root)")
        return
    print("longest run of each srcsd thread without blocking (ms; preemptions added up)")
    print()
    names = sorted(set(found.startup) | set(found.running))
    rows = [
        [name, f"{found.startup.get(name, 0):.3f}", f"{found.running.get(name, 0):.3f}"]
        for name in names
    ]
    print(table(["thread", "exec to READY=1", "after READY=1"], rows))
    print(f"({found.switches} context switches of srcsd recorded)")
    print()
    print(
        f"runs of {LONG_MS:g} ms or more, s from READY=1 "
        f"(SIGTERM at {result.terminated - result.ready:.1f} s):"
    )
    for when, name, length in found.long:
        print(f"  {when - result.ready:+8.3f} s  {name}  {length:.3f} ms")
    if scheduling.soft_us is not None and found.longest:
        print()
        print(
            f"longest: {found.longest:.3f} ms; the soft limit {_limit(scheduling.soft_us)} is "
            f"{scheduling.soft_us / 1000 / found.longest:.1f} times that"
        )


def main(argv: Sequence[str] | None = None) -> None:
    parser = argparse.ArgumentParser(prog="bench.rt_budget", description=__doc__)
    parser.add_argument("--stops", type=int, default=200)
    parser.add_argument("--no-perf", action="store_true", help="faults and survival only")
    parser.add_argument("--timehist", type=Path, default=None, help="keep perf's output here")
    args = parser.parse_args(argv)
    scheduling = read_unit()
    root = os.geteuid() == 0
    if not root:  # RLIMIT_RTTIME counts real-time threads only: this measures faults alone
        scheduling = Scheduling(0, 0, scheduling.soft_us, scheduling.hard_us)
        print("not root: SCHED_OTHER, no perf")
    print(f"machine: {machine()}")
    print(f"before: {load()}")
    cpu_before, started = CpuTimes.read(), time.monotonic()
    with tempfile.TemporaryDirectory(prefix="srcs-bench-") as directory:
        result = run(Path(directory), args.stops, scheduling, use_perf=root and not args.no_perf)
    print(f"after: {load()}; {time.monotonic() - started:.0f} s; {steal_text(cpu_before)}")
    if args.timehist is not None:
        args.timehist.write_text(result.history)
    report(result, scheduling)


if __name__ == "__main__":
    main()
