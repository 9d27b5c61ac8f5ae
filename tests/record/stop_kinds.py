"""Windows of every kind of stop, made as the daemon makes them (``tests/record/flight_rig.py``):
a real safety core fed a VSC at 20 Hz with the operator's takeover, a client where the kind has
one, and the stop; its records as the loop numbers them, the start as the window's base.

Kinds: the remote's e-stop; the VSC's silence; a required client lost (after a hold it asked
for and released); category-1 braking (an output with an off delay, SR-1.4); and a failed proof
test (``vsc.prooftest = "record"``: the test runs only while STOPPED, so its failure is never
the change into STOPPED that writes a window; the robot is re-armed after it and the next stop's
window shows it)."""

from __future__ import annotations

import dataclasses
from collections.abc import Callable
from pathlib import Path
from typing import Any

from supervisord import __version__
from supervisord.protocol.codes import VscMode
from supervisord.protocol.messages import FeedbackSet, Joystick, VscHeartbeat
from supervisord.record.flight import Base, FlightWriter, Window
from supervisord.record.format import record_json
from supervisord.record.jsonl import RecordWriter
from supervisord.record.stop import read_record
from supervisord.release import Request
from supervisord.safety.config import ClientSpec, OutputRole, OutputSpec, SafetyConfig
from supervisord.safety.core import SafetyCore
from supervisord.safety.events import (
    ClientConnected,
    ClientHeartbeat,
    ClientHello,
    ClientHold,
    ClientRelease,
    Event,
    LinkOpened,
    Tick,
    VscReceived,
)
from supervisord.safety.prooftest import ProofTestPolicy
from supervisord.safety.transitions import State
from tests.record.flight_rig import MS, OFFSET, START_NS, UTC

RECORD = "stops.jsonl"
OUTPUTS = (OutputSpec("drive", OutputRole.MOTION), OutputSpec("lamp", OutputRole.POWER))


