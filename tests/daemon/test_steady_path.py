"""The loop's steady path against its full path (SR-9.4): two loops, one with the steady path
switched off, fed the same VSC traffic on the same manual clock, do the same.

The steady path (``Supervisor._apply``) applies a decision that sets the same levels as the
last, in the same state, with nothing to record or refuse, without the full path's output
loop and bookkeeping. These tests run both loops side by side over random VSC traffic (modes,
e-stop words, silences, bursts, joystick-free and with client-free API listener) and require
equal decisions, equal output levels after every decision, the same frames to the VSC and the
same records.
"""

from __future__ import annotations

import random
from collections.abc import Iterator
from dataclasses import dataclass, field
from pathlib import Path

import pytest

from supervisord.daemon import lifecycle
from supervisord.daemon.loop import Listener, Supervisor
from supervisord.links.base import Backoff
from supervisord.links.serial_link import SerialLink
from supervisord.outputs import create_output, parse_output_spec
from supervisord.protocol.codes import VscMode
from supervisord.record.jsonl import RecordWriter
from supervisord.safety.config import OutputRole, OutputSpec, SafetyConfig
from supervisord.safety.decision import Decision
from supervisord.sim.pty import PtyPort
from tests.daemon.peer import VscPeer
from tests.daemon.test_loop import ManualClock, arrived


@dataclass
class Seen(Listener):
    """Every decision the loop applied, with the outputs' levels right after it."""

    supervisor: Supervisor | None = None
    decisions: list[tuple[Decision, dict[str, bool]]] = field(default_factory=list)

    def decided(self, decision: Decision) -> None:
        assert self.supervisor is not None
        levels = {name: o.requested for name, o in self.supervisor.outputs.items()}
        self.decisions.append((decision, levels))


@dataclass
class Side:
    """One loop, its VSC peer and what it did."""

    supervisor: Supervisor
    peer: VscPeer
    port: PtyPort
    seen: Seen
    clock: ManualClock


def side(directory: Path, start_ns: int, *, steady: bool) -> Side:
    directory.mkdir()
    port = PtyPort(directory / "vsc")
    clock = ManualClock()
    clock.now = start_ns
    outputs = [
        create_output(parse_output_spec("drive", {"kind": "sim", "path": str(directory / "d")})),
        create_output(
            parse_output_spec(
                "lamp", {"kind": "sim", "role": "power", "path": str(directory / "l")}
            )
        ),
    ]
    safety = SafetyConfig(
        rearm_hold_ms=100,
        outputs=(OutputSpec("drive", OutputRole.MOTION), OutputSpec("lamp", OutputRole.POWER)),
    )
    seen = Seen()
    supervisor = Supervisor(
        safety,
        SerialLink(str(port.path)),
        outputs,
        RecordWriter(directory / "stops.jsonl"),
        backoff=Backoff(first_ms=20, max_ms=100),
        clock=clock,
        listener=seen,
    )
    supervisor.steady_path = steady
    seen.supervisor = supervisor
    return Side(supervisor, VscPeer(port, clock=clock.seconds), port, seen, clock)


@pytest.fixture
def sides(tmp_path: Path) -> Iterator[tuple[Side, Side]]:
    start_ns = ManualClock().now  # both loops' clocks read the same, always
    pair = (
        side(tmp_path / "steady", start_ns, steady=True),
        side(tmp_path / "full", start_ns, steady=False),
    )
    yield pair
    for one in pair:
        lifecycle.shutdown(one.supervisor)
        one.port.close()


def turn(one: Side, now: int) -> None:
    """One turn of the peer and the loop at ``now`` on the manual clock (as in test_loop)."""
    one.clock.now = now
    written = one.peer.written
    if one.peer.serve():
        arrived(one.supervisor, one.peer.written - written)
    one.supervisor.step()


def summary(decision: Decision) -> tuple[object, ...]:
    return (
        decision.now,
        decision.state,
        decision.causes,
        dict(decision.outputs),
        decision.heartbeat_estop,
        decision.next_deadline,
        decision.frames,
        decision.records,
        decision.refusals,
    )


@pytest.mark.parametrize("seed", [1, 2, 3])
def test_the_steady_path_does_what_the_full_path_does(sides: tuple[Side, Side], seed: int) -> None:
    """SR-9.4, SR-6.1: over random VSC traffic (takeovers, holds, e-stops, silences that lose
    the link, bursts) a loop with the steady path applies the same decisions as one without,
    its outputs stand at the same levels after each, and it sends the VSC the same frames."""
    rng = random.Random(seed)
    steady, full = sides
    full_applies = []
    apply_full = steady.supervisor._apply_full

    def counted(decision: Decision, since: int | None) -> None:
        full_applies.append(decision)
        apply_full(decision, since)

    steady.supervisor._apply_full = counted  # type: ignore[method-assign]
    for one in sides:
        lifecycle.start(one.supervisor)
    now = steady.clock.now
    for _ in range(1200):
        if rng.random() < 0.03:  # the VSC changes what its heartbeats say, or falls silent
            mode = rng.choice([VscMode.OPERATIONAL] * 4 + [VscMode.PAUSE, VscMode.LOCAL])
            estop = rng.choice([0] * 8 + [1, 4])
            silent = rng.random() < 0.1
            burst = rng.choice([1, 1, 1, 2])
            for one in sides:
                one.peer.mode, one.peer.estop = mode, estop
                one.peer.silent, one.peer.burst = silent, burst
        # The next thing due (the peer's heartbeat or the loop's deadline), or a step between.
        due = [int(steady.peer.next_due * 1e9) + 1_000]
        if steady.supervisor.decision is not None:
            due.append(steady.supervisor.decision.next_deadline)
        now = min((t for t in due if t > now), default=now + 1_000_000)
        now = min(now, steady.clock.now + rng.randrange(1, 60) * 1_000_000)
        for one in sides:
            turn(one, now)
    states = {d.state for d, _ in steady.seen.decisions}
    assert len(states) >= 2  # the traffic took the robot through changes, not one state
    # Most decisions took the steady path, the others the full one: both were exercised.
    assert 0 < len(full_applies) < len(steady.seen.decisions) / 2
    assert len(steady.seen.decisions) == len(full.seen.decisions)
    for (a, levels_a), (b, levels_b) in zip(
        steady.seen.decisions, full.seen.decisions, strict=True
    ):
        assert summary(a) == summary(b)
        assert levels_a == levels_b
    assert steady.peer.received == full.peer.received
