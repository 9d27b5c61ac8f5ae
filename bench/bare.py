"""The floor the benches measure srcsd against: the bare event-driven loop and the 50 Hz polling
model of the public drivers, each the child process of a rig (``bench/rig.py``).

Run by the rig as ``python -m bench.bare --model event|poll50 --port PTY --report-fd FD``. It
imports only the frame decoder, the messages and the sim output, none of the daemon's loop, so
that what this process costs (CPU time and resident memory, ``bench.idle_cost``) is the floor's
own and not that of modules it never runs.

Both loops do srcsd's I/O at the VSC's full traffic and nothing else: read what has arrived,
decode it with the project's frame decoder, switch the output on the last heartbeat's mode and
e-stop word, and send the user heartbeat. The event-driven loop sends it on srcsd's cadence,
every 50 ms on a schedule that does not drift (``next_due``, SR-5.1), and waits for the port or
for that heartbeat's time, as srcsd's loop waits for its descriptors or its next deadline. The
polling model sends one per 20 ms tick, as the drivers do.
"""

from __future__ import annotations

import argparse
import contextlib
import os
import select
import signal
import struct
import sys
import time
import tty
from collections.abc import Sequence
from pathlib import Path
from types import FrameType

from supervisord.clock import Clock
from supervisord.outputs.base import ReadBack
from supervisord.outputs.sim import SimOutput, SimSpec
from supervisord.protocol.codes import VscMode
from supervisord.protocol.framing import FrameDecoder, encode_frame
from supervisord.protocol.messages import UserHeartbeat, VscHeartbeat
from supervisord.timebase import NS_PER_MS, NS_PER_S, next_due

REPORT = struct.Struct("<?qq")  # level, write started, write finished (monotonic ns)
HEARTBEAT_NS = 50 * NS_PER_MS  # the VSC's heartbeat and srcsd's user heartbeat (20 Hz)
POLL_PERIOD_NS = 20 * NS_PER_MS  # the public drivers' 50 Hz loop
MODELS = ("poll50", "event")


class TimedOutput(SimOutput):
    """A sim output that reports every change of its level: (level, started, finished).

    ``started`` is taken as the loop enters the write, ``finished`` once the level is set and
    read back. By default the level lives in memory only, so ``finished - started`` is a few
    microseconds where a GPIO write would spend its ioctl; with ``--level-file`` the sim
    output also rewrites its mirror file in that interval, which costs milliseconds on ext4
    (its rename-over-a-file flushes the data). The report goes out after the second
    timestamp, so its cost is not in the measured interval.
    """

    def __init__(self, spec: SimSpec, report_fd: int) -> None:
        super().__init__(spec)
        self._report_fd = report_fd
        self._reported: bool | None = None

    def _write(self, on: bool, now: int) -> ReadBack:
        started = time.monotonic_ns()
        readback = super()._write(on, now)
        finished = time.monotonic_ns()
        if on != self._reported:  # a stop re-asserting off is no new edge
            self._reported = on
            os.write(self._report_fd, REPORT.pack(on, started, finished))
        return readback


class BareLoop:
    """The work of the bare loops for one wake-up: read what has arrived, decode it, switch
    the output on the last heartbeat's mode and e-stop word, send a user heartbeat when one is
    due (every wake-up for the polling model, as the drivers do; on srcsd's 50 ms cadence for
    the event-driven one). ``clock`` is the loop's clock (``bench.input_instructions`` drives
    it by hand)."""

    def __init__(self, fd: int, output: SimOutput, event_driven: bool, clock: Clock) -> None:
        self.fd, self.output, self.event_driven, self.clock = fd, output, event_driven, clock
        self.decoder = FrameDecoder()
        self.on = False
        self.next_beat = clock()

    def turn(self) -> None:
        try:
            data = os.read(self.fd, 4096)
        except BlockingIOError:
            data = b""
        for event in self.decoder.feed(data):
            if isinstance(event, VscHeartbeat):
                allowed = event.mode == VscMode.OPERATIONAL and event.estop == 0
                if allowed != self.on:
                    self.on = allowed
                    self.output.set(allowed, self.clock())
        now = self.clock()
        if not self.event_driven:  # polling: one per tick
            os.write(self.fd, encode_frame(UserHeartbeat(0)))
        elif now >= self.next_beat:  # srcsd's cadence: the schedule holds, a late turn
            os.write(self.fd, encode_frame(UserHeartbeat(0)))  # does not move it (SR-5.1)
            self.next_beat = next_due(self.next_beat, now, HEARTBEAT_NS)

    def wait_s(self) -> float:
        """How long the event-driven loop may wait for the port: until its next heartbeat."""
        return max(0, self.next_beat - self.clock()) / NS_PER_S


def open_port(path: str) -> int:
    """The supervisor side of the pty, raw and non-blocking, as the bare loops open it."""
    fd = os.open(path, os.O_RDWR | os.O_NOCTTY | os.O_NONBLOCK)
    tty.setraw(fd)
    return fd


def run(model: str, port: str, output: TimedOutput) -> int:
    """A minimal model of the public drivers' loop (``poll50``): wake every 20 ms, read what
    has arrived, decode it, act on each heartbeat, send a user heartbeat. Written for this
    bench; it is the best case of that design (the drivers hand the value to another node to
    act on).

    ``event`` is the same loop woken by the port or its heartbeat's time instead of a timer:
    the floor that any Python loop on this machine meets (pty hand-off, wake-up, read, decode,
    write), to tell the supervisor's own cost from the platform's. Until SIGTERM.
    """
    event_driven = model == "event"
    stop = False

    def request_stop(_signum: int, _frame: FrameType | None) -> None:
        nonlocal stop
        stop = True

    signal.signal(signal.SIGTERM, request_stop)
    fd = open_port(port)
    output.open(time.monotonic_ns())
    loop = BareLoop(fd, output, event_driven, time.monotonic_ns)
    tick = time.monotonic_ns()
    try:
        while not stop:
            if event_driven:
                with contextlib.suppress(InterruptedError):
                    select.select([fd], [], [], loop.wait_s())
            else:
                tick += POLL_PERIOD_NS
                time.sleep(max(0, tick - time.monotonic_ns()) / NS_PER_S)
            loop.turn()
    finally:
        output.close()
        os.close(fd)
    return 0


def main(argv: Sequence[str] | None = None) -> int:
    parser = argparse.ArgumentParser(prog="bench.bare", description="the floor's side of a rig")
    parser.add_argument("--model", choices=MODELS, default="event")
    parser.add_argument("--port", required=True)
    parser.add_argument("--report-fd", type=int, required=True)
    parser.add_argument("--level-file", default=None, help="mirror the level here (sim path)")
    args = parser.parse_args(argv)
    level_file = Path(args.level_file) if args.level_file else None
    output = TimedOutput(SimSpec(name="drive", path=level_file), args.report_fd)
    return run(args.model, args.port, output)


if __name__ == "__main__":
    sys.exit(main())
