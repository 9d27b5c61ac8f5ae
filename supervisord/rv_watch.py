"""``python3 -m supervisord.rv_watch``: the kernel judge's counter in the field (SR-9.9).

On a robot whose kernel has the rtapp monitors (docs/kernel-judge.md), ``srcs-rv.service``
runs this as root: it arms the monitors' ``error_*`` events in a tracefs instance of its own
(``instances/srcs-rv``: its own events and ring, so it disturbs no other reader of the
top-level trace), turns the three monitors and ``monitoring_on`` on, and then, every second,
reads the instance's ``trace_pipe`` (at most :data:`READ_MAX` bytes a turn), counts the
daemon's violations (:mod:`supervisord.rv_count`) and writes the running totals, whether the
judge is on and the events the ring lost, as JSON to ``/run/srcs-rv/violations.json``
(written to a temporary file and renamed over it, mode 0644: the exporter, another user,
reads it at each scrape).

Refusals, one line on stderr each, with their exit status (none is worth a restart):

- 3 (:class:`NoTracefs`): tracefs is not mounted at the root given (``--tracing``).
- 4 (:class:`NoMonitors`): the kernel has none of the rtapp monitors (or no ``rv`` at all):
  not a judged kernel. One that has some (arm64 has no ``pagefault``) is judged by those.
- 5 (:class:`NotArmed`): a tracefs file refused the write that arms the judge (not root, a
  locked-down kernel).
- 1: the totals' file cannot be written.

On SIGTERM or SIGINT it writes the totals a last time with ``judge_on`` false, and exits 0.
"""

from __future__ import annotations

import argparse
import json
import os
import signal
import sys
import threading
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from pathlib import Path
from types import FrameType
from typing import Any, Final

from supervisord.rv_count import MONITORS, ViolationCounter

TRACING: Final = Path("/sys/kernel/tracing")
INSTANCE: Final = "srcs-rv"
DEFAULT_OUTPUT: Final = Path("/run/srcs-rv/violations.json")
READ_MAX: Final = 1 << 20
"""Bytes read from the pipe a turn: a turn's work stays bounded under a flood of events
(what the ring cannot hold meanwhile it overwrites, and says so in ``lost_events``)."""
PERIOD_S: Final = 1.0
FORMAT: Final = 1
"""The file's layout (``format``): the exporter reads no other."""

EXIT_FAILED: Final = 1
EXIT_NO_TRACEFS: Final = 3
EXIT_NO_MONITORS: Final = 4
EXIT_NOT_ARMED: Final = 5


class Refusal(Exception):
    """Why the watch cannot run here; its exit status and its one line."""

    status = EXIT_FAILED


class NoTracefs(Refusal):
    status = EXIT_NO_TRACEFS


class NoMonitors(Refusal):
    status = EXIT_NO_MONITORS


class NotArmed(Refusal):
    status = EXIT_NOT_ARMED


def _write(path: Path, value: str, *, append: bool = False) -> None:
    """One ``write()`` of ``value``: tracefs parses each write on its own. ``append`` for
    ``rv/enabled_monitors`` and triggers, where O_TRUNC would turn every other entry off."""
    flags = os.O_WRONLY | (os.O_APPEND if append else os.O_TRUNC)
    try:
        fd = os.open(path, flags)
        try:
            os.write(fd, value.encode())
        finally:
            os.close(fd)
    except OSError as error:
        raise NotArmed(f"cannot write {value.strip()!r} to {path}: {error.strerror}") from None


def _read(path: Path) -> str | None:
    try:
        return path.read_text(errors="replace")
    except OSError:
        return None


def _is_on(text: str | None) -> bool:
    """A tracefs 0/1 file that reads 1. Linux 7.3's ``rv/monitoring_on`` reads ``1\\n`` and a
    NUL byte after it, which ``strip()`` keeps: read as text, it was never 1."""
    return (text or "").replace("\0", "").strip() == "1"


