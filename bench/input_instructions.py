"""Instructions per input: the loop's work counted by the CPU's instructions, not by the clock.

Run: ``.venv/bin/python -m bench.input_instructions [--seconds S] [--models srcsd,bare]``
(needs ``valgrind``).

The CPU share of ``bench.idle_cost`` moves with the machine's load (a cold turn on a busy
machine costs several times a warm one); the number of instructions a turn executes does not.
This bench counts them with ``valgrind --tool=callgrind`` (every thread of the process, user
space only) for a fixed, reproducible stretch of the VSC's full traffic, in a child process
that drives the loop turn by turn on a **virtual clock**:

- the VSC's traffic of ``bench.idle_cost`` (joystick 50 Hz with moving sticks from a seeded
  generator, heartbeat 20 Hz, GPS 1 Hz, the key-85 answer, a takeover into RUN), each frame
  written into a real pseudo-terminal at its virtual time, each in a turn of its own;
- **srcsd**: the daemon as ``srcsd --config`` builds it (``supervisord.daemon.assemble``: the
  serial link on the pty, the sim output, the record and its sink thread, the client API
  socket with no client), its ``Supervisor.step`` called once per frame and once per deadline
  of its own (the user heartbeat's 20 Hz, the flight recorder's snapshot), with the clock set to
  that frame's or deadline's time; everything in a turn is the real code, the epoll wait
  included (it returns at once: the frame is there, or the deadline has come);
- **bare**: the bare event-driven loop of ``bench.stop_latency --model event``
  (``bench.bare.BareLoop``: select, read, decode, set the output, a user heartbeat every 50 ms),
  one turn per frame;
- **driver**: the child's own side alone (writing each frame and reading the loop's user
  heartbeats back), which both counts above include; subtracted in the "own" columns.

Each model runs once: ``--warm-up`` virtual seconds (start-up, the takeover into RUN), then
``--seconds`` measured: callgrind dumps its counters at the two marks around that stretch, so
start-up, imports and the encoding of the VSC's frames (done before the first mark) are not
in the count. With
``PYTHONHASHSEED=0`` and a seeded generator the count repeats to within a fraction of a
percent from run to run, loaded machine or not.
"""

from __future__ import annotations

import argparse
import contextlib
import gc
import math
import os
import random
import re
import select
import subprocess
import sys
import tempfile
import time
from collections.abc import Callable, Iterator, Sequence
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path

from bench.bare import HEARTBEAT_NS, BareLoop, open_port
from bench.rig import GPS_NS, JOYSTICK_NS, REPO, SAMPLE_GGA, table
from supervisord.daemon import lifecycle
from supervisord.daemon.loop import Supervisor
from supervisord.protocol.codes import VscMode
from supervisord.protocol.framing import FrameDecoder, encode_frame
from supervisord.protocol.messages import (
    Axis,
    FeedbackGet,
    FeedbackSet,
    Gps,
    Joystick,
    UserHeartbeat,
    VscHeartbeat,
)
from supervisord.sim.pty import PtyPort
from supervisord.timebase import NS_PER_MS, NS_PER_S

MODELS = ("srcsd", "bare", "driver")
TAKEOVER_NS = 400 * NS_PER_MS  # LOCAL this long, then OPERATIONAL (SR-4's takeover)
HEARTBEAT_PHASE_NS = 7 * NS_PER_MS  # so that no two frames fall in one turn
GPS_PHASE_NS = 13 * NS_PER_MS


def traffic(seed: int) -> Iterator[tuple[int, bytes, bool]]:
    """(virtual ns from the start, frame, is the VSC heartbeat) of the VSC's full traffic:
    LOCAL for the takeover's first part, then OPERATIONAL with moving sticks."""
    rng = random.Random(seed)
    next_joystick, next_heartbeat, next_gps = 0, HEARTBEAT_PHASE_NS, GPS_PHASE_NS
    while True:
        now = min(next_joystick, next_heartbeat, next_gps)
        operational = now >= TAKEOVER_NS
        if now == next_joystick:
            left, right = (rng.randint(-1023, 1023) for _ in range(2))
            stick = Joystick(
                left_y=Axis.from_value(left if operational else 0),
                right_x=Axis.from_value(right if operational else 0),
            )
            yield now, encode_frame(stick), False
            next_joystick += JOYSTICK_NS
        elif now == next_heartbeat:
            mode = VscMode.OPERATIONAL if operational else VscMode.LOCAL
            yield now, encode_frame(VscHeartbeat(mode)), True
            next_heartbeat += HEARTBEAT_NS
        else:
            yield now, encode_frame(Gps(Gps.SOURCE_REMOTE, SAMPLE_GGA)), False
            next_gps += GPS_NS


