"""sd_notify checked on a real datagram socket."""

from __future__ import annotations

import socket
from pathlib import Path

from supervisord.daemon.notify import Notifier


def test_lines_arrive_on_the_notify_socket(tmp_path: Path) -> None:
    """READY and STATUS arrive as one datagram of KEY=value lines."""
    path = str(tmp_path / "notify")
    with socket.socket(socket.AF_UNIX, socket.SOCK_DGRAM) as server:
        server.bind(path)
        notifier = Notifier({"NOTIFY_SOCKET": path, "WATCHDOG_USEC": "2000000"})
        try:
            assert notifier.send(READY="1", STATUS="STOPPED: startup")
            assert server.recv(4096) == b"READY=1\nSTATUS=STOPPED: startup\n"
            assert notifier.watchdog_interval_ns == 1_000_000_000
        finally:
            notifier.close()


def test_abstract_socket_address() -> None:
    """An '@'-prefixed NOTIFY_SOCKET is an abstract socket."""
    with socket.socket(socket.AF_UNIX, socket.SOCK_DGRAM) as server:
        server.bind("\0srcs-notify-test")
        notifier = Notifier({"NOTIFY_SOCKET": "@srcs-notify-test"})
        try:
            assert notifier.send(WATCHDOG="1")
            assert server.recv(4096) == b"WATCHDOG=1\n"
        finally:
            notifier.close()


def test_without_systemd_nothing_happens() -> None:
    """Without NOTIFY_SOCKET the notifier is disabled and sending is a no-op."""
    notifier = Notifier({})
    assert not notifier.enabled
    assert not notifier.send(READY="1")
    assert notifier.watchdog_interval_ns is None


def test_a_vanished_socket_is_counted_not_raised(tmp_path: Path) -> None:
    """A notify socket that is gone costs a counted failure, never an exception in the loop."""
    notifier = Notifier({"NOTIFY_SOCKET": str(tmp_path / "gone")})
    try:
        assert not notifier.send(WATCHDOG="1")
        assert notifier.failures == 1
    finally:
        notifier.close()


def test_watchdog_for_another_pid_is_ignored() -> None:
    """WATCHDOG_USEC meant for another process (WATCHDOG_PID) is not ours to honour."""
    notifier = Notifier({"WATCHDOG_USEC": "1000000", "WATCHDOG_PID": "1"})
    assert notifier.watchdog_interval_ns is None
