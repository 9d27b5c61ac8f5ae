"""The HRI packet messages (manual §8.3) as immutable values that validate their wire ranges.

Every field holds what the wire carries: a peer may send a mode, key or status this code has
no name for, and the safety logic must still see it (an unknown mode is a fault, not an error
that hides the frame). Constructing a value that the wire cannot carry raises ``ValueError``.
Multi-byte fields are little-endian on the wire (PR-1).
"""

from __future__ import annotations

from dataclasses import dataclass, fields
from typing import TYPE_CHECKING, ClassVar

from supervisord.protocol.codes import (
    AutonomyMode,
    EstopSource,
    FeedbackKey,
    FieldStatus,
    MessageType,
    StringKey,
    VscMode,
    estop_sources,
)
from supervisord.protocol.nmea import GpsFix, parse_nmea

if TYPE_CHECKING:
    from typing_extensions import Self

U8 = (0, 0xFF)
U16 = (0, 0xFFFF)
U32 = (0, 0xFFFF_FFFF)
I32 = (-(2**31), 2**31 - 1)
AXIS_MAGNITUDE_MAX = 1023
_STATUS = tuple(FieldStatus)  # index by the 2-bit value: much faster than FieldStatus(v)
DECODED_KEPT = 4096
"""How many decoded axis words are kept for reuse (SR-9.4: a stick at rest sends the same
word in every frame, 50 a second). Values are immutable, so the same one can come back; the
store starts over when full, so it stays small (a few hundred kilobytes) whatever arrives."""
NAME_TEXT_LENGTH = 20  # manual §8.3.10: 20 bytes, NUL-padded


def check_range(name: str, value: int, bounds: tuple[int, int]) -> None:
    """Raise ``ValueError`` naming the field unless ``value`` is an int within ``bounds``."""
    low, high = bounds
    if isinstance(value, bool) or not isinstance(value, int) or not low <= value <= high:
        raise ValueError(f"{name} must be an integer in {low}..{high}, not {value!r}")


def check_text(name: str, text: str, max_length: int) -> None:
    """Raise ``ValueError`` unless ``text`` fits ``max_length`` single-byte characters, no NUL.

    Text travels as Latin-1 so that every byte value round-trips; NUL ends a string on the
    VSC, so a NUL inside the text could not come back out.
    """
    if not isinstance(text, str) or len(text) > max_length:
        raise ValueError(f"{name} must be text of at most {max_length} characters: {text!r}")
    if "\0" in text or any(ord(ch) > 0xFF for ch in text):
        raise ValueError(f"{name} must be single-byte characters without NUL: {text!r}")


@dataclass(frozen=True, slots=True)
class Axis:
    """One joystick axis word (manual table 19, PR-2.1, PR-2.2).

    Byte 0 holds the neutral, negative and positive status in bits 0-1, 2-3, 4-5 and the two
    low magnitude bits in 6-7; byte 1 holds the eight high magnitude bits.
    """

    neutral: FieldStatus
    negative: FieldStatus
    positive: FieldStatus
    magnitude: int

    def __post_init__(self) -> None:
        for name in ("neutral", "negative", "positive"):
            if not isinstance(getattr(self, name), FieldStatus):
                raise ValueError(f"axis {name} must be a FieldStatus")
        check_range("axis magnitude", self.magnitude, (0, AXIS_MAGNITUDE_MAX))

    @property
    def value(self) -> int | None:
        """The signed deflection -1023..1023, or ``None`` when the statuses make it invalid.

        Neutral set wins, then negative, then positive; any other combination (error, not
        available, nothing set) is invalid, which the safety logic treats as zero and a fault.
        """
        if self.neutral is FieldStatus.SET:
            return 0
        if self.negative is FieldStatus.SET:
            return -self.magnitude
        if self.positive is FieldStatus.SET:
            return self.magnitude
        return None

    @classmethod
    def from_value(cls, value: int) -> Self:
        """The axis word a healthy remote sends for a deflection of ``value``."""
        check_range("axis value", value, (-AXIS_MAGNITUDE_MAX, AXIS_MAGNITUDE_MAX))
        on, off = FieldStatus.SET, FieldStatus.NOT_SET
        if value == 0:
            return cls(on, off, off, 0)
        if value < 0:
            return cls(off, on, off, -value)
        return cls(off, off, on, value)

    @classmethod
    def from_word(cls, word: int) -> Axis:
        """The axis in a 16-bit wire word (the same value for the same word, see
        :data:`DECODED_KEPT`); ``ValueError`` for a word over 16 bits."""
        axis = _AXES_BY_WORD.get(word)
        if axis is None:
            low, high = word & 0xFF, word >> 8
            axis = cls(
                _STATUS[low & 3], _STATUS[low >> 2 & 3], _STATUS[low >> 4 & 3], high << 2 | low >> 6
            )
            if len(_AXES_BY_WORD) >= DECODED_KEPT:
                _AXES_BY_WORD.clear()
            _AXES_BY_WORD[word] = axis
        return axis

    def to_word(self) -> int:
        low = self.neutral | self.negative << 2 | self.positive << 4 | (self.magnitude & 3) << 6
        return (self.magnitude >> 2) << 8 | low


