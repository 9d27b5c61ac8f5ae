"""The README's first command: ``srcsctl demo``, the supervisor against the simulator."""

from __future__ import annotations

import datetime as dt
import fcntl
import json
import os
import pty
import re
import select
import struct
import subprocess
import tempfile
import termios
import time
from pathlib import Path
from zoneinfo import ZoneInfo

from tests.daemon.test_srcsctl import SRCSCTL


def test_sigterm_stops_the_demo_and_everything_it_started() -> None:
    """A demo ended by SIGTERM leaves no simulator or supervisor running behind it."""
    with subprocess.Popen(
        [SRCSCTL, "demo", "--auto"], stdout=subprocess.PIPE, stderr=subprocess.DEVNULL, text=True
    ) as demo:
        assert demo.stdout is not None
        while "supervisor: STOPPED" not in demo.stdout.readline():
            assert demo.poll() is None
        children = _children(demo.pid)
        assert len(children) == 2  # srcs-sim and srcsd
        demo.terminate()
        assert demo.wait(timeout=20) == 0
    end = time.monotonic() + 10
    while any(Path(f"/proc/{pid}").exists() for pid in children):
        assert time.monotonic() < end, "left running"
        time.sleep(0.05)


def _children(pid: int) -> list[int]:
    found = []
    for task in Path(f"/proc/{pid}/task").iterdir():
        found += [int(c) for c in (task / "children").read_text().split()]
    return found


def test_the_story_shows_stops_and_rearms() -> None:
    """SR-7.1: without a terminal the demo plays its story: commissioning, a takeover to RUN,
    a remote e-stop, a cut link and a pause, each followed by a re-arm, with every stop record
    from the first (#1, written before the demo could subscribe) as one line each: the local
    time (the zone of TZ), the state change, the kind and which cause was raised or cleared,
    never the whole cause set again, each state it reports after the record of the change into
    it (the story in the order it happened); it cleans up and exits 0."""
    zone = "Asia/Kolkata"  # +05:30: a time of day in UTC is hours away from it
    before = dt.datetime.now(ZoneInfo(zone))
    done = subprocess.run(
        [SRCSCTL, "demo", "--speed", "4"],
        capture_output=True,
        timeout=120,
        check=False,
        text=True,
        env={**os.environ, "TZ": zone},
    )
    assert done.returncode == 0, done.stderr
    states = re.findall(r"supervisor: (\w+); outputs drive (\w+)", done.stdout)
    assert states == [
        ("STOPPED", "off"),
        ("RUN", "ON"),
        ("STOPPED", "off"),
        ("RUN", "ON"),
        ("STOPPED", "off"),
        ("RUN", "ON"),
        ("RUN", "ON"),
    ]
    records = re.findall(r"^  record (\d\d):(\d\d):\S+  #(\d+) ", done.stdout, re.M)
    assert [int(seq) for _, _, seq in records] == list(range(1, len(records) + 1))
    hour, minute = int(records[0][0]), int(records[0][1])
    apart = (before.replace(hour=hour, minute=minute) - before).total_seconds() % 86400
    assert min(apart, 86400 - apart) < 600, (records[0], before)  # local time, not UTC
    assert re.search(r"STOPPED +commissioned +commissioned: key85=1 remote_status=on", done.stdout)
    assert re.search(
        r"prooftest +proof test passed: tripped after \d+ ms, limit 700 ms", done.stdout
    )
    assert re.search(
        r"RUN -> STOPPED +state_change +raised vsc_estop \(sources=remote\)", done.stdout
    )
    assert re.search(r"RUN -> STOPPED +state_change +raised transport_fault", done.stdout)
    assert re.search(r"RUN -> HOLD +state_change +raised vsc_mode:pause$", done.stdout, re.M)
    assert re.search(r"STOPPED -> RUN +state_change +re-armed by takeover", done.stdout)
    assert "[demo] srcsctl finds this demo: srcsctl --demo status (socket " in done.stdout
    assert _told_in_order(done.stdout)


