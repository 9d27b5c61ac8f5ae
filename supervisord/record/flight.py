"""The flight recorder's window files: the safety core's inputs before a stop, beside the record
(SR-7.10 to SR-7.12; ``docs/record.md`` "The flight recorder").

With every stop record the daemon writes one window: ``PATH.flight/SEQ.jsonl``, where ``PATH``
is the record file and ``SEQ`` the stop record's sequence number. JSON Lines:

1. the header: ``format``, ``version`` (of this layout and of the inputs' encoding,
   :data:`~supervisord.record.flight_codec.VERSION`), ``srcsd`` (the version that wrote it),
   ``seq``, ``stop`` (the stop record itself), ``config`` (the core's configuration),
   ``sequence_offset`` (what the daemon adds to the core's record numbers), ``window_ms``,
   ``inputs`` (how many input lines follow) and ``base``: where a replay starts, ``start`` (a
   fresh core at ``now_ns``: the daemon's start) or ``snapshot`` (the core's state then, on the
   next line), or ``none`` with a ``reason`` (the bound cut the window's start: no replay);
2. for ``snapshot``, one line ``{"snapshot": ...}`` (:mod:`supervisord.safety.snapshot`);
3. one line per input, oldest first (:mod:`supervisord.record.flight_codec`);
4. the trailer ``{"end": N}``, so that a cut file is never taken for a whole one.

A window is written to a temporary name, fsynced, renamed into place and the directory fsynced:
a reader sees a whole window or none. Each is at most the record's ``max_bytes`` and the
windows' ``budget`` (a window that would be larger starts from a later base, or keeps no base),
and the newest are kept as long as they take at most ``budget`` bytes together (the record's
``flight_max_bytes``, SR-7.12): a byte budget, not a count, so that small windows of many stops
stay while one large window cannot fill the disk. Only a directory is used as ``PATH.flight``
and only regular files are written in it, opened without following a link (SR-7.9's rule for
records).
"""

from __future__ import annotations

import contextlib
import dataclasses
import json
import math
import os
import re
import stat
from collections.abc import Iterator, Mapping
from pathlib import Path
from typing import Any, Final

from supervisord.lane import hand_over
from supervisord.record.flight_codec import (
    VERSION,
    FlightFormatError,
    config_from_json,
    config_to_json,
    event_from_json,
    event_to_json,
)
from supervisord.record.flight_times import check_moments
from supervisord.record.jsonl import DEFAULT_FLIGHT_MAX_BYTES as DEFAULT_BUDGET
from supervisord.record.stop import StopRecord
from supervisord.safety.config import SafetyConfig
from supervisord.safety.events import Event

FORMAT: Final = "srcs-flight"
SUFFIX: Final = ".jsonl"
YIELD_EVERY: Final = 64
"""Inputs encoded between two hand-overs of the interpreter's lock (``lane.hand_over``): the
lane's thread never holds the loop's thread back for more than about that many encodings
(SR-7.12)."""
MAX_NESTING: Final = 64
"""How deep a window's line may nest (objects and lists). A window's deepest line is the
snapshot's, some ten levels for a core with clients and causes; a deeper one is damaged, and is
refused as that before anything walks it with the interpreter's own stack (SR-7.13)."""
_NAME = re.compile(r"([1-9][0-9]*)\.jsonl")
_TEMPORARY = re.compile(r"\.([1-9][0-9]*)\.jsonl\.tmp")

Json = Any


class FlightError(Exception):
    """A window could not be written (``errno`` the OS error's, ``None`` for another reason):
    counted and logged, never a stop (as a record that cannot be written, SR-7.6)."""

    def __init__(self, message: str, errno: int | None = None) -> None:
        super().__init__(message)
        self.errno = errno


def flight_dir(path: Path | str) -> Path:
    """Where the windows of the record ``path`` go: ``PATH.flight``."""
    path = Path(path)
    return path.with_name(f"{path.name}.flight")


def window_path(path: Path | str, seq: int) -> Path:
    """The window of the stop record ``seq`` of the record ``path``."""
    return flight_dir(path) / f"{seq}{SUFFIX}"


