"""Stop latency: from the last byte of a stopping frame to the output off.

Run: ``.venv/bin/python -m bench.stop_latency [--stops N] [--blocks B] [--loaded]``.

By default one invocation measures the three loops side by side (docs/performance.md "Stop
latency"): srcsd's loop, the bare event-driven loop (the platform's floor) and the 50 Hz
polling model of the public drivers, interleaved in ``--blocks`` blocks of ``N / B`` stops
each, the order rotating from block to block, so that the three share the machine's state
(load, the host's steal, caches, frequency). It prints each loop's percentiles and the ratios
srcsd/bare and poll/srcsd, with the load average and the host's steal time over the run
(``/proc/stat``): on a virtual machine the absolute tails say more about the host than about
the supervisor, the ratios of one run do not. ``--model M`` measures one loop alone (``srcsd``
is ``supervisor``).
``--loaded`` starts two busy processes per core (unpinned) for the whole run, and runs every
loop under the service unit's own scheduling settings (``units/srcsd@.service``: its
``Nice=``, and ``CPUSchedulingPolicy=fifo`` with its priority if the unit sets it; as root).

The real supervisor loop runs in a child process against a pseudo-terminal VSC in this one
(``bench/rig.py``), under the VSC's full traffic (joystick 50 Hz, heartbeat 20 Hz, GPS 1 Hz).
Each stop starts in RUN, after a random 2-8 ms pause so that it lands at a random phase of the
traffic and of the supervisor's own heartbeat timer, and is one of:

- ``hold``: a heartbeat whose mode leaves Operational (Pause). RUN becomes HOLD, the motion
  output goes off; an Operational heartbeat brings it back (holds clear by themselves);
- ``estop``: an Operational heartbeat with the remote's e-stop bit (every K-th stop). RUN
  becomes STOPPED; a real re-arm follows: clear conditions for the re-arm hold (100 ms, the
  least the config allows), then the operator's takeover (SR-4).

The latency runs from just before the VSC side writes the frame (so it includes the write) to
the moment the output's set-and-read-back returned in the supervisor's process. ``--model
poll50`` runs the same stops against a model of the public drivers' 20 ms polling loop;
``--model event`` against a bare event-driven loop, the floor of any Python loop here.

``--client-flood`` serves the client API on a socket and runs the same stops while a client
pipelines hold/release and every other request kind into it as fast as it can (SR-10.1,
``bench/rig.py``). Its holds would switch a motion output by themselves, so with the flood the
measured output is a power output (off only when STOPPED) and every stop is an e-stop with
its re-arm; compare it with the e-stop row of a quiet run. The user heartbeat's periods as
the VSC heard them are printed too (the VSC's key-85 watchdog trips at 500 ms).
"""

from __future__ import annotations

