"""The kernel's judge in the guest: arm the rtapp monitors, and read what they found.

Only in a boot with ``srcs.judge`` on its command line (tests/system/run --judge), on the
judged kernel (tests/system/judge.config). :func:`arm` turns the three monitors on once, at the
boot's start, before any daemon runs; before each scenario :func:`begin` empties the trace, and
after it :func:`take` reads the ``error_*`` events with their stacks; tests/system/rv.py judges
them. The monitors are never turned off and on again: a monitor turned on judges a task that
already runs only once the task has told it every fact it needs (the ``sleep`` monitor's
rt-mutex and PI-futex facts are set only for a task created while it is on), so a re-armed
monitor would judge none of the daemons already running.
The trace buffer is the kernel's ring: :func:`take` also says how many events it overwrote, so
that a scenario never passes on a trace that lost what it should have judged.
"""

from __future__ import annotations

import os
from pathlib import Path

from tests.system.rv import MONITORS

TRACING = Path("/sys/kernel/tracing")
BUFFER_KB = 8192  # per CPU (the guest has one): a whole scenario's violations with stacks


def wanted() -> bool:
    return "srcs.judge" in Path("/proc/cmdline").read_text().split()


def _write(name: str, value: str, *, append: bool = False) -> None:
    # One write() per value: tracefs parses each write on its own (and O_TRUNC on
    # enabled_monitors would turn every monitor off).
    flags = os.O_WRONLY | (os.O_APPEND if append else os.O_TRUNC)
    fd = os.open(TRACING / name, flags)
    try:
        os.write(fd, value.encode())
    finally:
        os.close(fd)


def available() -> list[str]:
    """The rtapp monitors this kernel has (empty on a kernel that cannot judge)."""
    try:
        listed = (TRACING / "rv/available_monitors").read_text().split()
    except OSError:
        return []
    return [name for name in MONITORS if any(m.split(":")[-1] == name for m in listed)]


def _triggered(trigger: Path) -> bool:
    """Whether the event already has its stack trigger (``stacktrace:unlimited``); the file
    lists the available triggers, "stacktrace" among them, in comments when it has none."""
    lines = trigger.read_text().splitlines()
    return any(line.startswith("stacktrace") for line in lines)


def arm() -> None:
    """Every monitor on, the events with their stack trigger on, the trace empty: once."""
    missing = set(MONITORS) - set(available())
    if missing:
        raise RuntimeError(f"the kernel has no rtapp monitor {sorted(missing)}: not judged")
    _write("tracing_on", "0")
    _write("buffer_size_kb", str(BUFFER_KB))
    for monitor in MONITORS:
        _write("rv/enabled_monitors", f"!{monitor}", append=True)
    for monitor in MONITORS:
        event = f"events/rv/error_{monitor}"
        _write(f"{event}/enable", "1")
        if not _triggered(TRACING / event / "trigger"):
            _write(f"{event}/trigger", "stacktrace", append=True)
        _write("rv/enabled_monitors", monitor, append=True)
    _write("rv/monitoring_on", "1")
    begin()
    _write("tracing_on", "1")


def begin() -> None:
    """The trace emptied: what :func:`take` reads next is what happened from now on."""
    _write("trace", "")


def overwritten() -> int:
    """Events the ring lost since the trace was last emptied (``overrun`` of each CPU)."""
    lost = 0
    for stats in (TRACING / "per_cpu").glob("cpu*/stats"):
        for line in stats.read_text().splitlines():
            if line.startswith("overrun:"):
                lost += int(line.split(":", 1)[1])
    return lost


def take() -> tuple[str, int]:
    """The trace since :func:`arm` and the events it lost; the trace goes on."""
    return (TRACING / "trace").read_text(errors="replace"), overwritten()
