"""The acknowledged fleet stop in the fleet tier (docs/fleet.md "The fleet tier"; SR-8.19 to
SR-8.21, SR-13.13 to SR-13.15): the five robots, each with its package's ``srcs-fleet-agent``
as its unit starts it (its user ``srcs-fleet``, its own network namespace behind a veth,
tests/fleet/robot), a real mosquitto with the fleet's mutual TLS and ACL
(tests/fleet/broker.py) and the package's own console, ``srcsctl fleet stop`` and
``srcsctl fleet keepalive``. robot-5 is started again with the console required (2 s).

- ``fleet_stop_targets``: a stop to one robot, to a group and to all; every addressed robot
  answers stopped with its state, each output's read-back, its record and its time to outputs
  off, the record is in its own file, its output is off; a robot not addressed stays in RUN;
- ``fleet_no_rearm``: each stop released from the console: the robots stay STOPPED with their
  outputs off; only the operator's takeover re-arms;
- ``fleet_broker_down``: mosquitto killed: robot-5 (console required) stops with
  ``fleet_console_lost`` within its timeout, the others stay in RUN;
- ``fleet_replay_refused``: a console's stop, sent again byte for byte by an attacker with a
  console's certificate, is refused ``replayed``; one two minutes old ``stale``; the robot
  stays in RUN, no record is written;
- ``fleet_wrong_certificate``: a client with a certificate for robot-3 from another CA is
  refused by the broker (the same client with the fleet's certificate connects);
- ``fleet_rounds`` (figures): from the console's send to the last acknowledgement, p50, p95
  and p99 over a few dozen stops of all five robots (each released, so each round is a
  stop of its own);
- ``fleet_network_cut``: robot-2's link down; a stop to it names it silent at the deadline;
- ``fleet_loss``: 10 % loss on every robot's link (robot-2's still cut): every round names
  every robot that did not answer stopped within 1 s of the deadline.
"""

from __future__ import annotations

import json
import math
import subprocess
import threading
import time
import uuid
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from tests.fleet import broker as net
from tests.fleet.broker import FLEET, PORT, Broker
from tests.fleet.pki import BROKER_ADDRESS, CONSOLE, OTHER_CA
from tests.fleet.robots import Robot, poll

HERE = Path(__file__).resolve().parent
REQUIRED = 5
"""The robot whose config requires the fleet's console (SR-8.21)."""
REQUIRED_MS = 2000
CUT = 2
"""The robot whose link is cut."""
DEADLINE = 2.0
ROUNDS = 24
LOSS_ROUNDS = 6
LOSS_PERCENT = 10.0

Result = Callable[[str, bool, str], None]


def percentile(values: list[float], share: float) -> float:
    """The nearest-rank percentile."""
    ordered = sorted(values)
    return ordered[max(0, math.ceil(share * len(ordered)) - 1)]


def spread(values: list[float]) -> str:
    if not values:
        return "none"
    return (
        f"p50 {percentile(values, 0.5):.1f} ms, p95 {percentile(values, 0.95):.1f} ms,"
        f" p99 {percentile(values, 0.99):.1f} ms, max {max(values):.1f} ms over {len(values)}"
    )


def off(output: dict[str, Any]) -> bool:
    """Off by its read-back, or by its commanded level where it reads nothing back."""
    readback = output.get("readback")
    return readback is False or (readback is None and output.get("level") is False)


