"""The rig the timing benches share: a pseudo-terminal VSC in this process, the supervisor in
another.

Two processes, as on a robot, where the VSC and the supervisor do not share a scheduler slot:

- **This process is the VSC.** It holds the device side of a real pseudo-terminal
  (:class:`~supervisord.sim.pty.PtyPort`), sends the VSC's traffic at its real rates
  (joystick 50 Hz, heartbeat 20 Hz, GPS 1 Hz), answers the key-85 query, and timestamps what
  the supervisor writes back (its user heartbeats).
- **The child process is the supervisor** (``python -m bench.rig``): the real
  :class:`~supervisord.daemon.loop.Supervisor` with the real serial link, safety core and
  fsynced JSON Lines record; or, with ``--model event`` or ``poll50``, the bare event-driven
  loop or a minimal model of the public drivers' 20 ms polling loop over the same port
  (``python -m bench.bare``, a process of the floor's modules only). Its one output is a sim
  output that timestamps each change of level with ``time.monotonic_ns()`` right where the
  loop drives it and reports the time over a pipe: the timestamp is taken in the loop's own
  process, so no polling of a file adds to it. CLOCK_MONOTONIC is one clock for the whole
  machine, so the VSC's send times and the supervisor's output times subtract directly.
- **A flooding client** (``--client-flood``, ``python -m bench.rig flood SOCKET``): a third
  process that pipelines hold/release and every other request kind into the supervisor's
  API socket as fast as the socket takes them, and reads its replies as they come.
"""

from __future__ import annotations

import argparse
import contextlib
import json
import math
import os
import platform
import random
import select
import signal
import socket
import subprocess
import sys
import time
from collections.abc import Iterator, Sequence
from dataclasses import dataclass
from pathlib import Path
from types import FrameType, TracebackType

from bench.bare import HEARTBEAT_NS, REPORT, TimedOutput
from bench.bare import MODELS as BARE_MODELS
from supervisord.api.server import ApiServer, ServerConfig
from supervisord.daemon import lifecycle
from supervisord.daemon.api_listener import ApiListener
from supervisord.daemon.loop import Supervisor
from supervisord.links.base import Backoff
from supervisord.links.serial_link import SerialLink
from supervisord.outputs.sim import SimSpec
from supervisord.protocol.codes import VscMode
from supervisord.protocol.framing import FrameDecoder, encode_frame
from supervisord.protocol.messages import (
    Axis,
    FeedbackGet,
    FeedbackSet,
    Gps,
    Joystick,
    Message,
    UserHeartbeat,
    VscHeartbeat,
)
from supervisord.record.jsonl import RecordWriter
from supervisord.safety.config import OutputRole, OutputSpec, SafetyConfig
from supervisord.safety.core import TAKEOVER_DWELL_NS
from supervisord.sim.pty import PtyPort
from supervisord.timebase import NS_PER_MS, next_due
from supervisord.tooling.children import terminate

REPO = Path(__file__).resolve().parents[1]  # the child runs ``-m bench.rig`` from here
SAMPLE_GGA = "$GPGGA,123519.00,4807.0380,N,01131.0000,E,1,08,0.9,545.4,M,46.9,M,,*69"
JOYSTICK_NS = 20 * NS_PER_MS  # the VSC's default rates (manual table 5; HEARTBEAT_NS)
GPS_NS = 1000 * NS_PER_MS
MODELS = ("supervisor", *BARE_MODELS)


# ---------------------------------------------------------------------------------------------
# The child: the supervisor with a timestamping output (the floor's loops: bench/bare.py)


