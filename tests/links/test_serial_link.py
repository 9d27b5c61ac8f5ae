"""The serial link against real pseudo-terminals: traffic, unplug, replug, busy, missing."""

from __future__ import annotations

import os
import select
import subprocess
import sys
import time
from collections.abc import Iterator
from pathlib import Path

import pytest

from supervisord.links.base import Backoff, LinkBrokenError, LinkError
from supervisord.links.serial_link import SerialLink
from supervisord.protocol.framing import FrameDecoder, encode_frame
from supervisord.protocol.messages import FeedbackGet, UserHeartbeat, VscHeartbeat
from supervisord.sim.pty import PtyPort


def receive_until(link: SerialLink, count: int) -> list[object]:
    """Read from the link (waiting on its descriptor) until ``count`` things arrived."""
    received: list[object] = []
    while len(received) < count:
        fd = link.fileno()
        assert fd is not None
        ready, _, _ = select.select([fd], [], [], 2.0)
        assert ready, f"only {received} arrived"
        received += link.receive()
    return received


@pytest.fixture
def port(tmp_path: Path) -> Iterator[PtyPort]:
    with PtyPort(tmp_path / "vsc") as device:
        yield device


def test_frames_both_ways(port: PtyPort) -> None:
    """Frames the VSC writes are decoded; frames we send arrive byte-exact at the VSC."""
    link = SerialLink(str(port.path))
    link.open()
    try:
        port.write(
            encode_frame(VscHeartbeat(9)) + b"\x00junk" + encode_frame(VscHeartbeat(4, 0, 1))
        )
        received = receive_until(link, 3)
        assert [r for r in received if isinstance(r, VscHeartbeat)] == [
            VscHeartbeat(9),
            VscHeartbeat(4, 0, 1),
        ]
        link.send([UserHeartbeat(0), FeedbackGet(85)])
        assert FrameDecoder().feed(port.read(timeout=2.0)) == [UserHeartbeat(0), FeedbackGet(85)]
    finally:
        link.close()


def test_unplug_is_broken_and_replug_reopens(port: PtyPort) -> None:
    """Closing the device end makes receive raise LinkBrokenError; a new device at the same path
    opens again and its traffic decodes with a fresh decoder."""
    link = SerialLink(str(port.path))
    link.open()
    port.write(encode_frame(VscHeartbeat(9))[:5])  # half a frame, then the plug is pulled
    port.unplug()
    with pytest.raises(LinkBrokenError):
        receive_until(link, 1)
    link.close()
    with pytest.raises(LinkError):
        link.open()  # nothing at the path while unplugged
    port.replug()
    link.open()
    try:
        port.write(encode_frame(VscHeartbeat(9)))
        assert receive_until(link, 1) == [VscHeartbeat(9)]
    finally:
        link.close()


def test_missing_port_is_a_link_error(tmp_path: Path) -> None:
    """A port that does not exist gives LinkError with the system's reason."""
    with pytest.raises(LinkError, match="No such file"):
        SerialLink(str(tmp_path / "absent")).open()


def test_port_held_by_another_process_is_busy(port: PtyPort) -> None:
    """A port another process holds exclusively cannot be opened: LinkError, not a hang."""
    holder = subprocess.Popen(
        [
            sys.executable,
            "-c",
            "import serial, sys; s = serial.Serial(sys.argv[1], exclusive=True); "
            "print('held', flush=True); sys.stdin.read()",
            str(port.path),
        ],
        stdin=subprocess.PIPE,
        stdout=subprocess.PIPE,
    )
    try:
        assert holder.stdout is not None
        assert holder.stdout.readline() == b"held\n"
        with pytest.raises(LinkError, match="lock"):
            SerialLink(str(port.path)).open()
    finally:
        holder.communicate(b"", timeout=10)


def test_reopening_leaks_no_descriptor(port: PtyPort) -> None:
    """PR-6.5: a hundred open/unplug/fail/replug cycles leave the process's descriptor count as it
    was."""
    before = len(os.listdir("/proc/self/fd"))
    link = SerialLink(str(port.path))
    for _ in range(100):
        link.open()
        link.close()
        port.unplug()
        with pytest.raises(LinkError):
            link.open()
        port.replug()
    assert len(os.listdir("/proc/self/fd")) == before