@dataclass
class Fleet:
    robots: list[Robot]
    broker: Broker
    layer: Path
    pki: Path
    collector_root: Path
    result: Result
    say: Callable[[str], None]
    keepalive: subprocess.Popen[bytes] | None = None
    facts: list[str] = field(default_factory=list)

    def python(self) -> tuple[list[str], dict[str, str]]:
        """The robot package's interpreter, its srcsctl's (the console's own code)."""
        env = {"PATH": "/usr/sbin:/usr/bin:/sbin:/bin", "LANG": "C.UTF-8"}
        return [str(self.layer / "opt/srcsd/bin/python3")], env

    def tls(self, name: str) -> list[str]:
        return ["--cafile", str(self.pki / "ca.pem"), "--cert", str(self.pki / f"{name}.pem"),
                "--key", str(self.pki / f"{name}.key")]  # fmt: skip

    def console_args(self) -> list[str]:
        return ["--fleet", FLEET, "--broker", f"{BROKER_ADDRESS}:{PORT}", *self.tls(CONSOLE),
                "--name", CONSOLE]  # fmt: skip

    def rounds(
        self, count: int, release: bool, *target: str, deadline: float = DEADLINE
    ) -> list[dict[str, Any]]:
        """``count`` rounds of the console's ``srcsctl fleet stop TARGET`` (console.py)."""
        python, env = self.python()
        argv = [*python, str(HERE / "console.py"), str(count), "1" if release else "0", "--",
                *target, "--deadline", str(deadline), *self.console_args()]  # fmt: skip
        done = subprocess.run(  # noqa: PLW1510 - its answers are judged, not its status
            argv, capture_output=True, env=env, cwd="/", timeout=30 + count * (4 * deadline + 10)
        )
        answers = [json.loads(line) for line in done.stdout.decode().splitlines() if line.strip()]
        if len(answers) != count:
            self.say(f"console: {done.stderr.decode(errors='replace')[-1500:]}")
        return answers

    def start_keepalive(self) -> None:
        python, env = self.python()
        self.keepalive = subprocess.Popen(
            [*python, "-m", "supervisord.cli.srcsctl", "fleet", "keepalive", "--period", "0.5",
             *self.console_args()],
            env=env, cwd="/", stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL,
        )  # fmt: skip

    def stop_keepalive(self) -> None:
        if self.keepalive is not None:
            self.keepalive.kill()
            self.keepalive.wait()

    def robot(self, number: int) -> Robot:
        return self.robots[number - 1]

    def all_run(self, limit: float = 60) -> list[str]:
        """The operator's takeover on every robot not in RUN, in parallel; those still not."""
        failed: list[str] = []

        def one(robot: Robot) -> None:
            if robot.drive() != "1" and not robot.take_over(limit):
                failed.append(robot.name)

        threads = [threading.Thread(target=one, args=(r,)) for r in self.robots]
        for thread in threads:
            thread.start()
        for thread in threads:
            thread.join()
        return failed

    def agents_online(self, since: int, limit: float) -> bool:
        """Every agent connected to the broker (its log) after byte ``since``."""

        def connected() -> bool:
            text = self.broker.log.read_text(errors="replace")[since:]
            return all(f"u'{robot.name}'" in text for robot in self.robots)

        return poll(connected, limit, step=0.2) is not None


def ack_problem(row: dict[str, Any], robot: Robot) -> str | None:
    """What is wrong with a robot's acknowledgement of a stop, or nothing."""
    ack = row.get("ack") or {}
    if row.get("result") != "stopped":
        return f"{row.get('robot')} {row.get('result')}: {ack.get('reason')}"
    outputs = ack.get("outputs") or []
    seq = ack.get("record_seq")
    if ack.get("state") != "STOPPED" or not outputs or not all(off(o) for o in outputs):
        return f"{robot.name}: state {ack.get('state')}, outputs {outputs}"
    if not isinstance(seq, int) or not isinstance(ack.get("arrival_to_off_ms"), (int, float)):
        return f"{robot.name}: no record or time: {ack}"
    record = next((r for r in robot.own_records() if r.get("seq") == seq), None)
    if record is None or not any(
        str(c.get("name", "")).startswith("fleet_stop") for c in record.get("causes", [])
    ):
        return f"{robot.name}: record {seq} is no fleet stop: {record}"
    if robot.drive() != "0":
        return f"{robot.name}: output on"
    return None


def said(row: dict[str, Any]) -> str:
    ack = row.get("ack") or {}
    outputs = " ".join(
        f"{o.get('name')}=read {'off' if o.get('readback') is False else o.get('readback')}"
        for o in ack.get("outputs") or []
    )
    return (
        f"{row.get('robot')} {ack.get('state')} {outputs} record {ack.get('record_seq')}"
        f" off in {ack.get('arrival_to_off_ms')} ms"
    )


def targets(fleet: Fleet) -> list[tuple[list[str], str]]:
    """``fleet_stop_targets``; the stops made, each with its target, for their release."""
    made: list[tuple[list[str], str]] = []
    problems: list[str] = []
    shown: list[str] = []
    for target, addressed in (
        (["robot-1"], {1}),
        (["--group", "site-2"], {4, 5}),
        (["--all"], {1, 2, 3, 4, 5}),
    ):
        running = {r.number for r in fleet.robots if r.drive() == "1"}
        answers = fleet.rounds(1, False, *target)
        rows = answers[0]["rows"] if answers else []
        robots = [row for row in rows if "robot" in row]
        if rows:
            made.append((target, str(rows[-1].get("stop_id"))))
        named = {int(str(row["robot"]).split("-")[1]) for row in robots}
        if named != addressed:
            problems.append(f"{' '.join(target)}: answered {sorted(named)}")
        for row in robots:
            problem = ack_problem(row, fleet.robot(int(str(row["robot"]).split("-")[1])))
            if problem:
                problems.append(f"{' '.join(target)}: {problem}")
        for number in running - addressed:
            if fleet.robot(number).drive() != "1":
                problems.append(f"{' '.join(target)}: robot-{number} not addressed, not in RUN")
        ms = rows[-1].get("ms") if rows else None
        shown.append(f"{' '.join(target)} -> {len(robots)} stopped in {ms} ms")
        if target == ["--all"]:
            fleet.facts = [said(row) for row in robots]
    fleet.result(
        "fleet_stop_targets",
        not problems,
        "; ".join(shown)
        + f"; the robots not addressed stayed in RUN; acks: {', '.join(fleet.facts)}"
        + (f"; {'; '.join(problems)}" if problems else ""),
    )
    return made


