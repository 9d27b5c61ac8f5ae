"""Which sender each entry at a fleet's collector came from (SR-13.8): the address the
collector's file names, as journal-remote's files do.

A robot's ``_HOSTNAME`` is what its uploader says: any host that reaches the collector's port
may say robot-b (Debian 12's receiver checks no client certificate, docs/fleet.md). What the
uploader cannot choose is where its upload lands: systemd-journal-remote writes each sender's
entries into a file of its own, ``remote-ADDRESS.journal`` (``--split-mode=host``, its
default; the name is the certificate's subject where it checks certificates), set aside on
rotation as ``remote-ADDRESS@SEQNUM_ID-SEQNUM-TIME.journal`` (or ``...journal~``). The entry's
cursor (``__CURSOR``, ``s=``) names the file's sequence-number ID, which the collector draws for
each sender's first file and keeps across its rotations, and which an upload cannot set
(journal-remote ignores an upload's ``__SEQNUM_ID``); journalctl's own ``--header`` names each
file's. So: cursor -> sequence-number ID -> file name -> sender.
"""

from __future__ import annotations

import re
import subprocess
from collections.abc import Sequence
from pathlib import PurePath
from typing import Final

UNKNOWN: Final = "?"
"""The sender of an entry whose file could not be told (its file went away between the
reads, or two senders' files share the ID): never taken for any sender's."""
_REMOTE: Final = re.compile(
    r"remote-(?P<sender>.+?)"
    r"(?:@[0-9a-f]{32}-[0-9a-f]{16}-[0-9a-f]{16}\.journal|@[0-9a-f]{16}-[0-9a-f]{16}\.journal~"
    r"|\.journal~?)",
    re.ASCII | re.DOTALL,
)
_CURSOR_ID: Final = re.compile(r"s=([0-9a-f]{32})(?:;|$)", re.ASCII)


def sender_of_file(name: str) -> str | None:
    """The sender a collector's file name says (``remote-ADDRESS.journal`` and its rotated
    forms: ``ADDRESS``, with ``_`` for each ``/``, as journal-remote writes it), or ``None`` for
    a file that is no sender's at a collector (a robot's own journal copied)."""
    found = _REMOTE.fullmatch(PurePath(name).name)
    return found["sender"] if found else None


def cursor_id(cursor: str) -> str | None:
    """The file's sequence-number ID in an entry's cursor (``s=``)."""
    found = _CURSOR_ID.match(cursor)
    return found[1] if found else None


class Senders:
    """Each file's sender by its sequence-number ID, read with ``journalctl SOURCE --header``
    (``line``: journalctl and the source options) and read again when a cursor names an ID not
    read yet (a file that appeared since)."""

    def __init__(self, line: Sequence[str]) -> None:
        self.line = [*line, "--header", "--no-pager"]
        self.by_id: dict[str, str | None] = {}
        self.read()

    def read(self) -> None:
        """Read every file's header now (a journalctl that fails leaves what was read)."""
        try:
            done = subprocess.run(  # noqa: S603
                self.line, capture_output=True, text=True, errors="replace", check=False
            )
        except OSError:
            return
        found: dict[str, str | None] = {}
        path: str | None = None
        for text in done.stdout.splitlines():
            key, _, value = text.partition(": ")
            if key == "File path":
                path = value
            elif key == "Sequential number ID" and path is not None:
                sender = sender_of_file(path)
                # One ID in two senders' files cannot be told apart: neither is taken.
                found[value] = sender if found.get(value, sender) == sender else UNKNOWN
                path = None
        self.by_id.update(found)  # an ID not found again keeps what it was

    def of(self, cursor: str) -> str | None:
        """The sender of the entry at ``cursor``: an address (or a certificate's name),
        ``None`` for a file no collector named, :data:`UNKNOWN` when it cannot be told."""
        seqnum_id = cursor_id(cursor)
        if seqnum_id is None:
            return UNKNOWN
        if seqnum_id not in self.by_id:
            self.read()
            self.by_id.setdefault(seqnum_id, UNKNOWN)  # read again once, not at each entry
        return self.by_id[seqnum_id]
