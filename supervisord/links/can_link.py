"""The CAN link: J1939 frames through any python-can interface (manual §9, notes §3).

There is no user heartbeat on CAN: the VSC cannot watch the host, so the supervisor's own
outputs carry that duty alone (safety-rules.md §5). Error frames and failed sends are link
faults (bus-off shows as both).
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

import can

from supervisord.links.base import Link, LinkBroken, LinkError, Received
from supervisord.protocol.j1939 import (
    CanFrame,
    FeedbackStringSegment,
    JoystickAssembler,
    JoystickBasic,
    JoystickExtended,
    decode_can,
    encode_can,
    feedback_string_frames,
)
from supervisord.protocol.messages import FeedbackName, FeedbackSet, Message

MAX_FRAMES_PER_RECEIVE = 256  # a flood must not starve the loop's other duties
UDP_MULTICAST_HOP_LIMIT = 0  # frames reach this machine's sockets and no network (below)


def bus_options(interface: str, bitrate: int) -> dict[str, Any]:
    """The python-can options every bus of this project opens with, by interface.

    ``socketcan`` takes the bitrate. ``udp_multicast`` is CAN between processes of one
    machine, never a network: with a hop limit of 0, Linux delivers a frame to the local
    sockets that joined its group and sends it on no interface (python-can's default of 1
    put every frame on the machine's network segment). Joining the group still announces
    itself on the default interface, so outside a private network namespace it is not
    silent: ``docs/testing.md`` "Network".
    """
    if interface == "socketcan":
        return {"bitrate": bitrate}
    if interface == "udp_multicast":
        return {"hop_limit": UDP_MULTICAST_HOP_LIMIT}
    return {}


def to_python_can(frame: CanFrame) -> can.Message:
    return can.Message(
        arbitration_id=frame.arbitration_id, data=frame.data, is_extended_id=frame.is_extended_id
    )


def from_python_can(message: can.Message) -> CanFrame:
    """python-can's frame as ours. Its timestamp is wall-clock and is ignored on purpose."""
    return CanFrame(message.arbitration_id, bytes(message.data), message.is_extended_id)


class CanLink(Link):
    """One python-can bus to the VSC."""

    def __init__(
        self, interface: str, channel: str, bitrate: int, options: Mapping[str, Any] | None = None
    ) -> None:
        self._interface, self._channel, self._bitrate = interface, channel, bitrate
        self._options = dict(options or {})
        self._bus: can.BusABC | None = None
        self._joystick = JoystickAssembler()

    @property
    def description(self) -> str:
        return f"CAN {self._interface}:{self._channel}"

    @property
    def is_open(self) -> bool:
        return self._bus is not None

    @property
    def bus(self) -> can.BusABC | None:
        """The open bus, shared with CAN enable outputs configured on the same bus."""
        return self._bus

    def open(self) -> None:
        if self._bus is not None:
            return
        options = bus_options(self._interface, self._bitrate) | self._options
        try:
            self._bus = can.Bus(interface=self._interface, channel=self._channel, **options)
        except (can.CanError, OSError, ValueError, ImportError) as error:
            raise LinkError(str(error) or type(error).__name__) from error
        self._joystick = JoystickAssembler()

    def fileno(self) -> int | None:
        if self._bus is None:
            return None
        try:
            return int(self._bus.fileno())
        except NotImplementedError:
            return None  # e.g. the in-process "virtual" interface

    def receive(self) -> list[Received]:
        bus = self._require_open()
        received: list[Received] = []
        for _ in range(MAX_FRAMES_PER_RECEIVE):
            try:
                raw = bus.recv(timeout=0)
            except (can.CanError, OSError) as error:
                raise LinkBroken(str(error) or "receive failed") from error
            if raw is None:
                break
            if raw.is_error_frame:
                raise LinkBroken("CAN error frame (bus error or bus-off)")
            decoded = decode_can(from_python_can(raw))
            if isinstance(decoded, JoystickBasic | JoystickExtended):
                received.append(self._joystick.update(decoded))
            elif not isinstance(decoded, FeedbackStringSegment):  # only ever sent to the VSC
                received.append(decoded)
        return received

    def send(self, messages: list[Message]) -> None:
        """Send what has a CAN form (feedback values and strings); a heartbeat, key query or
        message control has none on CAN and is skipped."""
        bus = self._require_open()
        for message in messages:
            if isinstance(message, FeedbackSet):
                frames: tuple[CanFrame, ...] = (encode_can(message),)
            elif isinstance(message, FeedbackName):
                frames = feedback_string_frames(message.key, message.text[:18])
            else:
                continue
            for frame in frames:
                try:
                    bus.send(to_python_can(frame), timeout=0)
                except (can.CanError, OSError) as error:
                    raise LinkBroken(str(error) or "send failed") from error

    def close(self) -> None:
        bus, self._bus = self._bus, None
        if bus is not None:
            bus.shutdown()

    def _require_open(self) -> can.BusABC:
        if self._bus is None:
            raise LinkBroken("not open")
        return self._bus
