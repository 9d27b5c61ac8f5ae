"""The link port on the in-memory link (the serial protocol's bytes, no port: it passes the
links' conformance suite), time passed as ``now`` and a clock the test moves: opening with a
backoff, receiving into messages with their read time, sending, the counters and the
heartbeats' periods (SR-2, SR-2.2, SR-5.1, SR-8.18, SR-9.3). The port in the real loop, with
a pty VSC that is unplugged and replugged, is
``tests/daemon/test_loop.py::test_start_takeover_estop_silence_unplug``."""

from __future__ import annotations

import logging
import threading
import time
from collections.abc import Callable

import pytest

from supervisord.daemon.link_port import (
    CLOSE_THREAD,
    FAILURES_LOGGED_EVERY,
    PREPARE_POLL_NS,
    PREPARE_THREAD,
    LinkPort,
)
from supervisord.daemon.timings import Timings
from supervisord.links.base import Backoff
from supervisord.links.memory_link import MemoryLink, MemoryPort
from supervisord.protocol.codes import VscMode
from supervisord.protocol.framing import RejectReason, encode_frame
from supervisord.protocol.messages import UserHeartbeat, VscHeartbeat
from supervisord.safety.events import LinkBroken, LinkOpened
from supervisord.timebase import NS_PER_MS

MS = NS_PER_MS
RUN = VscHeartbeat(VscMode.OPERATIONAL)


class Clock:
    """A clock the test sets; it never runs backwards."""

    def __init__(self) -> None:
        self.now = 0

    def __call__(self) -> int:
        return self.now

    def at(self, now: int) -> int:
        assert now >= self.now
        self.now = now
        return now


@pytest.fixture
def rig() -> tuple[LinkPort, MemoryPort, Clock]:
    vsc, clock = MemoryPort(), Clock()
    return LinkPort(MemoryLink(vsc), clock, Timings(), Backoff(100, 400)), vsc, clock


def test_a_link_that_cannot_open_backs_off_and_says_why_until_it_opens(
    rig: tuple[LinkPort, MemoryPort, Clock],
) -> None:
    port, vsc, _ = rig
    vsc.unplug()
    failed = port.open(1_000 * MS)
    assert failed == LinkBroken(1_000 * MS, "cannot open: No such device")
    assert port.next_attempt == 1_100 * MS
    assert port.open(1_100 * MS) == LinkBroken(1_100 * MS, "cannot open: No such device")
    assert port.next_attempt == 1_300 * MS  # doubled
    status = port.status(1_200 * MS)
    assert (status.open, status.opens, status.open_failures) == (False, 0, 2)
    assert status.last_error == "cannot open: No such device"
    vsc.replug()
    assert port.open(1_300 * MS) == LinkOpened(1_300 * MS)
    status = port.status(1_500 * MS)
    assert (status.open, status.opens, status.open_failures) == (True, 1, 2)
    assert status.last_error is None  # SR-8.18: history once open; the count stays
    assert status.since_s == pytest.approx(0.2)
    assert status.error_frames is None  # CAN only


def test_what_was_read_comes_back_with_the_time_it_was_read_and_rejections_counted(
    rig: tuple[LinkPort, MemoryPort, Clock],
) -> None:
    """SR-2: stamped right after the read; SR-2.1: a frame that fails its check is counted
    by its reason and never handed on as a message."""
    port, vsc, clock = rig
    assert port.open(0) == LinkOpened(0)
    bad = bytearray(encode_frame(RUN))
    bad[-1] ^= 0xFF
    vsc.write(bytes(bad) + encode_frame(RUN) + encode_frame(VscHeartbeat(VscMode.PAUSE)))
    clock.at(7 * MS)
    assert port.receive() == (7 * MS, [RUN, VscHeartbeat(VscMode.PAUSE)])
    assert port.messages == 2
    assert port.rejections["bad_checksum"] == 1  # (and its bytes' resync, as the decoder says)
    assert set(port.rejections) <= {reason.value for reason in RejectReason}
    assert port.receive() == (7 * MS, [])
    rejected = dict(port.rejections)
    vsc.send(RUN)  # a read of messages alone, the usual one
    clock.at(9 * MS)
    assert port.receive() == (9 * MS, [RUN])
    assert (port.messages, port.rejections) == (3, rejected)


