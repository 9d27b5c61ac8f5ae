"""User-heartbeat period jitter: the 20 Hz heartbeat to the VSC, as the VSC receives it.

Run: ``.venv/bin/python -m bench.heartbeat_jitter [--seconds S] [--spinners N] [--no-pin]``.

The supervisor runs in RUN under the VSC's full traffic (``bench/rig.py``). The VSC side
timestamps every user heartbeat as it reads it from the pseudo-terminal and the bench prints
the periods between them and their deviation from the nominal 50 ms.

"The other core busy" (SR-9): by default the supervisor and the VSC side are
pinned to the last core and ``--spinners`` processes (default 1) spin on the other core(s).
``--no-pin`` pins nothing, so the spinners compete with the supervisor for every core.
"""

from __future__ import annotations

import argparse
import itertools
import os
import subprocess
import sys
import tempfile
from collections.abc import Iterator, Sequence
from contextlib import contextmanager
from pathlib import Path

from bench.rig import Rig, load, machine, ms, percentile, realtime, spread_table
from bench.stop_latency import CpuTimes, steal_text
from supervisord.timebase import NS_PER_MS

NOMINAL_NS = 50 * NS_PER_MS  # heartbeat_hz = 20 (SR-5 default)
TARGET_NS = 2 * NS_PER_MS  # SR-9.3: within 2 ms of nominal at p99


@contextmanager
def spinners(count: int, cpus: set[int] | None) -> Iterator[list[int]]:
    """``count`` processes that spin forever (pinned to ``cpus`` when given); their pids."""
    processes = [subprocess.Popen([sys.executable, "-c", "while True: pass"]) for _ in range(count)]
    try:
        for process in processes:
            if cpus is not None:
                os.sched_setaffinity(process.pid, cpus)
        yield [process.pid for process in processes]
    finally:
        for process in processes:
            process.kill()
            process.wait()


def run(
    directory: Path, seconds: float, spin: int, pin: bool, *, nice: int = 0, fifo: int = 0
) -> tuple[list[int], int]:
    """The heartbeat periods (ns) seen over ``seconds`` of RUN with ``spin`` spinners, and
    how often the supervisor stopped meanwhile (a starved VSC side or loop: each stop sends
    one heartbeat at once and restarts the cadence, so it is counted and shown); the
    supervisor and the VSC side run at ``nice`` (the service unit uses -5; below 0 needs
    root), the spinners at 0; ``fifo`` > 0 puts both in SCHED_FIFO at that priority."""
    cores = sorted(os.sched_getaffinity(0))
    ours = cores[-1] if pin and len(cores) > 1 else None
    others = set(cores[:-1]) if ours is not None else None
    previous = os.sched_getaffinity(0)
    previous_nice = os.getpriority(os.PRIO_PROCESS, 0)
    with spinners(spin, others):  # started first: they keep the nice value we had
        try:
            os.setpriority(os.PRIO_PROCESS, 0, nice)  # the supervisor inherits it
            if ours is not None:
                os.sched_setaffinity(0, {ours})  # the VSC side shares the supervisor's core
            with realtime(fifo), Rig(directory, cpu=ours) as rig:
                rig.arm()
                rig.vsc.pump_ms(500)  # settle: no stop, so the heartbeat keeps its cadence
                first, edges = len(rig.vsc.heartbeat_arrivals), len(rig.vsc.edges)
                rig.vsc.pump_ms(seconds * 1000)
                arrivals = rig.vsc.heartbeat_arrivals[first:]
                stops = sum(not edge.on for edge in rig.vsc.edges[edges:])
        finally:
            os.sched_setaffinity(0, previous)
            os.setpriority(os.PRIO_PROCESS, 0, previous_nice)
    return [later - earlier for earlier, later in itertools.pairwise(arrivals)], stops


def main(argv: Sequence[str] | None = None) -> None:
    parser = argparse.ArgumentParser(prog="bench.heartbeat_jitter", description=__doc__)
    parser.add_argument("--seconds", type=float, default=120.0)
    parser.add_argument("--spinners", type=int, default=1, help="busy processes")
    parser.add_argument("--no-pin", action="store_true", help="let everything share all cores")
    parser.add_argument("--nice", type=int, default=0, help="of the supervisor (unit: -5)")
    parser.add_argument("--fifo", type=int, default=0, help="SCHED_FIFO priority (0: none)")
    args = parser.parse_args(argv)
    print(f"machine: {machine()}")
    print(f"before: {load()}")
    cpu_before = CpuTimes.read()
    with tempfile.TemporaryDirectory(prefix="srcs-bench-") as directory:
        periods, stops = run(
            Path(directory),
            args.seconds,
            args.spinners,
            not args.no_pin,
            nice=args.nice,
            fifo=args.fifo,
        )
    print(f"after: {load()}; {steal_text(cpu_before)}")
    where = "all cores, unpinned" if args.no_pin else "the other core(s); supervisor pinned"
    print(
        f"user heartbeat at 20 Hz, {args.spinners} busy process(es) on {where}, nice {args.nice}"
        + (f", SCHED_FIFO {args.fifo}" if args.fifo else "")
    )
    if stops:
        print(f"WARNING: the supervisor stopped {stops} time(s) during the run (starved?)")
    print()
    deviations = [abs(period - NOMINAL_NS) for period in periods]
    print(spread_table((("period", periods), ("deviation from 50 ms", deviations))))
    p99 = percentile(deviations, 0.99)
    verdict = "PASS" if p99 < TARGET_NS else "FAIL"
    print()
    print(f"SR-9.3 target: within 2 ms of nominal at p99 -> {ms(p99)} ms: {verdict}")


if __name__ == "__main__":
    main()
