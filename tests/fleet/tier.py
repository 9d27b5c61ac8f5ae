"""The fleet tier (docs/fleet.md "The fleet tier"): five robots and a collector on systemd's
and Prometheus's own engines, in one network namespace of the tier's own (loopback only).

Run by ``tests/fleet/run`` as the first process of new mount, network and PID namespaces:
everything it mounts and starts ends with it. Scenarios, one line each:

- ``stop_at_collector`` (SR-13.1): a remote e-stop on every robot is at the collector within
  seconds, with ``SRCS_KIND``, ``SRCS_SEQ``, ``SRCS_CAUSE``, ``MESSAGE_ID`` and the robot's
  ``_HOSTNAME``;
- ``collector_outage`` (SR-13.1): journal-remote killed for a minute while robots stop three
  times each; once it is back every robot's records are there, none twice, ``SRCS_SEQ``
  without a gap, the same as the robot's own record file;
- ``robot_down_alert`` (SR-13.2): every process of one robot killed, during the outage;
  ``SrcsExporterDown`` from the shipped rules reaches Alertmanager with its ``robot`` label;
- ``skewed_clocks`` (SR-13.3): a robot 7 minutes behind and one 5 minutes ahead (libfaketime
  on all their processes, journald included) keep their own order at the collector;
- ``alert_at_receiver`` (SR-13.10): the first scenario's stops reach the team's receiver (a
  webhook) as ``SrcsStopped`` through the shipped rules and Alertmanager routes;
- ``windows_at_collector`` (SR-13.12): every stop's flight recorder window of the robots that
  are up is at the collector, and the collector package's installed ``srcsctl fleet replay`` of
  each says what the robot's own ``srcsctl replay`` says, matching its record; its ``--plot``
  draws the stop and its ``--mcap`` writes the MCAP file (``tests/fleet/windows.py``).

- the acknowledged fleet stop's scenarios, ``fleet_*`` (SR-8.19 to SR-8.21, SR-13.13 to
  SR-13.15): each robot's packaged agent, a real mosquitto with mutual TLS and the ACL, the
  package's console (``tests/fleet/fleet_stop.py``).

``SRCS_FLEET_SCENARIOS=fleet_stop`` runs only the fleet stop's (a development run).

The collector is the collector's package installed unchanged (tests/fleet/collector.py); the
robots upload only srcsd's journal namespace (SR-13.11, tests/fleet/robot). Figures (not
checks): a stop to its alert at the webhook, and to ``srcsctl fleet``'s answer, p50 and p95.

usage: python3 -m tests.fleet.tier --deb DEB --collector-deb DEB --work DIR [--started EPOCH]
Last line: "N passed, N failed"; the exit status is 1 when any failed.
"""

from __future__ import annotations

import argparse
import functools
import math
import os
import signal
import statistics
import subprocess
import sys
import threading
import time
from collections.abc import Callable
from pathlib import Path
from typing import Any

from tests.fleet import broker as fleet_net
from tests.fleet import pki
from tests.fleet.broker import Broker
from tests.fleet.collector import Collector, by_robot, fleet_answer, held, raw_copies
from tests.fleet.fleet_stop import Fleet
from tests.fleet.fleet_stop import scenarios as fleet_stop_scenarios
from tests.fleet.robots import Robot, make_layer, poll
from tests.fleet.windows import windows_at_collector

STOP_MESSAGE_ID = "26c2f33dae3d4a6c8996fc9bc658ad32"
"""A change of state's MESSAGE_ID (docs/record.md "The systemd journal")."""
MESSAGE_IDS = {"state_change": STOP_MESSAGE_ID, "cause_raised": "820501387c1a46049b855bcae8bc9ba2"}
SKEWS = {3: "-7m", 4: "+5m"}
"""Robots whose wall clock is off (SR-13.3), and by how much (libfaketime's notation)."""
SKEW_SECONDS = {"-7m": -420.0, "+5m": 300.0}
ROBOTS = 5
DOWN_ROBOT = 5
"""The robot taken down for the alert (SR-13.2)."""
OUTAGE_S = 60.0
STOPS_DURING_OUTAGE = 3
AT_COLLECTOR_LIMIT_S = 10.0
"""SR-13.1's "within seconds": one upload round trip plus journalctl's read, on a busy
two-core machine."""

