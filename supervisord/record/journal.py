"""The record of stops in the systemd journal (SR-7, ``docs/record.md``).

Each record becomes one journal entry with a stable ``MESSAGE_ID`` per record kind (so that
``journalctl MESSAGE_ID=...`` and journal catalogs find them across versions) and structured
``SRCS_*`` fields. A transition into STOPPED is logged at priority CRIT, which journald syncs to
disk at once; the rest at lower priorities (:func:`priority`).

:func:`journal_fields` is the pure mapping from a record to journal fields; :class:`JournalSink`
sends them with ``systemd.journal.sendv``. Where there is no journal (no socket at
:data:`JOURNAL_SOCKET`, or no ``systemd`` module), the sink says so through
:attr:`JournalSink.available` and its writes return ``False``: the JSON Lines file stays the
record that counts.
"""

from __future__ import annotations

import enum
import json
import os
import stat
import uuid
from collections.abc import Callable, Mapping
from typing import Final

from supervisord.compat import StrEnum
from supervisord.errors import SrcsError
from supervisord.record.jsonl import RecordUsageError, cause_names

JOURNAL_SOCKET: Final = "/run/systemd/journal/socket"
SYSLOG_IDENTIFIER: Final = "srcsd"


class RecordKind(StrEnum):
    """What a record reports, as its optional ``kind`` field says (absent: a state change)."""

    STATE_CHANGE = "state_change"
    """The state changed (a stop is a change into STOPPED)."""
    CAUSE_RAISED = "cause_raised"
    """A stop or hold cause became active."""
    CAUSE_CLEARED = "cause_cleared"
    """A cause's condition cleared."""
    REARM_REFUSED = "rearm_refused"
    """A re-arm was asked for and refused."""
    COMMISSIONED = "commissioned"
    """Key 85 was written to the VSC (``srcsctl commission``)."""
    PROOFTEST = "prooftest"
    """A proof test of the VSC's watchdog finished (SR-5.3, docs/safety.md "The proof test")."""


MESSAGE_IDS: Final[Mapping[RecordKind, uuid.UUID]] = {
    RecordKind.STATE_CHANGE: uuid.UUID("26c2f33dae3d4a6c8996fc9bc658ad32"),
    RecordKind.CAUSE_RAISED: uuid.UUID("820501387c1a46049b855bcae8bc9ba2"),
    RecordKind.CAUSE_CLEARED: uuid.UUID("fd9e4e6d79c643eb9a534d2f8228aa89"),
    RecordKind.REARM_REFUSED: uuid.UUID("2be6051d1b7c43d0a0bfd08ad06caac8"),
    RecordKind.COMMISSIONED: uuid.UUID("bdd0782d2f2b45a3bdc4e9984db1024d"),
    RecordKind.PROOFTEST: uuid.UUID("af4347b3c6a741d6a06ce07e58cea85a"),
}
"""Stable journal MESSAGE_IDs, one per record kind. Never change them: operators' queries and
alerting depend on them (``docs/record.md`` lists them)."""


class Priority(enum.IntEnum):
    """syslog priorities the sink uses."""

    CRIT = 2
    WARNING = 4
    NOTICE = 5


class JournalError(SrcsError):
    """The journal refused an entry (journald stopped, socket buffer full). ``errno`` says
    why. The JSON Lines record is unaffected."""

    def __init__(self, error: OSError) -> None:
        self.errno = error.errno
        super().__init__(f"journal refused the record: {error.strerror or error}")


def record_kind(record: Mapping[str, object]) -> RecordKind:
    """The record's kind (its ``kind`` field; a state change when absent).

    Raises :class:`RecordUsageError` for an unknown kind."""
    kind = record.get("kind", RecordKind.STATE_CHANGE.value)
    if isinstance(kind, str) and kind in RecordKind.__members__.values():
        return RecordKind(kind)
    raise RecordUsageError(f"unknown record kind {kind!r}")


def _is_stopped(state: object) -> bool:
    return str(state).upper() == "STOPPED"


def priority(record: Mapping[str, object]) -> Priority:
    """CRIT for a change into STOPPED, WARNING for a cause raised, a re-arm refused or a
    commissioning (it changes the VSC for good), NOTICE otherwise (a cause cleared, any other
    change of state)."""
    kind = record_kind(record)
    if kind is RecordKind.PROOFTEST:
        # A failed proof test leaves the robot with one stop path: CRIT, as a stop (SR-7.3).
        outcome = record.get("prooftest")
        failed = not isinstance(outcome, Mapping) or outcome.get("result") != "passed"
        return Priority.CRIT if failed else Priority.NOTICE
    if kind is RecordKind.STATE_CHANGE:
        into_stop = _is_stopped(record.get("to")) and not _is_stopped(record.get("from"))
        return Priority.CRIT if into_stop else Priority.NOTICE
    if kind in (RecordKind.CAUSE_RAISED, RecordKind.REARM_REFUSED, RecordKind.COMMISSIONED):
        return Priority.WARNING
    return Priority.NOTICE