def _listed(text: str | None) -> set[str]:
    """Monitor names in ``available_monitors`` or ``enabled_monitors`` (``rtapp:sleep`` or
    ``sleep``: the container's prefix is left out)."""
    return {entry.split(":")[-1] for entry in (text or "").split()}


@dataclass
class Judge:
    """The judge's files under a tracefs root: the global ``rv/`` and this watch's instance;
    ``monitors``: the rtapp monitors this kernel has, once :meth:`check` found them."""

    root: Path
    monitors: tuple[str, ...] = ()

    @property
    def instance(self) -> Path:
        return self.root / "instances" / INSTANCE

    def check(self) -> None:
        if not (self.root / "instances").is_dir():
            raise NoTracefs(f"tracefs is not mounted at {self.root} (no instances/ there)")
        listed = _listed(_read(self.root / "rv/available_monitors"))
        self.monitors = tuple(name for name in MONITORS if name in listed)
        if not self.monitors:
            raise NoMonitors(
                f"this kernel has no rtapp monitor ({', '.join(MONITORS)}; "
                f"{self.root / 'rv/available_monitors'}): it is not built to be judged "
                "(docs/kernel-judge.md)"
            )

    def arm(self) -> None:
        """The instance made (or taken as it is), its clock CLOCK_MONOTONIC (so an event's
        time can be put on the wall clock), the ``error_*`` events on in it, the monitors
        and ``monitoring_on`` on. Monitors another tool turned on stay on; none is turned
        off, so the top-level trace's users see what they saw."""
        try:
            self.instance.mkdir(exist_ok=True)
        except OSError as error:
            raise NotArmed(f"cannot make {self.instance}: {error.strerror}") from None
        if (self.instance / "trace_clock").exists():
            _write(self.instance / "trace_clock", "mono")
        for name in self.monitors:
            _write(self.instance / f"events/rv/error_{name}/enable", "1")
        enabled = _listed(_read(self.root / "rv/enabled_monitors"))
        for name in self.monitors:
            if name not in enabled:
                _write(self.root / "rv/enabled_monitors", f"{name}\n", append=True)
        _write(self.root / "rv/monitoring_on", "1")
        if (self.instance / "tracing_on").exists():
            _write(self.instance / "tracing_on", "1")

    def on(self) -> bool:
        """Whether the judge judges now: ``monitoring_on`` 1, this kernel's monitors enabled,
        their events on in this instance (anyone with root may turn any of them off)."""
        if not _is_on(_read(self.root / "rv/monitoring_on")):
            return False
        if not set(self.monitors) <= _listed(_read(self.root / "rv/enabled_monitors")):
            return False
        events = self.instance / "events/rv"
        return all(_is_on(_read(events / f"error_{name}/enable")) for name in self.monitors)

    def lost(self) -> int | None:
        """Events the instance's ring overwrote (``overrun`` of every CPU), ``None`` when its
        statistics cannot be read."""
        total, found = 0, False
        for stats in sorted((self.instance / "per_cpu").glob("cpu*/stats")):
            for line in (_read(stats) or "").splitlines():
                name, _, value = line.partition(":")
                if name == "overrun" and value.strip().isdigit():
                    total += int(value)
                    found = True
        return total if found else None


def read_turn(fd: int, counter: ViolationCounter, limit: int = READ_MAX) -> int:
    """Whatever the pipe holds now, up to ``limit`` bytes, fed to ``counter``; the bytes read.
    The pipe is non-blocking: empty is EAGAIN (tracefs) or end of file (a FIFO no one writes)."""
    taken = 0
    while taken < limit:
        try:
            data = os.read(fd, min(65536, limit - taken))
        except BlockingIOError:
            break
        except InterruptedError:
            continue
        if not data:
            break
        counter.feed(data)
        taken += len(data)
    return taken