TALLY = {"passed": 0, "failed": 0}
"""The scenarios' verdicts so far."""


def say(line: str) -> None:
    print(f"fleet: {line}", flush=True)


def result(name: str, ok: bool, detail: str) -> None:
    TALLY["passed" if ok else "failed"] += 1
    say(f"{'PASS' if ok else 'FAIL'} {name}: {detail}")


def in_parallel(jobs: dict[str, Callable[[], Any]]) -> dict[str, Any]:
    """Run each job in a thread of its own; each one's return value (or its exception)."""
    answers: dict[str, Any] = {}

    def run(name: str, job: Callable[[], Any]) -> None:
        try:
            answers[name] = job()
        except Exception as error:  # reported as the job's answer, judged by the caller
            answers[name] = error

    threads = [threading.Thread(target=run, args=item, daemon=True) for item in jobs.items()]
    for thread in threads:
        thread.start()
    for thread in threads:
        thread.join()
    return answers


def seqs(entries: list[dict[str, Any]]) -> list[int]:
    """``SRCS_SEQ`` of journal entries, or ``seq`` of the fleet's answer's records."""
    return [
        int(entry["SRCS_SEQ"] if "SRCS_SEQ" in entry else entry["seq"])
        for entry in entries
        if "SRCS_SEQ" in entry or "seq" in entry
    ]


def causes(entry: dict[str, Any]) -> list[str]:
    value = entry.get("SRCS_CAUSE", [])
    return [value] if isinstance(value, str) else list(value)


def is_estop_stop(entry: dict[str, Any]) -> bool:
    return (
        entry.get("SRCS_KIND") == "state_change"
        and str(entry.get("SRCS_TO", "")).upper() == "STOPPED"
        and "vsc_estop" in causes(entry)
    )


