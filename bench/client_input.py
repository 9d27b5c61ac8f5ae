"""Client input at its worst: what each line built to be slow costs the loop per KiB, and the
user heartbeat while every client slot floods the worst of them (SR-10.5, SR-10.1).

Run: ``.venv/bin/python -m bench.client_input [--seconds S] [--sizes 1,4,16,64]``.

First, for each family of worst-case lines (``supervisord/testkit/worst_input.py``: strings
that never close, nesting, escapes, long runs of one character, many keys in an op's place,
long numbers ...) and for the framing (a line fed one byte at a time), the CPU time the
server's path for one line takes (the parser, the SR-8.13 reader of a refused line, the
reply), in microseconds per KiB at each size, side by side: a cost linear in the line keeps
its row flat. The time is this thread's CPU time (``time.thread_time_ns``), the least of a few
tries, so a busy machine changes little of it.

Then the real supervisor loop (``bench/rig.py``: the serial link to this process's VSC, the
safety core, the record, the client API at the default line limit of 64 KiB) runs in RUN for
``--seconds`` while a flooding process holds every ordinary client slot
(``api.max_clients``, 16) and pipelines, on each, the costliest family's line at the limit as
fast as the socket takes it, reading its replies. The bench prints the user heartbeat's
periods as the VSC read them (the VSC's watchdog trips at 500 ms; SR-9.3's 2 ms is the quiet
machine's), and the loop's own turns: the most CPU time one turn took bounds how late the
loop can make the heartbeat (docs/performance.md "Client input").
"""

from __future__ import annotations

import argparse
import contextlib
import functools
import itertools
import json
import select
import signal
import socket
import subprocess
import sys
import tempfile
import time
from collections.abc import Callable, Sequence
from pathlib import Path
from types import FrameType

from bench.rig import REPO, TURNS_SUFFIX, Rig, load, machine, ms, percentile, spread_table, table
from bench.stop_latency import CpuTimes, steal_text
from supervisord.api.framing import LineReader
from supervisord.api.server import DEFAULT_MAX_CLIENTS
from supervisord.config.schema import DEFAULT_MAX_MESSAGE_BYTES
from supervisord.testkit.worst_input import LINES, serve_line
from supervisord.tooling.children import terminate

NOMINAL_NS = 50_000_000  # heartbeat_hz = 20 (SR-5 default)
WATCHDOG_NS = 500_000_000  # the VSC's key-85 watchdog (SR-5)
FRAMING = "framing: one byte per chunk"


def cpu_ns(action: Callable[[], object], tries: int) -> int:
    """The least CPU time of this thread ``action`` took over ``tries`` runs."""
    best: int | None = None
    for _ in range(tries):
        start = time.thread_time_ns()
        action()
        took = time.thread_time_ns() - start
        best = took if best is None else min(best, took)
    assert best is not None
    return best


def _fed_byte_by_byte(line: bytes) -> Callable[[], object]:
    chunks = [bytes([byte]) for byte in line] + [b"\n"]

    def feed() -> None:
        reader = LineReader(max_line=1 << 21, max_discard=1 << 21)
        for chunk in chunks:
            reader.feed(chunk)

    return feed


