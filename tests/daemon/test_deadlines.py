"""The turn's two questions about time (``daemon/deadlines.py``), asked of real parts: a link
port on the in-memory link (no descriptor: polled) and on a pty (a descriptor with bytes), an
output bank with an output not acquired yet, the service manager's face with a systemd
watchdog, and the listener's own deadline (SR-2, SR-6.5, SR-9.4, SR-10.1). The loop's use of
them: ``tests/daemon/test_loop.py`` (fairness, deadlines, reopen).

Mutants planted in ``deadlines.py`` and caught here: each of the five sources dropped (the
bank's, the reopen's, the poll's, the watchdog's, the listener's), ``<`` for the watchdog or
the listener turned ``>``, the poll's ``now +`` dropped, the clock read with no core deadline,
``>=`` turned ``>`` at the core's deadline, the link's readiness not asked, the question
waiting for the link (``select``'s timeout 0 turned 1).
"""

from __future__ import annotations

import os
import threading
import time
import tty
from collections.abc import Iterator
from pathlib import Path

import pytest

from supervisord.daemon.deadlines import POLL_NS, next_deadline, stop_path_waits
from supervisord.daemon.link_port import LinkPort
from supervisord.daemon.listener import Listener
from supervisord.daemon.notify import Notifier
from supervisord.daemon.output_bank import ACQUIRE_FIRST_MS, OutputBank
from supervisord.daemon.service_manager import ServiceManager
from supervisord.daemon.stoptimes import StopTimes
from supervisord.daemon.timings import Timings
from supervisord.links.base import Backoff
from supervisord.links.memory_link import MemoryLink, MemoryPort
from supervisord.links.serial_link import SerialLink
from supervisord.outputs.sim import SimOutput, SimSpec
from supervisord.protocol.framing import encode_frame
from supervisord.protocol.messages import VscHeartbeat
from supervisord.safety.config import SafetyConfig
from supervisord.safety.core import SafetyCore
from supervisord.safety.events import LinkOpened
from supervisord.testkit.clock import FakeClock
from tests.safety.rig import MS, OPERATIONAL, START_NS


class Due(Listener):
    """The listener's face with work of its own due at ``at`` (a commissioning's next frame)."""

    def __init__(self, at: int | None) -> None:
        self.at = at

    def next_deadline(self) -> int | None:
        return self.at


class Reads:
    """A clock that counts its reads: the question is asked without one when it need not."""

    def __init__(self, now: int) -> None:
        self.now, self.reads = now, 0

    def __call__(self) -> int:
        self.reads += 1
        return self.now


def _port(clock: FakeClock, vsc: MemoryPort) -> LinkPort:
    return LinkPort(MemoryLink(vsc), clock, Timings(), Backoff(100, 400))


def test_the_earliest_of_the_cores_the_banks_the_watchdogs_and_the_listeners_wins(
    tmp_path: Path,
) -> None:
    """SR-6.5, SR-9.4: with the link watched (a descriptor), the deadline is the core's unless
    the output bank's retry, the systemd watchdog or the listener's own work comes first."""
    clock = FakeClock(START_NS)
    now = clock()
    vsc = MemoryPort()
    port = _port(clock, vsc)
    port.open(now)
    lights = SimOutput(SimSpec(name="lights", path=tmp_path / "later" / "lights"))
    bank = OutputBank([lights], clock, StopTimes())
    plain = ServiceManager(Notifier({}))
    far = now + 10_000 * MS
    assert (
        next_deadline(now, far, 7, port, OutputBank([], clock, StopTimes()), plain, Due(None))
        == far
    )
    bank.open(now)  # not acquired: its retry comes first
    retry = now + ACQUIRE_FIRST_MS * MS
    assert next_deadline(now, far, 7, port, bank, plain, Due(None)) == retry
    assert next_deadline(now, retry - 1, 7, port, bank, plain, Due(None)) == retry - 1
    watched = ServiceManager(Notifier({"WATCHDOG_USEC": "2000000"}))
    watched.ready(now, SafetyCore(SafetyConfig(), now).decision)
    watched.watchdog(now)  # the next due half the period on
    assert watched.next_watchdog == now + 1_000 * MS
    empty = OutputBank([], clock, StopTimes())
    assert next_deadline(now, far, 7, port, empty, watched, Due(None)) == now + 1_000 * MS
    assert next_deadline(now, far, 7, port, bank, watched, Due(None)) == retry
    assert next_deadline(now, far, 7, port, bank, watched, Due(now + 5 * MS)) == now + 5 * MS
    assert next_deadline(now, far, 7, port, bank, watched, Due(far + 1)) == retry


