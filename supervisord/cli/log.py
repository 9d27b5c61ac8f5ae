"""``srcsctl log``: the record of stops, filtered by time and cause, as text or JSON lines."""

from __future__ import annotations

import datetime as dt
import json
import re
import sys
from collections.abc import Mapping
from pathlib import Path
from typing import IO

from supervisord.record.jsonl import BadLine, Record, read_records

EXIT_BAD_INPUT = 2
_RELATIVE = re.compile(r"(\d+)([smhd])")
_UNITS = {"s": "seconds", "m": "minutes", "h": "hours", "d": "days"}


class BadTime(ValueError):
    pass


def parse_time(text: str, now: dt.datetime) -> dt.datetime:
    """ISO 8601 (a time without a zone is UTC), or an age such as ``10m``, ``2h``, ``3d``."""
    relative = _RELATIVE.fullmatch(text)
    if relative:
        amount, unit = int(relative.group(1)), relative.group(2)
        return now - dt.timedelta(**{_UNITS[unit]: amount})
    try:
        when = dt.datetime.fromisoformat(text)
    except ValueError as error:
        raise BadTime(f"not a time: {text!r} (use ISO 8601 or an age like 10m, 2h, 3d)") from error
    return when if when.tzinfo else when.replace(tzinfo=dt.UTC)


def _causes(data: Mapping[str, object]) -> str:
    causes = data.get("causes")
    if not isinstance(causes, list):
        return ""
    names = []
    for cause in causes:
        if isinstance(cause, dict):
            mark = "*" if cause.get("active") else ""
            names.append(f"{cause.get('name')}{mark}")
    return ", ".join(names)


def format_record(data: Mapping[str, object]) -> str:
    """One line: time, sequence, transition, trigger, causes (* = condition active now)."""
    trigger = data.get("trigger")
    event = trigger.get("event", "?") if isinstance(trigger, dict) else "?"
    rearm = data.get("rearm")
    how = f" re-armed by {rearm.get('kind')}" if isinstance(rearm, dict) else ""
    move = f"{str(data.get('from')).upper()} -> {str(data.get('to')).upper()}"
    return f"{data.get('utc')}  #{data.get('seq')}  {move:18} {event}{how}  [{_causes(data)}]"


def run_log(
    path: Path,
    out: IO[str],
    errors: IO[str],
    *,
    since: str | None = None,
    until: str | None = None,
    cause: str | None = None,
    as_json: bool = False,
) -> int:
    now = dt.datetime.now(dt.UTC)
    try:
        start = parse_time(since, now) if since else None
        end = parse_time(until, now) if until else None
    except BadTime as error:
        print(f"srcsctl log: {error}", file=errors)
        return EXIT_BAD_INPUT
    if not path.exists():
        print(f"srcsctl log: {path}: no record yet", file=errors)
        return EXIT_BAD_INPUT
    for item in read_records(path, since=start, until=end, cause=cause):
        if isinstance(item, BadLine):
            print(f"srcsctl log: {item.file}:{item.line}: {item.reason.value}", file=errors)
        elif isinstance(item, Record):
            out.write(json.dumps(item.data) + "\n" if as_json else format_record(item.data) + "\n")
    return 0


if __name__ == "__main__":  # pragma: no cover
    sys.exit(run_log(Path(sys.argv[1]), sys.stdout, sys.stderr))
