"""The flight recorder's ring and bases (SR-7.10, SR-7.11; ``supervisord/daemon/flight.py``):
bounded by count, a snapshot every window or every half ring, a window that starts at the
oldest base the ring still reaches, and a window that nothing appended later can change."""

from __future__ import annotations

import pytest

from supervisord.daemon.flight import FlightRecorder, FlightSettings
from supervisord.safety.config import SafetyConfig
from supervisord.safety.core import SafetyCore
from supervisord.safety.events import Event, Tick
from tests.record.conftest import make_stop_record

MS = 1_000_000
START = 1_000 * MS


def _feed(recorder: FlightRecorder, core: SafetyCore, events: list[Event]) -> None:
    """As the loop's ``_feed`` does: append, count, handle."""
    for event in events:
        recorder.inputs.append(event)
        recorder.count += 1
        core.handle(event)


def _ticks(first_ms: int, count: int) -> list[Event]:
    return [Tick(START + (first_ms + i) * MS) for i in range(count)]


def test_the_ring_is_bounded_by_count() -> None:
    """SR-7.10: the ring holds at most ``max_inputs`` inputs, the newest."""
    core = SafetyCore(SafetyConfig(), START)
    recorder = FlightRecorder(core.config, FlightSettings(max_inputs=16))
    recorder.start(START, 0)
    events = _ticks(1, 40)
    _feed(recorder, core, events)
    assert list(recorder.inputs) == events[-16:]
    assert recorder.count == 40


def test_a_snapshot_is_due_every_window_or_every_half_ring() -> None:
    """SR-7.11: the next snapshot is due ``window_s`` after the last one, or once half the
    ring has filled since, whichever comes first."""
    core = SafetyCore(SafetyConfig(), START)
    recorder = FlightRecorder(core.config, FlightSettings(window_s=1.0, max_inputs=16))
    recorder.start(START, 0)
    assert not recorder.due(START + 999 * MS)
    assert recorder.due(START + 1000 * MS)
    _feed(recorder, core, _ticks(1, 7))
    assert not recorder.due(START + 10 * MS)
    _feed(recorder, core, _ticks(8, 1))
    assert recorder.due(START + 10 * MS)
    assert recorder.rebase(core, START + 10 * MS) is None
    assert not recorder.due(START + 11 * MS)


def test_a_window_starts_at_the_oldest_base_the_ring_reaches() -> None:
    """SR-7.11: the start, then a snapshot, then another: a window carries the bases still in
    the ring, oldest first; once the ring has passed them all, none, and says why."""
    core = SafetyCore(SafetyConfig(), START)
    recorder = FlightRecorder(core.config, FlightSettings(window_s=1.0, max_inputs=16))
    recorder.start(START, 3)
    _feed(recorder, core, _ticks(1, 4))
    window = recorder.window(make_stop_record(9), 3)
    assert [b.state is None for b in window.bases] == [True]
    assert window.bases[0].after_seq == 3
    recorder.last_seq = 5
    recorder.rebase(core, START + 5 * MS)
    _feed(recorder, core, _ticks(6, 4))
    window = recorder.window(make_stop_record(9), 3)
    assert [(b.index, b.state is None) for b in window.bases] == [(0, True), (4, False)]
    assert window.bases[1].after_seq == 5
    assert window.end == 8
    _feed(recorder, core, _ticks(10, 10))  # 18 inputs: the start (index 0) is out of the ring
    window = recorder.window(make_stop_record(9), 3)
    assert [b.index for b in window.bases] == [4]
    _feed(recorder, core, _ticks(20, 10))
    window = recorder.window(make_stop_record(9), 3)
    assert window.bases == ()
    assert "16 inputs" in window.cut


def test_a_window_does_not_change_with_later_inputs() -> None:
    """SR-7.12: the loop hands over a tuple of the ring: inputs appended after the stop are
    not in it, however long the sink takes to write it."""
    core = SafetyCore(SafetyConfig(), START)
    recorder = FlightRecorder(core.config)
    recorder.start(START, 0)
    _feed(recorder, core, _ticks(1, 5))
    window = recorder.window(make_stop_record(1), 0)
    _feed(recorder, core, _ticks(6, 5))
    assert window.inputs == tuple(_ticks(1, 5))
    assert window.end == 5


@pytest.mark.parametrize(
    "settings", [{"window_s": 0}, {"window_s": 61}, {"max_inputs": 15}, {"max_inputs": 1 << 21}]
)
def test_settings_out_of_range_are_refused(settings: dict[str, float]) -> None:
    """SR-7.10: the ring is bounded: neither its time nor its count can be unbounded."""
    with pytest.raises(ValueError, match="must be"):
        FlightSettings(**settings)  # type: ignore[arg-type]
