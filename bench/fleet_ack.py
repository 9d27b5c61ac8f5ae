"""A fleet stop's acknowledgement on one robot: what ``fleet_stop``'s reply says and what the
agent waits for it (SR-8.20; docs/api.md "fleet_stop").

Run: ``.venv/bin/python -m bench.fleet_ack [--stops N]``.

The real ``srcsd`` against ``srcs-sim`` (``supervisord.testkit.robot.Robot``, two sim outputs),
the bench's own process as the fleet agent's user. Each round re-arms the robot by a takeover,
sends ``fleet_stop`` with a new stop id and releases it. Printed, per round and as percentiles:
the reply's ``arrival_to_off_ms`` (the daemon's monotonic clock, from reading the request to the
last read-back of the outputs written off again) and the agent's round trip (this process's
monotonic clock, from the write of the request to the reply read). Figures, not a judgement:
the robot's own stop path is SR-9.1's (``bench.stop_latency``); the fleet's end-to-end figures
(console, broker, agent) are the fleet tier's.
"""

from __future__ import annotations

import argparse
import os
import tempfile
import time
from collections.abc import Sequence
from pathlib import Path

from bench.rig import percentile
from supervisord.api.ops import FleetReleaseRequest, FleetStopRequest
from supervisord.api.replies import FleetStopReply
from supervisord.testkit.robot import OutputDef, Robot

OUTPUTS = (OutputDef("drive"), OutputDef("lights", role="power"))


def run(directory: Path, stops: int) -> list[tuple[float, float]]:
    """``(arrival_to_off_ms, round_trip_ms)`` of ``stops`` fleet stops from RUN."""
    measured: list[tuple[float, float]] = []
    fleet = f"[fleet]\nagent_uid = {os.getuid()}\n"
    with Robot(directory, outputs=OUTPUTS, extra_toml=fleet) as robot:
        robot.arm()
        with robot.client() as agent:
            for index in range(stops):
                if index:
                    robot.rearm()
                sent = time.monotonic_ns()
                ack = agent.call(FleetStopRequest(f"bench-{index}", "bench"))
                back = time.monotonic_ns()
                assert isinstance(ack, FleetStopReply), ack
                assert all(o.readback is False for o in ack.outputs), ack
                measured.append((ack.arrival_to_off_ms, (back - sent) / 1e6))
                agent.call(FleetReleaseRequest(f"bench-{index}", "bench"))
    return measured


def main(argv: Sequence[str] | None = None) -> int:
    parser = argparse.ArgumentParser(prog="bench.fleet_ack", description=__doc__)
    parser.add_argument("--stops", type=int, default=20, help="fleet stops from RUN")
    args = parser.parse_args(argv)
    with tempfile.TemporaryDirectory(prefix="fleet-ack-") as work:
        measured = run(Path(work), args.stops)
    arrival = [a for a, _ in measured]
    trip = [t for _, t in measured]
    print(f"{len(measured)} fleet stops from RUN, two sim outputs")
    print("           p50      p95      max   (ms)")
    for name, values in (("arrival_to_off", arrival), ("round trip", trip)):
        p50, p95 = percentile(values, 0.5), percentile(values, 0.95)
        print(f"{name:14} {p50:7.3f}  {p95:7.3f}  {max(values):7.3f}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
