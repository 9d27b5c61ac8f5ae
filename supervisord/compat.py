"""Names newer than Python 3.10, for the modules that the client library (and so the ROS 2
bridge) imports: a ROS installation brings its own Python, 3.10 on Humble to 3.14 on Lyrical
(docs/ros2.md "Python versions"). The daemon runs on 3.10 to 3.14 too (docs/install.md).

Pure: the safety core imports it (``tests/safety/test_purity.py``)."""

from __future__ import annotations

import datetime as dt
import enum
import re


class StrEnum(str, enum.Enum):
    """What Python 3.11's ``enum.StrEnum`` does for explicit values: a member is its value
    wherever it is used as text (``str()``, f-strings, JSON)."""

    def __str__(self) -> str:
        return str(self.value)

    def __format__(self, spec: str) -> str:
        return str(self.value).__format__(spec)


class IntEnum(enum.IntEnum):
    """What Python 3.11's ``enum.IntEnum`` does: a member is its number wherever it is used as
    text, ``str()`` as well as f-strings. On 3.10 ``str()`` gives ``MessageType.JOYSTICK``,
    which a file written there (the simulator's EEPROM) cannot be read back from."""

    def __str__(self) -> str:
        return int.__repr__(self)

    def __format__(self, spec: str) -> str:
        return int.__format__(int(self), spec)


def from_iso(text: str) -> dt.datetime:
    """``datetime.fromisoformat`` with the UTC designator ``Z`` that people type and Python
    3.11 reads (``2026-11-24T14:02Z``); 3.10 takes only an offset, so ``Z`` becomes ``+00:00``.
    3.10 also reads a fraction of a second only as 3 or 6 digits (``14:02:00.5`` fails there,
    seen on a real 3.10): it is given 6, as 3.11 reads it. Raises ``ValueError`` as
    ``fromisoformat`` does."""
    if text[-1:] in ("Z", "z"):
        text = text[:-1] + "+00:00"
    text = _FRACTION.sub(lambda digits: "." + digits[1][:6].ljust(6, "0"), text, count=1)
    return dt.datetime.fromisoformat(text)


_FRACTION = re.compile(r"\.(\d+)")
