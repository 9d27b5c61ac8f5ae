"""The CAN messages of manual §9 and PR-3, also carried over a real python-can bus."""

from __future__ import annotations

import can
import pytest

from supervisord.protocol.codes import FieldStatus, VscMode
from supervisord.protocol.j1939 import (
    CanFrame,
    CanId,
    CanMessage,
    CanRejection,
    CanRejectReason,
    FeedbackStringSegment,
    Hand,
    JoystickAssembler,
    JoystickBasic,
    JoystickExtended,
    decode_can,
    encode_can,
    feedback_string_frames,
    j1939_axis,
    j1939_value,
)
from supervisord.protocol.messages import Axis, DPad, FeedbackSet, NumberedButtons, VscHeartbeat


def test_heartbeat_frame_layout() -> None:
    """PR-3.1: the CAN heartbeat carries the serial heartbeat's 6 bytes at id 0x0CFDE801,
    FF-padded."""
    frame = encode_can(VscHeartbeat(VscMode.LOCAL, 0, 1))
    assert frame == CanFrame(0x0CFDE801, bytes.fromhex("04 00 01 00 00 00 FF FF"))


def test_left_basic_joystick_layout() -> None:
    """PR-3.1: x in bytes 0-1, Y in 2-3, byte 4 unused, left buttons in byte 5 (manual table 24)."""
    message = JoystickBasic(
        Hand.LEFT, Axis.from_value(512), Axis.from_value(0), DPad(up=FieldStatus.SET)
    )
    frame = encode_can(message)
    assert frame == CanFrame(CanId.LEFT_BASIC, bytes.fromhex("10 80 01 00 FF 10 FF FF"))
    assert decode_can(frame) == message


def test_feedback_value_layout() -> None:
    """PR-3.1: the feedback value message is key then i32 little-endian, FF-padded (table 29)."""
    frame = encode_can(FeedbackSet(85, 1))
    assert frame == CanFrame(0x0CFDE900, bytes.fromhex("55 01 00 00 00 FF FF FF"))


def test_eighteen_character_string_goes_as_three_segments() -> None:
    """An 18-character feedback string is three 6-character segments 0, 1, 2 (manual §9.2.7)."""
    frames = feedback_string_frames(1, "Battery voltage V")
    assert [decode_can(frame) for frame in frames] == [
        FeedbackStringSegment(1, 0, "Batter"),
        FeedbackStringSegment(1, 1, "y volt"),
        FeedbackStringSegment(1, 2, "age V"),
    ]
    assert all(frame.arbitration_id == CanId.FEEDBACK_STRING for frame in frames)
    with pytest.raises(ValueError, match="at most 18"):
        feedback_string_frames(1, "x" * 19)


def test_priority_bits_are_ignored() -> None:
    """A heartbeat sent at another J1939 priority is still the heartbeat."""
    frame = CanFrame(0x18FDE801, bytes.fromhex("09 00 00 00 00 00 FF FF"))
    assert decode_can(frame) == VscHeartbeat(9)


@pytest.mark.parametrize(
    ("frame", "reason"),
    [
        (CanFrame(0x0CFDE801, bytes(5)), CanRejectReason.WRONG_LENGTH),
        (CanFrame(0x0CFDD733, bytes(1)), CanRejectReason.WRONG_LENGTH),
        (CanFrame(0x0CFDE802, bytes(8)), CanRejectReason.UNKNOWN_ID),
        (CanFrame(0x123, bytes(8), is_extended_id=False), CanRejectReason.STANDARD_ID),
        (CanFrame(0x0CFDEA00, bytes((1, 3)) + b"abcdef"), CanRejectReason.BAD_VALUE),
    ],
)
def test_rejections(frame: CanFrame, reason: CanRejectReason) -> None:
    """Short frames, unknown ids, 11-bit ids and impossible segments are rejected, typed."""
    assert decode_can(frame) == CanRejection(reason, frame.arbitration_id, len(frame.data))


@pytest.mark.parametrize("magnitude", [1022, 1023])
@pytest.mark.parametrize(
    "statuses",
    [
        (FieldStatus.NOT_SET, FieldStatus.NOT_SET, FieldStatus.SET),
        (FieldStatus.SET, FieldStatus.NOT_SET, FieldStatus.NOT_SET),
    ],
    ids=["positive", "neutral"],
)
def test_j1939_error_magnitudes_make_the_axis_invalid(
    magnitude: int, statuses: tuple[FieldStatus, FieldStatus, FieldStatus]
) -> None:
    """PR-3.2: on CAN, magnitudes 1022/1023 mean error / not available: no value, whatever
    the statuses say (even neutral set)."""
    axis = Axis(*statuses, magnitude)
    decoded = decode_can(CanFrame(CanId.RIGHT_EXTENDED, axis.to_word().to_bytes(2, "little")))
    assert isinstance(decoded, JoystickExtended)
    assert decoded.z == axis  # the frame's view keeps the bits as sent
    assert j1939_value(decoded.z) is None


