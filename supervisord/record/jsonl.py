"""The record of stops as an append-only JSON Lines file (SR-7, ``docs/record.md``).

Writing (:class:`RecordWriter`):

- one JSON object per line, written with a single ``write`` and made durable with ``fsync``
  before :meth:`RecordWriter.append` returns. A record is *acknowledged* when ``append``
  returns; an acknowledged record survives a crash and a power cut.
- bounded rotation: when a record would take the file past ``max_bytes``, the files move up
  one number (``stops.jsonl`` -> ``stops.jsonl.1`` -> ... -> ``stops.jsonl.KEEP``, the oldest
  dropped) and a new file starts. Rotation uses renames only, oldest first, and fsyncs the
  directory before any record goes into the new file: a crash at any step leaves every
  acknowledged record in exactly one file, and the numbering still sorts the files by age
  (a crash can leave a gap in the numbers, never a wrong order).
- a torn tail (a last line without its newline, left by a crash in the middle of a write) was
  never acknowledged. On open the writer **truncates** it, so the next record starts on a line
  of its own. A failed write is cut off the same way before the next append.
- every OS error (``ENOSPC`` for a full disk, ``EIO``, ``EACCES``) raises :class:`RecordError`
  with its ``errno``; the record was then **not** acknowledged. Nothing is swallowed: the
  daemon counts and logs every one (``docs/record.md`` "A full disk").

Reading (:func:`read_records`): across the rotated files, oldest first, yielding
:class:`StoredRecord` and :class:`BadLine` items; a torn or undecodable last line of a file is
reported as ``TORN_TAIL``, never misread; a bad line elsewhere as ``NOT_JSON`` or
``NOT_A_RECORD``. Filters: time (``since <= utc < until``) and cause name.

The store checks only what it needs to file and filter a record: the fields in
:data:`REQUIRED_FIELDS`, ``utc`` an ISO 8601 time with a zone, and ``causes`` a list of objects
that each have a ``name``. Everything else in a record is the daemon's business.
"""

from __future__ import annotations

import contextlib
import dataclasses
import datetime as dt
import errno as errno_codes
import json
import os
import re
import stat
from collections.abc import Callable, Iterator, Mapping, Sequence
from pathlib import Path
from typing import TYPE_CHECKING, Final

from supervisord.compat import StrEnum, from_iso
from supervisord.errors import SrcsError

if TYPE_CHECKING:
    from typing_extensions import Self

REQUIRED_FIELDS: Final = ("seq", "mono_ns", "utc", "from", "to", "causes", "trigger")
"""Fields every record has (``docs/record.md`` describes each)."""

DEFAULT_MAX_BYTES: Final = 4 * 1024 * 1024
MAX_BYTES_RANGE: Final = (4096, 1 << 30)
DEFAULT_KEEP: Final = 4
DEFAULT_FLIGHT_MAX_BYTES: Final = 64 * 1024 * 1024
"""The flight recorder's windows beside the record take at most this many bytes together, by
default (``[record] flight_max_bytes``, SR-7.12): a window is some 10 to 600 KB
(docs/record.md "The flight recorder"), so the windows of a hundred stops and more."""
FLIGHT_MAX_BYTES_RANGE: Final = (4096, 1 << 40)
KEEP_RANGE: Final = (1, 99)

_CHUNK = 4096


class RecordError(SrcsError):
    """The record file could not be written: the record was **not** acknowledged.

    ``errno`` is the OS error number (``errno.ENOSPC`` for a full disk). The daemon counts it
    (``record_errors`` in ``status``) and logs it; it is no stop cause, and the outputs stay
    where the safety core says (``docs/record.md`` "A full disk")."""

    def __init__(self, path: Path, action: str, error: OSError) -> None:
        self.path, self.action, self.errno = path, action, error.errno
        super().__init__(f"cannot {action} {path}: {error.strerror or error}")

    @property
    def disk_full(self) -> bool:
        """True when the file system is out of space (or quota)."""
        return self.errno in (errno_codes.ENOSPC, errno_codes.EDQUOT)


