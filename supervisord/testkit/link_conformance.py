"""The links' conformance suite, for an integrator's new link as for the project's own
(docs/testing.md "The kit for integrators", docs/protocol.md "Links").

A link (``supervisord.links.base.Link``) opens, hands the loop what arrived decoded into
messages or rejections, writes the protocol's frames, closes, and reports a world that broke
it as ``LinkBrokenError``. Bytes from the device never raise anything else: a frame that
fails the protocol's check, a partial frame or plain garbage is a rejection or nothing
(SR-2.10), so the daemon's loop never sees an exception from what a VSC sent.

To run it, subclass ``LinkConformance`` in a test module (the name starting with ``Test``)
and give it a ``harness`` fixture that yields a fresh ``LinkHarness`` per test, its link not
yet open, on a real medium (a pseudo-terminal, a virtual bus) the harness holds the far end
of::

    class TestMyLink(LinkConformance):
        @pytest.fixture
        def harness(self, tmp_path): ...

Every wait is on an event with a bound (``BOUND_S``), never on a time. No check imports
pytest: each is a plain method that raises ``AssertionError`` when the link breaks the
contract.
"""

from __future__ import annotations

import dataclasses
import random
import select
import time
from collections.abc import Callable

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

BOUND_S = 10.0
"""How long anything may take to arrive on a busy machine before a check fails."""
REJECTIONS = (Rejection, CanRejection, HidRejection)

GARBAGE: tuple[bytes, ...] = (
    bytes(range(256)),
    b"\xff" * 70,
    b"\x00" * 70,
    random.Random(48).randbytes(512),
)
"""What a broken or noisy device may send: every byte value, runs of one byte, noise."""


@dataclasses.dataclass
class LinkHarness:
    """A link under test and its far end, the VSC's side of the medium.

    ``first`` and ``second`` are two different things the far end can send, as the link must
    decode them; ``put`` sends one in the protocol's encoding, ``put_corrupt`` sends its frame
    damaged so that the protocol's check refuses it, ``put_partial`` only the start of it,
    ``put_garbage`` raw bytes as the medium carries them (a bus: in frames of its own).
    ``taken`` is what has reached the far end so far, decoded there. ``carries`` is the set
    of message types the transport has a form for (the others are not sent). ``hang_up``
    makes the far end go away for real; ``come_back`` brings a new one at the same place.
    ``place`` is what the link's description must name.
    """

    link: Link
    place: str
    first: Incoming
    second: Incoming
    put: Callable[[Incoming], None]
    put_corrupt: Callable[[Incoming], None]
    put_partial: Callable[[Incoming], None]
    put_garbage: Callable[[bytes], None]
    taken: Callable[[], list[Message]]
    carries: frozenset[type[Message]]
    hang_up: Callable[[], None]
    come_back: Callable[[], None]


def receive(link: Link) -> list[Incoming]:
    """One ``receive``; anything it raises but ``LinkBrokenError`` fails the contract (a
    device's bytes never raise into the loop, SR-2.10)."""
    try:
        return link.receive()
    except LinkBrokenError:
        raise
    except Exception as error:
        raise AssertionError(
            f"{type(link).__name__}.receive raised {error!r} on what the device sent: "
            "a link hands a rejection, never an exception (SR-2.10)"
        ) from error


def receive_when_ready(link: Link) -> list[Incoming]:
    """One receive as the daemon's loop makes it: once the link's descriptor is readable
    (waiting a little for it), or after a short sleep when it has none."""
    fd = link.fileno()
    if fd is None:
        time.sleep(0.001)
        return receive(link)
    ready, _, _ = select.select([fd], [], [], 0.05)
    return receive(link) if ready else []


def receive_until(link: Link, done: Callable[[list[Incoming]], bool]) -> list[Incoming]:
    """Everything received until ``done`` holds of it; fails after ``BOUND_S``."""
    got: list[Incoming] = []
    deadline = time.monotonic() + BOUND_S
    while not done(got):
        assert time.monotonic() < deadline, f"only {got} arrived"
        got += receive_when_ready(link)
    return got


def receive_until_broken(link: Link) -> list[Incoming]:
    """Everything received until the link reports itself broken; fails after ``BOUND_S``."""
    got: list[Incoming] = []
    deadline = time.monotonic() + BOUND_S
    while time.monotonic() < deadline:
        try:
            got += receive_when_ready(link)
        except LinkBrokenError:
            return got
    raise AssertionError(f"never broken; received {got}")


def accepted(got: list[Incoming]) -> list[Incoming]:
    return [thing for thing in got if not isinstance(thing, REJECTIONS)]