_AXES_BY_WORD: dict[int, Axis] = {}
NEUTRAL_AXIS = Axis.from_value(0)


class _ButtonByte:
    """Four 2-bit button statuses in one byte, the first field in bits 0-1 (manual table 21).

    A button is pressed only when its status is SET; ERROR and NOT_AVAILABLE are not pressed.
    """

    __slots__ = ()

    def __post_init__(self) -> None:
        for f in fields(self):  # type: ignore[arg-type]
            if not isinstance(getattr(self, f.name), FieldStatus):
                raise ValueError(f"button {f.name} must be a FieldStatus")

    @classmethod
    def from_byte(cls, byte: int) -> Self:
        """The buttons in one wire byte; the same immutable value for the same byte (at most
        256 per class are kept, SR-9.4)."""
        key = (cls, byte)
        buttons = _BUTTONS_BY_BYTE.get(key)
        if buttons is None:
            statuses = _STATUS[byte & 3], _STATUS[byte >> 2 & 3], _STATUS[byte >> 4 & 3]
            # The subclasses are dataclasses of exactly four statuses in wire order.
            buttons = cls(*statuses, _STATUS[byte >> 6])  # type: ignore[call-arg]
            _BUTTONS_BY_BYTE[key] = buttons
        assert isinstance(buttons, cls)
        return buttons

    def to_byte(self) -> int:
        return sum(
            getattr(self, f.name) << 2 * i
            for i, f in enumerate(fields(self))  # type: ignore[arg-type]
        )

    @property
    def pressed(self) -> frozenset[str]:
        """The names of the buttons whose status is SET."""
        return frozenset(
            f.name
            for f in fields(self)  # type: ignore[arg-type]
            if getattr(self, f.name) is FieldStatus.SET
        )


_BUTTONS_BY_BYTE: dict[tuple[type[_ButtonByte], int], _ButtonByte] = {}
_UP = FieldStatus.NOT_SET


@dataclass(frozen=True, slots=True)
class DPad(_ButtonByte):
    """The left hand's four-way pad, in wire order (manual table 21)."""

    down: FieldStatus = _UP
    right: FieldStatus = _UP
    up: FieldStatus = _UP
    left: FieldStatus = _UP


@dataclass(frozen=True, slots=True)
class NumberedButtons(_ButtonByte):
    """The right hand's buttons 1-4, in wire order (PR-2.4)."""

    button_1: FieldStatus = _UP
    button_2: FieldStatus = _UP
    button_3: FieldStatus = _UP
    button_4: FieldStatus = _UP


