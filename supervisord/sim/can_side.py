"""The simulator's CAN edge: J1939 frames on any python-can interface (manual §9, PR-3).

``udp_multicast`` carries frames between processes on one machine (a channel is a multicast
group, e.g. ``239.74.163.2``); ``virtual`` only within one process, so it suits tests that
run the simulator's engine in the test process. ``socketcan`` works with a vcan or real
interface.

Bus-off: a real controller that goes bus-off stops sending, and the other nodes see error
frames first. ``bus_off(True)`` sends one error frame (every interface above carries it)
and then nothing until ``bus_off(False)``. Unplug closes the bus: the VSC is gone.
"""

from __future__ import annotations

import contextlib
from collections.abc import Iterator

import can

from supervisord.links.can_link import bus_options
from supervisord.protocol.j1939 import (
    CanFrame,
    CanRejection,
    FeedbackStringSegment,
    Hand,
    JoystickBasic,
    JoystickExtended,
    decode_can,
    encode_can,
    j1939_axis,
)
from supervisord.protocol.messages import FeedbackSet, Joystick, Message, RemoteStatus, VscHeartbeat
from supervisord.sim.faults import CanErrorFrame, Item

MAX_FRAMES_PER_RECEIVE = 256

CanReceived = FeedbackSet | FeedbackStringSegment | CanRejection


def can_frames(message: Message) -> Iterator[CanFrame]:
    """The frames that carry ``message`` on CAN; a message with no CAN form gives none (GPS,
    and feedback answers: there is no Feedback Get on CAN)."""
    if isinstance(message, VscHeartbeat | RemoteStatus):
        yield encode_can(message)
    elif isinstance(message, Joystick):
        # PR-3.2: 1022 and 1023 are J1939's error and not-available markers, so a stick at
        # full deflection (the serial 1023) goes on CAN as 1021 (docs/simulator.md).
        lx, ly, lz, rx, ry, rz = (j1939_axis(axis) for axis in message.axes)
        yield encode_can(JoystickBasic(Hand.LEFT, lx, ly, message.left_buttons))
        yield encode_can(JoystickExtended(Hand.LEFT, lz))
        yield encode_can(JoystickBasic(Hand.RIGHT, rx, ry, message.right_buttons))
        yield encode_can(JoystickExtended(Hand.RIGHT, rz))


class CanSide:
    """One python-can bus; ``interface`` and ``channel`` as python-can names them."""

    kind = "can"

    def __init__(self, interface: str, channel: str, bitrate: int = 250_000) -> None:
        self.interface, self.channel, self.bitrate = interface, channel, bitrate
        self._bus: can.BusABC | None = None
        self.is_bus_off = False
        self.send_errors = 0
        self.replug()

    @property
    def description(self) -> str:
        return f"{self.interface}:{self.channel}"

    @property
    def plugged(self) -> bool:
        return self._bus is not None

    def fileno(self) -> int | None:
        if self._bus is None:
            return None
        try:
            fd = int(self._bus.fileno())
        except NotImplementedError:
            return None  # "virtual": the loop polls instead
        return fd if fd >= 0 else None

    def receive(self) -> list[CanReceived]:
        """What the host sent: feedback values and string segments. Our own frames (an
        interface may echo them) and other nodes' traffic are not for the VSC."""
        if self._bus is None:
            return []
        out: list[CanReceived] = []
        for _ in range(MAX_FRAMES_PER_RECEIVE):
            try:
                raw = self._bus.recv(timeout=0)
            except (can.CanError, OSError):
                break
            if raw is None:
                break
            if raw.is_error_frame or raw.is_remote_frame:
                continue
            decoded = decode_can(CanFrame(raw.arbitration_id, bytes(raw.data), raw.is_extended_id))
            if isinstance(decoded, FeedbackSet | FeedbackStringSegment | CanRejection):
                out.append(decoded)
        return out

    def send(self, item: Item) -> None:
        if self._bus is None or self.is_bus_off or isinstance(item, bytes):
            return
        self._send(item)

    def _send(self, item: CanFrame | CanErrorFrame) -> None:
        assert self._bus is not None
        if isinstance(item, CanErrorFrame):
            message = can.Message(
                arbitration_id=item.classes, is_error_frame=True, is_extended_id=True
            )
        else:
            message = can.Message(
                arbitration_id=item.arbitration_id,
                data=item.data,
                is_extended_id=item.is_extended_id,
            )
        try:
            self._bus.send(message, timeout=0)
        except (can.CanError, OSError):
            self.send_errors += 1  # a full queue on a real bus: the frame is lost

    def bus_off(self, on: bool) -> None:
        """Enter bus-off (one error frame, then silence) or recover from it."""
        if on and not self.is_bus_off and self._bus is not None:
            self._send(CanErrorFrame(0x40))  # CAN_ERR_BUSOFF, as SocketCAN reports it
        self.is_bus_off = on

    def unplug(self) -> None:
        bus, self._bus = self._bus, None
        if bus is not None:
            bus.shutdown()

    def replug(self) -> None:
        self.unplug()
        options = bus_options(self.interface, self.bitrate)
        self._bus = can.Bus(interface=self.interface, channel=self.channel, **options)

    def close(self) -> None:
        with contextlib.suppress(can.CanError, OSError):
            self.unplug()