def run_supervisor(args: argparse.Namespace, output: TimedOutput) -> int:
    """The real loop: serial link, safety core, outputs, fsynced record; until SIGTERM."""
    safety = SafetyConfig(
        vsc_timeout_ms=args.timeout_ms,
        rearm_hold_ms=args.hold_ms,
        outputs=(OutputSpec(output.name, OutputRole(args.role)),),
    )
    listener = None
    if args.api_socket:
        config = ServerConfig(path=Path(args.api_socket))
        if args.api_max_line:  # api.max_message_bytes (bench/client_input.py: the default)
            config = ServerConfig(path=config.path, max_line=args.api_max_line)
        listener = ApiListener(ApiServer(config))
    supervisor = Supervisor(
        safety,
        SerialLink(args.port),
        [output],
        RecordWriter(Path(args.record)),
        backoff=Backoff(20, 100),
        listener=listener,
    )
    if args.fsync_delay_ms:
        slow_disk(args.fsync_delay_ms / 1000)
    if not args.api_socket:
        return lifecycle.run(supervisor)
    turns = TurnStats(supervisor)
    status = lifecycle.run(supervisor)
    Path(f"{args.record}{TURNS_SUFFIX}").write_text(json.dumps(turns.summary()))
    return status


TURNS_SUFFIX = ".turns.json"
"""With the client API (``--client-flood``), the loop's turns are written to the record's path
plus this suffix when the child ends (:class:`TurnStats`)."""


class TurnStats:
    """The loop's turns, from its wait returning to its next wait: the longest in wall-clock
    and in the thread's own CPU time, and the share of the time spent in turns (busy). A turn
    serves at most ``requests_per_turn`` client requests (docs/api.md "Limits"): its CPU time
    is the loop's own cost; wall time beyond it is time the machine did not give the loop.

    Bench instrumentation only: it wraps the loop's wait of this one process."""

    def __init__(self, supervisor: Supervisor) -> None:
        self.turns = 0
        self.max_wall_ns = self.max_cpu_ns = self.busy_ns = 0
        self._first_ns: int | None = None
        self._woke: tuple[int, int] | None = None
        wait = supervisor.waiter.wait  # the loop's epoll wait, measured from outside: no hook

        def select(timeout: float | None = None, maxevents: int = -1) -> list[tuple[int, int]]:
            self._turn_ends()
            ready = wait(timeout, maxevents)
            self._woke = (time.monotonic_ns(), time.thread_time_ns())
            return ready

        supervisor.waiter.wait = select

    def _turn_ends(self) -> None:
        now = time.monotonic_ns()
        if self._first_ns is None:
            self._first_ns = now
        if self._woke is None:
            return
        wall, cpu = now - self._woke[0], time.thread_time_ns() - self._woke[1]
        self.turns += 1
        self.busy_ns += wall
        self.max_wall_ns = max(self.max_wall_ns, wall)
        self.max_cpu_ns = max(self.max_cpu_ns, cpu)
        self._woke = None

    def summary(self) -> dict[str, float]:
        span = time.monotonic_ns() - (self._first_ns or time.monotonic_ns())
        return {
            "turns": self.turns,
            "max_wall_ms": self.max_wall_ns / 1e6,
            "max_cpu_ms": self.max_cpu_ns / 1e6,
            "busy": self.busy_ns / span if span else 0.0,
        }


def slow_disk(delay_s: float) -> None:
    """``--slow-disk`` (SR-7.5): every ``os.fsync`` of this child process (the stop
    record's, in the record sink's thread) takes ``delay_s`` longer, as on a slow SD card. It
    sleeps after the real fsync: a sleep releases the GIL as a blocking fsync does, so the
    loop's thread runs meanwhile exactly as it would. The delay ends when the bench stops the
    child, so that the shutdown drains the record queue at once instead of 50 ms a record."""
    real_fsync = os.fsync
    slow = [True]

    def fsync(fd: int) -> None:
        real_fsync(fd)
        if slow[0]:
            time.sleep(delay_s)

    os.fsync = fsync  # type: ignore[assignment] # the record writer passes descriptors
    shutdown = lifecycle.shutdown  # the one ``lifecycle.run`` calls, in this child only

    def fast_shutdown(loop: Supervisor) -> None:
        slow[0] = False
        shutdown(loop)

    lifecycle.shutdown = fast_shutdown


