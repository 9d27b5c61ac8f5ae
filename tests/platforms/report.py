"""What a platform job saw: each check as one line, passed or failed, and the times it took.

Every job of ``tests/platforms`` (docs/platforms.md) prints through one ``Report`` and exits
with its status: 0 when every check passed, 1 otherwise. ``tests/platforms/run`` counts the
jobs. Only the standard library: the jobs run with the host's ``python3``.
"""

from __future__ import annotations

import sys
import time


class Report:
    """Checks of one job, printed as they come: ``JOB: ok WHAT`` or ``JOB: FAILED WHAT``."""

    def __init__(self, job: str) -> None:
        self.job = job
        self.failures: list[str] = []
        self.started = time.monotonic()

    def say(self, text: str) -> None:
        print(f"{self.job}: {text}", flush=True)

    def check(self, passed: bool, what: str, seen: object = "") -> bool:
        """One check; ``seen`` is printed only when it failed (what was found instead)."""
        if passed:
            self.say(f"ok {what}")
        else:
            self.failures.append(what)
            self.say(f"FAILED {what}" + (f": {seen}" if seen not in ("", None) else ""))
        return passed

    def fail(self, what: str, seen: str = "") -> None:
        self.check(False, what, seen)

    def took(self, what: str, since: float) -> float:
        """Print and return the seconds since ``since`` (a ``time.monotonic()``)."""
        seconds = time.monotonic() - since
        self.say(f"time {what}: {seconds:.0f} s")
        return seconds

    def end(self) -> int:
        seconds = time.monotonic() - self.started
        if self.failures:
            self.say(f"{len(self.failures)} check(s) failed in {seconds:.0f} s")
            for what in self.failures:
                self.say(f"  failed: {what}")
            return 1
        self.say(f"every check passed in {seconds:.0f} s")
        return 0


def tail(text: str, lines: int = 25) -> str:
    """The end of a command's output, indented, for a failure's explanation."""
    return "\n" + "\n".join("    " + line for line in text.splitlines()[-lines:])


if __name__ == "__main__":  # pragma: no cover - a library
    sys.exit("tests/platforms/report.py is a library of the platform jobs")