def _told_in_order(story: str) -> bool:
    """Whether every ``supervisor: STATE`` line of the story comes after a record whose state
    (the state it changed into) is STATE: the record of a change before the next act."""
    recorded = None
    for line in story.splitlines():
        record = re.match(r"  record \S+ +#\d+ +(?:\w+ -> )?(\w+) ", line)
        if record:
            recorded = record.group(1)
        shown = re.match(r"  supervisor: (\w+);", line)
        if shown and shown.group(1) != recorded:
            raise AssertionError(f"{line!r} before the record of it (last: {recorded}):\n{story}")
    return True


SEEN: list[bytes] = [b""]


def _read_until(fd: int, pattern: str, limit: float = 30.0, *, required: bool = True) -> bool:
    seen = SEEN[0] = b""
    end = time.monotonic() + limit
    while re.search(pattern, seen.decode(errors="replace")) is None:
        if time.monotonic() > end:
            assert not required, seen[-2000:]
            return False
        ready, _, _ = select.select([fd], [], [], 0.2)
        if ready:
            seen += os.read(fd, 65536)
            SEEN[0] = seen
    return True


def test_keys_in_a_terminal_take_over_and_stop() -> None:
    """In a terminal the view is redrawn live; [t] takes over (RUN, outputs on), [e] presses
    the remote's e-stop (STOPPED, outputs off), [q] quits with exit status 0."""
    controller, terminal = pty.openpty()
    with subprocess.Popen(
        [SRCSCTL, "demo"], stdin=terminal, stdout=terminal, stderr=subprocess.PIPE
    ) as demo:
        os.close(terminal)
        try:
            _read_until(controller, r"supervisor  state STOPPED")
            _read_until(controller, r"commissioned: key 85 reads 1")
            running = r"state RUN[\s\S]{0,80}drive ON"
            for _ in range(10):  # until the re-arm hold has passed since the last cause cleared
                os.write(controller, b"t")
                if _read_until(controller, running, 2.0, required=False):
                    break
            else:
                raise AssertionError(SEEN[0][-3000:].decode(errors="replace"))
            os.write(controller, b"e")
            _read_until(controller, r"state STOPPED[\s\S]{0,80}vsc_estop")
            os.write(controller, b"q")
            assert demo.wait(timeout=20) == 0
        finally:
            if demo.poll() is None:  # SIGTERM: the demo stops its simulator and supervisor
                demo.terminate()
                demo.wait(timeout=20)
            os.close(controller)


WIDTH = 100  # columns of the demo's terminal: a line wider than this would wrap and tear


class Screen:
    """The demo's terminal as a person sees it: the last whole frame it drew."""

    def __init__(self, fd: int) -> None:
        self.fd = fd
        self.data = b""

    def frames(self) -> list[str]:
        # Each frame starts by homing the cursor and clearing the screen.
        return self.data.decode(errors="replace").split("\x1b[H\x1b[2J")[1:-1]

    def until(self, pattern: str, limit: float = 30.0) -> list[str]:
        """The lines of the first whole frame after now that matches ``pattern``."""
        start = len(self.frames())
        end = time.monotonic() + limit
        while True:
            for frame in self.frames()[start:]:
                if re.search(pattern, frame, re.M):
                    return frame.splitlines()
            assert time.monotonic() < end, self.frames()[-1:]
            ready, _, _ = select.select([self.fd], [], [], 0.2)
            if ready:
                self.data += os.read(self.fd, 65536)

    def press(self, key: str) -> None:
        os.write(self.fd, key.encode())

    def read_until_exit(self, process: subprocess.Popen[bytes], limit: float = 20.0) -> int:
        """Keep reading, as a terminal does, until ``process`` exits; its exit status. (A
        terminal that stops reading fills the pty, and the demo's next frame waits for it.)"""
        end = time.monotonic() + limit
        while process.poll() is None:
            assert time.monotonic() < end, "the demo did not exit"
            ready, _, _ = select.select([self.fd], [], [], 0.05)
            if ready:
                try:
                    self.data += os.read(self.fd, 65536)
                except OSError:  # EIO: the last holder of the terminal's end closed it
                    process.wait(max(0.0, end - time.monotonic()))
        return process.returncode


