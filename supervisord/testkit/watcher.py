"""Watching the files of ``kind = "sim"`` outputs: every level each showed, and when."""

from __future__ import annotations

import select
import threading
import time
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path

from supervisord.testkit.inotify import IN_CLOSE_WRITE, IN_CREATE, IN_MOVED_TO, Inotify
from supervisord.testkit.wait import WAIT_S, wait_until


@dataclass(frozen=True)
class Level:
    """One observed level of an output file: ``t`` (monotonic s) when it was seen, ``on``.
    ``inferred`` marks a level the watcher did not read but knows must have been there
    (see ``OutputWatcher``)."""

    t: float
    on: bool
    inferred: bool = False


class OutputWatcher:
    """Follows the files of ``kind = "sim"`` outputs with inotify, from a thread, and keeps
    every level each file showed, with the monotonic time it was seen.

    The simulated output replaces its file atomically, and only when the level changes
    (``supervisord/outputs/sim.py``); the only exception is the "off" it writes when the
    output is acquired at a daemon start. So between two daemon starts the levels must
    alternate: two "off" readings in a row mean an "on" came and went faster than this
    thread could read it. The watcher records that "on" as ``inferred`` at the second
    reading's time, so a brief "on" is never missed, only timed late. Call ``daemon_started``
    before each daemon start. One case it cannot tell: after a daemon start, an "on" and an
    "off" that this thread reads together with the acquisition's "off" (a starved thread,
    seen once under load) look like the acquisition alone; a test that needs the level after a
    restart reads the file itself (``Robot.output_file``)."""

    def __init__(self, paths: Sequence[Path]) -> None:
        self.paths = {path.name: path for path in paths}
        self.levels: dict[str, list[Level]] = {name: [] for name in self.paths}
        self._starts: list[float] = []
        self._lock = threading.Lock()
        self._stop = threading.Event()
        self._inotify = Inotify()
        for folder in {path.parent for path in paths}:
            self._inotify.watch(folder, IN_MOVED_TO | IN_CLOSE_WRITE | IN_CREATE)
        self._thread = threading.Thread(target=self._run, name="output-watcher", daemon=True)
        self._thread.start()

    def daemon_started(self) -> None:
        with self._lock:
            self._starts.append(time.monotonic())

    def _run(self) -> None:
        fd = self._inotify.fd
        while not self._stop.is_set():
            ready, _, _ = select.select([fd], [], [], 0.05)
            if not ready:
                continue
            seen = time.monotonic()
            for name in dict.fromkeys(self._inotify.read()):
                if name in self.paths:
                    self._sample(name, seen)

    def _sample(self, name: str, seen: float) -> None:
        try:
            text = self.paths[name].read_text()
        except FileNotFoundError:
            return
        if text not in ("0\n", "1\n"):
            return  # never seen: the file is replaced atomically; be safe all the same
        on = text == "1\n"
        with self._lock:
            history = self.levels[name]
            if history and history[-1].on == on:
                started = any(history[-1].t <= start <= seen for start in self._starts)
                if on or not started:
                    # A missed level in between: the opposite one, for an instant.
                    history.append(Level(seen, not on, inferred=True))
                elif not on:
                    return  # the "off" written when a restarted daemon acquired the output
            history.append(Level(seen, on))

    def level(self, name: str) -> bool | None:
        with self._lock:
            history = self.levels[name]
            return history[-1].on if history else None

    def level_at(self, name: str, t: float) -> bool | None:
        """The level last seen before ``t``."""
        before = [lv for lv in self.history(name) if lv.t < t]
        return before[-1].on if before else None

    def history(self, name: str) -> list[Level]:
        with self._lock:
            return list(self.levels[name])

    def first(self, name: str, on: bool, after: float) -> Level | None:
        """The first level ``on`` seen at or after ``after``."""
        return next((lv for lv in self.history(name) if lv.on == on and lv.t >= after), None)

    def wait(self, name: str, on: bool, after: float, timeout: float = WAIT_S) -> Level:
        """The first level ``on`` of ``name`` seen at or after ``after``; waits for it."""
        found = wait_until(
            lambda: self.first(name, on, after),
            timeout,
            poll=0.005,
            what=f"output {name} {'on' if on else 'off'}",
        )
        assert isinstance(found, Level)
        return found

    def ons_between(self, start: float, end: float) -> list[tuple[str, Level]]:
        """Every "on" seen in ``[start, end)``, on any output."""
        return [
            (name, lv)
            for name in self.paths
            for lv in self.history(name)
            if lv.on and start <= lv.t < end
        ]

    def close(self) -> None:
        self._stop.set()
        self._thread.join()
        self._inotify.close()
