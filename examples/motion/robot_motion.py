"""A robot's motion service, as an example of a required client of srcsd (docs/bringup.md).

It names itself with ``hello`` (the config's ``[[clients]]`` entry binds the name to this
service's user), sends a heartbeat every 100 ms, and drives a simulated wheel only while the
supervisor is in RUN: the wheel is a file holding the speed set-point, where a real robot
writes to its motor controller. It tells the supervisor whether its command is non-zero
(``command``, SR-4.6), so a takeover never re-arms into a moving wheel.

Fail safe (SR-1.3, SR-4): the wheel is set to 0 before anything else, when the state leaves RUN
(before the supervisor is told the command is zero), on SIGTERM, and when the connection to
the supervisor is lost; a lost connection ends the program with status 1, and systemd starts it
again behind ``srcsctl wait-ready`` (examples/systemd/robot-motion@.service).

Which supervisor: ``-R NAME`` reads the socket from the robot's config ``/etc/srcs/NAME.toml``
and ``--config FILE`` from that file, as ``srcsctl -R`` and ``srcsctl --config`` do (the same
reader, :mod:`supervisord.config.client`), so the program and its unit's ``srcsctl -R %i
wait-ready`` gate cannot disagree on the socket, whether the robot is alone on its computer
(``/run/srcsd/api.sock``) or one of several (SR-8.10). ``--socket PATH`` names it directly.

usage: robot_motion.py [-R NAME | --config FILE | --socket PATH] [--name NAME] [--wheel FILE]
                       [--speed S]
"""

from __future__ import annotations

import argparse
import os
import signal
import sys
import time
from pathlib import Path
from types import FrameType

from supervisord.api.pushes import StatePush
from supervisord.client import DEFAULT_SOCKET_PATH, SupervisorClient
from supervisord.config.client import load_client_config
from supervisord.errors import ConfigError, SrcsError
from supervisord.vocabulary import State

HEARTBEAT_S = 0.1  # 10 Hz: well inside the [[clients]] entry's timeout_ms (docs/api.md)
REPLY_TIMEOUT_S = 5.0
CONFIG_DIR = Path("/etc/srcs")  # srcsd@NAME reads /etc/srcs/NAME.toml (docs/install.md)


class Wheel:
    """The simulated wheel: its speed set-point in a file, replaced whole at each change."""

    def __init__(self, path: Path) -> None:
        self.path = path
        self.speed: float | None = None

    def set(self, speed: float) -> None:
        if speed == self.speed:
            return
        fresh = self.path.with_suffix(".new")
        fresh.write_text(f"{speed:.2f}\n")
        os.replace(fresh, self.path)
        self.speed = speed


class Motion:
    """The loop: heartbeats, the state from the supervisor's pushes, the wheel set from it."""

    def __init__(self, client: SupervisorClient, wheel: Wheel, speed: float) -> None:
        self.client, self.wheel, self.speed = client, wheel, speed
        self.state = State.STOPPED  # every input starts as "not OK"
        self.stopping = False

    def run(self) -> None:
        self.client.command(False)
        self.client.subscribe("state")  # the first push comes right after subscribing
        next_beat = time.monotonic()
        while not self.stopping:
            now = time.monotonic()
            if now >= next_beat:
                self.client.heartbeat()
                next_beat = now + HEARTBEAT_S
            event = self.client.next_event(timeout=max(0.0, next_beat - time.monotonic()))
            if isinstance(event, StatePush):
                self.state = event.report.state
            self.apply()

    def apply(self) -> None:
        """Drive only in RUN. Into RUN: the command declared non-zero before the wheel turns;
        out of it: the wheel at 0 before the command is declared zero (SR-4.6)."""
        moving = bool(self.wheel.speed)
        if self.state is State.RUN and not self.stopping and not moving:
            self.client.command(True)
            self.wheel.set(self.speed)
        elif (self.state is not State.RUN or self.stopping) and moving:
            self.wheel.set(0.0)
            self.client.command(False)

    def stop(self, _signum: int, _frame: FrameType | None) -> None:
        self.wheel.set(0.0)
        self.stopping = True


def supervisor_socket(args: argparse.Namespace) -> Path:
    """The client socket: the robot's config's ``[api] socket`` (``-R``, ``--config``), else
    ``--socket``, else the default. Raises :class:`ConfigError` for a missing or bad config."""
    if args.robot:
        return load_client_config(CONFIG_DIR / f"{args.robot}.toml").socket
    if args.config:
        return load_client_config(args.config).socket
    return Path(args.socket or DEFAULT_SOCKET_PATH)


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    where = parser.add_mutually_exclusive_group()
    where.add_argument("-R", "--robot", metavar="NAME", help="the robot of srcsd@NAME")
    where.add_argument("--config", metavar="FILE", help="the robot's config: its [api] socket")
    where.add_argument("--socket", help=f"srcsd's client socket (default {DEFAULT_SOCKET_PATH})")
    parser.add_argument("--name", default="motion", help="the name under [[clients]]")
    parser.add_argument("--wheel", default="wheel", help="the simulated wheel's file")
    parser.add_argument("--speed", type=float, default=0.5, help="the speed in RUN, m/s")
    args = parser.parse_args(argv)
    wheel = Wheel(Path(args.wheel))
    wheel.set(0.0)  # before the supervisor is even asked: the wheel stands
    try:
        socket = supervisor_socket(args)
    except ConfigError as error:
        print(f"robot-motion: {error}", file=sys.stderr, flush=True)
        return 2
    try:
        with SupervisorClient.connect(socket, args.name, timeout=REPLY_TIMEOUT_S) as client:
            motion = Motion(client, wheel, args.speed)
            signal.signal(signal.SIGTERM, motion.stop)
            print(f"robot-motion: {args.name} connected to {socket}", flush=True)
            motion.run()
            client.command(False)
    except (SrcsError, OSError) as error:
        wheel.set(0.0)
        print(f"robot-motion: the supervisor is gone: {error}", file=sys.stderr, flush=True)
        return 1
    wheel.set(0.0)
    print("robot-motion: stopped", flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