def test_a_link_broken_under_a_read_or_a_write_is_closed_and_reopened_after_the_backoff(
    rig: tuple[LinkPort, MemoryPort, Clock],
) -> None:
    port, vsc, clock = rig
    port.open(0)
    vsc.unplug()
    clock.at(50 * MS)
    assert port.receive() == LinkBroken(50 * MS, "device gone")
    assert not port.link.is_open
    assert port.next_attempt == 150 * MS
    assert port.status(60 * MS).last_error == "device gone"
    assert port.send((UserHeartbeat(),), 60 * MS) is None  # closed: nothing is written
    vsc.replug()
    assert port.open(150 * MS) == LinkOpened(150 * MS)
    vsc.unplug()
    assert port.send((UserHeartbeat(),), 200 * MS) == LinkBroken(200 * MS, "device gone")
    assert port.next_attempt == 300 * MS  # the backoff started afresh at the open


def test_frames_go_out_in_order_and_the_user_heartbeat_period_is_the_writes_return(
    rig: tuple[LinkPort, MemoryPort, Clock],
) -> None:
    """SR-5.1, SR-9.3: the period the VSC's watchdog sees, from when each write returned."""
    port, vsc, clock = rig
    port.open(0)
    for sent in (10 * MS, 60 * MS, 115 * MS):
        clock.at(sent)
        assert port.send((UserHeartbeat(),), sent - MS) is None
    assert vsc.read() == encode_frame(UserHeartbeat()) * 3
    periods = port.timings.user_heartbeat_period
    assert (periods.count, periods.sum_ns) == (2, 105 * MS)
    assert port.send((), 200 * MS) is None


def test_a_vsc_heartbeat_period_is_one_per_read_and_a_reopen_starts_afresh(
    rig: tuple[LinkPort, MemoryPort, Clock],
) -> None:
    """SR-2.2: one period per read that brought heartbeats; none across a reopen (it would
    measure the outage, docs/fleet.md)."""
    port, _, _ = rig
    port.open(0)
    port.heard(100 * MS)
    port.heard(150 * MS)
    port.heard(210 * MS)
    periods = port.timings.vsc_heartbeat_period
    assert (periods.count, periods.sum_ns) == (2, 110 * MS)
    port.send((UserHeartbeat(),), 220 * MS)
    port.link.close()
    port.open(5_000 * MS)
    port.heard(5_050 * MS)
    assert periods.count == 2
    assert port.timings.last_user_heartbeat_ns is None


def test_a_link_that_keeps_failing_to_open_is_logged_once_then_one_failure_in_50(
    rig: tuple[LinkPort, MemoryPort, Clock], caplog: pytest.LogCaptureFixture
) -> None:
    """A missing device retried for hours must not flood the log; its count is in status."""
    port, vsc, _ = rig
    vsc.unplug()
    with caplog.at_level(logging.WARNING, logger="srcsd"):
        for attempt in range(FAILURES_LOGGED_EVERY * 2):
            port.open(attempt * 500 * MS)
    assert [r.getMessage() for r in caplog.records] == [
        "memory memory: cannot open: No such device (retrying)"
    ] * 3  # the 1st, the 50th and the 100th
    assert port.status(0).open_failures == FAILURES_LOGGED_EVERY * 2


