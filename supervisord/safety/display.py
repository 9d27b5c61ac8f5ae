"""The remote's display content, kept so it can be sent again after the remote re-links.

PR-2: labels and the display mode are lost when the remote restarts or re-links;
values go at most at 20 Hz and strings at most at 4 Hz (manual §6.5: a text row every 250 ms).
The limits are applied per class of message, across all keys: one value frame per 50 ms and
one string frame per 250 ms. Internal to the core.

The core may show a notice of its own on the text page (SR-4.6: why a re-arm was refused): it
takes the four text rows and the display mode, and the remote vibrates once; the clients'
rows and mode are kept meanwhile and sent again when the notice ends.
"""

from __future__ import annotations

from supervisord.protocol.codes import USER_VALUE_KEYS, DisplayMode, FeedbackKey, StringKey
from supervisord.protocol.messages import FeedbackName, FeedbackSet, Message
from supervisord.safety.canonical import Canonical, clock
from supervisord.safety.decision import RefusalReason
from supervisord.safety.face import Seen

VALUE_PERIOD_NS = 50_000_000  # values at most 20 Hz
STRING_PERIOD_NS = 250_000_000  # strings at most 4 Hz

_KEPT_VALUE_KEYS = frozenset(USER_VALUE_KEYS) | {FeedbackKey.DISPLAY_MODE.value}
_VIBRATE_KEYS = frozenset(
    {FeedbackKey.VIBRATE_LEFT, FeedbackKey.VIBRATE_RIGHT, FeedbackKey.VIBRATE_BOTH}
)
_NAME_KEYS = frozenset(USER_VALUE_KEYS) | {k.value for k in StringKey}
_DISPLAY_MODES = frozenset(m.value for m in DisplayMode)
_ROW_KEYS = tuple(k.value for k in StringKey)  # the text page's four rows
_MODE_KEY = FeedbackKey.DISPLAY_MODE.value
_NOTICE_KEYS = frozenset({*_ROW_KEYS, _MODE_KEY})  # what a notice takes over
Notice = tuple[str, str, str, str]
"""The four rows of a notice, each at most 20 single-byte characters."""