class RecordUnreadable(SrcsError):
    """A record file, or the folder that holds it, is there but cannot be read (no
    permission, an I/O error). A reader says so and stops: it never takes a record it cannot
    read for an empty one (SR-7.9). ``errno`` is the OS error number."""

    def __init__(self, path: Path, error: OSError) -> None:
        self.path, self.errno = Path(path), error.errno
        super().__init__(f"cannot read {path}: {error.strerror or error}")


def _file_kind(mode: int) -> str | None:
    """What a file of ``mode`` is, when it is not a regular file (``None`` when it is)."""
    kinds = (
        (stat.S_ISFIFO, "a FIFO"),
        (stat.S_ISLNK, "a symbolic link"),
        (stat.S_ISDIR, "a directory"),
        (stat.S_ISSOCK, "a socket"),
        (stat.S_ISCHR, "a character device"),
        (stat.S_ISBLK, "a block device"),
    )
    if stat.S_ISREG(mode):
        return None
    return next((name for test, name in kinds if test(mode)), "not a regular file")


def not_a_regular_file(path: Path | str) -> str | None:
    """What ``path`` is when something other than a regular file is there (a FIFO, a symbolic
    link, a device...), else ``None`` (a regular file, or nothing). Never opens it: a FIFO or a
    device must not be opened to find out (SR-7.9)."""
    try:
        mode = os.lstat(path).st_mode
    except OSError:  # nothing there, or not reachable (a file where a folder should be): the
        return None  # open that follows says what is wrong, never this look
    return _file_kind(mode)


class RecordUsageError(SrcsError, ValueError):
    """Our own code passed a record the store cannot file (a field missing or of the wrong
    type, a value JSON cannot hold), or used a closed writer. Nothing was written."""


def _check_record(record: Mapping[str, object]) -> None:
    missing = [f for f in REQUIRED_FIELDS if f not in record]
    if missing:
        raise RecordUsageError(f"record lacks {', '.join(missing)}")
    for key in ("seq", "mono_ns"):
        value = record[key]
        if isinstance(value, bool) or not isinstance(value, int):
            raise RecordUsageError(f"record field {key!r} must be an integer, not {value!r}")
    if parse_utc(record["utc"]) is None:
        raise RecordUsageError(
            f"record field 'utc' must be ISO 8601 with a zone: {record['utc']!r}"
        )
    if cause_names(record) is None:
        raise RecordUsageError("record field 'causes' must be a list of objects with a 'name'")


def parse_utc(value: object) -> dt.datetime | None:
    """``value`` as an aware datetime, or ``None`` if it is not ISO 8601 text with a zone."""
    if not isinstance(value, str):
        return None
    try:
        when = from_iso(value)
    except ValueError:
        return None
    return when if when.tzinfo is not None else None


def format_utc(when: dt.datetime) -> str:
    """``when`` (aware) as the ISO 8601 text records carry, in UTC with microseconds."""
    return when.astimezone(dt.timezone.utc).isoformat(timespec="microseconds")


def cause_names(record: Mapping[str, object]) -> tuple[str, ...] | None:
    """The names in a record's ``causes``, or ``None`` if ``causes`` is malformed."""
    causes = record.get("causes")
    if not isinstance(causes, list):
        return None
    names = []
    for cause in causes:
        if not isinstance(cause, dict) or not isinstance(cause.get("name"), str):
            return None
        names.append(cause["name"])
    return tuple(names)


def encode(record: Mapping[str, object]) -> bytes:
    """One record as its line in the file: compact UTF-8 JSON and a newline.

    Raises :class:`RecordUsageError` for a record the store cannot file."""
    _check_record(record)
    try:
        text = json.dumps(record, ensure_ascii=False, separators=(",", ":"), allow_nan=False)
    except (TypeError, ValueError) as e:
        raise RecordUsageError(f"record is not plain JSON: {e}") from e
    return text.encode() + b"\n"  # json.dumps escapes newlines: one record, one line