def stop_at_collector(collector: Collector, robots: list[Robot]) -> dict[str, float]:
    """SR-13.1: one remote e-stop per robot, at once; the seconds from each press to its
    record at the collector, with its fields. Returns each robot's wall-clock press time."""
    pressed_mono: dict[str, float] = {}
    pressed_wall: dict[str, float] = {}
    before = {robot.name: len(robot.own_records()) for robot in robots}

    def press(robot: Robot) -> float | None:
        pressed_wall[robot.name] = time.time()
        pressed_mono[robot.name] = time.monotonic()
        return robot.estop(10)

    offs = in_parallel({robot.name: functools.partial(press, robot) for robot in robots})
    seen: dict[str, float] = {}
    wrong: list[str] = []

    def arrived() -> bool:
        holding = by_robot(held(collector.journal))
        for robot in robots:
            if robot.name in seen:
                continue
            # The record of this press: a stop, or a cause raised when something else (a
            # loop woken late on the busy machine, SR-9) had stopped the robot already.
            pressed = [
                r
                for r in robot.own_records()[before[robot.name] :]
                if any(c.get("name") == "vsc_estop" for c in r.get("causes", []))
            ]
            if not pressed:
                continue
            record = pressed[0]
            for entry in holding.get(robot.name, []):
                if entry.get("SRCS_SEQ") == str(record["seq"]):
                    seen[robot.name] = time.monotonic() - pressed_mono[robot.name]
                    kind = record.get("kind", "state_change")
                    if not (
                        entry.get("SRCS_KIND") == kind
                        and "vsc_estop" in causes(entry)
                        and entry.get("MESSAGE_ID") == MESSAGE_IDS.get(kind)
                        and entry.get("_HOSTNAME") == robot.name
                    ):
                        wrong.append(f"{robot.name}: {entry}")
        return all(robot.name in seen for robot in robots if not robot.skew)

    poll(arrived, 60, step=0.2)
    delays = sorted(seen.values())
    # "Within seconds" is judged on the robots whose clocks are true. The uploader of a robot
    # whose journald runs under libfaketime notices its new entries late or not until it is
    # started again (docs/fleet.md "The fleet tier"): a fault of the test's clock, not of the
    # path. Their stops are shown if they came, and checked at the collector in skewed_clocks,
    # after the outage has started every uploader again.
    true_clock = [robot for robot in robots if not robot.skew]
    ok = (
        all(robot.name in seen for robot in true_clock)
        and not wrong
        and all(isinstance(off, float) for off in offs.values())
        and max(seen[r.name] for r in true_clock) <= AT_COLLECTOR_LIMIT_S
    )
    detail = (
        f"{len(seen)}/{len(robots)} stops at the collector with SRCS_KIND, SRCS_SEQ, SRCS_CAUSE,"
        f" MESSAGE_ID, _HOSTNAME; press to collector "
        + (
            f"median {statistics.median(delays):.2f} s, max {max(delays):.2f} s"
            if delays
            else "none"
        )
        + f" (limit {AT_COLLECTOR_LIMIT_S:.0f} s on a true clock): "
        + ", ".join(f"{name} {delay:.2f} s" for name, delay in sorted(seen.items()))
    )
    if wrong:
        detail += f"; wrong fields: {wrong[:2]}"
    missing = [robot.name for robot in robots if robot.name not in seen]
    if missing:
        detail += f"; not yet at the collector: {missing}"
    result("stop_at_collector", ok, detail)
    for robot in robots:  # what a late robot's uploader did meanwhile, from its timed log
        if not robot.skew and seen.get(robot.name, AT_COLLECTOR_LIMIT_S + 1) > AT_COLLECTOR_LIMIT_S:
            upload_log = (robot.run / "fleet/upload.log").read_text(errors="replace")
            say(f"{robot.name} upload.log, its end: {upload_log[-6000:]}")
    return pressed_wall


def robot_down_alert(collector: Collector, robot: Robot, killed: float) -> None:
    """SR-13.2: the robot's every process killed at ``killed`` (monotonic);
    SrcsExporterDown with its robot label at Alertmanager, and no other robot named."""

    def firing() -> list[dict[str, Any]]:
        return [
            alert
            for alert in collector.alerts()
            if alert.get("status", {}).get("state") == "active"
            and alert["labels"].get("alertname") in ("SrcsExporterDown", "SrcsSupervisorDown")
        ]

    # The rule's for: 2m, the shipped prometheus.yml's 15 s scrapes and evaluations, and the
    # scrape timeout.
    took = poll(
        lambda: any(a["labels"].get("robot") == robot.name for a in firing()),
        180 - (time.monotonic() - killed),
        step=1.0,
    )
    after = time.monotonic() - killed
    try:
        alerts = firing()
    except OSError as error:
        alerts = []
        result("robot_down_alert", False, f"Alertmanager: {error}")
        return
    named = sorted({f"{a['labels'].get('alertname')}{{robot={a['labels'].get('robot')}}}"
                    for a in alerts})  # fmt: skip
    ok = took is not None and all(a["labels"].get("robot") == robot.name for a in alerts)
    result(
        "robot_down_alert",
        ok,
        f"{robot.name} killed; at Alertmanager {after:.0f} s later: {', '.join(named) or 'nothing'}"
        " (SrcsExporterDown's for: 2m)",
    )


