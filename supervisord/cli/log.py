"""``srcsctl log``: the record of stops, filtered by time and cause, as text or JSON lines.

journalctl's habits (docs/srcsctl.md "log"): ``-n`` alone is the last 10, ``-f`` prints the
last 10 and then each record as it is written (the file is watched, :mod:`follow`), ``-r``
newest first, ``-o json`` as ``--json``, and journalctl's relative times. One time rule with
``watch`` (:mod:`times`), one line per record with ``watch`` and the demo (:mod:`record_text`).
"""

from __future__ import annotations

import datetime as dt
import json
import os
import signal
import sys
from collections.abc import Mapping
from pathlib import Path
from typing import IO, Any, Final

from supervisord.cli.follow import Follower
from supervisord.cli.record_text import record_line
from supervisord.cli.times import BadTime, parse_time, show_time
from supervisord.record.jsonl import BadLine, RecordUnreadable, StoredRecord, read_records

EXIT_BAD_INPUT: Final = 2
FOLLOW_LAST: Final = 10
"""What ``-n`` alone and ``-f`` without ``-n`` show first: the last 10, as journalctl."""


def format_record(
    data: Mapping[str, Any],
    *,
    utc: bool = False,
    previous: Mapping[str, Any] | None = None,
    causes: bool = False,
) -> str:
    """One line: the time (local with its offset, or UTC), then what happened
    (:func:`~supervisord.cli.record_text.record_line`)."""
    return record_line(data, show_time(data.get("utc"), utc=utc), previous=previous, causes=causes)


def run_log(
    path: Path,
    out: IO[str],
    errors: IO[str],
    *,
    since: str | None = None,
    until: str | None = None,
    cause: str | None = None,
    as_json: bool = False,
    utc: bool = False,
    last: int | None = None,
    follow: bool = False,
    reverse: bool = False,
    causes: bool = False,
) -> int:
    """Print the records (the ``last`` N of them when given; newest first with ``reverse``);
    with ``follow``, then every record appended after, until Ctrl-C or SIGTERM (exit 0). A
    record (or its folder) that cannot be read raises :class:`RecordUnreadable`."""
    now = dt.datetime.now(dt.timezone.utc)
    try:
        start = parse_time(since, now, utc=utc) if since else None
        end = parse_time(until, now, utc=utc) if until else None
    except BadTime as error:
        print(f"srcsctl log: {error}", file=errors)
        return EXIT_BAD_INPUT
    refused = _refusal(path, follow=follow, reverse=reverse)
    if refused:
        print(f"srcsctl log: {refused}", file=errors)
        return EXIT_BAD_INPUT
    if follow and last is None and since is None and until is None:
        last = FOLLOW_LAST
    printer = _Printer(out, as_json=as_json, utc=utc, causes=causes)
    follower: Follower | None = None
    try:  # from the handlers on: a signal that comes while the follower opens ends it too
        if follow:
            interruptible()
            follower = Follower(path)  # opened first: nothing falls between
        records = _scan(path, start, end, cause, errors)
        shown = [] if last == 0 else records[-last:] if last is not None else records
        if len(records) > len(shown) and shown:  # the one before: what the first changed
            printer.previous = records[-len(shown) - 1].data
        printer.show(shown, reverse=reverse)
        if follower is None:
            return 0
        # A record written between the follower's start and the scan is in both: shown once.
        # Known by seq and monotonic time, so that a numbering started again is still shown.
        scanned = {_identity(record) for record in records}
        for fresh in follower:
            wanted = [
                r for r in fresh if _identity(r) not in scanned and _wanted(r, start, end, cause)
            ]
            if wanted:
                printer.show(wanted)
    except KeyboardInterrupt:
        return 0
    finally:
        if follower is not None:
            follower.close()
    return 0  # pragma: no cover - the follower never ends by itself


def _refusal(path: Path, *, follow: bool, reverse: bool) -> str | None:
    """Why these options cannot be served, or ``None``."""
    if follow and reverse:
        return "-r and -f do not go together (as in journalctl)"
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


class _Printer:
    """Prints records as lines (or JSON), each line saying what changed since the one
    before it (:attr:`previous`, for records that do not say it themselves)."""

    def __init__(self, out: IO[str], *, as_json: bool, utc: bool, causes: bool) -> None:
        self.out, self.as_json, self.utc, self.causes = out, as_json, utc, causes
        self.previous: Mapping[str, Any] | None = None

    def show(self, records: list[StoredRecord], *, reverse: bool = False) -> None:
        lines = []
        for record in records:
            if self.as_json:
                lines.append(json.dumps(record.data))
                continue
            lines.append(
                format_record(record.data, utc=self.utc, previous=self.previous, causes=self.causes)
            )
            self.previous = record.data
        for line in reversed(lines) if reverse else lines:
            self.out.write(line + "\n")
        self.out.flush()  # a pipe sees each record as it comes (line by line, not at exit)


def _scan(
    path: Path,
    start: dt.datetime | None,
    end: dt.datetime | None,
    cause: str | None,
    errors: IO[str],
) -> list[StoredRecord]:
    found: list[StoredRecord] = []
    if not _there(path):
        return found
    for item in read_records(path, since=start, until=end, cause=cause):
        if isinstance(item, BadLine):
            print(f"srcsctl log: {item.file}:{item.line}: {item.reason.value}", file=errors)
        elif isinstance(item, StoredRecord):
            found.append(item)
    return found


def _identity(record: StoredRecord) -> tuple[object, object]:
    return record.seq, record.data.get("mono_ns")


def _wanted(
    record: StoredRecord, start: dt.datetime | None, end: dt.datetime | None, cause: str | None
) -> bool:
    if start is not None and record.utc < start:
        return False
    if end is not None and record.utc >= end:
        return False
    return cause is None or record.matches_cause(cause)


def interruptible() -> None:
    """Ctrl-C and SIGTERM end a following command, even when it was started with SIGINT
    ignored (a background job of a script: Python then installs no handler of its own,
    which is what once made ``watch`` outlive its SIGINT in a test)."""

    def interrupt(_sig: int, _frame: object) -> None:
        raise KeyboardInterrupt

    for sig in (signal.SIGINT, signal.SIGTERM):
        signal.signal(sig, interrupt)


if __name__ == "__main__":  # pragma: no cover
    sys.exit(run_log(Path(sys.argv[1]), sys.stdout, sys.stderr))