def test_closing_closes_the_link_then_runs_every_release_though_one_fails() -> None:
    """SR-6.6: the shutdown closes the link, then releases what was opened for it (the CAN bus
    a link owns), each release best effort: one that raises leaves the next to run and the
    exit to go on. Mutants caught: a release run before the link is closed, the suppression
    dropped, the releases stopped at the first failure."""
    vsc, clock = MemoryPort(), Clock()
    seen: list[str] = []

    def failing() -> None:
        seen.append(f"first, link open: {port.link.is_open}")
        raise OSError("the bus is gone")

    port = LinkPort(
        MemoryLink(vsc),
        clock,
        Timings(),
        Backoff(100, 400),
        [failing, lambda: seen.append("second")],
    )
    assert port.open(0) == LinkOpened(0)
    port.close()
    assert not port.link.is_open
    assert seen == ["first, link open: False", "second"]


def test_the_failures_logged_are_the_first_then_the_50th_and_every_50th_after(
    rig: tuple[LinkPort, MemoryPort, Clock], caplog: pytest.LogCaptureFixture
) -> None:
    """Which failures are logged, by their number (the count above would not tell a line at
    the 2nd from one at the 1st, nor 1 in 49 or 51 from 1 in 50): the 1st, the 50th, the
    100th."""
    port, vsc, _ = rig
    vsc.unplug()
    logged = []
    with caplog.at_level(logging.WARNING, logger="srcsd"):
        for attempt in range(1, 101):
            before = len(caplog.records)
            port.open(attempt * 500 * MS)
            if len(caplog.records) > before:
                logged.append(attempt)
    assert logged == [1, 50, 100]
    assert FAILURES_LOGGED_EVERY == 50  # as the docstring and docs say


def test_a_read_of_rejected_frames_alone_hands_on_no_message(
    rig: tuple[LinkPort, MemoryPort, Clock],
) -> None:
    """SR-2.1: a read that brought only frames that failed their check hands on none of them
    and counts none as a message (the usual read's shortcut is taken only when every item is
    a message)."""
    port, vsc, clock = rig
    assert port.open(0) == LinkOpened(0)
    bad = bytearray(encode_frame(RUN))
    bad[-1] ^= 0xFF
    vsc.write(bytes(bad))
    clock.at(3 * MS)
    assert port.receive() == (3 * MS, [])
    assert port.messages == 0
    assert port.rejections["bad_checksum"] == 1


def test_a_new_ports_counters_start_at_zero() -> None:
    """SR-8.18: ``srcsctl status`` counts from the start: one failed open is one failure, a
    read of two messages is two. (The port is made here, not by the fixture: ``./dev
    mutate`` traces a test's body only.)"""
    vsc, clock = MemoryPort(), Clock()
    port = LinkPort(MemoryLink(vsc), clock, Timings(), Backoff(250, 400))
    assert (port.opens, port.failures, port.messages) == (0, 0, 0)
    vsc.unplug()
    port.open(0)
    assert port.next_attempt == 250 * MS  # the backoff handed in, not a default one
    vsc.replug()
    port.open(250 * MS)
    vsc.send(RUN)
    vsc.send(RUN)
    port.receive()
    status = port.status(0)
    assert (status.opens, status.open_failures, port.messages) == (1, 1, 2)


def test_the_log_says_when_the_link_opened_and_why_it_broke(
    rig: tuple[LinkPort, MemoryPort, Clock], caplog: pytest.LogCaptureFixture
) -> None:
    """The operator's log holds each open and each break with its reason (the counters in
    status say how many; the log says when)."""
    port, vsc, clock = rig
    with caplog.at_level(logging.INFO, logger="srcsd"):
        port.open(0)
        vsc.unplug()
        clock.at(50 * MS)
        port.receive()
    assert [r.getMessage() for r in caplog.records] == [
        "memory memory: open",
        "memory memory: broken: device gone",
    ]


def _opened_after(port: LinkPort, now: int, end: float) -> LinkOpened | LinkBroken:
    """``port.open(now)``, asked until it says more than ``None`` (the link's thread under way
    has returned), before ``end`` (``time.monotonic``)."""
    while (opened := port.open(now)) is None:
        assert time.monotonic() < end, "the open never followed the link's thread"
        time.sleep(0.001)
    return opened