def _notes(lines: list[str]) -> list[str]:
    """The notes under NEXT (lines starting ``> ``, with their folded continuations)."""
    notes: list[str] = []
    for line in lines[3:]:
        if line.startswith("> "):
            notes.append(line[2:])
        elif line.startswith("  ") and notes:
            notes[-1] += " " + line.strip()
        else:
            break
    return notes


def _srcsctl(*args: str, env: dict[str, str]) -> subprocess.CompletedProcess[str]:
    return subprocess.run(
        [SRCSCTL, *args], capture_output=True, text=True, timeout=30, check=False, env=env
    )


def test_the_screen_says_what_to_do_and_shows_a_refused_takeover() -> None:
    """SR-4 (the refusal's reason), SR-7.1: in a 100-column terminal every line of the demo
    fits (nothing wraps); the first screen's top line says the one thing to do once the
    supervisor may re-arm, and the screen names the socket; ``srcsctl --demo`` finds the
    running demo by itself (status, and the log from record #1 with the proof test's verdict
    and the commissioning); a takeover while the supervisor proves the VSC's watchdog again
    after a restored link is shown refused, with its reason, in the notes under that line.

    The demo and ``srcsctl --demo`` share a temporary directory of the test's own ($TMPDIR,
    short: the socket's path must fit), so that another demo on the machine is not found."""
    with tempfile.TemporaryDirectory(prefix="sd-", dir="/tmp") as private:
        _screen_and_refusal({**os.environ, "TMPDIR": private})


def _screen_and_refusal(env: dict[str, str]) -> None:
    controller, terminal = pty.openpty()
    fcntl.ioctl(terminal, termios.TIOCSWINSZ, struct.pack("HHHH", 50, WIDTH, 0, 0))
    with subprocess.Popen(
        [SRCSCTL, "demo"], stdin=terminal, stdout=terminal, stderr=subprocess.PIPE, env=env
    ) as demo:
        os.close(terminal)
        screen = Screen(controller)
        try:
            first = screen.until(r"^NEXT: press \[t\] to take over")
            assert all(len(line) <= WIDTH for line in first), first
            assert first[2].startswith("NEXT: press [t] to take over"), first
            assert any("srcsctl --demo status" in line for line in first), first

            status = _srcsctl("--demo", "status", env=env)
            assert status.returncode == 0, status.stderr
            assert status.stdout.startswith("robot demo: STOPPED")
            log = _srcsctl("log", "--demo", env=env)
            assert log.returncode == 0, log.stderr
            assert re.search(r"  #1 +STOPPED +cause_raised +raised startup\*", log.stdout)
            assert "commissioned: key85=1 remote_status=on" in log.stdout
            assert re.search(r"proof test passed: tripped after \d+ ms, limit 700 ms", log.stdout)

            refused = None
            for _ in range(5):  # until one takeover comes while the proof test runs
                screen.press("l")
                screen.until(r"^NEXT: the link is cut")
                screen.press("l")
                screen.until(r"^NEXT: wait: the supervisor is proving the VSC's watchdog")
                screen.press("t")
                shown = screen.until(r"^> takeover refused: |^NEXT: RUN")
                if any(line.startswith("> takeover refused: ") for line in shown):
                    refused = shown
                    break
            assert refused is not None, screen.frames()[-1:]
            assert all(len(line) <= WIDTH for line in refused), refused
            recorded = _srcsctl("log", "--demo", "-o", "json", env=env)
            records = [json.loads(line) for line in recorded.stdout.splitlines()]
            last = [r for r in records if r["kind"] == "rearm_refused"][-1]
            # The note, folded onto as many lines as it needs, says the record's reason, and
            # is among the notes right under NEXT, where the operator looks.
            notes = _notes(refused)
            assert f"takeover refused: {last['reason']}" in notes, refused
            screen.press("q")
            assert screen.read_until_exit(demo) == 0
        finally:
            if demo.poll() is None:
                demo.terminate()
                screen.read_until_exit(demo)
            os.close(controller)
    gone = _srcsctl("--demo", "status", env=env)
    assert gone.returncode == 2
    assert "no demo is running (start one with: srcsctl demo)" in gone.stderr
