"""``srcsctl log``: the record of stops, filtered by time and cause, as text or JSON lines.

journalctl's habits (docs/srcsctl.md "log"): ``-n`` alone is the last 10, ``-e`` the last
1000, ``-f`` prints the last 10 and then each record as it is written (the file is watched,
:mod:`follow`), ``-r`` newest first, ``-b`` since the machine booted, ``-o`` its output modes,
``-- No entries --`` when nothing matched, and journalctl's relative times. One time rule with
``watch`` (:mod:`times`), one line per record with ``watch`` and the demo (:mod:`record_text`).

``--cause NAME`` selects the records *about* that cause: those that raised, updated, cleared or
released it (the record's ``changes``), as ``journalctl`` selects the entries a unit wrote;
``--cause-present NAME`` the records made while it was present, latched included.
"""

from __future__ import annotations

import datetime as dt
import json
import os
import sys
from collections.abc import Mapping
from pathlib import Path
from typing import IO, Any, Final

from supervisord.cli.cause_names import CauseFilter
from supervisord.cli.follow import Follower
from supervisord.cli.interrupt import interruptible
from supervisord.cli.log_options import FOLLOW_LAST
from supervisord.cli.record_print import JSON_OUTPUTS, NO_ENTRIES, RecordPrinter
from supervisord.cli.record_text import record_line, written_line
from supervisord.cli.tally_text import tally_json, tally_line
from supervisord.cli.terminal_text import printable
from supervisord.cli.times import BadTime, parse_time, show_time
from supervisord.record.counted import Tally, changes
from supervisord.record.jsonl import BadLine, RecordUnreadable, StoredRecord, read_records
from supervisord.record.stop import StopRecord, read_written

EXIT_BAD_INPUT: Final = 2
PROC_STAT: Final = Path("/proc/stat")


class NoBootTime(Exception):
    """``/proc/stat`` gives no boot time (``-b`` cannot be served)."""


def boot_time(stat: Path = PROC_STAT) -> dt.datetime:
    """When the machine booted: ``/proc/stat``'s ``btime`` (seconds since the epoch, UTC).
    Raises :class:`NoBootTime` when it cannot be read."""
    try:
        for line in stat.read_text(encoding="ascii", errors="replace").splitlines():
            name, _, value = line.partition(" ")
            if name == "btime" and value.strip().isdigit():
                return dt.datetime.fromtimestamp(int(value), dt.timezone.utc)
    except OSError as error:
        raise NoBootTime(f"{stat}: {error.strerror}") from None
    raise NoBootTime(f"{stat} has no btime")


def format_record(
    data: Mapping[str, Any],
    *,
    utc: bool = False,
    previous: StopRecord | None = None,
    causes: bool = False,
) -> str:
    """One line: the time (local with its offset, or UTC), then what happened
    (:func:`~supervisord.cli.record_text.record_line`; a line that is no typed record, as
    written)."""
    record = read_written(data)
    if record is None:
        return written_line(data, show_time(data.get("utc"), utc=utc))
    return record_line(record, show_time(record.utc, utc=utc), previous=previous, causes=causes)


def run_log(
    path: Path,
    out: IO[str],
    errors: IO[str],
    *,
    since: str | None = None,
    until: str | None = None,
    cause: CauseFilter | None = None,
    cause_present: CauseFilter | None = None,
    output: str = "short",
    utc: bool = False,
    last: int | None = None,
    follow: bool = False,
    reverse: bool = False,
    causes: bool = False,
    this_boot: bool = False,
    quiet: bool = False,
    summary: bool = False,
) -> int:
    """Print the records (the ``last`` N of them when given; newest first with ``reverse``);
    with ``follow``, then every record appended after, until Ctrl-C or SIGTERM (exit 0). A
    record (or its folder) that cannot be read raises :class:`RecordUnreadable`. Nothing
    matched: :data:`NO_ENTRIES` on ``out`` (unless ``quiet``, following or JSON)."""
    try:
        start, end = _times(since, until, utc=utc, this_boot=this_boot)
    except (BadTime, NoBootTime) as error:
        print(f"srcsctl log: {error}", file=errors)
        return EXIT_BAD_INPUT
    wanted = _Filter(start, end, cause, cause_present)
    refused = _refusal(path, follow=follow, reverse=reverse, summary=summary)
    if refused:
        print(f"srcsctl log: {refused}", file=errors)
        return EXIT_BAD_INPUT
    if follow and last is None and start is None and end is None:
        last = FOLLOW_LAST
    printer = RecordPrinter(out, output=output, utc=utc, causes=causes)
    follower: Follower | None = None
    try:  # from the handlers on: a signal that comes while the follower opens ends it too
        if follow:
            interruptible()
            follower = Follower(path)  # opened first: nothing falls between
        every = _scan(path, start, end, errors)
        records = wanted.select(every)
        shown = [] if last == 0 else records[-last:] if last is not None else records
        if summary:
            _summarize(shown, wanted, out, json_lines=output in JSON_OUTPUTS, utc=utc)
            return 0
        # the one before: what the first changed
        printer.previous = wanted.before.get(_identity(shown[0])) if shown else None
        printer.show([r.data for r in shown], reverse=reverse)
        if follower is None:
            if not shown and not quiet and output not in JSON_OUTPUTS:
                print(NO_ENTRIES, file=out)
            return 0
        # A record written between the follower's start and the scan is in both: shown once.
        # Known by seq and monotonic time, so that a numbering started again is still shown.
        scanned = {_identity(record) for record in every}
        for fresh in follower:
            new = wanted.select([r for r in fresh if _identity(r) not in scanned])
            if new:
                printer.show([r.data for r in new])
    except KeyboardInterrupt:
        return 0
    finally:
        if follower is not None:
            follower.close()
    return 0  # pragma: no cover - the follower never ends by itself


