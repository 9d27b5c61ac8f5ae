"""An integrator's own tests with the kit (docs/testing.md "The kit for integrators"): a fake
clock driving the safety core, the links' and the outputs' conformance suites run on a link
and an output of one's own, and the typed records ``Robot`` hands out.

Run it with ``python -m pytest examples/testkit/test_my_robot.py``. Here the "own" link and
output are the project's in-memory link and simulated output, so that the example runs
anywhere; a real one is built the same way, its far end on a real medium (a pseudo-terminal,
a virtual CAN bus, a gpio-sim chip). ``tests/testkit/test_example.py`` runs this file.
"""

from __future__ import annotations

from collections.abc import Iterator

import pytest

from supervisord.links.memory_link import MemoryLink, MemoryPort
from supervisord.outputs import OutputFault
from supervisord.outputs.sim import SimOutput, SimSpec
from supervisord.protocol.framing import FrameDecoder, Rejection, encode_frame
from supervisord.protocol.messages import (
    FeedbackGet,
    FeedbackName,
    FeedbackSet,
    Message,
    UserHeartbeat,
    VscHeartbeat,
)
from supervisord.record.stop import StopRecord
from supervisord.safety.config import SafetyConfig
from supervisord.safety.core import SafetyCore
from supervisord.testkit.clock import ClockWentBackwardsError, FakeClock
from supervisord.testkit.link_conformance import LinkConformance, LinkHarness
from supervisord.testkit.output_conformance import OutputConformance, OutputHarness
from supervisord.testkit.robot import Robot
from supervisord.vocabulary import CauseKind, State

# --------------------------------------------------------------------- 1. a fake clock


def test_the_core_decides_on_fake_time() -> None:
    """Ten seconds of the core's deadlines in no time; the clock never goes back."""
    clock = FakeClock()
    core = SafetyCore(SafetyConfig(), clock.now_ns)
    decision = core.decision
    while clock.now_ns < FakeClock().now_ns + 10 * 10**9:
        decision = core.tick(clock.advance_to(decision.next_deadline))
    assert decision.state is State.STOPPED  # no VSC: the link's causes hold it (SR-2)
    with pytest.raises(ClockWentBackwardsError):
        clock.advance(ms=-1)


# --------------------------------------------------------------------- 2. a new link


class TestMyLink(LinkConformance):
    """Every check of the links' suite on my link, each on a fresh harness."""

    @pytest.fixture
    def harness(self) -> Iterator[LinkHarness]:
        port = MemoryPort("my-vsc")  # the far end: what my VSC sends and reads
        link = MemoryLink(port)
        decoder = FrameDecoder()
        arrived: list[Message] = []

        def taken() -> list[Message]:
            events = decoder.feed(port.read())
            arrived.extend(e for e in events if not isinstance(e, Rejection))
            return arrived

        def frame(thing: object) -> bytes:
            assert isinstance(thing, VscHeartbeat)
            return encode_frame(thing)

        yield LinkHarness(
            link=link,
            place="my-vsc",
            first=VscHeartbeat(9),
            second=VscHeartbeat(4, 0, 1),
            put=lambda thing: port.write(frame(thing)),
            put_corrupt=lambda thing: port.write(frame(thing)[:-1] + b"\x00"),
            put_partial=lambda thing: port.write(frame(thing)[:5]),
            put_garbage=port.write,
            taken=taken,
            carries=frozenset({UserHeartbeat, FeedbackSet, FeedbackName, FeedbackGet}),
            hang_up=port.unplug,
            come_back=port.replug,
        )
        link.close()


# --------------------------------------------------------------------- 3. a new output


class TestMyOutput(OutputConformance):
    """Every check of the outputs' suite on my output, each on a fresh harness."""

    @pytest.fixture
    def harness(self) -> Iterator[OutputHarness]:
        out = SimOutput(SimSpec(name="my-enable"))
        yield OutputHarness(
            output=out,
            outside=lambda: out.device_level,  # the level seen from outside the object
            break_device=lambda level: out.stick(not level),  # a welded contact
            fault=OutputFault.MISMATCH,
            periodic=False,
            break_before_open=lambda: out.stick(True),
        )
        out.close()


# --------------------------------------------------------------------- 4. typed records


def stops_raising(robot: Robot, kind: CauseKind, since: float) -> list[StopRecord]:
    """With the real daemon (``with Robot(tmp_path) as robot:``, docs/faults.md), records
    are ``StopRecord``s and states and causes the vocabulary's members, as a client reads
    them from the API."""
    return [r for r in robot.records_since(since) if r.is_stop and robot.raised_in(r, kind)]