def transitions_path(path: Path | str) -> Path:
    """Where the stop transitions of ``path`` are kept apart (``stops.jsonl.transitions``,
    rotated as ``stops.jsonl.transitions.N``): a flood of other records cannot rotate them
    away (SR-7.8, ``docs/record.md`` "Rotation")."""
    path = Path(path)
    return path.with_name(f"{path.name}.transitions")


def record_paths(path: Path | str, keep: int) -> list[tuple[Path, str]]:
    """Every file the record of ``path`` may use, each with what it is: the current file, its
    rotated files, the stop transitions' file and its rotated files."""
    path, stops = Path(path), transitions_path(path)
    files = [(path, "")] + [(rotated(path, n), f"rotated file {n}") for n in range(1, keep + 1)]
    files.append((stops, "stop transitions file"))
    files += [(rotated(stops, n), f"stop transitions file {n}") for n in range(1, keep + 1)]
    return files


def is_stop_transition(record: Mapping[str, object]) -> bool:
    """Whether ``record`` is a change of state into or out of STOPPED: a stop, or the re-arm
    that ended one (SR-7.8). Their rate is bounded by the re-arm rules, not by clients."""
    if record.get("kind", "state_change") != "state_change":
        return False
    before, after = (str(record.get(key, "")).upper() for key in ("from", "to"))
    return before != after and "STOPPED" in (before, after)


def rotated(path: Path, n: int) -> Path:
    """The ``n``-th rotated file of ``path`` (``n`` = 0 is ``path`` itself)."""
    return path if n == 0 else path.with_name(f"{path.name}.{n}")


def record_files(path: Path) -> list[Path]:
    """The record files of ``path`` that exist, oldest first (``path.N`` ... ``path.1``,
    ``path``). Gaps in the numbering (left by a crash during rotation) are skipped."""
    path = Path(path)
    pattern = re.compile(re.escape(path.name) + r"\.([1-9][0-9]*)")
    numbered = []
    try:
        names = os.listdir(path.parent)
    except (FileNotFoundError, NotADirectoryError):
        return []
    except OSError as error:  # there, but not ours to read: say so, never "no records"
        raise RecordUnreadable(path.parent, error) from None
    for name in names:
        m = pattern.fullmatch(name)
        if m:
            numbered.append((int(m.group(1)), path.with_name(name)))
    files = [p for _, p in sorted(numbered, reverse=True)]
    if path.name in names:
        files.append(path)
    return files


def fsync_dir(folder: Path) -> None:
    """Make the directory entries of ``folder`` (creations, renames) durable."""
    fd = os.open(folder, os.O_RDONLY | os.O_DIRECTORY | os.O_CLOEXEC)
    try:
        os.fsync(fd)
    finally:
        os.close(fd)


