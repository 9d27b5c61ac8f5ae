"""``srcsctl fleet``'s reading of a collector's journal: journalctl itself, never a parser of
journal files of our own (docs/fleet.md "srcsctl fleet"), and each entry back as the record
``srcsctl log`` prints (SR-13.4).

An entry names its robot by ``_HOSTNAME``, which journald adds on the robot and
systemd-journal-remote keeps, and by its sender, the address the collector's file names
(:mod:`fleet_senders`): a host name is what an uploader says, the address is where its upload
came from (SR-13.8); its time is the robot's own (``__REALTIME_TIMESTAMP`` as
forwarded: the collector adds no time of its own). The record is rebuilt from the ``SRCS_*``
fields ``supervisord/record/journal.py`` writes; an entry without them is named and skipped.
"""

from __future__ import annotations

import datetime as dt
import json
import re
import shutil
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Final, TypeGuard

from supervisord.cli.fleet_senders import Senders
from supervisord.cli.terminal_text import printable
from supervisord.journal_ids import MESSAGE_IDS_BY_KIND
from supervisord.record.stop import StopRecord, read_written

DEFAULT_DIRECTORY: Final = Path("/var/log/journal/remote")
"""Where systemd-journal-remote writes by default (``remote-HOST.journal``)."""
ROBOT_NAME: Final = re.compile(r"[A-Za-z0-9][A-Za-z0-9._-]{0,63}", re.ASCII)
"""A host name as journald records it (at most 64 characters, HOST_NAME_MAX): letters,
digits, ``.``, ``-`` and ``_``. Anything else is refused before it reaches journalctl, where
``=`` or a lone ``+`` would change what the match means."""
_TEXT_FIELDS: Final = (("kind", "SRCS_KIND"), ("from", "SRCS_FROM"), ("to", "SRCS_TO"))
_JSON_FIELDS: Final = (
    ("causes", "SRCS_CAUSES"),
    ("changes", "SRCS_CHANGES"),
    ("prooftest", "SRCS_PROOFTEST"),
    ("stoptest", "SRCS_STOPTEST"),
    ("rearm", "SRCS_REARM"),
)
"""The record's objects, as supervisord/record/journal.py writes them (JSON); with the text
fields and ``version`` they rebuild the record the robot wrote, so that its line here is the
robot's own (SR-13.4)."""


class NoJournalctl(Exception):
    """journalctl is not installed here."""


@dataclass(frozen=True)
class Entry:
    """One record as a collector holds it: the robot that sent it (its ``_HOSTNAME`` as sent,
    raw: escaped only where printed), the journal's cursor (its place in the collector's
    files) and the record rebuilt from its fields."""

    robot: str
    cursor: str
    data: Mapping[str, Any]
    stamp_us: int | None = None
    """``__REALTIME_TIMESTAMP``: the robot's clock when its journald took the entry."""
    record: StopRecord | None = None
    """The record typed (:func:`~supervisord.record.stop.read_written`); ``None`` for one
    that is no typed record, shown from its fields as written."""
    identity: tuple[str, ...] | None = None
    """What names this entry as the robot wrote it (:func:`identity`), the same in a copy
    the collector was sent twice; ``None`` without the robot's stamps."""
    sender: str | None = None
    """Where the upload came from (:meth:`~supervisord.cli.fleet_senders.Senders.of`)."""

    @property
    def who(self) -> tuple[str, str | None]:
        """The robot: its host name and its sender, together (SR-13.8)."""
        return self.robot, self.sender

    @property
    def label(self) -> str:
        """:func:`label` of the robot."""
        return label(self.robot, self.sender)

    def within(self, start: dt.datetime | None, end: dt.datetime | None) -> bool:
        """Whether the robot's stamp is at or after ``start`` and before ``end``. journalctl's
        ``--since`` only seeks: in a robot's file whose clock went back it goes on past
        entries stamped before it, which ``log``'s rule leaves out (SR-13.5)."""
        if self.stamp_us is None:
            return start is None and end is None
        when = dt.datetime.fromtimestamp(self.stamp_us / 1e6, dt.timezone.utc)
        return (start is None or when >= start) and (end is None or when < end)


def robot_name(text: str) -> str:
    """``text`` if it can be a robot's host name (:data:`ROBOT_NAME`); else ``ValueError``
    naming the rule."""
    if not ROBOT_NAME.fullmatch(text):
        raise ValueError(
            f"{text[:80]!r} is not a robot's host name: letters, digits, '.', '-' and '_', "
            "at most 64, starting with a letter or digit"
        )
    return text


def journalctl() -> str:
    """The journalctl to run. Raises :class:`NoJournalctl`."""
    found = shutil.which("journalctl")
    if found is None:
        raise NoJournalctl("journalctl not found: it comes with systemd, on every collector")
    return found


def _stamp(when: dt.datetime) -> str:
    """A time as journalctl reads it in any zone: ``@SECONDS.MICROSECONDS`` since the epoch."""
    micros = round(when.timestamp() * 1_000_000)
    return f"@{micros // 1_000_000}.{micros % 1_000_000:06d}"


def command(
    source: Sequence[str],
    *,
    robot: str | None = None,
    since: dt.datetime | None = None,
    until: dt.datetime | None = None,
    follow: bool = False,
) -> list[str]:
    """The journalctl line: ``source`` (``--directory DIR`` or ``--file FILE``...), every
    field in full (``--all``: journalctl writes a field over 4096 bytes as null without it),
    the record kinds' MESSAGE_IDs (one match per kind: journalctl ORs a field's values) and
    the robot's ``_HOSTNAME``; with ``follow``, every entry in the window and then each new one
    (``--lines=all``, ``--follow``)."""
    line = [journalctl(), *source, "--output=json", "--no-pager", "--all", "--quiet"]
    if since is not None:
        line.append(f"--since={_stamp(since)}")
    if until is not None:
        line.append(f"--until={_stamp(until)}")
    if follow:
        line += ["--follow", "--lines=all"]
    line += [f"MESSAGE_ID={uid.hex}" for uid in MESSAGE_IDS_BY_KIND.values()]
    if robot is not None:
        line.append(f"_HOSTNAME={robot}")
    return line