def no_rearm(fleet: Fleet, made: list[tuple[list[str], str]]) -> None:
    """``fleet_no_rearm``: the console's release of every stop leaves the robots STOPPED."""
    problems: list[str] = []
    for target, stop_id in made:
        answers = fleet.rounds(1, False, *target, "--release", "--stop-id", stop_id)
        rows = [row for row in (answers[0]["rows"] if answers else []) if "robot" in row]
        if not rows or any(row.get("result") != "released" for row in rows):
            problems.append(f"release {' '.join(target)}: {[r.get('result') for r in rows]}")
    time.sleep(1.0)  # what a re-arm would need: the release's way back and a loop's period
    still_off = [r.name for r in fleet.robots if r.drive() == "0"]
    if len(still_off) != len(fleet.robots):
        problems.append(
            f"re-armed by the release: {sorted({r.name for r in fleet.robots} - set(still_off))}"
        )
    failed = fleet.all_run()
    if failed:
        problems.append(f"the takeover did not re-arm {failed}")
    fleet.result(
        "fleet_no_rearm",
        not problems,
        f"{len(made)} stops released from the console: every robot still STOPPED, outputs off,"
        " 1 s later; the operator's takeover alone re-armed them"
        + (f"; {'; '.join(problems)}" if problems else ""),
    )


def broker_down(fleet: Fleet) -> None:
    """``fleet_broker_down``: mosquitto killed; only the robot that requires the console
    stops, with ``fleet_console_lost``, within its timeout."""
    required = fleet.robot(REQUIRED)
    before = len(required.own_records())
    killed = time.monotonic()
    fleet.broker.kill()
    took = poll(lambda: required.drive() == "0", REQUIRED_MS / 1000 + 10, step=0.01)
    # The others are watched past the required robot's timeout, with as much again.
    rest = killed + 2 * REQUIRED_MS / 1000 - time.monotonic()
    if rest > 0:
        time.sleep(rest)
    others = [r.name for r in fleet.robots if r is not required and r.drive() != "1"]
    causes = [
        str(c.get("name"))
        for record in required.own_records()[before:]
        for c in record.get("causes", [])
    ]
    since = fleet.broker.log.stat().st_size
    fleet.broker.start()
    back = fleet.agents_online(since, 30)
    rearmed = required.take_over(30)
    ok = took is not None and took <= REQUIRED_MS / 1000 + 1.0 and not others
    ok = ok and "fleet_console_lost" in causes and back and rearmed
    fleet.result(
        "fleet_broker_down",
        ok,
        f"broker killed: {required.name} (console required, {REQUIRED_MS} ms) output off "
        + (f"{took:.2f} s later" if took is not None else "never")
        + f" with {sorted(set(causes))}; the others in RUN {2 * REQUIRED_MS / 1000:.0f} s after:"
        f" {not others}{f' (not: {others})' if others else ''}; broker restarted, every agent"
        f" back: {back}; {required.name} re-armed by the takeover: {rearmed}",
    )


def mosquitto_client(tool: str, tls: list[str], *argv: str) -> list[str]:
    return [tool, "-h", BROKER_ADDRESS, "-p", str(PORT), *tls, *argv]


def attack(fleet: Fleet, robot: Robot, payload: bytes) -> dict[str, Any] | None:
    """``payload`` published to the robot's stop topic with a console's certificate (the
    attacker holds one, or the broker), and the robot's next acknowledgement."""
    tls = fleet.tls(CONSOLE)
    listener = subprocess.Popen(
        mosquitto_client("mosquitto_sub", tls, "-t", f"srcs/{FLEET}/ack/{robot.name}", "-R",
                         "-C", "1", "-W", "10"),
        stdout=subprocess.PIPE, stderr=subprocess.PIPE,
    )  # fmt: skip
    time.sleep(0.5)  # its subscription made (a missed ack is a failure, not a false pass)
    subprocess.run(
        mosquitto_client("mosquitto_pub", tls, "-q", "1", "-t",
                         f"srcs/{FLEET}/stop/robot/{robot.name}", "-s"),
        input=payload, check=False, capture_output=True, timeout=20,
    )  # fmt: skip
    out, _ = listener.communicate(timeout=20)
    try:
        answer: dict[str, Any] = json.loads(out)
        return answer
    except ValueError:
        return None


