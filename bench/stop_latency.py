"""Stop latency: from the last byte of a stopping frame to the output off.

Run: ``.venv/bin/python -m bench.stop_latency [--stops N] [--estop-every K] [--model M]``.

The real supervisor loop runs in a child process against a pseudo-terminal VSC in this one
(``bench/rig.py``), under the VSC's full traffic (joystick 50 Hz, heartbeat 20 Hz, GPS 1 Hz).
Each stop starts in RUN, after a random 2-8 ms pause so that it lands at a random phase of the
traffic and of the supervisor's own heartbeat timer, and is one of:

- ``hold``: a heartbeat whose mode leaves Operational (Pause). RUN becomes HOLD, the motion
  output goes off; an Operational heartbeat brings it back (holds clear by themselves);
- ``estop``: an Operational heartbeat with the remote's e-stop bit (every K-th stop). RUN
  becomes STOPPED; a real re-arm follows: clear conditions for the re-arm hold (100 ms, the
  least the config allows), then the operator's takeover (safety-rules §4).

The latency runs from just before the VSC side writes the frame (so it includes the write) to
the moment the output's set-and-read-back returned in the supervisor's process. ``--model
poll50`` runs the same stops against a model of the public drivers' 20 ms polling loop;
``--model event`` against a bare event-driven loop, the floor of any Python loop here.

``--client-flood`` serves the client API on a socket and runs the same stops while a client
pipelines hold/release and every other request kind into it as fast as it can (issue 11,
``bench/rig.py``). Its holds would switch a motion output by themselves, so with the flood the
measured output is a power output (off only when STOPPED) and every stop is an e-stop with
its re-arm; compare it with the e-stop row of a quiet run. The user heartbeat's periods as
the VSC heard them are printed too (the VSC's key-85 watchdog trips at 500 ms).
"""

from __future__ import annotations

import argparse
import contextlib
import itertools
import random
import tempfile
import time
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path

from bench.rig import (
    MODELS,
    Edge,
    Rig,
    RigError,
    load,
    machine,
    ms,
    percentile,
    realtime,
    start_flood,
    table,
)
from supervisord.client import SupervisorClient
from supervisord.protocol.codes import VscMode
from supervisord.testkit.process import terminate

ESTOP_REMOTE = 0x01  # the remote's e-stop bit of the heartbeat's e-stop word (notes §2)
TARGET_P99_NS = 2_000_000  # safety-rules §9


@dataclass(frozen=True)
class Stop:
    """One measured stop: its kind, when its frame was written, and the output's off edge."""

    kind: str
    sent: int
    edge: Edge

    @property
    def latency(self) -> int:
        """Frame written to output off and read back (ns)."""
        return self.edge.finished - self.sent

    @property
    def to_write(self) -> int:
        """Frame written to the loop entering the output write (ns): decode and decision."""
        return self.edge.started - self.sent


def run(
    directory: Path,
    stops: int,
    estop_every: int,
    model: str = "supervisor",
    *,
    back_to_back: bool = False,
    mirror: bool = False,
    nice: int = 0,
    seed: int = 1,
    client_flood: bool = False,
    heartbeats: list[int] | None = None,
) -> list[Stop]:
    """Measure ``stops`` stops; every ``estop_every``-th is an e-stop (0: none).

    By default each stop waits until the supervisor is idle in RUN (its record of the re-arm
    written and fsynced), then 0-5 ms more, as a stop in service meets a loop that is not
    busy with an earlier change. ``back_to_back`` sends it 2-8 ms after the re-arm instead,
    to show what a stop costs when it lands while the loop is still writing a record. The
    polling model's stops wait 2-22 ms, a uniform phase against its 20 ms tick.
    """
    rng = random.Random(seed)
    measured: list[Stop] = []
    api_socket = directory / "api.sock" if client_flood else None
    if client_flood:
        estop_every = 1  # the flood's holds would be measured too: e-stops on a power output
    with contextlib.ExitStack() as stack:
        rig = stack.enter_context(
            Rig(
                directory,
                model=model,
                mirror=mirror,
                nice=nice,
                api_socket=api_socket,
                role="power" if client_flood else "motion",
            )
        )
        if api_socket is not None:
            flood = start_flood(api_socket)
            stack.callback(terminate, flood)
        _measure(
            rig,
            stops,
            estop_every,
            model=model,
            back_to_back=back_to_back,
            rng=rng,
            measured=measured,
        )
        if heartbeats is not None:
            heartbeats += rig.vsc.heartbeat_arrivals
        if api_socket is not None:
            with SupervisorClient.connect(api_socket) as client:
                daemon = client.status()["daemon"]
            alive = "still connected" if flood.poll() is None else f"ended ({flood.poll()})"
            print(
                f"flood: {alive}; {daemon['rate_limited']} requests refused by the record "
                f"budget, {daemon['record_errors']} record errors, "
                f"{daemon['internal_faults']} internal faults"
            )
    return measured