def _text(value: object) -> str:
    if isinstance(value, str):
        return value
    return json.dumps(value, ensure_ascii=False, separators=(",", ":"), sort_keys=True)


def journal_fields(record: Mapping[str, object]) -> list[tuple[str, str]]:
    """The journal fields for ``record``, in order. ``SRCS_CAUSE`` repeats once per cause, so
    that ``journalctl SRCS_CAUSE=vsc_estop`` matches any record that names it.

    Raises :class:`RecordUsageError` for a record without well-formed ``causes``."""
    names = cause_names(record)
    if names is None:
        raise RecordUsageError("record field 'causes' must be a list of objects with a 'name'")
    kind = record_kind(record)
    before, after, trigger, reason = (
        _text(record.get(k, "")) for k in ("from", "to", "trigger", "reason")
    )
    listed = ", ".join(names) or "none"
    message = {
        RecordKind.STATE_CHANGE: f"{before} -> {after}: causes {listed}; trigger {trigger}",
        RecordKind.CAUSE_RAISED: f"cause raised: {listed} (state {after}; trigger {trigger})",
        RecordKind.CAUSE_CLEARED: f"cause cleared: {listed} (state {after}; trigger {trigger})",
        RecordKind.REARM_REFUSED: f"re-arm refused: {reason} (state {after}; causes {listed})",
        RecordKind.COMMISSIONED: f"VSC commissioned: {reason} (trigger {trigger})",
        RecordKind.PROOFTEST: f"VSC watchdog proof test {reason} (state {after})",
    }[kind]
    fields = [
        ("MESSAGE", message),
        ("MESSAGE_ID", MESSAGE_IDS[kind].hex),
        ("PRIORITY", str(int(priority(record)))),
        ("SYSLOG_IDENTIFIER", SYSLOG_IDENTIFIER),
        ("SRCS_KIND", kind.value),
        ("SRCS_SEQ", _text(record.get("seq"))),
        ("SRCS_MONO_NS", _text(record.get("mono_ns"))),
        ("SRCS_UTC", _text(record.get("utc"))),
        ("SRCS_FROM", before),
        ("SRCS_TO", after),
        ("SRCS_TRIGGER", trigger),
    ]
    if reason:
        fields.append(("SRCS_REASON", reason))
    fields += [("SRCS_CAUSE", name) for name in names]
    fields.append(("SRCS_CAUSES", _text(record.get("causes"))))
    return fields


def _default_sendv() -> tuple[Callable[..., object] | None, str | None]:
    try:
        from systemd import journal  # noqa: PLC0415  (optional at run time: see available)
    except ImportError as e:
        return None, f"no systemd module: {e}"
    sendv: Callable[..., object] = journal.sendv
    return sendv, None


class JournalSink:
    """Sends records to the systemd journal.

    ``available`` is decided once, at construction: the ``systemd`` module imports and
    ``socket_path`` is a socket. ``sendv`` (default ``systemd.journal.sendv``) is called with
    ``"FIELD=value"`` strings.
    """

    def __init__(
        self,
        sendv: Callable[..., object] | None = None,
        socket_path: str = JOURNAL_SOCKET,
    ) -> None:
        reason = None
        if sendv is None:
            sendv, reason = _default_sendv()
        if reason is None and not _is_socket(socket_path):
            reason = f"no journal socket at {socket_path}"
        self._sendv = sendv
        self.unavailable_reason: str | None = reason
        """Why the journal is not used, or ``None`` when it is."""

    @property
    def available(self) -> bool:
        """Whether records go to the journal."""
        return self.unavailable_reason is None

    def write(self, record: Mapping[str, object]) -> bool:
        """Send ``record``; ``True`` if sent, ``False`` if the journal is unavailable.

        Raises :class:`JournalError` if the journal refuses it, :class:`RecordUsageError` for
        a malformed record."""
        fields = journal_fields(record)
        if self.unavailable_reason is not None or self._sendv is None:
            return False
        try:
            self._sendv(*(f"{key}={value}" for key, value in fields))
        except OSError as e:
            raise JournalError(e) from e
        return True


def _is_socket(path: str) -> bool:
    try:
        return stat.S_ISSOCK(os.stat(path).st_mode)
    except OSError:
        return False
