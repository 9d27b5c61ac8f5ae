"""``srcsctl log``: the record of stops, filtered by time and cause, as text or JSON lines.

One time rule with ``watch`` (issue 13, docs/srcsctl.md "Times"): times are shown in local
time with their UTC offset, or in UTC with ``--utc``; a time typed without a zone is read the
same way. One marker: ``*`` after a cause means its condition has cleared and the stop waits
for a re-arm (SR-4), in ``log`` as in ``watch``.
"""

from __future__ import annotations

import datetime as dt
import json
import re
import signal
import sys
import time
from collections.abc import Mapping
from pathlib import Path
from typing import IO, Final

from supervisord.compat import from_iso
from supervisord.record.jsonl import BadLine, StoredRecord, read_records

EXIT_BAD_INPUT = 2
FOLLOW_POLL_S: Final = 0.25
"""How often ``log -f`` looks for new records (the file is appended and fsynced per record)."""
_RELATIVE = re.compile(r"-?(\d+)([smhd])")
_UNITS = {"s": "seconds", "m": "minutes", "h": "hours", "d": "days"}


class BadTime(ValueError):
    pass


def zone(utc: bool) -> dt.tzinfo | None:
    """The zone times are shown and read in: UTC with ``--utc``, else local (``None``)."""
    return dt.timezone.utc if utc else None


def parse_time(text: str, now: dt.datetime, *, utc: bool = False) -> dt.datetime:
    """ISO 8601 (a time without a zone is local, or UTC with ``utc``), ``today`` or
    ``yesterday`` (midnight, in the same zone), or an age such as ``10m``, ``-1h``, ``3d``."""
    relative = _RELATIVE.fullmatch(text)
    if relative:
        amount, unit = int(relative.group(1)), relative.group(2)
        return now - dt.timedelta(**{_UNITS[unit]: amount})
    if text in ("today", "yesterday"):
        midnight = now.astimezone(zone(utc)).replace(hour=0, minute=0, second=0, microsecond=0)
        return midnight - dt.timedelta(days=1 if text == "yesterday" else 0)
    try:
        when = from_iso(text)
    except ValueError as error:
        raise BadTime(
            f"not a time: {text!r} (use ISO 8601, today, yesterday or an age like 10m, -2h, 3d)"
        ) from error
    if when.tzinfo:
        return when
    return when.replace(tzinfo=dt.timezone.utc) if utc else when.astimezone()


def show_time(utc_text: object, *, utc: bool = False) -> str:
    """A record's ``utc`` in the display zone, to the millisecond, with its offset."""
    try:
        when = from_iso(str(utc_text))
    except ValueError:
        return str(utc_text)
    if when.tzinfo is None:
        when = when.replace(tzinfo=dt.timezone.utc)
    return when.astimezone(zone(utc)).isoformat(timespec="milliseconds")


def cause_mark(cause: Mapping[str, object]) -> str:
    """The one marker of ``log`` and ``watch``: ``*`` when the cause's condition has cleared
    and only its latch holds the stop (it waits for a re-arm, SR-4), else nothing."""
    return "" if cause.get("active") else "*"


def _causes(data: Mapping[str, object]) -> str:
    causes = data.get("causes")
    if not isinstance(causes, list):
        return ""
    names = []
    for cause in causes:
        if isinstance(cause, dict):
            names.append(f"{cause.get('name')}{cause_mark(cause)}")
    return ", ".join(names)


def format_record(data: Mapping[str, object], *, utc: bool = False) -> str:
    """One line: time, sequence, transition, trigger, causes (* = cleared, waits for a re-arm)."""
    trigger = data.get("trigger")
    event = trigger.get("event", "?") if isinstance(trigger, dict) else "?"
    rearm = data.get("rearm")
    how = f" re-armed by {rearm.get('kind')}" if isinstance(rearm, dict) else ""
    move = f"{str(data.get('from')).upper()} -> {str(data.get('to')).upper()}"
    when = show_time(data.get("utc"), utc=utc)
    return f"{when}  #{data.get('seq')}  {move:18} {event}{how}  [{_causes(data)}]"


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
) -> int:
    """Print the records (the ``last`` N of them when given); with ``follow``, then every
    record appended after, until Ctrl-C or SIGTERM (exit 0)."""
    now = dt.datetime.now(dt.timezone.utc)
    try:
        start = parse_time(since, now, utc=utc) if since else None
        end = parse_time(until, now, utc=utc) if until else None
    except BadTime as error:
        print(f"srcsctl log: {error}", file=errors)
        return EXIT_BAD_INPUT
    if not path.exists() and not follow:
        print(f"srcsctl log: {path}: no record yet", file=errors)
        return EXIT_BAD_INPUT

    reported: set[tuple[str, int]] = set()

    def scan() -> list[StoredRecord]:
        found: list[StoredRecord] = []
        if not path.exists():
            return found
        for item in read_records(path, since=start, until=end, cause=cause):
            if isinstance(item, BadLine):
                if (str(item.file), item.line) not in reported:
                    reported.add((str(item.file), item.line))
                    print(f"srcsctl log: {item.file}:{item.line}: {item.reason.value}", file=errors)
            elif isinstance(item, StoredRecord):
                found.append(item)
        return found

    def show(records: list[StoredRecord]) -> None:
        for record in records:
            data = record.data
            out.write(json.dumps(data) + "\n" if as_json else format_record(data, utc=utc) + "\n")
        out.flush()  # a pipe sees each record as it comes (line by line, not at exit)

    records = scan()
    show(records[-last:] if last is not None else records)
    if not follow:
        return 0
    interruptible()
    seen = records[-1].seq if records else 0
    try:
        while True:
            time.sleep(FOLLOW_POLL_S)
            # A record's seq only grows (docs/record.md); a restart continues it. A lower
            # number than seen means the file was replaced: start over from it.
            fresh = scan()
            newer = [r for r in fresh if r.seq > seen]
            if fresh and fresh[-1].seq < seen:
                newer = fresh
            if newer:
                show(newer)
                seen = newer[-1].seq
    except KeyboardInterrupt:
        return 0


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
