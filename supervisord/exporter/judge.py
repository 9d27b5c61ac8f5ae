"""The kernel judge's totals, as ``srcs-rv`` wrote them, read at each scrape (SR-9.9).

``srcs-rv.service`` (:mod:`supervisord.rv_watch`) writes its running totals to
``/run/srcs-rv/violations.json`` once a second, on a robot whose kernel has the rtapp monitors
(docs/kernel-judge.md). :func:`read_judge_file` reads it, bounded, and :func:`parse` checks
every value before the model sees it. No file is no judge, and no metric: most robots run
without one. A file that is too big, not JSON, of another format or with a value of the wrong
type is a :class:`JudgeFileRefused` with its reason, which the exporter counts
(``srcs_rt_file_refusals_total``) and says; it never raises into a scrape.
"""

from __future__ import annotations

import json
import logging
import math
import os
import stat
from dataclasses import dataclass
from pathlib import Path
from typing import Final

from supervisord.rv_count import DAEMON_THREAD, MAX_KEYS, MONITORS

DEFAULT_RV_FILE: Final = Path("/run/srcs-rv/violations.json")
MAX_FILE_BYTES: Final = 64 * 1024
"""The watch's file holds at most 64 series: about 3 KiB."""
STALE_S: Final = 30.0
"""A file not rewritten for this long is from a watch that no longer runs (killed, hung):
its judge is said off, its totals are kept."""
FORMAT: Final = 1
_MAX_COUNT: Final = 2**53  # a JSON number a float still holds exactly

log = logging.getLogger("srcs-exporter")


class JudgeFileRefused(Exception):
    """The file was there and is not one this exporter takes; ``reason`` is a fixed label."""

    def __init__(self, reason: str, detail: str) -> None:
        super().__init__(f"{reason}: {detail}")
        self.reason = reason


@dataclass(frozen=True, slots=True)
class JudgeTotals:
    """The watch's totals: each (monitor, thread, count) of the daemon's threads, the
    violations past its cap of series by monitor, and its own counts."""

    judge_on: bool
    violations: tuple[tuple[str, str, int], ...]
    overflow: tuple[tuple[str, int], ...]
    unreadable_lines: int
    lost_events: int
    last_violation_unix: float | None


def _count(value: object, what: str) -> int:
    if type(value) is not int or not 0 <= value < _MAX_COUNT:
        raise JudgeFileRefused("bad_value", f"{what} is not a count: {str(value)[:40]!r}")
    return value


def _series(violations: dict[object, object]) -> list[tuple[str, str, int]]:
    """``{monitor: {thread: count}}``: known monitors, the daemon's thread names (SR-9.7),
    counts; at most the watch's cap of series and the loop's three."""
    series: list[tuple[str, str, int]] = []
    for monitor, threads in violations.items():
        if monitor not in MONITORS or not isinstance(threads, dict):
            raise JudgeFileRefused("bad_value", f"no monitor {str(monitor)[:40]!r}")
        for thread, count in threads.items():
            if not isinstance(thread, str) or DAEMON_THREAD.fullmatch(thread) is None:
                raise JudgeFileRefused("bad_value", f"not a thread of srcsd: {thread!s:.40}")
            if len(thread) > 15:  # a kernel comm's length
                raise JudgeFileRefused("bad_value", f"not a thread of srcsd: {thread:.40}")
            series.append((str(monitor), thread, _count(count, f"{monitor}/{thread}")))
    if len(series) > MAX_KEYS + len(MONITORS):
        raise JudgeFileRefused("bad_value", f"{len(series)} series")
    return series


def _overflow(overflow: dict[object, object]) -> list[tuple[str, int]]:
    past_cap: list[tuple[str, int]] = []
    for monitor, count in overflow.items():
        if monitor not in MONITORS:
            raise JudgeFileRefused("bad_value", f"no monitor {str(monitor)[:40]!r}")
        past_cap.append((str(monitor), _count(count, f"overflow/{monitor}")))
    return past_cap


def parse(data: bytes, age_s: float) -> JudgeTotals:
    """The totals in ``data``, written ``age_s`` seconds ago; raises
    :class:`JudgeFileRefused` on anything the watch does not write."""
    if len(data) > MAX_FILE_BYTES:
        raise JudgeFileRefused("too_big", f"over {MAX_FILE_BYTES} bytes")
    try:
        document = json.loads(data)
    except (ValueError, RecursionError) as error:
        raise JudgeFileRefused("not_json", str(error)[:80]) from None
    form = document.get("format") if isinstance(document, dict) else None
    if type(form) is not int or form != FORMAT:  # ``true`` is no 1 here
        raise JudgeFileRefused("format", f"not format {FORMAT}")
    judge_on = document.get("judge_on")
    violations = document.get("violations")
    overflow = document.get("overflow")
    last = document.get("last_violation_unix")
    if type(judge_on) is not bool:
        raise JudgeFileRefused("bad_value", "judge_on is not true or false")
    if not isinstance(violations, dict) or not isinstance(overflow, dict):
        raise JudgeFileRefused("bad_value", "violations or overflow is not an object")
    series = _series(violations)
    past_cap = _overflow(overflow)
    if last is not None and (type(last) not in (int, float) or not math.isfinite(last) or last < 0):
        raise JudgeFileRefused("bad_value", "last_violation_unix is not a time")
    return JudgeTotals(
        judge_on=judge_on and age_s <= STALE_S,
        violations=tuple(sorted(series)),
        overflow=tuple(sorted(past_cap)),
        unreadable_lines=_count(document.get("unreadable_lines"), "unreadable_lines"),
        lost_events=_count(document.get("lost_events"), "lost_events"),
        last_violation_unix=None if last is None else float(last),
    )


def read_judge_file(path: Path, now_s: float) -> JudgeTotals | None:
    """The totals at ``path`` (``now_s``: the wall clock, for its age), ``None`` when there is
    no file; raises :class:`JudgeFileRefused`, an unreadable file included."""
    try:
        fd = os.open(path, os.O_RDONLY | os.O_NONBLOCK | os.O_NOFOLLOW)
    except FileNotFoundError:
        return None
    except OSError as error:
        raise JudgeFileRefused("unreadable", error.strerror or str(error)) from None
    try:
        status = os.fstat(fd)
        if not stat.S_ISREG(status.st_mode):
            raise JudgeFileRefused("unreadable", "not a regular file")
        if status.st_size > MAX_FILE_BYTES:
            raise JudgeFileRefused("too_big", f"{status.st_size} bytes")
        data = os.read(fd, MAX_FILE_BYTES + 1)
    except OSError as error:
        raise JudgeFileRefused("unreadable", error.strerror or str(error)) from None
    finally:
        os.close(fd)
    return parse(data, max(0.0, now_s - status.st_mtime))


class JudgeFile:
    """The file at ``path``, read at each scrape: its totals, or the reason it was refused,
    said once when a refusal begins or changes (a scrape every 15 s must not flood the
    journal), never raised."""

    def __init__(self, path: Path) -> None:
        self.path = path
        self._said: str | None = None

    def read(self, now_s: float) -> tuple[JudgeTotals | None, str | None]:
        try:
            totals = read_judge_file(self.path, now_s)
        except JudgeFileRefused as refused:
            if str(refused) != self._said:
                log.warning("%s refused: %s", self.path, refused)
            self._said = str(refused)
            return None, refused.reason
        self._said = None
        return totals, None