class RecordWriter:
    """Appends records to ``path`` with fsync per record and bounded, crash-safe rotation.

    Opening creates the file if needed (mode 0640; the directory must exist) and truncates a
    torn tail; ``repaired_bytes`` says how many bytes that removed. ``max_bytes`` bounds each
    file (a single record larger than that gets a file of its own); ``keep`` rotated files are
    kept besides the current one, so the record takes at most about ``(keep + 1) * max_bytes``,
    and as much again for the stop transitions kept apart (``keep_transitions``, SR-7.8).
    Raises :class:`RecordError` if the file cannot be opened or is not a regular file.

    One writer per path, used by one thread at a time: in the daemon, the sink's record lane
    thread (``supervisord/daemon/sink.py``) is the only writer.
    """

    def __init__(
        self,
        path: Path | str,
        max_bytes: int = DEFAULT_MAX_BYTES,
        keep: int = DEFAULT_KEEP,
        *,
        keep_transitions: bool = True,
    ) -> None:
        low, high = MAX_BYTES_RANGE
        if not low <= max_bytes <= high:
            raise RecordUsageError(f"max_bytes must be {low} to {high}, not {max_bytes}")
        if not KEEP_RANGE[0] <= keep <= KEEP_RANGE[1]:
            raise RecordUsageError(f"keep must be {KEEP_RANGE[0]} to {KEEP_RANGE[1]}, not {keep}")
        self.path = Path(path)
        self.max_bytes, self.keep = max_bytes, keep
        self.repaired_bytes = 0
        self.reopens = 0
        """How often the current file was found removed or replaced and opened again."""
        self.last_reopen: str | None = None
        """Why it was opened again the last time (``removed``, ``replaced``), for the log."""
        self._fd: int | None = None
        self._identity = (0, 0)  # (st_dev, st_ino) of the open file
        self._size = 0  # bytes of acknowledged records in the current file
        self._dirty = False  # a failed write may have left bytes past _size
        self._closed = False
        self._unsettled: str | None = None  # what the open left to make durable (_settle)
        self._guard("open", self._open_current)
        self._transitions: RecordWriter | None = None
        if keep_transitions:  # SR-7.8: a second series of the same size, for stops alone
            try:
                self._transitions = RecordWriter(
                    transitions_path(self.path), max_bytes, keep, keep_transitions=False
                )
            except BaseException:
                self.close()
                raise

    # -- public ---------------------------------------------------------------------------

    def append(self, record: Mapping[str, object]) -> None:
        """Write ``record`` as one line and fsync it; it is acknowledged when this returns.

        Raises :class:`RecordUsageError` (nothing written) for a record the store cannot file,
        :class:`RecordError` for an OS error (not acknowledged; the next append first cuts
        off whatever part of it reached the file)."""
        self.append_fitting([record])

    def append_fitting(self, records: Sequence[Mapping[str, object]]) -> int:
        """Write the first of ``records`` and as many after it as fit in the current file,
        with one write and one fsync for them all; return how many that is. Each is
        acknowledged when this returns: a queue of records costs one fsync, not one each
        (SR-7.7: at the exit's deadline, on a slow disk). Errors as :meth:`append`; then none
        of them is acknowledged. ``records`` must not be empty."""
        if self._closed:
            raise RecordUsageError(f"record writer for {self.path} is closed")
        lines = [encode(record) for record in records]  # a bad record: nothing written
        written: list[int] = []
        self._guard("append to", lambda: written.append(self._append(lines)))
        if self._transitions is not None:
            stops = [record for record in records[: written[0]] if is_stop_transition(record)]
            while stops:
                stops = stops[self._transitions.append_fitting(stops) :]
        return written[0]

    def close(self) -> None:
        """Close the files. Every acknowledged record is already on disk. Idempotent."""
        self._closed = True
        fd, self._fd = self._fd, None
        if fd is not None:
            os.close(fd)
        if self._transitions is not None:
            self._transitions.close()

    @property
    def size(self) -> int:
        """Bytes of acknowledged records in the current file."""
        return self._size

    def __enter__(self) -> Self:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()

    # -- internals --------------------------------------------------------------------------

    def _guard(self, action: str, step: Callable[[], None]) -> None:
        try:
            step()
        except OSError as e:
            self._dirty = True
            raise RecordError(self.path, action, e) from e

    def _append(self, lines: list[bytes]) -> int:
        if self._fd is None:
            self._open_current()
        else:
            self._follow_path()
            if self._dirty:
                self._cut_back()
        if self._size > 0 and self._size + len(lines[0]) > self.max_bytes:
            self._rotate()
        count, size = 1, self._size + len(lines[0])
        while count < len(lines) and size + len(lines[count]) <= self.max_bytes:
            size += len(lines[count])
            count += 1
        data = b"".join(lines[:count])
        self._write(data)
        if self._follow_path():
            # Removed or replaced while we wrote: the lines are in a file no reader finds.
            # Write them again into the file now at the path (SR-7.9).
            self._write(data)
        return count

    def _write(self, line: bytes) -> None:
        if self._size > 0 and self._size + len(line) > self.max_bytes:
            self._rotate()
        if self._unsettled is not None:
            self._settle()
        fd = self._fd
        assert fd is not None
        view = memoryview(line)
        while view:
            written = os.write(fd, view)
            view = view[written:]
        os.fsync(fd)
        self._size += len(line)

    def _follow_path(self) -> bool:
        """If the file at ``path`` is no longer the one open (a cleanup job removed it, a
        log rotation renamed it and created another), open the one at ``path`` (creating it)
        and say so: ``True``. One ``lstat``, so cheap enough for every record (SR-7.9)."""
        try:
            now = os.lstat(self.path)
            reason = None if (now.st_dev, now.st_ino) == self._identity else "replaced"
        except FileNotFoundError:
            reason = "removed"
        if reason is None:
            return False
        fd, self._fd = self._fd, None
        if fd is not None:
            os.close(fd)  # every acknowledged record in it is on disk already
        self.reopens += 1
        self.last_reopen = reason
        self._open_current()
        return True

    def _open_current(self) -> None:
        """Open (creating if needed) the current file and truncate a torn tail.

        Only a regular file is taken: whatever else is at the path (a FIFO, whose read would
        never return; a symlink; a device) is refused without being opened, and the open
        itself neither blocks nor follows a link, in case one appears meanwhile (SR-7.9)."""
        kind = not_a_regular_file(self.path)
        if kind is not None:
            raise OSError(errno_codes.EINVAL, f"{kind} is there, not a regular file")
        flags = os.O_RDWR | os.O_APPEND | os.O_CREAT | os.O_CLOEXEC
        flags |= os.O_NOFOLLOW | os.O_NONBLOCK | os.O_NOCTTY
        fd = os.open(self.path, flags, 0o640)
        try:
            info = os.fstat(fd)
            kind = _file_kind(info.st_mode)
            if kind is not None:  # it changed between the look and the open
                raise OSError(errno_codes.EINVAL, f"{kind} is there, not a regular file")
            os.set_blocking(fd, True)
            cut = self._truncate_torn_tail(fd)
            self.repaired_bytes += cut
            self._size = os.fstat(fd).st_size
        except BaseException:  # whatever stops us, do not leak the descriptor
            os.close(fd)
            raise
        self._fd, self._dirty = fd, False
        self._identity = (info.st_dev, info.st_ino)
        self._unsettled = "cut" if cut else "name"

    def _settle(self) -> None:
        """Make the open durable before the first record goes into the file: its name (new,
        or renamed by an interrupted rotation) and a torn tail's cut. The first append does
        it, on the lane that writes the records, not the open: the daemon's start opens its
        record on the real-time loop's thread, which must not wait on the disk (SR-7.5,
        SR-9.8). Until then nothing in the file needs to be durable: a crash before the
        first record loses no record, and a torn tail that comes back is cut again."""
        assert self._fd is not None
        fsync_dir(self.path.parent)
        if self._unsettled == "cut":
            os.fsync(self._fd)
        self._unsettled = None

    @staticmethod
    def _truncate_torn_tail(fd: int) -> int:
        """Cut the file after its last newline; return how many bytes that removed."""
        size = os.fstat(fd).st_size
        if size == 0 or os.pread(fd, 1, size - 1) == b"\n":
            return 0
        end = size
        keep = 0
        while end > 0:
            start = max(0, end - _CHUNK)
            chunk = os.pread(fd, end - start, start)
            nl = chunk.rfind(b"\n")
            if nl >= 0:
                keep = start + nl + 1
                break
            end = start
        os.ftruncate(fd, keep)  # made durable with the first record (_settle)
        return size - keep

    def _cut_back(self) -> None:
        """After a failed append: drop any bytes past the last acknowledged record."""
        assert self._fd is not None
        if os.fstat(self._fd).st_size != self._size:
            os.ftruncate(self._fd, self._size)
            os.fsync(self._fd)
        self._dirty = False

    def _rotate(self) -> None:
        """Shift the files up one number (renames only, oldest first), then start a new file.

        The current file's records are already fsynced, so it is closed first. A crash between
        any two steps leaves each record in one file, in age order (see the module docstring);
        if a step fails, the next append reopens ``path`` and tries again.
        """
        assert self._fd is not None
        os.close(self._fd)
        self._fd = None
        for n in range(self.keep - 1, 0, -1):
            # A missing file is a gap left by an earlier crash, or fewer files than keep.
            with contextlib.suppress(FileNotFoundError):
                os.replace(rotated(self.path, n), rotated(self.path, n + 1))
        os.replace(self.path, rotated(self.path, 1))
        fsync_dir(self.path.parent)
        self._open_current()


