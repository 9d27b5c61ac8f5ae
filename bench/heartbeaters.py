"""Robot programs for ``bench.idle_cost``: N required clients heartbeating srcsd at 10 Hz each.

Run by the bench as ``python -m bench.heartbeaters SOCKET N --count FILE``: a process of its
own, as a robot's programs are, so that neither their work nor the VSC's (the bench's process)
is counted in srcsd's CPU time. Each client is the real client library
(:class:`~supervisord.client.SupervisorClient`) on its own connection to the API socket: it
says hello under its name (``bench-0`` ... ``bench-N-1``, the config's ``[[clients]]``) and
then sends a heartbeat and waits for its reply every 100 ms, as the library's own example does
(SR-8). The N clients' heartbeats are spread evenly over the period, so that srcsd meets one
request at a time, as from N programs that do not beat in step. Once all have said hello, and
then once a second, the count of heartbeats sent so far and the monotonic time are written to
``FILE`` (replaced whole), so that the bench can tell the rate that the clients achieved
over its window.
"""

from __future__ import annotations

import argparse
import contextlib
import os
import signal
import sys
import time
from collections.abc import Sequence
from pathlib import Path
from types import FrameType

from supervisord.api.framing import ApiError
from supervisord.client import SupervisorClient
from supervisord.timebase import NS_PER_S, next_due

NAME_PREFIX = "bench-"
RATE_HZ = 10
HELLO_LIMIT_S = 30.0


def client_names(count: int) -> list[str]:
    """The names the clients say hello under (the config's ``[[clients]]``)."""
    return [f"{NAME_PREFIX}{index}" for index in range(count)]


def write_count(path: Path, beats: int) -> None:
    """``beats`` and the monotonic time now, replacing ``path`` whole (never read half)."""
    partial = path.with_name(path.name + ".part")
    partial.write_text(f"{beats} {time.monotonic_ns()}\n")
    os.replace(partial, path)


def read_count(path: Path) -> tuple[int, int]:
    """What :func:`write_count` last wrote: heartbeats sent, and when (monotonic ns)."""
    beats, at = path.read_text().split()
    return int(beats), int(at)


def hello(client: SupervisorClient, name: str) -> SupervisorClient:
    """Say hello as ``name``; a hello the record budget refuses (each hello is a record, and
    the budget counts a user's records per second, SR-8.5) is said again a moment later."""
    deadline = time.monotonic() + HELLO_LIMIT_S
    while True:
        try:
            client.hello(name)
        except ApiError:
            if time.monotonic() > deadline:
                raise
            time.sleep(0.1)
        else:
            return client


def main(argv: Sequence[str] | None = None) -> int:
    parser = argparse.ArgumentParser(prog="bench.heartbeaters", description=__doc__)
    parser.add_argument("socket")
    parser.add_argument("clients", type=int)
    parser.add_argument("--count", required=True, help="where to write the heartbeats sent")
    parser.add_argument("--rate", type=float, default=RATE_HZ, help="per client (Hz)")
    args = parser.parse_args(argv)
    stop = False

    def request_stop(_signum: int, _frame: FrameType | None) -> None:
        nonlocal stop
        stop = True

    signal.signal(signal.SIGTERM, request_stop)
    count = Path(args.count)
    with contextlib.ExitStack() as stack:
        clients = [
            hello(stack.enter_context(SupervisorClient.connect(args.socket)), name)
            for name in client_names(args.clients)
        ]
        step = int(NS_PER_S / args.rate / len(clients))  # one client's turn every step
        beats = 0
        write_count(count, beats)
        due = report = time.monotonic_ns()
        while not stop:
            time.sleep(max(0, due - time.monotonic_ns()) / NS_PER_S)
            clients[beats % len(clients)].heartbeat()
            beats += 1
            now = time.monotonic_ns()
            due = next_due(due, now, step)  # a late process restarts the cadence (SR-5.1)
            if now >= report:
                write_count(count, beats)
                report = now + NS_PER_S
    return 0


if __name__ == "__main__":
    sys.exit(main())