class Driver:
    """The VSC's side in the child: writes each frame into the pty at its virtual time
    (setting the clock to it), reads what the loop sent, answers key 85 (with the next
    frame), counts turns and frames, and marks where the measured stretch starts."""

    def __init__(self, port: PtyPort, schedule: list[tuple[int, bytes]], measured_from: int):
        self.port = port
        self.schedule = schedule
        self.measured_from = measured_from
        self.next = 0  # the index of the next frame
        self.now = schedule[0][0]  # the virtual clock
        self.decoder = FrameDecoder()
        self.answer = b""
        self.user_heartbeats = self.turns = self.frames = 0
        self.counting = False
        self.inputs_so_far: Callable[[], int] = lambda: 0  # the loop's core inputs, if known
        self.first_measured_input = 0

    def clock(self) -> int:
        return self.now

    def next_due(self) -> int | None:
        return self.schedule[self.next][0] if self.next < len(self.schedule) else None

    def deliver(self, reader_fd: int) -> None:
        """The next frame, at its time: written, and readable on the loop's side."""
        self.hear()
        due, frame = self.schedule[self.next]
        self.next += 1
        if not self.counting and due >= self.measured_from:
            self.counting = True
            self.turns = self.frames = self.user_heartbeats = 0
            self.first_measured_input = self.inputs_so_far()
            mark()
        self.now = due
        self.port.write(self.answer + frame)
        self.answer = b""
        select.select([reader_fd], [], [], 1.0)
        self.turns += 1
        self.frames += 1

    def idle_turn(self, until: int) -> None:
        """A turn of the loop's own, at its deadline ``until``: no frame."""
        self.hear()
        self.now = until
        self.turns += 1

    def hear(self) -> None:
        data = self.port.read()
        if not data:
            return
        for event in self.decoder.feed(data):
            if type(event) is FeedbackGet and event.key == 85:
                self.answer = encode_frame(FeedbackSet(85, 1))
            elif type(event) is UserHeartbeat:
                self.user_heartbeats += 1


def mark() -> None:
    """Where the count starts and ends: callgrind dumps its counters before each call of
    libc's ``getppid`` (``--dump-before=getppid``), which nothing else in the child calls."""
    os.getppid()


def run_srcsd(directory: Path, driver: Driver, *, settle: bool = True) -> str:
    """The daemon as ``srcsd --config`` builds it, on the driver's clock, until the last
    frame; its state at the end. Its wait is wrapped (as ``bench.rig.TurnStats`` does: one
    call per turn): the driver delivers the next frame there when it comes before the loop's
    own deadline, else moves the clock to that deadline (the timeout rounded up to the
    millisecond, as epoll takes it) and the real wait returns at once. ``settle``: the heap
    settled after the start, as ``lifecycle.run`` does (``supervisord/daemon/heap.py``); at
    the end, what a full collection of the garbage collector costs (without valgrind, the
    child alone: ``... child --model srcsd --warm-up 3 --seconds 20 [--unsettled]``)."""
    from supervisord.config.loader import load_config  # noqa: PLC0415
    from supervisord.daemon import heap  # noqa: PLC0415
    from supervisord.daemon.assemble import build_api, build_supervisor  # noqa: PLC0415
    from supervisord.testkit.daemon import LASTING_CONFIG  # noqa: PLC0415

    # As bench.idle_cost runs it: the proof test off (the rig's VSC has no watchdog).
    text = LASTING_CONFIG.replace('port = "vsc"\n', 'port = "vsc"\nprooftest = "off"\n')
    (directory / "robot.toml").write_text(text)
    config = load_config(directory / "robot.toml")
    start = driver.now
    supervisor = build_supervisor(config, build_api(config), clock=driver.clock)
    lifecycle.start(supervisor)
    if settle:
        heap.settle()  # as ``lifecycle.run`` does between the start and the first turn
    reader = supervisor.link.fileno()
    assert reader is not None
    wait = supervisor.waiter.wait

    def virtual_wait(timeout: float | None = None, maxevents: int = -1) -> list[tuple[int, int]]:
        own = driver.now + math.ceil((timeout or 0.0) * 1000) * NS_PER_MS
        due = driver.next_due()
        if due is not None and due <= own:
            driver.deliver(reader)
            return wait(timeout, maxevents)
        driver.idle_turn(own)
        return wait(0, maxevents)

    supervisor.waiter.wait = virtual_wait
    flight = supervisor.records.flight
    assert flight is not None
    driver.inputs_so_far = lambda: flight.count
    while driver.next_due() is not None:
        supervisor.step()
    mark()
    assert supervisor.decision is not None
    state = supervisor.decision.state.value
    started = time.perf_counter_ns()
    gc.collect()  # what a full collection costs the loop now (docs/performance.md "The heap")
    print(f"full_collection_ms={(time.perf_counter_ns() - started) / 1e6:.2f}")
    replay_core(supervisor, start, driver.first_measured_input)
    lifecycle.shutdown(supervisor)
    return state