def child_main(argv: Sequence[str] | None = None) -> int:
    parser = argparse.ArgumentParser(prog="bench.rig", description="the supervisor side")
    parser.add_argument("--port", required=True)
    parser.add_argument("--report-fd", type=int, required=True)
    parser.add_argument("--level-file", default=None, help="mirror the level here (sim path)")
    parser.add_argument("--record", required=True)
    parser.add_argument("--timeout-ms", type=int, default=200)
    parser.add_argument("--hold-ms", type=int, default=100)
    parser.add_argument("--api-socket", default=None, help="serve the client API here")
    parser.add_argument("--api-max-line", type=int, default=0, help="its line limit (0: 4096)")
    parser.add_argument("--role", choices=("motion", "power"), default="motion")
    parser.add_argument("--fsync-delay-ms", type=float, default=0, help="a slow disk")
    args = parser.parse_args(argv)
    level_file = Path(args.level_file) if args.level_file else None
    output = TimedOutput(SimSpec(name="drive", path=level_file), args.report_fd)
    return run_supervisor(args, output)


# ---------------------------------------------------------------------------------------------
# The flooding client

FLOOD_REQUESTS: tuple[object, ...] = (
    {"op": "hold"},
    {"op": "release", "what": "hold"},
    {"op": "hold"},
    {"op": "release", "what": "hold"},
    {"op": "status"},
    {"op": "heartbeat"},
    {"op": "release", "what": "estop"},
    {"op": "hello", "name": "again"},
    {"op": "subscribe", "topics": ["state"]},
    {"op": "display", "value": {"key": 1, "value": 42}},
    {"op": "display", "label": {"key": 1, "text": "speed"}},
    {"op": "display", "row": {"index": 1, "text": "flooding"}},
    {"op": "display", "mode": 1},
    {"op": "vibrate", "side": "both"},
    {"op": "reset"},
    {"op": "nonsense"},
    "not json",
)
"""One round of the flood: hold/release pairs and every other kind of request a client may
send (no ``estop``: it would stop the robot, which is the point of no flood; no
``commission``: it writes the VSC)."""


def flood_main(socket_path: str) -> int:
    """Say hello as ``flood``, then keep the socket full of requests and read every reply,
    until the connection ends or SIGTERM."""
    batch = b"".join(
        (r if isinstance(r, str) else json.dumps(r)).encode() + b"\n" for r in FLOOD_REQUESTS
    )
    batch *= 20
    stop = False

    def request_stop(_signum: int, _frame: FrameType | None) -> None:
        nonlocal stop
        stop = True

    signal.signal(signal.SIGTERM, request_stop)
    with socket.socket(socket.AF_UNIX, socket.SOCK_STREAM) as sock:
        sock.connect(socket_path)
        sock.sendall(b'{"op": "hello", "name": "flood"}\n')
        sock.setblocking(False)
        out = bytearray()
        while not stop:
            if len(out) < 65536:
                out += batch
            with contextlib.suppress(InterruptedError):
                readable, writable, _ = select.select([sock], [sock], [], 0.05)
                if writable:
                    with contextlib.suppress(BlockingIOError):
                        del out[: sock.send(out)]
                if readable and not sock.recv(1 << 20):
                    return 1  # the daemon closed the connection
    return 0


def start_flood(socket_path: Path) -> subprocess.Popen[bytes]:
    """The flooding client as a process of its own (stop it with ``terminate``)."""
    deadline = time.monotonic() + 10
    while not socket_path.exists():
        if time.monotonic() > deadline:
            raise RigError(f"no API socket at {socket_path}")
        time.sleep(0.01)
    command = [sys.executable, "-m", "bench.rig", "flood", str(socket_path)]
    return subprocess.Popen(command, cwd=REPO)  # noqa: S603 -- our own interpreter and module


# ---------------------------------------------------------------------------------------------
# This process: the VSC


@dataclass(frozen=True)
class Edge:
    """One change of the output's level, as the supervisor's process timed it."""

    on: bool
    started: int
    finished: int


class RigError(RuntimeError):
    """The supervisor did not do what the bench waited for (or died)."""


