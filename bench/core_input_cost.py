"""What one input costs the pure safety core in a steady RUN (docs/performance.md "Per input").

    .venv/bin/python -m bench.core_input_cost [--before TREE] [--rounds N] [--inputs N]

A core on the robot of the tests (serial, one required client, a motion and a power output) is
brought to RUN, then fed a steady VSC heartbeat (Operational, word 0) every 10 ms on the core's own
clock with a client heartbeat every 50 ms between them, then the other way round, then joystick
frames every 10 ms with a VSC and a client heartbeat every 50 ms between them (the inert input: most
of the VSC's traffic, SR-9.4), so that the user heartbeat falls due every 50 ms as on the robot;
each input of the steady kind is timed alone (``perf_counter_ns`` around ``handle``) and the median
of each kind is printed. No input changes a condition. With
``--before TREE`` (another copy of the tree, e.g. the commit before a change), the rounds
alternate between that tree and this one, each in a fresh interpreter, so that both see the
same machine; the load (as ``uptime`` prints it) before and after.
"""

from __future__ import annotations

import argparse
import json
import os
import statistics
import subprocess
import sys
from pathlib import Path

HERE = Path(__file__).resolve().parent.parent

_CHILD = """
import json, statistics, sys, time
from supervisord.protocol.codes import VscMode
from supervisord.protocol.messages import Axis, FeedbackSet, Joystick, VscHeartbeat
from supervisord.safety import (
    ClientConnected, ClientHeartbeat, ClientHello, ClientSpec, LinkOpened, OutputRole,
    OutputSpec, SafetyConfig, SafetyCore, State, VscReceived,
)
MS = 1_000_000
config = SafetyConfig(
    clients=(ClientSpec("planner"),),
    outputs=(OutputSpec("drive", OutputRole.MOTION), OutputSpec("lights", OutputRole.POWER)),
)
now = 5_000 * MS
core = SafetyCore(config, now)
core.handle(LinkOpened(now))
core.handle(VscReceived(now, FeedbackSet(85, 1)))
core.handle(ClientConnected(now, 1, None))
core.handle(ClientHello(now, 1, "planner"))
local, operational = VscMode.LOCAL.value, VscMode.OPERATIONAL.value
for _ in range(12):
    now += 50 * MS
    core.handle(VscReceived(now, VscHeartbeat(local, 0, 0)))
    core.handle(ClientHeartbeat(now, 1))
now += 50 * MS
assert core.handle(VscReceived(now, VscHeartbeat(operational, 0, 0))).state is State.RUN
clock = time.perf_counter_ns
def timed(make, other, inputs):
    # make(now) every 10 ms, timed; the inputs of other(now) every 50 ms between them, not timed
    global now
    times = []
    for number in range(inputs):
        now += 10 * MS
        if number % 5 == 0:
            for extra in other(now):
                core.handle(extra)
            now += 1
        event = make(now)
        start = clock()
        decision = core.handle(event)
        times.append(clock() - start)
        assert decision.state is State.RUN and not decision.records
    return statistics.median(times)
beat = lambda now: VscReceived(now, VscHeartbeat(operational, 0, 0))
client = lambda now: ClientHeartbeat(now, 1)
stick = Joystick(left_y=Axis.from_value(300))
joystick = lambda now: VscReceived(now, stick)
inputs = int(sys.argv[1])
kinds = (
    (beat, lambda now: [client(now)]),
    (client, lambda now: [beat(now)]),
    (joystick, lambda now: [beat(now), client(now)]),
)
print(json.dumps([timed(make, other, inputs) for make, other in kinds]))
"""


def _round(tree: Path, inputs: int) -> tuple[float, float, float]:
    env = dict(os.environ, PYTHONPATH=str(tree))
    out = subprocess.run(  # noqa: S603 -- our own interpreter and script
        [sys.executable, "-c", _CHILD, str(inputs)],
        cwd=tree,
        env=env,
        capture_output=True,
        text=True,
        check=True,
    ).stdout
    vsc, client, joystick = json.loads(out)
    return vsc / 1000, client / 1000, joystick / 1000


def _uptime() -> None:
    """The load the rounds ran under, as ``uptime`` words it (from ``/proc/loadavg``)."""
    load = Path("/proc/loadavg").read_text(encoding="ascii").split()[:3]
    print("uptime: load average:", ", ".join(load))


def main(argv: list[str] | None = None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--before", type=Path, help="another tree, measured in alternation")
    parser.add_argument("--rounds", type=int, default=4)
    parser.add_argument("--inputs", type=int, default=20_000, help="of each kind per round")
    args = parser.parse_args(argv)
    trees = [("after", HERE)] if args.before is None else [("before", args.before), ("after", HERE)]
    _uptime()
    results: dict[str, list[tuple[float, float, float]]] = {name: [] for name, _ in trees}
    for number in range(args.rounds):
        for name, tree in trees if number % 2 == 0 else reversed(trees):
            row = _round(tree, args.inputs)
            results[name].append(row)
            print(f"round {number + 1} {name:6}: {_kinds(row)}")
    _uptime()
    for name, rows in results.items():
        medians = tuple(statistics.median(r[kind] for r in rows) for kind in range(3))
        print(f"{name:6} median of rounds: {_kinds(medians)}")


def _kinds(times: tuple[float, ...]) -> str:
    vsc, client, joystick = times
    return f"VSC heartbeat {vsc:6.1f} µs, client {client:6.1f} µs, joystick {joystick:6.1f} µs"


if __name__ == "__main__":
    main()
