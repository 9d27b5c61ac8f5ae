"""A flight recorder window made the way the daemon makes one, without the daemon: a real
safety core fed a story of inputs, its records as the loop numbers them, the bases the
recorder keeps (the start, and a snapshot taken between two inputs)."""

from __future__ import annotations

import datetime as dt
from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import Any

from supervisord import __version__
from supervisord.protocol.codes import VscMode
from supervisord.protocol.messages import FeedbackSet, Joystick, VscHeartbeat
from supervisord.record.flight import Base, Window
from supervisord.record.format import record_json
from supervisord.record.stop import read_record
from supervisord.safety.config import OutputRole, OutputSpec, SafetyConfig
from supervisord.safety.core import SafetyCore
from supervisord.safety.events import Event, LinkOpened, Tick, VscReceived
from supervisord.safety.snapshot import snapshot
from supervisord.safety.transitions import State

MS = 1_000_000
START_NS = 7_000 * MS
OFFSET = 40  # the record already held 40 records when this start began
CONFIG = SafetyConfig(
    rearm_hold_ms=100,
    outputs=(OutputSpec("drive", OutputRole.MOTION), OutputSpec("lamp", OutputRole.POWER)),
)
UTC = dt.datetime(2026, 3, 1, 12, tzinfo=dt.timezone.utc)


def story(seconds: float = 2.0) -> list[Event]:
    """A VSC at 20 Hz with joysticks at 50 Hz: Local, the operator's takeover, RUN for a while,
    then the remote's e-stop (the last input)."""
    events: list[Event] = [LinkOpened(START_NS), VscReceived(START_NS, FeedbackSet(85, 1))]
    now = START_NS
    beats = int(seconds / 0.05)
    for beat in range(beats + 1):
        now += 50 * MS
        last = beat == beats
        mode = VscMode.LOCAL if beat < 8 else VscMode.OPERATIONAL
        events.append(Tick(now - 1))
        events.append(VscReceived(now, VscHeartbeat(mode, 0, 1 if last else 0)))
        if not last:
            events.append(VscReceived(now + 20 * MS, Joystick()))
    return events


@dataclass
class Run:
    """The core's run: its inputs, the records as the loop writes them, the bases."""

    inputs: list[Event]
    records: list[dict[str, Any]] = field(default_factory=list)
    bases: list[Base] = field(default_factory=list)

    @property
    def stop(self) -> dict[str, Any]:
        stops = [r for r in self.records if r["to"] == "STOPPED" and r["from"] != "STOPPED"]
        return stops[-1]

    def window(
        self, bases: Sequence[Base] | None = None, keep: int | None = None, cut: str = ""
    ) -> Window:
        inputs = self.inputs if keep is None else self.inputs[-keep:]
        return Window(
            stop=read_record(self.stop),
            config=CONFIG,
            sequence_offset=OFFSET,
            inputs=tuple(inputs),
            end=len(self.inputs),
            bases=tuple(self.bases if bases is None else bases),
            window_ns=500 * MS,
            version=__version__,
            cut=cut,
        )


def run(inputs: list[Event], snapshot_at: Sequence[int] = ()) -> Run:
    """Feed ``inputs`` to a fresh core; a snapshot base before each input of ``snapshot_at``."""
    core = SafetyCore(CONFIG, START_NS)
    result = Run(inputs, bases=[Base(0, START_NS, OFFSET, None)])
    result.records += [record_json(r, UTC, OFFSET) for r in core.decision.records]
    for index, event in enumerate(inputs):
        if index in snapshot_at:
            last = result.records[-1]["seq"] if result.records else OFFSET
            result.bases.append(Base(index, event.now, last, snapshot(core)))
        result.records += [record_json(r, UTC, OFFSET) for r in core.handle(event).records]
    assert core.state is State.STOPPED
    return result