class Vsc:
    """The VSC's side of a pseudo-terminal: its traffic, its answers, and what it hears.

    ``pump`` is the only place time passes: it sends what is due, reads the supervisor's
    frames and, when a report pipe is given, the output's edges.
    """

    def __init__(self, port_path: Path, report_fd: int | None = None, seed: int = 1) -> None:
        self.port = PtyPort(port_path)
        self.report_fd = report_fd
        self.rng = random.Random(seed)
        self.mode = VscMode.LOCAL
        self.estop = 0
        self.silent = False
        self.joystick = True
        self.edges: list[Edge] = []
        self.heartbeat_arrivals: list[int] = []  # monotonic ns of each user heartbeat read
        self.heartbeat_estops = 0
        self.heard_frames = 0  # every frame the supervisor wrote, of any kind
        self.sent_frames = 0
        self.sent_bytes = 0
        self._decoder = FrameDecoder()
        self._report_buffer = b""
        now = time.monotonic_ns()
        self._next_joystick = now
        self._next_heartbeat = now
        self._next_gps = now

    def close(self) -> None:
        self.port.close()

    def send(self, message: Message) -> int:
        """Write one frame; returns the monotonic time taken just before the write, so that
        a latency measured from it is an upper bound (it includes the write itself)."""
        frame = encode_frame(message)
        sent = time.monotonic_ns()
        self.port.write(frame)
        self.sent_frames += 1
        self.sent_bytes += len(frame)
        return sent

    def set_state(self, mode: VscMode, estop: int = 0) -> int:
        """Change what the heartbeats say and send one at once (the cadence restarts from
        now, as a VSC reporting a change would); returns its send time."""
        self.mode, self.estop = mode, estop
        self._next_heartbeat = time.monotonic_ns() + HEARTBEAT_NS
        return self.send(VscHeartbeat(mode, 0, estop))

    def _traffic(self, now: int) -> int:
        """Send whatever is due at ``now``; returns when the next frame is due."""
        if self.silent:
            return now + HEARTBEAT_NS
        if self.joystick and now >= self._next_joystick:
            moving = self.mode == VscMode.OPERATIONAL  # the VSC zeroes the sticks otherwise
            self.send(
                Joystick(
                    left_y=Axis.from_value(self.rng.randint(-1023, 1023) if moving else 0),
                    right_x=Axis.from_value(self.rng.randint(-1023, 1023) if moving else 0),
                )
            )
            self._next_joystick = next_due(self._next_joystick, now, JOYSTICK_NS)
        if now >= self._next_heartbeat:
            self.send(VscHeartbeat(self.mode, 0, self.estop))
            self._next_heartbeat = next_due(self._next_heartbeat, now, HEARTBEAT_NS)
        if self.joystick and now >= self._next_gps:
            self.send(Gps(Gps.SOURCE_REMOTE, SAMPLE_GGA))
            self._next_gps = next_due(self._next_gps, now, GPS_NS)
        due = [self._next_heartbeat]
        if self.joystick:
            due += [self._next_joystick, self._next_gps]
        return min(due)

    def _hear(self) -> None:
        data = self.port.read()
        arrived = time.monotonic_ns()
        for event in self._decoder.feed(data):
            self.heard_frames += 1
            if isinstance(event, UserHeartbeat):
                self.heartbeat_arrivals.append(arrived)
                self.heartbeat_estops += event.estop != 0
            elif event == FeedbackGet(85):
                self.send(FeedbackSet(85, 1))  # the VSC's user watchdog is on

    def _read_reports(self) -> None:
        assert self.report_fd is not None
        data = os.read(self.report_fd, 4096)
        if not data:
            raise RigError("the supervisor closed its report pipe (did it die?)")
        self._report_buffer += data
        while len(self._report_buffer) >= REPORT.size:
            on, started, finished = REPORT.unpack_from(self._report_buffer)
            self._report_buffer = self._report_buffer[REPORT.size :]
            self.edges.append(Edge(on, started, finished))

    def pump(self, until: int) -> None:
        """Run the VSC until monotonic time ``until``."""
        while True:
            now = time.monotonic_ns()
            wake = min(self._traffic(now), until)
            watched = [self.port.fd] + ([self.report_fd] if self.report_fd is not None else [])
            ready, _, _ = select.select(watched, [], [], max(0, wake - now) / 1e9)
            if self.port.fd in ready:
                self._hear()
            if self.report_fd is not None and self.report_fd in ready:
                self._read_reports()
            if time.monotonic_ns() >= until:
                return

    def pump_ms(self, ms: float) -> None:
        self.pump(time.monotonic_ns() + int(ms * NS_PER_MS))

    def wait_edge(self, on: bool, limit_ms: float = 1000) -> Edge | None:
        """Run until the output reports a change to ``on``; ``None`` after ``limit_ms``."""
        seen = len(self.edges)
        end = time.monotonic_ns() + int(limit_ms * NS_PER_MS)
        while time.monotonic_ns() < end:
            for edge in self.edges[seen:]:
                if edge.on == on:
                    return edge
            seen = len(self.edges)
            self.pump(min(end, time.monotonic_ns() + 5 * NS_PER_MS))
        return None


