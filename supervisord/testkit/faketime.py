"""Wall-clock jumps for one process, with Debian's libfaketime (package ``faketime``)."""

from __future__ import annotations

import glob
import os
from pathlib import Path

from supervisord.testkit.wait import FaultHarnessError


def libfaketime() -> Path | None:
    """Debian's ``libfaketime`` (package ``faketime``), if installed."""
    found = sorted(glob.glob("/usr/lib/*/faketime/libfaketime.so.1"))
    return Path(found[0]) if found else None


CACHE_S = 1
"""How long libfaketime keeps the offset it read from the file (``FAKETIME_CACHE_DURATION``)."""

SEEN_WITHIN_S = 2.0 * CACHE_S
"""A ``jump`` reaches the process's next wall-clock read at most this long after it: the
cache expires once more than ``CACHE_S`` whole seconds (of the real clock) have passed since
its last read of the file. Measured: 0.35 to 0.9 s."""


class FakeWallClock:
    """Makes a process see its wall clock jump while its monotonic clock runs on untouched.

    The process is started with libfaketime preloaded, reading its offset from a file
    (``FAKETIME_TIMESTAMP_FILE``); ``jump`` rewrites the file, and the process sees the new
    offset within ``SEEN_WITHIN_S``. ``DONT_FAKE_MONOTONIC`` (and its newer spelling) leave
    ``CLOCK_MONOTONIC`` alone: it is the clock every deadline uses (SR-2), and the scenario
    checks from the stop record that it really was left alone.

    Not ``FAKETIME_NO_CACHE`` (the file read at every call): with it, the preloaded daemon's
    loop stalls by itself, quiet machine or not. Measured over 3 s of RUN with no jump at
    all: 21 to 30 of its user heartbeats late by more than half a period, and vsc_link_lost
    stops, against 1 to 5 with a one-second cache and 1 without libfaketime. Those stops
    were the scenario's failures on a loaded machine, none of them the product's.

    libfaketime 0.9.10 also fails ``time.sleep`` with EINVAL in the preloaded process (its
    ``clock_nanosleep`` on a monotonic deadline); the daemon waits in ``select`` only."""

    def __init__(self, folder: Path) -> None:
        library = libfaketime()
        if library is None:
            raise FaultHarnessError(
                "libfaketime is not installed (Debian package 'faketime'): "
                "a real wall-clock jump needs it"
            )
        self.library = library
        self.path = folder / "faketime.rc"
        self.offset_s = 0
        self.path.write_text("+0\n")

    def env(self) -> dict[str, str]:
        return {
            "LD_PRELOAD": str(self.library),
            "FAKETIME_TIMESTAMP_FILE": str(self.path),
            "FAKETIME_CACHE_DURATION": str(CACHE_S),
            "DONT_FAKE_MONOTONIC": "1",
            "FAKETIME_DONT_FAKE_MONOTONIC": "1",
            # Off: the "monotonic fix" (on by itself with this glibc) rewrites every
            # pthread_cond_timedwait, and CPython hands its GIL over with those; with it on,
            # a thread waiting for the GIL waited 100-160 ms at the 99th percentile instead
            # of 25-30 ms (two threads, loaded machine), enough for the daemon's heartbeats
            # to miss the VSC's 500 ms watchdog. It exists for a faked monotonic clock,
            # which this one is not.
            "FAKETIME_FORCE_MONOTONIC_FIX": "0",
        }

    def jump(self, seconds: int) -> None:
        """Move the wall clock by ``seconds`` (relative to the current fake offset); the
        process sees it within ``SEEN_WITHIN_S``."""
        self.offset_s += seconds
        tmp = self.path.with_suffix(".tmp")
        tmp.write_text(f"{self.offset_s:+d}\n")
        os.replace(tmp, self.path)
