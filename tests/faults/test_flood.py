"""A robot program floods the API socket with pipelined requests of every kind while the VSC
reports an e-stop (SR-10.1, SR-7.5, SR-8.5; ``docs/faults.md``; ``docs/safety.md`` "The stop
path first").

The flood is a separate process that keeps the socket full: hold/release pairs and every
other request a client may send, written as fast as the socket takes them, its replies read
as they come. It keeps at most two batches of requests unanswered (about 180 KiB of replies
and pushes at most), so the daemon never drops it for output it left unread (256 KiB,
docs/api.md) even when the machine starves the flood itself: the daemon always has a batch
to read, and what is measured is the daemon under a flood, not a flooder that stopped
reading. The user heartbeats are read on the simulator's side: a second control connection
samples the VSC's age of the last user heartbeat every few milliseconds, and the VSC's own
watchdog bit (``user_timeout``)."""

from __future__ import annotations

import subprocess
import sys
import threading
import time
from pathlib import Path
from typing import Any

from supervisord.api.framing import ApiError
from supervisord.client import ClientError, SupervisorClient
from supervisord.safety.budget import RECORDS_PER_UID
from supervisord.sim.process import SimControl, SimError
from supervisord.testkit.clients import BELOW_THE_DAEMON
from supervisord.testkit.robot import Robot
from supervisord.testkit.wait import wait_until

WATCHDOG_S = 0.5  # the VSC's key-85 watchdog (SR-5, docs/faults.md)
FLOOD_S = 3.0  # the flood runs this long before the e-stop

FLOODER = r"""
import json, select, socket, sys
requests = [
    {"op": "hold"}, {"op": "release", "what": "hold"},
    {"op": "hold"}, {"op": "release", "what": "hold"},
    {"op": "status"}, {"op": "heartbeat"}, {"op": "release", "what": "estop"},
    {"op": "hello", "name": "again"}, {"op": "subscribe", "topics": ["state"]},
    {"op": "display", "value": {"key": 1, "value": 42}},
    {"op": "display", "label": {"key": 1, "text": "speed"}},
    {"op": "display", "row": {"index": 1, "text": "flooding"}},
    {"op": "display", "mode": 1}, {"op": "vibrate", "side": "both"}, {"op": "reset"},
    {"op": "nonsense"}, "not json",
]
batch = b"".join(
    (r if isinstance(r, str) else json.dumps(r)).encode() + b"\n" for r in requests
) * 20
sock = socket.socket(socket.AF_UNIX, socket.SOCK_STREAM)
sock.connect(sys.argv[1])
sock.sendall(b'{"op": "hello", "name": "flood"}\n')
sock.setblocking(False)
per_batch = batch.count(b"\n")
out = bytearray()
sent, replies, answered, partial = 1, 0, 0, b""
print("flooding", flush=True)
while True:
    if not out and sent - answered < per_batch:
        out += batch
    readable, writable, _ = select.select([sock], [sock] if out else [], [], 0.05)
    if writable:
        try:
            n = sock.send(out)
        except BlockingIOError:
            n = 0
        sent += out[:n].count(b"\n")
        del out[:n]
    if readable:
        data = sock.recv(1 << 20)
        if not data:
            print(f"closed after {sent} requests, {replies} lines", flush=True)
            break
        lines = (partial + data).split(b"\n")
        partial = lines.pop()
        replies += len(lines)
        answered += sum(line.startswith(b'{"ok"') for line in lines)  # pushes have "event"
"""


def _release_hold(robot: Robot, name: str) -> bool:
    """End the hold a killed client left (docs/safety.md choice 12: it outlives the client);
    past the user's record budget the hello and the release are refused for a while
    (``rate_limited``, SR-8.5)."""
    try:
        with SupervisorClient.connect(robot.socket_path, name=name) as client:
            client.release("hold")
    except (ApiError, ClientError) as error:
        return "no such request" in str(error)
    return True


