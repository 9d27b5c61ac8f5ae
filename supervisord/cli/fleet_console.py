"""``srcsctl fleet stop`` and ``srcsctl fleet status``: the fleet's console (SR-13.15,
docs/fleet.md "The fleet stop").

``keepalive`` says the console is there until interrupted (SR-8.21). ``stop`` sends one stop
(``--all``, ``--group G`` or ``ROBOT...``) through the fleet's broker, waits for the robots'
acknowledgements until every robot has answered or ``--deadline``, and shows per robot: stopped
(state, each output's read-back, the stop record's number, the robot's arrival-to-off time and
the time to its answer), not stopped (why), or silent. Silent robots are sent the same stop
again (a new nonce, the same ``stop_id``) every ``--retry`` seconds until the deadline: the
daemon answers a stop_id it has seen without a second record. ``--release`` withdraws the
console's stop instead (the robots stay STOPPED until the operator's takeover on the remote).
``status`` shows the robots the broker knows, online or not, their groups and their last
acknowledgement.

Every text shown is another machine's and is escaped (:mod:`terminal_text`). Exit status: 0
when every robot the stop is for answered stopped (or released), 1 when one did not or is
silent or the broker could not be reached, 2 for bad arguments.
"""

from __future__ import annotations

import argparse
import json
import queue
import signal
import threading
import time
from collections.abc import Callable
from pathlib import Path
from typing import IO, TYPE_CHECKING, Final

from supervisord.cli.terminal_text import printable
from supervisord.fleet_agent import ack as acks
from supervisord.fleet_agent.message import new_message, new_stop_id
from supervisord.fleet_agent.tally import Round
from supervisord.fleet_agent.topics import (
    ALL,
    PREFIX,
    Target,
    checked_name,
    keepalive_topic,
    parse_robot_topic,
    stop_topic,
)

if TYPE_CHECKING:
    from supervisord.fleet_agent.mqtt_edge import Connection

EXIT_FAILED: Final = 1
EXIT_BAD_INPUT: Final = 2
CONNECT_S: Final = 5.0


def _name(what: str) -> Callable[[str], str]:
    def check(text: str) -> str:
        try:
            return checked_name(text, what)
        except ValueError as e:
            raise argparse.ArgumentTypeError(str(e)) from None

    return check


def _broker(fleet: argparse.ArgumentParser) -> None:
    from supervisord.cli.fleet_agent import broker_address  # noqa: PLC0415

    fleet.add_argument("--fleet", dest="fleet_name", type=_name("fleet"), required=True)
    fleet.add_argument("--broker", type=broker_address, required=True, metavar="HOST[:PORT]")
    fleet.add_argument("--cafile", type=Path, required=True, help="the fleet's CA")
    fleet.add_argument("--cert", type=Path, required=True, help="this console's certificate")
    fleet.add_argument("--key", type=Path, required=True, help="its private key")
    fleet.add_argument(
        "--name",
        dest="console",
        type=_name("console"),
        required=True,
        help="this console's name: its certificate's CN, recorded with the stop",
    )
    fleet.add_argument("--json", dest="console_json", action="store_true", help="JSON lines")


def add_subcommands(actions: argparse._SubParsersAction) -> None:  # type: ignore[type-arg]
    """``fleet stop`` and ``fleet status`` beside ``fleet replay``."""
    stop = actions.add_parser(
        "stop",
        help="stop robots of the fleet through its broker and show each one's acknowledgement",
        description="Send a fleet stop through the fleet's MQTT broker and show, per robot, "
        "stopped (its state, outputs read back, record and times), not stopped (why) or silent "
        "(srcsctl(1), docs/fleet.md 'The fleet stop').",
    )
    who = stop.add_mutually_exclusive_group(required=True)
    who.add_argument("--all", dest="stop_all", action="store_true", help="every robot")
    who.add_argument("--group", dest="stop_group", type=_name("group"), help="a group's robots")
    who.add_argument("stop_robots", metavar="ROBOT", nargs="*", type=_name("robot"), default=[])
    stop.add_argument(
        "--deadline", type=float, default=2.0, help="seconds to wait for the answers (2)"
    )
    stop.add_argument(
        "--retry", type=float, default=0.5, help="send again to silent robots this often (0.5 s)"
    )
    stop.add_argument(
        "--release",
        action="store_true",
        help="withdraw this console's stop STOP_ID (the robots stay stopped until takeover)",
    )
    stop.add_argument("--stop-id", dest="stop_id", help="the stop's id (default: a new one)")
    _broker(stop)
    keepalive = actions.add_parser(
        "keepalive",
        help="say this console is there, until interrupted (for robots that require it)",
        description="Send this console's keepalive every --period seconds until SIGINT or "
        "SIGTERM, for robots whose config makes the fleet's console a required stop source "
        "([fleet] console_required): they stop when it ends (docs/fleet.md 'The fleet stop').",
    )
    keepalive.add_argument(
        "--period", type=float, default=1.0, help="seconds between keepalives (1)"
    )
    _broker(keepalive)
    status = actions.add_parser(
        "status",
        help="the robots the fleet's broker knows, online or not, and their last answers",
    )
    status.add_argument("--wait", type=float, default=1.0, help="seconds to gather the answers (1)")
    _broker(status)