import argparse
import contextlib
import itertools
import json
import os
import random
import subprocess
import sys
import tempfile
import time
from collections.abc import Iterator, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from bench.rig import (
    MODELS,
    REPO,
    TURNS_SUFFIX,
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
from bench.unit import Scheduling, read_unit, rttime_limit
from supervisord.client import SupervisorClient
from supervisord.protocol.codes import VscMode
from supervisord.tooling.children import terminate

ESTOP_REMOTE = 0x01  # the remote's e-stop bit of the heartbeat's e-stop word (PR-2)
TARGET_P99_NS = 2_000_000  # SR-9.1
# docs/performance.md "Targets", the loop's redesign: srcsd's median within 1.15 times the
# bare loop's, same run, quiet and loaded
TARGET_P50_RATIO = 1.15
TARGET_P99_RATIO = 1.3  # and its p99 within 1.3 times
SIDE_BY_SIDE = ("supervisor", "event", "poll50")
SLOW_DISK = "slowdisk"  # srcsd's loop with a record fsync 50 ms slower (``--slow-disk``)
SLOW_FSYNC_MS = 50.0
NAMES = {"supervisor": "srcsd", "event": "bare", "poll50": "poll50", SLOW_DISK: "srcsd-slow"}
SRCSD_LOOPS = ("supervisor", SLOW_DISK)
UNIT = REPO / "units" / "srcsd@.service"


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
    first: int = 0,
    notes: list[str] | None = None,
) -> list[Stop]:
    """Measure ``stops`` stops; every ``estop_every``-th is an e-stop (0: none), counting
    from stop number ``first`` (a block of a longer run continues its kinds' sequence).

    By default each stop waits until the supervisor is idle in RUN (its record of the re-arm
    written and fsynced), then 0-5 ms more, as a stop in service meets a loop that is not
    busy with an earlier change. ``back_to_back`` sends it 2-8 ms after the re-arm instead,
    to show what a stop costs when it lands while the loop is still writing a record. The
    polling model's stops wait 2-22 ms, a uniform phase against its 20 ms tick.
    """
    rng = random.Random(seed)
    measured: list[Stop] = []
    # Only srcsd serves the API; the other loops run the same e-stops on the same power
    # output, so that the ratios compare like with like.
    api_socket = directory / "api.sock" if client_flood and model == "supervisor" else None
    if client_flood:
        estop_every = 1  # the flood's holds would be measured too: e-stops on a power output
    with contextlib.ExitStack() as stack:
        rig = stack.enter_context(
            Rig(
                directory,
                model="supervisor" if model == SLOW_DISK else model,
                mirror=mirror,
                nice=nice,
                api_socket=api_socket,
                role="power" if client_flood else "motion",
                fsync_delay_ms=SLOW_FSYNC_MS if model == SLOW_DISK else 0,
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
            first=first,
        )
        if heartbeats is not None:
            heartbeats += rig.vsc.heartbeat_arrivals
        if model == SLOW_DISK:
            # Each change of the output is a change of state, so a record: how far the
            # record sink had got when the last stop was measured shows that the stops
            # met fsyncs in progress (and a queue behind them), not an idle disk.
            lines = (directory / "stops.jsonl").read_bytes().count(b"\n")
            note = (
                f"slow disk ({SLOW_FSYNC_MS:g} ms more per fsync): {lines} records on the "
                f"disk when the block's stops were done; the output changed "
                f"{len(rig.vsc.edges)} times (a record each)"
            )
            if notes is None:
                print(note)
            else:
                notes.append(note)
        if api_socket is not None:
            with SupervisorClient.connect(api_socket) as client:
                daemon = client.status().json()["daemon"]
            alive = "still connected" if flood.poll() is None else f"ended ({flood.poll()})"
            note = (
                f"flood: {alive}; {daemon['rate_limited']} requests refused by the record "
                f"budget, {daemon['record_errors']} record errors, "
                f"{daemon['internal_faults']} internal faults; srcsd's own user heartbeat "
                f"period at most {_worst_bucket_ms(daemon['histograms'])} ms (its histogram)"
            )
            if notes is None:
                print(note)
            else:
                notes.append(note)
    if api_socket is not None:  # the child has ended and written its turns
        turns = json.loads((directory / f"stops.jsonl{TURNS_SUFFIX}").read_text())
        note = (
            f"flood: srcsd's loop made {turns['turns']} turns, busy {turns['busy']:.0%} of the "
            f"time; its longest turn took {turns['max_wall_ms']:.1f} ms, its most CPU in one "
            f"turn {turns['max_cpu_ms']:.1f} ms"
        )
        if notes is None:
            print(note)
        else:
            notes.append(note)
    return measured


def _worst_bucket_ms(histograms: dict[str, Any]) -> str:
    """The upper bound of the highest non-empty bucket of srcsd's user-heartbeat periods, as
    the loop saw them when each write returned (docs/fleet.md "Timing histograms"): the
    daemon's side of a gap, to compare with the VSC's."""
    periods = histograms["user_heartbeat_period_seconds"]
    for le, cumulative in zip(periods["le"], periods["counts"], strict=True):
        if cumulative == periods["count"]:
            return f"{le * 1000:g}"
    return "inf"


def _measure(
    rig: Rig,
    stops: int,
    estop_every: int,
    *,
    model: str,
    back_to_back: bool,
    rng: random.Random,
    measured: list[Stop],
    first: int = 0,
) -> None:
    """The stops of ``run``, appended to ``measured``."""
    vsc = rig.vsc
    rig.arm()
    for index in range(first, first + stops):
        if model == "poll50":
            # The on edge happened at one of its ticks: a gap spread over a whole period
            # makes the stop's phase against the 20 ms tick uniform, as in service.
            vsc.pump_ms(rng.uniform(2, 22))
        elif back_to_back or model not in SRCSD_LOOPS:
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


def side_by_side(
    directory: Path,
    stops: int,
    estop_every: int,
    *,
    blocks: int = 10,
    models: Sequence[str] = SIDE_BY_SIDE,
    back_to_back: bool = False,
    mirror: bool = False,
    nice: int = 0,
    seed: int = 1,
    client_flood: bool = False,
    periods: list[int] | None = None,
    notes: list[str] | None = None,
) -> dict[str, list[Stop]]:
    """``stops`` stops of each of ``models``, in ``blocks`` blocks: block ``b`` runs every
    model once, in the order rotated by ``b``, each on a fresh rig in its own directory (an
    idle rig would see the VSC fall silent while another block runs). srcsd's user heartbeat
    periods as the VSC heard them, within each block, are added to ``periods``."""
    measured: dict[str, list[Stop]] = {model: [] for model in models}
    blocks = max(1, min(blocks, stops))
    for block in range(blocks):
        size = stops // blocks + (1 if block < stops % blocks else 0)
        order = [models[(block + k) % len(models)] for k in range(len(models))]
        for model in order:
            where = directory / f"{NAMES.get(model, model)}-{block}"
            where.mkdir()
            arrivals: list[int] = []
            measured[model] += run(
                where,
                size,
                estop_every,
                model,
                back_to_back=back_to_back,
                mirror=mirror,
                nice=nice,
                seed=seed * 1000 + block,
                client_flood=client_flood,
                heartbeats=arrivals,
                first=len(measured[model]),
                notes=notes,
            )
            if periods is not None and model == "supervisor":
                periods += [b - a for a, b in itertools.pairwise(arrivals)]
    return measured


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


def ratio_rows(measured: dict[str, list[Stop]]) -> list[list[object]]:
    """srcsd/bare (the supervisor's own cost over the platform's floor) and poll/srcsd (how
    much sooner than the public drivers' design), at p50, p99 and max, from one run."""
    rows: list[list[object]] = []
    pairs = [
        ("srcsd / bare", "supervisor", "event"),
        ("poll50 / srcsd", "poll50", "supervisor"),
        ("srcsd slow disk / srcsd", SLOW_DISK, "supervisor"),
    ]
    for name, top, bottom in pairs:
        if not measured.get(top) or not measured.get(bottom):
            continue
        a = [s.latency for s in measured[top]]
        b = [s.latency for s in measured[bottom]]
        rows.append(
            [
                name,
                f"{percentile(a, 0.5) / percentile(b, 0.5):.2f}",
                f"{percentile(a, 0.99) / percentile(b, 0.99):.2f}",
                f"{max(a) / max(b):.2f}",
            ]
        )
    return rows


@dataclass(frozen=True)
class CpuTimes:
    """The machine's CPU time so far (``/proc/stat``, first line, in clock ticks)."""

    total: int
    steal: int

    @classmethod
    def read(cls) -> CpuTimes:
        try:
            fields = Path("/proc/stat").read_text().splitlines()[0].split()
        except (OSError, IndexError):
            return cls(0, 0)
        # user nice system idle iowait irq softirq steal guest guest_nice; guest time is
        # already counted in user and nice.
        values = [int(v) for v in fields[1:9]]
        return cls(sum(values), values[7] if len(values) > 7 else 0)


def steal_share(before: CpuTimes, after: CpuTimes) -> float | None:
    """The share of all CPU time the host took from this machine between the two readings
    (``None`` where ``/proc/stat`` is unreadable)."""
    total = after.total - before.total
    return (after.steal - before.steal) / total if total > 0 else None


def steal_text(before: CpuTimes) -> str:
    """The host's steal time since ``before``, as every timing bench prints it with the load
    (on a virtual machine the host takes CPU time the guest cannot see otherwise)."""
    steal = steal_share(before, CpuTimes.read())
    share = f"{steal * 100:.1f} %" if steal is not None else "unknown"
    return f"host steal during the run: {share} of CPU time"


def unit_scheduling(unit: Path = UNIT) -> tuple[int, int]:
    """The service unit's ``Nice=`` and SCHED_FIFO priority (0 unless it sets
    ``CPUSchedulingPolicy=fifo``), so that ``--loaded`` runs the loops as the unit would."""
    scheduling = read_unit(unit)
    return scheduling.nice, scheduling.priority


@contextlib.contextmanager
def busy(per_core: int) -> Iterator[int]:
    """``per_core`` busy processes per core, unpinned, for the duration (``--loaded``).
    Started before any real-time policy is set, so they never inherit it."""
    count = per_core * (os.cpu_count() or 1)
    spinners = [
        # Our own interpreter with a fixed program: no input reaches the command.
        subprocess.Popen([sys.executable, "-c", "while True: pass"])
        for _ in range(count)
    ]
    try:
        yield count
    finally:
        for spinner in spinners:
            terminate(spinner)


def _parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(prog="bench.stop_latency", description=__doc__)
    parser.add_argument(
        "--stops", type=int, default=1000, help="per loop (default 1000), spread over the blocks"
    )
    parser.add_argument("--blocks", type=int, default=10, help="blocks of the side-by-side run")
    parser.add_argument("--estop-every", type=int, default=25, help="0: holds only")
    parser.add_argument(
        "--model",
        choices=("all", "srcsd", *MODELS),
        default="all",
        help="all (default): the three loops side by side; or one alone",
    )
    parser.add_argument(
        "--loaded",
        action="store_true",
        help="two busy processes per core meanwhile; the unit's scheduling settings",
    )
    parser.add_argument(
        "--back-to-back",
        action="store_true",
        help="stop 2-8 ms after each re-arm, while its record may still be being written",
    )
    parser.add_argument(
        "--mirror", action="store_true", help="the sim output also rewrites its level file"
    )
    parser.add_argument(
        "--nice", type=int, default=None, help="of the loops; the service unit's with --loaded"
    )
    parser.add_argument(
        "--fifo", type=int, default=None, help="SCHED_FIFO priority of both sides (0: none; root)"
    )
    parser.add_argument("--seed", type=int, default=1)
    parser.add_argument(
        "--slow-disk",
        action="store_true",
        help=f"also srcsd with every record fsync {SLOW_FSYNC_MS:g} ms slower, side by side",
    )
    parser.add_argument(
        "--client-flood",
        action="store_true",
        help="a client pipelines requests of every kind into srcsd's API socket meanwhile",
    )
    return parser


def main(argv: Sequence[str] | None = None) -> None:
    args = _parser().parse_args(argv)
    model = "supervisor" if args.model == "srcsd" else args.model
    models: tuple[str, ...] = SIDE_BY_SIDE if model == "all" else (model,)
    if args.slow_disk:
        models = (*models, SLOW_DISK) if "supervisor" in models else (SLOW_DISK, *models)
    unit = read_unit(UNIT) if args.loaded else Scheduling()
    nice = args.nice if args.nice is not None else unit.nice
    fifo = args.fifo if args.fifo is not None else unit.priority
    # The unit's RLIMIT_RTTIME too, with its FIFO policy: a loop that ran too long without
    # blocking would die here as under systemd (the bench then fails: "did it die?").
    limit = unit if fifo and args.fifo is None else Scheduling()
    print(f"machine: {machine()}")
    print(f"before: {load()}")
    started = time.monotonic()
    periods: list[int] = []
    notes: list[str] = []
    with contextlib.ExitStack() as stack:
        spinners = stack.enter_context(busy(2)) if args.loaded else 0
        directory = Path(stack.enter_context(tempfile.TemporaryDirectory(prefix="srcs-bench-")))
        cpu_before = CpuTimes.read()
        with rttime_limit(limit), realtime(fifo):
            measured = side_by_side(
                directory,
                args.stops,
                args.estop_every,
                blocks=args.blocks if len(models) > 1 else 1,
                models=models,
                back_to_back=args.back_to_back,
                mirror=args.mirror,
                nice=nice,
                seed=args.seed,
                client_flood=args.client_flood,
                periods=periods,
                notes=notes,
            )
        cpu_after = CpuTimes.read()
    wall = time.monotonic() - started
    steal = steal_share(cpu_before, cpu_after)
    steal_text = f"{steal * 100:.1f} %" if steal is not None else "unknown"
    print(f"after: {load()}; {wall:.0f} s; host steal during the run: {steal_text} of CPU time")
    extras = [f"nice {nice}"]
    extras += [f"SCHED_FIFO {fifo}"] if fifo else []
    if limit.soft_us is not None:
        extras += [f"RLIMIT_RTTIME soft {limit.soft_us / 1e6:g} s (the unit's)"]
    extras += [f"loaded: {spinners} busy processes, unpinned"] if spinners else ["quiet"]
    extras += ["back to back"] if args.back_to_back else []
    extras += ["a client flooding srcsd's API socket"] if args.client_flood else []
    blocks = min(args.blocks, args.stops) if len(models) > 1 else 1
    print(
        f"conditions: {', '.join(extras)}; {args.stops} stops per loop in {blocks} "
        "interleaved block(s)"
    )
    for note in notes:
        print(note)
    report(measured, models, periods)


def report(measured: dict[str, list[Stop]], models: Sequence[str], periods: list[int]) -> None:
    """Each loop's table, the ratios of the run, srcsd's heartbeat periods, the verdicts."""
    print("stop latency, last byte of the stopping frame written -> output off and read back (ms)")
    what = {
        "supervisor": "srcsd: the srcsd loop (Supervisor, serial link, safety core, record)",
        "event": "bare: a bare event-driven loop (select, read, decode, set), the platform's floor",
        "poll50": "poll50: a 20 ms polling loop (model of the public drivers)",
        SLOW_DISK: f"srcsd-slow: the srcsd loop, every record fsync {SLOW_FSYNC_MS:g} ms slower",
    }
    for name in models:
        print()
        print(what[name])
        print()
        print(
            table(
                ["stops", "n", "p50", "p99", "p99.9", "max", "mean"], summary_rows(measured[name])
            )
        )
    ratios = ratio_rows(measured)
    if ratios:
        print()
        print("ratios of the same run (latency of the first loop / of the second)")
        print()
        print(table(["ratio", "p50", "p99", "max"], ratios))
    if periods:
        print()
        print("srcsd's user heartbeat period as the VSC heard it (ms; nominal 50, watchdog 500)")
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
    print()
    if "supervisor" in measured and "event" in measured:
        own = [s.latency for s in measured["supervisor"]]
        floor = [s.latency for s in measured["event"]]
        for share, target in ((0.5, TARGET_P50_RATIO), (0.99, TARGET_P99_RATIO)):
            value = percentile(own, share) / percentile(floor, share)
            verdict = "PASS" if value <= target else "FAIL"
            print(
                f"side-by-side target: srcsd p{share * 100:g} within {target} x bare -> "
                f"{value:.2f}: {verdict}"
            )
    headline = "supervisor" if "supervisor" in measured else models[0]
    p99 = percentile([s.latency for s in measured[headline]], 0.99)
    verdict = "PASS" if p99 < TARGET_P99_NS else "FAIL"
    print(f"SR-9 target: p99 under 2 ms ({NAMES[headline]}) -> p99 {ms(p99)} ms: {verdict}")


if __name__ == "__main__":
    main()