# ---------------------------------------------------------------------------------------------
# Reading


class BadLineReason(StrEnum):
    """Why a line of a record file is not a record."""

    TORN_TAIL = "torn_tail"
    """The last line of a file is unterminated or undecodable: a write cut short by a crash.
    It was never acknowledged; it is reported so that the crash is visible, never misread."""
    NOT_JSON = "not_json"
    """A line that is not a JSON object, not at the end of a file (damage)."""
    NOT_A_RECORD = "not_a_record"
    """A JSON object that lacks the fields the store needs."""
    NOT_A_FILE = "not_a_file"
    """Something other than a regular file (a FIFO, a device, a symlink) has a record file's
    name; it is not opened (a FIFO would never answer). Reported as line 0 (SR-7.9)."""


@dataclasses.dataclass(frozen=True)
class BadLine:
    """A line that is not a record: where it is, why, and its start (at most 200 chars)."""

    file: Path
    line: int
    reason: BadLineReason
    text: str


@dataclasses.dataclass(frozen=True)
class StoredRecord:
    """One record as read back: the JSON object, and where it was found.

    ``data`` is the object as written; the properties give the fields the store knows."""

    data: Mapping[str, object]
    file: Path
    line: int

    @property
    def seq(self) -> int:
        """The record's sequence number."""
        value = self.data["seq"]
        assert isinstance(value, int)
        return value

    @property
    def utc(self) -> dt.datetime:
        """The record's wall-clock time (aware)."""
        when = parse_utc(self.data["utc"])
        assert when is not None
        return when

    @property
    def cause_names(self) -> tuple[str, ...]:
        """The names of the record's causes."""
        names = cause_names(self.data)
        assert names is not None
        return names

    def matches_cause(self, cause: str) -> bool:
        """Whether a cause of the record is ``cause`` or a cause under it: ``client_lost``
        matches ``client_lost`` and ``client_lost:autonomy``, not ``client_lost_x``."""
        return any(n == cause or n.startswith(cause + ":") for n in self.cause_names)