def test_a_prepared_port_is_taken_by_the_open_and_closed_if_never_taken(port: PtyPort) -> None:
    """SR-9.8: ``prepare`` opens the port (off the loop: a tty's open waits for the kernel's
    locks and a USB device's replies), ``open`` takes it; one never taken is closed with the
    link, and a prepare that failed is raised by the open as its own would be."""
    link = SerialLink(str(port.path))
    assert link.prepares_open
    link.prepare()
    assert link.fileno() is None  # made, not yet taken
    with pytest.raises(LinkError, match="lock"):
        SerialLink(str(port.path)).open()  # the prepared port holds the exclusive lock
    link.open()
    assert link.fileno() is not None
    port.write(encode_frame(VscHeartbeat(9)))
    assert receive_until(link, 1) == [VscHeartbeat(9)]
    link.close()
    link.prepare()
    link.close()  # never taken: closed all the same
    other = SerialLink(str(port.path))
    other.open()  # the lock went with it
    other.close()
    port.unplug()
    link.prepare()
    with pytest.raises(LinkError, match="No such file"):
        link.open()
    assert not link.is_open


def test_a_detached_port_is_closed_to_the_loop_at_once_and_released_by_what_it_returns(
    port: PtyPort,
) -> None:
    """SR-9.8: after a break the link is closed to the loop at once (not open, no descriptor,
    a read is a break) while the tty itself stays open until the release it returned runs:
    the link port runs it off the loop, since a tty's close waits for the tty's lock, which
    an unplug's hang-up holds. A second detach has nothing left to release."""
    link = SerialLink(str(port.path))
    link.open()
    fd = link.fileno()
    assert fd is not None
    release = link.detach()
    assert release is not None
    assert (link.is_open, link.fileno()) == (False, None)
    with pytest.raises(LinkBrokenError, match="not open"):
        link.receive()
    assert os.readlink(f"/proc/self/fd/{fd}") == os.path.realpath(port.path)  # still open
    with pytest.raises(LinkError, match="lock"):
        SerialLink(str(port.path)).open()  # the old port still holds its exclusive lock
    release()
    assert not os.path.exists(f"/proc/self/fd/{fd}") or os.readlink(
        f"/proc/self/fd/{fd}"
    ) != os.path.realpath(port.path)
    assert link.detach() is None
    link.open()  # the lock went with the close
    link.close()


def test_backoff_doubles_to_its_limit_and_resets() -> None:
    """Reopen attempts wait 100, 200, 400 ms ... up to the limit, and start over after success."""
    backoff = Backoff(first_ms=100, max_ms=500)
    waits = []
    for now in (0, 10**9, 2 * 10**9, 3 * 10**9, 4 * 10**9):
        backoff.failed(now)
        waits.append((backoff.next_attempt - now) // 1_000_000)
    assert waits == [100, 200, 400, 500, 500]
    backoff.succeeded()
    backoff.failed(0)
    assert backoff.next_attempt == 100_000_000


def test_what_waited_in_the_port_before_open_is_discarded(port: PtyPort) -> None:
    """Heartbeats the VSC wrote before the link opened (an e-stop-free Operational one among
    them) are never read as current: the first thing read is what came after."""
    stale = encode_frame(VscHeartbeat(9)) * 20 + encode_frame(VscHeartbeat(4, 0, 1))
    port.write(stale)
    time.sleep(0.05)  # the bytes are in the line's input queue before anyone opens it
    link = SerialLink(str(port.path))
    link.open()
    try:
        port.write(encode_frame(VscHeartbeat(11)))
        assert receive_until(link, 1) == [VscHeartbeat(11)]
        fd = link.fileno()
        assert fd is not None
        ready, _, _ = select.select([fd], [], [], 0.1)
        assert not ready  # and nothing of the old stream follows
    finally:
        link.close()
