"""srcs-fleet-agent: a robot's end of the fleet stop (docs/fleet.md "The fleet stop").

Subscribes to the robot's stops at the fleet's MQTT broker (mutual TLS), forwards each fresh
one to the supervisor as a fleet_stop request and publishes the supervisor's acknowledgement
(SR-13.13, SR-13.14, SR-13.15). Exit status: 0 after SIGTERM or SIGINT, 2 for bad arguments,
78 for a config or certificate it cannot read (the unit does not restart then).
"""

from __future__ import annotations

import argparse
import json
import logging
import queue
import signal
import socket
import sys
import threading
from collections.abc import Sequence
from pathlib import Path
from types import FrameType
from typing import TYPE_CHECKING

from supervisord import __version__
from supervisord.client import DEFAULT_SOCKET_PATH
from supervisord.errors import ConfigError
from supervisord.fleet_agent.agent import Agent, socket_requester
from supervisord.fleet_agent.replay import SKEW_S, WINDOW_S, ReplayGuard
from supervisord.fleet_agent.topics import ack_topic, checked_name, presence_topic, stop_topics

if TYPE_CHECKING:
    from supervisord.fleet_agent.mqtt_edge import Connection

EXIT_CONFIG = 78
DEFAULT_PORT = 8883


def _name(what: str) -> type[str]:
    def check(text: str) -> str:
        try:
            return checked_name(text, what)
        except ValueError as e:
            raise argparse.ArgumentTypeError(str(e)) from None

    return check  # type: ignore[return-value]


def broker_address(text: str) -> tuple[str, int]:
    """``HOST`` or ``HOST:PORT`` (default port 8883, MQTT over TLS)."""
    host, sep, port = text.rpartition(":")
    if not sep:
        return text, DEFAULT_PORT
    if not port.isdigit() or not 0 < int(port) < 65536 or not host:
        raise argparse.ArgumentTypeError(f"{text!r} is not HOST:PORT")
    return host.strip("[]"), int(port)


def add_tls(parser: argparse.ArgumentParser) -> None:
    """The certificates: the fleet's CA, this end's certificate (CN: its name) and key."""
    parser.add_argument("--broker", type=broker_address, required=True, metavar="HOST[:PORT]")
    parser.add_argument("--cafile", type=Path, required=True, help="the fleet's CA")
    parser.add_argument("--cert", type=Path, required=True, help="this end's certificate")
    parser.add_argument("--key", type=Path, required=True, help="its private key")


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(prog="srcs-fleet-agent", description=__doc__)
    where = parser.add_mutually_exclusive_group()
    where.add_argument("--config", metavar="FILE", help="the robot's config (its [api] socket)")
    where.add_argument("--socket", metavar="PATH", type=Path, help="the API socket")
    parser.add_argument("--fleet", type=_name("fleet"), required=True)
    parser.add_argument(
        "--robot",
        type=_name("robot"),
        default=None,
        help="this robot's name at the broker: its certificate's CN (default: the host name)",
    )
    parser.add_argument(
        "--group",
        dest="groups",
        type=_name("group"),
        action="append",
        default=[],
        help="a group this robot answers stops for; may be given again",
    )
    add_tls(parser)
    parser.add_argument(
        "--window", type=float, default=WINDOW_S, help=f"seconds a stop is fresh ({WINDOW_S:g})"
    )
    parser.add_argument(
        "--skew", type=float, default=SKEW_S, help=f"clock difference tolerated ({SKEW_S:g} s)"
    )
    parser.add_argument(
        "--timeout", type=float, default=2.0, help="seconds to wait for the supervisor (2)"
    )
    parser.add_argument("--version", action="version", version=f"%(prog)s {__version__}")
    return parser


def main(argv: Sequence[str] | None = None) -> int:
    args = build_parser().parse_args(argv)
    logging.basicConfig(
        level=logging.INFO, format="srcs-fleet-agent: %(levelname)s: %(message)s", stream=sys.stderr
    )
    log = logging.getLogger("srcs-fleet-agent")
    socket_path: Path = args.socket or DEFAULT_SOCKET_PATH
    if args.config:
        from supervisord.config.client import load_client_config  # noqa: PLC0415

        try:
            socket_path = load_client_config(args.config).socket
        except ConfigError as error:
            print(f"srcs-fleet-agent: {error}", file=sys.stderr)
            return EXIT_CONFIG
    for path in (args.cafile, args.cert, args.key):
        if not path.is_file():
            print(f"srcs-fleet-agent: cannot read {path}", file=sys.stderr)
            return EXIT_CONFIG
    robot = args.robot or checked_name(socket.gethostname(), "robot (the host name)")
    groups = frozenset(args.groups)
    # paho only now: the arguments are good.
    from supervisord.fleet_agent import mqtt_edge  # noqa: PLC0415

    presence = {"v": 1, "robot": robot, "groups": sorted(groups)}
    online = json.dumps({**presence, "online": True}).encode()
    offline = json.dumps({**presence, "online": False}).encode()
    tls = mqtt_edge.Tls(args.cafile, args.cert, args.key)
    try:
        connection = mqtt_edge.Connection(
            f"srcs-agent-{robot}",
            tls,
            stop_topics(args.fleet, robot, groups),
            will=mqtt_edge.Will(presence_topic(args.fleet, robot), offline),
            on_connect_publish=[(presence_topic(args.fleet, robot), online)],
        )
    except (OSError, ValueError) as error:  # ssl.SSLError is an OSError
        print(f"srcs-fleet-agent: the certificates: {error}", file=sys.stderr)
        return EXIT_CONFIG
    agent = Agent(
        args.fleet,
        robot,
        groups,
        socket_requester(socket_path, args.timeout),
        ReplayGuard(args.window, args.skew),
    )
    stop = threading.Event()

    def on_signal(signum: int, frame: FrameType | None) -> None:
        stop.set()

    signal.signal(signal.SIGTERM, on_signal)
    signal.signal(signal.SIGINT, on_signal)
    host, port = args.broker
    log.info(
        "robot %s of fleet %s, groups %s, broker %s:%s",
        robot,
        args.fleet,
        sorted(groups),
        host,
        port,
    )
    connection.start(host, port)
    answers = ack_topic(args.fleet, robot)
    try:
        _serve(agent, connection, answers, stop, log)
    finally:
        connection.publish(presence_topic(args.fleet, robot), offline, retain=True)
        connection.stop()
    return 0


def _serve(
    agent: Agent, connection: Connection, answers: str, stop: threading.Event, log: logging.Logger
) -> None:
    """Answer each message until ``stop``; log each change of the broker's connection."""
    was, keepalive = "", ""
    while not stop.is_set():
        if connection.last_error != was:
            was = connection.last_error
            log.info("broker: %s", was or "connected")
        if agent.keepalive_error != keepalive:
            keepalive = agent.keepalive_error
            log.info("%s", keepalive or "keepalives passed on")
        try:
            item = connection.incoming.get(timeout=0.5)
        except queue.Empty:
            continue
        answer = agent.handle(
            item.topic, item.payload, retained=item.retained, arrived=item.arrived
        )
        if answer is None:
            continue
        # The daemon's word is kept at the broker for `srcsctl fleet status`; a refused
        # message's answer is not, so it never hides the robot's last real acknowledgement.
        keep = answer.result != "refused"
        connection.publish(answers, answer.encode(), retain=keep)
        log.info(
            "%s %s: %s%s",
            answer.kind,
            answer.stop_id,
            answer.result,
            f" ({answer.reason})" if answer.reason else "",
        )


if __name__ == "__main__":
    sys.exit(main())