def document(
    counter: ViolationCounter,
    monitors: tuple[str, ...],
    *,
    judge_on: bool,
    lost: int | None,
    mono_s: float,
    wall_s: float,
) -> dict[str, Any]:
    """The file's JSON: the running totals. The loop's series of each monitor armed are always
    there, from 0, so that the first violation is an increase an alert sees. The last
    violation's trace time (CLOCK_MONOTONIC) is put on the wall clock with the two clocks read
    together."""
    violations: dict[str, dict[str, int]] = {name: {"srcsd": 0} for name in monitors}
    for (monitor, thread), count in sorted(counter.violations.items()):
        violations.setdefault(monitor, {})[thread] = count
    last = counter.last_seconds
    last_wall = None if last is None or last > mono_s else wall_s - (mono_s - last)
    return {
        "format": FORMAT,
        "judge_on": judge_on,
        "monitors": list(monitors),
        "violations": violations,
        "overflow": dict(sorted(counter.overflow.items())),
        "others": counter.others,
        "unreadable_lines": counter.unreadable,
        "lost_events": lost if lost is not None else counter.lost_reported,
        "last_violation_unix": last_wall,
    }


def write_atomically(path: Path, content: dict[str, Any]) -> None:
    """Written beside ``path`` and renamed over it: a reader sees the old file or the new,
    never a part. Mode 0644: the exporter runs as another user."""
    temporary = path.with_name(f".{path.name}.tmp")
    fd = os.open(temporary, os.O_WRONLY | os.O_CREAT | os.O_TRUNC, 0o644)
    try:
        os.fchmod(fd, 0o644)
        os.write(fd, (json.dumps(content, sort_keys=True) + "\n").encode())
    finally:
        os.close(fd)
    os.replace(temporary, path)


def watch(
    root: Path,
    output: Path,
    stop: threading.Event,
    *,
    period: float = PERIOD_S,
    clock: Callable[[], float] = time.monotonic,
    wall: Callable[[], float] = time.time,
) -> None:
    """Check, arm, then count until ``stop`` is set; raises :class:`Refusal`."""
    judge = Judge(root)
    judge.check()
    judge.arm()
    try:
        fd = os.open(judge.instance / "trace_pipe", os.O_RDONLY | os.O_NONBLOCK)
    except OSError as error:
        raise NotArmed(f"cannot open {judge.instance / 'trace_pipe'}: {error.strerror}") from None
    counter = ViolationCounter()
    try:
        while True:
            stopping = stop.is_set()  # a last turn, then the judge said off
            read_turn(fd, counter)
            on = judge.on() and not stopping
            content = document(
                counter,
                judge.monitors,
                judge_on=on,
                lost=judge.lost(),
                mono_s=clock(),
                wall_s=wall(),
            )
            try:
                write_atomically(output, content)
            except OSError as error:
                raise Refusal(f"cannot write {output}: {error.strerror}") from None
            if stopping:
                return
            stop.wait(period)
    finally:
        os.close(fd)


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(
        prog="python3 -m supervisord.rv_watch", description=__doc__.split("\n", 1)[0]
    )
    parser.add_argument(
        "--tracing", type=Path, default=TRACING, help=f"tracefs's root (default {TRACING})"
    )
    parser.add_argument(
        "--output", type=Path, default=DEFAULT_OUTPUT, help=f"the totals (default {DEFAULT_OUTPUT})"
    )
    parser.add_argument(
        "--period", type=float, default=PERIOD_S, help="seconds between reads (default 1)"
    )
    return parser


def main(argv: Sequence[str] | None = None) -> int:
    args = build_parser().parse_args(argv)
    if not 0.05 <= args.period <= 60:
        print("srcs-rv: --period must be between 0.05 and 60 seconds", file=sys.stderr)
        return 2
    stop = threading.Event()

    def on_signal(signum: int, frame: FrameType | None) -> None:
        stop.set()

    signal.signal(signal.SIGTERM, on_signal)
    signal.signal(signal.SIGINT, on_signal)
    try:
        watch(args.tracing, args.output, stop, period=args.period)
    except Refusal as refusal:
        print(f"srcs-rv: {refusal}", file=sys.stderr)
        return refusal.status
    return 0


if __name__ == "__main__":
    sys.exit(main())