def outage(collector: Collector, robots: list[Robot], down: Robot) -> None:
    """SR-13.1, SR-13.2: the collector killed for a minute while the robots stop, and one
    robot killed at the same time for its alert."""
    up_robots = [robot for robot in robots if robot is not down]
    # The robot to be killed first uploads what it wrote (a few seconds at most): a record its
    # uploader never got to send dies with it, which no collector can show, and the scenario
    # asks whether what was sent is all there after the outage, not whether a kill waits.
    own = {int(x["seq"]) for x in down.own_records()}
    poll(lambda: set(seqs(by_robot(held(collector.journal)).get(down.name, []))) >= own, 60)
    killed = time.monotonic()
    down.kill()
    collector.kill_journal_remote()
    alert = threading.Thread(target=robot_down_alert, args=(collector, down, killed))
    alert.start()

    def stops(robot: Robot) -> int:
        made = 0
        for _ in range(STOPS_DURING_OUTAGE):
            if robot.take_over(30) and robot.estop(10) is not None:
                made += 1
        return made

    made = in_parallel({robot.name: functools.partial(stops, robot) for robot in up_robots})
    rest = OUTAGE_S - (time.monotonic() - killed)
    if rest > 0:
        time.sleep(rest)  # the outage's length is the scenario itself, not a wait for timing
    count_before = len(held(collector.journal))
    collector.start_journal_remote()
    back = time.monotonic()

    def caught_up() -> bool:
        holding = by_robot(held(collector.journal))
        return all(
            set(seqs(holding.get(r.name, []))) >= {int(x["seq"]) for x in r.own_records()}
            for r in robots
        )

    took = poll(caught_up, 90, step=0.2)
    raw = held(collector.journal)
    count_after = len(raw)
    copies = raw_copies(raw)
    # "None twice" is the fleet's answer (SR-13.1): srcsctl fleet holds each record once,
    # while the collector's journal keeps what journal-upload sent again as it got it.
    holding = by_robot(fleet_answer(collector), key="robot")
    problems: list[str] = []
    per_robot: list[str] = []
    for robot in robots:
        own_file = [int(record["seq"]) for record in robot.own_records()]
        own_journal = seqs(robot.own_journal())
        there = seqs(holding.get(robot.name, []))
        if len(there) != len(set(there)):
            problems.append(
                f"{robot.name} twice: {sorted(s for s in set(there) if there.count(s) > 1)}"
            )
        if sorted(set(there)) != list(range(min(there, default=1), max(there, default=0) + 1)):
            problems.append(f"{robot.name} gap: {sorted(set(there))}")
        if set(there) != set(own_file) or set(there) != set(own_journal):
            problems.append(
                f"{robot.name}: collector {sorted(set(there))}, file {own_file},"
                f" journal {own_journal}"
            )
        per_robot.append(f"{robot.name} {len(there)}")
    stops_made = sum(v for v in made.values() if isinstance(v, int))
    wanted = STOPS_DURING_OUTAGE * len(up_robots)
    if stops_made != wanted:
        problems.append(f"{stops_made} of {wanted} stops made: {made}")
    if took is None:
        problems.append("not caught up within 90 s")
    catch_up = (
        f"caught up {took:.1f} s after the restart, {count_after - count_before} records,"
        f" {(count_after - count_before) / took:.1f} records/s"
        if took
        else "not caught up"
    )
    result(
        "collector_outage",
        not problems,
        f"journal-remote down {back - killed:.0f} s, {stops_made} stops meanwhile; {catch_up};"
        f" records per robot in srcsctl fleet's answer, none twice, no gap, as in its own file"
        f" and journal: {', '.join(per_robot)}; the collector's journal held {copies}"
        " copies journal-upload sent again" + (f"; {'; '.join(problems)}" if problems else ""),
    )
    alert.join()