class Rig:
    """The VSC here, the supervisor (or the polling model) in a child process.

    Use as a context manager; it stops the child with SIGTERM and removes nothing it did not
    create (everything lives in ``directory``). ``fsync_delay_ms``: every fsync of the
    supervisor's record takes that much longer (``--slow-disk``, :func:`slow_disk`).
    """

    def __init__(
        self,
        directory: Path,
        *,
        model: str = "supervisor",
        timeout_ms: int = 200,
        hold_ms: int = 100,
        cpu: int | None = None,
        mirror: bool = False,
        nice: int = 0,
        api_socket: Path | None = None,
        api_max_line: int = 0,
        role: str = "motion",
        fsync_delay_ms: float = 0,
    ) -> None:
        self.hold_ms = hold_ms
        self.api_socket = api_socket
        read_fd, write_fd = os.pipe()
        self.vsc = Vsc(directory / "vsc", read_fd)
        port = f"--port={directory / 'vsc'}"
        command = [sys.executable, "-m"]
        if model != "supervisor":  # the floor: a process of its own modules only (bench/bare.py)
            command += ["bench.bare", f"--model={model}", port, f"--report-fd={write_fd}"]
        else:
            command += [
                "bench.rig",
                port,
                f"--report-fd={write_fd}",
                f"--record={directory / 'stops.jsonl'}",
                f"--timeout-ms={timeout_ms}",
                f"--hold-ms={hold_ms}",
                f"--role={role}",
            ]
            if api_socket is not None:
                command.append(f"--api-socket={api_socket}")
            if api_max_line:
                command.append(f"--api-max-line={api_max_line}")
            if fsync_delay_ms:
                command.append(f"--fsync-delay-ms={fsync_delay_ms}")
        if mirror:
            command.append(f"--level-file={directory / 'drive'}")
        # Our own interpreter running our own module: no untrusted input reaches the command.
        self.process = subprocess.Popen(command, cwd=REPO, pass_fds=(write_fd,))  # noqa: S603
        os.close(write_fd)  # the child's copy is the only writer: EOF means it died
        if cpu is not None:
            os.sched_setaffinity(self.process.pid, {cpu})
        if nice:  # the service unit runs srcsd at Nice=-5; below 0 needs root
            os.setpriority(os.PRIO_PROCESS, self.process.pid, nice)

    @property
    def pid(self) -> int:
        return self.process.pid

    def close(self) -> None:
        terminate(self.process)
        if self.vsc.report_fd is not None:
            os.close(self.vsc.report_fd)
            self.vsc.report_fd = None
        self.vsc.close()

    def __enter__(self) -> Rig:
        return self

    def __exit__(
        self,
        kind: type[BaseException] | None,
        error: BaseException | None,
        traceback: TracebackType | None,
    ) -> None:
        self.close()

    def wait_idle(self, limit_ms: float = 200) -> bool:
        """Run the VSC until the supervisor's process sleeps in its loop's ``epoll_wait``:
        done with the previous input, including the fsync of its record. False when that
        cannot be seen (no ``/proc/PID/wchan``) or did not happen within ``limit_ms``."""
        wchan = Path(f"/proc/{self.pid}/wchan")
        end = time.monotonic_ns() + int(limit_ms * NS_PER_MS)
        while time.monotonic_ns() < end:
            try:
                if "epoll" in wchan.read_text():
                    return True
            except OSError:
                return False
            self.vsc.pump(time.monotonic_ns() + NS_PER_MS // 2)
        return False

    def arm(self, tries: int = 10) -> Edge:
        """Bring the output on: a non-Operational heartbeat, clear conditions for the re-arm
        hold (and key 85 answered), then Operational: the operator's takeover
        (SR-4.2). Returns the on edge."""
        for _ in range(tries):
            self.vsc.silent = False
            self.vsc.set_state(VscMode.LOCAL)
            # the hold, and Local heartbeats spanning the takeover dwell (re-arm rule 4)
            self.vsc.pump_ms(max(self.hold_ms + 30, TAKEOVER_DWELL_NS / NS_PER_MS + 50))
            self.vsc.set_state(VscMode.OPERATIONAL)
            edge = self.vsc.wait_edge(True, limit_ms=1000)
            if edge is not None:
                return edge
            if self.process.poll() is not None:
                break
        raise RigError(f"the output did not come on (child status {self.process.poll()})")


@contextlib.contextmanager
def realtime(priority: int) -> Iterator[None]:
    """Run this process, and the children it starts meanwhile, in SCHED_FIFO at ``priority``
    (0: leave the scheduling as it is). As ``CPUSchedulingPolicy=fifo`` would run the
    service; needs root (CAP_SYS_NICE)."""
    if not priority:
        yield
        return
    previous = os.sched_getscheduler(0), os.sched_getparam(0)
    os.sched_setscheduler(0, os.SCHED_FIFO, os.sched_param(priority))
    try:
        yield
    finally:
        os.sched_setscheduler(0, previous[0], previous[1])


def percentile(values: Sequence[float], share: float) -> float:
    """The nearest-rank percentile (``share`` in 0..1) of ``values``: always a measured value."""
    ordered = sorted(values)
    rank = max(1, min(len(ordered), math.ceil(share * len(ordered))))
    return ordered[rank - 1]


def machine() -> str:
    """The machine in one line: CPU model, cores, kernel, Python (no host name)."""
    model = platform.processor() or platform.machine()
    with contextlib.suppress(OSError):
        for line in Path("/proc/cpuinfo").read_text().splitlines():
            if line.startswith("model name"):
                model = line.split(":", 1)[1].strip()
                break
    return (
        f"{model}, {os.cpu_count()} cores, {platform.machine()}, Linux {platform.release()}, "
        f"Python {platform.python_version()}"
    )


def load() -> str:
    """The load averages, to show how busy the machine was around a run."""
    one, five, fifteen = os.getloadavg()
    return f"load average {one:.2f} {five:.2f} {fifteen:.2f}"


def table(header: Sequence[str], rows: Sequence[Sequence[object]]) -> str:
    """A Markdown table (the benches' output pastes into docs/performance.md as it is)."""
    lines = ["| " + " | ".join(header) + " |", "|" + "---|" * len(header)]
    lines += ["| " + " | ".join(str(cell) for cell in row) + " |" for row in rows]
    return "\n".join(lines)


def ms(ns: float) -> str:
    return f"{ns / NS_PER_MS:.3f}"


def spread_table(named: Sequence[tuple[str, Sequence[float]]]) -> str:
    """The min, p50, p99 and max of each named series of nanoseconds, in ms, as one table."""
    rows = [
        [
            name,
            len(values),
            ms(min(values)),
            ms(percentile(values, 0.5)),
            ms(percentile(values, 0.99)),
            ms(max(values)),
        ]
        for name, values in named
    ]
    return table(["ms", "n", "min", "p50", "p99", "max"], rows)


if __name__ == "__main__":
    if sys.argv[1:2] == ["flood"]:
        sys.exit(flood_main(sys.argv[2]))
    sys.exit(child_main())
