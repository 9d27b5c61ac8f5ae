"""Rejections, resynchronisation and bounded memory of the serial frame decoder."""

from __future__ import annotations

import pytest

from supervisord.errors import UnsafeCommandError
from supervisord.protocol.framing import (
    MAX_FRAME,
    FrameDecoder,
    Rejection,
    RejectReason,
    build_frame,
    encode_frame,
)
from supervisord.protocol.messages import (
    FeedbackName,
    Gps,
    MessageControl,
    UserHeartbeat,
    VscHeartbeat,
)

HEARTBEAT = VscHeartbeat(9)
HB = encode_frame(HEARTBEAT)


def decode_all(data: bytes) -> list[object]:
    decoder = FrameDecoder()
    return [*decoder.feed(data), *decoder.end()]


def reasons(events: list[object]) -> list[RejectReason]:
    return [event.reason for event in events if isinstance(event, Rejection)]


def test_bad_checksum_is_rejected_and_the_next_frame_survives() -> None:
    """PR-1.6: a frame with a wrong checksum is one BAD_CHECKSUM; the heartbeat after it decodes."""
    bad = bytearray(HB)
    bad[-1] ^= 0xFF
    events = decode_all(bytes(bad) + HB)
    assert events[0] == Rejection(
        RejectReason.BAD_CHECKSUM, 1, 0x20, 6, "received 0xf640, computed 0x0940"
    )
    assert events[-1] == HEARTBEAT
    assert reasons(events) == [RejectReason.BAD_CHECKSUM, RejectReason.NOISE]


@pytest.mark.parametrize("length", range(249, 256))
def test_impossible_length_is_rejected_at_once(length: int) -> None:
    """PR-1.5, PR-6.4: a length byte over 248 is rejected without waiting for the bytes it
    claims."""
    decoder = FrameDecoder()
    events = decoder.feed(bytes((0x10, 0x01, 0x20, length)))
    assert events[0] == Rejection(RejectReason.BAD_LENGTH, 1, 0x20, length, "over 248")
    assert decoder.buffered == 0


def test_corrupt_length_does_not_swallow_following_heartbeats() -> None:
    """PR-1.6, PR-6.4: a length byte corrupted upwards costs its own frame only: every good
    heartbeat inside the claimed span still decodes (PR-1)."""
    corrupt = bytearray(HB)
    corrupt[3] = 40  # claims 40 payload bytes: the next three heartbeats lie inside
    events = decode_all(bytes(corrupt) + HB * 4)
    assert events.count(HEARTBEAT) == 4
    assert reasons(events)[0] is RejectReason.WRONG_LENGTH  # a heartbeat is never 40 bytes


def test_bogus_header_of_unknown_type_delays_but_loses_nothing() -> None:
    """Noise that looks like a header of an unknown type with a long length delays the frames
    behind it until the claimed bytes arrive, then they all decode."""
    bogus = bytes((0x10, 0x01, 0x82, 40))
    events = decode_all(bogus + HB * 4)
    assert events.count(HEARTBEAT) == 4
    assert reasons(events)[0] is RejectReason.BAD_CHECKSUM


@pytest.mark.parametrize(
    ("kind", "length"),
    [(0x20, 5), (0x20, 40), (0x10, 15), (0x12, 0), (0x31, 20), (0x21, 0)],
)
def test_known_type_with_impossible_length_is_rejected_at_once(kind: int, length: int) -> None:
    """PR-1.7: a known type with a length byte it never has is WRONG_LENGTH from its header alone,
    never half-decoded, and the decoder does not wait for the bytes it claims."""
    frame = build_frame(kind, bytes(length))
    decoder = FrameDecoder()
    assert decoder.feed(frame[:4])[0] == Rejection(RejectReason.WRONG_LENGTH, 1, kind, length)
    events = [*decoder.feed(frame[4:] + HB), *decoder.end()]
    assert events[-1] == HEARTBEAT
    assert all(isinstance(event, Rejection) for event in events[:-1])


