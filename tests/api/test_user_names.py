"""User names looked up off the loop (SR-10.3): the cache and its thread, and the server's rule
for a connection whose name is not known yet, with a lookup the test holds as long as it likes
(a hung NSS), on a clock the test drives."""

from __future__ import annotations

import os
import select
import threading
import time
from collections.abc import Callable, Iterator
from pathlib import Path

import pytest

from supervisord.api.names import NAME_POLL_NS, NAME_WAIT_NS, UserNames
from supervisord.api.requests import Estop, FleetStopRequest, Heartbeat, Hello
from supervisord.api.server import Received, ServerConfig
from supervisord.testkit.wait import wait_until
from tests.api.test_api_server import Loop, Peer
from tests.daemon.test_loop import ManualClock

S = 1_000_000_000


class HeldLookup:
    """A user database that answers only when the test lets it: ``release`` ends every wait."""

    def __init__(self) -> None:
        self.released = threading.Event()
        self.asked: list[int] = []

    def __call__(self, uid: int) -> str:
        self.asked.append(uid)
        self.released.wait(30)
        return f"user{uid}"


@pytest.fixture
def held() -> Iterator[HeldLookup]:
    lookup = HeldLookup()
    yield lookup
    lookup.released.set()


def _taken(names: UserNames, now: int) -> Callable[[], list[tuple[int, str]]]:
    got: list[tuple[int, str]] = []

    def take() -> list[tuple[int, str]]:
        got.extend(names.take(now))
        return got

    return take


def test_a_name_is_never_waited_for_and_is_cached_once_found(held: HeldLookup) -> None:
    """SR-10.3: asking for a name the cache lacks returns ``None`` at once and queues one
    lookup (asking again queues nothing more); once the thread found it, it is answered from
    the cache."""
    names = UserNames(held)
    try:
        assert names.name(4242, 0) is None
        assert names.name(4242, 1) is None
        wait_until(lambda: held.asked == [4242], 10.0, what="the lookup to start")
        held.released.set()
        take = _taken(names, 5)
        wait_until(lambda: take() == [(4242, "user4242")], 10.0, what="the lookup's end")
        assert names.name(4242, 6) == "user4242"
        assert held.asked == [4242]
    finally:
        names.close()


def test_an_old_name_is_still_answered_while_it_is_looked_up_again(held: HeldLookup) -> None:
    """SR-10.3: past ``ttl_ns`` the cached name is still answered (a rename is rare, a wait is
    never allowed) and looked up again; before it, no second lookup."""
    held.released.set()
    names = UserNames(held, ttl_ns=10 * S)
    try:
        names.ask(7)
        take = _taken(names, 0)
        wait_until(lambda: take() == [(7, "user7")], 10.0, what="the first lookup")
        assert names.name(7, 10 * S - 1) == "user7"
        assert held.asked == [7]
        assert names.name(7, 10 * S) == "user7"
        wait_until(lambda: held.asked == [7, 7], 10.0, what="the second lookup")
    finally:
        names.close()


def test_a_full_queue_asks_for_nothing_more(held: HeldLookup) -> None:
    """SR-10.3: the lookups waiting are bounded: past ``max_queued`` nothing more is queued
    (the uid stands in for the name), so a flood of uids cannot grow the queue."""
    names = UserNames(held, max_queued=2)
    try:
        for uid in (1, 2, 3):
            assert names.name(uid, 0) is None
        wait_until(lambda: held.asked == [1], 10.0, what="the first lookup")
        held.released.set()
        take = _taken(names, 0)
        wait_until(lambda: len(take()) == 2, 10.0, what="two lookups")
        assert held.asked == [1, 2]
    finally:
        names.close()