def skewed_clocks(collector: Collector, robots: list[Robot], pressed: dict[str, float]) -> None:
    """SR-13.3: the skewed robots' records in their own order at the collector, and their
    clocks off by what libfaketime says (measured on the first scenario's stop)."""
    holding = by_robot(held(collector.journal))
    answer = by_robot(fleet_answer(collector), key="robot")
    problems: list[str] = []
    seen: list[str] = []
    for robot in robots:
        entries = holding.get(robot.name, [])
        order = seqs(answer.get(robot.name, []))
        if order != sorted(order) or not order:
            problems.append(f"{robot.name} out of order: {order}")
        if not robot.skew:
            continue
        first_stop = next((e for e in entries if is_estop_stop(e)), None)
        if first_stop is None:
            problems.append(f"{robot.name}: no stop")
            continue
        offset = int(first_stop["__REALTIME_TIMESTAMP"]) / 1e6 - pressed[robot.name]
        seen.append(f"{robot.name} {offset:+.0f} s")
        if abs(offset - SKEW_SECONDS[robot.skew]) > 30:
            problems.append(f"{robot.name}: clock {offset:+.0f} s, not {robot.skew}")
    result(
        "skewed_clocks",
        not problems,
        f"clocks at the collector {', '.join(seen)}; every robot's seq ascending in"
        f" srcsctl fleet's answer" + (f"; {'; '.join(problems)}" if problems else ""),
    )


def percentile(values: list[float], share: float) -> float:
    """The nearest-rank percentile: the smallest value with ``share`` of them at or below."""
    ordered = sorted(values)
    return ordered[max(0, math.ceil(share * len(ordered)) - 1)]


def spread(delays: dict[str, float]) -> str:
    if not delays:
        return "none"
    values = list(delays.values())
    each = ", ".join(f"{name} {delay:.1f} s" for name, delay in sorted(delays.items()))
    return (
        f"p50 {percentile(values, 0.5):.1f} s, p95 {percentile(values, 0.95):.1f} s"
        f" over {len(values)} stops ({each})"
    )


def answer_times(
    collector: Collector, robots: list[Robot], before: dict[str, int]
) -> dict[str, float]:
    """The wall-clock time at which each robot's first e-stop after ``before`` was first in
    ``srcsctl fleet``'s answer (the installed command, as a user would run it, again and
    again), for the robots whose clocks are true (a skewed robot's upload is late by the
    fake clock's doing, docs/fleet.md "The fleet tier")."""
    seen: dict[str, float] = {}
    wanted = [robot for robot in robots if not robot.skew]
    limit = time.monotonic() + 60
    while time.monotonic() < limit and len(seen) < len(wanted):
        try:
            answer = by_robot(fleet_answer(collector), key="robot")
        except (OSError, ValueError, subprocess.TimeoutExpired):
            answer = {}
        now = time.time()
        for robot in wanted:
            pressed = [
                r
                for r in robot.own_records()[before[robot.name] :]
                if any(c.get("name") == "vsc_estop" for c in r.get("causes", []))
            ]
            if robot.name in seen or not pressed:
                continue
            if pressed[0]["seq"] in seqs(answer.get(robot.name, [])):
                seen[robot.name] = now
        time.sleep(0.2)
    return seen


def alert_at_receiver(
    collector: Collector, pressed: dict[str, float], answered: dict[str, float]
) -> None:
    """SR-13.10: each robot's stop of ``stop_at_collector`` as ``SrcsStopped`` at the team's
    webhook through the shipped rules and routes (a robot killed before a scrape saw its stop
    is left out: robot-5 goes down at the start of the outage). Figures: press to the alert
    at the webhook and to srcsctl fleet's answer."""
    assert collector.webhook is not None
    arrived = collector.webhook.first_firing("SrcsStopped")
    to_alert = {name: arrived[name] - pressed[name] for name in pressed if name in arrived}
    to_answer = {name: at - pressed[name] for name, at in answered.items()}
    say(f"figure: stop to its alert at the webhook: {spread(to_alert)}")
    say(f"figure: stop to srcsctl fleet's answer: {spread(to_answer)}")
    others = [name for name in arrived if name not in pressed]
    result(
        "alert_at_receiver",
        len(to_alert) >= len(pressed) - 1 and not others,
        f"SrcsStopped at the webhook for {sorted(to_alert)} of {sorted(pressed)}"
        + (f"; for robots that did not stop: {others}" if others else ""),
    )


