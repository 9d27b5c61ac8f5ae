"""HRI packet framing over serial (manual §8.2, PR-1), without any I/O.

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
from supervisord.protocol.payload import (
    FIXED_LENGTH,
    decode_joystick,
    decode_payload,
    encode_payload,
    payload_length_ok,
)

HEADER = b"\x10\x01"  # the manual's "uint16 0x1001", sent as 10 01 (PR-1)
HEADER_SIZE = 4  # header, type, length
CHECKSUM_SIZE = 2
MAX_PAYLOAD = 248  # PR-1: the largest payload any peer accepts
MAX_FRAME = HEADER_SIZE + MAX_PAYLOAD + CHECKSUM_SIZE
FRAMES_KEPT = 64
"""How many recent frames a decoder keeps with what they decoded to. Decoding is a pure
function of a frame's bytes, and most frames repeat exactly (every heartbeat of a steady
state, every joystick frame of a stick at rest): a repeat costs one lookup instead of the
checksum and the decode (SR-9.4). Starts over when full, so it stays a few kilobytes."""
# Never switched off by us: without them the supervisor would be blind (manual §8.3.6 note).
ESSENTIAL_TYPES = frozenset({MessageType.VSC_HEARTBEAT, MessageType.JOYSTICK})


class RejectReason(enum.Enum):
    """Why bytes did not become a message."""

    BAD_CHECKSUM = "bad_checksum"  # the candidate frame's checksum did not match
    BAD_LENGTH = "bad_length"  # the length byte is over 248: no peer sends that
    WRONG_LENGTH = "wrong_length"  # a known type with a length byte it never has
    UNKNOWN_TYPE = "unknown_type"  # a checksummed frame of a type the manual does not define
    NOISE = "noise"  # bytes outside any frame, before the next header
    TRUNCATED = "truncated"  # the stream ended inside this frame (only from ``end``)


@dataclass(frozen=True, slots=True)
class Rejection:
    """Bytes that were not a valid message; ``byte_count`` says how many were consumed.

    Unless the frame's checksum held (an unknown type), only the first header byte is
    consumed: the decoder looks for the next header one byte on (PR-1), so a corrupt
    length byte cannot swallow the good frames behind it.
    """

    reason: RejectReason
    byte_count: int
    message_type: int | None = None
    length: int | None = None
    detail: str = ""


Decoded = Message | Rejection
"""What the decoder yields for each frame or run of noise: a message, or why bytes were not one."""


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
        self._decoded: dict[bytes, Decoded] = {}  # FRAMES_KEPT recent frames, decoded
        # The last frame of each type byte and what it decoded to: a steady heartbeat is found
        # here whatever the moving joystick frames between two of them did to ``_decoded``.
        self._last: list[tuple[bytes, Decoded] | None] = [None] * 256

    def feed(self, data: bytes | bytearray | memoryview) -> list[Decoded]:
        """Take ``data`` and return the events it completes, in stream order."""
        buf = self._buffer
        buf += data
        events: list[Decoded] = []
        # Whole frames first, then the general loop from where they stopped (SR-9.4).
        pos = self._whole_frames(buf, events)
        if pos == len(buf) and not self._noise:
            del buf[:pos]  # the usual read: whole frames only, a call fewer
            return events
        return self._parse(events, pos, final=False)

    def end(self) -> list[Decoded]:
        """Close the stream. Each header whose frame never completed is one TRUNCATED event
        (one byte), and the bytes behind it are scanned again, so a frame hidden behind a
        bogus length byte still comes out."""
        events: list[Decoded] = []
        return self._parse(events, self._whole_frames(self._buffer, events), final=True)

    def _parse(self, events: list[Decoded], pos: int, *, final: bool) -> list[Decoded]:
        """The general loop, from ``pos`` (where the whole frames in ``events`` ended)."""
        buf = self._buffer
        end = len(buf)
        if pos == end and not self._noise:
            del buf[:pos]
            return events
        while pos < end:
            start = buf.find(HEADER, pos)
            if start < 0:
                # A last 0x10 may be the first half of a header: keep it unless the stream ended.
                keep = 1 if not final and buf[end - 1] == HEADER[0] else 0
                self._noise += end - keep - pos
                pos = end - keep
                break
            self._noise += start - pos
            pos = start
            rejection: Rejection | None = None
            frame_end = pos + HEADER_SIZE
            if end - pos < HEADER_SIZE:
                if not final:
                    break
                rejection = Rejection(RejectReason.TRUNCATED, 1)
            else:
                message_type, length = buf[pos + 2], buf[pos + 3]
                rejection = _header_rejection(message_type, length)
                frame_end += length + CHECKSUM_SIZE
                if rejection is None and end < frame_end:
                    if not final:
                        break
                    rejection = Rejection(RejectReason.TRUNCATED, 1, message_type, length)
            self._take_noise(events)
            event = rejection or self._decode(bytes(buf[pos:frame_end]))
            events.append(event)
            pos += event.byte_count if isinstance(event, Rejection) else frame_end - pos
        del buf[:pos]
        self._take_noise(events)
        return events

    def _whole_frames(self, buf: bytearray, events: list[Decoded]) -> int:
        """The usual read (SR-9.4): whole frames of fixed-length types, one after another from
        the start of the buffer, no noise. Each costs a table lookup and, for the last frame of
        its type again, one comparison; else one copy and :meth:`_decode`. Appends what it
        decoded to ``events`` and returns where the general loop of :meth:`_parse` goes on."""
        pos, end = 0, len(buf)
        lengths, last = _FRAME_LENGTHS, self._last
        while end - pos >= HEADER_SIZE and buf[pos] == 0x10 and buf[pos + 1] == 0x01:
            kind = buf[pos + 2]
            frame_end = pos + lengths[kind]
            if frame_end != pos + HEADER_SIZE + buf[pos + 3] + CHECKSUM_SIZE or frame_end > end:
                break  # a variable length (GPS), an unknown type, a wrong length, or a part
            repeat = last[kind]
            if repeat is not None and buf.startswith(repeat[0], pos):
                event = repeat[1]  # the last frame of its type again: compared, not copied
            elif kind == _JOYSTICK_TYPE:
                # A moving stick: a new frame 50 times a second, checked and decoded by
                # the joystick's own path (no dispatch, no recent frames' churn).
                frame = bytes(buf[pos:frame_end])
                event = _decode_joystick_frame(frame)
                last[kind] = (frame, event)
            else:
                frame = bytes(buf[pos:frame_end])
                event = self._decode(frame)  # the recent frames' dictionary, or the decode
                last[kind] = (frame, event)
            events.append(event)
            if type(event) is Rejection:
                pos += event.byte_count
                break
            pos = frame_end
        return pos

    def _decode(self, frame: bytes) -> Decoded:
        decoded = self._decoded
        event = decoded.get(frame)
        if event is None:
            event = _decode_frame(frame)
            if len(decoded) >= FRAMES_KEPT:
                decoded.clear()
            decoded[frame] = event
        return event

    @property
    def buffered(self) -> int:
        """Bytes held for a frame not yet complete (at most ``MAX_FRAME - 1``)."""
        return len(self._buffer)

    def _take_noise(self, events: list[Decoded]) -> None:
        if self._noise:
            events.append(Rejection(RejectReason.NOISE, self._noise))
            self._noise = 0


_FRAME_LENGTHS: tuple[int, ...] = tuple(
    HEADER_SIZE + FIXED_LENGTH[known] + CHECKSUM_SIZE
    if (known := MessageType.parse(value)) is not None and known in FIXED_LENGTH
    else 0
    for value in range(256)
)
"""The whole frame's length for each type byte of a fixed-length type (0 for GPS, whose
length varies, and for the types without a name): the fast path's header check."""


