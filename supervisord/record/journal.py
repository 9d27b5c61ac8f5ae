"""The record of stops in the systemd journal (SR-7, ``docs/record.md``).

Each record becomes one journal entry with a stable ``MESSAGE_ID`` per record kind (so that
``journalctl MESSAGE_ID=...`` and journal catalogs find them across versions) and structured
``SRCS_*`` fields. A transition into STOPPED is logged at priority CRIT, which journald syncs to
disk at once; the rest at lower priorities (:func:`priority`).

:func:`journal_fields` is the pure mapping from a record to journal fields and
:func:`encode_native` the pure encoding of an entry in journald's native protocol;
:class:`JournalSink` sends it to journald's socket itself, as ``daemon/notify.py`` does for
sd_notify: no libsystemd, nothing compiled, so the robot needs no compiler (see
``docs/record.md`` "Why no journal library"). Where there is no journal (no socket at
:data:`JOURNAL_SOCKET`), the sink says so through :attr:`JournalSink.available` and its writes
return ``False``: the JSON Lines file stays the record that counts.
"""

from __future__ import annotations

import array
import errno
import fcntl
import json
import os
import re
import socket
import stat
import struct
import uuid
from collections.abc import Iterable, Mapping
from typing import Final

from supervisord.compat import IntEnum
from supervisord.errors import SrcsError
from supervisord.journal_ids import MESSAGE_IDS_BY_KIND
from supervisord.record.format import written_kind
from supervisord.record.jsonl import RecordUsageError, cause_names
from supervisord.record.stop import RecordKind

JOURNAL_SOCKET: Final = "/run/systemd/journal/socket"
SYSLOG_IDENTIFIER: Final = "srcsd"


MESSAGE_IDS: Final[Mapping[RecordKind, uuid.UUID]] = {
    kind: MESSAGE_IDS_BY_KIND[kind.value] for kind in RecordKind
}
"""Stable journal MESSAGE_IDs, one per record kind. Never change them: operators' queries and
alerting depend on them (``docs/record.md`` lists them)."""


class Priority(IntEnum):
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


def _is_stopped(state: object) -> bool:
    return str(state).upper() == "STOPPED"


def priority(record: Mapping[str, object]) -> Priority:
    """CRIT for a change into STOPPED, WARNING for a cause raised, a re-arm refused or a
    commissioning (it changes the VSC for good), NOTICE otherwise (a cause cleared, any other
    change of state)."""
    kind = written_kind(record)
    if kind is RecordKind.PROOFTEST:
        # A failed proof test leaves the robot with one stop path: CRIT, as a stop (SR-7.3).
        outcome = record.get("prooftest")
        failed = not isinstance(outcome, Mapping) or outcome.get("result") != "passed"
        return Priority.CRIT if failed else Priority.NOTICE
    if kind is RecordKind.STOPTEST:
        # A field stop test that failed: the stop path is slower than its target, or an output
        # did not go off (SR-12.1): a warning to act on, the robot itself did stop.
        outcome = record.get("stoptest")
        failed = not isinstance(outcome, Mapping) or outcome.get("result") != "passed"
        return Priority.WARNING if failed else Priority.NOTICE
    if kind is RecordKind.STATE_CHANGE:
        into_stop = _is_stopped(record.get("to")) and not _is_stopped(record.get("from"))
        return Priority.CRIT if into_stop else Priority.NOTICE
    if kind in (
        RecordKind.CAUSE_RAISED,
        RecordKind.REARM_REFUSED,
        RecordKind.COMMISSIONED,
        RecordKind.HELLO_REFUSED,  # someone tried to speak as another user's client (SR-8)
    ):
        return Priority.WARNING
    return Priority.NOTICE


CARRIED: Final = (
    ("prooftest", "SRCS_PROOFTEST"),
    ("stoptest", "SRCS_STOPTEST"),
    ("rearm", "SRCS_REARM"),
    ("version", "SRCS_VERSION"),
)
"""The record's optional fields each entry carries when the record has them: as JSON, but
``version``, a text (docs/record.md "In the journal")."""


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
    kind = written_kind(record)
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
        RecordKind.HELLO_REFUSED: f"hello refused: {reason} (trigger {trigger})",
        RecordKind.STOPTEST: f"field stop test {reason} (state {after})",
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
    if isinstance(record.get("changes"), list):
        # What the record raised, cleared or released: a collector's `srcsctl fleet --cause`
        # and its lines say it as `srcsctl log` does, without the record before (SR-13.4).
        fields.append(("SRCS_CHANGES", _text(record.get("changes"))))
    for key, field in CARRIED:
        # The rest of the record: the proof test's verdict and reason, the stop test's, the
        # re-arm's kind and caller, the daemon's version, so that the collector rebuilds the
        # record the robot wrote and prints the robot's own line for it (SR-13.4).
        value = record.get(key)
        if value is not None:
            fields.append((field, _text(value)))
    # The record whole, as the record file holds it (ASCII JSON, so any text goes through and
    # comes back the same): a collector replays a stop's window against the robot's own
    # records, every field, as the robot does (SR-13.12, `srcsctl fleet replay`).
    fields.append(("SRCS_RECORD", json.dumps(dict(record), separators=(",", ":"))))
    return fields


