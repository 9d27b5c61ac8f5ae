"""The loop's wait on real sockets and a real epoll set: what it watches, how it sorts what was
ready, the wake pair and the clients' order (SR-9.4, SR-10.1, SR-8.14). The loop's use of it,
the link before the clients and a bounded share for them, is checked on the real loop in
``tests/daemon/test_loop.py::test_each_turn_serves_the_link_first_and_a_bounded_number_of_clients``."""

from __future__ import annotations

import socket
from collections.abc import Iterator

import pytest

from supervisord.daemon.waiter import Waiter

WAIT_S = 5.0  # a bound, never reached where something is ready: the wait returns at once


class Pair:
    """A connected pair: ``near`` is the descriptor watched, ``far`` the peer that writes."""

    def __init__(self) -> None:
        self.near, self.far = socket.socketpair()

    @property
    def fd(self) -> int:
        return self.near.fileno()

    def close(self) -> None:
        self.near.close()
        self.far.close()


@pytest.fixture
def pairs() -> Iterator[list[Pair]]:
    made = [Pair() for _ in range(4)]
    try:
        yield made
    finally:
        for pair in made:
            pair.close()


@pytest.fixture
def waiter() -> Iterator[Waiter]:
    made = Waiter()
    try:
        yield made
    finally:
        made.close()


def test_the_link_the_sink_and_the_clients_are_sorted_and_the_wake_byte_drained(
    waiter: Waiter, pairs: list[Pair]
) -> None:
    link, sink, client, quiet = pairs
    waiter.start(sink.fd)
    waiter.watch(link.fd, [(client.fd, False), (quiet.fd, False)])
    assert waiter.link_fd == link.fd
    link.far.send(b"x")
    sink.far.send(b"x")
    client.far.send(b"x")
    waiter.wake()
    link_ready, sink_ready, clients = waiter.sort(waiter.wait(WAIT_S))
    assert (link_ready, sink_ready) == (True, True)
    assert [fd for fd, _ in clients] == [client.fd]
    link.near.recv(1), sink.near.recv(1), client.near.recv(1)
    assert waiter.wait(0) == []  # the wake byte was read: it ends one wait only


def test_a_wake_from_a_signal_handler_ends_a_wait_with_nothing_else_ready(
    waiter: Waiter, pairs: list[Pair]
) -> None:
    waiter.start(pairs[0].fd)
    waiter.watch(None, [])
    waiter.wake()
    assert waiter.sort(waiter.wait(WAIT_S)) == (False, False, [])


def test_the_usual_turn_registers_nothing_and_a_change_is_followed(
    waiter: Waiter, pairs: list[Pair]
) -> None:
    """SR-9.4: the same list as the last turn's leaves the set as it is; a dropped client is
    no longer watched, a link closed (``None``) no longer either."""
    link, one, two, _ = pairs
    watched = [(one.fd, False), (two.fd, False)]
    waiter.watch(link.fd, watched)
    before = waiter.watched
    waiter.watch(link.fd, list(watched))  # equal, as the listener hands its list each turn
    assert waiter.watched is before
    waiter.watch(None, [(two.fd, False)])
    assert waiter.watched == {two.fd: waiter.watched[two.fd]}
    assert waiter.link_fd is None
    for pair in (link, one, two):
        pair.far.send(b"x")
    assert [fd for fd, _ in waiter.wait(WAIT_S)] == [two.fd]


def test_readiness_follows_what_is_watched(waiter: Waiter, pairs: list[Pair]) -> None:
    """Writable only where a write is wanted; a hang-up reads as both where watched, so the
    listener reads the end of its connection (as ``selectors`` does)."""
    reader, writer, _, _ = pairs
    waiter.watch(None, [(reader.fd, False), (writer.fd, True)])
    ready = dict(waiter.wait(WAIT_S))
    assert list(ready) == [writer.fd]  # nothing to read yet; room to write
    assert waiter.readiness(writer.fd, ready[writer.fd]) == (False, True)
    reader.far.close()
    ready = dict(waiter.wait(WAIT_S))
    assert waiter.readiness(reader.fd, ready[reader.fd]) == (True, False)
    assert waiter.readiness(12345, ready[reader.fd]) == (False, False)  # not watched


def test_urgent_clients_come_first_and_the_others_in_their_turn(waiter: Waiter) -> None:
    """SR-10.1: after the one served last, wrapping round; SR-8.14: the operator socket
    before them all."""
    ready = [(9, 1), (4, 1), (7, 1), (5, 1)]
    assert waiter.order(ready, frozenset()) == ([], [(4, 1), (5, 1), (7, 1), (9, 1)])
    waiter.cursor = 5
    assert waiter.order(ready, frozenset()) == ([], [(7, 1), (9, 1), (4, 1), (5, 1)])
    assert waiter.order(ready, frozenset({9})) == ([(9, 1)], [(7, 1), (4, 1), (5, 1)])
    waiter.cursor = 9
    assert waiter.order(ready, frozenset())[1][0] == (4, 1)
