"""HRI packet framing over serial (manual §8.2, notes §1), without any I/O.

``encode_frame`` turns a message into wire bytes. ``FrameDecoder`` is fed bytes in any
chunking and returns, in order, the messages found and a ``Rejection`` for everything else.
It keeps at most one partial frame (253 bytes) between calls, whatever it is fed.
"""

from __future__ import annotations

import enum
from dataclasses import dataclass

from supervisord.errors import UnsafeCommandError
from supervisord.protocol.checksum import fletcher16
from supervisord.protocol.codes import MessageType
from supervisord.protocol.messages import Message, MessageControl
from supervisord.protocol.payload import decode_payload, encode_payload, payload_length_ok

HEADER = b"\x10\x01"  # the manual's "uint16 0x1001", sent as 10 01 (notes §1)
HEADER_SIZE = 4  # header, type, length
CHECKSUM_SIZE = 2
MAX_PAYLOAD = 248  # notes §1: the largest payload any peer accepts
MAX_FRAME = HEADER_SIZE + MAX_PAYLOAD + CHECKSUM_SIZE
# Never switched off by us: without them the supervisor would be blind (manual §8.3.6 note).
ESSENTIAL_TYPES = frozenset({MessageType.VSC_HEARTBEAT, MessageType.JOYSTICK})


class RejectReason(enum.Enum):
    """Why bytes did not become a message."""

    BAD_CHECKSUM = "bad_checksum"  # the candidate frame's checksum did not match
    BAD_LENGTH = "bad_length"  # the length byte is over 248: no peer sends that
    WRONG_LENGTH = "wrong_length"  # a checksummed frame of a known type, wrong payload length
    UNKNOWN_TYPE = "unknown_type"  # a checksummed frame of a type the manual does not define
    NOISE = "noise"  # bytes outside any frame, before the next header
    TRUNCATED = "truncated"  # the stream ended inside a frame (only from ``end``)


@dataclass(frozen=True, slots=True)
class Rejection:
    """Bytes that were not a valid message; ``byte_count`` says how many were consumed.

    After a bad checksum or a bad length only the first header byte is consumed: the decoder
    looks for the next header one byte on (notes §1), so a corrupt length byte cannot swallow
    the good frames behind it.
    """

    reason: RejectReason
    byte_count: int
    message_type: int | None = None
    length: int | None = None
    detail: str = ""


Event = Message | Rejection


def build_frame(message_type: int, payload: bytes) -> bytes:
    """A frame with a correct checksum around any type and payload (also for fault tests)."""
    if not 0 <= message_type <= 0xFF or len(payload) > 0xFF:
        raise ValueError("type and payload length must each fit one byte")
    head = HEADER + bytes((message_type, len(payload))) + payload
    checksum = fletcher16(head)
    return head + bytes((checksum & 0xFF, checksum >> 8))


def encode_frame(message: Message) -> bytes:
    """The wire bytes of ``message``.

    Raises ``UnsafeCommandError`` for a ``MessageControl`` that would switch off the VSC
    heartbeat or joystick message.
    """
    if (
        isinstance(message, MessageControl)
        and message.message_type in ESSENTIAL_TYPES
        and not message.enabled
    ):
        name = MessageType(message.message_type).name.lower()
        raise UnsafeCommandError(f"refusing to switch off the VSC's {name} message")
    return build_frame(message.TYPE, encode_payload(message))


class FrameDecoder:
    """Incremental, total decoder of a serial byte stream.

    ``feed`` never raises on any input. Noise is reported at the end of each ``feed`` so a
    wrong baud rate shows at once; two chunkings of the same stream give the same events
    except that a run of noise may be split differently.
    """

    def __init__(self) -> None:
        self._buffer = bytearray()
        self._noise = 0

    def feed(self, data: bytes | bytearray | memoryview) -> list[Event]:
        """Take ``data`` and return the events it completes, in stream order."""
        buf = self._buffer
        buf += data
        events: list[Event] = []
        pos, end = 0, len(buf)
        while True:
            start = buf.find(HEADER, pos)
            if start < 0:
                # A last 0x10 may be the first half of a header: keep it.
                keep = 1 if end > pos and buf[end - 1] == HEADER[0] else 0
                self._noise += end - keep - pos
                pos = end - keep
                break
            self._noise += start - pos
            pos = start
            if end - pos < HEADER_SIZE:
                break
            message_type, length = buf[pos + 2], buf[pos + 3]
            if length > MAX_PAYLOAD:
                self._take_noise(events)
                events.append(
                    Rejection(RejectReason.BAD_LENGTH, 1, message_type, length, "over 248")
                )
                pos += 1
                continue
            frame_end = pos + HEADER_SIZE + length + CHECKSUM_SIZE
            if end < frame_end:
                break
            self._take_noise(events)
            event = _decode_frame(bytes(buf[pos:frame_end]))
            events.append(event)
            pos += event.byte_count if isinstance(event, Rejection) else frame_end - pos
        del buf[:pos]
        self._take_noise(events)
        return events

    def end(self) -> list[Event]:
        """Close the stream: a partial frame left in the buffer becomes a TRUNCATED event."""
        events: list[Event] = []
        if self._buffer:
            head = self._buffer
            events.append(
                Rejection(
                    RejectReason.TRUNCATED,
                    len(head),
                    head[2] if len(head) > 2 else None,
                    head[3] if len(head) > 3 else None,
                )
            )
            self._buffer = bytearray()
        return events

    @property
    def buffered(self) -> int:
        """Bytes held for a frame not yet complete (at most ``MAX_FRAME - 1``)."""
        return len(self._buffer)

    def _take_noise(self, events: list[Event]) -> None:
        if self._noise:
            events.append(Rejection(RejectReason.NOISE, self._noise))
            self._noise = 0


def _decode_frame(frame: bytes) -> Event:
    """One candidate frame whose length byte fits the bytes given."""
    message_type, length = frame[2], frame[3]
    received = frame[-2] | frame[-1] << 8
    computed = fletcher16(frame[:-2])
    if received != computed:
        detail = f"received {received:#06x}, computed {computed:#06x}"
        return Rejection(RejectReason.BAD_CHECKSUM, 1, message_type, length, detail)
    known = MessageType.parse(message_type)
    if known is None:
        return Rejection(RejectReason.UNKNOWN_TYPE, len(frame), message_type, length)
    if not payload_length_ok(known, length):
        return Rejection(RejectReason.WRONG_LENGTH, len(frame), message_type, length)
    return decode_payload(known, frame[HEADER_SIZE:-CHECKSUM_SIZE])