_JOYSTICK_TYPE = int(MessageType.JOYSTICK)
_JOYSTICK_END = HEADER_SIZE + FIXED_LENGTH[MessageType.JOYSTICK]  # where its checksum starts


def _decode_joystick_frame(frame: bytes) -> Decoded:
    """A whole joystick frame whose header, type and length byte the caller has checked
    (``_FRAME_LENGTHS``): its checksum here, then the payload. A checksum that does not match
    takes :func:`_decode_frame`, so a bad frame gets exactly the general path's rejection
    ("only a checked frame counts", PR-1)."""
    if frame[_JOYSTICK_END] | frame[_JOYSTICK_END + 1] << 8 != fletcher16(frame[:_JOYSTICK_END]):
        return _decode_frame(frame)
    return decode_joystick(frame, HEADER_SIZE)


def _header_rejection(message_type: int, length: int) -> Rejection | None:
    """A rejection decided by the header alone, so the decoder never waits for bytes that a
    corrupt length byte claims: a length over 248, or a known type's impossible length."""
    if length > MAX_PAYLOAD:
        return Rejection(RejectReason.BAD_LENGTH, 1, message_type, length, "over 248")
    known = MessageType.parse(message_type)
    if known is not None and not payload_length_ok(known, length):
        return Rejection(RejectReason.WRONG_LENGTH, 1, message_type, length)
    return None


def _decode_frame(frame: bytes) -> Decoded:
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
    return decode_payload(known, frame[HEADER_SIZE:-CHECKSUM_SIZE])