@pytest.mark.parametrize("kind", [0xA2, 0x25, 0x90, 0xF9])
def test_unknown_type_is_skipped_whole(kind: int) -> None:
    """PR-2.13: a checksummed frame of a type the manual does not define (the setup protocol among
    them) is one UNKNOWN_TYPE covering the frame, then decoding goes on."""
    frame = build_frame(kind, bytes(3))
    assert decode_all(frame + HB) == [
        Rejection(RejectReason.UNKNOWN_TYPE, len(frame), kind, 3),
        HEARTBEAT,
    ]


def test_end_recovers_a_frame_behind_a_bogus_length() -> None:
    """At the end of a capture, a header that claims more bytes than follow is one TRUNCATED
    byte and the heartbeat behind it still decodes."""
    bogus = bytes((0x10, 0x01, 0x82, 0xB7, 0xFF))
    decoder = FrameDecoder()
    assert decoder.feed(bogus + HB) == []
    assert decoder.end() == [
        Rejection(RejectReason.TRUNCATED, 1, 0x82, 0xB7),
        Rejection(RejectReason.NOISE, 4),
        HEARTBEAT,
    ]


def test_truncated_tail_is_reported_by_end() -> None:
    """A stream ending inside a frame gives a TRUNCATED event from end(), not a message."""
    decoder = FrameDecoder()
    assert decoder.feed(HB[:-1]) == []
    assert decoder.end() == [
        Rejection(RejectReason.TRUNCATED, 1, 0x20, 6),
        Rejection(RejectReason.NOISE, len(HB) - 2),
    ]


def test_trailing_header_byte_waits_for_the_next_chunk() -> None:
    """A chunk ending in 0x10 keeps that byte: it may be the first half of a header."""
    decoder = FrameDecoder()
    assert decoder.feed(b"\xee" + HB[:1]) == [Rejection(RejectReason.NOISE, 1)]
    assert decoder.feed(HB[1:]) == [HEARTBEAT]


def test_memory_stays_bounded_under_endless_partial_frames() -> None:
    """However much is fed, at most one partial frame (253 bytes) is held between calls."""
    decoder = FrameDecoder()
    almost = build_frame(0x12, bytes(248))[:-1]
    for _ in range(200):
        decoder.feed(almost)
        assert decoder.buffered <= MAX_FRAME - 1
    decoder.feed(bytes(100_000))
    assert decoder.buffered <= MAX_FRAME - 1


def test_name_string_is_nul_padded_and_read_up_to_nul() -> None:
    """PR-2.12: a label travels NUL-padded to 20 bytes and comes back without the padding."""
    frame = encode_frame(FeedbackName(90, "Hello"))
    assert frame[4:-2] == bytes((90,)) + b"Hello" + bytes(15)
    assert decode_all(frame) == [FeedbackName(90, "Hello")]


def test_gps_length_counts_the_source_byte() -> None:
    """The GPS length byte counts the source byte and the sentence (PR-2.9)."""
    frame = encode_frame(Gps(1, "$GPGGA"))
    assert frame[3] == 7
    assert decode_all(frame) == [Gps(1, "$GPGGA")]


@pytest.mark.parametrize("essential", [0x10, 0x20])
def test_encoder_refuses_to_switch_off_heartbeat_or_joystick(essential: int) -> None:
    """PR-2.11: switching off the VSC heartbeat or joystick message raises instead of sending."""
    with pytest.raises(UnsafeCommandError):
        encode_frame(MessageControl(essential, 0, 100))
    assert encode_frame(MessageControl(essential, 1, 100))  # re-timing stays allowed


@pytest.mark.parametrize(
    ("build", "message"),
    [
        (lambda: UserHeartbeat(256), "user heartbeat e-stop"),
        (lambda: VscHeartbeat(-1), "vsc mode"),
        (lambda: VscHeartbeat(9, 0, 2**32), "e-stop word"),
        (lambda: FeedbackName(1, "x" * 21), "at most 20"),
        (lambda: FeedbackName(1, "a\0b"), "without NUL"),
        (lambda: Gps(1, "\u20ac"), "single-byte"),
        (lambda: MessageControl(0x22, 1, True), "interval"),
    ],
)
def test_values_the_wire_cannot_carry_are_refused(build: object, message: str) -> None:
    """Constructing a message outside its wire ranges raises ValueError naming the field."""
    with pytest.raises(ValueError, match=message):
        build()  # type: ignore[operator]