def _is_record(obj: object) -> bool:
    if not isinstance(obj, dict) or any(f not in obj for f in REQUIRED_FIELDS):
        return False
    seq, mono = obj["seq"], obj["mono_ns"]
    return (
        isinstance(seq, int)
        and isinstance(mono, int)
        and parse_utc(obj["utc"]) is not None
        and cause_names(obj) is not None
    )


def scan_file(file: Path) -> Iterator[StoredRecord | BadLine]:
    """Every line of one record file, as a :class:`StoredRecord` or a :class:`BadLine`, unfiltered.
    A file that does not exist (rotated away meanwhile) has no lines; something other than a
    regular file is one ``NOT_A_FILE`` bad line, never read (SR-7.9)."""
    kind = not_a_regular_file(file)
    if kind is not None:
        yield BadLine(file, 0, BadLineReason.NOT_A_FILE, kind)
        return
    flags = os.O_RDONLY | os.O_CLOEXEC | os.O_NOFOLLOW | os.O_NONBLOCK | os.O_NOCTTY
    try:
        fd = os.open(file, flags)
    except FileNotFoundError:
        return  # rotated away while we listed: the next listing shows it under a new name
    except OSError as error:
        if error.errno != errno_codes.ELOOP:  # not allowed, or the disk fails: not a bad line
            raise RecordUnreadable(file, error) from None
        yield BadLine(file, 0, BadLineReason.NOT_A_FILE, str(error))  # a symlink put there since
        return
    kind = _file_kind(os.fstat(fd).st_mode)
    if kind is not None:  # replaced since the look
        os.close(fd)
        yield BadLine(file, 0, BadLineReason.NOT_A_FILE, kind)
        return
    with os.fdopen(fd, "rb") as handle:
        lines = iter(handle)
        current = next(lines, None)
        number = 0
        while current is not None:
            number += 1
            following = next(lines, None)
            last = following is None
            yield _parse_line(file, number, current, last)
            current = following


