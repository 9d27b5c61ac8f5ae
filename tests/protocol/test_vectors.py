"""The test vectors of PR-1.8, each encoded, and decoded whole, byte by byte,
and followed by garbage."""

from __future__ import annotations

import pytest

from supervisord.protocol.checksum import fletcher16
from supervisord.protocol.codes import EstopSource, FieldStatus, VscMode
from supervisord.protocol.framing import FrameDecoder, Rejection, RejectReason, encode_frame
from supervisord.protocol.messages import (
    Axis,
    DPad,
    FeedbackGet,
    FeedbackSet,
    Joystick,
    Message,
    MessageControl,
    NumberedButtons,
    RemoteStatus,
    UserHeartbeat,
    VscHeartbeat,
)

SET = FieldStatus.SET
VECTORS: list[tuple[str, Message, str]] = [
    ("user heartbeat, no e-stop", UserHeartbeat(0), "10 01 21 01 00 33 B9"),
    ("user heartbeat, e-stop", UserHeartbeat(1), "10 01 21 01 01 34 BA"),
    ("feedback get key 85", FeedbackGet(85), "10 01 32 01 55 99 41"),
    ("feedback set key 85 = 1", FeedbackSet(85, 1), "10 01 30 05 55 01 00 00 00 9C B3"),
    ("feedback set key 99 = 1", FeedbackSet(99, 1), "10 01 30 05 63 01 00 00 00 AA F9"),
    (
        "message control 0x22 on every 1000 ms",
        MessageControl(0x22, 1, 1000),
        "10 01 23 04 22 01 E8 03 46 CB",
    ),
    (
        "VSC heartbeat operational",
        VscHeartbeat(VscMode.OPERATIONAL, 0, 0),
        "10 01 20 06 09 00 00 00 00 00 40 09",
    ),
    (
        "VSC heartbeat local, remote e-stop",
        VscHeartbeat(VscMode.LOCAL, 0, 1),
        "10 01 20 06 04 00 01 00 00 00 3C EF",
    ),
    (
        "remote status 80 %",
        RemoteStatus(80, 0, 2, 2, 0, 0),
        "10 01 22 06 50 00 02 02 00 00 8D D1",
    ),
    (
        "joystick LX +512, RX -1023, left up, right button 1",
        Joystick(
            left_x=Axis.from_value(512),
            right_x=Axis.from_value(-1023),
            left_buttons=DPad(up=SET),
            right_buttons=NumberedButtons(button_1=SET),
        ),
        "10 01 10 0E 10 80 01 00 01 00 C4 FF 01 00 01 00 10 01 97 BD",
    ),
]
IDS = [name for name, _, _ in VECTORS]
GARBAGE = bytes.fromhex("FF 00 10 10 01 FE 55")


@pytest.mark.parametrize(("name", "message", "wire"), VECTORS, ids=IDS)
def test_encode_gives_the_vector(name: str, message: Message, wire: str) -> None:
    """PR-1.1 to PR-1.4: encoding the message gives exactly the bytes of the vector (PR-1.8)."""
    assert encode_frame(message) == bytes.fromhex(wire), name


@pytest.mark.parametrize(("name", "message", "wire"), VECTORS, ids=IDS)
def test_checksum_is_the_manuals_algorithm(name: str, message: Message, wire: str) -> None:
    """PR-1.3: the last two bytes are sum1 then sum2 of the manual's Fletcher-16 over all before
    them."""
    frame = bytes.fromhex(wire)
    assert fletcher16(frame[:-2]) == frame[-1] << 8 | frame[-2], name


@pytest.mark.parametrize(("name", "message", "wire"), VECTORS, ids=IDS)
def test_decode_whole(name: str, message: Message, wire: str) -> None:
    """The vector fed in one piece decodes to exactly the message, nothing else."""
    decoder = FrameDecoder()
    assert decoder.feed(bytes.fromhex(wire)) == [message], name
    assert decoder.end() == []


@pytest.mark.parametrize(("name", "message", "wire"), VECTORS, ids=IDS)
def test_decode_byte_by_byte(name: str, message: Message, wire: str) -> None:
    """Fed one byte at a time, only the last byte completes the message."""
    decoder = FrameDecoder()
    data = bytes.fromhex(wire)
    events = [decoder.feed(data[i : i + 1]) for i in range(len(data))]
    assert events[:-1] == [[]] * (len(data) - 1), name
    assert events[-1] == [message]


@pytest.mark.parametrize(("name", "message", "wire"), VECTORS, ids=IDS)
def test_decode_followed_by_garbage(name: str, message: Message, wire: str) -> None:
    """Garbage after the frame leaves the message intact and is reported as noise/truncation."""
    decoder = FrameDecoder()
    events = decoder.feed(bytes.fromhex(wire) + GARBAGE) + decoder.end()
    assert events[0] == message, name
    assert all(isinstance(event, Rejection) for event in events[1:])
    assert sum(event.byte_count for event in events[1:] if isinstance(event, Rejection)) == len(
        GARBAGE
    )


def test_vsc_heartbeat_names_the_remote_source() -> None:
    """PR-2.5, PR-2.6: the 'remote e-stop bit' vector decodes to an e-stop whose named source is the
    remote."""
    (heartbeat,) = FrameDecoder().feed(bytes.fromhex("10 01 20 06 04 00 01 00 00 00 3C EF"))
    assert isinstance(heartbeat, VscHeartbeat)
    assert heartbeat.known_mode is VscMode.LOCAL
    assert heartbeat.estop_sources == {EstopSource.REMOTE}


def test_joystick_vector_values() -> None:
    """PR-2.1 to PR-2.4: the joystick vector reads as LX +512, RX -1023, others 0, left Up and right
    button 1."""
    wire = "10 01 10 0E 10 80 01 00 01 00 C4 FF 01 00 01 00 10 01 97 BD"
    (joystick,) = FrameDecoder().feed(bytes.fromhex(wire))
    assert isinstance(joystick, Joystick)
    assert [axis.value for axis in joystick.axes] == [512, 0, 0, -1023, 0, 0]
    assert joystick.left_buttons.pressed == {"up"}
    assert joystick.right_buttons.pressed == {"button_1"}


def test_noise_before_a_frame_is_one_event() -> None:
    """Bytes before a header are one noise event counting them, then the frame."""
    events = FrameDecoder().feed(b"\xaa\xbb\xcc" + encode_frame(UserHeartbeat(0)))
    assert events == [Rejection(RejectReason.NOISE, 3), UserHeartbeat(0)]