def costs(sizes_kib: Sequence[int]) -> dict[str, list[float]]:
    """Microseconds of CPU per KiB of each family at each size."""
    rows: dict[str, list[float]] = {}
    for name, make in LINES.items():
        rows[name] = []
        for kib in sizes_kib:
            line = make(kib * 1024 - 1)
            tries = max(3, 64 // kib)
            rows[name].append(cpu_ns(functools.partial(serve_line, line), tries) / 1e3 / kib)
    rows[FRAMING] = [
        cpu_ns(_fed_byte_by_byte(LINES["escaped quotes"](kib * 1024 - 1)), 3) / 1e3 / kib
        for kib in sizes_kib
    ]
    return rows


# ---------------------------------------------------------------------------------------------
# The flood: every client slot pipelines the worst line


def flood_main(socket_path: str, family: str, size: int, connections: int) -> int:
    """Open ``connections`` connections and keep each full of ``family``'s line of ``size``
    bytes (and its newline), reading every reply, until SIGTERM."""
    line = LINES[family](size - 1) + b"\n"
    stop = False

    def request_stop(_signum: int, _frame: FrameType | None) -> None:
        nonlocal stop
        stop = True

    signal.signal(signal.SIGTERM, request_stop)
    socks = []
    for _ in range(connections):
        sock = socket.socket(socket.AF_UNIX, socket.SOCK_STREAM)
        sock.connect(socket_path)
        sock.setblocking(False)
        socks.append(sock)
    out = {sock: bytearray() for sock in socks}
    while not stop:
        for sock in socks:
            if len(out[sock]) < 2 * len(line):
                out[sock] += line
        with contextlib.suppress(InterruptedError):
            readable, writable, _ = select.select(socks, socks, [], 0.05)
            for sock in writable:
                with contextlib.suppress(BlockingIOError):
                    del out[sock][: sock.send(out[sock])]
            for sock in readable:
                if not sock.recv(1 << 20):
                    return 1  # the daemon closed a connection
    return 0


def heartbeat_under_flood(
    directory: Path, seconds: float, family: str
) -> tuple[list[int], dict[str, float], int | None]:
    """The user heartbeat's periods (ns) as the VSC read them over ``seconds`` of RUN while
    every client slot floods ``family`` at the default line limit; the loop's turns; the
    flood's exit status (``None``: it ran to the end)."""
    api = directory / "api.sock"
    with Rig(directory, api_socket=api, api_max_line=DEFAULT_MAX_MESSAGE_BYTES) as rig:
        rig.arm()
        command = [
            sys.executable,
            "-m",
            "bench.client_input",
            "flood",
            str(api),
            family,
            str(DEFAULT_MAX_MESSAGE_BYTES),
            str(DEFAULT_MAX_CLIENTS),
        ]
        flood = subprocess.Popen(command, cwd=REPO)  # noqa: S603 -- our interpreter and module
        try:
            rig.vsc.pump_ms(500)  # the flood connects and fills its sockets
            first = len(rig.vsc.heartbeat_arrivals)
            rig.vsc.pump_ms(seconds * 1000)
            arrivals = rig.vsc.heartbeat_arrivals[first:]
            status = flood.poll()
        finally:
            terminate(flood)
    turns = json.loads((directory / f"stops.jsonl{TURNS_SUFFIX}").read_text())
    periods = [later - earlier for earlier, later in itertools.pairwise(arrivals)]
    return periods, turns, status


def main(argv: Sequence[str] | None = None) -> None:
    parser = argparse.ArgumentParser(prog="bench.client_input", description=__doc__)
    parser.add_argument("--seconds", type=float, default=20.0, help="of the flood")
    parser.add_argument("--sizes", default="1,4,16,64", help="line sizes in KiB")
    args = parser.parse_args(argv)
    sizes = [int(size) for size in args.sizes.split(",")]
    print(f"machine: {machine()}")
    print(f"before: {load()}")
    cpu_before = CpuTimes.read()
    rows = costs(sizes)
    header = ["us of CPU per KiB", *(f"{kib} KiB" for kib in sizes), "last / first"]
    print()
    print(
        table(
            header,
            [
                [name, *(f"{value:.1f}" for value in values), f"{values[-1] / values[0]:.2f}"]
                for name, values in rows.items()
            ],
        )
    )
    worst = max((name for name in LINES), key=lambda name: rows[name][-1])
    print()
    print(
        f"the costliest at {sizes[-1]} KiB: {worst!r}, {rows[worst][-1]:.1f} us/KiB: one line "
        f"at the 64 KiB limit costs {rows[worst][-1] * 64 / 1000:.1f} ms of CPU"
    )
    with tempfile.TemporaryDirectory(prefix="srcs-bench-") as directory:
        periods, turns, status = heartbeat_under_flood(Path(directory), args.seconds, worst)
    print(f"after: {load()}; {steal_text(cpu_before)}")
    print()
    print(
        f"user heartbeat at 20 Hz while {DEFAULT_MAX_CLIENTS} connections pipeline {worst!r} "
        f"lines of {DEFAULT_MAX_MESSAGE_BYTES} bytes for {args.seconds:.0f} s:"
    )
    print(spread_table((("period", periods),)))
    print(
        f"loop: {turns['turns']} turns, busy {turns['busy']:.0%} of the time; longest turn "
        f"{turns['max_wall_ms']:.1f} ms, most CPU in one turn {turns['max_cpu_ms']:.1f} ms"
    )
    if status is not None:
        print(f"WARNING: the flood ended early (status {status}): the daemon closed on it")
    gap = max(periods) if periods else 0
    verdict = "PASS" if periods and gap < WATCHDOG_NS else "FAIL"
    print(
        f"worst gap {ms(gap)} ms, p99 {ms(percentile(periods, 0.99) if periods else 0)} ms, "
        f"against the VSC's 500 ms watchdog: {verdict}"
    )


if __name__ == "__main__":
    if sys.argv[1:2] == ["flood"]:
        sys.exit(flood_main(sys.argv[2], sys.argv[3], int(sys.argv[4]), int(sys.argv[5])))
    main()