def _measure(
    rig: Rig,
    stops: int,
    estop_every: int,
    *,
    model: str,
    back_to_back: bool,
    rng: random.Random,
    measured: list[Stop],
) -> None:
    """The stops of ``run``, appended to ``measured``."""
    vsc = rig.vsc
    rig.arm()
    for index in range(stops):
        if model == "poll50":
            # The on edge happened at one of its ticks: a gap spread over a whole period
            # makes the stop's phase against the 20 ms tick uniform, as in service.
            vsc.pump_ms(rng.uniform(2, 22))
        elif back_to_back or model != "supervisor":
            vsc.pump_ms(rng.uniform(2, 8))
        else:
            rig.wait_idle()
            vsc.pump_ms(rng.uniform(0, 5))
        if not vsc.edges or not vsc.edges[-1].on:
            # something else stopped it meanwhile (or the flood's hold): only from RUN
            _back_on(rig)
        estop = estop_every > 0 and index % estop_every == estop_every - 1
        if estop:
            sent = vsc.set_state(VscMode.OPERATIONAL, ESTOP_REMOTE)
        else:
            sent = vsc.set_state(VscMode.PAUSE)
        edge = vsc.wait_edge(False, limit_ms=1000)
        if edge is None:
            raise RigError(f"stop {index}: the output did not go off within 1 s")
        measured.append(Stop("estop" if estop else "hold", sent, edge))
        if estop:
            rig.arm()
        else:
            vsc.set_state(VscMode.OPERATIONAL)
            if vsc.wait_edge(True, limit_ms=1000) is None:
                rig.arm()


def _back_on(rig: Rig) -> None:
    """Wait up to 100 ms for the output to come back on by itself (a flooding client's hold
    released), else re-arm."""
    vsc = rig.vsc
    if vsc.wait_edge(True, limit_ms=100) is None and (not vsc.edges or not vsc.edges[-1].on):
        rig.arm()


def summary_rows(measured: Sequence[Stop]) -> list[list[object]]:
    rows: list[list[object]] = []
    groups = [
        ("all stops", [s.latency for s in measured]),
        ("hold (mode leaves Operational)", [s.latency for s in measured if s.kind == "hold"]),
        ("e-stop (VSC e-stop word)", [s.latency for s in measured if s.kind == "estop"]),
        ("all: frame to output write begins", [s.to_write for s in measured]),
    ]
    for name, values in groups:
        if not values:
            continue
        rows.append(
            [
                name,
                len(values),
                ms(percentile(values, 0.5)),
                ms(percentile(values, 0.99)),
                ms(percentile(values, 0.999)),
                ms(max(values)),
                ms(sum(values) / len(values)),
            ]
        )
    return rows


def main(argv: Sequence[str] | None = None) -> None:
    parser = argparse.ArgumentParser(prog="bench.stop_latency", description=__doc__)
    parser.add_argument("--stops", type=int, default=None, help="default 10000 (poll50: 3000)")
    parser.add_argument("--estop-every", type=int, default=25, help="0: holds only")
    parser.add_argument("--model", choices=MODELS, default="supervisor")
    parser.add_argument(
        "--back-to-back",
        action="store_true",
        help="stop 2-8 ms after each re-arm, while its record may still be being written",
    )
    parser.add_argument(
        "--mirror", action="store_true", help="the sim output also rewrites its level file"
    )
    parser.add_argument(
        "--nice", type=int, default=0, help="of the supervisor; the service unit uses -5 (root)"
    )
    parser.add_argument(
        "--fifo", type=int, default=0, help="SCHED_FIFO priority of both sides (0: none; root)"
    )
    parser.add_argument("--seed", type=int, default=1)
    parser.add_argument(
        "--client-flood",
        action="store_true",
        help="a client pipelines requests of every kind into the API socket meanwhile",
    )
    args = parser.parse_args(argv)
    default_stops = 10_000 if args.model == "supervisor" else 3000
    stops = args.stops if args.stops is not None else default_stops
    print(f"machine: {machine()}")
    print(f"before: {load()}")
    started = time.monotonic()
    heartbeats: list[int] = []
    with tempfile.TemporaryDirectory(prefix="srcs-bench-") as directory, realtime(args.fifo):
        measured = run(
            Path(directory),
            stops,
            args.estop_every,
            args.model,
            back_to_back=args.back_to_back,
            mirror=args.mirror,
            nice=args.nice,
            seed=args.seed,
            client_flood=args.client_flood,
            heartbeats=heartbeats,
        )
    wall = time.monotonic() - started
    print(f"after: {load()}; {wall:.0f} s")
    what = {
        "supervisor": "the srcsd loop (Supervisor, serial link, safety core, fsynced record)",
        "poll50": "a 20 ms polling loop (model of the public drivers)",
        "event": "a bare event-driven loop (select, read, decode, set): the platform's floor",
    }[args.model]
    extras = [f"nice {args.nice}"]
    extras += [f"SCHED_FIFO {args.fifo}"] if args.fifo else []
    extras += ["back to back"] if args.back_to_back else []
    extras += ["a client flooding the API socket"] if args.client_flood else []
    print(f"model: {what}, {', '.join(extras)}")
    print("stop latency, last byte of the stopping frame written -> output off and read back (ms)")
    print()
    print(table(["stops", "n", "p50", "p99", "p99.9", "max", "mean"], summary_rows(measured)))
    periods = [b - a for a, b in itertools.pairwise(heartbeats)]
    if periods:
        print()
        print("user heartbeat period as the VSC heard it (ms; nominal 50, watchdog 500)")
        print()
        print(
            table(
                ["periods", "p50", "p99", "max"],
                [
                    [
                        len(periods),
                        ms(percentile(periods, 0.5)),
                        ms(percentile(periods, 0.99)),
                        ms(max(periods)),
                    ]
                ],
            )
        )
    p99 = percentile([s.latency for s in measured], 0.99)
    verdict = "PASS" if p99 < TARGET_P99_NS else "FAIL"
    print()
    print(f"safety-rules §9 target: p99 under 2 ms -> p99 {ms(p99)} ms: {verdict}")


if __name__ == "__main__":
    main()