class DisplayStore:
    """Latest display content per key, and the frames still waiting for their rate slot."""

    def __init__(self) -> None:
        self._values: dict[int, FeedbackSet] = {}
        self._names: dict[int, FeedbackName] = {}
        self._pending_values: dict[int, FeedbackSet] = {}
        self._pending_names: dict[int, FeedbackName] = {}
        self._next_value_ns: int | None = None
        self._next_name_ns: int | None = None
        self._notice: Notice | None = None

    def accept(self, message: FeedbackSet | FeedbackName) -> RefusalReason | None:
        """Keep and queue a client's display content; the refusal reason if it is not allowed.

        Keys 80-85 are VSC settings (85 is the permanent user watchdog): clients never set them.
        """
        if isinstance(message, FeedbackName):
            if message.key not in _NAME_KEYS:
                return RefusalReason.DISPLAY_KEY_NOT_ALLOWED
            self._names[message.key] = message
            self._queue_name(message)
            return None
        if message.key in _VIBRATE_KEYS:
            if message.value != 1:  # PR-2: vibrate takes the value 1
                return RefusalReason.DISPLAY_VALUE_OUT_OF_RANGE
            self._pending_values[message.key] = message  # momentary: not kept for re-links
            return None
        if message.key not in _KEPT_VALUE_KEYS:
            return RefusalReason.DISPLAY_KEY_NOT_ALLOWED
        if message.key == FeedbackKey.DISPLAY_MODE and message.value not in _DISPLAY_MODES:
            return RefusalReason.DISPLAY_VALUE_OUT_OF_RANGE
        self._values[message.key] = message
        self._queue_value(message)
        return None

    def _queue_name(self, message: FeedbackName) -> None:
        if self._notice is None or message.key not in _NOTICE_KEYS:
            self._pending_names[message.key] = message

    def _queue_value(self, message: FeedbackSet) -> None:
        if self._notice is None or message.key not in _NOTICE_KEYS:
            self._pending_values[message.key] = message

    def edited_on_remote(self, message: FeedbackSet) -> None:
        """The operator changed a user value in the remote's menu: keep it, so a re-link does
        not overwrite it with an older value."""
        if message.key in self._values:
            self._values[message.key] = message
            self._pending_values.pop(message.key, None)

    def relink(self) -> None:
        """The remote re-linked and forgot its display: queue everything kept, labels first
        (a notice's rows first of all)."""
        for name in self._names.values():
            self._queue_name(name)
        for value in self._values.values():
            self._queue_value(value)
        if self._notice is not None:
            self._queue_notice(self._notice)

    def notice(self, rows: Notice) -> None:
        """Show the core's own ``rows`` on the text page, before any other string waiting, and
        vibrate the remote once when they are new (SR-4.6)."""
        if rows == self._notice:
            return
        self._notice = rows
        self._queue_notice(rows)
        self._pending_values[FeedbackKey.VIBRATE_BOTH.value] = FeedbackSet(
            FeedbackKey.VIBRATE_BOTH, 1
        )

    def _queue_notice(self, rows: Notice) -> None:
        first = {key: FeedbackName(key, text) for key, text in zip(_ROW_KEYS, rows, strict=True)}
        rest = {k: m for k, m in self._pending_names.items() if k not in first}
        self._pending_names = {**first, **rest}
        self._pending_values[_MODE_KEY] = FeedbackSet(_MODE_KEY, DisplayMode.TEXT_ROWS.value)

    def end_notice(self) -> None:
        """The notice ends: the clients' rows and display mode come back (empty rows and the
        default page where a client set none)."""
        if self._notice is None:
            return
        self._notice = None
        for key in _ROW_KEYS:
            self._pending_names[key] = self._names.get(key, FeedbackName(key, ""))
        default = FeedbackSet(_MODE_KEY, DisplayMode.GPS.value)
        self._pending_values[_MODE_KEY] = self._values.get(_MODE_KEY, default)

    @property
    def showing_notice(self) -> bool:
        return self._notice is not None

    def due(self, now: int) -> list[Message]:
        """At most one string and one value frame whose rate slot has come."""
        frames: list[Message] = []
        if self._pending_names and (self._next_name_ns is None or now >= self._next_name_ns):
            key = next(iter(self._pending_names))
            frames.append(self._pending_names.pop(key))
            self._next_name_ns = now + STRING_PERIOD_NS
        if self._pending_values and (self._next_value_ns is None or now >= self._next_value_ns):
            key = next(iter(self._pending_values))
            frames.append(self._pending_values.pop(key))
            self._next_value_ns = now + VALUE_PERIOD_NS
        return frames

    def next_due(self) -> int | None:
        """When the next waiting frame may go, or ``None`` when nothing waits."""
        times = []
        if self._pending_names and self._next_name_ns is not None:
            times.append(self._next_name_ns)
        if self._pending_values and self._next_value_ns is not None:
            times.append(self._next_value_ns)
        return min(times) if times else None

    # ----------------------------------------------------------------- the face (face.py)

    def can_move(self) -> bool:
        """The display moves only at its rate slots."""
        return False

    def moving(self) -> bool:
        return False

    def due_by(self, view: Seen) -> bool:
        """Whether a waiting frame may go at ``view.now`` (SR-5.4)."""
        due = self.next_due()
        return due is not None and due <= view.now

    def next_deadline(self, view: Seen) -> int | None:
        """When the next waiting frame may go, if after ``view.now`` and on an open link."""
        due = self.next_due() if view.vsc.open else None
        return due if due is not None and due > view.now else None

    def canonical(self, view: Seen) -> Canonical:
        """The content kept and waiting, in order, and the rate slots as clocks that matter
        only once they have come (docs/verification.md), as the one fact ``display``."""
        now = view.now
        facts = (
            tuple(self._values.items()),
            tuple(self._names.items()),
            tuple(self._pending_values.items()),
            tuple(self._pending_names.items()),
            self._notice,
        )
        slots = (("display:value", self._next_value_ns), ("display:name", self._next_name_ns))
        clocks = tuple(clock(name, at, now, 0) for name, at in slots if at is not None)
        return (("display", facts),), clocks

    @property
    def pending(self) -> bool:
        return bool(self._pending_names or self._pending_values)
