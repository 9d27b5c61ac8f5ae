"""Hypothesis strategies for every protocol value, over the full range the wire can carry."""

from __future__ import annotations

from hypothesis import strategies as st

from supervisord.protocol.codes import FieldStatus
from supervisord.protocol.hid import HidInput, HidOutput
from supervisord.protocol.j1939 import (
    CanMessage,
    FeedbackStringSegment,
    Hand,
    JoystickBasic,
    JoystickExtended,
)
from supervisord.protocol.messages import (
    Axis,
    DPad,
    FeedbackGet,
    FeedbackName,
    FeedbackSet,
    Gps,
    Joystick,
    Message,
    MessageControl,
    NumberedButtons,
    RemoteStatus,
    UserHeartbeat,
    VscHeartbeat,
)

u8 = st.integers(0, 0xFF)
u16 = st.integers(0, 0xFFFF)
u32 = st.integers(0, 0xFFFF_FFFF)
i32 = st.integers(-(2**31), 2**31 - 1)
status = st.sampled_from(FieldStatus)


def text(max_size: int) -> st.SearchStrategy[str]:
    """Single-byte text without NUL, as the wire's strings carry."""
    return st.text(st.characters(min_codepoint=1, max_codepoint=0xFF), max_size=max_size)


axes = st.builds(Axis, status, status, status, st.integers(0, 1023))
dpads = st.builds(DPad, status, status, status, status)
numbered = st.builds(NumberedButtons, status, status, status, status)

messages: st.SearchStrategy[Message] = st.one_of(
    st.builds(Joystick, axes, axes, axes, axes, axes, axes, dpads, numbered),
    st.builds(Gps, u8, st.text(st.characters(min_codepoint=0, max_codepoint=0xFF), max_size=247)),
    st.builds(VscHeartbeat, u8, u8, u32),
    st.builds(UserHeartbeat, u8),
    st.builds(RemoteStatus, u8, u8, u8, u8, u8, u8),
    st.builds(MessageControl, u8.filter(lambda t: t not in (0x10, 0x20)), u8, u16),
    st.builds(FeedbackSet, u8, i32),
    st.builds(FeedbackName, u8, text(20)),
    st.builds(FeedbackGet, u8),
)

can_messages: st.SearchStrategy[CanMessage] = st.one_of(
    st.builds(JoystickBasic, st.just(Hand.LEFT), axes, axes, dpads),
    st.builds(JoystickBasic, st.just(Hand.RIGHT), axes, axes, numbered),
    st.builds(JoystickExtended, st.sampled_from(Hand), axes),
    st.builds(VscHeartbeat, u8, u8, u32),
    st.builds(RemoteStatus, u8, u8, u8, u8, u8, u8),
    st.builds(FeedbackSet, u8, i32),
    st.builds(FeedbackStringSegment, u8, st.integers(0, 2), text(6)),
)

hid_inputs = st.builds(
    HidInput,
    *(st.integers(-128, 127) for _ in range(6)),
    st.integers(0, 15),
    st.integers(0, 15),
    u8,
    u8,
)
hid_outputs = st.builds(HidOutput, u8, i32, u8, text(20))