@dataclasses.dataclass
class Story:
    """A core and what it was told and made, stepped 50 ms at a time as a VSC beats."""

    config: SafetyConfig
    now: int = START_NS
    mode: int = VscMode.LOCAL
    estop: int = 0
    beating: bool = True  # the VSC sends its heartbeats
    client: int | None = None  # the client's connection, while it beats
    inputs: list[Event] = dataclasses.field(default_factory=list)
    records: list[dict[str, Any]] = dataclasses.field(default_factory=list)

    def __post_init__(self) -> None:
        self.core = SafetyCore(self.config, self.now)
        self.records += [record_json(r, UTC, OFFSET) for r in self.core.decision.records]
        self.feed(LinkOpened(self.now))
        self.feed(VscReceived(self.now, FeedbackSet(85, 1)))

    def feed(self, event: Event) -> None:
        self.inputs.append(event)
        decision = self.core.handle(event)
        self.records += [record_json(r, UTC, OFFSET) for r in decision.records]

    @property
    def state(self) -> State:
        return self.core.state

    def beat(self, count: int = 1) -> None:
        """``count`` times 50 ms: a tick, the heartbeat, the sticks, a client's heartbeat
        every other beat; nothing more once the core stopped."""
        for _ in range(count):
            self.now += 50 * MS
            self.feed(Tick(self.now - 1))
            if self.beating:
                self.feed(VscReceived(self.now, VscHeartbeat(self.mode, 0, self.estop)))
                if self.state is not State.STOPPED or self.mode == VscMode.LOCAL:
                    self.feed(VscReceived(self.now + 20 * MS, Joystick()))
            if self.client is not None and (self.now // (50 * MS)) % 2 == 0:
                self.feed(ClientHeartbeat(self.now + 10 * MS, self.client))

    def until_stopped(self, limit: int = 100) -> None:
        for _ in range(limit):
            if self.state is State.STOPPED:
                return
            self.beat()
        raise AssertionError(f"no stop within {limit} beats")

    def takeover(self) -> None:
        """The operator: Local a while, Pause for the takeover's rule, then Operational."""
        self.mode = VscMode.PAUSE
        self.beat(8)
        self.mode = VscMode.OPERATIONAL
        self.beat(2)
        assert self.state is State.RUN, self.records[-1]

    @property
    def stop(self) -> dict[str, Any]:
        stops = [r for r in self.records if r["to"] == "STOPPED" and r["from"] != "STOPPED"]
        return stops[-1]

    def window(self) -> Window:
        """The window the daemon writes at the stop (the last input): from the start."""
        assert self.state is State.STOPPED
        return Window(
            stop=read_record(self.stop),
            config=self.config,
            sequence_offset=OFFSET,
            inputs=tuple(self.inputs),
            end=len(self.inputs),
            bases=(Base(0, START_NS, OFFSET, None),),
            window_ns=5_000 * MS,
            version=__version__,
        )

    def write(self, folder: Path) -> Path:
        """The records in a record file and the window beside it; the window's path."""
        with RecordWriter(folder / RECORD) as records:
            for record in self.records:
                records.append(record)
        return FlightWriter(folder / RECORD, 1 << 20).write(self.window())


def _running(config: SafetyConfig) -> Story:
    story = Story(config)
    story.beat(6)
    story.takeover()
    story.beat(10)
    return story


def remote_estop() -> Story:
    story = _running(SafetyConfig(rearm_hold_ms=100, outputs=OUTPUTS))
    story.estop = 1  # the remote's e-stop: bits 0-1 (PR-2.5)
    story.mode = VscMode.LOCAL
    story.until_stopped()
    return story


def silence() -> Story:
    story = _running(SafetyConfig(rearm_hold_ms=100, outputs=OUTPUTS))
    story.beating = False  # the VSC falls silent: the ticks find its timeout passed
    story.until_stopped()
    return story


def client_lost() -> Story:
    config = SafetyConfig(
        rearm_hold_ms=100, outputs=OUTPUTS, clients=(ClientSpec("nav", timeout_ms=300),)
    )
    story = Story(config)
    story.feed(ClientConnected(story.now + MS, 1))
    story.feed(ClientHello(story.now + 2 * MS, 1, "nav"))
    story.client = 1
    story.beat(6)
    story.takeover()
    story.beat(4)
    story.feed(ClientHold(story.now + 5 * MS, 1))
    assert story.state.name == "HOLD"
    story.beat(6)
    story.feed(ClientRelease(story.now + 5 * MS, 1, Request.HOLD))
    assert story.state.name == "RUN"
    story.beat(6)
    story.client = None  # the client hangs: its heartbeats stop
    story.until_stopped()
    return story


def category_1() -> Story:
    outputs = (OutputSpec("drive", OutputRole.MOTION), OutputSpec("brake", OutputRole.POWER, 400))
    story = _running(SafetyConfig(rearm_hold_ms=100, outputs=outputs))
    story.estop = 1
    story.mode = VscMode.LOCAL
    story.until_stopped()
    return story


def prooftest_failed() -> Story:
    config = SafetyConfig(rearm_hold_ms=100, outputs=OUTPUTS, prooftest=ProofTestPolicy.RECORD)
    story = Story(config)
    story.beat(50)  # the VSC's watchdog never trips: no trip within 1.5 s, failed
    assert any(r.get("kind") == "prooftest" for r in story.records), story.records
    story.takeover()
    story.beat(6)
    story.estop = 1
    story.mode = VscMode.LOCAL
    story.until_stopped()
    return story


KINDS: dict[str, Callable[[], Story]] = {
    "remote_estop": remote_estop,
    "silence": silence,
    "client_lost": client_lost,
    "category_1": category_1,
    "prooftest_failed": prooftest_failed,
}
CAUSES = {
    "remote_estop": "vsc_estop",
    "silence": "vsc_link_lost",
    "client_lost": "client_lost:nav",
    "category_1": "vsc_estop",
    "prooftest_failed": "vsc_estop",
}
