"""Robot programs that misbehave, as processes of their own: ``ClientProcess`` starts them
(``python -m supervisord.testkit.clients client|flood|subscriber``); ``main`` is what runs."""

from __future__ import annotations

import argparse
import contextlib
import json
import os
import signal
import socket
import subprocess
import sys
import threading
import time
from collections.abc import Callable, Sequence
from pathlib import Path

from supervisord.api.framing import ApiError, ErrorCode
from supervisord.client import SupervisorClient
from supervisord.errors import SrcsError
from supervisord.testkit.wait import WAIT_S, wait_until
from supervisord.tooling.children import kill, log_tail

BELOW_THE_DAEMON = ("nice", "-n", "10")
"""The prefix for a client a scenario runs to flood or churn the socket as fast as it can. On
a robot ``srcsd`` runs SCHED_FIFO 10 (``units/srcsd@.service``), above every client however
busy; the harness starts it without real-time scheduling, so such a client, left at the
daemon's own priority, would take CPU time the unit never lets it take and starve the loop
for reasons of the harness. Nice 10 keeps the order of the unit without its privilege."""


class ClientProcess:
    """A robot program as a separate process (``python -m supervisord.testkit.clients``):

    - ``client``: says hello as ``name`` and sends a heartbeat every ``period`` s, reconnecting
      when the daemon closes the connection; ``--estop`` asks for an e-stop once first;
      ``--progress`` gives each heartbeat a progress value one ahead of the last (SR-8.16);
    - ``flood``: connects and writes one endless line as fast as the socket takes it;
    - ``subscriber``: subscribes to every topic and never reads a byte.

    It prints one line per event to its log (``hello``, ``closed``, ...). ``kill``, ``stop``
    and ``cont`` send SIGKILL, SIGSTOP, SIGCONT."""

    def __init__(
        self,
        socket_path: Path,
        mode: str,
        log: Path,
        *,
        name: str = "",
        period: float = 0.1,
        extra: Sequence[str] = (),
    ) -> None:
        self.log_path = log
        command = [sys.executable, "-m", "supervisord.testkit.clients", mode, str(socket_path)]
        if mode == "flood":  # as fast as the socket takes it: below the daemon, as on a robot
            command = [*BELOW_THE_DAEMON, *command]
        if name:
            command += ["--name", name]
        command += ["--period", str(period), *extra]
        self.command = command
        self.process: subprocess.Popen[bytes] | None = None

    def start(self) -> ClientProcess:
        with self.log_path.open("ab") as log:
            self.process = subprocess.Popen(  # noqa: S603 - our own interpreter and module
                self.command, stdin=subprocess.DEVNULL, stdout=log, stderr=log
            )
        return self

    def log(self) -> str:
        return log_tail(self.log_path)

    def wait_log(self, text: str, timeout: float = WAIT_S) -> None:
        wait_until(lambda: text in self.log(), timeout, what=f"{text!r} in {self.log_path.name}")

    def signal(self, sig: signal.Signals) -> None:
        assert self.process is not None
        self.process.send_signal(sig)

    def kill(self) -> None:
        kill(self.process)

    def alive(self) -> bool:
        return self.process is not None and self.process.poll() is None


# ------------------------------------------------------------------ the programs


def _client_main(args: argparse.Namespace) -> int:
    """Hello, then heartbeats, reconnecting whenever the daemon closes the connection.
    SIGUSR1 makes it stall: it pipelines thousands of requests, never reads a reply, and
    stops itself (SIGSTOP), as a program hung in the middle of its work. With ``--progress``,
    SIGUSR2 freezes its progress value while its heartbeats go on, as a control loop stuck
    while the heartbeat's thread runs (SR-8.16); it logs each refusal and carries on."""
    stall, stuck = threading.Event(), threading.Event()
    signal.signal(signal.SIGUSR1, lambda *_: stall.set())
    signal.signal(signal.SIGUSR2, lambda *_: stuck.set())
    while True:
        try:
            with SupervisorClient.connect(args.socket, name=args.name, timeout=2.0) as api:
                _say("hello")
                if args.estop:
                    api.estop()
                    _say("estop")
                progress = 0
                while not stall.is_set():
                    if not args.progress:
                        api.heartbeat()
                    else:
                        progress += 0 if stuck.is_set() else 1
                        _progress_beat(api, progress)
                    time.sleep(args.period)
                _stall(api)
        except SrcsError as error:  # closed, refused (too_many_clients), timed out
            _say(f"closed: {type(error).__name__}")
            time.sleep(0.05)


def _progress_beat(api: SupervisorClient, progress: int) -> None:
    try:
        api.heartbeat(progress=progress)
    except ApiError as error:
        if error.code != ErrorCode.REFUSED:
            raise
        _say(f"refused: {error.extra.get('reason')} at progress {progress}")


def _stall(api: SupervisorClient) -> None:
    with socket.socket(fileno=os.dup(api.fileno())) as raw:
        raw.setblocking(False)
        pending = b'{"op": "status"}\n' * 4096
        with contextlib.suppress(OSError):
            while pending:
                pending = pending[raw.send(pending) :]
        _say("stalled")
        os.kill(os.getpid(), signal.SIGSTOP)
        time.sleep(3600)


def _flood_main(args: argparse.Namespace) -> int:
    """One endless line: the server must cut it off (``flood``) and carry on."""
    with socket.socket(socket.AF_UNIX, socket.SOCK_STREAM) as sock:
        sock.connect(args.socket)
        _say("connected")
        chunk = b"x" * 65536
        sent = 0
        try:
            while True:
                sent += sock.send(chunk)
        except OSError as error:
            _say(f"closed after {sent} bytes: {type(error).__name__}")
        with contextlib.suppress(OSError):
            _say(f"reply {sock.recv(4096)[:200]!r}")
    return 0


def _subscriber_main(args: argparse.Namespace) -> int:
    """Subscribes to everything and then never reads: the server must drop it, not wait."""
    with socket.socket(socket.AF_UNIX, socket.SOCK_STREAM) as sock:
        sock.connect(args.socket)
        topics = ["state", "joystick", "gps", "remote_status", "records"]
        sock.sendall(json.dumps({"op": "subscribe", "topics": topics}).encode() + b"\n")
        _say("subscribed")
        while True:
            time.sleep(1.0)


def _say(text: str) -> None:
    print(text, flush=True)


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(
        prog="python -m supervisord.testkit.clients",
        description="Robot programs that misbehave, for fault injection (docs/faults.md).",
    )
    parser.add_argument("mode", choices=["client", "flood", "subscriber"])
    parser.add_argument("socket")
    parser.add_argument("--name", default=None)
    parser.add_argument("--period", type=float, default=0.1)
    parser.add_argument("--estop", action="store_true", help="client: ask for an e-stop first")
    parser.add_argument(
        "--progress", action="store_true", help="client: heartbeats carry a progress value"
    )
    args = parser.parse_args(argv)
    signal.signal(signal.SIGTERM, signal.SIG_DFL)
    runs: dict[str, Callable[[argparse.Namespace], int]] = {
        "client": _client_main,
        "flood": _flood_main,
        "subscriber": _subscriber_main,
    }
    return runs[args.mode](args)


if __name__ == "__main__":
    sys.exit(main())
