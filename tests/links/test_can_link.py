"""The CAN link over python-can's real interfaces: virtual in one process, udp_multicast
between processes' sockets."""

from __future__ import annotations

import os
import socket
import time
from collections.abc import Iterator

import can
import pytest

from supervisord.links.base import LinkBrokenError
from supervisord.links.can_link import CanLink, from_python_can, to_python_can
from supervisord.protocol.j1939 import (
    FeedbackStringSegment,
    Hand,
    JoystickBasic,
    decode_can,
    encode_can,
)
from supervisord.protocol.messages import (
    Axis,
    DPad,
    FeedbackName,
    FeedbackSet,
    Joystick,
    UserHeartbeat,
    VscHeartbeat,
)


@pytest.fixture
def vsc_bus() -> Iterator[can.BusABC]:
    with can.Bus(interface="virtual", channel="link-test") as bus:
        yield bus


@pytest.fixture
def link(vsc_bus: can.BusABC) -> Iterator[CanLink]:
    link = CanLink("virtual", "link-test", 250_000)
    link.open()
    yield link
    link.close()


def test_heartbeat_and_joystick_arrive_decoded(vsc_bus: can.BusABC, link: CanLink) -> None:
    """A heartbeat frame and a basic joystick frame from the VSC become a VscHeartbeat and a
    whole Joystick."""
    vsc_bus.send(to_python_can(encode_can(VscHeartbeat(9))))
    basic = JoystickBasic(Hand.LEFT, Axis.from_value(300), Axis.from_value(-5), DPad())
    vsc_bus.send(to_python_can(encode_can(basic)))
    received = []
    for _ in range(100):
        received += link.receive()
        if len(received) == 2:
            break
    assert received[0] == VscHeartbeat(9)
    assert isinstance(received[1], Joystick)
    assert (received[1].left_x.value, received[1].left_y.value) == (300, -5)


def error_frame(class_bits: int = 0x08, data: bytes = bytes(8)) -> can.Message:
    """A SocketCAN error frame: the class in the identifier (0x08 protocol violation,
    0x04 controller problem, 0x40 bus-off), details in the data (linux/can/error.h)."""
    return can.Message(arbitration_id=class_bits, data=data, is_error_frame=True)


def drain(link: CanLink) -> list[object]:
    received: list[object] = []
    for _ in range(20):
        received += link.receive()
    return received


def test_an_isolated_error_frame_is_counted_and_stops_nothing(
    vsc_bus: can.BusABC, link: CanLink
) -> None:
    """SR-2.12: one error frame among good traffic is counted, and the heartbeat after it still
    arrives: CAN retransmits the frame itself (docs/safety.md "CAN error frames")."""
    vsc_bus.send(error_frame())
    vsc_bus.send(to_python_can(encode_can(VscHeartbeat(9))))
    assert drain(link) == [VscHeartbeat(9)]
    assert link.error_frames == 1


def test_errors_below_the_limit_in_a_window_stop_nothing(vsc_bus: can.BusABC) -> None:
    """As many error frames as the limit within the window are counted, never a fault."""
    link = CanLink("virtual", "link-test", 250_000, error_limit=16, error_window_ms=1000)
    link.open()
    try:
        for _ in range(16):
            vsc_bus.send(error_frame())
        drain(link)
        assert link.error_frames == 16
    finally:
        link.close()


def test_errors_above_the_limit_in_a_window_break_the_link(vsc_bus: can.BusABC) -> None:
    """One error frame more than the limit within the window is a transport fault."""
    link = CanLink("virtual", "link-test", 250_000, error_limit=16, error_window_ms=1000)
    link.open()
    try:
        for _ in range(17):
            vsc_bus.send(error_frame())
        with pytest.raises(LinkBrokenError, match="17 CAN error frames"):
            drain(link)
    finally:
        link.close()


def test_bus_off_breaks_the_link_at_once(vsc_bus: can.BusABC, link: CanLink) -> None:
    """An error frame that reports bus-off is a transport fault at the first one."""
    vsc_bus.send(error_frame(0x40))
    with pytest.raises(LinkBrokenError, match="bus-off"):
        drain(link)


def test_error_passive_for_too_long_breaks_the_link(vsc_bus: can.BusABC) -> None:
    """A controller that reports error-passive and is not back to error-active within the
    configured time breaks the link; one back in time does not."""
    link = CanLink("virtual", "link-test", 250_000, error_passive_ms=50)
    link.open()
    try:
        passive, active = bytes([0, 0x10, 0, 0, 0, 0, 0, 0]), bytes([0, 0x40, 0, 0, 0, 0, 0, 0])
        vsc_bus.send(error_frame(0x04, passive))
        drain(link)
        vsc_bus.send(error_frame(0x04, active))
        drain(link)
        time.sleep(0.08)
        vsc_bus.send(to_python_can(encode_can(VscHeartbeat(9))))
        assert drain(link) == [VscHeartbeat(9)]  # back to active in time: nothing stops
        vsc_bus.send(error_frame(0x04, passive))
        drain(link)
        time.sleep(0.08)
        vsc_bus.send(to_python_can(encode_can(VscHeartbeat(9))))
        with pytest.raises(LinkBrokenError, match="error-passive"):
            drain(link)
    finally:
        link.close()


def test_send_has_only_feedback_on_can(vsc_bus: can.BusABC, link: CanLink) -> None:
    """PR-3.3: feedback values go as one frame and labels as three segments; a user heartbeat has no
    CAN form and is not sent (PR-3)."""
    link.send([UserHeartbeat(0), FeedbackSet(1, 42), FeedbackName(90, "Hello CAN world!")])
    frames = []
    while (raw := vsc_bus.recv(timeout=0.5)) is not None:
        frames.append(decode_can(from_python_can(raw)))
    assert frames == [
        FeedbackSet(1, 42),
        FeedbackStringSegment(90, 0, "Hello "),
        FeedbackStringSegment(90, 1, "CAN wo"),
        FeedbackStringSegment(90, 2, "rld!"),
    ]


@pytest.mark.usefixtures("private_network")
def test_virtual_bus_has_no_descriptor_udp_multicast_has_one() -> None:
    """The loop can wait on udp_multicast's socket; the in-process virtual bus has none."""
    virtual = CanLink("virtual", "fd-test", 250_000)
    virtual.open()
    try:
        assert virtual.fileno() is None
    finally:
        virtual.close()
    udp = CanLink("udp_multicast", "239.74.163.2", 250_000)
    udp.open()
    try:
        assert isinstance(udp.fileno(), int)
        assert udp.description == "CAN udp_multicast:239.74.163.2"
    finally:
        udp.close()


@pytest.mark.usefixtures("private_network")
def test_udp_multicast_frames_never_leave_the_machine() -> None:
    """udp_multicast is CAN between processes of one machine: its socket sends with a
    multicast TTL of 0, which Linux delivers locally and puts on no interface."""
    udp = CanLink("udp_multicast", "239.74.163.2", 250_000)
    udp.open()
    try:
        fd = udp.fileno()
        assert fd is not None
        with socket.socket(fileno=os.dup(fd)) as view:
            assert view.getsockopt(socket.IPPROTO_IP, socket.IP_MULTICAST_TTL) == 0
    finally:
        udp.close()