def replay_core(supervisor: Supervisor, start: int, first: int) -> None:
    """The safety core's own share: a fresh core fed the loop's inputs again (the flight
    recorder's ring holds every one since the start), the measured stretch's between two more
    marks. The core is pure, so it decides the same (checked)."""
    from supervisord.safety.core import SafetyCore  # noqa: PLC0415

    assert supervisor.records.flight is not None
    inputs = list(supervisor.records.flight.inputs)
    assert len(inputs) == supervisor.records.flight.count, "raise FlightSettings.max_inputs"
    core = SafetyCore(supervisor.safety, start)
    for event in inputs[:first]:
        core.handle(event)
    mark()
    for event in inputs[first:]:
        core.handle(event)
    mark()
    assert core.decision == supervisor.decision
    print(f"core_inputs={len(inputs) - first}")


def run_bare(directory: Path, driver: Driver, *, loop: bool) -> str:
    """The bare event-driven loop (``loop``), or only reading the port (the driver's own
    share), one turn per frame; whether its output is on at the end."""
    from supervisord.outputs.sim import SimOutput, SimSpec  # noqa: PLC0415

    reader = open_port(str(directory / "vsc"))
    output = SimOutput(SimSpec(name="drive", path=None))
    output.open(driver.clock())
    bare = BareLoop(reader, output, True, driver.clock)
    try:
        while driver.next_due() is not None:
            driver.deliver(reader)
            if loop:
                select.select([reader], [], [], 0.05)
                bare.turn()
            else:
                with contextlib.suppress(BlockingIOError):
                    os.read(reader, 4096)
        mark()
    finally:
        os.close(reader)
    return "on" if bare.on else "off"


def child(model: str, warm_up: float, seconds: float, seed: int, *, settle: bool = True) -> int:
    """Drive ``model`` over ``warm_up`` and then ``seconds`` of virtual traffic, the latter
    between two :func:`mark` calls; print the measured stretch's turns and frames and the
    state at its end."""
    start = 1_000 * NS_PER_S  # the virtual clock's origin: any positive time
    measured_from = start + int(warm_up * NS_PER_S)
    end = measured_from + int(seconds * NS_PER_S)
    schedule = []  # encoded before the count starts: the VSC's own work is not the loop's
    for offset, frame, _ in traffic(seed):
        if start + offset >= end:
            break
        schedule.append((start + offset, frame))
    with tempfile.TemporaryDirectory(prefix="srcs-instr-") as name:
        directory = Path(name)
        port = PtyPort(directory / "vsc")
        driver = Driver(port, schedule, measured_from)
        if model == "srcsd":
            state = run_srcsd(directory, driver, settle=settle)
        else:
            state = run_bare(directory, driver, loop=model == "bare")
        port.close()
    beats = driver.user_heartbeats
    print(f"turns={driver.turns} frames={driver.frames} heartbeats={beats} state={state}")
    return 0