def figures(collector: Collector) -> None:
    say(f"figure: journal-remote CPU {collector.journal_remote_cpu_now():.2f} s in all")
    for name, size in collector.bytes_per_file().items():
        say(f"figure: {name} {size / 1024:.0f} KiB")


def logs(collector: Collector, robots: list[Robot]) -> None:
    """The ends of the logs, for a failed run."""
    for path in sorted((collector.work / "collector").glob("*.log")):
        say(f"{path.name}: {path.read_text(errors='replace')[-1500:]}")
    for robot in robots:
        for name in ("srcsd.log", "journald.log", "upload.log"):
            path = robot.run / "fleet" / name
            if path.exists():
                say(f"{robot.name} {name}: {path.read_text(errors='replace')[-800:]}")


def keep_for_a_look(work: Path, collector: Collector, robots: list[Robot]) -> None:
    """SRCS_FLEET_KEEP=DIR: the collector's logs and journal and each robot's /run and /var,
    copied there for a look afterwards."""
    keep = os.environ.get("SRCS_FLEET_KEEP")
    if not keep:
        return
    subprocess.run(["rm", "-rf", keep], check=False)
    # The collector's logs and journal; not its root, which is this machine's / too.
    subprocess.run(["mkdir", "-p", keep], check=False)
    for path in [*collector.base.glob("*.log"), collector.journal]:
        subprocess.run(["cp", "-a", str(path), keep], check=False)
    for robot in robots:
        subprocess.run(["cp", "-a", str(robot.run), f"{keep}/{robot.name}"], check=False)
        subprocess.run(
            ["cp", "-a", str(robot.dir / "upper/var"), f"{keep}/{robot.name}-var"], check=False
        )


def stop_on_signal(number: int, _frame: object) -> None:
    raise SystemExit(128 + number)


def certificates(collector: Collector, layer: Path, robots: list[Robot]) -> None:
    collector.mount(layer)
    pki.make(collector, [robot.name for robot in robots])


def ready_to_run(robot: Robot) -> bool:
    """The robot's parts are up and it is in RUN."""
    return robot.up(90) and robot.take_over(90)