@dataclass(frozen=True, slots=True)
class Joystick:
    """0x10, from the VSC: six axes and both button bytes (manual §8.3.1, 14 bytes).

    The VSC zeroes all of it outside Operational mode (manual §6).
    """

    TYPE: ClassVar[MessageType] = MessageType.JOYSTICK

    left_x: Axis = NEUTRAL_AXIS
    left_y: Axis = NEUTRAL_AXIS
    left_z: Axis = NEUTRAL_AXIS
    right_x: Axis = NEUTRAL_AXIS
    right_y: Axis = NEUTRAL_AXIS
    right_z: Axis = NEUTRAL_AXIS
    left_buttons: DPad = DPad()
    right_buttons: NumberedButtons = NumberedButtons()

    AXES: ClassVar[tuple[str, ...]] = (
        "left_x",
        "left_y",
        "left_z",
        "right_x",
        "right_y",
        "right_z",
    )

    def __post_init__(self) -> None:
        # One expression for the common case (every frame, SR-9.4); the loop names the culprit.
        axes: tuple[object, ...] = (
            self.left_x,
            self.left_y,
            self.left_z,
            self.right_x,
            self.right_y,
            self.right_z,
        )
        if not (
            isinstance(axes[0], Axis)
            and isinstance(axes[1], Axis)
            and isinstance(axes[2], Axis)
            and isinstance(axes[3], Axis)
            and isinstance(axes[4], Axis)
            and isinstance(axes[5], Axis)
        ):
            for name in self.AXES:
                if not isinstance(getattr(self, name), Axis):
                    raise ValueError(f"joystick {name} must be an Axis")
        if not isinstance(self.left_buttons, DPad):
            raise ValueError("joystick left_buttons must be a DPad")
        if not isinstance(self.right_buttons, NumberedButtons):
            raise ValueError("joystick right_buttons must be NumberedButtons")

    @property
    def axes(self) -> tuple[Axis, ...]:
        return tuple(getattr(self, name) for name in self.AXES)


@dataclass(frozen=True, slots=True)
class Gps:
    """0x12, from the VSC: a source byte (1 = the remote) and one NMEA sentence (manual §8.3.2).

    ``sentence`` is the text as sent, Latin-1 decoded so every byte round-trips.
    """

    TYPE: ClassVar[MessageType] = MessageType.GPS
    SOURCE_REMOTE: ClassVar[int] = 1

    source: int
    sentence: str

    def __post_init__(self) -> None:
        check_range("gps source", self.source, U8)
        if not isinstance(self.sentence, str) or any(ord(ch) > 0xFF for ch in self.sentence):
            raise ValueError("gps sentence must be single-byte text")
        if len(self.sentence) > 247:  # the length byte counts the source byte too
            raise ValueError("gps sentence must be at most 247 characters")

    @property
    def fix(self) -> GpsFix | None:
        """The sentence parsed (UTC time, position, fix quality), or ``None`` if unreadable."""
        return parse_nmea(self.sentence)


@dataclass(frozen=True, slots=True)
class VscHeartbeat:
    """0x20, from the VSC: mode, autonomy mode, e-stop word (manual §8.3.3, 6 bytes).

    Any non-zero e-stop word is a stop, including bits without a name (PR-2).
    """

    TYPE: ClassVar[MessageType] = MessageType.VSC_HEARTBEAT

    mode: int
    autonomy_mode: int = AutonomyMode.USER
    estop: int = 0

    def __post_init__(self) -> None:
        check_range("vsc mode", self.mode, U8)
        check_range("autonomy mode", self.autonomy_mode, U8)
        check_range("e-stop word", self.estop, U32)

    @property
    def known_mode(self) -> VscMode | None:
        return VscMode.parse(self.mode)

    @property
    def estop_sources(self) -> frozenset[EstopSource]:
        return estop_sources(self.estop)


