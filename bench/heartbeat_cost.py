"""What a client's heartbeat costs the loop, in process and hot: CPU time per turn.

Run: ``.venv/bin/python -m bench.heartbeat_cost [--turns K] [--clients N]``; to compare two
trees, run it from each with ``PYTHONPATH`` set to that tree, alternated
(docs/performance.md "A client's heartbeat, trimmed").

``bench.idle_cost`` measures the whole daemon's share, in which a heartbeat's wake-up and
the machine's load weigh as much as the work; this bench takes the work alone. The loop is
``srcsd --config``'s (``supervisord.daemon.assemble``: the serial link on a pseudo-terminal,
the sim output, the record, the client socket, N required clients), on a clock that stands
still (no deadline comes, so every turn is the input's), its wait real. It measures the CPU
time of this thread (the loop's) over ``--turns`` turns of each kind:

- **A**: a VSC joystick frame, no client connected;
- **B**: a VSC joystick frame, N named clients connected and quiet (what connections cost
  every turn, SR-9.4);
- **C**: one client's heartbeat (``{"op":"heartbeat"}``, what the client library sends) and
  its reply, read back by the client (its own part is in the count, a ``send`` and a
  ``recv``).
"""

from __future__ import annotations

import argparse
import socket
import tempfile
import time
from collections.abc import Callable, Sequence
from pathlib import Path

from bench.idle_cost import srcsd_config
from supervisord.config.loader import load_config
from supervisord.daemon import heap, lifecycle
from supervisord.daemon.assemble import build_api, build_supervisor
from supervisord.protocol.framing import encode_frame
from supervisord.protocol.messages import Axis, Joystick
from supervisord.sim.pty import PtyPort

HEARTBEAT = b'{"op":"heartbeat"}\n'
START_NS = 10**12  # the standing clock's time: any positive time


def per_turn(turns: int, turn: Callable[[], object]) -> float:
    """The CPU time of this thread per ``turn``, in microseconds."""
    started = time.thread_time_ns()
    for _ in range(turns):
        turn()
    return (time.thread_time_ns() - started) / turns / 1e3


def measure(turns: int, clients: int) -> tuple[float, float, float]:
    """Microseconds of CPU per turn of kinds A, B and C (the module docstring)."""
    now = [START_NS]
    with tempfile.TemporaryDirectory(prefix="srcs-beat-") as name:
        directory = Path(name)
        port = PtyPort(directory / "vsc")
        (directory / "robot.toml").write_text(srcsd_config(clients))
        config = load_config(directory / "robot.toml")
        supervisor = build_supervisor(config, build_api(config), clock=lambda: now[0])
        sockets: list[socket.socket] = []
        try:
            lifecycle.start(supervisor)
            heap.settle()  # as lifecycle.run does
            frames = [
                encode_frame(Joystick(left_y=Axis.from_value(i % 1000 - 500))) for i in range(64)
            ]
            sent = [0]

            def frame_turn() -> None:
                port.write(frames[sent[0] % 64])  # the stick moves: no two frames alike
                sent[0] += 1
                supervisor.step()
                port.read()  # the user heartbeats and key-85 asks, if any

            per_turn(turns, frame_turn)  # warm
            a = per_turn(turns, frame_turn)
            for index in range(clients):
                client = socket.socket(socket.AF_UNIX)
                client.connect(str(config.api.socket))
                client.sendall(b'{"op":"hello","name":"bench-%d"}\n' % index)
                sockets.append(client)
            for _ in range(4 * clients + 10):
                supervisor.step()
            for client in sockets:
                reply = client.recv(4096)
                assert reply == b'{"ok":true,"op":"hello"}\n', reply
            per_turn(turns, frame_turn)
            b = per_turn(turns, frame_turn)
            beater = sockets[0]

            def heartbeat_turn() -> None:
                beater.sendall(HEARTBEAT)
                supervisor.step()
                beater.recv(4096)

            per_turn(turns, heartbeat_turn)
            c = per_turn(turns, heartbeat_turn)
        finally:
            for client in sockets:
                client.close()
            lifecycle.shutdown(supervisor)
            port.close()
    return a, b, c


def main(argv: Sequence[str] | None = None) -> None:
    parser = argparse.ArgumentParser(prog="bench.heartbeat_cost", description=__doc__)
    parser.add_argument("--turns", type=int, default=6000, help="turns of each kind")
    parser.add_argument("--clients", type=int, default=10, help="named clients connected")
    args = parser.parse_args(argv)
    a, b, c = measure(args.turns, max(1, args.clients))
    print(
        f"CPU per turn: A (VSC frame, no client) {a:.1f} us; B (VSC frame, {args.clients} "
        f"named clients quiet) {b:.1f} us; C (one client's heartbeat) {c:.1f} us"
    )


if __name__ == "__main__":
    main()
