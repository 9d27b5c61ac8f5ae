"""Harnesses for the links' conformance suite: one per link kind, each on a real medium.

Each harness holds a link that is not open yet and the far end a VSC would hold: it sends
what a VSC sends, encoded by the protocol's own encoders, reads back what the link sent,
decoded by the protocol's own decoders, and can go away as a VSC does (unplugged, hung up,
bus-off). Serial and HID run on real pseudo-terminals, CAN on python-can's in-process virtual
bus (no socket: nothing leaves the process), the memory link on its ``MemoryPort``.
"""

from __future__ import annotations

import signal
import uuid
from collections.abc import Callable, Iterator
from pathlib import Path
from typing import Protocol

import can
import pytest

from supervisord.links.base import Incoming, Link
from supervisord.links.can_link import CanLink, from_python_can, to_python_can
from supervisord.links.hid_link import NO_REPORT_ID, HidLink
from supervisord.links.memory_link import MemoryLink, MemoryPort
from supervisord.links.serial_link import SerialLink
from supervisord.protocol.framing import FrameDecoder, Rejection, encode_frame
from supervisord.protocol.hid import (
    OUTPUT_LENGTH,
    HidInput,
    HidOutput,
    decode_hid_output,
    encode_hid_input,
)
from supervisord.protocol.j1939 import (
    SEGMENT_COUNT,
    CanFrame,
    FeedbackStringSegment,
    decode_can,
    encode_can,
)
from supervisord.protocol.messages import (
    FeedbackGet,
    FeedbackName,
    FeedbackSet,
    Message,
    UserHeartbeat,
    VscHeartbeat,
)
from supervisord.sim.pty import PtyPort
from supervisord.testkit.link_conformance import LinkHarness

KINDS = ["serial-pty", "can-virtual", "hid-pty", "memory"]


Harness = LinkHarness
"""The kit's harness (``supervisord.testkit.link_conformance``), by its old name here."""


EVERY_MESSAGE: frozenset[type[Message]] = frozenset(
    {UserHeartbeat, FeedbackSet, FeedbackName, FeedbackGet, VscHeartbeat}
)
FEEDBACK_ONLY: frozenset[type[Message]] = frozenset({FeedbackSet, FeedbackName})


def _frame_of(thing: Incoming) -> bytes:
    assert isinstance(thing, VscHeartbeat)
    return encode_frame(thing)


def _damaged(frame: bytes) -> bytes:
    return frame[:-1] + bytes([frame[-1] ^ 0xFF])  # the checksum no longer matches


def _serial_decoded(decoder: FrameDecoder, data: bytes) -> list[Message]:
    messages: list[Message] = []
    for event in decoder.feed(data):
        assert not isinstance(event, Rejection), f"the far end could not decode {event}"
        messages.append(event)
    return messages


class _BytePort(Protocol):
    """A far end that carries the serial protocol's bytes: a pty or a memory port."""

    def write(self, data: bytes) -> None: ...
    def read(self) -> bytes: ...
    def unplug(self) -> None: ...
    def replug(self) -> None: ...


def _serial_harness(
    link: Link, place: str, port: _BytePort, plugged: Callable[[], bool]
) -> Harness:
    """The harness of a link whose far end carries the serial protocol's bytes."""
    decoder = FrameDecoder()
    arrived: list[Message] = []

    def taken() -> list[Message]:
        if plugged():
            arrived.extend(_serial_decoded(decoder, port.read()))
        return arrived

    return Harness(
        link,
        place,
        VscHeartbeat(9),
        VscHeartbeat(4, 0, 1),
        lambda thing: port.write(_frame_of(thing)),
        lambda thing: port.write(_damaged(_frame_of(thing))),
        lambda thing: port.write(_frame_of(thing)[:5]),
        port.write,
        taken,
        EVERY_MESSAGE,
        port.unplug,
        port.replug,
    )


def _serial(tmp_path: Path) -> Iterator[Harness]:
    port = PtyPort(tmp_path / "ttyVSC")
    link = SerialLink(str(port.path))
    yield _serial_harness(link, str(port.path), port, lambda: port.plugged)
    link.close()
    port.close()


def _memory(tmp_path: Path) -> Iterator[Harness]:
    port = MemoryPort("vsc0")
    link = MemoryLink(port)
    yield _serial_harness(link, "vsc0", port, lambda: True)
    link.close()


# SocketCAN's report of a controller that lost the bus (linux/can/error.h: CAN_ERR_BUSOFF in
# the identifier of an error frame): what a CAN link sees when the VSC side of the bus is gone.
BUS_OFF = can.Message(arbitration_id=0x40, data=bytes(8), is_error_frame=True)