FIELD_NAME: Final = re.compile(r"[A-Z][A-Z0-9_]{0,63}")
"""What journald accepts as a field name that a client may set: upper-case letters, digits and
underscores, not starting with an underscore (those are journald's own) or a digit, at most 64
characters (systemd.journal-fields(7))."""

SEND_TIMEOUT_S: Final = 2.0
"""How long a write may wait for room in journald's queue. journald drains it in milliseconds;
a journald that is stuck must not stall the journal lane for longer than this per entry
(SR-7.5): the entry is refused and counted; records have a lane of their own (SR-7.7)."""

_SEALS: Final = fcntl.F_SEAL_SHRINK | fcntl.F_SEAL_GROW | fcntl.F_SEAL_WRITE | fcntl.F_SEAL_SEAL


def encode_native(fields: Iterable[tuple[str, str]]) -> bytes:
    """One journal entry in journald's native protocol (systemd.io/JOURNAL_NATIVE_PROTOCOL):
    ``KEY=value\n`` per field, and for a value with a newline in it the binary form
    ``KEY\n`` + its length as a 64-bit little-endian number + the bytes + ``\n``.

    Raises :class:`RecordUsageError` for a field name journald would drop."""
    out = bytearray()
    for key, value in fields:
        if not FIELD_NAME.fullmatch(key):
            raise RecordUsageError(f"not a journal field name: {key[:80]!r}")
        data = value.encode("utf-8", "surrogateescape")
        if b"\n" in data:
            out += key.encode() + b"\n" + struct.pack("<Q", len(data)) + data + b"\n"
        else:
            out += key.encode() + b"=" + data + b"\n"
    return bytes(out)


class JournalSink:
    """Sends records to the systemd journal over its native socket.

    ``available`` is decided once, at construction: ``socket_path`` is a socket. The entry goes
    as one datagram; one too large for a datagram goes as a sealed memfd passed with
    SCM_RIGHTS, as libsystemd does. :meth:`close` closes the sending socket.
    """

    def __init__(self, socket_path: str = JOURNAL_SOCKET) -> None:
        self.socket_path = socket_path
        self._socket: socket.socket | None = None
        self.unavailable_reason: str | None = None
        """Why the journal is not used, or ``None`` when it is."""
        if not _is_socket(socket_path):
            self.unavailable_reason = f"no journal socket at {socket_path}"
            return
        self._socket = socket.socket(socket.AF_UNIX, socket.SOCK_DGRAM | socket.SOCK_CLOEXEC)
        # A blocking socket with a kernel send timeout: the kernel sleeps until journald's
        # queue has room (an unconnected datagram socket polls as always writable, so a
        # Python-side timeout would spin) and fails with EAGAIN after SEND_TIMEOUT_S.
        seconds = int(SEND_TIMEOUT_S)
        timeval = struct.pack("ll", seconds, int((SEND_TIMEOUT_S - seconds) * 1_000_000))
        self._socket.setsockopt(socket.SOL_SOCKET, socket.SO_SNDTIMEO, timeval)

    @property
    def available(self) -> bool:
        """Whether records go to the journal."""
        return self.unavailable_reason is None

    def write(self, record: Mapping[str, object]) -> bool:
        """Send ``record``; ``True`` if sent, ``False`` if the journal is unavailable.

        Raises :class:`JournalError` if the journal refuses it, :class:`RecordUsageError` for
        a malformed record."""
        return self.send(journal_fields(record))

    def send(self, fields: Iterable[tuple[str, str]]) -> bool:
        """Send one entry of ``fields`` (a record's, or a stop's window's: SR-13.12); as
        :meth:`write` (raises :class:`JournalError`, :class:`RecordUsageError`)."""
        entry = encode_native(fields)
        if self._socket is None:
            return False
        try:
            self._send(self._socket, entry)
        except OSError as e:
            raise JournalError(e) from e
        return True

    def close(self) -> None:
        if self._socket is not None:
            self._socket.close()
            self._socket = None
            self.unavailable_reason = "closed"

    def __enter__(self) -> JournalSink:
        return self

    def __exit__(self, *_: object) -> None:
        self.close()

    def _send(self, sock: socket.socket, entry: bytes) -> None:
        try:
            sock.sendto(entry, self.socket_path)
            return
        except OSError as e:
            # Too large for one datagram (the socket's send buffer): libsystemd's fallback.
            if e.errno not in (errno.EMSGSIZE, errno.ENOBUFS):
                raise
        fd = os.memfd_create("srcsd-journal", os.MFD_CLOEXEC | os.MFD_ALLOW_SEALING)
        try:
            view = memoryview(entry)
            while view:
                view = view[os.write(fd, view) :]
            # journald takes a memfd only when it is sealed: nobody can change it any more.
            fcntl.fcntl(fd, fcntl.F_ADD_SEALS, _SEALS)
            rights = [(socket.SOL_SOCKET, socket.SCM_RIGHTS, array.array("i", [fd]).tobytes())]
            sock.sendmsg([], rights, 0, self.socket_path)
        finally:
            os.close(fd)


def _is_socket(path: str) -> bool:
    try:
        return stat.S_ISSOCK(os.stat(path).st_mode)
    except OSError:
        return False