def record_of(window: Path) -> Path | None:
    """The record file a window file belongs to, from its folder's name (``PATH.flight``)."""
    folder = window.parent
    if folder.name.endswith(".flight") and len(folder.name) > len(".flight"):
        return folder.with_name(folder.name[: -len(".flight")])
    return None


@dataclasses.dataclass(frozen=True, slots=True)
class Base:
    """Where a replay can start: before the input numbered ``index`` (inputs are counted from
    the daemon's start), at ``now_ns`` on the loop's clock, after the record ``after_seq``,
    from the core's ``state`` (a snapshot), or from a fresh core when ``state`` is ``None``
    (the daemon's start)."""

    index: int
    now_ns: int
    after_seq: int
    state: Json | None


@dataclasses.dataclass(frozen=True, slots=True)
class Window:
    """What the loop hands over with a stop record (immutable; the lane encodes it): the ring's
    inputs, the last of them numbered ``end - 1``, and the bases that reach into them, oldest
    first; ``cut`` says why there is none."""

    stop: StopRecord
    """The stop's record, typed: its JSON is made only where the window is encoded."""
    config: SafetyConfig
    sequence_offset: int
    inputs: tuple[Event, ...]
    end: int
    bases: tuple[Base, ...]
    window_ns: int
    version: str
    cut: str = ""


@dataclasses.dataclass(frozen=True)
class LoadedWindow:
    """A window read back from its file."""

    path: Path
    header: Mapping[str, Json]
    config: SafetyConfig
    base: Mapping[str, Json]
    snapshot: Json | None
    inputs: list[Event]

    @property
    def seq(self) -> int:
        value = self.header.get("seq")
        return value if isinstance(value, int) else 0

    @property
    def stop(self) -> Mapping[str, Json]:
        stop = self.header.get("stop")
        return stop if isinstance(stop, dict) else {}


def _line(value: Json) -> bytes:
    # ASCII with escapes: any text an input carries (a lone surrogate of an undecodable login
    # name included) goes through and comes back the same.
    return json.dumps(value, separators=(",", ":"), allow_nan=False).encode() + b"\n"


def encode_window(window: Window, max_bytes: int) -> bytes:
    """The file's bytes: from the oldest base whose window fits ``max_bytes``, else from the
    next; with no base that fits, the newest inputs that do, and no replay (``base`` none)."""
    first = window.end - len(window.inputs)
    start = min((b.index for b in window.bases), default=first)
    inputs = window.inputs[start - first :]
    lines = []
    for number, event in enumerate(inputs, 1):
        lines.append(_line(event_to_json(event)))
        if number % YIELD_EVERY == 0:
            hand_over()  # let the loop's thread have the interpreter (SR-7.12)
    header: dict[str, Json] = {
        "format": FORMAT,
        "version": VERSION,
        "srcsd": window.version,
        "seq": window.stop.seq,
        "sequence_offset": window.sequence_offset,
        "window_ms": window.window_ns // 1_000_000,
        "config": config_to_json(window.config),
        "stop": window.stop.json(),
    }
    for base in window.bases:
        kept = lines[base.index - start :]
        if base.state is None:
            described: dict[str, Json] = {"kind": "start"}
            extra = b""
        else:
            described, extra = {"kind": "snapshot"}, _line({"snapshot": base.state})
        described |= {"now_ns": base.now_ns, "after_seq": base.after_seq}
        data = _assemble(header | {"inputs": len(kept), "base": described}, extra, kept)
        if len(data) <= max_bytes:
            return data
    reason = window.cut or "the window is larger than the record's max_bytes"
    header |= {"base": {"kind": "none", "reason": reason}}
    kept, size = [], len(_line(header | {"inputs": len(lines)})) + len(_line({"end": len(lines)}))
    for line in reversed(lines):  # the newest inputs that fit, for a person to read
        if size + len(line) > max_bytes:
            break
        kept.append(line)
        size += len(line)
    kept.reverse()
    return _assemble(header | {"inputs": len(kept)}, b"", kept)


def _assemble(header: Mapping[str, Json], extra: bytes, lines: list[bytes]) -> bytes:
    return b"".join([_line(dict(header)), extra, *lines, _line({"end": len(lines)})])