def _can(tmp_path: Path) -> Iterator[Harness]:
    channel = f"conformance-{uuid.uuid4().hex}"  # no other test's frames on this bus
    far = can.Bus(interface="virtual", channel=channel)
    segments: dict[int, dict[int, str]] = {}
    arrived: list[Message] = []

    def frame_of(thing: Incoming) -> CanFrame:
        assert isinstance(thing, VscHeartbeat)
        return encode_can(thing)

    def put(frame: CanFrame) -> None:
        far.send(to_python_can(frame))

    def taken() -> list[Message]:
        while (raw := far.recv(timeout=0)) is not None:
            decoded = decode_can(from_python_can(raw))
            if isinstance(decoded, FeedbackStringSegment):  # a label comes in three parts
                parts = segments.setdefault(decoded.key, {})
                parts[decoded.segment] = decoded.text
                if len(parts) == SEGMENT_COUNT:
                    text = "".join(parts[i] for i in range(SEGMENT_COUNT))
                    arrived.append(FeedbackName(decoded.key, text))
                    del segments[decoded.key]
            else:
                assert isinstance(decoded, FeedbackSet), f"the far end could not use {decoded}"
                arrived.append(decoded)
        return arrived

    def corrupt(thing: Incoming) -> None:
        frame = frame_of(thing)  # the same bits under an identifier the protocol never uses
        put(CanFrame(frame.arbitration_id & 0x7FF, frame.data, is_extended_id=False))

    def partial(thing: Incoming) -> None:
        frame = frame_of(thing)
        put(CanFrame(frame.arbitration_id, frame.data[:2], frame.is_extended_id))

    def garbage(data: bytes) -> None:
        # Frames of noise: identifiers and payloads from the bytes, standard and extended.
        for at in range(0, len(data), 8):
            chunk = data[at : at + 8]
            ident = int.from_bytes(chunk[:4].ljust(4, b"\0"), "big")
            extended = bool(chunk[0] & 1)
            ident &= 0x1FFFFFFF if extended else 0x7FF
            far.send(can.Message(arbitration_id=ident, data=chunk, is_extended_id=extended))

    link = CanLink("virtual", channel, 250_000)
    yield Harness(
        link,
        channel,
        VscHeartbeat(9),
        VscHeartbeat(4, 0, 1),
        lambda thing: put(frame_of(thing)),
        corrupt,
        partial,
        garbage,
        taken,
        FEEDBACK_ONLY,
        lambda: far.send(BUS_OFF),
        lambda: None,  # a bus-off controller recovers when its link reopens the bus
    )
    link.close()
    far.shutdown()


def _hid(tmp_path: Path) -> Iterator[Harness]:
    """A pseudo-terminal stands for the hidraw node, not the named pipe of test_hid_link.py:
    a pipe the link opens read-write never reports its far end gone, while a pseudo-terminal
    whose device end closes fails the link's reads with EIO, as an unplugged hidraw node
    does. Raw mode passes the reports' bytes untouched, and each report is one write, so one
    read."""
    # HidLink opens its node without O_NOCTTY (hidraw is no terminal). Were this process a
    # session leader without a terminal, the pseudo-terminal would become its controlling
    # terminal and the hang-up below would send it SIGHUP; ignored for the harness's life.
    previous = signal.signal(signal.SIGHUP, signal.SIG_IGN)
    port = PtyPort(tmp_path / "hidraw0")
    arrived: list[Message] = []
    size = len(NO_REPORT_ID) + OUTPUT_LENGTH
    pending = bytearray()

    def report_of(thing: Incoming) -> bytes:
        assert isinstance(thing, HidInput)
        return encode_hid_input(thing)

    def taken() -> list[Message]:
        if port.plugged:
            pending.extend(port.read())
        while len(pending) >= size:
            chunk, pending[:] = bytes(pending[:size]), pending[size:]
            assert chunk[:1] == NO_REPORT_ID, "each report behind the report number 0"
            report = decode_hid_output(chunk[1:])
            assert isinstance(report, HidOutput), report
            if report.string_key or report.text:
                arrived.append(FeedbackName(report.string_key, report.text))
            else:
                arrived.append(FeedbackSet(report.key, report.value))
        return arrived

    link = HidLink(str(port.path))
    yield Harness(
        link,
        str(port.path),
        HidInput(12, -34, 0, -127, 127, 5, dpad=2, buttons=0b1001, mode=9, estop=1),
        HidInput(0, 0, 0, 0, 0, 0, dpad=0, buttons=0, mode=1, estop=0),
        lambda thing: port.write(report_of(thing)),
        lambda thing: port.write(report_of(thing) + b"\0"),  # a report of the wrong length
        lambda thing: port.write(report_of(thing)[:5]),
        port.write,
        taken,
        FEEDBACK_ONLY,
        port.unplug,
        port.replug,
    )
    link.close()
    port.close()
    signal.signal(signal.SIGHUP, previous)


HARNESSES = {"serial-pty": _serial, "can-virtual": _can, "hid-pty": _hid, "memory": _memory}


@pytest.fixture(params=KINDS)
def harness(request: pytest.FixtureRequest, tmp_path: Path) -> Iterator[Harness]:
    yield from HARNESSES[request.param](tmp_path)