class HeartbeatWatch:
    """Samples the simulated VSC's age of the last user heartbeat on a connection of its
    own, from a thread owned and joined by the test."""

    def __init__(self, control_path: Path) -> None:
        self.control = SimControl(control_path)
        self.worst_age = 0.0
        self.tripped = False
        self.samples = 0
        self._done = threading.Event()
        self._thread = threading.Thread(target=self._run, name="heartbeat-watch")

    def __enter__(self) -> HeartbeatWatch:
        self._thread.start()
        return self

    def __exit__(self, *exc: object) -> None:
        self._done.set()
        self._thread.join()
        self.control.close()

    def _run(self) -> None:
        while not self._done.is_set():
            try:
                state: dict[str, Any] = self.control.state()
            except (SimError, OSError):
                continue
            age = state.get("user_heartbeat_age")
            if age is not None:
                self.worst_age = max(self.worst_age, float(age))
            self.tripped |= "user_timeout" in state.get("estop_bits", [])
            self.samples += 1
            time.sleep(0.003)


def test_client_flood_neither_delays_the_estop_nor_starves_the_heartbeat(tmp_path: Path) -> None:
    """SR-5, SR-6, SR-8: while one client pipelines hold/release and every other
    request kind as fast as the socket takes them, the user heartbeat keeps its period
    within the VSC's 500 ms watchdog (read on the VSC's side; the watchdog never trips), a
    remote e-stop turns every output off within the next VSC heartbeat (+ the allowance),
    no output turns on after the daemon read it, the flood's records stay within the
    record budget (docs/safety.md), and the robot re-arms afterwards."""
    with Robot(tmp_path) as robot:
        robot.arm()
        flood_log = tmp_path / "flood.log"
        with (
            flood_log.open("wb") as log,
            subprocess.Popen(
                [*BELOW_THE_DAEMON, sys.executable, "-c", FLOODER, str(robot.socket_path)],
                stdin=subprocess.DEVNULL,
                stdout=log,
                stderr=log,
            ) as flooder,
        ):
            try:
                wait_until(lambda: "flooding" in flood_log.read_text(), what="the flood")
                t_flood = robot.now()
                with HeartbeatWatch(robot.sim.control_path) as beats:
                    time.sleep(FLOOD_S)
                    stop = robot.remote_estop()
                    time.sleep(1.0)  # the flood goes on after the stop
                    t_end = robot.now()
                assert flooder.poll() is None, flood_log.read_text()  # never dropped
            finally:
                flooder.kill()
        t_read = stop.record.mono_ns / 1e9
        assert robot.watcher is not None
        late = robot.watcher.ons_between(t_read, t_end)
        assert late == [], f"outputs on after the e-stop was read: {late}"
        print(
            f"user heartbeat, worst period seen by the VSC: {beats.worst_age * 1000:.0f} ms "
            f"({beats.samples} samples); e-stop off {1000 * (stop.t_off - stop.t_fault):.0f} ms"
        )
        assert beats.samples > 100
        assert not beats.tripped, "the VSC's key-85 watchdog tripped during the flood"
        # The rule's bound, the VSC's watchdog; the period the flood leaves is a number for
        # the bench to measure and this test to print (docs/performance.md "Ten floods"):
        # 455 ms was seen once on a loaded machine, where 250 ms had been asserted.
        assert beats.worst_age < WATCHDOG_S, beats.worst_age
        during = [r for r in robot.records_since(t_flood) if r.mono_ns < stop.record.mono_ns]
        seconds = stop.t_fault - t_flood
        # One budget, the flood's user (hold/release as a named client, reset as a local
        # caller: SR-8.5); a few records of the VSC's own besides.
        assert len(during) <= (RECORDS_PER_UID + 5) * (seconds + 1), len(during)
        counters = robot.counters()
        assert counters.rate_limited > 0
        assert counters.internal_faults == 0
        robot.vsc.release()
        wait_until(lambda: _release_hold(robot, "flood"), what="the flood's hold released")
        rearm = robot.rearm()
        robot.assert_nothing_on(t_read, rearm)
        robot.assert_serving(rearm)