class FlightWriter:
    """Writes windows beside the record ``path``, each at most ``max_bytes`` and ``budget``,
    and keeps the newest that take at most ``budget`` bytes together. Used by one thread: the
    sink's flight lane (``supervisord/daemon/sink.py``)."""

    def __init__(self, path: Path | str, max_bytes: int, budget: int = DEFAULT_BUDGET) -> None:
        self.path = Path(path)
        self.folder = flight_dir(self.path)
        self.max_bytes, self.budget = max_bytes, budget

    def write(self, window: Window) -> Path:
        """Encode and write ``window`` (its stop record's ``seq`` names it), then drop the
        oldest windows past the budget. Raises :class:`FlightError`."""
        return self.write_bytes(window)[0]

    def write_bytes(self, window: Window) -> tuple[Path, bytes]:
        """:meth:`write`, and the bytes written (what the journal's copy carries, SR-13.12)."""
        seq = window.stop.seq
        if not isinstance(seq, int) or isinstance(seq, bool) or seq < 1:
            raise FlightError(f"a stop record without a sequence number: {seq!r}")
        try:
            data = encode_window(window, min(self.max_bytes, self.budget))
        except (FlightFormatError, TypeError, ValueError) as error:
            raise FlightError(f"cannot encode the window of record {seq}: {error}") from error
        try:
            folder = self._open_folder()
            try:
                self._write_file(folder, seq, data)
                self._prune(folder, seq)
            finally:
                os.close(folder)
        except OSError as error:
            raise FlightError(
                f"cannot write {window_path(self.path, seq)}: {error.strerror or error}",
                error.errno,
            ) from error
        return window_path(self.path, seq), data

    def _open_folder(self) -> int:
        """The windows' folder, created if missing; only a directory, never through a link."""
        with contextlib.suppress(FileExistsError):
            os.mkdir(self.folder, 0o750)
        mode = os.lstat(self.folder).st_mode
        if not stat.S_ISDIR(mode):
            kind = "a symbolic link" if stat.S_ISLNK(mode) else "not a directory"
            raise OSError(0, f"{self.folder} is {kind}")
        flags = os.O_RDONLY | os.O_DIRECTORY | os.O_NOFOLLOW | os.O_CLOEXEC
        return os.open(self.folder, flags)

    @staticmethod
    def _write_file(folder: int, seq: int, data: bytes) -> None:
        temporary, name = f".{seq}{SUFFIX}.tmp", f"{seq}{SUFFIX}"
        with contextlib.suppress(FileNotFoundError):
            os.unlink(temporary, dir_fd=folder)  # a crashed write's: never opened, replaced
        flags = os.O_WRONLY | os.O_CREAT | os.O_EXCL | os.O_NOFOLLOW | os.O_CLOEXEC
        fd = os.open(temporary, flags, 0o640, dir_fd=folder)
        try:
            view = memoryview(data)
            while view:
                view = view[os.write(fd, view) :]
            os.fsync(fd)
        finally:
            os.close(fd)
        # A rename replaces whatever was at the name without opening it (a FIFO, a link).
        os.rename(temporary, name, src_dir_fd=folder, dst_dir_fd=folder)
        os.fsync(folder)

    def _prune(self, folder: int, seq: int) -> None:
        """Keep the newest windows that take at most :attr:`budget` bytes together; the one
        just written always stays (it is at most the budget, but for a header alone larger). A
        window numbered above ``seq`` is of a record that was removed since (numbers only grow
        with the record): it goes first; so does a temporary file left by a write that never
        finished."""
        windows = []
        for name in os.listdir(folder):
            if (match := _NAME.fullmatch(name)) is not None:
                number = int(match.group(1))
                windows.append((number > seq, number, name))
            elif (match := _TEMPORARY.fullmatch(name)) is not None and int(match.group(1)) != seq:
                windows.append((True, 0, name))  # left by a write that never finished
        taken, full = 0, False
        for stale, _, name in sorted(windows, key=lambda w: (not w[0], -w[1])):
            if not (stale or full):
                try:
                    size = os.stat(name, dir_fd=folder, follow_symlinks=False).st_size
                except FileNotFoundError:
                    continue
                full = taken > 0 and taken + size > self.budget  # the newest always stays
                taken += 0 if full else size
            if stale or full:
                with contextlib.suppress(FileNotFoundError, IsADirectoryError):
                    os.unlink(name, dir_fd=folder)


