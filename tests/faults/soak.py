"""The soak: the real ``srcsd`` under full VSC traffic for a long time, with faults injected
at random; at the end its memory and descriptor counts must not have grown.

    python -m tests.faults.soak --minutes 60            # on demand (docs/faults.md)
    python -m tests.faults.soak --minutes 5 --seed 7

Not collected by pytest (the file name does not start with ``test_``). Full traffic: joystick
at 50 Hz with the sticks and buttons moving while the robot runs, heartbeats at 20 Hz, GPS at
1 Hz, remote status at 1 Hz (switched on by a real commissioning), a required client beating
at 10 Hz and a subscriber reading every push. Each round picks one fault at random: a stop
fault, checked with the same four promises as the suite (``Robot.expect_stop`` and
``Robot.recover``), or a noise fault the robot must ride through (``Robot.stays_running``).
The daemon's RSS and open descriptors are sampled after the first arm and after each
minute; the run fails (exit 1) on any broken promise, or if the descriptors grew at all or
the RSS grew by more than ``--rss-growth-mb``.
"""

from __future__ import annotations

import argparse
import random
import shutil
import signal
import sys
import tempfile
import threading
import time
import traceback
from collections import Counter
from collections.abc import Callable
from pathlib import Path

from supervisord.client import SupervisorClient
from supervisord.errors import SrcsError
from supervisord.testkit.robot import Robot, Stop
from supervisord.testkit.wait import wait_until
from supervisord.vocabulary import State

HEARTBEAT = 0x20


def rss_kib(pid: int) -> int:
    for line in Path(f"/proc/{pid}/status").read_text().splitlines():
        if line.startswith("VmRSS:"):
            return int(line.split()[1])
    raise RuntimeError("no VmRSS")


def fd_count(pid: int) -> int:
    return len(list(Path(f"/proc/{pid}/fd").iterdir()))


class Subscriber(threading.Thread):
    """Reads every push of every topic, as a robot's logger would."""

    def __init__(self, socket_path: Path) -> None:
        super().__init__(name="subscriber", daemon=True)
        self.socket_path = socket_path
        self.pushes: Counter[str] = Counter()
        self.reconnects = 0
        self.done = threading.Event()

    def run(self) -> None:
        while not self.done.is_set():
            try:
                with SupervisorClient.connect(self.socket_path, timeout=2.0) as api:
                    api.subscribe("state", "joystick", "gps", "remote_status", "records")
                    while not self.done.is_set():
                        push = api.next_event(timeout=0.5)
                        if push is not None:
                            self.pushes[push.event] += 1
            except SrcsError:
                self.reconnects += 1
                time.sleep(0.2)