def _summarize(
    shown: list[StoredRecord], wanted: _Filter, out: IO[str], *, json_lines: bool, utc: bool
) -> None:
    """The records shown, counted as ``fleet --summary`` counts a robot's (SR-13.9): one line,
    or one JSON object; escaped (SR-13.7)."""
    tally = Tally()
    for stored in shown:
        before = wanted.before.get(_identity(stored))
        tally.add(read_written(stored.data), None if before is None else read_written(before))
    if json_lines:
        out.write(json.dumps(tally_json(tally)) + "\n")
    else:
        out.write(printable(tally_line(tally, utc=utc)) + "\n")
    out.flush()


def _times(
    since: str | None, until: str | None, *, utc: bool, this_boot: bool
) -> tuple[dt.datetime | None, dt.datetime | None]:
    """``--since`` (or the boot, whichever is later, with ``-b``) and ``--until`` as times.
    Raises :class:`BadTime` or :class:`NoBootTime`."""
    now = dt.datetime.now(dt.timezone.utc)
    start = parse_time(since, now, utc=utc) if since else None
    end = parse_time(until, now, utc=utc) if until else None
    if this_boot:
        booted = boot_time()
        start = booted if start is None else max(start, booted)
    return start, end


def _refusal(path: Path, *, follow: bool, reverse: bool, summary: bool = False) -> str | None:
    """Why these options cannot be served, or ``None``."""
    if follow and reverse:
        return "-r and -f do not go together (as in journalctl)"
    if follow and summary:
        return "--summary and -f do not go together"
    if not _there(path) and not follow:
        return f"{path}: no record yet"
    if follow and not _there(path.parent):
        return f"{path.parent}: no such directory"
    return None


def _there(path: Path) -> bool:
    """Whether something is at ``path``; a folder on the way closed to this user is
    :class:`RecordUnreadable`, never "no record yet"."""
    try:
        os.lstat(path)
    except (FileNotFoundError, NotADirectoryError):
        return False
    except OSError as error:
        raise RecordUnreadable(path.parent, error) from None
    return True


def _scan(
    path: Path, start: dt.datetime | None, end: dt.datetime | None, errors: IO[str]
) -> list[StoredRecord]:
    """The records within the times, in file order; each bad line said on ``errors``."""
    found: list[StoredRecord] = []
    if not _there(path):
        return found
    for item in read_records(path, since=start, until=end):
        if isinstance(item, BadLine):
            print(f"srcsctl log: {item.file}:{item.line}: {item.reason.value}", file=errors)
        elif isinstance(item, StoredRecord):
            found.append(item)
    return found


def _identity(record: StoredRecord) -> tuple[object, object]:
    return record.seq, record.data.get("mono_ns")


class _Filter:
    """Which records ``log`` shows: within the times, and, with ``--cause``, those whose
    changes name the cause (a record without ``changes``, written by another tool, by its
    difference from the record before it); with ``--cause-present``, those that hold it.
    Keeps the record before each one chosen (:attr:`before`), for what its line says changed.
    A line that is no typed record (:func:`~supervisord.record.stop.read_written`) names no
    cause a filter takes."""

    def __init__(
        self,
        start: dt.datetime | None,
        end: dt.datetime | None,
        cause: CauseFilter | None,
        present: CauseFilter | None,
    ) -> None:
        self.start, self.end, self.cause, self.present = start, end, cause, present
        self.last: Mapping[str, Any] | None = None  # the record read before, chosen or not
        self.before: dict[tuple[object, object], Mapping[str, Any] | None] = {}

    def select(self, records: list[StoredRecord]) -> list[StoredRecord]:
        """The records wanted, in order; each record is seen once (the last one is kept)."""
        chosen = []
        for record in records:
            previous, self.last = self.last, record.data
            if self._wanted(record, previous):
                self.before[_identity(record)] = previous
                chosen.append(record)
        return chosen

    def _wanted(self, stored: StoredRecord, previous: Mapping[str, Any] | None) -> bool:
        if self.start is not None and stored.utc < self.start:
            return False
        if self.end is not None and stored.utc >= self.end:
            return False
        if self.present is None and self.cause is None:
            return True
        record = read_written(stored.data)
        if record is None:
            return False
        present = self.present
        if present is not None and not any(present.takes(c.name) for c in record.causes):
            return False
        if self.cause is None:
            return True
        before = None if previous is None else read_written(previous)
        return any(self.cause.takes(name) for _, name in changes(record, before))


if __name__ == "__main__":  # pragma: no cover
    sys.exit(run_log(Path(sys.argv[1]), sys.stdout, sys.stderr))