@dataclass(frozen=True, slots=True)
class UserHeartbeat:
    """0x21, to the VSC: the user computer's e-stop byte, 0 = OK (manual §8.3.5)."""

    TYPE: ClassVar[MessageType] = MessageType.USER_HEARTBEAT

    estop: int = 0

    def __post_init__(self) -> None:
        check_range("user heartbeat e-stop", self.estop, U8)


@dataclass(frozen=True, slots=True)
class RemoteStatus:
    """0x22, from the VSC, 1 Hz when enabled (manual §8.3.4, 6 bytes).

    The VSC does not clear these when the remote link drops: the heartbeat's mode says
    whether a remote is linked.
    """

    TYPE: ClassVar[MessageType] = MessageType.REMOTE_STATUS

    battery_level: int
    battery_charging: int = 0
    connection_strength_vsc: int = 0
    connection_strength_src: int = 0
    rssi_vsc: int = 0
    rssi_src: int = 0

    def __post_init__(self) -> None:
        for f in fields(self):
            check_range(f.name, getattr(self, f.name), U8)


@dataclass(frozen=True, slots=True)
class MessageControl:
    """0x23, to the VSC: switch a VSC message on or off and set its interval (manual §8.3.6).

    Stored permanently by the VSC. The encoder refuses to switch off the heartbeat or the
    joystick message (a note in manual §8.3.6, PR-2.11; a supervisor must never blind itself).
    """

    TYPE: ClassVar[MessageType] = MessageType.MESSAGE_CONTROL

    message_type: int
    enabled: int
    interval: int

    def __post_init__(self) -> None:
        check_range("message type", self.message_type, U8)
        check_range("enabled", self.enabled, U8)
        check_range("interval", self.interval, U16)


@dataclass(frozen=True, slots=True)
class FeedbackSet:
    """0x30, both directions: a feedback key and its signed 32-bit value (manual §8.3.7/8.3.9).

    The VSC sends it when a value is edited on the remote and in answer to ``FeedbackGet``.
    """

    TYPE: ClassVar[MessageType] = MessageType.FEEDBACK_SET

    key: int
    value: int

    def __post_init__(self) -> None:
        check_range("feedback key", self.key, U8)
        check_range("feedback value", self.value, I32)

    @property
    def known_key(self) -> FeedbackKey | None:
        """The key's name; ``None`` for a user value (``USER_VALUE_KEYS``) or an unknown key."""
        return FeedbackKey.parse(self.key)


@dataclass(frozen=True, slots=True)
class FeedbackName:
    """0x31, to the VSC: a label (keys 1-9) or a text row (keys 90-93) of 20 characters
    (manual §8.3.10). Sent NUL-padded; received text ends at the first NUL.
    """

    TYPE: ClassVar[MessageType] = MessageType.FEEDBACK_NAME

    key: int
    text: str

    def __post_init__(self) -> None:
        check_range("feedback name key", self.key, U8)
        check_text("feedback name text", self.text, NAME_TEXT_LENGTH)

    @property
    def known_key(self) -> StringKey | None:
        """The key's name; ``None`` for a user value's label (``USER_VALUE_KEYS``) or an
        unknown key."""
        return StringKey.parse(self.key)


@dataclass(frozen=True, slots=True)
class FeedbackGet:
    """0x32, to the VSC: ask for a key's value; the VSC answers with ``FeedbackSet``.

    Manual §8.3.8; PR-2.8.
    """

    TYPE: ClassVar[MessageType] = MessageType.FEEDBACK_GET

    key: int

    def __post_init__(self) -> None:
        check_range("feedback key", self.key, U8)

    @property
    def known_key(self) -> FeedbackKey | None:
        """The key's name; ``None`` for a user value (``USER_VALUE_KEYS``) or an unknown key."""
        return FeedbackKey.parse(self.key)


Message = (
    Joystick
    | Gps
    | VscHeartbeat
    | UserHeartbeat
    | RemoteStatus
    | MessageControl
    | FeedbackSet
    | FeedbackName
    | FeedbackGet
)
