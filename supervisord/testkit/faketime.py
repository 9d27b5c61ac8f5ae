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


class FakeWallClock:
    """Makes a process see its wall clock jump while its monotonic clock runs on untouched.

    The process is started with libfaketime preloaded, reading its offset from a file on every
    call (``FAKETIME_NO_CACHE``); ``jump`` rewrites the file. ``DONT_FAKE_MONOTONIC`` (and its
    newer spelling) leave ``CLOCK_MONOTONIC`` alone: it is the clock every deadline uses
    (SR-2), and the scenario checks from the stop record that it really was left
    alone."""

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
            "FAKETIME_NO_CACHE": "1",
            "DONT_FAKE_MONOTONIC": "1",
            "FAKETIME_DONT_FAKE_MONOTONIC": "1",
        }

    def jump(self, seconds: int) -> None:
        """Move the wall clock by ``seconds`` (relative to the current fake offset)."""
        self.offset_s += seconds
        tmp = self.path.with_suffix(".tmp")
        tmp.write_text(f"{self.offset_s:+d}\n")
        os.replace(tmp, self.path)
