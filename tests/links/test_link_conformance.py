"""The links' conformance suite: the contract of ``supervisord.links.base.Link``, run against
every link kind on a real medium (tests/links/conftest.py; docs/protocol.md "Links").

Every wait is on an event with a bound (``BOUND_S``), never on a time: a receive is repeated
until what the far end sent has come, waiting on the link's descriptor when it has one.
"""

from __future__ import annotations

import select
import time
from collections.abc import Callable

import pytest

from supervisord.links.base import Incoming, Link, LinkBrokenError
from supervisord.protocol.framing import Rejection
from supervisord.protocol.hid import HidRejection
from supervisord.protocol.j1939 import CanRejection
from supervisord.protocol.messages import (
    FeedbackGet,
    FeedbackName,
    FeedbackSet,
    Message,
    UserHeartbeat,
)
from tests.links.conftest import Harness

BOUND_S = 10.0
"""How long anything may take to arrive on a busy machine before the test fails."""
REJECTIONS = (Rejection, CanRejection, HidRejection)


def _receive_when_ready(link: Link) -> list[Incoming]:
    """One receive as the daemon's loop makes it: once the link's descriptor is readable
    (waiting a little for it), or after a short sleep when it has none."""
    fd = link.fileno()
    if fd is None:
        time.sleep(0.001)
        return link.receive()
    ready, _, _ = select.select([fd], [], [], 0.05)
    return link.receive() if ready else []


def receive_until(link: Link, done: Callable[[list[Incoming]], bool]) -> list[Incoming]:
    """Everything received until ``done`` holds of it; fails after ``BOUND_S``."""
    got: list[Incoming] = []
    deadline = time.monotonic() + BOUND_S
    while not done(got):
        assert time.monotonic() < deadline, f"only {got} arrived"
        got += _receive_when_ready(link)
    return got


def receive_until_broken(link: Link) -> list[Incoming]:
    """Everything received until the link reports itself broken; fails after ``BOUND_S``."""
    got: list[Incoming] = []
    deadline = time.monotonic() + BOUND_S
    while time.monotonic() < deadline:
        try:
            got += _receive_when_ready(link)
        except LinkBrokenError:
            return got
    raise AssertionError(f"never broken; received {got}")


def accepted(got: list[Incoming]) -> list[Incoming]:
    return [thing for thing in got if not isinstance(thing, REJECTIONS)]


def test_starts_closed(harness: Harness) -> None:
    """A new link is not open, and receive and send on it are refused as broken."""
    link = harness.link
    assert not link.is_open
    with pytest.raises(LinkBrokenError):
        link.receive()
    with pytest.raises(LinkBrokenError):
        link.send([FeedbackSet(1, 1)])


def test_open_and_close_are_idempotent(harness: Harness) -> None:
    """A second open keeps the link as it is, a second close does nothing, and a closed link
    opens again and carries traffic."""
    link = harness.link
    states = []
    link.open()
    fd = link.fileno()
    link.open()
    states.append(link.is_open)
    assert link.fileno() == fd
    link.close()
    link.close()
    states.append(link.is_open)
    with pytest.raises(LinkBrokenError):
        link.receive()
    link.open()
    states.append(link.is_open)
    assert states == [True, False, True]
    harness.put(harness.first)
    assert receive_until(link, bool) == [harness.first]


def test_a_frame_is_received_once_decoded(harness: Harness) -> None:
    """A valid frame from the far end comes out of receive once, decoded; the next one after
    it, and nothing between."""
    link = harness.link
    link.open()
    harness.put(harness.first)
    got = receive_until(link, bool)
    harness.put(harness.second)
    got += receive_until(link, lambda later: len(later) > 0)
    assert got == [harness.first, harness.second]


def test_silence_yields_nothing(harness: Harness) -> None:
    """With nothing sent, the link's descriptor is not readable, or, when it has none,
    receive returns nothing (and does not wait for something)."""
    link = harness.link
    link.open()
    fd = link.fileno()
    if fd is None:
        assert link.receive() == []
        assert link.receive() == []
    else:
        assert select.select([fd], [], [], 0) == ([], [], [])


def test_a_corrupt_frame_is_a_rejection_not_a_message(harness: Harness) -> None:
    """SR-2.10: a frame that fails the protocol's check (checksum, identifier, length) is
    received as a rejection, never a message; the valid frame after it is the one message."""
    link = harness.link
    link.open()
    harness.put_corrupt(harness.first)
    got = receive_until(link, bool)
    assert got
    assert all(isinstance(thing, REJECTIONS) for thing in got), got
    harness.put(harness.second)
    got += receive_until(link, lambda later: harness.second in later)
    assert accepted(got) == [harness.second]


def test_a_partial_frame_is_not_a_message_and_the_far_end_going_away_breaks_the_link(
    harness: Harness,
) -> None:
    """SR-2.3: the start of a frame and then the far end gone (unplugged, hung up, bus-off):
    receive raises LinkBrokenError and nothing before it was a message. The link then closes, opens
    again once the far end is back, and its first message is the far end's next whole frame
    (no half frame survives a reopen)."""
    link = harness.link
    link.open()
    harness.put_partial(harness.first)
    harness.hang_up()
    assert accepted(receive_until_broken(link)) == []
    link.close()
    assert not link.is_open
    link.close()  # safe after a failure, and twice
    harness.come_back()
    link.open()
    harness.put(harness.second)
    assert receive_until(link, bool) == [harness.second]


def test_writes_reach_the_far_end_as_the_protocols_frames(harness: Harness) -> None:
    """What is sent reaches the far end in order, decoded there by the protocol's decoder;
    a message the transport has no form for is not sent (PR-3.3, PR-4.1)."""
    link = harness.link
    link.open()
    sent: list[Message] = [UserHeartbeat(1), FeedbackSet(3, 42), FeedbackName(2, "Speed")]
    sent += [FeedbackGet(85), FeedbackSet(4, -7)]
    link.send(sent)
    expected = [message for message in sent if type(message) in harness.carries]
    assert len(expected) >= 3  # every transport carries feedback values and labels
    deadline = time.monotonic() + BOUND_S
    while len(harness.taken()) < len(expected):
        assert time.monotonic() < deadline, f"only {harness.taken()} arrived"
        time.sleep(0.001)
    assert harness.taken() == expected


def test_the_descriptor_is_the_one_to_wait_on(harness: Harness) -> None:
    """While open, fileno is None (the loop polls) or a descriptor that becomes readable when
    the far end has sent something."""
    link = harness.link
    link.open()
    fd = link.fileno()
    harness.put(harness.first)
    if fd is not None:
        ready, _, _ = select.select([fd], [], [], BOUND_S)
        assert ready == [fd]
    assert receive_until(link, bool) == [harness.first]


def test_the_description_names_where_the_link_goes(harness: Harness) -> None:
    """The description names the port, node or bus, open or not."""
    link = harness.link
    closed = link.description
    assert harness.place in closed
    link.open()
    assert link.description == closed