def _one(entry: Mapping[str, Any], field: str) -> str | None:
    """A field's text: journalctl writes a repeated field as a list (the last is taken), and a
    value with a control character or not UTF-8 as a list of its bytes, read here as UTF-8
    with U+FFFD for what is not (its controls are escaped where it is shown, SR-13.7: a
    record's reason or state is shown, not dropped, whatever it holds)."""
    value = entry.get(field)
    if _is_bytes(value):
        return bytes(value).decode(errors="replace")
    if isinstance(value, list) and value:
        value = value[-1]
    if _is_bytes(value):
        return bytes(value).decode(errors="replace")
    return value if isinstance(value, str) else None


def _is_bytes(value: object) -> TypeGuard[list[int]]:
    """Whether ``value`` is journalctl's list of a value's bytes (an empty list is not)."""
    return (
        isinstance(value, list)
        and bool(value)
        and all(isinstance(b, int) and 0 <= b <= 255 for b in value)
    )


def _json(text: str | None) -> object:
    try:
        return json.loads(text) if text is not None else None
    except (ValueError, RecursionError):  # RecursionError: nested thousands deep (SR-8.7)
        return None


def label(robot: str, sender: str | None) -> str:
    """A robot as a line shows it: ``HOST@ADDRESS`` (``HOST`` alone for a file no collector
    named), escaped (SR-13.7). A host name that is no host name (:data:`ROBOT_NAME`) is in
    quotes, so that no ``_HOSTNAME`` can pass for another robot's label (``robot-b@10.0.0.5``
    sent from elsewhere is ``"robot-b@10.0.0.5"@ELSEWHERE``, SR-13.8)."""
    name = (
        robot if ROBOT_NAME.fullmatch(robot) else '"' + printable(robot).replace('"', '\\"') + '"'
    )
    return name if sender is None else f"{name}@{printable(sender)}"


def entry(line: str, senders: Senders | None = None) -> Entry | str:
    """One line of ``journalctl -o json`` as an :class:`Entry` (its sender from ``senders``),
    or why it is not a record (raw: the caller escapes it)."""
    try:
        fields = json.loads(line)
    except (ValueError, RecursionError):
        return "not a journal entry (journalctl's JSON)"
    if not isinstance(fields, dict):
        return "not a journal entry (journalctl's JSON)"
    robot = _one(fields, "_HOSTNAME") or "?"
    seq, mono = _one(fields, "SRCS_SEQ"), _one(fields, "SRCS_MONO_NS")
    utc = _one(fields, "SRCS_UTC")
    if seq is None or not seq.isdigit() or mono is None or not mono.isdigit() or utc is None:
        return f"{robot}: an entry without SRCS_SEQ, SRCS_MONO_NS or SRCS_UTC"
    causes = _json(_one(fields, "SRCS_CAUSES"))
    if not isinstance(causes, list):
        return f"{robot}: #{seq}: SRCS_CAUSES is not a list"
    data: dict[str, Any] = {"seq": int(seq), "mono_ns": int(mono), "utc": utc}
    for name, field in _TEXT_FIELDS:
        data[name] = _one(fields, field) or ""
    for name, field in _JSON_FIELDS:
        value = _json(_one(fields, field))
        if value is not None:
            data[name] = value
    trigger = _one(fields, "SRCS_TRIGGER") or ""
    parsed = _json(trigger)
    data["trigger"] = parsed if isinstance(parsed, dict) else trigger
    reason = _one(fields, "SRCS_REASON")
    if reason:
        data["reason"] = reason
    version = _one(fields, "SRCS_VERSION")
    if version is not None:
        data["version"] = version
    stamp = _one(fields, "__REALTIME_TIMESTAMP")
    stamp_us = int(stamp) if stamp is not None and stamp.isdigit() else None
    cursor = str(fields.get("__CURSOR", ""))
    sender = senders.of(cursor) if senders is not None else None
    known = identity(fields)
    known = None if known is None else (*known, sender or "")  # another sender's is not a copy
    return Entry(robot, cursor, data, stamp_us, read_written(data), known, sender)


_ROBOTS_STAMPS: Final = (
    "_HOSTNAME",
    "_MACHINE_ID",
    "_BOOT_ID",
    "__MONOTONIC_TIMESTAMP",
    "__REALTIME_TIMESTAMP",
    "SRCS_SEQ",
)
"""The robot, the record's ``seq`` and the stamps the robot's journald gave the entry: its
boot, its monotonic and its wall clock. systemd-journal-remote keeps all of them as sent;
only the collector's own place (``__CURSOR``, ``__SEQNUM``) differs in a second copy."""


def identity(fields: Mapping[str, Any]) -> tuple[str, ...] | None:
    """The entry's :data:`_ROBOTS_STAMPS`, or ``None`` when the robot's boot or monotonic
    stamp is missing (then no entry is taken for a copy of it). systemd-journal-upload sends
    an entry again when the collector went away before it answered (its cursor is saved after
    the answer), and the collector then holds it twice; two records of one robot with the same
    ``seq`` (a new record file) differ in their stamps (SR-13.1)."""
    values = tuple(_one(fields, name) for name in _ROBOTS_STAMPS)
    if values[2] is None or values[3] is None:
        return None
    return tuple(value or "" for value in values)