def test_a_closed_link_wakes_the_loop_at_its_reopen_and_one_without_a_descriptor_to_poll() -> None:
    """SR-2, SR-5.1: a link not open (unplugged) is tried again at its backoff's time; an open
    link with no descriptor (in memory, python-can "virtual") is polled every ``POLL_NS``."""
    clock = FakeClock(START_NS)
    now = clock()
    vsc = MemoryPort()
    port = _port(clock, vsc)
    bank, service = OutputBank([], clock, StopTimes()), ServiceManager(Notifier({}))
    far = now + 10_000 * MS
    vsc.unplug()
    port.open(now)
    assert not port.link.is_open
    assert next_deadline(now, far, None, port, bank, service, Due(None)) == now + 100 * MS
    assert next_deadline(now, now + MS, None, port, bank, service, Due(None)) == now + MS
    vsc.replug()
    assert port.open(now + 100 * MS) == LinkOpened(now + 100 * MS)
    assert port.link.fileno() is None
    later = now + 100 * MS
    assert next_deadline(later, far, None, port, bank, service, Due(None)) == later + POLL_NS
    assert next_deadline(later, far, 9, port, bank, service, Due(None)) == far  # watched


@pytest.fixture
def pty_link(tmp_path: Path) -> Iterator[tuple[SerialLink, int]]:
    vsc, host = os.openpty()
    tty.setraw(vsc)
    link = SerialLink(os.ttyname(host))
    link.open()
    try:
        yield link, vsc
    finally:
        link.close()
        os.close(vsc)
        os.close(host)


def test_the_stop_path_waits_when_the_cores_deadline_has_come_or_the_link_has_bytes(
    pty_link: tuple[SerialLink, int],
) -> None:
    """SR-10.1: between two clients the loop yields to the stop path when the core's deadline
    has come (at it, not only after) or the VSC's bytes wait on the link; with no core
    deadline (before the start) the clock is not read."""
    link, vsc = pty_link
    clock = Reads(START_NS)
    assert not stop_path_waits(clock, None, link)
    assert clock.reads == 0
    assert not stop_path_waits(clock, START_NS + 1, link)
    assert stop_path_waits(clock, START_NS, link)
    assert stop_path_waits(clock, START_NS - 1, link)
    os.write(vsc, encode_frame(VscHeartbeat(OPERATIONAL)))
    assert stop_path_waits(clock, START_NS + 1, link)
    assert stop_path_waits(clock, None, link)
    link.close()
    assert not stop_path_waits(clock, None, link)  # closed: nothing to read


def _sleeps_in_select_over(tid: int, fd: int) -> bool:
    """Whether thread ``tid`` of this process sleeps in ``select`` over descriptors up to
    ``fd`` (the kernel shows a thread's system call and its first argument, here ``nfds``,
    only while the thread sleeps in it; a running thread shows ``running``)."""
    try:
        fields = Path(f"/proc/self/task/{tid}/syscall").read_text().split()
    except OSError:  # the thread ended
        return False
    return len(fields) > 1 and fields[1] == hex(fd + 1)


def test_the_stop_paths_question_looks_at_the_link_and_does_not_wait_for_it(
    pty_link: tuple[SerialLink, int],
) -> None:
    """SR-10.1, SR-9.4: asked between two clients, the question looks at the link as it is
    and returns; it never waits for the VSC's bytes (a wait there holds the clients behind it
    and the core's deadline). A watcher thread sends the VSC's frame only once the asking
    thread sleeps in ``select`` over the link: a question that does not wait never sleeps
    there (a timeout of 0), so the frame is not sent and the answer is no."""
    link, vsc = pty_link
    fd = link.fileno()
    assert fd is not None
    asker = threading.get_native_id()
    watching, asked = threading.Event(), threading.Event()
    sent: list[bool] = []

    def watch() -> None:
        watching.set()
        while not asked.is_set():
            if _sleeps_in_select_over(asker, fd):
                os.write(vsc, encode_frame(VscHeartbeat(OPERATIONAL)))
                sent.append(True)
                return
            time.sleep(0.0005)

    watcher = threading.Thread(target=watch, name="watcher")
    watcher.start()
    watching.wait()
    try:
        waits = stop_path_waits(Reads(START_NS), None, link)
    finally:
        asked.set()
        watcher.join()
    assert sent == []
    assert not waits
