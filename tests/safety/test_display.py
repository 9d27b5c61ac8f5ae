"""The remote's display: forwarded within the rate limits and sent again after a re-link."""

from __future__ import annotations

import itertools

from supervisord.protocol.messages import FeedbackName, FeedbackSet
from supervisord.safety import DisplayUpdate, LinkOpened, RefusalReason
from tests.safety.rig import LOCAL, MS, OPERATIONAL, PAUSE, SEARCHING, Rig


def _ready() -> Rig:
    rig = Rig()
    rig.open_link()
    rig.key85(1)
    rig.vsc(LOCAL)
    return rig


def _sent(rig: Rig) -> list[tuple[int, object]]:
    return [
        (d.now, f)
        for d in rig.decisions
        for f in d.frames
        if isinstance(f, FeedbackName | FeedbackSet)
    ]


def _run_deadlines(rig: Rig, ms: int) -> None:
    end = rig.now + ms * MS
    while rig.last.next_deadline <= end:
        rig.now = rig.last.next_deadline
        rig.tick()


def test_text_rows_go_out_at_most_every_250_ms() -> None:
    """Four text rows set at once are sent one per 250 ms (strings at most 4 Hz)."""
    rig = _ready()
    for key in (90, 91, 92, 93):
        rig.feed(DisplayUpdate(rig.now, FeedbackName(key, f"row {key}")))
    _run_deadlines(rig, 1000)
    sent = _sent(rig)
    assert [f for _, f in sent] == [FeedbackName(k, f"row {k}") for k in (90, 91, 92, 93)]
    times = [t for t, _ in sent]
    assert all(b - a >= 250 * MS for a, b in itertools.pairwise(times))


def test_values_go_out_at_most_every_50_ms() -> None:
    """Values are sent one per 50 ms (at most 20 Hz); while a key waits for its slot only its
    latest value is kept."""
    rig = _ready()
    for value in (1, 2, 3):
        rig.feed(DisplayUpdate(rig.now, FeedbackSet(1, value)))
    rig.feed(DisplayUpdate(rig.now, FeedbackSet(2, 7)))
    _run_deadlines(rig, 200)
    sent = _sent(rig)
    assert [f for _, f in sent] == [FeedbackSet(1, 1), FeedbackSet(1, 3), FeedbackSet(2, 7)]
    times = [t for t, _ in sent]
    assert all(b - a >= 50 * MS for a, b in itertools.pairwise(times))


def test_display_is_sent_again_after_the_remote_relinks() -> None:
    """PR-2.12: labels and the display mode are sent again when the remote re-links
    (Searching then a linked mode), not before: a remote that is searching has no display to
    show them; vibration is not repeated."""
    rig = _ready()
    rig.feed(DisplayUpdate(rig.now, FeedbackName(1, "speed")))
    rig.feed(DisplayUpdate(rig.now, FeedbackSet(99, 2)))
    rig.feed(DisplayUpdate(rig.now, FeedbackSet(12, 1)))
    _run_deadlines(rig, 500)
    first = len(_sent(rig))
    assert first == 3
    rig.advance(10)
    rig.vsc(SEARCHING)
    _run_deadlines(rig, 40)
    assert len(_sent(rig)) == first  # nothing while the remote searches
    rig.advance(50)
    rig.vsc(LOCAL)
    _run_deadlines(rig, 500)
    again = [f for _, f in _sent(rig)[first:]]
    assert again == [FeedbackName(1, "speed"), FeedbackSet(99, 2)]


def test_display_is_sent_again_after_the_link_opens_again() -> None:
    """PR-2.12, SR-4.4: a VSC reconnect (the link reported open again, here without a close
    first) is a re-link: the labels and values kept go again with its first linked heartbeat."""
    rig = _ready()
    rig.feed(DisplayUpdate(rig.now, FeedbackName(1, "speed")))
    rig.feed(DisplayUpdate(rig.now, FeedbackSet(99, 2)))
    _run_deadlines(rig, 500)
    first = len(_sent(rig))
    assert first == 2
    rig.advance(10)
    rig.feed(LinkOpened(rig.now))
    rig.key85(1)
    rig.advance(50)
    rig.vsc(LOCAL)
    _run_deadlines(rig, 500)
    again = [f for _, f in _sent(rig)[first:]]
    assert again == [FeedbackName(1, "speed"), FeedbackSet(99, 2)]


def test_display_is_not_sent_again_while_the_remote_stays_linked() -> None:
    """PR-2.12, choice 18: only a re-link (a linked mode after Searching, an unknown mode or
    no heartbeat) sends the display again; heartbeats in linked modes, one mode after
    another, do not."""
    rig = _ready()
    rig.feed(DisplayUpdate(rig.now, FeedbackName(1, "speed")))
    rig.feed(DisplayUpdate(rig.now, FeedbackSet(99, 2)))
    _run_deadlines(rig, 500)
    first = len(_sent(rig))
    assert first == 2
    for mode in (LOCAL, OPERATIONAL, PAUSE, LOCAL, OPERATIONAL):
        rig.advance(50)
        rig.vsc(mode)
        _run_deadlines(rig, 40)
    assert _sent(rig)[first:] == []


def test_a_value_edited_on_the_remote_is_not_overwritten_on_relink() -> None:
    """A user value the operator edited in the remote's menu replaces ours in the store."""
    rig = _ready()
    rig.feed(DisplayUpdate(rig.now, FeedbackSet(3, 10)))
    _run_deadlines(rig, 100)
    rig.from_vsc(FeedbackSet(3, 42))
    rig.vsc(SEARCHING)
    rig.advance(50)
    rig.vsc(OPERATIONAL)
    _run_deadlines(rig, 200)
    assert _sent(rig)[-1][1] == FeedbackSet(3, 42)


def test_clients_cannot_set_vsc_settings_or_bad_values() -> None:
    """Key 85 (and the other VSC settings) and an out-of-range display mode are refused."""
    rig = _ready()
    refused = rig.feed(DisplayUpdate(rig.now, FeedbackSet(85, 0)))
    assert [r.reason for r in refused.refusals] == [RefusalReason.DISPLAY_KEY_NOT_ALLOWED]
    refused = rig.feed(DisplayUpdate(rig.now, FeedbackSet(99, 7)))
    assert [r.reason for r in refused.refusals] == [RefusalReason.DISPLAY_VALUE_OUT_OF_RANGE]
    refused = rig.feed(DisplayUpdate(rig.now, FeedbackName(50, "x")))
    assert [r.reason for r in refused.refusals] == [RefusalReason.DISPLAY_KEY_NOT_ALLOWED]
    _run_deadlines(rig, 500)
    assert _sent(rig) == []