def main() -> int:  # noqa: PLR0912 - the tier's one sequence, its setup's checks
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--deb", type=Path, required=True)
    parser.add_argument("--collector-deb", type=Path, required=True)
    parser.add_argument("--work", type=Path, required=True)
    parser.add_argument("--started", type=float, default=time.time())
    args = parser.parse_args()
    if os.getpid() != 1:
        say("run through tests/fleet/run: the tier needs namespaces of its own")
        return 2
    # The first process of a PID namespace ignores a signal it has no handler for: a SIGTERM
    # sent to this process ends the tier through its cleanup below. (A SIGTERM to
    # tests/fleet/run's unshare is not passed on: SIGKILL it, and --kill-child ends all.)
    signal.signal(signal.SIGTERM, stop_on_signal)
    work: Path = args.work
    # The fleet's network: this namespace's loopback, nothing else.
    subprocess.run(["ip", "link", "set", "lo", "up"], check=True)
    # Each robot's journal-upload (uid 61000+N, tests/fleet/robot) connects from the robot's
    # own address, as it would from its own machine: the local table moves behind one rule
    # per robot, whose table gives loopback the robot's address as source.
    subprocess.run(["ip", "rule", "add", "pref", "1000", "lookup", "local"], check=True)
    subprocess.run(["ip", "rule", "del", "pref", "0"], check=True)
    for n in range(1, ROBOTS + 1):
        uid, table = str(61000 + n), str(100 + n)
        subprocess.run(
            ["ip", "rule", "add", "pref", "100", "uidrange", f"{uid}-{uid}", "lookup", table],
            check=True,
        )
        subprocess.run(
            ["ip", "route", "add", "local", "127.0.0.0/8", "dev", "lo", "src", f"127.0.1.{n}",
             "table", table],
            check=True,
        )  # fmt: skip
    # This PID namespace's /proc: the processes' CPU seconds are read by their pids.
    subprocess.run(["mount", "-t", "proc", "proc", "/proc"], check=True)
    work.mkdir(parents=True, exist_ok=True)
    # A tmpfs of this mount namespace: the overlays' upper layers may not live on the
    # filesystem of their lower layer, this machine's /.
    subprocess.run(["mount", "-t", "tmpfs", "-o", "mode=0755", "fleet", str(work)], check=True)
    robots = [Robot(n, work, SKEWS.get(n, "")) for n in range(1, ROBOTS + 1)]
    collector = Collector(work, {r.name: f"{r.address}:9817" for r in robots})
    broker = Broker(work)
    only_fleet_stop = os.environ.get("SRCS_FLEET_SCENARIOS") == "fleet_stop"
    t0 = time.monotonic()
    fleet: Fleet | None = None
    try:
        made = in_parallel(
            {
                "layer": lambda: make_layer(work, args.deb),
                "collector-layer": lambda: make_layer(work, args.collector_deb, "collector-layer"),
            }
        )
        if not isinstance(made["collector-layer"], Exception):
            # The collector's root, then the certificates made in it by its own tool.
            made["pki"] = in_parallel(
                {"pki": functools.partial(certificates, collector, made["collector-layer"], robots)}
            )["pki"]
        for name, answer in made.items():
            if isinstance(answer, Exception):
                detail = getattr(answer, "stderr", b"") or b""
                say(f"setup: {name} failed: {answer} {detail.decode(errors='replace')[-2000:]}")
                return 1
        say(f"setup: certificates and the installed layers in {time.monotonic() - t0:.1f} s")
        collector.start()
        # The fleet stop's broker, and each robot's agent's network, before the robots.
        broker.configure(collector.pki, [robot.name for robot in robots])
        broker.start()
        for robot in robots:
            fleet_net.link(robot.number, robot.netns)
        for robot in robots:
            robot.start(made["layer"], collector.pki)
        ready = in_parallel({r.name: functools.partial(ready_to_run, r) for r in robots})
        not_ready = [name for name, ok in ready.items() if ok is not True]
        if not_ready:
            result("fleet_up", False, f"not in RUN: {not_ready}")
            logs(collector, robots)
            return 1
        say(f"setup: {ROBOTS} robots in RUN {time.monotonic() - t0:.1f} s after the start")
        fleet = Fleet(robots, broker, made["layer"], collector.pki, collector.root, result, say)
        if only_fleet_stop:
            fleet_stop_scenarios(fleet, made["layer"], collector.pki)
            return 1 if TALLY["failed"] else 0
        before = {robot.name: len(robot.own_records()) for robot in robots}
        answers: dict[str, float] = {}
        timer = threading.Thread(
            target=lambda: answers.update(answer_times(collector, robots, before)), daemon=True
        )
        timer.start()
        pressed = stop_at_collector(collector, robots)
        outage(collector, robots, robots[DOWN_ROBOT - 1])
        skewed_clocks(collector, robots, pressed)
        timer.join()
        alert_at_receiver(collector, pressed, answers)
        windows_at_collector(
            collector,
            robots,
            robots[DOWN_ROBOT - 1],
            made["layer"] / "opt/srcsd/bin/srcsctl",
            result,
        )
        fleet_stop_scenarios(fleet, made["layer"], collector.pki)
        figures(collector)
        if TALLY["failed"]:
            logs(collector, robots)
    finally:
        if fleet is not None:
            fleet.stop_keepalive()
        broker.kill()
        for robot in robots:
            robot.kill()
        collector.stop()
        keep_for_a_look(work, collector, robots)
        say(f"took {time.time() - args.started:.0f} s")
    print(f"{TALLY['passed']} passed, {TALLY['failed']} failed", flush=True)
    return 1 if TALLY["failed"] else 0


if __name__ == "__main__":
    sys.exit(main())