class Soak:
    def __init__(self, robot: Robot, rng: random.Random) -> None:
        self.robot = robot
        self.rng = rng
        self.rounds: Counter[str] = Counter()
        self.failures: list[str] = []

    # -- stop faults: each returns the Stop, with the fault still in place -----------------

    def drop_heartbeats(self) -> Stop:
        t = self.robot.now()
        self.robot.vsc.fault(drop=1.0, only_types=[HEARTBEAT])
        return self.robot.expect_stop("vsc_link_lost", t, self.robot.vsc_timeout_s)

    def corrupt_heartbeats(self) -> Stop:
        t = self.robot.now()
        self.robot.vsc.fault(corrupt=1.0, only_types=[HEARTBEAT])
        return self.robot.expect_stop("vsc_link_lost", t, self.robot.vsc_timeout_s)

    def silence(self) -> Stop:
        t = self.robot.now()
        self.robot.vsc.silence(True)
        stop = self.robot.expect_stop("vsc_link_lost", t, self.robot.vsc_timeout_s)
        time.sleep(self.rng.uniform(0.0, 1.0))
        self.robot.vsc.silence(False)
        return stop

    def unplug(self) -> Stop:
        t = self.robot.now()
        self.robot.vsc.unplug()
        time.sleep(self.rng.uniform(0.0, 1.0))
        self.robot.vsc.replug()
        return self.robot.expect_stop("transport_fault", t, 0.0)

    def reboot(self) -> Stop:
        t = self.robot.now()
        self.robot.vsc.reboot(delay=self.rng.uniform(0.2, 1.5))
        stop = self.robot.expect_stop("transport_fault", t, 0.0)
        self.robot.vsc.wait_for(lambda s: s["plugged"] and not s["booting"])
        return stop

    def remote_estop(self) -> Stop:
        stop = self.robot.remote_estop()
        time.sleep(self.rng.uniform(0.0, 0.5))
        self.robot.vsc.release()
        return stop

    def local_estop(self) -> Stop:
        t = self.robot.now()
        with self.robot.client() as operator:
            operator.estop()
            stop = self.robot.expect_stop("local_estop", t, 0.0)
            time.sleep(self.rng.uniform(0.0, 0.5))
            operator.release("estop")
        return stop

    def client_stopped(self) -> Stop:
        nav = self.robot.client_processes["nav"]
        t = self.robot.now()
        nav.signal(signal.SIGSTOP)
        try:
            return self.robot.expect_stop("client_lost:nav", t, 0.5)
        finally:
            nav.signal(signal.SIGCONT)

    def client_killed(self) -> Stop:
        t = self.robot.now()
        self.robot.client_processes["nav"].kill()
        stop = self.robot.expect_stop("client_lost:nav", t, 0.0)
        self.robot.start_clients()
        return stop

    # -- noise the robot rides through ------------------------------------------------------

    NOISE = (
        {"garbage": 0.5, "garbage_max": 64},
        {"unknown_type": 0.5},
        {"duplicate": 0.5},
        {"reorder": 0.2},
        {"chunk_bytes": 16, "chunk_gap_s": 0.002},
        {"corrupt": 0.05},
        {"drop": 0.05},
    )

    def noise(self) -> None:
        plan = self.rng.choice(self.NOISE)
        self.rounds[f"noise {plan}"] += 1
        self.robot.vsc.fault(**plan)
        try:
            self.robot.stays_running(self.rng.uniform(1.0, 5.0))
        finally:
            self.robot.vsc.fault()

    def drive(self) -> None:
        """Sticks and buttons moving while the robot runs (full joystick content)."""
        control = self.robot.vsc
        for _ in range(self.rng.randint(5, 30)):
            control.axes(
                left_x=self.rng.randint(-1023, 1023),
                left_y=self.rng.randint(-1023, 1023),
                right_z=self.rng.randint(-1023, 1023),
            )
            names = ["up", "down", "left", "right", "button_1", "button_2"]
            control.buttons(*self.rng.sample(names, self.rng.randint(0, 2)))
            time.sleep(0.05)
        control.axes(left_x=0, left_y=0, left_z=0, right_x=0, right_y=0, right_z=0)
        control.buttons()

    def round(self) -> None:
        stops: list[Callable[[], Stop]] = [
            self.drop_heartbeats,
            self.corrupt_heartbeats,
            self.silence,
            self.unplug,
            self.reboot,
            self.remote_estop,
            self.local_estop,
            self.client_stopped,
            self.client_killed,
        ]
        self.drive()
        if self.rng.random() < 0.35:
            self.noise()
            return
        fault = self.rng.choice(stops)
        self.rounds[fault.__name__] += 1
        print(f"soak: {fault.__name__}", flush=True)
        try:
            stop = fault()
        finally:
            self.robot.vsc.fault()
        time.sleep(0.3)  # frames held back by a fault drain before the takeover
        self.robot.recover(stop)

    def recover_after_failure(self) -> None:
        """After a broken promise: clear everything and get back to RUN for the next round."""
        self.robot.vsc.fault()
        self.robot.vsc.silence(False)
        state = self.robot.vsc.state()
        if not state["plugged"]:
            self.robot.vsc.replug()
        if state["remote_estop"]:
            self.robot.vsc.release()
        self.robot.start_clients()
        self.robot.rearm()


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(prog="python -m tests.faults.soak", description=__doc__)
    parser.add_argument("--minutes", type=float, default=60.0)
    parser.add_argument("--seed", type=int, default=None)
    parser.add_argument("--rss-growth-mb", type=float, default=8.0)
    parser.add_argument("--keep", action="store_true", help="keep the working directory")
    args = parser.parse_args(argv)
    seed = args.seed if args.seed is not None else random.randrange(1 << 32)
    rng = random.Random(seed)
    print(f"soak: {args.minutes:g} minutes, seed {seed}", flush=True)
    workdir = Path(tempfile.mkdtemp(prefix="srcs-soak-"))
    robot = Robot(workdir, clients=("nav",), seed=seed, boot_delay=1.0)
    subscriber = Subscriber(robot.socket_path)
    failed = False
    try:
        robot.start()
        with robot.client() as admin:
            reply = admin.commission()  # remote status on at 1 Hz: the full traffic
        print(f"soak: commissioned {reply}", flush=True)
        robot.arm()
        subscriber.start()
        assert robot.daemon is not None
        pid = robot.daemon.pid
        time.sleep(2.0)
        first = (rss_kib(pid), fd_count(pid))
        print(f"soak: start RSS {first[0]} KiB, {first[1]} descriptors", flush=True)
        soak = Soak(robot, rng)
        end = time.monotonic() + args.minutes * 60
        next_sample = time.monotonic() + 60
        while time.monotonic() < end:
            try:
                soak.round()
            except (AssertionError, SrcsError) as error:
                soak.failures.append(f"{type(error).__name__}: {error}")
                print(f"soak: FAILED round: {error}", flush=True)
                traceback.print_exc()
                soak.recover_after_failure()
            if time.monotonic() >= next_sample:
                next_sample += 60
                counters = robot.counters()
                print(
                    f"soak: {(time.monotonic() - end) / 60 + args.minutes:5.1f} min: "
                    f"RSS {rss_kib(pid)} KiB, {fd_count(pid)} fds, "
                    f"{counters.messages} messages, rounds {sum(soak.rounds.values())}",
                    flush=True,
                )
        wait_until(lambda: robot.status().report.state is State.RUN, what="RUN at the end")
        time.sleep(2.0)
        last = (rss_kib(pid), fd_count(pid))
        counters = robot.counters()
        records = len(robot.records())
        subscriber.done.set()
        subscriber.join(5)
        print(f"soak: end RSS {last[0]} KiB, {last[1]} descriptors", flush=True)
        print(f"soak: rounds {dict(sorted(soak.rounds.items()))}", flush=True)
        print(
            f"soak: daemon messages {counters.messages}, rejections {dict(counters.rejections)},"
            f" link opens {counters.link.opens}, record errors {counters.record_errors},"
            f" internal faults {counters.internal_faults}; records in the files {records}",
            flush=True,
        )
        print(f"soak: pushes read {dict(subscriber.pushes)}", flush=True)
        growth_mb = (last[0] - first[0]) / 1024
        if last[1] > first[1]:
            print(f"soak: FAIL descriptors grew {first[1]} -> {last[1]}", flush=True)
            failed = True
        if growth_mb > args.rss_growth_mb:
            print(f"soak: FAIL RSS grew {growth_mb:.1f} MB", flush=True)
            failed = True
        if soak.failures:
            print(f"soak: FAIL {len(soak.failures)} broken promises", flush=True)
            failed = True
        robot.finish()
    finally:
        subscriber.done.set()
        robot.close()
        if not args.keep:
            shutil.rmtree(workdir, ignore_errors=True)
        else:
            print(f"soak: kept {workdir}", flush=True)
    print("soak: FAIL" if failed else "soak: OK", flush=True)
    return 1 if failed else 0


if __name__ == "__main__":
    sys.exit(main())
