"""A stop's flight recorder window as a journal entry of its own, both ways (SR-13.12;
``docs/fleet.md`` "A stop's evidence at the collector").

The window's file (:mod:`supervisord.record.flight`) is JSON Lines; in the journal it is one
field, ``SRCS_FLIGHT``: the file's bytes compressed with zlib and written in base64, one line of
ASCII, which journald stores, systemd-journal-upload sends in the export format and journalctl
gives back as the same text (a field with a newline or a byte that is not UTF-8 would come back
from ``journalctl -o json`` as a list of numbers, four times its size). Beside it, the stop
record it belongs to (``SRCS_SEQ``, ``SRCS_MONO_NS``, ``SRCS_UTC``), the file's length
(``SRCS_FLIGHT_BYTES``) and its SHA-256 (``SRCS_FLIGHT_SHA256``): what a collector reads back is
the robot's file byte for byte, or it is refused (:class:`WindowEntryError`), never half a
window.

The entry's ``SYSLOG_IDENTIFIER`` is ``srcsd-flight``, not ``srcsd``: ``journalctl -t srcsd``
and every reader of the records (``srcsctl fleet``, the exporter's alerts) see the records
alone; the entry is in srcsd's journal (its namespace) and travels with it.

The engine's own limits (systemd 252, journald and systemd-journal-remote alike,
``src/shared/journal-importer.h``): a field of at most 768 MiB (``DATA_SIZE_MAX``), an entry of
at most 770 MiB (``ENTRY_SIZE_MAX``) and 1024 fields; systemd-journal-remote drops the upload's
connection at an entry past them. Tighter in practice: an entry must fit in one journal file,
whose largest size journald derives from the disk (``SystemMaxFileSize=``, an eighth of
``SystemMaxUse=``, 10 % of the file system). :data:`MAX_FIELD` (1 MiB) keeps far inside all
of them; a window's field past it is not sent (counted and logged by the sink; its file stays).

Importing nothing of the safety core: a collector decodes with it (SR-13.6).
"""

from __future__ import annotations

import base64
import binascii
import hashlib
import zlib
from collections.abc import Mapping
from typing import Final

from supervisord.journal_ids import FLIGHT_WINDOW_MESSAGE_ID
from supervisord.lane import hand_over

ENCODING: Final = "zlib+base64"
"""``SRCS_FLIGHT_ENCODING``: how ``SRCS_FLIGHT`` holds the file's bytes."""
SYSLOG_IDENTIFIER: Final = "srcsd-flight"
MAX_FIELD: Final = 1 << 20
"""The longest ``SRCS_FLIGHT`` sent (bytes of base64). A window of the ring's 4096 inputs is
some 600 KB as a file and under 100 KB here (docs/fleet.md)."""
MAX_WINDOW: Final = 1 << 30
"""The longest window a collector decodes: the record's largest ``max_bytes``."""
PRIORITY_INFO: Final = "6"
"""Not an event of its own: the stop's record is the entry at CRIT (SR-7.3)."""
CHUNK: Final = 64 * 1024
"""Bytes compressed between two hand-overs of the interpreter's lock (``lane.hand_over``), as the
window's encoding does (SR-7.12): the sink's thread never holds the loop's back for long."""
TEXT_CHUNK: Final = 48 * 1024
"""Bytes written in base64 at a time (a multiple of 3: the pieces join into one text)."""


class WindowEntryError(ValueError):
    """A window that cannot go into the journal (too large), or an entry that is no whole window
    (damaged, cut, another encoding): said in words, never half a window."""


def encode(data: bytes) -> str:
    """The file's bytes as ``SRCS_FLIGHT``'s text, compressed a chunk at a time."""
    packer = zlib.compressobj(6)
    packed = []
    for start in range(0, len(data), CHUNK):
        packed.append(packer.compress(data[start : start + CHUNK]))
        hand_over()  # let the loop's thread have the interpreter (SR-7.12)
    packed.append(packer.flush())
    whole = b"".join(packed)
    text = []
    for start in range(0, len(whole), TEXT_CHUNK):
        text.append(base64.b64encode(whole[start : start + TEXT_CHUNK]))
        hand_over()
    return b"".join(text).decode("ascii")


def window_entry(data: bytes, stop: Mapping[str, object]) -> list[tuple[str, str]]:
    """The journal entry's fields for the window file ``data`` of the stop record ``stop``.
    Raises :class:`WindowEntryError` when its field would pass :data:`MAX_FIELD`."""
    text = encode(data)
    seq = stop.get("seq")
    if len(text) > MAX_FIELD:
        raise WindowEntryError(
            f"the window of record {seq} is {len(text)} bytes compressed, past the journal "
            f"entry's {MAX_FIELD}: not sent (its file is kept)"
        )
    return [
        ("MESSAGE", f"flight recorder window of record #{seq}: {len(data)} bytes"),
        ("MESSAGE_ID", FLIGHT_WINDOW_MESSAGE_ID.hex),
        ("PRIORITY", PRIORITY_INFO),
        ("SYSLOG_IDENTIFIER", SYSLOG_IDENTIFIER),
        ("SRCS_SEQ", str(seq)),
        ("SRCS_MONO_NS", str(stop.get("mono_ns"))),
        ("SRCS_UTC", str(stop.get("utc"))),
        ("SRCS_FLIGHT_ENCODING", ENCODING),
        ("SRCS_FLIGHT_BYTES", str(len(data))),
        ("SRCS_FLIGHT_SHA256", hashlib.sha256(data).hexdigest()),
        ("SRCS_FLIGHT", text),
    ]


def window_bytes(fields: Mapping[str, str | None]) -> bytes:
    """The window file's bytes from an entry's fields (as journalctl gives them). Raises
    :class:`WindowEntryError` for anything but the whole window :func:`window_entry` sent."""
    encoding, size = fields.get("SRCS_FLIGHT_ENCODING"), fields.get("SRCS_FLIGHT_BYTES")
    digest, text = fields.get("SRCS_FLIGHT_SHA256"), fields.get("SRCS_FLIGHT")
    if encoding != ENCODING:
        raise WindowEntryError(f"a window in {encoding!r}; this reads {ENCODING}")
    if size is None or not size.isdigit() or int(size) > MAX_WINDOW:
        raise WindowEntryError(f"SRCS_FLIGHT_BYTES is not a window's length: {str(size)[:40]!r}")
    if text is None or digest is None:
        raise WindowEntryError("an entry without SRCS_FLIGHT or SRCS_FLIGHT_SHA256")
    try:
        packed = base64.b64decode(text, validate=True)
    except (binascii.Error, ValueError) as error:
        raise WindowEntryError(f"SRCS_FLIGHT is not base64: {error}") from error
    unpacker = zlib.decompressobj()
    try:
        # At most one byte past the announced length: a bomb is cut there, not inflated.
        data = unpacker.decompress(packed, int(size) + 1)
    except zlib.error as error:
        raise WindowEntryError(f"SRCS_FLIGHT does not decompress: {error}") from error
    if len(data) != int(size) or not unpacker.eof or unpacker.unused_data:
        raise WindowEntryError(
            f"SRCS_FLIGHT is cut or damaged: {len(data)} bytes of the {size} announced"
        )
    if hashlib.sha256(data).hexdigest() != digest:
        raise WindowEntryError("SRCS_FLIGHT's bytes are not the window's: SHA-256 differs")
    return data
