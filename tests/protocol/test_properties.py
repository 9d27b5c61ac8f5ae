"""Properties of the codecs over generated values and arbitrary bytes."""

from __future__ import annotations

import itertools

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from bench.checksum_escape import escapes
from supervisord.protocol.framing import (
    MAX_FRAME,
    Decoded,
    FrameDecoder,
    Rejection,
    RejectReason,
    encode_frame,
)
from supervisord.protocol.hid import (
    decode_hid_input,
    decode_hid_output,
    encode_hid_input,
    encode_hid_output,
)
from supervisord.protocol.j1939 import decode_can, encode_can
from supervisord.protocol.messages import Message, VscHeartbeat
from tests.protocol import strategies

chunk_cuts = st.lists(st.integers(0, 2000), max_size=30)


def feed_in_chunks(data: bytes, cuts: list[int]) -> list[Decoded]:
    decoder = FrameDecoder()
    events: list[Decoded] = []
    points = sorted({0, len(data), *(c for c in cuts if c < len(data))})
    for start, stop in itertools.pairwise(points):
        events += decoder.feed(data[start:stop])
        assert decoder.buffered <= MAX_FRAME - 1
    return events + decoder.end()


def merge_noise(events: list[Decoded]) -> list[Decoded]:
    """Adjacent noise events as one: chunking may split a run of noise differently."""
    merged: list[Decoded] = []
    for event in events:
        last = merged[-1] if merged else None
        if (
            isinstance(event, Rejection)
            and event.reason is RejectReason.NOISE
            and isinstance(last, Rejection)
            and last.reason is RejectReason.NOISE
        ):
            merged[-1] = Rejection(RejectReason.NOISE, last.byte_count + event.byte_count)
        else:
            merged.append(event)
    return merged


def consumed(event: Decoded) -> int:
    return event.byte_count if isinstance(event, Rejection) else len(encode_frame(event))


@given(strategies.messages)
def test_serial_round_trip(message: Message) -> None:
    """decode(encode(m)) == m for every serial message type over its whole wire range."""
    decoder = FrameDecoder()
    assert decoder.feed(encode_frame(message)) == [message]


@given(strategies.can_messages)
def test_can_round_trip(message: object) -> None:
    """decode_can(encode_can(m)) == m for every CAN message type."""
    assert decode_can(encode_can(message)) == message  # type: ignore[arg-type]


@given(strategies.hid_inputs, strategies.hid_outputs)
def test_hid_round_trip(report_in: object, report_out: object) -> None:
    """Both HID reports decode back to what was encoded."""
    assert decode_hid_input(encode_hid_input(report_in)) == report_in  # type: ignore[arg-type]
    assert decode_hid_output(encode_hid_output(report_out)) == report_out  # type: ignore[arg-type]


@settings(max_examples=300)
@given(st.binary(max_size=3000), chunk_cuts, chunk_cuts)
def test_arbitrary_bytes_in_any_chunking(data: bytes, cuts_a: list[int], cuts_b: list[int]) -> None:
    """Any bytes in any chunking give only messages and rejections, account for every byte,
    and give the same events (noise runs merged) whatever the chunking."""
    events_a = feed_in_chunks(data, cuts_a)
    events_b = feed_in_chunks(data, cuts_b)
    assert merge_noise(events_a) == merge_noise(events_b)
    assert sum(consumed(event) for event in events_a) == len(data)


@settings(max_examples=300)
@given(st.lists(strategies.messages, min_size=1, max_size=8), st.binary(max_size=40), chunk_cuts)
def test_frames_among_garbage(messages: list[Message], garbage: bytes, cuts: list[int]) -> None:
    """Valid frames separated by garbage without a header all come out, in order."""
    clean = garbage.replace(b"\x10", b"\x11")
    stream = b"".join(clean + encode_frame(message) for message in messages)
    decoded = [event for event in feed_in_chunks(stream, cuts) if not isinstance(event, Rejection)]
    assert decoded == messages


@settings(max_examples=500)
@given(strategies.messages, st.data())
def test_a_frame_with_one_corrupted_byte_is_never_accepted(
    message: Message, data: st.DataObject
) -> None:
    """Changing any one byte of a frame means no message is decoded at the frame's start
    (Fletcher-16 catches every single-byte error; a broken header is noise)."""
    frame = bytearray(encode_frame(message))
    at = data.draw(st.integers(0, len(frame) - 1))
    frame[at] ^= data.draw(st.integers(1, 255))
    events = [*FrameDecoder().feed(bytes(frame)), Rejection(RejectReason.TRUNCATED, 0)]
    assert isinstance(events[0], Rejection)


@pytest.mark.parametrize("count", [2, 3, 4])
def test_random_multi_byte_corruption_rarely_escapes(count: int) -> None:
    """With a fixed seed, at most a few of 20,000 random multi-byte corruptions of a heartbeat
    pass the checksum (ideal Fletcher-16: 1 in 65,536); bench/checksum_escape.py measures more."""
    assert escapes(encode_frame(VscHeartbeat(9)), count, 20_000) <= 5


def test_single_byte_corruption_never_escapes() -> None:
    """Every one of 20,000 random single-byte corruptions is caught."""
    assert escapes(encode_frame(VscHeartbeat(9)), 1, 20_000) == 0
