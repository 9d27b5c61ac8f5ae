"""A directory laid out as tracefs is on a kernel with the rtapp monitors, and the kernel's side
of it: the lines its ``error_*`` events write (SR-9.9).

The host's kernel has no monitors, so the field counter (``supervisord.rv_watch``) runs
against this: the global ``rv/`` files, and the ``srcs-rv`` instance as ``mkdir`` makes it
(its events' ``enable`` and ``trigger``, ``trace_clock``, ``tracing_on``, per-CPU statistics,
``trace``) with ``trace_pipe`` a FIFO, which, like the kernel's, gives each byte once. The
watch reads and writes these files as it would tracefs's; a test writes the kernel's lines
into the pipe and reads what the watch made of them.
"""

from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path
from typing import Any

from supervisord.rv_count import MONITORS
from supervisord.rv_watch import INSTANCE
from supervisord.testkit.wait import wait_until


def kernel_line(running: str, stamp: float, monitor: str, judged: str) -> str:
    """One ``error_*`` event as ftrace prints it, newline included."""
    return (
        f"{running:>20} [000] d..2. {stamp:12.6f}: error_{monitor}: {judged}: violation detected\n"
    )


class FakeTracefs:
    def __init__(self, root: Path, *, monitors: tuple[str, ...] = MONITORS) -> None:
        self.root = root
        self.instance = root / "instances" / INSTANCE
        rv = root / "rv"
        rv.mkdir(parents=True)
        listed = ["wwnr", "rtapp", *(f"rtapp:{name}" for name in monitors)]
        (rv / "available_monitors").write_text("\n".join(listed) + "\n")
        (rv / "enabled_monitors").write_text("wwnr\n")  # another tool's: must stay on
        (rv / "monitoring_on").write_text("0\n")
        for name in MONITORS:
            event = self.instance / "events/rv" / f"error_{name}"
            event.mkdir(parents=True)
            (event / "enable").write_text("0\n")
            (event / "trigger").write_text("# Available triggers:\n# traceon traceoff\n")
        (self.instance / "trace_clock").write_text("[local] global counter uptime perf mono\n")
        (self.instance / "tracing_on").write_text("1\n")
        (self.instance / "trace").write_text("# tracer: nop\n")
        stats = self.instance / "per_cpu/cpu0"
        stats.mkdir(parents=True)
        self.set_overrun(0)
        os.mkfifo(self.instance / "trace_pipe")
        self._pipe: int | None = None

    def set_overrun(self, events: int) -> None:
        text = f"entries: 0\noverrun: {events}\ncommit overrun: 0\nbytes: 0\n"
        (self.instance / "per_cpu/cpu0/stats").write_text(text)

    def read(self, relative: str) -> str:
        return (self.root / relative).read_text()

    def write(self, relative: str, text: str) -> None:
        (self.root / relative).write_text(text)

    def emit(self, text: str) -> None:
        """The kernel writes ``text`` into the ring; the pipe is opened once the watch reads it."""
        if self._pipe is None:

            def opened() -> bool:
                try:
                    self._pipe = os.open(self.instance / "trace_pipe", os.O_WRONLY | os.O_NONBLOCK)
                except OSError:  # ENXIO: no reader yet
                    return False
                return True

            wait_until(opened, 15.0, what="the watch reading trace_pipe")
        assert self._pipe is not None
        os.write(self._pipe, text.encode())

    def close(self) -> None:
        if self._pipe is not None:
            os.close(self._pipe)
            self._pipe = None


class Watch:
    """``python -m supervisord.rv_watch`` against a fake tracefs at ``root``, every 0.1 s,
    writing ``output``; its output in watch.log beside it."""

    def __init__(self, root: Path, output: Path) -> None:
        self.output = output
        self.log = output.with_name("watch.log")
        with self.log.open("ab") as log:
            self.process = subprocess.Popen(
                [
                    sys.executable,
                    "-m",
                    "supervisord.rv_watch",
                    *("--tracing", str(root), "--output", str(output), "--period", "0.1"),
                ],
                stdin=subprocess.DEVNULL,
                stdout=log,
                stderr=log,
            )

    def totals(self) -> dict[str, Any] | None:
        try:
            content: dict[str, Any] = json.loads(self.output.read_text())
        except FileNotFoundError:
            return None
        return content

    def wait_for(self, what: str, check: Any) -> dict[str, Any]:
        def seen() -> dict[str, Any] | None:
            if self.process.poll() is not None:
                raise AssertionError(self.log.read_text())
            totals = self.totals()
            return totals if totals is not None and check(totals) else None

        found: dict[str, Any] = wait_until(seen, 15.0, poll=0.05, what=what)
        return found