def windows(path: Path | str) -> list[tuple[int, Path]]:
    """The windows of the record ``path`` that exist, oldest first."""
    folder = flight_dir(path)
    try:
        names = os.listdir(folder)
    except (FileNotFoundError, NotADirectoryError):
        return []
    found = [(int(m.group(1)), folder / n) for n in names if (m := _NAME.fullmatch(n))]
    return sorted(found)


def read_window(path: Path) -> LoadedWindow:
    """A window file read back. Raises :class:`FlightFormatError` for anything that is not a
    whole window of this version, ``OSError`` when it cannot be read."""
    flags = os.O_RDONLY | os.O_CLOEXEC | os.O_NOFOLLOW | os.O_NONBLOCK | os.O_NOCTTY
    fd = os.open(path, flags)
    try:
        if not stat.S_ISREG(os.fstat(fd).st_mode):
            raise FlightFormatError(f"{path} is not a regular file")
        with os.fdopen(fd, "rb", closefd=False) as file:
            lines = list(_json_lines(file))
    finally:
        os.close(fd)
    if not lines:
        raise FlightFormatError(f"{path} is empty")
    header, rest = lines[0], lines[1:]
    if not isinstance(header, dict) or header.get("format") != FORMAT:
        raise FlightFormatError(f"{path} is not a flight recorder window")
    if header.get("version") != VERSION:
        raise FlightFormatError(
            f"{path} is a window of version {header.get('version')!r}; this reads {VERSION}"
        )
    base = header.get("base")
    if not isinstance(base, dict):
        raise FlightFormatError(f"{path}: no base")
    snapshot = None
    if base.get("kind") == "snapshot":
        if not rest or not isinstance(rest[0], dict) or "snapshot" not in rest[0]:
            raise FlightFormatError(f"{path}: the snapshot line is missing")
        snapshot, rest = rest[0]["snapshot"], rest[1:]
    count = header.get("inputs")
    if not rest or rest[-1] != {"end": count} or len(rest) - 1 != count:
        raise FlightFormatError(f"{path} is cut short: {count!r} inputs announced")
    inputs = [event_from_json(line) for line in rest[:-1]]
    stop = header.get("stop")
    # Every time in range before anything replays or exports it (SR-7.13).
    check_moments(stop if isinstance(stop, dict) else {}, base, [event.now for event in inputs])
    config = config_from_json(header.get("config"))
    return LoadedWindow(path, header, config, base, snapshot, inputs)


def _json_lines(file: Any) -> Iterator[Json]:
    for number, raw in enumerate(file, 1):
        try:
            value = json.loads(raw, parse_constant=_no_constant, parse_float=_finite)
        except ValueError as error:
            raise FlightFormatError(f"line {number} is not JSON: {error}") from error
        except RecursionError as error:  # deeper than the parser's own stack can go
            raise FlightFormatError(f"line {number} is nested too deep") from error
        if _nesting_over(value, MAX_NESTING):
            raise FlightFormatError(f"line {number} is nested deeper than {MAX_NESTING} levels")
        yield value


def _no_constant(name: str) -> float:
    """``NaN``, ``Infinity``, ``-Infinity``: no JSON, and the daemon never writes them
    (``allow_nan=False``); a window with one is damaged (SR-7.13)."""
    raise ValueError(f"{name} is not a JSON number")


def _finite(text: str) -> float:
    """A JSON number with a fraction or exponent; one too large for a float (``1e999``) is
    refused as the infinity it would be read as (SR-7.13)."""
    value = float(text)
    if not math.isfinite(value):
        raise ValueError(f"{text[:40]} is beyond a float's range")
    return value


def _nesting_over(value: Json, limit: int) -> bool:
    """Whether ``value`` nests objects and lists more than ``limit`` deep; walked with a list of
    its own, never the interpreter's stack."""
    todo = [(value, 1)]
    while todo:
        item, depth = todo.pop()
        if isinstance(item, dict | list):
            if depth > limit:
                return True
            todo.extend(
                (child, depth + 1) for child in (item.values() if isinstance(item, dict) else item)
            )
    return False