def test_j1939_magnitudes_up_to_1021_are_deflections() -> None:
    """PR-3.2: below the reserved pair a CAN magnitude is a deflection, as on serial."""
    assert j1939_value(Axis.from_value(1021)) == 1021
    assert j1939_value(Axis.from_value(-1021)) == -1021
    assert j1939_value(Axis.from_value(0)) == 0
    assert j1939_value(Axis(FieldStatus.ERROR, FieldStatus.ERROR, FieldStatus.ERROR, 5)) is None


@pytest.mark.parametrize(
    ("magnitude", "status"), [(1022, FieldStatus.ERROR), (1023, FieldStatus.NOT_AVAILABLE)]
)
def test_assembled_joystick_carries_the_reserved_meaning(
    magnitude: int, status: FieldStatus
) -> None:
    """PR-3.2: the serial Joystick the CAN link assembles reads a reserved magnitude as the
    error or not-available status, so every reader of ``Axis.value`` sees no value."""
    assembler = JoystickAssembler()
    joystick = assembler.update(
        JoystickBasic(Hand.LEFT, Axis.from_value(magnitude), Axis.from_value(-5), DPad())
    )
    assert joystick.left_x.value is None
    assert joystick.left_x == Axis(status, status, status, magnitude)
    assert joystick.left_y.value == -5


def test_j1939_axis_never_sends_a_reserved_magnitude_as_a_deflection() -> None:
    """PR-3.2: a deflection past 1021 goes on CAN as 1021 (the nearest value that is not a
    marker); the error and not-available markers and smaller deflections go unchanged."""
    for value in range(-1023, 1024):
        sent = j1939_axis(Axis.from_value(value))
        assert j1939_value(sent) == max(-1021, min(1021, value))
    marker = Axis(FieldStatus.ERROR, FieldStatus.ERROR, FieldStatus.ERROR, 1022)
    assert j1939_axis(marker) == marker


def test_right_hand_must_carry_numbered_buttons() -> None:
    """A basic joystick message pairs the right hand with buttons 1-4, never a D-pad."""
    with pytest.raises(ValueError, match="NumberedButtons"):
        JoystickBasic(Hand.RIGHT, Axis.from_value(0), Axis.from_value(0), DPad())
    assert JoystickBasic(Hand.RIGHT, Axis.from_value(0), Axis.from_value(0), NumberedButtons())


def test_frames_cross_a_real_python_can_bus() -> None:
    """Encoded frames sent through python-can's virtual interface decode on the other end."""
    sent: list[CanMessage] = [
        VscHeartbeat(9),
        JoystickExtended(Hand.LEFT, Axis.from_value(-300)),
        FeedbackSet(99, 1),
    ]
    with (
        can.Bus(interface="virtual", channel="srcs-test", receive_own_messages=False) as tx,
        can.Bus(interface="virtual", channel="srcs-test") as rx,
    ):
        for message in sent:
            frame = encode_can(message)
            tx.send(
                can.Message(
                    arbitration_id=frame.arbitration_id, data=frame.data, is_extended_id=True
                )
            )
        received = []
        for _ in sent:
            raw = rx.recv(timeout=1.0)
            assert raw is not None
            received.append(
                decode_can(CanFrame(raw.arbitration_id, bytes(raw.data), raw.is_extended_id))
            )
    assert received == sent


def test_assembler_joins_the_four_joystick_messages() -> None:
    """Basic and extended messages of both hands combine into one Joystick value."""
    assembler = JoystickAssembler()
    first = assembler.update(
        JoystickBasic(
            Hand.RIGHT,
            Axis.from_value(7),
            Axis.from_value(-8),
            NumberedButtons(button_2=FieldStatus.SET),
        )
    )
    assert first.right_x.value == 7
    assert first.left_x == Axis.from_value(0)
    joined = assembler.update(JoystickExtended(Hand.LEFT, Axis.from_value(100)))
    assert [axis.value for axis in joined.axes] == [0, 0, 100, 7, -8, 0]
    assert joined.right_buttons.pressed == {"button_2"}