class _PreparingLink(MemoryLink):
    """A memory link whose open has a part to do off the loop: ``prepare`` waits until the
    test releases it, and says on which thread it ran."""

    prepares_open = True

    def __init__(self, port: MemoryPort) -> None:
        super().__init__(port)
        self.release = threading.Event()
        self.prepared_on: list[str] = []

    def prepare(self) -> None:
        self.prepared_on.append(threading.current_thread().name)
        self.release.wait(30)


def test_a_link_that_prepares_its_open_is_opened_once_its_prepare_has_returned(
    rig: tuple[LinkPort, MemoryPort, Clock],
) -> None:
    """SR-9.8: the sleeping part of a link's open (a HID node's, 50 ms in usbhid) runs on a
    thread of its own, ``srcsd-open``, never on the loop: while it runs, ``open`` says so with
    ``None`` at once and asks again ``PREPARE_POLL_NS`` later, counting no failure; once it has
    returned, the next ``open`` opens the link. One prepare at a time."""
    _, vsc, clock = rig
    link = _PreparingLink(vsc)
    port = LinkPort(link, clock, Timings(), Backoff(first_ms=100, max_ms=400))
    assert port.open(0) is None
    assert port.next_attempt == PREPARE_POLL_NS
    assert port.open(PREPARE_POLL_NS) is None
    assert (link.is_open, port.failures, port.opens) == (False, 0, 0)
    end = time.monotonic() + 10
    while not link.prepared_on:
        assert time.monotonic() < end, "prepare never ran"
        time.sleep(0.001)
    link.release.set()
    assert _opened_after(port, 2 * PREPARE_POLL_NS, end) == LinkOpened(2 * PREPARE_POLL_NS)
    assert link.is_open
    assert link.prepared_on == [PREPARE_THREAD]


class _SlowClosingLink(MemoryLink):
    """A memory link whose release after a break has a part to do off the loop (a tty's
    close): it waits until the test lets it go, and says on which thread it ran."""

    def __init__(self, port: MemoryPort) -> None:
        super().__init__(port)
        self.let_go = threading.Event()
        self.released_on: list[str] = []

    def detach(self) -> Callable[[], None]:
        self.close()

        def release() -> None:
            self.released_on.append(threading.current_thread().name)
            self.let_go.wait(30)

        return release


def test_a_broken_links_slow_release_runs_off_the_loop_and_the_reopen_waits_for_it() -> None:
    """SR-9.8: a break is decided at once, while what may sleep of the link's release (a
    tty's close, which waits for the hang-up's lock) runs on ``srcsd-close``; the next open
    waits for it, saying ``None`` and asking again ``PREPARE_POLL_NS`` later without counting
    a failure (a serial port is opened exclusively: beside the old close it would be busy)."""
    vsc, clock = MemoryPort(), Clock()
    link = _SlowClosingLink(vsc)
    port = LinkPort(link, clock, Timings(), Backoff(first_ms=100, max_ms=400))
    assert port.open(0) == LinkOpened(0)
    vsc.unplug()
    clock.at(50 * MS)
    assert port.receive() == LinkBroken(50 * MS, "device gone")  # the release still held
    assert not link.is_open
    end = time.monotonic() + 10
    while not link.released_on:
        assert time.monotonic() < end, "the release never ran"
        time.sleep(0.001)
    assert link.released_on == [CLOSE_THREAD]
    vsc.replug()
    assert port.open(150 * MS) is None
    assert port.next_attempt == 150 * MS + PREPARE_POLL_NS
    assert (link.is_open, port.failures, port.opens) == (False, 0, 1)
    link.let_go.set()
    assert _opened_after(port, 160 * MS, end) == LinkOpened(160 * MS)
    assert (port.failures, port.opens) == (0, 2)