def test_a_connection_waiting_for_its_name_is_served_estop_and_the_rest_in_order(
    tmp_path: Path, held: HeldLookup
) -> None:
    """SR-10.3, SR-8.4, SR-8.13: while the lookup of the caller's name hangs, an ``estop`` sent
    after a ``hello`` is acted on at once (the uid names the caller), the ``hello`` and the
    heartbeat behind it wait; 2 s of the loop's clock later they are served, under the uid,
    and the three replies leave in request order (the e-stop's behind the hello's); when the
    lookup ends, the connection is named."""
    clock = ManualClock()
    loop = Loop(ServerConfig(tmp_path / "api.sock"), clock=clock, names=UserNames(held))
    peer = Peer(tmp_path / "api.sock")
    try:
        peer.send(b'{"op":"hello","name":"nav"}\n{"op":"estop"}\n{"op":"heartbeat"}\n')
        loop.until(lambda: bool(loop.of_type(Received)))
        served = [r.request for r in loop.of_type(Received)]
        assert served == [Estop()]
        uid = os.getuid()
        assert loop.of_type(Received)[0].client.caller.name == str(uid)
        clock.advance(NAME_WAIT_NS - 1)
        for _ in range(5):
            loop.turn()
        assert [r.request for r in loop.of_type(Received)] == [Estop()]
        assert not peer.has(1)  # the e-stop's reply waits for the hello's
        clock.advance(1)
        hello, estop, heartbeat = peer.read(loop, 3)
        assert [r["op"] for r in (hello, estop, heartbeat)] == ["hello", "estop", "heartbeat"]
        assert estop == {"ok": True, "op": "estop"}
        served = [r.request for r in loop.of_type(Received)]
        assert served == [Estop(), Hello(name="nav"), Heartbeat()]
        held.released.set()

        def named() -> bool:
            clock.advance(NAME_POLL_NS)  # the loop looks at its own deadline (SR-10.7)
            return loop.server.clients()[0].caller.name == f"user{uid}"

        loop.until(named)
    finally:
        peer.close()
        loop.close()


def test_a_fleet_stop_is_served_while_the_name_is_looked_up(
    tmp_path: Path, held: HeldLookup
) -> None:
    """SR-10.3, SR-8.19: a ``fleet_stop`` is judged by the peer's uid alone, so, as an
    ``estop``, it is served at once while the lookup of the caller's name hangs; a
    ``fleet_release`` behind it waits for the name."""
    clock = ManualClock()
    loop = Loop(ServerConfig(tmp_path / "api.sock"), clock=clock, names=UserNames(held))
    peer = Peer(tmp_path / "api.sock")
    try:
        peer.send(
            b'{"op":"fleet_stop","stop_id":"s-1","sender":"c"}\n'
            b'{"op":"fleet_release","stop_id":"s-1","sender":"c"}\n'
        )
        loop.until(lambda: bool(loop.of_type(Received)))
        for _ in range(5):
            loop.turn()
        assert [r.request for r in loop.of_type(Received)] == [FleetStopRequest("s-1", "c")]
    finally:
        held.released.set()
        peer.close()
        loop.close()


class SignalledLookup(HeldLookup):
    """A held lookup that says when it has returned its answer."""

    def __init__(self) -> None:
        super().__init__()
        self.returned = threading.Event()

    def __call__(self, uid: int) -> str:
        try:
            return super().__call__(uid)
        finally:
            if self.released.is_set():
                self.returned.set()


def test_a_finished_lookup_wakes_nothing_the_loop_waits_on(tmp_path: Path) -> None:
    """SR-10.7: the lookup thread (ordinary priority) never wakes the loop (SCHED_FIFO): when
    the name a connection waits for is found, nothing the loop watches becomes readable; the
    loop takes the name at its own deadline, ``NAME_POLL_NS`` after its turn, and the
    connection's hello is served then, not after ``NAME_WAIT_NS``."""
    lookup = SignalledLookup()
    clock = ManualClock()
    loop = Loop(ServerConfig(tmp_path / "api.sock"), clock=clock, names=UserNames(lookup))
    peer = Peer(tmp_path / "api.sock")
    try:
        peer.send(b'{"op":"hello","name":"nav"}\n')
        loop.until(lambda: bool(loop.server.clients()))
        for _ in range(5):
            loop.turn()
        assert not loop.of_type(Received)  # the hello waits for the name
        lookup.released.set()
        assert lookup.returned.wait(30)
        time.sleep(0.5)  # ample for the thread to hand the name over, however it does
        watched = [fd for fd, _ in loop.server.descriptors(clock())]
        readable, _, _ = select.select(watched, [], [], 0)
        assert readable == [], "a finished lookup made a descriptor of the loop readable"
        due = loop.server.next_deadline()
        assert due is not None
        assert due <= clock() + NAME_POLL_NS
        clock.advance(NAME_POLL_NS)
        loop.turn()
        assert [r.request for r in loop.of_type(Received)] == [Hello(name="nav")]
        assert loop.of_type(Received)[0].client.caller.name == f"user{os.getuid()}"
    finally:
        lookup.released.set()
        peer.close()
        loop.close()
