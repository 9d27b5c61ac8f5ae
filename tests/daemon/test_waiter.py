"""The loop's wait on real sockets and a real epoll set: what it watches, how it sorts what was
ready, the wake pair and the clients' order (SR-9.4, SR-10.1, SR-8.14). The loop's use of it,
the link before the clients and a bounded share for them, is checked on the real loop in
``tests/daemon/test_loop.py::test_each_turn_serves_the_link_first_and_a_bounded_number_of_clients``."""

from __future__ import annotations

import contextlib
import os
import select
import signal
import socket
import threading
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
    link_events, sink_ready, clients = waiter.sort(waiter.wait(WAIT_S))
    assert (link_events, sink_ready) == (select.EPOLLIN, True)  # the link's mask, for the port
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


def test_a_client_given_the_broken_links_descriptor_number_is_watched(
    waiter: Waiter, pairs: list[Pair]
) -> None:
    """SR-10.1: the link breaks and is closed in a turn, and a client accepted in the same
    turn gets the lowest free descriptor, the link's number. The next watch must register it
    as the client it is: the kernel dropped the closed link's watch, and a waiter that still
    took that number for watched would never see the client's requests."""
    link, client, _, _ = pairs
    number = link.fd
    waiter.watch(number, [])
    link.near.close()  # the break's close
    reused = socket.socket(fileno=os.dup2(client.fd, number))  # the accept's new descriptor
    try:
        waiter.watch(None, [(number, False)])
        client.far.send(b"x")
        assert [fd for fd, _ in waiter.wait(WAIT_S)] == [number]
    finally:
        reused.close()


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


def test_a_real_signal_whose_handler_wakes_ends_the_wait_with_the_wake_byte(
    waiter: Waiter, pairs: list[Pair]
) -> None:
    """A stopping signal ends the loop's wait at once (docs/safety.md "The stop path first"):
    its handler's byte is what the wait returns, and nothing else (a wake that wrote nothing
    would leave the wait to its timeout, retried by Python across the signal, PEP 475)."""
    waiter.start(pairs[0].fd)
    waiter.watch(None, [])
    previous = signal.signal(signal.SIGALRM, lambda _signum, _frame: waiter.wake())
    try:
        signal.setitimer(signal.ITIMER_REAL, 0.05)
        ready = waiter.wait(WAIT_S)
    finally:
        signal.setitimer(signal.ITIMER_REAL, 0)
        signal.signal(signal.SIGALRM, previous)
    assert len(ready) == 1  # the wake pair's byte ended it
    assert waiter.sort(ready) == (False, False, [])
    assert waiter.wait(0) == []  # drained


def test_the_drain_never_blocks_the_loop_and_reads_64_bytes_a_turn(
    waiter: Waiter, pairs: list[Pair]
) -> None:
    """SR-9.4: sorting a ready list whose wake byte is already read returns at once (the wake
    pair's read end is non-blocking), and a turn's drain is one bounded read of 64 bytes:
    more wakes than that end the next wait at once too, so none is lost."""
    waiter.start(pairs[0].fd)
    waiter.watch(None, [])
    for _ in range(65):
        waiter.wake()
    ready = waiter.wait(WAIT_S)
    assert waiter.sort(ready) == (False, False, [])
    left = waiter.wait(0)
    assert left == ready  # one byte of the 65 is left for the next turn
    assert waiter.sort(left) == (False, False, [])
    assert waiter.wait(0) == []
    for _ in range(64):
        waiter.wake()
    ready = waiter.wait(WAIT_S)
    waiter.sort(ready)
    assert waiter.wait(0) == []  # 64 bytes: one read drains them all
    # The same list sorted again, its byte read: a blocking read would hang the loop here.
    done = threading.Event()

    def sort_again() -> None:
        waiter.sort(ready)
        done.set()

    sorter = threading.Thread(target=sort_again, daemon=True)
    sorter.start()
    finished = done.wait(WAIT_S)
    if not finished:
        waiter.wake()  # release the blocked read, so the thread ends
    sorter.join(WAIT_S)
    assert finished, "sort blocked on the drained wake pair"


def test_a_flood_of_wakes_never_blocks_the_signal_handler(
    waiter: Waiter, pairs: list[Pair]
) -> None:
    """SR-6.6, SR-7.14: a handler's wake never blocks, however many come before the loop
    drains them (the shutdown drains none): a blocking write on a full wake pair would hold
    the main thread inside the handler, and with it the shutdown's record drain, until the
    unit's stop timeout kills it. One pending byte is enough to end a wait; the rest are
    dropped, so the wait still ends at once after the flood."""
    waiter.start(pairs[0].fd)
    waiter.watch(None, [])
    wakes = 100_000  # far past a socket pair's buffer (a few hundred one-byte sends)
    done = threading.Event()

    def flood() -> None:
        for _ in range(wakes):
            waiter.wake()
        done.set()

    flooder = threading.Thread(target=flood, daemon=True)
    flooder.start()
    finished = done.wait(30.0)  # the flood takes well under a second unblocked
    if not finished:
        while flooder.is_alive():  # release the blocked send, so the thread ends
            with contextlib.suppress(BlockingIOError):
                waiter.wait(0)
                waiter._wake_r.recv(1 << 16)
            flooder.join(0.01)
    assert finished, "a wake blocked on the full wake pair"
    assert len(waiter.wait(WAIT_S)) == 1  # the flood's bytes still end the next wait


def test_a_client_that_comes_to_want_a_write_is_watched_for_it_and_back(
    waiter: Waiter, pairs: list[Pair]
) -> None:
    """A listener's client with a reply to send is watched for room to write from the next
    turn, and no longer once sent (the change is made to the epoll set, not only recorded)."""
    client = pairs[0]
    waiter.watch(None, [(client.fd, False)])
    assert waiter.wait(0) == []  # nothing to read; a write not wanted
    waiter.watch(None, [(client.fd, True)])
    assert waiter.wait(WAIT_S) == [(client.fd, select.EPOLLOUT)]
    waiter.watch(None, [(client.fd, False)])
    assert waiter.wait(0) == []


def test_descriptor_0_is_a_client_like_any_other_in_the_first_turn() -> None:
    """SR-10.1: a daemon started with its standard input closed may accept a client on
    descriptor 0; before any client is served it comes first, in descriptor order. (The
    waiter is made here, not by the fixture: ``./dev mutate`` traces a test's body only.)"""
    waiter = Waiter()
    try:
        ready = [(6, 1), (0, 1), (3, 1)]
        assert waiter.order(ready, frozenset()) == ([], [(0, 1), (3, 1), (6, 1)])
    finally:
        waiter.close()


def test_closing_releases_every_descriptor_it_made() -> None:
    """The epoll set and both ends of the wake pair are closed: a daemon that restarts its
    loop leaks none (made here, not by the fixture: ``./dev mutate`` traces a test's body)."""
    before = len(os.listdir("/proc/self/fd"))
    waiter = Waiter()
    assert len(os.listdir("/proc/self/fd")) == before + 3
    waiter.close()
    assert len(os.listdir("/proc/self/fd")) == before