def run_stop(args: argparse.Namespace, out: IO[str], errors: IO[str]) -> int:
    if not 0.1 <= args.deadline <= 600 or not 0.05 <= args.retry <= 600:
        print("srcsctl fleet stop: --deadline 0.1 to 600 s, --retry 0.05 to 600 s", file=errors)
        return EXIT_BAD_INPUT
    if args.release and not args.stop_id:
        print("srcsctl fleet stop: --release needs the --stop-id it withdraws", file=errors)
        return EXIT_BAD_INPUT
    if args.stop_all:
        targets: tuple[Target, ...] = (ALL,)
    elif args.stop_group:
        targets = (Target("group", args.stop_group),)
    elif args.stop_robots:
        targets = tuple(Target("robot", r) for r in dict.fromkeys(args.stop_robots))
    else:
        print("srcsctl fleet stop: say --all, --group G or the robots", file=errors)
        return EXIT_BAD_INPUT
    connection = _connect(args, errors)
    if connection is None:
        return EXIT_FAILED
    kind = "release" if args.release else "stop"
    try:
        sent_at = time.time()
        stop_id = args.stop_id or new_stop_id(args.console, sent_at)
        tally = Round(stop_id, targets, kind)
        start = time.monotonic()
        deadline = start + args.deadline

        def send(to: tuple[Target, ...]) -> None:
            for target in to:
                message = new_message(kind, stop_id, args.console, time.time())
                connection.publish(stop_topic(args.fleet_name, target), message.encode())

        send(targets)
        next_retry = start + args.retry
        while not tally.done and (now := time.monotonic()) < deadline:
            if now >= next_retry:
                send(tuple(Target("robot", r) for r in tally.silent))
                next_retry = now + args.retry
            _take(connection, tally, args.fleet_name, min(deadline, next_retry) - now, start)
        ended = time.monotonic() - start
    finally:
        connection.stop()
    return _report(tally, kind, ended, args.console_json, out)


def run_keepalive(args: argparse.Namespace, out: IO[str], errors: IO[str]) -> int:
    """Publish a keepalive every ``--period`` until a signal; a broker away meanwhile is
    reconnected to by paho, and the robots' own timeouts judge the gap (SR-8.21)."""
    if not 0.05 <= args.period <= 20:
        print("srcsctl fleet keepalive: --period 0.05 to 20 s", file=errors)
        return EXIT_BAD_INPUT
    connection = _connect(args, errors)
    if connection is None:
        return EXIT_FAILED
    stop = threading.Event()
    for signum in (signal.SIGINT, signal.SIGTERM):
        signal.signal(signum, lambda *_: stop.set())
    topic = keepalive_topic(args.fleet_name, args.console)
    sent = 0
    try:
        while not stop.is_set():
            message = new_message("keepalive", "keepalive", args.console, time.time())
            sent += connection.publish(topic, message.encode())
            stop.wait(args.period)
    finally:
        connection.stop()
    out.write(f"{sent} keepalives sent\n")
    return 0


def run_status(args: argparse.Namespace, out: IO[str], errors: IO[str]) -> int:
    connection = _connect(args, errors)
    if connection is None:
        return EXIT_FAILED
    tally = Round(None, (ALL,))
    try:
        start = time.monotonic()
        while (left := start + max(0.1, args.wait) - time.monotonic()) > 0:
            _take(connection, tally, args.fleet_name, left, start)
    finally:
        connection.stop()
    for robot in tally.expected:
        presence = tally.roster.get(robot)
        answer = tally.answers.get(robot)
        groups = sorted(presence.groups) if presence else []
        row = {
            "robot": robot,
            "online": presence.online if presence else None,
            "groups": groups,
            "last": json.loads(answer.encode()) if answer else None,
        }
        if args.console_json:
            out.write(json.dumps(row) + "\n")
            continue
        online = "?" if presence is None else "online" if presence.online else "OFFLINE"
        last = (
            "no answer held"
            if answer is None
            else f"last {answer.kind} {answer.stop_id}: {_said(answer)}"
        )
        out.write(printable(f"{robot:<16} {online:<8} {','.join(groups) or '-':<16} {last}") + "\n")
    if not tally.expected:
        print("srcsctl fleet status: the broker knows no robot of this fleet", file=errors)
        return EXIT_FAILED
    return 0