def replay(fleet: Fleet) -> None:
    """``fleet_replay_refused``."""
    robot = fleet.robot(CUT)
    stop_id = f"{CONSOLE}-{int(time.time())}-replay"
    message = {"v": 1, "kind": "stop", "stop_id": stop_id, "sender": CONSOLE,
               "sent_utc": time.time(), "nonce": uuid.uuid4().hex}  # fmt: skip
    payload = json.dumps(message).encode()
    first = attack(fleet, robot, payload)
    problems: list[str] = []
    if not first or first.get("result") != "stopped":
        problems.append(f"the console's own stop: {first}")
    fleet.rounds(1, False, robot.name, "--release", "--stop-id", stop_id)
    if not robot.take_over(30):
        problems.append("not re-armed after the first stop")
    before = len(robot.own_records())
    again = attack(fleet, robot, payload)
    old = dict(message, nonce=uuid.uuid4().hex, sent_utc=time.time() - 120)
    stale = attack(fleet, robot, json.dumps(old).encode())
    time.sleep(0.5)
    for what, answer, reason in (("the copy", again, "replayed"), ("2 min old", stale, "stale")):
        if not answer or answer.get("result") != "refused" or answer.get("reason") != reason:
            problems.append(f"{what}: {answer}")
    running, written = robot.drive() == "1", len(robot.own_records()) - before
    if not running or written:
        problems.append(f"{robot.name} stopped or wrote a record")
    fleet.result(
        "fleet_replay_refused",
        not problems,
        f"{robot.name}: the console's stop stopped it; the same bytes again: "
        f"{(again or {}).get('result')} {(again or {}).get('reason')}; a copy 120 s old with a"
        f" new nonce: {(stale or {}).get('result')} {(stale or {}).get('reason')};"
        f" {robot.name} still in RUN: {running}, records written: {written}"
        + (f"; {'; '.join(problems)}" if problems else ""),
    )


def wrong_certificate(fleet: Fleet) -> None:
    """``fleet_wrong_certificate``."""
    other = fleet.collector_root / OTHER_CA.lstrip("/")
    ca = ["--cafile", str(fleet.pki / "ca.pem")]
    since = fleet.broker.log.stat().st_size

    def connect(pair: Path) -> subprocess.CompletedProcess[bytes]:
        tls = [*ca, "--cert", str(pair / "robot-3.pem"), "--key", str(pair / "robot-3.key")]
        return subprocess.run(
            mosquitto_client("mosquitto_sub", tls, "-t", f"srcs/{FLEET}/stop/all", "-C", "1",
                             "-W", "3"),
            capture_output=True, check=False, timeout=30,
        )  # fmt: skip

    wrong = connect(other)
    right = connect(fleet.pki)
    said_wrong = (wrong.stdout + wrong.stderr).decode(errors="replace").strip()
    said_right = (right.stdout + right.stderr).decode(errors="replace").strip()
    time.sleep(0.3)
    log = fleet.broker.log.read_text(errors="replace")[since:]
    refused_line = next((line for line in log.splitlines() if "OpenSSL" in line), "")
    # mosquitto_sub's -W ends a connected client that got nothing with status 27.
    ok = wrong.returncode not in (0, 27) and right.returncode == 27
    fleet.result(
        "fleet_wrong_certificate",
        ok,
        f"robot-3 with another CA's certificate: status {wrong.returncode}, '{said_wrong[:120]}';"
        f" the broker's log: '{refused_line.strip()[:160]}'; with the fleet's: connected"
        f" (status {right.returncode}{', ' + said_right[:80] if said_right else ''})",
    )


