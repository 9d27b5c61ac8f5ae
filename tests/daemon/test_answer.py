"""The one answering of the listener's asks (``daemon/answer.py``): each ask answered with its
kind, in the work's order, every answer back in the work before it goes on; and the
listener's side narrowing an answer to its kind (SR-6, SR-8). Driven with work written as a
listener writes it (a generator) and a face that answers with a real core's decisions. The
daemon's listener through it, over real sockets: ``tests/api/test_api_listener.py`` (its
``Judged`` answers through :func:`serve`, not a copy); a wrong answer refused there too.

Mutants planted in ``answer.py`` and caught here: the look's and the off check's answers
swapped, the send's answer left at the previous one, the event answered without being
decided, the serving ended after the first ask, ``look``'s or ``check_off``'s narrowing
dropped (the answer handed on whatever its kind).
"""

from __future__ import annotations

import pytest

from supervisord.daemon import answer
from supervisord.daemon.listener import Answer, Ask, Asks, CheckOff, Look, Send, Snapshot
from supervisord.daemon.offcheck import OffCheck
from supervisord.daemon.stoptimes import StopTimes
from supervisord.protocol.messages import Message, UserHeartbeat
from supervisord.safety.config import SafetyConfig
from supervisord.safety.core import SafetyCore
from supervisord.safety.decision import Decision
from supervisord.safety.events import Event, Tick
from tests.api.samples import LOOP
from tests.safety.rig import MS, START_NS

FRAMES: tuple[Message, ...] = (UserHeartbeat(1),)


class Face:
    """What answers, as the loop does: a real core decides each event; what was asked is
    kept in order."""

    def __init__(self) -> None:
        self.core = SafetyCore(SafetyConfig(), START_NS)
        self.snapshot = Snapshot(LOOP, StopTimes())
        self.asked: list[tuple[str, object]] = []

    def decide(self, event: Event) -> Decision:
        self.asked.append(("decide", event))
        return self.core.handle(event)

    def look(self, now: int) -> Snapshot:
        self.asked.append(("look", now))
        return self.snapshot

    def check_off(self, now: int) -> OffCheck:
        self.asked.append(("check_off", now))
        return OffCheck((), now, 0)

    def send(self, frames: tuple[Message, ...], now: int) -> None:
        self.asked.append(("send", (frames, now)))


def test_each_ask_is_answered_with_its_kind_in_order_before_the_work_goes_on() -> None:
    """SR-6, SR-8: an event is decided (its decision the answer), a look answered with the
    snapshot, an off check with the check (SR-8.20), a send with nothing, in the work's order."""
    face, got = Face(), []
    tick = Tick(START_NS + 10 * MS)

    def work() -> Asks:
        got.append((yield Look(START_NS + 1)))
        got.append((yield tick))
        got.append((yield CheckOff(START_NS + 2)))
        got.append((yield Send(FRAMES, START_NS + 3)))
        got.append((yield from answer.look(START_NS + 4)))
        got.append((yield from answer.check_off(START_NS + 5)))

    answer.serve(work(), face)
    assert face.asked == [
        ("look", START_NS + 1),
        ("decide", tick),
        ("check_off", START_NS + 2),
        ("send", (FRAMES, START_NS + 3)),
        ("look", START_NS + 4),
        ("check_off", START_NS + 5),
    ]
    decision = got[1]
    assert isinstance(decision, Decision)
    assert decision.now == tick.now
    assert got == [
        face.snapshot,
        decision,
        OffCheck((), START_NS + 2, 0),
        None,
        face.snapshot,
        OffCheck((), START_NS + 5, 0),
    ]


def test_no_work_is_nothing_asked() -> None:
    """SR-9.4: no work, or work that asks nothing, asks nothing of the loop."""
    face = Face()
    answer.serve(None, face)

    def empty() -> Asks:
        yield from ()  # work that asks nothing

    answer.serve(empty(), face)
    assert face.asked == []


@pytest.mark.parametrize(
    ("ask", "wrong", "right"),
    [
        (answer.look, OffCheck((), 0, 0), Snapshot(LOOP, StopTimes())),
        (answer.check_off, Snapshot(LOOP, StopTimes()), OffCheck((), 0, 0)),
    ],
)
def test_the_listener_takes_an_answer_only_of_its_kind(
    ask: object, wrong: Answer, right: Answer
) -> None:
    """A loop that answered with another kind (or none) is ``None`` to the listener, which
    refuses its client's request typed instead of asserting (SR-6, SR-8)."""
    for answered, expected in ((wrong, None), (None, None), (right, right)):
        asking = ask(7)  # type: ignore[operator]
        first: Ask = next(asking)
        assert first in (Look(7), CheckOff(7))
        with pytest.raises(StopIteration) as ended:
            asking.send(answered)
        assert ended.value.value == expected