def _connect(args: argparse.Namespace, errors: IO[str]) -> Connection | None:
    """A connection subscribed to the answers and presence, or ``None`` (said why)."""
    try:
        from supervisord.fleet_agent import mqtt_edge  # noqa: PLC0415
    except ImportError as error:
        print(f"srcsctl fleet: needs paho-mqtt (the fleet extra): {error}", file=errors)
        return None
    for path in (args.cafile, args.cert, args.key):
        if not path.is_file():
            print(f"srcsctl fleet: cannot read {path}", file=errors)
            return None
    fleet = args.fleet_name
    topics = [f"{PREFIX}/{fleet}/ack/+", f"{PREFIX}/{fleet}/robot/+"]
    try:
        connection = mqtt_edge.Connection(
            f"srcs-console-{args.console}-{time.monotonic_ns()}",
            mqtt_edge.Tls(args.cafile, args.cert, args.key),
            topics,
        )
    except (OSError, ValueError) as error:
        print(f"srcsctl fleet: the certificates: {error}", file=errors)
        return None
    host, port = args.broker
    connection.start(host, port)
    if not connection.subscribed.wait(CONNECT_S):
        print(
            f"srcsctl fleet: no broker at {host}:{port} within {CONNECT_S:g} s "
            f"({printable(connection.last_error)})",
            file=errors,
        )
        connection.stop()
        return None
    return connection


def _take(connection: Connection, tally: Round, fleet: str, wait: float, start: float) -> None:
    """Feed ``tally`` what arrives within ``wait`` seconds (at least one message's wait)."""
    try:
        item = connection.incoming.get(timeout=max(0.001, wait))
    except queue.Empty:
        return
    while True:
        robot = parse_robot_topic(fleet, item.topic, "robot")
        if robot is not None:
            _presence(tally, robot, item.payload)
        elif parse_robot_topic(fleet, item.topic, "ack") is not None:
            answer = acks.parse(item.payload)
            # A robot answers on its own topic alone (the ACL): its name must match.
            if answer is not None and parse_robot_topic(fleet, item.topic, "ack") == answer.robot:
                tally.answer(answer, item.arrived - start)
        try:
            item = connection.incoming.get_nowait()
        except queue.Empty:
            return


def _presence(tally: Round, robot: str, payload: bytes) -> None:
    try:
        obj = json.loads(payload)
    except (ValueError, UnicodeDecodeError, RecursionError):
        return
    if not isinstance(obj, dict):
        return
    groups = obj.get("groups")
    names = (
        frozenset(g for g in groups if isinstance(g, str))
        if isinstance(groups, list)
        else frozenset()
    )
    tally.presence(robot, names, obj.get("online") is True)


def _said(answer: acks.Ack) -> str:
    if answer.result in ("stopped", "released"):
        outputs = " ".join(
            f"{o.name}={'off' if o.off else 'ON'}"
            + ("" if o.readback is None else f"(read {'on' if o.readback else 'off'})")
            for o in answer.outputs
        )
        seq = "-" if answer.record_seq is None else str(answer.record_seq)
        off = "-" if answer.arrival_to_off_ms is None else f"{answer.arrival_to_off_ms:.2f} ms"
        return f"{answer.result} {answer.state} {outputs or 'no outputs'} record {seq} off in {off}"
    return f"{answer.result.replace('_', ' ')}: {answer.reason or '?'}"


def _report(tally: Round, kind: str, ended: float, as_json: bool, out: IO[str]) -> int:
    for robot in tally.expected:
        answer = tally.answers.get(robot)
        at = tally.answered_at.get(robot)
        if as_json:
            row = {
                "robot": robot,
                "stop_id": tally.stop_id,
                "answer_ms": None if at is None else round(at * 1000, 1),
            }
            row["ack"] = json.loads(answer.encode()) if answer else None
            row["result"] = answer.result if answer else "silent"
            out.write(json.dumps(row) + "\n")
            continue
        if answer is None:
            presence = tally.roster.get(robot)
            why = (
                "agent offline (broker's will)" if presence and not presence.online else "no answer"
            )
            line = f"{robot:<16} silent: {why}"
        else:
            line = (
                f"{robot:<16} {_said(answer)}  answered in {at * 1000:.0f} ms"
                if at is not None
                else robot
            )
        out.write(printable(line) + "\n")
    expected = tally.expected
    if as_json:
        out.write(
            json.dumps(
                {
                    "stop_id": tally.stop_id,
                    "kind": kind,
                    "robots": len(expected),
                    "answered": len(expected) - len(tally.silent),
                    "all_answered": tally.done,
                    "ms": round(ended * 1000, 1),
                }
            )
            + "\n"
        )
    elif tally.done:
        stop = printable(tally.stop_id or "")
        out.write(f"every robot answered ({len(expected)}) in {ended * 1000:.0f} ms; stop {stop}\n")
    elif not expected:
        out.write("no robot of this fleet is known to the broker, and none answered\n")
    else:
        silent = tally.silent
        out.write(
            printable(
                f"{len(expected) - len(silent)} of {len(expected)} answered within {ended:.1f} s; "
                f"silent: {', '.join(silent) or 'none'}; stop {tally.stop_id}"
            )
            + "\n"
        )
    ok = tally.done and all(tally.answers[r].result in ("stopped", "released") for r in expected)
    return 0 if ok else EXIT_FAILED
