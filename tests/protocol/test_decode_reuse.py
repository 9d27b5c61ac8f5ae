"""Decoded frames and axis words are reused (SR-9.4): the same results, bounded, still checked.

A stick at rest and a steady VSC send the same bytes again and again; the decoder keeps what
recent frames decoded to, and the axis and button decoders keep their values. These tests pin
down that reuse changes no result, keeps no unbounded state and skips no check.
"""

from __future__ import annotations

import random
import struct

import pytest

from supervisord.protocol import framing, messages
from supervisord.protocol.codes import FieldStatus
from supervisord.protocol.framing import (
    FRAMES_KEPT,
    FrameDecoder,
    Rejection,
    RejectReason,
    build_frame,
    encode_frame,
)
from supervisord.protocol.messages import (
    DECODED_KEPT,
    Axis,
    DPad,
    Joystick,
    NumberedButtons,
    VscHeartbeat,
)


def test_a_repeated_frame_decodes_as_a_fresh_decoder_decodes_it() -> None:
    """PR-1.1, SR-9.4: a frame fed again and again gives, every time, the message a decoder that
    never saw it gives; a one-bit corruption of it is still a checksum rejection."""
    frame = encode_frame(Joystick(left_y=Axis.from_value(-700), right_x=Axis.from_value(5)))
    keeper = FrameDecoder()
    for _ in range(5):
        assert keeper.feed(frame) == FrameDecoder().feed(frame)
    corrupt = bytearray(frame)
    corrupt[6] ^= 0x01
    events = keeper.feed(bytes(corrupt))
    assert events == FrameDecoder().feed(bytes(corrupt))
    assert isinstance(events[0], Rejection)
    assert events[0].reason.value == "bad_checksum"


def test_the_frames_kept_stay_bounded_whatever_arrives() -> None:
    """SR-9.4: ten times more distinct frames than the decoder keeps leave it holding at most
    ``FRAMES_KEPT`` of them, and every one decoded right."""
    decoder = FrameDecoder()
    for i in range(10 * FRAMES_KEPT):
        heartbeat = VscHeartbeat(3, 0, i)
        assert decoder.feed(encode_frame(heartbeat)) == [heartbeat]
    assert len(decoder._decoded) <= FRAMES_KEPT


def test_axis_words_are_reused_and_still_checked() -> None:
    """PR-2.1, SR-9.4: an axis word decodes to the value a fresh construction gives, the same
    word to the same value; a word over 16 bits is still refused after valid ones were kept,
    and the words kept stay bounded."""
    word = Axis.from_value(-512).to_word()
    first = Axis.from_word(word)
    assert first == Axis(FieldStatus.NOT_SET, FieldStatus.SET, FieldStatus.NOT_SET, 512)
    assert Axis.from_word(word) is first
    with pytest.raises(ValueError, match="axis magnitude"):
        Axis.from_word(0x1_0000)
    for value in range(-1023, 1024):
        assert Axis.from_word(Axis.from_value(value).to_word()).value == value
    for word in range(0, 0x1_0000, 7):
        Axis.from_word(word)
    assert len(messages._AXES_BY_WORD) <= DECODED_KEPT


def test_button_bytes_are_reused_per_class() -> None:
    """PR-2.4, SR-9.4: a button byte decodes to the same value each time, of the class asked
    for (the left pad and the numbered buttons never share a value)."""
    left, right = DPad.from_byte(0b01_00_00_01), NumberedButtons.from_byte(0b01_00_00_01)
    assert DPad.from_byte(0b01_00_00_01) is left
    assert isinstance(left, DPad)
    assert isinstance(right, NumberedButtons)
    assert left.pressed == frozenset({"down", "left"})
    assert right.pressed == frozenset({"button_1", "button_4"})


def test_a_steady_heartbeat_is_decoded_once_between_moving_sticks(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    """SR-9.4: a VSC heartbeat that repeats exactly is decoded once, however many distinct
    joystick frames (a moving stick, more than ``FRAMES_KEPT``) arrive between two of them,
    and each read still gives what a fresh decoder gives; a corrupt repeat is still refused."""
    decodes: list[bytes] = []
    decode = framing._decode_frame

    def counted(frame: bytes) -> framing.Decoded:
        decodes.append(frame)
        return decode(frame)

    beat = encode_frame(VscHeartbeat(9, 0, 0))
    # One read a turn: a heartbeat and a joystick frame, and what a fresh decoder makes of it.
    reads = [
        beat + encode_frame(Joystick(left_x=Axis.from_value(i - 500)))
        for i in range(3 * FRAMES_KEPT)
    ]
    fresh = [FrameDecoder().feed(read) for read in reads]
    monkeypatch.setattr(framing, "_decode_frame", counted)
    decoder = FrameDecoder()
    assert [decoder.feed(read) for read in reads] == fresh
    assert decodes.count(beat) == 1
    corrupt = bytearray(beat)
    corrupt[5] ^= 0x01
    events = decoder.feed(bytes(corrupt))
    assert isinstance(events[0], Rejection)
    assert events[0].reason.value == "bad_checksum"


def test_the_joystick_path_decodes_as_the_validating_constructor() -> None:
    """PR-1.1, PR-2.1, SR-9.4: every moving-stick frame takes the joystick's own checked path;
    for random words and button bytes it gives the value ``Joystick``'s validating constructor
    gives, of the same types, and a frame with any one byte corrupted gets exactly the general
    path's rejection."""
    rng = random.Random(7)
    decoder = FrameDecoder()
    for _ in range(2000):
        words = [rng.randrange(0x1_0000) for _ in range(6)]
        left, right = rng.randrange(256), rng.randrange(256)
        frame = build_frame(0x10, struct.pack("<6HBB", *words, left, right))
        lx, ly, lz, rx, ry, rz = (Axis.from_word(word) for word in words)
        expected = Joystick(
            lx, ly, lz, rx, ry, rz, DPad.from_byte(left), NumberedButtons.from_byte(right)
        )
        (event,) = decoder.feed(frame)
        assert type(event) is Joystick
        assert event == expected
        assert [type(axis) for axis in event.axes] == [Axis] * 6
        assert type(event.left_buttons) is DPad
        assert type(event.right_buttons) is NumberedButtons
        corrupt = bytearray(frame)
        corrupt[rng.randrange(4, len(frame))] ^= 1 << rng.randrange(8)
        primed = FrameDecoder()  # its last joystick frame is the good one
        assert primed.feed(frame) == [expected]
        got = primed.feed(bytes(corrupt))
        assert got == FrameDecoder().feed(bytes(corrupt))
        assert got[0] == framing._decode_frame(bytes(corrupt))
        assert isinstance(got[0], Rejection)
        assert got[0].reason is RejectReason.BAD_CHECKSUM