def rounds(fleet: Fleet) -> None:
    """``fleet_rounds``: the figures, every round a new stop of all five, then released."""
    answers = fleet.rounds(ROUNDS, True, "--all")
    times: list[float] = []
    bad = 0
    for answer in answers:
        rows = answer["rows"]
        robots = [row for row in rows if "robot" in row]
        if (rows and rows[-1].get("all_answered") and len(robots) == len(fleet.robots)
                and all(row.get("result") == "stopped" for row in robots)):  # fmt: skip
            times.append(float(rows[-1]["ms"]))
        else:
            bad += 1
    fleet.say(f"figure: fleet stop, send to the last acknowledgement, 5 robots: {spread(times)}")
    fleet.result(
        "fleet_rounds",
        len(answers) == ROUNDS and bad == 0,
        f"{ROUNDS} stops of all 5 robots, each answered stopped by every robot in {len(times)}"
        f" ({bad} not); send to last ack {spread(times)}",
    )


def cut_and_loss(fleet: Fleet) -> None:
    """``fleet_network_cut`` and ``fleet_loss``."""
    cut = fleet.robot(CUT)
    net.cut(CUT, True)
    try:
        answers = fleet.rounds(1, False, cut.name)
        rows = answers[0]["rows"] if answers else []
        row: dict[str, Any] = next((r for r in rows if r.get("robot") == cut.name), {})
        ms = rows[-1].get("ms") if rows else None
        fleet.result(
            "fleet_network_cut",
            row.get("result") == "silent" and ms is not None and ms <= (DEADLINE + 1) * 1000,
            f"{cut.name}'s veth down: the console named it {row.get('result')} after {ms} ms"
            f" (deadline {DEADLINE:g} s)",
        )
        net.loss(LOSS_PERCENT)
        answers = fleet.rounds(LOSS_ROUNDS, True, "--all")
        problems: list[str] = []
        late: list[float] = []
        answered: list[float] = []
        named_total = 0
        for i, answer in enumerate(answers):
            rows = answer["rows"]
            robots = [r for r in rows if "robot" in r]
            ms = float(rows[-1]["ms"]) if rows else math.inf
            not_stopped = [r["robot"] for r in robots if r.get("result") != "stopped"]
            named_total += len(not_stopped)
            late.append(ms - DEADLINE * 1000)
            if {r["robot"] for r in robots} != {r.name for r in fleet.robots}:
                problems.append(f"round {i + 1}: listed {[r['robot'] for r in robots]}")
            if cut.name not in not_stopped:
                problems.append(f"round {i + 1}: {cut.name} not named")
            if ms > (DEADLINE + 1) * 1000:
                problems.append(f"round {i + 1}: verdict at {ms:.0f} ms")
            answered += [float(r["answer_ms"]) for r in robots if r.get("answer_ms") is not None]
        if len(answers) != LOSS_ROUNDS:
            problems.append(f"{len(answers)} of {LOSS_ROUNDS} rounds")
        fleet.say(
            f"figure: fleet stop with {LOSS_PERCENT:g} % loss on the robots' links: each robot's"
            f" answer {spread(answered)}; verdict {max(late, default=0):.0f} ms after the"
            " deadline at most"
        )
        fleet.result(
            "fleet_loss",
            not problems,
            f"{LOSS_PERCENT:g} % loss on every robot's link (nftables; no netem here), {cut.name}"
            f" cut: {len(answers)} rounds, {named_total} robots named not stopped ({cut.name} in"
            f" each), the verdict {max(late, default=0):.0f} ms after the {DEADLINE:g} s"
            f" deadline at most (rule: 1 s); answers {spread(answered)}"
            + (f"; {'; '.join(problems)}" if problems else ""),
        )
    finally:
        net.no_loss()
        net.cut(CUT, False)


def scenarios(fleet: Fleet, layer: Path, pki: Path) -> None:
    """robot-5 started again with the console required, the console's keepalive running,
    every robot in RUN; then each scenario in turn."""
    t0 = time.monotonic()
    fleet.start_keepalive()
    required = fleet.robot(REQUIRED)
    required.kill()
    # Its output file says what the killed srcsd last wrote, until the new one writes its own.
    (required.run / "fleet/drive").unlink(missing_ok=True)
    required.console_ms = str(REQUIRED_MS)
    required.start(layer, pki)
    if not required.up(90):
        fleet.result("fleet_up", False, f"{required.name} not up again")
        return
    failed = fleet.all_run(90)
    if failed or not fleet.agents_online(0, 30):
        fleet.result("fleet_up", False, f"not in RUN: {failed}, or agents offline")
        return
    fleet.say(f"fleet stop: 5 robots in RUN, agents online, in {time.monotonic() - t0:.1f} s")
    made = targets(fleet)
    no_rearm(fleet, made)
    broker_down(fleet)
    replay(fleet)
    wrong_certificate(fleet)
    rounds(fleet)
    cut_and_loss(fleet)
    fleet.say(f"fleet stop: its scenarios in {time.monotonic() - t0:.1f} s")