def _parse_line(file: Path, number: int, raw: bytes, last: bool) -> StoredRecord | BadLine:
    def bad(reason: BadLineReason) -> BadLine:
        return BadLine(file, number, reason, raw[:200].decode(errors="replace"))

    try:
        obj = json.loads(raw)
    # UnicodeDecodeError and JSONDecodeError are ValueErrors; a line nested thousands deep
    # raises RecursionError in the decoder (SR-8.7: a bad line, never a traceback)
    except (ValueError, RecursionError):
        obj = None
    if last and (not raw.endswith(b"\n") or not isinstance(obj, dict)):
        return bad(BadLineReason.TORN_TAIL)
    if not isinstance(obj, dict):
        return bad(BadLineReason.NOT_JSON)
    if not _is_record(obj):
        return bad(BadLineReason.NOT_A_RECORD)
    return StoredRecord(obj, file, number)


def read_records(
    path: Path | str,
    since: dt.datetime | None = None,
    until: dt.datetime | None = None,
    cause: str | None = None,
) -> Iterator[StoredRecord | BadLine]:
    """The records of ``path`` and its rotated files, oldest first, with the bad lines met;
    before them, the stop transitions older than the oldest of those files' records, from
    the transitions' own files (SR-7.8: what rotation dropped, the stops stay).

    Only records with ``since <= utc < until`` (aware datetimes) and, when ``cause`` is given,
    a matching cause (:meth:`StoredRecord.matches_cause`) are yielded; bad lines are always yielded,
    so that the caller can report them. Safe to run while the writer appends or rotates: a
    file rotated away between listing and opening is skipped.
    """
    files = record_files(Path(path))
    oldest = _first_seq(files)
    for item in _older_transitions(Path(path), oldest):
        if isinstance(item, BadLine) or _wanted(item, since, until, cause):
            yield item
    for file in files:
        for item in scan_file(file):
            if isinstance(item, BadLine) or _wanted(item, since, until, cause):
                yield item


def _wanted(
    item: StoredRecord, since: dt.datetime | None, until: dt.datetime | None, cause: str | None
) -> bool:
    if since is not None and item.utc < since:
        return False
    if until is not None and item.utc >= until:
        return False
    return cause is None or item.matches_cause(cause)


def _first_seq(files: list[Path]) -> int | None:
    """The sequence number of the oldest record in ``files`` (oldest first)."""
    for file in files:
        for item in scan_file(file):
            if isinstance(item, StoredRecord):
                return item.seq
    return None


def _older_transitions(path: Path, oldest: int | None) -> Iterator[StoredRecord | BadLine]:
    """The kept stop transitions of ``path`` from before ``oldest`` (all if ``None``)."""
    for file in record_files(transitions_path(path)):
        for item in scan_file(file):
            if isinstance(item, BadLine) or oldest is None or item.seq < oldest:
                yield item


def last_record(path: Path | str) -> StoredRecord | None:
    """The newest record of ``path`` or of its kept stop transitions (to continue its ``seq``
    after a restart), or ``None``. Reads only the newest file of each that holds a record."""
    found = [_last_in(record_files(p)) for p in (Path(path), transitions_path(path))]
    records = [record for record in found if record is not None]
    return max(records, key=lambda record: record.seq) if records else None


def _last_in(files: list[Path]) -> StoredRecord | None:
    for file in reversed(files):
        found = None
        for item in scan_file(file):
            if isinstance(item, StoredRecord):
                found = item
        if found is not None:
            return found
    return None