def count(
    model: str, warm_up: float, seconds: float, seed: int, keep: Path | None
) -> tuple[int, dict[str, str]]:
    """Run the child under callgrind; the measured stretch's instructions and what the child
    printed. ``keep``: where to leave the stretch's callgrind file (for callgrind_annotate)."""
    with tempfile.TemporaryDirectory(prefix="srcs-callgrind-") as name:
        out = Path(name) / "callgrind.out"
        command = [
            "valgrind",
            "--tool=callgrind",
            "--dump-before=getppid",
            f"--callgrind-out-file={out}",
            sys.executable,
            "-m",
            "bench.input_instructions",
            "child",
            "--model",
            model,
            "--warm-up",
            str(warm_up),
            "--seconds",
            str(seconds),
            "--seed",
            str(seed),
        ]
        env = dict(os.environ, PYTHONHASHSEED="0")
        # Our own interpreter, our own module: no untrusted input reaches the command.
        done = subprocess.run(  # noqa: S603
            command, cwd=REPO, env=env, capture_output=True, text=True, check=False
        )
        if done.returncode != 0:
            raise RuntimeError(f"{model}: the child failed:\n{done.stderr[-2000:]}")
        # .1: up to the first mark; .2: the measured stretch; for srcsd, .4: the core's replay
        stretch = out.with_name(out.name + ".2")
        if keep is not None:
            keep.write_bytes(stretch.read_bytes())
        said = dict(re.findall(r"(\w+)=(\S+)", done.stdout))
        if model == "srcsd":
            said["core"] = str(totals(out.with_name(out.name + ".4")))
        return totals(stretch), said


def totals(path: Path) -> int:
    """The instructions a callgrind file counted."""
    found = re.search(r"^totals: (\d+)", path.read_text(), re.MULTILINE)
    assert found is not None, path
    return int(found.group(1))


def main(argv: Sequence[str] | None = None) -> None:
    parser = argparse.ArgumentParser(prog="bench.input_instructions", description=__doc__)
    sub = parser.add_subparsers(dest="command")
    run_child = sub.add_parser("child")
    run_child.add_argument("--model", choices=MODELS, required=True)
    run_child.add_argument("--warm-up", type=float, required=True)
    run_child.add_argument("--seconds", type=float, required=True)
    run_child.add_argument("--seed", type=int, default=1)
    run_child.add_argument("--unsettled", action="store_true", help="the heap as start-up left it")
    parser.add_argument("--seconds", type=float, default=20.0, help="virtual seconds measured")
    parser.add_argument("--warm-up", type=float, default=3.0, help="virtual seconds before")
    parser.add_argument("--models", default="srcsd,bare,driver")
    parser.add_argument("--seed", type=int, default=1)
    parser.add_argument("--keep", type=Path, default=None, help="keep srcsd's callgrind file here")
    args = parser.parse_args(argv)
    if args.command == "child":
        sys.exit(
            child(args.model, args.warm_up, args.seconds, args.seed, settle=not args.unsettled)
        )
    models = args.models.split(",")
    with ThreadPoolExecutor(max_workers=2) as pool:
        results = list(
            pool.map(
                lambda model: count(
                    model,
                    args.warm_up,
                    args.seconds,
                    args.seed,
                    args.keep if model == "srcsd" else None,
                ),
                models,
            )
        )
    measured: dict[str, tuple[float, float, str]] = {}
    for model, (instructions, said) in zip(models, results, strict=True):
        turns, frames = int(said["turns"]), int(said["frames"])
        measured[model] = (instructions / frames, instructions / turns, said["state"])
        print(f"{model}: {instructions} instructions over {turns} turns, {frames} frames")
        if "core" in said:
            core, inputs = int(said["core"]), int(said["core_inputs"])
            print(
                f"  of which the safety core, replayed: {core} over {inputs} inputs "
                f"({core / inputs:,.0f} per input, {core / turns:,.0f} per turn, "
                f"{100 * core / instructions:.0f} % of srcsd's)"
            )
    rows = []
    driver = measured.get("driver", (0.0, 0.0, ""))[0]
    for model, (per_frame, per_turn, state) in measured.items():
        own = per_frame - driver if model != "driver" else per_frame
        rows.append([model, f"{per_turn:,.0f}", f"{per_frame:,.0f}", f"{own:,.0f}", state])
    print()
    print(table(["model", "per turn", "per VSC frame", "per frame, own", "state"], rows))
    if "srcsd" in measured and "bare" in measured:
        ratio = (measured["srcsd"][0] - driver) / (measured["bare"][0] - driver)
        print(f"\nsrcsd / bare, own instructions per VSC frame: {ratio:.2f}")


if __name__ == "__main__":
    main()
