"""The closed vocabularies of the SRCS protocol: every wire code the manual names, as enums.

Fields that arrive from a peer keep their raw integer (a VSC may send a mode or key this
module does not know); each enum's ``parse`` turns a raw value into a member or ``None``.
Section numbers refer to the user manual (``srcs-user-manual.txt``), IDs ``PR-N.M`` to the
protocol requirements of ``docs/requirements.md``; ``docs/protocol.md`` collects both.
"""

from __future__ import annotations

import enum
from typing import TYPE_CHECKING, Final

from supervisord.compat import IntEnum

if TYPE_CHECKING:
    from typing_extensions import Self


class _Parsable(IntEnum):
    @classmethod
    def parse(cls, value: int) -> Self | None:
        """The member for ``value``, or ``None`` when the value has no name."""
        # The enum's own value table: one lookup instead of ``cls(value)`` and a ValueError
        # for every unnamed value (called for every frame, SR-9.4).
        member = cls._value2member_map_.get(value)
        return member if isinstance(member, cls) else None


class MessageType(_Parsable):
    """HRI packet message types (manual §8.3, table 5)."""

    JOYSTICK = 0x10
    GPS = 0x12
    VSC_HEARTBEAT = 0x20
    USER_HEARTBEAT = 0x21
    REMOTE_STATUS = 0x22
    MESSAGE_CONTROL = 0x23
    FEEDBACK_SET = 0x30
    FEEDBACK_NAME = 0x31
    FEEDBACK_GET = 0x32


class VscMode(_Parsable):
    """VSC modes (manual §6 table 1, PR-2.7). Only OPERATIONAL allows motion."""

    SEARCHING = 0x01
    LOCAL = 0x04
    REMOTE = 0x06  # newer firmware: linked, not yet operational
    OPERATIONAL = 0x09
    MENU = 0x0A
    PAUSE = 0x0B


class AutonomyMode(_Parsable):
    """Autonomy mode byte of the VSC heartbeat (manual §8.3.3)."""

    USER = 0
    SHARED = 1
    AUTONOMOUS = 2


class FieldStatus(_Parsable):
    """The 2-bit status of a joystick direction or a button (manual tables 20/22, PR-2).

    The manual prints these as ``0x00 0x01 0x10 0x11``; they are binary, so ERROR is 2.
    """

    NOT_SET = 0
    SET = 1
    ERROR = 2
    NOT_AVAILABLE = 3


class EstopSource(enum.Enum):
    """Named sources of the VSC heartbeat's e-stop word (PR-2.5, PR-2.6)."""

    REMOTE = "remote"  # bits 0-1: the remote's button, the remote off, or out of range
    WIRED = "wired"  # bits 2-3: the VSC's wired e-stop input
    USER = "user"  # bits 6-7: the user computer's software e-stop (0x21, or key 85 timeout)
    UNKNOWN = "unknown"  # any other bit: still a stop, only without a name


ESTOP_SOURCE_MASKS: tuple[tuple[EstopSource, int], ...] = (
    (EstopSource.REMOTE, 0b0000_0011),
    (EstopSource.WIRED, 0b0000_1100),
    (EstopSource.USER, 0b1100_0000),
)
ESTOP_KNOWN_BITS = 0b1100_1111


def estop_sources(word: int) -> frozenset[EstopSource]:
    """The named sources of a non-zero e-stop word; empty for 0 (no e-stop)."""
    found = {source for source, mask in ESTOP_SOURCE_MASKS if word & mask}
    if word & ~ESTOP_KNOWN_BITS:
        found.add(EstopSource.UNKNOWN)
    return frozenset(found)


USER_VALUE_KEYS: Final = range(1, 10)
"""Keys 1-9 of both key tables (manual tables 13 and 18): the nine user values, named
``user_value_N``. They are kept apart from the two enums below, which name only the keys
each table has alone, so that the shared keys have one definition (PR-2)."""


def user_value_name(key: int) -> str | None:
    """``user_value_N`` for a user-value key, else ``None``."""
    return f"user_value_{key}" if key in USER_VALUE_KEYS else None


class FeedbackKey(_Parsable):
    """Keys of the User Feedback Set/Get messages (manual table 13, PR-2), beyond the user
    values (``USER_VALUE_KEYS``).

    The manual prints key 81 twice; the second one (inactivity pause enable) is 84.
    """

    VIBRATE_LEFT = 10
    VIBRATE_RIGHT = 11
    VIBRATE_BOTH = 12
    INACTIVITY_PAUSE_MINUTES = 80
    AUTO_OFF_ENABLE = 81
    ORIENTATION_PAUSE_ENABLE = 82
    FREE_FALL_PAUSE_ENABLE = 83
    INACTIVITY_PAUSE_ENABLE = 84
    USER_ESTOP_TIMEOUT = 85  # the VSC's watchdog on our heartbeat; stored permanently
    DISPLAY_MODE = 99


class StringKey(_Parsable):
    """Keys of the User Feedback Name String message (manual table 18), beyond the user
    values' labels (``USER_VALUE_KEYS``)."""

    TEXT_ROW_1 = 90
    TEXT_ROW_2 = 91
    TEXT_ROW_3 = 92
    TEXT_ROW_4 = 93


class DisplayMode(_Parsable):
    """Values of feedback key 99 (manual §6.5 and table 13)."""

    GPS = 0
    TEXT_ROWS = 1
    LABELLED_VALUES = 2
    VALUES = 3