def refused_as_broken(call: Callable[[], object]) -> bool:
    """Whether ``call`` raised ``LinkBrokenError`` (and nothing else)."""
    try:
        call()
    except LinkBrokenError:
        return True
    return False


class LinkConformance:
    """The contract of ``Link``, one check per method, each on a fresh ``harness``."""

    def test_starts_closed(self, harness: LinkHarness) -> None:
        """A new link is not open, and receive and send on it are refused as broken."""
        link = harness.link
        assert not link.is_open
        assert refused_as_broken(link.receive), "receive on a link never opened"
        assert refused_as_broken(lambda: link.send([FeedbackSet(1, 1)])), "send, never opened"

    def test_open_and_close_are_idempotent(self, harness: LinkHarness) -> None:
        """A second open keeps the link as it is, a second close does nothing, and a closed
        link opens again and carries traffic."""
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
        assert refused_as_broken(link.receive), "receive on a closed link"
        link.open()
        states.append(link.is_open)
        assert states == [True, False, True]
        harness.put(harness.first)
        assert receive_until(link, bool) == [harness.first]

    def test_a_frame_is_received_once_decoded(self, harness: LinkHarness) -> None:
        """A valid frame from the far end comes out of receive once, decoded; the next one
        after it, and nothing between."""
        link = harness.link
        link.open()
        harness.put(harness.first)
        got = receive_until(link, bool)
        harness.put(harness.second)
        got += receive_until(link, lambda later: len(later) > 0)
        assert got == [harness.first, harness.second]

    def test_silence_yields_nothing(self, harness: LinkHarness) -> None:
        """With nothing sent, the link's descriptor is not readable, or, when it has none,
        receive returns nothing (and does not wait for something)."""
        link = harness.link
        link.open()
        fd = link.fileno()
        if fd is None:
            assert receive(link) == []
            assert receive(link) == []
        else:
            assert select.select([fd], [], [], 0) == ([], [], [])

    def test_a_corrupt_frame_is_a_rejection_not_a_message(self, harness: LinkHarness) -> None:
        """SR-2.10: a frame that fails the protocol's check (checksum, identifier, length) is
        received as a rejection, never a message; the valid frame after it is the one
        message."""
        link = harness.link
        link.open()
        harness.put_corrupt(harness.first)
        got = receive_until(link, bool)
        assert got
        assert all(isinstance(thing, REJECTIONS) for thing in got), got
        harness.put(harness.second)
        got += receive_until(link, lambda later: harness.second in later)
        assert accepted(got) == [harness.second]

    def test_garbage_never_raises_and_the_link_carries_on(self, harness: LinkHarness) -> None:
        """SR-2.10: whatever bytes the device sends, receive hands rejections or nothing and
        never raises (but ``LinkBrokenError`` for a medium that broke, which garbage is not);
        the link stays open, and a valid frame after the garbage still arrives."""
        link = harness.link
        link.open()
        for garbage in GARBAGE:
            harness.put_garbage(garbage)
            got: list[Incoming] = []
            deadline = time.monotonic() + BOUND_S
            # The garbage may leave the decoder inside a frame that swallows the next valid
            # one: send it again until one arrives whole.
            while harness.second not in got:
                assert time.monotonic() < deadline, f"nothing valid after garbage: {got}"
                harness.put(harness.second)
                end = time.monotonic() + 0.5
                while harness.second not in got and time.monotonic() < end:
                    got += receive_when_ready(link)
            assert link.is_open, "garbage closed the link"

    def test_a_partial_frame_is_not_a_message_and_the_far_end_going_away_breaks_the_link(
        self, harness: LinkHarness
    ) -> None:
        """SR-2.3: the start of a frame and then the far end gone (unplugged, hung up,
        bus-off): receive raises LinkBrokenError and nothing before it was a message. The link
        then closes, opens again once the far end is back, and its first message is the far
        end's next whole frame (no half frame survives a reopen)."""
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

    def test_writes_reach_the_far_end_as_the_protocols_frames(self, harness: LinkHarness) -> None:
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

    def test_the_descriptor_is_the_one_to_wait_on(self, harness: LinkHarness) -> None:
        """While open, fileno is None (the loop polls) or a descriptor that becomes readable
        when the far end has sent something."""
        link = harness.link
        link.open()
        fd = link.fileno()
        harness.put(harness.first)
        if fd is not None:
            ready, _, _ = select.select([fd], [], [], BOUND_S)
            assert ready == [fd]
        assert receive_until(link, bool) == [harness.first]

    def test_the_description_names_where_the_link_goes(self, harness: LinkHarness) -> None:
        """The description names the port, node or bus, open or not."""
        link = harness.link
        closed = link.description
        assert harness.place in closed
        link.open()
        assert link.description == closed
