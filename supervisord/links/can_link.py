"""The CAN link: J1939 frames through any python-can interface (manual §9, PR-3).

There is no user heartbeat on CAN: the VSC cannot watch the host, so the supervisor's own
outputs carry that duty alone (SR-5). Failed sends, bus-off, a sustained rate
of error frames and a controller error-passive for too long are link faults; an isolated
error frame is counted and stops nothing (SR-2.12; docs/safety.md "CAN error frames").
"""

from __future__ import annotations

import logging
import time
from collections import deque
from collections.abc import Mapping
from typing import Any

import can

from supervisord.links.base import Incoming, Link, LinkBrokenError, LinkError
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
from supervisord.timebase import NS_PER_MS, NS_PER_S

MAX_FRAMES_PER_RECEIVE = 256  # a flood must not starve the loop's other duties
ERROR_LIMIT = 16
"""docs/safety.md "CAN error frames": more than this many error frames within
``ERROR_WINDOW_MS`` break the link. CAN's fault confinement adds 8 to a node's error counter
per error and takes 1 per good frame; 16 errors with no good frame between are 128, the
error-passive threshold. Fewer errors than that cannot make any node error-passive."""
ERROR_WINDOW_MS = 1000
ERROR_PASSIVE_MS = 1000
"""A controller that reports error-passive (counter >= 128) and not error-active again
within this long breaks the link: errors outnumber good frames 1 to 8 for that long."""
ERROR_LOG_NS = NS_PER_S  # isolated error frames are logged as a count, once a second
# SocketCAN error classes (linux/can/error.h): in the identifier, details in data[1].
CAN_ERR_CRTL, CAN_ERR_BUSOFF = 0x04, 0x40
CAN_ERR_CRTL_PASSIVE, CAN_ERR_CRTL_ACTIVE = 0x10 | 0x20, 0x40  # RX/TX passive; back to active

log = logging.getLogger("srcsd")
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
        self,
        interface: str,
        channel: str,
        bitrate: int,
        options: Mapping[str, Any] | None = None,
        *,
        error_limit: int = ERROR_LIMIT,
        error_window_ms: int = ERROR_WINDOW_MS,
        error_passive_ms: int = ERROR_PASSIVE_MS,
    ) -> None:
        self._interface, self._channel, self._bitrate = interface, channel, bitrate
        self._options = dict(options or {})
        self._bus: can.BusABC | None = None
        self._joystick = JoystickAssembler()
        self._error_limit = error_limit
        self._error_window_ns = error_window_ms * NS_PER_MS
        self._error_passive_ns = error_passive_ms * NS_PER_MS
        self._recent: deque[int] = deque()  # times of the error frames within the window
        self._passive_since: int | None = None
        self.error_frames = 0
        """Error frames seen since start (for ``status``; isolated ones stop nothing)."""
        self._unlogged = 0
        self._next_log = 0

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
        self._recent.clear()
        self._passive_since = None

    def fileno(self) -> int | None:
        if self._bus is None:
            return None
        try:
            return int(self._bus.fileno())
        except NotImplementedError:
            return None  # e.g. the in-process "virtual" interface

    def receive(self) -> list[Incoming]:
        bus = self._require_open()
        received: list[Incoming] = []
        for _ in range(MAX_FRAMES_PER_RECEIVE):
            try:
                raw = bus.recv(timeout=0)
            except (can.CanError, OSError) as error:
                raise LinkBrokenError(str(error) or "receive failed") from error
            if raw is None:
                break
            now = time.monotonic_ns()
            if raw.is_error_frame:
                self._error_frame(raw, now)
                continue
            if self._passive_since is not None and now - self._passive_since >= (
                self._error_passive_ns
            ):
                raise LinkBrokenError(
                    f"CAN controller error-passive for {self._error_passive_ns // NS_PER_MS} ms"
                )
            decoded = decode_can(from_python_can(raw))
            if isinstance(decoded, JoystickBasic | JoystickExtended):
                received.append(self._joystick.update(decoded))
            elif not isinstance(decoded, FeedbackStringSegment):  # only ever sent to the VSC
                received.append(decoded)
        return received

    def _error_frame(self, raw: can.Message, now: int) -> None:
        """Count an error frame; raise ``LinkBrokenError`` for bus-off, a sustained rate, or an
        error-passive controller for too long (docs/safety.md "CAN error frames")."""
        self.error_frames += 1
        classes = raw.arbitration_id
        detail = raw.data[1] if len(raw.data) > 1 else 0
        if classes & CAN_ERR_BUSOFF:
            raise LinkBrokenError("CAN bus-off")
        if classes & CAN_ERR_CRTL:
            if detail & CAN_ERR_CRTL_ACTIVE:
                self._passive_since = None
            elif detail & CAN_ERR_CRTL_PASSIVE and self._passive_since is None:
                self._passive_since = now
        if self._passive_since is not None and now - self._passive_since >= (
            self._error_passive_ns
        ):
            raise LinkBrokenError(
                f"CAN controller error-passive for {self._error_passive_ns // NS_PER_MS} ms"
            )
        recent = self._recent
        recent.append(now)
        while now - recent[0] >= self._error_window_ns:
            recent.popleft()
        if len(recent) > self._error_limit:
            raise LinkBrokenError(
                f"{len(recent)} CAN error frames within {self._error_window_ns // NS_PER_MS} ms"
            )
        self._unlogged += 1
        if now >= self._next_log:  # counted and logged, at most a line a second
            log.warning(
                "%s: %d CAN error frame(s) (%d since start; the bus retransmits, nothing stops)",
                self.description,
                self._unlogged,
                self.error_frames,
            )
            self._unlogged, self._next_log = 0, now + ERROR_LOG_NS

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
                    raise LinkBrokenError(str(error) or "send failed") from error

    def close(self) -> None:
        bus, self._bus = self._bus, None
        if bus is not None:
            bus.shutdown()

    def _require_open(self) -> can.BusABC:
        if self._bus is None:
            raise LinkBrokenError("not open")
        return self._bus
