"""The README's first command: ``srcsctl demo``, the supervisor against the simulator."""

from __future__ import annotations

import os
import pty
import re
import select
import subprocess
import time
from pathlib import Path

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
    """Without a terminal the demo plays its story: commissioning, a takeover to RUN, a
    remote e-stop, a cut link and a pause, each followed by a re-arm, with the stop records
    as they are written; it cleans up and exits 0."""
    done = subprocess.run(
        [SRCSCTL, "demo", "--speed", "4"], capture_output=True, timeout=120, check=False, text=True
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
    assert "[commissioned]" in done.stdout
    assert re.search(r"RUN -> STOPPED \[state_change\] causes: vsc_estop", done.stdout)
    assert re.search(r"RUN -> STOPPED \[state_change\] causes: transport_fault", done.stdout)
    assert "RUN -> HOLD [state_change] causes: vsc_mode:pause" in done.stdout


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
